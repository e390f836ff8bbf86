"""Tests of moments_ref.scene.raster against brute-force per-sample references.

The references here are deliberately naive and written from the definitions: a
Python loop over pixels and samples, edge tests in exact integers with the
top-left rule phrased geometrically ("horizontal edge with the third vertex
below", "the interior lies to the right of the edge"), depths from barycentric
coordinates in exact fractions, and ray/plane intersections for perspective.
"""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from moments_ref import InputError
from moments_ref.scene import raster
from moments_ref.scene.raster import (
    look_at,
    orthographic,
    perspective,
    project_points,
    rasterize_depth,
    rasterize_fragments,
    sample_positions,
)

# Written out from the Direct3D 11 documentation (D3D11_STANDARD_MULTISAMPLE_PATTERN),
# in 1/16 pixel, x right, y down; independent of raster._D3D11_PATTERN.
D3D11 = {
    1: [(0, 0)],
    4: [(-2, -6), (6, -2), (-6, 2), (2, 6)],
    8: [(1, -3), (-1, 3), (5, 1), (-3, -5), (-5, 5), (-7, -1), (3, 7), (7, -7)],
}


# ---------------------------------------------------------------------------
# Brute-force reference


def _snap(ndc, h, w):
    """Window position of an NDC vertex in 1/256 pixel (round half to even, like np.rint)."""
    x, y = float(ndc[0]), float(ndc[1])
    return round((x + 1.0) * w / 2 * 256), round((1.0 - y) * h / 2 * 256)


def _on_edge_included(a, b, o):
    """Top-left rule for a sample exactly on edge ab of a triangle whose third vertex is o."""
    (ax, ay), (bx, by), (ox, oy) = a, b, o
    if ay == by:  # horizontal: a top edge if the triangle lies below it (y grows downwards)
        return oy > ay
    # Non-horizontal: a left edge if the interior is to its right, i.e. the third vertex
    # lies right of the edge's line at the third vertex's height.
    x_at = Fraction(ax) + Fraction(oy - ay) * Fraction(bx - ax, by - ay)
    return ox > x_at


def ref_coverage_depth(ndc_tris, h, w, samples, cull="none"):
    """Per-sample nearest depth (Fractions → float), 1.0 where uncovered, and a coverage count.

    ndc_tris : list of 3 NDC vertices (x, y, z) each.
    """
    depth = np.ones((h, w, samples))
    count = np.zeros((h, w, samples), dtype=int)
    for tri in ndc_tris:
        P = [_snap(v, h, w) for v in tri]
        zs = [Fraction(float(v[2])) for v in tri]
        area = (P[1][0] - P[0][0]) * (P[2][1] - P[0][1]) - (P[1][1] - P[0][1]) * (P[2][0] - P[0][0])
        if area == 0:
            continue
        # Counter-clockwise in NDC (y up) means clockwise on screen (y down): area < 0.
        front = area < 0
        if (cull == "back" and not front) or (cull == "front" and front):
            continue
        for r in range(h):
            for c in range(w):
                for s, (dx, dy) in enumerate(D3D11[samples]):
                    px, py = c * 256 + 128 + dx * 16, r * 256 + 128 + dy * 16
                    inside = True
                    for i in range(3):
                        a, b, o = P[i], P[(i + 1) % 3], P[(i + 2) % 3]
                        e = (b[0] - a[0]) * (py - a[1]) - (b[1] - a[1]) * (px - a[0])
                        eo = (b[0] - a[0]) * (o[1] - a[1]) - (b[1] - a[1]) * (o[0] - a[0])
                        if e * eo > 0:
                            continue
                        if e == 0 and _on_edge_included(a, b, o):
                            continue
                        inside = False
                        break
                    if not inside:
                        continue
                    # Barycentric depth in exact arithmetic: λ_k = area with p replacing v_k.
                    def tri_area(a, b, c):
                        return (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
                    q = (px, py)
                    lam = [Fraction(tri_area(q, P[1], P[2]), area),
                           Fraction(tri_area(P[0], q, P[2]), area),
                           Fraction(tri_area(P[0], P[1], q), area)]
                    z = float(sum(lk * zk for lk, zk in zip(lam, zs)))
                    if -1 <= z <= 1:
                        count[r, c, s] += 1
                        depth[r, c, s] = min(depth[r, c, s], z)
    return depth, count


def _mesh(ndc_tris):
    v = np.asarray(ndc_tris, dtype=np.float64).reshape(-1, 3)
    return v, np.arange(v.shape[0]).reshape(-1, 3)


def test_reference_barycentrics_sanity():
    # The reference's own barycentrics: depth at a vertex-adjacent sample of a flat
    # triangle equals the constant, and a tilted one matches a hand-computed value.
    tri = [(-1, -1, 0.25), (1, -1, 0.25), (-1, 1, 0.25)]
    d, n = ref_coverage_depth([tri], 4, 4, 1)
    assert n.sum() == 6 and set(d[n > 0].tolist()) == {0.25}
    tri = [(-1, -1, 0.0), (3, -1, 0.8), (-1, 3, 0.0)]  # z = 0.2 (x_ndc + 1)
    d, n = ref_coverage_depth([tri], 2, 2, 1)
    assert np.allclose(d[:, 0, 0], 0.2 * 0.5) and np.allclose(d[:, 1, 0], 0.2 * 1.5)


# Vertices on the 1/16-pixel grid make samples on edges (ties) frequent.
def _grid_tris(draw, h, w, n):
    tris = []
    for _ in range(n):
        tri = []
        for _ in range(3):
            gx = draw(st.integers(-8, 16 * w + 8))
            gy = draw(st.integers(-8, 16 * h + 8))
            z = draw(st.floats(-0.95, 0.95, allow_nan=False))
            tri.append((gx / 16 / w * 2 - 1, 1 - gy / 16 / h * 2, z))
        tris.append(tri)
    return tris


@st.composite
def tiny_scenes(draw):
    h, w = draw(st.integers(1, 6)), draw(st.integers(1, 6))
    samples = draw(st.sampled_from([1, 4, 8]))
    n = draw(st.integers(1, 4))
    if draw(st.booleans()):
        tris = _grid_tris(draw, h, w, n)
    else:
        coord = st.floats(-1.4, 1.4, allow_nan=False)
        tris = [[(draw(coord), draw(coord), draw(st.floats(-0.95, 0.95))) for _ in range(3)]
                for _ in range(n)]
    return h, w, samples, tris


@given(tiny_scenes(), st.sampled_from(["none", "back", "front"]))
@settings(max_examples=60)
def test_depth_matches_brute_force(scene, cull):
    h, w, samples, tris = scene
    ref, count = ref_coverage_depth(tris, h, w, samples, cull)
    v, t = _mesh(tris)
    got, stats = rasterize_depth(v, t, np.eye(4), (h, w), samples=samples, cull=cull)
    assert got.shape == (h, w, samples) and got.dtype == np.float32
    np.testing.assert_array_equal(got < 1, count > 0)  # coverage: exact
    np.testing.assert_allclose(got, ref, rtol=0, atol=2e-7)  # float32 rounding only
    assert stats.samples_covered == count.sum()


@given(tiny_scenes())
@settings(max_examples=40)
def test_fragments_match_brute_force_and_depth_map(scene):
    h, w, samples, tris = scene
    _, count = ref_coverage_depth(tris, h, w, samples)
    v, t = _mesh(tris)
    frags, stats = rasterize_fragments(v, t, np.eye(4), (h, w), samples=samples)
    # Counts per sample equal the brute-force coverage counts (no depth test).
    got = np.zeros(h * w * samples, dtype=int)
    np.add.at(got, frags.texel * samples + frags.sample, 1)
    np.testing.assert_array_equal(got.reshape(h, w, samples), count)
    assert len(frags) == stats.samples_covered == count.sum()
    # The depth map is the per-sample minimum of the fragments.
    dmap, _ = rasterize_depth(v, t, np.eye(4), (h, w), samples=samples)
    m = np.ones(h * w * samples, np.float32)
    np.minimum.at(m, frags.texel * samples + frags.sample, frags.depth)
    np.testing.assert_array_equal(m.reshape(h, w, samples), dmap)


def test_fragment_count_is_sum_over_triangles():
    rng = np.random.default_rng(3)
    v = np.concatenate([rng.uniform(-1.2, 1.2, (60, 2)), rng.uniform(-0.9, 0.9, (60, 1))], axis=1)
    t = np.arange(60).reshape(20, 3)
    for samples in (1, 4, 8):
        frags, _ = rasterize_fragments(v, t, np.eye(4), (24, 20), samples=samples)
        per_tri = [len(rasterize_fragments(v, t[i:i + 1], np.eye(4), (24, 20), samples=samples)[0])
                   for i in range(len(t))]
        assert len(frags) == sum(per_tri)
        assert np.array_equal(np.bincount(frags.triangle, minlength=20), per_tri)


# ---------------------------------------------------------------------------
# Top-left rule: watertight meshes


def _perturbed_grid(rng, h, w, nx, ny):
    """A grid mesh covering more than the map; interior vertices jittered on 1/16 px."""
    gx = np.linspace(-0.5, w + 0.5, nx + 1)
    gy = np.linspace(-0.5, h + 0.5, ny + 1)
    X, Y = np.meshgrid(gx, gy)
    X[1:-1, 1:-1] += rng.uniform(-0.3, 0.3, (ny - 1, nx - 1)) * (w / nx)
    Y[1:-1, 1:-1] += rng.uniform(-0.3, 0.3, (ny - 1, nx - 1)) * (h / ny)
    X, Y = np.round(X * 16) / 16, np.round(Y * 16) / 16  # many samples land on edges
    ndc = np.stack([X / w * 2 - 1, 1 - Y / h * 2, rng.uniform(-0.5, 0.5, X.shape)], axis=-1)
    idx = np.arange((nx + 1) * (ny + 1)).reshape(ny + 1, nx + 1)
    a, b, c, d = idx[:-1, :-1], idx[:-1, 1:], idx[1:, :-1], idx[1:, 1:]
    diag = rng.random(a.shape) < 0.5  # random choice of the quad's diagonal
    t1 = np.where(diag[..., None], np.stack([a, c, b], -1), np.stack([a, c, d], -1))
    t2 = np.where(diag[..., None], np.stack([b, c, d], -1), np.stack([a, d, b], -1))
    return ndc.reshape(-1, 3), np.concatenate([t1.reshape(-1, 3), t2.reshape(-1, 3)])


@given(st.integers(0, 2**32 - 1), st.sampled_from([1, 4, 8]))
@settings(max_examples=25)
def test_watertight_grid_covers_every_sample_exactly_once(seed, samples):
    rng = np.random.default_rng(seed)
    h, w = int(rng.integers(3, 12)), int(rng.integers(3, 12))
    v, t = _perturbed_grid(rng, h, w, int(rng.integers(2, 6)), int(rng.integers(2, 6)))
    frags, _ = rasterize_fragments(v, t, np.eye(4), (h, w), samples=samples)
    count = np.bincount(frags.texel * samples + frags.sample, minlength=h * w * samples)
    assert count.min() == 1 and count.max() == 1


@given(st.integers(0, 2**32 - 1))
@settings(max_examples=30)
def test_random_quads_shared_diagonal_exhaustive(seed):
    # Two triangles forming a convex quad: every sample is covered by at most one of
    # them, and exactly as often as the brute-force reference covers it with the quad
    # (its diagonal is interior, so samples on it must be covered exactly once).
    rng = np.random.default_rng(seed)
    h, w = 6, 6
    while True:
        ang = np.sort(rng.uniform(0, 2 * np.pi, 4))
        pts = np.stack([3 + 2.6 * np.cos(ang), 3 + 2.6 * np.sin(ang)], -1)
        pts = np.round(pts * 16) / 16
        d = np.roll(pts, -1, axis=0) - pts
        cross = d[:, 0] * np.roll(d, -1, axis=0)[:, 1] - d[:, 1] * np.roll(d, -1, axis=0)[:, 0]
        if min(cross) > 0.5:
            break
    ndc = np.stack([pts[:, 0] / w * 2 - 1, 1 - pts[:, 1] / h * 2, np.zeros(4)], -1)
    t = np.array([[0, 1, 2], [0, 2, 3]]) if rng.random() < 0.5 else np.array([[0, 1, 3], [1, 2, 3]])
    for samples in (1, 4):
        frags, _ = rasterize_fragments(ndc, t, np.eye(4), (h, w), samples=samples)
        key = frags.texel * samples + frags.sample
        assert np.unique(key).size == key.size  # no double coverage
        _, count = ref_coverage_depth([ndc[t[0]].tolist(), ndc[t[1]].tolist()], h, w, samples)
        assert count.max() <= 1
        got = np.bincount(key, minlength=h * w * samples).reshape(h, w, samples)
        np.testing.assert_array_equal(got, count)
        # No gaps: a sample strictly inside the quad (winding test in floats, away from the
        # outer boundary) must be covered.
        c = np.arange(w) + 0.5
        r = np.arange(h) + 0.5
        off = np.asarray(D3D11[samples]) / 16
        SX, SY = np.broadcast_arrays(c[None, :, None] + off[None, None, :, 0],
                                     r[:, None, None] + off[None, None, :, 1])
        inside = np.ones(SX.shape, bool)
        for i in range(4):
            a, b = pts[i], pts[(i + 1) % 4]
            e = (b[0] - a[0]) * (SY - a[1]) - (b[1] - a[1]) * (SX - a[0])
            inside &= e > 1e-9
        assert (got[inside] == 1).all()


def test_shared_edge_mutant_fails():
    # Power of the exact-once check: with the top-left rule replaced by "all edges
    # inclusive" a shared diagonal through sample centres is covered twice.
    v = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], float)
    t = np.array([[0, 1, 2], [0, 2, 3]])
    frags, _ = rasterize_fragments(v, t, np.eye(4), 4)
    assert np.bincount(frags.texel, minlength=16).max() == 1
    _, count = ref_coverage_depth([v[t[0]], v[t[1]]], 4, 4, 1)
    assert count.max() == 1 and count.min() == 1
    # the mutant reference: inclusive edges
    orig = _on_edge_included
    try:
        globals()["_on_edge_included"] = lambda a, b, o: True
        _, mutant = ref_coverage_depth([v[t[0]], v[t[1]]], 4, 4, 1)
    finally:
        globals()["_on_edge_included"] = orig
    assert mutant.max() == 2


