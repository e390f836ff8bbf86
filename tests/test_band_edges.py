"""golden.bands at the edges of its rule, on hand-computed rows (every number a power of two or exact).

The module docstring's rule: the band is [lo − m, hi + m], the margin m = max(4 × noise, 3 × width,
8 ulps of max(|e|, floor scale)) in the port's precision; a bounded output's band reaches at most
CAP × its range from e; a formulation (the printed formulas) widens a contract row only where its
error stays within the cap, and beyond it flags a hazard; a chained case's row is ill-conditioned
where its band with the margin reaches beyond the cap. Each expected value below is written out
from that rule, with a range of [0, 50] so that the cap is exactly 1.
"""

from __future__ import annotations

import numpy as np
import pytest

from moments_ref.golden import bands
from moments_ref.golden.cases import CASES, Case


def _identity(x):
    return (np.asarray(x),)


def _case(value_range=None, function="toy"):
    return Case(name="toy", function=function, dtype="float32", inputs=("x",), outputs=("y",), rows=None,
                reference=_identity, metric="abs", value_range=value_range, floor_scale=1.0)


def _band(case, e, core, hooks=(), noise=0.0):
    e = np.asarray(e, np.float64)
    (lo, hi, ill, hazard, bad), = bands.interval_parts(
        case, np.dtype(np.float32), [e], np.ones(len(e), bool), (noise,),
        [(np.asarray(v, np.float64),) for v in core], [(np.asarray(v, np.float64),) for v in hooks])
    return lo, hi, ill, hazard, bad


def test_a_formulation_exactly_the_cap_away_widens_the_band_and_one_beyond_is_a_hazard():
    # e = 4 on [0, 50]: cap 1. A formulation at 5 (exactly the cap) widens the band to 5 (the cap); one at
    # 5 + 2^-40 explains nothing: a hazard, and the band keeps the floor, 8 float32 ulps of 4 (2^-21 each).
    lo, hi, ill, hazard, bad = _band(_case((0, 50)), [4.0, 4.0], [[4.0, 4.0]], hooks=[[5.0, 5.0 + 2.0**-40]])
    assert hazard.tolist() == [False, True] and not ill.any() and not bad.any()
    assert hi.tolist() == [5.0, 4.0 + 8 * 2.0**-21]
    assert lo.tolist() == [4.0 - 1.0, 4.0 - 8 * 2.0**-21]  # three widths of 1 below, capped at e - 1


def test_a_chained_row_whose_band_reaches_exactly_the_cap_is_not_ill():
    # e = 2, one evaluation 1/4 away: width 1/4, margin three widths (3/4), the band reaches 1/4 + 3/4 = 1 =
    # the cap exactly, below and above: not ill, and capped at e ± 1. 2^-20 farther: ill, not capped.
    chained = _case((0, 50), function="kernels.toy")
    d = 2.0**-20
    lo, hi, ill, hazard, bad = _band(chained, [2.0] * 4, [[1.75, 2.25, 1.75 - d, 2.25 + d]])
    assert ill.tolist() == [False, False, True, True]
    assert lo[:2].tolist() == [1.0, 2.0 - 0.75] and hi[:2].tolist() == [2.0 + 0.75, 3.0]
    assert lo[2] == 1.75 - d - 3 * (0.25 + d) and hi[3] == 2.25 + d + 3 * (0.25 + d)


def test_an_unbounded_outputs_band_is_lo_minus_and_hi_plus_the_margin():
    # no range, no cap: e = 1 with an evaluation at 1/2 (width 1/2, margin 3/2) gives [-1, 5/2]; above, the same
    lo, hi, ill, hazard, bad = _band(_case(), [1.0, 1.0], [[0.5, 1.5]])
    assert lo.tolist() == [0.5 - 1.5, 1.0 - 1.5] and hi.tolist() == [1.0 + 1.5, 1.5 + 1.5]
    assert not ill.any() and not hazard.any()
    # a formulation widens an unbounded contract row whatever its distance (no cap to exceed)
    lo, hi, *_ = _band(_case(), [1.0], [[1.0]], hooks=[[9.0]])
    assert (lo[0], hi[0]) == (1.0 - 24.0, 9.0 + 24.0)


# ---------------------------------------------------------------------------
# integer outputs: the goldens' tie rule, on a toy code whose every legitimate evaluation is told apart

