"""Moment shadow mapping [Peters and Klein 2015] at 64 and 128 bits per texel.

The texture holds the four power moments, resolved over the MSAA samples and
blurred (three-pass filtering, as HPG17 §5 implements the related work). Shading
filters it bilinearly (moments are filterable), biases the moments and applies
HPG17 Algorithm 1 (:func:`moments_ref.msm.shadow_intensity`, the sharp lower
bound of Z(z < zf)).

* ``msm64``: the optimized basis (:func:`moments_ref.affine.to_optimized`) in
  R16G16B16A16_UNORM; bias ``BIAS_UNORM16`` (α = 6e-5) after decoding (HPG17 §5,
  Slides "Bias the moments").
* ``msm128``: b1..b4 in R32G32B32A32_FLOAT; bias ``BIAS_FLOAT32`` (α = 3e-7).

Shading runs in float32, as a shader would.

References
----------
.. [1] Peters and Klein 2015: Christoph Peters and Reinhard Klein. 2015. *Moment Shadow Mapping*.
       In Proceedings of the 19th ACM SIGGRAPH Symposium on Interactive 3D Graphics and Games (i3D
       '15). ACM, 7–14. https://doi.org/10.1145/2699276.2699277
.. [2] HPG17: Christoph Peters. 2017. *Non-Linearly Quantized Moment Shadow Maps*. In Proceedings
       of High Performance Graphics (HPG '17). ACM. The non-linear quantization Φ, Ψ4, Algorithms
       1–3, the texel formats and the compute shader of §4.1.
.. [3] Slides: Christoph Peters. *Rendering antialiased shadows with moment shadow mapping*,
       lecture slides (PDF version, with notes) on moment shadow mapping, translucent occluders,
       moment soft shadow mapping and prefiltered single scattering; http://MomentsInGraphics.de/.
       Cited by slide title, e.g. Slides, "Bias the moments".
"""

from __future__ import annotations

import numpy as np

from ..affine import encode_unorm16, from_optimized, unorm_to_float
from ..moments import BIAS_FLOAT32, BIAS_UNORM16, bias_moments
from ..msm import shadow_intensity
from ._interface import Step, Technique, bilinear_filtered, register
from ._steps import in_row_bands, moment_steps

__all__ = ["msm64_steps", "msm64_lookup", "MSM64", "MSM128"]


def _quantize_affine64(b, params):
    return in_row_bands(encode_unorm16, np.asarray(b))


def _store_float128(b, params):
    return np.asarray(b, dtype=np.float32)


def msm64_steps(samples, layered):
    """Moments, blur, then the optimized basis in UNORM16 (``quantize_affine64``)."""
    prefix = "translucency_" if layered else ""
    return moment_steps(samples, layered) + (Step(prefix + "quantize_affine64", _quantize_affine64),)


def msm64_lookup(texture, uv, zf, noise):
    """Bilinear fetch of the UNORM16 texels, inverse basis, BIAS_UNORM16, Algorithm 1 (float32)."""
    q = bilinear_filtered(unorm_to_float(texture, 16, np.float32), uv, np.float32)
    b = from_optimized(q)
    return shadow_intensity(bias_moments(b, BIAS_UNORM16), zf.astype(np.float32))


def _msm128_steps(samples, layered):
    prefix = "translucency_" if layered else ""
    return moment_steps(samples, layered) + (Step(prefix + "store_float128", _store_float128),)


def _msm128_lookup(texture, uv, zf, noise):
    b = bilinear_filtered(texture, uv, np.float32)
    return shadow_intensity(bias_moments(b, BIAS_FLOAT32), zf.astype(np.float32))


MSM64 = register(Technique(
    name="msm64", bits_per_texel=64, depth_bias=1e-3, make_steps=msm64_steps, lookup=msm64_lookup,
    description="moment shadow mapping, optimized basis in R16G16B16A16_UNORM, alpha = 6e-5",
    reference="Peters and Klein 2015; HPG17 §2, Algorithm 1, §5", four_moments=True,
))
MSM128 = register(Technique(
    name="msm128", bits_per_texel=128, depth_bias=1e-3, make_steps=_msm128_steps, lookup=_msm128_lookup,
    description="moment shadow mapping, b1..b4 in R32G32B32A32_FLOAT, alpha = 3e-7",
    reference="Peters and Klein 2015; HPG17 §2, Algorithm 1, §5", four_moments=True,
))
