"""Tests of moments_ref.packing: the 64-bit and 32-bit texel formats (HPG17 §3.3, §3.5).

Independent references: exhaustive enumeration of all depth-code pairs and all
6-bit ξ4 codes, the bit layout written down in docs/formats.md (reassembled here
by hand), brute-force depth distributions and their exact Z(z < zf).

The 32-bit decoder reads depths and Ψ4 at the upper end of their cell and √v2 at its
centre (HPG17 §3.5's lower-bound principle; the HPG17 demo's decoder): the tests
below check that choice against the alternatives (the cell centre for depths, the
old grid on which v2 reached 0 and 1) on the same measures as docs/formats.md.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from moments_ref import InputError, nonlinear as nl, packing as pk, precise
from moments_ref.moments import BIAS_FLOAT32, bias_moments, power_moments
from moments_ref.tools.strategies import depth_distributions


@st.composite
def representations(draw):
    y1 = draw(st.floats(-1, 1))
    y2 = draw(st.floats(y1, 1))
    v2 = draw(st.floats(0, 1))
    xi4 = draw(st.one_of(st.floats(0, 0.25), st.sampled_from([0.0, 1.2e-7, 1e-6, 0.25])))
    return np.array([y1, y2, v2, xi4])


# ---------------------------------------------------------------------------
# Triangle fold (Figure 5), exhaustive


def all_pairs():
    t1, t2 = np.triu_indices(1023)  # all 0 ≤ t1 ≤ t2 ≤ 1022
    return t1, t2


def test_fold_is_a_bijection_into_19_bits():
    t1, t2 = all_pairs()
    assert t1.size == 1023 * 1024 // 2 == 523776
    f1, f2 = pk.fold(t1, t2)
    assert f1.min() >= 0 and f1.max() <= 511  # 9 bits
    assert f2.min() >= 0 and f2.max() <= 1022  # 10 bits
    key = f1 * 1024 + f2
    assert np.unique(key).size == t1.size  # injective
    u1, u2 = pk.unfold(f1, f2)
    np.testing.assert_array_equal(u1, t1)
    np.testing.assert_array_equal(u2, t2)
    # 18 bits cannot hold them (pigeonhole), 19 do; without the fold it takes 20.
    assert t1.size > 2**18
    assert key.max() < 2**19


def test_fold_mutant_without_the_minus_one_collides():
    """The fold's 1022 − ỹ2 (not 1023 − ỹ2) matters: with 1023 pairs collide."""
    t1, t2 = all_pairs()
    flip = t1 >= 512
    g1 = np.where(flip, 1023 - t1, t1)
    g2 = np.where(flip, 1023 - t2, t2)
    assert np.unique(g1 * 1024 + g2).size < t1.size


def test_depth_code_cells():
    k = np.arange(1023)
    centres = (k + 0.5) / 511.5 - 1
    np.testing.assert_array_equal(pk.depth_code(centres), k)
    lower_edges = k / 511.5 - 1
    np.testing.assert_array_equal(pk.depth_code(lower_edges + 1e-12), k)
    assert pk.depth_code(1.0) == 1022 and pk.depth_code(-1.0) == 0


def test_pack32_every_depth_pair_round_trips():
    """Every pair of depth cells: decoded at the upper end of the cell, exactly (t + 1)/511.5 − 1."""
    t1, t2 = all_pairs()
    y1 = (t1 + 0.5) / 511.5 - 1
    y2 = (t2 + 0.5) / 511.5 - 1
    r = np.stack([y1, y2, np.full_like(y1, 0.3), np.full_like(y1, 1e-5)], -1)
    d = pk.unpack32(pk.pack32(r))
    np.testing.assert_array_equal(d[:, 0], (t1 + 1) / 511.5 - 1)
    np.testing.assert_array_equal(d[:, 1], (t2 + 1) / 511.5 - 1)
    assert np.all(d[:, 0] <= d[:, 1])


def test_pack32_bit_layout():
    """Reassemble a texel by hand from the layout in docs/formats.md."""
    y1 = (3 + 0.5) / 511.5 - 1  # ỹ1 = 3 (not folded)
    y2 = (700 + 0.5) / 511.5 - 1  # ỹ2 = 700
    v2 = ((5 + 0.5) / 128) ** 2  # √v2 in cell 5 (of width 1/128)
    xi4 = nl.psi4_inverse((9 + 0.5) / 64)  # Ψ4 in cell 9 (of width 1/64)
    p = pk.pack32([y1, y2, v2, xi4])
    assert p.dtype == np.uint32
    assert int(p) == 700 | (3 << 10) | (5 << 19) | (9 << 26)
    # Folded: ỹ1 = 600, ỹ2 = 900 -> 1023 − 600 = 423, 1022 − 900 = 122.
    y1, y2 = (600.5 / 511.5 - 1), (900.5 / 511.5 - 1)
    assert int(pk.pack32([y1, y2, 0.0, 0.0])) == 122 | (423 << 10)
    # The worked example of docs/formats.md, and its decode.
    p = pk.pack32([y1, y2, (5.5 / 128) ** 2, nl.psi4_inverse(9.5 / 64)])
    assert int(p) == 0x242E_9C7A
    d = pk.unpack32(p)
    np.testing.assert_allclose(d[:3], [601 / 511.5 - 1, 901 / 511.5 - 1, (5.5 / 128) ** 2], rtol=0, atol=1e-15)
    np.testing.assert_allclose(d[3], nl.psi4_inverse(10 / 64), rtol=1e-14)
    # Cell ends: √v2 = 1 and Ψ4 = 1 join the top cells 127 and 63.
    assert int(pk.pack32([0.0, 0.0, 1.0, 0.25])) >> 19 == 127 | (63 << 7)


