"""The Pareto front of the report against brute force, and the scene deciding what runs."""

import numpy as np
import pytest
from hypothesis import given, strategies as st

from moments_ref import report, techniques
from moments_ref.report import _pareto
from moments_ref.scene import load_scene


def _brute(points):
    """Row i is on the front iff no row j is ≤ in every coordinate and < in one (NaN rows never)."""
    out = []
    for i, p in enumerate(points):
        if not all(np.isfinite(p)):
            out.append(False)
            continue
        dominated = False
        for j, q in enumerate(points):
            if j != i and all(np.isfinite(q)) and all(a <= b for a, b in zip(q, p)) and any(
                    a < b for a, b in zip(q, p)):
                dominated = True
        out.append(not dominated)
    return out


_value = st.one_of(st.sampled_from([0.0, 0.5, 1.0, 2.0]), st.floats(0, 10, allow_nan=False),
                   st.just(float("nan")))


@given(st.lists(st.tuples(_value, _value, _value), min_size=1, max_size=12))
def test_pareto_mask_equals_brute_force(points):
    assert list(report.pareto_mask(points)) == _brute(points)


def test_pareto_mask_by_hand():
    pts = [(0.0, 0.0, 1.2), (0.04, 0.7, 0.05), (0.05, 1.1, 0.07), (0.04, 0.7, 0.05), (0.1, 0.1, 0.1)]
    # Row 2 is beaten by row 1 everywhere; equal rows 1 and 3 do not beat each other.
    assert list(report.pareto_mask(pts)) == [True, True, False, True, True]


def _row(scene, tech, e, t, f):
    return {"scene": scene, "technique": tech, "rmse": e, "texel_seconds": t, "fragment_seconds": f}


def test_fronts_are_per_scene_and_reference():
    rows = [_row("a", "pcf", 0.0, 0.0, 1.0), _row("a", "msm64", 0.05, 1.0, 0.1), _row("a", "nlq32", 0.06, 1.5, 0.2),
            _row("a", "mvr", 0.0, 9.0, 9.0), _row("b", "nlq32", 0.5, 5.0, 5.0)]
    report.mark_pareto(rows)
    assert [r["pareto"] for r in rows] == [True, True, False, True, True]  # mvr: its own reference
    md = "\n".join(_pareto.front_lines(rows))
    assert "| nlq32 | no | 0.06 | 1.5 | 0.2 | msm64 (RMSE 0.06 vs 0.05, texel 1.5 vs 1, fragment 0.2 vs 0.1) |" in md
    summary = "\n".join(_pareto.summary_lines(rows))
    assert "| pcf | **0** | **1** | — | — |" in summary  # best RMSE and cost of scene a
    assert "| nlq32 | 0.06 | 1.7 | **0.5** | **10** |" in summary


@pytest.mark.parametrize("name", ["railing", "facade", "knot", "scattering"])
def test_the_scene_outputs_decide_what_runs(name):
    sc = load_scene(name)
    assert report._scene_techniques(sc) == list(sc.outputs)
    every = report._scene_techniques(sc, all_techniques=True)
    assert set(sc.outputs) <= set(every) and all(techniques.get(n).refusal(sc) is None for n in every)
    assert report._scene_techniques(sc, ["pcf", "msm64"]) in (["pcf", "msm64"], [])


def test_settings_are_announced_with_the_reduction(capsys):
    sc = load_scene("three-occluders")
    acc = report._Collected(repeats=2)
    report._announce(acc, sc, ["msm64"], ((1024, 1024), 4, (480, 270)), {"pcf": {}}, False)
    err = capsys.readouterr().err
    assert "shadow map 1024×1024 (scene: 2048×2048)" in err and "camera 480×270 (scene: 1920×1080)" in err
    assert "--full" in err and "MSAA 4×," in err
    acc2 = report._Collected()
    report._announce(acc2, sc, ["msm64"], ((2048, 2048), 4, (1920, 1080)), {"pcf": {}}, True)
    assert "the scene's own settings" in capsys.readouterr().err and not acc2.settings[sc.name]["reduced"]
    assert report._scene_settings(sc, True, {"shadow_map_size": None, "msaa": None, "resolution": None}) == (
        (2048, 2048), 4, (1920, 1080))

