"""Coarse tiles: large triangles drawn 4×4 pixels at a time, as dense blocks of depths.

Part of :mod:`moments_ref.scene.raster` (see its docstring for the conventions).

llvmpipe (and most hardware) classifies the map's aligned tiles against each triangle
before testing samples: a tile every sample of which lies inside all three edges needs
no per-sample test. Here the classification comes from the exact spans themselves
(:func:`._spans._rect_bounds`, the box aligned to tile rows): tile (tr, tc) is inside
triangle t when the span of every one of its 4 S (pixel row, sample) rows is nonempty and
contains the columns 4 tc .. 4 tc + 3, which is exactly the per-sample test of the
top-left rule in the same integer arithmetic. In a row of tiles the inside tiles form one
run (the triangle is convex); the tiles from the one holding the row's leftmost covered
sample to the one holding its rightmost, outside the run, are partial: drawn the same way
with the uncovered samples' depths replaced by +inf, which the depth test (a minimum)
ignores. No sample goes through the per-sample expansion of the span path.

Cores. In a piece (:data:`._spans._DENSE_ROWS` rows) of a large triangle, the columns of
tiles inside every one of its tile rows form a rectangle, the piece's core. A core at
least :data:`CORE_MIN_TILES` tiles wide is drawn as one dense block: its depths computed
sample by sample into a (rows, columns, S) block in the map's layout, and the depth test
a minimum into the map's rectangle (a strided view), without the flat indices and the
scatter-min (``np.minimum.at``) of the other tiles; the piece's inside tiles outside the
core are drawn as above. On the bench's railing case (32 triangles, 9.05 M of its
10.43 M samples in tiles) the cores hold 81 % of the inside tiles (docs/bench.md,
Kernel history).

Depth. A sample's depth is ``(z0 + za X) + zb Y`` (X, Y its integer offsets from
vertex 0, :func:`._spans._iter_spans`), in float64, rounded once to the map's dtype.
Over a tile the first sum depends on (column, sample) only and ``zb Y`` on (row,
sample) only: each is computed once per tile, and the tile's 16 S depths are one
broadcast addition of the two, the same operations in the same order on the same
values as the span path: bit for bit the same depths (tests/test_raster.py compares
the maps byte for byte and against the brute-force reference).

Which triangles: only large ones (inscribed circle of radius >= TILE_MIN_INRADIUS
pixels) whose depths are proven in [-1, 1] (no depth clip) and whose box is exact in
float64 (:data:`._spans._FLOAT_SAFE_COORD`). For the bench's triangles of about 150 pixels
the tiles cost more than the spans (about 1.2 times the time with every triangle tiled,
1.05 with 2×2-pixel tiles): docs/bench.md, Kernel history, round seven.
"""

from __future__ import annotations

import numpy as np

from ._matrices import _HALF, _SUB
from ._spans import _DENSE_ROWS, _ROW_BUDGET, _rect_bounds

#: Tile side in pixels (a power of two).
TILE = 4
_SHIFT = TILE.bit_length() - 1
#: Boxes at least this many pixels in both directions try the tile path (smaller ones
#: hold few whole tiles, and the aligned layout would cost them rows).
TILE_MIN_BOX = 2 * TILE
#: Tiles per batch (2^16 samples at 4× MSAA): cache-sized, as the spans' batches.
TILE_BATCH = 1 << 12
#: Triangles whose inscribed circle has at least this radius (pixels) take the tile path:
#: thinner ones hold few whole tiles for the cost of the tile layout.
TILE_MIN_INRADIUS = 16.0
#: A piece's core (module docstring) at least this many tiles wide is drawn as a dense block
#: (narrower ones go through the flat indices and the scatter-min with the other tiles).
CORE_MIN_TILES = 4
#: Samples per block of a core (:func:`_draw_cores`): bounds its temporaries (1 MiB of float32 depths).
CORE_BLOCK = 1 << 18


def tiled_boxes(s, nc, nr, safe):
    """Which boxes take the tile path: large enough, exact in float64, and depths provably in [-1, 1]."""
    big = (nr >= TILE_MIN_BOX) & (nc >= TILE_MIN_BOX) & safe & s["inside"]
    if TILE_MIN_INRADIUS > 0 and big.any():
        # Inradius = 2 area / perimeter, in 1/256 pixels (area2 = 2 area, edge (A, B) = (-dy, dx)).
        X, Y = s["X"], s["Y"]
        area2 = np.abs((X[1] - X[0]) * (Y[2] - Y[0]) - (Y[1] - Y[0]) * (X[2] - X[0])).astype(np.float64)
        perim = np.hypot(s["A"], s["B"]).sum(axis=0)
        big &= area2 >= TILE_MIN_INRADIUS * _SUB * perim
    return big


