"""Slang, the fourth language: the shipped Slang ports and an independent one pass on both drivers,
their one-change mutants fail, messages name the porter's files, lines and names, and without
the optional extra ``--slang`` exits 2 with the install line.

Needs the extra (``pip install -e ".[slang]"``: slangpy's Slang compiler library) besides the
drivers and compilers of the other conformance tests; without it these tests skip, except the
one that checks the refusal.
"""

from __future__ import annotations

import io
import json
from pathlib import Path

import numpy as np
import pytest

from moments_ref import cli, conformance
from moments_ref.conformance import _slang, languages
from moments_ref.conformance.kernel import run_kernel
from moments_ref.golden.kernels import KERNEL_CASES
from moments_ref.ports import SLANG_DIR

from _harness import one_change
from _oracles import golden_folder

INDEPENDENT = Path(__file__).parent / "fixtures" / "slang" / "independent.slang"
CASES = [c for c in conformance.shipped_cases(("float32",)) if conformance.shipped_port(c, "slang") is not None]
needs_slang = pytest.mark.skipif(not _slang.available(), reason='the Slang extra is not installed '
                                                               '(pip install -e ".[slang]")')


@pytest.fixture(scope="module")
def kernel_goldens():
    return golden_folder(("kernel-filter-nlq64", "kernel-filter-nlq32"))


def test_without_the_extra_slang_exits_2_with_the_install_line(monkeypatch, capsys, tmp_path):
    monkeypatch.setattr(_slang, "library_path", lambda: None)
    conformance._run._SPIRV.clear()
    f = tmp_path / "p.slang"
    f.write_text("float f(float x) { return x; }\n")
    for argv in (["conformance", "--slang", str(f), "--function", "psi4", "--case", "psi4-float32"],
                 ["conformance", "--kernel", "--slang", "hpg17_filter_nlq64.slang", "--entry", "filter_nlq64",
                  "--case", "kernel-filter-nlq64"]):
        assert cli.main(argv) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and 'pip install -e ".[slang]"' in err[0], err


def test_the_table_names_every_language_once():
    # Suffixes belong to one language each; every language has a route to both drivers (Slang also to the CPU).
    seen = [s for lang in languages.TABLE.values() for s in lang.suffixes]
    assert len(seen) == len(set(seen))
    assert set(languages.LANGUAGES) == {"glsl", "hlsl", "wgsl", "slang"}
    assert all(set(lang.routes) - ({"cpu"} if name == "slang" else set()) == set(languages.DRIVERS)
               for name, lang in languages.TABLE.items())
    assert "cpu" in languages.TABLE["slang"].routes and "cpu" in languages.TABLE["slang"].precise
    assert languages.language_of("x.slang") == "slang" and conformance.LANGUAGES == ("glsl", "hlsl", "wgsl")
    assert languages.unmangle("slang", "uniform block block_Params_0, depth_0, f_12 x_1", {"Params", "depth", "f"}) \
        == "uniform block Params, depth, f x_1"


@needs_slang
@pytest.mark.parametrize("driver", ["gl", "vulkan"])
@pytest.mark.parametrize("case", CASES)
def test_shipped_slang_ports_pass(drivers, golden_dir, case, driver):
    path, function = conformance.shipped_port(case, "slang")
    report = conformance.run_case(path, function, case, golden_dir, "slang", driver)
    assert report.passed, report.format()
    assert report.driver == driver and "Slang" in report.renderer


@needs_slang
def test_slang_and_hlsl_ports_give_the_same_bits(drivers, golden_dir):
    # The Slang modules were written from the HLSL ports: the same operations in the same order.
    for case in ("shadow_intensity-lower-float32", "phi-float32", "shade-float32", "pack32-float32"):
        outs = {}
        for lang, drv in (("slang", "gl"), ("slang", "vulkan"), ("hlsl", "vulkan")):
            path, function = conformance.shipped_port(case, lang)
            outs[(lang, drv)] = conformance.run_case(path, function, case, golden_dir, lang, drv).outputs
        ref = outs[("hlsl", "vulkan")]
        for key, got in outs.items():
            for name in ref:
                assert np.array_equal(np.asarray(got[name]).view(np.uint32), np.asarray(ref[name]).view(np.uint32)), \
                    (case, key, name)


