"""Six-moment bounds (moments_ref.msm6) checked by independent means.

References, none of them msm6 itself: the exact Z of the drawn distribution
(strategies.exact_shadow), the mpmath twin (precise.shadow_bounds6: lu_solve,
polyroots, Vandermonde at 50 digits), a linear program over distributions on a
grid (HiGHS), and the fact that at most three depths are the unique distribution
with their six moments.

Tolerances:

* ALPHA = BIAS6_FLOAT64.alpha (float64), ALPHA32 = BIAS6_FLOAT32.alpha (float32):
  biased moments are those of (1 − α) Z + α Z* (Z* the five-point target), so the
  sharp lower bound is at most Z(z < zf) + α.
* float32 bracket: ALPHA32 + 1e-3 (msm6 docstring: worst excess measured 6.9e-4
  with zf at and next to support points; 1.0 with α = 3e-7, which
  test_float32_needs_stronger_bias keeps).
* float64 against precise: 1e-8 (measured worst over 300 random biased cases
  3.1e-12; near support points the roots are ill-conditioned, stated with margin).
* float32 against precise away (≥ 0.05) from support points: 2e-2 (measured worst
  1.3e-3 on 300 random cases).
"""

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from moments_ref import InputError, msm, msm6, precise
from moments_ref.moments import bias_moments, power_moments
from moments_ref._msm6_rows import bounds_chunk
from moments_ref.tools.strategies import depth_distributions, depths, exact_shadow

from _oracles import check_bounds, lp_grid, lp_lower, zf_candidates

ALPHA = msm6.BIAS6_FLOAT64.alpha
ALPHA32 = msm6.BIAS6_FLOAT32.alpha
F64_VS_PRECISE = 1e-8
F32_VS_PRECISE_FAR = 2e-2
F32_SLACK = ALPHA32 + 1e-3


def _check(bounds, z, w, zf, dtype, slack):
    """:func:`_oracles.check_bounds` of six moments, biased with the preset of their dtype."""
    preset = msm6.BIAS6_FLOAT32 if dtype == np.float32 else msm6.BIAS6_FLOAT64
    check_bounds(bounds, z, w, zf, dtype, slack, preset, n=6)


@given(depth_distributions(), depths())
def test_bounds_biased_float64(dist, zf):
    z, w = dist
    _check(msm6.shadow_bounds, z, w, zf_candidates(z, zf), np.float64, ALPHA + 1e-9)


@given(depth_distributions(), depths())
def test_bounds_biased_float32(dist, zf):
    z, w = dist
    _check(msm6.shadow_bounds, z, w, zf_candidates(z, zf), np.float32, F32_SLACK)


@settings(max_examples=25)
@given(depth_distributions(max_points=6), depths())
def test_bounds_biased_precise(dist, zf):
    z, w = dist
    _check(precise.shadow_bounds6, z, w, zf_candidates(z, zf)[:4], np.float64, ALPHA + 1e-15)


def test_float32_needs_stronger_bias():
    # One depth at 0.9, zf = 0.9 in float32: Z(z < zf) = 0. With α = 3e-7 the float32 pivots
    # drown in rounding and the lower bound comes out 1.0; BIAS6_FLOAT32 keeps it bracketed.
    b32 = power_moments(np.array([0.9]), n=6).astype(np.float32)
    zf = np.float32(0.9)
    weak = msm6.shadow_intensity(bias_moments(b32, msm6.BIAS6_FLOAT64), zf)
    assert weak > 0.0 + 0.1
    assert msm6.shadow_intensity(bias_moments(b32, msm6.BIAS6_FLOAT32), zf) <= 0.0 + F32_SLACK
    # Z = ¼ δ−1 + ½ δ0 + ¼ δ1, zf = 1: Z(z < zf) = 0.75. The witness of the weak bias until the
    # trigonometric cubic was replaced (it gave 1.0; the Sturm count and one root give 0.75).
    z, w = np.array([-1.0, 0.0, 1.0]), np.array([0.25, 0.5, 0.25])
    b32 = power_moments(z, w, n=6).astype(np.float32)
    assert msm6.shadow_intensity(bias_moments(b32, msm6.BIAS6_FLOAT32), np.float32(1.0)) <= 0.75 + F32_SLACK


