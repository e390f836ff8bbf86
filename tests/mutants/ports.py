"""Independent small ports of the core functions, written from the papers, in float32.

These do not import the functions they port (only ``numpy``): they are what a
porter would write from HPG17 and the slides. Each takes a mutation dictionary
``m``: an empty one is the port as intended; one key changed is a one-change
mutant (tests/mutants/corpus.py). ``Ar`` is the port's arithmetic: precision,
fused multiply-add, division and square root off by a number of ulps (the
GLSL/HLSL accuracy limits are 2.5 ulps for division, 3 for square root).
"""

from __future__ import annotations

import numpy as np

TINY32 = np.float32(np.finfo(np.float32).tiny)


class Ar:
    """Arithmetic of a port: ``dtype``, ``fma``, ``div_ulps``, ``sqrt_ulps``, ``half`` (float16 intermediates)."""

    def __init__(self, m):
        self.dt = np.float64 if m.get("f64") else np.float32
        self.fma_on = bool(m.get("fma"))
        self.div_ulps = int(m.get("div_ulps", 0))
        self.sqrt_ulps = int(m.get("sqrt_ulps", 0))
        self.half = bool(m.get("half"))

    def c(self, x):
        return np.asarray(x, dtype=self.dt)

    def h(self, x):
        """An intermediate stored in a variable (float16 if the port used half precision)."""
        x = np.asarray(x, self.dt)
        return x.astype(np.float16).astype(self.dt) if self.half else x

    @staticmethod
    def _nudge(x, k):
        x = np.asarray(x)
        for _ in range(abs(k)):
            x = np.nextafter(x, np.asarray(np.inf if k > 0 else -np.inf, x.dtype))
        return x

    def div(self, a, b):
        """``a / b`` off by ``div_ulps`` (exact where a and b are the same number: x/x = 1)."""
        a, b = np.broadcast_arrays(self.c(a), self.c(b))
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            q = a / b
            return np.where(a == b, q, self._nudge(q, self.div_ulps))

    def sqrt(self, x):
        with np.errstate(invalid="ignore"):
            return self._nudge(np.sqrt(self.c(x)), self.sqrt_ulps)

    def fma(self, a, b, c):
        """``a·b + c``: one rounding if fused, two otherwise."""
        if self.fma_on:
            return (np.asarray(a, np.float64) * np.asarray(b, np.float64) + np.asarray(c, np.float64)).astype(self.dt)
        return self.c(a) * self.c(b) + self.c(c)

    def out(self, x):
        """Results are written as float32 (a GPU port computing in double still stores float)."""
        return np.asarray(x).astype(np.float32)


def saturate(x):
    """HLSL ``saturate``: clamp to [0, 1], NaN -> 0."""
    x = np.asarray(x)
    return np.where(np.isnan(x), 0, np.clip(x, 0, 1)).astype(x.dtype)


# ---------------------------------------------------------------------------
# HPG17 §3.2: biasing


def bias(b, alpha, target, m):
    A = Ar(m)
    b = A.c(b)
    if m.get("missing"):
        return A.out(b)
    alpha = A.c(m.get("alpha", alpha))
    target = A.c(m.get("target", target))
    if m.get("rearranged"):  # b + α (b* − b)
        return A.out(A.fma(alpha, target - b, b))
    if m.get("sign"):
        return A.out((1 + alpha) * b - alpha * target)
    return A.out(A.fma(alpha, target, (1 - alpha) * b))


# ---------------------------------------------------------------------------
# HPG17 Algorithm 1 (4 moments, Hamburger), with the singular cases of B(b)


def _two_point_bound(b1, b2, b3, d22, zf, upper, A):
    """Singular B(b) of rank 2: two depths from b1..b3 (HPG17 Algorithm 2, steps 1-5)."""
    q1 = b1 * b2 - b3
    q0 = -b1 * q1 - b2 * d22
    disc = A.sqrt(np.maximum(q1 * q1 - 4 * d22 * q0, 0))
    t = -0.5 * (q1 + np.copysign(disc, q1))
    with np.errstate(divide="ignore", invalid="ignore"):
        ya, yb = t / d22, q0 / t
        y1, y2 = np.fmin(ya, yb), np.fmax(ya, yb)
        v2 = (b1 - y1) / (y2 - y1)
    hit = (lambda y: y <= zf) if upper else (lambda y: y < zf)
    return (1 - v2) * hit(y1) + v2 * hit(y2)


