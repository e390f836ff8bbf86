// Moment shadow mapping with six moments: the sharp lower and upper bounds of Z(z < zf)
// from b = (b1, ..., b6) (Peters and Klein 2015; used for prefiltered single scattering
// in the lecture slides, "Prefiltered single scattering with 6 moments").
//
// HLSL (Shader Model 5 / 6), float32. Part of moments_ref (the NumPy reference moments_ref/msm6.py is the
// oracle: `moments-ref conformance --hlsl msm6.hlsl --function NAME --case CASE`).
// Six moments do not fit a float4: they are passed as float b[6] = (b1, ..., b6), b0 = 1
// implicit; bias them first (moments_ref.msm6.BIAS6_FLOAT32: alpha = 3e-4, target the
// moments of 0.4 delta_0 + 0.15 (delta_-1 + delta_1 + delta_-1/2 + delta_1/2)).
//
// The steps (as in msm6.py):
//   (1) B(b) = L D L^T, the 4x4 Hankel matrix B[i][j] = b_(i+j), D = diag(1, D1, D2, D3)
//   (2) solve B q = v(zf), v(z) = (1, z, z^2, z^3)
//   (3) the roots z_l of q3 z^3 + q2 z^2 + q1 z + q0, found as t_l = 1 / (z_l - zf), the
//       roots of P(t) = p(zf) t^3 + p'(zf) t^2 + p''(zf)/2 t + q3 (p(zf) = 1/w0 >= 1 never
//       vanishes; q3 -> 0 sends a root to infinity, which is t = 0 here, harmless). The
//       roots interlace with the Gauss nodes (roots of the orthogonal polynomial P3), so the
//       number k of nodes below zf (a Sturm sequence, free) says which roots lie below zf,
//       and the bounds need one root: the smallest t (k = 1) or the largest (k = 2), from
//       Blinn's closed form without trigonometric functions
//   (4) its weight w = 1 / (v(z)^T B^-1 v(z)) (Peters and Klein 2015, Prop. 10)
//   (5) lower = sum of w_l over z_l < zf: 0, w, 1 - w0 - w or 1 - w0 for k = 0, 1, 2, 3;
//       upper = lower + w0.

#ifndef MOMENTS_REF_MSM6_HLSL
#define MOMENTS_REF_MSM6_HLSL

static const float MSM6_FLT_MAX = 3.4028235e38;

// One Newton step on c0 t^3 + c1 t^2 + c2 t + c3 at t, skipped where it is not finite or
// larger than |t| + 1 (the closed form loses digits in the smallest root when the roots
// spread over many orders of magnitude).
float msm6_newton(float c0, float c1, float c2, float c3, float t)
{
    float f = ((c0 * t + c1) * t + c2) * t + c3;
    float fp = (3.0 * c0 * t + 2.0 * c1) * t + c2;
    float step = f / fp;
    return (abs(step) <= abs(t) + 1.0 && abs(step) <= MSM6_FLT_MAX) ? t - step : t;
}

// cos(arccos(rho) / 3), the largest root of 4c^3 - 3c = rho, without trigonometric
// functions: with u = sqrt((1 + rho) / 2) it is cos(2/3 arccos u), analytic in u on [0, 1];
// a degree-6 polynomial in u holds it to 1.6e-7 (Horner; |.|: rho a little below -1 by
// rounding gives u ~ 0, not NaN).
float msm6_cos_third(float rho)
{
    float u = sqrt(abs(rho * 0.5 + 0.5));
    float c = u * -0.0021434685253637615;
    c = (c + 0.010623147312699203) * u;
    c = (c - 0.02653837949755497) * u;
    c = (c + 0.051548030727594105) * u;
    c = (c - 0.11082308230793778) * u;
    c = (c + 0.5773334661660559) * u;
    return c + 0.5000001629519066;
}

// Blinn's form of c0 t^3 + c1 t^2 + c2 t + c3 (Blinn, "How to solve a cubic equation";
// Peters, "How to solve a cubic equation, revisited"): (B, 2m, r) with the roots
// 2m cos(theta_k) - B, cos(3 theta) = r; B = c1/(3c0), C = c2/(3c0), D = c3/c0, the Hessian's
// d0 = C - B^2 (<= 0 for three real roots), m = sqrt(-d0), r = -(d1 - 2 B d0) / (2 m^3),
// d1 = D - B C.
float3 msm6_blinn(float c0, float c1, float c2, float c3)
{
    float c0_3 = 3.0 * c0;
    float B = c1 / c0_3;
    float C = c2 / c0_3;
    float D = c3 / c0;
    float d0 = C - B * B;
    float minus_dep = B * (C + 2.0 * d0) - D;
    float minus_d0 = abs(d0);  // rounding may leave d0 a little above 0
    float m2 = sqrt(4.0 * minus_d0);
    return float3(B, m2, minus_dep / (m2 * minus_d0));
}

