// Non-linearly quantized moment shadow maps (Peters 2017, HPG17 §3): the representation
// Phi(b) = (y1, y2, v2, xi4) (Algorithm 2), its inverse (Eq. (4)), the warp Psi4 of xi4
// (§3.3) and its inverse, and shading straight from the representation (Algorithm 3).
//
// WGSL, f32. Part of moments_ref; the NumPy reference is moments_ref/nonlinear.py
// and `moments-ref conformance --wgsl nonlinear.wgsl --function NAME --case CASE` checks
// these functions against its golden vectors. Depths in [-1, 1]; moments b = (b1..b4).
//
// Typical use:
//     resolve/filter pass:  let r = phi(bias_moments_float32(b));      // msm.wgsl
//                           let texel = pack64(r);  or  pack32(r);     // packing.wgsl
//     shading pass:         let shadow = shade(unpack64(texel), fragment_depth);

// ---------------------------------------------------------------------------------------
// Phi: HPG17 Algorithm 2
// ---------------------------------------------------------------------------------------

const NL_FLT_MAX: f32 = 3.4028235e38;

// HPG17 Algorithm 2: (y1, y2, v2, xi4) = Phi(b) for moments b that are already biased
// with bias_moments_float32 (which keeps sigma2 > 0 and y1 != y2).
//   (1) sigma2 := q2 := b2 - b1^2        (2) q1 := b1 b2 - b3
//   (3) q0 := -b1 q1 - b2 q2              (4) y1 < y2 := roots of q2 z^2 + q1 z + q0
//   (5) v2 := (b1 - y1) / (y2 - y1)       (6) L21 := (b3 - b1 b2) / sigma2
//   (7) xi4 := b4 - b2^2 - L21^2 sigma2   (the third pivot of B = L D L^T, Eq. (3))
// For unbiased singular input (one depth) the result is that depth: y1 = y2 = b1, v2 = 0,
// xi4 = b4 - b1^4 (Eq. (1)).
fn phi(b: vec4<f32>) -> vec4<f32> {
    // (1)-(3) The quadratic whose roots are the two depths of S = v1 delta_y1 + v2 delta_y2.
    let sigma2 = b.y - b.x * b.x;
    let q2 = sigma2;
    let q1 = b.x * b.y - b.z;
    let q0 = -b.x * q1 - b.y * q2;
    // (4) Roots without cancellation: the textbook (-q1 +- sqrt(D)) / (2 q2) loses every
    // digit of a depth near 0 in float32; t never cancels and q0 / t is Vieta's other root.
    let disc = sqrt(max(q1 * q1 - 4.0 * q2 * q0, 0.0));
    let t = -0.5 * (q1 + select(disc, -disc, q1 < 0.0));
    let ra = t / q2;
    let rb = q0 / t;
    var y1 = min(ra, rb);
    var y2 = max(ra, rb);
    // (5) Weight of the larger depth.
    var v2 = (b.x - y1) / (y2 - y1);
    // (6)-(7) L21 and the third pivot xi4 of B(b) = L D L^T.
    let l21 = (b.z - b.x * b.y) / sigma2;
    var xi4 = b.w - b.y * b.y - l21 * l21 * sigma2;
    // Singular input (not biased, or rounding): one depth at b1.
    let single = !(sigma2 > 0.0) || !(abs(xi4) <= NL_FLT_MAX);
    if (single || !(y2 > y1) || !(abs(v2) <= NL_FLT_MAX)
        || !(abs(y1) <= NL_FLT_MAX) || !(abs(y2) <= NL_FLT_MAX)) {
        y1 = b.x;
        y2 = b.x;
        v2 = 0.0;
        if (single) {
            let b1sq = b.x * b.x;
            xi4 = b.w - b1sq * b1sq;
        }
    }
    return vec4<f32>(y1, y2, v2, xi4);
}

