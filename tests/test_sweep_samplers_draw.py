"""The sweep's draw (sweep/samplers.py) against the distributions docs/sweep.md writes as formulas, second part.

Each statistic is compared with its value computed from the formula (not from the code), within 6 binomial
standard deviations (or a bound of the same size), on a fixed seed:

* clusters: each of the two clusters lies within 2s of its centre, s = 10^U(−6, −1) one spread per texel, so the
  distance between two depths of a cluster is s·|u₁ − u₂| (uᵢ ~ U(−1, 1); clip(·, −1, 1) only brings them closer): E log10 = −3.5 + (ln 2 − 3/2)/ln 10;
* weights: gᵢ ~ Gamma(1, 1), so among three-depth texels w₂/(w₂ + w₃) ~ Beta(1, 1) (uniform: E (x − ½)² = 1/12);
  the first weight of a texel whose six slots are all used (a 3 + 3 cluster) relative to the mean of the others,
  R = w₁ / mean(w₂ … w₆), has P(R < r) = ¼ · clip((log10 r + 4)/4, 0, 1) + ¾ · (1 − (1 + r/5)^−5) (faint with
  probability ¼: 10^U(−4, 0); else g₁/Σ₂⁶gᵢ is Beta-prime(1, 5));
* a texel whose weights all vanish (Gamma(1, 1) can round to 0) is one depth of weight 1, never NaN;
* ``near`` receivers: K uniform over the texel's depths, the offset's sign ± with probability ½;
* the generator: the seed's 32 bits all count;
* Algorithm 3's ξ4 range as float32 bounds: the nearest float32 values inside it (exact rationals).
"""

from __future__ import annotations

import math
from fractions import Fraction

import mpmath
import numpy as np
import pytest

from moments_ref.golden.cases import CASES
from moments_ref.sweep import samplers
from moments_ref.sweep.samplers import RECEIVERS, draw_rows

from _mutants import kept_mutant


def _sigma_ok(count, n, p, k=6):
    return abs(count - n * p) <= k * math.sqrt(n * p * (1 - p)) + 1


def _chunks(*chunks, case="shade-float32", seed=23):
    rs = [draw_rows(CASES[case], seed, c) for c in chunks]
    return {k: np.concatenate([r[k] for r in rs]) for k in rs[0]}


def _kinds(r):
    s = r["stratum"].astype(int)
    return s // len(RECEIVERS), s % len(RECEIVERS)


def _cluster_gaps(r):
    """Per cluster texel and cluster j (slots 0-2, 3-5): the largest distance between two of its depths, NaN for a
    cluster of one depth; and the gap of the first two depths of the first cluster where it has exactly two."""
    texel, _ = _kinds(r)
    z, w = r["z"][texel == 4], r["w"][texel == 4]
    gaps = []
    for j in (0, 3):
        zz = np.where(w[:, j:j + 3] > 0, z[:, j:j + 3], np.nan)
        n = (w[:, j:j + 3] > 0).sum(axis=1)
        g = np.where(n >= 2, np.nanmax(zz, axis=1) - np.nanmin(zz, axis=1), np.nan)
        gaps.append(np.where(np.nanmax(np.abs(zz), axis=1) < 1, g, -1.0))  # −1: clipped at an end
    two = ((w[:, :3] > 0).sum(axis=1) == 2) & (np.abs(z[:, :3]).max(axis=1) < 0.8)  # no clip: |c| < 0.9, s ≤ 0.1
    return gaps, np.abs(z[two, 0] - z[two, 1])


def test_each_cluster_is_within_its_spread_and_the_spread_is_log_uniform():
    r = _chunks(0)
    (g1, g2), pair = _cluster_gaps(r)
    for g in (g1, g2):  # both clusters: s·|u_i − u_j| ≤ 2s ≤ 0.2, and > 0 (u continuous)
        g = g[~np.isnan(g)]
        assert len(g) > 5000 and (g <= 0.2 + 1e-12).all() and (g[g != -1] > 0).all() and (g > 0).mean() > 0.9
    # two depths: log10 |z1 − z2| = U(−6, −1) + log10 |u1 − u2|, |u1 − u2| triangular on [0, 2]
    want = -3.5 + (math.log(2) - 1.5) / math.log(10)
    e1 = mpmath.quad(lambda d: mpmath.log(d) * (2 - d) / 2, [0, 2])
    e2 = mpmath.quad(lambda d: mpmath.log(d)**2 * (2 - d) / 2, [0, 2])
    assert abs(e1 - (math.log(2) - 1.5)) < 1e-12
    sd = math.sqrt(25 / 12 + float(e2 - e1**2) / math.log(10)**2)  # U(−6, −1)'s variance + the gap's
    got = np.log10(pair).mean()
    assert abs(got - want) <= 6 * sd / math.sqrt(len(pair)), (got, want, len(pair))


