"""Helpers shared by the four- and six-moment kernels, and the chunk sizes of every vectorized loop.

One home for what :mod:`moments_ref.msm`, :mod:`moments_ref.msm6` and
:mod:`moments_ref.nonlinear` all use: the chunk size of the vectorized kernels,
the singularity threshold of the Hankel matrix, the two-point distribution of
HPG17 Algorithm 2 and a bit-level ``copysign``. Keeping them here lets msm6
build on them without importing msm (which dispatches six-moment input to msm6).

The chunk (block, band) sizes of the other vectorized loops of the package live
here too, one table with the measurement behind each: a machine with another cache
is retuned in one place, and no result depends on any of them.

References
----------
.. [1] HPG17: Christoph Peters. 2017. *Non-Linearly Quantized Moment Shadow Maps*. In Proceedings
       of High Performance Graphics (HPG '17). ACM. The non-linear quantization Φ, Ψ4, Algorithms
       1–3, the texel formats and the compute shader of §4.1.
"""

from __future__ import annotations

import numpy as np

from ._arrays import float_dtype

__all__ = ["CHUNK", "MSM_CHUNK", "MSM6_CHUNK", "SHADE_CHUNK", "PHI_CHUNK", "ENCODE_CHUNK", "SAT_QUERY_CHUNK", "PCF_CHUNK", "RESOLVE_CHUNK", "RASTER_SETUP_CHUNK", "SWEEP_CHUNK", "WARP_BLOCK",
           "SHADING_BLOCK", "FILTER_BAND_BYTES", "ROW_BAND_BYTES", "RESOLVE_BYTES", "PATH_BAND_TEXELS", "RASTER_ROW_BUDGET", "RASTER_SAMPLE_BUDGET", "SINGULAR_RTOL", "singular_thresholds", "two_point", "copysign_inplace", "copysign_exact",
           "broadcast_chunks"]

