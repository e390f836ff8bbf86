"""figure_png / save_figure draw a tight-laid-out figure once, and write the bytes matplotlib's own savefig writes."""

from __future__ import annotations

import io

import numpy as np
import pytest

matplotlib = pytest.importorskip("matplotlib")
matplotlib.use("Agg", force=False)

import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402

from moments_ref._io import PNG_METADATA, figure_png, save_figure  # noqa: E402


def _figure(layout):
    # A small grid of images with titles and a colour bar, laid out as the report's figures are.
    fig, axes = plt.subplots(2, 3, figsize=(6, 3.5), constrained_layout=layout == "constrained")
    rng = np.random.default_rng(7)
    im = None
    for i, ax in enumerate(axes.flat):
        im = ax.imshow(rng.random((12, 12)), interpolation="nearest", vmin=0, vmax=1)
        ax.set_title(f"panel {i}: e", fontsize=7)
    fig.suptitle("a title", fontsize="medium")
    if layout == "tight":
        fig.tight_layout(rect=(0, 0, 0.85, 1))
        fig.colorbar(im, cax=fig.add_axes((0.88, 0.1, 0.02, 0.8)))
    return fig


def _draws(fig, monkeypatch):
    count = []
    draw = Figure.draw

    def counted(self, renderer):
        count.append(1)
        return draw(self, renderer)

    monkeypatch.setattr(Figure, "draw", counted)
    return count


@pytest.mark.parametrize("layout", ["tight", "constrained", "none"])
def test_figure_png_is_matplotlibs_own_png(layout, monkeypatch, tmp_path):
    # The reference: the same figure saved by savefig as it was (the placeholder engine
    # tight_layout leaves in place, so savefig's extra draw runs first).
    ref = _figure(layout)
    buf = io.BytesIO()
    ref.savefig(buf, format="png", dpi=110, metadata=PNG_METADATA)
    plt.close(ref)
    fig = _figure(layout)
    count = _draws(fig, monkeypatch)
    got = figure_png(fig, dpi=110)
    assert got == buf.getvalue()
    # tight: one draw instead of two; a working engine (constrained) keeps its layout draw.
    assert len(count) == (2 if layout == "constrained" else 1)
    plt.close(fig)
    # save_figure likewise (a fresh figure: a constrained layout saved twice moves a little).
    fig = _figure(layout)
    path = save_figure(fig, tmp_path / "f.png", dpi=110)
    assert path.read_bytes() == buf.getvalue()
    plt.close(fig)


def test_compress_level_changes_the_bytes_not_the_pixels():
    # The report's PNGs (a lower zlib level, quicker to encode): the pixels of matplotlib's own
    # savefig, decoded by Pillow; level 0 stores the rows uncompressed, so the file holds at least
    # every pixel's bytes (the level reaches the encoder).
    from PIL import Image

    from moments_ref._io import REPORT_PNG_LEVEL

    ref = _figure("tight")
    buf = io.BytesIO()
    ref.savefig(buf, format="png", dpi=110, metadata=PNG_METADATA)
    plt.close(ref)
    want = np.asarray(Image.open(io.BytesIO(buf.getvalue())))
    for level in (REPORT_PNG_LEVEL, 0):
        fig = _figure("tight")
        got = figure_png(fig, dpi=110, compress_level=level)
        plt.close(fig)
        assert got != buf.getvalue()
        assert np.array_equal(np.asarray(Image.open(io.BytesIO(got))), want)
    assert len(got) >= want.nbytes


def _crop_like():
    # Axes of the report's crop figures: images with titles, a text panel, a ticked overview, a suptitle.
    fig = plt.figure(figsize=(7, 5))
    grid = fig.add_gridspec(3, 4, height_ratios=[1.4, 1, 1])
    rng = np.random.default_rng(3)
    over = fig.add_subplot(grid[0, :2])
    over.imshow(rng.random((27, 48)), extent=(0, 48, 27, 0))
    over.set_xlabel("camera pixel x", fontsize=7)
    note = fig.add_subplot(grid[0, 2:])
    note.axis("off")
    note.text(0.0, 1.0, "a legend\nof several lines that reach\nbeyond the panel's right edge", va="top", fontsize=7,
              transform=note.transAxes)
    for i in range(1, 3):
        for j in range(4):
            ax = fig.add_subplot(grid[i, j])
            ax.imshow(rng.random((8, 8)), interpolation="nearest")
            ax.set(xticks=[], yticks=[])
            ax.set_title(f"{i}: technique {j}\nmax |e| {rng.random():.2g}", fontsize=7)
    fig.suptitle("a title\nof two lines", fontsize="medium")
    return fig


def _count_tight_boxes(monkeypatch):
    """The Axes whose tight box is measured from now on, in order, one entry per measurement."""
    from matplotlib.axes import Axes

    calls, measure = [], Axes.get_tightbbox

    def counted(self, *args, **kwargs):
        calls.append(self)
        return measure(self, *args, **kwargs)

    monkeypatch.setattr(Axes, "get_tightbbox", counted)
    return calls


@pytest.mark.parametrize("rect", [(0, 0, 0.85, 1), (0, 0.05, 0.88, 1), None])
def test_tight_layout_measures_each_axes_once_and_lays_out_as_matplotlib(rect, monkeypatch):
    from moments_ref._io import tight_layout

    ref = _crop_like()
    ref.tight_layout(rect=rect)
    want = (ref.subplotpars.left, ref.subplotpars.right, ref.subplotpars.bottom, ref.subplotpars.top,
            ref.subplotpars.wspace, ref.subplotpars.hspace)
    png = figure_png(ref, dpi=110)
    plt.close(ref)
    calls = _count_tight_boxes(monkeypatch)
    fig = _crop_like()
    tight_layout(fig, rect=rect)
    got = (fig.subplotpars.left, fig.subplotpars.right, fig.subplotpars.bottom, fig.subplotpars.top,
           fig.subplotpars.wspace, fig.subplotpars.hspace)
    assert got == want  # the same floats: the same layout
    # matplotlib asks twice per Axes with a rect (once without); here each Axes is measured once.
    assert len(calls) == len(fig.axes) and set(calls) == set(fig.axes)
    assert all("get_tightbbox" not in ax.__dict__ for ax in fig.axes)  # the memo is gone after the call
    monkeypatch.undo()
    assert figure_png(fig, dpi=110) == png
    plt.close(fig)


def test_tight_layout_with_a_rect_asks_matplotlib_twice(monkeypatch):
    # What tight_layout saves: without the memo, matplotlib's layout with a rect measures every Axes twice
    # (if a matplotlib release measures once, the memo is harmless and this says so).
    calls = _count_tight_boxes(monkeypatch)
    fig = _crop_like()
    fig.tight_layout(rect=(0, 0, 0.85, 1))
    assert len(calls) == 2 * len(fig.axes)
    plt.close(fig)
