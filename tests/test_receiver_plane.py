"""The 9×9 PCF reference with receiver-plane depth (Isidoro 2006): exact on planes, contact shadows kept.

The expectations are computed here independently: the plane's depth analytically,
the filtered visibility by a plain Python loop over the taps with the Direct3D 11
4× sample pattern written out.
"""

import math

import numpy as np

from moments_ref.gpu.filtering import gaussian_weights
from moments_ref.scene.raster import rasterize_depth
from moments_ref.techniques.pcf import pcf_filtered

N = 64  # map side; identity view-projection: u = (x + 1)·N/2, v = (1 − y)·N/2, depth = z
A, B, C = 0.15, 0.1, 0.5  # plane z = C + A·x + B·y in NDC
GRAD = np.array([2 * A / N, -2 * B / N])  # its depth change per texel (∂z/∂u, ∂z/∂v)
D3D11_4X = [(-2 / 16, -6 / 16), (6 / 16, -2 / 16), (-6 / 16, 2 / 16), (2 / 16, 6 / 16)]


def _plane_depth(u, v):
    return C + A * (2 * u / N - 1) + B * (1 - 2 * v / N)


def _tilted_plane_map():
    """The plane rasterized into an N² map with 4× MSAA (a quad covering the whole map)."""
    x = np.array([-1.5, 1.5, 1.5, -1.5])
    y = np.array([-1.5, -1.5, 1.5, 1.5])
    vertices = np.stack([x, y, C + A * x + B * y], axis=1)
    depth, _ = rasterize_depth(vertices, np.array([[0, 1, 2], [0, 2, 3]]), np.eye(4), N, samples=4)
    return depth


def test_lit_tilted_plane_is_unshadowed_by_the_receiver_plane_reference():
    """No occluder: exactly 0 with receiver-plane depth; about half shadowed with one unbiased depth."""
    maps = _tilted_plane_map()
    rng = np.random.default_rng(1)
    uv = rng.uniform(6, N - 6, (300, 2))  # the 10×10 footprint stays inside the map
    zf = _plane_depth(uv[:, 0], uv[:, 1]) - 1e-3
    plane = pcf_filtered(maps, uv, zf, gradient=GRAD)
    assert plane.max() == 0.0
    single = pcf_filtered(maps, uv, zf)  # the old unbiased 9×9 PCF: surface acne
    assert 0.4 < np.median(single) < 0.6
    # power: the plane tilted the wrong way is not the receiver plane
    assert np.median(pcf_filtered(maps, uv, zf, gradient=-GRAD)) > 0.4


def _contact_map():
    """The plane plus a wedge occluder for u < 32 rising from it: z = plane − 0.01·(32 − u), touching at u = 32."""
    maps = np.empty((N, N, 4), np.float32)
    for s, (ox, oy) in enumerate(D3D11_4X):
        v, u = np.mgrid[0:N, 0:N] + 0.5
        u, v = u + ox, v + oy
        z = _plane_depth(u, v)
        maps[:, :, s] = np.where(u < 32, z - 0.01 * (32 - u), z)
    return maps


def _brute_force(occlusion, u, v, zf, grad):
    """Σ over the 2×2 bilinear texels, the 9×9 Gaussian taps and the 4 samples, in plain Python.

    ``occlusion(row, col, s, plane)``: how much of the sample lies in front of the
    receiver plane's depth ``plane`` there (0 or 1 for a plain map).
    """
    g = gaussian_weights()
    x0, y0 = math.floor(u - 0.5), math.floor(v - 0.5)
    fx, fy = u - 0.5 - x0, v - 0.5 - y0
    total = 0.0
    for bx, wbx in ((x0, 1 - fx), (x0 + 1, fx)):
        for by, wby in ((y0, 1 - fy), (y0 + 1, fy)):
            for tx in range(-4, 5):
                for ty in range(-4, 5):
                    col, row = bx + tx, by + ty
                    w = wbx * wby * g[tx + 4] * g[ty + 4] / 4
                    for s, (ox, oy) in enumerate(D3D11_4X):
                        plane = zf + grad[0] * (col + 0.5 + ox - u) + grad[1] * (row + 0.5 + oy - v)
                        total += w * occlusion(row, col, s, plane)
    return total


