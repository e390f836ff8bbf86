"""MSAA resolve, Gaussian weights and the two-pass reference blur (HPG17 §4, §4.1)."""

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp
from scipy import ndimage

from moments_ref import InputError
from moments_ref.tools.bench import bench_filtering
from moments_ref.gpu.filtering import (
    SIGMA,
    TAPS,
    blur,
    gaussian_weights,
    resolve_moments,
)

depth_values = st.floats(-1, 1, allow_nan=False, width=32)


def depth_maps(max_h=12, max_w=12, max_s=4, dtype=np.float64):
    shapes = st.tuples(st.integers(1, max_h), st.integers(1, max_w), st.integers(1, max_s))
    return shapes.flatmap(lambda s: hnp.arrays(dtype, s, elements=depth_values))


# ---------------------------------------------------------------- resolve


@given(depth_maps())
def test_resolve_is_the_mean_of_b(z):
    b = resolve_moments(z)
    assert b.shape == z.shape[:2] + (4,) and b.dtype == np.float64
    # Brute force: each texel, each power, with Python floats.
    H, W, S = z.shape
    for y in range(H):
        for x in range(W):
            for k in range(1, 5):
                want = math.fsum(float(v) ** k for v in z[y, x]) / S
                assert abs(b[y, x, k - 1] - want) <= 1e-15 * (S + k)


@given(depth_maps(max_h=4, max_w=4, max_s=6), st.randoms(use_true_random=False))
def test_resolve_ignores_sample_order(z, rnd):
    perm = list(range(z.shape[2]))
    rnd.shuffle(perm)
    np.testing.assert_allclose(resolve_moments(z[:, :, perm]), resolve_moments(z), rtol=0, atol=1e-15)


@given(st.floats(-1, 1), st.integers(1, 8))
def test_resolve_of_equal_samples_is_b_of_z(zv, S):
    b = resolve_moments(np.full((2, 3, S), zv))
    want = np.array([zv, zv**2, zv**3, zv**4])
    np.testing.assert_allclose(b, np.broadcast_to(want, (2, 3, 4)), rtol=1e-15, atol=1e-300)


def test_resolve_dtype_policy():
    z = np.linspace(-1, 1, 24).reshape(2, 3, 4)
    assert resolve_moments(z.astype(np.float32)).dtype == np.float32
    assert resolve_moments(z).dtype == np.float64
    assert resolve_moments(np.zeros((1, 1, 2), dtype=np.int32)).dtype == np.float64


def test_resolve_rejects_bad_depths_with_first_index():
    z = np.zeros((3, 4, 2))
    z[1, 2, 1] = 1.0000001
    z[2, 0, 0] = -3
    with pytest.raises(InputError, match=r"\[-1, 1\].*\(1, 2, 1\)"):
        resolve_moments(z)
    z = np.zeros((3, 4, 2), dtype=np.float32)
    z[0, 3, 0] = np.nan
    with pytest.raises(InputError, match=r"\(0, 3, 0\)"):
        resolve_moments(z)
    with pytest.raises(InputError, match="H, W, S"):
        resolve_moments(np.zeros((3, 4)))
    with pytest.raises(InputError):
        resolve_moments(np.zeros((3, 4, 0)))
    # The boundary itself is valid.
    resolve_moments(np.array([[[-1.0, 1.0]]]))


# ---------------------------------------------------------------- Gaussian weights


def test_gaussian_weights_match_the_formula():
    w = gaussian_weights()
    assert w.shape == (TAPS,) and TAPS == 9 and SIGMA == 2.4
    raw = [math.exp(-(i * i) / (2 * 2.4**2)) for i in range(-4, 5)]
    np.testing.assert_allclose(w, np.array(raw) / math.fsum(raw), rtol=1e-15)
    assert math.isclose(math.fsum(w), 1.0, rel_tol=1e-15)
    assert np.array_equal(w, w[::-1])


