"""The non-linear representation of four moments (HPG17 §3).

HPG17 §3.1 replaces the moments ``b = (b1, b2, b3, b4)`` of a depth distribution Z
by four quantities ``Φ(b) = (y1, y2, v2, ξ4)``:

* ``S = (1 − v2) δ_y1 + v2 δ_y2`` is the two-point distribution with the same
  b0..b3 as Z (the limit zf → ∞ of Algorithm 1's canonical representation);
* ``ξ4 = b4 − E_S(z⁴) ≥ 0`` (HPG17 Eq. (1)) is the offset of the fourth moment,
  HPG17's measure of light leaking (§3.2).

This module holds the four maps of §3.1–§3.4 and Algorithm 3:

========================  ===================================================
:func:`phi`               Φ, HPG17 Algorithm 2
:func:`phi_inverse`       Φ⁻¹, the moments of HPG17 Eq. (4)
:func:`psi4`              Ψ4, the warp of ξ4 to [0, 1] (HPG17 §3.3)
:func:`psi4_inverse`      Ψ4⁻¹
:func:`shade`             HPG17 Algorithm 3: the lower bound straight from Φ(b)
========================  ===================================================

The texel formats built on these (64 and 32 bits) live in :mod:`moments_ref.packing`.
The representation is a ``(..., 4)`` array in the order ``(y1, y2, v2, ξ4)``.
The proofs of the facts used here (y1, y2 ∈ [-1, 1]; 0 ≤ ξ4 ≤ 0.25; Eq. (2), (3);
the affine change of §3.4; the three cases of Algorithm 3; Algorithm 3 = Algorithm 1
on Eq. (4)) are in ``proofs/lemma_*.py``, each with the test that checks it.

Domain of a representation and rounding tolerance
-------------------------------------------------
A representation is *valid* if ``y1 ≤ y2``, ``0 ≤ v2 ≤ 1`` and ``ξ4 ≥ 0``. Rounded
arithmetic (float32 Algorithm 2, decoding, user code) can miss this domain by a few
units in the last place; such inputs are accepted and clamped onto the domain.
The tolerance is :func:`rounding_tolerance`: ``ROUNDING_ULPS · eps(dtype)``
(absolute, since every quantity is O(1)), i.e. 7.6e-6 for float32 and 1.4e-14 for
float64 (``ROUNDING_ULPS = 64``; float32 Algorithm 2 on biased moments leaves ξ4
down to about −3e-8 by cancellation in step (7), see :func:`phi`). Anything further
outside raises :class:`~moments_ref.InputError`.

References
----------
.. [1] HPG17: Christoph Peters. 2017. *Non-Linearly Quantized Moment Shadow Maps*. In Proceedings
       of High Performance Graphics (HPG '17). ACM. The non-linear quantization Φ, Ψ4, Algorithms
       1–3, the texel formats and the compute shader of §4.1.
.. [2] Peters and Klein 2015: Christoph Peters and Reinhard Klein. 2015. *Moment Shadow Mapping*.
       In Proceedings of the 19th ACM SIGGRAPH Symposium on Interactive 3D Graphics and Games (i3D
       '15). ACM, 7–14. https://doi.org/10.1145/2699276.2699277
"""

from __future__ import annotations

import math
import threading
from functools import lru_cache

import numpy as np

from ._arrays import InputError, first_index, float_dtype, lookup_inputs, real_input, refuse_lookup
from ._docs import fill_doc
from ._kernels import PHI_CHUNK, SHADE_CHUNK, copysign_inplace

__all__ = [
    "PSI4_C0",
    "PSI4_C1",
    "phi_rows",
    "psi4_clamped",
    "phi",
    "phi_inverse",
    "psi4",
    "psi4_inverse",
    "shade",
    "PSI4_XI_MIN",
    "PSI4_XI_MAX",
    "SHADE_TOLERANCE",
    "CLAMP_BAND",
    "ROUNDING_ULPS",
    "rounding_tolerance",
    "validate_representation",
]

#: Texels per chunk in :func:`shade` in float64, twice as many in float32 (:func:`shade_chunk`; the
#: values and their reason: :data:`moments_ref._kernels.SHADE_CHUNK`).
CHUNK = SHADE_CHUNK

#: HPG17 §3.3: ξ4 is clamped to at least 1.2e-7 before the warp Ψ4.
PSI4_XI_MIN = 1.2e-7
#: HPG17 §3.3 (proved in the supplementary, here in proofs/lemma_2): ξ4 ≤ 0.25.
PSI4_XI_MAX = 0.25
#: HPG17 §3.4: Algorithm 3 clamps 1e-6 away from y1 = y2, v2 = 0 and v2 = 1.
SHADE_TOLERANCE = 1e-6
#: Offsets of the §3.4 clamps that are implementation choices, not bugs: from 1e-7
#: (below it ``1 − clamp`` is within one float32 spacing of 1, so the clamp of v2 is
#: lost to rounding) to 1/65535 (one UNORM16 step: up to there the clamp changes the
#: bound by less than one 64-bit rounding step of v2 does, HPG17 §3.4's criterion).
CLAMP_BAND = (1e-7, 1 / 65535)
#: Multiple of eps(dtype) by which a representation may miss its domain by rounding.
ROUNDING_ULPS = 64


def rounding_tolerance(dtype) -> float:
    """``ROUNDING_ULPS · eps(dtype)``: how far outside the domain rounding may put r."""
    return ROUNDING_ULPS * float(np.finfo(float_dtype(dtype)).eps)


#: Ψ4's constants (HPG17 §3.3): Ψ4(ξ) = (ln ln(ξ·1e7) − c0) / c1, so that Ψ4(1.2e-7) = 0 and Ψ4(0.25) = 1.
PSI4_C0 = float(np.log(np.log(1.2)))
PSI4_C1 = float(np.log(np.log(0.25e7))) - PSI4_C0


# ---------------------------------------------------------------------------
# Φ and Φ⁻¹


