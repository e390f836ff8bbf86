// Moment shadow mapping with four moments: HPG17 Algorithm 1 (Peters and Klein 2015),
// the optimized quantization basis and the moment bias of the lecture slides.
//
// WGSL, f32. Part of moments_ref (the NumPy reference in moments_ref/msm.py,
// moments_ref/affine.py and moments_ref/moments.py is the oracle these functions are
// tested against: `moments-ref conformance --wgsl msm.wgsl --function NAME --case CASE`).
// Conventions as in the papers: depth z in [-1, 1], moments b = (b1, b2, b3, b4) with
// b0 = 1 implicit. WGSL has no out parameters: msm_bounds returns (lower, upper).
//
// Typical use in a fragment shader with a 64-bit moment shadow map (rgba16unorm):
//     let b = bias_moments_unorm16(from_optimized(textureSample(moment_map, s, uv)));
//     let shadow = shadow_intensity_lower(b, fragment_depth);
// With a 128-bit map (rgba32float) use bias_moments_float32(textureSample(...)).

// ---------------------------------------------------------------------------------------
// Optimized basis (Slides, "Compute moments in resolve" and "Retrieve moments")
// ---------------------------------------------------------------------------------------

// Slides, "Compute moments in resolve":
//     (R, G, B, A) = M * (b1, b2, b3, b4) + (0.5, 0, 0.5, 0),
//     R = 1.5 b1 - 2 b3 + 0.5,         G = 4 b2 - 4 b4,
//     B = (sqrt3/2) b1 - (2 sqrt3/9) b3 + 0.5,  A = 0.5 b2 + 0.5 b4.
// Every depth distribution on [-1, 1] maps into [0, 1]^4.
fn to_optimized(b: vec4<f32>) -> vec4<f32> {
    return vec4<f32>(1.5 * b.x - 2.0 * b.z + 0.5,
                     4.0 * b.y - 4.0 * b.w,
                     0.8660254 * b.x - 0.38490018 * b.z + 0.5,
                     0.5 * b.y + 0.5 * b.w);
}

// Slides, "Retrieve moments": the exact inverse of to_optimized,
//     b1 = -R'/3 + sqrt3 B',   b2 = G/8 + A,   b3 = -0.75 R' + 0.75 sqrt3 B',   b4 = -G/8 + A
// with R' = R - 0.5, B' = B - 0.5. No bias: call bias_moments_* afterwards.
fn from_optimized(q: vec4<f32>) -> vec4<f32> {
    let r = q.x - 0.5;
    let bb = q.z - 0.5;
    return vec4<f32>(-0.33333334 * r + 1.7320508 * bb,
                     0.125 * q.y + q.w,
                     -0.75 * r + 1.299038 * bb,
                     -0.125 * q.y + q.w);
}

// A 64-bit texel read as raw codes (an rgba16uint view or a storage buffer):
// UNORM16 -> float is c / 65535 (the WebGPU / Vulkan conversion rule), then from_optimized.
// A filtering fetch from an rgba16unorm texture already returns c / 65535.
fn decode_unorm16(u: vec4<u32>) -> vec4<f32> {
    return from_optimized(vec4<f32>(u) / 65535.0);
}

// ---------------------------------------------------------------------------------------
// Biasing (HPG17 §3.2; Slides, "Bias the moments")
// ---------------------------------------------------------------------------------------

// b' = (1 - alpha) b + alpha b*: pulls moments that rounding pushed out of the moment
// space back inside, and keeps the Hankel matrix B(b') positive definite.
fn bias_moments(b: vec4<f32>, alpha: f32, target_b: vec4<f32>) -> vec4<f32> {
    return (1.0 - alpha) * b + alpha * target_b;
}

// Moments in float32 (128-bit texels, or the input of Algorithm 2):
// alpha = 3e-7, b* = (0, 0.375, 0, 0.375).
fn bias_moments_float32(b: vec4<f32>) -> vec4<f32> {
    return bias_moments(b, 3.0e-7, vec4<f32>(0.0, 0.375, 0.0, 0.375));
}

// Moments stored as four UNORM16 in the optimized basis (64-bit texels):
// alpha = 6e-5, b* = (0, 0.628, 0, 0.628).
fn bias_moments_unorm16(b: vec4<f32>) -> vec4<f32> {
    return bias_moments(b, 6.0e-5, vec4<f32>(0.0, 0.628, 0.0, 0.628));
}

// ---------------------------------------------------------------------------------------
// Algorithm 1 (HPG17, Peters and Klein 2015)
// ---------------------------------------------------------------------------------------

// Largest finite float32 (a root at +-infinity fails abs(z) <= MSM_FLT_MAX).
const MSM_FLT_MAX: f32 = 3.4028235e38;

