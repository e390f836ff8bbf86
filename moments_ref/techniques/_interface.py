"""The shared interface of the shadow techniques: Technique, Step, Stage, Reference, the registry.

Everything :mod:`moments_ref.techniques` re-exports; the technique modules import
it from here (not from the package, which imports them: no cycle). See the
package docstring for the conventions.

References
----------
.. [1] Slides: Christoph Peters. *Rendering antialiased shadows with moment shadow mapping*,
       lecture slides (PDF version, with notes) on moment shadow mapping, translucent occluders,
       moment soft shadow mapping and prefiltered single scattering; http://MomentsInGraphics.de/.
       Cited by slide title, e.g. Slides, "Bias the moments".
.. [2] VWSS: Adam Marrs, Benjamin Watson and Christopher Healey. 2018. *View-warped Multi-view Soft
       Shadowing for Local Area Lights*. Journal of Computer Graphics Techniques (JCGT) 7, 3, 1–28.
       http://jcgt.org/published/0007/03/01/
.. [3] HPG17: Christoph Peters. 2017. *Non-Linearly Quantized Moment Shadow Maps*. In Proceedings
       of High Performance Graphics (HPG '17). ACM. The non-linear quantization Φ, Ψ4, Algorithms
       1–3, the texel formats and the compute shader of §4.1.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np

from .._arrays import InputError, real_input
from .._shim import renamed_keywords
from ..scene.gbuffer import z_ndc_lookup

__all__ = [
    "Step",
    "Technique",
    "LayeredSamples",
    "register",
    "get",
    "names",
    "TECHNIQUES",
    "sample_count",
    "is_layered",
    "check_uv_depth",
    "bilinear_filtered",
    "Stage",
    "stage_key",
    "Plan",
    "PlanContext",
    "Reference",
    "REFERENCES",
    "register_reference",
    "get_reference",
    "texture_stages",
    "reduced_settings",
]


@dataclass(frozen=True)
class LayeredSamples:
    """Per-sample depth distributions of a shadow map with translucent occluders.

    Attributes
    ----------
    depth : (H, W, S, K) float32 array
        Layer depths in [-1, 1], nearest first; unused layers hold 1 (far).
    weight : (H, W, S, K) float64 array
        Non-negative layer weights summing to 1 over K: the share of the light
        that layer k absorbs, ``α_k ∏_{l<k} (1 − α_l)``; the last used layer is the
        opaque surface (or the far plane) with the remaining transmittance.

    Notes
    -----
    Slides, "Translucent occluders": rendering to a moment shadow map with alpha
    blending, far to near, leaves exactly ``Σ_k weight_k b(depth_k)`` in each
    sample; ``Σ_{depth_k < zf} weight_k`` is one minus the product of the
    transmittances in front of ``zf``.
    """

    depth: np.ndarray
    weight: np.ndarray

    @property
    def shape(self):
        """``(H, W, S)``."""
        return self.depth.shape[:3]


def is_layered(samples) -> bool:
    """True for :class:`LayeredSamples` (translucency pass output)."""
    return isinstance(samples, LayeredSamples)


def sample_count(samples) -> int:
    """MSAA samples per texel of an (H, W, S) map or of :class:`LayeredSamples`."""
    return int(samples.shape[2])


def _fmt_param(v) -> str:
    if isinstance(v, (tuple, list)):
        return "_".join(_fmt_param(x) for x in v)
    if isinstance(v, float):
        return f"{v:g}"
    return str(v)


def stage_key(name: str, params=()) -> str:
    """The key of a stage: its name followed by ``_<param><value>`` per parameter.

    ``stage_key("reference_pcf", {"bias": 0.001}) == "reference_pcf_bias0.001"``;
    sequences join with ``_`` (``{"c": (5.5, 5.5)}`` -> ``_c5.5_5.5``). Stage
    parameters are thus part of the key by construction, never spelled by hand.
    """
    items = params.items() if isinstance(params, dict) else params
    return name + "".join(f"_{k}{_fmt_param(v)}" for k, v in items)


@dataclass(frozen=True)
class Step:
    """One named stage of building a technique's texture.

    ``fn(x, params) -> y``. Equal keys (:attr:`key`: the name and the stage
    parameters ``params``) mean equal results for the same shadow map: the
    pipeline computes a key once and shares it between techniques.
    """

    name: str
    fn: Callable[[Any, dict], Any]
    params: tuple = ()

    @property
    def key(self) -> str:
        """:func:`stage_key` of the name and the parameters."""
        return stage_key(self.name, self.params)


#: Stages the pipeline provides to every technique (keys of its graph).
SHADOW_MAP, TRANSLUCENCY, GBUFFER, PROJECTION, NOISE = (
    "raster_shadow_map", "translucency_pass", "camera_gbuffer", "light_projection", "frame_noise")


@dataclass(frozen=True)
class Stage:
    """One node of the pipeline's stage graph: ``fn(*values of deps, **params, **bound)``.

    ``deps`` are keys of other stages; ``params`` (pairs) are keyword arguments of
    ``fn`` and part of the key (:func:`stage_key`); ``bound`` (pairs) are further
    keyword arguments that follow from the key (a technique, a step and its
    options), compared when a key is added twice but not shown. Two stages of
    equal key compute the same value and are computed once.
    """

    name: str
    fn: Callable
    deps: tuple = ()
    params: tuple = ()
    bound: tuple = ()

    @property
    def key(self) -> str:
        """:func:`stage_key` of the name and the parameters."""
        return stage_key(self.name, self.params)

    def __call__(self, *values):
        return self.fn(*values, **dict(self.params), **dict(self.bound))

    def same_as(self, other) -> bool:
        """Equal key, dependencies and step (the same code with equal bound values)."""
        return (self.key == other.key and tuple(self.deps) == tuple(other.deps)
                and _same_value(self.params, other.params) and _same_value(self.bound, other.bound)
                and _same_callable(self.fn, other.fn))


def _same_callable(a, b) -> bool:
    if a is b:
        return True
    if isinstance(a, Step) and isinstance(b, Step):
        return a.key == b.key and _same_callable(a.fn, b.fn)
    code = getattr(a, "__code__", None)
    if code is None or code is not getattr(b, "__code__", None):
        return bool(a == b)
    cells = [tuple(c.cell_contents for c in (f.__closure__ or ())) for f in (a, b)]
    return _same_value(cells[0], cells[1]) and _same_value(a.__defaults__, b.__defaults__)


def _same_value(x, y) -> bool:
    if x is y:
        return True
    if type(x) is not type(y):
        return False
    if isinstance(x, Step):
        return _same_callable(x, y)
    if isinstance(x, (tuple, list)):
        return len(x) == len(y) and all(_same_value(a, b) for a, b in zip(x, y))
    if isinstance(x, dict):
        return x.keys() == y.keys() and all(_same_value(x[k], y[k]) for k in x)
    if callable(x):
        return _same_callable(x, y)
    if isinstance(x, np.ndarray):
        return x.shape == y.shape and x.dtype == y.dtype and bool(np.array_equal(x, y))
    try:
        return bool(x == y)
    except (TypeError, ValueError):
        return False


@dataclass(frozen=True)
class Plan:
    """What a technique adds to the graph: its stages, its texture stages and its shade stage.

    ``texel`` are the keys whose seconds are its texel cost (shared stages count
    fully for each technique: its cost alone); ``shade`` is the key of the stage
    whose value is its result for the receivers (its fragment cost); ``bits``
    overrides the technique's ``bits_per_texel`` where the storage follows from
    the settings. ``result`` says what the shade stage holds: the shadow intensity
    (default) or the visibility ``1 − intensity`` (the soft shadows of VWSS §4, whose
    shading pass computes the visible fraction of the light; the pipeline reports
    ``1 − visibility`` as their intensity).
    """

    stages: tuple
    texel: tuple
    shade: str
    bits: int = None
    result: str = "intensity"


@dataclass(frozen=True)
class PlanContext:
    """The settings of one pipeline run that techniques and references plan with.

    Attributes
    ----------
    scene : Scene
    size : (H, W) shadow-map size; samples : MSAA samples; resolution : (width, height)
    params : dict, the scene's ``params`` with the run's overrides
    translucent : bool, the scene has translucent occluders
    light_clip_from_world : (4, 4) the light's shadow-map matrix
    noise_tiles, frame : blue-noise settings (HPG17 §4.2)
    full : bool, paper-scale settings (``moments-ref report --full``)
    receivers : str, the key of the stage holding the receivers the techniques
        shade (a :class:`~moments_ref.scene.gbuffer.GBuffer`; ``light_projection``
        unless the run asks for the depth G-buffer)
    """

    scene: Any
    size: tuple
    samples: int
    resolution: tuple
    params: dict
    translucent: bool
    light_clip_from_world: Any
    noise_tiles: int = 64
    frame: int = 0
    full: bool = False
    receivers: str = PROJECTION


def reduced_settings(scene):
    """The default (reduced) resolution: shadow map halved per side, camera a quarter per side.

    Returns ``(shadow_map_size (H, W), msaa, resolution (width, height))``.
    """
    h, w = scene.shadow_map_size
    cw, ch = scene.camera.resolution
    return (max(h // 2, 16), max(w // 2, 16)), scene.msaa, (max(cw // 4, 16), max(ch // 4, 9))


def _apply_step(x, step, params):
    return step.fn(x, params)


def _shade(tex, gb, noise=None, technique=None):
    return technique.shadow(tex, gb.uv, z_ndc_lookup(gb, technique.slope_bias), noise=noise)


def texture_stages(technique, ctx: PlanContext, settings=None) -> Plan:
    """The stages of a shadow-map technique: its :meth:`Technique.steps` and its lookup.

    The steps start from ``raster_shadow_map`` (or ``translucency_pass`` for a
    technique with ``translucency`` on a scene with translucent occluders); the
    shade stage ``shade_<name>`` looks the texture up at the receiver pixels of
    ``light_projection`` (with ``frame_noise`` when it ``needs_noise``).
    """
    layered = technique.translucency and ctx.translucent
    node = TRANSLUCENCY if layered else SHADOW_MAP
    params = {**technique.defaults, **ctx.params}
    stages, texel = [], []
    for step in technique.steps(ctx.samples, layered):
        st = Stage(step.key, _apply_step, (node,), bound=(("step", step), ("params", params)))
        stages.append(st)
        node = st.key
        texel.append(node)
    deps = (node, PROJECTION) + ((NOISE,) if technique.needs_noise else ())
    shade = Stage(f"shade_{technique.name}", _shade, deps, bound=(("technique", technique),))
    return Plan(tuple(stages) + (shade,), tuple(texel), shade.key)


@dataclass(frozen=True)
class Technique:
    """A shadow technique behind the shared interface (module docstring).

    Attributes
    ----------
    name : str
    bits_per_texel : int
        Storage per shadow-map texel of the filtered texture.
    depth_bias : float
        Subtracted from the fragment depth in :meth:`shadow`.
    slope_bias : bool
        Its shade stage also lowers the fragment depth by the receiver-slope bias
        (:func:`moments_ref.scene.gbuffer.z_ndc_lookup`): PCF, HPG17 §5's "higher depth
        bias"; the filterable techniques use the constant alone (default False).
    make_steps : callable ``(samples: int, layered: bool) -> tuple[Step, ...]``
        The steps from the shadow map to the texture for a map with ``samples``
        MSAA samples, opaque or layered. An empty chain means the texture is the
        shadow map itself (PCF).
    lookup : callable ``(texture, uv, zf, noise) -> intensity``
        Shadow intensity at the already biased depth ``zf`` (in :attr:`depth_space`).
    description, reference : str
        One line each: what it is, where it comes from.
    needs_noise : bool
        Its lookup reads per-pixel blue noise (HPG17 §4.2).
    translucency : bool
        It renders translucent occluders with alpha blending (it then receives
        :class:`LayeredSamples` when the scene has translucent geometry);
        techniques without it see only the opaque occluders.
    requires_translucency : bool
        The report runs it only on scenes with translucent occluders.
    four_moments : bool
        It reconstructs from four moments (HPG17 §5: such techniques leak with
        three occluders in a filter region).
    light_kinds : tuple of str
        Light kinds it supports ("directional", "area"; an area light is used
        as a spot light from its centre).
    multiview : bool
        It renders several views of an area light.
    defaults : dict
        Parameters of its steps (overridden by the scene's ``params``).
    stages : callable ``(technique, ctx: PlanContext, settings: dict) -> Plan``
        The stages it adds to the pipeline's graph. Default
        :func:`texture_stages`: its :meth:`steps` on the shadow map and its
        :meth:`shadow` on the receiver pixels.
    truth : str
        Name of the registered :class:`Reference` its error is measured against
        (its reference stage and its metric); default ``"pcf"``, the filtered hard
        shadow (:mod:`moments_ref.techniques.references`).
    requires_medium : bool
        It needs a participating medium (scene ``params.medium``): the report runs it
        only on such scenes.
    artifacts : callable ``(out_dir) -> (measurements, markdown lines, paths)``, optional
        Measured artifacts the report adds once when the technique has rows.
    """

    name: str
    bits_per_texel: int
    depth_bias: float
    make_steps: Callable[[int, bool], tuple]
    lookup: Callable
    description: str = ""
    reference: str = ""
    needs_noise: bool = False
    translucency: bool = False
    requires_translucency: bool = False
    four_moments: bool = False
    light_kinds: tuple = ("directional", "area")
    multiview: bool = False
    defaults: dict = field(default_factory=dict)
    stages: Callable = texture_stages
    truth: str = "pcf"
    requires_medium: bool = False
    artifacts: Callable = None
    slope_bias: bool = False

    def refusal(self, scene):
        """Why the technique cannot run on ``scene`` (a sentence), or None when it can."""
        kind = getattr(scene.light, "kind", "directional")
        if kind not in self.light_kinds or (self.multiview and kind != "area"):
            kinds = " or ".join(self.light_kinds)
            return (f"technique {self.name!r} needs a{'n' if kinds[0] in 'aeiou' else ''} {kinds} light"
                    f"{' (multi-view: an area light)' if self.multiview else ''}; scene {scene.name!r} "
                    f"has a {kind} light")
        if self.requires_translucency and not bool(np.any(scene.occluder_translucent)):
            return (f"technique {self.name!r} renders translucent occluders and scene {scene.name!r} has none "
                    "(its opaque equivalent is msm64)")
        if self.requires_medium and not (scene.params or {}).get("medium"):
            return f"technique {self.name!r} needs a participating medium (params.medium); scene {scene.name!r} has none"
        return None

    def steps(self, samples: int, layered: bool = False) -> tuple:
        """The :class:`Step` chain for a map with ``samples`` samples (layered or not)."""
        return tuple(self.make_steps(int(samples), bool(layered)))

    def prepare(self, depth_samples, params=None):
        """Build the filtered texture from the shadow map.

        Parameters
        ----------
        depth_samples : (H, W, S) float array or LayeredSamples
            The shadow map (module docstring). Layered input is accepted only by
            techniques with ``translucency``.
        params : dict, optional
            Overrides of :attr:`defaults` (scene parameters).

        Returns
        -------
        texture : array in the technique's storage format
        """
        layered = is_layered(depth_samples)
        if layered and not self.translucency:
            raise InputError(f"depth_samples: technique {self.name!r} does not render translucent occluders; "
                             "pass the opaque (H, W, S) depth map")
        if not layered:
            from ..gpu.filtering import check_depth_samples

            depth_samples = check_depth_samples(depth_samples)
        p = {**self.defaults, **(params or {})}
        x = depth_samples
        for step in self.steps(sample_count(depth_samples), layered):
            x = step.fn(x, p)
        return x

    #: The depth space :meth:`shadow` takes (the name of its third argument): light NDC,
    #: [-1, 1], the papers' fragment depth zf (docs/architecture.md, "Depth conventions").
    depth_space = "z_ndc_light"

    @renamed_keywords(depth="z_ndc_light")
    def shadow(self, texture, uv, z_ndc_light, noise=None):
        """Shadow intensity in [0, 1] of fragments (1 = fully shadowed).

        Parameters
        ----------
        texture : array
            Output of :meth:`prepare`.
        uv : (..., 2) float array
            Texel coordinates (module docstring).
        z_ndc_light : (...) float array
            Fragment depth in the light's NDC, [-1, 1] (HPG17's zf; for a G-buffer
            :func:`moments_ref.scene.gbuffer.z_ndc_lookup`); the technique's
            ``depth_bias`` is subtracted here. (``depth=`` is its old name.)
        noise : (..., 2) float array in [0, 1], optional
            Per-fragment blue noise (:func:`moments_ref.gpu.bluenoise.frame_noise`);
            required when ``needs_noise``.

        Returns
        -------
        intensity : (...) float array
        """
        return self.shadow_at(texture, uv, z_ndc_light, noise)

    def shadow_at(self, texture, uv, z, noise=None):
        """:meth:`shadow` with the depth ``z`` in this technique's :attr:`depth_space` (validated under that name)."""
        uv, zf = check_uv_depth(uv, z, self.depth_space)
        if self.needs_noise and noise is None:
            raise InputError(f"noise: technique {self.name!r} needs per-fragment blue noise (..., 2), got None")
        zf = zf - zf.dtype.type(self.depth_bias)
        return self.lookup(texture, uv, zf, noise)


