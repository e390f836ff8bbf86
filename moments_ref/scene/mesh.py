"""Triangle meshes: procedural generators, 4×4 transforms and an OBJ reader.

A mesh is a pair of arrays: ``vertices`` (V, 3) float64 world positions and
``triangles`` (T, 3) int64 vertex indices. Generators wind every triangle
counter-clockwise seen from outside (its right-hand normal points outwards), the
front-face convention of :mod:`moments_ref.scene.raster`. The world is y-up.

Generators build the geometry of the test scenes of HPG17 (Figure 1: a railing,
a banner and the ground; Figure 8: a facade with a protrusion; Figure 9: an
umbrella, a roof and a railing) and a torus knot of 100k–500k triangles as the
complex occluder of VWSS §5 (Table 1 lists scenes of that size).

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

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .._arrays import InputError, check_memory, first_index
from .objtext import MAX_OBJ_LINE, obj_statements

__all__ = [
    "Mesh",
    "merge",
    "translate",
    "rotate",
    "scale",
    "box",
    "cylinder",
    "plane",
    "railing",
    "banner",
    "umbrella",
    "torus_knot",
    "read_obj",
    "GENERATORS",
    "BYTES_PER_ELEMENT",
]

#: Memory estimate of the generators and the OBJ reader: bytes per vertex and per
#: triangle (24 B stored each, the rest index grids and temporaries), checked
#: against :func:`moments_ref._arrays.max_memory` before allocating.
BYTES_PER_ELEMENT = 160
#: Largest magnitude of an OBJ coordinate: the bound of every number of a scene file
#: (:data:`moments_ref.scene._checks.MAX_MAGNITUDE`), so that no transform or projection overflows.
MAX_COORDINATE = 1e9
#: Vertices or triangles an OBJ file is read in at a time (see :func:`read_obj`).
OBJ_CHUNK = 1 << 16


@dataclass(frozen=True)
class Mesh:
    """An indexed triangle mesh.

    Attributes
    ----------
    vertices : (V, 3) float64 array
    triangles : (T, 3) int64 array
    """

    vertices: np.ndarray
    triangles: np.ndarray

    def __post_init__(self):
        v = np.asarray(self.vertices, dtype=np.float64).reshape(-1, 3)
        t = np.asarray(self.triangles, dtype=np.int64).reshape(-1, 3)
        bad = ~np.isfinite(v)
        if bad.any():
            idx = first_index(bad)
            raise InputError(f"vertices: expected finite coordinates, got {v[idx]!r} at index {idx}")
        if t.size and (t.min() < 0 or t.max() >= v.shape[0]):
            raise InputError(f"triangles: expected indices in [0, {v.shape[0]}), got range [{t.min()}, {t.max()}]")
        object.__setattr__(self, "vertices", v)
        object.__setattr__(self, "triangles", t)

    @property
    def n_triangles(self) -> int:
        return int(self.triangles.shape[0])

    @property
    def n_vertices(self) -> int:
        return int(self.vertices.shape[0])

    def transformed(self, matrix) -> "Mesh":
        """The mesh with vertices mapped by a 4×4 affine matrix (column vectors).

        A matrix with negative determinant (a mirror) reverses the winding so that
        faces keep pointing outwards.
        """
        m = np.asarray(matrix, dtype=np.float64)
        v = self.vertices @ m[:3, :3].T + m[:3, 3]
        t = self.triangles if np.linalg.det(m[:3, :3]) >= 0 else self.triangles[:, [0, 2, 1]]
        return Mesh(v, t)

    def bounds(self) -> np.ndarray:
        """(2, 3) array: the minimum and maximum corner of the bounding box."""
        if self.n_vertices == 0:
            return np.zeros((2, 3))
        return np.stack([self.vertices.min(0), self.vertices.max(0)])

    def face_normals(self) -> np.ndarray:
        """(T, 3) right-hand normals (v1 − v0) × (v2 − v0), not normalized (length = 2 · area)."""
        p = self.vertices[self.triangles]
        return np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])

    def areas(self) -> np.ndarray:
        """(T,) triangle areas."""
        return 0.5 * np.linalg.norm(self.face_normals(), axis=1)

    def sample_points(self, n, rng=None):
        """``n`` points uniformly distributed over the surface (area-weighted).

        Returns
        -------
        points : (n, 3) float64 array
        triangle : (n,) int64 array, the triangle each point lies on
        """
        rng = np.random.default_rng(rng)
        a = self.areas()
        tri = rng.choice(self.n_triangles, size=int(n), p=a / a.sum())
        r1, r2 = rng.random(int(n)), rng.random(int(n))
        s = np.sqrt(r1)
        w = np.stack([1 - s, s * (1 - r2), s * r2], axis=1)
        p = self.vertices[self.triangles[tri]]
        return np.einsum("nk,nkj->nj", w, p), tri


def merge(meshes) -> tuple[Mesh, np.ndarray]:
    """Concatenate meshes.

    Returns
    -------
    mesh : Mesh
    source : (T,) int64 array, index of the input mesh of each triangle
    """
    meshes = list(meshes)
    if not meshes:
        return Mesh(np.zeros((0, 3)), np.zeros((0, 3), np.int64)), np.zeros(0, np.int64)
    offs = np.cumsum([0] + [m.n_vertices for m in meshes[:-1]])
    v = np.concatenate([m.vertices for m in meshes])
    t = np.concatenate([m.triangles + o for m, o in zip(meshes, offs)])
    src = np.repeat(np.arange(len(meshes)), [m.n_triangles for m in meshes])
    return Mesh(v, t), src


# ---------------------------------------------------------------------------
# Transforms (4×4, column vectors)


def translate(offset) -> np.ndarray:
    """4×4 translation by ``offset`` (3,)."""
    m = np.eye(4)
    m[:3, 3] = np.asarray(offset, dtype=np.float64).reshape(3)
    return m


def rotate(axis, degrees) -> np.ndarray:
    """4×4 rotation by ``degrees`` about ``axis`` (right-hand rule, Rodrigues' formula)."""
    a = np.asarray(axis, dtype=np.float64).reshape(3)
    n = np.linalg.norm(a)
    if not np.isfinite(n) or n == 0:
        raise InputError(f"axis: expected a non-zero finite direction, got {a.tolist()}")
    x, y, z = a / n
    th = np.radians(float(degrees))
    c, s = np.cos(th), np.sin(th)
    k = np.array([[0, -z, y], [z, 0, -x], [-y, x, 0]])
    m = np.eye(4)
    m[:3, :3] = c * np.eye(3) + s * k + (1 - c) * np.outer([x, y, z], [x, y, z])
    return m


def scale(factor) -> np.ndarray:
    """4×4 scaling by a scalar or per-axis (3,) ``factor``."""
    f = np.broadcast_to(np.asarray(factor, dtype=np.float64), (3,))
    return np.diag([*f, 1.0])


# ---------------------------------------------------------------------------
# Generators


def _positive(name, value):
    if isinstance(value, (bool, str)) or not np.isscalar(value):
        raise InputError(f"{name}: expected a positive finite number, got {value!r}")
    v = float(value)
    if not (np.isfinite(v) and v > 0):
        raise InputError(f"{name}: expected a positive finite number, got {value!r}")
    return v


def _real(name, value):
    if isinstance(value, (bool, str)) or not np.isscalar(value) or not np.isfinite(value):
        raise InputError(f"{name}: expected a finite number, got {value!r}")
    return float(value)


def _count(name, value, lo=1):
    if (isinstance(value, (bool, str)) or not np.isscalar(value) or not np.isfinite(value)
            or int(value) != value or int(value) < lo):
        raise InputError(f"{name}: expected an integer >= {lo}, got {value!r}")
    return int(value)


def _budget(what, n_vertices, n_triangles):
    """Refuse a generator call whose mesh would exceed the memory limit, before allocating."""
    check_memory(BYTES_PER_ELEMENT * (int(n_vertices) + int(n_triangles)), what)


def _grid(nu, nv, closed_u=False):
    """Triangles of a (nv+1) × (nu+1) vertex grid (row-major, u fastest), CCW for u × v."""
    cols = nu if closed_u else nu + 1
    i, j = np.meshgrid(np.arange(nu), np.arange(nv))
    a = j * cols + i
    b = j * cols + (i + 1) % cols
    c = (j + 1) * cols + i
    d = (j + 1) * cols + (i + 1) % cols
    t = np.concatenate([np.stack([a, b, d], -1).reshape(-1, 3), np.stack([a, d, c], -1).reshape(-1, 3)])
    return t


def box(size=(1.0, 1.0, 1.0)) -> Mesh:
    """Axis-aligned box centred at the origin with edge lengths ``size``: 12 triangles."""
    s = np.broadcast_to(np.asarray(size, dtype=np.float64), (3,))
    for k, v in zip("xyz", s):
        _positive(f"size.{k}", v)
    corners = np.array([[x, y, z] for x in (-0.5, 0.5) for y in (-0.5, 0.5) for z in (-0.5, 0.5)]) * s
    # index = 4 ix + 2 iy + iz; faces listed counter-clockwise seen from outside
    quads = np.array([[0, 1, 3, 2], [4, 6, 7, 5],    # -x, +x
                      [0, 4, 5, 1], [2, 3, 7, 6],    # -y, +y
                      [0, 2, 6, 4], [1, 5, 7, 3]])   # -z, +z
    t = np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])
    return Mesh(corners, t)


