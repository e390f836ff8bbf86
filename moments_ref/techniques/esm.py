"""Exponential shadow mapping [Annen et al. 2008] at 32 bits per texel.

The texture stores ``E[exp(c z)]`` (one float32 channel), resolved over the MSAA
samples and blurred like the moments. Shading uses Markov's inequality on the
non-negative variable ``exp(c (z − zf))``, which is at least 1 wherever
``z ≥ zf``:

    P(z ≥ zf) ≤ E[exp(c (z − zf))] = E[exp(c z)] · exp(−c zf),

so ``1 − min(1, E[exp(c z)] exp(−c zf))`` is a lower bound of the shadow
intensity Z(z < zf). It is exact when every occluder lies far in front of the
receiver and every other depth equals zf; occluders within about 1/c of the
receiver leak light.

``c = ESM_C = 80`` on NDC depth z ∈ [-1, 1]: ``exp(80) ≈ 5.5e34`` still fits
float32 (whose limit is exp(88.7)). The product is evaluated as
``exp(ln E − c zf)`` so that it cannot overflow.

References
----------
.. [1] Annen et al. 2008: Thomas Annen, Tom Mertens, Hans-Peter Seidel, Eddy Flerackers and Jan
       Kautz. 2008. *Exponential Shadow Maps*. In Proceedings of Graphics Interface 2008 (GI '08).
       155–161. https://doi.org/10.20380/GI2008.20
"""

from __future__ import annotations

import numpy as np

from ..scene.depth import warped_positive
from ._interface import Step, Technique, bilinear_filtered, register
from ._steps import feature_steps

__all__ = ["ESM_C", "esm_feature", "esm_shadow", "ESM"]

#: Exponent of ESM on z ∈ [-1, 1] (largest round value whose exp fits float32).
ESM_C = 80.0


def esm_feature(z, c=ESM_C):
    """``exp(c z)`` as a (..., 1) float64 feature."""
    return warped_positive(np.asarray(z, dtype=np.float64), c)[..., None]


def esm_shadow(mean_exp, zf, c=ESM_C):
    """Shadow intensity ``1 − min(1, E[exp(c z)] exp(−c zf))`` (a lower bound of Z(z < zf)).

    Parameters
    ----------
    mean_exp : (...) float array
        Filtered ``E[exp(c z)]`` (> 0).
    zf : (...) float array
        Biased fragment depth.
    c : float
        The exponent used for ``mean_exp``.

    Returns
    -------
    (...) array of the dtype of ``mean_exp`` (float32 or float64).
    """
    m = np.asarray(mean_exp)
    dt = np.result_type(m, np.float32)
    with np.errstate(divide="ignore", over="ignore"):
        lit = np.exp(np.log(m.astype(dt)) - dt.type(c) * np.asarray(zf, dtype=dt))
    return (dt.type(1) - np.minimum(lit, dt.type(1))).astype(dt)


def _store(x, params):
    return x.astype(np.float32)


def _steps(samples, layered):
    return feature_steps("esm", esm_feature, samples, layered, (("c", ESM_C),)) + (Step("store_esm_float32", _store),)


def _lookup(texture, uv, zf, noise):
    m = bilinear_filtered(texture, uv, np.float32)[..., 0]
    return esm_shadow(m, zf.astype(np.float32), ESM_C)


ESM = register(Technique(
    name="esm",
    bits_per_texel=32,
    depth_bias=1e-3,
    make_steps=_steps,
    lookup=_lookup,
    description="exponential shadow mapping, exp(80 z) in R32_FLOAT, Markov bound",
    reference="Annen et al. 2008",
))
