"""``moments-ref vwss``: VWSS against MVR, naive warping and PCSS (VWSS §4, Tables 1–2).

For a scene with a rectangular area light this renders the receiver's visibility
with

* ``vwss``: layered points from the enlarged source view (back faces culled, the
  paper's setting), warped into N light-sample maps;
* ``vwss_nocull``: the same with back-face culling off (§3.1's "to increase accuracy");
* ``vwss_naive``: plain image warping (VWSS Figure 4 left, Figure 5 left): the
  nearest fragment per texel of the light's *centre* view at the samples'
  resolution, warped into every sample view; it misses data at disocclusions
  and beyond the centre view's field of view;
* ``mvr``: N rasterized maps with the same light samples;
* ``pcss``: one rasterized map from the light centre, 64-tap blocker search,
  96-tap PCF;

and measures the RMSE of the visibility (in [0, 1], over the receiver pixels of
the camera) against a reference: MVR with many light samples (its own Poisson
set). Times are wall-clock seconds of this NumPy implementation on one core,
not GPU times: they show how the costs scale, not the paper's milliseconds.

Near plane. All views use the light's own near plane ``z_n`` (VWSS Listing 1,
``light.nearZ``): the scene's ``params.light_near``
(:func:`moments_ref.techniques.vwss.lights.light_near`), or ``near=`` / ``--near``. It sets
the source view's resolution by Eq. (3) and bounds PCSS's blocker-search plane
(the nearest depth in PCSS's map, :func:`moments_ref.techniques.vwss.shading.pcss`).

Holes and bloat (VWSS §3.2, Figure 6) are measured per light sample against the
MVR map of the same view (:func:`coverage_difference`) on the first warp pass's
views and the outermost light sample.

Outputs (written atomically): ``vwss.csv``, ``vwss.md`` (table, parameters and
the claims table), ``claims.json`` (:mod:`moments_ref.claims` records built by
:mod:`moments_ref.techniques.vwss.paper`, the paper's figure beside ours), ``vwss.png``
(visibility and error images) and ``vwss_depth.png`` (one light sample's depth
maps and the coverage difference of Figure 6).

References
----------
VWSS : see docs/bib.md.
"""

from __future__ import annotations

import csv
import io
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..._arrays import InputError
from ...claims import markdown_table, write_json
from ...scene.depth import d_view_from_ndc
from ...scene.gbuffer import depth_gbuffer
from ...scene.raster import rasterize_depth
from .lights import depth_range, light_near, light_views
from .mvr import mvr_passes
from .points import center_view, generate_points, naive_points, source_view
from .shading import pcf_sum, pcss
from .warp import warp_passes
from . import paper

__all__ = ["COLUMNS", "SETTINGS", "subdivide", "Comparison", "coverage_difference", "run_detailed", "run", "main"]

COLUMNS = ("technique", "views", "points", "triangles", "rmse", "seconds_points", "seconds_depth",
           "seconds_lighting", "seconds_total")

#: Defaults of the full and the quick run.
SETTINGS = {
    "full": {"map_size": 1024, "views": (24, 128), "reference_views": 512, "camera": (640, 360),
             "views_per_pass": 8, "scaling_views": 12},
    "quick": {"map_size": 256, "views": (8,), "reference_views": 64, "camera": (192, 108),
              "views_per_pass": 8, "scaling_views": 4},
}


def subdivide(vertices, triangles):
    """Split every triangle into four at its edge midpoints (same surface, 4× triangles).

    Returns ``(vertices, triangles)``; midpoints are not shared between
    triangles (the surface and the winding are unchanged, which is all the
    triangle-count experiment needs).
    """
    v = np.asarray(vertices, np.float64)
    t = np.asarray(triangles, np.int64)
    a, b, c = v[t[:, 0]], v[t[:, 1]], v[t[:, 2]]
    ab, bc, ca = (a + b) / 2, (b + c) / 2, (c + a) / 2
    nv = np.stack([a, b, c, ab, bc, ca], 1).reshape(-1, 3)
    base = 6 * np.arange(t.shape[0])[:, None]
    local = np.array([[0, 3, 5], [3, 1, 4], [5, 4, 2], [3, 4, 5]])
    nt = (base[:, None, :] + local[None]).reshape(-1, 3)
    return nv, nt


