"""HPG17 Figure 4: histograms of ξ4 and Ψ4(ξ4) from a real filtered shadow map."""

import csv

import numpy as np

from moments_ref.cli import main
from moments_ref.tools.figures import figure4_data
from moments_ref.moments import BIAS_FLOAT32, bias_moments, power_moments
from moments_ref.nonlinear import phi, psi4


def test_histograms_count_every_covered_texel_and_psi4_spreads_them():
    d = figure4_data("railing", size=256, samples=4, sigmas=(1.0, 2.4))
    for i in range(2):
        assert d["xi4_counts"][i].sum() == d["texels"][i] == d["psi4_counts"][i].sum()
        # Ψ4 uses the codes far better than uniform quantization of ξ4 (HPG17 §3.3).
        assert d["psi4_entropy"][i] > d["linear_entropy"][i] + 2
        assert d["psi4_entropy"][i] <= d["uniform_entropy"] + 1e-12
    # "Note the prevalence of small values": the most frequent ξ4 lies below 1e-5
    # (below 1e-6 at the paper's 2048², see figure4.md).
    mode = d["xi4_edges"][np.argmax(d["xi4_counts"], axis=1) + 1]
    assert (mode <= 1e-5).all()


def test_psi4_histogram_counts_the_same_texels_in_the_same_order():
    """Ψ4 is monotone, so the ξ4 and Ψ4(ξ4) histograms rank the texels identically.

    Checked on the Φ outputs that figure4_data histograms: for every ξ4 bin edge e,
    the texels with ξ4 < e are exactly those with Ψ4(ξ4) < Ψ4(e) (a warp that is not
    monotone, or histograms over different texels, fail this).
    """
    from moments_ref.nonlinear import PSI4_XI_MAX, PSI4_XI_MIN

    rng = np.random.default_rng(3)
    z = rng.choice([-0.5, 0.2, 0.21, 0.9], size=(2000, 9)) + rng.normal(0, 1e-3, (2000, 9))
    b = bias_moments(power_moments(np.clip(z, -1, 1)).astype(np.float32), BIAS_FLOAT32)
    xi4 = np.clip(phi(b)[:, 3], PSI4_XI_MIN, PSI4_XI_MAX)
    u = psi4(xi4)
    assert (u >= 0).all() and (u <= 1).all()
    for e in np.geomspace(PSI4_XI_MIN, PSI4_XI_MAX, 65)[1:-1]:
        below = xi4 < np.float32(e)
        assert np.array_equal(below, u < psi4(np.float32(e))), e


def test_cli_writes_csv_png_md(tmp_path):
    assert main(["figure4", "--out", str(tmp_path), "--size", "96", "--scene", "facade"]) == 0
    with open(tmp_path / "figure4.csv") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 4 * 64
    assert {"sigma", "xi4_count", "psi4_count", "linear_count"} <= set(rows[0])
    assert (tmp_path / "figure4.png").stat().st_size > 1000
    assert "bits" in (tmp_path / "figure4.md").read_text()
