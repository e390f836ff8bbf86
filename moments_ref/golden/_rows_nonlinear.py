"""Golden rows, part 2: the non-linear representation, Algorithm 3, the texel formats.

Rows follow HPG17 §3.3–§3.5: random representations, the clamps of Algorithm 3
(§3.4) exactly as the decoders produce them (y1 = y2 in one 32-bit cell; v2 = 0 and
v2 = 1 from the 64-bit codes 0 and 65535), the fold boundaries of Figure 5 and the Ψ4
cell boundaries.

References
----------
.. [1] HPG17: Christoph Peters. 2017. *Non-Linearly Quantized Moment Shadow Maps*. In Proceedings
       of High Performance Graphics (HPG '17). ACM. The non-linear quantization Φ, Ψ4, Algorithms
       1–3, the texel formats and the compute shader of §4.1.
"""

from __future__ import annotations

import numpy as np

from ._rows import Rows, _rows

def _random_representations(rng, n):
    y = np.sort(rng.uniform(-1, 1, (n, 2)), axis=1)
    v2 = rng.uniform(0.01, 0.99, n)
    xi4 = 10 ** rng.uniform(-7, np.log10(0.25), n)
    return np.column_stack([y, v2, xi4])


# (representation, comment, flags). Rows at the clamps of Algorithm 3 are gated: the
# clamped value is the specification (HPG17 §3.4), not a float32 limitation.
_STIFF_REPRESENTATIONS = [
    ((-0.8, 0.4, 0.6, 1.2e-7), "ξ4 at the Ψ4 clamp 1.2e-7", ("clamp",)),
    ((-0.8, 0.4, 0.6, 1.3e-7), "ξ4 just above the Ψ4 clamp", ()),
    ((0.1, 0.1 + 1e-6, 0.5, 1e-7), "y2 - y1 = 1e-6 (Algorithm 3 clamp)", ("clamp",)),
    ((0.1, 0.1 + 1e-4, 0.5, 1e-9), "y2 - y1 = 1e-4, tiny ξ4", ()),
    ((0.1, 0.1 + 1e-5, 0.5, 1e-6), "y2 - y1 = 1e-5, small gap above the clamp", ()),
    ((-0.5, 0.5, 1e-6, 1e-5), "v2 = 1e-6 (Algorithm 3 clamp)", ("clamp",)),
    ((-0.5, 0.5, 1 - 1e-6, 1e-5), "v2 = 1 - 1e-6 (Algorithm 3 clamp)", ("clamp",)),
    ((-0.3, 0.2, 0.4, 0.0), "ξ4 = 0 (two-point distribution)", ()),
    ((0.2, 0.6, 0.0, 1e-3), "v2 = 0 exactly (Algorithm 3 clamps v2 to 1e-6)", ("clamp",)),
    ((0.2, 0.6, 1.0, 1e-3), "v2 = 1 exactly (Algorithm 3 clamps v2 to 1 - 1e-6)", ("clamp",)),
    ((0.3, 0.3, 0.5, 1e-4), "y1 = y2 exactly (Algorithm 3 clamps the gap to 1e-6)", ("clamp",)),
    ((-0.7, -0.7, 0.2, 1e-6), "y1 = y2 exactly, small ξ4", ("clamp",)),
    ((0.4, 0.4 + 5e-7, 0.7, 1e-5), "y2 - y1 = 5e-7, below the gap clamp", ("clamp",)),
    ((-0.2, -0.2, 0.0, 1e-4), "y1 = y2 and v2 = 0 (both clamps)", ("clamp",)),
]
_EDGE_REPRESENTATIONS = [
    ((-1.0, 1.0, 0.5, 0.25), "depths at ±1, ξ4 at its maximum 0.25", ()),
    ((-1.0, -1.0 + 2 / 1023, 0.5, 1e-4), "depths in the lowest 32-bit cells", ()),
    ((1.0 - 2 / 1023, 1.0, 0.5, 1e-4), "depths in the highest 32-bit cells", ()),
    ((-0.0005, 0.0005, 0.5, 1e-6), "depths around the 32-bit fold at ỹ = 511.5", ()),
    ((511.25 / 511.5 - 1, 0.5, 0.5, 1e-4), "ỹ1 = 511, the last unfolded code (Figure 5)", ("fold",)),
    ((512.25 / 511.5 - 1, 0.5, 0.5, 1e-4), "ỹ1 = 512, the first folded code (Figure 5)", ("fold",)),
    ((-0.5, -0.5 + 0.5 / 511.5, 0.5, 1e-4), "ỹ1 = ỹ2 in the lower half (one cell)", ("fold",)),
    ((0.5, 0.5 + 0.5 / 511.5, 0.5, 1e-4), "ỹ1 = ỹ2 in the upper half (one cell, folded)", ("fold",)),
    ((1.0, 1.0, 0.5, 1e-4), "y1 = y2 = 1 (the top cell 1022)", ("fold", "clamp")),
    ((-1.0, -1.0, 0.5, 1e-4), "y1 = y2 = -1", ("fold", "clamp")),
]


