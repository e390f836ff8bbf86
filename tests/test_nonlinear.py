"""Tests of moments_ref.nonlinear: Φ (Alg. 2), Φ⁻¹ (Eq. 4), Ψ4 and Algorithm 3.

References used here, independent of the code under test: the definition of the
moments (power_moments of explicit distributions), HPG17 Eq. (1) and Eq. (3)
(``det B / σ²`` with numpy.linalg.det), Algorithm 1 (msm.shadow_intensity) on
the moments of Eq. (4), the mpmath twins in moments_ref.precise, and the values
HPG17 §3.2 states.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from moments_ref import InputError, msm, nonlinear as nl, precise
from moments_ref.moments import BIAS_FLOAT32, BIAS_UNORM16, bias_moments, hankel, power_moments
from moments_ref.tools.strategies import depth_distributions, two_point_distributions

# Rounding slack of Algorithm 2's outputs for moments of a distribution on [-1, 1]
# biased with BIAS_FLOAT32 (measured: float32 ξ4 down to −3e-8, y within 1 ulp of ±1).
SLACK = {np.float64: 1e-12, np.float32: 4e-7}


def biased(dist, dtype=np.float64, preset=BIAS_FLOAT32):
    z, w = dist
    return bias_moments(power_moments(z, w), preset).astype(dtype)


# ---------------------------------------------------------------------------
# Φ (Algorithm 2)


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
@given(dist=depth_distributions())
def test_phi_ranges_after_float32_bias(dtype, dist):
    r = nl.phi(biased(dist, dtype))
    assert r.dtype == dtype
    s = SLACK[dtype]
    y1, y2, v2, xi4 = r
    assert -1 - s <= y1 <= y2 <= 1 + s
    assert -s <= v2 <= 1 + s
    assert -s <= xi4 <= 0.25 + s
    # The float32 output is accepted by shade without error (within rounding).
    assert 0 <= nl.shade(r, np.asarray(0.0, dtype)) <= 1


@given(dist=two_point_distributions())
def test_phi_two_point_unbiased_is_exact(dist):
    z, w = dist
    r = nl.phi(power_moments(z, w))
    assert abs(r[3]) <= 1e-12  # ξ4 = 0 up to rounding
    gap = z[1] - z[0]
    np.testing.assert_allclose(r[:2], z, atol=1e-9 / gap)
    np.testing.assert_allclose(r[2], w[1], atol=1e-9 / gap**2)


def test_phi_two_point_float32():
    z, w = np.array([-0.3, 0.55]), np.array([0.7, 0.3])
    r = nl.phi(power_moments(z, w).astype(np.float32))
    assert r.dtype == np.float32
    assert abs(r[3]) <= 1e-6
    np.testing.assert_allclose(r[:3], [-0.3, 0.55, 0.3], atol=1e-5)


@given(dist=depth_distributions(min_points=3))
def test_xi4_three_ways(dist):
    """Algorithm 2 step (7) vs Eq. (1) b4 − v1 y1⁴ − v2 y2⁴ vs Eq. (3) det B / σ²."""
    b = biased(dist)
    y1, y2, v2, xi4 = nl.phi(b)
    eq1 = b[3] - (1 - v2) * y1**4 - v2 * y2**4
    sigma2 = b[1] - b[0] ** 2
    eq3 = np.linalg.det(hankel(b)) / sigma2
    tol = 1e-13 + 1e-12 * xi4 + 1e-16 / sigma2
    assert abs(xi4 - eq1) <= tol + 1e-11 / (y2 - y1)
    assert abs(xi4 - eq3) <= tol


def test_xi4_mutant_eq1_detects_wrong_weight():
    """The Eq. (1) check has power: swapping v1 and v2 is caught."""
    b = biased((np.array([-0.5, 0.2, 0.9]), np.array([0.2, 0.5, 0.3])))
    y1, y2, v2, xi4 = nl.phi(b)
    wrong = b[3] - v2 * y1**4 - (1 - v2) * y2**4
    assert abs(wrong - xi4) > 1e-3


def test_xi4_extreme_case_of_section_3_2():
    """HPG17 §3.2: Z = ½δ0.915 + ½δ1 has ξ4 = 0, and ≈ 2.8e-4 after BIAS_UNORM16."""
    z, w = np.array([0.915, 1.0]), np.array([0.5, 0.5])
    b = power_moments(z, w)
    assert abs(nl.phi(b)[3]) < 1e-15
    xi = nl.phi(bias_moments(b, BIAS_UNORM16))[3]
    assert xi == pytest.approx(2.8e-4, rel=0.02)


def test_xi4_extreme_case_is_the_maximum_over_two_point_distributions():
    """A grid over two-point distributions: the maximum of ξ4 after BIAS_UNORM16 is HPG17's."""
    g = np.linspace(-1, 1, 401)  # step 0.005, contains 0.915 and 1
    i, j = np.triu_indices(g.size, 1)
    v = np.linspace(0.05, 0.95, 19)
    z1 = np.repeat(g[i], v.size)
    z2 = np.repeat(g[j], v.size)
    v2 = np.tile(v, i.size)
    b = nl.phi_inverse(np.stack([z1, z2, v2, np.zeros_like(z1)], -1))
    xi = nl.phi(bias_moments(b, BIAS_UNORM16))[:, 3]
    k = np.argmax(xi)
    ref = nl.phi(bias_moments(power_moments([0.915, 1.0]), BIAS_UNORM16))[3]
    assert xi[k] <= ref * (1 + 1e-9)
    # At Z = ½δ0.915 + ½δ1 or its mirror image ½δ-1 + ½δ-0.915 (b* is symmetric).
    top = np.flatnonzero(xi >= ref * (1 - 1e-9))
    found = {(round(abs(a), 9), round(abs(c), 9), round(float(w), 9)) for a, c, w in zip(z1[top], z2[top], v2[top])}
    assert found == {(0.915, 1.0, 0.5), (1.0, 0.915, 0.5)}


