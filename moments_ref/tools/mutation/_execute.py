"""Run mutants against the tests that reach them: per-test coverage, then one fork per mutant.

Coverage (coverage.py, one context per test) says which tests execute each line of the
mutated modules; a mutant runs only the tests that execute its statement. The parent
process imports the package and the test modules once; each mutant runs in a forked
child that swaps the code of the one function it changes (``function.__code__``, so
every reference to the function, ``from x import f`` included, sees the mutant) and
runs its tests with pytest, stopping at the first failure.
"""

from __future__ import annotations

import os
import shutil
import signal
import tempfile
import time
from collections import defaultdict
from pathlib import Path

__all__ = ["collect_coverage", "import_tests", "run_mutant", "baseline", "module_name_of"]


class _Recorder:
    """pytest plugin: one coverage context per test; durations and failures per test."""

    def __init__(self, cov=None):
        self.cov = cov
        self.durations = defaultdict(float)
        self.failed = []

    def pytest_runtest_protocol(self, item, nextitem):
        if self.cov is not None:
            self.cov.switch_context(item.nodeid)

    def pytest_runtest_logreport(self, report):
        self.durations[report.nodeid] += report.duration
        if report.failed:
            self.failed.append(report.nodeid)


def _pytest(args, plugin):
    import pytest

    return pytest.main(["-p", "no:cacheprovider", "-p", "no:xdist", "-q", *args], plugins=[plugin])


def _forked(fn, timeout, quiet=True):
    """Run ``fn() -> bytes`` in a forked child; ``(exit status, its bytes, timed out)``.

    The child's temporary files go to a folder of its own, removed when it has ended: a child
    ends without its exit handlers (``os._exit``, the alarm, the timeout's SIGKILL), so the
    files it would remove at exit (a driver process's log, ``tempfile``'s) are removed here.
    """
    scratch = tempfile.mkdtemp(prefix="moments-ref-mutant-")
    try:
        return _forked_in(fn, timeout, quiet, scratch)
    finally:
        shutil.rmtree(scratch, ignore_errors=True)


def _forked_in(fn, timeout, quiet, scratch):
    rfd, wfd = os.pipe()
    pid = os.fork()
    if pid == 0:  # child
        os.close(rfd)
        os.setpgid(0, 0)
        os.environ["TMPDIR"] = tempfile.tempdir = scratch  # and the processes it starts
        if quiet:
            null = os.open(os.devnull, os.O_WRONLY)
            os.dup2(null, 1)
            os.dup2(null, 2)
        code = 3
        try:
            view = memoryview(fn())
            while view:
                view = view[os.write(wfd, view):]
            code = 0
        finally:
            os._exit(code)
    os.close(wfd)
    os.set_blocking(rfd, False)
    deadline = time.monotonic() + timeout
    chunks, timed_out = [], False
    while True:  # drain the pipe while waiting: a payload over the pipe's buffer would block the child
        try:
            while chunk := os.read(rfd, 1 << 20):
                chunks.append(chunk)
        except BlockingIOError:
            pass
        done, status = os.waitpid(pid, os.WNOHANG)
        if done:
            break
        if time.monotonic() > deadline:
            os.killpg(pid, signal.SIGKILL)
            os.waitpid(pid, 0)
            status, timed_out = -1, True
            break
        time.sleep(0.02)
    os.set_blocking(rfd, True)
    with os.fdopen(rfd, "rb") as f:
        chunks.append(f.read())
    data = b"".join(chunks)
    return status, data, timed_out


def collect_coverage(paths, pytest_args, timeout=7200):
    """``({path: {line: [test ids]}}, {test id: seconds}, [failed test ids])`` over ``pytest_args``."""
    import json

    try:
        import coverage  # noqa: F401
    except ImportError:
        raise SystemExit("mutation: needs coverage.py (pip install -e \".[mutation]\")") from None

    def child():
        import coverage

        cov = coverage.Coverage(data_file=None, include=[str(Path(p).resolve()) for p in paths],
                                config_file=False)
        rec = _Recorder(cov)
        cov.start()
        try:
            _pytest(pytest_args, rec)
        finally:
            cov.stop()
        data = cov.get_data()
        lines = {}
        for p in paths:
            by_line = data.contexts_by_lineno(str(Path(p).resolve()))
            lines[p] = {int(k): sorted(c for c in v if c) for k, v in by_line.items()}
        return json.dumps({"lines": lines, "durations": rec.durations, "failed": rec.failed}).encode()

    status, data, timed_out = _forked(child, timeout)
    if status != 0 or timed_out:
        raise RuntimeError(f"coverage run failed (status {status}, timed out {timed_out})")
    out = json.loads(data)
    lines = {p: {int(k): v for k, v in d.items()} for p, d in out["lines"].items()}
    return lines, out["durations"], out["failed"]


