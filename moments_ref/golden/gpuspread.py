"""What a GPU does differently, as legitimate variants of the chained cases' spread model.

A GPU filters in float32, in whatever order its threads add, and its ``log`` and
``exp`` are a few ulps off (GLSL 4.30 §4.7.1: 3 ulp, ``exp`` 3 + 2|x| ulp). The
chained cases (``e2e-*``, ``e2e-block-*``, ``engine-nlq*``, and compute-kernel cases)
measure their tolerances on these too:

* :func:`float32_filters`: the MSAA resolve and the two 9-tap Gaussian passes of
  HPG17 §4.1 in float32 as the kernels of :mod:`moments_ref.gpu.filter32` compute
  them (sums in sequential, reversed, pairwise or symmetric order, z⁴ two ways, the
  weights rounded or computed in float32, and the §4.1 shared-memory emulation);
* :func:`nlq_chain_gpu`: the NLQ chain with Ψ4's two logarithms and Ψ4⁻¹'s two
  exponentials :data:`TRANSCENDENTAL_ULPS` ulps off, up or down (as a relative change
  of ξ4 of the same effect, before encoding and after decoding);
* :func:`nlq_chain_fused`: the NLQ chain as a compiler contracts and reassociates it
  (:mod:`moments_ref.gpu.fused32`: the bias, Algorithm 2 and Algorithm 3 with every
  ``a·b + c`` fused, either product of a two-product sum, sums in either order), and
  :func:`msm_chain_fused`: Algorithm 1 after the 64-bit affine decode by the plain
  Cholesky evaluation with and without fma (:func:`moments_ref.golden.paper.cholesky_bound`).

Drivers choose differently here (llvmpipe's GLSL path and lavapipe's SPIR-V path fuse
and reassociate different sums of the same chain), so these evaluations, not a safety
factor, are what lets the same file pass on both: the chained cases take the band
model's normal margin (:mod:`moments_ref.golden.bands`).

References
----------
.. [1] HPG17: Christoph Peters. 2017. *Non-Linearly Quantized Moment Shadow Maps*. In Proceedings
       of High Performance Graphics (HPG '17). ACM. The non-linear quantization Φ, Ψ4, Algorithms
       1–3, the texel formats and the compute shader of §4.1.
"""

from __future__ import annotations

import numpy as np

from ..moments import bias_moments

__all__ = ["float32_filters", "nlq_chain_gpu", "nlq_chain_fused", "msm_chain_fused", "TRANSCENDENTAL_ULPS", "FUSED_STAGES",
           "block_spread", "chain_spread", "msm_spread"]

#: How far a GPU's log and exp may be off (GLSL 4.30 §4.7.1: 3 ulp outside [0.5, 2]).
TRANSCENDENTAL_ULPS = 3
_EPS32 = float(np.finfo(np.float32).eps)


def float32_filters(depth):
    """Filtered moments ``(H, W, 4)`` float32 of one block of MSAA depths, as GPUs compute them: every
    legitimate float32 kernel of :data:`moments_ref.gpu.filter32.VARIANTS` (the one place they live), and the
    filter with exact sums rounded once to float32 (float64 arithmetic: the limit every order of the sums
    approaches, and what a port that filters in double precision stores)."""
    from ..gpu.filter32 import variant_moments
    from ..gpu.filtering import blur, resolve_moments

    d = np.asarray(depth, np.float32)
    exact = blur(resolve_moments(d.astype(np.float64))).astype(np.float32)
    return list(variant_moments(d).values()) + [exact]


def _nudge_xi(r, sign, decoded):
    """ξ4 moved as a GPU's log (encoding) or exp (decoding) off by TRANSCENDENTAL_ULPS ulps would move it."""
    r = np.array(r, copy=True)
    xi = np.maximum(r[..., 3].astype(np.float64), 1.2e-7)
    big_l = np.log(xi * 1e7)  # ln(ξ4 · 1e7) in [0.18, 14.7]
    if decoded:  # ξ4 = 1e-7 exp(exp(x)): outer exp 1 unit, inner exp amplified by its value L
        rel = 1 + np.abs(big_l)
    else:  # Ψ4 = (ln ln(1e7 ξ4) − c0)/c1: inner log L, outer log ln L, both relative to ξ4
        rel = np.abs(big_l) + np.abs(big_l * np.log(np.maximum(big_l, 1e-300)))
    r[..., 3] = (xi * (1 + sign * TRANSCENDENTAL_ULPS * _EPS32 * rel)).astype(r.dtype)
    return r


def nlq_chain_gpu(fmt, bias, clamp=None, case_test="stored", sign=1, texel=None):
    """The NLQ chain of :func:`moments_ref.golden.endtoend.nlq_chain` with a GPU's log and exp (``sign``: up
    or down; ``texel``: the profile's texel-format choices)."""

    def chain(b, zf):
        from ..moments import bias_moments
        from ..nonlinear import SHADE_TOLERANCE, phi
        from ..packing import pack32, pack64, unpack32, unpack64
        from .variants import decode32, rounding64, shade_reference

        dt = np.asarray(b).dtype
        r = _nudge_xi(phi(b if bias is None else bias_moments(b, bias)), sign, decoded=False)
        if fmt == "64":
            r = unpack64(pack64(r, **rounding64(texel)), dtype=dt)
        else:
            r = unpack32(pack32(r), dtype=dt, **decode32(texel))
        return shade_reference(SHADE_TOLERANCE if clamp is None else clamp, case_test)(
            _nudge_xi(r, sign, decoded=True), zf)

    return chain


