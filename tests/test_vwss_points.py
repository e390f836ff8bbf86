"""VWSS light samples and point generation (VWSS §3.1, Eqs. (1)-(3))."""

import math
from fractions import Fraction
from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import given, strategies as st

from moments_ref import InputError
from moments_ref.scene.raster import project_points, rasterize_depth, rasterize_fragments
from moments_ref.scene import AreaLight, box, torus_knot
from moments_ref.techniques.vwss.lights import depth_range, light_views, poisson_disk
from moments_ref.techniques.vwss.points import center_view, enlarged_view, generate_points, naive_points, source_view


def _light(w=1.2, h=0.8, fov=90):
    return AreaLight(center=(0.0, 4.0, 0.0), normal=(0.0, -1.0, 0.0), width=w, height=h, up=(0, 0, -1), fov=fov)


# --- Eqs. (1) and (3) against hand computation -------------------------------------------------

def test_enlarged_view_by_hand():
    # 1.2 x 0.8 light, 90 degrees: d = 1.2 / (2 tan 45) = 0.6; m (zn + d) / zn = 1024 * 2.4 / 1.8 = 1365.33 -> 1366
    d, res = enlarged_view(1.2, 0.8, math.pi / 2, math.pi / 2, 1.8, 1024)
    assert d == pytest.approx(0.6, rel=1e-15)
    assert res == 1366
    # max of the two fovs is used: 60 and 90 degrees -> the 90 degree one
    assert enlarged_view(1.2, 0.8, math.pi / 3, math.pi / 2, 1.8, 1024)[0] == pytest.approx(0.6)
    # 60 degrees: d = 0.6 / tan 30 = 1.0392...
    d60, _ = enlarged_view(0.8, 1.2, math.pi / 3, math.pi / 3, 1.0, 512)
    assert d60 == pytest.approx(0.6 / math.tan(math.pi / 6), rel=1e-14)
    # exact integers do not round up by a float error: zn = d doubles the side
    assert enlarged_view(1.0, 0.5, math.pi / 2, math.pi / 2, 0.5, 1024)[1] == 2048
    assert enlarged_view(1.0, 0.5, math.pi / 2, math.pi / 2, 0.5, (256, 512))[1] == (512, 1024)


@given(st.integers(1, 20), st.integers(1, 20), st.integers(1, 9), st.integers(1, 40), st.integers(1, 4096))
def test_enlarged_view_matches_exact_rational(w10, h10, q10, zn10, m):
    # fov = 2 atan(q) makes tan(fov / 2) = q rational, so Eqs. (1) and (3) are exact fractions.
    w, h, q, zn = Fraction(w10, 10), Fraction(h10, 10), Fraction(q10, 4), Fraction(zn10, 10)
    fov = 2 * math.atan(float(q))
    d_exact = max(w, h) / (2 * q)
    res_exact = math.ceil(m * (zn + d_exact) / zn)
    d, res = enlarged_view(float(w), float(h), fov, fov * 0.5, float(zn), m)
    assert d == pytest.approx(float(d_exact), rel=1e-12)
    assert res == res_exact


@pytest.mark.parametrize("bad", [dict(width=0.0), dict(height=-1.0), dict(fov_v=0.0), dict(fov_h=math.pi),
                                 dict(fov_v=float("nan")), dict(near=0.0), dict(base_resolution=0),
                                 dict(base_resolution=2.5)])
def test_enlarged_view_bad_input(bad):
    args = dict(width=1.0, height=1.0, fov_v=1.0, fov_h=1.0, near=1.0, base_resolution=64)
    args.update(bad)
    with pytest.raises(InputError):
        enlarged_view(**args)


# --- light samples ---------------------------------------------------------------------------

