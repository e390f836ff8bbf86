"""``moments-ref vwss``: VWSS against MVR, naive warping and PCSS (VWSS §4, Tables 1–2).

An experiment over :func:`moments_ref.pipeline.run`, as the report is: every row is
a technique of :mod:`moments_ref.techniques.soft` run through the pipeline with
the depth G-buffer (:func:`moments_ref.scene.gbuffer.depth_gbuffer`, VWSS §4's
deferred pass, every receiver pixel) and the MVR reference of
:mod:`moments_ref.techniques.area`; its settings are one
:class:`ComparisonSettings`.

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
(:func:`moments_ref.techniques.vwss.lights.light_near`), or ``near`` / ``--near``. It sets
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
.. [1] VWSS: Adam Marrs, Benjamin Watson and Christopher Healey. 2018. *View-warped Multi-view Soft
       Shadowing for Local Area Lights*. Journal of Computer Graphics Techniques (JCGT) 7, 3, 1–28.
       http://jcgt.org/published/0007/03/01/
"""

from __future__ import annotations

import csv
import dataclasses
import io
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .._arrays import InputError, positive_int
from .._shim import warn_renamed
from ..claims import markdown_table, to_json
from .. import pipeline
from ..scene.depth import d_view_from_ndc
from ..techniques.area import LIGHT_SAMPLES
from ..techniques.soft import MVR, PCSS, VWSS, VWSS_NAIVE, VWSS_NOCULL
from ..techniques.vwss import paper
from ..techniques.vwss.lights import light_near, light_views
from ..techniques.vwss.mvr import mvr_passes
from ..techniques.vwss.points import generate_points, source_view
from ..techniques.vwss.warp import warp_passes

__all__ = ["COLUMNS", "SETTINGS", "ComparisonSettings", "comparison_settings", "subdivide", "Comparison",
           "coverage_difference", "measure", "run_detailed", "run", "markdown", "write_outputs", "main"]

COLUMNS = ("technique", "views", "points", "triangles", "rmse", "seconds_points", "seconds_depth",
           "seconds_lighting", "seconds_total")

#: Defaults of the full and the quick run (:func:`comparison_settings`).
SETTINGS = {
    "full": {"map_size": 1024, "views": (24, 128), "reference_views": 512, "camera": (640, 360),
             "views_per_pass": 8, "scaling_views": 12},
    "quick": {"map_size": 256, "views": (8,), "reference_views": 64, "camera": (192, 108),
              "views_per_pass": 8, "scaling_views": 4},
}
#: The techniques of each light-sample count, in row order (PCSS, one map, follows once).
TECHNIQUES = (VWSS, VWSS_NOCULL, VWSS_NAIVE, MVR)


@dataclass(frozen=True)
class ComparisonSettings:
    """The settings of :func:`measure` (build them with :func:`comparison_settings`).

    Attributes
    ----------
    views : tuple of int, light-sample counts N (one run each)
    map_size : int, side of every depth map (and of the MVR reference's)
    reference_views : int, light samples of the MVR reference (its own Poisson set, seed + 1000)
    camera : (width, height), the G-buffer's resolution
    views_per_pass : int, maps rendered per traversal of the points (the warp's passes)
    scaling_views : int, the smaller view count of the view × triangle timing experiment
    bias : float, optional, depth bias in world units; default 0.002 × far
    seed : int, seed of the light samples
    near : float, optional, the light's near plane z_n (VWSS Listing 1's ``light.nearZ``);
        default the scene's ``params.light_near``, else just in front of the nearest occluder
    scaling : bool, run the 2 × 2 view-count × triangle-count timing experiment
    progress : bool, tqdm bars on stderr
    """

    views: tuple
    map_size: int
    reference_views: int
    camera: tuple
    views_per_pass: int
    scaling_views: int
    bias: float = None
    seed: int = 0
    near: float = None
    scaling: bool = True
    progress: bool = True


