"""golden.engine's bands (issue 37 items 1-3): the interval of legitimate values, checked by independent means.

Independent means here: the mpmath twins (moments_ref.precise.bias_moments, shadow_bounds) on the moments of
each row's distribution (exact rationals, rounded once), over the float32 neighbourhood of the receiver; the
exact Z from math.fsum over the distribution; and the comparator and conformance verdict as a port meets them.
"""

import math

import numpy as np
import pytest

from moments_ref import golden, precise
from moments_ref.conformance.verdict import compare_case
from moments_ref.golden import bands, engine
from moments_ref.golden.conventions import profiled_arrays
from moments_ref.golden.profile import parse_profile
from moments_ref.golden.writer import manifest_entry
from moments_ref.moments import BIAS_FLOAT32, BiasPreset


def _mp_bound(unbiased, preset, zf, bound):
    """The exact (mpmath) bound of the moments biased by ``preset``, at float64 receivers ``zf``."""
    biased = precise.bias_moments(unbiased, preset)
    lower, upper = precise.shadow_bounds(biased, np.asarray(zf, np.float64))
    return upper if bound == "upper" else lower


def _ill(arrays):
    return np.array(["wide_spread" in str(f).split(",") for f in arrays["flags"]], bool)


def _unbiased(arrays):
    return engine.moments_of_rows(arrays["support"], arrays["mass"], np.dtype(np.float64))


def test_the_engine_constants_are_the_band_models():
    assert engine.CAP == bands.CAP and (bands.MARGIN_WIDTH, bands.FLOOR_ULPS) == (3.0, 8)


@pytest.mark.parametrize("name", ["engine-lower-float32", "engine-upper-float32"])
def test_default_band_holds_the_exact_bound_of_the_harness_bias_and_is_capped(name):
    # No profile: the harness biases with BIAS_FLOAT32 before the call; a correct port returns the bound of those
    # moments. The band holds its exact value (mpmath), on the receiver and, at a depth of the distribution, on the
    # receiver's float32 neighbours; no band of a row that is not flagged ill reaches farther than CAP.
    case = golden.CASES[name]
    bound = case.kwargs["bound"]
    a = golden.golden_arrays(case)
    e, zf, unbiased = a["intensity"], a["zf"].astype(np.float64), _unbiased(a)
    ill = _ill(a)
    for d in ("float32", "float64"):
        t = a[f"intensity_tolerance_{d}"]
        assert (t[~ill] <= bands.CAP).all() and np.isfinite(t).all()
        assert (t >= 8 * np.finfo(d).eps).all()
    t = a["intensity_tolerance_float32"]
    assert (np.abs(_mp_bound(unbiased, BIAS_FLOAT32, zf, bound) - e) <= t).all()
    at_depth = np.array(["support_point" in f for f in a["flags"]])
    assert at_depth.sum() >= 5
    z32 = zf.astype(np.float32)
    for step in (np.inf, -np.inf):
        nb = np.nextafter(z32, np.float32(step)).astype(np.float64)
        got = _mp_bound(unbiased[at_depth], BIAS_FLOAT32, nb[at_depth], bound)
        assert (np.abs(got - e[at_depth]) <= t[at_depth]).all()
    # This package's own float32 pipeline on the port's input (informational column) lies in the band too.
    assert (np.abs(a["intensity_float32"].astype(np.float64) - e) <= t).all()
    # Ill rows are exactly those whose band is wider than the cap.
    assert ill.any() and (t[ill] > bands.CAP).all()
    # The expected value is the band's midpoint, not the exact Z of the distribution (which a correct biased MSM
    # does not return): Z lies outside the band on some rows, and the comment names it.
    sup, mass = a["support"], a["mass"]
    z = np.array([math.fsum(m[(s <= f) if bound == "upper" else (s < f)]) for s, m, f in zip(sup, mass, zf)])
    assert (np.abs(z - e) > t).any()
    for i in range(0, len(zf), 17):
        assert f"Z(z {'<=' if bound == 'upper' else '<'} zf) = {z[i]:.9g}" in a["comment"][i]


def test_a_declared_interior_target_gives_its_own_band_and_not_another_targets():
    # A port declaring alpha 3e-3 toward (0, 2/3, 0, 2/3) (inside the moment space): its band holds the exact bound
    # of its own biased moments, and not the bound with the papers' target (0, 0.375, 0, 0.375) where the two
    # differ by more than the band.
    target = (0.0, 2 / 3, 0.0, 2 / 3)
    prof = parse_profile({"bias": {"alpha": 3e-3, "target": list(target), "applied": "inside"}})
    _, a = profiled_arrays("engine-lower-float32", prof)
    e, t, zf, unbiased = a["intensity"], a["intensity_tolerance_float32"], a["zf"].astype(np.float64), _unbiased(a)
    own = _mp_bound(unbiased, BiasPreset(3e-3, target, "own"), zf, "lower")
    assert (np.abs(own - e) <= t).all()
    other = _mp_bound(unbiased, BiasPreset(3e-3, engine.LEGIT_TARGETS[0], "papers"), zf, "lower")
    apart = np.abs(other - own) > 2 * t
    assert apart.sum() >= 5
    assert (np.abs(other - e)[apart] > t[apart]).all()


