"""HPG17 Algorithm 1 (moments_ref.msm) checked by independent means.

References used here, none of them msm itself: the exact Z of the drawn
distribution (moments_ref.tools.strategies.exact_shadow), the mpmath twin
(moments_ref.precise, Algorithm 1 literally at 50 digits), a linear program over
distributions on a grid (scipy HiGHS), and closed-form facts (a two-point
distribution is the only one with its moments).

Tolerances, and why:

* ALPHA_SLACK = α of BIAS_FLOAT32. Biased moments are exactly the moments of the
  mixture (1 − α) Z + α Z* with Z* = 0.625 δ0 + 0.1875 (δ−1 + δ1) (whose moments
  are b*), so a sharp lower bound of the biased moments is at most
  Z(z < zf) + α, and the upper bound at least Z(z ≤ zf) − α.
* float64 against precise: 1e-9 (docs/stability.md measures ≤ 1.5e-10 on every
  category).
* float32 against the exact Z: α + 1e-3. float32 rounding of moments near a
  support point moves the smeared step; with msm's float32 singular threshold at
  0 stability.measure_two_point finds lower − Z up to 5.9e-4 (with the earlier
  threshold 8·eps32 it was 0.96: test_float32_threshold_regression keeps that case).
"""

import numpy as np
import pytest
from hypothesis import assume, example, given
from hypothesis import strategies as st

from moments_ref import InputError, precise
from moments_ref.tools import stability
from moments_ref.moments import BIAS_FLOAT32, bias_moments, power_moments
from moments_ref.msm import (
    canonical_representation,
    reduce_light_leaking,
    shadow_intensity,
    singular_thresholds,
)
from moments_ref.tools.strategies import depth_distributions, depths, exact_shadow, two_point_distributions

from _oracles import check_bounds, lp_grid, lp_lower, zf_candidates

ALPHA_SLACK = BIAS_FLOAT32.alpha
F64_VS_PRECISE = 1e-9
F32_SLACK = ALPHA_SLACK + 1e-3
UNBIASED_TOL = 1e-6


def _msm(b, zf, bound):
    return shadow_intensity(b, zf, bound=bound)


def _check(fn, z, w, zf, dtype, slack):
    """:func:`_oracles.check_bounds` of a four-moment kernel ``fn(b, zf, bound)``, moments biased with BIAS_FLOAT32."""
    check_bounds(lambda b, f: (fn(b, f, "lower"), fn(b, f, "upper")), z, w, zf, dtype, slack, BIAS_FLOAT32)


# ---------------------------------------------------------------------------
# bounds


def _two_point_weight_error(z, w):
    """How far float64 moments place a two-point distribution's weights from the true ones: ``2 eps/σ³``.

    The weights are functions of the skewness γ = μ3/σ³ alone (w = 1/2 ∓ γ/(2√(γ² + 4)), slope at most 1/4),
    and μ3 = b3 − 3 b1 b2 + 2 b1³ from moments rounded to float64 (|b| ≤ 1) is off by up to 6 units of
    roundoff, 3 eps: so 3 eps/(4σ³), taken here as 2 eps/σ³. 0 for other distributions.
    """
    u = np.unique(z[w > 0])
    if len(u) != 2:
        return 0.0
    m = (w * z).sum() / w.sum()
    sigma = np.sqrt((w * (z - m) ** 2).sum() / w.sum())
    with np.errstate(divide="ignore"):  # σ³ underflows for points a denormal apart: nothing is known
        return 2 * float(np.finfo(np.float64).eps) / sigma**3


def _exact_pivots(z, w):
    """``(σ², ξ4, b4)`` of the distribution (z, w) itself (not of its rounded moments), in 50-digit mpmath."""
    import mpmath

    with mpmath.workdps(50):
        zs, ws = [mpmath.mpf(float(x)) for x in z], [mpmath.mpf(float(x)) for x in w]
        total = mpmath.fsum(ws)
        b = [mpmath.fsum(wi * zi**k for zi, wi in zip(zs, ws)) / total for k in range(5)]
        s2 = b[2] - b[1] ** 2
        xi4 = b[4] - b[2] ** 2 - (b[3] - b[1] * b[2]) ** 2 / s2 if s2 > 0 else mpmath.mpf(0)
        return float(s2), float(xi4), float(b[4])


@given(depth_distributions(kind="random") | depth_distributions(kind="boundary"), depths())
# Found by the thorough profile: two points 2.3e-4 apart (σ = 1.1e-4, 2 eps/σ³ = 3e-4), equal weights: the
# bound between them is 0.5000058 in float64 (precise on the same rounded moments: 0.5000083).
@example(dist=(np.array([0.640625, 0.64039512]), np.array([0.5, 0.5])), zf=-1.0)
# Found by the thorough profile: 1, 0.999999 and 0.999 (and a weight of 2.4e-4 at 0.999 in the second): ξ4 of
# 1.8e-19 and 8.5e-17, under float64's unit of b4 (2.2e-16), so the rounded moments have ξ4 < 0 and are those of
# two points; the bound was 1.2e-6 and 2.4e-4 off Z (precise on the same moments agrees with the kernel).
@example(dist=(np.array([1.0, 1.0, 0.999999, 0.999]), np.array([8, 8, 8, 5]) / 29.0), zf=-1.0)
@example(dist=(np.array([1.0, 1.0, 1.0, 1.0, 0.999999, 0.999]),
               np.array([0.24236548715462916, 0.24236548715462916, 0.24236548715462916, 0.15147842947164322,
                         0.12118274357731458, 0.00024236548715462916])), zf=-1.0)
