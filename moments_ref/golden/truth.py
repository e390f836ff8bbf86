"""Ground truth for golden cases that :mod:`moments_ref.precise` does not cover literally.

:func:`shade_clamped` is HPG17 Algorithm 3 *with* its §3.4 clamps, evaluated in
mpmath: the clamps are part of the specification (a port must apply them), so the
expected value of a row at v2 = 0 or y1 = y2 is the clamped one. Away from the
clamps it equals :func:`moments_ref.precise.shade` (Algorithm 1 on Eq. (4)); the
tests check that.

:func:`nlq_chain` and :func:`msm64_chain` are the chains' twins (the end-to-end and engine
cases' confirmation): bias, Φ, the texel's codes decided on the exact values, the exact decode
and Algorithm 3 (or the affine texel and Algorithm 1). Quantization has no single exact value
where an exact value lies on a code boundary, so they return an interval ``(lo, hi)`` per row.
They live here, not in :mod:`moments_ref.precise`, because they need the clamped Algorithm 3
above and the texel tables of :mod:`moments_ref.golden.texel_truth`.

References
----------
.. [1] HPG17: Christoph Peters. 2017. *Non-Linearly Quantized Moment Shadow Maps*. In Proceedings
       of High Performance Graphics (HPG '17). ACM. The non-linear quantization Φ, Ψ4, Algorithms
       1–3, the texel formats and the compute shader of §4.1.
.. [2] Slides: Christoph Peters. *Rendering antialiased shadows with moment shadow mapping*,
       lecture slides (PDF version, with notes) on moment shadow mapping, translucent occluders,
       moment soft shadow mapping and prefiltered single scattering; http://MomentsInGraphics.de/.
       Cited by slide title, e.g. Slides, "Bias the moments".
"""

from __future__ import annotations

from itertools import product

import mpmath
import numpy as np

from .. import precise
from .texel_truth import decode_unorm16, encode_unorm16, to_optimized

__all__ = ["shade_clamped", "SHADE_CLAMP", "CHAIN_TIE", "nlq_chain", "msm64_chain"]

#: HPG17 §3.4: v2 ∈ [1e-6, 1 − 1e-6] and y2 − y1 ≥ 1e-6.
SHADE_CLAMP = 1e-6


def _shade_row(y1, y2, v2, xi4, zf, eps, clamped_test=False):
    """Algorithm 3 on one row with clamp offset ``eps``, all arguments mpf (50 digits).

    ``clamped_test``: the case test ``zf ≤ y2`` compares with the clamped y2 = max(y2, y1 + eps)
    (the author's demo code) instead of the stored y2 (the reference's reading).
    """
    if zf <= y1:
        return mpmath.mpf(0)  # "if zf ≤ y1 return 0"
    if clamped_test:
        y2 = max(y2, y1 + eps)
    v2 = min(max(v2, eps), 1 - eps)
    gap = max(y2 - y1, eps)
    zp = (zf - y1) / gap
    xip = max(xi4 / gap**4, mpmath.mpf("1e-60"))  # ξ'4 → 0⁺ limit for ξ4 = 0
    if zf <= y2:  # the case test uses the stored y2 (the clamp only moves the y2 used above)
        if zp >= 1:
            zl = mpmath.mpf(0)  # limit z'f → 1⁻: q1 → −∞, the smaller root → 0
        else:
            q0 = -xip / ((1 - v2) * zp)
            q1 = -q0 * (v2 - zp) / (v2 - v2 * zp) - 1
            zl = -q1 / 2 - mpmath.sqrt(q1 * q1 / 4 - q0)
    else:
        zl = zp
    wl = 1 / ((1 - zl) ** 2 / (1 - v2) + zl**2 / v2 + (1 - zl) ** 2 * zl**2 / xip)
    out = wl if zf <= y2 else 1 - wl
    return min(max(out, mpmath.mpf(0)), mpmath.mpf(1))


