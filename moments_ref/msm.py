"""Moment shadow mapping: HPG17 Algorithm 1 (Peters and Klein 2015).

Given moments ``b = (b1, b2, b3, b4)`` of a depth distribution Z (b0 = 1) and a
fragment depth ``zf``, Algorithm 1 returns the sharp lower bound of ``Z(z < zf)``
over all distributions with these moments. The minimizing distribution has three
points of support ``zf, z1, z2`` (the *canonical representation*, HPG17 Fig. 2).

Implementation notes (why the code does not read like the algorithm box line by
line):

* Step (2) solves ``B(b) q = (1, zf, zf²)`` through the factorization
  ``B = L D Lᵀ`` (L unit lower triangular, ``D = diag(1, σ², ξ4)``), as the slides
  insist; the third pivot is HPG17's ξ4 (Eq. (3)).
* Step (3) uses the cancellation-free quadratic formula, so a leading coefficient
  ``q2 → 0`` (zf at a support point of the two-point representation) sends one
  root to ±inf instead of producing 0/0.
* Step (4) is replaced by HPG17 §3.4's ``w_l = 1 / ((1, z_l, z_l²) B⁻¹ (1, z_l, z_l²)ᵀ)``
  (Peters and Klein 2015, Prop. 10), evaluated as ``Σ (L⁻¹v)_i² / D_i``: it
  needs no Vandermonde solve, is exactly 0 for a root at infinity and is
  positive by construction. ``w2 = 1 − w0 − w1`` because b0 = 1. The mpmath twin
  in :mod:`moments_ref.precise` solves the Vandermonde system literally and
  serves as the independent check.

Degenerate input. When ``B(b)`` is singular the distribution with these moments
is unique and ``Z(z < zf)`` is known exactly; both bounds then return it:

* ``σ² = b2 − b1² ≤ τ·b2``: one depth at ``b1``;
* otherwise ``ξ4 ≤ τ·max(b4, σ²)``: the two-point distribution of HPG17
  Algorithm 2 (depths y1 < y2, weights 1 − v2, v2).

The relative threshold ``τ = SINGULAR_RTOL[dtype]·eps`` is ``8·eps`` in float64:
moments of one or two depths computed in float64 round to pivots of that size,
while biased moments (α ≥ 3e-7) lie nine orders of magnitude above it. In
float32 ``τ = 0``: ``BIAS_FLOAT32`` lifts ξ4 only to about
``α·λmin(B(b*)) ≈ 6e-8``, which is float32's own rounding of b4, so any positive
threshold would catch biased moments and replace the paper's bound by a hard step
at a *rounded* support point (measured: up to 0.96 above the true Z when zf lies
between the rounded and the true support point). float32 therefore takes the
singular branch only for pivots that are zero or negative.

Negative σ² or ξ4 (moments just outside the moment space after rounding)
fall into the same branches: they are projected onto the boundary of the moment
space, which keeps b1..b3 (or b1) and lowers b4 (or b2). Further outside the
result is that of the projection, not an error; bias the moments to stay inside.

Bounds. ``lower ≤ Z(z < zf) ≤ Z(z ≤ zf) ≤ upper``: the upper bound is
``lower + w0``, the largest mass a distribution with these moments can have at or
below zf. For a unique (singular) distribution both are attained.
"""

from __future__ import annotations

import numpy as np

from ._arrays import InputError, broadcast_pair, real_input

__all__ = [
    "shadow_intensity",
    "canonical_representation",
    "reduce_light_leaking",
    "SINGULAR_RTOL",
    "singular_thresholds",
]

#: Multiple of the dtype's machine epsilon below which B(b) counts as singular
#: (relative to b2 for σ², to max(b4, σ²) for ξ4); see the module docstring.
SINGULAR_RTOL = {"float32": 0.0, "float64": 8.0}

#: Texels per chunk in the vectorized kernels (keeps temporaries in L2 cache).
CHUNK = 1 << 14


def singular_thresholds(dtype):
    """The relative singularity threshold ``SINGULAR_RTOL[dtype]·eps`` of float32 or float64."""
    dt = np.dtype(dtype)
    return SINGULAR_RTOL[dt.name] * np.finfo(dt).eps


