"""Prefiltered single scattering with six moments (Slides, "Prefiltered single scattering").

Single scattering of a directional light in a homogeneous participating medium
(the setting the slides restrict to) needs, per pixel, the integral of the
light's visibility along the view ray,

    S(pixel) = ∫_0^{t_end} V(eye + t·ω_p) dt,

(in-scattered radiance = σ_s · phase(ω_l·ω_p) · E · S; the constant factors
are left out, and so is extinction along the view ray: with it the integrand's
weight would depend on the ray's inclination and prefix sums along rows could not
represent it). ``t_end`` is the distance to the surface the pixel sees, or
:attr:`EpipolarFrame.t_max` (the farthest corner of the scene's bounding box) for
background pixels.

Klehm et al. 2014: ray marching is percentage-closer filtering with the view ray
as kernel, so a filterable shadow map can be prefiltered along view rays. The
slides do it with six moments, in five steps:

1. **Epipolar resampling** (Slides, "Resampling using epipolar geometry"). Put the
   camera at the origin and the light direction ω_l on the z axis; a point with
   cylindrical radius ρ (distance from the light axis through the camera),
   azimuth φ and offset ``a`` along ω_l has inclination ``θ = atan2(ρ, a)``
   (the angle between ω_l and the direction from the camera). The new map has
   rows = φ (``v = φ``), columns = ρ (``u = r``: the radius of the polar
   coordinates of the shadow-map plane around the camera) and depth
   ``z' = π − θ``, stored normalized to [-1, 1] as ``z = 2z'/π − 1 = 1 − 2θ/π``.
   Each texel is one light ray; a view ray (fixed φ_p, θ_p) crosses the light
   rays ρ ∈ [0, t_end·sin θ_p] of its row, uniformly (``dt = dρ / sin θ_p``),
   and the point where it crosses light ray ρ is shadowed iff
   ``z_p > z_occ(ρ)`` (a point deeper along the light has a smaller
   inclination). So ``S = t_end · (1 − Z_row(z < z_p))`` with ``Z_row`` the
   distribution of the texel depths of the row prefix ``[0, ρ_end]``: "View rays
   are rows", the left column is the camera.

   *Without filtering* (Slides, "Resampling without filtering"): convert
   coordinates, sample the depth map (nearest texel, one sample, no filtering),
   convert the depth, six moments of that one depth. Aliased.

   *With filtering* (Slides, "Resampling with filtering"): sample the filtered
   four-moment map (:mod:`moments_ref.gpu.filtering`: MSAA resolve and the 9×9
   Gaussian, bilinear lookup), drop b4 and represent b1..b3 by two depths
   (HPG17 Algorithm 2, ``y1, y2, v2``), convert both depths, and combine
   ``(1 − v2)·b(z1) + v2·b(z2)`` (six moments each).

2. **Quantization** (Slides, "6 moments: 2×R10G10B10A2"): the optimized
   six-moment basis in 10-bit UNORM (:func:`moments_ref.affine.encode_r10g10b10a2`).
3. **Prefix sums along rows** (Slides, "Prefix sums along rows"), normalized to
   avoid overflow: texel k stores the *mean* of texels 0..k (a convex
   combination, so it stays a moment vector and fits the same UNORM format).
4. **Deferred pass** (Slides, "Deferred pass for single scattering"): per pixel
   two texture lookups (one per R10G10B10A2 texture) at row φ_p and column
   ρ_end; the column coordinate is warped so that the hardware's linear filter
   between prefix means k−1 and k returns exactly the mean over ``[0, ρ_end]``
   (see :func:`prefix_lookup_coordinate`). Six-moment bounds
   (:mod:`moments_ref.msm6`) of ``Z(z < z_p)``, biased with
   :data:`moments_ref.msm6.BIAS6_UNORM10`.
5. **Interpolation between the bounds** (Slides, "Interpolation between bounds",
   "Adaptive overestimation"): ``shadow = β·lower + (1 − β)·upper`` with
   ``β = (1 + ω_lᵀω_p)/2``, ω_l the normalized light direction, ω_p the
   normalized view ray direction (β = 0 looking into the light: always too dark
   rather than too bright).

Ground truth: ray marching through the MSAA shadow map (:func:`ray_march`), a
midpoint rule with N samples per view ray; the slides use N = 128 as "ground
truth", :func:`convergence` shows how far that is from N = 4096.

Conventions and clamps (documented, not errors):

* Depth-map texels at NDC depth ≥ :data:`FAR_NDC` (cleared to 1, or a two-depth
  reconstruction there) hold no occluder: depth +∞ along the light, ``z = 1``,
  never shadowing. The fitted light box leaves geometry below NDC 0.98.
* A view ray within :data:`AXIS_ANGLE` of the light axis (looking straight into
  the light or straight away from it: light direction parallel to the view
  direction, where the epipolar map degenerates because the inclination is
  constant along the light axis) has its inclination clamped to
  ``[AXIS_ANGLE, π − AXIS_ANGLE]``. The answer there is the first column's
  average, finite and in [0, t_end], with an error bounded by the column width
  (the map cannot resolve depth along the axis).
* Only directional lights: an area light raises :class:`InputError`.
* Receivers that are also occluders put their own depths right next to the
  end point of every view ray that ends on them (the ground under the light ray
  at ρ_end *is* the ray's end point), so the row distribution has much mass just
  above ``z_p`` and the upper bound (lower + w0) counts it: the six-moment
  analogue of surface acne. On the shipped scene with the ground as an occluder
  the RMSE of scattering_6m was 0.055 (worse than ignoring all shadows, 0.045);
  with the ground as receiver only, 0.018. The scene therefore makes the lowest
  surface a receiver only (it shadows no point of the medium above it).

Package layout: :mod:`.epipolar` (steps 1–5: frame, resampling, quantization,
prefix means, deferred lookup), :mod:`.rays` (camera rays, ray marching, the
metric and the figure); here the techniques ``scattering_6m``,
``scattering_6m_unfiltered`` and ``raymarch``, their stages and their reference
``raymarch`` (ray marching with ``params.reference_samples``, 4096), and
:func:`render`, :func:`convergence`, :func:`report_rows`.

Stages (all named ``scattering_*`` or ``shade_scattering_*``):
``scattering_raster_shadow_map`` (the light's MSAA map), ``scattering_camera_rays``
(view rays, ``t_max`` and the epipolar frame), ``scattering_raymarch_reference``,
per six-moment technique its texture steps (the shared moment steps get the
prefix ``scattering_``) and ``shade_<technique>``, and ``scattering_raymarch``
(the slides' 128 samples).

References
----------
.. [1] Slides: Christoph Peters. *Rendering antialiased shadows with moment shadow mapping*,
       lecture slides (PDF version, with notes) on moment shadow mapping, translucent occluders,
       moment soft shadow mapping and prefiltered single scattering; http://MomentsInGraphics.de/.
       Cited by slide title, e.g. Slides, "Bias the moments".
.. [2] Klehm et al. 2014: Oliver Klehm, Hans-Peter Seidel and Elmar Eisemann. 2014. *Prefiltered
       Single Scattering*. In Proceedings of the 18th ACM SIGGRAPH Symposium on Interactive 3D
       Graphics and Games (i3D '14). ACM.
.. [3] HPG17: Christoph Peters. 2017. *Non-Linearly Quantized Moment Shadow Maps*. In Proceedings
       of High Performance Graphics (HPG '17). ACM. The non-linear quantization Φ, Ψ4, Algorithms
       1–3, the texel formats and the compute shader of §4.1.
.. [4] Duff et al. 2017: Tom Duff, James Burgess, Per Christensen, Christophe Hery, Andrew Kensler,
       Max Liani and Ryusuke Villemin. 2017. *Building an Orthonormal Basis, Revisited*. Journal of
       Computer Graphics Techniques (JCGT) 6, 1, 1–8.
"""


