"""The lazy runner: a scene and the outputs it asks for -> only the stages they need.

A scene file names its ``outputs`` (technique names, :mod:`moments_ref.techniques`).
:func:`run` builds a graph of named stages, walks back from the requested
``shade_<technique>`` stages (and the references their errors need) and computes
exactly the stages on those paths, each once:

==========================  ======================================================
``raster_shadow_map``       opaque occluders into the light's (H, W, S) depth map
``translucency_pass``       layers of translucent occluders (only if the scene has
                            translucent geometry and a technique or the reference
                            renders it)
``camera_gbuffer``          receiver points seen by the camera (nearest fragment
                            per pixel of the scene rasterized from the camera)
``light_projection``        their texel coordinates and depth in the shadow map
``bluenoise_textures``      HPG17 §4.2 texture array (only for dithered techniques)
``frame_noise``             the per-pixel blue noise of frame 0
technique steps             e.g. ``resolve_moments`` (``compute_moments`` for a 1×
                            map: nothing to resolve), ``blur_moments``,
                            ``quantize_affine64``, ``onchip_resolve_blur``,
                            ``quantize_nlq64``; equal names are computed once and
                            shared (msm64, msm128 and vsm share the resolve and
                            the blur; nlq64 and nlq64_dither share the texture)
``reference_pcf_bias<b>``   the filtered hard shadow at the fragment depth minus
                            b (:func:`moments_ref.techniques.pcf.pcf_filtered`);
                            ``translucency_reference_bias<b>`` with translucent
                            occluders (product of transmittances)
``shade_<technique>``       the technique's lookup for every receiver pixel
==========================  ======================================================

Area-light outputs (:data:`AREA_OUTPUTS`: ``msm_soft``, ``pcss``, ``vwss``,
``mvr``; only for a scene whose light is an :class:`~moments_ref.scene.AreaLight`)
shade the same receiver pixels (``light_projection``) with the soft-shadow
techniques and measure them against multi-view rasterization (MVR) with many
light samples, the reference of VWSS §4. They reuse :mod:`moments_ref.vwss`
and :mod:`moments_ref.techniques.msm_soft` (settings: :func:`area_settings`):

==========================  ======================================================
``area_center_view``        the light's centre view (``vwss.light_views`` with one
                            sample: the projection, near and far)
``area_center_depth_map``   one depth map from the light's centre
                            (``LightSamples.center_view_proj()``), shared by
                            msm_soft and PCSS
``msm_soft_sat``            :func:`moments_ref.techniques.msm_soft.prepare`:
                            linear depth, moments, summed-area table
``shade_msm_soft``          :func:`moments_ref.techniques.msm_soft.shade_points`
``shade_pcss``              :func:`moments_ref.vwss.pcss` (64-tap blocker search,
                            96-tap PCF) on the centre map
``vwss_light_samples``      the N Poisson-disk light samples and their views
``vwss_points``             layered points from the enlarged source view (VWSS
                            §3.1, :func:`moments_ref.vwss.generate_points`)
``vwss_warp``               the points warped into the N light-sample maps
                            (VWSS §3.2, :func:`moments_ref.vwss.warp.warp`)
``shade_vwss``              5-tap PCF in every map, averaged
                            (:func:`moments_ref.vwss.multiview_visibility`)
``mvr_vwss``                the N light-sample maps rasterized (only for ``mvr``)
``shade_mvr_vwss``          5-tap PCF in those maps
``mvr_reference_vwss``      the reference: MVR with R light samples of their own
                            Poisson set, each map shaded as it is rasterized
                            (``vwss.compare._shade_multiview``)
==========================  ======================================================

The texel cost of ``msm_soft`` is ``area_center_depth_map + msm_soft_sat``, of
``pcss`` the centre map, of ``vwss`` ``vwss_points + vwss_warp``, of ``mvr``
``mvr_vwss``; the fragment cost is the ``shade_`` stage (choosing the light
samples and views is set-up, counted in neither, like the camera G-buffer).
Shadow intensity is
``1 − visibility`` for these outputs and for the reference.

:attr:`RunResult.stages` records the stages that ran, in order; a stage name
contains ``translucen`` only for translucency work and ``vwss`` only for
multi-view work (the area-light stages that render or read several light-sample
views), and there is no multi-view work without an area light: area-light
outputs and registered techniques with ``multiview`` are refused for other
lights.

Scattering outputs (:data:`SCATTERING_OUTPUTS`, scene ``scattering``):
:func:`run_scattering` takes the rows of
:func:`moments_ref.techniques.scattering.report_rows` and names the stages that
call ran (:func:`scattering_stages`), all starting with ``scattering_`` (or
``shade_scattering_``).

Lights. A directional light gets its fitted orthographic map (HPG17 §5). An area
light (scene ``knot``) is used as a spot light from its centre by the hard-shadow
techniques (:meth:`moments_ref.scene.Scene.shadow_view_proj`).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from ._arrays import InputError
from .raster import project_points, rasterize_fragments
from . import techniques as _techniques

__all__ = ["GBuffer", "RunResult", "run", "plan", "reduced_settings", "check_scene", "AREA_OUTPUTS",
           "AREA_BITS_PER_TEXEL", "area_settings", "SCATTERING_OUTPUTS", "ScatteringResult", "scattering_stages",
           "run_scattering"]

#: kind image codes of :class:`GBuffer`.
BACKGROUND, RECEIVER, OCCLUDER, OUTSIDE_LIGHT = 0, 1, 2, 3

#: Outputs shaded under an area light against the MVR reference (module docstring).
AREA_OUTPUTS = ("msm_soft", "pcss", "vwss", "mvr")
#: Storage per texel: msm_soft four uint32 SAT channels; PCSS one float32 map; VWSS and
#: MVR a float32 depth per texel of each of their N light-sample maps.
AREA_BITS_PER_TEXEL = {"msm_soft": 128, "pcss": 32, "vwss": 32, "mvr": 32}
#: Outputs of :func:`run_scattering` (rows of ``techniques.scattering.report_rows``).
SCATTERING_OUTPUTS = ("scattering_6m", "scattering_6m_unfiltered", "raymarch")


@dataclass
class GBuffer:
    """Receiver points seen by the camera.

    Attributes
    ----------
    resolution : (width, height)
    kind : (height, width) int8 image
        0 background, 1 receiver (shaded, counted in the metrics), 2 occluder,
        3 receiver outside the light's shadow map (left unshadowed, not counted).
    pixel : (N,) int64
        Flat index ``row * width + col`` of each pixel with ``kind == 1``.
    position : (N, 3) float64 world positions
    lambert : (N,) float64 ``|n · l|`` (two-sided surfaces)
    normal : (N, 3) float64 unit face normals
    uv : (N, 2) float64 texel coordinates in the shadow map (filled by ``light_projection``)
    depth : (N,) float64 NDC depth in the light's view, minus the receiver-slope bias
    slope : (N,) float64 depth change per shadow-map texel along the receiver surface
    """

    resolution: tuple
    kind: np.ndarray
    pixel: np.ndarray
    position: np.ndarray
    lambert: np.ndarray
    normal: np.ndarray = None
    uv: np.ndarray = None
    depth: np.ndarray = None
    slope: np.ndarray = None


@dataclass
class RunResult:
    """What :func:`run` computed.

    Attributes
    ----------
    scene : Scene
    techniques : list of str
    stages : list of str, the stages that ran, in order
    seconds : dict stage -> wall-clock seconds
    gbuffer : GBuffer
    shadow : dict technique -> (N,) shadow intensity of the receiver pixels
    reference : dict technique -> (N,) float64 reference intensity at its depth bias
    texel_seconds : dict technique -> seconds of its texture stages (shared stages
        count fully for each technique that uses them: its cost alone)
    fragment_seconds : dict technique -> seconds of its ``shade_`` stage
    shadow_map_size : (H, W); msaa : int
    values : dict stage -> result (textures, maps) for inspection
    bits_per_texel : dict technique -> storage per texel
    area : dict, the settings of the area-light outputs (:func:`area_settings`
        plus ``near``, ``far``, ``bias``), empty without them
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