@settings(max_examples=15)
@given(dist=depth_distributions(min_points=2))
def test_phi_matches_precise(dist):
    b = biased(dist)
    r = nl.phi(b)
    ref = precise.phi(b)
    gap = ref[1] - ref[0]
    assert abs(r[3] - ref[3]) <= 1e-14 + 1e-9 * ref[3]
    if gap > 1e-3:
        np.testing.assert_allclose(r[:3], ref[:3], atol=1e-9)


def test_phi_singular_input_is_defined():
    """σ² = 0 (one depth, not biased) and σ² < 0 (rounding): (b1, b1, 0, b4 − b1⁴), no NaN."""
    for dtype in (np.float64, np.float32):
        b = power_moments(np.array([0.3, 0.3]))
        b = b.astype(dtype)
        r = nl.phi(b)
        assert np.all(np.isfinite(r))
        np.testing.assert_allclose(r, [b[0], b[0], 0, b[3] - b[0] ** 4], atol=1e-7)
        bad = np.array([0.5, 0.25 - 1e-6, 0.125, 0.0625], dtype)  # σ² < 0
        r = nl.phi(bad)
        assert np.all(np.isfinite(r)) and r[2] == 0 and r[0] == r[1] == bad[0]
    zero = nl.phi(np.zeros(4))
    np.testing.assert_array_equal(zero, np.zeros(4))
    ref = precise.phi(power_moments(np.array([-0.7])))
    np.testing.assert_allclose(nl.phi(power_moments(np.array([-0.7]))), ref, atol=1e-15)


@given(dist=depth_distributions())
def test_phi_inverse_of_phi_is_identity(dist):
    b = biased(dist)
    np.testing.assert_allclose(nl.phi_inverse(nl.phi(b)), b, atol=1e-10)


@given(
    y1=st.floats(-1, 0.9),
    gap=st.floats(1e-2, 1),
    v2=st.floats(0.01, 0.99),
    xi4=st.floats(0, 0.01),
)
def test_phi_of_phi_inverse_is_identity(y1, gap, v2, xi4):
    r = np.array([y1, min(y1 + gap, 1.0), v2, xi4])
    np.testing.assert_allclose(nl.phi(nl.phi_inverse(r)), r, atol=1e-9)


