"""Engine cases: the engine's own pipeline in the loop, from depth distributions to a shadow intensity.

The moment cases feed Algorithm 1 the moments the papers define; they cannot see
what an engine's bias does. The ``engine-*`` cases start from depth distributions:

* one depth (at and between the planes); two depths, the near and far planes among
  them; near- and far-plane mixtures (the moments of w δ_near + (1 − w) δ_far, which a
  bias toward a two-point target keeps singular); tight clusters; three occluders
  over a receiver (HPG17 Figure 9); and 9×9 Gaussian footprints of 4× MSAA samples
  from the shipped scenes' shadow maps (HPG17 §4.1's filter);
* the harness computes the unbiased moments of each distribution in the engine's
  depth convention (exactly, rounded once); the port applies its own bias as its
  profile declares (inside, or the harness before the call), then its bound
  (``engine-lower``, ``engine-upper``: Algorithm 1) or its NLQ chain
  (``engine-nlq64``, ``engine-nlq32``: the bias precedes Φ, HPG17 §3.2);
* the **band** of a row is the interval of the values a correct engine may return
  (issue 37): ``[lo − m, hi + m]`` with ``lo``, ``hi`` the least and largest of

  - the bound of the moments biased by each **legitimate bias** (:func:`legit_biases`:
    the declared α and target where the target lies strictly inside the moment space,
    the port says what it does; the declared α toward each of :data:`LEGIT_TARGETS`
    where the declared target is singular; undeclared, the default bias the harness
    applies), in float64; in float32 by this package, the papers' printed
    formulations and the chain as a SPIR-V/GLSL compiler contracts it (the bias as
    ``(1 − α) b + α b*`` or ``b + α (b* − b)`` (``mix``/``lerp``), either product fused
    or none, then the shipped ports' Cholesky evaluation with and without fma; the NLQ
    chain's stages contracted as in :mod:`moments_ref.golden.gpuspread`);
  - the same on the port's input rounding: the unbiased moments moved by one ulp per
    component (alternating signs), in the port's precision and in float64 (the exact
    value over the neighbourhood), and over zf's neighbourhood (:data:`NEIGHBOUR_ULPS`
    ulps each way, float64);
  - this package's pipeline as the port runs it on the port's own input (and on it moved
    by one ulp; in float64 on b and zf scaled jointly by 1 ± 1–3 ulps, the points the sweep's
    confirmation values exactly, so that one neighbourhood decides the band, the ill rows and
    the confirmation), where the port's own bias is legitimate (a singular one is not: it is
    judged by its outputs, :func:`singular_target_rows` says which rows it explains);
  - where zf lies within rounding of a depth of the distribution (flag ``support_point``,
    and receivers between two depths one float32 ulp apart), Z just below and at that
    depth: the biased canonical representation has a support point within rounding of
    zf, and a correct float32 evaluation lands anywhere across the jump of Z;

  and ``m`` the band model's margin (:mod:`moments_ref.golden.bands`): max(3 × (hi − lo),
  4 × the case's rounding noise (:func:`case_noise`: the median width over its random
  golden rows that are not ill-conditioned, a constant per case), 8 ulps of 1 in the
  port's precision), the band reaching no farther
  than ``CAP`` (0.02) from its midpoint. NaN evaluations are no values;
* the expected value (column ``intensity``) is the band's **midpoint** (for the float32
  port; for visibility 1 − it), the tolerance ``intensity_tolerance_<dtype>`` its
  half-width about that midpoint, rounded up to two digits: not the exact Z of the
  distribution, which a correct biased MSM does not return (each row's comment gives Z);
* a row whose legitimate values spread wider than ``CAP`` is **ill-conditioned**: flagged
  ``wide_spread`` (the flag and report section of :mod:`moments_ref.golden.bands`), its
  band the whole interval widened by ``CAP``, judged by that band (a correct port never
  fails it), never counted as a pass of the port.

Verdicts come from outputs: a bias toward a singular target fails exactly where its
outputs leave that band (:func:`singular_target_rows` says which rows the target
explains, for the report).

References
----------
.. [1] HPG17: Christoph Peters. 2017. *Non-Linearly Quantized Moment Shadow Maps*. In Proceedings
       of High Performance Graphics (HPG '17). ACM. The non-linear quantization Φ, Ψ4, Algorithms
       1–3, the texel formats and the compute shader of §4.1.
.. [2] Peters and Klein 2015: Christoph Peters and Reinhard Klein. 2015. *Moment Shadow Mapping*.
       In Proceedings of the 19th ACM SIGGRAPH Symposium on Interactive 3D Graphics and Games (i3D
       '15). ACM, 7–14. https://doi.org/10.1145/2699276.2699277
"""