@dataclass
class Comparison:
    """Everything :func:`run_detailed` measured."""

    rows: list
    statements: list
    settings: dict
    scaling: list = field(default_factory=list)
    convergence: list = field(default_factory=list)
    coverage: dict = field(default_factory=dict)
    leaks: dict = field(default_factory=dict)
    images: dict = field(default_factory=dict)
    depth_images: dict = field(default_factory=dict)
    mask: np.ndarray = None
    holes: dict = field(default_factory=dict)
    claims: list = field(default_factory=list)


def _rmse(a, b):
    return float(np.sqrt(np.mean((a - b) ** 2))) if a.size else float("nan")


def _shade_multiview(maps_iter, P, ls, bias, keep=None):
    """Consume (sel, maps) passes; return (visibility, depth seconds, lighting seconds, covered texels).

    ``keep`` (a dict whose keys are view indices) receives the maps of those views.
    """
    acc = np.zeros(P.shape[0])
    t_depth = t_light = 0.0
    covered = 0
    t0 = time.perf_counter()
    for sel, maps in maps_iter:
        t1 = time.perf_counter()
        t_depth += t1 - t0
        covered += int(np.count_nonzero(maps < 1))
        for j, i in enumerate(sel):
            if keep is not None and int(i) in keep:
                keep[int(i)] = maps[j].copy()
        acc += pcf_sum(P, maps, ls.clip_from_world[sel], ls.near, ls.far, bias)
        t0 = time.perf_counter()
        t_light += t0 - t1
    return acc / len(ls), t_depth, t_light, covered


def coverage_difference(warped, rasterized, near, far, bias):
    """Holes and bloat of warped maps against rasterized maps of the same views (VWSS §3.2, Figure 6).

    Parameters
    ----------
    warped, rasterized : (K, H, W) float arrays
        NDC depth maps (1 = empty) of the same K views.
    near, far : float
        The views' near and far distances.
    bias : float
        Depth tolerance in world units (the shading bias).

    Returns
    -------
    dict of (K,) float64 arrays, fractions of the texels the rasterized map covers:
    ``holes`` (the rasterized map has a surface, the warped map none or one more
    than ``bias`` farther: light would leak there) and ``bloat`` (the warped map
    has a surface more than ``bias`` nearer than the rasterized one, or where it
    has none: the shadow grows).
    """
    w = np.asarray(warped, np.float64)
    r = np.asarray(rasterized, np.float64)
    lw, lr = d_view_from_ndc(w, near, far), d_view_from_ndc(r, near, far)
    cov_r, cov_w = r < 1, w < 1
    holes = cov_r & (~cov_w | (lw > lr + bias))
    bloat = cov_w & (~cov_r | (lw < lr - bias))
    n = np.maximum(cov_r.sum(axis=(1, 2)), 1)
    return {"holes": holes.sum(axis=(1, 2)) / n, "bloat": bloat.sum(axis=(1, 2)) / n}


def _mvr_iter(v, t, ls, m, progress):
    for i, d, _ in mvr_passes(v, t, ls, m, progress=progress):
        yield np.array([i]), d[None]


def _times(fn, repeat):
    out = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        out.append(time.perf_counter() - t0)
    return out


def _scaling(sc, near, far, m, n_views, vpp, seed, progress):
    """Depth-map time over 2 view counts × 2 triangle counts (original, subdivided once).

    The three warp repeats alternate between the two meshes, so that a change of the
    machine's load during the experiment reaches both alike.
    """
    out = []
    meshes = [(sc.occluder.vertices, sc.occluder.triangles)]
    meshes.append(subdivide(*meshes[0]))
    counts = (n_views, 2 * n_views)
    if progress:
        from tqdm import tqdm

        counts = tqdm(counts, desc="scaling", unit="count", file=sys.stderr, disable=None, leave=False)
    for n in counts:
        ls = light_views(sc.light, n, near, far, seed=seed)
        src = source_view(ls, m)
        pcs, t_pts, warp_times = [], [], [[], []]
        for v, t in meshes:
            t0 = time.perf_counter()
            pcs.append(generate_points(v, t, src))
            t_pts.append(time.perf_counter() - t0)
        for _ in range(3):  # alternate the meshes
            for level, pc in enumerate(pcs):
                warp_times[level] += _times(lambda: [None for _ in warp_passes(pc.positions, ls, m, vpp)], 1)
        for level, (v, t) in enumerate(meshes):
            t_mvr = min(_times(lambda: [None for _ in mvr_passes(v, t, ls, m)], 1))
            out.append({"level": level, "triangles": int(t.shape[0]), "views": n, "points": len(pcs[level]),
                        "seconds_points": t_pts[level], "seconds_warp": min(warp_times[level]),
                        "seconds_warp_max": max(warp_times[level]), "seconds_mvr": t_mvr})
    return sorted(out, key=lambda x: (x["level"], x["views"]))