#: One-change mutants of the shipped Slang ports: (file, old, new, function, case).
MUTANTS = [
    ("msm.slang", "float w0 = 1.0 / (1.0 + y2 * y2 / sigma2 + y3 * y3 / xi4);",
     "float w0 = 1.0 / (1.0 + y2 * y2 / sigma2 + y3 * y3 * xi4);", "shadow_intensity_lower",
     "shadow_intensity-lower-float32"),
    ("msm.slang", "return msm_bounds(b, zf).upper;", "return msm_bounds(b, zf).lower;", "shadow_intensity_upper",
     "shadow_intensity-upper-float32"),
    ("nonlinear.slang", "float v2 = (b.x - y1) / (y2 - y1);", "float v2 = (b.x - y1) / (y2 + y1);", "phi",
     "phi-float32"),
    ("nonlinear.slang", "float v2 = clamp(r.z, 1.0e-6, 1.0 - 1.0e-6);", "float v2 = clamp(r.z, 1.0e-3, 1.0 - 1.0e-3);",
     "shade", "shade-float32"),
    ("packing.slang", "uint v = min(uint(floor(sv)), 127u);", "uint v = min(uint(round(sv)), 127u);", "pack32",
     "pack32-float32"),
    ("packing.slang", "precise float s2 = r.z * 65535.0;", "precise float s2 = r.z * 65534.0;", "pack64",
     "pack64-float32"),
]


@needs_slang
@pytest.mark.parametrize("fname,old,new,function,case", MUTANTS, ids=[f"{m[0]}:{m[3]}" for m in MUTANTS])
def test_one_change_mutants_fail(drivers, golden_dir, tmp_path, fname, old, new, function, case):
    path = one_change(tmp_path, SLANG_DIR, fname, old, new)
    report = conformance.run_case(path, function, case, golden_dir, "slang", "gl")
    assert not report.passed, report.format()


@needs_slang
@pytest.mark.parametrize("function,case", [("msm_lower", "shadow_intensity-lower-float32"),
                                           ("nlq_shade", "shade-float32")])
def test_an_independent_port_from_the_paper_passes(drivers, golden_dir, function, case):
    # Algorithm 1 solved literally (Gaussian elimination of B(b) from the raw moments, no branch for a pivot that
    # rounds to 0) reproduces the printed formulation: it fails exactly the sweep's one-depth texel after
    # BIAS_FLOAT32 (its last pivot xi4 is 0.7 float32 ulp of b4), flagged printed_hazard, and is told so (issue 37).
    for driver in ("gl", "vulkan"):
        report = conformance.run_case(INDEPENDENT, function, case, golden_dir, "slang", driver, worst_rows=50)
        if function == "nlq_shade":
            assert report.passed, report.format()
            continue
        bad = [r for r in report.worst if not r["passed"]]
        assert not report.passed and report.failures == len(bad) == 1, report.format()
        assert "printed_hazard" in bad[0]["flags"] and "one depth -0.9908" in bad[0]["comment"], bad
        assert "your result matches the papers' printed formulation, which cancels on this row" in report.format()


@needs_slang
def test_the_printed_algorithm_3_root_fails_where_it_is_nan(drivers, golden_dir, tmp_path):
    # The box's z_l = -q1/2 - sqrt(q1^2/4 - q0) is infinity minus infinity at zf = y2: a port that
    # takes it literally returns NaN on those contract rows, and the verdict says so.
    old = ("        float half = q1 / 2.0;\n        float s = half + (half < 0.0 ? -1.0 : 1.0) * sqrt(half * half - q0);\n"
           "        zl = min(-s, -q0 / s);")
    path = one_change(tmp_path, INDEPENDENT.parent, INDEPENDENT.name, old, "        zl = -q1 / 2.0 - sqrt(q1 * q1 / 4.0 - q0);")
    report = conformance.run_case(path, "nlq_shade", "shade-float32", golden_dir, "slang", "gl")
    assert not report.passed and "support_point" in report.format()


@needs_slang
def test_messages_name_the_porters_file_line_and_names(drivers, golden_dir, tmp_path):
    f = tmp_path / "port.slang"
    f.write_text("// a port\nfloat helper(float x) { return x * undefined_thing; }\n"
                 "float psi4_port(float xi4) { return helper(xi4); }\n")
    err = io.StringIO()
    assert conformance.run_cli(f, "psi4_port", "psi4-float32", golden_dir, out=io.StringIO(), err=err) == 2
    text = err.getvalue()
    assert f"{f}:2:" in text and "undefined_thing" in text and "_0" not in text, text
    f.write_text("float psi4_port(float xi4, float extra) { return xi4; }\n")
    err = io.StringIO()
    assert conformance.run_cli(f, "psi4_port", "psi4-float32", golden_dir, out=io.StringIO(), err=err) == 2
    assert "expected signature: float psi4_port(float xi4)" in err.getvalue(), err.getvalue()


