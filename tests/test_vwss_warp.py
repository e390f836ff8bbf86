"""VWSS view warping: z-buffering on the uint view of reversed-z depth (§3.2, Listing 2), MVR."""

import numpy as np
import pytest
from hypothesis import given, strategies as st
from hypothesis.extra import numpy as hnp

from moments_ref import InputError
from moments_ref.scene.raster import rasterize_depth
from moments_ref.scene import AreaLight, torus_knot
from moments_ref.techniques.vwss.lights import depth_range, light_views
from moments_ref.techniques.vwss.mvr import mvr
from moments_ref.techniques.vwss.points import generate_points, source_view
from moments_ref.scene.depth import d_view_from_ndc
from moments_ref.tools.bench import bench_entries
from moments_ref.techniques.vwss import warp as warp_mod
from moments_ref.techniques.vwss.warp import project_to_texels, warp, zbuffer_max


def _light():
    return AreaLight(center=(0.0, 4.0, 0.0), normal=(0.0, -1.0, 0.0), width=1.0, height=0.8, up=(0, 0, -1), fov=90)


def _brute_max(idx, z, n):
    out = np.zeros(n, z.dtype)
    for t in range(n):  # brute force over texels (test only)
        sel = z[idx == t]
        if sel.size:
            out[t] = max(float(v) for v in sel)
    return out


# --- zbuffer_max ------------------------------------------------------------------------------

@given(st.integers(1, 40).flatmap(lambda n: st.tuples(
    st.just(n),
    hnp.arrays(np.int64, st.integers(0, 200), elements=st.integers(0, n - 1)),
)), st.sampled_from([np.float32, np.float64]), st.data())
def test_zbuffer_max_equals_brute_force(n_idx, dtype, data):
    n, idx = n_idx
    z = data.draw(hnp.arrays(dtype, idx.shape, elements=st.floats(0, 1e30 if dtype == np.float64 else float(np.float32(1e30)), width=32 if dtype == np.float32 else 64)))
    got = zbuffer_max(idx, z, n)
    assert got.dtype == dtype
    assert np.array_equal(got, _brute_max(idx, z, n))


def test_zbuffer_mutant_min_is_caught():
    # Power: a z-buffer keeping the minimum (forward z on reversed depth) differs from the brute force.
    rng = np.random.default_rng(0)
    idx, z = rng.integers(0, 5, 50), rng.uniform(0.1, 1, 50).astype(np.float32)
    buf = np.full(5, np.inf, np.float32)
    np.minimum.at(buf, idx, z)
    assert not np.array_equal(buf, _brute_max(idx, z, 5))
    assert np.array_equal(zbuffer_max(idx, z, 5), _brute_max(idx, z, 5))


def _nonnegative_float32_samples():
    """Bit patterns across every exponent: 0, denormals, normals, the largest finite, +inf."""
    rng = np.random.default_rng(1)
    exps = np.arange(0, 255, dtype=np.uint32) << 23
    mants = np.concatenate([[0, 1, 2, 0x7FFFFF, 0x400000], rng.integers(0, 1 << 23, 6)]).astype(np.uint32)
    bits = (exps[:, None] | mants[None]).ravel()
    bits = np.concatenate([bits, [0x7F800000]]).astype(np.uint32)  # +inf
    return bits


def test_uint_ordering_equals_float_ordering_for_nonnegative():
    bits = _nonnegative_float32_samples()
    f = bits.view(np.float32)
    assert f[0] == 0 and np.isinf(f).sum() == 1 and np.any((f > 0) & (f < np.finfo(np.float32).tiny))
    order_f = f[:, None] < f[None]
    order_u = bits[:, None] < bits[None]
    assert np.array_equal(order_f, order_u)  # every pair of ~2800 values
    # float64 / uint64 as well
    b64 = (np.arange(0, 2047, dtype=np.uint64) << np.uint64(52)) | np.uint64(12345)
    f64 = b64.view(np.float64)
    assert np.array_equal(f64[:, None] < f64[None], b64[:, None] < b64[None])


