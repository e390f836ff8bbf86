"""The six-moment bounds kernel's steps on reused rows: :mod:`moments_ref.msm6`, one chunk at a time.

Steps 1–4 of :mod:`moments_ref.msm6` (Cholesky ``B(b) = L D Lᵀ``, the solve of
``B q = v(zf)`` with the Sturm signs, the one root of the reversed cubic the bound needs
by Blinn's closed form, its weight ``1 / Σ u_i²/D_i``) written as ufunc calls into a
per-thread workspace (``out=``): the same arithmetic in the same order as the expressions
of :func:`moments_ref.msm6._ldl`, :func:`moments_ref.msm6._reversed_cubic`,
:func:`moments_ref.msm6._extreme_root` and :func:`moments_ref.msm6._weights`, so the
results are theirs bit for bit (tests/test_msm6.py). A chunk allocates nothing.
"""

from __future__ import annotations

import threading
from operator import itemgetter

import numpy as np

from ._kernels import MSM6_CHUNK, MSM_CHUNK, singular_thresholds

__all__ = ["BOUNDS_CHUNK", "BOUNDS_CHUNK64", "bounds_chunk", "COS_THIRD_POLY", "ROWS", "workspace", "ldl_rows",
           "regular_chunk", "regular_mask", "solve_rows", "blinn_rows", "root_rows", "weight_rows"]

#: ``cos(⅔·arccos u)`` for u ∈ [0, 1] as a polynomial in u, ascending powers: least squares on
#: 4001 Chebyshev points of [0, 1], largest error 1.6e-7 (2.2e-7 evaluated in float32).
COS_THIRD_POLY = (0.5000001629519066, 0.5773334661660559, -0.11082308230793778, 0.051548030727594105,
                  -0.02653837949755497, 0.010623147312699203, -0.0021434685253637615)

#: Texels per chunk of the float32 bounds (the fast path of :mod:`moments_ref._msm6_bound`):
#: ``_kernels.MSM6_CHUNK`` (measured there).
BOUNDS_CHUNK = MSM6_CHUNK

#: Texels per chunk of the float64 bounds (the Christoffel kernel throughout): Algorithm 1's 2^15
#: (round nine: 2^16 took 1.155 (1.108–1.174) of its time, 15 pairs, load 3–4).
BOUNDS_CHUNK64 = MSM_CHUNK

#: Float rows of the bounds kernel's workspace (:func:`_workspace`), named by what they first hold.
ROWS = ("d1", "d2", "d3", "l21", "l31", "l32", "a", "b", "t", "y1", "y2", "y3", "c1", "c2", "c3", "e", "f", "g")

#: The rows :func:`ldl_rows` writes (an itemgetter: one call instead of a generator per chunk).
_LDL_ROWS = itemgetter("d1", "d2", "d3", "l21", "l31", "l32", "a", "b", "t")

#: Per thread, the bounds kernel's workspace of a whole chunk per dtype (:func:`_workspace`).
_LOCAL = threading.local()


def bounds_chunk(dtype):
    """Texels per chunk of the bounds in ``dtype``: :data:`BOUNDS_CHUNK` for float32, else :data:`BOUNDS_CHUNK64`."""
    return BOUNDS_CHUNK if np.dtype(dtype).type is np.float32 else BOUNDS_CHUNK64


