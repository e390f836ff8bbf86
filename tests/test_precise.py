"""The mpmath twins (moments_ref.precise) and the stability report (moments_ref.tools.stability).

The oracle is checked against what it must satisfy by definition (its canonical
representation reproduces b0..b4; a dyadic two-point distribution is reproduced
exactly, support points included), against sympy (Eq. (2)/(3) and Algorithm 2's
ξ4 are the same polynomial identity), against a higher precision (its own
convergence), and it in turn checks Algorithm 3 (moments_ref.nonlinear) in float64.
"""

from fractions import Fraction

import numpy as np
import pytest
import sympy
from hypothesis import assume, example, given
from hypothesis import strategies as st

from moments_ref import InputError, precise
from moments_ref.tools import stability
from moments_ref.moments import BIAS_FLOAT32, bias_moments, power_moments
from moments_ref.tools.strategies import depth_distributions, depths, exact_shadow


@given(depth_distributions(), depths())
def test_canonical_representation_reproduces_five_moments(dist, zf):
    z, w = dist
    b = bias_moments(power_moments(z, w), BIAS_FLOAT32)
    d, wt = precise.canonical_representation(b, zf)
    assert (wt >= -1e-30).all()
    finite = np.isfinite(d)
    assume(np.abs(d[finite]).max() <= 1e3)
    dd = np.where(finite, d, 0.0)
    full = [1.0] + b.tolist()
    for k in range(5):
        scale = (wt * np.abs(dd) ** k).sum()
        # float64 rounding of the outputs only: 1e-14 relative to the terms summed
        assert abs((wt * dd**k).sum() - full[k]) <= 1e-14 * max(scale, 1.0)


def test_moment_check_has_power():
    b = bias_moments(power_moments(np.array([-0.5, 0.1, 0.6])), BIAS_FLOAT32)
    d, w = precise.canonical_representation(b, 0.3)
    assert abs((w * d**4).sum() - b[3]) < 1e-14
    assert abs((w * d**4).sum() - (b[3] + 1e-9)) > 1e-12  # a perturbed b4 is told apart


DYADIC = st.integers(-64, 64).map(lambda k: k / 64.0)


@given(st.lists(DYADIC, min_size=2, max_size=2, unique=True), st.integers(1, 7), DYADIC)
def test_exact_two_point_distribution_is_exact_everywhere(zs, k, zf):
    # Dyadic depths and weights: the float64 moments are exact, B(b) exactly singular, so
    # the oracle must return Z itself, also with zf exactly at a support point.
    z = np.array(sorted(zs))
    w = np.array([k / 8, 1 - k / 8])
    b = power_moments(z, w)
    assert precise.shadow_intensity(b, zf) == exact_shadow(z, w, zf)
    assert precise.shadow_intensity(b, zf, "upper") == exact_shadow(z, w, zf, strict=False)


@given(depth_distributions(kind="random"), depths())
def test_precision_converged(dist, zf):
    z, w = dist
    b = bias_moments(power_moments(z, w), BIAS_FLOAT32)
    lo50, up50 = precise.shadow_bounds(b, zf, dps=50)
    lo80, up80 = precise.shadow_bounds(b, zf, dps=80)
    assert abs(lo50 - lo80) <= 1e-15 and abs(up50 - up80) <= 1e-15


def test_xi4_formulas_agree_symbolically():
    # HPG17 Eq. (3): ξ4 = det B / σ², and Algorithm 2 step (7): ξ4 = b4 − b2² − L21² σ².
    b1, b2, b3, b4 = sympy.symbols("b1 b2 b3 b4", real=True)
    sigma2 = b2 - b1**2
    B = sympy.Matrix([[1, b1, b2], [b1, b2, b3], [b2, b3, b4]])
    l21 = (b3 - b1 * b2) / sigma2
    assert sympy.simplify(B.det() / sigma2 - (b4 - b2**2 - l21**2 * sigma2)) == 0


