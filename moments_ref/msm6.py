"""Moment shadow mapping with six moments: sharp bounds from b1..b6.

The six-moment analogue of HPG17 Algorithm 1 (Peters and Klein 2015, used for
prefiltered single scattering in the slides, "Prefiltered single scattering with
6 moments"): given ``b = (b1, ..., b6)`` of a depth distribution Z (b0 = 1) and a
fragment depth ``zf``, the sharp lower bound of ``Z(z < zf)`` over all
distributions with these moments is attained by a distribution with four points
of support ``zf, z1, z2, z3`` (the *canonical representation*); ``z1, z2, z3``
are the roots of the cubic ``q3 z³ + q2 z² + q1 z + q0`` with
``B(b) q = (1, zf, zf², zf³)`` and B(b) the 4×4 Hankel matrix ``B[i, j] = b_{i+j}``.

Algorithm (what the kernel does, step by step):

1. ``B(b) = L D Lᵀ`` (L unit lower triangular, ``D = diag(1, D1, D2, D3)``): the
   Cholesky factorization the slides insist on, without square roots.
2. Solve ``B q = v(zf)``, ``v(z) = (1, z, z², z³)``: forward substitution
   ``L y = v(zf)``, scaling ``c = D⁻¹ y``, back substitution ``Lᵀ q = c``.
3. The roots of ``p(z) = q3 z³ + q2 z² + q1 z + q0``. They are found as roots
   ``t_l = 1 / (z_l − zf)`` of the reversed Taylor polynomial at zf,

       P(t) = p(zf) t³ + p'(zf) t² + p''(zf)/2 t + q3,

   whose leading coefficient ``p(zf) = vᵀ B⁻¹ v = 1/w0 ≥ 1`` never vanishes
   (``q3``, the leading coefficient of p, does: then a root z runs off to
   infinity, which is ``t = 0`` here, harmless). ``t < 0`` is exactly
   ``z < zf``, so step 5 needs only the sign of t. The cubic is solved by the
   trigonometric method (Blinn; Peters, "How to solve a cubic equation,
   revisited") and polished by two Newton steps; all three roots are real for
   positive definite B (they are nodes of a Gauss–Radau quadrature).
4. Weights ``w_l = 1 / (v_lᵀ B⁻¹ v_l)`` (Peters and Klein 2015, Prop. 10, as
   :mod:`moments_ref.msm` uses), evaluated as ``Σ (L⁻¹ g)_i² / D_i`` with
   ``g = t³ v(zf + 1/t)``, a polynomial in t, so ``w = t⁶ / Σ (L⁻¹ g)_i² / D_i``
   is 0 (not NaN) at a root at infinity. ``w0 = 1 / Σ y_i² / D_i``.
5. ``lower = Σ_{z_l < zf} w_l = Σ_{t_l < 0} w_l``; ``upper = lower + w0``.

The mpmath twin :func:`moments_ref.precise.shadow_intensity6` does steps 2–4
literally (``lu_solve``, ``polyroots`` on q, a Vandermonde solve) and serves as
the independent check.

Cubic solver: measured on 20 000 biased random six-moment cases (float64,
:func:`cubic_solver_benchmark`), the trigonometric method with two Newton steps
is as accurate as the companion-matrix eigenvalues of ``np.linalg.eigvals``
(largest error relative to the largest root, against ``mpmath.polyroots`` on 200
of them: 1.0e-14 trigonometric, 2.2e-14 eigvals) and five times faster (4.9 ms
against 26.5 ms), and it stays in the working dtype (float32 for float32 input,
as a shader would).

Degenerate input. When ``B(b)`` is singular the distribution with these moments
is unique (at most three distinct depths) and ``Z(z < zf)`` is known exactly;
both bounds return it (``upper = Z(z ≤ zf)``):

* ``D1 = b2 − b1² ≤ τ·b2``: one depth at b1;
* else ``D2 ≤ τ·max(b4, D1)``: the two-point distribution of b1..b3 (HPG17
  Algorithm 2, shared with :mod:`moments_ref.msm`);
* else ``D3 ≤ τ·max(b6, D2)``: three depths, the roots of the monic orthogonal
  polynomial ``(L⁻¹ v(z))_3`` with Christoffel weights
  ``1 / Σ_{i<3} (L⁻¹ v(z_l))_i² / D_i`` (Gauss quadrature with three nodes).

``τ = SINGULAR_RTOL[dtype]·eps`` with the same values and the same reasoning as
:mod:`moments_ref.msm`: ``8·eps`` in float64 (moments of at most three depths
computed in float64 round to pivots of that size; biased moments lie orders of
magnitude above), ``0`` in float32 (a positive threshold would catch biased
float32 moments whose last pivot is of the size of float32's rounding of b6 and
replace the bound by a hard step at a rounded support point). Negative pivots
(moments just outside the moment space after rounding or quantization) fall into
the same branches: the moments are projected onto the boundary of the moment
space, keeping b1..b5 (or b1..b3, or b1).

Bias. The slides give no six-moment bias; this module ships two presets built
like HPG17 §3.2 (``b' = (1 − α) b + α b*``) with the target ``b*`` the moments
of the symmetric five-point distribution
``0.4 δ0 + 0.15 (δ−1 + δ1 + δ−1/2 + δ1/2)`` (:data:`BIAS6_TARGET`; five points, so
B(b*) is positive definite: the six-moment sibling of HPG17's
``(0, 0.375, 0, 0.375)``, the moments of a three-point distribution):

* :data:`BIAS6_FLOAT64` (α = 3e-7, as HPG17's BIAS_FLOAT32) for float64
  arithmetic: the last pivot D3 of biased moments is at least about
  ``α·D3(b*) = 1e-8`` (D3(b*) = 0.034), far above float64 rounding.
* :data:`BIAS6_FLOAT32` (α = 3e-4) for float32 moments and arithmetic. α = 3e-7
  is useless there: D3 of biased moments (≈ 1e-8) is below float32's rounding
  of the pivots (≈ 1e-7), and bounds of three-point distributions at their
  support points came out up to 1.0 above Z. Measured on 4000 stiff cases (1–6
  depths, clustered, at ±1; zf at and next to every support point), the worst
  ``lower − Z(z < zf)`` / ``Z(z ≤ zf) − upper`` is 1.0 / 1.0 for α = 3e-7,
  2.1e-3 / 6.6e-3 for 1e-5, 1.2e-3 / 2.2e-3 for 1e-4, 2.5e-4 / 6.9e-4 for 3e-4,
  8.5e-4 / 8.5e-4 for 1e-3.
* :data:`BIAS6_UNORM10` (α = 1e-3, the 2×R10G10B10A2 storage of the slides).
  Two measurements decided it. (a) :func:`measure_unorm10_bias` (4000 quantized
  moment vectors of 1–6 random depths): the share inside the moment space after
  biasing is 75.8 % for α = 1e-3, 93.5 % for 2e-3, 99.0 % for 3e-3, 100 % for
  5e-3. (b) The shipped ``scattering`` scene (shadow map 256², 160×90 pixels,
  epipolar map 128×256, ray-marching reference with 1024 samples): RMSE of the
  normalized scattering term 0.0141, 0.0142, 0.0146, 0.0151, 0.0159, 0.0178 for
  α = 1e-5, 1e-4, 5e-4, 1e-3, 2e-3, 5e-3 (ignoring all shadows: 0.0451).
  The slides: "rounding errors are less malicious for single scattering": the
  prefix means are averages of many texels and lie well inside the moment
  space; a vector outside it is projected onto its boundary (singular branch,
  exact Z of the projection, never NaN), which costs less than a strong bias
  smearing every bound. α = 1e-3 keeps three quarters of even single-texel
  vectors inside at an RMSE cost of 0.001.

References
----------
HPG17, Slides, Peters and Klein 2015 : see docs/bib.md.
"""

