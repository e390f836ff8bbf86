"""The verdict engine's own rules, stated as specifications: golden.compare (what passes, what a row's
error and score are), golden.spread (ulps, tolerance rounding, the legitimate variants a tolerance
must hold) and conformance.verdict (readback words, ulp distance, the rows shown).

Each expectation is written from the rule in the module's docstring, with hand-built manifest
entries and golden arrays, never from the code's output.
"""

import numpy as np
import pytest

from moments_ref import InputError
from moments_ref.conformance.verdict import compare_case, select_worst, ulp_distance
from moments_ref.golden.compare import compare
from moments_ref.golden.units import ceil2 as _ceil2, ulp

F32 = np.float32


def _entry(metric="abs", dtype="float32", out_dtype="float32", value_range=None, exact=False):
    e = {"compare": ["y"], "outputs": {"y": {"dtype": out_dtype}}, "dtype": dtype, "metric": metric,
         "inputs": ["x"], "input_order": ["x"], "exact": exact}
    if value_range is not None:
        e["value_range"] = value_range
    return e


def _golden(y, tol32, tol64=None, result=None):
    y = np.asarray(y, np.float64)
    n = len(y)
    return {"y": y, "y_tolerance_float32": np.broadcast_to(np.asarray(tol32, np.float64), y.shape).copy(),
            "y_tolerance_float64": np.broadcast_to(np.asarray(tol64 if tol64 is not None else tol32, np.float64),
                                                   y.shape).copy(),
            "result": np.asarray(result if result is not None else ["valid"] * n), "tc_id": np.arange(1, n + 1),
            "x": np.zeros(n), "category": np.asarray(["random"] * n), "flags": np.asarray([""] * n),
            "comment": np.asarray([""] * n)}


# ---------------------------------------------------------------------------
# golden.compare: the rule


def test_a_value_exactly_at_its_tolerance_passes_and_the_next_float_fails():
    tol = 2.0 ** -10  # exactly representable: the error 0.5 + 2^-10 - 0.5 is exactly 2^-10
    g = _golden([0.5, 0.5, 0.5], tol)
    got = np.array([0.5 + tol, 0.5 - tol, np.nextafter(F32(0.5 + tol), F32(1))], F32)
    v = compare(_entry(), g, {"y": got})
    assert v.row_pass.tolist() == [True, True, False]
    assert v.score[:2].tolist() == [1.0, 1.0] and v.score[2] > 1
    assert not v.passed and v.failures == 1


def test_nan_and_inf_fail_with_an_infinite_score_even_on_ungated_rows():
    g = _golden([0.5, 0.5, 0.5, 0.5], [0.1, 0.1, np.inf, np.inf], result=["valid", "valid", "acceptable",
                                                                            "acceptable"])
    got = np.array([np.nan, np.inf, np.nan, 0.25], F32)
    v = compare(_entry(value_range=[0.0, 1.0]), g, {"y": got})
    assert v.row_pass.tolist() == [False, False, False, True]
    assert np.isinf(v.score[:3]).all() and v.score[3] == 0
    assert v.gated.tolist() == [True, True, False, False]


def test_ungated_rows_need_only_a_finite_value_in_the_value_range():
    g = _golden([0.5] * 4, np.inf, result=["acceptable"] * 4)
    got = np.array([0.0, 1.0, -1e-3, 1.001], F32)
    v = compare(_entry(value_range=[0.0, 1.0]), g, {"y": got})
    assert v.row_pass.tolist() == [True, True, False, False]
    assert v.score.tolist() == [0.0, 0.0, np.inf, np.inf]
    assert compare(_entry(), g, {"y": got}).passed  # no range stated: any finite value


def test_the_worst_component_of_a_vector_output_decides_the_row():
    # Per component tolerances; component 2 is the worst relative to its tolerance although
    # component 0 has the largest absolute error.
    e = np.zeros((2, 4))
    tol = np.array([[1e-2, 1e-3, 1e-4, 1e-3]] * 2)
    g = _golden(e, tol)
    got = np.array([[5e-3, 0, 5e-4, 0], [0, 0, 0, 5e-4]], F32)
    v = compare(_entry(), g, {"y": got})
    assert v.row_pass.tolist() == [False, True]
    np.testing.assert_allclose(v.score, [5e-4 / 1e-4, 0.5], rtol=1e-6)
    np.testing.assert_allclose(v.error, [5e-4, 5e-4], rtol=1e-6)
    np.testing.assert_allclose(v.tolerance, [1e-4, 1e-3])
    assert v.worst_rows(None) == [0]


def test_ulps_are_counted_in_the_ports_precision_at_the_expected_value():
    # Just above 2: the float32 spacing is 2^-22, below 2 it is 2^-23.
    above, below = float(np.nextafter(F32(2), F32(3))), float(np.nextafter(F32(2), F32(0)))
    g = _golden([above, below], 2.0)
    got = np.array([above + 2 * 2.0 ** -22, below - 3 * 2.0 ** -23], F32)
    v = compare(_entry(metric="ulps"), g, {"y": got})
    assert v.row_pass.tolist() == [True, False]
    np.testing.assert_allclose(v.error, [2.0, 3.0])
    # In float64 the same differences are many ulps.
    v64 = compare(_entry(metric="ulps", dtype="float64"), g, {"y": got.astype(np.float64)}, port_dtype="float64")
    assert not v64.row_pass.any()
    assert v64.error[0] == 2 * 2.0 ** -22 / np.spacing(above)


def test_worst_rows_are_the_failing_rows_by_score_each_once():
    g = _golden([0.0] * 6, 1.0)
    got = np.array([3.0, 0.5, 7.0, 2.0, 7.0, 0.0], F32)
    v = compare(_entry(), g, {"y": got})
    assert v.worst_rows(None) == [2, 4, 0, 3]  # largest score first, ties in row order, passing rows never
    assert v.worst_rows(2) == [2, 4] and v.worst_rows(0) == []


def test_integer_codes_accept_the_stored_alternatives_only_on_acceptable_rows():
    e = {"compare": ["q"], "outputs": {"q": {"dtype": "uint16"}}, "dtype": "float32", "metric": "exact"}
    g = {"q": np.array([[10, 20], [10, 20], [10, 20]], np.uint16),
         "q_acceptable": np.array([[[10, 20], [11, 20]]] * 3, np.uint16),
         "result": np.array(["acceptable", "valid", "acceptable"]), "tc_id": np.arange(1, 4)}
    got = np.array([[11, 20], [11, 20], [12, 20]], np.uint16)
    v = compare(e, g, {"q": got})
    assert v.row_pass.tolist() == [True, False, False]
    assert v.score.tolist() == [0.0, np.inf, np.inf]
    assert v.error.tolist() == [1.0, 1.0, 2.0]  # the distance to the golden code, also where accepted
    assert v.gated.tolist() == [False, True, False]
    # codes compare by value whatever the integer width; a value beyond the format is a wrong code
    assert compare(e, g, {"q": got.astype(np.uint32)}).row_pass.tolist() == [True, False, False]
    wide = got.astype(np.uint32)
    wide[0, 0] += 1 << 16  # 0x1000B: not a 16-bit code, although its low bits are
    assert compare(e, g, {"q": wide}).row_pass.tolist() == [False, False, False]
    assert compare(e, g, {"q": got.astype(np.int16)}).row_pass.tolist() == [True, False, False]  # the same bits
    with pytest.raises(InputError, match="negative code"):
        compare(e, g, {"q": -got.astype(np.int64)})
    with pytest.raises(InputError, match="integer dtype"):
        compare(e, g, {"q": got.astype(np.float32)})
    with pytest.raises(InputError, match="has shape"):
        compare(e, g, {"q": got[:2]})


