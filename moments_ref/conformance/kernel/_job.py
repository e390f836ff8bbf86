"""What crosses to the driver process and back: a kernel job and its result (plain, picklable data)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["Bind", "Output", "Job", "Result", "POISON", "FORMATS"]

#: Poison words of the output: still there afterwards = never written.
POISON = (0xDEADBEEF, 0x0BADF00D)
#: Storage image formats: (channels, numpy dtype, wgpu format).
FORMATS = {"rgba32ui": (4, np.uint32, "rgba32uint"), "r32ui": (1, np.uint32, "r32uint"),
           "rgba32f": (4, np.float32, "rgba32float")}


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
    dispatch_seconds: float = 60.0
    compile_seconds: float = 180.0
    trace_words: int = 0  # > 0: bind a trace buffer of this many words (shared-memory trace)


@dataclass
class Result:
    """What the driver process returns."""

    output: np.ndarray | None = None  # raw words (image: (h, w, channels); buffer: (words,))
    timings: dict = field(default_factory=dict)  # compile, upload, dispatch (list), readback seconds
    renderer: str = ""
    trace: np.ndarray | None = None
    error: str | None = None  # "compile: ..." or "driver: ..."