def test_bounds_unbiased_float64(dist, zf):
    # Unbiased float64 moments cannot resolve a support point from zf closer than their
    # rounding (e.g. depths {−1, 7e-18} give the moments of {−1, 0}): zf keeps 1e-6 away.
    # Tolerance UNBIASED_TOL, plus for two points what their rounded moments cannot know of the weights
    # (_two_point_weight_error): depths {1, 1 − 1e-6} (weights 1/3, 2/3) fall into msm's two-point branch with
    # y1 = 0.999004 and a bound 2.2e-7 above Z at zf = 0.999998 (precise on the same input: 2e-16).
    # Nor a third point whose ξ4 is under two float64 units of b4 (more than two points, but ξ4 < 2 eps b4):
    # the rounded moments are then those of two points (or just outside the moment space).
    z, w = dist
    s2, xi4, b4 = _exact_pivots(z, w)
    assume(not 0 < xi4 < 2 * float(np.finfo(np.float64).eps) * max(b4, s2))
    zf = np.concatenate([[zf], z + 1e-6, z - 1e-6])
    zf = zf[(np.abs(zf[:, None] - z).min(axis=1) >= 1e-6 * (1 - 1e-9)) & (np.abs(zf) <= 1)]
    b = power_moments(z, w)
    lower, upper = shadow_intensity(b, zf), shadow_intensity(b, zf, "upper")
    tol = UNBIASED_TOL + _two_point_weight_error(z, w)
    assert (lower <= exact_shadow(z, w, zf) + tol).all()
    assert (exact_shadow(z, w, zf, strict=False) <= upper + tol).all()


@given(depth_distributions(), depths())
def test_bounds_biased_float64(dist, zf):
    z, w = dist
    _check(_msm, z, w, zf_candidates(z, zf), np.float64, ALPHA_SLACK + 1e-12)


@given(depth_distributions(), depths())
def test_bounds_biased_precise(dist, zf):
    # The oracle itself obeys the mixture argument with no float slack at all.
    z, w = dist
    _check(lambda b, zf, bound: precise.shadow_intensity(b, zf, bound),
                 z, w, zf_candidates(z, zf), np.float64, ALPHA_SLACK + 1e-15)


#: Support points closer than this are one point to biased float32 moments: the bias
#: α = 3e-7 adds a variance of order α, i.e. a spread of order √α ≈ 5.5e-4, so a z_f beside
#: two points closer than about 4√α has no float32-resolvable answer (a thorough run found
#: pairs 5e-7 and clusters 1e-4 apart failing the bracket by up to 0.6).
F32_RESOLUTION = 4 * BIAS_FLOAT32.alpha ** 0.5


def _resolvable(z, w, zf, dtype, eps=F32_RESOLUTION):
    """The candidates with at most one distinct support point within ``eps`` of the depth the kernel sees, and
    not every point there: a distribution that is one point at z_f to within ``eps`` has biased float32
    moments whose variance is the bias's (docs/stability.md, "variance near the bias floor": float32 errors up
    to 1), so its step lies anywhere in that spread."""
    zx = zf.astype(dtype).astype(np.float64)
    u = np.unique(z)
    near = np.abs(u[None, :] - zx[:, None]) < eps
    keep = (near.sum(axis=1) <= 1) & ~near.all(axis=1)
    # And a receiver at a support point of a texel whose last pivot ξ4 (exact, of the biased float32 moments) is
    # below two float32 units of b4: float32's ξ4 = b4 − b2² − L32·(b3 − b1 b2), a difference of terms of b4's
    # size, is then mostly rounding, and so is the side of zf its roots fall on. Measured on 6 000 texels of 2 or
    # 3 depths (half with one at or within 2 % of ±1) with zf on a depth: the bracket failed on 6, all with ξ4
    # under 0.86 units (test_float32_receiver_on_a_depth_at_the_ends_of_the_range below: at ±1 the bias
    # target's atom sits on the depth and lifts ξ4 least).
    at = np.abs(u[None, :] - zx[:, None]) <= 2.0**-21  # on a depth, to a few float32 steps
    if at.any():
        b = bias_moments(power_moments(z, w).astype(dtype), BIAS_FLOAT32).astype(np.float64)
        sigma2, xi4 = precise.pivots(b[None])[0]
        if xi4 < 2 * float(np.finfo(dtype).eps) * max(b[3], sigma2):
            keep &= ~at.any(axis=1)
    return zf[keep]


