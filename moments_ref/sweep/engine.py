"""The engine cases in the sweep: depth distributions drawn per chunk, judged by the engine cases' own derivation.

An ``engine-*`` case (:mod:`moments_ref.golden.engine`) starts from a depth distribution
(support points z_i and masses w_i) and a receiver zf, in the engine's depth convention. The
sweep draws the distributions as it draws every texel (:func:`.samplers.draw_texels`: the
depths and weights, in the papers' frame [−1, 1]) and

* converts them to the engine's frame as the golden rows are converted: z ↦ (z + 1)/2 under a
  ``[0,1]`` depth profile (:func:`moments_ref.scene.depth.z_unit_from_ndc`, exact in float64),
  the receiver rounded once to the case's dtype;
* hands the port b = Σ w_i (z_i, z_i², z_i³, z_i⁴) / Σ w_i rounded once to float32, biased by
  the harness first (b − α (b − b*), exactly) where the case's context says the bias comes
  "before" the call (the default, BIAS_FLOAT32), unbiased where the profile puts it inside
  the port (:func:`moments_ref.golden.engine.moments_of_rows`, the helper the derivation uses;
  :func:`interval` checks the two agree bit for bit);
* judges each row by :func:`moments_ref.golden.engine.derive_engine` itself (one model): its
  expected value and per-row tolerance, read in one place (:func:`band`); rows it flags
  ``wide_spread`` are ill-conditioned, reported apart and never wrong.

:func:`confirm` decides a flagged row with mpmath: the port's output is wrong only where it lies
outside [min, max] of the exact values of its pipeline under every legitimate bias
(:func:`moments_ref.golden.engine.legit_biases`, applied to the distribution's moments) and on the
port's own input (its bias inside applied, if declared) over its float32 neighbourhood (b and zf
scaled jointly by 1 ± k ulps, k = 0 … 3), widened by the band model's margin floor (8 float32 ulps of 1).
The exact values are, per case:

* ``engine-lower``/``engine-upper``: the exact bounds (:func:`moments_ref.precise.shadow_bounds`,
  HPG17 Algorithm 1; Slides, "Bias the moments");
* ``engine-nlq64``/``engine-nlq32``: the exact NLQ chain (:func:`moments_ref.golden.truth.nlq_chain`:
  Φ of the exact moments, the texel's codes decided on the exact Φ, both codes where Φ lies within
  the goldens' tie band of a code boundary (2⁻¹⁸ of the code range,
  :data:`moments_ref.golden.truth.CHAIN_TIE`), the exact decode and HPG17 Algorithm 3 with its
  §3.4 clamps, under the profile's clamp and texel choices), and this package's own chain in
  float32 and float64 on the port's input (legitimate evaluations).

References
----------
.. [1] HPG17: Christoph Peters. 2017. *Non-Linearly Quantized Moment Shadow Maps*. In Proceedings
       of High Performance Graphics (HPG '17). ACM. The non-linear quantization Φ, Ψ4, Algorithms
       1–3, the texel formats and the compute shader of §4.1.
.. [2] Slides: Christoph Peters. *Rendering antialiased shadows with moment shadow mapping*,
       lecture slides (PDF version, with notes) on moment shadow mapping, translucent occluders,
       moment soft shadow mapping and prefiltered single scattering; http://MomentsInGraphics.de/.
       Cited by slide title, e.g. Slides, "Bias the moments".
"""

from __future__ import annotations

import numpy as np

from .. import precise
from ..golden.engine import (CAP, engine_band, engine_reference, legit_biases, moments_of_rows, own_bias_is_legitimate,
                             port_input_evaluations)

__all__ = ["is_engine", "engine_inputs", "band", "interval", "exact_span", "confirm", "printed_values", "rounding_envelope",
           "MARGIN_ULPS", "NEIGHBOUR_ULPS"]

#: Confirmation's widening, in ulps of 1 in the port's precision (the band model's floor, golden.bands.FLOOR_ULPS).
MARGIN_ULPS = 8
#: The port's own input is scaled jointly by 1 ± k ulps, k = 1 … NEIGHBOUR_ULPS (golden.bands.PERTURB_ULPS).
NEIGHBOUR_ULPS = 3


def is_engine(case):
    """Whether ``case`` is an engine case (judged by :func:`moments_ref.golden.engine.derive_engine`)."""
    return case.name.startswith("engine-") and bool(case.engine)


