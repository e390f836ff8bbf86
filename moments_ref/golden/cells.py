"""The two published √v2 cell encodings of the 32-bit texel (HPG17 §3.5, Figure 5; docs/formats.md).

HPG17 stores √v2 as "a fixed-point number in seven bits" (bits 19–25 of the 32-bit
texel) and leaves the grid open. Two grids are published:

* ``"floor128"``: the code ``min(⌊128 √v2⌋, 127)``, read at the cell centre,
  ``v2 = ((c + ½)/128)²``: the HPG17 demo's and this package's format
  (:func:`moments_ref.packing.pack32`, golden schema 3);
* ``"round127"``: the code ``round(127 √v2)``, read as ``v2 = (c/127)²``: the grid of
  golden schema 2, which some engines ship.

A profile declares the grid of a 32-bit kernel with ``[format] v2_cell`` (the key of
:data:`moments_ref.golden.profile.FORMAT_KEYS`); the kernel case is then judged
against the texels of the declared grid (:mod:`moments_ref.golden.kernels`). The
other fields of the texel are the format's own either way.

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

import numpy as np

__all__ = ["V2_CELLS", "DEFAULT_CELL", "HONOURED_BY", "v2_codes", "recode", "decode_v2"]

#: The √v2 grids a profile may declare (``[format] v2_cell``); the first is the format's own.
V2_CELLS = ("floor128", "round127")
DEFAULT_CELL = V2_CELLS[0]
#: Cases whose expected values follow a declared ``v2_cell`` (every other case refuses another grid).
HONOURED_BY = ("kernel-filter-nlq32",)
_SHIFT, _BITS = 19, 7
_MASK = np.uint32(((1 << _BITS) - 1) << _SHIFT)


def v2_codes(v2, cell, dtype=np.float64):
    """The 7-bit codes of √v2 on the grid ``cell``, computed in ``dtype`` (a float32 shader's rounding)."""
    s = np.sqrt(np.maximum(np.asarray(v2, np.float64).astype(dtype), 0))
    if cell == "floor128":
        c = np.floor(s * dtype(128))
    else:
        c = np.rint(s * dtype(127))
    return np.clip(c, 0, 127).astype(np.uint32)


def recode(texels, v2, cell, dtype=np.float64):
    """32-bit texels with bits 19–25 replaced by the ``cell`` codes of ``v2`` (one per texel)."""
    t = np.asarray(texels, np.uint32)
    return (t & ~_MASK) | (v2_codes(v2, cell, dtype).reshape(t.shape) << np.uint32(_SHIFT))


def decode_v2(texels, cell):
    """v2 of 32-bit texels read on the grid ``cell`` (float64)."""
    c = ((np.asarray(texels, np.uint32) & _MASK) >> np.uint32(_SHIFT)).astype(np.float64)
    return ((c + 0.5) / 128) ** 2 if cell == "floor128" else (c / 127) ** 2
