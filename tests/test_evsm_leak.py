"""EVSM at 128 bits leaks far less than at 64 bits over short range (HPG17 §5, Figure 1).

Two occluders at short range in front of a flat receiver: occluder A covers the
left half of the map, B the top half, and a 9×9 filter region near the corner
holds three depths (A, B, receiver): the case where two moments of a mildly
warped depth (c = 5.5) cannot tell the occluders from the receiver and light
leaks, while c⁺ = 40 squeezes both occluders towards 0 and leaves a two-point
distribution for which Cantelli's bound is exact. The exact shadow Z(z < zf) is
summed here tap by tap over the 9×9 Gaussian (σ = 2.4) footprint, independently of
the filtering module and of the technique code.
"""

import numpy as np
import pytest

from moments_ref.techniques import get

H = W = 48


def _scene(d_a, d_b, zr):
    m = np.full((H, W, 1), zr, np.float32)
    m[:, :W // 2] = zr - d_a
    m[:H // 2, :] = zr - d_b
    m[:H // 2, :W // 2] = zr - max(d_a, d_b)
    return m


def _exact(m, rows, cols, zf):
    k = np.exp(-0.5 * (np.arange(-4, 5) / 2.4) ** 2)
    k /= k.sum()
    g = np.outer(k, k)
    return np.array([float((g * (m[r - 4:r + 5, c - 4:c + 5, 0] < zf)).sum())
                     for r, c in zip(rows.ravel(), cols.ravel())])


@pytest.mark.parametrize("zr", [-0.6, -0.2, 0.5])
@pytest.mark.parametrize("d_a,d_b", [(0.1, 0.05), (0.15, 0.075), (0.2, 0.1)])
def test_evsm128_leaks_far_less_than_evsm64_over_short_range(d_a, d_b, zr):
    m = _scene(d_a, d_b, zr)
    rows, cols = np.mgrid[12:36, 12:36]
    uv = np.stack([cols + 0.5, rows + 0.5], -1).reshape(-1, 2)  # texel centres: no bilinear mixing
    depth = np.full(len(uv), zr)
    leak, frac = {}, {}
    for name in ("evsm64", "evsm128"):
        t = get(name)
        exact = _exact(m, rows, cols, zr - t.depth_bias)
        s = t.shadow(t.prepare(m), uv, depth)
        # Cantelli's bound on either warp is a lower bound of the exact shadow
        # (float16 storage of evsm64 may cross it by its rounding).
        assert np.all(s <= exact + (1e-2 if name == "evsm64" else 1e-4))
        leak[name] = float(np.maximum(exact - s, 0).sum())
        frac[name] = float(np.mean(exact - s > 0.05))
    assert frac["evsm64"] > 0.01  # the case provokes leaking at 64 bits
    assert frac["evsm128"] <= 0.25 * frac["evsm64"]
    assert leak["evsm128"] <= 0.5 * leak["evsm64"]