def comparison_settings(quick=False, **overrides) -> ComparisonSettings:
    """The full (VWSS Tables 1–2 scale) or quick preset of :data:`SETTINGS` with ``overrides`` (None keeps the preset's).

    ``overrides`` are fields of :class:`ComparisonSettings`; ``views`` may be one int.
    """
    names = {f.name for f in dataclasses.fields(ComparisonSettings)}
    over = {k: v for k, v in overrides.items() if v is not None}
    unknown = set(over) - names
    if unknown:
        raise InputError(f"settings: unknown {sorted(unknown)}; known: {', '.join(sorted(names))}")
    cfg = {**SETTINGS["quick" if quick else "full"], **over}
    views = cfg["views"]
    cfg["views"] = (int(views),) if np.ndim(views) == 0 else tuple(int(v) for v in views)
    if not cfg["views"] or any(v < 1 for v in cfg["views"]):
        raise InputError(f"views: expected positive light-sample counts, got {cfg['views']}")
    for key in ("map_size", "reference_views", "views_per_pass", "scaling_views"):
        cfg[key] = positive_int(cfg[key], key, "settings")
    return ComparisonSettings(**cfg)


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


def _area_scene(scene):
    """The loaded scene, refused unless it has an area light and an occluder."""
    from ..scene import AreaLight, load_scene

    sc = load_scene(scene)
    if not isinstance(sc.light, AreaLight):
        raise InputError(f"scene: expected a scene with an area light (type = \"area\"), "
                         f"got a {type(sc.light).__name__} in {sc.name!r}")
    if sc.occluder.n_triangles == 0:
        raise InputError(f"scene: {sc.name!r} has no occluder")
    return sc


def _pipeline_settings(cs, n, reference):
    """The pipeline's settings of one run: the depth G-buffer, maps and light samples of ``cs`` with N = ``n``."""
    area = {"map_size": cs.map_size, "light_samples": n, "reference_views": cs.reference_views,
            "views_per_pass": cs.views_per_pass, "seed": cs.seed, "bias": cs.bias, "near": cs.near}
    return pipeline.Settings(resolution=tuple(cs.camera), gbuffer="depth", reference=reference,
                             overrides={"area": area}, warmup=False, progress=cs.progress)


@dataclass
class _Run:
    """What the comparison keeps of one technique's pipeline run (its N maps are dropped).

    ``kept``: the maps of the views compared with MVR (:func:`_wanted`; view 0
    first); ``covered``: texels covered over all N maps.
    """

    vis: np.ndarray
    row: dict
    kept: np.ndarray = None
    covered: int = 0


def _wanted(samples, cs, n):
    """The views compared with MVR: those of the first warp pass and the outermost light sample (its index)."""
    outer = int(np.argmax(np.linalg.norm(samples.uv - 0.5, axis=1)))
    return sorted(set(range(min(cs.views_per_pass, n))) | {outer}), outer


def _technique_run(sc, tech, cs, n):
    """:func:`moments_ref.pipeline.run` of one technique (one at a time: its N maps are freed before the next)."""
    return _as_run(sc, tech, pipeline.run(sc, [tech], _pipeline_settings(cs, n, False)), cs, n)


def _as_run(sc, tech, r, cs, n):
    """The :class:`_Run` of technique ``tech`` in the pipeline result ``r``."""
    p = r.plans[tech.name]
    sec = r.seconds
    row = {"technique": tech.name, "views": n if tech is not PCSS else 1,
           "points": sum(len(r.values[k]) for k in p.texel[:-1]), "triangles": int(sc.occluder.triangles.shape[0]),
           "rmse": None, "seconds_points": float(sum(sec[k] for k in p.texel[:-1])),
           "seconds_depth": sec[p.texel[-1]], "seconds_lighting": sec[p.shade]}
    row["seconds_total"] = row["seconds_points"] + row["seconds_depth"] + row["seconds_lighting"]
    if tech is PCSS:
        return _Run(vis=r.values[p.shade], row=row)
    maps = r.values[p.texel[-1]]
    wanted, _ = _wanted(r.values[LIGHT_SAMPLES], cs, n)
    return _Run(vis=r.values[p.shade], row=row, kept=maps[wanted], covered=int(np.count_nonzero(maps < 1)))


