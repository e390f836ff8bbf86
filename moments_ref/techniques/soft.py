"""The soft-shadow techniques of VWSS §4's comparison: PCSS, VWSS and MVR with N light samples.

Registered with reference ``mvr`` (:mod:`moments_ref.techniques.area`, which
lists their stages). They shade world points of the receivers under an area
light, not shadow-map texels: their ``shadow`` refuses texel lookups, and the
pipeline runs their stages. Their shade stages hold the visibility (VWSS §4's
shading pass: the visible fraction of the light; ``Plan.result``), which the
pipeline reports as the shadow intensity ``1 − visibility``.

Two variants of VWSS that ``moments-ref vwss`` measures are built here but not
registered (the report does not run them): :data:`VWSS_NOCULL`, with back-face
culling off (VWSS §3.1, "to increase accuracy"), and :data:`VWSS_NAIVE`, plain
image warping of the light's centre view (VWSS Figure 4 left, Figure 5 left).

References
----------
.. [1] VWSS: Adam Marrs, Benjamin Watson and Christopher Healey. 2018. *View-warped Multi-view Soft
       Shadowing for Local Area Lights*. Journal of Computer Graphics Techniques (JCGT) 7, 3, 1–28.
       http://jcgt.org/published/0007/03/01/
.. [2] Fernando 2005: Randima Fernando. 2005. *Percentage-Closer Soft Shadows*. In ACM SIGGRAPH
       2005 Sketches. https://doi.org/10.1145/1187112.1187153 (PCSS)
"""

from __future__ import annotations

from .._arrays import InputError
from .vwss import center_view, generate_points, multiview_visibility, naive_points, pcss, source_view
from .vwss.mvr import mvr
from .vwss.warp import warp
from ._interface import Plan, Stage, Technique, register
from .area import CENTER_MAP, LIGHT_SAMPLES, center_map_stages, samples_stage

__all__ = ["PCSS", "VWSS", "MVR", "VWSS_NOCULL", "VWSS_NAIVE"]


def _occluder(scene):
    return scene.occluder_mesh(translucent=False)


def _shade_pcss(c, gb, bias):
    return pcss(gb.position, c[1][..., 0], c[0], bias)


def _pcss_stages(technique, ctx, cfg):
    shade = Stage("shade_pcss", _shade_pcss, (CENTER_MAP, ctx.receivers), bound=(("bias", cfg["bias"]),))
    return Plan(center_map_stages(ctx, cfg) + (shade,), (CENTER_MAP,), shade.key, result="visibility")


def _points(ls, scene, cfg):
    # Layered points of the enlarged source view (VWSS Eqs. (1)-(3), back faces culled).
    occ = _occluder(scene)
    return generate_points(occ.vertices, occ.triangles, source_view(ls, cfg["map_size"]))


def _points_nocull(ls, scene, cfg):
    occ = _occluder(scene)
    return generate_points(occ.vertices, occ.triangles, source_view(ls, cfg["map_size"]), cull_back_faces=False)


def _points_naive(ls, scene, cfg):
    # The nearest surface of the light's centre view at the samples' resolution.
    occ = _occluder(scene)
    return naive_points(occ.vertices, occ.triangles, center_view(ls, cfg["map_size"]), cull_back_faces=True)


def _warp(pc, ls, cfg):
    return warp(pc.positions, ls, cfg["map_size"], cfg["views_per_pass"])


def _shade_maps(maps, ls, gb, bias):
    return multiview_visibility(gb.position, maps, ls, bias)


def _warped_stages(points, variant=""):
    """The stages of VWSS with the point generation ``points``: points, warp into the N maps, 5-tap PCF."""
    suffix = f"_{variant}" if variant else ""

    def stages(technique, ctx, cfg):
        bound = (("scene", ctx.scene), ("cfg", cfg))
        pts = Stage(f"vwss_points{suffix}", points, (LIGHT_SAMPLES,), bound=bound)
        wrp = Stage(f"vwss_warp{suffix}", _warp, (pts.key, LIGHT_SAMPLES), bound=(("cfg", cfg),))
        shade = Stage(f"shade_{technique.name}", _shade_maps, (wrp.key, LIGHT_SAMPLES, ctx.receivers),
                      bound=(("bias", cfg["bias"]),))
        # storage: one 32-bit depth map per light sample
        return Plan((samples_stage(ctx, cfg), pts, wrp, shade), (pts.key, wrp.key), shade.key,
                    bits=32 * int(cfg["light_samples"]), result="visibility")

    return stages


def _mvr_maps(ls, scene, cfg):
    occ = _occluder(scene)
    return mvr(occ.vertices, occ.triangles, ls, cfg["map_size"])[0]


def _mvr_stages(technique, ctx, cfg):
    maps = Stage("mvr_vwss", _mvr_maps, (LIGHT_SAMPLES,), bound=(("scene", ctx.scene), ("cfg", cfg)))
    shade = Stage("shade_mvr_vwss", _shade_maps, ("mvr_vwss", LIGHT_SAMPLES, ctx.receivers),
                  bound=(("bias", cfg["bias"]),))
    return Plan((samples_stage(ctx, cfg), maps, shade), (maps.key,), shade.key, bits=32 * int(cfg["light_samples"]),
                result="visibility")


def _not_texel_lookup(name):
    def lookup(texture, uv, zf, noise):
        raise InputError(f"technique: {name!r} shades world points under an area light, not shadow-map texels; "
                         "run it through moments_ref.pipeline.run")
    return lookup


def _no_steps(samples, layered):
    return ()


def _area_technique(name, stages, description, reference, multiview, registered=True):
    t = Technique(name=name, bits_per_texel=32, depth_bias=0.0, make_steps=_no_steps, lookup=_not_texel_lookup(name),
                  description=description, reference=reference, light_kinds=("area",), multiview=multiview,
                  stages=stages, truth="mvr")
    return register(t) if registered else t


#: PCSS on the centre map: one float32 map.
PCSS = _area_technique("pcss", _pcss_stages, "percentage-closer soft shadows: 64-tap blocker search, 96-tap PCF",
                       "Fernando 2005; VWSS §4", False)
#: VWSS: a float32 depth per texel of each of the N light-sample maps.
VWSS = _area_technique("vwss", _warped_stages(_points), "view-warped multi-view soft shadows: points warped into N maps",
                       "VWSS §3", True)
#: MVR with the same N light samples as VWSS (the error of the light sampling alone).
MVR = _area_technique("mvr", _mvr_stages, "multi-view rasterization with the N light samples of VWSS",
                      "VWSS §2.1", True)
#: VWSS with back-face culling off (not registered: ``moments-ref vwss`` measures it).
VWSS_NOCULL = _area_technique("vwss_nocull", _warped_stages(_points_nocull, "nocull"),
                              "VWSS with back-face culling off", "VWSS §3.1", True, registered=False)
#: Naive image warping of the centre view (not registered: ``moments-ref vwss`` measures it).
VWSS_NAIVE = _area_technique("vwss_naive", _warped_stages(_points_naive, "naive"),
                             "naive image warping of the light's centre view", "VWSS Figures 4 and 5", True,
                             registered=False)
