"""Bilinear sampling of moment textures on the drivers (golden.bilinear, docs/ports.md "Texture arguments").

The shipped ports sample with a linear sampler between texel centres and pass on both
drivers, bit for bit alike; a port that filters by hand from four loads (engines without
filterable float32 textures) passes too; the mistakes porters make (a half-texel offset, a
point sampler, swapped fractions, swapped weights) fail. Drivers absent: skipped, or failed
under CI (conftest.py).
"""

from __future__ import annotations

import numpy as np
import pytest

from moments_ref import conformance

SAMPLE, INTENSITY = "sample_bilinear-float32", "shadow_intensity_bilinear-float32"
#: (language, driver) the bilinear cases run on: all but those declared not available
#: (conformance.NOT_AVAILABLE: GLSL's sampler2D on OpenGL only; wgpu's OpenGL adapter has no
#: filterable rgba32float).
COMBOS = [(lang, drv) for lang in conformance.LANGUAGES for drv in conformance.DRIVERS
          if not conformance.not_available(SAMPLE, lang, drv)]

# Manual bilinear from four loads (`hand`) and its mutants, and sampling mutants; each as
# `vec4 NAME(texture, [sampler,] uv)`: the texel space position p = uv * size - 0.5.
_HAND = {
    "glsl": """
vec4 texel(sampler2D m, ivec2 p) {{ return texelFetch(m, p, 0); }}
vec4 NAME(sampler2D m, vec2 uv) {{
    vec2 p = uv * vec2(textureSize(m, 0)) {OFFSET};
    vec2 f = fract(p);
    ivec2 i = ivec2(floor(p));
    {FRAC}
    vec4 top = texel(m, i) * (({W0}).x) + texel(m, i + ivec2(1, 0)) * (({W1}).x);
    vec4 bottom = texel(m, i + ivec2(0, 1)) * (({W0}).x) + texel(m, i + ivec2(1, 1)) * (({W1}).x);
    return top * (({W0}).y) + bottom * (({W1}).y);
}}
""",
    "hlsl": """
float4 NAME(Texture2D<float4> m, SamplerState s, float2 uv) {{
    uint w, h;
    m.GetDimensions(w, h);
    float2 p = uv * float2(w, h) {OFFSET};
    float2 f = frac(p);
    int2 i = int2(floor(p));
    {FRAC}
    float4 top = m.Load(int3(i, 0)) * (({W0}).x) + m.Load(int3(i + int2(1, 0), 0)) * (({W1}).x);
    float4 bottom = m.Load(int3(i + int2(0, 1), 0)) * (({W0}).x) + m.Load(int3(i + int2(1, 1), 0)) * (({W1}).x);
    return top * (({W0}).y) + bottom * (({W1}).y);
}}
""",
    "wgsl": """
fn NAME(m: texture_2d<f32>, s: sampler, uv: vec2<f32>) -> vec4<f32> {{
    let p = uv * vec2<f32>(textureDimensions(m, 0)) {OFFSET};
    var f = fract(p);
    let i = vec2<i32>(floor(p));
    {FRAC}
    let top = textureLoad(m, i, 0) * (({W0}).x) + textureLoad(m, i + vec2<i32>(1, 0), 0) * (({W1}).x);
    let bottom = textureLoad(m, i + vec2<i32>(0, 1), 0) * (({W0}).x) + textureLoad(m, i + vec2<i32>(1, 1), 0) * (({W1}).x);
    return top * (({W0}).y) + bottom * (({W1}).y);
}}
""",
}
_ONE = {"glsl": "vec2(1.0)", "hlsl": "float2(1.0, 1.0)", "wgsl": "vec2<f32>(1.0)"}
_SWAP = {"glsl": "f = f.yx;", "hlsl": "f = f.yx;", "wgsl": "f = f.yx;"}
#: Hand-filter variants: name -> (kind, offset, fraction statement, weights (W0, W1)).
_VARIANTS = {
    "hand": ("legit", "- 0.5", "", ("{one} - f", "f")),
    "hand_corner": ("bug", "", "", ("{one} - f", "f")),  # the texel's corner taken for its centre
    "hand_swapped_xy": ("bug", "- 0.5", "{swap}", ("{one} - f", "f")),
    "hand_swapped_weights": ("bug", "- 0.5", "", ("f", "{one} - f")),
}
#: Sampling mutants: name -> body returning the moments, in each language.
_SAMPLED = {
    "half_texel": {  # half a texel off: the coordinate of the texel corner
        "glsl": "vec4 NAME(sampler2D m, vec2 uv) { return textureLod(m, uv + 0.5 / vec2(textureSize(m, 0)), 0.0); }",
        "hlsl": "float4 NAME(Texture2D<float4> m, SamplerState s, float2 uv) { uint w, h; m.GetDimensions(w, h); "
                "return m.SampleLevel(s, uv + 0.5 / float2(w, h), 0.0); }",
        "wgsl": "fn NAME(m: texture_2d<f32>, s: sampler, uv: vec2<f32>) -> vec4<f32> { return textureSampleLevel(m, s, "
                "uv + 0.5 / vec2<f32>(textureDimensions(m, 0)), 0.0); }"},
    "point_sampled": {  # the nearest texel, as a point sampler (texelFetch) returns it
        "glsl": "vec4 NAME(sampler2D m, vec2 uv) { return texelFetch(m, ivec2(uv * vec2(textureSize(m, 0))), 0); }",
        "hlsl": "float4 NAME(Texture2D<float4> m, SamplerState s, float2 uv) { uint w, h; m.GetDimensions(w, h); "
                "return m.Load(int3(uv * float2(w, h), 0)); }",
        "wgsl": "fn NAME(m: texture_2d<f32>, s: sampler, uv: vec2<f32>) -> vec4<f32> { return textureLoad(m, "
                "vec2<i32>(uv * vec2<f32>(textureDimensions(m, 0))), 0); }"},
}