def alg1(b, zf, m, bound="lower"):
    A = Ar(m)
    upper = (bound == "upper") != bool(m.get("swap_bound"))
    b = A.h(A.c(b))
    zf = A.c(zf)
    if m.get("depth01"):
        zf = (zf + 1) / 2
    if m.get("bias_inside"):
        b = (1 - A.c(3e-7)) * b + A.c(3e-7) * A.c([0, 0.375, 0, 0.375])
    if "bias" in m:  # the engine's own bias inside the function: (alpha, target) in its depth convention
        alpha, target = m["bias"]
        b = (1 - A.c(alpha)) * b + A.c(alpha) * A.c(target)
    b1, b2, b3, b4 = (b[:, k] for k in range(4))
    with np.errstate(all="ignore"):
        # Cholesky factorization B = L D Lᵀ (only the non-trivial entries).
        d22 = A.fma(-b1, b1, b2) if not m.get("d22_sign") else A.fma(b1, b1, b2)
        l32d22 = A.fma(-b1, b2, b3)
        var2 = A.fma(-b2, b2, b4)
        d33d22 = A.fma(var2, d22, -l32d22 * l32d22)
        if "pivot_floor" in m:  # pivots floored at an absolute constant (a VSM-like fallback in the wild)
            d22 = np.maximum(d22, A.c(m["pivot_floor"]))
            d33d22 = np.maximum(d33d22, A.c(m["pivot_floor"]) * d22)
        if m.get("cholesky"):  # textbook Cholesky with square roots: NaN when a float32 pivot rounds below 0
            l22 = A.sqrt(b2 - b1 * b1)
            l32 = A.div(b3 - b1 * b2, l22)
            l33 = A.sqrt((b4 - b2 * b2) - l32 * l32)
            d22, d33d22 = l22 * l22, (l33 * l33) * (l22 * l22)
        inv_d22 = A.div(1, d22)
        l32 = l32d22 * inv_d22
        # Forward substitution L c1 = (1, zf, zf²), scaling D c2 = c1, backward substitution Lᵀ c3 = c2.
        c1 = zf - b1
        c2 = zf * zf - b2 - (0 if m.get("no_l32") else l32 * c1)
        c1 = c1 * inv_d22
        c2 = c2 * A.div(d22, d33d22)
        c1 = c1 - l32 * c2
        c0 = 1 - A.fma(b1, c1, b2 * c2)
        # Roots of c0 + c1 z + c2 z².
        if m.get("recip"):
            inv = A.div(1, c2)
            p, q = c1 * inv, c0 * inv
        else:
            p, q = A.div(c1, c2), A.div(c0, c2)
        d = p * p * (0.5 if m.get("quarter") else 0.25) - q
        r = A.sqrt(d)
        if m.get("literal_root"):  # -p/2 ∓ r: cancels for the root of smaller magnitude
            z1, z2 = -p * 0.5 - r, -p * 0.5 + r
        else:  # t without cancellation, the other root by Vieta (z1 z2 = q)
            t = -(p * 0.5 + np.copysign(r, p))
            za, zb = t, A.div(q, t)
            z1, z2 = np.fmin(za, zb), np.fmax(za, zb)
        if m.get("swap_roots"):
            z1, z2 = z2, z1
        # Weights of the canonical representation on (zf, z1, z2).
        w0 = A.div(z1 * z2 - b1 * (z1 + z2) + b2, (zf - z1) * (zf - z2))
        w1 = A.div(zf * z2 - b1 * (zf + z2) + b2, (z1 - zf) * (z1 - z2))
        w2 = A.div(zf * z1 - b1 * (zf + z1) + b2, (z2 - zf) * (z2 - z1))
        below = (lambda z: z <= zf) if m.get("le") else (lambda z: z < zf)
        if m.get("sum_weights"):
            lower = np.where(below(z1), w1, 0) + np.where(below(z2), w2, 0)
        else:
            lower = np.where(below(z2), 1 - w0, np.where(below(z1), w1, 0))
        res = lower + w0 if upper else lower
        if not m.get("no_singular"):
            two = _two_point_bound(b1, b2, b3, d22, zf, upper, A)
            one = (b1 <= zf) if (upper or m.get("le")) else (b1 < zf)
            res = np.where(d33d22 <= 0, two, res)
            res = np.where(d22 <= 0, one, res)
        if "factor" in m:  # a constant factor on the bound (a light-leak hack baked in)
            res = res * A.c(m["factor"])
        if m.get("early_exit"):  # "receiver at or before the mean: lit"
            res = np.where(zf <= b1, 0, res)
    if m.get("unclamped"):
        return A.out(1 - res if m.get("visibility") else res)
    res = saturate(res)
    return A.out(1 - res if m.get("visibility") else res)