def test_uint_ordering_fails_for_negative_mutant():
    # Power: with one negative value the orderings disagree, which is why zbuffer_max refuses it.
    f = np.array([-1.0, 0.5], np.float32)
    assert (f[0] < f[1]) != (f.view(np.uint32)[0] < f.view(np.uint32)[1])


def test_zbuffer_bad_input_and_negative_zero():
    with pytest.raises(InputError, match="non-negative"):
        zbuffer_max([0, 1], np.float32([0.5, -0.25]), 2)
    with pytest.raises(InputError, match="NaN"):
        zbuffer_max([0], np.float32([np.nan]), 2)
    with pytest.raises(InputError, match="texel_index"):
        zbuffer_max([2], np.float32([0.5]), 2)
    with pytest.raises(InputError):
        zbuffer_max([0, 1], np.float32([0.5]), 2)
    # -0.0 is folded into +0.0 (its bit pattern would beat every positive float)
    out = zbuffer_max([0, 0], np.float32([-0.0, 1e-45]), 1)
    assert out[0] == np.float32(1e-45)
    out = zbuffer_max([0], np.float32([-0.0]), 1)
    assert out.view(np.uint32)[0] == 0
    # +inf is allowed and orders highest
    assert zbuffer_max([0, 0], np.float32([np.inf, 3.0]), 1)[0] == np.inf


# --- warp -------------------------------------------------------------------------------------

def _scene():
    k = torus_knot(p=2, q=3, radius=0.8, tube=0.15, segments=160, sides=10)
    v, t = k.vertices + np.array([0.0, 2.0, 0.0]), k.triangles
    light = _light()
    near, far = depth_range(light, v)
    return v, t, light, near, far


@given(st.integers(1, 7), st.sampled_from([np.float32, np.float64]))
def test_traversal_orders_identical(k, dtype):
    v, t, light, near, far = _scene()
    ls = light_views(light, 7, near, far, seed=2)
    pts = np.random.default_rng(k).uniform([-1, 1, -1], [1, 3, 1], (3000, 3)).astype(dtype)
    full = warp(pts, ls, (40, 48), views_per_pass=None)
    part = warp(pts, ls, (40, 48), views_per_pass=k)
    serial = np.stack([warp(pts, ls.clip_from_world[i], (40, 48))[0] for i in range(len(ls))])
    assert full.dtype == dtype
    assert np.array_equal(full, part) and np.array_equal(full, serial)
    # points in random order give the same maps (atomics are order-free)
    perm = np.random.default_rng(0).permutation(len(pts))
    assert np.array_equal(full, warp(pts[perm], ls, (40, 48), views_per_pass=k))


def test_warp_equals_brute_force_projection():
    v, t, light, near, far = _scene()
    ls = light_views(light, 3, near, far)
    rng = np.random.default_rng(5)
    pts = rng.uniform([-1.5, 0.5, -1.5], [1.5, 3.5, 1.5], (500, 3))
    got = warp(pts, ls, 16)
    h = w = 16
    want = np.ones((3, h, w))
    for i in range(3):  # brute force: per view, per point
        for p in pts:
            c = ls.clip_from_world[i] @ np.r_[p, 1.0]
            if c[3] <= 0:
                continue
            x, y, z = (c[0] / c[3] + 1) * w / 2, (1 - c[1] / c[3]) * h / 2, c[2] / c[3]
            if 0 <= x < w and 0 <= y < h and -1 <= z <= 1:
                want[i, int(y), int(x)] = min(want[i, int(y), int(x)], z)
    assert np.allclose(got, want, atol=1e-12)


