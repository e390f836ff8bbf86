"""Which stages a scene needs: the graph of the base stages, each requested technique's and its reference's.

:func:`plan` builds one :class:`~moments_ref.pipeline.graph.StageGraph` from what every
requested technique declares (``Technique.stages``) and from the reference it is
measured against (``Technique.truth``); nothing runs yet.

References
----------
.. [1] VWSS: Adam Marrs, Benjamin Watson and Christopher Healey. 2018. *View-warped Multi-view Soft
       Shadowing for Local Area Lights*. Journal of Computer Graphics Techniques (JCGT) 7, 3, 1–28.
       http://jcgt.org/published/0007/03/01/
"""

from __future__ import annotations

import numpy as np

from .._arrays import InputError
from ..gpu.bluenoise import blue_noise_textures, frame_noise
from ..scene.gbuffer import GBuffer, camera_gbuffer, depth_gbuffer, light_projection
from .. import techniques as _techniques
from ..techniques import PlanContext, Stage, Technique, get_reference
from ..techniques._interface import GBUFFER, NOISE, PROJECTION, SHADOW_MAP, TRANSLUCENCY
from ..techniques.translucent import translucency_pass
from .graph import StageGraph
from .records import RunPlan, Settings, TechniquePlan, settings_of

__all__ = ["outputs_of", "AREA_OUTPUTS", "AREA_BITS_PER_TEXEL", "SCATTERING_OUTPUTS", "GBUFFERS", "check_scene", "plan"]


def outputs_of(reference) -> tuple:
    """Names of the registered techniques measured against ``reference`` (registration order)."""
    return tuple(n for n, t in _techniques.TECHNIQUES.items() if t.truth == reference)


#: Outputs shaded under an area light against the MVR reference (``outputs_of("mvr")``).
AREA_OUTPUTS = outputs_of("mvr")
#: Storage per texel: msm_soft four uint32 SAT channels; PCSS one float32 map; VWSS and
#: MVR a float32 depth per texel of each of their N light-sample maps.
AREA_BITS_PER_TEXEL = {n: _techniques.get(n).bits_per_texel for n in AREA_OUTPUTS}
#: Outputs measured against converged ray marching (``outputs_of("raymarch")``).
SCATTERING_OUTPUTS = outputs_of("raymarch")


#: The G-buffers of :attr:`Settings.gbuffer`: the stage holding the receivers every technique shades.
GBUFFERS = {"fragments": PROJECTION, "depth": "camera_depth_gbuffer"}

def check_scene(scene):
    """Refuse a scene the runner cannot shade, with the reason (InputError)."""
    name = getattr(scene, "name", "?")
    rec = getattr(scene, "receiver", None)
    if rec is None or rec.n_triangles == 0:
        raise InputError(f"scene {name!r}: no receiver (no object with role receiver or both): nothing to shade")
    if getattr(scene, "camera", None) is None:
        raise InputError(f"scene {name!r}: no camera: the report shades the camera's view")
    if hasattr(scene.camera, "check_sees"):
        scene.camera.check_sees(rec, f"scene {name!r}'s receivers")
    occ = getattr(scene, "occluder", None)
    if occ is None or occ.n_triangles == 0:
        raise InputError(f"scene {name!r}: no occluder: nothing casts a shadow")

# ---------------------------------------------------------------------------
# the stages every technique may use


def _shadow_map(scene, size, samples):
    return scene.shadow_map(size=size, samples=samples)[0]


def _layers(opaque, scene, clip_from_world):
    m = scene.occluder_mesh(translucent=True)
    alpha = scene.occluder_opacity[scene.occluder_translucent]
    return translucency_pass(opaque, m.vertices, m.triangles, alpha, clip_from_world)


def _noise(textures, gb, frame):
    w, h = gb.resolution
    return frame_noise(frame, (h, w), textures).reshape(h * w, -1)[gb.pixel]


def _depth_gbuffer(scene, resolution):
    width, height = resolution
    return depth_gbuffer(scene.receiver.vertices, scene.receiver.triangles, scene.camera.resized(resolution).clip_from_world(),
                         (height, width), scene.occluder.vertices, scene.occluder.triangles)


def _given(gbuffer):
    """The camera G-buffer the caller rendered (``Settings.camera_gbuffer``), as the stage's value."""
    return gbuffer


def _gbuffer_stage(ctx, given):
    """The camera G-buffer's stage: rendered, or the one the caller rendered (``Settings.camera_gbuffer``)."""
    if given is None:
        return Stage(GBUFFER, camera_gbuffer, bound=(("scene", ctx.scene), ("resolution", ctx.resolution)))
    if not isinstance(given, GBuffer) or tuple(given.resolution) != tuple(ctx.resolution):
        got = f"resolution {tuple(given.resolution)}" if isinstance(given, GBuffer) else type(given).__name__
        raise InputError(f"camera_gbuffer: expected the camera G-buffer of the run's resolution "
                         f"{tuple(ctx.resolution)} (scene.gbuffer.camera_gbuffer), got {got}")
    return Stage(GBUFFER, _given, bound=(("gbuffer", given),))