def _holes(runs, samples, cs, n, cfg):
    """Holes and bloat of the warped maps against MVR's on the views compared (VWSS §3.2, Figure 6)."""
    wanted, outer = _wanted(samples, cs, n)
    return {(w, n): {"views": wanted, "outermost": outer,
                     **{k: v.tolist() for k, v in coverage_difference(runs[w].kept, runs["mvr"].kept, cfg["near"],
                                                                        cfg["far"], cfg["bias"]).items()}}
            for w in ("vwss", "vwss_nocull", "vwss_naive")}


def _reference(sc, cs):
    """The first pipeline run: PCSS from the light's centre and the MVR reference, on the depth G-buffer."""
    r = pipeline.run(sc, [PCSS], _pipeline_settings(cs, max(cs.views), True))
    if r.gbuffer.position.shape[0] == 0:
        raise InputError(f"scene: no receiver pixel is visible from the camera of {sc.name!r}")
    return r, r.values[r.plans["pcss"].reference]


def _settings_dict(sc, cs, area):
    """The settings as written in vwss.md and the claims (the preset's keys first, then what the run found)."""
    zn = light_near(sc)
    rule = ("the scene's params.light_near" if cs.near is None and zn is not None else
            "given (--near)" if cs.near is not None else "just in front of the nearest occluder (the scene names no "
            "params.light_near)")
    cfg = {k: getattr(cs, k) for k in ("map_size", "views", "reference_views", "camera", "views_per_pass",
                                       "scaling_views")}
    cfg.update({"scene": sc.name, "near": area["near"], "near_rule": rule, "far": area["far"], "bias": area["bias"],
                "seed": cs.seed, "triangles": sc.occluder.n_triangles})
    return cfg


def measure(scene="knot", settings: ComparisonSettings = None, out_dir=None) -> Comparison:
    """Run the comparison through the pipeline and return all measurements.

    Parameters
    ----------
    scene : str or Path
        A shipped scene name or a scene file with an area light.
    settings : ComparisonSettings, optional
        Default :func:`comparison_settings` (the full run).
    out_dir : path, optional
        Write vwss.csv, vwss.md, claims.json, vwss.png, vwss_depth.png there.
    """
    cs = comparison_settings() if settings is None else settings
    sc = _area_scene(scene)
    first, vis_ref = _reference(sc, cs)
    cfg = _settings_dict(sc, cs, first.settings["mvr"])
    gb = first.gbuffer
    rows, vis, first_maps, coverage, holes = [], {}, {}, {}, {}
    for n in cs.views:
        runs = {t.name: _technique_run(sc, t, cs, n) for t in TECHNIQUES}
        ls = light_views(sc.light, n, cfg["near"], cfg["far"], seed=cs.seed)  # the runs' light samples
        for name, t in runs.items():
            t.row["rmse"] = _rmse(t.vis, vis_ref)
            rows.append(t.row)
            coverage[(name, n)] = t.covered
        holes.update(_holes(runs, ls, cs, n, cfg))
        src = source_view(ls, cs.map_size)
        cfg["source_resolution"], cfg["source_distance"] = src.resolution, src.distance
        if n == max(cs.views):
            vis.update({name: t.vis for name, t in runs.items()})
            first_maps.update({name: t.kept[0] for name, t in runs.items()})  # view 0 is always kept
    pcss_run = _as_run(sc, PCSS, first, cs, max(cs.views))  # PCSS from the light's centre, with the same near plane
    pcss_run.row["rmse"] = _rmse(pcss_run.vis, vis_ref)
    rows.append(pcss_run.row)
    vis["pcss"], vis["reference"] = pcss_run.vis, vis_ref
    return _finish(sc, cs, cfg, gb, rows, vis, first_maps, coverage, holes, out_dir)