def workspace(dtype, n):
    """The kernel's rows for ``n ≤ bounds_chunk(dtype)`` texels: one set per thread and dtype, kept between calls.

    Float rows (:data:`ROWS`), three boolean rows, an integer row for sign bits, the
    constant rows 0 and 1 (``np.maximum``, ``np.minimum`` and ``np.fmax`` are fast only
    array–array) and the sign bit as a 0-d integer (an array–0-d bitwise loop is faster
    than array–array), and each float row's integer view (``"i" + name``). Every step
    writes into them (``out``): a chunk allocates nothing and its rows stay in cache;
    kept between calls because fresh chunk-sized arrays are faulted in from the OS on
    every call (as :mod:`moments_ref.msm` measured). 5.7 MB in float32 (2^16 texels), 5.6 MB
    in float64 (2^15) per thread that called; per thread, so that concurrent calls never share one. The
    views of a full chunk and of the last shorter one are kept too (a chunk builds no views).
    """
    cache = _LOCAL.__dict__.setdefault("ws", {})
    m = bounds_chunk(dtype)
    key = (np.dtype(dtype), m)  # the dtype itself: its .name is a Python property (about 1 µs)
    views = cache.get(key)
    if views is None:
        if len(cache) >= 4:  # float32 and float64 (the chunk size only guards a changed CHUNK)
            cache.clear()
        it = np.int32 if np.dtype(dtype) == np.float32 else np.int64
        base = {"block": np.empty((len(ROWS), m), dtype=dtype), "mask": np.empty((3, m), dtype=bool),
                "bits": np.empty(m, dtype=it), "zero": np.zeros(m, dtype=dtype), "one": np.ones(m, dtype=dtype)}
        views = cache[key] = {m: _views(base, np.array(np.iinfo(it).min, dtype=it), m)}
    ws = views.get(n)
    if ws is None:
        full = views[m]
        for k in [k for k in views if k != m]:  # keep one shorter chunk's views
            del views[k]
        ws = views[n] = _views({k: full[k] for k in ("block", "mask", "bits", "zero", "one")}, full["sign"], n)
    return ws


def _views(base, sign, n):
    """The workspace of :func:`workspace` on the first ``n`` texels of the full rows ``base``."""
    ws = {k: v[..., :n] for k, v in base.items()}  # "block": the float rows as one (len(ROWS), n) array
    ws["sign"] = sign
    ws.update(zip(ROWS, ws["block"]))
    ws.update(("i" + k, r.view(ws["bits"].dtype)) for k, r in zip(ROWS, ws["block"]))
    return ws


def ldl_rows(b, w):
    """Step 1 into the workspace ``w``: :func:`moments_ref.msm6._ldl`, operation for operation (23 passes)."""
    b1, b2, b3, b4, b5, b6 = b
    d1, d2, d3, l21, l31, l32, a, c, t = _LDL_ROWS(w)
    np.multiply(b1, b1, d1)  # D1 = b2 − b1²
    np.subtract(b2, d1, d1)
    np.multiply(b1, b2, a)  # L21 D1 = b3 − b1 b2
    np.subtract(b3, a, a)
    np.multiply(b1, b3, c)  # L31 D1 = b4 − b1 b3
    np.subtract(b4, c, c)
    np.divide(a, d1, l21)
    np.divide(c, d1, l31)
    np.multiply(b2, b2, d2)  # D2 = b4 − b2² − L21·(L21 D1)
    np.subtract(b4, d2, d2)
    np.multiply(l21, a, t)
    np.subtract(d2, t, d2)
    np.multiply(b2, b3, a)  # L32 D2 = b5 − b2 b3 − L21·(L31 D1)
    np.subtract(b5, a, a)
    np.multiply(l21, c, t)
    np.subtract(a, t, a)
    np.divide(a, d2, l32)
    np.multiply(b3, b3, d3)  # D3 = b6 − b3² − L31·(L31 D1) − L32·(L32 D2)
    np.subtract(b6, d3, d3)
    np.multiply(l31, c, t)
    np.subtract(d3, t, d3)
    np.multiply(l32, a, t)
    np.subtract(d3, t, d3)
    return d1, d2, d3, l21, l31, l32