from __future__ import annotations

import numpy as np

from ..moments import BIAS_FLOAT32, BIAS_UNORM16, BiasPreset
from ._ddmoments import moments_of_rows
from ._rows import Rows
from .contract import PD_MIN, hankel_above

__all__ = ["engine_specs", "LEGIT_TARGETS", "derive_engine", "engine_band", "singular_target_rows", "target_support", "moments_of_rows",
           "legit_biases", "papers_chain32", "engine_interval", "case_noise", "port_input_evaluations", "CAP",
           "NEIGHBOUR_ULPS", "own_bias_is_legitimate"]

#: Targets strictly inside the moment space (papers' frame): the presets' and the uniform distribution's.
LEGIT_TARGETS = ((0.0, 0.375, 0.0, 0.375), (0.0, 0.628, 0.0, 0.628), (0.0, 1 / 3, 0.0, 0.2),
                 (0.1, 0.4, 0.05, 0.3))
#: The band model's cap (moments_ref.golden.bands.CAP, a test keeps the two equal): no band of an intensity reaches
#: farther than this from its midpoint; a row whose legitimate values spread wider is ill-conditioned.
CAP = 0.02
#: The receiver's neighbourhood: zf moved by up to this many ulps of the port's precision each way (at a depth of
#: the distribution the biased bound moves steeply).
NEIGHBOUR_ULPS = 3
# The band model's margin, max(3 × the width of the evaluations, 8 ulps): moments_ref.golden.bands' MARGIN_WIDTH and
# FLOOR_ULPS (bands imports the case table, which imports this module; a test keeps the two equal).
_MARGIN_WIDTH, _FLOOR_ULPS, _MARGIN_NOISE = 3.0, 8, 4.0
_SCENES = ("railing", "three-occluders", "chair")


def _points(depths, weights):
    return np.asarray(depths, np.float64), np.asarray(weights, np.float64) / np.sum(weights)


def _synthetic():
    """(depths, weights, category, comment, flags) of the hand-made distributions (papers' frame)."""
    out = []
    for d in (-1.0, -0.5, 0.0, 0.3, 1.0):
        out.append(([d], [1.0], "edge", f"one depth {d}", ()))
    for w in (0.25, 1 / 3, 0.5, 2 / 3, 0.75, 0.9):
        out.append(([-1.0, 1.0], [w, 1 - w], "stiff", f"near plane (w = {w:.3g}) and far plane", ("near_far",)))
    for zs, ws in (([-1.0, 0.2, 1.0], [0.3, 0.3, 0.4]), ([-1.0, -0.999, 1.0], [0.5, 0.2, 0.3])):
        out.append((zs, ws, "stiff", f"near and far plane mixed with {zs[1]}", ("near_far",)))
    for zs in ((-0.8, 0.4), (-0.5, 0.5), (0.2, 1.0), (-1.0, 0.6)):
        out.append((list(zs), [0.6, 0.4], "random", f"two depths {zs}", ()))
    for c, s in ((0.3, 1e-4), (-0.6, 1e-3), (0.95, 1e-4)):
        out.append(([c - s, c, c + s / 2, c + s], [0.2, 0.3, 0.3, 0.2], "stiff", f"tight cluster of 4 depths within "
                    f"{s:g} of {c}", ("cluster",)))
    out.append(([-0.6, -0.2, 0.3, 1.0], [0.25, 0.25, 0.25, 0.25], "stiff",
                "three occluders (umbrella, roof, railing) and the far plane (HPG17 Figure 9)", ()))
    out.append(([-0.6, -0.2, 0.3], [0.3, 0.3, 0.4], "stiff", "three occluders (HPG17 Figure 9)", ()))
    return out