def shade_clamped(r, zf, dps=50, clamp=SHADE_CLAMP, case_test="stored"):
    """Exact Algorithm 3 with the §3.4 clamps: ``(n, 4)`` r and ``(n,)`` zf -> float64 ``(n,)``.

    ``clamp`` is the offset of the clamps (the paper's 1e-6, or a port's declared
    offset, docs/ports.md); it is taken as the float given, exactly. ``case_test``:
    the y2 the case test ``zf ≤ y2`` compares with, ``"stored"`` (default) or
    ``"clamped"`` (max(y2, y1 + clamp)): the paper does not say which.
    """
    r = np.asarray(r, np.float64).reshape(-1, 4)
    zf = np.broadcast_to(np.asarray(zf, np.float64), r.shape[:1])
    out = np.empty(len(zf))
    with mpmath.workdps(dps):
        eps = mpmath.mpf(float(clamp))
        for i in range(len(zf)):
            out[i] = float(_shade_row(*(mpmath.mpf(float(x)) for x in r[i]), mpmath.mpf(float(zf[i])), eps,
                                      case_test == "clamped"))
    return out


# ---------------------------------------------------------------------------
# The NLQ chain: bias -> Φ -> texel codes -> decode -> Algorithm 3, exactly

#: Confirmation's rounding tie, a fraction of each code's range: the goldens' tie rule (golden.bands.TIE_BAND, 2⁻¹⁸;
#: bands imports the case table, which imports this module: a test keeps the two equal). A float32 port stores either
#: code where the exact value lies that close to a rounding boundary.
CHAIN_TIE = 2.0**-18
#: Decode positions of a 32-bit cell (docs/formats.md; a profile's ``format.*_decode``).
_POSITION = {"lower": mpmath.mpf(0), "centre": mpmath.mpf("0.5"), "upper": mpmath.mpf(1)}
#: The 32-bit texel's default decode positions: depth and Ψ4 at the upper end, √v2 at the centre (HPG17 §3.5).
_DECODE32 = {"depth_decode": "upper", "v2_decode": "centre", "xi_decode": "upper"}


def _psi4(x):
    """HPG17 §3.3, Ψ4 with ξ4 clamped to [1.2e-7, 0.25] (Ψ4 in [0, 1]), at the working precision."""
    c0 = mpmath.log(mpmath.log(mpmath.mpf("1.2")))
    c1 = mpmath.log(mpmath.log(mpmath.mpf("0.25") * 10**7)) - c0
    x = min(max(x, mpmath.mpf("1.2e-7")), mpmath.mpf("0.25"))
    return (mpmath.log(mpmath.log(x * 10**7)) - c0) / c1


def _psi4_inverse(u):
    c0 = mpmath.log(mpmath.log(mpmath.mpf("1.2")))
    c1 = mpmath.log(mpmath.log(mpmath.mpf("0.25") * 10**7)) - c0
    return mpmath.exp(mpmath.exp(c0 + u * c1)) / 10**7


def _candidates(s, rounding, tie, top):
    """The codes of the exact scaled value ``s`` (``rounding``: "nearest", "up" or "down"), both neighbours where
    ``s`` lies within ``tie`` of the rounding's boundary (half-integers for "nearest", integers otherwise)."""
    if rounding == "nearest":
        k = int(mpmath.floor(s))
        near = abs(s - k - mpmath.mpf("0.5")) < tie
        codes = {k, k + 1} if near else {int(mpmath.nint(s))}
    else:
        k = int(mpmath.nint(s))
        if abs(s - k) < tie:
            codes = {k, k + 1} if rounding == "up" else {k - 1, k}
        else:
            codes = {int(mpmath.ceil(s)) if rounding == "up" else int(mpmath.floor(s))}
    return sorted({min(max(c, 0), top) for c in codes})


def _saturate(y1, y2, v2, xi4):
    """docs/formats.md, Input: y1, y2 to [−1, 1] (y2 at least y1), v2 to [0, 1], ξ4 ≥ 0."""
    one = mpmath.mpf(1)
    y1 = min(max(y1, -one), one)
    return y1, max(min(max(y2, -one), one), y1), min(max(v2, mpmath.mpf(0)), one), max(xi4, mpmath.mpf(0))


