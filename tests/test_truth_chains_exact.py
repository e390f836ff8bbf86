"""golden/truth.py's chains against the papers' equations written out here in mpmath at 60 digits.

msm64_chain (Slides, "Compute moments in resolve" and "Retrieve moments", then HPG17 Algorithm 1): the four
UNORM16 codes round_half_up(65535 clamp(M b + c, 0, 1)) with the slide's matrix typed here (rows (1.5, 0, −2, 0),
(0, 4, 0, −4), (√3/2, 0, −2√3/9, 0), (0, 1/2, 0, 1/2), offset (1/2, 0, 1/2, 0)), decoded by solving the slide's
affine map by hand (b2 ± b4 from the second and fourth rows, b1, b3 from the other two), biased by
(1 − α) b + α b*, and bounded by Algorithm 1 as Peters and Klein state it: the support {zf, z2, z3} of the
canonical representation (B(b) c = (1, zf, zf²), the roots of c2 z² + c1 z + c0), its weights from the
Vandermonde system with right side (1, b1, b2), the lower bound the sum of the weights of the points below zf.

nlq_chain (HPG17 Eq. (4), §3.3, §3.5, docs/formats.md): the moments are built here from a chosen
(y1, y2, v2, ξ4) by Eq. (4), so the position of each channel against its code boundaries is known; the 64-bit codes
are round(65535 (y + 1)/2), round(65535 v2), ceil(65535 Ψ4(ξ4)), the 32-bit cells ⌊511.5 (y + 1)⌋ (at most 1022),
each decoded as docs/formats.md says, and Algorithm 3 is truth.shade_clamped on the decoded texel (itself checked
against precise.shade and the float64 Algorithm 3 in tests/test_truth_shade.py).

A tie (both codes of a channel) is asked of a channel whose exact value lies within the tie, a fraction of the code's
range, of a rounding boundary; the default tie is 10^-(dps/2) (the docstrings), checked here at dps = 20 (10^-10).
"""

from __future__ import annotations

from itertools import product

import mpmath
import numpy as np
import pytest

from moments_ref.golden.truth import CHAIN_TIE, msm64_chain, nlq_chain, shade_clamped
from moments_ref.moments import BIAS_UNORM16
from _mutants import kept_mutant

DPS = 60
TOP = 65535


def _mpf(x):
    return mpmath.mpf(float(x))


def _channels(b):
    """Slides, "Compute moments in resolve": M b + c, exactly."""
    b1, b2, b3, b4 = (_mpf(x) for x in b)
    s3 = mpmath.sqrt(3)
    return [mpmath.mpf(3) / 2 * b1 - 2 * b3 + mpmath.mpf(1) / 2, 4 * b2 - 4 * b4,
            s3 / 2 * b1 - 2 * s3 / 9 * b3 + mpmath.mpf(1) / 2, (b2 + b4) / 2]


def _decode(codes):
    """Slides, "Retrieve moments": M⁻¹ (q − c) with q = codes / 65535, solved by hand."""
    return _inverse([mpmath.mpf(int(c)) / TOP for c in codes])


def _inverse(q):
    """M⁻¹ (q − c) for the optimized basis values q."""
    q0, q1, q2, q3 = q
    b2, b4 = q3 + q1 / 8, q3 - q1 / 8  # 4 (b2 − b4) = q1, (b2 + b4) / 2 = q3
    # 3/2 b1 − 2 b3 = q0 − 1/2 and (√3/2 b1 − 2√3/9 b3) 9/√3 = 9/2 b1 − 2 b3 = 3√3 (q2 − 1/2)
    b1 = (3 * mpmath.sqrt(3) * (q2 - mpmath.mpf(1) / 2) - (q0 - mpmath.mpf(1) / 2)) / 3
    b3 = (mpmath.mpf(3) / 2 * b1 - (q0 - mpmath.mpf(1) / 2)) / 2
    return [b1, b2, b3, b4]


