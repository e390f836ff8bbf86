"""Depth maps in reused memory (moments_ref.scene.raster._maps): new values every call, never shared with a live map.

The invariants: a map is ``np.full(n, 1)`` whatever memory it reuses; a map, or any view of
it, that the caller still holds is never handed out again (its values never change under the
caller); the maps of :func:`rasterize_depth` do not depend on the reuse. A mutant without the
``memoryview`` between the kept buffer and the map (a plain view, whose views reference the
buffer directly) fails the lifetime tests.
"""

from __future__ import annotations

import gc

import numpy as np
import pytest

from moments_ref.scene.raster import _maps, rasterize_depth
from moments_ref.scene.raster._maps import MIN_KEPT_BYTES, cleared_map

N = MIN_KEPT_BYTES // 4 + 124  # float32 elements: just above the smallest kept map (a multiple of 4)


def _address(a):
    return a.__array_interface__["data"][0]


@pytest.fixture(autouse=True)
def _empty_pool():
    _maps._FREE.clear()
    yield
    _maps._FREE.clear()


@pytest.mark.parametrize("n, dtype", [(N, np.float32), (N // 2, np.float64), (1000, np.float32), (0, np.float64)])
def test_cleared_map_is_np_full(n, dtype):
    first = cleared_map(n, dtype)
    first[::7] = -0.5  # dirty the memory, then drop it
    del first
    gc.collect()
    m = cleared_map(n, dtype)
    assert m.dtype == np.dtype(dtype) and m.shape == (n,) and m.flags.writeable and m.flags.c_contiguous
    assert m.tobytes() == np.full(n, 1.0, dtype).tobytes()


def test_dropped_map_memory_is_reused_and_cleared():
    m = cleared_map(N, np.float32)
    where = _address(m)
    m[:] = -1.0
    del m
    gc.collect()
    again = cleared_map(N, np.float32)
    assert _address(again) == where  # the dropped map's memory
    assert np.all(again == 1.0)
    other = cleared_map(N + 1, np.float32)  # another size: fresh memory
    assert _address(other) != where


@pytest.mark.parametrize("view", [
    lambda m: m.reshape(-1, 4)[:, 1],
    lambda m: m.reshape(-1, 4)[:, 1][::3].reshape(-1, 1),  # a view of a view of a view
    lambda m: m[10:],
    lambda m: np.frombuffer(memoryview(m), m.dtype),  # through the buffer protocol
])
def test_a_held_view_keeps_the_map_out_of_reuse(view):
    m = cleared_map(N, np.float32)
    m[:] = np.arange(N, dtype=np.float32)
    v = view(m)
    expect = v.copy()
    del m
    gc.collect()
    other = cleared_map(N, np.float32)
    assert not np.shares_memory(other, v)
    other[:] = -7.0
    np.testing.assert_array_equal(v, expect)
    del v, other
    gc.collect()
    assert cleared_map(N, np.float32).tobytes() == np.ones(N, np.float32).tobytes()


def test_plain_view_mutant_fails(monkeypatch):
    """Without the memoryview a view of the map references the kept buffer itself: its values get overwritten."""
    def mutant(n, dtype, value=1.0):
        dt = np.dtype(dtype)
        key = (n, dt.str)
        raw = _maps._FREE.pop(key, None)
        raw = np.empty(n, dt) if raw is None else raw
        raw.fill(value)
        out = raw[:]
        _maps.weakref.finalize(out, _maps._release, key, raw).atexit = False
        return out

    monkeypatch.setattr(_maps, "cleared_map", mutant)
    m = _maps.cleared_map(N, np.float32)
    m[:] = 3.0
    v = m[5:]
    del m
    gc.collect()
    other = _maps.cleared_map(N, np.float32)
    assert np.shares_memory(other, v)  # the bug the memoryview prevents


def test_rasterize_depth_maps_do_not_depend_on_reuse():
    """Two scenes drawn alternately, each map kept or dropped: every map equals the first one of its scene."""
    rng = np.random.default_rng(3)
    scenes = []
    for _ in range(2):
        v = rng.uniform(-1, 1, (60, 3))
        t = rng.integers(0, 60, (20, 3))
        scenes.append((v, t))
    size, S = 1024, 4  # 16 MiB float32: above MIN_KEPT_BYTES
    first = [rasterize_depth(v, t, np.eye(4), size, samples=S)[0].copy() for v, t in scenes]
    kept = []
    for i in range(6):
        v, t = scenes[i % 2]
        d, _ = rasterize_depth(v, t, np.eye(4), size, samples=S)
        assert d.tobytes() == first[i % 2].tobytes()
        if i % 3 == 0:
            kept.append((i % 2, d))  # held: the next calls must not touch it
        del d
        gc.collect()
    for k, d in kept:
        assert d.tobytes() == first[k].tobytes()


def test_maps_outside_the_kept_sizes_are_not_kept():
    for n in (MIN_KEPT_BYTES // 4 - 4, _maps.MAX_KEPT_BYTES // 8 + 8):  # float32 below, float64 above
        dt = np.float32 if n < MIN_KEPT_BYTES else np.float64
        m = cleared_map(n, dt)
        assert np.all(m[:: max(1, n // 1000)] == 1.0)
        del m
        gc.collect()
        assert not _maps._FREE
