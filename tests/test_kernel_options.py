"""Kernel parity: every option of function conformance works with ``--kernel`` or exits 2, and a
failing 32-bit kernel is told which texel field is off, by how many cells, on which texels.

Needs the drivers and compilers of tests/test_kernel_conformance.py (skipped without them,
failed under CI).
"""

from __future__ import annotations

import contextlib
import io
import json

import pytest

from moments_ref import cli
from moments_ref.conformance.kernel.cli import shipped_kernel
from moments_ref.ports import PORTS_DIR

from _harness import need_tool, one_change
from _oracles import golden_folder

CASE = "kernel-filter-nlq32"


@pytest.fixture(scope="module")
def drivers(drivers):
    for tool in ("spirv-dis", "spirv-as"):
        need_tool(tool)


@pytest.fixture(scope="module")
def goldens():
    return str(golden_folder((CASE,)))


def _cli(args):
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = cli.main(["conformance", "--kernel", *args])
    return code, out.getvalue(), err.getvalue()


def _shipped(goldens, *extra):
    path, entry = shipped_kernel(CASE, "glsl")
    return ["--glsl", str(path), "--entry", entry, "--case", CASE, "--golden", goldens, *extra]


@pytest.mark.parametrize("extra,word", [
    (["--function", "pack32"], "--entry"),
    (["--profile", "MISSING.toml"], "cannot read"),
    (["--clamp", "1e-5"], "--clamp"),
    (["--adapter", "as-written"], "as-written"),
])
def test_options_a_kernel_cannot_take_exit_2_with_one_line(drivers, goldens, extra, word):
    code, out, err = _cli(_shipped(goldens, *extra))
    assert code == 2 and not out and len(err.strip().splitlines()) == 1 and word in err, err


def test_json_rows_and_both_drivers(drivers, goldens, tmp_path):
    out_json = tmp_path / "k.json"
    code, out, err = _cli(_shipped(goldens, "--json", str(out_json), "--rows", "1", "--adapter", "both", "--strict"))
    assert code == 0, err
    doc = json.loads(out_json.read_text())
    assert doc["command"] == "conformance --kernel" and doc["passed"] is True
    assert [r["driver"] for r in doc["cases"]] == ["gl", "vulkan"]
    # Every texel's verdict is there, as function conformance writes every row's.
    assert all(r["strict"] is True and r["rows"] and r["codes"]["fields"] == [] for r in doc["cases"])


def test_include_define_and_prelude_reach_the_kernel(drivers, goldens, tmp_path):
    # The shipped kernel with its packing include moved to a folder given by --include, and the
    # cell count of sqrt(v2) given by --define: unchanged behaviour, so the kernel passes.
    lib = tmp_path / "lib"
    lib.mkdir()
    for f in ("nonlinear.glsl", "msm.glsl", "hpg17_filter.glsl"):
        (lib / f).write_text((PORTS_DIR / "glsl" / f).read_text())
    text = (PORTS_DIR / "glsl" / "packing.glsl").read_text()
    assert text.count("sqrt(r.z) * 128.0") == 1
    (lib / "packing.glsl").write_text(text.replace("sqrt(r.z) * 128.0", "sqrt(r.z) * V2_CELLS"))
    src = tmp_path / "k" / "kernel.comp"
    src.parent.mkdir()
    src.write_text((PORTS_DIR / "glsl" / "hpg17_filter_nlq32.glsl").read_text())
    prelude = tmp_path / "prelude.glsl"
    prelude.write_text("// engine macros\n#define MR_TEST_PRELUDE 1\n")
    args = ["--glsl", str(src), "--entry", "main", "--case", CASE, "--golden", goldens, "--include", str(lib)]
    code, out, err = _cli(args + ["--define", "V2_CELLS=128.0", "--prelude", str(prelude)])
    assert code == 0, err + out
    code, out, err = _cli(args)  # without the define it does not compile: exit 2, naming file and line
    assert code == 2 and "packing.glsl" in err and "V2_CELLS" in err, err


def test_a_failing_32_bit_kernel_names_the_field_and_the_cells(drivers, goldens, tmp_path):
    # Another published cell encoding of sqrt(v2): round(127 sqrt(v2)) instead of min(floor(128 sqrt(v2)), 127).
    one_change(tmp_path, PORTS_DIR / "glsl", "packing.glsl",
               "precise float sv = sqrt(r.z) * 128.0;\n    uint v = min(uint(floor(sv)), 127u);",
               "precise float sv = sqrt(r.z) * 127.0;\n    uint v = uint(round(sv));")
    out_json = tmp_path / "k.json"
    code, out, err = _cli(["--glsl", str(tmp_path / "hpg17_filter_nlq32.glsl"), "--entry", "main", "--case", CASE,
                           "--golden", goldens, "--adapter", "gl", "--json", str(out_json), "--rows", "2"])
    assert code == 1, err
    assert 0 < out.count("        FAIL row ") <= 6  # --rows 2: at most two failing texels per category
    fields = json.loads(out_json.read_text())["cases"][0]["codes"]["fields"]
    top = max(fields, key=lambda f: f["texels"])
    # The field of sqrt(v2) (bits 19-25) carries the failures, a cell below the reference's on most texels.
    assert top["field"].startswith("sqrt(v2)") and top["offset"] == -1 and top["share"] > top["texels"] // 2
    assert "field sqrt(v2) cell (bits 19-25): differs from the global path's code on" in out
    assert all(f["field"] != "folded y1 (bits 10-18)" for f in fields)


