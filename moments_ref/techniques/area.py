"""Area lights: the MVR reference of the soft-shadow techniques, their settings and shared stages.

The soft-shadow techniques (:mod:`moments_ref.techniques.msm_soft`, and PCSS,
VWSS and MVR in :mod:`moments_ref.techniques.soft`) shade the
receiver pixels of the camera view (``light_projection``) under a rectangular
area light and are measured against multi-view rasterization (MVR) with many
light samples, the reference of VWSS §4 (reference ``mvr``,
:data:`MVR_REFERENCE`). Their stages:

==========================  ======================================================
``area_center_view``        the light's centre view (``vwss.light_views`` with one
                            sample: the projection, near and far)
``area_center_depth_map``   one depth map from the light's centre
                            (``LightSamples.center_clip_from_world()``), shared by
                            msm_soft and PCSS
``shade_pcss``              :func:`moments_ref.techniques.vwss.pcss` (64-tap blocker search,
                            96-tap PCF) on the centre map
``vwss_light_samples``      the N Poisson-disk light samples and their views
``vwss_points``             layered points from the enlarged source view (VWSS
                            §3.1, :func:`moments_ref.techniques.vwss.generate_points`)
``vwss_warp``               the points warped into the N light-sample maps
                            (VWSS §3.2, :func:`moments_ref.techniques.vwss.warp.warp`)
``shade_vwss``              5-tap PCF in every map, averaged
                            (:func:`moments_ref.techniques.vwss.multiview_visibility`)
``mvr_vwss``                the N light-sample maps rasterized (only for ``mvr``)
``shade_mvr_vwss``          5-tap PCF in those maps
``mvr_reference_vwss``      the reference: MVR with R light samples of their own
                            Poisson set, each map shaded as it is rasterized
==========================  ======================================================

The texel cost of ``pcss`` is the centre map, of ``vwss`` ``vwss_points +
vwss_warp``, of ``mvr`` ``mvr_vwss``; the fragment cost is the ``shade_`` stage
(choosing the light samples and views is set-up, counted in neither, like the
camera G-buffer). Shadow intensity is ``1 − visibility`` for these outputs and
for the reference. A stage name contains ``vwss`` only for multi-view work.

References
----------
.. [1] VWSS: Adam Marrs, Benjamin Watson and Christopher Healey. 2018. *View-warped Multi-view Soft
       Shadowing for Local Area Lights*. Journal of Computer Graphics Techniques (JCGT) 7, 3, 1–28.
       http://jcgt.org/published/0007/03/01/
.. [2] Slides: Christoph Peters. *Rendering antialiased shadows with moment shadow mapping*,
       lecture slides (PDF version, with notes) on moment shadow mapping, translucent occluders,
       moment soft shadow mapping and prefiltered single scattering; http://MomentsInGraphics.de/.
       Cited by slide title, e.g. Slides, "Bias the moments".
"""

from __future__ import annotations

import numpy as np

from .._arrays import positive_int
from ..claims import find_row
from ..scene.raster import rasterize_depth
from .vwss import depth_range, light_near, light_views
from .vwss.mvr import mvr_visibility
from ._interface import Reference, Stage, reduced_settings, register_reference
from ._errormaps import error_maps, visibility_maps
from .references import intensity_metric

__all__ = ["AREA_SETTINGS", "area_settings", "configure", "soft_statements", "soft_figure", "MVR_REFERENCE",
           "CENTER_MAP", "LIGHT_SAMPLES", "center_map_stages", "samples_stage"]

#: Settings of the area-light techniques (:func:`configure`).
AREA_SETTINGS = ("map_size", "light_samples", "reference_views", "views_per_pass", "seed", "bias", "near")
#: Keys of the shared stages.
CENTER_VIEW, CENTER_MAP, LIGHT_SAMPLES = "area_center_view", "area_center_depth_map", "vwss_light_samples"


