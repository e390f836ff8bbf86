"""Moment shadow mapping: HPG17 Algorithm 1 (Peters and Klein 2015).

Given moments ``b = (b1, b2, b3, b4)`` of a depth distribution Z (b0 = 1) and a
fragment depth ``zf``, Algorithm 1 returns the sharp lower bound of ``Z(z < zf)``
over all distributions with these moments. The minimizing distribution has three
points of support ``zf, z1, z2`` (the *canonical representation*, HPG17 Fig. 2).

Implementation notes (why the code does not read like the algorithm box line by
line):

* Step (2) solves ``B(b) q = (1, zf, zf²)`` through the factorization
  ``B = L D Lᵀ`` (L unit lower triangular, ``D = diag(1, σ², ξ4)``), as the slides
  insist; the third pivot is HPG17's ξ4 (Eq. (3)).
* Step (3) uses the cancellation-free quadratic formula, so a leading coefficient
  ``q2 → 0`` (zf at a support point of the two-point representation) sends one
  root to ±inf instead of producing 0/0.
* Step (4) is replaced by HPG17 §3.4's ``w_l = 1 / ((1, z_l, z_l²) B⁻¹ (1, z_l, z_l²)ᵀ)``
  (Peters and Klein 2015, Prop. 10), evaluated as ``Σ (L⁻¹v)_i² / D_i``: it
  needs no Vandermonde solve, is exactly 0 for a root at infinity and is
  positive by construction. ``w2 = 1 − w0 − w1`` because b0 = 1. The bounds alone
  (:func:`shadow_intensity`) take a shorter route that is as accurate: the quadratic
  of step (3) written about zf, ``q2 t² − p'(zf) t + 1/w0`` in ``t = zf − z``, whose root
  weight ``w1 = ((1 − w0)/2·(S + p'(zf)) − (zf − b1) q2)/S`` (S the square root of its
  discriminant; w1 from the first two moments about zf) is, with q2 replaced by
  ``min(q2, 0)``, the bound of step (5) in all its cases, with the texels where that
  has no finite value handed to the full kernel (:func:`_bound_rows`). The mpmath twin
  in :mod:`moments_ref.precise` solves the Vandermonde system literally and
  serves as the independent check.

Degenerate input. When ``B(b)`` is singular the distribution with these moments
is unique and ``Z(z < zf)`` is known exactly; both bounds then return it:

* ``σ² = b2 − b1² ≤ τ·b2``: one depth at ``b1``;
* otherwise ``ξ4 ≤ τ·max(b4, σ²)``: the two-point distribution of HPG17
  Algorithm 2 (depths y1 < y2, weights 1 − v2, v2).

The relative threshold ``τ = SINGULAR_RTOL[dtype]·eps`` is ``8·eps`` in float64:
moments of one or two depths computed in float64 round to pivots of that size,
while biased moments (α ≥ 3e-7) lie nine orders of magnitude above it. In
float32 ``τ = 0``: ``BIAS_FLOAT32`` lifts ξ4 only to about
``α·λmin(B(b*)) ≈ 6e-8``, which is float32's own rounding of b4, so any positive
threshold would catch biased moments and replace the paper's bound by a hard step
at a *rounded* support point (measured: up to 0.96 above the true Z when zf lies
between the rounded and the true support point). float32 therefore takes the
singular branch only for pivots that are zero or negative, or where the regular
branch overflows: unbiased moments of a cluster whose width is near float32's
resolution (``b = (1.38889e-05, 1.92979e-10, 2.68242e-15, 3.73012e-20)``) have a ξ4
of rounding noise (10⁻²⁵ here), the coefficients of step (3) reach 10²⁴ and their
squares overflow, which gave NaN depths and 0 where the truth is 1. A non-finite
discriminant marks such a texel singular; biased moments never get there
(``ξ4 ≥ 6e-8`` keeps the coefficients below 10⁸). Rounding can also put
``w0 + w1`` just above 1 (seen: ``w2 = −4.5e−6``); w2 is clamped at 0.

The regular branch has the same limit in float32: where the bias lifts ξ4 by a
float32 unit of b4 or less (near two-point texels; least where a depth sits on one
of the bias target's atoms at ±1), float32's ξ4 is mostly rounding, and a receiver on
one of the texel's depths may be put on either side of it (measured: 0.906 where the
exact bound of the same float32 moments is 5e-8; docs/stability.md, "zf at a depth
at ±1"). float64 stays within 3e-11 there.

Negative σ² or ξ4 (moments just outside the moment space after rounding)
fall into the same branches: they are projected onto the boundary of the moment
space, which keeps b1..b3 (or b1) and lowers b4 (or b2). Further outside the
result is that of the projection, not an error; bias the moments to stay inside.

Bounds. ``lower ≤ Z(z < zf) ≤ Z(z ≤ zf) ≤ upper``: the upper bound is
``lower + w0``, the largest mass a distribution with these moments can have at or
below zf. For a unique (singular) distribution both are attained.

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

import threading

import numpy as np

from ._arrays import InputError, lookup_inputs, real_input, refuse_lookup
from ._docs import fill_doc
from ._kernels import MSM_CHUNK, SINGULAR_RTOL, broadcast_chunks, singular_thresholds, two_point

__all__ = [
    "shadow_intensity",
    "canonical_representation",
    "reduce_light_leaking",
    "SINGULAR_RTOL",
    "singular_thresholds",
]

# One home for the chunk size, the singularity threshold and the two-point step (HPG17
# Algorithm 2), shared with msm6 and nonlinear; re-exported here (public names).
_two_point = two_point

#: :data:`moments_ref._kernels.MSM_CHUNK` (2^15 texels): half the kernel's chunk in both dtypes
#: (:func:`chunk_texels`).
CHUNK = MSM_CHUNK

def chunk_texels(dtype):
    """Texels per chunk of the kernel for ``dtype``: ``4·CHUNK`` (2^17) in float32, ``2·CHUNK`` (2^16) in float64.

    Each ufunc call per chunk costs about 0.65 µs besides its elements (measured: 2048² float32
    from chunks of 2^12 to 2^17, 17.8, 13.4, 11.0, 10.0, 9.5, 9.4 ns a texel, load 10.6), and a
    pass over rows that stay in the 1 MiB L2 of a core is no cheaper per element than one over
    rows in L3 (0.13–0.16 ns a float32 element from 2^13 to 2^17): the largest chunk whose
    rows keep the kernel's working set near L2 wins. For the 38-pass bounds (issue 41, round
    six), interleaved A/B at 2048², 15 pairs, CPU time, load 12–14: float32 2^16 0.91
    (quartiles 0.86–0.93) of the time of 2^17 and 2^15 1.03 (1.01–1.05) of 2^16; float64 2^16
    0.91 (0.88–0.92) of 2^15. Round twelve, on the quiet machine (the bench's 2048² input, 21
    interleaved rounds, CPU time): float32 2^17 0.962 (0.956–0.975) and 0.987 (0.984–0.995) of
    the time of 2^16 at load 1.0 and 1.7, 0.996 (0.914–1.031) beside a process streaming memory
    on the other core; so float32 takes 2^17 (the loaded machine of round six, where other
    sessions shared the L3, no longer decides it). The results do not depend on the chunk.
    docs/bench.md, "Where Algorithm 1's time goes".
    """
    return 4 * CHUNK if np.dtype(dtype) == np.float32 else 2 * CHUNK


def _constants(dtype, n):
    """Constant arrays for the kernel (array–array ufunc loops are the fast ones), and its workspace.

    ``ws`` holds the kernel's float rows (``_ROWS`` of them) and two boolean rows: every step
    writes into them (``out=``), so a chunk allocates nothing and its rows stay in cache.
    """
    it = np.int32 if np.dtype(dtype) == np.float32 else np.int64
    return {
        "zero": np.zeros(n, dtype=dtype),
        "one": np.ones(n, dtype=dtype),
        "sign": np.full(n, np.iinfo(it).min, dtype=it),
        "two": np.dtype(dtype).type(2),
        "rtol": np.dtype(dtype).type(singular_thresholds(dtype)),
        "ws": np.empty((_ROWS, n), dtype=dtype),
        "bits": np.empty(n, dtype=it),
        "mask": np.empty((2, n), dtype=bool),
    }


#: Float rows of the kernel's workspace (:func:`_constants`).
_ROWS = 9

#: Per thread, the constants and workspace of a whole chunk per dtype (:func:`_chunk_constants`).
_LOCAL = threading.local()


def _chunk_constants(dtype, n):
    """:func:`_constants` for ``n ≤ chunk_texels(dtype)`` texels: views of one set per thread and dtype, kept.

    Fresh chunk-sized arrays are faulted in from the OS on every call (measured: a call of one
    chunk of float32 took 4.5 times the per-texel time of a call of 2^20 texels); kept, they cost
    7 MB (float32, 2^17 texels) or 6.9 MB (float64, 2^16) per thread that called. Per
    thread, so that concurrent calls never share a workspace.
    """
    chunk = chunk_texels(dtype)
    cache, key = _LOCAL.__dict__.setdefault("consts", {}), (np.dtype(dtype).name, chunk)
    if key not in cache:
        if len(cache) >= 4:  # float32 and float64 (the key's chunk size only guards a changed CHUNK)
            cache.clear()
        cache[key] = _constants(dtype, chunk)
    full = cache[key]
    return full if n == chunk else {k: v[..., :n] if np.ndim(v) else v for k, v in full.items()}


def _cholesky(b, ws):
    """Step (2) begins with the Cholesky decomposition ``B(b) = L D Lᵀ``, without square roots.

    ``L = [[1], [b1, 1], [b2, L32, 1]]`` and ``D = diag(1, σ², ξ4)`` with ``σ² = b2 − b1²``,
    ``L32 = (b3 − b1 b2)/σ²`` and ``ξ4 = b4 − b2² − L32² σ²`` (HPG17 Eq. (3)). Writes
    σ², L32, ξ4 into ``ws[0:3]`` (ten passes).
    """
    b1, b2, b3, b4 = b
    sigma2, l32, xi4, t = ws[0], ws[1], ws[2], ws[8]
    np.multiply(b1, b1, out=sigma2)
    np.subtract(b2, sigma2, out=sigma2)
    np.multiply(b1, b2, out=l32)
    np.subtract(b3, l32, out=l32)
    np.divide(l32, sigma2, out=l32)
    # E_S(z⁴) = b2² + L32² σ², S the two-point distribution (HPG17 Eq. (1)); ξ4 = b4 − E_S(z⁴).
    np.multiply(l32, l32, out=xi4)
    np.multiply(xi4, sigma2, out=xi4)
    np.multiply(b2, b2, out=t)
    np.add(xi4, t, out=xi4)
    np.subtract(b4, xi4, out=xi4)
    return sigma2, l32, xi4


def _singular_rows(b, sigma2, xi4, finite, c):
    """Singular B(b) (module docstring): ``σ² ≤ τ·b2`` or ``ξ4 ≤ τ·max(b4, σ²)``, or a non-finite root.

    Returns the mask (a row of the workspace, or a fresh array in float64) of the singular texels.
    """
    regular = c["mask"][1]
    if c["rtol"] == 0:  # float32: the pivots' signs only (a NaN pivot fails both comparisons)
        np.greater(sigma2, c["zero"], out=regular)
        regular &= xi4 > c["zero"]
    else:
        _, b2, _, b4 = b
        np.greater(sigma2, b2 * c["rtol"], out=regular)
        regular &= xi4 > np.maximum(b4, sigma2) * c["rtol"]
    regular &= finite
    return np.logical_not(regular, out=regular)


def _forward(zf, b1, b2, l32, y2, y3, t):
    """Forward substitution L y = (1, zf, zf²) of HPG17 Algorithm 1, step 2, into ``y2``, ``y3`` (``t`` scratch):
    y2 = zf − b1, y3 = zf² − b2 − L32 y2 (y1 = 1)."""
    np.subtract(zf, b1, y2)
    np.multiply(zf, zf, y3)
    np.subtract(y3, b2, y3)
    np.multiply(l32, y2, t)
    np.subtract(y3, t, y3)


def _solve(b, zf, sigma2, l32, xi4, ws):
    """Step (2): ``B(b) q = (1, zf, zf²)``, and ``w0 = 1 / ((1, zf, zf²) B⁻¹ (1, zf, zf²)ᵀ)``.

    Returns ``(q0, q1, q2, w0)`` (rows 3–6 of ``ws``). w0 is the weight of zf in the canonical
    representation (Peters and Klein 2015, Prop. 10): ``1 / (1 + y2²/σ² + y3²/ξ4)`` with y
    from the forward substitution, a sum of squares (no cancellation).
    """
    b1, b2 = b[0], b[1]
    q0, q1, q2, w0, y2, t = ws[3], ws[4], ws[5], ws[6], ws[7], ws[8]
    # Forward substitution to solve L y = (1, zf, zf²): y1 = 1 (y3 lives in q0 until q2 is known).
    y3 = q0
    _forward(zf, b1, b2, l32, y2, y3, t)
    # Scaling to solve D c = y: c1 = 1, c2 = y2/σ² (in q1 until the back substitution), c3 = q2.
    c2 = q1
    np.divide(y2, sigma2, out=c2)
    np.divide(y3, xi4, out=q2)
    # 1/w0 = 1 + y2 c2 + y3 c3.
    np.multiply(y2, c2, out=w0)
    np.multiply(y3, q2, out=t)
    np.add(w0, t, out=w0)
    np.add(w0, 1, out=w0)
    np.divide(1, w0, out=w0)
    # Back substitution to solve Lᵀ q = c.
    np.multiply(l32, q2, out=t)
    np.subtract(c2, t, out=q1)
    # The first row of B q = (1, zf, zf²): q0 = 1 − b1 q1 − b2 q2.
    np.multiply(b1, q1, out=q0)
    np.multiply(b2, q2, out=t)
    np.add(q0, t, out=q0)
    np.subtract(1, q0, out=q0)
    return q0, q1, q2, w0


def _roots(q0, q1, q2, b4, c):
    """Step (3): the roots ``z1 ≤ z2`` of ``q2 z² + q1 z + q0``, and where they are finite.

    Without cancellation: ``s = −q1/2 − sign(q1)·√(q1²/4 − q2 q0)`` has none, and the
    roots are ``s/q2`` and ``q0/s`` (Vieta). ``q2 → 0`` (zf at a support point of the
    two-point representation) sends one root to ±∞ instead of giving 0/0. A non-finite
    discriminant (q1² or q2·q0 overflowing: ξ4 at the rounding level of b4 in float32)
    marks the texel singular; ``d + b4`` also catches ``b4 = +∞``, the one non-finite
    input that leaves the pivots and the discriminant finite (d ≤ 2e19 in float32, so
    only a b4 within that of the largest float overflows besides). z1, z2 go to rows 7
    and 4 of the workspace (q1's row: q1 is used up here).
    """
    ws = c["ws"]
    h, root, t = ws[7], ws[8], q1
    np.multiply(q1, -0.5, out=h)
    np.multiply(h, h, out=root)
    np.multiply(q2, q0, out=t)
    np.subtract(root, t, out=root)
    np.maximum(root, c["zero"], out=root)
    np.sqrt(root, out=root)
    finite = c["mask"][0]
    np.add(root, b4, out=t)
    np.isfinite(t, out=finite)
    # root takes h's sign (bit-level copysign, root ≥ 0): s = h + sign(h)·root.
    sign, bits = c["sign"], c["bits"]
    np.bitwise_and(h.view(sign.dtype), sign, out=bits)
    np.bitwise_or(root.view(sign.dtype), bits, out=root.view(sign.dtype))
    np.add(h, root, out=h)
    np.divide(h, q2, out=root)  # ra
    np.divide(q0, h, out=t)  # rb
    z1, z2 = h, t
    np.minimum(root, t, out=z1)
    np.maximum(root, t, out=z2)
    return z1, z2, finite


def _weights(z1, b, sigma2, l32, xi4, w0, c):
    """Step (4): ``w1 = 1 / ((1, z1, z1²) B⁻¹ (1, z1, z1²)ᵀ)`` and ``w2 = 1 − w0 − w1``.

    HPG17 §3.4 (Peters and Klein 2015, Prop. 10) instead of the Vandermonde solve of the
    algorithm box: ``u = L⁻¹(1, z1, z1²)``, ``w1 = 1 / (1 + u2²/σ² + u3²/ξ4)``, positive
    by construction and 0 for a root at infinity (its NaN, ∞ − ∞, becomes 0). ``w2``
    uses b0 = 1; ``w0 + w1`` may round above 1 (−4.5e−6 seen in float32), so w2 ≥ 0.
    w1 and w2 go to rows 3 and 5 of the workspace (q0's and q2's, used up).
    """
    b1, b2 = b[0], b[1]
    ws = c["ws"]
    u2, u3, w1, w2 = ws[8], ws[3], ws[3], ws[5]
    np.subtract(z1, b1, out=u2)
    np.multiply(z1, z1, out=u3)
    np.subtract(u3, b2, out=u3)
    np.multiply(l32, u2, out=w2)
    np.subtract(u3, w2, out=u3)
    np.multiply(u2, u2, out=u2)  # 1/w1 = 1 + u2²/σ² + u3²/ξ4
    np.divide(u2, sigma2, out=u2)
    np.multiply(u3, u3, out=u3)
    np.divide(u3, xi4, out=u3)
    np.add(u2, u3, out=u2)
    np.add(u2, 1, out=u2)
    np.divide(1, u2, out=w1)
    np.fmax(w1, c["zero"], out=w1)
    np.subtract(1, w0, out=w2)
    np.subtract(w2, w1, out=w2)
    return w1, np.maximum(w2, c["zero"], out=w2)


def _kernel(b, zf, want, c, dest, refuse):
    """HPG17 Algorithm 1 on flat chunks: b (4, n) rows b1..b4, zf (n,) -> dict.

    One function per step of the algorithm box (step (1), B(b), stays implicit in the
    rows b): :func:`_cholesky` and :func:`_solve` (2), :func:`_roots` (3),
    :func:`_weights` (4), the sum below (5). ``want`` is drawn from {"lower", "upper",
    "canonical"}; ``c`` holds the constant arrays and the workspace of :func:`_constants`
    (same length); a bound in ``want`` is written into ``dest[bound]`` when ``dest`` has
    it; ``refuse()`` raises the error of a NaN or inf in the input. Every case is computed
    for every element and step (5) multiplies by 0/1 masks: ``np.where``, masked ufuncs and
    array–scalar ``np.maximum`` cost several arithmetic passes each in NumPy. Every step
    writes into the workspace rows (``out=``): no chunk allocates. The per-chunk cost is
    in docs/bench.md ("Kernel history").
    """
    ws = c["ws"]
    with np.errstate(divide="ignore", invalid="ignore", over="ignore", under="ignore"):
        sigma2, l32, xi4 = _cholesky(b, ws)
        q0, q1, q2, w0 = _solve(b, zf, sigma2, l32, xi4, ws)
        z1, z2, finite = _roots(q0, q1, q2, b[3], c)
        w1, w2 = _weights(z1, b, sigma2, l32, xi4, w0, c)
        singular = _singular_rows(b, sigma2, xi4, finite, c)
        # Step (5): lower = Σ_{z_l < zf} w_l = [zf > z1]·(w1 + [zf > z2]·w2) (z1 ≤ z2).
        lower = dest.get("lower", ws[2] if "canonical" not in want else np.empty_like(zf))
        above = c["mask"][0]
        np.greater(zf, z2, out=above)
        np.multiply(w2, above, out=lower)
        np.add(lower, w1, out=lower)
        np.greater(zf, z1, out=above)
        np.multiply(lower, above, out=lower)
    if singular.any():
        # A NaN or inf in b or zf makes its texel singular (a pivot or the discriminant is
        # not finite, see _roots), so the chunk needs its full check only here.
        if not (np.isfinite(b).all() and np.isfinite(zf).all()):
            refuse()
        _unique_distribution(b, zf, singular, c["rtol"], lower, w0, (z1, z2), (w1, w2))
    out = {}
    # Clamped to 1 like saturate (w0 + w1, or w1 + w2 computed from it, may round above 1);
    # every term is ≥ 0, so the bounds are.
    if "upper" in want:
        upper = dest.get("upper", ws[0])
        np.add(lower, w0, out=upper)
        out["upper"] = np.minimum(upper, c["one"], out=upper)
    if "lower" in want:
        out["lower"] = np.minimum(lower, c["one"], out=lower)
    if "canonical" in want:
        out["depths"] = np.stack([zf, z1, z2], axis=-1)
        out["weights"] = np.stack([w0, w1, w2], axis=-1)
    return out


def _quadratic_about_zf(b, zf, c):
    """Steps (1)–(3) of :func:`_bound_rows`: ``(k2, q2m, 1/w0, 1/w0 − 1, y2, regular)``, rows of ``c["ws"]``.

    ``k2 = p'(zf)``, ``q2m = min(q2, 0)``; ``regular``: :func:`_pivots_positive`'s mask, or None
    where every pivot clears the threshold. 25 passes (9 Cholesky, 5 forward substitution, 5
    scaling and 1/w0 − 1, 4 k2, 1/w0 and q2m).
    """
    ws, (b1, b2, b3, b4) = c["ws"], b
    s2, t, l32, xi, y2, y3, inv_w0 = ws[:7]
    # Each value goes into the row of an input it no longer needs where one exists: a pass
    # that writes one of the rows it reads moves two rows, not three (the same operations on
    # the same operands as before, so the same bits; docs/bench.md, Kernel history, round seven).
    # Cholesky, B(b) = L D Lᵀ: L32 = (b3 − b1 b2)/σ², ξ4 = b4 − b2² − L32·(b3 − b1 b2).
    np.multiply(b1, b1, s2)
    np.subtract(b2, s2, s2)
    np.multiply(b1, b2, t)
    np.subtract(b3, t, t)
    np.divide(t, s2, l32)
    np.multiply(l32, t, t)
    np.multiply(b2, b2, xi)
    np.add(t, xi, xi)
    np.subtract(b4, xi, xi)
    regular = _pivots_positive(b, s2, xi, t, c)
    # Forward substitution to solve L y = (1, zf, zf²): y2 = zf − b1, y3 = zf² − b2 − L32 y2.
    _forward(zf, b1, b2, l32, y2, y3, t)
    # p(z) = 1 + c2 (z − b1) + q2 (z² − b2 − L32 (z − b1)) (back substitution folded in), so
    # k2 = p'(zf) = c2 + q2 (2 zf − L32) (in L32's row).
    k2 = np.subtract(zf, l32, l32)
    np.add(k2, zf, k2)
    # Scaling to solve D c = y: c2 = y2/σ², q2 = c3 = y3/ξ4; 1/w0 − 1 = y2 c2 + y3 q2 (Prop. 10).
    c2 = np.divide(y2, s2, s2)
    q2 = np.divide(y3, xi, xi)
    np.multiply(k2, q2, k2)
    np.add(k2, c2, k2)
    cm1 = np.multiply(y2, c2, c2)
    np.multiply(y3, q2, y3)
    np.add(cm1, y3, cm1)
    np.add(cm1, 1, inv_w0)  # an array–scalar add reads one row, not two
    q2m = np.minimum(q2, c["zero"], out=q2)
    return k2, q2m, inv_w0, cm1, y2, regular


def _bound_rows(b, zf, bound, c, dest):
    """One bound of Algorithm 1 on the regular texels of a chunk, in the fewest passes; or None.

    Steps (1)–(2) as :func:`_cholesky` (L32² σ² as L32·(b3 − b1 b2), one pass fewer) and
    :func:`_solve` up to the scaling: ``c2 = y2/σ²``, ``q2 = y3/ξ4`` and
    ``1/w0 = 1 + y2 c2 + y3 q2`` (Peters and Klein 2015, Prop. 10). Step (3) about zf: with
    ``t = zf − z`` the quadratic of step (3) is ``q2 t² − k2 t + 1/w0`` (``k2 = p'(zf)``, its
    value at zf is ``1/w0``), whose roots ``t_a ≥ t_b`` have the product ``1/(w0 q2)``: for
    ``q2 > 0`` both lie on the side of zf that the sign of k2 gives, and the bound is ``1 − w0``
    (k2 > 0, zf above both) or 0; for ``q2 < 0`` zf lies between them and the bound is w1. Step
    (4) only for w1, from the first two moments about zf (``w1 + w2 = 1 − w0``,
    ``w1 t_a + w2 t_b = zf − b1 = y2``) and the roots ``(k2 ± S)/(2 q2)``,
    ``S = √(k2² − 4 q2/w0)``: ``w1 = ((1 − w0)/2·(S + k2) − y2 q2)/S``. Written with
    ``q2m = min(q2, 0)`` in place of q2 the same expression is the bound in all three cases
    (for ``q2 ≥ 0``, ``S = |k2|`` exactly, and ``(S + k2)/S`` is 2 or exactly 0), so step (5)
    needs no comparison and no mask. 38 ufunc passes and four reductions over a float32 chunk
    for the lower bound (the upper bound 3 more; float64 checks its relative thresholds by five
    reductions instead of two), instead of the 49 of the roots as distances from zf used before, the 63 of
    the slides' quotient formulation and the ~75 of :func:`_kernel` (docs/bench.md, "Kernel
    history"). Where B(b) is singular (module docstring) or the result is not finite (a root at
    infinity, k2 = 0 with q2 ≥ 0, an overflow, a non-finite input), the texels are handed to
    :func:`_kernel`, which has the limits of all; their indices are returned (None when there
    are none).
    """
    k2, q2m, inv_w0, cm1, y2, regular = _quadratic_about_zf(b, zf, c)
    ws = c["ws"]
    v, s = ws[1], ws[5]
    # (1 − w0)/2 = (1/w0 − 1)/(2/w0), with 2/w0 doubled in place (an array–scalar pass writing the
    # row it reads: cheaper than 1/w0 + 1/w0, the same bits) and the quotient into 1/w0 − 1's row.
    inv2 = np.multiply(inv_w0, c["two"], inv_w0)
    h = np.divide(cm1, inv2, cm1)
    # S = √(k2² − 4 q2m/w0) = √(k2² − 2·q2m·(2/w0)): k2² + 4|q2| /w0 for q2 < 0, exactly |k2| for
    # q2 ≥ 0 (the bits of 4·(q2m/w0): scalings by 2 are exact short of overflow and underflow;
    # 2/w0 > finfo.max, where 1/w0 + 1/w0 overflowed too, makes S infinite and sends the texel to
    # _kernel; in 2/w0's row for the lower bound, the upper bound keeps 2/w0 for w0).
    p = np.multiply(q2m, inv2, v if bound == "upper" else inv2)
    np.multiply(p, c["two"], p)
    np.multiply(k2, k2, s)
    np.subtract(s, p, s)
    np.sqrt(s, s)  # NaN or inf for an overflow: the texel goes to _kernel
    # lower = ((1 − w0)/2·(S + k2) − y2 q2m)/S.
    num = np.add(s, k2, k2)
    np.multiply(num, h, num)
    np.multiply(y2, q2m, y2)
    np.subtract(num, y2, num)
    lower = dest[bound] if bound == "lower" else num
    np.divide(num, s, lower)
    # Saturate: a rounded w1 < 0 (every chunk of the bench's input has some) by a maximum with
    # the zero row (NaN stays NaN), the upper end only where the chunk's largest value (one
    # reduction, which the finiteness check takes anyway) is above 1 or NaN: np.clip's result bit
    # for bit, in a cheaper pass.
    np.maximum(lower, c["zero"], out=lower)
    top = np.maximum.reduce(lower)
    if not top <= 1:
        np.minimum(lower, c["one"], out=lower)
    # Irregular: a pivot below the threshold, or a result that is not finite (the largest of a
    # chunk of values in [0, 1] is a NaN if one of them is: one reduction instead of a mask).
    irregular = None
    if regular is not None or not top <= 1:
        finite = np.isfinite(lower, out=c["mask"][0])
        regular = finite if regular is None else np.logical_and(regular, finite, out=regular)
        irregular = np.flatnonzero(np.logical_not(regular, out=regular))
    if bound == "upper":
        w0 = v
        np.divide(c["two"], inv2, w0)  # 2/(2/w0): the bits of 1/(1/w0)
        np.add(lower, w0, dest["upper"])
        np.minimum(dest["upper"], c["one"], out=dest["upper"])
    return irregular if irregular is not None and irregular.size else None


def _pivots_positive(b, sigma2, xi4, t, c):
    """The mask (``c["mask"][1]``) of the texels whose pivots clear the singular threshold, or None for all.

    float32: ``min(σ², ξ4) > 0``; float64: ``σ² > τ b2`` and ``ξ4 > τ max(b4, σ²)``. A chunk
    whose extremes clear them (``min σ² > τ max b2``, ``min ξ4 > τ max(max b4, max σ²)``: two
    or five reductions; a NaN fails every comparison) needs no mask; the others get the exact
    one. ``t`` is a free row.
    """
    regular, rtol, (_, b2, _, b4) = c["mask"][1], c["rtol"], b
    if rtol == 0:
        if np.minimum.reduce(sigma2) > 0 and np.minimum.reduce(xi4) > 0:
            return None
        np.minimum(sigma2, xi4, out=t)
        return np.greater(t, c["zero"], out=regular)
    if (np.minimum.reduce(sigma2) > rtol * np.maximum.reduce(b2)
            and np.minimum.reduce(xi4) > rtol * max(np.maximum.reduce(b4), np.maximum.reduce(sigma2))):
        return None
    above = c["mask"][0]
    np.multiply(b[1], c["rtol"], out=t)
    np.greater(sigma2, t, out=regular)
    np.maximum(b[3], sigma2, out=t)
    np.multiply(t, c["rtol"], out=t)
    regular &= np.greater(xi4, t, out=above)
    return regular


def _bound(b, zf, bound, c, dest, refuse, errors):
    """``dest[bound]`` := the bound of Algorithm 1 on a chunk: :func:`_bound_rows`, and :func:`_kernel` on the rest.

    Called with NumPy's floating-point errors ignored (:func:`_run`, once per call); ``errors``, the
    caller's settings (``np.geterr()``), are restored for :func:`_kernel`.
    """
    if not np.maximum.reduce(b[3]) < np.inf:  # b4 = +inf is the one non-finite input that can leave the result finite
        refuse()
    rest = _bound_rows(b, zf, bound, c, dest)
    if rest is not None:
        sub = _constants(b.dtype, rest.size)
        with np.errstate(**errors):
            dest[bound][rest] = _kernel(np.ascontiguousarray(b[:, rest]), zf[rest], {bound}, sub, {}, refuse)[bound]


def _unique_distribution(b, zf, singular, rtol, lower, w0, z, w):
    """Singular B(b): the unique distribution ``(1 − v2) δ_y1 + v2 δ_y2``, written into the rows.

    Exact ``Z(z < zf)`` into ``lower``; the canonical representation ``(zf, y1, y2)``
    with the mass at a support point equal to zf moved to w0, so that
    ``upper = lower + w0`` holds in every case.
    """
    s = singular
    sb1, sb2 = b[0][s], b[1][s]
    ssig = sb2 - sb1 * sb1
    ty1, ty2, tv2 = _two_point(sb1, sb2, b[2][s], ssig)
    one = ssig <= rtol * sb2  # one depth at b1
    ty1 = np.where(one, sb1, ty1)
    ty2 = np.where(one, sb1, ty2)
    tv2 = np.where(one, 0, tv2).astype(b.dtype)
    tv1 = 1 - tv2
    zs = zf[s]
    at1, at2 = ty1 == zs, ty2 == zs
    lower[s] = tv1 * (ty1 < zs) + tv2 * (ty2 < zs)
    z[0][s], z[1][s] = ty1, ty2
    w0[s] = tv1 * at1 + tv2 * at2
    w[0][s] = np.where(at1, 0, tv1)
    w[1][s] = np.where(at2, 0, tv2)


def _run(b, zf, shape, want, keys):
    """The kernel over :func:`~moments_ref._kernels.broadcast_chunks` (broadcasts never materialized).

    NaN and inf are found by the kernel (their texels come out singular), instead of a
    pass over the whole input.
    """
    n = int(np.prod(shape, dtype=np.int64))
    outs = {k: np.empty((n, 3) if k in ("depths", "weights") else (n,), dtype=b.dtype) for k in keys}
    chunk = chunk_texels(b.dtype)
    consts = _chunk_constants(b.dtype, min(chunk, max(n, 1)))
    refuse = lambda: refuse_lookup(b, "b", zf)  # noqa: E731 (raises: a value is NaN or inf)
    if want <= {"lower", "upper"}:
        bound, errors = keys[0], np.geterr()
        with np.errstate(divide="ignore", invalid="ignore", over="ignore", under="ignore"):
            for start, stop, bc, zc in broadcast_chunks(b, zf, shape, chunk):
                m = stop - start
                c = consts if m == chunk or n <= chunk else {k: v[..., :m] if np.ndim(v) else v
                                                             for k, v in consts.items()}
                _bound(bc, zc, bound, c, {bound: outs[bound][start:stop]}, refuse, errors)
        return outs
    for start, stop, bc, zc in broadcast_chunks(b, zf, shape, chunk):
        m = stop - start
        c = consts if m == chunk or n <= chunk else {k: v[..., :m] if np.ndim(v) else v for k, v in consts.items()}
        dest = {k: outs[k][start:stop] for k in keys if k in ("lower", "upper")}
        res = _kernel(bc, zc, want, c, dest, refuse)
        for k in keys:
            if k not in dest:
                outs[k][start:stop] = res[k]
    return outs


def _six(b) -> bool:
    """True for a six-moment vector (trailing axis 6): dispatched to :mod:`moments_ref.msm6`."""
    shape = getattr(b, "shape", None)
    if shape is None:
        try:
            shape = np.shape(b) if not isinstance(b, (str, bytes)) else ()
        except ValueError:  # a ragged list: refused by the four-moment path's validation
            return False
    return len(shape) > 0 and shape[-1] == 6


@fill_doc
def shadow_intensity(b, zf, bound="lower"):
    """Sharp bound of the filtered shadow intensity Z(z < zf) from four (or six) moments.

    Parameters
    ----------
    b : (..., 4) or (..., 6) float array
        Moments b1..b4 (b0 = 1 implicit), normally biased with
        :func:`moments_ref.moments.bias_moments`. A trailing axis of 6 (b1..b6)
        dispatches to :func:`moments_ref.msm6.shadow_intensity`, the six-moment
        bounds (four support points, one at zf).
    %(zf)s
        Cast to b's dtype.
    bound : {"lower", "upper"}
        ``"lower"``: HPG17 Algorithm 1, the sharp lower bound of Z(z < zf).
        ``"upper"``: the lower bound plus w0, the sharp upper bound of Z(z ≤ zf).

    Returns
    -------
    intensity : (...) float array in [0, 1], dtype of ``b`` (per the dtype policy)

    Notes
    -----
    HPG17 Algorithm 1 / Peters and Klein 2015. With the canonical representation
    ``(zf, z1, z2; w0, w1, w2)``, ``lower = Σ_{z_l < zf} w_l``. Singular B(b) gives
    the exact Z of the unique distribution (see the module docstring for the
    thresholds). The result is clamped to [0, 1] like ``saturate`` in the slides.

    Examples
    --------
    Two equal depths at −0.5 and 0.5 (a two-point distribution, exact bound):

    >>> from moments_ref.moments import power_moments
    >>> b = power_moments([-0.5, 0.5])
    >>> shadow_intensity(b, [-0.6, 0.0, 0.6])
    array([0. , 0.5, 1. ])
    """
    if bound not in ("lower", "upper"):
        raise InputError(f"bound: expected 'lower' or 'upper', got {bound!r}")
    if _six(b):
        from . import msm6

        return msm6.shadow_intensity(b, zf, bound)
    b, zf, shape = lookup_inputs(b, "b", zf)
    out = _run(b, zf, shape, {bound}, (bound,))
    return out[bound].reshape(shape)


@fill_doc
def canonical_representation(b, zf):
    """The three-point distribution attaining Algorithm 1's bounds (HPG17 Fig. 2).

    Parameters
    ----------
    %(b)s
    %(zf)s

    Returns
    -------
    depths : (..., 3) float array
        ``(zf, z1, z2)`` with ``z1 ≤ z2`` the roots of step (3); a root may be
        ±inf when zf is a support point of the two-point representation (its
        weight is then 0).
    weights : (..., 3) float array
        ``(w0, w1, w2)``, non-negative, summing to 1, with
        ``Σ w_l (1, z_l, z_l²) = (1, b1, b2)``.

    Notes
    -----
    For singular B(b) the unique distribution is returned as ``(zf, y1, y2)`` with
    weights ``(mass at zf, 1 − v2, v2)`` (mass at a support point equal to zf is
    moved to w0, so that ``upper = lower + w0`` holds in every case).

    Six moments (trailing axis 6) dispatch to
    :func:`moments_ref.msm6.canonical_representation`, which returns (..., 4)
    depths ``(zf, z1, z2, z3)`` and weights.
    """
    if _six(b):
        from . import msm6

        return msm6.canonical_representation(b, zf)
    b, zf, shape = lookup_inputs(b, "b", zf)
    out = _run(b, zf, shape, {"canonical"}, ("depths", "weights"))
    return out["depths"].reshape(shape + (3,)), out["weights"].reshape(shape + (3,))


def reduce_light_leaking(intensity, factor=0.98):
    """Divide a shadow intensity by ``factor`` and clamp to [0, 1].

    Slides, "Compute the shadow intensity": "divide by ~98% to diminish remaining
    light leaking". Off unless called; it trades weak leaks for slight
    overestimation of the shadow, so the result is no longer a lower bound.
    """
    x = real_input(intensity, "intensity")
    f = factor
    if (isinstance(f, (bool, str)) or not np.isscalar(f) or not np.isreal(f)
            or (isinstance(f, int) and abs(f) > 2**53) or not np.isfinite(f)):  # a huge int is no float
        raise InputError(f"factor: expected a number in (0, 1], got {factor!r}")
    # Checked in the working dtype: 1e-46 is positive in float64 but 0 in float32.
    f = x.dtype.type(f)
    if not (0 < f <= 1):
        raise InputError(f"factor: expected a value in (0, 1] (in {x.dtype}), got {factor!r}")
    return np.clip(x / f, 0, 1)
