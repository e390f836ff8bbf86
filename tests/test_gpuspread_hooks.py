"""golden/gpuspread.py's hooks, second part: each evaluation is the one its docstring names, checked against the
reference chain (golden/endtoend.py), the float64 filter (gpu/filtering.py) and Algorithm 1 (msm.py).

* float32_filters: float32 arrays of the depths read in float32; the last is the filter with exact sums (float64) rounded once to float32.
* block_spread: for each filter, the case's chain on that filter's moments cropped by the guard, then the two
  nudged chains and the eight contracted ones; float32 ports only.
* chain_spread: the chain with ξ4 nudged up and with it nudged down (two different evaluations, neither the plain
  chain's everywhere).
* nlq_chain_fused with no stage contracted is the reference chain bit for bit (the bias applied, float32 kept).
* msm_spread: the Cholesky evaluation without and with fma (two different evaluations); msm_chain_fused(fma=None)
  is the texel decoded, biased and bounded in float64 by Algorithm 1.
"""

from __future__ import annotations

import numpy as np
import pytest

from moments_ref import golden
from moments_ref.affine import decode_unorm16, encode_unorm16
from moments_ref.golden import gpuspread
from moments_ref.golden.endtoend import nlq_chain
from moments_ref.gpu.filtering import blur, resolve_moments
from moments_ref.moments import BIAS_FLOAT32, BIAS_UNORM16, bias_moments
from moments_ref.msm import shadow_intensity

from _mutants import kept_mutant


def _rows(n, seed):
    rng = np.random.default_rng(seed)
    z = rng.uniform(-0.9, 0.9, (n, 3))
    w = rng.dirichlet(np.ones(3), n)
    b = np.stack([(w * z**j).sum(axis=1) for j in range(1, 5)], axis=1).astype(np.float32)
    zf = np.clip(z[:, rng.integers(0, 3)] + rng.choice([-1, 1], n) * 10.0 ** rng.uniform(-4, -1, n), -1, 1)
    return b, zf.astype(np.float32)


def test_the_float32_filters_end_with_the_exact_filter_rounded_once():
    depth = golden.golden_arrays(golden.CASES["e2e-block-nlq64-float32"])["depth"][0]
    fs = gpuspread.float32_filters(depth.astype(np.float64))
    assert len(fs) >= 2 and all(f.dtype == np.float32 and f.shape == depth.shape[:2] + (4,) for f in fs)
    exact = blur(resolve_moments(depth.astype(np.float64)))
    assert exact.dtype == np.float64
    np.testing.assert_array_equal(fs[-1], exact.astype(np.float32))
    assert not np.array_equal(fs[0], fs[-1])  # a float32 kernel's sums are not the exact ones
    # a GPU reads the depth buffer in float32: depths not representable in float32 are rounded first
    d64 = depth.astype(np.float64) + np.random.default_rng(0).uniform(-1, 1, depth.shape) * 2.0**-30
    assert not np.array_equal(d64, d64.astype(np.float32))
    for f, g in zip(gpuspread.float32_filters(d64), gpuspread.float32_filters(d64.astype(np.float32))):
        np.testing.assert_array_equal(f, g)


