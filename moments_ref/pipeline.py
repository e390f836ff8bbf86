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
``light_projection``        their texel coordinates and depth in the shadow map
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

References
----------
HPG17, VWSS, Slides : see docs/bib.md.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from ._arrays import InputError
from .gpu.bluenoise import blue_noise_textures, frame_noise
from .scene.gbuffer import GBuffer, camera_gbuffer, light_projection
from . import techniques as _techniques
from .techniques import PlanContext, Stage, get_reference, reduced_settings
from .techniques._interface import GBUFFER, NOISE, PROJECTION, SHADOW_MAP, TRANSLUCENCY
from .techniques.area import area_settings
from .techniques.translucent import translucency_pass

__all__ = ["GBuffer", "RunResult", "run", "plan", "reduced_settings", "check_scene", "AREA_OUTPUTS",
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


@dataclass
class RunResult:
    """What :func:`run` computed.

    Attributes
    ----------
    scene : Scene
    techniques : list of str
    stages : list of str, the stages that ran, in order
    seconds : dict stage -> seconds (the median of its timed repeats; wall-clock or CPU, ``run(clock=...)``)
    times : dict stage -> list of seconds: its timed repeats (after a warm-up run) for
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

    def run(self, targets, progress=False, desc="stages", timed=(), repeats=1, clock=time.perf_counter):
        """Compute the stages ``targets`` need; return ``(order, values, times)``.

        A stage in ``timed`` runs once as a warm-up (its value is kept) and then
        ``repeats`` times more, each timed; ``times[stage]`` lists those seconds
        (one entry, the single run, for the other stages), read from ``clock``.
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
                    times[name] = [_timed(stage, args, clock) for _ in range(max(int(repeats), 1))]
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


def _used_by(graph, info, order):
    """Stage -> the techniques whose result or reference depends on it (run order)."""
    out = {k: [] for k in order}
    for n, i in info.items():
        for k in graph.order([x for x in (i["shade"], i["reference"]) if x]):
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


def _base_stages(ctx):
    scene = ctx.scene
    out = [Stage(SHADOW_MAP, _shadow_map, bound=(("scene", scene), ("size", ctx.size), ("samples", ctx.samples))),
           Stage(GBUFFER, camera_gbuffer, bound=(("scene", scene), ("resolution", ctx.resolution))),
           Stage(PROJECTION, light_projection, (GBUFFER,), bound=(("clip_from_world", ctx.clip_from_world), ("size", ctx.size))),
           Stage("bluenoise_textures", blue_noise_textures, bound=(("count", ctx.noise_tiles),)),
           Stage(NOISE, _noise, ("bluenoise_textures", PROJECTION), bound=(("frame", ctx.frame),))]
    if ctx.translucent:
        out.append(Stage(TRANSLUCENCY, _layers, (SHADOW_MAP,), bound=(("scene", scene), ("clip_from_world", ctx.clip_from_world))))
    return out


def _known_outputs():
    groups = {}
    for n, t in _techniques.TECHNIQUES.items():
        groups.setdefault(get_reference(t.truth).label, []).append(n)
    parts = [f"{label}: {', '.join(ns)}" for label, ns in groups.items()]
    return "known techniques: " + "; ".join([parts[0].split(": ", 1)[1]] + parts[1:])


def _requested(scene, outputs):
    names = list(dict.fromkeys(scene.outputs if outputs is None else outputs))
    if not names:
        raise InputError(f"outputs: scene {scene.name!r} requests no outputs; {_known_outputs()}")
    for n in names:
        if n not in _techniques.TECHNIQUES:
            raise InputError(f"technique: unknown technique {n!r}; {_known_outputs()}")
    techs = [_techniques.get(n) for n in names]
    for t in techs:
        reason = t.refusal(scene)
        if reason:
            raise InputError(f"outputs: {reason}")
    return techs


def _context(scene, shadow_map_size, msaa, resolution, params, noise_tiles, frame, full, given):
    size = tuple(scene.shadow_map_size) if shadow_map_size is None else (
        (shadow_map_size, shadow_map_size) if np.isscalar(shadow_map_size) else tuple(shadow_map_size))
    if given is None:
        given = {"shadow_map_size": shadow_map_size, "msaa": msaa, "resolution": resolution}
    return PlanContext(scene=scene, size=size, samples=scene.msaa if msaa is None else int(msaa),
                       resolution=tuple(scene.camera.resolution) if resolution is None else tuple(resolution),
                       params={**scene.params, **(params or {})},
                       translucent=bool(np.any(scene.occluder_translucent)), clip_from_world=scene.light_clip_from_world(),
                       noise_tiles=noise_tiles, frame=frame, full=bool(full), given=dict(given))


def plan(scene, outputs=None, *, shadow_map_size=None, msaa=None, resolution=None, reference=True,
         noise_tiles=64, frame=0, params=None, area=None, settings=None, full=False, given=None):
    """Build the stage graph; return ``(graph, targets, meta)`` without running anything.

    Parameters as :func:`run`. ``meta["info"]`` maps each technique to its texture
    stage keys (``steps``), its shade stage, its reference stage and its reference's
    name (``truth``); ``meta["settings"]`` maps each reference used to its settings.
    """
    check_scene(scene)
    techs = _requested(scene, outputs)
    ctx = _context(scene, shadow_map_size, msaa, resolution, params, noise_tiles, frame, full, given)
    overrides = dict(settings or {})
    if area is not None:
        overrides["area"] = area
    g = _Graph()
    for st in _base_stages(ctx):
        g.add(st)
    cfgs, targets, info, bits = {}, [], {}, {}
    for t in techs:
        ref = get_reference(t.truth)
        if ref.name not in cfgs:
            cfgs[ref.name] = ref.settings(ctx, overrides.get(ref.option or ref.name))
        p = t.stages(t, ctx, cfgs[ref.name])
        for st in p.stages:
            g.add(st)
        targets.append(p.shade)
        ref_key = None
        if reference:
            st = ref.stage(ctx, cfgs[ref.name], t)
            ref_key = None if st is None else g.add(st)
        if ref_key is not None:
            targets.append(ref_key)
        info[t.name] = {"steps": list(p.texel), "shade": p.shade, "reference": ref_key, "truth": ref.name}
        bits[t.name] = t.bits_per_texel if p.bits is None else p.bits
    meta = {"size": ctx.size, "samples": ctx.samples, "resolution": ctx.resolution, "info": info,
            "techniques": [t.name for t in techs], "bits_per_texel": bits, "settings": cfgs,
            "area": cfgs.get("mvr", {})}
    return g, list(dict.fromkeys(targets)), meta


def run(scene, outputs=None, *, shadow_map_size=None, msaa=None, resolution=None, reference=True,
        noise_tiles=64, frame=0, params=None, area=None, settings=None, full=False, given=None, progress=False,
        repeats=1, clock="wall"):
    """Compute the requested techniques' results on a scene's camera view, lazily.

    Parameters
    ----------
    scene : Scene or str
        A loaded scene, a shipped scene name or a scene file path.
    outputs : list of str, optional
        Registered technique names (default: the scene's ``outputs``). Unknown
        names raise :class:`~moments_ref.InputError` listing the known ones;
        techniques that cannot run on the scene raise it with the reason.
    shadow_map_size : int or (H, W), optional
        Default: the scene's.
    msaa : int, optional
        Samples per shadow-map texel; default the scene's.
    resolution : (width, height), optional
        Camera resolution; default the scene's.
    reference : bool
        Also compute each technique's reference (its ``truth``).
    noise_tiles : int
        Blue-noise tiles generated (HPG17 §4.2: 64).
    frame : int
        Frame number selecting the blue-noise tile and offsets.
    params : dict, optional
        Overrides of the scene's ``params`` passed to the technique steps.
    area : dict, optional
        Settings of the area-light outputs (reference ``mvr``): ``map_size``
        (default the larger side of ``shadow_map_size``), ``light_samples`` (N,
        default ``params.light_samples`` or 24), ``reference_views`` (R, default
        64), ``views_per_pass`` (8), ``seed`` (0) and ``bias`` (world units,
        default ``0.002 · far``); see :func:`area_settings`. Same as
        ``settings={"area": ...}``.
    settings : dict, optional
        Per reference option (``Reference.option``: ``area``, ``scattering``) its
        overrides, e.g. ``{"scattering": {"epipolar_size": (64, 128)}}``.
    full : bool
        Paper-scale settings for the references that have them (``--full``).
    given : dict, optional
        The sizes the caller set explicitly (default: the arguments above).
    progress : bool
        Show a tqdm progress bar of the stages on stderr.
    repeats : int
        Timed repeats of each stage of a technique's cost (its texture stages and
        its shade stage), after a warm-up run whose value is used; the seconds are
        their median (``spread``: median, min, max). The other stages (base
        stages, references) run once.
    clock : "wall" or "cpu"
        What the seconds measure: wall-clock time (``time.perf_counter``) or the
        CPU time of this process, all its threads (``time.process_time``: not
        inflated when other processes compete for the cores; the report's choice).

    Returns
    -------
    RunResult
    """
    if not hasattr(scene, "receiver"):
        from .scene import load_scene

        scene = load_scene(scene)
    g, targets, meta = plan(scene, outputs, shadow_map_size=shadow_map_size, msaa=msaa, resolution=resolution,
                            reference=reference, noise_tiles=noise_tiles, frame=frame, params=params, area=area,
                            settings=settings, full=full, given=given)
    info = meta["info"]
    timed = {k for i in info.values() for k in (*i["steps"], i["shade"])}
    repeats = max(int(repeats), 1)
    order, values, times = g.run(targets, progress=progress, desc=scene.name, timed=timed, repeats=repeats,
                                 clock=_clock(clock))
    seconds = {k: _spread(v)[0] for k, v in times.items()}
    spread = {n: {"texel": _spread(_cost(times, i["steps"], repeats)),
                  "fragment": _spread(_cost(times, [i["shade"]], repeats))} for n, i in info.items()}
    return RunResult(scene=scene, techniques=meta["techniques"], stages=order, seconds=seconds,
                     gbuffer=values.get(PROJECTION),
                     shadow={n: values[i["shade"]] for n, i in info.items()},
                     reference={n: values[i["reference"]] for n, i in info.items() if i["reference"]},
                     texel_seconds={n: v["texel"][0] for n, v in spread.items()},
                     fragment_seconds={n: v["fragment"][0] for n, v in spread.items()},
                     shadow_map_size=meta["size"], msaa=meta["samples"], values=values,
                     bits_per_texel=meta["bits_per_texel"], area=meta["area"], settings=meta["settings"],
                     truth={n: i["truth"] for n, i in info.items()}, times=times, repeats=repeats,
                     used_by=_used_by(g, info, order), spread=spread)


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
    r = run(scene, list(SCATTERING_OUTPUTS), shadow_map_size=shadow_map_size, msaa=msaa, resolution=resolution,
            settings={"scattering": {k: v for k, v in over.items() if v is not None}})
    seconds = time.perf_counter() - t0
    first = r.techniques[0]
    images = {"reference": r.reference[first], **{n: r.shadow[n] for n in r.techniques}}
    from .techniques.scattering import RAYS

    return ScatteringResult(rows=r.rows(), images=images, t_max=float(r.values[RAYS][1]), stages=r.stages,
                            seconds=seconds, settings=r.settings["raymarch"])
