"""golden.spread's rounding-tie rule on a toy code whose every legitimate evaluation is told apart.

The goldens accept, per row of an integer output, the truth's code, the reference's in float64 and
float32, and the float64 reference's on the inputs scaled by 1 ± 8 float32 eps (inputs inside [−1, 1]
stay inside); a row with more than one code is a rounding tie (flagged ``rounding_tie``, category
stiff, result acceptable). The toy's reference (tests/test_band_edges.py) gives the code 10 below the
exact one in float32 and 20 above in float64, so the acceptable set says which evaluation made each
code; every code below is computed by hand in the comments.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from moments_ref.golden.spread import derive
from test_band_edges import _code_case

N = 8 * 2.0**-23  # the nudge


def _derive(case, x):
    n = len(x)
    return derive(case, {"x": x}, ["random"] * n, [""] * n, [()] * n)


def test_the_acceptable_codes_are_the_truths_the_references_and_the_nudged_inputs_in_float64():
    # x = 1 + 2^-21: x K + 1/2 = 2^20 + 1, code c. float64 reference: c + 20; float32: x K + 1/2 is exact in
    # float32 too, c - 10. x (1 + N) K + 1/2 = 2^20 + 2 + 2^-21: c + 1, so c + 21. x (1 - N) = 1 - 2^-21 - 2^-41:
    # x (1 - N) K + 1/2 = 2^20 - 2^-21, code c - 2, so c + 18 (in float32 the product would round to
    # 1 - 2^-21, code c - 1).
    # x = -(1 + 2^-21): beyond [-1, 1], scaled too: code c' = -2^20; c' + 20, c' - 10, and x (1 + N) K + 1/2 =
    # -2^20 - 1 - 2^-21: c' - 2, so c' + 18; x (1 - N) K + 1/2 = -2^20 + 1 + 2^-21: c' + 1, so c' + 21.
    c, c2 = 2**20 + 1, -(2**20)
    x = np.array([1 + 2.0**-21, -(1 + 2.0**-21)], np.float32)
    a = _derive(_code_case(), x)
    assert a["q"].tolist() == [c, c2]
    assert a["q_acceptable"].tolist() == [[c, c + 20, c - 10, c + 21, c + 18], [c2, c2 + 20, c2 - 10, c2 + 18, c2 + 21]]
    assert [f.split(",") for f in a["flags"]] == [["rounding_tie"], ["rounding_tie"]]
    assert a["category"].tolist() == ["stiff", "stiff"] and a["result"].tolist() == ["acceptable"] * 2
    assert all(s.endswith("[on a rounding boundary: the code changes within float32 rounding of the inputs]")
               for s in a["comment"])


def test_an_input_inside_minus_one_one_is_kept_where_its_nudge_would_leave_it():
    # float64 inputs: x = fl(1 / (1 + N)) with fl(x (1 + N)) = 1 exactly stays at 1 (not beyond); at 1 itself
    # the up-nudge would leave [-1, 1]: x is kept, its code c = 2^20 (x K + 1/2 = 2^20 + 1/2)
    case = replace(_code_case(), dtype="float64")
    x1 = 1 / (1 + N)
    assert x1 * (1 + N) == 1.0
    a = _derive(case, np.array([x1, 1.0]))
    # x1: x1 K + 1/2 = 2^20 - 1 + 1/2 + ..., code 2^20 - 1; scaled up: exactly 1, code 2^20; down: 2^20 - 2
    lo = 2**20 - 1
    assert a["q_acceptable"][0].tolist() == [lo, lo + 20, lo - 10, 2**20 + 20, lo - 1 + 20]
    # 1: up-nudge kept at 1 (code 2^20, so 2^20 + 20); down: 1 - N, K (1 - N) + 1/2 = 2^20 - 1/2 (N K = 1), code
    # 2^20 - 1, so 2^20 + 19
    assert a["q_acceptable"][1].tolist() == [2**20, 2**20 + 20, 2**20 - 10, 2**20 + 20, 2**20 + 19]