# ---------------------------------------------------------------------------
# MSAA sample positions


def test_sample_positions_are_d3d11_standard():
    for s, pat in D3D11.items():
        np.testing.assert_array_equal(sample_positions(s), np.asarray(pat) / 16)


@pytest.mark.parametrize("samples", [1, 4, 8])
@pytest.mark.parametrize("axis", [0, 1])
def test_sample_positions_through_coverage(samples, axis):
    # A half-plane edge sweeping through one pixel in 1/32 steps: sample s is covered
    # iff its offset along the axis lies left of (above) the edge. This reads the
    # sample positions back from coverage alone.
    off = np.asarray(D3D11[samples]) / 16
    for k in range(-15, 16):
        edge = 0.5 + (k + 0.5) / 32  # never on a sample (samples are on the 1/16 grid)
        # big triangle covering window coordinates below `edge` along the axis (1x1 map)
        if axis == 0:
            win = [(-50, -50), (edge, -50), (edge, 50), (-50, 50)]
        else:
            win = [(-50, -50), (50, -50), (50, edge), (-50, edge)]
        ndc = np.array([(x * 2 - 1, 1 - y * 2, 0.0) for x, y in win])
        d, _ = rasterize_depth(ndc, [[0, 1, 2], [0, 2, 3]], np.eye(4), 1, samples=samples)
        expect = 0.5 + off[:, axis] < edge
        np.testing.assert_array_equal(d[0, 0] < 1, expect, err_msg=f"edge={edge}")


def test_unsupported_sample_count_lists_supported():
    v = np.zeros((3, 3))
    for bad in (0, 2, 3, 16, 4.5, "4"):
        with pytest.raises(InputError, match=r"\(1, 4, 8\)"):
            rasterize_depth(v, [[0, 1, 2]], np.eye(4), 4, samples=bad)


# ---------------------------------------------------------------------------
# Culling


def test_culling_follows_ndc_winding_and_right_hand_normal():
    ccw = np.array([[-0.5, -0.5, 0.0], [0.5, -0.5, 0.0], [0.0, 0.5, 0.0]])
    cw = ccw[[0, 2, 1]]
    for verts, front in ((ccw, True), (cw, False)):
        for cull in ("none", "back", "front"):
            d, st_ = rasterize_depth(verts, [[0, 1, 2]], np.eye(4), 8, cull=cull)
            drawn = (d < 1).any()
            expect = cull == "none" or (cull == "back") == front
            assert drawn == expect
            assert st_.culled == (0 if expect else 1)
    # Through a camera: a triangle whose right-hand normal faces the eye is front.
    tri = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float)  # normal +z
    vp = perspective(60, 1, 0.1, 10) @ look_at((0.3, 0.3, 3), (0.3, 0.3, 0), (0, 1, 0))
    assert (rasterize_depth(tri, [[0, 1, 2]], vp, 16, cull="back")[0] < 1).any()
    vp_back = perspective(60, 1, 0.1, 10) @ look_at((0.3, 0.3, -3), (0.3, 0.3, 0), (0, 1, 0))
    assert not (rasterize_depth(tri, [[0, 1, 2]], vp_back, 16, cull="back")[0] < 1).any()


def _box():
    v = np.array([[x, y, z] for x in (-0.5, 0.5) for y in (-0.5, 0.5) for z in (-0.5, 0.5)])
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    t = []
    for a, b, c, d in quads:
        t += [(a, b, c), (a, c, d)]
    t = np.array(t)
    # make every face's right-hand normal point outwards
    n = np.cross(v[t[:, 1]] - v[t[:, 0]], v[t[:, 2]] - v[t[:, 0]])
    out = (n * v[t].mean(1)).sum(1) > 0
    t[~out] = t[~out][:, [0, 2, 1]]
    return v, t


def test_back_face_culling_on_closed_box_keeps_nearest_surface():
    v, t = _box()
    vp = perspective(50, 1, 0.5, 6) @ look_at((1.2, 1.5, 2.0), (0, 0, 0), (0, 1, 0))
    d_all, _ = rasterize_depth(v, t, vp, 32, samples=4)
    d_back, st_ = rasterize_depth(v, t, vp, 32, samples=4, cull="back")
    np.testing.assert_array_equal(d_all, d_back)
    assert st_.culled == 6  # three faces seen from outside, three culled
    f_all, _ = rasterize_fragments(v, t, vp, 32, samples=4)
    f_back, _ = rasterize_fragments(v, t, vp, 32, samples=4, cull="back")
    assert len(f_back) * 2 == len(f_all)  # the silhouette is the same front and back


# ---------------------------------------------------------------------------
# Depth against analytic planes (orthographic and perspective)


def _plane_quad(p0, u, v):
    verts = np.array([p0, p0 + u, p0 + u + v, p0 + v])
    return verts, np.array([[0, 1, 2], [0, 2, 3]])


