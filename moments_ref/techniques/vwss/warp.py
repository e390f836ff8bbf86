"""Depth-map rendering by view warping: reproject, snap, z-buffer (VWSS §3.2, Listing 2).

Each point is projected into every light-sample view, snapped to the texel that
contains it (its nearest texel centre) and z-buffered with an atomic maximum on
the 32-bit integer view of its reversed-z depth, as Listing 2::

    InterlockedMax(rt_depth_int[float3(x, y, lightIndex)], asuint(cp.z));

Reversed z. Listing 2 keeps the *largest* depth, so nearer must be larger: the
reversed depth ``r = (1 − z_ndc) / 2`` is 1 on the near plane and 0 on the far
plane (Direct3D's reversed-z convention), and an empty texel holds 0. For
non-negative IEEE-754 floats the order of the bit patterns read as unsigned
integers equals the order of the values (sign bit 0, then exponent, then
mantissa, most significant first), so a ``uint32`` maximum is a float maximum.
It fails for negative numbers (sign bit set: they order above every positive
float) and NaN (exponent all ones, mantissa non-zero: above +inf); those are
refused. −0.0 is folded into +0.0 first.

NumPy. ``np.maximum.at`` is the unbuffered scatter-maximum that plays the role
of the atomics: the result does not depend on the order of the updates, so a
serial (one view per traversal of the points), partially parallel (k views per
traversal) or fully parallel (all views in one traversal) order gives the same
maps bit for bit (VWSS §3.2, Figure 2).

The public maps are NDC depth in [−1, 1] (``z = 1 − 2 r``, empty = 1 = far), the
convention of :func:`moments_ref.scene.raster.rasterize_depth`, so that warped and
rasterized maps compare directly.

References
----------
.. [1] VWSS: Adam Marrs, Benjamin Watson and Christopher Healey. 2018. *View-warped Multi-view Soft
       Shadowing for Local Area Lights*. Journal of Computer Graphics Techniques (JCGT) 7, 3, 1–28.
       http://jcgt.org/published/0007/03/01/
"""

from __future__ import annotations

import numpy as np

from ..._arrays import InputError, first_index, positive_int, real_input
from ..._kernels import WARP_BLOCK
from ..._shim import renamed_keywords
from .lights import check_resolution, check_views
from ...scene.depth import x_window_from_ndc, y_window_from_ndc, z_ndc_from_reversed, z_reversed_from_ndc

__all__ = ["zbuffer_max", "project_to_texels", "warp", "warp_passes", "zbuffer_dtype", "zmax_into", "depth_key",
           "key_depth", "EMPTY_KEY"]

# Point-view pairs per block of :func:`project_to_texels` and :func:`warp_passes` (moments_ref._kernels' table,
# with the reason; results do not depend on the block size).
_BLOCK = WARP_BLOCK


def zbuffer_dtype(dt):
    """The unsigned integer type of a z-buffer of ``dt`` depths: uint32 for float32 (Listing 2), else uint64."""
    return np.uint32 if np.dtype(dt) == np.float32 else np.uint64


#: The key of a texel no point was written to (the clear value; below every depth's key).
EMPTY_KEY = 0


def depth_key(depth):
    """Order-preserving 32-bit key of float32 depths: ``asuint`` with the sign transform.

    Parameters
    ----------
    depth : float array
        Depths, any sign (rounded to float32); −0.0 is taken as +0.0.

    Returns
    -------
    key : uint32 array
        ``asuint(d) ^ 0x80000000`` for ``d ≥ 0`` (the sign bit set), ``asuint(d) ^
        0xFFFFFFFF`` for ``d < 0`` (every bit flipped), so that ``key(a) < key(b)``
        exactly when ``a < b``: an ``InterlockedMax`` on keys is a maximum of depths of
        any sign. Every key of a non-NaN depth is above :data:`EMPTY_KEY`.

    Notes
    -----
    VWSS Listing 2 runs ``InterlockedMax`` on ``asuint(cp.z)``, which orders only
    non-negative floats: a negative float has its sign bit set and orders above
    every positive one (module docstring). Listing 2 clips no depth, so a point
    behind the far plane (reversed depth below 0) would win the z-test; the sign
    transform is the standard repair. For ``d ≥ 0`` the key is the paper's
    ``asuint(d)`` with the top bit set.

    Examples
    --------
    >>> [hex(k) for k in depth_key(np.float32([-1.0, -0.0, 0.0, 0.5]))]
    ['0x407fffff', '0x80000000', '0x80000000', '0xbf000000']
    """
    d = np.asarray(depth, np.float32) + np.float32(0.0)  # -0.0 -> +0.0
    u = d.view(np.uint32)
    return np.where(u >> np.uint32(31) == 1, ~u, u | np.uint32(0x80000000)).astype(np.uint32)