def _finish(sc, cs, cfg, gb, rows, vis, first_maps, coverage, holes, out_dir):
    """Leaks, the scaling experiment, the claims and the images; written to ``out_dir`` when given."""
    leaks = {}
    # Leaks against MVR with the same light samples (isolates warping from sampling).
    for tech in ("vwss", "vwss_nocull", "vwss_naive"):
        ex = vis[tech] - vis["mvr"]
        leaks[tech] = {"mean_excess": float(np.mean(np.maximum(ex, 0))),
                       "pixels_over_0.1": float(np.mean(ex > 0.1)),
                       "mean_difference": float(np.mean(ex))}
    scal = (_scaling(sc, cfg["near"], cfg["far"], cs.map_size, cs.scaling_views, cs.views_per_pass, cs.seed,
                     cs.progress) if cs.scaling else [])
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


#: The keyword arguments of the comparison before :class:`ComparisonSettings` (deprecated).
_OLD = ("views", "quick", "progress", "map_size", "reference_views", "camera_size", "bias", "seed", "scaling",
        "views_per_pass", "near")


def _old_settings(settings, old, fn):
    unknown = set(old) - set(_OLD)
    if unknown:
        raise TypeError(f"{fn}() got an unexpected keyword argument {sorted(unknown)[0]!r}")
    if not old:
        return settings
    warn_renamed(f"vwss.{fn}(scene, views=..., quick=..., ...)", f"vwss.{fn}(scene, comparison_settings(...))")
    kw = dict(old)
    quick = bool(kw.pop("quick", False))
    if "camera_size" in kw:
        kw["camera"] = kw.pop("camera_size")
    return comparison_settings(quick, **kw)


def run_detailed(scene="knot", settings=None, out_dir=None, **old) -> Comparison:
    """:func:`measure`; the old keyword arguments (``views=``, ``quick=``, ...) still work, deprecated."""
    return measure(scene, _old_settings(settings, old, "run_detailed"), out_dir)


def run(scene="knot", settings=None, out_dir=None, **old):
    """Run the comparison; return the CSV rows (dicts with :data:`COLUMNS`). See :func:`measure`."""
    return measure(scene, _old_settings(settings, old, "run"), out_dir).rows


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


#: The files :func:`write_outputs` writes.
OUTPUTS = ("vwss.csv", "vwss.md", "claims.json", "vwss.png", "vwss_depth.png")


def write_outputs(res, out_dir):
    """Write vwss.csv, vwss.md, claims.json, vwss.png and vwss_depth.png into ``out_dir``, all or none.

    Every file is made in memory first and the set is written by
    :func:`moments_ref._io.write_files`: a full disk leaves none of them behind.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from .._io import figure_png, write_files

    out = Path(out_dir)
    blobs = {"vwss.csv": _csv(res.rows), "vwss.md": markdown(res), "claims.json": to_json(res.claims)}
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
    blobs["vwss.png"] = figure_png(fig, dpi=110)
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
    blobs["vwss_depth.png"] = figure_png(fig, dpi=100)
    plt.close(fig)
    return write_files(out, blobs)


def main(args) -> int:
    """``moments-ref vwss``: ``args`` has ``scene`` (name or file), ``views`` (int or None),
    ``quick`` (bool), ``near`` (float or None) and ``out`` (folder). Returns exit code 0."""
    from .._io import check_own

    for name in OUTPUTS:  # a FIFO, device, link or folder in the way: refused before the measurement
        check_own(Path(args.out) / name)
        if (Path(args.out) / name).is_dir():
            raise InputError(f"--out: {Path(args.out) / name} is a folder; vwss writes its file there")
    cs = comparison_settings(bool(getattr(args, "quick", False)), views=getattr(args, "views", None),
                             near=getattr(args, "near", None))
    res = measure(getattr(args, "scene", None) or "knot", cs, out_dir=args.out)
    for c in res.claims:
        print(f"[{c.verdict}] {c.id}: paper {c.paper}; measured {c.measured}. {c.why}")
    print(f"wrote {Path(args.out) / 'vwss.csv'}, vwss.md, claims.json, vwss.png, vwss_depth.png")
    return 0
