"""The speed targets of ``moments-ref bench``: every target is printed with a ratio and a mark.

No timing is asserted (targets are read, not enforced); these tests check that the
measurement interleaves candidate and baseline and takes the median of the pair ratios, that every target is reported, and
that a missing llvmpipe is reported with its reason instead of a number.
"""

from __future__ import annotations

import numpy as np
import pytest

from moments_ref.tools.bench import _llvmpipe, _targets, _timing


def _reporting(times, calls, tag):
    """A callable that reports the given (cpu) times in turn (as the llvmpipe worker does)."""
    it = iter(times)
    return lambda: (calls.append(tag), {"cpu": (c := next(it)), "wall": 2 * c})[1]


def test_paired_interleaves_and_takes_the_median_of_pair_ratios():
    calls = []
    # first value of each: the calibration call; then pairs (1, 1), (5, 20), (10, 30)
    k = _reporting([9.0, 1.0, 20.0, 30.0], calls, "k")
    b = _reporting([9.0, 1.0, 5.0, 10.0], calls, "b")
    r = _timing.paired(k, b, pairs=3, least=0)
    assert calls == ["k", "b"] + ["b", "k"] * 3  # calibration, then baseline right before kernel
    assert r.median == 3.0  # pair ratios 1, 4, 3; the ratio of the medians would say 20 / 5 = 4
    assert (r.low, r.high) == (2.0, 3.5) and r.kernel == 20.0 and r.baseline == 5.0 and r.kernel_wall == 40.0


def test_a_target_is_marked_only_when_its_spread_allows():
    r = _timing.Ratio(1.0, 0.9, 1.1, 1, 1, 1, 1, 9)
    assert r.mark(1.2) == "pass" and r.mark(0.8) == "miss" and r.mark(1.0) == "undecided (noisy)"
    assert r.mark(1.1) == "pass" and r.mark(0.9) == "undecided (noisy)"
    assert abs(r.spread - 0.1) < 1e-12


def test_quick_calls_are_repeated_within_a_sample():
    calls = []
    _timing.paired(lambda: calls.append(1), lambda: None, pairs=3, least=1e-3)
    assert len(calls) > 4  # one calibration call, then more than one call per sample


def test_a_quick_call_timed_by_another_process_is_repeated_and_its_own_times_averaged():
    # The llvmpipe worker reports its own CPU time per draw; a 30 ms draw alone is too short a sample.
    calls = []
    k = _reporting([0.01] + [0.01, 0.03] * 3, calls, "k")  # calibration 0.01 s: 5 calls per 0.05 s sample
    r = _timing.paired(k, lambda: {"cpu": 0.1, "wall": 0.3}, pairs=1, least=0.05)
    assert calls == ["k"] * 6
    assert abs(r.kernel - 0.018) < 1e-12 and abs(r.kernel_wall - 0.036) < 1e-12  # the mean of the 5 reported
    assert r.baseline == 0.1 and r.baseline_wall == 0.3 and abs(r.median - 0.18) < 1e-12


def test_agreement_table_flags_runs_that_differ():
    row = lambda t, x: {"target": t, "ratio": x, "limit": 2.2}  # noqa: E731
    runs = [[row("a", 1.0), row("b", 2.0), row("c", None)], [row("a", 1.1), row("b", 2.5), row("c", None)]]
    text = _targets.agreement_markdown(runs)
    assert "| a | 1.00× | 1.10× | 1.100 | yes | 2 of 2 |" in text
    assert "| b | 2.00× | 2.50× | 1.250 | NO | 1 of 2 |" in text and "not measured" in text
    # A ratio equal to the limit is not under it.
    runs = [[row("d", 2.2)], [row("d", 2.1)], [row("d", 2.3)]]
    assert "| 1 of 3 |" in _targets.agreement_markdown(runs)


