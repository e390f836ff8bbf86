"""moments_ref.tools.decoders reproduces docs/formats.md's measurement of the 32-bit D."""

import numpy as np
import pytest

from moments_ref import nonlinear as nl, packing as pk
from moments_ref.tools import decoders as D


@pytest.mark.parametrize("dtype,want", [
    ("float32", {"schema 2": (0.918, 0.0538), "schema 3 (HPG17 demo)": (0.183, 0.0196),
                 "schema 3 with the demo's clamp offset 5e-6": (0.168, 0.0195)}),
    ("float64", {"schema 2": (0.917, 0.0539), "schema 3 (HPG17 demo)": (0.183, 0.0192),
                 "schema 3 with the demo's clamp offset 5e-6": (0.168, 0.0192)}),
])
def test_e2e_rows_figures_of_the_docs(dtype, want):
    b, zf = D.e2e_rows(dtype)
    for name, (over, mean) in want.items():
        s = D.against_bound(b, zf, D.DECODERS[name])
        assert (round(s["over_max"], 3), round(s["abs_mean"], 4)) == (over, mean), name


def test_schema2_roundtrip_is_the_old_grid():
    """The baseline by hand: v2 = 0.995 reaches the top grid point 1, depths at the cell centre."""
    r = np.array([[0.1, 0.5, 0.995, 1e-4]])
    d = D.schema2_roundtrip(r)
    assert d[0, 2] == 1.0
    np.testing.assert_allclose(d[0, :2], (np.floor(511.5 * np.array([1.1, 1.5])) + 0.5) / 511.5 - 1, atol=1e-15)
    assert d[0, 3] >= 1e-4 and nl.psi4(d[0, 3]) * 63 % 1 == pytest.approx(0.5, abs=1e-9)
    np.testing.assert_allclose(D.schema3_roundtrip(r), pk.unpack32(pk.pack32(r)))


def test_random_distributions_rank_the_decoders():
    b, zf, Z = D.random_distributions(n=300, seed=1)
    assert b.shape == (len(zf), 4) and np.all((Z >= 0) & (Z <= 1 + 1e-12))
    over = {n: D.against_z(b, zf, Z, d)["over_max"] for n, d in D.DECODERS.items()}
    assert over["schema 3 (HPG17 demo)"] < 0.1 < over["schema 3, depths at the cell centre"]
    assert over["schema 3 (HPG17 demo)"] < over["schema 2"]


def test_evsm_study_recomputes_the_pipeline():
    """The EVSM study's first row is the pipeline's own leak fractions; every variation gives a verdict."""
    from moments_ref.metrics import LEAK_THRESHOLD
    from moments_ref.tools import claim_parameters as C

    rows = C.evsm_variations(sizes=(128, 1, (96, 54)))
    res = C._railing(False, (128, 1, (96, 54)))
    ref = np.asarray(res.reference["evsm128"], np.float64)
    own = {t: float(np.mean(np.asarray(res.shadow[t], np.float64) - ref < -LEAK_THRESHOLD))
           for t in ("evsm64", "evsm128", "msm128")}
    assert {t: rows[0][t] for t in own} == pytest.approx(own, abs=1e-12)
    assert len(rows) == 24 and all(isinstance(r["holds"], bool) for r in rows)


def test_random_row_figures_state_their_sampler_count_and_interval():
    """docs/formats.md's excess over the bound: the seed-0 figure, and a row of the table the command writes."""
    from pathlib import Path

    doc = (Path(__file__).parent.parent / "docs" / "formats.md").read_text(encoding="utf-8")
    first, _, uniform = D.SAMPLERS.values()
    assert D.excess_over_bound(first, seeds=[0])["max_median"] == pytest.approx(0.133, abs=5e-4)
    s = D.excess_over_bound(uniform, seeds=range(8))
    lo, hi = s["share_over_95"]
    assert lo < s["share_over"] < hi and s["rows_per_sample"] == 400_000
    assert s["max_min"] <= s["max_median"] <= s["max_max"]
    row = (f"| {list(D.SAMPLERS)[2]} | 400000 | {s['max_median']:.3f} ({s['max_min']:.3f} to "
           f"{s['max_max']:.3f}) | {s['share_over']:.1e} ({lo:.1e} to {hi:.1e}) |")
    assert row in doc, "regenerate: python -m moments_ref.tools.decoders --samples"
    r, zf = D.random_representations(10, seed=1)
    np.testing.assert_array_equal(zf.reshape(10, 4)[:, :2], np.minimum(r[::4, :2] + 1e-3, 1.0))
    # the Wilson interval of 0 in 100 and of 50 in 100 (closed form)
    assert D._wilson(0, 100)[0] == 0 and D._wilson(50, 100) == pytest.approx((0.4038, 0.5962), abs=1e-4)
