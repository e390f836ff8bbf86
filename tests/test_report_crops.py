"""The crops where the techniques differ most, and the visibility figure, against brute force and by hand."""

from types import SimpleNamespace

import matplotlib
import numpy as np
import pytest
from hypothesis import given, strategies as st

from moments_ref.scene.gbuffer import BACKGROUND, OCCLUDER, RECEIVER
from moments_ref.report import _crops
from moments_ref.techniques import _errormaps
from moments_ref.techniques.scattering import RAYS

matplotlib.use("Agg")


def test_window_side_scales_with_the_camera_height():
    assert _crops.window_side((480, 270)) == 48
    assert _crops.window_side((1920, 1080)) == 192
    assert _crops.window_side((48, 27)) == _crops.MIN_SIDE == 8
    assert _crops.window_side((6, 5)) == 5  # never larger than the image


def test_spread_by_hand():
    nan = np.nan
    e = np.array([[[0.2, nan, -0.1, 0.0]], [[0.5, nan, -0.4, 0.0]], [[-0.3, nan, 0.1, 0.0]]])
    # max(0, max e) − min(0, min e): 0.5 + 0.3; no error: 0; 0.1 + 0.4; all exact: 0
    assert _crops.spread(e) == pytest.approx(np.array([[0.8, 0.0, 0.5, 0.0]]))
    assert _crops.spread(e[:1]) == pytest.approx(np.array([[0.2, 0.0, 0.1, 0.0]]))  # one technique: |e|


def _brute_windows(score, side, count, gap):
    """Every window's mean by loops, sorted by (−mean, row, col); accepted when ``gap`` apart from the accepted."""
    h, w = score.shape
    cands = sorted(((-score[r:r + side, c:c + side].sum() / side ** 2, r, c) for r in range(h - side + 1)
                    for c in range(w - side + 1)))
    out = []
    for m, r, c in cands:
        if -m <= 0 or len(out) == count or (out and -m < _crops.MIN_SHARE * out[0][2]):
            break
        if all(r + side + gap <= r2 or r2 + side + gap <= r or c + side + gap <= c2 or c2 + side + gap <= c
               for r2, c2, _ in out):
            out.append((r, c, -m))
    return out


@given(st.integers(1, 14), st.integers(1, 14), st.integers(1, 5), st.integers(1, 4), st.integers(0, 3),
       st.randoms(use_true_random=False))
def test_windows_equal_brute_force(h, w, side, count, gap, rnd):
    side = min(side, h, w)
    # Small integers: exact sums in both computations, and many ties to break the same way.
    score = np.array([[rnd.choice([0, 0, 0, 1, 2, 30]) for _ in range(w)] for _ in range(h)], dtype=float)
    assert _crops.box_means(score, side) == pytest.approx(
        np.array([[score[r:r + side, c:c + side].mean() for c in range(w - side + 1)] for r in range(h - side + 1)]))
    assert _crops.choose_windows(score, side, count, gap) == _brute_windows(score, side, count, gap)


def test_windows_find_planted_differences():
    score = np.zeros((60, 100))
    score[10:14, 80:84] = 1.0  # strongest
    score[40:44, 10:14] = 0.6
    score[45:48, 50:53] = 0.5  # weaker and smaller
    score[5:6, 5:6] = 0.1  # a fourth: left out
    score[10:14, 86:88] = 0.9  # beside the strongest: in its window or within half a window of it
    got = _crops.choose_windows(score, 8, 3)
    assert len(got) == 3
    for (r, c, _), (y, x) in zip(got, [(12, 82), (42, 12), (46, 51)]):
        assert r <= y < r + 8 and c <= x < c + 8
    assert got[0][2] == pytest.approx((16 + 8 * 0.9) / 64) and got[0][2] > got[1][2] > got[2][2]
    assert _crops.choose_windows(np.zeros((20, 20)), 8) == []  # the techniques agree: no window
    score[45:48, 50:53] = 0.0  # the third now below a tenth of the first: left out
    score[45, 50] = 0.5
    assert len(_crops.choose_windows(score, 8, 3)) == 2