@fill_doc
def phi(b):
    """HPG17 Algorithm 2: the non-linear representation ``(y1, y2, v2, ξ4) = Φ(b)``.

    Parameters
    ----------
    %(b)s
        *Already biased*: HPG17 applies
        ``bias_moments(b, BIAS_FLOAT32)`` to the input of Algorithm 2 (§3.1, §3.2),
        which ensures σ² > 0 and y1 ≠ y2.

    Returns
    -------
    r : (..., 4) float array, dtype of ``b``
        ``(y1, y2, v2, ξ4)`` with ``y1 ≤ y2``.

    See Also
    --------
    moments_ref.gpu.filtering.quantize_nlq, moments_ref.gpu.filtering.global_path_nlq :
        the same bits for whole maps, a chunk at a time (docs/formats.md, "From depth
        samples to texels, fast").

    Notes
    -----
    HPG17 Algorithm 2, step by step:

    (1) ``σ² := q2 := b2 − b1²``; (2) ``q1 := b1 b2 − b3``;
    (3) ``q0 := −b1 q1 − b2 q2``; (4) ``y1 < y2`` the roots of ``q2 z² + q1 z + q0``;
    (5) ``v2 := (b1 − y1) / (y2 − y1)``; (6) ``L21 := (b3 − b1 b2) / σ²``;
    (7) ``ξ4 := b4 − b2² − L21² σ²`` (the third pivot of ``B = L D Lᵀ``, Eq. (3)).

    Step (4) uses the cancellation-free quadratic formula
    ``t = −(q1 + sign(q1) √(q1² − 4 q2 q0)) / 2``, roots ``t / q2`` and ``q0 / t``:
    the textbook ``(−q1 ± √…) / (2 q2)`` subtracts nearly equal numbers for the
    root of smaller magnitude (a depth near 0, where ``|y1 y2| = |q0 / q2|`` is
    small), which in float32 loses all digits of that depth. A negative
    discriminant (only by rounding; the exact one is ``(σ² (y2 − y1))² ≥ 0``) is
    set to 0.

    For moments of a distribution on [-1, 1] (biased or not) the exact values
    satisfy ``y1, y2 ∈ [-1, 1]``, ``0 ≤ v2 ≤ 1`` and ``0 ≤ ξ4 ≤ 0.25``
    (proofs/lemma_1, lemma_2). The outputs are Algorithm 2's rounded values and
    are *not* clamped: in float32 on BIAS_FLOAT32-biased moments, ξ4 can come out
    slightly negative (down to about −3e-8 measured, from cancellation in step
    (7) when ξ4 is of the order of the bias) and v2 slightly outside [0, 1]; the
    consumers (:func:`shade`, :mod:`moments_ref.packing`) accept such values
    within :func:`rounding_tolerance` and clamp them. Measured against
    :func:`moments_ref.precise.phi` on biased moments of random distributions
    (same input bits): float64 errors about 3e-15 in y, v2 and 1e-16 in ξ4;
    float32 errors about 1e-6 in y, v2 and 4e-8 in ξ4 (y and v2 errors grow
    like 1/(y2 − y1) for clustered depths).

    Singular input (not biased). If ``σ² ≤ 0`` (one depth, or rounding below
    zero), Algorithm 2 divides by zero. Then, and also if rounding leaves no
    usable pair of distinct finite roots, the result is the representation of
    the single depth ``b1``: ``y1 = y2 = b1``, ``v2 = 0`` and, from Eq. (1),
    ``ξ4 = b4 − b1⁴`` (0 for exact moments of one depth). This is the limit of
    step (7) as Z tends to a single depth (``L21 → 2 b1`` and ``L21² σ² → 0``) and
    matches :func:`moments_ref.precise.phi`. No NaN is produced for finite input.

    Examples
    --------
    >>> import numpy as np
    >>> from moments_ref.moments import power_moments
    >>> r = phi(power_moments([-0.5, 0.5, 0.5, 0.5]))
    >>> np.round(r, 12) + 0.0
    array([-0.5 ,  0.5 ,  0.75,  0.  ])
    """
    b = real_input(b, "b", trailing=4)
    flat = b.reshape(-1, 4)
    out = np.empty(flat.shape, dtype=b.dtype)
    # L2-sized chunks, each transposed to one contiguous row per moment (structure of
    # arrays): the same operations per element as on the whole array.
    res = np.empty((4, min(_PHI_CHUNK, flat.shape[0])), dtype=b.dtype)
    for lo in range(0, flat.shape[0], _PHI_CHUNK):
        rows = np.ascontiguousarray(flat[lo : lo + _PHI_CHUNK].T)
        m = rows.shape[1]
        phi_rows(rows, res[:, :m])
        # One strided store per output channel (cheaper than a transposing copy).
        for k in range(4):
            out[lo : lo + m, k] = res[k, :m]
    return out.reshape(b.shape)


#: Texels per chunk of :func:`phi` (four float32 rows and a dozen temporaries in L2).
_PHI_CHUNK = PHI_CHUNK  # the value and its reason: moments_ref._kernels


def phi_rows(rows, out):
    """Algorithm 2 on the rows b1..b4 (4, m) of a chunk (m ≤ PHI_CHUNK) into the rows (y1, y2, v2, ξ4) of ``out``.

    Returns the output rows' minima and maxima ``([min y1, min y2, min v2, min ξ4],
    [max ...])``, all finite, where the chunk has no failing texel (the reductions that
    proved it, for the encoders' saturation); else None.
    """
    m = rows.shape[1]
    full = _phi_constants(rows.dtype)
    c = full if m == _PHI_CHUNK else {k: v[:m] for k, v in full.items()}
    return _phi_chunk(*rows, out, c)


@lru_cache(maxsize=4)
def _phi_constants(dtype):
    """Constant rows of one chunk of :func:`phi`: zero and the sign-bit mask (array–array loops are the fast ones)."""
    it = np.int32 if np.dtype(dtype) == np.float32 else np.int64
    out = {"zero": np.zeros(_PHI_CHUNK, dtype=dtype), "sign": np.full(_PHI_CHUNK, np.iinfo(it).min, dtype=it)}
    for v in out.values():
        v.flags.writeable = False
    return out


def _phi_chunk(b1, b2, b3, b4, out, c):
    """Algorithm 2 on rows b1..b4 of one chunk into the rows ``out = (y1, y2, v2, ξ4)``, see :func:`phi`.

    Speed: temporaries reused through ``out=`` and in-place ufuncs, no ``np.where``
    on the common path. Each step's comment gives the formula; the code performs
    its operations in that order (IEEE ``a − b = −(b − a)`` and ``(−a)² = a²``
    are exact, which is all that ``L21² = (q1/σ²)²`` uses), so the values are bit
    for bit those of the formulas.
    """
    y1, y2, v2, xi4 = out
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        # (1)-(3) σ² = q2 = b2 − b1², q1 = b1 b2 − b3, q0 = (−b1) q1 − b2 q2.
        sigma2 = np.multiply(b1, b1)
        np.subtract(b2, sigma2, out=sigma2)
        q2 = sigma2
        q1 = np.multiply(b1, b2)
        q1 -= b3
        q0 = np.negative(b1)
        q0 *= q1
        t = np.multiply(b2, q2)
        q0 -= t
        # (4) t = −0.5 (q1 + copysign(√max(q1² − (4 q2) q0, 0), q1)), roots t/q2 and q0/t.
        d = np.multiply(q1, q1)
        np.multiply(q2, 4, out=t)
        t *= q0
        d -= t
        np.maximum(d, c["zero"], out=d)
        np.sqrt(d, out=d)
        copysign_inplace(d, q1, c["sign"])  # d ≥ 0 (a NaN d gives NaN roots either way: _phi_degenerate's)
        d += q1
        d *= -0.5
        np.divide(d, q2, out=t)
        np.divide(q0, d, out=q0)
        np.fmin(t, q0, out=y1)
        np.fmax(t, q0, out=y2)
        # (5) v2 = (b1 − y1) / (y2 − y1).
        np.subtract(b1, y1, out=v2)
        np.subtract(y2, y1, out=t)
        ordered = np.minimum.reduce(t) > 0  # y2 > y1 everywhere (a NaN fails it): for _phi_degenerate
        v2 /= t
        # (6)-(7) L21 = (b3 − b1 b2)/σ² = −q1/σ², ξ4 = (b4 − b2²) − L21² σ².
        np.divide(q1, sigma2, out=t)
        t *= t
        t *= sigma2
        np.multiply(b2, b2, out=xi4)
        np.subtract(b4, xi4, out=xi4)
        xi4 -= t
    return _phi_degenerate(b1, b4, sigma2, out, ordered)