def cylinder(radius=0.5, height=1.0, segments=16, caps=True) -> Mesh:
    """Cylinder around the y axis from y = 0 to ``height``."""
    r, h = _positive("radius", radius), _positive("height", height)
    n = _count("segments", segments, 3)
    _budget(f"cylinder(segments={n})", 2 * n + 2, 4 * n)
    phi = 2 * np.pi * np.arange(n) / n
    ring = np.stack([r * np.cos(phi), np.zeros(n), -r * np.sin(phi)], -1)  # CCW seen from +y
    v = np.concatenate([ring, ring + [0, h, 0]])
    t = [_grid(n, 1, closed_u=True)]
    if caps:
        v = np.concatenate([v, [[0, 0, 0], [0, h, 0]]])
        i = np.arange(n)
        t.append(np.stack([np.full(n, 2 * n), (i + 1) % n, i], -1))          # bottom, faces -y
        t.append(np.stack([np.full(n, 2 * n + 1), n + i, n + (i + 1) % n], -1))  # top, faces +y
    return Mesh(v, np.concatenate(t))


def plane(width=1.0, depth=1.0, nx=1, nz=1) -> Mesh:
    """Rectangle in the xz plane at y = 0, centred at the origin, facing +y."""
    w, d = _positive("width", width), _positive("depth", depth)
    nx, nz = _count("nx", nx), _count("nz", nz)
    _budget(f"plane(nx={nx}, nz={nz})", (nx + 1) * (nz + 1), 2 * nx * nz)
    x = np.linspace(-w / 2, w / 2, nx + 1)
    z = np.linspace(d / 2, -d / 2, nz + 1)  # u = +x, v = -z: u × v = +y
    X, Z = np.meshgrid(x, z)
    v = np.stack([X, np.zeros_like(X), Z], -1).reshape(-1, 3)
    return Mesh(v, _grid(nx, nz))