# ---------------------------------------------------------------------------
# HPG17 §3.3: Ψ4 and Ψ4⁻¹


def _psi_constants(m):
    lo, hi = m.get("psi_lo", 1.2e-7), m.get("psi_hi", 0.25)
    if m.get("const32"):  # constants from float32 end points, each step rounded to float32
        f = np.float32
        c0 = np.log(np.log(f(lo) * f(1e7)))
        c1 = np.log(np.log(f(hi) * f(1e7))) - c0
        return f(lo), f(hi), f(c0), f(c1)
    with np.errstate(divide="ignore"):  # the mutant lo = 1e-7 gives ln ln 1 = -inf
        c0 = np.log(np.log(lo * 1e7))
    return lo, hi, c0, np.log(np.log(hi * 1e7)) - c0


def psi4(xi4, m, raw=False):
    A = Ar(m)
    lo, hi, c0, c1 = _psi_constants(m)
    lo_c = A.c(m.get("clamp", lo))
    if m.get("clamp_order"):
        x = A.h(np.minimum(np.maximum(A.c(xi4), lo_c), A.c(hi)))
    else:
        x = A.h(np.maximum(np.minimum(A.c(xi4), A.c(hi)), lo_c))
    log = np.log10 if m.get("log10") else np.log
    with np.errstate(all="ignore"):
        inner = np.log(x) + A.c(np.log(1e7)) if m.get("log_sum") else np.log(x * A.c(1e7))
        u = np.clip((log(inner) - A.c(c0)) * A.div(1, A.c(c1)), 0, 1)
    return u if raw else A.out(u)


def psi4_inverse(u, m, raw=False):
    A = Ar(m)
    lo, hi, c0, c1 = _psi_constants(m)
    u = A.c(u)
    with np.errstate(all="ignore"):
        if m.get("swap_c"):
            x = A.c(c1) + u * A.c(c0)
        else:
            x = A.fma(u, A.c(c1), A.c(c0))
        e = np.exp(x) if m.get("exp_once") else np.exp(np.exp(x))
        xi = e * A.c(1e-7)
    xi = np.clip(xi, A.c(lo), A.c(hi))
    return xi if raw else A.out(xi)


# ---------------------------------------------------------------------------
# HPG17 Algorithm 3 with the clamps of §3.4


def alg3(r, zf, m):
    A = Ar(m)
    r = A.c(r)
    y1, y2, v2, xi4 = (r[:, k] for k in range(4))
    zf = A.c(zf)
    if m.get("depth01"):
        zf = (zf + 1) / 2
    eps = A.c(m.get("clamp", 1e-6))
    with np.errstate(all="ignore"):
        if not m.get("no_v2_clamp"):
            v2 = np.maximum(v2, eps)
            if not m.get("no_upper_v2_clamp"):
                v2 = np.minimum(v2, 1 - eps)
        gap = y2 - y1 if m.get("no_gap_clamp") else np.maximum(y2 - y1, eps)
        zp = A.h(A.div(zf - y1, gap))
        g4 = gap * gap * gap * gap if m.get("gap_pow") else (gap * gap) * (gap * gap)
        if m.get("gap_cubed"):
            g4 = gap * gap * gap
        xip = A.div(xi4, g4) if m.get("no_xi_guard") else np.maximum(A.div(xi4, g4), A.c(TINY32))
        v1 = 1 - v2
        # Case y1 < zf ≤ y2: the smaller root of z² + q1 z + q0.
        q0 = -A.div(xip, v1 * zp)
        q1 = -q0 * A.div(v2 - zp, v2 - v2 * zp) - 1
        h, p = q1 * 0.5, -q0
        s = A.sqrt(h * h + p)
        if m.get("literal_root"):
            zl = -h - s
        else:  # no cancellation: −(h + s) for h ≥ 0, else Vieta's −P / (s − h)
            zl = np.where(h >= 0, -(h + s), -A.div(p, s - h))
        if m.get("zp_test"):  # the author's demo code: z'f < 1 on the clamped gap
            inside = zp < 1
        elif m.get("clamped_test"):  # the case test on the clamped y2
            inside = zf <= np.maximum(y2, y1 + eps)
        else:
            inside = (zf < y2) if m.get("lt_y2") else (zf <= y2)
        zl = np.where(inside, zl, zp)
        a, z2 = (1 - zl) * (1 - zl), zl * zl
        if m.get("swap_weights"):
            v1, v2 = v2, v1
        last = a * z2 * xip if m.get("xi_times") else A.div(a * z2, xip)
        wl = A.div(1, A.div(a, v1) + A.div(z2, v2) + last)
        res = np.where(inside, wl, 1 - wl)
        if not m.get("no_early_return"):
            res = np.where(zf <= y1, 0, res)
    return A.out(res if m.get("unclamped") else saturate(res))


