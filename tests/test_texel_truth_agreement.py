"""The exact texel codes (golden/texel_truth.py) against the package's float64 encoders, written apart.

texel_truth types the formats of docs/formats.md again and computes them in exact rationals and
mpmath; moments_ref.packing and moments_ref.affine implement them in float64 (their own tables,
their own saturation). Away from a rounding boundary the two must give the same codes, and the
decoders the same values to a few float64 ulps; the truth's margin (the distance to the nearest
rounding boundary, in units of the code range) must be the one the float64 scaled values show.
Rows cover the saturation (y out of [−1, 1], y2 < y1, v2 > 1, ξ4 < 0 or above the Ψ4 range) and
both halves of the 32-bit fold.
"""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest

from moments_ref import affine, nonlinear, packing
from moments_ref.golden import texel_truth as T

from _mutants import kept_mutant

#: codes compare where the truth's margin exceeds this (float64 scaled values are exact to ~1e-12 codes)
CLEAR = 1e-9


def _texels(n, seed):
    """(n, 4) rows (y1, y2, v2, ξ4): most inside the format's domain, some beyond each end of each saturation."""
    rng = np.random.default_rng(seed)
    y = np.sort(rng.uniform(-1, 1, (n, 2)), axis=1)
    r = np.column_stack([y, rng.uniform(0, 1, n), 10.0 ** rng.uniform(-7, -0.6, n)])
    k = n // 8
    r[:k, 0] -= 0.5  # y1 below -1 for some
    r[k:2 * k, 1] += 0.6  # y2 above 1 for some
    r[2 * k:3 * k, [0, 1]] = r[2 * k:3 * k, [1, 0]]  # y2 < y1
    r[3 * k:4 * k, 2] += 1.0  # v2 > 1
    r[4 * k:4 * k + k // 2, 3] = -r[4 * k:4 * k + k // 2, 3]  # ξ4 < 0
    r[4 * k + k // 2:5 * k, 3] = 0.5 + r[4 * k + k // 2:5 * k, 3]  # ξ4 above the Ψ4 range (0.25)
    r[5 * k:5 * k + 3, 2] = -0.3  # v2 < 0
    r[5 * k + 3:5 * k + 6, :2] = [1.2, 1.4]  # both depths above 1
    r[5 * k + 6:5 * k + 9, :2] = [-1.4, -1.2]  # both below -1
    return r


def _saturate(r):
    """docs/formats.md, Input, in float64: y1 to [-1, 1], y2 to [y1, 1], v2 to [0, 1], ξ4 ≥ 0."""
    y1 = np.clip(r[:, 0], -1, 1)
    return np.column_stack([y1, np.maximum(np.clip(r[:, 1], -1, 1), y1), np.clip(r[:, 2], 0, 1),
                            np.maximum(r[:, 3], 0)])


def _to_half(x):
    return np.abs(x - np.floor(x) - 0.5)


def _to_integer(x):
    return np.abs(x - np.rint(x))


@pytest.mark.parametrize("xi_rounding", ["up", "nearest"])
def test_pack64_codes_and_margin_are_the_float64_encoders_off_the_boundaries(xi_rounding):
    r = _texels(160, 1)
    codes, margin = T.pack64(r, xi_rounding=xi_rounding, margin=True)
    s = _saturate(r)
    scaled = np.column_stack([65535 * (s[:, 0] + 1) / 2, 65535 * (s[:, 1] + 1) / 2, 65535 * s[:, 2]])
    u = 65535 * np.asarray(nonlinear.psi4(np.clip(s[:, 3], 1.2e-7, 0.25)), np.float64)
    xi_dist = _to_integer(u) if xi_rounding == "up" else _to_half(u)
    mine = np.minimum(_to_half(scaled).min(axis=1), xi_dist) / 65535
    np.testing.assert_allclose(margin, mine, rtol=0, atol=1e-13)
    clear = margin > CLEAR  # saturated rows sit on a boundary (y = ±1, ξ4 at Ψ4's ends under "up")
    assert clear.sum() > 110
    theirs = packing.pack64(s, xi_rounding=xi_rounding)  # the truth saturates by itself
    k = 160 // 8
    ends = np.arange(5 * k, 5 * k + 9)  # v2 < 0, both depths above 1, both below -1: exact at the ends
    np.testing.assert_array_equal(codes[ends, :3], theirs[ends, :3])
    assert codes.dtype == np.uint16 and codes.shape == (160, 4)
    np.testing.assert_array_equal(codes[clear], theirs[clear])
    # without margin=True: the codes only, the same
    (alone,) = T.pack64(r, xi_rounding=xi_rounding)
    np.testing.assert_array_equal(alone, codes)


def test_pack32_codes_and_margin_are_the_float64_encoder_off_the_boundaries():
    r = _texels(160, 2)
    codes, margin = T.pack32(r, margin=True)
    s = _saturate(r)
    depth = 1023 / 2 * (s[:, :2] + 1)
    sv = 128 * np.sqrt(s[:, 2])
    u = 64 * np.asarray(nonlinear.psi4(np.clip(s[:, 3], 1.2e-7, 0.25)), np.float64)
    mine = np.minimum.reduce([_to_integer(depth).min(axis=1) / 1023, _to_integer(sv) / 128, _to_integer(u) / 64])
    np.testing.assert_allclose(margin, mine, rtol=0, atol=1e-13)
    clear = margin > CLEAR
    assert clear.sum() > 90
    folded = (np.floor(depth[:, 0]) >= 512) & clear
    assert folded.sum() > 10 and (clear & ~folded).sum() > 10  # both halves of HPG17 Figure 5's triangle
    assert codes.dtype == np.uint32
    np.testing.assert_array_equal(codes[clear], packing.pack32(s)[clear])
    k = 160 // 8
    ends = np.arange(5 * k + 3, 5 * k + 9)  # both depths above 1 or below -1: the end cells, exactly
    np.testing.assert_array_equal(codes[ends] & 0x7FFFF, packing.pack32(s)[ends] & 0x7FFFF)
    (alone,) = T.pack32(r)
    np.testing.assert_array_equal(alone, codes)


def test_unpack_is_the_float64_decoders():
    rng = np.random.default_rng(3)
    q = rng.integers(0, 65536, (120, 4)).astype(np.uint16)
    q[:4] = [[0, 0, 0, 0], [65535, 65535, 65535, 65535], [1, 65534, 2, 1], [32767, 32768, 65535, 65534]]
    np.testing.assert_allclose(T.unpack64(q)[0], packing.unpack64(q), rtol=4e-14, atol=4e-16)
    # 32 bits: random words (both fold halves, every field's ends) under the default decode positions and others
    p = packing.pack32(_saturate(_texels(120, 4)))
    p = np.concatenate([p, np.array([0, 0xFFFFFFFF, 0x3FFFFFF, 0xFC000000], np.uint32)])
    np.testing.assert_allclose(T.unpack32(p)[0], packing.unpack32(p), rtol=4e-14, atol=4e-16)
    for depth, v2, xi in (("lower", "lower", "lower"), ("centre", "upper", "centre")):
        offsets = {"depth": Fraction(packing.DECODE_POSITIONS[depth]).limit_denominator(2),
                   "v": Fraction(packing.DECODE_POSITIONS[v2]).limit_denominator(2),
                   "xi": Fraction(packing.DECODE_POSITIONS[xi]).limit_denominator(2)}
        np.testing.assert_allclose(T.unpack32(p, offsets)[0],
                                   packing.unpack32(p, depth_decode=depth, v2_decode=v2, xi_decode=xi),
                                   rtol=4e-14, atol=4e-16)


def _moments(n, seed, k=6):
    rng = np.random.default_rng(seed)
    z = rng.uniform(-1, 1, (n, 3))
    w = rng.dirichlet(np.ones(3), n)
    return np.stack([(w * z**j).sum(axis=1) for j in range(1, k + 1)], axis=1)


def test_the_affine_basis_codes_and_values_are_the_float64_ones():
    b = _moments(150, 5, 4)
    b[:5] *= 1.3
    b[5:10] *= 4.0  # beyond [0, 1] after the basis change, above and below: clamped codes
    b[10:15] *= -4.0
    np.testing.assert_allclose(T.to_optimized(b)[0], affine.to_optimized(b), rtol=0, atol=2e-15)
    # any leading shape: (3, 50, 4) rows as the (150, 4) ones
    np.testing.assert_array_equal(T.to_optimized(b.reshape(3, 50, 4))[0].reshape(150, 4), T.to_optimized(b)[0])
    np.testing.assert_array_equal(T.from_optimized(b.reshape(3, 50, 4))[0].reshape(150, 4), T.from_optimized(b)[0])
    q = affine.to_optimized(b)
    np.testing.assert_allclose(T.from_optimized(q)[0], affine.from_optimized(q), rtol=0, atol=2e-14)
    codes, margin = T.encode_unorm16(b, margin=True)
    scaled = 65535 * np.clip(affine.to_optimized(b), 0, 1)
    np.testing.assert_allclose(margin, _to_half(scaled).min(axis=1) / 65535, rtol=0, atol=1e-13)
    assert ((scaled == 0) | (scaled == 65535)).any(axis=1)[5:15].all()
    clear = margin > CLEAR
    assert clear.sum() > 120 and codes.dtype == np.uint16
    np.testing.assert_array_equal(codes[clear], affine.encode_unorm16(b)[clear])
    np.testing.assert_array_equal(T.encode_unorm16(b)[0], codes)
    np.testing.assert_allclose(T.decode_unorm16(codes)[0], affine.decode_unorm16(codes), rtol=0, atol=2e-14)


def test_the_six_moment_words_are_the_float64_ones():
    b = _moments(150, 6, 6)
    np.testing.assert_allclose(T.to_optimized6(b)[0], affine.to_optimized6(b), rtol=0, atol=2e-15)
    words, margin = T.encode_r10g10b10a2(b, margin=True)
    scaled = 1023 * np.clip(affine.to_optimized6(b), 0, 1)
    np.testing.assert_allclose(margin, _to_half(scaled).min(axis=1) / 1023, rtol=0, atol=1e-13)
    clear = margin > CLEAR
    assert clear.sum() > 130 and words.dtype == np.uint32 and words.shape == (150, 2)
    np.testing.assert_array_equal(words[clear], affine.encode_r10g10b10a2(b)[clear])
    np.testing.assert_array_equal(T.encode_r10g10b10a2(b)[0], words)
    np.testing.assert_allclose(T.decode_r10g10b10a2(words)[0], affine.decode_r10g10b10a2(words), rtol=0, atol=2e-13)


def test_kept_mutant_a_rounding_slip_in_the_truth_is_seen_by_the_float64_encoder():
    """The 64-bit truth rounding v2 down (floor for round) disagrees with the float64 encoder off the boundaries."""
    r = _texels(40, 7)
    codes, margin = T.pack64(r, margin=True)
    clear = margin > CLEAR
    with kept_mutant("moments_ref/golden/texel_truth.py", "_unorm::mpmath.floor -> mpmath.ceil#0"):
        b = _moments(40, 8, 4)
        bad, m2 = T.encode_unorm16(b, margin=True)
        assert (bad[m2 > CLEAR] != affine.encode_unorm16(b)[m2 > CLEAR]).any()
    np.testing.assert_array_equal(codes[clear], packing.pack64(_saturate(r))[clear])
