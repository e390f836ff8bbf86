// Moment shadow mapping with six moments: the sharp lower and upper bounds of Z(z < zf)
// from b = (b1, ..., b6) (Peters and Klein 2015; used for prefiltered single scattering
// in the lecture slides, "Prefiltered single scattering with 6 moments").
//
// GLSL 4.30, float32. Part of moments_ref (the NumPy reference moments_ref/msm6.py is the
// oracle: `moments-ref conformance --glsl msm6.glsl --function NAME --case CASE`).
// Six moments do not fit a vec4: they are passed as float b[6] = (b1, ..., b6), b0 = 1
// implicit; bias them first (moments_ref.msm6.BIAS6_FLOAT32: alpha = 3e-4, target the
// moments of 0.4 delta_0 + 0.15 (delta_-1 + delta_1 + delta_-1/2 + delta_1/2)).
//
// The steps (as in msm6.py):
//   (1) B(b) = L D L^T, the 4x4 Hankel matrix B[i][j] = b_(i+j), D = diag(1, D1, D2, D3)
//   (2) solve B q = v(zf), v(z) = (1, z, z^2, z^3)
//   (3) the roots z_l of q3 z^3 + q2 z^2 + q1 z + q0, found as t_l = 1 / (z_l - zf), the
//       roots of P(t) = p(zf) t^3 + p'(zf) t^2 + p''(zf)/2 t + q3 (p(zf) = 1/w0 >= 1 never
//       vanishes; q3 -> 0 sends a root to infinity, which is t = 0 here, harmless)
//   (4) weights w_l = 1 / (v(z_l)^T B^-1 v(z_l)) (Peters and Klein 2015, Prop. 10)
//   (5) lower = sum of w_l over z_l < zf (that is t_l < 0); upper = lower + w0.

#ifndef MOMENTS_REF_MSM6_GLSL
#define MOMENTS_REF_MSM6_GLSL

const float MSM6_FLT_MAX = 3.4028235e38;

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

// The three real roots of c0 t^3 + c1 t^2 + c2 t + c3 (c0 != 0): the trigonometric
// solution of Blinn / Peters ("How to solve a cubic equation, revisited") with the
// Hessian (d0, d1, d2), then two Newton steps per root.
vec3 msm6_solve_cubic(float c0, float c1, float c2, float c3)
{
    float B = c1 / (3.0 * c0);
    float C = c2 / (3.0 * c0);
    float D = c3 / c0;
    float d0 = C - B * B;
    float d1 = D - B * C;
    float d2 = B * D - C * C;
    // Discriminant >= 0 for three real roots (rounding below 0 is clamped).
    float disc = max(4.0 * d0 * d2 - d1 * d1, 0.0);
    float dep = d1 - 2.0 * B * d0;
    float theta = atan(sqrt(disc), -dep) / 3.0;
    float cs = cos(theta);
    float sn = sin(theta);
    float scale = 2.0 * sqrt(max(-d0, 0.0));
    vec3 r = vec3(cs, -0.5 * cs + 0.8660254 * sn, -0.5 * cs - 0.8660254 * sn) * scale - B;
    for (int k = 0; k < 2; ++k) {
        r = vec3(msm6_newton(c0, c1, c2, c3, r.x), msm6_newton(c0, c1, c2, c3, r.y),
                 msm6_newton(c0, c1, c2, c3, r.z));
    }
    return r;
}

// A weight that is not finite or not positive (a root at infinity) is 0.
float msm6_finite_weight(float w)
{
    return (w > 0.0 && w <= MSM6_FLT_MAX) ? w : 0.0;
}

// Weight of the support point z = zf + 1/t from step (4): with g = t^3 v(zf + 1/t), a
// polynomial in t, w = t^6 / sum_i (L^-1 g)_i^2 / D_i is 0 (not NaN) at t = 0.
float msm6_weight(float t, float zf, float b1, float b2, float b3, float L21, float L31, float L32,
                  float D1, float D2, float D3)
{
    float s = 1.0 + zf * t;
    float g0 = t * t * t;
    // Forward substitution L u = g.
    float u1 = t * t * s - b1 * g0;
    float u2 = t * s * s - b2 * g0 - L21 * u1;
    float u3 = s * s * s - b3 * g0 - L31 * u1 - L32 * u2;
    float k = g0 * g0 + u1 * u1 / D1 + u2 * u2 / D2 + u3 * u3 / D3;
    return msm6_finite_weight(g0 * g0 / k);
}

// Singular B(b): the unique distribution with these moments, exact Z(z < zf) (lower) and
// Z(z <= zf) (upper). One depth (D1 <= 0), two depths (D2 <= 0, HPG17 Algorithm 2 on
// b1..b3) or three depths (D3 <= 0: roots of the orthogonal polynomial (L^-1 v(z))_3 with
// Christoffel weights 1 / sum_(i<3) (L^-1 v(z_l))_i^2 / D_i).
void msm6_singular(float b1, float b2, float b3, float D1, float D2, float D3, float L21, float L31,
                   float L32, float zf, out float lower, out float at)
{
    vec3 z = vec3(b1, MSM6_FLT_MAX, MSM6_FLT_MAX);
    vec3 w = vec3(1.0, 0.0, 0.0);
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
            { z = vec3(y1, y2, MSM6_FLT_MAX); w = vec3(1.0 - v2, v2, 0.0); }
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
    // (1) B = L D L^T (the first column of L is (1, b1, b2, b3)).
    float D1 = b2 - b1 * b1;
    float L21 = (b3 - b1 * b2) / D1;
    float L31 = (b4 - b1 * b3) / D1;
    float D2 = b4 - b2 * b2 - L21 * L21 * D1;
    float L32 = (b5 - b2 * b3 - L21 * L31 * D1) / D2;
    float D3 = b6 - b3 * b3 - L31 * L31 * D1 - L32 * L32 * D2;
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
        float p1 = q1 + (2.0 * q2 + 3.0 * q3 * zf) * zf;
        float p2 = q2 + 3.0 * q3 * zf;
        vec3 t = msm6_solve_cubic(pz, p1, p2, q3);
        // (4), (5) lower = sum of w_l over t_l < 0.
        lower = 0.0;
        for (int l = 0; l < 3; ++l) {
            float wl = msm6_weight(t[l], zf, b1, b2, b3, L21, L31, L32, D1, D2, D3);
            lower += (t[l] < 0.0) ? wl : 0.0;
        }
        w0 = (abs(w0) <= MSM6_FLT_MAX) ? w0 : 0.0;
    }
    upper = clamp(lower + w0, 0.0, 1.0);
    lower = clamp(lower, 0.0, 1.0);
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

#endif // MOMENTS_REF_MSM6_GLSL