def _decoded64(r, texel, tie):
    """Every decoded (y1, y2, v2, ξ4) the 64-bit texel may hold for the exact r (docs/formats.md, 64 bits);
    ``tie``: a fraction of the code range."""
    y1, y2, v2, xi4 = _saturate(*r)
    top = 65535
    tie = tie * top
    xi_rounding = "up" if (texel or {}).get("xi_rounding", "up") == "up" else "nearest"
    c1 = _candidates(top * (y1 + 1) / 2, "nearest", tie, top)
    c2 = _candidates(top * (y2 + 1) / 2, "nearest", tie, top)
    cv = _candidates(top * v2, "nearest", tie, top)
    cx = _candidates(top * _psi4(xi4), xi_rounding, tie, top)
    return [(mpmath.mpf(2 * a) / top - 1, mpmath.mpf(2 * b) / top - 1, mpmath.mpf(v) / top,
             _psi4_inverse(mpmath.mpf(x) / top)) for a in c1 for b in c2 if a <= b for v in cv for x in cx]


def _decoded32(r, texel, tie):
    """Every decoded (y1, y2, v2, ξ4) the 32-bit texel may hold for the exact r (docs/formats.md, 32 bits).

    The cells ⌊511.5 (y + 1)⌋ (0 … 1022), ⌊128 √v2⌋ (≤ 127), ⌊64 Ψ4⌋ (≤ 63), each read at its decode position.
    HPG17 Figure 5's fold (ỹ1 ≥ 512 -> 1023 − ỹ1, 1022 − ỹ2) is undone by the decoder (a folded pair has
    ỹ2 < ỹ1, an unfolded one ỹ1 ≤ ỹ2), so the decoded value is that of the unfolded cells.
    """
    y1, y2, v2, xi4 = _saturate(*r)
    pos = {k: _POSITION[v] for k, v in dict(_DECODE32, **{k: v for k, v in (texel or {}).items()
                                                           if k in _DECODE32}).items()}
    half = mpmath.mpf(1023) / 2
    t1 = _candidates(half * (y1 + 1), "down", tie * 1023, 1022)
    t2 = _candidates(half * (y2 + 1), "down", tie * 1023, 1022)
    cv = _candidates(128 * mpmath.sqrt(v2), "down", tie * 128, 127)
    cx = _candidates(64 * _psi4(xi4), "down", tie * 64, 63)
    d = pos["depth_decode"]
    return [((a + d) / half - 1, (b + d) / half - 1, ((v + pos["v2_decode"]) / 128) ** 2,
             _psi4_inverse((x + pos["xi_decode"]) / 64)) for a in t1 for b in t2 if a <= b for v in cv for x in cx]