def test_contact_shadow_equals_brute_force():
    maps = _contact_map()
    pts = [(32.3, 20.7), (33.1, 40.2), (34.9, 31.5), (36.6, 12.0), (30.4, 50.5), (25.2, 22.2)]
    uv = np.array(pts)
    zf = _plane_depth(uv[:, 0], uv[:, 1]) - 1e-3
    got = pcf_filtered(maps, uv, zf, gradient=GRAD)
    def occlusion(row, col, s, plane):
        return float(maps[row, col, s]) < plane

    want = [_brute_force(occlusion, u, v, z, GRAD) for (u, v), z in zip(pts, zf)]
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-12)
    # the contact shadow: next to the contact line about half the footprint lies under the wedge
    assert got[0] > 0.3 and got[-2] > 0.6 and abs(got[-1] - 1) < 1e-12
    # PCF's receiver-slope bias (4.5√2 texels × slope) loses most of the contact shadow on the lit side
    biased = pcf_filtered(maps, uv, zf - 4.5 * 2**0.5 * np.hypot(*GRAD))
    assert biased[0] < got[0] - 0.2
    # far from it the plane is lit, exactly
    assert pcf_filtered(maps, np.array([[50.0, 30.0]]), _plane_depth(50.0, 30.0) - 1e-3, gradient=GRAD)[0] == 0.0


def test_translucent_contact_shadow_equals_brute_force():
    """Layered map (translucency reference): a wedge of opacity 0.4 over the plane, Σ_k weight_k [z_k < plane]."""
    from moments_ref.techniques import LayeredSamples

    plane_map = _contact_map()
    wedge = plane_map < _tilted_plane_map() - 1e-6  # samples where the wedge lies in front of the plane
    depth = np.stack([np.where(wedge, plane_map, 1.0), _tilted_plane_map()], axis=-1).astype(np.float32)
    weight = np.stack([np.where(wedge, 0.4, 0.0), np.where(wedge, 0.6, 1.0)], axis=-1)
    layered = LayeredSamples(depth, weight)
    pts = [(32.3, 20.7), (33.1, 40.2), (30.4, 50.5), (25.2, 22.2)]
    uv = np.array(pts)
    zf = _plane_depth(uv[:, 0], uv[:, 1]) - 1e-3
    got = pcf_filtered(layered, uv, zf, gradient=GRAD)

    def occlusion(row, col, s, plane):
        return sum(weight[row, col, s, k] for k in range(2) if float(depth[row, col, s, k]) < plane)

    want = [_brute_force(occlusion, u, v, z, GRAD) for (u, v), z in zip(pts, zf)]
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-12)
    assert abs(got[-1] - 0.4) < 1e-12 and got[0] > 0.1  # inside the wedge's shadow: its opacity


def test_receiver_plane_depths_are_the_documented_sums_bit_for_bit():
    """Every tap's and sample's plane depth, summed per element by plain Python floats in the documented order:
    ``min(((zf + gx·(x − u)) + gy·(y − v)) + gx·o_x + gy·o_y, 1)`` (x, y the tap centres, o the 4× offsets)."""
    from moments_ref.techniques.pcf import _receiver_plane, _sample_offsets, tap_centres

    rng = np.random.default_rng(7)
    n, size = 6, 40
    uv = rng.uniform(-3, size + 3, (n, 2))
    zf = rng.uniform(-1, 1.2, n)
    grad = rng.normal(0, 0.05, (n, 2))
    off = _sample_offsets(4)
    got = _receiver_plane(zf[:, None, None, None], grad, uv, off, size, size)
    cx, cy = tap_centres(uv[:, 0], size), tap_centres(uv[:, 1], size)
    assert got.shape == (n, 10, 10, 4)
    for i in range(n):
        gx, gy = float(grad[i, 0]), float(grad[i, 1])
        for r in range(10):
            for c in range(10):
                for s in range(4):
                    want = float(zf[i]) + gx * (float(cx[i, c]) - float(uv[i, 0])) + gy * (float(cy[i, r]) - float(uv[i, 1]))
                    want = min(want + gx * float(off[s, 0]) + gy * float(off[s, 1]), 1.0)
                    assert got[i, r, c, s] == want, (i, r, c, s)
    assert (got == 1.0).any() and (got < 1.0).any()
