// HPG17 §4.1 filter kernel writing 32-bit non-linearly quantized texels (§3.5): resolve,
// 9² Gaussian in workgroup memory (hpg17_filter.wgsl), then per texel the bias of the
// uniform block (BIAS_FLOAT32 in the golden case, HPG17 §3.2), Phi (Algorithm 2) and pack32.
// Run: moments-ref conformance --kernel --wgsl hpg17_filter_nlq32.wgsl --entry filter_nlq32
//          --case kernel-filter-nlq32

#include "hpg17_filter.wgsl"
#include "msm.wgsl"
#include "packing.wgsl"

@group(0) @binding(1) var texels: texture_storage_2d<r32uint, write>;

// One group of 256 threads per 32x24 output block (block origin: the uniform block).
@compute @workgroup_size(256) fn filter_nlq32(@builtin(workgroup_id) gid: vec3<u32>, @builtin(local_invocation_index) gi: u32) {
    let o = hpg17_filter(gid, gi);
    for (var i = 0u; i < 3u; i++) {
        let t = o.texel[i];
        if (t.x < i32(params.size.x) && t.y < i32(params.size.y)) {
            let r = phi(bias_moments(o.b[i], params.bias.x, params.bias_target));
            textureStore(texels, t, vec4<u32>(pack32(r), 0u, 0u, 0u));
        }
    }
}
