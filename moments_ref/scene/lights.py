"""Lights and their shadow-map views.

* :class:`DirectionalLight`: parallel light (HPG17 §5: one directional light, an
  orthographic shadow map "simply fitted to the convex hull").
* :class:`AreaLight`: a rectangle with centre, normal, width and height (VWSS §3.1,
  "a rectangular area light" with ``l_c``, ``l_n``, ``l_w``, ``l_h``); its shadow
  maps are perspective views from points on the rectangle looking along the normal.

The matrix builders live in :mod:`moments_ref.scene.raster` (OpenGL conventions, NDC
depth in [−1, 1]).

References
----------
.. [1] HPG17: Christoph Peters. 2017. *Non-Linearly Quantized Moment Shadow Maps*. In Proceedings
       of High Performance Graphics (HPG '17). ACM. The non-linear quantization Φ, Ψ4, Algorithms
       1–3, the texel formats and the compute shader of §4.1.
.. [2] VWSS: Adam Marrs, Benjamin Watson and Christopher Healey. 2018. *View-warped Multi-view Soft
       Shadowing for Local Area Lights*. Journal of Computer Graphics Techniques (JCGT) 7, 3, 1–28.
       http://jcgt.org/published/0007/03/01/
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._arrays import InputError
from .._shim import alias
from .raster import look_at, orthographic, perspective

__all__ = ["DirectionalLight", "AreaLight"]


def _unit(v, name):
    v = np.asarray(v, dtype=np.float64).reshape(3)
    n = np.linalg.norm(v)
    if not np.isfinite(n) or n == 0:
        raise InputError(f"{name}: expected a non-zero finite direction, got {v.tolist()}")
    return v / n


def _helper_up(d):
    """A world direction not parallel to d, for look_at."""
    return np.array([0.0, 0.0, 1.0]) if abs(d[1]) > 0.9 else np.array([0.0, 1.0, 0.0])


@dataclass(frozen=True)
class DirectionalLight:
    """Parallel light travelling along ``direction`` (from the light into the scene)."""

    direction: np.ndarray

    def __post_init__(self):
        object.__setattr__(self, "direction", _unit(self.direction, "direction"))

    kind = "directional"

    def clip_from_world(self, points, margin=0.01) -> np.ndarray:
        """Orthographic light view fitted to the bounding box (in light space) of ``points``.

        Parameters
        ----------
        points : (N, 3) float array
            Scene vertices (or bounding-box corners); the map covers their convex hull.
        margin : float
            Relative enlargement of the box on every side so nothing touches its faces.

        Returns
        -------
        (4, 4) float64 array, ``orthographic @ look_at``.
        """
        pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        centre = 0.5 * (pts.min(0) + pts.max(0))
        d = self.direction
        view = look_at(centre - d, centre, _helper_up(d))
        q = pts @ view[:3, :3].T + view[:3, 3]
        lo, hi = q.min(0), q.max(0)
        pad = margin * max(float((hi - lo).max()), 1e-9)
        lo, hi = lo - pad, hi + pad
        # view space looks along -z: distances are -z
        return orthographic(lo[0], hi[0], lo[1], hi[1], -hi[2], -lo[2]) @ view

    #: Old name (DeprecationWarning).
    view_proj = alias("clip_from_world")


@dataclass(frozen=True)
class AreaLight:
    """Rectangular area light (VWSS §3.1).

    Attributes
    ----------
    center : (3,) the rectangle's centre ``l_c``.
    normal : (3,) unit normal ``l_n``, the direction the light emits into.
    width, height : float, side lengths ``l_w`` (along :attr:`tangent`) and ``l_h``
        (along :attr:`bitangent`).
    up : (3,) hint for the direction of the height side (projected onto the plane).
    fov : float, vertical and horizontal field of view (degrees) of its shadow maps.
    """

    center: np.ndarray
    normal: np.ndarray
    width: float
    height: float
    up: np.ndarray = None
    fov: float = 90.0

    kind = "area"

    def __post_init__(self):
        c = np.asarray(self.center, dtype=np.float64).reshape(3)
        if not np.isfinite(c).all():
            raise InputError(f"center: expected finite coordinates, got {c.tolist()}")
        n = _unit(self.normal, "normal")
        for name in ("width", "height"):
            v = float(getattr(self, name))
            if not (np.isfinite(v) and v > 0):
                raise InputError(f"{name}: expected a positive finite size, got {v}")
            object.__setattr__(self, name, v)
        up = _helper_up(n) if self.up is None else _unit(self.up, "up")
        if np.linalg.norm(np.cross(up, n)) < 1e-9:
            raise InputError(f"up: expected a direction not parallel to normal {n.tolist()}, got {up.tolist()}")
        if not (0 < float(self.fov) < 180):
            raise InputError(f"fov: expected a field of view in (0, 180) degrees, got {self.fov}")
        object.__setattr__(self, "center", c)
        object.__setattr__(self, "normal", n)
        object.__setattr__(self, "up", up)
        object.__setattr__(self, "fov", float(self.fov))

    @property
    def bitangent(self) -> np.ndarray:
        """Unit direction of the height side: ``up`` projected onto the light's plane."""
        b = self.up - (self.up @ self.normal) * self.normal
        return b / np.linalg.norm(b)

    @property
    def tangent(self) -> np.ndarray:
        """Unit direction of the width side, ``bitangent × normal``."""
        return np.cross(self.bitangent, self.normal)

    def point(self, uv) -> np.ndarray:
        """Points on the rectangle for ``uv`` (..., 2) in [0, 1]² (0.5, 0.5 = centre)."""
        uv = np.asarray(uv, dtype=np.float64)
        return (self.center + (uv[..., :1] - 0.5) * self.width * self.tangent
                + (uv[..., 1:2] - 0.5) * self.height * self.bitangent)

    def corners(self) -> np.ndarray:
        """(4, 3) corners, counter-clockwise seen from the lit side."""
        return self.point(np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float))

    def clip_from_world(self, points, eye=None) -> np.ndarray:
        """Perspective view from ``eye`` (default: the centre) looking along the normal.

        The field of view is :attr:`fov` in both directions; near and far planes
        enclose ``points`` in front of the light (near at least 1e-3 · far).
        """
        eye = self.center if eye is None else np.asarray(eye, dtype=np.float64).reshape(3)
        view = look_at(eye, eye + self.normal, self.bitangent)
        pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        dist = -(pts @ view[2, :3] + view[2, 3])
        far = float(dist.max()) * 1.01 if dist.size and dist.max() > 0 else 1.0
        near = max(float(dist[dist > 0].min()) * 0.99 if (dist > 0).any() else 0.0, 1e-3 * far)
        return perspective(self.fov, 1.0, near, far) @ view

    #: Old name (DeprecationWarning).
    view_proj = alias("clip_from_world")