def test_the_weights_are_dirichlet_one():
    r = _chunks(0)
    texel, _ = _kinds(r)
    w = r["w"][texel == 2]  # three depths: slots 1 and 2 are never faint
    x = w[:, 1] / (w[:, 1] + w[:, 2])
    # Beta(1, 1): E (x − ½)² = 1/12, Var (x − ½)² = 1/80 − 1/144
    d = ((x - 0.5)**2).mean()
    assert abs(d - 1 / 12) <= 6 * math.sqrt((1 / 80 - 1 / 144) / len(x)), d


def _faint_cdf(r):
    """P(w₁ / mean(w₂ … w₆) < r) (docs/sweep.md: faint with probability ¼ as 10^U(−4, 0) · mean, else Gamma(1, 1))."""
    faint = min(max((math.log10(r) + 4) / 4, 0.0), 1.0)
    return 0.25 * faint + 0.75 * (1 - (1 + r / 5) ** -5)


def test_the_faint_weight_is_log_uniform_times_the_others_mean():
    r = _chunks(0, 1)
    texel, _ = _kinds(r)
    w = r["w"][(texel == 4) & ((r["w"] > 0).sum(axis=1) == 6)]  # a 3 + 3 cluster: all six weights seen
    ratio = w[:, 0] / w[:, 1:].mean(axis=1)
    assert len(ratio) > 4000
    for x in (1e-4 * 0.999, 1e-3, 1e-2, 0.1, 1.0, 3.0):
        assert _sigma_ok((ratio < x).sum(), len(ratio), _faint_cdf(x)), (x, (ratio < x).mean(), _faint_cdf(x))


class _SomeZeroGammas:
    """A generator whose Gamma draws are 0 on every other row (what Gamma(1, 1) rounds to, rarely)."""

    def __init__(self, seed):
        self.rng = np.random.default_rng(seed)

    def __getattr__(self, name):
        return getattr(self.rng, name)

    def gamma(self, shape, scale, size):
        g = self.rng.gamma(shape, scale, size)
        g[::2] = 0.0
        return g


def test_a_texel_whose_weights_vanish_is_one_depth_of_weight_one():
    z, w, kind = samplers.draw_texels(_SomeZeroGammas(3), 4000)
    assert np.isfinite(w).all() and np.isfinite(z).all()
    np.testing.assert_allclose(w.sum(axis=1), 1, rtol=0, atol=1e-12)
    zero = np.zeros(len(w), bool)
    zero[::2] = True
    faint = (w[zero, 0] > 0) & (w[zero, 0] < 1)  # a faint first weight stays: 10^U · mean(0) = 0 on these rows
    assert not faint.any()
    np.testing.assert_array_equal(w[zero], np.broadcast_to(np.eye(6)[0], w[zero].shape))
    assert (w[~zero] > 0).sum(axis=1).min() >= 1 and (w[~zero, 1:] > 0).any()


def _near_rows(r, texel_kind):
    texel, receiver = _kinds(r)
    sel = (texel == texel_kind) & (receiver == 1)
    k = texel_kind + 1
    z, zf = r["z"][sel, :k], r["zf"][sel]
    gaps = np.abs(z[:, :, None] - z[:, None, :]) + np.eye(k)[None] * 9
    clear = (gaps.min(axis=(1, 2)) > 0.2) & (np.abs(z).max(axis=1) < 0.9)  # K unambiguous, no clip at ±1
    return z[clear], zf[clear]


def test_near_receivers_pick_each_depth_equally_and_either_side():
    r = _chunks(0, 1, 2, 3)
    for t in (1, 3):  # two and four depths
        z, zf = _near_rows(r, t)
        pick = np.argmin(np.abs(z - zf[:, None]), axis=1)
        counts = np.bincount(pick, minlength=t + 1)
        assert len(z) > 500 and all(_sigma_ok(c, len(z), 1 / (t + 1)) for c in counts), (t, counts)
        side = zf > z[np.arange(len(z)), pick]
        assert _sigma_ok(side.sum(), len(z), 0.5), (t, side.mean())