from __future__ import annotations

import time

import numpy as np

from ..._arrays import InputError
from ..._shim import renamed_keys, renamed_keywords
from ...affine import encode_r10g10b10a2
from .._interface import Plan, Reference, Stage, Step, Technique, register, register_reference
from .._steps import moment_steps
from .epipolar import (AXIS_ANGLE, EPIPOLAR_SIZE, FAR_NDC, EpipolarFrame, deferred_shadow, epipolar_coordinates,
                       epipolar_depth, epipolar_frame, prefix_lookup_coordinate, prefix_means, quantize6,
                       resample_filtered, resample_unfiltered)
from .rays import (CameraRays, camera_rays, check_directional, pixel_epipolar, ray_march, scattering_figure,
                   scattering_metric, write_images)

__all__ = [
    "EpipolarTechnique",
    "FAR_NDC",
    "AXIS_ANGLE",
    "EpipolarFrame",
    "epipolar_frame",
    "epipolar_coordinates",
    "epipolar_depth",
    "resample_unfiltered",
    "resample_filtered",
    "quantize6",
    "prefix_means",
    "prefix_lookup_coordinate",
    "deferred_shadow",
    "camera_rays",
    "ray_march",
    "convergence",
    "render",
    "report_rows",
    "write_images",
    "SCATTERING_6M",
    "SCATTERING_6M_UNFILTERED",
    "RAYMARCH",
    "RAYMARCH_REFERENCE",
    "SCATTERING_TECHNIQUES",
]

