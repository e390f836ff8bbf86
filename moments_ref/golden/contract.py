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
(α = 3e-7 toward (0, 0.375, 0, 0.375)) keeps λ ≥ 6e-8.

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

__all__ = ["PD_MIN", "XI4_RANGE", "hankel_lambda_min", "moments_inside", "moments_of_a_distribution",
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
    b = np.asarray(b, np.float64)
    n = b.shape[-1] // 2 + 1
    full = np.concatenate([np.ones(b.shape[:-1] + (1,)), b], axis=-1)
    idx = np.add.outer(np.arange(n), np.arange(n))
    return np.linalg.eigvalsh(full[..., idx])[..., 0]


def _biased(b, bias):
    """``(1 − α) b + α b*`` in float64 (``bias``: None or (alpha, target) in b's frame)."""
    b = np.asarray(b, np.float64)
    if bias is None:
        return b
    alpha, target = bias
    return (1 - alpha) * b + alpha * np.asarray(target, np.float64)


def moments_inside(b, bias=None):
    """Rows whose moments, after ``bias``, are inside the moment space (Algorithm 1's contract)."""
    return hankel_lambda_min(_biased(b, bias)) > PD_MIN


def moments_of_a_distribution(b, bias=None):
    """Rows whose moments, after ``bias``, are in the closed moment space (the e2e chains' contract)."""
    return hankel_lambda_min(_biased(b, bias)) > -PD_MIN


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
    return ((hankel_lambda_min(b) > PD_MIN) & (np.linalg.eigvalsh(loc)[..., 0] > -HAUSDORFF_SLACK)
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