def test_every_target_has_a_ratio_and_a_mark(monkeypatch):
    def unavailable():
        raise _llvmpipe.LlvmpipeUnavailable("moderngl is not importable (test)")

    monkeypatch.setattr(_llvmpipe, "Llvmpipe", unavailable)
    rows = _targets.run_targets(quick=True)
    names = [r["target"] for r in rows]
    for want in ("vs llvmpipe", "NLQ64 global path vs copy", "NLQ32 global path vs copy", "NLQ64 on-chip vs global",
                 "NLQ32 on-chip vs global", "shadow_intensity float32 vs copy", "shade float32 vs copy",
                 "six moments float32 vs copy", "six moments float32 peak memory", "linear growth: rasterizer",
                 "pipeline peak memory per shadow-map texel"):
        assert any(want in n for n in names), want
    text = _targets.targets_markdown(rows)
    raster = [r for r in rows if "llvmpipe" in r["target"]]
    assert raster and all(r["ratio"] is None and "moderngl is not importable (test)" in r["detail"] for r in raster)
    assert "not measured" in text
    for r in rows:
        if r["ratio"] is not None:
            assert np.isfinite(r["ratio"]) and 0 < r["low"] <= r["ratio"] <= r["high"]
            assert r["mark"] == ("pass" if r["high"] <= r["limit"] else "miss" if r["low"] > r["limit"]
                                 else "undecided (noisy)")
            assert r["passed"] == {"pass": True, "miss": False}.get(r["mark"])
            assert f"| {r['mark']} |" in text


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


def test_end_to_end_times_the_documented_fused_paths_beside_the_passes(monkeypatch):
    from moments_ref.gpu import filtering
    from moments_ref.tools import bench

    rows = bench.end_to_end(size=32, samples=4)
    paths = {r["path"] for r in rows}
    assert paths == {"global", "onchip", "fused", "fused from moments"}
    totals = [r["path"] for r in rows if r["stage"] == "total"]
    assert sorted(totals) == ["global", "onchip"]  # one-stage paths need no total row
    # A fused path that changed a bit would make the speed comparison meaningless: refused.
    monkeypatch.setattr(filtering, "quantize_nlq", lambda m, fmt: filtering.nlq_texels(m, fmt) ^ 1)
    with pytest.raises(RuntimeError, match="quantize_nlq"):
        bench.end_to_end(size=32, samples=4)


def test_a_new_bench_md_keeps_the_hand_kept_history(tmp_path):
    from moments_ref.tools import bench

    path = tmp_path / "bench.md"
    assert bench.keep_history("# new\n\n| t |\n", path) == "# new\n\n| t |\n"  # no old file
    path.write_text("# old\n\n| old table |\n\n## Kernel history\n\nkept by hand\n", encoding="utf-8")
    assert bench.keep_history("# new\n\n| t |\n", path) == "# new\n\n| t |\n\n## Kernel history\n\nkept by hand\n"
    path.write_text("# old without a history\n", encoding="utf-8")
    assert bench.keep_history("# new\n", path) == "# new\n"


def test_a_floor_probe_does_the_kernels_data_movement():
    # The probe's output is the last pass's product (or zf without passes), chunk by chunk:
    # the transposing copy and the chunking really ran over every row.
    from moments_ref.tools.bench._probes import pass_probe

    rng = np.random.default_rng(0)
    b = rng.uniform(-1, 1, (1000, 4)).astype(np.float32)
    zf = rng.uniform(-1, 1, 1000).astype(np.float32)
    assert np.array_equal(pass_probe(b, zf, 0, 64)(), zf)
    assert np.array_equal(pass_probe(b, zf, 6, 64)(), b[:, 1] * b[:, 2])  # pass 5 multiplies columns 1 and 2


