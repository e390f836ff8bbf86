"""The bias as a compiler may emit it (moments_ref.gpu.fused32): checked against exact rational arithmetic."""

from fractions import Fraction

import numpy as np

from moments_ref.gpu.fused32 import bias_fused, bias_lerp
from moments_ref.moments import BiasPreset

F32 = np.float32


def _half_ulp(x):
    x = F32(x)
    return Fraction(float(np.spacing(abs(x)))) / 2


def _moments(n=200):
    rng = np.random.default_rng(7)
    z = rng.uniform(-1, 1, n)
    return np.stack([z, z * z + 0.01, z ** 3, z ** 4 + 0.02], axis=-1).astype(F32)


def test_a_fused_lerp_is_the_exact_alpha_times_difference_plus_b_rounded_once_and_the_plain_one_twice():
    p = BiasPreset(0.3, (0.0, 0.628, 0.0, 0.628), "t")  # a large alpha: the product's rounding shows
    b = _moments()
    fused, plain = bias_lerp(b, p, fused=True), bias_lerp(b, p, fused=False)
    a = F32(p.alpha)
    for i in range(0, len(b), 7):
        for k in range(4):
            d = F32(F32(p.target[k]) - b[i, k])  # the subtraction, rounded
            exact = Fraction(float(a)) * Fraction(float(d)) + Fraction(float(b[i, k]))
            assert abs(Fraction(float(fused[i, k])) - exact) <= _half_ulp(fused[i, k])
            prod = F32(a * d)
            assert plain[i, k] == F32(prod + b[i, k])


def test_the_contracted_forms_of_the_bias_agree_within_a_few_ulps_and_are_not_all_identical():
    p = BiasPreset(0.3, (0.1, 0.4, 0.05, 0.3), "t")  # a large alpha: each rounding shows
    b = _moments(2000)
    forms = [bias_fused(b, p, s) for s in (False, True)] + [bias_lerp(b, p, f) for f in (False, True)]
    a, t = float(F32(p.alpha)), np.asarray(p.target, F32).astype(np.float64)
    exact = (1 - a) * b.astype(np.float64) + a * t  # within 2^-48 of the exact value
    scale = np.maximum(np.abs(b), np.abs(t).astype(F32))  # the terms' magnitude: each form rounds 2-3 times
    for f in forms:
        assert f.dtype == F32
        assert (np.abs(f - exact) <= 2 * np.spacing(scale)).all()
    assert any((f != forms[0]).any() for f in forms[1:])