def test_bounds_check_has_power():
    # Mutant: reporting the upper bound as the lower one is caught.
    z, w = np.array([-0.5, 0.2, 0.7, 0.9]), np.array([0.3, 0.3, 0.2, 0.2])
    mutant = lambda b, zf: (msm6.shadow_bounds(b, zf)[1],) * 2
    with pytest.raises(AssertionError):
        _check(mutant, z, w, zf_candidates(z, 0.0), np.float64, ALPHA)


@given(st.lists(st.floats(-1, 1), min_size=1, max_size=3, unique=True), st.floats(-1, 1))
def test_at_most_three_depths_are_exact(zs, zf):
    # Unique distribution: both bounds equal Z (away from the support points by 1e-6).
    z = np.array(zs)
    assume(np.abs(z - zf).min() >= 1e-6)
    if len(z) > 1:
        assume(np.diff(np.sort(z)).min() >= 1e-2)  # well separated: pivots far from rounding
    w = np.full(len(z), 1 / len(z))
    b = power_moments(z, w, n=6)
    lo, up = msm6.shadow_bounds(b, zf)
    assert lo == pytest.approx(exact_shadow(z, w, zf), abs=1e-6)
    assert up == pytest.approx(exact_shadow(z, w, zf, strict=False), abs=1e-6)


# ---------------------------------------------------------------------------
# canonical representation


@given(depth_distributions(min_points=4), depths())
def test_canonical_reproduces_moments(dist, zf):
    z, w = dist
    b = bias_moments(power_moments(z, w, n=6), msm6.BIAS6_FLOAT64)
    d, wt = msm6.canonical_representation(b, zf)
    assert d.shape == (4,) and (wt >= -1e-12).all()
    finite = np.isfinite(d)
    assert (wt[~finite] == 0).all()
    assume(np.abs(d[finite]).max() <= 3)
    dd = np.where(finite, d, 0.0)
    full = [1.0] + b.tolist()
    for k in range(7):
        scale = (wt * np.abs(dd) ** k).sum()
        assert abs((wt * dd**k).sum() - full[k]) <= 1e-7 * max(scale, 1.0), k


def test_canonical_against_precise():
    rng = np.random.default_rng(4)
    z, w = rng.uniform(-1, 1, (40, 5)), rng.uniform(0.1, 1, (40, 5))
    b = bias_moments(power_moments(z, w, n=6), msm6.BIAS6_FLOAT64)
    zf = rng.uniform(-1, 1, 40)
    d, wt = msm6.canonical_representation(b, zf)
    dx, wx = precise.canonical_representation6(b, zf)
    np.testing.assert_allclose(wt, wx, atol=1e-9)
    big = np.abs(dx) < 5
    np.testing.assert_allclose(d[big], dx[big], atol=1e-8)


def test_canonical_check_has_power():
    b = bias_moments(power_moments(np.array([-0.5, 0.2, 0.7, 0.9]), np.array([0.3, 0.3, 0.2, 0.2]), n=6),
                     msm6.BIAS6_FLOAT64)
    d, w = msm6.canonical_representation(b, 0.1)
    w = w[[0, 2, 1, 3]]  # mutant: two weights swapped
    assert abs((w * d).sum() - b[0]) > 1e-3


# ---------------------------------------------------------------------------
# the trig-free cubic: cos(arccos(r)/3), the extreme root, the Sturm count


@pytest.mark.parametrize("dt, refine, tol", [(np.float64, 0, 2e-7), (np.float64, 1, 2e-14), (np.float32, 0, 4e-7)])
def test_cos_third_against_trigonometry(dt, refine, tol):
    r = np.linspace(-1, 1, 20001).astype(dt)
    exact = np.cos(np.arccos(r.astype(np.float64)) / 3)
    got = msm6._cos_third(r, refine)
    assert got.dtype == dt
    assert np.abs(got - exact).max() <= tol
    # ρ a little beyond ±1 (rounding): the value next to the end, no NaN
    out = msm6._cos_third(np.array([-1 - 1e-7, 1 + 1e-7], dtype=dt), refine)
    assert np.isfinite(out).all() and abs(out[0] - msm6._cos_third(np.array([-1 + 1e-7], dtype=dt))[0]) <= 1e-6
    assert abs(out[1] - 1) <= 1e-6