@given(depth_distributions(), depths())
# Found by random runs: {0.875, 0.8750005} is one point in float32 (z_f = 0.8750005 rounds below
# it), and so is the cluster {0.875, 0.875075, 0.8751}.
@example(dist=(np.array([0.875, 0.8750005]), np.array([0.5, 0.5])), zf=0.0)
@example(dist=(np.array([0.875, 0.875075, 0.8751]), np.array([0.4, 0.3, 0.3])), zf=0.0)
# Found by the thorough profile: one point, z_f at its float32 value (float32 msm returns 1, the exact bound of
# the same float32 moments is 1.5e-7): unresolvable, as above.
@example(dist=(np.array([0.83433474]), np.array([1.0])), zf=-1.0)
# Found by the thorough profile: depths 1 and −0.609375, the receiver on −0.609375 (float32 msm returns 0.5, the
# exact bound of the same float32 moments is 1.3e-9): ξ4 0.57 float32 units of b4, unresolvable as above.
@example(dist=(np.array([1.0, -0.609375]), np.array([0.5, 0.5])), zf=-1.0)
def test_bounds_biased_float32(dist, zf):
    z, w = dist
    _check(_msm, z, w, _resolvable(z, w, zf_candidates(z, zf), np.float32), np.float32, F32_SLACK)


def test_float32_unresolvable_pair_is_excluded_and_would_fail():
    """The exclusion is needed (the pair fails the bracket) and narrow (one point is kept)."""
    z, w = np.array([0.875, 0.8750005]), np.array([0.5, 0.5])
    zf = zf_candidates(z, 0.0)
    with pytest.raises(AssertionError):
        _check(_msm, z, w, zf, np.float32, F32_SLACK)
    assert list(_resolvable(z, w, zf, np.float32)) == [0.0]
    z2 = np.array([0.5, 0.875])
    assert len(_resolvable(z2, w, zf_candidates(z2, 0.0), np.float32)) == 7
    # one point: the candidates at it fail the bracket, and only they are dropped
    z1, w1 = np.array([0.83433474]), np.array([1.0])
    zf1 = zf_candidates(z1, -1.0)
    with pytest.raises(AssertionError):
        _check(_msm, z1, w1, zf1, np.float32, F32_SLACK)
    assert list(_resolvable(z1, w1, zf1, np.float32)) == [-1.0]
    # ξ4 below two float32 units of b4: the candidates on a depth fail the bracket, and only they are dropped
    z3 = np.array([1.0, -0.609375])
    zf3 = zf_candidates(z3, 0.25)
    with pytest.raises(AssertionError):
        _check(_msm, z3, w, zf3[1:], np.float32, F32_SLACK)
    assert list(_resolvable(z3, w, zf3, np.float32)) == [0.25]


def test_float32_receiver_on_a_depth_at_the_ends_of_the_range():
    """Found by the thorough profile: depths 1 and −0.609375 (equal weights), zf = 1, biased float32 moments.
    The exact bound of those float32 moments is 0.5000001 (mpmath), float64 Algorithm 1 on them agrees, float32
    Algorithm 1 returns 1: at ±1 the texel's depth and the bias target's atom coincide, the bias lifts the last
    pivot ξ4 least there (0.57 float32 units of b4 here), and float32, whose ξ4 is then mostly rounding, cannot
    tell the receiver from the depth. One float32 step inside (1 − 2^-24) the same; 10^-5 inside, 0.5 again."""
    b = bias_moments(power_moments(np.array([1.0, -0.609375]), np.array([0.5, 0.5])).astype(np.float32),
                     BIAS_FLOAT32)
    sigma2, xi4 = precise.pivots(b.astype(np.float64)[None])[0]
    assert 0.5 < xi4 / (float(np.finfo(np.float32).eps) * b[3]) < 0.6
    for zf, wrong in ((1.0, True), (1 - 2.0**-24, True), (1 - 1e-5, False)):
        exact = float(precise.shadow_intensity(b.astype(np.float64), float(np.float32(zf))))
        assert abs(exact - 0.5) < 1e-6
        assert abs(float(shadow_intensity(b.astype(np.float64), np.float64(np.float32(zf)))) - exact) < 1e-9
        assert (abs(float(shadow_intensity(b, np.float32(zf))) - exact) > 0.4) == wrong


def test_stability_category_at_the_ends_samples_the_float32_breakdown():
    """docs/stability.md's "zf at a depth at ±1" draws the receivers of the test above: on 2000 of its rows
    float32 Algorithm 1 errs by more than 0.4 against mpmath on the same float32 moments, only with zf at ±1 or
    one float32 step inside (every row has one of those), and float64 Algorithm 1 on the same inputs does not
    (so the error is float32's arithmetic, not the input or the bound)."""
    b64, zf64 = stability.MSM_CATEGORIES["zf at a depth at ±1"](np.random.default_rng(11), 2000)
    assert set(np.abs(zf64.astype(np.float32))) == {np.float32(1), np.float32(1 - 2.0**-24)}
    b = bias_moments(b64.astype(np.float32), BIAS_FLOAT32)
    zf = zf64.astype(np.float32)
    exact = precise.shadow_bounds(b, zf)
    for bound, x in zip(("lower", "upper"), exact):
        assert np.abs(shadow_intensity(b, zf, bound) - x).max() > 0.4, bound
        assert np.abs(shadow_intensity(b.astype(np.float64), zf.astype(np.float64), bound) - x).max() \
            <= F64_VS_PRECISE, bound


