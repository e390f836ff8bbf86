"""golden.bilinear's rows against what their comments, categories and the module's docstring state.

Read back from the rows themselves: a stiff row's comment names its edge (which texels of the
2×2 see the occluder) and the occluder's and receiver's depths (to 3 decimals); its texels must be
the moments of depths within 0.01 of those, the receiver zf at the stated offsets from the
receiver; an edge row's comment names its fraction; the flags follow from the fractions and the
categories; fractions are multiples of 2^-16 in [0, 1) (exact texture coordinates).
"""

from __future__ import annotations

import re

import numpy as np
import pytest

from moments_ref.golden import bilinear

#: which texels (t00, t10, t01, t11: i right, j down) see the occluder, from each edge's name
OCCLUDED = {"vertical edge (left column occluded)": (True, False, True, False),
            "horizontal edge (top row occluded)": (True, True, False, False),
            "corner (one texel occluded)": (True, False, False, False),
            "corner (three texels occluded)": (True, True, True, False)}
EDGE_FRACTIONS = (0.0, 0.5, 1 - 2.0**-16, 2.0**-16, 77 / 256, 77.5 / 256)


def fresh_rows():
    """The bilinear cases' rows and their inputs in float64."""
    r = bilinear._rows(np.random.default_rng(5), "float32")
    return r, {k: np.asarray(v, np.float64) for k, v in r.inputs.items()}


@pytest.fixture()
def rows():
    # per test (0.2 s), not per module: so that per-test coverage (tools.mutation) sees each test reach the rows
    return fresh_rows()


def test_the_rows_are_the_same_whatever_the_generator_and_in_three_categories(rows):
    r, a = rows
    again = bilinear._rows(np.random.default_rng(99), "float64")
    assert all(np.array_equal(a[k], again.inputs[k]) for k in a) and again.comment == r.comment
    assert list(r.category) == ["random"] * 128 + ["stiff"] * 128 + ["edge"] * 72
    assert a["texels"].shape == (328, 16) and a["fraction"].shape == (328, 2) and a["zf"].shape == (328,)
    # texels hold float32 moments
    assert np.array_equal(a["texels"], a["texels"].astype(np.float32))


def test_fractions_are_exact_and_span_the_texel_the_stiff_ones_half_near_the_middle(rows):
    _, a = rows
    f = a["fraction"]
    assert np.all((f >= 0) & (f < 1)) and np.all(f * 2**16 == np.round(f * 2**16))
    rnd, stiff = f[:128], f[128:256]
    assert rnd.min() < 0.02 and rnd.max() > 0.98
    # the first half of the stiff rows within 2048 · 2^-16 of the middle, both ways; the others anywhere
    k = (stiff - 0.5) * 2**16
    assert np.all((k[:64] >= -2048) & (k[:64] < 2048)) and k[:64].min() < -1800 and k[:64].max() > 1800
    assert np.sum(k[:64, 0] == k[:64, 1]) < 4  # the two coordinates drawn each on its own
    assert np.sum(np.all(np.abs(k[64:]) <= 2048, axis=1)) < 4 and stiff[64:].min() < 0.05 and stiff[64:].max() > 0.95


def test_edge_rows_are_every_pair_of_the_edge_fractions_on_a_random_and_a_stiff_neighbourhood(rows):
    r, a = rows
    f = a["fraction"][256:]
    pairs = {(x, y) for x in EDGE_FRACTIONS for y in EDGE_FRACTIONS}
    assert {tuple(p) for p in f[:36].tolist()} == pairs == {tuple(p) for p in f[36:].tolist()}
    for i in range(72):
        want = "random texels" if i < 36 else "shadow-edge texels"
        assert r.comment[256 + i] == f"{want}, fraction ({float(f[i, 0])!r}, {float(f[i, 1])!r})"
    assert np.all(a["texels"][256:292] == a["texels"][0]) and np.all(a["texels"][292:] == a["texels"][128])
    assert np.all(a["zf"][256:292] == 0.1) and np.all(a["zf"][292:] == a["zf"][128])


def test_flags_follow_from_the_category_and_the_fraction(rows):
    r, a = rows
    grid = np.all(a["fraction"] * 256 == np.round(a["fraction"] * 256), axis=1)
    edge = np.r_[np.zeros(128, bool), np.ones(128, bool), np.zeros(36, bool), np.ones(36, bool)]
    want = [(("shadow_edge",) if e else ()) + (("weight_grid",) if g else ()) for e, g in zip(edge, grid)]
    assert [tuple(x) for x in r.flags] == want
    assert grid[256:].sum() == 2 * 9 and grid[:256].sum() < 4  # 0, 0.5 and 77/256 on the 8-bit grid


def test_random_rows_are_moments_of_distributions_with_receivers_across_the_range(rows):
    r, a = rows
    t = a["texels"][:128].reshape(-1, 4)
    assert np.all(np.abs(t) <= 1) and np.all(t[:, 1] >= t[:, 0] ** 2 - 1e-6) and np.all(t[:, 3] >= t[:, 1] ** 2 - 1e-6)
    assert np.all(np.abs(a["zf"][:128]) <= 1) and a["zf"][:128].min() < -0.9 and a["zf"][:128].max() > 0.9
    assert set(r.comment[:128]) == {"four texels of 3 to 8 random depths each, unbiased float32 moments"}


