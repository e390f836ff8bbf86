"""The float32 fast path of the six-moment bounds (moments_ref._msm6_bound) checked by independent means.

References: the mpmath twin (precise.shadow_bounds6: lu_solve, polyroots, a Vandermonde
solve at 50 digits), the exact Z of the drawn distribution, and the Christoffel kernel
(msm6._bounds_kernel) it hands its irregular texels to. Tolerances:

* against mpmath on biased random rows: F32_TOL = 2e-3 (measured worst 1.1e-4 over 3000 rows
  with zf at and 1e-5 from support points, the Christoffel kernel 1.1e-4; 4.5e-4 and 4.5e-4 on
  the 40 of 4000 rows where the two differ most);
* the fast path is at least as close to mpmath as the Christoffel kernel up to SAME = 5e-5
  (their forward substitutions, cubics and weights are evaluated differently in float32:
  measured largest excess 2.2e-5, on a row whose bound is 2.2e-4);
* a texel's bounds do not depend on its chunk: equal bits alone and among others.
* the in-place kernel is its formulas written as plain float32 expressions with Python
  scalars, bit for bit on every texel it keeps (so a rearrangement of its calls, outputs or
  constants that changes a bit is caught);
* the rational cos(arccos(σr)/3) (COS_THIRD_RATIONAL, and its constants in v = √2 u) against
  mpmath: 4e-7 and 5e-7 (measured 2.6e-7 and 3.7e-7 in float32 on 2001 points).
"""

import numpy as np

from moments_ref import msm6, precise
from moments_ref import _msm6_bound
from moments_ref._msm6_rows import workspace
from moments_ref.moments import bias_moments, power_moments

F32_TOL = 2e-3
SAME = 5e-5


def _rows(n, seed, unbiased=0.0):
    rng = np.random.default_rng(seed)
    k = rng.integers(2, 9, n)
    z = rng.uniform(-1, 1, (n, 8))
    b = power_moments(z, rng.uniform(0.05, 1, (n, 8)) * (np.arange(8) < k[:, None]), n=6)
    biased = rng.random(n) >= unbiased
    b[biased] = bias_moments(b[biased], msm6.BIAS6_FLOAT32)
    zf = rng.uniform(-1.05, 1.05, n)
    near = rng.random(n) < 0.3
    zf[near] = z[near, 0] + rng.choice([0, 1e-5, -1e-5, 1e-3], near.sum())
    return b.astype(np.float32), zf.astype(np.float32)


def _christoffel(b, zf):
    dest = {k: np.empty(len(zf), np.float32) for k in ("lower", "upper")}
    msm6._bounds_kernel(np.ascontiguousarray(b.T), zf, msm6._NEWTON_STEPS["float32"], dest, None)
    return dest["lower"], dest["upper"]


def _precise(b, zf):
    return [np.array([float(x) for x in v]) for v in precise.shadow_bounds6(b, zf)]


def test_fast_path_matches_precise_and_the_christoffel_kernel():
    b, zf = _rows(4000, 1)
    lo, up = msm6.shadow_bounds(b, zf)
    clo, cup = _christoffel(b, zf)
    diff = np.maximum(np.abs(lo - clo), np.abs(up - cup))
    assert 0 < diff.max() < 1e-3  # the weights' formulas differ: not the Christoffel kernel's bits
    pick = np.argsort(-diff)[:40]  # where the two differ most, and 20 rows drawn at random
    pick = np.concatenate([pick, np.random.default_rng(2).choice(len(zf), 20, replace=False)])
    plo, pup = _precise(b[pick], zf[pick])
    err = np.maximum(np.abs(lo[pick] - plo), np.abs(up[pick] - pup))
    cerr = np.maximum(np.abs(clo[pick] - plo), np.abs(cup[pick] - pup))
    assert err.max() <= F32_TOL
    assert (err <= cerr + SAME).all()


def test_fast_path_hands_back_singular_nonfinite_and_near_double_roots(monkeypatch):
    # A chunk mixing regular rows with singular ones (three and one depths, unbiased), a row whose
    # root pair nearly meets (forced: U_MIN raised so that many rows count as such): every texel's
    # bounds are its bounds alone (the same bits), and the handed-back rows are the Christoffel
    # kernel's, exact on the singular ones.
    b, zf = _rows(3000, 3)
    b[1::7] = power_moments(np.array([-0.5, 0.1, 0.6]), n=6).astype(np.float32)
    b[3::14] = power_moments(np.array([0.25]), n=6).astype(np.float32)
    zf[1::7] = 0.3
    zf[3::14] = 0.5
    monkeypatch.setattr(_msm6_bound, "U_MIN", 0.3)
    lo, up = msm6.shadow_bounds(b, zf)
    alone = [msm6.shadow_bounds(b[i:i + 1], zf[i:i + 1]) for i in range(0, 3000, 37)]
    assert all(lo[i] == a[0][0] and up[i] == a[1][0] for i, a in zip(range(0, 3000, 37), alone))
    assert np.allclose(lo[1::7], 2 / 3, atol=1e-6) and np.allclose(up[1::7], 2 / 3, atol=1e-6)
    assert (lo[3::14] == 1).all()
    w = workspace(np.float32, 3000)
    dest = {"lower": np.empty(3000, np.float32)}
    with np.errstate(all="ignore"):
        rest = _msm6_bound.bound_rows(np.ascontiguousarray(b.T), zf, w, dest)
    sing = np.zeros(3000, bool)
    sing[1::7] = sing[3::14] = True
    assert rest is not None and sing[rest].sum() == sing.sum() and (~sing[rest]).sum() > 20
    clo, cup = _christoffel(b[rest], zf[rest])
    assert np.array_equal(lo[rest], clo) and np.array_equal(up[rest], cup)


