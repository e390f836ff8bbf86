"""The encoders' exact codes, vectorised: float64 with a proven error bound, mpmath only near a boundary.

:mod:`moments_ref.golden.texel_truth` decides every code of the 64- and 32-bit texels (docs/formats.md, HPG17 §3.3)
in exact rationals and mpmath, one row at a time (about 10⁴ rows/s). The sweep judges 10⁷ rows, so this module
computes the same codes for whole arrays in float64 and hands a row to ``texel_truth`` only where the float64
scaled value lies within :data:`SCALED_ERROR` of a rounding boundary, or its distance to one within
:data:`SCALED_ERROR` of the tie band (:data:`TIE_BAND`): elsewhere the float64 decision is the exact one. The
results equal ``texel_truth``'s (tests/test_texel_codes.py compares them on random rows and on rows placed on and
next to each boundary).

The error bound. The scaled values are 65535 (y + 1)/2 and 65535 v2 (64 bits), 511.5 (y + 1) and 128 √v2 (32 bits):
one or two float64 operations on a float input, absolute error below 65535 · 2⁻⁵² ≈ 1.5·10⁻¹¹ code. The Ψ4 code
65535 Ψ4(ξ4) = 65535 (log(log(10⁷ ξ4)) − c0)/c1 with ξ4 clamped to [1.2·10⁻⁷, 0.25] (HPG17 §3.3): 10⁷ ξ4 has a
relative error of 2⁻⁵³; L = log(10⁷ ξ4) ∈ [0.182, 14.8] an absolute error below 2·10⁻¹⁵ (its input's relative
error plus half an ulp of 14.8), so a relative one below 1.1·10⁻¹⁴; log(L) ∈ [−1.71, 2.70] an absolute error
below 1.2·10⁻¹⁴; c0 and c1 are correctly rounded from 50 digits, c1 ≈ 4.39: Ψ4 is within 3·10⁻¹⁵ and the code
within 2·10⁻¹⁰. :data:`SCALED_ERROR` = 10⁻⁹ code holds five times that. Clamped rows are exact (Ψ4 = 0 or 1); a
ξ4 equal to float64(1.2·10⁻⁷), where the float64 comparison with the decimal clamp is not the exact one, goes to
mpmath, as do non-finite inputs.

Per component, besides the code: its margin (the distance of its exact scaled value to its nearest rounding
boundary, in units of the code range) and the code on the other side of that boundary, the **per-component tie
rule** (:func:`moments_ref.golden.bands.tie_accepted`): a component within :data:`TIE_BAND` of its boundary may
hold either code; the others hold their exact code.

References
----------
.. [1] HPG17: Christoph Peters. 2017. *Non-Linearly Quantized Moment Shadow Maps*. In Proceedings
       of High Performance Graphics (HPG '17). ACM. The non-linear quantization Φ, Ψ4, Algorithms
       1–3, the texel formats and the compute shader of §4.1.
"""

from __future__ import annotations

import mpmath
import numpy as np

from . import texel_truth

__all__ = ["pack64", "pack32", "pack64_ties", "pack32_ties", "pack64_neighbours", "pack32_neighbours",
           "encode_unorm16_neighbours", "encode_r10g10b10a2_neighbours", "TIE_BAND", "SCALED_ERROR"]

#: A code is on a rounding tie where the exact scaled value lies within this fraction of the code range from a
#: rounding boundary; there either neighbouring code is legitimate (a GPU's ``log`` or ``exp`` a few ulps off moves
#: the scaled value by that much). The goldens (:mod:`moments_ref.golden.spread`) and the sweep use this band.
TIE_BAND = 64 * 2.0**-24
#: Bound on |float64 scaled value − exact scaled value|, in codes (module docstring).
SCALED_ERROR = 1e-9

_XI_MIN, _XI_MAX = float(np.float64(1.2e-7)), 0.25
with mpmath.workdps(50):
    _C0 = mpmath.log(mpmath.log(mpmath.mpf("1.2")))
    _C1 = float(mpmath.log(mpmath.log(mpmath.mpf("0.25") * 10**7)) - _C0)
    _C0 = float(_C0)


