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

from ..metrics import flip_mean, metrics, shaded_image
from ._errormaps import error_maps
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
    """The shaded reference, each technique's shaded image and its signed error (:func:`._errormaps.error_maps`)."""
    return error_maps(result, names, "9×9 PCF", f"{result.scene.name}: signed error against the filtered hard "
                      "shadow (9×9 Gaussian PCF at each technique's depth bias)")


def _figures(result, names):
    return {f"errors_{result.scene.name}.png": error_figure(result, names)}


#: The filtered hard shadow at each technique's depth bias.
PCF_REFERENCE = register_reference(Reference(
    name="pcf", label="hard-shadow techniques", stage=_reference_stage, metric=intensity_metric,
    figures=_figures,
))
