"""Texel formats for the non-linear representation: 64 bits (HPG17 §3.3), 32 bits (§3.5).

Both store the output ``(y1, y2, v2, ξ4)`` of HPG17 Algorithm 2
(:func:`moments_ref.nonlinear.phi`). The bit layouts are drawn in docs/formats.md;
they are **stable**: golden vectors and GPU ports depend on them, so a change is a
format version change.

64 bits, :func:`pack64` -> ``uint16 (..., 4)`` (four UNORM16 channels, HPG17 §3.3)::

    channel 0   round(65535 · (y1 + 1)/2)
    channel 1   round(65535 · (y2 + 1)/2)
    channel 2   round(65535 · v2)
    channel 3   ceil(65535 · Ψ4(ξ4))       (rounded up, see below)

Decoding is plain UNORM: ``c / 65535`` (what a texture fetch returns), then
``y = 2 u − 1`` and ``ξ4 = Ψ4⁻¹(u)``.

32 bits, :func:`pack32` -> ``uint32 (...)`` (HPG17 §3.5, Figure 5), LSB first::

    bits  0.. 9  (10 bits)  ỹ2  after the fold
    bits 10..18  ( 9 bits)  ỹ1  after the fold
    bits 19..25  ( 7 bits)  ⌊128 · √v2⌋, at most 127
    bits 26..31  ( 6 bits)  ⌊64 · Ψ4(ξ4)⌋, at most 63

Every field is the index of a *cell*: depths ``ỹ = ⌊511.5 · (y + 1)⌋`` clamped to
0..1022 (y = 1 alone would give 1023; it joins the top cell), √v2 in cells of 1/128,
Ψ4 in cells of 1/64. Since y1 ≤ y2 the pairs (ỹ1, ỹ2) fill a triangle; the fold of
Figure 5 replaces ``ỹ1, ỹ2`` by ``1023 − ỹ1, 1022 − ỹ2`` when ``ỹ1 ≥ 512``, after
which ``ỹ1 ≤ 511`` fits 9 bits and ``ỹ2 ≤ 1022`` fits 10 bits. A stored pair with
``ỹ2 < ỹ1`` was folded (unfolded pairs keep ỹ1 ≤ ỹ2, folded ones have
``1022 − ỹ2 < 1023 − ỹ1``), so the decoder inverts the fold without a flag.

The decoder reads each cell at a *decode position* (:data:`DECODE32`), chosen by
HPG17 §3.5's principle: "During loading, we ensure that it is rounded up to
guarantee a lower bound to the shadow intensity". Depths decode at the **upper**
end of their cell, ``y = (ỹ + 1)/511.5 − 1`` (an occluder never moves towards the
light: the error is in [0, 1/511.5)); Ψ4 at the upper end ``(c + 1)/64`` (the lower
bound of Algorithm 1 never increases with ξ4); √v2 at the **centre** ``(c + ½)/128``,
so that v2 is never exactly 0 or 1 (a decoded v2 of 0 or 1 drops a depth and
over-shadows by up to 0.8, docs/formats.md). These are the positions of the HPG17
demo's decoder; docs/formats.md has the measurements behind them, and ``unpack32``
takes the positions as keyword arguments (``depth_decode``, ``v2_decode``,
``xi_decode``) for the variants ports implement.

Lower bound guarantee. The decoded ξ4 is never below the stored one (after the
clamp of Ψ4 at 1.2e-7): the 32-bit decoder reads the upper end of the Ψ4 cell, the
64-bit encoder stores ``ceil(65535 Ψ4)`` (``xi_rounding="up"``) because a UNORM
fetch cannot round up. Floating-point rounding in Ψ4 and Ψ4⁻¹ could still put the
decoded value one ulp low; the encoders check the decoded value in the working
dtype and bump the code where needed, so the guarantee is exact (tested
exhaustively over the 64 codes).

Input. Encoders saturate each quantity onto its stored range (y1, y2 to [-1, 1],
v2 to [0, 1], ξ4 ≥ 0) as a UNORM texture write does: float32 Algorithm 2 on real
maps leaves the domain by more than rounding (y1 = −1.0026 measured). They raise
:class:`~moments_ref.InputError` for non-finite values and for y1 > y2 beyond
:func:`moments_ref.nonlinear.rounding_tolerance`. Decoders take only uint16/uint32 and a
``dtype`` keyword (float64 default, float32 to emulate a GPU).

References
----------
.. [1] HPG17: Christoph Peters. 2017. *Non-Linearly Quantized Moment Shadow Maps*. In Proceedings
       of High Performance Graphics (HPG '17). ACM. The non-linear quantization Φ, Ψ4, Algorithms
       1–3, the texel formats and the compute shader of §4.1.
.. [2] HPG17 demo: The demo code accompanying HPG17 (Direct3D; C. Peters), whose 32-bit texel
       functions ``QuantizeMomentsNonLinear32Bit`` and ``UnpackMomentsNonLinear32Bit`` are public
       in engine code ported from it, e.g. the repository kingofthebongo2008/UCEngine,
       ``src/uc_dev/private/gx/dx12/shaders/shadows/moment_shadow_maps_32.hlsli`` and
       ``shadows.hlsli`` (cited for their behaviour; no code is copied). Its 64-bit format is a
       UNORM16 render-target write (``moment_shadow_maps_64.hlsli``).
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np

from ._arrays import InputError, as_array, first_index, float_dtype, real_input
from ._docs import fill_doc
from ._kernels import ENCODE_CHUNK
from .moments import BIAS_FLOAT32, bias_moments
from .nonlinear import (PSI4_XI_MAX, PSI4_XI_MIN, phi_rows, psi4_clamped, phi, psi4_inverse,
                        rounding_tolerance, validate_representation)

__all__ = [
    "pack64",
    "unpack64",
    "pack32",
    "unpack32",
    "fold",
    "unfold",
    "depth_code",
    "Y_BITS",
    "Y1_SHIFT",
    "Y1_BITS",
    "Y2_SHIFT",
    "Y2_BITS",
    "V_SHIFT",
    "V_BITS",
    "XI_SHIFT",
    "XI_BITS",
    "V_CELLS",
    "XI_CELLS",
    "DECODE_POSITIONS",
    "DECODE32",
    "XI_ROUNDINGS",
    "DEPTH_STEP32",
    "DEPTH_STEP64",
    "nlq_texels",
    "saturate",
]

# 32-bit layout (stable): field shifts and widths.
Y2_SHIFT, Y2_BITS = 0, 10
Y1_SHIFT, Y1_BITS = 10, 9
V_SHIFT, V_BITS = 19, 7
XI_SHIFT, XI_BITS = 26, 6
#: Bits used by both depths together after the fold (HPG17 §3.5).
Y_BITS = Y1_BITS + Y2_BITS

#: √v2 is stored in cells of width 1/128, Ψ4(ξ4) in cells of width 1/64 (the field's code range).
V_CELLS = 1 << V_BITS
XI_CELLS = 1 << XI_BITS
_V_MAX = V_CELLS - 1  # 127
_XI_MAX = XI_CELLS - 1  # 63
_U16 = 65535

#: Where a decoder reads a cell ``[c, c + 1)``: offset from the cell's lower end, in cells.
DECODE_POSITIONS = {"lower": 0.0, "centre": 0.5, "upper": 1.0}
#: The 32-bit format's decode positions (HPG17 §3.5's principle; the HPG17 demo's decoder):
#: depths and Ψ4 at the upper end of their cell, √v2 at its centre. Keyword defaults of
#: :func:`unpack32` (``depth_decode``, ``v2_decode``, ``xi_decode``).
DECODE32 = {"depth": "upper", "v2": "centre", "xi": "upper"}
#: Roundings of the 64-bit Ψ4 code (:func:`pack64`'s ``xi_rounding``): "up" (ours, the
#: lower-bound guarantee) and "nearest" (a UNORM render-target write, the HPG17 demo).
XI_ROUNDINGS = ("up", "nearest")

#: Width of a 32-bit depth cell, 1/511.5; a decoded depth lies in [y, y + DEPTH_STEP32).
DEPTH_STEP32 = 1 / 511.5
#: Width of a 64-bit depth step, 2/65535; decoded depths are within half of it.
DEPTH_STEP64 = 2 / 65535


def _encoder_input(r):
    """Float copy of r saturated onto the stored ranges, as a UNORM texture write does.

    y1, y2 -> [-1, 1], v2 -> [0, 1], ξ4 -> [0, ∞) (Ψ4 clamps it at 1.2e-7 anyway).
    float32 Φ on real filtered maps leaves this domain by more than rounding
    (measured: y1 = −1.0026 for mass near depth −1 on a 2048² 4× MSAA map, where the
    exact y1 lies in [-1, 1] by proofs/lemma_1); a GPU writing the texel
    saturates, and so do the encoders. Only an inconsistent order, y1 > y2 by more
    than :func:`~moments_ref.nonlinear.rounding_tolerance`, and non-finite values are
    refused.
    """
    r = real_input(r, "r", trailing=4)
    tol = rounding_tolerance(r.dtype)
    bad = r[..., 0] > r[..., 1] + tol
    if bad.any():
        idx = first_index(bad)
        raise InputError(f"r: expected y1 <= y2 (rounding tolerance {tol:.3g}), got y1 = {r[idx][0]!r}, "
                         f"y2 = {r[idx][1]!r} at index {idx}")
    r = np.array(r, copy=True)
    np.clip(r[..., :2], -1, 1, out=r[..., :2])
    np.maximum(r[..., 1], r[..., 0], out=r[..., 1])
    np.clip(r[..., 2], 0, 1, out=r[..., 2])
    np.maximum(r[..., 3], 0, out=r[..., 3])
    return r


@fill_doc
def saturate(r):
    """What the encoders store before quantizing: ``r`` saturated onto the stored ranges.

    Parameters
    ----------
    %(r)s

    Returns
    -------
    (..., 4) float array (a copy): y1, y2 clipped to [-1, 1] with y2 ≥ y1, v2 to [0, 1],
    ξ4 ≥ 0, as a UNORM texture write does; InputError for non-finite values and for
    y1 > y2 beyond rounding.
    """
    return _encoder_input(r)


#: Texels per chunk of the encoders (the value and its reason: :data:`moments_ref._kernels.ENCODE_CHUNK`).
_ENCODE_CHUNK = ENCODE_CHUNK


@lru_cache(maxsize=4)
def _bounds(dtype):
    """Constant rows of one chunk: -1, 0, 1, Ψ4's clamp bounds (read-only).

    Speed: NumPy's maximum/minimum against a constant *array* are vectorized, its
    clip and maximum against a scalar are not (about 2× slower); for finite values
    ``clip(x, a, b) = minimum(maximum(x, a), b)`` exactly.
    """
    dt = np.dtype(dtype)
    out = {k: np.full(_ENCODE_CHUNK, v, dtype=dt) for k, v in
           (("-1", -1), ("0", 0), ("1", 1), ("xi_min", dt.type(PSI4_XI_MIN)), ("xi_max", dt.type(PSI4_XI_MAX)))}
    for v in out.values():
        v.flags.writeable = False
    return out


def _encoder_rows(r):
    """``(start, stop, rows, bounds)`` over the texels of r: rows ``(y1, y2, v2, ξ4)`` saturated as by :func:`_encoder_input`.

    Speed: one transposing copy per L2-sized chunk (structure of arrays), the
    saturation in place on contiguous rows, the checks per chunk; the same
    operations per element as :func:`_encoder_input`, so the same values. A chunk
    that fails a check hands the whole array to :func:`_encoder_input`, which
    raises the error it always raised (first bad index of r). ``bounds`` are the
    rows of :func:`_bounds` cut to the chunk.
    """
    flat = r.reshape(-1, 4)
    tol = r.dtype.type(rounding_tolerance(r.dtype))
    full = _bounds(r.dtype)
    for lo in range(0, flat.shape[0], _ENCODE_CHUNK):
        rows = np.array(flat[lo : lo + _ENCODE_CHUNK].T, order="C")
        m = rows.shape[1]
        c = full if m == _ENCODE_CHUNK else {k: v[:m] for k, v in full.items()}
        if not _saturated(rows, c, tol):
            _encoder_input(r)  # raises
        yield lo, lo + m, rows, c


def _all_finite(rows):
    """``np.isfinite(rows).all()`` of a non-empty array, decided by its minimum and maximum.

    Speed: a NaN propagates through ``np.minimum``/``np.maximum`` and an infinity is an
    extreme, so finite extremes prove every value finite; the two vectorized
    reductions take about half the time of one pairwise sum, and cannot overflow.
    """
    return math.isfinite(np.maximum.reduce(rows, axis=None)) and math.isfinite(np.minimum.reduce(rows, axis=None))


def _saturated(rows, c, tol, ordered=False, extremes=None):
    """Saturate the rows ``(y1, y2, v2, ξ4)`` in place as :func:`_encoder_input` does; False (rows untouched) if they fail its checks.

    ``ordered``: y1 ≤ y2 holds on every texel (Φ's output: ``fmin``/``fmax`` of the same
    two roots), so the order check and ``y2 = max(y2, y1)`` (which clamping both keeps)
    are skipped. A clamp runs only where a chunk's extremes leave its range (reductions
    instead of passes; a skipped clamp would have returned every value unchanged).
    ``extremes``: the rows' ``(minima, maxima)`` where the caller has them (:func:`phi_rows`).
    """
    y1, y2, v2, xi4 = rows
    # Each row's extremes, taken before any clamp: a NaN propagates through min and max and
    # an infinity is an extreme, so finite extremes prove every value finite (no sum needed).
    mn, mx = np.minimum.reduce, np.maximum.reduce
    lo, hi = extremes if extremes is not None else ([mn(x) for x in rows], [mx(x) for x in rows])
    if not all(map(math.isfinite, lo + hi)) or (not ordered and (y1 > y2 + tol).any()):
        return False
    for k, y in enumerate((y1, y2)):
        if not (lo[k] >= -1 and hi[k] <= 1):
            np.maximum(y, c["-1"], out=y)
            np.minimum(y, c["1"], out=y)
    if not ordered:
        np.maximum(y2, y1, out=y2)
    if not (lo[2] >= 0 and hi[2] <= 1):
        np.maximum(v2, c["0"], out=v2)
        np.minimum(v2, c["1"], out=v2)
    if not lo[3] >= 0:
        np.maximum(xi4, c["0"], out=xi4)
    return True


@lru_cache(maxsize=None)
def _decoded_xi64(dtype):
    """``psi4_inverse(c / 65535)`` for every 16-bit code c (what :func:`unpack64` decodes), read-only."""
    dt = np.dtype(dtype)
    t = psi4_inverse(np.arange(_U16 + 1).astype(dt) / dt.type(_U16))
    t.flags.writeable = False
    return t


@lru_cache(maxsize=None)
def _decoded_xi32(dtype):
    """:func:`_decode_xi32` of every 6-bit code, read-only."""
    t = _decode_xi32(np.arange(_XI_MAX + 1), dtype)
    t.flags.writeable = False
    return t


def _xi_codes(xi4, scale, rounding, table, c):
    """The Ψ4 code of saturated ξ4 rows, ``rounding`` (np.ceil, np.floor or np.rint) of ``Ψ4 · scale``.

    ``code = min(rounding(Ψ4(clamp(ξ4))·scale), len(table) − 1)``, then ``code + 1``
    where the code's decoded ξ4 is below the clamped ξ4 (float rounding of Ψ4 and
    Ψ4⁻¹) and the code is not the largest; the decoded value of a code is looked up
    in ``table`` (the decoder applied once to every code) instead of evaluating Ψ4⁻¹
    (two exp) per texel. ``table`` None: no decode check (rounding to nearest).
    """
    x = np.maximum(xi4, c["xi_min"])
    np.minimum(x, c["xi_max"], out=x)
    u = psi4_clamped(x, c["0"], c["1"])
    u *= scale
    rounding(u, out=u)
    if table is None:
        return u.astype(np.intp)
    # The codes are small integers, exact in u's dtype: the clamp to the largest code where a
    # chunk reaches it (Ψ4 ≤ 1, so ceil(65535 Ψ4) never does; ⌊64 Ψ4⌋ at Ψ4 = 1 does), then int32.
    cmax = len(table) - 1
    if np.maximum.reduce(u) > cmax:
        np.minimum(u, cmax, out=u)
    code = u.astype(np.int32)
    # The bump: the largest code decodes to Ψ4⁻¹(1) ≥ XI_MAX ≥ x (tests/test_packing.py), so
    # "table[code] < x" already implies "code < cmax".
    low = np.take(table, code) < x
    code += low
    return code


def _choice(value, name, allowed):
    """``value`` if it is one of ``allowed``, else InputError naming the argument."""
    if not isinstance(value, str) or value not in allowed:
        raise InputError(f"{name}: expected one of {', '.join(map(repr, allowed))}, got {value!r}")
    return value


def _uint_input(q, name, dtype, trailing=None):
    """An unsigned array of exactly ``dtype``'s width (any byte order), native, or InputError."""
    q = as_array(q, name, "an integer array")
    want = np.dtype(dtype)
    if q.dtype.kind != "u" or q.dtype.itemsize != want.itemsize:
        raise InputError(f"{name}: expected an array of dtype {want}, got dtype {q.dtype}")
    if trailing is not None and (q.ndim == 0 or q.shape[-1] != trailing):
        raise InputError(f"{name}: expected a trailing axis of length {trailing}, got shape {q.shape}")
    return q.astype(want, copy=False)


