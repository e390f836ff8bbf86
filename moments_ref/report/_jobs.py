"""The report's independent tasks (scenes, the temporal claim, the artifacts) on ``--jobs`` worker processes.

:meth:`Workers.run` runs a list of tasks, each a top-level function and its
arguments (spawn-safe: the workers start a fresh interpreter and import the
function by name), either one after the other in this process (``jobs`` 1, the
serial path) or in a :class:`concurrent.futures.ProcessPoolExecutor` of
``jobs`` workers (start method ``spawn``: no inherited threads or locks). The
tasks are submitted in the order given (the caller puts the longest first, so
that the last task to finish is a short one); the results come back under their
keys in that same order, whatever order the workers finish in, so what is
written does not depend on the schedule.

A worker's exception is raised here as it was raised there (an
:class:`~moments_ref.InputError` stays one, so the command line prints its one
line); the other workers are stopped at once and nothing has been written: the
tasks only compute, the report writes after the last one returned. A worker the
system killed (memory) surfaces as :class:`WorkerDied`, an ``InputError`` naming
the remedy. The processes stay for a second batch (the report's Pareto-front plots,
which need every scene's rows).
"""

from __future__ import annotations

import multiprocessing
import os
import sys
import time
from concurrent.futures import FIRST_EXCEPTION, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool

from .._arrays import InputError, max_memory, set_max_memory

__all__ = ["usable_cores", "Workers", "WorkerDied"]


class WorkerDied(InputError):
    """A worker process ended without a result (killed by the system, usually for memory)."""


def usable_cores() -> int:
    """Cores this process may run on (``os.sched_getaffinity``; ``os.cpu_count`` where that is missing)."""
    try:
        return max(len(os.sched_getaffinity(0)), 1)
    except AttributeError:  # not on Linux
        return max(os.cpu_count() or 1, 1)


def _init_worker(limit):
    """Worker start: the parent's memory limit (``--max-memory``), matplotlib without a display."""
    set_max_memory(limit)
    import matplotlib

    matplotlib.use("Agg")


def _call(fn, args):
    """``fn(*args)`` and how long it took: ``(result, {"pid", "cpu", "wall"})`` (seconds)."""
    t0, c0 = time.perf_counter(), time.process_time()
    result = fn(*args)
    return result, {"pid": os.getpid(), "cpu": time.process_time() - c0, "wall": time.perf_counter() - t0}


def _serial(tasks, bar):
    out = {}
    for key, fn, args in tasks:
        out[key] = _call(fn, args)
        if bar is not None:
            bar.update(1)
    return out


def _stop(pool):
    """End the running workers (the processes this pool started) and cancel what has not started."""
    # The executor has no public way to stop a running task: its worker processes
    # (``_processes``, cleared by ``shutdown``) are terminated first.
    for p in list((getattr(pool, "_processes", None) or {}).values()):
        if p.is_alive():
            p.terminate()
    pool.shutdown(wait=False, cancel_futures=True)


def _parallel(pool, tasks, bar):
    try:
        futures = {pool.submit(_call, fn, args): key for key, fn, args in tasks}
        pending = set(futures)
        while pending:
            done, pending = wait(pending, return_when=FIRST_EXCEPTION)
            for f in done:
                f.result()  # raises the worker's exception here
                if bar is not None:
                    bar.set_postfix_str(" ".join(futures[f]), refresh=False)
                    bar.update(1)
    except BrokenProcessPool:
        _stop(pool)
        raise WorkerDied("jobs: a worker process was killed before it finished (often for lack of memory); "
                         "rerun with --jobs 1 or fewer jobs") from None
    except BaseException:
        _stop(pool)
        raise
    return {key: f.result() for f, key in futures.items()}


class Workers:
    """Up to ``jobs`` worker processes for several batches of tasks (a context manager).

    The processes start with the first :meth:`run` of more than one task (at most
    one per task of that batch) and stay for the next batches, whose tasks then
    skip the start-up (a fresh interpreter importing NumPy, SciPy and matplotlib).
    ``jobs`` 1 runs every batch here. Leaving the block lets the workers exit
    without waiting for them (they have nothing left to do; the interpreter
    joins them at exit); after an error they are terminated.
    """

    def __init__(self, jobs=1):
        self.jobs = max(int(jobs), 1)
        self._pool = None

    def __enter__(self):
        return self

    def __exit__(self, kind, value, tb):
        if self._pool is not None:
            if kind is None:
                self._pool.shutdown(wait=False)
            else:
                _stop(self._pool)
            self._pool = None
        return False

    def run(self, tasks, progress=False, desc="report", timings=None):
        """Run ``tasks`` (a list of ``(key, function, args)``); return ``{key: result}`` in the tasks' order.

        ``progress``: a tqdm bar of the tasks on stderr. ``timings``: a dict
        receiving per key the task's ``{"pid", "cpu", "wall"}`` (the process that
        ran it, its CPU and wall seconds).
        """
        tasks = list(tasks)
        bar = None
        if progress and tasks:
            from tqdm import tqdm

            bar = tqdm(total=len(tasks), desc=desc, unit="task", file=sys.stderr, leave=False)
        try:
            if self._pool is None and min(self.jobs, len(tasks)) > 1:
                self._pool = ProcessPoolExecutor(max_workers=min(self.jobs, len(tasks)),
                                                 mp_context=multiprocessing.get_context("spawn"),
                                                 initializer=_init_worker, initargs=(max_memory(),))
            done = _serial(tasks, bar) if self._pool is None else _parallel(self._pool, tasks, bar)
        finally:
            if bar is not None:
                bar.close()
        if timings is not None:
            timings.update({k: t for k, (_, t) in done.items()})
        return {k: r for k, (r, _) in done.items()}
