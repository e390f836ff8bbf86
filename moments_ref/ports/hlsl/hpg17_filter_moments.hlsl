// HPG17 §4.1 filter kernel writing the filtered moments b1..b4 (a 128-bit RGBA32F map):
// resolve and 9² Gaussian in groupshared memory (hpg17_filter.hlsl), no bias, no quantization.
// Run: moments-ref conformance --kernel --hlsl hpg17_filter_moments.hlsl --entry filter_moments
//          --case kernel-filter-moments

#include "hpg17_filter.hlsl"

RWTexture2D<float4> moments : register(u1);

// One group of 256 threads per 32x24 output block (block origin: the uniform block).
[numthreads(256, 1, 1)] void filter_moments(uint3 gid : SV_GroupID, uint gi : SV_GroupIndex)
{
    float4 b[3];
    int2 texel[3];
    hpg17_filter(gid, gi, b, texel);
    for (int i = 0; i < 3; ++i)
        if (texel[i].x < int(size.x) && texel[i].y < int(size.y))
            moments[texel[i]] = b[i];
}
