"""The fresh hand-written batch's survivors in golden/ (issue 38, round six): one statement each.

Each test states what the docs promise, against hand-built inputs or an independent computation,
not the code's own output.
"""

from __future__ import annotations

import itertools
from dataclasses import replace
from fractions import Fraction

import mpmath
import numpy as np
import pytest

from moments_ref import InputError, golden, precise
from moments_ref.golden import bands, engine, texel_codes, texel_truth, truth
from moments_ref.golden.profile import Profile, parse_profile, profile_from_args
from moments_ref.golden.units import ceil2, ulp
from moments_ref.golden.verifier import verify

MJP_BIAS = {"alpha": 3e-6, "target": [0.5, 0.34375, 0.265625, 0.2265625], "applied": "inside"}


@pytest.mark.parametrize("value", [8.0, True, 16.0])
def test_subtexel_bits_is_an_integer_not_a_float_or_bool_that_compares_equal(value):
    # 8.0 == 8 and True == 1 in Python: a membership test alone would accept them (docs/ports.md: 4 .. 16, the
    # integer bits of the filter weights).
    with pytest.raises(InputError, match=r"format\.subtexel_bits.*integer"):
        parse_profile({"format": {"subtexel_bits": value}})
    assert dict(parse_profile({"format": {"subtexel_bits": 8}}).format) == {"subtexel_bits": 8}


def test_a_functions_table_is_part_of_the_key():
    # Two profiles differing only in [functions.shade] derive different goldens: different keys, not default.
    p = parse_profile({"functions": {"shade": {"depth": "[0,1]"}}})
    q = parse_profile({"functions": {"shade": {"depth": "[-1,1]", "output": "visibility"}}})
    assert len({p.key, q.key, Profile().key}) == 3 and not p.is_default


def test_a_bias_flag_keeps_the_files_other_bias_keys(tmp_path):
    f = tmp_path / "p.toml"
    f.write_text('[bias]\nalpha = 3e-6\ntarget = [0.5, 0.34375, 0.265625, 0.2265625]\napplied = "inside"\n')
    q = profile_from_args(f, "x", bias_alpha="1e-4")
    assert (q.bias.alpha, q.bias.target, q.bias.applied) == (1e-4, (0.5, 0.34375, 0.265625, 0.2265625), "inside")
    r = profile_from_args(f, "x", bias_applied="before")
    assert (r.bias.alpha, r.bias.target, r.bias.applied) == (3e-6, (0.5, 0.34375, 0.265625, 0.2265625), "before")


def test_a_profiled_folder_verified_without_the_profile_keeps_its_ill_rows(tmp_path):
    # A folder written under a profile holds the profile's exact values; verified without --profile, its
    # ill-conditioned rows must not be re-judged by the plain case's neighbourhood (other depths, no bias).
    name = "shadow_intensity-lower-float32"
    p = parse_profile({"depth": "[0,1]", "output": "visibility", "bias": MJP_BIAS})
    golden.write(tmp_path / "g", [name], profile=p)
    with np.load(tmp_path / "g" / f"{name}.npz") as g:
        got, flags = g["intensity_float32"], g["flags"]
    assert sum("wide_spread" in str(f) for f in flags) >= 5  # the statement has rows to bite on
    np.savez(tmp_path / "r.npz", **{f"{name}.intensity": got})
    case = verify(tmp_path / "g", tmp_path / "r.npz").cases[0]
    assert case.status == "pass" and case.verdict.row_pass.all()