@given(st.integers(0, 10), st.floats(0.5, 20))
def test_gaussian_weights_are_a_sampled_gaussian(r, sigma):
    w = gaussian_weights(2 * r + 1, sigma)
    assert abs(w.sum() - 1) < 1e-14 and (w > 0).all()
    # Neighbouring ratio exp(−((i+1)² − i²)/(2σ²)), independent of the normalization.
    i = np.arange(-r, r)
    np.testing.assert_allclose(w[1:] / w[:-1], np.exp(-(2 * i + 1) / (2 * sigma**2)), rtol=1e-12)


def test_gaussian_weights_reject_bad_parameters():
    for taps in (0, 8, 2.0, True):
        with pytest.raises(InputError, match="taps"):
            gaussian_weights(taps)
    for sigma in (0, -1, float("nan")):
        with pytest.raises(InputError, match="sigma"):
            gaussian_weights(9, sigma)


# ---------------------------------------------------------------- blur


def brute_blur(m, w):
    """Σ_{s,t} w_s w_t m[clip(y+s), clip(x+t)] over all 81 offsets (clamp-to-edge)."""
    H, W = m.shape[:2]
    r = len(w) // 2
    out = np.zeros(m.shape)
    ys, xs = np.arange(H), np.arange(W)
    for s in range(-r, r + 1):
        for t in range(-r, r + 1):
            rows = np.clip(ys + s, 0, H - 1)
            cols = np.clip(xs + t, 0, W - 1)
            out += w[s + r] * w[t + r] * m[rows][:, cols]
    return out


maps = st.tuples(st.integers(1, 14), st.integers(1, 14), st.integers(1, 4)).flatmap(
    lambda s: hnp.arrays(np.float64, s, elements=st.floats(-1, 1))
)


@given(maps)
def test_blur_equals_2d_clamped_convolution(m):
    out = blur(m)
    assert out.dtype == np.float64 and out.shape == m.shape
    np.testing.assert_allclose(out, brute_blur(m, gaussian_weights()), rtol=0, atol=1e-14)


@given(maps)
def test_blur_equals_scipy_nearest(m):
    # scipy.ndimage's mode="nearest" is clamp-to-edge.
    w = gaussian_weights()
    want = ndimage.correlate1d(ndimage.correlate1d(m, w, axis=1, mode="nearest"), w, axis=0, mode="nearest")
    np.testing.assert_allclose(blur(m), want, rtol=0, atol=1e-14)


@given(maps)
def test_blur_commutes_with_transposition(m):
    np.testing.assert_allclose(blur(m.transpose(1, 0, 2)), blur(m).transpose(1, 0, 2), rtol=0, atol=1e-14)


@given(st.integers(1, 20), st.integers(1, 20), st.floats(-1, 1))
def test_blur_keeps_constants(h, w, c):
    # Clamp-to-edge keeps a constant map constant at the border too.
    np.testing.assert_allclose(blur(np.full((h, w, 4), c)), c, rtol=1e-15, atol=1e-300)


def test_border_rule_is_clamp_to_edge_and_a_wrong_rule_is_detected():
    # A ramp along x: the border texel sees 4 copies of itself beyond the edge.
    m = np.tile(np.arange(1.0, 21.0)[None, :, None], (3, 1, 1))
    w = gaussian_weights()
    got = blur(m)[1, 0, 0]
    want = sum(w[t + 4] * (1 + max(t, 0)) for t in range(-4, 5))
    assert abs(got - want) < 1e-13
    # Mutant: zero padding or mirroring would give a different border value.
    for mode in ("constant", "mirror", "reflect", "wrap"):
        other = ndimage.correlate1d(m, w, axis=1, mode=mode)[1, 0, 0]
        assert abs(other - got) > 1e-3, mode


def test_blur_float32_input_gives_float64_reference():
    m = np.random.default_rng(0).uniform(-1, 1, (5, 6, 4)).astype(np.float32)
    out = blur(m)
    assert out.dtype == np.float64
    np.testing.assert_allclose(out, brute_blur(m.astype(np.float64), gaussian_weights()), atol=1e-14)


