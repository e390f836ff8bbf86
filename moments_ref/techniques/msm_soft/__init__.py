"""Moment soft shadow mapping: PCSS with a summed-area table of moments (Slides, "Moment soft shadow mapping").

Percentage-closer soft shadows [Fernando 2005] in three steps (Slides,
"Percentage-closer soft shadows"), each replaced by a constant-time query:

1. **Blocker search** (Slides, "Moment-based blocker search"): one interpolated
   query of the summed-area table (:mod:`moments_ref.gpu.sat`) over the search
   region gives the moments of its depth distribution; Algorithm 1's canonical
   representation ``(zf, z1, z2; w0, w1, w2)`` (:func:`moments_ref.msm.canonical_representation`)
   reconstructs it with three depths, and the average blocker depth is

       z_b = (Σ_{l: z_l < zf} w_l z_l + ε zf) / (Σ_{l: z_l < zf} w_l + ε),  ε = 10⁻³,

   the support points in front of the fragment, with "a little bias towards the
   depth of the pixel" for a small denominator.
2. **Penumbra estimation** (Slides, "Penumbra estimation and filtering"), as in
   PCSS with parallel planes: ``w_penumbra = (d_r − d_b)·l / d_b``.
3. **Filtering**: a single interpolated SAT query over the filter region (a
   rectangle: "rectangular filter → rectangular light source") gives the moments
   for Algorithm 1 (:func:`moments_ref.msm.shadow_intensity`, lower bound) after
   biasing ("The moment bias can be smaller here", see :func:`soft_bias`).

Geometry and units
------------------
The single shadow map is the perspective view from the area light's centre
along its normal (:meth:`moments_ref.scene.Scene.light_clip_from_world`, or
:meth:`moments_ref.techniques.vwss.LightSamples.center_clip_from_world`); its samples and the
fragments' depths arrive as NDC depths z ∈ [−1, 1] (the package's depth convention,
docs/architecture.md). Distances
``d`` are view depths in world units along the light normal,
``d = 2 f n / ((f + n) − z (f − n))`` (:meth:`LightFrustum.d_view_from_ndc`,
:func:`moments_ref.scene.depth.d_view_from_ndc`).

Stored depth. By default (``depth="linear"``) the texture holds the moments of
the depth *linear in d*, remapped to [−1, 1]: ``z_lin = 2 (d − n)/(f − n) − 1``
(empty texels, NDC 1, stay at 1). Perspective NDC depth crowds everything far
from the near plane against 1, where the biased moments cannot separate an
occluder from the receiver: on the ``column`` artifact scene (column at d = 3.6,
receiver at 4, near 0.5, far 5: NDC 0.914 and 0.944) the blocker depth
reconstructed from NDC moments comes out between 2.4 and 3.1 instead of 3.6.
``depth="ndc"`` keeps the NDC depth for comparison. The blocker depth ``z_b``
is averaged in the stored depth, as the slides average the stored depths, and
then converted to ``d_b``.

For a receiver at view depth ``d_r`` the light rectangle (extent ``l`` along a
map axis) seen through the plane at depth ``d`` covers, in the map, a rectangle
centred on the receiver's texel position with full extent ``l (1/d − 1/d_r)``
in tan units, times ``k = W / (2 tan(fov/2))`` texels per tan unit:

* search region: at the near plane, ``d = near`` (the largest region that can
  hold a blocker, as :func:`moments_ref.techniques.vwss.pcss`);
* filter region: at ``d = d_b``; this is the PCSS penumbra width
  ``w_penumbra = (d_r − d_b) l / d_b`` on the receiver, projected (divided by
  ``d_r``). For an occluder parallel to the light it is exactly the set of
  occluder points between the receiver and the light, which makes the result
  exact for one planar parallel occluder (up to texels and the bias).

Regions are clamped (documented clamp, counted in the details) to at least one
texel (the query is then bilinear filtering: a hard shadow) and at most
``max_kernel`` texels per side, the SAT's largest kernel ``n = max_kernel²``;
rectangles reaching over the map's border are intersected with the map
(:func:`moments_ref.gpu.sat.interpolated_mean` with ``clamp=True``). Fragments
outside the map or behind the light are lit.

The texture stores the optimized basis (:func:`moments_ref.affine.to_optimized`)
of the per-texel moments (MSAA resolved, unfiltered: the SAT is the filter) in
four uint32 channels, 128 bits per texel.

Package layout: :mod:`.shadow` (the method: frustum, SAT texture, blocker
search, penumbra, filtering), :mod:`.artifacts` (the artifacts the slides name,
measured on synthetic scenes with exact references); here the registered
technique ``msm_soft`` and its pipeline stages.

References
----------
.. [1] Slides: Christoph Peters. *Rendering antialiased shadows with moment shadow mapping*,
       lecture slides (PDF version, with notes) on moment shadow mapping, translucent occluders,
       moment soft shadow mapping and prefiltered single scattering; http://MomentsInGraphics.de/.
       Cited by slide title, e.g. Slides, "Bias the moments".
.. [2] Fernando 2005: Randima Fernando. 2005. *Percentage-Closer Soft Shadows*. In ACM SIGGRAPH
       2005 Sketches. https://doi.org/10.1145/1187112.1187153 (PCSS)
.. [3] MSM-JCGT, Peters et al. 2017: Christoph Peters, Cedrick Münstermann, Nico Wetzstein and
       Reinhard Klein. 2017. *Improved Moment Shadow Maps for Translucent Occluders, Soft Shadows
       and Single Scattering*. Journal of Computer Graphics Techniques (JCGT) 6, 1, 17–67.
       http://jcgt.org/published/0006/01/03/
.. [4] HPG17: Christoph Peters. 2017. *Non-Linearly Quantized Moment Shadow Maps*. In Proceedings
       of High Performance Graphics (HPG '17). ACM. The non-linear quantization Φ, Ψ4, Algorithms
       1–3, the texel formats and the compute shader of §4.1.
"""


