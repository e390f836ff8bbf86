"""The driver process and its supervisor: every driver call of the harness runs in one child process.

A driver's compiler and its dispatch run inside the process that calls them: a
macro that expands without bound, a local array of 2^26 floats (Mesa aborts with
``std::bad_alloc``), a kernel that writes out of bounds or a loop that never ends
would take the harness down with them, or hang it (a GPU driver does not stop a
loop; llvmpipe and lavapipe have no GPU reset). So the OpenGL context and the wgpu
devices live in one child process (``python -m moments_ref.conformance._driverproc``,
started on first use and reused, so that each driver starts once), and the harness
sends it *jobs*: a function's dispatch (:mod:`._dispatch`) or a kernel run
(:mod:`.kernel._job`). The jobs differ; this machinery is the same for both.

* The child's data segment is limited to ``max_memory()`` (``--max-memory``, 4 GiB
  by default); its stdout and stderr (driver chatter) go to a log file; it is a
  process group of its own and dies with its parent.
* A job reports a heartbeat after each step (the compile, each dispatch), and every
  step has a time limit the job names (its ``step``): :data:`COMPILE_SECONDS` to
  compile, the watchdog (:func:`set_watchdog`, ``--watchdog``, :data:`WATCHDOG_SECONDS`
  by default) for each dispatch.
* A child that overruns a step is :class:`DriverTimeout`, one that dies
  :class:`DriverDied`: its process group is killed and the next job starts a fresh
  child. Both are :class:`DriverError`, an :class:`~moments_ref.InputError` (exit 2,
  one line) that names the step the driver was in, the signal, the memory limit and
  the driver's last line on stderr. The kernel runner reports a dispatch stopped by
  the watchdog as the kernel's failure instead (an endless loop is the port's fault).

A job is any picklable object with ``step(done)`` (here: ``(what, seconds,
watchdog)`` of the step after heartbeat ``done``, None for the first) and
``run(drivers, beat)`` (in the child: ``drivers.open(target)`` gives the driver,
``beat(done)`` sends a heartbeat; raises :class:`~._errors.ContextError` without a
driver, :class:`~._errors.LocalCompileError` with the compiler's log).
"""

from __future__ import annotations

import atexit
import contextlib
import os
import signal
import subprocess
import sys
import tempfile
from pathlib import Path

from .._arrays import InputError, format_bytes, max_memory
from ._errors import ContextError
from ._toolchain import COMPILE_SECONDS

__all__ = ["COMPILE_SECONDS", "WATCHDOG_SECONDS", "DriverError", "DriverTimeout", "DriverDied", "CompileFailed",
           "run", "watchdog", "set_watchdog", "using_watchdog", "driver_pid", "shutdown"]

#: Seconds one dispatch may run before the driver process is stopped (``--watchdog``), for functions and kernels.
WATCHDOG_SECONDS = 10.0
_STATE = {"watchdog": WATCHDOG_SECONDS, "child": None}


class DriverError(InputError):
    """The driver process failed, died or overran a step; ``str(exc)`` says which step and why."""


class DriverTimeout(DriverError):
    """A step did not finish within its limit: ``step`` (what the driver was doing), ``seconds``, and
    ``watchdog`` (True: a dispatch, stopped by the watchdog; False: the compile)."""

    def __init__(self, step, seconds, watchdog):
        hint = ("the watchdog stopped it (a loop that never ends, or a shader the driver takes that long?; "
                "--watchdog sets the limit)" if watchdog else "the compile time limit")
        super().__init__(f"the driver did not finish {step} within {seconds:g} s: {hint}")
        self.step, self.seconds, self.watchdog = step, seconds, watchdog


class DriverDied(DriverError):
    """The driver process died (a signal, an abort, out of memory) during a job."""


class CompileFailed(Exception):
    """The driver's compiler refused the shader; ``args[0]`` is its raw log (formatted by the caller)."""


def watchdog():
    """Seconds one dispatch may run (:func:`set_watchdog`)."""
    return _STATE["watchdog"]


def set_watchdog(seconds, name="watchdog"):
    """Set the dispatch watchdog (seconds > 0) for functions and kernels; returns the previous value."""
    try:
        value = float(seconds)
    except (TypeError, ValueError):
        value = float("nan")
    if not value > 0 or value == float("inf"):
        raise InputError(f"{name}: expected a positive number of seconds, got {seconds!r}")
    old, _STATE["watchdog"] = _STATE["watchdog"], value
    return old


