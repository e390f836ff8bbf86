"""The camera of the shaded view (eye, target, up, vertical field of view, resolution)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._arrays import InputError
from ..raster import look_at, perspective

__all__ = ["Camera"]


@dataclass(frozen=True)
class Camera:
    """A perspective camera.

    Attributes
    ----------
    eye, target, up : (3,) float arrays
    fov : float, vertical field of view in degrees
    resolution : (width, height) in pixels
    near, far : float, clip distances
    """

    eye: np.ndarray
    target: np.ndarray
    up: np.ndarray = (0.0, 1.0, 0.0)
    fov: float = 45.0
    resolution: tuple = (1280, 720)
    near: float = 0.05
    far: float = 100.0

    def __post_init__(self):
        for name in ("eye", "target", "up"):
            v = np.asarray(getattr(self, name), dtype=np.float64).reshape(3)
            object.__setattr__(self, name, v)
        w, h = (int(x) for x in self.resolution)
        if w < 1 or h < 1:
            raise InputError(f"resolution: expected positive (width, height), got {self.resolution}")
        object.__setattr__(self, "resolution", (w, h))
        self.view_proj()  # validates eye/target/up, fov, near/far

    def view(self) -> np.ndarray:
        """World → view matrix (4, 4)."""
        return look_at(self.eye, self.target, self.up)

    def projection(self) -> np.ndarray:
        """Perspective projection (4, 4) with aspect = width / height."""
        w, h = self.resolution
        return perspective(self.fov, w / h, self.near, self.far)

    def view_proj(self) -> np.ndarray:
        """``projection @ view``."""
        return self.projection() @ self.view()