def check_scene(scene):
    """Refuse a scene the runner cannot shade, with the reason (InputError)."""
    name = getattr(scene, "name", "?")
    rec = getattr(scene, "receiver", None)
    if rec is None or rec.n_triangles == 0:
        raise InputError(f"scene {name!r}: no receiver (no object with role receiver or both): nothing to shade")
    if getattr(scene, "camera", None) is None:
        raise InputError(f"scene {name!r}: no camera: the report shades the camera's view")
    occ = getattr(scene, "occluder", None)
    if occ is None or occ.n_triangles == 0:
        raise InputError(f"scene {name!r}: no occluder: nothing casts a shadow")


def reduced_settings(scene):
    """The default (reduced) resolution: shadow map halved per side, camera a quarter per side.

    Returns ``(shadow_map_size (H, W), msaa, resolution (width, height))``.
    """
    h, w = scene.shadow_map_size
    cw, ch = scene.camera.resolution
    return (max(h // 2, 16), max(w // 2, 16)), scene.msaa, (max(cw // 4, 16), max(ch // 4, 9))


def _has_translucent(scene) -> bool:
    return bool(np.any(scene.occluder_translucent))


class _Graph:
    """Named stages with dependencies, evaluated on demand, each once."""

    def __init__(self):
        self.nodes = {}

    def add(self, name, deps, fn):
        if name not in self.nodes:  # equal names are equal stages (shared)
            self.nodes[name] = (tuple(deps), fn)
        return name

    def order(self, targets):
        """Topological order of the stages ``targets`` need (dependencies first)."""
        seen, out = set(), []

        def visit(n, stack=()):
            if n in seen:
                return
            if n in stack:
                raise RuntimeError(f"cycle through stage {n}")
            for d in self.nodes[n][0]:
                visit(d, stack + (n,))
            seen.add(n)
            out.append(n)

        for t in targets:
            visit(t)
        return out

    def run(self, targets, progress=False, desc="stages"):
        order = self.order(targets)
        values, seconds = {}, {}
        bar = None
        if progress:
            import sys

            from tqdm import tqdm

            bar = tqdm(total=len(order), desc=desc, unit="stage", file=sys.stderr, leave=False)
        try:
            for name in order:
                deps, fn = self.nodes[name]
                if bar is not None:
                    bar.set_postfix_str(name, refresh=False)
                t0 = time.perf_counter()
                values[name] = fn(*(values[d] for d in deps))
                seconds[name] = time.perf_counter() - t0
                if bar is not None:
                    bar.update(1)
        finally:
            if bar is not None:
                bar.close()
        return order, values, seconds


def _camera_gbuffer(scene, resolution):
    """Nearest fragment per camera pixel among receivers and opaque occluder-only objects."""
    width, height = resolution
    rec = scene.receiver
    # Occluders that are not also receivers hide receivers; translucent ones do not
    # (the receiver is seen through them).
    role = np.array([scene.objects[i].role == "occluder" for i in scene.occluder_object], dtype=bool).reshape(-1)
    keep = role & ~scene.occluder_translucent
    occ_tri = scene.occluder.triangles[keep]
    v = np.concatenate([rec.vertices, scene.occluder.vertices])
    tri = np.concatenate([rec.triangles, occ_tri + rec.vertices.shape[0]])
    frags, _ = rasterize_fragments(v, tri, scene.camera.view_proj(), (height, width), samples=1, dtype=np.float64)
    kind = np.zeros(height * width, dtype=np.int8)
    if len(frags):
        order = np.lexsort((frags.depth, frags.texel))
        texel = frags.texel[order]
        first = np.ones(texel.shape[0], bool)
        first[1:] = texel[1:] != texel[:-1]
        sel = order[first]
    else:
        sel = np.zeros(0, np.intp)
    texel, tri_id = frags.texel[sel], frags.triangle[sel]
    is_rec = tri_id < rec.triangles.shape[0]
    kind[texel] = np.where(is_rec, RECEIVER, OCCLUDER)
    pixel = texel[is_rec]
    pos = frags.position[sel][is_rec].astype(np.float64)
    # Face normals of the receiver triangles (two-sided Lambert).
    t = rec.triangles[tri_id[is_rec]]
    p0, p1, p2 = (rec.vertices[t[:, k]] for k in range(3))
    n = np.cross(p1 - p0, p2 - p0)
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-30)
    if getattr(scene.light, "kind", "directional") == "directional":
        to_light = np.broadcast_to(-scene.light.direction, pos.shape)
    else:
        d = scene.light.center - pos
        to_light = d / np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-30)
    lambert = np.abs(np.einsum("ij,ij->i", n, to_light))
    return GBuffer(resolution=(width, height), kind=kind.reshape(height, width), pixel=pixel,
                   position=pos, lambert=lambert, normal=n)