def _two_point(b1, b2, b3, sigma2):
    """Depths y1 ≤ y2 and weight v2 of the two-point distribution with moments b1..b3.

    HPG17 Algorithm 2, steps (1)–(5): roots of ``σ² z² + q1 z + q0`` with
    ``q1 = b1 b2 − b3`` and ``q0 = −b1 q1 − b2 σ²``; ``v2 = (b1 − y1)/(y2 − y1)``.
    """
    q1 = b1 * b2 - b3
    q0 = -b1 * q1 - b2 * sigma2
    disc = np.sqrt(np.maximum(q1 * q1 - 4 * sigma2 * q0, 0))
    t = -0.5 * (q1 + np.copysign(disc, q1))
    with np.errstate(divide="ignore", invalid="ignore"):
        ra = t / sigma2
        rb = q0 / t
    y1 = np.minimum(ra, rb)
    y2 = np.maximum(ra, rb)
    gap = y2 - y1
    with np.errstate(divide="ignore", invalid="ignore"):
        v2 = np.clip((b1 - y1) / gap, 0, 1)
    bad = ~np.isfinite(v2)
    if bad.any():  # no usable second depth: all mass at b1
        y1 = np.where(bad, b1, y1)
        y2 = np.where(bad, b1, y2)
        v2 = np.where(bad, 0, v2).astype(b1.dtype)
    return y1, y2, v2


def _kernel(b, zf, want):
    """Algorithm 1 on flat chunks: b (n, 4), zf (n,) -> dict of requested arrays.

    ``want`` is a set drawn from {"lower", "upper", "canonical"}.
    """
    dt = b.dtype.type
    b1, b2, b3, b4 = b[:, 0], b[:, 1], b[:, 2], b[:, 3]
    rtol = dt(singular_thresholds(b.dtype))
    # LDLᵀ of the Hankel matrix B(b): D = diag(1, σ², ξ4).
    sigma2 = b2 - b1 * b1
    single = sigma2 <= rtol * b2
    with np.errstate(divide="ignore", invalid="ignore"):
        l32 = (b3 - b1 * b2) / sigma2
        xi4 = b4 - b2 * b2 - l32 * l32 * sigma2
        two = ~single & (xi4 <= rtol * np.maximum(b4, sigma2))
        regular = ~(single | two)
        # Forward substitution L·y = (1, zf, zf²): y = (1, zf − b1, zf² − b2 − L32·y2).
        y2 = zf - b1
        y3 = zf * zf - b2 - l32 * y2
        # Scaling D·c = y, back substitution Lᵀ·q = c.
        q2 = y3 / xi4
        q1 = y2 / sigma2 - l32 * q2
        q0 = 1 - b1 * q1 - b2 * q2
        # Step (3): roots of q2 z² + q1 z + q0 without cancellation.
        disc = np.sqrt(np.maximum(q1 * q1 - 4 * q2 * q0, 0))
        t = -0.5 * (q1 + np.copysign(disc, q1))
        ra = t / q2
        rb = q0 / t
        z1 = np.fmin(ra, rb)
        z2 = np.fmax(ra, rb)
        # Step (4) via Prop. 10: 1/w_l = 1 + (L⁻¹v)_2²/σ² + (L⁻¹v)_3²/ξ4.
        w0 = 1 / (1 + y2 * y2 / sigma2 + y3 * y3 / xi4)
        u2 = z1 - b1
        u3 = z1 * z1 - b2 - l32 * u2
        w1 = 1 / (1 + u2 * u2 / sigma2 + u3 * u3 / xi4)
    w1 = np.where(np.isfinite(w1), w1, 0)
    w2 = 1 - w0 - w1
    out = {}
    if "lower" in want or "upper" in want:
        lower = np.where(zf <= z1, 0, np.where(zf <= z2, w1, 1 - w0))
    if not regular.all():
        # Singular B(b): the unique distribution, (1 − v2) δ_y1 + v2 δ_y2.
        s = ~regular
        ty1, ty2, tv2 = _two_point(b1[s], b2[s], b3[s], sigma2[s])
        is_single = single[s]
        ty1 = np.where(is_single, b1[s], ty1)
        ty2 = np.where(is_single, b1[s], ty2)
        tv2 = np.where(is_single, 0, tv2).astype(b.dtype)
        tv1 = 1 - tv2
        zs = zf[s]
        at1, at2 = ty1 == zs, ty2 == zs
        below1, below2 = ty1 < zs, ty2 < zs
        if "lower" in want or "upper" in want:
            lower[s] = tv1 * below1 + tv2 * below2
        z1 = z1.copy()
        z2 = z2.copy()
        z1[s], z2[s] = ty1, ty2
        w0[s] = tv1 * at1 + tv2 * at2
        w1[s] = np.where(at1, 0, tv1)
        w2[s] = np.where(at2, 0, tv2)
    if "lower" in want:
        out["lower"] = np.clip(lower, 0, 1)
    if "upper" in want:
        out["upper"] = np.clip(lower + w0, 0, 1)
    if "canonical" in want:
        out["depths"] = np.stack([zf, z1, z2], axis=-1)
        out["weights"] = np.stack([w0, w1, w2], axis=-1)
    return out


