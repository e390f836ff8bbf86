"""The six-moment bounds on the regular texels of a float32 chunk, in the fewest passes.

:mod:`moments_ref.msm6` steps 1–5, on the rows of the workspace of
:func:`moments_ref._msm6_rows.workspace`, with steps 2–4 written differently:

* Step 2 by the three-term recurrence of the monic orthogonal polynomials (Gauss
  quadrature; ``P_{i+1}(z) = (z − α_i) P_i(z) − β_i P_{i−1}(z)``, here ``α1 = L21 − b1``,
  ``α2 = L32 − L21``, ``β1 = D1``, ``β_i = D_i/D_{i−1}`` from the Cholesky factors of step 1):
  ``y = (P1, P2, P3)(zf)`` and the derivatives ``g = P2'(zf)``, ``h = P3'(zf)``,
  ``k = P3''(zf)/2`` by the same recurrence.
* Step 3's cubic without the back substitution and the Taylor shift: by the
  Christoffel–Darboux identity the kernel polynomial of step 2 is
  ``p(z) = K(zf, z) = (y3/D3)·P4*(z)/(z − zf)`` for the polynomial
  ``P4* = (z − zf + γ) P3 − β3 P2`` with ``β3 = D3/D2`` and ``γ = β3 y2/y3`` (the
  Gauss–Radau polynomial: the one with the next recurrence step whose root is zf). With
  ``d = z − zf``, ``P4*(zf + d)/d = d³ + K1 d² + K2 d + ℓ``, ``K1 = k + γ``,
  ``K2 = h + γ k − β3``, ``ℓ = y3 + γ h − β3 g``, so the reversed cubic of msm6's step 3 is
  ``P(t) = ℓ t³ + K2 t² + K1 t + 1`` (msm6's ``(p(zf), p'(zf), p''(zf)/2, q3)`` times
  ``λ = D3/y3``; ``w0 = 1/p(zf) = λ/ℓ``). Its root is Blinn's closed form as in msm6, σ the
  sign bit of ``y3`` applied to ``2m`` (one integer AND, one XOR), ``r/2`` with the ½
  folded into its denominator; the square roots of negative numbers (rounding at a double
  root: ``Δ0 > 0`` or ``|r| > 1``) give NaN, and the texel is handed back.
* Step 4, the weight of that root ``t = 1/(z_a − zf)``, from the first moments about zf
  instead of the Christoffel function ``1 / Σ u_i²/D_i`` (which needs the forward
  substitution of ``v(z_a)``): the canonical representation puts ``w0`` at zf and
  ``w_a, w_b, w_c`` at the roots ``d_l`` of ``d³ + K1 d² + K2 d + ℓ``, and its moments about
  zf are those of Z: ``Σ w_l = 1 − w0``, ``Σ w_l d_l = b1 − zf = −y1``,
  ``Σ w_l d_l² = E[(Z − zf)²] = y1² + D1``. The Vandermonde system solved for ``w_a`` with
  the other two roots eliminated by Vieta (``d_b + d_c = −K1 − d_a``, ``d_b d_c = −ℓ/d_a``)
  and written in t (``K2 t² + 2 K1 t + 3 = −t P'(t)`` at a root) is

      w_a = (ℓ (1 − w0) t² − A t + y1) / P'(t),   A = y1² + D1 − K1 y1,

  with ``ℓ (1 − w0) = ℓ − λ`` and ``P'(t) = 3ℓ ((t + 2B) t + C)`` (B, C of Blinn's form). With
  the root written as ``t = −s − B`` (``s = σ·2m·cos(arccos(σr)/3)``, ``m² = Δ0' = B² − C``),
  ``(t + 2B) t + C = s² − Δ0' = Δ0' (4cos²(·) − 1)`` (a third of the product of the root's
  distances to the other two), two passes from s instead of three from t, and free of the
  cancellation of ``B²`` against ``C`` where ``Δ0' ≪ B²``.

Where the two roots next to each other nearly meet (``u = √((1 + σr)/2) < U_MIN``: the
Vandermonde weight divides two small numbers there), where B(b) is singular, or where the
result is not finite (y3 = 0 exactly, an overflow, a non-finite input), the texels are
handed to :func:`moments_ref.msm6._bounds_kernel` (the Christoffel weight, the exact
singular branches): decided per texel, by reductions per chunk, a mask built only in a
chunk that has such a texel.

Passes over a float32 chunk for the lower bound: 23 Cholesky, 11 forward substitution,
8 the signs, the case masks and σ's sign bit, 5 the derivatives at zf, 11 the Radau cubic,
4 λ and ``A = y1 (y1 − K1) + D1``, 4 Blinn's B, C, D, 9 Blinn's form and σ (in halves:
:func:`_root`), 3 ``v = √2 u``, 8 cos(arccos(σr)/3) (a rational function,
:data:`COS_THIRD_RATIONAL`), 2 the root, 9 its weight (``P'(t)/(3ℓ) = s² − Δ0'``, :func:`bound_rows`),
6 step (5) and saturate: 103, and three reductions (the pivots, min v, max of the saturated bound;
four until round nine; the Christoffel kernel: 128 and five). The upper
bound 3 more. Every call takes its output positionally and its constants as 0-d float32 arrays
(the values a Python float rounds to in a float32 call, so the same bits; about 0.35 µs less per
call), except ``np.maximum`` and ``np.minimum``, whose positional output NumPy deprecates.
"""