def test_float32_threshold_regression():
    # Z = 0.4 δ−0.3 + 0.6 δ0.5; zf = 0.5 exactly: Z(z < zf) = 0.4. float32 msm returns 1.0
    # (its rounded y2 = 0.49999998 < zf); the exact bound of the same float32 moments is 0.4.
    b = bias_moments(power_moments(np.array([-0.3, 0.5]), np.array([0.4, 0.6])).astype(np.float32),
                     BIAS_FLOAT32)
    zf = np.float32(0.5)
    exact = precise.shadow_intensity(b, zf)
    assert abs(exact - 0.4) < 1e-6
    assert shadow_intensity(b, zf) <= 0.4 + F32_SLACK


def test_bounds_check_has_power():
    # Mutant: an "Algorithm 1" that reports the upper bound as the lower one is caught.
    z, w = np.array([-0.5, 0.2, 0.7]), np.array([0.3, 0.3, 0.4])
    mutant = lambda b, zf, bound: shadow_intensity(b, zf, "upper")
    with pytest.raises(AssertionError):
        _check(mutant, z, w, zf_candidates(z, 0.0), np.float64, ALPHA_SLACK)


# ---------------------------------------------------------------------------
# canonical representation


@given(depth_distributions(), depths())
# Found by the thorough profile: depths 0 (weight 0.887) and −0.999999, zf = −1. The two roots besides zf are
# 5.9e-4 and 4.3e-4 from 0 (σ = 5.0e-4 about their mean), whose weights the kernel's float64 steps fix only to
# about 2 eps/σ³ = 3.5e-6 (as float64 moments do, _two_point_weight_error): off 4.5e-8 from mpmath's.
@example(dist=(np.array([0.0, 0.0, -0.999999]),
               np.array([0.8067857834762322, 0.08067857834762324, 0.11253563817614455])), zf=-1.0)
def test_canonical_representation_reproduces_moments(dist, zf):
    z, w = dist
    b = bias_moments(power_moments(z, w), BIAS_FLOAT32)  # biased: B(b) regular
    d, wt = canonical_representation(b, zf)
    assert (wt >= -1e-12).all()
    finite = np.isfinite(d)
    assert (wt[~finite] == 0).all()  # a root at infinity carries no weight
    assume(np.abs(d[finite]).max() <= 4)  # far roots make Σ w z⁴ ill-conditioned in float64
    dd = np.where(finite, d, 0.0)
    full = [1.0] + b.tolist()
    for k in range(5):
        scale = (wt * np.abs(dd) ** k).sum()
        assert abs((wt * dd**k).sum() - full[k]) <= 1e-9 * max(scale, 1.0), k
    # and the support points agree with the literal Algorithm 1 in mpmath
    dx, wx = precise.canonical_representation(b, zf)
    np.testing.assert_allclose(wt, wx, atol=1e-9 + _two_point_weight_error(dd[1:], wt[1:]))


def test_canonical_check_has_power():
    # Mutant: the Algorithm 1 weights with w1 and w2 swapped fail the moment test.
    b = bias_moments(power_moments(np.array([-0.5, 0.2, 0.7]), np.array([0.3, 0.3, 0.4])), BIAS_FLOAT32)
    d, w = canonical_representation(b, 0.1)
    w = w[[0, 2, 1]]
    assert abs((w * d).sum() - b[0]) > 1e-3


# ---------------------------------------------------------------------------
# two-point distributions (the unique distribution with its moments)


@given(two_point_distributions(), depths())
# Found by the thorough profile: depths 0.011 apart, the bound 9e-12 off; the moments know the weights to
# 2 eps/σ³ = 2.7e-9 only (_two_point_weight_error).
@example(dist=(np.array([0.33271113, 0.34375]), np.array([0.5, 0.5])), zf=0.3359375)
def test_two_point_exact_away_from_support(dist, zf):
    z, w = dist
    assume(np.abs(z - zf).min() >= 1e-6)
    b = power_moments(z, w)
    tol = 1e-12 + _two_point_weight_error(z, w)
    assert shadow_intensity(b, zf) == pytest.approx(exact_shadow(z, w, zf), abs=tol)
    assert shadow_intensity(b, zf, "upper") == pytest.approx(exact_shadow(z, w, zf, strict=False), abs=tol)


def test_two_point_after_bias_measured():
    # The table in docs/stability.md: deviation shrinks with distance; bound never above Z + α.
    rows = stability.measure_two_point(seed=1, n=400)
    f64 = [r for r in rows if r["dtype"] == "float64" and r["gap"] == "gap ≥ 0.1" and r["distance"] != "0"]
    assert f64[-1]["lower_dev"] < 1e-3 < f64[0]["lower_dev"]
    assert max(r["lower_above_Z"] for r in rows if r["dtype"] == "float64") <= ALPHA_SLACK
    assert max(r["lower_above_Z_exact"] for r in rows) <= ALPHA_SLACK


# ---------------------------------------------------------------------------
# singular thresholds


