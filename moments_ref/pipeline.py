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

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass, field

import numpy as np

from ._arrays import InputError
from ._shim import warn_renamed
from .gpu.bluenoise import blue_noise_textures, frame_noise
from .scene.gbuffer import GBuffer, camera_gbuffer, depth_gbuffer, light_projection
from . import techniques as _techniques
from .techniques import PlanContext, Stage, Technique, get_reference, reduced_settings
from .techniques._interface import GBUFFER, NOISE, PROJECTION, SHADOW_MAP, TRANSLUCENCY
from .techniques.area import area_settings
from .techniques.translucent import translucency_pass

__all__ = ["GBuffer", "Settings", "TechniquePlan", "RunPlan", "RunResult", "run", "plan", "reduced_settings", "check_scene", "AREA_OUTPUTS",
           "AREA_BITS_PER_TEXEL", "area_settings", "SCATTERING_OUTPUTS", "ScatteringResult", "scattering_stages",
           "run_scattering", "outputs_of"]


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


@dataclass(frozen=True)
class Settings:
    """The settings of one pipeline run (:func:`plan`, :func:`run`); None means the scene's own.

    Attributes
    ----------
    shadow_map_size : int or (H, W), optional
    msaa : int, optional
        Samples per shadow-map texel.
    resolution : (width, height), optional
        Camera resolution.
    reference : bool
        Also compute each technique's reference (its ``truth``).
    noise_tiles, frame : int
        Blue-noise tiles generated (HPG17 §4.2: 64) and the frame selecting tile and offsets.
    params : dict, optional
        Overrides of the scene's ``params`` passed to the technique steps.
    overrides : dict, optional
        Per reference option (``Reference.option``: ``area``, ``scattering``) its
        settings, e.g. ``{"area": {"light_samples": 8}}``
        (:func:`moments_ref.techniques.area.configure`,
        :func:`moments_ref.techniques.scattering.configure`).
    full : bool
        Paper-scale settings for the references that have them (``--full``).
    gbuffer : {"fragments", "depth"}
        The receivers: the camera's nearest fragments inside the light's shadow map
        (every technique), or every receiver pixel unprojected from a depth buffer
        (VWSS §4's deferred pass; techniques that shade world positions only).
    repeats : int
        Timed repeats of each stage of a technique's cost (its texture stages and
        its shade stage), after a warm-up run whose value is used; the seconds are
        their median (``spread``: median, min, max). The other stages run once.
    warmup : bool
        The warm-up run of the cost stages (default). Without it their first run is
        the first timed repeat: ``repeats=1`` runs each stage once (the
        ``moments-ref vwss`` comparison, whose stages hold N depth maps).
    clock : {"wall", "cpu"}
        What the seconds measure: wall-clock time (``time.perf_counter``) or the
        CPU time of this process, all its threads (``time.process_time``: not
        inflated when other processes compete for the cores; the report's choice).
    progress : bool
        A tqdm bar of the stages on stderr.
    """

    shadow_map_size: object = None
    msaa: int = None
    resolution: tuple = None
    reference: bool = True
    noise_tiles: int = 64
    frame: int = 0
    params: dict = None
    overrides: dict = None
    full: bool = False
    gbuffer: str = "fragments"
    repeats: int = 1
    warmup: bool = True
    clock: str = "wall"
    progress: bool = False

    def replace(self, **changes) -> "Settings":
        """A copy with ``changes``."""
        return dataclasses.replace(self, **changes)


#: The keyword arguments :func:`plan` and :func:`run` took before :class:`Settings` (deprecated).
_OLD_KEYWORDS = ("shadow_map_size", "msaa", "resolution", "reference", "noise_tiles", "frame", "params", "full",
                 "repeats", "clock", "progress", "area", "given")


