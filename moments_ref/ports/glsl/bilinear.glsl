// Bilinear sampling of a 128-bit moment shadow map (R32G32B32A32_FLOAT): moments are linear
// in the depth distribution, so the filtered texel is the moments of the filtered
// distribution (HPG17 §1, prefiltering), and the bound is taken after the filter.
//
// GLSL 4.30, float32. Part of moments_ref, checked by `moments-ref conformance --glsl
// bilinear.glsl --function NAME --case sample_bilinear-float32` (and
// shadow_intensity_bilinear-float32): the harness binds the golden 2x2 neighbourhoods as an
// rgba32float texture with linear filtering, clamped to the edge, one mipmap level, and
// passes uv between the texel centres. The hardware's filter weights are the
// implementation-defined part (sub-texel precision, docs/formats.md).

#include "msm.glsl"

#ifndef MOMENTS_REF_BILINEAR_GLSL
#define MOMENTS_REF_BILINEAR_GLSL

// The filtered moments at uv (texture coordinates in [0, 1]^2), level 0.
vec4 sample_moments(sampler2D moment_map, vec2 uv)
{
    return textureLod(moment_map, uv, 0.0);
}

// Filter first, then bias (BIAS_FLOAT32, HPG17 §3.2), then HPG17 Algorithm 1's lower bound.
float shadow_intensity_bilinear(sampler2D moment_map, vec2 uv, float zf)
{
    return shadow_intensity_lower(bias_moments_float32(sample_moments(moment_map, uv)), zf);
}

#endif