def test_light_samples_deterministic_and_on_the_light():
    light = _light()
    a = light_views(light, 24, 1.0, 5.0, seed=3)
    b = light_views(light, 24, 1.0, 5.0, seed=3)
    c = light_views(light, 24, 1.0, 5.0, seed=4)
    assert np.array_equal(a.positions, b.positions) and not np.array_equal(a.positions, c.positions)
    assert len(a) == 24 and a.clip_from_world.shape == (24, 4, 4)
    # on the rectangle: in its plane, within its half sides
    rel = a.positions - light.center
    assert np.allclose(rel @ light.normal, 0, atol=1e-12)
    assert np.all(np.abs(rel @ light.tangent) <= light.width / 2 + 1e-12)
    assert np.all(np.abs(rel @ light.bitangent) <= light.height / 2 + 1e-12)
    # each eye projects to w = 0 (it is the eye) and a point 2 units along the normal to the centre of its map
    for i in range(len(a)):
        xy, z = project_points(a.positions[i] + 2 * light.normal, a.clip_from_world[i], 64)
        assert np.allclose(xy, 32, atol=1e-9)


def test_poisson_disk_min_distance():
    uv = poisson_disk(128, seed=1)
    d = np.linalg.norm(uv[:, None] - uv[None], axis=-1) + np.eye(128)
    # Poisson-disk: far from clumping; iid uniform points would have min distance ~ 1/128
    assert d.min() > 0.3 / math.sqrt(128)
    assert uv.shape == (128, 2) and uv.min() >= 0 and uv.max() < 1


def test_light_bad_input():
    light = _light()
    with pytest.raises(InputError):
        AreaLight(center=(0, 4, 0), normal=(0, -1, 0), width=0.0, height=1.0)
    zero = SimpleNamespace(center=light.center, normal=light.normal, width=0.0, height=1.0,
                           tangent=light.tangent, bitangent=light.bitangent, fov=90.0)
    with pytest.raises(InputError, match="area"):
        light_views(zero, 4, 1.0, 5.0)
    for fov in (0.0, -0.1, math.pi, 4.0):
        with pytest.raises(InputError, match="fov"):
            light_views(light, 4, 1.0, 5.0, fov=fov)
    with pytest.raises(InputError):
        light_views(light, 4, 5.0, 1.0)
    with pytest.raises(InputError):
        light_views(light, 0, 1.0, 5.0)


# --- the source view (Eq. (2)) ---------------------------------------------------------------

