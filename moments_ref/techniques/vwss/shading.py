"""Deferred shading of soft shadows: multi-view PCF and PCSS (VWSS §4).

VWSS §4 renders "1) a G-Buffer (with albedo, normals, and world positions), 2)
... VWSS, MVR, or standard depth-map rendering for PCSS, and 3) ... a
fullscreen pass to perform shading and shadow mapping". The G-buffer, the world
positions of the receiver as seen by the camera, is
:func:`moments_ref.scene.gbuffer.depth_gbuffer`; shading returns the visibility
factor per pixel (the fraction of the area light the point sees).

* Multi-view (VWSS, MVR): visibility = mean over the light-sample maps of a
  5-sample PCF test (VWSS §4: "a 5-sample PCF filter per pixel ... 120 depth-map
  samples per pixel" for 24 maps). The five taps are the texel containing the
  point and its four edge neighbours.
* PCSS (Fernando 2005; VWSS §4: "a 64-sample blocker search and 96-sample PCF
  filter"), from the single map of the light's centre.

Depth comparisons use the distance along the light normal (the view distance
``d_view``, :func:`moments_ref.scene.depth.d_view_from_ndc` of the maps' NDC depth), so
that the bias is in world units. A tap outside a map, an empty texel (z = 1) or a
point behind a view counts as lit.

NumPy. Each map becomes one flat array padded by a one-texel border: the view
depth of the occluder where ``z < 1`` and +inf at empty texels and on the
border. A tap clips ``floor(x + dx)`` to the border (NaN and ±inf positions of
points on the light's plane included), gathers once and compares with
``cw − bias``, which is −inf for a point behind the view: the same booleans as
testing "inside, in front, occupied, nearer" one by one. Points are shaded in
blocks of ``2**14`` (the results do not depend on the block size).

References
----------
.. [1] VWSS: Adam Marrs, Benjamin Watson and Christopher Healey. 2018. *View-warped Multi-view Soft
       Shadowing for Local Area Lights*. Journal of Computer Graphics Techniques (JCGT) 7, 3, 1–28.
       http://jcgt.org/published/0007/03/01/
.. [2] Fernando 2005: Randima Fernando. 2005. *Percentage-Closer Soft Shadows*. In ACM SIGGRAPH
       2005 Sketches. https://doi.org/10.1145/1187112.1187153 (PCSS)
"""

from __future__ import annotations

import functools

import numpy as np

from ..._arrays import InputError, first_index, real_input
from ..._kernels import SHADING_BLOCK
from ...scene.depth import d_view_from_ndc, x_window_from_ndc, y_window_from_ndc
from ..._shim import renamed, renamed_keywords
from .lights import LightSamples, poisson_disk

__all__ = ["PCF5", "pcf_sum", "multiview_visibility", "pcss",
           "PCSS_BLOCKER_TAPS", "PCSS_FILTER_TAPS"]

#: Texel offsets (dx, dy) of the 5-sample PCF filter: centre and the 4 edge neighbours.
PCF5 = np.array([[0, 0], [1, 0], [-1, 0], [0, 1], [0, -1]], np.int64)
#: PCSS tap counts of VWSS §4.
PCSS_BLOCKER_TAPS = 64
PCSS_FILTER_TAPS = 96
# Points per block of the shading loops (moments_ref._kernels' table, with the reason). Results do not depend
# on the block size.
_BLOCK = SHADING_BLOCK


#: Old names (a DeprecationWarning): linear_depth, GBuffer and gbuffer moved to moments_ref.scene.
__getattr__ = renamed("techniques.vwss.shading")


def _project(positions, clip_from_world, h, w):
    """Continuous window coordinates and view depth (w_clip) of positions in one view."""
    hom = positions @ clip_from_world[:3, :3].T
    cw = positions @ clip_from_world[3, :3] + clip_from_world[3, 3]
    # The translation added to the x and y columns alone (the same sums as adding the (3,) row to
    # the (P, 3) product, whose 3-long inner loops cost more than the product; z is not needed).
    with np.errstate(divide="ignore", invalid="ignore"):
        x = x_window_from_ndc((hom[:, 0] + clip_from_world[0, 3]) / cw, w)
        y = y_window_from_ndc((hom[:, 1] + clip_from_world[1, 3]) / cw, h)
    return x, y, cw