@pytest.mark.parametrize("fmt", ["64", "32"])
def test_the_block_hook_is_each_filter_then_each_chain_on_the_guarded_interior(fmt):
    a = golden.golden_arrays(golden.CASES[f"e2e-block-nlq{fmt}-float32"])
    depth, zf = a["depth"][:2], a["zf"][:2]
    guard = (depth.shape[1] - zf.shape[1]) // 2
    hook = gpuspread.block_spread(fmt, BIAS_FLOAT32, None, "stored", guard, nlq_chain)
    assert hook({"depth": depth, "zf": zf}, np.float64) == []
    outs = hook({"depth": depth, "zf": zf}, np.float32)
    chains = 1 + 2 + len(gpuspread.FUSED_STAGES)
    nf = len(gpuspread.float32_filters(depth[0]))
    assert len(outs) == nf * chains
    assert all(len(o) == 1 and o[0].dtype == np.float32 and o[0].shape == zf.shape for o in outs)
    plain = nlq_chain(fmt, BIAS_FLOAT32)
    for i in range(2):  # the exact filter (the last), cropped by the guard, then the case's chain
        b = blur(resolve_moments(depth[i].astype(np.float64))).astype(np.float32)[guard:-guard, guard:-guard]
        np.testing.assert_array_equal(outs[(nf - 1) * chains][0][i], plain(b, zf[i])[0])
    ref = outs[(nf - 1) * chains][0]
    up, down = outs[(nf - 1) * chains + 1][0], outs[(nf - 1) * chains + 2][0]  # the GPU's log and exp, up and down
    assert (up != ref).any() and (down != ref).any() and (up != down).any()
    b = blur(resolve_moments(depth[0].astype(np.float64))).astype(np.float32)[guard:-guard, guard:-guard]
    for v, s in ((up, 1), (down, -1)):
        np.testing.assert_array_equal(v[0], gpuspread.nlq_chain_gpu(fmt, BIAS_FLOAT32, sign=s)(b, zf[0])[0])
    for (v,) in outs:  # every evaluation near the exact filter's chain; not one repeated
        assert np.abs(v.astype(np.float64) - ref).max() <= 0.05
    assert len({o[0].tobytes() for o in outs}) > chains


@pytest.mark.parametrize("fmt", ["64", "32"])
def test_the_chain_hook_nudges_xi4_both_ways(fmt):
    b, zf = _rows(3000, 7)
    outs = gpuspread.chain_spread(fmt, BIAS_FLOAT32)({"b": b, "zf": zf}, np.float32)
    plain = nlq_chain(fmt, BIAS_FLOAT32)(b, zf)[0]
    up, down = outs[0][0], outs[1][0]
    assert (up != plain).any() and (down != plain).any() and (up != down).any()
    # the two are the GPU chain of TRANSCENDENTAL_ULPS ulps up and down (its nudge checked in mpmath: test_gpuspread.py)
    for v, s in ((up, 1), (down, -1)):
        np.testing.assert_array_equal(v, gpuspread.nlq_chain_gpu(fmt, BIAS_FLOAT32, sign=s)(b, zf)[0])


@pytest.mark.parametrize("fmt", ["64", "32"])
@pytest.mark.parametrize("bias", [BIAS_FLOAT32, None])
def test_the_fused_chain_without_a_contracted_stage_is_the_reference_chain(fmt, bias):
    b, zf = _rows(3000, 8)
    v = gpuspread.nlq_chain_fused(fmt, bias, stages=(None, None, None))(b.astype(np.float64), zf)[0]
    want = nlq_chain(fmt, bias)(b, zf)[0]
    assert v.dtype == np.float32
    np.testing.assert_array_equal(v, want)


def test_the_msm_hook_has_two_evaluations_and_the_float64_stand_in_is_algorithm1():
    b, zf = _rows(3000, 9)
    outs = gpuspread.msm_spread(BIAS_UNORM16)({"b": b, "zf": zf}, np.float32)
    assert len(outs) == 2 and (outs[0][0] != outs[1][0]).any()
    assert all(o[0].dtype == np.float32 for o in outs)
    v = gpuspread.msm_chain_fused(BIAS_UNORM16, None)(b, zf)[0]
    bq = bias_moments(decode_unorm16(encode_unorm16(b), dtype=np.float64), BIAS_UNORM16)
    want = shadow_intensity(bq, zf.astype(np.float64))
    assert v.dtype == np.float64
    np.testing.assert_array_equal(v, want)


def test_kept_mutant_a_fused_chain_that_forgets_the_bias_is_seen():
    b, zf = _rows(3000, 8)
    want = nlq_chain("64", BIAS_FLOAT32)(b, zf)[0]
    with kept_mutant("moments_ref/golden/gpuspread.py", "nlq_chain_fused.chain::bias is not None -> bias is None#0"):
        v = gpuspread.nlq_chain_fused("64", BIAS_FLOAT32, stages=(None, None, None))(b, zf)[0]
    assert (v != want).any()


