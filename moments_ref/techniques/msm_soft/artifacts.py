"""The artifacts of moment soft shadow mapping the slides name, measured (Slides, "Results for soft shadows").

Synthetic scenes of rectangles parallel to a rectangular light, whose exact
visibility :func:`ray_cast_visibility` computes: light through a small hole
takes the light's rectangular shape, and a distant occluder in the blocker
search region softens the shadow of a near one.

References
----------
.. [1] Slides: Christoph Peters. *Rendering antialiased shadows with moment shadow mapping*,
       lecture slides (PDF version, with notes) on moment shadow mapping, translucent occluders,
       moment soft shadow mapping and prefiltered single scattering; http://MomentsInGraphics.de/.
       Cited by slide title, e.g. Slides, "Bias the moments".
"""

from __future__ import annotations

import numpy as np

from ...scene.raster import look_at, perspective, rasterize_depth
from .shadow import precision_bits_text, prepare, shade_points

__all__ = ["ARTIFACT_SCENES", "ray_cast_visibility", "artifact_measurements", "artifact_images",
           "report_artifacts"]


#: The light of the artifact scenes: 1.0 × 0.6 (width along the map's columns), 60° maps.
_ART_LIGHT = dict(center=(0.0, 0.0, 0.0), normal=(0.0, -1.0, 0.0), width=1.0, height=0.6, up=(0.0, 0.0, -1.0),
                  fov=60.0)
#: Receiver plane distance, near and far of the artifact scenes.
_ART_RECEIVER, _ART_NEAR, _ART_FAR = 4.0, 0.5, 5.0
#: Rectangles (x0, x1, y0, y1, d) in the light's frame (tangent, bitangent, distance).
_HOLE = 0.08
ARTIFACT_SCENES = {
    # A plate at d = 3 with a small square hole at its centre.
    "hole": ((-2.0, -_HOLE / 2, -2.0, 2.0, 3.0), (_HOLE / 2, 2.0, -2.0, 2.0, 3.0),
             (-_HOLE / 2, _HOLE / 2, -2.0, -_HOLE / 2, 3.0), (-_HOLE / 2, _HOLE / 2, _HOLE / 2, 2.0, 3.0)),
    # A column close to the receiver (d = 3.6) ...
    "column": ((-1.0, -0.1, -2.0, 2.0, 3.6),),
    # ... and the same with a wall nearer the light (d = 3) that shadows none of the
    # receiver points left of x = 0 but lies in their blocker-search regions.
    "column_wall": ((-1.0, -0.1, -2.0, 2.0, 3.6), (0.18, 2.0, -2.0, 2.0, 3.0)),
}


def _frame_points(light, x, y, d):
    x, y, d = np.broadcast_arrays(np.asarray(x, np.float64), np.asarray(y, np.float64), np.asarray(d, np.float64))
    return (light.center + x[..., None] * light.tangent + y[..., None] * light.bitangent
            + d[..., None] * light.normal)


def _rect_mesh(light, rects):
    """Two triangles per rectangle (x0, x1, y0, y1, d) of the light's frame."""
    r = np.asarray(rects, np.float64).reshape(-1, 5)
    xs = np.stack([r[:, 0], r[:, 1], r[:, 1], r[:, 0]], 1)
    ys = np.stack([r[:, 2], r[:, 2], r[:, 3], r[:, 3]], 1)
    v = _frame_points(light, xs, ys, np.repeat(r[:, 4:5], 4, 1)).reshape(-1, 3)
    base = 4 * np.arange(r.shape[0])[:, None, None]
    t = (base + np.array([[0, 1, 2], [0, 2, 3]])[None]).reshape(-1, 3)
    return v, t


def ray_cast_visibility(light, rects, points, samples=64):
    """Reference visibility for rectangles parallel to the light, by a grid of light samples.

    Parameters
    ----------
    light : AreaLight
    rects : (R, 5) float array
        ``(x0, x1, y0, y1, d)`` in the light's frame: ``x`` along the tangent
        (width), ``y`` along the bitangent (height), ``d`` the distance along
        the normal.
    points : (P, 3) float array
        Receiver points behind the rectangles.
    samples : int
        Light samples per side (midpoint grid).

    Returns
    -------
    (P,) float64: the fraction of the ``samples²`` segments from the point to the
    light samples that miss every rectangle.
    """
    r = np.asarray(rects, np.float64).reshape(-1, 5)
    p = np.asarray(points, np.float64).reshape(-1, 3) - light.center
    px, py, pd = p @ light.tangent, p @ light.bitangent, p @ light.normal
    g = (np.arange(samples) + 0.5) / samples - 0.5
    # The grid is separable: sample (i, j) sits at (g_i·width, g_j·height), so where a segment
    # crosses a rectangle's plane its x depends on (point, i) only and its y on (point, j) only;
    # a hit is the outer product of the two interval tests.
    sx, sy = g * light.width, g * light.height
    vis = np.empty(p.shape[0])
    for lo in range(0, p.shape[0], 2048):  # chunks of points
        sl = slice(lo, lo + 2048)
        hit = np.zeros((px[sl].shape[0], samples, samples), bool)
        both = np.empty_like(hit)  # one rectangle's hits, reused
        for x0, x1, y0, y1, d in r:  # loop over rectangles
            t = (d / pd[sl])[:, None]  # where the segment crosses the rectangle's plane
            xx = sx + (px[sl, None] - sx) * t
            yy = sy + (py[sl, None] - sy) * t
            in_x = (t < 1) & (xx >= x0) & (xx <= x1)
            in_y = (yy >= y0) & (yy <= y1)
            hit |= np.logical_and(in_x[:, :, None], in_y[:, None, :], out=both)
        vis[sl] = 1 - hit.reshape(hit.shape[0], -1).mean(1)
    return vis