def test_pack64_layout():
    q = pk.pack64([-1.0, 1.0, 0.5, 1.2e-7])
    assert q.dtype == np.uint16
    np.testing.assert_array_equal(q, [0, 65535, 32768, 0])


# ---------------------------------------------------------------------------
# Round trips


@given(r=representations())
def test_round_trip_64_within_one_step(r):
    d = pk.unpack64(pk.pack64(r))
    assert np.all(np.abs(d[:2] - r[:2]) <= 1 / 65535 + 1e-15)  # half a step of 2/65535
    assert abs(d[2] - r[2]) <= 0.5 / 65535 + 1e-15
    du = nl.psi4(d[3]) - nl.psi4(r[3])
    assert -1e-12 <= du <= 1 / 65535 + 1e-12
    assert d[3] >= min(max(r[3], 1.2e-7), 0.25)  # never below the stored ξ4
    assert d[0] <= d[1]


@given(r=representations())
def test_round_trip_64_nearest_xi_within_half_a_step(r):
    q = pk.pack64(r, xi_rounding="nearest")
    np.testing.assert_array_equal(q[:3], pk.pack64(r)[:3])
    du = nl.psi4(pk.unpack64(q)[3]) - nl.psi4(r[3])
    assert abs(du) <= 0.5 / 65535 + 1e-12


@given(r=representations())
def test_round_trip_32_within_one_cell(r):
    d = pk.unpack32(pk.pack32(r))
    y = np.clip(r[:2], -1, 1)
    y[1] = max(y[1], y[0])
    assert np.all(d[:2] >= y - 1e-15) and np.all(d[:2] - y <= 1 / 511.5 + 1e-15)  # upper end: never in front
    assert abs(np.sqrt(d[2]) - np.sqrt(np.clip(r[2], 0, 1))) <= 0.5 / 128 + 1e-12  # centre of a 1/128 cell
    assert (0.5 / 128) ** 2 <= d[2] <= (127.5 / 128) ** 2  # never 0 or 1
    du = nl.psi4(d[3]) - nl.psi4(r[3])
    assert -1e-12 <= du <= 1 / 64 + 1e-12
    assert d[3] >= min(max(r[3], 1.2e-7), 0.25)
    assert d[0] <= d[1]


def test_every_32_bit_field_decodes_inside_its_cell():
    """All √v2 and Ψ4 codes and all depth codes: decoded at the stated position of the cell."""
    c = np.arange(128, dtype=np.uint32)
    d = pk.unpack32((c << pk.V_SHIFT) | (700 << pk.Y2_SHIFT))
    np.testing.assert_array_equal(d[:, 2], ((c + 0.5) / 128) ** 2)
    c = np.arange(64, dtype=np.uint32)
    d = pk.unpack32((c << pk.XI_SHIFT) | (700 << pk.Y2_SHIFT))
    np.testing.assert_allclose(nl.psi4(d[:, 3]), (c + 1) / 64, rtol=0, atol=1e-13)
    for pos, off in (("lower", 0.0), ("centre", 0.5), ("upper", 1.0)):
        t = np.arange(512, dtype=np.uint32)  # unfolded pairs (t, t)
        d = pk.unpack32((t << pk.Y1_SHIFT) | (t << pk.Y2_SHIFT), depth_decode=pos)
        np.testing.assert_array_equal(d[:, 0], (t + off) / 511.5 - 1)
        d = pk.unpack32(c << pk.V_SHIFT, v2_decode=pos)
        np.testing.assert_array_equal(d[:64, 2], ((c + off) / 128) ** 2)
        d = pk.unpack32(c << pk.XI_SHIFT, xi_decode=pos)
        np.testing.assert_allclose(nl.psi4(d[:, 3]), np.maximum((c + off) / 64, 0), rtol=0, atol=1e-13)
    assert pk.DECODE32 == {"depth": "upper", "v2": "centre", "xi": "upper"}


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_decoded_xi4_never_below_stored_exhaustive_32(dtype):
    """All 64 codes: ξ4 at both ends of each code's cell and dense inside."""
    c = np.arange(65)
    edges = nl.psi4_inverse(c / 64)  # cell boundaries
    xs = [edges, np.nextafter(edges, 0), np.nextafter(edges, 1)]
    xs.append(np.geomspace(1.2e-7, 0.25, 200001))
    xs.append(np.linspace(0, 0.25, 100001))
    xi = np.clip(np.concatenate(xs), 0, 0.25).astype(dtype)
    r = np.zeros((xi.size, 4), dtype)
    r[:, 1] = 0.5
    r[:, 2] = 0.5
    r[:, 3] = xi
    p = pk.pack32(r)
    d = pk.unpack32(p, dtype=dtype)[:, 3]
    assert np.all(d >= np.maximum(xi, dtype(1.2e-7)))
    codes = (p.astype(np.int64) >> 26) & 63
    assert set(np.unique(codes)) == set(range(64))  # every code exercised
    # ... and not needlessly high: at most one code above truncation.
    floor = np.minimum(np.floor(nl.psi4(xi.astype(np.float64)) * 64), 63)
    assert np.all(codes - floor <= 1) and np.mean(codes == floor) > 0.999


