"""Tests of moments_ref.affine: optimized basis, UNORM16, 6-moment basis, R10G10B10A2.

Independent means used: sympy with exact coefficients (Rational, sqrt(3)) for the
4-moment matrix and its inverse; the slide's constants copied here as decimal
strings (Fractions) and evaluated by the test itself; exact rational rounding
(Fraction) as the oracle of the float -> UNORM conversion; exhaustive enumeration of
all codes; Chebyshev polynomials from numpy.polynomial; Python integer bit
arithmetic for the packed layout.
"""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np
import pytest
import sympy as sp
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp
from numpy.polynomial import chebyshev as cheb

from moments_ref import InputError, power_moments
from moments_ref import affine
from moments_ref.affine import (
    decode_r10g10b10a2,
    decode_unorm16,
    encode_r10g10b10a2,
    encode_unorm16,
    float_to_unorm,
    from_optimized,
    from_optimized6,
    to_optimized,
    to_optimized6,
    unorm_to_float,
)
from moments_ref.tools.strategies import depth_distributions, moment_vectors

DTYPES = [np.float64, np.float32]
STEP16 = 1.0 / 65535
STEP10 = 1.0 / 1023

# --- independent statements of the sources ------------------------------------------

SQ3 = sp.sqrt(3)
R = sp.Rational
#: Slides, "Compute moments in resolve" (the "3 2" and "12 9" of the extracted text
#: are sqrt(3)/2 and sqrt(12)/9 = 2 sqrt(3)/9).
M_EXACT = sp.Matrix(
    [
        [R(3, 2), 0, -2, 0],
        [0, 4, 0, -4],
        [SQ3 / 2, 0, -2 * SQ3 / 9, 0],
        [0, R(1, 2), 0, R(1, 2)],
    ]
)
C_EXACT = sp.Matrix([R(1, 2), 0, R(1, 2), 0])
#: Slides, "Retrieve moments", as printed (rows -1/3 0 sqrt3 0 / 0 0.125 0 1 / ...).
SLIDE_INVERSE = sp.Matrix(
    [
        [R(-1, 3), 0, SQ3, 0],
        [0, R(1, 8), 0, 1],
        [R(-3, 4), 0, R(3, 4) * SQ3, 0],
        [0, R(-1, 8), 0, 1],
    ]
)

#: Slides, 6-moment "Quantization transform", the rows as the text prints them.
M0_TEXT = [
    ["2.5", "-1.87499864", "1.26583039"],
    ["-10", "4.20757543", "-1.47644883"],
    ["8", "-1.83257679", "0.71061660"],
]
M1_TEXT = [
    ["4", "9", "-0.57759806"],
    ["-4", "-24", "4.61936648"],
    ["0", "16", "-3.07953907"],
]
C0_TEXT = ["0.5", "0.5", "0.5"]
C1_TEXT = ["0", "0", "0.018888946"]
#: Each printed coefficient is within 5e-9 of the intended one (8 decimals), the
#: offset within 5e-10; |z^k| <= 1, so a channel can be off by 3*5e-9 + 5e-10.
PRINT_TOL = 3 * 5e-9 + 5e-10


def _ulps(value: float, exact) -> float:
    """|value - exact| in units of the float64 spacing at exact (exact arithmetic)."""
    diff = abs(sp.Rational(value) - exact)
    if exact == 0:
        return 0.0 if value == 0 else math.inf
    return float(diff.evalf(40)) / float(np.spacing(abs(float(exact.evalf(40)))))


def _unorm_oracle(x: float, bits: int) -> int:
    """Nearest code to clamp(x)·(2^n − 1), ties up, in exact rational arithmetic."""
    c = min(max(Fraction(float(x)), Fraction(0)), Fraction(1))
    return math.floor(c * (2**bits - 1) + Fraction(1, 2))


def _basis6(z, matrix_text, offset_text, powers, transpose):
    """Evaluate a 6-moment triple for depths z from the slide's text, in float64."""
    m = np.array([[float(Fraction(v)) for v in row] for row in matrix_text])
    m = m.T if transpose else m
    c = np.array([float(Fraction(v)) for v in offset_text])
    p = np.stack([z**k for k in powers], axis=-1)
    return p @ m.T + c