def test_warp_of_dense_plane_matches_analytic_depth():
    light = _light()
    ls = light_views(light, 5, 1.0, 6.0, seed=1)
    res = 48
    # a tilted plane through (0, 2, 0) with normal n, sampled densely (much finer than a texel)
    n = np.array([0.3, 1.0, 0.2])
    n /= np.linalg.norm(n)
    a = np.cross(n, [0, 0, 1.0]); a /= np.linalg.norm(a)
    b = np.cross(n, a)
    s = np.linspace(-3, 3, 1200)
    S, T = np.meshgrid(s, s)
    pts = np.array([0, 2.0, 0]) + S.reshape(-1, 1) * a + T.reshape(-1, 1) * b
    maps = warp(pts, ls, res)
    for i in range(len(ls)):
        inv = np.linalg.inv(ls.clip_from_world[i])
        eye = ls.positions[i]
        # analytic depth of the plane at the texel corners: ray through the corner, plane hit, projected
        g = np.arange(res + 1)
        X, Y = np.meshgrid(2 * g / res - 1, 1 - 2 * g / res)
        far_pts = np.stack([X, Y, np.ones_like(X), np.ones_like(X)], -1) @ inv.T
        far_pts = far_pts[..., :3] / far_pts[..., 3:]
        d = far_pts - eye
        tt = ((np.array([0, 2.0, 0]) - eye) @ n) / (d @ n)
        hit = eye + tt[..., None] * d
        hh = np.c_[hit.reshape(-1, 3), np.ones(hit[..., 0].size)] @ ls.clip_from_world[i].T
        zc = (hh[:, 2] / hh[:, 3]).reshape(res + 1, res + 1)
        corners = np.stack([zc[:-1, :-1], zc[1:, :-1], zc[:-1, 1:], zc[1:, 1:]])
        lo, hi = corners.min(0), corners.max(0)
        # texels whose corners all hit the sampled patch inside the depth range are covered, within the texel's range
        inside = np.all(np.abs(np.stack([(hit - [0, 2, 0]) @ a, (hit - [0, 2, 0]) @ b])) < 2.9, axis=0)
        ok = inside[:-1, :-1] & inside[1:, :-1] & inside[:-1, 1:] & inside[1:, 1:] & (hi < 1) & (lo > -1)
        assert ok.sum() > res * res // 4
        m = maps[i][ok]
        assert np.all(m >= lo[ok] - 1e-6) and np.all(m <= hi[ok] + 1e-6)


def test_warp_bad_input_and_empty_results():
    light = _light()
    ls = light_views(light, 3, 1.0, 5.0)
    pts = np.zeros((4, 3), np.float32) + [0, 2, 0]
    pts[2, 1] = np.nan
    with pytest.raises(InputError, match="points"):
        warp(pts, ls, 16)
    with pytest.raises(InputError, match="views_per_pass"):
        warp(np.zeros((1, 3)), ls, 16, views_per_pass=0)
    with pytest.raises(InputError, match="resolution"):
        warp(np.zeros((1, 3)), ls, 0)
    # points behind the light or beyond far: views see nothing -> all far (1), documented
    behind = np.array([[0, 5.0, 0], [0, 40.0, 0], [100, -1.0, 0]])
    assert np.all(warp(behind, ls, 16) == 1)
    assert np.all(warp(np.zeros((0, 3)), ls, 16) == 1)
    f, r = project_to_texels(behind, ls.clip_from_world, 16)
    assert f.size == 0 and r.size == 0


# --- MVR and the warp against it ---------------------------------------------------------------

def test_mvr_equals_raster_per_view():
    v, t, light, near, far = _scene()
    ls = light_views(light, 4, near, far)
    maps, stats = mvr(v, t, ls, 32)
    assert stats.triangles == 4 * len(t)
    for i in range(4):
        d, _ = rasterize_depth(v, t, ls.clip_from_world[i], 32)
        assert np.array_equal(maps[i], d[..., 0])


