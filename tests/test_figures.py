"""Tests of moments_ref.tools.figures (HPG17 Figure 3) and of notebooks/figure3.ipynb."""

from __future__ import annotations

import csv
import shutil
from pathlib import Path

import numpy as np
import pytest

from moments_ref import InputError
from moments_ref.tools import figures

ROOT = Path(__file__).resolve().parents[1]


def test_figure3_files_and_columns(tmp_path):
    paths = figures.write_figure3(tmp_path / "out")
    csv_path, png_path = paths
    assert csv_path.name == "figure3.csv" and png_path.name == "figure3.png"
    assert png_path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    with open(csv_path, newline="") as fh:
        rows = list(csv.reader(fh))
    assert rows[0] == ["zf", "xi4=0", "xi4=1e-06", "xi4=1e-05", "xi4=0.0001", "xi4=0.001", "xi4=0.01"]
    data = np.array(rows[1:], dtype=float)
    assert data.shape == (1001, 7)
    zf, lower = figures.figure3_data()
    np.testing.assert_array_equal(data[:, 0], zf)
    np.testing.assert_array_equal(data[:, 1:], lower.T)  # %.17g round-trips float64
    # No temporary files left behind.
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["figure3.csv", "figure3.png"]


def test_figure3_curves_monotone_in_zf_and_decreasing_in_xi4():
    zf, lower = figures.figure3_data(n=2001)
    assert np.all(np.diff(lower, axis=1) >= -1e-12)  # a CDF bound: non-decreasing in zf
    assert np.all(np.diff(lower, axis=0) <= 1e-12)  # HPG17 §3.2: decreases as ξ4 grows
    assert np.all((lower >= 0) & (lower <= 1))
    # and strictly somewhere between the steps (the figure's point)
    assert np.all(lower[0] - lower[-1] >= -1e-12) and np.max(lower[0] - lower[-1]) > 0.3


def test_figure3_zero_xi4_is_the_exact_two_step_function():
    zf, lower = figures.figure3_data(xi4_values=(0.0,), n=1001)
    # The grid points within rounding of the jumps (linspace gives 0.4 + 1 ulp)
    # are decided by rounding; test_nonlinear covers zf exactly at y1, y2.
    at_jump = (np.abs(zf + 0.8) < 1e-12) | (np.abs(zf - 0.4) < 1e-12)
    assert at_jump.sum() == 2
    exact = 0.4 * (zf > -0.8) + 0.6 * (zf > 0.4)  # (1 − v2) δ_y1 + v2 δ_y2, by definition
    np.testing.assert_allclose(lower[0][~at_jump], exact[~at_jump], atol=1e-12)


def test_figure3_bad_arguments():
    with pytest.raises(InputError):
        figures.figure3_data(n=1)
    with pytest.raises(InputError):
        figures.figure3_data(xi4_values=(-1e-3,))
    with pytest.raises(InputError):
        figures.figure3_data(y1=0.5, y2=0.4)


def test_notebook_executes(tmp_path):
    nbformat = pytest.importorskip("nbformat")
    nbclient = pytest.importorskip("nbclient")
    src = ROOT / "notebooks" / "figure3.ipynb"
    work = tmp_path / "figure3.ipynb"
    shutil.copy(src, work)
    nb = nbformat.read(work, as_version=4)
    client = nbclient.NotebookClient(nb, timeout=120, kernel_name="python3", resources={"metadata": {"path": str(tmp_path)}})
    client.execute()
    shapes = [o for c in nb.cells if c.cell_type == "code" for o in c.get("outputs", []) if o.get("output_type") == "execute_result"]
    assert any("(6, 1001)" in o["data"]["text/plain"] for o in shapes)
