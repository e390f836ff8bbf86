"""golden/paper.py: each of the papers' formulations against the formula written out here, in float32 and float64.

Two statements per formulation:

* float64: on well-conditioned rows (biased moments of one to four depths, receivers away from the support; for
  Algorithm 3 non-linear moments away from y2) it is the bound itself: moments_ref.precise's mpmath Algorithm 1
  (lower and upper) or the clamped Algorithm 3 in mpmath (golden.truth.shade_clamped);
* float32: bit for bit the formula as the source prints it, evaluated here operation by operation in float32: the
  slides' "Compute the shadow intensity" (HLSL; ``mad(a, b, c)`` as a·b + c, two roundings, ``dot`` as a sum of
  products, ``saturate`` as a clip), HPG17 Algorithm 1 as printed (steps (2) to (5): B = L D Lᵀ, the textbook
  quadratic formula, the Vandermonde weights in closed form), the Cholesky evaluation of Peters and Klein 2015,
  Prop. 10 (fused or not), and HPG17 Algorithm 3 with the §3.4 clamps. One departure of the code from the slides
  is kept here as the code has it: p and q are c1 / c2 and c0 / c2 (the slides multiply by InvC2 = 1 / c2).

Each NaN is where the formula divides by zero (kept, never clipped), each value in [0, 1] (Algorithm 1) where it has
one. The spread hooks built afresh (``alg1_paper_spread``, ``alg3_paper_spread``) return exactly these evaluations.
"""

from __future__ import annotations

import numpy as np
import pytest

from moments_ref import precise
from moments_ref.golden import paper
from moments_ref.golden.truth import shade_clamped
from moments_ref.moments import BIAS_FLOAT32

BOUNDS = ("lower", "upper")


def _rows(n=400, seed=17):
    """Biased moments of one to four depths (float64, float32-representable receivers), and rows with no value."""
    rng = np.random.default_rng(seed)
    k = rng.integers(1, 5, n)
    z = rng.uniform(-0.95, 0.95, (n, 4))
    w = rng.uniform(0.05, 1, (n, 4)) * (np.arange(4) < k[:, None])
    w /= w.sum(1, keepdims=True)
    b = np.stack([(w * z**j).sum(1) for j in range(1, 5)], axis=1)
    a, t = BIAS_FLOAT32.alpha, np.asarray(BIAS_FLOAT32.target)
    b = (1 - a) * b + a * t
    zf = rng.uniform(-1, 1, n).astype(np.float32).astype(np.float64)
    far = np.abs(z[:, :, None] - zf[:, None, None]).min(axis=(1, 2)) > 1e-2
    return b, zf, far


def _singular():
    """Unbiased moments of one depth (B(b) singular) and of two (ξ4 = 0): the formulas divide by zero."""
    b = np.array([[0.5, 0.25, 0.125, 0.0625], [0.0, 0.25, 0.0, 0.0625]])
    return b, np.array([0.75, 0.1])


def _dyadic():
    """Edge rows. Unbiased moments of three dyadic depths with the receiver at the lowest one: every step of the slides' code is
    exact in float32, so the larger root lands exactly on 0 or 1 where no Switch applies (zf below both roots)."""
    def moments(z, w):
        return [sum(wi * zi**k for zi, wi in zip(z, w)) for k in range(1, 5)]

    b = np.array([moments([-0.75, -0.5, 0.0], [0.25, 0.25, 0.5]), moments([-0.75, -0.5, 1.0], [0.25, 0.25, 0.5]),
                  # biased moments of two depths, the receiver near one: HPG17's printed weights reach −∞ in
                  # float32 (a root on zf), which the clip makes 0 (found by a search over 200 000 such rows)
                  [-0.170774815152704, 0.5377617177384723, 0.010871267717502502, 0.3099287335480629],
                  # and two where the Cholesky evaluation's discriminant is below 1 (float32 and float64)
                  [-0.3298645417663087, 0.724223817219766, -0.22394141441809362, 0.5248636318309452],
                  [0.6659768579158193, 0.8963402369860792, 0.6033290836735886, 0.803516065112089],
                  # and two dyadic rows with q1 = 0 exactly in the Cholesky evaluation (the root's sign choice)
                  [-0.5, 0.625, -0.5, 0.53125], [-0.1875, 0.5703125, -0.0263671875, 0.5098876953125],
                  # and moments outside the moment space with b2 < b1² but ξ4 > 0: the Cholesky ports' σ² ≤ 0 branch
                  [0.5, 0.2, 0.1, 0.3]])
    return b, np.array([-0.75, -0.75, 0.8641511797904968, -0.8436462879180908, 0.9488574266433716, 0.25, -0.375,
                        0.3])


def _t(dt):
    return np.dtype(dt).type