def _prepare(scene, views, quick, map_size, reference_views, camera_size, bias, seed, views_per_pass, near):
    """Load and check the scene; the settings, the light's near plane (and its rule), far and bias."""
    from ...scene import AreaLight, load_scene

    cfg = dict(SETTINGS["quick" if quick else "full"])
    if views is not None:
        cfg["views"] = (int(views),) if np.ndim(views) == 0 else tuple(int(v) for v in views)
    if any(v < 1 for v in cfg["views"]):
        raise InputError(f"views: expected positive light-sample counts, got {cfg['views']}")
    for key, val in (("map_size", map_size), ("reference_views", reference_views), ("camera", camera_size),
                     ("views_per_pass", views_per_pass)):
        if val is not None:
            cfg[key] = val
    sc = load_scene(scene)
    if not isinstance(sc.light, AreaLight):
        raise InputError(f"scene: expected a scene with an area light (type = \"area\"), "
                         f"got a {type(sc.light).__name__} in {sc.name!r}")
    if sc.occluder.n_triangles == 0:
        raise InputError(f"scene: {sc.name!r} has no occluder")
    zn = light_near(sc) if near is None else near
    rule = ("the scene's params.light_near" if near is None and zn is not None else
            "given (--near)" if near is not None else "just in front of the nearest occluder (the scene names no "
            "params.light_near)")
    near, far = depth_range(sc.light, sc.occluder.vertices, sc.receiver.vertices, near=zn)
    bias = 0.002 * far if bias is None else float(bias)
    cfg.update({"scene": sc.name, "near": near, "near_rule": rule, "far": far, "bias": bias, "seed": seed,
                "triangles": sc.occluder.n_triangles})
    return sc, cfg, near, far, bias


def _pcss_row(ls, c):
    """PCSS (64-tap blocker search, 96-tap PCF) from the light-centre map: its row and visibility."""
    t0 = time.perf_counter()
    dmap, _ = rasterize_depth(c["occ_v"], c["occ_t"], ls.center_clip_from_world(), c["m"])
    t_d = time.perf_counter() - t0
    vis = pcss(c["P"], dmap[..., 0], ls, c["bias"])
    t_l = time.perf_counter() - t0 - t_d
    return {"technique": "pcss", "views": 1, "points": 0, "triangles": c["n_tri"], "rmse": _rmse(vis, c["vis_ref"]),
            "seconds_points": 0.0, "seconds_depth": t_d, "seconds_lighting": t_l, "seconds_total": t_d + t_l}, vis


def _one_view_count(ls, src, cen, c):
    """VWSS (culled, not culled), naive warping and MVR with the light samples ``ls``.

    Returns ``(rows, visibility, first maps, covered texels, holes)``; holes and bloat
    compare the maps of the first warp pass's views and of the outermost sample with MVR's.
    """
    n, m, vpp = len(ls), c["m"], c["vpp"]
    outer = int(np.argmax(np.linalg.norm(ls.uv - 0.5, axis=1)))
    wanted = sorted(set(range(min(vpp, n))) | {outer})
    rows, vis, first, coverage, holes, kept = [], {}, {}, {}, {}, {}
    for tech, make in (("vwss", lambda: generate_points(c["occ_v"], c["occ_t"], src, cull_back_faces=True)),
                       ("vwss_nocull", lambda: generate_points(c["occ_v"], c["occ_t"], src, cull_back_faces=False)),
                       ("vwss_naive", lambda: naive_points(c["occ_v"], c["occ_t"], cen, cull_back_faces=True)),
                       ("mvr", None)):
        kept[tech] = dict.fromkeys(wanted)  # always view 0: the first maps
        if make is not None:
            t0 = time.perf_counter()
            pc = make()
            t_pts, n_pts = time.perf_counter() - t0, len(pc)
            it = warp_passes(pc.positions, ls, m, vpp, progress=c["progress"])
        else:
            t_pts, n_pts = 0.0, 0
            it = _mvr_iter(c["occ_v"], c["occ_t"], ls, m, c["progress"])
        v_, t_d, t_l, cov = _shade_multiview(it, c["P"], ls, c["bias"], kept[tech])
        rows.append({"technique": tech, "views": n, "points": n_pts, "triangles": c["n_tri"],
                     "rmse": _rmse(v_, c["vis_ref"]), "seconds_points": t_pts, "seconds_depth": t_d,
                     "seconds_lighting": t_l, "seconds_total": t_pts + t_d + t_l})
        coverage[(tech, n)] = cov
        vis[tech], first[tech] = v_, kept[tech][0]
    ras = np.stack([kept["mvr"][i] for i in wanted])
    for w in ("vwss", "vwss_nocull", "vwss_naive"):
        d = coverage_difference(np.stack([kept[w][i] for i in wanted]), ras, c["near"], c["far"], c["bias"])
        holes[(w, n)] = {"views": wanted, "outermost": outer, **{k: v.tolist() for k, v in d.items()}}
    return rows, vis, first, coverage, holes


