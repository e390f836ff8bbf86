"""View rays of the camera, ray marching through the shadow map, the scattering metric and figure.

The ground truth of :mod:`moments_ref.techniques.scattering`: ray marching is a
midpoint rule along each view ray through the MSAA shadow map (the slides' "ground
truth" uses 128 samples; the report's reference 4096).

References
----------
.. [1] Slides: Christoph Peters. *Rendering antialiased shadows with moment shadow mapping*,
       lecture slides (PDF version, with notes) on moment shadow mapping, translucent occluders,
       moment soft shadow mapping and prefiltered single scattering; http://MomentsInGraphics.de/.
       Cited by slide title, e.g. Slides, "Bias the moments".
.. [2] FLIP: Pontus Andersson, Jim Nilsson, Tomas Akenine-Möller, Magnus Oskarsson, Kalle Åström
       and Mark D. Fairchild. 2020. *ꟻLIP: A Difference Evaluator for Alternating Images*.
       Proceedings of the ACM on Computer Graphics and Interactive Techniques (HPG 2020) 3, 2. Used
       through the package ``flip-evaluator``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..._arrays import InputError
from ..._io import tight_layout
from ..._shim import renamed_keywords
from ...gpu.filtering import check_depth_samples
from ...metrics import flip_mean, light_metrics
from ...scene.depth import window_scale, x_window_from_ndc, y_window_from_ndc
from ...scene.raster import rasterize_depth, unproject_points
from .epipolar import AXIS_ANGLE, FAR_NDC, epipolar_depth

__all__ = ["CameraRays", "camera_rays", "check_directional", "pixel_epipolar", "ray_march", "scattering_metric",
           "scattering_figure", "write_images"]


@dataclass
class CameraRays:
    """Per-pixel view rays: directions (H, W, 3) unit, ``t_end`` (H, W), hit mask (H, W)."""

    direction: np.ndarray
    t_end: np.ndarray
    hit: np.ndarray
    resolution: tuple


def camera_rays(scene, resolution=None, t_max=None):
    """View rays through the pixel centres and their lengths (depth buffer of all geometry).

    Parameters
    ----------
    scene : Scene
    resolution : (width, height), default the camera's
    t_max : float, optional
        Length of background rays; default the distance from the eye to the farthest
        corner of the scene's bounding box.

    Returns
    -------
    CameraRays, t_max
    """
    cam = scene.camera
    w, h = cam.resolution if resolution is None else (int(resolution[0]), int(resolution[1]))
    cam = cam.resized((w, h))
    vp = cam.clip_from_world()
    verts = np.concatenate([scene.receiver.vertices, scene.occluder.vertices])
    tris = np.concatenate([scene.receiver.triangles, scene.occluder.triangles + scene.receiver.vertices.shape[0]])
    depth, _ = rasterize_depth(verts, tris, vp, (h, w), samples=1, dtype=np.float64)
    depth = depth[..., 0]
    col, row = np.meshgrid(np.arange(w) + 0.5, np.arange(h) + 0.5)
    centres = np.stack([col, row], axis=-1)  # pixel centres, window coordinates

    def unproject(zn):
        return unproject_points(centres, np.broadcast_to(zn, col.shape), vp, (h, w))

    far_pt = unproject(0.0)
    d = far_pt - cam.eye
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    hit = depth < 1.0
    t_hit = np.linalg.norm(unproject(depth) - cam.eye, axis=-1)
    if t_max is None:
        lo, hi = scene.bounds()
        corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
        t_max = float(np.linalg.norm(corners - cam.eye, axis=1).max())
    t_end = np.where(hit, np.minimum(t_hit, t_max), t_max)
    return CameraRays(d, t_end, hit, (w, h)), t_max


def check_directional(scene):
    """Refuse (InputError) a scene whose light is not directional: single scattering needs one."""
    if getattr(scene.light, "kind", None) != "directional":
        raise InputError(f"scene {scene.name!r}: single scattering needs a directional light "
                         f"(Slides, 'Integrate shadow along view ray'), got {getattr(scene.light, 'kind', '?')!r}")


def _padded_samples(depth_samples):
    """The map's samples with empty ones (``≥ FAR_NDC``) and a one-texel border set to +inf, flattened; (H, W, S).

    A march sample is visible against an MSAA sample ``o`` when ``o ≥ z``; +inf is
    visible against every ``z``, so an empty sample and a point outside the map
    (clamped onto the border) need no separate test.
    """
    d = check_depth_samples(depth_samples)
    h, w, s = d.shape
    pad = np.full((h + 2, w + 2, s), np.inf, d.dtype)
    inner = pad[1:-1, 1:-1]
    inner[...] = d
    inner[inner >= FAR_NDC] = np.inf
    return pad.reshape(-1, s), (h, w, s)


@renamed_keywords(view_proj="clip_from_world")
def ray_march(depth_samples, clip_from_world, eye, rays, n_samples, chunk=1 << 17):
    """Visibility integral by ray marching through the shadow map (midpoint rule).

    Parameters
    ----------
    depth_samples : (H, W, S) float array
        The light's MSAA depth map in [-1, 1] (cleared to 1 = no occluder).
    clip_from_world : (4, 4) the light's matrix (orthographic: ``w = 1``)
    eye : (3,) camera position
    rays : CameraRays
    n_samples : int ≥ 1
        Samples per view ray, at ``t_k = (k + ½) t_end / N``.
    chunk : int
        March samples per block (sized for the L2 cache).

    Returns
    -------
    S : (H, W) float64, ``t_end · mean_k V(t_k)``; V is the share of the MSAA samples of
        the nearest texel that do not occlude the point (1 outside the map).

    Notes
    -----
    The light's clip coordinates are affine in ``t`` along a ray, ``c(t) = c(eye) +
    t · M d``, so each sample costs one multiply-add per coordinate instead of a
    3×3 product per point. The visible samples are counted as integers; for a
    power-of-two S the result equals the mean of the per-sample shares exactly. A ray
    whose samples all fall on texels without an occluder sample is counted lit without
    marching (:func:`_lit_throughout`; the same count).
    """
    if not isinstance(n_samples, (int, np.integer)) or n_samples < 1:
        raise InputError(f"n_samples: expected a positive integer, got {n_samples!r}")
    flat, (h, w, s) = _padded_samples(depth_samples)
    dirs = np.asarray(rays.direction, np.float64).reshape(-1, 3)
    t_end = np.asarray(rays.t_end, np.float64).reshape(-1)
    m = np.asarray(clip_from_world, dtype=np.float64)
    o = m[:3, :3] @ np.asarray(eye, np.float64) + m[:3, 3]  # clip coordinates of the eye
    # Window coordinates + 1 (the padded map's), affine in t: a + t · b per ray.
    a = np.array([x_window_from_ndc(o[0], w) + 1, y_window_from_ndc(o[1], h) + 1, o[2]])
    b = (dirs @ m[:3, :3].T) * np.array([*window_scale((h, w)), 1.0])
    frac = (np.arange(n_samples) + 0.5) / n_samples
    # float64 (exact), so that the comparisons with z are exact without a conversion per sample
    lo_d, hi_d = _sample_extremes(flat)
    # Rays that cross only texels without an occluder sample are lit at every sample (z ≤ +inf):
    # S per sample, without marching (about half of the scattering scene's camera rays).
    count = np.full(t_end.shape[0], n_samples * s, np.int64)
    todo = np.flatnonzero(~_lit_throughout(np.isfinite(lo_d).reshape(h + 2, w + 2), a, b,
                                           t_end * frac[0], t_end * frac[-1]))
    per = max(1, chunk // n_samples)
    for lo in range(0, todo.size, per):  # loop over blocks of the other rays
        rr = todo[lo:lo + per]
        t = t_end[rr, None] * frac[None, :]
        br = b[rr]
        idx = _texel(a[1], t, br[:, 1], h + 1)
        idx *= w + 2
        idx += _texel(a[0], t, br[:, 0], w + 1)
        z = t
        z *= br[:, 2, None]
        z += a[2]
        # All S samples visible where z ≤ the texel's nearest sample, none where z > its farthest.
        full = z <= lo_d[idx]
        c = np.count_nonzero(full, axis=1) * s
        # The others: none visible where z > the farthest sample; the rest are counted sample by
        # sample. (The farthest sample is looked up for the others only: most samples are lit.)
        part = np.flatnonzero(~full)
        zp, ip = z.ravel()[part], idx.ravel()[part]
        near = zp <= hi_d[ip]
        part, zp, ip = part[near], zp[near], ip[near]
        if part.size:
            seen = np.count_nonzero(flat[ip] >= zp[:, None], axis=1)
            np.add.at(c, part // n_samples, seen)
        count[rr] = c
    return (t_end * (count / s / n_samples)).reshape(rays.t_end.shape)


def _sample_extremes(flat):
    """Each texel's nearest and farthest sample of the padded (T, S) map as float64 (exact): ``min``, ``max`` over S.

    Folded one sample column at a time (S − 1 long passes) instead of NumPy's reduction over
    the short inner axis, which runs an S-element loop per texel (about 15 times slower on
    a 4× map). The same values: the samples are finite or +inf, never NaN, and minimum and
    maximum are exact (a ±0 tie may keep the other zero, which every comparison treats alike).
    """
    lo, hi = flat[:, 0].copy(), flat[:, 0].copy()
    for s in range(1, flat.shape[1]):  # loop over the MSAA samples
        np.minimum(lo, flat[:, s], out=lo)
        np.maximum(hi, flat[:, s], out=hi)
    return lo.astype(np.float64), hi.astype(np.float64)


def _lit_throughout(occupied, a, b, t_first, t_last):
    """Per ray, True where every march sample falls on a texel with no occluder sample.

    ``occupied``: the padded map's texels holding a sample nearer than the far plane.
    Each coordinate of a sample's texel, ``floor(clip(a + t · b))`` as :func:`ray_march`
    computes it, is monotone in t (every rounding is), as t is in k; so the texels of a
    ray's samples lie in the box spanned by those of its first and last sample, and a
    box without an occupied texel (a summed-area count) leaves every sample lit. A ray
    whose end coordinates are not finite is never taken here.
    """
    hp, wp = occupied.shape
    ends = []
    for t in (t_first, t_last):
        y = t * b[:, 1]
        y += a[1]
        x = t * b[:, 0]
        x += a[0]
        ok = np.isfinite(y) & np.isfinite(x) & np.isfinite(t * b[:, 2] + a[2])
        ends.append((_texel(a[1], t[:, None], b[:, 1], hp - 1)[:, 0],
                     _texel(a[0], t[:, None], b[:, 0], wp - 1)[:, 0], ok))
    (y0, x0, ok0), (y1, x1, ok1) = ends
    sat = np.zeros((hp + 1, wp + 1), np.int64)
    np.cumsum(np.cumsum(occupied, axis=0), axis=1, out=sat[1:, 1:])
    ok = ok0 & ok1
    y0, y1, x0, x1 = (np.where(ok, v, 0) for v in (y0, y1, x0, x1))  # no index from a NaN coordinate
    ylo, yhi = np.minimum(y0, y1), np.maximum(y0, y1) + 1
    xlo, xhi = np.minimum(x0, x1), np.maximum(x0, x1) + 1
    return ok & (sat[yhi, xhi] - sat[ylo, xhi] - sat[yhi, xlo] + sat[ylo, xlo] == 0)


def _texel(a, t, b, top):
    """``floor(a + t · b)`` clamped to ``[0, top]`` as intp (the padded map's row or column)."""
    x = t * b[:, None]
    x += a
    np.clip(x, 0, top, out=x)
    return x.astype(np.intp)  # truncation is floor for x ≥ 0


def pixel_epipolar(rays, frame):
    """uv (columns, rows) and depth of every pixel's view ray; inclination clamped near the axis."""
    rows, cols = frame.size
    d = rays.direction
    cos_t = np.clip(d @ frame.light, -1, 1)
    theta = np.clip(np.arccos(cos_t), AXIS_ANGLE, np.pi - AXIS_ANGLE)
    phi = np.mod(np.arctan2(d @ frame.e2, d @ frame.e1), 2 * np.pi)
    rho_end = rays.t_end * np.sin(theta)
    uv = np.stack([rho_end / frame.rho_max * cols, phi / (2 * np.pi) * rows], axis=-1)
    return uv, epipolar_depth(theta)


def _ldr(img, t_max):
    x = np.clip(np.asarray(img, dtype=np.float64) / t_max, 0, 1)
    return np.repeat(x[..., None], 3, axis=2).astype(np.float32)


def scattering_metric(img, ref, t_max):
    """Error columns of a scattering image against the reference (normalized by ``t_max``) and mean ꟻLIP."""
    return {**light_metrics(img, ref, t_max), "flip_mean": flip_mean(_ldr(ref, t_max), _ldr(img, t_max))}


def scattering_figure(images, t_max):
    """One figure with the normalized scattering term of each image (reference first)."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    names = list(images)
    fig, axes = plt.subplots(1, len(names), figsize=(4 * len(names) + 1, 3.2), squeeze=False)
    im = None
    for ax, name in zip(axes[0], names):
        h, w = np.shape(images[name])[:2]
        im = ax.imshow(np.clip(images[name] / t_max, 0, 1), cmap="magma", vmin=0, vmax=1, extent=(0, w, h, 0))
        ax.set_title(name, fontsize=9)
        ax.set_xlabel("camera pixel x")
        ax.set_ylabel("camera pixel y")
    fig.suptitle("in-scattered light along each view ray / t_max (t_max: the longest view ray, world units)",
                 fontsize=9)
    tight_layout(fig, rect=(0, 0, 0.93, 1))
    if im is not None:
        cax = fig.add_axes((0.945, 0.18, 0.012, 0.64))
        fig.colorbar(im, cax=cax).set_label("scattering term / t_max (dimensionless)", fontsize=8)
    return fig


def write_images(images, t_max, path):
    """Write :func:`scattering_figure` to ``path`` (PNG, atomically); return ``path``."""
    import matplotlib.pyplot as plt

    from ..._io import save_figure

    fig = scattering_figure(images, t_max)
    save_figure(fig, path, dpi=100)
    plt.close(fig)
    return path
