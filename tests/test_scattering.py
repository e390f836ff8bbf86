"""Prefiltered single scattering (moments_ref.techniques.scattering) checked independently.

References: hand-computed spherical coordinates, the closed-form depth of a plane
seen from the camera, brute-force means of piecewise-constant rows, the exact
moments of two-point distributions (power_moments), ray marching with many
samples, and the unfiltered epipolar integral computed by brute force.

Stated errors (measured, see the report): on the shipped scene at 1/8 camera
resolution (80×45), a 128² shadow map and a 64×128 epipolar map, the RMSE of the
normalized scattering term against ray marching with 1024 samples is
SCENE_RMSE_6M_MEASURED for scattering_6m; the test allows SCENE_RMSE_6M.
"""

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from moments_ref import InputError
from moments_ref.affine import decode_r10g10b10a2, encode_r10g10b10a2
from moments_ref.moments import power_moments
from moments_ref.scene import load_scene
from moments_ref.techniques import scattering as sc
from moments_ref.techniques.scattering.epipolar import _bilinear_wrap_rows
from moments_ref.techniques.scattering.rays import pixel_epipolar

SCENE_RMSE_6M_MEASURED = 0.018  # scattering_6m; 0.013 unfiltered; 0.045 ignoring all shadows
SCENE_RMSE_6M = 0.03


def _frame(eye=(0.0, 0.0, -0.5), light=(0.0, 0.0, 1.0), rho_max=1.0, size=(16, 32)):
    return sc.epipolar_frame(np.array(eye), np.array(light), rho_max, size)


# ---------------------------------------------------------------------------
# geometry


def test_known_point_maps_to_row_column_depth():
    f = _frame(eye=(1.0, 2.0, 3.0), light=(0, 0, 1), rho_max=4.0, size=(8, 16))
    # Offset (0, 2, 2) from the eye: 2 from the light axis, azimuth 90° (e2 = y for light +z),
    # 2 along the light, inclination 45° -> depth 1 − 2·(π/4)/π = 0.5.
    phi, rho, theta, a = sc.epipolar_coordinates([1.0, 4.0, 5.0], f)
    assert np.allclose(f.e1, [1, 0, 0]) and np.allclose(f.e2, [0, 1, 0])
    assert phi == pytest.approx(np.pi / 2) and rho == pytest.approx(2.0) and a == pytest.approx(2.0)
    assert theta == pytest.approx(np.pi / 4)
    assert sc.epipolar_depth(theta) == pytest.approx(0.5)
    rows, cols = f.size
    assert phi / (2 * np.pi) * rows == pytest.approx(2.0)  # row coordinate (row 2 starts here)
    assert rho / f.rho_max * cols == pytest.approx(8.0)  # column coordinate
    # A point straight down the light (θ = 0) is deepest (z = 1); straight up the light z = −1.
    assert sc.epipolar_depth(sc.epipolar_coordinates([1.0, 2.0, 4.0], f)[2]) == pytest.approx(1.0)
    assert sc.epipolar_depth(sc.epipolar_coordinates([1.0, 2.0, 2.0], f)[2]) == pytest.approx(-1.0)


@given(st.lists(st.floats(-1, 1), min_size=3, max_size=3), st.lists(st.floats(-3, 3), min_size=3, max_size=3))
def test_coordinates_match_definition_for_any_light(light, p):
    light = np.array(light)
    if np.linalg.norm(light) < 1e-3:
        return
    f = sc.epipolar_frame(np.zeros(3), light, 1.0, (4, 4))
    l = light / np.linalg.norm(light)
    p = np.array(p)
    # orthonormal frame, whatever the light direction (no degenerate view direction)
    basis = np.stack([f.e1, f.e2, f.light])
    np.testing.assert_allclose(basis @ basis.T, np.eye(3), atol=1e-12)
    phi, rho, theta, a = sc.epipolar_coordinates(p, f)
    assert rho == pytest.approx(np.linalg.norm(p - (p @ l) * l), abs=1e-12)
    assert a == pytest.approx(p @ l, abs=1e-12)
    if np.linalg.norm(p) > 1e-6:
        assert theta == pytest.approx(math.acos(np.clip(p @ l / np.linalg.norm(p), -1, 1)), abs=1e-6)