from __future__ import annotations

import numpy as np

from ..._arrays import InputError
from ..._shim import renamed_keys
from .._interface import PROJECTION, Plan, Stage, Step, Technique, register
from ..area import CENTER_MAP, center_map_stages
from .artifacts import (ARTIFACT_SCENES, artifact_images, artifact_measurements, ray_cast_visibility,
                        report_artifacts)
from .shadow import (DEPTH_BIAS, EPSILON, MAX_AUTO_KERNEL, LightFrustum, SoftShadowMap, average_blocker_depth,
                     penumbra_width, precision_bits_text, prepare, prepare_moments, shade_points, soft_bias,
                     soft_shadow)

__all__ = [
    "EPSILON",
    "MAX_AUTO_KERNEL",
    "DEPTH_BIAS",
    "soft_bias",
    "LightFrustum",
    "SoftShadowMap",
    "prepare",
    "prepare_moments",
    "average_blocker_depth",
    "penumbra_width",
    "soft_shadow",
    "shade_points",
    "ray_cast_visibility",
    "ARTIFACT_SCENES",
    "artifact_measurements",
    "artifact_images",
    "MSM_SOFT",
]

_ = (EPSILON, MAX_AUTO_KERNEL, LightFrustum, SoftShadowMap, average_blocker_depth, penumbra_width,
     precision_bits_text, prepare_moments, soft_bias, ARTIFACT_SCENES, artifact_images, artifact_measurements,
     ray_cast_visibility)  # re-exported


# ---------------------------------------------------------------------------
# The shared technique interface (moments_ref.techniques)


def _params_light(params):
    params = renamed_keys(params, "params", view_proj="clip_from_world")
    scene = params.get("scene")
    light = params.get("light", getattr(scene, "light", None))
    vp = params.get("clip_from_world")
    if vp is None and scene is not None:
        vp = scene.light_clip_from_world()
    if light is None or vp is None:
        raise InputError("params: msm_soft needs the area light and its centre's view: pass params "
                         "{'scene': scene} or {'light': AreaLight, 'clip_from_world': (4, 4)}")
    return light, vp


def _build_step(samples, params):
    light, vp = _params_light(params)
    return prepare(samples, light, vp, params.get("max_kernel"), params.get("msm_soft_depth", "linear"))


def _steps(samples, layered):
    """One step, ``msm_soft_sat``: linear depth, resolve, optimized basis, SAT (:func:`prepare`)."""
    return (Step("msm_soft_sat", _build_step),)


def _lookup(texture, uv, zf, noise):
    # Technique.shadow subtracted DEPTH_BIAS; the receiver itself lies at zf + DEPTH_BIAS.
    dr = texture.frustum.d_view_from_ndc(np.asarray(zf, np.float64) + DEPTH_BIAS)
    return soft_shadow(texture, uv, zf, d_view_receiver=dr, dtype=np.float32)


def _sat_stage(c):
    return prepare(c[1], c[0].light, c[0].center_clip_from_world())


def _shade_stage(c, tex, gb, bias):
    return 1.0 - shade_points(c[0], tex, gb.position, bias=bias)


def _pipeline_stages(technique, ctx, cfg):
    """The centre map (shared with PCSS), ``msm_soft_sat`` (:func:`prepare`) and ``shade_msm_soft``."""
    sat = Stage("msm_soft_sat", _sat_stage, (CENTER_MAP,))
    shade = Stage("shade_msm_soft", _shade_stage, (CENTER_MAP, sat.key, PROJECTION), bound=(("bias", cfg["bias"]),))
    return Plan(center_map_stages(ctx, cfg) + (sat, shade), (CENTER_MAP, sat.key), shade.key)


#: Moment soft shadow mapping: four uint32 SAT channels = 128 bits per texel.
MSM_SOFT = register(Technique(
    name="msm_soft", bits_per_texel=128, depth_bias=DEPTH_BIAS, make_steps=_steps, lookup=_lookup,
    stages=_pipeline_stages, truth="mvr", artifacts=report_artifacts,
    description="moment soft shadow mapping: uint32 summed-area table of optimized moments, moment-based "
                "blocker search, PCSS penumbra, one interpolated query, Algorithm 1",
    reference="Peters et al. 2017 (JCGT); Slides, 'Moment soft shadow mapping'",
    four_moments=True, light_kinds=("area",),
))
