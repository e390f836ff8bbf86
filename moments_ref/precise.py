"""mpmath twins of :mod:`moments_ref.moments`, :mod:`moments_ref.msm` and the non-linear
representation: the ground truth the float32 and float64 kernels are measured against.

Every function here is the *literal* algorithm of the paper, evaluated in mpmath at
``dps`` significant decimal digits (50 by default), with none of the rearrangements
the fast kernels use for speed or float stability:

* HPG17 Algorithm 1 builds the Hankel matrix, solves ``B(b) q = (1, zf, zf²)`` with
  ``mpmath.lu_solve``, finds the roots of ``q2 z² + q1 z + q0`` with the quadratic
  formula and solves the Vandermonde system of step (4) with ``mpmath.lu_solve``.
  (The fast kernel replaces step (4) by Prop. 10 and an LDLᵀ factorization.)
* ξ4 comes from HPG17 Eq. (3), ``ξ4 = det B(b) / σ²`` (cofactor expansion).
* :func:`shade` reconstructs the moments of HPG17 Eq. (4) in mpmath and runs this
  module's Algorithm 1 on them, deliberately *not* Algorithm 3, so that it checks
  Algorithm 3 (:mod:`moments_ref.nonlinear`) independently. It has none of
  Algorithm 3's clamps: it is the exact value.

Inputs are converted exactly (``mpmath.mpf(float(x))`` is exact for float16/32/64
values), so the twin answers for *the very numbers the fast kernel received*; outputs
are rounded once to float64. This is an oracle: it loops over elements in Python
(a few thousand evaluations per second), which the house rules allow here and
nowhere else.

Singular Hankel matrices follow the same *definitions* as :mod:`moments_ref.msm`
with a threshold at working precision instead of a multiple of a float epsilon,
``tol = 10**-(dps - 10)``:

* ``σ² = b2 − b1² ≤ tol·b2``: the unique distribution is one depth at ``b1``;
* otherwise ``ξ4 ≤ tol·max(b4, σ²)``: the two-point distribution with depths
  ``y1 < y2`` the roots of ``σ² z² + q1 z + q0`` (``q1 = b1 b2 − b3``,
  ``q0 = −b1 q1 − b2 σ²``) and weight ``v2 = (b1 − y1)/(y2 − y1)``.

Both bounds then return Z of that distribution (``lower = Z(z < zf)``,
``upper = Z(z ≤ zf)``). Negative σ² or ξ4 (moments outside the moment space) fall
into the same branches, i.e. they are projected onto the boundary of the moment
space exactly as :mod:`moments_ref.msm` documents. In the regular case
``upper = lower + w0``, the sharp upper bound of ``Z(z ≤ zf)``.

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

import mpmath
import numpy as np

from ._arrays import InputError, brief, broadcast_pair, check_axis, real_input
from ._docs import fill_doc
from .moments import BiasPreset, bias_preset
from .nonlinear import validate_representation

__all__ = [
    "DPS",
    "power_moments",
    "bias_moments",
    "shadow_intensity",
    "shadow_bounds",
    "canonical_representation",
    "pivots",
    "phi",
    "phi_inverse",
    "psi4",
    "psi4_inverse",
    "shade",
    "shadow_bounds6",
    "shadow_intensity6",
    "canonical_representation6",
    "hausdorff_bounds",
    "hausdorff_intensity",
    "phi_exact",
]

#: Default working precision in significant decimal digits.
DPS = 50


# ---------------------------------------------------------------------------
# conversion helpers


def _mp(x) -> mpmath.mpf:
    """Exact conversion of one float (any width) to mpmath."""
    return mpmath.mpf(float(x))


def _tol(dps):
    """Singularity threshold at working precision: 10^-(dps-10)."""
    return mpmath.mpf(10) ** (-(int(dps) - 10))


#: Most significant digits a caller may ask for (beyond it mpmath's work grows
#: without bound: ``dps=10**20`` would never return).
MAX_DPS = 10_000


def _check_dps(dps):
    if isinstance(dps, bool) or not isinstance(dps, (int, np.integer)) or not 20 <= dps <= MAX_DPS:
        raise InputError(f"dps: expected an integer from 20 to {MAX_DPS} digits, got {brief(dps)}")
    return int(dps)


def _moment_input(b, name="b"):
    return real_input(b, name, trailing=4)


# ---------------------------------------------------------------------------
# moments


def power_moments(z, weights=None, axis=-1, n=4, dps=DPS):
    """mpmath twin of :func:`moments_ref.moments.power_moments`.

    Parameters
    ----------
    z : array_like, float
        Depths, samples along ``axis``.
    weights : array_like, optional
        Non-negative weights broadcastable to ``z``, normalized per distribution.
    axis : int
        Sample axis.
    n : int
        Number of moments (4 or 6).
    dps : int
        Working precision in decimal digits.

    Returns
    -------
    b : (..., n) float64 array
        ``b_k = Σ w_l z_l^k / Σ w_l`` evaluated in mpmath, rounded once.

    Notes
    -----
    HPG17 §2, ``b = E_Z(b(z))``, by the definition (a loop over samples).
    """
    dps = _check_dps(dps)
    if isinstance(n, bool) or n not in (4, 6):
        raise InputError(f"n: expected 4 or 6, got {n!r}")
    z = real_input(z, "z")
    if z.ndim == 0:
        raise InputError("z: expected at least one axis of samples, got a scalar")
    axis = check_axis(axis, z.ndim, "z")
    z = np.moveaxis(z, axis, -1)
    if weights is None:
        w = np.ones(z.shape, dtype=np.float64)
    else:
        w = np.moveaxis(np.broadcast_to(real_input(weights, "weights", dtype=np.float64),
                                        np.moveaxis(z, -1, axis).shape), axis, -1)
        if (w < 0).any():
            raise InputError("weights: expected non-negative values")
    out = np.empty(z.shape[:-1] + (n,), dtype=np.float64)
    with mpmath.workdps(dps):
        for idx in np.ndindex(z.shape[:-1]):
            zs = [_mp(v) for v in z[idx]]
            ws = [_mp(v) for v in w[idx]]
            total = mpmath.fsum(ws)
            if total <= 0:
                raise InputError(f"weights: expected a positive sum per distribution, got 0 at distribution {idx}")
            for k in range(1, n + 1):
                out[idx + (k - 1,)] = float(mpmath.fsum(wl * zl**k for wl, zl in zip(ws, zs)) / total)
    return out


def bias_moments(b, preset, dps=DPS):
    """mpmath twin of :func:`moments_ref.moments.bias_moments`: ``(1 − α) b + α b*``.

    α and b* are taken as the float64 numbers stored in the preset (the float32
    kernel rounds α to float32 first; that difference is part of what it is
    measured against).

    Returns
    -------
    b_biased : (..., 4) or (..., 6) float64 array
    """
    dps = _check_dps(dps)
    p = preset if isinstance(preset, BiasPreset) else bias_preset(preset)
    b = real_input(b, "b", trailing=(4, 6))
    if len(p.target) != b.shape[-1]:
        raise InputError(f"preset: expected a target of length {b.shape[-1]}, got {len(p.target)}")
    out = np.empty(b.shape, dtype=np.float64)
    with mpmath.workdps(dps):
        alpha = _mp(p.alpha)
        target = [_mp(t) for t in p.target]
        for idx in np.ndindex(b.shape[:-1]):
            for k in range(b.shape[-1]):
                out[idx + (k,)] = float((1 - alpha) * _mp(b[idx + (k,)]) + alpha * target[k])
    return out


# ---------------------------------------------------------------------------
# Algorithm 1 on mpmath scalars


def _two_point_mp(b1, b2, b3, sigma2):
    """Depths y1 < y2 and weight v2 of the two-point distribution matching b1..b3.

    HPG17 Algorithm 2 steps (1)-(5); σ² > 0 guarantees a positive discriminant
    (it equals (q1 + 2 b1 σ²)² + 4 σ⁶).
    """
    q1 = b1 * b2 - b3
    q0 = -b1 * q1 - b2 * sigma2
    y1, y2 = _roots(sigma2, q1, q0)
    v2 = (b1 - y1) / (y2 - y1)
    return y1, y2, v2


def _roots(a, b, c):
    """Real roots (r1 ≤ r2) of ``a z² + b z + c`` by the quadratic formula.

    Written in the form ``r = (−b − sign(b)·√D)/(2a)``, ``r' = c/(a·r)`` so that
    a root stays accurate to working precision when the other one runs off to
    infinity (``a → 0``, zf at a support point of the two-point distribution).
    ``a = 0`` exactly gives the linear root and +inf.
    """
    disc = b * b - 4 * a * c
    if disc < 0:  # only rounding at working precision can get here
        disc = mpmath.mpf(0)
    s = mpmath.sqrt(disc)
    t = -(b + s) / 2 if b >= 0 else -(b - s) / 2
    if a == 0:
        return (-c / b, mpmath.inf)
    r1 = t / a
    r2 = c / t if t != 0 else r1
    return (r1, r2) if r1 <= r2 else (r2, r1)


def _hankel_mp(b1, b2, b3, b4):
    """HPG17 Algorithm 1 step (1): B(b) as an mpmath matrix."""
    return mpmath.matrix([[1, b1, b2], [b1, b2, b3], [b2, b3, b4]])


def _det(B):
    """det B of a 3×3 mpmath matrix by cofactor expansion along the first row."""
    return (B[0, 0] * (B[1, 1] * B[2, 2] - B[1, 2] * B[2, 1])
            - B[0, 1] * (B[1, 0] * B[2, 2] - B[1, 2] * B[2, 0])
            + B[0, 2] * (B[1, 0] * B[2, 1] - B[1, 1] * B[2, 0]))


def _classify(b1, b2, b3, b4, tol):
    """Return (kind, σ², ξ4, B) with kind in {"single", "two", "regular"}."""
    sigma2 = b2 - b1 * b1
    if sigma2 <= tol * b2:
        return "single", sigma2, None, None
    B = _hankel_mp(b1, b2, b3, b4)
    xi4 = _det(B) / sigma2  # HPG17 Eq. (3)
    if xi4 <= tol * max(b4, sigma2):
        return "two", sigma2, xi4, B
    return "regular", sigma2, xi4, B


def _solve(A, rhs):
    """``mpmath.lu_solve``, falling back to Cramer's rule where its norm-relative
    singularity test trips on a regular but badly scaled system (b2 ≈ 1e-600)."""
    try:
        return mpmath.lu_solve(A, rhs)
    except ZeroDivisionError:
        d = _cofactor_det(A)
        if d == 0:
            raise
        out = []
        for i in range(A.rows):
            Ai = A.copy()
            for r in range(A.rows):
                Ai[r, i] = rhs[r]
            out.append(_cofactor_det(Ai) / d)
        return mpmath.matrix(out)


def _cofactor_det(A):
    """Determinant by cofactor expansion (no pivoting test; 2×2 and 3×3)."""
    if A.rows == 2:
        return A[0, 0] * A[1, 1] - A[0, 1] * A[1, 0]
    return (A[0, 0] * (A[1, 1] * A[2, 2] - A[1, 2] * A[2, 1])
            - A[0, 1] * (A[1, 0] * A[2, 2] - A[1, 2] * A[2, 0])
            + A[0, 2] * (A[1, 0] * A[2, 1] - A[1, 1] * A[2, 0]))


def _canonical_mp(b1, b2, b3, b4, zf, tol):
    """Canonical representation ((zf, z1, z2), (w0, w1, w2)) and the singular flag.

    Regular case: HPG17 Algorithm 1 steps (1)-(4) literally. Singular case: the
    unique distribution as ``(zf, y1, y2)`` with the mass at a support point equal
    to zf moved to w0 (same convention as :func:`moments_ref.msm.canonical_representation`).
    """
    kind, sigma2, _, B = _classify(b1, b2, b3, b4, tol)
    if kind != "regular":
        if kind == "single":
            y1 = y2 = b1
            v2 = mpmath.mpf(0)
        else:
            y1, y2, v2 = _two_point_mp(b1, b2, b3, sigma2)
        v1 = 1 - v2
        at1, at2 = y1 == zf, y2 == zf
        w0 = (v1 if at1 else 0) + (v2 if at2 else 0)
        w1 = mpmath.mpf(0) if at1 else v1
        w2 = mpmath.mpf(0) if at2 else v2
        return (zf, y1, y2), (mpmath.mpf(w0), w1, w2)
    # (1) Hankel matrix (built in _classify), (2) solve B q = (1, zf, zf²).
    q = _solve(B, mpmath.matrix([1, zf, zf * zf]))
    # (3) roots of q2 z² + q1 z + q0.
    z1, z2 = _roots(q[2], q[1], q[0])
    # (4) Vandermonde system for the weights.
    if mpmath.isinf(z2):  # q2 = 0 exactly: the second root sits at infinity with weight 0
        V = mpmath.matrix([[1, 1], [zf, z1]])
        w = _solve(V, mpmath.matrix([1, b1]))
        return (zf, z1, z2), (w[0], w[1], mpmath.mpf(0))
    # Columns scaled by 1/max(1, z_l²) (then unscaled): a root near infinity (zf next to
    # a support point of the two-point distribution) would otherwise trip mpmath's
    # norm-relative singularity check although the system is well posed.
    zs = (zf, z1, z2)
    scale = [max(mpmath.mpf(1), z * z) for z in zs]
    V = mpmath.matrix([[1 / s for s in scale], [z / s for z, s in zip(zs, scale)],
                       [z * z / s for z, s in zip(zs, scale)]])
    u = _solve(V, mpmath.matrix([1, b1, b2]))
    return zs, tuple(u[i] / scale[i] for i in range(3))


def _bounds_mp(b1, b2, b3, b4, zf, tol):
    """(lower, upper) of HPG17 Algorithm 1 step (5) for mpmath scalars."""
    depths, weights = _canonical_mp(b1, b2, b3, b4, zf, tol)
    lower = mpmath.fsum(w for z, w in zip(depths[1:], weights[1:]) if z < zf)
    upper = lower + weights[0]
    clamp = lambda x: min(max(x, mpmath.mpf(0)), mpmath.mpf(1))  # saturate, as the kernel
    return clamp(lower), clamp(upper)


def _prepare(b, zf, n=4):
    b = real_input(b, "b", trailing=n)
    zf = real_input(zf, "zf", dtype=b.dtype)
    shape = broadcast_pair(b[..., 0], "b[..., 0]", zf, "zf")
    return np.broadcast_to(b, shape + (n,)), np.broadcast_to(zf, shape), shape


def _bounds_over(bounds_mp, b, zf, dps):
    """``(lower, upper)`` float64 arrays of ``bounds_mp(b1, b2, b3, b4, zf, tol)`` per row, at ``dps`` digits."""
    dps = _check_dps(dps)
    b, zf, shape = _prepare(b, zf)
    lower = np.empty(shape, dtype=np.float64)
    upper = np.empty(shape, dtype=np.float64)
    with mpmath.workdps(dps):
        tol = _tol(dps)
        for idx in np.ndindex(shape):
            lo, up = bounds_mp(*(_mp(v) for v in b[idx]), _mp(zf[idx]), tol)
            lower[idx], upper[idx] = float(lo), float(up)
    return lower, upper


@fill_doc
def shadow_bounds(b, zf, dps=DPS):
    """Both bounds of HPG17 Algorithm 1 at once, in mpmath.

    Parameters
    ----------
    %(b)s
        Any float dtype; converted exactly.
    %(zf)s
    dps : int
        Working precision in decimal digits.

    Returns
    -------
    lower, upper : (...) float64 arrays
        ``lower`` the sharp lower bound of Z(z < zf), ``upper = lower + w0`` the sharp
        upper bound of Z(z ≤ zf) (exact Z of the unique distribution if B(b) is
        singular).
    """
    return _bounds_over(_bounds_mp, b, zf, dps)


def _one_bound(bounds, b, zf, bound, dps):
    """``bound`` ("lower" or "upper") of ``bounds(b, zf, dps=dps)``, the one check of its name."""
    if bound not in ("lower", "upper"):
        raise InputError(f"bound: expected 'lower' or 'upper', got {bound!r}")
    lower, upper = bounds(b, zf, dps=dps)
    return lower if bound == "lower" else upper


@fill_doc
def shadow_intensity(b, zf, bound="lower", dps=DPS):
    """mpmath twin of :func:`moments_ref.msm.shadow_intensity` (HPG17 Algorithm 1).

    Parameters
    ----------
    %(b)s
        Any float dtype; converted exactly.
    %(zf)s
    bound : {"lower", "upper"}
        Sharp lower bound of Z(z < zf), or sharp upper bound of Z(z ≤ zf).
    dps : int
        Working precision in decimal digits (default 50).

    Returns
    -------
    intensity : (...) float64 array in [0, 1]

    Notes
    -----
    Steps (1)–(5) of HPG17 Algorithm 1 literally (see the module docstring),
    singular B(b) at working precision as in :mod:`moments_ref.msm`.

    Examples
    --------
    >>> shadow_intensity([[0.0, 0.25, 0.0, 0.0625]], [0.0])
    array([0.5])
    """
    return _one_bound(shadow_bounds, b, zf, bound, dps)


def canonical_representation(b, zf, dps=DPS):
    """mpmath twin of :func:`moments_ref.msm.canonical_representation`.

    Returns
    -------
    depths : (..., 3) float64 array
        ``(zf, z1, z2)``, ``z1 ≤ z2`` (``z2 = +inf`` with weight 0 when q2 = 0
        exactly; for singular B(b) the unique distribution's ``(zf, y1, y2)``).
    weights : (..., 3) float64 array
        ``(w0, w1, w2)`` solving the Vandermonde system of Algorithm 1 step (4).
    """
    dps = _check_dps(dps)
    b, zf, shape = _prepare(b, zf)
    depths = np.empty(shape + (3,), dtype=np.float64)
    weights = np.empty(shape + (3,), dtype=np.float64)
    with mpmath.workdps(dps):
        tol = _tol(dps)
        for idx in np.ndindex(shape):
            d, w = _canonical_mp(*(_mp(v) for v in b[idx]), _mp(zf[idx]), tol)
            depths[idx] = [float(x) for x in d]
            weights[idx] = [float(x) for x in w]
    return depths, weights


def _hausdorff_mp(b1, b2, b3, b4, zf, tol):
    """(lower, upper) of the Hausdorff bound for mpmath scalars (depths in [0, 1]).

    Algorithm 1's canonical representation where its roots lie in [0, 1]; else the
    four points ``(0, zf, x, 1)``: x from ``E[Z (Z − 1)(Z − zf)(Z − x)] = 0`` with the
    polynomial ``Z (Z − 1)(Z − zf)`` multiplied out in mpmath, the weights from the
    Vandermonde system of ``(1, b1, b2, b3)`` (``mpmath.lu_solve``).
    """
    m = (mpmath.mpf(1), b1, b2, b3, b4)
    depths, weights = _canonical_mp(b1, b2, b3, b4, zf, tol)
    if all(0 <= z <= 1 for z in depths[1:]) or not 0 < zf < 1:
        lower = mpmath.fsum(w for z, w in zip(depths[1:], weights[1:]) if z < zf)
        upper = lower + weights[0]
    else:
        c = [mpmath.mpf(0), zf, -(1 + zf), mpmath.mpf(1)]  # Z (Z − 1)(Z − zf), ascending powers
        x = mpmath.fsum(ck * m[k + 1] for k, ck in enumerate(c)) / mpmath.fsum(ck * m[k] for k, ck in enumerate(c))
        zs = (mpmath.mpf(0), zf, x, mpmath.mpf(1))
        w = _solve(mpmath.matrix([[z ** k for z in zs] for k in range(4)]), mpmath.matrix(m[:4]))
        lower = w[0] + (w[2] if x < zf else 0)
        upper = lower + w[1]
    if zf <= 0:
        lower = mpmath.mpf(0)  # no mass of a distribution on [0, 1] lies below 0
    if zf >= 1:
        upper = mpmath.mpf(1)
    clamp = lambda v: min(max(v, mpmath.mpf(0)), mpmath.mpf(1))  # noqa: E731 (saturate, as the kernel)
    return clamp(lower), clamp(upper)


def hausdorff_bounds(b, zf, dps=DPS):
    """mpmath twin of :func:`moments_ref.hausdorff.shadow_bounds` (Peters and Klein 2015, Hausdorff bound).

    ``b`` moments of depths in [0, 1] and ``zf`` in [0, 1] (the ``unit`` depth space); any
    float dtype, converted exactly. Returns ``(lower, upper)`` as float64 arrays.
    """
    return _bounds_over(_hausdorff_mp, b, zf, dps)


def hausdorff_intensity(b, zf, bound="lower", dps=DPS):
    """mpmath twin of :func:`moments_ref.hausdorff.shadow_intensity`: ``bound`` of :func:`hausdorff_bounds`."""
    return _one_bound(hausdorff_bounds, b, zf, bound, dps)


def pivots(b, dps=DPS):
    """The pivots σ² and ξ4 of ``B(b) = L D Lᵀ``, ``D = diag(1, σ², ξ4)``, in mpmath.

    ``σ² = b2 − b1²`` and ``ξ4 = det B(b) / σ²`` (HPG17 Eq. (3));
    ξ4 is NaN where σ² = 0. Negative values mean b lies outside the moment space.

    Returns
    -------
    p : (..., 2) float64 array
        ``(σ², ξ4)``.
    """
    dps = _check_dps(dps)
    b = _moment_input(b)
    out = np.empty(b.shape[:-1] + (2,), dtype=np.float64)
    with mpmath.workdps(dps):
        for idx in np.ndindex(b.shape[:-1]):
            b1, b2, b3, b4 = (_mp(v) for v in b[idx])
            sigma2 = b2 - b1 * b1
            xi4 = _det(_hankel_mp(b1, b2, b3, b4)) / sigma2 if sigma2 != 0 else mpmath.nan
            out[idx] = [float(sigma2), float(xi4)]
    return out


# ---------------------------------------------------------------------------
# non-linear representation (HPG17 §3)


def _phi_mp(b1, b2, b3, b4, tol):
    """HPG17 Algorithm 2 on mpmath scalars -> (y1, y2, v2, ξ4)."""
    # (1) σ² = q2, (2) q1, (3) q0.
    sigma2 = b2 - b1 * b1
    if sigma2 <= tol * b2:
        # Zero variance: Algorithm 2 is undefined; the representation of one depth
        # at b1 is y1 = y2 = b1, v2 = 0 and ξ4 from Eq. (1).
        return b1, b1, mpmath.mpf(0), b4 - b1**4
    q1 = b1 * b2 - b3
    q0 = -b1 * q1 - b2 * sigma2
    # (4) roots, (5) v2.
    y1, y2 = _roots(sigma2, q1, q0)
    v2 = (b1 - y1) / (y2 - y1)
    # (6) L21, (7) ξ4.
    l21 = (b3 - b1 * b2) / sigma2
    xi4 = b4 - b2 * b2 - l21 * l21 * sigma2
    return y1, y2, v2, xi4


def _phi_inverse_mp(y1, y2, v2, xi4):
    """HPG17 Eq. (4): b = (1 − v2) b(y1) + v2 b(y2) + (0, 0, 0, 0, ξ4)."""
    v1 = 1 - v2
    b = [v1 * y1**k + v2 * y2**k for k in range(1, 5)]
    b[3] += xi4
    return b


@fill_doc
def phi(b, dps=DPS):
    """mpmath twin of ``nonlinear.phi`` (HPG17 Algorithm 2).

    Parameters
    ----------
    %(b)s
        Any float dtype; converted exactly. HPG17 applies the
        float32 bias before Algorithm 2; this function takes b as given.

    Returns
    -------
    r : (..., 4) float64 array
        ``(y1, y2, v2, ξ4)`` with ``y1 ≤ y2``, ξ4 from step (7) (negative outside
        the moment space, not clamped). Zero variance at working precision gives
        ``(b1, b1, 0, b4 − b1⁴)`` (Eq. (1) for one depth).
    """
    dps = _check_dps(dps)
    b = _moment_input(b)
    out = np.empty(b.shape, dtype=np.float64)
    with mpmath.workdps(dps):
        tol = _tol(dps)
        for idx in np.ndindex(b.shape[:-1]):
            out[idx] = [float(x) for x in _phi_mp(*(_mp(v) for v in b[idx]), tol)]
    return out


@fill_doc
def phi_inverse(r, dps=DPS):
    """mpmath twin of ``nonlinear.phi_inverse`` (HPG17 Eq. (4)).

    Parameters
    ----------
    %(r)s

    Returns
    -------
    b : (..., 4) float64 array
        Moments b1..b4, each rounded once from the exact value.
    """
    dps = _check_dps(dps)
    r = real_input(r, "r", trailing=4)
    out = np.empty(r.shape, dtype=np.float64)
    with mpmath.workdps(dps):
        for idx in np.ndindex(r.shape[:-1]):
            out[idx] = [float(x) for x in _phi_inverse_mp(*(_mp(v) for v in r[idx]))]
    return out


def phi_exact(b, preset=None, dps=DPS):
    """HPG17 Algorithm 2 on the (biased) moments, unrounded: mpmath numbers for twins that quantize Φ.

    Parameters
    ----------
    b : (n, 4) float array
        Moments b1..b4 as the chain receives them; converted exactly.
    preset : BiasPreset, name or None
        The bias applied first, exactly: ``(1 − α) b + α b*`` (Slides, "Bias the moments"; α and b*
        the float64 numbers of the preset, as :func:`bias_moments`). None: b as given.

    Returns
    -------
    r : (n, 4) object array of mpmath.mpf
        ``(y1, y2, v2, ξ4)`` of :func:`phi`, computed at ``dps`` digits and not rounded to float64, so
        that a quantizer can compare them with its code boundaries exactly (HPG17 §3.3, §3.5).
        Evaluate further arithmetic on them inside ``mpmath.workdps(dps)``.
    """
    dps = _check_dps(dps)
    b = _moment_input(b).reshape(-1, 4)
    p = None if preset is None else (preset if isinstance(preset, BiasPreset) else bias_preset(preset))
    out = np.empty(b.shape, dtype=object)
    with mpmath.workdps(dps):
        a, t = (0, [0] * 4) if p is None else (_mp(p.alpha), [_mp(x) for x in p.target])  # a = 0: b exactly
        for i, row in enumerate(b):
            out[i] = list(_phi_mp(*((1 - a) * _mp(v) + a * tk for v, tk in zip(row, t)), _tol(dps)))
    return out


def psi4(xi4, dps=DPS):
    """mpmath twin of ``nonlinear.psi4`` (HPG17 §3.3).

    ``Ψ4(ξ4) = (ln ln(max(1.2e-7, ξ4)·1e7) − ln ln 1.2) / (ln ln(0.25·1e7) − ln ln 1.2)``.

    Returns
    -------
    u : (...) float64 array (not clamped above: ξ4 > 0.25 gives u > 1)
    """
    dps = _check_dps(dps)
    x = real_input(xi4, "xi4")
    out = np.empty(x.shape, dtype=np.float64)
    with mpmath.workdps(dps):
        lo = mpmath.mpf("1.2e-7")
        c0 = mpmath.log(mpmath.log(mpmath.mpf("1.2")))
        c1 = mpmath.log(mpmath.log(mpmath.mpf("0.25") * 10**7)) - c0
        for idx in np.ndindex(x.shape):
            v = max(lo, _mp(x[idx]))
            out[idx] = float((mpmath.log(mpmath.log(v * 10**7)) - c0) / c1)
    return out


def psi4_inverse(u, dps=DPS):
    """Inverse of :func:`psi4` on [0, 1]: ``ξ4 = 1e-7·exp(exp(c0 + u·c1))``.

    With ``c0 = ln ln 1.2`` and ``c1 = ln ln(0.25·1e7) − c0`` (HPG17 §3.3).
    """
    dps = _check_dps(dps)
    x = real_input(u, "u")
    out = np.empty(x.shape, dtype=np.float64)
    with mpmath.workdps(dps):
        c0 = mpmath.log(mpmath.log(mpmath.mpf("1.2")))
        c1 = mpmath.log(mpmath.log(mpmath.mpf("0.25") * 10**7)) - c0
        for idx in np.ndindex(x.shape):
            out[idx] = float(mpmath.exp(mpmath.exp(c0 + _mp(x[idx]) * c1)) / 10**7)
    return out


@fill_doc
def shade(r, zf, dps=DPS):
    """Exact lower bound for a non-linear representation: Algorithm 1 on Eq. (4).

    Parameters
    ----------
    %(r)s
        Any float dtype; converted exactly.
    %(zf)s

    Returns
    -------
    intensity : (...) float64 array in [0, 1]

    Notes
    -----
    HPG17 §3.4 suggests reconstructing the moments with Eq. (4) and running
    Algorithm 1; that is what this does, in mpmath, without rounding the moments.
    It is therefore an independent check of HPG17 Algorithm 3 and carries none of
    its clamps (1e-6 away from y1 = y2, v2 ∈ {0, 1}; ξ4 ≥ 1.2e-7 in Ψ4).

    The domain is that of :func:`moments_ref.nonlinear.shade`
    (:func:`~moments_ref.nonlinear.validate_representation`): ``y1 ≤ y2``,
    ``v2 ∈ [0, 1]``, ``ξ4 ≥ 0`` up to rounding (which is clamped away), else
    :class:`~moments_ref.InputError`.
    """
    dps = _check_dps(dps)
    r = validate_representation(r, "r")  # the domain check of nonlinear.shade
    zf = real_input(zf, "zf", dtype=r.dtype)
    shape = broadcast_pair(r[..., 0], "r[..., 0]", zf, "zf")
    r = np.broadcast_to(r, shape + (4,))
    zf = np.broadcast_to(zf, shape)
    out = np.empty(shape, dtype=np.float64)
    with mpmath.workdps(dps):
        tol = _tol(dps)
        for idx in np.ndindex(shape):
            b = _phi_inverse_mp(*(_mp(v) for v in r[idx]))
            out[idx] = float(_bounds_mp(*b, _mp(zf[idx]), tol)[0])
    return out


# ---------------------------------------------------------------------------
# six moments (the twin of moments_ref.msm6)
#
# Literally: the 4×4 Hankel matrix B(b), ``B q = (1, zf, zf², zf³)`` by
# ``mpmath.lu_solve``, the roots of ``q3 z³ + q2 z² + q1 z + q0`` by
# ``mpmath.polyroots`` and the weights by a Vandermonde solve of
# ``Σ w_l z_l^k = b_k`` (k = 0..3). The pivots come from determinants
# (``D1 = b2 − b1²``, ``D2 = det B3 / D1``, ``D3 = det B4 / det B3``), not from
# the LDLᵀ recurrence of the kernel. Singular B(b) at working precision, with the
# definitions of moments_ref.msm6: one depth, two depths (Algorithm 2 on b1..b3)
# or three depths, the roots of the monic polynomial ``z³ + a2 z² + a1 z + a0``
# with ``B3 a = −(b3, b4, b5)``, weights from the Vandermonde system.


def _pivots6_mp(b):
    """(D1, D2, D3) from determinants; b = [1, b1, ..., b6] mpmath."""
    d = [mpmath.mpf(1)]
    for m in (2, 3, 4):
        d.append(mpmath.det(mpmath.matrix([[b[i + j] for j in range(m)] for i in range(m)])))
    return [d[k] / d[k - 1] if d[k - 1] != 0 else mpmath.nan for k in (1, 2, 3)]


def _vandermonde_weights(zs, rhs):
    """Solve Σ_l w_l z_l^k = rhs_k (k = 0..len-1), columns scaled by 1/max(1, |z|^(n-1))."""
    n = len(zs)
    scale = [max(mpmath.mpf(1), abs(z) ** (n - 1)) for z in zs]
    V = mpmath.matrix([[z**k / s for z, s in zip(zs, scale)] for k in range(n)])
    u = mpmath.lu_solve(V, mpmath.matrix(rhs))
    return [u[i] / scale[i] for i in range(n)]


def _real_roots(coeffs):
    """Real parts of the roots of a polynomial (highest power first), ascending."""
    roots = mpmath.polyroots(coeffs, maxsteps=400, extraprec=4 * mpmath.mp.prec)
    return sorted(mpmath.re(r) for r in roots)


def _singular6_mp(b, piv, tol):
    """The unique distribution (depths, weights) of singular B(b), or None if regular."""
    D1, D2, D3 = piv
    if not D1 > tol * b[2]:
        return [b[1]], [mpmath.mpf(1)]
    if not D2 > tol * max(b[4], D1):
        y1, y2, v2 = _two_point_mp(b[1], b[2], b[3], D1)
        return [y1, y2], [1 - v2, v2]
    if not D3 > tol * max(b[6], D2):
        B3 = mpmath.matrix([[b[i + j] for j in range(3)] for i in range(3)])
        a = mpmath.lu_solve(B3, mpmath.matrix([-b[3], -b[4], -b[5]]))
        zs = _real_roots([1, a[2], a[1], a[0]])
        return zs, _vandermonde_weights(zs, b[0:3])
    return None


def _canonical6_mp(b, zf, tol):
    """((zf, z1, z2, z3), (w0, w1, w2, w3)) for b = [1, b1..b6] mpmath scalars."""
    piv = _pivots6_mp(b)
    sing = _singular6_mp(b, piv, tol)
    if sing is not None:
        zs, ws = sing
        zs = list(zs) + [mpmath.inf] * (3 - len(zs))
        ws = list(ws) + [mpmath.mpf(0)] * (3 - len(ws))
        w0 = mpmath.fsum(w for z, w in zip(zs, ws) if z == zf)
        ws = [mpmath.mpf(0) if z == zf else w for z, w in zip(zs, ws)]
        return [zf] + zs, [w0] + ws
    B = mpmath.matrix([[b[i + j] for j in range(4)] for i in range(4)])
    q = mpmath.lu_solve(B, mpmath.matrix([1, zf, zf**2, zf**3]))
    if q[3] == 0:  # a root at infinity, weight 0
        zs = _real_roots([q[2], q[1], q[0]]) + [mpmath.inf]
        w = _vandermonde_weights([zf] + zs[:2], b[0:3])
        return [zf] + zs, w + [mpmath.mpf(0)]
    zs = _real_roots([q[3], q[2], q[1], q[0]])
    w = _vandermonde_weights([zf] + zs, b[0:4])
    return [zf] + zs, w


def _bounds6_mp(b, zf, tol):
    depths, weights = _canonical6_mp(b, zf, tol)
    lower = mpmath.fsum(w for z, w in zip(depths[1:], weights[1:]) if z < zf)
    upper = lower + weights[0]
    clamp = lambda x: min(max(x, mpmath.mpf(0)), mpmath.mpf(1))  # saturate, as the kernel
    return clamp(lower), clamp(upper)


@fill_doc
def shadow_bounds6(b, zf, dps=DPS):
    """mpmath twin of :func:`moments_ref.msm6.shadow_bounds` (six moments).

    Parameters
    ----------
    b : (..., 6) float array
        Moments b1..b6 (any float dtype; converted exactly).
    %(zf)s
    dps : int
        Working precision in decimal digits.

    Returns
    -------
    lower, upper : (...) float64 arrays
        Sharp lower bound of Z(z < zf) and sharp upper bound of Z(z ≤ zf)
        (exact Z of the unique distribution for singular B(b)).
    """
    dps = _check_dps(dps)
    b, zf, shape = _prepare(b, zf, 6)
    lower = np.empty(shape, dtype=np.float64)
    upper = np.empty(shape, dtype=np.float64)
    with mpmath.workdps(dps):
        tol = _tol(dps)
        for idx in np.ndindex(shape):
            full = [mpmath.mpf(1)] + [_mp(v) for v in b[idx]]
            lo, up = _bounds6_mp(full, _mp(zf[idx]), tol)
            lower[idx], upper[idx] = float(lo), float(up)
    return lower, upper


def shadow_intensity6(b, zf, bound="lower", dps=DPS):
    """mpmath twin of :func:`moments_ref.msm6.shadow_intensity`.

    Returns
    -------
    intensity : (...) float64 array in [0, 1]

    Examples
    --------
    >>> shadow_intensity6([[0.0, 0.25, 0.0, 0.0625, 0.0, 0.015625]], [0.0])
    array([0.5])
    """
    return _one_bound(shadow_bounds6, b, zf, bound, dps)


def canonical_representation6(b, zf, dps=DPS):
    """mpmath twin of :func:`moments_ref.msm6.canonical_representation`.

    Returns
    -------
    depths : (..., 4) float64 array
        ``(zf, z1, z2, z3)`` ascending after zf (+inf for an unused or infinite root).
    weights : (..., 4) float64 array
        From the Vandermonde system of the canonical representation.
    """
    dps = _check_dps(dps)
    b, zf, shape = _prepare(b, zf, 6)
    depths = np.empty(shape + (4,), dtype=np.float64)
    weights = np.empty(shape + (4,), dtype=np.float64)
    with mpmath.workdps(dps):
        tol = _tol(dps)
        for idx in np.ndindex(shape):
            full = [mpmath.mpf(1)] + [_mp(v) for v in b[idx]]
            d, w = _canonical6_mp(full, _mp(zf[idx]), tol)
            depths[idx] = [float(x) for x in d]
            weights[idx] = [float(x) for x in w]
    return depths, weights
