"""golden.texel_codes and the per-component tie rule.

The vectorised codes equal the mpmath ones of texel_truth (random rows and rows placed on and next to every kind of
boundary); the per-component rule is checked on hand-built rows whose boundaries are computed here in exact
rationals and mpmath: a component may hold the code across its own boundary only where it is itself on a tie, and a
code one off in another component of that row is flagged by the sweep and confirmed wrong. The goldens' stored
acceptable codes already follow the rule.
"""

from __future__ import annotations

from dataclasses import replace
from fractions import Fraction

import mpmath
import numpy as np
import pytest

from moments_ref.golden import bands, texel_codes, texel_truth
from moments_ref.golden.cases import CASES
from moments_ref.sweep import judge


def _psi4_inverse(u):
    """Ψ4⁻¹ at 50 digits, written from HPG17 §3.3 (not texel_truth's)."""
    with mpmath.workdps(50):
        c0 = mpmath.log(mpmath.log(mpmath.mpf("1.2")))
        c1 = mpmath.log(mpmath.log(mpmath.mpf("0.25") * 10**7)) - c0
        u = mpmath.mpf(u.numerator) / u.denominator
        return float(mpmath.exp(mpmath.exp(c0 + u * c1)) / 10**7)


def _rows(n, seed):
    """Random rows (some outside the domain, saturated by the encoders) and rows on and beside boundaries."""
    rng = np.random.default_rng(seed)
    r = np.c_[rng.uniform(-1.1, 1.1, (n, 2)), rng.uniform(-0.1, 1.1, n), 10 ** rng.uniform(-9, 0, n)]
    b = r.copy()
    k, q = n // 6, rng.integers(0, 65535, n)
    b[:k, 0] = (2 * q[:k] + 1) / 65535 - 1  # y1 on a half-integer of the 64-bit code
    b[k:2 * k, 2] = (q[k:2 * k] + 0.5) / 65535  # v2 on a half-integer
    b[2 * k:3 * k, 1] = 2 * (q[2 * k:3 * k] % 1023) / 1023 - 1  # y2 on a 32-bit cell boundary
    b[3 * k:4 * k, 2] = ((q[3 * k:4 * k] % 128) / 128) ** 2  # √v2 on a cell boundary
    b[4 * k:5 * k, 3] = [_psi4_inverse(Fraction(int(x) % 64, 64)) for x in q[4 * k:5 * k]]  # Ψ4 on a 6-bit cell
    b[5 * k:, 3] = [_psi4_inverse(Fraction(int(x), 65535)) for x in q[5 * k:]]  # Ψ4 on a 16-bit code
    b[::7, 3], b[::11, 3], b[::13, 0] = 1.2e-7, 0.25, 0.0
    return np.concatenate([r, b])


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_vectorised_codes_equal_the_exact_ones(dtype):
    r = _rows(240, 3).astype(dtype)
    band64, band32 = texel_codes.pack64_tie_band(r), texel_codes.pack32_tie_band(r)
    for fast, exact, band in ((lambda x: texel_codes.pack64_ties(x), lambda x: texel_truth.pack64(x, components=True),
                               band64),
                              (lambda x: texel_codes.pack64_ties(x, "nearest"),
                               lambda x: texel_truth.pack64(x, "nearest", components=True), band64),
                              (texel_codes.pack32_ties, lambda x: texel_truth.pack32(x, components=True), band32)):
        codes, margins, across = fast(r)
        e_codes, e_margins, e_across = exact(r)
        tie = e_margins <= band
        assert np.array_equal(codes, e_codes)
        assert np.array_equal(margins <= band, tie)
        np.testing.assert_allclose(margins, e_margins, rtol=0, atol=1e-12)
        assert np.array_equal(across, np.where(tie, e_across, e_codes))
        assert tie.any(axis=0).all()  # every component is on a tie somewhere: the test reaches each boundary
    assert np.array_equal(texel_codes.pack32(r)[0], texel_truth.pack32(r)[0])
    fast, exact = texel_codes.pack64(r, margin=True)[1], texel_truth.pack64(r, margin=True)[1]
    np.testing.assert_allclose(fast, exact, rtol=0, atol=1e-12)


