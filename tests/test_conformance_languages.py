"""HLSL and WGSL beside GLSL, on both drivers: Vulkan (wgpu, lavapipe) and OpenGL (llvmpipe).

Needs wgpu with a Vulkan driver, moderngl with EGL, glslangValidator and spirv-cross.
Without them the tests are skipped with the reason, except under CI (``CI=true``),
where a missing driver or compiler is a failure (.ci/run installs them).
"""

from __future__ import annotations

import hashlib
import io
import re
import time

import numpy as np
import pytest

from moments_ref import InputError, cli, conformance
from moments_ref.conformance import ContextError, _run, _wgpu, _wrap
from moments_ref.conformance._source import load_source

from _harness import assert_ties_are_the_float32_reference

COMBOS = [(lang, drv) for lang in conformance.LANGUAGES for drv in conformance.DRIVERS]
CASES = conformance.shipped_cases()


# --------------------------------------------------------------------------
# Every shipped port of every language passes every case of its function on both drivers
# --------------------------------------------------------------------------


@pytest.mark.parametrize("language", conformance.LANGUAGES)
def test_every_language_ships_every_function(language):
    for case in CASES:
        path, function = conformance.shipped_port(case, language)
        src = load_source(path, language)
        assert function in conformance.defined_functions(src.body), (language, case, function)


@pytest.mark.parametrize("language", ["hlsl", "wgsl"])
def test_ports_name_each_step_in_comments(language):
    # Each function of a shipped port is preceded by a comment naming what it computes,
    # and the algorithms' numbered steps appear as in the GLSL ports.
    for path in sorted((conformance.PORTS_DIR / language).glob(f"*.{language}")):
        text = path.read_text()
        for m in re.finditer(r"^(?:fn |[\w<>]+ )(\w+)\(", text, flags=re.M):
            before = [x for x in text[: m.start()].rstrip("\n").splitlines()
                      if not x.startswith(("const ", "static const "))]  # constants sit under the comment
            assert before and before[-1].lstrip().startswith("//"), (path.name, m.group(1))
        glsl = (conformance.GLSL_DIR / f"{path.stem}.glsl").read_text()
        steps = set(re.findall(r"// \((\d)\)", glsl))
        assert steps <= set(re.findall(r"// \((\d)\)", text)), path.name


@pytest.mark.parametrize("language,driver", COMBOS)
@pytest.mark.parametrize("case", CASES)
def test_shipped_port_passes_on_both_drivers(drivers, golden_dir, language, driver, case):
    if conformance.not_available(case, language, driver):
        # Declared not available (conformance.NOT_AVAILABLE): refused with one line, before any verdict.
        path, function = conformance.shipped_port(case, language)
        with pytest.raises((InputError, ContextError)):
            conformance.run_case(path, function, case, golden_dir, language, driver)
        return
    report = _shipped_run(golden_dir, language, driver, case)
    assert report.passed, report.format()
    assert report.driver == driver and ("llvmpipe" in report.renderer or "lavapipe" in report.renderer)
    if report.exact:  # packing: bit-exact with the reference in float32 on every golden row
        assert_ties_are_the_float32_reference(report, golden_dir, case)


_RUNS = {}


def _shipped_run(golden_dir, language, driver, case):
    """The report of a shipped port on one driver (once per test process)."""
    if (language, driver, case) not in _RUNS:
        path, function = conformance.shipped_port(case, language)
        _RUNS[(language, driver, case)] = conformance.run_case(path, function, case, golden_dir, language, driver,
                                                               worst_rows=1000)  # every tie listed
    return _RUNS[(language, driver, case)]