def _snap_tolerance(depth):
    """Depth error allowed by snapping vertices to 1/256 pixel.

    The rasterized plane passes through the snapped vertices; each moves by at most
    √2/512 pixel, so at interior points the depth differs by at most |∇z|·√2/512
    (|∇z| per pixel, estimated from the analytic depths of neighbouring pixels), plus
    float rounding.
    """
    gy = np.nanmax(np.abs(np.diff(depth[..., 0], axis=0)))
    gx = np.nanmax(np.abs(np.diff(depth[..., 0], axis=1)))
    return float(np.hypot(gx, gy)) * np.sqrt(2) / 512 * 1.01 + 1e-9


def _sample_ndc(h, w, samples):
    off = sample_positions(samples)
    x = (np.arange(w)[None, :, None] + 0.5 + off[None, None, :, 0]) / w * 2 - 1
    y = 1 - (np.arange(h)[:, None, None] + 0.5 + off[None, None, :, 1]) / h * 2
    return np.broadcast_arrays(x, y)


@pytest.mark.parametrize("samples", [1, 4])
def test_orthographic_depth_is_the_analytic_plane(samples):
    h, w = 24, 32
    view = look_at((0.2, 3.0, 0.5), (0, 0, 0), (0, 0, -1))
    proj = orthographic(-2, 2, -1.5, 1.5, 0.5, 6.0)
    normal = np.array([0.3, 1.0, 0.2])
    normal /= np.linalg.norm(normal)
    # a big tilted quad through the origin with this normal
    u = np.cross(normal, [1, 0, 0])
    u /= np.linalg.norm(u)
    vv = np.cross(normal, u)
    verts, t = _plane_quad(-5 * u - 5 * vv, 10 * u, 10 * vv)
    d, _ = rasterize_depth(verts, t, proj @ view, (h, w), samples=samples, dtype=np.float64)
    # Analytic: the ray of an orthographic sample is the line through the unprojected
    # near-plane point along the view direction; intersect with the plane n·p = 0.
    inv = np.linalg.inv(proj @ view)
    x, y = _sample_ndc(h, w, samples)
    def unproject(z):
        p = np.stack([x, y, np.full_like(x, z), np.ones_like(x)], -1) @ inv.T
        return p[..., :3] / p[..., 3:]
    a, b = unproject(-1.0), unproject(1.0)
    s = -(a @ normal) / ((b - a) @ normal)  # fraction along [near, far]
    expect = -1 + 2 * s  # orthographic depth is linear along the ray
    np.testing.assert_allclose(d, expect, atol=_snap_tolerance(expect))


@pytest.mark.parametrize("samples", [1, 8])
def test_perspective_depth_is_the_analytic_plane(samples):
    h, w = 20, 28
    near, far = 0.5, 8.0
    eye = np.array([0.5, 2.0, 3.0])
    view = look_at(eye, (0, 0, 0), (0, 1, 0))
    proj = perspective(55, w / h, near, far)
    # Ground plane y = 0, large: it crosses the near plane and the far plane.
    verts, t = _plane_quad(np.array([-40.0, 0, 40]), np.array([80.0, 0, 0]), np.array([0, 0, -80.0]))
    d, st_ = rasterize_depth(verts, t, proj @ view, (h, w), samples=samples, dtype=np.float64)
    inv = np.linalg.inv(proj @ view)
    x, y = _sample_ndc(h, w, samples)
    p = np.stack([x, y, np.ones_like(x), np.ones_like(x)], -1) @ inv.T
    far_pt = p[..., :3] / p[..., 3:]
    ray = far_pt - eye
    tt = -eye[1] / ray[..., 1]
    hit = eye + tt[..., None] * ray
    # view-space distance along the viewing direction -> NDC depth (gluPerspective)
    fwd = -view[2, :3]
    dist = (hit - eye) @ fwd
    expect = (far + near) / (far - near) - 2 * far * near / ((far - near) * dist)
    valid = (tt > 0) & (expect >= -1) & (expect <= 1)
    ambiguous = np.abs(expect - 1) < 1e-6
    np.testing.assert_array_equal((d < 1)[~ambiguous], valid[~ambiguous])
    tol = _snap_tolerance(np.where(valid, expect, np.nan))
    np.testing.assert_allclose(d[valid], expect[valid], atol=tol)
    assert st_.rasterized == 2


def test_perspective_depth_mutant_linear_depth_fails():
    # The same check would catch a rasterizer that interpolated view distance instead of
    # NDC depth: the two differ by far more than the tolerance.
    near, far = 0.5, 8.0
    dist = np.linspace(1.0, 7.0, 5)
    ndc = (far + near) / (far - near) - 2 * far * near / ((far - near) * dist)
    linear = -1 + 2 * (dist - near) / (far - near)
    assert np.abs(ndc - linear).max() > 1e-2


def test_fragment_positions_project_back_to_their_samples():
    rng = np.random.default_rng(5)
    h, w, samples = 16, 16, 4
    view = look_at((0.3, 2.5, 2.0), (0, 0, 0), (0, 1, 0))
    vp = perspective(60, 1, 0.3, 10) @ view
    verts = rng.uniform(-1, 1, (30, 3))
    t = np.arange(30).reshape(10, 3)
    frags, _ = rasterize_fragments(verts, t, vp, (h, w), samples=samples, dtype=np.float64)
    xy, depth = project_points(frags.position, vp, (h, w))
    off = sample_positions(samples)[frags.sample]
    np.testing.assert_allclose(xy[:, 0], frags.col + 0.5 + off[:, 0], atol=2e-3)
    np.testing.assert_allclose(xy[:, 1], frags.row + 0.5 + off[:, 1], atol=2e-3)
    np.testing.assert_allclose(depth, frags.depth, atol=1e-5)
    # and each fragment lies on its triangle's plane
    a, b, c = (verts[t[frags.triangle, k]] for k in range(3))
    n = np.cross(b - a, c - a)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    assert np.abs(((frags.position - a) * n).sum(1)).max() < 1e-3


# ---------------------------------------------------------------------------
# Bad input, degenerate triangles, invariances


def test_degenerate_triangles_are_skipped_and_counted():
    good = np.array([[-0.8, -0.8, 0.1], [0.8, -0.8, 0.2], [0.0, 0.8, 0.3]])
    extra = np.array([
        [np.nan, 0, 0], [0.5, np.inf, 0],            # 3, 4 non-finite
        [0.1, 0.1, 0], [0.2, 0.2, 0], [0.3, 0.3, 0],  # 5, 6, 7 collinear
    ])
    v = np.concatenate([good, extra])
    t = np.array([[0, 1, 2], [3, 1, 2], [0, 4, 2], [5, 6, 7], [0, 0, 1], [1, 2, 2]])
    d, stats = rasterize_depth(v, t, np.eye(4), 16, samples=4)
    ref, _ = rasterize_depth(good, [[0, 1, 2]], np.eye(4), 16, samples=4)
    np.testing.assert_array_equal(d, ref)
    assert stats.nonfinite == 2 and stats.degenerate == 3 and stats.rasterized == 1
    assert stats.skipped_bad == 5 and stats.as_dict()["triangles"] == 6
    frags, fst = rasterize_fragments(v, t, np.eye(4), 16, samples=4)
    assert fst.nonfinite == 2 and fst.degenerate == 3 and set(frags.triangle.tolist()) == {0}


def test_zero_screen_area_and_outside_counted():
    v = np.array([[0, -0.5, -0.5], [0, 0.5, 0.0], [0, 0.0, 0.5],     # edge-on to the view: zero area
                  [2, 2, 0], [3, 2, 0], [2, 3, 0]], float)           # outside
    d, stats = rasterize_depth(v, [[0, 1, 2], [3, 4, 5]], np.eye(4), 8)
    assert (d == 1).all() and stats.zero_area == 1 and stats.outside == 1


def test_bad_input_refused():
    v = np.zeros((3, 3))
    with pytest.raises(InputError, match="size"):
        rasterize_depth(v, [[0, 1, 2]], np.eye(4), 0)
    with pytest.raises(InputError, match="size"):
        rasterize_depth(v, [[0, 1, 2]], np.eye(4), (0, 4))
    with pytest.raises(InputError, match="triangles"):
        rasterize_depth(v, [[0, 1, 3]], np.eye(4), 4)
    with pytest.raises(InputError, match="triangles"):
        rasterize_depth(v, [[0.0, 1.0, 2.0]], np.eye(4), 4)
    with pytest.raises(InputError, match="clip_from_world"):
        rasterize_depth(v, [[0, 1, 2]], np.eye(3), 4)
    with pytest.raises(InputError, match="cull"):
        rasterize_depth(v, [[0, 1, 2]], np.eye(4), 4, cull="ccw")
    with pytest.raises(InputError, match="up"):
        look_at((0, 0, 0), (0, 1, 0), (0, 2, 0))
    with pytest.raises(InputError, match="fovy"):
        perspective(180, 1, 0.1, 1)
    # empty meshes are fine
    d, stats = rasterize_depth(np.zeros((0, 3)), np.zeros((0, 3), int), np.eye(4), 4)
    assert (d == 1).all() and stats.triangles == 0