def test_view_ray_is_a_row_and_shadow_test_is_a_depth_comparison():
    # Along one view ray the azimuth is constant (one row); the point where it crosses
    # light ray ρ is behind an occluder at offset a_occ on that light ray iff z_p > z_occ.
    f = _frame(eye=(0.0, 0.0, 0.0), light=(0.3, -0.2, 0.9))
    rng = np.random.default_rng(0)
    d = rng.standard_normal(3)
    d /= np.linalg.norm(d)
    t = np.linspace(0.1, 5, 50)
    phi, rho, theta, a = sc.epipolar_coordinates(t[:, None] * d, f)
    assert np.ptp(phi) < 1e-12 and np.ptp(theta) < 1e-12
    a_occ = rng.uniform(-3, 3, 50)
    z_occ = sc.epipolar_depth(np.arctan2(rho, a_occ))
    np.testing.assert_array_equal(a > a_occ, sc.epipolar_depth(theta) > z_occ)


# ---------------------------------------------------------------------------
# resampling


def test_unfiltered_resampling_of_a_plane():
    # clip_from_world = identity: NDC = world, the light travels along +z; occluder plane z = 0.2.
    f = _frame(eye=(0.05, -0.1, -0.5), rho_max=0.6, size=(16, 32))
    depth = np.full((64, 64, 1), 0.2, dtype=np.float32)
    b = sc.resample_unfiltered(depth, np.eye(4), f)
    rho = f.rho_max * (np.arange(32) + 0.5) / 32
    expected = 1 - 2 / np.pi * np.arctan2(rho, np.float32(0.2) - (-0.5))
    np.testing.assert_allclose(b[..., 0], np.broadcast_to(expected, (16, 32)), atol=1e-12)
    np.testing.assert_allclose(b[..., 5], b[..., 0] ** 6, atol=1e-12)  # six moments of one depth


def test_cleared_texels_never_shadow():
    f = _frame(rho_max=0.6)
    b = sc.resample_unfiltered(np.ones((32, 32, 4), np.float32), np.eye(4), f)
    assert (b[..., 0] == 1).all()


@pytest.mark.parametrize("d1, d2, v2", [(-0.3, 0.4, 0.3), (0.1, 0.5, 0.6), (-0.8, -0.7, 0.9)])
def test_filtered_resampling_is_exact_for_two_depths(d1, d2, v2):
    # A filter region holding exactly two depths: b1..b3 determine them (Algorithm 2), so the
    # six-moment vector is the exact one of the two converted depths.
    f = _frame(eye=(0.0, 0.1, -0.9), rho_max=0.7, size=(8, 16))
    m4 = np.broadcast_to(power_moments(np.array([d1, d2]), np.array([1 - v2, v2])), (32, 32, 4))
    b6 = sc.resample_filtered(m4, np.eye(4), f)
    rho = f.rho_max * (np.arange(16) + 0.5) / 16
    z = np.stack([1 - 2 / np.pi * np.arctan2(rho, d + 0.9) for d in (d1, d2)], axis=-1)
    exact = power_moments(z, np.array([1 - v2, v2]), n=6)
    np.testing.assert_allclose(b6, np.broadcast_to(exact, b6.shape), atol=1e-9)
    # mutant: swapped weights (v2, 1 − v2) are detected
    wrong = power_moments(z, np.array([v2, 1 - v2]), n=6)
    assert np.abs(b6[0] - wrong).max() > 1e-3


# ---------------------------------------------------------------------------
# prefix sums, quantization