@pytest.mark.parametrize("language", conformance.LANGUAGES)
def test_shipped_ports_give_identical_bits_on_both_drivers(drivers, golden_dir, language):
    # One source, one answer: every output word of every golden row is the same on
    # OpenGL and on Vulkan. (Before: GLSL and WGSL phi_inverse differed on 86 rows,
    # Mesa's GLSL compiler rebalancing y*y*y*y; HLSL psi4_inverse/unpack64 on 23,
    # Mesa's GLSL compiler factoring SPIRV-Cross's fma(-n, lo, fma(-n, hi, x)).)
    differ = {}
    for case in CASES:
        if any(conformance.not_available(case, language, d) for d in conformance.DRIVERS):
            continue  # runs on one driver only (declared; refused on the other)
        gl = _shipped_run(golden_dir, language, "gl", case).outputs
        vk = _shipped_run(golden_dir, language, "vulkan", case).outputs
        for name in gl:
            a, b = np.asarray(gl[name]), np.asarray(vk[name])
            n = len(a)
            rows = (a.reshape(n, -1).view(np.uint32) != b.reshape(n, -1).view(np.uint32)).any(axis=1)
            if rows.any():
                differ[f"{case}.{name}"] = np.flatnonzero(rows).tolist()[:10]
    assert not differ, differ


# --------------------------------------------------------------------------
# The user's file, unchanged: own entry point, own resources, includes
# --------------------------------------------------------------------------

_OWN = {
    "glsl": ('#include "helper.glsl"\nlayout(local_size_x = 32) in;\n'
             "layout(std430, binding = 0) buffer Data { float data[]; };\n"
             "void main() { data[gl_GlobalInvocationID.x] = twice(data[gl_GlobalInvocationID.x]); }\n",
             "float twice(float x)\n{\n    return 2.0 * x + 1.0;\n}\n"),
    "hlsl": ('#include "helper.hlsl"\nRWStructuredBuffer<float> data : register(u0);\n'
             "[numthreads(32, 1, 1)]\nvoid main(uint3 id : SV_DispatchThreadID) { data[id.x] = twice(data[id.x]); }\n",
             "float twice(float x)\n{\n    return 2.0 * x + 1.0;\n}\n"),
    "wgsl": ('#include "helper.wgsl"\n@group(0) @binding(0) var<storage, read_write> data: array<f32>;\n'
             "@compute @workgroup_size(32)\nfn main(@builtin(global_invocation_id) id: vec3<u32>) "
             "{ data[id.x] = twice(data[id.x]); }\n",
             "fn twice(x: f32) -> f32 {\n    return 2.0 * x + 1.0;\n}\n"),
}


@pytest.mark.parametrize("language,driver", COMBOS)
def test_file_with_its_own_entry_point_and_include_runs_unchanged(drivers, tmp_path, language, driver):
    main_text, helper_text = _OWN[language]
    (tmp_path / f"port.{language}").write_text(main_text)
    (tmp_path / f"helper.{language}").write_text(helper_text)
    before = {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in tmp_path.iterdir()}
    x = np.linspace(-3, 3, 300, dtype=np.float32)
    got, _ = conformance.run_function(tmp_path / f"port.{language}", "twice", {"x": x},
                                      {"y": (np.float32, (300,))}, language, driver)
    assert np.array_equal(got["y"], 2 * x + 1)
    assert before == {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in tmp_path.iterdir()}


@pytest.mark.parametrize("language", ["glsl", "wgsl"])
def test_wrapper_is_the_file_plus_only_harness_lines(tmp_path, language):
    # The wrapper = the user's resolved text verbatim, then lines that mention only
    # harness names (mr_*), the entry point and buffer declarations.
    path = tmp_path / f"port.{language}"
    path.write_text(_OWN[language][0].replace(f'#include "helper.{language}"\n', _OWN[language][1]))
    src = load_source(path, language)
    ins = [conformance.Slot.of("x", np.float32, (5,))]
    outs = [conformance.Slot.of("y", np.float32, (5,))]
    if language == "glsl":
        text, local = _wrap.wrap_glsl(src, "twice", ins, outs)
        assert local == 32  # the file's own work-group size is kept (one layout per shader)
        user = text[text.index(src.body): text.index(src.body) + len(src.body)]
        rest = text.replace(src.body, "")
    else:
        text = _wrap.wrap_wgsl(src, "twice", ins, outs, group=_wrap.free_group(src.body, r"@group\((\d+)\)"))
        assert text.startswith(src.body)
        user, rest = src.body, text[len(src.body):]
    assert path.read_text().strip() in user.replace("#line 1 1\n", "")
    for line in rest.splitlines():
        s = line.strip()
        harness = ("#version", "#line", "#define main", "#undef", "void main()", "@compute", "layout(local_size")
        assert not s or s in ("{", "}") or "mr_" in s or s.startswith(harness), line


