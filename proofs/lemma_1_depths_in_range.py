"""Lemma 1 (HPG17 §3.1). If Z is a depth distribution on [-1, 1] with σ² > 0, the
depths y1, y2 of Algorithm 2 are real, distinct and lie in [-1, 1], and v2 ∈ [0, 1].

Proof. Write b_k = E_Z(z^k). Algorithm 2's quadratic is

    P(z) = σ² z² + q1 z + q0 = det [[1, b1, b2], [b1, b2, b3], [1, z, z²]]

(expand along the last row: the cofactors are b2 − b1² = σ², −(b3 − b1 b2) = q1
and b1 b3 − b2² = −b1 q1 − b2 σ² = q0). Replacing the last row by its expectation
under Z gives a matrix with two equal rows, so E_Z[P] = 0; multiplying the last row
by z first gives E_Z[z P(z)] = 0. Hence E_Z[P · ℓ] = 0 for every polynomial ℓ of
degree ≤ 1: P is the orthogonal polynomial of degree 2 of Z.

Real, distinct roots: if P had no real root or a double root, then P ≥ 0 on ℝ
(σ² > 0) and E_Z[P] = 0 would force Z to live on the zero set of P, at most one
point, contradicting σ² > 0.

Range: suppose y2 > 1. On [-1, 1] we have z − y2 < 0, so
P(z)(z − y1) = σ² (z − y1)² (z − y2) ≤ 0 there, and it vanishes only at z = y1.
But E_Z[P(z)(z − y1)] = 0 by orthogonality, so Z would be concentrated at y1:
σ² = 0, a contradiction. Symmetrically y1 < −1 is impossible (use (z − y2)).

Weights: S = (1 − v2) δ_y1 + v2 δ_y2 reproduces b0..b3, i.e. E_S[f] = E_Z[f] for
every polynomial f of degree ≤ 3 (the two-point Gauss quadrature of Z). With the
Lagrange polynomial ℓ2(z) = (z − y1)/(y2 − y1), v2 = E_S[ℓ2²] = E_Z[ℓ2²] ≥ 0 and
likewise 1 − v2 = E_Z[ℓ1²] ≥ 0.

Biased moments. The targets of both presets are moments of distributions on
[-1, 1]: b* = (0, 0.375, 0, 0.375) belongs to 0.625 δ0 + 0.1875 (δ−1 + δ1) and
(0, 0.628, 0, 0.628) to 0.372 δ0 + 0.314 (δ−1 + δ1). So (1 − α) b + α b* is the
moment vector of a mixture on [-1, 1] with σ² > 0, and the lemma applies to it. ∎
"""

import numpy as np
import sympy as sp
from hypothesis import given, settings

from moments_ref import nonlinear as nl
from moments_ref.moments import BIAS_FLOAT32, BIAS_UNORM16, bias_moments, power_moments
from moments_ref.tools.strategies import depth_distributions

PROFILE = settings(max_examples=100, derandomize=True, deadline=None)


def test_quadratic_is_the_determinant():
    b1, b2, b3, z = sp.symbols("b1 b2 b3 z")
    sigma2 = b2 - b1**2
    q1 = b1 * b2 - b3
    q0 = -b1 * q1 - b2 * sigma2
    det = sp.Matrix([[1, b1, b2], [b1, b2, b3], [1, z, z**2]]).det()
    assert sp.expand(det - (sigma2 * z**2 + q1 * z + q0)) == 0


def test_bias_targets_are_moments_of_distributions_on_the_interval():
    for preset, w0 in ((BIAS_FLOAT32, 0.625), (BIAS_UNORM16, 0.372)):
        b = power_moments(np.array([-1.0, 0.0, 1.0]), np.array([(1 - w0) / 2, w0, (1 - w0) / 2]))
        np.testing.assert_allclose(b, preset.target, atol=1e-15)


@PROFILE
@given(dist=depth_distributions(min_points=2))
def test_depths_in_range_and_weights_in_unit_interval(dist):
    z, w = dist
    b = power_moments(z, w)
    biased = b[1] - b[0] ** 2 < 1e-6  # the statement needs σ² > 0; keep rounding away
    if biased:
        b = bias_moments(b, BIAS_FLOAT32)
    y1, y2, v2, _ = nl.phi(b)
    assert -1 - 1e-9 <= y1 <= y2 <= 1 + 1e-9
    assert -1e-9 <= v2 <= 1 + 1e-9
    if not biased:
        # Roots of the orthogonal polynomial lie in the hull of the support.
        assert z.min() - 1e-6 <= y1 and y2 <= z.max() + 1e-6
