"""The sweep's verdict on rows of the three classes that made the shipped ports fail 10^7-row sweeps.

* Algorithm 1's upper bound: a biased one-depth texel whose float32 moments lie just outside the
  moment space (B(b) indefinite, positive definite 3 ulps away), where the shipped plain-Cholesky
  evaluation (0.9999965) and the exact value (1) part: the neighbourhood reaches the contract, so
  the papers' formulations are legitimate there and the row is not flagged; a value far off is.
* Robustness rows (beyond the contract's neighbourhood) are counted, failed only under strict.
* pack64: a code on a rounding tie (the exact scaled ξ4 within TIE_BAND of a boundary) is not
  flagged; a code two off on the same row, or one off on a row away from any tie, is. (The tie
  rule is the goldens' per row: on a row on a tie, every component may be one code off.)
* Six moments: rows on which the shipped ports' former evaluation (three trigonometric roots,
  their weights summed) was confirmed wrong by mpmath; the shipped ports pass them now, and a
  one-change mutant of them (the fragment's own weight w0 dropped) is flagged and confirmed.

The rows were found by ``moments-ref sweep`` (seed 0) and are written out here.
"""

from __future__ import annotations

import mpmath
import numpy as np
import pytest

from moments_ref.conformance import PORTS_DIR
from moments_ref.golden import bands
from moments_ref.golden.cases import CASES
from moments_ref.golden.paper import cholesky_bound
from moments_ref.sweep import judge

#: One of the 23 unconfirmed flags of round two (shadow_intensity-upper-float32, 10^7 rows): a biased
#: one-depth texel at -0.9444 (32-bit texel), zf = -0.8999; llvmpipe and lavapipe return GOT_UPPER.
UPPER_B = np.array([[-0.944408655166626, 0.8919081687927246, -0.8423259258270264, 0.7955002188682556]], np.float32)
UPPER_ZF = np.array([-0.8999294638633728], np.float32)
GOT_UPPER = np.float32(0.9999964833259583)

#: A pack64 row on a rounding tie of the Ψ4 code (the shipped port writes 54700, the band's codes are 54701).
TIE_R = np.array([[-0.949906051158905, 0.5926446914672852, 0.17064373195171356, 0.00012449920177459717]], np.float32)
TIE_GOT = np.array([[1641, 52187, 11183, 54700]], np.uint32)

#: Rows on which the former msm6 ports were confirmed wrong (lower, upper), and the bound near 1.
SIX = {
    "lower": [([-0.06256468594074249, 0.1611114889383316, -0.10715902596712112, 0.09594949334859848,
                -0.07752565294504166, 0.06486567854881287], 0.9014354944229126, 0.9998990893363953),
              ([-0.5122900605201721, 0.3425489068031311, -0.2135317176580429, 0.13582956790924072,
                -0.08603256940841675, 0.05477520078420639], 1.0, 0.9997637867927551)],
    "upper": [([-0.8319610357284546, 0.7671262621879578, -0.7414999008178711, 0.7312096357345581,
                -0.7265322804450989, 0.7242693901062012], 0.9999825358390808, 0.9999964237213135),
              ([0.7279825210571289, 0.5302301049232483, 0.3860321640968323, 0.2812046706676483,
                0.20470386743545532, 0.14915695786476135], 0.7406894564628601, 0.9999913573265076)],
}


def _lambda_min_exact(b):
    """Smallest eigenvalue of B(b) of one row, in mpmath (50 digits), from the float32 values."""
    with mpmath.workdps(50):
        full = [mpmath.mpf(1)] + [mpmath.mpf(float(x)) for x in b]
        m = mpmath.matrix([[full[i + j] for j in range(3)] for i in range(3)])
        return float(min(mpmath.eigsy(m)[0]))


def test_upper_bound_one_depth_row_just_outside_the_moment_space_takes_the_shipped_evaluation():
    case = CASES["shadow_intensity-upper-float32"]
    inputs = {"b": UPPER_B, "zf": UPPER_ZF}
    # Independently of the contract code: B(b) of the float32 moments is indefinite (mpmath eigenvalues) ...
    assert _lambda_min_exact(UPPER_B[0]) < 0
    assert not bands.contract_rows(case, inputs).any()
    # ... and positive definite 3 float32 ulps away (the moments scaled by 1 - 3 eps, rounded to float32).
    eps = float(np.finfo(np.float32).eps)
    assert _lambda_min_exact((UPPER_B[0].astype(np.float64) * (1 - 3 * eps)).astype(np.float32)) > 0
    reach = judge.contract_rows(case, inputs)
    assert reach.all()
    # The shipped evaluation, transliterated in NumPy float32, is what the drivers return there.
    assert cholesky_bound(UPPER_B, UPPER_ZF, "upper")[0] == GOT_UPPER
    got = {"intensity": np.array([GOT_UPPER])}
    bands_, ill = judge.legitimate_interval(case, inputs, contract=reach)
    assert not judge.flagged_rows(case, inputs, bands_, ill, got).any()
    # Without the neighbourhood (the exact contract) the default band lacks it: round two's unconfirmed flag. The
    # full band (the float64 reference over the confirmation's points, some inside the moment space) holds it.
    narrow, ill2 = judge.legitimate_interval(case, inputs, contract=bands.contract_rows(case, inputs))
    assert judge.wrong_rows(case, narrow, ill2, got).all() and not judge.confirm(case, inputs, got).any()
    assert not judge.flagged_rows(case, inputs, narrow, ill2, got).any()
    # A value off by far more than the shipped evaluation errs is flagged and confirmed.
    off = {"intensity": np.array([np.float32(0.99)])}
    assert judge.flagged_rows(case, inputs, bands_, ill, off).all() and judge.confirm(case, inputs, off).all()


