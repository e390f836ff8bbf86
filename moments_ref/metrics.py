"""Error metrics of shadow images: intensity statistics, the shaded LDR image, NVIDIA ꟻLIP.

Shared by the references of :mod:`moments_ref.techniques` (each declares its
metric from these) and re-exported by :mod:`moments_ref.report`.

References
----------
.. [1] FLIP: Pontus Andersson, Jim Nilsson, Tomas Akenine-Möller, Magnus Oskarsson, Kalle Åström
       and Mark D. Fairchild. 2020. *ꟻLIP: A Difference Evaluator for Alternating Images*.
       Proceedings of the ACM on Computer Graphics and Interactive Techniques (HPG 2020) 3, 2. Used
       through the package ``flip-evaluator``.
.. [2] HPG17: Christoph Peters. 2017. *Non-Linearly Quantized Moment Shadow Maps*. In Proceedings
       of High Performance Graphics (HPG '17). ACM. The non-linear quantization Φ, Ψ4, Algorithms
       1–3, the texel formats and the compute shader of §4.1.
"""

from __future__ import annotations

import math

import numpy as np

from .scene.gbuffer import OCCLUDER, OUTSIDE_LIGHT

__all__ = ["LEAK_THRESHOLD", "FULL_SHADOW", "VISIBLE", "metrics", "light_metrics", "shadow_leak",
           "visible_differences", "shaded_image", "flip_mean", "flip_available"]

#: A pixel leaks when it is lit more than this above the reference.
LEAK_THRESHOLD = 0.05
#: A receiver pixel is fully shadowed at or above this reference intensity (HPG17 §6: "light will
#: leak onto fully shadowed surfaces").
FULL_SHADOW = 0.999
#: Differences in shadow intensity a viewer sees: HPG17 §5 counts the pixels "above 3%" and
#: reports the highest difference "below 10%".
VISIBLE = (0.03, 0.10)


def metrics(shadow, reference):
    """Error statistics of shadow intensities against the reference.

    Returns a dict with ``rmse``, ``max_error``, ``p99_error``, ``leak_fraction``
    (NaN propagates: a non-finite intensity makes the statistics NaN).
    """
    s = np.asarray(shadow, dtype=np.float64)
    r = np.asarray(reference, dtype=np.float64)
    if s.size == 0:
        return {"rmse": math.nan, "max_error": math.nan, "p99_error": math.nan, "leak_fraction": math.nan}
    e = s - r
    a = np.abs(e)
    finite = bool(np.isfinite(e).all())
    return {
        "rmse": float(np.sqrt(np.mean(e * e))),
        "max_error": float(a.max()) if finite else math.nan,
        "p99_error": float(np.percentile(a, 99)) if finite else math.nan,
        "leak_fraction": float(np.mean(e < -LEAK_THRESHOLD)) if finite else math.nan,
    }


def light_metrics(light, reference, scale=1.0):
    """Error statistics of a light quantity (in-scattered light, visibility) against the reference.

    The statistics of :func:`metrics` in units of ``scale`` (the scattering term's ``t_max``),
    for a quantity that leaks where it is *brighter* than the reference by more than
    :data:`LEAK_THRESHOLD`: the shadow intensities ``−light/scale`` and ``−reference/scale``
    (a constant offset, as in ``1 − light``, would cancel in every statistic).
    """
    return metrics(-np.asarray(light, dtype=np.float64) / scale, -np.asarray(reference, dtype=np.float64) / scale)


def _pair(a, name_a, b, name_b):
    from ._arrays import InputError

    a, b = np.asarray(a, dtype=np.float64).reshape(-1), np.asarray(b, dtype=np.float64).reshape(-1)
    if a.shape != b.shape:
        raise InputError(f"{name_b}: expected {a.size} pixels like {name_a}, got {b.size}")
    return a, b


def _tag(t):
    return f"{round(100 * t):g}pct"