def _footprints(rng, per_scene=6, size=96):
    """9×9 Gaussian footprints of 4× MSAA depths from the shipped scenes (HPG17 §4.1)."""
    from ..gpu.filtering import SIGMA, TAPS, gaussian_weights
    from ..scene.files import load_scene

    g = gaussian_weights(TAPS, SIGMA)
    w = (g[:, None] * g[None, :])[..., None] * np.full(4, 0.25)
    h = TAPS // 2
    out = []
    for name in _SCENES:
        depth, _ = load_scene(name).shadow_map(size=size, samples=4)
        d = depth.astype(np.float64)
        pad = np.pad(d, ((h, h), (h, h), (0, 0)), mode="edge")
        # Footprints where occluders and receivers (or the far plane) mix: a depth range of at least 0.05.
        span = np.array([[np.ptp(pad[i:i + TAPS, j:j + TAPS]) for j in range(0, size, 4)] for i in range(0, size, 4)])
        cand = np.argwhere(span > 0.05) * 4
        for i, j in cand[rng.choice(len(cand), min(per_scene, len(cand)), replace=False)]:
            out.append((pad[i:i + TAPS, j:j + TAPS].reshape(-1), w.reshape(-1), "random",
                        f"{name}: 9x9 footprint of 4x MSAA samples at texel ({i}, {j})", ("footprint",)))
    return out


def _receivers(z, rng):
    """Fragment depths for one distribution: between its distinct depths, before and after them."""
    u = np.unique(z)
    zf = list(0.5 * (u[:-1] + u[1:])[:4]) + [max(-1.0, u[0] - 0.05), min(1.0, u[-1] + 0.05)]
    if len(u) > 5:
        zf += list(rng.uniform(max(-1.0, u[0] - 0.02), min(1.0, u[-1] + 0.02), 2))
    return np.unique(np.asarray(zf, np.float64))


def _engine_rows(rng, dtype):
    rng = np.random.default_rng(20170723)  # the same distributions in every engine case (HPG17's year and month)
    dists = _synthetic() + _footprints(rng)
    k = max(len(z) for z, *_ in dists)
    zf, cat, com, flags, sup, mass = [], [], [], [], [], []
    for z, w, c, what, fl in dists:
        z, w = _points(z, w)
        for x in _receivers(z, rng):
            zf.append(x), cat.append(c), com.append(f"{what}; zf = {x:.9g}")
            flags.append(fl + (("support_point",) if np.any(z == x) else ()))
            # One row per distribution, padded with points of mass 0 (they change no moment and no Z).
            sup.append(np.pad(z, (0, k - len(z)))), mass.append(np.pad(w, (0, k - len(w))))
    support, mass = np.array(sup), np.array(mass)
    b = moments_of_rows(support, mass, np.dtype(dtype))  # rounded once
    inputs = {"b": b.astype(np.float64), "zf": np.array(zf), "support": support, "mass": mass}
    return Rows(inputs, cat, com, flags)


# ---------------------------------------------------------------------------
# Expected values and tolerances


def _preset(alpha, target, unit):
    from ..scene.depth import moments_affine

    t = np.asarray(target, np.float64)
    if unit:
        t = moments_affine(t, 0.5, 0.5)
    return BiasPreset(float(alpha), tuple(float(x) for x in t), "legit")


def legit_biases(ctx):
    """The legitimate biases of a correct engine (engine frame).

    The declared α and target where the target lies strictly inside the moment space (the port says what it
    does); the declared α toward each of :data:`LEGIT_TARGETS` where the declared target is singular (such a port
    is judged by its outputs: :func:`singular_target_rows`); undeclared, the case's default bias that the harness
    applies before the call (``BIAS_FLOAT32``); with no bias at all (``bias = "none"``), the papers' presets
    ``BIAS_FLOAT32`` and ``BIAS_UNORM16``.
    """
    alpha, target, unit = ctx.get("alpha"), ctx.get("target"), ctx.get("unit", False)
    if alpha and target is not None and len(target) == 4 and target_support(target) is None:
        return [BiasPreset(float(alpha), tuple(float(x) for x in target), "declared")]
    if alpha:
        return [_preset(alpha, t, unit) for t in LEGIT_TARGETS]
    if ctx.get("before") is not None:
        before = ctx["before"]
        return [BiasPreset(float(before.alpha), tuple(float(x) for x in before.target), "default")]
    return [_preset(p.alpha, p.target, unit) for p in (BIAS_FLOAT32, BIAS_UNORM16)]