K = 2.0**20  # code = floor(x K + 1/2): one code every 2^-20, about one float32 nudge (8 · 2^-23) of x = 1


def _code_reference(x):
    """The reference: float32 arithmetic gives the code 10 below, float64 the code 20 above the exact one
    (a toy whose legitimate evaluations all differ, so each one's presence is visible)."""
    x = np.asarray(x)
    q = np.floor(x * x.dtype.type(K) + x.dtype.type(0.5)).astype(np.int64)
    return (q - 10 if x.dtype == np.float32 else q + 20,)


def _code_truth(x):
    return (np.floor(np.asarray(x, np.float64) * K + 0.5).astype(np.int64),)


def _code_case(**kw):
    return Case(name="toy", function="toy", dtype="float32", inputs=("x",), outputs=("q",), rows=None,
                reference=_code_reference, truth=_code_truth, metric="exact", **kw)


def test_a_codes_band_spans_the_truths_the_references_and_the_nudged_inputs_codes():
    # x = 1 + 2^-20: x K + 1/2 = 2^20 + 3/2, exact code c = 2^20 + 1 (and on every input within 3 float32 ulps:
    # they move x K by at most 3/8). float32 reference: c - 10; float64: c + 20; the float64 reference on
    # x (1 + 8 · 2^-23): x K = 2^20 + 2 + 2^-20, code c + 1, so c + 21; on x (1 - 8 · 2^-23): x K = 2^20 - 2^-20,
    # code c - 1, so c + 19.
    x = np.array([1 + 2.0**-20], np.float32)
    c = 2**20 + 1
    assert _code_truth(x)[0].tolist() == [c]
    (lo, hi), = bands.legitimate_interval(_code_case(), {"x": x})[0].values()
    assert (lo.tolist(), hi.tolist()) == ([c - 10.0], [c + 21.0])
    legit = {c, c - 10, c + 20, c + 21, c + 19}
    for q in range(c - 12, c + 24):
        assert bands.confirm(_code_case(), {"x": x}, {"q": np.array([q])}).tolist() == [q not in legit], q


def test_on_a_rounding_tie_either_neighbour_of_the_exact_code_is_explained():
    # the case's margin (distance to a rounding boundary) at or below TIE_BAND: the codes next to the exact
    # one are legitimate too (a GPU's log or exp a few ulps off); two away, or above the band, not
    x = np.array([1 + 2.0**-20] * 3, np.float32)
    c = 2**20 + 1

    def margin(at):
        return lambda x: np.full(len(x), at)

    tie = _code_case(margin=margin(bands.TIE_BAND))
    got = np.array([c - 1, c + 2, c + 1])
    assert bands.confirm(tie, {"x": x}, {"q": got}).tolist() == [False, True, False]
    assert bands.confirm(tie, {"x": x}, {"q": np.array([c - 2, c + 3, c + 18])}).tolist() == [True, True, True]
    above = _code_case(margin=margin(2 * bands.TIE_BAND))
    assert bands.confirm(above, {"x": x}, {"q": got}).tolist() == [True, True, True]


# ---------------------------------------------------------------------------
# confirm's neighbourhood: points within PERTURB_ULPS float32 ulps per component, not only jointly

E24 = 2.0**-24  # the float32 spacing in [0.5, 1)


def _difference(x1, x2):
    return ((np.asarray(x1, np.float64) - np.asarray(x2, np.float64)) * 1e6,)


def _difference_case():
    # y = (x1 - x2) 10^6 at x1 = x2 = 0.75: scaling both jointly leaves y = 0; only inputs rounded apart move it
    return Case(name="toy", function="toy", dtype="float32", inputs=("x1", "x2"), outputs=("y",), rows=None,
                reference=_difference, truth=_difference, perturb=True, floor_scale=0.0)