def test_phi_inverse_matches_precise():
    r = np.array([[-0.8, 0.4, 0.6, 1e-4], [0.1, 0.1 + 1e-7, 0.5, 0.0]])
    np.testing.assert_allclose(nl.phi_inverse(r), precise.phi_inverse(r), rtol=1e-15, atol=1e-17)


# ---------------------------------------------------------------------------
# Ψ4


def test_psi4_endpoints_and_clamp():
    for dt in (np.float64, np.float32):
        u = nl.psi4(np.array([-1.0, 0.0, 1e-7, 1.2e-7, 0.25, 0.3], dt))
        assert u.dtype == dt
        np.testing.assert_array_equal(u, [0, 0, 0, 0, 1, 1])
        xi = nl.psi4_inverse(np.array([0.0, 1.0], dt))
        assert xi[0] == dt(1.2e-7) and xi[1] == dt(0.25)


def test_psi4_monotone_and_matches_precise():
    xi = np.geomspace(1.2e-7, 0.25, 20001)
    u = nl.psi4(xi)
    assert np.all(np.diff(u) > 0)
    sample = xi[::1000]
    np.testing.assert_allclose(nl.psi4(sample), precise.psi4(sample), atol=1e-14)
    u32 = nl.psi4(xi.astype(np.float32))
    assert np.all(np.diff(u32) >= 0)
    np.testing.assert_allclose(u32, u, atol=2e-6)


@given(u=st.floats(0, 1))
def test_psi4_inverse_round_trip(u):
    xi = nl.psi4_inverse(u)
    assert 1.2e-7 <= xi <= 0.25
    assert nl.psi4(xi) == pytest.approx(u, abs=1e-12)
    assert xi == pytest.approx(precise.psi4_inverse(u), rel=1e-12)


def test_psi4_inverse_rejects_outside_unit_interval():
    with pytest.raises(InputError, match="u: expected values in"):
        nl.psi4_inverse([0.5, 1.01])
    assert nl.psi4_inverse(1 + 1e-15) == 0.25  # rounding noise is clamped


# ---------------------------------------------------------------------------
# Algorithm 3


@st.composite
def representations(draw, min_gap=1e-3, min_v=1e-3, xi_min=1e-8):
    y1 = draw(st.floats(-1, 1 - min_gap))
    y2 = draw(st.floats(y1 + min_gap, 1))
    v2 = draw(st.floats(min_v, 1 - min_v))
    xi4 = draw(st.one_of(st.floats(xi_min, 0.25), st.sampled_from([xi_min, 1e-6, 1e-4])))
    return np.array([y1, y2, v2, xi4])


@given(r=representations(), zf=st.lists(st.floats(-1.2, 1.2), min_size=1, max_size=8))
def test_shade_equals_algorithm_1_on_eq4(r, zf):
    zf = np.concatenate([zf, r[:2], r[:2] + 1e-9, r[:2] - 1e-9])
    ours = nl.shade(r, zf)
    ref = msm.shadow_intensity(nl.phi_inverse(r), zf)
    np.testing.assert_allclose(ours, ref, atol=1e-8)


@settings(max_examples=20)
@given(r=representations(min_gap=1e-6, min_v=1e-6, xi_min=0.0), zf=st.floats(-1, 1))
# Found by a random run: z_f 5.3e-100 above the jump at y1 = 0 (closer than mpmath's digits).
@example(r=np.array([0.0, 1e-6, 0.7734375, 0.0]), zf=5.3e-100)
def test_shade_matches_precise(r, zf):
    """Against mpmath Algorithm 1 on Eq. (4), including stiff inputs (tiny gap, ξ4 → 0)."""
    gap = r[1] - r[0]
    zf = np.array([zf, r[0], r[1], (r[0] + r[1]) / 2])
    if r[3] / gap**4 < 1e-30:
        # ξ'4 ≈ 0: the bound jumps at y1 and y2 and mpmath (singular below
        # 1e-40) takes y1, y2 from the roots of the moments, which differ from
        # the given ones in the 50th digit: skip the jump points and anything
        # closer to them than mpmath's digits.
        near = 1e-40 * max(gap, 1.0)
        zf = zf[(np.abs(zf - r[0]) > near) & (np.abs(zf - r[1]) > near)]
    ours = nl.shade(r, zf)
    ref = precise.shade(r, zf)
    gap = r[1] - r[0]
    xip = r[3] / gap**4
    # Error ≈ eps × the steepness of the bound, which grows as ξ'4 → 0.
    tol = 1e-9 if (gap > 1e-3 and (xip == 0 or xip > 1e-12)) else 2e-6
    np.testing.assert_allclose(ours, ref, atol=tol)


