"""One-change mutants of the shipped ports, in every language, on both drivers.

The fixtures are written by tests/fixtures/make_mutants.py from the shipped ports, so
each differs from the shipped function by exactly the change its header names. Every
mutant must fail with a report that names the failing rows, their inputs and reason.
Drivers absent: skipped, or failed under CI (the `drivers` fixture of conftest.py).
"""

from __future__ import annotations

import difflib
import io
import re
import sys
from pathlib import Path

import pytest

from moments_ref import conformance

FIXTURES = Path(__file__).resolve().parent / "fixtures"
sys.path.insert(0, str(FIXTURES))
import make_mutants  # noqa: E402

from test_conformance_languages import COMBOS  # noqa: E402

CASE = {"shade": "shade-float32", "unpack64": "unpack64-float32"}
CAUGHT = list(make_mutants.MUTANTS)
#: Hand-written GLSL fixtures (not generated): file stem -> (function, case).
GLSL_ONLY = {"pack64_xi_rounded": ("pack64_xi_rounded", "pack64-float32"),
             "shade_paper_literal": ("shade_paper_literal", "shade-float32")}


def _run(name, language, driver, golden_dir, **kw):
    function = make_mutants.MUTANTS[name][1]
    path = FIXTURES / language / f"{name}.{language}"
    return conformance.run_case(path, name, CASE[function], golden_dir, language, driver, **kw)


@pytest.mark.parametrize("language", make_mutants.EXT)
@pytest.mark.parametrize("name", list(make_mutants.MUTANTS))
def test_fixture_is_the_shipped_function_with_one_change(language, name):
    path = FIXTURES / language / f"{name}.{language}"
    assert path.read_text() == make_mutants.mutant_text(name, language), "run tests/fixtures/make_mutants.py"
    stem, function, _, changes = make_mutants.MUTANTS[name]
    shipped = make_mutants._function((conformance.PORTS_DIR / language / f"{stem}.{language}").read_text(),
                                     function, language)
    mutant = make_mutants._function(path.read_text(), name, language).replace(f"{name}(", f"{function}(", 1)
    changed = [x for x in difflib.ndiff(shipped.splitlines(), mutant.splitlines()) if x.startswith("+ ")]
    assert 1 <= len(changed) <= 2 and len(changed) == sum(old in shipped for old, _ in changes), changed


@pytest.mark.parametrize("language,driver", COMBOS)
@pytest.mark.parametrize("name", CAUGHT)
def test_mutant_fails_with_a_readable_report(drivers, golden_dir, name, language, driver):
    report = _run(name, language, driver, golden_dir)
    _assert_readable_failure(report, name)


@pytest.mark.parametrize("driver", ["gl", "vulkan"])
@pytest.mark.parametrize("name", list(GLSL_ONLY))
def test_glsl_fixture_mutant_fails_on_both_drivers(drivers, golden_dir, name, driver):
    if ("glsl", driver) not in COMBOS:
        pytest.skip(f"no {driver} driver")
    function, case = GLSL_ONLY[name]
    report = conformance.run_case(FIXTURES / "glsl" / f"{name}.glsl", function, case, golden_dir, "glsl", driver)
    _assert_readable_failure(report, function)


def _assert_readable_failure(report, function):
    text = report.format()
    assert not report.passed and report.failures > 0
    assert text.startswith(f"FAIL  {function}") and f"{report.failures} exceed the tolerance" in text
    first = next(r for r in report.worst if not r["passed"])
    what = r"got .*expected" if report.exact else r"(abs|ulps) \S+ \(tol \S+\).*got .*expected"
    row = re.search(rf"FAIL row {first['index']} \[{first['category']}\] {what}", text)
    assert row, text
    after = text[row.end():].splitlines()
    assert after[1].strip().startswith("inputs: ") and after[2].strip() == f"({first['comment']})"
    assert after[3].strip().startswith(f"tc_id {first['tc_id']}")


@pytest.mark.parametrize("language,driver", COMBOS)
def test_mutant_exits_1_through_the_cli(drivers, golden_dir, language, driver):
    out, err = io.StringIO(), io.StringIO()
    code = conformance.run_cli(FIXTURES / language / f"shade_xi_multiplied.{language}", "shade_xi_multiplied",
                               "shade-float32", golden_dir, out=out, err=err, language=language, adapter=driver)
    assert code == 1 and out.getvalue().startswith("FAIL") and err.getvalue() == ""


@pytest.mark.parametrize("language,driver", COMBOS)
def test_missing_clamp_fails_on_the_clamp_rows(drivers, golden_dir, language, driver):
    # Without the HPG17 §3.4 clamp of v2, the row v2 = 1, zf = y2 flips from 1e-6 to 1:
    # a gated row (flag clamp) whose per-row tolerance is far below that error.
    report = _run("shade_missing_clamp", language, driver, golden_dir)
    assert not report.passed, report.format()
    flip = [r for r in report.worst if not r["passed"] and "clamp" in r["flags"] and r["error"] > 0.99]
    assert flip and any("v2 = 1" in r["comment"] for r in flip), report.format()
    assert all(r["tolerance"] < 0.1 for r in flip)


@pytest.mark.parametrize("driver", ["gl", "vulkan"])
def test_the_slides_code_passes_and_fails_only_beyond_the_contract_with_strict(drivers, golden_dir, driver):
    # The slides' ComputeMSMShadowIntensity has no branch for a singular Hankel matrix: it divides by zero
    # on unbiased one- and two-point moments, which Algorithm 1 never receives (the paper biases first).
    if ("glsl", driver) not in COMBOS:
        pytest.skip(f"no {driver} driver")
    path = FIXTURES / "glsl" / "msm_slides_verbatim.glsl"
    case = "shadow_intensity-lower-float32"
    # On contract rows it fails exactly the sweep's one-depth texel after BIAS_FLOAT32, where its pivot rounds to 0
    # (NaN, saturated to 0, for 0.99985): flagged printed_hazard, and the verdict says so (issue 37).
    report = conformance.run_case(path, "ComputeMSMShadowIntensity", case, golden_dir, "glsl", driver, worst_rows=50)
    bad = [r for r in report.worst if not r["passed"]]
    assert not report.passed and report.failures == len(bad) == 1, report.format()
    assert "printed_hazard" in bad[0]["flags"] and "one depth -0.9908" in bad[0]["comment"], bad
    assert "your result matches the papers' printed formulation, which cancels on this row" in report.format()
    assert "beyond the algorithm's contract: 36 rows" in report.format()
    strict = conformance.run_case(path, "ComputeMSMShadowIntensity", case, golden_dir, "glsl", driver, strict=True)
    failing = ~strict.row_pass
    assert not strict.passed and int((failing & ~strict.verdict.robust).sum()) == 1
    assert all("robustness" in r["flags"] or "printed_hazard" in r["flags"] for r in strict.worst if not r["passed"])
