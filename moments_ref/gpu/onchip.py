"""Block-wise emulation of the HPG17 §4.1 compute shader: resolve, blur and quantize in shared memory.

The shader generates the filtered moment shadow map one output block of 32×24
texels at a time. A thread group of 256 threads (8 warps) loads the 40×32 input
block (output block plus a guard band of 4 texels on every side), resolves the
multisampled depths into moments in a flat float32 shared-memory array laid out as
in HPG17 §4.1 "Memory layout", blurs it horizontally and vertically with the 9-tap
Gaussian (σ = 2.4) in registers, and finally reads out three moment vectors per
thread, quantizes them and writes them to the texture. Device memory is read once
and written once.

This emulation runs the shader's shared-memory accesses literally: every phase
gathers from and scatters to a ``(blocks, words)`` float32 array through the word
addresses of :func:`moments_ref.gpu.banks.access_pattern` and
:func:`moments_ref.gpu.banks.shared_index`, so the accesses whose bank conflicts
:mod:`moments_ref.gpu.banks` counts are the accesses that produce the result here.
Loops run over batches of blocks, phases, rounds and filter taps; everything
inside is vectorized over blocks, warps and lanes. All arithmetic is float32.

Which texels a block covers
---------------------------
Output block ``(bx, by)`` (``bx ∈ 0..⌈W/32⌉−1``, ``by ∈ 0..⌈H/24⌉−1``) produces the
texels ``x ∈ [32·bx, 32·bx + 32)``, ``y ∈ [24·by, 24·by + 24)``, minus those outside
the map (the shader's only conditional, §4.1). Its input block is
``x ∈ [32·bx − 4, 32·bx + 36)``, ``y ∈ [24·by − 4, 24·by + 28)``: the 9-tap filter
needs 4 texels on each side, 32 + 8 = 40 and 24 + 8 = 32. Input coordinates
outside the map are clamped to the edge, as a texture load with clamp addressing
does; that is the border rule of :func:`moments_ref.gpu.filtering.blur`.

Quantization
------------
The readout of the shader quantizes the three vectors each thread reads and
writes the texels. Quantization acts on each texel alone, so
:func:`filter_and_quantize` applies it to the whole float32 map that the emulated
readout assembled; the texels are the same.

Agreement with the reference
----------------------------
``filter_moments(z)`` equals ``blur(resolve_moments(z))`` up to float32 rounding:
:func:`tolerance` gives the bound used by the tests (absolute, since the moments of
depths in [-1, 1] lie in [-1, 1]).

References
----------
.. [1] HPG17: Christoph Peters. 2017. *Non-Linearly Quantized Moment Shadow Maps*. In Proceedings
       of High Performance Graphics (HPG '17). ACM. The non-linear quantization Φ, Ψ4, Algorithms
       1–3, the texel formats and the compute shader of §4.1.
"""

from __future__ import annotations

import time

import numpy as np

from . import banks
from .._arrays import InputError
from .._kernels import RESOLVE_CHUNK
from ..packing import nlq_texels
from .filtering import SIGMA, TAPS, check_depth_samples, gaussian_weights

__all__ = [
    "FORMATS",
    "filter_moments",
    "filter_and_quantize",
    "tolerance",
    "block_grid",
]

#: Texture formats of :func:`filter_and_quantize` and their bits per texel.
FORMATS = {"nlq64": 64, "nlq32": 32, "affine64": 64, "float128": 128}

_OUT_W, _OUT_H = banks.BLOCK_OUT
_IN_W, _IN_H = banks.BLOCK_IN
_G = banks.GUARD
_STAGES = ("resolve", "horizontal", "vertical", "readout")