def _in_unit_box(q, tol):
    return bool(q.min() >= -tol and q.max() <= 1 + tol)


Z_GRID = np.concatenate(
    [
        np.linspace(-1.0, 1.0, 200_001),
        # extrema of the 4-moment basis polynomials
        [0.5, -0.5, math.sqrt(3) / 2, -math.sqrt(3) / 2, 1 / math.sqrt(2), -1 / math.sqrt(2)],
    ]
)


# --- 4 moments: the matrix and its exact inverse ---------------------------------


def test_forward_matrix_exact():
    for i in range(4):
        for j in range(4):
            assert _ulps(affine.OPTIMIZED_MATRIX[i, j], M_EXACT[i, j]) <= 1.0, (i, j)
        assert _ulps(affine.OPTIMIZED_OFFSET[i], C_EXACT[i]) == 0.0


def test_inverse_exact_sympy():
    inv = sp.simplify(M_EXACT.inv())
    assert sp.simplify(M_EXACT * inv - sp.eye(4)) == sp.zeros(4, 4)
    # the hand derivation agrees with the slide's printed inverse
    assert sp.simplify(inv - SLIDE_INVERSE) == sp.zeros(4, 4)
    for i in range(4):
        for j in range(4):
            assert _ulps(affine.OPTIMIZED_INVERSE[i, j], inv[i, j]) <= 1.0, (i, j)


def test_inverse_check_has_power():
    # Mutant: one entry off by 1e-12 (a few thousand ulps) fails the check above.
    inv = sp.simplify(M_EXACT.inv())
    mutant = affine.OPTIMIZED_INVERSE.copy()
    mutant[2, 2] += 1e-12
    assert _ulps(mutant[2, 2], inv[2, 2]) > 1.0


@pytest.mark.parametrize("dtype", DTYPES)
def test_functions_apply_the_exact_matrices(dtype):
    # Columns of the affine maps, read off through the public functions.
    eye = np.eye(4, dtype=dtype)
    fwd = to_optimized(eye) - to_optimized(np.zeros(4, dtype=dtype))  # rows = columns of M
    c = np.asarray(affine.OPTIMIZED_OFFSET, dtype=dtype)
    back = from_optimized(eye + c)  # rows = columns of M^-1 (e_j + c - c is exact)
    inv = M_EXACT.inv()
    tol = 2 * np.finfo(dtype).eps
    for i in range(4):
        for j in range(4):
            assert abs(fwd[j, i] - float(M_EXACT[i, j])) <= tol * 4
            assert abs(back[j, i] - float(inv[i, j])) <= tol * 2


def test_basis_polynomials():
    # Applied to b(z) of a single depth, the map is the basis of quartic polynomials.
    z = Z_GRID
    q = to_optimized(power_moments(z[:, None]))
    expect = np.stack(
        [
            1.5 * z - 2 * z**3 + 0.5,
            4 * z**2 - 4 * z**4,
            math.sqrt(3) / 2 * z - 2 * math.sqrt(3) / 9 * z**3 + 0.5,
            0.5 * z**2 + 0.5 * z**4,
        ],
        axis=-1,
    )
    np.testing.assert_allclose(q, expect, rtol=0, atol=8 * np.finfo(float).eps)


# --- 4 moments: range -----------------------------------------------------------


@pytest.mark.parametrize("dtype", DTYPES)
def test_every_depth_maps_into_unit_box(dtype):
    b = power_moments(Z_GRID[:, None].astype(dtype))
    q = to_optimized(b)
    assert q.dtype == dtype
    assert _in_unit_box(q, 4 * np.finfo(dtype).eps)
    # the range is used: each channel reaches 0 and 1 (the basis is optimized)
    q64 = to_optimized(power_moments(Z_GRID[:, None]))
    np.testing.assert_allclose(q64.min(axis=0), 0.0, atol=1e-9)
    np.testing.assert_allclose(q64.max(axis=0), 1.0, atol=1e-9)