def _decoded_representations():
    """Representations as the decoders produce them (y1 = y2; v2 = 0 or 1 exactly from the 64-bit decoder)."""
    from ..packing import pack32, pack64, unpack32, unpack64

    r = np.array([[0.3, 0.3005, 0.0, 1e-3], [0.3, 0.3005, 1.0, 1e-3], [-0.6004, -0.6, 0.5, 1e-5],
                  [0.1, 0.6, 0.0, 1e-2], [0.1, 0.6, 1.0, 1e-2]])
    r[:, :2].sort(axis=1)
    d32 = unpack32(pack32(r))
    d64 = unpack64(pack64(r))
    what = ["one 32-bit cell, v2 code 0", "one 32-bit cell, v2 code 127", "one 32-bit cell",
            "v2 code 0", "v2 code 127"]
    return np.concatenate([d32, d64]), [f"unpack32 output: {w}" for w in what] + \
        [f"unpack64 output: {w}" for w in what]


def _bump_xi(count=8):
    """float32 ξ4 whose rounded-up 16-bit Ψ4 code still decodes below ξ4 (found by search)."""
    from ..nonlinear import psi4, psi4_inverse

    f = np.float32
    k = np.arange(1, 65535, dtype=np.int64)
    xi = np.nextafter(psi4_inverse(k.astype(f) / f(65535)), f(1))
    code = np.ceil(psi4(xi) * f(65535))
    low = psi4_inverse(code.astype(f) / f(65535)) < xi
    idx = np.flatnonzero(low)
    pick = idx[np.linspace(0, len(idx) - 1, min(count, len(idx))).astype(int)] if len(idx) else idx
    return [(xi[i], int(k[i])) for i in pick]


def _ceil_xi(rng, count=6, n=200000):
    """float32 ξ4 whose 16-bit code is ceil(65535 Ψ4) = k + 1 although code k already decodes to ≥ ξ4.

    Rounding to nearest plus the decode check would store k there: the rows tell the
    prescribed rounding (up) from that alternative; found by a seeded search.
    """
    from ..nonlinear import psi4, psi4_inverse

    f = np.float32
    xi = (10 ** rng.uniform(-6.9, np.log10(0.25), n)).astype(f)
    u = psi4(xi) * f(65535)
    up, near = np.ceil(u), np.rint(u)
    keeps = (near < up) & (psi4_inverse(near.astype(f) / f(65535)) >= xi)
    for g in (1 + 8 * 2.0**-23, 1 - 8 * 2.0**-23):  # not a tie: stable under 8-ulp nudges
        keeps &= np.ceil(psi4((xi.astype(np.float64) * g).astype(f)) * f(65535)) == up
    idx = np.flatnonzero(keeps)[:count]
    return [(xi[i], int(near[i])) for i in idx]


def _psi4_boundary_xi(dtype=np.float64):
    """ξ4 on the cell boundaries of the 6-bit Ψ4 code (Ψ4 · 64 = k)."""
    from ..nonlinear import psi4_inverse
    from ..packing import XI_CELLS

    return psi4_inverse(np.array([1, 10, 31, 63]) / XI_CELLS)


