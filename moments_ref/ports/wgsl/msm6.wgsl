// Moment shadow mapping with six moments: the sharp lower and upper bounds of Z(z < zf)
// from b = (b1, ..., b6) (Peters and Klein 2015; used for prefiltered single scattering
// in the lecture slides, "Prefiltered single scattering with 6 moments").
//
// WGSL, f32. Part of moments_ref (the NumPy reference moments_ref/msm6.py is the
// oracle: `moments-ref conformance --wgsl msm6.wgsl --function NAME --case CASE`).
// Six moments do not fit a vec4: they are passed as b: array<f32, 6> = (b1, ..., b6), b0 = 1
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
// WGSL has no out parameters: msm6_bounds returns (lower, upper).

const MSM6_FLT_MAX: f32 = 3.4028235e38;

// One Newton step on c0 t^3 + c1 t^2 + c2 t + c3 at t, skipped where it is not finite or
// larger than |t| + 1 (the closed form loses digits in the smallest root when the roots
// spread over many orders of magnitude).
fn msm6_newton(c0: f32, c1: f32, c2: f32, c3: f32, t: f32) -> f32 {
    let f = ((c0 * t + c1) * t + c2) * t + c3;
    let fp = (3.0 * c0 * t + 2.0 * c1) * t + c2;
    let step = f / fp;
    return select(t, t - step, abs(step) <= abs(t) + 1.0 && abs(step) <= MSM6_FLT_MAX);
}

