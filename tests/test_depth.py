"""Depth conventions: each conversion against its definition on the depths themselves."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from moments_ref import InputError
from moments_ref.moments import power_moments
from moments_ref.scene import depth as D
from moments_ref.tools.strategies import depth_distributions


def test_depth_value_conversions_and_round_trips():
    z = np.array([-1.0, -0.25, 0.0, 0.5, 1.0])
    assert np.array_equal(D.z_unit_from_ndc(z), [0.0, 0.375, 0.5, 0.75, 1.0])
    assert np.array_equal(D.z_ndc_from_unit(D.z_unit_from_ndc(z)), z)
    u = np.array([0.0, 0.25, 1.0], np.float32)
    assert D.z_reversed_from_unit(u).dtype == np.float32
    assert np.array_equal(D.z_reversed_from_unit(u), [1.0, 0.75, 0.0])
    assert np.array_equal(D.z_unit_from_reversed(D.z_reversed_from_unit(u)), u)


@given(depth_distributions(max_points=6), st.sampled_from([(0.5, 0.5), (2.0, -1.0), (-1.0, 1.0), (0.3, -0.2)]))
def test_moments_affine_are_the_moments_of_the_mapped_depths(dist, so):
    z, w = dist
    s, o = so
    b = power_moments(z, w, n=6)
    direct = power_moments(s * z + o, w, n=6)
    # s z + o may leave [-1, 1] (2 z - 1 reaches -3): moments up to 3^6, error relative to them
    assert np.allclose(D.moments_affine(b, s, o), direct, rtol=1e-12, atol=1e-13)


@given(depth_distributions(max_points=4))
def test_named_moment_conversions(dist):
    z, w = dist
    b_ndc = power_moments(z, w)
    b_unit = power_moments((z + 1) / 2, w)
    assert np.allclose(D.moments_unit_from_ndc(b_ndc), b_unit, atol=1e-14, rtol=0)
    assert np.allclose(D.moments_ndc_from_unit(b_unit), b_ndc, atol=1e-14, rtol=0)
    b_rev = power_moments(1 - (z + 1) / 2, w)
    assert np.allclose(D.moments_reversed_from_unit(b_unit), b_rev, atol=1e-14, rtol=0)
    assert np.allclose(D.moments_unit_from_reversed(b_rev), b_unit, atol=1e-14, rtol=0)


def test_float32_moments_are_converted_in_float64_and_rounded_once():
    b = np.array([0.1, 0.2, 0.05, 0.1], np.float32)
    got = D.moments_unit_from_ndc(b)
    want = D.moments_unit_from_ndc(b.astype(np.float64)).astype(np.float32)
    assert got.dtype == np.float32 and np.array_equal(got, want)


def test_bad_moments_are_refused():
    with pytest.raises(InputError, match="b"):
        D.moments_unit_from_ndc(np.array([0.1, np.nan, 0.2, 0.3]))
    with pytest.raises(InputError, match="n >= 1"):
        D.moments_affine(np.zeros((3, 0)), 1.0, 0.0)


def test_window_from_ndc_puts_corners_and_centres_where_the_rasterizer_does():
    size = (4, 8)
    ndc = np.array([[-1.0, 1.0], [1.0, -1.0], [0.0, 0.0], [-1 + 1 / 8, 1 - 1 / 4]])
    xy = D.window_from_ndc(ndc, size)
    assert np.array_equal(xy, [[0, 0], [8, 4], [4, 2], [0.5, 0.5]])  # the last: centre of pixel (0, 0)
    assert np.allclose(D.ndc_from_window(xy, size), ndc)
    from moments_ref.scene.raster import orthographic, project_points

    m = orthographic(-1, 1, -1, 1, 0.5, 2.0)
    pts = np.array([[0.3, -0.4, -1.0]])
    xy_r, _ = project_points(pts, m, size)
    assert np.allclose(xy_r, D.window_from_ndc(np.array([[0.3, -0.4]]), size))


def test_window_conversions_keep_the_dtype_and_convert_in_place_alike():
    x = np.array([-1.0, -0.3, 0.0, 0.7, 1.0], np.float32)
    out = D.x_window_from_ndc(x, 640)
    assert out.dtype == np.float32 and np.array_equal(out, (x + np.float32(1)) * np.float32(320))
    buf = x.copy()
    assert D.x_window_from_ndc(buf, 640, out=buf) is buf and np.array_equal(buf, out)
    buf = x.copy()
    D.y_window_from_ndc(buf, 360, out=buf)
    assert np.array_equal(buf, D.y_window_from_ndc(x, 360)) and buf.dtype == np.float32
    # a width of W·2^8 gives coordinates in 1/256 pixel, exactly 256 times the pixel ones
    assert np.array_equal(D.x_window_from_ndc(x.astype(np.float64), 640 * 256),
                          D.x_window_from_ndc(x.astype(np.float64), 640) * 256)


def test_window_scale_is_the_derivative_of_the_window_transform():
    size = (90, 160)
    p0, step = np.array([0.25, -0.5]), np.array([0.5, 0.25])
    w0, w1 = D.window_from_ndc(p0, size), D.window_from_ndc(p0 + step, size)
    assert np.allclose(w1 - w0, np.array(D.window_scale(size)) * step, rtol=0, atol=1e-12)


def test_reversed_depth_is_one_minus_unit_depth():
    z = np.array([-1.0, -0.5, 0.0, 0.25, 1.0])
    r = D.z_reversed_from_ndc(z)
    assert np.array_equal(r, D.z_reversed_from_unit(D.z_unit_from_ndc(z)))  # dyadic values: exact
    assert np.array_equal(D.z_ndc_from_reversed(r), z)
    z32 = np.linspace(-1, 1, 101, dtype=np.float32)
    r32 = D.z_reversed_from_ndc(z32)
    assert r32.dtype == np.float32 and np.allclose(r32, (1 - z32.astype(np.float64)) / 2, atol=6e-8, rtol=0)
    assert np.allclose(D.z_ndc_from_reversed(r32), z32, atol=1.2e-7, rtol=0)
    assert D.z_reversed_from_ndc(0.5) == 0.25


@pytest.mark.parametrize("projection", ["perspective", "orthographic"])
def test_view_distance_inverts_the_projection_matrices(projection):
    """Points at known distances in front of the eye, projected by the rasterizer's own matrices."""
    from moments_ref.scene.raster import frustum, orthographic

    near, far = 0.3, 12.0
    m = (frustum(-0.2, 0.2, -0.1, 0.1, near, far) if projection == "perspective"
         else orthographic(-1, 1, -1, 1, near, far))
    d = np.linspace(near, far, 41)
    hom = np.c_[np.zeros((41, 2)), -d, np.ones(41)] @ m.T  # the eye looks along -z
    z = hom[:, 2] / hom[:, 3]
    assert z[0] == pytest.approx(-1) and z[-1] == pytest.approx(1)
    np.testing.assert_allclose(D.d_view_from_ndc(z, near, far, projection), d, rtol=1e-12)
    np.testing.assert_allclose(D.z_ndc_from_view(d, near, far, projection), z, rtol=0, atol=1e-12)
    with pytest.raises(InputError, match="projection"):
        D.d_view_from_ndc(z, near, far, "fisheye")