def _occluder_map(depth_map, near, far):
    """Flat (H+2)·(W+2) map: the occluder's view distance (:func:`~moments_ref.scene.depth.d_view_from_ndc`) where ``depth < 1``,
    +inf at empty texels and on a one-texel border (a tap outside the map reads +inf: lit)."""
    h, w = depth_map.shape
    occ = np.full((h + 2, w + 2), np.inf)
    occupied = depth_map < 1
    occ[1:-1, 1:-1][occupied] = d_view_from_ndc(depth_map[occupied], near, far)
    return occ.reshape(-1)


def _threshold(cw, bias):
    """``cw − bias`` where the point is in front of the view (``cw > 0``), −inf elsewhere (always lit)."""
    return np.where(cw > 0, cw - bias, -np.inf)


def _padded_floor(v, n):
    """``floor(v) + 1`` clipped to ``[0, n + 1]`` as intp: the index into a map padded by one texel.

    Out-of-range, infinite and NaN positions (``cw = 0``) land on the +inf border.
    """
    c = np.floor(v)
    np.fmin(c, n, out=c)  # NaN -> n (fmin returns the non-NaN operand)
    np.fmax(c, -1, out=c)
    c += 1
    return c.astype(np.intp)


def _shadowed(occ, row_index, col_index, threshold):
    """Shadowed (True) per point: the texel's occluder lies nearer than the threshold.

    ``occ`` from :func:`_occluder_map`; ``row_index`` = padded row × (W + 2), ``col_index`` =
    padded column. Equals, per point, "inside the map, in front of the view, an occluder
    (depth < 1) with view depth < cw − bias" (outside, behind or empty: +inf or −inf, False).
    """
    return occ.take(row_index + col_index) < threshold


def _lookup(occ, x, y, threshold, h, w):
    """Shadowed (True) per point for nearest-texel lookups at window positions (x, y)."""
    return _shadowed(occ, _padded_floor(y, h) * (w + 2), _padded_floor(x, w), threshold)


def _check_positions(positions):
    p = real_input(positions, "positions", trailing=3, dtype=np.float64)
    if p.ndim != 2:
        raise InputError(f"positions: expected a (P, 3) array, got shape {p.shape}")
    return p


def _check_maps(depth_maps, n_views, name="depth_maps"):
    """``(n_views, H, W)`` float NDC depths (an ``(H, W)`` map is one view); ±inf allowed, NaN not."""
    d = np.asarray(depth_maps)
    if d.dtype.kind != "f":
        raise InputError(f"{name}: expected float NDC depths, got dtype {d.dtype}")
    nan = np.isnan(d)
    if nan.any():
        raise InputError(f"{name}: expected NDC depths without NaN, got NaN at index {first_index(nan)}")
    if d.ndim == 2:
        d = d[None]
    if d.ndim != 3 or d.shape[0] != n_views:
        raise InputError(f"{name}: expected ({n_views}, H, W) maps (one per view), got shape {d.shape}")
    return d


@renamed_keywords(view_proj="clip_from_world")
def pcf_sum(positions, depth_maps, clip_from_world, near, far, bias, taps=PCF5):
    """Sum over maps of the fraction of PCF taps that are lit, per point.

    Parameters
    ----------
    positions : (P, 3) float array, world positions of the receiver
    depth_maps : (K, H, W) float array, NDC depth (1 = empty)
    clip_from_world : (K, 4, 4) float array, the maps' views
    near, far : float, the shared near and far distances of the views
    bias : float, depth bias in world units along the light normal
    taps : (T, 2) int array of texel offsets (dx, dy); default :data:`PCF5`

    Returns
    -------
    (P,) float64 array in [0, K]
    """
    p = _check_positions(positions)
    vp = real_input(clip_from_world, "clip_from_world", dtype=np.float64).reshape(-1, 4, 4)
    maps = _check_maps(depth_maps, vp.shape[0])
    taps = np.asarray(taps, np.int64).reshape(-1, 2)
    h, w = maps.shape[1:]
    acc = np.zeros(p.shape[0])
    for k in range(vp.shape[0]):  # loop over views
        occ = _occluder_map(maps[k], near, far)
        for lo in range(0, p.shape[0], _BLOCK):  # loop over blocks of points
            acc[lo:lo + _BLOCK] += _pcf_block(occ, p[lo:lo + _BLOCK], vp[k], h, w, bias, taps)
    return acc


