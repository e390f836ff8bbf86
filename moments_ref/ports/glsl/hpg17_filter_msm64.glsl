#version 430
// HPG17 §4.1 filter kernel writing the 64-bit moment shadow map of Peters and Klein (2015):
// resolve, 9² Gaussian in shared memory (hpg17_filter.glsl), then the optimized basis
// (Slides, "Compute moments in resolve") stored as four UNORM16 codes, round(65535 q)
// with ties up (Direct3D's rule), unbiased (the shading pass biases after decoding).
// Run: moments-ref conformance --kernel --glsl hpg17_filter_msm64.glsl --entry main
//          --case kernel-filter-msm64

#include "hpg17_filter.glsl"
#include "msm.glsl"

layout(local_size_x = 256) in;
layout(binding = 1, rgba32ui) uniform writeonly uimage2D texels;

void main()
{
    vec4 b[3];
    ivec2 texel[3];
    hpg17_filter(b, texel);
    for (int i = 0; i < 3; ++i) {
        if (texel[i].x < int(params.size.x) && texel[i].y < int(params.size.y)) {
            precise vec4 q = clamp(to_optimized(b[i]), 0.0, 1.0) * 65535.0 + 0.5;
            imageStore(texels, texel[i], uvec4(floor(q)));
        }
    }
}