def _codes(x, name, hi):
    """Integer codes in ``0..hi`` as int64, or InputError (floats, NaN, strings, out of range)."""
    a = as_array(x, name, "an integer array")
    if a.dtype.kind not in "iu":
        raise InputError(f"{name}: expected an integer array of codes in 0..{hi}, got dtype {a.dtype}")
    bad = (a < 0) | (a > hi)
    if bad.any():
        idx = first_index(bad)
        raise InputError(f"{name}: expected codes in 0..{hi}, got {a[idx]!r} at index {idx}")
    return a.astype(np.int64)


# ---------------------------------------------------------------------------
# 64 bits


@fill_doc
def pack64(r, *, xi_rounding="up"):
    """Store ``(y1, y2, v2, ξ4)`` in four UNORM16 channels (HPG17 §3.3).

    Parameters
    ----------
    %(r)s
    xi_rounding : {"up", "nearest"}
        The Ψ4 code: ``"up"`` (default) ``ceil(65535·Ψ4(ξ4))`` and the decode check,
        so the decoded ξ4 is never below the stored one (HPG17 §3.5's principle, which
        the paper states for 32 bits only); ``"nearest"`` ``round(65535·Ψ4(ξ4))``,
        what a UNORM render-target write does (the HPG17 demo). docs/formats.md
        measures both.

    Returns
    -------
    q : (..., 4) uint16 array
        ``round(65535·(y1+1)/2)``, ``round(65535·(y2+1)/2)``, ``round(65535·v2)``,
        the Ψ4 code.

    See Also
    --------
    moments_ref.gpu.filtering.quantize_nlq, moments_ref.gpu.filtering.global_path_nlq :
        the same bits for whole maps, a chunk at a time (docs/formats.md, "From depth
        samples to texels, fast").

    Notes
    -----
    HPG17 §3.3: "Storing the depths y1, y2 ∈ [-1, 1] to the first two channels
    directly works well. The weight v2 ∈ [0, 1] can also be stored directly",
    plus Ψ4(ξ4) in the fourth channel. The arithmetic runs in r's dtype.

    Examples
    --------
    >>> pack64([-1.0, 1.0, 0.5, 0.25])
    array([    0, 65535, 32768, 65535], dtype=uint16)
    """
    return _pack(r, "nlq64", _choice(xi_rounding, "xi_rounding", XI_ROUNDINGS))


