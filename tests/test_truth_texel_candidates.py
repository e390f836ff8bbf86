"""golden/truth.py's texel candidates: the decoded values each format admits for an exact representation.

Stated here from docs/formats.md: the 32-bit cells ⌊511.5 (y + 1)⌋ (0 … 1022), ⌊128 √v2⌋ (≤ 127), ⌊64 Ψ4⌋ (≤ 63),
each read at its decode position (depth and Ψ4 at the upper end, √v2 at the centre); the 64-bit codes round(65535
(y + 1)/2), round(65535 v2), ceil(65535 Ψ4). Where an exact value lies within the tie (a fraction of the code range)
of a boundary, both codes beside it; never a pair with y1 above y2; values beyond the ends saturate to the last
cell. And nlq_chain's (lo, hi) is the least and largest Algorithm 3 (precise.shade, mpmath) over those texels.
"""

from __future__ import annotations

import mpmath
import numpy as np
import pytest

from moments_ref import precise
from moments_ref.golden import truth

from _mutants import kept_mutant

mp = mpmath.mpf


def _psi4_inverse(u):
    return float(precise.psi4_inverse(np.array([u]))[0])


def _decoded(fn, r, tie, texel=None):
    with mpmath.workdps(50):
        return sorted(tuple(float(x) for x in t) for t in fn(tuple(mp(v) for v in r), texel, mp(tie)))


def test_32_bit_cells_their_decode_positions_and_their_ends():
    # y1 in cell 100, y2 = 1 (the last cell, 1022), v2 = 1 (√v2 cell 127), ξ4 above Ψ4's range (cell 63)
    y1 = (100 + 0.25) / 511.5 - 1
    got = _decoded(truth._decoded32, (y1, 1.0, 1.0, 0.3), 1e-12)
    want = [(101 / 511.5 - 1, 1023 / 511.5 - 1, (127.5 / 128) ** 2, _psi4_inverse(1.0))]
    np.testing.assert_allclose(got, want, rtol=1e-14, atol=0)
    # y2 below -1, v2 < 0, ξ4 < 0: saturated to the first cells
    got = _decoded(truth._decoded32, (-1.5, -1.2, -0.1, -1.0), 1e-12)
    np.testing.assert_allclose(got, [(1 / 511.5 - 1, 1 / 511.5 - 1, (0.5 / 128) ** 2, _psi4_inverse(1 / 64))],
                               rtol=1e-14, atol=0)
    # declared decode positions: the lower ends
    got = _decoded(truth._decoded32, (y1, 1.0, 1.0, 0.3), 1e-12,
                   {"depth_decode": "lower", "v2_decode": "lower", "xi_decode": "lower"})
    np.testing.assert_allclose(got, [(100 / 511.5 - 1, 1022 / 511.5 - 1, (127 / 128) ** 2, _psi4_inverse(63 / 64))],
                               rtol=1e-14, atol=0)


@pytest.mark.parametrize("field", ["y1", "v", "xi"])
def test_32_bit_boundary_within_the_tie_takes_both_cells(field):
    y1, y2, sv, u = (300 + 0.5) / 511.5 - 1, (700 + 0.5) / 511.5 - 1, 40.5 / 128, 20.5 / 64
    if field == "y1":
        y1 = 300 / 511.5 - 1 + 1e-9 / 1023  # 1e-9 cells above the boundary of cells 299 | 300
    elif field == "v":
        sv = (40 + 1e-9) / 128
    else:
        u = (20 + 1e-9) / 64
    xi = float(precise.psi4_inverse(np.array([u]))[0])
    r = (y1, y2, sv * sv, xi)
    one = _decoded(truth._decoded32, r, 1e-15)
    two = _decoded(truth._decoded32, r, 1e-6)
    assert len(one) == 1 and len(two) == 2
    i = {"y1": 0, "v": 2, "xi": 3}[field]
    lo, hi = two[0][i], two[1][i]
    assert hi > lo and [t[:i] + t[i + 1:] for t in two][0] == [t[:i] + t[i + 1:] for t in two][1]