from __future__ import annotations

import time

import numpy as np

from ._arrays import InputError, brief, broadcast_pair, check_broadcast, first_index, real_input
from .moments import BiasPreset, power_moments
from ._kernels import SINGULAR_RTOL, broadcast_chunks, singular_thresholds
from ._kernels import two_point as _two_point

__all__ = [
    "shadow_intensity",
    "shadow_bounds",
    "canonical_representation",
    "pivots",
    "solve_cubic",
    "BIAS6_TARGET",
    "BIAS6_FLOAT64",
    "BIAS6_FLOAT32",
    "BIAS6_UNORM10",
    "measure_unorm10_bias",
    "cubic_solver_benchmark",
]

#: Target of the six-moment bias: moments of 0.4 δ0 + 0.15 (δ−1 + δ1) + 0.15 (δ−1/2 + δ1/2),
#: a symmetric five-point distribution on [-1, 1] (B(b*) is positive definite: 5 > 4 points).
BIAS6_TARGET = tuple(float(x) for x in power_moments(np.array([0.0, -1.0, 1.0, -0.5, 0.5]),
                                                     np.array([0.4, 0.15, 0.15, 0.15, 0.15]), n=6))
#: Six moments in float64 arithmetic (α as HPG17's BIAS_FLOAT32).
BIAS6_FLOAT64 = BiasPreset(3e-7, BIAS6_TARGET, "float64x6")
#: Six moments in float32 storage and arithmetic (module docstring: α = 3e-7 is too weak there).
BIAS6_FLOAT32 = BiasPreset(3e-4, BIAS6_TARGET, "float32x6")
#: Six moments in 2×R10G10B10A2_UNORM (Slides, "6 moments"), α by :func:`measure_unorm10_bias`.
BIAS6_UNORM10 = BiasPreset(1e-3, BIAS6_TARGET, "unorm10x6")