@needs_slang
@pytest.mark.parametrize("fmt", ["nlq64", "nlq32"])
def test_shipped_slang_kernels_pass_on_both_drivers(drivers, kernel_goldens, fmt):
    case = f"kernel-filter-{fmt}"
    assert case in KERNEL_CASES
    report = run_kernel(SLANG_DIR / f"hpg17_filter_{fmt}.slang", f"filter_{fmt}", case, golden_dir=kernel_goldens,
                        timing=False)
    assert report.passed and [r.driver for r in report.runs] == ["gl", "vulkan"], report.format()
    # Slang's renaming is mapped back: the bindings are named as the file names them.
    text = report.format()
    assert "depth_0" not in text and "block_Params" not in text and "uniform block Params" in text, text


@needs_slang
def test_a_slang_kernel_mutant_fails(drivers, kernel_goldens, tmp_path):
    one_change(tmp_path, SLANG_DIR, "hpg17_filter.slang", "acc /= float(params.size.z);",
               "acc /= float(params.size.z + 1);")
    report = run_kernel(tmp_path / "hpg17_filter_nlq64.slang", "filter_nlq64", "kernel-filter-nlq64", golden_dir=kernel_goldens, timing=False)
    assert not report.passed


@needs_slang
def test_kernel_json_is_written(drivers, kernel_goldens, tmp_path, capsys):
    out = tmp_path / "k.json"
    code = cli.main(["conformance", "--kernel", "--slang", "hpg17_filter_nlq32.slang", "--entry", "filter_nlq32",
                     "--case", "kernel-filter-nlq32", "--golden", str(kernel_goldens), "--json", str(out)])
    assert code == 0 and out.is_file(), capsys.readouterr().err
    data = json.loads(out.read_text())
    assert data["command"] == "conformance --kernel" and data["passed"] is True
    assert [r["driver"] for r in data["cases"]] == ["gl", "vulkan"]
    assert all(r["passed"] and r["codes"]["differ"] == 0 for r in data["cases"])


# --- --adapter cpu: Slang's cpp target and the system C++ compiler (functions only) -------------

needs_cpu = pytest.mark.skipif(not _slang.available() or __import__("moments_ref.conformance._slangcpu",
                                                                      fromlist=["x"]).compiler() is None,
                               reason="needs the Slang extra and a C++ compiler")


@needs_cpu
def test_cpu_adapter_runs_slang_functions_and_fails_their_mutants(golden_dir, tmp_path):
    # A third driver: compiled by the system C++ compiler, not by Mesa. The shipped port passes; a
    # one-change mutant fails there too.
    for path, function, case in ((SLANG_DIR / "packing.slang", "pack32", "pack32-float32"),):
        report = conformance.run_case(path, function, case, golden_dir, "slang", "cpu")
        assert report.passed and report.driver == "cpu", report.format()
        assert "-ffp-contract=off" in report.format()
    fname, old, new, function, case = MUTANTS[-2]  # pack32 rounding to nearest instead of truncating
    report = conformance.run_case(one_change(tmp_path, SLANG_DIR, fname, old, new), function, case, golden_dir,
                                  "slang", "cpu")
    assert not report.passed, report.format()


@needs_slang
def test_cpu_adapter_refusals(capsys):
    # Other languages, and kernels (Slang's cpp target refuses the barrier), exit 2 with one line.
    glsl = str(Path(conformance.__file__).parents[1] / "ports" / "glsl" / "msm.glsl")
    for argv, word in ((["conformance", "--glsl", glsl, "--function", "shadow_intensity_lower", "--case",
                         "shadow_intensity-lower-float32", "--adapter", "cpu"], "cpu runs Slang files"),
                       (["conformance", "--kernel", "--slang", "hpg17_filter_nlq64.slang", "--entry", "filter_nlq64",
                         "--case", "kernel-filter-nlq64", "--adapter", "cpu"], "E36107")):
        assert cli.main(argv) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and word in err[0], err
