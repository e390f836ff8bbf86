"""The conformance probe table: odd and hostile shader files, each with the answer it must get.

Files as porters ship them run unchanged on both drivers (exit 0 or 1: a verdict on
the port); a harness, toolchain or driver failure is exit 2 with one line naming the
file, line and declaration where there is one, never a traceback and never exit 1.
Each probe is a small file written here that reproduces a situation met in public
engine files: unused input attachments, samplers, constant buffers and entry points;
``};`` after a function; ``#version 460``; absolute, relative, ``--include`` and
cyclic includes; engine macros (``--define``, ``--prelude``); text that is not UTF-8;
the function that ignores an argument (it crashed the Vulkan path); a buffer at set
0; and, as real processes under memory limits, a macro bomb, a huge local array and
a shader that outruns the watchdog.
"""

from __future__ import annotations

import os
import resource
import subprocess
import sys
import time
from pathlib import Path

import pytest

from moments_ref import golden
from moments_ref.cli import main

CASE = "shadow_intensity-lower-float32"
_F = {"glsl": "float f(vec4 b, float zf) { return 0.5; }\n", "hlsl": "float f(float4 b, float zf) { return 0.5; }\n",
      "wgsl": "fn f(b: vec4<f32>, zf: f32) -> f32 { return 0.5; }\n"}


@pytest.fixture(scope="module")
def golden_dir(drivers, tmp_path_factory):
    """The goldens of CASE (the drivers present, or skip; fail under CI)."""
    d = tmp_path_factory.mktemp("golden")
    golden.write(d, [CASE])
    return d


def _write(tmp, files):
    for name, data in files.items():
        p = tmp / name
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_bytes(data if isinstance(data, bytes) else data.encode())


def _cli(argv, capsys):
    """``main(argv)`` in-process: (exit code, stdout, stderr); a traceback fails the probe."""
    code = main(argv)
    out = capsys.readouterr()
    assert "Traceback" not in out.err, out.err
    return code, out.out, out.err


_UNUSED_HLSL = ("[[vk::input_attachment_index(0)]] SubpassInput<float4> gIn;\n"
                "cbuffer PerFrame : register(b0) { float4x4 view; float4 extra; }\n"
                "SamplerState pointSampler : register(s0);\nTexture2D<float4> shadowMap : register(t0);\n"
                "struct HDShadowData { float4 proj; };\nfloat4x4 GetProj(EngineStruct sd) { return 0; }\n"
                "float4 useAll() { return gIn.SubpassLoad() + shadowMap.Sample(pointSampler, extra.xy); }\n"
                "float f(float4 b, float zf) { return 0.5; }\n"
                "[numthreads(8, 8, 1)] void CSMain(uint3 id : SV_DispatchThreadID) { }\n"
                "float4 PSMain(float4 pos : SV_Position) : SV_Target { return useAll(); }\n")
_FRAGMENT_GLSL = ("#version 330 core\nin vec2 uv;\nout vec4 color;\nuniform sampler2D gAlbedo;\n"
                  "float f(vec4 b, float zf) { return 0.5; }\n"
                  "void main() { color = texture(gAlbedo, uv) * f(vec4(0.0), 0.0); }\n")

