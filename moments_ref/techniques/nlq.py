"""Non-linearly quantized moment shadow maps (HPG17 §3, §4): 64 and 32 bits, bilinear or dithered.

Texture: the compute shader of HPG17 §4.1 (:func:`moments_ref.gpu.onchip.filter_moments`,
resolve and 9×9 blur block by block in float32), then per texel
``bias_moments(b, BIAS_FLOAT32)``, Algorithm 2 (:func:`moments_ref.nonlinear.phi`)
and the 64-bit (§3.3, :func:`moments_ref.packing.pack64`) or 32-bit (§3.5,
:func:`moments_ref.packing.pack32`) texel format. This is what
:func:`moments_ref.gpu.onchip.filter_and_quantize` returns; here the filtering is a
stage of its own so that both formats and both lookups share it.

Lookup: non-linearly quantized texels cannot be filtered by the texture unit.

* ``nlq64``, ``nlq32``: true bilinear interpolation, four texels, four times
  Algorithm 3, interpolated intensities (HPG17 §4.2, the quality reference of
  Figure 7; :func:`moments_ref.gpu.bluenoise.lookup_bilinear`);
* ``nlq64_dither``, ``nlq32_dither``: one texel fetched at ``uv`` plus blue noise,
  one Algorithm 3 (HPG17 §4.2, :func:`moments_ref.gpu.bluenoise.lookup_dithered`).

Depth bias 1e-3 (HPG17 §5: "With non-linear quantization we use a constant depth
bias of 10⁻³ depth units for all results"). Shading runs in float32.

References
----------
.. [1] HPG17: Christoph Peters. 2017. *Non-Linearly Quantized Moment Shadow Maps*. In Proceedings
       of High Performance Graphics (HPG '17). ACM. The non-linear quantization Φ, Ψ4, Algorithms
       1–3, the texel formats and the compute shader of §4.1.
"""

from __future__ import annotations

import numpy as np

from ..gpu.bluenoise import lookup_bilinear, lookup_dithered
from ..nonlinear import shade
from ..gpu.onchip import filter_moments
from ..packing import nlq_texels, unpack32, unpack64
from ._interface import Step, Technique, register

__all__ = ["NLQ64", "NLQ32", "NLQ64_DITHER", "NLQ32_DITHER"]


def _onchip(x, params):
    return filter_moments(x)


def _quantizer(fmt):
    def quantize(b, params):
        return nlq_texels(b, fmt)  # pack(phi(bias_moments(b, BIAS_FLOAT32))) bit for bit, chunked
    return quantize


def _steps_for(bits):
    def steps(samples, layered):
        # The shader resolves the MSAA samples while loading; a 1x map has nothing to resolve.
        first = "onchip_resolve_blur" if samples > 1 else "onchip_blur"
        return (Step(first, _onchip), Step(f"quantize_nlq{bits}", _quantizer(f"nlq{bits}")))
    return steps


def _decoder(bits):
    unpack = unpack64 if bits == 64 else unpack32
    return lambda texels: unpack(texels, dtype=np.float32)


def _bilinear_lookup(bits):
    decode = _decoder(bits)

    def shade_texels(texels, zf):
        return shade(decode(texels), zf)

    def lookup(texture, uv, zf, noise):
        return lookup_bilinear(texture, uv.astype(np.float32), shade_texels, zf.astype(np.float32))
    return lookup


def _dither_lookup(bits):
    decode = _decoder(bits)

    def lookup(texture, uv, zf, noise):
        texels = lookup_dithered(texture, uv.astype(np.float32), noise)
        return shade(decode(texels), zf.astype(np.float32))
    return lookup


def _make(name, bits, dither):
    return register(Technique(
        name=name, bits_per_texel=bits, depth_bias=1e-3, make_steps=_steps_for(bits),
        lookup=_dither_lookup(bits) if dither else _bilinear_lookup(bits),
        description=(f"non-linearly quantized moments, {bits} bits, "
                     + ("blue-noise dithered fetch" if dither else "bilinear (4 x Algorithm 3)")),
        reference="HPG17 §3, Algorithm 2, 3, §4" + (".2 (dithering)" if dither else ""),
        needs_noise=dither, four_moments=True,
    ))


NLQ64 = _make("nlq64", 64, False)
NLQ32 = _make("nlq32", 32, False)
NLQ64_DITHER = _make("nlq64_dither", 64, True)
NLQ32_DITHER = _make("nlq32_dither", 32, True)