def test_unit_box_check_has_power():
    # Mutant: reading the garbled slide text literally (B = 1.5 z − (12/9) z³ + 0.5,
    # sqrt signs lost) leaves [0, 1]; so the property pins the sqrt(3) reading.
    z = Z_GRID
    wrong_b = 1.5 * z - 12 / 9 * z**3 + 0.5
    assert wrong_b.max() > 1.1


@given(z=st.floats(-1, 1))
def test_single_depth_in_unit_box(z):
    q = to_optimized(power_moments([z]))
    assert _in_unit_box(q, 4 * np.finfo(float).eps)


@pytest.mark.parametrize("dtype", DTYPES)
@given(data=st.data())
def test_distribution_moments_in_unit_box(dtype, data):
    # Convexity: moments of any distribution on [-1, 1] are a convex combination.
    b = data.draw(moment_vectors(dtype=dtype))
    q = to_optimized(b)
    assert _in_unit_box(q, 8 * np.finfo(dtype).eps)


# --- 4 moments: numerical round trip --------------------------------------------------


@pytest.mark.parametrize("dtype", DTYPES)
@given(data=st.data())
def test_round_trip_optimized(dtype, data):
    q = data.draw(hnp.arrays(dtype, (5, 4), elements=st.floats(0, 1, width=np.finfo(dtype).bits)))
    eps = np.finfo(dtype).eps
    back = to_optimized(from_optimized(q))
    assert back.dtype == dtype
    assert np.abs(back - q).max() <= 4 * eps  # measured: 2.6 eps
    b = data.draw(moment_vectors(dtype=dtype))
    assert np.abs(from_optimized(to_optimized(b)) - b).max() <= 4 * eps  # measured: 1.5 eps


# --- float -> UNORM rounding --------------------------------------------------------


def test_tie_rule_exact_halfway():
    # 2^n − 1 is odd, so 0.5 is the only float in [0, 1] at an exact tie; it goes up.
    assert float_to_unorm([0.5])[0] == 32768
    assert float_to_unorm([0.5], bits=10)[0] == 512
    assert float_to_unorm([0.5], bits=2)[0] == 2  # 1.5 -> 2
    assert float_to_unorm(np.float32([0.5]))[0] == 32768
    # In the texel: R and B of any symmetric distribution sit exactly on the tie.
    for b in ([0.0, 0.0, 0.0, 0.0], power_moments([-0.5, 0.5])):
        u = encode_unorm16(b)
        assert u[0] == 32768 and u[2] == 32768
    assert np.all(encode_r10g10b10a2(np.zeros(6)) & 0x3FF == [512, 0])


@pytest.mark.parametrize("bits", [16, 10])
@given(k=st.integers(0, 1022), side=st.sampled_from([-2, -1, 0, 1, 2]))
def test_near_ties_against_exact_oracle(bits, k, side):
    top = 2**bits - 1
    x = (k + 0.5) / top
    for _ in range(abs(side)):
        x = np.nextafter(x, 2.0 if side > 0 else -1.0)
    for dt in DTYPES:
        xd = np.asarray([x], dtype=dt)
        assert int(float_to_unorm(xd, bits)[0]) == _unorm_oracle(xd[0], bits)


def test_near_tie_test_has_power():
    # Mutant: the naive floor(x·65535 + 0.5) in float64 (and np.rint) misround some
    # of the floats nearest to the ties (their product rounds onto k + 0.5); the
    # exact implementation does not.
    k = np.arange(0, 65535, 7)
    t = (k + 0.5) / 65535
    x = np.concatenate([t, np.nextafter(t, 0), np.nextafter(t, 2)])
    oracle = np.array([_unorm_oracle(v, 16) for v in x])
    assert np.any(np.floor(x * 65535 + 0.5) != oracle)
    assert np.any(np.rint(x * 65535) != oracle)
    np.testing.assert_array_equal(float_to_unorm(x), oracle)


@given(x=st.floats(allow_nan=False, allow_infinity=False), bits=st.sampled_from([2, 10, 16]))
def test_float_to_unorm_matches_oracle(x, bits):
    assert int(float_to_unorm([x], bits)[0]) == _unorm_oracle(x, bits)