def test_hlsl_wrapper_is_the_file_plus_only_its_entry_point(tmp_path):
    # HLSL includes are resolved by the harness too (no compiler opens a user file):
    # the wrapper is the resolved text, then the harness's lines.
    path = tmp_path / "port.hlsl"
    path.write_text("float shade(float4 b, float zf) { return b.x + zf; }\n")
    src = load_source(path, "hlsl")
    ins = [conformance.Slot.of("b", np.float32, (5, 4)), conformance.Slot.of("zf", np.float32, (5,))]
    outs = [conformance.Slot.of("intensity", np.float32, (5,))]
    text = _wrap.wrap_hlsl(src, "shade", ins, outs, space=3)
    assert text.startswith(src.body) and path.read_text() in src.body
    rest = text[len(src.body):].strip().splitlines()
    assert rest[0] == "#line 1 0"
    assert all("mr_" in x or x in ("{", "}") or x.startswith("[numthreads") for x in rest[1:] if x.strip())


# --------------------------------------------------------------------------
# Compile errors: one line per error, the user's file and line
# --------------------------------------------------------------------------

_BAD = {"glsl": "float f(float x)\n{\n    return x +;\n}\n",
        "hlsl": "float f(float x)\n{\n    return x +;\n}\n",
        "wgsl": "fn f(x: f32) -> f32 {\n    let a = 1.0;\n    return x +;\n}\n"}


def _psi4_of(tmp_path, text, language, driver):
    """``(exit code, stderr lines)`` of ``f`` in ``text`` run on psi4-float32 (signature ``float f(float xi4)``)."""
    path = tmp_path / f"p.{language}"
    path.write_text(text)
    err = io.StringIO()
    code = conformance.run_cli(path, "f", "psi4-float32", None, out=io.StringIO(), err=err, language=language,
                               adapter=driver)
    assert "Traceback" not in err.getvalue()
    return code, err.getvalue().strip().splitlines()


@pytest.mark.parametrize("language,driver", COMBOS)
def test_compile_error_names_the_users_file_and_line(drivers, tmp_path, language, driver):
    code, lines = _psi4_of(tmp_path, _BAD[language], language, driver)
    assert code == 2, lines
    assert lines[0].startswith("moments-ref conformance: the wrapped function does not compile")
    # the error is inside the user's function and its signature is right: no signature hint
    assert "expected signature" not in lines[0], lines[0]
    assert len(lines) == 2 and re.match(rf"{re.escape(str(tmp_path / f'p.{language}'))}:3\b", lines[1]), lines


_TWO_ARGUMENTS = {"glsl": "float f(float x, float y)\n{\n    return x;\n}\n",
                  "hlsl": "float f(float x, float y)\n{\n    return x;\n}\n",
                  "wgsl": "fn f(x: f32, y: f32) -> f32 {\n    return x;\n}\n"}
_PSI4_SIGNATURE = {"glsl": "float f(float xi4)", "hlsl": "float f(float xi4)", "wgsl": "fn f(xi4: f32) -> f32"}


@pytest.mark.parametrize("language,driver", COMBOS)
def test_a_signature_that_does_not_match_names_the_expected_one(drivers, tmp_path, language, driver):
    # The function compiles on its own; the wrapper's call does not: the head names the signature it calls.
    code, lines = _psi4_of(tmp_path, _TWO_ARGUMENTS[language], language, driver)
    assert code == 2 and "does not compile" in lines[0], lines
    assert f"expected signature: {_PSI4_SIGNATURE[language]}" in lines[0], lines


