"""The rasterizer scenes that the bench times in both the reference and llvmpipe (same seeds)."""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from ...scene.raster import small_triangles

__all__ = ["raster_case", "MID_EXTENT"]

#: Vertex spread (pixels) of the mid-size triangles: mean area extent²/12 ≈ 150 pixels.
MID_EXTENT = 42.0


@lru_cache(maxsize=1)
def raster_case(name):
    """``(vertices, triangles, clip_from_world, size, samples)`` of a named rasterizer scene.

    ``small-N-Sx``: N random triangles about 4 pixels wide (random depths) into a
    1024² map with S samples, identity ``clip_from_world``. ``mid-N-Sx``: N random triangles
    of about 150 pixels (vertices within 42 pixels of a centre; mean area extent²/12) into a
    2048² map, the mid-size case of the scenes users bring. ``railing-Sx``: the
    railing scene's occluders (6.4k long, thin triangles) into its 2048² light
    map with S samples.
    """
    kind, *rest = name.split("-")
    samples = int(rest[-1].rstrip("x"))
    if kind == "small":
        v, t = small_triangles(int(rest[0]), 1024, 4.0, np.random.default_rng(0))
        return v, t, np.eye(4), 1024, samples
    if kind == "mid":
        v, t = small_triangles(int(rest[0]), 2048, MID_EXTENT, np.random.default_rng(0))
        return v, t, np.eye(4), 2048, samples
    from ...scene import load_scene

    scene = load_scene("railing")
    m = scene.occluder_mesh(translucent=False)
    return m.vertices, m.triangles, scene.light_clip_from_world(), 2048, samples
