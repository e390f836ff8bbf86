"""The engine's interval of legitimate values is exactly the set golden/engine.py's docstring lists.

The module docstring (HPG17 §3.2, Algorithm 1, the NLQ chain of §3.3–§3.5) says what a correct engine may return
on a row: the bound of the unbiased moments biased by each legitimate bias, in float64 and (for a float32 port) by
this package, the papers' printed formulations and the chain as a compiler contracts it; the same on the port's
input rounding (the unbiased moments moved by one ulp per component with alternating signs, b (1 ± ε s), s =
(+, −, +, −), and zf moved by 1 … 3 ulps each way); this package's pipeline as the port runs it on the port's own
input (moved by one ulp, and b and zf scaled jointly by 1 ± k ε, k = 1 … 3), where the port's own bias is
legitimate (a declared bias equal to a legitimate one within a relative 1e-12, targets within 1e-15 absolute
besides); the shipped ports' float32 Cholesky evaluation (with and without fma) where it lies within CAP of the
float64 bound; and Z just below and at-or-below zf's ±3-ulp neighbourhood where a depth with mass lies in it.

This file evaluates that list here, each item from the public evaluations (Algorithm 1, the printed and slides'
formulations, the shipped Cholesky, the fused and ``mix`` bias, the NLQ chains), the legitimate biases written by
hand per context, the moved inputs by the recipe's arithmetic and Z counted by hand from unnormalised weights;
the engine's [lo, hi] must be its least and largest value, bit for bit: a value missing from the list (a moved
input 2 ulps or ½ ulp away, a sign pattern paired differently, a formulation dropped) or one that no legitimate
evaluation gives (a bias matched too loosely, a neighbourhood in the wrong precision) changes an end on some row.
"""

from __future__ import annotations

import numpy as np
import pytest

from moments_ref.golden import engine
from moments_ref.golden.endtoend import nlq_chain
from moments_ref.golden.gpuspread import FUSED_STAGES, nlq_chain_fused, nlq_chain_gpu
from moments_ref.golden.paper import cholesky_bound, printed_bound, slides_bound
from moments_ref.gpu.fused32 import bias_fused, bias_lerp
from moments_ref.moments import BIAS_FLOAT32, BIAS_UNORM16, BiasPreset, bias_moments
from moments_ref.msm import shadow_intensity
from moments_ref.scene.depth import moments_affine

CAP, K = 0.02, 3
INTERIOR = (0.1, 0.4, 0.05, 0.3)  # one of the docstring's interior targets
SINGULAR = (0.0, 1.0, 0.0, 1.0)  # ½ δ(−1) + ½ δ(1): on the boundary of the moment space
PAPERS = [(0.0, 0.375, 0.0, 0.375), (0.0, 0.628, 0.0, 0.628), (0.0, 1 / 3, 0.0, 0.2), INTERIOR]


def _rows():
    """(support, mass, zf): unnormalised weights (Z is a fraction of the mass), padding points of mass 0 at depth 0,
    receivers between, on and within a few float32 ulps of the depths, and near 0 where only padding lies."""
    x = float(np.float32(0.3))
    u = float(np.spacing(np.float32(0.3)))
    dists = [([x, -0.5], [0.8, 1.2]), ([-0.8, 0.4], [3.0, 2.0]), ([-0.6, -0.2, 0.3, 1.0], [1, 1, 1, 1]),
             ([x - 1e-4, x, x + 5e-5, x + 1e-4], [0.2, 0.3, 0.3, 0.2]), ([-1.0, 1.0], [1.0, 2.0]),
             ([0.5], [2.5]), ([-0.6, -0.2, 0.3], [0.3, 0.3, 0.4]), ([x + 2 * u, -0.7, 0.9], [1.5, 0.5, 1.0])]
    receivers = [x, x - u, x + u, x - 2 * u, x + 3 * u, x - 4 * u, x + 1e-3, -0.1, 0.0, 1e-9, 0.45, 0.8, -0.7]
    sup, mass, zf = [], [], []
    for z, w in dists:
        for r in receivers:
            sup.append(np.pad(z, (0, 4 - len(z)))), mass.append(np.pad(w, (0, 4 - len(w)))), zf.append(r)
    return np.array(sup, np.float64), np.array(mass, np.float64), np.array(zf, np.float64)