def _pcf_block(occ, p, clip_from_world, h, w, bias, taps):
    """Lit fraction of the PCF taps of one view for a block of points (exact count / T)."""
    x, y, cw = _project(p, clip_from_world, h, w)
    thr = _threshold(cw, bias)
    # floor(x + dx) once per distinct offset (PCF5: 3 columns and 3 rows serve the 5 taps); the padded
    # index (row + 1)(W + 2) + col + 1 as row (W + 2) + col + (W + 3), the constant added to the rows
    cols = _offset_floors(x, w, np.unique(taps[:, 0]), 1, 0)
    rows = _offset_floors(y, h, np.unique(taps[:, 1]), w + 2, w + 3)
    t = taps.shape[0]
    shadowed = np.zeros(p.shape[0], np.uint8 if t < 256 else np.intp)  # counts up to T
    index, depth, nearer = np.empty(p.shape[0], np.intp), np.empty(p.shape[0]), np.empty(p.shape[0], bool)
    for dx, dy in taps:  # loop over the taps: _shadowed into buffers
        np.add(rows[dy], cols[dx], out=index)
        occ.take(index, out=depth)
        np.add(shadowed, np.less(depth, thr, out=nearer), out=shadowed)
    return (t - shadowed) / t


def _offset_floors(v, n, offsets, scale, shift):
    """``{d: clip(floor(v + d), −1, n) · scale + shift}`` as intp, for each integer offset ``d``.

    :func:`_padded_floor` without its ``+ 1`` (folded into ``shift``) and with one clip:
    ``v`` is first capped at ``n + 1 − min(d, 0)``, which takes NaN there (``fmin`` returns
    the other operand) and changes no result (from there on ``v + d ≥ n + 1`` for every
    offset, clipped to ``n`` as NaN is by :func:`_padded_floor`), so ``clip`` sees no NaN.
    """
    v = np.fmin(v, n + 1 - min(int(offsets.min()), 0))
    out = {}
    for d in offsets:  # loop over the distinct offsets
        c = np.add(v, d) if d else v.copy()
        np.floor(c, out=c)
        np.clip(c, -1, n, out=c)
        if scale != 1:
            c *= scale
        if shift:
            c += shift
        out[d] = c.astype(np.intp)
    return out


def multiview_visibility(positions, depth_maps, samples: LightSamples, bias, views=None, taps=PCF5):
    """Visibility per point: the mean over light-sample maps of a 5-tap PCF test (VWSS §4).

    Parameters
    ----------
    positions : (P, 3) float array
    depth_maps : (K, H, W) float array
        Maps of the views ``views`` of ``samples`` (default: all of them, K = len(samples)).
    samples : LightSamples
    bias : float
        World-space depth bias along the light normal.
    views : (K,) int array, optional
        Which light samples the maps belong to.
    taps : (T, 2) int array

    Returns
    -------
    visibility : (P,) float64 in [0, 1]
        ``(1/K) Σ_k (1/5) Σ_taps [d_k(tap) ≥ d_point − bias]``.
    """
    sel = np.arange(len(samples)) if views is None else np.asarray(views, np.int64)
    s = pcf_sum(positions, depth_maps, samples.clip_from_world[sel], samples.near, samples.far, bias, taps)
    return s / sel.size


@functools.lru_cache(maxsize=16)
def _tap_pattern(n, seed):
    """n deterministic Poisson-disk taps in [−1, 1]² (cached: Bridson's fill costs ~0.1 s)."""
    taps = poisson_disk(n, seed) * 2 - 1
    taps.setflags(write=False)
    return taps


def _search_depth(occ, near):
    """``max(near, nearest view depth of an occupied texel)``; ``near`` for an empty map."""
    nearest = float(occ.min())  # +inf when no texel is occupied
    return max(float(near), nearest) if np.isfinite(nearest) else float(near)


