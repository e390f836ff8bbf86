"""Legitimate float32 evaluations of the NLQ chain as a shader compiler may emit it: contracted and reassociated.

A shader compiler may contract ``a*b + c`` into one fused multiply-add and choose the
order of a sum unless the source marks the expression ``precise`` (GLSL 4.60 §4.7.1;
SPIR-V's ``NoContraction``): Mesa's NIR, behind both llvmpipe (GLSL) and lavapipe
(SPIR-V), fuses ``fmul``/``fadd`` pairs and reassociates inexact sums, and the two
drivers do not always choose alike. Two correct ports of the same chain then differ
by a rounding of each product that was or was not fused, and by the order of each sum.
:mod:`moments_ref.gpu.filter32` enumerates this for the filter (the taps, the MSAA
samples, the block); this module does it for the rest of the chain, the arithmetic of
HPG17 §3.2 and Algorithms 2 and 3 on one texel:

* :func:`bias_fused`: ``b (1 − α) + α b*`` with either product fused (HPG17 §3.2, Slides "Bias the moments");
* :func:`bias_lerp`: the same bias as an engine's ``lerp``/``mix`` may write it, ``b + α (b* − b)``, fused or not;
* :func:`phi_fused`: Algorithm 2 with every ``a b ± c`` fused (σ², q1, q0, the
  discriminant, ξ4 of Eq. (3));
* :func:`shade_fused`: Algorithm 3 with every ``a b ± c`` fused (P, q1/2, the
  root's ``h² + P``) and the three terms of ``w_l⁻¹`` (Peters and Klein 2015, Prop. 10)
  summed in a chosen order.

Each takes ``swapped``: where two products meet in one sum (``q0 = −b1 q1 − b2 q2``,
``q1² − 4 q2 q0``, ``(b4 − b2²) − L21² σ²``), the compiler may fuse either one;
``swapped=False`` fuses the first in source order and sums left to right,
``swapped=True`` fuses the other and sums right to left. A fused multiply-add is emulated
exactly: a product of two float32 numbers is exact in float64 and the sum is rounded
once more (to float64, then float32; the double rounding differs from one rounding only
on ties at 2⁻⁵³, which is itself a legitimate evaluation within half an ulp).

Float32 in, float32 out (this emulates a GPU port); degenerate rows of Φ (σ² ≤ 0, no
distinct roots) take the reference's values (:func:`moments_ref.nonlinear.phi`).

References
----------
.. [1] HPG17: Christoph Peters. 2017. *Non-Linearly Quantized Moment Shadow Maps*. In Proceedings
       of High Performance Graphics (HPG '17). ACM. The non-linear quantization Φ, Ψ4, Algorithms
       1–3, the texel formats and the compute shader of §4.1.
.. [2] Slides: Christoph Peters. *Rendering antialiased shadows with moment shadow mapping*,
       lecture slides (PDF version, with notes) on moment shadow mapping, translucent occluders,
       moment soft shadow mapping and prefiltered single scattering; http://MomentsInGraphics.de/.
       Cited by slide title, e.g. Slides, "Bias the moments".
.. [3] Peters and Klein 2015: Christoph Peters and Reinhard Klein. 2015. *Moment Shadow Mapping*.
       In Proceedings of the 19th ACM SIGGRAPH Symposium on Interactive 3D Graphics and Games (i3D
       '15). ACM, 7–14. https://doi.org/10.1145/2699276.2699277
"""

from __future__ import annotations

import numpy as np

from .._arrays import real_input
from ..moments import bias_preset
from ..nonlinear import SHADE_TOLERANCE, phi

__all__ = ["fma32", "bias_fused", "bias_lerp", "phi_fused", "shade_fused", "CONTRACTIONS"]

#: The contraction choices :func:`phi_fused` and :func:`shade_fused` enumerate (their ``swapped``).
CONTRACTIONS = (False, True)
_F32 = np.float32


def fma32(a, b, c):
    """``a·b + c`` rounded once to float32, as a GPU's ``fma`` (inputs float32; exact product in float64)."""
    return (np.asarray(a, np.float64) * np.asarray(b, np.float64) + np.asarray(c, np.float64)).astype(_F32)


def bias_fused(b, preset, swapped=False):
    """HPG17 §3.2's ``(1 − α) b + α b*`` with one product fused into the sum, float32 ``(..., 4)``.

    ``swapped=False``: ``fma(b, 1 − α, α b*)``; ``True``: ``fma(α, b*, (1 − α) b)``.
    """
    p = bias_preset(preset)
    b = np.asarray(b, _F32)
    alpha = _F32(p.alpha)
    target = np.asarray(p.target, _F32)
    if swapped:
        return fma32(alpha, target, (_F32(1) - alpha) * b)
    return fma32(b, _F32(1) - alpha, alpha * target)


def bias_lerp(b, preset, fused=False):
    """HPG17 §3.2's bias ``(1 − α) b + α b*`` written as a lerp, ``b + α (b* − b)`` (HLSL ``lerp``, one form of
    GLSL ``mix``), float32 ``(..., 4)``; ``fused``: ``fma(α, b* − b, b)``, as a compiler may contract it."""
    p = bias_preset(preset)
    b = np.asarray(b, _F32)
    alpha = _F32(p.alpha)
    d = np.asarray(p.target, _F32) - b
    return fma32(alpha, d, b) if fused else (b + alpha * d).astype(_F32)


