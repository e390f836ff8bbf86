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
//       vanishes; q3 -> 0 sends a root to infinity, which is t = 0 here, harmless)
//   (4) weights w_l = 1 / (v(z_l)^T B^-1 v(z_l)) (Peters and Klein 2015, Prop. 10)
//   (5) lower = sum of w_l over z_l < zf (that is t_l < 0); upper = lower + w0.
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

// The three real roots of c0 t^3 + c1 t^2 + c2 t + c3 (c0 != 0): the trigonometric
// solution of Blinn / Peters ("How to solve a cubic equation, revisited") with the
// Hessian (d0, d1, d2), then two Newton steps per root.
fn msm6_solve_cubic(c0: f32, c1: f32, c2: f32, c3: f32) -> vec3<f32> {
    let B = c1 / (3.0 * c0);
    let C = c2 / (3.0 * c0);
    let D = c3 / c0;
    let d0 = C - B * B;
    let d1 = D - B * C;
    let d2 = B * D - C * C;
    // Discriminant >= 0 for three real roots (rounding below 0 is clamped).
    let disc = max(4.0 * d0 * d2 - d1 * d1, 0.0);
    let dep = d1 - 2.0 * B * d0;
    let theta = atan2(sqrt(disc), -dep) / 3.0;
    let cs = cos(theta);
    let sn = sin(theta);
    let scale = 2.0 * sqrt(max(-d0, 0.0));
    var r = vec3<f32>(cs, -0.5 * cs + 0.8660254 * sn, -0.5 * cs - 0.8660254 * sn) * scale - B;
    for (var k = 0; k < 2; k++) {
        r = vec3<f32>(msm6_newton(c0, c1, c2, c3, r.x), msm6_newton(c0, c1, c2, c3, r.y),
                      msm6_newton(c0, c1, c2, c3, r.z));
    }
    return r;
}

// A weight that is not finite or not positive (a root at infinity) is 0.
fn msm6_finite_weight(w: f32) -> f32 {
    return select(0.0, w, w > 0.0 && w <= MSM6_FLT_MAX);
}

// Weight of the support point z = zf + 1/t from step (4): with g = t^3 v(zf + 1/t), a
// polynomial in t, w = t^6 / sum_i (L^-1 g)_i^2 / D_i is 0 (not NaN) at t = 0.
// l = (L21, L31, L32), d = (D1, D2, D3).
fn msm6_weight(t: f32, zf: f32, b1: f32, b2: f32, b3: f32, l: vec3<f32>, d: vec3<f32>) -> f32 {
    let s = 1.0 + zf * t;
    let g0 = t * t * t;
    // Forward substitution L u = g.
    let u1 = t * t * s - b1 * g0;
    let u2 = t * s * s - b2 * g0 - l.x * u1;
    let u3 = s * s * s - b3 * g0 - l.y * u1 - l.z * u2;
    let k = g0 * g0 + u1 * u1 / d.x + u2 * u2 / d.y + u3 * u3 / d.z;
    return msm6_finite_weight(g0 * g0 / k);
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
    // (1) B = L D L^T (the first column of L is (1, b1, b2, b3)).
    let D1 = b2 - b1 * b1;
    let L21 = (b3 - b1 * b2) / D1;
    let L31 = (b4 - b1 * b3) / D1;
    let D2 = b4 - b2 * b2 - L21 * L21 * D1;
    let L32 = (b5 - b2 * b3 - L21 * L31 * D1) / D2;
    let D3 = b6 - b3 * b3 - L31 * L31 * D1 - L32 * L32 * D2;
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
        let p1 = q1 + (2.0 * q2 + 3.0 * q3 * zf) * zf;
        let p2 = q2 + 3.0 * q3 * zf;
        let t = msm6_solve_cubic(pz, p1, p2, q3);
        // (4), (5) lower = sum of w_l over t_l < 0.
        for (var i = 0; i < 3; i++) {
            lower += select(0.0, msm6_weight(t[i], zf, b1, b2, b3, l, d), t[i] < 0.0);
        }
        w0 = select(0.0, w0, abs(w0) <= MSM6_FLT_MAX);
    }
    return vec2<f32>(clamp(lower, 0.0, 1.0), clamp(lower + w0, 0.0, 1.0));
}

// Six-moment lower bound of Z(z < zf): the shadow intensity with six moments.
fn shadow_intensity6_lower(b: array<f32, 6>, zf: f32) -> f32 {
    return msm6_bounds(b, zf).x;
}

// Six-moment upper bound of Z(z <= zf).
fn shadow_intensity6_upper(b: array<f32, 6>, zf: f32) -> f32 {
    return msm6_bounds(b, zf).y;
}