def test_robustness_rows_are_judged_but_decide_the_verdict_only_when_strict():
    # rows 1-3 lie beyond the contract; row 1 NaN, row 3 off by 1 and outside [0, 1], row 4 a
    # contract row with a NaN (it fails either way and is no robustness row)
    g = _golden([0.5] * 5, 0.1)
    g["flags"] = np.asarray(["", "robustness", "robustness", "wide_spread,robustness", ""])
    got = np.array([0.5, np.nan, 0.55, 1.5, np.nan], F32)
    v = compare(_entry(value_range=[0.0, 1.0]), g, {"y": got})
    assert v.level.tolist() == ["contract", "robustness", "robustness", "robustness", "contract"]
    assert v.row_pass.tolist() == [True, True, True, True, False] and v.failures == 1
    assert v.strict_pass.tolist() == [True, False, True, False, False]
    assert v.robustness_tally() == {"rows": 3, "would_fail": 2, "nonfinite": 1, "outside_range": 1}
    s = compare(_entry(value_range=[0.0, 1.0]), g, {"y": got}, strict=True)
    assert s.row_pass.tolist() == [True, False, True, False, False] and s.strict
    assert s.level.tolist() == v.level.tolist()
    del g["flags"]  # a golden file without flags: every row is a contract row
    v = compare(_entry(value_range=[0.0, 1.0]), g, {"y": got})
    assert set(v.level) == {"contract"} and v.robustness_tally()["rows"] == 0 and v.failures == 3


def test_integer_codes_compare_by_value_and_a_negative_value_names_its_row():
    e = {"compare": ["q"], "outputs": {"q": {"dtype": "uint16"}}, "dtype": "float32", "metric": "exact"}
    codes = np.array([[0, 0xFFFF], [0x8000, 7], [3, 0]], np.uint16)
    g = {"q": codes, "result": np.array(["valid"] * 3), "tc_id": np.arange(1, 4)}
    # a signed array of the format's width holds the codes' bits (a shader's int buffer): -1 is 0xFFFF
    assert compare(e, g, {"q": codes.view(np.int16)}).passed
    # any other integer array holds the values; 0 is a code, not a negative one
    for dt in (np.int32, np.int64, np.uint32, np.uint64):
        assert compare(e, g, {"q": codes.astype(dt)}).passed, dt
    got = codes.astype(np.int64)
    got[1, 1] = -5  # one negative component, after a row holding zeros
    with pytest.raises(InputError, match=r"'q' row 1 holds the negative code -5 \(int64\)"):
        compare(e, g, {"q": got})


def test_the_error_of_a_code_is_its_distance_to_the_golden_code_exactly():
    e = {"compare": ["p"], "outputs": {"p": {"dtype": "uint32"}}, "dtype": "float32", "metric": "exact"}
    g = {"p": np.array([2**24 + 1, 2**24, 10], np.uint32), "result": np.array(["valid"] * 3), "tc_id": np.arange(1, 4)}
    v = compare(e, g, {"p": np.array([2**24, 2**24 + 1, 7], np.uint32)})  # 2^24 + 1 is no float32
    assert v.error.tolist() == [1.0, 1.0, 3.0]  # below or above: a distance
    assert v.score.tolist() == [np.inf] * 3 and v.tolerance.tolist() == [0.0] * 3


def test_a_float64_port_is_judged_in_float64():
    g = _golden([0.1, 1 / 3], 1e-17, tol64=1e-17)  # neither value is a float32
    v = compare(_entry(dtype="float64"), g, {"y": np.array([0.1, 1 / 3])}, port_dtype="float64")
    assert v.passed and v.error.tolist() == [0.0, 0.0]
    v = compare(_entry(dtype="float64"), g, {"y": np.array([0.1, 1 / 3]).astype(F32).astype(np.float64)},
                port_dtype="float64")
    assert not v.row_pass.any()


def test_a_row_is_nonfinite_outside_the_range_or_ungated_when_any_component_is():
    g = _golden(np.full((4, 2), 0.5), np.array([[0.1, 0.1], [0.1, 0.1], [0.1, np.inf], [0.1, 0.1]]))
    got = np.array([[0.5, 0.5], [np.nan, 0.5], [0.5, 1.5], [-0.5, 0.55]], F32)
    v = compare(_entry(value_range=[0.0, 1.0]), g, {"y": got})
    assert v.nonfinite.tolist() == [False, True, False, False]
    assert v.outside_range.tolist() == [False, False, True, True]
    assert v.gated.tolist() == [True, True, False, True]
    assert v.row_pass.tolist() == [True, False, False, False]


@pytest.mark.parametrize("port, arr, ok", [("float32", np.float32, True), ("float32", np.float64, False),
                                          ("float64", np.float64, True), ("float64", np.float32, False)])
def test_float_outputs_must_be_in_the_ports_precision(port, arr, ok):
    g = _golden([0.5], 1.0)
    call = lambda: compare(_entry(), g, {"y": np.array([0.5], arr)}, port_dtype=port)  # noqa: E731
    if ok:
        assert call().passed
    else:
        with pytest.raises(InputError, match=port):
            call()
    with pytest.raises(InputError, match="missing"):
        compare(_entry(), g, {"z": np.array([0.5], arr)}, port_dtype=port)
    with pytest.raises(InputError, match="float16"):
        compare(_entry(), g, {"y": np.array([0.5], arr)}, port_dtype="float16")


def test_the_port_precision_picks_the_tolerance_column():
    g = _golden([0.5], 1e-3, tol64=1e-9)
    got32 = np.array([0.5 + 1e-4], F32)
    assert compare(_entry(), g, {"y": got32}).passed
    assert not compare(_entry(), g, {"y": got32.astype(np.float64)}, port_dtype="float64").passed


# ---------------------------------------------------------------------------
# golden.spread: ulps and tolerance rounding


