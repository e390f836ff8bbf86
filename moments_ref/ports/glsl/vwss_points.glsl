#version 430
// View-warped soft shadows, VWSS §3.2 and Listing 2: every point is reprojected into the
// light views of this dispatch and z-buffered into their depth maps with an atomic maximum
// on an integer key of its reversed depth r = (1 - z_ndc) / 2 (near = larger).
//
// GLSL 4.30. Part of moments_ref (the NumPy reference is moments_ref/techniques/vwss/warp.py).
// Listing 2 runs InterlockedMax on asuint(cp.z), which orders non-negative floats only; it
// clips no depth, so a point behind the far plane (r < 0) has its sign bit set and would win
// every texel. depth_key applies the sign transform (moments_ref.techniques.vwss.warp.depth_key):
// non-negative r get the top bit set, negative r all bits flipped, so keys order as depths.
// Run: moments-ref conformance --kernel --glsl vwss_points.glsl --entry main --case kernel-vwss-points
//
// Bindings (docs/ports.md, "Kernels"): 0 the points (vec4, w = 1), 1 the depth maps (uint keys,
// cleared to 0 = empty), 2 the uniform block Params (map size, views of this dispatch, points,
// the light views' clip-from-world matrices).

layout(local_size_x = 128) in;

layout(std430, binding = 0) readonly buffer Points { vec4 p[]; } points;
layout(std430, binding = 1) buffer Depth { uint key[]; } depth;
layout(std140, binding = 2) uniform Params {
    uvec4 size;          // map width, height, MSAA samples, light views
    ivec4 origin;        // zw: first view of this dispatch, views in it
    uvec4 count;         // x: points
    vec4 bias;
    vec4 bias_target;
    mat4 view[32];       // clip-from-world of each light view (VWSS: LIGHT_SAMPLES 32)
} params;

// Order-preserving key of a float: asuint with the sign transform.
uint depth_key(float r)
{
    uint u = floatBitsToUint(r);
    return (u >> 31) != 0u ? ~u : (u | 0x80000000u);
}

void main()
{
    uint i = gl_GlobalInvocationID.x;
    if (i >= params.count.x)   // early exit check
        return;
    vec4 wp = vec4(points.p[i].xyz, 1.0);
    uint w = params.size.x, h = params.size.y;
    for (int v = params.origin.z; v < params.origin.z + params.origin.w; ++v) {
        // Project into the view, perspective divide.
        vec4 cp = params.view[v] * wp;
        if (!(cp.w > 0.0))
            continue;
        vec3 ndc = cp.xyz / cp.w;
        // Nearest-neighbour destination texel (texel centres at half-integers).
        float x = (ndc.x + 1.0) * 0.5 * float(w);
        float y = (1.0 - ndc.y) * 0.5 * float(h);
        if (!(x >= 0.0 && x < float(w) && y >= 0.0 && y < float(h)))
            continue;
        float r = 0.5 - 0.5 * ndc.z;
        // Atomic z-buffering.
        atomicMax(depth.key[(uint(v) * h + uint(y)) * w + uint(x)], depth_key(r));
    }
}