def test_clamping():
    x = [-1e300, -1.0, -0.0, -1e-300, 1 + 2**-52, 2.0, 1e300]
    np.testing.assert_array_equal(float_to_unorm(x), [0, 0, 0, 0, 65535, 65535, 65535])
    # Moments outside the moment space are clamped, not an error.
    np.testing.assert_array_equal(encode_unorm16([2.0, 0.0, 0.0, 0.0]), [65535, 0, 65535, 0])
    np.testing.assert_array_equal(encode_unorm16([-2.0, 0.0, 0.0, 0.0]), [0, 0, 0, 0])
    np.testing.assert_array_equal(encode_unorm16([0.0, 1.0, 0.0, 3.0]), [32768, 0, 32768, 65535])


def test_unorm_to_float():
    u = np.arange(1024, dtype=np.uint16)
    np.testing.assert_array_equal(unorm_to_float(u, 10), np.array([k / 1023 for k in range(1024)]))
    f32 = unorm_to_float(u, 10, dtype=np.float32)
    assert f32.dtype == np.float32
    np.testing.assert_array_equal(f32, np.float32(u) / np.float32(1023))


# --- 64-bit texel: UNORM16 -------------------------------------------------------------


def _all_codes(n_codes, channels, seed):
    """Every code in every channel once; other channels permuted so they vary too."""
    rng = np.random.default_rng(seed)
    cols = [np.arange(n_codes)] + [rng.permutation(n_codes) for _ in range(channels - 1)]
    return np.stack(cols, axis=-1)


@pytest.mark.parametrize("dtype", DTYPES)
def test_exhaustive_unorm16_round_trip(dtype):
    u = _all_codes(65536, 4, seed=16).astype(np.uint16)
    b = decode_unorm16(u, dtype=dtype)
    assert b.dtype == dtype
    np.testing.assert_array_equal(encode_unorm16(b), u)
    # each channel in turn holds every code (checked, not assumed)
    assert all(np.unique(u[:, c]).size == 65536 for c in range(4))


@pytest.mark.parametrize("dtype", DTYPES)
@given(data=st.data())
def test_encode_decode_within_half_step(dtype, data):
    b = data.draw(moment_vectors(dtype=dtype))
    q_true = to_optimized(b.astype(np.float64))
    u = encode_unorm16(b)
    assert u.dtype == np.uint16 and u.shape == (4,)
    b_back = decode_unorm16(u, dtype=dtype)
    assert b_back.dtype == dtype
    q_back = to_optimized(b_back.astype(np.float64))
    slack = 16 * np.finfo(dtype).eps
    assert np.abs(q_back - np.clip(q_true, 0, 1)).max() <= 0.5 * STEP16 + slack


def test_shapes_broadcast():
    b = power_moments(np.linspace(-1, 1, 2 * 3 * 5).reshape(2, 3, 5))
    u = encode_unorm16(b)
    assert u.shape == (2, 3, 4)
    np.testing.assert_array_equal(encode_unorm16(b.reshape(6, 4)).reshape(2, 3, 4), u)
    assert decode_unorm16(u).shape == (2, 3, 4)
    assert to_optimized([0, 0, 0, 0]).dtype == np.float64  # ints -> float64


# --- six moments ------------------------------------------------------------------------


def test_six_moment_orientation():
    z = np.linspace(-1.0, 1.0, 200_001)
    q0 = _basis6(z, M0_TEXT, C0_TEXT, (1, 3, 5), transpose=True)
    q1 = _basis6(z, M1_TEXT, C1_TEXT, (2, 4, 6), transpose=True)
    assert _in_unit_box(q0, PRINT_TOL) and _in_unit_box(q1, PRINT_TOL)
    # the range is used: each channel reaches 0 and 1 up to the printed precision
    # (B1 peaks at 1 but ends at 0.98 for z = ±1)
    q = np.concatenate([q0, q1], axis=-1)
    np.testing.assert_allclose(q.min(axis=0), 0.0, atol=1e-6)
    np.testing.assert_allclose(q.max(axis=0), 1.0, atol=1e-6)
    # the library uses this orientation
    got = to_optimized6(power_moments(z[:, None], n=6))
    np.testing.assert_allclose(got, q, rtol=0, atol=64 * np.finfo(float).eps)
    assert _in_unit_box(got, PRINT_TOL + 64 * np.finfo(float).eps)