def test_shade_zero_xi4_gives_the_exact_steps():
    for dt, tol in ((np.float64, 1e-12), (np.float32, 1e-6)):
        r = np.array([-0.8, 0.4, 0.6, 0.0], dt)
        # A few ulps beside the jumps (at one ulp, z'f rounds onto 0 or 1).
        h = dt(1e-12 if dt == np.float64 else 1e-6)
        zf = np.array([-1, -0.8, -0.8 + h, 0.0, 0.4, 0.4 + h, 1.0], dt)
        expected = (1 - r[2]) * (zf > r[0]) + r[2] * (zf > r[1])
        np.testing.assert_allclose(nl.shade(r, zf), expected, atol=tol)


def test_shade_three_cases_by_y1_y2():
    """zf ≤ y1 gives exactly 0; the paper's formula with ξ'4 (not ξ'4⁻¹) would not match Alg. 1."""
    r = np.array([-0.2, 0.5, 0.3, 3e-3])
    zf = np.linspace(-1, -0.2, 50)
    assert np.all(nl.shade(r, zf) == 0)
    # Mutant: the printed "ξ'4 · (1 − z)² z²" term instead of ξ'4⁻¹, for zf > y2.
    zf = np.linspace(0.55, 1, 20)
    zp = (zf - r[0]) / (r[1] - r[0])
    xip = r[3] / (r[1] - r[0]) ** 4
    mutant = 1 - 1 / ((1 - zp) ** 2 / (1 - r[2]) + zp**2 / r[2] + xip * (1 - zp) ** 2 * zp**2)
    ref = precise.shade(r, zf)
    np.testing.assert_allclose(nl.shade(r, zf), ref, atol=1e-12)
    assert np.max(np.abs(mutant - ref)) > 0.05


@pytest.mark.parametrize("clamp", [nl.SHADE_TOLERANCE, nl.CLAMP_BAND[0], 5e-6, nl.CLAMP_BAND[1]])
@pytest.mark.parametrize("xi4", [1.2e-7, 1e-4, 1e-2])
@pytest.mark.parametrize("v2", [0.0, 1e-7, 1 - 1e-7, 1.0])
def test_shade_clamp_deviation_below_64bit_rounding(v2, xi4, clamp):
    """HPG17 §3.4: the clamps introduce less error than the 64-bit rounding, for every offset of CLAMP_BAND.

    Deviation from the exact bound (mpmath, no clamp) measured up to 1e-2 for
    v2 ∈ {0, 1} (the bound is steep in v2 there); one UNORM16 step of v2
    (1/65535) changes the exact bound by 5e-4 .. 7e-2 in the same cases. The
    band's upper end is that step itself: the criterion holds up to it (the
    author's demo code clamps with 5e-6, the paper's text says 1e-6).
    """
    zf = np.linspace(-1, 1, 101)
    r = np.array([-0.5, 0.5, v2, xi4])
    exact = precise.shade(r, zf)
    dev = np.max(np.abs(nl.shade(r, zf, clamp=clamp) - exact))
    step = r.copy()
    step[2] = v2 + 1 / 65535 if v2 < 0.5 else v2 - 1 / 65535
    rounding = np.max(np.abs(precise.shade(step, zf) - exact))
    # At the band's end, v2 = 0 clamped to 1/65535 is that rounding step itself.
    assert dev < rounding if clamp < nl.CLAMP_BAND[1] else dev <= rounding * (1 + 1e-12)
    if clamp == nl.SHADE_TOLERANCE:
        assert dev < 1.1e-2
    # The exact clamped value (golden.truth) agrees with the kernel in float64.
    from moments_ref.golden.truth import shade_clamped

    rows = np.broadcast_to(r, (len(zf), 4))
    np.testing.assert_allclose(nl.shade(rows, zf, clamp=clamp), shade_clamped(rows, zf, clamp=clamp), atol=1e-9)