def _artifact_setup(size):
    from ...scene import AreaLight

    light = AreaLight(**_ART_LIGHT)
    vp = perspective(light.fov, 1.0, _ART_NEAR, _ART_FAR) @ look_at(light.center, light.center + light.normal,
                                                                     light.bitangent)
    return light, vp


def _transition_width(x, v, lo=0.1, hi=0.9):
    """Distance between the first crossings of ``lo`` and ``hi`` of an increasing profile (NaN if not reached)."""
    if not (v >= hi).any() or not (v >= lo).any():
        return float("nan")
    i_lo = np.argmax(v >= lo)
    i_hi = np.argmax(v >= hi)
    def cross(i, level):
        if i == 0:
            return x[0]
        return x[i - 1] + (level - v[i - 1]) * (x[i] - x[i - 1]) / (v[i] - v[i - 1])
    return float(cross(i_hi, hi) - cross(i_lo, lo))


def artifact_measurements(size=256, max_kernel=64, grid=96, samples=64):
    """Measure the two artifacts of the slides on synthetic scenes with exact references.

    Scenes (:data:`ARTIFACT_SCENES`): a 1.0 × 0.6 light, receiver plane at
    distance 4, a 60° map of ``size²`` texels with near 0.5 and far 5.

    * ``hole``: a plate at distance 3 with a 0.08 × 0.08 hole. The light
      through the hole is the light's image, a rectangle of aspect
      ``width/height`` (Slides: "Rectangular light rather obvious").
    * ``column`` / ``column_wall``: a column at distance 3.6, alone and with a
      wall at distance 3 that does not shadow the measured receiver points but
      lies in their blocker-search regions (Slides: "The shadow of the distant
      wall makes the shadow of the nearby column softer").

    Returns
    -------
    dict with the images (``hole_msm``, ``hole_reference``: (grid, grid)
    visibility over [−0.5, 0.5]²), the column profiles (``profile_x`` and
    ``profile_*``) and the measured numbers: ``hole_aspect_msm`` /
    ``hole_aspect_reference`` (ratio of the lit spot's extents at half
    maximum along x and y), ``hole_fill_msm`` (lit area at half maximum over
    the product of those extents: 1 for a rectangle, π/4 for an ellipse),
    ``width_column``, ``width_column_wall`` (10 %–90 % transition width of
    msm_soft), ``width_reference`` (of the reference, which the wall does not
    change: ``wall_changes_reference`` is its largest effect on the profile).
    """
    light, vp = _artifact_setup(size)
    out = {}
    # Small hole.
    v, t = _rect_mesh(light, ARTIFACT_SCENES["hole"])
    dm, _ = rasterize_depth(v, t, vp, size)
    xs = np.linspace(-0.5, 0.5, grid)
    gx, gy = np.meshgrid(xs, xs)
    pts = _frame_points(light, gx, gy, _ART_RECEIVER).reshape(-1, 3)
    tex = prepare(dm, light, vp, max_kernel)
    vis = shade_points(light, tex, pts, clip_from_world=vp).reshape(grid, grid)
    ref = ray_cast_visibility(light, ARTIFACT_SCENES["hole"], pts, samples).reshape(grid, grid)
    step = xs[1] - xs[0]
    for name, im in (("msm", vis), ("reference", ref)):
        lit = im >= 0.5 * im.max()
        ex = lit.any(0).sum() * step
        ey = lit.any(1).sum() * step
        out[f"hole_aspect_{name}"] = float(ex / ey)
        out[f"hole_fill_{name}"] = float(lit.sum() * step * step / (ex * ey))
        out[f"hole_{name}"] = im
    # Column with and without the wall.
    # The wall shadows no receiver point with x < 0.073 (s ≥ 0.72 − 3x > 0.5 for every light sample s).
    px = np.linspace(-0.4, 0.07, 236)
    prof = _frame_points(light, px, 0.0 * px, _ART_RECEIVER)
    out["profile_x"] = px
    for key in ("column", "column_wall"):
        v, t = _rect_mesh(light, ARTIFACT_SCENES[key])
        dm, _ = rasterize_depth(v, t, vp, size)
        vis, info = shade_points(light, dm, prof, clip_from_world=vp, max_kernel=max_kernel, details=True)
        out[f"profile_{key}"] = vis
        out[f"profile_{key}_reference"] = ray_cast_visibility(light, ARTIFACT_SCENES[key], prof, samples)
        out[f"width_{key}"] = _transition_width(px, vis)
        out[f"blocker_depth_{key}"] = info["blocker_view_depth"]
    out["width_reference"] = _transition_width(px, out["profile_column_reference"])
    out["wall_changes_reference"] = float(np.abs(out["profile_column_wall_reference"]
                                                 - out["profile_column_reference"]).max())
    return out