def _boxes(centres, sizes) -> Mesh:
    """Many boxes at once: (n, 3) centres and (n, 3) sizes."""
    unit = box()
    centres, sizes = np.atleast_2d(centres), np.atleast_2d(sizes)
    v = unit.vertices[None] * sizes[:, None] + centres[:, None]
    t = unit.triangles[None] + 8 * np.arange(len(centres))[:, None, None]
    return Mesh(v.reshape(-1, 3), t.reshape(-1, 3))


def railing(length=3.0, height=1.0, bars=16, bar_width=0.035, rail_height=0.06, rail_depth=0.08) -> Mesh:
    """A railing along x, centred at x = 0, from y = 0 to ``height``: thin square bars
    under a hand rail (boxes)."""
    L, H = _positive("length", length), _positive("height", height)
    n = _count("bars", bars, 2)
    _budget(f"railing(bars={n})", 8 * (n + 2), 12 * (n + 2))
    bw, rh, rd = _positive("bar_width", bar_width), _positive("rail_height", rail_height), _positive("rail_depth", rail_depth)
    x = np.linspace(-L / 2 + bw, L / 2 - bw, n)
    bar_h = H - rh
    centres = np.stack([x, np.full(n, bar_h / 2), np.zeros(n)], -1)
    sizes = np.tile([bw, bar_h, bw], (n, 1))
    centres = np.vstack([centres, [0, H - rh / 2, 0], [0, 0.15 * H, 0]])
    sizes = np.vstack([sizes, [L, rh, rd], [L, rh / 2, bw]])  # hand rail and a low rail
    return _boxes(centres, sizes)


