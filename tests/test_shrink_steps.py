"""sweep.shrink.shrink on hand-made failing ports: the simplest row reached, derived by hand from the rules.

The rules (sweep/shrink.py's docstring): each step offers the simpler neighbours of the current
row, simplest first (the plain float32 texel, one depth fewer, equal weights, depths, weights and
zf rounded to fewer decimals, the coarsest rounding first, zf at a round offset from the nearest
depth, the smallest offset first), never a row tried before, runs them in one dispatch and keeps
the first that still fails and is confirmed; it stops when none does. The ports here are the
package's float32 Algorithm 1 with a bug on a stated region (an intensity of 2, outside [0, 1]),
so which rows fail is known without the code under test.
"""

from __future__ import annotations

import numpy as np
import pytest

from moments_ref.msm import shadow_intensity
from moments_ref.sweep.runner import Port, SweepSpec
from moments_ref.sweep.shrink import shrink

CASE = "shadow_intensity-lower-float32"


def _port(bad):
    """Algorithm 1, but an intensity of 2 where ``bad(b, zf)``."""

    def port(b, zf):
        v = np.asarray(shadow_intensity(b, zf), np.float32)
        return np.where(bad(np.asarray(b, np.float64), np.asarray(zf, np.float64)), np.float32(2), v)

    return port


def _shrink(bad, texel):
    return shrink(SweepSpec(CASE, Port(fn=_port(bad))), None, texel)


def test_a_port_failing_below_a_receiver_depth_shrinks_to_round_numbers():
    # fails iff zf < -0.5. By hand: the plain format (1), the first depth dropped twice (2, 3), the last
    # depth 0.8 rounded to 0 decimals, 1.0 (4), zf -0.7345 rounded to 0 decimals, -1.0 (5); then every
    # neighbour (zf moved to 1 − 10^e from the depth 1.0) was offered before: no sixth dispatch.
    texel, row, dispatches = _shrink(lambda b, zf: zf < -0.5, {"depths": [0.3712, -0.2219, 0.8],
                                                             "weights": [0.2, 0.5, 0.3], "zf": -0.7345, "format": 2})
    assert texel == {"depths": [1.0], "weights": [1.0], "zf": -1.0, "format": 0}
    assert dispatches == 5
    assert row["inputs"]["zf"] == -1.0 and row["got"] == {"intensity": 2.0}
    # the row's interval holds Algorithm 1's value on the shrunk texel (a depth at 1 lights a receiver at -1)
    assert row["lo"]["intensity"] <= 0.0 <= row["hi"]["intensity"] < 1e-4
    assert np.allclose(row["inputs"]["b"], 1.0, atol=1e-6)


def test_the_receiver_moves_to_the_smallest_round_offset_that_still_fails():
    # fails iff zf lies more than 1.5e-3 behind the mean depth b1. By hand: the depth 0.3712 rounds to 0.0;
    # then zf = 0 + 10^e for e = -8, -7, ...: 1e-8 ... 1e-3 pass (not more than 1.5e-3 behind), 0.01 fails
    # and is kept (before zf itself would be rounded).
    texel, row, dispatches = _shrink(lambda b, zf: zf > b[:, 0] + 1.5e-3, {"depths": [0.3712], "weights": [1.0],
                                                                         "zf": 0.6789, "format": 0})
    assert texel == {"depths": [0.0], "weights": [1.0], "zf": 0.01, "format": 0}
    assert row["got"] == {"intensity": 2.0} and row["inputs"]["zf"] == np.float32(0.01)


