"""golden/gpuspread.py: the GPU's legitimate evaluations of the chained cases, against statements made here.

* A GPU's ``log`` off by 3 ulps in Ψ4 = (ln ln(10^7 ξ4) − c0)/c1 (each of the two logs), or its ``exp`` off by
  3 ulps in Ψ4⁻¹ (each of the two exps), moves Ψ4 (or ξ4) as the nudge of ξ4 does: checked to first order in
  mpmath, by perturbing the logs and exps themselves.
* The fused stages enumerate every (bias, Φ) choice of plain / contracted / swapped but the reference's own.
* The spread hooks give float32 ports the GPU's evaluations (two nudges and the eight fused chains; the two
  Cholesky evaluations, without and with fma) and float64 ports none; each lies near the exact chain.
"""

from __future__ import annotations

import mpmath
import numpy as np
import pytest

from moments_ref.golden import gpuspread
from moments_ref.golden.truth import msm64_chain, nlq_chain
from moments_ref.moments import BIAS_FLOAT32, BIAS_UNORM16

from _mutants import kept_mutant

EPS32 = float(np.finfo(np.float32).eps)
C0 = mpmath.log(mpmath.log(mpmath.mpf("1.2")))
C1 = mpmath.log(mpmath.log(mpmath.mpf("0.25") * 10**7)) - C0


def _psi4(xi, inner=1, outer=1):
    """Ψ4 with its inner log scaled by ``inner`` and its outer log by ``outer`` (a GPU's relative errors)."""
    return (mpmath.log(mpmath.log(xi * 10**7) * inner) * outer - C0) / C1


def _r(xi):
    return np.array([[-0.5, 0.5, 0.25, xi]])


@pytest.mark.parametrize("xi", [2e-7, 1e-5, 1e-3, 0.05, 0.2])
@pytest.mark.parametrize("sign", [1, -1])
def test_the_encoding_nudge_moves_psi4_as_two_logs_three_ulps_off(xi, sign):
    with mpmath.workdps(40):
        d = sign * gpuspread.TRANSCENDENTAL_ULPS * EPS32
        # inner log off by d relative, outer log off by d relative, in the same direction as the nudge
        l = mpmath.log(mpmath.mpf(xi) * 10**7)
        want = _psi4(mpmath.mpf(xi), 1 + d * mpmath.sign(l), 1 + d * mpmath.sign(mpmath.log(l))) - _psi4(mpmath.mpf(xi))
        nudged = gpuspread._nudge_xi(_r(xi), sign, decoded=False)[0, 3]
        got = _psi4(mpmath.mpf(float(nudged))) - _psi4(mpmath.mpf(xi))
        assert abs(got - want) <= 1e-3 * abs(want) + 1e-18, (got, want)
    assert gpuspread.TRANSCENDENTAL_ULPS == 3  # GLSL 4.30 §4.7.1


@pytest.mark.parametrize("u", [0.05, 0.3, 0.7, 0.99])
@pytest.mark.parametrize("sign", [1, -1])
def test_the_decoding_nudge_moves_xi4_as_two_exps_three_ulps_off(u, sign):
    with mpmath.workdps(40):
        d = sign * gpuspread.TRANSCENDENTAL_ULPS * EPS32
        inner = mpmath.exp(C0 + u * C1)
        xi = mpmath.exp(inner) / 10**7
        off = mpmath.exp(inner * (1 + d)) * (1 + d) / 10**7  # both exps off by d, relative
        nudged = gpuspread._nudge_xi(_r(float(xi)), sign, decoded=True)[0, 3]
        want, got = off / xi - 1, mpmath.mpf(float(nudged)) / mpmath.mpf(float(xi)) - 1
        assert abs(got - want) <= 1e-3 * abs(want) + 1e-15, (got, want)