_SQRT3_2 = np.sqrt(3.0) / 2


# ---------------------------------------------------------------------------
# the cubic


def solve_cubic(c0, c1, c2, c3, newton=2):
    """Real roots of ``c0 t³ + c1 t² + c2 t + c3`` known to have three real roots.

    Parameters
    ----------
    c0, c1, c2, c3 : (n,) float arrays
        Coefficients, highest power first, finite and broadcastable; ``c0``
        decides the dtype (the others are cast to it) and must be non-zero (in
        this module it is ``1/w0 ≥ 1`` or 1). Anything else raises
        :class:`~moments_ref.InputError`.
    newton : int
        Newton steps (0..100) on the original polynomial after the closed form.

    Returns
    -------
    roots : (3, n) float array, dtype of the input, ``roots[0] ≥ roots[1] ≥ roots[2]``
        up to the Newton polish.

    Notes
    -----
    Trigonometric solution in the form of Peters' "SolveCubic" (Blinn, "How to
    solve a cubic equation"): with ``B = c1/(3c0)``, ``C = c2/(3c0)``,
    ``D = c3/c0``, the Hessian ``Δ = (C − B², D − BC, BD − C²)``, the
    discriminant ``4 Δ0 Δ2 − Δ1²`` (≥ 0 for three real roots; rounding below 0 is
    clamped), ``θ = atan2(√disc, −(Δ1 − 2BΔ0))/3`` and roots
    ``2√(−Δ0)·(cos θ, cos(θ + 2π/3), cos(θ − 2π/3)) − B``.
    """
    c0 = real_input(c0, "c0")
    cs = [c0] + [real_input(c, name, dtype=c0.dtype) for c, name in ((c1, "c1"), (c2, "c2"), (c3, "c3"))]
    try:
        shape = np.broadcast_shapes(*(c.shape for c in cs))
    except ValueError:
        raise InputError(f"c0..c3: expected broadcastable shapes, got {[c.shape for c in cs]}") from None
    check_broadcast(shape, [c.shape for c in cs], f"c0..c3 {[c.shape for c in cs]}")
    zero = c0 == 0
    if zero.any():
        idx = first_index(zero)
        raise InputError(f"c0: expected a non-zero leading coefficient, got 0 at index {idx}")
    if isinstance(newton, bool) or not isinstance(newton, (int, np.integer)) or not 0 <= newton <= 100:
        raise InputError(f"newton: expected an integer in 0..100, got {newton!r}")
    return _solve_cubic(*(np.broadcast_to(c, shape) for c in cs), newton=int(newton))


