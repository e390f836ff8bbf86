"""The contract of a golden case: the inputs its published algorithm defines.

A verdict is decided on *contract rows*: inputs the algorithm of the paper takes, as
an engine that follows the paper hands them over. The other rows of a case are
*robustness rows* (flag ``robustness``): they show what a port does beyond the
contract (a NaN, an out-of-range value, a different answer), are counted and shown
in their own section, and fail the verdict only with ``--strict`` (``strict=True``),
for porters who want the reference's extra guards.

=====================  ===========================================================
Algorithm 1            biased moments inside the moment space: the Hankel matrix
(``shadow_intensity``, B(b) of the moments the bound receives is positive definite.
six moments, Φ, the    HPG17 §3.2 and Algorithm 1 bias every moment vector before
e2e chains)            the bound (Peters and Klein 2015, §3.1 and Prop. 10: the
                       bias moves b into the interior, where the bound is defined);
                       unbiased one- and two-point moments (singular B(b)) and
                       moments outside the moment space are not its input.
Algorithm 3            representations the texel decoders produce (HPG17 §3.3,
(``shade``)            §3.5): ξ4 in [1.2e-7, 0.25] (the range of Ψ4⁻¹), v2 in
                       [0, 1] (0 and 1 included: √v2 codes 0 and 127), y1 ≤ y2 in
                       [−1, 1] (y1 = y2 included: one 32-bit cell).
=====================  ===========================================================

Positive definiteness is judged on the smallest eigenvalue of B(b) in float64 from
the exact input values: above :data:`PD_MIN` = 1e-12. Exactly singular inputs stored
in float32 or float64 evaluate to |λ| < 1e-15 there; the paper's smallest bias
(α = 3e-7 toward (0, 0.375, 0, 0.375)) keeps λ ≥ 6e-8. The verdict is LAPACK's
eigenvalue's (:func:`hankel_lambda_min`); :func:`hankel_above` reaches it without the
eigensolver on the rows a Cholesky factorization certifies (its docstring), so a sweep's
chunk of 10^5 rows is judged in milliseconds, not a tenth of a second.

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

import numpy as np

__all__ = ["PD_MIN", "XI4_RANGE", "hankel_lambda_min", "hankel_above", "CERTIFY_MARGIN", "moments_inside", "moments_of_a_distribution",
           "representation_inside", "rows_inside", "TEXT", "ALGORITHM1", "ALGORITHM3", "CHAIN",
           "HAUSDORFF", "HAUSDORFF_SLACK", "hausdorff_inside"]

#: Smallest eigenvalue of B(b) above which moments are inside the moment space (see above).
PD_MIN = 1e-12
#: How far the localizing matrix of z (1 − z) may be negative in a Hausdorff contract row: float32
#: rounding of moments of order 1 (a few units of 2⁻²⁴) on the boundary of the moment space of [0, 1].
HAUSDORFF_SLACK = 1e-6
#: The range of Ψ4⁻¹ (HPG17 §3.3), widened by two float32 spacings for the decoders' rounding.
XI4_RANGE = (1.2e-7 * (1 - 2.0**-22), 0.25 * (1 + 2.0**-22))

ALGORITHM1 = ("biased moments inside the moment space (B(b) positive definite), HPG17 §3.2 and Algorithm 1; "
              "unbiased singular moments and moments outside the moment space are robustness rows")
ALGORITHM3 = ("representations the 64- and 32-bit decoders produce (HPG17 §3.3, §3.5): xi4 in [1.2e-7, 0.25], "
              "v2 in [0, 1], y1 <= y2 in [-1, 1]; smaller xi4 are robustness rows")
CHAIN = ("filtered moments of a depth distribution (B(b) positive semidefinite), biased by the chain before "
         "Algorithm 2 or 1 (HPG17 §3.2): moments outside the moment space are robustness rows")
HAUSDORFF = ("moments of a distribution on [0, 1] whose Hankel matrix B(b) is positive definite (a biased "
             "texel of depths in [0, 1]), receivers zf in [0, 1] (0 and 1 included), Peters and Klein 2015; moments "
             "outside the moment space of [0, 1] and receivers beyond it are robustness rows")


def hankel_lambda_min(b):
    """Smallest eigenvalue of the Hankel matrix B(b) of ``(n, 4)`` or ``(n, 6)`` moments, in float64."""
    return np.linalg.eigvalsh(_hankel(b))[..., 0]


#: Relative margin of :func:`hankel_above`'s certificate: a row is decided without the eigensolver where a
#: Cholesky factorization of ``B(b) − (threshold + CERTIFY_MARGIN·tr B(b))·I`` succeeds (about 900 units of
#: float64 roundoff times the trace: the factorization's backward error is 5 units for n ≤ 4, the eigensolver's
#: a modest multiple of one).
CERTIFY_MARGIN = 1e-13


def _hankel(b):
    """``(..., n, n)`` float64 Hankel matrices B(b) of ``(..., 2n − 2)`` moments (b0 = 1 prepended)."""
    b = np.asarray(b, np.float64)
    n = b.shape[-1] // 2 + 1
    full = np.concatenate([np.ones(b.shape[:-1] + (1,)), b], axis=-1)
    return full[..., np.add.outer(np.arange(n), np.arange(n))]


def _cholesky_succeeds(a):
    """``(...)`` bool: rows whose float64 Cholesky factorization ``a = RᵀR`` finds every pivot positive."""
    n = a.shape[-1]
    r = np.zeros_like(a)
    ok = np.ones(a.shape[:-2], bool)
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):  # a failed row's NaN runs on, harmless
        for j in range(n):
            piv = a[..., j, j] - np.einsum("...k,...k->...", r[..., :j, j], r[..., :j, j])
            ok &= piv > 0  # NaN fails
            r[..., j, j] = np.sqrt(piv)
            for i in range(j + 1, n):
                s = a[..., j, i] - np.einsum("...k,...k->...", r[..., :j, j], r[..., :j, i])
                r[..., j, i] = s / r[..., j, j]
    return ok


def hankel_above(b, threshold):
    """``(...)`` bool: ``hankel_lambda_min(b) > threshold``, the eigensolver run only where it decides.

    Where the Cholesky factorization of ``A = B(b) − s·I``, ``s = threshold + CERTIFY_MARGIN·tr B(b)``,
    succeeds in float64 (every pivot positive), λ_min(B(b)) > ``threshold`` holds with room for the
    eigensolver's rounding, and the row is decided: the computed factor is exact for ``A + ΔA`` with
    ``|ΔA| ≤ γ_{n+1} |Rᵀ||R|`` (Higham, *Accuracy and Stability of Numerical Algorithms*, 2nd ed., Thm 10.3),
    so ``‖ΔA‖₂ ≤ γ_{n+1} ‖R‖_F² ≈ (n+1)·u·tr A`` and ``λ_min(B(b)) > s − 5.6e-16·tr B(b)`` for n ≤ 4, while
    LAPACK's symmetric eigenvalues are within a modest multiple of ``u·‖B(b)‖₂ ≤ u·tr B(b)`` of the exact
    ones (LAPACK Users' Guide §4.7), far inside the margin of ``1e-13·tr`` (about 900 u). Every other row
    (singular or indefinite moments, λ_min within the margin of the threshold) takes
    :func:`hankel_lambda_min`; a row with a non-finite moment is outside (the eigensolver refuses it).
    tests/test_contract_rows.py checks the equality on rows built to lie on both sides of the threshold
    within a few units of roundoff.
    """
    h = _hankel(b)
    with np.errstate(invalid="ignore", over="ignore"):
        # tr ≥ 1 wherever the factorization can succeed (a negative diagonal entry fails it)
        s = threshold + CERTIFY_MARGIN * np.trace(h, axis1=-2, axis2=-1)
        a = h - s[..., None, None] * np.eye(h.shape[-1])
    out = _cholesky_succeeds(a)
    rest = ~out & np.isfinite(h).all(axis=(-2, -1))  # a non-finite moment: outside
    if rest.any():
        out[rest] = hankel_lambda_min(np.asarray(b)[rest]) > threshold
    return out


def _biased(b, bias):
    """``(1 − α) b + α b*`` in float64 (``bias``: None or (alpha, target) in b's frame)."""
    b = np.asarray(b, np.float64)
    if bias is None:
        return b
    alpha, target = bias
    return (1 - alpha) * b + alpha * np.asarray(target, np.float64)


def moments_inside(b, bias=None):
    """Rows whose moments, after ``bias``, are inside the moment space (Algorithm 1's contract)."""
    return hankel_above(_biased(b, bias), PD_MIN)


def moments_of_a_distribution(b, bias=None):
    """Rows whose moments, after ``bias``, are in the closed moment space (the e2e chains' contract)."""
    return hankel_above(_biased(b, bias), -PD_MIN)


def hausdorff_inside(b, zf):
    """Rows of moments b of a distribution on [0, 1] with B(b) positive definite, and zf in [0, 1].

    The closed moment space of [0, 1] (degree 4): B(b) ⪰ 0 and the localizing matrix of
    z (1 − z), ``[[b1 − b2, b2 − b3], [b2 − b3, b3 − b4]]``, ⪰ 0, up to :data:`HAUSDORFF_SLACK`
    (float32 rounding of a texel on the boundary, such as one depth mixed toward the ends).
    """
    b = np.asarray(b, np.float64)
    b1, b2, b3, b4 = (b[..., k] for k in range(4))
    loc = np.stack([np.stack([b1 - b2, b2 - b3], -1), np.stack([b2 - b3, b3 - b4], -1)], -2)
    zf = np.asarray(zf, np.float64)
    return (hankel_above(b, PD_MIN) & (np.linalg.eigvalsh(loc)[..., 0] > -HAUSDORFF_SLACK)
            & (zf >= 0) & (zf <= 1))


def representation_inside(r):
    """Rows of ``(n, 4)`` representations that a texel decoder can produce (Algorithm 3's contract)."""
    r = np.asarray(r, np.float64)
    y1, y2, v2, xi4 = (r[..., k] for k in range(4))
    return ((xi4 >= XI4_RANGE[0]) & (xi4 <= XI4_RANGE[1]) & (v2 >= 0) & (v2 <= 1) & (y1 <= y2)
            & (y1 >= -1) & (y2 <= 1))


#: The contracts by kind (a case's ``contract``), in words for the manifest.
TEXT = {"moments_inside": ALGORITHM1, "distribution": CHAIN, "representation": ALGORITHM3, "hausdorff": HAUSDORFF}


def rows_inside(kind, inputs, bias=None):
    """``(n,)`` bool: rows of ``inputs`` inside the contract ``kind`` (:data:`TEXT`).

    ``bias``: ``(alpha, target)`` in the inputs' frame, the bias the moments get before
    the bound (a profile's); the ``distribution`` contract judges the unbiased input.
    """
    if kind == "representation":
        return representation_inside(inputs["r"])
    if kind == "distribution":
        return moments_of_a_distribution(inputs["b"])
    if kind == "hausdorff":
        return hausdorff_inside(inputs["b"], inputs["zf"])
    if kind == "moments_inside":
        return moments_inside(inputs["b"], bias)
    raise ValueError(f"unknown contract kind {kind!r}")
