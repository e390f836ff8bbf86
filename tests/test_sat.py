"""Wrap-around summed-area tables (Slides, "SAT over a moment shadow map", "Caveat: Bilinear interpolation").

References used here, independent of moments_ref.gpu.sat: Python integers (exact
sums, no wrap), float64 sums of the unquantized values, a brute-force area
integral over every texel's overlap with the query, and the hardware-style
bilinear filter of moments_ref.techniques.
"""

import itertools
import math

import numpy as np
import pytest
from hypothesis import given, strategies as st

from moments_ref import InputError
from moments_ref.gpu import sat


def all_rectangles(h, w):
    """Every [r0, r1) x [c0, c1) of an h x w map."""
    rows = [(a, b) for a in range(h) for b in range(a + 1, h + 1)]
    cols = [(a, b) for a in range(w) for b in range(a + 1, w + 1)]
    return [(r, c) for r in rows for c in cols]


def brute_area_mean(values, lo, hi):
    """(1/area) ∫∫ f over [lo, hi] for the box-texel texture, by every texel's overlap (float64)."""
    v = np.asarray(values, np.float64)
    h, w = v.shape[:2]
    j, i = np.arange(w), np.arange(h)
    ox = np.clip(np.minimum(hi[0], j + 1) - np.maximum(lo[0], j), 0, None)
    oy = np.clip(np.minimum(hi[1], i + 1) - np.maximum(lo[1], i), 0, None)
    return np.einsum("i,j,ijc->c", oy, ox, v) / ((hi[0] - lo[0]) * (hi[1] - lo[1]))


# ---------------------------------------------------------------------------
# The constants of the slides


def test_precision_of_a_27_squared_kernel_is_the_slides_22_5_bits():
    # The extracted slide reads "272 kernel -> 22.5 bits"; only 27² = 729 gives 22.5.
    assert round(sat.precision_bits(27 ** 2), 1) == 22.5
    assert round(sat.precision_bits(272), 1) != 22.5
    # The scale used is one code below 2³²/n at most: same precision to 1e-6 bits.
    assert abs(sat.precision_bits(729, nominal=False) - sat.precision_bits(729)) < 1e-6


@given(st.integers(1, 2 ** 32 - 1))
def test_scale_keeps_n_codes_below_2_to_the_32(n):
    q = sat.code_scale(n)
    assert n * q < 2 ** 32  # Python integers: exact
    assert n * (q + 1) >= 2 ** 32 - 1 or q + 1 > 2 ** 32 // n  # the largest such scale


