"""The engine cases' confirmation (sweep/engine.py): its span and margin, against mpmath computed here.

The span of a row holds the exact bound (precise, mpmath) of the distribution's moments under each
legitimate bias, and of the port's own input over its float32 neighbourhood (b and zf scaled
jointly by 1 ± k ulps, k = 0 … 3); a port's value is wrong only beyond it by more than 8 float32
ulps of 1 (MARGIN_ULPS). The engine's frame and bias of the port's input are the distribution's
moments, computed here in float64 and rounded once.
"""

from __future__ import annotations

import numpy as np
import pytest

from moments_ref import precise
from moments_ref.golden.cases import CASES
from moments_ref.golden.engine import legit_biases
from moments_ref.sweep import engine

from _mutants import kept_mutant

EPS32 = float(np.finfo(np.float32).eps)
Z = np.array([[-0.5, 0.2, 0.6, 0, 0, 0], [-0.9, -0.1, 0.7, 0, 0, 0], [0.3, 0, 0, 0, 0, 0], [-0.2, 0.1, 0, 0, 0, 0]])
W = np.array([[0.3, 0.3, 0.4, 0, 0, 0], [0.5, 0.25, 0.25, 0, 0, 0], [1, 0, 0, 0, 0, 0], [0.999, 0.001, 0, 0, 0, 0]])
ZF = np.array([0.4, 0.0, 0.3 + 3e-4, 0.05])


def _moments(z, w):
    return np.stack([(w * z**j).sum(axis=1) / w.sum(axis=1) for j in range(1, 5)], axis=1)


def _biased(b, p):
    return (1 - p.alpha) * b + p.alpha * np.asarray(p.target, np.float64)


@pytest.mark.parametrize("bound", ["lower", "upper"])
def test_the_port_gets_the_distributions_biased_moments_rounded_once(bound):
    case = CASES[f"engine-{bound}-float32"]
    inputs = engine.engine_inputs(case, Z, W, ZF)
    (p,) = legit_biases(case.engine)
    want = _biased(_moments(Z, W), p)
    assert inputs["b"].dtype == np.float32 and inputs["zf"].dtype == np.float32
    np.testing.assert_allclose(inputs["b"], want, rtol=0, atol=EPS32)
    np.testing.assert_array_equal(inputs["zf"], ZF.astype(np.float32))
    np.testing.assert_array_equal(inputs["support"], Z)
    np.testing.assert_array_equal(inputs["mass"], W)


@pytest.mark.parametrize("bound", ["lower", "upper"])
def test_the_span_holds_the_exact_bounds_of_the_neighbourhood_and_the_legitimate_biases(bound):
    case = CASES[f"engine-{bound}-float32"]
    inputs = engine.engine_inputs(case, Z, W, ZF)
    lo, hi = engine.exact_span(case, inputs)
    values = []
    for p in legit_biases(case.engine):
        values.append(precise.shadow_intensity(_biased(_moments(Z, W), p), ZF, bound))
    b, zf = inputs["b"].astype(np.float64), inputs["zf"].astype(np.float64)
    for k in range(-3, 4):
        f = 1 + k * EPS32
        values.append(precise.shadow_intensity((b * f).astype(np.float32).astype(np.float64),
                                               (zf * f).astype(np.float32).astype(np.float64), bound))
    v = np.asarray(values, np.float64)
    assert (lo <= v.min(axis=0)).all() and (v.max(axis=0) <= hi).all()
    # and not much beyond them: the shipped evaluation on the port's input lies within its cap
    assert (hi - lo <= (v.max(axis=0) - v.min(axis=0)) + 0.02).all()


@pytest.mark.parametrize("bound", ["lower", "upper"])
def test_a_value_is_confirmed_wrong_only_beyond_eight_float32_ulps_of_the_span(bound):
    case = CASES[f"engine-{bound}-float32"]
    inputs = engine.engine_inputs(case, Z, W, ZF)
    lo, hi = engine.exact_span(case, inputs)
    m = engine.MARGIN_ULPS * EPS32
    assert engine.MARGIN_ULPS == 8
    inside = np.concatenate([lo - 0.9 * m, hi + 0.9 * m, (lo + hi) / 2])
    outside = np.concatenate([lo - 1.5 * m, hi + 1.5 * m])
    n = len(ZF)
    for got, want in ((inside, False), (outside, True)):
        k = len(got) // n
        both = {key: np.concatenate([v] * k) for key, v in inputs.items()}
        assert (engine.confirm(case, both, {"intensity": got}) == want).all()
    # the ends of the widened span are inside it (closed)
    ends = {key: np.concatenate([v] * 2) for key, v in inputs.items()}
    assert not engine.confirm(case, ends, {"intensity": np.concatenate([lo - m, hi + m])}).any()
    # float64 ports: the margin is 8 float64 ulps, so 0.9 float32 margins beyond the span is wrong
    assert engine.confirm(case, inputs, {"intensity": hi + 0.9 * m}, "float64").all()
    empty = {k: v[:0] for k, v in inputs.items()}
    out = engine.confirm(case, empty, {"intensity": np.zeros(0)})
    assert out.shape == (0,) and out.dtype == bool


def test_a_visibility_port_is_judged_on_one_minus_the_span():
    from moments_ref.golden.profile import parse_profile
    from moments_ref.golden.conventions import profiled_case

    prof = parse_profile({"output": "visibility"})
    case = profiled_case(CASES["engine-lower-float32"], prof)
    plain = CASES["engine-lower-float32"]
    inputs = engine.engine_inputs(case, Z, W, ZF)
    lo, hi = engine.exact_span(plain, engine.engine_inputs(plain, Z, W, ZF))
    vlo, vhi = engine.exact_span(case, inputs)
    np.testing.assert_allclose(vlo, 1 - hi, rtol=0, atol=1e-15)
    np.testing.assert_allclose(vhi, 1 - lo, rtol=0, atol=1e-15)


def test_kept_mutant_a_neighbourhood_one_ulp_short_is_seen():
    """exact_span without its two outermost neighbours (k = 2, 3) misses the exact bound there on a one-depth texel whose
    receiver sits just behind the depth (the bound's steep part)."""
    case = CASES["engine-lower-float32"]
    inputs = engine.engine_inputs(case, Z, W, ZF)
    b, zf = inputs["b"].astype(np.float64), inputs["zf"].astype(np.float64)
    f = np.array([1 + 3 * EPS32, 1 - 3 * EPS32])
    edge = [precise.shadow_intensity((b * x).astype(np.float32).astype(np.float64),
                                     (zf * x).astype(np.float32).astype(np.float64)) for x in f]
    lo, hi = engine.exact_span(case, inputs)
    assert (lo <= np.minimum(*edge)).all() and (np.maximum(*edge) <= hi).all()
    with kept_mutant("moments_ref/sweep/engine.py", "exact_span::NEIGHBOUR_ULPS + 1 -> NEIGHBOUR_ULPS - 1#0"):
        lo2, hi2 = engine.exact_span(case, inputs)
    assert ((lo2 > np.minimum(*edge)) | (np.maximum(*edge) > hi2)).any()
