"""VWSS point generation: the enlarged source view and its fragments (VWSS §3.1).

The occluders are rasterized once from a *source view* that contains every light
sample's frustum, without a depth test, and every (front-facing) fragment becomes
a point: a layered depth image (VWSS §3.1, Figures 4 and 5, right). The points
are then warped into every light-sample view (:mod:`.warp`).

Source view (VWSS Eqs. (1)–(3), Listing 1). The eye starts at the light centre
``l_c`` and moves back along ``−l̂n`` by

    d = max(l_w, l_h) / (2 tan(max(fov_v, fov_h) / 2))            (Eq. 1)
    v_e = l_c − d l̂n                                               (Eq. 2)

so that at distance ``d`` (the light's plane) its frustum is exactly as wide as
the light's longer side. Its near plane lies in the light's plane (near = d) and
its resolution grows per side from the light samples' ``m`` to

    m (z_n + d) / z_n,   rounded up to an integer                  (Eq. 3)

where ``z_n`` is the near distance of the light-sample views (Listing 1's
``light.nearZ``): there the source view then has the texel density of a sample
view. Eq. (3) is printed squared because it counts texels; we round the side up
(ceil) so the density never falls below the samples'.

References
----------
.. [1] VWSS: Adam Marrs, Benjamin Watson and Christopher Healey. 2018. *View-warped Multi-view Soft
       Shadowing for Local Area Lights*. Journal of Computer Graphics Techniques (JCGT) 7, 3, 1–28.
       http://jcgt.org/published/0007/03/01/
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..._arrays import InputError
from ..._shim import alias
from ...scene.raster import RasterStats, look_at, perspective, rasterize_fragments
from .lights import LightSamples, check_fov, check_light

__all__ = ["enlarged_view", "SourceView", "source_view", "center_view", "PointCloud",
           "generate_points", "naive_points"]


def _positive(x, name):
    try:
        v = float(x)
    except (TypeError, ValueError):
        raise InputError(f"{name}: expected a positive finite number, got {x!r}") from None
    if not (np.isfinite(v) and v > 0):
        raise InputError(f"{name}: expected a positive finite number, got {v!r}")
    return v


def _side(x, name):
    try:
        k = int(x)
        ok = k == x and k >= 1
    except (TypeError, ValueError):
        ok = False
    if not ok:
        raise InputError(f"{name}: expected a positive integer side, got {x!r}")
    return k


def enlarged_view(width, height, fov_v, fov_h, near, base_resolution):
    """Distance and resolution of the source view that contains all light samples.

    Parameters
    ----------
    width, height : float
        Light sides ``l_w``, ``l_h`` (positive).
    fov_v, fov_h : float
        Vertical and horizontal fields of view of the light-sample views, radians in (0, π).
    near : float
        Near distance ``z_n`` of the light-sample views (positive).
    base_resolution : int or (H, W)
        Light-sample depth-map resolution ``m`` per side.

    Returns
    -------
    distance : float
        ``d = max(l_w, l_h) / (2 tan(max(fov_v, fov_h) / 2))`` (VWSS Eq. (1)).
    resolution : int or (H, W) tuple of int
        ``ceil(m (z_n + d) / z_n)`` per side (VWSS Eq. (3), rounded up); the same
        form as ``base_resolution``.

    Notes
    -----
    The ceiling ignores a relative excess of 1e-12 so that products that are
    integers in exact arithmetic (``z_n = d`` gives exactly ``2m``) do not round
    up by a floating-point error.

    Examples
    --------
    >>> enlarged_view(1.0, 0.5, np.pi / 2, np.pi / 2, 0.5, 1024)
    (0.5000000000000001, 2048)
    """
    w, h = _positive(width, "width"), _positive(height, "height")
    fv, fh = check_fov(fov_v, "fov_v"), check_fov(fov_h, "fov_h")
    zn = _positive(near, "near")
    d = max(w, h) / (2.0 * math.tan(max(fv, fh) / 2.0))  # Eq. (1)
    scale = (zn + d) / zn  # Eq. (3), per side

    def up(m):
        x = m * scale
        return int(math.ceil(x * (1 - 1e-12)))

    if np.ndim(base_resolution) == 0:
        return d, up(_side(base_resolution, "base_resolution"))
    hw = tuple(base_resolution)
    if len(hw) != 2:
        raise InputError(f"base_resolution: expected an int or (H, W), got {base_resolution!r}")
    return d, (up(_side(hw[0], "base_resolution[0]")), up(_side(hw[1], "base_resolution[1]")))


@dataclass(frozen=True)
class SourceView:
    """The view occluders are rasterized from to generate points.

    Attributes
    ----------
    eye : (3,) float64
    clip_from_world : (4, 4) float64
    distance : float, how far the eye sits behind the light's plane (Eq. (1); 0 for the centre view)
    resolution : int, map side
    near, far : float, near and far distances from the eye
    fov : float, radians
    """

    eye: np.ndarray
    clip_from_world: np.ndarray
    distance: float
    resolution: int
    near: float
    far: float
    fov: float

    #: Old name (DeprecationWarning).
    view_proj = alias("clip_from_world")


def source_view(samples: LightSamples, base_resolution) -> SourceView:
    """The enlarged source view of VWSS §3.1 (Eqs. (1)–(3)) for a set of light samples.

    Parameters
    ----------
    samples : LightSamples
        The light-sample views (their fov, ``near`` = ``z_n`` and ``far``).
    base_resolution : int
        Side ``m`` of the light-sample depth maps.

    Returns
    -------
    SourceView
        Eye ``l_c − d l̂n``, same orientation and fov as the samples, near plane in
        the light's plane (near = ``d``), far plane ``d + far``, side
        ``ceil(m (z_n + d) / z_n)``.
    """
    light = check_light(samples.light)
    d, res = enlarged_view(light.width, light.height, samples.fov, samples.fov, samples.near, base_resolution)
    eye = light.center - d * light.normal  # Eq. (2)
    view = look_at(eye, eye + light.normal, light.bitangent)
    proj = perspective(np.degrees(samples.fov), 1.0, d, d + samples.far)
    return SourceView(eye=eye, clip_from_world=proj @ view, distance=d, resolution=res,
                      near=d, far=d + samples.far, fov=samples.fov)


def center_view(samples: LightSamples, base_resolution) -> SourceView:
    """The plain image-warping source: the light-centre view at the samples' resolution.

    VWSS Figure 5, left: the source is one of the target views, so the warped
    maps miss data at disocclusions *and* beyond the source's field of view.
    """
    light = check_light(samples.light)
    m = _side(base_resolution, "base_resolution")
    return SourceView(eye=light.center.copy(), clip_from_world=samples.center_clip_from_world(), distance=0.0,
                      resolution=m, near=samples.near, far=samples.far, fov=samples.fov)


@dataclass(frozen=True)
class PointCloud:
    """Points generated from occluder triangles.

    Attributes
    ----------
    positions : (N, 3) float32 (or float64) world positions
    source : SourceView
    layered : bool, every fragment (True) or the nearest per texel (False)
    cull : str, the face culling used
    triangles : int, input triangle count
    stats : RasterStats of the source rasterization
    """

    positions: np.ndarray
    source: SourceView
    layered: bool
    cull: str
    triangles: int
    stats: RasterStats

    def __len__(self) -> int:
        return int(self.positions.shape[0])


def _cull(cull_back_faces):
    if cull_back_faces not in (True, False):
        raise InputError(f"cull_back_faces: expected True or False, got {cull_back_faces!r}")
    return "back" if cull_back_faces else "none"


def generate_points(vertices, triangles, source: SourceView, cull_back_faces=True, dtype=np.float32) -> PointCloud:
    """Every fragment of the occluders seen from the source view, as points (VWSS §3.1).

    Parameters
    ----------
    vertices : (V, 3) float array
    triangles : (T, 3) int array
    source : SourceView
        Usually :func:`source_view`.
    cull_back_faces : bool
        True (default, the paper's choice): only front-facing fragments. False also
        keeps back faces, roughly doubling the points (§3.1: "we find the
        improvement ... not worth the additional cost").
    dtype : float32 or float64
        Storage of the positions; float32 as the paper ("three 32-bit
        floating-point values").

    Returns
    -------
    PointCloud
        ``layered=True``; positions are the perspective-correct interpolated world
        positions of every covered texel centre, without z-buffering (the
        rasterizer's all-fragments mode, :func:`moments_ref.scene.raster.rasterize_fragments`).
    """
    cull = _cull(cull_back_faces)
    frags, stats = rasterize_fragments(vertices, triangles, source.clip_from_world, source.resolution,
                                       samples=1, cull=cull, dtype=dtype)
    return PointCloud(positions=frags.position, source=source, layered=True, cull=cull,
                      triangles=stats.triangles, stats=stats)


def naive_points(vertices, triangles, source: SourceView, cull_back_faces=True, dtype=np.float32) -> PointCloud:
    """Only the nearest fragment per source texel: plain image warping (VWSS Figure 4, left).

    Parameters and returns as :func:`generate_points`, with ``layered=False``: the
    points are exactly the surfaces a z-buffered source depth map would keep
    (ties between equal depths go to the lowest triangle index).
    """
    cull = _cull(cull_back_faces)
    frags, stats = rasterize_fragments(vertices, triangles, source.clip_from_world, source.resolution,
                                       samples=1, cull=cull, dtype=dtype)
    if len(frags):
        # Sort by (texel, depth, triangle); the first fragment of each texel is the nearest.
        order = np.lexsort((frags.triangle, frags.depth, frags.texel))
        tex = frags.texel[order]
        first = np.flatnonzero(np.r_[True, tex[1:] != tex[:-1]])
        pos = frags.position[order[first]]
    else:
        pos = frags.position
    return PointCloud(positions=pos, source=source, layered=False, cull=cull,
                      triangles=stats.triangles, stats=stats)
