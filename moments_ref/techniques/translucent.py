"""Translucent occluders in a 64-bit moment shadow map (Slides, "Translucent occluders").

The slides render translucent occluders "to a moment shadow map with alpha
blending", blend mode ``α · source + (1 − α) · destination``, on top of the
opaque occluders [Peters et al. 2016]. Drawn far to near, each translucent
fragment of opacity α at depth z turns the moments of a sample into
``α b(z) + (1 − α) b_old``, so the final sample holds

    b = Σ_k w_k b(z_k),   w_k = α_k ∏_{l nearer than k} (1 − α_l),

with the opaque surface (or the far plane z = 1 of the cleared map) as the last
layer, weighted by the remaining transmittance. These are the moments of a
depth distribution whose ``Z(z < zf)`` is one minus the product of the
transmittances along the light ray in front of zf: the filtered version of that
product (:func:`moments_ref.techniques.pcf.pcf_filtered` on the layers) is the
reference for translucent occluders.

:func:`translucency_pass` computes the layers of every MSAA sample in closed form
(the far-to-near blend, vectorized: sort the fragments of each sample by depth
and take running products); ``translucent_msm`` stores their moments as
``msm64`` does (the slides: "All of this is done with a single 64-bit moment
shadow map") and shades them with Algorithm 1. Techniques without translucency
support see only the opaque occluders (the default of
:meth:`moments_ref.scene.Scene.shadow_map`).

References
----------
.. [1] Slides: Christoph Peters. *Rendering antialiased shadows with moment shadow mapping*,
       lecture slides (PDF version, with notes) on moment shadow mapping, translucent occluders,
       moment soft shadow mapping and prefiltered single scattering; http://MomentsInGraphics.de/.
       Cited by slide title, e.g. Slides, "Bias the moments".
.. [2] Peters et al. 2016: Christoph Peters, Cedrick Münstermann, Nico Wetzstein and Reinhard
       Klein. 2016. *Beyond Hard Shadows: Moment Shadow Maps for Single Scattering, Soft Shadows
       and Translucent Occluders*. In Proceedings of the 20th ACM SIGGRAPH Symposium on Interactive
       3D Graphics and Games (i3D '16). ACM.
"""

from __future__ import annotations

import numpy as np

from .._arrays import InputError, real_input
from .._shim import renamed_keywords
from ..scene.raster import rasterize_fragments
from ._interface import LayeredSamples, Technique, register
from .msm import msm64_lookup, msm64_steps

__all__ = ["translucency_pass", "TRANSLUCENT_MSM"]


@renamed_keywords(view_proj="clip_from_world")
def translucency_pass(opaque_depth, vertices, triangles, opacity, clip_from_world, cull="none"):
    """Per-sample layers of translucent occluders in front of the opaque depth map.

    Parameters
    ----------
    opaque_depth : (H, W, S) float array
        Depth map of the opaque occluders (1 where nothing was drawn).
    vertices : (V, 3) float array
        Translucent geometry.
    triangles : (T, 3) int array
    opacity : (T,) float array in (0, 1]
        Opacity α of each triangle.
    clip_from_world : (4, 4) float array
        The light's matrix (the one that rendered ``opaque_depth``).
    cull : str
        Face culling, as :func:`moments_ref.scene.raster.rasterize_fragments`.

    Returns
    -------
    LayeredSamples
        ``depth (H, W, S, K)`` nearest first, the opaque depth as the last used
        layer of each sample, unused layers at 1 with weight 0; ``weight`` as in
        the module docstring, summing to 1 per sample.

    Notes
    -----
    Fragments behind the opaque surface fail the depth test and are dropped.
    Fully opaque translucent triangles (α = 1) are handled exactly (their
    transmittance 0 is counted, not taken as a logarithm).
    """
    z0 = real_input(opaque_depth, "opaque_depth")
    if z0.ndim != 3:
        raise InputError(f"opaque_depth: expected an (H, W, S) depth map, got shape {z0.shape}")
    H, W, S = z0.shape
    tri = np.asarray(triangles)
    alpha = real_input(opacity, "opacity", dtype=np.float64).reshape(-1)
    if alpha.shape[0] != tri.reshape(-1, 3).shape[0]:
        raise InputError(f"opacity: expected one value per triangle ({tri.reshape(-1, 3).shape[0]}), "
                         f"got {alpha.shape[0]}")
    if ((alpha <= 0) | (alpha > 1)).any():
        raise InputError("opacity: expected values in (0, 1]")
    frags, _ = rasterize_fragments(vertices, tri.reshape(-1, 3), clip_from_world, (H, W), samples=S, cull=cull)
    flat_opaque = z0.reshape(-1)
    key = frags.texel * S + frags.sample
    keep = frags.depth < flat_opaque[key]  # depth test against the opaque map
    key, z, a = key[keep], frags.depth[keep].astype(np.float64), alpha[frags.triangle[keep]]

    # Sort each sample's fragments near to far.
    order = np.lexsort((z, key))
    key, z, a = key[order], z[order], a[order]
    n = key.shape[0]
    new = np.ones(n, bool)
    new[1:] = key[1:] != key[:-1]
    group = np.cumsum(new) - 1
    start = np.flatnonzero(new)
    rank = np.arange(n) - start[group]

    # Transmittance in front of each fragment: running product within the sample.
    full = a >= 1.0
    log_t = np.where(full, 0.0, np.log1p(-np.where(full, 0.0, a)))
    cum_log = np.cumsum(log_t)
    cum_full = np.cumsum(full)
    excl_log = cum_log - log_t
    excl_full = cum_full - full
    before_log = excl_log - excl_log[start][group]
    before_full = excl_full - excl_full[start][group]
    t_before = np.where(before_full == 0, np.exp(before_log), 0.0)
    w = a * t_before

    counts = np.bincount(key, minlength=H * W * S)
    K = int(counts.max()) + 1 if n else 1
    depth = np.ones((H * W * S, K), dtype=np.float32)
    weight = np.zeros((H * W * S, K), dtype=np.float64)
    depth[key, rank] = z.astype(np.float32)
    weight[key, rank] = w
    # Remaining transmittance behind the last translucent layer goes to the opaque depth.
    t_total = np.ones(H * W * S)
    last = np.r_[start[1:] - 1, n - 1] if n else np.zeros(0, np.intp)
    t_total[key[last]] = t_before[last] * (1.0 - a[last])
    rows = np.arange(H * W * S)
    depth[rows, counts] = flat_opaque.astype(np.float32)
    weight[rows, counts] = t_total
    return LayeredSamples(depth.reshape(H, W, S, K), weight.reshape(H, W, S, K))


TRANSLUCENT_MSM = register(Technique(
    name="translucent_msm", bits_per_texel=64, depth_bias=1e-3, make_steps=msm64_steps, lookup=msm64_lookup,
    description="translucent occluders alpha-blended into a 64-bit moment shadow map (as msm64)",
    reference="Slides, 'Translucent occluders'; Peters et al. 2016",
    translucency=True, requires_translucency=True, four_moments=True,
))