def _pack64_flagged(r, got):
    case = CASES["pack64-float32"]
    inputs = {"r": r}
    bands_, ill = judge.legitimate_interval(case, inputs)
    return judge.flagged_rows(case, inputs, bands_, ill, {"q": got}), judge.confirm(case, inputs, {"q": got})


def test_pack64_code_on_a_rounding_tie_is_not_flagged_a_wrong_code_next_to_it_is():
    case = CASES["pack64-float32"]
    assert bands.on_tie(case, {"r": TIE_R}).all()
    lo, hi = judge.legitimate_interval(case, {"r": TIE_R})[0]["q"]
    assert not ((TIE_GOT >= lo) & (TIE_GOT <= hi)).all()  # outside the band's codes: only the tie rule accepts it
    flagged, wrong = _pack64_flagged(TIE_R, TIE_GOT)
    assert not flagged.any() and not wrong.any()
    two_off = TIE_GOT.copy()
    two_off[0, 3] -= 1  # 54699: two codes from the truth's 54701
    flagged, wrong = _pack64_flagged(TIE_R, two_off)
    assert flagged.all() and wrong.all()
    other = TIE_GOT.copy()
    other[0, 0] += 2
    assert _pack64_flagged(TIE_R, other)[0].all()


def test_pack64_one_code_off_away_from_a_tie_is_flagged():
    case = CASES["pack64-float32"]
    r = np.array([[-0.4881783723831177, 0.6832869052886963, 0.6538659930229187, 0.09653180837631226]], np.float32)
    assert not bands.on_tie(case, {"r": r}).any()
    truth = np.asarray(case.truth(r=r)[0], np.uint32)
    for k in range(4):
        got = truth.copy()
        got[0, k] += 1
        flagged, wrong = _pack64_flagged(r, got)
        assert flagged.all() and wrong.all(), k
    assert not _pack64_flagged(r, truth)[0].any()


def _six_rows(bound):
    b = np.array([r[0] for r in SIX[bound]], np.float32)
    zf = np.array([r[1] for r in SIX[bound]], np.float32)
    return {"b": b, "zf": zf}, np.array([r[2] for r in SIX[bound]], np.float32)


@pytest.mark.parametrize("bound", ["lower", "upper"])
def test_msm6_rows_the_former_ports_failed_are_confirmed_against_it(bound):
    case = CASES[f"shadow_intensity6-{bound}-float32"]
    inputs, former = _six_rows(bound)
    bands_, ill = judge.legitimate_interval(case, inputs)
    got = {"intensity": former}
    assert judge.flagged_rows(case, inputs, bands_, ill, got).all()
    assert judge.confirm(case, inputs, got).all()


@pytest.mark.parametrize("language", ["glsl", "hlsl", "wgsl"])
@pytest.mark.parametrize("bound", ["lower", "upper"])
def test_shipped_msm6_passes_those_rows_and_a_mutant_fails(ctx, tmp_path, language, bound):
    from moments_ref.sweep.runner import Port, SweepSpec, evaluate

    case_name = f"shadow_intensity6-{bound}-float32"
    case = CASES[case_name]
    inputs, _ = _six_rows(bound)
    path = PORTS_DIR / language / f"msm6.{language}"
    bands_, ill = judge.legitimate_interval(case, inputs)
    spec = SweepSpec(case_name, Port(str(path), f"shadow_intensity6_{bound}", language), ("gl",))
    got = evaluate(spec, inputs, "gl")
    assert not judge.flagged_rows(case, inputs, bands_, ill, got).any()
    if language != "glsl" or bound != "lower":
        return
    # One change: the fragment's own weight w0 dropped from 1 - w0 (two or three Gauss nodes below zf).
    src = path.read_text()
    old = "lower = (1.0 - w0) * two_below + w * (odd - two_below);"
    assert old in src
    mutant = tmp_path / "msm6_no_w0.glsl"
    mutant.write_text(src.replace(old, "lower = two_below + w * (odd - two_below);", 1))
    mutant_spec = SweepSpec(case_name, Port(str(mutant), f"shadow_intensity6_{bound}", language), ("gl",))
    got = evaluate(mutant_spec, inputs, "gl")
    flagged = judge.flagged_rows(case, inputs, bands_, ill, got)
    assert flagged[0] and judge.confirm(case, inputs, got)[flagged].all()  # the first row: three nodes below zf


def test_robustness_rows_are_counted_ungated_and_failed_only_under_strict():
    from moments_ref import oracle
    from moments_ref.golden.cases import evaluate_reference

    # The chains receive unbiased moments: float32 rounding leaves one-depth texels outside the moment space.
    case = CASES["e2e-nlq64-float32"]

    def nan_outside(*args):  # the reference, but NaN on robustness rows (beyond the contract's neighbourhood)
        inputs = dict(zip(case.inputs, args))
        out = np.asarray(evaluate_reference(case, inputs, np.float32)[0])
        return np.where(judge.contract_rows(case, inputs), out, np.float32(np.nan)).astype(np.float32)

    res = oracle.sweep(nan_outside, "e2e-nlq64", rows=4000, shrink=False)
    ungated = sum(s["ungated"] for s in res.record()["strata"].values())
    assert ungated > 0 and res.passed
    strict = oracle.sweep(nan_outside, "e2e-nlq64", rows=4000, shrink=False, strict=True)
    assert not strict.passed
    assert strict.record()["drivers"]["None"]["flagged"] == ungated
