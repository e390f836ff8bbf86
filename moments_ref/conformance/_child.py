"""The drivers run in a child process, under a memory limit and a watchdog.

A driver's compiler and its dispatch run inside the process that calls them: a
macro that expands without bound, a local array of 2^26 floats (Mesa aborts with
``std::bad_alloc``) or a loop that never ends would take the harness down with
them, or hang it (a GPU driver does not stop a loop). So the OpenGL context and
the wgpu devices live in one child process (started on first use with
``python -m``, then reused), whose data segment is limited to
``max_memory()`` (``--max-memory``, 4 GiB by default) and whose stderr goes to a
file. Each request is watched: compiling may take :data:`COMPILE_SECONDS`, each
dispatch :data:`WATCHDOG_SECONDS` (``--watchdog``). A child that dies or overruns
is killed and replaced on the next request, and the request ends as a
:class:`DriverError` (an :class:`~moments_ref.InputError`: exit 2, one line) that
says what the driver was doing, the signal, and the driver's last line on stderr.

The backend functions (:func:`._gl.dispatch`, :func:`._wgpu.dispatch`) are
general: they bind any list of storage buffers (:class:`Binding`), dispatch a
given grid and read back the writable ones; :func:`dispatch` runs them here.
"""

from __future__ import annotations

import atexit
import os
import signal
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

from .._arrays import InputError, format_bytes, max_memory
from ._errors import ContextError
from ._toolchain import COMPILE_SECONDS

__all__ = ["WATCHDOG_SECONDS", "Binding", "DriverError", "CompileFailed", "open_target", "dispatch", "set_watchdog", "shutdown"]

#: Seconds one dispatch may run before the driver process is killed (``--watchdog``).
WATCHDOG_SECONDS = 10.0
_STATE = {"watchdog": WATCHDOG_SECONDS, "worker": None}


class DriverError(InputError):
    """The driver died, ran out of memory or overran the watchdog; ``str(exc)`` says which."""


@dataclass(frozen=True)
class Binding:
    """One storage buffer: ``binding`` index, initial bytes (or None: ``size`` zero bytes), and
    ``mode`` ``"read"`` (read-only in the shader) or ``"write"`` (read back after the dispatch);
    or a 2-D texture (``mode`` ``"texture"``, ``texture`` = (width, height, WebGPU format name),
    ``data`` its texels)."""

    binding: int
    data: bytes | None
    size: int
    mode: str = "read"
    texture: tuple | None = None

    @property
    def kind(self):
        """``read``, ``write`` or ``texture:FORMAT`` (what a pipeline layout needs to know)."""
        return f"texture:{self.texture[2]}" if self.mode == "texture" else self.mode


def set_watchdog(seconds):
    """Set the dispatch watchdog (seconds > 0); returns the previous value."""
    seconds = float(seconds)
    if not seconds > 0:
        raise InputError(f"watchdog: expected seconds > 0, got {seconds}")
    old, _STATE["watchdog"] = _STATE["watchdog"], seconds
    return old


class _Worker:
    """The driver process: ``python -m moments_ref.conformance._driverproc`` with two pipes.

    Not ``multiprocessing``'s spawn, which runs the caller's main script again in
    the child (a script without a ``__main__`` guard would start itself again).
    """

    def __init__(self):
        from multiprocessing.connection import Connection

        fd, self.log = tempfile.mkstemp(prefix="moments-ref-driver-", suffix=".log")
        down_r, down_w = os.pipe()
        up_r, up_w = os.pipe()
        root = str(Path(__file__).resolve().parents[2])
        env = dict(os.environ, PYTHONPATH=os.pathsep.join([root, os.environ.get("PYTHONPATH", "")]).rstrip(os.pathsep))
        env.setdefault("XDG_RUNTIME_DIR", tempfile.gettempdir())  # silences Mesa on headless machines
        self.proc = subprocess.Popen([sys.executable, "-m", "moments_ref.conformance._driverproc", str(down_r),
                                      str(up_w)],
                                     pass_fds=(down_r, up_w), stdin=subprocess.DEVNULL, stdout=fd, stderr=fd,
                                     env=env, start_new_session=False)
        for x in (fd, down_r, up_w):
            os.close(x)
        self.send, self.recv = Connection(down_w, readable=False), Connection(up_r, writable=False)

    def last_words(self):
        try:
            with open(self.log, "rb") as fh:
                fh.seek(max(0, os.path.getsize(self.log) - 4096))
                lines = [x.strip() for x in fh.read().decode("utf-8", "replace").splitlines()]
        except OSError:
            return ""
        lines = [x for x in lines if x and "XDG_RUNTIME_DIR" not in x]
        return lines[-1] if lines else ""

    def alive(self):
        return self.proc.poll() is None

    def kill(self):
        if self.alive():
            self.proc.kill()
        self.proc.wait(5)
        self.send.close()
        self.recv.close()
        try:
            os.unlink(self.log)
        except OSError:
            pass