def _psi4(xi):
    """HPG17 §3.3 in float64, ξ4 clamped: Ψ4 exactly 0 and 1 at the clamps; ``unsure`` where ξ4 is the float64
    nearest 1.2·10⁻⁷ (the decimal clamp's exact comparison is not the float64 one)."""
    x = np.clip(xi, _XI_MIN, _XI_MAX)
    with np.errstate(invalid="ignore", divide="ignore"):
        u = (np.log(np.log(x * 1e7)) - _C0) / _C1
    u = np.where(xi < _XI_MIN, 0.0, np.where(xi >= _XI_MAX, 1.0, u))
    return u, xi == _XI_MIN


def _saturated(r):
    """docs/formats.md, Input: y1, y2 to [-1, 1] (y2 at least y1), v2 to [0, 1], ξ4 ≥ 0 (exact in float64)."""
    y1 = np.clip(r[:, 0], -1.0, 1.0)
    return y1, np.maximum(np.clip(r[:, 1], -1.0, 1.0), y1), np.clip(r[:, 2], 0.0, 1.0), np.maximum(r[:, 3], 0.0)


def _decide(scaled, integer, top, cells):
    """Codes, distances to the nearest boundary (codes) and the codes across it, of float64 scaled values.

    ``integer``: boundaries at integers (floor cells or ceil codes, ``cells`` says which), else at half-integers
    (round half to even); codes clipped to [0, top]."""
    if integer:
        k = np.rint(scaled)
        code = np.floor(scaled) if cells else np.ceil(scaled)
        lo = k - 1 if cells else k  # the codes either side of boundary k
    else:
        h = np.floor(scaled) + 0.5
        k, code, lo = h, np.rint(scaled), h - 0.5
    code = np.clip(code, 0, top)
    return code, np.abs(scaled - k), np.clip(2 * lo + 1 - code, 0, top)


def _unsure(dist, unit, extra):
    """Rows whose float64 decision may differ from the exact one: a distance (codes) within the error of 0 or of
    the tie band (``TIE_BAND`` × ``unit``, the codes of the component's range)."""
    d = np.where(np.isfinite(dist), dist, 0.0)
    near = (d <= SCALED_ERROR) | (np.abs(d - TIE_BAND * np.asarray(unit, np.float64)) <= SCALED_ERROR)
    return near.any(axis=1) | extra


def _doubtful(dist, y1, y2, v2, xi):
    """``dist`` with the components whose float64 value is exact set to 1 (no doubt): depths ±1, v2 0 or 1 (their
    scaled values are products of small integers) and ξ4 at a clamp (Ψ4 exactly 0 or 1)."""
    d = dist.copy()
    for i, exact in enumerate((np.abs(y1) == 1, np.abs(y2) == 1, (v2 == 0) | (v2 == 1), (xi < _XI_MIN) | (xi >= _XI_MAX))):
        d[exact, i] = 1.0
    return d


def _fill(codes, margins, across, rows, exact):
    """Replace ``rows`` with the exact ``(codes, margins, across)`` of texel_truth; ``across`` is the code itself
    where the component is not on a tie (its margin above :data:`TIE_BAND`)."""
    if rows.size:
        for a, b in zip((codes, margins, across), exact):
            a[rows] = b
    return codes, margins, np.where(margins <= TIE_BAND, across, codes)


def pack64_ties(r, xi_rounding="up"):
    """``(codes, margins, across)``, each ``(n, 4)``: :func:`moments_ref.golden.texel_truth.pack64` with
    ``components=True``, vectorised (module docstring)."""
    r = np.asarray(r, np.float64).reshape(-1, 4)
    y1, y2, v2, xi = _saturated(r)
    u, unsure_xi = _psi4(xi)
    parts = [_decide(65535 * ((y + 1) * 0.5), False, 65535, False) for y in (y1, y2)]
    parts.append(_decide(65535 * v2, False, 65535, False))
    parts.append(_decide(65535 * u, xi_rounding == "up", 65535, False))
    codes, dist, across = (np.stack([p[i] for p in parts], axis=1) for i in range(3))
    rows = np.flatnonzero(_unsure(_doubtful(dist, y1, y2, v2, xi), 65535, unsure_xi | ~np.isfinite(r).all(axis=1)))
    codes, margins, across = codes.astype(np.int64), dist / 65535, across.astype(np.int64)
    return _fill(codes, margins, across, rows, texel_truth.pack64(r[rows], xi_rounding, components=True))


