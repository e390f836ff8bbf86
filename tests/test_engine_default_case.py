"""The shipped engine cases without a profile, built fresh from engine_specs (docs/golden.md, "Engine cases").

Without a profile an engine port works in the papers' depth frame [-1, 1] and returns the shadow intensity
(HPG17 Algorithm 1's lower or upper bound; the NLQ chain of §3.2–§3.5): the harness applies BIAS_FLOAT32 before
the call and the reference is this package's Algorithm 1 on that input, as is, in the port's precision. Each case
is built now from engine_specs (the case table's closures are built at import, before a mutant's code is swapped
in), and its reference is compared with moments_ref.msm.shadow_intensity, bit for bit, on rows where Algorithm 1's
other float32 formulations (the slides', HPG17's printed one) differ from it.
"""

from __future__ import annotations

import numpy as np
import pytest

from moments_ref.golden.cases import Case
from moments_ref.golden.engine import engine_specs
from moments_ref.golden.paper import slides_bound
from moments_ref.moments import BIAS_FLOAT32, bias_moments
from moments_ref.msm import shadow_intensity
from moments_ref.sweep import engine as sweep_engine


def _fresh(name):
    dt = name.rsplit("-", 1)[1]
    (spec,) = [s for s in engine_specs(dt) if s["name"] == name]
    return Case(**spec)


def _rows(n=400):
    rng = np.random.default_rng(3801)
    z = np.sort(rng.uniform(-1, 1, (n, 3)), axis=1)
    w = rng.uniform(0.1, 1.0, (n, 3))
    zf = z[np.arange(n), rng.integers(0, 3, n)] + rng.uniform(-1e-3, 1e-3, n)
    return z, w, np.clip(zf, -1, 1)


@pytest.mark.parametrize("name", ["engine-lower-float32", "engine-upper-float32", "engine-lower-float64"])
def test_the_default_reference_is_algorithm_1_on_the_harness_biased_input_as_an_intensity(name):
    case = _fresh(name)
    dt, bound = np.dtype(case.dtype).type, name.split("-")[1]
    z, w, zf = _rows()
    b = (w[:, :, None] * z[:, :, None] ** np.arange(1, 5)).sum(1) / w.sum(1)[:, None]
    b = bias_moments(b, BIAS_FLOAT32).astype(dt)
    with np.errstate(all="ignore"):
        got = np.asarray(case.reference(b, zf.astype(dt))[0])
        want = shadow_intensity(b, zf.astype(dt), bound=bound)
        other = slides_bound(b, zf.astype(dt), bound, dt)
    assert got.dtype == dt and np.array_equal(got, want, equal_nan=True)
    if dt == np.float32:  # the rows tell Algorithm 1's float32 formulations apart
        assert not np.array_equal(want, other, equal_nan=True)


@pytest.mark.parametrize("name", ["engine-lower-float32", "engine-nlq64-float64"])
def test_the_default_case_keeps_the_papers_depth_frame(name):
    # the sweep's engine inputs: the distribution and the receiver as given (no [0, 1] conversion), b its moments
    # biased by BIAS_FLOAT32 before the call
    case = _fresh(name)
    z, w, zf = _rows(8)
    arrays = sweep_engine.engine_inputs(case, z, w, zf)
    assert np.array_equal(arrays["support"], z) and np.array_equal(arrays["zf"], zf.astype(case.dtype))
    b = bias_moments((w[:, :, None] * z[:, :, None] ** np.arange(1, 5)).sum(1) / w.sum(1)[:, None], BIAS_FLOAT32)
    assert np.allclose(arrays["b"], b, rtol=1e-6, atol=1e-7)


def test_kept_mutant_a_default_case_returning_visibility_is_seen():
    from _mutants import kept_mutant

    with kept_mutant("moments_ref/golden/engine.py", "_default_ctx::False -> True#1"):
        with pytest.raises(AssertionError):
            test_the_default_reference_is_algorithm_1_on_the_harness_biased_input_as_an_intensity("engine-lower-float32")