def shutdown():
    """Stop the driver process (a later request starts a new one)."""
    w, _STATE["worker"] = _STATE["worker"], None
    if w is not None:
        w.kill()


atexit.register(shutdown)


def _worker():
    w = _STATE["worker"]
    if w is None or not w.alive():
        if w is not None:
            w.kill()
        w = _STATE["worker"] = _Worker()
    return w


def _died(w, doing):
    try:
        code = w.proc.wait(5)
    except subprocess.TimeoutExpired:
        code = None
    try:
        how = f"signal {signal.Signals(-code).name}" if code is not None and code < 0 else f"exit {code}"
    except ValueError:
        how = f"signal {-code}"
    words = w.last_words()
    shutdown()
    return DriverError(f"the driver process died while {doing} ({how}; memory limit {format_bytes(max_memory())}, "
                       f"--max-memory)" + (f": {words}" if words else ""))


def _request(message, doing, first_limit):
    """Send ``message`` to the worker; returns its answer, raising what the worker raised."""
    w = _worker()
    try:
        w.send.send((max_memory(), message))
    except OSError:
        raise _died(w, doing) from None
    limit = first_limit
    while True:
        if not w.recv.poll(limit):
            shutdown()
            what = "the watchdog" if doing == "dispatching" else "the compile time limit"
            hint = (" (a loop that never ends, or a shader the driver takes that long to build?); raise it with "
                    "--watchdog") if doing == "dispatching" else ""
            raise DriverError(f"the driver did not finish {doing} within {limit:g} s, {what}{hint}")
        try:
            kind, value = w.recv.recv()
        except (EOFError, OSError):
            raise _died(w, doing) from None
        if kind == "compiled":
            doing, limit = "dispatching", _STATE["watchdog"]
            continue
        if kind == "ok":
            return value
        if kind == "context":
            raise ContextError(value)
        if kind == "compile":
            raise CompileFailed(value)
        raise DriverError(f"the driver failed while {doing}: {value}")


class CompileFailed(Exception):
    """The driver's compiler refused the shader; ``args[0]`` is its raw log (formatted by the caller)."""


def open_target(target):
    """``(renderer, version_code, takes SPIR-V)`` of ``target`` (``("gl",)`` or ``("wgpu", backend, name)``) in the child.

    Raises :class:`~._gl.ContextError` when there is no such driver.
    """
    return _request(("open", target), "starting the driver", COMPILE_SECONDS)


def dispatch(target, code, bindings, groups, entry="main", group=0, on_compile_error=None):
    """Compile ``code`` (GLSL text for ``("gl",)``; WGSL text or SPIR-V bytes for wgpu) and dispatch it.

    Parameters
    ----------
    target : tuple
        ``("gl",)`` or ``("wgpu", backend, adapter name or None)``.
    bindings : list of Binding
    groups : (gx, gy, gz)
    entry, group : wgpu only: entry point, and the bind group of the bindings.
    on_compile_error : callable(raw log) -> Exception, optional

    Returns
    -------
    (dict binding -> bytes of the "write" buffers, timings dict)
    """
    try:
        return _request(("dispatch", target, code, list(bindings), tuple(groups), entry, group), "compiling",
                        COMPILE_SECONDS)
    except CompileFailed as exc:
        if on_compile_error is None:
            raise DriverError(f"the shader does not compile: {exc.args[0]}") from None
        raise on_compile_error(exc.args[0]) from None
