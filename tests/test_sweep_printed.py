"""The sweep's hazard diagnosis: confirmed rows on which a port returns the papers' printed formulation's own value.

The slides' Algorithm 1 (what most engines ship) cancels in float32 on some engine rows (a pivot
D33D22 rounding to 0 where a depth sits near the end of the range, docs/sweep.md, "Printed
formulations that cancel"): those rows stay wrong (a correct port must not return that value) and
the sweep says whose value it is. Checked against an independent float32 transliteration of the
engine port the suite reproduces (tests/fixtures/wild/engine01.glsl) and mutants that return
something else.
"""

import numpy as np
import pytest

from moments_ref import golden, moments, msm, oracle
from moments_ref.golden.paper import printed_shade, slides_bound, slides_envelope
from moments_ref.golden.profile import Bias, Profile
from moments_ref.sweep import judge
from moments_ref.sweep.command import make_spec
from moments_ref.sweep.engine import engine_inputs
from moments_ref.sweep.runner import Port

ENGINE01 = Profile(depth="[0,1]", output="visibility",
                   bias=Bias(3e-6, (0.5, 0.34375, 0.265625, 0.2265625), "inside"))
TARGET = np.array([0.5, 0.34375, 0.265625, 0.2265625], np.float32)


def _engine01(b, zf):
    """tests/fixtures/wild/engine01.glsl in NumPy float32: :func:`_engine01_intensity`, ``clamp(NaN)`` = 0 as on
    Mesa, as visibility."""
    f = np.float32
    return (f(1) - np.nan_to_num(_engine01_intensity(b, zf), nan=0.0)).astype(f)


def _engine01_intensity(b, zf, reciprocal=True):
    """engine01's bias ``(1 − α) b + α b*`` and the slides' code operation by operation in float32, written apart
    from golden.paper; the intensity clipped to [0, 1], NaN where the code divides by zero. ``reciprocal``: p and q
    through ``1/c2`` as engine01 (and the author's demo) writes them, else divided by c2 as the slides do."""
    f, a = np.float32, np.float32(3e-6)
    b = (f(1) - a) * np.asarray(b, f) + a * TARGET
    z0 = np.asarray(zf, f)
    b0, b1, b2, b3 = b[:, 0], b[:, 1], b[:, 2], b[:, 3]
    with np.errstate(all="ignore"):
        l32d22, d22, var2 = -b0 * b1 + b2, -b0 * b0 + b1, -b1 * b1 + b3
        d33d22 = var2 * d22 + (-l32d22) * l32d22
        inv = f(1) / d22
        l32 = l32d22 * inv
        c1 = z0 - b0
        c2 = z0 * z0 - (b1 + l32 * c1)
        c1 = c1 * inv
        c2 = c2 * (d22 / d33d22)
        c1 = c1 - l32 * c2
        c0 = f(1) - (c1 * b0 + c2 * b1)
        ic = f(1) / c2
        p, q = (c1 * ic, c0 * ic) if reciprocal else (c1 / c2, c0 / c2)
        r = np.sqrt(p * p * f(0.25) - q)
        z1, z2 = -p * f(0.5) - r, -p * f(0.5) + r
        far, mid = z2 < z0, (z2 >= z0) & (z1 < z0)
        s0 = np.where(far, z1, np.where(mid, z0, f(0)))
        s1 = np.where(far, z0, np.where(mid, z1, f(0)))
        quotient = (s0 * z2 - b0 * (s0 + z2) + b1) / ((z2 - s1) * (z0 - z1))
        out = np.where(far, f(1), f(0)) + np.where(far | mid, f(1), f(0)) * quotient
    return np.clip(out, 0, 1).astype(f)


def _rows(case, depths, weights, zf):
    """One row per texel, in the papers' frame [−1, 1] (as the sweep draws them), for ``case``."""
    z = np.array([list(d) + [d[0]] * (6 - len(d)) for d in depths], np.float64)
    w = np.array([list(v) + [0.0] * (6 - len(v)) for v in weights], np.float64)
    return engine_inputs(case, z, w, np.asarray(zf, np.float64))