#: Texels per chunk of the six-moment kernel (:mod:`moments_ref.msm6`) and the default of
#: :func:`broadcast_chunks`: its ~140 passes hold twice the live rows of Algorithm 1, which at
#: 2^15 leave a core's L2.
CHUNK = 1 << 14
#: Texels per chunk of :func:`moments_ref.msm.shadow_intensity` (Algorithm 1): a ufunc call costs
#: about 0.4 µs whatever its length, so short chunks pay it ~60 times each; at 2^15 its nine float
#: workspace rows (1.2 MB in float32) still sit in the 2 MiB L2. Measured at 2048² float32, same
#: run, ratio to a copy of the traffic: 2^12 22.4×, 2^13 15.6×, 2^14 13.4×, 2^15 12.5×, 2^16 12.6×.
MSM_CHUNK = 1 << 15
#: Texels per chunk of :func:`moments_ref.nonlinear.shade` (Algorithm 3; same trade-off as
#: MSM_CHUNK) in float64, twice as many in float32 (``nonlinear.shade_chunk``). 2^16 since issue 41
#: round seven (32 passes, most of them writing a row they read): 2048² float32, interleaved, CPU
#: time, 12 and 16 rounds, load 3.2–3.3: 2^16 0.923 and 0.873 of the time of 2^15, 2^17 0.903,
#: 2^14 1.099. Float32 2^17 since round twelve, on the quiet machine (the bench's representation,
#: 21 interleaved rounds, CPU time): 0.963 (0.959–0.966) and 0.980 (0.973–0.983) of the time of
#: 2^16 at load 0.9 and 1.7, 0.980 (0.948–1.018) beside a process streaming memory on the other
#: core; float64 2^17 1.058 (1.049–1.064), so float64 keeps 2^16.
SHADE_CHUNK = 1 << 16
#: Texels per chunk of the six-moment bounds in float32 (the fast path of :mod:`moments_ref._msm6_bound`): 2^16
#: since issue 41 round nine (2048² bench input, CPU time, interleaved, load 2.6–2.7: 0.919
#: (0.864–0.964) of the time of 2^15 over 25 pairs, and 0.901 against 0.961 of the round's starting
#: code over 21; 2^17 0.948 against 2^16's 0.884 in one run). Before: Algorithm 1's 2^15 (round
#: five, the Christoffel kernel: 2^13 0.130 s, 2^14 0.104 s, 2^15 0.094 s, 2^16 0.098 s).
MSM6_CHUNK = 1 << 16
#: Input bytes per band of rows of a map-sized per-texel step of the pipeline (the resolve of a feature,
#: a texture's quantization: :func:`moments_ref.techniques._steps.in_row_bands`): their float64
#: temporaries, several times the map, then exist for one band, not the whole map (issue 41: the
#: report's peak memory per texel).
ROW_BAND_BYTES = 1 << 21
#: Texels per chunk of :func:`moments_ref.nonlinear.phi` (Algorithm 2 and Ψ4) and of the texel
#: encoders of :mod:`moments_ref.packing` (four float rows in and out): each of the ~100 ufunc
#: calls of a chunk costs about 0.65 µs besides its elements, a third of the time at 8192.
#: Interleaved A/B of 2^15 against 8192 at 2048² (load 9): quantize_nlq 0.752 (nlq64) and
#: 0.735 (nlq32) of the time, the global NLQ path 0.918 and 0.902; bit for bit.
PHI_CHUNK = 1 << 15
ENCODE_CHUNK = 1 << 15
#: Queries per chunk of :func:`moments_ref.gpu.sat.interpolated_mean` (each gathers 16 texels × C).
SAT_QUERY_CHUNK = 1 << 15
#: Fragments per chunk of :func:`moments_ref.techniques.pcf.pcf_filtered` (each gathers 10 × 10 texels × S × K).
PCF_CHUNK = 1 << 13
#: Texels per chunk of the per-thread resolve of :mod:`moments_ref.gpu.onchip` (its rows stay in L2).
RESOLVE_CHUNK = 1 << 14
#: Triangles set up per call of the rasterizer (:mod:`moments_ref.scene.raster`): bounds the per-triangle arrays
#: and keeps them in cache (1 M small triangles into 1024²: 2^15 gives 2.4 M/s, 2^17 2.0 M/s, 2^13 2.0 M/s).
RASTER_SETUP_CHUNK = 1 << 15
#: Rows per chunk of the differential sweep (:mod:`moments_ref.sweep`): the unit of determinism (the rows of
#: chunk i depend only on seed, case, profile and i, so it never changes with the machine), one driver dispatch
#: and one reference pass each (the stages' rows/s at this size: ``moments-ref bench --only sweep``).
SWEEP_CHUNK = 1 << 17
#: Point-view pairs per block of :mod:`moments_ref.techniques.vwss.warp`: the temporaries stay in cache and the
#: thin (n, 4) @ (4, 4k) product stays under OpenBLAS's multithreading threshold (m·n·k ≤ 2^18), whose threads
#: cost more than they save on it.
WARP_BLOCK = 1 << 13
#: Points per block of the shading loops of :mod:`moments_ref.techniques.vwss.shading` (likewise for the thin
#: (n, 3) @ (3, 3) product).
SHADING_BLOCK = 1 << 14
#: Bytes of one band of rows of :mod:`moments_ref.gpu.filtering` (about the L2 of one core; a sweep from 256 KiB
#: to 4 MiB at 2048² varied within the noise of a shared machine, 1 MiB at its fastest).
FILTER_BAND_BYTES = 1 << 20
#: Input bytes of one chunk of the resolve of :mod:`moments_ref.gpu.filtering` (its samples, powers
#: and sums stay in L2). 2^19 since issue 41 round eight (a band of the global path at 2048² 4× is
#: one chunk; each chunk's ~25 ufunc calls cost about 1 µs besides their elements): the resolve of a
#: quarter map, min of 15, 9.14 ms at 2^17, 8.06 at 2^18, 7.86 at 2^19; the global NLQ64 path
#: 0.961 (quartiles 0.930–0.993) of its time at 2^17, 15 interleaved pairs, load 2.2–2.5.
RESOLVE_BYTES = 1 << 19
#: Texels per band of :func:`moments_ref.gpu.filtering.global_path_nlq` (a band's float64 rows, about
#: 1.5 MiB at 2048², stay in cache whatever the map size). 2^15 since issue 41 round six: the global
#: NLQ64 path at 2048² 4× took 0.895, 0.942 and 0.969 of the time with 2^17 (interleaved, order
#: rotated, 9–12 rounds, load 5), 0.959 at 1024²; 2^14 and 2^18 were no quicker than 2^17.
PATH_BAND_TEXELS = 1 << 15
#: (triangle, row, sample) rows per vectorized batch of the rasterizer's span expansion
#: (:mod:`moments_ref.scene.raster`), and covered samples per yielded batch: 512 KiB per float64
#: array, so that a batch's temporaries stay in L2 (the in-place span expansion is bandwidth-bound:
#: railing 2048² 4×, 10.4 M samples, CPU time against main, min of 5: 2^19 samples 0.94, 2^16 0.67,
#: 2^14 0.73). Samples per batch 2^18 since issue 41 (the expansion has fewer passes and the batch's
#: fixed costs weigh more): 3 interleaved pairs against 2^16, load about 10: railing 0.84–0.90 of the
#: time, the mid-size case 0.89–0.93, 1 M small triangles 1× and 4× 0.98–1.03.
RASTER_ROW_BUDGET = 1 << 16
RASTER_SAMPLE_BUDGET = 1 << 18