from __future__ import annotations

from operator import itemgetter

import numpy as np

from ._msm6_rows import ldl_rows, regular_mask

__all__ = ["COS_THIRD_RATIONAL", "U_MIN", "bound_rows"]

#: ``cos(⅔·arccos u)`` for u ∈ [0, 1] (``cos(arccos(σr)/3)`` with ``u = √((1 + σr)/2)``) as the
#: rational function ``a u + k + A1/(u − p1) + A2/(u − p2)``, the tuple ``(a, k, p1, A1, p2, A2)``:
#: degree 3 over degree 2, fitted minimax (Lawson-weighted Sanathanan–Koerner iteration on 4001
#: Chebyshev points of [0, 1]) and written as partial fractions. Largest error on 200001 points of
#: [0, 1] 3.0e-8, 3.2e-7 evaluated in float32 (the poles −5.77 and −1.49 lie off the interval, no
#: cancellation); 8 passes against the degree-6 polynomial's 12 (``COS_THIRD_POLY``: 1.6e-7, 2.2e-7
#: in float32). ``cos(⅔θ)`` with u = cos θ is a function of θ², analytic at u = 1 and singular
#: at u = −1: the poles stand in for that singularity.
COS_THIRD_RATIONAL = (0.22876956086134295, 2.0743746258858473, -5.766828281376259, -8.201217143670977,
                      -1.4929475051953751, -0.22728344576288395)

#: :data:`COS_THIRD_RATIONAL` for ``2 cos(⅔·arccos(v/√2))``, v = √2·u (:func:`_root`), same layout.
_COS_THIRD_V = tuple(float(x * f) for x, f in zip(COS_THIRD_RATIONAL, (2 ** 0.5, 2, 2 ** 0.5, 8 ** 0.5, 2 ** 0.5, 8 ** 0.5)))

#: Smallest ``u = √((1 + σr)/2)`` left to the fast path: below it the root the bound needs and
#: its neighbour nearly meet and the texel takes the Christoffel weight (module docstring).
#: Measured on 2^20 biased random rows (2 to 8 depths, zf at and next to support points): none
#: below 0.01; 133 in [0.01, 0.03), where this path's largest error against mpmath (precise) on
#: the 40 rows differing most from the Christoffel kernel was 2.1e-4 (that kernel's 4.9e-4).
U_MIN = 0.01


