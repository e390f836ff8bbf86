// Non-linearly quantized moment shadow maps (Peters 2017, HPG17 §3): the representation
// Phi(b) = (y1, y2, v2, xi4) (Algorithm 2), its inverse (Eq. (4)), the warp Psi4 of xi4
// (§3.3) and its inverse, and shading straight from the representation (Algorithm 3).
//
// GLSL 4.30, float32. Part of moments_ref; the NumPy reference is moments_ref/nonlinear.py
// and `moments-ref conformance --glsl nonlinear.glsl --function NAME --case CASE` checks
// these functions against its golden vectors. Depths in [-1, 1]; moments b = (b1..b4).
//
// Typical use:
//     resolve/filter pass:  vec4 r = phi(bias_moments_float32(b));      // msm.glsl
//                           uvec4 texel = pack64(r);  or  uint texel = pack32(r);  // packing.glsl
//     shading pass:         float shadow = shade(unpack64(texel), fragment_depth);

#ifndef MOMENTS_REF_NONLINEAR_GLSL
#define MOMENTS_REF_NONLINEAR_GLSL

// ---------------------------------------------------------------------------------------
// Phi: HPG17 Algorithm 2
// ---------------------------------------------------------------------------------------

// HPG17 Algorithm 2: (y1, y2, v2, xi4) = Phi(b) for moments b that are already biased
// with bias_moments_float32 (which keeps sigma2 > 0 and y1 != y2).
//   (1) sigma2 := q2 := b2 - b1^2        (2) q1 := b1 b2 - b3
//   (3) q0 := -b1 q1 - b2 q2              (4) y1 < y2 := roots of q2 z^2 + q1 z + q0
//   (5) v2 := (b1 - y1) / (y2 - y1)       (6) L21 := (b3 - b1 b2) / sigma2
//   (7) xi4 := b4 - b2^2 - L21^2 sigma2   (the third pivot of B = L D L^T, Eq. (3))
// For unbiased singular input (one depth) the result is that depth: y1 = y2 = b1, v2 = 0,
// xi4 = b4 - b1^4 (Eq. (1)).
vec4 phi(vec4 b)
{
    // (1)-(3) The quadratic whose roots are the two depths of S = v1 delta_y1 + v2 delta_y2.
    float sigma2 = b.y - b.x * b.x;
    float q2 = sigma2;
    float q1 = b.x * b.y - b.z;
    float q0 = -b.x * q1 - b.y * q2;
    // (4) Roots without cancellation: the textbook (-q1 +- sqrt(D)) / (2 q2) loses every
    // digit of a depth near 0 in float32; t never cancels and q0 / t is Vieta's other root.
    float disc = sqrt(max(q1 * q1 - 4.0 * q2 * q0, 0.0));
    float t = -0.5 * (q1 + (q1 < 0.0 ? -disc : disc));
    float ra = t / q2;
    float rb = q0 / t;
    float y1 = min(ra, rb);
    float y2 = max(ra, rb);
    // (5) Weight of the larger depth.
    float v2 = (b.x - y1) / (y2 - y1);
    // (6)-(7) L21 and the third pivot xi4 of B(b) = L D L^T.
    float l21 = (b.z - b.x * b.y) / sigma2;
    float xi4 = b.w - b.y * b.y - l21 * l21 * sigma2;
    // Singular input (not biased, or rounding): one depth at b1.
    bool single = !(sigma2 > 0.0) || !(abs(xi4) <= 3.4028235e38);
    if (single || !(y2 > y1) || !(abs(v2) <= 3.4028235e38)
        || !(abs(y1) <= 3.4028235e38) || !(abs(y2) <= 3.4028235e38)) {
        y1 = b.x;
        y2 = b.x;
        v2 = 0.0;
        if (single) {
            float b1sq = b.x * b.x;
            xi4 = b.w - b1sq * b1sq;
        }
    }
    return vec4(y1, y2, v2, xi4);
}

