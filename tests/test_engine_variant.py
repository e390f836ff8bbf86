"""The engine cases under a profile (golden.engine's variant), against statements computed here in mpmath.

docs/formats.md's keys, as an engine port declares them:

* ``output = "visibility"``: the port returns 1 − intensity; the reference is 1 − the exact bound;
* ``bias`` applied ``inside`` with an interior target: the reference biases the port's input by the declared
  (α, b*) (HPG17 §3.2, b' = (1 − α) b + α b*) and the legitimate bias is that one alone;
* undeclared: the harness applies BIAS_FLOAT32 before the call and that is the one legitimate bias;
* a singular declared target under ``depth = "[0,1]"``: the legitimate targets are the papers' interior
  targets carried to [0, 1] depth, z' = (z + 1) / 2, whose moments are Σ_j C(k, j) b_j / 2^k (binomial
  expansion, mpmath here).

Kept mutant (tests/_mutants.py): the visibility flag read as "any profile", shown failing.
"""

from __future__ import annotations

from math import comb

import numpy as np
import pytest
from mpmath import mp, mpf

from moments_ref import precise
from moments_ref.golden.cases import CASES, Case
from moments_ref.golden.conventions import profiled_case
from moments_ref.golden.engine import LEGIT_TARGETS, engine_specs, legit_biases
from moments_ref.golden.profile import parse_profile
from moments_ref.moments import BIAS_FLOAT32, BiasPreset

from _mutants import kept_mutant

# biased moments of three-point distributions (well inside the moment space) and receivers between their depths
_Z = np.array([[-0.5, 0.2, 0.6], [-0.9, -0.1, 0.7], [-0.3, 0.0, 0.4], [0.1, 0.5, 0.9]])
_W = np.array([[0.3, 0.3, 0.4], [0.5, 0.25, 0.25], [0.2, 0.5, 0.3], [0.4, 0.4, 0.2]])
ZF = np.array([0.4, 0.0, 0.2, 0.7])
B = precise.bias_moments(np.stack([(_W * _Z**k).sum(1) for k in range(1, 5)], 1), BIAS_FLOAT32)
INTERIOR = (0.05, 0.4, 0.02, 0.3)


def _fresh(name):
    """The case ``name`` built now from engine_specs (the case table's closures are built at import, before a
    mutant's code is swapped in by the mutation tool or tests/_mutants.py)."""
    dt = name.rsplit("-", 1)[1]
    (spec,) = [s for s in engine_specs(dt) if s["name"] == name]
    return Case(**spec)


def _reference(profile, dt=np.float64):
    case = profiled_case(_fresh(f"engine-lower-{np.dtype(dt).name}"), parse_profile(profile))
    return case, np.asarray(case.reference(B.astype(dt), ZF.astype(dt))[0], np.float64)


@pytest.mark.parametrize("name, keys", [("engine-lower-float32", ("bias",)), ("engine-upper-float64", ("bias",)),
                                        ("engine-nlq64-float32", ("bias", "clamp", "format")),
                                        ("engine-nlq32-float64", ("bias", "clamp", "format"))])
def test_each_engine_case_states_what_docs_golden_says(name, keys):
    """An intensity in [0, 1] from four moments b1..b4 and zf; BIAS_FLOAT32 applied by the harness before the call
    unless the profile declares another (the cases' descriptions, HPG17 §3.2); the NLQ cases also take the clamp and the
    texel format."""
    case = _fresh(name)
    assert (case.inputs, case.outputs, case.value_range, case.width) == (("b", "zf"), ("intensity",), (0, 1), 4)
    assert case.default_bias == ("before", BIAS_FLOAT32) and case.bias_before is True
    assert tuple(case.profile_keys) == keys


def test_the_fresh_cases_are_the_case_tables():
    for name in ("engine-lower-float64", "engine-upper-float32", "engine-nlq64-float32", "engine-nlq32-float64"):
        fresh, table = _fresh(name), CASES[name]
        assert (fresh.function, fresh.kwargs, fresh.profile_keys, fresh.engine) == \
            (table.function, table.kwargs, table.profile_keys, table.engine)


