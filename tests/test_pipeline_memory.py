"""Issue 41, memory: values released after their last use, banded steps that change no value."""

import weakref

import numpy as np
import pytest

from moments_ref import pipeline
from moments_ref.gpu import filtering
from moments_ref.pipeline.graph import StageGraph
from moments_ref.report import paper_claims
from moments_ref.scene import load_scene
from moments_ref.techniques import Stage
from moments_ref.techniques import _steps

SMALL = dict(shadow_map_size=48, resolution=(40, 24), msaa=4)


def test_keep_releases_values_and_changes_no_result():
    sc = load_scene("railing")
    full = pipeline.run(sc, None, pipeline.Settings(**SMALL))
    keep = paper_claims.stages_read(4)
    lean = pipeline.run(sc, None, pipeline.Settings(**SMALL, keep=keep))
    for n in full.techniques:
        assert np.array_equal(full.shadow[n], lean.shadow[n]), n
        assert np.array_equal(full.reference[n], lean.reference[n]), n
    assert sorted(full.stages) == sorted(lean.stages)  # the same stages, each once
    targets = {k for t in lean.plans.values() for k in (t.shade, t.reference) if k}
    assert set(lean.values) == targets | set(keep) | {"light_projection"}
    for k in keep:
        assert np.array_equal(full.values[k], lean.values[k]), k
    assert set(full.values) == set(full.stages)  # keep=None (default): every value


def test_release_follows_the_last_use():
    g = StageGraph()
    for name, deps in (("a", ()), ("b", ("a",)), ("c", ("b",)), ("d", ("a", "c"))):
        g.add(Stage(name, lambda *args, name=name: name, deps))
    order, values, _ = g.run(["d"], keep=())
    assert order == ["a", "b", "c", "d"] and set(values) == {"d"}
    order, values, _ = g.run(["d"], keep=("b",))
    assert set(values) == {"b", "d"}


class _Texture:
    """A stage's value that can be watched (weakref) for being freed."""


@pytest.mark.parametrize("keep", [(), None])
def test_a_timed_run_replaces_the_previous_value_when_values_are_released(keep):
    # keep given (the report): each timed repeat's value replaces the previous run's, which is freed
    # before the run (no second texture beside the first at the peak); keep=None: as before, the
    # warm-up's value stays and the repeats' values are dropped
    refs, alive_at_run = [], []

    def make():
        alive_at_run.append([r() is not None for r in refs])  # the earlier runs' values still held
        value = _Texture()
        refs.append(weakref.ref(value))
        return value

    g = StageGraph()
    g.add(Stage("t", make, ()))
    _, values, times = g.run(["t"], timed=("t",), repeats=3, keep=keep)
    assert len(refs) == 4 and len(times["t"]) == 3
    if keep is None:
        assert alive_at_run[1:] == [[True], [True, False], [True, False, False]]
        assert values["t"] is refs[0]()
    else:
        assert alive_at_run[1:] == [[False], [False, False], [False, False, False]]
        assert values["t"] is refs[-1]()


@pytest.mark.parametrize("shape", [(37, 50, 2), (5, 9, 4), (1, 1, 4), (70, 13, 4)])
def test_blur_bands_change_no_value(shape, monkeypatch):
    m = np.random.default_rng(3).standard_normal(shape).astype(np.float32)
    whole = filtering.blur(m)
    w = filtering.gaussian_weights()
    # independent: clamp-to-edge padding and the separable sum, float64
    p = np.pad(m.astype(np.float64), ((4, 4), (4, 4), (0, 0)), mode="edge")
    hp = sum(w[t] * p[:, t : t + shape[1]] for t in range(9))
    ref = sum(w[t] * hp[t : t + shape[0]] for t in range(9))
    np.testing.assert_allclose(whole, ref, rtol=1e-12, atol=1e-12)
    for band in (1, 3000):
        monkeypatch.setattr(filtering, "_BLUR_BAND_BYTES", band)
        assert filtering.blur(m).tobytes() == whole.tobytes()


def test_row_bands_change_no_value(monkeypatch):
    x = np.random.default_rng(4).uniform(-1, 1, (33, 17, 4))
    fn = lambda b: np.exp(3 * b).astype(np.float32)[..., :2] * 2  # noqa: E731
    whole = fn(x)
    for band in (1, 700, 1 << 30):
        monkeypatch.setattr(_steps, "ROW_BAND_BYTES", band)
        got = _steps.in_row_bands(fn, x)
        assert got.dtype == whole.dtype and got.tobytes() == whole.tobytes()


@pytest.mark.slow
def test_memory_probe_runs():
    from moments_ref.tools.bench._memory import pipeline_peak_bytes

    per, peak, base = pipeline_peak_bytes("railing", 256, 4, resolution=(40, 24), baseline_size=64)
    assert peak >= base > 0 and np.isfinite(per)


@pytest.mark.slow
def test_memory_probe_measures_the_child_not_its_parent():
    # ru_maxrss survives fork and exec: a child started by a process that once held 600 MiB reported 600 MiB
    # at every map size, so the bench's per-texel figure read "no larger than the baseline"
    from moments_ref.tools.bench._memory import _child_peak

    held = np.ones(600 * 2**20 // 8)  # touched: resident in this (the parent) process
    child = _child_peak("railing", 64, 4, (40, 24))
    assert held.sum() > 0
    assert child < 400 * 2**20, child / 2**20
