// Moment shadow mapping with four moments: HPG17 Algorithm 1 (Peters and Klein 2015),
// the optimized quantization basis and the moment bias of the lecture slides.
//
// HLSL (Shader Model 5 / 6), float32. Part of moments_ref (the NumPy reference in moments_ref/msm.py,
// moments_ref/affine.py and moments_ref/moments.py is the oracle these functions are
// tested against: `moments-ref conformance --hlsl msm.hlsl --function NAME --case CASE`).
// Conventions as in the papers: depth z in [-1, 1], moments b = (b1, b2, b3, b4) with
// b0 = 1 implicit.
//
// Typical use in a pixel shader with a 64-bit moment shadow map (R16G16B16A16_UNORM):
//     float4 b = bias_moments_unorm16(from_optimized(moment_map.Sample(moment_sampler, uv)));
//     float shadow = shadow_intensity_lower(b, fragment_depth);
// With a 128-bit map (R32G32B32A32_FLOAT) use bias_moments_float32(moment_map.Sample(...)).

#ifndef MOMENTS_REF_MSM_HLSL
#define MOMENTS_REF_MSM_HLSL

// ---------------------------------------------------------------------------------------
// Optimized basis (Slides, "Compute moments in resolve" and "Retrieve moments")
// ---------------------------------------------------------------------------------------

// Slides, "Compute moments in resolve":
//     (R, G, B, A) = M * (b1, b2, b3, b4) + (0.5, 0, 0.5, 0),
//     R = 1.5 b1 - 2 b3 + 0.5,         G = 4 b2 - 4 b4,
//     B = (sqrt3/2) b1 - (2 sqrt3/9) b3 + 0.5,  A = 0.5 b2 + 0.5 b4.
// Every depth distribution on [-1, 1] maps into [0, 1]^4.
float4 to_optimized(float4 b)
{
    // The offset added first: Mesa's Vulkan compiler (through wgpu, which drops `precise`) moves
    // a constant term next to the first product, and the harness's OpenGL path evaluates
    // exactly as written; in this order both round alike.
    return float4((1.5 * b.x + 0.5) - 2.0 * b.z,
                4.0 * b.y - 4.0 * b.w,
                (0.8660254 * b.x + 0.5) - 0.38490018 * b.z,
                0.5 * b.y + 0.5 * b.w);
}

// Slides, "Retrieve moments": the exact inverse of to_optimized,
//     b1 = -R'/3 + sqrt3 B',   b2 = G/8 + A,   b3 = -0.75 R' + 0.75 sqrt3 B',   b4 = -G/8 + A
// with R' = R - 0.5, B' = B - 0.5. No bias: call bias_moments_* afterwards.
float4 from_optimized(float4 q)
{
    float r = q.x - 0.5;
    float bb = q.z - 0.5;
    return float4(-0.33333334 * r + 1.7320508 * bb,
                0.125 * q.y + q.w,
                -0.75 * r + 1.299038 * bb,
                -0.125 * q.y + q.w);
}

// A 64-bit texel read as raw codes (an R16G16B16A16_UINT view or an unpacked SSBO):
// UNORM16 -> float is c / 65535 (Direct3D / Vulkan conversion rule), then from_optimized.
// A filtering fetch from an R16G16B16A16_UNORM texture already returns c / 65535;
// pass that to from_optimized directly.
float4 decode_unorm16(uint4 u)
{
    return from_optimized(float4(u) / 65535.0);
}

// ---------------------------------------------------------------------------------------
// Biasing (HPG17 §3.2; Slides, "Bias the moments")
// ---------------------------------------------------------------------------------------

// b' = (1 - alpha) b + alpha b*: pulls moments that rounding pushed out of the moment
// space back inside, and keeps the Hankel matrix B(b') positive definite.
float4 bias_moments(float4 b, float alpha, float4 target)
{
    return (1.0 - alpha) * b + alpha * target;
}

// Moments in float32 (128-bit texels, or the input of Algorithm 2):
// alpha = 3e-7, b* = (0, 0.375, 0, 0.375).
float4 bias_moments_float32(float4 b)
{
    return bias_moments(b, 3.0e-7, float4(0.0, 0.375, 0.0, 0.375));
}

// Moments stored as four UNORM16 in the optimized basis (64-bit texels):
// alpha = 6e-5, b* = (0, 0.628, 0, 0.628).
float4 bias_moments_unorm16(float4 b)
{
    return bias_moments(b, 6.0e-5, float4(0.0, 0.628, 0.0, 0.628));
}

// ---------------------------------------------------------------------------------------
// Algorithm 1 (HPG17, Peters and Klein 2015)
// ---------------------------------------------------------------------------------------

// Largest finite float32 (a root at +-infinity fails abs(z) <= MSM_FLT_MAX).
static const float MSM_FLT_MAX = 3.4028235e38;