def _lower_bound(b, zf):
    """Algorithm 1's lower bound from the canonical representation (Peters and Klein 2015, Alg. 1)."""
    b1, b2, b3, b4 = b
    c = mpmath.lu_solve(mpmath.matrix([[1, b1, b2], [b1, b2, b3], [b2, b3, b4]]), mpmath.matrix([1, zf, zf * zf]))
    r = mpmath.sqrt(c[1] ** 2 - 4 * c[2] * c[0])
    z2, z3 = sorted([(-c[1] - r) / (2 * c[2]), (-c[1] + r) / (2 * c[2])])
    w = mpmath.lu_solve(mpmath.matrix([[1, 1, 1], [zf, z2, z3], [zf**2, z2**2, z3**2]]), mpmath.matrix([1, b1, b2]))
    return sum((w[i] for i, z in ((1, z2), (2, z3)) if z < zf), mpmath.mpf(0))


def _msm64(codes, zf):
    """The 64-bit chain on one texel: decode, bias (BIAS_UNORM16), Algorithm 1."""
    a, t = _mpf(BIAS_UNORM16.alpha), [_mpf(x) for x in BIAS_UNORM16.target]
    b = [(1 - a) * x + a * tk for x, tk in zip(_decode(codes), t)]
    return _lower_bound(b, _mpf(zf))


def _codes_and_gaps(b):
    """The exact codes and each channel's distance (in codes) to its nearest rounding boundary k + 1/2."""
    codes, gaps = [], []
    for v in _channels(b):
        s = min(max(v, mpmath.mpf(0)), mpmath.mpf(1)) * TOP
        codes.append(int(mpmath.floor(s + mpmath.mpf(1) / 2)))
        gaps.append(abs(s - mpmath.floor(s) - mpmath.mpf(1) / 2))
    return codes, gaps


def _texel_at(b0, offsets):
    """float64 moments whose channels lie ``offsets`` (codes, None: as they are) from a half code of b0's."""
    with mpmath.workdps(DPS):
        s = [v * TOP for v in _channels(b0)]
        s = [x if d is None else mpmath.floor(x) + mpmath.mpf(1) / 2 + mpmath.mpf(d) for x, d in zip(s, offsets)]
        b = np.array([float(x) for x in _inverse([x / TOP for x in s])])
        codes, gaps = _codes_and_gaps(b)
        for d, g in zip(offsets, gaps):  # the float64 moments keep each chosen position to 10^-10 codes
            assert d is None or abs(g - abs(d)) < 1e-10
    return b, codes, gaps


def _mixture(z, w):
    z, w = np.asarray(z, np.float64), np.asarray(w, np.float64) / np.sum(w)
    return np.array([(w * z**k).sum() for k in range(1, 5)])


B0 = _mixture([-0.6, 0.1, 0.5], [0.3, 0.3, 0.4])


def _allowed(b, band):
    """Per channel the codes a tie band (in codes) admits: its own, and the one across the half when the exact
    value lies within ``band`` of it."""
    out = []
    with mpmath.workdps(DPS):
        for v in _channels(b):
            s = min(max(v, mpmath.mpf(0)), mpmath.mpf(1)) * TOP
            k = int(mpmath.floor(s))
            own = int(mpmath.floor(s + mpmath.mpf(1) / 2))
            out.append(sorted({own, k, k + 1}) if abs(s - k - mpmath.mpf(1) / 2) < band and k < TOP else [own])
    return out


def _expected(allowed, zf):
    """(lo, hi) of the bound over every texel of the allowed codes."""
    with mpmath.workdps(DPS):
        v = [_msm64(t, zf) for t in product(*allowed)]
    return float(min(v)), float(max(v))


def test_msm64_chain_is_algorithm_1_on_the_slides_codes_over_the_tie_band():
    # random mixtures of one to four depths (the extremes ±1 included: channels at code 0 and 65535), receivers
    # between and beyond them; each channel within 2^-18 of the range (a quarter code) of a half takes both codes
    rng = np.random.default_rng(38)
    rows = [_mixture([1.0], [1.0]), _mixture([-1.0], [1.0]), _mixture([-1.0, 1.0], [0.4, 0.6]),
            _mixture([-0.999, 0.2, 1.0], [0.2, 0.3, 0.5])]
    for n in (1, 2, 3, 4, 4, 4):
        rows.append(_mixture(rng.uniform(-1, 1, n), rng.uniform(0.1, 1, n)))
    b = np.array(rows)
    zf = np.array([0.3, -0.2, 0.0, 0.5, 0.1, -0.4, 0.7, 0.05, 0.9, -0.8])
    lo, hi = msm64_chain(b, zf, BIAS_UNORM16, tie=CHAIN_TIE)
    band = CHAIN_TIE * TOP
    saturated = tied = 0
    for i in range(len(b)):
        with mpmath.workdps(DPS):
            gaps = [abs(v * TOP - mpmath.floor(v * TOP) - mpmath.mpf(1) / 2) for v in _channels(b[i])]
        assert all(abs(g - band) > 1e-6 for g in gaps)  # no channel on the band's edge
        allowed = _allowed(b[i], band)
        saturated += [TOP] in allowed
        tied += any(len(a) > 1 for a in allowed)
        np.testing.assert_allclose([lo[i], hi[i]], _expected(allowed, zf[i]), rtol=0, atol=1e-10, err_msg=str(i))
    assert saturated >= 2 and 2 <= tied < len(b)  # rows at the top code; tied rows and untied ones