def _cubics(rng, n, sigma):
    """Cubics as in the kernel: the σ-extreme root alone on its side of 0, magnitudes 1e-4..1e3."""
    one = sigma * 10.0 ** rng.uniform(-4, 3, n)
    others = -sigma * 10.0 ** rng.uniform(-4, 3, (n, 2))
    roots = np.column_stack([one, others])
    c0 = 10.0 ** rng.uniform(0, 3, n)
    c1 = -c0 * roots.sum(1)
    c2 = c0 * (roots[:, 0] * roots[:, 1] + roots[:, 0] * roots[:, 2] + roots[:, 1] * roots[:, 2])
    return (c0, c1, c2, -c0 * roots.prod(1)), roots


@pytest.mark.parametrize("sigma", [1.0, -1.0])
def test_extreme_root_against_known_roots(sigma):
    # float64 steps (one on cos(arccos(r)/3), two on the cubic): the root to its own size,
    # also when it is 1e7 times smaller than the others (measured worst 8e-16). Without the
    # step on cos(arccos(r)/3) the fit's 1.6e-7 leaves 5e-3 there (the check has power).
    (c0, c1, c2, c3), roots = _cubics(np.random.default_rng(21), 4000, sigma)
    with np.errstate(all="ignore"):
        t = msm6._extreme_root(c0, c1, c2, c3, np.full(4000, sigma), newton=2, refine=1)
        weak = msm6._extreme_root(c0, c1, c2, c3, np.full(4000, sigma), newton=2, refine=0)
    rel = np.abs(t - roots[:, 0]) / np.abs(roots[:, 0])
    assert rel.max() <= 1e-13
    assert (np.abs(weak - roots[:, 0]) / np.abs(roots[:, 0])).max() > 1e-6
    # all three: two roots of one side may nearly meet (ill-conditioned: 6e-8 seen for a gap of 6 %)
    three = np.sort(msm6.solve_cubic(c0, c1, c2, c3), axis=0)
    np.testing.assert_allclose(three, np.sort(roots.T, axis=0), rtol=1e-6, atol=0)


def test_solve_cubic_multiple_roots():
    # a triple root (m = 0: r is 0/0) and a double one
    np.testing.assert_allclose(msm6.solve_cubic([1.0, 1.0], [-3.0, 0.0], [3.0, -3.0], [-1.0, -2.0]),
                               [[1, 2], [1, -1], [1, -1]], atol=1e-5)


@given(depth_distributions(min_points=2), st.floats(-1, 1))
def test_sturm_count_is_the_number_of_roots_below_zf(dist, zf):
    # The signs of y = (1, P1, P2, P3)(zf) decide the case of step 5; checked against the
    # canonical representation of the mpmath twin (roots of q by polyroots, 50 digits).
    z, w = dist
    b = bias_moments(power_moments(z, w, n=6), msm6.BIAS6_FLOAT64)
    with np.errstate(all="ignore"):
        ldl, (y1, y2, y3), _ = msm6._reversed_cubic(b[:, None], np.array([zf]))
    assume(min(abs(y1[0]), abs(y2[0]), abs(y3[0])) > 1e-9)  # not at a node: the count is exact
    signs = [True, y1[0] >= 0, y2[0] >= 0, y3[0] >= 0]
    changes = sum(a != b for a, b in zip(signs, signs[1:]))  # Gauss nodes above zf
    d, _ = precise.canonical_representation6(b, zf)
    below = int((d[1:] < zf).sum())  # a root at infinity (+inf here) needs y3 = 0, excluded
    assert 3 - changes == below


def test_sturm_count_has_power():
    # Mutant: the root of the wrong side (sigma flipped) breaks the bracket of the bounds.
    z, w = np.array([-0.8, -0.3, 0.1, 0.5, 0.9]), np.array([0.2, 0.2, 0.2, 0.2, 0.2])
    zf = zf_candidates(z, 0.3)
    real = msm6.root_rows

    def flipped(cubic, steps, ws):  # sigma flipped for the root alone (step 5 keeps the true count)
        odd = ws["mask"][2]
        np.logical_not(odd, out=odd)
        try:
            return real(cubic, steps, ws)
        finally:
            np.logical_not(odd, out=odd)

    _check(msm6.shadow_bounds, z, w, zf, np.float64, ALPHA)
    msm6.root_rows = flipped
    try:
        with pytest.raises(AssertionError):
            _check(msm6.shadow_bounds, z, w, zf, np.float64, ALPHA)
    finally:
        msm6.root_rows = real