def _encode64(rows, c, out, xi_rounding="up"):
    """:func:`pack64` of saturated rows ``(y1, y2, v2, ξ4)`` (overwritten) into ``out`` (m, 4) uint16."""
    y1, y2, v2, xi4 = rows
    dt = rows.dtype.type
    scale = dt(_U16)
    # Channels 0, 1: round(65535 · (y + 1)/2). (y + 1)·0.5 is exact (y + 1 is 0 or normal
    # for |y| ≤ 1), so ((y + 1)·0.5)·65535 and (y + 1)·32767.5 round the same product: one pass.
    for k, y in enumerate((y1, y2)):
        y += 1
        y *= dt(_U16 / 2)
        out[:, k] = np.rint(y, out=y)
    # Channel 2: round(65535 · v2); channel 3: ceil(65535 · Ψ4(ξ4)) bumped up, or round.
    v2 *= scale
    out[:, 2] = np.rint(v2, out=v2)
    if xi_rounding == "up":
        out[:, 3] = _xi_codes(xi4, scale, np.ceil, _decoded_xi64(rows.dtype), c)
    else:
        out[:, 3] = _xi_codes(xi4, scale, np.rint, None, c)


def unpack64(q, dtype=np.float64):
    """Decode :func:`pack64` texels: UNORM16 -> ``(y1, y2, v2, ξ4)``.

    Parameters
    ----------
    q : (..., 4) uint16 array
    dtype : {float64, float32}
        Working and output dtype (float32 emulates a shader).

    Returns
    -------
    r : (..., 4) float array
        ``y = 2 c/65535 − 1``, ``v2 = c/65535``, ``ξ4 = Ψ4⁻¹(c/65535)``. Decoded
        depths satisfy y1 ≤ y2 whenever the encoded ones did.

    Examples
    --------
    >>> unpack64(np.array([0, 65535, 65535, 0], dtype=np.uint16))
    array([-1.0e+00,  1.0e+00,  1.0e+00,  1.2e-07])
    """
    q = _uint_input(q, "q", np.uint16, trailing=4)
    dt = float_dtype(dtype)
    u = q.astype(dt) / dt.type(_U16)
    r = np.empty(q.shape, dtype=dt)
    r[..., 0] = 2 * u[..., 0] - 1
    r[..., 1] = 2 * u[..., 1] - 1
    r[..., 2] = u[..., 2]
    r[..., 3] = psi4_inverse(u[..., 3])
    return r


