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

from moments_ref.golden import bands
from moments_ref.golden.cases import Case


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