def pack32_ties(r):
    """``(cells, margins, across)``, each ``(n, 4)`` in the order y1, y2, √v2, Ψ4 (before the fold):
    :func:`moments_ref.golden.texel_truth.pack32` with ``components=True``, vectorised (module docstring)."""
    r = np.asarray(r, np.float64).reshape(-1, 4)
    y1, y2, v2, xi = _saturated(r)
    u, unsure_xi = _psi4(xi)
    parts = [_decide(511.5 * (y + 1), True, 1022, True) for y in (y1, y2)]
    parts.append(_decide(128 * np.sqrt(v2), True, 127, True))
    parts.append(_decide(64 * u, True, 63, True))
    cells, dist, across = (np.stack([p[i] for p in parts], axis=1) for i in range(3))
    # ⌊128 √v2⌋ = isqrt(⌊16384 v2⌋) exactly (16384 v2 is exact; the square root of an integer below 2¹⁵ is
    # corrected by one step either way)
    m = np.floor(16384 * np.where(np.isfinite(v2), v2, 0.0))
    k = np.floor(np.sqrt(m))
    k = k - (k * k > m) + ((k + 1) * (k + 1) <= m)
    cells[:, 2] = np.minimum(k, 127)
    unit = np.array([1023, 1023, 128, 64], np.float64)
    doubtful = _doubtful(dist, y1, y2, v2, xi)
    doubtful[(16384 * v2 == m) & (k * k == m), 2] = 1.0  # 128 √v2 an integer: exact
    rows = np.flatnonzero(_unsure(doubtful, unit, unsure_xi | ~np.isfinite(r).all(axis=1)))
    cells, margins, across = cells.astype(np.int64), dist / unit, across.astype(np.int64)
    return _fill(cells, margins, across, rows, texel_truth.pack32(r[rows], components=True))


def pack64(r, xi_rounding="up", margin=False):
    """:func:`moments_ref.golden.texel_truth.pack64`, vectorised: the exact codes (and per row the least margin)."""
    codes, margins, _ = pack64_ties(r, xi_rounding)
    codes = codes.astype(np.uint16)
    return (codes, margins.min(axis=1)) if margin else (codes,)


def pack32(r, margin=False):
    """:func:`moments_ref.golden.texel_truth.pack32`, vectorised: the exact words (and per row the least margin)."""
    cells, margins, _ = pack32_ties(r)
    words = texel_truth.fold32(cells)
    return (words, margins.min(axis=1)) if margin else (words,)


def pack64_neighbours(r, xi_rounding="up"):
    """The per-component tie rule's other codes: one output tuple, the exact codes with every component on a tie
    (margin ≤ :data:`TIE_BAND`) taken across its boundary. Compared per component (as the goldens compare codes),
    each component may hold its exact code or, on its own tie, this one."""
    _, _, across = pack64_ties(r, xi_rounding)
    return [(across.astype(np.uint16),)]


def pack32_neighbours(r):
    """The per-component tie rule's other words: the exact cells with each non-empty subset of the components on a
    tie taken across their boundary, folded (:func:`moments_ref.golden.texel_truth.fold32`): 15 output tuples (a
    word holds all four fields, so a field's neighbour is a whole word)."""
    cells, _, across = pack32_ties(r)
    out = []
    for mask in range(1, 16):
        pick = np.array([(mask >> i) & 1 for i in range(4)], bool)
        out.append((texel_truth.fold32(np.where(pick, across, cells)),))
    return out


def _on_tie(codes, margins, across):
    return np.where(margins <= TIE_BAND, across, codes)


def encode_unorm16_neighbours(b):
    """The per-component tie rule for the 64-bit affine texel (four UNORM16 codes), as :func:`pack64_neighbours`;
    from :func:`moments_ref.golden.texel_truth.encode_unorm16`'s mpmath codes (its cases hold a few hundred rows
    and are not swept)."""
    return [(_on_tie(*texel_truth.encode_unorm16(b, components=True)).astype(np.uint16),)]


def encode_r10g10b10a2_neighbours(b):
    """The per-component tie rule for the six-moment texel (two R10G10B10A2 words of three fields each): the 7
    combinations of a word's fields on a tie taken across, as :func:`pack32_neighbours`; mpmath codes."""
    codes, margins, across = texel_truth.encode_r10g10b10a2(b, components=True)
    across = _on_tie(codes, margins, across)
    out = []
    for mask in range(1, 8):
        pick = np.array([(mask >> i) & 1 for i in range(3)] * 2, bool)
        out.append((texel_truth.words_r10(np.where(pick, across, codes)),))
    return out
