"""The six-moment lower bound on the regular texels of a chunk, in the fewest passes.

:mod:`moments_ref.msm6` steps 1–5 with two changes, on the rows of the workspace of
:func:`moments_ref._msm6_rows.workspace`:

* Step 4, the weight of the one root ``t = 1/(z_a − zf)`` the bound needs, from the first
  moments about zf instead of the Christoffel function ``1 / Σ u_i²/D_i`` (which needs
  the forward substitution of ``v(z_a)``). The canonical representation puts ``w0`` at zf
  and ``w_a, w_b, w_c`` at the roots ``d = z − zf`` of ``a3 d³ + a2 d² + a1 d + a0``
  (``a_i`` the Taylor coefficients of p at zf, ``a0 = p(zf) = 1/w0``). Its moments about
  zf are those of Z: ``Σ w_l = 1 − w0``, ``Σ w_l d_l = zf' − zf = −y1`` and
  ``Σ w_l d_l² = E[(Z − zf)²] = y1² + D1`` (``y1 = zf − b1``, ``D1 = b2 − b1²``). The
  Vandermonde system of the three weights, solved for ``w_a`` with the other two roots
  eliminated by Vieta (``a3 (d_b + d_c) = −a2 − a3 d_a``, ``a3 d_b d_c = −a0/d_a``) and
  written in ``t = 1/d_a`` with ``P'(t) = 3 a0 t² + 2 a1 t + a2`` (P the reversed cubic
  of msm6's step 3), is

      w_a = ((p(zf) − 1)·t² − A·t − a3·y1) / P'(t),   A = a3 (y1² + D1) − a2 y1

  (the sign: ``a1 t² + 2 a2 t + 3 a3 = −t P'(t)`` at a root). ``p(zf) − 1 = Σ y_i c_i``
  is the sum of squares of step 2, without cancellation. 13 passes instead of 24.
* Step 3's sign σ as the sign bit of ``y3`` applied to ``2m`` (one integer AND, one XOR),
  and Blinn's ``r/2`` with the ½ folded into its denominator. Square roots of negative
  numbers (a double root, where rounding leaves ``Δ0 > 0`` or ``|r| > 1``) give NaN, and
  the texel is handed back.

Where the two roots next to each other nearly meet (``u = √((1 + σr)/2) < U_MIN``, the
Vandermonde weight's condition grows like ``1/u²``), where B(b) is singular, or where the
result is not finite, the texels are handed to :func:`moments_ref.msm6._bounds_kernel`
(the Christoffel weight, the exact singular branches): decided per texel, by reductions
per chunk, a mask built only in a chunk that has such a texel.

Passes over a float32 chunk for the lower bound: 23 Cholesky, 11 forward substitution,
5 the signs and the case masks, 3 scaling, 2 ``y1² + D1``, 5 ``p(zf) − 1``, 12 the back
substitution and Taylor coefficients, 2 ``p(zf)`` and ``3p(zf)``, 3 Blinn's B, C, D, 10
Blinn's form and σ, 4 u, 12 cos(arccos(σr)/3), 2 the root, 13 its weight, 6 step (5):
113, and four reductions (against 128 and five of the Christoffel kernel).
"""

from __future__ import annotations

import numpy as np

from ._msm6_rows import COS_THIRD_POLY, ldl_rows, regular_mask

__all__ = ["U_MIN", "bound_rows"]

#: Smallest ``u = √((1 + σr)/2)`` left to the fast path: below it the root the bound needs and
#: its neighbour nearly meet and the texel takes the Christoffel weight (module docstring).
U_MIN = 0.01