def _scaled_y(y):
    return 65535 * (Fraction(float(y)) + 1) / 2


def _tie_row():
    """A float32 row whose y1 lies within the tie band of a half-integer of its code and whose other components lie
    far from theirs (exact rationals for y and v2, mpmath for Ψ4)."""
    y1 = np.float32(2 * 20000.5 / 65535 - 1)
    r = np.array([[y1, 0.3, 0.4, 0.01]], np.float32)
    s = _scaled_y(r[0, 0])
    assert abs(s - (20000 + Fraction(1, 2))) <= Fraction(float(texel_codes.pack64_tie_band(r)[0, 0])) * 65535
    for x in (_scaled_y(r[0, 1]), 65535 * Fraction(float(r[0, 2]))):
        assert abs(x - int(x) - Fraction(1, 2)) > Fraction(1, 8)
    with mpmath.workdps(50):
        c0 = mpmath.log(mpmath.log(mpmath.mpf("1.2")))
        u = (mpmath.log(mpmath.log(mpmath.mpf(float(r[0, 3])) * 10**7)) - c0) / (
            mpmath.log(mpmath.log(mpmath.mpf("0.25") * 10**7)) - c0) * 65535
        assert abs(u - mpmath.nint(u)) > 0.125
    return r


def _judge(case, r, got):
    inputs = {"r": r}
    b, ill = judge.legitimate_interval(case, inputs)
    out = {case.outputs[0]: got}
    return judge.flagged_rows(case, inputs, b, ill, out), judge.confirm(case, inputs, out)


def test_one_code_off_in_another_component_of_a_tie_row_is_flagged_and_confirmed():
    case, r = CASES["pack64-float32"], _tie_row()
    truth = texel_codes.pack64(r)[0].astype(np.int64)
    assert bands.on_tie(case, {"r": r}).all()  # the per-row rule's tie: every code could be one off
    other = truth.copy()
    other[0, 0] = 20000 if truth[0, 0] == 20001 else 20001  # y1 across its own boundary: accepted
    flagged, wrong = _judge(case, r, other)
    assert not flagged.any() and not wrong.any()
    for k in (1, 2, 3):  # one code off in a component far from its boundary: wrong
        for d in (-1, 1):
            got = truth.copy()
            got[0, k] += d
            flagged, wrong = _judge(case, r, got)
            assert flagged.all() and wrong.all(), (k, d)
    per_row = replace(case, tie_neighbours=None)  # the former, per-row rule accepts them all
    got = truth.copy()
    got[0, 2] += 1
    assert bands.tie_accepted(per_row, {"r": r}, {"q": got}).all()


def test_xi4_at_its_clamp_is_a_tie_of_xi4_only():
    # ξ4 below 1.2e-7: 65535 Ψ4 = 0 exactly, a ceil boundary (codes 0 and 1); y2 one code off is wrong there
    case = CASES["pack64-float32"]
    r = np.array([[-0.5, 0.3, 0.4, 1e-9]], np.float32)
    truth = texel_codes.pack64(r)[0].astype(np.int64)
    assert truth[0, 3] == 0
    got = truth.copy()
    got[0, 3] = 1
    assert not _judge(case, r, got)[0].any()
    got[0, 1] += 1
    flagged, wrong = _judge(case, r, got)
    assert flagged.all() and wrong.all()


