"""Moment shadow mapping with six moments: sharp bounds from b1..b6.

The six-moment analogue of HPG17 Algorithm 1 (Peters and Klein 2015, used for
prefiltered single scattering in the slides, "Prefiltered single scattering with
6 moments"): given ``b = (b1, ..., b6)`` of a depth distribution Z (b0 = 1) and a
fragment depth ``zf``, the sharp lower bound of ``Z(z < zf)`` over all
distributions with these moments is attained by a distribution with four points
of support ``zf, z1, z2, z3`` (the *canonical representation*); ``z1, z2, z3``
are the roots of the cubic ``q3 z³ + q2 z² + q1 z + q0`` with
``B(b) q = (1, zf, zf², zf³)`` and B(b) the 4×4 Hankel matrix ``B[i, j] = b_{i+j}``.

Algorithm (what the kernels do, step by step):

1. ``B(b) = L D Lᵀ`` (L unit lower triangular, ``D = diag(1, D1, D2, D3)``): the
   Cholesky factorization the slides insist on, without square roots.
2. Solve ``B q = v(zf)``, ``v(z) = (1, z, z², z³)``: forward substitution
   ``L y = v(zf)``, scaling ``c = D⁻¹ y``, back substitution ``Lᵀ q = c``. The
   forward substitution gives ``y = (1, P1(zf), P2(zf), P3(zf))``, the monic
   orthogonal polynomials of the moments at zf (``P3``'s roots ``x1 < x2 < x3`` are
   the Gauss nodes of b).
3. The roots of ``p(z) = q3 z³ + q2 z² + q1 z + q0``, found as roots
   ``t_l = 1 / (z_l − zf)`` of the reversed Taylor polynomial at zf,

       P(t) = p(zf) t³ + p'(zf) t² + p''(zf)/2 t + q3,

   whose leading coefficient ``p(zf) = vᵀ B⁻¹ v = 1/w0 ≥ 1`` never vanishes
   (``q3``, the leading coefficient of p, does: then a root z runs off to
   infinity, which is ``t = 0`` here, harmless). ``t < 0`` is exactly ``z < zf``.
   All three roots are real, and with zf they interlace with the Gauss nodes: one
   of ``zf, z1, z2, z3`` (∞ included) in each of ``(−∞, x1), (x1, x2), (x2, x3),
   (x3, ∞)``. So the number k of Gauss nodes below zf says which roots lie below
   zf, and k costs nothing: the Sturm sequence ``(1, y1, y2, y3)`` changes sign
   once per Gauss node above zf. The bounds need at most one root: none below
   (k = 0), the only root below zf, the smallest t (k = 1), the only root above,
   the largest t (k = 2), all three (k = 3, ``lower = 1 − w0``). That extreme root
   comes from Blinn's form of the cubic's closed form (Blinn, "How to solve a cubic
   equation"; Peters, "How to solve a cubic equation, revisited") without
   trigonometric functions: ``cos(arccos(r)/3)`` is a degree-6 polynomial in
   ``√((1 + r)/2)`` (error 1.6e-7), followed by Newton steps on P(t) (two in
   float64, none in float32, see "Cubic solver"). The canonical representation
   needs all three roots: :func:`solve_cubic`, the same closed form.
4. Weights ``w_l = 1 / (v_lᵀ B⁻¹ v_l)`` (Peters and Klein 2015, Prop. 10, as
   :mod:`moments_ref.msm` uses) at ``z_l = zf + 1/t_l``, evaluated as
   ``Σ (L⁻¹ v_l)_i² / D_i``; a root at infinity (or one whose z³ overflows) has
   weight 0. ``w0 = 1 / p(zf)``.
5. ``lower = Σ_{z_l < zf} w_l``: 0, ``w(t_min)``, ``1 − w0 − w(t_max)`` or
   ``1 − w0`` for k = 0, 1, 2, 3; ``upper = lower + w0``.

The mpmath twin :func:`moments_ref.precise.shadow_intensity6` does steps 2–4
literally (``lu_solve``, ``polyroots`` on q, a Vandermonde solve) and serves as
the independent check.

The float32 bounds. :func:`shadow_bounds` and :func:`shadow_intensity` in float32 take a
shorter path on their regular texels (:mod:`moments_ref._msm6_bound`, 103 passes instead of
128): the same steps, with the forward substitution by the three-term recurrence, the
cubic of step 3 from the Gauss–Radau polynomial through zf (Christoffel–Darboux: no back
substitution, no Taylor shift) and the weight of step 4 from the first moments about zf
(a Vandermonde solve with two roots eliminated by Vieta) instead of the Christoffel
function; texels it cannot guarantee (singular B(b), a nearly double root, a non-finite
result) take the kernel described here. The float32 goldens' worst error/tolerance and the
accuracy against mpmath are in docs/bench.md ("Kernel history", round seven).

Cubic solver. The trig-free closed form is as accurate as the trigonometric method it
replaced and more than the companion-matrix eigenvalues, and faster; the kernel's speed
comes from needing one root and one weight instead of three. float64 takes one Newton
step on ``cos(arccos(r)/3)`` and two on the cubic, float32 none (its coefficients'
rounding dominates). The measurements that chose this are in docs/msm6.md.

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

Bias. The slides give no six-moment bias; this module ships three presets built
like HPG17 §3.2 (``b' = (1 − α) b + α b*``) with the target ``b*`` the moments
of the symmetric five-point distribution
``0.4 δ0 + 0.15 (δ−1 + δ1 + δ−1/2 + δ1/2)`` (:data:`BIAS6_TARGET`; five points, so
B(b*) is positive definite: the six-moment sibling of HPG17's
``(0, 0.375, 0, 0.375)``, the moments of a three-point distribution):

* :data:`BIAS6_FLOAT64` (α = 3e-7, as HPG17's BIAS_FLOAT32) for float64
  arithmetic: the last pivot D3 of biased moments is at least about
  ``α·D3(b*) = 1e-8`` (D3(b*) = 0.034), far above float64 rounding.
* :data:`BIAS6_FLOAT32` (α = 3e-4) for float32 moments and arithmetic: α = 3e-7
  is useless there (D3 of biased moments, ≈ 1e-8, is below float32's rounding of
  the pivots, ≈ 1e-7); 3e-4 gave the smallest worst bracket excess on stiff cases.
* :data:`BIAS6_UNORM10` (α = 1e-3, the 2×R10G10B10A2 storage of the slides): it
  keeps three quarters of even single-texel quantized vectors inside the moment
  space at an RMSE cost of 0.001 on the ``scattering`` scene; a vector outside is
  projected onto the boundary (singular branch, never NaN). The slides: "rounding
  errors are less malicious for single scattering".

The measurements behind each α (:func:`measure_unorm10_bias`, the stiff cases, the
scattering scene) are in docs/msm6.md.

References
----------
.. [1] HPG17: Christoph Peters. 2017. *Non-Linearly Quantized Moment Shadow Maps*. In Proceedings
       of High Performance Graphics (HPG '17). ACM. The non-linear quantization Φ, Ψ4, Algorithms
       1–3, the texel formats and the compute shader of §4.1.
.. [2] Peters and Klein 2015: Christoph Peters and Reinhard Klein. 2015. *Moment Shadow Mapping*.
       In Proceedings of the 19th ACM SIGGRAPH Symposium on Interactive 3D Graphics and Games (i3D
       '15). ACM, 7–14. https://doi.org/10.1145/2699276.2699277
.. [3] Slides: Christoph Peters. *Rendering antialiased shadows with moment shadow mapping*,
       lecture slides (PDF version, with notes) on moment shadow mapping, translucent occluders,
       moment soft shadow mapping and prefiltered single scattering; http://MomentsInGraphics.de/.
       Cited by slide title, e.g. Slides, "Bias the moments".
"""

