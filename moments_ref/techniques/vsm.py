"""Variance shadow mapping [Donnelly and Lauritzen 2006] at 32 bits per texel.

The texture stores the first two moments of the depth ``d = (z + 1)/2 ∈ [0, 1]``
in two UNORM16 channels (R16G16_UNORM, HPG17 §6: "variance shadow mapping with 32
bits per texel"). They are affine in the power moments b1, b2 of z,

    E[d] = (b1 + 1)/2,    E[d²] = (b2 + 2 b1 + 1)/4,

so VSM shares the resolve and the blur of the moment techniques and only
quantizes differently. Shading interpolates the texture bilinearly (filterable)
and applies Cantelli's inequality (the one-sided Chebyshev bound): with
``μ = E[d]``, ``σ² = max(E[d²] − μ², σ²_min)`` and ``t = (zf + 1)/2``,

    Z(z < zf) ≥ (t − μ)² / (σ² + (t − μ)²)    for t > μ,  else 0,

the sharp lower bound of the shadow intensity given two moments.

``σ²_min = VSM_MIN_VARIANCE = 1e-5`` (in units of d²) is of the size of the
rounding error of the second UNORM16 channel (1/65535 ≈ 1.5e-5): without it a
lit surface whose rounded variance comes out zero or negative would be shadowed
by its own depth bias.

References
----------
.. [1] Donnelly and Lauritzen 2006: William Donnelly and Andrew Lauritzen. 2006. *Variance Shadow
       Maps*. In Proceedings of the 2006 ACM SIGGRAPH Symposium on Interactive 3D Graphics and
       Games (i3D '06). ACM, 161–165. https://doi.org/10.1145/1111411.1111440
.. [2] HPG17: Christoph Peters. 2017. *Non-Linearly Quantized Moment Shadow Maps*. In Proceedings
       of High Performance Graphics (HPG '17). ACM. The non-linear quantization Φ, Ψ4, Algorithms
       1–3, the texel formats and the compute shader of §4.1.
"""

from __future__ import annotations

import numpy as np

from ..affine import float_to_unorm, unorm_to_float
from ..scene.depth import z_unit_from_ndc
from ._interface import Step, Technique, bilinear_filtered, register
from ._steps import in_row_bands, moment_steps

__all__ = ["VSM_MIN_VARIANCE", "vsm_from_moments", "cantelli_shadow", "VSM"]

#: Minimum variance of d = (z + 1)/2 (see the module docstring).
VSM_MIN_VARIANCE = 1e-5


def vsm_from_moments(b):
    """``(E[d], E[d²])`` of ``d = (z + 1)/2`` from the power moments (..., ≥2) of z."""
    b = np.asarray(b, dtype=np.float64)
    b1, b2 = b[..., 0], b[..., 1]
    return np.stack([(b1 + 1) / 2, (b2 + 2 * b1 + 1) / 4], axis=-1)


def cantelli_shadow(mean, mean_sq, t, min_variance):
    """Cantelli's lower bound of P(x < t) from E[x], E[x²] (variance clamped below).

    Parameters
    ----------
    mean, mean_sq, t : float arrays (broadcast)
    min_variance : float or array

    Returns
    -------
    (...) array in [0, 1]: ``(t − μ)² / (σ² + (t − μ)²)`` for ``t > μ``, else 0.
    """
    dt = np.result_type(mean, np.float32)
    variance = np.maximum(mean_sq - mean * mean, np.asarray(min_variance, dtype=dt))
    d = t - mean
    den = variance + d * d
    with np.errstate(invalid="ignore", divide="ignore"):
        bound = d * d / den
    # σ² = 0 and d² under the smallest subnormal (d > 0 by less than 1e-162): the limit d²/d² = 1, not 0/0
    bound = np.where(den == 0, dt.type(1), bound)
    return np.where(d > 0, np.clip(bound, 0, 1), dt.type(0))


def _quantize(b, params):
    return in_row_bands(lambda band: float_to_unorm(vsm_from_moments(band), bits=16), np.asarray(b))


def _steps(samples, layered):
    return moment_steps(samples, layered) + (Step("quantize_vsm32", _quantize),)


def _lookup(texture, uv, zf, noise):
    # The texture unit filters the UNORM values as floats (float32).
    m = bilinear_filtered(unorm_to_float(texture, 16, np.float32), uv, np.float32)
    t = z_unit_from_ndc(zf).astype(np.float32)
    return cantelli_shadow(m[..., 0], m[..., 1], t, np.float32(VSM_MIN_VARIANCE))


VSM = register(Technique(
    name="vsm",
    bits_per_texel=32,
    depth_bias=1e-3,
    make_steps=_steps,
    lookup=_lookup,
    description="variance shadow mapping, (d, d^2) in R16G16_UNORM, Cantelli lower bound",
    reference="Donnelly and Lauritzen 2006; HPG17 §5, Figure 1",
))