def import_tests(test_ids):
    """Import the test modules of ``test_ids`` (and their conftest) in this process, as pytest
    would, so that every forked child starts with them loaded."""
    files = sorted({t.split("::")[0] for t in test_ids})
    if files:
        saved = os.dup(1)
        null = os.open(os.devnull, os.O_WRONLY)
        os.dup2(null, 1)
        try:
            _pytest(["--collect-only", *files], _Recorder())
        finally:
            os.dup2(saved, 1)
            os.close(null)
            os.close(saved)


def _live_function(module, qualname):
    """The function whose body the source's ``def`` holds: through a property, a method, and any
    decorator that records what it wraps (``functools.wraps``: the wrapper's own code is not the body)."""
    obj = module
    for part in qualname.split("."):
        obj = getattr(obj, part)
    for attr in ("fget", "__func__"):
        while hasattr(obj, attr) and not hasattr(obj, "__code__"):
            obj = getattr(obj, attr)
    while hasattr(obj, "__wrapped__"):
        obj = obj.__wrapped__
    return obj


def _child_run(module_name, top, code, test_ids, durations):
    """In the forked child: swap the code of ``top`` in ``module_name``, run ``test_ids``."""
    import importlib

    if code is not None:
        try:
            fn = _live_function(importlib.import_module(module_name), top)
            fn.__code__ = code
        except Exception as e:  # a harness failure, never a kill
            return f"-1\n{type(e).__name__}: {e}".encode()
        _clear_caches()
    rec = _Recorder()
    rc = 0
    with tempfile.TemporaryDirectory() as tmp:
        os.environ["HYPOTHESIS_STORAGE_DIRECTORY"] = tmp  # failures found under a mutant stay out of .hypothesis
        # derived goldens are cached on disk keyed by the sources, which a mutant does not change: each
        # mutant derives its own (a cache shared with the baseline would hand it the unmutated arrays)
        os.environ["MOMENTS_REF_CACHE"] = os.path.join(tmp, "cache")
        for batch in _batches(test_ids):
            # each file within a few times its measured time (and its collection, slow on a loaded machine):
            # a mutant that loops forever dies early (SIGALRM)
            signal.alarm(int(30 + 5 * sum(durations.get(t, 1.0) for t in batch)))
            rc = _pytest(["-x", *batch], rec)
            signal.alarm(0)
            if rc != 0:
                break
    return f"{int(rc)}\n{rec.failed[0] if rec.failed else ''}".encode()


def _clear_caches():
    """Empty every functools cache in the (forked) process: results the parent cached from the
    unmutated code (an lru_cache'd table, or a function that calls the mutated one) would hide the mutant."""
    import functools
    import gc

    for obj in gc.get_objects():
        if isinstance(obj, functools._lru_cache_wrapper):
            obj.cache_clear()


def _batches(test_ids):
    """One test file at a time, in the given order: most mutants die in the first, before the others are collected."""
    files = {}
    for t in test_ids:
        files.setdefault(t.split("::")[0], []).append(t)
    yield from files.values()


def run_mutant(module_name, top, code, test_ids, timeout, durations=None):
    """``(status, first failing test)`` of one mutant: ``killed``, ``survived``, ``timeout`` or ``error``.

    ``durations`` (test id -> seconds, measured unmutated): each test file may take ``30 s + 5×`` its time.
    """
    durations = {t: timeout for t in test_ids} if durations is None else durations
    status, data, timed_out = _forked(lambda: _child_run(module_name, top, code, test_ids, durations), timeout)
    if timed_out or (os.WIFSIGNALED(status) and os.WTERMSIG(status) == signal.SIGALRM):
        return "timeout", ""
    if os.WIFSIGNALED(status):  # the tests crashed the process (out of memory, a fault)
        return "killed", f"(signal {os.WTERMSIG(status)})"
    if status != 0 or not data:
        return "error", f"(harness exit {status})"
    rc, _, first = data.decode().partition("\n")
    rc = int(rc)
    if rc == -1:
        return "error", first
    if rc == 0:
        return "survived", ""
    if rc in (1, 2, 3):  # tests failed, collection failed (the mutant broke an import), internal error
        return "killed", first or f"(pytest exit {rc})"
    return "error", f"(pytest exit {rc})"


def baseline(module_name, test_ids, timeout):
    """The unmutated module on its tests: ``(passed, first failing test, seconds)``."""
    t0 = time.monotonic()
    status, first = run_mutant(module_name, "", None, test_ids, timeout)
    return status == "survived", first, time.monotonic() - t0


def module_name_of(path):
    """``moments_ref/golden/compare.py`` -> ``moments_ref.golden.compare``."""
    parts = list(Path(path).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)

