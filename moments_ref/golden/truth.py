"""Ground truth for golden cases that :mod:`moments_ref.precise` does not cover literally.

:func:`shade_clamped` is HPG17 Algorithm 3 *with* its §3.4 clamps, evaluated in
mpmath: the clamps are part of the specification (a port must apply them), so the
expected value of a row at v2 = 0 or y1 = y2 is the clamped one. Away from the
clamps it equals :func:`moments_ref.precise.shade` (Algorithm 1 on Eq. (4)); the
tests check that.

References
----------
.. [1] HPG17: Christoph Peters. 2017. *Non-Linearly Quantized Moment Shadow Maps*. In Proceedings
       of High Performance Graphics (HPG '17). ACM. The non-linear quantization Φ, Ψ4, Algorithms
       1–3, the texel formats and the compute shader of §4.1.
"""

from __future__ import annotations

import mpmath
import numpy as np

__all__ = ["shade_clamped", "SHADE_CLAMP"]

#: HPG17 §3.4: v2 ∈ [1e-6, 1 − 1e-6] and y2 − y1 ≥ 1e-6.
SHADE_CLAMP = 1e-6


def _shade_row(y1, y2, v2, xi4, zf, eps, clamped_test=False):
    """Algorithm 3 on one row with clamp offset ``eps``, all arguments mpf (50 digits).

    ``clamped_test``: the case test ``zf ≤ y2`` compares with the clamped y2 = max(y2, y1 + eps)
    (the author's demo code) instead of the stored y2 (the reference's reading).
    """
    if zf <= y1:
        return mpmath.mpf(0)  # "if zf ≤ y1 return 0"
    if clamped_test:
        y2 = max(y2, y1 + eps)
    v2 = min(max(v2, eps), 1 - eps)
    gap = max(y2 - y1, eps)
    zp = (zf - y1) / gap
    xip = max(xi4 / gap**4, mpmath.mpf("1e-60"))  # ξ'4 → 0⁺ limit for ξ4 = 0
    if zf <= y2:  # the case test uses the stored y2 (the clamp only moves the y2 used above)
        if zp >= 1:
            zl = mpmath.mpf(0)  # limit z'f → 1⁻: q1 → −∞, the smaller root → 0
        else:
            q0 = -xip / ((1 - v2) * zp)
            q1 = -q0 * (v2 - zp) / (v2 - v2 * zp) - 1
            zl = -q1 / 2 - mpmath.sqrt(q1 * q1 / 4 - q0)
    else:
        zl = zp
    wl = 1 / ((1 - zl) ** 2 / (1 - v2) + zl**2 / v2 + (1 - zl) ** 2 * zl**2 / xip)
    out = wl if zf <= y2 else 1 - wl
    return min(max(out, mpmath.mpf(0)), mpmath.mpf(1))


def shade_clamped(r, zf, dps=50, clamp=SHADE_CLAMP, case_test="stored"):
    """Exact Algorithm 3 with the §3.4 clamps: ``(n, 4)`` r and ``(n,)`` zf -> float64 ``(n,)``.

    ``clamp`` is the offset of the clamps (the paper's 1e-6, or a port's declared
    offset, docs/ports.md); it is taken as the float given, exactly. ``case_test``:
    the y2 the case test ``zf ≤ y2`` compares with, ``"stored"`` (default) or
    ``"clamped"`` (max(y2, y1 + clamp)): the paper does not say which.
    """
    r = np.asarray(r, np.float64).reshape(-1, 4)
    zf = np.broadcast_to(np.asarray(zf, np.float64), r.shape[:1])
    out = np.empty(len(zf))
    with mpmath.workdps(dps):
        eps = mpmath.mpf(float(clamp))
        for i in range(len(zf)):
            out[i] = float(_shade_row(*(mpmath.mpf(float(x)) for x in r[i]), mpmath.mpf(float(zf[i])), eps,
                                      case_test == "clamped"))
    return out