def _const(x):
    """``x`` as a read-only 0-d float32 array: the value a Python float rounds to in a float32 ufunc
    call (NEP 50), so the same bits, at a cheaper call (about 0.35 µs a call on a chunk)."""
    a = np.array(x, dtype=np.float32)
    a.flags.writeable = False
    return a


#: The constants of :func:`_root` as 0-d float32 arrays: 3, ½ and :data:`_COS_THIRD_V`.
_THREE, _HALF = _const(3), _const(0.5)
_COS_THIRD_K = tuple(_const(x) for x in _COS_THIRD_V)

#: The workspace rows :func:`_solve` and :func:`_root` use, in their order of unpacking.
_SOLVE_ROWS = itemgetter("a", "b", "t", "y1", "y2", "y3", "c1", "c2", "c3", "e", "f", "g")
_ROOT_ROWS = itemgetter("d2", "l32", "c1", "c2", "y2", "y3", "l21", "c3", "t", "ic3")


def _solve(b, zf, ldl, w):
    """Steps 2–3 by the recurrence and the Radau cubic (module docstring): rows ``(y1, A, K1, K2, ℓ, λ)``.

    Also the case masks (``mask[0]`` two Gauss nodes below zf, ``mask[2]`` an odd number)
    and σ's sign bit (``bits``).
    """
    b1 = b[0]
    d1, d2, d3, l21, l31, l32 = ldl
    blk = w["block"]  # consecutive rows (ROWS): y1..y3 are 9:12, c1..c3 12:15, e, f, g 15:18
    e1, e2, t, y1, y2, y3, g, k, h, gam, k1, k2 = _SOLVE_ROWS(w)
    # Forward substitution by the three-term recurrence: y = (P1, P2, P3)(zf), P_{i+1} = (z − α_i) P_i − β_i P_{i−1}
    # with α1 = L21 − b1, α2 = L32 − L21, β1 = D1, β2 = D2/D1; e_i = zf − α_i.
    np.subtract(zf, b1, y1)
    np.subtract(b1, l21, t)
    np.add(zf, t, e1)
    np.multiply(e1, y1, y2)
    np.subtract(y2, d1, y2)
    np.subtract(l21, l32, t)
    np.add(zf, t, e2)
    beta2 = gam
    np.divide(d2, d1, beta2)
    np.multiply(beta2, y1, h)
    np.multiply(e2, y2, y3)
    np.subtract(y3, h, y3)
    # The Sturm sequence (1, y1, y2, y3) by sign bits: two Gauss nodes below zf is "the signs
    # never turn back from − to +" (neg1 ≤ neg2 ≤ neg3), an odd number is "y3 not negative";
    # σ = −1 there, kept as y3's sign bit for step 3.
    neg1, neg2, neg3 = w["mask"]
    np.signbit(blk[9:12], w["mask"])
    np.less_equal(neg1, neg2, neg1)
    np.less_equal(neg2, neg3, neg2)
    np.logical_and(neg1, neg2, neg1)
    np.logical_not(neg3, neg3)
    np.bitwise_and(w["iy3"], w["sign"], w["bits"])
    # The derivatives at zf: g = P2' = y1 + e1, k = P3''/2 = g + e2, h = P3' = y2 + e2 g − β2.
    np.add(y1, e1, g)
    np.add(g, e2, k)
    np.multiply(e2, g, h)
    np.add(y2, h, h)
    np.subtract(h, beta2, h)
    # The Radau cubic: R(d) = d³ + K1 d² + K2 d + ℓ with γ = β3 y2 / y3, β3 = D3/D2.
    beta3 = e1
    np.divide(d3, d2, beta3)
    np.divide(y2, y3, gam)
    np.multiply(gam, beta3, gam)
    np.add(k, gam, k1)
    np.multiply(gam, k, k2)
    np.add(k2, h, k2)
    np.subtract(k2, beta3, k2)
    ell = e2
    np.multiply(gam, h, ell)
    np.add(ell, y3, ell)
    np.multiply(beta3, g, t)
    np.subtract(ell, t, ell)
    # λ = D3/y3 = ℓ w0 (the scale of R against p about zf); A = E[(Z − zf)²] − K1 y1 = y1 (y1 − K1) + D1.
    lam, A = l31, d1
    np.divide(d3, y3, lam)
    np.subtract(y1, k1, t)
    np.multiply(t, y1, t)
    np.add(A, t, A)
    return y1, A, k1, k2, ell, lam


