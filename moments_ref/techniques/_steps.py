"""Steps shared by several techniques: per-sample features, their MSAA resolve, the blur.

Every filterable technique stores a feature vector f(z) per texel (the power
moments for MSM and NLQ, (z, z²) for VSM, exponentials for ESM and EVSM), averages
it over the MSAA samples (the resolve, HPG17 §4) and blurs it with the 9×9
Gaussian of σ = 2.4 (HPG17 §4.1). All of these are linear in the depth
distribution, which is why alpha blending renders translucent occluders into
them (Slides, "Translucent occluders").

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

from .._kernels import ROW_BAND_BYTES
from ..gpu.filtering import blur, resolve_moments
from ..moments import power_moments
from ._interface import LayeredSamples, Step, is_layered

__all__ = ["in_row_bands", "resolve_features", "sample_mean", "moment_steps", "feature_steps"]


def in_row_bands(fn, x):
    """``fn(x)`` of an (H, ...) array computed a band of rows at a time, into one result.

    For a step that works texel by texel (each output row depends only on the same
    input row), so the bands change no value; its temporaries then exist for one
    band of ``ROW_BAND_BYTES`` of input (``moments_ref._kernels``), not for the map.
    """
    h = x.shape[0]
    rows = max(1, ROW_BAND_BYTES // max(x[:1].nbytes, 1))
    if rows >= h:
        return fn(x)
    first = fn(x[:rows])
    out = np.empty((h,) + first.shape[1:], first.dtype)
    out[:rows] = first
    for y in range(rows, h, rows):
        out[y : y + rows] = fn(x[y : y + rows])
    return out


def resolve_features(samples, feature):
    """Mean over the samples of ``feature(z)`` (weighted over the layers when layered).

    Parameters
    ----------
    samples : (H, W, S) float array or LayeredSamples
    feature : callable ``z (...) -> (..., C)`` float64

    Returns
    -------
    (H, W, C) float64 array
    """
    if is_layered(samples):
        f = feature(samples.depth.astype(np.float64))  # (H, W, S, K, C)
        f = np.einsum("hwskc,hwsk->hwc", f, samples.weight) / samples.depth.shape[2]
        return f
    return in_row_bands(lambda band: sample_mean(feature(np.asarray(band, dtype=np.float64))), np.asarray(samples))


def sample_mean(f):
    """``f.mean(axis=2)`` of an (H, W, S, C) float64 array, the same values, in fewer passes.

    NumPy's mean over the samples axis, when the features axis (C ≥ 2) is the inner
    one, adds the samples one after the other into each output, ``((0 + f_0) + f_1)
    + …``, and divides by S; so do these S − 1 whole-slice additions, 3 to 4 times
    quicker than the strided reduction (a band of evsm's 4 features at 1024 texels × 4
    samples). With one feature (C = 1) the samples are NumPy's inner loop, summed
    pairwise from 8 on: that case is left to ``f.mean`` itself. (The same values:
    tests/test_techniques_steps.py compares both on every S and C the techniques use.)
    """
    s = f.shape[2]
    if f.shape[3] < 2 or s >= 8:
        return f.mean(axis=2)
    out = f[:, :, 0] + 0.0  # NumPy's sum starts at +0: −0.0 + 0.0 = +0.0, every other value unchanged
    for k in range(1, s):  # loop over the samples
        out += f[:, :, k]
    out /= s
    return out


def _moments(samples, params):
    if is_layered(samples):
        h, w, s, k = samples.depth.shape
        # Alpha blending far to near leaves Σ_k weight_k b(depth_k) per sample.
        return power_moments(samples.depth.reshape(h, w, s * k).astype(np.float64),
                             weights=samples.weight.reshape(h, w, s * k), axis=-1, n=4)
    return resolve_moments(samples)


def _blur(x, params):
    return blur(x)


def moment_steps(samples: int, layered: bool) -> tuple:
    """Moments per texel (resolved over the MSAA samples) and the reference blur.

    Names: ``compute_moments`` for a 1× map (nothing to resolve),
    ``resolve_moments`` with MSAA, ``translucency_blend_moments`` for layered
    input; then ``blur_moments`` (or ``translucency_blur_moments``).
    """
    if layered:
        return (Step("translucency_blend_moments", _moments), Step("translucency_blur_moments", _blur))
    first = "resolve_moments" if samples > 1 else "compute_moments"
    return (Step(first, _moments), Step("blur_moments", _blur))


def feature_steps(tag: str, feature, samples: int, layered: bool, params=()) -> tuple:
    """Resolve and blur of ``feature(z)``: steps ``resolve_<tag>`` / ``features_<tag>`` and ``blur_<tag>``.

    ``params`` (pairs, e.g. ``(("c", 80.0),)``) are the feature's parameters: part of
    the steps' keys (``resolve_esm_c80``), so features with other parameters never
    share a stage.
    """
    def resolve(x, options):
        return resolve_features(x, feature)

    prefix = "translucency_" if layered else ""
    first = ("resolve_" if samples > 1 or layered else "features_") + tag
    params = tuple(params)
    return (Step(prefix + first, resolve, params), Step(prefix + "blur_" + tag, _blur, params))