def test_ulp_is_the_spacing_above_the_expected_magnitude():
    for x, want in [(1.0, 2.0 ** -23), (float(np.nextafter(F32(1), F32(0))), 2.0 ** -24),
                    (float(np.nextafter(F32(4), F32(5))), 2.0 ** -21), (-3.0, 2.0 ** -22), (0.0, 2.0 ** -149)]:
        assert ulp(x, np.float32) == want, x
    # below the smallest normal: the smallest normal's spacing, also in float64
    assert ulp(1e-40, np.float32) == 2.0 ** -149 and ulp(1e-310, np.float64) == 2.0 ** -1074
    assert ulp(1.0, np.float64) == 2.0 ** -52
    # float64 ulps of values that are no float32: just below 2, and beyond float32's range
    assert ulp(float(np.nextafter(2.0, 0.0)), np.float64) == 2.0 ** -52
    assert ulp(1e300, np.float64) == np.spacing(1e300) and ulp(-1e-300, np.float64) == np.spacing(1e-300)
    assert ulp(np.array([1.0, np.nan]), np.float32)[0] == 2.0 ** -23 and np.isnan(ulp(np.nan, np.float32))


def test_tolerances_round_up_to_two_significant_digits():
    t = np.array([1.234e-5, 1.2e-5, 9.91, 0.0, np.inf, 1e-300, 3.0 * (1 + 4e-16)])
    out = _ceil2(t)
    np.testing.assert_allclose(out[:3], [1.3e-5, 1.2e-5, 10.0], rtol=1e-12)
    assert out[3] == 0.0 and out[4] == np.inf and out[5] == 1e-300  # left alone
    assert out[6] == pytest.approx(3.0, rel=1e-12)  # a representation error above 3.0 is not a digit
    # ... but an excess over 10^-12 of the value is: it rounds up
    assert _ceil2(np.array([1.2e-5 * (1 + 1.5e-12)]))[0] == pytest.approx(1.3e-5, rel=1e-12, abs=0)
    # rounded down to 1e-290; below, where 10^e nears float64's smallest normals, left as they are
    assert _ceil2(np.array([1.234e-290]))[0] == pytest.approx(1.3e-290, rel=1e-12, abs=0)
    assert _ceil2(np.array([1e-290, 5e-291]))[:].tolist() == [1e-290, 5e-291]
    rng = np.random.default_rng(1)
    t = 10.0 ** rng.uniform(-30, 5, 2000)
    out = _ceil2(t)
    e = np.floor(np.log10(t)) - 1
    assert np.all(out >= t * (1 - 1e-12))
    assert np.all(out - t < 10 ** e * (1 + 1e-9))  # less than one unit in the second digit above
    mant = out / 10 ** e
    np.testing.assert_allclose(mant, np.round(mant), rtol=0, atol=1e-6)  # two digits


# ---------------------------------------------------------------------------
# conformance.verdict: readback words, ulp distance, the rows shown


def test_ulp_distance_counts_float32_values_across_zero():
    tiny = np.float32(2.0 ** -149)
    values = np.array([-2 * tiny, -tiny, 0.0, tiny, 2 * tiny, 3 * tiny], F32)
    for i, a in enumerate(values):
        for j, b in enumerate(values):
            assert ulp_distance(np.array([a]), np.array([b], np.float64))[0] == abs(i - j)
    assert ulp_distance(F32([-0.0]), np.array([0.0]))[0] == 0
    # -1 and 1: every positive float below 1 counted on each side
    assert ulp_distance(F32([-1.0]), np.array([1.0]))[0] == 2 * 0x3F800000
    assert ulp_distance(F32([1.0]), np.array([-1.0]))[0] == 2 * 0x3F800000


def test_ulp_distance_nan_in_either_is_inf_and_overflow_rounds_to_inf():
    d = ulp_distance(F32([np.nan, 1.0, np.nan, 1.0]), np.array([1.0, np.nan, np.nan, 1.0]))
    assert d.tolist() == [np.inf, np.inf, np.inf, 0.0]
    big = np.finfo(F32).max
    assert ulp_distance(F32([big]), np.array([1e39]))[0] == 1  # 1e39 rounds to +inf, one past the largest
    assert ulp_distance(F32([np.inf]), np.array([1e39]))[0] == 0


def _exact_case(codes, words, result=None):
    n = len(codes)
    meta = {"compare": ["q"], "outputs": {"q": {"dtype": "uint16"}}, "dtype": "float32", "metric": "exact",
            "exact": True, "inputs": ["x"], "input_order": ["x"]}
    arrays = {"q": np.asarray(codes, np.uint16), "q_acceptable": np.asarray(codes, np.uint16)[:, None],
              "result": np.asarray(result or ["valid"] * n), "tc_id": np.arange(1, n + 1), "x": np.zeros(n),
              "category": np.asarray(["random"] * n), "flags": np.asarray([""] * n),
              "comment": np.asarray([""] * n)}
    return compare_case("pack-test", meta, arrays, {"q": np.asarray(words, np.uint32)})


def test_a_readback_word_wider_than_the_format_fails_even_where_clipping_gives_the_code():
    v = _exact_case([0xFFFF, 0, 7], [0x1FFFF, 0, 7])  # 0x1FFFF clips to 0xFFFF, the expected code
    assert v.row_pass.tolist() == [False, True, True]
    assert any("wider than the format" in n for n in v.notes)
    assert v.worst[0]["index"] == 0 and v.worst[0]["score"] == np.inf
    assert _exact_case([0xFFFF, 0], [0xFFFF, 0]).passed and not _exact_case([0xFFFF], [0xFFFF]).notes


def test_ulp_distance_is_exact_beyond_float32s_integers():
    one = np.float32(1.0)
    far = (np.array([0x3F800000 + 2**24 + 1], np.uint32)).view(F32)  # 2^24 + 1 float32 values above 1
    # compared as Python floats: a float32 of 2^24 would equal the integer 2^24 + 1 converted to float32
    assert float(ulp_distance(np.array([one]), far.astype(np.float64))[0]) == 2**24 + 1
    assert float(ulp_distance(far, np.array([1.0]))[0]) == 2**24 + 1


def test_a_word_wider_than_the_format_in_any_component_fails_its_row():
    n = 3
    meta = {"compare": ["q"], "outputs": {"q": {"dtype": "uint16"}}, "dtype": "float32", "metric": "exact",
            "exact": True, "inputs": ["x"], "input_order": ["x"]}
    codes = np.array([[1, 0xFFFF], [2, 3], [4, 5]], np.uint16)
    arrays = {"q": codes, "result": np.asarray(["valid"] * n), "tc_id": np.arange(1, n + 1), "x": np.zeros(n),
              "category": np.asarray(["random"] * n), "flags": np.asarray([""] * n), "comment": np.asarray([""] * n)}
    words = codes.astype(np.uint32)
    words[0, 1] = 0x1FFFF  # clips to the expected 0xFFFF; the other component is right
    v = compare_case("pack-test", meta, arrays, {"q": words})
    assert v.row_pass.tolist() == [False, True, True]
    assert v.notes == ["1 rows hold a word wider than the format's uint16 codes (failed)"]