@contextlib.contextmanager
def using_watchdog(seconds, name="watchdog"):
    """The watchdog at ``seconds`` inside the block (None: unchanged), the previous one after it."""
    if seconds is None:
        yield
        return
    old = set_watchdog(seconds, name)
    try:
        yield
    finally:
        _STATE["watchdog"] = old


class _Child:
    """``python -m moments_ref.conformance._driverproc`` with two pipes, a log file and a process group.

    Not ``multiprocessing``'s spawn, which runs the caller's main script again in
    the child (a script without a ``__main__`` guard would start itself again).
    """

    def __init__(self):
        from multiprocessing.connection import Connection

        # The log has no name (created unlinked): a parent killed outright (SIGKILL) leaves no file behind.
        self.log = tempfile.TemporaryFile(prefix="moments-ref-driver-", suffix=".log")
        fd = os.dup(self.log.fileno())
        down_r, down_w = os.pipe()
        up_r, up_w = os.pipe()
        root = str(Path(__file__).resolve().parents[2])
        env = dict(os.environ, PYTHONPATH=os.pathsep.join([root, os.environ.get("PYTHONPATH", "")]).rstrip(os.pathsep))
        env.setdefault("XDG_RUNTIME_DIR", tempfile.gettempdir())  # silences Mesa on headless machines
        try:
            self.proc = subprocess.Popen([sys.executable, "-m", "moments_ref.conformance._driverproc", str(down_r),
                                          str(up_w)], pass_fds=(down_r, up_w), stdin=subprocess.DEVNULL, stdout=fd,
                                         stderr=fd, env=env, start_new_session=True)
        finally:
            for x in (fd, down_r, up_w):
                os.close(x)
        self.send, self.recv = Connection(down_w, readable=False), Connection(up_r, writable=False)

    def last_words(self):
        """The driver's last line on stderr (Mesa's and wgpu's chatter about the runtime dir dropped)."""
        try:
            fd = self.log.fileno()
            size = os.fstat(fd).st_size
            lines = [x.strip() for x in os.pread(fd, 4096, max(0, size - 4096)).decode("utf-8", "replace").splitlines()]
        except (OSError, ValueError):  # ValueError: the log is closed
            return ""
        lines = [x for x in lines if x and "XDG_RUNTIME_DIR" not in x]
        return lines[-1][:300] if lines else ""

    def kill(self):
        try:
            os.killpg(self.proc.pid, signal.SIGKILL)  # the group: anything the driver started goes too
        except (ProcessLookupError, PermissionError):
            pass
        self.proc.wait()
        for conn in (self.send, self.recv):
            conn.close()
        self.log.close()


def driver_pid():
    """The process id of the driver process, or None while there is none."""
    child = _STATE["child"]
    return child.proc.pid if child is not None and child.proc.poll() is None else None


def shutdown():
    """Stop the driver process (the next job starts a new one)."""
    child, _STATE["child"] = _STATE["child"], None
    if child is not None:
        child.kill()


atexit.register(shutdown)


def _child():
    child = _STATE["child"]
    if child is None or child.proc.poll() is not None:
        shutdown()
        child = _STATE["child"] = _Child()
    return child


def _died(child, step):
    try:
        code = child.proc.wait(5)
    except subprocess.TimeoutExpired:
        code = None
    try:
        how = f"signal {signal.Signals(-code).name}" if code is not None and code < 0 else f"exit {code}"
    except ValueError:
        how = f"signal {-code}"
    words = child.last_words()
    shutdown()
    return DriverDied(f"the driver process died during {step} ({how}; memory limit {format_bytes(max_memory())}, "
                      "--max-memory)" + (f": {words}" if words else ""))


def run(job):
    """Run ``job`` in the driver process; returns its answer.

    Raises :class:`DriverTimeout`, :class:`DriverDied` or :class:`DriverError` (the job
    raised), :class:`~._errors.ContextError` (no such driver) or :class:`CompileFailed`.
    """
    child = _child()
    step, limit, watched = job.step(None)
    try:
        child.send.send((max_memory(), job))
    except OSError:
        raise _died(child, step) from None
    while True:
        if not child.recv.poll(limit):
            shutdown()
            raise DriverTimeout(step, limit, watched)
        try:
            kind, value = child.recv.recv()
        except (EOFError, OSError):
            raise _died(child, step) from None
        if kind == "beat":
            step, limit, watched = job.step(value)
        elif kind == "ok":
            return value
        elif kind == "context":
            raise ContextError(value)
        elif kind == "compile":
            raise CompileFailed(value)
        else:
            raise DriverError(f"the driver failed during {step}: {value}")
