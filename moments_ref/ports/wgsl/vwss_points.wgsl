// View-warped soft shadows, VWSS §3.2 and Listing 2: every point is reprojected into the
// light views of this dispatch and z-buffered into their depth maps with atomicMax on an
// integer key of its reversed depth r = (1 - z_ndc) / 2 (near = larger).
//
// WGSL. Part of moments_ref (the NumPy reference is moments_ref/techniques/vwss/warp.py).
// Listing 2 runs InterlockedMax on asuint(cp.z), which orders non-negative floats only; it
// clips no depth, so a point behind the far plane (r < 0) has its sign bit set and would win
// every texel. depth_key applies the sign transform (moments_ref.techniques.vwss.warp.depth_key):
// non-negative r get the top bit set, negative r all bits flipped, so keys order as depths.
// WGSL has no atomics on storage textures: the maps are one buffer, texel (x, y) of view v
// at (v H + y) W + x.
// Run: moments-ref conformance --kernel --wgsl vwss_points.wgsl --entry CS --case kernel-vwss-points

struct Params {
    size: vec4<u32>,                 // map width, height, MSAA samples, light views
    origin: vec4<i32>,               // zw: first view of this dispatch, views in it
    count: vec4<u32>,                // x: points
    bias: vec4<f32>,
    bias_target: vec4<f32>,
    view: array<mat4x4<f32>, 32>,    // clip-from-world of each light view (LIGHT_SAMPLES 32)
}

@group(0) @binding(0) var<storage, read> points: array<vec4<f32>>;
@group(0) @binding(1) var<storage, read_write> depth: array<atomic<u32>>;
@group(0) @binding(2) var<uniform> params: Params;

// Order-preserving key of a float: bitcast with the sign transform.
fn depth_key(r: f32) -> u32 {
    let u = bitcast<u32>(r);
    return select(u | 0x80000000u, ~u, (u >> 31u) != 0u);
}

// One thread per point; this dispatch's views are origin.z .. origin.z + origin.w - 1.
@compute @workgroup_size(128) fn CS(@builtin(global_invocation_id) thread_id: vec3<u32>) {
    let i = thread_id.x;
    if (i >= params.count.x) {   // early exit check
        return;
    }
    let wp = vec4<f32>(points[i].xyz, 1.0);
    let w = params.size.x;
    let h = params.size.y;
    for (var v = params.origin.z; v < params.origin.z + params.origin.w; v++) {
        // Project into the view, perspective divide.
        let cp = params.view[v] * wp;
        if (!(cp.w > 0.0)) {
            continue;
        }
        let ndc = cp.xyz / cp.w;
        // Nearest-neighbour destination texel (texel centres at half-integers).
        let x = (ndc.x + 1.0) * 0.5 * f32(w);
        let y = (1.0 - ndc.y) * 0.5 * f32(h);
        if (!(x >= 0.0 && x < f32(w) && y >= 0.0 && y < f32(h))) {
            continue;
        }
        let r = 0.5 - 0.5 * ndc.z;
        // Atomic z-buffering.
        atomicMax(&depth[(u32(v) * h + u32(y)) * w + u32(x)], depth_key(r));
    }
}