_ = (CameraRays, EPIPOLAR_SIZE, prefix_lookup_coordinate, epipolar_coordinates, resample_filtered,
     resample_unfiltered, quantize6, prefix_means, AXIS_ANGLE, FAR_NDC, EpipolarFrame)  # re-exported


# ---------------------------------------------------------------------------
# the techniques (registered: the shared interface of moments_ref.techniques)


def _frame_params(params):
    params = renamed_keys(params, "params", view_proj="clip_from_world")
    try:
        return params["frame"], params["clip_from_world"]
    except (KeyError, TypeError):
        raise InputError("params: the scattering techniques need 'frame' (EpipolarFrame) and 'clip_from_world' "
                         "(the light's matrix); build them with moments_ref.techniques.scattering.render") from None


def _step_resample_filtered(m, params):
    frame, vp = _frame_params(params)
    return resample_filtered(m, vp, frame)


def _step_resample_unfiltered(d, params):
    frame, vp = _frame_params(params)
    return resample_unfiltered(d, vp, frame)


def _step_quantize(b, params):
    return quantize6(b)


def _step_prefix(b, params):
    return encode_r10g10b10a2(prefix_means(b))


def _steps_filtered(samples, layered):
    return moment_steps(samples, False) + (
        Step("scattering_resample_filtered", _step_resample_filtered),
        Step("scattering_filtered_quantize6", _step_quantize),
        Step("scattering_filtered_prefix_means", _step_prefix),
    )


def _steps_unfiltered(samples, layered):
    return (
        Step("scattering_resample_unfiltered", _step_resample_unfiltered),
        Step("scattering_unfiltered_quantize6", _step_quantize),
        Step("scattering_unfiltered_prefix_means", _step_prefix),
    )


def _lookup(texture, uv, zf, noise):
    return deferred_shadow(texture, uv, zf)


class EpipolarTechnique(Technique):
    """A six-moment scattering technique: its lookup takes epipolar coordinates and epipolar depth."""

    depth_space = "z_epipolar"

    @renamed_keywords(depth="z_epipolar")
    def shadow(self, texture, uv, z_epipolar, noise=None):
        """Shadowed fraction of view rays (:func:`deferred_shadow`).

        Parameters
        ----------
        texture : the prefix means of :meth:`prepare`
        uv : (..., 2) float array, epipolar texel coordinates of the view rays
        z_epipolar : (...) float array, epipolar depth ``1 − 2θ/π`` of the view rays
            (:func:`epipolar_depth`; ``depth=`` is its old name)
        noise : unused

        Returns
        -------
        fraction : (...) float array
        """
        return self.shadow_at(texture, uv, z_epipolar, noise)


#: Filtered resampling (Slides, "Resampling with filtering"). ``shadow(texture, uv, z_epipolar)``
#: takes epipolar coordinates (see :func:`deferred_shadow`) and returns the shadowed
#: fraction of the view ray.
SCATTERING_6M = EpipolarTechnique(
    name="scattering_6m", bits_per_texel=64, depth_bias=0.0, make_steps=_steps_filtered, lookup=_lookup,
    description="prefiltered single scattering, 6 moments in 2×R10G10B10A2, filtered epipolar resampling",
    reference="Slides, 'Prefiltered single scattering with 6 moments'; Klehm et al. 2014",
    light_kinds=("directional",), stages=lambda t, ctx, cfg: _scattering_stages(t, ctx, cfg),
    truth="raymarch", requires_medium=True,
)
#: Unfiltered resampling (Slides, "Resampling without filtering"): aliased.
SCATTERING_6M_UNFILTERED = EpipolarTechnique(
    name="scattering_6m_unfiltered", bits_per_texel=64, depth_bias=0.0, make_steps=_steps_unfiltered,
    lookup=_lookup,
    description="prefiltered single scattering, 6 moments, epipolar resampling of the plain depth map",
    reference="Slides, 'Resampling without filtering'", light_kinds=("directional",),
    stages=lambda t, ctx, cfg: _scattering_stages(t, ctx, cfg), truth="raymarch", requires_medium=True,
)
SCATTERING_TECHNIQUES = {t.name: t for t in (SCATTERING_6M, SCATTERING_6M_UNFILTERED)}