from __future__ import annotations

import time

import numpy as np

from ._arrays import InputError, brief, check_broadcast, first_index, lookup_inputs, real_input, refuse_lookup
from ._docs import fill_doc
from .moments import BiasPreset, power_moments
from ._kernels import CHUNK, SINGULAR_RTOL, broadcast_chunks, singular_thresholds
from ._msm6_rows import BOUNDS_CHUNK  # noqa: F401 (float32's chunk, read by the bench)
from ._msm6_rows import COS_THIRD_POLY as _COS_THIRD_POLY, bounds_chunk
from ._msm6_bound import bound_rows
from ._msm6_rows import ldl_rows, regular_chunk, regular_mask, root_rows, solve_rows, weight_rows, workspace
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


#: Newton steps of the closed form in the kernels, per dtype: on ``4c³ − 3c = r`` after the fit
#: of cos(arccos(r)/3), then on the cubic (module docstring, "Cubic solver").
_NEWTON_STEPS = {"float32": (0, 0), "float64": (1, 2)}


# ---------------------------------------------------------------------------
# the cubic


def _cos_third(rho, refine=0):
    """``cos(arccos(ρ)/3)``, the largest root of ``4c³ − 3c = ρ``, without trigonometric functions.

    Parameters
    ----------
    rho : float array in [−1, 1]
        Rounding a little below −1 gives the value at ``−1 + |δ|`` (u takes |1 + ρ|).
    refine : int
        Newton steps on ``4c³ − 3c − ρ`` after the fit.

    Returns
    -------
    c : float array in [1/2, 1], dtype of rho

    Notes
    -----
    With ``u = √((1 + ρ)/2) = cos(arccos(ρ)/2)`` the value is ``cos(⅔·arccos u)``,
    analytic on [0, 1]: the square-root singularity at ρ = −1 (where the two largest
    roots meet) is taken by u. :data:`_COS_THIRD_POLY`, a degree-6 polynomial in u,
    holds it to 1.6e-7 (float32's resolution); each Newton step squares that error
    (float64 takes one). The steps solve ``(2c − 1)·√(c + 1) = √2·u``, the same
    equation with its double root at ρ = −1 divided out (Newton on ``4c³ − 3c − ρ``
    stalls there, where ``12c² − 3`` vanishes: exactly where the closed form needs
    the digits, for a small root next to a root of opposite sign).

    >>> _cos_third(np.array([-1.0, 0.0, 1.0])).round(6)
    array([0.5     , 0.866025, 1.      ])
    """
    u = np.sqrt(np.abs(rho * 0.5 + 0.5))  # |·|: ρ < −1 by rounding gives u ≈ 0, not NaN
    c = u * _COS_THIRD_POLY[-1]  # Horner
    for a in _COS_THIRD_POLY[-2:0:-1]:
        c += a
        c *= u
    c += _COS_THIRD_POLY[0]
    if refine:
        # (2c − 1)·√(c + 1) = √2·u is 4c³ − 3c = ρ with the double root of ρ = −1 divided out:
        # increasing in c (slope ≥ √6 at c = 1/2), so Newton on it converges fast everywhere.
        su = u * np.sqrt(2.0)
        for _ in range(refine):
            s = np.sqrt(c + 1)
            x = 2 * c - 1
            c -= (x * s - su) / (2 * s + x / (2 * s))
    return c


