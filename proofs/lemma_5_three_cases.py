"""Lemma 5 (HPG17 §3.4). Let y1 < y2, 0 < v2 < 1, ξ4 > 0 and let z1 ≤ z2 be the roots of
Algorithm 1's quadratic for the moments of Eq. (4) at fragment depth zf. Then

* zf ≤ y1  ⇒  zf ≤ z1 ≤ z2 (no support point below zf): the bound is 0;
* y1 < zf ≤ y2  ⇒  z1 < y1 < zf ≤ y2 < z2: the bound is w1;
* zf > y2  ⇒  z1 < y1 < z2 < y2 < zf: the bound is w1 + w2 = 1 − w0.

So y1 and y2 decide the case of Algorithm 1's step (5), as Algorithm 3 uses.

Proof. By Lemma 4 take y1 = 0, y2 = 1, x = z'f, ξ = ξ'4. Then (HPG17 Eq. (5))
B = V diag(1 − v2, v2, ξ) Vᵀ with V = [[1, 1, 0], [0, 1, 0], [0, 1, 1]], and with
u(z) = (1, z, z²), V⁻¹ u(z) = (1 − z, z, z(z − 1)). Step (2)'s q = B⁻¹ u(x) gives the
quadratic q·u(z) = u(z)ᵀ B⁻¹ u(x), i.e.

    p(z) = (1 − z)(1 − x)/(1 − v2) + z x / v2 + z(z − 1) x(x − 1)/ξ,

with leading coefficient x(x − 1)/ξ, p(0) = (1 − x)/(1 − v2), p(1) = x/v2 and
p(x) = u(x)ᵀ B⁻¹ u(x) > 0.

* x < 0: the parabola opens upwards, p(0) > 0 and p(1) < 0, so one root lies in
  (0, 1) and the other in (1, ∞); both exceed x. (x = 0: p is linear with root 1.)
* 0 < x < 1: it opens downwards with p(0) > 0 and p(1) > 0, so the roots lie in
  (−∞, 0) and (1, ∞) and x sits between them. (x = 1: p(z) = z/v2 + 0, a single
  finite root 0 < x; the other went to infinity with weight 0.)
* x > 1: it opens upwards, p(0) < 0 < p(1): one root in (0, 1), the other below 0;
  both are below x.

Weights at roots on the wrong side of x do not count in step (5), which gives the
three values. ∎
"""

import numpy as np
import sympy as sp
from hypothesis import given, settings
from hypothesis import strategies as st

from moments_ref import msm, nonlinear as nl

PROFILE = settings(max_examples=100, derandomize=True, deadline=None)


def test_kernel_polynomial_is_step_2_quadratic():
    x, z, v, xi = sp.symbols("x z v2 xi", real=True)
    V = sp.Matrix([[1, 1, 0], [0, 1, 0], [0, 1, 1]])
    B = V * sp.diag(1 - v, v, xi) * V.T
    u = lambda t: sp.Matrix([1, t, t**2])  # noqa: E731
    q = B.LUsolve(u(x))
    p = (q.T * u(z))[0]
    expected = (1 - z) * (1 - x) / (1 - v) + z * x / v + z * (z - 1) * x * (x - 1) / xi
    assert sp.simplify(p - expected) == 0


@PROFILE
@given(v2=st.floats(0.01, 0.99), xi=st.floats(1e-4, 10), x=st.floats(-3, 4))
def test_roots_on_the_stated_sides(v2, xi, x):
    if min(abs(x), abs(x - 1)) < 1e-6:
        return
    a = x * (x - 1) / xi
    c0 = (1 - x) / (1 - v2)
    c1 = -(1 - x) / (1 - v2) + x / v2 - x * (x - 1) / xi
    z1, z2 = np.sort(np.roots([a, c1, c0]).real)
    if x < 0:
        assert x < z1 and 0 < z1 < 1 < z2
    elif x < 1:
        assert z1 < 0 and z2 > 1
    else:
        assert z1 < 0 < z2 < 1 < x


@PROFILE
@given(y1=st.floats(-1, 0.8), g=st.floats(0.05, 0.2), v2=st.floats(0.05, 0.95), xi4=st.floats(1e-6, 1e-3), zf=st.floats(-1, 1))
def test_cases_against_canonical_representation(y1, g, v2, xi4, zf):
    r = np.array([y1, y1 + g, v2, xi4])
    if min(abs(zf - r[0]), abs(zf - r[1])) < 1e-6:
        return  # x = 0 or 1: one root at infinity (weight 0), see the proof
    depths, weights = msm.canonical_representation(nl.phi_inverse(r), zf)
    z1, z2 = depths[1], depths[2]
    lower = msm.shadow_intensity(nl.phi_inverse(r), zf)
    if zf <= r[0]:
        assert z1 >= zf - 1e-9 and lower < 1e-9
    elif zf <= r[1]:
        assert z1 < r[0] + 1e-9 and z2 > r[1] - 1e-9
        assert abs(lower - weights[1]) < 1e-9
    else:
        assert z2 < r[1] + 1e-9 and abs(lower - (1 - weights[0])) < 1e-9