def _phi_degenerate(b1, b4, sigma2, out, ordered=False):
    """Where Algorithm 2 fails (see :func:`phi`, Notes): one depth at b1, ξ4 by Eq. (1).

    ``ordered``: y2 > y1 was seen on every texel. Then a chunk with ``min σ² > 0`` and finite
    minima and maxima of y1, y2, v2 and ξ4 (a NaN propagates through them, an infinity is an
    extreme) has no failing texel: decided by reductions instead of the masks, and those
    extremes are returned ``(lows, highs)``; None where the masks ran.
    """
    y1, y2, v2, xi4 = out
    if ordered and np.minimum.reduce(sigma2) > 0:
        lows, highs = [np.minimum.reduce(x) for x in out], [np.maximum.reduce(x) for x in out]
        if all(map(math.isfinite, lows + highs)):
            return lows, highs
    single = sigma2 > 0
    single &= np.isfinite(xi4)
    np.logical_not(single, out=single)
    ok = y2 > y1
    for x in (v2, y1, y2):
        ok &= np.isfinite(x)
    degenerate = np.logical_not(ok, out=ok)
    degenerate |= single
    if degenerate.any():
        np.copyto(y1, b1, where=degenerate)
        np.copyto(y2, b1, where=degenerate)
        np.copyto(v2, 0, where=degenerate)
        b1sq = b1 * b1
        np.copyto(xi4, b4 - b1sq * b1sq, where=single)


@fill_doc
def phi_inverse(r):
    """Moments of a non-linear representation, HPG17 Eq. (4).

    Parameters
    ----------
    %(r)s

    Returns
    -------
    b : (..., 4) float array, dtype of ``r``
        ``b = (1 − v2) b(y1) + v2 b(y2) + (0, 0, 0, 0, ξ4)``, components b1..b4.

    Notes
    -----
    HPG17 Eq. (4). No domain check: any real r has moments by this formula
    (they are the moments of a distribution only for a valid r).

    Examples
    --------
    >>> phi_inverse([-0.5, 0.5, 0.75, 0.0])
    array([0.25  , 0.25  , 0.0625, 0.0625])
    """
    r = real_input(r, "r", trailing=4)
    y1, y2, v2, xi4 = (r[..., k] for k in range(4))
    v1 = 1 - v2
    out = np.empty(r.shape, dtype=r.dtype)
    p1, p2 = y1.copy(), y2.copy()
    for k in range(4):
        out[..., k] = v1 * p1 + v2 * p2
        if k < 3:
            p1 *= y1
            p2 *= y2
    out[..., 3] += xi4
    return out


# ---------------------------------------------------------------------------
# Ψ4 and Ψ4⁻¹


def psi4(xi4):
    """HPG17 §3.3: the warp ``Ψ4(ξ4) ∈ [0, 1]`` that equalizes the histogram of ξ4.

    Parameters
    ----------
    xi4 : (...) float array
        Offsets of the fourth moment.

    Returns
    -------
    u : (...) float array in [0, 1], dtype per the policy

    Notes
    -----
    ``Ψ4(ξ4) = (ln ln(max(1.2e-7, ξ4)·1e7) − ln ln 1.2) / (ln ln(0.25·1e7) − ln ln 1.2)``
    (HPG17 §3.3). It is strictly increasing on [1.2e-7, 0.25] with Ψ4(1.2e-7) = 0
    and Ψ4(0.25) = 1. Below 1.2e-7 (including negative rounding noise) the clamp of
    the paper gives 0; above 0.25 (only reachable by rounding, ξ4 ≤ 0.25 is
    proved in proofs/lemma_2) the output is clamped to 1 so that it stays a valid
    fixed-point value.

    Examples
    --------
    >>> psi4([0.0, 1.2e-7, 0.25])
    array([0., 0., 1.])
    """
    x = real_input(xi4, "xi4")
    dt = x.dtype.type
    # max() is HPG17's clamp; min() only catches rounding above the proved bound.
    x = np.clip(x, dt(PSI4_XI_MIN), dt(PSI4_XI_MAX))
    u = (np.log(np.log(x * dt(1e7))) - dt(PSI4_C0)) * dt(1 / PSI4_C1)
    # Exact endpoints in both dtypes (float32 misses Ψ4(0.25) = 1 by an ulp).
    u = np.where(x >= dt(PSI4_XI_MAX), dt(1), np.clip(u, 0, 1))
    return np.where(x <= dt(PSI4_XI_MIN), dt(0), u)[()]


def psi4_clamped(x, zero=0, one=1):
    """Ψ4 of ξ4 already clamped to [1.2e-7, 0.25]: the operations of :func:`psi4`, in place.

    For the encoders' contiguous chunks (no validation, no copies beyond the result):
    the same ufuncs in the same order as :func:`psi4`, and masked stores instead of
    two ``np.where`` over whole arrays, so the values are those of psi4 (only the
    sign of a zero may differ, which no encoder's rounding keeps). ``zero`` and
    ``one`` may be constant arrays of x's length (the vectorized loops).
    """
    dt = x.dtype.type
    u = np.multiply(x, dt(1e7))
    np.log(u, out=u)
    np.log(u, out=u)
    u -= dt(PSI4_C0)
    u *= dt(1 / PSI4_C1)
    # clip(u, 0, 1); given as constant arrays, maximum/minimum are the vectorized loops
    # (u is never NaN here, and a zero's sign does not survive the encoders' rounding).
    np.maximum(u, zero, out=u)
    np.minimum(u, one, out=u)
    # u = 1 at ξ4 ≥ XI_MAX, 0 at ξ4 ≤ XI_MIN, as psi4's np.where: only where a chunk's extremes
    # reach them (reductions), the lower end as a product by the 0/1 mask (a masked store on a
    # scattered mask costs several passes; u·1 = u, u·0 = ±0).
    if np.maximum.reduce(x) >= dt(PSI4_XI_MAX):
        u[x >= dt(PSI4_XI_MAX)] = 1
    if np.minimum.reduce(x) <= dt(PSI4_XI_MIN):
        u *= x > dt(PSI4_XI_MIN)
    return u