def _chain(ctx, preset, dt):
    """The legitimate pipeline with ``preset``: Algorithm 1 (and the slides' code) or the NLQ chain."""
    from ..moments import bias_moments
    from ..msm import shadow_intensity
    from .paper import printed_bound, slides_bound

    fmt, bound = ctx.get("fmt"), ctx.get("bound", "lower")
    if fmt is not None:
        from .endtoend import nlq_chain

        from .gpuspread import nlq_chain_gpu

        args = (fmt, preset, ctx.get("clamp"), ctx.get("clamp_test") or "stored")
        texel = ctx.get("texel")
        chains = [nlq_chain(*args, texel)] + ([nlq_chain_gpu(*args, sign=s, texel=texel) for s in (1, -1)]
                                              if dt == np.float32 else [])
        return [lambda b, zf, c=c: c(b.astype(dt), zf.astype(dt))[0] for c in chains]

    def biased(b):
        return b.astype(dt) if preset is None else bias_moments(b.astype(dt), preset)

    out = [lambda b, zf: shadow_intensity(biased(b), zf.astype(dt), bound=bound)]
    if dt == np.float32:
        out.append(lambda b, zf: printed_bound(biased(b), zf, bound, dt))
        out.append(lambda b, zf: slides_bound(biased(b), zf, bound, dt))
    return out


def _contracted(ctx, preset):
    """The float32 pipeline with ``preset`` as a SPIR-V/GLSL compiler may contract and reassociate it: the bias as
    ``(1 − α) b + α b*`` or ``b + α (b* − b)`` (``mix``/``lerp``), either product fused or none
    (:mod:`moments_ref.gpu.fused32`), then Algorithm 1 by the shipped ports' Cholesky evaluation with and without
    fma (:func:`moments_ref.golden.paper.cholesky_bound`); the NLQ chain with its stages contracted
    (:data:`moments_ref.golden.gpuspread.FUSED_STAGES`)."""
    from .gpuspread import FUSED_STAGES, nlq_chain_fused

    fmt, bound = ctx.get("fmt"), ctx.get("bound", "lower")
    if fmt is not None:
        args = (fmt, preset, ctx.get("clamp"), ctx.get("clamp_test") or "stored")
        chains = [nlq_chain_fused(*args, stages=s, texel=ctx.get("texel")) for s in FUSED_STAGES]
        return [lambda b, zf, c=c: c(b.astype(np.float32), zf.astype(np.float32))[0] for c in chains]
    from ..gpu.fused32 import bias_fused, bias_lerp
    from ..moments import bias_moments
    from .paper import cholesky_bound

    forms = [lambda b: b] if preset is None else [lambda b: bias_moments(b, preset)] + [
        lambda b, s=s: bias_fused(b, preset, s) for s in (False, True)] + [
        lambda b, f=f: bias_lerp(b, preset, f) for f in (False, True)]
    return [lambda b, zf, g=g, m=m: cholesky_bound(g(b.astype(np.float32)), zf.astype(np.float32), bound, np.float32,
                                                     fma=m) for g in forms for m in (False, True)]


def papers_chain32(arrays, preset, ctx, n):
    """The papers' own formulation (last of :func:`_chain`) in float32 with ``preset``, on the rows'
    unbiased moments: for the diagnosis of a bias target."""
    b = moments_of_rows(arrays["support"], arrays["mass"], np.dtype(np.float32)).astype(np.float64)
    with np.errstate(all="ignore"):
        return np.asarray(_chain(ctx, preset, np.float32)[-1](b, np.asarray(arrays["zf"], np.float64)), np.float64)


def _same_bias(p, q):
    if p is None or q is None:
        return p is q
    return bool(np.isclose(p.alpha, q.alpha, rtol=1e-12, atol=0)
                and np.allclose(p.target, q.target, rtol=1e-12, atol=1e-15))


def _own_pipeline(ctx, legit):
    """The port's own bias (its caller's, or inside its function; None: it biases nothing), if legitimate."""
    own = ctx.get("before") if ctx.get("before") is not None else ctx.get("inside")
    return own is None or any(_same_bias(own, p) for p in legit)


def own_bias_is_legitimate(ctx):
    """Whether the port's own bias (its caller's or inside its function) is one of :func:`legit_biases`: a bias
    toward a singular target is not, and then nothing evaluated with it is a legitimate value."""
    return _own_pipeline(ctx, legit_biases(ctx))


def _across_depth(sup, mass, zf, dt):
    """Z below and at-or-below the receiver's float32 (``dt``) neighbourhood, NaN unless a depth of the distribution
    lies within :data:`NEIGHBOUR_ULPS` ulps of zf: there the biased canonical representation has a support point
    within rounding of zf, and a correct evaluation lands anywhere across the jump of Z."""
    from .units import ulp

    reach = (NEIGHBOUR_ULPS * ulp(zf, dt))[:, None]
    near = np.any((mass > 0) & (np.abs(sup - zf[:, None]) <= reach), axis=1)
    total = mass.sum(axis=1)
    below, upto = (mass * (sup < zf[:, None] - reach)).sum(axis=1), (mass * (sup <= zf[:, None] + reach)).sum(axis=1)
    return [np.where(near, below / total, np.nan), np.where(near, upto / total, np.nan)]


