"""The engine cases' exact span (sweep/engine.py) is the hull of the documented exact values, no wider.

Module docstring of sweep/engine.py: a flagged engine row is confirmed wrong where the port's output lies
outside [min, max] of the exact values of its pipeline under every legitimate bias (applied to the
distribution's moments) and on the port's own input over its neighbourhood (b and zf scaled jointly by
1 ± k ulps of the port's precision, k = 0 … 3), widened by 8 ulps of 1 (MARGIN_ULPS); for the NLQ chains
also this package's own chain on the port's input; for a float32 port of Algorithm 1 also the shipped
ports' float32 evaluations (as the goldens' engine interval, for a float32 port only).

Here a float64 port is judged on rows whose bound is steep (receivers just in front of or behind a depth), with every
documented value computed in the test: the distribution's moments in exact rationals, biased and rounded
once, then the bound in mpmath (``precise``). The span must hold each of them, and must not reach a value
beyond them: a port answering the exact value at the input moved by 6 ulps (twice the neighbourhood) is
confirmed wrong where that value lies beyond the margin. Kept mutants (tests/_mutants.py): the distribution
read in float32, the receiver read in float32, this package's own chain narrowed to float32.
"""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest

from moments_ref import precise
from moments_ref.golden.cases import CASES
from moments_ref.golden.engine import legit_biases
from moments_ref.golden.truth import CHAIN_TIE, nlq_chain
from moments_ref.sweep import engine

from _mutants import kept_mutant

EPS64 = float(np.finfo(np.float64).eps)
MARGIN64 = engine.MARGIN_ULPS * EPS64
PATH = "moments_ref/sweep/engine.py"


def _rows(n, seed):
    """Two- and three-point distributions (papers' frame) with each receiver 1e-7 … 1e-3 in front of or behind its first depth."""
    rng = np.random.default_rng(seed)
    z = rng.uniform(-0.9, 0.9, (n, 3))
    w = rng.uniform(0.05, 1, (n, 3)) * (np.arange(3) < rng.integers(2, 4, n)[:, None])
    zf = z[:, 0] + rng.choice([-1, 1], n) * 10 ** rng.uniform(-7, -3, n)
    return z, w, zf


def _exact_moments(z, w, bias):
    """Σ w z^k / Σ w (k = 1 … 4), biased b − α (b − b*), in exact rationals; rounded once to float64."""
    out = np.empty((len(z), 4))
    for i in range(len(z)):
        zi, wi = [Fraction(float(x)) for x in z[i]], [Fraction(float(x)) for x in w[i]]
        total = sum(wi)
        for k in range(4):
            m = sum(a * b ** (k + 1) for a, b in zip(wi, zi)) / total
            m -= Fraction(bias.alpha) * (m - Fraction(bias.target[k]))
            out[i, k] = float(m)
    return out


def _documented(case, inputs, z, w, zf, k_max=3, bounds=True):
    """The exact values the span is documented to hold (the bound in mpmath): ``(n, m)``."""
    ctx, bound = case.engine, case.engine["bound"]
    b, r = inputs["b"].astype(np.float64), inputs["zf"].astype(np.float64)
    values = [precise.shadow_intensity(_exact_moments(z, w, p), zf, bound) for p in legit_biases(ctx)]
    for k in range(-k_max, k_max + 1):
        f = 1 + k * EPS64  # exact in float64; b * f and r * f are rounded once, as the port's neighbour is
        values.append(precise.shadow_intensity(b * f, r * f, bound))
    return np.stack(values, axis=1)


@pytest.fixture(scope="module", params=["engine-lower-float64", "engine-upper-float64"])
def float64_rows(request):
    case = CASES[request.param]
    z, w, zf = _rows(96, 3801)
    inputs = engine.engine_inputs(case, z, w, zf)
    return case, inputs, _documented(case, inputs, z, w, zf)


def test_a_float64_span_holds_every_documented_exact_value_and_nothing_more(float64_rows):
    case, inputs, values = float64_rows
    lo, hi = engine.exact_span(case, inputs)
    want_lo, want_hi = values.min(axis=1), values.max(axis=1)
    # the moments rounded once from the rationals and from double-double may differ by one float64 ulp
    tiny = 4 * EPS64
    np.testing.assert_allclose(lo, want_lo, rtol=0, atol=tiny)
    np.testing.assert_allclose(hi, want_hi, rtol=0, atol=tiny)
    assert (hi - lo).max() > 1e-11  # steep rows: the neighbourhood's values do differ