def _settings_of(settings, old, fn):
    """The :class:`Settings` of a call; the old keywords (and ``settings`` as a dict of overrides) warn."""
    if isinstance(settings, Settings) and not old:
        return settings
    unknown = set(old) - set(_OLD_KEYWORDS)
    if unknown:
        raise TypeError(f"{fn}() got an unexpected keyword argument {sorted(unknown)[0]!r}")
    base = settings if isinstance(settings, Settings) else Settings()
    if settings is None and not old:
        return base
    warn_renamed(f"pipeline.{fn}(scene, outputs, <keywords>)", f"pipeline.{fn}(scene, outputs, Settings(...))")
    overrides = dict(base.overrides or {})
    if isinstance(settings, dict):  # the old per-reference overrides
        overrides.update(settings)
    if old.get("area") is not None:
        overrides["area"] = old["area"]
    kw = {k: v for k, v in old.items() if k not in ("area", "given")}
    return base.replace(overrides=overrides, **kw)


@dataclass(frozen=True)
class TechniquePlan:
    """What the graph computes for one technique.

    Attributes
    ----------
    name : str
    texel : tuple of str, the stage keys of its texture (its texel cost)
    shade : str, the key of its shade stage (its result; its fragment cost)
    reference : str or None, the key of its reference stage
    truth : str, the name of its reference
    bits : int, storage per texel
    result : {"intensity", "visibility"}, what its shade stage holds (:attr:`~moments_ref.techniques.Plan.result`)
    reference_result : {"intensity", "visibility"}, what its reference stage holds
    """

    name: str
    texel: tuple
    shade: str
    reference: str
    truth: str
    bits: int
    result: str = "intensity"
    reference_result: str = "intensity"


@dataclass
class RunPlan:
    """The stage graph of a run (:func:`plan`), nothing computed yet.

    Attributes
    ----------
    graph : the stages under their keys
    targets : list of str, the stages :func:`run` computes (and what they need)
    context : PlanContext, the resolved settings the techniques planned with
    techniques : dict name -> TechniquePlan, in request order
    settings : dict reference name -> its settings in this run
    """

    graph: object
    targets: list
    context: PlanContext
    techniques: dict
    settings: dict

    def __iter__(self):
        """The old ``(graph, targets, meta)`` triple (deprecated)."""
        warn_renamed("graph, targets, meta = pipeline.plan(...)", "pipeline.plan(...).graph, .targets, .techniques")
        ctx = self.context
        info = {n: {"steps": list(t.texel), "shade": t.shade, "reference": t.reference, "truth": t.truth}
                for n, t in self.techniques.items()}
        meta = {"size": ctx.size, "samples": ctx.samples, "resolution": ctx.resolution, "info": info,
                "techniques": list(self.techniques), "settings": self.settings, "area": self.settings.get("mvr", {}),
                "bits_per_texel": {n: t.bits for n, t in self.techniques.items()}}
        return iter((self.graph, self.targets, meta))