def regular_chunk(b, zf, ldl, w):
    """True when every texel of the chunk is regular and finite, decided by reductions (no pass).

    :func:`moments_ref.msm6._regular` holds for every texel when the extremes clear it: float32
    ``min D_i > 0``, float64 ``min D1 > τ max b2``, ``min D2 > τ max(max b4, max D1)``,
    ``min D3 > τ max(max b6, max D2)`` (a NaN fails every comparison). ``max D3 < ∞``
    catches b6 = +∞ and a finite sum of zf a NaN or ∞ in zf (the one thing the pivots do
    not see); a sum overflowing on finite zf only costs the exact check.
    """
    d1, d2, d3 = ldl[:3]
    mn, mx = np.minimum.reduce, np.maximum.reduce
    rtol = b.dtype.type(singular_thresholds(b.dtype))
    if rtol == 0:
        ok = mn(d1) > 0 and mn(d2) > 0 and mn(d3) > 0
    else:
        ok = (mn(d1) > rtol * mx(b[1]) and mn(d2) > rtol * max(mx(b[3]), mx(d1))
              and mn(d3) > rtol * max(mx(b[5]), mx(d2)))
    return bool(ok and mx(d3) < np.inf and np.isfinite(np.add.reduce(zf)))


def regular_mask(b, ldl):
    """True where B(b) is regular: every pivot above its threshold (:mod:`moments_ref.msm6`, "Degenerate input").

    float32: the pivots' signs only (a NaN pivot, after a zero one, is singular); float64
    ``D1 > τ b2``, ``D2 > τ max(b4, D1)``, ``D3 > τ max(b6, D2)``.
    """
    D1, D2, D3 = ldl[:3]
    rtol = b.dtype.type(singular_thresholds(b.dtype))
    if rtol == 0:
        return np.minimum(np.minimum(D1, D2), D3) > 0
    _, b2, _, b4, _, b6 = b
    return (D1 > rtol * b2) & (D2 > rtol * np.maximum(b4, D1)) & (D3 > rtol * np.maximum(b6, D2))


def solve_rows(b, zf, ldl, w):
    """Steps 2–3 into the workspace: the Sturm signs and ``(p(zf), p'(zf), p''(zf)/2, q3, w0)``.

    :func:`moments_ref.msm6._reversed_cubic`'s arithmetic operation for operation (32 passes, and 6 boolean
    ones for the signs): forward substitution ``L y = v(zf)``, scaling ``c = D⁻¹ y``, back
    substitution (q2, q1; q3 = c3), ``p(zf) = 1 + Σ y_i c_i`` and the Taylor coefficients
    at zf. The boolean rows ``mask[0]``, ``mask[2]`` get "at least two Gauss nodes below
    zf" and "an odd number below" (:func:`moments_ref.msm6.shadow_intensity`, step 5).
    """
    b1, b2, b3 = b[:3]
    d1, d2, d3, l21, l31, l32 = ldl
    zf2, p1, t, y1, y2, y3, c1, c2, c3, q2, q1, pz = (w[k] for k in ("a", "b", "t", "y1", "y2", "y3",
                                                                     "c1", "c2", "c3", "e", "f", "g"))
    # Forward substitution to solve L y = (1, zf, zf², zf³).
    np.multiply(zf, zf, out=zf2)
    np.subtract(zf, b1, out=y1)
    np.subtract(zf2, b2, out=y2)
    np.multiply(l21, y1, out=t)
    np.subtract(y2, t, out=y2)
    np.multiply(zf2, zf, out=y3)
    np.subtract(y3, b3, out=y3)
    np.multiply(l31, y1, out=t)
    np.subtract(y3, t, out=y3)
    np.multiply(l32, y2, out=t)
    np.subtract(y3, t, out=y3)
    # The Sturm sequence (1, y1, y2, y3): two nodes below is "the signs never turn back from − to +".
    pos1, pos2, pos3 = w["mask"]
    np.greater_equal(y1, w["zero"], out=pos1)
    np.greater_equal(y2, w["zero"], out=pos2)
    np.greater_equal(y3, w["zero"], out=pos3)
    np.less_equal(pos2, pos1, out=pos1)
    np.less_equal(pos3, pos2, out=pos2)
    np.logical_and(pos1, pos2, out=pos1)
    # Scaling to solve D c = y; back substitution Lᵀ q = c (q3 = c3).
    np.divide(y1, d1, out=c1)
    np.divide(y2, d2, out=c2)
    np.divide(y3, d3, out=c3)
    np.multiply(l32, c3, out=t)
    np.subtract(c2, t, out=q2)
    np.multiply(l21, q2, out=t)
    np.subtract(c1, t, out=q1)
    np.multiply(l31, c3, out=t)
    np.subtract(q1, t, out=q1)
    # p(zf) = 1 + Σ y_i c_i (= 1/w0, a sum of squares over pivots).
    np.multiply(y1, c1, out=pz)
    np.add(pz, 1, out=pz)
    np.multiply(y2, c2, out=t)
    np.add(pz, t, out=pz)
    np.multiply(y3, c3, out=t)
    np.add(pz, t, out=pz)
    # p''(zf)/2 = q2 + 3 q3 zf (into zf²'s row), p'(zf) = q1 + (q2 + p''/2) zf.
    p2 = zf2
    np.multiply(c3, 3, out=t)
    np.multiply(t, zf, out=t)
    np.add(q2, t, out=p2)
    np.add(q2, p2, out=t)
    np.multiply(t, zf, out=t)
    np.add(q1, t, out=p1)
    w0 = y1
    np.divide(1, pz, out=w0)
    return pz, p1, p2, c3, w0