def _blinn(c0, c1, c2, c3):
    """``(B, 2m, r)`` of Blinn's form: the roots are ``2m·cos θ_k − B`` with ``cos 3θ = r``.

    ``B = c1/(3c0)``, ``C = c2/(3c0)``, ``D = c3/c0``; the Hessian ``Δ0 = C − B²`` (≤ 0 for
    three real roots), ``m = √(−Δ0)`` and ``r = −(Δ1 − 2BΔ0)/(2m³)`` with ``Δ1 = D − BC``
    (the depressed cubic's constant term over its natural scale).
    """
    c0_3 = 3 * c0
    B, C, D = c1 / c0_3, c2 / c0_3, c3 / c0
    d0 = C - B * B
    minus_dep = B * (C + 2 * d0) - D  # −(Δ1 − 2BΔ0)
    minus_d0 = np.abs(d0)  # |·|: rounding may leave Δ0 a little above 0
    m2 = np.sqrt(4 * minus_d0)
    r = minus_dep / (m2 * minus_d0)  # 2m³ = 2m·(−Δ0)
    return B, m2, r


def _newton(c0, c1, c2, c3, t, steps):
    """``steps`` Newton steps on ``c0 t³ + c1 t² + c2 t + c3`` from t (no safeguard: t is close)."""
    for _ in range(steps):
        f = ((c0 * t + c1) * t + c2) * t + c3
        fp = (3 * c0 * t + 2 * c1) * t + c2
        t = t - f / fp
    return t