def test_the_rows_shown_tell_ties_and_their_acceptable_codes_apart_from_failures():
    n = 3
    meta = {"compare": ["q"], "outputs": {"q": {"dtype": "uint16"}}, "dtype": "float32", "metric": "exact",
            "exact": True, "inputs": ["x"], "input_order": ["x"]}
    arrays = {"q": np.array([5, 5, 5], np.uint16), "q_acceptable": np.array([[5, 6], [5, 6], [5, 6]], np.uint16),
              "result": np.asarray(["acceptable", "valid", "valid"]), "tc_id": np.arange(1, n + 1),
              "x": np.zeros(n), "category": np.asarray(["random", "stiff", "stiff"]),
              "flags": np.asarray(["rounding_tie", "", ""]), "comment": np.asarray([""] * n)}
    v = compare_case("pack-test", meta, arrays, {"q": np.array([6, 6, 5], np.uint32)})
    assert v.row_pass.tolist() == [True, False, True]
    rows = {r["index"]: r for r in v.worst}
    assert set(rows) == {0, 1}  # the tie (row 0, accepted) and the failure (row 1); row 2 is exact
    assert rows[0]["tie"] and rows[0]["acceptable"].tolist() == [5, 6]
    assert not rows[1]["tie"] and "acceptable" not in rows[1]  # a valid row has no acceptable set
    r, st = v.categories["random"], v.categories["stiff"]
    assert (r.mismatches, r.ties, st.mismatches, st.ties, st.failures) == (1, 1, 1, 0, 1)


def test_the_rows_shown_give_the_largest_component_errors_of_a_vector_output():
    meta = {**_entry(), "exact": False}
    arrays = _golden(np.array([[0.0, 0.1, 2.0], [0.5, 0.5, 0.5]]), 1e-4)
    got = np.array([[0.0, 0.1, 2.0 + 2**-10], [0.5, 0.5, 0.5]], F32)
    (row,) = compare_case("v-test", meta, arrays, {"y": got}).worst
    assert row["index"] == 0 and row["abs"] == 2**-10 and row["rel"] == 2**-11  # not the exact component's 0
    assert row["ulps"] == 2**12  # float32 values are 2^-22 apart above 2
    # the expected value as stored (float64), not rounded to the port's float32
    (row,) = _float_case([0.1], [1e-12], [0.1], ["random"]).worst
    assert row["abs"] == abs(float(F32(0.1)) - 0.1) > 0 and not row["passed"]


def test_vector_codes_count_the_mismatches_of_failing_rows_per_component():
    n = 3
    meta = {"compare": ["q"], "outputs": {"q": {"dtype": "uint16"}}, "dtype": "float32", "metric": "exact",
            "exact": True, "inputs": ["x"], "input_order": ["x"]}
    codes = np.array([[1, 2], [3, 4], [5, 6]], np.uint16)
    alts = np.stack([codes, codes + np.array([0, 1], np.uint16)], axis=1)  # (n, K, 2): component 1 may be +1
    arrays = {"q": codes, "q_acceptable": alts, "result": np.asarray(["acceptable", "valid", "valid"]),
              "tc_id": np.arange(1, n + 1), "x": np.zeros(n), "category": np.asarray(["random"] * n),
              "flags": np.asarray([""] * n), "comment": np.asarray([""] * n)}
    got = np.array([[1, 3], [9, 4], [6, 7]], np.uint32)  # row 0: an accepted tie in component 1
    v = compare_case("pack-test", meta, arrays, {"q": got})
    assert v.row_pass.tolist() == [True, False, False]
    assert v.components == {"mismatch": [2, 1]}  # failing rows only: row 1 in component 0, row 2 in both
    tie = [r for r in v.worst if r["index"] == 0]
    assert len(tie) == 1 and tie[0]["tie"] and v.categories["random"].ties == 1


def test_vector_ulps_beyond_a_million_are_shown_in_three_digits():
    meta = {**_entry(), "exact": False}
    arrays = _golden(np.ones((1, 3)), 1.0)
    bits = np.array([[0x3F800000 + 999_999, 0x3F800000 + 1_000_000, 0x3F800000 + 1_500_000]], np.uint32)
    v = compare_case("v-test", meta, arrays, {"y": bits.view(F32)})
    assert v.components == {"ulps": "[999999, 1e+06, 1.5e+06]"}


def test_the_relative_error_shown_is_positive_for_negative_expected_values():
    (row,) = _float_case([-2.0], [1e-6], [-2.0 - 2**-10], ["random"]).worst
    assert row["abs"] == 2**-10 and row["rel"] == 2**-11


def test_a_non_finite_value_shows_an_infinite_error_even_where_it_equals_the_expected_one():
    v = _float_case([np.inf, 1.0], [1e-3, 1e-3], [np.inf, np.nan], ["random", "stiff"])
    assert not v.row_pass.any()
    assert [r["abs"] for r in v.worst] == [np.inf, np.inf]


def test_at_most_three_accepted_ties_are_shown():
    n = 5
    meta = {"compare": ["q"], "outputs": {"q": {"dtype": "uint16"}}, "dtype": "float32", "metric": "exact",
            "exact": True, "inputs": ["x"], "input_order": ["x"]}
    arrays = {"q": np.full(n, 5, np.uint16), "q_acceptable": np.tile(np.array([5, 6], np.uint16), (n, 1)),
              "result": np.asarray(["acceptable"] * n), "tc_id": np.arange(1, n + 1), "x": np.zeros(n),
              "category": np.asarray(["edge"] * n), "flags": np.asarray([""] * n), "comment": np.asarray([""] * n)}
    v = compare_case("pack-test", meta, arrays, {"q": np.full(n, 6, np.uint32)})
    assert v.passed and [r["index"] for r in v.worst] == [0, 1, 2] and all(r["tie"] for r in v.worst)


def test_the_float64_note_needs_a_float_input_to_round():
    meta = {**_entry(dtype="float64"), "exact": False, "inputs": ["k", "x"], "input_order": ["k", "x"]}
    arrays = _golden([0.5], 1e-3)
    arrays["k"] = np.array([3], np.int32)  # an integer input first: uploaded as it is
    v = compare_case("f-test", meta, arrays, {"y": np.array([0.5], F32)})
    assert any("float32 tolerance column" in n for n in v.notes)
    meta = {**meta, "inputs": ["k"], "input_order": ["k"]}
    assert compare_case("f-test", meta, arrays, {"y": np.array([0.5], F32)}).notes == []


