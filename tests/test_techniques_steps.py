"""The samples' mean of the resolve steps (techniques/_steps.py): NumPy's mean, the same values."""

import numpy as np
import pytest

from moments_ref.techniques._steps import resolve_features, sample_mean


@pytest.mark.parametrize("s", [1, 2, 4, 8, 16])
@pytest.mark.parametrize("c", [1, 2, 4])
def test_sample_mean_is_numpys_mean_bit_for_bit(s, c):
    # Values over 16 decades with both signs and signed zeros: any other order of the additions
    # (pairwise, from a zero start) rounds differently somewhere among these rows.
    rng = np.random.default_rng(s * 10 + c)
    f = rng.standard_normal((5, 37, s, c)) * 10.0 ** rng.integers(-8, 9, (5, 37, s, c))
    f[0, :3] = -0.0
    want = f.mean(axis=2)
    got = sample_mean(f)
    assert got.shape == want.shape and got.dtype == want.dtype
    assert np.array_equal(got, want) and np.array_equal(np.signbit(got), np.signbit(want))


def test_sequential_order_differs_from_pairwise():
    # The test above can fail: the in-order sum and a regrouped one differ on its data.
    rng = np.random.default_rng(4)
    f = rng.standard_normal((5, 37, 4, 2)) * 10.0 ** rng.integers(-8, 9, (5, 37, 4, 2))
    regrouped = (f[:, :, 0] + (f[:, :, 1] + f[:, :, 2] + f[:, :, 3])) / 4
    assert not np.array_equal(regrouped, sample_mean(f))


def test_resolve_features_is_the_mean_of_the_features():
    rng = np.random.default_rng(1)
    z = rng.uniform(-1, 1, (9, 11, 4)).astype(np.float32)

    def feature(x):
        return np.stack([np.exp(3 * x), -np.exp(-2 * x)], axis=-1)

    want = feature(z.astype(np.float64)).mean(axis=2)
    assert np.array_equal(resolve_features(z, feature), want)
