"""The exact sums of the sweep's profiled conversion (sweep/profiled.py), against exact rationals.

The conversion rounds each converted moment once: its terms are split error-free (TwoSum, Dekker's
product), summed in three-fold precision (SumK, K = 3) and rounded to float32 with the residual deciding a
sum on a float32 midpoint (module docstring). Each step is checked here against ``fractions.Fraction``:

* TwoSum: s + e = a + b exactly, |e| ≤ ulp(s)/2; Dekker's product: p + e = a·b exactly;
* the rounded sum is the float32 nearest to the exact sum (ties to even), on sums with catastrophic
  cancellation (t + A + C + B + u − A − C − B with |A| up to 2^60, |t| down to 2^-60), on sums just off a float32 midpoint by 2^-60 of it
  (either side, the residual spread over several terms), on exact midpoints, and on one-term sums.

Kept mutants (tests/_mutants.py): one error-free pass instead of two, and the midpoint rule's direction
inverted, each shown giving another float32.
"""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest

from moments_ref.sweep import profiled

from _mutants import kept_mutant

PATH = "moments_ref/sweep/profiled.py"


def _round32(q):
    """The float32 nearest to the rational ``q`` (ties to even), chosen among three candidates by exact distance."""
    c = np.float32(float(q))
    cands = [np.nextafter(c, np.float32(-np.inf)), c, np.nextafter(c, np.float32(np.inf))]
    best = min(cands, key=lambda x: (abs(Fraction(float(x)) - q), int(np.asarray(x).view(np.uint32)) & 1))
    return np.float32(best)


def _expected(terms):
    t = np.stack(terms, axis=1)
    return np.array([_round32(sum(Fraction(float(v)) for v in row)) for row in t], np.float32)


def _signed(rng, n, lo, hi):
    return rng.choice([-1.0, 1.0], n) * 2.0 ** rng.uniform(lo, hi, n)


def _cancelling(rng, n):
    """t + A + C + B + u − A − C − B: three cancellations (|A| up to 2^60) leaving t + u (|t| down to 2^-60)."""
    a, b, c = _signed(rng, n, 40, 60), _signed(rng, n, -10, 10), _signed(rng, n, 10, 30)
    return [_signed(rng, n, -60, -40), a, c, b, _signed(rng, n, -40, -20), -a, -c, -b]


def _off_midpoint(rng, n):
    """Sums a hair (2^-60 relative, of either sign, or 0) off a float32 midpoint, spread over five terms."""
    f = rng.uniform(0.01, 1, n).astype(np.float32)
    mid = (f.astype(np.float64) + np.nextafter(f, np.float32(2)).astype(np.float64)) / 2  # exact in float64
    tiny = rng.choice([-1.0, 0.0, 1.0], n) * mid * 2.0**-60
    big = _signed(rng, n, 0, 30)  # cancelled exactly: the terms' exact sum is mid + tiny
    return [big, mid, tiny / 2, -big, tiny / 4, tiny / 4]


def _two_term_midpoint(rng, n):
    """mid + tiny in two terms: the residual is the second term itself."""
    f = rng.uniform(0.01, 1, n).astype(np.float32)
    mid = (f.astype(np.float64) + np.nextafter(f, np.float32(2)).astype(np.float64)) / 2
    return [mid, rng.choice([-1.0, 0.0, 1.0], n) * mid * 2.0**-60]


@pytest.mark.parametrize("make", [_cancelling, _off_midpoint, _two_term_midpoint])
def test_the_sum_is_the_exact_sum_rounded_once(make):
    rng = np.random.default_rng(3804)
    terms = make(rng, 3000)
    got = profiled._sum_rounded(terms)
    assert got.dtype == np.float32
    want = _expected(terms)
    np.testing.assert_array_equal(got.view(np.uint32), want.view(np.uint32))
    if make is not _cancelling:  # the residual decides: rounding the float64 sum alone (ties to even) would not do
        mid = terms[0] if make is _two_term_midpoint else terms[1]
        assert (mid.astype(np.float32) != want).sum() > len(mid) // 8


def test_random_sums_of_mixed_magnitudes_and_one_term_sums():
    rng = np.random.default_rng(3805)
    for m in (1, 2, 3, 7):
        terms = [_signed(rng, 2000, -40, 40) for _ in range(m)]
        np.testing.assert_array_equal(profiled._sum_rounded(terms).view(np.uint32), _expected(terms).view(np.uint32))


def test_two_sum_and_dekkers_product_are_error_free():
    rng = np.random.default_rng(3806)
    a, b = _signed(rng, 4000, -60, 60), _signed(rng, 4000, -60, 60)
    s, e = profiled._two_sum(a, b)
    for x, y, u, v in zip(a, b, s, e):
        assert Fraction(float(u)) + Fraction(float(v)) == Fraction(float(x)) + Fraction(float(y))
        assert abs(v) <= np.spacing(abs(u)) / 2
    for k in (-3e-7, 0.375, 6.0, 1 / 3):  # a bias α, a target, a binomial factor, a factor of 53 bits
        p, e = profiled._two_product(k, a)
        for x, u, v in zip(a, p, e):
            assert Fraction(float(u)) + Fraction(float(v)) == Fraction(k) * Fraction(float(x))


@pytest.mark.parametrize("mid", ["_sum_rounded::2 -> 1#0",
                                 "_sum_rounded::np.where(lo > 0, np.maximum(r, other), np.minimum(r, other)) -> "
                                 "np.where(lo > 0, np.minimum(r, other), np.maximum(r, other))#0"])
def test_kept_mutant_one_pass_or_the_midpoint_rule_inverted_rounds_elsewhere(mid):
    rng = np.random.default_rng(3804)
    terms = _cancelling(rng, 3000) if "2 -> 1" in mid else _off_midpoint(rng, 3000)
    with kept_mutant(PATH, mid):
        got = profiled._sum_rounded(terms)
    assert (got.view(np.uint32) != _expected(terms).view(np.uint32)).any()


def test_the_conversion_broadcasts_over_leading_axes():
    """House rule (every function broadcasts over leading axes): moments of shape (5, 7, 4), a single (4,) vector and
    (n, 6) six-moment rows convert as the same rows flattened to (n, 4) or (n, 6) do, bit for bit."""
    from moments_ref import golden
    from moments_ref.golden.conventions import profiled_case
    from moments_ref.golden.profile import Bias, Profile

    rng = np.random.default_rng(3807)
    profile = Profile(depth="[0,1]", bias=Bias(6e-5, (0.5, 0.3125, 0.2, 0.15), "before"))
    case = profiled_case(golden.CASES["shadow_intensity-lower-float32"], profile)
    z = rng.uniform(-1, 1, (35, 3))
    b = np.stack([(z**k).mean(axis=1) for k in range(1, 5)], axis=1).astype(np.float32)
    flat = profiled.convert_inputs(case, {"b": b, "zf": z[:, 0].astype(np.float32)})
    cube = profiled.convert_inputs(case, {"b": b.reshape(5, 7, 4), "zf": z[:, 0].astype(np.float32).reshape(5, 7)})
    one = profiled.convert_inputs(case, {"b": b[3], "zf": z[3, 0].astype(np.float32)})
    assert cube["b"].shape == (5, 7, 4) and one["b"].shape == (4,)
    np.testing.assert_array_equal(cube["b"].reshape(35, 4).view(np.uint32), flat["b"].view(np.uint32))
    np.testing.assert_array_equal(cube["zf"].reshape(35).view(np.uint32), flat["zf"].view(np.uint32))
    np.testing.assert_array_equal(one["b"].view(np.uint32), flat["b"][3].view(np.uint32))