@pytest.mark.parametrize("language", conformance.LANGUAGES)
def test_missing_function_and_wrong_signature_exit_2(drivers, golden_dir, language):
    err = io.StringIO()
    name = f"msm.{language}"
    assert conformance.run_cli(name, "no_such_function", "shadow_intensity-lower-float32", golden_dir,
                               out=io.StringIO(), err=err, language=language) == 2
    assert "shadow_intensity_lower" in err.getvalue() and "no_such_function(" in err.getvalue()
    err = io.StringIO()
    assert conformance.run_cli(name, "from_optimized", "shadow_intensity-lower-float32", golden_dir,
                               out=io.StringIO(), err=err, language=language) == 2
    sig = {"glsl": "float from_optimized(vec4 b, float zf)", "hlsl": "float from_optimized(float4 b, float zf)",
           "wgsl": "fn from_optimized(b: vec4<f32>, zf: f32) -> f32"}[language]
    assert sig in err.getvalue()


# --------------------------------------------------------------------------
# Command line: languages, adapters, exit codes
# --------------------------------------------------------------------------


@pytest.mark.parametrize("flag,name", [("--hlsl", "nonlinear.hlsl"), ("--wgsl", "nonlinear.wgsl"),
                                       ("--glsl", "nonlinear.glsl")])
def test_cli_runs_each_language(drivers, golden_dir, capsys, flag, name):
    assert cli.main(["conformance", flag, name, "--function", "shade", "--case", "shade-float32",
                     "--golden", str(golden_dir)]) == 0
    out = capsys.readouterr().out
    assert out.startswith("PASS  shade") and "renderer:" in out and "driver:" in out


def test_cli_adapter_picks_the_driver_and_names_it(drivers, golden_dir, capsys):
    for adapter, word in (("vulkan", "Vulkan"), ("gl", "OpenGL"), ("vulkan:llvmpipe", "Vulkan")):
        assert cli.main(["conformance", "--hlsl", "msm.hlsl", "--function", "shadow_intensity_upper",
                         "--case", "shadow_intensity-upper-float32", "--golden", str(golden_dir),
                         "--adapter", adapter]) == 0
        assert word in capsys.readouterr().out
    assert cli.main(["conformance", "--wgsl", "msm.wgsl", "--function", "shadow_intensity_upper",
                     "--case", "shadow_intensity-upper-float32", "--adapter", "vulkan:NoSuchGPU"]) == 2
    err = capsys.readouterr().err
    assert "NoSuchGPU" in err and "wgpu found" in err and len(err.strip().splitlines()) == 1


def test_cli_usage_errors_exit_2(capsys):
    assert cli.main(["conformance", "--function", "shade", "--case", "shade-float32"]) == 2
    assert "--glsl, --hlsl, --wgsl or --slang" in capsys.readouterr().err
    assert cli.main(["conformance", "--wgsl", "nonlinear.wgsl", "--case", "shade-float32"]) == 2
    assert "--function" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exc:
        cli.main(["conformance", "--glsl", "a.glsl", "--hlsl", "b.hlsl"])
    assert exc.value.code == 2


def test_no_driver_or_no_compiler_exits_2(monkeypatch, golden_dir):
    def no_vulkan(*a, **k):
        raise ContextError("no Vulkan adapter (test)")

    monkeypatch.setattr(_wgpu, "get_device", no_vulkan)
    err = io.StringIO()
    assert conformance.run_cli("msm.wgsl", "shadow_intensity_lower", "shadow_intensity-lower-float32", golden_dir,
                               out=io.StringIO(), err=err, language="wgsl") == 2
    assert "no Vulkan adapter (test)" in err.getvalue()
    monkeypatch.setattr(conformance._toolchain.shutil, "which", lambda name: None)
    conformance._run._SPIRV.clear()
    err = io.StringIO()
    assert conformance.run_cli("msm.hlsl", "shadow_intensity_lower", "shadow_intensity-lower-float32", golden_dir,
                               out=io.StringIO(), err=err, language="hlsl", adapter="gl") == 2
    assert "apt-get install glslang-tools" in err.getvalue()


