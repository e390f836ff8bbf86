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

__all__ = ["float32_filters", "nlq_chain_gpu", "nlq_chain_fused", "msm_chain_fused", "tied_codes", "TIE_SUBSETS",
           "TRANSCENDENTAL_ULPS", "FUSED_STAGES", "block_spread", "chain_spread", "msm_spread"]

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


def msm_chain_fused(bias, fma, flip=()):
    """``e2e-msm64``'s chain (decode_unorm16 of encode_unorm16, the bias, Algorithm 1) by the plain Cholesky
    evaluation the shipped ports run, with (``fma``) or without every ``a·b + c`` contracted, float32.

    ``flip``: channels whose code is replaced by the other code of its rounding tie (:func:`tied_codes`); the
    chain is NaN on rows where one of them is not on a tie (that texel is the row's own, evaluated without it).
    ``fma=None``: that texel decoded, biased and bounded in float64 (:func:`moments_ref.msm.shadow_intensity`), the
    exact value's stand-in."""

    def chain(b, zf):
        from ..affine import decode_unorm16
        from ..gpu.fused32 import bias_fused
        from ..msm import shadow_intensity
        from .paper import cholesky_bound

        codes, alt, tied = tied_codes(b)
        keep = np.ones(len(codes), bool)
        for c in flip:
            codes[:, c], keep = alt[:, c], keep & tied[:, c]
        dt = np.float64 if fma is None else np.float32
        bq = decode_unorm16(codes, dtype=dt)
        if bias is not None:
            bq = bias_fused(bq, bias) if fma else bias_moments(bq, bias)
        z = np.asarray(zf, dt)
        v = shadow_intensity(bq, z) if fma is None else cholesky_bound(bq, z, "lower", np.float32, fma=fma)
        return (np.where(keep, v, np.nan).astype(dt),)

    return chain


def tied_codes(b):
    """``(codes, alt, tied)`` of the 64-bit affine texel of ``b`` (``(n, 4)``): the float32 encoder's UNORM16 codes
    (:func:`moments_ref.affine.encode_unorm16`), and per channel whether its scaled value
    65535 · clamp(M·b + c, 0, 1) (float64) lies within the goldens' tie band of a rounding boundary
    (:data:`moments_ref.golden.truth.CHAIN_TIE`, 2⁻¹⁸ of the range, a hair wider for float64's rounding) and the
    other code of that tie: the texels the exact chain :func:`moments_ref.golden.truth.msm64_chain` takes, any of
    which a float32 encoder (a GPU's ``to_optimized`` a few ulps off) may store."""
    from ..affine import encode_unorm16, to_optimized
    from .truth import CHAIN_TIE

    b = np.asarray(b).reshape(-1, 4)
    codes = encode_unorm16(b.astype(np.float32)).astype(np.int64)
    v = np.clip(to_optimized(b.astype(np.float64)), 0, 1) * 65535
    low = np.floor(v).astype(np.int64)
    tied = (np.abs(v - low - 0.5) <= CHAIN_TIE * 65535 + 1e-6) & ((codes == low) | (codes == low + 1))
    alt = np.where(tied, 2 * low + 1 - codes, codes)
    return codes.astype(np.uint16), alt.clip(0, 65535).astype(np.uint16), tied


#: The non-empty sets of channels of a 64-bit affine texel whose codes a tie may flip (up to 4 at once).
TIE_SUBSETS = tuple(tuple(c for c in range(4) if m >> c & 1) for m in range(1, 16))


def msm_spread(bias, *_):
    """A ``spread_hook`` for ``e2e-msm64``: :func:`msm_chain_fused` without and with fma on the row's own texel.

    Its attribute ``full`` is the hook of the whole neighbourhood (:func:`moments_ref.golden.bands.evaluations`
    with ``full``, the points the confirmation values exactly): the same chain, with and without fma and in float64,
    on each texel the row's rounding ties admit (:data:`TIE_SUBSETS`, :func:`tied_codes`; the exact chain
    :func:`moments_ref.golden.truth.msm64_chain` takes every one), NaN on rows without that tie."""

    def hook(inputs, dt):
        if dt != np.float32:
            return []
        b, zf = np.asarray(inputs["b"], dt), np.asarray(inputs["zf"], dt)
        return [msm_chain_fused(bias, f)(b, zf) for f in (False, True)]

    def full(inputs, dt):
        if dt != np.float32:
            return []
        b, zf = np.asarray(inputs["b"], dt), np.asarray(inputs["zf"], dt)
        tied, out = tied_codes(b)[2], []
        for flip in TIE_SUBSETS:
            rows = np.flatnonzero(tied[:, list(flip)].all(axis=1))
            if rows.size:  # only the rows this flip changes (about 2^-|flip| of them)
                for f in (False, True, None):
                    v = np.full(len(b), np.nan)
                    v[rows] = msm_chain_fused(bias, f, flip)(b[rows], zf[rows])[0]
                    out.append((v,))
        return out

    hook.full = full
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
