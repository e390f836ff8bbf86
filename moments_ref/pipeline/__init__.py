"""The lazy runner: a scene and the outputs it asks for -> only the stages they need.

A scene file names its ``outputs`` (technique names, :mod:`moments_ref.techniques`).
:func:`plan` builds one graph of stages (:class:`~moments_ref.techniques.Stage`,
each under its key: name plus parameters) from what every requested technique
declares (``Technique.stages``) and from the reference it is measured against
(``Technique.truth``, a registered :class:`~moments_ref.techniques.Reference`);
:func:`run` walks back from the techniques' shade stages and their reference
stages and computes exactly the stages on those paths, each once. There is no
special path for any kind of technique.

The stages every technique may build on:

==========================  ======================================================
``raster_shadow_map``       opaque occluders into the light's (H, W, S) depth map
``translucency_pass``       layers of translucent occluders (only if the scene has
                            translucent geometry and a technique or the reference
                            renders it)
``camera_gbuffer``          receiver points seen by the camera (nearest fragment
                            per pixel of the scene rasterized from the camera,
                            :func:`moments_ref.scene.gbuffer.camera_gbuffer`)
``light_projection``        their texel coordinates and depth in the shadow map:
                            the receivers every technique shades
``camera_depth_gbuffer``    with ``Settings(gbuffer="depth")`` instead: every
                            receiver pixel, unprojected from a depth buffer
                            (:func:`moments_ref.scene.gbuffer.depth_gbuffer`, VWSS
                            §4; only for techniques that shade world positions)
``bluenoise_textures``      HPG17 §4.2 texture array (only for dithered techniques)
``frame_noise``             the per-pixel blue noise of frame 0
==========================  ======================================================

Then, per technique, its own stages: for the shadow-map techniques their steps
(e.g. ``resolve_moments``, or ``compute_moments`` for a 1× map: nothing to
resolve; ``blur_moments``, ``quantize_affine64``, ``onchip_resolve_blur``,
``quantize_nlq64``; equal keys are computed once and shared: msm64, msm128 and
vsm share the resolve and the blur, nlq64 and nlq64_dither the texture) and
``shade_<technique>``; for the area-light techniques the stages listed in
:mod:`moments_ref.techniques.area`; for the scattering techniques those of
:mod:`moments_ref.techniques.scattering`. The references add
``reference_pcf_bias<b>`` (the filtered hard shadow at depth bias b, a stage
parameter; ``translucency_reference_bias<b>`` with translucent occluders),
``mvr_reference_vwss`` (multi-view rasterization with many light samples) and
``scattering_raymarch_reference``.

:attr:`RunResult.stages` records the stages that ran, in order; a stage name
contains ``translucen`` only for translucency work and ``vwss`` only for
multi-view work, and there is no multi-view work without an area light:
techniques are refused, with the reason, on scenes they cannot run on
(``Technique.refusal``).

Lights. A directional light gets its fitted orthographic map (HPG17 §5). An area
light (scene ``knot``) is used as a spot light from its centre by the hard-shadow
techniques (:meth:`moments_ref.scene.Scene.light_clip_from_world`).

Settings and records. :func:`plan` and :func:`run` take a :class:`Settings` (map size,
MSAA, camera, reference overrides, repeats, clock, ...); :func:`plan` returns a
:class:`RunPlan` with one :class:`TechniquePlan` per technique (its texture stages,
its shade stage, its reference stage); :func:`run` returns a :class:`RunResult`.

The package, along its seams: :mod:`~moments_ref.pipeline.planner` (which stages a
scene and its outputs need: :func:`plan`, :func:`check_scene`),
:mod:`~moments_ref.pipeline.runner` (running them: :func:`run`),
:mod:`~moments_ref.pipeline.graph` (the stage graph that computes each stage once and
times it: the run's cache), :mod:`~moments_ref.pipeline.records` (:class:`Settings`,
:class:`RunPlan`, :class:`RunResult`) and :mod:`~moments_ref.pipeline.scattering`
(:func:`run_scattering`, a view of :func:`run`).

References
----------
.. [1] VWSS: Adam Marrs, Benjamin Watson and Christopher Healey. 2018. *View-warped Multi-view Soft
       Shadowing for Local Area Lights*. Journal of Computer Graphics Techniques (JCGT) 7, 3, 1–28.
       http://jcgt.org/published/0007/03/01/
.. [2] HPG17: Christoph Peters. 2017. *Non-Linearly Quantized Moment Shadow Maps*. In Proceedings
       of High Performance Graphics (HPG '17). ACM. The non-linear quantization Φ, Ψ4, Algorithms
       1–3, the texel formats and the compute shader of §4.1.
.. [3] Slides: Christoph Peters. *Rendering antialiased shadows with moment shadow mapping*,
       lecture slides (PDF version, with notes) on moment shadow mapping, translucent occluders,
       moment soft shadow mapping and prefiltered single scattering; http://MomentsInGraphics.de/.
       Cited by slide title, e.g. Slides, "Bias the moments".
"""

from ..scene.gbuffer import GBuffer
from ..techniques import reduced_settings
from ..techniques.area import area_settings
from .planner import AREA_BITS_PER_TEXEL, AREA_OUTPUTS, SCATTERING_OUTPUTS, check_scene, outputs_of, plan
from .records import RunPlan, RunResult, Settings, TechniquePlan
from .runner import run
from .scattering import ScatteringResult, run_scattering, scattering_stages

__all__ = ["GBuffer", "Settings", "TechniquePlan", "RunPlan", "RunResult", "run", "plan", "reduced_settings", "check_scene",
           "AREA_OUTPUTS", "AREA_BITS_PER_TEXEL", "area_settings", "SCATTERING_OUTPUTS", "ScatteringResult",
           "scattering_stages", "run_scattering", "outputs_of"]
