"""golden.compare on synthetic cases whose verdict is known row by row from their construction:
the robustness tally counted exactly, rows with an infinite tolerance, signed integer codes,
acceptable (tie) codes, the ulps metric."""

from __future__ import annotations

import numpy as np
import pytest

from moments_ref import InputError
from moments_ref.golden.compare import compare
from moments_ref.golden.units import ulp

N = 12


def _float_case(metric="abs"):
    entry = {"compare": ["v"], "outputs": {"v": {"dtype": "float64", "shape": [N, 2]}}, "dtype": "float32",
             "metric": metric, "value_range": [0, 1]}
    expected = {
        "v": np.full((N, 2), 0.5),
        "v_tolerance_float32": np.full((N, 2), 1e-3),
        "v_tolerance_float64": np.full((N, 2), 1e-9),
        "result": np.array(["valid"] * N, dtype="U10"),
        "flags": np.array([""] * N, dtype=object),
    }
    return entry, expected


def test_the_robustness_tally_counts_each_kind_of_failure_exactly():
    entry, expected = _float_case()
    robust = [0, 1, 2, 3, 4, 5]
    expected["flags"][robust] = ["robustness", "robustness,wide_spread", "robustness", "robustness", "robustness",
                                 "robustness"]
    got = np.full((N, 2), 0.5, np.float32)
    got[0, 1] = np.nan  # nonfinite
    got[1, 0] = np.inf  # nonfinite (outside the range too, but counted once, as nonfinite)
    got[2, 0] = 1.5  # finite, outside [0, 1]
    got[3, 1] = -0.25  # finite, outside [0, 1]
    got[4, 0] = 0.6  # in range, beyond the tolerance
    # row 5: a robustness row that passes; rows 6.. contract rows
    got[7, 0] = np.nan  # a contract row: fails the verdict, not in the tally
    got[8, 1] = 2.0  # a contract row outside the range: not in the tally
    v = compare(entry, expected, {"v": got})
    assert v.robustness_tally() == {"rows": 6, "would_fail": 5, "nonfinite": 2, "outside_range": 2}
    assert list(np.flatnonzero(~v.row_pass)) == [7, 8]
    assert list(np.flatnonzero(~v.strict_pass)) == [0, 1, 2, 3, 4, 7, 8]
    assert list(np.flatnonzero(v.nonfinite)) == [0, 1, 7]
    assert list(np.flatnonzero(v.outside_range)) == [2, 3, 8]
    vs = compare(entry, expected, {"v": got}, strict=True)
    assert list(np.flatnonzero(~vs.row_pass)) == [0, 1, 2, 3, 4, 7, 8] and vs.strict


def test_rows_with_an_infinite_tolerance_need_only_a_finite_value_in_range():
    entry, expected = _float_case()
    expected["v_tolerance_float32"][[3, 4, 5, 6]] = np.inf
    expected["result"][[3, 4, 5, 6]] = "acceptable"
    got = np.full((N, 2), 0.5, np.float32)
    got[3] = [0.0, 1.0]  # anything in [0, 1], its ends included
    got[4, 0] = np.nextafter(np.float32(1), np.float32(2))  # just outside
    got[5, 1] = np.nan
    got[6, 0] = -np.inf
    got[9, 0] = 0.5 + 2e-3  # gated: beyond its tolerance
    v = compare(entry, expected, {"v": got})
    assert list(np.flatnonzero(~v.row_pass)) == [4, 5, 6, 9]
    assert list(np.flatnonzero(~v.gated)) == [3, 4, 5, 6]
    assert v.score[3] == 0 and np.isinf(v.score[[4, 5, 6]]).all() and v.score[9] == pytest.approx(abs(float(np.float32(0.5 + 2e-3)) - 0.5) / 1e-3)
    assert list(np.flatnonzero(v.outside_range)) == [4] and list(np.flatnonzero(v.nonfinite)) == [5, 6]
    # the float64 column gates every row (its tolerances are finite)
    got64 = np.full((N, 2), 0.5)
    got64[3, 0] = 0.75
    v64 = compare(entry, expected, {"v": got64}, port_dtype="float64")
    assert list(np.flatnonzero(~v64.row_pass)) == [3] and v64.gated.sum() == N - 4  # result decides gated


