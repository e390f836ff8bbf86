"""Lemma 2 (HPG17 §3.1, §3.3). For a depth distribution Z on [-1, 1] with σ² > 0,
0 ≤ ξ4 ≤ 1/4, and the upper bound is attained.

Proof. B(b) is the Gram matrix of (1, z, z²) under Z: B_ij = E_Z[z^i z^j]. In the
factorization B = L D Lᵀ (L unit lower triangular) the pivots are D = diag(1, σ², ξ4)
(Lemma 3), and the last pivot of a Gram matrix is the squared distance of the last
vector from the span of the others:

    ξ4 = min over a, c of E_Z[(z² − a − c z)²].

This is a minimum of non-negative numbers, so ξ4 ≥ 0. For the upper bound choose
a = 1/2, c = 0: on [-1, 1], |z² − 1/2| ≤ 1/2, so ξ4 ≤ E_Z[(z² − 1/2)²] ≤ 1/4.
Z = 1/4 δ−1 + 1/2 δ0 + 1/4 δ1 has b = (0, 1/2, 0, 1/2), σ² = 1/2, L21 = 0 and
ξ4 = 1/2 − 1/4 = 1/4: the bound is sharp. Biased moments are moments of a mixture
on [-1, 1] (Lemma 1), so the bound holds for them too. ∎
"""

import numpy as np
import sympy as sp
from hypothesis import given, settings

from moments_ref import nonlinear as nl
from moments_ref.moments import BIAS_FLOAT32, bias_moments, power_moments
from moments_ref.tools.strategies import depth_distributions

PROFILE = settings(max_examples=100, derandomize=True, deadline=None)


def test_xi4_is_the_least_squares_residual():
    """ξ4 of Algorithm 2 = min_{a,c} E[(z² − a − c z)²] (sympy: stationary point value)."""
    b1, b2, b3, b4, a, c = sp.symbols("b1 b2 b3 b4 a c", real=True)
    m = {0: 1, 1: b1, 2: b2, 3: b3, 4: b4}
    # E[(z² − a − c z)²] expanded in moments.
    poly = sp.Poly(sp.expand((sp.Symbol("z") ** 2 - a - c * sp.Symbol("z")) ** 2), sp.Symbol("z"))
    e = sum(coef * m[k[0]] for k, coef in zip(poly.monoms(), poly.coeffs()))
    sol = sp.solve([sp.diff(e, a), sp.diff(e, c)], [a, c], dict=True)[0]
    residual = sp.simplify(e.subs(sol))
    sigma2 = b2 - b1**2
    l21 = (b3 - b1 * b2) / sigma2
    xi4 = b4 - b2**2 - l21**2 * sigma2
    assert sp.simplify(residual - xi4) == 0


def test_upper_bound_is_attained():
    b = power_moments(np.array([-1.0, 0.0, 1.0]), np.array([0.25, 0.5, 0.25]))
    assert nl.phi(b)[3] == 0.25


@PROFILE
@given(dist=depth_distributions())
def test_xi4_between_zero_and_a_quarter(dist):
    z, w = dist
    b = bias_moments(power_moments(z, w), BIAS_FLOAT32)
    xi4 = nl.phi(b)[3]
    assert -1e-12 <= xi4 <= 0.25 + 1e-12
    # The residual bound with a = 1/2, c = 0, computed from the distribution itself.
    assert xi4 <= np.sum(w * (z**2 - 0.5) ** 2) + 1e-6