#: The stages of the NLQ chain each compiled plainly (None: the reference's operations) or contracted either way
#: (:data:`moments_ref.gpu.fused32.CONTRACTIONS`): (bias, Φ, Algorithm 3). A compiler decides per expression, so
#: the bias and Φ, between which an ill-conditioned texel amplifies one rounding most, are enumerated jointly.
FUSED_STAGES = tuple((bi, ph, ph if ph is not None else bi) for bi in (None, False, True) for ph in (None, False, True)
                     if (bi, ph) != (None, None))


def nlq_chain_fused(fmt, bias, clamp=None, case_test="stored", stages=(False, False, False), texel=None):
    """The NLQ chain of :func:`moments_ref.golden.endtoend.nlq_chain` as a compiler contracts and reassociates it
    (:mod:`moments_ref.gpu.fused32`), float32. ``stages``: per stage (bias, Φ, Algorithm 3) None (the reference's
    operations), False or True (``swapped``: the other product fused, sums in the other order)."""

    def chain(b, zf):
        from ..gpu.fused32 import bias_fused, phi_fused, shade_fused
        from ..nonlinear import SHADE_TOLERANCE, phi
        from ..packing import pack32, pack64, unpack32, unpack64
        from .variants import decode32, rounding64, shade_reference

        sb, sp, ss = stages
        b = np.asarray(b, np.float32)
        if bias is not None:
            b = bias_moments(b, bias) if sb is None else bias_fused(b, bias, sb)
        r = phi(b) if sp is None else phi_fused(b, sp)
        if fmt == "64":
            r = unpack64(pack64(r, **rounding64(texel)), dtype=np.float32)
        else:
            r = unpack32(pack32(r), dtype=np.float32, **decode32(texel))
        c = SHADE_TOLERANCE if clamp is None else clamp
        return shade_reference(c, case_test)(r, zf) if ss is None else (shade_fused(r, zf, c, ss, case_test),)

    return chain


def msm_chain_fused(bias, fma):
    """``e2e-msm64``'s chain (decode_unorm16 of encode_unorm16, the bias, Algorithm 1) by the plain Cholesky
    evaluation the shipped ports run, with (``fma``) or without every ``a·b + c`` contracted, float32."""

    def chain(b, zf):
        from ..affine import decode_unorm16, encode_unorm16
        from ..gpu.fused32 import bias_fused
        from .paper import cholesky_bound

        bq = decode_unorm16(encode_unorm16(np.asarray(b, np.float32)), dtype=np.float32)
        if bias is not None:
            bq = bias_fused(bq, bias) if fma else bias_moments(bq, bias)
        return (cholesky_bound(bq, zf, "lower", np.float32, fma=fma),)

    return chain


def msm_spread(bias, *_):
    """A ``spread_hook`` for ``e2e-msm64``: :func:`msm_chain_fused` without and with fma."""

    def hook(inputs, dt):
        if dt != np.float32:
            return []
        b, zf = np.asarray(inputs["b"], dt), np.asarray(inputs["zf"], dt)
        return [msm_chain_fused(bias, f)(b, zf) for f in (False, True)]

    return hook


def chain_spread(fmt, bias, clamp=None, case_test="stored", texel=None):
    """A ``spread_hook`` for ``e2e-nlq*``: the chain with a GPU's log and exp, and contracted and reassociated
    (:func:`nlq_chain_fused`), in float32 ports' precision."""

    def hook(inputs, dt):
        if dt != np.float32:
            return []
        b, zf = np.asarray(inputs["b"], dt), np.asarray(inputs["zf"], dt)
        return [nlq_chain_gpu(fmt, bias, clamp, case_test, s, texel)(b, zf) for s in (1, -1)] + [
            nlq_chain_fused(fmt, bias, clamp, case_test, s, texel)(b, zf) for s in FUSED_STAGES]

    return hook


def block_spread(fmt, bias, clamp=None, case_test="stored", guard=4, nlq_chain=None, texel=None):
    """A ``spread_hook`` for ``e2e-block-nlq*``: float32 filters (the sums over samples and taps in every order
    :mod:`moments_ref.gpu.filter32` enumerates), then the chain ``nlq_chain`` (the case's, golden.endtoend), the
    same with a GPU's log and exp, and contracted and reassociated (:func:`nlq_chain_fused`)."""

    def hook(inputs, dt):
        if dt != np.float32:
            return []
        depth, zf = np.asarray(inputs["depth"]), np.asarray(inputs["zf"], dt)
        chains = [nlq_chain(fmt, bias, clamp, case_test, texel)] + [
            nlq_chain_gpu(fmt, bias, clamp, case_test, s, texel) for s in (1, -1)] + [
            nlq_chain_fused(fmt, bias, clamp, case_test, s, texel) for s in FUSED_STAGES]
        outs = []
        per_block = [float32_filters(depth[i]) for i in range(len(depth))]  # one block per row
        for k in range(len(per_block[0])):
            for chain in chains:
                out = np.empty(zf.shape, dt)
                for i in range(len(depth)):
                    b = per_block[i][k][guard:-guard, guard:-guard].astype(dt)
                    out[i] = chain(b, zf[i])[0]
                outs.append((out,))
        return outs

    return hook
