"""Triangle setup: validation, trivial rejection, clipping, snapping, culling, edge equations.

Part of :mod:`moments_ref.scene.raster` (see its docstring for the conventions).
"""

from __future__ import annotations

import numpy as np

from ..._arrays import InputError, first_index, real_input
from ..depth import x_window_from_ndc, y_window_from_ndc
from ._coverage import _boxes
from ._matrices import _SUB, _clip_space

# Window coordinates stay within ±2^20 pixels (guard band): with 8 sub-pixel bits
# edge-function products stay below 2^60 in int64.
_GUARD_PIXELS = 1 << 20

# ---------------------------------------------------------------------------
# Triangle setup


def _check_mesh(vertices, triangles):
    v = real_input(vertices, "vertices", trailing=3, dtype=np.float64, finite=False)
    if v.ndim != 2:
        raise InputError(f"vertices: expected a (V, 3) array, got shape {v.shape}")
    t = np.asarray(triangles)
    if t.size == 0:
        t = t.reshape(0, 3)
    if t.dtype.kind not in "iu":
        raise InputError(f"triangles: expected an integer (T, 3) index array, got dtype {t.dtype}")
    if t.ndim != 2 or t.shape[1] != 3:
        raise InputError(f"triangles: expected a (T, 3) index array, got shape {t.shape}")
    bad = (t < 0) | (t >= v.shape[0])
    if bad.any():
        idx = first_index(bad)
        raise InputError(
            f"triangles: expected indices in [0, {v.shape[0]}) (V = {v.shape[0]} vertices), "
            f"got {int(t[idx])} at index {idx}"
        )
    return v, t.astype(np.int64, copy=False)


def _clip_plane(attr, tid, dist):
    """Clip triangles against one plane (keep ``dist >= 0``), Sutherland–Hodgman.

    attr : (n, 3, k) per-vertex attributes, linear in clip space (clip xyzw, world xyz).
    Returns the new (m, 3, k) attributes and (m,) triangle ids; winding is kept.
    """
    inside = dist >= 0
    cnt = inside.sum(axis=1)
    keep = cnt == 3
    out_attr, out_tid = [attr[keep]], [tid[keep]]

    def rotated(sel, first):
        # Rotate the vertex order so that vertex `first` comes first (keeps winding).
        order = (first[:, None] + np.arange(3)) % 3
        a = np.take_along_axis(attr[sel], order[:, :, None], axis=1)
        d = np.take_along_axis(dist[sel], order, axis=1)
        return a, d

    def cut(a, d, i, j):
        # Intersection of edge (i, j) with the plane; d[i] and d[j] have opposite signs.
        t = d[:, i] / (d[:, i] - d[:, j])
        return a[:, i] + t[:, None] * (a[:, j] - a[:, i])

    one = cnt == 1
    if one.any():  # A inside, B and C outside: triangle (A, AB, AC)
        a, d = rotated(one, np.argmax(inside[one], axis=1))
        out_attr.append(np.stack([a[:, 0], cut(a, d, 0, 1), cut(a, d, 0, 2)], axis=1))
        out_tid.append(tid[one])
    two = cnt == 2
    if two.any():  # A outside, B and C inside: quad (AB, B, C, CA) -> two triangles
        a, d = rotated(two, np.argmin(inside[two], axis=1))
        ab, ca = cut(a, d, 0, 1), cut(a, d, 2, 0)
        out_attr.append(np.stack([ab, a[:, 1], a[:, 2]], axis=1))
        out_attr.append(np.stack([ab, a[:, 2], ca], axis=1))
        out_tid += [tid[two], tid[two]]
    return np.concatenate(out_attr), np.concatenate(out_tid)


def _all3(a):
    return a[0] & a[1] & a[2]


def _any3(a):
    return a[0] | a[1] | a[2]


