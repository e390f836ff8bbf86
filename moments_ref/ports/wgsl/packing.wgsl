// Texel formats of non-linearly quantized moment shadow maps: 64 bits (HPG17 §3.3) and
// 32 bits with the triangle fold (HPG17 §3.5, Figure 5). Bit layouts: docs/formats.md
// (stable; a change is a format version change).
//
// WGSL, f32 and u32 operations. Part of moments_ref; these functions are bit-exact with
// moments_ref/packing.py on the golden rows (pack64, pack32; unpack64's and unpack32's
// y and v2 up to fma contraction) and checked by `moments-ref conformance`. xi4 goes
// through log/exp, which GPUs evaluate with their own accuracy: see docs/ports.md.
//
// Needs psi4 and psi4_inverse from nonlinear.wgsl: WGSL has no include; paste it above
// this file, or let your preprocessor (and the moments_ref harness) resolve the line below.
#include "nonlinear.wgsl"

// WGSL has no `precise`: the products that become integer codes are written so that a
// fused multiply-add cannot change them (a + 1 before the product; 2u exact before - 1).

// Clamp a representation onto its domain (removes rounding noise from Algorithm 2):
// y2 >= y1, y1, y2 in [-1, 1], v2 in [0, 1], xi4 >= 0.
fn packing_clamp(r: vec4<f32>) -> vec4<f32> {
    let y1 = r.x;
    let y2 = max(r.y, y1);
    return vec4<f32>(clamp(y1, -1.0, 1.0), clamp(y2, -1.0, 1.0), clamp(r.z, 0.0, 1.0), max(r.w, 0.0));
}

// ---------------------------------------------------------------------------------------
// 64 bits: four UNORM16 (HPG17 §3.3)
// ---------------------------------------------------------------------------------------

// (y1, y2, v2, xi4) -> UNORM16 codes, for an rgba16uint texture or a storage buffer:
//     c0 = round(65535 (y1 + 1) / 2),  c1 = round(65535 (y2 + 1) / 2),  c2 = round(65535 v2),
//     c3 = ceil(65535 Psi4(xi4)), bumped by one where Psi4^-1(c3 / 65535) < max(xi4, 1.2e-7),
// so that the decoded xi4 is never below the stored one (a UNORM fetch cannot round up).
// WGSL round() is round-half-even, as in the reference.
fn pack64(r_in: vec4<f32>) -> vec4<u32> {
    let r = packing_clamp(r_in);
    let s0 = (r.x + 1.0) * 0.5 * 65535.0;
    let s1 = (r.y + 1.0) * 0.5 * 65535.0;
    let s2 = r.z * 65535.0;
    let s3 = psi4(r.w) * 65535.0;
    var c3 = u32(ceil(s3));
    // Guard against log/exp rounding: decoded xi4 >= the clamped xi4.
    let xi = clamp(r.w, PSI4_XI_MIN, PSI4_XI_MAX);
    let u3 = f32(c3) / 65535.0;
    if (psi4_inverse(u3) < xi && c3 < 65535u) {
        c3 = c3 + 1u;
    }
    return vec4<u32>(u32(round(s0)), u32(round(s1)), u32(round(s2)), c3);
}

// UNORM16 codes -> (y1, y2, v2, xi4): u = c / 65535 (what an rgba16unorm fetch
// returns), y = 2u - 1, v2 = u, xi4 = Psi4^-1(u).
fn unpack64(q: vec4<u32>) -> vec4<f32> {
    let u = vec4<f32>(q) / 65535.0;
    let y1 = 2.0 * u.x - 1.0;
    let y2 = 2.0 * u.y - 1.0;
    return vec4<f32>(y1, y2, u.z, psi4_inverse(u.w));
}

// ---------------------------------------------------------------------------------------
// 32 bits (HPG17 §3.5, Figure 5)
// ---------------------------------------------------------------------------------------
//   bits  0.. 9  y~2 (folded)     bits 10..18  y~1 (folded)
//   bits 19..25  floor(128 sqrt(v2)) <= 127   bits 26..31  floor(64 Psi4(xi4)) <= 63 (+1, see below)
// Every field is a cell index; the decoder reads depths and Psi4 at the upper end of their
// cell and sqrt(v2) at its centre (HPG17 §3.5: "rounded up to guarantee a lower bound").

// Depth code y~ = floor(511.5 (y + 1)), clamped to 0..1022 (y = 1 joins the top cell).
fn packing_depth_code(y: f32) -> u32 {
    let s = 511.5 * (y + 1.0);
    return u32(clamp(floor(s), 0.0, 1022.0));
}

// The 6-bit Psi4 code c decodes at the upper end of its cell, Psi4^-1((c + 1) / 64):
// "during loading ... rounded up to guarantee a lower bound to the shadow intensity"
// (HPG17 §3.5).
fn packing_decode_xi32(c: u32) -> f32 {
    let u = (f32(c) + 1.0) / 64.0;
    return psi4_inverse(u);
}

// (y1, y2, v2, xi4) -> one u32 (HPG17 §3.5).
fn pack32(r_in: vec4<f32>) -> u32 {
    let r = packing_clamp(r_in);
    var t1 = packing_depth_code(r.x);
    var t2 = packing_depth_code(r.y);
    // Fold (Figure 5): the pairs t1 <= t2 fill a triangle; rotating its upper half by
    // 180 degrees makes t1 fit 9 bits.
    if (t1 >= 512u) {
        t1 = 1023u - t1;
        t2 = 1022u - t2;
    }
    // Cells of 1/128 and 1/64 (powers of two: the products are exact), truncated.
    let sv = sqrt(r.z) * 128.0;
    let v = min(u32(floor(sv)), 127u);
    let sx = psi4(r.w) * 64.0;
    var x = min(u32(floor(sx)), 63u);
    // Bump where log/exp rounding would decode below the stored xi4.
    let xi = clamp(r.w, PSI4_XI_MIN, PSI4_XI_MAX);
    if (packing_decode_xi32(x) < xi && x < 63u) {
        x = x + 1u;
    }
    return t2 | (t1 << 10u) | (v << 19u) | (x << 26u);
}

// One u32 -> (y1, y2, v2, xi4): depths at the upper end of their cell, (y~ + 1)/511.5 - 1
// (never in front of the packed depth), v2 = ((c + 0.5) / 128)^2 (never 0 or 1), xi4 rounded up.
fn unpack32(p: u32) -> vec4<f32> {
    var f2 = extractBits(p, 0u, 10u);
    var f1 = extractBits(p, 10u, 9u);
    let v = extractBits(p, 19u, 7u);
    let x = extractBits(p, 26u, 6u);
    // Undo the fold: unfolded pairs have f1 <= f2, folded ones f2 < f1.
    if (f2 < f1) {
        f1 = 1023u - f1;
        f2 = 1022u - f2;
    }
    let y1 = (f32(f1) + 1.0) / 511.5 - 1.0;
    let y2 = (f32(f2) + 1.0) / 511.5 - 1.0;
    let sv = (f32(v) + 0.5) / 128.0;
    let v2 = sv * sv;
    return vec4<f32>(y1, y2, v2, packing_decode_xi32(x));
}
