"""golden.engine.papers_chain32: the slides' float32 code on the rows' moments rounded once to float32.

The diagnosis of a bias target (golden/diagnosis.py) re-evaluates the papers' own float32 formulation (the slides'
"Compute the shadow intensity") on the unbiased moments of each row's distribution, rounded once to float32 as the
engine cases' port input is (docs/golden.md, "Engine cases"). The rows here are one-depth distributions at a z whose
square lies above a float32 half-way point by less than half a float64 ulp: rounded to float64 first, b2 lands on
the half-way point and then on the even float32 neighbour, the wrong one. The expected moments are computed here
in exact rationals and rounded once (nearest, ties to even) by comparing the neighbours' distances.
"""

from __future__ import annotations

from fractions import Fraction

import numpy as np

from moments_ref.golden import engine
from moments_ref.golden.paper import slides_bound
from moments_ref.moments import BIAS_FLOAT32, bias_moments

# z with z² just above a float32 half-way point (found by z = sqrt(midpoint) in float64, kept as plain numbers)
Z = [0.5122457949622623, 0.927336356463762, 0.8396290171920269, 0.8928171417948835, 0.8109986114995714,
     0.9283803999427764]


def _round32(q):
    """The float32 nearest to the rational q (ties to even)."""
    x = np.float32(float(q))
    cands = [np.nextafter(x, np.float32(-1)), x, np.nextafter(x, np.float32(2))]
    dist = [abs(Fraction(float(c)) - q) for c in cands]
    best = min(dist)
    near = [c for c, d in zip(cands, dist) if d == best]
    return near[0] if len(near) == 1 else [c for c in near if int(np.array(c).view(np.uint32)) % 2 == 0][0]


def test_the_papers_chain_reads_the_moments_rounded_once_to_float32():
    b32 = np.array([[_round32(Fraction(z) ** k) for k in range(1, 5)] for z in Z], np.float32)
    twice = np.array([[z ** k for k in range(1, 5)] for z in Z], np.float64).astype(np.float32)
    assert (b32[:, 1] != twice[:, 1]).sum() >= 3  # the rows tell the two roundings apart
    sup = np.pad(np.array(Z)[:, None], ((0, 0), (0, 3)))
    mass = np.pad(np.ones((len(Z), 1)), ((0, 0), (0, 3)))
    for dz in (1e-6, -1e-5):
        zf = np.array(Z) + dz
        ctx = {"fmt": None, "bound": "lower"}
        with np.errstate(all="ignore"):
            got = engine.papers_chain32({"support": sup, "mass": mass, "zf": zf}, BIAS_FLOAT32, ctx, len(Z))
            want = slides_bound(bias_moments(b32, BIAS_FLOAT32), zf, "lower", np.float32)
        assert np.array_equal(got, np.asarray(want, np.float64), equal_nan=True), (got, want)
