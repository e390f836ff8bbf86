"""golden.diagnosis: failing rows grouped by level and flags, the lines printed, the JSON rows.

On a hand-made verdict of a few rows (row_pass, strict_pass, robust given), each expected group
is written out from the module's rule: failing rows, and robustness rows that fail only under
--strict, grouped by (level, flags without ``robustness``, else the category); rows an extra
group explains are taken out; target, then format/convention, contract, robustness, larger first.
"""

from __future__ import annotations

import json
from types import SimpleNamespace

import numpy as np

from moments_ref.golden.diagnosis import Group, _narrowed, group_lines, groups, json_rows, write_json
from moments_ref.golden.notes import CAUSES


def _verdict(row_pass, strict_pass=None, robust=None, **kw):
    return SimpleNamespace(row_pass=np.array(row_pass, bool),
                           strict_pass=None if strict_pass is None else np.array(strict_pass, bool),
                           robust=None if robust is None else np.array(robust, bool), **kw)


ARRAYS = {
    "flags": np.array(["shadow_edge", "shadow_edge", "", "robustness,outside_moment_space", "", "cluster,robustness",
                       "shadow_edge"]),
    "category": np.array(["random", "random", "edge", "stiff", "random", "stiff", "random"]),
}


def test_failing_rows_are_grouped_by_level_and_flags_larger_groups_first():
    v = _verdict([True, False, False, True, False, False, False],
                 strict_pass=[True, False, False, False, False, False, False],
                 robust=[False, False, False, True, False, True, False])
    gs = groups(v, ARRAYS)
    got = [(g.level, g.flags, g.rows) for g in gs]
    # contract: shadow_edge {1, 6} (two rows first), the edge row 2 and the random row 4 by category;
    # robustness: row 3 fails only when strict, row 5 fails (robust): flags without "robustness"
    assert got[0] == ("contract", "shadow_edge", [1, 6])
    assert sorted(got[1:3]) == [("contract", "edge", [2]), ("contract", "random", [4])]
    assert sorted(got[3:]) == [("robustness", "cluster", [5]), ("robustness", "outside_moment_space", [3])]
    assert gs[0].cause == CAUSES["shadow_edge"] and gs[0].count == 2
    by = {g.flags: g for g in gs}
    assert by["edge"].cause == "inputs at the ends of their ranges"
    assert by["random"].cause == "ordinary inputs: an arithmetic or algorithmic error"


def test_rows_passing_in_both_modes_are_in_no_group_and_without_strict_only_failures_count():
    v = _verdict([True, False, True, True, True, True, True])
    gs = groups(v, ARRAYS)
    assert [(g.level, g.rows) for g in gs] == [("contract", [1])]
    # without robust marks every failing row is a contract row
    v = _verdict([True, True, True, False, True, True, True], strict_pass=[True] * 7)
    assert [(g.level, g.flags, g.rows) for g in groups(v, ARRAYS)] == [("contract", "outside_moment_space", [3])]


def test_rows_of_an_extra_group_are_taken_out_and_the_extra_group_leads():
    v = _verdict([True, False, False, True, False, True, False], robust=[False] * 7)
    extra = [Group("target", "bias target [0, 1, 0, 1]", [1, 2], "singular"),
             Group("format", "format.x = 1", [4], "a choice")]
    gs = groups(v, ARRAYS, extra)
    assert [(g.level, g.rows) for g in gs] == [("target", [1, 2]), ("format", [4]), ("contract", [6])]


def test_group_lines_count_failures_and_name_robustness_rows_apart_unless_strict():
    gs = [Group("contract", "shadow_edge", [1, 6], "edge of a shadow"),
          Group("robustness", "cluster", [5], "a cluster")]
    lines = group_lines(gs, 3)
    assert lines == ["2 of 3 failures: shadow_edge (contract): edge of a shadow",
                     "1 beyond the algorithm's contract would fail with --strict: cluster: a cluster"]
    assert group_lines(gs, 3, strict=True)[1] == "1 of 3 failures: cluster (robustness): a cluster"


def _full_verdict():
    row_pass = np.array([True, False, True])
    return SimpleNamespace(
        row_pass=row_pass, strict_pass=np.array([True, False, False]), robust=np.array([False, False, True]),
        level=np.array(["contract", "contract", "robustness"]), error=np.array([0.0, np.inf, 2.5]),
        tolerance=np.array([1e-3, 1e-3, np.nan]), passed=False, strict=False, failures=1,
        robustness_tally=lambda: {"rows": 1, "would_fail": 1})


