"""Coverage by spans: for each (triangle, pixel row, sample) the covered columns, solved from the edges.

Part of :mod:`moments_ref.scene.raster` (see its docstring for the conventions).

Along a row of samples (fixed pixel row and sample index) the edge function of
edge e is affine in the pixel column u counted from the box's first column:
``F_e(u) = a_e u + L_e`` with ``a_e = 256 A_e``. The covered columns
``F_e(u) >= 0`` for all three edges are one interval: ``u >= ceil(-L_e / a_e)``
for ``a_e > 0``, ``u <= floor(-L_e / a_e)`` for ``a_e < 0``, all or nothing for
``a_e = 0``. So the work per row is a constant, and the covered samples are
written out from their intervals without testing the empty ones: the fill
rate of a large triangle costs only its covered samples.

Two shortcuts give the same samples and depths: boxes of up to 2 x 2 pixels of 1x maps
(a view of a finely tessellated mesh: 99 % of the knot's boxes at 512²) test each of
their samples against the three edges directly (:func:`_small_boxes`); and where a dense
group's boxes have few columns for their covered samples, ``z0 + za X`` is tabulated per
(sample, box, column), since X does not depend on the row, and each sample looks it up
(:func:`_rect_values`).
"""

from __future__ import annotations

import numpy as np

from ..._kernels import RASTER_ROW_BUDGET, RASTER_SAMPLE_BUDGET
from ._matrices import _HALF, _SUB

# (triangle, row, sample) rows per vectorized batch, and covered samples per yielded
# batch (moments_ref._kernels' table, with the measurement behind them).
_ROW_BUDGET = RASTER_ROW_BUDGET
_SAMPLE_BUDGET = RASTER_SAMPLE_BUDGET

# Below this magnitude an int64 L is exact in float64, and then ceil/floor of the
# correctly rounded float quotient L / a equals the exact integer one: a non-integer
# quotient lies at least 1/|a| from an integer, farther than its rounding error
# |L / a| 2^-53 whenever |L| < 2^53. (Integer floor division costs 8 ns an element in
# NumPy, a float division 0.5 ns.)
_EXACT_FLOAT = float(1 << 53)
# Boxes up to this many rows take the dense path (_rect_spans).
_DENSE_ROWS = 32
# Dense groups of boxes are merged with the next larger row counts up to this many layout rows
# (_merged_counts).
_MERGE_ROWS = 1 << 14
# The dense path hands _iter_spans its span rows' values (_rect_values); False: their indices.
_ROW_VALUES = True
# Boxes of up to 2 x 2 pixels of 1x maps take _small_boxes (a test per sample) where a chunk has at
# least this many (fewer cost more as a batch of their own than in the dense groups; with 4 or 8
# samples the dense rows are quicker, measured); 0: never. _SMALL_SAMPLES: the sample counts it serves.
_SMALL = 1024
_SMALL_SAMPLES = (1,)
# _rect_values hands over a table of z0 + za X per (sample, box, column) where it holds at most
# this many entries per covered sample; 0: never.
_TABLE = 1.0
# Triangles whose vertex coordinates (1/256 pixel) lie below this bound in magnitude
# have edge values below 2^51 at every sample in the map, so the dense path's float64
# arithmetic is exact: samples lie below 2^22 (16384 pixels), so |A|, |B| and the
# offsets from a vertex stay below 2^25 and |E| < 2 * 2^25 * 2^25.
_FLOAT_SAFE_COORD = 1 << 24