def test_layered_points_cover_what_mvr_covers():
    v, t, light, near, far = _scene()
    ls = light_views(light, 6, near, far)
    m = 64
    pc = generate_points(v, t, source_view(ls, m), cull_back_faces=False)
    w_maps = warp(pc.positions, ls, m)
    r_maps, _ = mvr(v, t, ls, m)
    cw, cr = w_maps < 1, r_maps < 1
    # same silhouettes up to about a texel: the symmetric difference is a small fraction
    assert np.count_nonzero(cw ^ cr) < 0.15 * np.count_nonzero(cr)
    # depth within about a texel: the difference in distance, in units of the texel footprint at that
    # distance (2 d tan(45°) / m), is small for most texels (large only at silhouettes and grazing faces)
    both = cw & cr
    lw, lr = d_view_from_ndc(w_maps[both], near, far), d_view_from_ndc(r_maps[both], near, far)
    r = np.abs(lw - lr) / (2 * lr / m)
    assert np.median(r) < 0.25 and np.mean(r <= 1) > 0.8


def test_bench_entries_run():
    for bm in (b for b in bench_entries() if b.name.startswith("vwss")):
        args = bm.setup(64, bm.dtype)
        bm.fn(*args)


def _brute_texels(points, views, h, w):
    """Per (point, view) pair in plain Python: the clip tests of a depth-map pass, by the definition."""
    hom = np.c_[points, np.ones(len(points), points.dtype)]
    flat, rev = [], []
    for n in range(len(points)):  # brute force (test only)
        for v in range(len(views)):
            c = hom[n] @ views[v].T  # exact for the matrices below (entries 0, ±1, ±1/2, 2)
            dt = points.dtype.type
            if not c[3] > 0:
                continue
            with np.errstate(over="ignore", invalid="ignore"):  # 1 / tiny w: inf, inf · 0
                inv = dt(1) / c[3]
                x = (c[0] * inv + dt(1)) * dt(w / 2)
                y = (dt(1) - c[1] * inv) * dt(h / 2)
                r = dt(0.5) - dt(0.5) * (c[2] * inv)
            if 0 <= x < w and 0 <= y < h and 0 <= r <= 1:
                flat.append((v * h + min(int(y), h - 1)) * w + min(int(x), w - 1))
                rev.append(r)
    return np.array(flat, np.intp), np.array(rev, points.dtype)


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_project_to_texels_equals_brute_force_on_the_bounds(dtype, monkeypatch):
    # Views with exact products put points exactly on x = 0, x = W, y = 0, y = H, r = 0, r = 1 and
    # one ulp either side, behind the view (w < 0) and on w = 0 (inf and NaN window positions).
    views = np.array([np.eye(4), [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0.5, 1]],
                      [[-1, 0, 0, 0.5], [0, 2, 0, 0], [0, 0, -1, 0], [0, 0, 0, 1]],
                      [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, -1, 0]]], dtype)
    edge = np.array([-1, 1, 0, 0.5, -0.5, 2, -2, 1e30], dtype)
    edge = np.concatenate([edge, np.nextafter(edge, dtype(np.inf)), np.nextafter(edge, dtype(-np.inf))])
    rng = np.random.default_rng(1)
    pts = np.c_[rng.choice(edge, 3000), rng.choice(edge, 3000), rng.choice(edge, 3000)].astype(dtype)
    pts[:5] = 0  # (0, 0, 0): w = 0 in the last view, 0 / 0
    monkeypatch.setattr(warp_mod, "_BLOCK", 256)  # many blocks and a partial last one
    with np.errstate(over="ignore"):  # 1 / w overflows for a subnormal w (a warning, as for any caller)
        flat, rev = project_to_texels(pts, views, (8, 16))
    want_flat, want_rev = _brute_texels(pts, views, 8, 16)
    assert 100 < flat.size < pts.shape[0] * len(views)
    assert np.array_equal(flat, want_flat) and rev.dtype == dtype and np.array_equal(rev, want_rev)
    assert {0.0, 1.0} <= set(rev.tolist())  # both depth bounds are kept
