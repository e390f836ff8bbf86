// View-warped soft shadows, VWSS §3.2 and Listing 2: every point is reprojected into the
// light views of this dispatch and z-buffered into their depth maps with InterlockedMax on an
// integer key of its reversed depth r = (1 - z_ndc) / 2 (near = larger).
//
// HLSL (glslang's front end; DXC-compatible syntax). Part of moments_ref (the NumPy reference
// is moments_ref/techniques/vwss/warp.py). Listing 2 runs InterlockedMax on asuint(cp.z),
// which orders non-negative floats only; it clips no depth, so a point behind the far plane
// (r < 0) has its sign bit set and would win every texel. depth_key applies the sign
// transform (moments_ref.techniques.vwss.warp.depth_key): non-negative r get the top bit set,
// negative r all bits flipped, so keys order as depths. A RWStructuredBuffer stands for
// Listing 2's RWTexture2DArray<uint> (texel (x, y) of view v at (v H + y) W + x), so that
// WGSL and GLSL ports can share the layout (WGSL has no atomics on storage textures).
// Run: moments-ref conformance --kernel --hlsl vwss_points.hlsl --entry CS --case kernel-vwss-points

StructuredBuffer<float4> points : register(t0);
RWStructuredBuffer<uint> depth : register(u1);

cbuffer Params : register(b2)
{
    uint4 size;          // map width, height, MSAA samples, light views
    int4 origin;         // zw: first view of this dispatch, views in it
    uint4 count;         // x: points
    float4 bias;
    float4 bias_target;
    float4x4 view[32];   // clip-from-world of each light view (LIGHT_SAMPLES 32)
};

// Order-preserving key of a float: asuint with the sign transform.
uint depth_key(float r)
{
    uint u = asuint(r);
    return (u >> 31) != 0 ? ~u : (u | 0x80000000u);
}

// One thread per point; this dispatch's views are origin.z .. origin.z + origin.w - 1.
[numthreads(128, 1, 1)] void CS(uint3 threadID : SV_DispatchThreadID)
{
    if (threadID.x >= count.x)   // early exit check
        return;
    float4 wp = float4(points[threadID.x].xyz, 1.0);
    uint w = size.x, h = size.y;
    for (int v = origin.z; v < origin.z + origin.w; ++v) {
        // Project into the view, perspective divide.
        float4 cp = mul(view[v], wp);
        if (!(cp.w > 0.0))
            continue;
        float3 ndc = cp.xyz / cp.w;
        // Nearest-neighbour destination texel (texel centres at half-integers).
        float x = (ndc.x + 1.0) * 0.5 * float(w);
        float y = (1.0 - ndc.y) * 0.5 * float(h);
        if (!(x >= 0.0 && x < float(w) && y >= 0.0 && y < float(h)))
            continue;
        float r = 0.5 - 0.5 * ndc.z;
        // Atomic z-buffering.
        uint previous;
        InterlockedMax(depth[(uint(v) * h + uint(y)) * w + uint(x)], depth_key(r), previous);
    }
}
