"""Ground truth of the texel formats and the affine bases, written from the papers.

The golden cases of :mod:`moments_ref.packing` and :mod:`moments_ref.affine` take
their expected values from here, not from the functions under test. Nothing here
imports those modules: the bit layouts are the tables of docs/formats.md typed
again, the affine matrices the ones printed on the slides ("Compute moments in
resolve", "Retrieve moments", the six-moment "Quantization transform"), and every
value is computed in exact rational arithmetic (depths, √v2, UNORM codes) or in
mpmath at 50 digits (Ψ4, √3, matrix inverses). ``tests/test_golden.py`` checks
that the constants of the modules under test agree with the tables here.

Encoders return exact codes: the code of the real number the formula gives for the
stored input. A float implementation may differ where that number lies within its
rounding of a code boundary; the golden writer accepts such a row only where the
reference's own legitimate evaluations disagree there too (a rounding tie), and
refuses to write when the reference disagrees with the truth anywhere else
(:func:`moments_ref.golden.spread.derive`).

References
----------
.. [1] HPG17 demo: The demo code accompanying HPG17 (Direct3D; C. Peters), whose 32-bit texel
       functions ``QuantizeMomentsNonLinear32Bit`` and ``UnpackMomentsNonLinear32Bit`` are public
       in engine code ported from it, e.g. the repository kingofthebongo2008/UCEngine,
       ``src/uc_dev/private/gx/dx12/shaders/shadows/moment_shadow_maps_32.hlsli`` and
       ``shadows.hlsli`` (cited for their behaviour; no code is copied). Its 64-bit format is a
       UNORM16 render-target write (``moment_shadow_maps_64.hlsli``).
.. [2] HPG17: Christoph Peters. 2017. *Non-Linearly Quantized Moment Shadow Maps*. In Proceedings
       of High Performance Graphics (HPG '17). ACM. The non-linear quantization Φ, Ψ4, Algorithms
       1–3, the texel formats and the compute shader of §4.1.
.. [3] Slides: Christoph Peters. *Rendering antialiased shadows with moment shadow mapping*,
       lecture slides (PDF version, with notes) on moment shadow mapping, translucent occluders,
       moment soft shadow mapping and prefiltered single scattering; http://MomentsInGraphics.de/.
       Cited by slide title, e.g. Slides, "Bias the moments".
"""

from __future__ import annotations

import math
from fractions import Fraction

import mpmath
import numpy as np

__all__ = ["LAYOUT32", "CELLS32", "DECODE_OFFSETS32", "pack64", "unpack64", "pack32", "unpack32",
           "fold32", "to_optimized", "from_optimized", "encode_unorm16", "decode_unorm16", "to_optimized6",
           "encode_r10g10b10a2", "decode_r10g10b10a2", "words_r10"]

_DPS = 50

#: docs/formats.md, 32 bits: field -> (lowest bit, width).
LAYOUT32 = {"y2": (0, 10), "y1": (10, 9), "v": (19, 7), "xi": (26, 6)}
#: Cells per unit of the stored quantity: depth cells of 1/511.5 on y + 1, √v2 cells of
#: 1/128, Ψ4 cells of 1/64 (docs/formats.md; the HPG17 demo's grids).
CELLS32 = {"depth": Fraction(1023, 2), "v": 128, "xi": 64}
#: Where the decoder reads each cell (docs/formats.md): depth and Ψ4 at the upper end,
#: √v2 at the centre (HPG17 §3.5: "rounded up to guarantee a lower bound").
DECODE_OFFSETS32 = {"depth": Fraction(1), "v": Fraction(1, 2), "xi": Fraction(1)}
#: Slides, "Compute moments in resolve" (√3 written out where the slide has it).
_OPTIMIZED = (("1.5", "0", "-2", "0"), ("0", "4", "0", "-4"), ("√3·1/2", "0", "√3·-2/9", "0"),
              ("0", "0.5", "0", "0.5"))
_OPTIMIZED_OFFSET = ("0.5", "0", "0.5", "0")
#: Slides, six moments, "Quantization transform" (rows as printed; applied transposed).
_M0 = (("2.5", "-1.87499864", "1.26583039"), ("-10", "4.20757543", "-1.47644883"),
       ("8", "-1.83257679", "0.71061660"))
