// Texel formats of non-linearly quantized moment shadow maps: 64 bits (HPG17 §3.3) and
// 32 bits with the triangle fold (HPG17 §3.5, Figure 5). Bit layouts: docs/formats.md
// (stable; a change is a format version change).
//
// HLSL (Shader Model 5 / 6), float32 and integer operations. Part of moments_ref; these functions are
// bit-exact with moments_ref/packing.py (pack64, unpack64's y and v2, pack32, unpack32's
// y and v2) and checked by `moments-ref conformance`. xi4 goes through log/exp, which
// GPUs evaluate with their own accuracy: see docs/ports.md.
//
// Needs psi4 and psi4_inverse from nonlinear.hlsl (paste it above this file, or let your
// shader preprocessor resolve the include).

#ifndef MOMENTS_REF_PACKING_HLSL
#define MOMENTS_REF_PACKING_HLSL

#include "nonlinear.hlsl"

// `precise` keeps the compiler from fusing a*b+c into fma or folding constants
// differently: the codes must be bit-exact with the reference.

// Clamp a representation onto its domain (removes rounding noise from Algorithm 2):
// y2 >= y1, y1, y2 in [-1, 1], v2 in [0, 1], xi4 >= 0.
float4 packing_clamp(float4 r)
{
    float y1 = r.x;
    float y2 = max(r.y, y1);
    return float4(clamp(y1, -1.0, 1.0), clamp(y2, -1.0, 1.0), clamp(r.z, 0.0, 1.0), max(r.w, 0.0));
}

// ---------------------------------------------------------------------------------------
// 64 bits: four UNORM16 (HPG17 §3.3)
// ---------------------------------------------------------------------------------------

// (y1, y2, v2, xi4) -> UNORM16 codes, for an R16G16B16A16_UINT image or an SSBO:
//     c0 = round(65535 (y1 + 1) / 2),  c1 = round(65535 (y2 + 1) / 2),  c2 = round(65535 v2),
//     c3 = ceil(65535 Psi4(xi4)), bumped by one where Psi4^-1(c3 / 65535) < max(xi4, 1.2e-7),
// so that the decoded xi4 is never below the stored one (a UNORM fetch cannot round up).
// round() is round-half-even, as in the reference.
uint4 pack64(float4 r)
{
    r = packing_clamp(r);
    precise float s0 = (r.x + 1.0) * 0.5 * 65535.0;
    precise float s1 = (r.y + 1.0) * 0.5 * 65535.0;
    precise float s2 = r.z * 65535.0;
    precise float s3 = psi4(r.w) * 65535.0;
    uint c3 = uint(ceil(s3));
    // Guard against log/exp rounding: decoded xi4 >= the clamped xi4.
    float xi = clamp(r.w, PSI4_XI_MIN, PSI4_XI_MAX);
    precise float u3 = float(c3) / 65535.0;
    if (psi4_inverse(u3) < xi && c3 < 65535u)
        c3 += 1u;
    return uint4(uint(round(s0)), uint(round(s1)), uint(round(s2)), c3);
}

// UNORM16 codes -> (y1, y2, v2, xi4): u = c / 65535 (what an R16G16B16A16_UNORM fetch
// returns), y = 2u - 1, v2 = u, xi4 = Psi4^-1(u).
float4 unpack64(uint4 q)
{
    precise float4 u = float4(q) / 65535.0;
    precise float y1 = 2.0 * u.x - 1.0;
    precise float y2 = 2.0 * u.y - 1.0;
    return float4(y1, y2, u.z, psi4_inverse(u.w));
}

// ---------------------------------------------------------------------------------------
// 32 bits (HPG17 §3.5, Figure 5)
// ---------------------------------------------------------------------------------------
//   bits  0.. 9  y~2 (folded)     bits 10..18  y~1 (folded)
//   bits 19..25  floor(128 sqrt(v2)) <= 127   bits 26..31  floor(64 Psi4(xi4)) <= 63 (+1, see below)
// Every field is a cell index; the decoder reads depths and Psi4 at the upper end of their
// cell and sqrt(v2) at its centre (HPG17 §3.5: "rounded up to guarantee a lower bound").

// Depth code y~ = floor(511.5 (y + 1)), clamped to 0..1022 (y = 1 joins the top cell).
uint packing_depth_code(float y)
{
    precise float s = 511.5 * (y + 1.0);
    return uint(clamp(floor(s), 0.0, 1022.0));
}

// The 6-bit Psi4 code c decodes at the upper end of its cell, Psi4^-1((c + 1) / 64):
// "during loading ... rounded up to guarantee a lower bound to the shadow intensity"
// (HPG17 §3.5).
float packing_decode_xi32(uint c)
{
    precise float u = (float(c) + 1.0) / 64.0;
    return psi4_inverse(u);
}

// (y1, y2, v2, xi4) -> one uint32 (HPG17 §3.5).
uint pack32(float4 r)
{
    r = packing_clamp(r);
    uint t1 = packing_depth_code(r.x);
    uint t2 = packing_depth_code(r.y);
    // Fold (Figure 5): the pairs t1 <= t2 fill a triangle; rotating its upper half by
    // 180 degrees makes t1 fit 9 bits.
    if (t1 >= 512u) {
        t1 = 1023u - t1;
        t2 = 1022u - t2;
    }
    // Cells of 1/128 and 1/64 (powers of two: the products are exact), truncated.
    precise float sv = sqrt(r.z) * 128.0;
    uint v = min(uint(floor(sv)), 127u);
    precise float sx = psi4(r.w) * 64.0;
    uint x = min(uint(floor(sx)), 63u);
    // Bump where log/exp rounding would decode below the stored xi4.
    float xi = clamp(r.w, PSI4_XI_MIN, PSI4_XI_MAX);
    if (packing_decode_xi32(x) < xi && x < 63u)
        x += 1u;
    return t2 | (t1 << 10) | (v << 19) | (x << 26);
}

// One uint32 -> (y1, y2, v2, xi4): depths at the upper end of their cell, (y~ + 1)/511.5 - 1
// (never in front of the packed depth), v2 = ((c + 0.5) / 128)^2 (never 0 or 1), xi4 rounded up.
float4 unpack32(uint p)
{
    uint f2 = ((p >> 0u) & 1023u);
    uint f1 = ((p >> 10u) & 511u);
    uint v = ((p >> 19u) & 127u);
    uint x = ((p >> 26u) & 63u);
    // Undo the fold: unfolded pairs have f1 <= f2, folded ones f2 < f1.
    if (f2 < f1) {
        f1 = 1023u - f1;
        f2 = 1022u - f2;
    }
    precise float y1 = (float(f1) + 1.0) / 511.5 - 1.0;
    precise float y2 = (float(f2) + 1.0) / 511.5 - 1.0;
    precise float sv = (float(v) + 0.5) / 128.0;
    precise float v2 = sv * sv;
    return float4(y1, y2, v2, packing_decode_xi32(x));
}

#endif // MOMENTS_REF_PACKING_HLSL