def test_rows_shown_per_category_worst_first_each_once():
    category = np.array(["random"] * 5 + ["stiff"] * 5 + ["edge"] * 3)
    score = np.array([0.5, 3.0, 2.0, 9.0, 0.1, 0.2, 0.9, 0.0, 0.4, 0.3, 0.0, 0.0, 0.0])
    row_pass = score <= 1
    # random fails (rows 1, 2, 3): the worst `keep` of them, largest first; stiff passes: its
    # three closest rows; edge passes with all scores 0: nothing to show; extra rows once.
    assert select_worst(category, score, row_pass, 2) == [3, 1, 6, 8, 9]
    assert select_worst(category, score, row_pass, 5, extra=[6, 12]) == [3, 1, 2, 6, 8, 9, 12]
    score[[1, 2, 3]] = 0.7
    assert select_worst(category, score, score <= 1, 2) == [1, 6, 8, 9]  # a passing random shows one row


# ---------------------------------------------------------------------------
# golden.spread: the tolerances hold the legitimate ports they are derived from


def _alternating(case, inputs, eps, sign, free):
    """Every float input component times 1 ± eps, the sign alternating over the components of
    all inputs in order (a port whose loads and first operations each round once), on ``free`` rows."""
    out, k = {}, 0
    for name, v in inputs.items():
        if name in case.integer_inputs:
            out[name] = v
            continue
        v = np.asarray(v, np.float64)
        m = int(np.prod(v.shape[1:], dtype=np.int64))
        s = np.array([sign if (k + j) % 2 == 0 else -sign for j in range(m)], np.float64).reshape(v.shape[1:])
        k += m
        f = 1 + eps * s[None] * free.reshape((-1,) + (1,) * (v.ndim - 1))
        p = v * f
        out[name] = np.where((np.abs(p) > 1) & (np.abs(v) <= 1), v, p)  # inputs in [-1, 1] stay there
    return out


def _joint(case, inputs, eps, sign):
    """Every float input times 1 + sign 3 eps (one rounding direction of a port 3 ulps off)."""
    return {k: v if k in case.integer_inputs else
            np.where((np.abs(v * (1 + 3 * sign * eps)) > 1) & (np.abs(v) <= 1), v, v * (1 + 3 * sign * eps))
            for k, v in ((k, np.asarray(v, np.float64)) for k, v in inputs.items())}


@pytest.mark.parametrize("name", ["shadow_intensity-lower-float32", "phi-float32", "shade-float32"])
@pytest.mark.parametrize("sign", [1, -1])
def test_a_port_with_every_input_one_ulp_off_in_alternating_directions_passes(name, sign):
    from moments_ref.golden.cases import CASES, evaluate_reference
    from moments_ref.golden.spread import STRUCTURED
    from moments_ref.golden.writer import golden_arrays, manifest_entry

    case = CASES[name]
    arrays = golden_arrays(case)
    inputs = {k: arrays[k] for k in case.inputs}
    flags = [str(f).split(",") for f in arrays["flags"]]
    x = np.sort(np.abs(np.concatenate([np.asarray(v, np.float64).reshape(len(flags), -1) for k, v in inputs.items()
                                       if k not in case.integer_inputs], axis=1)), axis=1)
    equal = np.any((np.diff(x, axis=1) == 0) & (x[:, 1:] != 0) & (x[:, 1:] != 1), axis=1)
    free = np.array([not any(f in STRUCTURED for f in fl) for fl in flags]) & ~equal
    assert free.mean() > 0.5
    eps = float(np.finfo(np.float32).eps)
    entry = manifest_entry(case, arrays)
    got = evaluate_reference(case, _alternating(case, inputs, eps, sign, free), np.float32)
    v = compare(entry, arrays, {o: np.asarray(g, np.float32) for o, g in zip(case.outputs, got)})
    assert v.row_pass[free].all(), np.flatnonzero(free & ~v.row_pass)[:5]
    # Every input scaled by 1 ± 3 eps together (the backward error of operations 3 ulps off): every row.
    got = evaluate_reference(case, _joint(case, inputs, eps, sign), np.float32)
    v = compare(entry, arrays, {o: np.asarray(g, np.float32) for o, g in zip(case.outputs, got)})
    assert v.passed, np.flatnonzero(~v.row_pass)[:5]


def test_the_worst_output_of_a_case_decides_the_rows_error_and_tolerance():
    e = {"compare": ["y", "z"], "outputs": {"y": {"dtype": "float32"}, "z": {"dtype": "float32"}},
         "dtype": "float32", "metric": "abs"}
    g = _golden([0.0, 0.0, 0.0], [1e-2, 1e-2, np.inf], result=["valid", "valid", "valid"])
    g.update({"z": np.zeros(3), "z_tolerance_float32": np.array([1e-3, 1e-3, 1e-3]),
              "z_tolerance_float64": np.ones(3)})
    v = compare(e, g, {"y": np.float32([5e-3, 2e-3, 7.0]), "z": np.float32([1e-4, 2e-3, 0.0])})
    assert v.row_pass.tolist() == [True, False, True]
    np.testing.assert_allclose(v.score, [0.5, 2.0, 0.0], rtol=1e-6)
    # row 0: y's error, row 1: z's; row 2 (both scores 0): the first output's, ungated
    np.testing.assert_allclose(v.error, [5e-3, 2e-3, 7.0], rtol=1e-6)
    np.testing.assert_allclose(v.tolerance, [1e-2, 1e-3, np.inf])
    assert v.gated.tolist() == [True, True, False]  # an infinite tolerance on a valid row: not gated


def test_one_dimensional_codes_accept_alternatives_on_acceptable_rows():
    e = {"compare": ["p"], "outputs": {"p": {"dtype": "uint32"}}, "dtype": "float32", "metric": "exact"}
    g = {"p": np.array([5, 5], np.uint32), "p_acceptable": np.array([[5, 6], [5, 6]], np.uint32),
         "result": np.array(["acceptable", "valid"]), "tc_id": np.arange(1, 3)}
    v = compare(e, g, {"p": np.array([6, 6], np.uint32)})
    assert v.row_pass.tolist() == [True, False]


def _float_case(y, tol, got, category, dtype="float32"):
    n = len(y)
    meta = {**_entry(dtype=dtype), "exact": False}
    arrays = _golden(y, tol)
    arrays["category"] = np.asarray(category)
    return compare_case("f-test", meta, arrays, {"y": np.asarray(got, np.float32)})