// HPG17 Eq. (4): the moments of r = (y1, y2, v2, xi4),
//     b = (1 - v2) b(y1) + v2 b(y2) + (0, 0, 0, xi4),   b(y) = (y, y^2, y^3, y^4).
vec4 phi_inverse(vec4 r)
{
    float y1 = r.x, y2 = r.y, v2 = r.z, v1 = 1.0 - v2;
    // Powers as squares (y^4 = (y^2)^2) and one sum at a time: Mesa's GLSL compiler rebalances
    // a chain like y*y*y*y into (y*y)*(y*y) and SPIR-V compilers do not, so the chain would
    // round differently on OpenGL and Vulkan; written this way every compiler evaluates it alike.
    float s1 = y1 * y1, s2 = y2 * y2;
    vec4 p1 = vec4(y1, s1, s1 * y1, s1 * s1);
    vec4 p2 = vec4(y2, s2, s2 * y2, s2 * s2);
    vec4 m = v1 * p1 + v2 * p2;
    return vec4(m.xyz, m.w + r.w);
}

// ---------------------------------------------------------------------------------------
// Psi4: HPG17 §3.3
// ---------------------------------------------------------------------------------------

// Psi4(xi) = (ln ln(xi 1e7) - ln ln 1.2) / (ln ln(0.25e7) - ln ln 1.2)
//          = (ln ln(xi 1e7) - PSI4_C0) * PSI4_INV_C1.
const float PSI4_C0 = -1.7019833;      // ln ln 1.2
const float PSI4_C1 = 4.391992;        // ln ln(0.25e7) - ln ln 1.2
const float PSI4_INV_C1 = 0.22768712;  // 1 / PSI4_C1
const float PSI4_XI_MIN = 1.2e-7;      // HPG17 §3.3 clamp
const float PSI4_XI_MAX = 0.25;        // xi4 <= 0.25 (HPG17 supplementary)

// HPG17 §3.3: Psi4(max(1.2e-7, xi4)), a monotonic warp of [1.2e-7, 0.25] onto [0, 1] that
// equalizes the histogram of xi4. Values above 0.25 (rounding only) give 1; the end
// points are exact (Psi4(1.2e-7) = 0, Psi4(0.25) = 1).
float psi4(float xi4)
{
    float x = clamp(xi4, PSI4_XI_MIN, PSI4_XI_MAX);
    float u = (log(log(x * 1.0e7)) - PSI4_C0) * PSI4_INV_C1;
    u = (x >= PSI4_XI_MAX) ? 1.0 : clamp(u, 0.0, 1.0);
    return (x <= PSI4_XI_MIN) ? 0.0 : u;
}

// exp(x) for |x| <= 16, accurate to about 1 ulp: Cody-Waite argument reduction
// x = n ln2 + r with |r| <= ln2/2 (ln2 = PSI4_LN2_HI + PSI4_LN2_LO, PSI4_LN2_HI exact in
// 16 bits so that n * PSI4_LN2_HI is exact), exp(x) = 2^n exp(r), and exp(r) by its Taylor
// polynomial of degree 8 (truncation below 1e-9 relative) in Horner form.
// Why not the built-in exp: GLSL allows it (3 + 2|x|) ulps (GLSL 4.30 §4.7.1) and
// psi4_inverse amplifies the relative error of its inner exp by up to ln(2.5e6) = 14.7.
const float PSI4_LN2_HI = 0.693145751953125;
const float PSI4_LN2_LO = 1.42860677e-6;
float psi4_exp(float x)
{
    float n = floor(x * 1.44269504 + 0.5);
    float r = (x - n * PSI4_LN2_HI) - n * PSI4_LN2_LO;
    float p = 1.0 + r * (1.0 + r * (0.5 + r * (1.6666667e-1 + r * (4.1666668e-2 + r * (8.3333338e-3
              + r * (1.3888889e-3 + r * (1.9841270e-4 + r * 2.4801587e-5)))))));
    return ldexp(p, int(n));
}