#: (id, language, files, extra argv, adapters): files run unchanged, the verdict is exit 1 (f returns 0.5).
RUNS = [
    ("ignored-argument-hlsl", "hlsl", {"p.hlsl": _F["hlsl"]}, [], ("gl", "vulkan")),
    ("semicolon-after-function", "glsl", {"p.glsl": "float f(vec4 b, float zf) { return 0.5; };\n"}, [],
     ("gl", "vulkan")),
    ("version-460", "glsl", {"p.glsl": "#version 460\n" + _F["glsl"]}, [], ("gl", "vulkan")),
    ("version-310-es", "glsl", {"p.glsl": "#version 310 es\nprecision highp float;\n" + _F["glsl"]}, [],
     ("gl", "vulkan")),
    ("unused-resources-hlsl", "hlsl", {"p.hlsl": _UNUSED_HLSL}, [], ("gl", "vulkan")),
    ("fragment-stage-glsl", "glsl", {"p.glsl": _FRAGMENT_GLSL}, [], ("gl", "vulkan")),
    ("unused-bindings-wgsl", "wgsl", {"p.wgsl": "@group(0) @binding(0) var t: texture_2d<f32>;\n"
                                                "@group(0) @binding(1) var<uniform> u: vec4<f32>;\n" + _F["wgsl"]},
     [], ("gl", "vulkan")),
    ("include-relative-and-cycle", "hlsl", {"p.hlsl": '#include "sub/a.hlsl"\n', "sub/a.hlsl": '#include "b.hlsl"\n',
                                            "sub/b.hlsl": '#include "a.hlsl"\n' + _F["hlsl"]}, [], ("gl", "vulkan")),
    ("include-virtual-path", "hlsl", {"p.hlsl": '#include "/Packages/core/f.hlsl"\n',
                                      "root/Packages/core/f.hlsl": _F["hlsl"]}, ["--include", "{tmp}/root"], ("gl",)),
    ("include-absolute", "glsl", {"p.glsl": '#include "{tmp}/lib/f.glsl"\n', "lib/f.glsl": _F["glsl"]}, [], ("gl",)),
    ("engine-macros-define", "hlsl", {"p.hlsl": "real f(real4 b, real zf) { return 0.5; }\n"},
     ["--define", "real=float", "--define", "real4=float4"], ("gl", "vulkan")),
    ("engine-macros-prelude", "glsl", {"p.glsl": "REAL f(vec4 b, REAL zf) { return HALF; }\n",
                                       "m.glsl": "#define REAL float\n#define HALF 0.5\n"},
     ["--prelude", "{tmp}/m.glsl"], ("gl", "vulkan")),
    ("latin1-comment", "glsl", {"p.glsl": b"// caf\xe9 cr\xe8me\n" + _F["glsl"].encode()}, [], ("gl",)),
    ("utf16-with-bom", "hlsl", {"p.hlsl": _F["hlsl"].encode("utf-16")}, [], ("gl",)),
    ("unused-missing-include", "glsl", {"p.glsl": '#if 0\n#include "nowhere.glsl"\n#endif\n' + _F["glsl"]}, [],
     ("gl",)),
]


@pytest.mark.parametrize("probe_id, language, files, extra, adapters", [pytest.param(*r, id=r[0]) for r in RUNS])
def test_file_runs_unchanged_on_both_drivers(golden_dir, tmp_path, capsys, probe_id, language, files, extra,
                                             adapters):
    _write(tmp_path, {k: v.replace("{tmp}", str(tmp_path)) if isinstance(v, str) else v for k, v in files.items()})
    extra = [a.replace("{tmp}", str(tmp_path)) for a in extra]
    name = next(iter(files))
    for adapter in adapters:
        code, out, err = _cli(["conformance", f"--{language}", str(tmp_path / name), "--function", "f", "--case", CASE,
                               "--golden", str(golden_dir), "--adapter", adapter, *extra], capsys)
        assert code == 1 and out.startswith("FAIL  f ") and not err, (adapter, code, err)


