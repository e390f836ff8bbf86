#version 430
// HPG17 §4.1 filter kernel writing the filtered moments b1..b4 (a 128-bit RGBA32F map):
// resolve and 9² Gaussian in shared memory (hpg17_filter.glsl), no bias, no quantization.
// Run: moments-ref conformance --kernel --glsl hpg17_filter_moments.glsl --entry main
//          --case kernel-filter-moments

#include "hpg17_filter.glsl"

layout(local_size_x = 256) in;
layout(binding = 1, rgba32f) uniform writeonly image2D moments;

void main()
{
    vec4 b[3];
    ivec2 texel[3];
    hpg17_filter(b, texel);
    for (int i = 0; i < 3; ++i)
        if (texel[i].x < int(params.size.x) && texel[i].y < int(params.size.y))
            imageStore(moments, texel[i], b[i]);
}
