"""Moment soft shadow mapping, the method: frustum, summed-area table of moments, blocker search, filtering.

See :mod:`moments_ref.techniques.msm_soft` for the derivation (Slides, "Moment
soft shadow mapping"; "Moment-based blocker search"; "Penumbra estimation and
filtering").

References
----------
.. [1] Slides: Christoph Peters. *Rendering antialiased shadows with moment shadow mapping*,
       lecture slides (PDF version, with notes) on moment shadow mapping, translucent occluders,
       moment soft shadow mapping and prefiltered single scattering; http://MomentsInGraphics.de/.
       Cited by slide title, e.g. Slides, "Bias the moments".
.. [2] HPG17: Christoph Peters. 2017. *Non-Linearly Quantized Moment Shadow Maps*. In Proceedings
       of High Performance Graphics (HPG '17). ACM. The non-linear quantization Φ, Ψ4, Algorithms
       1–3, the texel formats and the compute shader of §4.1.
.. [3] Fernando 2005: Randima Fernando. 2005. *Percentage-Closer Soft Shadows*. In ACM SIGGRAPH
       2005 Sketches. https://doi.org/10.1145/1187112.1187153 (PCSS)
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..._arrays import InputError, real_input
from ..._docs import fill_doc
from ...affine import from_optimized, to_optimized
from ...gpu.filtering import resolve_moments
from ...moments import BIAS_FLOAT32, BIAS_UNORM16, BiasPreset, bias_moments
from ...msm import canonical_representation, shadow_intensity
from ..._shim import alias, renamed_keywords
from ...scene.depth import d_view_from_ndc, z_ndc_from_view
from ...scene.raster import project_points
from ...gpu import sat as _sat

__all__ = ["EPSILON", "MAX_AUTO_KERNEL", "DEPTH_BIAS", "soft_bias", "LightFrustum", "SoftShadowMap", "prepare",
           "prepare_moments", "average_blocker_depth", "penumbra_width", "soft_shadow", "shade_points",
           "precision_bits_text"]


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
        (:func:`moments_ref.gpu.sat.code_scale`), target ``(0, 0.628, 0, 0.628)``.

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
    @renamed_keywords(view_proj="clip_from_world")
    def from_matrix(cls, light, clip_from_world, size):
        """Read near, far and field of view back from ``projection @ look_at`` (OpenGL).

        Raises :class:`InputError` for a matrix that is not a symmetric
        perspective view along the light's normal.
        """
        for attr in ("normal", "width", "height", "tangent", "bitangent"):
            if not hasattr(light, attr):
                raise InputError(f"light: expected a rectangular area light (moments_ref.scene.AreaLight), "
                                 f"got {type(light).__name__}")
        m = real_input(clip_from_world, "clip_from_world", dtype=np.float64)
        if m.shape != (4, 4):
            raise InputError(f"clip_from_world: expected a (4, 4) matrix, got shape {m.shape}")
        fwd = m[3, :3]  # w_clip = distance along the viewing direction
        ok = abs(np.linalg.norm(fwd) - 1) < 1e-9 and np.dot(fwd, light.normal) > 1 - 1e-9
        sx, sy = m[0, :3], m[1, :3]
        px, py = np.linalg.norm(sx), np.linalg.norm(sy)
        ok = ok and px > 0 and py > 0 and abs(np.dot(sx, fwd)) < 1e-9 * px and abs(np.dot(sy, fwd)) < 1e-9 * py
        a = -np.dot(m[2, :3], fwd)
        b = m[2, 3] + a * m[3, 3]
        near, far = (b / (a - 1), b / (a + 1)) if ok and a not in (1, -1) else (np.nan, np.nan)
        if not (ok and np.isfinite(near) and np.isfinite(far) and 0 < near < far):
            raise InputError("clip_from_world: expected a symmetric perspective view from the light along its normal "
                             "(Scene.light_clip_from_world() or LightSamples.center_clip_from_world())")
        ux, uy = sx / px, sy / py
        ext = (abs(light.tangent @ ux) * light.width + abs(light.bitangent @ ux) * light.height,
               abs(light.tangent @ uy) * light.width + abs(light.bitangent @ uy) * light.height)
        h, w = int(size[0]), int(size[1])
        return cls(near=float(near), far=float(far), tan_half_fov=(1 / px, 1 / py), size=(h, w),
                   extent=(float(ext[0]), float(ext[1])))

    #: Old name (DeprecationWarning).
    from_view_proj = alias("from_matrix")

    def d_view_from_ndc(self, z_ndc):
        """View distance (world units along the normal) of the map's NDC depth (:func:`~moments_ref.scene.depth.d_view_from_ndc`)."""
        return d_view_from_ndc(z_ndc, self.near, self.far)

    def z_ndc_from_view(self, d_view):
        """Inverse of :meth:`d_view_from_ndc` (float64)."""
        return z_ndc_from_view(d_view, self.near, self.far)

    def z_linear_from_ndc(self, z_ndc):
        """The map's NDC depth -> depth linear in the view distance on [−1, 1]: ``2 (d − n)/(f − n) − 1`` (float64).

        The NDC depth an orthographic map with the same near and far planes would
        store; NDC 1 (empty texel, far plane) stays 1, −1 (near plane) stays −1.
        """
        return z_ndc_from_view(self.d_view_from_ndc(z_ndc), self.near, self.far, "orthographic")

    def d_view_from_linear(self, z_linear):
        """Inverse of the linear remap: ``n + (z_linear + 1)(f − n)/2`` (float64)."""
        return d_view_from_ndc(z_linear, self.near, self.far, "orthographic")

    # Old names (DeprecationWarning): the NDC ones did not say which depth they return.
    view_depth = alias("d_view_from_ndc")
    ndc_depth = alias("z_ndc_from_view")
    linear_depth = alias("z_linear_from_ndc")
    linear_to_view = alias("d_view_from_linear")

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
        return self.frustum.z_linear_from_ndc(z) if self.depth == "linear" else z

    def d_view_from_stored(self, z_stored):
        """View distance (world units along the normal) of a stored depth (float64)."""
        z = np.asarray(z_stored, np.float64)
        return self.frustum.d_view_from_linear(z) if self.depth == "linear" else self.frustum.d_view_from_ndc(z)

    #: Old name (DeprecationWarning).
    view_depth = alias("d_view_from_stored")

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