def test_stiff_rows_are_the_shadow_edges_their_comments_name(rows):
    r, a = rows
    pat = re.compile(r"shadow edge, (.+): occluder near (-?[0-9.]+), receiver near (-?[0-9.]+)$")
    names, z_o, z_r = [], [], []
    for c in r.comment[128:256]:
        m = pat.match(c)
        assert m, c
        names.append(m.group(1))
        z_o.append(float(m.group(2)))
        z_r.append(float(m.group(3)))
    z_o, z_r = np.array(z_o), np.array(z_r)
    assert [names.count(n) for n in OCCLUDED] == [32] * 4 and names[:4] == list(OCCLUDED)
    assert np.all((z_o >= -0.9005) & (z_o <= -0.0995)) and z_o.min() < -0.85 and z_o.max() > -0.15
    assert np.all((z_r >= 0.1995) & (z_r <= 0.9005)) and z_r.min() < 0.25 and z_r.max() > 0.85
    t = a["texels"][128:256].reshape(128, 4, 4)
    centre = np.where(np.array([OCCLUDED[n] for n in names]), z_o[:, None], z_r[:, None])
    # every texel: depths within 0.01 of its surface (the comment's 3 decimals: 5e-4 more)
    assert np.all(np.abs(t[:, :, 0] - centre) <= 0.0105)
    var = t[:, :, 1] - t[:, :, 0] ** 2
    assert np.all(var <= 1.01e-4) and var.max() > 2.5e-5
    # zf: behind the receiver by 0.03, 0.015, in front by 0.015, or halfway to the occluder, in turn
    off = a["zf"][128:256] - z_r
    k = np.arange(128) % 4
    want = np.choose(k, [np.full(128, 0.03), np.full(128, 0.015), np.full(128, -0.015), 0.5 * (z_o - z_r)])
    assert np.all(np.abs(off - want) <= np.where(k == 3, 1.1e-3, 6e-4))


def _moments32(z, w):
    """b1..b4 of depths ``z`` with weights ``w`` (normalized here), rounded once to float32: (n, 4)."""
    w = w / w.sum(axis=1, keepdims=True)
    return np.stack([np.sum(w * z**k, axis=1) for k in range(1, 5)], axis=1).astype(np.float32).astype(np.float64)


def _recipe():
    """The rows' draws restated from docs/golden.md ("Bilinear cases"), with NumPy alone."""
    rng = np.random.default_rng(20170724)
    # 1. the random rows' texels: 512 distributions of 3 to 8 depths on [-1, 1], weights in [0.05, 1)
    z, w = rng.uniform(-1, 1, (512, 8)), rng.uniform(0.05, 1, (512, 8))
    w[np.arange(8)[None] >= rng.integers(3, 9, 512)[:, None]] = 0
    t_random = _moments32(z, w).reshape(128, 16)
    f_random = rng.integers(0, 2**16, (128, 2)) / 2**16
    # 2. the shadow edges: per row z_o, z_r, then the four texels t00, t10, t01, t11 in turn, each 2 to 4 depths
    # within 0.01 of its surface, weights in [0.2, 1)
    t_stiff, zf_stiff = [], []
    for k in range(128):
        z_o, z_r = rng.uniform(-0.9, -0.1), rng.uniform(0.2, 0.9)
        for occluded in list(OCCLUDED.values())[k % 4]:
            z = np.clip((z_o if occluded else z_r) + rng.uniform(-0.01, 0.01, (1, 4)), -1, 1)
            w = rng.uniform(0.2, 1, (1, 4)) * (np.arange(4)[None] < rng.integers(2, 5, 1)[:, None])
            t_stiff.append(_moments32(z, w)[0])
        zf_stiff.append(z_r + (0.03, 0.015, -0.015, 0.5 * (z_o - z_r))[k % 4])
    f_stiff = rng.integers(0, 2**16, (128, 2)) / 2**16
    f_stiff[:64] = 0.5 + rng.integers(-2048, 2048, (64, 2)) / 2**16
    # 3. the random rows' receivers, drawn last
    zf_random = rng.uniform(-1, 1, 128)
    return t_random, f_random, np.reshape(t_stiff, (128, 16)), np.array(zf_stiff), f_stiff, zf_random


def test_the_rows_are_the_draws_docs_golden_states(rows):
    # The goldens' rows are published: a port's verdicts are reproducible only if the same version draws the same
    # rows. Restated from docs/golden.md's recipe (seed, order and ranges of every draw), independently of _rows.
    _, a = rows
    t_random, f_random, t_stiff, zf_stiff, f_stiff, zf_random = _recipe()
    # the moments summed here in another order than power_moments: the float32 roundings may differ by an ulp
    np.testing.assert_allclose(a["texels"][:128], t_random, rtol=2.5e-7, atol=1e-12)
    np.testing.assert_allclose(a["texels"][128:256], t_stiff, rtol=2.5e-7, atol=1e-12)
    assert np.array_equal(a["fraction"][:128], f_random) and np.array_equal(a["fraction"][128:256], f_stiff)
    assert np.array_equal(a["zf"][:128], zf_random) and np.array_equal(a["zf"][128:256], zf_stiff)