def _solve_cubic(c0, c1, c2, c3, newton=2):
    """:func:`solve_cubic` without validation (the kernels' path)."""
    dt = c0.dtype.type
    B = c1 / (3 * c0)
    C = c2 / (3 * c0)
    D = c3 / c0
    d0 = C - B * B
    d1 = D - B * C
    d2 = B * D - C * C
    disc = np.maximum(4 * d0 * d2 - d1 * d1, dt(0))
    dep = d1 - 2 * B * d0  # constant coefficient of the depressed cubic (times 1)
    theta = np.arctan2(np.sqrt(disc), -dep) / dt(3)
    cs, sn = np.cos(theta), np.sin(theta)
    scale = 2 * np.sqrt(np.maximum(-d0, dt(0)))
    r = np.stack([cs, -0.5 * cs + dt(_SQRT3_2) * sn, -0.5 * cs - dt(_SQRT3_2) * sn]).astype(c0.dtype)
    r = r * scale - B
    # Newton polish on c0 t³ + c1 t² + c2 t + c3: the closed form loses digits in the
    # root of smallest magnitude when the roots spread over many orders of magnitude.
    with np.errstate(divide="ignore", invalid="ignore"):
        for _ in range(newton):
            f = ((c0 * r + c1) * r + c2) * r + c3
            fp = (3 * c0 * r + 2 * c1) * r + c2
            step = f / fp
            keep = np.isfinite(step) & (np.abs(step) <= np.abs(r) + 1)
            if not keep.all():  # np.where(keep, step, 0), without the full copy when every step is kept
                step[~keep] = 0
            r = r - step
    return r


# ---------------------------------------------------------------------------
# the kernel


def _ldl(b1, b2, b3, b4, b5, b6):
    """LDLᵀ of the 4×4 Hankel matrix: (D1, D2, D3, L21, L31, L32); L10..L30 = b1..b3."""
    D1 = b2 - b1 * b1
    L21 = (b3 - b1 * b2) / D1
    L31 = (b4 - b1 * b3) / D1
    D2 = b4 - b2 * b2 - L21 * L21 * D1
    L32 = (b5 - b2 * b3 - L21 * L31 * D1) / D2
    D3 = b6 - b3 * b3 - L31 * L31 * D1 - L32 * L32 * D2
    return D1, D2, D3, L21, L31, L32


def _forward(g0, g1, g2, g3, b1, b2, b3, L21, L31, L32):
    """Forward substitution L u = g (u0 = g0)."""
    u1 = g1 - b1 * g0
    u2 = g2 - b2 * g0 - L21 * u1
    u3 = g3 - b3 * g0 - L31 * u1 - L32 * u2
    return g0, u1, u2, u3