def banner(width=2.0, height=1.0, nx=32, ny=16, wave_amplitude=0.03, wave_length=0.5) -> Mesh:
    """A cloth-like banner: a grid in the xy plane, x centred, y from 0 to ``height``,
    facing +z, displaced in z by a gentle wave ``A sin(2π x / λ) (1 − y/height)``."""
    w, h = _positive("width", width), _positive("height", height)
    nx, ny = _count("nx", nx), _count("ny", ny)
    _budget(f"banner(nx={nx}, ny={ny})", (nx + 1) * (ny + 1), 2 * nx * ny)
    amp = _real("wave_amplitude", wave_amplitude)
    lam = _positive("wave_length", wave_length)
    x = np.linspace(-w / 2, w / 2, nx + 1)
    y = np.linspace(0, h, ny + 1)
    X, Y = np.meshgrid(x, y)
    Z = amp * np.sin(2 * np.pi * X / lam) * (1 - 0.5 * Y / h)
    v = np.stack([X, Y, Z], -1).reshape(-1, 3)
    return Mesh(v, _grid(nx, ny))


def umbrella(radius=1.0, height=2.0, segments=24, rings=6, droop=0.3, pole_radius=0.03) -> Mesh:
    """A garden umbrella: a drooping canopy (apex at y = ``height``) on a pole from y = 0."""
    R, H = _positive("radius", radius), _positive("height", height)
    n, m = _count("segments", segments, 3), _count("rings", rings, 1)
    d, pr = _real("droop", droop), _positive("pole_radius", pole_radius)
    _budget(f"umbrella(segments={n}, rings={m})", 1 + n * m + 18, 2 * n * m + 32)
    phi = 2 * np.pi * np.arange(n) / n
    s = np.arange(1, m + 1) / m
    rr = R * s
    yy = H - d * s ** 1.5
    ring = np.stack([rr[:, None] * np.cos(phi), np.broadcast_to(yy[:, None], (m, n)),
                     -rr[:, None] * np.sin(phi)], -1).reshape(-1, 3)
    v = np.vstack([[0, H, 0], ring])
    i = np.arange(n)
    t = [np.stack([np.zeros(n, np.int64), 1 + i, 1 + (i + 1) % n], -1)]  # apex fan, faces +y
    if m > 1:
        g = _grid(n, m - 1, closed_u=True) + 1
        t.append(g[:, [0, 2, 1]])  # rings grow outwards: flip so the canopy faces up
    canopy = Mesh(v, np.concatenate(t))
    pole = cylinder(pr, H, 8)
    return merge([canopy, pole])[0]