def _base_stages(ctx, given=None):
    scene = ctx.scene
    light = ctx.light_clip_from_world
    out = [Stage(SHADOW_MAP, _shadow_map, bound=(("scene", scene), ("size", ctx.size), ("samples", ctx.samples))),
           _gbuffer_stage(ctx, given),
           Stage(PROJECTION, light_projection, (GBUFFER,), bound=(("clip_from_world", light), ("size", ctx.size))),
           Stage(GBUFFERS["depth"], _depth_gbuffer, bound=(("scene", scene), ("resolution", ctx.resolution))),
           Stage("bluenoise_textures", blue_noise_textures, bound=(("count", ctx.noise_tiles),)),
           Stage(NOISE, _noise, ("bluenoise_textures", PROJECTION), bound=(("frame", ctx.frame),))]
    if ctx.translucent:
        out.append(Stage(TRANSLUCENCY, _layers, (SHADOW_MAP,), bound=(("scene", scene), ("clip_from_world", light))))
    return out


def _known_outputs():
    groups = {}
    for n, t in _techniques.TECHNIQUES.items():
        groups.setdefault(get_reference(t.truth).label, []).append(n)
    parts = [f"{label}: {', '.join(ns)}" for label, ns in groups.items()]
    return "known techniques: " + "; ".join([parts[0].split(": ", 1)[1]] + parts[1:])


def _requested(scene, outputs):
    names = list({getattr(n, "name", n): n for n in (scene.outputs if outputs is None else outputs)}.values())
    if not names:
        raise InputError(f"outputs: scene {scene.name!r} requests no outputs; {_known_outputs()}")
    for n in names:
        if not isinstance(n, Technique) and n not in _techniques.TECHNIQUES:
            raise InputError(f"technique: unknown technique {n!r}; {_known_outputs()}")
    techs = [_techniques.get(n) for n in names]
    for t in techs:
        reason = t.refusal(scene)
        if reason:
            raise InputError(f"outputs: {reason}")
    return techs


def _context(scene, st: Settings):
    size = tuple(scene.shadow_map_size) if st.shadow_map_size is None else (
        (st.shadow_map_size, st.shadow_map_size) if np.isscalar(st.shadow_map_size) else tuple(st.shadow_map_size))
    if st.gbuffer not in GBUFFERS:
        raise InputError(f"gbuffer: expected one of {', '.join(GBUFFERS)}, got {st.gbuffer!r}")
    if hasattr(scene, "at_shadow_map"):  # objects placed in texels of the map this run rasterizes
        scene = scene.at_shadow_map(size)
    return PlanContext(scene=scene, size=size, samples=scene.msaa if st.msaa is None else int(st.msaa),
                       resolution=tuple(scene.camera.resolution) if st.resolution is None else tuple(st.resolution),
                       params={**scene.params, **(st.params or {})},
                       translucent=bool(np.any(scene.occluder_translucent)),
                       light_clip_from_world=scene.light_clip_from_world(), noise_tiles=st.noise_tiles,
                       frame=st.frame, full=bool(st.full), receivers=GBUFFERS[st.gbuffer])


def _check_receivers(g, ctx, name, shade):
    """Refuse a technique that shades other receivers than the run's G-buffer holds."""
    if ctx.receivers != PROJECTION and PROJECTION in g.order([shade]):
        raise InputError(f"technique: {name!r} looks its texture up at the receivers inside the light's shadow map; "
                         "Settings(gbuffer='depth') serves only techniques that shade world positions")


def plan(scene, outputs=None, settings=None, **old) -> RunPlan:
    """Build the stage graph of a run without running anything.

    Parameters
    ----------
    scene : Scene
    outputs : list of str or Technique, optional
        Registered technique names, or techniques built by the caller (variants
        that are not registered); default the scene's ``outputs``.
    settings : Settings, optional
        (The old keyword arguments and a dict of reference overrides still work, deprecated.)

    Returns
    -------
    RunPlan
    """
    st = settings_of(settings, old, "plan")
    check_scene(scene)
    techs = _requested(scene, outputs)
    ctx = _context(scene, st)
    overrides = dict(st.overrides or {})
    g = StageGraph()
    for stage in _base_stages(ctx, st.camera_gbuffer):
        g.add(stage)
    cfgs, targets, plans = {}, [], {}
    for t in techs:
        ref = get_reference(t.truth)
        if ref.name not in cfgs:
            cfgs[ref.name] = ref.settings(ctx, overrides.get(ref.option or ref.name))
        p = t.stages(t, ctx, cfgs[ref.name])
        for stage in p.stages:
            g.add(stage)
        _check_receivers(g, ctx, t.name, p.shade)
        targets.append(p.shade)
        ref_stage = ref.stage(ctx, cfgs[ref.name], t) if st.reference else None
        ref_key = None if ref_stage is None else g.add(ref_stage)
        if ref_key is not None:
            targets.append(ref_key)
        plans[t.name] = TechniquePlan(name=t.name, texel=tuple(p.texel), shade=p.shade, reference=ref_key,
                                      truth=ref.name, bits=t.bits_per_texel if p.bits is None else p.bits,
                                      result=p.result, reference_result=ref.result)
    return RunPlan(graph=g, targets=list(dict.fromkeys(targets)), context=ctx, techniques=plans, settings=cfgs)