def _zf_neighbours(zf, dt):
    """zf rounded to ``dt`` and moved by 1 … :data:`NEIGHBOUR_ULPS` ulps of ``dt`` each way (float64)."""
    out, up, down = [], zf.astype(dt), zf.astype(dt)
    for _ in range(NEIGHBOUR_ULPS):
        up, down = np.nextafter(up, dt.type(np.inf)), np.nextafter(down, dt.type(-np.inf))
        out += [up.astype(np.float64), down.astype(np.float64)]
    return out


def _legit_values(ctx, p, unbiased, zf, dt):
    """The pipeline's values with the legitimate bias ``p`` for a port of precision ``dt`` (float64 arrays): the
    float64 reference; in float32 this package's, the papers' and the contracted evaluations; this package's in
    ``dt`` and in float64 on the unbiased moments moved by one ulp of ``dt`` per component (alternating signs: the
    port's input rounding); and the float64 bound over zf's neighbourhood in ``dt`` (where zf sits on a depth of
    the distribution the biased bound moves steeply)."""
    d = np.dtype(dt)
    ref = _chain(ctx, p, np.float64)[0]
    u = unbiased[d.name]
    out = [ref(unbiased["float64"], zf)]
    if d == np.float32:
        out += [f(u, zf) for f in _chain(ctx, p, np.float32)[1:] + _contracted(ctx, p)]
    sign = np.where(np.arange(4) % 2 == 0, 1.0, -1.0)
    own = _chain(ctx, p, d.type)[0]
    eps = float(np.finfo(d).eps)
    out.append(own(u, zf))
    others = _chain(ctx, p, np.float32)[1:] if d == np.float32 else []
    for s in (1, -1):
        moved = (u * (1 + s * eps * sign)).astype(d).astype(np.float64)
        out += [own(moved, zf), ref(moved, zf)] + [f(moved, zf) for f in others]
    out += [ref(unbiased["float64"], z) for z in _zf_neighbours(zf, d)]
    return [np.asarray(v, np.float64) for v in out]


def _own_values(ctx, b, zf, dt):
    """This package's pipeline as the port runs it (its bias inside, if declared) on the port's input ``b`` rounded
    to ``dt``: in ``dt`` and in float64, on b, on b moved by one ulp of ``dt`` per component (alternating signs),
    (float64) over zf's neighbourhood, and (float64, the exact value's stand-in) on b and zf scaled jointly by
    1 ± k ulps of ``dt``, k = 1 … :data:`NEIGHBOUR_ULPS`, rounded to ``dt``: the rounding of the port's own input,
    the points the sweep's confirmation values exactly (:func:`moments_ref.sweep.engine.exact_span`), so that a row
    whose exact values spread beyond :data:`CAP` over them is ill-conditioned here too."""
    d = np.dtype(dt)
    f, ref = _chain(ctx, ctx.get("inside"), d.type)[0], _chain(ctx, ctx.get("inside"), np.float64)[0]
    b64, zf = np.asarray(b, np.float64), np.asarray(zf, np.float64)
    b = b64.astype(d).astype(np.float64)
    sign = np.where(np.arange(4) % 2 == 0, 1.0, -1.0)
    eps = float(np.finfo(d).eps)
    out = [ref(b, z) for z in _zf_neighbours(zf, d)]
    for x in [b] + [(b * (1 + s * eps * sign)).astype(d).astype(np.float64) for s in (1, -1)]:
        out += [f(x, zf), ref(x, zf)]
    for k in range(1, NEIGHBOUR_ULPS + 1):
        for s in (1, -1):
            j = 1 + s * k * eps
            out.append(ref((b * j).astype(d).astype(np.float64), (zf * j).astype(d).astype(np.float64)))
    return [np.asarray(v, np.float64) for v in out]