def test_float_case_summaries_per_category():
    y = [1.0, 1.0, 2.0, 0.5, 0.25]
    got = [1.0, 1.0 + 2 ** -20, 2.0 - 2 ** -10, 0.5, np.nan]
    v = _float_case(y, [1e-3, 1e-3, 1e-4, 1e-3, 1e-3], got, ["random", "random", "stiff", "stiff", "edge"])
    r, s, e = v.categories["random"], v.categories["stiff"], v.categories["edge"]
    assert (r.rows, r.gated, r.failures) == (2, 2, 0) and (s.failures, e.failures) == (1, 1)
    assert r.worst_score == pytest.approx(2 ** -20 / 1e-3, rel=1e-6) and r.worst_error == pytest.approx(2 ** -20)
    assert s.worst_score == pytest.approx(2 ** -10 / 1e-4, rel=1e-6) and s.worst_tolerance == 1e-4
    assert e.worst_score == np.inf
    worst = {w["index"]: w for w in v.worst}
    assert set(worst) == {1, 2, 4}  # random passes: its closest row; stiff and edge: their failures
    assert worst[2]["abs"] == pytest.approx(2 ** -10) and worst[2]["rel"] == pytest.approx(2 ** -11)
    assert worst[2]["ulps"] == 2 ** 13  # float32 spacing below 2 is 2^-23
    assert worst[4]["abs"] == np.inf and worst[4]["ulps"] == np.inf
    assert not v.passed and v.notes == [] and v.components is None


def test_float64_cases_are_judged_by_their_float32_column_with_a_note():
    v = _float_case([0.5], [1e-3], [0.5 + 1e-4], ["random"], dtype="float64")
    assert v.passed and any("float32 tolerance column" in n for n in v.notes)


def test_vector_outputs_report_the_worst_ulps_per_component():
    meta = {**_entry(), "exact": False}
    arrays = _golden(np.ones((3, 4)), 1.0)
    got = np.ones((3, 4), np.float32)
    got[0, 1] = np.nextafter(np.float32(1), np.float32(2))
    got[2, 3] = np.float32(1 + 5 * 2 ** -23)
    v = compare_case("v-test", meta, arrays, {"y": got})
    assert v.components == {"ulps": "[0, 1, 0, 5]"}
    v = _exact_case([1, 2, 3], [1, 9, 3])
    assert v.components is None  # one code per row


# ---------------------------------------------------------------------------
# golden.spread on toy cases whose spread is known by hand


def _toy(reference, x, category, flags=None, metric="abs", dtype="float32", perturb=True, k=None, hook=None, x2=None,
         value_range=None):
    from moments_ref.golden.cases import Case
    from moments_ref.golden.spread import derive

    inputs = {"x": np.asarray(x, dtype)}
    if x2 is not None:
        inputs["x2"] = np.asarray(x2, dtype)
    if k is not None:  # an integer input beside x (a decoder's code)
        inputs["k"] = np.asarray(k, np.uint32)
    case = Case(name="toy", function="toy", dtype=dtype, inputs=tuple(inputs), outputs=("y",), rows=None,
                reference=reference, metric=metric, perturb=perturb,
                integer_inputs={"k": "uint32"} if k is not None else {}, spread_hook=hook, value_range=value_range)
    n = len(x)
    return derive(case, inputs, category, [""] * n, flags or [()] * n)


def _identity(x):
    return (np.asarray(x),)


def _circle(x):  # defined on [-1, 1] only
    with np.errstate(invalid="ignore"):
        return (np.sqrt(1 - np.asarray(x) * x),)


EPS32 = float(np.finfo(np.float32).eps)


def test_tolerances_hold_inputs_scaled_by_three_ulps_in_each_precision():
    # y = x: the legitimate values are x itself and x (1 ± 3 eps) rounded to the port's precision (x = 1 scaled
    # up stays 1); the band is their interval [x - 3 eps|x|, x + 3 eps|x|] (width 6 eps|x|) widened by the margin
    # max(3 × width, 8 ulps of max(|x|, 1)): no safety factor on the deviation. Stored as a symmetric tolerance.
    a = _toy(_identity, [0.0, -2.0, 1.0, 0.5], ["random", "edge", "edge", "edge"])
    t32, t64 = a["y_tolerance_float32"], a["y_tolerance_float64"]
    for x, t, want in zip([-2.0, 1.0, 0.5], t32[1:], [6 + 36, 3 + 9, 1.5 + 9]):
        assert want * EPS32 <= t <= 1.1 * want * EPS32, (x, t / EPS32)
    eps64 = float(np.finfo(np.float64).eps)
    for x, t, want in zip([-2.0, 1.0, 0.5], t64[1:], [6 + 36, 3 + 9, 1.5 + 9]):  # float64 ports: float64 ulps
        assert want * eps64 <= t <= 1.1 * want * eps64, (x, t / eps64)
    assert t32[0] == pytest.approx(9.6e-7, rel=1e-12, abs=0)  # y = 0: the floor, 8 ulps of 1, two digits
    assert (a["result"] == "valid").all() and a["tc_id"].tolist() == [1, 2, 3, 4]
    # a float32 case also stores the reference's own float32 result (informational); a float64 case does not
    assert a["y_float32"].dtype == np.float32 and a["y_float32"].tolist() == [0.0, -2.0, 1.0, 0.5]
    assert "y_float32" not in _toy(_identity, [0.5], ["random"], dtype="float64")


def _third(x):
    return (np.asarray(x) / np.asarray(x).dtype.type(3),)


def _times_code(x, k, dtype):
    return (np.asarray(x, dtype) * np.asarray(k).astype(dtype),)


def test_the_float64_column_is_measured_in_float64():
    # x / 3 rounds in float32 by up to half an ulp; a float64 port is held to float64's rounding
    a = _toy(_third, [0.3, -1.7, 0.9], ["random"] * 3)
    assert (a["y_tolerance_float64"] < 1e-13).all() and (a["y_tolerance_float32"] > 1e-7).all()


def test_unperturbed_cases_and_cases_with_integer_inputs():
    # perturb=False (a bias, whose inputs are exact by definition): only the evaluations in each
    # precision count, exact here, so the tolerance is the floor (8 ulps of max(|y|, 1), two digits)
    a = _toy(_identity, [0.5, -0.25], ["random"] * 2, perturb=False)
    np.testing.assert_allclose(a["y_tolerance_float32"], [9.6e-7, 9.6e-7], rtol=1e-12, atol=0)
    # an integer input beside the float one: the float input is still perturbed (3 eps |y| + 3 × 6 eps |y|)
    a = _toy(_times_code, [0.5, -0.25], ["random"] * 2, k=[2, 3])
    assert (a["y_tolerance_float32"] >= 21 * EPS32 * np.array([1.0, 0.75]) * (1 - 1e-9)).all()


def test_other_formulations_count_on_contract_rows_where_they_have_a_value():
    def hook(inputs, dt):  # another formulation, 1e-3 off; no value beyond 0.9
        x = np.asarray(inputs["x"], np.float64)
        return [(np.where(x > 0.9, np.nan, x + 1e-3),)]

    flags = [(), (), ("robustness",), ("robustness",)]
    # (the case's noise, measured on random rows, is kept small: row 1 only)
    a = _toy(_identity, [0.5, 0.95, 0.5, -2.0], ["edge", "random", "edge", "edge"], flags=flags, hook=hook)
    t = a["y_tolerance_float32"]
    assert 4e-3 <= t[0] <= 4.2e-3  # a contract row: the other formulation counts (interval 1e-3, margin 3e-3)
    assert t[1] < 1e-4  # no value there: it contributes nothing (not an infinite tolerance)
    assert t[2] < 1e-4  # beyond the contract it is no legitimate implementation of anything
    assert t[3] >= 42 * EPS32  # the reference's own variants still count on robustness rows
    assert "robustness" in a["flags"][2]