// HPG17 Eq. (4): the moments of r = (y1, y2, v2, xi4),
//     b = (1 - v2) b(y1) + v2 b(y2) + (0, 0, 0, xi4),   b(y) = (y, y^2, y^3, y^4).
fn phi_inverse(r: vec4<f32>) -> vec4<f32> {
    let y1 = r.x;
    let y2 = r.y;
    let v2 = r.z;
    let v1 = 1.0 - v2;
    // Powers as squares (y^4 = (y^2)^2) and one sum at a time: Mesa's GLSL compiler rebalances
    // a chain like y*y*y*y into (y*y)*(y*y) and SPIR-V compilers do not, so the chain would
    // round differently on OpenGL and Vulkan; written this way every compiler evaluates it alike.
    let s1 = y1 * y1;
    let s2 = y2 * y2;
    let p1 = vec4<f32>(y1, s1, s1 * y1, s1 * s1);
    let p2 = vec4<f32>(y2, s2, s2 * y2, s2 * s2);
    let m = v1 * p1 + v2 * p2;
    return vec4<f32>(m.xyz, m.w + r.w);
}

// ---------------------------------------------------------------------------------------
// Psi4: HPG17 §3.3
// ---------------------------------------------------------------------------------------

// Psi4(xi) = (ln ln(xi 1e7) - ln ln 1.2) / (ln ln(0.25e7) - ln ln 1.2)
//          = (ln ln(xi 1e7) - PSI4_C0) * PSI4_INV_C1.
const PSI4_C0: f32 = -1.7019833;      // ln ln 1.2
const PSI4_C1: f32 = 4.391992;        // ln ln(0.25e7) - ln ln 1.2
const PSI4_INV_C1: f32 = 0.22768712;  // 1 / PSI4_C1
const PSI4_XI_MIN: f32 = 1.2e-7;      // HPG17 §3.3 clamp
const PSI4_XI_MAX: f32 = 0.25;        // xi4 <= 0.25 (HPG17 supplementary)

// HPG17 §3.3: Psi4(max(1.2e-7, xi4)), a monotonic warp of [1.2e-7, 0.25] onto [0, 1] that
// equalizes the histogram of xi4. Values above 0.25 (rounding only) give 1; the end
// points are exact (Psi4(1.2e-7) = 0, Psi4(0.25) = 1).
fn psi4(xi4: f32) -> f32 {
    let x = clamp(xi4, PSI4_XI_MIN, PSI4_XI_MAX);
    var u = (log(log(x * 1.0e7)) - PSI4_C0) * PSI4_INV_C1;
    u = select(clamp(u, 0.0, 1.0), 1.0, x >= PSI4_XI_MAX);
    return select(u, 0.0, x <= PSI4_XI_MIN);
}

// exp(x) for |x| <= 16, accurate to about 1 ulp: Cody-Waite argument reduction
// x = n ln2 + r with |r| <= ln2/2 (ln2 = PSI4_LN2_HI + PSI4_LN2_LO, PSI4_LN2_HI exact in
// 16 bits so that n * PSI4_LN2_HI is exact), exp(x) = 2^n exp(r), and exp(r) by its Taylor
// polynomial of degree 8 (truncation below 1e-9 relative) in Horner form.
// Why not the built-in exp: WGSL allows it (3 + 2|x|) ulps and psi4_inverse amplifies the
// relative error of its inner exp by up to ln(2.5e6) = 14.7.
const PSI4_LN2_HI: f32 = 0.693145751953125;
const PSI4_LN2_LO: f32 = 1.42860677e-6;
fn psi4_exp(x: f32) -> f32 {
    let n = floor(x * 1.44269504 + 0.5);
    let r = (x - n * PSI4_LN2_HI) - n * PSI4_LN2_LO;
    let p = 1.0 + r * (1.0 + r * (0.5 + r * (1.6666667e-1 + r * (4.1666668e-2 + r * (8.3333338e-3
            + r * (1.3888889e-3 + r * (1.9841270e-4 + r * 2.4801587e-5)))))));
    return ldexp(p, i32(n));
}

