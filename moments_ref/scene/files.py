"""Scene files (TOML) and the :class:`Scene` they describe.

A scene file holds::

    name = "railing"                 # optional, defaults to the file stem
    description = "..."              # optional
    shadow_map_size = 1024           # int or [H, W]
    msaa = 4                         # 1, 4 or 8
    outputs = ["msm", "nlq64"]       # stored as given; a runner interprets them

    [params]                         # optional; the keys of _checks.PARAMS, stored as Scene.params

    [light]                          # type = "directional" | "area"
    type = "directional"
    direction = [0.2, -1.0, 0.5]     # directional: the direction light travels
    # area: center, normal, width, height, optional up, fov (degrees)

    [camera]                         # the shaded view
    eye = [0, 2, 5]
    target = [0, 0, 0]
    up = [0, 1, 0]                   # optional
    fov = 45                         # vertical, degrees
    resolution = [1280, 720]         # width, height
    # near, far optional

    [[objects]]
    name = "ground"
    generator = "plane"              # or: obj = "path/relative/to/the/scene.obj"
    params = { width = 6, depth = 4 }
    transform = [ { scale = 2 }, { rotate = { axis = [0, 1, 0], degrees = 30 } },
                  { translate = [0, 0, 1] } ]   # applied in this order
    role = "receiver"                # "receiver", "occluder" or "both"
    translucent = false              # optional; with opacity in (0, 1]
    opacity = 1.0
    texel_offset = [2, 0, 0]         # optional: a translation in shadow-map texels, after transform

Texel offsets. A configuration defined by the filter's footprint (HPG17 Figure 9:
three occluders within one 9×9 filter region, §4.1) is a size in texels, not in
world units: ``texel_offset`` moves an object by that many texels of the run's
shadow map (world axes, unit :meth:`Scene.texel_size`), so that the configuration is
the same at every map size. A loaded scene holds them resolved for its own
``shadow_map_size``; :meth:`Scene.shadow_map` and the pipeline resolve them for the map
they rasterize (:meth:`Scene.at_shadow_map`).
Directional lights only (an area light's perspective texels vary over the map).
The unit is measured on the scene's own hull, so offsets are meant for objects
inside the hull of the others (moving the hull would move the unit).

Roles: occluders are drawn into the shadow map; receivers are the surfaces whose
shadowing is evaluated; "both" puts an object in both sets (HPG17 Figure 1: the
banner receives the railing's shadow and shadows the ground).

Errors name the file, the key (``objects[2].generator``) and the problem.

Scene files come from other people (:mod:`._checks`): before anything is built,
nesting is bounded (:data:`~._checks.MAX_NESTING`), every number is finite and at
most :data:`~._checks.MAX_MAGNITUDE` in magnitude, the name is data and not a path
(no ``/``, ``\\``, ``..``, control characters, at most
:data:`~._checks.MAX_NAME_BYTES` bytes), and every ``[params]`` key is known
(:data:`~._checks.PARAMS`) with a value of its type and range.

Memory. A scene is refused at load, before anything is allocated, when its
geometry (:data:`~moments_ref.scene.mesh.BYTES_PER_ELEMENT` per vertex and
triangle), its camera image (:data:`~moments_ref.scene.camera.BYTES_PER_PIXEL`)
or its shadow map (:data:`BYTES_PER_SAMPLE` per texel and sample) would exceed
:func:`moments_ref._arrays.max_memory` (4 GiB unless raised, ``--max-memory`` on
the command line).

References
----------
.. [1] HPG17: Christoph Peters. 2017. *Non-Linearly Quantized Moment Shadow Maps*. In Proceedings
       of High Performance Graphics (HPG '17). ACM. The non-linear quantization Φ, Ψ4, Algorithms
       1–3, the texel formats and the compute shader of §4.1.
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass, field, replace
from importlib import resources
from pathlib import Path

import numpy as np

from .._arrays import InputError, check_memory
from .._shim import alias
from ._checks import Ctx, check_document, check_name, check_params, check_text
from .raster import SAMPLE_COUNTS, MAX_SIZE, rasterize_depth
from .camera import Camera
from .lights import AreaLight, DirectionalLight
from .mesh import GENERATORS, Mesh, merge, read_obj, rotate, scale, translate

__all__ = ["Scene", "SceneObject", "load_scene", "list_scenes", "ROLES", "BYTES_PER_SAMPLE", "shadow_map_memory"]

#: Memory estimate of a shadow map per texel and MSAA sample: the float32 depth,
#: its float64 moments after the resolve and the filter's temporaries.
BYTES_PER_SAMPLE = 64


def shadow_map_memory(size, samples) -> int:
    """Estimated bytes of a ``size`` (int or (H, W)) shadow map with ``samples`` MSAA samples."""
    h, w = (size, size) if np.isscalar(size) else size
    return BYTES_PER_SAMPLE * int(h) * int(w) * int(samples)

ROLES = ("receiver", "occluder", "both")
_TOP_KEYS = {"name", "description", "shadow_map_size", "msaa", "outputs", "params", "light", "camera", "objects"}
_OBJ_KEYS = {"name", "generator", "obj", "params", "transform", "role", "translucent", "opacity", "texel_offset"}


@dataclass(frozen=True)
class SceneObject:
    """One entry of ``objects``: its name, role, translucency, triangle count and texel offset."""

    name: str
    role: str
    translucent: bool
    opacity: float
    n_triangles: int
    texel_offset: tuple = (0.0, 0.0, 0.0)


@dataclass
class Scene:
    """A loaded scene: geometry merged per role, light, camera and parameters.

    Attributes
    ----------
    name, description : str
    path : Path of the scene file
    receiver : Mesh, all objects with role receiver or both
    occluder : Mesh, all objects with role occluder or both
    receiver_object, occluder_object : (T,) int64, index into ``objects`` per triangle
    occluder_translucent : (T_occ,) bool per occluder triangle
    occluder_opacity : (T_occ,) float64 per occluder triangle (1 for opaque)
    objects : tuple of SceneObject
    light : DirectionalLight or AreaLight
    camera : Camera
    shadow_map_size : (H, W)
    msaa : int
    outputs : tuple of str
    params : dict
    texel_shift : float, the world size of the texel the objects' ``texel_offset``
        are resolved for (:meth:`at_shadow_map`; 0 without offsets)
    """

    name: str
    description: str
    path: Path
    receiver: Mesh
    occluder: Mesh
    receiver_object: np.ndarray
    occluder_object: np.ndarray
    occluder_translucent: np.ndarray
    occluder_opacity: np.ndarray
    objects: tuple
    light: object
    camera: Camera
    shadow_map_size: tuple
    msaa: int
    outputs: tuple
    params: dict = field(default_factory=dict)
    texel_shift: float = 0.0

    def bounds(self) -> np.ndarray:
        """(2, 3) bounding box of all geometry."""
        v = np.concatenate([self.receiver.vertices, self.occluder.vertices])
        return np.stack([v.min(0), v.max(0)])

    def light_clip_from_world(self, eye=None) -> np.ndarray:
        """The light's shadow-map matrix: world to the light's clip coordinates.

        Directional light: orthographic, fitted to all scene vertices (HPG17 §5).
        Area light: perspective from ``eye`` on the light (default its centre).
        """
        pts = np.concatenate([self.receiver.vertices, self.occluder.vertices])
        if isinstance(self.light, DirectionalLight):
            return self.light.clip_from_world(pts)
        return self.light.clip_from_world(pts, eye=eye)

    #: Old name (DeprecationWarning).
    shadow_view_proj = alias("light_clip_from_world")

    def texel_size(self, size=None) -> float:
        """World width of one texel of the directional light's map at ``size`` (default the scene's own).

        The larger side of a texel: ``2 / (W |row 0|)`` and ``2 / (H |row 1|)`` of the
        orthographic :meth:`light_clip_from_world` (HPG17 §5: fitted to the scene's hull).
        """
        if not isinstance(self.light, DirectionalLight):
            raise InputError(f"scene {self.name!r}: texel_size needs a directional light (an area light's "
                             "perspective texels vary over its map)")
        h, w = _size_hw(self.shadow_map_size if size is None else size)
        rows = np.linalg.norm(self.light_clip_from_world()[:2, :3], axis=1)
        return float(max(2.0 / (w * rows[0]), 2.0 / (h * rows[1])))

    def at_shadow_map(self, size=None) -> "Scene":
        """The scene with its objects' ``texel_offset`` resolved for a shadow map of ``size``.

        Each object moves by ``texel_offset × texel_size(size)`` (world axes); a scene
        without offsets is returned as it is. Resolving again for another size moves
        by the difference (:attr:`texel_shift` records the unit applied).
        """
        offsets = np.array([o.texel_offset for o in self.objects], dtype=np.float64).reshape(-1, 3)
        if not offsets.any():
            return self
        t = self.texel_size(size)
        if t == self.texel_shift:
            return self
        step = (t - self.texel_shift) * offsets
        return replace(self, receiver=_moved(self.receiver, self.receiver_object, step),
                       occluder=_moved(self.occluder, self.occluder_object, step), texel_shift=t)

    def occluder_mesh(self, translucent=None, exclude=()) -> Mesh:
        """Occluder triangles: all (None), only opaque (False) or only translucent (True),
        leaving out the objects named in ``exclude``."""
        keep = np.ones(self.occluder.n_triangles, bool)
        if translucent is not None:
            keep &= self.occluder_translucent == bool(translucent)
        for name in exclude:
            idx = [i for i, o in enumerate(self.objects) if o.name == name]
            keep &= ~np.isin(self.occluder_object, idx)
        return Mesh(self.occluder.vertices, self.occluder.triangles[keep])

    def shadow_map(self, size=None, samples=None, translucent=False, exclude=(), cull="none"):
        """Rasterize the occluders into the light's depth map.

        Returns ``(depth (H, W, S) float32, stats)`` from :func:`moments_ref.scene.raster.rasterize_depth`.
        """
        size = self.shadow_map_size if size is None else size
        samples = self.msaa if samples is None else samples
        if np.isscalar(samples) and (np.isscalar(size) or len(size) == 2):
            check_memory(shadow_map_memory(size, samples), f"shadow map {size} with {samples} samples")
        own = self.at_shadow_map(size)  # objects placed in texels (texel_offset): for this map
        m = own.occluder_mesh(translucent=translucent, exclude=exclude)
        return rasterize_depth(m.vertices, m.triangles, own.light_clip_from_world(),
                               size, samples=samples, cull=cull)


def _size_hw(size):
    return (int(size), int(size)) if np.isscalar(size) else (int(size[0]), int(size[1]))


def _moved(mesh, triangle_object, step):
    """``mesh`` with each vertex moved by ``step`` of the object its triangles belong to."""
    obj = np.full(len(mesh.vertices), -1, dtype=np.int64)
    obj[mesh.triangles] = np.asarray(triangle_object, dtype=np.int64)[:, None]
    move = np.where((obj >= 0)[:, None], step[np.maximum(obj, 0)], 0.0)
    return Mesh(mesh.vertices + move, mesh.triangles)


#: Largest entry of an object's composed transform (a scene 1e9 wide scaled by 1e9 still fits float64 products).
MAX_TRANSFORM = 1e18


def _transform(ctx, steps, where):
    if not isinstance(steps, list):
        raise ctx.error(where, f"wrong type: expected a list of tables, got {type(steps).__name__}")
    m = np.eye(4)
    for i, step in enumerate(steps):
        w = f"{where}[{i}]"
        if not isinstance(step, dict) or len(step) != 1:
            raise ctx.error(w, f"expected a table with one of translate, rotate, scale, got {step!r}")
        (kind, val), = step.items()
        if kind == "translate":
            m = translate(ctx.vec3(step, "translate", f"{w}.")) @ m
        elif kind == "rotate":
            if not isinstance(val, dict):
                raise ctx.error(f"{w}.rotate", f"wrong type: expected {{ axis = [x, y, z], degrees = a }}, got {val!r}")
            ctx.unknown(val, {"axis", "degrees"}, f"{w}.rotate.")
            axis = ctx.vec3(val, "axis", f"{w}.rotate.")
            if not np.any(axis):
                raise ctx.error(f"{w}.rotate.axis", "expected a non-zero axis")
            m = rotate(axis, ctx.number(val, "degrees", f"{w}.rotate.")) @ m
        elif kind == "scale":
            if isinstance(val, list):
                f = ctx.vec3(step, "scale", f"{w}.")
            else:
                f = ctx.number(step, "scale", f"{w}.")
            if np.any(np.asarray(f) == 0):
                raise ctx.error(f"{w}.scale", "expected non-zero factors")
            m = scale(f) @ m
        else:
            raise ctx.error(f"{w}.{kind}", "unknown transform (expected translate, rotate or scale)")
        with np.errstate(over="ignore", invalid="ignore"):
            big = not np.all(np.abs(m) <= MAX_TRANSFORM)
        if big:  # each number is bounded, their product is not: refused before any vertex overflows
            raise ctx.error(w, f"the transform so far scales beyond {MAX_TRANSFORM:g} (its steps multiply)")
    return m


def _object(ctx, obj, i, base):
    where = f"objects[{i}]"
    if not isinstance(obj, dict):
        raise ctx.error(where, f"wrong type: expected a table, got {type(obj).__name__}")
    ctx.unknown(obj, _OBJ_KEYS, f"{where}.")
    name = obj.get("name", f"object{i}")
    if not isinstance(name, str):
        raise ctx.error(f"{where}.name", f"wrong type: expected a string, got {name!r}")
    if ("generator" in obj) == ("obj" in obj):
        raise ctx.error(where, "expected exactly one of 'generator' or 'obj'")
    params = ctx.table(obj, "params", f"{where}.", required=False)
    if "generator" in obj:
        gen = obj["generator"]
        if not isinstance(gen, str) or gen not in GENERATORS:
            raise ctx.error(f"{where}.generator", f"unknown generator {gen!r} (known: {', '.join(GENERATORS)})")
        try:
            mesh = GENERATORS[gen](**params)
        except TypeError as exc:
            raise ctx.error(f"{where}.params", f"bad parameters for generator {gen!r}: {exc}") from None
        except (InputError, ValueError) as exc:
            raise ctx.error(f"{where}.params", str(exc)) from None
    else:
        rel = obj["obj"]
        if not isinstance(rel, str):
            raise ctx.error(f"{where}.obj", f"wrong type: expected a path string, got {rel!r}")
        if params:
            raise ctx.error(f"{where}.params", "OBJ objects take no params")
        p = Path(rel) if Path(rel).is_absolute() else base / rel
        if not p.is_file():
            raise ctx.error(f"{where}.obj", f"OBJ file not found: {p}")
        mesh = read_obj(p)
    if "transform" in obj:
        mesh = mesh.transformed(_transform(ctx, obj["transform"], f"{where}.transform"))
    role = obj.get("role")
    if role is None:
        raise ctx.error(f"{where}.role", f"missing (expected one of {', '.join(ROLES)})")
    if role not in ROLES:
        raise ctx.error(f"{where}.role", f"expected one of {', '.join(ROLES)}, got {role!r}")
    translucent = obj.get("translucent", False)
    if not isinstance(translucent, bool):
        raise ctx.error(f"{where}.translucent", f"wrong type: expected true or false, got {translucent!r}")
    opacity = ctx.number(obj, "opacity", f"{where}.", default=1.0 if not translucent else None)
    if not (0 < opacity <= 1):
        raise ctx.error(f"{where}.opacity", f"expected a value in (0, 1], got {opacity}")
    if opacity < 1 and not translucent:
        raise ctx.error(f"{where}.opacity", "an opacity below 1 needs translucent = true")
    if translucent and role == "receiver":
        raise ctx.error(f"{where}.translucent", "a translucent object must be an occluder (role occluder or both)")
    offset = tuple(float(x) for x in ctx.vec3(obj, "texel_offset", f"{where}.")) if "texel_offset" in obj else (
        0.0, 0.0, 0.0)
    return SceneObject(name, role, translucent, opacity, mesh.n_triangles, offset), mesh


def _light(ctx, t):
    kind = t.get("type")
    if kind == "directional":
        ctx.unknown(t, {"type", "direction"}, "light.")
        d = ctx.vec3(t, "direction", "light.")
        if not np.any(d):
            raise ctx.error("light.direction", "expected a non-zero direction")
        return DirectionalLight(d)
    if kind == "area":
        ctx.unknown(t, {"type", "center", "normal", "width", "height", "up", "fov"}, "light.")
        try:
            return AreaLight(ctx.vec3(t, "center", "light."), ctx.vec3(t, "normal", "light."),
                             ctx.number(t, "width", "light.", positive=True),
                             ctx.number(t, "height", "light.", positive=True),
                             ctx.vec3(t, "up", "light.") if "up" in t else None,
                             ctx.number(t, "fov", "light.", default=90.0))
        except InputError as exc:
            if str(exc).startswith("scene file"):
                raise
            raise ctx.error("light", str(exc)) from None
    raise ctx.error("light.type", f"expected 'directional' or 'area', got {kind!r}")


def _camera(ctx, t):
    ctx.unknown(t, {"eye", "target", "up", "fov", "resolution", "near", "far"}, "camera.")
    res = t.get("resolution", [1280, 720])
    if (not isinstance(res, list) or len(res) != 2
            or not all(isinstance(x, int) and not isinstance(x, bool) and x > 0 for x in res)):
        raise ctx.error("camera.resolution", f"wrong type: expected [width, height] positive integers, got {res!r}")
    try:
        return Camera(ctx.vec3(t, "eye", "camera."), ctx.vec3(t, "target", "camera."),
                      ctx.vec3(t, "up", "camera.", default=(0.0, 1.0, 0.0)),
                      ctx.number(t, "fov", "camera.", default=45.0), tuple(res),
                      ctx.number(t, "near", "camera.", default=0.05, positive=True),
                      ctx.number(t, "far", "camera.", default=100.0, positive=True))
    except InputError as exc:
        if str(exc).startswith("scene file"):
            raise
        raise ctx.error("camera", str(exc)) from None


def _shadow_settings(ctx, doc):
    """``shadow_map_size`` as [H, W] and ``msaa``, checked, within the memory limit."""
    size = doc.get("shadow_map_size", 1024)
    hw = [size, size] if isinstance(size, int) and not isinstance(size, bool) else size
    if (not isinstance(hw, list) or len(hw) != 2
            or not all(isinstance(x, int) and not isinstance(x, bool) and 1 <= x <= MAX_SIZE for x in hw)):
        raise ctx.error("shadow_map_size", f"expected an integer or [H, W] in [1, {MAX_SIZE}], got {size!r}")
    msaa = doc.get("msaa", 1)
    if isinstance(msaa, bool) or msaa not in SAMPLE_COUNTS:
        raise ctx.error("msaa", f"expected one of the supported sample counts {SAMPLE_COUNTS}, got {msaa!r}")
    try:
        check_memory(shadow_map_memory(hw, msaa), f"shadow_map_size {hw[0]}×{hw[1]} with msaa {msaa}")
    except InputError as exc:
        raise ctx.error("shadow_map_size", str(exc)) from None
    return hw, msaa


def _scenes_dir():
    return resources.files("moments_ref.scene") / "scenes"


def list_scenes() -> list[str]:
    """Names of the shipped scenes (``moments_ref/scene/scenes/*.toml``), sorted."""
    return sorted(p.name[:-5] for p in _scenes_dir().iterdir() if p.name.endswith(".toml"))


def _resolve(name_or_path) -> Path:
    s = str(name_or_path)
    p = Path(s)
    if p.suffix == ".toml" or p.exists():
        if not p.is_file():
            kind = "a folder" if p.is_dir() else "not a regular file" if p.exists() else "not found"
            raise InputError(f"scene file {p}: {kind} (expected a .toml file)")
        check_memory(64 * p.stat().st_size, f"scene file {p}")
        return p
    if s in list_scenes():
        return Path(str(_scenes_dir() / f"{s}.toml"))
    raise InputError(f"scene: unknown scene {s!r}; known scenes: {', '.join(list_scenes())} "
                     "(or give the path of a .toml file)")


def _read_document(ctx, path):
    """The parsed TOML of ``path``, its nesting and numbers bounded (:mod:`._checks`)."""
    try:
        text = path.read_text(encoding="utf-8")
        check_text(ctx, text)
        doc = tomllib.loads(text)
    except InputError:
        raise
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"scene file {path}: not valid TOML ({exc})") from None
    except UnicodeDecodeError as exc:
        raise InputError(f"scene file {path}: not UTF-8 text (byte {exc.object[exc.start]:#04x} at "
                         f"offset {exc.start})") from None
    except OSError as exc:
        raise InputError(f"scene file {path}: cannot read ({exc.strerror})") from None
    except (RecursionError, ValueError) as exc:  # nesting the scan missed; an integer of over 4300 digits
        raise InputError(f"scene file {path}: not a scene file TOML can read ({str(exc)[:80]})") from None
    check_document(ctx, doc)
    return doc


def load_scene(name_or_path) -> Scene:
    """Load a shipped scene by name or a scene file by path.

    Parameters
    ----------
    name_or_path : str or Path
        One of :func:`list_scenes` or the path of a ``.toml`` file.

    Returns
    -------
    Scene

    Raises
    ------
    InputError
        Unknown name (listing the known ones), unreadable TOML, or a bad entry:
        the message names the file, the key and the problem.
    """
    path = _resolve(name_or_path)
    ctx = Ctx(path)
    doc = _read_document(ctx, path)
    ctx.unknown(doc, _TOP_KEYS, "")
    # The name and the parameters first: a scene refused for them costs nothing.
    name = check_name(ctx, doc.get("name", path.stem), "name" if "name" in doc else "name (the file name)")
    desc = doc.get("description", "")
    if not isinstance(desc, str):
        raise ctx.error("description", f"wrong type: expected a string, got {desc!r}")
    params = check_params(ctx, ctx.table(doc, "params", required=False))
    hw, msaa = _shadow_settings(ctx, doc)
    outputs = doc.get("outputs", [])
    if not isinstance(outputs, list) or not all(isinstance(o, str) for o in outputs):
        raise ctx.error("outputs", f"wrong type: expected a list of strings, got {outputs!r}")
    light = _light(ctx, ctx.table(doc, "light"))
    camera = _camera(ctx, ctx.table(doc, "camera"))

    objs = doc.get("objects")
    if objs is None:
        raise ctx.error("objects", "missing (expected an array of [[objects]] tables)")
    if not isinstance(objs, list) or not objs:
        raise ctx.error("objects", "wrong type: expected a non-empty array of [[objects]] tables")
    infos, meshes = zip(*(_object(ctx, o, i, path.parent) for i, o in enumerate(objs)))
    names = [o.name for o in infos]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise ctx.error("objects", f"duplicate object name {dup[0]!r}")

    rec = [i for i, o in enumerate(infos) if o.role in ("receiver", "both")]
    occ = [i for i, o in enumerate(infos) if o.role in ("occluder", "both")]
    if not rec:
        raise ctx.error("objects", "no object with role receiver or both")
    if not occ:
        raise ctx.error("objects", "no object with role occluder or both")
    moved = next((i for i, o in enumerate(infos) if any(o.texel_offset)), None)
    if moved is not None and not isinstance(light, DirectionalLight):
        raise ctx.error(f"objects[{moved}].texel_offset", "needs a directional light (an area light's perspective "
                        "texels vary over its map)")
    receiver, rsrc = merge(meshes[i] for i in rec)
    occluder, osrc = merge(meshes[i] for i in occ)
    occ_obj = np.asarray(occ)[osrc]
    return Scene(  # objects placed in texels (texel_offset) resolved for the scene's own map
        name=name, description=desc, path=path,
        receiver=receiver, occluder=occluder,
        receiver_object=np.asarray(rec)[rsrc], occluder_object=occ_obj,
        occluder_translucent=np.array([infos[i].translucent for i in occ_obj], dtype=bool).reshape(-1),
        occluder_opacity=np.array([infos[i].opacity for i in occ_obj], dtype=np.float64).reshape(-1),
        objects=tuple(infos), light=light, camera=camera,
        shadow_map_size=(hw[0], hw[1]), msaa=int(msaa), outputs=tuple(outputs), params=dict(params),
    ).at_shadow_map()
