"""The sweep's draw (sweep/samplers.py) against docs/sweep.md's description of it, stated here.

Every stratum is drawn, about equally often; each texel kind has its number of depths (weights
positive, summing to one, unused slots at the first depth); the depths and receivers have the
documented shapes (near an end, faint weights, a receiver near a depth of the texel or an end);
the texel formats are drawn equally; the case's inputs are what its sampler says (the moments in
float32, biased by the harness's preset or not, Φ of them or a decoded texel, the codes of a
fresh texel); the rows are a function of (seed, case, profile, chunk) only. A sampler that leaves
its contract or drops a stratum fails here.
"""

from __future__ import annotations

import numpy as np
import pytest

from moments_ref import moments, nonlinear, packing
from moments_ref.golden.cases import CASES
from moments_ref.golden.contract import XI4_RANGE, rows_inside
from moments_ref.msm6 import BIAS6_FLOAT32
from moments_ref.sweep import samplers
from moments_ref.sweep.samplers import CHUNK, RECEIVERS, STRATA, TEXELS, build_inputs, draw_rows

from _mutants import kept_mutant

N = CHUNK  # one whole chunk: 131072 rows, ~8700 per stratum


@pytest.fixture
def rows():
    """One chunk, drawn inside each test (not cached: the mutation tool's coverage then sees the draw in the test)."""
    return draw_rows(CASES["shade-float32"], 11, 2)


def _sigma_ok(count, n, p, k=6):
    return abs(count - n * p) <= k * np.sqrt(n * p * (1 - p))


def test_every_stratum_is_drawn_about_equally(rows):
    assert len(STRATA) == len(TEXELS) * len(RECEIVERS) == 15
    s = rows["stratum"].astype(int)
    counts = np.bincount(s, minlength=len(STRATA))
    assert len(counts) == 15 and all(_sigma_ok(c, N, 1 / 15) for c in counts), counts
    assert STRATA[4] == "two/near" and STRATA[14] == "cluster/end"
    f = np.bincount(rows["fmt"], minlength=3)
    assert len(f) == 3 and all(_sigma_ok(c, N, 1 / 3) for c in f), f


def test_each_texel_kind_has_its_depths_and_a_distribution(rows):
    z, w = rows["z"], rows["w"]
    texel = rows["stratum"].astype(int) // len(RECEIVERS)
    assert z.shape == w.shape == (N, 6) and z.dtype == w.dtype == np.float64
    assert (np.abs(z) <= 1).all() and (w >= 0).all()
    np.testing.assert_allclose(w.sum(axis=1), 1, rtol=0, atol=1e-12)
    used = w > 0
    for t in range(4):  # one .. four: exactly that many depths, in the first slots
        k = used[texel == t]
        assert (k.sum(axis=1) == t + 1).all() and k[:, :t + 1].all()
    c = used[texel == 4]  # clusters: 1-3 depths in slots 0-2, 1-3 in slots 3-5
    assert c[:, 0].all() and c[:, 3].all() and (c.sum(axis=1) >= 2).all()
    assert _sigma_ok((c.sum(axis=1) == 6).sum(), len(c), 1 / 9)  # three and three: (1/3)^2
    assert (z[~used] == np.broadcast_to(z[:, :1], z.shape)[~used]).all()  # unused slots: the first depth
    # the two clusters: spread at most 10^-1 around their centre
    zc = z[texel == 4]
    first = np.where(c[:, :3], zc[:, :3], np.nan)
    assert np.nanmax(np.nanmax(first, axis=1) - np.nanmin(first, axis=1)) <= 0.2 + 1e-12


def test_depths_near_an_end_and_faint_weights_are_drawn_as_documented(rows):
    z, w = rows["z"], rows["w"]
    texel = rows["stratum"].astype(int) // len(RECEIVERS)
    one = z[texel == 0, 0]
    # P(1 - |z| < 1e-2) = 1/2 · 1/2 (near an end, 10^U(-4, 0) < 1e-2) + 1/2 · 1e-2 (uniform)
    assert _sigma_ok((1 - np.abs(one) < 1e-2).sum(), len(one), 0.255)
    assert _sigma_ok((one > 0).sum(), len(one), 0.5)
    assert (1 - np.abs(one) >= 1e-4 * (1 - 1e-9)).mean() > 0.99  # near-end depths stay 10^-4 inside
    # faint: with probability 1/4 the first weight is 10^U(-4, 0) times the others' mean: among two-depth
    # texels, w0 < w1 / 100 for about 1/4 · 1/2 of them (Dirichlet alone: well under 1%)
    two = w[texel == 1]
    frac = (two[:, 0] < two[:, 1] / 100).mean()
    assert 0.09 < frac < 0.16, frac


