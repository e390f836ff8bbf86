"""The driver process (:mod:`._child` starts it): OpenGL context and wgpu devices, one request at a time.

Run as ``python -m moments_ref.conformance._driverproc READ_FD WRITE_FD``; answers
each request ``(memory limit, message)`` with ``(kind, value)``: ``compiled`` once
the shader is built, then ``ok`` and the result, or ``context``, ``compile`` or
``error`` and a one-line reason. Dies with its parent (Linux: a parent-death signal).
"""

from __future__ import annotations

import signal
import sys

from ._child import CompileFailed
from ._errors import ContextError, LocalCompileError
from ._toolchain import limit_memory

__all__ = []


def _die_with_parent():
    """Linux: SIGKILL this process when its parent dies (prctl PR_SET_PDEATHSIG)."""
    try:
        import ctypes

        ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGKILL)
    except (OSError, AttributeError):
        pass  # elsewhere the closed pipe ends the loop


def _serve(down, up):
    """The worker's loop: one request at a time, answers ``(kind, value)``."""
    from multiprocessing.connection import Connection

    from . import _gl, _wgpu

    _die_with_parent()
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the parent handles Ctrl-C and kills us
    recv, conn = Connection(down, writable=False), Connection(up, readable=False)

    targets = {}
    while True:
        try:
            mem, message = recv.recv()
        except (EOFError, OSError):
            return  # the parent is gone
        limit_memory(mem)
        try:
            conn.send(("ok", _handle(message, targets, conn, _gl, _wgpu)))
        except ContextError as exc:
            conn.send(("context", str(exc)))
        except CompileFailed as exc:
            conn.send(("compile", exc.args[0]))
        except MemoryError:
            conn.send(("error", "out of memory"))
        except Exception as exc:  # noqa: BLE001 - reported to the parent as one line
            text = " ".join(x.strip() for x in str(exc).splitlines() if x.strip())
            conn.send(("error", f"{type(exc).__name__}: {text[:400]}"))


def _handle(message, targets, conn, _gl, _wgpu):
    kind, target = message[0], message[1]
    if target not in targets:
        targets[target] = _gl.open_local() if target[0] == "gl" else _wgpu.open_local(*target[1:])
    driver = targets[target]
    if kind == "open":
        return driver.renderer, driver.version_code, getattr(driver, "spirv", False)
    code, bindings, groups, entry, group = message[2:]
    try:
        compiled = driver.compile(code, entry, group, [(b.binding, b.kind) for b in sorted(bindings, key=lambda b: b.binding)])
    except LocalCompileError as exc:
        raise CompileFailed(str(exc)) from None
    conn.send(("compiled", None))
    return driver.dispatch(compiled, bindings, groups, group)


if __name__ == "__main__":
    _serve(int(sys.argv[1]), int(sys.argv[2]))
