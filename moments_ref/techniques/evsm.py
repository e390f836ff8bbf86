"""Exponential variance shadow mapping [Lauritzen and McCool 2008]: 64 and 128 bits.

Depths are warped by ``x⁺ = exp(c⁺ z)`` and ``x⁻ = −exp(−c⁻ z)`` (both increasing
in z; :func:`moments_ref.scene.depth.warped_positive`, :func:`~moments_ref.scene.depth.warped_negative`) and the texture stores ``(E[x⁺], E[(x⁺)²], E[x⁻], E[(x⁻)²])``. Cantelli's
bound (:func:`moments_ref.techniques.vsm.cantelli_shadow`) on each warp is a lower
bound of ``Z(z < zf) = P(x± < x±(zf))``; EVSM takes the larger of the two.

Formats (HPG17 §5, Figure 1):

* ``evsm64``: c⁺ = c⁻ = 5.5 in four 16-bit float channels (R16G16B16A16_FLOAT):
  ``exp(2 · 5.5) ≈ 59874`` is below float16's largest value 65504;
* ``evsm128``: c⁺ = 40, c⁻ = 5.5 in float32 (``exp(80) ≈ 5.5e34``).

Minimum variance. The variance of each warp is clamped below by
``(δ · c · x(zf))²``, the variance of a depth spread of δ after linearizing the
warp at the fragment (the usual EVSM clamp). δ must cover the rounding of the
channels: float16 carries a relative error of 2⁻¹¹ in E[x²], i.e. a variance
noise of about 7e-4·x², hence ``δ = 5e-3`` for evsm64 (c δ ≈ 0.027); float32 needs
only ``δ = 1e-4`` for evsm128.

Where the positive warp helps and where it does not (tests/test_evsm_leak.py,
tests/test_evsm_scene.py). EVSM128 differs from EVSM64 only in its positive warp
(both have c⁻ = 5.5). Over short range, occluders in front of a receiver that
fills the rest of the filter region at the fragment's own depth, c⁺ = 40 squeezes
the occluders towards 0 and EVSM128 leaks far less (two occluders 0.05 to 0.2 in
front of a flat receiver, exact Z summed tap by tap). But a lit texel Δ *behind*
the fragment weighs ``exp(c⁺ Δ)`` in E[x⁺], and Cantelli reports shadow only when
``t > E[x⁺]``: a footprint with shadowed share p gets no shadow from the positive
warp once its lit part lies about ``ln(1/(1 − p))/c⁺`` behind the fragment. The
negative warp (identical to EVSM64's) then decides, and EVSM64's milder positive
warp can even beat it. Lit depths behind the fragment come from the cleared far
plane z = 1 where a receiver is not rendered into the map (hence every shipped
receiver that HPG17's setup would render casts), from a depth bias larger than
the constant 1e-3 (the receiver-slope bias of :mod:`moments_ref.scene.gbuffer`, up to
0.04 depth units on railing's steep banner, which is why EVSM, like every
filterable technique, uses the constant alone) and from depth discontinuities (the
ground behind the banner's edges): HPG17 §2, EVSM "misrepresents shadows at object
boundaries". That is the method's sensitivity, not a storage or filtering error:
evaluating the same texture in float64, without the minimum-variance clamp, or
filtering unrounded moments changes railing's and knot's RMSE by less than 1e-4.

Large exponents (tests/test_techniques.py). For a filter region whose depths lie
either at zf or at least Δ in front of it, the positive warp sends the occluders
to ``≤ exp(−c Δ)·x⁺(zf)``: as c grows the warped distribution becomes a two-point
distribution with one point at the fragment, for which Cantelli's bound is exact.
With δ = 0 EVSM then converges to the exact Z(z < zf) like ESM
(:func:`moments_ref.techniques.esm.esm_shadow`), both with errors O(exp(−c Δ)).

References
----------
.. [1] Lauritzen and McCool 2008: Andrew Lauritzen and Michael McCool. 2008. *Layered Variance
       Shadow Maps*. In Proceedings of Graphics Interface 2008 (GI '08). 139–146.
       https://doi.org/10.20380/GI2008.18 (exponential variance shadow maps, EVSM)
.. [2] HPG17: Christoph Peters. 2017. *Non-Linearly Quantized Moment Shadow Maps*. In Proceedings
       of High Performance Graphics (HPG '17). ACM. The non-linear quantization Φ, Ψ4, Algorithms
       1–3, the texel formats and the compute shader of §4.1.
"""