def torus_knot(p=2, q=3, radius=1.0, tube=0.1, segments=1600, sides=64) -> Mesh:
    """A (p, q) torus knot tube: ``2 · segments · sides`` triangles.

    The centre curve is ``((2 + cos qφ) cos pφ, (2 + cos qφ) sin pφ, −sin qφ) · radius / 3``;
    the tube frame is that of three.js's TorusKnotGeometry (built from the
    tangent and the sum of neighbouring curve points).
    """
    p, q = _count("p", p), _count("q", q)
    R, r = _positive("radius", radius), _positive("tube", tube)
    n, k = _count("segments", segments, 3), _count("sides", sides, 3)
    _budget(f"torus_knot(segments={n}, sides={k})", n * k, 2 * n * k)

    def curve(u):
        c = 2 + np.cos(q * u)
        return np.stack([c * np.cos(p * u), c * np.sin(p * u), -np.sin(q * u)], -1) * (R / 3)

    u = 2 * np.pi * np.arange(n) / n  # the curve closes after φ = 2π
    P1 = curve(u)
    P2 = curve(u + 0.01)
    T = P2 - P1
    N = P2 + P1
    B = np.cross(T, N)
    N = np.cross(B, T)
    B /= np.linalg.norm(B, axis=1, keepdims=True)
    N /= np.linalg.norm(N, axis=1, keepdims=True)
    a = 2 * np.pi * np.arange(k) / k
    cx, cy = -r * np.cos(a), r * np.sin(a)
    v = P1[:, None] + cx[None, :, None] * N[:, None] + cy[None, :, None] * B[:, None]
    v = v.reshape(-1, 3)
    # rows = segments (closed), columns = sides (closed)
    i, j = np.meshgrid(np.arange(k), np.arange(n))
    a_ = j * k + i
    b_ = ((j + 1) % n) * k + i
    c_ = ((j + 1) % n) * k + (i + 1) % k
    d_ = j * k + (i + 1) % k
    t = np.concatenate([np.stack([a_, b_, d_], -1).reshape(-1, 3), np.stack([b_, c_, d_], -1).reshape(-1, 3)])
    mesh = Mesh(v, t)
    # Orient outwards: the tube vertex minus its centre point must agree with the normal.
    nrm = mesh.face_normals()
    centre = np.repeat(P1, k, axis=0)[t[:, 0]]
    if ((mesh.vertices[t].mean(1) - centre) * nrm).sum() < 0:
        mesh = Mesh(v, t[:, [0, 2, 1]])
    return mesh


GENERATORS = {
    "box": box,
    "cylinder": cylinder,
    "plane": plane,
    "railing": railing,
    "banner": banner,
    "umbrella": umbrella,
    "torus_knot": torus_knot,
}


# ---------------------------------------------------------------------------
# OBJ


class _ObjParts:
    """The vertices and triangles of an OBJ file read so far: arrays of up to :data:`OBJ_CHUNK` rows each.

    Every full chunk is checked against the memory limit with the estimate of the
    generators (:data:`BYTES_PER_ELEMENT` per vertex and triangle read so far)
    before it becomes an array, so that reading stops at the limit, not after it.
    """

    def __init__(self, path):
        self.path, self.v, self.t, self.vbuf, self.tbuf, self.nv, self.nt = path, [], [], [], [], 0, 0

    def vertex(self, xyz):
        self.vbuf.append(xyz)
        self.nv += 1
        if len(self.vbuf) >= OBJ_CHUNK:
            self.flush()

    def face(self, idx):
        self.tbuf.extend([idx[0], idx[i], idx[i + 1]] for i in range(1, len(idx) - 1))
        self.nt += len(idx) - 2
        if len(self.tbuf) >= OBJ_CHUNK:
            self.flush()

    def flush(self):
        check_memory(BYTES_PER_ELEMENT * (self.nv + self.nt),
                     f"OBJ file {self.path} ({self.nv} vertices and {self.nt} triangles so far)")
        if self.vbuf:
            self.v.append(np.array(self.vbuf, dtype=np.float64).reshape(-1, 3))
        if self.tbuf:
            self.t.append(np.array(self.tbuf, dtype=np.int64).reshape(-1, 3))
        self.vbuf, self.tbuf = [], []

    def mesh(self):
        self.flush()
        v = np.concatenate(self.v) if self.v else np.zeros((0, 3))
        t = np.concatenate(self.t) if self.t else np.zeros((0, 3), np.int64)
        self.v = self.t = None
        return Mesh(v, t)


