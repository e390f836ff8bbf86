"""sweep.judge's verdict on hand-built rows: which rows it flags, gates and confirms.

Each expectation is stated here, independently of the judge: a band written by hand and the
row's place against it, a texel code computed in exact rationals (``fractions``) with its
distance to the rounding boundary, an exact bound from mpmath (:mod:`moments_ref.precise`), a
moment vector inside or outside the moment space by its Hankel determinant. They pin what must
hold (a row outside its band is flagged, NaN too; an ill row is judged except in the engine
cases; an ungated row is never flagged; on a rounding tie both codes next to the boundary are
accepted and a code two away is not), not how the judge computes it.
"""

from __future__ import annotations

from fractions import Fraction

import mpmath
import numpy as np
import pytest

from moments_ref import precise
from moments_ref.golden import bands as golden_bands
from moments_ref.golden.cases import CASES
from moments_ref.sweep import engine, judge

from _mutants import kept_mutant

PSI = CASES["psi4-float64"]  # a float output
ENGINE = CASES["engine-lower-float32"]  # an engine case: its ill rows are never wrong
PACK = CASES["pack64-float32"]  # integer output, UNORM16 codes round(65535 v2) (docs/formats.md)
JUDGE = "moments_ref/sweep/judge.py"

TINY = 2.0**-20  # representable in float32 too: 1 + TINY is 8 float32 ulps above 1
#: got, and whether it lies outside [0, 1]: inside, both ends (closed), just outside each end, NaN, ±inf.
ROWS = [(0.5, False), (0.0, False), (1.0, False), (-TINY, True), (1 + TINY, True), (np.nan, True),
        (np.inf, True), (-np.inf, True)]


def _unit_band(n, width=None):
    lo, hi = np.zeros(n), np.ones(n)
    return (lo, hi) if width is None else (np.zeros((n, width)), np.ones((n, width)))


def _hand_full_band(monkeypatch, bands, ill):
    """Inputs that make the hand-built ``bands`` the full band too.

    flagged_rows judges a flagged float row again by its band over the confirmation's whole neighbourhood
    (golden.bands.legitimate_interval with ``full``). These rows are hand-built bands, not inputs, so that
    band is the hand-built one: the returned inputs carry each row's index to it.
    """
    def full(case, inputs, port_dtype="float32", contract=None, full=False, **_):
        rows = np.asarray(inputs["row"])
        return {o: (lo[rows], hi[rows]) for o, (lo, hi) in bands.items()}, np.asarray(ill, bool)[rows]

    monkeypatch.setattr(golden_bands, "legitimate_interval", full)
    return {"row": np.arange(len(ill))}


def test_a_row_is_wrong_exactly_where_an_output_leaves_its_closed_band():
    got = np.array([g for g, _ in ROWS])
    want = np.array([w for _, w in ROWS])
    n = len(got)
    assert np.array_equal(judge.wrong_rows(PSI, {"u": _unit_band(n)}, np.zeros(n, bool), {"u": got}), want)
    # float32 output, as a port writes it: the same verdict
    got32 = got.astype(np.float32)
    assert np.array_equal(judge.wrong_rows(PSI, {"u": _unit_band(n)}, np.zeros(n, bool), {"u": got32}), want)
    # a float64 output is judged in float64: 2^-40 above the band is outside (float32 would round it onto 1)
    edge = np.array([1 + 2.0**-40, -(2.0**-60), 1.0])
    assert judge.wrong_rows(PSI, {"u": _unit_band(3)}, np.zeros(3, bool), {"u": edge}).tolist() == [True, True, False]


def test_a_row_without_a_band_is_never_wrong():
    """golden.bands: a row where no legitimate evaluation is finite gets the band (−inf, inf): nothing is wrong
    there, NaN included (a row of a finite band next to it still is)."""
    lo, hi = np.array([-np.inf, 0.0, -np.inf]), np.array([np.inf, 1.0, np.inf])
    got = np.array([np.nan, np.nan, 1e300])
    assert judge.wrong_rows(PSI, {"u": (lo, hi)}, np.zeros(3, bool), {"u": got}).tolist() == [False, True, False]