def _representation_table(decoded=False):
    """(r (n, 4), category, comment, flags) of the hand-picked representations.

    ``decoded``: also the outputs of the decoders (y1 = y2; v2 = 0 or 1 from 64 bits) for
    Algorithm 3; the encoders get those in case ``reencode64`` (they sit on ties).
    """
    rs, cats, comments, flags = [], [], [], []
    for cat, table in (("stiff", _STIFF_REPRESENTATIONS), ("edge", _EDGE_REPRESENTATIONS)):
        for r, what, fl in table:
            rs.append(r), cats.append(cat), comments.append(what), flags.append(fl)
    dec, what = _decoded_representations() if decoded else ([], [])
    for r, w in zip(dec, what):
        rs.append(tuple(r)), cats.append("edge"), comments.append(w), flags.append(("clamp",))
    return np.array(rs, dtype=np.float64), cats, comments, flags


def _reencode_rows(rng, dtype):
    """Representations whose ξ4 is a decoded 16-bit code (re-encoding a texel) or needs the decode check."""
    from ..nonlinear import psi4_inverse

    rs, comments = [], []
    for k in (1, 2, 7, 100, 3000, 40000, 65534):
        xi = float(psi4_inverse(np.float32(k) / np.float32(65535)))
        rs.append((-0.3, 0.45, 0.5, xi))
        comments.append(f"ξ4 = {xi:.9g}, the float32 decode of the 16-bit Ψ4 code {k} (re-encoding a texel)")
    for xi, k in _bump_xi():
        rs.append((-0.3, 0.45, 0.5, float(xi)))
        comments.append(f"ξ4 = {xi:.9g}, one float32 ulp above the decode of 16-bit code {k}: ceil(65535 Ψ4) "
                        "alone decodes below ξ4, the encoder's decode check must bump the code")
    for xi, k in _ceil_xi(rng):
        rs.append((-0.3, 0.45, 0.5, float(xi)))
        comments.append(f"ξ4 = {xi:.9g}: ceil(65535 Ψ4) = {k + 1}, although code {k} decodes to at least ξ4 "
                        f"(the format rounds up; rounding to nearest plus the check would keep {k})")
    dec, what = _decoded_representations()
    rs += [tuple(x) for x in dec]
    comments += what
    for xi in _psi4_boundary_xi():
        rs.append((-0.3, 0.45, 0.5, float(xi)))
        comments.append(f"ξ4 = {xi:.9g} on a 6-bit Ψ4 cell boundary")
    r = _random_representations(rng, 40)
    return Rows.concat([
        Rows({"r": np.array(rs)}, ["edge"] * len(rs), comments, [("code_boundary",)] * len(rs)),
        _rows({"r": r}, "random", "random representation (see case phi_inverse)"),
    ])


def _representation_rows(rng, dtype):
    r, cats, comments, flags = _representation_table()
    parts = [_rows({"r": _random_representations(rng, 150)}, "random",
                   "y1 < y2 uniform in [-1, 1], v2 in [0.01, 0.99], ξ4 log-uniform in [1e-7, 0.25]")]
    parts.append(Rows({"r": r}, cats, comments, flags))
    return Rows.concat(parts)


def _shade_rows(rng, dtype):
    r = _random_representations(rng, 200)
    parts = [_rows({"r": r, "zf": rng.uniform(-1, 1, 200)}, "random",
                   "random representation (see case phi_inverse) and zf uniform in [-1, 1]")]
    table, cats, comments, flags = _representation_table(decoded=True)
    for rep, cat, what, fl in zip(table, cats, comments, flags):
        y1, y2 = rep[0], rep[1]
        # "Just below y2": 2e-6 below (16 float32 ulps or more), so that z'f = (zf - y1)/(y2 - y1) < 1
        # survives a division 3 ulps off; closer than that the side of z'f = 1 is decided by rounding.
        zf = np.array([y1, y2, y1 + 1e-6, y2 + 1e-6, y2 - 2e-6, 0.5 * (y1 + y2), min(1.0, y2 + 0.1)])
        why = ["zf = y1 (exactly: 0)", "zf = y2 exactly", "zf = y1 + 1e-6", "zf = y2 + 1e-6", "zf = y2 - 2e-6",
               "zf midway", "zf = y2 + 0.1"]
        parts.append(Rows({"r": np.repeat(rep[None], len(zf), 0), "zf": zf}, [cat] * len(zf),
                          [f"{what}, {w} = {x:.9g}" for w, x in zip(why, zf)],
                          [fl + (("support_point",) if k < 2 else ()) for k in range(len(zf))]))
    return Rows.concat(parts + _shade_sweep_edges())