#: msm64_chain's float64 rule: a channel of a row with a tie takes both codes where its float64 scaled value lies
#: within the band plus 10^-9 codes of a half (the comment at ``band``: float64's own error on it is ~10^-11 codes)
SLACK = 1e-9
BAND = CHAIN_TIE * TOP


@pytest.mark.parametrize("offsets", [
    (1e-4, 0.3, 0.4, -0.35),  # channel 0 tied; the others a third of a code or more beside a half: their own
    (1e-4, 0.249994, 0.4, 0.4),  # channel 1 just inside the band: 2^-18 of the range is 0.2499962 codes
    (1e-4, 0.249998, 0.4, 0.4),  # channel 1 just outside it
    (-1e-4, 0.4, 0.4, -0.2),  # below the half: the same two codes; channel 3 tied too
    (1e-4, BAND + 0.75 * SLACK, 0.4, 0.4),  # channel 1 beyond the band by less than the float64 slack: both codes
    (1e-4, BAND + 1.5 * SLACK, 0.4, 0.4),  # beyond it by more: its own
])
def test_msm64_chain_takes_both_codes_of_each_channel_within_the_tie_and_no_other(offsets):
    b, codes, gaps = _texel_at(B0, offsets)
    zf = 0.2
    lo, hi = msm64_chain(b[None], np.array([zf]), BIAS_UNORM16, tie=CHAIN_TIE)
    allowed = _allowed(b, BAND + SLACK)
    assert [len(a) > 1 for a in allowed] == [abs(d) < BAND + SLACK for d in offsets]
    want = _expected(allowed, zf)
    assert want[1] - want[0] > 1e-7  # the codes matter
    np.testing.assert_allclose([lo[0], hi[0]], want, rtol=0, atol=1e-10)


def test_msm64_chains_default_tie_is_ten_to_minus_half_its_digits():
    # at dps = 20 the default tie is 10^-10 of the range: 6.6e-6 codes. A channel 10^-6 codes from a half takes both
    # codes; one 10^-3 codes from it, its own
    zf = np.array([0.2])
    for d, both in ((1e-6, True), (1e-3, False)):
        b, codes, _ = _texel_at(B0, (d, 0.4, 0.4, 0.4))
        lo, hi = msm64_chain(b[None], zf, BIAS_UNORM16, dps=20)
        allowed = [[codes[0] - 1, codes[0]] if both else [codes[0]]] + [[c] for c in codes[1:]]
        np.testing.assert_allclose([lo[0], hi[0]], _expected(allowed, zf[0]), rtol=0, atol=1e-10)
        assert (hi[0] > lo[0]) == both


# ---------------------------------------------------------------------------
# The NLQ chain


def _eq4(y1, y2, v2, xi4):
    """HPG17 Eq. (4): b = (1 − v2) b(y1) + v2 b(y2) + (0, 0, 0, ξ4), rounded once to float64."""
    with mpmath.workdps(DPS):
        y1, y2, v2, xi4 = (mpmath.mpf(x) for x in (y1, y2, v2, xi4))
        b = [(1 - v2) * y1**k + v2 * y2**k for k in range(1, 5)]
        b[3] += xi4
        return np.array([float(x) for x in b])