// Unique distribution of singular moments: (1 - v2) delta_y1 + v2 delta_y2, from b1..b3
// (HPG17 Algorithm 2, steps (1)-(5)). Only reached for unbiased input.
void msm_two_point(float4 b, float sigma2, out float y1, out float y2, out float v2)
{
    // (2), (3): q2 z^2 + q1 z + q0 with q2 = sigma2 has the roots y1, y2.
    float q1 = b.x * b.y - b.z;
    float q0 = -b.x * q1 - b.y * sigma2;
    // (4) Roots without cancellation: t never cancels, q0 / t is Vieta's other root.
    float disc = sqrt(max(q1 * q1 - 4.0 * sigma2 * q0, 0.0));
    float t = -0.5 * (q1 + (q1 < 0.0 ? -disc : disc));
    float ra = t / sigma2;
    float rb = q0 / t;
    y1 = min(ra, rb);
    y2 = max(ra, rb);
    // (5) Weight of the larger depth.
    v2 = clamp((b.x - y1) / (y2 - y1), 0.0, 1.0);
    if (!(abs(v2) <= 1.0) || !(abs(y1) <= MSM_FLT_MAX) || !(abs(y2) <= MSM_FLT_MAX)) {
        // No usable second depth: all mass at b1.
        y1 = b.x;
        y2 = b.x;
        v2 = 0.0;
    }
}

// HPG17 Algorithm 1: the sharp lower bound of Z(z < zf) and the sharp upper bound of
// Z(z <= zf) over all depth distributions Z with moments b (pass biased moments).
//   (1) B(b) = [[1, b1, b2], [b1, b2, b3], [b2, b3, b4]] (Hankel matrix)
//   (2) solve B(b) q = (1, zf, zf^2)
//   (3) z1, z2 = roots of q2 z^2 + q1 z + q0
//   (4) weights w0, w1, w2 of (zf, z1, z2) with sum w_l (1, z_l, z_l^2) = (1, b1, b2)
//   (5) lower = sum of w_l over z_l < zf;  upper = lower + w0.
void msm_bounds(float4 b, float zf, out float lower, out float upper)
{
    // (2) B = L D L^T with L unit lower triangular and D = diag(1, sigma2, xi4);
    // the third pivot is HPG17's xi4 (Eq. (3)).
    float sigma2 = b.y - b.x * b.x;
    float l32 = (b.z - b.x * b.y) / sigma2;
    float xi4 = b.w - b.y * b.y - l32 * l32 * sigma2;
    if (!(sigma2 > 0.0)) {
        // Singular B(b), variance 0: one depth at b1, Z is a step.
        lower = (b.x < zf) ? 1.0 : 0.0;
        upper = (b.x <= zf) ? 1.0 : 0.0;
        return;
    }
    if (!(xi4 > 0.0)) {
        // Singular B(b), xi4 <= 0: the unique two-point distribution; exact Z.
        float y1, y2, v2;
        msm_two_point(b, sigma2, y1, y2, v2);
        lower = (y1 < zf ? 1.0 - v2 : 0.0) + (y2 < zf ? v2 : 0.0);
        upper = (y1 <= zf ? 1.0 - v2 : 0.0) + (y2 <= zf ? v2 : 0.0);
        return;
    }
    // Forward substitution L y = (1, zf, zf^2): y = (1, zf - b1, zf^2 - b2 - L32 y2).
    float y2 = zf - b.x;
    float y3 = zf * zf - b.y - l32 * y2;
    // Scaling D c = y, then back substitution L^T q = c.
    float q2 = y3 / xi4;
    float q1 = y2 / sigma2 - l32 * q2;
    float q0 = 1.0 - b.x * q1 - b.y * q2;
    // (3) Roots of q2 z^2 + q1 z + q0 without cancellation (q2 -> 0 sends one root to
    // +-infinity instead of producing 0/0; its weight is then 0).
    float disc = sqrt(max(q1 * q1 - 4.0 * q2 * q0, 0.0));
    float t = -0.5 * (q1 + (q1 < 0.0 ? -disc : disc));
    float ra = t / q2;
    float rb = q0 / t;
    float z1 = min(ra, rb);
    float z2 = max(ra, rb);
    // (4) By Peters and Klein 2015, Prop. 10 (HPG17 §3.4):
    //     1 / w_l = (1, z_l, z_l^2) B^-1 (1, z_l, z_l^2)^T = 1 + u2^2 / sigma2 + u3^2 / xi4
    // with (1, u2, u3) = L^-1 (1, z_l, z_l^2). w0 reuses y2, y3 from above.
    float w0 = 1.0 / (1.0 + y2 * y2 / sigma2 + y3 * y3 / xi4);
    float u2 = z1 - b.x;
    float u3 = z1 * z1 - b.y - l32 * u2;
    float w1 = (abs(z1) <= MSM_FLT_MAX) ? 1.0 / (1.0 + u2 * u2 / sigma2 + u3 * u3 / xi4) : 0.0;
    // (5) zf <= z1: no mass below zf; z1 < zf <= z2: w1; z2 < zf: w1 + w2 = 1 - w0.
    float l = (zf <= z1) ? 0.0 : ((zf <= z2) ? w1 : 1.0 - w0);
    lower = clamp(l, 0.0, 1.0);
    upper = clamp(l + w0, 0.0, 1.0);
}

// HPG17 Algorithm 1, lower bound of Z(z < zf): the shadow intensity of moment shadow mapping.
float shadow_intensity_lower(float4 b, float zf)
{
    float lower, upper;
    msm_bounds(b, zf, lower, upper);
    return lower;
}

// Sharp upper bound of Z(z <= zf): Algorithm 1's lower bound plus w0.
float shadow_intensity_upper(float4 b, float zf)
{
    float lower, upper;
    msm_bounds(b, zf, lower, upper);
    return upper;
}

#endif // MOMENTS_REF_MSM_HLSL