def key_depth(key):
    """Inverse of :func:`depth_key`: float32 depths of uint32 keys (:data:`EMPTY_KEY` decodes to NaN)."""
    k = np.asarray(key)
    if k.dtype.kind != "u":
        raise InputError(f"key: expected an unsigned integer array, got dtype {k.dtype}")
    k = k.astype(np.uint32)
    u = np.where(k >> np.uint32(31) == 1, k & np.uint32(0x7FFFFFFF), ~k).astype(np.uint32)
    return u.view(np.float32)


def zmax_into(buf, index, depth):
    """``buf[index] = max(buf[index], asuint(depth))`` without checks (depth ≥ +0.0, no NaN): :func:`zbuffer_max`'s kernel."""
    np.maximum.at(buf, index, depth.view(buf.dtype))


def zbuffer_max(texel_index, depth, n_texels):
    """Z-buffer by an atomic maximum on the unsigned-integer view of reversed-z depth.

    Parameters
    ----------
    texel_index : (N,) int array
        Destination texel of each update, in ``[0, n_texels)``.
    depth : (N,) float array
        Reversed-z depth (larger = nearer), non-negative, not NaN (+inf is
        allowed: its bit pattern is the largest of the non-negative floats).
        float32 uses ``uint32`` as Listing 2; float64 uses ``uint64``; other
        inputs become float64 (the package's dtype policy).
    n_texels : int
        Size of the buffer.

    Returns
    -------
    zbuffer : (n_texels,) float array of the working dtype
        Per texel the largest depth written to it, 0 where nothing was written
        (the reversed-z clear value, far).

    Raises
    ------
    InputError
        Negative or NaN depth (the integer ordering would be wrong), an index
        outside ``[0, n_texels)``, or mismatched lengths.

    Notes
    -----
    VWSS Listing 2: ``InterlockedMax(rt_depth_int[...], asuint(cp.z))``. −0.0 is
    turned into +0.0 (by adding +0.0) because its bit pattern 0x80000000 would
    order above every positive float.

    Examples
    --------
    >>> zbuffer_max([0, 0, 2], np.float32([0.25, 0.5, 1.0]), 3)
    array([0.5, 0. , 1. ], dtype=float32)
    """
    z = real_input(depth, "depth", finite=False).reshape(-1)
    idx = np.asarray(texel_index)
    if idx.dtype.kind not in "iu":
        raise InputError(f"texel_index: expected an integer array, got dtype {idx.dtype}")
    idx = idx.reshape(-1)
    if idx.shape != z.shape:
        raise InputError(f"texel_index: expected {z.shape[0]} indices (one per depth), got {idx.shape[0]}")
    try:
        n = int(n_texels)
        ok = n == n_texels and n >= 0
    except (TypeError, ValueError):
        ok = False
    if not ok:
        raise InputError(f"n_texels: expected a non-negative integer, got {n_texels!r}")
    bad = np.isnan(z) | (z < 0)
    if bad.any():
        i = first_index(bad)
        raise InputError(f"depth: expected non-negative reversed-z depths (not NaN), got {z[i]!r} at index {i}")
    out = (idx < 0) | (idx >= n)
    if out.any():
        i = first_index(out)
        raise InputError(f"texel_index: expected indices in [0, {n}), got {idx[i]} at index {i}")
    z = z + z.dtype.type(0.0)  # -0.0 -> +0.0
    buf = np.zeros(n, zbuffer_dtype(z.dtype))
    zmax_into(buf, idx.astype(np.intp, copy=False), z)
    return buf.view(z.dtype)


