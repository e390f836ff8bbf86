// The filter compute shader of HPG17 §4.1: one workgroup of 256 invocations turns one 32x24
// block of a 4x MSAA shadow map into filtered moments, entirely in workgroup memory.
//
//   resolve     each invocation loads all samples of a texel of the 40x32 input block (the
//               output block and a guard band of 4 on every side), averages
//               b(z) = (z, z^2, z^3, z^4) and stores the four moments;
//   horizontal  the 9-tap Gaussian (sigma 2.4) along the rows, in registers;
//   vertical    the same along the columns;
//   readout     each invocation reads three complete moment vectors of the output block.
//
// WGSL, f32. Part of moments_ref; include it (#include "hpg17_filter.wgsl", resolved by the
// harness as engines' shader preprocessors do, or paste it) and write the texels in your
// own entry point (hpg17_filter_nlq64.wgsl and its siblings do). The access pattern of
// every phase is the one of moments_ref/gpu/banks.py, whose bank-conflict count
// `moments-ref conformance` checks against this code by running it (the lines tagged
// mr:shared-load / mr:shared-store are traced); the arithmetic is the one of
// moments_ref/gpu/onchip.py.
//
// Bindings (docs/ports.md, "Kernels"): group 0, binding 0 the multisampled depth texture
// (window depth d in [0, 1], z = 2 d - 1), binding 1 your output, binding 2 the uniform
// block Params.

struct Params {
    size: vec4<u32>,          // map width, height, MSAA samples, light views
    origin: vec4<i32>,        // xy: texel of workgroup (0, 0) of this dispatch; zw: views (VWSS)
    count: vec4<u32>,         // x: points (VWSS)
    bias: vec4<f32>,          // x: alpha of the moment bias (HPG17 §3.2)
    bias_target: vec4<f32>,   // b*
}

// texture_depth_multisampled_2d binds too (the harness binds a Depth32Float texture), but wgpu's
// OpenGL back end cannot translate textureLoad from a depth texture: the float view runs on both.
@group(0) @binding(0) var depth: texture_multisampled_2d<f32>;
@group(0) @binding(2) var<uniform> params: Params;

const HPG17_BLOCK_W: u32 = 32u;   // output block
const HPG17_BLOCK_H: u32 = 24u;
const HPG17_GUARD: i32 = 4;       // half the 9-tap filter
const HPG17_MOMENT_STRIDE: u32 = 1287u;   // 40 * 32 + 7

var<workgroup> hpg17_lds: array<f32, 5148>;

// The 9-tap Gaussian, sigma = 2.4 texels, normalized (moments_ref.gpu.filtering.gaussian_weights
// rounded to float32).
var<private> hpg17_weights: array<f32, 9> = array<f32, 9>(0.044044435, 0.08086959, 0.12481912, 0.16194914,
                                                           0.17663543, 0.16194914, 0.12481912, 0.08086959,
                                                           0.044044435);

// HPG17 §4.1 "Memory layout": moment b_j (j = 1..4) of block cell (x, y) lives at
//     (40*32 + 7)(j - 1) + 40 y + floor(y / 4) + (x < 20 ? 2 x : 2 x - 39):
// the left 20 cells of a row on even words, the right 20 on odd words, one padding word
// after every 4 rows; no phase has a bank conflict.
fn hpg17_index(j: u32, x: u32, y: u32) -> u32 {
    return HPG17_MOMENT_STRIDE * (j - 1u) + 40u * y + y / 4u + select(2u * x - 39u, 2u * x, x < 20u);
}

// Every shared-memory load goes through this function (the harness traces it) ...
fn hpg17_load(a: u32) -> f32 { return hpg17_lds[a]; }            // mr:shared-load
// ... and every store through this one.
fn hpg17_store(a: u32, v: f32) { hpg17_lds[a] = v; }             // mr:shared-store

// Resolve (Figure 6a): in round r warp w takes column x = 8 r + w, lane l row y = l; the
// texel is clamped to the map (the guard band at the border), its samples averaged.
fn hpg17_resolve(in_origin: vec2<i32>, warp: u32, lane: u32) {
    let last = vec2<i32>(params.size.xy) - 1;
    for (var r = 0u; r < 5u; r++) {
        let x = 8u * r + warp;
        let y = lane;
        let t = clamp(in_origin + vec2<i32>(i32(x), i32(y)), vec2<i32>(0), last);
        var acc = vec4<f32>(0.0);
        for (var s = 0; s < i32(params.size.z); s++) {
            let z = 2.0 * textureLoad(depth, t, s).x - 1.0;   // window depth -> [-1, 1]
            let z2 = z * z;
            acc += vec4<f32>(z, z2, z2 * z, z2 * z2);
        }
        acc /= f32(params.size.z);
        for (var j = 1u; j <= 4u; j++) {
            hpg17_store(hpg17_index(j, x, y), acc[j - 1u]);
        }
    }
}