def test_one_component_or_one_output_out_of_band_makes_the_row_wrong():
    n = 4
    vec = np.full((n, 4), 0.5)
    vec[1, 3] = 2.0  # row 1: the last component only
    vec[2, 0] = np.nan  # row 2: the first component NaN
    scalar = np.array([0.5, 0.5, 0.5, -1.0])  # row 3: the second output only
    bands = {"q": _unit_band(n, 4), "s": _unit_band(n)}
    got = {"q": vec, "s": scalar}
    assert judge.wrong_rows(PSI, bands, np.zeros(n, bool), got).tolist() == [False, True, True, True]
    # the outputs' order in the bands does not matter
    assert judge.wrong_rows(PSI, dict(reversed(list(bands.items()))), np.zeros(n, bool), got).tolist() == \
        [False, True, True, True]


@pytest.mark.parametrize("case, judged", [(PSI, True), (ENGINE, False)], ids=["golden", "engine"])
def test_ill_rows_are_judged_except_in_the_engine_cases(case, judged, monkeypatch):
    out = case.outputs[0]
    got = np.array([0.5, 3.0, 3.0, 0.5])  # rows 1 and 2 outside [0, 1]
    ill = np.array([False, False, True, True])
    inputs = _hand_full_band(monkeypatch, {out: _unit_band(4)}, ill)
    flagged = judge.flagged_rows(case, inputs, {out: _unit_band(4)}, ill, {out: got})
    assert flagged.tolist() == [False, True, judged, False]


def test_an_ungated_row_is_never_flagged_and_no_gate_gates_every_row(monkeypatch):
    got = np.array([3.0, 3.0, np.nan, 0.5])
    ill = np.zeros(4, bool)
    bands = {"u": _unit_band(4)}
    inputs = _hand_full_band(monkeypatch, bands, ill)
    assert judge.flagged_rows(PSI, inputs, bands, ill, {"u": got}).tolist() == [True, True, True, False]
    gated = np.array([1, 0, 0, 1])  # ints: read as bool
    assert judge.flagged_rows(PSI, inputs, bands, ill, {"u": got}, gated=gated).tolist() == \
        [True, False, False, False]


def test_a_float_flag_is_judged_again_by_the_full_band(monkeypatch):
    """A float row outside its default band but inside its band over the confirmation's whole neighbourhood is no
    flag; one outside both is (the full band is asked only about the flagged rows)."""
    got = np.array([0.5, 1.5, 3.0])
    ill = np.zeros(3, bool)
    wide = {"u": (np.zeros(3), np.full(3, 2.0))}
    inputs = _hand_full_band(monkeypatch, wide, ill)
    assert judge.flagged_rows(PSI, inputs, {"u": _unit_band(3)}, ill, {"u": got}).tolist() == [False, False, True]


def _scaled_v2(v2):
    """65535 v2 of the float64 v2, exactly (the UNORM16 code before rounding)."""
    return Fraction(float(v2)) * 65535


#: ξ4 of the tie rows, and its code ceil(65535 Ψ4(ξ4)) (HPG17 §3.3: Ψ4(ξ) = (ln ln(10^7 ξ) − c0) / c1), far from
#: the integers (the boundaries of ceil)
XI4 = 0.01


def _xi4_code():
    with mpmath.workdps(40):
        c0 = mpmath.log(mpmath.log(mpmath.mpf("1.2")))
        c1 = mpmath.log(mpmath.log(mpmath.mpf("0.25") * 10**7)) - c0
        s = 65535 * (mpmath.log(mpmath.log(mpmath.mpf(XI4) * 10**7)) - c0) / c1
        assert 0.1 < s - mpmath.floor(s) < 0.9
        return int(mpmath.ceil(s))


def _truth(r):
    """The exact codes of the tie rows: y1 -> 300, y2 -> 40000, v2 -> round half even, ξ4 -> :func:`_xi4_code`."""
    truth = np.zeros((len(r), 4))
    truth[:, 0], truth[:, 1], truth[:, 3] = 300, 40000, _xi4_code()
    truth[:, 2] = [round(_scaled_v2(x)) for x in r[:, 2]]
    return truth