def test_tied_codes_are_the_channels_within_the_tie_band_of_a_rounding_boundary():
    """tied_codes on texels built from chosen scaled values v = 65535·q (q = M·b + c, HPG17 Eq. (3)'s affine basis):
    a channel is tied exactly when frac(v) is within CHAIN_TIE·65535 of ½, and its other code is the other end of
    that rounding; the codes are the float32 encoder's (affine.encode_unorm16)."""
    from moments_ref.affine import from_optimized
    from moments_ref.golden.truth import CHAIN_TIE

    rng = np.random.default_rng(12)
    k = rng.integers(0, 65535, (4000, 4)).astype(np.float64)
    frac = rng.uniform(0, 1, (4000, 4))
    band = CHAIN_TIE * 65535
    frac = np.where(np.abs(np.abs(frac - 0.5) - band) < 1e-3, 0.5, frac)  # keep clear of the band's edges
    v = k + frac
    b = from_optimized(v / 65535)
    codes, alt, tied = gpuspread.tied_codes(b)
    np.testing.assert_array_equal(codes, encode_unorm16(b.astype(np.float32)))
    assert codes.dtype == alt.dtype == np.uint16 and tied.dtype == bool and tied.shape == (4000, 4)
    want = np.abs(frac - 0.5) <= band
    assert 0.3 < want.mean() < 0.7
    np.testing.assert_array_equal(tied, want & ((codes == k) | (codes == k + 1)))
    assert (tied == want).mean() > 0.999  # the float32 encoder rounds to an end of its rounding
    got = np.sort(np.stack([codes, alt], -1).astype(np.int64), axis=-1)
    np.testing.assert_array_equal(got[tied], np.stack([k, k + 1], -1)[tied])  # the two ends of the tie
    np.testing.assert_array_equal(alt[~tied], codes[~tied])  # no tie: no other code
    assert gpuspread.TIE_SUBSETS[0] == (0,) and len(gpuspread.TIE_SUBSETS) == 15 and gpuspread.TIE_SUBSETS[-1] == (0, 1, 2, 3)


def test_the_msm_full_hook_evaluates_each_tie_subset_on_its_rows_only():
    from moments_ref.affine import from_optimized

    rng = np.random.default_rng(13)
    v = rng.integers(0, 65535, (300, 4)) + np.where(rng.random((300, 4)) < 0.6, 0.5, 0.1)  # ties on 60 % of channels
    b = from_optimized(v / 65535).astype(np.float32)
    zf = rng.uniform(-1, 1, 300).astype(np.float32)
    full = gpuspread.msm_spread(BIAS_UNORM16).full
    assert full({"b": b, "zf": zf}, np.float64) == []
    outs = full({"b": b, "zf": zf}, np.float32)
    tied = gpuspread.tied_codes(b)[2]
    subsets = [f for f in gpuspread.TIE_SUBSETS if tied[:, list(f)].all(axis=1).any()]
    assert len(subsets) == 15 and len(outs) == 3 * len(subsets)  # without fma, with fma, float64
    for i, f in enumerate(subsets):
        rows = tied[:, list(f)].all(axis=1)
        for j in range(3):
            (x,) = outs[3 * i + j]
            assert np.isnan(x[~rows]).all() and not np.isnan(x[rows]).all()
        np.testing.assert_array_equal(outs[3 * i + 2][0][rows],
                                      gpuspread.msm_chain_fused(BIAS_UNORM16, None, f)(b[rows], zf[rows])[0])
        assert (outs[3 * i][0][rows] != outs[3 * i + 2][0][rows]).any()  # float32 and float64 evaluations


