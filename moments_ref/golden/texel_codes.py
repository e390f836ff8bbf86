"""The encoders' exact codes, vectorised: float64 with a proven error bound, mpmath only near a boundary.

:mod:`moments_ref.golden.texel_truth` decides every code of the 64- and 32-bit texels (docs/formats.md, HPG17 §3.3)
in exact rationals and mpmath, one row at a time (about 10⁴ rows/s). The sweep judges 10⁷ rows, so this module
computes the same codes for whole arrays in float64 and hands a row to ``texel_truth`` only where the float64
scaled value lies within :data:`SCALED_ERROR` of a rounding boundary, or its distance to one within
:data:`SCALED_ERROR` of the tie band (below): elsewhere the float64 decision is the exact one. The
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
rule** (:func:`moments_ref.golden.bands.tie_accepted`): a component whose margin is at most its **tie band**
(:func:`pack64_tie_band`, :func:`pack32_tie_band`) may hold either code; the others hold their exact code.

The tie band, derived from the formula. A legitimate float32 encoder receives the input within
:data:`INPUT_ULPS` ulps (the house's float32 neighbourhood, ``golden.bands.PERTURB_ULPS``; a float64 input rounded
to float32 is half an ulp off) and evaluates the layout's formula in at most :data:`OPS` float32 roundings (with or
without fma, in any of the printed orders: ``(y + 1)·0.5·65535``, ``y·32767.5 + 32767.5``, ``+ 0.5`` before a floor),
each of a quantity no larger in magnitude than the code range, and its GPU's log, exp and sqrt
(GLSL 4.30 §4.7.1, Vulkan's precision table: log 3 ulp, absolute 2⁻²¹ for arguments in [0.5, 2]; exp 3 + 2|x| ulp;
sqrt inherited from 1/inversesqrt, 2 + 2.5 ulp, declared :data:`SQRT_ULPS`). With u = 2⁻²⁴ (float32's unit
roundoff; one ulp of x is at most 2u|x|), the scaled value moves by at most, in codes:

* y (64 bits, HPG17 §3.3: s = 65535 (y + 1)/2, |y| ≤ 1) and v2 (s = 65535 v2, 0 ≤ v2 ≤ 1):
  ``2·INPUT_ULPS·u·a + OPS·u·2¹⁶`` with a = 32767.5 (y) or 65535 (v2) the factor on the input: 0.027 code (y),
  0.039 code (v2).
* y (32 bits, the cells ⌊511.5 (y + 1)⌋ of docs/formats.md): the same with a = 511.5 and 2¹⁰: 4.3·10⁻⁴ code.
* √v2 (32 bits, ⌊128 √v2⌋): ``128 u (INPUT_ULPS + 2·SQRT_ULPS + OPS)``: 1.3·10⁻⁴ code.
* Ψ4 (HPG17 §3.3: s = S (ln L − c0)/c1, L = ln(10⁷ ξ4) ∈ [0.182, 14.8], S = 65535 or 64), per row, from L: the
  product 10⁷ ξ4 is (2·INPUT_ULPS + 1) u relative off, so L is that plus the inner log's error
  max(6uL, 2⁻²¹) absolutely; ln L is off by that over L plus the outer log's max(6u|ln L|, 2⁻²¹); subtracting c0
  and dividing by c1 (both rounded) add u (|c0| + |ln L − c0|)/c1 + 2uΨ4. The shipped encoders' decode check
  (docs/formats.md: one code up where Ψ4⁻¹ of the code lies below ξ4) moves the ceil boundary as far as the two
  exponentials are off: ξ4 relative 2u((3 + 2L) + L(3 + 2|ln L|)), that is 1/(L c1) of it in Ψ4; the two add.
  S times the sum plus OPS·u·S: 0.14 code at the lower clamp (L = 0.182, where the inner log's absolute error
  2⁻²¹ over L dominates), 0.05–0.07 code for ξ4 from 10⁻⁶ to the upper clamp (S = 65535).

The linearisation (ln(L + δ) = ln L + δ/L) is off by (δ/L)², below 10⁻¹⁰ relative here. The band is
:data:`SAFETY` = 2 times the bound: room for a formulation with twice the roundings counted, and for the
terms' first-order treatment; it is a per-kind constant for y, v2 and √v2 (the largest bound over the domain:
the roundings' term is constant, so the bound varies at most 2.5-fold, near x = 0) and per row for Ψ4, whose
bound varies threefold with L. Until issue 36 the band was a quarter code (2⁻¹⁸ of every range) everywhere, which
accepted ``floor(s + 0.4)`` and ``floor(s + 0.6)`` for ``roundEven(s)`` (tests/sweep_mutants/corpus.py).

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
           "pack64_tie_band", "pack32_tie_band", "encode_unorm16_neighbours", "encode_r10g10b10a2_neighbours",
           "TIE_BAND", "SCALED_ERROR", "INPUT_ULPS", "OPS", "SQRT_ULPS", "SAFETY", "DERIVED_BAND"]

#: The tie band of the cases without a derived one (the affine encoders, the exact chains' confirmation), a fraction
#: of the code range: 2⁻¹⁸, a quarter code of a 16-bit code. The non-linear texels' encoders use
#: :func:`pack64_tie_band` and :func:`pack32_tie_band` (module docstring).
TIE_BAND = 64 * 2.0**-24
#: The functions whose tie band is derived from the formula (their cases' goldens store the per-component rule's
#: codes, golden.spread); the affine encoders keep :data:`TIE_BAND` and the nudged codes.
DERIVED_BAND = frozenset({"packing.pack64", "packing.pack32"})
#: The float32 neighbourhood of the encoder's input, in ulps (``golden.bands.PERTURB_ULPS``; a test keeps them equal).
INPUT_ULPS = 3
#: float32 roundings of the scaled value's formula a legitimate encoder may take (module docstring).
OPS = 4
#: A GPU's sqrt, in ulps: inherited from 1/inversesqrt (2 ulp) and a division (2.5 ulp), GLSL 4.30 §4.7.1.
SQRT_ULPS = 5
#: The tie band is this many times the bound on a legitimate encoder's error (module docstring).
SAFETY = 2.0
_U = 2.0**-24
_LOG_ULPS, _LOG_ABS = 3, 2.0**-21
_UNIT32 = np.array([1023, 1023, 128, 64], np.float64)
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


def _affine_band(a, top):
    """Tie half-width in codes of a scaled value a·x + b (|x| ≤ 1) whose magnitudes stay within ``top``: the input
    :data:`INPUT_ULPS` ulps off and :data:`OPS` roundings, times :data:`SAFETY` (module docstring)."""
    return SAFETY * _U * (2 * INPUT_ULPS * a + OPS * top)


def _psi4_band(xi, scale):
    """Tie half-width in codes of ``scale`` · Ψ4(ξ4) per row (HPG17 §3.3; module docstring): the GPU's two logs,
    the input's neighbourhood, c0 and c1 rounded, and the decode check's two exponentials, times :data:`SAFETY`."""
    x = np.clip(np.where(np.isfinite(xi), xi, _XI_MIN), _XI_MIN, _XI_MAX)
    big_l = np.log(x * 1e7)  # L = ln(10⁷ ξ4) in [0.182, 14.8]
    ln_l = np.log(big_l)
    d_big_l = (2 * INPUT_ULPS + 1) * _U + np.maximum(2 * _LOG_ULPS * _U * big_l, _LOG_ABS)
    d_ln_l = d_big_l / big_l + np.maximum(2 * _LOG_ULPS * _U * np.abs(ln_l), _LOG_ABS)
    psi = (ln_l - _C0) / _C1
    d_psi = (d_ln_l + _U * (abs(_C0) + np.abs(ln_l - _C0))) / _C1 + 2 * _U * psi
    # the decode check: ξ4 decoded through exp(exp(·)), each exp (3 + 2|x|) ulp off, seen in Ψ4 as 1/(L c1)
    d_psi = d_psi + 2 * _U * ((3 + 2 * big_l) + big_l * (3 + 2 * np.abs(ln_l))) / (big_l * _C1)
    return SAFETY * scale * (d_psi + OPS * _U)


def _bands64(xi):
    """``(n, 4)`` tie half-widths in codes of the 64-bit texel's scaled values (module docstring)."""
    n = len(xi)
    y, v = np.full(n, _affine_band(32767.5, 65536)), np.full(n, _affine_band(65535, 65536))
    return np.stack([y, y, v, _psi4_band(xi, 65535)], axis=1)