def nlq_chain(b, zf, fmt="64", bias=None, clamp=SHADE_CLAMP, case_test="stored", texel=None, dps=50, tie=None):
    """The exact NLQ chain: ``(lo, hi)`` float64 ``(n,)``, the least and largest intensity its texel allows.

    HPG17's pipeline evaluated exactly: the bias (Slides, "Bias the moments"), Φ (HPG17 Algorithm 2;
    :func:`moments_ref.precise.phi_exact`), the texel's codes (HPG17 §3.3 Ψ4, §3.5 and docs/formats.md: the
    64-bit UNORM16 channels round(65535 (y + 1)/2), round(65535 v2), ceil (or round, ``texel["xi_rounding"]``)
    65535 Ψ4(ξ4); the 32-bit cells), each code decided by comparing the exact value with the code boundaries,
    the decode (exact, in mpmath) and HPG17 Algorithm 3 with its §3.4 clamps (:func:`shade_clamped`'s row).
    Where an exact value lies within ``tie`` (a fraction of the code's range; default ``10^-(dps/2)``, the
    exact value's own accuracy; confirmation passes :data:`CHAIN_TIE`, the goldens' tie rule) of a rounding
    boundary both codes are taken: ``lo`` and ``hi`` are the least and largest intensity over the candidate
    texels (equal elsewhere).

    ``b``: ``(n, 4)`` moments as the chain receives them, ``zf``: ``(n,)``; ``bias``: a BiasPreset or None (the
    caller biased); ``clamp``, ``case_test``: the clamps of Algorithm 3 (:func:`shade_clamped`); ``texel``: the
    profile's format choices (``xi_rounding``, ``depth_decode``, ``v2_decode``, ``xi_decode``).
    """
    r = precise.phi_exact(b, bias, dps=dps)
    zf = np.broadcast_to(np.asarray(zf, np.float64), r.shape[:1])
    decoded = _decoded64 if str(fmt) == "64" else _decoded32
    lo, hi = np.empty(len(zf)), np.empty(len(zf))
    with mpmath.workdps(dps):
        tie = mpmath.mpf(10) ** -(dps // 2) if tie is None else mpmath.mpf(float(tie))
        eps = mpmath.mpf(float(SHADE_CLAMP if clamp is None else clamp))
        for i in range(len(zf)):
            z = mpmath.mpf(float(zf[i]))
            v = [_shade_row(*t, z, eps, case_test == "clamped") for t in decoded(r[i], texel, tie)]
            lo[i], hi[i] = float(min(v)), float(max(v))
    return lo, hi


def msm64_chain(b, zf, bias=None, dps=50, tie=None):
    """The exact 64-bit affine MSM chain: ``(lo, hi)`` float64 ``(n,)`` over the texels the exact codes allow.

    Slides, "Compute moments in resolve": the four UNORM16 codes round_half_up(65535 · clamp(M·b + c, 0, 1)),
    computed exactly (:func:`moments_ref.golden.texel_truth.encode_unorm16`); where a channel's exact value lies
    within ``tie`` (a fraction of the code range, default ``10^-(dps/2)``; see :func:`nlq_chain`) of a rounding
    boundary both codes are taken. Each texel is decoded exactly
    ("Retrieve moments", :func:`~moments_ref.golden.texel_truth.decode_unorm16`, rounded once to float64),
    biased (``bias``: a BiasPreset or None) and bounded by :func:`moments_ref.precise.shadow_intensity`
    (HPG17 Algorithm 1, lower bound) in mpmath.
    """
    b = np.asarray(b, np.float64).reshape(-1, 4)
    zf = np.broadcast_to(np.asarray(zf, np.float64), b.shape[:1])
    codes, margin = encode_unorm16(b, margin=True)
    tie = 10.0 ** -(dps // 2) if tie is None else float(tie)
    near = np.flatnonzero(margin < tie)
    scaled = np.clip(to_optimized(b[near])[0], 0, 1) * 65535 if near.size else np.zeros((0, 4))
    choices = [[(c,) for c in row] for row in codes.astype(np.int64)]
    band = tie * 65535 + 1e-9  # a tied channel: its float64 scaled value that close to a half, both codes
    for i, s in zip(near, scaled):
        choices[i] = [tuple({int(c), int(np.floor(v)), int(np.floor(v)) + 1}) if abs(v - np.floor(v) - 0.5) < band
                      else (int(c),) for c, v in zip(codes[i], s)]
    texels = [list(product(*ch)) for ch in choices]
    rows = np.repeat(np.arange(len(b)), [len(t) for t in texels])
    q = np.array([t for ts in texels for t in ts], np.int64).clip(0, 65535).astype(np.uint16)
    bq = decode_unorm16(q)[0]
    if bias is not None:
        bq = precise.bias_moments(bq, bias, dps=dps)
    v = precise.shadow_intensity(bq, zf[rows], dps=dps)
    lo, hi = np.full(len(b), np.inf), np.full(len(b), -np.inf)
    np.minimum.at(lo, rows, v)
    np.maximum.at(hi, rows, v)
    return lo, hi