def test_confirm_explains_inputs_moved_apart_by_up_to_three_ulps_each_but_not_farther():
    # 0.75 (1 + j 2^-23) rounds to 0.75 + {2, 3, 4} 2^-24 for j = 1, 2, 3 (ties to even), and below alike: two
    # inputs moved apart by j1 and j2 ulps differ by up to 8 · 2^-24 (equal inputs have no component-wise
    # legitimate evaluation: only confirm's component-wise neighbours move them apart). Those points are drawn once
    # and are the same for every row: every row explains the differences they reach, none explains 9 · 2^-24.
    n = 40
    x = np.full(n, 0.75, np.float32)
    case = _difference_case()
    pts = bands.confirm_points(case, {"x1": x, "x2": x})
    apart = [np.rint((p["x1"].astype(np.float64) - p["x2"]) / E24) for p in pts]
    assert all(np.ptp(d) == 0 for d in apart)  # the same for every row
    top, bottom = max(d[0] for d in apart), min(d[0] for d in apart)
    assert top >= 5 and bottom <= -5  # moved apart both ways, beyond one ulp each
    for k in (top, bottom):
        assert not bands.confirm(case, {"x1": x, "x2": x}, {"y": np.full(n, k * E24 * 1e6)}).any()
    for k in (9, -9):
        assert bands.confirm(case, {"x1": x, "x2": x}, {"y": np.full(n, k * E24 * 1e6)}).all()


def test_the_component_wise_points_move_each_component_both_ways_independently():
    # confirm_points: after the row and the six joint scalings, points with each component moved by j ulps, j from
    # -3 … 3 drawn per point and component (the same for every row)
    case = CASES["shadow_intensity-lower-float32"]
    b = np.full((2, 4), 0.75, np.float32)
    zf = np.full(2, 0.75, np.float32)
    pts = bands.confirm_points(case, {"b": b, "zf": zf})
    assert len(pts) == 1 + 2 * bands.PERTURB_ULPS + bands.NEIGHBOURS
    # offsets in units of 2^-24 at 0.75 (j = 1, 2, 3 ulps of 2^-23 round to 2, 3, 4): per point, b's 4 and zf
    moved = np.array([np.append(p["b"][0], p["zf"][0]) for p in pts[1 + 2 * bands.PERTURB_ULPS:]], np.float64)
    units = np.rint((moved - 0.75) / E24)
    assert np.abs(units).max() <= 4
    assert (units > 0).any(axis=0).all() and (units < 0).any(axis=0).all()  # each component both ways
    assert (np.ptp(units, axis=1) > 0).sum() >= len(units) - 1  # not joint scalings
    for p in pts:  # the same points for both rows
        assert np.array_equal(p["b"][0], p["b"][1]) and p["zf"][0] == p["zf"][1]


def _sqrt_of_distance(x):
    x = np.asarray(x, np.float64)
    with np.errstate(invalid="ignore"):
        return (np.sqrt(0.75 - x),)


def test_the_neighbourhood_interval_spans_the_finite_exact_values_around_the_row():
    # sqrt(0.75 - x) at x = 0.75: NaN above (no value), 0 on the row, and below it the farthest neighbour,
    # 0.75 (1 - 3 · 2^-23) rounded to float32 (0.75 - 4 · 2^-24, ties to even)
    case = Case(name="toy", function="toy", dtype="float32", inputs=("x",), outputs=("y",), rows=None,
                reference=_sqrt_of_distance, truth=_sqrt_of_distance, floor_scale=0.0)
    x = np.array([0.75, 0.75, 0.5], np.float32)
    (lo, hi), = bands.neighbourhood_interval(case, {"x": x}).values()
    assert lo.tolist()[:2] == [0.0, 0.0] and hi.tolist()[:2] == [np.sqrt(4 * E24)] * 2
    # at 0.5 (spacing 2^-24 above, 2^-25 below): the exact values at 0.5 (1 ± 3 · 2^-23), i.e. 0.5 ± 3 · 2^-24
    assert (lo[2], hi[2]) == (np.sqrt(0.25 - 3 * E24), np.sqrt(0.25 + 3 * E24))


# ---------------------------------------------------------------------------
# the case's rounding noise: the 90th percentile over its random rows, each row's neighbourhood as the rule says
# (component-wise neighbours only on rows without a structured flag and without equal inputs)

U = E24 * 1e6  # one float32 spacing of 0.75 or 0.5 in y = (x1 - x2) 10^6


def _noise_case(rows):
    """A toy case whose random rows are ``rows``: (x1, x2, flags) each."""
    from types import SimpleNamespace

    def generate(rng, dtype):
        return SimpleNamespace(inputs={"x1": [r[0] for r in rows], "x2": [r[1] for r in rows]},
                               category=["random"] * len(rows), comment=[""] * len(rows),
                               flags=[r[2] for r in rows])

    return Case(name="toy-noise", function="toy", dtype="float32", inputs=("x1", "x2"), outputs=("y",),
                rows=generate, reference=_difference, truth=_difference, floor_scale=0.0)