def run_detailed(scene="knot", views=None, quick=False, out_dir=None, progress=True, map_size=None,
                 reference_views=None, camera_size=None, bias=None, seed=0, scaling=True,
                 views_per_pass=None, near=None) -> Comparison:
    """Run the comparison and return all measurements (:func:`run` returns only the rows).

    Parameters
    ----------
    scene : str or Path
        A shipped scene name or a scene file with an area light.
    views : int or sequence of int, optional
        Light-sample counts; default (24, 128), quick (8,).
    quick : bool
        Reduced sizes: 256² maps, 64 reference views, a 192×108 camera.
    out_dir : path, optional
        Write vwss.csv, vwss.md, vwss.png, vwss_depth.png there.
    progress : bool
        tqdm bars on stderr over the multi-view loops.
    map_size, reference_views, camera_size, views_per_pass
        Override the settings of :data:`SETTINGS`; ``camera_size`` is (width, height).
    bias : float, optional
        Depth bias in world units; default 0.002 × far.
    seed : int
        Seed of the light samples (the reference uses ``seed + 1000``).
    scaling : bool
        Run the 2 × 2 view-count × triangle-count timing experiment.
    near : float, optional
        The light's near plane ``z_n`` in world units (VWSS Listing 1's
        ``light.nearZ``); default the scene's ``params.light_near``, else just in
        front of the nearest occluder (:func:`moments_ref.techniques.vwss.lights.depth_range`).
    """
    sc, cfg, near, far, bias = _prepare(scene, views, quick, map_size, reference_views, camera_size, bias, seed,
                                        views_per_pass, near)
    m, vpp = int(cfg["map_size"]), int(cfg["views_per_pass"])
    occ_v, occ_t = sc.occluder.vertices, sc.occluder.triangles
    n_tri = int(occ_t.shape[0])

    # G-buffer of the camera view.
    cw, ch = (int(x) for x in cfg["camera"])
    from ...scene import Camera

    cam = Camera(sc.camera.eye, sc.camera.target, sc.camera.up, sc.camera.fov, (cw, ch), sc.camera.near,
                 sc.camera.far)
    gb = depth_gbuffer(sc.receiver.vertices, sc.receiver.triangles, cam.clip_from_world(), (ch, cw), occ_v, occ_t)
    P = gb.position
    if P.shape[0] == 0:
        raise InputError(f"scene: no receiver pixel is visible from the camera of {sc.name!r}")

    # Reference: MVR with many light samples (its own Poisson set).
    ls_ref = light_views(sc.light, int(cfg["reference_views"]), near, far, seed=seed + 1000)
    vis_ref, _, _, _ = _shade_multiview(_mvr_iter(occ_v, occ_t, ls_ref, m, progress), P, ls_ref, bias)

    ctx = {"occ_v": occ_v, "occ_t": occ_t, "near": near, "far": far, "m": m, "vpp": vpp, "bias": bias,
           "P": P, "progress": progress, "vis_ref": vis_ref, "n_tri": n_tri}
    rows, vis, first_maps, coverage, leaks, holes = [], {}, {}, {}, {}, {}
    n_max = max(cfg["views"])
    for n in cfg["views"]:
        ls = light_views(sc.light, n, near, far, seed=seed)
        src = source_view(ls, m)
        cfg["source_resolution"], cfg["source_distance"] = src.resolution, src.distance
        r_, v_, f_, c_, h_ = _one_view_count(ls, src, center_view(ls, m), ctx)
        rows += r_
        coverage.update(c_)
        holes.update(h_)
        if n == n_max:
            vis.update(v_)
            first_maps.update(f_)
    # PCSS from the light-centre map, with the same near plane.
    row, vis["pcss"] = _pcss_row(light_views(sc.light, 1, near, far, seed=seed), ctx)
    rows.append(row)
    vis["reference"] = vis_ref

    # Leaks against MVR with the same light samples (isolates warping from sampling).
    for tech in ("vwss", "vwss_nocull", "vwss_naive"):
        ex = vis[tech] - vis["mvr"]
        leaks[tech] = {"mean_excess": float(np.mean(np.maximum(ex, 0))),
                       "pixels_over_0.1": float(np.mean(ex > 0.1)),
                       "mean_difference": float(np.mean(ex))}
    scal = _scaling(sc, near, far, m, int(cfg["scaling_views"]), vpp, seed, progress) if scaling else []
    conv = [(r["views"], r["rmse"]) for r in rows if r["technique"] == "mvr"]
    res = Comparison(rows=rows, statements=[], settings=cfg, scaling=scal, convergence=conv,
                     coverage=coverage, leaks=leaks, mask=gb.receiver_mask, holes=holes)
    res.claims = paper.claims(res)
    res.statements = [(c.statement, c.verdict == "holds", c.why) for c in res.claims]
    img = np.full(gb.kind.shape, np.nan)
    for k, v_ in vis.items():
        im = img.copy()
        im[gb.receiver_mask] = v_
        res.images[k] = im
    res.images["_occluder"] = gb.occluder_mask
    res.depth_images = first_maps
    if out_dir is not None:
        write_outputs(res, out_dir)
    return res


