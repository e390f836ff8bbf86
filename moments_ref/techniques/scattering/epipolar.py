"""Epipolar resampling and the prefiltered six-moment map (Slides, "Prefiltered single scattering").

Steps 1–4 of :mod:`moments_ref.techniques.scattering`: the epipolar frame of a
camera and a directional light, resampling (without and with filtering), the
2×R10G10B10A2 quantization, prefix means along rows and the deferred lookup
with six-moment bounds and the interpolation between them.

References
----------
.. [1] Slides: Christoph Peters. *Rendering antialiased shadows with moment shadow mapping*,
       lecture slides (PDF version, with notes) on moment shadow mapping, translucent occluders,
       moment soft shadow mapping and prefiltered single scattering; http://MomentsInGraphics.de/.
       Cited by slide title, e.g. Slides, "Bias the moments".
.. [2] Duff et al. 2017: Tom Duff, James Burgess, Per Christensen, Christophe Hery, Andrew Kensler,
       Max Liani and Ryusuke Villemin. 2017. *Building an Orthonormal Basis, Revisited*. Journal of
       Computer Graphics Techniques (JCGT) 6, 1, 1–8.
.. [3] HPG17: Christoph Peters. 2017. *Non-Linearly Quantized Moment Shadow Maps*. In Proceedings
       of High Performance Graphics (HPG '17). ACM. The non-linear quantization Φ, Ψ4, Algorithms
       1–3, the texel formats and the compute shader of §4.1.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..._arrays import InputError, real_input
from ..._shim import renamed_keywords
from ...affine import decode_r10g10b10a2, encode_r10g10b10a2, from_optimized6, unorm_to_float
from ...moments import bias_moments, power_moments
from ..._kernels import two_point
from ...msm6 import BIAS6_UNORM10, shadow_bounds
from ...scene.raster import project_points, unproject_points
from .._interface import bilinear_filtered

__all__ = ["FAR_NDC", "AXIS_ANGLE", "EPIPOLAR_SIZE", "EpipolarFrame", "epipolar_frame", "epipolar_coordinates",
           "epipolar_depth", "resample_unfiltered", "resample_filtered", "quantize6", "prefix_means",
           "prefix_lookup_coordinate", "deferred_shadow"]

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


def _light_offset(window_xy, ndc_depth, clip_from_world, size, frame):
    """Offset a along ω_l (relative to the eye) of shadow-map samples; +inf for no occluder."""
    world = unproject_points(window_xy, ndc_depth, clip_from_world, size)
    a = (world - frame.eye) @ frame.light
    return np.where(ndc_depth >= FAR_NDC, np.inf, a)


def _depth_from_offset(rho, a):
    """Epipolar depth of an occluder at radius ρ and offset a along ω_l (a = +inf: z = 1)."""
    return epipolar_depth(np.arctan2(rho, a))


@renamed_keywords(view_proj="clip_from_world")
def resample_unfiltered(depth_samples, clip_from_world, frame):
    """Six moments of one depth per epipolar texel (Slides, "Resampling without filtering").

    Parameters
    ----------
    depth_samples : (H, W, S) float array
        The light's depth map (NDC depth in [-1, 1], cleared to 1).
    clip_from_world : (4, 4) float array
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
    xy, _ = project_points(pts, clip_from_world, (h, w))
    col, row = np.floor(xy[..., 0]).astype(np.int64), np.floor(xy[..., 1]).astype(np.int64)
    inside = (col >= 0) & (col < w) & (row >= 0) & (row < h)
    depth = np.where(inside, d[np.clip(row, 0, h - 1), np.clip(col, 0, w - 1), 0], 1.0).astype(np.float64)
    centre = np.stack([col + 0.5, row + 0.5], axis=-1)
    z = _depth_from_offset(rho, _light_offset(centre, depth, clip_from_world, (h, w), frame))
    return power_moments(z[..., None], n=6)


def _two_depths(b):
    """HPG17 Algorithm 2 on b1..b3 (b4 dropped): depths y1, y2 and weight v2 (float64)."""
    b1, b2, b3 = b[..., 0], b[..., 1], b[..., 2]
    sigma2 = b2 - b1 * b1
    y1, y2, v2 = two_point(b1, b2, b3, sigma2)
    single = sigma2 <= 8 * np.finfo(np.float64).eps * np.abs(b2)  # one depth: σ² is rounding
    y1 = np.where(single, b1, y1)
    y2 = np.where(single, b1, y2)
    v2 = np.where(single, 0.0, v2)
    return np.clip(y1, -1, 1), np.clip(y2, -1, 1), v2


@renamed_keywords(view_proj="clip_from_world")
def resample_filtered(moments4, clip_from_world, frame):
    """Six moments from the filtered four-moment map (Slides, "Resampling with filtering").

    Parameters
    ----------
    moments4 : (H, W, 4) float array
        The filtered moment shadow map (b1..b4 per texel, resolved and blurred).
    clip_from_world : (4, 4) float array
    frame : EpipolarFrame

    Returns
    -------
    b : (rows, cols, 6) float64
        ``(1 − v2)·b(z1) + v2·b(z2)`` where ``y1, y2, v2`` represent b1..b3 of the
        bilinearly filtered moments (HPG17 Algorithm 2) and ``z1, z2`` are their
        epipolar depths.
    """
    m = np.asarray(moments4, dtype=np.float64)
    h, w = m.shape[:2]
    pts, rho = _texel_points(frame)
    xy, _ = project_points(pts, clip_from_world, (h, w))
    inside = (xy[..., 0] >= 0) & (xy[..., 0] <= w) & (xy[..., 1] >= 0) & (xy[..., 1] <= h)
    b = bilinear_filtered(m, xy, np.float64)
    y1, y2, v2 = _two_depths(b)
    y1 = np.where(inside, y1, 1.0)
    y2 = np.where(inside, y2, 1.0)
    z1 = _depth_from_offset(rho, _light_offset(xy, y1, clip_from_world, (h, w), frame))
    z2 = _depth_from_offset(rho, _light_offset(xy, y2, clip_from_world, (h, w), frame))
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
