"""Power moments, the Hankel matrix and biasing, checked by independent means.

References: the definition b_k = Σ w_l z_l^k (a Python loop with math.fsum), the
mpmath twins in moments_ref.precise, the preset values printed in HPG17 §3.2, and
the fact that the bias target b* is itself the moment vector of a distribution.
"""

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from moments_ref import InputError, precise
from moments_ref.moments import BIAS_FLOAT32, BIAS_UNORM16, bias_moments, hankel, power_moments
from moments_ref.tools.strategies import depth_distributions, moment_vectors


def _loop_moments(z, w, n):
    """b_k = Σ w_l z_l^k / Σ w_l by the definition (HPG17 §2), exactly summed."""
    total = math.fsum(w)
    return [math.fsum(wl * zl**k for zl, wl in zip(z, w)) / total for k in range(1, n + 1)]


@given(depth_distributions(), st.sampled_from([4, 6]))
def test_power_moments_match_definition(dist, n):
    z, w = dist
    b = power_moments(z, w, n=n)
    assert b.shape == (n,) and b.dtype == np.float64
    np.testing.assert_allclose(b, _loop_moments(z.tolist(), w.tolist(), n), rtol=0, atol=4e-16 * len(z))


@given(depth_distributions(), st.floats(1e-3, 1e3))
def test_weights_are_normalized(dist, scale):
    z, w = dist
    np.testing.assert_allclose(power_moments(z, w * scale), power_moments(z, w), rtol=0, atol=1e-15)


def test_equal_weights_default_and_mpmath_twin():
    z = np.array([-0.9, -0.1, 0.3, 0.7, 1.0])
    np.testing.assert_allclose(power_moments(z), _loop_moments(z.tolist(), [1.0] * 5, 4), atol=1e-16)
    np.testing.assert_allclose(power_moments(z, n=6), precise.power_moments(z, n=6), rtol=0, atol=2e-16)


def test_axis_handling():
    rng = np.random.default_rng(0)
    z = rng.uniform(-1, 1, (3, 5, 7))
    w = rng.uniform(0, 1, (3, 5, 7))
    for axis in (0, 1, 2, -1, -2):
        b = power_moments(z, w, axis=axis)
        zt, wt = np.moveaxis(z, axis, -1), np.moveaxis(w, axis, -1)
        assert b.shape == zt.shape[:-1] + (4,)
        for idx in np.ndindex(zt.shape[:-1]):
            np.testing.assert_allclose(b[idx], _loop_moments(zt[idx].tolist(), wt[idx].tolist(), 4), atol=1e-15)


def test_float32_stays_float32():
    z = np.linspace(-1, 1, 9, dtype=np.float32)
    b = power_moments(z)
    assert b.dtype == np.float32
    np.testing.assert_allclose(b, _loop_moments(z.astype(np.float64).tolist(), [1.0] * 9, 4), atol=1e-6)
    assert power_moments([1, 0, -1]).dtype == np.float64  # integers -> float64


@given(moment_vectors(n=4) | moment_vectors(n=6))
def test_hankel_structure(b):
    B = hankel(b)
    m = b.size // 2 + 1
    full = [1.0] + b.tolist()
    assert B.shape == (m, m)
    for i in range(m):
        for j in range(m):
            assert B[i, j] == full[i + j]


def test_hankel_broadcasts_and_is_psd_for_distributions():
    rng = np.random.default_rng(1)
    z = rng.uniform(-1, 1, (10, 6))
    b = power_moments(z)
    B = hankel(b)
    assert B.shape == (10, 3, 3)
    # Hankel matrices of distributions are positive semi-definite (Peters and Klein 2015, Prop. 4).
    assert (np.linalg.eigvalsh(B) > -1e-14).all()


def test_bias_presets_are_the_papers_values():
    # HPG17 §3.2: α = 3e-7, b* = (1, 0, 0.375, 0, 0.375) for floats; α = 6e-5, 0.628 for 64 bits.
    assert BIAS_FLOAT32.alpha == 3e-7 and BIAS_FLOAT32.target == (0.0, 0.375, 0.0, 0.375)
    assert BIAS_UNORM16.alpha == 6e-5 and BIAS_UNORM16.target == (0.0, 0.628, 0.0, 0.628)


@given(moment_vectors(), st.floats(0, 1), st.lists(st.floats(-1, 1), min_size=4, max_size=4))
def test_bias_is_the_affine_formula(b, alpha, target):
    got = bias_moments(b, (alpha, target))
    np.testing.assert_allclose(got, precise.bias_moments(b, (alpha, target)), rtol=0, atol=3e-16)


