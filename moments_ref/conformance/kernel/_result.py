"""What the driver process returns for a kernel job (:mod:`._job`), and the storage image formats it makes."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["Result", "FORMATS"]

#: Storage image formats: (channels, numpy dtype, wgpu format).
FORMATS = {"rgba32ui": (4, np.uint32, "rgba32uint"), "r32ui": (1, np.uint32, "r32uint"),
           "rgba32f": (4, np.float32, "rgba32float")}


@dataclass
class Result:
    """What the driver process returns."""

    output: np.ndarray | None = None  # raw words (image: (h, w, channels); buffer: (words,))
    timings: dict = field(default_factory=dict)  # compile, upload, dispatch (list), readback seconds
    renderer: str = ""
    trace: np.ndarray | None = None