def _points(points):
    p = real_input(points, "points", trailing=3)  # NaN or inf coordinates -> InputError
    if p.ndim != 2:
        raise InputError(f"points: expected an (N, 3) array, got shape {p.shape}")
    return p


@renamed_keywords(view_proj="clip_from_world")
def project_to_texels(points, clip_from_world, resolution, clip_depth=True):
    """Project points into views and snap them to texels (the per-point work of Listing 2).

    Parameters
    ----------
    points : (N, 3) float array
        World positions; float32 input is projected in float32 (as a shader).
    clip_from_world : (K, 4, 4) float array
    resolution : int or (H, W)
    clip_depth : bool
        Drop pairs whose NDC depth is outside [−1, 1] (a depth-map pass's clip
        test). ``False`` keeps them, as Listing 2 does (it tests no depth): their
        reversed depth is then below 0 (behind the far plane) or above 1.

    Returns
    -------
    flat : (M,) intp array
        ``view * H * W + row * W + col`` for each (point, view) pair that lands
        inside a view: ``w > 0``, window position inside the map and (with
        ``clip_depth``) NDC depth in [−1, 1].
    reversed_depth : (M,) float array of the working dtype
        ``r = (1 − z_ndc) / 2``, in [0, 1] with ``clip_depth`` (1 = near plane).

    Notes
    -----
    Window coordinates and reversed depth are those of :mod:`moments_ref.scene.depth`
    (``x_window_from_ndc``, ``y_window_from_ndc``, ``z_reversed_from_ndc``); the texel is ``(floor(y), floor(x))``, the one whose
    centre is nearest (VWSS §3.2, "snap the projected location to the nearest
    neighbor pixel").
    """
    p = _points(points)
    m = check_views(clip_from_world).astype(p.dtype)
    return _project_to_texels(p, m, *check_resolution(resolution), clip_depth=bool(clip_depth))