@pytest.mark.parametrize("clamp", [0.0, 9e-8, 2e-5, float("nan"), "1e-6", True])
def test_shade_refuses_a_clamp_outside_the_band(clamp):
    with pytest.raises(InputError, match="clamp"):
        nl.shade([-0.5, 0.5, 0.5, 1e-3], 0.0, clamp=clamp)


def test_shade_clamp_y1_equals_y2():
    """y1 = y2 (ξ4 = 0, a single depth): the used y2 is y1 + 1e-6, the step stays within 1e-6."""
    r = np.array([0.1, 0.1, 0.4, 0.0])
    zf = np.array([0.1 - 1e-3, 0.1, 0.1 + 2e-6, 0.1 + 1e-3])
    np.testing.assert_allclose(nl.shade(r, zf), [0, 0, 1, 1], atol=1e-12)


def test_shade_no_nan_on_extremes():
    vals_y = [-1.0, -1 + 1e-12, 0.0, 1 - 1e-12, 1.0]
    rows = []
    for y1 in vals_y:
        for dy in [0.0, 1e-12, 1e-7, 1e-3, 2.0]:
            for v2 in [0.0, 1e-12, 0.5, 1 - 1e-12, 1.0]:
                for xi in [0.0, 1e-30, 1.2e-7, 0.25, 1e6]:
                    rows.append([y1, y1 + dy, v2, xi])
    r = np.array(rows)
    tiny = np.finfo(np.float64).tiny
    zf = np.array([-2, -1, -1 + tiny, 0, tiny, 1 - 1e-16, 1, 1 + 1e-16, 3.0])
    for dt in (np.float64, np.float32):
        out = nl.shade(r[:, None, :].astype(dt), zf[None, :].astype(dt))
        assert out.dtype == dt
        assert np.all(np.isfinite(out)) and np.all((0 <= out) & (out <= 1))
        zero = zf[None, :].astype(dt) <= r[:, None, 0].astype(dt)
        assert np.all(out[zero] == 0)


def test_shade_float32_close_to_float64():
    rng = np.random.default_rng(5)
    n = 20000
    y1 = rng.uniform(-1, 0.8, n)
    r = np.stack([y1, y1 + rng.uniform(0.05, 0.2, n), rng.uniform(0.05, 0.95, n), 10 ** rng.uniform(-4, -1, n)], -1)
    zf = rng.uniform(-1, 1, n)
    a64 = nl.shade(r, zf)
    a32 = nl.shade(r.astype(np.float32), zf.astype(np.float32))
    assert a32.dtype == np.float32
    assert np.max(np.abs(a32 - a64)) < 2e-5  # measured 5e-6


def test_shade_broadcasting_and_chunks(monkeypatch):
    rng = np.random.default_rng(3)
    r = np.stack([np.full(6, -0.5), np.full(6, 0.5), np.linspace(0.1, 0.9, 6), np.geomspace(1e-6, 1e-2, 6)], -1)
    zf = rng.uniform(-1, 1, (5, 1))
    full = nl.shade(r, zf)
    assert full.shape == (5, 6)
    np.testing.assert_array_equal(full[2], nl.shade(r, zf[2, 0]))
    assert nl.shade(r[0], zf).shape == (5, 1)
    r32, zf32 = r.astype(np.float32), zf.astype(np.float32)
    full32 = nl.shade(r32, zf32)
    monkeypatch.setattr(nl, "CHUNK", 7)
    assert (nl.shade_chunk(np.float64), nl.shade_chunk(np.float32)) == (7, 14)  # float32 takes twice as many
    np.testing.assert_array_equal(nl.shade(r, zf), full)
    np.testing.assert_array_equal(nl.shade(r32, zf32), full32)  # 30 texels in chunks of 14: the same bits
    assert nl.shade(np.zeros((0, 4)), np.zeros(0)).shape == (0,)
    # The input is never modified (the kernel works in place on a copy).
    one = np.array([[-0.5, 0.5, 0.0, 1e-4]])
    keep = one.copy()
    nl.shade(one, 0.7)
    np.testing.assert_array_equal(one, keep)