def _receiver_result(errors, h=40, w=64):
    """A fake run: every pixel a receiver but the top row (background); reference 0.5 everywhere."""
    kind = np.full(h * w, RECEIVER)
    kind[:w] = BACKGROUND
    pixel = np.flatnonzero(kind == RECEIVER)
    gb = SimpleNamespace(resolution=(w, h), kind=kind, pixel=pixel, lambert=np.ones(len(pixel)))
    ref = np.full(len(pixel), 0.5)
    shadow = {n: ref + e.reshape(-1)[pixel] for n, e in errors.items()}
    return SimpleNamespace(scene=SimpleNamespace(name="toy"), gbuffer=gb, shadow=shadow,
                           reference={n: ref for n in errors}, values={})


def test_crop_figure_of_receivers():
    h, w = 40, 64
    a, b = np.zeros((h, w)), np.zeros((h, w))
    a[20:24, 40:44] = 0.4  # a darker than the reference here
    b[20:24, 40:44] = -0.1
    b[5:9, 5:9] = -0.3  # b lighter here
    figs = _crops.crop_figures(_receiver_result({"a": a, "b": b}), {"pcf": ["a", "b"]})
    fig = figs["crops_toy_pcf.png"]
    bars = [ax for ax in fig.axes if ax.get_ylabel().startswith("signed error")]
    assert len(bars) == 1 and bars[0].get_ylim() == pytest.approx((-0.4, 0.4))  # the largest |e| in the windows
    titles = [t.get_text() for ax in fig.axes for t in ax.texts]  # each crop's title above it
    assert "1: reference" in titles and "2: b" in titles and "b: e\nmax |e| 0.3" in titles
    grid = next(ax for ax in fig.axes if "1: reference" in [t.get_text() for t in ax.texts])
    assert len(grid.get_images()) == 2 * (3 + 2)  # per window the reference, a and b above the errors of a and b
    x, y = grid.get_xlim(), grid.get_ylim()
    for im in grid.get_images():  # every crop inside the grid's box: none cut off by the layout
        left, right, bottom, top = im.get_extent()
        assert x[0] <= left < right <= x[1] and y[1] <= top < bottom <= y[0]
    assert len([t for t in titles if t.startswith("3:")]) == 0  # two places differ: two windows
    assert _crops.crop_figures(_receiver_result({"a": np.zeros((h, w))}), {"pcf": ["a"]}) == {}
    lines = "\n".join(_crops.crop_lines(list(figs)))
    assert "![crops](crops_toy_pcf.png)" in lines and "largest mean" in lines
    matplotlib.pyplot.close("all")


def test_crop_figure_of_scattering_images():
    h, w, t_max = 30, 50, 2.0
    ref = np.full((h, w), 1.0)
    img = ref.copy()
    img[10:15, 30:40] = 1.5  # +0.25 of t_max
    res = SimpleNamespace(scene=SimpleNamespace(name="fog"), gbuffer=None, shadow={"s6": img, "rm": ref},
                          reference={"s6": ref, "rm": ref}, values={RAYS: (None, t_max)})
    fig = _crops.crop_figures(res, {"raymarch": ["s6", "rm"]})["crops_fog_raymarch.png"]
    labels = [ax.get_ylabel() for ax in fig.axes]
    assert "scattering term / t_max (dimensionless)" in labels
    err = next(ax for ax in fig.axes if ax.get_ylabel().startswith("signed error"))
    assert err.get_ylim() == pytest.approx((-0.25, 0.25))
    matplotlib.pyplot.close("all")