# ---------------------------------------------------------------------------
# stages and the reference (pipeline graph)

#: Keys of the shared scattering stages.
MAP, RAYS, REFERENCE = "scattering_raster_shadow_map", "scattering_camera_rays", "scattering_raymarch_reference"


def configure(ctx, overrides):
    """Settings of one run: the scattering map, camera and epipolar sizes and the ray-marching sample counts.

    The run's shadow-map size, MSAA and camera resolution (with ``--full`` the
    scene's own). ``epipolar_size``, ``reference_samples`` and
    ``raymarch_samples`` default to the scene's ``params`` (or (256, 512), 4096
    and 128).
    """
    params = ctx.scene.params or {}
    return {
        "shadow_map_size": tuple(ctx.size),
        "msaa": int(ctx.samples),
        "resolution": tuple(ctx.resolution),
        "epipolar_size": tuple(overrides.get("epipolar_size") or params.get("epipolar_size", EPIPOLAR_SIZE)),
        "reference_samples": int(overrides.get("reference_samples") or params.get("reference_samples", 4096)),
        "raymarch_samples": int(overrides.get("raymarch_samples") or params.get("raymarch_samples", 128)),
    }


def _raster(scene, cfg):
    return scene.shadow_map(size=cfg["shadow_map_size"], samples=cfg["msaa"])[0]


def _rays(scene, cfg):
    cam_rays, t_max = camera_rays(scene, cfg["resolution"])
    return cam_rays, t_max, _frame(scene, cam_rays, t_max, cfg["epipolar_size"])


def _frame(scene, cam_rays, t_max, size):
    cos_l = np.clip(cam_rays.direction @ scene.light.direction, -1, 1)
    rho_end = cam_rays.t_end * np.sqrt(np.maximum(0, 1 - cos_l ** 2))
    return epipolar_frame(scene.camera.eye, scene.light.direction, max(float(rho_end.max()) * 1.001, 1e-6),
                          tuple(size), t_max)


def _march(depth, rays, scene, samples):
    return ray_march(depth, scene.light_clip_from_world(), scene.camera.eye, rays[0], int(samples))


def _step(x, rays, step, clip_from_world):
    return step.fn(x, {"frame": rays[2], "clip_from_world": clip_from_world})


def _shade(texture, rays):
    uv, z = pixel_epipolar(rays[0], rays[2])
    return rays[0].t_end * (1 - deferred_shadow(texture, uv, z).astype(np.float64))


def _common(ctx, cfg):
    bound = (("scene", ctx.scene), ("cfg", cfg))
    return (Stage(MAP, _raster, bound=bound), Stage(RAYS, _rays, bound=bound))


def _scattering_stages(technique, ctx, cfg):
    """Texture steps on the scattering map and the deferred pass (shade_<name>)."""
    stages, node = list(_common(ctx, cfg)), MAP
    texel = [MAP]
    for step in technique.steps(cfg["msaa"]):
        key = step.key if step.key.startswith("scattering_") else "scattering_" + step.key
        st = Stage(key, _step, (node, RAYS), bound=(("step", step), ("clip_from_world", ctx.scene.light_clip_from_world())))
        stages.append(st)
        texel.append(key)
        node = key
    shade = Stage(f"shade_{technique.name}", _shade, (node, RAYS))
    return Plan(tuple(stages) + (shade,), tuple(texel), shade.key)


def _raymarch_stages(technique, ctx, cfg):
    march = Stage("scattering_raymarch", _march, (MAP, RAYS),
                  bound=(("scene", ctx.scene), ("samples", cfg["raymarch_samples"])))
    return Plan(_common(ctx, cfg) + (march,), (MAP,), march.key, bits=32 * cfg["msaa"])


def _reference_stage(ctx, cfg, technique):
    return Stage(REFERENCE, _march, (MAP, RAYS), bound=(("scene", ctx.scene), ("samples", cfg["reference_samples"])))


def _metric(result, name):
    return scattering_metric(result.shadow[name], result.reference[name], result.values[RAYS][1])


def _figures(result, names):
    images = {"reference": result.reference[names[0]], **{n: result.shadow[n] for n in names}}
    return {f"scattering_{result.scene.name}.png": scattering_figure(images, result.values[RAYS][1])}


