"""The decisive answer (report/_winners.py) against a plain search over the rows, and the scaling to the scene's size."""

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from moments_ref.report import _winners as W
from moments_ref.report._pareto import pareto_mask

_NAMES = ("a", "b", "c", "d", "e", "f")


@st.composite
def _rows(draw):
    n = draw(st.integers(1, 6))
    rmse = st.one_of(st.sampled_from([0.01, 0.02, 0.02, float("nan")]), st.floats(0, 1))
    rows = []
    for i in range(n):
        rows.append({"scene": draw(st.sampled_from(["s", "t"])), "technique": _NAMES[i],
                     "bits_per_texel": draw(st.sampled_from([16, 32, 64, 128, 256, 768])),
                     "rmse": draw(rmse), "own_total_seconds": draw(st.sampled_from([0.1, 0.2, 0.2, math.inf]) |
                                                                   st.floats(0, 5))})
    return rows


def _ok(r):
    return math.isfinite(r["rmse"]) and math.isfinite(r["own_total_seconds"])


@given(_rows())
def test_memory_winners_are_the_lowest_rmse_within_each_budget(rows):
    found = W.winners(rows, lambda r: "pcf")
    for scene in {r["scene"] for r in rows}:
        for budget in W.MEMORY_BUDGETS:
            fit = [r for r in rows if r["scene"] == scene and _ok(r) and r["bits_per_texel"] <= budget]
            got = [w for w in found if w["scene"] == scene and w["budget_kind"] == "bits_per_texel"
                   and w["budget"] == budget]
            if not fit:
                assert got == []
                continue
            best = min(fit, key=lambda r: (r["rmse"], r["bits_per_texel"], r["technique"]))  # ties: fewer bits
            assert [(w["technique"], w["rmse"]) for w in got] == [(best["technique"], best["rmse"])]


@given(_rows())
def test_time_budgets_are_the_steps_of_the_cost_rmse_front(rows):
    found = W.winners(rows, lambda r: "pcf")
    for scene in {r["scene"] for r in rows}:
        rs = [r for r in rows if r["scene"] == scene and _ok(r)]
        steps = [w for w in found if w["scene"] == scene and w["budget_kind"] == "total_seconds"]
        for w in steps:  # at its budget the winner has the lowest RMSE affordable; just below, something worse
            fit = [r for r in rs if r["own_total_seconds"] <= w["budget"]]
            assert w["rmse"] == min(r["rmse"] for r in fit)
            cheaper = [r["rmse"] for r in rs if r["own_total_seconds"] < w["budget"]]
            assert not cheaper or min(cheaper) > w["rmse"]
        # every budget: the lowest RMSE affordable is the last step at or below it
        for b in sorted({r["own_total_seconds"] for r in rs}):
            last = [w for w in steps if w["budget"] <= b][-1]
            assert last["rmse"] == min(r["rmse"] for r in rs if r["own_total_seconds"] <= b)
        if rs:  # the steps are the (cost, RMSE) Pareto front, up to exact ties
            pts = np.array([[r["own_total_seconds"], r["rmse"]] for r in rs])
            front = {tuple(p) for p in pts[pareto_mask(pts)]}
            assert {(w["budget"], w["rmse"]) for w in steps} == front


def test_ties_go_to_the_cheaper_and_nan_takes_no_part():
    rows = [{"scene": "s", "technique": "x", "bits_per_texel": 64, "rmse": 0.01, "own_total_seconds": 1.0},
            {"scene": "s", "technique": "y", "bits_per_texel": 32, "rmse": 0.01, "own_total_seconds": 0.5},
            {"scene": "s", "technique": "z", "bits_per_texel": 16, "rmse": float("nan"), "own_total_seconds": 0.1}]
    found = W.winners(rows, lambda r: "pcf")
    assert {(w["budget_kind"], w["budget"], w["technique"]) for w in found} == {
        ("bits_per_texel", 32, "y"), ("bits_per_texel", 64, "y"), ("bits_per_texel", 128, "y"),
        ("total_seconds", 0.5, "y")}
    text = "\n".join(W.winner_lines(found, {"s": "64×64 map, 32×18 camera"}))
    assert "32, 64 and 128 bits: **y**" in text and "within 0.5 s: **y**" in text
    assert W.winners_csv(found).splitlines()[0] == ",".join(W.WINNER_COLUMNS)


def test_costs_scale_to_the_scenes_own_size():
    cfg = {"size": (1024, 1024), "resolution": (480, 270), "own": ((2048, 2048), 4, (1920, 1080))}
    assert W.own_scale(cfg) == (4.0, 16.0)
    row = {"texel_seconds": 0.5, "fragment_seconds": 0.25, "texel_seconds_max": 1.0, "fragment_seconds_max": 0.5}
    assert W.own_total(row, W.own_scale(cfg)) == pytest.approx(4 * 0.5 + 16 * 0.25)
    assert W.own_total(row, W.own_scale(cfg), "_max") == pytest.approx(4 + 8)
    same = {"size": (64, 64), "resolution": (32, 18), "own": ((64, 64), 1, (32, 18))}
    assert W.own_scale(same) == (1.0, 1.0)


def test_the_sentence_names_each_memory_budget_once_merging_consecutive_equal_winners():
    rows = [{"scene": "s", "technique": "a", "bits_per_texel": 32, "rmse": 0.05, "own_total_seconds": 0.1},
            {"scene": "s", "technique": "b", "bits_per_texel": 64, "rmse": 0.01, "own_total_seconds": 2.0}]
    text = "\n".join(W.winner_lines(W.winners(rows, lambda r: "pcf"), {"s": "own"}))
    assert ("Lowest RMSE at 32 bits: **a** (RMSE 0.05); 64 and 128 bits: **b** (RMSE 0.01). At the scene's own "
            "resolution (own), within 0.1 s: **a** (RMSE 0.05); within 2 s: **b** (RMSE 0.01).") in text
    # Nothing within 128 bits: said so, not left blank.
    lines = W.winner_lines([{"scene": "s", "reference": "pcf", "budget_kind": "total_seconds", "budget": 3.0,
                             "technique": "a", "rmse": 0.5}], {})
    assert ("- **s** (reference `pcf`). No technique fits in 128 bits per texel. At the scene's own "
            "resolution (?), within 3 s: **a** (RMSE 0.5).") in lines
    assert lines[-1] == ""
    # Nothing within the smallest budgets: named after the winners of the larger ones.
    rows = [{"scene": "s", "technique": "b", "bits_per_texel": 128, "rmse": 0.01, "own_total_seconds": 2.0}]
    text = "\n".join(W.winner_lines(W.winners(rows, lambda r: "pcf"), {"s": "own"}))
    assert "Lowest RMSE at 128 bits: **b** (RMSE 0.01) (nothing fits in 32 and 64 bits). At the scene's own" in text