def port_input_evaluations(ctx, b, zf):
    """The shipped ports' float32 evaluation on the port's own input: Algorithm 1 by the plain Cholesky of Peters
    and Klein 2015, Prop. 10, with and without fma (:func:`moments_ref.golden.paper.cholesky_bound`), after the
    port's bias inside if declared, on ``b`` rounded to float32 (a list of float64 arrays, NaN where the evaluation
    errs beyond :data:`CAP` from the float64 bound of that input: a cancelling formula explains nothing), as
    intensities (the interval's frame; a visibility port's band is turned afterwards). As for the
    moment cases (:mod:`moments_ref.golden.bands`: the shipped plain-Cholesky evaluation is legitimate); empty for
    the NLQ chains, whose contracted stages :func:`_contracted` covers."""
    from ..moments import bias_moments
    from .paper import cholesky_bound

    if ctx.get("fmt") is not None:
        return []
    bound, inside = ctx.get("bound", "lower"), ctx.get("inside")
    b32 = np.asarray(b).astype(np.float32)
    z32 = np.asarray(zf).astype(np.float32)
    if inside is not None:
        b32 = bias_moments(b32, inside)
    ref = np.asarray(_chain(ctx, inside, np.float64)[0](np.asarray(b).astype(np.float32).astype(np.float64),
                                                          np.asarray(zf, np.float64)), np.float64)
    out = []
    with np.errstate(all="ignore"):
        for m in (False, True):
            v = np.asarray(cholesky_bound(b32, z32, bound, np.float32, fma=m), np.float64)
            out.append(np.where(np.abs(v - ref) <= CAP, v, np.nan))
    return out


def _span(values, n):
    lo, hi = np.full(n, np.inf), np.full(n, -np.inf)
    for v in values:
        lo, hi = np.fmin(lo, v), np.fmax(hi, v)
    return lo, hi


def engine_interval(ctx, arrays, b):
    """``{port dtype: (lo, hi)}``: the least and largest legitimate value of each row (module docstring),
    before the margin; NaN where no evaluation is finite."""
    from .units import PORT_DTYPES

    sup, mass = np.asarray(arrays["support"], np.float64), np.asarray(arrays["mass"], np.float64)
    zf = np.asarray(arrays["zf"], np.float64)
    n = len(zf)
    legit = legit_biases(ctx)
    unbiased = {d: moments_of_rows(sup, mass, np.dtype(d)).astype(np.float64) for d in PORT_DTYPES}
    values = {}
    with np.errstate(all="ignore"):
        for d in ("float64", "float32"):  # a float32 port's values include the float64 port's
            values[d] = list(values.get("float64", []))
            for p in legit:
                values[d] += _legit_values(ctx, p, unbiased, zf, d)
            if _own_pipeline(ctx, legit):
                values[d] += _own_values(ctx, b, zf, d)
                if d == "float32":
                    values[d] += port_input_evaluations(ctx, b, zf)
            values[d] += _across_depth(sup, mass, zf, np.dtype(d))
    out = {}
    for d in PORT_DTYPES:
        lo, hi = _span(values[d], n)
        out[d] = (np.where(lo <= hi, lo, np.nan), np.where(lo <= hi, hi, np.nan))
    return out


def _exact_z(arrays, upper):
    s, m, zf = np.asarray(arrays["support"]), np.asarray(arrays["mass"]), np.asarray(arrays["zf"], np.float64)
    below = (s <= zf[:, None]) if upper else (s < zf[:, None])
    return (m * below).sum(axis=1) / m.sum(axis=1)


_NOISE = {}


def case_noise(ctx, dtype):
    """``{port dtype: noise}``: the rounding noise of an engine case, a constant per case (its NLQ format, bound
    and precision ``dtype``), measured once on its golden rows with its default engine: the median width of the
    legitimate interval over the random rows that are not ill-conditioned. A band never depends on the other rows
    of a call (a sweep's chunk)."""
    key = (ctx.get("fmt"), ctx.get("bound", "lower"), np.dtype(dtype).name)
    if key not in _NOISE:
        default = _default_ctx(*key[:2])
        rows = _engine_rows(None, key[2])
        arrays = {k: rows.inputs[k] for k in ("zf", "support", "mass")}
        b = moments_of_rows(arrays["support"], arrays["mass"], np.dtype(key[2]), bias=default["before"])
        intervals = engine_interval(default, arrays, b)
        lo32, hi32 = intervals["float32"]
        keep = (np.asarray(rows.category) == "random") & (hi32 - lo32 <= CAP)
        _NOISE[key] = {d: float(np.median((hi - lo)[keep])) for d, (lo, hi) in intervals.items()}
    return _NOISE[key]