// Horizontal pass (Figure 6b): warp w blurs moment w mod 4 + 1 in half h = w div 4; lane l
// owns row l, loads the 24 cells 16 h .. 16 h + 23 and writes its 16 results to the
// columns no warp reads (left 0..15, right 24..39).
fn hpg17_horizontal(warp: u32, lane: u32) {
    let j = warp % 4u + 1u;
    let h = warp / 4u;
    var v: array<f32, 24>;
    for (var k = 0u; k < 24u; k++) {
        v[k] = hpg17_load(hpg17_index(j, 16u * h + k, lane));
    }
    for (var k = 0u; k < 16u; k++) {
        var acc = hpg17_weights[0] * v[k];
        for (var t = 1u; t < 9u; t++) {
            acc += hpg17_weights[t] * v[k + t];
        }
        hpg17_store(hpg17_index(j, 24u * h + k, lane), acc);
    }
}

// Vertical pass (Figure 6c), loads: on the strip of columns 24 h .. 24 h + 15, lane l takes
// column l mod 16 and rows 0..19 (l < 16) or 12..31.
fn hpg17_vertical_load(warp: u32, lane: u32) -> array<f32, 20> {
    let j = warp % 4u + 1u;
    let x = 24u * (warp / 4u) + lane % 16u;
    let y0 = 12u * (lane / 16u);
    var v: array<f32, 20>;
    for (var k = 0u; k < 20u; k++) {
        v[k] = hpg17_load(hpg17_index(j, x, y0 + k));
    }
    return v;
}

// Vertical pass, stores: the 12 results in place, rows 4..15 (upper) or 16..27 (lower).
fn hpg17_vertical_store(warp: u32, lane: u32, v_in: array<f32, 20>) {
    var v = v_in;
    let j = warp % 4u + 1u;
    let x = 24u * (warp / 4u) + lane % 16u;
    let y0 = 4u + 12u * (lane / 16u);
    for (var k = 0u; k < 12u; k++) {
        var acc = hpg17_weights[0] * v[k];
        for (var t = 1u; t < 9u; t++) {
            acc += hpg17_weights[t] * v[k + t];
        }
        hpg17_store(hpg17_index(j, x, y0 + k), acc);
    }
}

// Readout (Figure 6d): warp w reads output rows w, w + 8, w + 16; lane l is output column l,
// at cell l (l < 16) or l + 8, row + 4.
fn hpg17_readout(i: u32, warp: u32, lane: u32) -> vec4<f32> {
    let x = select(lane + 8u, lane, lane < 16u);
    let y = warp + 8u * i + u32(HPG17_GUARD);
    var b: vec4<f32>;
    for (var j = 1u; j <= 4u; j++) {
        b[j - 1u] = hpg17_load(hpg17_index(j, x, y));
    }
    return b;
}

// The output texels of the three vectors an invocation reads out.
struct Hpg17Out {
    b: array<vec4<f32>, 3>,
    texel: array<vec2<i32>, 3>,
}

// The whole block program for local invocation gi of workgroup gid.
fn hpg17_filter(gid: vec3<u32>, gi: u32) -> Hpg17Out {
    let warp = gi / 32u;
    let lane = gi % 32u;
    let out_origin = params.origin.xy + vec2<i32>(gid.xy) * vec2<i32>(i32(HPG17_BLOCK_W), i32(HPG17_BLOCK_H));
    hpg17_resolve(out_origin - HPG17_GUARD, warp, lane);
    workgroupBarrier();
    hpg17_horizontal(warp, lane);
    workgroupBarrier();
    let column = hpg17_vertical_load(warp, lane);
    // The upper lanes overwrite rows 12..15, which the lower lanes read: all loads first
    // (one warp of 32 does this in lockstep; narrower hardware needs the barrier, §4.1).
    workgroupBarrier();
    hpg17_vertical_store(warp, lane, column);
    workgroupBarrier();
    var o: Hpg17Out;
    for (var i = 0u; i < 3u; i++) {
        o.b[i] = hpg17_readout(i, warp, lane);
        o.texel[i] = out_origin + vec2<i32>(i32(lane), i32(warp + 8u * i));
    }
    return o;
}
