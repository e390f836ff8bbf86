"""Hausdorff ports (tests/fixtures/hausdorff) on both drivers: judged as Hausdorff ports when they declare it.

A correct, independent GLSL and WGSL port passes ``hausdorff-*`` with ``bound = "hausdorff"``; its
mutant that divides by zf at a receiver at depth 0 fails there, and the report names the rows; without
the declaration the correct port fails Algorithm 1's case and the diagnosis advises the key, because the
Hausdorff bound explains its failing rows within their own tolerance. Drivers absent: skipped, or failed
under CI.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import pytest

from moments_ref import conformance
from moments_ref.golden.profile import load_profile

from _oracles import golden_folder

HERE = Path(__file__).resolve().parent / "fixtures" / "hausdorff"
PROFILE = load_profile(HERE / "hausdorff.toml")
FUNCTIONS = {"glsl": ("hausdorffLower", "hausdorffUpper"), "wgsl": ("hausdorff_lower", "hausdorff_upper")}
CASES = ("shadow_intensity-lower-float32", "hausdorff-lower-float32", "hausdorff-upper-float32")


def _run(stem, language, function, case, driver, profile=PROFILE):
    goldens = golden_folder(CASES)
    return conformance.run_case(HERE / f"{stem}.{language}", function, case, goldens, language, driver,
                                profile=profile)


@pytest.mark.parametrize("driver", ["gl", "vulkan"])
@pytest.mark.parametrize("language", ["glsl", "wgsl"])
@pytest.mark.parametrize("bound", [0, 1])
def test_a_correct_hausdorff_port_passes_as_one(drivers, language, driver, bound):
    case = ("shadow_intensity-lower-float32", "shadow_intensity-upper-float32")[bound]
    report = _run("hausdorff", language, FUNCTIONS[language][bound], case, driver)
    assert report.case.startswith("hausdorff-"), report.case  # bound = "hausdorff" picked the case
    assert report.passed, report.format()


@pytest.mark.parametrize("driver", ["gl", "vulkan"])
@pytest.mark.parametrize("language", ["glsl", "wgsl"])
def test_the_depth_0_division_fails_at_the_receivers_at_depth_0(drivers, language, driver):
    report = _run("hausdorff_depth0_division", language, FUNCTIONS[language][0], "hausdorff-lower-float32", driver)
    assert not report.passed
    text = report.format()
    assert "receiver_at_depth_0 (contract)" in text and "divide by zf" in text, text
    zero = [g for g in report.groups if "receiver_at_depth_0" in g.flags]
    assert zero and sum(len(g.rows) for g in zero) >= 2


@pytest.mark.parametrize("driver", ["gl", "vulkan"])
def test_without_the_declaration_the_advice_is_bound_hausdorff(drivers, driver):
    """Judged as Algorithm 1 (depth [0,1] only), the correct port fails, and the advice is checked."""
    report = _run("hausdorff", "glsl", "hausdorffLower", "shadow_intensity-lower-float32", driver,
                  profile=replace(PROFILE, bound=None))
    assert report.case == "shadow_intensity-lower-float32" and not report.passed
    advice = [g for g in report.groups if g.flags == 'bound = "hausdorff"']
    assert advice and len(advice[0].rows) >= report.verdict.failures // 2, report.format()


def test_the_advice_is_not_given_to_a_port_it_does_not_explain(drivers):
    """A port whose outputs the Hausdorff bound does not explain (its upper bound, run on the lower case)
    is not told to declare it: the advice is checked against the rows' own tolerance."""
    report = _run("hausdorff", "glsl", "hausdorffUpper", "shadow_intensity-lower-float32", "gl",
                  profile=replace(PROFILE, bound=None))
    assert not report.passed
    assert not [g for g in report.groups if g.flags == 'bound = "hausdorff"'], report.format()


def test_both_drivers_judge_the_declared_case(drivers):
    """``--adapter both`` runs the case the declaration picks on each driver (not Algorithm 1's rows)."""
    import io

    out, err = io.StringIO(), io.StringIO()
    rc = conformance.run_cli(HERE / "hausdorff_depth0_division.glsl", "hausdorffLower", "shadow_intensity-lower-float32",
                             golden_folder(CASES), out=out, err=err, adapter="both", profile=PROFILE)
    text = out.getvalue()
    assert rc == 1, err.getvalue()
    assert text.count("on hausdorff-lower-float32: 252 rows, 4 exceed the tolerance") == 2, text  # gl and vulkan