def _count_ids(ids, lo, n) -> int:
    """Number of distinct triangle ids in ``ids`` (all within [lo, lo + n))."""
    if ids.size == 0:
        return 0
    if (ids[1:] > ids[:-1]).all():  # no triangle split by clipping: all distinct (one compare pass)
        return int(ids.size)
    mark = np.zeros(n, dtype=bool)
    mark[ids - lo] = True
    return int(np.count_nonzero(mark))


def _setup(verts, tri, lo, h, w, sx, sy, cull, stats, want_world, checked=False):
    """Clip, snap and set up edge equations for one chunk of triangles.

    ``verts`` from :func:`_vertices`. Arrays are component-major ("structure of
    arrays"); per-triangle results are (3, n) (one row per
    vertex or edge) or (n,). ``tri`` (n, 3) holds the chunk's indices, whose
    triangle ids start at ``lo``. Returns None when nothing is left to rasterize.
    Triangles whose pixel box holds no sample (sx, sy: the sample offsets) are
    dropped before their edge equations; ``s["box"]`` holds the boxes of the rest
    (:func:`moments_ref.scene.raster._coverage._boxes`).

    Four steps, one function each (a call per chunk of ``_SETUP_CHUNK`` triangles;
    ``moments-ref bench`` rasterize_depth 1× MSAA, 262144 small triangles into 1024²,
    CPU time, best of 9 in 3 interleaved runs: 310.5 ms as one function, 291.8 ms
    split, i.e. no slowdown within the noise):
    :func:`_reject`, :func:`_clip`, :func:`_snap_and_cull`, :func:`_edge_equations`.
    """
    n = tri.shape[0]
    attr, tid = _reject(verts, tri, lo, stats, want_world, checked)
    attr, tid = _clip(attr, tid, h, w, lo, n, stats)
    if tid.size == 0:
        return None
    X, Y, zv, area2, keep = _snap_and_cull(attr, tid, h, w, cull, lo, n, stats)
    box = _boxes(X, Y, h, w, sx, sy)
    keep &= (box[0] <= box[1]) & (box[2] <= box[3])
    # The attributes are only needed again for world positions (want_world). (Dividing the
    # depths only for the kept triangles, about 2/3 of a knot view's, costs more: the
    # compress of z and w instead of the quotient's.)
    snapped = (X, Y, zv, area2, tid, attr if want_world else None)
    if not keep.all():
        if not keep.any():
            return None
        # np.compress is twice as quick as a boolean index on the last axis.
        snapped = tuple(None if a is None else np.compress(keep, a, axis=-1) for a in snapped)
        box = tuple(np.compress(keep, a) for a in box)
    s = _edge_equations(*snapped, want_world)
    s["box"] = box
    return s


def valid_triangles(v, t, stats):
    """The triangles of the mesh (v, t) whose vertices are finite and not collinear, the others counted in ``stats``.

    The view-independent part of :func:`_reject`, done once for a mesh drawn from many views
    (chunk by chunk, no array of the mesh's size beyond the result).
    """
    vT = np.ascontiguousarray(v.T)
    keep = [np.ones(0, bool)]
    for lo in range(0, t.shape[0], 1 << 15):
        valid = _world_valid(_world_vertices(v, vT, np.ascontiguousarray(t[lo:lo + (1 << 15)].T)), stats)
        keep.append(np.ones(min(1 << 15, t.shape[0] - lo), bool) if valid is None else valid)
    keep = np.concatenate(keep)
    return t if keep.all() else t[keep]


def _vertices(v, m, n_triangles):
    """``(v, m, vT, cvT)`` for :func:`_setup`: world and clip-space vertices, component-major (3, V) and (4, V),
    when the mesh shares its vertices (fewer than 1.5 per triangle: transform each once and
    gather), else None for both (the triangles' vertices are gathered and transformed chunk
    by chunk, so no array of the size of the mesh is allocated). Same values either way."""
    if 2 * v.shape[0] > 3 * n_triangles:
        return v, m, None, None
    vT = np.ascontiguousarray(v.T)
    return v, m, vT, _clip_space(vT, m)