def _kernel(b, zf):
    """Bounds and canonical representation on flat chunks: b (6, n) rows, zf (n,)."""
    dt = b.dtype.type
    one, zero = dt(1), dt(0)
    b1, b2, b3, b4, b5, b6 = b
    rtol = dt(singular_thresholds(b.dtype))
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        # (1) B = L D Lᵀ.
        D1, D2, D3, L21, L31, L32 = _ldl(b1, b2, b3, b4, b5, b6)
        single = D1 <= rtol * b2
        two = ~single & ~(D2 > rtol * np.maximum(b4, D1))
        three = ~single & ~two & ~(D3 > rtol * np.maximum(b6, D2))
        singular = single | two | three
        # (2) L y = v(zf), c = D⁻¹ y, Lᵀ q = c.
        zf2 = zf * zf
        _, y1, y2, y3 = _forward(one, zf, zf2, zf2 * zf, b1, b2, b3, L21, L31, L32)
        c1, c2, c3 = y1 / D1, y2 / D2, y3 / D3
        q3 = c3
        q2 = c2 - L32 * q3
        q1 = c1 - L21 * q2 - L31 * q3
        q0 = one - b1 * q1 - b2 * q2 - b3 * q3
        # p(zf) = vᵀ B⁻¹ v = 1/w0 (the sum of squares, not Horner: no cancellation).
        pz = one + y1 * c1 + y2 * c2 + y3 * c3
        w0 = one / pz
        # (3) Taylor coefficients of p at zf, reversed: P(t) = p t³ + p' t² + p''/2 t + q3.
        p1 = q1 + (2 * q2 + 3 * q3 * zf) * zf
        p2 = q2 + 3 * q3 * zf
        ok = ~singular
        pairs = ((pz, one), (p1, zero), (p2, -one), (q3, zero))
        # np.where(ok, x, y); when no row is singular that is x itself (no copies).
        cf = [x for x, _ in pairs] if ok.all() else [np.where(ok, x, y) for x, y in pairs]
        t = _solve_cubic(*cf)  # (3, n); placeholder cubic t³ − t for singular rows
        # (4) weights w = t⁶ / Σ (L⁻¹ g)_i² / D_i, g = t³ v(zf + 1/t) = (t³, t²(1 + zf t), t(1 + zf t)², (1 + zf t)³).
        s = 1 + zf * t
        g = (t * t * t, t * t * s, t * s * s, s * s * s)
        u0, u1, u2, u3 = _forward(*g, b1, b2, b3, L21, L31, L32)
        k = u0 * u0 + u1 * u1 / D1 + u2 * u2 / D2 + u3 * u3 / D3
        t3 = g[0]
        w = t3 * t3 / k
        bad = ~(np.isfinite(w) & (w > 0))
        if bad.any():  # np.where(finite and positive, w, 0), in place
            w[bad] = zero
        z = zf + one / t  # ±inf for t = ±0
        # (5) lower = Σ_{z_l < zf} w_l.
        lower = (w * (t < 0)).sum(axis=0)
        w0[~np.isfinite(w0)] = zero  # np.where(isfinite, w0, 0), in place
    if singular.any():
        lower, w0, z, w = _singular(b, zf, single, two, three, singular, lower, w0, z, w,
                                    (D1, D2, L21, L31, L32))
    upper = np.clip(lower + w0, zero, one)
    lower = np.clip(lower, zero, one)
    return lower, upper, w0, z, w


def _singular(b, zf, single, two, three, singular, lower, w0, z, w, ldl):
    """The unique distribution of singular B(b) (module docstring), written into the outputs."""
    dt = b.dtype.type
    one = dt(1)
    b1, b2, b3, b4, b5, b6 = (x[singular] for x in b)
    D1, D2, L21, L31, L32 = (x[singular] for x in ldl)
    sg, tw, th = single[singular], two[singular], three[singular]
    m = b1.shape[0]
    pts = np.full((3, m), np.inf, dtype=b.dtype)
    wts = np.zeros((3, m), dtype=b.dtype)
    # one depth at b1
    pts[0, sg] = b1[sg]
    wts[0, sg] = one
    # two depths: HPG17 Algorithm 2 on b1..b3
    if tw.any():
        y1, y2, v2 = _two_point(b1[tw], b2[tw], b3[tw], D1[tw])
        pts[0, tw], pts[1, tw] = y1, y2
        wts[0, tw], wts[1, tw] = 1 - v2, v2
    # three depths: roots of the monic orthogonal polynomial u3(z) = (L⁻¹ v(z))_3 =
    # z³ − L32 z² + (L32 L21 − L31) z + (L31 b1 + L32 b2 − L32 L21 b1 − b3).
    if th.any():
        a1, a2, a3, l21, l31, l32 = b1[th], b2[th], b3[th], L21[th], L31[th], L32[th]
        d1, d2 = D1[th], D2[th]
        r = _solve_cubic(np.ones_like(a1), -l32, l32 * l21 - l31, l31 * a1 + l32 * a2 - l32 * l21 * a1 - a3)
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            u0, u1, u2, _ = _forward(np.ones_like(r), r, r * r, r * r * r, a1, a2, a3, l21, l31, l32)
            lam = one / (u0 * u0 + u1 * u1 / d1 + u2 * u2 / d2)  # Christoffel numbers
        lam = np.where(np.isfinite(lam) & (lam > 0), lam, 0)
        lam = lam / lam.sum(axis=0)
        pts[:, th] = r
        wts[:, th] = lam
    zs = zf[singular]
    lt = (wts * (pts < zs)).sum(axis=0)
    at = (wts * (pts == zs)).sum(axis=0)
    lower[singular] = lt
    w0[singular] = at
    z[:, singular] = pts
    w[:, singular] = np.where(pts == zs, 0, wts)
    return lower, w0, z, w