def test_results_do_not_depend_on_chunk_sizes(monkeypatch):
    rng = np.random.default_rng(11)
    # small and large triangles, some crossing the near plane of a perspective view
    v = rng.uniform(-3, 3, (600, 3))
    t = np.arange(600).reshape(200, 3)
    vp = perspective(70, 1.3, 0.5, 12) @ look_at((0, 0, 4), (0, 0, 0), (0, 1, 0))
    d1, s1 = rasterize_depth(v, t, vp, (40, 52), samples=4)
    f1, _ = rasterize_fragments(v, t, vp, (40, 52), samples=4)
    from moments_ref.scene.raster import _spans as spans  # the coverage chunking lives there

    monkeypatch.setattr(spans, "_ROW_BUDGET", 5)
    monkeypatch.setattr(spans, "_SAMPLE_BUDGET", 3)
    monkeypatch.setattr(raster, "_SETUP_CHUNK", 7)
    monkeypatch.setattr(spans, "_DENSE_ROWS", 4)
    d2, s2 = rasterize_depth(v, t, vp, (40, 52), samples=4)
    f2, _ = rasterize_fragments(v, t, vp, (40, 52), samples=4)
    np.testing.assert_array_equal(d1, d2)
    assert s1 == s2
    for name in ("position", "depth", "texel", "sample", "triangle"):
        np.testing.assert_array_equal(getattr(f1, name), getattr(f2, name))
    assert s1.rasterized > 0 and (d1 < 1).mean() > 0.2