FIXTURES = __import__("pathlib").Path(__file__).parent / "fixtures" / "kernels"


def test_a_profile_with_function_keys_is_refused_for_kernels(drivers, goldens, tmp_path):
    p = tmp_path / "engine.toml"
    p.write_text('depth = "01"\n[kernel]\nlayout = "planar"\n')
    code, out, err = _cli(_shipped(goldens, "--profile", str(p)))
    assert code == 2 and "'depth' is a function convention" in err, err
    p.write_text('[kernel]\nlayout = "sideways"\n')
    code, out, err = _cli(_shipped(goldens, "--profile", str(p)))
    assert code == 2 and "kernel.layout = 'sideways'" in err, err


@pytest.fixture(scope="module")
def nlq64():
    return str(golden_folder(("kernel-filter-nlq64",)))


def _layout(nlq64, fixture, *extra):
    return _cli(["--glsl", str(FIXTURES / fixture), "--entry", "main", "--case", "kernel-filter-nlq64",
                 "--golden", nlq64, "--include", str(PORTS_DIR / "glsl"), *extra])


def test_declared_output_layouts(drivers, nlq64, tmp_path):
    # A buffer of 16-bit fields packed in pairs, and one plane per component: each passes as declared.
    code, out, err = _layout(nlq64, "nlq64_packed16.glsl", "--kernel-layout", "packed16")
    assert code == 0, err + out
    p = tmp_path / "planar.toml"
    p.write_text('[kernel]\nlayout = "planar"\n')
    code, out, err = _layout(nlq64, "nlq64_planar.glsl", "--profile", str(p))
    assert code == 0, err + out
    # Undeclared, the packed buffer's 8-byte elements do not fit the contract: exit 2 naming the binding.
    code, out, err = _layout(nlq64, "nlq64_packed16.glsl")
    assert code == 2 and "'Texels'" in err and "8 bytes" in err, err
    # Declared wrongly, the planes are read as packed pairs: the texels fail.
    code, out, err = _layout(nlq64, "nlq64_planar.glsl", "--kernel-layout", "packed16")
    assert code == 1 and out.startswith("FAIL"), err + out
    code, out, err = _cli(["--glsl", "x.glsl", "--function", "f", "--case", "psi4-float32"][:0] + _shipped(
        str(golden_folder((CASE,))), "--kernel-layout", "packed16"))
    assert code == 2 and "packed16" in err, err


# --- the 32-bit √v2 grid a profile declares ([format] v2_cell) ---------------------------------

def _cell_kernel(goldens, fixture, *extra):
    return _cli(["--glsl", str(FIXTURES / fixture), "--entry", "main", "--case", CASE, "--golden", goldens,
                 "--include", str(PORTS_DIR / "glsl"), "--adapter", "gl", *extra])


def test_declared_v2_grid_passes_its_kernel_and_fails_the_mutant(drivers, goldens, tmp_path):
    p = tmp_path / "round127.toml"
    p.write_text('[format]\nv2_cell = "round127"\n')
    out_json = tmp_path / "k.json"
    code, out, err = _cell_kernel(goldens, "nlq32_round127.glsl", "--profile", str(p), "--json", str(out_json))
    assert code == 0, err + out
    assert "v2_cell = 'round127'" in out and "codes: " in out and " 0 differ" in out
    assert json.loads(out_json.read_text())["v2_cell"] == "round127"
    # The flag declares it too.
    code, out, err = _cell_kernel(goldens, "nlq32_round127.glsl", "--format-v2-cell", "round127")
    assert code == 0, err + out
    # Undeclared: the sqrt(v2) field fails, and its hint names the key (that grid explains every failing texel).
    code, out, err = _cell_kernel(goldens, "nlq32_round127.glsl")
    assert code == 1, err + out
    assert 'field sqrt(v2) cell (bits 19-25)' in out and 'declare [format] v2_cell = "round127"' in out
    # The one-change mutant (floor instead of round) fails with the declaration, and without it
    # gets no suggestion: the other grid does not explain its texels.
    code, out, err = _cell_kernel(goldens, "nlq32_round127_floor.glsl", "--profile", str(p))
    assert code == 1 and out.startswith("FAIL"), err + out
    code, out, err = _cell_kernel(goldens, "nlq32_round127_floor.glsl")
    assert code == 1 and "field sqrt(v2)" in out and "v2_cell" not in out, out


def test_declared_v2_grid_refusals(drivers, goldens, nlq64, tmp_path):
    p = tmp_path / "decode.toml"
    p.write_text('[format]\nv2_decode = "lower"\n')
    code, out, err = _cli(_shipped(goldens, "--profile", str(p)))
    assert code == 2 and "format.v2_decode" in err and len(err.strip().splitlines()) == 1, err
    p.write_text('[format]\nv2_cell = "round128"\n')
    code, out, err = _cli(_shipped(goldens, "--profile", str(p)))
    assert code == 2 and "format.v2_cell = 'round128'" in err, err
    code, out, err = _cli(_shipped(goldens, "--format-v2-cell", "nearest"))
    assert code == 2 and "--format-v2-cell" in err, err
    code, out, err = _layout(nlq64, "nlq64_planar.glsl", "--kernel-layout", "planar", "--format-v2-cell", "round127")
    assert code == 2 and "kernel-filter-nlq64" in err and "v2_cell" in err, err