def area_settings(scene, full=False, *, map_size=None, light_samples=None, reference_views=None):
    """Settings of the area-light outputs (msm_soft, PCSS, VWSS, MVR and the MVR reference).

    Parameters
    ----------
    scene : Scene with an area light
    full : bool
        Paper scale (VWSS §4, Table 1): maps of the scene's ``shadow_map_size``
        (knot: 1024²), a reference of 512 light samples. Otherwise the reduced
        run: maps of :func:`moments_ref.pipeline.reduced_settings` (knot: 512²), 64 reference samples.
    map_size, light_samples, reference_views : int, optional
        Overrides. ``light_samples`` (N, the VWSS and MVR maps) defaults to the
        scene's ``params.light_samples`` or 24 (VWSS Table 1) in both modes.

    Returns
    -------
    dict with ``map_size``, ``light_samples``, ``reference_views``,
    ``views_per_pass`` (8, warp passes as ``moments-ref vwss``) and ``seed`` (0;
    the reference uses ``seed + 1000``, as ``moments-ref vwss``, :mod:`moments_ref.report.vwss`).
    """
    size = tuple(scene.shadow_map_size) if full else reduced_settings(scene)[0]
    cfg = {"map_size": int(max(size)), "light_samples": int((scene.params or {}).get("light_samples", 24)),
           "reference_views": 512 if full else 64, "views_per_pass": 8, "seed": 0}
    for key, val in (("map_size", map_size), ("light_samples", light_samples),
                     ("reference_views", reference_views)):
        if val is not None:
            cfg[key] = positive_int(val, key, "area")
    return cfg


def configure(ctx, overrides):
    """The settings of one run: :func:`area_settings` plus ``near``, ``far`` and ``bias`` (world units).

    Maps of the run's shadow-map size, a reference of 64 light samples (512 with
    ``ctx.full``). ``near`` is the light's near plane ``z_n`` (default the scene's
    ``params.light_near``, else just in front of the nearest occluder:
    :func:`moments_ref.techniques.vwss.lights.depth_range`); ``bias`` defaults to
    ``0.002 · far``, as ``moments-ref vwss``.
    """
    scene = ctx.scene
    cfg = {"map_size": int(max(ctx.size)), "light_samples": int((scene.params or {}).get("light_samples", 24)),
           "reference_views": 512 if ctx.full else 64, "views_per_pass": 8, "seed": 0, "bias": None, "near": None}
    cfg.update({k: v for k, v in overrides.items() if v is not None})
    for key in ("map_size", "light_samples", "reference_views", "views_per_pass"):
        cfg[key] = positive_int(cfg[key], key, "area")
    occ = scene.occluder_mesh(translucent=False)
    zn = light_near(scene) if cfg["near"] is None else float(cfg["near"])
    near, far = depth_range(scene.light, occ.vertices, scene.receiver.vertices, near=zn)
    # World-space depth bias along the light normal: the default of `moments-ref vwss`.
    bias = 0.002 * far if cfg["bias"] is None else float(cfg["bias"])
    cfg.update({"near": near, "far": far, "bias": bias})
    return cfg


# ---------------------------------------------------------------------------
# stages (module-level functions: equal keys are equal steps)


def _occluder(scene):
    return scene.occluder_mesh(translucent=False)


def _center_view(scene, cfg):
    # One light sample is enough: only the shared projection, near and far are used.
    return light_views(scene.light, 1, cfg["near"], cfg["far"], seed=int(cfg["seed"]))


def _center_map(ls1, scene, cfg):
    occ = _occluder(scene)
    return ls1, rasterize_depth(occ.vertices, occ.triangles, ls1.center_clip_from_world(), cfg["map_size"])[0]


def _light_samples(scene, cfg):
    return light_views(scene.light, cfg["light_samples"], cfg["near"], cfg["far"], seed=int(cfg["seed"]))


def _reference_visibility(gb, scene, cfg):
    occ = _occluder(scene)
    ls_ref = light_views(scene.light, cfg["reference_views"], cfg["near"], cfg["far"], seed=int(cfg["seed"]) + 1000)
    return mvr_visibility(occ.vertices, occ.triangles, ls_ref, cfg["map_size"], gb.position, cfg["bias"])


def center_map_stages(ctx, cfg):
    """The centre view and its depth map (shared by msm_soft and PCSS)."""
    bound = (("scene", ctx.scene), ("cfg", cfg))
    return (Stage(CENTER_VIEW, _center_view, bound=bound),
            Stage(CENTER_MAP, _center_map, (CENTER_VIEW,), bound=bound))


def samples_stage(ctx, cfg):
    """The N light samples and their views (VWSS and MVR)."""
    return Stage(LIGHT_SAMPLES, _light_samples, bound=(("scene", ctx.scene), ("cfg", cfg)))


def _reference_stage(ctx, cfg, technique):
    return Stage("mvr_reference_vwss", _reference_visibility, (ctx.receivers,),
                 bound=(("scene", ctx.scene), ("cfg", cfg)))


# ---------------------------------------------------------------------------
# the report's part: statements, figure, section


