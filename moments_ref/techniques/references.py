"""The filtered hard shadow: the reference of the shadow-map techniques, and the intensity metric.

Reference ``pcf`` (:data:`PCF_REFERENCE`): the 9×9-Gaussian PCF over the MSAA
samples with receiver-plane depth (Isidoro 2006): each sample of each tap is
compared with the receiver plane's depth at that sample,
``zf + gx·(x − u) + gy·(y − v) − b`` (``GBuffer.gradient``,
:func:`moments_ref.techniques.pcf.pcf_filtered`), with only the technique's
constant bias ``b`` (10⁻³) against depth quantization. That is the exact
filtered hard shadow of the planar receiver: no self-shadowing of a plane lit
at an angle and no slope bias, so contact shadows are in the reference, and PCF
(the technique, with HPG17 §5's receiver-slope bias) loses them as its error.
With translucent occluders the filtered product of transmittances, alike.
Stage ``reference_pcf_bias<b>`` (or ``translucency_reference_bias<b>``): the bias is a stage parameter, so techniques
with equal biases share the stage.

:func:`intensity_metric` is the metric of every reference whose values are
shadow intensities of the receiver pixels (this one and ``mvr``): the
statistics of :func:`moments_ref.metrics.metrics` and the mean ꟻLIP between the
images shaded with the technique and with the reference.

References
----------
.. [1] Isidoro 2006: John R. Isidoro. 2006. *Shadow Mapping: GPU-based Tips and Techniques*. Game
       Developers Conference 2006 (receiver plane depth bias: the receiver's depth at each filter
       tap from its depth gradient in shadow-map space)
.. [2] HPG17: Christoph Peters. 2017. *Non-Linearly Quantized Moment Shadow Maps*. In Proceedings
       of High Performance Graphics (HPG '17). ACM. The non-linear quantization Φ, Ψ4, Algorithms
       1–3, the texel formats and the compute shader of §4.1.
.. [3] FLIP: Pontus Andersson, Jim Nilsson, Tomas Akenine-Möller, Magnus Oskarsson, Kalle Åström
       and Mark D. Fairchild. 2020. *ꟻLIP: A Difference Evaluator for Alternating Images*.
       Proceedings of the ACM on Computer Graphics and Interactive Techniques (HPG 2020) 3, 2. Used
       through the package ``flip-evaluator``.
"""

from __future__ import annotations

from ..scene.gbuffer import SLOPE_BIAS_TEXELS
from ..metrics import flip_mean, metrics, shaded_image
from ._errormaps import error_maps
from ._interface import PROJECTION, SHADOW_MAP, TECHNIQUES, TRANSLUCENCY, Reference, Stage, register_reference
from .pcf import pcf_filtered

__all__ = ["intensity_metric", "error_figure", "depth_bias_text", "PCF_REFERENCE"]


def intensity_metric(result, name):
    """Error columns of technique ``name``: intensity statistics and mean ꟻLIP of the shaded images."""
    shadow, ref = result.shadow[name], result.reference[name]
    out = metrics(shadow, ref)
    out["flip_mean"] = flip_mean(shaded_image(result.gbuffer, ref), shaded_image(result.gbuffer, shadow))
    return out


def _pcf(maps, gb, bias):
    # Receiver-plane depth at every tap (Isidoro 2006) minus the technique's constant bias; no slope term.
    return pcf_filtered(maps, gb.uv, gb.z_ndc_light - bias, gradient=gb.gradient)


def _reference_stage(ctx, settings, technique):
    name = "translucency_reference" if ctx.translucent else "reference_pcf"
    src = TRANSLUCENCY if ctx.translucent else SHADOW_MAP
    return Stage(name, _pcf, (src, PROJECTION), params=(("bias", technique.depth_bias),))


def depth_bias_text(names=None):
    """One sentence for the report's settings: which depth bias each technique uses, and why.

    ``names`` (default: every registered technique measured against ``pcf``) are
    split by their ``slope_bias``.
    """
    ts = [t for t in TECHNIQUES.values() if t.truth == "pcf" and (names is None or t.name in names)]
    slope = ", ".join(t.name for t in ts if t.slope_bias) or "none"
    const = ", ".join(t.name for t in ts if not t.slope_bias) or "none"
    value = " or ".join(f"{b:g}" for b in sorted({t.depth_bias for t in ts})) or "1e-3"
    return (f"Depth bias (HPG17 §5): the filterable techniques ({const}) use only the constant {value} (\"With "
            "non-linear quantization we use a constant depth bias of 10^-3 depth units for all results\"); "
            f"PCF ({slope}) adds a receiver-slope term of {SLOPE_BIAS_TEXELS:.3g} (4.5√2) texels times the "
            "receiver's depth change per texel, HPG17's \"higher depth bias\" of PCF, which costs it contact "
            "shadows. The 9×9 PCF reference compares each tap with the receiver plane's depth there (receiver-plane "
            "depth, Isidoro 2006) and the constant bias alone: the exact filtered hard shadow of the planar "
            "receiver, with its contact shadows and without self-shadowing of planes lit at an angle.")


def error_figure(result, names):
    """The shaded reference, each technique's shaded image and its signed error (:func:`._errormaps.error_maps`)."""
    return error_maps(result, names, "9×9 PCF", f"{result.scene.name}: signed error against the filtered hard "
                      "shadow (9×9 Gaussian PCF, receiver-plane depth, each technique's constant bias)")


def _figures(result, names):
    return {f"errors_{result.scene.name}.png": error_figure(result, names)}


#: The filtered hard shadow of the receiver plane at each technique's constant depth bias.
PCF_REFERENCE = register_reference(Reference(
    name="pcf", label="hard-shadow techniques", stage=_reference_stage, metric=intensity_metric,
    figures=_figures,
))