def test_the_tie_band_edges_and_the_codes_ends():
    """At the band's edge (CHAIN_TIE·65535 from ½, a hair of 1e-6 code wider for float64's rounding): tied just inside,
    not just outside; a tie at the range's ends keeps both codes in 0 … 65535; beyond the range nothing is tied."""
    from moments_ref.affine import from_optimized
    from moments_ref.golden.truth import CHAIN_TIE

    band = CHAIN_TIE * 65535
    v = np.array([[1000.5 + band + 0.7e-6, 2000.5 - band - 0.7e-6, 3000.5 + band + 1.7e-6, 4000.5 - band - 1.7e-6],
                  [0.5, 65534.5, 65535.5, -0.5]])
    codes, alt, tied = gpuspread.tied_codes(from_optimized(v / 65535))
    np.testing.assert_array_equal(tied, [[True, True, False, False], [True, True, False, False]])
    assert {int(codes[1, 0]), int(alt[1, 0])} == {0, 1} and {int(codes[1, 1]), int(alt[1, 1])} == {65534, 65535}
    assert codes[1, 2] == alt[1, 2] == 65535 and codes[1, 3] == alt[1, 3] == 0  # clamped: one code, no tie


def test_a_flipped_chain_is_nan_exactly_off_its_ties():
    from moments_ref.affine import from_optimized

    rng = np.random.default_rng(14)
    v = rng.integers(0, 65535, (400, 4)) + np.where(rng.random((400, 4)) < 0.5, 0.5, 0.1)
    b = from_optimized(v / 65535).astype(np.float32)
    zf = rng.uniform(-1, 1, 400).astype(np.float32)
    tied = gpuspread.tied_codes(b)[2]
    for flip in ((0,), (1, 3)):
        for fma in (False, True, None):
            x = gpuspread.msm_chain_fused(BIAS_UNORM16, fma, flip)(b, zf)[0]
            rows = tied[:, list(flip)].all(axis=1)
            assert np.isnan(x[~rows]).all() and np.isfinite(x[rows]).any()  # random codes: not all valid moments
    full = gpuspread.msm_spread(BIAS_UNORM16).full({"b": b, "zf": zf}, np.float32)
    assert any((full[i][0] != full[i + 1][0])[~np.isnan(full[i][0])].any() for i in range(0, len(full), 3))  # fma


@pytest.mark.parametrize("fmt", ["64", "32"])
def test_the_gpu_chain_nudges_as_the_logs_before_encoding_and_as_the_exps_after_decoding(fmt):
    """Ψ4's logs act when the texel is encoded, Ψ4⁻¹'s exps when it is decoded (HPG17 Eq. (5) and its inverse): the
    GPU chain is the reference chain with those two nudges (each checked in mpmath in tests/test_gpuspread.py)."""
    from moments_ref.golden.variants import shade_reference
    from moments_ref.nonlinear import SHADE_TOLERANCE, phi
    from moments_ref.packing import pack32, pack64, unpack32, unpack64

    b, zf = _rows(3000, 15)
    for s in (1, -1):
        r = gpuspread._nudge_xi(phi(bias_moments(b, BIAS_FLOAT32)), s, decoded=False)
        r = unpack64(pack64(r), dtype=np.float32) if fmt == "64" else unpack32(pack32(r), dtype=np.float32)
        want = shade_reference(SHADE_TOLERANCE, "stored")(gpuspread._nudge_xi(r, s, decoded=True), zf)[0]
        np.testing.assert_array_equal(gpuspread.nlq_chain_gpu(fmt, BIAS_FLOAT32, sign=s)(b, zf)[0], want)


def test_kept_mutant_a_tie_band_around_a_quarter_is_seen():
    """tied_codes measuring the distance to k + ¼ instead of k + ½ ties other channels than the band's."""
    from moments_ref.affine import from_optimized

    v = np.array([[10.5, 20.5, 30.25, 40.1]])
    with kept_mutant("moments_ref/golden/gpuspread.py", "tied_codes::0.5 -> 0.25#0"):
        tied = gpuspread.tied_codes(from_optimized(v / 65535))[2]
    assert not np.array_equal(tied, [[True, True, False, False]])  # the band's own ties (test above)
