// Bilinear sampling of a 128-bit moment shadow map (R32G32B32A32_FLOAT): moments are linear
// in the depth distribution, so the filtered texel is the moments of the filtered
// distribution (HPG17 §1, prefiltering), and the bound is taken after the filter.
//
// HLSL (Shader Model 5), float32. Part of moments_ref, checked by `moments-ref conformance
// --hlsl bilinear.hlsl --function NAME --case sample_bilinear-float32` (and
// shadow_intensity_bilinear-float32): the harness binds the golden 2x2 neighbourhoods as an
// rgba32float texture with a linear sampler, clamped to the edge, one mipmap level, and
// passes uv between the texel centres. The hardware's filter weights are the
// implementation-defined part (sub-texel precision, docs/formats.md).

#include "msm.hlsl"

#ifndef MOMENTS_REF_BILINEAR_HLSL
#define MOMENTS_REF_BILINEAR_HLSL

// The filtered moments at uv (texture coordinates in [0, 1]^2), level 0.
float4 sample_moments(Texture2D<float4> moment_map, SamplerState linear_sampler, float2 uv)
{
    return moment_map.SampleLevel(linear_sampler, uv, 0.0);
}

// Filter first, then bias (BIAS_FLOAT32, HPG17 §3.2), then HPG17 Algorithm 1's lower bound.
float shadow_intensity_bilinear(Texture2D<float4> moment_map, SamplerState linear_sampler, float2 uv, float zf)
{
    return shadow_intensity_lower(bias_moments_float32(sample_moments(moment_map, linear_sampler, uv)), zf);
}

#endif
