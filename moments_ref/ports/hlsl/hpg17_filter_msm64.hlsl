// HPG17 §4.1 filter kernel writing the 64-bit moment shadow map of Peters and Klein (2015):
// resolve, 9² Gaussian in groupshared memory (hpg17_filter.hlsl), then the optimized basis
// (Slides, "Compute moments in resolve") stored as four UNORM16 codes, round(65535 q) with
// ties up (Direct3D's rule), unbiased (the shading pass biases after decoding).
// Run: moments-ref conformance --kernel --hlsl hpg17_filter_msm64.hlsl --entry filter_msm64
//          --case kernel-filter-msm64

#include "hpg17_filter.hlsl"
#include "msm.hlsl"

RWTexture2D<uint4> texels : register(u1);

// One group of 256 threads per 32x24 output block (block origin: the uniform block).
[numthreads(256, 1, 1)] void filter_msm64(uint3 gid : SV_GroupID, uint gi : SV_GroupIndex)
{
    float4 b[3];
    int2 texel[3];
    hpg17_filter(gid, gi, b, texel);
    for (int i = 0; i < 3; ++i) {
        if (texel[i].x < int(size.x) && texel[i].y < int(size.y)) {
            precise float4 q = saturate(to_optimized(b[i])) * 65535.0 + 0.5;
            texels[texel[i]] = uint4(floor(q));
        }
    }
}