#: (id, language, files, extra argv, words the one stderr line must hold)
REFUSALS = [
    ("function-empty", "glsl", {"p.glsl": _F["glsl"]}, ["--function", ""], ["function", "identifier"]),
    ("function-expression", "glsl", {"p.glsl": _F["glsl"]}, ["--function", "f(b, zf) +"], ["identifier"]),
    ("buffer-at-set-0", "glsl", {"p.glsl": "layout(std430, set = 0, binding = 0) buffer E { float e[]; };\n"
                                           "float f(vec4 b, float zf) { return e[0]; }\n"},
     [], ["p.glsl:1", "'E'", "adapter"]),
    ("global-texture-read", "hlsl", {"p.hlsl": "Texture2D<float4> moments : register(t0);\n"
                                               "float f(float4 b, float zf) { return moments.Load(int3(0, 0, 0)).x; }\n"},
     [], ["p.hlsl:1", "moments"]),
    ("hlsl-implicit-uniform", "hlsl", {"p.hlsl": "float4 _Atlas;\nfloat f(float4 b, float zf) { return _Atlas.x; }\n"},
     [], ["p.hlsl:1", "_Atlas", "static const"]),
    ("utf16-without-bom", "glsl", {"p.glsl": _F["glsl"].encode("utf-16-le")}, [], ["p.glsl", "NUL", "UTF-16"]),
    ("nul-byte", "glsl", {"p.glsl": b"float f(vec4 b, float zf) { return 0.5; }\0\n"}, [], ["p.glsl:1", "NUL"]),
    ("source-over-limit", "glsl", {"p.glsl": "// " + "x" * 4000 + "\n" + _F["glsl"]}, ["--max-source", "2K"],
     ["p.glsl", "--max-source"]),
    ("include-over-limit", "glsl", {"p.glsl": '#include "big.glsl"\n' + _F["glsl"], "big.glsl": "//" + "y" * 5000},
     ["--max-source", "4K"], ["big.glsl", "--max-source"]),
    ("include-chain-1200", "glsl", {**{f"n{i}.glsl": f'#include "n{i + 1}.glsl"\n' for i in range(1200)},
                                    "n1200.glsl": _F["glsl"], "p.glsl": '#include "n0.glsl"\n'},
     [], ["deeper than 64"]),
    ("source-is-folder", "glsl", {"d/x": ""}, ["--glsl", "{tmp}/d"], ["a folder"]),
    ("prelude-missing", "glsl", {"p.glsl": _F["glsl"]}, ["--prelude", "{tmp}/none.glsl"], ["prelude", "none.glsl"]),
    ("define-not-identifier", "glsl", {"p.glsl": _F["glsl"]}, ["--define", "1x=2"], ["define"]),
    ("define-in-wgsl", "wgsl", {"p.wgsl": _F["wgsl"]}, ["--define", "X=1"], ["WGSL", "prelude"]),
]


@pytest.mark.parametrize("probe_id, language, files, extra, words", [pytest.param(*r, id=r[0]) for r in REFUSALS])
def test_refusal_is_exit_2_with_one_line(golden_dir, tmp_path, capsys, probe_id, language, files, extra, words):
    _write(tmp_path, files)
    argv = ["conformance", f"--{language}", str(tmp_path / ("n0.glsl" if "n0.glsl" in files else f"p.{language}")),
            "--function", "f", "--case", CASE, "--golden", str(golden_dir)]
    extra = [a.replace("{tmp}", str(tmp_path)) for a in extra]
    if extra[:1] == [f"--{language}"]:
        argv[2], extra = extra[1], extra[2:]
    if extra[:1] == ["--function"]:
        argv[4], extra = extra[1], extra[2:]
    code, _, err = _cli(argv + extra, capsys)
    lines = err.strip("\n").split("\n")
    assert code == 2 and len(lines) == 1, (code, err)
    assert all(w in lines[0] for w in words), lines[0]


def test_missing_include_and_symlink_loop_name_the_line(golden_dir, tmp_path, capsys):
    # Compile errors keep their format: a first line, then one line per error at the user's file:line.
    _write(tmp_path, {"p.glsl": "// x\n#include \"nowhere.glsl\"\n" + _F["glsl"]})
    (tmp_path / "l1.glsl").symlink_to(tmp_path / "l2.glsl")
    (tmp_path / "l2.glsl").symlink_to(tmp_path / "l1.glsl")
    _write(tmp_path, {"q.hlsl": '#include "l1.glsl"\n' + _F["hlsl"]})
    for name, lang, want in (("p.glsl", "glsl", ("p.glsl:2", "nowhere.glsl", "not found")),
                             ("q.hlsl", "hlsl", ("q.hlsl:1", "l1.glsl", "symbolic link"))):
        for adapter in ("gl", "vulkan"):
            code, _, err = _cli(["conformance", f"--{lang}", str(tmp_path / name), "--function", "f", "--case", CASE,
                                 "--golden", str(golden_dir), "--adapter", adapter], capsys)
            assert code == 2 and any(all(w in x for w in want) for x in err.splitlines()[1:]), (adapter, err)