def test_a_visibility_port_is_referenced_by_one_minus_the_bound():
    exact = precise.shadow_intensity(B, ZF)
    _, vis = _reference({"output": "visibility"})
    np.testing.assert_allclose(vis, 1 - exact, rtol=0, atol=1e-9)
    for other in ({"depth": "[0,1]"}, {}):
        _, ref = _reference(other)
        np.testing.assert_allclose(ref, exact, rtol=0, atol=1e-9)


def test_a_bias_declared_inside_is_applied_by_the_reference_and_is_the_one_legitimate_bias():
    profile = {"bias": {"alpha": 0.01, "target": list(INTERIOR), "applied": "inside"}}
    case, ref = _reference(profile)
    exact = precise.shadow_intensity(precise.bias_moments(B, BiasPreset(0.01, INTERIOR)), ZF)
    np.testing.assert_allclose(ref, exact, rtol=0, atol=1e-9)
    assert abs(ref - precise.shadow_intensity(B, ZF)).max() > 1e-4  # the bias matters on these rows
    (p,) = legit_biases(case.engine)
    assert (p.alpha, tuple(p.target)) == (0.01, INTERIOR)


@pytest.mark.parametrize("profile", [{}, {"depth": "[-1,1]"}, {"output": "visibility"}])
def test_undeclared_the_harness_bias_is_the_one_legitimate_bias(profile):
    case, _ = _reference(profile)
    (p,) = legit_biases(case.engine)
    assert (p.alpha, tuple(p.target)) == (BIAS_FLOAT32.alpha, tuple(BIAS_FLOAT32.target))


def _to_unit(b):
    """Moments of (z + 1) / 2 from those of z (b_0 = 1), by the binomial expansion in mpmath."""
    mp.dps = 40
    full = [mpf(1)] + [mpf(x) for x in b]
    return tuple(float(sum(comb(k, j) * full[j] for j in range(k + 1)) / 2**k) for k in range(1, 5))


@pytest.mark.parametrize("depth, frame", [("[0,1]", _to_unit), ("[-1,1]", lambda t: tuple(float(x) for x in t))])
def test_a_singular_target_is_judged_against_the_interior_targets_in_the_ports_frame(depth, frame):
    profile = {"depth": depth, "bias": {"alpha": 3e-6, "target": [0.5, 0.5, 0.5, 0.5], "applied": "inside"}}
    case, _ = _reference(profile)
    got = legit_biases(case.engine)
    assert [p.alpha for p in got] == [3e-6] * len(LEGIT_TARGETS)
    for p, t in zip(got, LEGIT_TARGETS):
        np.testing.assert_allclose(p.target, frame(t), rtol=0, atol=1e-15)


def test_kept_mutant_visibility_for_any_profile_is_seen():
    mid = ("_variant.variant::profile is not None and profile.output == 'visibility' -> "
           "profile is not None or profile.output == 'visibility'#0")
    with kept_mutant("moments_ref/golden/engine.py", mid):
        _, ref = _reference({"depth": "[0,1]"})
    assert abs(ref - precise.shadow_intensity(B, ZF)).max() > 0.1


def test_a_declared_depth_decode_reaches_the_nlq32_reference():
    """docs/formats.md (decode positions): 32-bit depths decode at the upper end of their cell, (ỹ + 1)/511.5 − 1, by
    default; a port declaring `[format] depth_decode = "centre"` or `"lower"` reads every depth lower, so every
    occluder moves toward the light and the shadow grows: intensity(lower) > intensity(centre) > intensity(upper) =
    intensity(default), on each row."""
    ref = {}
    for key, profile in (("default", {}), ("upper", {"format": {"depth_decode": "upper"}}),
                         ("centre", {"format": {"depth_decode": "centre"}}),
                         ("lower", {"format": {"depth_decode": "lower"}})):
        case = profiled_case(_fresh("engine-nlq32-float64"), parse_profile(profile))
        ref[key] = np.asarray(case.reference(B, ZF)[0], np.float64)
    np.testing.assert_array_equal(ref["upper"], ref["default"])
    assert (ref["lower"] > ref["centre"]).all() and (ref["centre"] > ref["upper"]).all()