def _csv(rows):
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=COLUMNS, lineterminator="\n")
    w.writeheader()
    for r in rows:
        w.writerow({k: (f"{r[k]:.6g}" if isinstance(r[k], float) else r[k]) for k in COLUMNS})
    return buf.getvalue()


def markdown(res) -> str:
    """The comparison as markdown: settings, table, claims, scaling, convergence."""
    c = res.settings
    lines = [f"# VWSS comparison: scene `{c['scene']}`", "",
             f"Maps {c['map_size']}² (source view {c['source_resolution']}², eye "
             f"{c['source_distance']:.4g} behind the light, VWSS Eqs. (1)–(3)), light samples "
             f"{', '.join(map(str, c['views']))}, reference MVR with {c['reference_views']} samples, camera "
             f"{c['camera'][0]}×{c['camera'][1]}, {c['triangles']} occluder triangles, near {c['near']:.4g}, "
             f"far {c['far']:.4g}, bias {c['bias']:.4g}, {c['views_per_pass']} views per warp pass.", "",
             "RMSE of the visibility in [0, 1] over receiver pixels against the reference. Seconds are "
             "NumPy wall-clock on one CPU core (not GPU times): compare their growth, not their size. "
             "G-buffer time is shared and not counted.", "",
             "| " + " | ".join(COLUMNS) + " |", "|" + "---|" * len(COLUMNS)]
    for r in res.rows:
        lines.append("| " + " | ".join(f"{r[k]:.4g}" if isinstance(r[k], float) else str(r[k])
                                       for k in COLUMNS) + " |")
    lines += ["", "`vwss_nocull` is an extra row: VWSS with back-face culling off (VWSS §3.1). `vwss_naive` "
              "warps the nearest surface of the light's centre view (VWSS Figure 5, left).", "",
              f"Near plane z_n = {c['near']:.4g} ({c['near_rule']}): the light-sample views, Eq. (3) and PCSS's "
              "map use the same value; PCSS's blocker search covers the light's projection on the plane of the "
              "nearest depth in its map (at least z_n).", "",
              "## The paper's claims, measured here (also `claims.json`)", "", markdown_table(res.claims)]
    if res.holes:
        lines += ["## Holes and bloat against MVR (same light samples)", "",
                  "Fractions of the texels MVR covers; views of the first warp pass and the outermost light sample.",
                  "", "| technique | N | views | holes mean | holes outermost | bloat mean | bloat outermost |",
                  "|---|---|---|---|---|---|---|"]
        for (tech, n), h in res.holes.items():
            o = h["views"].index(h["outermost"])
            lines.append(f"| {tech} | {n} | {len(h['views'])} | {np.mean(h['holes']):.4f} | {h['holes'][o]:.4f} | "
                         f"{np.mean(h['bloat']):.4f} | {h['bloat'][o]:.4f} |")
    if res.scaling:
        lines += ["", "## Depth-map time against views and triangles", "",
                  "| subdivision | triangles | views | points | points s | warp s | MVR s |", "|---|---|---|---|---|---|---|"]
        for x in res.scaling:
            lines.append(f"| {x['level']} | {x['triangles']} | {x['views']} | {x['points']} | "
                         f"{x['seconds_points']:.4f} | {x['seconds_warp']:.4f} | {x['seconds_mvr']:.4f} |")
    lines += ["", "Images: `vwss.png` (visibility and |error|), `vwss_depth.png` (light sample 0: depth maps "
              "and where warped and rasterized coverage differ).", ""]
    return "\n".join(lines)


