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

:attr:`RunResult.stages` records the stages that ran, in order; a stage name
contains ``translucen`` only for translucency work and ``vwss`` only for
multi-view work (none of the techniques here does multi-view work; a
registered technique with ``multiview`` is refused without an area light).

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

__all__ = ["GBuffer", "RunResult", "run", "plan", "reduced_settings", "check_scene"]

#: kind image codes of :class:`GBuffer`.
BACKGROUND, RECEIVER, OCCLUDER, OUTSIDE_LIGHT = 0, 1, 2, 3


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


def plan(scene, outputs=None, *, shadow_map_size=None, msaa=None, resolution=None, reference=True,
         noise_tiles=64, frame=0, params=None):
    """Build the stage graph; return ``(graph, targets, info)`` without running anything.

    Parameters as :func:`run`. ``info`` maps each technique to its texture-step
    names, its shade stage and its reference stage.
    """
    check_scene(scene)
    names = list(scene.outputs) if outputs is None else list(outputs)
    if not names:
        raise InputError(f"outputs: scene {scene.name!r} requests no outputs; known techniques: "
                         f"{', '.join(_techniques.names())}")
    techs = [_techniques.get(n) for n in names]
    light_kind = getattr(scene.light, "kind", "directional")
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
    meta = {"size": size, "samples": samples, "resolution": res, "info": info,
            "techniques": [t.name for t in techs]}
    return g, list(dict.fromkeys(targets)), meta


def run(scene, outputs=None, *, shadow_map_size=None, msaa=None, resolution=None, reference=True,
        noise_tiles=64, frame=0, params=None, progress=False):
    """Compute the requested techniques' shadows on a scene's camera view, lazily.

    Parameters
    ----------
    scene : Scene or str
        A loaded scene, a shipped scene name or a scene file path.
    outputs : list of str, optional
        Technique names (default: the scene's ``outputs``). Unknown names raise
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
                            reference=reference, noise_tiles=noise_tiles, frame=frame, params=params)
    order, values, seconds = g.run(targets, progress=progress, desc=scene.name)
    info = meta["info"]
    gb = values["light_projection"]
    shadow = {n: values[i["shade"]] for n, i in info.items()}
    ref = {n: values[i["reference"]] for n, i in info.items() if i["reference"]}
    texel = {n: float(sum(seconds[s] for s in i["steps"])) for n, i in info.items()}
    frag = {n: float(seconds[i["shade"]]) for n, i in info.items()}
    return RunResult(scene=scene, techniques=meta["techniques"], stages=order, seconds=seconds, gbuffer=gb,
                     shadow=shadow, reference=ref, texel_seconds=texel, fragment_seconds=frag,
                     shadow_map_size=meta["size"], msaa=meta["samples"], values=values)