def test_six_moment_other_orientation_fails():
    z = np.linspace(-1.0, 1.0, 20_001)
    q0 = _basis6(z, M0_TEXT, C0_TEXT, (1, 3, 5), transpose=False)
    q1 = _basis6(z, M1_TEXT, C1_TEXT, (2, 4, 6), transpose=False)
    assert not _in_unit_box(q0, 0.5)
    assert not _in_unit_box(q1, 0.5)


def test_six_moment_chebyshev():
    # Claimed in the module docstring: R0 = (T5+1)/2, R1 = (1−T4)/2, G1 = (T6+1)/2.
    z = np.linspace(-1, 1, 1001)
    q = to_optimized6(power_moments(z[:, None], n=6))
    t = [cheb.chebval(z, [0] * k + [1]) for k in range(7)]
    atol = 64 * np.finfo(float).eps
    np.testing.assert_allclose(q[:, 0], (t[5] + 1) / 2, atol=atol)
    np.testing.assert_allclose(q[:, 3], (1 - t[4]) / 2, atol=atol)
    np.testing.assert_allclose(q[:, 4], (t[6] + 1) / 2, atol=atol)


@pytest.mark.parametrize("dtype", DTYPES)
@given(data=st.data())
def test_six_moment_distributions_in_unit_box(dtype, data):
    b = data.draw(moment_vectors(dtype=dtype, n=6))
    q = to_optimized6(b)
    assert q.dtype == dtype
    assert _in_unit_box(q, PRINT_TOL + 64 * np.finfo(dtype).eps)


def test_six_moment_inverse_exact():
    # from_optimized6 against sympy's exact inverse of the printed (transposed) matrices.
    m0t = sp.Matrix([[sp.Rational(v) for v in row] for row in M0_TEXT]).T
    m1t = sp.Matrix([[sp.Rational(v) for v in row] for row in M1_TEXT]).T
    c0 = sp.Matrix([sp.Rational(v) for v in C0_TEXT])
    c1 = sp.Matrix([sp.Rational(v) for v in C1_TEXT])
    rng = np.random.default_rng(6)
    q = rng.random((8, 6))
    got = from_optimized6(q)
    for row, g in zip(q, got):
        qr = [sp.Rational(float(v)) for v in row]
        odd = m0t.inv() * (sp.Matrix(qr[:3]) - c0)
        even = m1t.inv() * (sp.Matrix(qr[3:]) - c1)
        exact = np.array([float(v) for pair in zip(odd, even) for v in pair])  # b1..b6
        np.testing.assert_allclose(g, exact, rtol=0, atol=64 * np.finfo(float).eps * np.abs(exact).max())


@pytest.mark.parametrize("dtype", DTYPES)
@given(data=st.data())
def test_six_moment_round_trip(dtype, data):
    eps = np.finfo(dtype).eps
    q = data.draw(hnp.arrays(dtype, (3, 6), elements=st.floats(0, 1, width=np.finfo(dtype).bits)))
    back = to_optimized6(from_optimized6(q))
    assert back.dtype == dtype
    assert np.abs(back - q).max() <= 64 * eps  # measured: 35 eps (cond(M0) = 33, cond(M1) = 48)
    b = data.draw(moment_vectors(dtype=dtype, n=6))
    assert np.abs(from_optimized6(to_optimized6(b)) - b).max() <= 16 * eps  # measured: 4.5 eps


@pytest.mark.parametrize("dtype", DTYPES)
@given(data=st.data())
def test_r10g10b10a2_within_half_step(dtype, data):
    b = data.draw(moment_vectors(dtype=dtype, n=6))
    q_true = np.clip(to_optimized6(b.astype(np.float64)), 0, 1)
    p = encode_r10g10b10a2(b)
    assert p.dtype == np.uint32 and p.shape == (2,)
    b_back = decode_r10g10b10a2(p, dtype=dtype)
    assert b_back.dtype == dtype
    q_back = to_optimized6(b_back.astype(np.float64))
    assert np.abs(q_back - q_true).max() <= 0.5 * STEP10 + 256 * np.finfo(dtype).eps


