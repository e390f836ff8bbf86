"""golden.engine's rows (the distributions every engine case judges) against the recipe docs/golden.md states.

Restated here with NumPy and the scenes' shadow maps, independently of golden.engine's row code: the
hand-made distributions (each as its comment names it), the 9×9 footprints of 4× MSAA depths drawn
from the shipped scenes, the receivers of each distribution, and the moments of every row. The rows
are published in the goldens: a port's verdicts are reproducible only if the same version draws the same
rows.
"""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest

from moments_ref.golden import engine
from moments_ref.gpu.filtering import gaussian_weights
from moments_ref.scene.files import load_scene

#: The hand-made distributions (depths, weights, category, flags), in docs/golden.md's order.
SYNTHETIC = ([([d], [1.0], "edge", ()) for d in (-1.0, -0.5, 0.0, 0.3, 1.0)]
             + [([-1.0, 1.0], [w, 1 - w], "stiff", ("near_far",)) for w in (0.25, 1 / 3, 0.5, 2 / 3, 0.75, 0.9)]
             + [([-1.0, 0.2, 1.0], [0.3, 0.3, 0.4], "stiff", ("near_far",)),
                ([-1.0, -0.999, 1.0], [0.5, 0.2, 0.3], "stiff", ("near_far",))]
             + [(list(z), [0.6, 0.4], "random", ()) for z in ((-0.8, 0.4), (-0.5, 0.5), (0.2, 1.0), (-1.0, 0.6))]
             + [([c - s, c, c + s / 2, c + s], [0.2, 0.3, 0.3, 0.2], "stiff", ("cluster",))
                for c, s in ((0.3, 1e-4), (-0.6, 1e-3), (0.95, 1e-4))]
             + [([-0.6, -0.2, 0.3, 1.0], [0.25] * 4, "stiff", ()), ([-0.6, -0.2, 0.3], [0.3, 0.3, 0.4], "stiff", ())])


def _footprints(rng):
    """Per scene (railing, three-occluders, chair): 6 of the 9×9 windows on the 4-texel grid of its 96² 4× MSAA
    shadow map (edge-padded by 4) whose depths span more than 0.05, chosen by rng.choice without replacement;
    weights: the 9×9 Gaussian (σ = 2.4) per tap, a quarter per sample."""
    g = gaussian_weights(9, 2.4)
    w = np.repeat((g[:, None] * g[None, :]).reshape(-1), 4) / 4
    out = []
    for name in ("railing", "three-occluders", "chair"):
        depth, _ = load_scene(name).shadow_map(size=96, samples=4)
        pad = np.pad(np.asarray(depth, np.float64), ((4, 4), (4, 4), (0, 0)), mode="edge")
        grid = [(i, j) for i in range(0, 96, 4) for j in range(0, 96, 4)]
        cand = [(i, j) for i, j in grid if np.ptp(pad[i:i + 9, j:j + 9]) > 0.05]
        for k in rng.choice(len(cand), min(6, len(cand)), replace=False):
            i, j = cand[k]
            out.append((pad[i:i + 9, j:j + 9].reshape(-1), w, "random", ("footprint",)))
    return out


def _receivers(z, rng):
    """Midpoints of the first distinct depths (at most 4), 0.05 before the first and after the last (within
    [-1, 1]); with more than 5 distinct depths two more uniform within 0.02 of their range; distinct, sorted."""
    u = sorted(set(z.tolist()))
    zf = [0.5 * (a + b) for a, b in zip(u[:-1], u[1:])][:4] + [max(-1.0, u[0] - 0.05), min(1.0, u[-1] + 0.05)]
    if len(u) > 5:
        zf += list(rng.uniform(max(-1.0, u[0] - 0.02), min(1.0, u[-1] + 0.02), 2))
    return sorted(set(zf))


@pytest.fixture(scope="module")
def rows():
    return engine._engine_rows(np.random.default_rng(7), "float32")


def test_the_engine_rows_are_the_recipes_distributions_and_receivers(rows):
    rng = np.random.default_rng(20170723)
    dists = [(np.array(z, np.float64), np.array(w, np.float64) / np.sum(w), c, f) for z, w, c, f in SYNTHETIC]
    dists += [(z, w / w.sum(), c, f) for z, w, c, f in _footprints(rng)]
    zf, cat, flags, owner = [], [], [], []
    for k, (z, w, c, f) in enumerate(dists):
        for x in _receivers(z, rng):
            zf.append(x), cat.append(c), owner.append(k)
            flags.append(tuple(f) + (("support_point",) if np.any(z == x) else ()))
    a = rows.inputs
    assert len(zf) == 197 and list(rows.category) == cat and [tuple(f) for f in rows.flags] == flags
    assert np.array_equal(a["zf"], zf)
    width = max(len(z) for z, *_ in dists)
    assert a["support"].shape == a["mass"].shape == (197, width)
    for r, k in enumerate(owner):
        z, w = dists[k][:2]
        n = len(z)
        assert np.array_equal(a["support"][r, :n], z) and np.all(a["support"][r, n:] == 0)
        np.testing.assert_allclose(a["mass"][r, :n], w, rtol=1e-15, atol=0)
        assert np.all(a["mass"][r, n:] == 0)


def test_each_rows_moments_are_its_distributions_rounded_once(rows):
    # b_k = sum of mass z^k over sum of mass, exactly (rationals), rounded once to float32: a few rows of each kind
    a = rows.inputs
    for r in (0, 5, 20, 40, 60, 120, 196):
        m = [Fraction(float(x)) for x in a["mass"][r]]
        z = [Fraction(float(x)) for x in a["support"][r]]
        total = sum(m)
        want = [float(np.float32(float(sum(mi * zi**k for mi, zi in zip(m, z)) / total))) for k in range(1, 5)]
        got = a["b"][r].tolist()
        assert all(abs(g - x) <= abs(x) * 2.0**-23 for g, x in zip(got, want)), (r, got, want)


def test_the_engine_goldens_number_their_rows_from_one():
    case = engine.engine_specs("float32")[0]["name"]
    from moments_ref.golden.cases import CASES

    rows = engine._engine_rows(None, "float32")
    out = engine.derive_engine(CASES[case], {k: rows.inputs[k] for k in ("zf", "support", "mass")}, rows.category,
                               rows.comment, rows.flags)
    assert out["tc_id"].dtype == np.int32 and out["tc_id"].tolist() == list(range(1, 198))
