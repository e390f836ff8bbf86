"""The papers' own formulations, run in a port's precision: legitimate variants of the spread model.

The reference computes Algorithm 1 with care (roots without cancellation, an exact
branch for singular B(b)). The code the papers print does not, and it is what the
engines ship: the slides' "Compute the shadow intensity" (Peters' demo code, as Unity
HDRP's ``HDIMS.hlsl`` and most public ports carry it) takes the roots as
``−p/2 ∓ √(p²/4 − q)`` and weighs the support points by the "Switch"/"Quotient"
formula. Run in float32 it is a legitimate implementation of the same equation: its
deviation on a row is part of the spread that sets the row's tolerance
(:mod:`moments_ref.golden.spread`). Where it has no finite value (singular B(b),
outside the contract) it contributes nothing. The same holds for Algorithm 3 as
HPG17 prints it (:func:`printed_shade`): its root ``−q1/2 − √(q1²/4 − q0)`` cancels as
zf approaches y2 from below (up to 6e-3 in float32), and at zf = y2 exactly it has no
value (q1 = ±∞), which a port must not return.

References
----------
.. [1] HPG17: Christoph Peters. 2017. *Non-Linearly Quantized Moment Shadow Maps*. In Proceedings
       of High Performance Graphics (HPG '17). ACM. The non-linear quantization Φ, Ψ4, Algorithms
       1–3, the texel formats and the compute shader of §4.1.
.. [2] Peters and Klein 2015: Christoph Peters and Reinhard Klein. 2015. *Moment Shadow Mapping*.
       In Proceedings of the 19th ACM SIGGRAPH Symposium on Interactive 3D Graphics and Games (i3D
       '15). ACM, 7–14. https://doi.org/10.1145/2699276.2699277
.. [3] Slides: Christoph Peters. *Rendering antialiased shadows with moment shadow mapping*,
       lecture slides (PDF version, with notes) on moment shadow mapping, translucent occluders,
       moment soft shadow mapping and prefiltered single scattering; http://MomentsInGraphics.de/.
       Cited by slide title, e.g. Slides, "Bias the moments".
"""

from __future__ import annotations

import numpy as np

__all__ = ["slides_bound", "printed_bound", "cholesky_bound", "alg1_paper_spread", "printed_shade", "alg3_paper_spread",
           "slides_envelope", "ENVELOPE_DRAWS"]


def slides_bound(b, zf, bound="lower", dtype=np.float32):
    """The slides' "Compute the shadow intensity", operation by operation in ``dtype``.

    ``bound="upper"`` adds the weight of the fragment depth, ``w0 = (z1 z2 − b1 (z1 + z2)
    + b2) / ((zf − z1)(zf − z2))``, computed from the same roots. Returns ``(n,)``
    in ``dtype``, saturated; NaN where the formula divides by zero (no ``saturate``
    is applied to NaN here, so that the caller can leave those rows out).
    """
    b = np.asarray(b).astype(dtype)
    z0 = np.asarray(zf).astype(dtype)
    with np.errstate(all="ignore"):
        return _slides_nudged(b, z0, bound, lambda x: x, None).astype(dtype)


#: Arrangements drawn by :func:`slides_envelope` (besides the code as written).
ENVELOPE_DRAWS = 256