def _pack(codes):
    """R10G10B10A2 words from (..., 6) codes with plain Python integers."""
    flat = codes.reshape(-1, 6)
    words = [
        [int(r[0]) | int(r[1]) << 10 | int(r[2]) << 20, int(r[3]) | int(r[4]) << 10 | int(r[5]) << 20]
        for r in flat
    ]
    return np.array(words, dtype=np.uint32).reshape(codes.shape[:-1] + (2,))


@pytest.mark.parametrize("dtype", DTYPES)
def test_exhaustive_r10g10b10a2_round_trip(dtype):
    p = _pack(_all_codes(1024, 6, seed=10))
    np.testing.assert_array_equal(encode_r10g10b10a2(decode_r10g10b10a2(p, dtype=dtype)), p)


@given(dist=depth_distributions())
def test_r10g10b10a2_bit_layout(dist):
    z, w = dist
    b = power_moments(z, w, n=6)
    p = encode_r10g10b10a2(b)
    q = to_optimized6(b)
    expect = [_unorm_oracle(v, 10) for v in q]
    for t in range(2):
        word = int(p[t])
        assert word >> 30 == 0  # A bits are zero
        assert [word & 0x3FF, (word >> 10) & 0x3FF, (word >> 20) & 0x3FF] == expect[3 * t : 3 * t + 3]
    # The little-endian byte image of word 0 starts with R's low 8 bits.
    assert p[:1].astype("<u4").tobytes()[0] == expect[0] & 0xFF


def test_r10g10b10a2_ignores_alpha():
    p = _pack(_all_codes(1024, 6, seed=3)[:50])
    with_alpha = p | np.uint32(3 << 30)
    np.testing.assert_array_equal(decode_r10g10b10a2(with_alpha), decode_r10g10b10a2(p))


# --- dtype policy -------------------------------------------------------------------------


@pytest.mark.parametrize(
    "fn,size",
    [(to_optimized, 4), (from_optimized, 4), (to_optimized6, 6), (from_optimized6, 6)],
)
def test_dtype_policy(fn, size):
    assert fn(np.full(size, 0.25, dtype=np.float32)).dtype == np.float32
    assert fn(np.full(size, 0.25)).dtype == np.float64
    assert fn([0] * size).dtype == np.float64


def test_decode_dtypes():
    u = np.array([1, 2, 3, 4], dtype=np.uint16)
    assert decode_unorm16(u).dtype == np.float64
    assert decode_unorm16(u, dtype=np.float32).dtype == np.float32
    p = np.array([1, 2], dtype=np.uint32)
    assert decode_r10g10b10a2(p, dtype=np.float32).dtype == np.float32


# --- bad inputs -----------------------------------------------------------------------------


@pytest.mark.parametrize("fn,size", [(to_optimized, 4), (from_optimized, 4), (encode_unorm16, 4),
                                     (to_optimized6, 6), (from_optimized6, 6), (encode_r10g10b10a2, 6)])
@pytest.mark.parametrize("bad", ["nan", "inf", "short", "long", "scalar", "complex", "object", "str"])
def test_bad_float_inputs(fn, size, bad):
    x = np.full((2, 3, size), 0.25)
    if bad == "nan":
        x[1, 2, 0] = np.nan
    elif bad == "inf":
        x[0, 1, size - 1] = -np.inf
    elif bad == "short":
        x = x[..., :-1]
    elif bad == "long":
        x = np.concatenate([x, x[..., :1]], axis=-1)
    elif bad == "scalar":
        x = 0.25
    elif bad == "complex":
        x = x.astype(complex)
    elif bad == "object":
        x = x.astype(object)
    elif bad == "str":
        x = [["a"] * size]
    with pytest.raises(InputError) as info:
        fn(x)
    msg = str(info.value)
    assert msg.split(":")[0] in ("b", "q")
    if bad == "nan":
        assert "(1, 2, 0)" in msg
    if bad == "inf":
        assert "(0, 1, " in msg


@pytest.mark.parametrize("fn", [from_optimized, from_optimized6])
def test_from_optimized_refuses_codes(fn):
    size = 4 if fn is from_optimized else 6
    with pytest.raises(InputError, match="decode"):
        fn(np.zeros(size, dtype=np.uint16))