@pytest.mark.parametrize("dt, tol", [(np.float32, 5e-6), (np.float64, 1e-11)])
def test_stiff_golden_rows_match_precise(dt, tol):
    # The golden case's stiff and edge rows (six depths within 0 .. 1e-2 of 0.3 with zf = b1,
    # three depths −1, 0, 1, zf at or beyond ±1). Measured: float32 3.3e-7 (the trigonometric
    # kernel: 1.6e-5), float64 4.3e-13.
    from moments_ref.golden._rows import _msm6_rows

    rows = _msm6_rows(np.random.default_rng(3), dt)
    hard = np.asarray(rows.category) != "random"
    b = np.asarray(rows.inputs["b"])[hard].astype(dt)
    zf = np.asarray(rows.inputs["zf"])[hard].astype(dt)
    lo, up = msm6.shadow_bounds(b, zf)
    plo, pup = precise.shadow_bounds6(b, zf)
    assert np.abs(lo - plo).max() <= tol and np.abs(up - pup).max() <= tol


# ---------------------------------------------------------------------------
# sharpness: the lower bound is the minimum of a linear program over distributions


SHARP_CASES = [
    ([-0.8, -0.1, 0.4, 0.9], [0.3, 0.2, 0.3, 0.2], 0.1),
    ([-0.5, 0.0, 0.3, 0.6, 0.8], [0.2, 0.2, 0.2, 0.2, 0.2], 0.45),
]
SHARP_ALPHA = 0.05
GRIDS = (201, 801, 3201)
LP_FINAL_TOL = 5e-3


@pytest.mark.parametrize("z, w, zf", SHARP_CASES)
def test_lower_bound_is_sharp(z, w, zf):
    b = bias_moments(power_moments(np.array(z), np.array(w), n=6), (SHARP_ALPHA, msm6.BIAS6_TARGET))
    exact = float(precise.shadow_intensity6(b, zf))
    d, _ = precise.canonical_representation6(b, zf)
    assert np.abs(d).max() < 3
    gaps = []
    for n in GRIDS:
        lp = lp_lower(b, zf, lp_grid(n))
        assert lp >= exact - 1e-7  # grid distributions are a subset
        gaps.append(lp - exact)
    assert gaps[-1] <= LP_FINAL_TOL, gaps
    assert gaps[-1] <= 0.5 * gaps[0] + 1e-9, gaps
    assert float(msm6.shadow_intensity(b, zf)) == pytest.approx(exact, abs=1e-9)


def test_sharpness_check_has_power():
    z, w, zf = SHARP_CASES[0]
    b = bias_moments(power_moments(np.array(z), np.array(w), n=6), (SHARP_ALPHA, msm6.BIAS6_TARGET))
    assert float(msm6.shadow_intensity(b, zf)) + 0.02 > lp_lower(b, zf, lp_grid(GRIDS[-1]))


# ---------------------------------------------------------------------------
# float32 / float64 against precise


@settings(max_examples=30)
@given(depth_distributions(kind="random", min_points=2), depths())
def test_float64_matches_precise(dist, zf):
    z, w = dist
    b = bias_moments(power_moments(z, w, n=6), msm6.BIAS6_FLOAT64)
    zf = np.array([zf, *(np.clip(z + 1e-3, -1, 1))])
    lo, up = msm6.shadow_bounds(b, zf)
    plo, pup = precise.shadow_bounds6(b, zf)
    np.testing.assert_allclose(lo, plo, atol=F64_VS_PRECISE)
    np.testing.assert_allclose(up, pup, atol=F64_VS_PRECISE)


@settings(max_examples=30)
@given(depth_distributions(kind="random", min_points=2), st.floats(-1, 1))
def test_float32_matches_precise_away_from_support(dist, zf):
    z, w = dist
    assume(np.abs(z - zf).min() >= 0.05)
    b = bias_moments(power_moments(z, w, n=6).astype(np.float32), msm6.BIAS6_FLOAT32)
    zf32 = np.float32(zf)
    lo, up = msm6.shadow_bounds(b, zf32)
    assert lo.dtype == np.float32 and up.dtype == np.float32
    plo, pup = precise.shadow_bounds6(b, zf32)
    assert abs(float(lo) - float(plo)) <= F32_VS_PRECISE_FAR
    assert abs(float(up) - float(pup)) <= F32_VS_PRECISE_FAR


# ---------------------------------------------------------------------------
# stiff input, singular branches, dispatch, bad input


