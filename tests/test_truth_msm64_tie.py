"""golden/truth.py's msm64_chain on a hand-built texel: which codes a rounding tie admits, and no others.

The optimized-basis values (Slides, "Compute moments in resolve") of a three-depth distribution are moved so
that channel 0 lies 10^-4 codes beside a half code (within the tie band: a rounding tie) and channel 1 0.3 codes beside one (0.8 above a
code: it rounds up, with no tie); the moments are taken back exactly. The chain's (lo, hi) must be the least and
largest lower bound (precise, mpmath) over the two texels of channel 0's two codes, decoded here by the
package's float64 decoder and biased by the formula.
"""

from __future__ import annotations

import numpy as np

from moments_ref import affine, precise
from moments_ref.golden import texel_truth
from moments_ref.golden.truth import CHAIN_TIE, msm64_chain
from moments_ref.moments import BIAS_UNORM16


def test_a_tied_channel_takes_both_codes_and_a_channel_beside_a_half_takes_its_own():
    z, w = np.array([-0.6, 0.1, 0.5]), np.array([0.3, 0.3, 0.4])
    b0 = np.array([(w * z**j).sum() for j in range(1, 5)])
    s = texel_truth.to_optimized(b0[None])[0][0] * 65535
    k = np.floor(s).astype(int)
    s[0], s[1] = k[0] + 0.5 + 1e-4, k[1] + 0.8  # 10^-4 codes from the half: inside the tie band (1/4 code)
    b = texel_truth.from_optimized((s / 65535)[None])[0]
    assert np.abs(texel_truth.to_optimized(b)[0][0] * 65535 - s).max() < 1e-6  # the positions survive the round trip
    zf = np.array([0.2])
    lo, hi = msm64_chain(b, zf, BIAS_UNORM16, tie=CHAIN_TIE)
    codes = np.rint(s).astype(int)
    codes[1] = k[1] + 1
    values = []
    for c0 in (k[0], k[0] + 1):
        c = codes.copy()
        c[0] = c0
        bq = affine.decode_unorm16(c.astype(np.uint16)[None])
        biased = (1 - BIAS_UNORM16.alpha) * bq + BIAS_UNORM16.alpha * np.asarray(BIAS_UNORM16.target)
        values.append(float(precise.shadow_intensity(biased, zf)[0]))
    np.testing.assert_allclose([lo[0], hi[0]], [min(values), max(values)], rtol=0, atol=1e-12)
    assert hi[0] - lo[0] > 1e-6  # the two codes matter
    # without the tie band (the exact value's own accuracy) channel 0's float64 rounding picks one code
    lo1, hi1 = msm64_chain(b, zf, BIAS_UNORM16)
    assert lo1[0] == hi1[0] and min(values) - 1e-12 <= lo1[0] <= max(values) + 1e-12
