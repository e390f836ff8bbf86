"""What a sweep prints (sweep/result.py): the summary lines and a failure as a row a porter reads, from a result
built here by hand, so that every number in the text is one the test chose."""

from __future__ import annotations

from moments_ref.sweep import STRATA
from moments_ref.sweep.result import SweepResult, describe
from moments_ref.sweep.runner import STAGES


def _failure(**extra):
    return dict({"texel": {"depths": [0.125, -0.5], "weights": [0.75, 0.25], "zf": 0.3, "format": 2},
                 "inputs": {"b": [0.1, 0.2, 0.3, 0.4], "zf": 0.3}, "stratum": "two/near", "driver": "gl",
                 "got": {"intensity": 0.9}, "lo": {"intensity": 0.25}, "hi": {"intensity": 0.75}}, **extra)


def _result():
    strata = {s: {"rows": 0, "ill_conditioned": 0, "ungated": 0} for s in STRATA}
    strata["two/near"] = {"rows": 1000, "ill_conditioned": 3, "ungated": 2}
    per = {s: {"flagged": 0, "confirmed": 0, "unconfirmed": 0} for s in STRATA}
    per["two/near"] = {"flagged": 70, "confirmed": 60, "unconfirmed": 4}
    drivers = {"gl": {"flagged": 70, "confirmed": 60, "unconfirmed": 4, "examined": 64, "first_confirmed": 12,
                      "per_stratum": per}}
    seconds = dict.fromkeys(STAGES, 0.0)
    seconds.update(draw=0.5, driver=2.0)
    return SweepResult("shade-float32", 1000, 7, strata, drivers, seconds,
                       [_failure(dispatches=9, row_file="out/failure-0")],
                       [_failure(stratum="one/end"), _failure(stratum="one/uniform"), _failure(stratum="x")], 3.25)


def test_the_summary_counts_what_the_result_holds():
    lines = _result().format().splitlines()
    assert lines[0] == "sweep shade-float32: 1000 rows, seed 7, 3.2 s"
    assert lines[1] == ("  driver gl: 70 flagged, 60 confirmed wrong (mpmath), 4 unconfirmed flags (a defect of the "
                        "tolerance model, not of the port), 6 flagged beyond the confirmation cap; first confirmed "
                        "row 12")
    row = next(l for l in lines if l.startswith("  two/near"))
    assert row.split() == ["two/near", "1000", "3", "2", "60"]
    seconds = next(l for l in lines if l.startswith("  seconds:"))
    assert "draw 0.50 (2e+03 rows/s)" in seconds and "driver 2.00 (500 rows/s)" in seconds and "reference 0" in seconds
    text = "\n".join(lines)
    assert text.count("unconfirmed flag (tolerance model): ") == 2  # the first two examples only
    assert "shrunk in 9 dispatches; rerun: out/failure-0" in text


def test_a_failure_reads_as_its_texel_got_expected_and_tolerance():
    text = describe(_failure(dispatches=3, row_file="f/failure-1", labels={"intensity": "visibility"}))
    lines = text.splitlines()
    assert lines[0] == ("[gl] two/near: 2 depth(s) 0.125 and -0.5, weights 0.75, 0.25, 32-bit non-linear texel, "
                        "zf = 0.3")
    assert lines[1] == "  visibility: got 0.9, expected 0.5, tolerance 0.25"
    assert lines[2] == "  inputs: {'b': [0.1, 0.2, 0.3, 0.4], 'zf': 0.3}"
    assert lines[3] == "  shrunk in 3 dispatches; rerun: f/failure-1"
    engine = describe(_failure(inputs={"b": [0.0] * 4, "zf": 0.1, "support": [0.5], "mass": [1.0]}))
    assert "the distribution's moments" in engine and "dispatches" not in engine


def test_passed_and_confirmed_sum_over_the_drivers():
    res = _result()
    res.drivers["vulkan"] = dict(res.drivers["gl"], confirmed=5)
    assert res.confirmed == 65 and not res.passed
    for d in res.drivers.values():
        d["confirmed"] = 0
    assert res.passed and res.record()["passed"] is True
    rec = res.record()
    assert rec["rows_per_s"]["draw"] == 2000 and rec["rows_per_s"]["reference"] is None and rec["wall_s"] == 3.25