@pytest.mark.parametrize("dt", [np.float32, np.float64])
def test_stiff_inputs_never_nonfinite(dt):
    rng = np.random.default_rng(7)
    cases = []
    for k in (1, 2, 3, 4, 6):  # 1–3 depths: singular; clustered depths: nearly singular
        for spread in (0.0, 1e-7, 1e-4, 1e-2, 1.0):
            c = rng.uniform(-1, 1, (50, 1))
            z = np.clip(c + spread * rng.uniform(-1, 1, (50, k)), -1, 1)
            cases.append(power_moments(z, rng.uniform(0.01, 1, (50, k)), n=6))
    b = np.concatenate(cases).astype(dt)
    b = np.concatenate([b, b + dt(1e-3) * rng.standard_normal(b.shape).astype(dt)])  # partly outside
    zf = rng.uniform(-1, 1, b.shape[0]).astype(dt)
    zf[::3] = b[::3, 0]  # zf at the mean
    for biased in (False, True):
        bb = bias_moments(b, msm6.BIAS6_FLOAT32 if dt == np.float32 else msm6.BIAS6_FLOAT64) if biased else b
        with np.errstate(all="raise"):
            lo, up = msm6.shadow_bounds(bb, zf)
        assert lo.dtype == dt
        assert np.isfinite(lo).all() and np.isfinite(up).all()
        assert ((0 <= lo) & (lo <= up) & (up <= 1)).all()
        d, w = msm6.canonical_representation(bb, zf)
        assert np.isfinite(w).all()


@pytest.mark.parametrize("dt", [np.float32, np.float64])
def test_degenerate_vectors(dt):
    b = np.array([
        [0.0] * 6,  # one depth at 0
        [1.0] * 6,  # one depth at 1
        [0.0, 1.0, 0.0, 1.0, 0.0, 1.0],  # ±1
        [0.0, 0.25, 0.0, 0.0625, 0.0, 0.015625],  # ±1/2
        [0.5, 0.2, 0.1, 0.05, 0.02, 0.01],  # D1 < 0: outside
    ], dtype=dt)
    zf = np.array([-1.0, -0.5, 0.0, 0.5, 1.0], dtype=dt)[:, None]
    out = msm6.shadow_intensity(b, zf)
    assert out.shape == (5, 5) and np.isfinite(out).all()
    np.testing.assert_array_equal(out[:, 3], exact_shadow([-0.5, 0.5], [0.5, 0.5], zf[:, 0].astype(np.float64)))


def test_singular_matches_precise():
    b = power_moments(np.array([[-0.6, 0.1, 0.7], [-0.2, 0.4, 0.4]]), np.array([[0.2, 0.5, 0.3], [0.5, 0.3, 0.2]]), n=6)
    zf = np.array([-0.7, -0.3, 0.0, 0.3, 0.55, 0.8])[:, None]
    for bound in ("lower", "upper"):
        np.testing.assert_allclose(msm6.shadow_intensity(b, zf, bound), precise.shadow_intensity6(b, zf, bound),
                                   atol=1e-9)


def test_msm_dispatches_six_moments():
    rng = np.random.default_rng(9)
    b6 = bias_moments(power_moments(rng.uniform(-1, 1, (20, 5)), n=6), msm6.BIAS6_FLOAT64)
    zf = rng.uniform(-1, 1, 20)
    np.testing.assert_array_equal(msm.shadow_intensity(b6, zf), msm6.shadow_intensity(b6, zf))
    np.testing.assert_array_equal(msm.shadow_intensity(b6, zf, "upper"), msm6.shadow_intensity(b6, zf, "upper"))
    d, w = msm.canonical_representation(b6, zf)
    assert d.shape == (20, 4) and w.shape == (20, 4)
    # the four-moment path is unchanged: three-point canonical representation
    d4, w4 = msm.canonical_representation(b6[:, :4], zf)
    assert d4.shape == (20, 3)
    # six moments carry more information: for four depths the six-moment bounds are tighter
    z = np.array([-0.7, -0.2, 0.3, 0.8])
    b = power_moments(z, n=6)
    gap6 = msm.shadow_intensity(b, 0.1, "upper") - msm.shadow_intensity(b, 0.1)
    gap4 = msm.shadow_intensity(b[:4], 0.1, "upper") - msm.shadow_intensity(b[:4], 0.1)
    assert gap6 < gap4