# ---------------------------------------------------------------------------
# 32 bits


def depth_code(y):
    """HPG17 §3.5: ``ỹ = ⌊511.5 · (y + 1)⌋`` for y ∈ [-1, 1], clamped to 0..1022.

    Parameters
    ----------
    y : (...) float array in [-1, 1]

    Returns
    -------
    code : (...) int64 array in 0..1022 (y = 1 alone maps to 1022, not 1023)
    """
    y = real_input(y, "y")
    c = np.floor(y.dtype.type(511.5) * (y + 1)).astype(np.int64)
    return np.clip(c, 0, 1022)


def fold(t1, t2):
    """The triangle fold of HPG17 Figure 5 on integer depth codes ``t1 ≤ t2``.

    Parameters
    ----------
    t1, t2 : (...) integer arrays with ``0 ≤ t1 ≤ t2 ≤ 1022`` (other codes, float or
        string arrays raise :class:`~moments_ref.InputError`)

    Returns
    -------
    f1, f2 : (...) int64 arrays
        ``(t1, t2)`` if ``t1 < 512``, else ``(1023 − t1, 1022 − t2)``; always
        ``f1 ≤ 511`` (9 bits) and ``f2 ≤ 1022`` (10 bits).
    """
    t1, t2 = _codes(t1, "t1", 1022), _codes(t2, "t2", 1022)
    shape = _pair_shape(t1, t2)
    bad = np.broadcast_to(t1 > t2, shape)
    if bad.any():
        idx = first_index(bad)
        raise InputError(f"t2: expected t1 <= t2, got t1 = {np.broadcast_to(t1, shape)[idx]!r}, "
                         f"t2 = {np.broadcast_to(t2, shape)[idx]!r} at index {idx}")
    flip = t1 >= 512
    return np.where(flip, 1023 - t1, t1), np.where(flip, 1022 - t2, t2)


