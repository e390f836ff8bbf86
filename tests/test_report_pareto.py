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



# ---------------------------------------------------------------------------
# the front beyond the timing spread


def _brute_spread(rows):
    """The rule of report._pareto typed out row by row: (rmse, [(median, min, max), (median, min, max)])."""
    def finite(r):
        return np.isfinite(r[0]) and all(np.isfinite(v) for c in r[1] for v in c)

    def beats(a, b):  # a dominates b
        if not (finite(a) and finite(b)) or a[0] > b[0]:
            return False
        no_worse = all(ca[2] <= cb[1] or ca == cb for ca, cb in zip(a[1], b[1]))
        better = a[0] < b[0] or any(ca[2] < cb[1] for ca, cb in zip(a[1], b[1]))
        return no_worse and better

    return [finite(r) and not any(beats(q, r) for j, q in enumerate(rows) if j != i) for i, r in enumerate(rows)]


def _arrays(rows):
    p = [[r[0]] + [c[0] for c in r[1]] for r in rows]
    lo = [[r[0]] + [c[1] for c in r[1]] for r in rows]
    hi = [[r[0]] + [c[2] for c in r[1]] for r in rows]
    return p, lo, hi


@st.composite
def _timed(draw):
    """A cost (median, min, max), often one of a few shared ones (the same stages charged to two rows)."""
    shared = [(1.0, 0.8, 1.2), (1.0, 0.9, 1.1), (2.0, 1.2, 2.5), (0.5, 0.5, 0.5)]
    if draw(st.booleans()):
        return draw(st.sampled_from(shared))
    a, b, c = sorted(draw(st.lists(st.sampled_from([0.1, 0.5, 0.8, 1.0, 1.1, 1.2, 2.0, 2.5]), min_size=3,
                                   max_size=3)))
    return (b, a, c)


_spread_row = st.tuples(st.one_of(st.sampled_from([0.0, 0.03, 0.05]), st.just(float("nan"))),
                        st.tuples(_timed(), _timed()))


@given(st.lists(_spread_row, min_size=1, max_size=9))
def test_front_beyond_the_spread_equals_brute_force(rows):
    mask = list(report.pareto_mask(*_arrays(rows)))
    assert mask == _brute_spread(rows)
    naive = report.pareto_mask(_arrays(rows)[0])
    assert all(m or not n for m, n in zip(mask, naive))  # it holds the front of the medians
    if any(np.isfinite(r[0]) for r in rows):
        assert any(mask)  # a strict partial order has minimal elements


def test_front_without_spread_is_the_front_of_the_medians():
    pts = [(0.0, 0.0, 1.2), (0.04, 0.7, 0.05), (0.05, 1.1, 0.07), (0.04, 0.7, 0.05), (0.1, 0.1, 0.1)]
    assert list(report.pareto_mask(pts, pts, pts)) == list(report.pareto_mask(pts)) == _brute(pts)


def _timed_row(tech, e, t, f):
    """A row with costs (median, min, max)."""
    return {"scene": "a", "technique": tech, "rmse": e, "texel_seconds": t[0], "texel_seconds_min": t[1],
            "texel_seconds_max": t[2], "fragment_seconds": f[0], "fragment_seconds_min": f[1],
            "fragment_seconds_max": f[2]}


def test_timing_noise_keeps_a_technique_on_the_front():
    """Hand-made rows on which the front of the medians and the front beyond the spread differ."""
    frag = (0.10, 0.09, 0.11)  # the same fragment stage timed once, charged to msm64 and nlq64 alike
    rows = [_timed_row("msm64", 0.05, (1.00, 0.80, 1.20), frag),
            # slower than msm64 in the median only, within the spread; same RMSE: a tie
            _timed_row("nlq64", 0.05, (1.05, 0.85, 1.30), frag),
            # slower than msm64 beyond the spread in both costs, worse RMSE: beaten
            _timed_row("nlq32", 0.06, (2.00, 1.90, 2.10), (0.20, 0.19, 0.21)),
            # the same costs as msm64 (same stages), worse RMSE: beaten although nothing is beyond the spread
            _timed_row("vsm", 0.09, (1.00, 0.80, 1.20), frag),
            # lower RMSE: on the front whatever its cost
            _timed_row("msm128", 0.04, (3.00, 2.90, 3.10), (0.30, 0.29, 0.31))]
    medians = [[r[k] for k in _pareto.KEYS] for r in rows]
    assert list(report.pareto_mask(medians)) == [True, False, False, False, True]
    report.mark_pareto(rows)
    assert [r["pareto"] for r in rows] == [True, True, False, False, True]
    md = "\n".join(_pareto.front_lines(rows))
    assert ("| **nlq64** | yes | 0.05 | 1.05 (0.85–1.3) | 0.1 (0.09–0.11) | on the medians only (within the "
            "spread): msm64 (RMSE 0.05 vs 0.05, texel 1.05 (0.85–1.3) vs 1 (0.8–1.2), fragment 0.1 (0.09–0.11) "
            "vs 0.1 (0.09–0.11)) |") in md
    assert "| **msm64** | yes | 0.05 | 1 (0.8–1.2) | 0.1 (0.09–0.11) | |" in md
    assert ("| nlq32 | no | 0.06 | 2 (1.9–2.1) | 0.2 (0.19–0.21) | msm64 (RMSE 0.06 vs 0.05, texel 2 (1.9–2.1) "
            "vs 1 (0.8–1.2), fragment 0.2 (0.19–0.21) vs 0.1 (0.09–0.11)) |") in md
    assert "| vsm | no | 0.09 |" in md and "`_max`" in md
    # One more repeat that separates nlq64 from msm64 beyond the spread takes it off the front.
    rows[1].update(texel_seconds_min=1.25, texel_seconds=1.28)
    assert [r["pareto"] for r in report.mark_pareto(rows)] == [True, False, False, False, True]


