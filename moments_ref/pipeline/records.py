"""The records of a run: its :class:`Settings`, the :class:`RunPlan` of its stages, the :class:`RunResult`.

References
----------
.. [1] HPG17: Christoph Peters. 2017. *Non-Linearly Quantized Moment Shadow Maps*. In Proceedings
       of High Performance Graphics (HPG '17). ACM. The non-linear quantization Φ, Ψ4, Algorithms
       1–3, the texel formats and the compute shader of §4.1.
.. [2] VWSS: Adam Marrs, Benjamin Watson and Christopher Healey. 2018. *View-warped Multi-view Soft
       Shadowing for Local Area Lights*. Journal of Computer Graphics Techniques (JCGT) 7, 3, 1–28.
       http://jcgt.org/published/0007/03/01/
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

from .._shim import warn_renamed
from ..scene.gbuffer import GBuffer
from ..techniques import PlanContext, get_reference
from .graph import spread

__all__ = ["Settings", "OLD_KEYWORDS", "settings_of", "TechniquePlan", "RunPlan", "RunResult"]


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
    keep : tuple of str, optional
        None (default): :attr:`RunResult.values` holds every stage's value. A tuple:
        each value is released after the last stage that needs it, except the
        techniques' and references' results, the receivers and the stages named here
        (the report keeps only what its claims read: the run's peak memory is then its
        largest live set of stages, not their sum).
    camera_gbuffer : GBuffer, optional
        The scene's camera G-buffer at ``resolution`` when the caller has it already
        (:func:`moments_ref.scene.gbuffer.check_shaded` returns it; the report checks
        every scene before its run): the run's ``camera_gbuffer`` stage takes it instead
        of rendering it again. None (default): rendered.
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
    keep: tuple = None
    camera_gbuffer: object = None

    def replace(self, **changes) -> "Settings":
        """A copy with ``changes``."""
        return dataclasses.replace(self, **changes)


#: The keyword arguments :func:`plan` and :func:`run` took before :class:`Settings` (deprecated).
OLD_KEYWORDS = ("shadow_map_size", "msaa", "resolution", "reference", "noise_tiles", "frame", "params", "full",
                 "repeats", "clock", "progress", "area", "given")


def settings_of(settings, old, fn):
    """The :class:`Settings` of a call; the old keywords (and ``settings`` as a dict of overrides) warn."""
    if isinstance(settings, Settings) and not old:
        return settings
    unknown = set(old) - set(OLD_KEYWORDS)
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
            med, lo, hi = spread(self.times.get(k, [self.seconds[k]]))
            out.append({"stage": k, "seconds": med, "min": lo, "max": hi, "used_by": list(self.used_by.get(k, []))})
        return out