def test_both_drivers_agree_and_name_the_rows_they_do_not(golden_dir, tmp_path, capsys):
    # One GLSL file whose mix() Mesa's GLSL compiler expands as x + a(y - x) and Vulkan's as
    # x(1 - a) + ya: --adapter both names the rows and the driver off the as-written value.
    _write(tmp_path, {"m.glsl": "float f(vec4 b, float zf) { return mix(b.x, b.y, zf * 0.5 + 0.5); }\n",
                      "s.glsl": "float f(vec4 b, float zf) { return b.x * 0.5; }\n"})
    code, out, _ = _cli(["conformance", "--glsl", str(tmp_path / "s.glsl"), "--function", "f", "--case", CASE,
                         "--golden", str(golden_dir), "--adapter", "both"], capsys)
    assert code == 1 and "AGREE  gl and vulkan give identical bits on all 387 rows" in out
    code, out, _ = _cli(["conformance", "--glsl", str(tmp_path / "m.glsl"), "--function", "f", "--case", CASE,
                         "--golden", str(golden_dir), "--adapter", "both"], capsys)
    line = next(x for x in out.splitlines() if x.startswith("DISAGREE"))
    assert code == 1 and "gl and vulkan differ on" in line
    assert "off the as-written value" in out and "gl off the as-written value" in out


def _process(argv, tmp_path, data_limit=6 << 30):
    """A real ``moments-ref`` process with a data-segment limit: (exit code, stderr, seconds)."""
    env = dict(os.environ, PYTHONPATH=str(Path(__file__).resolve().parents[1]))

    def limit():
        resource.setrlimit(resource.RLIMIT_DATA, (data_limit, data_limit))

    t0 = time.perf_counter()
    p = subprocess.run([sys.executable, "-m", "moments_ref", *argv], env=env, capture_output=True, text=True,
                       cwd=tmp_path, preexec_fn=limit, timeout=180)
    return p.returncode, p.stderr, time.perf_counter() - t0


_BOMB = "\n".join(["#define A0 x"] + [f"#define A{i + 1} A{i} A{i}" for i in range(40)]) + "\n"
HEAVY = [
    ("macro-bomb-gl", "glsl", "gl", _BOMB + "float f(vec4 b, float zf) { float x = 1.0; return A40; }\n", [],
     ["driver", "--max-memory"]),
    ("macro-bomb-hlsl", "hlsl", "gl", _BOMB + "float f(float4 b, float zf) { float x = 1.0; return A40; }\n", [],
     ["p.hlsl"]),
    ("huge-local-array", "glsl", "vulkan",
     "float f(vec4 b, float zf) { float a[67108864]; a[int(zf * 1000.0) + 5] = zf; return a[int(b.x * 10.0) + 5]; }\n",
     [], ["driver"]),
    ("watchdog", "glsl", "gl", "float f(vec4 b, float zf) { float s = b.x; for (int i = 0; i < 60000; i++) { "
     + " ".join(["s = sin(s * 1.7 + zf) + cos(s * 0.3);"] * 20) + " } return s; }\n",
     ["--watchdog", "0.5"], ["within 0.5 s", "--watchdog"]),
]


@pytest.mark.parametrize("probe_id, language, adapter, text, extra, words", [pytest.param(*r, id=r[0]) for r in HEAVY])
def test_bombs_end_as_one_line_within_the_limits(golden_dir, tmp_path, probe_id, language, adapter, text, extra, words):
    (tmp_path / f"p.{language}").write_text(text)
    code, err, seconds = _process(["conformance", f"--{language}", f"p.{language}", "--function", "f", "--case", CASE,
                                   "--golden", str(golden_dir), "--adapter", adapter, "--max-memory", "1G", *extra],
                                  tmp_path)
    lines = err.strip("\n").split("\n")
    assert code == 2 and "Traceback" not in err, err
    assert lines[0].startswith("moments-ref conformance:") and all(w in err for w in words), err
    if probe_id != "macro-bomb-hlsl":  # glslang's own message for an expansion it refuses: file:line per error
        assert len(lines) == 1, err
    assert seconds < 120, seconds


def test_a_function_name_is_an_identifier():
    from moments_ref import InputError
    from moments_ref.conformance import run_function

    with pytest.raises(InputError, match="identifier"):
        run_function("x.glsl", "", {"x": [1.0]}, {"y": ("float32", (1,))}, "glsl", "gl")