def test_the_slides_cancelling_on_an_engine_row_is_named_and_stays_wrong():
    case = make_spec("engine-lower-float32", Port(fn=_engine01), None, ENGINE01, 0, 10).case
    # The sweep's shrunk row (docs/sweep.md): depths 0.999866935 and −0.680386793, zf just in front of the first.
    inputs = _rows(case, [(0.999866935, -0.680386793)], [(0.607114, 0.392886)], [0.999866])
    d22 = inputs["b"][0, 1] - inputs["b"][0, 0] ** 2
    assert d22 > 0.1  # not a singular texel: the exact visibility is the occluder at −0.68's weight left over
    got = _engine01(inputs["b"], inputs["zf"])
    assert got[0] == 1.0  # the slides' code: D33D22 rounds to 0, NaN, clamped to 0 intensity
    bands, ill = judge.legitimate_interval(case, inputs)
    lo, hi = bands["intensity"]
    assert not ill[0] and lo[0] <= 0.60711 <= hi[0] and hi[0] - lo[0] < 1e-4
    assert judge.confirm(case, inputs, {"intensity": got})[0]  # wrong, and mpmath says so
    assert judge.printed_rows(case, inputs, {"intensity": got}, bands)[0]
    # A wrong value the printed formulation does not give: no excuse named (where it has no value, either end of the
    # range counts as what a clamp makes of its NaN, as for the goldens' hazard rows).
    for other in (0.5, 0.2, 0.99):
        assert not judge.printed_rows(case, inputs, {"intensity": np.float32([other])}, bands)[0]
    assert not judge.printed_rows(case, inputs, {"intensity": got}, bands, "float64")[0]
    # every arrangement of the code spans [0, 1] here (some lift D33D22 off 0): wider than the cap, so the rounding
    # envelope names no value (a hazard, not the tolerance model's gap); with zf NaN no arrangement has a value
    lo_e, hi_e = slides_envelope(inputs["b"], inputs["zf"], bias=(3e-6, tuple(TARGET.tolist())))
    assert lo_e[0] == 0 and hi_e[0] == 1
    ref = 1 - 0.60711  # the bound as an intensity: arrangements beyond the cap of it explain nothing
    lo_c, hi_c = slides_envelope(inputs["b"], inputs["zf"], bias=(3e-6, tuple(TARGET.tolist())), ref=ref, cap=0.02)
    assert ref - 0.02 <= lo_c[0] <= hi_c[0] <= ref + 0.02
    assert not judge.envelope_rows(case, inputs, {"intensity": np.float32([0.5])})[0]
    assert np.isnan(slides_envelope(inputs["b"], np.float32([np.nan]))).all()


def test_the_goldens_hazard_row_is_the_printed_formulations_value():
    """shadow_intensity-lower's ``printed_hazard`` row (one depth −0.9908, zf = −0.98, BIAS_FLOAT32 in float32):
    the slides' code returns 0 there (D22 cancels), and a port returning it is named; a port returning 0.7 is not."""
    case = golden.CASES["shadow_intensity-lower-float32"]
    stored = np.float32([[-0.9908193349838257, 0.9817230105400085, -0.9727101922035217, 0.9637800455093384]])
    b = moments.bias_moments(stored, moments.BIAS_FLOAT32)
    inputs = {"b": b, "zf": np.float32([-0.98])}
    assert np.isnan(slides_bound(b, inputs["zf"])[0])
    bands, _ = judge.legitimate_interval(case, inputs)
    lo, _ = bands["intensity"]
    assert lo[0] > 0.9  # the bound is about 0.9998
    assert judge.printed_rows(case, inputs, {"intensity": np.float32([0.0])}, bands)[0]
    assert not judge.printed_rows(case, inputs, {"intensity": np.float32([0.7])}, bands)[0]


def test_a_finite_printed_value_is_matched_within_the_rows_tolerance():
    """shade's hazard row (y1 = 0.1, y2 = 0.10001, v2 = 0.5, ξ4 = 1e-6, zf just below y2): HPG17's printed root of
    Algorithm 3 cancels to 0.5 where the bound is 0.265; a port within the row's tolerance of 0.5 is named, one
    farther from it is not."""
    case = golden.CASES["shade-float32"]
    inputs = {"r": np.float32([[0.1, 0.10001, 0.5, 1e-6]]), "zf": np.float32([0.10000800341367722])}
    h = float(printed_shade(inputs["r"], inputs["zf"])[0])
    bands, _ = judge.legitimate_interval(case, inputs)
    lo, hi = (float(x[0]) for x in bands["intensity"])
    assert lo <= 0.2651 <= hi and not lo <= h <= hi  # the printed value lies outside the band
    half = (hi - lo) / 2
    for got, named in ((h, True), (h + 0.9 * half, True), (h - 0.9 * half, True), (h + 1.5 * half, False), (0.4, False)):
        assert judge.printed_rows(case, inputs, {"intensity": np.float32([got])}, bands)[0] == named, got


