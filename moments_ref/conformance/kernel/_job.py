"""A kernel run as a job of the driver process (:mod:`.._supervisor`): what crosses to it, picklable data.

The job's steps, each under its own time limit: the compile, the warm-up dispatch
(which carries the driver's own compile: llvmpipe and lavapipe build the kernel at
its first dispatch), each timed dispatch, the readback. What comes back: :mod:`._result`.
"""

from __future__ import annotations

from dataclasses import dataclass

from .._supervisor import COMPILE_SECONDS, WATCHDOG_SECONDS

__all__ = ["Bind", "Output", "Job", "POISON"]

#: Poison words of the output: still there afterwards = never written.
POISON = (0xDEADBEEF, 0x0BADF00D)


@dataclass(frozen=True)
class Bind:
    """One resource of the kernel and what the harness puts there."""

    slot: str
    role: str  # input, output, params
    kind: str  # texture_ms, buffer, storage_image, uniform
    set: int
    binding: int
    name: str  # the kernel's name (GL: the uniform or block to point at the binding)
    access: str = "read"
    depth: bool = False
    format: str | None = None


@dataclass
class Output:
    """The output resource: a storage image (height, width, channels) or a buffer of words, pre-filled."""

    kind: str  # storage_image or buffer
    format: str | None  # image format, or the buffer word type
    shape: tuple  # image: (height, width, channels) with padding; buffer: (words,)
    fill: int  # word written everywhere before the dispatches


@dataclass
class Job:
    """One kernel run: compile, upload, dispatch each entry of ``dispatches``, read the output back."""

    backend: str  # moderngl or wgpu
    driver: str  # gl or vulkan (wgpu: which adapter kind)
    adapter: str | None  # wgpu adapter name filter
    code: object  # GLSL text (moderngl), WGSL text or SPIR-V bytes (wgpu)
    entry: str
    binds: list
    data: np.ndarray  # input: window depths (H, W, S) float32, or points (N, 4) float32
    output: Output
    dispatches: list  # [(groups (x, y, z), params bytes)]
    dispatch_seconds: float = WATCHDOG_SECONDS
    trace_words: int = 0  # > 0: bind a trace buffer of this many words (shared-memory trace)

    @property
    def target(self):
        """The driver the job runs on (:class:`~.._driverproc.Drivers`)."""
        if self.backend == "moderngl":
            return ("gl",)
        return ("wgpu", "OpenGL" if self.driver == "gl" else "Vulkan", self.adapter)

    def step(self, done):
        """``(what, seconds, watchdog)`` of the step after heartbeat ``done`` (None: the first)."""
        if done is None:
            return "the compile", COMPILE_SECONDS, False
        if done == "compiled":
            return ("the first dispatch (warm-up, with the driver's compile)", COMPILE_SECONDS + self.dispatch_seconds,
                    True)
        n = len(self.dispatches)
        k = 0 if done == "warm-up" else int(done.split()[1]) + 1
        return (f"dispatch {k + 1} of {n}" if k < n else "the readback"), self.dispatch_seconds, True

    def run(self, drivers, beat):
        """In the driver process: run on the job's driver, ``beat`` after the compile and each dispatch."""
        from . import _exec_gl, _exec_wgpu

        execute = _exec_gl.run if self.backend == "moderngl" else _exec_wgpu.run
        return execute(drivers.open(self.target), self, beat)