def slides(b, zf, bound, dt):
    """Slides, "Compute the shadow intensity", in ``dt``."""
    t = _t(dt)
    b = b.astype(dt)
    z0 = zf.astype(dt)
    with np.errstate(all="ignore"):
        L32D22 = -b[:, 0] * b[:, 1] + b[:, 2]
        D22 = -b[:, 0] * b[:, 0] + b[:, 1]
        SquaredDepthVariance = -b[:, 1] * b[:, 1] + b[:, 3]
        D33D22 = SquaredDepthVariance * D22 + (-L32D22) * L32D22
        InvD22 = t(1) / D22
        L32 = L32D22 * InvD22
        c0, c1, c2 = np.ones_like(z0), z0, z0 * z0
        c1 = c1 - b[:, 0]
        c2 = c2 - (b[:, 1] + L32 * c1)
        c1 = c1 * InvD22
        c2 = c2 * (D22 / D33D22)
        c1 = c1 - L32 * c2
        c0 = c0 - (c1 * b[:, 0] + c2 * b[:, 1])
        p, q = c1 / c2, c0 / c2  # the slides: c1 * InvC2, c0 * InvC2
        r = np.sqrt(p * p * t(0.25) - q)
        z1, z2 = -p * t(0.5) - r, -p * t(0.5) + r
        s = np.zeros((len(z0), 4), dt)
        far, mid = z2 < z0, ~(z2 < z0) & (z1 < z0)
        s[far] = np.stack([z1[far], z0[far], np.ones(far.sum(), dt), np.ones(far.sum(), dt)], 1)
        s[mid] = np.stack([z0[mid], z1[mid], np.zeros(mid.sum(), dt), np.ones(mid.sum(), dt)], 1)
        quotient = (s[:, 0] * z2 - b[:, 0] * (s[:, 0] + z2) + b[:, 1]) / ((z2 - s[:, 1]) * (z0 - z1))
        out = s[:, 2] + s[:, 3] * quotient
        if bound == "upper":  # plus the weight of zf: (z1 z2 − b1 (z1 + z2) + b2) / ((zf − z1)(zf − z2))
            out = out + (z1 * z2 - b[:, 0] * (z1 + z2) + b[:, 1]) / ((z0 - z1) * (z0 - z2))
        return _saturate(out, dt)


def _saturate(out, dt):
    keep = np.isnan(out)
    return np.where(keep, out, np.minimum(np.maximum(out, 0), 1)).astype(dt)


def printed(b, zf, bound, dt):
    """HPG17 Algorithm 1 as printed, steps (2) to (5), in ``dt``."""
    t = _t(dt)
    b = b.astype(dt)
    z0 = zf.astype(dt)
    b1, b2, b3, b4 = b.T
    with np.errstate(all="ignore"):
        # (2) B q = (1, zf, zf²) with B = L D Lᵀ: D = diag(1, d22, d33), L's entries b1, b2 and l32
        d22 = b2 - b1 * b1
        l32 = (b3 - b1 * b2) / d22
        d33 = (b4 - b2 * b2) - l32 * l32 * d22
        y1 = z0 - b1
        y2 = z0 * z0 - b2 - l32 * y1
        q2 = y2 / d33
        q1 = y1 / d22 - l32 * q2
        q0 = t(1) - b1 * q1 - b2 * q2
        # (3) the roots of q2 z² + q1 z + q0
        disc = np.sqrt(q1 * q1 - t(4) * q2 * q0)
        r1, r2 = (-q1 - disc) / (t(2) * q2), (-q1 + disc) / (t(2) * q2)
        z1, z2 = np.minimum(r1, r2), np.maximum(r1, r2)
        # (4) the weights of z0 = zf, z1, z2 (Lagrange form of the Vandermonde solve)
        w0 = (z1 * z2 - b1 * (z1 + z2) + b2) / ((z0 - z1) * (z0 - z2))
        w1 = (z0 * z2 - b1 * (z0 + z2) + b2) / ((z1 - z0) * (z1 - z2))
        w2 = (z0 * z1 - b1 * (z0 + z1) + b2) / ((z2 - z0) * (z2 - z1))
        # (5) the weights below zf (the upper bound: at or below)
        below = (lambda z: z <= z0) if bound == "upper" else (lambda z: z < z0)
        out = np.where(below(z1), w1, t(0)) + np.where(below(z2), w2, t(0))
        if bound == "upper":
            out = out + w0
        return _saturate(out, dt)


