"""Floor probes of ``moments-ref bench``: what a chunked NumPy kernel pays before its arithmetic, measured.

A shading kernel of this package (Algorithm 1, Algorithm 3, the six-moment bound) reads
``(n, k)`` moment rows, copies each chunk of them into ``k`` contiguous columns (one
transposing copy), runs its ufunc passes over chunk-long rows and writes a fresh ``(n,)``
result. A probe does exactly that with the arithmetic replaced by ``passes`` float
passes over the same chunk-long rows, as many of them writing a third row as the kernel's
(:data:`THIRD_ROW`; the others work in place): with ``passes = 0`` it is the floor of any
kernel written this way (the transposing copy and the first touch of the output), with
the kernel's own passes it is their floor. For Algorithms 1 and 3 those are the kernel's
own ufuncs (:data:`UFUNCS`: divisions and a square root cost more than the multiplications
that stood for them until round nine) and its min/max reductions (:data:`REDUCTIONS`),
checked against the calls the kernels make by tests/test_bench_targets.py. The bench
measures both in the same run as the kernel and prints them beside it, against the same
copy, so that a floor is a measurement, not a figure in the text.

Nothing here asserts a timing in the tests: probes are read, not enforced.
"""

from __future__ import annotations

import numpy as np

__all__ = ["pass_probe", "scatter_probe", "PASSES", "THIRD_ROW", "UFUNCS", "REDUCTIONS"]

#: Ufunc passes per chunk of each kernel's common path, counted in its code (float and
#: boolean passes alike; the rare singular or out-of-domain texels are handed elsewhere).
PASSES = {
    # msm._bound_rows: 9 Cholesky, 5 forward substitution, 5 scaling and 1/w0 − 1, 4 k2 = p'(zf),
    # 1/w0 and min(q2, 0), 5 the discriminant (its square root one), 2 (1 − w0)/2, 5 the weight
    # and 1 saturate (issue 41, round six; 49 before; since round seven 2/w0 is doubled in place,
    # the same count); its four reductions (pivots, b4, the results' finiteness): REDUCTIONS
    "shadow_intensity float32": 38,
    # nonlinear._shade_about_zf with the gap of shade's domain check: 1 gap, 2 X = zf − y1 and
    # m1 = v2 G, 3 σ² = (1 − v2) m1 G, 3 the forward substitution about y1 and 1 2X − G, 9 scaling,
    # k2, 1/w0 − 1, 1/w0 and min(q2, 0), 5 the discriminant, 2 (1 − w0)/2 (2/w0 doubled in place),
    # 5 the weight and 1 saturate (round seven: depths measured from y1; 34 in round six, 43
    # before); its seven reductions (the domain and the results' finiteness): REDUCTIONS;
    # the texels where a §3.4 clamp acts (none of filtered moments) take the clamped kernel
    "shade float32": 32,
    # msm6._bounds on float32 (moments_ref._msm6_bound.bound_rows): 23 Cholesky, 11 forward
    # substitution by the recurrence, 8 the signs, case masks and σ's sign bit, 5 the derivatives
    # at zf, 11 the Gauss–Radau cubic, 4 λ and y1 (y1 − K1) + D1, 4 Blinn's B, C, D, 9 Blinn's
    # form and σ (10 until round seven's second wave), 3 v = √2 u, 8 cos(arccos(σr)/3) (a
    # rational function in partial fractions: 12 as a polynomial before), 2 the root, 9 its
    # weight from the moments about zf (P'(t)/3ℓ = s² − Δ0': 10 until round nine), 6 step (5)
    # and saturate (issue 41, round seven; 128 in msm6._bounds_kernel before); 3 reductions (4
    # until round nine), not counted
    "shadow_intensity six moments float32": 103,
}

#: Of :data:`PASSES`, those that write a third row (read two rows and write a row neither of
#: them is): since round seven the two kernels above write every other value into a row they
#: read (two rows moved instead of three), and their probes do the same (an in-place add
#: stands for each of those passes). A kernel missing here counts every pass as a third row.
THIRD_ROW = {
    # b1 b2, L32 = (b3 − b1 b2)/σ², y2 = zf − b1, L32 y2, the bound into the output
    "shadow_intensity float32": 5,
    # the gap, y3 = X (X − G), the bound into the output (since round seven's second pass X, m1,
    # zf − y2 and q2 go into the rows of the chunk's transposed copy of r: 7 before)
    "shade float32": 3,
    # the Cholesky's products b_i b_j and L·(L D) terms, the recurrence's, the Radau cubic's, Blinn's
    # and the weight's products and quotients of two rows into a third, the bound into the output:
    # counted per chunk like the others (tests/test_bench_targets.py; round nine, all 103 before)
    "shadow_intensity six moments float32": 37,
}


#: Of :data:`PASSES`, which ufunc each pass calls (issue 41, round nine): a division costs more than
#: a multiplication where its rows leave L2, and a square root about three multiplications
#: (docs/bench.md, "What a pass costs"), so a probe of multiplications and additions alone
#: measured a floor below the kernel's own operations. Counted in the code and checked against
#: the kernels' calls by tests/test_bench_targets.py; the binary ones first in the order that
#: :func:`pass_probe` gives the passes writing a third row.
UFUNCS = {
    # msm._quadratic_about_zf and msm._bound_rows (the lower bound; the upper adds 3 passes)
    "shadow_intensity float32": {"multiply": 15, "divide": 5, "subtract": 9, "add": 6, "minimum": 1,
                                 "maximum": 1, "sqrt": 1},
    # shade's gap, nonlinear._shade_about_zf
    "shade float32": {"multiply": 13, "divide": 4, "subtract": 7, "add": 5, "minimum": 1, "maximum": 1,
                      "sqrt": 1},
}