#: Receiver-slope bias in shadow-map texels (see :func:`_light_projection`): the
#: farthest a tap of the 9×9 footprint reaches along any direction (4√2 texels on
#: the diagonal) plus half a texel diagonal for the fragment's position in its texel.
SLOPE_BIAS_TEXELS = 4.5 * 2**0.5


def _depth_slope(position, normal, view_proj, size):
    """|∂depth/∂(texel)| along the receiver plane at each point (light-space depth per texel).

    Two tangents of the surface are projected into the shadow map; the depth
    gradient with respect to texel coordinates solves the 2×2 system of their
    texel offsets. Grazing surfaces (singular system) get the largest finite slope.
    """
    a = np.where(np.abs(normal[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    t1 = np.cross(normal, a)
    t1 /= np.linalg.norm(t1, axis=1, keepdims=True)
    t2 = np.cross(normal, t1)
    scale = 1e-3 * max(1.0, float(np.abs(position).max()))
    xy0, z0 = project_points(position, view_proj, size)
    xy1, z1 = project_points(position + scale * t1, view_proj, size)
    xy2, z2 = project_points(position + scale * t2, view_proj, size)
    j = np.stack([xy1 - xy0, xy2 - xy0], axis=1)  # (N, 2 tangents, 2 texel axes)
    dz = np.stack([z1 - z0, z2 - z0], axis=1)
    det = j[:, 0, 0] * j[:, 1, 1] - j[:, 0, 1] * j[:, 1, 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        gx = (dz[:, 0] * j[:, 1, 1] - dz[:, 1] * j[:, 0, 1]) / det
        gy = (dz[:, 1] * j[:, 0, 0] - dz[:, 0] * j[:, 1, 0]) / det
        slope = np.hypot(gx, gy)
    finite = np.isfinite(slope)
    return np.where(finite, slope, slope[finite].max() if finite.any() else 0.0)


def _light_projection(g, view_proj, size):
    """Texel coordinates and depth of the receiver points in the shadow map.

    The depth is lowered by a receiver-slope bias of ``SLOPE_BIAS_TEXELS`` (4.5√2)
    texels times the depth change per texel along the receiver, applied alike to every
    technique and to the reference (each then subtracts its own constant bias,
    1e-3 for all here as HPG17 uses for NLQ). Without it, a plane lit at an angle
    has half of a 9×9 filter footprint in front of its own fragment and the exact
    filtered shadow (PCF) is 0.5 there: surface acne of the reference, not light
    leaking of a technique (HPG17 §5: PCF "with a higher depth bias").
    """
    h, w = size
    xy, depth = project_points(g.position, view_proj, (h, w))
    inside = (np.isfinite(depth) & (depth >= -1) & (depth <= 1)
              & (xy[:, 0] >= 0) & (xy[:, 0] <= w) & (xy[:, 1] >= 0) & (xy[:, 1] <= h))
    kind = g.kind.reshape(-1).copy()
    kind[g.pixel[~inside]] = OUTSIDE_LIGHT
    slope = _depth_slope(g.position[inside], g.normal[inside], view_proj, (h, w))
    return GBuffer(resolution=g.resolution, kind=kind.reshape(g.kind.shape), pixel=g.pixel[inside],
                   position=g.position[inside], lambert=g.lambert[inside], normal=g.normal[inside],
                   uv=xy[inside], depth=depth[inside] - SLOPE_BIAS_TEXELS * slope, slope=slope)


def _known_outputs():
    return (f"known techniques: {', '.join(_techniques.names())}; area-light outputs: "
            f"{', '.join(AREA_OUTPUTS)}")


def _positive_int(value, name):
    try:
        v = int(value)
        ok = v == value and v >= 1
    except (TypeError, ValueError):
        ok = False
    if not ok:
        raise InputError(f"area: expected {name} to be a positive integer, got {value!r}")
    return v


def area_settings(scene, full=False, *, map_size=None, light_samples=None, reference_views=None):
    """Settings of the area-light outputs (msm_soft, PCSS, VWSS, MVR and the MVR reference).

    Parameters
    ----------
    scene : Scene with an area light
    full : bool
        Paper scale (VWSS §4, Table 1): maps of the scene's ``shadow_map_size``
        (knot: 1024²), a reference of 512 light samples. Otherwise the reduced
        run: maps of :func:`reduced_settings` (knot: 512²), 64 reference samples.
    map_size, light_samples, reference_views : int, optional
        Overrides. ``light_samples`` (N, the VWSS and MVR maps) defaults to the
        scene's ``params.light_samples`` or 24 (VWSS Table 1) in both modes.

    Returns
    -------
    dict with ``map_size``, ``light_samples``, ``reference_views``,
    ``views_per_pass`` (8, warp passes as ``moments-ref vwss``) and ``seed`` (0;
    the reference uses ``seed + 1000``, as :func:`moments_ref.vwss.compare.run_detailed`).
    """
    size = tuple(scene.shadow_map_size) if full else reduced_settings(scene)[0]
    cfg = {"map_size": int(max(size)), "light_samples": int((scene.params or {}).get("light_samples", 24)),
           "reference_views": 512 if full else 64, "views_per_pass": 8, "seed": 0}
    for key, val in (("map_size", map_size), ("light_samples", light_samples),
                     ("reference_views", reference_views)):
        if val is not None:
            cfg[key] = _positive_int(val, key)
    return cfg


def _add_area_stages(g, scene, names, size, area, reference):
    """Add the area-light stages (module docstring) for ``names`` ⊆ AREA_OUTPUTS; return (info, cfg)."""
    from .raster import rasterize_depth
    from .techniques import msm_soft
    from .vwss import depth_range, generate_points, light_near, light_views, multiview_visibility, pcss, source_view
    from .vwss.compare import _mvr_iter, _shade_multiview
    from .vwss.mvr import mvr
    from .vwss.warp import warp

    cfg = {"map_size": int(max(size)), "light_samples": int((scene.params or {}).get("light_samples", 24)),
           "reference_views": 64, "views_per_pass": 8, "seed": 0, "bias": None}
    unknown = set(area or {}) - set(cfg)
    if unknown:
        raise InputError(f"area: unknown settings {sorted(unknown)}; known: {', '.join(cfg)}")
    cfg.update({k: v for k, v in (area or {}).items() if v is not None})
    for key in ("map_size", "light_samples", "reference_views", "views_per_pass"):
        cfg[key] = _positive_int(cfg[key], key)
    light = scene.light
    occ = scene.occluder_mesh(translucent=False)
    near, far = depth_range(light, occ.vertices, scene.receiver.vertices, near=light_near(scene))
    # World-space depth bias along the light normal: the default of `moments-ref vwss`.
    bias = 0.002 * far if cfg["bias"] is None else float(cfg["bias"])
    cfg.update({"near": near, "far": far, "bias": bias})
    m, n_views, seed = cfg["map_size"], cfg["light_samples"], int(cfg["seed"])

    def centre_map(ls1):
        return ls1, rasterize_depth(occ.vertices, occ.triangles, ls1.center_view_proj(), m)[0]

    def reference_visibility(gb):
        ls_ref = light_views(light, cfg["reference_views"], near, far, seed=seed + 1000)
        vis, _, _, _ = _shade_multiview(_mvr_iter(occ.vertices, occ.triangles, ls_ref, m, False), gb.position,
                                        ls_ref, bias, None)
        return 1.0 - vis

    info = {}
    ref = None
    if reference:
        ref = g.add("mvr_reference_vwss", ("light_projection",), reference_visibility)
    if {"msm_soft", "pcss"} & set(names):
        # One light sample is enough: only the shared projection, near and far are used.
        g.add("area_center_view", (), lambda: light_views(light, 1, near, far, seed=seed))
        g.add("area_center_depth_map", ("area_center_view",), centre_map)
    if {"vwss", "mvr"} & set(names):
        g.add("vwss_light_samples", (), lambda: light_views(light, n_views, near, far, seed=seed))
    for name in names:
        if name == "msm_soft":
            g.add("msm_soft_sat", ("area_center_depth_map",),
                  lambda c: msm_soft.prepare(c[1], c[0].light, c[0].center_view_proj()))
            g.add("shade_msm_soft", ("area_center_depth_map", "msm_soft_sat", "light_projection"),
                  lambda c, tex, gb: 1.0 - msm_soft.shade_points(c[0], tex, gb.position, bias=bias))
            steps = ["area_center_depth_map", "msm_soft_sat"]
        elif name == "pcss":
            g.add("shade_pcss", ("area_center_depth_map", "light_projection"),
                  lambda c, gb: 1.0 - pcss(gb.position, c[1][..., 0], c[0], bias))
            steps = ["area_center_depth_map"]
        elif name == "vwss":
            # Layered points of the enlarged source view (VWSS Eqs. (1)-(3), back faces culled).
            g.add("vwss_points", ("vwss_light_samples",),
                  lambda ls: generate_points(occ.vertices, occ.triangles, source_view(ls, m)))
            g.add("vwss_warp", ("vwss_points", "vwss_light_samples"),
                  lambda pc, ls: warp(pc.positions, ls, m, cfg["views_per_pass"]))
            g.add("shade_vwss", ("vwss_warp", "vwss_light_samples", "light_projection"),
                  lambda maps, ls, gb: 1.0 - multiview_visibility(gb.position, maps, ls, bias))
            steps = ["vwss_points", "vwss_warp"]
        else:  # mvr: the same N light samples rasterized
            g.add("mvr_vwss", ("vwss_light_samples",), lambda ls: mvr(occ.vertices, occ.triangles, ls, m)[0])
            g.add("shade_mvr_vwss", ("mvr_vwss", "vwss_light_samples", "light_projection"),
                  lambda maps, ls, gb: 1.0 - multiview_visibility(gb.position, maps, ls, bias))
            steps = ["mvr_vwss"]
        shade = "shade_mvr_vwss" if name == "mvr" else f"shade_{name}"
        info[name] = {"steps": steps, "shade": shade, "reference": ref}
    return info, cfg


def plan(scene, outputs=None, *, shadow_map_size=None, msaa=None, resolution=None, reference=True,
         noise_tiles=64, frame=0, params=None, area=None):
    """Build the stage graph; return ``(graph, targets, info)`` without running anything.

    Parameters as :func:`run`. ``info`` maps each technique to its texture-step
    names, its shade stage and its reference stage.
    """
    check_scene(scene)
    names = list(dict.fromkeys(scene.outputs if outputs is None else outputs))
    if not names:
        raise InputError(f"outputs: scene {scene.name!r} requests no outputs; {_known_outputs()}")
    light_kind = getattr(scene.light, "kind", "directional")
    for n in names:
        if n not in AREA_OUTPUTS and n not in _techniques.TECHNIQUES:
            raise InputError(f"technique: unknown technique {n!r}; {_known_outputs()}")
    area_names = [n for n in names if n in AREA_OUTPUTS]
    if area_names and light_kind != "area":
        raise InputError(f"outputs: {', '.join(map(repr, area_names))} need an area light (soft shadows against "
                         f"multi-view rasterization); scene {scene.name!r} has a {light_kind} light")
    techs = [_techniques.get(n) for n in names if n not in AREA_OUTPUTS]
    for t in techs:
        if light_kind not in t.light_kinds or (t.multiview and light_kind != "area"):
            raise InputError(f"outputs: technique {t.name!r} needs a light of kind {' or '.join(t.light_kinds)}"
                             f"{' (multi-view: an area light)' if t.multiview else ''}; scene {scene.name!r} "
                             f"has a {light_kind} light")
    translucent = _has_translucent(scene)
    for t in techs:
        if t.requires_translucency and not translucent:
            raise InputError(f"outputs: technique {t.name!r} renders translucent occluders and scene "
                             f"{scene.name!r} has none (its opaque equivalent is msm64)")
    size = tuple(scene.shadow_map_size) if shadow_map_size is None else (
        (shadow_map_size, shadow_map_size) if np.isscalar(shadow_map_size) else tuple(shadow_map_size))
    samples = scene.msaa if msaa is None else int(msaa)
    res = tuple(scene.camera.resolution) if resolution is None else tuple(resolution)
    p = {**scene.params, **(params or {})}
    view_proj = scene.shadow_view_proj()

    g = _Graph()
    g.add("raster_shadow_map", (), lambda: scene.shadow_map(size=size, samples=samples)[0])
    if translucent:
        def _layers(opaque):
            m = scene.occluder_mesh(translucent=True)
            alpha = scene.occluder_opacity[scene.occluder_translucent]
            return _techniques.translucent.translucency_pass(opaque, m.vertices, m.triangles, alpha, view_proj)
        g.add("translucency_pass", ("raster_shadow_map",), _layers)
    g.add("camera_gbuffer", (), lambda: _camera_gbuffer(scene, res))
    g.add("light_projection", ("camera_gbuffer",), lambda gb: _light_projection(gb, view_proj, size))

    def _noise(textures, gb):
        from .bluenoise import frame_noise

        w, h = gb.resolution
        return frame_noise(frame, (h, w), textures).reshape(h * w, -1)[gb.pixel]

    targets, info = [], {}
    for t in techs:
        layered = t.translucency and translucent
        node = "translucency_pass" if layered else "raster_shadow_map"
        step_names = []
        for step in t.steps(samples, layered):
            node = g.add(step.name, (node,), (lambda s, d: lambda x: s.fn(x, d))(step, {**t.defaults, **p}))
            step_names.append(step.name)
        deps = [node, "light_projection"]
        if t.needs_noise:
            from .bluenoise import blue_noise_textures

            g.add("bluenoise_textures", (), lambda: blue_noise_textures(count=noise_tiles))
            g.add("frame_noise", ("bluenoise_textures", "light_projection"), _noise)
            deps.append("frame_noise")

        def _shade(tex, gb, noise=None, t=t):
            return t.shadow(tex, gb.uv, gb.depth, noise=noise)

        shade = g.add(f"shade_{t.name}", deps, _shade)
        targets.append(shade)
        ref = None
        if reference:
            ref_src = "translucency_pass" if translucent else "raster_shadow_map"
            ref = (f"translucency_reference_bias{t.depth_bias:g}" if translucent
                   else f"reference_pcf_bias{t.depth_bias:g}")
            g.add(ref, (ref_src, "light_projection"),
                  (lambda b: lambda maps, gb: _techniques.pcf.pcf_filtered(maps, gb.uv, gb.depth - b))(t.depth_bias))
            targets.append(ref)
        info[t.name] = {"steps": step_names, "shade": shade, "reference": ref}
    bits = {t.name: t.bits_per_texel for t in techs}
    area_cfg = {}
    if area_names:
        area_info, area_cfg = _add_area_stages(g, scene, area_names, size, area, reference)
        for n in area_names:
            i = area_info[n]
            targets.append(i["shade"])
            if i["reference"]:
                targets.append(i["reference"])
            info[n] = i
            bits[n] = AREA_BITS_PER_TEXEL[n]
    order = [n for n in names if n in info]
    meta = {"size": size, "samples": samples, "resolution": res, "info": {n: info[n] for n in order},
            "techniques": order, "bits_per_texel": bits, "area": area_cfg}
    return g, list(dict.fromkeys(targets)), meta


def run(scene, outputs=None, *, shadow_map_size=None, msaa=None, resolution=None, reference=True,
        noise_tiles=64, frame=0, params=None, area=None, progress=False):
    """Compute the requested techniques' shadows on a scene's camera view, lazily.

    Parameters
    ----------
    scene : Scene or str
        A loaded scene, a shipped scene name or a scene file path.
    outputs : list of str, optional
        Technique names and area-light outputs (:data:`AREA_OUTPUTS`; default:
        the scene's ``outputs``). Unknown names raise
        :class:`~moments_ref.InputError` listing the known ones.
    shadow_map_size : int or (H, W), optional
        Default: the scene's.
    msaa : int, optional
        Samples per shadow-map texel; default the scene's.
    resolution : (width, height), optional
        Camera resolution; default the scene's.
    reference : bool
        Also compute the reference (filtered hard shadow, or the product of
        transmittances with translucent occluders) at each technique's depth bias.
    noise_tiles : int
        Blue-noise tiles generated (HPG17 §4.2: 64).
    frame : int
        Frame number selecting the blue-noise tile and offsets.
    params : dict, optional
        Overrides of the scene's ``params`` passed to the technique steps.
    area : dict, optional
        Settings of the area-light outputs (:data:`AREA_OUTPUTS`): ``map_size``
        (default the larger side of ``shadow_map_size``), ``light_samples`` (N,
        default ``params.light_samples`` or 24), ``reference_views`` (R, default
        64), ``views_per_pass`` (8), ``seed`` (0) and ``bias`` (world units,
        default ``0.002 · far``); see :func:`area_settings`.
    progress : bool
        Show a tqdm progress bar of the stages on stderr.

    Returns
    -------
    RunResult
    """
    if not hasattr(scene, "receiver"):
        from .scene import load_scene

        scene = load_scene(scene)
    g, targets, meta = plan(scene, outputs, shadow_map_size=shadow_map_size, msaa=msaa, resolution=resolution,
                            reference=reference, noise_tiles=noise_tiles, frame=frame, params=params, area=area)
    order, values, seconds = g.run(targets, progress=progress, desc=scene.name)
    info = meta["info"]
    gb = values["light_projection"]
    shadow = {n: values[i["shade"]] for n, i in info.items()}
    ref = {n: values[i["reference"]] for n, i in info.items() if i["reference"]}
    texel = {n: float(sum(seconds[s] for s in i["steps"])) for n, i in info.items()}
    frag = {n: float(seconds[i["shade"]]) for n, i in info.items()}
    return RunResult(scene=scene, techniques=meta["techniques"], stages=order, seconds=seconds, gbuffer=gb,
                     shadow=shadow, reference=ref, texel_seconds=texel, fragment_seconds=frag,
                     shadow_map_size=meta["size"], msaa=meta["samples"], values=values,
                     bits_per_texel=meta["bits_per_texel"], area=meta["area"])


# ---------------------------------------------------------------------------
# Prefiltered single scattering (rows of techniques.scattering.report_rows)


@dataclass
class ScatteringResult:
    """What :func:`run_scattering` computed.

    Attributes
    ----------
    rows : list of dict with the columns of :data:`moments_ref.report.COLUMNS`
    images : dict name -> (H, W) scattering term (``reference`` included)
    t_max : float, the normalization of the scattering term (longest view ray)
    stages : list of str, the stages ``report_rows`` ran (:func:`scattering_stages`)
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
    """Names of the stages :func:`moments_ref.techniques.scattering.report_rows` runs, in order.

    ``scattering_raster_shadow_map`` (the light's MSAA map), ``scattering_camera_rays``,
    ``scattering_raymarch_reference`` (ray marching with the reference sample
    count), per six-moment technique its texture steps (``Technique.steps``; the
    shared names ``resolve_moments``/``compute_moments`` and ``blur_moments`` get the
    prefix ``scattering_`` since they run again inside that call) and its lookup
    ``shade_<technique>``, then ``scattering_raymarch`` (the slides' 128 samples).
    """
    from .techniques.scattering import SCATTERING_TECHNIQUES

    out = ["scattering_raster_shadow_map", "scattering_camera_rays", "scattering_raymarch_reference"]
    for name, tech in SCATTERING_TECHNIQUES.items():
        for step in tech.steps(int(samples), False):
            out.append(step.name if step.name.startswith("scattering_") else "scattering_" + step.name)
        out.append(f"shade_{name}")
    out.append("scattering_raymarch")
    return out


def run_scattering(scene, *, shadow_map_size=None, msaa=None, resolution=None, epipolar_size=None,
                   reference_samples=None, raymarch_samples=None):
    """Rows of the prefiltered single-scattering outputs of a scene with a directional light.

    Parameters
    ----------
    scene : Scene or str
        A scene whose ``outputs`` name :data:`SCATTERING_OUTPUTS` (shipped: ``scattering``).
    shadow_map_size, msaa, resolution, epipolar_size, reference_samples, raymarch_samples
        As :func:`moments_ref.techniques.scattering.report_rows` (defaults: the
        scene's; the reference ray marching uses ``params.reference_samples`` or 4096).

    Returns
    -------
    ScatteringResult

    Notes
    -----
    The rows come unchanged from ``report_rows``: the error is that of the
    scattering term normalized by ``t_max`` against ray marching with the
    reference sample count. Its images are returned, not written (the report
    writes every file at the end).
    """
    from .techniques import scattering

    if not hasattr(scene, "receiver"):
        from .scene import load_scene

        scene = load_scene(scene)
    check_scene(scene)
    t0 = time.perf_counter()
    rows, images = scattering.report_rows(scene, shadow_map_size=shadow_map_size, msaa=msaa, resolution=resolution,
                                          epipolar_size=epipolar_size, reference_samples=reference_samples,
                                          raymarch_samples=raymarch_samples)
    seconds = time.perf_counter() - t0
    # t_max depends on the eye and the scene's bounding box only, not on the resolution.
    _, t_max = scattering.camera_rays(scene, (1, 1))
    samples = scene.msaa if msaa is None else int(msaa)
    params = scene.params or {}
    settings = {"shadow_map_size": shadow_map_size or tuple(scene.shadow_map_size), "msaa": samples,
                "resolution": tuple(resolution) if resolution is not None else tuple(scene.camera.resolution),
                "epipolar_size": tuple(epipolar_size or params.get("epipolar_size", scattering.EPIPOLAR_SIZE)),
                "reference_samples": int(reference_samples or params.get("reference_samples", 4096)),
                "raymarch_samples": int(raymarch_samples or params.get("raymarch_samples", 128))}
    return ScatteringResult(rows=rows, images=images, t_max=float(t_max), stages=scattering_stages(samples),
                            seconds=seconds, settings=settings)