def _pair_shape(a, b):
    try:
        return np.broadcast_shapes(a.shape, b.shape)
    except ValueError:
        raise InputError(f"expected broadcastable code arrays, got shapes {a.shape} and {b.shape}") from None


def unfold(f1, f2):
    """Inverse of :func:`fold`: a pair with ``f2 < f1`` was folded.

    ``f1`` takes 9 bits (0..511), ``f2`` 10 bits (0..1023); other codes are refused.
    """
    f1, f2 = _codes(f1, "f1", 511), _codes(f2, "f2", 1023)
    _pair_shape(f1, f2)
    flipped = f2 < f1
    return np.where(flipped, 1023 - f1, f1), np.where(flipped, 1022 - f2, f2)


@fill_doc
def pack32(r):
    """Pack ``(y1, y2, v2, ξ4)`` into one uint32 (HPG17 §3.5, Figure 5).

    Parameters
    ----------
    %(r)s

    Returns
    -------
    p : (...) uint32 array
        Layout (LSB first): ỹ2 (10 bits), ỹ1 (9 bits) after the fold,
        ``min(⌊128 √v2⌋, 127)`` (7 bits), ``min(⌊64 Ψ4(ξ4)⌋, 63)`` (6 bits, bumped
        where float rounding would decode it below ξ4); see the module docstring and
        docs/formats.md.

    See Also
    --------
    moments_ref.gpu.filtering.quantize_nlq, moments_ref.gpu.filtering.global_path_nlq :
        the same bits for whole maps, a chunk at a time (docs/formats.md, "From depth
        samples to texels, fast").

    Notes
    -----
    HPG17 §3.5: Ψ4(ξ4) "is simply stored as fixed-point number in six bits",
    √v2 "as fixed-point number in seven bits", and the depths as
    ``ỹl = ⌊511.5 (yl + 1)⌋`` with the fold "if ỹ1 ≥ 512, the integers ỹ1 and ỹ2
    are replaced by 1023 − ỹ1 and 1022 − ỹ2". The paper leaves the fixed-point
    scale open; the cells of 1/128 and 1/64, truncated, are the HPG17 demo's, whose
    decoder reads them at the positions :data:`DECODE32`.

    Examples
    --------
    >>> p = pack32([-0.5, 0.5, 0.25, 1e-4])
    >>> unpack32(p).round(2)
    array([-0.5 ,  0.5 ,  0.25,  0.  ])
    """
    return _pack(r, "nlq32")