@pytest.mark.parametrize("samples", [1, 4, 8])
def test_merged_row_count_groups_give_the_same_maps(monkeypatch, samples):
    # Boxes of 1 to about 40 rows (the tallest cut into pieces): the dense groups merged upwards
    # (the padded rows masked) into few groups, into one, or not at all, give the same maps and
    # fragments. A merge that gives a group the smallest of its row counts drops rows: it must fail.
    from moments_ref.scene.raster import _spans as spans

    rng = np.random.default_rng(5)
    v, t = raster.small_triangles(300, 96, 40.0, rng)
    got = {}
    for merge in (0, 1 << 9, 1 << 30):
        monkeypatch.setattr(spans, "_MERGE_ROWS", merge)
        d, st = rasterize_depth(v, t, np.eye(4), 96, samples=samples)
        f, _ = rasterize_fragments(v, t, np.eye(4), 96, samples=samples)
        got[merge] = d.tobytes(), st, f.texel * samples + f.sample, f.depth
    base = got[0]
    assert base[1].samples_covered > 0
    for merge, (d, st, flat, z) in got.items():
        assert d == base[0] and st == base[1], merge
        np.testing.assert_array_equal(flat, base[2])
        np.testing.assert_array_equal(z, base[3])

    def smallest(key, S):  # the mutant: each merged group takes its smallest row count
        n = np.bincount(key, minlength=spans._DENSE_ROWS + 1)
        to = np.arange(n.size)
        ks = np.flatnonzero(n[1:]) + 1
        for g in np.array_split(ks, max(1, ks.size // 3)):
            to[g] = g[0]
        return to[key]

    monkeypatch.setattr(spans, "_merged_counts", smallest)
    assert rasterize_depth(v, t, np.eye(4), 96, samples=samples)[0].tobytes() != base[0]


def test_merged_counts_take_the_largest_of_consecutive_counts(monkeypatch):
    from moments_ref.scene.raster import _spans as spans

    key = np.array([0, 3, 1, 1, 2, 5, 3, 0, 9, 2, 30])
    monkeypatch.setattr(spans, "_MERGE_ROWS", 0)
    np.testing.assert_array_equal(spans._merged_counts(key, 4), key)
    monkeypatch.setattr(spans, "_MERGE_ROWS", 20)  # weights k * count * S with S = 4: 1: 8, 2: 16, 3: 24, ...
    # 1 and 2 together reach 24 >= 20 (-> 2); 3 alone 24 (-> 3); 5: 20 (-> 5); 9: 36 (-> 9); 30 (-> 30)
    np.testing.assert_array_equal(spans._merged_counts(key, 4), [0, 3, 2, 2, 2, 5, 3, 0, 9, 2, 30])
    monkeypatch.setattr(spans, "_MERGE_ROWS", 1 << 30)  # one group: the largest count
    np.testing.assert_array_equal(spans._merged_counts(key, 4), np.where(key > 0, 30, 0))


@pytest.mark.parametrize("samples", [1, 4, 8])
def test_span_row_values_give_the_maps_of_span_indices(monkeypatch, samples):
    # The dense path hands _iter_spans each span row's values (_spans._rect_values) instead of
    # its (triangle, row, sample, column): on a non-square map with boxes of 1 to about 80 rows
    # (tall ones cut into pieces, groups merged, large triangles tiled), float32 and float64,
    # the maps must be those of the indices, byte for byte. A row value off by one sample
    # offset (x without the sample's sx) must fail.
    from moments_ref.scene.raster import _spans as spans

    rng = np.random.default_rng(11)
    v, t = raster.small_triangles(400, 160, 70.0, rng)
    v = v * np.array([1.0, 0.75, 1.0])  # the map is 160 x 120: rows and columns differ
    big = np.array([[-0.9, -0.8, -0.3], [0.8, -0.7, 0.2], [0.1, 0.9, 0.5]])  # tiled (inradius >= 16 px)
    v, t = np.concatenate([v, big]), np.concatenate([t, [[v.shape[0], v.shape[0] + 1, v.shape[0] + 2]]])
    got = {}
    for values in (False, True):
        monkeypatch.setattr(spans, "_ROW_VALUES", values)
        got[values] = [rasterize_depth(v, t, np.eye(4), (120, 160), samples=samples, dtype=dt)
                       for dt in (np.float32, np.float64)]
    for (d0, s0), (d1, s1) in zip(got[False], got[True]):
        assert d0.tobytes() == d1.tobytes() and s0 == s1
    assert got[True][0][1].samples_covered > 0 and (got[True][0][0] < 1).mean() > 0.3

    real = spans._rect_values

    def off_by_sx(s, tri, A3, B3, base3, c0, nc, r0, nr, k, sx, sy, w):  # the mutant
        return real(s, tri, A3, B3, base3, c0, nc, r0, nr, k, sx * 0, sy, w)

    monkeypatch.setattr(spans, "_rect_values", off_by_sx)
    if samples > 1:  # the 1x pattern's offset is 0
        assert rasterize_depth(v, t, np.eye(4), (120, 160), samples=samples)[0].tobytes() != got[False][0][0].tobytes()


@pytest.mark.parametrize("samples", [1, 4, 8])
def test_span_depth_table_gives_the_maps_of_the_row_values(monkeypatch, samples):
    # Where a dense group's boxes have few columns for their covered samples, _rect_values hands
    # _iter_spans a table of z0 + za X per (sample, box, column) to look up instead of the rows'
    # X, z0 and za (_spans._TABLE). On the map of the test above (boxes of 1 to about 80 rows,
    # tall ones cut into pieces, merged groups, a tiled triangle), 1x/4x/8x, float32 and float64,
    # the maps must be those without the table, byte for byte, whether some, none or every
    # group takes it; and the table must be taken. Mutants: a table one column off, or one
    # built without the sample's x offset, must fail.
    from moments_ref.scene.raster import _spans as spans

    rng = np.random.default_rng(11)
    v, t = raster.small_triangles(400, 160, 70.0, rng)
    v = v * np.array([1.0, 0.75, 1.0])
    big = np.array([[-0.9, -0.8, -0.3], [0.8, -0.7, 0.2], [0.1, 0.9, 0.5]])
    v, t = np.concatenate([v, big]), np.concatenate([t, [[v.shape[0], v.shape[0] + 1, v.shape[0] + 2]]])
    real = spans._rect_values
    taken = []

    def counting(*a):
        out = real(*a)
        taken.append(out[-1] is not None)
        return out

    monkeypatch.setattr(spans, "_rect_values", counting)
    got = {}
    for share in (0, 1.0, 1e9):
        monkeypatch.setattr(spans, "_TABLE", share)
        got[share] = [rasterize_depth(v, t, np.eye(4), (120, 160), samples=samples, dtype=dt)
                      for dt in (np.float32, np.float64)]
    for share in (1.0, 1e9):
        for (d0, s0), (d1, s1) in zip(got[0], got[share]):
            assert d0.tobytes() == d1.tobytes() and s0 == s1
    assert any(taken) and not all(taken)  # 0 never takes it, 1e9 always
    assert (got[0][0][0] < 1).mean() > 0.3

    def mutant(kind):
        def values(s, tri, A3, B3, base3, c0, nc, r0, nr, k, sx, sy, w):
            if kind == "sx":
                return real(s, tri, A3, B3, base3, c0, nc, r0, nr, k, sx * 0, sy, w)
            out = list(real(s, tri, A3, B3, base3, c0, nc, r0, nr, k, sx, sy, w))
            if out[-1] is not None:
                out[-1] = np.concatenate([out[-1][1:], out[-1][-1:]])  # every entry one column to the right
            return tuple(out)
        return values

    monkeypatch.setattr(spans, "_TABLE", 1e9)
    for kind in ("column", "sx") if samples > 1 else ("column",):  # the 1x pattern's offset is 0
        monkeypatch.setattr(spans, "_rect_values", mutant(kind))
        assert rasterize_depth(v, t, np.eye(4), (120, 160), samples=samples)[0].tobytes() != got[0][0][0].tobytes()


def test_float64_map_and_dense_vs_ragged_paths_agree(monkeypatch):
    # The same large triangle through the ragged int64 span path and (with a huge row
    # limit) the dense float64 span path gives the same map.
    v = np.array([[-0.9, -0.7, -0.3], [0.8, -0.9, 0.4], [0.1, 0.95, 0.9]])
    d1, _ = rasterize_depth(v, [[0, 1, 2]], np.eye(4), 48, samples=8, dtype=np.float64)
    monkeypatch.setattr(raster._spans, "_DENSE_ROWS", 64)
    d2, _ = rasterize_depth(v, [[0, 1, 2]], np.eye(4), 48, samples=8, dtype=np.float64)
    assert d1.dtype == np.float64
    np.testing.assert_array_equal(d1, d2)


def test_bench_raster_reports_numbers():
    out = raster.bench_raster(n_triangles=2000, size=64, samples=(1, 4), repeat=1,
                              resolve_samples=20000)
    assert out["raster_1x_tris_per_s"] > 0 and out["raster_4x_samples_covered"] > 0
    assert out["resolve_agree"] is True


def test_span_interval_is_exact_also_beyond_float_precision():
    # _solve_interval against Python's exact integers, with |L| up to 2^60 (the
    # integer fallback) and below 2^53 (the float quotient), a of both signs and 0.
    from moments_ref.scene.raster._spans import _solve_interval

    rng = np.random.default_rng(5)
    n = 4000
    L = np.concatenate([rng.integers(-2**60, 2**60, n // 2), rng.integers(-2**40, 2**40, n // 2)])
    L[::7] = (L[::7] // 256) * 256  # quotients that are exact integers
    a = rng.integers(-2**29, 2**29, n) * 256
    a[::5] = 0
    # Just off an exact quotient with |L| > 2^53, where float64 rounds L itself.
    q, d = rng.integers(2**46, 2**48, n // 4), rng.integers(1, 64, n // 4) * 256
    L[1::4], a[1::4] = q * d + rng.choice([-1, 0, 1], n // 4), d * rng.choice([-1, 1], n // 4)
    L[3::4], a[3::4] = -(q * d + rng.choice([-1, 0, 1], n // 4)), d * rng.choice([-1, 1], n // 4)  # L < -2^53
    lo = np.full(n, -2**62)
    hi = np.full(n, 2**62)
    _solve_interval(L, a, np.where(a == 0, 1, -a), lo, hi)
    for Li, ai, l, h in zip(L.tolist(), a.tolist(), lo.tolist(), hi.tolist()):
        if ai > 0:
            want = (-(Li // ai), 2**62)  # smallest u with a u + L >= 0
        elif ai < 0:
            want = (-2**62, Li // -ai)  # largest such u
        else:
            want = (-2**62, 2**62) if Li >= 0 else (-2**62, -1)
        assert (l, h) == want, (Li, ai)


# ---------------------------------------------------------------------------
# Internals of the span rasterizer against exact integer definitions


def _setup_from_window(X, Y):
    """Edge equations of triangles given by window vertices in 1/256 pixel, (3, n) int64 each."""
    from moments_ref.scene.raster._triangles import _edge_equations

    X, Y = np.array(X, dtype=np.int64), np.array(Y, dtype=np.int64)
    area2 = (X[1] - X[0]) * (Y[2] - Y[0]) - (Y[1] - Y[0]) * (X[2] - X[0])
    keep = area2 != 0
    X, Y = X[:, keep], Y[:, keep]
    zv = np.zeros(X.shape, dtype=np.float64)
    return _edge_equations(X.copy(), Y.copy(), zv, area2[keep], np.arange(X.shape[1]), None, False), X, Y


@settings(max_examples=60)
@given(st.integers(0, 2**32 - 1), st.sampled_from([1, 4, 8]), st.sampled_from([0, 3, 32]))
def test_span_rows_are_the_samples_inside_all_three_edges(seed, samples, dense_rows):
    # Every (triangle, row, sample, column) the span paths yield, against the definition:
    # the sample's three edge functions E = A x + B y + F0 >= 0 (top-left rule folded into
    # F0), evaluated in Python integers at every sample of the map. Triangles up to a few
    # pixels (dense path, with the edge reordering for k S >= 3) and larger (ragged path,
    # dense_rows = 0), with horizontal and vertical edges (a = 0) from a coarse grid.
    from moments_ref.scene.raster import _spans
    from moments_ref.scene.raster._coverage import _boxes
    from moments_ref.scene.raster._matrices import _D3D11_PATTERN

    rng = np.random.default_rng(seed)
    h, w, n = 12, 14, 6
    step = rng.choice([1, 32, 128])
    X = rng.integers(-300, w * 256 + 300, (3, n)) // step * step
    Y = rng.integers(-300, h * 256 + 300, (3, n)) // step * step
    s, X, Y = _setup_from_window(X, Y)
    pat = np.asarray(_D3D11_PATTERN[samples], dtype=np.int64) * 16
    sx, sy = pat[:, 0], pat[:, 1]
    c0, c1, r0, r1, safe = _boxes(X, Y, h, w, sx, sy)
    sel = np.flatnonzero((c0 <= c1) & (r0 <= r1))
    old = _spans._DENSE_ROWS
    _spans._DENSE_ROWS = dense_rows
    try:
        got = set()
        kept = {k: np.take(s[k], sel, axis=1) for k in ("A", "B", "F0")}  # the nonempty boxes' edges
        for pt, row, samp, col0, cnt in _spans._row_batches(kept, c0[sel], c1[sel] - c0[sel] + 1, r0[sel],
                                                             r1[sel] - r0[sel] + 1, safe[sel], sx, sy):
            assert (cnt > 0).all()
            for p, r, q, a, c in zip(*(x.tolist() for x in (sel[pt], row, samp, col0, cnt))):
                got.update((p, r, q, col) for col in range(a, a + c))
    finally:
        _spans._DENSE_ROWS = old
    want = set()
    A, B, F0 = (s[k].tolist() for k in ("A", "B", "F0"))
    for i in range(X.shape[1]):
        for r in range(h):
            for q in range(samples):
                for col in range(w):
                    x, y = col * 256 + 128 + int(sx[q]), r * 256 + 128 + int(sy[q])
                    if all(A[e][i] * x + B[e][i] * y + F0[e][i] >= 0 for e in range(3)):
                        want.add((i, r, q, col))
    assert got == want


@settings(max_examples=30)
@given(st.integers(0, 2**32 - 1), st.sampled_from([1, 4, 8]))
def test_span_edges_presorted_once_give_the_bounds_of_sorting_per_batch(seed, samples):
    # _row_batches puts the edges in _rect_bounds' order once per chunk (_edge_order) and passes
    # presorted=True; the bounds must be those _rect_bounds computes when it sorts them itself.
    # The order itself: per triangle a permutation of its three edges, a > 0 first, a < 0 second.
    # Power: the same call with the first two edges swapped and presorted=True must differ.
    from moments_ref.scene.raster import _spans
    from moments_ref.scene.raster._matrices import _D3D11_PATTERN, _HALF, _SUB

    rng = np.random.default_rng(seed)
    n, k = 40, int(rng.integers(1, 9))
    s, X, Y = _setup_from_window(rng.integers(-200, 12 * 256, (3, n)), rng.integers(-200, 12 * 256, (3, n)))
    A3, B3, F3 = s["A"], s["B"], s["F0"]
    oA, oB, oF = _spans._edge_order(A3, B3, F3)
    assert (oA[0] > 0).all() and (oA[1] < 0).all()
    key = lambda a, b, f: np.sort(np.stack([a, b, f], -1).view([("", a.dtype)] * 3), axis=0)
    assert (key(oA, oB, oF) == key(A3, B3, F3)).all()
    pat = np.asarray(_D3D11_PATTERN[samples], dtype=np.int64) * 16
    sx, sy = pat[:, 0], pat[:, 1]
    m = oA.shape[1]
    c0, r0 = rng.integers(0, 10, m), rng.integers(0, 10, m)
    nc, nr = rng.integers(1, 6, m), np.full(m, k)
    base = lambda a, b, f: f + a * (c0 * _SUB + _HALF) + b * (r0 * _SUB + _HALF)
    lo, cnt = _spans._rect_bounds(A3, B3, base(A3, B3, F3), nc, nr, k, sx, sy)
    lo2, cnt2 = _spans._rect_bounds(oA, oB, base(oA, oB, oF), nc, nr, k, sx, sy, presorted=True)
    np.testing.assert_array_equal(np.maximum(cnt, 0), np.maximum(cnt2, 0))
    np.testing.assert_array_equal(np.where(cnt > 0, lo, 0), np.where(cnt2 > 0, lo2, 0))
    if k * samples >= 3:
        sw = [1, 0, 2]
        lo3, cnt3 = _spans._rect_bounds(oA[sw], oB[sw], base(oA, oB, oF)[sw], nc, nr, k, sx, sy, presorted=True)
        assert not (np.array_equal(np.maximum(cnt3, 0), np.maximum(cnt, 0))
                    and np.array_equal(np.where(cnt3 > 0, lo3, 0), np.where(cnt > 0, lo, 0)))


@settings(max_examples=40)
@given(st.lists(st.integers(1, 40), min_size=1, max_size=60))
def test_span_repeater_is_np_repeat(counts):
    # Both branches (gather by a repeated row index for short rows, np.repeat for long).
    from moments_ref.scene.raster._spans import _repeater

    c = np.array(counts, dtype=np.int64)
    a = np.random.default_rng(len(counts)).normal(size=c.size)
    np.testing.assert_array_equal(_repeater(c, int(c.sum()))(a), np.repeat(a, c))
    np.testing.assert_array_equal(_repeater(c, int(c.sum()))(np.arange(c.size)), np.repeat(np.arange(c.size), c))


@pytest.mark.parametrize("cull", ["none", "back"])
@pytest.mark.parametrize("samples", [1, 4])
def test_shared_and_unshared_vertices_give_the_same_map(cull, samples):
    # A mesh sharing its vertices (transformed once, gathered) and the same triangles
    # with their own vertices (gathered, transformed per chunk): the same map and stats,
    # also with non-finite and repeated vertices among them.
    from moments_ref.scene import load_scene

    sc = load_scene("knot")
    mesh = sc.occluder_mesh(translucent=False)
    v, t = mesh.vertices.copy(), mesh.triangles[:20000]
    v[t[::997, 0]] = np.nan
    t = t.copy()
    t[5::1009, 2] = t[5::1009, 1]  # degenerate
    vp = sc.light_clip_from_world()
    d1, s1 = rasterize_depth(v, t, vp, 96, samples=samples, cull=cull)
    d2, s2 = rasterize_depth(v[t].reshape(-1, 3), np.arange(3 * t.shape[0]).reshape(-1, 3), vp, 96,
                             samples=samples, cull=cull)
    assert d1.tobytes() == d2.tobytes() and s1 == s2
    assert s1.nonfinite > 0 and s1.degenerate > 0 and (d1 < 1).any()




@settings(max_examples=30)
@given(st.integers(0, 2**32 - 1), st.sampled_from([1, 4]))
def test_span_rows_are_flagged_inside_exactly_when_their_depths_are_in_range(seed, samples):
    # _iter_spans marks a row "inside" (no per-sample depth clip needed) from its first and
    # last sample. Depth is monotone along a row, so the flag must equal "every depth of
    # the row in [-1, 1]"; and every depth is the plane through the three vertices. Depth
    # planes crossing -1 and 1 inside the map (no geometric clip here), two lying at
    # exactly 1 and -1; one row per batch (each row's flag seen) and batches of many rows
    # (the batch's flag: all its rows inside).
    from moments_ref.scene.raster import _spans
    from moments_ref.scene.raster._coverage import _boxes
    from moments_ref.scene.raster._matrices import _D3D11_PATTERN
    from moments_ref.scene.raster._triangles import _edge_equations

    rng = np.random.default_rng(seed)
    h, w, n = 10, 12, 5
    X = rng.integers(-200, w * 256 + 200, (3, n))
    Y = rng.integers(-200, h * 256 + 200, (3, n))
    zv = rng.uniform(-2.5, 2.5, (3, n))
    zv[:, 0], zv[:, 1] = 1.0, -1.0
    area2 = (X[1] - X[0]) * (Y[2] - Y[0]) - (Y[1] - Y[0]) * (X[2] - X[0])
    keep = area2 != 0
    X, Y, zv = X[:, keep].copy(), Y[:, keep].copy(), zv[:, keep].copy()
    s = _edge_equations(X, Y, zv, area2[keep], np.arange(X.shape[1]), None, False)  # orients X, Y, zv in place
    # The plane z = alpha + beta x + gamma y through the (oriented) vertices, solved per triangle.
    M = np.stack([np.ones_like(X, dtype=float), X.astype(float), Y.astype(float)], axis=-1).transpose(1, 0, 2)
    coef = np.linalg.solve(M, zv.T[..., None])[..., 0]
    pat = np.asarray(_D3D11_PATTERN[samples], dtype=np.int64) * 16
    sx, sy = pat[:, 0], pat[:, 1]
    c0, c1, r0, r1, safe = _boxes(X, Y, h, w, sx, sy)
    sel = np.flatnonzero((c0 <= c1) & (r0 <= r1))
    kept = {k: np.take(s[k], sel, axis=-1) for k in ("A", "B", "F0", "X", "Y", "z0", "za", "zb", "inside")}
    old = _spans._SAMPLE_BUDGET
    try:
        for budget in (1, 40, old):
            _spans._SAMPLE_BUDGET = budget
            _check_span_batches(_spans._iter_spans(kept, c0[sel], c1[sel], r0[sel], r1[sel], safe[sel], sx, sy, w,
                                                   True), coef[sel], w, samples, sx, sy, one_row=budget == 1)
    finally:
        _spans._SAMPLE_BUDGET = old


def _check_span_batches(batches, coef, w, samples, sx, sy, one_row):
    for flat, z, inside, (tri, row, col, samp) in batches:
        if one_row:
            assert len(set(zip(tri.tolist(), row.tolist(), samp.tolist()))) == 1
        x, y = col * 256 + 128 + sx[samp], row * 256 + 128 + sy[samp]
        a, b, c = coef[tri].T
        np.testing.assert_allclose(z, a + b * x + c * y, rtol=0, atol=1e-9)
        np.testing.assert_array_equal(flat, (row * w + col) * samples + samp)
        assert inside == bool(np.all((z >= -1) & (z <= 1))), (tri[0], row[0], z.min(), z.max())


@settings(max_examples=30)
@given(st.integers(0, 2**32 - 1), st.sampled_from([1, 4]))
def test_span_rows_are_exact_for_triangles_reaching_far_into_the_guard_band(seed, samples):
    # A vertex up to 2^20 pixels away (clipping's guard band): the edge values at the map's
    # samples exceed float64's exact integers (2^53), so such a triangle must take the int64
    # path even when its box on the map is small. Against the definition, in Python integers.
    from moments_ref.scene.raster import _spans
    from moments_ref.scene.raster._coverage import _boxes
    from moments_ref.scene.raster._matrices import _D3D11_PATTERN

    rng = np.random.default_rng(seed)
    h, w, n = 10, 12, 6
    X = rng.integers(-300, w * 256 + 300, (3, n))
    Y = rng.integers(-300, h * 256 + 300, (3, n))
    X[0] = rng.integers(2**26, 2**28, n) * rng.choice([-1, 1], n)  # the far vertex, in 1/256 pixel
    Y[0] = rng.integers(2**26, 2**28, n) * rng.choice([-1, 1], n)
    s, X, Y = _setup_from_window(X, Y)
    pat = np.asarray(_D3D11_PATTERN[samples], dtype=np.int64) * 16
    sx, sy = pat[:, 0], pat[:, 1]
    c0, c1, r0, r1, safe = _boxes(X, Y, h, w, sx, sy)
    sel = np.flatnonzero((c0 <= c1) & (r0 <= r1))
    assert not safe[sel].any()
    got = set()
    kept = {k: np.take(s[k], sel, axis=1) for k in ("A", "B", "F0")}
    for pt, row, samp, col0, cnt in _spans._row_batches(kept, c0[sel], c1[sel] - c0[sel] + 1, r0[sel],
                                                         r1[sel] - r0[sel] + 1, safe[sel], sx, sy):
        for p, r, q, a, c in zip(*(x.tolist() for x in (sel[pt], row, samp, col0, cnt))):
            got.update((p, r, q, col) for col in range(a, a + c))
    A, B, F0 = (s[k].tolist() for k in ("A", "B", "F0"))
    want = {(i, r, q, col) for i in range(X.shape[1]) for r in range(h) for q in range(samples) for col in range(w)
            if all(A[e][i] * (col * 256 + 128 + int(sx[q])) + B[e][i] * (r * 256 + 128 + int(sy[q])) + F0[e][i] >= 0
                   for e in range(3))}
    assert got == want


@settings(max_examples=25)
@given(st.integers(0, 2**32 - 1), st.sampled_from([1, 4]))
def test_dense_span_rows_are_exact_for_long_edges_through_samples(seed, samples):
    # Triangles whose boxes have at most 32 rows (the dense float path) across a wide map, vertices on
    # the pixel grid so that edges pass exactly through samples: edge values reach 2^26 there,
    # beyond float32's integers, and a sample one unit inside or outside an edge must be told apart.
    # Against the edge functions evaluated at every sample of each box in int64 (exact).
    from moments_ref.scene.raster import _spans
    from moments_ref.scene.raster._coverage import _boxes
    from moments_ref.scene.raster._matrices import _D3D11_PATTERN

    rng = np.random.default_rng(seed)
    h, w, n = 30, 1500, 8
    X = rng.integers(-20, w + 20, (3, n)) * 256
    Y = rng.integers(-2, 30, (3, n)) * 256 + rng.choice([0, 128], (3, n))
    # and steep or wide ones with a vertex up to 2^24 units away (still the float path): edge
    # coefficients beyond float32's 24 bits
    far = (2**24 - rng.integers(1, 2**16, n)) * rng.choice([-1, 1], n)
    X[0, : n // 4], Y[0, n // 4 : n // 2] = far[: n // 4], far[n // 4 : n // 2]
    s, X, Y = _setup_from_window(X, Y)
    pat = np.asarray(_D3D11_PATTERN[samples], dtype=np.int64) * 16
    sx, sy = pat[:, 0], pat[:, 1]
    c0, c1, r0, r1, safe = _boxes(X, Y, h, w, sx, sy)
    sel = np.flatnonzero((c0 <= c1) & (r0 <= r1))
    kept = {k: np.take(s[k], sel, axis=1) for k in ("A", "B", "F0")}
    got = []
    for pt, row, samp, col0, cnt in _spans._row_batches(kept, c0[sel], c1[sel] - c0[sel] + 1, r0[sel],
                                                         r1[sel] - r0[sel] + 1, safe[sel], sx, sy):
        rep = np.repeat(np.arange(cnt.size), cnt)
        col = np.repeat(col0, cnt) + np.arange(rep.size) - np.repeat(np.cumsum(cnt) - cnt, cnt)
        got.append((((sel[pt][rep] * h + row[rep]) * samples + samp[rep]) * w + col))
    got = np.sort(np.concatenate(got)) if got else np.zeros(0, np.int64)
    want = []
    cols = np.arange(w)
    for i in range(X.shape[1]):
        for r in range(h):
            for q in range(samples):
                x, y = cols * 256 + 128 + sx[q], r * 256 + 128 + sy[q]
                inside = np.all([s["A"][e][i] * x + s["B"][e][i] * y + s["F0"][e][i] >= 0 for e in range(3)], axis=0)
                want.append(((i * h + r) * samples + q) * w + cols[inside])
    np.testing.assert_array_equal(got, np.sort(np.concatenate(want)))


@pytest.mark.parametrize("samples,cull,dtype", [(1, "none", np.float32), (4, "back", np.float64), (1, "front", np.float32)])
def test_depth_views_are_rasterize_depth_per_view(samples, cull, dtype):
    # rasterize_depth_views checks the mesh once (non-finite vertices, zero world area) and
    # skips those checks per view: every map and every count must be rasterize_depth's, on a
    # mesh with non-finite, degenerate and clipped triangles, shared (transformed once) and
    # unshared vertices, and views from all sides (some see nothing).
    from moments_ref.scene import load_scene
    from moments_ref.scene.raster import look_at, perspective, rasterize_depth_views

    mesh = load_scene("knot").occluder_mesh(translucent=False)
    v, t = mesh.vertices.copy(), mesh.triangles[:6000].copy()
    v[t[::501, 0]] = np.nan
    v[t[7::613, 1]] = np.inf
    t[5::409, 2] = t[5::409, 1]  # repeated vertex
    t[9::397, 2] = t[9::397, 0]
    centre = v[np.isfinite(v).all(axis=1)].mean(axis=0)
    eyes = centre + np.array([[3.0, 1.0, 2.0], [-2.0, 4.0, 0.5], [0.2, -0.3, 0.4], [0.0, 0.0, -9.0]])
    mats = np.stack([perspective(60, 1.2, 0.5, 12.0) @ look_at(e, centre) for e in eyes])
    for vv, tt in ((v, t), (v[t].reshape(-1, 3), np.arange(3 * t.shape[0]).reshape(-1, 3))):
        got = list(rasterize_depth_views(vv, tt, mats, (70, 90), samples=samples, cull=cull, dtype=dtype))
        assert len(got) == len(mats)
        seen = 0
        for m, (d, st) in zip(mats, got):
            want, wst = rasterize_depth(vv, tt, m, (70, 90), samples=samples, cull=cull, dtype=dtype)
            assert d.dtype == want.dtype and d.tobytes() == want.tobytes() and st == wst
            seen += int((d < 1).any())
        assert st.nonfinite > 0 and st.degenerate > 0 and seen >= 2


def test_depth_views_refuse_bad_matrices():
    from moments_ref.scene.raster import rasterize_depth_views

    v = np.array([[-1, -1, 0], [1, -1, 0], [-1, 1, 0]], float)
    for bad in (np.eye(4), np.zeros((2, 3, 4)), np.full((1, 4, 4), np.nan)):
        with pytest.raises(InputError, match="clip_from_worlds"):
            next(rasterize_depth_views(v, [[0, 1, 2]], bad, 4))


# ---------------------------------------------------------------------------
# The tile path (scene/raster/_tiles.py): large triangles drawn tile by tile


def _all_tiled(monkeypatch):
    """Send every triangle whose box allows it through the tile path (not only large ones)."""
    monkeypatch.setattr(raster._tiles, "TILE_MIN_BOX", 1)
    monkeypatch.setattr(raster._tiles, "TILE_MIN_INRADIUS", 0.0)


@st.composite
def tile_scenes(draw):
    # Maps of a few tiles (sides not multiples of the tile), triangles on the 1/16-pixel
    # grid (samples on edges), quads split along a diagonal (shared edges), slivers and
    # repeated vertices, vertices beyond the map (clipped boxes).
    h, w = draw(st.integers(4, 13)), draw(st.integers(4, 13))
    samples = draw(st.sampled_from([1, 4, 8]))
    tris = _grid_tris(draw, h, w, draw(st.integers(1, 3)))
    if draw(st.booleans()):  # a quad: two triangles sharing their diagonal
        q = _grid_tris(draw, h, w, 1)[0] + _grid_tris(draw, h, w, 1)[0][:1]
        tris += [[q[0], q[1], q[2]], [q[0], q[2], q[3]]]
    if draw(st.booleans()):  # a sliver: the third vertex just off the first edge
        a, b = _grid_tris(draw, h, w, 1)[0][:2]
        tris.append([a, b, ((a[0] + b[0]) / 2 + 1e-3, (a[1] + b[1]) / 2, a[2])])
    if draw(st.booleans()):  # degenerate: a repeated vertex
        a, b = _grid_tris(draw, h, w, 1)[0][:2]
        tris.append([a, b, a])
    return h, w, samples, tris


@given(tile_scenes(), st.sampled_from(["none", "back"]))
@settings(max_examples=40, deadline=None)
def test_tile_path_matches_brute_force(scene, cull):
    h, w, samples, tris = scene
    ref, count = ref_coverage_depth(tris, h, w, samples, cull)
    v, t = _mesh(tris)
    with pytest.MonkeyPatch.context() as mp:
        _all_tiled(mp)
        got, stats = rasterize_depth(v, t, np.eye(4), (h, w), samples=samples, cull=cull)
    np.testing.assert_array_equal(got < 1, count > 0)
    np.testing.assert_allclose(got, ref, rtol=0, atol=2e-7)
    assert stats.samples_covered == count.sum()


def _big_scene():
    # A large triangle, a quad sharing a diagonal, and a sliver, on a map whose sides are
    # not multiples of the tile, with vertices beyond the map.
    tris = [[(-1.2, -0.9, -0.4), (0.95, -1.1, 0.3), (0.1, 1.3, 0.8)],
            [(-0.8, -0.8, 0.1), (0.7, -0.75, -0.2), (0.75, 0.6, 0.0)],
            [(-0.8, -0.8, 0.1), (0.75, 0.6, 0.0), (-0.7, 0.65, 0.5)],
            [(-0.9, 0.9, -0.5), (0.9, -0.85, 0.5), (0.905, -0.84, 0.5)]]
    return tris, 27, 22


@pytest.mark.parametrize("samples", [1, 4, 8])
def test_tile_path_is_taken_and_matches_brute_force(monkeypatch, samples):
    tris, h, w = _big_scene()
    ref, count = ref_coverage_depth(tris, h, w, samples)
    covered = []
    draw = raster._tiles.draw_tiles
    monkeypatch.setattr(raster, "draw_tiles", lambda *a: covered.append(draw(*a)) or covered[-1])
    monkeypatch.setattr(raster._tiles, "TILE_MIN_INRADIUS", 1.0)
    got, stats = rasterize_depth(*_mesh(tris), np.eye(4), (h, w), samples=samples)
    assert covered and covered[0] > count.sum() // 2  # most samples went through tiles
    np.testing.assert_array_equal(got < 1, count > 0)
    np.testing.assert_allclose(got, ref, rtol=0, atol=2e-7)
    assert stats.samples_covered == count.sum()


def test_tile_path_mutants_fail(monkeypatch):
    # Power: partial tiles drawn without their coverage mask, or every tile treated as
    # partial with a mask shifted by a column, give a different map.
    tris, h, w = _big_scene()
    ref, count = ref_coverage_depth(tris, h, w, 4)
    v, t = _mesh(tris)
    monkeypatch.setattr(raster._tiles, "TILE_MIN_INRADIUS", 1.0)
    masks = raster._tiles._tile_masks
    for mutant in (lambda *a: np.ones_like(masks(*a)),
                   lambda lo, cnt, j, q, x0: masks(lo, cnt, j, q, x0 + 1)):
        monkeypatch.setattr(raster._tiles, "_tile_masks", mutant)
        got, _ = rasterize_depth(v, t, np.eye(4), (h, w), samples=4)
        assert not np.array_equal(got < 1, count > 0)


def _bench_cases_small():
    from moments_ref.scene import load_scene
    from moments_ref.tools.bench._cases import MID_EXTENT

    v, t = raster.small_triangles(300, 384, MID_EXTENT, np.random.default_rng(0))
    yield "mid", v, t, np.eye(4), 384
    m = load_scene("railing").occluder_mesh(translucent=False)
    yield "railing", m.vertices, m.triangles, load_scene("railing").light_clip_from_world(), 512


@pytest.mark.parametrize("all_tiled", [False, True])
def test_tile_path_is_the_span_path_bit_for_bit_on_the_bench_cases(monkeypatch, all_tiled):
    # The bench's mid-size and railing cases at a small size: the map with tiles and the
    # map with every sample through the spans (raster._TILES = False) byte for byte.
    if all_tiled:
        _all_tiled(monkeypatch)
    for name, v, t, vp, size in _bench_cases_small():
        for dtype in (np.float32, np.float64):
            got, s1 = rasterize_depth(v, t, vp, size, samples=4, dtype=dtype)
            monkeypatch.setattr(raster, "_TILES", False)
            want, s2 = rasterize_depth(v, t, vp, size, samples=4, dtype=dtype)
            monkeypatch.setattr(raster, "_TILES", True)
            assert got.tobytes() == want.tobytes(), (name, dtype)
            assert s1 == s2 and s1.samples_covered > 0


def test_tile_path_does_not_depend_on_batch_and_piece_sizes(monkeypatch):
    # Pieces of 4 and 8 rows (boxes cut into several, the first one's rows above the box
    # masked), one piece per group and batches of 3 tiles give the map of the defaults.
    tris, h, w = _big_scene()
    v, t = _mesh(tris)
    _all_tiled(monkeypatch)
    want, s1 = rasterize_depth(v, t, np.eye(4), (h, w), samples=4)
    for rows in (4, 8):
        monkeypatch.setattr(raster._tiles, "_DENSE_ROWS", rows)
        monkeypatch.setattr(raster._tiles, "_ROW_BUDGET", 1)
        monkeypatch.setattr(raster._tiles, "TILE_BATCH", 3)
        got, s2 = rasterize_depth(v, t, np.eye(4), (h, w), samples=4)
        assert got.tobytes() == want.tobytes() and s1 == s2


def _core_samples(monkeypatch):
    """Record the samples each call of the tile path's dense cores draws."""
    drawn = []
    draw = raster._tiles._draw_cores
    monkeypatch.setattr(raster._tiles, "_draw_cores", lambda *a: drawn.append(draw(*a)) or drawn[-1])
    return drawn


@given(tile_scenes(), st.sampled_from([1, 2]))
@settings(max_examples=30, deadline=None)
def test_tile_cores_match_brute_force(scene, core_min):
    # Every piece's core drawn as a dense block down to one tile wide, on the tile scenes.
    h, w, samples, tris = scene
    ref, count = ref_coverage_depth(tris, h, w, samples)
    with pytest.MonkeyPatch.context() as mp:
        _all_tiled(mp)
        mp.setattr(raster._tiles, "CORE_MIN_TILES", core_min)
        got, stats = rasterize_depth(*_mesh(tris), np.eye(4), (h, w), samples=samples)
    np.testing.assert_array_equal(got < 1, count > 0)
    np.testing.assert_allclose(got, ref, rtol=0, atol=2e-7)
    assert stats.samples_covered == count.sum()


@pytest.mark.parametrize("samples", [1, 4, 8])
@pytest.mark.parametrize("block", [None, 1])
def test_tile_cores_are_the_span_path_bit_for_bit(monkeypatch, samples, block):
    # Large overlapping triangles with random depths on a map whose sides are not multiples
    # of the tile: most inside tiles lie in cores, and the map is the spans' byte for byte,
    # with the cores in blocks of the default size and in blocks of one tile column.
    if block is not None:
        monkeypatch.setattr(raster._tiles, "CORE_BLOCK", block)
    rng = np.random.default_rng(samples)
    v = rng.uniform(-1.5, 1.5, (60, 3))
    v[:, 2] = rng.uniform(-0.9, 0.9, 60)
    t = np.arange(60).reshape(20, 3)
    for dtype in (np.float32, np.float64):
        drawn = _core_samples(monkeypatch)
        got, s1 = rasterize_depth(v, t, np.eye(4), (203, 166), samples=samples, dtype=dtype)
        monkeypatch.setattr(raster, "_TILES", False)
        want, s2 = rasterize_depth(v, t, np.eye(4), (203, 166), samples=samples, dtype=dtype)
        monkeypatch.setattr(raster, "_TILES", True)
        assert sum(drawn) > s1.samples_covered // 3  # the cores hold a large share
        assert got.tobytes() == want.tobytes() and s1 == s2


def test_tile_core_mutants_fail(monkeypatch):
    # Power: a core drawn one tile column narrower or from one tile row lower (its tiles
    # still skipped by the enumeration) leaves samples undrawn.
    tris, h, w = _big_scene()
    v, t = _mesh(tris)
    _all_tiled(monkeypatch)
    monkeypatch.setattr(raster._tiles, "CORE_MIN_TILES", 1)
    want, _ = rasterize_depth(v, t, np.eye(4), (h, w), samples=4)
    cores = raster._tiles._cores
    for shift in ((0, 0, 0, -1), (1, 0, 0, 0)):
        def mutant(has, ta, tb, shift=shift):
            (j, qa, qb, ca, cb), ca_rows, cw = cores(has, ta, tb)
            return (j, qa + shift[0], qb + shift[1], ca + shift[2], cb + shift[3]), ca_rows, cw
        monkeypatch.setattr(raster._tiles, "_cores", mutant)
        got, _ = rasterize_depth(v, t, np.eye(4), (h, w), samples=4)
        assert got.tobytes() != want.tobytes(), shift


@pytest.mark.parametrize("samples", [1, 4, 8])
def test_tile_path_is_the_span_path_on_a_clipped_perspective_scene(monkeypatch, samples):
    # Triangles crossing the near plane and the map's borders, some with depths leaving
    # [-1, 1] (those stay on the span path), every other one tiled where its box allows.
    rng = np.random.default_rng(11)
    v = rng.uniform(-3, 3, (600, 3))
    t = np.arange(600).reshape(200, 3)
    vp = perspective(70, 1.3, 0.5, 12) @ look_at((0, 0, 4), (0, 0, 0), (0, 1, 0))
    _all_tiled(monkeypatch)
    covered = []
    draw = raster._tiles.draw_tiles
    monkeypatch.setattr(raster, "draw_tiles", lambda *a: covered.append(draw(*a)) or covered[-1])
    got, s1 = rasterize_depth(v, t, vp, (61, 75), samples=samples)
    monkeypatch.setattr(raster, "_TILES", False)
    want, s2 = rasterize_depth(v, t, vp, (61, 75), samples=samples)
    assert sum(covered) > 0 and got.tobytes() == want.tobytes() and s1 == s2


def test_setup_rewrites_keep_the_values_bit_for_bit():
    # _clip's near-plane distance (z + w) + 0.0 is the value of sum(k * attr[j]) = (0 + 1 z) + 1 w,
    # signed zeros included; _boxes' ceiling division (a + 255) >> 8 is -((-a) >> 8). Exhaustive
    # over special values and over integers around multiples of 256 (negative ones too).
    # Power: without the + 0.0, (-0) + (-0) keeps its sign and the first check fails.
    vals = np.array([0.0, -0.0, 1.0, -1.0, 5e-324, -5e-324, 1e308, -1e308, np.inf, -np.inf, 0.5, -0.5])
    z, w = np.meshgrid(vals, vals)
    with np.errstate(invalid="ignore", over="ignore"):
        want = sum(k * a for a, k in ((z, 1), (w, 1)))
        got = np.add(z, w)
        got += 0.0
        bare = np.add(z, w)
    assert want.tobytes() == got.tobytes()
    assert want.tobytes() != bare.tobytes()
    a = np.arange(-5 * 256 - 3, 5 * 256 + 4, dtype=np.int64)
    np.testing.assert_array_equal((a + 255) >> 8, -((-a) >> 8))
    np.testing.assert_array_equal((a + 255) >> 8, np.ceil(a / 256).astype(np.int64))


@pytest.mark.parametrize("samples", [1, 4, 8])
def test_small_boxes_give_the_maps_and_fragments_of_the_dense_bounds(monkeypatch, samples):
    # Boxes of up to 2 x 2 pixels are tested sample by sample against their three edges
    # (_spans._small_boxes; 1x maps by default, here 4x and 8x too) instead of going through
    # _rect_bounds: on tiny triangles
    # (boxes of one to four pixels, samples on edges: vertices on the 1/16 pixel grid) mixed with
    # larger ones, maps (float32 and float64) and fragments must be those of the dense bounds, byte
    # for byte, and the path must be taken for every box shape. Mutants: the third edge's test
    # dropped, the second pixel column's samples dropped, or (4x, 8x) the sample offsets dropped, must fail.
    from moments_ref.scene.raster import _spans as spans

    monkeypatch.setattr(spans, "_SMALL_SAMPLES", (1, 4, 8))
    rng = np.random.default_rng(5)
    v, t = raster.small_triangles(3000, 48, 1.2, rng)
    v2, t2 = raster.small_triangles(60, 48, 9.0, rng)
    v = np.concatenate([v, v2])
    v[:, :2] = np.round(v[:, :2] * 24 * 16) / (24 * 16)  # vertices on a 1/16 pixel grid
    t = np.concatenate([t, t2 + 3 * 3000])
    real = spans._small_boxes
    calls = []

    def counting(*a):
        calls.extend(zip(a[7].tolist(), a[8].tolist()))  # (rows, columns) of every box
        return real(*a)

    monkeypatch.setattr(spans, "_small_boxes", counting)
    got = {}
    for single in (False, True):
        monkeypatch.setattr(spans, "_SMALL", 1 if single else 0)
        maps = [rasterize_depth(v, t, np.eye(4), 48, samples=samples, dtype=dt) for dt in (np.float32, np.float64)]
        got[single] = maps, raster.rasterize_fragments(v, t, np.eye(4), 48, samples=samples)
    assert set(calls) == {(1, 1), (1, 2), (2, 1), (2, 2)}
    (m0, f0), (m1, f1) = got[False], got[True]
    for (d0, s0), (d1, s1) in zip(m0, m1):
        assert d0.tobytes() == d1.tobytes() and s0 == s1
    for name in ("position", "depth", "texel", "sample", "triangle"):
        assert getattr(f0[0], name).tobytes() == getattr(f1[0], name).tobytes()
    assert f0[1] == f1[1] and len(f0[0]) > 300

    def mutant(kind):
        def small(s, tri, A3, B3, base3, c0, r0, nr, nc, sx, sy, w=None):
            if kind == "offsets":
                return real(s, tri, A3, B3, base3, c0, r0, nr, nc, sx * 0, sy * 0, w)
            if kind == "column":  # boxes of two columns drawn as one
                return real(s, tri, A3, B3, base3, c0, r0, nr, np.minimum(nc, 1), sx, sy, w)
            return real(s, tri, A3[[0, 1, 1]], B3[[0, 1, 1]], base3[[0, 1, 1]], c0, r0, nr, nc, sx, sy, w)
        return small

    for kind in ("edge", "column", "offsets") if samples > 1 else ("edge", "column"):  # 1x: offset 0
        monkeypatch.setattr(spans, "_small_boxes", mutant(kind))
        assert rasterize_depth(v, t, np.eye(4), 48, samples=samples)[0].tobytes() != m0[0][0].tobytes()