def _bands32(xi):
    """``(n, 4)`` tie half-widths in codes of the 32-bit texel's cells y1, y2, √v2, Ψ4 (module docstring)."""
    n = len(xi)
    y = np.full(n, _affine_band(511.5, 1024))
    v = np.full(n, SAFETY * _U * 128 * (INPUT_ULPS + 2 * SQRT_ULPS + OPS))
    return np.stack([y, y, v, _psi4_band(xi, 64)], axis=1)


def pack64_tie_band(r):
    """The tie band of the 64-bit texel: ``(n, 4)`` per component (y1, y2, v2, Ψ4), a fraction of the code range
    (65535): a component whose exact scaled value lies within it of a rounding boundary may hold either code.

    Notes
    -----
    SAFETY times a proven bound on how far a legitimate float32 encoder's scaled value (HPG17 §3.3: 65535 (y + 1)/2,
    65535 v2, 65535 Ψ4(ξ4)) lies from the exact one: the derivation is the module docstring's. 0.055 code for y,
    0.078 for v2, 0.11–0.29 code for Ψ4 (per row, from ξ4; the widest just above its lower clamp).

    Examples
    --------
    >>> band = pack64_tie_band([[0.0, 0.5, 0.5, 1e-3]]) * 65535
    >>> [round(float(b), 3) for b in band[0]]
    [0.055, 0.055, 0.078, 0.126]
    """
    r = np.asarray(r, np.float64).reshape(-1, 4)
    return _bands64(np.maximum(r[:, 3], 0.0)) / 65535


