"""The samplers' figure (sweep/figure.py, docs/sweep.md): each panel holds the data of the draw it names.

The draw is read here with ``draw_rows`` and the panels' data recomputed with NumPy: the depths with weight, the
receivers' distance to the nearest depth per receiver stratum, the smallest weight of texels with two or more
depths, the spread of the first cluster, v2 of Algorithm 3's input, and the rows per stratum.
"""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("matplotlib")

from moments_ref import golden  # noqa: E402
from moments_ref.sweep import STRATA, figure  # noqa: E402
from moments_ref.sweep.samplers import TEXELS, build_inputs, draw_rows  # noqa: E402

ROWS = 3000


@pytest.fixture(scope="module")
def drawn():
    fig = figure.sampler_figure(rows=ROWS, seed=4)
    case = golden.CASES["shade-float32"]
    p = draw_rows(case, 4, 0, ROWS)
    yield fig, p, build_inputs(case, p)["r"].astype(np.float64)
    import matplotlib.pyplot as plt

    plt.close(fig)


def _counts(ax):
    return sum(patch.get_height() for patch in ax.patches)


def test_the_depths_and_the_strata(drawn):
    fig, p, _ = drawn
    ax = fig.axes
    used = p["w"] > 0
    assert _counts(ax[0]) == used.sum()
    bars = [patch.get_width() for patch in ax[5].patches]
    assert bars == np.bincount(p["stratum"], minlength=len(STRATA)).tolist()
    assert [t.get_text() for t in ax[5].get_yticklabels()] == list(STRATA)
    assert fig._suptitle.get_text() == f"What the sweep draws: chunk 0 of shade-float32, seed 4, {ROWS} rows"


def test_the_receivers_distances_per_stratum(drawn):
    fig, p, _ = drawn
    used = p["w"] > 0
    dist = np.array([np.min(np.abs(z[u] - zf)) for z, u, zf in zip(p["z"], used, p["zf"])])
    receiver = p["stratum"] % 3
    lines = fig.axes[1].patches  # one step outline per receiver stratum, in the order uniform, near, end
    assert len(lines) == 3
    for k, poly in enumerate(lines):
        xy = poly.get_xy()
        edges = np.unique(xy[:, 0])
        d = np.log10(np.maximum(dist[receiver == k], 1e-12))
        assert edges.min() == pytest.approx(d.min()) and edges.max() == pytest.approx(d.max())
    assert [t.get_text() for t in fig.axes[1].get_legend().get_texts()] == ["uniform", "near", "end"]


def test_weights_spreads_and_v2(drawn):
    fig, p, r = drawn
    used = p["w"] > 0
    texel = p["stratum"] // 3
    wmin = np.array([w[u].min() for w, u in zip(p["w"], used)])
    assert _counts(fig.axes[2]) == (texel > 0).sum()
    edges = [patch.get_x() for patch in fig.axes[2].patches]
    assert min(edges) == pytest.approx(np.log10(wmin[texel > 0]).min())
    cl = texel == TEXELS.index("cluster")
    spread = np.array([z[:3][u[:3]].max() - z[:3][u[:3]].min() for z, u in zip(p["z"][cl], used[cl])])
    assert _counts(fig.axes[3]) == (spread > 0).sum()
    assert _counts(fig.axes[4]) == ROWS
    v2 = r[:, 2]
    assert min(patch.get_x() for patch in fig.axes[4].patches) == pytest.approx(
        np.log10(np.maximum(np.minimum(v2, 1 - v2), 1e-12)).min())


def test_main_writes_the_png(tmp_path, capsys):
    out = tmp_path / "f.png"
    assert figure.main(["--out", str(out), "--rows", "500"]) == 0
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and f"wrote {out}" in capsys.readouterr().out