def test_64_bit_codes_ends_and_ties():
    # y1 = y2 on a rounding tie of its code: both codes for each, but never y1's above y2's
    y = (2 * 1000 + 1) / 65535 - 1  # 65535 (y + 1)/2 = 1000.5
    got = _decoded(truth._decoded64, (y, y, 0.25, 1e-3), 1e-9)
    ys = {(t[0], t[1]) for t in got}
    assert ys == {(2 * 1000 / 65535 - 1, 2 * 1000 / 65535 - 1), (2 * 1000 / 65535 - 1, 2 * 1001 / 65535 - 1),
                  (2 * 1001 / 65535 - 1, 2 * 1001 / 65535 - 1)}
    # ends: y beyond 1 and v2 beyond 1 saturate to the top code; ξ4 above the range to Ψ4 = 1
    (t,) = _decoded(truth._decoded64, (0.5, 1.5, 1.5, 0.3), 1e-12)
    np.testing.assert_allclose(t, (2 * round(65535 * 0.75) / 65535 - 1, 1.0, 1.0, _psi4_inverse(1.0)), rtol=1e-14)


def test_nlq_chain_32_is_the_extremes_of_algorithm_3_over_the_admitted_texels():
    # b from an exact representation whose y1 sits on a cell boundary; the chain takes both cells with the tie
    r = np.array([[300 / 511.5 - 1, (700 + 0.5) / 511.5 - 1, (40.5 / 128) ** 2, 1e-3]])
    b = np.asarray(precise.phi_inverse(r), np.float64)
    zf = np.array([(300.5 + 700.5) / 2 / 511.5 - 1])
    lo, hi = truth.nlq_chain(b, zf, "32", tie=2.0**-18)
    with mpmath.workdps(50):
        rr = precise.phi_exact(b)[0]
        texels = truth._decoded32(tuple(rr), None, mp(2.0**-18))
    assert len(texels) == 2
    vals = np.asarray(precise.shade(np.array([[float(x) for x in t] for t in texels]), np.repeat(zf, 2)), np.float64)
    np.testing.assert_allclose([lo[0], hi[0]], [vals.min(), vals.max()], rtol=0, atol=1e-13)
    assert hi[0] > lo[0]
    # without the tie: the exact value's own accuracy, one cell
    lo1, hi1 = truth.nlq_chain(b, zf, "32")
    assert lo1[0] == hi1[0]


def test_kept_mutant_the_last_depth_cell_one_too_far_is_seen():
    """_decoded32 clamping the depth cells at 1023 instead of 1022 decodes y2 = 1 above 1."""
    with kept_mutant("moments_ref/golden/truth.py", "_decoded32::1022 -> 1023#1"):
        got = _decoded(truth._decoded32, ((100 + 0.25) / 511.5 - 1, 1.0, 1.0, 0.3), 1e-12)
    assert any(t[1] > 1 for t in got)


def _row32(field, d):
    """A texel whose 32-bit cells all lie half a cell from a boundary except ``field``, ``d`` cells above one."""
    y1, y2, sv, u = (300 + 0.5) / 511.5 - 1, (700 + 0.5) / 511.5 - 1, 40.5 / 128, 20.5 / 64
    if field == "y1":
        y1 = (300 + d) / 511.5 - 1
    elif field == "y2":
        y2 = (700 + d) / 511.5 - 1
    elif field == "v":
        sv = (40 + d) / 128
    else:
        u = (20 + d) / 64
    return (y1, y2, sv * sv, float(precise.psi4_inverse(np.array([u]))[0]))


@pytest.mark.parametrize("field, cells", [("y1", 1023), ("y2", 1023), ("v", 128), ("xi", 64)])
def test_32_bit_tie_is_a_fraction_of_each_fields_code_range(field, cells):
    """The tie is a fraction of the code range: 10^-6 of it is 10^-6 · cells cells; a boundary 10^-7 cells away is
    within it for every field (and would not be within 10^-6 / cells cells)."""
    r = _row32(field, 1e-7)  # 1e-7 cells above a boundary
    assert len(_decoded(truth._decoded32, r, 1e-6)) == 2
    assert len(_decoded(truth._decoded32, r, 1e-6 / cells**2)) == 1


@pytest.mark.parametrize("field, cells", [("y1", 1023), ("y2", 1023), ("v", 128), ("xi", 64)])
def test_32_bit_tie_edge_is_exactly_the_fraction_times_the_cells(field, cells):
    """A boundary (c − 1/2)·tie cells away is inside the tie and (c + 1/2)·tie cells away is not, c the field's
    cells per unit: the tie is exactly that fraction of the code range (not of c − 1 or c + 1 cells)."""
    tie = 1e-6
    for d, two in ((tie * (cells - 0.5), True), (tie * (cells + 0.5), False)):
        r = _row32(field, d)
        assert len(_decoded(truth._decoded32, r, tie)) == (2 if two else 1), (field, d)
