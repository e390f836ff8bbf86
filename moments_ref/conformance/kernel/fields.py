"""Per-field hints for a failing quantizing kernel: which texel field is off, by how many cells, where.

A 64-bit texel (``nlq64``: HPG17 §3.3; ``msm64``: the optimized basis of the slides)
holds four 16-bit codes; a 32-bit texel (``nlq32``: HPG17 §3.5, Figure 5) four bit
fields. Where a kernel's texels fail, each field of its codes is compared with the
global path's code (``texels`` of the golden case): the hint names the field, on how
many failing texels it differs, the most common difference in cells and the range,
and the first texels. A kernel that stores √v2 as round(127·√v2) instead of
min(⌊128·√v2⌋, 127) shows up as the √v2 field, off by a cell or two; where the other
published grid's codes explain every failing texel, the hint's ``suggest`` names the
profile key that declares it (``[format] v2_cell``, :mod:`.declared`).

References
----------
.. [1] HPG17: Christoph Peters. 2017. *Non-Linearly Quantized Moment Shadow Maps*. In Proceedings
       of High Performance Graphics (HPG '17). ACM. The non-linear quantization Φ, Ψ4, Algorithms
       1–3, the texel formats and the compute shader of §4.1.
"""

from __future__ import annotations

import numpy as np

__all__ = ["FIELDS", "field_hints", "format_hint"]

#: Per texel format: (field name, shift, bits) of each field of a texel's code (64-bit: component index).
FIELDS = {
    "nlq64": (("y1 (component 0)", 0, 16), ("y2 (component 1)", 1, 16), ("v2 (component 2)", 2, 16),
              ("Psi4(xi4) (component 3)", 3, 16)),
    "msm64": (("R = 1.5 b1 - 2 b3 + 0.5 (component 0)", 0, 16), ("G = 4 b2 - 4 b4 (component 1)", 1, 16),
              ("B (component 2)", 2, 16), ("A = (b2 + b4) / 2 (component 3)", 3, 16)),
    "nlq32": (("folded y2 (bits 0-9)", 0, 10), ("folded y1 (bits 10-18)", 10, 9),
              ("sqrt(v2) cell (bits 19-25)", 19, 7), ("Psi4(xi4) cell (bits 26-31)", 26, 6)),
}


def _field(fmt, codes, shift, bits):
    c = np.asarray(codes)
    if fmt == "nlq32":
        return ((c.reshape(-1).astype(np.int64) >> shift) & ((1 << bits) - 1))
    return c.reshape(len(c), -1)[:, shift].astype(np.int64)


def field_hints(fmt, codes, expected, failing, width, first=3):
    """Hints for the texels ``failing`` (bool per texel) whose codes differ from ``expected``.

    Returns a list of dicts: ``field``, ``texels`` (failing texels where it differs),
    ``offset`` (the most common got - expected, in cells), ``share`` (texels with that
    offset), ``low``/``high`` (the range of the differences) and ``first`` ((x, y) of the
    first texels).
    """
    if fmt not in FIELDS:
        return []
    out = []
    for name, shift, bits in FIELDS[fmt]:
        d = _field(fmt, codes, shift, bits) - _field(fmt, expected, shift, bits)
        m = np.asarray(failing, bool) & (d != 0)
        if not m.any():
            continue
        values, counts = np.unique(d[m], return_counts=True)
        k = int(np.argmax(counts))
        rows = np.flatnonzero(m)[:first]
        out.append({"field": name, "texels": int(m.sum()), "offset": int(values[k]), "share": int(counts[k]),
                    "low": int(d[m].min()), "high": int(d[m].max()),
                    "first": [[int(i % width), int(i // width)] for i in rows]})
    return out


def format_hint(h):
    """One line of the report for a hint of :func:`field_hints`."""
    where = ", ".join(f"(x {x}, y {y})" for x, y in h["first"])
    rng = f" (range {h['low']:+d} .. {h['high']:+d})" if h["low"] != h["high"] else ""
    cells = "cell" if abs(h["offset"]) == 1 else "cells"
    line = (f"field {h['field']}: differs from the global path's code on {h['texels']} failing texels, by "
            f"{h['offset']:+d} {cells} on {h['share']} of them{rng}; first texels {where}")
    if h.get("suggest"):
        line += (f"; every failing texel holds the code of the other published sqrt(v2) grid: if the engine stores "
                 f"sqrt(v2) so, declare {h['suggest']} in the profile (--profile)")
    return line