def _squares(x, x2):
    return (np.asarray(x) * x - np.asarray(x2) * x2,)


def test_rows_with_equal_inputs_are_only_scaled_jointly():
    # x² - x2² is exactly 0 where |x| = |x2|, and stays 0 when both are scaled together; perturbing
    # them apart (1 ± eps) would invent a deviation of 4 eps x² that no port of the equation has
    a = _toy(_squares, [0.5, 0.5, 0.5], ["random", "random", "edge"], x2=[0.5, -0.5, 0.25])
    t = a["y_tolerance_float32"]
    np.testing.assert_allclose(t[:2], [9.6e-7, 9.6e-7], rtol=1e-12, atol=0)  # the floor only
    assert t[2] >= 4 * 2 * EPS32 * 0.25 - 1e-12  # unequal inputs: perturbed apart


def test_the_case_floor_is_the_random_rows_typical_deviation():
    # random rows x = -4 deviate by 12 eps (x (1 ± 3 eps) is exact in float32); edge rows x = -0.5 by 1.5 eps.
    # A row that deviates by nothing (y = 0) still gets a margin of 4 x the random rows' 90th percentile, 48 eps.
    x = [-4.0] * 5 + [-0.5] * 5 + [0.0]
    t = _toy(_identity, x, ["random"] * 5 + ["edge"] * 5 + ["stiff"])["y_tolerance_float32"]
    assert 48 * EPS32 <= t[-1] <= 1.1 * 48 * EPS32, t[-1] / EPS32
    # with random rows that deviate little, the floor (8 ulps of 1) applies
    t = _toy(_identity, x[5:], ["random"] * 5 + ["stiff"])["y_tolerance_float32"]
    assert t[-1] == pytest.approx(9.6e-7, rel=1e-12, abs=0)


def test_the_floor_is_eight_ulps_of_the_magnitude():
    t = _toy(_identity, [-4.0, 4.0, 0.5], ["random"] * 3, perturb=False)["y_tolerance_float32"]
    np.testing.assert_allclose(t, [3.9e-6, 3.9e-6, 9.6e-7], rtol=1e-12, atol=0)  # 8 ulp(4) = 32 eps, 8 ulp(1)


def _quarters(x):
    x = np.asarray(x)  # in the dtype of the evaluation
    with np.errstate(invalid="ignore"):
        return (np.nan_to_num(np.floor(4 * np.sqrt(1 - x * x)), nan=99).astype(np.uint16),)  # 99: no code, |x| > 1


def test_codes_that_change_within_rounding_of_the_inputs_are_ties_both_ways():
    from moments_ref.golden.cases import Case
    from moments_ref.golden.spread import derive

    case = Case(name="toy", function="toy", dtype="float64", inputs=("x",), outputs=("q",), rows=None,
                reference=_quarters, metric="exact", integer_inputs={})
    # sqrt(1 - x²) = 3/4 at x = sqrt(7)/4: just below it the code is 3, just above 2
    edge = np.sqrt(7) / 4
    x = np.array([edge * (1 - 4e-7), edge * (1 + 4e-7), 0.3, 1.0, 0.0, -1.0])
    cat, comment = ["random", "random", "random", "edge", "stiff", "edge"], ["a", "b", "c", "d", "e", "f"]
    a = derive(case, {"x": x}, cat, comment, [()] * 6)
    tie = np.array(["rounding_tie" in f for f in a["flags"]])
    # the nudge 1 ± 8 eps(float32) moves the first row up across the boundary, the second down
    assert tie.tolist() == [True, True, False, False, False, False]  # x = ±1: nudged outward it stays, no tie
    assert a["result"].tolist() == ["acceptable", "acceptable", "valid", "valid", "valid", "valid"]
    assert a["category"].tolist() == ["stiff", "stiff", "random", "edge", "stiff", "edge"]
    assert a["comment"][0].startswith("a [on a rounding boundary") and a["comment"][4] == "e"
    assert {2, 3} <= set(a["q_acceptable"][0].tolist()) and {2, 3} <= set(a["q_acceptable"][1].tolist())
    assert set(a["q_acceptable"][2].tolist()) == {a["q"][2]}


def test_rows_outside_the_given_contract_are_flagged_robustness_once():
    from moments_ref.golden.cases import Case
    from moments_ref.golden.spread import derive

    case = Case(name="toy", function="toy", dtype="float32", inputs=("x",), outputs=("y",), rows=None,
                reference=_identity)
    flags = [(), (), ("robustness",)]
    a = derive(case, {"x": np.float32([0.1, 0.2, 0.3])}, ["random"] * 3, [""] * 3, flags,
               contract=np.array([True, False, False]))
    assert a["flags"].tolist() == ["", "robustness", "robustness"]


def test_robust_rows_are_read_from_the_flags_and_none_without_them():
    from moments_ref.golden.spread import robust_rows

    assert robust_rows({"result": np.array(["valid"] * 3)}).tolist() == [False] * 3
    assert robust_rows({"result": np.array(["valid"] * 2)}, 2).tolist() == [False] * 2
    flags = np.array(["robustness", "wide_spread,robustness", "robustness_x", ""])
    assert robust_rows({"flags": flags, "result": np.array(["valid"] * 4)}).tolist() == [True, True, False, False]


def test_a_tie_away_from_a_rounding_boundary_is_a_bug_of_the_reference():
    from moments_ref.golden.cases import Case
    from moments_ref.golden.spread import TIE_BAND, TruthMismatch, derive

    edge = np.sqrt(7) / 4
    x = np.array([edge * (1 - 4e-7), edge * (1 + 4e-7), 0.3])

    def case(margins):
        return Case(name="toy", function="toy", dtype="float64", inputs=("x",), outputs=("q",), rows=None,
                    reference=_quarters, truth=_quarters, metric="exact", margin=lambda x: np.asarray(margins))

    a = derive(case([TIE_BAND, TIE_BAND, 0.5]), {"x": x}, ["random"] * 3, [""] * 3, [()] * 3)  # within the band
    assert a["result"].tolist() == ["acceptable", "acceptable", "valid"]
    with pytest.raises(TruthMismatch, match="on 1 rows away from a rounding boundary; first row 1"):
        derive(case([0.0, 2 * TIE_BAND, 0.5]), {"x": x}, ["random"] * 3, [""] * 3, [()] * 3)
    with pytest.raises(TruthMismatch, match="first row 0"):  # the margin is compared in float64
        derive(case([TIE_BAND * (1 + 1e-12), 0.0, 0.5]), {"x": x}, ["random"] * 3, [""] * 3, [()] * 3)