// cos(arccos(rho) / 3), the largest root of 4c^3 - 3c = rho, without trigonometric
// functions: with u = sqrt((1 + rho) / 2) it is cos(2/3 arccos u), analytic in u on [0, 1];
// a degree-6 polynomial in u holds it to 1.6e-7 (Horner; |.|: rho a little below -1 by
// rounding gives u ~ 0, not NaN).
fn msm6_cos_third(rho: f32) -> f32 {
    let u = sqrt(abs(rho * 0.5 + 0.5));
    var c = u * -0.0021434685253637615;
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
fn msm6_blinn(c0: f32, c1: f32, c2: f32, c3: f32) -> vec3<f32> {
    let c0_3 = 3.0 * c0;
    let B = c1 / c0_3;
    let C = c2 / c0_3;
    let D = c3 / c0;
    let d0 = C - B * B;
    let minus_dep = B * (C + 2.0 * d0) - D;
    let minus_d0 = abs(d0);  // rounding may leave d0 a little above 0
    let m2 = sqrt(4.0 * minus_d0);
    return vec3<f32>(B, m2, minus_dep / (m2 * minus_d0));
}

// The largest (sigma = 1) or smallest (sigma = -1) root of a cubic with three real roots:
// sigma 2m cos(arccos(sigma r) / 3) - B (no Newton step in float32: the coefficients'
// rounding dominates).
fn msm6_extreme_root(c0: f32, c1: f32, c2: f32, c3: f32, sigma: f32) -> f32 {
    let bmr = msm6_blinn(c0, c1, c2, c3);
    return sigma * bmr.y * msm6_cos_third(sigma * bmr.z) - bmr.x;
}

// The three real roots of c0 t^3 + c1 t^2 + c2 t + c3 (c0 != 0), Blinn's form with
// cos(theta) = c(r), cos(theta + 2 pi / 3) = -c(-r) and the middle one from their sum 0,
// then two Newton steps per root.
fn msm6_solve_cubic(c0: f32, c1: f32, c2: f32, c3: f32) -> vec3<f32> {
    let bmr = msm6_blinn(c0, c1, c2, c3);
    // r clamped to [-1, 1]; NaN (0/0 at a triple root) counts as 1.
    let r = select(select(1.0, bmr.z, bmr.z <= 1.0), -1.0, bmr.z < -1.0);
    let hi = msm6_cos_third(r);
    let lo = -msm6_cos_third(-r);
    var t = vec3<f32>(hi, -hi - lo, lo) * bmr.y - bmr.x;
    for (var k = 0; k < 2; k++) {
        t = vec3<f32>(msm6_newton(c0, c1, c2, c3, t.x), msm6_newton(c0, c1, c2, c3, t.y),
                      msm6_newton(c0, c1, c2, c3, t.z));
    }
    return t;
}

// A weight that is not finite or not positive (a root at infinity) is 0.
fn msm6_finite_weight(w: f32) -> f32 {
    return select(0.0, w, w > 0.0 && w <= MSM6_FLT_MAX);
}

// Weight of the support point z = zf + 1/t from step (4): w = 1 / sum_i (L^-1 v(z))_i^2 / D_i.
// A root at infinity (t = 0) or so far out that z^3 overflows has weight 0 (its NaN or 1/inf).
// l = (L21, L31, L32), d = (D1, D2, D3).
fn msm6_weight(t: f32, zf: f32, b1: f32, b2: f32, b3: f32, l: vec3<f32>, d: vec3<f32>) -> f32 {
    let z = zf + 1.0 / t;
    let z2 = z * z;
    // Forward substitution L u = v(z).
    let u1 = z - b1;
    let u2 = z2 - b2 - l.x * u1;
    let u3 = z2 * z - b3 - l.y * u1 - l.z * u2;
    let w = 1.0 / (1.0 + u1 * u1 / d.x + u2 * u2 / d.y + u3 * u3 / d.z);
    return select(0.0, w, w > 0.0);
}

// Singular B(b): the unique distribution with these moments; returns the exact
// (Z(z < zf), mass at zf). One depth (D1 <= 0), two depths (D2 <= 0, HPG17 Algorithm 2 on
// b1..b3) or three depths (D3 <= 0: roots of the orthogonal polynomial (L^-1 v(z))_3 with
// Christoffel weights 1 / sum_(i<3) (L^-1 v(z_l))_i^2 / D_i).
fn msm6_singular(b1: f32, b2: f32, b3: f32, l: vec3<f32>, d: vec3<f32>, zf: f32) -> vec2<f32> {
    var z = vec3<f32>(b1, MSM6_FLT_MAX, MSM6_FLT_MAX);
    var w = vec3<f32>(1.0, 0.0, 0.0);
    if (d.x > 0.0 && !(d.y > 0.0)) {
        // Two depths: roots of D1 z^2 + q1 z + q0 without cancellation, v2 by (5).
        let q1 = b1 * b2 - b3;
        let q0 = -b1 * q1 - b2 * d.x;
        let disc = sqrt(max(q1 * q1 - 4.0 * d.x * q0, 0.0));
        let t = -0.5 * (q1 + select(disc, -disc, q1 < 0.0));
        let y1 = min(t / d.x, q0 / t);
        let y2 = max(t / d.x, q0 / t);
        let v2 = clamp((b1 - y1) / (y2 - y1), 0.0, 1.0);
        if (abs(v2) <= 1.0) {  // else no usable second depth: all mass at b1
            z = vec3<f32>(y1, y2, MSM6_FLT_MAX);
            w = vec3<f32>(1.0 - v2, v2, 0.0);
        }
    } else if (d.x > 0.0) {
        // Three depths: z^3 - L32 z^2 + (L32 L21 - L31) z + (L31 b1 + L32 b2 - L32 L21 b1 - b3).
        z = msm6_solve_cubic(1.0, -l.z, l.z * l.x - l.y, l.y * b1 + l.z * b2 - l.z * l.x * b1 - b3);
        for (var i = 0; i < 3; i++) {
            let u1 = z[i] - b1;
            let u2 = z[i] * z[i] - b2 - l.x * u1;
            w[i] = msm6_finite_weight(1.0 / (1.0 + u1 * u1 / d.x + u2 * u2 / d.y));
        }
        w = w / (w.x + w.y + w.z);
    }
    var lower = 0.0;
    var at = 0.0;
    for (var i = 0; i < 3; i++) {
        lower += select(0.0, w[i], z[i] < zf);
        at += select(0.0, w[i], z[i] == zf);
    }
    return vec2<f32>(lower, at);
}

// The six-moment bounds (lower, upper): lower = sharp lower bound of Z(z < zf), upper =
// sharp upper bound of Z(z <= zf), over all depth distributions with moments b (steps 1-5).
fn msm6_bounds(b: array<f32, 6>, zf: f32) -> vec2<f32> {
    let b1 = b[0];
    let b2 = b[1];
    let b3 = b[2];
    let b4 = b[3];
    let b5 = b[4];
    let b6 = b[5];
    // (1) B = L D L^T (the first column of L is (1, b1, b2, b3)); each L_ij D_j is kept as
    // the numerator it is divided from, so that L_ij^2 D_j = L_ij (L_ij D_j).
    let D1 = b2 - b1 * b1;
    let L21D1 = b3 - b1 * b2;
    let L31D1 = b4 - b1 * b3;
    let L21 = L21D1 / D1;
    let L31 = L31D1 / D1;
    let D2 = b4 - b2 * b2 - L21 * L21D1;
    let L32D2 = b5 - b2 * b3 - L21 * L31D1;
    let L32 = L32D2 / D2;
    let D3 = b6 - b3 * b3 - L31 * L31D1 - L32 * L32D2;
    let l = vec3<f32>(L21, L31, L32);
    let d = vec3<f32>(D1, D2, D3);
    var lower = 0.0;
    var w0 = 0.0;
    if (!(D1 > 0.0) || !(D2 > 0.0) || !(D3 > 0.0)) {
        let s = msm6_singular(b1, b2, b3, l, d, zf);
        lower = s.x;
        w0 = s.y;
    } else {
        // (2) Forward substitution L y = v(zf), scaling c = D^-1 y, back substitution L^T q = c.
        let zf2 = zf * zf;
        let y1 = zf - b1;
        let y2 = zf2 - b2 - L21 * y1;
        let y3 = zf2 * zf - b3 - L31 * y1 - L32 * y2;
        let c1 = y1 / D1;
        let c2 = y2 / D2;
        let c3 = y3 / D3;
        let q3 = c3;
        let q2 = c2 - L32 * q3;
        let q1 = c1 - L21 * q2 - L31 * q3;
        // p(zf) = v^T B^-1 v = 1 / w0 (a sum of squares: no cancellation).
        let pz = 1.0 + y1 * c1 + y2 * c2 + y3 * c3;
        w0 = 1.0 / pz;
        // (3) Taylor coefficients of p at zf, reversed: P(t) = p t^3 + p' t^2 + p''/2 t + q3.
        let p2 = q2 + 3.0 * q3 * zf;
        let p1 = q1 + (q2 + p2) * zf;
        // How many of the three Gauss nodes (roots of P3) lie below zf: the Sturm sequence
        // (1, y1, y2, y3) changes sign once per node above zf. Its parity is the sign of y3;
        // "at least two below" is "the signs never turn back from - to +".
        let pos1 = y1 >= 0.0;
        let pos2 = y2 >= 0.0;
        let pos3 = y3 >= 0.0;
        let two_below = select(0.0, 1.0, (pos1 || !pos2) && (pos2 || !pos3));
        let odd = select(0.0, 1.0, pos3);
        // The roots of p interlace with the Gauss nodes: the one root needed is the only root
        // below zf (one node below: the smallest t, t < 0 is z < zf) or the only one above (two
        // nodes below: the largest t).
        let t = msm6_extreme_root(pz, p1, p2, q3, 1.0 - 2.0 * odd);
        let w = msm6_weight(t, zf, b1, b2, b3, l, d);
        // (4), (5) lower = sum of w_l over z_l < zf: 0 (no node below), w (one), 1 - w0 - w
        // (two), 1 - w0 (three), so that three nodes below give 1 - w0 exactly.
        lower = (1.0 - w0) * two_below + w * (odd - two_below);
    }
    // Clamped like saturate (a NaN lower counts as 0, a NaN upper as 1).
    lower = select(0.0, min(lower, 1.0), lower > 0.0);
    let upper = select(1.0, lower + w0, lower + w0 <= 1.0);
    return vec2<f32>(lower, upper);
}

// Six-moment lower bound of Z(z < zf): the shadow intensity with six moments.
fn shadow_intensity6_lower(b: array<f32, 6>, zf: f32) -> f32 {
    return msm6_bounds(b, zf).x;
}

// Six-moment upper bound of Z(z <= zf).
fn shadow_intensity6_upper(b: array<f32, 6>, zf: f32) -> f32 {
    return msm6_bounds(b, zf).y;
}