# ---------------------------------------------------------------------------
# 64-bit texel (HPG17 §3.3): four UNORM16


def pack64(r, m):
    A = Ar(m)
    r = A.c(r)
    y1, y2, v2, xi4 = (np.clip(r[:, k], *rg) for k, rg in enumerate([(-1, 1), (-1, 1), (0, 1), (0, None)]))
    if m.get("swap_y"):
        y1, y2 = y2, y1
    s = A.c(65535)
    depth = (lambda y: np.floor((y + 1) * 0.5 * s)) if m.get("floor_depth") else (lambda y: np.rint((y + 1) * 0.5 * s))
    if m.get("depth01"):
        depth = lambda y: np.rint(np.clip(y, 0, 1) * s)  # noqa: E731
    u = psi4(xi4, {"f64": m.get("f64")}, raw=True)
    code = (np.rint(u * s) if m.get("round_xi") else np.ceil(u * s)).astype(np.int64)
    if not m.get("no_bump"):  # the decoded ξ4 must not be below the stored one
        dec = psi4_inverse(code.astype(A.dt) / s, {"f64": m.get("f64")}, raw=True)
        code = code + ((dec < np.clip(xi4, 1.2e-7, 0.25).astype(A.dt)) & (code < 65535))
    q = np.stack([depth(y1), depth(y2), np.rint(v2 * s), code], axis=-1)
    return q.astype(np.uint16)


def unpack64(q, m):
    A = Ar(m)
    c = A.c(np.asarray(q).astype(np.int64))
    s = A.c(65536 if m.get("scale_65536") else 65535)
    u = c * A.div(1, s) if m.get("recip") else A.div(c, s)
    y = (lambda x: x - 1) if m.get("y_half") else (lambda x: 2 * x - 1)
    v2 = u[:, 2] * u[:, 2] if m.get("v2_square") else u[:, 2]
    xi = psi4_inverse(u[:, 3], {"f64": m.get("f64"), "const32": m.get("const32")}).astype(A.dt)
    return A.out(np.stack([y(u[:, 0]), y(u[:, 1]), v2, xi], axis=-1))


# ---------------------------------------------------------------------------
# 32-bit texel (HPG17 §3.5, Figure 5)


def pack32(r, m):
    A = Ar(m)
    r = A.c(r)
    y1, y2, v2, xi4 = (np.clip(r[:, k], *rg) for k, rg in enumerate([(-1, 1), (-1, 1), (0, 1), (0, None)]))
    step = A.c(511.5)
    cell = (lambda y: np.rint(step * (y + 1))) if m.get("round_depth") else (lambda y: np.floor(step * (y + 1)))
    top = 1023 if m.get("no_clip_1023") else 1022
    t1, t2 = (np.clip(cell(y), 0, top).astype(np.int64) for y in (y1, y2))
    at = 511 if m.get("fold_511") else 512
    flip = t1 >= at
    f1 = np.where(flip, 1023 - t1, t1)
    f2 = np.where(flip, (1023 if m.get("fold_1023") else 1022) - t2, t2)
    sv = v2 if m.get("v_linear") else A.sqrt(v2)
    if m.get("v_127"):  # the grid of 127 steps, rounded (the format before schema 3)
        vcode = np.rint(sv * 127).astype(np.int64)
    else:  # cells of 1/128, truncated
        vcode = np.minimum(np.floor(sv * 128).astype(np.int64), 127)
    u = psi4(xi4, {"f64": m.get("f64")}, raw=True)
    xcode = np.minimum((np.rint(u * 63) if m.get("xi_63") else np.floor(u * 64)).astype(np.int64), 63)
    if not m.get("no_bump"):  # the decoded xi4, Psi4^-1((c + 1) / 64), must not be below the stored one
        dec = psi4_inverse(((xcode + 1) / 64).astype(A.dt), {"f64": m.get("f64")}, raw=True)
        xcode = xcode + ((dec < np.clip(xi4, 1.2e-7, 0.25).astype(A.dt)) & (xcode < 63))
    p = (f2 & 1023) | ((f1 & 511) << 10) | ((vcode & 127) << 19) | ((xcode & 63) << 26)
    return p.astype(np.uint32)


