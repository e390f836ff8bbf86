"""sweep/engine.py at its edges: unbiased one-point texels and the [0, 1] receiver, against values stated here.

* A profile with no bias (``bias = "none"``) feeds the port the unbiased moments of its texel. On a texel of
  one depth z the distribution is δ(z), so the exact lower bound is Z(z < zf): 1 for a receiver behind it, 0
  in front (HPG17 §3.2: the bound is attained by the distribution itself). The shipped float32 evaluation
  divides by zero there (NaN); a NaN evaluation is no evaluation, so a port answering the exact value
  is not confirmed wrong, and one answering the other end is.
* A [0, 1] port's receiver is the float32 rounding of (zf + 1) / 2, rounded once from the exact value
  (computed here in rationals).

Kept mutant (tests/_mutants.py): the span taken with np.minimum, which lets the NaN through, shown
confirming the exact value wrong.
"""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest

from moments_ref.golden.cases import CASES
from moments_ref.golden.conventions import profiled_case
from moments_ref.golden.profile import parse_profile
from moments_ref.sweep import engine

from _mutants import kept_mutant

Z = np.array([[0.3, 0.0], [-0.45, 0.0], [0.3, 0.0], [-0.45, 0.0]])
W = np.array([[1.0, 0.0], [1.0, 0.0], [1.0, 0.0], [1.0, 0.0]])
ZF = np.array([0.5, 0.2, 0.1, -0.7])
EXACT = np.array([1.0, 1.0, 0.0, 0.0])  # Z(z < zf) of δ(z)


@pytest.fixture(scope="module")
def unbiased():
    case = profiled_case(CASES["engine-lower-float32"], parse_profile({"bias": "none"}))
    return case, engine.engine_inputs(case, Z, W, ZF)


def test_the_exact_value_of_a_one_point_texel_is_not_confirmed_wrong(unbiased):
    case, inputs = unbiased
    lo, hi = engine.exact_span(case, inputs)
    assert np.isfinite(lo).all() and np.isfinite(hi).all()
    assert not engine.confirm(case, inputs, {"intensity": EXACT}).any()
    assert engine.confirm(case, inputs, {"intensity": 1 - EXACT}).all()


@pytest.mark.parametrize("mid", ["exact_span::np.fmin -> np.minimum#0", "exact_span::np.fmax -> np.maximum#0"])
def test_kept_mutant_a_nan_evaluation_taken_as_an_end_is_seen(unbiased, mid):
    case, inputs = unbiased
    with kept_mutant("moments_ref/sweep/engine.py", mid):
        assert engine.confirm(case, inputs, {"intensity": EXACT}).any()


def test_a_unit_ports_receiver_is_rounded_once():
    case = profiled_case(CASES["engine-lower-float32"], parse_profile({"depth": "[0,1]"}))
    rng = np.random.default_rng(38)
    zf = np.concatenate([rng.uniform(-1, 1, 4000), rng.uniform(-1, 1, 4000).astype(np.float32)])
    z = np.zeros((len(zf), 1))
    got = engine.engine_inputs(case, z, np.ones_like(z), zf)["zf"]
    assert got.dtype == np.float32
    want = np.array([_round32((Fraction(float(x)) + 1) / 2) for x in zf])
    np.testing.assert_array_equal(got.astype(np.float64), want)


def _round32(q):
    """The float32 nearest to the rational ``q`` (ties to even), chosen among three candidates by exact distance."""
    c = np.float32(float(q))
    cands = [np.nextafter(c, np.float32(-np.inf)), c, np.nextafter(c, np.float32(np.inf))]
    best = min(cands, key=lambda x: (abs(Fraction(float(x)) - q), int(np.asarray(x).view(np.uint32)) & 1))
    return float(best)


@pytest.mark.parametrize("name", ["engine-lower-float32", "engine-upper-float64"])
def test_the_span_holds_every_neighbour_of_the_ports_input(name):
    """Module docstring: the exact bound on b and zf scaled jointly by 1 ± k ulps of the port's dtype, k = 0 … 3,
    each one (mpmath here); receivers just behind a depth, where the bound is steep and the neighbours' values not monotone in k."""
    from moments_ref import precise

    rng = np.random.default_rng(381)
    n = 40
    z = rng.uniform(-1, 1, (n, 3))
    w = rng.uniform(0, 1, (n, 3)) * (rng.uniform(size=(n, 3)) < 0.7)
    w[:, 0] += 0.05
    zf = np.clip(z[:, 0] + rng.normal(0, 0.02, n), -1, 1)
    case = CASES[name]
    bound = case.kwargs["bound"]
    inputs = engine.engine_inputs(case, z, w, zf)
    lo, hi = engine.exact_span(case, inputs)
    b, r = inputs["b"].astype(np.float64), inputs["zf"].astype(np.float64)
    dt = inputs["b"].dtype
    eps = float(np.finfo(dt).eps)
    for k in range(-3, 4):
        f = 1 + k * eps
        v = precise.shadow_intensity((b * f).astype(dt).astype(np.float64), (r * f).astype(dt).astype(np.float64), bound)
        assert (lo <= v).all() and (v <= hi).all(), k


def _nlq_rows(name):
    rng = np.random.default_rng(7)
    n = 40
    z, w = rng.uniform(-1, 1, (n, 3)), rng.uniform(0.05, 1, (n, 3))
    zf = np.clip(z.mean(1) + rng.normal(0, 0.1, n), -1, 1)
    case = CASES[name]
    return case, engine.engine_inputs(case, z, w, zf)


@pytest.mark.parametrize("name, least", [("engine-nlq32-float32", 20), ("engine-nlq64-float32", 1)])
def test_an_nlq_port_that_skips_the_quantization_is_confirmed_wrong(name, least):
    """HPG17 §3.3/§3.5: the chain shades the moments after pack/unpack; Algorithm 1's exact bound on the unquantized
    moments (mpmath) misses it by more than the margin on most 32-bit rows and on some 64-bit rows."""
    from moments_ref import precise

    case, inputs = _nlq_rows(name)
    skipped = precise.shadow_intensity(inputs["b"].astype(np.float64), inputs["zf"].astype(np.float64))
    assert engine.confirm(case, inputs, {"intensity": skipped}).sum() >= least