// Inverse of psi4: xi4 = 1e-7 exp(exp(PSI4_C0 + u PSI4_C1)), in [1.2e-7, 0.25],
// with exact end points. xi4 is ill-conditioned in u: a relative error e of the inner
// exp (a value up to ln(2.5e6) = 14.7) becomes 14.7 e in xi4, hence psi4_exp.
fn psi4_inverse(u: f32) -> f32 {
    let x = clamp(u, 0.0, 1.0);
    var xi = psi4_exp(psi4_exp(PSI4_C0 + x * PSI4_C1)) * 1.0e-7;
    xi = clamp(xi, PSI4_XI_MIN, PSI4_XI_MAX);
    xi = select(xi, PSI4_XI_MAX, x >= 1.0);
    return select(xi, PSI4_XI_MIN, x <= 0.0);
}

// ---------------------------------------------------------------------------------------
// Algorithm 3: HPG17 §3.4
// ---------------------------------------------------------------------------------------

// HPG17 Algorithm 3: the sharp lower bound of Z(z < zf) straight from r = (y1, y2, v2, xi4)
// (equal to Algorithm 1 on the moments of Eq. (4)). After the affine change to y1 = 0,
// y2 = 1 the Hankel matrix is V diag(1 - v2, v2, xi'4) V^T (Eq. (5)), so every weight is
// w_l = 1 / ((1 - v2)^-1 (1 - z_l)^2 + v2^-1 z_l^2 + xi'4^-1 (1 - z_l)^2 z_l^2)
// (Peters and Klein 2015, Prop. 10).
fn shade(r: vec4<f32>, zf: f32) -> f32 {
    let y1 = r.x;
    let y2 = r.y;
    let xi4 = r.w;
    // Zero variance (y1 = y2, v2 = 0 or 1) is undefined: clamp 1e-6 away (HPG17 §3.4).
    let v2 = clamp(r.z, 1.0e-6, 1.0 - 1.0e-6);
    let v1 = 1.0 - v2;
    // If zf <= y1: return 0.
    if (zf <= y1) {
        return 0.0;
    }
    // z'f := (zf - y1) / (y2 - y1),  xi'4 := xi4 / (y2 - y1)^4.
    let gap = max(y2 - y1, 1.0e-6);
    let zp = (zf - y1) / gap;
    let gap2 = gap * gap;
    // xi'4 = 0 (an exact two-point distribution) would give 0/0 below: the smallest
    // normal float is the limit xi'4 -> 0+.
    let xip = max(xi4 / (gap2 * gap2), 1.17549435e-38);
    // z_l := z'f (case zf > y2: w_l is w0 of the fragment depth).
    var zl = zp;
    if (zf <= y2) {
        // q0 := -xi'4 / ((1 - v2) z'f)  and  q1 := -q0 (v2 - z'f) / (v2 - v2 z'f) - 1.
        // With P := -q0 > 0 and h := q1 / 2 the smaller root of z^2 + q1 z + q0 is
        // z_l = -h - sqrt(h^2 + P). Written as -s with s = h + sign(h) sqrt(h^2 + P) and its
        // Vieta partner P / s (the roots' product is -P) it never cancels; the literal
        // formula loses z_l when h < 0 and xi'4 << 1.
        let p = min(xip / (v1 * zp), NL_FLT_MAX);
        let h = 0.5 * ((v2 - zp) / (v2 - v2 * zp) * p - 1.0);
        let s = h + select(1.0, -1.0, h < 0.0) * sqrt(h * h + p);
        zl = min(-s, p / s);
    }
    // w_l := 1 / ((1 - v2)^-1 (1 - z_l)^2 + v2^-1 z_l^2 + xi'4^-1 (1 - z_l)^2 z_l^2).
    let a = (1.0 - zl) * (1.0 - zl);
    let zl2 = zl * zl;
    let wl = min(1.0 / (a / v1 + zl2 / v2 + a * zl2 / xip), 1.0);
    // Return w_l if zf <= y2 and 1 - w_l otherwise.
    return select(1.0 - wl, wl, zf <= y2);
}