def _extreme_root(c0, c1, c2, c3, sigma, newton=2, refine=2):
    """The largest (σ = +1) or smallest (σ = −1) root of a cubic with three real roots.

    Parameters
    ----------
    c0, c1, c2, c3 : (n,) float arrays
        Coefficients of ``c0 t³ + c1 t² + c2 t + c3``, highest power first, ``c0 ≠ 0``.
    sigma : (n,) float array of ±1
    newton, refine : int
        Newton steps on the cubic after the closed form, and on ``4c³ − 3c = r``
        inside it (:func:`_cos_third`).

    Returns
    -------
    t : (n,) float array

    Notes
    -----
    Blinn's form (:func:`solve_cubic`): with ``c(r) = cos(arccos(r)/3)``
    (:func:`_cos_third`) the largest root is ``2m·c(r) − B`` and the smallest
    ``−2m·c(−r) − B`` (minus the largest root of the cubic in −t, whose r changes
    sign), so ``t = σ·2m·c(σr) − B``: no trigonometric function, one square root
    besides u's. The Newton steps recover the digits lost to cancellation when
    ``|t| ≪ |B|`` (roots spread over orders of magnitude).
    """
    B, m2, r = _blinn(c0, c1, c2, c3)
    t = sigma * m2 * _cos_third(sigma * r, refine) - B
    return _newton(c0, c1, c2, c3, t, newton)


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
    Blinn's form of the trigonometric solution ("How to solve a cubic equation";
    Peters' "SolveCubic"): with ``B = c1/(3c0)``, ``C = c2/(3c0)``, ``D = c3/c0``, the
    Hessian ``Δ = (C − B², D − BC, BD − C²)``, ``m = √(−Δ0)`` and
    ``cos 3θ = r = −(Δ1 − 2BΔ0)/(2m³)`` (clamped to [−1, 1]; a triple root, m = 0,
    counts as r = 1), the roots are ``2m·cos(θ + 2πk/3) − B``. The cosines are the
    roots of ``4c³ − 3c = r``, found without trigonometric functions: with
    ``c(r) = cos(arccos(r)/3)`` as a polynomial (:func:`_cos_third`, refined by one
    Newton step in float64), ``cos θ = c(r)``, ``cos(θ + 2π/3) = −c(−r)`` and the
    middle one from their sum, 0. The Newton steps (with a safeguard: a step is
    dropped where it is not finite or larger than ``|t| + 1``) polish each root.
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
    """:func:`solve_cubic` without validation (the canonical representation's path)."""
    refine = _NEWTON_STEPS[c0.dtype.name][0]
    with np.errstate(divide="ignore", invalid="ignore", over="ignore", under="ignore"):
        B, m2, r = _blinn(c0, c1, c2, c3)
        r = np.fmax(np.fmin(r, 1), -1)  # fmin/fmax: NaN (0/0 at a triple root) counts as 1
        hi, lo = _cos_third(r, refine), -_cos_third(-r, refine)
        return _polish(c0, c1, c2, c3, np.stack([hi, -hi - lo, lo]) * m2 - B, newton)


def _polish(c0, c1, c2, c3, roots, newton):
    """Newton steps on each of the roots (3, n), each dropped where it is not finite or exceeds ``|t| + 1``.

    The closed form loses digits in the root of smallest magnitude when the roots
    spread over many orders of magnitude.
    """
    with np.errstate(divide="ignore", invalid="ignore", over="ignore", under="ignore"):
        for _ in range(newton):
            f = ((c0 * roots + c1) * roots + c2) * roots + c3
            fp = (3 * c0 * roots + 2 * c1) * roots + c2
            step = f / fp
            keep = np.isfinite(step) & (np.abs(step) <= np.abs(roots) + 1)
            roots = roots - np.where(keep, step, 0).astype(roots.dtype)
    return roots


# ---------------------------------------------------------------------------
# the kernel


def _ldl(b1, b2, b3, b4, b5, b6):
    """LDLᵀ of the 4×4 Hankel matrix: (D1, D2, D3, L21, L31, L32); L10..L30 = b1..b3.

    Each ``L_ij D_j`` is kept as the numerator it is divided from, so that
    ``L_ij² D_j = L_ij · (L_ij D_j)`` costs one product.
    """
    D1 = b2 - b1 * b1
    L21D1 = b3 - b1 * b2
    L31D1 = b4 - b1 * b3
    L21, L31 = L21D1 / D1, L31D1 / D1
    D2 = b4 - b2 * b2 - L21 * L21D1
    L32D2 = b5 - b2 * b3 - L21 * L31D1
    L32 = L32D2 / D2
    D3 = b6 - b3 * b3 - L31 * L31D1 - L32 * L32D2
    return D1, D2, D3, L21, L31, L32


