"""End-to-end golden cases: a port's whole chain, compared where a user sees it.

Texel codes are not a stable thing to compare (Φ is ill-conditioned on nearly
singular moments: two correct implementations agreeing to 2e-7 in the moments can
store different codes), so these cases compare *shadow intensities*:

* ``e2e-nlq64-*``, ``e2e-nlq32-*``: filtered moments b and a fragment depth zf ->
  ``bias_moments(b, BIAS_FLOAT32)`` -> Φ (Algorithm 2) -> pack64 / pack32 ->
  unpack -> Algorithm 3;
* ``e2e-msm64-*``: b, zf -> ``encode_unorm16`` -> ``decode_unorm16`` ->
  ``bias_moments(·, BIAS_UNORM16)`` -> Algorithm 1 (the 64-bit affine MSM);
* ``e2e-block-nlq64-*``, ``e2e-block-nlq32-*``: one row is a 40×32 block of 4×
  MSAA depth samples (``depth`` (n, 32, 40, 4), the 32×24 texels of HPG17 §4.1 with
  a guard band of 4 on each side) and ``zf`` (n, 24, 32) -> MSAA resolve of
  b(z) -> 9² Gaussian blur (σ = 2.4) -> crop the guard band -> the NLQ chain
  above, so a compute-shader port of HPG17 §4.1 is checked as a whole.

The expected value is the same chain evaluated in float64 (the golden files keep it); a
flagged row of ``e2e-nlq*`` and ``e2e-msm64`` is confirmed with the chain's mpmath twin (:func:`nlq_exact`,
:func:`msm64_exact`, the case's ``confirm_truth``: the codes of the exact values, both where one lies on a code
boundary); per-row tolerances come from the spread of the float32 chain and
of perturbed inputs (:mod:`moments_ref.golden.spread`), so a row whose code flips
between legitimate implementations carries the resulting intensity difference.

References
----------
.. [1] HPG17: Christoph Peters. 2017. *Non-Linearly Quantized Moment Shadow Maps*. In Proceedings
       of High Performance Graphics (HPG '17). ACM. The non-linear quantization Φ, Ψ4, Algorithms
       1–3, the texel formats and the compute shader of §4.1.
"""

from __future__ import annotations

import numpy as np

from ..gpu.filtering import blur, resolve_moments
from ..moments import BIAS_FLOAT32, BIAS_UNORM16, bias_moments
from ._rows import Rows, _msm_rows
from .gpuspread import block_spread, chain_spread, msm_spread

__all__ = ["case_specs", "nlq_chain", "nlq_exact", "msm64_exact", "BLOCK", "GUARD"]

#: HPG17 §4.1: a thread group filters 32×24 texels from a 40×32 block (guard band 4).
BLOCK = (32, 40)
GUARD = 4


def nlq_chain(fmt, bias=BIAS_FLOAT32, clamp=None, case_test="stored", texel=None):
    """bias (a BiasPreset or None) -> Φ -> pack -> unpack -> shade (``clamp``, ``case_test``: golden.variants;
    ``texel``: the profile's texel-format choices, golden.variants.decode32 and rounding64)."""

    def chain(b, zf):
        from ..nonlinear import SHADE_TOLERANCE, phi
        from ..packing import pack32, pack64, unpack32, unpack64
        from .variants import decode32, rounding64, shade_reference

        dt = np.asarray(b).dtype
        r = phi(b if bias is None else bias_moments(b, bias))
        if fmt == "64":
            r = unpack64(pack64(r, **rounding64(texel)), dtype=dt)
        else:
            r = unpack32(pack32(r), dtype=dt, **decode32(texel))
        return shade_reference(SHADE_TOLERANCE if clamp is None else clamp, case_test)(r, zf)

    return chain


def nlq_exact(fmt, bias=BIAS_FLOAT32, clamp=None, case_test="stored", texel=None):
    """The mpmath twin of :func:`nlq_chain` (:func:`moments_ref.golden.truth.nlq_chain`): ``(b, zf) -> ((lo, hi),)``,
    the least and largest exact intensity over the texels the exact Φ may be stored as (either code within the goldens'
    tie band of a rounding boundary, :data:`moments_ref.golden.truth.CHAIN_TIE`). Only
    :func:`moments_ref.golden.bands.confirm` uses it (the case's ``confirm_truth``); the goldens' expected value
    stays the float64 chain."""

    def exact(b, zf):
        from .truth import CHAIN_TIE, nlq_chain as exact_chain

        return (exact_chain(b, zf, fmt, bias, clamp, case_test, texel, tie=CHAIN_TIE),)

    return exact


def msm64_exact(bias=BIAS_UNORM16, *_):
    """The mpmath twin of the e2e-msm64 chain (:func:`moments_ref.golden.truth.msm64_chain`): ``(b, zf) ->
    ((lo, hi),)``, the case's ``confirm_truth``."""

    def exact(b, zf):
        from .truth import CHAIN_TIE, msm64_chain

        return (msm64_chain(b, zf, bias, tie=CHAIN_TIE),)

    return exact


def _msm64(bias=BIAS_UNORM16, *_):
    def chain(b, zf):
        from ..affine import decode_unorm16, encode_unorm16
        from ..msm import shadow_intensity

        dt = np.asarray(b).dtype
        bq = decode_unorm16(encode_unorm16(b), dtype=dt)
        return (shadow_intensity(bq if bias is None else bias_moments(bq, bias), zf),)

    return chain