#: Reductions over a chunk-long row per chunk of each kernel's common path (min or max: the
#: refusal of b4 = +∞, the pivots' signs and the result's finiteness for Algorithm 1; the
#: domain's six extremes and the result's finiteness for Algorithm 3; float64's relative
#: thresholds take five reductions instead of the two of the signs). Each reads a row as a pass
#: does; :func:`pass_probe` does as many (round nine: uncounted before).
REDUCTIONS = {"shadow_intensity float32": 4, "shadow_intensity float64": 7, "shade float32": 7}


def _binary(f, x, y, out):
    """``f(x, y)`` into ``out`` as the kernels call it: ``out`` positional (cheaper), ``out=`` for the
    extrema (NumPy 2.4 deprecates their positional output)."""
    if f is np.maximum or f is np.minimum:
        return f(x, y, out=out)
    return f(x, y, out)


def pass_probe(b, zf, passes, chunk, third_row=None, ufuncs=None, reductions=0):
    """A callable doing a kernel's data movement on ``(b, zf)`` with ``passes`` float passes per chunk.

    ``b`` is ``(n, k)``, ``zf`` ``(n,)``; per chunk of ``chunk`` rows: the transposing copy
    into ``k`` reused rows, ``reductions`` min/max reductions over them, ``passes`` passes over
    chunk-long rows, and the chunk's result written into a fresh ``(n,)`` output. The first
    ``third_row`` passes (default: all) read two columns into a reused temporary (three rows
    moved), the others combine that temporary with a column in place (two rows moved), as
    :data:`THIRD_ROW` counts the kernels' passes. ``ufuncs`` (``{name: count}`` summing to
    ``passes``, as :data:`UFUNCS`) says which ufunc each pass calls, the binary ones first; by
    default multiplications into the temporary and additions in place. In place, a
    multiplication or division is by a kept row of ones and the square root that of the
    temporary, so that no value grows, shrinks to a denormal or depends on the data.
    """
    n, k = b.shape
    rows = np.empty((k, min(chunk, n)), dtype=b.dtype)
    tmp = np.empty(min(chunk, n), dtype=b.dtype)
    ones = np.ones(min(chunk, n), dtype=b.dtype)
    # at least one product, so that the in-place adds start from finite values
    third = passes if third_row is None else max(min(third_row, passes), min(passes, 1))
    if ufuncs is None:
        calls = ["multiply"] * third + ["add"] * (passes - third)
    else:
        if sum(ufuncs.values()) != passes:
            raise ValueError(f"ufuncs: {sum(ufuncs.values())} passes, expected {passes}")
        calls = [name for name, count in ufuncs.items() for _ in range(count)]
        calls.sort(key=lambda name: name == "sqrt")  # stable: the binary ufuncs first, in their order
    calls = [getattr(np, name) for name in calls]

    def run():
        out = np.empty(n, dtype=b.dtype)
        with np.errstate(all="ignore"):
            for lo in range(0, n, chunk):
                hi = min(lo + chunk, n)
                cols = rows[:, : hi - lo]
                np.copyto(cols, b[lo:hi].T)
                t, one = tmp[: hi - lo], ones[: hi - lo]
                for i in range(reductions):
                    (np.maximum if i % 2 else np.minimum).reduce(cols[i % k])
                for i, f in enumerate(calls[:third]):  # inputs left unchanged: no denormals, no overflow
                    if f is np.sqrt:
                        f(cols[i % k], t)
                    else:
                        _binary(f, cols[i % k], cols[(i + 1) % k], t)
                for i, f in enumerate(calls[third:]):  # a sum of at most a few hundred inputs: no overflow
                    if f is np.sqrt:
                        f(t, t)
                    else:
                        _binary(f, t, one if f in (np.multiply, np.divide) else cols[i % k], t)
                np.copyto(out[lo:hi], zf[lo:hi] if passes == 0 else t)
        return out

    return run


def scatter_probe(vertices, triangles, clip_from_world, size, samples):
    """The rasterizer's floor on a scene: the clear of a depth map and the scatter-min of its covered samples.

    Any rasterizer that writes each covered sample's depth through ``np.minimum.at`` (the
    depth test of :func:`moments_ref.scene.raster.rasterize_depth`) pays at least this: the
    clear of the ``size² samples`` map to the far value and one scatter-min per covered
    sample, with the flat sample indices and float32 depths already computed (here from
    :func:`~moments_ref.scene.raster.rasterize_fragments`, outside the timing). The map's
    memory is kept between calls, as llvmpipe keeps its framebuffer and as ``rasterize_depth``
    reuses a dropped map's memory (``moments_ref.scene.raster._maps``): the first touch of
    fresh pages is not part of the floor. Returns ``(probe, covered)``: a callable returning
    the map, and the count of covered samples.
    """
    from ...scene.raster import rasterize_fragments

    f, _ = rasterize_fragments(vertices, triangles, clip_from_world, size, samples=samples)
    flat = f.texel * samples + f.sample
    z = f.depth.astype(np.float32)
    n_map = size * size * samples
    del f

    depth = np.empty(n_map, np.float32)

    def probe():
        depth.fill(1.0)
        np.minimum.at(depth, flat, z)
        return depth

    return probe, int(flat.size)