def test_shade_bad_input():
    ok = np.array([-0.5, 0.5, 0.5, 1e-4])
    with pytest.raises(InputError, match=r"y1 <= y2.*index \(1,\)"):
        nl.shade(np.array([ok, [0.5, -0.5, 0.5, 1e-4]]), 0.0)
    with pytest.raises(InputError, match="v2 in"):
        nl.shade([-0.5, 0.5, 1.01, 1e-4], 0.0)
    with pytest.raises(InputError, match="v2 in"):
        nl.shade([-0.5, 0.5, -0.01, 1e-4], 0.0)
    with pytest.raises(InputError, match="xi4 >= 0"):
        nl.shade([-0.5, 0.5, 0.5, -1e-3], 0.0)
    with pytest.raises(InputError, match="finite"):
        nl.shade([-0.5, 0.5, np.nan, 1e-4], 0.0)
    with pytest.raises(InputError, match="trailing axis"):
        nl.shade([-0.5, 0.5, 0.5], 0.0)
    with pytest.raises(InputError, match="broadcastable"):
        nl.shade(np.tile(ok, (3, 1)), np.zeros(2))
    with pytest.raises(InputError, match="index \\(40000,\\)"):  # index across chunks
        r = np.tile(ok, (40001, 1))
        r[40000, 2] = 2.0
        nl.shade(r, 0.0)
    # Within rounding of the domain: accepted and clamped.
    eps = np.finfo(np.float64).eps
    edge = np.array([0.5, 0.5 - 4 * eps, 1 + 4 * eps, -4 * eps])
    assert 0 <= nl.shade(edge, 0.7) <= 1
    assert nl.shade(edge.astype(np.float32), np.float32(0.7)).dtype == np.float32


def test_shade_never_nan_below_y1_in_float32():
    """Regression: zf ≤ y1 with v2 = 1 made the unused branch NaN (√ of a negative), and NaN·0 leaked."""
    r = np.float32([-0.57086998, 0.99902248, 1.0, 1.2077858e-07])
    assert nl.shade(r, np.float32(-0.6016781)) == 0
    rng = np.random.default_rng(0)
    n = 50_000
    for dt in (np.float32, np.float64):
        rr = np.column_stack([np.sort(rng.uniform(-1, 1, (n, 2)), 1), rng.uniform(0, 1, n),
                              10 ** rng.uniform(-9, -0.6, n)]).astype(dt)
        rr[::7, 2] = 1
        rr[::11, 2] = 0
        zf = rng.uniform(-1.2, 1.2, n).astype(dt)
        out = nl.shade(rr, zf)
        assert np.isfinite(out).all() and out.min() >= 0 and out.max() <= 1
        assert (out[zf <= rr[:, 0]] == 0).all()


# ---------------------------------------------------------------------------
# Gaps found by mutating the library (the suite's own power)


def test_validate_representation_clamps_rounding_and_refuses_the_rest():
    tol = nl.rounding_tolerance(np.float32)  # 64 ulps: 7.6e-6
    r = np.array([[0.5, 0.5 - 1e-6, -1e-6, -1e-6], [-0.2, 0.3, 1 + 1e-6, 0.01]], np.float32)
    out = nl.validate_representation(r)
    assert out.dtype == np.float32 and out is not r
    assert np.array_equal(out, np.array([[0.5, 0.5, 0.0, 0.0], [-0.2, 0.3, 1.0, 0.01]], np.float32))
    assert r[0, 1] == np.float32(0.5 - 1e-6)  # the input is not modified
    for bad, what in (([0.5, 0.5 - 2 * tol, 0.5, 0.1], "y1 <= y2"), ([0.0, 0.1, -2 * tol, 0.1], "v2 in"),
                      ([0.0, 0.1, 1 + 2 * tol, 0.1], "v2 in"), ([0.0, 0.1, 0.5, -2 * tol], "xi4 >= 0")):
        rows = np.array([[0.0, 0.1, 0.5, 0.1], bad], np.float32)
        with pytest.raises(InputError, match=rf"{what}.*at index \(1,\)"):
            nl.validate_representation(rows, name="texels")