def psi4_inverse(u):
    """Inverse of :func:`psi4`: ``ξ4 = 1e-7 · exp(exp(ln ln 1.2 + u · c1))``.

    Parameters
    ----------
    u : (...) float array in [0, 1]
        Values outside [0, 1] by less than :func:`rounding_tolerance` are clamped;
        further outside raises :class:`~moments_ref.InputError`.

    Returns
    -------
    xi4 : (...) float array in [1.2e-7, 0.25], dtype per the policy

    Notes
    -----
    ``c1 = ln ln(0.25·1e7) − ln ln 1.2`` (HPG17 §3.3). The endpoints are exact:
    ``psi4_inverse(0) == 1.2e-7`` and ``psi4_inverse(1) == 0.25`` in both dtypes
    (the results are clamped to that interval, which only removes rounding).

    Examples
    --------
    >>> psi4_inverse([0.0, 1.0])
    array([1.2e-07, 2.5e-01])
    >>> round(float(psi4_inverse(psi4(1e-4))), 15)
    0.0001
    """
    x = real_input(u, "u")
    tol = rounding_tolerance(x.dtype)
    bad = (x < -tol) | (x > 1 + tol)
    if bad.any():
        idx = first_index(bad)
        raise InputError(f"u: expected values in [0, 1], got {x[idx]!r} at index {idx}")
    dt = x.dtype.type
    x = np.clip(x, 0, 1)
    xi = np.exp(np.exp(dt(PSI4_C0) + x * dt(PSI4_C1))) * dt(1e-7)
    xi = np.clip(xi, dt(PSI4_XI_MIN), dt(PSI4_XI_MAX))
    # Exact endpoints (exp(exp(·)) misses 0.25 by an ulp or two).
    xi = np.where(x >= 1, dt(PSI4_XI_MAX), xi)
    return np.where(x <= 0, dt(PSI4_XI_MIN), xi)[()]


# ---------------------------------------------------------------------------
# Validation of representations (shared with packing)


@fill_doc
def validate_representation(r, name="r"):
    """Check a ``(..., 4)`` representation and clamp rounding noise onto its domain.

    Parameters
    ----------
    %(r)s
    name : str
        Argument name for error messages.

    Returns
    -------
    r : (..., 4) float array
        A copy (dtype per the policy) with ``y2 ≥ y1``, ``v2 ∈ [0, 1]``, ``ξ4 ≥ 0``.

    Raises
    ------
    InputError
        Non-finite values, a wrong trailing axis, or ``y1 > y2``, ``v2 ∉ [0, 1]``,
        ``ξ4 < 0`` by more than :func:`rounding_tolerance`.
    """
    r = real_input(r, name, trailing=4)
    r = np.array(r, copy=True)
    _check_domain(r, name, offset=0, full_shape=r.shape[:-1])
    _clamp_domain(r)
    return r


def _domain_violation(y1, y2, v2, xi4, tol):
    """Mask and reason of representations outside the domain by more than ``tol``."""
    checks = (
        (y1 > y2 + tol, "y1 <= y2", lambda i: f"y1 = {y1[i]!r} > y2 = {y2[i]!r}"),
        ((v2 < -tol) | (v2 > 1 + tol), "v2 in [0, 1]", lambda i: f"v2 = {v2[i]!r}"),
        (xi4 < -tol, "xi4 >= 0", lambda i: f"xi4 = {xi4[i]!r}"),
    )
    return checks


def _check_domain(r, name, offset, full_shape):
    """Raise for the first representation outside the domain (flat ``offset`` into full_shape)."""
    tol = r.dtype.type(rounding_tolerance(r.dtype))
    y1, y2, v2, xi4 = (r[..., k] for k in range(4))
    for mask, want, what in _domain_violation(y1, y2, v2, xi4, tol):
        if mask.any():
            local = first_index(mask)
            flat = offset + (int(np.ravel_multi_index(local, mask.shape)) if mask.ndim else 0)
            idx = tuple(int(i) for i in np.unravel_index(flat, full_shape)) if full_shape else ()
            raise InputError(
                f"{name}: expected a representation with {want} (rounding tolerance "
                f"{float(tol):.3g}), got {what(local)} at index {idx}"
            )


def _clamp_domain(r):
    """In place: y2 ≥ y1, v2 ∈ [0, 1], ξ4 ≥ 0 (removes rounding noise only)."""
    np.maximum(r[..., 1], r[..., 0], out=r[..., 1])
    np.clip(r[..., 2], 0, 1, out=r[..., 2])
    np.maximum(r[..., 3], 0, out=r[..., 3])


# ---------------------------------------------------------------------------
# Algorithm 3


def _clamp_offset(clamp):
    """``clamp`` as a float inside :data:`CLAMP_BAND`, else :class:`InputError`."""
    try:
        c = float(clamp)
    except (TypeError, ValueError):
        c = math.nan
    if isinstance(clamp, (bool, str)) or not CLAMP_BAND[0] <= c <= CLAMP_BAND[1]:
        raise InputError(f"clamp: expected an offset in [{CLAMP_BAND[0]:g}, 1/65535], got {clamp!r}")
    return c


def _kernel_constants(dtype, n, clamp=SHADE_TOLERANCE):
    """Constant arrays of length n for the kernel (``clamp``: the §3.4 offset).

    NumPy's array–scalar loops of maximum/minimum/clip and of the integer
    bitwise operations are not vectorized and cost about four array–array
    passes; comparing against a constant *array* is the fast path.
    """
    dt = np.dtype(dtype).type
    it = np.int32 if np.dtype(dtype) == np.float32 else np.int64
    fi = np.finfo(dtype)
    full = lambda v: np.full(n, v, dtype=dtype)  # noqa: E731
    return {
        "lo": full(dt(clamp)),
        "hi": full(1 - dt(clamp)),
        "tiny": full(fi.tiny),
        "huge": full(fi.max),
        "one": full(1),
        "zero": full(0),
        "sign": np.full(n, np.iinfo(it).min, dtype=it),
        # The kernel's rows, reused by every chunk: fresh temporaries of a chunk's size are
        # faulted in from the OS again and again (measured: 1.4 ms instead of 0.3 ms a chunk).
        "ws": np.empty((_SHADE_ROWS, n), dtype=dtype),
        "bits": np.empty(n, dtype=it),
        "mask": np.empty(n, dtype=bool),
    }