def draw_tiles(depth, w, s, idx, c0, nc, r0, nr, sx, sy, dtype):
    """Draw the boxes ``idx`` of setup ``s`` tile by tile into the flat depth map ``depth``; the covered count.

    ``depth`` is the (h, w, S) map, flat.

    Each box is aligned to tile rows (the rows above it masked) and cut into pieces of
    _DENSE_ROWS rows (a multiple of TILE), whose exact spans come from
    :func:`._spans._rect_bounds`. In each row of tiles, the tiles from the one holding the
    leftmost covered sample to the one holding the rightmost are drawn: the inside tiles
    as they are, the others with their uncovered samples masked.
    """
    S = sx.shape[0]
    A3, B3 = np.take(s["A"], idx, axis=1), np.take(s["B"], idx, axis=1)
    # Align each box's first row to a tile row: `skip` rows above the box are masked.
    off = r0[idx] & (TILE - 1)
    r0a, nra = r0[idx] - off, nr[idx] + off
    c0i = c0[idx]
    base3 = (np.take(s["F0"], idx, axis=1) + A3 * (c0i * _SUB + _HALF) + B3 * (r0a * _SUB + _HALF))
    # Pieces of _DENSE_ROWS rows (a multiple of TILE: every piece starts on a tile row).
    pieces = (nra + _DENSE_ROWS - 1) // _DENSE_ROWS
    p = np.repeat(np.arange(idx.size), pieces)
    drow = (np.arange(p.size) - np.repeat(np.cumsum(pieces) - pieces, pieces)) * _DENSE_ROWS
    based = np.take(base3, p, axis=1) + np.take(B3, p, axis=1) * (drow * _SUB)
    nrp = np.minimum(nra[p] - drow, _DENSE_ROWS)
    skip = np.where(drow == 0, off[p], 0)
    r0p = r0a[p] + drow
    key = (nrp + TILE - 1) >> _SHIFT  # tile rows of the piece
    covered = 0
    for kt in np.flatnonzero(np.bincount(key))[::-1]:
        sel = np.flatnonzero(key == kt)
        k = int(kt) * TILE
        step = max(1, _ROW_BUDGET // (k * S))
        for a in range(0, sel.size, step):
            g = sel[a:a + step]
            pg = p[g]
            lo, cnt = _rect_bounds(np.take(A3, pg, axis=1), np.take(B3, pg, axis=1), np.take(based, g, axis=1),
                                   nc[idx[pg]], nrp[g], k, sx, sy, skip[g])
            covered += _draw_piece_tiles(depth, w, s, idx[pg], lo, cnt, c0i[pg], r0p[g], sx, sy, dtype)
    return covered


def _draw_piece_tiles(depth, w, s, tri, lo, cnt, c0, r0, sx, sy, dtype):
    """Draw the tiles of pieces of triangles ``tri`` (setup indices), dense spans ``lo``, ``cnt``; the covered count."""
    S = sx.shape[0]
    full, part, cores = _tiles_of(lo, cnt, c0, r0)
    covered = _draw_cores(depth, w, s, tri, cores, r0, sx, sy, dtype)
    for (j, tr, tc), masked in ((full, False), (part, True)):
        for b0 in range(0, j.size, TILE_BATCH):  # cache-sized batches
            b = slice(b0, b0 + TILE_BATCH)
            jb, trb, tcb = j[b], tr[b], tc[b]
            z = tile_depths(s, tri[jb], trb, tcb, sx, sy, dtype)
            if masked:
                inside = _tile_masks(lo, cnt, jb, trb - (r0[jb] >> _SHIFT), tcb * TILE - c0[jb])
                covered += int(np.count_nonzero(inside))
                np.copyto(z, np.inf, where=~inside)
            else:
                covered += int(z.size)
            write_tiles(depth, w, S, trb, tcb, z)
    return covered


def _tiles_of(lo, cnt, c0, r0):
    """The tiles of the dense spans (k, S, n) of pieces starting on tile row ``r0 / TILE``.

    Returns the inside tiles outside the pieces' cores and the other tiles holding a covered
    sample, each as (piece, tile row, tile column) int64 arrays, piece by piece, and the cores
    (:func:`_cores`).
    """
    k, S, n = lo.shape
    K = k // TILE
    keep = (cnt > 0).reshape(K, TILE * S, n)
    # Per (tile row, piece): the covered columns' hull [lo_min, end_max), and, where every
    # row is covered, the columns [first, end) inside every row.
    anyc = keep.any(axis=1)
    full = keep.all(axis=1) & anyc
    lo4 = lo.reshape(K, TILE * S, n)
    end4 = (lo + cnt).reshape(K, TILE * S, n)
    lo_min = np.where(anyc, np.where(keep, lo4, np.inf).min(axis=1), 0.0).astype(np.int64) + c0
    end_max = np.where(anyc, end4.max(axis=1), 0.0).astype(np.int64) + c0
    first = np.where(full, lo4.max(axis=1), 0.0).astype(np.int64) + c0
    end = np.where(full, end4.min(axis=1), 0.0).astype(np.int64) + c0
    t0 = lo_min >> _SHIFT
    t1 = np.where(anyc, ((end_max - 1) >> _SHIFT) + 1, t0)  # tiles t0 .. t1 - 1 hold a covered sample
    ta = (first + TILE - 1) >> _SHIFT
    tb = end >> _SHIFT  # tiles ta .. tb - 1 lie inside every row
    has = full & (tb > ta)
    ta, tb = np.where(has, ta, t0), np.where(has, tb, t0)
    cores, ca, cw = _cores(has, ta, tb)
    return (_enumerate(ta, tb - ta - cw, r0, skip_at=ca - ta, skip=cw),
            _enumerate(t0, t1 - t0 - (tb - ta), r0, skip_at=ta - t0, skip=tb - ta), cores)


def _cores(has, ta, tb):
    """The pieces' cores from their inside tiles ``[ta, tb)`` per (tile row, piece) (``has``: some).

    A piece's core spans the tile rows from its first to its last with inside tiles, when
    every one of them has some, and the tile columns inside all of them, when at least
    :data:`CORE_MIN_TILES`. Returns ``(piece, first tile row, end tile row, first tile
    column, end tile column)`` of each core, and per (tile row, piece) the core's first
    tile column and width (0 outside cores), to skip in the inside tiles' enumeration.
    """
    K = has.shape[0]
    qa = np.argmax(has, axis=0)
    qb = K - np.argmax(has[::-1], axis=0)
    q = np.arange(K)[:, None]
    rows = (q >= qa) & (q < qb)
    far = np.iinfo(np.int64).max
    ca = np.where(rows, ta, -far).max(axis=0)
    cb = np.where(rows, tb, far).min(axis=0)
    core = (has | ~rows).all(axis=0) & has.any(axis=0) & (cb - ca >= CORE_MIN_TILES)
    cw = np.where(rows & core, cb - ca, 0)
    j = np.flatnonzero(core)
    return (j, qa[j], qb[j], ca[j], cb[j]), np.broadcast_to(np.where(core, ca, 0), ta.shape), cw


def _draw_cores(depth, w, s, tri, cores, r0, sx, sy, dtype):
    """Depth test of the pieces' cores (:func:`_cores`) into the flat map ``depth`` (h w S); the covered count.

    Each core's depths ``(z0 + za X) + zb Y`` as in :func:`tile_depths` (the same operations
    on the same values, so the same bits), one sample index at a time over (rows, columns)
    so that the passes run over rows of columns, then one minimum into the map's rectangle.
    """
    S = sx.shape[0]
    d3 = depth.reshape(-1, w, S)
    j, qa, qb, ca, cb = cores
    i = tri[j]
    X0, Y0, za, zb, z0 = s["X"][0][i], s["Y"][0][i], s["za"][i], s["zb"][i], s["z0"][i]
    row0 = ((r0[j] >> _SHIFT) + qa) * TILE
    covered = 0
    for m in range(j.size):
        y0, nr, x0, x1 = int(row0[m]), int(qb[m] - qa[m]) * TILE, int(ca[m]) * TILE, int(cb[m]) * TILE
        # Offsets from vertex 0 of each (row or column, sample): exact integers in float64.
        yz = (np.arange(y0, y0 + nr)[:, None] * _SUB + (_HALF - Y0[m]) + sy).astype(np.float64)
        yz *= zb[m]
        step = max(TILE, CORE_BLOCK // (nr * S) // TILE * TILE)  # columns a block: the temporaries cache-sized
        for c in range(x0, x1, step):
            nc = min(step, x1 - c)
            xz = (np.arange(c, c + nc)[:, None] * _SUB + (_HALF - X0[m]) + sx).astype(np.float64)
            xz *= za[m]
            xz += z0[m]
            z = np.empty((nr, nc, S), dtype)
            for k in range(S):
                np.add(xz[:, k], yz[:, k, None], out=z[:, :, k])
            view = d3[y0:y0 + nr, c:c + nc]
            np.minimum(view, z, out=view)
        covered += nr * (x1 - x0) * S
    return covered


def _enumerate(start, count, r0, skip_at=None, skip=None):
    """(piece, tile row, tile column) of ``count`` tiles from ``start`` per (tile row, piece), piece by piece;
    ``skip`` columns are jumped over from the ``skip_at``-th tile on."""
    jt, q = np.nonzero(count.T > 0)
    m = count[q, jt]
    rep = np.repeat(np.arange(q.size), m)
    u = np.arange(rep.size) - np.repeat(np.cumsum(m) - m, m)
    if skip is not None:
        u += np.where(u >= skip_at[q, jt][rep], skip[q, jt][rep], 0)
    return jt[rep], (r0[jt] >> _SHIFT)[rep] + q[rep], start[q, jt][rep] + u


def _tile_masks(lo, cnt, j, q, x0):
    """Covered samples (TILE, TILE, S, n) of tiles in tile row ``q`` of pieces ``j``, first column ``x0`` (local)."""
    k, S, n = lo.shape
    # Rows (TILE, S, m) of each tile in the dense layout.
    at = ((q * TILE)[None, None] + np.arange(TILE)[:, None, None]) * (S * n) + (np.arange(S) * n)[None, :, None] + j
    lo_t = np.take(lo, at)
    end_t = lo_t + np.take(cnt, at)
    col = (x0 + np.arange(TILE)[:, None]).astype(np.float64)  # (TILE columns, m)
    col = col[None, :, None, :]
    return (lo_t[:, None] <= col) & (col < end_t[:, None])


def tile_depths(s, i, tr, tc, sx, sy, dtype):
    """Depths (TILE, TILE, S, n) of the samples (row, column, sample) of tiles (tr, tc) of setup triangles ``i``.

    ``(z0 + za X) + zb Y`` as in :func:`._spans._iter_spans`: X, Y the samples' integer
    offsets from vertex 0 (exact in float64), the last addition rounded to ``dtype``.
    The tiles are the innermost axis, so that every pass runs over long rows.
    """
    S = sx.shape[0]
    step = (np.arange(TILE) * _SUB)[:, None, None]
    # Offsets of the tile's first pixel centre from vertex 0, and of each (column or row, sample) from it.
    x0 = (tc * (TILE * _SUB) + _HALF - s["X"][0][i]).astype(np.float64)
    y0 = (tr * (TILE * _SUB) + _HALF - s["Y"][0][i]).astype(np.float64)
    xz = (step + sx[:, None]).astype(np.float64) + x0  # (TILE columns, S, n): exact integers
    xz *= s["za"][i]
    xz += s["z0"][i]
    yz = (step + sy[:, None]).astype(np.float64) + y0  # (TILE rows, S, n)
    yz *= s["zb"][i]
    z = np.empty((TILE, TILE, S, i.size), dtype)
    return np.add(xz[None], yz[:, None], out=z)


def write_tiles(depth, w, S, tr, tc, z):
    """Depth test of the tiles' depths ``z`` (TILE, TILE, S, n) into the flat map ``depth`` (h w S)."""
    base = (tr * (TILE * w) + tc * TILE) * S
    off = ((np.arange(TILE)[:, None] * w + np.arange(TILE)) * S)[:, :, None] + np.arange(S)
    flat = (off[..., None] + base).ravel()
    if (int(tr.max()) + 1) * TILE * w * S > depth.size or (int(tc.max()) + 1) * TILE > w:
        # A partial tile at the map's last rows or columns: its samples beyond the map are
        # masked (+inf), so any index in the map does for them (beyond the right edge they
        # already land on the next row's first samples).
        np.minimum(flat, depth.size - 1, out=flat)
    np.minimum.at(depth, flat, z.ravel())