@given(st.floats(0.1, 3.0), st.floats(0.1, 3.0), st.floats(20, 150), st.floats(0.05, 2.0))
def test_source_view_contains_light_and_all_sample_frustums(w, h, fov_deg, near):
    light = _light(w, h, fov_deg)
    ls = light_views(light, 6, near, near + 5.0, seed=0)
    src = source_view(ls, 64)
    # the light rectangle lies on the source's near plane (NDC z = -1), inside the frustum, touching it
    hom = np.c_[light.corners(), np.ones(4)] @ src.clip_from_world.T
    ndc = hom[:, :3] / hom[:, 3:]
    assert np.allclose(ndc[:, 2], -1, atol=1e-9)
    assert np.all(np.abs(ndc[:, :2]) <= 1 + 1e-9)
    assert np.abs(ndc[:, :2]).max() == pytest.approx(1, abs=1e-9)
    # every light-sample frustum is inside the source frustum: corners of the samples' frustums
    inv = np.linalg.inv(ls.clip_from_world)
    cube = np.array([[x, y, z, 1] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
    world = np.einsum("vij,cj->vci", inv, cube)
    world = world[..., :3] / world[..., 3:]
    hs = np.c_[world.reshape(-1, 3), np.ones(world.shape[0] * 8)] @ src.clip_from_world.T
    ns = hs[:, :3] / hs[:, 3:]
    assert np.all(hs[:, 3] > 0)
    assert np.all(np.abs(ns) <= 1 + 1e-7)


def test_source_view_mutant_is_caught():
    # Power of the geometric check: a source eye moved back by only half of d cuts off the light's corners.
    light = _light(1.2, 0.8, 90)
    ls = light_views(light, 4, 1.0, 6.0)
    src = source_view(ls, 64)
    from moments_ref.scene.raster import look_at, perspective
    eye = light.center - 0.5 * src.distance * light.normal
    vp = perspective(90, 1, 0.5 * src.distance, 6.0) @ look_at(eye, eye + light.normal, light.bitangent)
    hom = np.c_[light.corners(), np.ones(4)] @ vp.T
    assert np.abs(hom[:, :2] / hom[:, 3:]).max() > 1.5


# --- points ----------------------------------------------------------------------------------

def _knot():
    k = torus_knot(p=2, q=3, radius=0.8, tube=0.15, segments=200, sides=12)
    return k.vertices + np.array([0.0, 2.0, 0.0]), k.triangles


def test_points_are_all_front_fragments_and_naive_is_nearest():
    v, t = _knot()
    light = _light()
    near, far = depth_range(light, v)
    ls = light_views(light, 4, near, far)
    src = source_view(ls, 64)
    pc = generate_points(v, t, src)
    frags, _ = rasterize_fragments(v, t, src.clip_from_world, src.resolution, cull="back")
    assert len(pc) == len(frags) and pc.positions.dtype == np.float32
    assert np.array_equal(pc.positions, frags.position)
    # no culling adds the back faces: about twice as many for a closed mesh
    pn = generate_points(v, t, src, cull_back_faces=False)
    assert 1.5 < len(pn) / len(pc) < 2.5
    # naive: one point per covered texel, lying on the depth-tested surface
    nv = naive_points(v, t, src)
    dmap, _ = rasterize_depth(v, t, src.clip_from_world, src.resolution, cull="back", dtype=np.float64)
    assert len(nv) == np.count_nonzero(dmap < 1)
    xy, z = project_points(nv.positions.astype(np.float64), src.clip_from_world, src.resolution)
    row, col = np.floor(xy[:, 1]).astype(int), np.floor(xy[:, 0]).astype(int)
    assert np.allclose(z, dmap[row, col, 0], atol=1e-5)
    assert len(np.unique(row * src.resolution + col)) == len(nv)


def test_center_view_is_the_plain_warping_source():
    light = _light()
    ls = light_views(light, 4, 1.0, 5.0)
    c = center_view(ls, 128)
    assert c.resolution == 128 and c.distance == 0 and np.array_equal(c.clip_from_world, ls.center_clip_from_world())


def test_poisson_disk_covers_the_whole_light():
    # Mutant seen: the first n points of a larger Bridson fill cluster around its start point.
    for n in (8, 24, 128):
        uv = poisson_disk(n, seed=0)
        assert np.all(np.abs(uv.mean(0) - 0.5) < 0.12), n
        quad = (uv[:, 0] > 0.5) * 2 + (uv[:, 1] > 0.5)
        assert np.bincount(quad, minlength=4).min() >= n // 8


def test_poisson_disk_cache_cannot_be_corrupted_by_callers():
    from moments_ref.techniques.vwss import lights
    from moments_ref.techniques.vwss.shading import _tap_pattern

    fresh = lights._poisson_disk.__wrapped__(24, 5)  # the fill without the cache
    a = poisson_disk(24, seed=5)
    assert np.array_equal(a, fresh) and a.flags.writeable
    a[:] = -1.0  # a caller writing into its result
    b = poisson_disk(24, seed=5)
    assert b is not a and np.array_equal(b, fresh)
    ls = light_views(_light(), 24, 1.0, 5.0, seed=5)
    ls.uv[:] = 0.0  # nor through LightSamples.uv
    assert np.array_equal(light_views(_light(), 24, 1.0, 5.0, seed=5).uv, fresh)
    assert np.array_equal(poisson_disk(24.0, seed=5.0), fresh)  # same key for equal numbers
    taps = _tap_pattern(24, 5)
    assert not taps.flags.writeable and np.array_equal(taps, fresh * 2 - 1)
    with pytest.raises(ValueError):
        taps[0, 0] = 0.0


def test_stored_fills_are_scipys_and_need_no_scipy_stats():
    from moments_ref.techniques.vwss import lights

    # The fills stored with the package equal scipy's Bridson fills bit for bit, and a stored pair is
    # served without importing scipy.stats (a fresh interpreter).
    import subprocess
    import sys

    stored = lights._stored_fills()
    assert sorted(stored) == sorted(lights.STORED_FILLS)
    for (k, seed), uv in stored.items():
        assert uv.shape == (k, 2) and not uv.flags.writeable
        assert np.array_equal(uv, lights._scipy_fill(k, seed)), (k, seed)
    code = ("import sys; from moments_ref.techniques.vwss.lights import poisson_disk; "
            "poisson_disk(24, 0); poisson_disk(512, 1000); print('scipy.stats' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "False"