def _rep_with_xi4(rng, factor):
    """Moments of (y1, y2, v2) with ξ4 = factor × msm's float64 threshold (exact, then rounded)."""
    rtol = singular_thresholds(np.float64)
    while True:
        y1, y2 = np.sort(rng.uniform(-1, 1, 2))
        v2 = rng.uniform(0.05, 0.95)
        if y2 - y1 < 0.05:
            continue
        b0 = precise.phi_inverse([y1, y2, v2, 0.0])
        target = factor * rtol * max(b0[3], b0[1] - b0[0] ** 2)
        b = precise.phi_inverse([y1, y2, v2, target])
        sigma2, xi4 = precise.pivots(b)
        inside = xi4 <= rtol * max(b[3], sigma2)
        if inside == (factor < 1):  # the rounded b must land on the intended side
            return b, (y1, y2, v2)


def _zf_away(y1, y2):
    return np.array([y1 - 0.1, y1 - 1e-2, y1 + 1e-2, (y1 + y2) / 2, y2 - 1e-2, y2 + 1e-2, y2 + 0.1])


def test_xi4_just_below_threshold_gives_unique_distribution():
    rng = np.random.default_rng(0)
    for _ in range(30):
        b, (y1, y2, v2) = _rep_with_xi4(rng, 0.4)
        zf = _zf_away(y1, y2)
        truth = exact_shadow([y1, y2], [1 - v2, v2], zf)
        np.testing.assert_allclose(shadow_intensity(b, zf), truth, atol=1e-12)
        np.testing.assert_allclose(shadow_intensity(b, zf, "upper"), truth, atol=1e-12)


#: Measured: worst |msm − precise| just above the ξ4 threshold at distance ≥ 1e-2 from the
#: support points is ~4e-6 over 600 cases (ξ4 ≈ 2e-15 carries a relative rounding error of
#: O(1), but the bound there is insensitive to ξ4); stated with margin.
ABOVE_THRESHOLD_TOL = 1e-4


@pytest.mark.parametrize("factor", [2.0, 10.0])
def test_xi4_just_above_threshold_agrees_with_precise(factor):
    rng = np.random.default_rng(1)
    worst = 0.0
    for _ in range(30):
        b, (y1, y2, v2) = _rep_with_xi4(rng, factor)
        zf = _zf_away(y1, y2)
        for bound in ("lower", "upper"):
            err = np.abs(shadow_intensity(b, zf, bound) - precise.shadow_intensity(b, zf, bound))
            worst = max(worst, err.max())
    assert worst <= ABOVE_THRESHOLD_TOL


@pytest.mark.parametrize("factor", [0.4, 3.0])
def test_sigma2_threshold_both_sides(factor):
    rtol = singular_thresholds(np.float64)
    rng = np.random.default_rng(2)
    for _ in range(20):
        c = rng.uniform(-0.9, 0.9)
        s2 = factor * rtol * c * c
        # depths c ± s with equal weights: σ² = s², ξ4 = 0 before rounding
        s = np.sqrt(s2)
        b = precise.phi_inverse([c - s, c + s, 0.5, 0.0])
        sig = precise.pivots(b)[0]
        if (sig <= rtol * b[1]) != (factor < 1):
            continue
        zf = np.array([c - 1e-3, c + 1e-3, c - 0.5, c + 0.5])
        if factor < 1:  # one depth at b1, exactly
            np.testing.assert_array_equal(shadow_intensity(b, zf), (b[0] < zf).astype(float))
            np.testing.assert_array_equal(shadow_intensity(b, zf, "upper"), (b[0] <= zf).astype(float))
        else:
            np.testing.assert_allclose(shadow_intensity(b, zf), precise.shadow_intensity(b, zf), atol=1e-6)


# ---------------------------------------------------------------------------
# sharpness: Algorithm 1 equals the minimum of a linear program over distributions


SHARP_CASES = [  # (depths, weights, zf): biased, canonical support inside [-3, 3]
    ([-0.8, 0.4], [0.4, 0.6], 0.1),
    ([-0.5, 0.0, 0.6], [0.2, 0.5, 0.3], 0.3),
    ([-0.9, -0.2, 0.3, 0.8], [0.25, 0.25, 0.25, 0.25], -0.5),
    ([0.1, 0.35, 0.9], [0.5, 0.3, 0.2], 0.5),
]
#: Bias strength of the sharpness cases: α = 0.02 keeps b well inside the moment space, so
#: that even the coarsest grid can reproduce it.
SHARP_ALPHA = 0.02
#: Grid sizes and the gap (LP minimum − sharp bound) allowed at the finest grid. Measured gaps
#: (101, 401, 1601, 6401 points): 2.1e-3, 2.9e-4, 6.4e-5, 1.4e-5 for the first case and
#: 2.3e-2, 5.4e-3, 1.3e-3, 3.2e-4 for the slowest (canonical point at −1.44): O(h), the
#: canonical points snapping to the grid. Required: each refinement at least halves the gap.
GRIDS = (101, 401, 1601, 6401)
LP_FINAL_TOL = 1e-3