@given(st.lists(st.floats(-1, 1), min_size=2, max_size=40), st.floats(0, 1))
def test_warped_lookup_gives_the_mean_over_the_ray(values, frac):
    m = np.array(values)
    cols = m.size
    x = frac * cols
    P = sc.prefix_means(m.reshape(1, cols, 1))[0, :, 0]
    u = sc.prefix_lookup_coordinate(x, cols)
    # the texture unit: linear interpolation between texel centres (clamped)
    got = np.interp(u, np.arange(cols) + 0.5, P)
    # brute force: full texels plus the partial one
    k = np.arange(cols)
    cover = np.clip(x - k, 0, 1)
    expected = (m * cover).sum() / x if x > 1e-12 else m[0]
    if x < 1:
        expected = m[0]  # the first texel covers [0, 1): the mean over [0, x] is m_0
    assert got == pytest.approx(expected, abs=1e-9)


def test_prefix_means_are_normalized():
    rng = np.random.default_rng(3)
    b = power_moments(rng.uniform(-1, 1, (4, 100, 1)), n=6)
    P = sc.prefix_means(b)
    np.testing.assert_allclose(P[:, -1], b.mean(axis=1), atol=1e-14)
    assert np.abs(P).max() <= 1  # no growth with the row length: fits UNORM after the basis


def test_quantization_round_trip():
    rng = np.random.default_rng(4)
    z, w = rng.uniform(-1, 1, (500, 3)), rng.uniform(0.1, 1, (500, 3))
    b = power_moments(z, w, n=6)
    q = sc.quantize6(b)
    np.testing.assert_array_equal(sc.quantize6(q), q)  # stored values are fixed points
    np.testing.assert_array_equal(encode_r10g10b10a2(q), encode_r10g10b10a2(b))
    assert np.abs(q - b).max() < 0.02  # 10 bits: 1/2046 per channel through the inverse basis
    assert np.abs(decode_r10g10b10a2(encode_r10g10b10a2(b)) - b).max() < 0.02


# ---------------------------------------------------------------------------
# the shipped scene, ray marching


@pytest.fixture(scope="module")
def small_scene():
    scene = load_scene("scattering")
    vp = scene.light_clip_from_world()
    depth, _ = scene.shadow_map(size=(128, 128), samples=4)
    rays = sc.camera_rays(scene, (80, 45))
    ref = sc.ray_march(depth, vp, scene.camera.eye, rays[0], 1024)
    return scene, (depth, vp), rays, ref


def test_ray_marching_converges(small_scene):
    scene, (depth, vp), rays, ref = small_scene
    t_max = rays[1]
    errs = [np.sqrt(np.mean(((sc.ray_march(depth, vp, scene.camera.eye, rays[0], n) - ref) / t_max) ** 2))
            for n in (8, 32, 128)]
    assert errs[0] > errs[1] > errs[2], errs
    assert errs[2] < 0.01, errs  # 128 samples ("ground truth" in the slides) are close, not converged


def _marched_by_definition(depth, vp, eye, dirs, t_end, n):
    """Per ray ``t_end · mean_k V(t_k)`` by the definition: every sample projected with
    ``raster.project_points``, its nearest texel's MSAA samples compared one by one
    (visible: ``o ≥ z`` or ``o ≥ FAR_NDC``; 1 outside the map). Also returns, per ray,
    whether a sample lies within 1e-9 of a texel edge or of a sample depth (where
    rounding may decide)."""
    from moments_ref.scene.raster import project_points

    h, w, _ = depth.shape
    out, close = np.empty(len(t_end)), np.zeros(len(t_end), bool)
    frac = (np.arange(n) + 0.5) / n
    for r in range(len(t_end)):  # loop over rays
        t = frac * t_end[r]
        xy, dz = project_points(eye + t[:, None] * dirs[r], vp, (h, w))
        col, row = np.floor(xy[:, 0]).astype(int), np.floor(xy[:, 1]).astype(int)
        ok = (col >= 0) & (col < w) & (row >= 0) & (row < h)
        occ = depth[np.clip(row, 0, h - 1), np.clip(col, 0, w - 1)].astype(np.float64)
        vis = np.where(ok, ((occ >= dz[:, None]) | (occ >= np.float32(sc.FAR_NDC))).mean(axis=1), 1.0)
        out[r] = t_end[r] * vis.mean()
        edge = np.minimum(np.abs(xy - np.round(xy)).min(axis=1), np.abs(occ - dz[:, None]).min(axis=1))
        close[r] = bool((edge < 1e-9).any())
    return out, close


