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