def _prepare(b, zf):
    b = real_input(b, "b", trailing=6)
    zf = real_input(zf, "zf", dtype=b.dtype)
    shape = broadcast_pair(b[..., 0], "b[..., 0]", zf, "zf")
    return b, zf, shape


def _run(b, zf, want):
    """The kernel over chunks; only the outputs named in ``want`` are allocated.

    ``want`` is drawn from lower, upper, w0 (n,) and z, w (n, 3); returns
    ``(dict, zf, shape)``.
    """
    b, zf, shape = _prepare(b, zf)
    n = int(np.prod(shape, dtype=np.int64))
    outs = {k: np.empty((n, 3) if k in ("z", "w") else n, dtype=b.dtype) for k in want}
    for start, stop, bc, zc in broadcast_chunks(b, zf, shape):
        lo, up, ww0, zz, wl = _kernel(bc, zc)
        res = {"lower": lo, "upper": up, "w0": ww0, "z": zz.T, "w": wl.T}
        for k in want:
            outs[k][start:stop] = res[k]
    return outs, zf, shape


def shadow_bounds(b, zf):
    """Both sharp bounds from six moments: ``(lower, upper)``.

    Parameters
    ----------
    b : (..., 6) float array
        Moments b1..b6 (b0 = 1 implicit), normally biased
        (:data:`BIAS6_FLOAT64`, :data:`BIAS6_FLOAT32`, :data:`BIAS6_UNORM10`).
    zf : (...) float array
        Fragment depth, broadcast against ``b[..., 0]``; cast to b's dtype.

    Returns
    -------
    lower, upper : (...) float arrays in [0, 1], dtype of ``b``
        Sharp lower bound of Z(z < zf) and sharp upper bound of Z(z ≤ zf).
    """
    outs, _, shape = _run(b, zf, ("lower", "upper"))
    return outs["lower"].reshape(shape), outs["upper"].reshape(shape)


def shadow_intensity(b, zf, bound="lower"):
    """Sharp bound of ``Z(z < zf)`` (or of ``Z(z ≤ zf)``) from six moments.

    Parameters
    ----------
    b : (..., 6) float array
        Moments b1..b6, normally biased.
    zf : (...) float array
        Fragment depth, broadcast against ``b[..., 0]``.
    bound : {"lower", "upper"}

    Returns
    -------
    intensity : (...) float array in [0, 1], dtype of ``b``

    Notes
    -----
    The six-moment analogue of HPG17 Algorithm 1 (module docstring, steps 1–5);
    singular B(b) gives the exact Z of the unique distribution. Clamped to
    [0, 1] like ``saturate``.

    Examples
    --------
    Three depths are the unique distribution of their six moments (exact):

    >>> b = power_moments([-0.5, 0.0, 0.5], n=6)
    >>> shadow_intensity(b, [-0.6, -0.25, 0.25, 0.6]).round(12)
    array([0.        , 0.33333333, 0.66666667, 1.        ])
    """
    if bound not in ("lower", "upper"):
        raise InputError(f"bound: expected 'lower' or 'upper', got {bound!r}")
    outs, _, shape = _run(b, zf, (bound,))  # only the requested bound: peak ≈ output + one chunk
    return outs[bound].reshape(shape)