def test_a_singular_declared_target_is_judged_against_interior_targets():
    # (0.5, 0.5, 0.5, 0.5) in [0, 1] depths: the moments of 1/2 (d0 + d1). Its own bound is no legitimate value:
    # on near/far mixtures (which stay singular) it leaves the band built from interior targets.
    prof = parse_profile({"depth": "[0,1]", "bias": {"alpha": 3e-6, "target": [0.5] * 4, "applied": "inside"}})
    pcase, a = profiled_arrays("engine-lower-float32", prof)
    assert all(engine.target_support(p.target) is None for p in engine.legit_biases(pcase.engine))
    assert {p.alpha for p in engine.legit_biases(pcase.engine)} == {3e-6}
    singular = BiasPreset(3e-6, (0.5, 0.5, 0.5, 0.5), "singular")
    kept = engine.singular_target_rows(a, singular)
    assert kept.sum() >= 5
    # The papers' own float32 code (no singular branch) with that bias divides by zero where the target keeps the
    # distribution singular, and leaves the band there; with the papers' interior target it stays inside.
    from moments_ref.golden.paper import slides_bound
    from moments_ref.moments import bias_moments

    b32 = engine.moments_of_rows(a["support"], a["mass"], np.dtype(np.float32))
    zf, e, t = a["zf"].astype(np.float64), a["intensity"], a["intensity_tolerance_float32"]
    interior = BiasPreset(3e-6, (0.5, 0.34375, 0.265625, 0.2265625), "papers, in [0, 1]")
    with np.errstate(all="ignore"):
        own = np.asarray(slides_bound(bias_moments(b32, singular), zf, "lower", np.float32), np.float64)
        papers = np.asarray(slides_bound(bias_moments(b32, interior), zf, "lower", np.float32), np.float64)
    assert (~(np.abs(own - e) <= t))[kept].sum() >= 3
    assert (np.abs(papers - e) <= t).all()


def _verdict(name, arrays, got):
    case = golden.CASES[name]
    return compare_case(name, manifest_entry(case, arrays), arrays, {"intensity": np.asarray(got, np.float32)})


def test_an_ill_row_answered_from_its_neighbourhood_passes_is_reported_ill_and_is_no_pass():
    name = "engine-upper-float32"
    a = golden.golden_arrays(golden.CASES[name])
    zf, ill = a["zf"].astype(np.float64), _ill(a)
    b = a["b"].astype(np.float64)  # the port's input: biased by the harness
    exact = precise.shadow_bounds(b, zf)[1]
    # On the ill rows, the exact bound at the receiver's next float32 neighbour (what a correct port may return).
    nb = np.nextafter(zf.astype(np.float32), np.float32(np.inf)).astype(np.float64)
    got = np.where(ill, precise.shadow_bounds(b, nb)[1], exact)
    v = _verdict(name, a, got)
    assert v.passed
    tally = v.record["ill_conditioned"]
    assert tally["rows"] == ill.sum() > 0 and tally["inside"] == ill.sum() and tally["outside"] == 0
    gated = sum(c.gated for c in v.categories.values())
    assert gated == len(zf) - ill.sum()  # ill rows never count as passes
    assert {r["index"] for r in v.ill} <= set(np.flatnonzero(ill))


def test_a_value_outside_every_legitimate_bound_fails_an_ill_row():
    name = "engine-upper-float32"
    a = golden.golden_arrays(golden.CASES[name])
    zf, ill, e, t = a["zf"].astype(np.float64), _ill(a), a["intensity"], a["intensity_tolerance_float32"]
    b = a["b"].astype(np.float64)
    # An ill row whose band leaves room in [0, 1]; the exact bounds over its neighbourhood (receiver and moments
    # moved by up to 3 float32 ulps) all lie on one side of the value given.
    rows = np.flatnonzero(ill & ((e - t > 0.1) | (e + t < 0.9)))
    assert rows.size
    i = rows[0]
    value = 0.0 if e[i] - t[i] > 0.1 else 1.0
    eps = float(np.finfo(np.float32).eps)
    nbs = []
    for k in range(-3, 4):
        for s in (1.0, -1.0):
            bb = (b[i] * (1 + k * eps * np.array([s, -s, s, -s]))).astype(np.float32).astype(np.float64)
            zz = np.float64(np.float32(zf[i] * (1 + k * eps)))
            nbs.append(precise.shadow_bounds(bb[None], np.array([zz]))[1][0])
    assert min(abs(x - value) for x in nbs) > bands.CAP
    got = precise.shadow_bounds(b, zf)[1]
    got[i] = value
    v = _verdict(name, a, got)
    assert not v.passed and not v.row_pass[i] and v.row_pass.sum() == len(zf) - 1
    assert v.record["ill_conditioned"]["outside"] == 1