#: Float rows of :func:`_shade_kernel`'s workspace: seven for the kernel, one for the gap.
_SHADE_ROWS = 8

#: Per thread, the constants and workspace of a whole chunk per dtype and clamp (:func:`_chunk_constants`).
_LOCAL = threading.local()


def shade_chunk(dtype):
    """Texels per chunk of :func:`shade` for ``dtype``: ``2·CHUNK`` in float32, ``CHUNK`` in float64."""
    return 2 * CHUNK if np.dtype(dtype) == np.float32 else CHUNK


def _chunk_constants(dtype, n, clamp):
    """:func:`_kernel_constants` for ``n ≤ shade_chunk(dtype)`` texels, and the chunk's rows: views of one set per thread.

    Kept between calls (fresh chunk-sized arrays are faulted in from the OS on every call: a
    call of one chunk took 4.5 times the per-texel time of a call of 2^20 texels), per thread
    so that concurrent calls never share them; 10.5 MB (float32, 2^17 texels, or float64, 2^16) per clamp a
    thread used.
    """
    cache, chunk = _LOCAL.__dict__.setdefault("consts", {}), shade_chunk(dtype)
    key = (np.dtype(dtype).name, clamp, chunk)
    if key not in cache:
        if len(cache) >= 4:  # a few clamps at most in practice; never grow without bound
            cache.clear()
        cache[key] = (_kernel_constants(dtype, chunk, clamp), np.empty((4, chunk), dtype=dtype))
    full, rows = cache[key]
    return (full, rows) if n == chunk else ({k: v[..., :n] for k, v in full.items()}, rows[:, :n])


def _shade_kernel(y1, y2, v2, xi4, zf, out, c, gap=None, ext=None):
    """HPG17 Algorithm 3 on flat, contiguous 1-D chunks; writes the result to ``out``.

    ``c`` holds the constant arrays of :func:`_kernel_constants` (same length);
    ``gap`` is ``y2 − y1`` when already computed (it is overwritten). ``ext``, when
    given, are the chunk's extremes of :func:`_chunk_ok`: a clamp that they prove
    changes no value is skipped (:func:`_clamps_needed`), bit for bit the same result.
    The inputs are already checked against the domain (up to rounding); ``v2`` is
    modified in place. Every case is computed for every element and the result is
    selected at the end (no per-element branching); temporaries are reused
    through ``out=``. Masked ufuncs, boolean indexing and ``np.where`` cost as
    much as 5–30 arithmetic passes in NumPy, so the final selection multiplies by
    a boolean instead (the values selected there are finite: z'f ≥ 0 keeps every
    lane's formula NaN-free).
    """
    dt = y1.dtype.type
    ws, it = c["ws"], c["sign"].dtype
    v1, zp, xip, p, den, h, k = ws[:7]
    # Clamps of §3.4 (they also remove rounding noise): v2 ∈ [1e-6, 1 − 1e-6]
    # and y2 − y1 ≥ 1e-6, i.e. the y2 used below is max(y2, y1 + 1e-6).
    need = _clamps_needed(ext, c)
    gap = np.subtract(y2, y1) if gap is None else gap
    _clamp_v2_and_gap(v2, gap, need, c)
    np.subtract(1, v2, out=v1)
    # Affine change to y1 = 0, y2 = 1 (HPG17 §3.4, proofs/lemma_4):
    # z'f := (zf − y1)/(y2 − y1) and ξ'4 := ξ4/(y2 − y1)⁴. The early return for zf ≤ y1
    # is z'f clamped at 0: the formulas below give w_l = 1/∞ = 0 there (the limit
    # z'f → 0⁺: P = ∞ sends z_l to −∞), without a mask and a NaN guard.
    np.subtract(zf, y1, out=zp)
    np.maximum(zp, c["zero"], out=zp)
    zp /= gap
    gap *= gap
    gap *= gap
    np.divide(xi4, gap, out=xip)
    # ξ'4 ≤ 0 (an exact two-point distribution, or negative rounding noise) would
    # make the ξ'4⁻¹ term 0/0; the smallest normal number gives the limit ξ'4 → 0⁺.
    if need["xi'4"]:
        np.maximum(xip, c["tiny"], out=xip)

    # --- Case y1 < zf ≤ y2: z_l is the smaller root of z² + q1 z + q0. ---
    # P := −q0 = ξ'4 / ((1 − v2) z'f) > 0, capped below +inf (z'f → 0).
    np.multiply(v1, zp, out=p)
    np.divide(xip, p, out=p)
    np.minimum(p, c["huge"], out=p)
    # h := q1/2 with q1 := −q0 (v2 − z'f)/(v2 − v2 z'f) − 1 (±inf at z'f = 1 is fine).
    np.multiply(v2, zp, out=den)
    np.subtract(v2, den, out=den)
    np.subtract(v2, zp, out=h)
    h /= den
    h *= p
    h -= 1
    h *= dt(0.5)
    # z_l := −q1/2 − √(q1²/4 − q0) = −(h + √(h² + P)), without cancellation:
    # s := h + sign(h)·√(h² + P) has none, and the roots are −s and P/s (Vieta:
    # their product is q0 = −P). They have opposite signs, so z_l = min(−s, P/s).
    # (The literal formula loses z_l when h < 0 and P is small, i.e. ξ'4 ≪ 1.)
    s = den
    np.multiply(h, h, out=s)
    s += p
    np.sqrt(s, out=s)
    bits = c["bits"]  # s takes h's sign bit (s ≥ 0): copysign in two integer passes
    np.bitwise_and(h.view(it), c["sign"], out=bits)
    np.bitwise_or(s.view(it), bits, out=s.view(it))
    s += h
    np.divide(p, s, out=p)
    np.negative(s, out=s)
    zl = np.minimum(s, p, out=s)
    # --- Case zf > y2: z_l := z'f (the weight w_0 of the fragment depth). ---
    above = np.greater(zf, y2, out=c["mask"])
    # zl := where(above, zp, zl), by bits: zl may be ±inf here (no arithmetic
    # blend), and np.where's loop costs 7–15 passes (measured), these three about 4
    # (an integer row times a boolean row costs two).
    np.bitwise_xor(zp.view(it), zl.view(it), out=bits)
    np.multiply(bits, above, out=bits)
    np.bitwise_xor(zl.view(it), bits, out=zl.view(it))

    # w_l := 1 / ((1 − v2)⁻¹ (1 − z_l)² + v2⁻¹ z_l² + ξ'4⁻¹ (1 − z_l)² z_l²)
    # (Peters and Klein 2015, Prop. 10 with B = V diag(1 − v2, v2, ξ'4) Vᵀ of
    # HPG17 Eq. (5); proofs/lemma_6).
    a = h
    np.subtract(1, zl, out=a)
    a *= a
    zl *= zl
    np.divide(a, v1, out=k)
    a *= zl
    a /= xip
    k += a
    np.divide(zl, v2, out=zl)
    k += zl
    # 1/K ≤ 1 exactly (K ≥ 1 by Cauchy–Schwarz); min() removes rounding above 1.
    np.divide(1, k, out=k)
    np.minimum(k, c["one"], out=k)
    # Return w_l if zf ≤ y2 and 1 − w_l otherwise: |[zf > y2] − w| (0 ≤ w ≤ 1), one
    # rounding (of 1 − w) and two calls instead of w + [zf > y2]·(1 − 2w) in four.
    np.subtract(above, k, out=out)
    np.absolute(out, out=out)