def test_every_bit_of_the_seed_counts():
    case = CASES["shade-float32"]
    for a, b in ((0, 1), (4, 5), (2**31, 2**31 + 1)):
        assert not np.array_equal(draw_rows(case, a, 0, rows=64)["zf"], draw_rows(case, b, 0, rows=64)["zf"])
    # the seed is taken modulo 2^32 (SeedSequence words)
    np.testing.assert_array_equal(draw_rows(case, 7, 0, rows=64)["zf"], draw_rows(case, 2**32 + 7, 0, rows=64)["zf"])


def test_kept_mutant_near_receivers_at_unused_slots_are_seen():
    """A pick over every slot (w ≥ 0: the unused ones hold the first depth) makes K the first depth too often."""
    with kept_mutant("moments_ref/sweep/samplers.py", "_receivers::w > 0 -> w >= 0#0"):
        z, zf = _near_rows(_chunks(0), 1)
    pick = np.argmin(np.abs(z - zf[:, None]), axis=1)
    assert not _sigma_ok((pick == 0).sum(), len(z), 0.5)


@pytest.mark.parametrize("lo, hi", [(1.2e-7 * (1 - 2**-22), 0.25 + 1e-12), (0.5, 0.75), (-0.1, 0.1), (1.2e-7, 0.3)])
def test_the_float32_bounds_are_the_nearest_inside(lo, hi):
    """_inward32: the least float32 ≥ lo and the largest ≤ hi, compared in exact rationals."""
    lo32, hi32 = samplers._inward32(lo, hi)
    assert lo32.dtype == hi32.dtype == np.float32
    f = Fraction
    assert f(float(lo32)) >= f(lo) and f(float(np.nextafter(lo32, np.float32(-1)))) < f(lo)
    assert f(float(hi32)) <= f(hi) and f(float(np.nextafter(hi32, np.float32(1)))) > f(hi)


def test_the_sweepable_cases_are_the_float32_cases_of_the_samplers():
    assert samplers.sweepable("shade-float32") and samplers.sweepable("e2e-msm64-float32")
    assert samplers.sweepable("shadow_intensity6-lower-float32")
    assert not samplers.sweepable("shade-float64") and not samplers.sweepable("no-such-case-float32")
    assert not samplers.sweepable("shade")  # a prefix alone is no case


def test_the_engine_cases_take_the_distribution_and_a_plain_profile_changes_nothing():
    from moments_ref.golden.profile import Profile
    from moments_ref.sweep import engine

    case = CASES["engine-lower-float32"]
    r = draw_rows(case, 3, 0, rows=500)
    got = samplers.build_inputs(case, dict(r))
    want = engine.engine_inputs(case, r["z"], r["w"], r["zf"])  # docs/sweep.md: the distribution, the engine's frame
    assert set(got) == set(want) and all(np.array_equal(got[k], want[k]) for k in want)
    # a profile that declares nothing converts nothing: the same inputs, and no contract rows recorded
    shade = CASES["shade-float32"]
    r = draw_rows(shade, 3, 0, rows=500)
    plain = samplers.build_inputs(shade, dict(r))
    params = dict(r)
    under = samplers.build_inputs(shade, params, Profile())
    assert "contract" not in params and all(np.array_equal(plain[k], under[k]) for k in plain)


def _spread_stat(r):
    pair = _cluster_gaps(r)[1]
    return np.log10(pair).mean(), -3.5 + (math.log(2) - 1.5) / math.log(10)


def _dirichlet_stat(r):
    texel, _ = _kinds(r)
    w = r["w"][texel == 2]
    return ((w[:, 1] / (w[:, 1] + w[:, 2]) - 0.5)**2).mean()


def test_kept_mutants_a_wider_cluster_spread_and_a_gamma_of_shape_half_are_seen():
    """s = 10^U(−7, −1) shifts E log10 |z1 − z2| by −½; Gamma(½, 1) weights make w₂/(w₂ + w₃) Beta(½, ½) (E (x − ½)² = 1/8)."""
    with kept_mutant("moments_ref/sweep/samplers.py", "draw_texels::6 -> 7#0"):
        got, want = _spread_stat(_chunks(0))
    assert abs(got - want - (-0.5)) < 0.15
    with kept_mutant("moments_ref/sweep/samplers.py", "draw_texels::1.0 -> 0.5#0"):
        d = _dirichlet_stat(_chunks(0))
    assert abs(d - 1 / 8) < 0.01
