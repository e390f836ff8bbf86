"""The camera of the shaded view (eye, target, up, vertical field of view, resolution)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._arrays import InputError, check_memory
from .._shim import alias
from .raster import look_at, perspective

__all__ = ["Camera", "BYTES_PER_PIXEL"]

#: Memory estimate of shading one camera pixel (G-buffer, light-space positions,
#: per-technique intensities and references): the report's pipeline measured
#: about 120 B per pixel; twice that is checked against the memory limit
#: (:func:`moments_ref._arrays.max_memory`) when a camera is made.
BYTES_PER_PIXEL = 256


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
            try:
                v = np.asarray(getattr(self, name), dtype=np.float64).reshape(3)
            except (TypeError, ValueError):
                raise InputError(f"{name}: expected 3 numbers, got {getattr(self, name)!r}") from None
            object.__setattr__(self, name, v)
        try:
            w, h = (int(x) for x in self.resolution)
        except (TypeError, ValueError, OverflowError):
            raise InputError(f"resolution: expected (width, height) integers, got {self.resolution!r}") from None
        if w < 1 or h < 1:
            raise InputError(f"resolution: expected positive (width, height), got {self.resolution}")
        object.__setattr__(self, "resolution", (w, h))
        check_memory(BYTES_PER_PIXEL * w * h, f"camera resolution {w}×{h}")
        self.clip_from_world()  # validates eye/target/up, fov, near/far

    def sees(self, mesh) -> bool:
        """Whether some triangle of ``mesh`` may be in view (conservative frustum test).

        A triangle is out of view when its three vertices lie outside one of the
        clip planes ``x = ±w``, ``y = ±w``, ``z = ±w`` (OpenGL clip space).
        """
        if mesh.n_triangles == 0:
            return False
        v = mesh.vertices @ self.clip_from_world()[:, :3].T + self.clip_from_world()[:, 3]
        x, y, z, w = v.T
        outside = np.stack([x < -w, x > w, y < -w, y > w, z < -w, z > w], axis=-1)
        return not outside[mesh.triangles].all(axis=1).any(axis=-1).all()

    def check_sees(self, mesh, what="the receivers") -> None:
        """Refuse (:class:`InputError`) a camera that sees no triangle of ``mesh``."""
        if not self.sees(mesh):
            raise InputError(f"camera: sees none of {what} (eye {self.eye.tolist()}, target "
                             f"{self.target.tolist()}, fov {self.fov}): nothing to shade")

    def view(self) -> np.ndarray:
        """World → view matrix (4, 4)."""
        return look_at(self.eye, self.target, self.up)

    def projection(self) -> np.ndarray:
        """Perspective projection (4, 4) with aspect = width / height."""
        w, h = self.resolution
        return perspective(self.fov, w / h, self.near, self.far)

    def resized(self, resolution) -> "Camera":
        """The same camera rendering ``resolution`` = (width, height) pixels (its aspect follows)."""
        return Camera(self.eye, self.target, self.up, self.fov, tuple(resolution), self.near, self.far)

    def clip_from_world(self) -> np.ndarray:
        """``projection @ view``: world to clip coordinates of the camera."""
        return self.projection() @ self.view()

    #: Old name (DeprecationWarning).
    view_proj = alias("clip_from_world")