def test_receivers_are_uniform_near_a_depth_or_near_an_end(rows):
    z, w, zf = rows["z"], rows["w"], rows["zf"]
    receiver = rows["stratum"].astype(int) % len(RECEIVERS)
    assert (np.abs(zf) <= 1).all()
    u = zf[receiver == 0]
    assert _sigma_ok((u > 0).sum(), len(u), 0.5) and _sigma_ok((np.abs(u) < 0.5).sum(), len(u), 0.5)
    near = receiver == 1
    dist = np.where(w[near] > 0, np.abs(z[near] - zf[near, None]), np.inf).min(axis=1)
    assert (dist <= 0.1 + 1e-12).all()
    assert _sigma_ok((dist < 1e-4).sum(), near.sum(), 0.5, k=8)  # 10^U(-7, -1): half below 10^-4
    end = 1 - np.abs(zf[receiver == 2])
    assert (end >= 1e-7 * (1 - 1e-6)).all() and (end <= 0.1 + 1e-12).all()
    assert _sigma_ok((end < 1e-4).sum(), len(end), 0.5) and _sigma_ok((zf[receiver == 2] > 0).sum(), len(end), 0.5)


def test_rows_are_a_function_of_seed_case_profile_and_chunk():
    case = CASES["shade-float32"]
    a = draw_rows(case, 5, 1, rows=500)
    assert all(len(v) == 500 for v in a.values())
    again = draw_rows(case, 5, 1, rows=500)
    assert all(np.array_equal(a[k], again[k]) for k in a)
    for other in (draw_rows(case, 5, 1, rows=500, profile_key="unit"), draw_rows(CASES["pack64-float32"], 5, 1, 500),
                  draw_rows(case, 6, 1, rows=500), draw_rows(case, 5, 2, rows=500)):
        assert not np.array_equal(other["zf"], a["zf"])
    # the engine cases take the distribution: no texel format
    assert (draw_rows(CASES["engine-lower-float32"], 5, 1, rows=500)["fmt"] == 0).all()


def _moments32(r, k=4):
    """b = Σ w z^j (j = 1..k) in float64, rounded once to float32 (a 128-bit float texel)."""
    return np.stack([(r["w"] * r["z"]**j).sum(axis=1) for j in range(1, k + 1)], axis=1).astype(np.float32)


def _bias(b, preset):
    """Slides, "Bias the moments": b' = (1 - α) b + α b*, exactly (float64)."""
    return (1 - preset.alpha) * np.asarray(b, np.float64) + preset.alpha * np.asarray(preset.target, np.float64)


@pytest.mark.parametrize("name, k, preset", [("shadow_intensity-lower-float32", 4, moments.BIAS_FLOAT32),
                                             ("shadow_intensity-upper-float32", 4, moments.BIAS_FLOAT32),
                                             ("shadow_intensity6-lower-float32", 6, BIAS6_FLOAT32),
                                             ("e2e-nlq64-float32", 4, None), ("e2e-msm64-float32", 4, None)])
def test_the_moment_inputs_are_the_texels_moments_biased_by_the_harness_or_not(name, k, preset):
    case = CASES[name]
    r = draw_rows(case, 3, 0, rows=3000)
    inputs = build_inputs(case, dict(r))
    b, zf = inputs["b"], inputs["zf"]
    assert b.dtype == zf.dtype == np.float32 and b.shape == (3000, k)
    np.testing.assert_array_equal(zf, r["zf"].astype(np.float32))
    want = _moments32(r, k) if preset is None else _bias(_moments32(r, k), preset)
    np.testing.assert_allclose(b, want, rtol=0, atol=4 * 2.0**-24)  # a float32 shader's bias: a few ulps
    if preset is not None:
        assert np.abs(b - _moments32(r, k)).max() > 1e-2 * preset.alpha  # biased, not the raw moments


def _phi32(r):
    """Φ of the texel's moments biased in float32 (HPG17 Eq. (5), Slides "Bias the moments"), as a shader computes
    it, then kept inside Algorithm 3's contract: v2 in [0, 1], ξ4 in the contract's range (its float32 bounds inside)."""
    b = _moments32(r)
    biased = (np.float32(1 - moments.BIAS_FLOAT32.alpha) * b
              + np.float32(moments.BIAS_FLOAT32.alpha) * np.asarray(moments.BIAS_FLOAT32.target, np.float32))
    assert np.abs(biased.astype(np.float64) - _bias(b, moments.BIAS_FLOAT32)).max() < 4 * 2.0**-24
    phi = np.asarray(nonlinear.phi(moments.bias_moments(b, moments.BIAS_FLOAT32)))
    assert phi.dtype == np.float32
    lo, hi = (np.float32(v) for v in XI4_RANGE)
    lo = lo if float(lo) >= XI4_RANGE[0] else np.nextafter(lo, np.float32(1))  # the float32 bounds inside the range
    hi = hi if float(hi) <= XI4_RANGE[1] else np.nextafter(hi, np.float32(0))
    assert XI4_RANGE[0] <= float(lo) < XI4_RANGE[0] * (1 + 2**-22) and XI4_RANGE[1] * (1 - 2**-22) < float(hi)
    phi[:, 2] = np.clip(phi[:, 2], 0, 1)
    phi[:, 3] = np.clip(phi[:, 3], lo, hi)
    return phi