def test_ray_march_against_brute_force_visibility(small_scene):
    # Every ray of a 40×22 camera, against the definition sample by sample (project_points).
    scene, (depth, vp), _, _ = small_scene
    cam_rays, _ = sc.camera_rays(scene, (40, 22))
    dirs, t_end = cam_rays.direction.reshape(-1, 3), cam_rays.t_end.reshape(-1)
    want, close = _marched_by_definition(depth, vp, scene.camera.eye, dirs, t_end, 48)
    got = sc.ray_march(depth, vp, scene.camera.eye, cam_rays, 48).reshape(-1)
    assert 0 < np.mean(want < t_end) < 1  # some rays are shadowed, some not
    off = got != want
    assert not (off & ~close).any(), np.flatnonzero(off & ~close)[:10]
    assert off.sum() <= 2


def test_ray_march_ties_and_outside():
    # A ray at constant light depth z = 0.5 (x direction, identity light matrix): samples
    # at exactly z are visible (o ≥ z), nearer ones occlude; points outside the map are lit.
    depth = np.array([[[0.5, 0.25, 0.5, 0.75]] * 4] * 4, np.float32)  # (4, 4, 4): one sample of 4 nearer
    ray = sc.CameraRays(np.array([[[1.0, 0.0, 0.0]]]), np.array([[1.0]]), np.ones((1, 1), bool), (1, 1))
    got = sc.ray_march(depth, np.eye(4), np.array([-0.999, 0.1, 0.5]), ray, 8)[0, 0]
    # samples at x = −0.999 + (k + ½)/8: all 8 inside [−1, 1): 3/4 visible each
    assert got == 0.75
    got = sc.ray_march(depth, np.eye(4), np.array([0.5, 0.1, 0.5]), ray, 8)[0, 0]
    # x = 0.5 + (k + ½)/8 leaves the map at x = 1 after 4 samples: (4 · 3/4 + 4) / 8
    assert got == (4 * 0.75 + 4) / 8