def test_bad_input():
    with pytest.raises(InputError, match="trailing axis"):
        msm6.shadow_intensity(np.zeros(5), 0.0)
    with pytest.raises(InputError, match="trailing axis of length 4"):
        msm.shadow_intensity(np.zeros(5), 0.0)
    with pytest.raises(InputError, match="finite"):
        msm6.shadow_intensity([0, 0.1, 0, np.nan, 0, 0.1], 0.0)
    with pytest.raises(InputError, match="bound"):
        msm.shadow_intensity(np.zeros(6), 0.0, bound="middle")
    with pytest.raises(InputError, match="zf"):
        msm6.shadow_intensity(np.zeros((3, 6)), np.zeros(4))
    with pytest.raises(InputError):
        precise.shadow_intensity6(np.zeros(4), 0.0)


def test_broadcasting_and_dtype():
    b = power_moments(np.array([-0.5, 0.1, 0.6, 0.9]), n=6)
    zf = np.linspace(-1, 1, 7).reshape(7, 1)
    out = msm6.shadow_intensity(b, zf)
    assert out.shape == (7, 1)
    assert msm6.shadow_intensity(b.astype(np.float32), zf).dtype == np.float32
    elementwise = np.array([msm6.shadow_intensity(b, z) for z in zf[:, 0]])
    np.testing.assert_array_equal(out[:, 0], elementwise)


def test_cubic_solver_measurement():
    m = msm6.cubic_solver_benchmark(n=2000, reference=30)
    assert m["trig_max_rel_err"] < 1e-10 and m["eig_max_rel_err"] < 1e-10
    assert m["closed_max_rel_err"] < 1e-10


def test_unorm10_bias_measurement():
    share = msm6.measure_unorm10_bias(alphas=(1e-5, msm6.BIAS6_UNORM10.alpha, 5e-3), n=1000)
    assert share[1e-5] < share[msm6.BIAS6_UNORM10.alpha] <= share[5e-3]
    assert share[msm6.BIAS6_UNORM10.alpha] > 0.6


@pytest.mark.parametrize("dt", [np.float32, np.float64])
@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
@pytest.mark.parametrize("neighbour", [False, True])
def test_every_nonfinite_input_is_refused(dt, bad, neighbour):
    # The bounds kernel finds NaN and inf through the rows they make singular (and D3 + zf):
    # every component, every sign, alone in a chunk of regular texels or next to a singular
    # one. Without the D3 + zf of msm6._bounds_kernel, b6 = +inf and a non-finite zf slip
    # through.
    from moments_ref._kernels import CHUNK

    rng = np.random.default_rng(5)
    n = CHUNK + 100  # the bad value goes into the second chunk
    b = bias_moments(power_moments(rng.uniform(-1, 1, (n, 4)), n=6).astype(dt), msm6.BIAS6_FLOAT32)
    if neighbour:
        b[-3] = power_moments(np.array([0.2]), n=6)  # a singular texel in the same chunk
    zf = rng.uniform(-1, 1, n).astype(dt)
    for k in range(7):
        bb, zz = b.copy(), zf.copy()
        if k < 6:
            bb[CHUNK + 7, k] = bad
        else:
            zz[CHUNK + 7] = bad
        for bound in ("lower", "upper"):
            with pytest.raises(InputError) as info:
                msm6.shadow_intensity(bb, zz, bound)
            assert f"({CHUNK + 7}" in str(info.value) and ("zf" if k == 6 else "b") in str(info.value)
    # finite inputs, |zf| near the largest float: D3 + zf overflows, the full check passes
    huge = np.full(3, np.finfo(dt).max / 2, dtype=dt) * np.array([1, -1, 1], dtype=dt)
    lo, up = msm6.shadow_bounds(b[:3], huge)
    assert np.isfinite(lo).all() and np.isfinite(up).all()