@dataclass
class RunResult:
    """What :func:`run` computed.

    Attributes
    ----------
    scene : Scene
    techniques : list of str
    stages : list of str, the stages that ran, in order
    seconds : dict stage -> seconds (the median of its timed repeats; wall-clock or CPU, ``run(clock=...)``)
    times : dict stage -> list of seconds: its timed repeats (after a warm-up run, ``Settings.warmup``) for
        the stages of the techniques' costs, the single run for the others
    repeats : int, timed repeats of the cost stages
    used_by : dict stage -> techniques whose result or reference needs it
    gbuffer : GBuffer (None when no technique shades the receiver pixels)
    shadow : dict technique -> its result (shadow intensity of the receiver pixels,
        or the scattering image)
    reference : dict technique -> its reference values
    texel_seconds : dict technique -> median over the repeats of the summed seconds of
        its texture stages (shared stages count fully for each technique that uses
        them: its cost alone)
    fragment_seconds : dict technique -> median seconds of its ``shade_`` stage
    spread : dict technique -> {"texel": (median, min, max), "fragment": (median, min, max)}
    shadow_map_size : (H, W); msaa : int
    values : dict stage -> result (textures, maps) for inspection
    bits_per_texel : dict technique -> storage per texel
    area : dict, the settings of the area-light outputs (:func:`area_settings`
        plus ``near``, ``far``, ``bias``), empty without them
    settings : dict reference name -> its settings in this run
    truth : dict technique -> the name of its reference
    plans : dict technique -> its :class:`TechniquePlan` (stage keys into ``values``)
    """

    scene: object
    techniques: list
    stages: list
    seconds: dict
    gbuffer: GBuffer
    shadow: dict
    reference: dict
    texel_seconds: dict
    fragment_seconds: dict
    shadow_map_size: tuple
    msaa: int
    values: dict = field(repr=False, default_factory=dict)
    bits_per_texel: dict = field(default_factory=dict)
    area: dict = field(default_factory=dict)
    settings: dict = field(default_factory=dict)
    truth: dict = field(default_factory=dict)
    times: dict = field(default_factory=dict)
    repeats: int = 1
    used_by: dict = field(default_factory=dict)
    spread: dict = field(default_factory=dict)
    plans: dict = field(default_factory=dict)

    def rows(self) -> list:
        """One results.csv row per technique: its reference's metric, bits and seconds (median, min, max)."""
        out = []
        for n in self.techniques:
            m = get_reference(self.truth[n]).metric(self, n)
            row = {"scene": self.scene.name, "technique": n, "bits_per_texel": self.bits_per_texel[n], **m}
            for kind in ("texel", "fragment"):
                med, lo, hi = self.spread[n][kind] if n in self.spread else (getattr(self, f"{kind}_seconds")[n],) * 3
                row.update({f"{kind}_seconds": med, f"{kind}_seconds_min": lo, f"{kind}_seconds_max": hi})
            row["repeats"] = self.repeats
            out.append(row)
        return out

    def stage_table(self) -> list:
        """Per stage that ran: ``{"stage", "seconds" (median), "min", "max", "used_by"}``."""
        out = []
        for k in self.stages:
            med, lo, hi = _spread(self.times.get(k, [self.seconds[k]]))
            out.append({"stage": k, "seconds": med, "min": lo, "max": hi, "used_by": list(self.used_by.get(k, []))})
        return out


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


class _Graph:
    """Stages under their keys, with dependencies, evaluated on demand, each once."""

    def __init__(self):
        self.nodes = {}

    def add(self, stage: Stage) -> str:
        """Add ``stage`` under its key; an equal stage again is shared, a different one raises."""
        key = stage.key
        old = self.nodes.get(key)
        if old is None:
            self.nodes[key] = stage
        elif not old.same_as(stage):
            raise ValueError(f"stage {key!r} added twice with different steps (dependencies {old.deps} and "
                             f"{stage.deps}); give one of them its own name or parameters")
        return key

    def order(self, targets):
        """Topological order of the stages ``targets`` need (dependencies first)."""
        seen, out = set(), []

        def visit(n, stack=()):
            if n in seen:
                return
            if n in stack:
                raise RuntimeError(f"cycle through stage {n}")
            for d in self.nodes[n].deps:
                visit(d, stack + (n,))
            seen.add(n)
            out.append(n)

        for t in targets:
            visit(t)
        return out

    def run(self, targets, progress=False, desc="stages", timed=(), repeats=1, clock=time.perf_counter,
            warmup=True):
        """Compute the stages ``targets`` need; return ``(order, values, times)``.

        A stage in ``timed`` runs once as a warm-up (its value is kept) and then
        ``repeats`` times more, each timed; ``times[stage]`` lists those seconds
        (one entry, the single run, for the other stages), read from ``clock``.
        Without ``warmup`` the first run is the first of the ``repeats``.
        """
        order = self.order(targets)
        values, times = {}, {}
        bar = _stage_bar(progress, len(order), desc)
        try:
            for name in order:
                stage = self.nodes[name]
                if bar is not None:
                    bar.set_postfix_str(name, refresh=False)
                args = [values[d] for d in stage.deps]
                t0 = clock()
                values[name] = stage(*args)
                times[name] = [clock() - t0]
                if name in timed:
                    more = [_timed(stage, args, clock) for _ in range(max(int(repeats), 1) - (not warmup))]
                    times[name] = more if warmup else times[name] + more
                if bar is not None:
                    bar.update(1)
        finally:
            if bar is not None:
                bar.close()
        return order, values, times