def blinn_rows(cubic, w):
    """Blinn's form of P(t) (msm6._blinn) with the sign σ applied: rows ``(σr, B, C, D, |Δ0|, σ·2m, ·)``.

    ``B = c1/(3c0)``, ``C = c2/(3c0)``, ``D = c3/c0``, ``Δ0 = C − B²``, ``2m = √(4|Δ0|)``,
    ``r = (B (C + 2Δ0) − D)/(2m |Δ0|)``; σ = −1 where an odd number of Gauss nodes lies
    below zf (``mask[2]``), applied as a flip of the sign bit (exactly the product by ±1).
    18 passes; the last row returned is free.
    """
    c0, c1, c2, c3 = cubic
    t, bb, cc, dd, d0, dep, m2 = (w[k] for k in ("t", "e", "f", "y2", "y3", "c1", "c2"))
    np.multiply(c0, 3, out=t)
    np.divide(c1, t, out=bb)
    np.divide(c2, t, out=cc)
    np.divide(c3, c0, out=dd)
    np.multiply(bb, bb, out=d0)
    np.subtract(cc, d0, out=d0)
    np.multiply(d0, 2, out=dep)  # −(Δ1 − 2BΔ0) = B (C + 2Δ0) − D
    np.add(cc, dep, out=dep)
    np.multiply(bb, dep, out=dep)
    np.subtract(dep, dd, out=dep)
    np.abs(d0, out=d0)
    np.multiply(d0, 4, out=m2)
    np.sqrt(m2, out=m2)
    np.multiply(m2, d0, out=t)
    np.divide(dep, t, out=t)  # r
    # σ r and σ 2m: the sign bit flipped where σ = −1.
    bits, it = w["bits"], w["bits"].dtype
    np.multiply(w["mask"][2], w["sign"], out=bits)
    np.bitwise_xor(t.view(it), bits, out=t.view(it))
    np.bitwise_xor(m2.view(it), bits, out=m2.view(it))
    return t, bb, cc, dd, d0, m2, dep