# Functions that read their moments (or NLQ texels) from a texture: the harness binds the
# golden inputs as a texture and passes each row's texel (docs/ports.md, "Texture arguments").
_TEX = {
    "hlsl": ('#include "msm.hlsl"\n#include "packing.hlsl"\n'
             "float f(Texture2D<float4> m, int2 p, float zf) { return shadow_intensity_lower(m.Load(int3(p, 0)), zf); }\n"
             "float4 u64(Texture2D<uint4> t, int2 p) { return unpack64(t.Load(int3(p, 0))); }\n"
             "float4 up32(Texture2D<uint> t, int2 p) { return unpack32(t.Load(int3(p, 0))); }\n"
             "float4 dec(Texture2D<float4> t, int2 p) { return from_optimized(t.Load(int3(p, 0))); }\n"),
    "wgsl": ('#include "msm.wgsl"\n#include "packing.wgsl"\n'
             "fn f(m: texture_2d<f32>, p: vec2<i32>, zf: f32) -> f32 {\n"
             "    return shadow_intensity_lower(textureLoad(m, p, 0), zf); }\n"
             "fn u64(t: texture_2d<u32>, p: vec2<i32>) -> vec4<f32> { return unpack64(textureLoad(t, p, 0)); }\n"
             "fn up32(t: texture_2d<u32>, p: vec2<i32>) -> vec4<f32> { return unpack32(textureLoad(t, p, 0).x); }\n"
             "fn dec(t: texture_2d<f32>, p: vec2<i32>) -> vec4<f32> { return from_optimized(textureLoad(t, p, 0)); }\n"),
    "glsl": ('#include "msm.glsl"\n#include "packing.glsl"\n'
             "float f(sampler2D m, ivec2 p, float zf) { return shadow_intensity_lower(texelFetch(m, p, 0), zf); }\n"
             "vec4 u64(usampler2D t, ivec2 p) { return unpack64(texelFetch(t, p, 0)); }\n"
             "vec4 up32(usampler2D t, ivec2 p) { return unpack32(texelFetch(t, p, 0).x); }\n"
             "vec4 dec(sampler2D t, ivec2 p) { return from_optimized(texelFetch(t, p, 0)); }\n"),
}
#: (function, case, texture format the harness makes)
_TEX_CASES = [("f", CASE, "rgba32float moments"), ("u64", "unpack64-float32", "rgba16uint NLQ texels"),
              ("up32", "unpack32-float32", "r32uint NLQ texels"), ("dec", "decode_unorm16-float32", "rgba16unorm")]


@pytest.mark.parametrize("language,adapter", [("hlsl", "gl"), ("hlsl", "vulkan"), ("wgsl", "gl"), ("wgsl", "vulkan"),
                                              ("glsl", "gl")])
@pytest.mark.parametrize("function,case,what", _TEX_CASES)
def test_texture_reading_function_passes(golden_dir, tmp_path, language, adapter, function, case, what):
    from moments_ref.conformance import run_case

    if (language, adapter, function) == ("wgsl", "gl", "dec"):
        pytest.skip("wgpu's OpenGL adapter has no 16-bit normalized textures")
    path = tmp_path / f"t.{language}"
    path.write_text(_TEX[language])
    report = run_case(path, function, case, language=language, adapter=adapter)
    assert report.passed, report.format()
    assert report.rows > 100


_SAMPLED = {
    "hlsl": ('#include "msm.hlsl"\n'
             "float f(Texture2D<float4> m, SamplerState s, float2 uv, float zf) "
             "{ return shadow_intensity_lower(m.Sample(s, uv), zf); }\n"),
    "wgsl": ('#include "msm.wgsl"\n'
             "fn f(m: texture_2d<f32>, s: sampler, uv: vec2<f32>, zf: f32) -> f32 "
             "{ return shadow_intensity_lower(textureSampleLevel(m, s, uv, 0.0), zf); }\n"),
    "glsl": ('#include "msm.glsl"\n'
             "float f(sampler2D m, vec2 uv, float zf) { return shadow_intensity_lower(texture(m, uv), zf); }\n"),
}