#: Edge rows from the sweep's shrunk failures (docs/sweep.md): representations Φ of biased two-depth texels.
_SHADE_SWEEP_EDGES = [
    ((0.995, -0.998), (0.5, 0.5), 0.9951,
     "sweep: a nearly two-point texel (depths 0.995, -0.998, equal weights) after BIAS_FLOAT32, zf = 0.9951 "
     "(xi'4 near 1e-8: a floor on xi'4 above the smallest normal float moves w_l)"),
    ((-0.997, 0.93), (0.00082, 0.99918), -0.996,
     "sweep: v2 within 1e-3 of 1 (a faint depth -0.997 in front of 0.93) after BIAS_FLOAT32, zf 1e-3 behind y1 "
     "(a one-sided early out returns 0 here)"),
]


def _shade_sweep_edges():
    from ..moments import BIAS_FLOAT32, bias_moments, power_moments
    from ..nonlinear import phi

    parts = []
    for zs, ws, zf, why in _SHADE_SWEEP_EDGES:
        r = phi(bias_moments(power_moments(np.array(zs), np.array(ws)), BIAS_FLOAT32))
        parts.append(_rows({"r": r[None], "zf": np.array([zf])}, "edge", why))
    return parts


def _psi4_rows(rng, dtype):
    return Rows.concat([
        _rows({"xi4": 10 ** rng.uniform(-7, np.log10(0.25), 120)}, "random", "ξ4 log-uniform in [1e-7, 0.25]"),
        _rows({"xi4": np.array([1.2e-7 * (1 + 1e-6), 1.2e-7 * (1 - 1e-6)])}, "stiff",
              ["just above the clamp 1.2e-7", "just below the clamp 1.2e-7"]),
        _rows({"xi4": np.array([0.0, 1e-7, 1.2e-7, 0.25])}, "edge",
              ["ξ4 = 0 (clamped)", "ξ4 = 1e-7 (clamped)", "ξ4 at the clamp: Ψ4 = 0", "ξ4 = 0.25: Ψ4 = 1"]),
    ])


def _psi4_inverse_rows(rng, dtype):
    from ..packing import XI_CELLS

    k = np.arange(0, 64, 9)
    return Rows.concat([
        _rows({"u": rng.uniform(0, 1, 120)}, "random", "u uniform in [0, 1]"),
        _rows({"u": np.array([0.0, 1.0, 0.5])}, "edge", ["u = 0", "u = 1", "u = 0.5"]),
        _rows({"u": np.concatenate([k / XI_CELLS, (k + 1) / XI_CELLS])}, "edge",
              [f"u = {x}/64 (the lower end of a 6-bit Ψ4 cell)" for x in k]
              + [f"u = ({x} + 1)/64 (a 6-bit Ψ4 code read at the upper end of its cell)" for x in k],
              ("code_boundary",)),
    ])


def _pack64_input_rows(rng, dtype):
    from ..packing import pack64

    r = _representation_rows(rng, dtype)
    return Rows({"q": pack64(r.inputs["r"])}, r.category, [f"pack64 of: {c}" for c in r.comment], r.flags)


def _pack32_input_rows(rng, dtype):
    from ..packing import V_SHIFT, XI_SHIFT, Y1_SHIFT, Y2_SHIFT, pack32

    r = _representation_rows(rng, dtype)
    base = (300 << Y1_SHIFT) | (700 << Y2_SHIFT)  # ỹ1 = 300, ỹ2 = 700 (unfolded)
    codes = np.concatenate([base | (np.arange(64) << XI_SHIFT) | (64 << V_SHIFT),
                            base | (np.arange(128) << V_SHIFT) | (20 << XI_SHIFT)]).astype(np.int64)
    every = Rows({"p": codes}, ["edge"] * 192,
                 [f"every 6-bit Ψ4 code: {k}" for k in range(64)] + [f"every 7-bit √v2 code: {k}" for k in range(128)],
                 [("code_boundary",)] * 192)
    return Rows.concat([Rows({"p": pack32(r.inputs["r"]).astype(np.int64)}, r.category,
                             [f"pack32 of: {c}" for c in r.comment], r.flags), every])
