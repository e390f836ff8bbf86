"""Depth-map memory reused between calls: a map's pages come back when its caller drops it.

Part of :mod:`moments_ref.scene.raster` (see its docstring for the conventions).

A fresh map is cleared memory the process has not touched yet: every page of it is
faulted in and zeroed by the kernel before the clear to the far value writes it again.
On the bench machine a 2048² 4× float32 map (64 MiB) costs about 10 ms through
``np.ones``, of which about 7.6 ms are those first touches; refilling memory that is
already mapped costs about 2.4 ms. llvmpipe keeps its framebuffer between draws and only
clears it, and :func:`cleared_map` does the same for the maps that
:func:`~moments_ref.scene.raster.rasterize_depth` returns: a map owns its memory as long
as the caller holds it or any view of it; once the last reference is gone, its memory is
kept (one buffer, at most :data:`MAX_KEPT_BYTES`) and the next map of the same size and
dtype is cleared into it instead of into fresh pages.

How the lifetime is tracked. The returned array is made with ``np.frombuffer`` over a
``memoryview`` of the kept buffer, so its ``base`` is not an ndarray: NumPy stops
collapsing a view's ``base`` chain there, so every view of the map (and every view of a
view) holds the returned array itself, and a weak-reference finalizer on it runs only
when no view of the map is alive. The buffer is then free for reuse. The values are the
same as those of ``np.full``: only where the memory comes from changes.
"""

from __future__ import annotations

import weakref

import numpy as np

#: Maps at least this large (bytes) take the reused memory: below it first touches are few
#: (NumPy asks the kernel for huge pages from 4 MiB on) and a finalizer would cost more.
MIN_KEPT_BYTES = 1 << 22
#: Largest buffer kept for reuse after its map is dropped (bytes): a 2048² 4× float64 map. Larger
#: maps (4096² 4× float32 is 256 MiB) are not kept, so that memory held for reuse stays small
#: beside the memory budget of a 4096² run.
MAX_KEPT_BYTES = 1 << 27

# The free buffer, keyed by (element count, dtype): at most one is kept.
_FREE = {}


def cleared_map(n, dtype, value=1.0):
    """A flat writeable array of ``n`` elements of ``dtype``, every one ``value``: ``np.full(n, value, dtype)``.

    Its memory is a dropped map's where one of the same size and dtype is free (see the
    module docstring); the array is new to the caller either way.
    """
    dt = np.dtype(dtype)
    nbytes = n * dt.itemsize
    if not MIN_KEPT_BYTES <= nbytes <= MAX_KEPT_BYTES:
        return np.full(n, value, dt)
    key = (n, dt.str)
    raw = _FREE.pop(key, None)
    if raw is None:
        raw = np.empty(n, dt)
    raw.fill(value)
    out = np.frombuffer(memoryview(raw), dt)
    weakref.finalize(out, _release, key, raw).atexit = False
    return out


def _release(key, raw):
    """Keep ``raw`` (the memory of a map nobody holds any more) for the next map of its size; drop any other."""
    _FREE.clear()
    _FREE[key] = raw