def test_a_float64_port_a_hair_beyond_the_documented_neighbourhood_is_confirmed_wrong(float64_rows):
    case, inputs, values = float64_rows
    lo, hi = values.min(axis=1), values.max(axis=1)
    b, r = inputs["b"].astype(np.float64), inputs["zf"].astype(np.float64)
    bound = case.engine["bound"]
    beyond = np.stack([precise.shadow_intensity(b * (1 + s * 6 * EPS64), r * (1 + s * 6 * EPS64), bound)
                       for s in (1, -1)], axis=1)
    # per row, the 6-ulp neighbour farthest outside the documented values
    out = np.maximum(lo[:, None] - beyond, beyond - hi[:, None])
    j = out.argmax(axis=1)
    got = beyond[np.arange(len(j)), j]
    far = out.max(axis=1) > 4 * MARGIN64
    assert far.sum() >= 3, "the rows must be steep enough for a 6-ulp neighbour to leave the span"
    confirmed = engine.confirm(case, inputs, {"intensity": got}, "float64")
    assert confirmed[far].all()
    # and the documented ends, widened by the margin, are not
    ends = {k: np.concatenate([v, v]) for k, v in inputs.items()}
    assert not engine.confirm(case, ends, {"intensity": np.concatenate([lo - 0.9 * MARGIN64, hi + 0.9 * MARGIN64])},
                              "float64").any()


@pytest.mark.parametrize("mid", ["exact_span::np.float64 -> np.float32#1", "exact_span::np.float64 -> np.float32#0"])
def test_kept_mutant_the_distribution_or_the_receiver_read_in_float32_widens_the_span(float64_rows, mid):
    case, inputs, values = float64_rows
    with kept_mutant(PATH, mid):
        lo, hi = engine.exact_span(case, inputs)
    assert ((lo < values.min(axis=1) - 1e-12) | (hi > values.max(axis=1) + 1e-12)).any()


def test_a_float32_port_of_a_float64_case_also_takes_the_shipped_float32_evaluations(float64_rows):
    """golden.engine.engine_interval: a float32 port's values include the shipped float32 evaluations."""
    case, inputs, values = float64_rows
    lo64, hi64 = engine.exact_span(case, inputs, "float64")
    lo32, hi32 = engine.exact_span(case, inputs, "float32")
    assert (lo32 <= lo64).all() and (hi32 >= hi64).all() and ((lo32 < lo64) | (hi32 > hi64)).any()


# --- the NLQ chains: this package's own chain on the port's input ------------------------------------------------

def _nlq(name, n=12, seed=3802):
    case = CASES[name]
    rng = np.random.default_rng(seed)
    z, w = rng.uniform(-0.9, 0.9, (n, 3)), rng.uniform(0.05, 1, (n, 3))
    zf = np.clip(z.mean(axis=1) + rng.normal(0, 0.2, n), -1, 1)
    return case, engine.engine_inputs(case, z, w, zf), (z, w, zf)


def test_a_float64_nlq_span_is_the_exact_chain_and_the_float64_chain_only():
    """For a float64 port the own evaluations are this package's chain in float64 (the port's dtype and
    float64 are the same): the span is the hull of the exact chain's values and that one evaluation."""
    case, inputs, (z, w, zf) = _nlq("engine-nlq64-float64")
    ctx = case.engine
    b, r = inputs["b"].astype(np.float64), inputs["zf"].astype(np.float64)
    ends = []
    for p in legit_biases(ctx):
        ends += nlq_chain(_exact_moments(z, w, p), zf, "64", None, ctx["clamp"], "stored", ctx.get("texel"),
                          tie=CHAIN_TIE)
    for k in range(-3, 4):
        f = 1 + k * EPS64
        ends += nlq_chain(b * f, r * f, "64", None, ctx["clamp"], "stored", ctx.get("texel"), tie=CHAIN_TIE)
    ends.append(np.asarray(engine.engine_reference(ctx)(b, r)[0], np.float64))
    v = np.stack(ends, axis=1)
    lo, hi = engine.exact_span(case, inputs)
    np.testing.assert_allclose(lo, v.min(axis=1), rtol=0, atol=4 * EPS64)
    np.testing.assert_allclose(hi, v.max(axis=1), rtol=0, atol=4 * EPS64)
    for mid in ("exact_span::np.float64 -> np.float32#5", "exact_span::np.float64 -> np.float32#6"):
        with kept_mutant(PATH, mid):
            lo2, hi2 = engine.exact_span(case, inputs)
        assert ((lo2 < v.min(axis=1) - 1e-12) | (hi2 > v.max(axis=1) + 1e-12)).any(), mid


def test_this_packages_float32_chain_is_never_confirmed_wrong():
    """A row at the end of the depth range (chunk 0 of seed 0, row 95) where this package's float32 NLQ chain lies
    3·10⁻³ below every exact value of the neighbourhood: that evaluation is legitimate (module docstring), so a port
    answering it is not confirmed wrong; the mutant that takes the own chain for Algorithm 1 instead drops it."""
    case = CASES["engine-nlq64-float32"]
    z = np.array([[0.18433332415475223, 0.9969663357313723]])
    w = np.array([[0.31584654011756824, 0.6841534598824318]])
    inputs = engine.engine_inputs(case, z, w, np.array([0.9999996318763427]))
    own = np.asarray(engine.engine_reference(case.engine)(inputs["b"], inputs["zf"])[0], np.float64)
    exact = nlq_chain(inputs["b"].astype(np.float64), inputs["zf"].astype(np.float64), "64", None, None, "stored",
                      None, tie=CHAIN_TIE)
    assert (exact[0] - own > 1e-3).all()  # far below the exact chain on the port's input
    assert not engine.confirm(case, inputs, {"intensity": own}).any()
    assert engine.confirm(case, inputs, {"intensity": own - 1e-3}).all()
    with kept_mutant(PATH, "exact_span::ctx.get('fmt') is not None -> ctx.get('fmt') is None#0"):
        assert engine.confirm(case, inputs, {"intensity": own}).all()