_M1 = (("4", "9", "-0.57759806"), ("-4", "-24", "4.61936648"), ("0", "16", "-3.07953907"))
_OFFSET6 = (("0.5", "0.5", "0.5"), ("0", "0", "0.018888946"))
#: DXGI_FORMAT_R10G10B10A2_UNORM read as a little-endian word: R, G, B at bits 0, 10, 20.
_R10_SHIFTS = (0, 10, 20)


def _mp(text):
    """A printed entry as an mpf: a decimal or fraction, or ``√3·q`` for √3 times the fraction q."""
    if text.startswith("√3·"):
        q = Fraction(text[3:])
        return mpmath.sqrt(3) * q.numerator / q.denominator
    q = Fraction(text)
    return mpmath.mpf(q.numerator) / q.denominator


def _matrix(rows, transpose=False):
    m = mpmath.matrix([[_mp(v) for v in row] for row in rows])
    return m.T if transpose else m


def _psi4(x):
    """HPG17 §3.3 at 50 digits, ξ4 clamped to [1.2e-7, 0.25] (Ψ4 in [0, 1])."""
    lo, hi = mpmath.mpf("1.2e-7"), mpmath.mpf("0.25")
    c0 = mpmath.log(mpmath.log(mpmath.mpf("1.2")))
    c1 = mpmath.log(mpmath.log(hi * 10**7)) - c0
    x = min(max(x, lo), hi)
    return (mpmath.log(mpmath.log(x * 10**7)) - c0) / c1


def _psi4_inverse(u):
    c0 = mpmath.log(mpmath.log(mpmath.mpf("1.2")))
    c1 = mpmath.log(mpmath.log(mpmath.mpf("0.25") * 10**7)) - c0
    return mpmath.exp(mpmath.exp(c0 + u * c1)) / 10**7


def _saturated(row):
    """docs/formats.md, Input: y1, y2 to [-1, 1] (y2 at least y1), v2 to [0, 1], ξ4 ≥ 0; exact."""
    y1, y2, v2, xi = (Fraction(float(v)) for v in row)
    y1 = min(max(y1, Fraction(-1)), Fraction(1))
    y2 = max(min(max(y2, Fraction(-1)), Fraction(1)), y1)
    return y1, y2, min(max(v2, Fraction(0)), Fraction(1)), max(xi, Fraction(0))


def _round_half_even(x):
    return int(round(x))  # Fraction.__round__ rounds half to even


def _to_half(x):
    """Distance of x to the nearest half-integer (the boundaries of rounding to nearest)."""
    return abs(x - math.floor(x) - Fraction(1, 2)) if isinstance(x, Fraction) else \
        abs(x - mpmath.floor(x) - mpmath.mpf("0.5"))


def _to_integer(x):
    """Distance of x to the nearest integer (the boundaries of floor and ceil)."""
    return abs(x - round(x)) if isinstance(x, Fraction) else abs(x - mpmath.nint(x))


def _mpq(q):
    return mpmath.mpf(q.numerator) / q.denominator


def _across(code, boundary, integer, top):
    """The code on the other side of ``boundary`` from ``code``, within [0, top]: the codes either side of a ceil
    boundary k (``integer``) are k and k + 1, of a round-to-nearest boundary h + 1/2 they are h and h + 1."""
    lo = int(mpmath.floor(boundary)) if integer else int(mpmath.floor(boundary - mpmath.mpf("0.5")))
    return min(max(2 * lo + 1 - code, 0), top)


def _pack64_row(row, xi_rounding):
    """Codes, per-component margins (distance / 65535) and the code across each component's nearest boundary."""
    y1, y2, v2, xi = _saturated(row)
    s = [65535 * (y1 + 1) / 2, 65535 * (y2 + 1) / 2, 65535 * v2]
    u = _psi4(_mpq(xi)) * 65535
    up = xi_rounding == "up"
    codes = [_round_half_even(x) for x in s] + [int(mpmath.ceil(u)) if up else int(mpmath.nint(u))]
    dist = [_to_half(x) for x in s] + [_to_integer(u) if up else _to_half(u)]
    # the boundary nearest each scaled value: a half-integer (round) or an integer (ceil)
    bounds = [math.floor(x) + Fraction(1, 2) for x in s] + [mpmath.nint(u) if up else mpmath.floor(u) + mpmath.mpf("0.5")]
    across = [_across(c, _mpq(b) if isinstance(b, Fraction) else b, i == 3 and up, 65535)
              for i, (c, b) in enumerate(zip(codes, bounds))]
    return codes, [float(d) / 65535 for d in dist], across


