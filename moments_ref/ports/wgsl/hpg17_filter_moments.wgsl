// HPG17 §4.1 filter kernel writing the filtered moments b1..b4 (a 128-bit RGBA32F map):
// resolve and 9² Gaussian in workgroup memory (hpg17_filter.wgsl), no bias, no quantization.
// Run: moments-ref conformance --kernel --wgsl hpg17_filter_moments.wgsl --entry filter_moments
//          --case kernel-filter-moments

#include "hpg17_filter.wgsl"

@group(0) @binding(1) var moments: texture_storage_2d<rgba32float, write>;

// One group of 256 threads per 32x24 output block (block origin: the uniform block).
@compute @workgroup_size(256) fn filter_moments(@builtin(workgroup_id) gid: vec3<u32>, @builtin(local_invocation_index) gi: u32) {
    let o = hpg17_filter(gid, gi);
    for (var i = 0u; i < 3u; i++) {
        let t = o.texel[i];
        if (t.x < i32(params.size.x) && t.y < i32(params.size.y)) {
            textureStore(moments, t, o.b[i]);
        }
    }
}
