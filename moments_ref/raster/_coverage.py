"""Coverage: which samples of which pixels each set-up triangle covers (small boxes binned, large ones tiled).

Part of :mod:`moments_ref.raster` (see its docstring for the conventions).
"""

from __future__ import annotations

import numpy as np

from ._matrices import _HALF, _SUB
from ._triangles import _all3

# Bounding boxes up to this many pixels per side are "small"; larger ones are tiled.
_TILE = 32
# Elements (triangles × grid pixels × samples) evaluated per vectorized chunk.
_BUDGET = 1 << 21

# ---------------------------------------------------------------------------
# Coverage


# Grid sides of the coverage bins: exact for tiny boxes, then steps of 1/4 to 1/3 octave
# so that a bin's grid wastes little over its boxes.
_GRID_SIDES = np.array(sorted({1, 2, 3, 4, 5, 6, 7} | {int(b * f) for b in 2 ** np.arange(3, 16)
                                                        for f in (1, 1.25, 1.5, 1.75)}))


def _grid_key(nr, nc):
    """Bin key of boxes with nr rows and nc columns; decode with _grid_dims."""
    return np.searchsorted(_GRID_SIDES, nr) * 256 + np.searchsorted(_GRID_SIDES, nc)


def _grid_dims(key):
    return int(_GRID_SIDES[key // 256]), int(_GRID_SIDES[key % 256])


def _cover(s, items, r0, c0, nr, nc, gh, gw, sx, sy, itype):
    """Covered samples of `items` (indices into the setup arrays) on a gh × gw grid.

    The grid of item i starts at pixel (r0[i], c0[i]); only its first nr[i] rows and
    nc[i] columns are valid. Returns (item position, row, col, sample) of covered samples.

    Layout (gh, gw, S, n) with the items innermost and n padded to a power of two:
    the broadcast adds then run over long contiguous rows, and decoding a flat index
    is a shift and a mask instead of integer divisions.
    """
    S = sx.shape[0]
    n = items.shape[0]
    npad = 1 << max(0, int(n - 1).bit_length())
    shift = npad.bit_length() - 1
    A = np.zeros((3, npad), np.int64)
    B = np.zeros((3, npad), np.int64)
    F0 = np.full((3, npad), -1, np.int64)  # padding items fail every test
    A[:, :n], B[:, :n], F0[:, :n] = s["A"][:, items], s["B"][:, items], s["F0"][:, items]
    # Edge function at the centre of the grid's first pixel, then per sample / row / column.
    base = F0
    base[:, :n] += A[:, :n] * (c0 * _SUB + _HALF) + B[:, :n] * (r0 * _SUB + _HALF)  # exact in int64
    oy = np.arange(gh, dtype=np.int64)[:, None] * _SUB
    ox = np.arange(gw, dtype=np.int64)[:, None] * _SUB
    acc = None
    for e in range(3):
        a, b = A[e], B[e]
        fs = (base[e] + a * sx[:, None] + b * sy[:, None]).astype(itype)  # (S, n)
        fy = (b * oy).astype(itype)  # (gh, n)
        fx = (a * ox).astype(itype)  # (gw, n)
        f_ys = fy[:, None, :] + fs[None, :, :]  # (gh, S, n)
        if acc is None:
            acc = f_ys[:, None] + fx[None, :, None]  # (gh, gw, S, n)
        else:
            F = f_ys[:, None] + fx[None, :, None]
            np.bitwise_or(acc, F, out=acc)
    # Grid cells beyond an item's bounding box: a negative "edge" makes them fail.
    if (nc < gw).any():
        vx = np.zeros((gw, npad), itype)
        vx[:, :n] = nc.astype(itype) - 1 - np.arange(gw, dtype=itype)[:, None]
        np.bitwise_or(acc, vx[None, :, None, :], out=acc)
    if (nr < gh).any():
        vy = np.zeros((gh, npad), itype)
        vy[:, :n] = nr.astype(itype) - 1 - np.arange(gh, dtype=itype)[:, None]
        np.bitwise_or(acc, vy[:, None, None, :], out=acc)
    idx = np.flatnonzero(acc >= 0)
    del acc
    item = idx & (npad - 1)
    cell = idx >> shift  # = (row * gw + col) * S + sample within the grid
    cy, rest = np.divmod(np.arange(gh * gw * S), gw * S)
    cx, cs = np.divmod(rest, S)
    return item, r0[item] + cy[cell], c0[item] + cx[cell], cs[cell]


def _bins(key):
    """Split positions 0..len(key)-1 into groups of equal key: (key, positions) pairs."""
    order = np.argsort(key, kind="stable")
    ks = key[order]
    bounds = np.flatnonzero(np.diff(ks)) + 1
    for part in np.split(order, bounds):
        if part.size:
            yield int(key[part[0]]), part


def _iter_coverage(s, h, w, sx, sy):
    """Yield (setup index, row, col, sample) arrays of covered samples, batch by batch.

    sx, sy : (S,) int64 sample offsets in 1/256 pixel. Small boxes are binned by
    their size (:func:`_cover_binned`), large ones cut into tiles
    (:func:`_iter_large`); a generator call per batch: no measurable cost (measured
    with the triangle setup split, see :func:`moments_ref.raster._triangles._setup`).
    """
    c0, c1, r0, r1, small = _boxes(s, h, w, sx, sy)
    nonempty = (c0 <= c1) & (r0 <= r1)
    # Small triangles: bins by the (rows, cols) of the clamped box (see _GRID_SIDES); int32
    # is exact because |E| <= 2 (34 * 256)^2 < 2^31 within such a box.
    sel = np.flatnonzero(small & nonempty)
    yield from _cover_binned(s, sel, r0[sel], c0[sel], r1[sel] - r0[sel] + 1, c1[sel] - c0[sel] + 1, sx, sy,
                             np.int32)
    big = np.flatnonzero(~small & nonempty)
    if big.size:
        yield from _iter_large(s, big, c0, c1, r0, r1, sx, sy)


def _boxes(s, h, w, sx, sy):
    """Pixel bounding boxes (c0, c1, r0, r1) clamped to the map, and which are small (unclamped)."""
    X, Y = s["X"], s["Y"]
    # Pixel col has a sample at col*256 + 128 + sx; it may be covered only if some
    # sample lies within [min X, max X] of the vertices.
    c0 = -((-(X.min(0) - _HALF - sx.max())) // _SUB)
    c1 = (X.max(0) - _HALF - sx.min()) // _SUB
    r0 = -((-(Y.min(0) - _HALF - sy.max())) // _SUB)
    r1 = (Y.max(0) - _HALF - sy.min()) // _SUB
    small = (c1 - c0 < _TILE) & (r1 - r0 < _TILE)  # unclamped: vertices are near the box
    np.maximum(c0, 0, out=c0)
    np.minimum(c1, w - 1, out=c1)
    np.maximum(r0, 0, out=r0)
    np.minimum(r1, h - 1, out=r1)
    return c0, c1, r0, r1, small


def _cover_binned(s, tri, r0, c0, nr, nc, sx, sy, itype):
    """Coverage of the boxes (r0, c0, nr, nc) of triangles ``tri``, binned by box size, in budgeted batches."""
    S = sx.shape[0]
    for key, part in _bins(_grid_key(nr, nc)):
        gh, gw = _grid_dims(key)
        step = max(1, _BUDGET // (gh * gw * S))
        for k in range(0, part.size, step):
            p = part[k:k + step]
            item, row, col, samp = _cover(s, tri[p], r0[p], c0[p], nr[p], nc[p], gh, gw, sx, sy, itype)
            yield tri[p][item], row, col, samp


def _iter_large(s, big, c0, c1, r0, r1, sx, sy):
    """Large triangles: cut the clamped box into _TILE × _TILE tiles, reject tiles outside an edge, int64."""
    S = sx.shape[0]
    tx0, tx1 = c0[big] // _TILE, c1[big] // _TILE
    ty0, ty1 = r0[big] // _TILE, r1[big] // _TILE
    ntx = tx1 - tx0 + 1
    counts = ntx * (ty1 - ty0 + 1)
    csum = np.cumsum(counts)
    chunk_pairs = max(1, _BUDGET // (_TILE * _TILE * S)) * 8
    start = 0
    while start < big.size:
        # Process (triangle, tile) pairs for a run of triangles to bound memory.
        stop = int(np.searchsorted(csum, (csum[start - 1] if start else 0) + chunk_pairs, side="right"))
        stop = max(stop, start + 1)
        ids = np.arange(start, stop)
        cnt = counts[ids]
        pair = np.repeat(ids, cnt)
        local = np.arange(pair.size) - np.repeat(np.cumsum(cnt) - cnt, cnt)
        tcol = tx0[pair] + local % ntx[pair]
        trow = ty0[pair] + local // ntx[pair]
        t = big[pair]
        pc0 = np.maximum(tcol * _TILE, c0[t])
        pc1 = np.minimum(tcol * _TILE + _TILE - 1, c1[t])
        pr0 = np.maximum(trow * _TILE, r0[t])
        pr1 = np.minimum(trow * _TILE + _TILE - 1, r1[t])
        # Tile rejection: the largest F of each edge over the tile's sample extremes.
        xlo, xhi = pc0 * _SUB + _HALF + sx.min(), pc1 * _SUB + _HALF + sx.max()
        ylo, yhi = pr0 * _SUB + _HALF + sy.min(), pr1 * _SUB + _HALF + sy.max()
        A, B, F0 = s["A"][:, t], s["B"][:, t], s["F0"][:, t]
        fmax = A * np.where(A > 0, xhi, xlo) + B * np.where(B > 0, yhi, ylo) + F0
        live = _all3(fmax >= 0)
        t, pr0, pc0, pr1, pc1 = t[live], pr0[live], pc0[live], pr1[live], pc1[live]
        yield from _cover_binned(s, t, pr0, pc0, pr1 - pr0 + 1, pc1 - pc0 + 1, sx, sy, np.int64)
        start = stop


def _depth_at(s, i, row, col, samp, sx, sy):
    """Plane depth (float64) of setup triangle i at the given samples."""
    Xs = col * _SUB + _HALF + sx[samp] - s["X"][0, i]
    Ys = row * _SUB + _HALF + sy[samp] - s["Y"][0, i]
    return s["z0"][i] + s["za"][i] * Xs + s["zb"][i] * Ys