def _encode32(rows, c, out):
    """:func:`pack32` of saturated rows ``(y1, y2, v2, ξ4)`` (overwritten) into ``out`` (m,) uint32."""
    y1, y2, v2, xi4 = rows
    dt = rows.dtype.type
    # Depth codes clip(⌊511.5 (y + 1)⌋, 0, 1022) (:func:`depth_code`), kept as floats:
    # small integers are exact, and the fold needs no integer temporaries.
    for y in (y1, y2):
        y += 1
        y *= dt(511.5)
        np.floor(y, out=y)
        np.maximum(y, c["0"], out=y)
        np.minimum(y, 1022, out=y)
    # The fold of Figure 5 (:func:`fold`): ỹ1 ≥ 512 -> (1023 − ỹ1, 1022 − ỹ2).
    flip = y1 >= 512
    np.subtract(1023, y1, out=y1, where=flip)
    np.subtract(1022, y2, out=y2, where=flip)
    # min(⌊128 √v2⌋, 127) and min(⌊64 Ψ4(ξ4)⌋, 63) (bumped up where it decodes below ξ4);
    # the scales are powers of two, so the products are exact.
    np.sqrt(v2, out=v2)
    v2 *= dt(V_CELLS)
    np.floor(v2, out=v2)
    np.minimum(v2, _V_MAX, out=v2)
    xcode = _xi_codes(xi4, dt(XI_CELLS), np.floor, _decoded_xi32(rows.dtype), c)
    # Shift and or, in uint32 (every field fits its bits; ỹ2 sits at Y2_SHIFT = 0).
    out[:] = y2
    out |= y1.astype(np.uint32) << Y1_SHIFT
    out |= v2.astype(np.uint32) << V_SHIFT
    out |= xcode.astype(np.uint32) << XI_SHIFT


# ---------------------------------------------------------------------------
# moments -> texels in one pass


def _texel_output(lead_shape, fmt):
    """Empty texels of ``fmt`` for ``lead_shape`` texels and their flat view (one row or entry per texel)."""
    if fmt == "nlq64":
        out = np.empty(lead_shape + (4,), np.uint16)  # four UNORM16 channels
        return out, out.reshape(-1, 4)
    out = np.empty(lead_shape, np.uint32)
    return out, out.reshape(-1)