def test_blur_custom_weights_and_bad_input():
    m = np.random.default_rng(1).uniform(-1, 1, (6, 7, 2))
    w = np.array([0.25, 0.5, 0.25])
    np.testing.assert_allclose(blur(m, w), brute_blur(m, w), atol=1e-15)
    with pytest.raises(InputError):
        blur(m, np.ones(4))
    with pytest.raises(InputError):
        blur(m[..., 0])
    with pytest.raises(InputError):
        blur(np.full((2, 2, 4), np.inf))


def test_bench_filtering_reports_numbers():
    r = bench_filtering(size=48, samples=2)
    for key in ("global_resolve_s", "global_blur_s", "global_total_s", "onchip_total_s",
                "onchip_resolve_s", "onchip_horizontal_s", "onchip_vertical_s", "onchip_readout_s"):
        assert r[key] > 0, key
    assert r["texels"] == 48 * 48
    assert r["max_abs_difference"] < 1e-5


def test_blur_across_chunk_boundaries():
    # Larger than the internal chunk of 64 rows/columns in both directions.
    m = np.random.default_rng(2).uniform(-1, 1, (150, 131, 2))
    w = gaussian_weights()
    want = ndimage.correlate1d(ndimage.correlate1d(m, w, axis=1, mode="nearest"), w, axis=0, mode="nearest")
    np.testing.assert_allclose(blur(m), want, rtol=0, atol=1e-14)


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_resolve_is_bit_identical_to_power_moments_across_chunks(dtype, monkeypatch):
    # The chunked structure-of-arrays resolve against moments.power_moments (an
    # independent loop over array-of-structures powers and np.mean), bit for bit,
    # for every sample count (sequential sums below 8, pairwise at 8, delegated
    # above), with signed zeros (NumPy's sum starts from +0; odd powers of tiny negative
    # depths underflow to -0.0) and chunk boundaries.
    from moments_ref.gpu import filtering
    from moments_ref.moments import power_moments

    monkeypatch.setattr(filtering, "_RESOLVE_BYTES", 200)
    rng = np.random.default_rng(3)
    for S in range(1, 18):
        z = rng.uniform(-1, 1, (7, 9, S)).astype(dtype)
        z.flat[::5] = -0.0
        z[0, 0] = -0.0
        z[1, 1] = 1.0
        z[2, 2] = -1.0
        # tiny negative depths: z³ (and for float32 z²·z) underflows to -0.0, z⁴ to +0.0
        z[3, 3] = -np.finfo(dtype).tiny ** 0.5
        z[4, 4] = -np.finfo(dtype).smallest_subnormal
        z[5, 5, :1] = -np.finfo(dtype).tiny
        got, want = resolve_moments(z), power_moments(z, axis=-1, n=4)
        assert got.dtype == want.dtype and got.tobytes() == want.tobytes(), S


def test_blur_bands_do_not_change_the_result(monkeypatch):
    # One row per band against the default bands: the same terms in the same order.
    from moments_ref.gpu import filtering

    m = np.random.default_rng(4).uniform(-1, 1, (23, 17, 3)).astype(np.float32)
    want = blur(m)
    monkeypatch.setattr(filtering, "_BAND_BYTES", 1)
    assert blur(m).tobytes() == want.tobytes()


# ---------------------------------------------------------------------------
# the whole global path in bands (filtering.global_path_nlq) against its passes


@pytest.mark.parametrize("fmt", ["nlq64", "nlq32"])
@pytest.mark.parametrize("shape", [(37, 23, 4), (9, 64, 1), (3, 5, 3)])
def test_global_path_in_bands_is_the_passes_one_after_the_other(monkeypatch, fmt, shape):
    from moments_ref.gpu import filtering
    from moments_ref.moments import BIAS_FLOAT32, bias_moments
    from moments_ref.nonlinear import phi
    from moments_ref.packing import pack32, pack64

    rng = np.random.default_rng(sum(shape))
    z = rng.uniform(-1, 1, shape).astype(np.float32)
    z[::4, ::3] = -0.0
    z[1::5] = 1.0
    r = phi(bias_moments(blur(resolve_moments(z)).astype(np.float32), BIAS_FLOAT32))
    want = pack64(r) if fmt == "nlq64" else pack32(r)
    # bands of 2 rows: every band has guard rows inside the map and at its border
    monkeypatch.setattr(filtering, "_PATH_BAND_TEXELS", 2 * shape[1])
    got = filtering.global_path_nlq(z, fmt)
    assert got.dtype == want.dtype and got.shape == want.shape
    assert np.array_equal(got, want)
    assert np.array_equal(filtering.quantize_nlq(blur(resolve_moments(z)).astype(np.float32), fmt), want)


