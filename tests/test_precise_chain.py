"""Issue 36, item 3: the mpmath twin of the NLQ chain (golden.truth.nlq_chain), by which the e2e-nlq and engine-nlq
flags are confirmed.

Away from code boundaries it agrees with the float64 chain (golden.endtoend.nlq_chain) to float64 rounding; on rows
built by hand so that the exact Φ lies on a code boundary it returns both codes' intensities, each checked against
the texel formats' own exact decoders (golden.texel_truth, written from docs/formats.md in Fractions) and the
clamped Algorithm 3.
"""

from __future__ import annotations

import numpy as np
import pytest

from moments_ref import precise
from moments_ref.golden import CASES, texel_truth, truth
from moments_ref.golden.endtoend import nlq_chain
from moments_ref.golden.profile import parse_profile
from moments_ref.golden.conventions import profiled_case
from moments_ref.moments import BIAS_FLOAT32, power_moments
from moments_ref.sweep import judge


def _random_rows(n, seed):
    rng = np.random.default_rng(seed)
    z = rng.uniform(-1, 1, (n, 4))
    w = rng.dirichlet(np.ones(4), n)
    return power_moments(z, w), rng.uniform(-1, 1, n)


@pytest.mark.parametrize("fmt", ["64", "32"])
@pytest.mark.parametrize("texel", [None, {"xi_rounding": "nearest", "depth_decode": "lower", "v2_decode": "upper",
                                          "xi_decode": "centre"}])
def test_twin_agrees_with_the_float64_chain_away_from_code_boundaries(fmt, texel):
    b, zf = _random_rows(60, 3)
    lo, hi = truth.nlq_chain(b, zf, fmt, BIAS_FLOAT32, texel=texel)
    ref = nlq_chain(fmt, BIAS_FLOAT32, texel=texel)(b, zf)[0]
    assert np.array_equal(lo, hi)  # no exact Φ of these rows lies within 1e-25 of a boundary
    assert np.abs(lo - ref).max() < 1e-12
    assert 0.05 < np.mean((lo > 0) & (lo < 1))  # rows inside the penumbra, not only 0 and 1


def test_phi_exact_is_phi_unrounded():
    b, _ = _random_rows(20, 4)
    r = np.vectorize(float)(precise.phi_exact(b, BIAS_FLOAT32))
    assert np.allclose(r, precise.phi(precise.bias_moments(b, BIAS_FLOAT32)), rtol=0, atol=1e-9)
    assert np.array_equal(np.vectorize(float)(precise.phi_exact(b)), precise.phi(b))  # unbiased: one rounding


def _b(y1, y2, v2):
    return np.array([[(1 - v2) * y1**k + v2 * y2**k for k in range(1, 5)]])


def _expected(texels, zf, decode):
    values = [truth.shade_clamped(decode(t)[0], np.array([zf]))[0] for t in texels]
    return min(values), max(values), values


def test_64_bit_row_on_a_rounding_tie_returns_both_codes():
    # depths -0.5, 0.5 with v2 = 1/2 (exact in binary; Φ of these moments is exact): 65535 v2 = 32767.5, a tie of
    # round-to-nearest; ξ4 = 0 clamps Ψ4 to 0, the ceil's boundary: codes 0 and 1.
    b, zf = _b(-0.5, 0.5, 0.5), 0.1
    lo, hi = truth.nlq_chain(b, np.array([zf]), "64")
    texels = [np.array([[16384, 49151, v, x]], np.uint16) for v in (32767, 32768) for x in (0, 1)]
    e_lo, e_hi, values = _expected(texels, zf, texel_truth.unpack64)
    assert (lo[0], hi[0]) == pytest.approx((e_lo, e_hi), abs=1e-15) and e_hi - e_lo > 1e-6
    assert len(set(values)) == 4
    # the package's float64 chain stores one of them
    assert lo[0] - 1e-15 <= nlq_chain("64", None)(b, np.array([zf]))[0][0] <= hi[0] + 1e-15
    # v2 off the tie by far more than the tie distance (65535 v2 = 32767.50003): one v2 code, 32768
    lo2, hi2 = truth.nlq_chain(_b(-0.5, 0.5, 0.5 + 2**-30), np.array([zf]), "64")
    e_lo2, e_hi2, _ = _expected([np.array([[16384, 49151, 32768, x]], np.uint16) for x in (0, 1)], zf,
                                texel_truth.unpack64)
    assert (lo2[0], hi2[0]) == pytest.approx((e_lo2, e_hi2), abs=1e-12)


