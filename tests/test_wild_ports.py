"""Behaviours found in public MSM ports, reproduced (tests/fixtures/wild), on both drivers.

Each legitimate one passes with the profile its engine declares and no adapter (the
harness converts the inputs and derives expected values for it); each bug fails for
its own reason: the failing rows, their level, and for a singular bias target the
report's cause naming it. Drivers absent: skipped, or failed under CI.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from moments_ref import conformance
from moments_ref.golden.profile import load_profile

from _oracles import golden_folder


WILD = Path(__file__).resolve().parent / "fixtures" / "wild"
ALG1 = ["shadow_intensity-lower-float32", "engine-lower-float32"]
#: stem -> ({language: function}, cases)
LEGIT = {
    "biased_caller": ({"hlsl": "ComputeBiasedShadowIntensity", "glsl": "ComputeBiasedShadowIntensity",
                       "wgsl": "compute_biased_shadow_intensity"}, ALG1),
    "engine01": ({"hlsl": "EngineVisibility01", "glsl": "engine_visibility01", "wgsl": "engine_visibility01"}, ALG1),
}
#: The HPG17 author's demo shading: its root is the printed -p/2 - sqrt(p^2/4 - q), which cancels in float32.
AUTHOR_SHADE = {"hlsl": "AuthorShade", "glsl": "author_shade", "wgsl": "author_shade"}
SINGULAR = {"hlsl": "SingularTargetVisibility", "glsl": "singular_target_visibility",
            "wgsl": "singular_target_visibility"}


def _run(stem, language, function, case, driver, profile=True):
    p = WILD / f"{stem}.toml"
    prof = load_profile(p) if profile and p.exists() else None
    # the cases' golden folder, written once per test run (not generated again for every port)
    goldens = golden_folder(tuple(sorted(set(ALG1) | {"shade-float32"})))
    return conformance.run_case(WILD / f"{stem}.{language}", function, case, goldens, language, driver, profile=prof)


@pytest.mark.parametrize("driver", ["gl", "vulkan"])
@pytest.mark.parametrize("stem,language,function,case", [
    (stem, lang, fn, case) for stem, (fns, cases) in LEGIT.items() for lang, fn in fns.items() for case in cases])
def test_a_legitimate_port_passes_with_its_profile_and_no_adapter(drivers, stem, language, function, case, driver):
    report = _run(stem, language, function, case, driver)
    assert report.passed, report.format()
    assert any(n.startswith("profile: ") for n in report.notes)


@pytest.mark.parametrize("driver", ["gl", "vulkan"])
@pytest.mark.parametrize("language", ["hlsl", "glsl", "wgsl"])
def test_the_authors_demo_root_fails_where_the_printed_formula_cancels(drivers, language, driver):
    """With its clamp declared, the demo's shading fails only rows flagged ``printed_hazard`` (the band of the
    interval model no longer stretches to 16 × the printed formula's error: it returned 0.99998 for 0.0154),
    and the report names the printed root and the stable one."""
    report = _run("author_shade", language, AUTHOR_SHADE[language], "shade-float32", driver)
    assert not report.passed
    gated = [g for g in report.groups if g.level == "contract"]
    assert gated and all("printed_hazard" in g.flags.split(",") for g in gated), gated
    assert sum(len(g.rows) for g in gated) == report.failures
    text = report.format()
    assert "printed formula" in text and "without cancellation" in text


@pytest.mark.parametrize("driver", ["gl", "vulkan"])
def test_without_its_profile_a_legitimate_port_is_told_apart(drivers, driver):
    # The conventions matter: the [0, 1] visibility port without its profile fails ordinary rows.
    report = _run("engine01", "glsl", "engine_visibility01", "shadow_intensity-lower-float32", driver, profile=False)
    assert not report.passed and report.categories["random"].failures > 100


@pytest.mark.parametrize("driver", ["gl", "vulkan"])
@pytest.mark.parametrize("language", ["hlsl", "glsl", "wgsl"])
def test_a_singular_bias_target_fails_the_engine_rows_and_the_report_names_it(drivers, language, driver):
    moments = _run("singular_target", language, SINGULAR[language], "shadow_intensity-lower-float32", driver)
    # the moment rows cannot see the engine's bias, except where the slides' formula it copies cancels: rows
    # flagged printed_hazard, ill-conditioned ones judged by the profiled case's neighbourhood (a cluster within
    # 1e-4 of the far plane, zf = 1: it returns lit) ...
    failing = [g for g in moments.groups if g.level != "robustness"]  # robustness rows are not gated
    assert all(g.level == "contract" and "printed_hazard" in g.flags.split(",") for g in failing), failing
    # ... on which it returns the printed formulation's value (the diagnosis names that cause), no other row
    assert all(g.cause.startswith("your result matches the papers' printed formulation") for g in failing), failing
    assert 0 < moments.failures == sum(len(g.rows) for g in failing) <= 6
    report = _run("singular_target", language, SINGULAR[language], "engine-lower-float32", driver)
    assert not report.passed  # ... the engine rows can
    assert report.groups[0].level == "target" and report.groups[0].count == report.failures
    text = report.format()
    assert "the bias target is singular: the moments of 0.5·δ(0) + 0.5·δ(1)" in text
    # The failing rows: near/far mixtures, or one depth on a plane, each on the target's support.
    rows = [r for r in report.worst if not r["passed"]]
    assert rows and all("near_far" in r["flags"] or r["comment"].startswith(("one depth -1", "one depth 1"))
                        for r in rows), [(r["flags"], r["comment"]) for r in rows]


@pytest.mark.parametrize("driver", ["gl", "vulkan"])
@pytest.mark.parametrize("stem,language,function,case,category", [
    ("factor", "glsl", "factor_shadow_intensity", "shadow_intensity-lower-float32", "random"),
    ("early_exit", "glsl", "early_exit_shadow_intensity", "shadow_intensity-lower-float32", "random"),
    ("early_exit", "glsl", "early_exit_shadow_intensity", "engine-lower-float32", "random"),
    ("pivot_floor", "wgsl", "pivot_floor_shadow_intensity", "shadow_intensity-lower-float32", "stiff"),
    ("nan_guard", "glsl", "nan_guard_shadow_intensity", "shadow_intensity-lower-float32", "stiff"),
    ("nan_guard", "glsl", "nan_guard_shadow_intensity", "engine-lower-float32", "stiff"),
    ("unclamped", "glsl", "unclamped_shadow_intensity", "shadow_intensity-lower-float32", "stiff"),
])
def test_a_bug_found_in_the_wild_fails_on_contract_rows(drivers, stem, language, function, case, category, driver):
    report = _run(stem, language, function, case, driver)
    assert not report.passed and report.categories[category].failures > 0, report.format()
    assert all(g.level != "robustness" for g in report.groups if g.level in ("contract", "target")), report.groups
    v = report.verdict
    failing = ~v.row_pass
    assert not (failing & v.robust).any()  # every failure is a contract row
    if stem == "nan_guard":
        assert (failing & v.nonfinite).any()
    if stem == "unclamped":  # NaN or values out of [0, 1] where a clamp would have hidden them
        got = np.asarray(report.outputs["intensity"])[failing]
        assert (~np.isfinite(got) | (got < 0) | (got > 1)).all()