def test_equal_weights_first_then_depths_and_zf_by_the_rules_order():
    # fails iff there are at least two distinct depths (b2 − b1² > 1e-4): no depth can go, weights become equal
    def two(b, zf):
        return b[:, 1] - b[:, 0] ** 2 > 1e-4

    texel, row, dispatches = _shrink(two, {"depths": [0.123, -0.456], "weights": [0.3, 0.7], "zf": 0.9,
                                           "format": 0})
    # By hand: no depth can go; equal weights (1); depths to 0 decimals are one depth (0, -0), to 1 decimal
    # (0.1, -0.5) fail (2); zf at the smallest round offset from the nearest depth 0.1, 0.1 + 1e-8 (3); zf
    # rounded to 0 decimals, 0.0 (4); from 0.0 the nearest depth 0.1 is above: 0.1 − 1e-8 (5); then every
    # neighbour was tried (0.0 and 0.1 + 1e-8) or passes: the sixth dispatch finds none.
    assert texel == {"depths": [0.1, -0.5], "weights": [0.5, 0.5], "zf": 0.1 - 1e-8, "format": 0}
    assert dispatches == 6 and row["got"] == {"intensity": 2.0}
    assert row["lo"]["intensity"] < 0.5 < row["hi"]["intensity"]  # a receiver at the depth 0.1 of half the weight


def test_a_port_that_never_fails_keeps_its_row_after_one_dispatch():
    t = {"depths": [0.25, -0.5], "weights": [0.5, 0.5], "zf": 0.3, "format": 0}
    texel, row, dispatches = _shrink(lambda b, zf: np.zeros(len(zf), bool), t)
    assert texel == t and row is None and dispatches == 1


def _rows(texel):
    """Candidates as plain tuples (depths, weights of the texel's weighted depths, zf, format), exact floats."""
    from moments_ref.sweep.shrink import candidates

    out = []
    for z, w, zf, fmt in candidates(texel):
        keep = w > 0
        out.append((z[keep].tolist(), w[keep].tolist(), zf, fmt))
    return out


def test_the_receiver_offsets_are_powers_of_ten_from_the_nearest_depth_on_the_receivers_side():
    # zf below the depth -0.5 + 0.5: 0 is 0.5 above it; offsets 10^e closer than 0.5 (e = -8 ... -1) and the
    # power of ten nearest 0.5 on a log scale (10^round(log10 0.5) = 1): -0.5 + 1 = 0.5; the plain format first,
    # the depth rounded to 0 decimals (-0.0: round half to even) next, zf itself is 0 already
    got = _rows({"depths": [-0.5], "weights": [1.0], "zf": 0.0, "format": 1})
    assert got[0] == ([-0.5], [1.0], 0.0, 0) and got[1] == ([0.0], [1.0], 0.0, 1)
    assert [r[2] for r in got[2:]] == [-0.5 + 10.0**e for e in range(-8, 0)] + [0.5]
    # below the depth: 0.5 − 10^e for 10^e < 0.12 (e = -8 ... -1; 10^round(log10 0.12) = 0.1 as well), then zf
    # rounded: 0.0 (to 0 decimals; 0.4 to one decimal was offered already)
    got = _rows({"depths": [0.5], "weights": [1.0], "zf": 0.38, "format": 0})
    assert got == [([0.0], [1.0], 0.38, 0)] + [([0.5], [1.0], 0.5 - 10.0**e, 0) for e in range(-8, 0)] + [
        ([0.5], [1.0], 0.0, 0)]
    # an offset beyond the range is clipped to it: 0.5 + 10^0 -> 1.0, -0.5 - 1 -> -1.0
    for zf in (0.9, -0.9):
        got = _rows({"depths": [0.5 * np.sign(zf), 0.2 * np.sign(zf)], "weights": [0.5, 0.5], "zf": zf, "format": 0})
        assert all(-1 <= r[2] <= 1 for r in got) and got[-1][2] == np.sign(zf)


def test_the_row_itself_is_never_offered_and_inputs_stay_in_float64():
    # zf exactly 0.1 above the depth 0: the offset 10^-1 would give the row itself
    got = _rows({"depths": [0.0], "weights": [1.0], "zf": 0.1, "format": 0})
    assert ([0.0], [1.0], 0.1, 0) not in got and got
    # depths and weights as given (float64, not rounded to float32): 0.3 and 0.7 are not float32 numbers
    got = _rows({"depths": [0.123, -0.456], "weights": [0.3, 0.7], "zf": 0.25, "format": 1})
    assert got[0] == ([0.123, -0.456], [0.3, 0.7], 0.25, 0)