def artifact_images(out_dir, size=256, max_kernel=64):
    """Write ``msm_soft_artifacts.png`` and ``msm_soft_artifacts.md`` (measured statements) to ``out_dir``.

    Returns the measurements of :func:`artifact_measurements` and the paths written.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from pathlib import Path

    from ..._io import save_figure, write_text

    m = artifact_measurements(size=size, max_kernel=max_kernel)
    fig, ax = plt.subplots(1, 3, figsize=(13, 4), constrained_layout=True)
    ext = (-0.5, 0.5, -0.5, 0.5)
    im0 = ax[0].imshow(m["hole_msm"], cmap="gray", vmin=0, vmax=max(m["hole_msm"].max(), 1e-9), extent=ext,
                       origin="lower")
    ax[0].set_title(f"msm_soft: light through a 0.08² hole\naspect {m['hole_aspect_msm']:.2f}, "
                    f"fill {m['hole_fill_msm']:.2f}", fontsize=9)
    im1 = ax[1].imshow(m["hole_reference"], cmap="gray", vmin=0, vmax=max(m["hole_reference"].max(), 1e-9),
                       extent=ext, origin="lower")
    for a, im in ((ax[0], im0), (ax[1], im1)):
        a.set_xlabel("receiver x (world units)")
        a.set_ylabel("receiver y (world units)")
        fig.colorbar(im, ax=a, shrink=0.85).set_label("visibility (1 = fully lit)", fontsize=8)
    ax[1].set_title(f"reference (1.0 × 0.6 light)\naspect {m['hole_aspect_reference']:.2f}", fontsize=9)
    x = m["profile_x"]
    ax[2].plot(x, m["profile_column_reference"], "k-", label="reference (with or without wall)")
    ax[2].plot(x, m["profile_column"], "b--", label=f"msm_soft, column only (width {m['width_column']:.3f})")
    ax[2].plot(x, m["profile_column_wall"], "r-",
               label=f"msm_soft, column + distant wall (width {m['width_column_wall']:.3f})")
    ax[2].set_xlabel("receiver x (world units)")
    ax[2].set_ylabel("visibility")
    ax[2].legend(fontsize=7)
    ax[2].set_title("a distant occluder softens a near shadow", fontsize=9)
    out = Path(out_dir)
    paths = [save_figure(fig, out / "msm_soft_artifacts.png", dpi=100)]
    plt.close(fig)
    text = "\n".join([
        "# Moment soft shadow mapping: the artifacts of the slides, measured", "",
        f"Map {size}², largest kernel {max_kernel}² ({precision_bits_text(max_kernel)}), light 1.0 × 0.6.", "",
        f"- Light through a small hole is the light's rectangle: lit-spot aspect {m['hole_aspect_msm']:.3f} "
        f"(reference {m['hole_aspect_reference']:.3f}, light 1.667), fill of its bounding box "
        f"{m['hole_fill_msm']:.3f} (1 = rectangle, 0.785 = ellipse).",
        f"- A distant wall softens the column's shadow: 10–90 % width {m['width_column']:.4f} without, "
        f"{m['width_column_wall']:.4f} with the wall; reference {m['width_reference']:.4f} in both cases "
        f"(the wall changes the reference profile by at most {m['wall_changes_reference']:.3g}).", ""])
    paths.append(write_text(out / "msm_soft_artifacts.md", text))
    return m, paths


def report_artifacts(out_dir):
    """The report's part: :func:`artifact_images` in ``out_dir`` and the markdown stating them.

    Returns ``(measurements, lines, paths)``.
    """
    from pathlib import Path

    a, paths = artifact_images(out_dir)
    png, md = (Path(p).name for p in paths)
    lines = ["### Artifacts of moment soft shadow mapping (Slides, 'Results for soft shadows')", "",
             f"![msm_soft artifacts]({png}) (details: [{md}]({md}))", "",
             f"- Light through a small hole takes the light's rectangular shape: lit-spot aspect "
             f"{a['hole_aspect_msm']:.3f} (reference {a['hole_aspect_reference']:.3f}), fill of its "
             f"bounding box {a['hole_fill_msm']:.3f} (1 = rectangle, 0.785 = ellipse).",
             f"- A distant wall in the blocker-search region softens a near column's shadow: 10–90 % "
             f"width {a['width_column']:.4f} without the wall, {a['width_column_wall']:.4f} with it; "
             f"reference {a['width_reference']:.4f} in both (the wall changes the reference by at most "
             f"{a['wall_changes_reference']:.3g}).", ""]
    return a, lines, paths
