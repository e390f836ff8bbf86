"""``--uniform NAME=VALUE``: a function that reads a uniform, constant-buffer or push-constant member
runs unchanged, the member given its value; a wrong value fails, a missing one exits 2 naming it."""

from __future__ import annotations

import io

import pytest

from moments_ref import InputError, cli
from moments_ref.conformance._uniforms import constant_declaration, parse_uniforms

CASE = "bias_moments-float32-float32"
SOURCES = {
    "glsl": "// engine code\nlayout(std140, binding = 3) uniform ShadowParams { float alpha; vec4 bias_target; } params;\n"
            "vec4 engine_bias(vec4 b) { return (1.0 - params.alpha) * b + params.alpha * params.bias_target; }\n",
    "hlsl": "cbuffer ShadowParams : register(b3)\n{\n    float alpha;\n    float4 bias_target;\n};\n"
            "float4 engine_bias(float4 b) { return (1.0 - alpha) * b + alpha * bias_target; }\n",
    "wgsl": "struct ShadowParams { alpha: f32, bias_target: vec4<f32> }\n"
            "@group(0) @binding(3) var<uniform> params: ShadowParams;\n"
            "fn engine_bias(b: vec4<f32>) -> vec4<f32> { return (1.0 - params.alpha) * b + params.alpha * "
            "params.bias_target; }\n",
}
TARGET = "bias_target=0,0.375,0,0.375"


def _run(tmp_path, language, *uniforms, extra=()):
    f = tmp_path / f"engine.{language}"
    f.write_text(SOURCES[language])
    err, out = io.StringIO(), io.StringIO()
    import contextlib

    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = cli.main(["conformance", f"--{language}", str(f), "--function", "engine_bias", "--case", CASE,
                         *[x for u in uniforms for x in ("--uniform", u)], *extra])
    return code, out.getvalue(), err.getvalue(), f


@pytest.mark.parametrize("language", ["glsl", "hlsl", "wgsl"])
def test_a_function_reading_a_uniform_runs_with_given_values(drivers, tmp_path, language):
    # BIAS_FLOAT32 (alpha 3e-7, b* = (0, 0.375, 0, 0.375)) is what the case expects.
    code, out, err, f = _run(tmp_path, language, "alpha=3e-7", TARGET)
    assert code == 0, err + out
    code, out, err, f = _run(tmp_path, language, "alpha=6e-5", TARGET)  # another alpha: every row off
    assert code == 1 and out.startswith("FAIL")
    code, out, err, f = _run(tmp_path, language, "alpha=3e-7")
    line = 1 if language == "hlsl" else 2
    assert code == 2 and f"{f}:{line}: give bias_target a value with --uniform" in err, err
    code, out, err, f = _run(tmp_path, language)
    assert code == 2 and "--uniform NAME=VALUE" in err and "does not bind" in err, err


def test_values_are_checked_and_typed():
    assert parse_uniforms(["a=1", "params.t=0,0.5"]) == {"a": ["1"], "params.t": ["0", "0.5"]}
    for bad in ("a", "1a=2", "a=x"):
        with pytest.raises(InputError, match="uniform"):
            parse_uniforms([bad])
    vals = parse_uniforms(["alpha=3e-7", "n=2", "t=0,0.375,0,0.375"])
    assert constant_declaration("uniform uint n;", "glsl", vals, "", "f:1") == "const uint n = 2u;"
    assert constant_declaration("float alpha : register(c0);", "hlsl", vals, "", "f:1") == \
        "static const float alpha = 3e-07;"
    with pytest.raises(InputError, match=r"t is a vec2 \(2 values\), got 4"):
        constant_declaration("uniform vec2 t;", "glsl", vals, "", "f:1")


def test_kernels_refuse_uniform(capsys):
    assert cli.main(["conformance", "--kernel", "--glsl", "hpg17_filter_nlq32.glsl", "--entry", "main",
                     "--case", "kernel-filter-nlq32", "--uniform", "a=1"]) == 2
    assert "--uniform" in capsys.readouterr().err


def _run_profile(tmp_path, toml, *uniforms, language="glsl"):
    p = tmp_path / "engine.toml"
    p.write_text(toml)
    return _run(tmp_path, language, *uniforms, extra=("--profile", str(p)))


@pytest.mark.parametrize("language", ["glsl", "wgsl"])
def test_profile_uniforms_and_the_command_line_on_top(drivers, tmp_path, language, monkeypatch):
    good = '[uniforms]\nalpha = 3e-7\nbias_target = [0, 0.375, 0, 0.375]\n'
    code, out, err, f = _run_profile(tmp_path, good, language=language)
    assert code == 0, err + out
    assert "uniforms: alpha = 3e-07 (profile engine.toml); bias_target = 0,0.375,0,0.375 (profile engine.toml)" in out
    # The command line wins over the profile, and the report says which value came from where.
    code, out, err, f = _run_profile(tmp_path, good, "alpha=6e-5", language=language)
    assert code == 1 and "alpha = 6e-5 (--uniform); bias_target = 0,0.375,0,0.375 (profile engine.toml)" in out
    code, out, err, f = _run_profile(tmp_path, good.replace("3e-7", "6e-5"), "alpha=3e-7", language=language)
    assert code == 0 and "alpha = 3e-7 (--uniform)" in out, err + out
    # An instance's members under [uniforms.INSTANCE] (GLSL and WGSL blocks name an instance).
    code, out, err, f = _run_profile(tmp_path, '[uniforms.params]\nalpha = 3e-7\nbias_target = [0, 0.375, 0, 0.375]\n',
                                     language=language)
    assert code == 0 and "params.alpha = 3e-07" in out, err + out


def test_unknown_uniform_names_exit_2_naming_the_nearest_member(drivers, tmp_path):
    code, out, err, f = _run(tmp_path, "glsl", "alpah=3e-7", TARGET)
    assert code == 2 and not out and "'alpah' (from --uniform)" in err and "did you mean 'alpha'" in err, err
    code, out, err, f = _run_profile(tmp_path, '[uniforms]\nalpha = 3e-7\nbias_targe = [0, 0.375, 0, 0.375]\n')
    assert code == 2 and "'bias_targe' (from profile engine.toml)" in err and "'bias_target'" in err, err
    assert len(err.strip().splitlines()) == 1
    for bad in ('[uniforms]\nalpha = "x"\n', '[uniforms]\nalpha = []\n', 'uniforms = 3\n'):
        code, out, err, f = _run_profile(tmp_path, bad)
        assert code == 2 and "uniforms" in err and len(err.strip().splitlines()) == 1, (bad, err)