def root_rows(cubic, steps, w):
    """The one root ``t`` of P(t) the bound needs: :func:`moments_ref.msm6._extreme_root`, operation for operation.

    ``cubic = (p(zf), p'(zf), p''(zf)/2, q3)``. 36 passes in float32 (:func:`blinn_rows`
    18, cos(arccos(σr)/3) 16, the root 2); float64 adds its Newton steps. Returns the
    row holding t.
    """
    c0, c1, c2, c3 = cubic
    t, bb, cc, dd, d0, m2, c = blinn_rows(cubic, w)  # c: σr's numerator's row, free
    # cos(arccos(σr)/3) (msm6._cos_third): Horner in u = √|σr/2 + 1/2|, then the Newton refinement.
    np.multiply(t, 0.5, out=t)
    np.add(t, 0.5, out=t)
    np.abs(t, out=t)
    np.sqrt(t, out=t)
    np.multiply(t, COS_THIRD_POLY[-1], out=c)
    for a in COS_THIRD_POLY[-2:0:-1]:
        np.add(c, a, out=c)
        np.multiply(c, t, out=c)
    np.add(c, COS_THIRD_POLY[0], out=c)
    if steps[0]:
        su, s, x = dd, cc, d0
        np.multiply(t, np.sqrt(2.0), out=su)
        for _ in range(steps[0]):  # c −= ((2c − 1)√(c + 1) − √2 u) / (2√(c + 1) + (2c − 1)/(2√(c + 1)))
            np.add(c, 1, out=s)
            np.sqrt(s, out=s)
            np.multiply(c, 2, out=x)
            np.subtract(x, 1, out=x)
            np.multiply(x, s, out=t)
            np.subtract(t, su, out=t)
            np.multiply(s, 2, out=s)
            np.divide(x, s, out=x)
            np.add(s, x, out=s)
            np.divide(t, s, out=t)
            np.subtract(c, t, out=c)
    # t = σ 2m c − B, and the Newton steps on P(t) (msm6._newton).
    root = c
    np.multiply(m2, c, out=root)
    np.subtract(root, bb, out=root)
    f, fp, u = w["e"], w["f"], w["y2"]
    for _ in range(steps[1]):
        np.multiply(c0, root, out=f)
        np.add(f, c1, out=f)
        np.multiply(f, root, out=f)
        np.add(f, c2, out=f)
        np.multiply(f, root, out=f)
        np.add(f, c3, out=f)
        np.multiply(c0, 3, out=fp)
        np.multiply(fp, root, out=fp)
        np.multiply(c1, 2, out=u)
        np.add(fp, u, out=fp)
        np.multiply(fp, root, out=fp)
        np.add(fp, c2, out=fp)
        np.divide(f, fp, out=f)
        np.subtract(root, f, out=root)
    return root


def weight_rows(root, b, zf, ldl, w):
    """Step 4 at ``z = zf + 1/t``: :func:`moments_ref.msm6._weights`, operation for operation (24 passes).

    Returns the row of w.
    """
    b1, b2, b3 = b[:3]
    d1, d2, d3, l21, l31, l32 = ldl
    z, z2, u1, u2, t = (w[k] for k in ("e", "f", "y2", "y3", "t"))
    u3 = z2
    np.divide(1, root, out=z)
    np.add(zf, z, out=z)
    np.multiply(z, z, out=z2)
    np.subtract(z, b1, out=u1)  # forward substitution L u = v(z)
    np.subtract(z2, b2, out=u2)
    np.multiply(l21, u1, out=t)
    np.subtract(u2, t, out=u2)
    np.multiply(z2, z, out=u3)
    np.subtract(u3, b3, out=u3)
    np.multiply(l31, u1, out=t)
    np.subtract(u3, t, out=u3)
    np.multiply(l32, u2, out=t)
    np.subtract(u3, t, out=u3)
    # w = 1 / (1 + u1²/D1 + u2²/D2 + u3²/D3), and 0 where that is not a positive number.
    np.multiply(u1, u1, out=u1)
    np.divide(u1, d1, out=u1)
    np.add(u1, 1, out=u1)
    np.multiply(u2, u2, out=u2)
    np.divide(u2, d2, out=u2)
    np.add(u1, u2, out=u1)
    np.multiply(u3, u3, out=u3)
    np.divide(u3, d3, out=u3)
    np.add(u1, u3, out=u1)
    np.divide(1, u1, out=u1)
    return np.fmax(u1, w["zero"], out=u1)