def canonical_representation(b, zf):
    """The four-point distribution attaining the six-moment bounds.

    Parameters
    ----------
    b : (..., 6) float array
    zf : (...) float array

    Returns
    -------
    depths : (..., 4) float array
        ``(zf, z1, z2, z3)``, ``z1 ≤ z2 ≤ z3``; a root may be ±inf (weight 0)
        when zf is a support point of a three-point representation. For singular
        B(b) the unique distribution's depths (unused slots +inf, weight 0).
    weights : (..., 4) float array
        ``(w0, w1, w2, w3)`` non-negative, summing to 1, with
        ``Σ w_l z_l^k = b_k`` for k = 0..6 (k ≤ 5 for the root at infinity).
        Mass at a support point equal to zf is moved to w0.
    """
    outs, zf, shape = _run(b, zf, ("w0", "z", "w"))
    w0, z, w = outs["w0"], outs["z"], outs["w"]
    zflat = np.broadcast_to(zf, shape).reshape(-1)
    order = np.argsort(z, axis=-1, kind="stable")
    z = np.take_along_axis(z, order, axis=-1)
    w = np.take_along_axis(w, order, axis=-1)
    depths = np.concatenate([zflat[:, None], z], axis=-1).reshape(shape + (4,))
    weights = np.concatenate([w0[:, None], w], axis=-1).reshape(shape + (4,))
    return depths, weights


def pivots(b):
    """The pivots ``(D1, D2, D3)`` of ``B(b) = L D Lᵀ`` (4×4 Hankel), dtype of b.

    After a pivot the kernel counts as singular (``D1 ≤ τ·b2``, ``D2 ≤ τ·max(b4, D1)``,
    module docstring) the later pivots are 0, as for the moments of one or two
    depths, instead of the 0/0 of the elimination.

    >>> pivots(power_moments([0.5], n=6))
    array([0., 0., 0.])
    """
    b = real_input(b, "b", trailing=6)
    rtol = b.dtype.type(singular_thresholds(b.dtype))
    b1, b2, b3, b4, b5, b6 = np.moveaxis(b, -1, 0)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        D1, D2, D3, *_ = _ldl(b1, b2, b3, b4, b5, b6)
    single = D1 <= rtol * b2
    D2 = np.where(single, 0, D2).astype(b.dtype)
    D3 = np.where(single | (D2 <= rtol * np.maximum(b4, D1)), 0, D3).astype(b.dtype)
    return np.stack([D1, D2, D3], axis=-1)


# ---------------------------------------------------------------------------
# measurements behind the documented choices


#: Most draws the measurements below accept (about 1 GiB of float64 temporaries).
MAX_DRAWS = 10_000_000


def _count(value, name, lo=1, hi=MAX_DRAWS):
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not lo <= value <= hi:
        raise InputError(f"{name}: expected an integer in [{lo}, {hi}], got {brief(value)}")
    return int(value)


def _draws(n, seed):
    """``n`` checked and a generator seeded with ``seed`` (a non-negative integer)."""
    n = _count(n, "n")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise InputError(f"seed: expected a non-negative integer, got {brief(seed)}")
    return n, np.random.default_rng(int(seed))