@pytest.mark.parametrize("language,adapter", [("hlsl", "gl"), ("hlsl", "vulkan"), ("wgsl", "gl"), ("wgsl", "vulkan"),
                                              ("glsl", "gl")])
def test_sampling_function_at_texel_centres_passes(golden_dir, tmp_path, language, adapter):
    # Sample/texture at each row's texel centre (a point sampler; bilinear filtering gives
    # the texel there too): a coordinate off by a texel would read a neighbour's moments.
    from moments_ref.conformance import run_case

    path = tmp_path / f"s.{language}"
    path.write_text(_SAMPLED[language])
    report = run_case(path, "f", CASE, golden_dir, language=language, adapter=adapter)
    assert report.passed, report.format()


_DITHER = {
    "hlsl": ('#include "msm.hlsl"\n'
             "float f(Texture2D<float4> m, float2 c, float2 u, float zf) "
             "{ return shadow_intensity_lower(m.Load(int3(floor(c + u), 0)), zf); }\n"
             "float ignores_noise(Texture2D<float4> m, float2 c, float2 u, float zf) "
             "{ return shadow_intensity_lower(m.Load(int3(floor(c), 0)), zf); }\n"
             "float rounds(Texture2D<float4> m, float2 c, float2 u, float zf) "
             "{ return shadow_intensity_lower(m.Load(int3(round(c + u), 0)), zf); }\n"),
    "wgsl": ('#include "msm.wgsl"\n'
             "fn f(m: texture_2d<f32>, c: vec2<f32>, u: vec2<f32>, zf: f32) -> f32 "
             "{ return shadow_intensity_lower(textureLoad(m, vec2<i32>(floor(c + u)), 0), zf); }\n"),
    "glsl": ('#include "msm.glsl"\n'
             "float f(sampler2D m, vec2 c, vec2 u, float zf) "
             "{ return shadow_intensity_lower(texelFetch(m, ivec2(floor(c + u)), 0), zf); }\n"),
}


@pytest.mark.parametrize("language,adapter", [("hlsl", "gl"), ("hlsl", "vulkan"), ("wgsl", "gl"), ("wgsl", "vulkan"),
                                              ("glsl", "gl")])
def test_blue_noise_dithered_load_passes_and_its_mutants_fail(golden_dir, tmp_path, language, adapter):
    # HPG17 §4.2: floor(coordinate + noise) picks the texel; the harness passes 8-bit noise
    # and a coordinate whose floor is the texel before (even rows) or whose rounding is the
    # next texel (odd rows), so ignoring the noise or rounding instead of flooring fails.
    from moments_ref.conformance import run_case

    path = tmp_path / f"d.{language}"
    path.write_text(_DITHER[language])
    assert run_case(path, "f", CASE, golden_dir, language=language, adapter=adapter).passed
    if language == "hlsl":
        for mutant in ("ignores_noise", "rounds"):
            report = run_case(path, mutant, CASE, golden_dir, language=language, adapter=adapter)
            assert report.failures > 100, (mutant, report.failures)


def test_texture_refusals_are_one_line(golden_dir, tmp_path, capsys):
    _write(tmp_path, {"t.glsl": _TEX["glsl"],
                      "c.hlsl": "float f(Texture2D<float4> m, float zf) { return m.Load(int3(0, 0, 0)).x; }\n"})
    for name, adapter, words in (("t.glsl", "vulkan", ["sampler2D", "--adapter gl"]),
                                 ("c.hlsl", "gl", ["texel coordinate", "'b'"])):
        code, _, err = _cli(["conformance", f"--{name[2:]}", str(tmp_path / name), "--function", "f", "--case", CASE,
                             "--golden", str(golden_dir), "--adapter", adapter], capsys)
        assert code == 2 and len(err.strip().splitlines()) == 1 and all(w in err for w in words), err


