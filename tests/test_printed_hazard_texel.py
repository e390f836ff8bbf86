"""The sweep's one-depth texel (issue 37): a printed formulation that cancels is a hazard row, not a wider band.

The float32-stored moments of one depth -0.9908 and a receiver at -0.98 behind it. After BIAS_FLOAT32 the
third Cholesky pivot xi4 is below one float32 ulp of b4, so the printed formulations (the HPG17 author's demo,
the slides' code, Algorithm 1 as printed) divide by a pivot that rounds to 0, while the exact value is 0.99985.
Checked here by independent means: mpmath for the pivot and the bound, float32 arithmetic written out inline.
"""

import mpmath as mp
import numpy as np
import pytest

from moments_ref import precise
from moments_ref.golden.cases import CASES
from moments_ref.golden.conventions import profiled_arrays
from moments_ref.golden.profile import parse_profile
from moments_ref.golden.spread import golden_arrays
from moments_ref.moments import BIAS_FLOAT32

STORED = np.array([-0.9908193349838257, 0.9817230105400085, -0.9727101922035217, 0.9637800455093384], np.float32)
ZF = -0.98
#: The bias a shader applies in float32: b + alpha (b* - b), BIAS_FLOAT32's alpha and target.
ALPHA, TARGET = np.float32(3e-7), np.array([0.0, 0.375, 0.0, 0.375], np.float32)
INSIDE = parse_profile({"bias": {"alpha": 3e-7, "target": [0.0, 0.375, 0.0, 0.375], "applied": "inside"}})


def _biased():
    return STORED + (TARGET - STORED) * ALPHA  # float32 throughout


def _pivots(b):
    """(sigma2, xi4) of B(b) in mpmath from the float32 values."""
    with mp.workdps(60):
        b1, b2, b3, b4 = (mp.mpf(float(x)) for x in b)
        s2 = b2 - b1 * b1
        return s2, b4 - b2 * b2 - (b3 - b1 * b2) ** 2 / s2


def _rows(arrays, what):
    return [i for i, c in enumerate(arrays["comment"]) if str(c).startswith(f"sweep, {what}")]


def test_the_pivot_lies_below_float32_resolution_and_the_printed_pivot_rounds_to_zero():
    b = _biased()
    s2, xi4 = _pivots(b)
    ulp_b4 = float(np.spacing(b[3]))
    assert 0 < float(xi4) < ulp_b4 and float(s2) > 0  # inside the moment space, 0.7 ulp of b4
    assert float(_pivots(STORED)[1]) < 0  # unbiased, the stored moments are just outside it
    # The demo's / slides' pivot: D22D11 = (b4 - b2^2)(b2 - b1^2) - (b3 - b1 b2)^2, products rounded (no fma).
    b1, b2, b3, b4 = b
    d11 = np.float32(b2 - b1 * b1)
    l21d11 = np.float32(b3 - b1 * b2)
    assert np.float32(np.float32(b4 - b2 * b2) * d11 - l21d11 * l21d11) <= 0


@pytest.mark.parametrize("bound", ["lower", "upper"])
def test_the_biased_row_is_a_printed_hazard_whose_band_holds_the_exact_and_the_guarded_values(bound):
    a = golden_arrays(CASES[f"shadow_intensity-{bound}-float32"])
    (r,) = _rows(a, "after BIAS_FLOAT32")
    assert np.array_equal(a["b"][r].astype(np.float32), _biased()) and a["zf"][r] == np.float32(ZF)
    exact = float(precise.shadow_intensity(_biased()[None].astype(np.float64), np.array([ZF]), bound=bound)[0])
    assert exact > 0.999
    flags = str(a["flags"][r]).split(",")
    assert "printed_hazard" in flags and "robustness" not in flags and "wide_spread" not in flags
    e, t = a["intensity"][r], a["intensity_tolerance_float32"][r]
    assert abs(e - exact) < 1e-9 and t <= 0.02
    # The guarded float32 evaluation (the two-point branch for xi4 <= 0) gives 0.99999976: inside the band;
    # what a printed formulation returns here (0, or NaN that saturate makes 0) is not.
    assert abs(0.99999976 - e) <= t and abs(0.0 - e) > t


@pytest.mark.parametrize("bound", ["lower", "upper"])
def test_for_a_function_that_biases_inside_the_stored_row_is_the_hazard(bound):
    name = f"shadow_intensity-{bound}-float32"
    plain = golden_arrays(CASES[name])
    (stored,) = _rows(plain, "as stored")
    (biased,) = _rows(plain, "after BIAS_FLOAT32")
    assert np.array_equal(plain["b"][stored].astype(np.float32), STORED)
    assert "robustness" in str(plain["flags"][stored]).split(",")  # unbiased: outside the moment space
    _, a = profiled_arrays(name, INSIDE)
    flags = str(a["flags"][stored]).split(",")
    assert "printed_hazard" in flags and "robustness" not in flags
    exact = float(precise.shadow_intensity(precise.bias_moments(STORED[None].astype(np.float64), BIAS_FLOAT32),
                                           np.array([ZF]), bound=bound)[0])
    e, t = a["intensity"][stored], a["intensity_tolerance_float32"][stored]
    assert abs(e - exact) < 1e-6 and abs(0.0 - e) > t
    # Biased twice (the harness's row, then the function's own bias) the texel is no hazard: re-derived, not kept.
    assert "printed_hazard" not in str(a["flags"][biased]).split(",")


@pytest.mark.parametrize("value, matches", [(0.0, True), (float("nan"), True), (0.5, False)])
def test_the_verdict_names_the_printed_formulation_only_when_the_output_is_its_value(tmp_path, value, matches):
    # A port correct everywhere but on the hazard row: 0 (what Algorithm 1 as printed returns there) and NaN
    # (the slides' code, before saturate) are the printed formulation's; 0.5 is nobody's.
    from moments_ref import golden

    from _oracles import golden_folder

    name = "shadow_intensity-lower-float32"
    gdir = golden_folder((name,))
    with np.load(gdir / f"{name}.npz") as g:
        expected = g["intensity"].astype(np.float32)
        (r,) = [i for i, c in enumerate(g["comment"]) if str(c).startswith("sweep, after BIAS_FLOAT32")]
    got = expected.copy()
    got[r] = value
    np.savez(tmp_path / "r.npz", **{f"{name}.intensity": got})
    case = golden.verify(gdir, tmp_path / "r.npz").cases[0]
    assert case.status == "fail" and case.verdict.failures == 1
    (group,) = case.groups
    assert group.rows == [r] and "printed_hazard" in group.flags
    assert group.cause.startswith("your result matches the papers' printed formulation, which cancels on this row "
                                  "(hazard)") == matches, group.cause