def _psi4_inverse(u):
    """Ψ4⁻¹(u) at 50 digits, from HPG17 §3.3's Ψ4 (not texel_truth's)."""
    with mpmath.workdps(50):
        c0 = mpmath.log(mpmath.log(mpmath.mpf("1.2")))
        c1 = mpmath.log(mpmath.log(mpmath.mpf("0.25") * 10**7)) - c0
        return float(mpmath.exp(mpmath.exp(c0 + mpmath.mpf(u.numerator) / u.denominator * c1)) / 10**7)


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_a_32bit_word_with_all_four_fields_on_ties_has_all_fifteen_neighbours(dtype):
    # y1, y2 on 10-bit cell boundaries, sqrt(v2) on a 7-bit one, Psi4 on a 6-bit one: every field on its tie, so
    # the per-component rule accepts each of the 2**4 - 1 words with a non-empty set of fields taken across.
    r = np.array([[2 * 300 / 1023 - 1, 2 * 700 / 1023 - 1, (50 / 128) ** 2, _psi4_inverse(Fraction(20, 64))]], dtype)
    cells, margins, across = texel_truth.pack32(r, components=True)
    assert (margins <= texel_codes.pack32_tie_band(r)).all() and (across != cells).all()
    want = {int(texel_truth.fold32(np.where(np.array(pick, bool), across, cells))[0])
            for pick in itertools.product((0, 1), repeat=4) if any(pick)}
    got = [int(w[0][0]) for w in texel_codes.pack32_neighbours(r)]
    assert len(want) == 15 and set(got) == want


def test_rows_at_the_tie_bands_edge_decide_as_the_exact_codes():
    # y1 within a few float64 ulps either side of (boundary +- band): the float64 margin can fall on the other side
    # of the band than the exact one, so such rows are recomputed exactly (texel_truth, mpmath).
    band = texel_codes.pack32_tie_band(np.zeros((1, 4)))[0, 0]  # a fraction of the range: |y - boundary| / 2
    ys = []
    for k, s in itertools.product((200, 300, 700), (1, -1)):
        y0 = 2 * k / 1023 - 1 + 2 * s * band
        ys += list(y0 + np.spacing(y0) * np.arange(-40, 41))
    y = np.array(ys)
    r = np.c_[y, np.full_like(y, 0.1), np.full_like(y, 0.3), np.full_like(y, 0.01)]
    cells, margins, across = texel_codes.pack32_ties(r)
    band = texel_codes.pack32_tie_band(r)
    e_cells, e_margins, e_across = texel_truth.pack32(r, components=True)
    tie = e_margins <= band
    assert 0 < tie[:, 0].sum() < len(r)  # the rows straddle the edge
    assert np.array_equal(margins <= band, tie) and np.array_equal(across, np.where(tie, e_across, e_cells))


@pytest.mark.parametrize("name", ["engine-lower-float32", "engine-upper-float32"])
def test_the_engine_bands_and_ill_flags_follow_the_documented_recipe(name):
    # golden/engine.py's docstring: from the interval [lo, hi] of legitimate values, ill = float32 width > CAP;
    # half-width ceil2(max(mid - lo, hi - mid) + (CAP if ill else m)), m = max(3 (hi - lo), 4 noise, 8 ulp(1)),
    # capped at CAP unless ill; the midpoint of the float32 interval is the expected value.
    case = golden.CASES[name]
    a, ctx = golden.golden_arrays(case), case.engine
    b = engine.moments_of_rows(a["support"], a["mass"], np.dtype(case.dtype), bias=ctx.get("before"))
    intervals, noise = engine.engine_interval(ctx, a, b), engine.case_noise(ctx, case.dtype)
    lo32, hi32 = intervals["float32"]
    ill, mid, n = hi32 - lo32 > 0.02, (lo32 + hi32) / 2, len(b)
    assert np.array_equal(ill, ["wide_spread" in str(f).split(",") for f in a["flags"]])
    for d, (lo, hi) in intervals.items():
        m = np.maximum.reduce([3 * (hi - lo), np.full(n, 4 * noise[d]), 8 * ulp(np.ones(n), d)])
        want = np.where(ill, ceil2(np.fmax(mid - lo, hi - mid) + 0.02),
                        np.minimum(ceil2(np.fmax(mid - lo, hi - mid) + m), 0.02))
        np.testing.assert_array_equal(a[f"intensity_tolerance_{d}"], np.where(np.isfinite(mid), want, np.inf))
    if name == "engine-upper-float32":  # the statement bites: rows between CAP and 2 CAP, rows the noise decides
        assert ((hi32 - lo32 > 0.02) & (hi32 - lo32 <= 0.04)).any() and noise["float32"] > 0
        lo, hi = intervals["float32"]
        assert (4 * noise["float32"] > np.maximum(3 * (hi - lo), 8 * ulp(np.ones(n), "float32")))[~ill].any()


