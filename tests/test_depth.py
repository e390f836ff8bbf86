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
