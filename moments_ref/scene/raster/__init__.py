"""Triangle rasterizer: depth maps with MSAA and an all-fragments mode.

The shadow maps of HPG17 are rendered by Direct3D 11 with 4× MSAA (HPG17 §5:
"The 2048² shadow map with 4× multisample antialiasing (MSAA) is simply fitted
to the convex hull"); VWSS §3.1 turns the fragments of a rasterized central view
into a point cloud. This module reproduces both on the CPU, vectorized, so that
the rest of the package has depth samples to filter and fragments to warp.

Conventions
-----------
Matrices. 4×4 float64, column vectors: ``clip = clip_from_world @ (x, y, z, 1)``.
:func:`look_at`, :func:`orthographic`, :func:`frustum` and :func:`perspective`
follow OpenGL (right-handed view space, the camera looks along −z) because
OpenGL's normalized device depth lies in [−1, 1], the depth range the papers
use (HPG17 §2: "depth z ∈ [−1, 1]"). A Direct3D depth d ∈ [0, 1] is 2d − 1 here.

Window. A map of size (H, W) has texel ``(row, col)``; window coordinates are
``x = (x_ndc + 1) W / 2`` (right) and ``y = (1 − y_ndc) H / 2`` (down, as in
Direct3D), so row 0 is the top (y_ndc = +1) and texel (row, col) spans
``[col, col + 1) × [row, row + 1)`` with its centre at ``(col + ½, row + ½)``.
:func:`project_points` maps world points to these coordinates.

Samples. Sample ``s`` of texel (row, col) sits at the centre plus the offset of
the Direct3D 11 standard multisample pattern (``D3D11_STANDARD_MULTISAMPLE_PATTERN``,
offsets in 1/16 pixel, x right, y down): 1×: (0, 0); 4×: (−2, −6), (6, −2),
(−6, 2), (2, 6); 8×: (1, −3), (−1, 3), (5, 1), (−3, −5), (−5, 5), (−7, −1),
(3, 7), (7, −7). See :func:`sample_positions`.

Coverage. Vertex window positions are snapped to 1/256 pixel (Direct3D 11's 8
bits of sub-pixel precision; ties to even) and edge functions are evaluated in
exact integer arithmetic, so the top-left fill rule of Direct3D decides samples
on an edge: a sample is covered if it is strictly inside all three edges, or on
an edge that is a *top* edge (exactly horizontal, the triangle below it) or a
*left* edge. Two triangles sharing an edge therefore never both cover, and never
both miss, a sample on it. Triangles whose snapped area is zero cover nothing.

Depth. NDC depth ``z_ndc = z_clip / w_clip`` is affine in window space; each
sample gets the plane through the three snapped vertices, evaluated in float64
and stored in the map's dtype (float32 by default, a D32_FLOAT buffer). Samples
with depth outside [−1, 1] are clipped (Direct3D's depth clip). The depth test
keeps the nearest (smallest) depth; the map is cleared to the far value 1, in
the memory of a map the caller has dropped where one of its size is free (as
llvmpipe clears the framebuffer it keeps; :mod:`moments_ref.scene.raster._maps`).
Geometry is clipped against the near plane (z_clip ≥ −w_clip) before the
perspective division, and against a guard band of ±2²⁰ pixels so that the
integer edge functions cannot overflow.

Facing. A triangle is front-facing when its vertices appear counter-clockwise in
NDC (x right, y up), i.e. its right-hand normal (v1 − v0) × (v2 − v0) points
towards the viewer: OpenGL's default, and the winding of the meshes in
:mod:`moments_ref.scene`. ``cull="back"`` drops the others (VWSS §3.1 rasterizes
with back-face culling).

Vectorization. Triangles are set up chunk by chunk, then rasterized by spans
(:mod:`moments_ref.scene.raster._spans`): for every (triangle, pixel row, sample) of
the triangle's pixel box the covered columns form one interval, solved from the
three edge functions exactly (a division per edge, no test per sample), and the
covered samples are written out from the intervals. Boxes of up to 32 rows are
evaluated together on a dense (rows, samples, triangles) layout in float64
(exact: the edge values are integers below 2^53); taller boxes (mid-size and long
thin triangles) are cut into pieces of 32 rows that take the same path, and only
triangles reaching far into the guard band go row by row in int64. Boxes of up to
2×2 pixels of a 1× map (a finely tessellated mesh seen from afar) test each sample
against the three edges instead. A triangle
whose depths are proven to lie in [−1, 1] from its vertices (with a bound on the
rounding) skips the depth-clip test of its rows. Large triangles (an inscribed
circle of 16 pixels or more) of a depth map are drawn 4×4 pixels at a time instead
(:mod:`moments_ref.scene.raster._tiles`): the tiles come from the same exact spans,
and each tile's depths are one broadcast addition of a per-(column, sample) and a
per-(row, sample) part, the same operations as the span path, so the map is the
same bit for bit. So the cost is the triangle
setup plus the covered samples, never the empty part of a bounding box. The
depth resolve is ``np.minimum.at`` (NumPy ≥
1.25 made ``ufunc.at`` fast; on NumPy 2.4 it beats a lexsort + reduceat resolve
by two orders of magnitude, see :func:`bench_raster`). Python loops run over
chunks only; results do not depend on the chunk size.

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

import time
from functools import partial
from dataclasses import asdict, dataclass

import numpy as np

from ..._arrays import InputError, float_dtype, real_input
from ..._kernels import RASTER_SETUP_CHUNK
from ..._shim import renamed_keywords
from ._spans import _iter_spans
from ._matrices import (_D3D11_PATTERN, _HALF, _SUB, MAX_SIZE, SAMPLE_COUNTS, SUBPIXEL_BITS, _check_matrix, _check_samples,
                       _check_size, _homogeneous, frustum, look_at, orthographic, perspective,
                       project_points, sample_positions, unproject_points)
from ._maps import cleared_map
from ._tiles import draw_tiles, tiled_boxes
from ._spans import _row_batches
from ._triangles import _check_mesh, _setup, _vertices, valid_triangles

__all__ = [
    "SAMPLE_COUNTS",
    "SUBPIXEL_BITS",
    "MAX_SIZE",
    "sample_positions",
    "look_at",
    "orthographic",
    "frustum",
    "perspective",
    "project_points",
    "unproject_points",
    "RasterStats",
    "Fragments",
    "rasterize_depth",
    "rasterize_depth_views",
    "rasterize_fragments",
    "bench_raster",
    "small_triangles",
]

_ = (_D3D11_PATTERN, MAX_SIZE, SUBPIXEL_BITS, frustum, look_at, orthographic, perspective, project_points,
     unproject_points, sample_positions, _homogeneous)  # re-exported

# Triangles set up per chunk (moments_ref._kernels' table of chunk sizes, with its measurement).
_SETUP_CHUNK = RASTER_SETUP_CHUNK
# Depth maps draw the 4×4-pixel tiles inside large triangles as dense blocks (:mod:`._tiles`;
# the same maps bit for bit; False draws every sample through the spans).
_TILES = True



# ---------------------------------------------------------------------------
# Results


@dataclass
class RasterStats:
    """What happened to the input triangles (counts of input triangles).

    Attributes
    ----------
    triangles : int
        Input triangles.
    nonfinite : int
        Skipped: a vertex holds NaN or inf.
    degenerate : int
        Skipped: zero area in world space (collinear or repeated vertices).
    outside : int
        Skipped: entirely outside the view volume (or behind the camera).
    culled : int
        Skipped by face culling.
    zero_area : int
        Skipped: zero area after snapping to 1/256 pixel (seen edge-on, or too
        thin to matter); like Direct3D, they cover nothing.
    rasterized : int
        Triangles that reached coverage evaluation (a triangle split by the near
        plane counts once; if one of its pieces collapses it may also count in
        ``zero_area``).
    samples_covered : int
        Covered samples inside the depth range, before the depth test
        (= the number of fragments of :func:`rasterize_fragments`).
    samples_depth_clipped : int
        Covered samples discarded because their depth left [−1, 1].
    """

    triangles: int = 0
    nonfinite: int = 0
    degenerate: int = 0
    outside: int = 0
    culled: int = 0
    zero_area: int = 0
    rasterized: int = 0
    samples_covered: int = 0
    samples_depth_clipped: int = 0

    @property
    def skipped_bad(self) -> int:
        """Triangles skipped as bad input (non-finite or degenerate)."""
        return self.nonfinite + self.degenerate

    def as_dict(self) -> dict:
        """The counts as a plain dict."""
        return asdict(self)


@dataclass
class Fragments:
    """Every covered sample of a rasterization, without a depth test (VWSS §3.1).

    Sorted by (triangle, texel, sample), i.e. in API order.

    Attributes
    ----------
    position : (N, 3) array
        World-space position of each fragment, interpolated perspective-correctly
        as a vertex attribute (VWSS §3.1: "the 3D world-space position (XYZ) of
        each fragment—interpolated as an attribute").
    depth : (N,) array
        NDC depth in [−1, 1].
    texel : (N,) int64 array
        Flat texel index ``row * W + col``.
    sample : (N,) int64 array
        Sample index within the texel.
    triangle : (N,) int64 array
        Index of the input triangle.
    size : (int, int)
        Map size (H, W).
    samples : int
        MSAA sample count.
    """

    position: np.ndarray
    depth: np.ndarray
    texel: np.ndarray
    sample: np.ndarray
    triangle: np.ndarray
    size: tuple
    samples: int

    def __len__(self) -> int:
        return int(self.depth.shape[0])

    @property
    def row(self) -> np.ndarray:
        """Texel row of each fragment."""
        return self.texel // self.size[1]

    @property
    def col(self) -> np.ndarray:
        """Texel column of each fragment."""
        return self.texel % self.size[1]


def _prepare(vertices, triangles, clip_from_world, size, samples, cull, dtype):
    v, t = _check_mesh(vertices, triangles)
    m = _check_matrix(clip_from_world)
    h, w = _check_size(size)
    S = _check_samples(samples)
    if cull not in ("none", "back", "front"):
        raise InputError(f"cull: expected 'none', 'back' or 'front', got {cull!r}")
    dt = float_dtype(dtype)
    pat = np.asarray(_D3D11_PATTERN[S], dtype=np.int64)
    return v, t, m, h, w, S, pat[:, 0] * 16, pat[:, 1] * 16, dt


def _covered_samples(v, m, t, h, w, sx, sy, cull, stats, want_world, dtype=np.float64, checked=False, tiles=None):
    """Every covered sample with its depth in [-1, 1], chunk by chunk.

    Yields ``(s, flat, z, rcs)``: the chunk's setup ``s``, the flat sample index
    ``(row * w + col) * S + sample``, the depth (float64 or ``dtype``: the same value
    once rounded to ``dtype``), and (only when ``want_world``,
    else None) the (triangle index into ``s``, row, col, sample) arrays; samples
    clipped by depth are counted in ``stats`` and left out. Shared by
    :func:`rasterize_depth` and :func:`rasterize_fragments`, so both see exactly
    the same coverage. ``tiles``, when given, is the flat depth map (h w S) of ``dtype``: the
    large triangles are drawn into it tile by tile (:mod:`._tiles`), their samples not yielded.
    """
    verts = _vertices(v, m, t.shape[0])
    for lo in range(0, t.shape[0], _SETUP_CHUNK):
        s = _setup(verts, t[lo:lo + _SETUP_CHUNK], lo, h, w, sx, sy, cull, stats, want_world, checked)
        if s is None:
            continue
        batches = None
        if tiles is not None:
            c0, c1, r0, r1, safe = s["box"]
            big = tiled_boxes(s, c1 - c0 + 1, r1 - r0 + 1, safe)
            if big.any():
                stats.samples_covered += draw_tiles(tiles, w, s, np.flatnonzero(big), c0, c1 - c0 + 1, r0, r1 - r0 + 1,
                                                    sx, sy, dtype)
                batches = partial(_row_batches, taken=big)
        for flat, z, inside, rcs in _iter_spans(s, *s["box"], sx, sy, w, want_world, dtype, batches):
            ok = None if inside else (z >= -1.0) & (z <= 1.0)
            if ok is not None and not ok.all():
                stats.samples_depth_clipped += int(ok.size - np.count_nonzero(ok))
                flat, z = flat[ok], z[ok]
                rcs = rcs and tuple(a[ok] for a in rcs)
            stats.samples_covered += int(z.size)
            yield s, flat, z, rcs


@renamed_keywords(view_proj="clip_from_world")
def rasterize_depth(vertices, triangles, clip_from_world, size, samples=1, cull="none",
                    dtype=np.float32):
    """Rasterize triangles into a depth map with MSAA (the shadow-map pass).

    Parameters
    ----------
    vertices : (V, 3) float array
        World positions. Non-finite vertices are allowed: triangles using them
        are skipped and counted.
    triangles : (T, 3) int array
        Vertex indices per triangle.
    clip_from_world : (4, 4) float array
        ``projection @ view`` (see :func:`look_at`, :func:`orthographic`,
        :func:`perspective`).
    size : int or (H, W)
        Map size, each side in [1, 16384].
    samples : {1, 4, 8}
        MSAA sample count (Direct3D 11 standard pattern).
    cull : {"none", "back", "front"}
        Face culling; front faces are counter-clockwise in NDC.
    dtype : float32 or float64
        Storage of the depth map (float32 = D32_FLOAT).

    Returns
    -------
    depth : (H, W, samples) array of ``dtype``
        Nearest NDC depth per sample, in [−1, 1]; 1 (far) where nothing was drawn.
    stats : RasterStats
        Counts of skipped (non-finite, degenerate, outside, culled, zero-area)
        and rasterized triangles and of covered samples.

    Raises
    ------
    InputError
        On a malformed mesh or matrix, a map size of zero or above 16384, an
        unsupported sample count (the message lists 1, 4, 8) or cull mode.

    Notes
    -----
    See the module docstring for the conventions (window space, D3D11 sample
    pattern, 1/256-pixel snapping, the top-left rule, near-plane clipping).

    Examples
    --------
    >>> import numpy as np
    >>> v = np.array([[-1, -1, 0], [1, -1, 0], [-1, 1, 0]], float)
    >>> d, st = rasterize_depth(v, [[0, 1, 2]], np.eye(4), 4)
    >>> d[..., 0]  # texel centres on the diagonal lie on a right edge: not covered
    array([[1., 1., 1., 1.],
           [0., 1., 1., 1.],
           [0., 0., 1., 1.],
           [0., 0., 0., 1.]], dtype=float32)
    >>> st.samples_covered
    6
    """
    v, t, m, h, w, S, sx, sy, dt = _prepare(vertices, triangles, clip_from_world, size, samples, cull, dtype)
    return _depth_map(v, t, m, h, w, sx, sy, cull, dt, RasterStats(triangles=int(t.shape[0])))


def _depth_map(v, t, m, h, w, sx, sy, cull, dt, stats, checked=False):
    """The depth map of :func:`rasterize_depth` and ``stats``, counted on from the given ones."""
    S = sx.shape[0]
    depth = cleared_map(h * w * S, dt)  # the far value 1, in a dropped map's memory where one is free (._maps)

    for _, flat, z, _ in _covered_samples(v, m, t, h, w, sx, sy, cull, stats, False, dt, checked,
                                          depth if _TILES else None):
        # Depth test: keep the nearest.
        np.minimum.at(depth, flat, z.astype(dt, copy=False))
    return depth.reshape(h, w, S), stats


def rasterize_depth_views(vertices, triangles, clip_from_worlds, size, samples=1, cull="none", dtype=np.float32):
    """:func:`rasterize_depth` of one mesh for each of many matrices, one view at a time (multi-view rasterization).

    Parameters
    ----------
    vertices, triangles, size, samples, cull, dtype
        As for :func:`rasterize_depth`.
    clip_from_worlds : (N, 4, 4) float array
        One ``clip_from_world`` per view.

    Yields
    ------
    depth, stats
        Per view, in order: exactly what ``rasterize_depth(vertices, triangles,
        clip_from_worlds[i], size, samples, cull, dtype)`` returns (the same map and counts).

    Notes
    -----
    The mesh's view-independent checks (non-finite vertices, zero area in world space) run
    once for all the views instead of once per view (VWSS §2.1's MVR draws one mesh from
    every light sample). The matrices are checked before the first view.
    """
    mats = real_input(clip_from_worlds, "clip_from_worlds", dtype=np.float64)
    if mats.ndim != 3 or mats.shape[1:] != (4, 4):
        raise InputError(f"clip_from_worlds: expected an (N, 4, 4) array of matrices, got shape {mats.shape}")
    v, t, _, h, w, S, sx, sy, dt = _prepare(vertices, triangles, np.eye(4), size, samples, cull, dtype)
    world = RasterStats(triangles=int(t.shape[0]))
    t = valid_triangles(v, t, world)
    for m in mats:
        yield _depth_map(v, t, m, h, w, sx, sy, cull, dt, RasterStats(**world.as_dict()), checked=True)


@renamed_keywords(view_proj="clip_from_world")
def rasterize_fragments(vertices, triangles, clip_from_world, size, samples=1, cull="none",
                        dtype=np.float32):
    """Every covered sample, without a depth test (VWSS §3.1 point generation).

    Parameters
    ----------
    vertices, triangles, clip_from_world, size, samples, cull
        As for :func:`rasterize_depth`.
    dtype : float32 or float64
        dtype of the returned positions and depths (float32 as VWSS stores them:
        "three 32-bit floating-point values").

    Returns
    -------
    fragments : Fragments
        Position, depth, texel, sample and triangle of each covered sample,
        sorted by (triangle, texel, sample).
    stats : RasterStats

    Notes
    -----
    Coverage and depth are exactly those of :func:`rasterize_depth`: the depth
    map equals the per-sample minimum of the fragments' depths. World positions
    use perspective-correct barycentrics μᵢ ∝ λᵢ / wᵢ of the (clipped) vertices.
    """
    v, t, m, h, w, S, sx, sy, dt = _prepare(vertices, triangles, clip_from_world, size, samples, cull, dtype)
    stats = RasterStats(triangles=int(t.shape[0]))
    parts = []
    for s, _, z, (i, row, col, samp) in _covered_samples(v, m, t, h, w, sx, sy, cull, stats, True):
        # Screen-space barycentrics from the (unbiased) edge functions, exact in int64.
        Xs = col * _SUB + _HALF + sx[samp]
        Ys = row * _SUB + _HALF + sy[samp]
        E = s["A"][:, i] * Xs + s["B"][:, i] * Ys + s["C"][:, i]  # (3, n)
        # Edge e (v_e -> v_e+1) is opposite vertex e+2: λ_{e+2} = E_e / area2.
        lam = E[[1, 2, 0]].astype(np.float64) / s["area2"][i]
        mu = lam * s["q"][:, i]
        mu /= mu.sum(axis=0)
        wv = s["world"][:, :, i]  # (3 coords, 3 vertices, n)
        pos = (mu[0] * wv[:, 0] + mu[1] * wv[:, 1] + mu[2] * wv[:, 2]).T
        parts.append((s["tid"][i], (row * w + col).astype(np.int64), samp.astype(np.int64),
                      z.astype(dt), pos.astype(dt)))
    if parts:
        tri_id, texel, samp, z, pos = (np.concatenate(c) for c in zip(*parts))
        order = np.lexsort((samp, texel, tri_id))
        tri_id, texel, samp, z, pos = tri_id[order], texel[order], samp[order], z[order], pos[order]
    else:
        tri_id = texel = samp = np.zeros(0, np.int64)
        z, pos = np.zeros(0, dt), np.zeros((0, 3), dt)
    return Fragments(position=pos, depth=z, texel=texel, sample=samp, triangle=tri_id,
                     size=(h, w), samples=S), stats


# ---------------------------------------------------------------------------
# Benchmark


def small_triangles(n, size, extent, rng):
    """n random triangles with vertices within ``extent`` pixels of a random centre, in NDC (benchmark input).

    Returns ``(vertices (3n, 3), triangles (n, 3))``; drawn with an identity matrix they
    land in a ``size``² map.
    """
    centre = rng.uniform(extent, size - extent, (n, 1, 2))
    xy = centre + rng.uniform(-extent / 2, extent / 2, (n, 3, 2))
    z = rng.uniform(-0.9, 0.9, (n, 1, 1)) + rng.uniform(-0.05, 0.05, (n, 3, 1))
    ndc = np.concatenate([xy / size * 2 - 1, z], axis=-1).reshape(-1, 3)
    return ndc, np.arange(3 * n).reshape(n, 3)


def bench_raster(n_triangles=500_000, size=1024, extent=4.0, samples=(1, 4), repeat=3, seed=0,
                 resolve_samples=4_000_000):
    """Measure rasterizer throughput for small triangles and the depth-resolve options.

    Parameters
    ----------
    n_triangles : int
        Random triangles, each with vertices within ``extent`` pixels of a
        random centre (bounding boxes of about ``extent`` pixels; mean area about
        ``extent²/12`` pixels), with random depths, drawn in NDC with an identity
        clip_from_world.
    size : int
        Square map side.
    extent : float
        Triangle extent in pixels.
    samples : sequence of int
        MSAA counts to measure.
    repeat : int
        Best of this many runs.
    seed : int
        Random seed.
    resolve_samples : int
        Random samples for the depth-resolve comparison.

    Returns
    -------
    dict
        ``raster_{S}x_tris_per_s``, ``raster_{S}x_seconds``,
        ``raster_{S}x_samples_covered`` per sample count, and for the depth
        resolve of ``resolve_samples`` random samples into a ``size²`` map:
        ``resolve_minimum_at_seconds`` and ``resolve_lexsort_reduceat_seconds``,
        plus the parameters.
    """
    rng = np.random.default_rng(seed)
    v, t = small_triangles(int(n_triangles), size, float(extent), rng)
    out = {"n_triangles": int(n_triangles), "size": int(size), "extent_px": float(extent),
           "numpy": np.__version__}
    for S in samples:
        best = np.inf
        for _ in range(max(1, repeat)):
            t0 = time.perf_counter()
            _, st = rasterize_depth(v, t, np.eye(4), size, samples=S)
            best = min(best, time.perf_counter() - t0)
        out[f"raster_{S}x_seconds"] = best
        out[f"raster_{S}x_tris_per_s"] = n_triangles / best
        out[f"raster_{S}x_samples_covered"] = st.samples_covered
    # Depth resolve alternatives on the same workload size.
    n = int(resolve_samples)
    flat = rng.integers(0, size * size, n)
    z = rng.uniform(-1, 1, n).astype(np.float32)
    d1 = np.ones(size * size, np.float32)
    t0 = time.perf_counter()
    np.minimum.at(d1, flat, z)
    out["resolve_minimum_at_seconds"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    order = np.lexsort((z, flat))
    fs = flat[order]
    start = np.flatnonzero(np.r_[True, fs[1:] != fs[:-1]])
    d2 = np.ones(size * size, np.float32)
    d2[fs[start]] = np.minimum.reduceat(z[order], start)
    out["resolve_lexsort_reduceat_seconds"] = time.perf_counter() - t0
    out["resolve_samples"] = n
    out["resolve_agree"] = bool(np.array_equal(d1, d2))
    return out