def check_uv_depth(uv, depth, name="depth"):
    """Validate ``uv`` (..., 2) and ``depth`` (called ``name`` in errors) broadcastable to ``uv[..., 0]``; float64 both."""
    uv = real_input(uv, "uv", trailing=2, dtype=np.float64)
    zf = real_input(depth, name, dtype=np.float64)
    try:
        shape = np.broadcast_shapes(uv.shape[:-1], zf.shape)
    except ValueError:
        raise InputError(f"{name}: expected a shape broadcastable to uv.shape[:-1] {uv.shape[:-1]}, "
                         f"got {zf.shape}") from None
    return np.broadcast_to(uv, shape + (2,)), np.broadcast_to(zf, shape)


def bilinear_filtered(texture, uv, dtype=np.float32):
    """Hardware bilinear filtering of a float texture (clamp to edge).

    Parameters
    ----------
    texture : (H, W, C) float array
        Texel values after the format's decode (what the texture unit filters).
    uv : (..., 2) float array
        Texel coordinates, centres at ``i + 0.5``.
    dtype : float32 or float64
        Arithmetic of the interpolation (float32 emulates the texture unit).

    Returns
    -------
    values : (..., C) array of ``dtype``
    """
    from ..gpu.bluenoise import bilinear_footprint

    tex = np.asarray(texture)
    rows, cols, w = bilinear_footprint(np.asarray(uv, dtype=dtype), tex.shape)
    # One gather by flat texel index (row · W + col): the texels of tex[rows, cols], 5 to 7 times quicker
    # than the two-array fancy index.
    flat = tex.reshape(tex.shape[0] * tex.shape[1], *tex.shape[2:])
    t = flat.take(rows * tex.shape[1] + cols, axis=0).astype(dtype, copy=False)  # (..., 4, C)
    return np.einsum("...k,...kc->...c", w.astype(dtype), t)