#: Multiple of the dtype's machine epsilon below which B(b) counts as singular
#: (relative to b2 for σ², to max(b4, σ²) for ξ4); see :mod:`moments_ref.msm`.
SINGULAR_RTOL = {"float32": 0.0, "float64": 8.0}


def singular_thresholds(dtype):
    """The relative singularity threshold ``SINGULAR_RTOL[dtype]·eps`` of float32 or float64."""
    dt = float_dtype(dtype)
    return SINGULAR_RTOL[dt.name] * np.finfo(dt).eps


def two_point(b1, b2, b3, sigma2):
    """Depths y1 ≤ y2 and weight v2 of the two-point distribution with moments b1..b3.

    HPG17 Algorithm 2, steps (1)–(5): roots of ``σ² z² + q1 z + q0`` with
    ``q1 = b1 b2 − b3`` and ``q0 = −b1 q1 − b2 σ²``; ``v2 = (b1 − y1)/(y2 − y1)``.
    """
    q1 = b1 * b2 - b3
    q0 = -b1 * q1 - b2 * sigma2
    disc = np.sqrt(np.maximum(q1 * q1 - 4 * sigma2 * q0, 0))
    t = -0.5 * (q1 + np.copysign(disc, q1))
    with np.errstate(divide="ignore", invalid="ignore"):
        ra = t / sigma2
        rb = q0 / t
    y1 = np.minimum(ra, rb)
    y2 = np.maximum(ra, rb)
    gap = y2 - y1
    with np.errstate(divide="ignore", invalid="ignore"):
        v2 = np.clip((b1 - y1) / gap, 0, 1)
    bad = ~np.isfinite(v2)
    if bad.any():  # no usable second depth: all mass at b1
        y1 = np.where(bad, b1, y1)
        y2 = np.where(bad, b1, y2)
        v2 = np.where(bad, 0, v2).astype(b1.dtype)
    return y1, y2, v2


def copysign_inplace(d, h, sign):
    """``d := copysign(d, h)`` for ``d ≥ 0``, by setting d's sign bit from h; returns d.

    Same result as ``np.copysign`` (IEEE sign bit, so −0 counts as negative);
    ``sign`` is an integer array holding only the sign bit (int32 for float32,
    int64 for float64). Two integer passes are several times faster than
    NumPy's float32 copysign loop.
    """
    it = sign.dtype
    bits = np.bitwise_and(h.view(it), sign)
    np.bitwise_or(d.view(it), bits, out=d.view(it))
    return d


def copysign_exact(d, h, sign):
    """``d := np.copysign(d, h)`` for any d (NaN included), by moving h's sign bit into d.

    ``sign`` as in :func:`copysign_inplace`. Three integer passes: clear d's sign
    bit, take h's, or them together; the IEEE result of ``np.copysign`` bit for bit.
    """
    it = sign.dtype
    di = d.view(it)
    np.bitwise_and(di, np.invert(sign), out=di)
    np.bitwise_or(di, np.bitwise_and(h.view(it), sign), out=di)


def _flat_view(a, shape):
    """``a`` reshaped to ``shape`` without copying, or None where that needs a copy."""
    try:
        return np.reshape(a, shape, copy=False)
    except ValueError:
        return None


def broadcast_chunks(b, zf, shape, chunk=None):
    """``(start, stop, b rows (k, m), zf (m,))`` over the broadcast shape, ``chunk`` (default CHUNK) at a time.

    ``b`` has a trailing axis of k moments (4 or 6). The broadcast inputs are never
    materialized: a flat view where one exists, else a gather of the chunk's
    elements, so the peak memory of a call is its outputs plus one chunk of
    temporaries. The rows are one buffer, refilled for every chunk (one transposing
    copy each; a fresh array per chunk measured 8 % slower): use a chunk's rows
    before asking for the next one.
    """
    k = b.shape[-1]
    n = int(np.prod(shape, dtype=np.int64))
    bb, zz = np.broadcast_to(b, shape + (k,)), np.broadcast_to(zf, shape)
    bflat, zflat = _flat_view(bb, (-1, k)), _flat_view(zz, (-1,))
    chunk = CHUNK if chunk is None else chunk
    rows = np.empty((k, min(chunk, n)), dtype=b.dtype)
    for start in range(0, n, chunk):
        stop = min(start + chunk, n)
        if bflat is None or zflat is None:
            idx = np.unravel_index(np.arange(start, stop), shape)
        bc = bflat[start:stop] if bflat is not None else bb[idx]
        zc = zflat[start:stop] if zflat is not None else zz[idx]
        out = rows[:, : stop - start]
        np.copyto(out, bc.T)
        yield start, stop, out, np.ascontiguousarray(zc)
