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

Workers die with the parent, however it ends: each asks the kernel for SIGKILL
when its parent ends (Linux ``PR_SET_PDEATHSIG``) and watches its parent id
from a thread (every :data:`WATCH_SECONDS`, on any system), so that a parent
killed by SIGTERM or SIGKILL leaves no worker computing for nobody. Workers
ignore SIGINT: Ctrl-C reaches the parent, which stops them. Warnings a task
raises come back with its result and are raised again in the parent, so that
none is printed by a worker before the parent's one-line refusal.

References
----------
.. [1] FLIP: Pontus Andersson, Jim Nilsson, Tomas Akenine-Möller, Magnus Oskarsson, Kalle Åström
       and Mark D. Fairchild. 2020. *ꟻLIP: A Difference Evaluator for Alternating Images*.
       Proceedings of the ACM on Computer Graphics and Interactive Techniques (HPG 2020) 3, 2. Used
       through the package ``flip-evaluator``.
"""

from __future__ import annotations

import gc
import multiprocessing
import os
import signal
import sys
import threading
import time
import warnings
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


#: Seconds between a worker's checks that its parent still runs.
WATCH_SECONDS = 0.5


def _die_with_parent(parent):
    """End this worker when process ``parent`` ends: the kernel's parent-death signal and a watching thread."""
    if sys.platform.startswith("linux"):
        import ctypes

        try:  # prctl(PR_SET_PDEATHSIG, SIGKILL): the kernel kills this process when its parent ends
            ctypes.CDLL(None, use_errno=True).prctl(1, int(signal.SIGKILL), 0, 0, 0)
        except (OSError, AttributeError):
            pass  # the watching thread below still ends it

    def watch():
        while os.getppid() == parent:
            time.sleep(WATCH_SECONDS)
        os._exit(1)

    if os.getppid() != parent:  # the parent ended before the signal was asked for
        os._exit(1)
    threading.Thread(target=watch, name="watch-parent", daemon=True).start()


#: A worker's threshold of young objects for the cyclic garbage collector (Python's default 700).
#: The tasks' figures allocate many small objects; at 700 the collector took about 2 % of a
#: worker's CPU (0.34 to 0.44 s of the knot and railing scenes' 19 to 22 s, 370 young collections),
#: at 5000 0.09 s (51), with the same peak memory (the arrays are not tracked by the collector).
GC_YOUNG = 5000


def _init_worker(limit, parent=None, threads=None):
    """Worker start: die with the parent, ignore Ctrl-C (the parent stops the workers), the parent's
    memory limit (``--max-memory``), :data:`GC_YOUNG`, matplotlib without a display, and the worker's share of the
    cores (``threads``) for OpenMP code loaded later (ꟻLIP's ``flip-evaluator``) unless the user
    set ``OMP_NUM_THREADS``."""
    if parent is not None:
        _die_with_parent(parent)
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    set_max_memory(limit)
    if threads is not None:
        # The workers already fill the cores: an OpenMP pool per worker as wide as the machine
        # only oversubscribes it, and its threads spin while they wait (ꟻLIP took about 1.4 times
        # the CPU with two threads as with one, the same values). Read when libgomp loads.
        os.environ.setdefault("OMP_NUM_THREADS", str(threads))
    gc.set_threshold(GC_YOUNG, *gc.get_threshold()[1:])
    import matplotlib

    matplotlib.use("Agg")


def _warm(module):
    """A worker's first task when started early (:meth:`Workers.start`): import ``module``."""
    import importlib

    importlib.import_module(module)


def _call(fn, args):
    """``fn(*args)`` and how it ran: ``(result, {"pid", "cpu", "wall", "warnings"})`` (seconds; the warnings
    it raised as ``(message, category, filename, lineno)``, raised again by the parent)."""
    t0, c0 = time.perf_counter(), time.process_time()
    with warnings.catch_warnings(record=True) as caught:
        result = fn(*args)
    return result, {"pid": os.getpid(), "cpu": time.process_time() - c0, "wall": time.perf_counter() - t0,
                    "warnings": [(str(w.message), w.category, w.filename, w.lineno) for w in caught]}