@pytest.mark.parametrize("z, w, zf", SHARP_CASES)
def test_lower_bound_is_sharp(z, w, zf):
    b = bias_moments(power_moments(np.array(z), np.array(w)), (SHARP_ALPHA, BIAS_FLOAT32.target))
    exact = float(precise.shadow_intensity(b, zf))
    depths, _ = precise.canonical_representation(b, zf)
    assert np.abs(depths).max() < 3
    gaps = []
    for n in GRIDS:
        lp = lp_lower(b, zf, lp_grid(n))
        assert lp >= exact - 1e-8  # grid distributions are a subset: never below the sharp bound
        gaps.append(lp - exact)
    assert gaps[-1] <= LP_FINAL_TOL
    assert all(g1 <= 0.5 * g0 for g0, g1 in zip(gaps, gaps[1:])), gaps  # converges
    assert float(shadow_intensity(b, zf)) == pytest.approx(exact, abs=1e-10)


def test_sharpness_check_has_power():
    # Mutant: a bound raised by 0.01 is above the LP minimum of the finest grid.
    z, w, zf = SHARP_CASES[1]
    b = bias_moments(power_moments(np.array(z), np.array(w)), (SHARP_ALPHA, BIAS_FLOAT32.target))
    assert float(shadow_intensity(b, zf)) + 0.01 > lp_lower(b, zf, lp_grid(GRIDS[-1]))


# ---------------------------------------------------------------------------
# against precise, float32 and float64


@given(depth_distributions(kind="random", min_points=2), depths())
def test_float64_matches_precise(dist, zf):
    z, w = dist
    b = bias_moments(power_moments(z, w), BIAS_FLOAT32)
    zf = zf_candidates(z, zf)
    for bound in ("lower", "upper"):
        np.testing.assert_allclose(shadow_intensity(b, zf, bound), precise.shadow_intensity(b, zf, bound),
                                   atol=F64_VS_PRECISE)


#: float32 away from support points (distance ≥ 0.05), random distributions: measured worst
#: |msm32 − precise| 1.8e-3 in docs/stability.md ('random'); stated with margin.
F32_VS_PRECISE_FAR = 1e-2


@given(depth_distributions(kind="random", min_points=2), st.floats(-1, 1))
def test_float32_matches_precise_away_from_support(dist, zf):
    z, w = dist
    assume(np.abs(z - zf).min() >= 0.05)
    b = bias_moments(power_moments(z, w).astype(np.float32), BIAS_FLOAT32)
    zf32 = np.float32(zf)
    for bound in ("lower", "upper"):
        got = shadow_intensity(b, zf32, bound)
        assert got.dtype == np.float32
        assert abs(float(got) - float(precise.shadow_intensity(b, zf32, bound))) <= F32_VS_PRECISE_FAR


@pytest.mark.parametrize("category", list(stability.MSM_CATEGORIES))
def test_stiff_categories_never_nonfinite(category):
    b64, zf64 = stability.MSM_CATEGORIES[category](np.random.default_rng(5), 200)
    for dt in (np.float32, np.float64):
        for biased in (True, False):
            b = b64.astype(dt)
            b = bias_moments(b, BIAS_FLOAT32) if biased else b
            for bound in ("lower", "upper"):
                with np.errstate(all="raise"):  # no floating-point exception may escape either
                    out = shadow_intensity(b, zf64.astype(dt), bound)
                assert out.dtype == dt
                assert np.isfinite(out).all() and (out >= 0).all() and (out <= 1).all()
            d, wt = canonical_representation(b, zf64.astype(dt))
            assert np.isfinite(wt).all()
        if dt is np.float64:
            lo = shadow_intensity(bias_moments(b64, BIAS_FLOAT32), zf64)
            assert np.abs(lo - precise.shadow_intensity(bias_moments(b64, BIAS_FLOAT32), zf64)).max() <= F64_VS_PRECISE


@pytest.mark.parametrize("dt", [np.float32, np.float64])
def test_degenerate_vectors_are_finite(dt):
    b = np.array([
        [0.0, 0.0, 0.0, 0.0],  # one depth at 0
        [1.0, 1.0, 1.0, 1.0],  # one depth at 1
        [-1.0, 1.0, -1.0, 1.0],  # one depth at −1
        [0.0, 1.0, 0.0, 1.0],  # ±1 with equal weight
        [0.5, 0.2, 0.1, 0.05],  # σ² < 0: outside the moment space
        [0.0, 0.25, 0.0, 0.01],  # ξ4 < 0: outside
        [0.0, 0.25, 0.0, 0.0625],  # two-point ±0.5
    ], dtype=dt)
    zf = np.array([-1.0, -0.5, 0.0, 0.5, 1.0], dtype=dt)[:, None]
    for bound in ("lower", "upper"):
        out = shadow_intensity(b, zf, bound)
        assert np.isfinite(out).all() and out.shape == (5, 7)


def test_outside_moment_space_is_projected_like_precise():
    # ξ4 < 0 keeps b1..b3 (two-point distribution), σ² < 0 keeps b1 (one depth).
    b = np.array([[0.0, 0.25, 0.0, 0.01], [0.5, 0.2, 0.1, 0.05]])
    zf = np.array([-0.6, -0.4, 0.45, 0.55, 0.6])[:, None]
    for bound in ("lower", "upper"):
        np.testing.assert_allclose(shadow_intensity(b, zf, bound), precise.shadow_intensity(b, zf, bound), atol=1e-12)
    np.testing.assert_array_equal(shadow_intensity(b, zf)[:, 0], exact_shadow([-0.5, 0.5], [0.5, 0.5], zf[:, 0]))
    np.testing.assert_array_equal(shadow_intensity(b, zf)[:, 1], (zf[:, 0] > 0.5).astype(float))