def engine_inputs(case, z, w, zf):
    """The port's inputs and the distribution, in the engine's frame: ``{b, zf, support, mass}``.

    ``z``, ``w``: ``(n, K)`` depths (papers' frame) and weights (0 for padding); ``zf``: ``(n,)``.
    """
    ctx = case.engine
    dt = np.dtype(case.dtype)
    support = np.asarray(z, np.float64)
    receiver = np.asarray(zf, np.float64)
    if ctx.get("unit"):
        from ..scene.depth import z_unit_from_ndc

        support, receiver = z_unit_from_ndc(support), z_unit_from_ndc(receiver)
    mass = np.asarray(w, np.float64)
    b = moments_of_rows(support, mass, dt, bias=ctx.get("before"))
    return {"b": b, "zf": receiver.astype(dt), "support": support, "mass": mass}


def band(arrays, port_dtype):
    """``(lo, hi)`` of a derivation's rows: expected ± the per-row tolerance (the one place the band is read)."""
    e = np.asarray(arrays["intensity"], np.float64)
    t = np.asarray(arrays[f"intensity_tolerance_{port_dtype}"], np.float64)
    return e - t, e + t


def interval(case, inputs, port_dtype="float32"):
    """``(bands, ill_conditioned)`` of engine rows (``inputs`` from :func:`engine_inputs`), by ``derive_engine``'s
    band (:func:`moments_ref.golden.engine.engine_band`: its rows' ``wide_spread`` flag is the ill mask)."""
    b, mid, half, ill = engine_band(case, {k: np.asarray(v) for k, v in inputs.items()})
    if not np.array_equal(b.view(np.uint32 if case.dtype == "float32" else np.uint64),
                          np.asarray(inputs["b"]).view(np.uint32 if case.dtype == "float32" else np.uint64)):
        raise RuntimeError(f"{case.name}: the sweep's port input b differs from derive_engine's")
    dt = str(np.dtype(port_dtype))  # derive_engine's arrays, less the rows' texts, read by the one band function
    arrays = {"intensity": 1 - mid if case.engine.get("visibility") else mid, f"intensity_tolerance_{dt}": half[dt]}
    return {"intensity": band(arrays, dt)}, np.asarray(ill, bool)


def _exact(ctx, b, zf):
    """``(lo, hi)`` of the exact intensities of the pipeline on moments ``b`` (float64, biased as given)."""
    if ctx.get("fmt") is None:
        lower, upper = precise.shadow_bounds(np.asarray(b, np.float64), np.asarray(zf, np.float64))
        v = lower if ctx.get("bound", "lower") == "lower" else upper
        return v, v
    from ..golden.truth import CHAIN_TIE, nlq_chain

    return nlq_chain(b, zf, ctx["fmt"], None, ctx.get("clamp"), ctx.get("clamp_test") or "stored", ctx.get("texel"),
                     tie=CHAIN_TIE)


def exact_span(case, inputs, port_dtype=None):
    """``(lo, hi)`` per row: the least and largest exact value over the legitimate biases and the port's input's
    float32 neighbourhood (module docstring), as the port reports it (intensity or visibility); for the NLQ chains
    also this package's chain in float32 and float64 on the port's input; for a float32 port (``port_dtype``,
    default the case's dtype) of Algorithm 1 also the shipped ports' float32 evaluations, as the goldens' engine
    interval takes them for a float32 port only (:func:`moments_ref.golden.engine.engine_interval`)."""
    ctx = case.engine
    sup, mass = np.asarray(inputs["support"], np.float64), np.asarray(inputs["mass"], np.float64)
    zf = np.asarray(inputs["zf"], np.float64)
    legit = legit_biases(ctx)
    values = [v for p in legit for v in _exact(ctx, moments_of_rows(sup, mass, np.dtype(np.float64), bias=p), zf)]
    b = np.asarray(inputs["b"])
    eps = float(np.finfo(b.dtype).eps)
    # the port's input under its own bias inside; under the legitimate ones instead where its own is not (a singular
    # target), as the band takes the port's own pipeline only where its bias is legitimate (derive_engine)
    own = own_bias_is_legitimate(ctx)
    inside = ctx.get("inside")
    biases = [inside] if inside is None or own else legit
    for f in [1.0] + [1 + s * k * eps for k in range(1, NEIGHBOUR_ULPS + 1) for s in (1, -1)]:
        bk = (b.astype(np.float64) * f).astype(b.dtype).astype(np.float64)
        zk = (zf * f).astype(b.dtype).astype(np.float64)
        for p in biases:
            values.extend(_exact(ctx, bk if p is None else precise.bias_moments(bk, p), zk))
    v = np.stack(values)
    lo, hi = v.min(axis=0), v.max(axis=0)
    if ctx.get("visibility"):
        lo, hi = 1 - hi, 1 - lo
    if ctx.get("fmt") is not None and own:  # legitimate float evaluations, already in the port's output convention
        ref = engine_reference(ctx)
        own = [np.asarray(ref(b.astype(d), np.asarray(inputs["zf"]).astype(d))[0], np.float64)
               for d in (b.dtype, np.float64)]
        lo, hi = np.minimum.reduce([lo] + own), np.maximum.reduce([hi] + own)
    # the shipped ports' float32 evaluation on the port's input, as the goldens' confirm takes the legitimate
    # evaluations (within the cap of the exact value: golden.engine.port_input_evaluations)
    float32_port = np.dtype(case.dtype if port_dtype is None else port_dtype) == np.float32
    for v in port_input_evaluations(ctx, b, inputs["zf"]) if float32_port and own else ():
        v = 1 - v if ctx.get("visibility") else v
        lo, hi = np.fmin(lo, v), np.fmax(hi, v)
    return lo, hi