def _bands(intervals, noise):
    """``(expected, {port dtype: half-width}, ill)`` from :func:`engine_interval`'s intervals and the case's
    rounding ``noise`` (:func:`case_noise`; module docstring)."""
    from .units import ceil2, ulp

    lo32, hi32 = intervals["float32"]
    n = len(lo32)
    mid = 0.5 * (lo32 + hi32)
    ill = hi32 - lo32 > CAP
    half = {}
    for d, (lo, hi) in intervals.items():
        m = np.maximum.reduce([_MARGIN_WIDTH * (hi - lo), np.full(n, _MARGIN_NOISE * noise[d]),
                               _FLOOR_ULPS * ulp(np.ones(n), d)])
        t = ceil2(np.fmax(mid - lo, hi - mid) + np.where(ill, CAP, m))
        half[d] = np.where(np.isfinite(mid), np.where(ill, t, np.minimum(t, CAP)), np.inf)
    return np.where(np.isfinite(mid), mid, 0.0), half, ill


def engine_band(case, arrays):
    """``(b, mid, half, ill)`` of engine rows: the port's input, the band's midpoint (the intensity), its
    half-width per port precision (dict) and the ill-conditioned rows; :func:`derive_engine` without the rows'
    texts (the sweep's reference, :mod:`moments_ref.sweep.engine`). ``arrays`` as there."""
    ctx = case.engine
    sup, mass = np.asarray(arrays["support"]), np.asarray(arrays["mass"])
    b = moments_of_rows(sup, mass, np.dtype(case.dtype), bias=ctx.get("before"))
    mid, half, ill = _bands(engine_interval(ctx, arrays, b), case_noise(ctx, case.dtype))
    return b, mid, half, ill


def derive_engine(case, arrays, category, comment, flags, contract=None):
    """Arrays of an engine case: the port's input b, the band's midpoint, its half-width per port precision, the
    rows' flags (``wide_spread``: ill-conditioned; module docstring).

    ``arrays`` holds the rows' ``zf`` and distributions (``support``, ``mass``: per row,
    padded with points of mass 0) in the engine's depth convention; ``case.engine`` the context (the
    bias the harness applies before the call, the declared α and target, the output).
    """
    from .units import PORT_DTYPES

    ctx = case.engine
    n = len(category)
    b, mid, half, ill = engine_band(case, arrays)
    z = _exact_z(arrays, ctx.get("bound") == "upper")
    vis = bool(ctx.get("visibility"))
    out = {"b": b, "intensity": 1 - mid if vis else mid, "tc_id": np.arange(1, n + 1, dtype=np.int32)}
    for d in PORT_DTYPES:
        out[f"intensity_tolerance_{d}"] = half[d]
    out["category"] = np.asarray(category).astype("U6")
    rel = "<=" if ctx.get("bound") == "upper" else "<"
    exact = [f"{c}; the distribution's {'1 - ' if vis else ''}Z(z {rel} zf) = {1 - x if vis else x:.9g}"
             for c, x in zip(comment, z)]
    out["comment"] = np.asarray(exact).astype(f"U{max(1, max(len(c) for c in exact))}")
    joined = [",".join(dict.fromkeys(tuple(f) + (("wide_spread",) if w else ()))) for f, w in zip(flags, ill)]
    out["flags"] = np.asarray(joined).astype(f"U{max(1, max(len(f) for f in joined))}")
    out["result"] = np.full(n, "valid", dtype="U10")
    if case.dtype == "float32":  # informational: the reference's own float32 pipeline on the port's input
        zf = np.asarray(arrays["zf"], np.float64)
        with np.errstate(all="ignore"):
            v = np.asarray(_chain(ctx, ctx.get("inside"), np.float32)[0](b.astype(np.float64), zf), np.float32)
        out["intensity_float32"] = 1 - v if vis else v
    return out


# ---------------------------------------------------------------------------
# Diagnosis: a singular bias target


def target_support(target):
    """Support points and weights of a singular target (its unique distribution), else None."""
    t = np.asarray(target, np.float64)
    lam, vec = np.linalg.eigh(np.array([[1, t[0], t[1]], [t[0], t[1], t[2]], [t[1], t[2], t[3]]]))
    if lam[0] > PD_MIN:
        return None
    if lam[1] <= PD_MIN:  # rank 1: one point
        return [(float(t[0]), 1.0)]
    c = vec[:, 0]  # the kernel: c0 + c1 z + c2 z² vanishes on the support
    pts = np.sort(np.roots(c[::-1]).real) if abs(c[2]) > 1e-12 else np.array([-c[0] / c[1]])
    if len(pts) == 1:
        return [(float(pts[0]), 1.0)]
    w2 = (t[0] - pts[0]) / (pts[1] - pts[0])
    return [(float(pts[0]), float(1 - w2)), (float(pts[1]), float(w2))]