def _forward(g0, g1, g2, g3, b1, b2, b3, L21, L31, L32):
    """Forward substitution L u = g (u0 = g0)."""
    u1 = g1 - b1 * g0
    u2 = g2 - b2 * g0 - L21 * u1
    u3 = g3 - b3 * g0 - L31 * u1 - L32 * u2
    return g0, u1, u2, u3


def _regular(b, ldl):
    """True where B(b) is regular: every pivot above its threshold (module docstring)."""
    return regular_mask(b, ldl)


def _reversed_cubic(b, zf):
    """Steps 1–3 on flat chunks, b (6, n) rows, zf (n,): ``(ldl, y, P)``.

    ``ldl = (D1, D2, D3, L21, L31, L32)``; ``y = (y1, y2, y3)`` the forward substitution
    of ``v(zf)`` without its leading 1, i.e. the monic orthogonal polynomials P1..P3
    at zf; ``P = (p(zf), p'(zf), p''(zf)/2, q3)`` the coefficients of the reversed
    Taylor cubic P(t), highest power first.
    """
    b1, b2, b3, b4, b5, b6 = b
    # (1) Cholesky decomposition without square roots: B = L D Lᵀ.
    ldl = _ldl(b1, b2, b3, b4, b5, b6)
    D1, D2, D3, L21, L31, L32 = ldl
    # (2) Forward substitution L y = v(zf) = (1, zf, zf², zf³).
    zf2 = zf * zf
    y1 = zf - b1
    y2 = zf2 - b2 - L21 * y1
    y3 = zf2 * zf - b3 - L31 * y1 - L32 * y2
    # Scaling D c = y, back substitution Lᵀ q = c (q0 is not needed: P(t) uses p's derivatives at zf).
    c1, c2, c3 = y1 / D1, y2 / D2, y3 / D3
    q3 = c3
    q2 = c2 - L32 * q3
    q1 = c1 - L21 * q2 - L31 * q3
    # p(zf) = vᵀ B⁻¹ v = 1/w0 (the sum of squares, not Horner: no cancellation).
    pz = 1 + y1 * c1 + y2 * c2 + y3 * c3
    # (3) P(t) = p(zf) t³ + p'(zf) t² + p''(zf)/2 t + q3, p'' / 2 = q2 + 3 q3 zf.
    p2 = q2 + 3 * q3 * zf
    p1 = q1 + (q2 + p2) * zf  # p'(zf) = q1 + 2 q2 zf + 3 q3 zf²
    return ldl, (y1, y2, y3), (pz, p1, p2, q3)


def _weights(t, zf, b1, b2, b3, ldl, zero):
    """(4) ``w = 1 / (v(z)ᵀ B⁻¹ v(z)) = 1 / Σ (L⁻¹ v(z))_i² / D_i`` at the roots ``z = zf + 1/t``.

    t broadcasts against zf ((n,) or (3, n)); ``zero`` is an array of zeros like zf. A root
    at infinity (t = 0) or so far out that z³ overflows has weight 0 (exactly:
    ``w ≈ t⁶ D3``): its NaN (∞ − ∞) or ``1/∞`` becomes 0, as does any other weight that
    is not a positive number.
    """
    D1, D2, D3, L21, L31, L32 = ldl
    z = zf + 1 / t
    z2 = z * z
    u1 = z - b1  # forward substitution L u = v(z)
    u2 = z2 - b2 - L21 * u1
    u3 = z2 * z - b3 - L31 * u1 - L32 * u2
    w = 1 / (1 + u1 * u1 / D1 + u2 * u2 / D2 + u3 * u3 / D3)
    return np.fmax(w, zero, out=w)  # an array, not 0: NumPy's array-scalar fmax is 4x slower


