"""The driver process (:mod:`._supervisor` starts it): opens the drivers once, runs one job at a time.

Run as ``python -m moments_ref.conformance._driverproc READ_FD WRITE_FD``. Each
request is ``(memory limit, job)``; the answers are ``("beat", done)`` heartbeats
while the job runs, then ``("ok", result)``, or ``context``, ``compile`` or
``error`` with a one-line reason. Dies with its parent (Linux: a parent-death signal).

:class:`Drivers` is the one place where the drivers are set up, for functions and
kernels alike: the OpenGL 4.3 context through EGL (:func:`._gl.open_local`) and the
wgpu device of an adapter with the limits the kernels need
(:func:`._wgpu.open_local`).
"""

from __future__ import annotations

import signal
import sys

from ._errors import ContextError, LocalCompileError
from ._toolchain import limit_memory

__all__ = ["Drivers"]


class Drivers:
    """The drivers of this process, each opened on first use and kept.

    ``open(("gl",))`` is a :class:`~._gl.LocalGL`; ``open(("wgpu", backend, name))``
    a :class:`~._wgpu.LocalDevice` on the first ``backend`` adapter (``Vulkan`` or
    ``OpenGL``) whose name contains ``name``. Raises ContextError without one.
    """

    def __init__(self):
        self._open = {}

    def open(self, target):
        if target not in self._open:
            from . import _gl, _wgpu

            self._open[target] = _gl.open_local() if target[0] == "gl" else _wgpu.open_local(*target[1:])
        return self._open[target]


def _die_with_parent():
    """Linux: SIGKILL this process when its parent dies (prctl PR_SET_PDEATHSIG)."""
    try:
        import ctypes

        ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGKILL)
    except (OSError, AttributeError):
        pass  # elsewhere the closed pipe ends the loop


def _one_line(exc):
    text = " ".join(x.strip() for x in str(exc).splitlines() if x.strip())
    return f"{type(exc).__name__}: {text[:400]}" if text else type(exc).__name__


def serve(down, up):
    """The loop: read a job, run it with heartbeats, answer ``(kind, value)``; return when the parent is gone."""
    from multiprocessing.connection import Connection

    _die_with_parent()
    recv, conn = Connection(down, writable=False), Connection(up, readable=False)
    drivers = Drivers()

    def beat(done):
        conn.send(("beat", done))

    while True:
        try:
            mem, job = recv.recv()
        except (EOFError, OSError):
            return  # the parent is gone
        limit_memory(mem)
        try:
            conn.send(("ok", job.run(drivers, beat)))
        except ContextError as exc:
            conn.send(("context", str(exc)))
        except LocalCompileError as exc:
            conn.send(("compile", str(exc)))
        except MemoryError:
            conn.send(("error", "out of memory"))
        except Exception as exc:  # noqa: BLE001 - reported to the parent as one line
            conn.send(("error", _one_line(exc)))


if __name__ == "__main__":
    serve(int(sys.argv[1]), int(sys.argv[2]))