def singular_target_rows(arrays, bias, unit=False):
    """Rows whose distribution stays singular under ``bias`` (α, target in the engine frame): a bound with
    no singular branch divides by zero there. Empty unless the target is singular."""
    if target_support(bias.target) is None:
        return np.zeros(len(arrays["zf"]), bool)
    n = len(arrays["zf"])
    b = moments_of_rows(arrays["support"], arrays["mass"], np.dtype(np.float64))
    biased = (1 - bias.alpha) * b + bias.alpha * np.asarray(bias.target, np.float64)
    return ~hankel_above(biased, PD_MIN)


# ---------------------------------------------------------------------------
# The cases


def _variant(texel, bound):
    """A profile's bias (inside or before), depth convention and output for an engine case."""

    def variant(bias=None, clamp=None, fmt=None, before=None, profile=None, clamp_test=None, **_):
        from .variants import preset_of

        declared = profile.bias if profile is not None and profile.bias is not None else None
        ctx = {"fmt": texel, "bound": bound, "clamp": clamp, "clamp_test": clamp_test, "texel": dict(fmt or {}), "unit": profile is not None and profile.depth == "[0,1]",
               "visibility": profile is not None and profile.output == "visibility",
               "before": None if before is None else preset_of(before),
               "inside": None if bias is None else preset_of(bias),
               "alpha": declared.alpha if declared is not None and declared.active else None,
               "target": tuple(declared.target) if declared is not None and declared.active else None}
        return {"engine": ctx, "reference": engine_reference(ctx)}

    return variant


def engine_reference(ctx):
    """This package as the engine's port: its bias inside (if declared), Algorithm 1 or the NLQ chain."""

    def reference(b, zf):
        dt = np.asarray(b).dtype.type
        v = np.asarray(_chain(ctx, ctx.get("inside"), dt)[0](np.asarray(b), np.asarray(zf)), dt)
        return (1 - v if ctx.get("visibility") else v,)

    return reference


def _default_ctx(fmt, bound):
    return {"fmt": fmt, "bound": bound, "clamp": None, "unit": False, "visibility": False,
            "before": BIAS_FLOAT32, "inside": None, "alpha": None}


def engine_specs(dt):
    """Keyword dicts for :class:`moments_ref.golden.cases.Case`, one per engine case."""
    common = dict(dtype=dt, inputs=("b", "zf"), outputs=("intensity",), rows=_engine_rows, truth=None,
                  value_range=(0, 1), aux=("support", "mass"), deriver=derive_engine, width=4,
                  default_bias=("before", BIAS_FLOAT32), bias_before=True)
    specs = []
    for bound in ("lower", "upper"):
        specs.append(dict(
            **common, name=f"engine-{bound}-{dt}", function="engine.shadow_intensity", kwargs={"bound": bound},
            depth_roles={"zf": "depth", "support": "depth"}, profile_keys=("bias",), variant=_variant(None, bound),
            engine=_default_ctx(None, bound), reference=engine_reference(_default_ctx(None, bound)),
            description=f"the engine's pipeline (HPG17 §3.2, Algorithm 1, {bound} bound): depth distributions -> "
                        "unbiased moments in the engine's convention -> the engine's bias (declared in its profile; "
                        "default BIAS_FLOAT32 applied before the call) -> the bound; expected: the midpoint of the "
                        "interval of correct biased bounds (the declared bias; the row's comment gives the exact "
                        f"Z(z {'<=' if bound == 'upper' else '<'} zf)), tolerance: its half-width"))
    for f in ("64", "32"):
        specs.append(dict(
            **common, name=f"engine-nlq{f}-{dt}", function=f"engine.nlq{f}", kwargs={},
            profile_keys=("bias", "clamp", "format"), variant=_variant(f, "lower"), engine=_default_ctx(f, "lower"),
            reference=engine_reference(_default_ctx(f, "lower")),
            description=f"the engine's NLQ pipeline (HPG17 §3.2, Alg. 2, §3.3/§3.5, Alg. 3): depth distributions "
                        f"-> unbiased moments -> the engine's bias -> phi -> pack{f} -> unpack{f} -> shade; expected: "
                        "the midpoint of the interval of correct biased chains (the declared bias; the row's comment "
                        "gives the exact Z(z < zf)), tolerance: its half-width"))
    return specs
