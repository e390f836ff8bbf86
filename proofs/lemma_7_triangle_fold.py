"""Lemma 7 (HPG17 §3.5, Figure 5). On the depth codes 0 ≤ ỹ1 ≤ ỹ2 ≤ 1022, the fold

    (ỹ1, ỹ2) ↦ (ỹ1, ỹ2) if ỹ1 < 512, else (1023 − ỹ1, 1022 − ỹ2)

is injective with image in [0, 511] × [0, 1022], so the pair fits in 9 + 10 = 19 bits
and is recovered exactly; 18 bits cannot hold all pairs and the two unfolded 10-bit
codes would need 20, so the fold saves exactly one bit.

Proof. Unfolded pairs have ỹ1 ≤ 511 and ỹ1 ≤ ỹ2. A folded pair (ỹ1 ≥ 512) becomes
f1 = 1023 − ỹ1 ∈ [1, 511] and f2 = 1022 − ỹ2 ≤ 1022 − ỹ1 = f1 − 1 < f1, with f2 ≥ 0.
So the two images are disjoint (f2 ≥ f1 versus f2 < f1), each branch is injective
(affine with slope ±1), and the test f2 < f1 identifies the branch: the inverse is
the same formula applied again. There are 1023 · 1024 / 2 = 523776 > 2¹⁸ = 262144
pairs, so at least 19 bits are necessary (pigeonhole). ∎

The test enumerates all 523776 pairs (vectorized).
"""

import numpy as np

from moments_ref import packing as pk


def test_fold_exhaustive():
    t1, t2 = np.triu_indices(1023)
    f1, f2 = pk.fold(t1, t2)
    assert f1.max() < 2**9 and f2.max() < 2**10 and f1.min() >= 0 and f2.min() >= 0
    assert np.unique((f1 << 10) | f2).size == t1.size
    np.testing.assert_array_equal(np.where(t1 >= 512, f2 < f1, f2 >= f1), True)
    u1, u2 = pk.unfold(f1, f2)
    np.testing.assert_array_equal(u1, t1)
    np.testing.assert_array_equal(u2, t2)


def test_bit_count():
    pairs = 1023 * 1024 // 2
    assert 2**18 < pairs <= 2**19
    assert 2 * int(np.ceil(np.log2(1023))) == 20
