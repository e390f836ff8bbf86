"""The driver process and its watchdog: kernels run in a child process that can be killed.

A kernel can hang the driver (an infinite loop runs forever on llvmpipe and
lavapipe; there is no GPU reset) or crash it, and neither may take the harness
down. :func:`run_job` sends a job to a long-lived child process
(``python -m moments_ref.conformance.kernel._worker``, one per process of the
harness, reused across jobs so that drivers start once) and waits for its
heartbeats: one after the compile, one after each dispatch. A step that does not
report within its time limit (``compile_seconds``, ``dispatch_seconds``) is a
:class:`KernelTimeout`: the child's process group is killed and the next job
starts a fresh one. A child that dies is a :class:`DriverCrash` with the last
lines it printed.

Messages are pickled frames (8-byte length, then the pickle) on two pipes of
their own; the child's stdout and stderr (driver chatter) go to a log file.
"""

from __future__ import annotations

import atexit
import os
import pickle
import select
import signal
import struct
import subprocess
import sys
import tempfile
from pathlib import Path

__all__ = ["KernelTimeout", "DriverCrash", "run_job", "shutdown", "main"]


class KernelTimeout(RuntimeError):
    """A step of a kernel job exceeded its time limit; ``stage`` says which."""

    def __init__(self, stage, seconds):
        super().__init__(f"{stage} did not finish within {seconds:g} s")
        self.stage, self.seconds = stage, seconds


class DriverCrash(RuntimeError):
    """The driver process died while running a job."""


def _send(fd, obj):
    data = pickle.dumps(obj, protocol=pickle.HIGHEST_PROTOCOL)
    view = memoryview(struct.pack("<Q", len(data)) + data)
    while view:
        view = view[os.write(fd, view):]


def _read_exact(fd, n):
    chunks, left = [], n
    while left:
        b = os.read(fd, min(left, 1 << 20))
        if not b:
            raise EOFError
        chunks.append(b)
        left -= len(b)
    return b"".join(chunks)


def _recv(fd, timeout=None):
    if timeout is not None and not select.select([fd], [], [], max(timeout, 0))[0]:
        return _TIMEOUT
    (n,) = struct.unpack("<Q", _read_exact(fd, 8))
    return pickle.loads(_read_exact(fd, n))


_TIMEOUT = object()


class _Child:
    def __init__(self):
        to_child, self._w = os.pipe()
        self._r, from_child = os.pipe()
        self.log = tempfile.NamedTemporaryFile(prefix="moments-ref-driver-", suffix=".log", delete=False)
        env = dict(os.environ)
        root = str(Path(__file__).resolve().parents[3])
        env["PYTHONPATH"] = root + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
        env.setdefault("XDG_RUNTIME_DIR", "/tmp")
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "moments_ref.conformance.kernel._worker", str(to_child), str(from_child)],
            pass_fds=(to_child, from_child), stdin=subprocess.DEVNULL, stdout=self.log, stderr=self.log,
            start_new_session=True, env=env)
        os.close(to_child)
        os.close(from_child)

    def kill(self):
        try:
            os.killpg(self.proc.pid, signal.SIGKILL)
        except (ProcessLookupError, PermissionError):
            pass
        self.proc.wait()
        for fd in (self._w, self._r):
            try:
                os.close(fd)
            except OSError:
                pass
        self.log.close()
        try:
            os.unlink(self.log.name)
        except OSError:
            pass

    def tail(self):
        self.log.flush()
        try:
            lines = Path(self.log.name).read_text(errors="replace").strip().splitlines()
        except OSError:
            return ""
        return " | ".join(x.strip() for x in lines[-3:])


_CHILD = {}


def shutdown():
    """Stop the driver process (at exit, or to start the next job afresh)."""
    child = _CHILD.pop("child", None)
    if child is not None:
        child.kill()


atexit.register(shutdown)


def run_job(job):
    """Run a :class:`~._job.Job` in the driver process; raises KernelTimeout or DriverCrash."""
    child = _CHILD.get("child")
    if child is None or child.proc.poll() is not None:
        shutdown()
        child = _CHILD["child"] = _Child()
    try:
        _send(child._w, job)
    except OSError:
        shutdown()
        raise DriverCrash("the driver process could not take the job") from None
    limit, stage = job.compile_seconds, "the compile"
    while True:
        try:
            msg = _recv(child._r, limit)
        except EOFError:
            tail, code = child.tail(), child.proc.wait()
            shutdown()
            raise DriverCrash(f"the driver process died (exit status {code}) during {stage}"
                              + (f"; its last output: {tail}" if tail else "")) from None
        if msg is _TIMEOUT:
            shutdown()
            raise KernelTimeout(stage, limit)
        kind, value = msg
        if kind == "done":
            return value
        limit, stage = _next_stage(value, job)


def _next_stage(done, job):
    """Time limit and name of the step after the one just reported (dispatches counted from 1)."""
    if done == "compiled":  # the warm-up dispatch also carries the driver's own compile
        return job.compile_seconds + job.dispatch_seconds, "the first dispatch (warm-up, with the driver's compile)"
    n = len(job.dispatches)
    k = 0 if done == "warm-up" else int(done.split()[1]) + 1
    return job.dispatch_seconds, (f"dispatch {k + 1} of {n}" if k < n else "the readback")


def main(argv=None):
    """The driver process: read jobs, run them, send heartbeats and results."""
    argv = sys.argv[1:] if argv is None else argv
    rfd, wfd = int(argv[0]), int(argv[1])
    from . import _exec_gl, _exec_wgpu
    from ._job import Result

    while True:
        try:
            job = _recv(rfd)
        except EOFError:
            return 0
        try:
            run = _exec_gl.run if job.backend == "moderngl" else _exec_wgpu.run
            result = run(job, lambda stage: _send(wfd, ("progress", stage)))
        except Exception as exc:  # a driver failure is the job's result, reported as such
            result = Result(error=f"driver: {type(exc).__name__}: {exc}")
        _send(wfd, ("done", result))


if __name__ == "__main__":
    sys.exit(main())