def _project_to_texels(p, m, h, w, clip_depth=True):
    """:func:`project_to_texels` of checked points ``p`` (N, 3) and views ``m`` (k, 4, 4) of p's dtype."""
    k = m.shape[0]
    mt = _stacked(m)
    step = max(1, _BLOCK // k)
    parts = [_texel_block(p[lo:lo + step], mt, k, h, w, clip_depth) for lo in range(0, p.shape[0], step)]
    if len(parts) == 1:
        return parts[0]
    if not parts:
        return np.zeros(0, np.intp), np.zeros(0, p.dtype)
    return np.concatenate([f for f, _ in parts]), np.concatenate([r for _, r in parts])


def _stacked(m):
    """The k views as one (4, 4k) matrix, columns ordered (component, view): one product for all views."""
    return m.transpose(2, 1, 0).reshape(4, 4 * m.shape[0])


def _texel_block(p, mt, k, h, w, clip_depth=True):
    """Texels and reversed depths of one block of points, in (point, view) order."""
    dt, ut = p.dtype.type, zbuffer_dtype(p.dtype)
    hom = np.concatenate([p, np.ones((p.shape[0], 1), p.dtype)], axis=1)
    clip = (hom @ mt).reshape(p.shape[0], 4, k)
    cw = clip[:, 3]
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = dt(1) / cw
        x = clip[:, 0] * inv  # NDC, then window and reversed depth in place (scene.depth)
        x_window_from_ndc(x, w, out=x)
        y = clip[:, 1] * inv
        y_window_from_ndc(y, h, out=y)
        r = clip[:, 2] * inv
        z_reversed_from_ndc(r, out=r)
    # 0 ≤ x < W, 0 ≤ y < H, 0 ≤ r ≤ 1 as one unsigned comparison each: none of x, y, r can be
    # −0.0 (a − b rounds to +0.0 when a = b, and the factors are ≥ 1/2), so the bit pattern orders
    # them (module docstring); negative values and NaN have patterns above every bound.
    ok = cw > 0
    ok &= x.view(ut) < np.array(w, p.dtype).view(ut)
    ok &= y.view(ut) < np.array(h, p.dtype).view(ut)
    if clip_depth:
        ok &= r.view(ut) <= np.array(1, p.dtype).view(ut)
    i = np.flatnonzero(ok)  # = point * k + view
    col = x.reshape(-1).take(i).astype(np.intp)
    row = y.reshape(-1).take(i).astype(np.intp)
    # float rounding can put x == w after the test on the unrounded value; clamp.
    np.minimum(col, w - 1, out=col)
    np.minimum(row, h - 1, out=row)
    flat = (i % k * h + row) * w + col
    return flat, r.reshape(-1).take(i) + dt(0.0)


def warp_passes(points, views, resolution, views_per_pass=None, progress=False):
    """Yield the warped depth maps pass by pass: ``(view indices, maps (k, H, W))``.

    Parameters as :func:`warp`. Each pass traverses all points once and renders
    ``views_per_pass`` maps (the last pass may have fewer).
    """
    p = _points(points)
    m = check_views(views)
    h, w = check_resolution(resolution)
    nv = m.shape[0]
    k = nv if views_per_pass is None else views_per_pass
    k = min(positive_int(k, "views_per_pass"), nv)
    udt = zbuffer_dtype(p.dtype)
    starts = range(0, nv, k)
    if progress:
        import sys

        from tqdm import tqdm

        starts = tqdm(starts, desc="warp", unit="pass", file=sys.stderr, disable=None, leave=False)
    for s in starts:
        sel = np.arange(s, min(s + k, nv))
        buf = np.zeros(sel.size * h * w, udt)
        mt = _stacked(m[sel].astype(p.dtype))
        step = max(1, _BLOCK // sel.size)
        for lo in range(0, p.shape[0], step):  # each block straight into the z-buffer, no concatenation
            zmax_into(buf, *_texel_block(p[lo:lo + step], mt, sel.size, h, w))
        r = buf.view(p.dtype).reshape(sel.size, h, w)
        # Back to NDC depth (empty texels, r = 0, become 1 = far).
        yield sel, z_ndc_from_reversed(r)


def warp(points, views, resolution, views_per_pass=None, progress=False):
    """Render one depth map per light-sample view from points (VWSS §3.2).

    Parameters
    ----------
    points : (N, 3) float array
        World positions (:class:`~moments_ref.techniques.vwss.points.PointCloud.positions`);
        float32 points are projected in float32 and give float32 maps.
        NaN or inf coordinates raise :class:`InputError`. N = 0 is allowed.
    views : LightSamples or (V, 4, 4) float array
        View-projection matrices of the light samples.
    resolution : int or (H, W)
        Depth-map size.
    views_per_pass : int, optional
        Maps rendered per traversal of the points: 1 = serial, 1 < k < V =
        partially parallel, None or V = fully parallel. The maps do not depend on it.
    progress : bool
        Show a tqdm bar over the passes (stderr).

    Returns
    -------
    depth : (V, H, W) float array
        NDC depth of the nearest point per texel, in [−1, 1]; 1 (far) where no
        point landed. Views that see no point are entirely 1: a documented empty
        result, not an error.

    Notes
    -----
    VWSS Listing 2: per point and view ``cp = mul(wp, viewToLight)``, perspective
    divide, nearest texel, ``InterlockedMax(asuint(z))`` on reversed-z depth
    (see :func:`zbuffer_max` and the module docstring).
    """
    p = _points(points)
    h, w = check_resolution(resolution)
    m = check_views(views)
    out = np.empty((m.shape[0], h, w), p.dtype)
    for sel, maps in warp_passes(p, m, (h, w), views_per_pass, progress):
        out[sel] = maps
    return out
