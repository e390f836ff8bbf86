"""The output layout of a filter kernel that writes a buffer: how its texels lie in the words.

HPG17 §4.1 writes one texel per invocation and leaves the memory layout of the map
to the engine. A kernel that writes a storage image has one layout; one that writes
a buffer may write

* ``interleaved`` (the default): texel (x, y) at words ``(y w + x) c .. + c - 1``
  (``c`` = 4 for 64-bit and 128-bit texels, one 32-bit word per component; 1 for nlq32);
* ``planar``: component k of texel (x, y) at word ``k h w + y w + x``;
* ``packed16``: a 64-bit texel (nlq64, msm64) as two words, the 16-bit fields packed in
  pairs, ``c0 | c1 << 16`` and ``c2 | c3 << 16``.

The harness sizes the buffer for the declared layout (the padding of a block more,
after the map, catches writes outside it), reads the texels back in that layout and
judges them as any other kernel's (``--kernel-layout``, or ``layout`` in a profile's
``[kernel]`` table).

References
----------
.. [1] HPG17: Christoph Peters. 2017. *Non-Linearly Quantized Moment Shadow Maps*. In Proceedings
       of High Performance Graphics (HPG '17). ACM. The non-linear quantization Φ, Ψ4, Algorithms
       1–3, the texel formats and the compute shader of §4.1.
"""

from __future__ import annotations

import numpy as np

from ..._arrays import InputError

__all__ = ["LAYOUTS", "check_layout", "buffer_words", "element_bytes", "split"]

#: The output layouts of a buffer a filter kernel may declare.
LAYOUTS = ("interleaved", "planar", "packed16")


def _components(fmt):
    return 1 if fmt == "nlq32" else 4


def check_layout(layout, fmt):
    """``layout`` if the texel format ``fmt`` can have it, else :class:`InputError` (exit 2)."""
    if layout not in LAYOUTS:
        raise InputError(f"kernel layout: expected one of {', '.join(LAYOUTS)}, got {layout!r}")
    if layout == "packed16" and fmt not in ("nlq64", "msm64"):
        raise InputError(f"kernel layout: packed16 packs 16-bit fields, which {fmt} texels do not have "
                         "(nlq64, msm64 do)")
    if layout == "planar" and fmt == "nlq32":
        raise InputError("kernel layout: an nlq32 texel is one word; planar and interleaved are the same")
    return layout


def buffer_words(fmt, layout, texels, pad):
    """Words of the output buffer: ``texels`` of the map and ``pad`` texels of padding after it."""
    per = 2 if layout == "packed16" else _components(fmt)
    return (texels + pad) * per


def element_bytes(fmt, layout):
    """Bytes per buffer element the layout allows (None: the contract's own)."""
    return {"planar": (4,), "packed16": (4, 8)}.get(layout)


def split(raw, fmt, layout, h, w, fill):
    """``(codes (h w, c), unwritten (h, w), outside mask)`` of a buffer read back in ``layout``."""
    n, c = h * w, _components(fmt)
    if layout == "planar":
        planes = raw[: c * n].reshape(c, n)
        mapped = np.ascontiguousarray(planes.T)
        unwritten = (planes == fill).all(axis=0).reshape(h, w)
        return mapped, unwritten, raw[c * n:] != fill
    if layout == "packed16":
        words = raw[: 2 * n].reshape(n, 2).astype(np.uint32)
        mapped = np.stack([words[:, 0] & 0xFFFF, words[:, 0] >> 16, words[:, 1] & 0xFFFF, words[:, 1] >> 16], axis=1)
        unwritten = (words == fill).all(axis=1).reshape(h, w)
        return mapped, unwritten, raw[2 * n:] != fill
    mapped = raw[: n * c].reshape(n, c)
    return mapped, (mapped == fill).all(axis=-1).reshape(h, w), raw[n * c:] != fill
