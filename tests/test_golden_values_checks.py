"""golden/values.py: the value checks of a golden case's arrays, one statement at a time.

A small case written here by hand passes; each perturbation of one array (a missing array, an unknown
category or result, a non-finite or out-of-range expected value, a tolerance zero, negative or NaN, an
acceptable code the output's dtype cannot hold or of the wrong shape) raises InputError naming the array
and the first offending row with its tc_id; the edges that are allowed (a value on either end of the
range, a tolerance of +inf, an exact case without tolerances) pass.
"""

from __future__ import annotations

import numpy as np
import pytest

from moments_ref import InputError
from moments_ref.golden.notes import CATEGORIES, RESULTS
from moments_ref.golden.values import check_case_values

N = 5


def _float_case():
    meta = {"inputs": ["b"], "compare": ["intensity"], "metric": "abs", "value_range": [0.0, 1.0],
            "outputs": {"intensity": {"dtype": "float32"}}}
    arrays = {"b": np.zeros((N, 4)), "intensity": np.linspace(0, 1, N), "category": np.array([CATEGORIES[0]] * N),
              "comment": np.array([""] * N), "result": np.array([tuple(RESULTS)[0]] * N),
              "tc_id": np.arange(10, 10 + N), "intensity_tolerance_float32": np.full(N, 1e-6),
              "intensity_tolerance_float64": np.full(N, np.inf)}
    return meta, arrays


def _exact_case():
    meta = {"inputs": ["r"], "compare": ["q"], "metric": "exact", "outputs": {"q": {"dtype": "uint16"}}}
    arrays = {"r": np.zeros((N, 4)), "q": np.zeros((N, 4), np.uint16), "category": np.array([CATEGORIES[-1]] * N),
              "comment": np.array([""] * N), "result": np.array([tuple(RESULTS)[-1]] * N), "tc_id": np.arange(N),
              "q_acceptable": np.zeros((N, 2, 4), np.int64)}
    return meta, arrays


def test_a_well_formed_case_passes_its_edges_included():
    meta, arrays = _float_case()
    assert check_case_values(meta, arrays, "t") is None  # values 0 and 1: both ends of the range
    meta, arrays = _exact_case()
    arrays["q_acceptable"][:, 1] = 65535  # the dtype's ends
    assert check_case_values(meta, arrays, "t") is None
    del arrays["q_acceptable"]  # optional
    assert check_case_values(meta, arrays, "t") is None
    meta, arrays = _float_case()
    del meta["value_range"]  # a cache entry has none: any finite value
    arrays["intensity"][2] = 7.0
    assert check_case_values(meta, arrays, "t") is None


@pytest.mark.parametrize("key", ["b", "intensity", "category", "comment", "result", "tc_id",
                                 "intensity_tolerance_float32", "intensity_tolerance_float64"])
def test_each_needed_array_is_required(key):
    meta, arrays = _float_case()
    del arrays[key]
    with pytest.raises(InputError, match=f"t lacks the array '{key}'"):
        check_case_values(meta, arrays, "t")


def _bad(meta, arrays, match):
    with pytest.raises(InputError, match=match):
        check_case_values(meta, arrays, "case x")


@pytest.mark.parametrize("key, value", [("category", "bogus"), ("result", "bogus")])
def test_unknown_categories_and_results_name_the_first_row(key, value):
    meta, arrays = _float_case()
    arrays[key] = arrays[key].astype(object)
    arrays[key][3] = value
    arrays[key][4] = value
    _bad(meta, arrays, rf"case x: {key} is '{value}', not one of .* at row 3 \(tc_id 13\)")


@pytest.mark.parametrize("value, problem", [(np.nan, "is not finite"), (np.inf, "is not finite"),
                                            (-np.inf, "is not finite"), (1 + 2.0**-40, "beyond the case's value_range"),
                                            (-(2.0**-60), "beyond the case's value_range")])
def test_expected_values_finite_and_in_range(value, problem):
    meta, arrays = _float_case()
    arrays["intensity"][0] = 1.0  # the range's upper end, before the bad row: not named
    arrays["intensity"][1] = value
    arrays["intensity"][4] = value
    _bad(meta, arrays, rf"case x: intensity (is [^ ]+, )?{problem}.* at row 1 \(tc_id 11\)")


@pytest.mark.parametrize("dt", ["float32", "float64"])
@pytest.mark.parametrize("value", [0.0, -1e-9, np.nan, -np.inf])
def test_tolerances_positive_never_nan(dt, value):
    meta, arrays = _float_case()
    arrays[f"intensity_tolerance_{dt}"][2] = value
    _bad(meta, arrays, rf"intensity_tolerance_{dt} is .* at row 2 \(tc_id 12\)")


def test_the_message_ends_with_the_first_row_and_its_tc_id():
    meta, arrays = _float_case()
    arrays["intensity"][0] = np.nan
    with pytest.raises(InputError) as err:
        check_case_values(meta, arrays, "c")
    assert str(err.value).endswith("at row 0 (tc_id 10)")


@pytest.mark.parametrize("change", ["above", "below", "flat", "shape"])
def test_acceptable_codes_fit_the_outputs_dtype_and_shape(change):
    meta, arrays = _exact_case()
    acc = arrays["q_acceptable"]
    if change == "above":
        acc[4, 1, 3] = 65536
    elif change == "below":
        acc[0, 0, 0] = -1
    elif change == "flat":
        arrays["q_acceptable"] = np.zeros(N, np.int64)
    else:
        arrays["q_acceptable"] = np.zeros((N, 2, 3), np.int64)
    _bad(meta, arrays, r"case x: q_acceptable must hold uint16 codes of shape \(rows, K\) \+ \(4,\)")


def test_an_exact_case_needs_no_tolerances_and_skips_the_float_checks():
    meta, arrays = _exact_case()
    assert not any(k.startswith("q_tolerance") for k in arrays)
    arrays["q"] = arrays["q"].astype(np.float64)
    arrays["q"][0, 0] = np.nan  # not a float output: its finiteness is not this check's
    assert check_case_values(meta, arrays, "t") is None


def test_a_vector_outputs_bad_row_is_named_by_its_row_not_its_column():
    meta, arrays = _float_case()
    arrays["intensity"] = np.full((N, 4), 0.5)
    arrays["intensity"][3, 1] = np.nan
    _bad(meta, arrays, r"case x: intensity is not finite at row 3 \(tc_id 13\)")


def test_a_scalar_exact_outputs_acceptable_codes_are_rows_by_k():
    meta, arrays = _exact_case()
    arrays["q"] = np.zeros(N, np.uint16)
    arrays["q_acceptable"] = np.zeros((N, 2), np.int64)
    assert check_case_values(meta, arrays, "t") is None
    arrays["q_acceptable"] = np.zeros(N, np.int64)  # one code per row: not (rows, K)
    _bad(meta, arrays, r"q_acceptable must hold uint16 codes of shape \(rows, K\) \+ \(\)")