def confirm(case, inputs, got, port_dtype="float32"):
    """``(n,)`` bool: flagged engine rows mpmath confirms wrong (module docstring)."""
    n = len(inputs["zf"])
    if n == 0:
        return np.zeros(n, bool)
    lo, hi = exact_span(case, inputs, port_dtype)
    m = MARGIN_ULPS * float(np.finfo(np.dtype(port_dtype)).eps)
    g = np.asarray(got["intensity"], np.float64).reshape(n)
    with np.errstate(invalid="ignore"):
        return ~((g >= lo - m) & (g <= hi + m))


def printed_values(case, inputs):
    """The papers' printed Algorithm 1 (the slides' code, Algorithm 1 as printed) in float32 on the port's own
    input, after its bias inside if declared, as the port reports it (intensity or visibility): a list of
    ``(n,)`` float64 arrays, NaN where the formulation has no value; uncapped, for the hazard diagnosis
    (:func:`moments_ref.sweep.judge.printed_rows`). Empty for the NLQ chains (their printed Algorithm 3 runs
    behind decoding, which the chain's stages cover)."""
    from ..golden.paper import alg1_paper_spread
    from ..moments import bias_moments

    ctx = case.engine
    if ctx.get("fmt") is not None or not own_bias_is_legitimate(ctx):  # a singular target: its own cause
        return []
    b = np.asarray(inputs["b"]).astype(np.float32)
    if ctx.get("inside") is not None:
        b = bias_moments(b, ctx["inside"])
    printed = alg1_paper_spread(ctx.get("bound", "lower")).printed  # the moment cases' list of printed formulations
    values = [np.asarray(v[0], np.float64) for v in printed({"b": b, "zf": inputs["zf"]}, np.dtype(np.float32))]
    return [1 - v for v in values] if ctx.get("visibility") else values


def rounding_envelope(case, inputs):
    """``(lo, hi)`` of the slides' code over arrangements rounding each operation differently
    (:func:`moments_ref.golden.paper.slides_envelope`) on the port's own input and its bias inside if declared,
    each within the band's cap of this package's float64 value of that input (an arrangement that cancels
    beyond it explains nothing), as the port reports it; None for the NLQ chains and for a singular bias target."""
    from ..golden.paper import slides_envelope

    ctx = case.engine
    if ctx.get("fmt") is not None or not own_bias_is_legitimate(ctx):
        return None
    inside = ctx.get("inside")
    bias = None if inside is None else (inside.alpha, inside.target)
    b, zf = np.asarray(inputs["b"]), np.asarray(inputs["zf"])
    ref = np.asarray(engine_reference(ctx)(b.astype(np.float64), zf.astype(np.float64))[0], np.float64)
    if ctx.get("visibility"):  # engine_reference reports as the port does; the slides' code gives intensities
        ref = 1 - ref
    lo, hi = slides_envelope(b, zf, ctx.get("bound", "lower"), bias, ref=ref, cap=CAP)
    return (1 - hi, 1 - lo) if ctx.get("visibility") else (lo, hi)