def test_decoded_xi4_never_below_stored_64():
    xi = np.concatenate([np.geomspace(1.2e-7, 0.25, 300001), np.linspace(0, 0.25, 100001)])
    r = np.zeros((xi.size, 4))
    r[:, 1] = 0.5
    r[:, 3] = xi
    d = pk.unpack64(pk.pack64(r))[:, 3]
    assert np.all(d >= np.maximum(xi, 1.2e-7))
    # Rounding to nearest (the HPG17 demo's UNORM write) goes below: the guarantee needs "up".
    d = pk.unpack64(pk.pack64(r, xi_rounding="nearest"))[:, 3]
    assert np.mean(d < np.maximum(xi, 1.2e-7)) > 0.3


def test_round_up_mutant_nearest_decoding_fails():
    """Power check: reading a 6-bit Ψ4 cell anywhere but at its upper end goes below ξ4."""
    xi = np.geomspace(1.2e-7, 0.25, 10001)
    codes = np.minimum(np.floor(nl.psi4(xi) * 64), 63)
    for off in (0, 0.5):
        assert np.any(nl.psi4_inverse((codes + off) / 64) < xi)
    p = pk.pack32(np.stack([np.zeros_like(xi), np.full_like(xi, 0.5), np.full_like(xi, 0.5), xi], -1))
    assert np.any(pk.unpack32(p, xi_decode="centre")[:, 3] < xi)


@pytest.mark.parametrize("pack,unpack", [(pk.pack64, pk.unpack64), (pk.pack32, pk.unpack32)])
def test_float32_decoding_matches_float64(pack, unpack):
    rng = np.random.default_rng(1)
    y = np.sort(rng.uniform(-1, 1, (1000, 2)), axis=1)
    r = np.column_stack([y, rng.uniform(0, 1, 1000), 10 ** rng.uniform(-8, np.log10(0.25), 1000)])
    q = pack(r)
    d64 = unpack(q)
    d32 = unpack(q, dtype=np.float32)
    assert d32.dtype == np.float32
    np.testing.assert_allclose(d32, d64, rtol=1e-5, atol=1e-7)


# ---------------------------------------------------------------------------
# Lower bound after quantization


def _exact_z(z, w, zf):
    return (w[None, :] * (z[None, :] < zf[:, None])).sum(-1)


# Biasing and Algorithm 3's clamps raise the bound by up to ~1e-6 over Z (measured).
BIAS_SLACK = 2e-6


@given(dist=depth_distributions())
def test_shading_64_bit_texel_stays_a_lower_bound(dist):
    """shade(unpack64(pack64(Φ(b)))) ≤ Z(z < zf + 1/65535) + 0.5/65535 + 2e-6 while 0 < v2 code < 65535.

    The depth shift is the 64-bit depth error (half a step), the additive term the
    v2 error (half a step); ξ4 is rounded up so it costs nothing. v2 codes 0 and 65535
    are a limitation of the format (test below, docs/formats.md).
    """
    z, w = dist
    r = nl.phi(bias_moments(power_moments(z, w), BIAS_FLOAT32))
    q = pk.pack64(r)
    if q[2] in (0, 65535):
        return
    zf = np.concatenate([np.linspace(-1.01, 1.01, 203), z, z + 1e-9, z - 1e-9])
    low = nl.shade(pk.unpack64(pk.pack64(r, xi_rounding="up")), zf)  # the guarantee is the rounding up's (below)
    assert np.all(low <= _exact_z(z, w, zf + pk.DEPTH_STEP64 / 2) + 0.5 / 65535 + BIAS_SLACK)


def test_64_bit_xi4_rounded_to_nearest_is_not_the_guarantee():
    """Found by the thorough profile: Ψ4 rounded to nearest (the demo's, a legitimate variant) stores ξ4 one code
    lower than rounding up on this texel, and the bound at zf = 0 (between the depths −1 and 6.1e-5) rises 1.3e-5
    over Z + the 64-bit terms, by as much as the exact bound of the decoded texel (mpmath) does; rounding up stays
    under them (HPG17 §3.5: "rounded up to guarantee a lower bound")."""
    z = np.array([-1.0] * 5 + [6.10351562e-05, -1.0, 1.0])
    w = np.array([0.15726568, 0.15726568, 0.15726568, 0.07863284, 0.07003238, 0.15726568, 0.10432278, 0.11794926])
    w = w / w.sum()
    r = nl.phi(bias_moments(power_moments(z, w), BIAS_FLOAT32))
    zf = np.array([0.0])
    limit = _exact_z(z, w, zf + pk.DEPTH_STEP64 / 2) + 0.5 / 65535 + BIAS_SLACK
    up, near = (pk.unpack64(pk.pack64(r, xi_rounding=x)) for x in ("up", "nearest"))
    assert pk.pack64(r, xi_rounding="nearest")[3] == pk.pack64(r, xi_rounding="up")[3] - 1
    assert nl.shade(up, zf)[0] <= limit[0] < nl.shade(near, zf)[0]
    assert precise.shade(near, zf[0]) > limit[0] + 1e-5