def _solve(b, zf, ldl, w):
    """Steps 2–3 into the workspace (old arithmetic for y, c, q): rows ``(y1, y1²+D1, c3, p''/2, p', p(zf)−1)``."""
    b1, b2, b3 = b[:3]
    d1, d2, d3, l21, l31, l32 = ldl
    zf2, p1, t, y1, y2, y3, c1, c2, c3, q2, q1, cm1 = (w[k] for k in ("a", "b", "t", "y1", "y2", "y3",
                                                                     "c1", "c2", "c3", "e", "f", "g"))
    # Forward substitution to solve L y = (1, zf, zf², zf³).
    np.multiply(zf, zf, out=zf2)
    np.subtract(zf, b1, out=y1)
    np.subtract(zf2, b2, out=y2)
    np.multiply(l21, y1, out=t)
    np.subtract(y2, t, out=y2)
    np.multiply(zf2, zf, out=y3)
    np.subtract(y3, b3, out=y3)
    np.multiply(l31, y1, out=t)
    np.subtract(y3, t, out=y3)
    np.multiply(l32, y2, out=t)
    np.subtract(y3, t, out=y3)
    # The Sturm sequence (1, y1, y2, y3) by sign bits: two Gauss nodes below zf is "the signs
    # never turn back from − to +" (neg1 ≤ neg2 ≤ neg3), an odd number is "y3 not negative";
    # σ = −1 there, kept as y3's sign bit for step 3.
    neg1, neg2, neg3 = w["mask"]
    blk = w["block"]  # consecutive rows (ROWS): y1..y3 are 9:12, D1..D3 0:3, c1..c3 12:15, e, f, g 15:18
    np.signbit(blk[9:12], out=w["mask"])
    np.less_equal(neg1, neg2, out=neg1)
    np.less_equal(neg2, neg3, out=neg2)
    np.logical_and(neg1, neg2, out=neg1)
    np.logical_not(neg3, out=neg3)
    np.bitwise_and(y3.view(w["bits"].dtype), w["sign"], out=w["bits"])
    # Scaling to solve D c = y; E[(Z − zf)²] = y1² + D1 into D1's row; p(zf) − 1 = Σ y_i c_i.
    np.divide(blk[9:12], blk[0:3], out=blk[12:15])
    mm = d1
    np.multiply(y1, y1, out=t)
    np.add(mm, t, out=mm)
    np.multiply(blk[9:12], blk[12:15], out=blk[15:18])  # y_i c_i into q2's, q1's and the sum's rows
    np.add(q2, q1, out=q2)
    np.add(q2, cm1, out=cm1)
    # Back substitution Lᵀ q = c (q3 = c3), then p''(zf)/2 = q2 + 3 q3 zf, p'(zf) = q1 + (q2 + p''/2) zf.
    np.multiply(l32, c3, out=t)
    np.subtract(c2, t, out=q2)
    np.multiply(l21, q2, out=t)
    np.subtract(c1, t, out=q1)
    np.multiply(l31, c3, out=t)
    np.subtract(q1, t, out=q1)
    p2 = zf2
    np.multiply(c3, 3, out=t)
    np.multiply(t, zf, out=t)
    np.add(q2, t, out=p2)
    np.add(q2, p2, out=t)
    np.multiply(t, zf, out=t)
    np.add(q1, t, out=p1)
    return y1, mm, c3, p2, p1, cm1


def _root(cubic, w):
    """Step 3: ``(−t, σ·2m·c, B, C, 3p(zf), p(zf), u)``: the root the bound needs, negated, and what its weight uses.

    ``cubic = (p(zf) − 1, p'(zf), p''(zf)/2, q3)``; Blinn's form as :func:`moments_ref.msm6._blinn`
    (``Δ0' = B² − C = −Δ0``), σ from the sign bit of y3 (``ms = copysign(2m, y3) = −σ·2m``).
    """
    cm1, p1, p2, q3 = cubic
    a0, e3, bb, cc, dd, dp, h2, dep, ms, den = (w[k] for k in ("d2", "d3", "l21", "l31", "l32", "y2", "y3",
                                                               "c1", "c2", "e"))
    np.add(cm1, 1, out=a0)
    np.multiply(a0, 3, out=e3)
    bb, cc = cc, bb  # p''/2 and p' are rows 6, 7 ("a", "b"): C and B into rows 3, 4 in one call
    np.divide(w["block"][6:8], e3, out=w["block"][3:5])
    np.divide(q3, a0, out=dd)
    np.multiply(bb, bb, out=dp)
    np.subtract(dp, cc, out=dp)
    np.multiply(dp, 2, out=h2)
    # −(B (C + 2Δ0) − D) = D − B (C − 2Δ0'); σr/2 = that / (ms·2Δ0')
    np.subtract(cc, h2, out=dep)
    np.multiply(dep, bb, out=dep)
    np.subtract(dd, dep, out=dep)
    np.multiply(dp, 4, out=ms)
    np.sqrt(ms, out=ms)
    it = w["bits"].dtype
    np.bitwise_xor(ms.view(it), w["bits"], out=ms.view(it))
    np.multiply(ms, h2, out=den)
    u = dd  # D's row, free: u stays until the bound's checks
    np.divide(dep, den, out=u)
    np.add(u, 0.5, out=u)
    np.sqrt(u, out=u)  # NaN for σr < −1 (rounding at a double root): handed back
    # cos(arccos(σr)/3) (msm6._cos_third), Horner in u
    c = w["f"]
    np.multiply(u, COS_THIRD_POLY[-1], out=c)
    for a in COS_THIRD_POLY[-2:0:-1]:
        np.add(c, a, out=c)
        np.multiply(c, u, out=c)
    np.add(c, COS_THIRD_POLY[0], out=c)
    # t = σ·2m·c − B, kept as −t = ms·c + B
    s, nt = den, dp
    np.multiply(ms, c, out=s)
    np.add(s, bb, out=nt)
    return nt, s, bb, cc, e3, a0, u


