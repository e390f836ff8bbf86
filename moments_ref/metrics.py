"""Error metrics of shadow images: intensity statistics, the shaded LDR image, NVIDIA ꟻLIP.

Shared by the references of :mod:`moments_ref.techniques` (each declares its
metric from these) and re-exported by :mod:`moments_ref.report`.

References
----------
.. [1] FLIP: Pontus Andersson, Jim Nilsson, Tomas Akenine-Möller, Magnus Oskarsson, Kalle Åström
       and Mark D. Fairchild. 2020. *ꟻLIP: A Difference Evaluator for Alternating Images*.
       Proceedings of the ACM on Computer Graphics and Interactive Techniques (HPG 2020) 3, 2. Used
       through the package ``flip-evaluator``.
"""

from __future__ import annotations

import math

import numpy as np

from .scene.gbuffer import OCCLUDER, OUTSIDE_LIGHT

__all__ = ["LEAK_THRESHOLD", "metrics", "light_metrics", "shaded_image", "flip_mean", "flip_available"]

#: A pixel leaks when it is lit more than this above the reference.
LEAK_THRESHOLD = 0.05


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
    """Mean ꟻLIP (LDR) of ``test_image`` against ``reference_image``; NaN if flip-evaluator is missing."""
    try:
        import flip_evaluator
    except ImportError:
        return math.nan
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
