"""The papers' own formulations, run in a port's precision: legitimate variants of the spread model.

The reference computes Algorithm 1 with care (roots without cancellation, an exact
branch for singular B(b)). The code the papers print does not, and it is what the
engines ship: the slides' "Compute the shadow intensity" (Peters' demo code, as Unity
HDRP's ``HDIMS.hlsl`` and most public ports carry it) takes the roots as
``−p/2 ∓ √(p²/4 − q)`` and weighs the support points by the "Switch"/"Quotient"
formula. Run in float32 it is a legitimate implementation of the same equation: its
deviation on a row is part of the spread that sets the row's tolerance
(:mod:`moments_ref.golden.spread`). Where it has no finite value (singular B(b),
outside the contract) it contributes nothing.

References
----------
Slides, HPG17, Peters and Klein 2015 : see docs/bib.md.
"""

from __future__ import annotations

import numpy as np

__all__ = ["slides_bound", "alg1_paper_spread"]


def slides_bound(b, zf, bound="lower", dtype=np.float32):
    """The slides' "Compute the shadow intensity", operation by operation in ``dtype``.

    ``bound="upper"`` adds the weight of the fragment depth, ``w0 = (z1 z2 − b1 (z1 + z2)
    + b2) / ((zf − z1)(zf − z2))``, computed from the same roots. Returns ``(n,)``
    in ``dtype``, saturated; NaN where the formula divides by zero (no ``saturate``
    is applied to NaN here, so that the caller can leave those rows out).
    """
    t = np.dtype(dtype).type
    b = np.asarray(b).astype(dtype)
    z0 = np.asarray(zf).astype(dtype)
    b0, b1, b2, b3 = (b[..., k] for k in range(4))
    with np.errstate(all="ignore"):
        l32d22 = -b0 * b1 + b2
        d22 = -b0 * b0 + b1
        var2 = -b1 * b1 + b3
        d33d22 = var2 * d22 + (-l32d22) * l32d22
        inv_d22 = t(1) / d22
        l32 = l32d22 * inv_d22
        c1 = z0 - b0
        c2 = z0 * z0 - (b1 + l32 * c1)
        c1 = c1 * inv_d22
        c2 = c2 * (d22 / d33d22)
        c1 = c1 - l32 * c2
        c0 = t(1) - (c1 * b0 + c2 * b1)
        p = c1 / c2
        q = c0 / c2
        r = np.sqrt(p * p * t(0.25) - q)
        z1 = -p * t(0.5) - r
        z2 = -p * t(0.5) + r
        far = z2 < z0
        mid = ~far & (z1 < z0)
        s0 = np.where(far, z1, np.where(mid, z0, t(0)))
        s1 = np.where(far, z0, np.where(mid, z1, t(0)))
        s2 = np.where(far, t(1), t(0))
        s3 = np.where(far | mid, t(1), t(0))
        quotient = (s0 * z2 - b0 * (s0 + z2) + b1) / ((z2 - s1) * (z0 - z1))
        out = s2 + s3 * quotient
        if bound == "upper":
            out = out + (z1 * z2 - b0 * (z1 + z2) + b1) / ((z0 - z1) * (z0 - z2))
        return np.where(np.isnan(out), out, np.clip(out, 0, 1)).astype(dtype)


def alg1_paper_spread(bound):
    """A ``spread_hook`` for Algorithm 1 cases: the slides' code in the port's precision."""

    def hook(inputs, dt):
        return [(slides_bound(inputs["b"], inputs["zf"], bound, dt),)]

    return hook