def _world_vertices(v, vT, triT):
    """The world vertices of the triangles ``triT`` (3, n), as (3 coords, 3 vertices, n).

    np.take is 2.7 times quicker than the equal fancy index vT[:, triT] (NumPy 2.4); without
    vT, whole rows of v are gathered and the chunk transposed once (in cache).
    """
    n = triT.shape[1]
    return np.take(vT, triT, axis=1) if vT is not None else np.take(v, triT.ravel(), axis=0).T.reshape(3, 3, n)


def _world_valid(p, stats):
    """Which triangles of world vertices ``p`` (3, 3, n) have finite vertices and a nonzero area; the others counted.

    Returns None when all do. Non-finite triangles count in ``stats.nonfinite``; of the
    others, those with exactly collinear or repeated vertices in ``stats.degenerate``.
    """
    n = p.shape[2]
    fin = np.isfinite(p).reshape(9, n)
    ok = None if fin.all() else fin.all(axis=0)
    if ok is not None:
        stats.nonfinite += int(ok.size - np.count_nonzero(ok))
    # Zero area in world space: exactly collinear or repeated vertices (a non-finite triangle
    # gives False or NaN comparisons here; it is already counted and dropped).
    with np.errstate(invalid="ignore", over="ignore"):
        e1, e2 = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
        nondeg = ((e1[1] * e2[2] != e1[2] * e2[1]) | (e1[2] * e2[0] != e1[0] * e2[2])
                  | (e1[0] * e2[1] != e1[1] * e2[0]))
    if ok is not None:
        nondeg &= ok
    stats.degenerate += int(nondeg.size - np.count_nonzero(nondeg)) - (0 if ok is None else int(n - np.count_nonzero(ok)))
    return None if nondeg.all() else nondeg


def _reject(verts, tri, lo, stats, want_world, checked=False):
    """Drop non-finite, degenerate and trivially outside triangles; (attributes (k, 3, n), ids).

    ``checked``: the triangles are known to pass :func:`_world_valid` (:func:`valid_triangles`
    dropped the others once for many views), so a depth pass skips their world vertices.
    """
    v, m, vT, cvT = verts
    n = tri.shape[0]
    tid = np.arange(lo, lo + n)
    triT = np.ascontiguousarray(tri.T)  # a contiguous index makes np.take below quicker
    p = None
    if not (checked and want_world is False and cvT is not None):
        p = _world_vertices(v, vT, triT)
        valid = None if checked else _world_valid(p, stats)
        if valid is not None:
            triT, tid, p = np.compress(valid, triT, axis=1), tid[valid], np.compress(valid, p, axis=2)
    # (4, 3, n) clip-space vertices (the same operations whether transformed here or gathered).
    c = np.take(cvT, triT, axis=1) if cvT is not None else _clip_space(p, m)
    x, y, z, cw = c
    # Trivial reject: all three vertices outside the same plane of the view volume.
    ncw = -cw
    out = (_all3(x > cw) | _all3(x < ncw) | _all3(y > cw) | _all3(y < ncw)
           | _all3(z > cw) | _all3(z < ncw) | _all3(cw <= 0))
    stats.outside += int(np.count_nonzero(out))
    attr = np.concatenate([c, p]) if want_world else c  # (k, 3, n), linear in clip space
    if out.any():
        attr, tid = np.compress(~out, attr, axis=2), tid[~out]
    return attr, tid