def test_parse_adapter_and_language_of():
    assert _run.parse_adapter(None, "hlsl") == _run.Target(conformance.DEFAULT_DRIVER["hlsl"])
    assert _run.parse_adapter("vulkan:NVIDIA", "glsl") == _run.Target("vulkan", "NVIDIA")
    assert _run.parse_adapter("Radeon", "glsl") == _run.Target("vulkan", "Radeon")
    assert _run.language_of("x.hlsl") == "hlsl" and _run.language_of("x.txt", "wgsl") == "wgsl"
    with pytest.raises(InputError, match="--glsl, --hlsl, --wgsl or --slang"):
        _run.language_of("x.txt")


# --------------------------------------------------------------------------
# Six moments and speed
# --------------------------------------------------------------------------


def test_six_moment_array_argument_reaches_the_function(drivers, tmp_path):
    # b[6] is uploaded flat and rebuilt per row in each language: the sum of the six
    # values weighted by their index checks order and stride.
    texts = {"glsl": "float f(float b[6], float zf) { float s = zf; for (int i = 0; i < 6; ++i) "
                     "s += float(i + 1) * b[i]; return s; }\n",
             "hlsl": "float f(float b[6], float zf) { float s = zf; for (int i = 0; i < 6; ++i) "
                     "s += (float)(i + 1) * b[i]; return s; }\n",
             "wgsl": "fn f(b: array<f32, 6>, zf: f32) -> f32 { var s = zf; for (var i = 0; i < 6; i++) "
                     "{ s += f32(i + 1) * b[i]; } return s; }\n"}
    b = np.arange(6 * 70, dtype=np.float32).reshape(70, 6)
    zf = np.arange(70, dtype=np.float32) * 0.5
    for language, driver in COMBOS:
        path = tmp_path / f"f.{language}"
        path.write_text(texts[language])
        got, _ = conformance.run_function(path, "f", {"b": b, "zf": zf}, {"y": (np.float32, (70,))}, language, driver)
        assert np.array_equal(got["y"], zf + b @ np.arange(1, 7, dtype=np.float32)), (language, driver)


def test_one_case_under_two_seconds_after_the_first_on_lavapipe(drivers, golden_dir):
    path, function = conformance.shipped_port("shade-float32", "hlsl")
    conformance.run_case(path, function, "shade-float32", golden_dir, "hlsl", "vulkan")
    for case in ("shade-float64", "psi4-float32"):  # a new compile, then the same
        path, function = conformance.shipped_port(case, "wgsl")
        t0 = time.perf_counter()
        report = conformance.run_case(path, function, case, golden_dir, "wgsl", "vulkan")
        assert report.passed and time.perf_counter() - t0 < 2.0


@pytest.mark.parametrize("language", ["hlsl", "wgsl"])
def test_error_in_an_included_file_names_that_file(drivers, tmp_path, language):
    helper = {"hlsl": "float helper(float x)\n{\n    return x + undefined_thing;\n}\n",
              "wgsl": "fn helper(x: f32) -> f32 {\n    let a = 1.0;\n    return x + undefined_thing;\n}\n"}[language]
    main = {"hlsl": '// main\n#include "h.hlsl"\nfloat f(float x) { return helper(x); }\n',
            "wgsl": '// main\n#include "h.wgsl"\nfn f(x: f32) -> f32 { return helper(x); }\n'}[language]
    (tmp_path / f"h.{language}").write_text(helper)
    (tmp_path / f"m.{language}").write_text(main)
    with pytest.raises(conformance.ShaderError) as exc:
        conformance.run_case(tmp_path / f"m.{language}", "f", "psi4-float32", language=language)
    lines = str(exc.value).splitlines()[1:]
    assert lines and all(x.startswith(f"{tmp_path / f'h.{language}'}:3") for x in lines), lines


# --------------------------------------------------------------------------
# Measured floating-point behaviour (docs/ports.md states it)
# --------------------------------------------------------------------------