# ---------------------------------------------------------------------------
# array conventions


def test_broadcasting_matches_elementwise():
    rng = np.random.default_rng(3)
    b = bias_moments(power_moments(rng.uniform(-1, 1, (3, 1, 6))), BIAS_FLOAT32)  # (3, 1, 4)
    zf = rng.uniform(-1, 1, 5)
    for bound in ("lower", "upper"):
        out = shadow_intensity(b, zf, bound)
        assert out.shape == (3, 5)
        for i in range(3):
            for j in range(5):
                assert out[i, j] == shadow_intensity(b[i, 0], zf[j], bound)
    d, w = canonical_representation(b, zf)
    assert d.shape == (3, 5, 3) and w.shape == (3, 5, 3)
    assert shadow_intensity(b[0, 0], 0.0).shape == ()


def test_dtype_policy():
    b = np.array([0.0, 0.3, 0.0, 0.2])
    assert shadow_intensity(b.astype(np.float32), 0.1).dtype == np.float32
    assert shadow_intensity(b.astype(np.float32), np.float64(0.1)).dtype == np.float32  # b decides
    assert shadow_intensity(b, np.float32(0.1)).dtype == np.float64
    assert shadow_intensity([0, 1, 0, 1], 0).dtype == np.float64  # integers -> float64
    d, w = canonical_representation(b.astype(np.float32), 0.1)
    assert d.dtype == w.dtype == np.float32


@pytest.mark.parametrize(
    "call, words",
    [
        (lambda: shadow_intensity([0.0, 0.3, 0.0], 0.1), ["b", "4"]),
        (lambda: shadow_intensity([[0.0, 0.3, 0.0, 0.2], [0.0, np.nan, 0.0, 0.2]], 0.1), ["b", "(1, 1)"]),
        (lambda: shadow_intensity([0.0, 0.3, 0.0, 0.2], [0.1, np.inf]), ["zf", "(1,)"]),
        (lambda: shadow_intensity(np.zeros((2, 4)), np.zeros(3)), ["zf", "broadcast"]),
        (lambda: shadow_intensity([0.0, 0.3, 0.0, 0.2], 0.1, bound="middle"), ["bound", "middle"]),
        (lambda: canonical_representation([0.0, 0.3, 0.0, 0.2], "x"), ["zf"]),
        (lambda: reduce_light_leaking([0.5, np.nan]), ["intensity", "(1,)"]),
        (lambda: reduce_light_leaking([0.5], factor=0.0), ["factor"]),
    ],
)
def test_bad_input_names_argument_and_index(call, words):
    with pytest.raises(InputError) as info:
        call()
    for word in words:
        assert word in str(info.value)


@given(st.lists(st.floats(0, 1), min_size=1, max_size=20), st.floats(0.5, 1.0),
       st.sampled_from([np.float32, np.float64]))
def test_reduce_light_leaking(values, factor, dt):
    x = np.asarray(values, dtype=dt)
    out = reduce_light_leaking(x, factor)
    assert out.dtype == dt
    expect = np.minimum(1.0, x.astype(np.float64) / factor)  # the slides' divide-and-saturate
    # atol: float32 subnormals carry fewer significant bits than eps promises.
    np.testing.assert_allclose(out, expect, rtol=2 * np.finfo(dt).eps, atol=np.finfo(dt).smallest_subnormal)
    assert (out >= x).all() and (out <= 1).all()


@pytest.mark.parametrize("dt", [np.float32, np.float64])
@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
@pytest.mark.parametrize("neighbour", [False, True])
def test_every_nonfinite_input_is_refused(dt, bad, neighbour):
    # The kernel finds NaN and inf through the singular texels they make (msm._roots): every
    # component, every sign, in a chunk of regular (biased) texels, alone or next to a
    # singular texel. Without the d + b4 of msm._roots, b4 = +inf alone slips through.
    from moments_ref.msm import chunk_texels

    CHUNK = chunk_texels(dt)
    rng = np.random.default_rng(5)
    n = CHUNK + 100  # the bad value goes into the second chunk
    b = bias_moments(power_moments(rng.uniform(-1, 1, (n, 3))), BIAS_FLOAT32).astype(dt)
    if neighbour:
        b[-3] = power_moments(np.array([0.2]))  # a singular texel in the same chunk
    zf = rng.uniform(-1, 1, n).astype(dt)
    for k in range(5):
        bb, zz = b.copy(), zf.copy()
        if k < 4:
            bb[CHUNK + 7, k] = bad
        else:
            zz[CHUNK + 7] = bad
        for bound in ("lower", "upper"):
            with pytest.raises(InputError) as info:
                shadow_intensity(bb, zz, bound)
            assert f"({CHUNK + 7}" in str(info.value) and ("zf" if k == 4 else "b") in str(info.value)