def bound_rows(b, zf, w, dest):
    """The bounds named in ``dest`` (``lower``, ``upper``) on the regular texels of a chunk; the others' indices, or None.

    b (6, n) rows, zf (n,), ``w`` the workspace of n texels, ``dest`` the output rows. The
    texels returned (singular, not finite, or ``u < U_MIN``: module docstring) are left
    unspecified in ``dest``, for :func:`moments_ref.msm6._bounds_kernel`.
    """
    ldl = ldl_rows(b, w)
    # float32's singular threshold is 0 (msm6, "Degenerate input"): every pivot positive, by one
    # reduction over the three pivot rows (a NaN fails the comparison), and D3 < ∞ (b6 = +∞).
    regular = np.minimum.reduce(w["block"][0:3], axis=None) > 0 and np.maximum.reduce(ldl[2]) < np.inf
    y1, mm, a3, a2, a1, cm1 = _solve(b, zf, ldl, w)
    # E[(Z − zf)²] = y1² + D1 is finite and ≥ 0 unless zf (or b1, b2) is not finite or zf overflows it
    regular = regular and np.maximum.reduce(mm) < np.inf
    pre = None
    if not regular:  # the exact mask, only in a chunk that needs it (allocates; the pivots are recomputed)
        ldl = ldl_rows(b, w)
        ok = regular_mask(b, ldl) & np.isfinite(ldl[2] + zf)  # D3 + zf: b6 = +inf, a non-finite zf
        pre = np.flatnonzero(~ok)
        y1, mm, a3, a2, a1, cm1 = _solve(b, zf, ldl, w)
    nt, s, bb, cc, e3, a0, u = _root((cm1, a1, a2, a3), w)
    umin = np.minimum.reduce(u)
    # (4) w_a = ((p(zf) − 1) t² − A t − a3 y1) / P'(t) with t = −nt, P'(t) = 3p(zf)·((t + 2B) t + C)
    A, B, N = w["t"], w["y3"], w["c1"]
    np.multiply(a3, mm, out=A)
    np.multiply(a2, y1, out=B)
    np.subtract(A, B, out=A)
    np.multiply(cm1, nt, out=N)
    np.add(N, A, out=N)
    np.multiply(N, nt, out=N)
    np.multiply(a3, y1, out=A)
    np.add(N, A, out=N)
    Q = s
    np.subtract(s, bb, out=Q)  # −(t + 2B)
    np.multiply(Q, nt, out=Q)
    np.add(Q, cc, out=Q)
    np.multiply(Q, e3, out=Q)
    wt = N
    np.divide(N, Q, out=wt)
    # (5) lower = [k ≥ 2]·(1 − w0 − w) + [k odd]·w: 0, w, 1 − w0 − w, 1 − w0 for k = 0..3.
    two, odd = w["mask"][0], w["mask"][2]
    h, omw0 = A, cm1
    np.divide(cm1, a0, out=omw0)  # 1 − w0 = (p(zf) − 1)/p(zf)
    np.subtract(omw0, wt, out=h)
    np.multiply(h, two, out=h)
    np.multiply(wt, odd, out=wt)
    lower = dest.get("lower", w["y1"])
    np.add(h, wt, out=lower)
    # Saturate below (rounding leaves 1 − w0 − w a little under 0). lower is finite or NaN (a weight
    # ±∞ meets a 0 or an opposite ∞ in step 5), and np.maximum keeps the NaN for the reduction.
    np.maximum(lower, w["zero"], out=lower)
    hi = np.maximum.reduce(lower)
    rest = pre
    if not (umin >= U_MIN and hi < np.inf):  # NaN fails every comparison
        keep, near = w["mask"][0], w["mask"][1]
        np.isfinite(lower, out=keep)
        np.greater_equal(u, U_MIN, out=near)
        np.logical_and(keep, near, out=keep)
        post = np.flatnonzero(np.logical_not(keep, out=keep))
        rest = post if pre is None else np.union1d(pre, post)
    if not hi <= 1:
        np.minimum(lower, w["one"], out=lower)
    if "upper" in dest:
        w0 = w["t"]
        np.divide(1, a0, out=w0)
        np.add(lower, w0, out=dest["upper"])
        np.minimum(dest["upper"], w["one"], out=dest["upper"])
    return rest if rest is not None and rest.size else None