def _chain_rows(n=8, seed=7):
    rng = np.random.default_rng(seed)
    sup, mass = rng.uniform(-0.9, 0.9, (n, 3)), rng.dirichlet([1, 1, 1], n)
    return engine.moments_of_rows(sup, mass, np.dtype(np.float64)), np.clip(sup[:, 0] + 0.05, -1, 1)


def test_the_affine_chain_with_a_tie_over_half_a_code_spans_all_sixteen_texels():
    # msm64_chain's docstring: a channel within `tie` of a rounding boundary takes both codes. Every channel lies
    # within half a code of one, so with a tie over half a code the chain is the bound over all 2**4 texels
    # {floor(s), floor(s) + 1} per channel (enumerated here, decoded and bounded in mpmath).
    b, zf = _chain_rows()
    # every channel 0.4 codes from its half-integer boundary (frac 0.1 or 0.9): inside a tie of 0.52 codes only
    s = np.clip(texel_truth.to_optimized(b)[0], 0, 1) * 65535
    s = np.floor(s) + np.where(np.arange(8)[:, None] % 2, 0.1, 0.9)
    b = texel_truth.from_optimized(s / 65535)[0]
    lo, hi = truth.msm64_chain(b, zf, dps=30, tie=0.52 / 65535)
    s = texel_truth.to_optimized(b)[0] * 65535
    q = np.array([list(itertools.product(*[(int(np.floor(v)), int(np.floor(v)) + 1) for v in row])) for row in s])
    bq = texel_truth.decode_unorm16(q.reshape(-1, 4).clip(0, 65535).astype(np.uint16))[0]
    v = precise.shadow_intensity(bq, np.repeat(zf, 16), dps=30).reshape(-1, 16)
    assert (hi > lo).sum() >= 4
    np.testing.assert_array_equal(lo, v.min(axis=1))
    np.testing.assert_array_equal(hi, v.max(axis=1))


def test_the_nlq_chain_takes_both_codes_of_every_channel_within_its_tie():
    # nlq_chain's docstring: both codes where the exact value lies within `tie` of the rounding boundary. Every
    # channel lies within half a code of its boundary, so any two ties above half a code give the same chain,
    # and it holds the chain of any smaller tie.
    b, zf = _chain_rows(6, 11)
    wide = truth.nlq_chain(b, zf, "64", dps=30, tie=0.95 / 65535)
    np.testing.assert_array_equal(truth.nlq_chain(b, zf, "64", dps=30, tie=0.55 / 65535), wide)
    lo, hi = truth.nlq_chain(b, zf, "64", dps=30)
    assert (wide[0] <= lo).all() and (hi <= wide[1]).all() and (wide[1] - wide[0] > hi - lo).sum() >= 3


@pytest.mark.parametrize("formulation,explained", [(0.29, True), (0.51, True), (0.27, False), (0.53, False)])
def test_a_formulation_is_kept_within_the_cap_of_the_nearest_exact_value(formulation, explained):
    # bands.confirm: formulations count only within CAP (0.02 of the range) of the row's exact values, measured
    # from the nearest (a confirm_truth gives lo and hi). A hand-built case: reference 0.4 everywhere, exact
    # values lo = 0.3 and hi = 0.5, one formulation; a port returning the formulation is explained iff it lies
    # within 0.02 of 0.3 or of 0.5.
    def const(x):
        return lambda b, zf, **kw: (np.full(len(zf), x),)

    def lo_hi(b, zf):
        return ((np.full(len(zf), 0.3), np.full(len(zf), 0.5)),)

    def hook(inputs, dt):
        return [(np.full(len(inputs["zf"]), formulation),)]

    case = replace(golden.CASES["shadow_intensity-lower-float32"], reference=const(0.4), truth=None,
                   confirm_truth=lo_hi, spread_hook=hook, value_range=(0, 1))
    inputs = {"b": np.array([[0.1, 0.4, 0.1, 0.3]], np.float32), "zf": np.array([0.2], np.float32)}
    wrong = bands.confirm(case, inputs, {"intensity": np.array([formulation])})
    assert wrong.tolist() == [not explained]