def test_32_bit_row_on_a_cell_boundary_returns_both_cells():
    # v2 = 1/4: 128 √v2 = 64 exactly, the boundary of cells 63 and 64 (the fold does not apply: ỹ1 = 255 < 512)
    b, zf = _b(-0.5, 0.5, 0.25), 0.0
    lo, hi = truth.nlq_chain(b, np.array([zf]), "32")
    lay = texel_truth.LAYOUT32
    words = [np.array([(767 << lay["y2"][0]) | (255 << lay["y1"][0]) | (v << lay["v"][0])], np.uint32)
             for v in (63, 64)]
    e_lo, e_hi, _ = _expected(words, zf, texel_truth.unpack32)
    assert (lo[0], hi[0]) == pytest.approx((e_lo, e_hi), abs=1e-15) and e_hi - e_lo > 1e-3
    assert lo[0] - 1e-15 <= nlq_chain("32", None)(b, np.array([zf]))[0][0] <= hi[0] + 1e-15


def test_e2e_cases_confirm_with_the_twin_and_keep_the_float64_expected_value():
    case = CASES["e2e-nlq64-float32"]
    assert case.confirm_truth is not None and case.truth is None  # golden files keep the float64 chain
    b, zf = _random_rows(12, 5)
    inputs = {"b": b.astype(np.float32), "zf": zf.astype(np.float32)}
    exact = truth.nlq_chain(inputs["b"], inputs["zf"], "64", BIAS_FLOAT32)[0]
    got = {"intensity": np.concatenate([exact, np.where(exact > 0.5, exact - 0.2, exact + 0.2)]).astype(np.float32)}
    both = {k: np.concatenate([v, v]) for k, v in inputs.items()}
    assert judge.confirm(case, both, got).tolist() == [False] * 12 + [True] * 12
    # a profile's output convention reaches the twin: visibility flips the interval
    vis = profiled_case(case, parse_profile({"output": "visibility"}))
    lo, hi = vis.confirm_truth(b=inputs["b"].astype(float), zf=inputs["zf"].astype(float))[0]
    e_lo, e_hi = truth.nlq_chain(inputs["b"], inputs["zf"], "64", BIAS_FLOAT32, tie=truth.CHAIN_TIE)
    assert np.array_equal(lo, 1 - e_hi) and np.array_equal(hi, 1 - e_lo)


def test_msm64_twin_agrees_with_the_float64_chain_and_takes_both_codes_on_a_tie():
    from moments_ref.affine import decode_unorm16
    from moments_ref.golden.endtoend import _msm64
    from moments_ref.moments import BIAS_UNORM16, bias_moments
    from moments_ref.msm import shadow_intensity

    b, zf = _random_rows(40, 6)
    lo, hi = truth.msm64_chain(b, zf, BIAS_UNORM16)
    assert np.array_equal(lo, hi) and np.abs(lo - _msm64()(b, zf)[0]).max() < 1e-10
    # one depth at 0: b = 0, the optimized basis' R and B channels are exactly 1/2, 65535/2 a tie (round half up)
    lo, hi = truth.msm64_chain(np.zeros((1, 4)), np.array([0.1]), BIAS_UNORM16)
    texels = np.array([[r, 0, bb, 0] for r in (32767, 32768) for bb in (32767, 32768)], np.uint16)
    v = shadow_intensity(bias_moments(decode_unorm16(texels), BIAS_UNORM16), np.full(4, 0.1))
    assert (lo[0], hi[0]) == pytest.approx((v.min(), v.max()), abs=1e-9) and v.max() - v.min() > 1e-4
    assert CASES["e2e-msm64-float32"].confirm_truth is not None


def test_confirmation_takes_either_code_within_the_goldens_tie_band():
    from moments_ref.golden import bands

    assert truth.CHAIN_TIE == bands.TIE_BAND
    # v2 = 1/4 + 2^-24: 128 √v2 = 64 + 2^-17·(1 + …), 1.2e-4 cells (2^-21.4 of the range) above the boundary: one
    # cell exactly, both within the tie band (a float32 √ lands on either side)
    b, zf = _b(-0.5, 0.5, 0.25 + 2**-24), np.array([0.0])
    lo, hi = truth.nlq_chain(b, zf, "32")
    lo_t, hi_t = truth.nlq_chain(b, zf, "32", tie=truth.CHAIN_TIE)
    assert lo[0] == hi[0] and lo_t[0] <= lo[0] <= hi_t[0] and hi_t[0] - lo_t[0] > 1e-3
    lo_t2, hi_t2 = truth.nlq_chain(_b(-0.5, 0.5, 0.25 + 2**-12), zf, "32", tie=truth.CHAIN_TIE)
    assert lo_t2[0] == hi_t2[0]  # 0.016 cells away: outside the band, one cell