@pytest.mark.parametrize("dt, tol", [(np.float32, 1e-3), (np.float64, 1e-9)])
def test_bounds_agree_with_the_canonical_representation(dt, tol):
    # The bounds come from msm._bound_rows (the roots' distances from zf and the weights from the
    # first two moments, its singular and non-finite texels handed to msm._kernel); the canonical
    # representation from the kernel's cancellation-free roots and HPG17 §3.4 weights. Step (5)
    # on the latter is an independent evaluation of the same bound, on rows of every kind:
    # biased, unbiased with one to four depths (singular B(b)), zf at and next to a support point.
    # In float64 on every row. In float32 on the rows whose pivots (in float64, of the float32
    # inputs) clear 1e-5 of their scale: below it ξ4 or σ² is float32's rounding noise (biased
    # moments lift ξ4 by ~6e-8 only), and two correct evaluations differ by up to a whole weight
    # (a texel of two depths with zf 1e-6 from one: 0.25 either way, each evaluation missing on
    # other rows; docs/stability.md's float32 breakdowns). There both stay finite and in [0, 1].
    rng = np.random.default_rng(3)
    n = 20_000
    z = rng.uniform(-1, 1, (n, 4))
    k = rng.integers(1, 5, n)
    z = np.where(np.arange(4) < k[:, None], z, z[:, :1])
    b = power_moments(z)
    biased = rng.uniform(0, 1, n) < 0.6
    b = np.where(biased[:, None], bias_moments(b, BIAS_FLOAT32), b).astype(dt)
    zf = np.where(rng.uniform(0, 1, n) < 0.2, z[:, 1], rng.uniform(-1.1, 1.1, n))
    zf = np.where(rng.uniform(0, 1, n) < 0.05, z[:, 1] + rng.normal(0, 1e-5, n), zf).astype(dt)
    depths, weights = canonical_representation(b, zf)
    lower = np.minimum(np.sum(weights[:, 1:] * (depths[:, 1:] < zf[:, None]), axis=1), 1)
    upper = np.minimum(lower + weights[:, 0], 1)
    clear = np.ones(n, dtype=bool)
    if dt == np.float32:
        b1, b2, b3, b4 = b.astype(np.float64).T
        sigma2 = b2 - b1 * b1
        with np.errstate(divide="ignore", invalid="ignore"):
            xi4 = b4 - b2 * b2 - (b3 - b1 * b2) ** 2 / sigma2
        clear = (sigma2 > 1e-5 * b2) & (xi4 > 1e-5 * np.maximum(b4, sigma2))
        assert clear.sum() > n // 2
    for bound, want in (("lower", lower), ("upper", upper)):
        got = shadow_intensity(b, zf, bound)
        assert got.dtype == dt and np.isfinite(got).all() and (0 <= got).all() and (got <= 1).all()
        np.testing.assert_allclose(got[clear], want[clear], rtol=0, atol=tol)


def test_threads_share_no_workspace():
    # msm and nonlinear keep a chunk's constants and workspace between calls, one set per
    # thread (msm._chunk_constants): calls running at the same time in several threads give
    # the results of the same calls made one after another. Shared rows would mix the threads'
    # intermediate values (seen with one module-level set: wrong results in most runs).
    from concurrent.futures import ThreadPoolExecutor

    from moments_ref.msm import chunk_texels
    from moments_ref.nonlinear import phi, shade

    rng = np.random.default_rng(11)
    jobs = []
    for i in range(8):
        n = int(rng.integers(1, 3 * chunk_texels(np.float32)))
        dt = (np.float32, np.float64)[i % 2]
        b = bias_moments(power_moments(rng.uniform(-1, 1, (n, 4))), BIAS_FLOAT32).astype(dt)
        zf = rng.uniform(-1, 1, n).astype(dt)
        jobs.append((b, zf, phi(b)))

    def run(job):
        b, zf, r = job
        return [shadow_intensity(b, zf, bound) for bound in ("lower", "upper")] + [shade(r, zf)]

    serial = [run(j) for j in jobs]
    for _ in range(3):
        with ThreadPoolExecutor(4) as pool:
            for got, want in zip(pool.map(run, jobs), serial):
                for g, w in zip(got, want):
                    assert g.dtype == w.dtype and np.array_equal(g, w)


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_bound_outside_both_roots_is_exact(dtype):
    # The closed form of msm._bound_rows has no selection: with q2 ≥ 0 its S is |k2| exactly and
    # (S + k2)/S is 2 or exactly 0. So where the canonical representation (the full kernel, roots
    # and weights) puts zf below both roots the lower bound is exactly 0, as step (5)'s empty sum
    # (lit texels stay exactly lit). A form with the same value written as
    # (1 − w0)/2 + ((1 − w0) k2/2 − y2 q2)/S (cancelling) leaves ulps there and fails here.
    rng = np.random.default_rng(41)
    n = 20000
    z = rng.uniform(-1, 1, (n, 4))
    b = bias_moments(power_moments(z, weights=rng.dirichlet(np.ones(4), n)), BIAS_FLOAT32).astype(dtype)
    zf = rng.uniform(-1.5, 1.5, n).astype(dtype)
    depths, weights = canonical_representation(b, zf)
    below, above = zf < depths[:, 1], zf > depths[:, 2]
    assert below.sum() > 1000 and above.sum() > 1000
    lower = shadow_intensity(b, zf)
    assert np.all(lower[below] == 0)
    assert np.all(lower[above] > 0)