def test_the_nudge_keeps_the_dtype_the_other_components_and_the_input():
    r = np.array([[-0.5, 0.5, 0.25, 1e-3], [0.1, 0.2, 0.5, 1e-9]], np.float32)
    keep = r.copy()
    out = gpuspread._nudge_xi(r, 1, decoded=False)
    assert out.dtype == np.float32 and np.array_equal(r, keep) and np.array_equal(out[:, :3], r[:, :3])
    assert out[0, 3] > r[0, 3] and out[1, 3] >= np.float32(1.2e-7)  # ξ4 below Ψ4's range read at its clamp
    assert gpuspread._nudge_xi(r, -1, decoded=True)[0, 3] < r[0, 3]


def test_the_fused_stages_are_every_choice_but_the_references():
    st = gpuspread.FUSED_STAGES
    assert len(st) == 8 and len(set(st)) == 8
    assert {(b, p) for b, p, _ in st} == {(b, p) for b in (None, False, True) for p in (None, False, True)} - {(None, None)}
    assert all(s == (p if p is not None else b) for b, p, s in st)


def _rows(n, seed):
    rng = np.random.default_rng(seed)
    z = rng.uniform(-0.9, 0.9, (n, 3))
    w = rng.dirichlet(np.ones(3), n)
    b = np.stack([(w * z**j).sum(axis=1) for j in range(1, 5)], axis=1).astype(np.float32)
    zf = np.clip(z[:, 1] + 0.05, -1, 1).astype(np.float32)
    return b, zf


@pytest.mark.parametrize("fmt", ["64", "32"])
def test_the_chain_hook_gives_float32_ports_the_gpus_evaluations_near_the_exact_chain(fmt):
    b, zf = _rows(12, 1)
    hook = gpuspread.chain_spread(fmt, BIAS_FLOAT32)
    assert hook({"b": b, "zf": zf}, np.float64) == []
    outs = hook({"b": b, "zf": zf}, np.float32)
    assert len(outs) == 2 + 8
    lo, hi = nlq_chain(b.astype(np.float64), zf.astype(np.float64), fmt, BIAS_FLOAT32)
    for (v,) in outs:
        v = np.asarray(v)
        assert v.dtype == np.float32 and v.shape == (12,)
        assert (np.abs(v - (lo + hi) / 2) <= (hi - lo) / 2 + 0.02).all()
    assert len({np.asarray(v).tobytes() for (v,) in outs}) > 1  # not one evaluation repeated


def test_the_msm_hook_is_the_cholesky_evaluation_without_and_with_fma():
    b, zf = _rows(12, 2)
    hook = gpuspread.msm_spread(BIAS_UNORM16)
    assert hook({"b": b, "zf": zf}, np.float64) == []
    outs = hook({"b": b, "zf": zf}, np.float32)
    assert len(outs) == 2
    lo, hi = msm64_chain(b.astype(np.float64), zf.astype(np.float64), BIAS_UNORM16)
    for (v,) in outs:
        assert np.asarray(v).dtype == np.float32
        assert (np.abs(np.asarray(v, np.float64) - (lo + hi) / 2) <= (hi - lo) / 2 + 1e-3).all()


def test_kept_mutant_an_encoding_nudge_without_the_outer_log_is_seen():
    """_nudge_xi with the outer log's share dropped (rel = |L| only) moves Ψ4 by less than two logs off."""
    xi = 1e-3
    with mpmath.workdps(40):
        d = gpuspread.TRANSCENDENTAL_ULPS * EPS32
        want = _psi4(mpmath.mpf(xi), 1 + d, 1 + d) - _psi4(mpmath.mpf(xi))
        with kept_mutant("moments_ref/golden/gpuspread.py",
                         "_nudge_xi::np.abs(big_l) + np.abs(big_l * np.log(np.maximum(big_l, 1e-300))) -> "
                         "np.abs(big_l) - np.abs(big_l * np.log(np.maximum(big_l, 1e-300)))#0"):
            nudged = gpuspread._nudge_xi(_r(xi), 1, decoded=False)[0, 3]
        got = _psi4(mpmath.mpf(float(nudged))) - _psi4(mpmath.mpf(xi))
        assert abs(got - want) > 0.1 * abs(want)