def test_fast_path_check_has_power(monkeypatch):
    # Mutant: w0 dropped from the weight and step (5) (λ = ℓ w0 taken as 0) is caught by the
    # comparison with mpmath.
    b, zf = _rows(200, 4)
    real = _msm6_bound._solve

    def mutant(*args):
        out = real(*args)
        out[-1][...] = 0
        return out

    monkeypatch.setattr(_msm6_bound, "_solve", mutant)
    lo, _ = msm6.shadow_bounds(b, zf)
    plo, _ = _precise(b[:40], zf[:40])
    assert np.abs(lo[:40] - plo).max() > F32_TOL


def _rational(consts, x):
    # the kernel's order of operations (_msm6_bound._root), in float32
    a, k, p1, a1, p2, a2 = (np.float32(c) for c in consts)
    return a1 / (x - p1) + a2 / (x - p2) + x * a + k


def test_cos_third_rational_against_mpmath():
    # cos(arccos(σr)/3) with u = √((1 + σr)/2), by mpmath at 30 digits on 2001 points of [0, 1]:
    # documented largest error 3.2e-7 in float32; in v = √2 u the kernel's constants give 2·cos.
    import mpmath

    u = np.linspace(0, 1, 2001)
    with mpmath.workdps(30):
        ref = np.array([float(mpmath.cos(mpmath.acos(2 * mpmath.mpf(x) ** 2 - 1) / 3)) for x in u])
    got = _rational(_msm6_bound.COS_THIRD_RATIONAL, u.astype(np.float32))
    assert np.abs(got - ref).max() <= 4e-7
    got_v = _rational(_msm6_bound._COS_THIRD_V, (np.sqrt(2) * u).astype(np.float32))
    assert np.abs(got_v / 2 - ref).max() <= 5e-7
    off = list(_msm6_bound.COS_THIRD_RATIONAL)
    off[3] *= 1 + 1e-5  # one residue perturbed: caught
    assert np.abs(_rational(off, u.astype(np.float32)) - ref).max() > 4e-7


def _fast_by_expressions(b, zf):
    # The fast path's arithmetic (module docstring of _msm6_bound) as plain float32 expressions
    # with Python scalars, in the kernel's order of operations: (lower, upper, the texels it keeps).
    b1, b2, b3, b4, b5, b6 = b.T
    D1 = b2 - b1 * b1
    a, c = b3 - b1 * b2, b4 - b1 * b3
    L21, L31 = a / D1, c / D1
    D2 = (b4 - b2 * b2) - L21 * a
    a32 = (b5 - b2 * b3) - L21 * c
    L32 = a32 / D2
    D3 = ((b6 - b3 * b3) - L31 * c) - L32 * a32
    y1 = zf - b1  # the recurrence, e_i = zf − α_i
    e1, e2 = zf + (b1 - L21), zf + (L21 - L32)
    beta2, beta3 = D2 / D1, D3 / D2
    y2 = e1 * y1 - D1
    y3 = e2 * y2 - beta2 * y1
    n1, n2, n3 = np.signbit(y1), np.signbit(y2), np.signbit(y3)
    two, odd = (n1 <= n2) & (n2 <= n3), ~n3
    g = y1 + e1
    k = g + e2
    h = (y2 + e2 * g) - beta2
    gam = (y2 / y3) * beta3  # the Radau cubic
    K1, K2 = k + gam, (gam * k + h) - beta3
    ell = (gam * h + y3) - beta3 * g
    lam, A = D3 / y3, D1 + (y1 - K1) * y1
    e3 = ell * 3  # Blinn's form in halves
    C, B = K1 / e3, K2 / e3
    dp = B * B - C
    H = 0.5 / ell - (C * 0.5 - dp) * B
    sm = np.copysign(np.sqrt(dp), y3)
    X = sm * dp
    v = np.sqrt((H + X) / X)
    ka, kk, p1, a1, p2, a2 = _msm6_bound._COS_THIRD_V
    cv = ((a1 / (v - p1) + a2 / (v - p2)) + v * ka) + kk
    s = sm * cv
    nt = s + B
    cm1 = ell - lam  # the weight from the moments about zf
    wt = ((cm1 * nt + A) * nt + y1) / ((s * s - dp) * e3)
    lower = np.minimum(np.maximum((cm1 / ell - wt) * two + wt * odd, 0), 1)
    upper = np.minimum(lower + lam / ell, 1)
    keep = (D1 > 0) & (D2 > 0) & (D3 > 0) & (D3 < np.inf) & np.isfinite(lower) & (v >= 2 ** 0.5 * _msm6_bound.U_MIN)
    return lower, upper, keep


def test_fast_path_is_its_expressions_bit_for_bit():
    # The in-place fast path (reused rows, positional outputs, 0-d constants, sign bits, checks by
    # reductions) claims the arithmetic of the expressions above operation for operation: equal
    # bits on every texel it keeps, over several chunks and a partial one (biased and unbiased
    # rows, zf at and next to support points). Seen failing on a reassociated sum and on a
    # constant rounded differently (0.5 as its float32 neighbour).
    b, zf = _rows(2 * msm6.BOUNDS_CHUNK + 777, 9, unbiased=0.2)
    with np.errstate(all="ignore"):
        lower, upper, keep = _fast_by_expressions(b, zf)
    assert keep.mean() > 0.75
    lo, up = msm6.shadow_bounds(b, zf)
    assert np.array_equal(lo[keep].view(np.uint32), lower[keep].view(np.uint32))
    assert np.array_equal(up[keep].view(np.uint32), upper[keep].view(np.uint32))