def _warn_again(done):
    """Raise the warnings the tasks recorded here, in the tasks' order (after every task succeeded)."""
    for _, info in done.values():
        for message, category, filename, lineno in info.pop("warnings", ()):
            warnings.warn_explicit(message, category, filename, lineno)


def _serial(tasks, bar):
    out = {}
    for key, fn, args in tasks:
        out[key] = _call(fn, args)
        if bar is not None:
            bar.update(1)
    return out


#: Longest wait for a pool's manager thread when the pool is left.
JOIN_SECONDS = 10


def _retire(pool, stop=False):
    """Shut ``pool`` down and wait for its manager thread; ``stop``: end the running workers first.

    The wait matters at exit: CPython 3.11's exit hook wakes a pool's manager thread
    without the pool's lock, and a manager thread still closing its pipe then makes
    the interpreter print a traceback (``OSError: Bad file descriptor``) after the
    command's one-line refusal. Once the thread has ended, the hook has nothing to wake.
    """
    manager = getattr(pool, "_executor_manager_thread", None)  # cleared by shutdown
    if stop:
        # The executor has no public way to stop a running task: its worker processes
        # (``_processes``, cleared by ``shutdown``) are terminated first.
        for p in list((getattr(pool, "_processes", None) or {}).values()):
            if p.is_alive():
                p.terminate()
    pool.shutdown(wait=False, cancel_futures=stop)
    if manager is not None:
        manager.join(JOIN_SECONDS)


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
        _retire(pool, stop=True)
        raise WorkerDied("jobs: a worker process was killed before it finished (often for lack of memory); "
                         "rerun with --jobs 1 or fewer jobs") from None
    except BaseException:
        _retire(pool, stop=True)
        raise
    return {key: f.result() for f, key in futures.items()}


class Workers:
    """Up to ``jobs`` worker processes for several batches of tasks (a context manager).

    The processes start with the first :meth:`run` of more than one task (at most
    one per task of that batch) and stay for the next batches, whose tasks then
    skip the start-up (a fresh interpreter importing NumPy, SciPy and matplotlib).
    ``jobs`` 1 runs every batch here. Leaving the block ends the idle workers
    (after an error, the running ones are terminated) and waits until the pool's
    manager thread has joined them (:func:`_retire`).
    """

    def __init__(self, jobs=1):
        self.jobs = max(int(jobs), 1)
        self._pool = None

    def __enter__(self):
        return self

    def __exit__(self, kind, value, tb):
        if self._pool is not None:
            _retire(self._pool, stop=kind is not None)
            self._pool = None
        return False

    def start(self, tasks, module):
        """Start the worker processes for up to ``tasks`` tasks now, without waiting for them.

        They import ``module`` (the tasks' functions' module, :func:`_warm`) while the
        caller prepares their tasks, instead of after it; nothing happens with one job
        or one task.
        """
        n = min(self.jobs, int(tasks))
        if self._pool is None and n > 1:
            self._pool = self._new_pool(n)
            for _ in range(n):
                self._pool.submit(_warm, module)

    def _new_pool(self, n):
        threads = max(1, usable_cores() // n)
        return ProcessPoolExecutor(max_workers=n, mp_context=multiprocessing.get_context("spawn"),
                                   initializer=_init_worker, initargs=(max_memory(), os.getpid(), threads))

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
                self._pool = self._new_pool(min(self.jobs, len(tasks)))
            done = _serial(tasks, bar) if self._pool is None else _parallel(self._pool, tasks, bar)
        finally:
            if bar is not None:
                bar.close()
        _warn_again(done)
        if timings is not None:
            timings.update({k: t for k, (_, t) in done.items()})
        return {k: r for k, (r, _) in done.items()}