def _shade_about_zf(y1, y2, v2, xi4, zf, gap, out, c):
    """Algorithm 3's bound where no §3.4 clamp acts, in 31 passes (32 with the gap); the texels it leaves, or None.

    Algorithm 1's closed form (:func:`moments_ref.msm._bound_rows`) in depths measured from y1,
    ``u = z − y1``: the bound is invariant under this shift, and in these coordinates the
    two-point distribution of HPG17 §3.4 has its support at 0 and the gap ``G = y2 − y1``, so
    its moments are ``m1 = v2 G``, ``σ² = v1 v2 G²`` (``v1 = 1 − v2``), ``L32 = G``, and ξ4 is the
    input's (HPG17 Eq. (5) scales it by ``G⁴`` into the unit coordinates of §3.4, where
    ``ξ'4 = ξ4/G⁴``). The forward substitution of step (2) at ``X = zf − y1`` gives ``y2 = X − m1``
    and ``y3 = X (X − G)`` with ``X − G = zf − y2`` (one rounding, and the signs of both
    factors exact, so the case of Algorithm 3 that applies is decided exactly), so ``c2 = y2/σ²``, ``q2 = y3/ξ4``, ``1/w0 − 1 = y2 c2 + y3 q2`` (a sum of
    squares: no cancellation near w0 = 1), ``k2 = c2 + q2 (2X − G)`` and, with ``q2m = min(q2, 0)``
    and ``S = √(k2² − 4 q2m/w0)``, the bound ``((1 − w0)/2·(S + k2) − y2 q2m)/S``: the weight of the
    root below zf for ``0 < X < G`` (Algorithm 3's z_l case), ``1 − w0`` for ``X ≥ G`` (its
    ``1 − w_l`` with z_l = z'f) and exactly 0 for ``X ≤ 0`` (its early return), without
    comparisons or masks. Unlike the unit coordinates (round six) no division by G and no
    ``G⁴``: three passes fewer. A texel whose result is not finite (ξ4 = 0, an overflow, a
    non-finite zf: ``X = ±∞`` or NaN makes ``S`` or the quotient NaN, tests/test_nonlinear.py)
    is left to :func:`_shade_kernel`: its flat indices in the chunk are returned. ``y1``, ``y2``,
    ``v2`` and ``xi4`` are overwritten (in :func:`shade` they are the chunk's transposed copy,
    and :func:`_shade_rows` gathers the texels it hands on from ``r``).
    """
    g, s2, inv_w0 = c["ws"][:3]
    # Each value goes into the row of an input or a temporary it no longer needs (a pass writing
    # a row it reads moves two rows, not three): X in y1's, m1 in v2's, zf − y2 in y2's, q2 in ξ4's.
    # σ² = v1 v2 G² = (1 − v2)·m1·G (1 − v2 is exact for v2 ≥ 1/2: no cancellation near v2 = 1).
    np.subtract(1, v2, s2)  # array–scalar: one row read, not two
    x = np.subtract(zf, y1, y1)  # X = zf − y1
    m1 = np.multiply(v2, gap, v2)  # m1 = v2 G, the mean about y1
    np.multiply(s2, m1, s2)
    np.multiply(s2, gap, s2)
    # Forward substitution at X: y2 = X − m1 (in m1's row), y3 = X (X − G) (in g), X − G = zf − y2.
    y2n = np.subtract(x, m1, m1)
    e = np.subtract(zf, y2, y2)
    np.multiply(x, e, g)
    e2 = np.add(x, e, x)  # 2X − G = p'(X)'s factor of q2
    # Scaling: c2 = y2/σ², q2 = y3/ξ4, k2 = c2 + q2 (2X − G), 1/w0 − 1 = y2 c2 + y3 q2.
    c2 = np.divide(y2n, s2, s2)
    q2 = np.divide(g, xi4, xi4)
    k2 = np.multiply(e2, q2, e2)
    np.add(k2, c2, k2)
    cm1 = np.multiply(y2n, c2, c2)
    np.multiply(g, q2, g)
    np.add(cm1, g, cm1)
    np.add(cm1, 1, inv_w0)
    q2m = np.minimum(q2, c["zero"], out=q2)
    # Step (3)–(5) as msm._bound_rows: S = √(k2² − 4 q2m/w0), ((1 − w0)/2·(S + k2) − y2 q2m)/S.
    # (1 − w0)/2 = (1/w0 − 1)/(2/w0) with 2/w0 doubled in place and 4 q2m/w0 as 2·q2m·(2/w0): the
    # same bits as 1/w0 + 1/w0 and 4·(q2m/w0) (scalings by 2 are exact) in two array–scalar passes
    # writing the rows they read.
    two, s = y1.dtype.type(2), g
    inv2 = np.multiply(inv_w0, two, inv_w0)
    h = np.divide(cm1, inv2, cm1)
    p = np.multiply(q2m, inv2, inv2)
    np.multiply(p, two, p)
    np.multiply(k2, k2, s)
    np.subtract(s, p, s)
    np.sqrt(s, s)
    num = np.add(s, k2, k2)
    np.multiply(num, h, num)
    np.subtract(num, np.multiply(y2n, q2m, y2n), num)
    np.divide(num, s, out)
    # Saturate as msm._bound_rows: a maximum with the zero row (NaN stays NaN), the upper clamp
    # only where the largest value (the finiteness check's reduction) is above 1 or NaN.
    np.maximum(out, c["zero"], out=out)
    if np.maximum.reduce(out) <= 1:  # NaN propagates: one reduction finds a non-finite result
        return None
    np.minimum(out, c["one"], out=out)
    return np.flatnonzero(np.logical_not(np.isfinite(out, out=c["mask"]), out=c["mask"]))


def _clamped_texels(v2, xi4, gap, c):
    """Flat indices of the texels of a chunk on which a §3.4 clamp acts (v2, the gap, ξ'4 ≥ tiny)."""
    act = np.less(v2, c["lo"]) | (v2 > c["hi"]) | (gap < c["lo"])
    g4 = np.maximum(gap, c["lo"])
    g4 *= g4
    g4 *= g4
    act |= ~(np.divide(xi4, g4) >= c["tiny"])
    return np.flatnonzero(act)