def pack32_tie_band(r):
    """The tie band of the 32-bit texel: ``(n, 4)`` per cell (y1, y2, √v2, Ψ4 before the fold), a fraction of each
    cell's range (1023, 1023, 128, 64), as :func:`pack64_tie_band` (module docstring)."""
    r = np.asarray(r, np.float64).reshape(-1, 4)
    return _bands32(np.maximum(r[:, 3], 0.0)) / _UNIT32


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


def _unsure(dist, band, extra):
    """Rows whose float64 decision may differ from the exact one: a distance (codes) within the error of 0 or of
    the tie band (``band``, codes)."""
    d = np.where(np.isfinite(dist), dist, 0.0)
    near = (d <= SCALED_ERROR) | (np.abs(d - band) <= SCALED_ERROR)
    return near.any(axis=1) | extra


def _doubtful(dist, y1, y2, v2, xi):
    """``dist`` with the components whose float64 value is exact set to 1 (no doubt): depths ±1, v2 0 or 1 (their
    scaled values are products of small integers) and ξ4 at a clamp (Ψ4 exactly 0 or 1)."""
    d = dist.copy()
    for i, exact in enumerate((np.abs(y1) == 1, np.abs(y2) == 1, (v2 == 0) | (v2 == 1), (xi < _XI_MIN) | (xi >= _XI_MAX))):
        d[exact, i] = 1.0
    return d


def _fill(codes, margins, across, rows, exact, band):
    """Replace ``rows`` with the exact ``(codes, margins, across)`` of texel_truth; ``across`` is the code itself
    where the component is not on a tie (its margin above its tie band ``band``, a fraction of the range)."""
    if rows.size:
        for a, b in zip((codes, margins, across), exact):
            a[rows] = b
    return codes, margins, np.where(margins <= band, across, codes)


def pack64_ties(r, xi_rounding="up", band=None):
    """``(codes, margins, across)``, each ``(n, 4)``: :func:`moments_ref.golden.texel_truth.pack64` with
    ``components=True``, vectorised (module docstring). ``band``: a tie band (a fraction of the range, broadcast to
    ``(n, 4)``) other than :func:`pack64_tie_band`, e.g. :data:`TIE_BAND` to compare with the former rule."""
    r = np.asarray(r, np.float64).reshape(-1, 4)
    y1, y2, v2, xi = _saturated(r)
    u, unsure_xi = _psi4(xi)
    parts = [_decide(65535 * ((y + 1) * 0.5), False, 65535, False) for y in (y1, y2)]
    parts.append(_decide(65535 * v2, False, 65535, False))
    parts.append(_decide(65535 * u, xi_rounding == "up", 65535, False))
    codes, dist, across = (np.stack([p[i] for p in parts], axis=1) for i in range(3))
    band = _bands64(xi) if band is None else np.broadcast_to(np.asarray(band, np.float64) * 65535, (len(r), 4))
    rows = np.flatnonzero(_unsure(_doubtful(dist, y1, y2, v2, xi), band, unsure_xi | ~np.isfinite(r).all(axis=1)))
    codes, margins, across = codes.astype(np.int64), dist / 65535, across.astype(np.int64)
    return _fill(codes, margins, across, rows, texel_truth.pack64(r[rows], xi_rounding, components=True), band / 65535)


def pack32_ties(r, band=None):
    """``(cells, margins, across)``, each ``(n, 4)`` in the order y1, y2, √v2, Ψ4 (before the fold):
    :func:`moments_ref.golden.texel_truth.pack32` with ``components=True``, vectorised (module docstring);
    ``band`` as in :func:`pack64_ties`."""
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
    band = _bands32(xi) if band is None else np.broadcast_to(np.asarray(band, np.float64) * _UNIT32, (len(r), 4))
    doubtful = _doubtful(dist, y1, y2, v2, xi)
    doubtful[(16384 * v2 == m) & (k * k == m), 2] = 1.0  # 128 √v2 an integer: exact
    rows = np.flatnonzero(_unsure(doubtful, band, unsure_xi | ~np.isfinite(r).all(axis=1)))
    cells, margins, across = cells.astype(np.int64), dist / _UNIT32, across.astype(np.int64)
    return _fill(cells, margins, across, rows, texel_truth.pack32(r[rows], components=True), band / _UNIT32)


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
    (margin ≤ its :func:`pack64_tie_band`) taken across its boundary. Compared per component (as the goldens
    compare codes), each component may hold its exact code or, on its own tie, this one."""
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