def phi_fused(b, swapped=False):
    """HPG17 Algorithm 2 (steps as :func:`moments_ref.nonlinear.phi`) with every ``a b ± c`` fused, float32.

    Notes
    -----
    (1) σ² = fma(−b1, b1, b2); (2) q1 = fma(b1, b2, −b3); (3) q0 = −b1 q1 − b2 q2 with one
    of the two products fused; (4) the discriminant q1² − (4 q2) q0 likewise, the roots by
    the cancellation-free quadratic formula; (5) v2 = (b1 − y1)/(y2 − y1);
    (6)-(7) ξ4 = (b4 − b2²) − L21² σ², both subtractions fused (or b4 − L21² σ² first).
    """
    b = real_input(b, "b", trailing=4).astype(_F32)
    b1, b2, b3, b4 = (b[..., k] for k in range(4))
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        sigma2 = fma32(-b1, b1, b2)
        q1 = fma32(b1, b2, -b3)
        if swapped:
            q0 = fma32(-b2, sigma2, -(b1 * q1))
            d = fma32(q1, q1, -((_F32(4) * sigma2) * q0))
        else:
            q0 = fma32(-b1, q1, -(b2 * sigma2))
            d = fma32(-(_F32(4) * sigma2), q0, q1 * q1)
        d = np.sqrt(np.maximum(d, _F32(0)))
        t = _F32(-0.5) * (q1 + np.copysign(d, q1))
        ra, rb = t / sigma2, q0 / t
        y1, y2 = np.fmin(ra, rb), np.fmax(ra, rb)
        v2 = (b1 - y1) / (y2 - y1)
        l21 = q1 / sigma2
        l2s = l21 * l21
        if swapped:
            xi4 = fma32(-b2, b2, fma32(-l2s, sigma2, b4))
        else:
            xi4 = fma32(-l2s, sigma2, fma32(-b2, b2, b4))
    out = np.stack([y1, y2, v2, xi4], axis=-1)
    ok = (sigma2 > 0) & (y2 > y1) & np.isfinite(out).all(axis=-1)
    return np.where(ok[..., None], out, phi(b))


def _weight_terms(zl, v1, v2, xip, swapped):
    """``w_l⁻¹ = (1 − z_l)²/(1 − v2) + z_l²/v2 + (1 − z_l)² z_l²/ξ'4``, summed in the chosen order."""
    a = (_F32(1) - zl) * (_F32(1) - zl)
    z2 = zl * zl
    terms = [a / v1, (a * z2) / xip, z2 / v2]
    if swapped:
        return (terms[2] + terms[1]) + terms[0]
    return (terms[0] + terms[1]) + terms[2]


def shade_fused(r, zf, clamp=SHADE_TOLERANCE, swapped=False, case_test="stored"):
    """HPG17 Algorithm 3 (steps as :func:`moments_ref.nonlinear.shade`) with every ``a b ± c`` fused, float32.

    ``clamp``: the §3.4 offset; ``case_test``: ``"stored"`` (z_f > y2 on the stored y2) or
    ``"clamped"`` (on y2 raised to y1 + clamp first), as :func:`moments_ref.golden.variants.shade_reference`.

    Notes
    -----
    With z'f = (zf − y1)/(y2 − y1) and ξ'4 = ξ4/(y2 − y1)⁴ (HPG17 §3.4): P = ξ'4/((1 − v2) z'f),
    the denominator v2 − v2 z'f = fma(−v2, z'f, v2), q1/2 = (fma((v2 − z'f)/(v2 − v2 z'f), P, −1))/2,
    z_l = min(−s, P/s) with s = h + sign(h) √fma(h, h, P); z_l = z'f where zf > y2; the result
    w_l = 1/K or 1 − w_l, K summed by :func:`_weight_terms`.
    """
    r = real_input(r, "r", trailing=4).astype(_F32)
    zf = np.asarray(zf, _F32)
    c = _F32(clamp)
    y1, y2, v2, xi4 = (r[..., k] for k in range(4))
    if case_test == "clamped":
        y2 = np.maximum(y2, y1 + c)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        v2 = np.clip(v2, c, _F32(1) - c)
        v1 = _F32(1) - v2
        gap = np.maximum(y2 - y1, c)
        zp = np.maximum(zf - y1, _F32(0)) / gap
        g2 = gap * gap
        xip = np.maximum(xi4 / (g2 * g2), np.finfo(_F32).tiny)
        p = np.minimum(xip / (v1 * zp), np.finfo(_F32).max)
        h = _F32(0.5) * fma32((v2 - zp) / fma32(-v2, zp, v2), p, _F32(-1))
        s = np.sqrt(fma32(h, h, p))
        s = np.copysign(s, h) + h
        zl = np.minimum(-s, p / s)
        above = zf > y2
        zl = np.where(above, zp, zl)
        w = np.minimum(_F32(1) / _weight_terms(zl, v1, v2, xip, swapped), _F32(1))
    return np.where(above, _F32(1) - w, w).astype(_F32)
