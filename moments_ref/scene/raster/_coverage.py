"""Coverage: the pixel box of each set-up triangle, which the span rasterizer (:mod:`._spans`) fills.

Part of :mod:`moments_ref.scene.raster` (see its docstring for the conventions).
"""

from __future__ import annotations

import numpy as np

from ._matrices import _HALF, SUBPIXEL_BITS
from ._spans import _FLOAT_SAFE_COORD


def _boxes(X, Y, h, w, sx, sy):
    """Pixel bounding boxes (c0, c1, r0, r1) of triangles with snapped vertices X, Y (3, n), clamped to the map
    (empty where c0 > c1 or r0 > r1), and which triangles the exact float64 span path can take
    (see :data:`_FLOAT_SAFE_COORD`)."""
    # The three rows' minima and maxima elementwise (a reduction over the short first axis is
    # a strided one, about three times the time).
    xmin, xmax = np.minimum(np.minimum(X[0], X[1]), X[2]), np.maximum(np.maximum(X[0], X[1]), X[2])
    ymin, ymax = np.minimum(np.minimum(Y[0], Y[1]), Y[2]), np.maximum(np.maximum(Y[0], Y[1]), Y[2])
    # Pixel col has a sample at col*256 + 128 + sx; it may be covered only if some
    # sample lies within [min X, max X] of the vertices.
    # Floor division by _SUB = 2^8 as an arithmetic shift (exact for negative values
    # too; NumPy's int64 floor division costs 8 ns an element, a shift 0.4 ns).
    # Ceiling division as (a + 2^8 - 1) >> 8, the constants folded into one addition (exact integers).
    up = (1 << SUBPIXEL_BITS) - 1
    c0 = (xmin + int(up - _HALF - sx.max())) >> SUBPIXEL_BITS
    c1 = (xmax - int(_HALF + sx.min())) >> SUBPIXEL_BITS
    r0 = (ymin + int(up - _HALF - sy.max())) >> SUBPIXEL_BITS
    r1 = (ymax - int(_HALF + sy.min())) >> SUBPIXEL_BITS
    np.maximum(c0, 0, out=c0)
    np.minimum(c1, w - 1, out=c1)
    np.maximum(r0, 0, out=r0)
    np.minimum(r1, h - 1, out=r1)
    lim = _FLOAT_SAFE_COORD
    safe = (xmin > -lim) & (xmax < lim) & (ymin > -lim) & (ymax < lim)
    return c0, c1, r0, r1, safe