def test_the_slides_literal_scale_wraps_an_all_white_kernel_to_zero():
    # Why the scale is floor((2³² − 1)/n): with 2³²/n, n texels of value 1 sum to 2³² ≡ 0.
    n = 16
    literal = np.full((4, 4), 2 ** 32 // n, np.uint32)
    assert int(np.sum(literal, dtype=np.uint32)) == 0
    s = sat.build(np.ones((4, 4)), n)
    assert int(sat.rectangle_sum(s, [0, 4], [0, 4])[0]) == n * sat.code_scale(n)


def test_table_is_uint32_without_upcasting():
    s = sat.build(np.ones((3, 5, 4), np.float32), 2)
    assert s.table.dtype == np.uint32 and s.table.shape == (4, 6, 4)
    assert not s.table[0].any() and not s.table[:, 0].any()


# ---------------------------------------------------------------------------
# Wrap-around: exhaustive on small tables


@pytest.mark.parametrize("n", [1, 2, 3, 6, 12, 20])
@pytest.mark.parametrize("kind", ["ones", "random", "binary"])
def test_every_rectangle_of_at_most_n_texels_is_exact_despite_overflow(n, kind):
    h, w, c = 4, 5, 2
    rng = np.random.default_rng(n)
    values = {"ones": np.ones((h, w, c)), "random": rng.random((h, w, c)),
              "binary": rng.integers(0, 2, (h, w, c)).astype(float)}[kind]
    s = sat.build(values, n)
    q = sat.code_scale(n)
    codes = [[[int(round(values[i, j, k] * q)) for k in range(c)] for j in range(w)] for i in range(h)]
    if kind == "ones" and n < h * w:
        # The table did wrap: its last entry is not the exact total.
        assert int(s.table[h, w, 0]) != h * w * q
    checked = 0
    for (r0, r1), (c0, c1) in all_rectangles(h, w):
        m = (r1 - r0) * (c1 - c0)
        if m > n:
            with pytest.raises(InputError, match="at most n"):
                sat.rectangle_sum(s, [r0, r1], [c0, c1])
            continue
        got = sat.rectangle_sum(s, [r0, r1], [c0, c1])
        for k in range(c):
            exact = sum(codes[i][j][k] for i in range(r0, r1) for j in range(c0, c1))
            assert exact < 2 ** 32
            assert int(got[k]) == exact
            # Against the float64 sum of the unquantized values: m half-codes at most.
            assert abs(exact / q - values[r0:r1, c0:c1, k].sum()) <= m * 0.5 / q * (1 + 1e-9)
        mean = sat.rectangle_mean(s, [r0, r1], [c0, c1])
        np.testing.assert_allclose(mean, values[r0:r1, c0:c1].mean((0, 1)), rtol=0, atol=0.5 / q + 1e-12)
        checked += 1
    assert checked > 0


@given(st.integers(1, 7), st.integers(1, 7), st.integers(1, 49), st.integers(0, 2 ** 31), st.data())
def test_random_rectangle_sum_is_exact(h, w, n, seed, data):
    values = np.random.default_rng(seed).random((h, w, 1))
    s = sat.build(values, n)
    r0 = data.draw(st.integers(0, h - 1))
    r1 = data.draw(st.integers(r0 + 1, h))
    c0 = data.draw(st.integers(0, w - 1))
    c1 = data.draw(st.integers(c0 + 1, min(w, c0 + max(1, n // (r1 - r0)))))
    if (r1 - r0) * (c1 - c0) > n:
        return
    q = sat.code_scale(n)
    exact = sum(int(x) for x in np.floor(values[r0:r1, c0:c1, 0] * q + 0.5).ravel())
    assert int(sat.rectangle_sum(s, [r0, r1], [c0, c1])[0]) == exact


def test_vectorized_rectangle_sums_match_one_by_one():
    rng = np.random.default_rng(3)
    s = sat.build(rng.random((6, 8, 3)), 48)
    rects = all_rectangles(6, 8)
    rows = np.array([r for r, _ in rects])
    cols = np.array([c for _, c in rects])
    ok = (rows[:, 1] - rows[:, 0]) * (cols[:, 1] - cols[:, 0]) <= 48
    many = sat.rectangle_sum(s, rows[ok], cols[ok])
    one = np.stack([sat.rectangle_sum(s, r, c) for r, c in zip(rows[ok], cols[ok])])
    np.testing.assert_array_equal(many, one)


# ---------------------------------------------------------------------------
# Interpolated queries against the brute-force area integral


def rectangles(h, w):
    """Strategy: (lo, hi) inside [0, w] x [0, h] with max(1, width)·max(1, height) small."""
    coord = st.floats(0, 1, allow_nan=False)

    @st.composite
    def rect(draw):
        x0 = draw(coord) * (w - 0.01)
        y0 = draw(coord) * (h - 0.01)
        # min: x0 + 0.01 + (w − x0 − 0.01) can round above w (the thorough profile drew 9.000000000000002)
        x1 = min(x0 + 0.01 + draw(coord) * (w - x0 - 0.01), w)
        y1 = min(y0 + 0.01 + draw(coord) * (h - y0 - 0.01), h)
        return np.array([x0, y0]), np.array([x1, y1])

    return rect()


@given(rectangles(9, 11), st.integers(0, 2 ** 31), st.sampled_from([np.float64, np.float32]))
def test_interpolated_mean_is_the_area_integral(rect, seed, dtype):
    lo, hi = rect
    values = np.random.default_rng(seed).random((9, 11, 2))
    n = 9 * 11
    s = sat.build(values, n)
    got = sat.interpolated_mean(s, lo.astype(dtype), hi.astype(dtype))
    assert got.dtype == dtype
    # The float32 path receives corners rounded to float32: compare at those corners.
    want = brute_area_mean(values, lo.astype(dtype).astype(np.float64), hi.astype(dtype).astype(np.float64))
    tol = 0.5 / sat.code_scale(n) + (1e-12 if dtype == np.float64 else 4e-6)
    np.testing.assert_allclose(got, want, rtol=0, atol=tol)


def test_interpolated_mean_wraps_and_stays_exact_on_a_saturated_table():
    # All-ones values with a small n: the table wraps many times, queries stay exact.
    n = 9
    s = sat.build(np.ones((12, 12, 1)), n)
    assert (s.table[1:, 1:, 0].astype(np.int64) != np.arange(1, 13)[:, None] * np.arange(1, 13)
            * sat.code_scale(n)).any()
    rng = np.random.default_rng(0)
    lo = rng.uniform(0, 9, (500, 2))
    hi = lo + rng.uniform(0.05, 3.0, (500, 2))
    got = sat.interpolated_mean(s, lo, hi)
    np.testing.assert_allclose(got, 1.0, rtol=0, atol=1e-12)


def test_naive_interpolation_of_the_wrapped_table_is_wrong():
    # Mutant: lerp the uint32 SAT as floats (what a texture unit would do) instead of
    # combining exact 3×3 integer sums. On a wrapped table this is garbage.
    n = 9
    values = np.random.default_rng(1).random((12, 12, 1))
    s = sat.build(values, n)
    lo, hi = np.array([6.3, 7.6]), np.array([8.8, 9.2])

    def lerp(x, y):
        t = s.table[..., 0].astype(np.float64)
        i, j = int(np.floor(y)), int(np.floor(x))
        fy, fx = y - i, x - j
        return ((1 - fy) * ((1 - fx) * t[i, j] + fx * t[i, j + 1]) + fy * ((1 - fx) * t[i + 1, j]
                                                                          + fx * t[i + 1, j + 1]))
    naive = (lerp(hi[0], hi[1]) - lerp(lo[0], hi[1]) - lerp(hi[0], lo[1]) + lerp(lo[0], lo[1]))
    naive /= (hi - lo).prod() * s.scale
    want = brute_area_mean(values, lo, hi)[0]
    assert abs(naive - want) > 0.1
    assert abs(sat.interpolated_mean(s, lo, hi)[0] - want) < 1e-6


def test_unit_query_is_bilinear_filtering():
    from moments_ref.techniques import bilinear_filtered

    rng = np.random.default_rng(5)
    values = rng.random((16, 16, 4))
    s = sat.build(values, 4)
    uv = rng.uniform(1.0, 15.0, (300, 2))
    got = sat.interpolated_mean(s, uv - 0.5, uv + 0.5)
    want = bilinear_filtered(values, uv, np.float64)
    np.testing.assert_allclose(got, want, rtol=0, atol=0.5 / s.scale + 1e-12)


def test_clamp_averages_over_the_part_inside_the_map():
    values = np.random.default_rng(2).random((8, 8, 1))
    s = sat.build(values, 64)
    lo, hi = np.array([-2.5, 5.2]), np.array([3.1, 10.0])
    got = sat.interpolated_mean(s, lo, hi, clamp=True)
    want = brute_area_mean(values, np.array([0.0, 5.2]), np.array([3.1, 8.0]))
    np.testing.assert_allclose(got, want, atol=1e-8)


@given(st.integers(1, 400), st.floats(0.01, 30), st.floats(0.01, 30), st.floats(0, 1), st.floats(0, 1))
def test_every_rectangle_within_n_is_accepted(n, wd, ht, fx, fy):
    # Documented acceptance rule: max(1, width)·max(1, height) <= n is always accepted.
    if max(1, wd) * max(1, ht) > n:
        return
    s = sat.build(np.zeros((40, 40, 1)), n)
    lo = np.array([fx * (40 - wd), fy * (40 - ht)])
    sat.interpolated_mean(s, lo, lo + [wd, ht])


# ---------------------------------------------------------------------------
# Bad input


def test_bad_input_is_refused():
    s = sat.build(np.random.default_rng(0).random((10, 10, 2)), 16)
    with pytest.raises(InputError, match="largest kernel"):
        sat.interpolated_mean(s, [0.5, 0.5], [7.5, 7.5])  # 6 x 6 inner texels > 16
    with pytest.raises(InputError, match="inside"):
        sat.interpolated_mean(s, [-0.5, 1.0], [1.0, 2.0])
    with pytest.raises(InputError, match="entirely outside"):
        sat.interpolated_mean(s, [11.0, 1.0], [12.0, 2.0], clamp=True)
    with pytest.raises(InputError, match="lo < hi"):
        sat.interpolated_mean(s, [1.0, 1.0], [1.0, 2.0])
    with pytest.raises(InputError, match="finite"):
        sat.interpolated_mean(s, [np.nan, 1.0], [2.0, 2.0])
    with pytest.raises(InputError, match="start < stop"):
        sat.rectangle_sum(s, [3, 3], [0, 1])
    with pytest.raises(InputError, match="start < stop"):
        sat.rectangle_sum(s, [0, 11], [0, 1])
    with pytest.raises(InputError, match="integer"):
        sat.rectangle_sum(s, [0.5, 2], [0, 1])
    with pytest.raises(InputError, match="n:"):
        sat.build(np.ones((2, 2)), 0)
    with pytest.raises(InputError, match="n:"):
        sat.build(np.ones((2, 2)), 2 ** 32)
    with pytest.raises(InputError, match="finite"):
        sat.build(np.array([[np.inf]]), 4)
    with pytest.raises(InputError, match="SummedAreaTable"):
        sat.rectangle_sum(np.zeros((3, 3, 1), np.uint32), [0, 1], [0, 1])


def test_out_of_range_values_are_clamped_like_unorm():
    s = sat.build(np.array([[-0.25, 1.5]]), 2)
    got = sat.rectangle_sum(s, [0, 1], [0, 2])
    assert int(got[0]) == sat.code_scale(2)
    assert math.isclose(sat.rectangle_mean(s, [0, 1], [0, 1])[0], 0.0)


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_interpolated_mean_loads_the_texels_of_the_four_by_four_index(dtype):
    # The slides' steps written out with the 2-D index table[lines_y, lines_x] (what the flat gather of
    # interpolated_mean loads): the same values bit for bit, at the map's edges (clamp) and inside, on a
    # non-square map with 3 channels (a wrong row stride reads other texels)
    rng = np.random.default_rng(4)
    h, w = 13, 21
    s = sat.build(rng.random((h, w, 3)), 36)
    lo = rng.uniform(-2, [w + 1, h + 1], (500, 2))
    hi = lo + rng.uniform(0.05, 5.5, (500, 2))
    lo[:20], hi[:20] = [0, 0], [w, h]  # whole map: lines at the last row and column
    lo[20:40], hi[20:40] = [w - 0.5, h - 0.5], [w + 3.0, h + 3.0]
    keep = ((np.minimum(hi, [w, h]) - np.maximum(lo, [0, 0])) > 0).all(axis=1)
    keep &= (np.minimum(hi, [w, h]) - np.maximum(lo, 0)).clip(1).prod(axis=1) <= 36
    lo, hi = lo[keep], hi[keep]
    got = sat.interpolated_mean(s, lo, hi, clamp=True, dtype=dtype)
    lo_c, hi_c = np.clip(lo, 0, [w, h]), np.clip(hi, 0, [w, h])
    lx, wx = sat._axis_lines(lo_c[:, 0], hi_c[:, 0], w)
    ly, wy = sat._axis_lines(lo_c[:, 1], hi_c[:, 1], h)
    g = s.table[ly[:, :, None], lx[:, None, :]]
    band = (g[:, 1:, 1:] - g[:, :-1, 1:]) - g[:, 1:, :-1] + g[:, :-1, :-1]
    dt = np.dtype(dtype)
    want = np.einsum("nk,nl,nklc->nc", wy.astype(dt), wx.astype(dt), band.astype(dt))
    want /= ((hi_c[:, 0] - lo_c[:, 0]) * (hi_c[:, 1] - lo_c[:, 1])).astype(dt)[:, None] * dt.type(s.scale)
    assert len(lo) > 300
    assert got.tobytes() == want.tobytes()