def _root(cubic, w):
    """Step 3: ``(−t, s, Δ0', 3ℓ, v)``: the root the bound needs, negated, what its weight uses, and ``v = √2·u``.

    ``cubic = (K1, K2, ℓ)``: P(t) = ℓ t³ + K2 t² + K1 t + 1, Blinn's form as
    :func:`moments_ref.msm6._blinn` (``Δ0' = B² − C = −Δ0``), σ from the sign bit of y3
    (``ms = copysign(2m, y3) = −σ·2m``), written in halves: with ``sm = ms/2`` (``m = √Δ0'``),
    ``H = D/2 − (C/2 − Δ0') B`` (msm6's ``−(B (C + 2Δ0) − D)/2``) and ``X = sm·Δ0'``, msm6's
    ``σr/2 = H/(2X)``, so ``v² = 2u² = 1 + σr = (H + X)/X`` (no 4Δ0', 2Δ0' or ½ pass), and the
    factor 2 of ``ms`` and the √2 of ``u = v/√2`` go into the constants of
    :data:`COS_THIRD_RATIONAL` (``2c(v/√2) = √2 a v + 2k + Σ 2√2 A_i/(v − √2 p_i)``).
    """
    k1, k2, ell = cubic
    e3, dd, cc, bb, dp, x, g, sm, t, ism = _ROOT_ROWS(w)
    np.multiply(ell, _THREE, e3)
    np.divide(w["block"][16:18], e3, w["block"][12:14])  # (K1, K2)/(3ℓ) = (C, B)
    np.divide(_HALF, ell, dd)  # D/2
    np.multiply(bb, bb, dp)
    np.subtract(dp, cc, dp)  # Δ0'
    # H = D/2 − (C/2 − Δ0') B
    np.multiply(cc, _HALF, g)
    np.subtract(g, dp, g)
    np.multiply(g, bb, g)
    np.subtract(dd, g, dd)
    np.sqrt(dp, sm)
    np.bitwise_xor(ism, w["bits"], ism)  # sm = copysign(√Δ0', y3)
    np.multiply(sm, dp, x)
    v = dd  # H's row: v stays until the bound's checks
    np.add(dd, x, v)
    np.divide(v, x, v)
    np.sqrt(v, v)  # NaN for σr < −1 (rounding at a double root): handed back
    # 2 cos(arccos(σr)/3) (msm6._cos_third) by COS_THIRD_RATIONAL in v = √2 u (docstring)
    c = g
    a, k, p1, a1, p2, a2 = _COS_THIRD_K
    np.subtract(v, p1, c)
    np.divide(a1, c, c)
    np.subtract(v, p2, t)
    np.divide(a2, t, t)
    np.add(c, t, c)
    np.multiply(v, a, t)
    np.add(c, t, c)
    np.add(c, k, c)
    # t = σ·2m·c − B, kept as −t = ms·c + B = sm·2c + B
    s, nt = t, x
    np.multiply(sm, c, s)
    np.add(s, bb, nt)
    return nt, s, dp, e3, v


