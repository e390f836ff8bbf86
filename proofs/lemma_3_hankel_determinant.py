"""Lemma 3 (HPG17 Eq. (1), (2), (3)). With σ² = b2 − b1², L21 = (b3 − b1 b2)/σ² and
ξ4 = b4 − b2² − L21² σ² (Algorithm 2, step (7)):

(a) Eq. (2): det B(b) = σ² b4 + det B((1, b1, b2, b3, 0));
(b) Eq. (3): det B(b) = σ² ξ4;
(c) in B = L D Lᵀ with L unit lower triangular, D = diag(1, σ², ξ4);
(d) Eq. (1): if b = (1 − v2) b(y1) + v2 b(y2) + ξ (0, 0, 0, 0, 1) (Eq. (4)) with
    y1 ≠ y2 and 0 < v2 < 1, then Algorithm 2 returns exactly ξ4 = ξ, i.e.
    ξ4 = b4 − v1 y1⁴ − v2 y2⁴ with the y1, y2, v2 of Algorithm 2.

Proof. (a) The determinant is linear in its last row; split (b2, b3, b4) =
(b2, b3, 0) + (0, 0, b4). The second part gives b4 times the 2×2 minor
det [[1, b1], [b1, b2]] = σ².
(c) Gaussian elimination without pivoting: the first pivot is b0 = 1; eliminating
the first column leaves the Schur complement [[σ², b3 − b1 b2], [b3 − b1 b2,
b4 − b2²]], whose first pivot is σ², multiplier L32 = (b3 − b1 b2)/σ² = L21 of
Algorithm 2 (HPG17 calls it L21), and last pivot b4 − b2² − L21² σ² = ξ4.
(b) follows: det B = det L · det D · det Lᵀ = 1 · σ² · ξ4.
(d) For the moments of Eq. (4), b0..b3 are those of S = v1 δ_y1 + v2 δ_y2, and by
(a) det B is affine in b4 with slope σ²; at ξ = 0 it is det of the Gram matrix of
(1, z, z²) under a two-point distribution, which is singular (three functions,
two points). So det B = σ² ξ and by (b) ξ4 = ξ. Algorithm 2's y1, y2, v2 are those
of S (Lemma 1's orthogonal polynomial of S has the roots y1, y2), so ξ = b4 − E_S(z⁴)
= b4 − v1 y1⁴ − v2 y2⁴. ∎

All four are checked symbolically below (sympy).
"""

import sympy as sp

b1, b2, b3, b4 = sp.symbols("b1 b2 b3 b4", real=True)
SIGMA2 = b2 - b1**2
L21 = (b3 - b1 * b2) / SIGMA2
XI4 = b4 - b2**2 - L21**2 * SIGMA2


def hankel(m1, m2, m3, m4):
    return sp.Matrix([[1, m1, m2], [m1, m2, m3], [m2, m3, m4]])


def test_eq2_determinant_split():
    lhs = hankel(b1, b2, b3, b4).det()
    rhs = SIGMA2 * b4 + hankel(b1, b2, b3, 0).det()
    assert sp.expand(lhs - rhs) == 0


def test_eq3_determinant_is_sigma2_times_xi4():
    assert sp.simplify(hankel(b1, b2, b3, b4).det() - SIGMA2 * XI4) == 0


def test_ldlt_pivots():
    B = hankel(b1, b2, b3, b4)
    L = sp.Matrix([[1, 0, 0], [b1, 1, 0], [b2, L21, 1]])
    D = sp.diag(1, SIGMA2, XI4)
    assert sp.simplify(L * D * L.T - B) == sp.zeros(3, 3)


def test_eq1_on_the_moments_of_eq4():
    y1, y2, v2, xi = sp.symbols("y1 y2 v2 xi", real=True)
    m = [(1 - v2) * y1**k + v2 * y2**k for k in range(1, 5)]
    m[3] += xi
    xi4 = XI4.subs({b1: m[0], b2: m[1], b3: m[2], b4: m[3]}, simultaneous=True)
    assert sp.simplify(xi4 - xi) == 0
    # Algorithm 2's quadratic has the roots y1 and y2 (so its v2 is the given one).
    sigma2 = m[1] - m[0] ** 2
    q1 = m[0] * m[1] - m[2]
    q0 = -m[0] * q1 - m[1] * sigma2
    for y in (y1, y2):
        assert sp.simplify(sigma2 * y**2 + q1 * y + q0) == 0