def _clip(attr, tid, h, w, lo, n, stats):
    """Near plane z_clip >= -w_clip, then the guard band |x|, |y| <= G w (only where needed)."""
    g = 2.0 * _GUARD_PIXELS / max(h, w) - 1.0
    planes = [(0, 0, 1, 1)]
    gw_ = g * attr[3]
    if (np.abs(attr[0]) > gw_).any() or (np.abs(attr[1]) > gw_).any():
        planes += [(-1, 0, 0, g), (1, 0, 0, g), (0, -1, 0, g), (0, 1, 0, g)]
    for pl in planes:
        if pl == (0, 0, 1, 1):  # (z + w) + 0: the value of the sum below, signed zeros too, in two passes
            dist = np.add(attr[2], attr[3])
            dist += 0.0
        else:
            dist = sum(k * attr[j] for j, k in enumerate(pl) if k != 0)
        need = _any3(dist < 0)
        if need.any():
            ca, ct = _clip_plane(attr[:, :, need].transpose(2, 1, 0), tid[need], dist[:, need].T)
            attr = np.concatenate([attr[:, :, ~need], ca.transpose(2, 1, 0)], axis=2)
            tid = np.concatenate([tid[~need], ct])
    pos_w = _all3(attr[3] > 0)  # a non-standard matrix may leave w <= 0
    if not pos_w.all():
        stats.outside += _count_ids(tid[~pos_w], lo, n)
        attr, tid = np.compress(pos_w, attr, axis=2), tid[pos_w]
    return attr, tid


def _snap_and_cull(attr, tid, h, w, cull, lo, n, stats):
    """Perspective division, viewport transform, snapping to 1/256 pixel, culling.

    Returns X, Y, zv, area2 of every triangle and which to keep (nonzero snapped
    area, not culled); the caller drops the others together with those whose box
    is empty (one np.compress per array).
    """
    cw = attr[3]
    # window coordinates in 1/_SUB pixels: those of a map _SUB times the size (exact: _SUB = 2^8)
    # (In place in one buffer: the same operations as x_window_from_ndc(attr[0] / cw, ...).)
    t = np.divide(attr[0], cw)
    X = np.rint(x_window_from_ndc(t, w * _SUB, out=t), out=t).astype(np.int64)  # (3, n)
    np.divide(attr[1], cw, out=t)
    Y = np.rint(y_window_from_ndc(t, h * _SUB, out=t), out=t).astype(np.int64)
    zv = attr[2] / cw

    area2 = (X[1] - X[0]) * (Y[2] - Y[0]) - (Y[1] - Y[0]) * (X[2] - X[0])
    zero = area2 == 0
    # Counter-clockwise in NDC (y up) is clockwise in window space (y down): area2 < 0.
    if cull == "back":
        culled = area2 > 0
    elif cull == "front":
        culled = area2 < 0
    else:
        culled = np.zeros_like(zero)
    stats.zero_area += _count_ids(tid[zero], lo, n)
    stats.culled += _count_ids(tid[culled], lo, n)
    keep = ~(zero | culled)
    stats.rasterized += _count_ids(tid if keep.all() else tid[keep], lo, n)
    return X, Y, zv, area2, keep