def _bounds_by_expressions(b, zf):
    # The bounds kernel written as NumPy expressions (the module's _reversed_cubic, _extreme_root
    # and _weights, step 5 as a sum of 0/1 masks): what moments_ref._msm6_rows does in place.
    dt = b.dtype.type
    bt = np.ascontiguousarray(np.moveaxis(b, -1, 0))
    steps = msm6._NEWTON_STEPS[b.dtype.name]
    with np.errstate(all="ignore"):
        ldl, (y1, y2, y3), (pz, p1, p2, q3) = msm6._reversed_cubic(bt, zf)
        w0 = 1 / pz
        pos1, pos2, pos3 = y1 >= 0, y2 >= 0, y3 >= 0
        two = ((pos2 <= pos1) & (pos3 <= pos2)).astype(dt)
        odd = pos3.astype(dt)
        t = msm6._extreme_root(pz, p1, p2, q3, 1 - 2 * odd, newton=steps[1], refine=steps[0])
        w = msm6._weights(t, zf, bt[0], bt[1], bt[2], ldl, np.zeros_like(zf))
        lower = np.fmin(np.fmax((1 - w0) * two + w * (odd - two), 0), 1).astype(b.dtype)
    return lower, np.fmin(lower + w0, 1).astype(b.dtype), msm6._regular(bt, ldl)


def _christoffel_bounds(b, zf):
    # msm6._bounds_kernel (the Christoffel weight) over chunks: float64's kernel throughout, and
    # float32's for the texels its fast path (moments_ref._msm6_bound) hands back.
    bt, n = np.ascontiguousarray(b.T), len(zf)
    out = {k: np.empty(n, dtype=b.dtype) for k in ("lower", "upper")}
    chunk = bounds_chunk(b.dtype)  # 2^16 in float32, 2^15 in float64
    for lo in range(0, n, chunk):
        hi = min(n, lo + chunk)
        msm6._bounds_kernel(np.ascontiguousarray(bt[:, lo:hi]), zf[lo:hi], msm6._NEWTON_STEPS[b.dtype.name],
                            {k: v[lo:hi] for k, v in out.items()}, None)
    return out["lower"], out["upper"]


@pytest.mark.parametrize("dt", [np.float32, np.float64])
def test_bounds_rows_are_the_expressions_bit_for_bit(dt):
    # The in-place Christoffel kernel (reused rows, out=, sign flips by bits, checks by reductions)
    # claims the arithmetic of the expressions above operation for operation: equal bits on regular
    # rows of several chunks (biased and unbiased, zf at and next to support points, a partial
    # chunk). float64 runs it throughout (checked through shadow_bounds below); float32 runs the
    # fast path of moments_ref._msm6_bound (tests/test_msm6_fast.py) and this kernel on the rest.
    rng = np.random.default_rng(7)
    n = 2 * msm6.BOUNDS_CHUNK + 1234
    k = rng.integers(4, 7, n)
    z = rng.uniform(-1, 1, (n, 6))
    b = power_moments(z, rng.uniform(0.05, 1, (n, 6)) * (np.arange(6) < k[:, None]), n=6)
    biased = rng.random(n) < 0.5
    b[biased] = bias_moments(b[biased], msm6.BIAS6_FLOAT32 if dt == np.float32 else msm6.BIAS6_FLOAT64)
    zf = rng.uniform(-1.1, 1.1, n)
    near = rng.random(n) < 0.3
    zf[near] = z[near, 0] + rng.choice([0, 1e-6, -1e-6], near.sum())
    b, zf = b.astype(dt), zf.astype(dt)
    lower, upper, regular = _bounds_by_expressions(b, zf)
    assert regular.mean() > 0.9
    got = _christoffel_bounds(b, zf)
    if dt == np.float64:
        assert all(np.array_equal(g, c) for g, c in zip(msm6.shadow_bounds(b, zf), got))
    for g, want in zip(got, (lower, upper)):
        assert g.dtype == dt and np.array_equal(g[regular].view(np.uint8), want[regular].view(np.uint8))


def test_bounds_threads_share_no_workspace():
    # The bounds kernel's workspace is kept per thread (_msm6_rows.workspace): calls running at
    # the same time give the serial results.
    from concurrent.futures import ThreadPoolExecutor

    rng = np.random.default_rng(12)
    jobs = []
    for i in range(6):
        n = int(rng.integers(1, 2 * msm6.BOUNDS_CHUNK))
        dt = (np.float32, np.float64)[i % 2]
        b = bias_moments(power_moments(rng.uniform(-1, 1, (n, 5)), n=6), msm6.BIAS6_FLOAT32).astype(dt)
        jobs.append((b, rng.uniform(-1, 1, n).astype(dt)))

    def run(job):
        return msm6.shadow_bounds(*job)

    serial = [run(j) for j in jobs]
    with ThreadPoolExecutor(3) as pool:
        for got, want in zip(pool.map(run, jobs), serial):
            assert all(np.array_equal(g, w) for g, w in zip(got, want))
