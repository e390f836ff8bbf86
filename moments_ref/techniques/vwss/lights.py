"""Light samples on a rectangular area light and their perspective views (VWSS §2.1, §4).

VWSS §4: "MVR and VWSS use identical area light-sample positions with Poisson
distribution." A light sample is a point on the rectangle; its depth map is a
perspective view from that point looking along the light normal ``l̂n``. All
samples share one field of view, one orientation and one near/far pair, so the
views differ only by a translation in the light's plane (VWSS Figure 5).

Near plane. Every light-sample view and PCSS's light-centre view share the
light's own near plane ``z_n`` (VWSS Listing 1, ``light.nearZ``): a distance in
front of the light's plane, a property of the light like its size. It is a scene
parameter, ``params.light_near`` (:data:`LIGHT_NEAR_PARAM`, world units), read by
:func:`light_near`. It enters VWSS Eq. (3) (the enlarged source view is
``(z_n + d) / z_n`` times the samples' resolution per side, :mod:`.points`) and
PCSS's map, whose blocker search covers the light's projection on the plane of
the nearest depth in the map, never nearer than ``z_n``
(:func:`moments_ref.techniques.vwss.shading.pcss`), so both methods see the same value. A
scene without ``light_near`` gets the older rule of :func:`depth_range`: just in
front of the nearest occluder (the largest near plane that clips nothing, and
then the smallest source view), and reports say which rule was used. The
enlarged source view of :mod:`.points`, whose eye lies behind the light, puts its
near plane exactly in the light's plane (VWSS §3.1).

Angles are in radians in this package (``fov`` in (0, π));
:class:`moments_ref.scene.AreaLight` stores degrees.

References
----------
.. [1] VWSS: Adam Marrs, Benjamin Watson and Christopher Healey. 2018. *View-warped Multi-view Soft
       Shadowing for Local Area Lights*. Journal of Computer Graphics Techniques (JCGT) 7, 3, 1–28.
       http://jcgt.org/published/0007/03/01/
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..._arrays import InputError, real_input
from ..._shim import alias
from ...scene.raster import look_at, perspective

__all__ = ["poisson_disk", "LightSamples", "check_fov", "check_light", "check_views", "check_resolution", "depth_range",
           "light_views", "LIGHT_NEAR_PARAM", "light_near"]

#: Scene parameter holding the light's near plane z_n (Listing 1's ``light.nearZ``).
LIGHT_NEAR_PARAM = "light_near"


def check_fov(fov, name="fov") -> float:
    """A field of view in radians, strictly inside (0, π), or :class:`InputError`."""
    try:
        f = float(fov)
    except (TypeError, ValueError):
        raise InputError(f"{name}: expected a field of view in radians in (0, pi), got {fov!r}") from None
    if not (0.0 < f < np.pi):
        raise InputError(f"{name}: expected a field of view in radians in (0, pi), got {f!r}")
    return f


def check_light(light):
    """Refuse a light with zero (or non-finite) area or a degenerate frame."""
    for attr in ("center", "normal", "width", "height", "tangent", "bitangent"):
        if not hasattr(light, attr):
            raise InputError(f"light: expected a rectangular area light (moments_ref.scene.AreaLight), "
                             f"got {type(light).__name__} without '{attr}'")
    w, h = float(light.width), float(light.height)
    if not (np.isfinite(w) and np.isfinite(h) and w > 0 and h > 0):
        raise InputError(f"light: expected a rectangle of positive finite area, got width={w}, height={h}")
    return light


def poisson_disk(n, seed=0) -> np.ndarray:
    """``n`` Poisson-disk distributed points in the unit square, deterministic per seed.

    Parameters
    ----------
    n : int
        Number of points, at least 1.
    seed : int
        Seed of :class:`scipy.stats.qmc.PoissonDisk` (Bridson's algorithm).

    Returns
    -------
    uv : (n, 2) float64 array in [0, 1)²
        A fresh (writable) copy on every call: the fill is computed once per
        ``(n, seed)`` and cached (it costs about 0.2 s at n = 64 and 3 s at 512);
        the pairs of :data:`STORED_FILLS` come stored with the package.

    Notes
    -----
    Bridson's algorithm fills the square with a disk radius that starts at the
    spacing of a hexagonal packing of ``n`` points, ``a = sqrt(2 / (√3 n))``, and
    shrinks by 5 % until the filled square holds at least ``n`` points; then a
    seeded random choice of ``n`` of them is kept. (Taking the *first* ``n``
    points of a larger fill would keep a blob around Bridson's start point and
    under-sample part of the light.) The result depends only on ``(n, seed)``.
    """
    try:
        k = int(n)
        ok = k == n and k >= 1
    except (TypeError, ValueError):
        ok = False
    if not ok:
        raise InputError(f"n: expected a positive integer number of samples, got {n!r}")
    return _poisson_disk(k, int(seed)).copy()


#: The ``(n, seed)`` pairs whose fills are stored with the package (``poisson_fills.npz``): the
#: report's light samples, its MVR references at both settings, PCSS's blocker-search taps and
#: the single view of the centre. They are scipy's fills, written by :func:`write_stored_fills`
#: and compared with scipy's by the suite, so that the report neither imports ``scipy.stats``
#: (1.5 s in every worker) nor fills the square again (0.2 s at n = 64, 3 s at 512), and gives
#: the same light samples whatever scipy's version.
STORED_FILLS = ((1, 0), (24, 0), (64, 0), (64, 1000), (96, 1), (512, 1000))
_FILLS_FILE = Path(__file__).with_name("poisson_fills.npz")


@functools.lru_cache(maxsize=32)
def _poisson_disk(k, seed):
    """The cached fill of :func:`poisson_disk` (read-only: callers get copies)."""
    stored = _stored_fills().get((k, seed))
    return stored if stored is not None else _scipy_fill(k, seed)


@functools.lru_cache(maxsize=1)
def _stored_fills():
    """``{(n, seed): (n, 2) read-only array}`` of ``poisson_fills.npz`` (empty if it is missing)."""
    try:
        with np.load(_FILLS_FILE, allow_pickle=False) as z:
            fills = {tuple(map(int, name.split("_"))): z[name] for name in z.files}
    except OSError:
        return {}
    for a in fills.values():
        a.setflags(write=False)
    return fills


def _scipy_fill(k, seed):
    """Bridson's fill of :class:`scipy.stats.qmc.PoissonDisk` and the seeded choice of ``k`` points."""
    from scipy.stats import qmc  # ~1.5 s to import: only when a new (n, seed) is asked for

    radius = np.sqrt(2.0 / (np.sqrt(3.0) * k))
    while True:
        pts = qmc.PoissonDisk(d=2, radius=min(radius, 0.5), rng=seed).fill_space()
        if pts.shape[0] >= k:
            keep = np.sort(np.random.default_rng(seed).choice(pts.shape[0], k, replace=False))
            uv = pts[keep]
            uv.setflags(write=False)
            return uv
        radius *= 0.95


def write_stored_fills(path=_FILLS_FILE):
    """Write scipy's fills of :data:`STORED_FILLS` to ``path`` (the package's ``poisson_fills.npz``)."""
    np.savez(path, **{f"{k}_{seed}": _scipy_fill(k, seed) for k, seed in STORED_FILLS})


@dataclass(frozen=True)
class LightSamples:
    """Light samples on an area light and their shared-projection perspective views.

    Attributes
    ----------
    light : AreaLight
    uv : (N, 2) float64, sample coordinates on the rectangle in [0, 1]²
    positions : (N, 3) float64, world positions (the eyes of the views)
    fov : float, field of view in radians (vertical = horizontal, square maps)
    near, far : float, distances of the near and far planes in front of the light's plane
    view : (N, 4, 4) float64 world → view matrices (look along ``l̂n``, up = bitangent)
    projection : (4, 4) float64, shared by all views
    """

    light: object
    uv: np.ndarray
    positions: np.ndarray
    fov: float
    near: float
    far: float
    view: np.ndarray
    projection: np.ndarray

    def __len__(self) -> int:
        return int(self.uv.shape[0])

    @property
    def clip_from_world(self) -> np.ndarray:
        """(N, 4, 4) ``projection @ view`` per sample."""
        return self.projection @ self.view

    def center_clip_from_world(self) -> np.ndarray:
        """(4, 4) ``projection @ view`` from the light's centre (the single map of PCSS)."""
        return self.projection @ _view_from(self.light, self.light.center)

    # Old names (DeprecationWarning).
    view_proj = alias("clip_from_world")
    center_view_proj = alias("center_clip_from_world")


def _view_from(light, eye):
    return look_at(eye, eye + light.normal, light.bitangent)


def light_near(scene):
    """The light's near plane ``z_n`` of a scene (``params.light_near``), or None if it names none.

    Raises :class:`InputError` for a value that is not a positive finite number.
    """
    v = (getattr(scene, "params", None) or {}).get(LIGHT_NEAR_PARAM)
    if v is None:
        return None
    ok = isinstance(v, (int, float)) and not isinstance(v, bool) and np.isfinite(v) and v > 0
    if not ok:
        raise InputError(f"params.{LIGHT_NEAR_PARAM}: expected the light's near plane, a positive distance in "
                         f"world units, got {v!r}")
    return float(v)


def depth_range(light, occluder_vertices, receiver_vertices=None, margin=0.02, near=None):
    """Shared near and far distances that enclose a scene in front of the light.

    Parameters
    ----------
    light : AreaLight
    occluder_vertices : (V, 3) float array
    receiver_vertices : (V', 3) float array, optional
        Included in the far plane.
    margin : float
        Relative safety margin on both planes.
    near : float, optional
        The light's own near plane ``z_n`` (Listing 1's ``light.nearZ``,
        :func:`light_near`). Refused if an occluder vertex in front of the light
        lies nearer (it would be clipped). Without it the near plane lies just
        before the nearest occluder vertex in front of the light's plane (no
        occluder is clipped, and Eq. (3)'s ``z_n`` is as large as possible).

    Returns
    -------
    near, far : float
        ``0 < near < far``; without ``near``, ``near >= 1e-3 far``.
    """
    check_light(light)
    occ = real_input(occluder_vertices, "occluder_vertices", trailing=3, dtype=np.float64).reshape(-1, 3)
    pts = occ
    if receiver_vertices is not None:
        rec = real_input(receiver_vertices, "receiver_vertices", trailing=3, dtype=np.float64).reshape(-1, 3)
        pts = np.concatenate([occ, rec])
    dist = (pts - light.center) @ light.normal
    if not (dist > 0).any():
        raise InputError("occluder_vertices: expected geometry in front of the light (along its normal), got none")
    far = float(dist.max()) * (1 + margin)
    docc = (occ - light.center) @ light.normal
    front = docc[docc > 0]
    if near is not None:
        zn = float(near)
        if not (np.isfinite(zn) and 0 < zn < far):
            raise InputError(f"near: expected the light's near plane in (0, far = {far:.6g}), got {near!r}")
        if front.size and front.min() < zn:
            i = int(np.flatnonzero((docc > 0) & (docc < zn))[0])
            raise InputError(f"near: the light's near plane {zn:.6g} clips occluder vertex {i} at distance "
                             f"{docc[i]:.6g} in front of the light; expected a near plane below {front.min():.6g}")
        return zn, far
    zn = float(front.min()) * (1 - margin) if front.size else 1e-3 * far
    return max(zn, 1e-3 * far), far


def light_views(light, n_views, near, far, seed=0, fov=None) -> LightSamples:
    """Poisson-disk light samples on ``light`` and one perspective view per sample.

    Parameters
    ----------
    light : AreaLight
        Rectangle with centre ``l_c``, normal ``l̂n``, width ``l_w``, height ``l_h``.
    n_views : int
        Number of light samples (depth maps).
    near, far : float
        Shared near and far distances in front of the light's plane, ``0 < near < far``
        (see :func:`depth_range`).
    seed : int
        Seed of the Poisson-disk sampler; the same seed gives the same samples.
    fov : float, optional
        Field of view in radians in (0, π), vertical = horizontal; default
        ``radians(light.fov)``.

    Returns
    -------
    LightSamples

    Raises
    ------
    InputError
        A light of zero area, a field of view outside (0, π), ``near``/``far``
        not satisfying ``0 < near < far``, or a non-positive sample count.

    Notes
    -----
    Every view looks along ``l̂n`` with the light's bitangent as up, so its image
    plane is parallel to the light's plane, and all views share the projection:
    they are translated copies of the centre view (VWSS Figure 5, right).
    """
    check_light(light)
    f = check_fov(np.radians(light.fov) if fov is None else fov)
    n, fa = float(near), float(far)
    if not (np.isfinite(n) and np.isfinite(fa) and 0 < n < fa):
        raise InputError(f"near, far: expected 0 < near < far, got near={near}, far={far}")
    uv = poisson_disk(n_views, seed)
    pos = light.point(uv)
    view = np.stack([_view_from(light, p) for p in pos])  # loop over views
    proj = perspective(np.degrees(f), 1.0, n, fa)
    return LightSamples(light=light, uv=uv, positions=pos, fov=f, near=n, far=fa, view=view, projection=proj)


def check_resolution(resolution):
    """``(H, W)`` of a map resolution given as a positive int or a pair (InputError otherwise)."""
    try:
        hw = (resolution, resolution) if np.ndim(resolution) == 0 else tuple(resolution)
        h, w = (int(v) for v in hw)
        ok = len(hw) == 2 and all(int(v) == v for v in hw) and h >= 1 and w >= 1
    except (TypeError, ValueError):
        ok = False
    if not ok:
        raise InputError(f"resolution: expected a positive int or (H, W), got {resolution!r}")
    return h, w


def check_views(views):
    """The ``(V, 4, 4)`` float64 clip-from-world matrices of LightSamples or of matrices (InputError otherwise)."""
    vp = getattr(views, "clip_from_world", views)
    m = real_input(vp, "views", dtype=np.float64)
    if m.ndim == 2:
        m = m[None]
    if m.ndim != 3 or m.shape[1:] != (4, 4):
        raise InputError(f"views: expected LightSamples or (V, 4, 4) view-projection matrices, got shape {m.shape}")
    if m.shape[0] == 0:
        raise InputError("views: expected at least one view, got none")
    return m