def soft_statements(rows, scene):
    """Measured statements on the area-light rows of ``scene`` (RMSE against the MVR reference).

    Returns a list of strings, empty when the scene has no such rows. Every
    number comes from ``rows``; comparisons are stated as measured (ratios),
    not assumed.
    """
    r = {t: find_row(rows, scene, t) for t in ("msm_soft", "pcss", "vwss", "mvr")}
    r = {t: v for t, v in r.items() if v is not None}
    if not r:
        return []
    out = []
    rm = {t: v["rmse"] for t, v in r.items()}
    out.append("RMSE of the shadow intensity against the MVR reference: "
               + ", ".join(f"{t} {v:.4g}" for t, v in rm.items())
               + "; ranked from lowest: " + " < ".join(sorted((t for t in rm if np.isfinite(rm[t])), key=rm.get))
               + ".")

    def ratio(a, b, text):
        if a in rm and b in rm and np.isfinite(rm[a]) and np.isfinite(rm[b]) and rm[b] > 0:
            q = rm[a] / rm[b]
            word = "below" if q < 1 else ("equal to" if q == 1 else "above")
            out.append(f"{a}'s RMSE is {word} {b}'s (ratio {q:.2f}){text}.")

    ratio("msm_soft", "pcss", ": moment soft shadow mapping against PCSS from the same single centre map")
    ratio("vwss", "pcss", " (VWSS §4 reports VWSS well below PCSS)")
    ratio("msm_soft", "vwss", "")
    ratio("vwss", "mvr", ": the error VWSS adds to MVR with the same light samples, whose own RMSE is the "
          "error of the light sampling alone")
    out.append("Seconds (texel + fragment, NumPy): "
               + ", ".join(f"{t} {v['texel_seconds']:.3g} + {v['fragment_seconds']:.3g}" for t, v in r.items())
               + ".")
    return out


def soft_figure(result, names):
    """Visibility (1 − intensity) of the MVR reference and of each area-light row on the camera view.

    :func:`._errormaps.visibility_maps`: one grey scale with its colour bar, occluders and pixels
    without a receiver in documented colours.
    """
    return visibility_maps(result, names, "MVR reference", f"{result.scene.name}: visibility under the area "
                           f"light (camera view, {result.gbuffer.resolution[0]}×{result.gbuffer.resolution[1]} "
                           "pixels)")


def _figures(result, names):
    return {f"soft_{result.scene.name}.png": soft_figure(result, names),
            f"errors_soft_{result.scene.name}.png": error_maps(
                result, names, "MVR", f"{result.scene.name}: signed error against multi-view rasterization (MVR)")}


def _section(settings, statements, images):
    lines = ["## Soft shadows under area lights (measured)", "",
             "Rows msm_soft (moment soft shadow mapping: one map from the light's centre, summed-area "
             "table of moments, moment-based blocker search; Slides, 'Moment soft shadow mapping'), "
             "pcss (the same centre map, 64-tap blocker search, 96-tap PCF), vwss (layered points from "
             "the enlarged source view warped into N light-sample maps, 5-tap PCF in each; VWSS §3) and "
             "mvr (the same N maps rasterized). Error: shadow intensity 1 − visibility against MVR with "
             "the reference's own Poisson set of light samples, over the receiver pixels of the camera "
             "view (the same pixels as the hard-shadow rows). texel_seconds: depth-map and texture "
             "stages; fragment_seconds: lookups.", "",
             "| scene | soft-shadow maps | light samples (vwss, mvr) | MVR reference samples | "
             "near | far | bias (world) |", "|---|---|---|---|---|---|---|"]
    for s, a in settings.items():
        lines.append(f"| {s} | {a['map_size']}² | {a['light_samples']} | {a['reference_views']} | "
                     f"{a['near']:.4g} | {a['far']:.4g} | {a['bias']:.3g} |")
    lines.append("")
    for s, st in statements.items():
        a = settings.get(s, {})
        lines += [f"**{s}** ({a.get('map_size', '?')}² maps, N = {a.get('light_samples', '?')}, reference MVR "
                  f"with {a.get('reference_views', '?')} light samples): " + " ".join(st), ""]
    for p in images:
        lines += [f"![visibility]({p})", ""]
    return lines


#: Multi-view rasterization with many light samples (VWSS §4): the reference of the soft shadows.
MVR_REFERENCE = register_reference(Reference(
    name="mvr", label="area-light outputs", stage=_reference_stage, metric=intensity_metric, option="area",
    configure=configure, settings_keys=AREA_SETTINGS, figures=_figures, statements=soft_statements,
    section=_section, result="visibility",
))