def _slides_nudged(b, z0, bound, r, bias):
    """The slides' code in the dtype of ``b`` and ``z0``, each operation's result passed through ``r`` (the identity
    for :func:`slides_bound`; a one-ulp move for :func:`slides_envelope`), ``bias`` ``(α, b*)`` applied first."""
    t = b.dtype.type
    if bias is not None:  # the engine's own bias, (1 − α) b + α b*
        b = r(r(r(t(1) - t(bias[0])) * b) + r(t(bias[0]) * np.asarray(bias[1], t)))
    b0, b1, b2, b3 = (b[..., k] for k in range(4))
    l32d22, d22, var2 = r(r(-b0 * b1) + b2), r(r(-b0 * b0) + b1), r(r(-b1 * b1) + b3)
    d33d22 = r(r(var2 * d22) + r((-l32d22) * l32d22))
    inv_d22 = r(t(1) / d22)
    l32 = r(l32d22 * inv_d22)
    c1 = r(z0 - b0)
    c2 = r(r(z0 * z0) - r(b1 + r(l32 * c1)))
    c1 = r(c1 * inv_d22)
    c2 = r(c2 * r(d22 / d33d22))
    c1 = r(c1 - r(l32 * c2))
    c0 = r(t(1) - r(r(c1 * b0) + r(c2 * b1)))
    p, q = r(c1 / c2), r(c0 / c2)
    root = r(np.sqrt(r(r(r(p * p) * t(0.25)) - q)))
    z1, z2 = r(r(-p * t(0.5)) - root), r(r(-p * t(0.5)) + root)
    far = z2 < z0
    mid = ~far & (z1 < z0)
    s0 = np.where(far, z1, np.where(mid, z0, t(0)))
    s1 = np.where(far, z0, np.where(mid, z1, t(0)))
    out = np.where(far, t(1), t(0)) + np.where(far | mid, t(1), t(0)) * r(
        r(r(r(s0 * z2) - r(b0 * r(s0 + z2))) + b1) / r(r(z2 - s1) * r(z0 - z1)))
    if bound == "upper":
        out = out + r(r(r(r(z1 * z2) - r(b0 * r(z1 + z2))) + b1) / r(r(z0 - z1) * r(z0 - z2)))
    return np.where(np.isnan(out), out, np.clip(out, 0, 1))


def slides_envelope(b, zf, bound="lower", bias=None, draws=ENVELOPE_DRAWS, ref=None, cap=None):
    """``(lo, hi)`` of the slides' code in float32 over arrangements that round each operation differently.

    The code as written, and ``draws`` evaluations in which the float32 result of each operation is moved by
    −1, 0 or +1 ulp (a fixed table per operation, seeded, the same for every row, so that a row's envelope
    depends on that row alone): the rounding a compiler's reassociation, a reciprocal in place of a quotient
    or another order of a sum gives a formulation that cancels. ``bias``: ``(α, b*)`` applied first, as an
    engine biasing inside does. With ``ref`` and ``cap``, an arrangement counts on a row only within ``cap`` of
    ``ref`` there (the band model's rule for a legitimate evaluation: one that cancels beyond the cap explains
    nothing). float64 arrays, NaN where no arrangement counts. A diagnosis of the sweep
    (:func:`moments_ref.sweep.judge.envelope_rows`), not a band: the goldens and the sweep's bands do not hold
    it (docs/sweep.md, "Known gap").
    """
    b = np.asarray(b).astype(np.float32)
    z0 = np.asarray(zf).astype(np.float32)
    steps = np.random.default_rng(20171).integers(-1, 2, size=(draws, 96))
    lo = np.full(z0.shape, np.inf)
    hi = np.full(z0.shape, -np.inf)
    with np.errstate(all="ignore"):
        for row in [np.zeros(96, int)] + list(steps):
            k = iter(row)

            def r(x, k=k):
                d = next(k)
                x = np.asarray(x, np.float32)
                return x if d == 0 else np.nextafter(x, np.float32(np.inf if d > 0 else -np.inf))

            v = _slides_nudged(b, z0, bound, r, bias).astype(np.float64)
            if cap is not None:
                v = np.where(np.abs(v - ref) <= cap, v, np.nan)
            lo, hi = np.fmin(lo, v), np.fmax(hi, v)
    none = ~np.isfinite(lo)
    return np.where(none, np.nan, lo), np.where(none, np.nan, hi)