def test_the_tolerance_is_inclusive_and_measured_in_ulps_where_the_case_says():
    entry, expected = _float_case("ulps")
    expected["v_tolerance_float32"][:] = 4
    step = float(ulp(np.array([0.5]), "float32")[0])
    got = np.full((N, 2), 0.5, np.float32)
    got[1, 0] = np.float32(0.5 + 4 * step)  # exactly 4 ulps: passes
    got[2, 1] = np.float32(0.5 - 5 * step)  # 5 ulps: fails
    v = compare(entry, expected, {"v": got})
    assert list(np.flatnonzero(~v.row_pass)) == [2]
    assert v.error[1] == 4 and v.error[2] == 5


def _code_case(width="uint32"):
    entry = {"compare": ["c"], "outputs": {"c": {"dtype": width, "shape": [4, 2]}}, "dtype": "float32",
             "metric": "exact", "value_range": None}
    codes = np.array([[0xFFFFFFF0, 7], [1, 2], [0x80000000, 0], [5, 5]], np.uint64).astype(width)
    alts = np.zeros((4, 2, 2), width)
    alts[3] = [[6, 5], [5, 4]]  # row 3 is on a rounding tie: either code of each component
    expected = {"c": codes, "c_acceptable": alts, "result": np.array(["valid", "valid", "valid", "acceptable"]),
                "flags": np.array([""] * 4, dtype=object)}
    return entry, expected, codes


def test_signed_codes_of_the_manifests_width_are_read_as_their_bits():
    entry, expected, codes = _code_case()
    assert compare(entry, expected, {"c": codes.view(np.int32)}).passed  # 0xFFFFFFF0 as -16, 0x80000000 as -2^31
    assert compare(entry, expected, {"c": codes.astype(np.int64)}).passed  # the values, wider
    with pytest.raises(InputError, match=r"'c' row 0 holds the negative code -16 \(int64\)"):
        compare(entry, expected, {"c": codes.view(np.int32).astype(np.int64)})  # sign-extended: no code
    wide = codes.astype(np.uint64)
    wide[1, 0] += 1 << 32  # beyond the width: a wrong code, not the low bits
    v = compare(entry, expected, {"c": wide})
    assert list(np.flatnonzero(~v.row_pass)) == [1]


def test_a_tie_row_accepts_its_stored_codes_and_no_other_row_does():
    entry, expected, codes = _code_case()
    got = codes.copy()
    got[3] = [6, 4]  # each component one of the tie's codes
    assert compare(entry, expected, {"c": got}).passed
    got[3] = [4, 5]  # 4 is not stored for component 0
    assert list(np.flatnonzero(~compare(entry, expected, {"c": got}).row_pass)) == [3]
    expected["c_acceptable"][1] = [[2, 2], [1, 3]]  # alternatives on a valid row are not accepted
    got = codes.copy()
    got[1] = [2, 3]
    v = compare(entry, expected, {"c": got})
    assert list(np.flatnonzero(~v.row_pass)) == [1] and np.isinf(v.score[1]) and v.error[1] == 1


def test_a_row_held_to_no_value_and_no_range_still_needs_a_finite_value():
    entry, expected = _float_case()
    entry["value_range"] = None
    expected["v_tolerance_float32"][[2, 3]] = np.inf
    expected["result"][[2, 3]] = "acceptable"
    got = np.full((N, 2), 0.5, np.float32)
    got[2] = [1e30, -7.0]  # any finite value: no range to leave
    got[3, 1] = np.nan
    v = compare(entry, expected, {"v": got})
    assert list(np.flatnonzero(~v.row_pass)) == [3] and list(np.flatnonzero(v.nonfinite)) == [3]
    got[3, 1] = -np.inf
    assert list(np.flatnonzero(~compare(entry, expected, {"v": got}).row_pass)) == [3]


def test_a_negative_code_is_refused_naming_its_row_and_a_bad_precision_or_dtype_naming_the_array():
    entry, expected, codes = _code_case()
    c = codes.astype(np.int64)
    c[2, 1] = -1
    with pytest.raises(InputError, match=r"'c' row 2 holds the negative code -1 \(int64\)"):
        compare(entry, expected, {"c": c})
    entry, expected = _float_case()
    with pytest.raises(InputError, match="port_dtype: expected float32 or float64, got 'float16'"):
        compare(entry, expected, {"v": np.zeros((N, 2), np.float32)}, port_dtype="float16")
    with pytest.raises(InputError, match=r"^results: 'v' expected a real float32 array"):
        compare(entry, expected, {"v": np.zeros((N, 2), np.int32)})
    with pytest.raises(InputError, match=r"^results: 'k.v' expected a real float32 array"):
        compare(entry, expected, {"v": np.zeros((N, 2), np.int32)}, case="k")
