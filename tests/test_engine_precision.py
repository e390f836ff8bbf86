"""The float64 engine cases judge a float64 port at float64 precision.

A port that evaluates Algorithm 1 in float32 (this package's float32 Algorithm 1, HPG17's printed
formulation or the slides' code, on the case's float64 input) is not a float64 implementation: on the
engine cases' well-conditioned rows its values lie outside the float64 band, while the float64
reference lies inside every band. Computed here with the public evaluations, on the goldens' arrays.
"""

from __future__ import annotations

import numpy as np
import pytest

from moments_ref.golden import engine
from moments_ref.golden.cases import CASES
from moments_ref.golden.paper import printed_bound, slides_bound
from moments_ref.msm import shadow_intensity


def _outside(name):
    """Per evaluation: how many rows not flagged wide_spread lie outside the float64 band."""
    case, bound = CASES[name], name.split("-")[1]
    rows = engine._engine_rows(None, case.dtype)
    arrays = {k: rows.inputs[k] for k in ("zf", "support", "mass")}
    out = engine.derive_engine(case, arrays, rows.category, rows.comment, rows.flags)
    b, zf = out["b"], arrays["zf"]
    ill = np.array(["wide_spread" in str(f).split(",") for f in out["flags"]])
    with np.errstate(all="ignore"):
        values = {"float64": shadow_intensity(b, zf, bound=bound),
                  "float32": shadow_intensity(b.astype(np.float32), zf.astype(np.float32), bound=bound),
                  "printed32": printed_bound(b, zf, bound, np.float32), "slides32": slides_bound(b, zf, bound, np.float32)}
    return {k: int(np.sum(~(np.abs(np.asarray(v, np.float64) - out["intensity"]) <= out["intensity_tolerance_float64"])
                          & ~ill)) for k, v in values.items()}


@pytest.mark.parametrize("name", ["engine-lower-float64", "engine-upper-float64"])
def test_a_float64_port_computing_in_float32_fails_the_float64_engine_case(name):
    got = _outside(name)
    assert got["float64"] == 0, got
    assert min(got["float32"], got["printed32"], got["slides32"]) >= 20, got


@pytest.mark.parametrize("bound", ["lower", "upper"])  # the lower case's noise is 0 (the widths' median), the upper's not
def test_the_case_noise_is_the_median_width_over_the_random_well_conditioned_rows(bound, monkeypatch):
    # golden.engine.case_noise's docstring: the median width of the legitimate interval (engine_interval) over the
    # random rows that are not ill-conditioned (a float32 width beyond CAP), per port precision, on the case's
    # golden rows with its default engine (the harness biases with BIAS_FLOAT32 before the call)
    from moments_ref.moments import BIAS_FLOAT32

    ctx = {"fmt": None, "bound": bound, "clamp": None, "unit": False, "visibility": False, "before": BIAS_FLOAT32,
           "inside": None, "alpha": None}
    rows = engine._engine_rows(None, "float32")
    arrays = {k: rows.inputs[k] for k in ("zf", "support", "mass")}
    b = engine.moments_of_rows(arrays["support"], arrays["mass"], np.dtype(np.float32), bias=BIAS_FLOAT32)
    intervals = engine.engine_interval(ctx, arrays, b)
    width32 = intervals["float32"][1] - intervals["float32"][0]
    random = np.asarray(rows.category) == "random"
    keep = random & (width32 <= engine.CAP)
    assert 0 < keep.sum() < random.sum() and (width32[~random] > 0).any()  # the filters matter on these rows
    monkeypatch.setattr(engine, "_NOISE", {})  # measured now, not read from this process's cache
    noise = engine.case_noise(ctx, "float32")
    for d, (lo, hi) in intervals.items():
        assert noise[d] == np.median((hi - lo)[keep]), d
        assert noise[d] != np.median((hi - lo)[random | (width32 <= engine.CAP)])