def _shade_rows(cols, rchunk, zc, out, c, gap, ext, clamp, refuse):
    """One chunk of :func:`shade`: :func:`_shade_about_zf` where no clamp acts, :func:`_shade_kernel` on the rest.

    ``cols`` is the chunk's transposed copy of ``rchunk`` (its ``(m, 4)`` rows of r), which the
    closed form overwrites; the texels it leaves are gathered from ``rchunk``. ``refuse()``
    raises the error of a non-finite zf: :func:`_chunk_ok` does not reduce zf, and only the
    texels whose closed-form result is not finite (or where a clamp acts) can hold one.
    """
    y1, y2, v2, xi4 = cols
    rest = _clamped_texels(v2, xi4, gap, c) if any(_clamps_needed(ext, c).values()) else None
    left = _shade_about_zf(y1, y2, v2, xi4, zc, gap, out, c)
    if rest is None or not rest.size:
        rest = left
    elif left is not None:  # the union by a count, not union1d's sort (the same sorted, unique indices)
        rest = np.flatnonzero(np.bincount(np.concatenate((rest, left)), minlength=out.shape[0]))
    if rest is not None and rest.size:
        if not np.isfinite(zc[rest]).all():
            refuse()
        sub = _kernel_constants(cols.dtype, rest.size, clamp)
        res = np.empty(rest.size, dtype=cols.dtype)
        y1r, y2r, v2r, xir = np.ascontiguousarray(rchunk[rest].T)
        _shade_kernel(y1r, y2r, v2r, xir, zc[rest], res, sub)
        out[rest] = res


@fill_doc
def shade(r, zf, clamp=SHADE_TOLERANCE):
    """HPG17 Algorithm 3: the sharp lower bound of Z(z < zf) from ``(y1, y2, v2, ξ4)``.

    Parameters
    ----------
    r : (..., 4) float array
        Non-linear representation ``(y1, y2, v2, ξ4)`` (output of :func:`phi` or
        of a decoder in :mod:`moments_ref.packing`). Must lie in the domain
        ``y1 ≤ y2``, ``0 ≤ v2 ≤ 1``, ``ξ4 ≥ 0`` up to :func:`rounding_tolerance`
        (then clamped onto it); otherwise :class:`~moments_ref.InputError`.
    %(zf)s
        Cast to r's dtype.
    clamp : float
        The offset of the §3.4 clamps (default ``SHADE_TOLERANCE = 1e-6``, the
        paper's). Any offset in :data:`CLAMP_BAND` keeps the clamp's effect below
        one 64-bit rounding step of v2 (tests/test_nonlinear.py); ports declare
        theirs in a profile (docs/ports.md).

    Returns
    -------
    intensity : (...) float array in [0, 1], dtype of ``r``

    Notes
    -----
    HPG17 Algorithm 3, vectorized: every case is computed for every element and
    the result is selected afterwards (a bit blend for z_l, ``|[zf > y2] − w_l|``
    for the returned value; the early return is z'f clamped at 0, where the
    formulas give exactly 0); no per-element branching:

    * if ``zf ≤ y1``: 0;
    * ``z'f = (zf − y1)/(y2 − y1)``, ``ξ'4 = ξ4/(y2 − y1)⁴``, ``z_l = z'f``;
    * if ``zf ≤ y2``: ``q0 = −ξ'4 / ((1 − v2) z'f)``,
      ``q1 = −q0 (v2 − z'f)/(v2 − v2 z'f) − 1``,
      ``z_l = −q1/2 − √(q1²/4 − q0)`` (the smaller root; computed without
      cancellation, see the code);
    * ``w_l = 1 / ((1 − v2)⁻¹ (1 − z_l)² + v2⁻¹ z_l² + ξ'4⁻¹ (1 − z_l)² z_l²)``;
    * ``w_l`` if ``zf ≤ y2``, else ``1 − w_l``.

    The text of the paper available to us prints the last term of ``w_l`` as
    ``ξ'4 · (1 − z_l)² z_l²``; the derivation from HPG17 Eq. (5) and
    Prop. 10 gives ``ξ'4⁻¹`` (proofs/lemma_6 checks it with sympy and against
    Algorithm 1 numerically), and that is implemented.

    Clamps (HPG17 §3.4, tolerance ``SHADE_TOLERANCE = 1e-6``): ``v2`` is clamped
    to ``[1e-6, 1 − 1e-6]`` and the gap ``y2 − y1`` to at least 1e-6 (y1 is kept,
    the used ``y2`` is ``max(y2, y1 + 1e-6)``; the case test ``zf ≤ y2`` uses the
    input y2). Two more guards are not in the paper and change no finite result
    of the paper's formula: ``ξ'4`` is raised to the smallest normal number
    (so ξ4 = 0 gives the limit ξ4 → 0⁺, the exact two steps), and ``q0`` is
    capped at ``−finfo.max`` (zf within a denormal of y1). The ``q1 = ±∞`` that
    the paper's formula gives at ``zf = y2`` is evaluated in IEEE arithmetic to
    its limit ``z_l = 0``, ``w_l = 1 − v2``. No NaN results from finite input.

    Accuracy (tests/test_nonlinear.py; measured on 2e5 random inputs with
    ``y2 − y1 ≥ 1e-3``, ``v2 ∈ [1e-3, 1 − 1e-3]``, ``ξ4 ≥ 1e-8``, i.e. away from
    the clamps): float64 differs from :func:`moments_ref.precise.shade` (mpmath)
    by 2e-16 and from ``msm.shadow_intensity(phi_inverse(r), zf)`` by up to 4e-9,
    which is the error of the latter (it differs from mpmath by 8e-12 on the same
    sample and loses more where B(b) is nearly singular). The tests assert 1e-8
    against msm, 1e-9 against mpmath (2e-6 for gaps, weights and ξ'4 down to
    1e-6 .. 1e-12, where the bound is steep). float32 differs from float64 by
    5e-6 for gaps ≥ 0.05 and ``ξ4 ≥ 1e-4`` (2.2e-5 over the whole sample). Near the clamps the deviation from the exact bound is up to
    1e-2 (v2 = 0 or 1 with ξ4 ≥ 1e-5, where the bound is steep in v2; 1e-3 for
    ξ4 = 1e-7), always less than the change one UNORM16 step of v2 causes, as
    HPG17 §3.4 states; for ``y2 − y1 < 1e-6`` the steps move by less than 1e-6
    in depth.

    Performance: chunks of :func:`shade_chunk` texels (``_kernels.SHADE_CHUNK``), one transposing copy per
    chunk; finiteness and the domain of r are checked on the loaded chunk by six
    min/max reductions (the full checks run only to raise), which also tell which
    §3.4 clamps can act in the chunk; a non-finite zf shows as a non-finite result. Where no
    clamp acts on a texel (every texel of filtered moments) the bound is Algorithm 1's closed
    form in depths measured from y1 (``_shade_about_zf``: the three cases above in one
    expression, 32 ufunc passes with the gap, no selection, four of them writing into the rows
    of the chunk's copy of r that they read); the texels where a clamp acts,
    and those where the closed form is not finite (ξ4 = 0, an overflow), take the clamped algorithm above (``_shade_kernel``,
    43 passes, 47 with every clamp), decided per texel, so the result does not depend on the
    chunk size; the two agree within 4 ulps of 1 (tests/test_nonlinear.py). The measurements
    are in docs/bench.md ("Kernel history").

    Examples
    --------
    >>> shade([-0.5, 0.5, 0.75, 0.0], [-0.6, 0.0, 0.6])
    array([0.  , 0.25, 1.  ])
    """
    r, zf, shape = lookup_inputs(r, "r", zf)
    rflat = np.broadcast_to(r, shape + (4,)).reshape(-1, 4)
    zflat = np.broadcast_to(zf, shape).reshape(-1)
    out = np.empty(zflat.size, dtype=r.dtype)
    tol = r.dtype.type(rounding_tolerance(r.dtype))
    chunk, clamp = shade_chunk(r.dtype), _clamp_offset(clamp)
    consts, rows = _chunk_constants(r.dtype, min(chunk, out.size), clamp)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore", under="ignore"):
        for start in range(0, out.size, chunk):
            stop = min(start + chunk, out.size)
            # One transposing copy per chunk into the same rows: contiguous columns for the
            # ufuncs (always a copy: the kernel works in place and r may be read-only).
            cols = rows[:, : stop - start]
            np.copyto(cols, rflat[start:stop].T)
            zc = np.ascontiguousarray(zflat[start:stop])
            m = stop - start
            c = consts if m == len(consts["one"]) else {k: v[..., :m] for k, v in consts.items()}
            gap = np.subtract(cols[1], cols[0], out=c["ws"][7])
            ext = _chunk_ok(cols, zc, gap, tol)
            if ext is None:
                _refuse(r, zf, cols, start, shape)  # raises for every input that is refused
            _shade_rows(cols, rflat[start:stop], zc, out[start:stop], c, gap, ext, clamp,
                        lambda: _refuse(r, zf))
    return out.reshape(shape)