def _phi(b):
    """HPG17 Algorithm 2 on the float64 moments, at 60 digits: (y1, y2, v2, ξ4)."""
    with mpmath.workdps(DPS):
        b1, b2, b3, b4 = (_mpf(x) for x in b)
        sigma2 = b2 - b1 * b1
        q1 = b1 * b2 - b3
        q0 = -b1 * q1 - b2 * sigma2
        r = mpmath.sqrt(q1 * q1 - 4 * sigma2 * q0)
        y1, y2 = sorted([(-q1 - r) / (2 * sigma2), (-q1 + r) / (2 * sigma2)])
        l21 = (b3 - b1 * b2) / sigma2
        return y1, y2, (b1 - y1) / (y2 - y1), b4 - b2 * b2 - l21 * l21 * sigma2


def _psi4(x):
    c0 = mpmath.log(mpmath.log(mpmath.mpf("1.2")))
    return (mpmath.log(mpmath.log(max(x, mpmath.mpf("1.2e-7")) * 10**7)) - c0) / (
        mpmath.log(mpmath.log(mpmath.mpf("0.25") * 10**7)) - c0)


def _psi4_inverse(u):
    c0 = mpmath.log(mpmath.log(mpmath.mpf("1.2")))
    return mpmath.exp(mpmath.exp(c0 + u * (mpmath.log(mpmath.log(mpmath.mpf("0.25") * 10**7)) - c0))) / 10**7


def _nlq64(y1_code, r, zf, case_test="stored"):
    """Algorithm 3 on the 64-bit texel with y1's code ``y1_code`` and the others of ``r`` rounded."""
    with mpmath.workdps(DPS):
        y1, y2, v2, xi4 = (mpmath.mpf(x) for x in r)
        c2, cv = int(mpmath.nint(TOP * (y2 + 1) / 2)), int(mpmath.nint(TOP * v2))
        cx = int(mpmath.ceil(TOP * _psi4(xi4)))
        dec = [2 * mpmath.mpf(y1_code) / TOP - 1, 2 * mpmath.mpf(c2) / TOP - 1, mpmath.mpf(cv) / TOP,
               _psi4_inverse(mpmath.mpf(cx) / TOP)]
        return float(shade_clamped(np.array([[float(x) for x in dec]]), zf, case_test=case_test)[0])


@pytest.mark.parametrize("d, both", [(4e-6, True), (1e-5, False), (-4e-6, True)])
def test_nlq_chains_default_tie_is_ten_to_minus_half_its_digits(d, both):
    # y1 placed d codes from a half code of round(65535 (y1 + 1)/2); at dps = 20 the default tie is 10^-10 of the
    # range, 6.55e-6 codes: 4e-6 is inside it (and outside 11^-10), 1e-5 outside it (and inside 9^-10)
    k = 20000
    y1 = 2 * (mpmath.mpf(k) + mpmath.mpf(1) / 2 + mpmath.mpf(d)) / TOP - 1
    b = _eq4(y1, mpmath.mpf("0.55"), mpmath.mpf("0.4"), mpmath.mpf("0.01"))
    r = _phi(b)  # y1 as the chain finds it from the float64 moments: still d codes from the half, to 10^-7
    with mpmath.workdps(DPS):
        assert abs(TOP * (r[0] + 1) / 2 - k - mpmath.mpf(1) / 2 - d) < 1e-7
    zf = 0.1
    lo, hi = nlq_chain(b[None], np.array([zf]), dps=20)
    own = k + (1 if d > 0 else 0)
    want = [_nlq64(c, r, zf) for c in ((k, k + 1) if both else (own,))]
    np.testing.assert_allclose([lo[0], hi[0]], [min(want), max(want)], rtol=0, atol=1e-12)
    assert (hi[0] - lo[0] > 1e-9) == both


def test_nlq_chain_passes_its_case_test_to_algorithm_3():
    # y1 and y2 in one code (decoded equal: the clamp y2 - y1 >= 1e-6 moves the clamped y2 beyond the stored one): a
    # receiver between the stored y2 and y1 + 1e-6 is inside with the clamped test and beyond y2 with the stored one
    k = 30000
    yc = 2 * mpmath.mpf(k) / TOP - 1  # both depths 5e-6 from code k's value: both code k, decoded equal
    b = _eq4(yc - mpmath.mpf("5e-6"), yc + mpmath.mpf("5e-6"), mpmath.mpf("0.4"), mpmath.mpf("1e-4"))
    r = _phi(b)
    zf = float(yc) + 1e-7  # z'f = 0.1 < v2: there the two readings differ (beyond v2 both give the same limit)
    out = {}
    for test in ("stored", "clamped"):
        lo, hi = nlq_chain(b[None], np.array([zf]), case_test=test, tie=0.0)
        want = _nlq64(k, r, zf, test)
        assert lo[0] == hi[0] and abs(lo[0] - want) < 1e-9, (test, lo[0], want)
        out[test] = lo[0]
    assert abs(out["stored"] - out["clamped"]) > 0.1


