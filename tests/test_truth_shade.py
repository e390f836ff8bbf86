"""golden/truth.py's clamped Algorithm 3 (the shade cases' truth) against two routes written apart.

Away from the §3.4 clamps :func:`shade_clamped` is HPG17 Algorithm 1 on Eq. (4), which
:func:`moments_ref.precise.shade` computes by another road (the canonical representation in
mpmath); at the clamps (v2 at 0 or 1, y1 = y2, ξ4 = 0, zf at y1 or y2, a clamp offset declared,
the case test on the stored or the clamped y2) it is the package's float64 Algorithm 3
(:func:`moments_ref.nonlinear.shade`, vectorised, its own clamps) to float64 rounding.
"""

from __future__ import annotations

import numpy as np
import pytest

from moments_ref import nonlinear, precise
from moments_ref.golden.truth import SHADE_CLAMP, shade_clamped

from _mutants import kept_mutant


def _rows(n, seed):
    rng = np.random.default_rng(seed)
    y1 = rng.uniform(-0.9, 0.6, n)
    y2 = y1 + rng.uniform(0.05, 0.3, n)
    v2 = rng.uniform(0.05, 0.95, n)
    xi4 = 10.0 ** rng.uniform(-5, -1.5, n) * (y2 - y1) ** 4
    r = np.column_stack([y1, y2, v2, xi4])
    # receivers before y1, between y1 and y2, beyond y2
    zf = np.where(np.arange(n) % 3 == 0, y1 - 0.05, np.where(np.arange(n) % 3 == 1, (y1 + y2) / 2, y2 + 0.05))
    return r, zf


def test_away_from_the_clamps_it_is_algorithm_1_on_eq_4():
    r, zf = _rows(90, 1)
    got = shade_clamped(r, zf)
    assert got.dtype == np.float64 and got.shape == (90,)
    want = np.asarray(precise.shade(r, zf), np.float64)
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-12)
    assert (got[::3] == 0).all() and (got[1::3] > 0).all() and (got[2::3] > got[1::3].min()).any()
    # broadcasting a scalar receiver, and 1-D r of one row
    np.testing.assert_array_equal(shade_clamped(r[:4], zf[1]), shade_clamped(r[:4], np.full(4, zf[1])))


def _clamp_rows():
    """Rows at each clamp of HPG17 §3.4, each with receivers at y1, at y2, between, just past y1 and y2, beyond."""
    y1, y2 = -0.3, 0.4
    rows = [(y1, y2, 0.0, 1e-4), (y1, y2, 1.0, 1e-4), (y1, y2, 0.5, 0.0), (y1, y2, 1e-8, 1e-6), (y1, y2, 0.5, 1e-3)]
    zfs = [y1, y2, (y1 + y2) / 2, y1 + 1e-9, y2 + 1e-7, 0.9]
    flat = [(0.2, 0.2, 0.5, 1e-9)]  # y1 = y2: receivers at it, inside (y2, y1 + eps] for either offset, past it
    flat_zfs = [0.2, 0.2 + 5e-7, 0.2 + 5e-6, 0.2 + 2e-4, 0.1, 0.9]
    r = np.array([row for row in rows for _ in zfs] + [row for row in flat for _ in flat_zfs], np.float64)
    zf = np.array(zfs * len(rows) + flat_zfs)
    return r, zf


@pytest.mark.parametrize("clamp", [SHADE_CLAMP, 1e-5])
@pytest.mark.parametrize("case_test", ["stored", "clamped"])
def test_at_the_clamps_it_is_the_float64_algorithm_3(clamp, case_test):
    r, zf = _clamp_rows()
    got = shade_clamped(r, zf, clamp=clamp, case_test=case_test)
    rr = r.copy()
    if case_test == "clamped":  # the case test zf <= y2 on the clamped y2 = max(y2, y1 + clamp)
        rr[:, 1] = np.maximum(rr[:, 1], rr[:, 0] + clamp)
    want = np.asarray(nonlinear.shade(rr, zf, clamp=clamp), np.float64)
    np.testing.assert_allclose(got, want, rtol=0, atol=2e-9)
    assert ((got >= 0) & (got <= 1)).all()


def test_the_clamp_offset_and_the_case_test_change_the_value_where_they_apply():
    r, zf = _clamp_rows()
    a = shade_clamped(r, zf)
    b = shade_clamped(r, zf, clamp=1e-5)
    c = shade_clamped(r, zf, case_test="clamped")
    assert (np.abs(a - b) > 1e-6).any()  # v2 = 0 rows: v2 clamped to the offset
    flat = r[:, 0] == r[:, 1]
    assert (a[flat] != c[flat]).any() and (a[~flat] == c[~flat]).all()  # only y1 = y2 rows: zf in (y2, y1 + eps]
    np.testing.assert_allclose(shade_clamped(r, zf, dps=30), a, rtol=0, atol=1e-14)


def test_kept_mutant_the_case_test_made_strict_is_seen():
    """shade_clamped with the case test zf < y2 for zf ≤ y2 (a receiver on y2 shaded as behind it) disagrees with the
    float64 Algorithm 3."""
    r, zf = _clamp_rows()
    want = np.asarray(nonlinear.shade(r, zf), np.float64)
    with kept_mutant("moments_ref/golden/truth.py", "_shade_row::zf <= y2 -> zf < y2#0"):
        assert np.abs(shade_clamped(r, zf) - want).max() > 0.5