def _prepare(b, zf):
    b = real_input(b, "b", trailing=4)
    zf = real_input(zf, "zf", dtype=b.dtype)
    shape = broadcast_pair(b[..., 0], "b[..., 0]", zf, "zf")
    if b.shape[:-1] == shape:
        bflat = np.ascontiguousarray(b).reshape(-1, 4)
    else:
        bflat = np.ascontiguousarray(np.broadcast_to(b, shape + (4,))).reshape(-1, 4)
    zflat = np.broadcast_to(zf, shape).reshape(-1) if zf.shape != shape else np.ascontiguousarray(zf).reshape(-1)
    return bflat, zflat, shape


def _run(bflat, zflat, want, keys):
    n = zflat.size
    outs = {}
    for start in range(0, max(n, 1), CHUNK):
        stop = min(start + CHUNK, n)
        res = _kernel(bflat[start:stop], np.ascontiguousarray(zflat[start:stop]), want)
        for k in keys:
            if k not in outs:
                outs[k] = np.empty((n,) + res[k].shape[1:], dtype=bflat.dtype)
            outs[k][start:stop] = res[k]
    return outs


def shadow_intensity(b, zf, bound="lower"):
    """Sharp bound of the filtered shadow intensity Z(z < zf) from four moments.

    Parameters
    ----------
    b : (..., 4) float array
        Moments b1..b4 (b0 = 1 implicit), normally biased with
        :func:`moments_ref.moments.bias_moments`.
    zf : (...) float array
        Fragment depth, broadcast against ``b[..., 0]``; cast to b's dtype.
    bound : {"lower", "upper"}
        ``"lower"``: HPG17 Algorithm 1, the sharp lower bound of Z(z < zf).
        ``"upper"``: the lower bound plus w0, the sharp upper bound of Z(z ≤ zf).

    Returns
    -------
    intensity : (...) float array in [0, 1], dtype of ``b`` (per the dtype policy)

    Notes
    -----
    HPG17 Algorithm 1 / Peters and Klein 2015. With the canonical representation
    ``(zf, z1, z2; w0, w1, w2)``, ``lower = Σ_{z_l < zf} w_l``. Singular B(b) gives
    the exact Z of the unique distribution (see the module docstring for the
    thresholds). The result is clamped to [0, 1] like ``saturate`` in the slides.

    Examples
    --------
    Two equal depths at −0.5 and 0.5 (a two-point distribution, exact bound):

    >>> from moments_ref.moments import power_moments
    >>> b = power_moments([-0.5, 0.5])
    >>> shadow_intensity(b, [-0.6, 0.0, 0.6])
    array([0. , 0.5, 1. ])
    """
    if bound not in ("lower", "upper"):
        raise InputError(f"bound: expected 'lower' or 'upper', got {bound!r}")
    bflat, zflat, shape = _prepare(b, zf)
    out = _run(bflat, zflat, {bound}, (bound,))
    return out[bound].reshape(shape)


def canonical_representation(b, zf):
    """The three-point distribution attaining Algorithm 1's bounds (HPG17 Fig. 2).

    Parameters
    ----------
    b : (..., 4) float array
        Moments b1..b4.
    zf : (...) float array
        Fragment depth.

    Returns
    -------
    depths : (..., 3) float array
        ``(zf, z1, z2)`` with ``z1 ≤ z2`` the roots of step (3); a root may be
        ±inf when zf is a support point of the two-point representation (its
        weight is then 0).
    weights : (..., 3) float array
        ``(w0, w1, w2)``, non-negative, summing to 1, with
        ``Σ w_l (1, z_l, z_l²) = (1, b1, b2)``.

    Notes
    -----
    For singular B(b) the unique distribution is returned as ``(zf, y1, y2)`` with
    weights ``(mass at zf, 1 − v2, v2)`` (mass at a support point equal to zf is
    moved to w0, so that ``upper = lower + w0`` holds in every case).
    """
    bflat, zflat, shape = _prepare(b, zf)
    out = _run(bflat, zflat, {"canonical"}, ("depths", "weights"))
    return out["depths"].reshape(shape + (3,)), out["weights"].reshape(shape + (3,))


def reduce_light_leaking(intensity, factor=0.98):
    """Divide a shadow intensity by ``factor`` and clamp to [0, 1].

    Slides, "Compute the shadow intensity": "divide by ~98% to diminish remaining
    light leaking". Off unless called; it trades weak leaks for slight
    overestimation of the shadow, so the result is no longer a lower bound.
    """
    x = real_input(intensity, "intensity")
    if not (0.0 < float(factor) <= 1.0):
        raise InputError(f"factor: expected a value in (0, 1], got {factor!r}")
    return np.clip(x / x.dtype.type(factor), 0, 1)