def _timed(stage, args, clock):
    t0 = clock()
    stage(*args)
    return clock() - t0


def _stage_bar(progress, total, desc):
    if not progress:
        return None
    import sys

    from tqdm import tqdm

    return tqdm(total=total, desc=desc, unit="stage", file=sys.stderr, leave=False)


def _clock(name):
    """The timer of ``run(clock=name)``."""
    clocks = {"wall": time.perf_counter, "cpu": time.process_time}
    if name not in clocks:
        raise InputError(f"clock: expected one of {', '.join(clocks)}, got {name!r}")
    return clocks[name]


def _spread(per_repeat):
    """(median, min, max) of a list of seconds."""
    a = np.asarray(per_repeat, dtype=float)
    return float(np.median(a)), float(a.min()), float(a.max())


def _cost(times, keys, repeats):
    """Per repeat the sum of the stages ``keys`` (a stage run once counts its one time in each)."""
    if not keys:
        return [0.0] * repeats
    return [float(sum(times[k][min(i, len(times[k]) - 1)] for k in keys)) for i in range(repeats)]


def _used_by(graph, plans, order):
    """Stage -> the techniques whose result or reference depends on it (run order)."""
    out = {k: [] for k in order}
    for n, t in plans.items():
        for k in graph.order([x for x in (t.shade, t.reference) if x]):
            out[k].append(n)
    return out


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