@given(st.floats(-1, 1), st.floats(0.01, 1), st.floats(0.01, 0.99), st.floats(0, 0.01))
def test_phi_inverts_eq4(y1, gap, v2, xi4):
    y2 = y1 + gap
    assume(y2 <= 1)
    r = np.array([y1, y2, v2, xi4])
    back = precise.phi(precise.phi_inverse(r))
    np.testing.assert_allclose(back[:3], r[:3], atol=1e-9)
    assert abs(back[3] - xi4) <= 1e-12
    # Eq. (1): ξ4 = b4 − v1 y1⁴ − v2 y2⁴ on the rounded moments
    b = precise.phi_inverse(r)
    y1b, y2b, v2b, xib = precise.phi(b)
    assert abs(xib - (b[3] - (1 - v2b) * y1b**4 - v2b * y2b**4)) <= 1e-12


def test_psi4_endpoints_and_inverse():
    u = precise.psi4([0.0, 1.2e-7, 1e-6, 0.25])
    assert u[0] == 0 and u[1] == 0 and u[3] == pytest.approx(1, abs=1e-15) and 0 < u[2] < 1
    xi = np.array([1.2e-7, 1e-6, 3e-5, 0.01, 0.25])
    np.testing.assert_allclose(precise.psi4_inverse(precise.psi4(xi)), xi, rtol=1e-14)
    assert (np.diff(precise.psi4(np.geomspace(1.2e-7, 0.25, 50))) > 0).all()


@given(st.floats(-1, 1), st.floats(1e-3, 1), st.floats(0.01, 0.99), depths())
@example(y1=0.4624022302664699, gap=0.5, v2=0.4624022302664699, zf=0.5)  # 1 − v2 a rounding tie in float64
def test_shade_with_xi4_zero_is_the_two_point_z(y1, gap, v2, zf):
    """precise.shade is the two-point Z in exact arithmetic, rounded once: within half an ulp of it (a tie, as
    1 − v2 for v2 < 1/2 can be, rounds either way from precise's 50 digits)."""
    y2 = y1 + gap
    assume(y2 <= 1 and min(abs(zf - y1), abs(zf - y2)) > 1e-12)
    exact = (1 - Fraction(v2)) * (y1 < zf) + Fraction(v2) * (y2 < zf)
    got = float(precise.shade([y1, y2, v2, 0.0], zf))
    assert abs(Fraction(got) - exact) <= Fraction(float(np.spacing(got))) / 2 * (1 + Fraction(1, 2**30))


@given(st.floats(-1, 1), st.floats(1e-2, 1), st.floats(0.01, 0.99), st.floats(1e-7, 0.01), depths())
def test_shade_is_algorithm1_on_eq4(y1, gap, v2, xi4, zf):
    # Away from the support points, rounding the moments of Eq. (4) to float64 barely matters.
    y2 = y1 + gap
    assume(y2 <= 1 and min(abs(zf - y1), abs(zf - y2)) > 1e-3)
    r = np.array([y1, y2, v2, xi4])
    assert abs(precise.shade(r, zf) - precise.shadow_intensity(precise.phi_inverse(r), zf)) <= 1e-8


# --- the oracle checks HPG17 Algorithm 3 (moments_ref.nonlinear) -----------------------


@given(st.floats(-1, 1), st.floats(2e-6, 1), st.floats(2e-6, 1 - 2e-6), st.floats(1.2e-7, 0.25), depths())
def test_nonlinear_shade_matches_precise_float64(y1, gap, v2, xi4, zf):
    nonlinear = pytest.importorskip("moments_ref.nonlinear")
    y2 = y1 + gap
    assume(y2 <= 1)
    r = np.array([y1, y2, v2, xi4])
    for z in (zf, y1, y2):
        # Algorithm 3's clamps stay below 1e-6 in effect; float64 rounding far below.
        assert abs(float(nonlinear.shade(r, z)) - float(precise.shade(r, z))) <= 1e-5


@given(depth_distributions(kind="random", min_points=2))
def test_nonlinear_phi_matches_precise_float64(dist):
    nonlinear = pytest.importorskip("moments_ref.nonlinear")
    z, w = dist
    b = bias_moments(power_moments(z, w), BIAS_FLOAT32)
    got, exact = nonlinear.phi(b), precise.phi(b)
    np.testing.assert_allclose(got[:3], exact[:3], atol=1e-6)
    assert abs(got[3] - exact[3]) <= 1e-12


# --- input handling ---------------------------------------------------------------------