def _bounds_kernel(b, zf, steps, dest, refuse):
    """The bounds named in ``dest`` (rows of the output) on flat chunks: b (6, n) rows, zf (n,).

    Module docstring, steps 1–5, in the workspace of :func:`_workspace`: every operation
    writes into a reused row (``out=``) and the bounds go straight into ``dest``; the same
    arithmetic in the same order as the expressions of :func:`_ldl`, :func:`_reversed_cubic`,
    :func:`_extreme_root` and :func:`_weights` (bit for bit). 128 passes over a float32
    chunk for the lower bound (the upper 2 more; float32 runs it only on the texels that
    :mod:`moments_ref._msm6_bound`'s 103 passes hand back, :func:`_bounds`), and the checks as reductions
    (:func:`_regular_chunk`): a chunk needs the exact mask of :func:`_regular` only where
    a texel is singular or not finite. ``steps`` is the dtype's entry of
    :data:`_NEWTON_STEPS`; ``refuse()`` raises the error of a NaN or inf in the input.
    """
    w = workspace(b.dtype, zf.shape[0])
    with np.errstate(divide="ignore", invalid="ignore", over="ignore", under="ignore"):
        ldl = ldl_rows(b, w)
        pz, p1, p2, q3, w0 = solve_rows(b, zf, ldl, w)
        root = root_rows((pz, p1, p2, q3), steps, w)
        wt = weight_rows(root, b, zf, ldl, w)
        # (5) lower = Σ_{z_l < zf} w_l = (1 − w0)·[two below] + w·([odd] − [two below]): 0, w,
        # 1 − w0 − w, 1 − w0 for 0..3 Gauss nodes below zf (1 − w0 exactly for three).
        two_below, odd = w["mask"][0], w["mask"][2]
        lower = dest.get("lower", w["c2"])
        r0, sel = w["e"], w["f"]
        np.subtract(1, w0, out=r0)
        np.multiply(r0, two_below, out=r0)
        np.subtract(odd, two_below, out=sel, dtype=b.dtype)
        np.multiply(wt, sel, out=sel)
        np.add(r0, sel, out=lower)
    if not regular_chunk(b, zf, ldl, w):
        regular = _regular(b, ldl)
        if not (regular & np.isfinite(ldl[2] + zf)).all():
            if not (np.isfinite(b).all() and np.isfinite(zf).all()):
                refuse()
            s = ~regular
            lower[s], w0[s] = _singular(b[:, s], zf[s])[:2]
            np.fmax(lower, w["zero"], out=lower)
            np.fmin(lower, w["one"], out=lower)  # a sum of the unique distribution's weights above 1
    # Clamped like saturate (rounding: 1 − w0 − w < 0); fmax also turns a NaN from overflow into 0.
    # Above 1 only on singular rows: 0 ≤ w ≤ 1 and 1 − w0 ∈ [0, 1) (w0 = 1/p(zf), p(zf) ≥ 1).
    np.fmax(lower, w["zero"], out=lower)
    if "upper" in dest:
        np.add(lower, w0, out=dest["upper"])
        np.fmin(dest["upper"], w["one"], out=dest["upper"])


def _bounds(b, zf, steps, dest, refuse):
    """The bounds named in ``dest`` on a chunk: :func:`~moments_ref._msm6_bound.bound_rows` in float32, the rest by :func:`_bounds_kernel`.

    float32 takes the fast path (the weight from the first moments about zf) and hands
    its singular, non-finite and nearly-double-root texels to :func:`_bounds_kernel`;
    float64 (Newton steps on the root) runs :func:`_bounds_kernel` throughout. Called
    under :func:`_run`'s ``np.errstate`` (one per call, not one per chunk).
    """
    if b.dtype.type is np.float32:
        rest = bound_rows(b, zf, workspace(b.dtype, zf.shape[0]), dest)
        if rest is None:
            return
        sub = {k: np.empty(rest.size, dtype=b.dtype) for k in dest}
        _bounds_kernel(np.ascontiguousarray(b[:, rest]), zf[rest], steps, sub, refuse)
        for k, v in sub.items():
            dest[k][rest] = v
        return
    _bounds_kernel(b, zf, steps, dest, refuse)


def _canonical_kernel(b, zf, zero, one):
    """``(w0, z (3, n), w (3, n))`` of the canonical representation on flat chunks (all three roots)."""
    b1, b2, b3 = b[:3]
    with np.errstate(divide="ignore", invalid="ignore", over="ignore", under="ignore"):
        ldl, _, P = _reversed_cubic(b, zf)
        regular = _regular(b, ldl)
        if not regular.all():  # placeholder cubic t³ − t for singular rows (replaced below)
            P = [np.where(regular, x, y).astype(b.dtype) for x, y in zip(P, (1, 0, -1, 0))]
        t = _solve_cubic(*P)  # two safeguarded Newton steps for all three roots, either dtype
        w = _weights(t, zf, b1, b2, b3, ldl, zero)
        z = zf + 1 / t  # ±inf for t = ±0
        w0 = np.fmax(1 / P[0], zero)
    if not regular.all():
        s = ~regular
        _, w0[s], z[:, s], w[:, s] = _singular(b[:, s], zf[s])
    return w0, z, w


