"""golden.bands: bands from the interval of legitimate evaluations, checked by independent means.

Independent means here: the exact values of the mpmath twins (moments_ref.precise, through the case's
truth) over the float32 neighbourhood of a row, and the shipped ports/glsl/msm.glsl run on the driver
(the band counts golden.paper.cholesky_bound, a transliteration of that file, as legitimate: judging the
transliteration against the band would compare the band with a part of itself).
"""

import numpy as np
import pytest

from moments_ref.golden import bands
from moments_ref.golden.cases import CASES
from moments_ref.golden.contract import rows_inside
from moments_ref.golden.paper import cholesky_bound, printed_shade
from moments_ref.golden.spread import golden_arrays
from moments_ref.moments import BIAS_FLOAT32, bias_moments


def _near_singular_rows(n=4000, seed=7):
    # One or two depths, the float32 bias, receivers 1e-4 .. 1e-2 behind a depth (issue 36, item 5).
    rng = np.random.default_rng(seed)
    k = rng.integers(1, 3, n)
    d = rng.uniform(-1, 1, (n, 2))
    d[:, 1] = np.where(k == 1, d[:, 0], d[:, 1])
    w = rng.dirichlet([1, 1], n)
    b = (w[:, :, None] * d[:, :, None] ** np.arange(1, 5)).sum(1)
    b32 = bias_moments(b.astype(np.float32), BIAS_FLOAT32)
    zf = np.clip(d[np.arange(n), rng.integers(0, 2, n)] + 10 ** rng.uniform(-4, -2, n), -1, 1).astype(np.float32)
    return b32, zf


@pytest.mark.parametrize("bound", ["upper", "lower"])
def test_the_shipped_port_lies_in_its_band_near_singular_texels(ctx, bound):
    from moments_ref.conformance import PORTS_DIR, run_function

    case = CASES[f"shadow_intensity-{bound}-float32"]
    b, zf = _near_singular_rows()
    (lo, hi), = [bands.legitimate_interval(case, {"b": b, "zf": zf})[0]["intensity"]]
    got = np.asarray(run_function(PORTS_DIR / "glsl" / "msm.glsl", f"shadow_intensity_{bound}", {"b": b, "zf": zf},
                                  {"intensity": ("float32", zf.shape)}, adapter="gl")[0]["intensity"], np.float64)
    inside = rows_inside(case.contract, {"b": b, "zf": zf})  # robustness rows are judged apart
    assert inside.mean() > 0.5
    ok = ((got >= lo) & (got <= hi)) | ~inside
    assert ok.all(), np.flatnonzero(~ok)[:5]
    # The class exists: the driver's value leaves the float64 reference by more than 1e-5 on some rows
    # (the plain float32 Cholesky evaluation the shipped file and the paper use lands z2 just above zf).
    ref = np.asarray(case.reference(b=b.astype(np.float64), zf=zf.astype(np.float64))[0])
    if bound == "upper":
        assert np.nanmax(np.where(inside, np.abs(got - ref), 0)) > 1e-5


def test_the_transliteration_of_the_shipped_port_matches_the_driver(ctx):
    """golden.paper.cholesky_bound is what makes the band hold the shipped port: it must be that port."""
    from moments_ref.conformance import PORTS_DIR, run_function

    b, zf = _near_singular_rows(1000, seed=11)
    got = np.asarray(run_function(PORTS_DIR / "glsl" / "msm.glsl", "shadow_intensity_upper", {"b": b, "zf": zf},
                                  {"intensity": ("float32", zf.shape)}, adapter="gl")[0]["intensity"], np.float64)
    mine = np.asarray(cholesky_bound(b, zf, "upper"), np.float64)
    # llvmpipe runs the file's operations in the file's order, without contraction: bit for bit, NaN rows alike.
    assert np.array_equal(mine, got, equal_nan=True) and np.isfinite(got).mean() > 0.9


def test_bounded_bands_are_capped_unless_ill_conditioned():
    case = CASES["shadow_intensity-lower-float32"]
    a = golden_arrays(case)
    t = a["intensity_tolerance_float32"]
    wide = np.array(["wide_spread" in f for f in a["flags"]])
    fin = np.isfinite(t)
    assert (t[fin & ~wide] <= bands.CAP * 1.01).all()