def test_the_envelope_is_the_slides_code_and_narrow_where_it_is_well_conditioned():
    """The envelope's arrangement as written (and so :func:`slides_bound`, the same code) is an independent float32
    transliteration's value bit for bit, NaN where it divides by zero; on biased random texels the envelope holds
    that value and is narrow (the rounding of a well-conditioned evaluation), where a broken port is far outside."""
    rng = np.random.default_rng(5)
    b = moments.bias_moments(moments.power_moments(rng.uniform(-1, 1, (3000, 3)), rng.random((3000, 3)))
                             .astype(np.float32), moments.BIAS_FLOAT32)
    zf = rng.uniform(-1, 1, 3000).astype(np.float32)
    zf[0] = np.nan  # no value
    lo, hi = slides_envelope(b, zf, draws=0, bias=(3e-6, tuple(TARGET.tolist())))
    want = _engine01_intensity(b, zf, reciprocal=False).astype(np.float64)
    assert np.isnan(want).any() and np.array_equal(lo, want, equal_nan=True) and np.array_equal(hi, want, equal_nan=True)
    zf[0] = 0.5
    v = slides_bound(b, zf).astype(np.float64)
    lo, hi = slides_envelope(b, zf)
    ok = np.isfinite(v)
    assert ok.mean() > 0.99 and np.all((lo[ok] <= v[ok]) & (v[ok] <= hi[ok]))
    assert np.median(hi[ok] - lo[ok]) < 1e-6 and np.mean(hi[ok] - lo[ok] < 1e-4) > 0.97


def test_a_gap_row_is_within_the_envelope_and_a_deviation_is_not():
    """A row engine01 fails on lavapipe (one depth made regular by its bias: the formulation is ill-conditioned,
    the band ±1.1e-6): its value 0.00022197 lies within the envelope of the slides' code, 0.0003 does not."""
    case = make_spec("engine-lower-float32", Port(fn=_engine01), None, ENGINE01, 0, 10).case
    inputs = {"b": np.float32([[5.91572024859488e-05, 3.4995746300836572e-09, 2.0702505736189952e-13,
                                1.2247022736862089e-17]]), "zf": np.float32([0.021497204899787903])}
    got = np.float32([0.0002219676971435547])
    bands, _ = judge.legitimate_interval(case, {**inputs, **_rows(case, [(-0.999882,)], [(1.0,)], [-0.9570056])})
    lo, hi = bands["intensity"]
    assert not lo[0] <= got[0] <= hi[0] and hi[0] - lo[0] < 3e-6  # outside a band of ±1.1e-6
    assert judge.envelope_rows(case, inputs, {"intensity": got})[0]
    assert not judge.printed_rows(case, inputs, {"intensity": got}, bands)[0]
    for other in (0.0003, 0.00021, 0.5):
        assert not judge.envelope_rows(case, inputs, {"intensity": np.float32([other])})[0]
    # the envelope's edge, widened by the confirmation's 8 float32 ulps of 1 (visibility: 1 − the intensities)
    lo_e, hi_e = slides_envelope(inputs["b"], inputs["zf"], bias=(3e-6, tuple(TARGET.tolist())))
    edge, ulp = 1 - hi_e[0], float(np.finfo(np.float32).eps)
    assert edge < got[0] and hi_e[0] - lo_e[0] < 1e-4
    assert judge.envelope_rows(case, inputs, {"intensity": np.float64([edge - 4 * ulp])})[0]
    assert not judge.envelope_rows(case, inputs, {"intensity": np.float64([edge - 12 * ulp])})[0]
    top = 1 - lo_e[0]
    assert judge.envelope_rows(case, inputs, {"intensity": np.float64([top + 4 * ulp])})[0]
    assert not judge.envelope_rows(case, inputs, {"intensity": np.float64([top + 12 * ulp])})[0]
    # a second row of the same run, visibility 0.742 (intensity 0.258): the cap is taken about the intensity
    row = {"b": np.float32([[0.00018242692749481648, 3.327958353338545e-08, 6.071092413517665e-12,
                             1.1075307304023087e-15]]), "zf": np.float32([0.00036632720730267465])}
    assert judge.envelope_rows(case, row, {"intensity": np.float32([0.7420995235443115])})[0]
    assert not judge.envelope_rows(case, inputs, {"intensity": got}, "float64")[0]
    # the port's own value as written (a finite printed value, in visibility): named by the printed rule
    assert judge.printed_rows(case, inputs, {"intensity": _engine01(inputs["b"], inputs["zf"])}, bands)[0]
    shade = golden.CASES["shade-float32"]  # not Algorithm 1: no envelope
    r = {"r": np.float32([[0.1, 0.10001, 0.5, 1e-6]]), "zf": np.float32([0.10000800341367722])}
    assert not judge.envelope_rows(shade, r, {"intensity": np.float32([0.5])})[0]