def _obj_vertex(parts, where, line):
    """``v x y z``, ``v x y z w`` (w divides and must be non-zero) or ``v x y z r g b`` (vertex colours, as
    MeshLab and ZBrush export them: ignored); coordinates finite and within :data:`MAX_COORDINATE`."""
    if len(parts) not in (4, 5, 7):
        raise InputError(f"{where}: expected 'v x y z', 'v x y z w' or 'v x y z r g b' (colours), got "
                         f"{len(parts) - 1} numbers: {line.strip()[:80]!r}")
    try:
        xyz = [float(x) for x in parts[1:5 if len(parts) == 5 else 4]]
    except ValueError:
        raise InputError(f"{where}: expected 'v x y z [w]' with numbers, got {line.strip()[:80]!r}") from None
    if not all(np.isfinite(xyz)):
        raise InputError(f"{where}: expected finite coordinates, got {line.strip()[:80]!r}")
    if len(xyz) == 4:
        if xyz[3] == 0:
            raise InputError(f"{where}: expected a non-zero w (a point, not a direction), got {line.strip()!r}")
        xyz = [c / xyz[3] for c in xyz[:3]]
    if not all(abs(c) <= MAX_COORDINATE for c in xyz):
        raise InputError(f"{where}: a coordinate beyond the scene bounds (|x| <= {MAX_COORDINATE:g}, the largest "
                         f"number a scene file takes), got {line.strip()[:80]!r}")
    return xyz


def _obj_face(parts, where, line, n_vertices):
    if len(parts) < 4:
        raise InputError(f"{where}: expected a face with at least 3 vertices, got {line.strip()!r}")
    idx = []
    for tok in parts[1:]:
        try:
            k = int(tok.split("/")[0])
        except ValueError:
            raise InputError(f"{where}: expected an integer vertex index, got {tok!r}") from None
        k = k - 1 if k > 0 else n_vertices + k
        if k < 0 or k >= n_vertices or tok.split("/")[0] in ("0", "-0"):
            raise InputError(f"{where}: vertex index {tok.split('/')[0]} out of range ({n_vertices} vertices so far)")
        idx.append(k)
    return idx


def read_obj(path) -> Mesh:
    """Read the geometry of a Wavefront OBJ file as exporters write it.

    Reads ``v`` (x y z; x y z w, where w divides and must be non-zero; x y z r g b,
    vertex colours, ignored; coordinates finite and within :data:`MAX_COORDINATE`,
    the scene files' bound) and ``f`` lines; a face's indices may be
    ``v``, ``v/vt``, ``v//vn`` or ``v/vt/vn``, 1-based, or negative (relative to
    the vertices read so far). Polygons are triangulated as fans (v0, vi, vi+1),
    which is exact for convex polygons. The other statements of the specification
    (vt, vn, vp, l, p, o, g, s, usemtl, usemap, mtllib, ...) are ignored; a UTF-8
    BOM, UTF-16 text, CRLF line ends and ``\\`` continuations are read
    (:mod:`moments_ref.scene.objtext`). A file without faces, binary data (a binary
    STL named ``.obj``), an ASCII STL and a line whose keyword is no OBJ statement
    are refused.

    Memory. The file is read line by line (lines of at most :data:`MAX_OBJ_LINE`
    characters) into arrays of :data:`OBJ_CHUNK` rows; the vertices and
    triangles read so far are checked against the memory limit with the
    generators' estimate (:data:`BYTES_PER_ELEMENT` each) before each chunk is
    kept, so a file that would exceed the limit is refused while it is read.

    Raises
    ------
    InputError
        Naming the file and line of a malformed vertex or face, an index out of
        range, a line too long, a coordinate out of bounds, a file that is not
        OBJ text or has no face, or a mesh above the memory limit.
    """
    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: expected a regular OBJ file, got {'a folder' if path.is_dir() else 'no file' if not path.exists() else 'a special file'}")
    acc = _ObjParts(path)
    try:
        for where, parts, line in obj_statements(path):
            if parts[0] == "v":
                acc.vertex(_obj_vertex(parts, where, line))
            elif parts[0] == "f":
                acc.face(_obj_face(parts, where, line, acc.nv))
    except OSError as exc:
        raise InputError(f"{path}: cannot read OBJ file ({exc.strerror})") from None
    if acc.nt == 0:
        raise InputError(f"{path}: expected an OBJ file with at least one face ('f' line), got {acc.nv} vertices "
                         "and no face")
    return acc.mesh()
