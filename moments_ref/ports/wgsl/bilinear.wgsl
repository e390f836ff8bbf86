// Bilinear sampling of a 128-bit moment shadow map (rgba32float): moments are linear in the
// depth distribution, so the filtered texel is the moments of the filtered distribution
// (HPG17 §1, prefiltering), and the bound is taken after the filter.
//
// WGSL, f32. Part of moments_ref, checked by `moments-ref conformance --wgsl bilinear.wgsl
// --function NAME --case sample_bilinear-float32` (and shadow_intensity_bilinear-float32):
// the harness binds the golden 2x2 neighbourhoods as an rgba32float texture with a linear
// sampler, clamped to the edge, one mipmap level, and passes uv between the texel centres.
// A filtering sampler on rgba32float needs the device feature "float32-filterable". The
// hardware's filter weights are the implementation-defined part (sub-texel precision,
// docs/formats.md).
//
// Needs shadow_intensity_lower and bias_moments_float32 from msm.wgsl: WGSL has no include;
// paste it above this file, or let your preprocessor (and the moments_ref harness) resolve
// the line below.
#include "msm.wgsl"

// The filtered moments at uv (texture coordinates in [0, 1]^2), level 0 (compute shaders
// have no implicit level: textureSampleLevel).
fn sample_moments(moment_map: texture_2d<f32>, linear_sampler: sampler, uv: vec2<f32>) -> vec4<f32> {
    return textureSampleLevel(moment_map, linear_sampler, uv, 0.0);
}

// Filter first, then bias (BIAS_FLOAT32, HPG17 §3.2), then HPG17 Algorithm 1's lower bound.
fn shadow_intensity_bilinear(moment_map: texture_2d<f32>, linear_sampler: sampler, uv: vec2<f32>, zf: f32) -> f32 {
    return shadow_intensity_lower(bias_moments_float32(sample_moments(moment_map, linear_sampler, uv)), zf);
}
