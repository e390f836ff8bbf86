"""The kernel golden cases without a driver: what they contain, and that they tell kernels apart.

The reference's own float32 kernels (the filter32 variants, gpu.onchip's arithmetic) pass;
kernels with a wrong filter (guard band 3, an input origin one texel off, weights not
normalized, a sample ignored) and a z-buffer without the sign transform fail, judged by the
one comparator on the golden arrays.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from moments_ref import golden
from moments_ref.golden import kernels as K
from moments_ref.golden.writer import manifest_entry
from moments_ref.gpu import filter32, filtering, onchip
from moments_ref.techniques.vwss import warp


@pytest.fixture(scope="module")
def arrays():
    return {name: golden.golden_arrays(golden.CASES[name]) for name in K.KERNEL_CASES}


def _verdict(name, arrays, out):
    c = golden.CASES[name]
    return golden.compare(manifest_entry(c, arrays[name]), arrays[name], out, "float32")


def _filter_out(name, arrays, moments_of):
    fmt = name.rsplit("-", 1)[1]
    h, w = K.MAPS[fmt]
    a = arrays[name]
    m = moments_of(a["depth"].reshape(h, w, -1)).reshape(h * w, 4).astype(np.float32)
    if fmt == "moments":
        return {"moments": m}
    return {"intensity": K.decode_intensity(fmt, K.filter_codes(fmt, m), a["zf"]).astype(np.float32)}


def _blocks(z, guard=4, dx=0):
    """A block-wise float32 filter whose input block starts ``dx`` texels right and has a guard band ``guard``."""
    h, w, _ = z.shape
    m = filter32.resolve_float32(z)
    wts = filter32.weights_float32()
    out = np.empty((h, w, 4), np.float32)
    for by in range(-(-h // 24)):  # loop over blocks
        for bx in range(-(-w // 32)):
            ys = np.clip(np.arange(24 * by - guard, 24 * by + 24 + guard), 0, h - 1)
            xs = np.clip(np.arange(32 * bx - guard + dx, 32 * bx + 32 + guard + dx), 0, w - 1)
            blk = np.pad(m[np.ix_(ys, xs)], ((4 - guard,) * 2, (4 - guard,) * 2, (0, 0)), mode="edge")
            r = filter32.blur_float32(blk, wts)[4:-4, 4:-4]
            hh, ww = min(24, h - 24 * by), min(32, w - 32 * bx)
            out[24 * by:24 * by + hh, 32 * bx:32 * bx + ww] = r[:hh, :ww]
    return out


def _unnormalized(z):
    i = np.arange(9) - 4.0
    return filter32.blur_float32(filter32.resolve_float32(z), np.exp(-i * i / (2 * 2.4**2)).astype(np.float32))


LEGITIMATE = {
    "global path (float64)": lambda z: filtering.blur(filtering.resolve_moments(z.astype(np.float64))),
    "block emulation (gpu.onchip)": lambda z: onchip.filter_moments(z),
    "blocks, guard band 4": _blocks,
    **{f"filter32 {v.name}": (lambda v: lambda z: filter32.filter_float32(z, v))(v) for v in filter32.VARIANTS},
}
BUGS = {
    "guard band 3": lambda z: _blocks(z, guard=3),
    "input origin one texel off": lambda z: _blocks(z, dx=1),
    "weights not normalized": _unnormalized,
    "resolve ignoring a sample": lambda z: filter32.filter_float32(np.concatenate([z[..., :3], z[..., 2:3]], -1)),
}


@pytest.mark.parametrize("name", [n for n in K.KERNEL_CASES if n.startswith("kernel-filter")])
@pytest.mark.parametrize("kernel", LEGITIMATE)
def test_legitimate_float32_kernels_pass(arrays, name, kernel):
    v = _verdict(name, arrays, _filter_out(name, arrays, LEGITIMATE[kernel]))
    assert v.passed, (kernel, v.failures, float(v.score.max()))


@pytest.mark.parametrize("name", [n for n in K.KERNEL_CASES if n.startswith("kernel-filter")])
@pytest.mark.parametrize("bug", BUGS)
def test_filter_bugs_fail(arrays, name, bug):
    v = _verdict(name, arrays, _filter_out(name, arrays, BUGS[bug]))
    assert v.failures > 50, (bug, v.failures)


def test_filter_maps_have_partial_blocks_edges_and_ill_conditioned_texels(arrays):
    for fmt, (h, w) in K.MAPS.items():
        assert h % 24 and w % 32 and -(-h // 24) * -(-w // 32) >= 4, fmt
        a = arrays[f"kernel-filter-{fmt}"]
        cats = set(a["category"])
        assert cats == {"random", "edge", "stiff"}
        z = a["depth"].astype(np.float64)
        assert np.array_equal(((z + 1) / 2).astype(np.float32).astype(np.float64) * 2 - 1, z)  # exact window depth
    assert "wide_spread" in ",".join(arrays["kernel-filter-nlq64"]["flags"])


def test_codes_table_holds_the_legitimate_kernels_codes(arrays):
    for fmt in ("nlq64", "nlq32", "msm64"):
        a = arrays[f"kernel-filter-{fmt}"]
        h, w = K.MAPS[fmt]
        emu = K.filter_codes(fmt, onchip.filter_moments(a["depth"].reshape(h, w, -1)).reshape(-1, 4))
        n = len(emu)
        alts = a["texels_acceptable"].reshape(n, a["texels_acceptable"].shape[1], -1)
        assert (alts == emu.reshape(n, 1, -1)).all(axis=2).any(axis=1).all()


@given(st.lists(st.floats(allow_nan=False, width=32), min_size=2, max_size=50))
def test_depth_key_orders_as_the_depths(d):
    d = np.float32(d)
    k = warp.depth_key(d)
    i, j = np.triu_indices(len(d), 1)
    assert np.array_equal(k[i] < k[j], d[i] < d[j]) and np.array_equal(k[i] == k[j], d[i] == d[j])
    assert (k > warp.EMPTY_KEY).all()
    assert np.array_equal(warp.key_depth(k), d + np.float32(0.0))


def test_vwss_case_has_collisions_and_depths_behind_the_far_plane(arrays):
    a = arrays["kernel-vwss-points"]
    d = a["depth"]
    assert ((d < 0) & (d != K.EMPTY_DEPTH)).sum() > 100  # texels whose nearest point is beyond the far plane
    assert (a["category"] == "stiff").sum() > 1000 and (d == K.EMPTY_DEPTH).sum() > 1000
    # the listing's plain asuint ordering (no sign transform) picks other winners
    v, h, w = K.VWSS_MAP
    idx, r = warp.project_to_texels(a["points"][:, :3], a["views"], (h, w), clip_depth=False)
    keys = np.zeros(v * h * w, np.uint32)
    np.maximum.at(keys, idx, r.view(np.uint32) | np.uint32(0x80000000))
    wrong = np.where(keys == 0, np.float32(K.EMPTY_DEPTH), warp.key_depth(keys)).astype(np.float32)
    assert _verdict("kernel-vwss-points", arrays, {"depth": wrong}).failures > 100
    right = K.vwss_reference(a["points"], a["views"])[0]
    assert _verdict("kernel-vwss-points", arrays, {"depth": right}).passed
    swapped = right.reshape(v, h, w)[[1, 0, 2, 3, 4, 5, 6, 7]].reshape(-1)
    assert _verdict("kernel-vwss-points", arrays, {"depth": swapped}).failures > 100


def test_filter32_onchip_variant_is_the_block_emulation_bit_for_bit():
    z = np.random.default_rng(3).uniform(-1, 1, (50, 70, 4)).astype(np.float32)
    assert np.array_equal(filter32.filter_float32(z, "onchip"), onchip.filter_moments(z))