def shadow_leak(shadow, reference, full_shadow=FULL_SHADOW, visible=VISIBLE):
    """Light leaking in HPG17's sense: light where the reference is in full shadow, by area and magnitude.

    Only the receiver pixels whose reference intensity is at least ``full_shadow``
    count (HPG17 §6: "light will leak onto fully shadowed surfaces"); penumbrae and
    lit pixels do not, so over-shadowing elsewhere cannot offset a leak and a
    softer edge is not counted as one. The leak of a pixel is
    ``max(0, reference − shadow)``: the light it receives that the reference says
    it should not.

    Returns
    -------
    dict with ``shadowed_pixels`` (how many count), ``leak_mean`` (mean leak over
    them: the magnitude), ``leak_max``, and per threshold ``t`` of ``visible``
    ``leak_area_{100 t}pct`` (the fraction of them leaking more than ``t``: the
    area). ``over_mean``: the mean of ``max(0, shadow − reference)`` over the
    pixels the reference leaves fully lit (reference ≤ 1 − ``full_shadow``), the
    opposite error (a depth bias trades one for the other). NaN where no pixel counts.
    """
    s, r = _pair(reference, "reference", shadow, "shadow")[::-1]
    full, lit = r >= full_shadow, r <= 1.0 - full_shadow
    leak = np.maximum(r[full] - s[full], 0.0)
    out = {"shadowed_pixels": int(full.sum()),
           "leak_mean": float(leak.mean()) if leak.size else math.nan,
           "leak_max": float(leak.max()) if leak.size else math.nan}
    for t in visible:
        out[f"leak_area_{_tag(t)}"] = float(np.mean(leak > t)) if leak.size else math.nan
    over = np.maximum(s[lit] - r[lit], 0.0)
    out["over_mean"] = float(over.mean()) if over.size else math.nan
    return out


def visible_differences(a, b, visible=VISIBLE, image_pixels=None):
    """Per-pixel differences in shadow intensity a viewer sees: HPG17 §5's count of pixels above 3 %.

    Returns a dict with ``max`` (largest ``|a − b|``), ``pixels`` (how many were
    compared), and per threshold ``t`` of ``visible`` ``above_{100 t}pct`` (the
    count of ``|a − b| > t``) and ``rate_{100 t}pct`` (that count over
    ``image_pixels``, the pixels of the whole image as the paper counts them;
    default: the pixels compared).
    """
    a, b = _pair(a, "a", b, "b")
    d = np.abs(a - b)
    n = int(d.size if image_pixels is None else image_pixels)
    out = {"max": float(d.max()) if d.size else math.nan, "pixels": int(d.size)}
    for t in visible:
        k = int(np.count_nonzero(d > t))
        out[f"above_{_tag(t)}"] = k
        out[f"rate_{_tag(t)}"] = k / n if n else math.nan
    return out


def shaded_image(gbuffer, shadow):
    """An LDR grey image of the camera view: ``0.1 + 0.8 |n·l| (1 − shadow)`` on receivers.

    Occluders are flat grey (0.35), the background black, receivers outside the
    shadow map unshadowed. Returns (H, W, 3) float32 in [0, 1].
    """
    w, h = gbuffer.resolution
    kind = gbuffer.kind.reshape(-1)
    img = np.zeros(h * w)
    img[kind == OCCLUDER] = 0.35
    # Receivers outside the map: Lambert unknown here, shade them mid-grey unshadowed.
    img[kind == OUTSIDE_LIGHT] = 0.5
    lit = 1.0 - np.clip(np.nan_to_num(np.asarray(shadow, dtype=np.float64), nan=1.0), 0, 1)
    img[gbuffer.pixel] = 0.1 + 0.8 * gbuffer.lambert * lit
    return np.repeat(np.clip(img, 0, 1).reshape(h, w, 1), 3, axis=2).astype(np.float32)


def flip_mean(reference_image, test_image):
    """Mean ꟻLIP (LDR) of ``test_image`` against ``reference_image``; NaN if flip-evaluator is missing.

    Equal images are 0 without asking ꟻLIP (its colour and feature differences are 0 at every
    pixel, so its error is 0 there; tested against ꟻLIP's own value): a technique that is its own
    reference (PCF against the PCF reference where no receiver slope separates them) costs nothing.
    """
    try:
        import flip_evaluator
    except ImportError:
        return math.nan
    if np.array_equal(reference_image, test_image):
        return 0.0
    _, mean, _ = flip_evaluator.evaluate(np.ascontiguousarray(reference_image), np.ascontiguousarray(test_image),
                                         "LDR", applyMagma=False)
    return float(mean)


def flip_available() -> bool:
    """True when the package ``flip-evaluator`` (NVIDIA ꟻLIP) is installed."""
    try:
        import flip_evaluator  # noqa: F401
        return True
    except ImportError:
        return False