def test_a_floor_probe_with_in_place_passes_counts_them_as_the_kernel_does():
    # Round seven: of the kernels' passes only THIRD_ROW write a third row; the probe's others
    # add a column in place. Its output is the last product plus one column per in-place pass,
    # in order, and never fewer than one product (the adds start from finite values).
    from moments_ref.tools.bench._probes import PASSES, THIRD_ROW, pass_probe

    rng = np.random.default_rng(1)
    b = rng.uniform(-1, 1, (1000, 4)).astype(np.float32)
    zf = rng.uniform(-1, 1, 1000).astype(np.float32)
    want = b[:, 1] * b[:, 2]
    for j in range(5):
        want = want + b[:, j % 4]
    assert np.array_equal(pass_probe(b, zf, 7, 64, 2)(), want)
    assert np.array_equal(pass_probe(b, zf, 2, 64, 0)(), b[:, 0] * b[:, 1] + b[:, 0])
    assert set(THIRD_ROW) <= set(PASSES) and all(0 < THIRD_ROW[k] <= PASSES[k] for k in THIRD_ROW)


def test_the_scatter_min_floor_probe_is_the_rasterizers_depth_test():
    # The probe scatters exactly the covered samples with their depths: its map is the rasterizer's.
    from moments_ref.scene.raster import rasterize_depth, small_triangles
    from moments_ref.tools.bench._probes import scatter_probe

    v, t = small_triangles(300, 64, 12.0, np.random.default_rng(2))
    probe, covered = scatter_probe(v, t, np.eye(4), 64, 4)
    want, stats = rasterize_depth(v, t, np.eye(4), 64, samples=4)
    assert covered == stats.samples_covered > 0
    np.testing.assert_array_equal(probe().reshape(64, 64, 4), want)


def test_target_groups_pick_their_rows_only(monkeypatch):
    # each group is measured by its own function: stub them, and --only targets-GROUP must call exactly that one
    calls = []
    for fn in ("_raster_rows", "_nlq_rows", "_kernel_rows", "_growth_rows", "_memory_row"):
        monkeypatch.setattr(_targets, fn, lambda *a, _fn=fn: calls.append(_fn) or ({} if _fn == "_memory_row" else []))
    expected = {"raster": "_raster_rows", "nlq": "_nlq_rows", "algorithms": "_kernel_rows",
                "growth": "_growth_rows", "memory": "_memory_row"}
    assert set(expected) == set(_targets.TARGET_GROUPS)
    for group, fn in expected.items():
        calls.clear()
        _targets.run_targets(quick=True, groups=(group,))
        assert calls == [fn], group
    calls.clear()
    _targets.run_targets(quick=True)
    assert sorted(calls) == sorted(expected.values())
    with pytest.raises(ValueError, match="no target group 'kernel'"):
        _targets.run_targets(quick=True, groups=("kernel",))


def test_bench_only_names_a_target_group_or_exits_2(capsys):
    from moments_ref.cli import main

    assert main(["bench", "--only", "targets-nothing"]) == 2
    err = capsys.readouterr().err
    assert "targets-raster" in err and len(err.strip().splitlines()) == 1


class _Counting:
    """A stand-in for a kernel module's ``np``: counts the ufunc calls and reductions over chunk-long rows."""

    def __init__(self, m):
        self.m, self.calls, self.reductions, self.third = m, {}, 0, 0

    def __getattr__(self, name):
        f = getattr(np, name)
        return self._ufunc(f) if isinstance(f, np.ufunc) else f

    def _ufunc(self, f):
        outer = self

        class Counted:
            def __call__(self, *args, **kw):
                rows = []  # the distinct chunk-long rows read
                for a in args[:f.nin]:
                    new = not any(np.shares_memory(a, r) for r in rows) if isinstance(a, np.ndarray) else False
                    if new and a.size == outer.m:
                        rows.append(a)
                out = kw.get("out", args[f.nin] if len(args) > f.nin else None)
                out = out[0] if isinstance(out, tuple) else out
                if isinstance(out, np.ndarray) and out.size == outer.m:
                    outer.calls[f.__name__] = outer.calls.get(f.__name__, 0) + 1
                    # a third row: two rows read and a row written that is neither of them
                    outer.third += len(rows) == 2 and not any(np.shares_memory(out, r) for r in rows)
                return f(*args, **kw)

            def reduce(self, a, *args, **kw):
                if isinstance(a, np.ndarray) and a.size % outer.m == 0 and a.size:
                    outer.reductions += a.size // outer.m  # one per chunk-long row
                return f.reduce(a, *args, **kw)

        return Counted()