def _cells32(y):
    return min(int(mpmath.floor(mpmath.mpf(1023) / 2 * (min(max(y, mpmath.mpf(-1)), mpmath.mpf(1)) + 1))), 1022)


@pytest.mark.parametrize("y1, y2, zf", [
    ("0.9985", "0.9995", 0.999),  # y1 and y2 in the last cell, 1022: decoded at its upper end, 1; zf below: 0
    ("1.001", "1.01", 0.5),  # beyond the range: saturated to 1, the last cell (not a 1023rd)
])
def test_nlq_chain_32_bits_at_the_last_depth_cell(y1, y2, zf):
    b = _eq4(mpmath.mpf(y1), mpmath.mpf(y2), mpmath.mpf("0.4"), mpmath.mpf("1e-3"))
    r = _phi(b)
    lo, hi = nlq_chain(b[None], np.array([zf]), fmt="32", tie=0.0)
    with mpmath.workdps(DPS):
        half = mpmath.mpf(1023) / 2
        c1, c2 = _cells32(r[0]), _cells32(r[1])
        assert c1 == c2 == 1022
        dec = [(c1 + 1) / half - 1, (c2 + 1) / half - 1,
               ((int(mpmath.floor(128 * mpmath.sqrt(r[2]))) + mpmath.mpf(1) / 2) / 128) ** 2,
               _psi4_inverse((int(mpmath.floor(64 * _psi4(r[3]))) + 1) / mpmath.mpf(64))]
        want = float(shade_clamped(np.array([[float(x) for x in dec]]), zf)[0])
    assert lo[0] == hi[0] == want


def test_kept_mutant_a_default_tie_of_ten_to_minus_dps_is_seen():
    with kept_mutant("moments_ref/golden/truth.py", "msm64_chain::dps // 2 -> dps * 2#0"):
        with pytest.raises(AssertionError):
            test_msm64_chains_default_tie_is_ten_to_minus_half_its_digits()


def test_nlq_chain_32_bits_reads_each_cell_at_its_decode_position():
    # docs/formats.md, 32 bits: depth cells read at their upper end, √v2 at its centre, Ψ4 at its upper end; a texel
    # inside the range, a receiver between its depths (every channel moves the bound)
    b = _eq4(mpmath.mpf("-0.3"), mpmath.mpf("0.4"), mpmath.mpf("0.3"), mpmath.mpf("1e-3"))
    r = _phi(b)
    zf = 0.1
    lo, hi = nlq_chain(b[None], np.array([zf]), fmt="32", tie=0.0)
    with mpmath.workdps(DPS):
        half = mpmath.mpf(1023) / 2
        dec = [(_cells32(r[0]) + 1) / half - 1, (_cells32(r[1]) + 1) / half - 1,
               ((int(mpmath.floor(128 * mpmath.sqrt(r[2]))) + mpmath.mpf(1) / 2) / 128) ** 2,
               _psi4_inverse((int(mpmath.floor(64 * _psi4(r[3]))) + 1) / mpmath.mpf(64))]
        want = float(shade_clamped(np.array([[float(x) for x in dec]]), zf)[0])
    assert lo[0] == hi[0] == want and 0.05 < want < 0.95


def test_kept_mutants_the_tie_band_and_the_last_32_bit_cell_are_seen():
    with kept_mutant("moments_ref/golden/truth.py", "msm64_chain::65535 -> 65534#1"):
        with pytest.raises(AssertionError):
            test_msm64_chain_takes_both_codes_of_each_channel_within_the_tie_and_no_other((1e-4, 0.249994, 0.4, 0.4))
    with kept_mutant("moments_ref/golden/truth.py", "_decoded32::1022 -> 1021#0"):
        with pytest.raises(AssertionError):
            test_nlq_chain_32_bits_at_the_last_depth_cell("0.9985", "0.9995", 0.999)