// Unique distribution of singular moments: (1 - v2) delta_y1 + v2 delta_y2, from b1..b3
// (HPG17 Algorithm 2, steps (1)-(5)); returns (y1, y2, v2). Only reached for unbiased input.
fn msm_two_point(b: vec4<f32>, sigma2: f32) -> vec3<f32> {
    // (2), (3): q2 z^2 + q1 z + q0 with q2 = sigma2 has the roots y1, y2.
    let q1 = b.x * b.y - b.z;
    let q0 = -b.x * q1 - b.y * sigma2;
    // (4) Roots without cancellation: t never cancels, q0 / t is Vieta's other root.
    let disc = sqrt(max(q1 * q1 - 4.0 * sigma2 * q0, 0.0));
    let t = -0.5 * (q1 + select(disc, -disc, q1 < 0.0));
    let ra = t / sigma2;
    let rb = q0 / t;
    let y1 = min(ra, rb);
    let y2 = max(ra, rb);
    // (5) Weight of the larger depth.
    let v2 = clamp((b.x - y1) / (y2 - y1), 0.0, 1.0);
    if (!(abs(v2) <= 1.0) || !(abs(y1) <= MSM_FLT_MAX) || !(abs(y2) <= MSM_FLT_MAX)) {
        // No usable second depth: all mass at b1.
        return vec3<f32>(b.x, b.x, 0.0);
    }
    return vec3<f32>(y1, y2, v2);
}

// HPG17 Algorithm 1: the sharp lower bound of Z(z < zf) and the sharp upper bound of
// Z(z <= zf) over all depth distributions Z with moments b (pass biased moments);
// returns (lower, upper).
//   (1) B(b) = [[1, b1, b2], [b1, b2, b3], [b2, b3, b4]] (Hankel matrix)
//   (2) solve B(b) q = (1, zf, zf^2)
//   (3) z1, z2 = roots of q2 z^2 + q1 z + q0
//   (4) weights w0, w1, w2 of (zf, z1, z2) with sum w_l (1, z_l, z_l^2) = (1, b1, b2)
//   (5) lower = sum of w_l over z_l < zf;  upper = lower + w0.
fn msm_bounds(b: vec4<f32>, zf: f32) -> vec2<f32> {
    // (2) B = L D L^T with L unit lower triangular and D = diag(1, sigma2, xi4);
    // the third pivot is HPG17's xi4 (Eq. (3)).
    let sigma2 = b.y - b.x * b.x;
    let l32 = (b.z - b.x * b.y) / sigma2;
    let xi4 = b.w - b.y * b.y - l32 * l32 * sigma2;
    if (!(sigma2 > 0.0)) {
        // Singular B(b), variance 0: one depth at b1, Z is a step.
        return vec2<f32>(select(0.0, 1.0, b.x < zf), select(0.0, 1.0, b.x <= zf));
    }
    if (!(xi4 > 0.0)) {
        // Singular B(b), xi4 <= 0: the unique two-point distribution; exact Z.
        let s = msm_two_point(b, sigma2);
        let v1 = 1.0 - s.z;
        return vec2<f32>(select(0.0, v1, s.x < zf) + select(0.0, s.z, s.y < zf),
                         select(0.0, v1, s.x <= zf) + select(0.0, s.z, s.y <= zf));
    }
    // Forward substitution L y = (1, zf, zf^2): y = (1, zf - b1, zf^2 - b2 - L32 y2).
    let y2 = zf - b.x;
    let y3 = zf * zf - b.y - l32 * y2;
    // Scaling D c = y, then back substitution L^T q = c.
    let q2 = y3 / xi4;
    let q1 = y2 / sigma2 - l32 * q2;
    let q0 = 1.0 - b.x * q1 - b.y * q2;
    // (3) Roots of q2 z^2 + q1 z + q0 without cancellation (q2 -> 0 sends one root to
    // +-infinity instead of producing 0/0; its weight is then 0).
    let disc = sqrt(max(q1 * q1 - 4.0 * q2 * q0, 0.0));
    let t = -0.5 * (q1 + select(disc, -disc, q1 < 0.0));
    let ra = t / q2;
    let rb = q0 / t;
    let z1 = min(ra, rb);
    let z2 = max(ra, rb);
    // (4) By Peters and Klein 2015, Prop. 10 (HPG17 §3.4):
    //     1 / w_l = (1, z_l, z_l^2) B^-1 (1, z_l, z_l^2)^T = 1 + u2^2 / sigma2 + u3^2 / xi4
    // with (1, u2, u3) = L^-1 (1, z_l, z_l^2). w0 reuses y2, y3 from above.
    let w0 = 1.0 / (1.0 + y2 * y2 / sigma2 + y3 * y3 / xi4);
    let u2 = z1 - b.x;
    let u3 = z1 * z1 - b.y - l32 * u2;
    let w1 = select(0.0, 1.0 / (1.0 + u2 * u2 / sigma2 + u3 * u3 / xi4), abs(z1) <= MSM_FLT_MAX);
    // (5) zf <= z1: no mass below zf; z1 < zf <= z2: w1; z2 < zf: w1 + w2 = 1 - w0.
    let l = select(select(1.0 - w0, w1, zf <= z2), 0.0, zf <= z1);
    return vec2<f32>(clamp(l, 0.0, 1.0), clamp(l + w0, 0.0, 1.0));
}

// HPG17 Algorithm 1, lower bound of Z(z < zf): the shadow intensity of moment shadow mapping.
fn shadow_intensity_lower(b: vec4<f32>, zf: f32) -> f32 {
    return msm_bounds(b, zf).x;
}

// Sharp upper bound of Z(z <= zf): Algorithm 1's lower bound plus w0.
fn shadow_intensity_upper(b: vec4<f32>, zf: f32) -> f32 {
    return msm_bounds(b, zf).y;
}