def _singular(b, zf):
    """The unique distribution of singular B(b) (module docstring): ``(lower, w0, z, w)``.

    For rows b (6, m) and zf (m,) whose B(b) is singular; z and w are (3, m), unused
    slots +inf with weight 0, mass at zf moved to w0.
    """
    dt = b.dtype.type
    one = dt(1)
    rtol = dt(singular_thresholds(b.dtype))
    b1, b2, b3, b4, b5, b6 = b
    with np.errstate(divide="ignore", invalid="ignore", over="ignore", under="ignore"):
        D1, D2, D3, L21, L31, L32 = _ldl(b1, b2, b3, b4, b5, b6)
    sg = D1 <= rtol * b2
    tw = ~sg & ~(D2 > rtol * np.maximum(b4, D1))
    th = ~sg & ~tw  # the remaining rows: D3 ≤ τ·max(b6, D2)
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
        with np.errstate(divide="ignore", invalid="ignore", over="ignore", under="ignore"):
            u0, u1, u2, _ = _forward(np.ones_like(r), r, r * r, r * r * r, a1, a2, a3, l21, l31, l32)
            lam = one / (u0 * u0 + u1 * u1 / d1 + u2 * u2 / d2)  # Christoffel numbers
        lam = np.where(np.isfinite(lam) & (lam > 0), lam, 0)
        lam = lam / lam.sum(axis=0)
        pts[:, th] = r
        wts[:, th] = lam
    lower = (wts * (pts < zf)).sum(axis=0)
    w0 = (wts * (pts == zf)).sum(axis=0)
    return lower, w0, pts, np.where(pts == zf, 0, wts)


def _run(b, zf, want):
    """The kernels over chunks; only the outputs named in ``want`` are allocated.

    ``want`` is drawn from lower, upper (the bounds kernel) or w0 (n,), z, w (n, 3)
    (the canonical kernel); returns ``(dict, zf, shape)``. Each chunk is checked for
    NaN and inf while it is in cache (the bounds kernel: only where a texel comes out
    singular, which a NaN or inf makes it), instead of a pass over the whole input.
    """
    b, zf, shape = lookup_inputs(b, "b", zf, trailing=6)
    n = int(np.prod(shape, dtype=np.int64))
    outs = {k: np.empty((n, 3) if k in ("z", "w") else n, dtype=b.dtype) for k in want}
    steps = _NEWTON_STEPS[b.dtype.name]
    zeros, ones = (np.zeros(min(n, CHUNK), b.dtype), np.ones(min(n, CHUNK), b.dtype)) if "z" in want else (None, None)
    refuse = lambda: refuse_lookup(b, "b", zf)  # noqa: E731 (raises: a value is NaN or inf)
    if "z" not in want:  # the bounds are written into the output
        with np.errstate(divide="ignore", invalid="ignore", over="ignore", under="ignore"):
            for start, stop, bc, zc in broadcast_chunks(b, zf, shape, bounds_chunk(b.dtype)):
                _bounds(bc, zc, steps, {k: outs[k][start:stop] for k in want}, refuse)
        return outs, zf, shape
    for start, stop, bc, zc in broadcast_chunks(b, zf, shape, CHUNK):
        if not (np.isfinite(bc).all() and np.isfinite(zc).all()):
            refuse()
        w0, z, w = _canonical_kernel(bc, zc, zeros[: stop - start], ones[: stop - start])
        res = {"w0": w0, "z": z.T, "w": w.T}
        for k in want:
            outs[k][start:stop] = res[k]
    return outs, zf, shape


@fill_doc
def shadow_bounds(b, zf):
    """Both sharp bounds from six moments: ``(lower, upper)``.

    Parameters
    ----------
    b : (..., 6) float array
        Moments b1..b6 (b0 = 1 implicit), normally biased
        (:data:`BIAS6_FLOAT64`, :data:`BIAS6_FLOAT32`, :data:`BIAS6_UNORM10`).
    %(zf)s
        Cast to b's dtype.

    Returns
    -------
    lower, upper : (...) float arrays in [0, 1], dtype of ``b``
        Sharp lower bound of Z(z < zf) and sharp upper bound of Z(z ≤ zf).
    """
    outs, _, shape = _run(b, zf, ("lower", "upper"))
    return outs["lower"].reshape(shape), outs["upper"].reshape(shape)


