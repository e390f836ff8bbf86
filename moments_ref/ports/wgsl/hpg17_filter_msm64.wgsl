// HPG17 §4.1 filter kernel writing the 64-bit moment shadow map of Peters and Klein (2015):
// resolve, 9² Gaussian in workgroup memory (hpg17_filter.wgsl), then the optimized basis
// (Slides, "Compute moments in resolve") stored as four UNORM16 codes, round(65535 q) with
// ties up (Direct3D's rule), unbiased (the shading pass biases after decoding).
// Run: moments-ref conformance --kernel --wgsl hpg17_filter_msm64.wgsl --entry filter_msm64
//          --case kernel-filter-msm64

#include "hpg17_filter.wgsl"
#include "msm.wgsl"

@group(0) @binding(1) var texels: texture_storage_2d<rgba32uint, write>;

// One group of 256 threads per 32x24 output block (block origin: the uniform block).
@compute @workgroup_size(256) fn filter_msm64(@builtin(workgroup_id) gid: vec3<u32>, @builtin(local_invocation_index) gi: u32) {
    let o = hpg17_filter(gid, gi);
    for (var i = 0u; i < 3u; i++) {
        let t = o.texel[i];
        if (t.x < i32(params.size.x) && t.y < i32(params.size.y)) {
            let q = clamp(to_optimized(o.b[i]), vec4<f32>(0.0), vec4<f32>(1.0)) * 65535.0 + 0.5;
            textureStore(texels, t, vec4<u32>(floor(q)));
        }
    }
}