def test_visibility_figure_colours_and_bar():
    h, w = 10, 16
    kind = np.full(h * w, RECEIVER)
    kind[:w] = BACKGROUND
    kind[w:2 * w] = OCCLUDER
    pixel = np.flatnonzero(kind == RECEIVER)
    gb = SimpleNamespace(resolution=(w, h), kind=kind, pixel=pixel, lambert=np.ones(len(pixel)))
    inten = np.full(len(pixel), 0.25)
    rgb = _errormaps._visibility_rgb(gb, inten, matplotlib.pyplot.get_cmap("gray"))
    assert rgb[0, 0] == pytest.approx(_errormaps.VISIBILITY_MASK)
    assert rgb[1, 0] == pytest.approx(_errormaps.OCCLUDER_COLOUR)
    assert rgb[5, 5] == pytest.approx([0.75] * 3, abs=1 / 255)  # visibility 1 − 0.25 on the grey scale
    res = SimpleNamespace(scene=SimpleNamespace(name="toy"), gbuffer=gb, shadow={"x": inten}, reference={"x": inten})
    fig = _errormaps.visibility_maps(res, ["x"], "MVR")
    assert any("visibility" in ax.get_ylabel() for ax in fig.axes)
    assert {t.get_text() for t in fig.legends[0].get_texts()} >= {"occluder"}
    matplotlib.pyplot.close("all")


def test_claim_crops_drawn_from_the_crops_alone():
    """The report sends a worker only each scene's claim crops (report._claim_crops_only): the same PNGs."""
    from moments_ref import report
    from moments_ref.report import _claim_crops, paper_claims

    rng = np.random.default_rng(3)
    crops = {"hpg17-nlq32-close-to-nlq64": {"names": ["reference", "nlq64", "nlq32"], "side": 24, "pixel": [40, 30],
                                            "images": rng.random((3, 24, 24)).astype(np.float16)}}
    measured = {"railing": {"crops": crops, "rmse": {"nlq64": 0.1}}, "facade": {"rmse": {"nlq64": 0.2}}}
    sent = report._claim_crops_only(measured)
    assert sent == {"railing": {"crops": crops}, "facade": {"crops": None}}
    got = paper_claims.crop_pngs(sent)
    assert list(got) == [_claim_crops.file_name("hpg17-nlq32-close-to-nlq64")]
    assert got == paper_claims.crop_pngs(measured)
    png = next(iter(got.values()))
    assert png.startswith(b"\x89PNG")


def test_error_maps_panels_titles_and_bar():
    h, w = 10, 16
    kind = np.full(h * w, RECEIVER)
    kind[:w] = BACKGROUND
    pixel = np.flatnonzero(kind == RECEIVER)
    gb = SimpleNamespace(resolution=(w, h), kind=kind, pixel=pixel, lambert=np.ones(len(pixel)))
    ref = np.full(len(pixel), 0.5)
    shadow = {"a": ref + 0.2, "b": ref - np.linspace(0, 0.4, len(pixel))}
    res = SimpleNamespace(scene=SimpleNamespace(name="toy"), gbuffer=gb, shadow=shadow, reference={n: ref for n in shadow})
    fig = _errormaps.error_maps(res, ["a", "b"], "PCF")
    grid = next(ax for ax in fig.axes if ax.texts)
    titles = [t.get_text() for t in grid.texts]
    assert "PCF (shaded)" in titles and "a (shaded)" in titles and "b: e, max |e| 0.4, 1.4% clipped" in titles  # 2 of 144 above the 99th percentile
    assert any(t.startswith("signed error e = technique − PCF") for t in titles)  # the legend in the second slot
    assert len(grid.get_images()) == 1 + 2 * 2
    x, y = grid.get_xlim(), grid.get_ylim()
    for im in grid.get_images():  # every panel inside the grid's box
        left, right, bottom, top = im.get_extent()
        assert x[0] <= left < right <= x[1] and y[1] <= top < bottom <= y[0]
    bar = next(ax for ax in fig.axes if ax.get_ylabel().startswith("signed error e"))
    # one range for both: the largest 99th percentile of |e| (b's errors reach 0.4; a's are 0.2)
    assert bar.get_ylim()[1] == pytest.approx(np.percentile(np.linspace(0, 0.4, len(pixel)), 99))
    matplotlib.pyplot.close("all")
