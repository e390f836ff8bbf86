#version 430
// HPG17 §4.1 filter kernel writing 32-bit non-linearly quantized texels (§3.5): resolve,
// 9² Gaussian in shared memory (hpg17_filter.glsl), then per texel the bias of the uniform
// block (BIAS_FLOAT32 in the golden case, HPG17 §3.2), Phi (Algorithm 2) and pack32.
// Run: moments-ref conformance --kernel --glsl hpg17_filter_nlq32.glsl --entry main
//          --case kernel-filter-nlq32

#include "hpg17_filter.glsl"
#include "msm.glsl"
#include "packing.glsl"

layout(local_size_x = 256) in;
layout(binding = 1, r32ui) uniform writeonly uimage2D texels;

void main()
{
    vec4 b[3];
    ivec2 texel[3];
    hpg17_filter(b, texel);
    for (int i = 0; i < 3; ++i) {
        if (texel[i].x < int(params.size.x) && texel[i].y < int(params.size.y)) {
            vec4 r = phi(bias_moments(b[i], params.bias.x, params.bias_target));
            imageStore(texels, texel[i], uvec4(pack32(r), 0u, 0u, 0u));
        }
    }
}
