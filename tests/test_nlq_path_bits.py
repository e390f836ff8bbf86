"""The global NLQ path and the on-chip emulation, bit for bit against straightforward references.

Issue 41 (round eight) moved data, not arithmetic: the on-chip emulation's loads and
stores (resolve, readout), the division by a power-of-two sample count as a product,
pack64's depth codes in one product. Each test here computes the same values by the
plainest NumPy code (whole-map passes, the formulas' operations in their order) and
asks for equal bits, on shapes with partial blocks, one texel, thin maps and every
sample count the shader meets.
"""

import numpy as np
import pytest

from moments_ref.gpu.filtering import bench_depth_map, blur, gaussian_weights, global_path_nlq, resolve_moments
from moments_ref.gpu.onchip import filter_and_quantize, filter_moments
from moments_ref.moments import BIAS_FLOAT32, bias_moments, power_moments
from moments_ref.nonlinear import phi
from moments_ref.packing import pack32, pack64

SHAPES = [(1, 1, 1), (3, 5, 4), (70, 33, 2), (131, 200, 4), (300, 17, 8), (9, 400, 4), (40, 50, 3)]


def depths(shape, seed=0, dtype=np.float32):
    """Uniform depths with −0.0 and tiny samples (z⁴ subnormal in float32: the mean's rounding there)."""
    z = np.random.default_rng(seed).uniform(-1, 1, shape)
    z.flat[::7] = -0.0
    z.flat[3::11] = np.random.default_rng(seed + 1).choice([1e-10, -3e-10, 2.5e-10], size=z.flat[3::11].shape)
    z[-1, ::2] = np.random.default_rng(seed + 2).choice([1e-10, -3e-10, 2.5e-10, -0.0], size=z[-1, ::2].shape)
    return z.astype(dtype)


def texels(b, fmt):
    """pack(phi(bias_moments(b, BIAS_FLOAT32))): the three public steps one after the other."""
    r = phi(bias_moments(b, BIAS_FLOAT32))
    return pack64(r) if fmt == "nlq64" else pack32(r)


def shader_moments(z):
    """The HPG17 §4.1 shader's float32 arithmetic on the whole map, written plainly.

    Resolve: z, z², z²·z, z²·z² accumulated from 0 in sample order, divided by S.
    Blur: clamp-to-edge, horizontal then vertical, each output ``w0·v0`` then ``+ w_t·v_t``
    for t = 1..8 in float32 (the emulation's ``_convolve``).
    """
    z = z.astype(np.float32)
    h, w, s = z.shape
    acc = np.zeros((4, h, w), np.float32)
    for k in range(s):
        zs = z[..., k]
        q = zs * zs
        acc[0] += zs
        acc[1] += q
        acc[2] += q * zs
        acc[3] += q * q
    m = acc / np.float32(s)
    wt = gaussian_weights().astype(np.float32)
    cols = np.clip(np.arange(-4, w + 4), 0, w - 1)
    p = m[:, :, cols]
    hp = wt[0] * p[:, :, 0:w]
    for t in range(1, 9):
        hp += wt[t] * p[:, :, t : t + w]
    rows = np.clip(np.arange(-4, h + 4), 0, h - 1)
    p = hp[:, rows]
    out = wt[0] * p[:, 0:h]
    for t in range(1, 9):
        out += wt[t] * p[:, t : t + h]
    return np.moveaxis(out, 0, -1)


@pytest.mark.parametrize("shape", SHAPES)
@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_global_path_is_the_separate_steps(shape, dtype):
    z = depths(shape, seed=sum(shape), dtype=dtype)
    b32 = blur(resolve_moments(z)).astype(np.float32)
    for fmt in ("nlq64", "nlq32"):
        assert np.array_equal(global_path_nlq(z, fmt), texels(b32, fmt)), fmt


@pytest.mark.parametrize("samples", [1, 2, 3, 4, 8])
def test_resolve_is_power_moments_for_every_sample_count(samples):
    # Powers of two take the product with 1/S: the same rounding as power_moments' division.
    z = depths((37, 29, samples), seed=samples)
    for dt in (np.float32, np.float64):
        zz = z.astype(dt)
        assert np.array_equal(resolve_moments(zz), power_moments(zz, axis=-1, n=4))
    b4 = power_moments(z, axis=-1, n=4)[..., 3]
    assert np.count_nonzero((0 < b4) & (b4 < np.finfo(np.float32).tiny)) > 0  # subnormal means reached


@pytest.mark.parametrize("shape", SHAPES)
@pytest.mark.parametrize("batch", [1, 5, 64])
def test_onchip_moments_are_the_shaders_arithmetic(shape, batch):
    z = depths(shape, seed=3 * sum(shape))
    ref = shader_moments(z)
    for layout in ("paper", "row-major"):
        assert np.array_equal(filter_moments(z, blocks_per_batch=batch, layout=layout), ref), layout


def test_shader_reference_has_power():
    # Equality is exact: one value one ulp off fails it, and so does another summation order.
    z = depths((30, 40, 4), seed=9)
    ref = shader_moments(z)
    got = filter_moments(z)
    assert np.array_equal(got, ref)
    wrong = got.copy()
    wrong[5, 7, 2] = np.nextafter(wrong[5, 7, 2], np.float32(2))
    assert not np.array_equal(wrong, ref)
    # The float64 reference (taps summed folded), rounded to float32, is not these bits.
    zs = resolve_moments(z).astype(np.float32)
    folded = blur(zs).astype(np.float32)
    assert not np.array_equal(folded, ref)


@pytest.mark.parametrize("shape", [(3, 5, 4), (70, 33, 2), (131, 200, 4), (9, 400, 4)])
def test_onchip_texture_is_the_separate_steps(shape):
    z = depths(shape, seed=5 * sum(shape))
    b = shader_moments(z)
    for fmt in ("nlq64", "nlq32"):
        assert np.array_equal(filter_and_quantize(z, fmt), texels(b, fmt)), fmt


def test_pack64_depth_codes_follow_the_formula():
    # round(65535 · (y + 1)/2) with the operations in the formula's order, per dtype.
    rng = np.random.default_rng(4)
    for dt in (np.float32, np.float64):
        y = np.concatenate([rng.uniform(-1, 1, 200000), [-1, 1, 0, -0.0], np.linspace(-1, 1, 65536 * 4 + 1)]).astype(dt)
        y = np.concatenate([y, np.nextafter(y, dt(2)), np.nextafter(y, dt(-2))])
        y = np.clip(y, -1, 1).astype(dt)
        r = np.zeros((y.size, 4), dt)
        r[:, 0], r[:, 1], r[:, 2], r[:, 3] = y, y, 0.5, 0.01
        want = np.rint(((y + dt(1)) * dt(0.5)) * dt(65535)).astype(np.uint16)
        got = pack64(r)
        assert np.array_equal(got[:, 0], want) and np.array_equal(got[:, 1], want)


@pytest.mark.slow
def test_bench_map_2048_bit_for_bit():
    z = bench_depth_map()
    b32 = blur(resolve_moments(z)).astype(np.float32)
    assert np.array_equal(global_path_nlq(z, "nlq64"), texels(b32, "nlq64"))
    ref = shader_moments(z)
    assert np.array_equal(filter_moments(z), ref)
    assert np.array_equal(filter_and_quantize(z, "nlq64"), texels(ref, "nlq64"))