def _base_stages(ctx):
    scene = ctx.scene
    light = ctx.light_clip_from_world
    out = [Stage(SHADOW_MAP, _shadow_map, bound=(("scene", scene), ("size", ctx.size), ("samples", ctx.samples))),
           Stage(GBUFFER, camera_gbuffer, bound=(("scene", scene), ("resolution", ctx.resolution))),
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
    st = _settings_of(settings, old, "plan")
    check_scene(scene)
    techs = _requested(scene, outputs)
    ctx = _context(scene, st)
    overrides = dict(st.overrides or {})
    g = _Graph()
    for stage in _base_stages(ctx):
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


def _intensity(value, kind):
    """Shadow intensity of a stage value that holds ``kind`` ("intensity" or "visibility", ``1 − intensity``)."""
    return 1.0 - value if kind == "visibility" else value


def run(scene, outputs=None, settings=None, **old) -> RunResult:
    """Compute the requested techniques' results on a scene's camera view, lazily.

    Parameters
    ----------
    scene : Scene or str
        A loaded scene, a shipped scene name or a scene file path.
    outputs : list of str or Technique, optional
        Registered technique names (default: the scene's ``outputs``), or
        techniques built by the caller. Unknown names raise
        :class:`~moments_ref.InputError` listing the known ones; techniques that
        cannot run on the scene raise it with the reason.
    settings : Settings, optional
        Sizes, references, repeats and clock (:class:`Settings`; default the
        scene's own). The old keyword arguments (``shadow_map_size=``, ``msaa=``,
        ..., ``area=``, ``settings={option: overrides}``, ``given=``) still work
        for one release, with a DeprecationWarning.

    Returns
    -------
    RunResult
    """
    if not hasattr(scene, "receiver"):
        from .scene import load_scene

        scene = load_scene(scene)
    st = _settings_of(settings, old, "run")
    rp = plan(scene, outputs, st)
    plans = rp.techniques
    timed = {k for t in plans.values() for k in (*t.texel, t.shade)}
    repeats = max(int(st.repeats), 1)
    order, values, times = rp.graph.run(rp.targets, progress=st.progress, desc=scene.name, timed=timed,
                                        repeats=repeats, clock=_clock(st.clock), warmup=st.warmup)
    seconds = {k: _spread(v)[0] for k, v in times.items()}
    spread = {n: {"texel": _spread(_cost(times, t.texel, repeats)),
                  "fragment": _spread(_cost(times, [t.shade], repeats))} for n, t in plans.items()}
    ctx = rp.context
    return RunResult(scene=scene, techniques=list(plans), stages=order, seconds=seconds,
                     gbuffer=values.get(ctx.receivers),
                     shadow={n: _intensity(values[t.shade], t.result) for n, t in plans.items()},
                     reference={n: _intensity(values[t.reference], t.reference_result)
                                for n, t in plans.items() if t.reference},
                     texel_seconds={n: v["texel"][0] for n, v in spread.items()},
                     fragment_seconds={n: v["fragment"][0] for n, v in spread.items()},
                     shadow_map_size=ctx.size, msaa=ctx.samples, values=values,
                     bits_per_texel={n: t.bits for n, t in plans.items()}, area=rp.settings.get("mvr", {}),
                     settings=rp.settings, truth={n: t.truth for n, t in plans.items()}, times=times,
                     repeats=repeats, used_by=_used_by(rp.graph, plans, order), spread=spread, plans=plans)


# ---------------------------------------------------------------------------
# Public since the first release, kept for its callers: thin views of run()


@dataclass
class ScatteringResult:
    """What :func:`run_scattering` computed.

    Attributes
    ----------
    rows : list of dict with the columns of :data:`moments_ref.report.COLUMNS`
    images : dict name -> (H, W) scattering term (``reference`` included)
    t_max : float, the normalization of the scattering term (longest view ray)
    stages : list of str, the stages that ran
    seconds : float, wall-clock seconds of the whole call
    settings : dict, the settings used
    """

    rows: list
    images: dict
    t_max: float
    stages: list
    seconds: float
    settings: dict


def scattering_stages(samples):
    """Keys of the stages of the scattering outputs for a map with ``samples`` MSAA samples.

    ``scattering_raster_shadow_map``, ``scattering_camera_rays``,
    ``scattering_raymarch_reference``, per six-moment technique its texture steps
    (the shared moment steps with the prefix ``scattering_``) and
    ``shade_<technique>``, then ``scattering_raymarch``.
    """
    from .techniques.scattering import MAP, RAYS, REFERENCE

    out = [MAP, RAYS, REFERENCE]
    for name in SCATTERING_OUTPUTS:
        steps = _techniques.get(name).steps(int(samples), False)
        for step in steps:
            out.append(step.key if step.key.startswith("scattering_") else "scattering_" + step.key)
        if steps:
            out.append(f"shade_{name}")
    out.append("scattering_raymarch")
    return out


def run_scattering(scene, *, shadow_map_size=None, msaa=None, resolution=None, epipolar_size=None,
                   reference_samples=None, raymarch_samples=None):
    """Rows of the scattering outputs of a scene: :func:`run` on :data:`SCATTERING_OUTPUTS`.

    Parameters as :func:`run` (defaults: the scene's); ``epipolar_size``,
    ``reference_samples`` and ``raymarch_samples`` as the settings of reference
    ``raymarch`` (:func:`moments_ref.techniques.scattering.configure`).

    Returns
    -------
    ScatteringResult
    """
    if not hasattr(scene, "receiver"):
        from .scene import load_scene

        scene = load_scene(scene)
    t0 = time.perf_counter()
    over = {"epipolar_size": epipolar_size, "reference_samples": reference_samples,
            "raymarch_samples": raymarch_samples}
    r = run(scene, list(SCATTERING_OUTPUTS), Settings(shadow_map_size=shadow_map_size, msaa=msaa, resolution=resolution,
                                                      overrides={"scattering": {k: v for k, v in over.items()
                                                                                if v is not None}}))
    seconds = time.perf_counter() - t0
    first = r.techniques[0]
    images = {"reference": r.reference[first], **{n: r.shadow[n] for n in r.techniques}}
    from .techniques.scattering import RAYS

    return ScatteringResult(rows=r.rows(), images=images, t_max=float(r.values[RAYS][1]), stages=r.stages,
                            seconds=seconds, settings=r.settings["raymarch"])