def test_64_bit_v2_rounded_to_0_over_shadows():
    """Limitation of HPG17 §3.3's 64-bit format (and the HPG17 demo's): v2 < 0.5/65535 is stored as 0.

    A 5-depth cluster at −0.35 whose Φ puts v2 = 7.2e-6 on the far depth: the decoded v2 = 0
    (clamped to 1e-6 by Algorithm 3) over-shadows a fragment 1.5e-5 behind the cluster's front
    by 0.15 over Z; the v2 code 1 instead would not (docs/formats.md).
    """
    z = np.array([-0.34983, -0.35101, -0.35002, -0.34975, -0.35094])
    w = np.array([0.1219, 0.333, 0.0798, 0.3436, 0.1217])
    w = w / w.sum()
    r = nl.phi(bias_moments(power_moments(z, w), BIAS_FLOAT32))
    q = pk.pack64(r)
    assert 0 < r[2] < 0.5 / 65535 and q[2] == 0
    zf = np.array([-0.34983])
    bound = _exact_z(z, w, zf + pk.DEPTH_STEP64 / 2)
    assert nl.shade(pk.unpack64(q), zf) - bound > 0.1
    q[2] = 1
    assert nl.shade(pk.unpack64(q), zf) - bound < 0.05


@given(dist=depth_distributions())
def test_shading_32_bit_texel_stays_a_lower_bound_with_exact_v2(dist):
    """With v2 kept exact: shade ≤ Z(z < zf + 1/1023) + 2e-6 (measured 0 beyond the bias slack)."""
    z, w = dist
    r = nl.phi(bias_moments(power_moments(z, w), BIAS_FLOAT32))
    d = pk.unpack32(pk.pack32(r))
    d[2] = np.clip(r[2], 0, 1)
    zf = np.concatenate([np.linspace(-1.01, 1.01, 203), z, z + 1e-9, z - 1e-9])
    low = nl.shade(d, zf)
    assert np.all(low <= _exact_z(z, w, zf + pk.DEPTH_STEP32 / 2) + BIAS_SLACK)


#: The largest error of √v2 read at the centre of a 1/128 cell, in v2: 1 − (127.5/128)².
V2_SLACK32 = 1 - (127.5 / 128) ** 2


@given(dist=depth_distributions())
def test_shading_32_bit_texel_full_decode(dist):
    """All fields decoded, every v2: shade ≤ Z(z < zf + 1/1023) + 1 − (127.5/128)² + 2e-6.

    √v2 read at the centre of its cell keeps v2 off 0 and 1 ((0.5/128)² ≤ v2 ≤ (127.5/128)²);
    the grid that reached v2 = 1 dropped a depth and over-shadowed by up to 0.77 here.
    """
    z, w = dist
    r = nl.phi(bias_moments(power_moments(z, w), BIAS_FLOAT32))
    d = pk.unpack32(pk.pack32(r))
    zf = np.concatenate([np.linspace(-1.01, 1.01, 203), z, z + 1e-9, z - 1e-9])
    low = nl.shade(d, zf)
    assert np.all(low <= _exact_z(z, w, zf + pk.DEPTH_STEP32 / 2) + V2_SLACK32 + BIAS_SLACK)


def test_32_bit_v2_near_one_keeps_the_far_depth():
    """The old grid's limitation is gone: v2 = 0.995 decodes to (127.5/128)², not 1.

    With v2 = 1 (√v2 rounded to the grid point 127/127) this distribution's bound
    exceeded Z by 0.47; read at the cell centre it stays within the v2 slack.
    """
    z = np.array([0.6186, 0.632, 0.6277])
    w = np.array([0.027, 0.467, 0.506])
    r = nl.phi(bias_moments(power_moments(z, w), BIAS_FLOAT32))
    d = pk.unpack32(pk.pack32(r))
    assert r[2] < 1 and d[2] == (127.5 / 128) ** 2
    zf = np.concatenate([np.linspace(0.6, 0.65, 501), z, z - 1e-9])
    bound = _exact_z(z, w, zf + pk.DEPTH_STEP32 / 2)
    assert np.all(nl.shade(d, zf) <= bound + V2_SLACK32 + BIAS_SLACK)
    old = d.copy()
    old[2] = 1.0  # the old grid's decode
    assert np.max(nl.shade(old, zf) - bound) > 0.4


def test_upper_depth_decode_keeps_an_occluder_behind_its_surface():
    """The decoder choice, measured: one depth at 1 (e2e-nlq32's worst row) shaded at zf = 1.

    Read at the cell centre the depth moves 9.8e-4 towards the light and the receiver
    shadows itself (0.92 over the unquantized bound); read at the upper end it does not.
    """
    r = nl.phi(bias_moments(power_moments(np.array([1.0])), BIAS_FLOAT32))
    unq = nl.shade(r, np.array([1.0]))[0]
    p = pk.pack32(r)
    upper = nl.shade(pk.unpack32(p), np.array([1.0]))[0]
    centre = nl.shade(pk.unpack32(p, depth_decode="centre"), np.array([1.0]))[0]
    assert upper - unq < 0.01 and centre - unq > 0.9