def test_the_moment_cases_envelope_holds_the_slides_value_and_not_a_shifted_one():
    """``shadow_intensity-lower``: on biased random rows the slides' value as written lies within its envelope
    (where that is narrower than the cap), 0.01 above it does not."""
    case = golden.CASES["shadow_intensity-lower-float32"]
    rng = np.random.default_rng(9)
    b = moments.bias_moments(moments.power_moments(rng.uniform(-1, 1, (64, 2)), rng.random((64, 2)))
                             .astype(np.float32), moments.BIAS_FLOAT32)
    inputs = {"b": b, "zf": rng.uniform(-1, 1, 64).astype(np.float32)}
    v = slides_bound(b, inputs["zf"])
    lo, hi = slides_envelope(b, inputs["zf"])
    ok = np.isfinite(v) & (hi - lo <= 0.04)
    assert ok.sum() > 50
    assert judge.envelope_rows(case, inputs, {"intensity": v})[ok].all()
    assert not judge.envelope_rows(case, inputs, {"intensity": v + np.float32(0.01)})[ok & (hi - lo < 1e-3)].any()
    k = int(np.flatnonzero(ok & (hi < 0.9))[0])  # the upper edge, widened by 8 float32 ulps of 1
    one = {key: val[k:k + 1] for key, val in inputs.items()}
    ulp = float(np.finfo(np.float32).eps)
    assert judge.envelope_rows(case, one, {"intensity": np.float64([hi[k] + 4 * ulp])})[0]
    assert not judge.envelope_rows(case, one, {"intensity": np.float64([hi[k] + 12 * ulp])})[0]


@pytest.mark.parametrize("mutant", [False, True], ids=["slides", "slides-plus-0.01"])
def test_a_sweep_counts_and_names_the_printed_hazard(mutant):
    """20 000 engine rows of the engine01 profile: the slides' port fails only rows where the printed formulation
    cancels, every one of them named so; a mutant off by 0.01 fails rows no formulation explains."""
    port = (lambda b, zf: np.clip(_engine01(b, zf) + np.float32(0.01), 0, 1)) if mutant else _engine01
    res = oracle.sweep(port, "engine-lower-float32", rows=20000, seed=0, shrink=True, profile=ENGINE01)
    d = next(iter(res.drivers.values()))
    assert not res.passed and d["confirmed"] > 0
    text = res.format()
    if mutant:
        assert d["printed"] < d["confirmed"] and d["envelope"] < d["confirmed"] / 10
        assert all(not f.get("printed") or f["got"]["intensity"] in (0.0, 1.0) for f in res.failures)
    else:
        assert d["printed"] == d["confirmed"] == d["examined"]  # every flag confirmed, every one the printed value
        assert d["envelope"] == 0  # counted only where the printed value is not
        assert all(f.get("printed") for f in res.failures)  # the shrunk rows too
        assert f"({d['confirmed']} of them the papers' printed formulation's own value" in text
        assert judge.PRINTED_CAUSE in text


SINGULAR = Profile(depth="[0,1]", output="visibility", bias=Bias(3e-5, (0.5, 0.5, 0.5, 0.5), "inside"))


def _singular_port(b, zf):
    """Algorithm 1 as this package computes it, behind a bias toward (0.5, 0.5, 0.5, 0.5): the moments of
    ½δ(0) + ½δ(1) in [0, 1] (a published engine's choice, tests/fixtures/wild/singular_target.glsl)."""
    biased = moments.bias_moments(np.asarray(b, np.float32), (3e-5, (0.5, 0.5, 0.5, 0.5)))
    return (1 - msm.shadow_intensity(biased, np.asarray(zf, np.float32))).astype(np.float32)


def test_a_singular_bias_target_is_confirmed_wrong_and_named_not_excused():
    """The band judges such a port by the legitimate targets (golden.engine.legit_biases); the confirmation used
    to explain its rows by its own singular bias, which counted them as defects of the tolerance model (338 of the
    512 rows a GLSL engine's port had examined on 10^6 rows). Now every examined flag is confirmed, none is named a
    printed formulation's value or the rounding envelope, and the sweep names the target, as the goldens do."""
    res = oracle.sweep(_singular_port, "engine-lower-float32", rows=20000, seed=0, shrink=False, profile=SINGULAR)
    d = next(iter(res.drivers.values()))
    assert d["confirmed"] > 0 and d["confirmed"] == d["examined"] and d["unconfirmed"] == 0
    assert d["printed"] == 0 and d["envelope"] == 0
    assert res.notes and "the bias target is singular" in res.notes[0] and "0.5·δ(0) + 0.5·δ(1)" in res.notes[0]
    assert "a two-point distribution" in res.notes[0]
    assert "cause: bias target [0.5, 0.5, 0.5, 0.5]" in res.format()
    ok = oracle.sweep(_engine01, "engine-lower-float32", rows=2000, seed=0, shrink=False, profile=ENGINE01)
    assert ok.notes == []  # an interior target: no such cause
