"""golden.bilinear's building blocks against exact rational arithmetic written in the test.

The bilinear blend of four texels t00, t10, t01, t11 at fraction (fx, fy) is
(1 − fx)(1 − fy) t00 + fx (1 − fy) t10 + (1 − fx) fy t01 + fx fy t11 (a texture unit's order:
along x, then y); the filter's rounding allowance is FILTER_ULPS ulps of the largest texel
component; a b-bit filter's weights are the multiples of 2^-b at or next to the fraction.
"""

from __future__ import annotations

from fractions import Fraction

import numpy as np

from moments_ref.golden import bilinear
from moments_ref.golden.cases import CASES


def _exact(t, fx, fy):
    """The blend in Python's rationals, rounded once."""
    fx, fy = Fraction(fx), Fraction(fy)
    w = ((1 - fx) * (1 - fy), fx * (1 - fy), (1 - fx) * fy, fx * fy)
    return [float(sum(wk * Fraction(float(t[k][c])) for k, wk in enumerate(w))) for c in range(4)]


TEXELS = np.array([[0.0, 0.1, -0.3, 1.0,   1.0, 0.2, 0.3, 2.0,   2.0, 0.7, -0.9, 3.0,   4.0, 0.4, 0.5, -1.0],
                   [0.25, 0.5, 0.75, 1.0,  -0.5, 0.125, 0.6, 0.9,  0.3, 0.3, 0.3, 0.3,  1e-3, 7.0, -2.0, 0.01]])
FRACTION = np.array([[0.25, 0.5], [12345 / 65536, 50000 / 65536]])


def test_the_exact_blend_weights_each_corner_by_its_rectangle():
    got = bilinear.blend_exact(TEXELS, FRACTION)
    assert got.shape == (2, 4) and got.dtype == np.float64
    # row 0, component 0 by hand: 0.375·0 + 0.125·1 + 0.375·2 + 0.125·4 = 1.375
    assert got[0, 0] == 1.375
    for r in range(2):
        t = TEXELS[r].reshape(4, 4)
        assert got[r].tolist() == _exact(t, FRACTION[r, 0], FRACTION[r, 1])


def test_the_float_blend_lerps_along_x_then_y_within_the_filter_allowance():
    got = bilinear.blend(TEXELS, FRACTION[:, 0], FRACTION[:, 1], np.float64)
    want = np.array([_exact(TEXELS[r].reshape(4, 4), FRACTION[r, 0], FRACTION[r, 1]) for r in range(2)])
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-15)
    ref = CASES["sample_bilinear-float32"].reference(texels=TEXELS.astype(np.float32),
                                                     fraction=FRACTION.astype(np.float32))[0]
    assert ref.dtype == np.float32
    allowance = 8 * 2.0**-23 * np.abs(TEXELS.reshape(2, 4, 4)).max(axis=1)
    assert (np.abs(ref.astype(np.float64) - want) <= allowance).all()
    # the axes are not interchangeable: blending with (fy, fx) misses the exact value on row 1
    swapped = np.array([_exact(TEXELS[r].reshape(4, 4), FRACTION[r, 1], FRACTION[r, 0]) for r in range(2)])
    assert (np.abs(ref.astype(np.float64) - swapped) > allowance)[1].any()


def test_the_filter_allowance_is_eight_ulps_of_the_largest_component_over_the_four_texels():
    got = bilinear._filter_rounding(TEXELS, np.float32)
    big = np.array([[4.0, 0.7, 0.9, 3.0], [0.5, 7.0, 2.0, 1.0]])  # per component, the largest |t| over the texels
    assert np.array_equal(got, 8 * 2.0**-23 * big)
    assert np.array_equal(bilinear._filter_rounding(TEXELS, np.float64), 8 * 2.0**-52 * big)


def test_a_b_bit_filters_weights_are_the_grid_points_at_or_next_to_the_fraction():
    lo, hi = bilinear.quantized(np.array([0.3, 0.25, 1 - 2.0**-16]), 2)
    assert lo.tolist() == [0.25, 0.25, 0.75] and hi.tolist() == [0.5, 0.25, 1.0]
    # in float64: a fraction 2^-30 above a grid point of 2^-24 has the next point above it (float32 would drop it)
    f = 0.5 + 2.0**-30
    lo, hi = bilinear.quantized(np.array([f]), 24)
    assert lo[0] == 0.5 and hi[0] == 0.5 + 2.0**-24
    (lx, hx), (ly, hy) = bilinear.weight_interval(np.array([[f, 0.3]]), 24)
    assert (lx[0], hx[0]) == (0.5, 0.5 + 2.0**-24) and ly[0] <= 0.3 <= hy[0] and hy[0] - ly[0] == 2.0**-24


def test_the_intensity_reference_in_float64_is_algorithm_1_on_the_float64_blend_unrounded():
    from moments_ref.moments import BIAS_FLOAT32, bias_moments
    from moments_ref.msm import shadow_intensity

    z = np.array([[0.2, 0.5, -0.3, 0.7], [0.1, -0.4, 0.35, 0.6]])  # one depth per texel: its power moments
    texels = (z[:, :, None] ** np.arange(1, 5)).reshape(2, 16)
    zf = np.array([0.3, 0.123456789])
    got = CASES["shadow_intensity_bilinear-float32"].reference(texels=texels, fraction=FRACTION, zf=zf)[0]
    b = bilinear.blend(texels, FRACTION[:, 0], FRACTION[:, 1], np.float64)
    want = np.asarray(shadow_intensity(bias_moments(b, BIAS_FLOAT32), zf), np.float64)
    assert got.dtype == np.float64 and np.array_equal(got, want)
    assert ((want > 0.01) & (want < 0.99)).all() and not np.array_equal(want, want.astype(np.float32))


def test_the_bilinear_goldens_number_their_rows_from_one():
    from moments_ref.golden.spread import golden_arrays

    a = golden_arrays(CASES["sample_bilinear-float32"])
    n = len(a["category"])
    assert a["tc_id"].tolist() == list(range(1, n + 1)) and a["tc_id"].dtype == np.int32
    assert (a["result"] == "valid").all()