def test_depths_and_zf_are_rounded_to_0_to_7_decimals_and_weights_to_1_to_5():
    got = _rows({"depths": [0.123456789], "weights": [1.0], "zf": -0.987654321, "format": 0})
    depths = [r[0][0] for r in got if r[2] == -0.987654321]
    assert depths == [round(0.123456789, d) for d in range(8)]  # every one changes the depth
    zfs = [r[2] for r in got if r[0] == [0.123456789]]
    # zf: to 0 and 1 decimals both -1.0 (offered once), then 2 ... 7 decimals, after the offsets from the depth
    assert zfs[-7:] == list(dict.fromkeys(round(-0.987654321, d) for d in range(8)))
    assert zfs[:-7] == [0.123456789 - 10.0**e for e in range(-8, 1)]
    # weights of seven decimals: rounded to 1 ... 5 decimals (not 6), and only where every weight stays positive
    w = [0.1234567, 0.3765433, 0.5]
    got = _rows({"depths": [0.25, 0.5, 0.75], "weights": w, "zf": 0.0, "format": 0})
    rounded = [r[1] for r in got if r[0] == [0.25, 0.5, 0.75] and r[2] == 0.0 and r[1] != [1 / 3] * 3]
    assert rounded == [[round(x, d) / sum(round(y, d) for y in w) for x in w] for d in range(1, 6)]
    # one weight rounding to 0 at one decimal: that rounding (weights 0, 0.5, 0.5) is not offered
    got = _rows({"depths": [0.25, 0.5, 0.75], "weights": [0.04, 0.46, 0.5], "zf": 0.0, "format": 0})
    assert ([0.5, 0.75], [0.5, 0.5], 0.0, 0) not in got
    assert [r[1] for r in got if r[0] == [0.25, 0.5, 0.75] and r[2] == 0.0] == [[1 / 3] * 3]
    # weights of which only some change at one decimal are rounded too
    got = _rows({"depths": [0.25, 0.5, 0.75], "weights": [0.5, 0.25, 0.25], "zf": 0.0, "format": 0})
    # (0.5, 0.2, 0.2) / 0.9
    assert any(len(r[1]) == 3 and np.allclose(r[1], [5 / 9, 2 / 9, 2 / 9], rtol=0, atol=1e-15) for r in got)


def test_one_depth_fewer_keeps_the_other_depths_weights_in_proportion():
    got = _rows({"depths": [0.1, 0.2, 0.3], "weights": [0.2, 0.3, 0.5], "zf": 0.0, "format": 0})
    fewer = got[:3]
    assert [r[0] for r in fewer] == [[0.2, 0.3], [0.1, 0.3], [0.1, 0.2]]
    for r, w in zip(fewer, ([0.3, 0.5], [0.2, 0.5], [0.2, 0.3])):
        assert np.allclose(r[1], np.array(w) / sum(w), rtol=0, atol=1e-15)


def test_rows_are_told_apart_to_17_decimals():
    # a depth of 1e-18 is 0 to 17 decimals: rounding it to 0 decimals gives the row itself, not offered;
    # 3e-17 is not: its rounding to 0 is offered
    def rounded(z):
        return [r for r in _rows({"depths": [z], "weights": [1.0], "zf": 0.5, "format": 0}) if r[2] == 0.5]

    assert rounded(1e-18) == [] and rounded(3e-17) == [([0.0], [1.0], 0.5, 0)]


