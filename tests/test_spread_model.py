"""golden.spread: what the golden file stores, on toy cases whose values are known by hand.

Each expectation is written from the rule in the module's docstring (the smallest symmetric
tolerance holding the band, infinite where a legitimate evaluation has no value, flags per row
from any component, ties named by their first row, gated counts below 0.1), never from the
code's output.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from moments_ref.golden.cases import CASES, Case
from moments_ref.golden.spread import TIE_BAND, TruthMismatch, derive, gated_summary, golden_arrays


def _case(reference, dtype="float32", value_range=None, outputs=("y",), hook=None, metric="abs"):
    return Case(name="toy", function="toy", dtype=dtype, inputs=("x",), outputs=outputs, rows=None,
                reference=reference, value_range=value_range, spread_hook=hook, metric=metric)


def _derive(case, x, flags=None):
    n = len(x)
    return derive(case, {"x": np.asarray(x, case.dtype)}, ["random"] * n, [""] * n, flags or [()] * n)


def _nan_below_zero(x):
    x = np.asarray(x)
    return (np.where(x < 0, x.dtype.type(np.nan), x),)


def test_a_row_without_an_expected_value_gets_an_infinite_tolerance_not_nan():
    a = _derive(_case(_nan_below_zero), [0.5, -0.5])
    for dt in ("float32", "float64"):
        t = a[f"y_tolerance_{dt}"]
        assert np.isfinite(t[0]) and t[1] == np.inf


def _pair_second_ill(x):
    # two components: x, and x + 0.05 in float32 only (float32 and float64 disagree by 0.05: ill-conditioned)
    x = np.asarray(x)
    second = x + x.dtype.type(0.05) if x.dtype == np.float32 else x
    return (np.stack([x, second], axis=1),)


def test_a_row_is_wide_spread_when_any_component_is():
    a = _derive(_case(_pair_second_ill, value_range=(0, 1)), [0.5, 0.25])
    assert all("wide_spread" in f for f in a["flags"])


def _hook_in_float32(inputs, dtype):
    # a printed formulation beyond the cap of a bounded output, in float32 only
    x = np.asarray(inputs["x"], np.float64)
    return [(x + (0.3 if dtype == np.float32 else 0.0),)]


def _hook_in_float64(inputs, dtype):
    x = np.asarray(inputs["x"], np.float64)
    return [(x + (0.3 if dtype == np.float64 else 0.0),)]


def _hook_one_component(inputs, dtype):
    x = np.asarray(inputs["x"], np.float64)
    return [(np.stack([x, x + 0.3], axis=1),)]


def _pair(x):
    x = np.asarray(x)
    return (np.stack([x, x], axis=1),)


def test_printed_hazards_are_the_float32_ports_and_any_component_flags_the_row():
    # A port in float32 is the one that copies the printed formula: its hazard flags the row; a float64-only one
    # does not.
    a = _derive(_case(_identity, value_range=(0, 1), hook=_hook_in_float32), [0.5])
    assert "printed_hazard" in a["flags"][0]
    a = _derive(_case(_identity, value_range=(0, 1), hook=_hook_in_float64), [0.5])
    assert "printed_hazard" not in a["flags"][0]
    a = _derive(_case(_pair, value_range=(0, 1), hook=_hook_one_component), [0.5])
    assert "printed_hazard" in a["flags"][0]


def _identity(x):
    return (np.asarray(x),)


def test_a_float64_cases_expected_values_are_stored_in_float64():
    a = _derive(_case(_identity, dtype="float64"), [0.1, 1 / 3])
    assert a["y"].dtype == np.float64 and a["y"].tolist() == [0.1, 1 / 3]


def test_the_ungated_reason_is_the_rows_first_ungated_flag():
    both = ("outside_moment_space", "near_support_point")
    a = _derive(_case(_identity), [0.5, 0.25, 0.125], flags=[both, (), both])
    levels = gated_summary(_case(_identity), a)["float32"]["levels"]
    assert levels["contract"]["ungated"] == {"outside_moment_space": 2}


def test_a_tolerance_of_exactly_0_1_is_not_gated_below_0_1():
    case = _case(_identity)
    a = _derive(case, [0.5, 0.25])
    a = dict(a)
    a["y_tolerance_float32"] = np.array([0.1, 0.05])
    assert gated_summary(case, a)["float32"]["gated_below_0.1"] == 1


def _quarters(x):
    x = np.asarray(x)  # in the dtype of the evaluation: floor(4 sqrt(1 - x^2)) changes code at x = sqrt(7)/4
    return (np.floor(4 * np.sqrt(1 - x * x)).astype(np.uint16),)


def test_a_reference_disagreeing_with_its_truth_names_the_first_row_away_from_a_boundary():
    edge = np.sqrt(7) / 4
    x = np.array([edge * (1 - 4e-7), edge * (1 + 4e-7), 0.3])
    case = Case(name="toy", function="toy", dtype="float64", inputs=("x",), outputs=("q",), rows=None,
                reference=_quarters, truth=_quarters, metric="exact", margin=lambda x: np.full(3, 2 * TIE_BAND))
    with pytest.raises(TruthMismatch, match="on 2 rows away from a rounding boundary; first row 0"):
        derive(case, {"x": x}, ["random"] * 3, [""] * 3, [()] * 3)


def test_a_shipped_cases_arrays_are_shared_read_only_and_a_copy_is_generated_anew():
    case = CASES["psi4-float32"]
    a = golden_arrays(case)
    assert not any(v.flags.writeable for v in a.values())
    # a changed copy of the case (another reference) is not the shipped one: its own arrays
    doubled = replace(case, reference=lambda xi4: tuple(2 * np.asarray(v) for v in case.reference(xi4=xi4)),
                      truth=None)
    b = golden_arrays(doubled)
    assert np.array_equal(b["u"], 2 * np.asarray(case.reference(xi4=a["xi4"].astype(np.float64))[0]))
    assert all(v.flags.writeable for v in b.values())


def test_the_summarys_typical_tolerance_is_the_median_of_the_finite_row_tolerances():
    case = _case(_identity)
    a = dict(_derive(case, [0.5, 0.25, 0.125, 0.0625]))
    a["y_tolerance_float32"] = np.array([1e-6, 2e-6, 1e-3, np.inf])
    s = gated_summary(case, a)["float32"]
    assert s["median_tolerance"] == 2e-6 and s["gated"] == 3
