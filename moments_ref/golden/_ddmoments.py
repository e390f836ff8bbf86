"""The moments of the engine cases' texels, exactly: double-double sums rounded once (:mod:`moments_ref.golden.engine`).

A texel of an engine case is a distribution (depths ``support``, masses ``mass``); the port receives
its power moments ``Σ m z^k / Σ m`` as an engine would store them, rounded once from the exact value.
Dekker's and Knuth's error-free transformations (two-sum, two-product with Veltkamp's split) carry
the sums in double-double arithmetic (about 2^-100 relative), and :func:`moments_of_rows` rounds
them once to float32 or float64 without double rounding at a tie (tests/test_verdicts.py compares
them with exact rationals).
"""

from __future__ import annotations

import numpy as np

__all__ = ["moments_of_rows", "MOMENT_ROWS", "two_sum", "split", "two_prod", "two_prod_split"]

_SPLIT = 134217729.0  # 2^27 + 1 (Dekker)


def two_sum(a, b):
    s = a + b
    v = s - a
    return s, (a - (s - v)) + (b - v)


def split(a):
    """Dekker's split of ``a`` into ``(hi, lo)``, each of at most 26 significant bits."""
    ah = a * _SPLIT
    ah = ah - (ah - a)
    return ah, a - ah


def two_prod_split(a, a_split, b, b_split):
    """``(a·b, its rounding error)`` (Dekker's two-product) given the factors' :func:`split` (a factor used
    twice is split once)."""
    (ah, al), (bh, bl) = a_split, b_split
    p = a * b
    return p, ((ah * bh - p) + ah * bl + al * bh) + al * bl


def two_prod(a, b):
    return two_prod_split(a, split(a), b, split(b))


def _dd_add(x, y):
    s, e = two_sum(x[0], y[0])
    e = e + x[1] + y[1]
    return two_sum(s, e)


def _dd_mul(x, y):
    p, e = two_prod(x[0], y[0])
    e = e + (x[0] * y[1] + x[1] * y[0])
    return two_sum(p, e)


def _dd_round(hi, lo, dtype):
    """A normalized double-double rounded once to ``dtype`` (float32: no double rounding at ties)."""
    if np.dtype(dtype) == np.float64:
        return hi + lo
    x = hi.astype(np.float32)
    r = (hi - x.astype(np.float64)) + lo  # what x misses, about exactly
    up = np.nextafter(x, np.float32(np.inf)).astype(np.float64) - x
    down = x - np.nextafter(x, np.float32(-np.inf)).astype(np.float64)
    x = np.where(r > up / 2, np.nextafter(x, np.float32(np.inf)), x)
    return np.where(r < -down / 2, np.nextafter(x, np.float32(-np.inf)), x)


def moments_of_rows(support, mass, dtype, bias=None):
    """``(n, 4)``: each row's distribution's moments ``Σ m z^k / Σ m`` (``support``, ``mass``: ``(n, K)``, points of
    mass 0 for padding), biased (``bias``: a BiasPreset applied as ``b − α (b − b*)``), in double-double
    arithmetic (about 2^-100 relative) and rounded once to ``dtype``."""
    z, w = np.asarray(support, np.float64), np.asarray(mass, np.float64)
    if len(z) <= MOMENT_ROWS:
        return _moments_block(z, w, dtype, bias)
    # Row by row, so in blocks whose ~40 temporaries stay in cache (131072 rows: 0.133 -> 0.093 s at 8192)
    return np.concatenate([_moments_block(z[i:i + MOMENT_ROWS], w[i:i + MOMENT_ROWS], dtype, bias)
                           for i in range(0, len(z), MOMENT_ROWS)])


#: Rows per block of :func:`moments_of_rows`.
MOMENT_ROWS = 8192


def _moments_block(z, w, dtype, bias):
    """:func:`moments_of_rows` of ``(n, K)`` float64 ``z``, ``w``."""
    n, k = z.shape
    zero = np.zeros(n)
    tot, acc = (zero, zero), [(zero, zero)] * 4
    for j in range(k):  # compensated sums over each row's points, vectorized over rows
        # _dd_mul(wj, p) and _dd_mul(p, u) with u = (z_j, 0), wj = (w_j, 0), each factor split once (the same bits)
        u, wj = z[:, j], w[:, j]
        us, ws = split(u), split(wj)
        p = (u, zero)
        tot = _dd_add(tot, (wj, zero))
        for m in range(4):
            ps = split(p[0])
            q, e = two_prod_split(wj, ws, p[0], ps)
            acc[m] = _dd_add(acc[m], two_sum(q, e + (wj * p[1] + zero * p[0])))
            q, e = two_prod_split(p[0], ps, u, us)
            p = two_sum(q, e + (p[0] * zero + p[1] * u))
    out = np.empty((n, 4), dtype=dtype)
    for m in range(4):
        q0 = acc[m][0] / tot[0]  # b = acc / tot with one correction step
        r = _dd_add(acc[m], _dd_mul((-q0, zero), tot))
        b = two_sum(q0, (r[0] + r[1]) / tot[0])
        if bias is not None:
            d = _dd_add(b, (np.full(n, -bias.target[m]), zero))
            b = _dd_add(b, _dd_mul((np.full(n, -bias.alpha), zero), d))
        out[:, m] = _dd_round(b[0], b[1], dtype)
    return out
