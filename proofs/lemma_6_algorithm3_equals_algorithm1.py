"""Lemma 6 (HPG17 §3.4, Algorithm 3). For y1 < y2, 0 < v2 < 1, ξ4 > 0, Algorithm 3 returns
Algorithm 1's lower bound for the moments of Eq. (4). In particular, in the
normalized coordinates of Lemma 4,

    w_l = 1 / ((1, z_l, z_l²) B⁻¹ (1, z_l, z_l²)ᵀ)
        = 1 / ((1 − v2)⁻¹ (1 − z_l)² + v2⁻¹ z_l² + ξ'4⁻¹ (1 − z_l)² z_l²),

and Algorithm 3's q0, q1 are the coefficients of Algorithm 1's quadratic divided
by its leading coefficient.

Proof. Peters and Klein 2015, Prop. 10 gives w_l = 1/(u(z_l)ᵀ B⁻¹ u(z_l)) for the
canonical representation. With B = V D Vᵀ (HPG17 Eq. (5), D = diag(1 − v2, v2, ξ'4))
we get u(z)ᵀ B⁻¹ u(z) = ‖D^(-1/2) V⁻¹ u(z)‖² and V⁻¹ u(z) = (1 − z, z, z² − z), which
is the formula above (note ξ'4 in the denominator: the text of the paper we have
prints "ξ'4 · (1 − z_l)² z_l²", which contradicts this derivation and is caught by
a mutant test in tests/test_nonlinear.py). Dividing Lemma 5's polynomial p by its
leading coefficient x(x − 1)/ξ'4 gives z² + q1 z + q0 with q0 = −ξ'4/((1 − v2) x)
and q1 = −q0 (v2 − x)/(v2 − v2 x) − 1, Algorithm 3's values; for 0 < x ≤ 1 the root
below y1 is the smaller one (Lemma 5), −q1/2 − √(q1²/4 − q0). Lemma 5 also says
which weight step (5) returns: w1 for y1 < zf ≤ y2 and 1 − w0 (z_l = x) above y2.
Lemma 4 transfers everything back to the original depths. ∎
"""

import numpy as np
import sympy as sp
from hypothesis import given, settings
from hypothesis import strategies as st

from moments_ref import msm, nonlinear as nl

PROFILE = settings(max_examples=100, derandomize=True, deadline=None)

x, z, v, xi = sp.symbols("x z v2 xi", positive=True)
V = sp.Matrix([[1, 1, 0], [0, 1, 0], [0, 1, 1]])
B = V * sp.diag(1 - v, v, xi) * V.T


def u(t):
    return sp.Matrix([1, t, t**2])


def test_weight_formula():
    lhs = (u(z).T * B.inv() * u(z))[0]
    rhs = (1 - z) ** 2 / (1 - v) + z**2 / v + (1 - z) ** 2 * z**2 / xi
    assert sp.simplify(lhs - rhs) == 0
    wrong = (1 - z) ** 2 / (1 - v) + z**2 / v + xi * (1 - z) ** 2 * z**2
    assert sp.simplify(lhs - wrong) != 0


def test_q0_q1_are_the_normalized_quadratic():
    q = B.LUsolve(u(x))
    q0, q1 = sp.simplify(q[0] / q[2]), sp.simplify(q[1] / q[2])
    q0_alg3 = -xi / ((1 - v) * x)
    q1_alg3 = -q0_alg3 * (v - x) / (v - v * x) - 1
    assert sp.simplify(q0 - q0_alg3) == 0
    assert sp.simplify(q1 - q1_alg3) == 0


def test_weights_of_prop_10_solve_the_vandermonde_system():
    """Prop. 10's weights at the three support points reproduce b0, b1, b2 (numeric)."""
    vv, xx, xii = 0.3, 0.6, 1e-2
    Bn = np.array(B.subs({v: vv, xi: xii}).evalf(), dtype=float)
    q = np.linalg.solve(Bn, [1, xx, xx**2])
    z1, z2 = np.sort(np.roots(q[::-1]).real)
    pts = np.array([xx, z1, z2])
    w = np.array([1 / (np.array([1, p, p * p]) @ np.linalg.solve(Bn, [1, p, p * p])) for p in pts])
    np.testing.assert_allclose(np.vander(pts, 3, increasing=True).T @ w, Bn[0], atol=1e-12)


@PROFILE
@given(
    y1=st.floats(-1, 0.9), g=st.floats(1e-2, 1), v2=st.floats(1e-3, 1 - 1e-3),
    xi4=st.floats(1e-9, 0.25), zf=st.floats(-1.1, 1.1),
)
def test_algorithm_3_equals_algorithm_1(y1, g, v2, xi4, zf):
    r = np.array([y1, min(y1 + g, 1.0), v2, xi4])
    alg3 = nl.shade(r, zf)
    alg1 = msm.shadow_intensity(nl.phi_inverse(r), zf)
    assert abs(alg3 - alg1) < 1e-8