def pack64(r, xi_rounding="up", margin=False, components=False):
    """docs/formats.md, 64 bits: round(65535 (y + 1)/2), round(65535 v2), ceil (or round) 65535 Ψ4(ξ4).

    ``margin``: also return, per row, the distance of the exact scaled values to the
    nearest rounding boundary, in units of the code range (where a float
    implementation may legitimately store the neighbouring code).
    ``components``: return ``(codes, margins, across)`` instead, each ``(n, 4)``: per component its distance to its
    nearest rounding boundary (units of the code range) and the code on the other side of that boundary (the
    per-component tie rule, :mod:`moments_ref.golden.texel_codes`).
    """
    r = np.asarray(r, np.float64).reshape(-1, 4)
    out, m, a = np.empty((len(r), 4), np.uint16), np.empty((len(r), 4)), np.empty((len(r), 4), np.int64)
    with mpmath.workdps(_DPS):
        for i, row in enumerate(r):
            out[i], m[i], a[i] = _pack64_row(row, xi_rounding)
    if components:
        return out, m, a
    return (out, m.min(axis=1)) if margin else (out,)


def unpack64(q):
    """UNORM16 -> y = 2c/65535 − 1, v2 = c/65535, ξ4 = Ψ4⁻¹(c/65535)."""
    q = np.asarray(q).reshape(-1, 4).astype(np.int64)
    out = np.empty(q.shape, np.float64)
    with mpmath.workdps(_DPS):
        for i, (a, b, c, d) in enumerate(q):
            out[i] = [float(Fraction(2 * a, 65535) - 1), float(Fraction(2 * b, 65535) - 1), float(Fraction(c, 65535)),
                      float(_psi4_inverse(mpmath.mpf(int(d)) / 65535))]
    return (out,)


def _codes32(row):
    """The four cells (y1, y2, √v2, Ψ4) before the fold, their margins (distance to a cell boundary / cells) and the
    cells across each one's nearest boundary."""
    y1, y2, v2, xi = _saturated(row)
    s = [CELLS32["depth"] * (y + 1) for y in (y1, y2)]
    t = [min(max(math.floor(x), 0), 1022) for x in s]
    # ⌊128 √v2⌋ = isqrt(⌊16384 v2⌋), exactly
    v = min(math.isqrt(math.floor(CELLS32["v"] ** 2 * v2)), CELLS32["v"] - 1)
    sv = mpmath.sqrt(_mpq(v2)) * CELLS32["v"]
    u = _psi4(_mpq(xi)) * CELLS32["xi"]
    x = min(int(mpmath.floor(u)), CELLS32["xi"] - 1)
    cells, tops = t + [v, x], (1022, 1022, CELLS32["v"] - 1, CELLS32["xi"] - 1)
    scaled = [_mpq(q) for q in s] + [sv, u]
    margins = [float(_to_integer(q)) / 1023 for q in s] + [float(_to_integer(sv)) / CELLS32["v"],
                                                          float(_to_integer(u)) / CELLS32["xi"]]
    # floor cells: the cells either side of the nearest integer k are k - 1 and k
    across = [min(max(2 * int(mpmath.nint(q)) - 1 - c, 0), top) for q, c, top in zip(scaled, cells, tops)]
    return cells, margins, across


def fold32(cells):
    """The 32-bit words of ``(n, 4)`` cells (y1, y2, √v2, Ψ4) before the fold: HPG17 Figure 5, the upper half of the
    triangle rotated (t1 ≥ 512: t1 → 1023 − t1, t2 → 1022 − t2), the fields at the bits of :data:`LAYOUT32`."""
    c = np.asarray(cells, np.int64).reshape(-1, 4)
    fold = c[:, 0] >= 512
    t1, t2 = np.where(fold, 1023 - c[:, 0], c[:, 0]), np.where(fold, 1022 - c[:, 1], c[:, 1])
    fields = {"y1": t1, "y2": t2, "v": c[:, 2], "xi": c[:, 3]}
    return sum(f.astype(np.uint64) << np.uint64(LAYOUT32[k][0]) for k, f in fields.items()).astype(np.uint32)