@renamed_keywords(view_proj="clip_from_world")
def prepare_moments(moments, light, clip_from_world, max_kernel=None, depth="linear") -> SoftShadowMap:
    """Build the :class:`SoftShadowMap` from per-texel moments b1..b4.

    Parameters
    ----------
    moments : (H, W, 4) float array
        Moments of each texel's stored depths (resolved, unfiltered), of the
        depth named by ``depth``.
    light : AreaLight
    clip_from_world : (4, 4) float array
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
    fr = LightFrustum.from_matrix(light, clip_from_world, b.shape[:2])
    k = _check_kernel(max_kernel, fr)
    table = _sat.build(to_optimized(b), k * k)
    return SoftShadowMap(sat=table, frustum=fr, max_kernel=k, bias=soft_bias(k * k), depth=_check_depth(depth))


@renamed_keywords(view_proj="clip_from_world")
def prepare(depth_samples, light, clip_from_world, max_kernel=None, depth="linear") -> SoftShadowMap:
    """Resolve a shadow map to moments and build its summed-area table.

    Parameters
    ----------
    depth_samples : (H, W) or (H, W, S) float array
        NDC depths in [−1, 1] from the light's centre (1 = empty).
    light, clip_from_world, max_kernel, depth
        As :func:`prepare_moments`; with ``depth="linear"`` the samples are
        remapped to ``2 (d − n)/(f − n) − 1`` before their moments are taken.

    Returns
    -------
    SoftShadowMap
    """
    z = np.asarray(depth_samples)
    if z.ndim == 2:
        z = z[..., None]
    from ...gpu.filtering import check_depth_samples

    z = check_depth_samples(z).astype(np.float64)
    if _check_depth(depth) == "linear":
        fr = LightFrustum.from_matrix(light, clip_from_world, z.shape[:2])
        z = np.clip(fr.z_linear_from_ndc(z), -1.0, 1.0)
    return prepare_moments(resolve_moments(z), light, clip_from_world, max_kernel, depth)


@fill_doc
def average_blocker_depth(b, zf, epsilon=EPSILON):
    """Average depth of the blockers in front of ``zf`` from four moments.

    Parameters
    ----------
    %(b)s
        Biased: the moments of the search region.
    %(zf)s
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