@pytest.mark.parametrize("name", ["shadow_intensity float32", "shadow_intensity float64", "shade float32"])
def test_the_pass_probes_count_the_kernels_ufuncs_and_reductions(name, monkeypatch):
    # The floor probe of a kernel runs the ufuncs, reductions and third-row writes that the kernel's
    # common path calls per chunk: counted here on two full chunks of the bench's input, with every
    # `np.<ufunc>` of the kernel's module replaced by a counter. A kernel changed without its probe fails.
    from moments_ref import msm, nonlinear
    from moments_ref.tools.bench._probes import PASSES, REDUCTIONS, THIRD_ROW, UFUNCS

    module = msm if name.startswith("shadow") else nonlinear
    m = _targets._CHUNKS[name]
    key = name.replace("float64", "float32")  # the bench casts float32's input (_kernel_rows)
    fn, args, _ = _targets.kernel_inputs(2 * m)[key]
    args = tuple(a.astype(name.split()[-1]) for a in args)
    want = fn(*args)
    counter = _Counting(m)
    monkeypatch.setattr(module, "np", counter)
    assert np.array_equal(fn(*args), want)
    monkeypatch.undo()
    assert {k: v / 2 for k, v in counter.calls.items()} == UFUNCS[key]
    assert sum(UFUNCS[key].values()) == PASSES[key]
    assert counter.reductions / 2 == REDUCTIONS[name]
    assert counter.third / 2 == THIRD_ROW[key]


def test_a_floor_probe_with_the_kernels_ufuncs_calls_them():
    # With ufuncs given, the probe's passes are those ufuncs: the binary ones into the third row
    # first (here a division of columns 0 and 1, then a subtraction of columns 1 and 2), then in
    # place against the ones row (× and ÷ keep the value) or a column (+, −, min, max), sqrt last.
    from moments_ref.tools.bench._probes import pass_probe

    rng = np.random.default_rng(2)
    b = rng.uniform(0.5, 1, (1000, 4)).astype(np.float32)
    zf = rng.uniform(-1, 1, 1000).astype(np.float32)
    probe = pass_probe(b, zf, 6, 64, 2, ufuncs={"divide": 1, "sqrt": 1, "subtract": 1, "multiply": 2, "add": 1},
                       reductions=3)
    # third row: divide(c0, c1), subtract(c1, c2); in place (counting from 0 again): multiply(t, 1),
    # multiply(t, 1), add(t, c2), sqrt(t)
    np.testing.assert_array_equal(probe(), np.sqrt((b[:, 1] - b[:, 2]) + b[:, 2]))
    with pytest.raises(ValueError, match="ufuncs"):
        pass_probe(b, zf, 5, 64, 2, ufuncs={"add": 1})


def test_the_six_moment_probe_counts_the_kernels_third_row_passes(monkeypatch):
    # The six-moment kernel's passes over single chunk-long rows that read two rows and write a
    # third: THIRD_ROW (its block calls over several rows and its boolean ones are in place or
    # narrower, and the probe's other passes work in place).
    from moments_ref import _msm6_bound, _msm6_rows
    from moments_ref.tools.bench._probes import THIRD_ROW

    name = "shadow_intensity six moments float32"
    m = _targets._CHUNKS[name]
    fn, args, _ = _targets.kernel_inputs(2 * m)[name]
    want = fn(*args)
    counter = _Counting(m)
    monkeypatch.setattr(_msm6_bound, "np", counter)
    monkeypatch.setattr(_msm6_rows, "np", counter)
    assert np.array_equal(fn(*args), want)
    monkeypatch.undo()
    assert counter.third / 2 == THIRD_ROW[name]