def _pack(r, fmt, xi_rounding="up"):
    """:func:`pack64` / :func:`pack32`: encode ``r`` in L2 chunks of rows; finiteness checked per chunk."""
    r = real_input(r, "r", trailing=4, finite=False)
    out, flat = _texel_output(r.shape[:-1], fmt)
    encode = _encoder(fmt, xi_rounding)
    for lo, hi, rows, c in _encoder_rows(r):
        encode(rows, c, flat[lo:hi])
    return out


def _encoder(fmt, xi_rounding):
    """The encoder of ``fmt`` (rows, c, out), the 64-bit one with its Ψ4 rounding."""
    if fmt == "nlq32":
        return _encode32
    return lambda rows, c, out: _encode64(rows, c, out, xi_rounding)


def nlq_texels(b, fmt="nlq64", *, xi_rounding="up", out=None, planar=False):
    """``pack64(phi(bias_moments(b, BIAS_FLOAT32)))`` (or pack32) bit for bit, one L2 chunk at a time.

    Parameters
    ----------
    b : (..., 4) float array, or (4, ...) with ``planar``
        Moments b1..b4 (float32 in the shader), not yet biased.
    fmt : {"nlq64", "nlq32"}
    xi_rounding : {"up", "nearest"}
        The 64-bit Ψ4 code's rounding (:func:`pack64`); the 32-bit format has one.
    out : C-contiguous array of the result's shape and dtype, optional
        Where to write the texels (a band of a larger texture: no copy); returned.
    planar : bool
        ``b`` holds the moments as four planes b1..b4 (structure of arrays, as a
        band of :func:`moments_ref.gpu.filtering.global_path_nlq`): each chunk's rows
        are read contiguously, the bias's scaling doing the copy, with no transposition.
        Errors name the texel and moment as for ``np.moveaxis(b, 0, -1)``.

    Returns
    -------
    texels : (..., 4) uint16 (nlq64) or (...) uint32 (nlq32)

    Notes
    -----
    HPG17 §3.2 (bias), Algorithm 2 (Φ), §3.3 / §3.5 (the formats). Speed: each chunk
    is transposed once into rows (structure of arrays) and stays there through
    the bias, Φ and the encoder, instead of three whole-array passes with a
    transposition each; every step is elementwise with the operations of the
    separate functions, so the texels are the same. Input that any of the three
    would refuse goes through them (and raises their error).
    """
    if fmt not in ("nlq64", "nlq32"):
        raise InputError(f"fmt: expected 'nlq64' or 'nlq32', got {fmt!r}")
    encode = _encoder(fmt, _choice(xi_rounding, "xi_rounding", XI_ROUNDINGS))
    if planar:
        b = real_input(b, "b", finite=False)
        if b.ndim == 0 or b.shape[0] != 4:
            raise InputError(f"b: expected four planes b1..b4 on the first axis, got shape {b.shape}")
        b = np.moveaxis(b, 0, -1)  # a view; the chunks read its planes
    else:
        b = real_input(b, "b", trailing=4, finite=False)
    if out is None:
        out, oflat = _texel_output(b.shape[:-1], fmt)
    else:
        oflat = _checked_out(out, b.shape[:-1], fmt)
    flat = b.reshape(-1, 4)  # planar: (4, N) planes seen transposed (a view when they are contiguous)
    scale, shift = _bias_rows(b.dtype)
    tol = b.dtype.type(rounding_tolerance(b.dtype))
    full = _bounds(b.dtype)
    n = min(_ENCODE_CHUNK, flat.shape[0])
    res = np.empty((4, n), dtype=b.dtype)
    # Texels whose moments lie in four planes (``planar``, or a transposed view of them)
    # are read a plane at a time, the scaling doing the copy; others are transposed first.
    in_planes = flat.strides[0] == flat.itemsize
    buf = np.empty((4, n), dtype=b.dtype) if in_planes else None
    for lo in range(0, flat.shape[0], _ENCODE_CHUNK):
        # Bias: b·(1 − α) + α b* (moments.bias_moments), row k gets α b*_k (a scalar
        # per row: NumPy's array + scalar loop is vectorized, a broadcast column is not).
        if in_planes:
            rows = np.multiply(flat[lo : lo + _ENCODE_CHUNK].T, scale, out=buf[:, : min(n, flat.shape[0] - lo)])
        else:
            rows = np.array(flat[lo : lo + _ENCODE_CHUNK].T, order="C")
            rows *= scale
        m = rows.shape[1]
        c = full if m == _ENCODE_CHUNK else {k: v[:m] for k, v in full.items()}
        if not _all_finite(rows):  # (1 − α)·x is finite exactly where x is
            return _nlq_separately(b, fmt, xi_rounding, out)
        for k in range(4):
            rows[k] += shift[k]
        extremes = phi_rows(rows, res[:, :m])
        if not _saturated(res[:, :m], c, tol, ordered=True, extremes=extremes):
            return _nlq_separately(b, fmt, xi_rounding, out)
        encode(res[:, :m], c, oflat[lo : lo + m])
    return out