def test_a_spread_not_around_its_median_is_refused():
    with pytest.raises(report.InputError, match=r"low <= points <= high.*index \(1, 1\)"):
        report.pareto_mask([[0, 1], [0, 1]], [[0, 1], [0, 1.5]], [[0, 1], [0, 2]])


def test_a_cost_whose_slowest_repeat_equals_anothers_fastest_is_no_slower_but_not_faster():
    frag = (0.10, 0.09, 0.11)  # the same stage charged to both: equal
    a = _timed_row("msm64", 0.05, (1.00, 0.90, 1.10), frag)
    b = _timed_row("nlq64", 0.05, (1.50, 1.10, 1.80), frag)  # its fastest repeat is a's slowest
    # Same RMSE: a is no slower, but better in nothing beyond the spread: both stay.
    assert [r["pareto"] for r in report.mark_pareto([a, b])] == [True, True]
    # A lower RMSE makes a better in one coordinate: b is beaten.
    a["rmse"] = 0.04
    assert [r["pareto"] for r in report.mark_pareto([a, b])] == [True, False]
    # b's fastest repeat just below a's slowest: no longer beaten beyond the spread.
    b["texel_seconds_min"] = 1.09
    assert [r["pareto"] for r in report.mark_pareto([a, b])] == [True, True]
    # Strictly faster beyond the spread with equal RMSE: beaten.
    a["rmse"], b["texel_seconds_min"] = 0.05, 1.11
    assert [r["pareto"] for r in report.mark_pareto([a, b])] == [True, False]


@pytest.mark.parametrize("bad", [float("nan"), float("inf")])
@pytest.mark.parametrize("key", ["rmse", "texel_seconds_max", "fragment_seconds"])
def test_a_row_with_a_nan_or_infinite_coordinate_is_off_the_front_and_beats_nothing(bad, key):
    frag = (0.10, 0.09, 0.11)
    rows = [_timed_row("msm64", 0.06, (2.0, 1.9, 2.1), frag), _timed_row("nlq64", 0.05, (1.0, 0.9, 1.1), frag)]
    assert _pareto.dominates(*_pareto._spread(rows)).tolist() == [[False, False], [True, False]]  # finite: beaten
    rows[0][key] = bad
    if key == "fragment_seconds":
        rows[0]["fragment_seconds_max"] = bad  # a spread around a non-finite median
    d = _pareto.dominates(*_pareto._spread(rows))
    assert not d.any()  # neither dominated nor dominating
    assert [r["pareto"] for r in report.mark_pareto(rows)] == [False, True]
    if key == "rmse":  # the table prints the RMSE as it is
        assert f"| msm64 | no | {bad} |" in "\n".join(_pareto.front_lines(rows))


def test_an_empty_group_has_an_empty_front():
    assert report.pareto_mask([]).shape == (0,) and report.pareto_mask([]).dtype == bool
    assert report.mark_pareto([]) == []


def test_a_beaten_row_names_the_front_row_of_least_rmse_then_least_total_cost():
    rows = [_row("a", "msm64", 0.02, 0.6, 0.1), _row("a", "nlq64", 0.02, 0.3, 0.5),  # both on the front
            _row("a", "nlq32", 0.03, 0.7, 0.6), _row("a", "vsm", 0.01, 5.0, 5.0)]
    report.mark_pareto(rows)
    assert [r["pareto"] for r in rows] == [True, True, False, True]
    md = "\n".join(_pareto.front_lines(rows))
    # msm64 and nlq64 both beat nlq32 with the same RMSE: the cheaper in texel + fragment (0.7 < 0.8) is named
    assert "| nlq32 | no | 0.03 | 0.7 | 0.6 | msm64 (RMSE 0.03 vs 0.02, texel 0.7 vs 0.6, fragment 0.6 vs 0.1) |" in md


def test_the_summary_has_one_table_per_reference_and_bolds_the_finite_best():
    rows = [_row("a", "msm64", float("nan"), 0.1, 0.1), _row("a", "pcf", 0.02, 0.5, 0.5),
            _row("a", "nlq32", 0.03, 0.2, 0.2), _row("a", "mvr", 0.0, 9.0, 9.0), _row("b", "nlq32", 0.5, 5.0, 5.0)]
    md = "\n".join(_pareto.summary_lines(rows))
    hard, soft = md.split(f"**{techniques.get_reference('mvr').label}**")
    assert "| mvr |" in soft and "| mvr |" not in hard
    assert all(f"| {t} |" in hard and f"| {t} |" not in soft for t in ("msm64", "pcf", "nlq32"))
    assert "| msm64 | nan | **0.2** | — | — |" in hard  # a NaN RMSE is never the best
    assert "| pcf | **0.02** | 1 | — | — |" in hard
    assert "| nlq32 | 0.03 | 0.4 | **0.5** | **10** |" in hard