# --- the band and the interval ---------------------------------------------------------------------------------

def test_the_band_is_expected_plus_minus_the_tolerance_in_float64():
    """``band``: expected ± the per-row tolerance of the port's dtype, in float64 (a float64 port's tolerance is
    far below float32's resolution: read in float32, 0.1 moves by 1.5e-9 and the tolerance by 2^-25 of itself)."""
    t = float(np.float32(1e-13)) * (1 + 2.0**-25)  # rounds down to float32 by 2^-25 of itself
    arrays = {"intensity": np.array([0.1, 0.0]), "intensity_tolerance_float64": np.array([1e-14, t]),
              "intensity_tolerance_float32": np.array([1e-6, 1e-6])}
    lo, hi = engine.band(arrays, "float64")
    assert lo.dtype == hi.dtype == np.float64
    assert lo.tolist() == [0.1 - 1e-14, -t] and hi.tolist() == [0.1 + 1e-14, t]
    lo32, hi32 = engine.band(arrays, "float32")
    assert lo32.tolist() == [0.1 - 1e-6, -1e-6] and hi32.tolist() == [0.1 + 1e-6, 1e-6]


def test_the_interval_refuses_a_port_input_that_is_not_the_derivations():
    """``interval`` checks that the sweep's port input b is bit for bit the one ``derive_engine`` hands the port:
    one float32 ulp off in one row is a RuntimeError (a harness defect), never a band for other inputs."""
    case = CASES["engine-lower-float32"]
    z, w, zf = _rows(4, 3803)
    inputs = engine.engine_inputs(case, z, w, zf)
    bands, ill = engine.interval(case, inputs)
    assert bands["intensity"][0].shape == (4,) and ill.shape == (4,)
    moved = dict(inputs, b=inputs["b"].copy())
    moved["b"][2, 1] = np.nextafter(moved["b"][2, 1], np.float32(1))
    with pytest.raises(RuntimeError, match="port input b differs"):
        engine.interval(case, moved)


def test_a_declared_clamped_case_test_is_the_one_the_exact_chain_takes():
    """Profile ``clamp_test = "clamped"`` (Algorithm 3's case test zf ≤ max(y2, y1 + clamp), the author's demo code):
    on an unbiased two-point texel whose 32-bit texel decodes to y1 = y2, with the receiver half a clamp behind
    them, the stored and the clamped test part (0.0257 against 0 in mpmath). A port that declares the clamped test
    but compares with the stored y2 is confirmed wrong; one that compares with the clamped y2 is not."""
    from moments_ref.golden.conventions import profiled_case
    from moments_ref.golden.profile import parse_profile

    clamp = 1 / 65535
    case = profiled_case(CASES["engine-nlq32-float32"],
                         parse_profile({"bias": "none", "clamp": clamp, "clamp_test": "clamped"}))
    z = np.array([[0.006032540505304215, 0.006136900117190373]])
    w = np.array([[0.3961969167816973, 0.6038030832183028]])
    inputs = engine.engine_inputs(case, z, w, np.array([0.006850249256793894]))
    b, r = inputs["b"].astype(np.float64), inputs["zf"].astype(np.float64)
    stored = nlq_chain(b, r, "32", None, clamp, "stored", {}, tie=CHAIN_TIE)
    clamped = nlq_chain(b, r, "32", None, clamp, "clamped", {}, tie=CHAIN_TIE)
    assert stored[0] > 0.02 and clamped[1] < 1e-30
    assert engine.confirm(case, inputs, {"intensity": stored[0]}).all()
    assert not engine.confirm(case, inputs, {"intensity": clamped[0]}).any()
    with kept_mutant(PATH, "_exact::ctx.get('clamp_test') or 'stored' -> ctx.get('clamp_test') and 'stored'#0"):
        assert not engine.confirm(case, inputs, {"intensity": stored[0]}).any()


@pytest.mark.parametrize("name", ["engine-lower-float32", "engine-upper-float64"])
def test_the_span_defaults_to_a_port_of_the_cases_precision(name):
    case = CASES[name]
    z, w, zf = _rows(16, 3808)
    inputs = engine.engine_inputs(case, z, w, zf)
    plain = engine.exact_span(case, inputs)
    own = engine.exact_span(case, inputs, case.dtype)
    other = engine.exact_span(case, inputs, "float64" if case.dtype == "float32" else "float32")
    assert all(np.array_equal(a, b) for a, b in zip(plain, own))
    assert not all(np.array_equal(a, b) for a, b in zip(plain, other))
