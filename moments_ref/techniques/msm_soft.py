"""Moment soft shadow mapping: PCSS with a summed-area table of moments (Slides, "Moment soft shadow mapping").

Percentage-closer soft shadows [Fernando 2005] in three steps (Slides,
"Percentage-closer soft shadows"), each replaced by a constant-time query:

1. **Blocker search** (Slides, "Moment-based blocker search"): one interpolated
   query of the summed-area table (:mod:`moments_ref.sat`) over the search
   region gives the moments of its depth distribution; Algorithm 1's canonical
   representation ``(zf, z1, z2; w0, w1, w2)`` (:func:`moments_ref.msm.canonical_representation`)
   reconstructs it with three depths, and the average blocker depth is

       z_b = (Σ_{l: z_l < zf} w_l z_l + ε zf) / (Σ_{l: z_l < zf} w_l + ε),  ε = 10⁻³,

   the support points in front of the fragment, with "a little bias towards the
   depth of the pixel" for a small denominator.
2. **Penumbra estimation** (Slides, "Penumbra estimation and filtering"), as in
   PCSS with parallel planes: ``w_penumbra = (d_r − d_b)·l / d_b``.
3. **Filtering**: a single interpolated SAT query over the filter region (a
   rectangle: "rectangular filter → rectangular light source") gives the moments
   for Algorithm 1 (:func:`moments_ref.msm.shadow_intensity`, lower bound) after
   biasing ("The moment bias can be smaller here", see :func:`soft_bias`).

Geometry and units
------------------
The single shadow map is the perspective view from the area light's centre
along its normal (:meth:`moments_ref.scene.Scene.shadow_view_proj`, or
:meth:`moments_ref.vwss.LightSamples.center_view_proj`); its samples and the
fragments' depths arrive as NDC depths z ∈ [−1, 1] (design.md). Distances
``d`` are view depths in world units along the light normal,
``d = 2 f n / ((f + n) − z (f − n))`` (:meth:`LightFrustum.view_depth`).

Stored depth. By default (``depth="linear"``) the texture holds the moments of
the depth *linear in d*, remapped to [−1, 1]: ``z_lin = 2 (d − n)/(f − n) − 1``
(empty texels, NDC 1, stay at 1). Perspective NDC depth crowds everything far
from the near plane against 1, where the biased moments cannot separate an
occluder from the receiver: on the ``column`` artifact scene (column at d = 3.6,
receiver at 4, near 0.5, far 5: NDC 0.914 and 0.944) the blocker depth
reconstructed from NDC moments comes out between 2.4 and 3.1 instead of 3.6.
``depth="ndc"`` keeps the NDC depth for comparison. The blocker depth ``z_b``
is averaged in the stored depth, as the slides average the stored depths, and
then converted to ``d_b``.

For a receiver at view depth ``d_r`` the light rectangle (extent ``l`` along a
map axis) seen through the plane at depth ``d`` covers, in the map, a rectangle
centred on the receiver's texel position with full extent ``l (1/d − 1/d_r)``
in tan units, times ``k = W / (2 tan(fov/2))`` texels per tan unit:

* search region: at the near plane, ``d = near`` (the largest region that can
  hold a blocker, as :func:`moments_ref.vwss.pcss`);
* filter region: at ``d = d_b``; this is the PCSS penumbra width
  ``w_penumbra = (d_r − d_b) l / d_b`` on the receiver, projected (divided by
  ``d_r``). For an occluder parallel to the light it is exactly the set of
  occluder points between the receiver and the light, which makes the result
  exact for one planar parallel occluder (up to texels and the bias).

Regions are clamped (documented clamp, counted in the details) to at least one
texel (the query is then bilinear filtering: a hard shadow) and at most
``max_kernel`` texels per side, the SAT's largest kernel ``n = max_kernel²``;
rectangles reaching over the map's border are intersected with the map
(:func:`moments_ref.sat.interpolated_mean` with ``clamp=True``). Fragments
outside the map or behind the light are lit.

The texture stores the optimized basis (:func:`moments_ref.affine.to_optimized`)
of the per-texel moments (MSAA resolved, unfiltered: the SAT is the filter) in
four uint32 channels, 128 bits per texel.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .._arrays import InputError, real_input
from ..affine import from_optimized, to_optimized
from ..filtering import resolve_moments
from ..moments import BIAS_FLOAT32, BIAS_UNORM16, BiasPreset, bias_moments
from ..msm import canonical_representation, shadow_intensity
from .. import sat as _sat
from . import Step, Technique, register

__all__ = [
    "EPSILON",
    "MAX_AUTO_KERNEL",
    "DEPTH_BIAS",
    "soft_bias",
    "LightFrustum",
    "SoftShadowMap",
    "prepare",
    "prepare_moments",
    "average_blocker_depth",
    "penumbra_width",
    "soft_shadow",
    "shade_points",
    "ray_cast_visibility",
    "ARTIFACT_SCENES",
    "artifact_measurements",
    "artifact_images",
    "MSM_SOFT",
]

#: ε of the average blocker depth (Slides, "Moment-based blocker search": ε := 10⁻³).
EPSILON = 1e-3
#: Cap of the automatic largest kernel side: 128² texels leave log2(2³²/128²) = 18 bits and
#: a bias α = 1.5e-5. Larger kernels cost precision and need a larger bias. Measured on
#: the square-occluder scene of the tests (256² map, every search region clamped), RMSE
#: against the exact visibility: linear depth 0.0057 / 0.0056 / 0.0052 at caps 64 / 128 /
#: 256; NDC depth 0.011 / 0.019 / 0.060 (there the bias pulls the blocker depth towards
#: the receiver).
MAX_AUTO_KERNEL = 128
#: Depth bias in NDC units of the registered technique (as the other techniques, HPG17 §5).
DEPTH_BIAS = 1e-3


def soft_bias(n) -> BiasPreset:
    """The moment bias for moments read from a SAT with largest kernel ``n``.

    Parameters
    ----------
    n : int
        Texels of the SAT's largest kernel.

    Returns
    -------
    BiasPreset
        ``α = max(3·10⁻⁷, 6·10⁻⁵ · (2¹⁶ − 1)/Q)`` with ``Q = floor((2³² − 1)/n)``
        (:func:`moments_ref.sat.code_scale`), target ``(0, 0.628, 0, 0.628)``.

    Notes
    -----
    Slides, "Penumbra estimation and filtering": "The moment bias can be
    smaller here", without a number. Slides, "Bias the moments": α "only
    depends on the amount of rounding error", 6·10⁻⁵ at 16 bits per moment in
    the optimized basis. A SAT mean in the same basis is off by at most
    ``0.5/Q`` instead of ``0.5/(2¹⁶ − 1)``, so α is scaled by that ratio, and
    never below the float32 bias 3·10⁻⁷ (the shader converts to float):
    n = 27² gives α = 6.7·10⁻⁷, n = 256² gives 6.0·10⁻⁵. The tests check the
    property this must deliver: adversarially rounded SAT moments of extreme
    distributions stay inside the moment space after biasing.
    """
    q = _sat.code_scale(n)
    alpha = max(BIAS_FLOAT32.alpha, BIAS_UNORM16.alpha * 65535.0 / q)
    return BiasPreset(alpha, BIAS_UNORM16.target, f"sat_n{int(n)}")


@dataclass(frozen=True)
class LightFrustum:
    """The perspective shadow map of a rectangular light's centre.

    Attributes
    ----------
    near, far : float
        Clip distances along the light normal (world units).
    tan_half_fov : (float, float)
        ``tan(fov/2)`` horizontally (columns) and vertically (rows).
    size : (int, int)
        ``(H, W)`` of the map.
    extent : (float, float)
        Extent of the light rectangle along the map's x (columns) and y (rows)
        axes, world units (its bounding box there; width and height when the
        map's up vector is the light's bitangent).
    """

    near: float
    far: float
    tan_half_fov: tuple
    size: tuple
    extent: tuple

    @classmethod
    def from_view_proj(cls, light, view_proj, size):
        """Read near, far and field of view back from ``projection @ look_at`` (OpenGL).

        Raises :class:`InputError` for a matrix that is not a symmetric
        perspective view along the light's normal.
        """
        for attr in ("normal", "width", "height", "tangent", "bitangent"):
            if not hasattr(light, attr):
                raise InputError(f"light: expected a rectangular area light (moments_ref.scene.AreaLight), "
                                 f"got {type(light).__name__}")
        m = real_input(view_proj, "view_proj", dtype=np.float64)
        if m.shape != (4, 4):
            raise InputError(f"view_proj: expected a (4, 4) matrix, got shape {m.shape}")
        fwd = m[3, :3]  # w_clip = distance along the viewing direction
        ok = abs(np.linalg.norm(fwd) - 1) < 1e-9 and np.dot(fwd, light.normal) > 1 - 1e-9
        sx, sy = m[0, :3], m[1, :3]
        px, py = np.linalg.norm(sx), np.linalg.norm(sy)
        ok = ok and px > 0 and py > 0 and abs(np.dot(sx, fwd)) < 1e-9 * px and abs(np.dot(sy, fwd)) < 1e-9 * py
        a = -np.dot(m[2, :3], fwd)
        b = m[2, 3] + a * m[3, 3]
        near, far = (b / (a - 1), b / (a + 1)) if ok and a not in (1, -1) else (np.nan, np.nan)
        if not (ok and np.isfinite(near) and np.isfinite(far) and 0 < near < far):
            raise InputError("view_proj: expected a symmetric perspective view from the light along its normal "
                             "(Scene.shadow_view_proj() or LightSamples.center_view_proj())")
        ux, uy = sx / px, sy / py
        ext = (abs(light.tangent @ ux) * light.width + abs(light.bitangent @ ux) * light.height,
               abs(light.tangent @ uy) * light.width + abs(light.bitangent @ uy) * light.height)
        h, w = int(size[0]), int(size[1])
        return cls(near=float(near), far=float(far), tan_half_fov=(1 / px, 1 / py), size=(h, w),
                   extent=(float(ext[0]), float(ext[1])))

    def view_depth(self, z):
        """World distance along the normal of NDC depth z: ``2 f n / ((f + n) − z (f − n))`` (float64)."""
        z = np.asarray(z, np.float64)
        n, f = self.near, self.far
        return 2 * f * n / ((f + n) - z * (f - n))

    def ndc_depth(self, d):
        """Inverse of :meth:`view_depth`: ``((f + n) − 2 f n / d) / (f − n)`` (float64)."""
        d = np.asarray(d, np.float64)
        n, f = self.near, self.far
        return ((f + n) - 2 * f * n / d) / (f - n)

    def linear_depth(self, z):
        """NDC depth -> depth linear in the view distance, on [−1, 1]: ``2 (d − n)/(f − n) − 1`` (float64).

        NDC 1 (empty texel, far plane) stays 1; NDC −1 (near plane) stays −1.
        """
        d = self.view_depth(z)
        return 2 * (d - self.near) / (self.far - self.near) - 1

    def linear_to_view(self, zl):
        """Inverse of the linear remap: ``n + (zl + 1)(f − n)/2`` (float64)."""
        return self.near + (np.asarray(zl, np.float64) + 1) * (self.far - self.near) / 2

    @property
    def texels_per_tan(self) -> np.ndarray:
        """``(W / (2 tan(fov_x/2)), H / (2 tan(fov_y/2)))``."""
        h, w = self.size
        return np.array([w / (2 * self.tan_half_fov[0]), h / (2 * self.tan_half_fov[1])])

    def region_half_extent(self, d, d_receiver):
        """Half extent in texels (..., 2) of the light seen through depth ``d`` from ``d_receiver``.

        ``0.5 · k · l · (1/d − 1/d_r)`` per map axis (module docstring).
        """
        s = 1 / np.asarray(d, np.float64) - 1 / np.asarray(d_receiver, np.float64)
        return 0.5 * (self.texels_per_tan * np.asarray(self.extent))[None, :] * s.reshape(-1)[:, None]

    def largest_search_side(self) -> float:
        """The full side in texels of the largest search region (near plane, receiver at far)."""
        return float(self.region_half_extent(self.near, self.far).max() * 2)


@dataclass(frozen=True)
class SoftShadowMap:
    """The texture of moment soft shadow mapping.

    Attributes
    ----------
    sat : SummedAreaTable
        Optimized-basis moments per texel, four uint32 channels.
    frustum : LightFrustum
    max_kernel : int
        Largest region side in texels (``sat.n = max_kernel²``).
    bias : BiasPreset
        :func:`soft_bias` of ``sat.n``.
    depth : {"linear", "ndc"}
        The depth the moments are of (module docstring).
    """

    sat: object
    frustum: LightFrustum
    max_kernel: int
    bias: BiasPreset
    depth: str = "linear"

    def stored_depth(self, z_ndc):
        """The stored depth of NDC depths (float64)."""
        z = np.asarray(z_ndc, np.float64)
        return self.frustum.linear_depth(z) if self.depth == "linear" else z

    def view_depth(self, z_stored):
        """World distance along the normal of a stored depth (float64)."""
        z = np.asarray(z_stored, np.float64)
        return self.frustum.linear_to_view(z) if self.depth == "linear" else self.frustum.view_depth(z)

    @property
    def precision_bits(self) -> float:
        """``log2(2³²/n)`` (Slides, "SAT over a moment shadow map")."""
        return _sat.precision_bits(self.sat.n)


def _check_kernel(max_kernel, frustum):
    if max_kernel is None:
        side = math.ceil(frustum.largest_search_side())
        return int(min(max(side, 1), MAX_AUTO_KERNEL, max(frustum.size)))
    try:
        k = int(max_kernel)
        ok = k == max_kernel and 1 <= k <= 65535
    except (TypeError, ValueError):
        ok = False
    if not ok:
        raise InputError(f"max_kernel: expected the largest region side in texels, an integer in [1, 65535], "
                         f"got {max_kernel!r}")
    return k


def _check_depth(depth):
    if depth not in ("linear", "ndc"):
        raise InputError(f"depth: expected 'linear' or 'ndc', got {depth!r}")
    return depth


def prepare_moments(moments, light, view_proj, max_kernel=None, depth="linear") -> SoftShadowMap:
    """Build the :class:`SoftShadowMap` from per-texel moments b1..b4.

    Parameters
    ----------
    moments : (H, W, 4) float array
        Moments of each texel's stored depths (resolved, unfiltered), of the
        depth named by ``depth``.
    light : AreaLight
    view_proj : (4, 4) float array
        The map's view from the light's centre.
    max_kernel : int, optional
        Largest region side in texels. Default: the side of the largest search
        region (:meth:`LightFrustum.largest_search_side`) capped at
        :data:`MAX_AUTO_KERNEL` and the map size.
    depth : {"linear", "ndc"}
        What the moments are of (module docstring).

    Returns
    -------
    SoftShadowMap
    """
    b = real_input(moments, "moments", trailing=4, dtype=np.float64)
    if b.ndim != 3:
        raise InputError(f"moments: expected an (H, W, 4) array, got shape {b.shape}")
    fr = LightFrustum.from_view_proj(light, view_proj, b.shape[:2])
    k = _check_kernel(max_kernel, fr)
    table = _sat.build(to_optimized(b), k * k)
    return SoftShadowMap(sat=table, frustum=fr, max_kernel=k, bias=soft_bias(k * k), depth=_check_depth(depth))


def prepare(depth_samples, light, view_proj, max_kernel=None, depth="linear") -> SoftShadowMap:
    """Resolve a shadow map to moments and build its summed-area table.

    Parameters
    ----------
    depth_samples : (H, W) or (H, W, S) float array
        NDC depths in [−1, 1] from the light's centre (1 = empty).
    light, view_proj, max_kernel, depth
        As :func:`prepare_moments`; with ``depth="linear"`` the samples are
        remapped to ``2 (d − n)/(f − n) − 1`` before their moments are taken.

    Returns
    -------
    SoftShadowMap
    """
    z = np.asarray(depth_samples)
    if z.ndim == 2:
        z = z[..., None]
    from ..filtering import check_depth_samples

    z = check_depth_samples(z).astype(np.float64)
    if _check_depth(depth) == "linear":
        fr = LightFrustum.from_view_proj(light, view_proj, z.shape[:2])
        z = np.clip(fr.linear_depth(z), -1.0, 1.0)
    return prepare_moments(resolve_moments(z), light, view_proj, max_kernel, depth)


def average_blocker_depth(b, zf, epsilon=EPSILON):
    """Average depth of the blockers in front of ``zf`` from four moments.

    Parameters
    ----------
    b : (..., 4) float array
        (Biased) moments of the search region.
    zf : (...) float array
        Fragment depth.
    epsilon : float
        ε of the slides (10⁻³).

    Returns
    -------
    z_b : (...) float array, dtype of ``b``
        ``(Σ w_l z_l + ε zf) / (Σ w_l + ε)`` over the support points ``z_l < zf``
        of the canonical representation; ``zf`` when there is none.
    blocked : (...) float array
        ``Σ w_l`` over those points (Algorithm 1's lower bound).

    Notes
    -----
    Slides, "Moment-based blocker search", steps 1 and 2. A root at ±inf has
    weight 0 and is left out.
    """
    depths, weights = canonical_representation(b, zf)
    dt = depths.dtype
    zf = np.broadcast_to(np.asarray(zf, dt), depths.shape[:-1])
    z = depths[..., 1:]
    front = np.isfinite(z) & (z < zf[..., None]) & (weights[..., 1:] > 0)
    w = np.where(front, weights[..., 1:], dt.type(0))
    wz = (w * np.where(front, z, dt.type(0))).sum(-1)
    eps = dt.type(epsilon)
    blocked = w.sum(-1)
    return (wz + eps * zf) / (blocked + eps), blocked


def penumbra_width(d_receiver, d_blocker, light_size):
    """PCSS penumbra width by parallel planes: ``(d_r − d_b)·l / d_b`` (world units on the receiver).

    Parameters
    ----------
    d_receiver, d_blocker : float arrays
        View depths (world distance along the light normal), ``0 < d_b ≤ d_r``.
    light_size : float
        Extent of the light along the axis of interest (world units).

    Notes
    -----
    Slides, "Penumbra estimation and filtering": "Penumbra size is estimated
    as in percentage-closer soft shadows" [Fernando 2005].
    """
    dr = np.asarray(d_receiver, np.float64)
    db = np.asarray(d_blocker, np.float64)
    return (dr - db) * float(light_size) / db


def _query_moments(tex, centre, half, dtype):
    q = _sat.interpolated_mean(tex.sat, centre - half, centre + half, clamp=True, dtype=dtype)
    return bias_moments(from_optimized(q), tex.bias)


def soft_shadow(texture, uv, zf, receiver_depth=None, dtype=np.float32, epsilon=EPSILON, details=False):
    """Shadow intensity of fragments by moment soft shadow mapping.

    Parameters
    ----------
    texture : SoftShadowMap
    uv : (..., 2) float array
        Texel coordinates of the fragments in the map (u = column, v = row).
    zf : (...) float array
        Fragment NDC depth, depth bias already subtracted (converted to the
        texture's stored depth here).
    receiver_depth : (...) float array, optional
        The fragment's view depth ``d_r`` (world units); default
        ``view_depth(zf)``.
    dtype : float32 or float64
        Arithmetic of the SAT conversion, the biasing and Algorithm 1
        (float32 emulates the shader). Region geometry is float64.
    epsilon : float
        ε of the blocker search.
    details : bool
        Also return a dict of per-fragment intermediates.

    Returns
    -------
    intensity : (...) float64 array in [0, 1]
        0 for fragments outside the map or with ``zf`` outside (−1, 1].
    details : dict, only with ``details=True``
        ``inside`` (bool), ``blocker_depth`` (stored depth z_b), ``blocker_view_depth``
        (d_b), ``blocked`` (Σ w of the blocker search), ``search_half`` and
        ``filter_half`` ((..., 2) texels, after clamping), ``search_clamped``,
        ``filter_clamped`` (the region exceeded ``max_kernel``),
        ``penumbra_width`` (world units, along the map's x axis).
    """
    if not isinstance(texture, SoftShadowMap):
        raise InputError(f"texture: expected a SoftShadowMap (msm_soft.prepare), got {type(texture).__name__}")
    dt = np.dtype(dtype)
    if dt not in (np.float32, np.float64):
        raise InputError(f"dtype: expected float32 or float64, got {dtype!r}")
    uv = real_input(uv, "uv", trailing=2, dtype=np.float64, finite=False)
    z = real_input(zf, "zf", dtype=np.float64, finite=False)
    try:
        shape = np.broadcast_shapes(uv.shape[:-1], z.shape)
    except ValueError:
        raise InputError(f"zf: expected a shape broadcastable to uv.shape[:-1] {uv.shape[:-1]}, got {z.shape}") from None
    uvf = np.broadcast_to(uv, shape + (2,)).reshape(-1, 2)
    zff = np.broadcast_to(z, shape).reshape(-1)
    fr = texture.frustum
    dr = fr.view_depth(zff) if receiver_depth is None else np.broadcast_to(
        real_input(receiver_depth, "receiver_depth", dtype=np.float64, finite=False), shape).reshape(-1)
    h, w = fr.size
    inside = (np.isfinite(uvf).all(-1) & (uvf[:, 0] >= 0) & (uvf[:, 0] <= w) & (uvf[:, 1] >= 0)
              & (uvf[:, 1] <= h) & np.isfinite(zff) & (zff > -1) & (zff <= 1) & np.isfinite(dr) & (dr > 0))
    i = np.flatnonzero(inside)
    c, zi, di = uvf[i], texture.stored_depth(zff[i]), dr[i]
    lo_h, hi_h = 0.5, 0.5 * texture.max_kernel
    # 1. Blocker search: the region at the near plane, one interpolated query.
    s_raw = fr.region_half_extent(fr.near, di)
    s_half = np.clip(s_raw, lo_h, hi_h)
    b = _query_moments(texture, c, s_half, dt)
    zb, blocked = average_blocker_depth(b, zi.astype(dt), epsilon)
    # 2. Penumbra estimate (parallel planes) -> filter region at the blocker depth.
    db = np.minimum(texture.view_depth(zb.astype(np.float64)), di)
    f_raw = fr.region_half_extent(db, di)
    f_half = np.clip(f_raw, lo_h, hi_h)
    # 3. One interpolated query over the filter region, Algorithm 1 (lower bound).
    b = _query_moments(texture, c, f_half, dt)
    out = np.zeros(uvf.shape[0])
    out[i] = shadow_intensity(b, zi.astype(dt))
    out = out.reshape(shape)
    if not details:
        return out

    def full(x, fill, tail=()):
        a = np.full((uvf.shape[0],) + tail, fill, dtype=np.asarray(x).dtype)
        a[i] = x
        return a.reshape(shape + tail)

    info = {
        "inside": inside.reshape(shape),
        "blocker_depth": full(zb.astype(np.float64), np.nan),
        "blocker_view_depth": full(db, np.nan),
        "blocked": full(blocked.astype(np.float64), np.nan),
        "search_half": full(s_half, np.nan, (2,)),
        "filter_half": full(f_half, np.nan, (2,)),
        "search_clamped": full((s_raw > hi_h).any(-1), False),
        "filter_clamped": full((f_raw > hi_h).any(-1), False),
        "penumbra_width": full(penumbra_width(di, db, fr.extent[0]), np.nan),
    }
    return out, info


def _resolve_source(source, view_proj):
    """(light, view_proj) from a Scene, a LightSamples or an AreaLight (+ view_proj)."""
    if hasattr(source, "center_view_proj") and hasattr(source, "light"):  # vwss.LightSamples
        return source.light, source.center_view_proj() if view_proj is None else view_proj
    if hasattr(source, "shadow_view_proj") and hasattr(source, "light"):  # scene.Scene
        return source.light, source.shadow_view_proj() if view_proj is None else view_proj
    if view_proj is None:
        raise InputError(f"view_proj: required with a light of type {type(source).__name__} "
                         "(or pass a Scene or vwss.LightSamples)")
    return source, view_proj


def shade_points(source, depth_map, points, *, view_proj=None, bias=None, max_kernel=None, dtype=np.float32,
                 details=False, depth="linear"):
    """Visibility of world points under a rectangular area light by moment soft shadow mapping.

    Parameters
    ----------
    source : Scene, vwss.LightSamples or AreaLight
        The light and the view of its centre's map (``Scene.shadow_view_proj()``,
        ``LightSamples.center_view_proj()``, or ``view_proj`` with a bare light).
    depth_map : (H, W) or (H, W, S) float array, or SoftShadowMap
        NDC depths of the occluders rasterized with that view (1 = empty), or
        an already prepared texture.
    points : (P, 3) float array
        World positions of the receivers (e.g. ``vwss.gbuffer(...).points``).
    view_proj : (4, 4) float array, optional
        Overrides the source's view (required for a bare AreaLight).
    bias : float, optional
        Depth bias in world units along the light normal, default ``0.002·far``
        (the default of ``moments-ref vwss`` for PCSS and MVR).
    max_kernel : int, optional
        See :func:`prepare_moments` (ignored for a prepared texture).
    depth : {"linear", "ndc"}
        Stored depth (module docstring; ignored for a prepared texture).
    dtype : float32 or float64
        See :func:`soft_shadow`.
    details : bool
        Also return :func:`soft_shadow`'s details.

    Returns
    -------
    visibility : (P,) float64 array in [0, 1]
        ``1 − intensity``; 1 for points outside the map or behind the light
        (the convention of :func:`moments_ref.vwss.pcss`).
    """
    from ..raster import project_points

    light, vp = _resolve_source(source, view_proj)
    if isinstance(depth_map, SoftShadowMap):
        tex = depth_map
    else:
        tex = prepare(depth_map, light, vp, max_kernel, depth)
    p = real_input(points, "points", trailing=3, dtype=np.float64)
    if p.ndim != 2:
        raise InputError(f"points: expected a (P, 3) array, got shape {p.shape}")
    fr = tex.frustum
    xy, _ = project_points(p, vp, fr.size)
    m = real_input(vp, "view_proj", dtype=np.float64)
    d_r = p @ m[3, :3] + m[3, 3]  # w_clip: distance along the light normal
    b = 0.002 * fr.far if bias is None else float(bias)
    with np.errstate(divide="ignore", invalid="ignore"):
        zf = np.where(d_r - b > 0, fr.ndc_depth(d_r - b), np.nan)
    res = soft_shadow(tex, xy, zf, receiver_depth=d_r, dtype=dtype, details=details)
    if details:
        return 1.0 - res[0], res[1]
    return 1.0 - res


# ---------------------------------------------------------------------------
# The artifacts the slides name (Slides, "Results for soft shadows")

#: The light of the artifact scenes: 1.0 × 0.6 (width along the map's columns), 60° maps.
_ART_LIGHT = dict(center=(0.0, 0.0, 0.0), normal=(0.0, -1.0, 0.0), width=1.0, height=0.6, up=(0.0, 0.0, -1.0),
                  fov=60.0)
#: Receiver plane distance, near and far of the artifact scenes.
_ART_RECEIVER, _ART_NEAR, _ART_FAR = 4.0, 0.5, 5.0
#: Rectangles (x0, x1, y0, y1, d) in the light's frame (tangent, bitangent, distance).
_HOLE = 0.08
ARTIFACT_SCENES = {
    # A plate at d = 3 with a small square hole at its centre.
    "hole": ((-2.0, -_HOLE / 2, -2.0, 2.0, 3.0), (_HOLE / 2, 2.0, -2.0, 2.0, 3.0),
             (-_HOLE / 2, _HOLE / 2, -2.0, -_HOLE / 2, 3.0), (-_HOLE / 2, _HOLE / 2, _HOLE / 2, 2.0, 3.0)),
    # A column close to the receiver (d = 3.6) ...
    "column": ((-1.0, -0.1, -2.0, 2.0, 3.6),),
    # ... and the same with a wall nearer the light (d = 3) that shadows none of the
    # receiver points left of x = 0 but lies in their blocker-search regions.
    "column_wall": ((-1.0, -0.1, -2.0, 2.0, 3.6), (0.18, 2.0, -2.0, 2.0, 3.0)),
}


def _frame_points(light, x, y, d):
    x, y, d = np.broadcast_arrays(np.asarray(x, np.float64), np.asarray(y, np.float64), np.asarray(d, np.float64))
    return (light.center + x[..., None] * light.tangent + y[..., None] * light.bitangent
            + d[..., None] * light.normal)


def _rect_mesh(light, rects):
    """Two triangles per rectangle (x0, x1, y0, y1, d) of the light's frame."""
    r = np.asarray(rects, np.float64).reshape(-1, 5)
    xs = np.stack([r[:, 0], r[:, 1], r[:, 1], r[:, 0]], 1)
    ys = np.stack([r[:, 2], r[:, 2], r[:, 3], r[:, 3]], 1)
    v = _frame_points(light, xs, ys, np.repeat(r[:, 4:5], 4, 1)).reshape(-1, 3)
    base = 4 * np.arange(r.shape[0])[:, None, None]
    t = (base + np.array([[0, 1, 2], [0, 2, 3]])[None]).reshape(-1, 3)
    return v, t


def ray_cast_visibility(light, rects, points, samples=64):
    """Reference visibility for rectangles parallel to the light, by a grid of light samples.

    Parameters
    ----------
    light : AreaLight
    rects : (R, 5) float array
        ``(x0, x1, y0, y1, d)`` in the light's frame: ``x`` along the tangent
        (width), ``y`` along the bitangent (height), ``d`` the distance along
        the normal.
    points : (P, 3) float array
        Receiver points behind the rectangles.
    samples : int
        Light samples per side (midpoint grid).

    Returns
    -------
    (P,) float64: the fraction of the ``samples²`` segments from the point to the
    light samples that miss every rectangle.
    """
    r = np.asarray(rects, np.float64).reshape(-1, 5)
    p = np.asarray(points, np.float64).reshape(-1, 3) - light.center
    px, py, pd = p @ light.tangent, p @ light.bitangent, p @ light.normal
    g = (np.arange(samples) + 0.5) / samples - 0.5
    sx = (g[:, None] * light.width + 0 * g[None, :]).reshape(-1)
    sy = (0 * g[:, None] + g[None, :] * light.height).reshape(-1)
    vis = np.empty(p.shape[0])
    for lo in range(0, p.shape[0], 2048):  # chunks of points
        sl = slice(lo, lo + 2048)
        hit = np.zeros((px[sl].shape[0], sx.size), bool)
        for x0, x1, y0, y1, d in r:  # loop over rectangles
            t = (d / pd[sl])[:, None]  # where the segment crosses the rectangle's plane
            xx = sx + (px[sl, None] - sx) * t
            yy = sy + (py[sl, None] - sy) * t
            hit |= (t < 1) & (xx >= x0) & (xx <= x1) & (yy >= y0) & (yy <= y1)
        vis[sl] = 1 - hit.mean(1)
    return vis


def _artifact_setup(size):
    from ..raster import look_at, perspective
    from ..scene import AreaLight

    light = AreaLight(**_ART_LIGHT)
    vp = perspective(light.fov, 1.0, _ART_NEAR, _ART_FAR) @ look_at(light.center, light.center + light.normal,
                                                                     light.bitangent)
    return light, vp


def _transition_width(x, v, lo=0.1, hi=0.9):
    """Distance between the first crossings of ``lo`` and ``hi`` of an increasing profile (NaN if not reached)."""
    if not (v >= hi).any() or not (v >= lo).any():
        return float("nan")
    i_lo = np.argmax(v >= lo)
    i_hi = np.argmax(v >= hi)
    def cross(i, level):
        if i == 0:
            return x[0]
        return x[i - 1] + (level - v[i - 1]) * (x[i] - x[i - 1]) / (v[i] - v[i - 1])
    return float(cross(i_hi, hi) - cross(i_lo, lo))


def artifact_measurements(size=256, max_kernel=64, grid=96, samples=64):
    """Measure the two artifacts of the slides on synthetic scenes with exact references.

    Scenes (:data:`ARTIFACT_SCENES`): a 1.0 × 0.6 light, receiver plane at
    distance 4, a 60° map of ``size²`` texels with near 0.5 and far 5.

    * ``hole``: a plate at distance 3 with a 0.08 × 0.08 hole. The light
      through the hole is the light's image, a rectangle of aspect
      ``width/height`` (Slides: "Rectangular light rather obvious").
    * ``column`` / ``column_wall``: a column at distance 3.6, alone and with a
      wall at distance 3 that does not shadow the measured receiver points but
      lies in their blocker-search regions (Slides: "The shadow of the distant
      wall makes the shadow of the nearby column softer").

    Returns
    -------
    dict with the images (``hole_msm``, ``hole_reference``: (grid, grid)
    visibility over [−0.5, 0.5]²), the column profiles (``profile_x`` and
    ``profile_*``) and the measured numbers: ``hole_aspect_msm`` /
    ``hole_aspect_reference`` (ratio of the lit spot's extents at half
    maximum along x and y), ``hole_fill_msm`` (lit area at half maximum over
    the product of those extents: 1 for a rectangle, π/4 for an ellipse),
    ``width_column``, ``width_column_wall`` (10 %–90 % transition width of
    msm_soft), ``width_reference`` (of the reference, which the wall does not
    change: ``wall_changes_reference`` is its largest effect on the profile).
    """
    light, vp = _artifact_setup(size)
    out = {}
    # Small hole.
    v, t = _rect_mesh(light, ARTIFACT_SCENES["hole"])
    from ..raster import rasterize_depth

    dm, _ = rasterize_depth(v, t, vp, size)
    xs = np.linspace(-0.5, 0.5, grid)
    gx, gy = np.meshgrid(xs, xs)
    pts = _frame_points(light, gx, gy, _ART_RECEIVER).reshape(-1, 3)
    tex = prepare(dm, light, vp, max_kernel)
    vis = shade_points(light, tex, pts, view_proj=vp).reshape(grid, grid)
    ref = ray_cast_visibility(light, ARTIFACT_SCENES["hole"], pts, samples).reshape(grid, grid)
    step = xs[1] - xs[0]
    for name, im in (("msm", vis), ("reference", ref)):
        lit = im >= 0.5 * im.max()
        ex = lit.any(0).sum() * step
        ey = lit.any(1).sum() * step
        out[f"hole_aspect_{name}"] = float(ex / ey)
        out[f"hole_fill_{name}"] = float(lit.sum() * step * step / (ex * ey))
        out[f"hole_{name}"] = im
    # Column with and without the wall.
    # The wall shadows no receiver point with x < 0.073 (s ≥ 0.72 − 3x > 0.5 for every light sample s).
    px = np.linspace(-0.4, 0.07, 236)
    prof = _frame_points(light, px, 0.0 * px, _ART_RECEIVER)
    out["profile_x"] = px
    for key in ("column", "column_wall"):
        v, t = _rect_mesh(light, ARTIFACT_SCENES[key])
        dm, _ = rasterize_depth(v, t, vp, size)
        vis, info = shade_points(light, dm, prof, view_proj=vp, max_kernel=max_kernel, details=True)
        out[f"profile_{key}"] = vis
        out[f"profile_{key}_reference"] = ray_cast_visibility(light, ARTIFACT_SCENES[key], prof, samples)
        out[f"width_{key}"] = _transition_width(px, vis)
        out[f"blocker_depth_{key}"] = info["blocker_view_depth"]
    out["width_reference"] = _transition_width(px, out["profile_column_reference"])
    out["wall_changes_reference"] = float(np.abs(out["profile_column_wall_reference"]
                                                 - out["profile_column_reference"]).max())
    return out


def artifact_images(out_dir, size=256, max_kernel=64):
    """Write ``msm_soft_artifacts.png`` and ``msm_soft_artifacts.md`` (measured statements) to ``out_dir``.

    Returns the measurements of :func:`artifact_measurements` and the paths written.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from pathlib import Path

    from .._io import save_figure, write_text

    m = artifact_measurements(size=size, max_kernel=max_kernel)
    fig, ax = plt.subplots(1, 3, figsize=(13, 4), constrained_layout=True)
    ext = (-0.5, 0.5, -0.5, 0.5)
    ax[0].imshow(m["hole_msm"], cmap="gray", vmin=0, vmax=max(m["hole_msm"].max(), 1e-9), extent=ext,
                 origin="lower")
    ax[0].set_title(f"msm_soft: light through a 0.08² hole\naspect {m['hole_aspect_msm']:.2f}, "
                    f"fill {m['hole_fill_msm']:.2f}", fontsize=9)
    ax[1].imshow(m["hole_reference"], cmap="gray", vmin=0, vmax=max(m["hole_reference"].max(), 1e-9), extent=ext,
                 origin="lower")
    ax[1].set_title(f"reference (1.0 × 0.6 light)\naspect {m['hole_aspect_reference']:.2f}", fontsize=9)
    x = m["profile_x"]
    ax[2].plot(x, m["profile_column_reference"], "k-", label="reference (with or without wall)")
    ax[2].plot(x, m["profile_column"], "b--", label=f"msm_soft, column only (width {m['width_column']:.3f})")
    ax[2].plot(x, m["profile_column_wall"], "r-",
               label=f"msm_soft, column + distant wall (width {m['width_column_wall']:.3f})")
    ax[2].set_xlabel("receiver x (world units)")
    ax[2].set_ylabel("visibility")
    ax[2].legend(fontsize=7)
    ax[2].set_title("a distant occluder softens a near shadow", fontsize=9)
    out = Path(out_dir)
    paths = [save_figure(fig, out / "msm_soft_artifacts.png", dpi=100)]
    plt.close(fig)
    text = "\n".join([
        "# Moment soft shadow mapping: the artifacts of the slides, measured", "",
        f"Map {size}², largest kernel {max_kernel}² ({precision_bits_text(max_kernel)}), light 1.0 × 0.6.", "",
        f"- Light through a small hole is the light's rectangle: lit-spot aspect {m['hole_aspect_msm']:.3f} "
        f"(reference {m['hole_aspect_reference']:.3f}, light 1.667), fill of its bounding box "
        f"{m['hole_fill_msm']:.3f} (1 = rectangle, 0.785 = ellipse).",
        f"- A distant wall softens the column's shadow: 10–90 % width {m['width_column']:.4f} without, "
        f"{m['width_column_wall']:.4f} with the wall; reference {m['width_reference']:.4f} in both cases "
        f"(the wall changes the reference profile by at most {m['wall_changes_reference']:.3g}).", ""])
    paths.append(write_text(out / "msm_soft_artifacts.md", text))
    return m, paths


def precision_bits_text(max_kernel) -> str:
    """``"22.5 bits, alpha = 6.7e-07"`` for a kernel side."""
    n = int(max_kernel) ** 2
    return f"{_sat.precision_bits(n):.1f} bits, alpha = {soft_bias(n).alpha:.2g}"


# ---------------------------------------------------------------------------
# The shared technique interface (moments_ref.techniques)


def _params_light(params):
    scene = params.get("scene")
    light = params.get("light", getattr(scene, "light", None))
    vp = params.get("view_proj")
    if vp is None and scene is not None:
        vp = scene.shadow_view_proj()
    if light is None or vp is None:
        raise InputError("params: msm_soft needs the area light and its centre's view: pass params "
                         "{'scene': scene} or {'light': AreaLight, 'view_proj': (4, 4)}")
    return light, vp


def _build_step(samples, params):
    light, vp = _params_light(params)
    return prepare(samples, light, vp, params.get("max_kernel"), params.get("msm_soft_depth", "linear"))


def _steps(samples, layered):
    """One step, ``msm_soft_sat``: linear depth, resolve, optimized basis, SAT (:func:`prepare`)."""
    return (Step("msm_soft_sat", _build_step),)


def _lookup(texture, uv, zf, noise):
    # Technique.shadow subtracted DEPTH_BIAS; the receiver itself lies at zf + DEPTH_BIAS.
    dr = texture.frustum.view_depth(np.asarray(zf, np.float64) + DEPTH_BIAS)
    return soft_shadow(texture, uv, zf, receiver_depth=dr, dtype=np.float32)


#: Moment soft shadow mapping: four uint32 SAT channels = 128 bits per texel.
MSM_SOFT = register(Technique(
    name="msm_soft", bits_per_texel=128, depth_bias=DEPTH_BIAS, make_steps=_steps, lookup=_lookup,
    description="moment soft shadow mapping: uint32 summed-area table of optimized moments, moment-based "
                "blocker search, PCSS penumbra, one interpolated query, Algorithm 1",
    reference="Peters et al. 2017 (JCGT); Slides, 'Moment soft shadow mapping'",
    four_moments=True, light_kinds=("area",),
))
