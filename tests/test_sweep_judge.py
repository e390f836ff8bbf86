"""sweep.judge: the sweep judges by the goldens' band model, in the port's precision."""

from __future__ import annotations

import numpy as np

from moments_ref.golden import bands
from moments_ref.golden.cases import CASES
from moments_ref.sweep import judge


def test_the_sweeps_bands_and_confirmation_are_the_goldens_in_the_ports_precision():
    case = CASES["psi4-float64"]
    xi4 = np.array([0.1, 0.5, 0.9, 1e-3])
    for dt in ("float32", "float64"):
        mine, ill = judge.legitimate_interval(case, {"xi4": xi4}, dt)
        theirs, ill2 = bands.legitimate_interval(case, {"xi4": xi4}, dt)
        assert np.array_equal(mine["u"][0], theirs["u"][0]) and np.array_equal(mine["u"][1], theirs["u"][1])
        assert np.array_equal(ill, ill2)
    exact = np.asarray(case.truth(xi4=xi4)[0], np.float64)
    # 5e-7 off: within a float32 port's floor (8 float32 ulps of the scale 1: 9.5e-7), far beyond a float64 port's
    off = exact + 5e-7
    assert judge.confirm(case, {"xi4": xi4}, {"u": off}, "float64").all()
    assert not judge.confirm(case, {"xi4": xi4}, {"u": off}, "float32").any()
    assert not judge.confirm(case, {"xi4": xi4}, {"u": exact}, "float64").any()
    lo64, hi64 = judge.legitimate_interval(case, {"xi4": xi4}, "float64")[0]["u"]
    lo32, hi32 = judge.legitimate_interval(case, {"xi4": xi4}, "float32")[0]["u"]
    assert ((hi64 - lo64) < (hi32 - lo32)).all()
