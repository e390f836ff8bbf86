"""The soft-shadow techniques of VWSS §4's comparison: PCSS, VWSS and MVR with N light samples.

Registered with reference ``mvr`` (:mod:`moments_ref.techniques.area`, which
lists their stages). They shade world points of the receivers under an area
light, not shadow-map texels: their ``shadow`` refuses texel lookups, and the
pipeline runs their stages.

References
----------
VWSS : see docs/bib.md. PCSS: Fernando 2005, cited in place.
"""

from __future__ import annotations

from .._arrays import InputError
from .vwss import generate_points, multiview_visibility, pcss, source_view
from .vwss.mvr import mvr
from .vwss.warp import warp
from ._interface import PROJECTION, Plan, Stage, Technique, register
from .area import CENTER_MAP, LIGHT_SAMPLES, _occluder, center_map_stages, samples_stage

__all__ = ["PCSS", "VWSS", "MVR"]


def _shade_pcss(c, gb, bias):
    return 1.0 - pcss(gb.position, c[1][..., 0], c[0], bias)


def _pcss_stages(technique, ctx, cfg):
    shade = Stage("shade_pcss", _shade_pcss, (CENTER_MAP, PROJECTION), bound=(("bias", cfg["bias"]),))
    return Plan(center_map_stages(ctx, cfg) + (shade,), (CENTER_MAP,), shade.key)


def _points(ls, scene, cfg):
    # Layered points of the enlarged source view (VWSS Eqs. (1)-(3), back faces culled).
    occ = _occluder(scene)
    return generate_points(occ.vertices, occ.triangles, source_view(ls, cfg["map_size"]))


def _warp(pc, ls, cfg):
    return warp(pc.positions, ls, cfg["map_size"], cfg["views_per_pass"])


def _shade_maps(maps, ls, gb, bias):
    return 1.0 - multiview_visibility(gb.position, maps, ls, bias)


def _vwss_stages(technique, ctx, cfg):
    bound = (("scene", ctx.scene), ("cfg", cfg))
    pts = Stage("vwss_points", _points, (LIGHT_SAMPLES,), bound=bound)
    wrp = Stage("vwss_warp", _warp, ("vwss_points", LIGHT_SAMPLES), bound=(("cfg", cfg),))
    shade = Stage("shade_vwss", _shade_maps, ("vwss_warp", LIGHT_SAMPLES, PROJECTION), bound=(("bias", cfg["bias"]),))
    # storage: one 32-bit depth map per light sample
    return Plan((samples_stage(ctx, cfg), pts, wrp, shade), (pts.key, wrp.key), shade.key,
                bits=32 * int(cfg["light_samples"]))


def _mvr_maps(ls, scene, cfg):
    occ = _occluder(scene)
    return mvr(occ.vertices, occ.triangles, ls, cfg["map_size"])[0]


def _mvr_stages(technique, ctx, cfg):
    maps = Stage("mvr_vwss", _mvr_maps, (LIGHT_SAMPLES,), bound=(("scene", ctx.scene), ("cfg", cfg)))
    shade = Stage("shade_mvr_vwss", _shade_maps, ("mvr_vwss", LIGHT_SAMPLES, PROJECTION),
                  bound=(("bias", cfg["bias"]),))
    return Plan((samples_stage(ctx, cfg), maps, shade), (maps.key,), shade.key, bits=32 * int(cfg["light_samples"]))


def _not_texel_lookup(name):
    def lookup(texture, uv, zf, noise):
        raise InputError(f"technique: {name!r} shades world points under an area light, not shadow-map texels; "
                         "run it through moments_ref.pipeline.run")
    return lookup


def _no_steps(samples, layered):
    return ()


def _area_technique(name, stages, description, reference, multiview):
    return register(Technique(
        name=name, bits_per_texel=32, depth_bias=0.0, make_steps=_no_steps, lookup=_not_texel_lookup(name),
        description=description, reference=reference, light_kinds=("area",), multiview=multiview,
        stages=stages, truth="mvr"))


#: PCSS on the centre map: one float32 map.
PCSS = _area_technique("pcss", _pcss_stages, "percentage-closer soft shadows: 64-tap blocker search, 96-tap PCF",
                       "Fernando 2005; VWSS §4", False)
#: VWSS: a float32 depth per texel of each of the N light-sample maps.
VWSS = _area_technique("vwss", _vwss_stages, "view-warped multi-view soft shadows: points warped into N maps",
                       "VWSS §3", True)
#: MVR with the same N light samples as VWSS (the error of the light sampling alone).
MVR = _area_technique("mvr", _mvr_stages, "multi-view rasterization with the N light samples of VWSS",
                      "VWSS §2.1", True)