// Inverse of psi4: xi4 = 1e-7 exp(exp(PSI4_C0 + u PSI4_C1)), in [1.2e-7, 0.25],
// with exact end points. xi4 is ill-conditioned in u: a relative error e of the inner
// exp (a value up to ln(2.5e6) = 14.7) becomes 14.7 e in xi4, hence psi4_exp.
float psi4_inverse(float u)
{
    float x = clamp(u, 0.0, 1.0);
    float xi = psi4_exp(psi4_exp(PSI4_C0 + x * PSI4_C1)) * 1.0e-7;
    xi = clamp(xi, PSI4_XI_MIN, PSI4_XI_MAX);
    xi = (x >= 1.0) ? PSI4_XI_MAX : xi;
    return (x <= 0.0) ? PSI4_XI_MIN : xi;
}

// ---------------------------------------------------------------------------------------
// Algorithm 3: HPG17 §3.4
// ---------------------------------------------------------------------------------------

// HPG17 Algorithm 3: the sharp lower bound of Z(z < zf) straight from r = (y1, y2, v2, xi4)
// (equal to Algorithm 1 on the moments of Eq. (4)). After the affine change to y1 = 0,
// y2 = 1 the Hankel matrix is V diag(1 - v2, v2, xi'4) V^T (Eq. (5)), so every weight is
// w_l = 1 / ((1 - v2)^-1 (1 - z_l)^2 + v2^-1 z_l^2 + xi'4^-1 (1 - z_l)^2 z_l^2)
// (Peters and Klein 2015, Prop. 10).
float shade(vec4 r, float zf)
{
    float y1 = r.x, y2 = r.y, xi4 = r.w;
    // Zero variance (y1 = y2, v2 = 0 or 1) is undefined: clamp 1e-6 away (HPG17 §3.4).
    float v2 = clamp(r.z, 1.0e-6, 1.0 - 1.0e-6);
    float v1 = 1.0 - v2;
    // If zf <= y1: return 0.
    if (zf <= y1)
        return 0.0;
    // z'f := (zf - y1) / (y2 - y1),  xi'4 := xi4 / (y2 - y1)^4.
    float gap = max(y2 - y1, 1.0e-6);
    float zp = (zf - y1) / gap;
    float gap2 = gap * gap;
    // xi'4 = 0 (an exact two-point distribution) would give 0/0 below: the smallest
    // normal float is the limit xi'4 -> 0+.
    float xip = max(xi4 / (gap2 * gap2), 1.17549435e-38);
    // z_l := z'f (case zf > y2: w_l is w0 of the fragment depth).
    float zl = zp;
    if (zf <= y2) {
        // q0 := -xi'4 / ((1 - v2) z'f)  and  q1 := -q0 (v2 - z'f) / (v2 - v2 z'f) - 1.
        // With P := -q0 > 0 and h := q1 / 2 the smaller root of z^2 + q1 z + q0 is
        // z_l = -h - sqrt(h^2 + P). Written as -s with s = h + sign(h) sqrt(h^2 + P) and its
        // Vieta partner P / s (the roots' product is -P) it never cancels; the literal
        // formula loses z_l when h < 0 and xi'4 << 1.
        float p = min(xip / (v1 * zp), 3.4028235e38);
        float h = 0.5 * ((v2 - zp) / (v2 - v2 * zp) * p - 1.0);
        float s = h + (h < 0.0 ? -1.0 : 1.0) * sqrt(h * h + p);
        zl = min(-s, p / s);
    }
    // w_l := 1 / ((1 - v2)^-1 (1 - z_l)^2 + v2^-1 z_l^2 + xi'4^-1 (1 - z_l)^2 z_l^2).
    float a = (1.0 - zl) * (1.0 - zl);
    float zl2 = zl * zl;
    float wl = min(1.0 / (a / v1 + zl2 / v2 + a * zl2 / xip), 1.0);
    // Return w_l if zf <= y2 and 1 - w_l otherwise.
    return (zf <= y2) ? wl : 1.0 - wl;
}

#endif // MOMENTS_REF_NONLINEAR_GLSL