def _inside(case, inputs):
    return np.asarray(rows_inside(case.contract, inputs), bool)


def test_algorithm3_gets_phi_of_the_biased_moments_or_a_decoded_texel_inside_its_contract():
    case = CASES["shade-float32"]
    r = draw_rows(case, 4, 0, rows=6000)
    inputs = build_inputs(case, dict(r))
    x = inputs["r"]
    assert x.dtype == np.float32 and x.shape == (6000, 4)
    assert _inside(case, inputs).all()
    fmt = r["fmt"]
    assert {0, 1, 2} <= set(fmt.tolist())
    phi = _phi32(r)
    np.testing.assert_array_equal(x[fmt == 0], phi[fmt == 0])
    # a decoded 64-bit texel re-encodes to itself (y1, y2, v2 to float32 rounding, ξ4 to a code: its float32
    # rounding can cross a ceil boundary); a fresh Φ mostly does not (up to half a code off the grid)
    x64 = x.astype(np.float64)
    again64 = packing.unpack64(packing.pack64(x64))
    np.testing.assert_allclose(again64[fmt == 1, :3], x64[fmt == 1, :3], rtol=0, atol=2e-7)
    np.testing.assert_allclose(again64[fmt == 1, 3], x64[fmt == 1, 3], rtol=2e-3, atol=0)
    assert (np.abs(again64[fmt == 0, :3] - x64[fmt == 0, :3]).max(axis=1) > 1e-6).mean() > 0.5
    # a decoded 32-bit texel lies on its cells' decode positions (docs/formats.md: depth at a cell's upper end,
    # 511.5 (y + 1) an integer; √v2 at the centre, 128 √v2 − 1/2 an integer); Φ and the 64-bit texel mostly do not
    def on_grid(t):
        d = 511.5 * (t[:, :2] + 1)
        v = 128 * np.sqrt(t[:, 2]) - 0.5
        return (np.abs(d - np.rint(d)).max(axis=1) < 1e-3) & (np.abs(v - np.rint(v)) < 1e-3)

    assert on_grid(x64[fmt == 2]).all()
    assert on_grid(x64[fmt == 0]).mean() < 0.01 and on_grid(x64[fmt == 1]).mean() < 0.01


@pytest.mark.parametrize("fmt", ["64", "32"])
def test_the_codecs_get_a_fresh_texel_and_its_codes(fmt):
    pack, unpack = CASES[f"pack{fmt}-float32"], CASES[f"unpack{fmt}-float32"]
    r = draw_rows(pack, 9, 0, rows=3000)
    x = build_inputs(pack, dict(r))["r"]
    assert x.dtype == np.float32
    np.testing.assert_array_equal(x, _phi32(r))  # Φ of every row, whatever its fmt
    encode = packing.pack64 if fmt == "64" else packing.pack32
    codes = build_inputs(unpack, dict(r))["q" if fmt == "64" else "p"]
    np.testing.assert_array_equal(codes, encode(x))  # the float32 encoder, as a shader


def _end_distance(r):
    receiver = r["stratum"].astype(int) % len(RECEIVERS)
    return 1 - np.abs(r["zf"][receiver == 2])


def test_kept_mutant_end_receivers_drawn_beyond_the_end_are_seen():
    """The sampler whose "end" receivers are ±(1 + 10^U(−7, −1)) (a sign slip) leaves the depth range."""
    case = CASES["shade-float32"]
    d = _end_distance(draw_rows(case, 11, 2, rows=5000))
    assert ((d >= 1e-7 * (1 - 1e-6)) & (d <= 0.1 + 1e-12)).all()
    with kept_mutant("moments_ref/sweep/samplers.py",
                     "_receivers::1 - _log_uniform(rng, -7, -1, n) -> 1 + _log_uniform(rng, -7, -1, n)#0"):
        assert (_end_distance(draw_rows(case, 11, 2, rows=5000)) < 0).all()