@fill_doc
def shadow_intensity(b, zf, bound="lower"):
    """Sharp bound of ``Z(z < zf)`` (or of ``Z(z ≤ zf)``) from six moments.

    Parameters
    ----------
    b : (..., 6) float array
        Moments b1..b6, normally biased.
    %(zf)s
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
    with np.errstate(divide="ignore", invalid="ignore", over="ignore", under="ignore"):
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


def _trig_roots(c0, c1, c2, c3, newton=2):
    """The trigonometric method (``arctan2``, cos, sin) that :func:`solve_cubic` replaced, for the benchmark."""
    dt = c0.dtype.type
    B, m2, r = _blinn(c0, c1, c2, c3)
    theta = np.arctan2(np.sqrt(np.maximum(1 - r * r, 0)), r) / dt(3)
    cs, sn = np.cos(theta), np.sin(theta)
    roots = np.stack([cs, -cs / 2 + dt(np.sqrt(0.75)) * sn, -cs / 2 - dt(np.sqrt(0.75)) * sn]) * m2 - B
    return _polish(c0, c1, c2, c3, roots, newton)


def cubic_solver_benchmark(n=20000, seed=0, reference=200):
    """Accuracy and speed of the trig-free solver against the trigonometric one and np.linalg.eigvals.

    Builds the reversed cubics P(t) of the kernel for biased random six-moment
    vectors and fragment depths, solves them three ways in float64 (each with two
    Newton steps but eigvals), compares ``reference`` of them with mpmath.polyroots,
    and times the two closed forms in float32 as well.

    Returns
    -------
    dict with ``closed_seconds``, ``trig_seconds``, ``eig_seconds`` (float64),
    ``closed32_seconds``, ``trig32_seconds`` (float32, no Newton step) and
    ``closed_max_rel_err``, ``trig_max_rel_err``, ``eig_max_rel_err`` (relative to
    the largest |root| per cubic).
    """
    import mpmath

    from .moments import bias_moments

    n, rng = _draws(n, seed)
    reference = _count(reference, "reference", lo=0)
    z = rng.uniform(-1, 1, (n, 5))
    wt = rng.uniform(0.05, 1, (n, 5))
    b = bias_moments(power_moments(z, wt, n=6), BIAS6_FLOAT64)
    zf = rng.uniform(-1, 1, n)
    with np.errstate(divide="ignore", invalid="ignore"):
        _, _, P = _reversed_cubic(b.T, zf)
    P32 = [p.astype(np.float32) for p in P]
    pz, p1, p2, q3 = P
    out = {}
    for name, fn, args in (("closed", _solve_cubic, P), ("trig", _trig_roots, P),
                           ("closed32", lambda *c: _solve_cubic(*c, newton=0), P32),
                           ("trig32", lambda *c: _trig_roots(*c, newton=0), P32)):
        seconds = []
        for _ in range(3):  # best of three
            t0 = time.perf_counter()
            roots = fn(*args)
            seconds.append(time.perf_counter() - t0)
        out[f"{name}_seconds"] = min(seconds)
        if name in ("closed", "trig"):
            out[name] = np.sort(roots, axis=0).T
    t0 = time.perf_counter()
    comp = np.zeros((n, 3, 3))
    comp[:, 0, :] = -np.stack([p1, p2, q3], axis=-1) / pz[:, None]
    comp[:, 1, 0] = comp[:, 2, 1] = 1
    out["eig"] = np.sort(np.linalg.eigvals(comp).real, axis=-1)
    out["eig_seconds"] = time.perf_counter() - t0
    err = dict.fromkeys(("closed", "trig", "eig"), 0.0)
    with mpmath.workdps(40):
        for i in range(min(reference, n)):
            ex = sorted(float(mpmath.re(r)) for r in mpmath.polyroots(
                [mpmath.mpf(float(x)) for x in (pz[i], p1[i], p2[i], q3[i])], maxsteps=200, extraprec=200))
            sc = max(abs(x) for x in ex)
            for k in err:
                err[k] = max(err[k], max(abs(a - e) for a, e in zip(out[k][i], ex)) / sc)
    for k, e in err.items():
        out[f"{k}_max_rel_err"] = e
        del out[k]
    return out