# ---------------------------------------------------------------------------
# Bad input


def test_bad_input():
    with pytest.raises(InputError, match="dtype uint16"):
        pk.unpack64(np.zeros(4, dtype=np.int32))
    with pytest.raises(InputError, match="dtype uint32"):
        pk.unpack32(np.zeros(3, dtype=np.float64))
    with pytest.raises(InputError, match="trailing axis of length 4"):
        pk.unpack64(np.zeros(3, dtype=np.uint16))
    with pytest.raises(InputError, match="float32 or float64"):
        pk.unpack32(np.zeros(3, dtype=np.uint32), dtype=np.int16)
    with pytest.raises(InputError, match="y1 <= y2"):
        pk.pack64([0.5, -0.5, 0.5, 0.0])
    with pytest.raises(InputError, match="finite"):
        pk.pack32([np.nan, 0.5, 0.5, 0.0])
    # Outside the stored ranges: saturated, as a UNORM texture write does.
    assert pk.pack32([-1.5, 0.5, 0.5, 0.0]) == pk.pack32([-1.0, 0.5, 0.5, 0.0])
    np.testing.assert_array_equal(pk.unpack64(pk.pack64([-0.5, 0.5, 1.5, -0.1])),
                                  pk.unpack64(pk.pack64([-0.5, 0.5, 1.0, 0.0])))
    # float32 Algorithm 2 on mass near -1 (seen on a 2048² railing map) gives y1 < -1.
    np.testing.assert_array_equal(pk.pack64(np.float32([-1.0026203, -0.9, 0.5, 1e-6])),
                                  pk.pack64(np.float32([-1.0, -0.9, 0.5, 1e-6])))
    # Rounding noise is accepted and clamped.
    eps = np.finfo(np.float64).eps
    q = pk.pack64([-1 - 2 * eps, 1 + 2 * eps, 1 + 2 * eps, -eps])
    np.testing.assert_array_equal(q, [0, 65535, 65535, 0])


def test_shapes_and_dtypes():
    r = np.zeros((2, 3, 4))
    r[..., 1] = 0.5
    assert pk.pack64(r).shape == (2, 3, 4)
    assert pk.pack32(r).shape == (2, 3)
    assert pk.unpack32(pk.pack32(r)).shape == (2, 3, 4)
    assert pk.unpack64(pk.pack64(r.astype(np.float32)), dtype=np.float32).dtype == np.float32


def test_depth_steps_by_value():
    """DEPTH_STEP32 is the 32-bit cell width 1/511.5 (used as slack elsewhere; a wrong value weakens them)."""
    assert pk.DEPTH_STEP32 == 1 / 511.5 and pk.DEPTH_STEP64 == 2 / 65535
    # Every depth decodes at most one cell behind itself, never in front.
    y = np.linspace(-1, 1, 20001)
    r = np.stack([y, y, np.full_like(y, 0.5), np.full_like(y, 1e-3)], axis=-1)
    d = pk.unpack32(pk.pack32(r))[:, 0]
    assert (d - y).min() >= -1e-15 and (d - y).max() <= pk.DEPTH_STEP32 + 1e-12
    assert (d - y).max() > 0.99 * pk.DEPTH_STEP32
    d64 = pk.unpack64(pk.pack64(r))[:, 0]
    assert np.abs(d64 - y).max() <= pk.DEPTH_STEP64 / 2 + 1e-12


# ---------------------------------------------------------------------------
# bias, Φ and pack in one pass (packing.nlq_texels) against the three calls


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
@pytest.mark.parametrize("fmt", ["nlq64", "nlq32"])
def test_nlq_texels_is_bias_phi_pack(dtype, fmt):
    rng = np.random.default_rng(7)
    parts = [power_moments(rng.uniform(-1, 1, (9000, k))) for k in (1, 2, 3, 4)]  # one depth: singular rows
    parts.append(power_moments(np.clip(rng.uniform(-1, 1, (3000, 1)) + rng.normal(0, 1e-6, (3000, 4)), -1, 1)))
    b = np.concatenate(parts).astype(dtype)  # 39000 texels: several chunks and a short last one
    r = nl.phi(bias_moments(b, BIAS_FLOAT32))
    want = pk.pack64(r) if fmt == "nlq64" else pk.pack32(r)
    got = pk.nlq_texels(b, fmt)
    assert got.dtype == want.dtype and np.array_equal(got, want)
    assert np.array_equal(pk.nlq_texels(b.reshape(3, -1, 4), fmt), want.reshape((3, -1, 4)[: want.ndim + 1]))


def test_nlq_texels_raises_the_errors_of_its_steps():
    b = np.zeros((20000, 4), np.float32)
    b[12345, 2] = np.nan
    with pytest.raises(InputError) as want:
        bias_moments(b, BIAS_FLOAT32)
    with pytest.raises(InputError) as got:
        pk.nlq_texels(b)
    assert str(got.value) == str(want.value)