#: The registry: name -> Technique, in registration order.
TECHNIQUES: dict[str, Technique] = {}


def register(technique: Technique) -> Technique:
    """Add a technique to the registry (its name must be new); return it."""
    if not isinstance(technique, Technique):
        raise InputError(f"technique: expected a Technique, got {type(technique).__name__}")
    if technique.name in TECHNIQUES and TECHNIQUES[technique.name] is not technique:
        raise InputError(f"technique: the name {technique.name!r} is already registered")
    TECHNIQUES[technique.name] = technique
    return technique


def names() -> list[str]:
    """Registered technique names, in registration order."""
    return list(TECHNIQUES)


def get(name) -> Technique:
    """The registered technique ``name``; unknown names list the known ones."""
    if isinstance(name, Technique):
        return name
    try:
        return TECHNIQUES[name]
    except (KeyError, TypeError):
        raise InputError(f"technique: unknown technique {name!r}; known techniques: {', '.join(TECHNIQUES)}") from None


@dataclass(frozen=True)
class Reference:
    """What techniques are measured against: the reference values, the metric, the report's part.

    Attributes
    ----------
    name : str
        Registry name (``Technique.truth``).
    label : str
        The group of its techniques in messages ("area-light outputs").
    option : str
        The keyword of its settings in :func:`moments_ref.pipeline.run` and
        :func:`moments_ref.report.run` (``area``, ``scattering``; empty: none).
    stage : callable ``(ctx, settings, technique) -> Stage or None``
        The stage computing the reference for ``technique`` (None: no reference).
    metric : callable ``(result, name) -> dict``
        The error columns of technique ``name`` in a :class:`~moments_ref.pipeline.RunResult`.
    configure : callable ``(ctx, overrides: dict) -> dict``
        Its settings for a run (validated overrides); stored per scene in the report.
    settings_keys : tuple of str
        The overrides ``configure`` accepts.
    figures : callable ``(result, names) -> {file name: matplotlib Figure}``, optional
    statements : callable ``(rows, scene) -> list of str``, optional
        Measured statements on the rows of its techniques.
    section : callable ``(settings, statements, images) -> list of str``, optional
        Its section of report.md (``settings``: scene -> its settings).
    result : {"intensity", "visibility"}
        What its stage holds (as :attr:`Plan.result`).
    """

    name: str
    label: str
    stage: Callable
    metric: Callable
    option: str = ""
    configure: Callable = None
    settings_keys: tuple = ()
    figures: Callable = None
    statements: Callable = None
    section: Callable = None
    result: str = "intensity"

    def settings(self, ctx, overrides=None) -> dict:
        """:attr:`configure` of the run (``{}`` without one); unknown overrides raise InputError."""
        overrides = dict(overrides or {})
        unknown = set(overrides) - set(self.settings_keys)
        if unknown:
            raise InputError(f"{self.option or self.name}: unknown settings {sorted(unknown)}; known: "
                             f"{', '.join(self.settings_keys) or 'none'}")
        return self.configure(ctx, overrides) if self.configure is not None else {}


#: Registered references: name -> Reference, in registration order.
REFERENCES: dict[str, Reference] = {}


def register_reference(reference: Reference) -> Reference:
    """Add a reference to the registry (its name must be new); return it."""
    if reference.name in REFERENCES and REFERENCES[reference.name] is not reference:
        raise InputError(f"reference: the name {reference.name!r} is already registered")
    REFERENCES[reference.name] = reference
    return reference


def get_reference(name) -> Reference:
    """The registered reference ``name``."""
    try:
        return REFERENCES[name]
    except KeyError:
        raise InputError(f"reference: unknown reference {name!r}; known: {', '.join(REFERENCES)}") from None