def pack32(r, margin=False, components=False):
    """docs/formats.md, 32 bits: the four cell indices at the bits of :data:`LAYOUT32` (``margin``: see pack64;
    ``components``: ``(cells, margins, across)``, each ``(n, 4)`` in the order y1, y2, √v2, Ψ4, the cells before the
    fold: :func:`fold32` makes the word)."""
    r = np.asarray(r, np.float64).reshape(-1, 4)
    cells, m, a = (np.empty((len(r), 4), np.int64), np.empty((len(r), 4)), np.empty((len(r), 4), np.int64))
    with mpmath.workdps(_DPS):
        for i, row in enumerate(r):
            cells[i], m[i], a[i] = _codes32(row)
    if components:
        return cells, m, a
    out = fold32(cells)
    return (out, m.min(axis=1)) if margin else (out,)


def unpack32(p, offsets=None):
    """Fields by :data:`LAYOUT32`, the fold undone, each cell read at :data:`DECODE_OFFSETS32` (or at
    ``offsets``: ``{"depth", "v", "xi"}`` -> Fraction of a cell, a port's declared decode positions)."""
    offsets = dict(DECODE_OFFSETS32, **(offsets or {}))
    p = np.asarray(p).reshape(-1).astype(np.int64)
    out = np.empty((len(p), 4), np.float64)
    with mpmath.workdps(_DPS):
        for i, w in enumerate(p):
            f = {k: (int(w) >> s) & ((1 << n) - 1) for k, (s, n) in LAYOUT32.items()}
            t1, t2 = f["y1"], f["y2"]
            if t2 < t1:  # a folded pair (unfolded pairs keep t1 ≤ t2)
                t1, t2 = 1023 - t1, 1022 - t2
            y = [(t + offsets["depth"]) / CELLS32["depth"] - 1 for t in (t1, t2)]
            sv = (f["v"] + offsets["v"]) / CELLS32["v"]
            u = (f["xi"] + offsets["xi"]) / CELLS32["xi"]
            out[i] = [float(y[0]), float(y[1]), float(sv * sv),
                      float(_psi4_inverse(mpmath.mpf(u.numerator) / u.denominator))]
    return (out,)


def _apply(matrix, offset, x):
    """``matrix · x + offset`` per row of x (float64 in, mpmath at 50 digits, float64 out)."""
    x = np.asarray(x, np.float64)
    out = np.empty(x.shape[:-1] + (matrix.rows,), np.float64)
    flat_in, flat_out = x.reshape(-1, x.shape[-1]), out.reshape(-1, matrix.rows)
    for i, row in enumerate(flat_in):
        v = matrix * mpmath.matrix([mpmath.mpf(float(t)) for t in row]) + offset
        flat_out[i] = [float(t) for t in v]
    return out


def _optimized():
    return _matrix(_OPTIMIZED), mpmath.matrix([_mp(v) for v in _OPTIMIZED_OFFSET])


def to_optimized(b):
    """Slides, "Compute moments in resolve": (R, G, B, A) = M·b + c."""
    with mpmath.workdps(_DPS):
        m, c = _optimized()
        return (_apply(m, c, b),)


def from_optimized(q):
    """Slides, "Retrieve moments": b = M⁻¹·(q − c), M⁻¹ computed here at 50 digits."""
    with mpmath.workdps(_DPS):
        m, c = _optimized()
        inv = mpmath.inverse(m)
        return (_apply(inv, -(inv * c), q),)


def _unorm(x, top):
    """Direct3D FLOAT -> UNORM: clamp to [0, 1], × top, round half up (x an mpf at 50 digits)."""
    return int(mpmath.floor(min(max(x, mpmath.mpf(0)), mpmath.mpf(1)) * top + mpmath.mpf("0.5")))


def _unorm_ties(values, top):
    """Per value: its code, the distance of the clamped, scaled value to its nearest rounding boundary h + 1/2
    (/ top), and the code across that boundary (h or h + 1, within [0, top])."""
    out = []
    for x in values:
        t = min(max(x, mpmath.mpf(0)), mpmath.mpf(1)) * top
        c, lo = _unorm(x, top), int(mpmath.floor(t))
        out.append((c, float(_to_half(t)) / top, min(max(2 * lo + 1 - c, 0), top)))
    return [list(v) for v in zip(*out)]