@pytest.mark.parametrize("fmt", ["nlq64", "nlq32"])
def test_nlq_texels_out_is_written_in_place(fmt):
    # out= (a band of a larger texture, as the global path writes it): the same texels as the
    # three calls, in the caller's array, also where the chunk loop hands over to the three
    # steps (a texel Φ refuses: y1 > y2 is impossible here, so an infinite moment's error).
    rng = np.random.default_rng(11)
    b = power_moments(rng.uniform(-1, 1, (40000, 3))).astype(np.float32).reshape(200, 200, 4)
    r = nl.phi(bias_moments(b, BIAS_FLOAT32))
    want = pk.pack64(r) if fmt == "nlq64" else pk.pack32(r)
    big = np.zeros((3,) + want.shape, want.dtype)
    got = pk.nlq_texels(b, fmt, out=big[1])
    assert got is big[1] or np.shares_memory(got, big)
    assert np.array_equal(big[1], want) and not big[0].any() and not big[2].any()
    for bad in (np.zeros(want.shape, np.float32), np.zeros(want.shape[:-1] if fmt == "nlq64" else want.shape + (4,),
                                                            want.dtype), big[1][:, ::-1]):
        with pytest.raises(InputError, match="out: expected a C-contiguous"):
            pk.nlq_texels(b, fmt, out=bad)
    b2 = b.copy()
    b2[150, 7, 1] = np.inf
    with pytest.raises(InputError, match=r"^b: expected finite values, got .*inf\)? at index \(150, 7, 1\)$"):
        pk.nlq_texels(b2, fmt, out=np.empty_like(want))


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
@pytest.mark.parametrize("fmt", ["nlq64", "nlq32"])
def test_nlq_texels_planar_reads_four_planes(dtype, fmt):
    # planar=True (the global path's bands, b1..b4 as contiguous planes): the texels of the
    # three calls on the interleaved moments, over several chunks and a short last one, from
    # contiguous and strided planes; the error path (a non-finite moment) names the texel and
    # moment as the interleaved layout does; planes not on the first axis are refused.
    rng = np.random.default_rng(13)
    parts = [power_moments(rng.uniform(-1, 1, (12000, k))) for k in (1, 2, 4)]
    b = np.concatenate(parts).astype(dtype).reshape(2, -1, 4)  # 36000 texels
    r = nl.phi(bias_moments(b, BIAS_FLOAT32))
    want = pk.pack64(r) if fmt == "nlq64" else pk.pack32(r)
    planes = np.ascontiguousarray(np.moveaxis(b, -1, 0))
    assert np.array_equal(pk.nlq_texels(planes, fmt, planar=True), want)
    got = np.zeros_like(want)
    assert pk.nlq_texels(planes, fmt, out=got, planar=True) is got and np.array_equal(got, want)
    assert np.array_equal(pk.nlq_texels(np.moveaxis(b, -1, 0), fmt, planar=True), want)  # strided planes
    bad = planes.copy()
    bad[2, 1, 77] = np.nan
    with pytest.raises(InputError, match=r"at index \(1, 77, 2\)$"):
        pk.nlq_texels(bad, fmt, planar=True)
    for shape in [(3, 10), (10, 4), ()]:
        with pytest.raises(InputError, match="b: expected four planes"):
            pk.nlq_texels(np.zeros(shape, dtype), fmt, planar=True)


def test_nlq32_depth_codes_keep_the_constant_bias():
    """HPG17 §3.5's 10-bit depths, read at the upper end of their cell, never eat the 1e-3 bias (§5).

    A lit plane's narrow footprint (depths z0 ± 2e-4) shaded 3e-4 behind its texel's depth,
    as a sloped receiver or a neighbour texel gives: with the depths read at the cell
    centre (up to 9.8e-4 towards the light, leaving 2e-5 of the bias) NLQ32 over-shadowed
    a tenth of the depths, the speckles of railing's --full run; read at the upper end it
    over-shadows none, like NLQ64 (paper_claims.NLQ32_DECODE_NOTE).
    """
    from moments_ref.moments import BIAS_FLOAT32, bias_moments, power_moments
    from moments_ref.nonlinear import phi, shade

    z0 = np.linspace(-0.99, 0.99, 4001)
    z = z0[:, None] + np.linspace(-2e-4, 2e-4, 9)[None, :]
    r = phi(bias_moments(power_moments(z, np.full(z.shape, 1 / 9)).astype(np.float32), BIAS_FLOAT32))
    p = pk.pack32(r)
    y32 = pk.unpack32(p, dtype=np.float32)
    centre = pk.unpack32(p, dtype=np.float32, depth_decode="centre")
    d = y32[:, :2] - r[:, :2]
    assert d.min() >= -1e-6 and d.max() <= 1 / 511.5 + 1e-6
    for behind in (0.0, 3e-4):
        zf = (z0 + behind - 1e-3).astype(np.float32)
        over64 = np.mean(shade(pk.unpack64(pk.pack64(r), dtype=np.float32), zf) > 0.05)
        assert np.mean(shade(y32, zf) > 0.05) == 0 and over64 == 0, behind
    zf = (z0 + 3e-4 - 1e-3).astype(np.float32)
    assert 0.05 <= np.mean(shade(centre, zf) > 0.05) <= 0.2  # the decode this replaced