def pcss(positions, depth_map, samples: LightSamples, bias, blocker_taps=PCSS_BLOCKER_TAPS,
         filter_taps=PCSS_FILTER_TAPS, seed=0, search_depth=None):
    """Percentage-closer soft shadows from the light-centre map (Fernando 2005; VWSS §4).

    Parameters
    ----------
    positions : (P, 3) float array
    depth_map : (H, W) float array
        NDC depth rasterized from the light's centre with the samples' projection
        (``samples.center_clip_from_world()``).
    samples : LightSamples
        For the light, the shared projection, near and far.
    bias : float
        World-space depth bias.
    blocker_taps, filter_taps : int
        64 and 96 in VWSS §4.
    seed : int
        Seed of the (deterministic) Poisson-disk tap patterns.
    search_depth : float, optional
        View depth of the plane whose rectangle the blocker search covers;
        default ``max(samples.near, nearest depth in the map)`` (see Notes).

    Returns
    -------
    visibility : (P,) float64 in [0, 1]

    Notes
    -----
    For a rectangular light the occluders that can block a receiver at depth
    ``z_r`` lie, at depth ``z``, in a rectangle centred on the receiver's
    projection with half-extents ``(l_w / 2, l_h / 2) (1/z − 1/z_r)`` in
    projected (tan) units: the cross-section of the pyramid from the receiver to
    the light. Steps:

    These rectangles are nested: the nearer the plane, the larger. Fernando's
    search region, ``w_search = l (z_r − z_n) / z_r`` at the near plane ``z_n``,
    is the one at the nearest depth a blocker can have. Here that depth is
    ``z_s = max(z_n, z_min)`` with ``z_min`` the nearest depth in the map (a min
    reduction): no blocker lies nearer, so the region still holds every blocker,
    and it no longer depends on where the light's own near plane (``samples.near``,
    VWSS Listing 1's ``light.nearZ``, which also sets VWSS's Eq. (3)) happens to
    lie. With the literal ``z_n`` (``search_depth=samples.near``) a small near
    plane makes the region many times the map: on the knot scene at ``z_n = 0.2``
    it is about 2.8 map widths across, 54 of the 64 taps fall outside the map,
    the rest miss the thin tube and umbra pixels come out fully lit.

    1. Blocker search over the rectangle at ``z_s``: mean depth ``z_b`` of the
       taps nearer than ``z_r − bias``. No blocker: lit.
    2. Penumbra estimate by parallel planes, ``w = l (z_r − z_b) / z_b`` on the
       receiver, i.e. half-extents ``(l / 2)(1/z_b − 1/z_r)`` in tan units.
    3. PCF with ``filter_taps`` taps over that rectangle.
    """
    p = _check_positions(positions)
    dmap = _check_maps(depth_map, 1, "depth_map")[0]
    h, w = dmap.shape
    light = samples.light
    n, f = samples.near, samples.far
    vp = samples.center_clip_from_world()
    occ = _occluder_map(dmap, n, f)
    # tan units -> texels: half-extents of the light (l_w / 2, l_h / 2) in texels per tan unit
    kx = w / (2 * np.tan(samples.fov / 2))
    ky = h / (2 * np.tan(samples.fov / 2))
    half = (light.width / 2 * kx, light.height / 2 * ky)
    # 1. Blocker search over the rectangle at the nearest depth a blocker can have.
    zs = _search_depth(occ, n) if search_depth is None else float(search_depth)
    taps = (_tap_pattern(blocker_taps, seed), _tap_pattern(filter_taps, seed + 1))
    vis = np.empty(p.shape[0])
    for lo in range(0, p.shape[0], _BLOCK):  # loop over blocks of points
        x, y, zr = _project(p[lo:lo + _BLOCK], vp, h, w)
        vis[lo:lo + _BLOCK] = _pcss_block(occ, h, w, x, y, zr, bias, 1 / zs, half, taps)
    return vis


def _pcss_block(occ, h, w, x, y, zr, bias, inv_s, half, taps):
    """PCSS steps 1–3 (see :func:`pcss`) for a block of points at window (x, y), view depth zr."""
    hx, hy = half
    thr = _threshold(zr, bias)
    with np.errstate(divide="ignore", invalid="ignore"):
        inv_r = np.where(zr > 0, 1 / zr, 0.0)
    reach = np.maximum(inv_s - inv_r, 0.0)
    sx, sy = hx * reach, hy * reach
    total = np.zeros(x.shape[0])
    count = np.zeros(x.shape[0])
    for ox, oy in taps[0]:  # loop over the blocker-search taps
        d = occ.take(_padded_floor(y + oy * sy, h) * (w + 2) + _padded_floor(x + ox * sx, w))
        blk = d < thr  # an occluder nearer than the receiver minus the bias
        np.add(total, d, out=total, where=blk)
        count += blk
    has = count > 0
    zb = np.where(has, total / np.maximum(count, 1), 1.0)
    # 2. Penumbra by parallel planes; 3. PCF over it.
    fx, fy = hx * (1 / zb - inv_r), hy * (1 / zb - inv_r)
    shadowed = np.zeros(x.shape[0], np.intp)
    for ox, oy in taps[1]:  # loop over the filter taps
        shadowed += _lookup(occ, x + ox * fx, y + oy * fy, thr, h, w)
    vis = (taps[1].shape[0] - shadowed) / taps[1].shape[0]
    vis[~has] = 1.0
    return vis