def _clamp_v2_and_gap(v2, gap, need, c):
    """In place, HPG17 §3.4: v2 into [lo, 1 − lo], the gap y2 − y1 to ≥ lo, each where ``need`` says it acts."""
    if need["v2 lo"]:
        np.maximum(v2, c["lo"], out=v2)
    if need["v2 hi"]:
        np.minimum(v2, c["hi"], out=v2)
    if need["gap"]:
        np.maximum(gap, c["lo"], out=gap)


def _clamps_needed(ext, c):
    """Which of :func:`_shade_kernel`'s clamps can change a value of a chunk with extremes ``ext``.

    ``ext`` = (min, max) of the gap y2 − y1, of v2 and of ξ4 (:func:`_chunk_ok`),
    or None (every clamp runs). ``max(v2, lo)`` is v2 where v2 ≥ lo, and so on; ξ'4 =
    ξ4 / max(gap, lo)⁴ is at least ``min ξ4 / max(gap, lo)⁴`` up to three roundings of
    the power and one of the quotient (a relative 2^-21 in float32), so a margin of 2
    proves ``ξ'4 ≥ tiny`` without computing it, where the power cannot overflow. ``c``: the
    kernel's constants. In practice a chunk of filtered moments has none of the §3.4 cases
    and skips the four passes.
    """
    if not ext:
        return dict.fromkeys(("v2 lo", "v2 hi", "gap", "xi'4"), True)
    gmin, gmax, vmin, vmax, xmin = (float(e) for e in ext[:5])
    lo, hi, tiny, huge = (float(c[k][0]) for k in ("lo", "hi", "tiny", "huge"))
    g4 = max(gmax, lo) ** 4
    return {"v2 lo": vmin < lo, "v2 hi": vmax > hi, "gap": gmin < lo,
            "xi'4": not (g4 <= huge / 2 and xmin / g4 >= 2 * tiny)}  # 2·tiny·g4 may underflow to 0


def _chunk_ok(cols, zc, gap, tol):
    """The chunk's extremes if a chunk of ``shade``'s ``r`` is finite and in the domain, else None.

    Six reductions in four calls.

    ``gap = y2 − y1``. Minima and maxima are finite exactly when every value is
    (NaN propagates through them); those of the gap cover y1 and y2 (an infinite
    or NaN depth makes the gap infinite or NaN), and ``y1 − y2 = −gap`` exactly,
    so ``max(y1 − y2) > tol`` is ``min(gap) < −tol``. A finite gap that overflows
    only sends the chunk to the full checks. None sends the call to
    :func:`_refuse`, which raises the error of the full checks. The extremes
    (min and max of the gap, v2, ξ4; empty for an empty chunk) tell
    :func:`_shade_kernel` which clamps it can skip. ``zc`` is not reduced (it was, two
    reductions, until issue 41 round seven): a non-finite zf makes the closed form's result
    NaN on every texel whose ``r`` passes these checks (:func:`_shade_about_zf`;
    tests/test_nonlinear.py enumerates the domain's edges), and :func:`_shade_rows` checks zf
    on the texels whose result is not finite before the clamped kernel sees them.
    """
    if cols.shape[1] == 0:
        return []
    # v2's and ξ4's extremes by one call each over their two adjacent rows (the same reductions).
    (vmin, xmin), (vmax, xmax) = np.minimum.reduce(cols[2:], axis=1), np.maximum.reduce(cols[2:], axis=1)
    ext = [np.minimum.reduce(gap), np.maximum.reduce(gap), vmin, vmax, xmin, xmax]
    # Finite and in the domain: min ≤ max, so a finite lower bound on each minimum and a finite
    # upper bound on each maximum (comparisons fail for NaN) make all six finite.
    ok = (ext[0] >= -tol and ext[1] < np.inf and vmin >= -tol and vmax <= 1 + tol
          and xmin >= -tol and xmax < np.inf)
    return ext if ok else None


def _refuse(r, zf, cols=None, start=0, shape=()):
    """Raise the :class:`InputError` of :func:`shade`'s checks, in their order.

    Finite values in all of ``r`` and ``zf`` first (first bad index of each), then
    broadcastable shapes, then the domain of the chunk ``cols`` (its rows starting
    at flat index ``start`` of the broadcast ``shape``).
    """
    refuse_lookup(r, "r", zf)
    if cols is not None:
        _check_domain(cols.T, "r", offset=start, full_shape=shape)
