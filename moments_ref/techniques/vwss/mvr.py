"""Multi-view rasterization (MVR): one rasterized depth map per light sample (VWSS §2.1).

The brute-force baseline and the reference of VWSS §4: "Light samples are set as
an eye location, and the GPU rasterizes geometry ... to produce a depth map"
for every sample. Here each view is one map of
:func:`moments_ref.scene.raster.rasterize_depth_views` (one sample per texel, texel-centre
coverage with the top-left rule), so the maps are directly comparable with the
point-warped maps of :func:`moments_ref.techniques.vwss.warp.warp` (same views, same NDC
depth convention, empty = 1).

References
----------
.. [1] VWSS: Adam Marrs, Benjamin Watson and Christopher Healey. 2018. *View-warped Multi-view Soft
       Shadowing for Local Area Lights*. Journal of Computer Graphics Techniques (JCGT) 7, 3, 1–28.
       http://jcgt.org/published/0007/03/01/
"""

from __future__ import annotations

import sys

import numpy as np

from ..._arrays import InputError
from ...scene.raster import RasterStats, rasterize_depth_views
from .lights import LightSamples, check_resolution, check_views
from .shading import pcf_sum

__all__ = ["mvr_passes", "mvr", "mvr_visibility"]


def mvr_passes(vertices, triangles, views, resolution, cull="none", dtype=np.float32, progress=False):
    """Yield ``(view index, depth map (H, W), RasterStats)`` one light sample at a time.

    Parameters as :func:`mvr`.
    """
    m = check_views(views)
    h, w = check_resolution(resolution)
    it = range(m.shape[0])
    if progress:
        from tqdm import tqdm

        it = tqdm(it, desc="mvr", unit="view", file=sys.stderr, disable=None, leave=False)
    # One view at a time; the mesh's view-independent checks once for all of them.
    for i, (d, st) in zip(it, rasterize_depth_views(vertices, triangles, m, (h, w), samples=1, cull=cull, dtype=dtype)):
        yield i, d[..., 0], st


def mvr(vertices, triangles, views, resolution, cull="none", dtype=np.float32, progress=False):
    """Rasterize the occluders once per light-sample view.

    Parameters
    ----------
    vertices : (V, 3) float array
    triangles : (T, 3) int array
    views : LightSamples or (N, 4, 4) float array
        View-projection matrices.
    resolution : int or (H, W)
    cull : {"none", "back", "front"}
    dtype : float32 or float64
        Depth storage (float32 = D32_FLOAT, the paper's "32-bit floating-point precision").
    progress : bool
        tqdm bar over the views on stderr.

    Returns
    -------
    depth : (N, H, W) array of ``dtype``
        NDC depth of the nearest triangle per texel centre; 1 where none.
    stats : RasterStats
        Counts summed over the views (``triangles`` = input triangles × views).
    """
    m = check_views(views)
    h, w = check_resolution(resolution)
    if np.dtype(dtype) not in (np.float32, np.float64):
        raise InputError(f"dtype: expected float32 or float64, got {dtype!r}")
    out = np.empty((m.shape[0], h, w), dtype)
    total = RasterStats()
    for i, d, st in mvr_passes(vertices, triangles, m, (h, w), cull, dtype, progress):
        out[i] = d
        for k, v in st.as_dict().items():
            setattr(total, k, getattr(total, k) + v)
    return out, total


def mvr_visibility(vertices, triangles, samples: LightSamples, resolution, positions, bias, progress=False):
    """Visibility of world points under MVR, each light sample's map shaded as soon as it is rasterized.

    The reference of VWSS §4 (and of the area-light rows of the report): the 5-tap
    PCF of :func:`moments_ref.techniques.vwss.shading.pcf_sum` in each of the
    ``len(samples)`` maps, averaged; one map is held at a time, so hundreds of
    views fit in memory.

    Parameters
    ----------
    vertices, triangles : the occluders
    samples : LightSamples
    resolution : int or (H, W)
    positions : (P, 3) float array, world positions of the receivers
    bias : float, depth bias in world units along the light normal
    progress : bool, tqdm bar over the views on stderr

    Returns
    -------
    (P,) float64 array in [0, 1]
    """
    acc = np.zeros(np.shape(positions)[0])
    for i, d, _ in mvr_passes(vertices, triangles, samples, resolution, progress=progress):
        acc += pcf_sum(positions, d[None], samples.clip_from_world[[i]], samples.near, samples.far, bias)
    return acc / len(samples)