def encode_unorm16(b, margin=False, components=False):
    """Four UNORM16 codes of the optimized basis (``margin``, ``components``: see pack64)."""
    b = np.asarray(b, np.float64).reshape(-1, 4)
    out, mg, a = np.empty(b.shape, np.uint16), np.empty(b.shape), np.empty(b.shape, np.int64)
    with mpmath.workdps(_DPS):
        m, c = _optimized()
        for i, row in enumerate(b):
            v = m * mpmath.matrix([mpmath.mpf(float(t)) for t in row]) + c
            out[i], mg[i], a[i] = _unorm_ties(v, 65535)
    if components:
        return out, mg, a
    return (out, mg.min(axis=1)) if margin else (out,)


def decode_unorm16(u):
    """Slides, "Retrieve moments" on u / 65535, exactly."""
    codes, top = np.asarray(u).reshape(-1, 4), 65535
    with mpmath.workdps(_DPS):
        m, c = _optimized()
        inv = mpmath.inverse(m)
        out = np.empty(codes.shape, np.float64)
        for i, row in enumerate(codes.astype(np.int64)):
            v = inv * (mpmath.matrix([mpmath.mpf(int(t)) / top for t in row]) - c)
            out[i] = [float(t) for t in v]
    return (out,)


def _six():
    """((M0ᵀ, offset0), (M1ᵀ, offset1)) at 50 digits."""
    return ((_matrix(_M0, True), mpmath.matrix([_mp(v) for v in _OFFSET6[0]])),
            (_matrix(_M1, True), mpmath.matrix([_mp(v) for v in _OFFSET6[1]])))


def _to6(row):
    (m0, c0), (m1, c1) = _six()
    odd = m0 * mpmath.matrix([mpmath.mpf(float(row[k])) for k in (0, 2, 4)]) + c0
    even = m1 * mpmath.matrix([mpmath.mpf(float(row[k])) for k in (1, 3, 5)]) + c1
    return list(odd) + list(even)


def to_optimized6(b):
    """Slides, six moments: (R0, G0, B0) = M0ᵀ·(b1, b3, b5) + 0.5, (R1, G1, B1) = M1ᵀ·(b2, b4, b6) + c1."""
    b = np.asarray(b, np.float64).reshape(-1, 6)
    with mpmath.workdps(_DPS):
        return (np.array([[float(t) for t in _to6(row)] for row in b]),)


def words_r10(fields):
    """The two R10G10B10A2_UNORM words of ``(n, 6)`` 10-bit codes (R0, G0, B0, R1, G1, B1), alpha 0."""
    f = np.asarray(fields, np.int64).reshape(-1, 6)
    return np.stack([sum(f[:, k + j] << s for j, s in enumerate(_R10_SHIFTS)) for k in (0, 3)], axis=1).astype(np.uint32)


def encode_r10g10b10a2(b, margin=False, components=False):
    """Two R10G10B10A2_UNORM words: 10-bit codes of (R0, G0, B0) and (R1, G1, B1), alpha 0 (``margin``: see pack64;
    ``components``: ``(codes, margins, across)``, each ``(n, 6)``, :func:`words_r10` makes the words)."""
    b = np.asarray(b, np.float64).reshape(-1, 6)
    codes, mg, a = np.empty((len(b), 6), np.int64), np.empty((len(b), 6)), np.empty((len(b), 6), np.int64)
    with mpmath.workdps(_DPS):
        for i, row in enumerate(b):
            codes[i], mg[i], a[i] = _unorm_ties(_to6(row), 1023)
    if components:
        return codes, mg, a
    out = words_r10(codes)
    return (out, mg.min(axis=1)) if margin else (out,)


def decode_r10g10b10a2(p):
    """The six 10-bit codes / 1023 through the exact inverses of M0ᵀ and M1ᵀ (alpha ignored)."""
    p = np.asarray(p).reshape(-1, 2).astype(np.int64)
    out = np.empty((len(p), 6), np.float64)
    with mpmath.workdps(_DPS):
        (m0, c0), (m1, c1) = _six()
        i0, i1 = mpmath.inverse(m0), mpmath.inverse(m1)
        for i, (w0, w1) in enumerate(p):
            q = [[mpmath.mpf((int(w) >> s) & 1023) / 1023 for s in _R10_SHIFTS] for w in (w0, w1)]
            odd = i0 * (mpmath.matrix(q[0]) - c0)
            even = i1 * (mpmath.matrix(q[1]) - c1)
            out[i] = [float(odd[0]), float(even[0]), float(odd[1]), float(even[1]), float(odd[2]), float(even[2])]
    return (out,)