def _block(fmt, bias=BIAS_FLOAT32, clamp=None, case_test="stored", texel=None):
    inner = nlq_chain(fmt, bias, clamp, case_test, texel)

    def chain(depth, zf):
        dt = np.asarray(depth).dtype
        g = GUARD
        out = np.empty(zf.shape, dtype=dt)
        for i in range(len(depth)):  # one block per row (loop over blocks, not texels)
            b = blur(resolve_moments(depth[i]))[g:-g, g:-g].astype(dt)
            out[i] = inner(b, zf[i])[0]
        return (out,)

    return chain


def _block_spread(fmt, bias, clamp=None, case_test="stored", texel=None):
    return block_spread(fmt, bias, clamp, case_test, GUARD, nlq_chain, texel)


def _chain_variant(make, *args, hook=None, exact=None):
    """A profile's bias (inside the chain; None: the caller biased), clamp, case test and texel-format
    choices for ``make(*args, ...)``, its GPU spread ``hook(*args, ...)`` (golden.gpuspread) and its mpmath twin
    ``exact(*args, ...)`` (the case's ``confirm_truth``)."""

    def variant(bias=None, clamp=None, fmt=None, clamp_test=None, **_):
        from .variants import preset_of

        p = None if bias is None else preset_of(bias)
        extra = (clamp, clamp_test or "stored", dict(fmt or {}))
        out = {"reference": make(*args, p, *extra)}
        if hook is not None:
            out["spread_hook"] = hook(*args, p, *extra)
        if exact is not None:
            out["confirm_truth"] = exact(*args, p, *extra)
        return out

    return variant


def _block_rows(rng, dtype):
    h, w = BLOCK
    y, x = np.mgrid[0:h, 0:w].astype(np.float64)
    blocks, comments = [], []
    plane = -0.2 + 0.01 * x + 0.004 * y
    step = np.where(x + 0.5 * y > 24, plane - 0.5, plane)  # an occluder edge crossing the block
    jitter = rng.uniform(-1, 1, (h, w, 4)) * 2e-3
    blocks.append(np.clip(step[..., None] + jitter, -1, 1))
    comments.append("tilted receiver with an occluder edge, 4 jittered samples per texel")
    blocks.append(rng.uniform(-1, 1, (h, w, 4)))
    comments.append("independent uniform depths (foliage-like), 4 samples per texel")
    blocks.append(np.clip(0.3 + rng.uniform(-1, 1, (h, w, 4)) * 1e-5, -1, 1))
    comments.append("nearly constant depth 0.3 (variance near zero: Φ ill-conditioned)")
    blocks.append(np.where(rng.uniform(0, 1, (h, w, 4)) < 0.5, -0.9, 0.95))
    comments.append("two layers at -0.9 and 0.95 mixed per sample (strong light-leaking setup)")
    depth = np.stack(blocks)
    g = GUARD
    mean = depth.mean(axis=-1)[:, g:-g, g:-g]
    zf = np.clip(mean + rng.choice([-0.05, 0.002, 0.05, 0.3], mean.shape), -1, 1)
    return Rows({"depth": depth, "zf": zf}, ["random", "random", "stiff", "stiff"], comments)


_CHAIN = dict(contract="distribution")


def case_specs(dt):
    """Keyword dicts for :class:`moments_ref.golden.cases.Case`, one per end-to-end case."""
    chain = ("filtered moments b -> bias_moments(BIAS_FLOAT32) -> phi -> pack{0} -> unpack{0} -> shade "
             "(HPG17 Alg. 2, §3.3/§3.5, Alg. 3); compared as shadow intensities")
    nlq = dict(profile_keys=("bias", "clamp", "format"), bias_before=True, default_bias=("inside", BIAS_FLOAT32))
    specs = [dict(name=f"e2e-nlq{f}-{dt}", function=f"endtoend.nlq{f}", dtype=dt, inputs=("b", "zf"),
                  outputs=("intensity",), rows=_msm_rows, reference=nlq_chain(f), truth=None,
                  description=chain.format(f), value_range=(0, 1), **_CHAIN, **nlq,
                  depth_roles={}, variant=_chain_variant(nlq_chain, f, hook=chain_spread, exact=nlq_exact), width=4,
                  spread_hook=chain_spread(f, BIAS_FLOAT32), confirm_truth=nlq_exact(f))
             for f in ("64", "32")]
    specs.append(dict(name=f"e2e-msm64-{dt}", function="endtoend.msm64", dtype=dt, inputs=("b", "zf"),
                      outputs=("intensity",), rows=_msm_rows, reference=_msm64(), truth=None, value_range=(0, 1),
                      **_CHAIN, profile_keys=("bias",), default_bias=("inside", BIAS_UNORM16),
                      variant=_chain_variant(_msm64, hook=msm_spread, exact=msm64_exact), width=4,
                      spread_hook=msm_spread(BIAS_UNORM16), confirm_truth=msm64_exact(),
                      description="filtered moments b -> encode_unorm16 -> decode_unorm16 -> "
                                  "bias_moments(BIAS_UNORM16) -> Algorithm 1; compared as shadow intensities"))
    for f in ("64", "32"):
        specs.append(dict(
            name=f"e2e-block-nlq{f}-{dt}", function=f"endtoend.block_nlq{f}", dtype=dt, inputs=("depth", "zf"),
            outputs=("intensity",), rows=_block_rows, reference=_block(f), truth=None, value_range=(0, 1),
            profile_keys=("bias", "clamp", "format"), default_bias=("inside", BIAS_FLOAT32),
            variant=_chain_variant(_block, f, hook=_block_spread), width=4, spread_hook=_block_spread(f, BIAS_FLOAT32),
            description="40×32 block of 4× MSAA depths (HPG17 §4.1, guard band 4) -> resolve b(z) -> "
                        f"9² Gaussian blur (sigma 2.4) -> crop to 32×24 -> " + chain.format(f)))
    return specs