def block_grid(height, width) -> tuple[int, int]:
    """Number of output blocks ``(rows, columns)`` = ``(⌈H/24⌉, ⌈W/32⌉)`` for an H×W map."""
    return -(-int(height) // _OUT_H), -(-int(width) // _OUT_W)


def tolerance(samples, taps=TAPS) -> float:
    """Absolute float32 tolerance between :func:`filter_moments` and the float64 reference.

    Parameters
    ----------
    samples : int
        MSAA samples per texel.
    taps : int
        Filter taps per pass.

    Returns
    -------
    atol : float
        ``(2·(samples + 7) + 2·(taps + 1)) · u`` with ``u = 2⁻²⁴``, the unit roundoff of
        float32.

    Notes
    -----
    A first-order bound with ``|z| ≤ 1``, so every moment and every partial sum has
    magnitude ≤ 1: rounding the depth to float32 and forming ``z⁴`` costs ≤ 7u, the
    float32 mean of ``samples`` terms ≤ (samples − 1)u + u; both the emulation and
    the reference's own float32 resolve carry this, hence the factor 2. Each
    float32 pass rounds its ``taps`` weights and does ``taps`` products and
    ``taps − 1`` additions of a convex combination: ≤ (taps + 1)u, two passes.
    """
    return float((2 * (int(samples) + 7) + 2 * (int(taps) + 1)) * 2.0**-24)


def _addresses(layout):
    pattern = banks.access_pattern()
    addr = {name: banks.shared_index(p.j, p.x, p.y, layout) for name, p in pattern.items()}
    # The readout's word addresses by destination (moment, row, column of the output block):
    # the threads' loads (each texel's vector is read once), in the texture's order.
    ro = pattern["readout"]
    by_texel = np.full((4, _OUT_H, _OUT_W), -1, dtype=addr["readout"].dtype)
    by_texel[np.arange(4).reshape(1, 4, 1, 1), ro.texel_y, ro.texel_x] = addr["readout"]
    addr["readout by texel"] = by_texel
    # The resolve's word addresses by source (moment, row, column of the input block).
    rs = pattern["resolve"]
    by_input = np.full((4, _IN_H, _IN_W), -1, dtype=addr["resolve"].dtype)
    by_input[np.arange(4).reshape(1, 4, 1, 1), rs.texel_y, rs.texel_x] = addr["resolve"]
    addr["resolve by texel"] = by_input
    return pattern, addr


def _convolve(values, w, n_out, axis):
    """Brute-force convolution in registers, float32: Σ_t w[t]·v[k + t], one tap at a time."""
    def shifted(t):
        s = [slice(None)] * values.ndim
        s[axis] = slice(t, t + n_out)
        return values[tuple(s)]

    acc = w[0] * shifted(0)
    tmp = np.empty_like(acc)
    for t in range(1, len(w)):
        acc += np.multiply(w[t], shifted(t), out=tmp)
    return acc


#: Texels per chunk of :func:`_thread_moments` (its rows stay in L2; moments_ref._kernels' table).
_RESOLVE_CHUNK = RESOLVE_CHUNK


def _thread_moments(z):
    """The 4 moments every resolving thread computes, for each texel of the map: ``(4, H·W)`` float32.

    ``z`` is the ``(H·W, S)`` float32 samples. A thread of the resolve loads the S
    samples of its texel and accumulates, in float32 and in sample order, ``z``,
    ``z²``, ``z²·z`` and ``z²·z²`` from 0, then divides by S. Texels of a guard band
    are resolved by every block that loads them, always to the same values, so each
    texel is computed here once, an L2 chunk of texels at a time (the same
    operations per texel; the chunk's samples are transposed into one contiguous
    row per sample first), and the threads' loads become gathers of these rows.
    """
    n, S = z.shape
    # The division by S; for S a power of two as the product with 1/S (exact: both are
    # the correctly rounded z-sum · 2^-k, also for subnormals), a third of its time.
    inv = np.float32(S)
    scale = np.float32(1.0 / S) if S & (S - 1) == 0 else None
    mom = np.empty((4, n), dtype=np.float32)
    m = min(n, _RESOLVE_CHUNK)
    z2, tmp = np.empty((2, m), dtype=np.float32)
    zt = np.empty((S, m), dtype=np.float32)
    for lo in range(0, n, _RESOLVE_CHUNK):
        hi = min(lo + _RESOLVE_CHUNK, n)
        acc, q, t, zc = mom[:, lo:hi], z2[: hi - lo], tmp[: hi - lo], zt[:, : hi - lo]
        np.copyto(zc, z[lo:hi].T)
        acc[...] = 0
        for s in range(S):
            zs = zc[s]
            np.multiply(zs, zs, out=q)
            acc[0] += zs
            acc[1] += q
            acc[2] += np.multiply(q, zs, out=t)
            acc[3] += np.multiply(q, q, out=t)
        if scale is None:
            acc /= inv
        else:
            acc *= scale
    return mom


def _run_batch(mom, shape, bx, by, out, pattern, addr, words, w, timings):
    """Emulate the thread groups of the blocks ``(bx[i], by[i])`` and write their texels.

    Shared memory is held as ``(words, blocks)``: the blocks of a batch run the same
    program, so every gather or scatter through a word address moves one contiguous
    run of ``blocks`` floats (structure of arrays over thread groups). The
    arithmetic is the same for any arrangement. ``mom`` holds each texel's resolved
    moments (:func:`_thread_moments`) and ``out`` the result, both as ``(4, H·W)``,
    one contiguous row per moment, so that loads and stores are contiguous
    gathers and scatters.
    """
    H, W, S = shape
    nb = len(bx)
    shared = np.zeros((words, nb), dtype=np.float32)
    x0 = _OUT_W * bx - _G
    y0 = _OUT_H * by - _G

    # Resolve: 5 rounds; each thread loads all samples of one texel (clamped to the
    # map), averages b(z) (:func:`_thread_moments`) and writes the 4 moments. The
    # 5 rounds × 4 moments write disjoint words (each input texel's moments once), so
    # their stores are done at once: through the table ordered by input texel from a
    # window of the moment planes, or for blocks at the map's edge from one clamped gather.
    t0 = time.perf_counter()
    inside = (x0 >= 0) & (x0 + _IN_W <= W) & (y0 >= 0) & (y0 + _IN_H <= H)
    # Blocks whose input lies inside the map: a block row's run of them reads one window
    # of the moment planes (overlapping input blocks as a strided view, no clamping).
    for s, e in _runs(by, inside):
        planes = mom.reshape(4, H, W)[:, int(y0[s]) :, int(x0[s]) :]
        win = np.lib.stride_tricks.as_strided(
            planes, (4, _IN_H, _IN_W, e - s), planes.strides + (_OUT_W * planes.strides[2],), writeable=False)
        shared[:, s:e][addr["resolve by texel"]] = win
    edge = np.flatnonzero(~inside)
    if len(edge):
        res = pattern["resolve"]
        tx, ty = res.texel_x[:, 0], res.texel_y[:, 0]  # (round, warp, lane), same for every j
        # The clamped coordinates are separable: a row offset per input row, a column per column.
        col = np.clip(x0[edge] + np.arange(_IN_W)[:, None], 0, W - 1)  # (input column, blocks)
        row = np.clip(y0[edge] + np.arange(_IN_H)[:, None], 0, H - 1) * W  # (input row, blocks)
        texel = row[ty] + col[tx]  # (round, warp, lane, blocks)
        shared[addr["resolve"].swapaxes(0, 1)[..., None], edge] = mom.take(texel, axis=1)  # (j, round, warp, lane, blocks)
    t1 = time.perf_counter()

    # Horizontal blur: 24 loads per thread, 16 results to the non-read-only columns.
    # Loads as ``take`` along the word axis: the same words as ``shared[addr]``, about half the time.
    v = shared.take(addr["horizontal read"], axis=0)  # (warp, 24, lane, blocks)
    shared[addr["horizontal write"]] = _convolve(v, w, 16, axis=1)
    t2 = time.perf_counter()

    # Vertical blur: 20 loads per thread (upper or lower half of the strip), 12 results.
    v = shared.take(addr["vertical read"], axis=0)  # (warp, 20, lane, blocks)
    shared[addr["vertical write"]] = _convolve(v, w, 12, axis=1)
    t3 = time.perf_counter()

    # Readout: each thread reads three complete vectors; out-of-map texels are skipped.
    # The loads are gathered in the texture's order (the same words, each read once), so
    # the blocks of a block row are stored by one strided copy instead of a scatter.
    v = shared.take(addr["readout by texel"], axis=0)  # (moment, row, column, blocks)
    _store_blocks(v, out.reshape(4, H, W), bx, by)
    _record(timings, (t0, t1, t2, t3, time.perf_counter()))


def _runs(by, keep):
    """``(start, stop)`` of the runs of consecutive blocks with the same ``by`` where ``keep`` holds."""
    cut = np.flatnonzero(np.diff(by, prepend=-1) | np.diff(keep.astype(np.int8), prepend=0))
    stops = np.append(cut[1:], len(by))
    return [(int(a), int(b)) for a, b in zip(cut, stops) if keep[a]]


def _store_blocks(v, planes, bx, by):
    """Write the output blocks ``v`` (4, 24, 32, blocks) into the planes (4, H, W), texels outside the map skipped.

    The blocks of a batch are consecutive in raster order, so those of one block row
    have consecutive ``bx``: their texels are one (4, rows, blocks, 32) window of the
    planes (every texel is written once, so this equals the threads' stores).
    """
    H, W = planes.shape[1:]
    starts = np.flatnonzero(np.diff(by, prepend=-1))
    for s, e in zip(starts, np.append(starts[1:], len(by))):
        y0 = _OUT_H * int(by[s])
        ny = min(_OUT_H, H - y0)
        a, c = int(bx[s]), int(bx[e - 1]) + 1
        full = max(a, min(c, W // _OUT_W))  # blocks a .. full − 1 lie inside the map's width
        if full > a:
            dst = planes[:, y0 : y0 + ny, _OUT_W * a : _OUT_W * full].reshape(4, ny, full - a, _OUT_W)
            np.copyto(dst, v[:, :ny, :, s : s + full - a].transpose(0, 1, 3, 2))
        for b in range(full, c):  # the block that the map's right edge cuts
            x0 = _OUT_W * b
            planes[:, y0 : y0 + ny, x0:W] = v[:, :ny, : W - x0, s + b - a]


def _record(timings, t):
    """Add the stage times between the time stamps ``t`` to ``timings`` (if given)."""
    if timings is not None:
        for name, a, b in zip(_STAGES, t[:-1], t[1:]):
            timings[name] = timings.get(name, 0.0) + (b - a)


def filter_moments(depth_samples, *, blocks_per_batch=64, layout="paper", timings=None):
    """Resolve and blur a multisampled shadow map block by block, as the HPG17 §4.1 shader does.

    Parameters
    ----------
    depth_samples : (H, W, S) float array
        Sample depths in [-1, 1]. Converted to float32 (the shader's precision).
    blocks_per_batch : int, keyword-only
        How many thread groups are emulated together. The result does not depend
        on it.
    layout : {"paper", "row-major"}, keyword-only
        Shared-memory layout (:func:`moments_ref.gpu.banks.shared_index`). The result
        does not depend on it either; only the bank conflicts do.
    timings : dict, optional, keyword-only
        If given, seconds per stage (``resolve``, ``horizontal``, ``vertical``,
        ``readout``) are added to it.

    Returns
    -------
    b : (H, W, 4) float32 array
        Filtered moments, equal to ``blur(resolve_moments(depth_samples))`` within
        :func:`tolerance` ``(S)``.

    Raises
    ------
    InputError
        As :func:`moments_ref.gpu.filtering.resolve_moments`.

    Notes
    -----
    HPG17 §4.1 and Figure 6; the access pattern of each phase is written down in
    :mod:`moments_ref.gpu.banks`, the block coverage in this module's docstring.
    """
    out, (H, W) = _filter_rows(depth_samples, blocks_per_batch=blocks_per_batch, layout=layout, timings=timings)
    return np.ascontiguousarray(out.T).reshape(H, W, 4)


def _filter_rows(depth_samples, *, blocks_per_batch=64, layout="paper", timings=None):
    """:func:`filter_moments` as ``(4, H·W)`` rows (the emulation's own layout, one row per moment) and ``(H, W)``."""
    z = check_depth_samples(depth_samples).astype(np.float32, copy=False)
    if isinstance(blocks_per_batch, bool) or not isinstance(blocks_per_batch, (int, np.integer)) or blocks_per_batch < 1:
        raise InputError(f"blocks_per_batch: expected a positive integer, got {blocks_per_batch!r}")
    words = banks.layout_words(layout)
    pattern, addr = _addresses(layout)
    w = gaussian_weights(TAPS, SIGMA).astype(np.float32)
    H, W, _ = z.shape
    rows, cols = block_grid(H, W)
    out = np.empty((4, H * W), dtype=np.float32)
    t0 = time.perf_counter()
    mom = _thread_moments(z.reshape(H * W, -1))
    if timings is not None:
        timings["resolve"] = timings.get("resolve", 0.0) + time.perf_counter() - t0
    ids = np.arange(rows * cols)
    for start in range(0, len(ids), int(blocks_per_batch)):
        b = ids[start : start + int(blocks_per_batch)]
        _run_batch(mom, z.shape, b % cols, b // cols, out, pattern, addr, words, w, timings)
    return out, (H, W)


def filter_and_quantize(depth_samples, fmt="nlq64", **kwargs):
    """The texture the HPG17 §4.1 shader writes: filtered moments in a storage format.

    Parameters
    ----------
    depth_samples : (H, W, S) float array
        Sample depths in [-1, 1].
    fmt : {"nlq64", "nlq32", "affine64", "float128"}
        ``"nlq64"``: bias with ``BIAS_FLOAT32``, ``nonlinear.phi`` (HPG17 Alg. 2),
        ``packing.pack64`` → uint16 (H, W, 4). ``"nlq32"``: same, ``packing.pack32``
        → uint32 (H, W). ``"affine64"``: ``affine.encode_unorm16`` → uint16 (H, W, 4),
        *without* bias: for the affine format biasing (``BIAS_UNORM16``) is the
        shading side's step, after decoding the rounded moments. ``"float128"``:
        the float32 moments (H, W, 4), unbiased.
    **kwargs
        Passed to :func:`filter_moments`.

    Returns
    -------
    texture : array, dtype and shape per format

    Notes
    -----
    HPG17 §4.1 "Readout and quantization" and §3.3 (the float32 bias is applied to
    the filtered single-precision moments before Algorithm 2).
    """
    if fmt not in FORMATS:
        raise InputError(f"fmt: expected one of {tuple(FORMATS)}, got {fmt!r}")
    if fmt in ("nlq64", "nlq32"):
        # Bias, Φ and pack an L2 chunk at a time straight from the emulation's rows:
        # the (H, W, 4) view of the rows reads each chunk as four contiguous runs and
        # spares the transposing copy of filter_moments; the same texel values.
        # The rows are finite (convex combinations of depths in [-1, 1]): nlq_texels checks
        # each chunk's finiteness itself, so quantize_nlq's whole-map check is skipped.
        rows, (H, W) = _filter_rows(depth_samples, **kwargs)
        return nlq_texels(rows.reshape(4, H, W), fmt, planar=True)
    b = filter_moments(depth_samples, **kwargs)
    if fmt == "float128":
        return b
    from ..affine import encode_unorm16

    return encode_unorm16(b)