def _random_rows(n=240):
    """Random distributions of 1 to 4 depths (unnormalised weights), each with a receiver within a few float32 ulps
    of one of its depths, or between them: the rows where a rounding moves the bound most."""
    rng = np.random.default_rng(38)
    k = rng.integers(1, 5, n)
    sup = np.where(np.arange(4) < k[:, None], rng.uniform(-1, 1, (n, 4)), 0.0)
    mass = np.where(np.arange(4) < k[:, None], rng.uniform(0.05, 2.0, (n, 4)), 0.0)
    pick = sup[np.arange(n), rng.integers(0, k)]
    ulps = rng.integers(-4, 5, n) * np.spacing(np.abs(pick).astype(np.float32)).astype(np.float64)
    zf = np.where(rng.random(n) < 0.7, pick + ulps, rng.uniform(-1, 1, n))
    return sup, mass, np.clip(zf, -1, 1)


# Rows where the shipped float32 Cholesky errs by more than CAP below (and above) the float64 bound: its value is
# then no legitimate one (found by a search over random two-point and one-point rows; kept here as plain numbers).
_ERRING = ([[-0.8789022976393828, 0, 0, 0], [0.025824136491511718, -0.6332313249387418, 0, 0],
            [-0.750305098343387, -0.0834570779202255, 0, 0], [-0.7659147706025584, -0.8411022491289626, 0, 0]],
           [[0.54697707448205, 0, 0, 0], [0.5962321401305076, 1.6654894413910988, 0, 0],
            [1.9300070960562692, 0.1697104643694864, 0, 0], [1.420258089452696, 1.7728397097218662, 0, 0]],
           [-0.8791359700123125, -0.6330159478494031, -0.7512969822113511, -0.7678955343005982])
def _tie_rows():
    """Distributions whose moments have a float32 mantissa of 1.5 (0.75 = 1.5 · 2^-1): there b (1 ± ε) lies exactly
    half-way between two float32 numbers, and b / (1 ∓ ε) does not, so the moved inputs are exactly the recipe's."""
    dists = [([0.75], [1.0]), ([-0.375], [2.0]), ([0.75, -0.5], [1.0, 1.0]), ([-0.75, 0.25], [3.0, 1.0])]
    sup, mass, zf = [], [], []
    for z, w in dists:
        for d in z:
            for r in (d - 1e-3, d - 2e-7, d - 6e-8, d, d + 6e-8, d + 2e-7, d + 1e-3):
                sup.append(np.pad(z, (0, 4 - len(z)))), mass.append(np.pad(w, (0, 4 - len(w)))), zf.append(r)
    return np.array(sup, np.float64), np.array(mass, np.float64), np.array(zf, np.float64)


