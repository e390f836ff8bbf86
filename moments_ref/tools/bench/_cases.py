"""The rasterizer scenes that the bench times in both the reference and llvmpipe (same seeds)."""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from ...scene.raster import small_triangles

__all__ = ["raster_case"]


@lru_cache(maxsize=1)
def raster_case(name):
    """``(vertices, triangles, clip_from_world, size, samples)`` of a named rasterizer scene.

    ``small-N-Sx``: N random triangles about 4 pixels wide (random depths) into a
    1024² map with S samples, identity ``clip_from_world``. ``railing-Sx``: the
    railing scene's occluders (6.4k long, thin triangles) into its 2048² light
    map with S samples.
    """
    kind, *rest = name.split("-")
    samples = int(rest[-1].rstrip("x"))
    if kind == "small":
        v, t = small_triangles(int(rest[0]), 1024, 4.0, np.random.default_rng(0))
        return v, t, np.eye(4), 1024, samples
    from ...scene import load_scene

    scene = load_scene("railing")
    m = scene.occluder_mesh(translucent=False)
    return m.vertices, m.triangles, scene.light_clip_from_world(), 2048, samples