def _tie_rows():
    """Texels of the 64-bit format whose y1, y2, ξ4 codes lie far from any boundary and whose v2 lies on
    a tie (65535 v2 within 1e-9 of k + 1/2) or midway between ties (65535 v2 within 1e-9 of an integer)."""
    k = np.array([100, 20000, 54321, 7])
    on = (2 * k + 1) / 131070.0  # v2 = (k + 1/2) / 65535, rounded once to float64
    off = k / 65535.0
    v2 = np.concatenate([on, off])
    r = np.zeros((len(v2), 4))
    r[:, 0], r[:, 1], r[:, 2], r[:, 3] = 2 * 300 / 65535 - 1, 2 * 40000 / 65535 - 1, v2, XI4
    for x, tie in zip(v2, [True] * 4 + [False] * 4):
        s = _scaled_v2(x)
        dist = abs(s - (s.numerator // s.denominator) - Fraction(1, 2))
        assert (dist < Fraction(1, 10**9)) if tie else (dist > Fraction(1, 2) - Fraction(1, 10**9))
    return r, np.concatenate([k, k])


def test_on_a_rounding_tie_both_codes_next_to_the_boundary_pass_and_others_are_flagged():
    r, k = _tie_rows()
    n = len(r)
    truth = _truth(r)
    bands = {"q": (truth.copy(), truth.copy())}  # a band of the truth's code only: the tie rule decides
    ill, inputs = np.zeros(n, bool), {"r": r}
    tie = np.arange(n) < 4

    def flagged(v2_code):
        got = truth.copy()
        got[:, 2] = v2_code
        return judge.flagged_rows(PACK, inputs, bands, ill, {"q": got.astype(np.uint16)})

    assert not flagged(truth[:, 2]).any()
    # on a tie, k and k + 1 (the codes either side of k + 1/2) are legitimate; midway between ties only k is
    assert flagged(k).tolist() == [False] * 4 + [False] * 4
    assert flagged(k + 1).tolist() == [False] * 4 + [True] * 4
    assert flagged(k - 1).tolist()[4:] == [True] * 4
    # two codes from the boundary's codes, or NaN: flagged everywhere
    assert flagged(k + 3).all() and flagged(k - 2).all()
    got = truth.copy()
    got[:, 2] = np.nan
    assert judge.flagged_rows(PACK, inputs, bands, ill, {"q": got}).all()
    assert tie.sum() == 4


def test_kept_mutant_a_tie_code_flagged_when_the_tie_rule_is_skipped():
    """The judge without its tie rule (the early return taken) flags a legitimate code on a tie."""
    r, k = _tie_rows()
    truth = _truth(r)
    got = truth.copy()
    got[:4, 2] = np.where(truth[:4, 2] == k[:4], k[:4] + 1, k[:4])  # the other code next to each tie
    args = (PACK, {"r": r}, {"q": (truth, truth.copy())}, np.zeros(len(r), bool), {"q": got.astype(np.uint16)})
    assert not judge.flagged_rows(*args).any()
    with kept_mutant(JUDGE, "flagged_rows::look.size -> not look.size#0"):
        assert judge.flagged_rows(*args)[:4].all()


def test_the_contract_rows_are_the_moment_space_or_the_profiles_decision():
    case = CASES["shadow_intensity-lower-float32"]
    z = np.array([-0.8, -0.3, 0.1, 0.4, 0.9])
    inside = [float(np.mean(z**j)) for j in range(1, 5)]  # five equal atoms: inside the moment space
    outside = [0.0, 0.5, 0.0, 0.1]  # det B = 0.05 - 0.125 < 0: no distribution has these moments
    b = np.array([inside, outside], np.float32)
    B = np.array([[1, 0, 0.5], [0, 0.5, 0], [0.5, 0, 0.1]])
    assert np.linalg.det(B) < -0.05
    zf = np.array([0.0, 0.0], np.float32)
    assert judge.contract_rows(case, {"b": b, "zf": zf}).tolist() == [True, False]
    assert judge.contract_rows(case, {"b": b, "zf": zf}, contract=[0, 1]).tolist() == [False, True]


def test_the_engine_cases_are_judged_and_confirmed_by_the_exact_bound():
    z = np.array([[-0.5, 0.2, 0.6], [-0.9, -0.1, 0.7]])
    w = np.array([[0.3, 0.3, 0.4], [0.5, 0.25, 0.25]])
    zf = np.array([0.4, 0.0])
    inputs = engine.engine_inputs(ENGINE, z, w, zf)
    exact = np.asarray(precise.shadow_intensity(inputs["b"].astype(np.float64), inputs["zf"].astype(np.float64),
                                                "lower"), np.float64)
    bands, ill = judge.legitimate_interval(ENGINE, inputs)
    lo, hi = bands["intensity"]
    assert ((lo <= exact) & (exact <= hi)).all() and not ill.any()
    assert not judge.confirm(ENGINE, inputs, {"intensity": exact.astype(np.float32)}).any()
    assert judge.confirm(ENGINE, inputs, {"intensity": (exact + 0.1).astype(np.float32)}).all()
    # and a golden case by its own band model: Ψ4 1e-3 off its exact value is wrong
    xi4 = np.array([0.01, 0.1])
    u = np.asarray(PSI.truth(xi4=xi4)[0], np.float64)
    assert judge.confirm(PSI, {"xi4": xi4}, {"u": u + 1e-3}, "float64").all()


def test_a_float_output_outside_its_band_is_flagged_even_at_the_exact_value(monkeypatch):
    """The tie rule is for integer codes only: a float row outside its band stays flagged (here the band, the full
    one too, is built to exclude the exact Ψ4, and the port returns exactly that)."""
    xi4 = np.array([0.01, 0.1, 0.2])
    exact = np.asarray(PSI.truth(xi4=xi4)[0], np.float64)
    bands = {"u": (exact + 0.25, exact + 0.5)}  # within one unit of the exact value, as a code's neighbour would be
    inputs = {"xi4": xi4, **_hand_full_band(monkeypatch, bands, np.zeros(3, bool))}
    assert judge.flagged_rows(PSI, inputs, bands, np.zeros(3, bool), {"u": exact}).all()


@pytest.mark.parametrize("shift", [2, -2])
def test_a_code_two_from_the_exact_code_is_flagged_whatever_the_band(shift):
    """The tie rule's set (the exact codes and each component's own tie neighbour) is the definitive one: a code
    two from the exact one is flagged even inside a (hand-built) band that holds it, and the exact code is
    accepted even where a band two codes off says otherwise."""
    r, _ = _tie_rows()
    truth = _truth(r)
    off = truth.copy()
    off[:, 0] += shift  # the y1 channel two codes off
    flagged = judge.flagged_rows(PACK, {"r": r}, {"q": (np.minimum(off, truth) - 2, np.maximum(off, truth) + 2)},
                                 np.zeros(len(r), bool), {"q": off.astype(np.uint16)})
    assert flagged.all()
    exact = judge.flagged_rows(PACK, {"r": r}, {"q": (off, off.copy())}, np.zeros(len(r), bool),
                               {"q": truth.astype(np.uint16)})
    assert not exact.any()


def test_a_32_bit_word_is_compared_exactly_on_a_tie_of_its_low_field():
    """pack32: ỹ2 (bits 0-9) on a cell boundary, ξ4's field high (a word above 2^31, beyond float32's exact
    integers): the word with the other ỹ2 cell is accepted, one with a ỹ2 two cells off is flagged."""
    case = CASES["pack32-float32"]
    m = np.array([300, 301, 450])  # 511.5 (y2 + 1) = m: a floor boundary; y1's cell 100, far from its boundaries
    r = np.column_stack([np.full(3, 100.5 / 511.5 - 1), m / 511.5 - 1, np.full(3, (40.5 / 128) ** 2),
                         np.full(3, 0.2)])
    for y2 in r[:, 1]:
        s = Fraction(float(y2) + 1) * Fraction(1023, 2)
        assert abs(s - round(s)) < Fraction(1, 10**12)
    from moments_ref.golden.texel_truth import pack32

    (word,) = pack32(r)
    word = word.astype(np.int64)
    assert (word >= 2**31).all() and ((word & 1023) - (m - 1) <= 1).all()
    other = np.where((word & 1023) == m, word - 1, word + 1)  # the other cell next to the boundary
    bands = {"p": (word.astype(np.float64), word.astype(np.float64))}
    ill = np.zeros(3, bool)
    assert not judge.flagged_rows(case, {"r": r}, bands, ill, {"p": other.astype(np.uint32)}).any()
    far = np.where((word & 1023) == m, word + 2, word - 2)
    assert judge.flagged_rows(case, {"r": r}, bands, ill, {"p": far.astype(np.uint32)}).all()


def test_the_judge_confirms_an_engine_row_by_the_engine_cases_route():
    """judge.confirm sends an engine row to the engine cases' confirmation (the exact bounds over the legitimate
    biases and the shipped ports' float32 evaluation on the port's input): 0.9999141693 is what the shipped
    msm.glsl upper bound returned on llvmpipe and lavapipe for this one-depth texel (tests/test_sweep_engine.py),
    legitimate there; the goldens' route alone would confirm it wrong."""
    case = CASES["engine-upper-float32"]
    z = np.full((1, 6), -0.9298073219944447)
    w = np.array([[1.0, 0, 0, 0, 0, 0]])
    inputs = engine.engine_inputs(case, z, w, np.array([-0.928851842880249]))
    driver = np.float32(0.9999141693115234)
    assert not judge.confirm(case, inputs, {"intensity": np.array([driver])})[0]
    assert judge.confirm(case, inputs, {"intensity": np.array([driver - np.float32(1e-3)])})[0]