def test_global_path_refuses_what_its_passes_refuse():
    from moments_ref.gpu import filtering

    with pytest.raises(InputError, match=r"depth_samples: expected depths in \[-1, 1\], got .* at index \(1, 0, 0\)"):
        filtering.global_path_nlq(np.array([[[0.0]], [[1.5]]]))
    with pytest.raises(InputError, match="fmt"):
        filtering.global_path_nlq(np.zeros((2, 2, 1)), "nlq16")


# ---------------------------------------------------------------------------
# the folded sums of the symmetric 9-tap kernel (scipy.ndimage's order)


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_blur_sums_as_scipy_ndimage_bit_for_bit(dtype):
    # An exactly symmetric kernel is summed folded, centre first and then the pairs
    # from the outermost in, in both passes: the horizontal pass is ndimage's C loop,
    # the vertical pass NumPy ufuncs in the same order, so ndimage along axis 0 is an
    # independent evaluation of it. The term-by-term sums (the code before the
    # folding) differ from it in about half of the float64 values: this test fails on them.
    m = np.random.default_rng(6).uniform(-1, 1, (150, 131, 4)).astype(dtype)
    w = gaussian_weights()
    h = ndimage.correlate1d(m, w, axis=1, mode="nearest", output=np.float64)
    want = ndimage.correlate1d(h, w, axis=0, mode="nearest")
    assert blur(m).tobytes() == want.tobytes()


def test_blur_is_within_a_forward_error_bound_of_the_exact_2d_sum():
    # HPG17 §4.1's filter as a 2D sum Σ_{s,t} w_s w_t m[clip(y+s), clip(x+t)] in long
    # double (64-bit significand on x86; else the float64 brute force, a weaker check),
    # with cancelling inputs: each pass rounds at most 2r + 2 times per output.
    rng = np.random.default_rng(7)
    m = rng.uniform(-1, 1, (40, 37, 4)) * rng.choice([1e-3, 1.0, 1e3], (40, 37, 1))
    w = gaussian_weights()
    exact = brute_blur(m.astype(np.longdouble), w.astype(np.longdouble))
    scale = brute_blur(np.abs(m), w)
    err = np.abs(blur(m).astype(np.longdouble) - exact).astype(np.float64)
    assert np.all(err <= 2 * (len(w) + 3) * 2.0**-53 * scale)


def test_folded_vertical_sum_rounds_once_into_float32():
    # _correlate_symmetric(final=...) of the global path's vertical pass: the float64 sum
    # rounded once on store, bit for bit .astype(np.float32) of the sum kept in float64,
    # which is itself the brute-force correlation (the terms in the folded order).
    from moments_ref.gpu import filtering

    hp = np.random.default_rng(8).uniform(-1, 1, (29, 11, 4))
    for w in (gaussian_weights(), np.array([0.15, 0.25, 0.2, 0.25, 0.15]), np.array([1.0])):
        n, r = 29 - len(w) + 1, (len(w) - 1) // 2
        acc, tmp = np.empty((n, 11, 4)), np.empty((n, 11, 4))
        filtering._correlate_symmetric(hp, w, acc, tmp, axis=0)
        folded = w[r] * hp[r : r + n]
        for j in range(r):
            folded = folded + w[j] * (hp[j : j + n] + hp[2 * r - j : 2 * r - j + n])
        assert acc.tobytes() == folded.tobytes()
        f32 = np.empty((n, 11, 4), np.float32)
        filtering._correlate_symmetric(hp, w, np.empty((n, 11, 4)), tmp, axis=0, final=f32)
        assert f32.tobytes() == acc.astype(np.float32).tobytes()
