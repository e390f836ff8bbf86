"""Every receiver of the EVSM figure scene is in the shadow map (HPG17 §5, Figure 1).

HPG17's scenes render all their geometry into the shadow map. A receiver left out
of it leaves the cleared far plane (z = 1) in the filter regions around the
shadows it receives: lit depths far behind the fragment, which the positive warp
``exp(c⁺ z)`` of EVSM weighs by ``exp(c⁺ Δ)`` (e^26 for Δ = 0.66 and c⁺ = 40), so
that its Cantelli bound reports no shadow and EVSM128 falls back to the c⁻ = 5.5
warp it shares with EVSM64.

The first test reads the rasterized map itself (no technique code): every texel
of the 9×9 footprint of the shaded receiver pixels must hold geometry (except\nat the ground's own border). The
second shows, with the exact Z summed tap by tap, what the far plane does to the
method on the short-range case of tests/test_evsm_leak.py.
"""

import numpy as np
import pytest

from moments_ref import pipeline
from moments_ref.scene import load_scene
from moments_ref.techniques import get
from moments_ref.techniques.pcf import tap_weights

from test_evsm_leak import _exact, _scene


@pytest.fixture(scope="module")
def railing():
    return pipeline.run(load_scene("railing"), ["evsm64", "evsm128"], pipeline.Settings(shadow_map_size=192, msaa=1, resolution=(96, 54), reference=False))


def test_railing_receivers_cast_into_the_shadow_map(railing):
    sc, r = railing.scene, railing
    assert {o.role for o in sc.objects if o.name == "ground"} == {"both"}
    smap = r.values["raster_shadow_map"][..., 0]
    uv = r.values["light_projection"].uv
    c, rr = np.floor(uv[:, 0]).astype(int), np.floor(uv[:, 1]).astype(int)
    h, w = smap.shape
    far = 0
    for dy in range(-4, 5):
        for dx in range(-4, 5):
            far += smap[np.clip(rr + dy, 0, h - 1), np.clip(c + dx, 0, w - 1)] >= 1.0
    # Of the 2641 receiver pixels of a 96×54 view, the far plane is in the footprint
    # of 94 % with a receiver-only ground, of 1.3 % (the ground's own border) with it casting.
    assert len(uv) > 1000
    assert np.mean(far > 0) < 0.02


@pytest.mark.parametrize("d_a,d_b", [(0.1, 0.05), (0.2, 0.1)])
def test_far_plane_in_the_footprint_takes_evsm128s_advantage(d_a, d_b):
    zr = -0.2
    rows, cols = np.mgrid[12:36, 12:36]
    uv = np.stack([cols + 0.5, rows + 0.5], -1).reshape(-1, 2)
    depth = np.full(len(uv), zr)
    leak = {}
    for receiver_in_map in (True, False):
        m = _scene(d_a, d_b, zr)
        if not receiver_in_map:
            m[m == np.float32(zr)] = 1.0  # the receiver is not rendered: cleared far plane
        for name in ("evsm64", "evsm128"):
            t = get(name)
            exact = _exact(m, rows, cols, zr - t.depth_bias)
            s = t.shadow(t.prepare(m), uv, depth)
            leak[name, receiver_in_map] = float(np.maximum(exact - s, 0).sum())
    assert leak["evsm128", True] <= 0.5 * leak["evsm64", True]
    # with the far plane 1.2 behind the receiver the positive warp gives no shadow
    # and EVSM128 leaks as much as EVSM64 or more
    assert leak["evsm128", False] >= 0.9 * leak["evsm64", False]
    assert leak["evsm128", False] >= 5 * leak["evsm128", True]


@pytest.mark.parametrize("name,c_pos,c_neg,delta,tol", [("evsm64", 5.5, 5.5, 5e-3, 5e-3),
                                                        ("evsm128", 40.0, 5.5, 1e-4, 1e-4)])
def test_evsm_on_railing_is_its_bound_in_float64(railing, name, c_pos, c_neg, delta, tol):
    """Storage, filtering and float32 evaluation are not what makes EVSM128 leak.

    The filtered warped moments are summed here in float64 straight from the depth
    map with the filter's tap weights (bilinear ⊗ Gaussian), and Cantelli's bound
    of each warp is written out: the technique (float16/float32 storage, float32
    texture filtering and arithmetic, E[x²] up to e^80) agrees to ``tol``
    (measured: 7e-4 for evsm64, its float16 rounding; 1e-6 for evsm128).
    """
    z = railing.values["raster_shadow_map"][..., 0].astype(np.float64)
    proj = railing.values["light_projection"]
    ci, cw = tap_weights(proj.uv[:, 0], z.shape[1])
    ri, rw = tap_weights(proj.uv[:, 1], z.shape[0])
    d = z[ri[:, :, None], ci[:, None, :]]
    zf = proj.z_ndc_light - 1e-3
    bound = np.zeros(len(zf))
    for x, t, c in ((np.exp(c_pos * d), np.exp(c_pos * zf), c_pos), (-np.exp(-c_neg * d), -np.exp(-c_neg * zf), c_neg)):
        mu = np.einsum("nij,ni,nj->n", x, rw, cw)
        var = np.maximum(np.einsum("nij,ni,nj->n", x * x, rw, cw) - mu * mu, (delta * c * t) ** 2)
        bound = np.maximum(bound, np.where(t > mu, (t - mu) ** 2 / (var + (t - mu) ** 2), 0.0))
    s = railing.shadow[name]
    assert np.max(np.abs(s - bound)) < tol


@pytest.mark.parametrize("shape", [(), (3,), (37, 41, 4), (1 << 15,)])
def test_evsm_feature_is_its_definition(shape):
    # (exp(c+ z), exp(c+ z)², −exp(−c− z), exp(−c− z)²) per depth, however the map is chunked.
    from moments_ref.techniques.evsm import evsm_feature

    z = np.random.default_rng(len(shape)).uniform(-1, 1, shape)
    got = evsm_feature(z, 40.0, 5.5)
    p, n = np.exp(40.0 * z), -np.exp(-5.5 * z)
    assert got.shape == np.shape(z) + (4,) and got.dtype == np.float64
    assert np.array_equal(got, np.stack([p, p * p, n, n * n], axis=-1))
    assert np.array_equal(evsm_feature(z.T, 40.0, 5.5), np.stack([p.T, p.T ** 2, n.T, n.T * n.T], axis=-1))