def cholesky(b, zf, bound, dt, fma=False):
    """Peters and Klein 2015, Prop. 10: the plain Cholesky evaluation of the ports, in ``dt`` (``fma``: each a·b + c
    rounded once more in float64 before ``dt``, as paper._fma documents)."""
    t = _t(dt)
    b = b.astype(dt)
    zf = zf.astype(dt)

    def mad(x, y, z):
        if fma and dt == np.float32:
            return (x.astype(np.float64) * y.astype(np.float64) + z.astype(np.float64)).astype(dt)
        return x * y + z

    b1, b2, b3, b4 = b.T
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
        z1, z2 = np.minimum(tt / q2, q0 / tt), np.maximum(tt / q2, q0 / tt)
        w0 = t(1) / (t(1) + y2 * y2 / sigma2 + y3 * y3 / xi4)
        u2 = z1 - b1
        u3 = mad(z1, z1, -b2) - l32 * u2
        w1 = t(1) / (t(1) + u2 * u2 / sigma2 + u3 * u3 / xi4)
        w1 = np.where(np.isinf(z1), t(0), w1)
        low = np.where(zf <= z1, t(0), np.where(zf <= z2, w1, t(1) - w0))
        out = np.clip(low + w0 if bound == "upper" else low, 0, 1)
        return np.where((sigma2 > 0) & (xi4 > 0), out, np.nan).astype(dt)


FORMULAS = {"slides": (paper.slides_bound, slides), "printed": (paper.printed_bound, printed),
            "cholesky": (paper.cholesky_bound, cholesky)}


@pytest.mark.parametrize("name", list(FORMULAS))
@pytest.mark.parametrize("bound", BOUNDS)
def test_each_algorithm_1_formulation_in_float64_is_the_bound(name, bound):
    code, _ = FORMULAS[name]
    b, zf, far = _rows()
    got = code(b, zf, bound, np.float64)
    assert got.dtype == np.float64
    want = precise.shadow_intensity(b[far], zf[far], bound)
    np.testing.assert_allclose(got[far], want, rtol=0, atol=1e-6)
    assert np.nanmin(got) >= 0 and np.nanmax(got) <= 1


@pytest.mark.parametrize("name", list(FORMULAS))
@pytest.mark.parametrize("bound", BOUNDS)
@pytest.mark.parametrize("dt", [np.float32, np.float64])
def test_each_algorithm_1_formulation_is_the_printed_formula_bit_for_bit(name, bound, dt):
    code, formula = FORMULAS[name]
    b, zf, _ = _rows()
    db, dz = _dyadic()
    sb, sz = _singular()
    b, zf = np.concatenate([b, db, sb]), np.concatenate([zf, dz, sz])
    got = code(b, zf, bound, dt)
    assert got.dtype == dt
    np.testing.assert_array_equal(got, formula(b, zf, bound, dt))
    # the singular rows: no value, kept as NaN (HPG17's lower bound as printed sums no weight there: NaN roots are
    # below no receiver)
    assert np.isnan(got[-2:]).any() == (name != "printed" or bound == "upper")


@pytest.mark.parametrize("bound", BOUNDS)
def test_the_fused_cholesky_evaluation_rounds_each_mad_once_in_float64(bound):
    b, zf, _ = _rows()
    fused = paper.cholesky_bound(b, zf, bound, np.float32, fma=True)
    np.testing.assert_array_equal(fused, cholesky(b, zf, bound, np.float32, fma=True))
    assert (fused != paper.cholesky_bound(b, zf, bound, np.float32)).sum() > 5  # fusing changes some rows
    np.testing.assert_array_equal(paper.cholesky_bound(b, zf, bound, np.float64, fma=True),
                                  cholesky(b, zf, bound, np.float64))  # float64: a·b + c as it is


def test_the_algorithm_1_spread_hook_built_afresh_holds_the_four_evaluations():
    b, zf, _ = _rows(60)
    for bound in BOUNDS:
        for dt in (np.float32, np.float64):
            out = paper.alg1_paper_spread(bound)({"b": b, "zf": zf}, dt)
            want = [slides(b, zf, bound, dt), printed(b, zf, bound, dt), cholesky(b, zf, bound, dt),
                    cholesky(b, zf, bound, dt, fma=True)]
            assert len(out) == 4 and all(len(o) == 1 for o in out)
            for o, w in zip(out, want):
                np.testing.assert_array_equal(o[0], w)


# ---------------------------------------------------------------------------
# HPG17 Algorithm 3 as printed