@renamed_keywords(receiver_depth="d_view_receiver")
def soft_shadow(texture, uv, zf, d_view_receiver=None, dtype=np.float32, epsilon=EPSILON, details=False):
    """Shadow intensity of fragments by moment soft shadow mapping.

    Parameters
    ----------
    texture : SoftShadowMap
    uv : (..., 2) float array
        Texel coordinates of the fragments in the map (u = column, v = row).
    zf : (...) float array
        Fragment NDC depth, depth bias already subtracted (converted to the
        texture's stored depth here).
    d_view_receiver : (...) float array, optional
        The fragment's view distance ``d_r`` (world units along the light normal);
        default ``frustum.d_view_from_ndc(zf)``. (Old name ``receiver_depth``, deprecated.)
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
    dr = fr.d_view_from_ndc(zff) if d_view_receiver is None else np.broadcast_to(
        real_input(d_view_receiver, "d_view_receiver", dtype=np.float64, finite=False), shape).reshape(-1)
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
    db = np.minimum(texture.d_view_from_stored(zb.astype(np.float64)), di)
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


def _resolve_source(source, clip_from_world):
    """(light, clip_from_world) from a Scene, a LightSamples or an AreaLight (+ clip_from_world)."""
    if hasattr(source, "center_clip_from_world") and hasattr(source, "light"):  # vwss.LightSamples
        return source.light, source.center_clip_from_world() if clip_from_world is None else clip_from_world
    if hasattr(source, "light_clip_from_world") and hasattr(source, "light"):  # scene.Scene
        return source.light, source.light_clip_from_world() if clip_from_world is None else clip_from_world
    if clip_from_world is None:
        raise InputError(f"clip_from_world: required with a light of type {type(source).__name__} "
                         "(or pass a Scene or vwss.LightSamples)")
    return source, clip_from_world


@renamed_keywords(view_proj="clip_from_world")
def shade_points(source, depth_map, points, *, clip_from_world=None, bias=None, max_kernel=None, dtype=np.float32,
                 details=False, depth="linear"):
    """Visibility of world points under a rectangular area light by moment soft shadow mapping.

    Parameters
    ----------
    source : Scene, vwss.LightSamples or AreaLight
        The light and the view of its centre's map (``Scene.light_clip_from_world()``,
        ``LightSamples.center_clip_from_world()``, or ``clip_from_world`` with a bare light).
    depth_map : (H, W) or (H, W, S) float array, or SoftShadowMap
        NDC depths of the occluders rasterized with that view (1 = empty), or
        an already prepared texture.
    points : (P, 3) float array
        World positions of the receivers (e.g. ``vwss.gbuffer(...).points``).
    clip_from_world : (4, 4) float array, optional
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
        (the convention of :func:`moments_ref.techniques.vwss.pcss`).
    """
    light, vp = _resolve_source(source, clip_from_world)
    if isinstance(depth_map, SoftShadowMap):
        tex = depth_map
    else:
        tex = prepare(depth_map, light, vp, max_kernel, depth)
    p = real_input(points, "points", trailing=3, dtype=np.float64)
    if p.ndim != 2:
        raise InputError(f"points: expected a (P, 3) array, got shape {p.shape}")
    fr = tex.frustum
    xy, _ = project_points(p, vp, fr.size)
    m = real_input(vp, "clip_from_world", dtype=np.float64)
    d_r = p @ m[3, :3] + m[3, 3]  # w_clip: distance along the light normal
    b = 0.002 * fr.far if bias is None else float(bias)
    with np.errstate(divide="ignore", invalid="ignore"):
        zf = np.where(d_r - b > 0, fr.z_ndc_from_view(d_r - b), np.nan)
    res = soft_shadow(tex, xy, zf, d_view_receiver=d_r, dtype=dtype, details=details)
    if details:
        return 1.0 - res[0], res[1]
    return 1.0 - res


def precision_bits_text(max_kernel) -> str:
    """``"22.5 bits, alpha = 6.7e-07"`` for a kernel side."""
    n = int(max_kernel) ** 2
    return f"{_sat.precision_bits(n):.1f} bits, alpha = {soft_bias(n).alpha:.2g}"