from __future__ import annotations

import numpy as np

from .._kernels import CHUNK
from ..scene.depth import warped_negative, warped_positive
from ._interface import Step, Technique, bilinear_filtered, register
from ._steps import feature_steps
from .vsm import cantelli_shadow

__all__ = ["evsm_feature", "evsm_shadow", "EVSM64", "EVSM128"]


def evsm_feature(z, c_pos, c_neg):
    """``(x⁺, (x⁺)², x⁻, (x⁻)²)`` with ``x⁺ = exp(c⁺ z)``, ``x⁻ = −exp(−c⁻ z)``; (..., 4) float64."""
    z = np.asarray(z, dtype=np.float64)
    out = np.empty(z.shape + (4,))
    flat, rows = z.reshape(-1), out.reshape(-1, 4)
    # A chunk at a time: the four interleaved columns are written while the chunk is in cache
    # (np.stack of the whole map wrote them in four strided passes, 4x slower at 1024² 4x MSAA).
    for i in range(0, flat.size, CHUNK):
        zc, o = flat[i : i + CHUNK], rows[i : i + CHUNK]
        p, n = warped_positive(zc, c_pos), warped_negative(zc, c_neg)
        o[:, 0] = p
        np.multiply(p, p, out=o[:, 1])
        o[:, 2] = n
        np.multiply(n, n, out=o[:, 3])
    return out


def evsm_shadow(m, zf, c_pos, c_neg, min_depth_std=0.0):
    """EVSM shadow intensity: the larger Cantelli bound of the two warps.

    Parameters
    ----------
    m : (..., 4) float array
        Filtered ``(E[x⁺], E[(x⁺)²], E[x⁻], E[(x⁻)²])``.
    zf : (...) float array
        Biased fragment depth.
    c_pos, c_neg : float
        Exponents.
    min_depth_std : float
        δ of the minimum variance ``(δ c x(zf))²`` (module docstring).

    Returns
    -------
    (...) array in [0, 1], dtype of ``m`` (at least float32).
    """
    m = np.asarray(m)
    dt = np.result_type(m, np.float32)
    m = m.astype(dt)
    zf = np.asarray(zf, dtype=dt)
    tp, tn = warped_positive(zf, c_pos), warped_negative(zf, c_neg)
    vp = (dt.type(min_depth_std * c_pos) * tp) ** 2
    vn = (dt.type(min_depth_std * c_neg) * tn) ** 2
    return np.maximum(cantelli_shadow(m[..., 0], m[..., 1], tp, vp),
                      cantelli_shadow(m[..., 2], m[..., 3], tn, vn))


def _make(name, bits, c_pos, c_neg, storage, delta, description):

    def feature(z):
        return evsm_feature(z, c_pos, c_neg)

    def store(x, params):
        return x.astype(storage)

    def steps(samples, layered):
        return feature_steps("evsm", feature, samples, layered, (("c", (c_pos, c_neg)),)) + (
            Step(f"store_{name}_{np.dtype(storage).name}", store),)

    def lookup(texture, uv, zf, noise):
        # The texture unit filters float16 and float32 texels in float32.
        m = bilinear_filtered(texture, uv, np.float32)
        return evsm_shadow(m, zf.astype(np.float32), c_pos, c_neg, delta)

    return register(Technique(
        name=name, bits_per_texel=bits, depth_bias=1e-3, make_steps=steps, lookup=lookup,
        description=description, reference="Lauritzen and McCool 2008; HPG17 §5, Figure 1",
        defaults={"c_pos": c_pos, "c_neg": c_neg, "min_depth_std": delta},
    ))


EVSM64 = _make("evsm64", 64, 5.5, 5.5, np.float16, 5e-3,
               "exponential variance shadow mapping, c+ = c- = 5.5, R16G16B16A16_FLOAT")
EVSM128 = _make("evsm128", 128, 40.0, 5.5, np.float32, 1e-4,
                "exponential variance shadow mapping, c+ = 40, c- = 5.5, R32G32B32A32_FLOAT")
