"""Lemma 4 (HPG17 §3.4). Under the affine change z' = (z − y1)/g, g = y2 − y1 > 0, the
representation (y1, y2, v2, ξ4) becomes (0, 1, v2, ξ4/g⁴), and the lower bound is
invariant: Z(z < zf) = Z'(z' < z'f) with z'f = (zf − y1)/g.

Proof. The map z ↦ z' is increasing, so it preserves the order of depths and
therefore every probability Z(z < zf) and every bound over distributions with given
moments (the moments of Z' are polynomials in those of Z, and the change is
invertible). The two-point distribution S moves to S' with depths 0, 1 and the same
weights. For ξ4 use Lemma 2's characterization ξ4 = min E[(z² − a − c z)²]:
substituting z = y1 + g z' gives z² = g² z'² + 2 y1 g z' + y1², so every quadratic
z² − a − c z equals g² (z'² − a' − c' z') for a unique (a', c') and vice versa.
Hence ξ4 = g⁴ ξ'4. ∎

The tests check ξ'4 = ξ4/g⁴ symbolically on Algorithm 2's formula and the invariance
of the bound numerically with Algorithm 1.
"""

import numpy as np
import sympy as sp
from hypothesis import given, settings
from hypothesis import strategies as st

from moments_ref import msm, nonlinear as nl

PROFILE = settings(max_examples=60, derandomize=True, deadline=None)


def _xi4(m1, m2, m3, m4):
    s2 = m2 - m1**2
    l21 = (m3 - m1 * m2) / s2
    return m4 - m2**2 - l21**2 * s2


def test_xi4_scales_with_the_fourth_power():
    b1, b2, b3, b4, y1 = sp.symbols("b1 b2 b3 b4 y1", real=True)
    g = sp.Symbol("g", positive=True)
    m = {0: 1, 1: b1, 2: b2, 3: b3, 4: b4}
    z = sp.Symbol("z")

    def moment(k):  # E[((z − y1)/g)^k] from the moments of z
        p = sp.Poly(sp.expand(((z - y1) / g) ** k), z)
        return sum(c * m[e[0]] for e, c in zip(p.monoms(), p.coeffs()))

    new = _xi4(moment(1), moment(2), moment(3), moment(4))
    assert sp.simplify(new - _xi4(b1, b2, b3, b4) / g**4) == 0


@PROFILE
@given(
    y1=st.floats(-1, 0.5), g=st.floats(0.05, 0.5), v2=st.floats(0.05, 0.95),
    xi4=st.floats(1e-6, 1e-2), zf=st.floats(-1, 1),
)
def test_bound_is_invariant(y1, g, v2, xi4, zf):
    r = np.array([y1, y1 + g, v2, xi4])
    unit = np.array([0.0, 1.0, v2, xi4 / g**4])
    b, bu = nl.phi_inverse(r), nl.phi_inverse(unit)
    assert abs(msm.shadow_intensity(b, zf) - msm.shadow_intensity(bu, (zf - y1) / g)) < 1e-8
    np.testing.assert_allclose(nl.phi(b), r, atol=1e-9)
    np.testing.assert_allclose(nl.phi(bu)[3], xi4 / g**4, rtol=1e-6)