def test_keyword_choices():
    p = pk.pack32([[-0.5, 0.5, 0.25, 1e-4]])
    for name in ("depth_decode", "v2_decode", "xi_decode"):
        with pytest.raises(InputError, match=name):
            pk.unpack32(p, **{name: "middle"})
    with pytest.raises(InputError, match="xi_rounding"):
        pk.pack64([-0.5, 0.5, 0.25, 1e-4], xi_rounding="down")
    with pytest.raises(InputError, match="xi_rounding"):
        pk.nlq_texels(np.zeros((2, 4)), "nlq64", xi_rounding=None)
    b = power_moments(np.random.default_rng(3).uniform(-1, 1, (500, 3)))
    want = pk.pack64(nl.phi(bias_moments(b, BIAS_FLOAT32)), xi_rounding="nearest")
    assert np.array_equal(pk.nlq_texels(b, "nlq64", xi_rounding="nearest"), want)
    assert not np.array_equal(want, pk.nlq_texels(b, "nlq64"))


# ---------------------------------------------------------------------------
# The chunked encoders store exactly saturate(r)


def _needs_clamping(n, dtype, seed):
    """Rows out of the stored ranges, with y1 one ulp above y2 (rounding noise the encoders accept)."""
    rng = np.random.default_rng(seed)
    y = np.sort(rng.uniform(-1.3, 1.3, (n, 2)), axis=1).astype(dtype)
    r = np.stack([y[:, 0], y[:, 1], rng.uniform(-0.2, 1.2, n).astype(dtype),
                  rng.uniform(-0.1, 2.0, n).astype(dtype)], axis=-1)
    above = rng.random(n) < 0.4
    r[above, 0] = np.nextafter(r[above, 1], dtype(np.inf))  # y1 = y2 + 1 ulp, also beyond ±1
    r[::5, 1] = np.maximum(r[::5, 1], dtype(1.05))
    r[::5, 0] = np.nextafter(r[::5, 1], dtype(np.inf))
    return r


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
@pytest.mark.parametrize("chunk", [7, 8192])
def test_the_chunked_encoders_store_saturate_of_r(dtype, chunk, monkeypatch):
    # Every chunk (whole, and the short last one) holds saturate(r) exactly: y1, y2 in
    # [-1, 1] with y2 >= y1, v2 in [0, 1], xi4 >= 0; and the codes are those of saturate(r).
    r = _needs_clamping(20000 + 3, dtype, 11)
    pk._bounds.cache_clear()
    monkeypatch.setattr(pk, "_ENCODE_CHUNK", chunk)
    try:
        got = np.concatenate([rows for _, _, rows, _ in pk._encoder_rows(r)], axis=1).T
        want = pk.saturate(r)
        np.testing.assert_array_equal(got, want)
        assert np.all(want[:, 1] >= want[:, 0]) and np.all(np.abs(want[:, :2]) <= 1)
        assert np.all((want[:, 2] >= 0) & (want[:, 2] <= 1)) and np.all(want[:, 3] >= 0)
        np.testing.assert_array_equal(pk.pack64(r), pk.pack64(want))
        np.testing.assert_array_equal(pk.pack32(r), pk.pack32(want))
        np.testing.assert_array_equal(pk.pack64(r[:5]), pk.pack64(want[:5]))
    finally:
        pk._bounds.cache_clear()


def test_saturate_is_the_unorm_write():
    r = np.array([[-1.5, 1.5, -0.25, -1.0], [0.25, 0.25 - 1e-17, 1.25, 3.0], [1.2, 1.2, 0.5, 0.0]])
    np.testing.assert_array_equal(pk.saturate(r), [[-1.0, 1.0, 0.0, 0.0], [0.25, 0.25, 1.0, 3.0],
                                                   [1.0, 1.0, 0.5, 0.0]])
    y2 = 0.5
    r = np.array([[np.nextafter(y2, 1.0), y2, 0.5, 0.1]])  # y1 one ulp above y2: y2 raised to y1
    np.testing.assert_array_equal(pk.saturate(r)[0, :2], [r[0, 0], r[0, 0]])