// The largest (sigma = 1) or smallest (sigma = -1) root of a cubic with three real roots:
// sigma 2m cos(arccos(sigma r) / 3) - B (no Newton step in float32: the coefficients'
// rounding dominates).
float msm6_extreme_root(float c0, float c1, float c2, float c3, float sigma)
{
    float3 bmr = msm6_blinn(c0, c1, c2, c3);
    return sigma * bmr.y * msm6_cos_third(sigma * bmr.z) - bmr.x;
}

// The three real roots of c0 t^3 + c1 t^2 + c2 t + c3 (c0 != 0), Blinn's form with
// cos(theta) = c(r), cos(theta + 2 pi / 3) = -c(-r) and the middle one from their sum 0,
// then two Newton steps per root.
float3 msm6_solve_cubic(float c0, float c1, float c2, float c3)
{
    float3 bmr = msm6_blinn(c0, c1, c2, c3);
    // r clamped to [-1, 1]; NaN (0/0 at a triple root) counts as 1.
    float r = (bmr.z < -1.0) ? -1.0 : ((bmr.z <= 1.0) ? bmr.z : 1.0);
    float hi = msm6_cos_third(r);
    float lo = -msm6_cos_third(-r);
    float3 t = float3(hi, -hi - lo, lo) * bmr.y - bmr.x;
    for (int k = 0; k < 2; ++k) {
        t = float3(msm6_newton(c0, c1, c2, c3, t.x), msm6_newton(c0, c1, c2, c3, t.y),
                 msm6_newton(c0, c1, c2, c3, t.z));
    }
    return t;
}

// A weight that is not finite or not positive (a root at infinity) is 0.
float msm6_finite_weight(float w)
{
    return (w > 0.0 && w <= MSM6_FLT_MAX) ? w : 0.0;
}

// Weight of the support point z = zf + 1/t from step (4): w = 1 / sum_i (L^-1 v(z))_i^2 / D_i.
// A root at infinity (t = 0) or so far out that z^3 overflows has weight 0 (its NaN or 1/inf).
float msm6_weight(float t, float zf, float b1, float b2, float b3, float L21, float L31, float L32,
                  float D1, float D2, float D3)
{
    float z = zf + 1.0 / t;
    float z2 = z * z;
    // Forward substitution L u = v(z).
    float u1 = z - b1;
    float u2 = z2 - b2 - L21 * u1;
    float u3 = z2 * z - b3 - L31 * u1 - L32 * u2;
    float w = 1.0 / (1.0 + u1 * u1 / D1 + u2 * u2 / D2 + u3 * u3 / D3);
    return (w > 0.0) ? w : 0.0;
}

// Singular B(b): the unique distribution with these moments, exact Z(z < zf) (lower) and
// Z(z <= zf) (upper). One depth (D1 <= 0), two depths (D2 <= 0, HPG17 Algorithm 2 on
// b1..b3) or three depths (D3 <= 0: roots of the orthogonal polynomial (L^-1 v(z))_3 with
// Christoffel weights 1 / sum_(i<3) (L^-1 v(z_l))_i^2 / D_i).
void msm6_singular(float b1, float b2, float b3, float D1, float D2, float D3, float L21, float L31,
                   float L32, float zf, out float lower, out float at)
{
    float3 z = float3(b1, MSM6_FLT_MAX, MSM6_FLT_MAX);
    float3 w = float3(1.0, 0.0, 0.0);
    if (D1 > 0.0 && !(D2 > 0.0)) {
        // Two depths: roots of D1 z^2 + q1 z + q0 without cancellation, v2 by (5).
        float q1 = b1 * b2 - b3;
        float q0 = -b1 * q1 - b2 * D1;
        float disc = sqrt(max(q1 * q1 - 4.0 * D1 * q0, 0.0));
        float t = -0.5 * (q1 + (q1 < 0.0 ? -disc : disc));
        float y1 = min(t / D1, q0 / t);
        float y2 = max(t / D1, q0 / t);
        float v2 = clamp((b1 - y1) / (y2 - y1), 0.0, 1.0);
        if (abs(v2) <= 1.0)  // else no usable second depth: all mass at b1
            { z = float3(y1, y2, MSM6_FLT_MAX); w = float3(1.0 - v2, v2, 0.0); }
    } else if (D1 > 0.0) {
        // Three depths: z^3 - L32 z^2 + (L32 L21 - L31) z + (L31 b1 + L32 b2 - L32 L21 b1 - b3).
        z = msm6_solve_cubic(1.0, -L32, L32 * L21 - L31, L31 * b1 + L32 * b2 - L32 * L21 * b1 - b3);
        for (int l = 0; l < 3; ++l) {
            float u1 = z[l] - b1;
            float u2 = z[l] * z[l] - b2 - L21 * u1;
            w[l] = msm6_finite_weight(1.0 / (1.0 + u1 * u1 / D1 + u2 * u2 / D2));
        }
        w /= w.x + w.y + w.z;
    }
    lower = 0.0;
    at = 0.0;
    for (int l = 0; l < 3; ++l) {
        lower += (z[l] < zf) ? w[l] : 0.0;
        at += (z[l] == zf) ? w[l] : 0.0;
    }
}

