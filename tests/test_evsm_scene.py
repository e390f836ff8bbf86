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

from test_evsm_leak import _exact, _scene


def test_railing_receivers_cast_into_the_shadow_map():
    sc = load_scene("railing")
    assert {o.role for o in sc.objects if o.name == "ground"} == {"both"}
    r = pipeline.run(sc, ["evsm128"], shadow_map_size=192, msaa=1, resolution=(96, 54), reference=False)
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