@pytest.mark.parametrize(
    "u",
    [
        np.zeros(4, dtype=np.float64),
        np.zeros(4, dtype=np.int32),
        np.zeros(4, dtype=np.uint32),
        np.zeros(4, dtype=np.uint8),
        [0, 0, 0, 0],
        np.zeros(3, dtype=np.uint16),
        np.zeros((2, 5), dtype=np.uint16),
        np.uint16(0),
    ],
)
def test_decode_unorm16_bad(u):
    with pytest.raises(InputError, match="^u:"):
        decode_unorm16(u)


@pytest.mark.parametrize(
    "p",
    [
        np.zeros(2, dtype=np.uint16),
        np.zeros(2, dtype=np.int64),
        np.zeros(2, dtype=np.float32),
        np.zeros(3, dtype=np.uint32),
        [1, 2],
    ],
)
def test_decode_r10g10b10a2_bad(p):
    with pytest.raises(InputError, match="^p:"):
        decode_r10g10b10a2(p)


@pytest.mark.parametrize("dtype", [np.float16, np.int32, "complex128", "nonsense"])
def test_decode_bad_dtype(dtype):
    with pytest.raises(InputError, match="^dtype:"):
        decode_unorm16(np.zeros(4, dtype=np.uint16), dtype=dtype)
    with pytest.raises(InputError, match="^dtype:"):
        decode_r10g10b10a2(np.zeros(2, dtype=np.uint32), dtype=dtype)


@pytest.mark.parametrize("bits", [0, 17, True, 2.5, "16"])
def test_bad_bits(bits):
    with pytest.raises(InputError, match="^bits:"):
        float_to_unorm([0.5], bits)
    with pytest.raises(InputError, match="^bits:"):
        unorm_to_float(np.zeros(1, dtype=np.uint16), bits)


def test_unorm_to_float_bad_codes():
    with pytest.raises(InputError, match=r"index \(2,\)"):
        unorm_to_float(np.array([0, 1023, 1024], dtype=np.uint16), 10)
    with pytest.raises(InputError, match="^u:"):
        unorm_to_float(np.array([0, 1], dtype=np.int16), 10)
    with pytest.raises(InputError, match="^x:"):
        float_to_unorm([np.nan])


def _unorm_oracle_float32(x, bits):
    """The rule's codes of float32 ``x`` in [0, 1], exactly, in integers: ``x = M·2^(E−24)``,
    ``floor(x·(2ⁿ − 1) + ½) = (2·M·(2ⁿ − 1) + 2^(24−E)) >> (25 − E)`` (0 below 2⁻³⁸)."""
    f, e = np.frexp(x.astype(np.float64))
    m = (f * 2.0**24).astype(np.int64)  # exact: 24 significant bits
    e = e.astype(np.int64)
    tiny = e < -37
    e = np.where(tiny, 0, e)
    code = (2 * m * (2**bits - 1) + (np.int64(1) << (24 - e))) >> (25 - e)
    return np.where(tiny, 0, code)


@pytest.mark.parametrize("bits", [16, 10, 2])
def test_float32_codes_exact_at_every_tie(bits):
    # Every float32 within 4 ulps of every tie (k + ½)/(2ⁿ − 1), and the first and last floats of
    # [0, 1]: the float32 path (an exact float64 product and floor(s + ½)) against integer arithmetic.
    top = 2**bits - 1
    t = ((np.arange(top) + 0.5) / top).astype(np.float32)
    near = [t]
    for direction in (0.0, 2.0):
        u = t
        for _ in range(4):
            u = np.nextafter(u, np.float32(direction))
            near.append(u)
    ends = np.float32([0.0, 1.0, np.nextafter(np.float32(1), np.float32(0)), 2.0**-126, 2.0**-149, 2.0**-38])
    x = np.concatenate(near + [ends])
    oracle = _unorm_oracle_float32(x, bits)
    assert np.array_equal(float_to_unorm(x, bits), oracle)
    spot = np.random.default_rng(bits).choice(x.size, min(200, x.size), replace=False)  # vs the rational oracle
    assert [_unorm_oracle(float(v), bits) for v in x[spot]] == oracle[spot].tolist()