def test_shade_upper_v2_clamp_is_one_minus_1e6():
    """v2 = 1 is shaded as v2 = 1 - 1e-6 (HPG17 §3.4), compared with the mpmath bound at that v2."""
    r = np.array([-0.5, 0.5, 1.0, 1e-5])
    for zf in (0.0, 0.3, 0.49):
        clamped = precise.shade([-0.5, 0.5, 1 - 1e-6, 1e-5], zf)
        assert float(nl.shade(r, zf)) == pytest.approx(clamped, rel=1e-9)
        # The clamp constant matters here: 1 - 2e-6 gives an intensity 10 times larger.
        assert precise.shade([-0.5, 0.5, 1 - 2e-6, 1e-5], zf) > 5 * clamped


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_shade_skips_only_the_clamps_that_change_nothing(dtype):
    # shade runs the clamped Algorithm 3 (_shade_kernel, every clamp) on the texels where a
    # §3.4 clamp acts (v2 < 1e-6, v2 > 1 − 1e-6, gap < 1e-6, ξ4/max(gap, 1e-6)⁴ < tiny,
    # computed here in the dtype) and the closed form of _shade_about_zf on the others, in
    # chunks whose extremes do not prove every clamp a no-op. Against the kernel with every
    # clamp run: bit for bit where a clamp acts, within 4 ulps of 1 elsewhere (the two
    # formulations of the same bound), on chunks of filtered moments (no clamp needed) with
    # one row that needs each clamp, ξ4 around the proven threshold 2·tiny·max(gap)⁴, and a
    # gap whose fourth power overflows, and ξ4 = 0 with gaps of 1e-6 (where the threshold
    # computed as 2·tiny·gap⁴ underflowed to 0: seen failing). Leaving the rows of the v2 or
    # gap clamps to the closed form fails this test; a ξ'4 below tiny sends the closed form
    # to an overflow (k2² = ∞), a non-finite result, which goes to the kernel as well.
    rng = np.random.default_rng(12)
    n = 1000
    b = bias_moments(power_moments(rng.uniform(-1, 1, (n, 4))), BIAS_FLOAT32).astype(dtype)
    base, zf = nl.phi(b), rng.uniform(-1, 1, n).astype(dtype)
    tiny = float(np.finfo(dtype).tiny)
    g = float(base[:, 1].max() - base[:, 0].min())
    edits = [(2, 0.0), (2, 1.0), (2, 5e-7), (2, 1 - 5e-7), (1, None), (3, 0.0), (3, 3 * tiny),
             (3, tiny * g**4 * 0.5), (3, tiny * g**4 * 1.99), (3, tiny * g**4 * 2.01), (3, 1e-35)]
    chunks = [base.copy()] + [base.copy() for _ in edits] + [base.copy()]
    for ch, (col, v) in zip(chunks[1:], edits):
        ch[7, col] = ch[7, 0] if v is None else v
    chunks[-1][3, :2] = (-1e10, 1e10)  # the gap's fourth power overflows float32, ξ'4 underflows
    chunks[-1][3, 3] = 1e3
    tight = np.tile(np.array([0.0, 1e-6, 0.7734375, 0.0], dtype), (n, 1))  # 2·tiny·gap⁴ underflows
    chunks.append(tight)
    narrow = base.copy()  # a gap below the clamp's 1e-6 but not 0
    narrow[7, 1] = narrow[7, 0] + dtype(5e-7)
    chunks.append(narrow)
    consts, _ = nl._chunk_constants(dtype, n, nl._clamp_offset(nl.SHADE_TOLERANCE))
    zf[7] = base[7, 0] + 0.25 * (base[7, 1] - base[7, 0])  # between y1 and y2: the edited row's bound is w_l
    for ch in chunks:
        want = np.empty(n, dtype)
        cols = np.ascontiguousarray(ch.T)
        with np.errstate(all="ignore"):
            nl._shade_kernel(*cols, zf.copy(), want, consts)
            y1, y2, v2, xi4 = np.ascontiguousarray(ch.T)
            lo, tiny_d = dtype(nl.SHADE_TOLERANCE), dtype(tiny)
            g4 = np.maximum(y2 - y1, lo) ** 4
            acts = (v2 < lo) | (v2 > 1 - lo) | (y2 - y1 < lo) | ~(xi4 / g4 >= tiny_d)
        got = nl.shade(ch, zf)
        assert got[acts].tobytes() == want[acts].tobytes()
        assert np.abs(got[~acts] - want[~acts]).max(initial=0) <= 4 * np.finfo(dtype).eps
    ext = nl._chunk_ok(np.ascontiguousarray(base.T), zf, base[:, 1] - base[:, 0], 1e-6)
    assert not any(nl._clamps_needed(ext, consts).values())  # filtered moments skip all four


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_a_non_finite_zf_makes_the_closed_form_non_finite(dtype):
    # shade does not reduce zf per chunk (issue 41, round seven): it relies on a non-finite zf
    # sending _shade_about_zf's result to NaN (then _shade_rows refuses the call before the
    # clamped kernel sees it). Enumerated over the edges of the domain that _chunk_ok lets
    # through (y1 ≤ y2, v2 ∈ [0, 1], ξ4 ≥ 0, each up to the rounding tolerance, every value
    # finite), and through the public function with the bad zf among good texels of a
    # chunk after the first: InputError naming zf and the first bad index. Dropping the zf
    # check of _shade_rows fails the second half.
    fi, tol = np.finfo(dtype), float(nl.rounding_tolerance(dtype))
    big = float(fi.max) / 4
    y1s = [-big, -1.0, -0.0, 0.0, float(fi.tiny), 1.0, big]
    gaps = [0.0, float(fi.smallest_subnormal), float(fi.tiny), 1e-6, 1.0, big]
    v2s = [-tol, -0.0, 0.0, 1e-7, 0.5, 1 - 1e-7, 1.0, 1 + tol]
    xis = [-tol, -0.0, 0.0, float(fi.smallest_subnormal), float(fi.tiny), 1e-30, 1.0, big]
    grid = np.array(np.meshgrid(y1s, gaps, v2s, xis, indexing="ij"), dtype).reshape(4, -1)
    y1, gap, v2, xi4 = grid
    y2 = (y1 + gap).astype(dtype)
    assert np.isfinite(y2).all() and (y2 - y1 >= -tol).all()
    n = y1.size
    for bad in (np.inf, -np.inf, np.nan):
        out = np.empty(n, dtype)
        c = nl._kernel_constants(dtype, n)
        with np.errstate(all="ignore"):
            nl._shade_about_zf(y1.copy(), y2.copy(), v2.copy(), xi4.copy(), np.full(n, bad, dtype),
                               (y2 - y1).astype(dtype), out, c)
        assert not np.isfinite(out).any(), grid[:, np.isfinite(out)].T[:3]
    rng = np.random.default_rng(3)
    n, first = nl.shade_chunk(dtype) + 3000, nl.shade_chunk(dtype) + 17  # the second chunk
    b = bias_moments(power_moments(rng.uniform(-1, 1, (n, 4))), BIAS_FLOAT32).astype(dtype)
    r, zf = nl.phi(b), rng.uniform(-1, 1, n).astype(dtype)
    for bad in (np.inf, -np.inf, np.nan):
        z = zf.copy()
        z[[first, n - 1]] = bad
        with pytest.raises(InputError, match=rf"zf: expected finite.*index \({first},\)"):
            nl.shade(r, z)