def test_pack32_field_across_its_own_boundary_only():
    case = CASES["pack32-float32"]
    xi = np.float32(_psi4_inverse(Fraction(20, 64)))  # Ψ4 on a cell boundary of the 6-bit code
    r = np.array([[-0.25, 0.5, 0.3, xi]], np.float32)
    cells, margins, across = texel_codes.pack32_ties(r)
    band = texel_codes.pack32_tie_band(r)
    assert margins[0, 3] <= band[0, 3] and (margins[0, :3] > band[0, :3]).all()
    assert across[0, 3] != cells[0, 3]
    other = cells.copy()
    other[0, 3] = across[0, 3]
    assert not _judge(case, r, texel_truth.fold32(other))[0].any()
    for k in range(3):
        bad = other.copy()
        bad[0, k] += 1
        flagged, wrong = _judge(case, r, texel_truth.fold32(bad))
        assert flagged.all() and wrong.all(), k


def test_a_word_between_two_acceptable_words_is_flagged():
    # the band of a word is an interval; a word inside it is not acceptable for being inside
    case = CASES["pack32-float32"]
    xi = np.float32(_psi4_inverse(Fraction(20, 64)))
    r = np.array([[-0.25, 0.5, 0.3, xi]], np.float32)
    cells, _, across = texel_codes.pack32_ties(r)
    words = [int(texel_truth.fold32(cells)[0]), int(texel_truth.fold32(np.where([[0, 0, 0, 1]], across, cells))[0])]
    between = np.array([min(words) + (1 << 19)], np.uint32)  # the √v2 field one up, Ψ4 as the lower word
    flagged, wrong = _judge(case, r, between)
    assert flagged.all() and wrong.all()


@pytest.mark.parametrize("name", ["pack64-float32", "pack64-float64", "reencode64-float32", "pack32-float32",
                                  "reencode32-float32", "encode_unorm16-float32", "encode_r10g10b10a2-float32"])
def test_the_goldens_acceptable_codes_follow_the_per_component_rule(name):
    """The golden compare accepts per component the codes stored for a row; the writer stores a code other than the
    truth's only in a component on its own tie, so the goldens need no change and no regeneration."""
    from moments_ref.golden.conventions import profiled_arrays

    case, arrays = profiled_arrays(name)
    o, key = case.outputs[0], case.inputs[0]
    r, expected = np.asarray(arrays[key]), np.asarray(arrays[o]).astype(np.int64)
    acceptable = np.asarray(arrays[f"{o}_acceptable"]).astype(np.int64).reshape(len(r), -1, *expected.shape[1:])
    allowed = [expected] + [np.asarray(t[0]).astype(np.int64) for t in case.tie_neighbours(**{key: r})]
    inside = np.zeros(acceptable.shape, bool)
    for a in allowed:
        inside |= acceptable == a[:, None]
    assert inside.all()
    assert (acceptable != expected[:, None]).any()  # the stored codes hold ties: the test is not vacuous


@pytest.mark.parametrize("name", ["encode_unorm16-float32", "encode_r10g10b10a2-float32"])
def test_the_affine_encoders_take_the_per_component_rule_too(name):
    # on the golden rows with a tie in exactly one code: that code across its boundary is accepted, a code of
    # another component one off is confirmed wrong
    from moments_ref.golden.conventions import profiled_arrays

    case, arrays = profiled_arrays(name)
    b = np.asarray(arrays["b"])
    fn = getattr(texel_truth, name.split("-")[0])
    codes, margins, across = fn(b, components=True)
    top = 65535 if "unorm16" in name else 1023
    one = np.flatnonzero(((margins <= texel_codes.TIE_BAND).sum(axis=1) == 1) & (codes < top).all(axis=1))[:3]
    assert one.size
    words = (lambda c: c.astype(np.uint16)) if "unorm16" in name else texel_truth.words_r10
    for i in one:
        k = int(np.flatnonzero(margins[i] <= texel_codes.TIE_BAND)[0])
        other = (k + 1) % codes.shape[1]
        tie, off = codes[i:i + 1].copy(), codes[i:i + 1].copy()
        tie[0, k], off[0, other] = across[i, k], off[0, other] + 1
        o = case.outputs[0]
        assert not bands.confirm(case, {"b": b[i:i + 1]}, {o: words(tie)}).any()
        assert bands.confirm(case, {"b": b[i:i + 1]}, {o: words(off)}).all()
