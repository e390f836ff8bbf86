"""The filtered hard shadow: the reference of the shadow-map techniques, and the intensity metric.

Reference ``pcf`` (:data:`PCF_REFERENCE`): the 9×9-Gaussian PCF over the MSAA
samples at the technique's own depth bias (:func:`moments_ref.techniques.pcf.pcf_filtered`),
the exact filtered hard shadow ``Z(z < zf)``; with translucent occluders the
filtered product of transmittances. Stage ``reference_pcf_bias<b>`` (or
``translucency_reference_bias<b>``): the bias is a stage parameter, so techniques
with equal biases share the stage.

:func:`intensity_metric` is the metric of every reference whose values are
shadow intensities of the receiver pixels (this one and ``mvr``): the
statistics of :func:`moments_ref.metrics.metrics` and the mean ꟻLIP between the
images shaded with the technique and with the reference.

References
----------
HPG17, FLIP : see docs/bib.md.
"""

from __future__ import annotations

import numpy as np

from ..metrics import flip_mean, metrics, shaded_image
from ._interface import PROJECTION, SHADOW_MAP, TRANSLUCENCY, Reference, Stage, register_reference
from .pcf import pcf_filtered

__all__ = ["intensity_metric", "error_figure", "PCF_REFERENCE"]


def intensity_metric(result, name):
    """Error columns of technique ``name``: intensity statistics and mean ꟻLIP of the shaded images."""
    shadow, ref = result.shadow[name], result.reference[name]
    out = metrics(shadow, ref)
    out["flip_mean"] = flip_mean(shaded_image(result.gbuffer, ref), shaded_image(result.gbuffer, shadow))
    return out


def _pcf(maps, gb, bias):
    return pcf_filtered(maps, gb.uv, gb.depth - bias)


def _reference_stage(ctx, settings, technique):
    name = "translucency_reference" if ctx.translucent else "reference_pcf"
    src = TRANSLUCENCY if ctx.translucent else SHADOW_MAP
    return Stage(name, _pcf, (src, PROJECTION), params=(("bias", technique.depth_bias),))


def error_figure(result, names):
    """``|shadow − reference|`` of each technique on the camera view."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    ncols = min(4, len(names))
    nrows = -(-len(names) // ncols)
    w, h = result.gbuffer.resolution
    fig, axes = plt.subplots(nrows, ncols, figsize=(3.2 * ncols, 3.2 * nrows * h / w + 0.6), squeeze=False)
    im = None
    for ax in axes.ravel():
        ax.axis("off")
    for ax, n in zip(axes.ravel(), names):
        img = np.full(h * w, np.nan)
        img[result.gbuffer.pixel] = np.abs(result.shadow[n] - result.reference[n])
        im = ax.imshow(img.reshape(h, w), cmap="magma", vmin=0, vmax=0.5, interpolation="nearest")
        ax.set_title(n, fontsize="small")
    fig.suptitle(f"{result.scene.name}: |shadow − reference| (the filtered hard shadow)")
    if im is not None:
        fig.colorbar(im, ax=axes.ravel().tolist(), shrink=0.8)
    return fig


def _figures(result, names):
    return {f"errors_{result.scene.name}.png": error_figure(result, names)}


#: The filtered hard shadow at each technique's depth bias.
PCF_REFERENCE = register_reference(Reference(
    name="pcf", label="hard-shadow techniques", stage=_reference_stage, metric=intensity_metric,
    figures=_figures,
))