@pytest.mark.parametrize("language,driver", COMBOS)
def test_llvmpipe_never_fuses_and_clamps_nan_to_zero(drivers, language, driver):
    from moments_ref.conformance import _probes

    found = _probes.measure(language, driver)
    assert found["p_fma"] == "unfused" and found["p_contract"] == "unfused"
    assert found["p_clamp"] == "0"
    assert found["p_div"].startswith("0 of") and found["p_sqrt"].startswith("0 of")
    # Mesa keeps denormals (the Vulkan and GLSL specs allow a flush; docs/conformance.md records a GPU's).
    assert found["denormal"] == {"stored": "unchanged", "x·1": "kept", "product": "kept", "x > 0": "true"}
    for fn in ("p_exp", "p_log"):  # llvmpipe's exp and log are polynomials: not correctly rounded, a few ulps off
        k, n, ulp = map(int, re.match(r"(\d+) of (\d+) \(max (\d+) ulp", found[fn]).groups())
        assert n == 20000 and 0 < k < n and 0 < ulp < 10 ** 4
    assert 0 < float(found["p_log_abs"]) < 1e-6


@pytest.mark.parametrize("language,driver", COMBOS)
def test_xi4_codes_differ_only_next_to_a_code_boundary(drivers, language, driver):
    """docs/conformance.md's ξ4 table: only the log-fed code differs, by one, within float32 reach of an integer."""
    import math

    from moments_ref.conformance import _probes

    n = 4000
    found = _probes.xi4_codes(language, driver, n)
    r = _probes._random_representations(n, 7)
    x = np.clip(r[:, 3].astype(np.float64), 1.2e-7, 0.25)  # Psi4 in float64, apart from precise.psi4
    c0 = math.log(math.log(1.2))
    s = 65535 * (np.log(np.log(x * 1e7)) - c0) / (math.log(math.log(0.25e7)) - c0)
    near = int(np.count_nonzero(np.abs(s - np.round(s)) < 0.01))  # rows a float32 log may round either way
    other, k, big, far = found["pack64"]
    assert other == 0 and big <= 1 and k <= near
    assert k == 0 or far < 0.01
    assert found["pack32"][0] == 0 and found["pack32"][2] <= 1


def test_glslang_contracts_hlsl_unless_precise(drivers):
    from moments_ref.conformance import _probes

    assert _probes.hlsl_contraction() == {"p_contract": (1, 0), "p_precise": (0, 2)}


# What each path's compiler changes (docs/ports.md, "What the drivers' compilers change"):
# measured on Mesa 22.3; the as-written path is the one that changes nothing the source did not ask for.
_RULES_MEASURED = {
    ("glsl", "gl"): ("x+a(y-x)", "division", "(1.5x+0.5)-2y", "(w*w)*(w*w)"),
    ("glsl", "vulkan"): ("x(1-a)+ya", "division", "(1.5x+0.5)-2y", "left to right"),
    ("glsl", "as-written"): ("x(1-a)+ya", "division", "as written", "left to right"),
    ("hlsl", "gl"): ("x(1-a)+ya", "x*(1/3)", "as written", "left to right"),
    ("hlsl", "vulkan"): ("x(1-a)+ya", "x*(1/3)", "(1.5x+0.5)-2y", "left to right"),
    ("hlsl", "as-written"): ("x(1-a)+ya", "x*(1/3)", "as written", "left to right"),
    ("wgsl", "gl"): ("x+a(y-x)", "division", "(1.5x+0.5)-2y", "(w*w)*(w*w)"),
    ("wgsl", "vulkan"): ("x(1-a)+ya", "division", "(1.5x+0.5)-2y", "left to right"),
}


@pytest.mark.parametrize("language,driver", sorted(_RULES_MEASURED))
def test_what_each_compiler_changes(drivers, language, driver):
    from moments_ref.conformance import _probes

    assert tuple(_probes.rules(language, driver).values()) == _RULES_MEASURED[(language, driver)]


def test_all_with_adapter_both_runs_every_driver():
    # --all --adapter both is the default (every language on gl and vulkan), not a Vulkan adapter named "both".
    from moments_ref.conformance import _cli

    assert _cli._targets("both") == _cli._targets(None)
    assert {d for _, d in _cli._targets(None)} == set(_run.DRIVERS)
    assert {d for _, d in _cli._targets("gl")} == {"gl"}