def test_a_texel_of_another_format_shrinks_to_the_plain_float32_texel_first():
    # Algorithm 3 (shade) reads the texel's format: 0 is Φ of the float32 moments, 1 and 2 what the 64- and 32-bit
    # texels decode to. A port wrong everywhere (2, outside [0, 1]) is shrunk first to the plain format, whose
    # input r is Φ itself (computed here from the texel's biased moments), then to round numbers.
    from moments_ref.moments import BIAS_FLOAT32, bias_moments, power_moments
    from moments_ref.nonlinear import phi

    spec = SweepSpec("shade-float32", Port(fn=lambda r, zf: np.full(len(zf), np.float32(2))))
    texel, row, dispatches = shrink(spec, None, {"depths": [0.3712], "weights": [1.0], "zf": 0.6137, "format": 2})
    assert texel["format"] == 0 and texel["depths"] == [0.0] and texel["zf"] in (-1.0, 0.0, 1.0), texel
    b = bias_moments(power_moments(np.array([texel["depths"]], np.float32).astype(np.float64)).astype(np.float32),
                     BIAS_FLOAT32)
    np.testing.assert_allclose(row["inputs"]["r"], phi(b)[0], rtol=0, atol=2e-6)


def test_weights_are_told_apart_to_17_decimals_too():
    # a row tried before is not offered again; weights that agree to 17 decimals are the same row, weights that
    # differ in the 17th are not (rounded half to even at the 17th decimal here: 1e-17 steps)
    from moments_ref.sweep.shrink import candidates

    def offered_after(w_seen, w_now):
        seen = set()
        candidates({"depths": [0.25, 0.75], "weights": [w_seen, 1 - w_seen], "zf": 0.5, "format": 0}, seen)
        return candidates({"depths": [0.25, 0.75], "weights": [w_now, 1 - w_now], "zf": 0.5, "format": 0}, seen)

    w = 0.012345678901234561  # the float64 number nearest; 1 - w and 1 - (w + 3e-18) are the same float64
    assert 1 - w == 1 - (w + 3e-18) and np.round(w, 17) == np.round(w + 3e-18, 17) and w != w + 3e-18
    assert offered_after(w, w + 3e-18) == []  # within the 17th decimal: every candidate was tried
    assert np.round(w, 16) == np.round(w + 3e-17, 16) and np.round(w, 17) != np.round(w + 3e-17, 17)
    assert offered_after(w, w + 3e-17) != []  # apart in the 17th decimal: a new row, its neighbours are new


def _confirm_only_call(monkeypatch, k):
    """judge.confirm made to confirm only its k-th call (1-based) of the whole shrink: ``calls`` counts them."""
    from moments_ref.sweep import judge

    calls = []

    def confirm(case, inputs, got, port_dtype="float32"):
        calls.append(len(next(iter(inputs.values()))))
        return np.array([len(calls) == k])

    monkeypatch.setattr(judge, "confirm", confirm)
    return calls


@pytest.mark.parametrize("k", [8, 9])
def test_a_step_confirms_the_first_eight_flagged_candidates_one_row_each(monkeypatch, k):
    # sweep/shrink.py's docstring: of a step's flagged candidates, the first 8 (simplest first) are confirmed in
    # turn, each alone, and the first confirmed one is kept. A port wrong everywhere flags every candidate: the
    # 8th confirmed is kept (the 8th candidate, then a second step), the 9th is never asked (no step is taken).
    from moments_ref.sweep.shrink import candidates

    t = {"depths": [0.123, -0.456], "weights": [0.3, 0.7], "zf": 0.9, "format": 0}
    calls = _confirm_only_call(monkeypatch, k)
    texel, row, dispatches = _shrink(lambda b, zf: np.ones(len(zf), bool), t)
    assert calls[:8] == [1] * 8 and len(candidates(t)) > 9
    if k == 8:
        z, w, zf, fmt = candidates(t)[7]
        assert texel == {"depths": z[w > 0].tolist(), "weights": w[w > 0].tolist(), "zf": zf, "format": fmt}
        assert dispatches == 2 and row is not None
    else:
        assert len(calls) == 8 and texel == t and row is None and dispatches == 1