def measure_unorm10_bias(alphas=(1e-3, 2e-3, 3e-3, 5e-3), n=4000, seed=0):
    """Share of 2×R10G10B10A2-quantized moments inside the moment space after biasing.

    Draws distributions of 1..6 depths in [-1, 1] (random weights), quantizes their
    six moments (:func:`moments_ref.affine.encode_r10g10b10a2`), decodes and biases
    them with each α and the target :data:`BIAS6_TARGET`, and counts the vectors
    whose Hankel pivots are all positive.

    Returns
    -------
    dict α -> fraction inside
    """
    from .affine import decode_r10g10b10a2, encode_r10g10b10a2
    from .moments import bias_moments

    n, rng = _draws(n, seed)
    alphas = [float(real_input(a, "alphas", dtype=np.float64)) for a in np.atleast_1d(np.asarray(alphas, object))]
    k = rng.integers(1, 7, n)
    z = rng.uniform(-1, 1, (n, 6))
    wt = rng.uniform(0.05, 1, (n, 6)) * (np.arange(6) < k[:, None])
    b = power_moments(z, wt, n=6)
    bq = decode_r10g10b10a2(encode_r10g10b10a2(b))
    out = {}
    for a in alphas:
        p = pivots(bias_moments(bq, BiasPreset(a, BIAS6_TARGET)))
        out[a] = float(np.mean((p > 0).all(axis=-1)))
    return out


def cubic_solver_benchmark(n=20000, seed=0, reference=200):
    """Accuracy and speed of the trigonometric solver against np.linalg.eigvals.

    Builds the reversed cubics P(t) of the kernel for biased random six-moment
    vectors and fragment depths, solves them both ways in float64, and compares
    ``reference`` of them with mpmath.polyroots.

    Returns
    -------
    dict with ``trig_seconds``, ``eig_seconds``, ``trig_max_rel_err``,
    ``eig_max_rel_err`` (relative to the largest |root| per cubic).
    """
    import mpmath

    from .moments import bias_moments

    n, rng = _draws(n, seed)
    reference = _count(reference, "reference", lo=0)
    z = rng.uniform(-1, 1, (n, 5))
    wt = rng.uniform(0.05, 1, (n, 5))
    b = bias_moments(power_moments(z, wt, n=6), BIAS6_FLOAT64)
    zf = rng.uniform(-1, 1, n)
    b1, b2, b3, b4, b5, b6 = b.T
    D1, D2, D3, L21, L31, L32 = _ldl(b1, b2, b3, b4, b5, b6)
    _, y1, y2, y3 = _forward(1.0, zf, zf * zf, zf ** 3, b1, b2, b3, L21, L31, L32)
    c1, c2, c3 = y1 / D1, y2 / D2, y3 / D3
    q3 = c3
    q2 = c2 - L32 * q3
    q1 = c1 - L21 * q2 - L31 * q3
    pz = 1 + y1 * c1 + y2 * c2 + y3 * c3
    p1 = q1 + (2 * q2 + 3 * q3 * zf) * zf
    p2 = q2 + 3 * q3 * zf
    t0 = time.perf_counter()
    r_trig = np.sort(solve_cubic(pz, p1, p2, q3), axis=0).T
    t1 = time.perf_counter()
    comp = np.zeros((n, 3, 3))
    comp[:, 0, :] = -np.stack([p1, p2, q3], axis=-1) / pz[:, None]
    comp[:, 1, 0] = comp[:, 2, 1] = 1
    r_eig = np.sort(np.linalg.eigvals(comp).real, axis=-1)
    t2 = time.perf_counter()
    err_t, err_e = 0.0, 0.0
    with mpmath.workdps(40):
        for i in range(min(reference, n)):
            ex = sorted(float(mpmath.re(r)) for r in mpmath.polyroots(
                [mpmath.mpf(float(x)) for x in (pz[i], p1[i], p2[i], q3[i])], maxsteps=200, extraprec=200))
            sc = max(abs(x) for x in ex)
            err_t = max(err_t, max(abs(a - e) for a, e in zip(r_trig[i], ex)) / sc)
            err_e = max(err_e, max(abs(a - e) for a, e in zip(r_eig[i], ex)) / sc)
    return {"trig_seconds": t1 - t0, "eig_seconds": t2 - t1, "trig_max_rel_err": err_t, "eig_max_rel_err": err_e}