def _bilinear_weights(u):
    """Weight of the second texel of a 2×1 rgba32float texture (0, 1) sampled linearly at ``u``,
    on OpenGL (moderngl) and Vulkan (wgpu), in this process."""
    import moderngl
    import numpy as np
    import wgpu

    texels = np.array([[0, 0, 0, 0], [1, 1, 1, 1]], np.float32)
    ctx = moderngl.create_standalone_context(backend="egl", require=430)
    t = ctx.texture((2, 1), 4, texels.tobytes(), dtype="f4")
    t.filter = (moderngl.LINEAR, moderngl.LINEAR)
    t.use(0)
    cs = ctx.compute_shader("#version 430\nlayout(local_size_x = 64) in;\nlayout(binding = 0) uniform sampler2D t;\n"
                            "layout(std430, binding = 1) readonly buffer U { float u[]; };\n"
                            "layout(std430, binding = 2) buffer O { float o[]; };\n"
                            "void main() { uint i = gl_GlobalInvocationID.x; "
                            "o[i] = textureLod(t, vec2(u[i], 0.5), 0.0).x; }\n")
    bu, bo = ctx.buffer(u.tobytes()), ctx.buffer(reserve=u.nbytes)
    bu.bind_to_storage_buffer(1)
    bo.bind_to_storage_buffer(2)
    cs.run(len(u) // 64)
    gl = np.frombuffer(bo.read(), np.float32)
    ctx.release()
    a = next(x for x in wgpu.gpu.enumerate_adapters_sync() if x.info["backend_type"] == "Vulkan")
    d = a.request_device_sync(required_features=["float32-filterable"])
    tx = d.create_texture(size=(2, 1, 1), format="rgba32float",
                          usage=wgpu.TextureUsage.TEXTURE_BINDING | wgpu.TextureUsage.COPY_DST)
    d.queue.write_texture({"texture": tx}, texels.tobytes(), {"bytes_per_row": 32, "rows_per_image": 1}, (2, 1, 1))
    m = d.create_shader_module(code="@group(0) @binding(0) var t: texture_2d<f32>;\n"
                               "@group(0) @binding(1) var s: sampler;\n"
                               "@group(0) @binding(2) var<storage, read> u: array<f32>;\n"
                               "@group(0) @binding(3) var<storage, read_write> o: array<f32>;\n"
                               "@compute @workgroup_size(64) fn main(@builtin(global_invocation_id) id: vec3<u32>) "
                               "{ o[id.x] = textureSampleLevel(t, s, vec2<f32>(u[id.x], 0.5), 0.0).x; }\n")
    p = d.create_compute_pipeline(layout="auto", compute={"module": m, "entry_point": "main"})
    bu2 = d.create_buffer_with_data(data=u.tobytes(), usage=wgpu.BufferUsage.STORAGE)
    bo2 = d.create_buffer(size=u.nbytes, usage=wgpu.BufferUsage.STORAGE | wgpu.BufferUsage.COPY_SRC)
    bg = d.create_bind_group(layout=p.get_bind_group_layout(0), entries=[
        {"binding": 0, "resource": tx.create_view()},
        {"binding": 1, "resource": d.create_sampler(mag_filter="linear", min_filter="linear")},
        {"binding": 2, "resource": {"buffer": bu2}}, {"binding": 3, "resource": {"buffer": bo2}}])
    e = d.create_command_encoder()
    cp = e.begin_compute_pass()
    cp.set_pipeline(p)
    cp.set_bind_group(0, bg)
    cp.dispatch_workgroups(len(u) // 64)
    cp.end()
    d.queue.submit([e.finish()])
    return gl, np.frombuffer(d.queue.read_buffer(bo2), np.float32)


def test_bilinear_weights_of_float_textures_are_the_exact_fraction(golden_dir):
    # docs/ports.md, "Texture arguments": llvmpipe and lavapipe filter rgba32float textures
    # with float weights, the sub-texel fraction itself (GPUs: 8 bits of sub-texel position,
    # steps of 1/256), so a bilinear golden made here could not see a GPU's spread.
    import numpy as np

    u = ((0.5 + np.random.default_rng(0).uniform(0.001, 0.999, 4096)) / 2.0).astype(np.float32)
    f = u.astype(np.float64) * 2 - 0.5  # the fraction between the two texel centres
    gl, vk = _bilinear_weights(u)
    assert np.array_equal(gl, vk)
    assert np.abs(gl - f).max() < 2 ** -24 and len(np.unique(gl)) > 4000