@given(st.integers(0, 2**32 - 1), st.sampled_from([1, 2, 3, 4, 8]), st.integers(1, 40))
def test_ray_march_random_maps(seed, s, n):
    # Random MSAA maps with cleared samples, rays leaving the map and a light view that is
    # not axis-aligned: equal to the definition (S = 3: to rounding of the mean of thirds).
    rng = np.random.default_rng(seed)
    h, w = rng.integers(1, 9, size=2)
    depth = rng.uniform(-1, 1, (h, w, s)).astype(np.float32)
    depth[rng.random(depth.shape) < 0.3] = 1.0
    vp = np.eye(4)
    vp[:3, :3] = np.linalg.qr(rng.normal(size=(3, 3)))[0] * 0.7
    vp[:3, 3] = rng.uniform(-0.3, 0.3, 3)
    dirs = rng.normal(size=(6, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    t_end = rng.uniform(0.1, 3.0, 6)
    eye = rng.uniform(-0.5, 0.5, 3)
    want, close = _marched_by_definition(depth, vp, eye, dirs, t_end, n)
    rays = sc.CameraRays(dirs.reshape(2, 3, 3), t_end.reshape(2, 3), np.ones((2, 3), bool), (3, 2))
    got = sc.ray_march(depth, vp, eye, rays, n).reshape(-1)
    ok = np.isclose(got, want, rtol=1e-14, atol=0) if s == 3 else got == want
    assert (ok | close).all(), (got, want)


@pytest.mark.parametrize("s", [1, 2, 3, 4, 8])
def test_sample_extremes_are_each_texels_nearest_and_farthest_sample(s):
    # The march's per-texel bounds against a sort of each texel's samples: the first and the
    # last, as float64; with +inf (empty samples, the border), ±0 and the ends of [−1, 1].
    from moments_ref.techniques.scattering.rays import _padded_samples, _sample_extremes

    rng = np.random.default_rng(s)
    special = rng.choice(np.array([-1.0, -0.0, 0.0, 0.25, 1.0, -0.5, 0.999], np.float32), (7, 9, s))
    depth = np.where(rng.random(special.shape) < 0.5, special, rng.uniform(-1, 1, special.shape).astype(np.float32))
    flat, _ = _padded_samples(depth)
    lo, hi = _sample_extremes(flat)
    ordered = np.sort(flat, axis=1)
    assert lo.dtype == hi.dtype == np.float64
    assert np.array_equal(lo, ordered[:, 0].astype(np.float64))
    assert np.array_equal(hi, ordered[:, -1].astype(np.float64))
    assert np.isinf(lo).any() and (lo < 1).any() and (hi == np.inf).any()


@pytest.mark.parametrize("seed", range(6))
def test_rays_over_empty_texels_skip_the_march_with_the_same_result(seed, monkeypatch):
    # Maps mostly empty with a few occupied blocks, rays from one eye in every direction: the rays
    # that ray_march counts lit without marching (no occupied texel between their first and last
    # sample's texel) give the bytes of marching every ray sample by sample; some rays take the
    # shortcut, some do not.
    from moments_ref.techniques.scattering import rays as rays_module

    rng = np.random.default_rng(seed)
    h, w, s = int(rng.integers(8, 40)), int(rng.integers(8, 40)), int(rng.choice([1, 4]))
    depth = np.ones((h, w, s), np.float32)
    for _ in range(3):
        r, c = rng.integers(0, h - 3), rng.integers(0, w - 3)
        depth[r:r + 3, c:c + 3] = rng.uniform(-1, 0.5, (3, 3, s))
    vp = np.eye(4)
    vp[:3, :3] = np.linalg.qr(rng.normal(size=(3, 3)))[0] * 0.8
    dirs = rng.normal(size=(60, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    rays = sc.CameraRays(dirs.reshape(6, 10, 3), rng.uniform(0.05, 2.5, (6, 10)), np.ones((6, 10), bool), (10, 6))
    eye = rng.uniform(-0.4, 0.4, 3)
    taken = []
    lit = rays_module._lit_throughout
    monkeypatch.setattr(rays_module, "_lit_throughout", lambda *a: taken.append(lit(*a)) or taken[-1])
    got = sc.ray_march(depth, vp, eye, rays, 37)
    monkeypatch.setattr(rays_module, "_lit_throughout", lambda occupied, a, b, t0, t1: np.zeros(t0.shape, bool))
    want = sc.ray_march(depth, vp, eye, rays, 37)
    assert np.array_equal(got, want)
    assert 0 < taken[0].sum() < taken[0].size


def test_six_moment_technique_close_to_reference(small_scene):
    scene, smap, rays, ref = small_scene
    t_max = rays[1]
    out = {}
    for name in ("scattering_6m", "scattering_6m_unfiltered"):
        r = sc.render(scene, name, epipolar_size=(64, 128), shadow_map=smap, rays=rays)
        s = r["scattering"]
        assert np.isfinite(s).all() and (s >= 0).all() and (s <= rays[0].t_end + 1e-9).all()
        assert ((r["lower"] <= r["shadow"] + 1e-6) & (r["shadow"] <= r["upper"] + 1e-6)).all()
        out[name] = np.sqrt(np.mean(((s - ref) / t_max) ** 2))
    assert out["scattering_6m"] <= SCENE_RMSE_6M, out
    # mutant: ignoring the shadows (all lit) is more than twice as far off
    all_lit = np.sqrt(np.mean(((rays[0].t_end - ref) / t_max) ** 2))
    assert all_lit > 2 * out["scattering_6m"] and all_lit > SCENE_RMSE_6M, (all_lit, out)


def test_moment_bounds_bracket_exact_epipolar_integral(small_scene):
    # Unquantized, unbiased float64 prefix means of the unfiltered map: the six-moment
    # bounds bracket the exact fraction of shadowed texels on the row prefix.
    from moments_ref.msm6 import shadow_bounds

    scene, (depth, vp), rays, _ = small_scene
    cam_rays, t_max = rays
    f = sc.epipolar_frame(scene.camera.eye, scene.light.direction, t_max, (64, 128), t_max)
    b = sc.resample_unfiltered(depth, vp, f)
    uv, z = pixel_epipolar(cam_rays, f)
    row = np.floor(uv[..., 1]).astype(int) % 64
    x = uv[..., 0]
    k = np.arange(128)
    cover = np.clip(x[..., None] - k, 0, 1)
    exact = ((b[..., 0][row] < z[..., None]) * cover).sum(-1) / np.maximum(x, 1e-12)
    exact = np.where(x < 1, (b[..., 0][row][..., 0] < z), exact)
    P = sc.prefix_means(b)
    u = sc.prefix_lookup_coordinate(x, 128)
    bb = _bilinear_wrap_rows(P, u, row + 0.5)  # the pixel's own row (no filtering across rows)
    lo, up = shadow_bounds(bb, z)
    assert (lo <= exact + 1e-6).all() and (exact <= up + 1e-6).all()


def test_view_along_the_light_is_clamped_not_garbage(small_scene):
    scene, smap, (cam_rays, t_max), _ = small_scene
    # Pixels looking exactly along ±ω_l (light parallel to the view direction).
    d = np.stack([scene.light.direction, -scene.light.direction]).reshape(1, 2, 3)
    rays = sc.CameraRays(d, np.full((1, 2), t_max), np.zeros((1, 2), bool), (2, 1))
    for name in ("scattering_6m", "scattering_6m_unfiltered"):
        r = sc.render(scene, name, epipolar_size=(16, 32), shadow_map=smap, rays=(rays, t_max))
        s = r["scattering"]
        assert np.isfinite(s).all() and (s >= 0).all() and (s <= t_max).all()


# ---------------------------------------------------------------------------
# bad input


def test_bad_input():
    with pytest.raises(InputError, match="light_direction"):
        sc.epipolar_frame(np.zeros(3), np.zeros(3), 1.0)
    with pytest.raises(InputError, match="finite"):
        sc.epipolar_frame(np.zeros(3), [np.nan, 0, 1], 1.0)
    with pytest.raises(InputError, match="rho_max"):
        sc.epipolar_frame(np.zeros(3), [0, 0, 1], 0.0)
    with pytest.raises(InputError, match="size"):
        sc.epipolar_frame(np.zeros(3), [0, 0, 1], 1.0, (1, 8))
    with pytest.raises(InputError, match="directional"):
        sc.render(load_scene("knot"))
    with pytest.raises(InputError, match="technique"):
        sc.render(load_scene("scattering"), "msm64")
    with pytest.raises(InputError, match="params"):
        sc.SCATTERING_6M.prepare(np.zeros((4, 4, 1), np.float32), {})
    with pytest.raises(InputError, match=r"depth_samples.*\(0, 1, 0\)"):
        sc.ray_march(np.array([[[0.5], [np.nan]]]), np.eye(4), np.zeros(3),
                     sc.CameraRays(np.zeros((1, 1, 3)), np.ones((1, 1)), np.ones((1, 1), bool), (1, 1)), 4)
    with pytest.raises(InputError, match="n_samples"):
        sc.ray_march(np.zeros((4, 4, 1)), np.eye(4), np.zeros(3),
                     sc.CameraRays(np.zeros((1, 1, 3)), np.ones((1, 1)), np.ones((1, 1), bool), (1, 1)), 0)