def printed_bound(b, zf, bound="lower", dtype=np.float32):
    """HPG17 Algorithm 1 as printed, operation by operation in ``dtype``: B(b) q = (1, zf, zf²) through
    B = L D Lᵀ, the roots of q2 z² + q1 z + q0 by the textbook formula, the weights of the Vandermonde
    system (step 4) in closed form, the sum of the weights of z_l < zf (upper: ≤), clipped to [0, 1] (the
    algorithm's bound is a probability). NaN where it divides by zero: a NaN is kept, never clipped."""
    t = np.dtype(dtype).type
    b = np.asarray(b).astype(dtype)
    z0 = np.asarray(zf).astype(dtype)
    b1, b2, b3, b4 = (b[..., k] for k in range(4))
    with np.errstate(all="ignore"):
        d22 = b2 - b1 * b1
        l32 = (b3 - b1 * b2) / d22
        d33 = (b4 - b2 * b2) - l32 * l32 * d22
        c1 = z0 - b1  # forward substitution L y = (1, zf, zf²)
        c2 = z0 * z0 - b2 - l32 * c1
        q2 = c2 / d33  # scaling and backward substitution
        q1 = c1 / d22 - l32 * q2
        q0 = t(1) - b1 * q1 - b2 * q2
        r = np.sqrt(q1 * q1 - t(4) * q2 * q0)
        z1 = (-q1 - r) / (t(2) * q2)
        z2 = (-q1 + r) / (t(2) * q2)
        z1, z2 = np.minimum(z1, z2), np.maximum(z1, z2)
        w0 = (z1 * z2 - b1 * (z1 + z2) + b2) / ((z0 - z1) * (z0 - z2))
        w1 = (z0 * z2 - b1 * (z0 + z2) + b2) / ((z1 - z0) * (z1 - z2))
        w2 = (z0 * z1 - b1 * (z0 + z1) + b2) / ((z2 - z0) * (z2 - z1))
        hit = (lambda z: z <= z0) if bound == "upper" else (lambda z: z < z0)
        out = np.where(hit(z1), w1, t(0)) + np.where(hit(z2), w2, t(0)) + (w0 if bound == "upper" else t(0))
        return np.where(np.isnan(out), out, np.clip(out, 0, 1)).astype(dtype)


def _fma(a, b, c, dt):
    """``a·b + c`` rounded once to ``dt`` (a fused multiply-add: the product of two float32 is exact in
    float64, the sum is rounded once more there, then to float32; the double rounding moves the result
    by at most one float32 ulp on a tie, within every band's floor)."""
    if dt == np.float64:
        return a * b + c
    return (a.astype(np.float64) * b.astype(np.float64) + c.astype(np.float64)).astype(dt)


def cholesky_bound(b, zf, bound="lower", dtype=np.float32, fma=False):
    """Algorithm 1 by the plain float32 Cholesky evaluation of Peters and Klein 2015, Prop. 10, as the
    shipped ports (``ports/glsl/msm.glsl``, ``.hlsl``, ``.wgsl``) and most engines run it.

    B = L D Lᵀ with D = diag(1, σ², ξ4); L y = (1, zf, zf²); q from D and Lᵀ; the roots of
    q2 z² + q1 z + q0 without cancellation; 1/w_l = 1 + u2²/σ² + u3²/ξ4 with (1, u2, u3) = L⁻¹(1, z_l, z_l²);
    lower = 0 (zf ≤ z1), w1 (z1 < zf ≤ z2), 1 − w0 (z2 < zf); upper = lower + w0; both clamped to [0, 1].
    Near singular texels (one or two depths after the float32 bias) its z2 lands within rounding of zf,
    on either side: both branches are legitimate there. ``fma=True`` contracts every ``a·b + c`` as a
    SPIR-V or HLSL compiler may. NaN where σ² ≤ 0 or ξ4 ≤ 0 (the ports' singular branches; outside the
    contract of biased moments).
    """
    t = np.dtype(dtype).type
    dt = np.dtype(dtype).type
    b = np.asarray(b).astype(dtype)
    zf = np.asarray(zf).astype(dtype)
    b1, b2, b3, b4 = (b[..., k] for k in range(4))
    mad = (lambda x, y, z: _fma(x, y, z, dt)) if fma else (lambda x, y, z: x * y + z)
    with np.errstate(all="ignore"):
        sigma2 = mad(-b1, b1, b2)
        l32 = mad(-b1, b2, b3) / sigma2
        xi4 = mad(-l32 * l32, sigma2, mad(-b2, b2, b4))
        y2 = zf - b1
        y3 = mad(zf, zf, -b2) - l32 * y2
        q2 = y3 / xi4
        q1 = mad(-l32, q2, y2 / sigma2)
        q0 = mad(-b2, q2, mad(-b1, q1, t(1)))
        disc = np.sqrt(np.maximum(mad(q1, q1, -t(4) * q2 * q0), t(0)))
        tt = t(-0.5) * (q1 + np.where(q1 < 0, -disc, disc))
        ra, rb = tt / q2, q0 / tt
        z1, z2 = np.minimum(ra, rb), np.maximum(ra, rb)
        w0 = t(1) / (t(1) + y2 * y2 / sigma2 + y3 * y3 / xi4)
        u2 = z1 - b1
        u3 = mad(z1, z1, -b2) - l32 * u2
        w1 = np.where(np.abs(z1) <= np.finfo(dtype).max, t(1) / (t(1) + u2 * u2 / sigma2 + u3 * u3 / xi4), t(0))
        low = np.where(zf <= z1, t(0), np.where(zf <= z2, w1, t(1) - w0))
        out = low + w0 if bound == "upper" else low
        out = np.clip(out, 0, 1)
        return np.where((sigma2 > 0) & (xi4 > 0), out, np.nan).astype(dtype)