def _solve_interval(L, a, na, lo, hi):
    """Narrow [lo, hi] (int64, in place) to the columns u with ``a u + L >= 0``.

    Per row: L int64, a = 256 A int64, na = -a where a != 0 and 1 where a == 0 (so
    that the float quotient is finite everywhere and no mask is needed for it).
    """
    t = L / na
    pos = a > 0
    neg = a < 0
    bound = np.where(pos, np.ceil(t), np.floor(t)).astype(np.int64)
    big = np.flatnonzero(np.abs(L) >= _EXACT_FLOAT)
    if big.size:  # exact integer division (huge triangles reaching into the guard band)
        Lb, ab = L[big], a[big]
        safe = np.where(ab == 0, 1, ab)
        bound[big] = np.where(ab > 0, -(Lb // safe), Lb // np.abs(safe))
    np.maximum(lo, np.where(pos, bound, lo), out=lo)
    np.minimum(hi, np.where(neg, bound, hi), out=hi)
    # a == 0 (edge parallel to the rows): the whole row or nothing.
    np.minimum(hi, np.where((~(pos | neg)) & (L < 0), -1, hi), out=hi)


def _groups(weight, budget):
    """Split positions 0..n-1 into consecutive runs of summed ``weight`` about ``budget`` (at least one each)."""
    csum = np.cumsum(weight)
    start = 0
    while start < weight.size:
        base = csum[start - 1] if start else 0
        stop = max(start + 1, int(np.searchsorted(csum, base + budget, side="right")))
        yield start, stop
        start = stop


def _row_spans(A3, B3, base3, c0, nc, r0, nr, sx, sy):
    """Covered column interval of every (triangle, row, sample) row of the boxes, in int64.

    A3, B3 : (3, n) edge coefficients; base3 : (3, n) edge values at the centre of
    the box's first pixel. Rows are ordered by triangle, pixel row, sample. Returns
    the row's triangle position, pixel row, sample, first covered column and count
    (count 0 rows left out).
    """
    S = sx.shape[0]
    R = nr * S
    pt = np.repeat(np.arange(nr.size), R)
    k = np.arange(pt.size) - np.repeat(np.cumsum(R) - R, R)
    ro, samp = np.divmod(k, S) if S & (S - 1) else (k >> (S.bit_length() - 1), k & (S - 1))  # S = 1, 4, 8: shifts
    yoff = sy[samp] + ro * _SUB
    xoff = sx[samp]
    lo = np.zeros(pt.size, np.int64)
    hi = (nc - 1)[pt]
    for e in range(3):
        A, B, base = A3[e], B3[e], base3[e]
        a = A * _SUB
        na = np.where(a == 0, 1, -a)
        L = base[pt] + A[pt] * xoff + B[pt] * yoff
        _solve_interval(L, a[pt], na[pt], lo, hi)
    cnt = hi - lo + 1
    keep = cnt > 0  # np.compress: quicker than a boolean or integer index
    pt, ro, samp, lo, cnt = (np.compress(keep, a) for a in (pt, ro, samp, lo, cnt))
    return pt, r0[pt] + ro, samp, c0[pt] + lo, cnt


def _row_batches(s, c0, nc, r0, nr, safe, sx, sy, taken=None, w=None):
    """Yield _row_spans-like batches (row's triangle index first) over all triangles of ``s``.

    ``taken`` (bool per box, optional): boxes another path draws (:mod:`._tiles`), left out
    here; they must be ``safe``. ``w`` (the map's width, optional): the dense path's batches
    are yielded as the span rows' values instead (:func:`_rect_values`).

    Boxes of up to _DENSE_ROWS rows go, grouped by their row count (a bincount, no sort;
    groups of few boxes merged with the next larger counts, :func:`_merged_counts`), to the
    dense float path; taller boxes go there too, cut into pieces of
    _DENSE_ROWS rows (:func:`_tall_pieces`: the same rows, the same exact edge values).
    Only boxes too far into the guard band for float64 to be exact (and every box when
    _DENSE_ROWS is 0) take the ragged int64 path.
    """
    S = sx.shape[0]
    A3, B3 = s["A"], s["B"]
    # Edge functions at the centre of each box's first pixel, exact in int64.
    base3 = s["F0"] + A3 * (c0 * _SUB + _HALF) + B3 * (r0 * _SUB + _HALF)
    mine = np.ones(nr.size, bool) if taken is None else ~taken
    dense = (nr <= _DENSE_ROWS) & safe & mine
    safe = safe & mine
    tall = np.flatnonzero(~dense & safe) if _DENSE_ROWS > 0 else np.zeros(0, np.int64)
    # The dense boxes, then the tall boxes' pieces: the triangle of each, its box and edge values.
    if tall.size:
        tri, c0d, ncd, r0d, nrd, based = _tall_pieces(np.flatnonzero(dense), tall, c0, nc, r0, nr, base3, B3)
        A3d, B3d = np.take(A3, tri, axis=1), np.take(B3, tri, axis=1)
        key = nrd
    else:  # no pieces: the boxes as they are (the others have key 0)
        tri, c0d, ncd, r0d, nrd, based, A3d, B3d = None, c0, nc, r0, nr, base3, A3, B3
        key = np.where(dense, nr, 0)
    if _SMALL > 0 and S in _SMALL_SAMPLES:  # boxes of up to 2 x 2 pixels: each sample tested against the three edges (_small_boxes)
        small = (key > 0) & (key <= 2) & (ncd <= 2)
        if np.count_nonzero(small) >= _SMALL:  # enough of them for a batch of its own
            key = np.where(small, 0, key)  # (a new array: key may be nrd itself)
            one = np.flatnonzero(small)
            edges = (np.take(x, one, axis=1) for x in (A3d, B3d, based))
            yield _small_boxes(s, one if tri is None else tri[one], *edges, c0d[one], r0d[one], nrd[one], ncd[one],
                               sx, sy, w if _ROW_VALUES else None)
    key = _merged_counts(key, S)
    # The dense groups' edges in _rect_bounds' order (_edge_order), once for the chunk; pos maps a
    # box to its column there.
    ordered = np.flatnonzero(key)
    if ordered.size:
        A3o, B3o, E3o = _edge_order(*(np.take(x, ordered, axis=1) for x in (A3d, B3d, based)))
        pos = np.zeros(key.size, np.intp)
        pos[ordered] = np.arange(ordered.size)
    for k in np.flatnonzero(np.bincount(key, minlength=1)[1:]) + 1:
        sel = np.flatnonzero(key == k)
        step = max(1, _ROW_BUDGET // (int(k) * S))
        for a in range(0, sel.size, step):
            g = sel[a:a + step]
            a3, b3, e3 = (np.take(x, pos[g], axis=1) for x in (A3o, B3o, E3o))
            if w is not None and _ROW_VALUES:
                yield _rect_values(s, g if tri is None else tri[g], a3, b3, e3, c0d[g], ncd[g], r0d[g], nrd[g], int(k),
                                   sx, sy, w)
                continue
            j, row, samp, col0, cnt = _rect_spans(a3, b3, e3, c0d[g], ncd[g], r0d[g], nrd[g], int(k), sx, sy,
                                                  presorted=True)
            yield (g if tri is None else tri[g])[j], row, samp, col0, cnt
    rest = np.flatnonzero((~dense if _DENSE_ROWS <= 0 else ~safe) & mine)
    for g0, g1 in _groups(nr[rest] * S, _ROW_BUDGET):
        g = rest[g0:g1]
        a3, b3, e3 = (np.take(x, g, axis=1) for x in (A3, B3, base3))
        pt, row, samp, col0, cnt = _row_spans(a3, b3, e3, c0[g], nc[g], r0[g], nr[g], sx, sy)
        yield g[pt], row, samp, col0, cnt


def _small_boxes(s, tri, A3, B3, base3, c0, r0, nr, nc, sx, sy, w=None):
    """The span rows of boxes of up to 2 x 2 pixels (setup triangles ``tri``): a covered sample is a row of one.

    ``base3`` (3, m): the edge values at the centre of the box's first pixel (exact int64).
    The sample q of the pixel (dr, dc) of a box is covered when ``base3 + A3 ox + B3 oy >= 0``
    for the three edges, (ox, oy) = (dc 256 + sx_q, dr 256 + sy_q) its offset: the test
    :func:`_rect_bounds` solves per row, here in three integer passes per edge over the
    nr nc S samples of each box (the boxes of each shape together) instead of its dozens per
    row. Rows in (shape, pixel, sample, box) order, yielded as :func:`_rect_values` yields
    them (``w`` given; the same values for the same samples) or as :func:`_row_batches`'
    indices (triangle, row, sample, column, count 1).
    """
    S = sx.shape[0]
    parts = []
    shape = nr * 2 + nc  # 3, 4, 5, 6 for 1 x 1, 1 x 2, 2 x 1, 2 x 2
    for R, C in ((1, 1), (1, 2), (2, 1), (2, 2)):
        sel = np.flatnonzero(shape == 2 * R + C)
        if sel.size == 0:
            continue
        # The R C S candidate samples: pixel row and column within the box, sample (in cov's order).
        k = np.arange(R * C * S)
        dr, dc, q = k // (C * S), k // S % C, k % S
        a3, b3, e3 = (np.take(x, sel, axis=1) for x in (A3, B3, base3)) if sel.size < c0.size else (A3, B3, base3)
        cov = np.ones((R, C, S, sel.size), bool)
        for e in range(3):
            # The edge at each pixel's samples: the first pixel's plus 256 A per column, 256 B per row.
            v = e3[e] + a3[e] * sx[:, None] + b3[e] * sy[:, None] if sx.any() or sy.any() else e3[e][None]
            for r in range(R):
                if r:
                    v = v + b3[e] * _SUB
                cov[r, 0] &= v >= 0
                if C == 2:
                    cov[r, 1] &= (v + a3[e] * _SUB) >= 0
        p, j = np.divmod(np.flatnonzero(cov), sel.size)  # candidate, box
        j = np.take(sel, j)
        parts.append((j, np.take(r0, j) + np.take(dr, p), np.take(c0, j) + np.take(dc, p), np.take(q, p)))
    j, row, col, samp = (np.concatenate(x) for x in zip(*parts))
    t = np.take(tri, j)
    ones = np.ones(j.size, np.int64)
    if w is None:
        return t, row, samp, col, ones
    xs0 = ((col * _SUB + np.take(_HALF - s["X"][0], t)) + np.take(sx, samp)).astype(np.float64)
    y = ((row * _SUB + np.take(_HALF - s["Y"][0], t)) + np.take(sy, samp)).astype(np.float64)
    flat0 = (row * w + col) * S + samp
    return xs0, y * np.take(s["zb"], t), np.take(s["z0"], t), np.take(s["za"], t), flat0, ones, None


def _merged_counts(key, S):
    """Row counts ``key`` (0: not on the dense path) with small groups merged upwards.

    Ascending, the boxes of consecutive row counts are gathered until they hold _MERGE_ROWS
    (row, sample, box) rows of the dense layout, and take the largest of their counts (the rows
    beyond a box's own are masked in _rect_bounds): fewer groups, each a few dozen NumPy calls,
    for few padded rows. Groups that are large on their own (small triangles by the thousand)
    stay as they are.
    """
    if _MERGE_ROWS <= 0:
        return key
    n = np.bincount(key, minlength=_DENSE_ROWS + 1)
    to = np.arange(n.size)
    acc, members = 0, []
    for k in np.flatnonzero(n[1:]) + 1:
        acc += int(n[k]) * int(k) * S
        members.append(k)
        if acc >= _MERGE_ROWS:
            to[members] = k
            acc, members = 0, []
    if members:
        to[members] = members[-1]
    return to[key]


def _tall_pieces(small, tall, c0, nc, r0, nr, base3, B3):
    """The boxes ``small`` as they are and the boxes ``tall`` cut into pieces of _DENSE_ROWS rows.

    Returns (triangle, c0, nc, r0, nr, base3) of every box or piece. A piece starting
    ``d`` rows below its box has the edge values ``base3 + B3 d 256`` at its first
    pixel (exact in int64), so its rows are those of the whole box.
    """
    if tall.size == 0:
        return small, c0[small], nc[small], r0[small], nr[small], np.take(base3, small, axis=1)
    pieces = (nr[tall] + _DENSE_ROWS - 1) // _DENSE_ROWS
    ti = np.repeat(tall, pieces)
    first = np.repeat(np.cumsum(pieces) - pieces, pieces)
    drow = (np.arange(ti.size) - first) * _DENSE_ROWS  # rows from the box's top to the piece's
    tri = np.concatenate([small, ti])
    based = np.concatenate([np.take(base3, small, axis=1),
                            np.take(base3, ti, axis=1) + np.take(B3, ti, axis=1) * (drow * _SUB)], axis=1)
    return (tri, c0[tri], nc[tri], np.concatenate([r0[small], r0[ti] + drow]),
            np.concatenate([nr[small], np.minimum(nr[ti] - drow, _DENSE_ROWS)]), based)


def _iter_spans(s, c0, c1, r0, r1, safe, sx, sy, w, want_rcs, dtype=np.float64, batches=None):
    """Yield (flat sample index, depth, all in [-1, 1], (setup index, row, col, sample) or None).

    Boxes are clamped to the map and nonempty; the flat index is
    ``(row * w + col) * S + sample``, the (setup index, row, col, sample) arrays
    are built only when ``want_rcs``. The depth is the plane through the snapped vertices,
    ``z0 + za (X - X0) + zb (Y - Y0)`` in float64 with the integer offsets
    converted exactly, evaluated in this order for every sample (so the values do
    not depend on how samples are batched). The per-row parts are computed once
    per row and repeated along the row's covered columns. The depth is float64 where
    some may lie outside [-1, 1] (the caller clips them), else already rounded to
    ``dtype`` by the last addition (the same value as rounding the float64 sum).
    ``batches``: the span rows to expand, when not those of :func:`_row_batches` of every box
    (a callable of (s, c0, nc, r0, nr, safe, sx, sy) returning an iterable of batches; given the
    keyword ``w`` when no fragments and no clip tests are wanted, it may yield the rows' values
    of :func:`_rect_values` instead of their indices).
    """
    S = sx.shape[0]
    nc, nr = c1 - c0 + 1, r1 - r0 + 1
    tri_inside = s["inside"]  # every covered sample's depth provably in [-1, 1] (_triangles._depth_inside)
    all_inside = bool(tri_inside.all())  # once for the chunk, not a gather per span row
    # Offsets of a box's pixel centres from vertex 0, per triangle (integers, exact).
    cx, cy = _HALF - s["X"][0], _HALF - s["Y"][0]
    # Without fragments and depth clips, the dense path hands over each span row's values,
    # not its (triangle, row, sample, column) (_rect_values).
    fast = {"w": w} if all_inside and not want_rcs else {}
    rows = (batches or _row_batches)(s, c0, nc, r0, nr, safe, sx, sy, **fast)
    for item in rows:
        table = None
        if len(item) == 7:
            xs0, zbY, z0, za, flat0, cnt, table = item
            i_row = row = samp = col0 = None
        else:
            i_row, row, samp, col0, cnt = item
            xs0 = col0 * _SUB + sx[samp] + cx[i_row]
            zbY = s["zb"][i_row] * (row * _SUB + sy[samp] + cy[i_row])
            z0, za = s["z0"][i_row], s["za"][i_row]
            flat0 = (row * w + col0) * S + samp
        if all_inside or tri_inside[i_row].all():
            inside = None  # every row's depths in [-1, 1]
        else:
            # z is monotone along a row (each rounding step is), so a row whose first and
            # last sample lie in [-1, 1] needs no depth-clip test per sample.
            zf, zl = z0 + za * xs0 + zbY, z0 + za * (xs0 + (cnt - 1) * _SUB) + zbY
            inside = (np.minimum(zf, zl) >= -1.0) & (np.maximum(zf, zl) <= 1.0)
        for b0, b1 in _groups(cnt, _SAMPLE_BUDGET):
            b = slice(b0, b1)
            c = cnt[b]
            n = int(c.sum())
            start = np.cumsum(c) - c  # first position of each row in the batch
            rep = _repeater(c, n)
            # Positions k = start + local: fold -start into the row values, and add the
            # constant ramps k * step (cached), one repeat and one add per array. The
            # column offsets are integers below 2^53, exact in float64, and the depth is
            # (z0 + za Xs) + zb Ys, evaluated in place.
            if table is not None:  # z0 + za Xs looked up in the table of the rows' columns (_rect_values)
                z = rep(xs0[b] - start)
                z += _ramp(n, 1)
                z = np.take(table, z)
            else:
                z = rep((xs0[b] - start * _SUB).astype(np.float64, copy=False))
                z += _ramp(n, _SUB, np.float64)
                z *= rep(za[b])
                z += rep(z0[b])
            ins = inside is None or bool(inside[b].all())
            # The last addition rounds straight to dtype when no depth needs a clip test.
            z = np.add(z, rep(zbY[b]), out=z if not ins or dtype == np.float64 else np.empty(n, dtype))
            flat = rep(flat0[b] - start * S)
            flat += _ramp(n, S)
            # The depth pass needs only flat and z: the rest is built for fragments only.
            rcs = None
            if want_rcs:
                rcs = (rep(i_row[b]), rep(row[b]), rep(col0[b] - start) + _ramp(n, 1), rep(samp[b]))
            yield flat, z, ins, rcs


def _repeater(c, n):
    """``rep(a)`` = ``np.repeat(a, c)`` (n = c.sum(), every c >= 1; ``a`` itself where every c is 1, so callers
    write only into results of arrays they made): for short rows as a gather by one
    repeated row index (np.take), quicker than np.repeat's per-row copies below about 8 samples a row
    (measured). The row index is the running count of row starts (a cumsum of marks at the starts:
    2.5 ms instead of 3.8 ms for np.repeat of the row numbers on the bench's mid-size case)."""
    if n == c.size:  # every row one sample (_small_boxes' rows): the rows themselves (callers only read them)
        return lambda a: a
    if n >= 8 * c.size:
        return lambda a: np.repeat(a, c)
    ri = np.zeros(n, np.intp)
    ri[np.cumsum(c[:-1])] = 1
    np.cumsum(ri, out=ri)
    return lambda a: np.take(a, ri)


_RAMPS = {}


def _ramp(n, step, dtype=np.int64):
    """``np.arange(n) * step`` as ``dtype``, read-only, cut from a cached array grown as needed (a constant of the batch size)."""
    key = (step, np.dtype(dtype).char)
    r = _RAMPS.get(key)
    if r is None or r.size < n:
        r = (np.arange(max(n, 2 * (0 if r is None else r.size), 1 << 16), dtype=np.int64) * step).astype(dtype)
        r.flags.writeable = False
        _RAMPS[key] = r
    return r[:n]


def _rect_spans(A3, B3, base3, c0, nc, r0, nr, k, sx, sy, presorted=False):
    """As :func:`_row_spans` for boxes of at most k rows, on a dense (k, S, n) layout in float64.

    The bounds are :func:`_rect_bounds`' (``presorted``: the edges already in :func:`_edge_order`'s
    order); this keeps the nonempty rows.
    """
    S = sx.shape[0]
    n = nr.size
    lo, cnt = _rect_bounds(A3, B3, base3, nc, nr, k, sx, sy, presorted=presorted)
    # The nonempty rows in (row, sample, triangle) order: their flat positions (r S + sample) n + j,
    # split by one division by the scalar n (NumPy divides by a scalar without a hardware division)
    # and a shift and a mask (S = 1, 4, 8); lo and cnt gathered at the positions. On a 25 x 4 x 128
    # layout (a batch of the bench's mid-size case) 0.73 of the time of np.nonzero of the 3-d mask
    # with two boolean indexes (np.nonzero costs about 5 ns an element, np.flatnonzero 1).
    keep = np.flatnonzero(cnt > 0)
    rs, j = np.divmod(keep, n)
    r, samp = rs >> (S.bit_length() - 1), rs & (S - 1)  # S a power of two (the D3D11 patterns' 1, 4, 8)
    return j, r0[j] + r, samp, c0[j] + np.take(lo, keep).astype(np.int64), np.take(cnt, keep).astype(np.int64)


def _rect_values(s, tri, A3, B3, base3, c0, nc, r0, nr, k, sx, sy, w):
    """The values :func:`_iter_spans` needs of each nonempty span row of :func:`_rect_spans` (edges presorted).

    Returns (xs0, zbY, z0, za, flat0, cnt, table) per row in :func:`_rect_spans`' order: xs0
    the first covered sample's X offset from vertex 0, ``zbY = zb Y`` of the row, the
    triangle's z0 and za, the flat index of the first covered sample, and ``table`` None.
    The same integers and the same float64 product as :func:`_iter_spans` computes from
    (triangle, row, sample, column), taken from small (sample, box) tables and two dense
    (k, S, n) ones, so each row costs about a dozen passes instead of thirty.

    Where the boxes' columns are fewer than half the covered samples (boxes of many rows),
    ``table`` is instead the flat (S, n, W) array of ``z0 + za X`` at every column of every
    (sample, box) (W the widest box; X depends on the column and the sample, not the row),
    xs0 the row's index of its first covered sample in it, z0 and za None: each sample then
    needs one lookup instead of three gathers, a multiplication and an addition, with the
    same operations in the same order (so the same depths).
    """
    S = sx.shape[0]
    n = nr.size
    lo, cnt = _rect_bounds(A3, B3, base3, nc, nr, k, sx, sy, presorted=True)
    keep = np.flatnonzero(cnt > 0)  # (r S + sample) n + box
    at = keep % (S * n)  # sample n + box
    lo_k = np.take(lo, keep)
    cnt = np.take(cnt, keep).astype(np.int64)
    # X of the box's first column and Y of its first row, per (sample, box): exact integers.
    x_sb = ((c0 * _SUB + np.take(_HALF - s["X"][0], tri)) + sx[:, None]).astype(np.float64)
    y_sb = ((r0 * _SUB + np.take(_HALF - s["Y"][0], tri)) + sy[:, None]).astype(np.float64)
    zbY = np.add(y_sb[None], (np.arange(k, dtype=np.float64) * _SUB)[:, None, None])
    zbY *= np.take(s["zb"], tri)  # (k, S, n): zb Y, Y exact in float64
    flat_t = ((r0 * w + c0) * S + np.arange(S)[:, None])[None] + (np.arange(k) * (w * S))[:, None, None]
    flat0 = lo_k.astype(np.int64)
    cols = int(nc.max())
    if S * n * cols <= _TABLE * int(cnt.sum()):
        table = np.add(x_sb[:, :, None], _ramp(cols, _SUB, np.float64))  # X (S, n, W), exact
        table *= np.take(s["za"], tri)[:, None]
        table += np.take(s["z0"], tri)[:, None]
        tix0 = at * cols
        tix0 += flat0
        flat0 *= S
        flat0 += np.take(flat_t, keep)
        return tix0, np.take(zbY, keep), None, None, flat0, cnt, table.reshape(-1)
    xs0 = lo_k * _SUB  # float64, exact
    xs0 += np.take(x_sb, at)
    flat0 *= S
    flat0 += np.take(flat_t, keep)
    zs = np.empty((2, S, n))  # z0 and za per (sample, box)
    zs[0], zs[1] = np.take(s["z0"], tri), np.take(s["za"], tri)
    return xs0, np.take(zbY, keep), np.take(zs[0], at), np.take(zs[1], at), flat0, cnt, None


def _edge_order(A3, B3, F3):
    """The (3, n) edge arrays with each triangle's edges in the order (one with a > 0, one with a < 0, the third).

    The A of a closed triangle sum to 0 and are not all 0, so both exist (:func:`_rect_bounds`).
    Which edge of each sign comes first follows from the signs of A0 and A1 alone (the first
    edge of that sign; the third edge's A is minus their sum): a code 3 sign(A0) + sign(A1) + 4
    picks the triangle's row order from a table of nine (:data:`_ORDER`), one pass over 2 n
    values and a gather of 3 n instead of np.argmax and np.argmin over the short axis (each a
    strided reduction, together about twice the time). The bounds are maxima of the same values
    in either order, so any edge of the right sign gives the same bounds. One fancy index over
    the three rows: np.take_along_axis costs some 15 µs a call in Python.
    """
    n = A3.shape[1]
    code = np.sign(A3[0]) * 3
    code += np.sign(A3[1])
    flat = np.take(_ORDER * n, code + 4, axis=1)  # (3, n) row offsets
    flat += _ramp(n, 1)
    return tuple(np.take(x, flat) for x in (A3, B3, F3))


def _orders():
    """(3, 9): the edge order (first edge with A > 0, first with A < 0, the third) of each sign code of :func:`_edge_order`."""
    out = np.zeros((3, 9), np.int64)
    for s0 in (-1, 0, 1):
        for s1 in (-1, 0, 1):
            i_pos = 0 if s0 > 0 else 1 if s1 > 0 else 2
            i_neg = 0 if s0 < 0 else 1 if s1 < 0 else 2
            if i_pos == i_neg:  # A0 = A1 = 0: an open triangle, never drawn; any order
                i_neg = 1
            out[:, 3 * s0 + s1 + 4] = (i_pos, i_neg, 3 - i_pos - i_neg)
    return out


_ORDER = _orders()


def _rect_bounds(A3, B3, base3, nc, nr, k, sx, sy, skip=None, presorted=False):
    """First covered column and count of every (row, sample, box) of boxes of at most k rows: (k, S, n) float64.

    Dense and triangle-innermost: the broadcast ufuncs run over contiguous rows
    with no gathers or repeats (k is small, the boxes' rows beyond nr, and the first
    ``skip`` rows where given, are masked: their count is <= 0).
    Float64 is exact here: every L is an integer below 2^53 in magnitude (the caller
    checks), so sums are exact and ceil of the quotient is exact (_EXACT_FLOAT).
    Edges along the rows (a = 0) divide by -2^-40: ceil gives <= 0 for L >= 0 and
    >= 2^40 (an empty row) for L <= -1, so they need no branch.

    For larger layouts the edges of each triangle are taken in the order (one with
    a > 0, one with a < 0, the third): the A of a closed triangle sum to 0 and are not
    all 0, so both exist, and the first two bound only the first resp. the last column
    (no masks). ``presorted``: the caller gave them in that order (:func:`_edge_order`).
    The bounds are maxima of the same values in another order, so they are the same.
    """
    S = sx.shape[0]
    n = nr.size
    ro = (np.arange(k, dtype=np.float64) * _SUB)[:, None, None]
    # Sorting the edges costs about 15 passes over the n triangles, and saves 6 over the
    # k S n rows: only for k S >= 3.
    ordered = k * S >= 3
    if ordered and not presorted:
        A3, B3, base3 = _edge_order(A3, B3, base3)
    d3 = np.where(A3 == 0, -2.0 ** -40, -np.abs(A3 * _SUB).astype(np.float64))

    def bound(e, out):
        # ceil(L / d) of edge e at every (row, sample, triangle), into out.
        Ls = (base3[e] + A3[e] * sx[:, None] + B3[e] * sy[:, None]).astype(np.float64)  # (S, n), exact
        np.add(Ls[None], B3[e].astype(np.float64) * ro, out=out)
        np.divide(out, d3[e], out=out)
        return np.ceil(out, out=out)

    # Minus the last covered column starts at 1 - nc, +inf for rows beyond the box (empty).
    rows = np.arange(k)[:, None]
    masked = rows >= nr if skip is None else (rows >= nr) | (rows < skip)
    nhi0 = np.where(masked, np.inf, 0.0)[:, None, :] + (1.0 - nc)
    if ordered:
        # In place: two fresh (k, S, n) arrays fewer (their first touch costs as much as a pass).
        lo = bound(0, np.empty((k, S, n)))
        np.maximum(lo, 0.0, out=lo)
        nhi = bound(1, np.empty((k, S, n)))
        np.maximum(nhi, nhi0, out=nhi)
    else:
        lo, nhi = np.zeros((k, S, n)), np.broadcast_to(nhi0, (k, S, n)).copy()
    m, t = np.empty((k, S, n)), np.empty((k, S, n))
    for e in (2,) if ordered else (0, 1, 2):
        # An edge of either side: its mask is added as a 0 / -inf penalty (a ufunc's
        # where= costs 11 ns an element, an add 0.4). a >= 0 bounds the first column.
        pos = A3[e] >= 0
        bound(e, m)
        np.maximum(lo, np.add(m, np.where(pos, 0.0, -np.inf), out=t), out=lo)
        np.maximum(nhi, np.add(m, np.where(pos, -np.inf, 0.0), out=t), out=nhi)
    cnt = np.subtract(1.0, nhi, out=nhi)
    cnt -= lo
    return lo, cnt