def _section(settings, statements, images):
    refs = sorted({v["reference_samples"] for v in settings.values()})
    lines = ["## Prefiltered single scattering", "",
             "| scene | scattering shadow map | MSAA | camera | epipolar map | reference ray march | "
             "ray march row |", "|---|---|---|---|---|---|---|"]
    for s, v in settings.items():
        sm = v["shadow_map_size"]
        lines.append(f"| {s} | {sm[0]}×{sm[1]} | {v['msaa']}× | {v['resolution'][0]}×{v['resolution'][1]} | "
                     f"{v['epipolar_size'][0]}×{v['epipolar_size'][1]} | {v['reference_samples']} samples | "
                     f"{v['raymarch_samples']} samples |")
    lines += ["", "Rows scattering_6m (six moments, filtered epipolar resampling), scattering_6m_unfiltered "
              "(resampling the plain depth map) and raymarch (the slides' ray marching, "
              f"{', '.join(str(v['raymarch_samples']) for v in settings.values())} samples per ray): "
              "for these rows the error is that of the scattering term (the integral of the light's "
              "visibility along the view ray) normalized by t_max, the longest view ray, against ray "
              f"marching with {', '.join(map(str, refs))} samples per ray; leak_fraction is the share of "
              "pixels brighter than that reference by more than 0.05, flip_mean compares LDR images of "
              "the normalized term (moments_ref.techniques.scattering).", ""]
    for p in images:
        lines += [f"![scattering]({p})", ""]
    return lines


#: Ray marching with the reference sample count (``params.reference_samples``, 4096).
RAYMARCH_REFERENCE = register_reference(Reference(
    name="raymarch", label="scattering outputs", stage=_reference_stage, metric=_metric, option="scattering",
    configure=configure, settings_keys=("epipolar_size", "reference_samples", "raymarch_samples"),
    figures=_figures, section=_section,
))
register(SCATTERING_6M)
register(SCATTERING_6M_UNFILTERED)


def _not_texel_lookup(texture, uv, zf, noise):
    raise InputError("technique: 'raymarch' marches view rays through the shadow map; use ray_march")


#: The slides' ray marching (128 samples per view ray): a float32 depth per MSAA sample.
RAYMARCH = register(Technique(
    name="raymarch", bits_per_texel=128, depth_bias=0.0, make_steps=lambda samples, layered: (),
    lookup=_not_texel_lookup, description="ray marching through the MSAA shadow map, params.raymarch_samples",
    reference="Slides, 'Integrate shadow along view ray'", light_kinds=("directional",),
    stages=_raymarch_stages, truth="raymarch", requires_medium=True,
))


def render(scene, technique="scattering_6m", *, shadow_map_size=None, msaa=None, resolution=None,
           epipolar_size=None, shadow_map=None, rays=None):
    """Render the scattering term of a scene with a six-moment technique.

    Parameters
    ----------
    scene : Scene with a directional light
    technique : "scattering_6m", "scattering_6m_unfiltered" or a Technique
    shadow_map_size, msaa, resolution, epipolar_size : overrides of the scene's
        settings (``epipolar_size`` also from ``scene.params['epipolar_size']``)
    shadow_map : (depth (H, W, S), clip_from_world), optional, reuse a rasterized map
    rays : (CameraRays, t_max), optional, reuse camera rays

    Returns
    -------
    dict with ``scattering`` (H, W) float64 (``t_end · (1 − shadow)``), ``shadow``,
    ``lower``, ``upper`` (shadowed fractions), ``texture``, ``frame``,
    ``texel_seconds``, ``fragment_seconds``.
    """
    check_directional(scene)
    tech = SCATTERING_TECHNIQUES.get(technique, technique) if isinstance(technique, str) else technique
    if not isinstance(tech, Technique) or tech.name not in SCATTERING_TECHNIQUES:
        raise InputError(f"technique: expected one of {', '.join(SCATTERING_TECHNIQUES)}, got {technique!r}")
    depth, vp, cam_rays, t_max = _scene_inputs(scene, shadow_map, shadow_map_size, msaa, rays, resolution)
    size = epipolar_size or scene.params.get("epipolar_size", EPIPOLAR_SIZE)
    frame = _frame(scene, cam_rays, t_max, size)
    t0 = time.perf_counter()
    texture = tech.prepare(depth, {"frame": frame, "clip_from_world": vp})
    t1 = time.perf_counter()
    uv, z = pixel_epipolar(cam_rays, frame)
    shadow, lower, upper = deferred_shadow(texture, uv, z, bounds=True)
    t2 = time.perf_counter()
    scat = cam_rays.t_end * (1 - shadow.astype(np.float64))
    return {"scattering": scat, "shadow": shadow, "lower": lower, "upper": upper, "texture": texture,
            "frame": frame, "texel_seconds": t1 - t0, "fragment_seconds": t2 - t1, "t_max": t_max}


