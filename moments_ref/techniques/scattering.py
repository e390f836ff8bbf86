"""Prefiltered single scattering with six moments (Slides, "Prefiltered single scattering").

Single scattering of a directional light in a homogeneous participating medium
(the setting the slides restrict to) needs, per pixel, the integral of the
light's visibility along the view ray,

    S(pixel) = ∫_0^{t_end} V(eye + t·ω_p) dt,

(in-scattered radiance = σ_s · phase(ω_l·ω_p) · E · S; the constant factors
are left out, and so is extinction along the view ray: with it the integrand's
weight would depend on the ray's inclination and prefix sums along rows could not
represent it). ``t_end`` is the distance to the surface the pixel sees, or
:attr:`EpipolarFrame.t_max` (the farthest corner of the scene's bounding box) for
background pixels.

Klehm et al. 2014: ray marching is percentage-closer filtering with the view ray
as kernel, so a filterable shadow map can be prefiltered along view rays. The
slides do it with six moments, in five steps:

1. **Epipolar resampling** (Slides, "Resampling using epipolar geometry"). Put the
   camera at the origin and the light direction ω_l on the z axis; a point with
   cylindrical radius ρ (distance from the light axis through the camera),
   azimuth φ and offset ``a`` along ω_l has inclination ``θ = atan2(ρ, a)``
   (the angle between ω_l and the direction from the camera). The new map has
   rows = φ (``v = φ``), columns = ρ (``u = r``: the radius of the polar
   coordinates of the shadow-map plane around the camera) and depth
   ``z' = π − θ``, stored normalized to [-1, 1] as ``z = 2z'/π − 1 = 1 − 2θ/π``.
   Each texel is one light ray; a view ray (fixed φ_p, θ_p) crosses the light
   rays ρ ∈ [0, t_end·sin θ_p] of its row, uniformly (``dt = dρ / sin θ_p``),
   and the point where it crosses light ray ρ is shadowed iff
   ``z_p > z_occ(ρ)`` (a point deeper along the light has a smaller
   inclination). So ``S = t_end · (1 − Z_row(z < z_p))`` with ``Z_row`` the
   distribution of the texel depths of the row prefix ``[0, ρ_end]``: "View rays
   are rows", the left column is the camera.

   *Without filtering* (Slides, "Resampling without filtering"): convert
   coordinates, sample the depth map (nearest texel, one sample, no filtering),
   convert the depth, six moments of that one depth. Aliased.

   *With filtering* (Slides, "Resampling with filtering"): sample the filtered
   four-moment map (:mod:`moments_ref.filtering`: MSAA resolve and the 9×9
   Gaussian, bilinear lookup), drop b4 and represent b1..b3 by two depths
   (HPG17 Algorithm 2, ``y1, y2, v2``), convert both depths, and combine
   ``(1 − v2)·b(z1) + v2·b(z2)`` (six moments each).

2. **Quantization** (Slides, "6 moments: 2×R10G10B10A2"): the optimized
   six-moment basis in 10-bit UNORM (:func:`moments_ref.affine.encode_r10g10b10a2`).
3. **Prefix sums along rows** (Slides, "Prefix sums along rows"), normalized to
   avoid overflow: texel k stores the *mean* of texels 0..k (a convex
   combination, so it stays a moment vector and fits the same UNORM format).
4. **Deferred pass** (Slides, "Deferred pass for single scattering"): per pixel
   two texture lookups (one per R10G10B10A2 texture) at row φ_p and column
   ρ_end; the column coordinate is warped so that the hardware's linear filter
   between prefix means k−1 and k returns exactly the mean over ``[0, ρ_end]``
   (see :func:`prefix_lookup_coordinate`). Six-moment bounds
   (:mod:`moments_ref.msm6`) of ``Z(z < z_p)``, biased with
   :data:`moments_ref.msm6.BIAS6_UNORM10`.
5. **Interpolation between the bounds** (Slides, "Interpolation between bounds",
   "Adaptive overestimation"): ``shadow = β·lower + (1 − β)·upper`` with
   ``β = (1 + ω_lᵀω_p)/2``, ω_l the normalized light direction, ω_p the
   normalized view ray direction (β = 0 looking into the light: always too dark
   rather than too bright).

Ground truth: ray marching through the MSAA shadow map (:func:`ray_march`), a
midpoint rule with N samples per view ray; the slides use N = 128 as "ground
truth", :func:`convergence` shows how far that is from N = 4096.

Conventions and clamps (documented, not errors):

* Depth-map texels at NDC depth ≥ :data:`FAR_NDC` (cleared to 1, or a two-depth
  reconstruction there) hold no occluder: depth +∞ along the light, ``z = 1``,
  never shadowing. The fitted light box leaves geometry below NDC 0.98.
* A view ray within :data:`AXIS_ANGLE` of the light axis (looking straight into
  the light or straight away from it: light direction parallel to the view
  direction, where the epipolar map degenerates because the inclination is
  constant along the light axis) has its inclination clamped to
  ``[AXIS_ANGLE, π − AXIS_ANGLE]``. The answer there is the first column's
  average, finite and in [0, t_end], with an error bounded by the column width
  (the map cannot resolve depth along the axis).
* Only directional lights: an area light raises :class:`InputError`.
* Receivers that are also occluders put their own depths right next to the
  end point of every view ray that ends on them (the ground under the light ray
  at ρ_end *is* the ray's end point), so the row distribution has much mass just
  above ``z_p`` and the upper bound (lower + w0) counts it: the six-moment
  analogue of surface acne. On the shipped scene with the ground as an occluder
  the RMSE of scattering_6m was 0.055 (worse than ignoring all shadows, 0.045);
  with the ground as receiver only, 0.018. The scene therefore makes the lowest
  surface a receiver only (it shadows no point of the medium above it).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from .._arrays import InputError, real_input
from ..affine import decode_r10g10b10a2, encode_r10g10b10a2, from_optimized6, unorm_to_float
from ..moments import bias_moments, power_moments
from ..msm import _two_point
from ..msm6 import BIAS6_UNORM10, shadow_bounds
from ..raster import project_points, rasterize_depth
from . import Step, Technique
from ._steps import moment_steps

__all__ = [
    "FAR_NDC",
    "AXIS_ANGLE",
    "EpipolarFrame",
    "epipolar_frame",
    "epipolar_coordinates",
    "epipolar_depth",
    "resample_unfiltered",
    "resample_filtered",
    "quantize6",
    "prefix_means",
    "prefix_lookup_coordinate",
    "deferred_shadow",
    "camera_rays",
    "ray_march",
    "convergence",
    "render",
    "report_rows",
    "SCATTERING_6M",
    "SCATTERING_6M_UNFILTERED",
    "SCATTERING_TECHNIQUES",
]

#: Depth-map values at or above this NDC depth hold no occluder (cleared far plane).
FAR_NDC = 0.999
#: View rays closer than this angle (radians) to the light axis are clamped (module docstring).
AXIS_ANGLE = 1e-4
#: Default epipolar map size (rows = azimuths, columns = radii).
EPIPOLAR_SIZE = (256, 512)


# ---------------------------------------------------------------------------
# geometry


@dataclass(frozen=True)
class EpipolarFrame:
    """The epipolar coordinate system of one camera position and one directional light.

    Attributes
    ----------
    eye : (3,) float64, the camera (origin)
    light : (3,) float64, unit light direction ω_l (the direction light travels), the z axis
    e1, e2 : (3,) float64, orthonormal, perpendicular to ω_l (azimuth φ = 0 along e1)
    rho_max : float, radius of the last column's far edge
    size : (rows, cols)
    t_max : float, ray length of background pixels
    """

    eye: np.ndarray
    light: np.ndarray
    e1: np.ndarray
    e2: np.ndarray
    rho_max: float
    size: tuple
    t_max: float


def _unit(v, name):
    v = real_input(v, name, dtype=np.float64).reshape(-1)
    if v.shape != (3,):
        raise InputError(f"{name}: expected 3 numbers, got shape {v.shape}")
    n = float(np.linalg.norm(v))
    if n == 0:
        raise InputError(f"{name}: expected a non-zero direction, got {v.tolist()}")
    return v / n


def epipolar_frame(eye, light_direction, rho_max, size=EPIPOLAR_SIZE, t_max=None):
    """Build the :class:`EpipolarFrame` (camera at the origin, ω_l on the z axis).

    Parameters
    ----------
    eye : (3,) float array
    light_direction : (3,) float array, non-zero (normalized here)
    rho_max : float > 0
        Largest distance from the light axis that a view ray reaches.
    size : (rows, cols), each ≥ 2
    t_max : float, optional
        Ray length for background pixels (default ``rho_max``).

    Notes
    -----
    e1, e2 by the branchless orthonormal basis of Duff et al. 2017 (no special
    case for any light direction, so no view direction makes the frame degenerate).
    """
    eye = real_input(eye, "eye", dtype=np.float64).reshape(-1)
    if eye.shape != (3,):
        raise InputError(f"eye: expected 3 numbers, got shape {eye.shape}")
    n = _unit(light_direction, "light_direction")
    try:
        rho_max = float(rho_max)
    except (TypeError, ValueError):
        raise InputError(f"rho_max: expected a positive number, got {rho_max!r}") from None
    if not (math.isfinite(rho_max) and rho_max > 0):
        raise InputError(f"rho_max: expected a positive finite number, got {rho_max!r}")
    try:
        rows, cols = (int(s) for s in size)
    except (TypeError, ValueError):
        raise InputError(f"size: expected (rows, cols), got {size!r}") from None
    if rows < 2 or cols < 2 or rows * cols > 1 << 26:
        raise InputError(f"size: expected rows, cols ≥ 2 and at most 2^26 texels, got {size!r}")
    sign = math.copysign(1.0, n[2])
    a = -1.0 / (sign + n[2])
    b = n[0] * n[1] * a
    e1 = np.array([1.0 + sign * n[0] * n[0] * a, sign * b, -sign * n[0]])
    e2 = np.array([b, sign + n[1] * n[1] * a, -n[1]])
    t_max = rho_max if t_max is None else float(t_max)
    return EpipolarFrame(eye, n, e1, e2, rho_max, (rows, cols), t_max)


def epipolar_coordinates(points, frame):
    """Spherical coordinates about the camera with ω_l as the z axis.

    Parameters
    ----------
    points : (..., 3) float array, world positions
    frame : EpipolarFrame

    Returns
    -------
    phi : (...) azimuth in [0, 2π)
    rho : (...) distance from the light axis through the camera (column coordinate)
    theta : (...) inclination in [0, π], the angle between ω_l and ``point − eye``
    a : (...) offset along ω_l (depth relative to the camera in the light's direction)
    """
    p = real_input(points, "points", trailing=3, dtype=np.float64) - frame.eye
    a = p @ frame.light
    x, y = p @ frame.e1, p @ frame.e2
    rho = np.hypot(x, y)
    phi = np.mod(np.arctan2(y, x), 2 * np.pi)
    theta = np.arctan2(rho, a)
    return phi, rho, theta, a


def epipolar_depth(theta):
    """Normalized epipolar depth ``z = 2(π − θ)/π − 1 = 1 − 2θ/π`` in [-1, 1] (Slides: z' = π − θ)."""
    return 1.0 - (2.0 / np.pi) * np.asarray(theta, dtype=np.float64)


def _texel_points(frame):
    """World points (rows, cols, 3) on the light rays through the epipolar texel centres, and ρ."""
    rows, cols = frame.size
    phi = 2 * np.pi * (np.arange(rows) + 0.5) / rows
    rho = frame.rho_max * (np.arange(cols) + 0.5) / cols
    d = np.cos(phi)[:, None] * frame.e1 + np.sin(phi)[:, None] * frame.e2  # (rows, 3)
    pts = frame.eye + rho[None, :, None] * d[:, None, :]
    return pts, np.broadcast_to(rho, (rows, cols))


def _light_offset(window_xy, ndc_depth, view_proj, size, frame):
    """Offset a along ω_l (relative to the eye) of shadow-map samples; +inf for no occluder."""
    h, w = size
    ndc = np.stack([window_xy[..., 0] * (2.0 / w) - 1, 1 - window_xy[..., 1] * (2.0 / h),
                    ndc_depth, np.ones_like(ndc_depth)], axis=-1)
    world = ndc @ np.linalg.inv(view_proj).T
    world = world[..., :3] / world[..., 3:4]
    a = (world - frame.eye) @ frame.light
    return np.where(ndc_depth >= FAR_NDC, np.inf, a)


def _depth_from_offset(rho, a):
    """Epipolar depth of an occluder at radius ρ and offset a along ω_l (a = +inf: z = 1)."""
    return epipolar_depth(np.arctan2(rho, a))


def resample_unfiltered(depth_samples, view_proj, frame):
    """Six moments of one depth per epipolar texel (Slides, "Resampling without filtering").

    Parameters
    ----------
    depth_samples : (H, W, S) float array
        The light's depth map (NDC depth in [-1, 1], cleared to 1).
    view_proj : (4, 4) float array
        The light's shadow-map matrix.
    frame : EpipolarFrame

    Returns
    -------
    b : (rows, cols, 6) float64
        ``b(z)`` of the converted depth of sample 0 of the nearest texel (no filtering).
    """
    d = np.asarray(depth_samples)
    h, w = d.shape[:2]
    pts, rho = _texel_points(frame)
    xy, _ = project_points(pts, view_proj, (h, w))
    col, row = np.floor(xy[..., 0]).astype(np.int64), np.floor(xy[..., 1]).astype(np.int64)
    inside = (col >= 0) & (col < w) & (row >= 0) & (row < h)
    depth = np.where(inside, d[np.clip(row, 0, h - 1), np.clip(col, 0, w - 1), 0], 1.0).astype(np.float64)
    centre = np.stack([col + 0.5, row + 0.5], axis=-1)
    z = _depth_from_offset(rho, _light_offset(centre, depth, view_proj, (h, w), frame))
    return power_moments(z[..., None], n=6)


def _two_depths(b):
    """HPG17 Algorithm 2 on b1..b3 (b4 dropped): depths y1, y2 and weight v2 (float64)."""
    b1, b2, b3 = b[..., 0], b[..., 1], b[..., 2]
    sigma2 = b2 - b1 * b1
    y1, y2, v2 = _two_point(b1, b2, b3, sigma2)
    single = sigma2 <= 8 * np.finfo(np.float64).eps * np.abs(b2)  # one depth: σ² is rounding
    y1 = np.where(single, b1, y1)
    y2 = np.where(single, b1, y2)
    v2 = np.where(single, 0.0, v2)
    return np.clip(y1, -1, 1), np.clip(y2, -1, 1), v2


def resample_filtered(moments4, view_proj, frame):
    """Six moments from the filtered four-moment map (Slides, "Resampling with filtering").

    Parameters
    ----------
    moments4 : (H, W, 4) float array
        The filtered moment shadow map (b1..b4 per texel, resolved and blurred).
    view_proj : (4, 4) float array
    frame : EpipolarFrame

    Returns
    -------
    b : (rows, cols, 6) float64
        ``(1 − v2)·b(z1) + v2·b(z2)`` where ``y1, y2, v2`` represent b1..b3 of the
        bilinearly filtered moments (HPG17 Algorithm 2) and ``z1, z2`` are their
        epipolar depths.
    """
    from . import bilinear_filtered

    m = np.asarray(moments4, dtype=np.float64)
    h, w = m.shape[:2]
    pts, rho = _texel_points(frame)
    xy, _ = project_points(pts, view_proj, (h, w))
    inside = (xy[..., 0] >= 0) & (xy[..., 0] <= w) & (xy[..., 1] >= 0) & (xy[..., 1] <= h)
    b = bilinear_filtered(m, xy, np.float64)
    y1, y2, v2 = _two_depths(b)
    y1 = np.where(inside, y1, 1.0)
    y2 = np.where(inside, y2, 1.0)
    z1 = _depth_from_offset(rho, _light_offset(xy, y1, view_proj, (h, w), frame))
    z2 = _depth_from_offset(rho, _light_offset(xy, y2, view_proj, (h, w), frame))
    z = np.stack([z1, z2], axis=-1)
    wt = np.stack([1 - v2, v2], axis=-1)
    return power_moments(z, wt, n=6)


def quantize6(b):
    """Store six moments in 2×R10G10B10A2_UNORM and read them back (float64)."""
    return decode_r10g10b10a2(encode_r10g10b10a2(b))


def prefix_means(b):
    """Normalized prefix sums along rows: texel k holds the mean of texels 0..k.

    Parameters
    ----------
    b : (rows, cols, C) float array

    Returns
    -------
    (rows, cols, C) float64
        ``P_k = (1/(k+1)) Σ_{j ≤ k} b_j`` (Slides, "Prefix sums along rows": "The sums
        should be normalized to avoid overflows"). Accumulated in float64.
    """
    b = np.asarray(b, dtype=np.float64)
    k = np.arange(1, b.shape[1] + 1, dtype=np.float64)
    return np.cumsum(b, axis=1) / k[None, :, None]


def prefix_lookup_coordinate(x, cols):
    """Column texture coordinate at which linear filtering of prefix means gives the mean over [0, x].

    Parameters
    ----------
    x : (...) float array
        End of the integration interval in texels (``ρ_end / rho_max · cols``).
    cols : int

    Returns
    -------
    u : (...) float64 texture coordinate (texel centres at k + 0.5)

    Notes
    -----
    For texels of constant value m_j, the mean over [0, x] with
    ``k = ⌊x⌋ ≥ 1`` is ``(k P_{k−1} + (x − k) m_k)/x = (1 − c) P_{k−1} + c P_k`` with
    ``c = (x − k)(k + 1)/x ∈ [0, 1]``: linear interpolation between the centres
    ``k − ½`` and ``k + ½``, i.e. ``u = k − ½ + c``. For ``x < 1`` it is ``P_0``.
    """
    x = np.clip(np.asarray(x, dtype=np.float64), 0, cols)
    k = np.minimum(np.floor(x), cols - 1)
    with np.errstate(divide="ignore", invalid="ignore"):
        c = np.where(x >= 1, (x - k) * (k + 1) / np.maximum(x, 1), 0.0)
    return np.where(x >= 1, k - 0.5 + c, 0.5)


def _bilinear_wrap_rows(tex, u, v):
    """Bilinear filtering, columns clamped, rows wrapped (the azimuth is periodic)."""
    rows, cols = tex.shape[:2]
    x = u - 0.5
    y = v - 0.5
    x0 = np.floor(x)
    y0 = np.floor(y)
    fx = (x - x0)[..., None]
    fy = (y - y0)[..., None]
    c0 = np.clip(x0, 0, cols - 1).astype(np.int64)
    c1 = np.clip(x0 + 1, 0, cols - 1).astype(np.int64)
    r0 = np.mod(y0, rows).astype(np.int64)
    r1 = np.mod(y0 + 1, rows).astype(np.int64)
    t = tex
    return ((1 - fy) * ((1 - fx) * t[r0, c0] + fx * t[r0, c1])
            + fy * ((1 - fx) * t[r1, c0] + fx * t[r1, c1]))


def deferred_shadow(texture, uv, depth, bounds=False, bias=BIAS6_UNORM10):
    """Shadowed fraction of view rays from the prefiltered six-moment map (deferred pass).

    Parameters
    ----------
    texture : (rows, cols, 2) uint32
        Prefix means in 2×R10G10B10A2 (:func:`quantize6` of :func:`prefix_means`).
    uv : (..., 2) float array
        ``u`` = ray end in columns (``ρ_end / rho_max · cols``, not yet warped),
        ``v`` = azimuth in rows (``φ_p / 2π · rows``).
    depth : (...) float array
        Epipolar depth of the view ray, ``1 − 2θ_p/π``.
    bounds : bool
        Also return the lower and upper bound.
    bias : BiasPreset
        Six-moment bias applied after decoding (default BIAS6_UNORM10).

    Returns
    -------
    shadow : (...) float32 in [0, 1]
        ``β·lower + (1 − β)·upper`` with ``β = (1 + cos θ_p)/2`` (Slides,
        "Adaptive overestimation").

    Notes
    -----
    Shader arithmetic in float32: decode UNORM, filter (one lookup per texture,
    warped column coordinate), inverse basis, BIAS6_UNORM10, six-moment bounds.
    """
    tex = np.asarray(texture)
    cols = tex.shape[1]
    uv = np.asarray(uv, dtype=np.float64)
    zf = np.asarray(depth, dtype=np.float64)
    u = prefix_lookup_coordinate(uv[..., 0], cols)
    shifts = np.array([0, 10, 20], dtype=np.uint32)
    codes = (tex[..., :, None] >> shifts) & np.uint32(0x3FF)  # (rows, cols, 2, 3)
    q = unorm_to_float(codes.reshape(tex.shape[:2] + (6,)).astype(np.uint16), 10, np.float32)
    qf = _bilinear_wrap_rows(q, u, uv[..., 1]).astype(np.float32)
    b = bias_moments(from_optimized6(qf), bias)
    lower, upper = shadow_bounds(b, zf.astype(np.float32))
    theta = (1 - zf) * (np.pi / 2)
    beta = ((1 + np.cos(theta)) / 2).astype(np.float32)
    shadow = np.clip(beta * lower + (1 - beta) * upper, 0, 1)
    return (shadow, lower, upper) if bounds else shadow


# ---------------------------------------------------------------------------
# the techniques (shared interface of moments_ref.techniques; not registered)


def _frame_params(params):
    try:
        return params["frame"], params["view_proj"]
    except (KeyError, TypeError):
        raise InputError("params: the scattering techniques need 'frame' (EpipolarFrame) and 'view_proj' "
                         "(the light's matrix); build them with moments_ref.techniques.scattering.render") from None


def _step_resample_filtered(m, params):
    frame, vp = _frame_params(params)
    return resample_filtered(m, vp, frame)


def _step_resample_unfiltered(d, params):
    frame, vp = _frame_params(params)
    return resample_unfiltered(d, vp, frame)


def _step_quantize(b, params):
    return quantize6(b)


def _step_prefix(b, params):
    return encode_r10g10b10a2(prefix_means(b))


def _steps_filtered(samples, layered):
    return moment_steps(samples, False) + (
        Step("scattering_resample_filtered", _step_resample_filtered),
        Step("scattering_filtered_quantize6", _step_quantize),
        Step("scattering_filtered_prefix_means", _step_prefix),
    )


def _steps_unfiltered(samples, layered):
    return (
        Step("scattering_resample_unfiltered", _step_resample_unfiltered),
        Step("scattering_unfiltered_quantize6", _step_quantize),
        Step("scattering_unfiltered_prefix_means", _step_prefix),
    )


def _lookup(texture, uv, zf, noise):
    return deferred_shadow(texture, uv, zf)


#: Filtered resampling (Slides, "Resampling with filtering"). ``shadow(texture, uv, depth)``
#: takes epipolar coordinates (see :func:`deferred_shadow`) and returns the shadowed
#: fraction of the view ray.
SCATTERING_6M = Technique(
    name="scattering_6m", bits_per_texel=64, depth_bias=0.0, make_steps=_steps_filtered, lookup=_lookup,
    description="prefiltered single scattering, 6 moments in 2×R10G10B10A2, filtered epipolar resampling",
    reference="Slides, 'Prefiltered single scattering with 6 moments'; Klehm et al. 2014",
    light_kinds=("directional",),
)
#: Unfiltered resampling (Slides, "Resampling without filtering"): aliased.
SCATTERING_6M_UNFILTERED = Technique(
    name="scattering_6m_unfiltered", bits_per_texel=64, depth_bias=0.0, make_steps=_steps_unfiltered,
    lookup=_lookup,
    description="prefiltered single scattering, 6 moments, epipolar resampling of the plain depth map",
    reference="Slides, 'Resampling without filtering'", light_kinds=("directional",),
)
SCATTERING_TECHNIQUES = {t.name: t for t in (SCATTERING_6M, SCATTERING_6M_UNFILTERED)}


# ---------------------------------------------------------------------------
# camera rays, ray marching, rendering


@dataclass
class CameraRays:
    """Per-pixel view rays: directions (H, W, 3) unit, ``t_end`` (H, W), hit mask (H, W)."""

    direction: np.ndarray
    t_end: np.ndarray
    hit: np.ndarray
    resolution: tuple


def camera_rays(scene, resolution=None, t_max=None):
    """View rays through the pixel centres and their lengths (depth buffer of all geometry).

    Parameters
    ----------
    scene : Scene
    resolution : (width, height), default the camera's
    t_max : float, optional
        Length of background rays; default the distance from the eye to the farthest
        corner of the scene's bounding box.

    Returns
    -------
    CameraRays, t_max
    """
    cam = scene.camera
    w, h = cam.resolution if resolution is None else (int(resolution[0]), int(resolution[1]))
    from ..scene.camera import Camera

    cam = Camera(cam.eye, cam.target, cam.up, cam.fov, (w, h), cam.near, cam.far)
    vp = cam.view_proj()
    verts = np.concatenate([scene.receiver.vertices, scene.occluder.vertices])
    tris = np.concatenate([scene.receiver.triangles, scene.occluder.triangles + scene.receiver.vertices.shape[0]])
    depth, _ = rasterize_depth(verts, tris, vp, (h, w), samples=1, dtype=np.float64)
    depth = depth[..., 0]
    col, row = np.meshgrid(np.arange(w) + 0.5, np.arange(h) + 0.5)
    xn, yn = col * (2.0 / w) - 1, 1 - row * (2.0 / h)
    inv = np.linalg.inv(vp)

    def unproject(zn):
        p = np.stack([xn, yn, np.broadcast_to(zn, xn.shape), np.ones_like(xn)], axis=-1) @ inv.T
        return p[..., :3] / p[..., 3:4]

    far_pt = unproject(0.0)
    d = far_pt - cam.eye
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    hit = depth < 1.0
    t_hit = np.linalg.norm(unproject(depth) - cam.eye, axis=-1)
    if t_max is None:
        lo, hi = scene.bounds()
        corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
        t_max = float(np.linalg.norm(corners - cam.eye, axis=1).max())
    t_end = np.where(hit, np.minimum(t_hit, t_max), t_max)
    return CameraRays(d, t_end, hit, (w, h)), t_max


def _check_directional(scene):
    if getattr(scene.light, "kind", None) != "directional":
        raise InputError(f"scene {scene.name!r}: single scattering needs a directional light "
                         f"(Slides, 'Integrate shadow along view ray'), got {getattr(scene.light, 'kind', '?')!r}")


def ray_march(depth_samples, view_proj, eye, rays, n_samples, chunk=1 << 21):
    """Visibility integral by ray marching through the shadow map (midpoint rule).

    Parameters
    ----------
    depth_samples : (H, W, S) float array
        The light's MSAA depth map (cleared to 1 = no occluder).
    view_proj : (4, 4) the light's matrix
    eye : (3,) camera position
    rays : CameraRays
    n_samples : int ≥ 1
        Samples per view ray, at ``t_k = (k + ½) t_end / N``.

    Returns
    -------
    S : (H, W) float64, ``t_end · mean_k V(t_k)``; V is the share of the MSAA samples of
        the nearest texel that do not occlude the point (1 outside the map).
    """
    if not isinstance(n_samples, (int, np.integer)) or n_samples < 1:
        raise InputError(f"n_samples: expected a positive integer, got {n_samples!r}")
    d = np.asarray(depth_samples)
    h, w, s = d.shape
    flat = d.reshape(h * w, s)
    dirs = rays.direction.reshape(-1, 3)
    t_end = rays.t_end.reshape(-1)
    out = np.empty(t_end.shape[0])
    frac = (np.arange(n_samples) + 0.5) / n_samples
    m = np.asarray(view_proj, dtype=np.float64)
    per = max(1, chunk // n_samples)
    for lo in range(0, t_end.shape[0], per):
        hi = min(lo + per, t_end.shape[0])
        t = t_end[lo:hi, None] * frac[None, :]
        p = np.asarray(eye, dtype=np.float64) + t[..., None] * dirs[lo:hi, None, :]
        clip = p @ m[:3, :3].T + m[:3, 3]  # orthographic: w = 1
        x = (clip[..., 0] + 1) * (w / 2)
        y = (1 - clip[..., 1]) * (h / 2)
        col, row = np.floor(x).astype(np.int64), np.floor(y).astype(np.int64)
        inside = (col >= 0) & (col < w) & (row >= 0) & (row < h)
        idx = np.clip(row, 0, h - 1) * w + np.clip(col, 0, w - 1)
        occ = flat[idx]  # (n, N, S)
        vis = ((occ >= clip[..., 2:3]) | (occ >= FAR_NDC)).mean(axis=-1)
        vis = np.where(inside, vis, 1.0)
        out[lo:hi] = t_end[lo:hi] * vis.mean(axis=-1)
    return out.reshape(rays.t_end.shape)


def _pixel_epipolar(rays, frame):
    """uv (columns, rows) and depth of every pixel's view ray; inclination clamped near the axis."""
    rows, cols = frame.size
    d = rays.direction
    cos_t = np.clip(d @ frame.light, -1, 1)
    theta = np.clip(np.arccos(cos_t), AXIS_ANGLE, np.pi - AXIS_ANGLE)
    phi = np.mod(np.arctan2(d @ frame.e2, d @ frame.e1), 2 * np.pi)
    rho_end = rays.t_end * np.sin(theta)
    uv = np.stack([rho_end / frame.rho_max * cols, phi / (2 * np.pi) * rows], axis=-1)
    return uv, epipolar_depth(theta)


def render(scene, technique="scattering_6m", *, shadow_map_size=None, msaa=None, resolution=None,
           epipolar_size=None, shadow_map=None, rays=None):
    """Render the scattering term of a scene with a six-moment technique.

    Parameters
    ----------
    scene : Scene with a directional light
    technique : "scattering_6m", "scattering_6m_unfiltered" or a Technique
    shadow_map_size, msaa, resolution, epipolar_size : overrides of the scene's
        settings (``epipolar_size`` also from ``scene.params['epipolar_size']``)
    shadow_map : (depth (H, W, S), view_proj), optional, reuse a rasterized map
    rays : (CameraRays, t_max), optional, reuse camera rays

    Returns
    -------
    dict with ``scattering`` (H, W) float64 (``t_end · (1 − shadow)``), ``shadow``,
    ``lower``, ``upper`` (shadowed fractions), ``texture``, ``frame``,
    ``texel_seconds``, ``fragment_seconds``.
    """
    _check_directional(scene)
    tech = SCATTERING_TECHNIQUES.get(technique, technique) if isinstance(technique, str) else technique
    if not isinstance(tech, Technique) or tech.name not in SCATTERING_TECHNIQUES:
        raise InputError(f"technique: expected one of {', '.join(SCATTERING_TECHNIQUES)}, got {technique!r}")
    depth, vp, cam_rays, t_max = _scene_inputs(scene, shadow_map, shadow_map_size, msaa, rays, resolution)
    size = epipolar_size or scene.params.get("epipolar_size", EPIPOLAR_SIZE)
    rho_end = cam_rays.t_end * np.sqrt(np.maximum(0, 1 - np.clip(cam_rays.direction @ scene.light.direction, -1, 1) ** 2))
    frame = epipolar_frame(scene.camera.eye, scene.light.direction, max(float(rho_end.max()) * 1.001, 1e-6),
                           tuple(size), t_max)
    t0 = time.perf_counter()
    texture = tech.prepare(depth, {"frame": frame, "view_proj": vp})
    t1 = time.perf_counter()
    uv, z = _pixel_epipolar(cam_rays, frame)
    shadow, lower, upper = deferred_shadow(texture, uv, z, bounds=True)
    t2 = time.perf_counter()
    scat = cam_rays.t_end * (1 - shadow.astype(np.float64))
    return {"scattering": scat, "shadow": shadow, "lower": lower, "upper": upper, "texture": texture,
            "frame": frame, "texel_seconds": t1 - t0, "fragment_seconds": t2 - t1, "t_max": t_max}


def _scene_inputs(scene, shadow_map, shadow_map_size, msaa, rays, resolution):
    """The light's depth map and matrix and the camera rays: given ones, or rendered from ``scene``."""
    if shadow_map is None:
        vp = scene.shadow_view_proj()
        depth, _ = scene.shadow_map(size=shadow_map_size, samples=msaa)
    else:
        depth, vp = shadow_map
    cam_rays, t_max = camera_rays(scene, resolution) if rays is None else rays
    return depth, vp, cam_rays, t_max


def convergence(scene, counts=(16, 32, 64, 128, 256, 512), reference=4096, *, shadow_map_size=None, msaa=None,
                resolution=None, shadow_map=None, rays=None):
    """RMSE of ray marching with ``counts`` samples against ``reference`` samples.

    Returns
    -------
    dict count -> RMSE of ``S / t_max`` over all pixels, and the reference image under
    key ``"reference_image"`` (``S``, (H, W)).
    """
    _check_directional(scene)
    depth, vp, cam_rays, t_max = _scene_inputs(scene, shadow_map, shadow_map_size, msaa, rays, resolution)
    ref = ray_march(depth, vp, scene.camera.eye, cam_rays, int(reference))
    out = {"reference_image": ref}
    for n in counts:
        img = ray_march(depth, vp, scene.camera.eye, cam_rays, int(n))
        out[int(n)] = float(np.sqrt(np.mean(((img - ref) / t_max) ** 2)))
    return out


def _metrics(img, ref, t_max):
    e = (np.asarray(img) - np.asarray(ref)) / t_max  # normalized scattering: 1 = a fully lit ray of t_max
    a = np.abs(e)
    return {"rmse": float(np.sqrt(np.mean(e * e))), "max_error": float(a.max()),
            "p99_error": float(np.percentile(a, 99)),
            # leaking light: scattering brighter than the reference by more than 0.05
            "leak_fraction": float(np.mean(e > 0.05))}


def _ldr(img, t_max):
    x = np.clip(np.asarray(img, dtype=np.float64) / t_max, 0, 1)
    return np.repeat(x[..., None], 3, axis=2).astype(np.float32)


def report_rows(scene, *, shadow_map_size=None, msaa=None, resolution=None, epipolar_size=None,
                reference_samples=None, raymarch_samples=None, out_dir=None):
    """Rows for results.csv: ``scattering_6m``, ``scattering_6m_unfiltered`` and ``raymarch``.

    Error of the scattering term normalized by ``t_max`` (so 1 is a fully lit ray of
    maximal length) against ray marching with ``reference_samples`` per ray (default
    ``scene.params['reference_samples']`` or 4096); ``raymarch`` is the slides' ray
    marching with ``raymarch_samples`` (default 128). Columns as
    :data:`moments_ref.report.COLUMNS`; ``flip_mean`` compares LDR images of the
    normalized scattering term (NaN without flip-evaluator).

    Returns
    -------
    rows : list of dict
    images : dict name -> (H, W) scattering term (``reference`` included)

    With ``out_dir`` the images are written as ``scattering_<scene>.png``.
    """
    _check_directional(scene)
    params = scene.params or {}
    ref_n = int(reference_samples or params.get("reference_samples", 4096))
    rm_n = int(raymarch_samples or params.get("raymarch_samples", 128))
    vp = scene.shadow_view_proj()
    t0 = time.perf_counter()
    depth, _ = scene.shadow_map(size=shadow_map_size, samples=msaa)
    raster_seconds = time.perf_counter() - t0
    rays = camera_rays(scene, resolution)
    cam_rays, t_max = rays
    ref = ray_march(depth, vp, scene.camera.eye, cam_rays, ref_n)
    images = {"reference": ref}
    rows = []
    try:
        from ..report import flip_mean
    except ImportError:  # pragma: no cover - report is optional here
        flip_mean = None
    for name in ("scattering_6m", "scattering_6m_unfiltered"):
        r = render(scene, name, resolution=resolution, epipolar_size=epipolar_size, shadow_map=(depth, vp), rays=rays)
        images[name] = r["scattering"]
        rows.append({"scene": scene.name, "technique": name, "bits_per_texel": 64,
                     **_metrics(r["scattering"], ref, t_max),
                     "flip_mean": flip_mean(_ldr(ref, t_max), _ldr(r["scattering"], t_max)) if flip_mean else math.nan,
                     "texel_seconds": raster_seconds + r["texel_seconds"],
                     "fragment_seconds": r["fragment_seconds"]})
    t0 = time.perf_counter()
    rm = ray_march(depth, vp, scene.camera.eye, cam_rays, rm_n)
    t1 = time.perf_counter()
    images["raymarch"] = rm
    rows.append({"scene": scene.name, "technique": "raymarch", "bits_per_texel": 32 * int(depth.shape[2]),
                 **_metrics(rm, ref, t_max),
                 "flip_mean": flip_mean(_ldr(ref, t_max), _ldr(rm, t_max)) if flip_mean else math.nan,
                 "texel_seconds": raster_seconds, "fragment_seconds": t1 - t0})
    if out_dir is not None:
        write_images(images, t_max, f"{out_dir}/scattering_{scene.name}.png")
    return rows, images


def write_images(images, t_max, path):
    """One figure with the normalized scattering term of each image (reference first)."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    from .._io import save_figure

    names = list(images)
    fig, axes = plt.subplots(1, len(names), figsize=(4 * len(names), 3), squeeze=False)
    for ax, name in zip(axes[0], names):
        ax.imshow(np.clip(images[name] / t_max, 0, 1), cmap="magma", vmin=0, vmax=1)
        ax.set_title(name)
        ax.axis("off")
    fig.tight_layout()
    save_figure(fig, path, dpi=100)
    plt.close(fig)
    return path