def test_warped_depths_are_evsms_exponentials():
    z = np.array([-1.0, -0.2, 0.0, 0.6, 1.0])
    assert np.allclose(D.warped_positive(z, 5.5), [np.exp(5.5 * v) for v in z], rtol=1e-15)
    assert np.allclose(D.warped_negative(z, 5.5), [-np.exp(-5.5 * v) for v in z], rtol=1e-15)
    assert np.all(np.diff(D.warped_negative(z, 5.5)) > 0)  # both warps increase with depth
    z32 = z.astype(np.float32)
    p32 = D.warped_positive(z32, 40.0)
    assert p32.dtype == np.float32 and np.array_equal(p32, np.exp(np.float32(40.0) * z32))


def test_unproject_inverts_project():
    from moments_ref.scene.raster import look_at, perspective, project_points, unproject_points

    m = perspective(50, 16 / 9, 0.5, 20) @ look_at((1, 2, 3), (0, 0, 0), (0, 1, 0))
    pts = np.random.default_rng(1).uniform(-1, 1, (50, 3))
    xy, z = project_points(pts, m, (90, 160))
    np.testing.assert_allclose(unproject_points(xy, z, m, (90, 160)), pts, atol=1e-9)


def test_old_matrix_names_still_work_with_a_deprecation_warning():
    """view_proj said neither frame: the matrices are clip_from_world now; the old spellings warn and forward."""
    from moments_ref.scene import load_scene
    from moments_ref.scene.raster import project_points, rasterize_depth
    from moments_ref.techniques.vwss import light_views

    sc = load_scene("knot")
    m = sc.light_clip_from_world()
    with pytest.warns(DeprecationWarning, match="Scene.shadow_view_proj is now Scene.light_clip_from_world"):
        assert np.array_equal(sc.shadow_view_proj(), m)
    with pytest.warns(DeprecationWarning, match="Camera.view_proj"):
        assert np.array_equal(sc.camera.view_proj(), sc.camera.clip_from_world())
    ls = light_views(sc.light, 2, 0.5, 5.0)
    with pytest.warns(DeprecationWarning, match="LightSamples.view_proj"):
        assert np.array_equal(ls.view_proj, ls.clip_from_world)
    with pytest.warns(DeprecationWarning, match="LightSamples.center_view_proj"):
        assert np.array_equal(ls.center_view_proj(), ls.center_clip_from_world())
    pts = sc.occluder.vertices[:5]
    with pytest.warns(DeprecationWarning, match=r"project_points\(view_proj=...\)"):
        old = project_points(pts, view_proj=m, size=64)
    new = project_points(pts, clip_from_world=m, size=64)
    assert all(np.array_equal(a, b, equal_nan=True) for a, b in zip(old, new))
    tri = np.array([[0, 1, 2]])
    v = np.array([[-0.5, -0.5, 0.0], [0.5, -0.5, 0.0], [0.0, 0.5, 0.0]])
    with pytest.warns(DeprecationWarning):
        assert np.array_equal(rasterize_depth(v, tri, view_proj=np.eye(4), size=8)[0],
                              rasterize_depth(v, tri, np.eye(4), 8)[0])