def test_float32_input_is_converted_exactly():
    rng = np.random.default_rng(0)
    b32 = bias_moments(power_moments(rng.uniform(-1, 1, (5, 4))).astype(np.float32), BIAS_FLOAT32)
    zf32 = rng.uniform(-1, 1, 5).astype(np.float32)
    for bound in ("lower", "upper"):
        np.testing.assert_array_equal(precise.shadow_intensity(b32, zf32, bound),
                                      precise.shadow_intensity(b32.astype(np.float64), zf32.astype(np.float64), bound))


def test_broadcasting_and_output_dtype():
    rng = np.random.default_rng(1)
    b = bias_moments(power_moments(rng.uniform(-1, 1, (3, 1, 5))), BIAS_FLOAT32).astype(np.float32)
    zf = rng.uniform(-1, 1, 4)
    out = precise.shadow_intensity(b, zf)
    assert out.shape == (3, 4) and out.dtype == np.float64
    assert out[2, 1] == precise.shadow_intensity(b[2, 0], zf[1].astype(np.float32))
    d, w = precise.canonical_representation(b, zf)
    assert d.shape == w.shape == (3, 4, 3)
    r = np.array([[-0.5, 0.5, 0.5, 1e-4]])
    assert precise.shade(r, zf).shape == (4,) and precise.phi(b).shape == (3, 1, 4)


@pytest.mark.parametrize(
    "call, words",
    [
        (lambda: precise.shadow_intensity([0.0, 0.3, 0.0], 0.1), ["b", "4"]),
        (lambda: precise.shadow_intensity([[0, 0.3, 0, 0.2], [0, np.nan, 0, 0.2]], 0.1), ["b", "(1, 1)"]),
        (lambda: precise.shadow_intensity([0.0, 0.3, 0.0, 0.2], [0.1, np.inf]), ["zf", "(1,)"]),
        (lambda: precise.shadow_intensity([0.0, 0.3, 0.0, 0.2], 0.1, bound="x"), ["bound"]),
        (lambda: precise.shadow_intensity([0.0, 0.3, 0.0, 0.2], 0.1, dps=5), ["dps"]),
        (lambda: precise.shade([0.0, 0.3, 0.5], 0.1), ["r", "4"]),
        (lambda: precise.psi4([np.nan]), ["xi4", "(0,)"]),
    ],
)
def test_bad_input(call, words):
    with pytest.raises(InputError) as info:
        call()
    for word in words:
        assert word in str(info.value)


# --- stability report -------------------------------------------------------------------


def test_stability_measure_is_deterministic_and_complete(tmp_path):
    rows = stability.measure(seed=3, n=12, include_nonlinear=False)
    again = stability.measure(seed=3, n=12, include_nonlinear=False)
    assert rows == again
    err = [r for r in rows if r["table"] == "error"]
    expected = {(f"msm.shadow_intensity ({b})", c, d) for b in ("lower", "upper")
                for c in stability.MSM_CATEGORIES for d in ("float32", "float64")}
    assert {(r["function"], r["category"], r["dtype"]) for r in err} == expected
    for r in err:  # the reported worst input reproduces the reported error
        b = np.array(r["worst_input"]["b"], dtype=r["dtype"])
        zf = np.array(r["worst_input"]["zf"][0], dtype=r["dtype"])
        exact = precise.shadow_intensity(b, zf, "lower" if "lower" in r["function"] else "upper")
        assert float(exact) == r["worst_exact"]
    path = stability.write_markdown(tmp_path / "stability.md", rows)
    text = path.read_text()
    assert "moments-ref stability --out docs/" in text and "## Interpretation" in text
    assert "## msm.shadow_intensity (lower)" in text and "Two-point" in text


def test_stability_nonlinear_rows():
    pytest.importorskip("moments_ref.nonlinear")
    rows = stability.measure_nonlinear(seed=0, n=8)
    functions = {r["function"] for r in rows}
    assert functions == {"nonlinear.phi (y1, y2, v2)", "nonlinear.phi (Ψ4(ξ4))", "nonlinear.shade"}
    cats = {r["category"] for r in rows if r["function"] == "nonlinear.shade"}
    assert "zf at y1 or y2" in cats and "ξ4 at the clamp 1.2e-7" in cats
    assert all(r["nonfinite"] == 0 for r in rows)
