"""An independent port of bilinear sampling of a moment texture, in float32, with its mutations.

What a porter writes who samples a moment texture between texel centres (HPG17 §1:
moments are linear in the distribution, so the filtered texel is the moments of the
filtered distribution) and shades the sample with HPG17 §3.2's bias and Algorithm 1.
It imports only ``numpy`` and the sibling ports (``ports.py``). A row is a 2×2
neighbourhood, texel (i, j) (i right, j down) at ``texels[4 (2 j + i) : 4 (2 j + i) + 4]``,
and the fraction (fx, fy) of the sample's position between the four texel centres.
"""

from __future__ import annotations

import numpy as np

try:  # imported as a package (tests) or by path (moments-ref mutants)
    from . import ports
except ImportError:  # pragma: no cover
    import ports  # type: ignore

#: HPG17 §3.2, float32 moments: alpha = 3e-7 toward b* = (0, 0.375, 0, 0.375).
ALPHA32, TARGET32 = 3e-7, [0.0, 0.375, 0.0, 0.375]
#: Keys of ``m`` that change the arithmetic of the whole port, also of the bias and Algorithm 1.
_ARITH = ("f64", "fma")


def _weight(f, m):
    """The weight of the second texel along one axis, at the fraction ``f`` between the two centres."""
    if m.get("half_texel"):  # the texel's corner taken for its centre: half a texel on, the edge texel beyond
        f = np.minimum(f + 0.5, 1)
    if m.get("point"):  # a point sampler: the nearest texel
        f = np.floor(f + 0.5)
    bits = m.get("weight_bits")
    if bits:  # a texture unit's sub-texel precision: the position quantized to `bits` fraction bits
        s = 2.0**bits
        f = (np.floor(f * s + 0.5) if m.get("weight_round") == "nearest" else np.floor(f * s)) / s
    return f


def _lerp(a, b, w, A, m):
    """GLSL ``mix(a, b, w)``: a (1 − w) + b w (or a + w (b − a), or with the weights swapped)."""
    w = A.c(w)[:, None]
    if m.get("swap_weights"):
        return a * w + b * (1 - w)
    if m.get("lerp_delta"):
        return a + w * (b - a)
    return a * (1 - w) + b * w


def sample(texels, fraction, m):
    """The bilinear sample ``(n, 4)``: lerps along x, then along y (a texture unit's order)."""
    A = ports.Ar(m)
    t = A.c(texels).reshape(-1, 4, 4)
    t00, t10, t01, t11 = t[:, 0], t[:, 1], t[:, 2], t[:, 3]
    f = np.asarray(fraction, np.float64)
    fx, fy = (f[:, 1], f[:, 0]) if m.get("swap_xy") else (f[:, 0], f[:, 1])
    wx, wy = _weight(fx, m), _weight(fy, m)
    if m.get("hand"):  # by hand from four loads: the four weights' products, summed
        wx, wy = A.c(wx)[:, None], A.c(wy)[:, None]
        return A.out((1 - wx) * (1 - wy) * t00 + wx * (1 - wy) * t10 + (1 - wx) * wy * t01 + wx * wy * t11)
    top, bottom = _lerp(t00, t10, wx, A, m), _lerp(t01, t11, wx, A, m)
    return A.out(_lerp(top, bottom, wy, A, m))


def shadow_intensity(texels, fraction, zf, m):
    """HPG17 Algorithm 1's lower bound on the bilinear sample, biased inside (§3.2, float32 preset)."""
    arith = {k: m[k] for k in _ARITH if k in m}
    b = ports.bias(sample(texels, fraction, m), ALPHA32, TARGET32, arith)
    return ports.alg1(b, zf, arith, bound="lower")