@given(moment_vectors(dtype=np.float32))
def test_bias_float32_arithmetic(b):
    got = bias_moments(b, BIAS_FLOAT32)
    assert got.dtype == np.float32
    np.testing.assert_allclose(got, precise.bias_moments(b, BIAS_FLOAT32), rtol=0, atol=2e-7)


def _lambda_min_target(preset):
    return np.linalg.eigvalsh(hankel(np.array(preset.target)))[0]


@given(depth_distributions())
def test_bias_lifts_xi4_above_its_floor(dist):
    # B(b') = (1 − α) B(b) + α B(b*) ⪰ α B(b*), and ξ4 = 1/(B⁻¹)_33 ≥ λ_min(B):
    # biased moments of any distribution have ξ4 ≥ α·λ_min(B(b*)) (≈ 6e-8 for floats).
    z, w = dist
    for preset in (BIAS_FLOAT32, BIAS_UNORM16):
        b = bias_moments(power_moments(z, w), preset)
        sigma2, xi4 = precise.pivots(b)
        floor = preset.alpha * _lambda_min_target(preset)
        assert xi4 >= floor * (1 - 1e-6)


def test_bias_target_is_a_distribution():
    # b* = (0, 0.375, 0, 0.375) are the moments of 0.625 δ0 + 0.1875 (δ−1 + δ1).
    np.testing.assert_array_equal(power_moments([-1.0, 0.0, 1.0], [0.1875, 0.625, 0.1875]),
                                  BIAS_FLOAT32.target)


def test_bias_floor_check_has_power():
    # Mutant: without the bias the same distribution violates the floor (two points: ξ4 = 0).
    b = power_moments([-0.5, 0.25], [0.5, 0.5])
    assert precise.pivots(b)[1] < BIAS_FLOAT32.alpha * _lambda_min_target(BIAS_FLOAT32)


@pytest.mark.parametrize(
    "call, words",
    [
        (lambda: power_moments([0.1, np.nan, 0.3]), ["z", "(1,)"]),
        (lambda: power_moments([[0.1, 0.2], [0.3, np.inf]]), ["z", "(1, 1)"]),
        (lambda: power_moments([0.1, 0.2, 0.3], [1.0, -1.0, 1.0]), ["weights", "(1,)"]),
        (lambda: power_moments([[0.1, 0.2], [0.3, 0.4]], [[1.0, 1.0], [0.0, 0.0]]), ["weights", "distribution"]),
        (lambda: power_moments([0.1, 0.2], n=5), ["n", "5"]),
        (lambda: power_moments(0.5), ["z", "scalar"]),
        (lambda: power_moments([0.1, 0.2], axis=3), ["axis", "3"]),
        (lambda: power_moments(["a", "b"]), ["z", "real"]),
        (lambda: hankel([0.1, 0.2, 0.3]), ["b", "4 or 6"]),
        (lambda: hankel([[0.0, 0.5, 0.0, 0.5], [0.0, np.nan, 0.0, 0.5]]), ["b", "(1, 1)"]),
        (lambda: bias_moments([0.0, 0.5, 0.0, 0.5], (1.5, (0, 0.375, 0, 0.375))), ["preset", "alpha"]),
        (lambda: bias_moments([0.0, 0.5, 0.0, 0.5], (0.1, (0, 0.375))), ["preset", "length"]),
        (lambda: bias_moments([0.0, 0.5, 0.0, 0.5], "float32"), ["preset"]),
    ],
)
def test_bad_input_names_argument_and_index(call, words):
    with pytest.raises(InputError) as info:
        call()
    for word in words:
        assert word in str(info.value)


def test_reduce_light_leaking_default_factor_is_98_percent():
    """Slides: 'divide by ~98%'; the default factor, exercised (a wrong default would pass otherwise)."""
    from moments_ref.msm import reduce_light_leaking

    assert reduce_light_leaking(0.49) == pytest.approx(0.5, abs=1e-15)
    assert reduce_light_leaking(np.float32(0.49)) == pytest.approx(0.5, abs=1e-7)
    assert reduce_light_leaking(np.float32(0.49)).dtype == np.float32
    assert reduce_light_leaking(0.99) == 1.0  # clamped
    assert reduce_light_leaking(0.0) == 0.0