def test_the_demo_cancelling_root_fails_its_hazard_rows_and_a_stable_root_passes():
    case = CASES["shade-float32"]
    a = golden_arrays(case)
    haz = np.array(["printed_hazard" in f for f in a["flags"]])
    assert haz.any()
    demo = np.asarray(printed_shade(a["r"], a["zf"], np.float32), np.float64)
    e, t = a["intensity"], a["intensity_tolerance_float32"]
    # Beyond the band, or no value at all (NaN at zf = y2, where q1 = ±inf: also flagged, issue 37).
    assert (~(np.abs(demo[haz] - e[haz]) <= t[haz])).all() and np.isfinite(demo[haz]).sum() >= 3
    # Confirmed with mpmath over the neighbourhood: the demo's value is no neighbour's exact value.
    rows = np.flatnonzero(haz & np.isfinite(demo))[:3]
    inputs = {"r": a["r"][rows], "zf": a["zf"][rows]}
    assert bands.confirm(case, inputs, {"intensity": demo[rows]}).all()
    assert not bands.confirm(case, inputs, {"intensity": e[rows]}).any()


def test_an_ill_conditioned_upper_bound_row_answered_by_a_correct_port_passes():
    # Rows whose exact bound moves under 1-ulp input changes: the band holds every neighbour's exact value.
    case = CASES["shadow_intensity-upper-float32"]
    a = golden_arrays(case)
    wide = np.flatnonzero([("wide_spread" in f) and ("robustness" not in f) for f in a["flags"]])[:4]
    assert wide.size
    inputs = {"b": a["b"][wide], "zf": a["zf"][wide]}
    lo, hi = bands.legitimate_interval(case, inputs)[0]["intensity"]
    eps = float(np.finfo(np.float32).eps)
    for f in (1 + eps, 1 - eps):  # exact values (mpmath) on float32 neighbours
        nb = {"b": (inputs["b"].astype(np.float64) * f).astype(np.float32), "zf": inputs["zf"]}
        exact = np.asarray(case.truth(b=nb["b"].astype(np.float64), zf=nb["zf"].astype(np.float64))[0])
        assert ((exact >= lo - 1e-6) & (exact <= hi + 1e-6)).all()
        assert not bands.confirm(case, inputs, {"intensity": exact}).any()


def test_bands_of_many_rows_are_finite_and_ordered():
    # Speed is measured by `moments-ref bench --only sweep`, not asserted here.
    case = CASES["shadow_intensity-lower-float32"]
    b, zf = _near_singular_rows(200_000, seed=3)
    (lo, hi), ill = [(v["intensity"], i) for v, i in [bands.legitimate_interval(case, {"b": b, "zf": zf})]][0]
    inside = rows_inside(case.contract, {"b": b, "zf": zf})
    assert lo.shape == hi.shape == (200_000,) and ill.shape == (200_000,)
    assert (lo[inside] <= hi[inside]).all() and np.isfinite(lo[inside & ~ill]).all()


def _biased_port(alpha, target):
    from moments_ref.msm import shadow_intensity

    def port(b, zf):
        b = np.asarray(b, np.float32)
        biased = (np.float32(1 - alpha) * b + np.float32(alpha) * np.asarray(target, np.float32)).astype(np.float32)
        return shadow_intensity(biased, np.asarray(zf, np.float32), bound="lower")

    return port


def test_a_port_biasing_toward_its_own_interior_target_passes_its_engine_case():
    # Issue 37: the engine case's band is built from the declared alpha and target (2/3: inside the moment space).
    from moments_ref import oracle
    from moments_ref.golden.profile import parse_profile

    target = [0.0, 2 / 3, 0.0, 2 / 3]
    prof = parse_profile({"bias": {"alpha": 3e-3, "target": target, "applied": "inside"}})
    rep = oracle.check(_biased_port(3e-3, target), "engine-lower", profile=prof, n_hypothesis=0)
    assert rep.passed, rep
    # The same port declaring another target than it uses is told apart (the band is not widened wholesale).
    other = parse_profile({"bias": {"alpha": 3e-3, "target": [0.0, 0.375, 0.0, 0.375], "applied": "inside"}})
    wrong = _biased_port(0.3, target)
    assert not oracle.check(wrong, "engine-lower", profile=other, n_hypothesis=0).passed


def test_a_phi_that_biases_inside_is_judged_with_its_declared_bias():
    # Issue 37: the phi case honours a declared bias (the author's demo biases before Phi, inside its function).
    from moments_ref import oracle
    from moments_ref.golden.profile import parse_profile
    from moments_ref.moments import BiasPreset
    from moments_ref.nonlinear import phi

    preset = BiasPreset(6e-5, (0.0, 0.628, 0.0, 0.628), "demo")

    def port(b):
        return phi(bias_moments(np.asarray(b, np.float32), preset))

    prof = parse_profile({"bias": {"alpha": 6e-5, "target": [0.0, 0.628, 0.0, 0.628], "applied": "inside"}})
    assert oracle.check(port, "phi", profile=prof, n_hypothesis=0).passed
    assert not oracle.check(port, "phi", n_hypothesis=0).passed  # undeclared: its outputs differ