def bound_rows(b, zf, w, dest):
    """The bounds named in ``dest`` (``lower``, ``upper``) on the regular texels of a chunk; the others' indices, or None.

    b (6, n) rows, zf (n,), ``w`` the workspace of n texels, ``dest`` the output rows. The
    texels returned (singular, not finite, or ``u < U_MIN``: module docstring) are left
    unspecified in ``dest``, for :func:`moments_ref.msm6._bounds_kernel`.
    """
    ldl = ldl_rows(b, w)
    # float32's singular threshold is 0 (msm6, "Degenerate input"): every pivot positive, by one
    # reduction over the three pivot rows (a NaN fails the comparison). D3 = +∞ (b6 = +∞, or an
    # overflow) needs no reduction: β3 = D3/D2 = ∞ makes ℓ = y3 + γh − β3 g and K1 = k + γ infinite
    # or NaN, so C = K1/(3ℓ), Δ0' and v are NaN, and the result's check hands the texel back.
    regular = np.minimum.reduce(w["block"][0:3], axis=None) > 0
    pre = None
    if not regular:  # the exact mask, only in a chunk that needs it (allocates)
        ok = regular_mask(b, ldl) & np.isfinite(ldl[2] + zf)  # D3 + zf: b6 = +inf, a non-finite zf
        pre = np.flatnonzero(~ok)
    # A non-finite zf (or one so large that y2 or y3 overflows) makes y3 NaN (∞ − ∞ through β2 y1 > 0
    # or γ = ∞/∞), and with it the result: such texels are handed back by the result's check.
    y1, A, k1, k2, ell, lam = _solve(b, zf, ldl, w)
    nt, s, dp, e3, v = _root((k1, k2, ell), w)
    vmin, v_min = np.minimum.reduce(v), 2 ** 0.5 * U_MIN  # v = √2 u
    # (4) w_a = (ℓ(1 − w0) t² − A t + y1) / P'(t), A = y1² + D1 − K1 y1, with t = −nt,
    # P'(t) = 3ℓ·((t + 2B) t + C) = 3ℓ·(s² − Δ0') and ℓ(1 − w0) = ℓ − λ (module docstring).
    cm1, N, Q = w["e"], w["c3"], s
    np.subtract(ell, lam, cm1)
    np.multiply(cm1, nt, N)
    np.add(N, A, N)
    np.multiply(N, nt, N)
    np.add(N, y1, N)
    np.multiply(s, s, Q)  # (t + 2B) t + C = (B − s)(−s − B) + C = s² − Δ0' (t = −s − B, Δ0' = B² − C)
    np.subtract(Q, dp, Q)
    np.multiply(Q, e3, Q)
    wt = N
    np.divide(N, Q, wt)
    # (5) lower = [k ≥ 2]·(1 − w0 − w) + [k odd]·w: 0, w, 1 − w0 − w, 1 − w0 for k = 0..3.
    two, odd = w["mask"][0], w["mask"][2]
    h, omw0 = w["a"], cm1
    np.divide(cm1, ell, omw0)  # 1 − w0 = (ℓ − λ)/ℓ
    np.subtract(omw0, wt, h)
    np.multiply(h, two, h)
    np.multiply(wt, odd, wt)
    lower = dest.get("lower", w["y1"])
    np.add(h, wt, lower)
    # Saturate below (rounding leaves 1 − w0 − w a little under 0). lower is finite or NaN (a weight
    # ±∞ meets a 0 or an opposite ∞ in step 5), and np.maximum keeps the NaN for the reduction.
    np.maximum(lower, w["zero"], out=lower)
    hi = np.maximum.reduce(lower)
    rest = pre
    if not (vmin >= v_min and hi < np.inf):  # NaN fails every comparison
        keep, near = w["mask"][0], w["mask"][1]
        np.isfinite(lower, keep)
        np.greater_equal(v, v_min, near)
        np.logical_and(keep, near, keep)
        post = np.flatnonzero(np.logical_not(keep, keep))
        rest = post if pre is None else np.union1d(pre, post)
    if not hi <= 1:
        np.minimum(lower, w["one"], out=lower)
    if "upper" in dest:
        w0 = w["t"]
        np.divide(lam, ell, w0)  # w0 = λ/ℓ
        np.add(lower, w0, dest["upper"])
        np.minimum(dest["upper"], w["one"], out=dest["upper"])
    return rest if rest is not None and rest.size else None