def alg3(r, zf, dt, clamp=1e-6, case_test="stored"):
    """HPG17 Algorithm 3 with the §3.4 clamps (v2 in [ε, 1 − ε], y2 − y1 ≥ ε), in ``dt``; 1/w_l's last term
    (1 − z_l)² z_l² / ξ'4."""
    t = _t(dt)
    r = r.astype(dt)
    zf = zf.astype(dt)
    y1, y2, v2, xi4 = r.T
    eps = t(clamp)
    with np.errstate(all="ignore"):
        v2 = np.minimum(np.maximum(v2, eps), t(1) - eps)
        gap = np.maximum(y2 - y1, eps)
        zp = (zf - y1) / gap  # z'f
        xip = xi4 / ((gap * gap) * (gap * gap))  # ξ'4
        inside = zf <= y2 if case_test == "stored" else zp < 1
        q0 = -xip / ((t(1) - v2) * zp)
        q1 = -q0 * (v2 - zp) / (v2 - v2 * zp) - t(1)
        zl = np.where(inside, -q1 / t(2) - np.sqrt(q1 * q1 / t(4) - q0), zp)
        wl = t(1) / ((t(1) - zl) * (t(1) - zl) / (t(1) - v2) + zl * zl / v2 + (t(1) - zl) * (t(1) - zl) * zl * zl / xip)
        return np.where(zf <= y1, t(0), np.where(inside, wl, t(1) - wl)).astype(dt)


def _nlq_rows(n=300, seed=5):
    rng = np.random.default_rng(seed)
    y = np.sort(rng.uniform(-0.9, 0.9, (n, 2)), axis=1)
    v2 = rng.uniform(0.05, 0.95, n)
    xi4 = 10 ** rng.uniform(-6, -2, n)
    r = np.stack([y[:, 0], y[:, 1], v2, xi4], axis=1)
    zf = rng.uniform(-1, 1, n).astype(np.float32).astype(np.float64)
    # edge rows: the clamps (v2 = 0 and 1, y1 = y2), a receiver at y2 and at y1 (also with y2 < y1: no decoder's)
    edge = np.array([[-0.2, 0.3, 0.0, 1e-3], [-0.2, 0.3, 1.0, 1e-3], [0.1, 0.1, 0.5, 1e-4], [-0.5, 0.25, 0.4, 1e-3],
                     [-0.5, 0.25, 0.4, 1e-3], [0.1, 0.1 + 2e-7, 0.5, 1e-4], [0.3, 0.1, 0.4, 1e-3]])
    ez = np.array([0.0, 0.0, 0.1 + 5e-8, 0.25, -0.5, 0.1 + 1e-7, 0.3])
    return np.concatenate([r, edge]), np.concatenate([zf, ez]), np.abs(zf - y[:, 1]) > 1e-2


@pytest.mark.parametrize("case_test", ["stored", "clamped"])
def test_printed_algorithm_3_in_float64_is_the_clamped_algorithm_3(case_test):
    r, zf, away = _nlq_rows()
    n = len(away)
    got = paper.printed_shade(r, zf, np.float64, case_test=case_test)
    assert got.dtype == np.float64
    want = shade_clamped(r[:n][away], zf[:n][away], case_test=case_test)
    np.testing.assert_allclose(got[:n][away], want, rtol=0, atol=1e-7)


@pytest.mark.parametrize("case_test", ["stored", "clamped"])
@pytest.mark.parametrize("clamp", [1e-6, 5e-6])
@pytest.mark.parametrize("dt", [np.float32, np.float64])
def test_printed_algorithm_3_is_the_printed_formula_bit_for_bit(case_test, clamp, dt):
    r, zf, _ = _nlq_rows()
    got = paper.printed_shade(r, zf, dt, clamp, case_test)
    assert got.dtype == dt
    np.testing.assert_array_equal(got, alg3(r, zf, dt, clamp, case_test))
    if case_test == "stored":
        assert np.isnan(got[-4])  # zf = y2 exactly: the printed root has no value (q1 = ±∞)


def test_printed_algorithm_3_reads_its_clamp_and_case_test():
    r, zf, _ = _nlq_rows()
    a = paper.printed_shade(r, zf, np.float32)
    assert (a != paper.printed_shade(r, zf, np.float32, clamp=0.1)).sum() > 10
    assert not np.array_equal(a[-7:], paper.printed_shade(r, zf, np.float32, case_test="clamped")[-7:], equal_nan=True)


def test_the_algorithm_3_spread_hook_built_afresh_is_the_printed_formula():
    r, zf, _ = _nlq_rows(40)
    for dt in (np.float32, np.float64):
        out = paper.alg3_paper_spread(5e-6, "clamped")({"r": r, "zf": zf}, dt)
        assert len(out) == 1 and len(out[0]) == 1
        np.testing.assert_array_equal(out[0][0], alg3(r, zf, dt, 5e-6, "clamped"))


def test_kept_mutants_the_cholesky_roots_sign_choice_and_the_slides_switch_are_seen():
    from _mutants import kept_mutant

    for mid, name in (("cholesky_bound::q1 < 0 -> q1 <= 0#0", "cholesky"), ("_slides_nudged::0 -> 1#2", "slides")):
        with kept_mutant("moments_ref/golden/paper.py", mid):
            with pytest.raises(AssertionError):
                test_each_algorithm_1_formulation_is_the_printed_formula_bit_for_bit(name, "lower", np.float32)