def _source(language, name):
    if name in _SAMPLED:
        return _SAMPLED[name][language].replace("NAME", name) + "\n"
    _, offset, frac, (w0, w1) = _VARIANTS[name]
    one, swap = _ONE[language], _SWAP[language]
    return _HAND[language].format(OFFSET=offset, FRAC=frac.format(swap=swap),
                                  W0=w0.format(one=one), W1=w1.format(one=one)).replace("NAME", name)


def _run(tmp_path, golden_dir, language, driver, name, case=SAMPLE, **kw):
    path = tmp_path / f"{name}.{language}"
    path.write_text(_source(language, name))
    return conformance.run_case(path, name, case, golden_dir, language, driver, **kw)


def _shipped(golden_dir, language, driver, case):
    path, function = conformance.shipped_port(case, language)
    return conformance.run_case(path, function, case, golden_dir, language, driver)


def test_bilinear_cases_run_on_four_pairs():
    assert COMBOS == [("glsl", "gl"), ("hlsl", "gl"), ("hlsl", "vulkan"), ("wgsl", "vulkan")]
    assert all(conformance.not_available(INTENSITY, lang, drv) == conformance.not_available(SAMPLE, lang, drv)
               for lang in conformance.LANGUAGES for drv in conformance.DRIVERS)


@pytest.mark.parametrize("case", [SAMPLE, INTENSITY])
@pytest.mark.parametrize("language,driver", COMBOS)
def test_shipped_bilinear_port_passes(drivers, golden_dir, language, driver, case):
    report = _shipped(golden_dir, language, driver, case)
    assert report.passed and report.rows > 300, report.format()


@pytest.mark.parametrize("case", [SAMPLE, INTENSITY])
def test_shipped_bilinear_ports_agree_bit_for_bit_across_drivers(drivers, golden_dir, case):
    # llvmpipe and lavapipe both weight with the exact float32 fraction (test_conformance_probes.py)
    # and lerp in the same order: every shipped language on every driver gives the same bits.
    got = [_shipped(golden_dir, lang, drv, case).outputs for lang, drv in COMBOS]
    for g in got[1:]:
        for k in got[0]:
            assert np.array_equal(got[0][k].view(np.uint32), g[k].view(np.uint32))


@pytest.mark.parametrize("language,driver", COMBOS)
def test_bilinear_by_hand_from_four_loads_passes(drivers, golden_dir, tmp_path, language, driver):
    report = _run(tmp_path, golden_dir, language, driver, "hand")
    assert report.passed, report.format()


@pytest.mark.parametrize("name", ["hand_corner", "hand_swapped_xy", "hand_swapped_weights", "half_texel", "point_sampled"])
@pytest.mark.parametrize("language,driver", COMBOS)
def test_bilinear_mutant_fails(drivers, golden_dir, tmp_path, language, driver, name):
    report = _run(tmp_path, golden_dir, language, driver, name)
    assert not report.passed and report.failures > 100, (name, report.failures)


def test_linear_sampler_refused_by_an_adapter_without_filterable_float32(drivers, golden_dir, tmp_path, capsys):
    # wgpu's OpenGL adapter lacks "float32-filterable": exit 2, one line naming the feature.
    from moments_ref.cli import main

    path, function = conformance.shipped_port(SAMPLE, "wgsl")
    code = main(["conformance", "--wgsl", str(path), "--function", function, "--case", SAMPLE,
                 "--golden", str(golden_dir), "--adapter", "gl"])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1 and "float32-filterable" in err, err


def test_bilinear_case_refuses_an_integer_coordinate(drivers, golden_dir, tmp_path, capsys):
    from moments_ref.cli import main

    path = tmp_path / "i.hlsl"
    path.write_text("float4 f(Texture2D<float4> m, int2 p) { return m.Load(int3(p, 0)); }\n")
    code = main(["conformance", "--hlsl", str(path), "--function", "f", "--case", SAMPLE,
                 "--golden", str(golden_dir), "--adapter", "vulkan"])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1 and "linear sampler" in err, err