def _nlq_separately(b, fmt, xi_rounding="up", out=None):
    """The three steps of :func:`nlq_texels` one after the other (the reference, and the error path)."""
    r = phi(bias_moments(b, BIAS_FLOAT32))
    t = pack64(r, xi_rounding=xi_rounding) if fmt == "nlq64" else pack32(r)
    if out is None:
        return t
    out[...] = t
    return out


def _checked_out(out, lead_shape, fmt):
    """The flat view (one row or entry per texel) of a caller's ``out`` for ``lead_shape`` texels of ``fmt``."""
    want, dt = (lead_shape + (4,), np.uint16) if fmt == "nlq64" else (lead_shape, np.uint32)
    if not isinstance(out, np.ndarray) or out.shape != want or out.dtype != dt or not out.flags.c_contiguous:
        got = f"shape {out.shape}, dtype {out.dtype}" if isinstance(out, np.ndarray) else type(out).__name__
        raise InputError(f"out: expected a C-contiguous {np.dtype(dt).name} array of shape {want}, got {got}")
    return out.reshape(-1, 4) if fmt == "nlq64" else out.reshape(-1)


@lru_cache(maxsize=4)
def _bias_rows(dtype):
    """``(1 − α, α b*)`` of BIAS_FLOAT32 in dtype, as :func:`moments_ref.moments.bias_moments` computes them (α b* as scalars)."""
    dt = np.dtype(dtype).type
    alpha = dt(BIAS_FLOAT32.alpha)
    shift = alpha * np.asarray(BIAS_FLOAT32.target, dtype=dtype)
    return dt(1) - alpha, tuple(shift)


def _decode_xi32(code, dt, xi_decode="upper"):
    """6-bit Ψ4 code -> ξ4: ``Ψ4⁻¹((c + offset)/64)``, by default at the upper end of its cell."""
    dt = np.dtype(dt)
    u = (code.astype(dt) + dt.type(DECODE_POSITIONS[xi_decode])) / dt.type(XI_CELLS)
    return psi4_inverse(u)


def unpack32(p, dtype=np.float64, *, depth_decode="upper", v2_decode="centre", xi_decode="upper"):
    """Decode :func:`pack32` texels -> ``(y1, y2, v2, ξ4)``.

    Parameters
    ----------
    p : (...) uint32 array
    dtype : {float64, float32}
        Working and output dtype (float32 emulates a shader).
    depth_decode, v2_decode, xi_decode : {"lower", "centre", "upper"}
        Where each field's cell is read (:data:`DECODE_POSITIONS`: offset 0, ½ or 1
        cell). The defaults (:data:`DECODE32`) are the format's, chosen by HPG17
        §3.5's lower-bound principle and measured in docs/formats.md; the others
        are the variants a port may implement (the oracle's profiles pass them).

    Returns
    -------
    r : (..., 4) float array
        After undoing the fold, by default: depths at the upper end of their cell
        ``(ỹ + 1)/511.5 − 1`` (never in front of the packed depth), ``v2 = ((c + ½)/128)²``
        (never 0 or 1), ``ξ4 = Ψ4⁻¹((c + 1)/64)`` (never below the packed ξ4).

    Examples
    --------
    >>> r = unpack32(np.array([0], dtype=np.uint32))[0]
    >>> r[:2]  # both depths in the lowest cell, read at its upper end
    array([-0.99804497, -0.99804497])
    >>> float(r[2]) == (0.5 / 128) ** 2  # √v2 code 0 read at its cell's centre
    True
    >>> bool(r[3] > 1.2e-7)  # the lowest Ψ4 code decodes rounded up
    True
    """
    p = _uint_input(p, "p", np.uint32)
    dt = float_dtype(dtype)
    pos = {k: dt.type(DECODE_POSITIONS[_choice(v, f"{k}_decode", tuple(DECODE_POSITIONS))])
           for k, v in (("depth", depth_decode), ("v2", v2_decode), ("xi", xi_decode))}
    w = p.astype(np.int64)
    f2 = (w >> Y2_SHIFT) & ((1 << Y2_BITS) - 1)
    f1 = (w >> Y1_SHIFT) & ((1 << Y1_BITS) - 1)
    vcode = (w >> V_SHIFT) & _V_MAX
    xcode = (w >> XI_SHIFT) & _XI_MAX
    t1, t2 = unfold(f1, f2)
    r = np.empty(p.shape + (4,), dtype=dt)
    step = dt.type(511.5)
    r[..., 0] = (t1.astype(dt) + pos["depth"]) / step - 1
    r[..., 1] = (t2.astype(dt) + pos["depth"]) / step - 1
    sv = (vcode.astype(dt) + pos["v2"]) / dt.type(V_CELLS)
    r[..., 2] = sv * sv
    r[..., 3] = _decode_xi32(xcode, dt, xi_decode)
    return r