def test_saturate_accepts_y1_up_to_the_rounding_tolerance_above_y2_and_copies():
    from moments_ref.nonlinear import rounding_tolerance

    for dt in (np.float32, np.float64):
        tol = dt(rounding_tolerance(dt))
        r = np.array([[tol, 0.0, 0.5, 0.1], [-0.5, 0.5, 1.5, 0.1]], dt)  # y1 = y2 + tol: still rounding
        before = r.copy()
        out = pk.saturate(r)
        np.testing.assert_array_equal(out[:, :3], [[tol, tol, 0.5], [-0.5, 0.5, 1.0]])
        np.testing.assert_array_equal(r, before)  # a copy: the caller's array is untouched
        r[1, 0] = np.nextafter(r[1, 1] + tol, dt(1))  # beyond the tolerance in one row of two
        with pytest.raises(InputError, match=r"y1 <= y2 .* at index \(1,\)"):
            pk.saturate(r)


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_the_cached_tables_of_the_encoders_and_decoders_are_read_only(dtype):
    """They are shared by every later call (lru_cache): a write would change all later texels."""
    tables = list(pk._bounds(dtype).values()) + [pk._decoded_xi64(dtype), pk._decoded_xi32(dtype)]
    for t in tables:
        with pytest.raises(ValueError, match="read-only"):
            t[0] = 0


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_the_encoders_check_chunks_as_saturate_does(dtype):
    from moments_ref.nonlinear import rounding_tolerance

    tol = dtype(rounding_tolerance(dtype))
    r = np.tile(np.array([[-0.5, 0.5, 0.5, 0.1]], dtype), (5, 1))
    r[2, :2] = [tol, 0.0]  # y1 = y2 + tol: rounding, accepted; y2 raised to y1
    r[0, :3] = [-1.5, 1.25, 1.5]  # in the same chunk, a row that needs clamping
    np.testing.assert_array_equal(pk.pack64(r), pk.pack64(pk.saturate(r)))
    np.testing.assert_array_equal(pk.pack32(r), pk.pack32(pk.saturate(r)))
    r[3, 0] = np.nextafter(r[3, 1] + tol, dtype(1))  # one row of five beyond it
    for pack in (pk.pack64, pk.pack32):
        with pytest.raises(InputError, match=r"y1 <= y2 .* at index \(3,\)"):
            pack(r)


def test_huge_finite_xi4_is_encoded_at_the_top_code():
    # the chunk's finiteness check sums the rows: a finite sum proves them finite, an overflowing one
    # must not refuse finite rows
    r = np.array([[-1.5, 0.5, 0.5, 1e308], [-0.5, 0.5, 0.5, 1e308], [0.0, 0.0, 0.5, 0.25]])
    with np.errstate(over="ignore"):  # the sum's overflow warns (harmless)
        q, p, want = pk.pack64(r), pk.pack32(r), pk.pack64(pk.saturate(r))
    assert q[:, 3].tolist() == [65535] * 3 and q[0, 0] == 0  # y1 = -1.5 clamped to -1 as well
    assert (p >> pk.XI_SHIFT).tolist() == [63] * 3
    np.testing.assert_array_equal(q, want)


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_xi4_at_and_beyond_the_clamp_gets_the_top_code(dtype):
    r = np.array([[0, 0, 0.5, 0.25], [0, 0, 0.5, 1.0], [0, 0, 0.5, nl.PSI4_XI_MAX]], dtype)
    for rounding in ("up", "nearest"):
        assert pk.pack64(r, xi_rounding=rounding)[:, 3].tolist() == [65535] * 3
    assert (pk.pack32(r) >> pk.XI_SHIFT).tolist() == [63] * 3


def test_decoders_take_unsigned_words_of_their_width_only():
    for bad in (np.zeros((1, 4), np.uint32), np.zeros((1, 4), np.int16), np.zeros((1, 4), np.uint8)):
        with pytest.raises(InputError, match="dtype uint16"):
            pk.unpack64(bad)
    for bad in (np.zeros(2, np.uint16), np.zeros(2, np.int32), np.zeros(2, np.uint64)):
        with pytest.raises(InputError, match="dtype uint32"):
            pk.unpack32(bad)


def test_fold_refuses_codes_outside_its_range_in_any_element():
    for t1, t2, name in (([0, -1], [5, 5], "t1"), ([0, 5], [5, 1023], "t2"), ([0, 1023], [5, 1023], "t1"),
                         ([0, 7], [5, 6], "t2")):  # the first argument found wrong is named
        with pytest.raises(InputError, match=f"^{name}:"):
            pk.fold(np.array(t1), np.array(t2))
    for f1, f2 in (([0, 512], [5, 5]), ([0, 5], [5, 1024]), ([-1, 5], [5, 5])):
        with pytest.raises(InputError, match="f[12]"):
            pk.unfold(np.array(f1), np.array(f2))
    assert [x.tolist() for x in pk.unfold(np.array([511, 0]), np.array([1023, 0]))] == [[511, 0], [1023, 0]]
    f1, f2 = pk.fold(np.array([0, 1022]), np.array([1022, 1022]))  # the top code is allowed
    assert f1.tolist() == [0, 1] and f2.tolist() == [1022, 0]


@pytest.mark.parametrize("dt", [np.float32, np.float64])
def test_largest_xi_code_decodes_at_or_above_the_clamp(dt):
    # packing._xi_codes drops "code < largest" from its bump test because the largest code of
    # each format decodes to Ψ4⁻¹(1) ≥ XI_MAX ≥ any clamped ξ4 (so "decodes below ξ4" is false
    # there). Decoded through the public decoders, not the tables the encoder uses.
    from moments_ref.nonlinear import PSI4_XI_MAX

    top64 = pk.unpack64(np.array([0, 0, 0, 65535], np.uint16), dtype=dt)[3]
    top32 = pk.unpack32(np.array([np.uint32(0xFFFFFFFF)]), dtype=dt)[0, 3]
    assert top64 >= dt(PSI4_XI_MAX) and top32 >= dt(PSI4_XI_MAX)