def _split_row_0(x):
    y = np.array(x, copy=True)
    if y.dtype == np.float32:
        y[0] += y.dtype.type(0.05)  # float32 and float64 disagree by 0.05 on row 0: ill-conditioned there
    return (y,)


def test_ill_conditioned_rows_and_printed_hazards_of_a_bounded_output():
    from moments_ref.golden.bands import CAP
    from moments_ref.golden.notes import UNGATED

    def hook(inputs, dt):  # another formulation 0.1 off on row 2: beyond the cap, it widens nothing
        x = np.asarray(inputs["x"], np.float64)
        return [(x + np.array([0.0, 0.0, 0.1, 0.001]),)]

    flags = [(), (UNGATED[0],), (), ()]
    a = _toy(_split_row_0, [0.5] * 4, ["edge", "edge", "random", "random"], flags=flags, hook=hook, value_range=(0, 1))
    assert a["flags"].tolist() == ["wide_spread", UNGATED[0], "printed_hazard", ""]
    t = a["y_tolerance_float32"]
    assert t[0] >= 0.05  # the whole interval of legitimate values: a correct port never fails it
    assert t[2] < 1e-5 and 0.004 <= t[3] <= CAP  # the hazard widens nothing; a formulation within the cap does
    a = _toy(_split_row_0, [0.5] * 4, ["edge", "edge", "random", "random"], flags=flags, hook=hook)
    assert a["flags"].tolist() == ["", UNGATED[0], "", ""]  # an unbounded output has no cap


def test_the_gated_summary_counts_rows_per_precision_and_level():
    from moments_ref.golden.cases import Case
    from moments_ref.golden.notes import UNGATED, UNGATED32
    from moments_ref.golden.spread import gated_summary

    def hook(inputs, dt):  # 0.05 off on row 2 (tolerance 0.05 + 3 x 0.05 in both columns)
        return [(np.asarray(inputs["x"], np.float64) + np.array([0.0, 0.0, 0.05, 0.0]),)]

    flags = [(), (UNGATED[0],), (), ("robustness", UNGATED32[0])]
    a = _toy(_identity, [0.5] * 4, ["random", "edge", "edge", "edge"], flags=flags, hook=hook)
    case = Case(name="toy", function="toy", dtype="float32", inputs=("x",), outputs=("y",), rows=None,
                reference=_identity)
    s = gated_summary(case, a)
    assert s["rows"] == 4
    f32, f64 = s["float32"], s["float64"]
    assert (f32["gated"], f32["gated_below_0.1"], f64["gated"], f64["gated_below_0.1"]) == (2, 1, 3, 2)
    assert f32["levels"] == {"contract": {"rows": 3, "gated": 2, "ungated": {UNGATED[0]: 1}},
                             "robustness": {"rows": 1, "gated": 0, "ungated": {UNGATED32[0]: 1}}}
    assert f64["levels"] == {"contract": {"rows": 3, "gated": 2, "ungated": {UNGATED[0]: 1}},
                             "robustness": {"rows": 1, "gated": 1, "ungated": {}}}
    t = a["y_tolerance_float32"]
    assert f32["median_tolerance"] == pytest.approx((t[0] + t[2]) / 2, rel=1e-12, abs=0)


def _no_float32_value_on_row_0(x):
    y = np.array(x, copy=True)
    if y.dtype == np.float32:
        y[0] = np.nan
    return (y,)


def test_a_legitimate_evaluation_without_a_value_leaves_the_row_ungated_in_its_precision():
    a = _toy(_no_float32_value_on_row_0, [0.5, 0.25], ["random"] * 2)
    assert a["y_tolerance_float32"][0] == np.inf and np.isfinite(a["y_tolerance_float32"][1])
    assert np.isfinite(a["y_tolerance_float64"]).all()
    # the only random row has no finite deviation: no case floor from it (the other row keeps its own)
    a = _toy(_no_float32_value_on_row_0, [0.5, 0.25], ["random", "edge"])
    assert a["y_tolerance_float32"][1] < 1e-5


def test_ulps_tolerances_count_whole_ulps_of_the_ports_precision():
    # y = x at -2: x (1 ± 3 eps) lies exactly 3 float32 ulps (2 eps each) away: interval ±3 ulps, margin 3 x its
    # width of 6 = 18 ulps: 21 ulps; y = 0: the floor, 8
    a = _toy(_identity, [-2.0, 0.0], ["random", "edge"], metric="ulps")
    assert a["y_tolerance_float32"].tolist() == [21.0, 8.0]
    assert a["y_tolerance_float64"].tolist() == [21.0, 8.0]  # the same 3 ulps, of float64


def test_a_rows_tolerance_is_the_largest_over_its_outputs_and_components():
    from types import SimpleNamespace

    from moments_ref.golden.spread import row_tolerance

    arrays = {"category": np.array(["random", "edge"]),
              "y_tolerance_float32": np.array([[0.1, 0.3], [0.2, 0.05]]), "z_tolerance_float32": np.array([0.4, 0.01])}
    assert row_tolerance(SimpleNamespace(outputs=("y", "z")), arrays, "float32").tolist() == [0.4, 0.2]


def test_perturbed_inputs_in_minus_one_to_one_stay_there():
    # sqrt(1 - x²) has no value beyond ±1: x = ±1 scaled up would leave its domain; only x (1 - 3 eps) counts
    a = _toy(_circle, [0.0, 1.0, -1.0], ["random", "edge", "edge"])
    t = a["y_tolerance_float32"]
    assert np.isfinite(t).all()
    dev = np.sqrt(1 - (1 - 3 * EPS32) ** 2)  # the inward perturbation's deviation at the ends
    assert (t[1:] >= 4 * dev * 0.9).all() and (t[1:] <= 4 * dev * 1.2).all()  # the interval and 3 x its width


def test_ungated_flags_give_an_infinite_tolerance_and_an_acceptable_result():
    from moments_ref.golden.notes import UNGATED, UNGATED32

    assert UNGATED and UNGATED32
    flags = [(), ("random_x", UNGATED[0]), ("random_x", UNGATED32[0])]  # one of its flags is enough
    a = _toy(_identity, [0.5, 0.5, 0.5], ["random"] * 3, flags=flags)
    assert a["result"].tolist() == ["valid", "acceptable", "valid"]
    assert np.isfinite(a["y_tolerance_float32"][0]) and a["y_tolerance_float32"][1] == np.inf
    assert a["y_tolerance_float64"][1] == np.inf
    # undefined in float32 only: the float64 column stays gated
    assert a["y_tolerance_float32"][2] == np.inf and np.isfinite(a["y_tolerance_float64"][2])
