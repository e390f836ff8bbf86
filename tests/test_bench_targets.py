"""The speed targets of ``moments-ref bench``: every target is printed with a ratio and a mark.

No timing is asserted (targets are read, not enforced); these tests check that the
measurement alternates candidate and baseline, that every target is reported, and
that a missing llvmpipe is reported with its reason instead of a number.
"""

from __future__ import annotations

import numpy as np
import pytest

from moments_ref.tools.bench import _llvmpipe, _targets


def test_measure_alternates_and_takes_medians():
    calls = []
    times = iter([{"cpu": c, "wall": 2 * c} for c in (9.0, 5.0, 1.0, 3.0)])  # the first is the warm-up
    got = _targets.measure([lambda: calls.append("a"), lambda: (calls.append("b"), next(times))[1]], repeat=3,
                           least=0)
    assert calls == ["a", "b"] * 4
    assert got[1] == (3.0, 6.0)  # the median of the reported times, not the last one


def test_measure_repeats_quick_calls_within_a_sample():
    calls = []
    _targets.measure([lambda: calls.append(1)], repeat=3, least=1e-3)
    assert len(calls) > 4  # one warm-up, then more than one call per sample


def test_every_target_has_a_ratio_and_a_mark(monkeypatch):
    def unavailable():
        raise _llvmpipe.LlvmpipeUnavailable("moderngl is not importable (test)")

    monkeypatch.setattr(_llvmpipe, "Llvmpipe", unavailable)
    rows = _targets.run_targets(quick=True)
    names = [r["target"] for r in rows]
    for want in ("vs llvmpipe", "NLQ64 global path vs copy", "NLQ32 global path vs copy", "NLQ64 on-chip vs global",
                 "NLQ32 on-chip vs global", "shadow_intensity float32 vs copy", "shade float32 vs copy",
                 "six moments float32 vs copy", "six moments float32 peak memory", "linear growth: rasterizer"):
        assert any(want in n for n in names), want
    text = _targets.targets_markdown(rows)
    raster = [r for r in rows if "llvmpipe" in r["target"]]
    assert raster and all(r["ratio"] is None and "moderngl is not importable (test)" in r["detail"] for r in raster)
    assert "not measured" in text
    for r in rows:
        if r["ratio"] is not None:
            assert np.isfinite(r["ratio"]) and r["ratio"] > 0
            assert (r["ratio"] <= r["limit"]) == r["passed"]
            assert ("pass" if r["passed"] else "MISS") in text


def test_llvmpipe_worker_draws_the_same_scene():
    pytest.importorskip("moderngl")
    try:
        lp = _llvmpipe.Llvmpipe()
    except _llvmpipe.LlvmpipeUnavailable as exc:
        pytest.skip(str(exc))
    with lp:
        assert "llvmpipe" in lp.renderer
        lp.case("small-4096-1x")
        t = lp.time()
    assert t["cpu"] > 0 and t["wall"] > 0