def test_json_rows_give_every_row_in_plain_values():
    arrays = {"tc_id": np.array([7, 8, 9], np.int32), "category": np.array(["random", "edge", "stiff"]),
              "flags": np.array(["", "shadow_edge", "robustness"]), "comment": np.array(["a", "b", "c"]),
              "x": np.array([0.5, np.nan, -np.inf]), "k": np.array([[1, 2], [3, 4], [5, 6]], np.uint16),
              "y": np.array([0.25, 0.5, 0.75]), "whole": np.array([1.0, 2.0])}
    meta = {"compare": ["y"], "input_order": ["x", "k", "whole"]}
    got = {"y": np.array([0.25, np.nan, 1.0], np.float32)}
    gs = [Group("contract", "shadow_edge", [1], "edge")]
    doc = json_rows("toy", meta, arrays, got, _full_verdict(), gs)
    json.dumps(doc, allow_nan=False)  # plain JSON: NaN and infinities are null
    assert (doc["case"], doc["passed"], doc["strict"], doc["failures"]) == ("toy", False, False, 1)
    assert doc["robustness"] == {"rows": 1, "would_fail": 1}
    assert doc["groups"] == [{"level": "contract", "flags": "shadow_edge", "rows": 1, "cause": "edge"}]
    r = doc["rows"]
    assert [x["tc_id"] for x in r] == [7, 8, 9] and [x["passed"] for x in r] == [True, False, True]
    assert [x["passed_strict"] for x in r] == [True, False, False]
    assert [x["level"] for x in r] == ["contract", "contract", "robustness"]
    assert [x["cause"] for x in r] == ["", "contract", ""]
    assert [x["error"] for x in r] == [0.0, None, 2.5] and [x["tolerance"] for x in r] == [1e-3, 1e-3, None]
    assert [x["got"] for x in r] == [0.25, None, 1.0] and [x["expected"] for x in r] == [0.25, 0.5, 0.75]
    # per-row inputs only (not the whole-case array), floats with null for non-finite, integer codes as lists
    assert [x["inputs"] for x in r] == [{"x": 0.5, "k": [1, 2]}, {"x": None, "k": [3, 4]}, {"x": None, "k": [5, 6]}]
    assert [x["category"] for x in r] == ["random", "edge", "stiff"] and r[1]["flags"] == "shadow_edge"
    assert [x["comment"] for x in r] == ["a", "b", "c"]
    # without a strict verdict, no strict result
    v = _full_verdict()
    v.strict_pass = None
    assert [x["passed_strict"] for x in json_rows("toy", meta, arrays, got, v)["rows"]] == [None] * 3


def test_json_values_of_vector_and_string_entries():
    arrays = {"tc_id": np.array([1]), "category": np.array(["random"]), "flags": np.array([""]),
              "comment": np.array([""]), "v": np.array([[0.5, np.inf]]), "s": np.array([["a", "b"]]),
              "y": np.array([[1.0, 2.0]])}
    v = SimpleNamespace(row_pass=np.array([True]), strict_pass=None, robust=None, level=np.array(["contract"]),
                        error=np.array([[0.0, 1.0]]), tolerance=np.array([[1.0, 1.0]]), passed=True, strict=False,
                        failures=0, robustness_tally=lambda: {})
    doc = json_rows("toy", {"compare": ["y"], "input_order": ["v", "s"]}, arrays, {"y": np.array([[1.0, 2.0]])}, v)
    row = doc["rows"][0]
    assert row["inputs"] == {"v": [0.5, None], "s": ["a", "b"]} and row["expected"] == [1.0, 2.0]
    assert row["error"] == [0.0, 1.0]


def test_write_json_writes_the_cases_and_the_extra_keys(tmp_path):
    out = tmp_path / "v.json"
    write_json(out, [{"case": "a"}], {"port": "p"})
    text = out.read_text()
    assert json.loads(text) == {"port": "p", "cases": [{"case": "a"}]} and text.endswith("}\n")
    write_json(out, [])
    assert json.loads(out.read_text()) == {"cases": []}


def test_readback_words_are_narrowed_to_the_codes_dtype_only_where_they_fit():
    arrays = {"q": np.zeros(2, np.uint16)}
    fits = _narrowed({"q": np.array([0, 65535], np.uint32)}, arrays)["q"]
    assert fits.dtype == np.uint16 and fits.tolist() == [0, 65535]
    wide = _narrowed({"q": np.array([0, 65536], np.uint32)}, arrays)["q"]
    assert wide.dtype == np.uint32 and wide.tolist() == [0, 65536]
    neg = _narrowed({"q": np.array([-1, 3], np.int32)}, arrays)["q"]
    assert neg.dtype == np.int32
    # floats, and outputs the goldens do not hold, stay as they are
    assert _narrowed({"q": np.array([1.0])}, arrays)["q"].dtype == np.float64
    assert _narrowed({"z": np.array([1], np.uint32)}, arrays)["z"].dtype == np.uint32


def test_levels_are_ordered_target_format_or_convention_contract_robustness_whatever_their_size():
    n = 13
    arrays = {"flags": np.array(["shadow_edge"] * n), "category": np.array(["random"] * n)}
    v = _verdict([False] * n, robust=[False] * 7 + [True] * 6)
    extra = [Group("target", "t", [0], ""), Group("format", "f", [1, 2], ""), Group("convention", "c", [3], "")]
    gs = groups(v, arrays, extra)
    assert [(g.level, g.count) for g in gs] == [("target", 1), ("format", 2), ("convention", 1), ("contract", 3),
                                                ("robustness", 6)]


def test_json_rows_judge_the_first_compared_output_and_give_string_inputs_as_strings():
    arrays = {"tc_id": np.array([1]), "category": np.array(["random"]), "flags": np.array([""]),
              "comment": np.array([""]), "t": np.array(["p"]), "y": np.array([1.0]), "z": np.array([5.0])}
    v = SimpleNamespace(row_pass=np.array([True]), strict_pass=None, robust=None, level=np.array(["contract"]),
                        error=np.array([0.0]), tolerance=np.array([1.0]), passed=True, strict=False,
                        failures=0, robustness_tally=lambda: {})
    doc = json_rows("toy", {"compare": ["y", "z"], "input_order": ["t"]}, arrays,
                    {"y": np.array([1.0]), "z": np.array([9.0])}, v)
    assert doc["rows"][0]["got"] == 1.0 and doc["rows"][0]["expected"] == 1.0
    assert doc["rows"][0]["inputs"] == {"t": "p"}


def test_write_json_refuses_a_non_finite_value_and_writes_nothing(tmp_path):
    import pytest

    out = tmp_path / "v.json"
    with pytest.raises(ValueError):
        write_json(out, [{"x": float("nan")}])
    assert not out.exists()