def _edge_equations(X, Y, zv, area2, tid, attr, want_world):
    """Edge functions with the top-left rule and the depth plane of each (oriented) triangle."""
    # Orient every triangle so that area2 > 0 (swap v1 and v2); edge functions are then
    # positive inside.
    flip = area2 < 0
    if flip.any():
        # Swap vertices 1 and 2 in place in the flipped columns, as bits: d = (v1 ^ v2) where
        # flipped, else 0, then v1 ^= d, v2 ^= d (four passes over n, no fancy index: a third
        # of the time of gathering and scattering the flipped columns; the same values).
        for a in (X, Y, zv):
            b = a.view(f"u{a.itemsize}")  # the bits, whatever the dtype
            d = np.bitwise_xor(b[1], b[2])
            np.multiply(d, flip, out=d)
            b[1] ^= d
            b[2] ^= d
        area2 = np.abs(area2)
        if want_world:
            attr = np.where(flip, attr[:, [0, 2, 1]], attr)

    # Edge e runs from vertex e to vertex e+1: E(p) = dx (py - ay) - dy (px - ax)
    # = A px + B py + C with A = -dy, B = dx. Top-left rule: a top edge has dy == 0 and
    # dx > 0, a left edge dy < 0; F = E + tl - 1 >= 0 is "E > 0, or E == 0 on a top-left
    # edge". (Integers: every order of the sums is exact.)
    A, B = _edge_deltas(Y, X)  # A = -dy = Y_e - Y_e+1, B = dx = X_e+1 - X_e
    B = np.negative(B, out=B)
    tl = (A > 0) | ((A == 0) & (B > 0))
    C = A * X
    C += B * Y
    np.negative(C, out=C)  # C = dy X - dx Y
    F0 = C + tl
    F0 -= 1

    # Depth plane through the snapped vertices, relative to vertex 0:
    # z = z0 + λ1 (z1 - z0) + λ2 (z2 - z0), λ1 = E_20 / area2, λ2 = E_01 / area2.
    fa = area2.astype(np.float64)
    dz1, dz2 = zv[1] - zv[0], zv[2] - zv[0]
    pa, pb = (A[2] * dz1, A[0] * dz2), (B[2] * dz1, B[0] * dz2)
    za = (pa[0] + pa[1]) / fa
    zb = (pb[0] + pb[1]) / fa

    s = {"tid": tid, "X": X, "Y": Y, "A": A, "B": B, "F0": F0, "z0": zv[0], "za": za, "zb": zb,
         "inside": _depth_inside(zv, za, zb, B, A, pa, pb, fa)}
    if want_world:
        s["C"] = C
        s["area2"] = fa
        s["q"] = 1.0 / attr[3]  # 1/w for perspective-correct interpolation
        s["world"] = attr[4:7]  # (3 coords, 3 vertices, n)
    return s


def _edge_deltas(U, V):
    """(U_e - U_e+1, V_e - V_e+1) of the three edges e (vertex e to e+1) of (3, n) U and V, from row slices."""
    out = []
    for a in (U, V):
        d = np.empty_like(a)
        np.subtract(a[:2], a[1:], out=d[:2])
        np.subtract(a[2], a[0], out=d[2])
        out.append(d)
    return out


def _depth_inside(zv, za, zb, dx, dy_neg, pa, pb, fa):
    """Per triangle: is the computed depth of every sample it covers provably in [-1, 1] (no clip test)?

    A covered sample lies in the closed snapped triangle, so the exact plane through its
    vertices gives a depth within the vertices' range [min zv, max zv], and its offsets
    from vertex 0 are at most those of the other vertices (``dx``, ``dy`` of the edges
    from and to vertex 0; ``dy_neg`` = -dy) plus half a pixel. The computed depth
    ``(z0 + za X) + zb Y`` differs from the exact one by the rounding of za and zb (a few
    ulps of the magnitudes of their terms ``pa``, ``pb``, the products summed into
    ``za fa`` and ``zb fa``) and of the three operations (a few ulps of
    ``|za X| + |z0| + |zb Y|``); the bound allows 2^-40, over a thousand times more. A
    triangle not proven inside has its rows checked exactly (:func:`._spans._iter_spans`);
    the flag only skips checks that would pass.
    """
    ma = np.abs(za) + (np.abs(pa[0]) + np.abs(pa[1])) / fa
    mb = np.abs(zb) + (np.abs(pb[0]) + np.abs(pb[1])) / fa
    xm = np.maximum(np.abs(dx[0]), np.abs(dx[2])) + _SUB
    ym = np.maximum(np.abs(dy_neg[0]), np.abs(dy_neg[2])) + _SUB
    err = (ma * xm + mb * ym + np.abs(zv[0]) + 1.0) * 2.0 ** -40
    zmin, zmax = np.minimum(np.minimum(zv[0], zv[1]), zv[2]), np.maximum(np.maximum(zv[0], zv[1]), zv[2])
    return (zmin - err >= -1.0) & (zmax + err <= 1.0)