def _scene_inputs(scene, shadow_map, shadow_map_size, msaa, rays, resolution):
    """The light's depth map and matrix and the camera rays: given ones, or rendered from ``scene``."""
    if shadow_map is None:
        vp = scene.light_clip_from_world()
        depth, _ = scene.shadow_map(size=shadow_map_size, samples=msaa)
    else:
        depth, vp = shadow_map
    cam_rays, t_max = camera_rays(scene, resolution) if rays is None else rays
    return depth, vp, cam_rays, t_max


def convergence(scene, counts=(16, 32, 64, 128, 256, 512), reference=4096, *, shadow_map_size=None, msaa=None,
                resolution=None, shadow_map=None, rays=None):
    """RMSE of ray marching with ``counts`` samples against ``reference`` samples.

    Returns
    -------
    dict count -> RMSE of ``S / t_max`` over all pixels, and the reference image under
    key ``"reference_image"`` (``S``, (H, W)).
    """
    check_directional(scene)
    depth, vp, cam_rays, t_max = _scene_inputs(scene, shadow_map, shadow_map_size, msaa, rays, resolution)
    ref = ray_march(depth, vp, scene.camera.eye, cam_rays, int(reference))
    out = {"reference_image": ref}
    for n in counts:
        img = ray_march(depth, vp, scene.camera.eye, cam_rays, int(n))
        out[int(n)] = float(np.sqrt(np.mean(((img - ref) / t_max) ** 2)))
    return out


def report_rows(scene, *, shadow_map_size=None, msaa=None, resolution=None, epipolar_size=None,
                reference_samples=None, raymarch_samples=None, out_dir=None):
    """Rows for results.csv: ``scattering_6m``, ``scattering_6m_unfiltered`` and ``raymarch``.

    Error of the scattering term normalized by ``t_max`` (so 1 is a fully lit ray of
    maximal length) against ray marching with ``reference_samples`` per ray (default
    ``scene.params['reference_samples']`` or 4096); ``raymarch`` is the slides' ray
    marching with ``raymarch_samples`` (default 128). Columns as
    :data:`moments_ref.report.COLUMNS`; ``flip_mean`` compares LDR images of the
    normalized scattering term (NaN without flip-evaluator).

    Returns
    -------
    rows : list of dict
    images : dict name -> (H, W) scattering term (``reference`` included)

    With ``out_dir`` the images are written as ``scattering_<scene>.png``.
    """
    check_directional(scene)
    params = scene.params or {}
    ref_n = int(reference_samples or params.get("reference_samples", 4096))
    rm_n = int(raymarch_samples or params.get("raymarch_samples", 128))
    vp = scene.light_clip_from_world()
    t0 = time.perf_counter()
    depth, _ = scene.shadow_map(size=shadow_map_size, samples=msaa)
    raster_seconds = time.perf_counter() - t0
    rays = camera_rays(scene, resolution)
    cam_rays, t_max = rays
    ref = ray_march(depth, vp, scene.camera.eye, cam_rays, ref_n)
    images = {"reference": ref}
    rows = []
    for name in ("scattering_6m", "scattering_6m_unfiltered"):
        r = render(scene, name, resolution=resolution, epipolar_size=epipolar_size, shadow_map=(depth, vp), rays=rays)
        images[name] = r["scattering"]
        rows.append({"scene": scene.name, "technique": name, "bits_per_texel": 64,
                     **scattering_metric(r["scattering"], ref, t_max),
                     "texel_seconds": raster_seconds + r["texel_seconds"],
                     "fragment_seconds": r["fragment_seconds"]})
    t0 = time.perf_counter()
    rm = ray_march(depth, vp, scene.camera.eye, cam_rays, rm_n)
    t1 = time.perf_counter()
    images["raymarch"] = rm
    rows.append({"scene": scene.name, "technique": "raymarch", "bits_per_texel": 32 * int(depth.shape[2]),
                 **scattering_metric(rm, ref, t_max),
                 "texel_seconds": raster_seconds, "fragment_seconds": t1 - t0})
    if out_dir is not None:
        write_images(images, t_max, f"{out_dir}/scattering_{scene.name}.png")
    return rows, images
