// HPG17 §4.1 filter kernel writing 64-bit non-linearly quantized texels (§3.3): resolve,
// 9² Gaussian in groupshared memory (hpg17_filter.hlsl), then per texel the bias of the
// constant buffer (BIAS_FLOAT32 in the golden case, HPG17 §3.2), Phi (Algorithm 2) and pack64.
// Run: moments-ref conformance --kernel --hlsl hpg17_filter_nlq64.hlsl --entry filter_nlq64
//          --case kernel-filter-nlq64

#include "hpg17_filter.hlsl"
#include "msm.hlsl"
#include "packing.hlsl"

RWTexture2D<uint4> texels : register(u1);

// One group of 256 threads per 32x24 output block (block origin: the uniform block).
[numthreads(256, 1, 1)] void filter_nlq64(uint3 gid : SV_GroupID, uint gi : SV_GroupIndex)
{
    float4 b[3];
    int2 texel[3];
    hpg17_filter(gid, gi, b, texel);
    for (int i = 0; i < 3; ++i) {
        if (texel[i].x < int(size.x) && texel[i].y < int(size.y)) {
            float4 r = phi(bias_moments(b[i], bias.x, bias_target));
            texels[texel[i]] = pack64(r);
        }
    }
}