// The six-moment bounds: lower = sharp lower bound of Z(z < zf), upper = sharp upper bound
// of Z(z <= zf), over all depth distributions with moments b (module comment, steps 1-5).
void msm6_bounds(float b[6], float zf, out float lower, out float upper)
{
    float b1 = b[0], b2 = b[1], b3 = b[2], b4 = b[3], b5 = b[4], b6 = b[5];
    // (1) B = L D L^T (the first column of L is (1, b1, b2, b3)); each L_ij D_j is kept as
    // the numerator it is divided from, so that L_ij^2 D_j = L_ij (L_ij D_j).
    float D1 = b2 - b1 * b1;
    float L21D1 = b3 - b1 * b2;
    float L31D1 = b4 - b1 * b3;
    float L21 = L21D1 / D1;
    float L31 = L31D1 / D1;
    float D2 = b4 - b2 * b2 - L21 * L21D1;
    float L32D2 = b5 - b2 * b3 - L21 * L31D1;
    float L32 = L32D2 / D2;
    float D3 = b6 - b3 * b3 - L31 * L31D1 - L32 * L32D2;
    float w0;
    if (!(D1 > 0.0) || !(D2 > 0.0) || !(D3 > 0.0)) {
        msm6_singular(b1, b2, b3, D1, D2, D3, L21, L31, L32, zf, lower, w0);
    } else {
        // (2) Forward substitution L y = v(zf), scaling c = D^-1 y, back substitution L^T q = c.
        float zf2 = zf * zf;
        float y1 = zf - b1;
        float y2 = zf2 - b2 - L21 * y1;
        float y3 = zf2 * zf - b3 - L31 * y1 - L32 * y2;
        float c1 = y1 / D1, c2 = y2 / D2, c3 = y3 / D3;
        float q3 = c3;
        float q2 = c2 - L32 * q3;
        float q1 = c1 - L21 * q2 - L31 * q3;
        // p(zf) = v^T B^-1 v = 1 / w0 (a sum of squares: no cancellation).
        float pz = 1.0 + y1 * c1 + y2 * c2 + y3 * c3;
        w0 = 1.0 / pz;
        // (3) Taylor coefficients of p at zf, reversed: P(t) = p t^3 + p' t^2 + p''/2 t + q3.
        float p2 = q2 + 3.0 * q3 * zf;
        float p1 = q1 + (q2 + p2) * zf;
        // How many of the three Gauss nodes (roots of P3) lie below zf: the Sturm sequence
        // (1, y1, y2, y3) changes sign once per node above zf. Its parity is the sign of y3;
        // "at least two below" is "the signs never turn back from - to +".
        bool pos1 = y1 >= 0.0, pos2 = y2 >= 0.0, pos3 = y3 >= 0.0;
        float two_below = ((pos1 || !pos2) && (pos2 || !pos3)) ? 1.0 : 0.0;
        float odd = pos3 ? 1.0 : 0.0;
        // The roots of p interlace with the Gauss nodes: the one root needed is the only root
        // below zf (one node below: the smallest t, t < 0 is z < zf) or the only one above (two
        // nodes below: the largest t).
        float t = msm6_extreme_root(pz, p1, p2, q3, 1.0 - 2.0 * odd);
        float w = msm6_weight(t, zf, b1, b2, b3, L21, L31, L32, D1, D2, D3);
        // (4), (5) lower = sum of w_l over z_l < zf: 0 (no node below), w (one), 1 - w0 - w
        // (two), 1 - w0 (three), so that three nodes below give 1 - w0 exactly.
        lower = (1.0 - w0) * two_below + w * (odd - two_below);
    }
    // Clamped like saturate (a NaN lower counts as 0, a NaN upper as 1).
    lower = (lower > 0.0) ? min(lower, 1.0) : 0.0;
    upper = (lower + w0 <= 1.0) ? lower + w0 : 1.0;
}

// Six-moment lower bound of Z(z < zf): the shadow intensity with six moments.
float shadow_intensity6_lower(float b[6], float zf)
{
    float lower, upper;
    msm6_bounds(b, zf, lower, upper);
    return lower;
}

// Six-moment upper bound of Z(z <= zf).
float shadow_intensity6_upper(float b[6], float zf)
{
    float lower, upper;
    msm6_bounds(b, zf, lower, upper);
    return upper;
}

#endif // MOMENTS_REF_MSM6_HLSL
