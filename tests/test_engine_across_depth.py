"""The engine rows whose receiver lies on a depth of the distribution (golden.engine's bands, through the sweep).

Docstring of the bands (HPG17 §3.2): where a depth of the distribution lies within NEIGHBOUR_ULPS float32 ulps
of zf, the biased canonical representation has a support point within rounding of zf, and a correct float32
evaluation lands anywhere across the jump of Z: the band holds [Z(z < zf − r), Z(z ≤ zf + r)], r = 3 ulps,
both counted here by hand from the depths and weights (weights not normalised: the band is a fraction of the
mass). A receiver 5 ulps from every depth is off the jump, and its band stays narrow.
"""

from __future__ import annotations

import numpy as np
import pytest

from moments_ref.golden.cases import CASES
from moments_ref.sweep import engine

ZF = np.float32(0.3)
ULP = float(np.spacing(ZF))
R = 3 * ULP
ZF64 = float(ZF)


def _rows():
    # (depths, weights): at zf; 2 and exactly 3 ulps in front; exactly 3 ulps behind; 5 ulps (off the jump)
    z = np.array([[ZF64, -0.5], [ZF64 - 2 * ULP, 0.7], [ZF64 - R, 0.7], [ZF64 + R, -0.5], [ZF64 + 5 * ULP, -0.5]])
    w = np.array([[0.8, 1.2], [0.8, 1.2], [0.8, 1.2], [0.8, 1.2], [0.8, 1.2]])
    return z, w, np.full(len(z), ZF64)


def _jump(z, w):
    below = (w * (z < ZF64 - R)).sum(1) / w.sum(1)
    upto = (w * (z <= ZF64 + R)).sum(1) / w.sum(1)
    return below, upto


@pytest.mark.parametrize("name", ["engine-lower-float32", "engine-upper-float32"])
def test_a_receiver_on_a_depth_is_judged_across_the_jump(name):
    case = CASES[name]
    z, w, zf = _rows()
    bands, _ = engine.interval(case, engine.engine_inputs(case, z, w, zf))
    lo, hi = bands["intensity"]
    below, upto = _jump(z, w)
    near = slice(0, 4)
    assert (lo[near] <= below[near] + 1e-6).all() and (hi[near] >= upto[near] - 1e-6).all()
    assert hi[4] - lo[4] < 0.1  # 5 ulps off: no jump in its band


def test_kept_mutant_a_row_needing_every_depth_near_zf_is_seen():
    from _mutants import kept_mutant

    with kept_mutant("moments_ref/golden/engine.py", "_across_depth::np.any -> np.all#0"):
        with pytest.raises(AssertionError):
            test_a_receiver_on_a_depth_is_judged_across_the_jump("engine-lower-float32")