def unpack32(p, m):
    A = Ar(m)
    w = np.asarray(p).astype(np.int64)
    f2, f1 = w & 1023, (w >> 10) & 511
    vcode, xcode = (w >> 19) & 127, (w >> 26) & 63
    flipped = (f2 <= f1) if m.get("unfold_le") else (f2 < f1)
    if m.get("no_unfold"):
        flipped = np.zeros_like(flipped)
    t1, t2 = np.where(flipped, 1023 - f1, f1), np.where(flipped, 1022 - f2, f2)
    step = A.c(511 if m.get("step_511") else 511.5)
    # Depths at the upper end of their cell (HPG17 §3.5's "rounded up"); mutants: the corner, the centre.
    top = A.c(0 if m.get("corner") else 0.5 if m.get("centre") else 1)
    if m.get("recip"):
        y = lambda t: (A.c(t) + top) * A.div(1, step) - 1  # noqa: E731
    elif m.get("mad"):  # the HPG17 demo's form: t · (1/511.5) + (−1 + 2/1023)
        y = lambda t: A.c(t) * A.div(1, step) + A.c(-1 + 2 / 1023)  # noqa: E731
    else:
        y = lambda t: A.div(A.c(t) + top, step) - 1  # noqa: E731
    sv = A.div(A.c(vcode), 127) if m.get("v_127") else A.div(A.c(vcode) + A.c(0.5), 128)
    v2 = sv if m.get("v_linear") else sv * sv
    xoff = 0 if m.get("xi_no_roundup") else 0.5 if m.get("xi_centre") else 1
    u = A.div(A.c(xcode) + A.c(xoff), 64)
    xi = psi4_inverse(np.minimum(u, 1), {"f64": m.get("f64"), "const32": m.get("const32")}).astype(A.dt)
    return A.out(np.stack([y(t1), y(t2), v2, xi], axis=-1))


# ---------------------------------------------------------------------------
# Six moments (slides, "Prefiltered single scattering"): Hankel solve, cubic, weights


def msm6(b, zf, m, bound="lower"):
    A = Ar(m)
    b = A.c(b)
    zf = A.c(zf)
    n = len(zf)
    full = np.concatenate([np.ones((n, 1), A.dt), b], axis=1)
    shift = 1 if m.get("hankel_shift") else 0
    idx = np.minimum(np.add.outer(np.arange(4), np.arange(4)) + shift, 6)
    B = full[:, idx]
    sz = -zf if m.get("rhs_sign") else zf
    rhs = np.stack([np.ones(n, A.dt), sz, zf * zf, zf * zf * (sz if not m.get("rhs_zf2") else 1)], axis=1)
    with np.errstate(all="ignore"):
        if m.get("inverse"):
            q = np.einsum("nij,nj->ni", np.linalg.pinv(B), rhs)
        else:
            q = _solve(B, rhs)
        # Roots of q0 + q1 z + q2 z² + q3 z³: eigenvalues of the companion matrix.
        comp = np.zeros((n, 3, 3), A.dt)
        comp[:, 1, 0] = comp[:, 2, 1] = 1
        comp[:, :, 2] = -(q[:, :3] / q[:, 3:4])
        comp = np.where(np.isfinite(comp), comp, 0)
        z = np.sort(np.linalg.eigvals(comp).real.astype(A.dt), axis=1)
        nodes = np.concatenate([zf[:, None], z], axis=1)
        vander = nodes[:, None, :] ** np.arange(4)[None, :, None]
        w = _solve(vander, full[:, :4])
    below = (z <= zf[:, None]) if m.get("le") else (z < zf[:, None])
    lower = (w[:, 1:] * below).sum(axis=1)
    upper = (bound == "upper") != bool(m.get("swap_bound"))
    return A.out(saturate(lower + w[:, 0] if upper else lower))


def _solve(a, rhs):
    """Batched ``a x = rhs``; singular systems by least squares (pseudo-inverse)."""
    try:
        return np.linalg.solve(a, rhs[..., None])[..., 0]
    except np.linalg.LinAlgError:
        return np.einsum("nij,nj->ni", np.linalg.pinv(a), rhs)
