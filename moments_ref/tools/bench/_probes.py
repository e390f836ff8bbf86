"""Floor probes of ``moments-ref bench``: what a chunked NumPy kernel pays before its arithmetic, measured.

A shading kernel of this package (Algorithm 1, Algorithm 3, the six-moment bound) reads
``(n, k)`` moment rows, copies each chunk of them into ``k`` contiguous columns (one
transposing copy), runs its ufunc passes over chunk-long rows and writes a fresh ``(n,)``
result. A probe does exactly that with the arithmetic replaced by ``passes`` float
multiplications over the same chunk-long rows: with ``passes = 0`` it is the floor of any
kernel written this way (the transposing copy and the first touch of the output), with
the kernel's own count of passes it is that count's floor. The bench measures both in the
same run as the kernel and prints them beside it, against the same copy, so that a floor
is a measurement, not a figure in the text.

Nothing here is asserted by the tests: probes are read, not enforced.
"""

from __future__ import annotations

import numpy as np

__all__ = ["pass_probe", "scatter_probe", "PASSES"]

#: Ufunc passes per chunk of each kernel's common path, counted in its code (float and
#: boolean passes alike; the rare singular or out-of-domain texels are handed elsewhere).
PASSES = {
    # msm._bound_rows: 9 Cholesky, 5 forward substitution, 5 scaling and 1/w0 − 1, 4 k2 = p'(zf),
    # 1/w0 and min(q2, 0), 5 the discriminant (its square root one), 2 (1 − w0)/2, 5 the weight
    # and 1 saturate (issue 41, round six; 49 before); its four reductions (pivots, b4, the
    # results' finiteness) are not counted
    "shadow_intensity float32": 38,
    # nonlinear._shade_about_zf with the gap of shade's domain check: 1 gap, 5 z'f and ξ'4,
    # 5 the forward substitution in unit coordinates, 8 scaling, 1/w0 − 1 and k2, 2 1/w0 and
    # min(q2, 0), 5 the discriminant, 2 (1 − w0)/2, 6 the weight and saturate (round six; 43
    # before); the texels where a §3.4 clamp acts (none of filtered moments) take the clamped
    # kernel
    "shade float32": 34,
    # msm6._bounds on float32 (moments_ref._msm6_bound.bound_rows): 23 Cholesky, 11 forward
    # substitution by the recurrence, 8 the signs, case masks and σ's sign bit, 5 the derivatives
    # at zf, 11 the Gauss–Radau cubic, 4 λ and y1 (y1 − K1) + D1, 4 Blinn's B, C, D, 10 Blinn's
    # form and σ, 3 u, 12 cos(arccos(σr)/3), 2 the root, 10 its weight from the moments about zf,
    # 6 step (5) and saturate (issue 41, round seven; 128 in msm6._bounds_kernel before); 4
    # reductions
    "shadow_intensity six moments float32": 109,
}


def pass_probe(b, zf, passes, chunk):
    """A callable doing a kernel's data movement on ``(b, zf)`` with ``passes`` multiplications per chunk.

    ``b`` is ``(n, k)``, ``zf`` ``(n,)``; per chunk of ``chunk`` rows: the transposing copy
    into ``k`` reused rows, ``passes`` multiplications of chunk-long rows into a reused
    temporary, and the chunk's result written into a fresh ``(n,)`` output.
    """
    n, k = b.shape
    rows = np.empty((k, min(chunk, n)), dtype=b.dtype)
    tmp = np.empty(min(chunk, n), dtype=b.dtype)

    def run():
        out = np.empty(n, dtype=b.dtype)
        for lo in range(0, n, chunk):
            hi = min(lo + chunk, n)
            cols = rows[:, : hi - lo]
            np.copyto(cols, b[lo:hi].T)
            t = tmp[: hi - lo]
            for i in range(passes):  # inputs left unchanged: no denormals, no overflow
                np.multiply(cols[i % k], cols[(i + 1) % k], out=t)
            np.copyto(out[lo:hi], zf[lo:hi] if passes == 0 else t)
        return out

    return run


def scatter_probe(vertices, triangles, clip_from_world, size, samples):
    """The rasterizer's floor on a scene: a fresh cleared depth map and the scatter-min of its covered samples.

    Any rasterizer that writes each covered sample's depth through ``np.minimum.at`` (the
    depth test of :func:`moments_ref.scene.raster.rasterize_depth`) pays at least this: the
    first touch of the ``size² samples`` map and one scatter-min per covered sample, with
    the flat sample indices and float32 depths already computed (here from
    :func:`~moments_ref.scene.raster.rasterize_fragments`, outside the timing). Returns
    ``(probe, covered)``: a callable returning the map, and the count of covered samples.
    """
    from ...scene.raster import rasterize_fragments

    f, _ = rasterize_fragments(vertices, triangles, clip_from_world, size, samples=samples)
    flat = f.texel * samples + f.sample
    z = f.depth.astype(np.float32)
    n_map = size * size * samples
    del f

    def probe():
        depth = np.ones(n_map, np.float32)
        np.minimum.at(depth, flat, z)
        return depth

    return probe, int(flat.size)