def write_outputs(res, out_dir):
    """Write vwss.csv, vwss.md, vwss.png and vwss_depth.png into ``out_dir`` (atomically)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ..._io import save_figure, write_text

    out = Path(out_dir)
    paths = [write_text(out / "vwss.csv", _csv(res.rows)), write_text(out / "vwss.md", markdown(res)),
             write_json(res.claims, out / "claims.json")]
    names = ["reference", "vwss", "vwss_naive", "mvr", "pcss"]
    fig, axes = plt.subplots(2, len(names), figsize=(3.2 * len(names), 4.6), constrained_layout=True)
    occ = res.images["_occluder"]
    for j, k in enumerate(names):
        im = res.images[k]
        rgb = np.dstack([np.nan_to_num(im, nan=1.0)] * 3)
        rgb[occ] = (0.85, 0.55, 0.3)
        axes[0, j].imshow(rgb, interpolation="nearest")
        axes[0, j].set_title(k, fontsize=9)
        err = np.abs(im - res.images["reference"])
        h = axes[1, j].imshow(err, cmap="magma", vmin=0, vmax=0.5, interpolation="nearest")
        axes[1, j].set_title(f"|{k} - reference|", fontsize=8)
    for a in axes.ravel():
        a.set_axis_off()
    fig.colorbar(h, ax=axes[1, :], shrink=0.8)
    paths.append(save_figure(fig, out / "vwss.png", dpi=110))
    plt.close(fig)
    d = res.depth_images
    fig, axes = plt.subplots(1, 5, figsize=(16, 3.6), constrained_layout=True)
    for a, k in zip(axes, ("mvr", "vwss", "vwss_nocull", "vwss_naive")):
        a.imshow(d[k], cmap="viridis", vmin=float(np.min(d["mvr"])), vmax=1, interpolation="nearest")
        a.set_title(f"{k}: light sample 0", fontsize=9)
    diff = np.ones(d["mvr"].shape + (3,))
    cw, cm = d["vwss"] < 1, d["mvr"] < 1
    diff[cw & cm] = 0.7
    diff[cw & ~cm] = (0.9, 0.1, 0.1)
    diff[cm & ~cw] = (0.1, 0.2, 0.9)
    axes[4].imshow(diff, interpolation="nearest")
    axes[4].set_title("red: only warped (bloat), blue: only MVR", fontsize=9)
    for a in axes:
        a.set_axis_off()
    paths.append(save_figure(fig, out / "vwss_depth.png", dpi=100))
    plt.close(fig)
    return paths


def run(scene="knot", views=None, quick=False, out_dir=None, progress=True, **kwargs):
    """Run the comparison; return the CSV rows (dicts with :data:`COLUMNS`). See :func:`run_detailed`."""
    return run_detailed(scene=scene, views=views, quick=quick, out_dir=out_dir, progress=progress, **kwargs).rows


def main(args) -> int:
    """``moments-ref vwss``: ``args`` has ``scene`` (name or file), ``views`` (int or None),
    ``quick`` (bool), ``near`` (float or None) and ``out`` (folder). Returns exit code 0."""
    res = run_detailed(scene=getattr(args, "scene", None) or "knot", views=getattr(args, "views", None),
                       quick=bool(getattr(args, "quick", False)), out_dir=args.out, progress=True,
                       near=getattr(args, "near", None))
    for c in res.claims:
        print(f"[{c.verdict}] {c.id}: paper {c.paper}; measured {c.measured}. {c.why}")
    print(f"wrote {Path(args.out) / 'vwss.csv'}, vwss.md, claims.json, vwss.png, vwss_depth.png")
    return 0