def alg1_paper_spread(bound):
    """A ``spread_hook`` for Algorithm 1 cases: the slides' code and the printed algorithm in the port's
    precision."""

    def printed(inputs, dt):
        return [(slides_bound(inputs["b"], inputs["zf"], bound, dt),),
                (printed_bound(inputs["b"], inputs["zf"], bound, dt),)]

    def hook(inputs, dt):
        return printed(inputs, dt) + [(cholesky_bound(inputs["b"], inputs["zf"], bound, dt),),
                                      (cholesky_bound(inputs["b"], inputs["zf"], bound, dt, fma=True),)]

    hook.printed = printed  # the papers' own code alone (the sweep's hazard diagnosis), not the shipped Cholesky
    return hook


def printed_shade(r, zf, dtype=np.float32, clamp=1e-6, case_test="stored"):
    """HPG17 Algorithm 3 as printed, with its §3.4 clamps, operation by operation in ``dtype``.

    ``case_test``: ``"stored"`` tests ``zf <= y2`` on the stored y2 (the reference's
    reading), ``"clamped"`` tests ``z'f < 1`` on the clamped gap (the author's demo
    code). NaN where the printed formula has no value (zf = y2 with the stored test,
    ξ4 = 0); nothing is saturated.
    """
    t = np.dtype(dtype).type
    r = np.asarray(r).astype(dtype)
    zf = np.asarray(zf).astype(dtype)
    y1, y2, v2, xi4 = (r[..., k] for k in range(4))
    eps = t(clamp)
    with np.errstate(all="ignore"):
        v2 = np.minimum(np.maximum(v2, eps), t(1) - eps)
        gap = np.maximum(y2 - y1, eps)
        zp = (zf - y1) / gap
        g2 = gap * gap
        xip = xi4 / (g2 * g2)
        inside = (zf <= y2) if case_test == "stored" else (zp < 1)
        q0 = -xip / ((t(1) - v2) * zp)
        q1 = -q0 * (v2 - zp) / (v2 - v2 * zp) - t(1)
        zl = np.where(inside, -q1 / t(2) - np.sqrt(q1 * q1 / t(4) - q0), zp)
        a = (t(1) - zl) * (t(1) - zl)
        wl = t(1) / (a / (t(1) - v2) + zl * zl / v2 + a * zl * zl / xip)
        out = np.where(inside, wl, t(1) - wl)
        return np.where(zf <= y1, t(0), out).astype(dtype)


def alg3_paper_spread(clamp=1e-6, case_test="stored"):
    """A ``spread_hook`` for Algorithm 3: the printed formula in the port's precision."""

    def hook(inputs, dt):
        return [(printed_shade(inputs["r"], inputs["zf"], dt, clamp, case_test),)]

    hook.printed = hook  # every value of this hook is the printed formula's
    return hook