def _cluster_rows(n=300):
    """Tight clusters of 1, 2 or 4 depths (spread 1e-7 to 1) with a receiver 1e-7 to 0.1 away: unbiased, their
    moments are (nearly) singular, Φ's y2 lies within the clamp of y1 and the bound moves steeply."""
    rng = np.random.default_rng(3802)
    k = np.repeat([1, 2, 4], n // 3)
    c = rng.uniform(-1, 1, (len(k), 1))
    spread = rng.uniform(-1, 1, (len(k), 4)) * 10 ** rng.uniform(-7, 0, (len(k), 1))
    sup = np.where(np.arange(4) < k[:, None], np.clip(c + spread, -1, 1), 0.0)
    mass = np.where(np.arange(4) < k[:, None], rng.uniform(0.05, 2, (len(k), 4)), 0.0)
    zf = np.clip(c[:, 0] + rng.uniform(-1, 1, len(k)) * 10 ** rng.uniform(-7, -1, len(k)), -1, 1)
    return sup, mass, zf


ROWS = {"hand": _rows(), "ties": _tie_rows(), "clusters": _cluster_rows(), "random": _random_rows(), "erring": tuple(np.array(x, np.float64) for x in _ERRING)}
SUP, MASS, ZF = (np.concatenate([r[i] for r in ROWS.values()]) for i in range(3))
SIGN = np.array([1.0, -1.0, 1.0, -1.0])


def _ctx(before=None, inside=None, alpha=None, target=None, fmt=None, bound="lower", unit=False, clamp_test=None,
         clamp=None):
    return {"fmt": fmt, "bound": bound, "clamp": clamp, "clamp_test": clamp_test, "texel": {}, "unit": unit,
            "visibility": False, "before": before, "inside": inside, "alpha": alpha, "target": target}


def _r(x, d):
    return np.asarray(x, np.float64).astype(d).astype(np.float64)


def _f64(v):
    return np.asarray(v, np.float64)


def _bound(ctx, p, d):
    """Algorithm 1 (or the NLQ chain) biased by ``p`` in precision ``d``, as (b, zf) -> float64."""
    if ctx["fmt"] is not None:
        c = nlq_chain(ctx["fmt"], p, ctx["clamp"], ctx["clamp_test"] or "stored", {})
        return lambda b, zf: _f64(c(b.astype(d), zf.astype(d))[0])
    return lambda b, zf: _f64(shadow_intensity(b.astype(d) if p is None else bias_moments(b.astype(d), p),
                                               zf.astype(d), bound=ctx["bound"]))


def _others32(ctx, p):
    """The float32 formulations besides this package's: the papers' printed ones, or the NLQ chain with a GPU's
    log and exp (each way)."""
    if ctx["fmt"] is not None:
        cs = [nlq_chain_gpu(ctx["fmt"], p, ctx["clamp"], ctx["clamp_test"] or "stored", sign=s, texel={}) for s in (1, -1)]
        return [lambda b, zf, c=c: _f64(c(b.astype(np.float32), zf.astype(np.float32))[0]) for c in cs]
    g = (lambda b: b.astype(np.float32)) if p is None else (lambda b: bias_moments(b.astype(np.float32), p))
    return [lambda b, zf, h=h: _f64(h(g(b), zf, ctx["bound"], np.float32)) for h in (printed_bound, slides_bound)]


def _contracted32(ctx, p):
    """The float32 chain as a compiler contracts it: the bias plain, fused either way, as ``mix`` either way,
    then the shipped Cholesky with and without fma; for NLQ, every contracted stage triple."""
    if ctx["fmt"] is not None:
        cs = [nlq_chain_fused(ctx["fmt"], p, ctx["clamp"], ctx["clamp_test"] or "stored", stages=s,
                              texel={}) for s in FUSED_STAGES]
        return [lambda b, zf, c=c: _f64(c(b.astype(np.float32), zf.astype(np.float32))[0]) for c in cs]
    forms = [lambda b: b] if p is None else [
        lambda b: bias_moments(b, p), lambda b: bias_fused(b, p, False), lambda b: bias_fused(b, p, True),
        lambda b: bias_lerp(b, p, False), lambda b: bias_lerp(b, p, True)]
    return [lambda b, zf, g=g, m=m: _f64(cholesky_bound(g(b.astype(np.float32)), zf.astype(np.float32), ctx["bound"],
                                                        np.float32, fma=m)) for g in forms for m in (False, True)]


def _zf_moved(zf, d):
    """zf rounded to ``d`` and moved by 1 … K ulps of ``d`` each way."""
    out, up, down = [], zf.astype(d), zf.astype(d)
    for _ in range(K):
        up, down = np.nextafter(up, d(np.inf)), np.nextafter(down, d(-np.inf))
        out += [_f64(up), _f64(down)]
    return out


def _legit(ctx, p, d):
    u64 = engine.moments_of_rows(SUP, MASS, np.dtype(np.float64))
    u = _f64(engine.moments_of_rows(SUP, MASS, np.dtype(d)))
    eps = float(np.finfo(d).eps)
    ref, own = _bound(ctx, p, np.float64), _bound(ctx, p, d)
    others = _others32(ctx, p) if d == np.float32 else []
    out = [ref(u64, ZF), own(u, ZF)]
    out += [f(u, ZF) for f in others + (_contracted32(ctx, p) if d == np.float32 else [])]
    for s in (1.0, -1.0):
        moved = _r(u * (1 + s * eps * SIGN), d)
        out += [own(moved, ZF), ref(moved, ZF)] + [f(moved, ZF) for f in others]
    return out + [ref(u64, z) for z in _zf_moved(ZF, d)]


def _own(ctx, b, d):
    """This package's pipeline with the port's own bias inside (if any) on the port's input rounded to ``d``."""
    inside = ctx["inside"]
    f, ref = _bound(ctx, inside, d), _bound(ctx, inside, np.float64)
    eps = float(np.finfo(d).eps)
    b = _r(b, d)
    out = [ref(b, z) for z in _zf_moved(ZF, d)]
    for x in (b, _r(b * (1 + eps * SIGN), d), _r(b * (1 - eps * SIGN), d)):
        out += [f(x, ZF), ref(x, ZF)]
    for k in range(1, K + 1):
        for s in (1, -1):
            out.append(ref(_r(b * (1 + s * k * eps), d), _r(ZF * (1 + s * k * eps), d)))
    if d == np.float32 and ctx["fmt"] is None:  # the shipped ports' Cholesky on the port's own input
        b32 = b.astype(np.float32) if inside is None else bias_moments(b.astype(np.float32), inside)
        exact = ref(b, ZF)
        for m in (False, True):
            v = _f64(cholesky_bound(b32, ZF.astype(np.float32), ctx["bound"], np.float32, fma=m))
            out.append(np.where(np.abs(v - exact) <= CAP, v, np.nan))
    return out


def _across(d):
    r = (K * np.spacing(np.abs(ZF).astype(d)).astype(np.float64))[:, None]
    near = ((MASS > 0) & (SUP >= ZF[:, None] - r) & (SUP <= ZF[:, None] + r)).any(1)
    below = (MASS * (SUP < ZF[:, None] - r)).sum(1) / MASS.sum(1)
    upto = (MASS * (SUP <= ZF[:, None] + r)).sum(1) / MASS.sum(1)
    return [np.where(near, below, np.nan), np.where(near, upto, np.nan)]


def _expected(ctx, b, legit, own_legit):
    values = {"float64": []}
    for d in (np.float64, np.float32):
        v = list(values["float64"]) if d == np.float32 else []
        for p in legit:
            v += _legit(ctx, p, d)
        if own_legit:
            v += _own(ctx, b, d)
        values[np.dtype(d).name] = v + _across(d)
    out = {}
    for d, v in values.items():
        with np.errstate(all="ignore"):
            lo, hi = np.nanmin(np.array(v), axis=0), np.nanmax(np.array(v), axis=0)
        out[d] = (lo, hi)
    return out


def _check(ctx, b, legit, own_legit):
    with np.errstate(all="ignore"):
        got = engine.engine_interval(ctx, {"support": SUP, "mass": MASS, "zf": ZF}, b)
        want = _expected(ctx, b, legit, own_legit)
    for d in ("float32", "float64"):
        for end in (0, 1):
            g, w = got[d][end], want[d][end]
            bad = ~((g == w) | (np.isnan(g) & np.isnan(w)))
            assert not bad.any(), (d, "lo" if end == 0 else "hi", np.flatnonzero(bad)[:5], g[bad][:3], w[bad][:3])


def _port_input(before, dt=np.float32):  # the harness's b: float32 unless a float64 port
    return engine.moments_of_rows(SUP, MASS, np.dtype(dt), bias=before)


def _preset(alpha, target):
    return BiasPreset(alpha, tuple(target), "t")


@pytest.mark.parametrize("bound, dt", [("lower", np.float32), ("upper", np.float32), ("lower", np.float64)])
def test_undeclared_the_harness_bias_alone_and_the_ports_pipeline_on_its_input(bound, dt):
    ctx = _ctx(before=BIAS_FLOAT32, bound=bound)
    _check(ctx, _port_input(BIAS_FLOAT32, dt), [BIAS_FLOAT32], True)


@pytest.mark.parametrize("fmt, clamp, clamp_test", [("64", None, None), ("32", None, None), ("64", 1 / 65535, "clamped")])
def test_the_nlq_chains_interval_is_the_listed_chains_and_no_other(fmt, clamp, clamp_test):
    # the profile's clamp and clamp test ("clamped": y2 raised to y1 + clamp first, golden.variants) in every chain
    if clamp_test is None:
        ctx = _ctx(before=BIAS_FLOAT32, fmt=fmt, clamp=clamp)
        _check(ctx, _port_input(BIAS_FLOAT32), [BIAS_FLOAT32], True)
        return
    # a port that biases nothing: its own chain on the unbiased moments, where the case tests differ
    ctx = _ctx(fmt=fmt, clamp=clamp, clamp_test=clamp_test)
    legit = [BIAS_FLOAT32, BIAS_UNORM16]
    plain, clamped = (_expected(c, _port_input(None), legit, True) for c in (dict(ctx, clamp_test=None), ctx))
    assert not all(np.array_equal(plain[d][e], clamped[d][e], equal_nan=True) for d in plain for e in (0, 1))
    _check(ctx, _port_input(None), legit, True)


def test_a_declared_interior_bias_inside_is_the_one_legitimate_bias():
    p = _preset(1e-4, INTERIOR)
    ctx = _ctx(inside=p, alpha=1e-4, target=INTERIOR)
    _check(ctx, _port_input(None), [p], True)


def test_a_declared_bias_applied_before_the_call():
    p = _preset(1e-4, INTERIOR)
    ctx = _ctx(before=p, alpha=1e-4, target=INTERIOR)
    _check(ctx, _port_input(p), [p], True)


@pytest.mark.parametrize("dt", [np.float32, np.float64])
def test_no_bias_at_all_admits_both_presets_and_the_unbiased_pipeline(dt):
    _check(_ctx(), _port_input(None, dt), [BIAS_FLOAT32, BIAS_UNORM16], True)


def test_an_own_bias_equal_to_one_of_several_legitimate_ones_is_legitimate():
    _check(_ctx(inside=BIAS_UNORM16), _port_input(None), [BIAS_FLOAT32, BIAS_UNORM16], True)


@pytest.mark.parametrize("unit", [False, True])
def test_a_singular_declared_target_is_replaced_by_the_interior_ones_and_its_pipeline_is_no_value(unit):
    alpha = 3e-5
    targets = [moments_affine(np.array(t), 0.5, 0.5) if unit else np.array(t) for t in PAPERS]
    legit = [_preset(alpha, [float(x) for x in t]) for t in targets]
    ctx = _ctx(inside=_preset(alpha, SINGULAR), alpha=alpha, target=SINGULAR, unit=unit)
    _check(ctx, _port_input(None), legit, False)


def test_a_singular_bias_before_the_call_is_no_legitimate_pipeline():
    alpha = 3e-5
    ctx = _ctx(before=_preset(alpha, SINGULAR), alpha=alpha, target=SINGULAR)
    _check(ctx, _port_input(_preset(alpha, SINGULAR)), [_preset(alpha, t) for t in PAPERS], False)


@pytest.mark.parametrize("rel, same", [(0.7e-12, True), (1.5e-12, False), (1e-9, False)])
def test_a_declared_bias_is_the_legitimate_one_only_within_a_relative_1e_12(rel, same):
    p = _preset(1e-4, INTERIOR)
    own = _preset(1e-4 * (1 + rel), INTERIOR)
    _check(_ctx(inside=own, alpha=1e-4, target=INTERIOR), _port_input(None), [p], same)


@pytest.mark.parametrize("k, off, same", [(1, 1.5e-12, False), (1, 0.7e-12, True), (0, 1.5e-15, False),
                                          (0, 0.7e-15, True)])
def test_a_declared_target_is_the_legitimate_one_only_within_1e_12_relative_and_1e_15_absolute(k, off, same):
    target = (0.0, 0.375, 0.0, 0.375)
    p = _preset(1e-4, target)
    moved = list(target)
    moved[k] = target[k] * (1 + off) if target[k] else off
    _check(_ctx(inside=_preset(1e-4, moved), alpha=1e-4, target=target), _port_input(None), [p], same)


def test_an_own_bias_toward_the_same_target_with_another_alpha_is_not_legitimate():
    p = _preset(1e-4, INTERIOR)
    _check(_ctx(inside=_preset(2e-4, INTERIOR), alpha=1e-4, target=INTERIOR), _port_input(None), [p], False)


def test_each_rows_comment_gives_the_distributions_exact_z():
    # derive_engine's comment: Z(z < zf) (lower) of the row's distribution, the fraction of its mass (weights not
    # normalised here) strictly in front of zf in float64; the second row's depth lies between float32(zf) and zf
    from moments_ref.golden.cases import CASES

    x = float(np.float32(0.3))
    sup = np.array([[-0.5, 0.2, 0.6], [x + 1e-13, -0.9, 0.9], [0.1, 0.1 + 1e-12, 0.8]])
    mass = np.array([[1.0, 2.0, 1.0], [3.0, 1.0, 1.0], [1.0, 1.0, 2.0]])
    zf = np.array([0.3, x + 2e-13, 0.1 + 1e-12])
    want = [3 / 4, 4 / 5, 1 / 4]
    out = engine.derive_engine(CASES["engine-lower-float32"], {"support": sup, "mass": mass, "zf": zf},
                               ["random"] * 3, ["r"] * 3, [()] * 3)
    got = [float(str(c).rsplit("= ", 1)[1]) for c in out["comment"]]
    assert got == pytest.approx(want, rel=1e-8), got


@pytest.mark.parametrize("mid, test", [
    # the port's own input moved by 2 ulps instead of one
    ("_own_values::1.0 -> 2.0#0", lambda: test_a_declared_interior_bias_inside_is_the_one_legitimate_bias()),
    # the unbiased moments' sign pattern paired (+, +, −, −)
    ("_legit_values::np.arange(4) % 2 -> np.arange(4) // 2#0",
     lambda: test_undeclared_the_harness_bias_alone_and_the_ports_pipeline_on_its_input("lower", np.float32)),
    # a declared bias matched within 2e-12 instead of 1e-12
    ("_same_bias::1e-12 -> 2e-12#0", lambda: test_a_declared_bias_is_the_legitimate_one_only_within_a_relative_1e_12(
        1.5e-12, False)),
    # the NLQ chain's GPU log and exp one way only
    ("_chain::-1 -> 1#0", lambda: test_the_nlq_chains_interval_is_the_listed_chains_and_no_other("64", None, None)),
])
def test_kept_mutants_of_the_interval_are_seen(mid, test):
    from _mutants import kept_mutant

    with kept_mutant("moments_ref/golden/engine.py", mid):
        with pytest.raises(AssertionError):
            test()