def test_the_noise_takes_component_wise_neighbours_only_where_the_rule_allows_them():
    # (0.75, 0.5): jointly scaled by 1 ± 3 · 2^-23 and rounded, 0.75 ± 4 · 2^-24 and 0.5 ± 3 · 2^-24: y moves by
    # 1 U; one ulp each way with alternating signs, 0.75 ± 2 · 2^-24 (ties to even) and 0.5 ∓ 2^-24: 3 U.
    # (0.75, 0.75), equal inputs: jointly 0; component-wise it would be 4 U.
    plain, edge, fold, equal = (0.75, 0.5, ()), (0.75, 0.5, ("shadow_edge",)), (0.75, 0.5, ("fold",)), \
        (0.75, 0.75, ())
    # devs 3 U on nine rows flagged with a non-structured flag, 1 U on the structured one, 0 on the equal one
    assert bands.case_noise(_noise_case([edge] * 9 + [fold, equal]), "float32") == (3 * U,)
    # nine unflagged rows
    assert bands.case_noise(_noise_case([plain] * 9 + [fold, equal]), "float32") == (3 * U,)
    # nine rows of equal inputs and one plain: the 90th percentile of (0 x 9, 3 U), 0.3 U
    assert bands.case_noise(_noise_case([equal] * 9 + [plain]), "float32") == pytest.approx((0.3 * U,), rel=1e-12)


def test_a_formulation_within_the_cap_explains_a_float64_ports_value_to_its_last_bit():
    # range [-25, 25], cap 1: formulations x + 1/2 + 2^-30 and x - 1 (exactly at the cap in float64 for x = 0.1:
    # fl(fl(0.1 - 1) - 0.1) = -1). A float64 port returning either value exactly is explained (its floor is 8
    # float64 ulps of 1); the same value read in float32 would lose the 2^-30, or put 0.1 - 1 beyond the cap.
    def hook(inputs, dtype):
        x = np.asarray(inputs["x"], np.float64)
        return [(x + 0.5 + 2.0**-30,), (x - 1.0,)]

    case = Case(name="toy", function="toy", dtype="float64", inputs=("x",), outputs=("y",), rows=None,
                reference=_identity, truth=_identity, value_range=(-25, 25), spread_hook=hook)
    x = np.array([0.25, 0.1])
    assert abs((0.1 - 1.0) - 0.1) == 1.0 and abs((0.1 - 1.0) - float(np.float32(0.1))) > 1.0
    got = np.array([0.75 + 2.0**-30, 0.1 - 1.0])
    assert not bands.confirm(case, {"x": x}, {"y": got}, "float64").any()
    assert bands.confirm(case, {"x": x}, {"y": got + 2.0**-40}, "float64").tolist() == [True, False]


def _peak(x):
    # -((x - c) / 2^-24)^2 with c = fl32(0.75 (1 + 2^-23)) = 0.75 + 2 · 2^-24: 0 at c, -4 at 0.75
    return (-(((np.asarray(x, np.float64) - (0.75 + 2 * E24)) / E24) ** 2),)


def test_confirm_takes_the_exact_value_one_ulp_away_on_every_row():
    # The row x = 0.75: its neighbours 0.75 (1 + k 2^-23) rounded are 0.75 + {2, 3, 4} 2^-24 (k = 1, 2, 3): the peak
    # (0) is at k = 1 alone; the other points give -1 and -4, below 0.75 - 2, -3, -4 ulps -16, -25, -36. A port
    # returning 0 is explained on every row (by the k = 1 point, whatever the random neighbours draw); 1/2 not.
    case = Case(name="toy", function="toy", dtype="float32", inputs=("x",), outputs=("y",), rows=None,
                reference=_peak, truth=_peak, perturb=False, floor_scale=0.0)
    x = np.full(40, 0.75, np.float32)
    assert not bands.confirm(case, {"x": x}, {"y": np.zeros(40)}).any()
    assert bands.confirm(case, {"x": x}, {"y": np.full(40, 0.5)}).all()
