"""Crops where the techniques differ most: the magnified insets of HPG17 Figure 1, the close-ups of VWSS Figure 8.

Per scene and reference, up to :data:`MAX_WINDOWS` square windows of camera
pixels are chosen where the techniques' signed errors against the reference
(``e = technique − reference``) differ most:

1. each pixel's **spread** ``s = max(0, max_t e_t) − min(0, min_t e_t)``: the
   range of the signed errors of the techniques ``t`` and of the reference
   itself (whose error is 0); with one technique it is ``|e|``. Pixels without
   an error (not a receiver inside the shadow map) count 0;
2. its mean over every position of a ``side × side`` window (a box filter,
   from a summed-area table);
3. greedily the window with the largest mean (ties: the first in row-major
   order of its top-left corner, so the choice is deterministic), then the
   next largest among the windows at least :data:`GAP` × ``side`` pixels away
   from every chosen one (in x or in y: not two views of one feature), until
   :data:`MAX_WINDOWS` or no window with a mean of at least :data:`MIN_SHARE`
   of the first's is left.

``side`` is :data:`WINDOW` camera pixels at :data:`WINDOW_ROWS` rows, scaled
with the camera's height (the same part of the view at every resolution; 192
pixels at 1080 rows), at least :data:`MIN_SIDE`.

The figure ``crops_<scene>_<reference>.png`` shows the reference with the
windows outlined and numbered, then per window the reference and each
technique (nearest-neighbour magnified) above each technique's signed error,
all errors on one symmetric colour scale (the largest ``|e|`` inside the
windows: nothing is clipped) with its colour bar; grey
(:data:`moments_ref.techniques._errormaps.MASK`) marks pixels without an error.
Scattering images (the normalized scattering term, 2-D per camera pixel) get a
second colour bar for their values.

References
----------
.. [1] HPG17: Christoph Peters. 2017. *Non-Linearly Quantized Moment Shadow Maps*. In Proceedings
       of High Performance Graphics (HPG '17). ACM. The non-linear quantization Φ, Ψ4, Algorithms
       1–3, the texel formats and the compute shader of §4.1.
.. [2] VWSS: Adam Marrs, Benjamin Watson and Christopher Healey. 2018. *View-warped Multi-view Soft
       Shadowing for Local Area Lights*. Journal of Computer Graphics Techniques (JCGT) 7, 3, 1–28.
       http://jcgt.org/published/0007/03/01/
"""

from __future__ import annotations

import numpy as np

from .._panels import frames, panel, panel_axes
from ..metrics import shaded_image
from ..techniques import get_reference
from ..techniques._errormaps import MASK

__all__ = ["WINDOW", "WINDOW_ROWS", "MIN_SIDE", "MAX_WINDOWS", "GAP", "MIN_SHARE", "window_side", "spread",
           "box_means", "choose_windows", "crop_figure", "crop_figures", "crop_lines"]

#: Window side in camera pixels at :data:`WINDOW_ROWS` rows of the camera.
WINDOW = 48
WINDOW_ROWS = 270
#: The smallest window side (pixels).
MIN_SIDE = 8
#: Windows per figure, at most.
MAX_WINDOWS = 3
#: Least gap between two windows, as a share of their side.
GAP = 0.5
#: Least mean spread of a window, as a share of the first window's.
MIN_SHARE = 0.1


def window_side(resolution):
    """Side of the windows for a camera of ``resolution = (width, height)``: ``WINDOW · height / WINDOW_ROWS``."""
    w, h = (int(v) for v in resolution)
    return int(min(w, h, max(MIN_SIDE, round(WINDOW * h / WINDOW_ROWS))))


def spread(errors):
    """Per pixel ``max(0, max_t e_t) − min(0, min_t e_t)`` of ``errors`` (t, H, W); NaN (no error) counts 0."""
    errors = list(errors)
    hi = np.zeros(np.shape(errors[0]))
    lo = np.zeros_like(hi)
    for e in errors:  # loop over techniques; fmax/fmin skip NaN, so NaN counts 0
        e = np.asarray(e, dtype=np.float64)
        np.fmax(hi, e, out=hi)
        np.fmin(lo, e, out=lo)
    return np.subtract(hi, lo, out=hi)


def box_means(score, side):
    """Mean of ``score`` (H, W) over each ``side × side`` window by its top-left pixel: (H−side+1, W−side+1)."""
    s = np.asarray(score, dtype=np.float64)
    sat = np.zeros((s.shape[0] + 1, s.shape[1] + 1))
    sat[1:, 1:] = s.cumsum(axis=0).cumsum(axis=1)
    total = sat[side:, side:] - sat[:-side, side:] - sat[side:, :-side] + sat[:-side, :-side]
    return total / (side * side)


def choose_windows(score, side, count=MAX_WINDOWS, gap=None, share=MIN_SHARE):
    """Up to ``count`` windows of largest mean ``score``, apart from each other: list of ``(row, col, mean)``.

    ``(row, col)`` is the top-left pixel. Greedy, ties to the first in row-major
    order; each next window at least ``gap`` pixels (default ``GAP · side``)
    from every chosen one in x or in y, with a mean of at least ``share`` of
    the first's and above 0 (module docstring).
    """
    gap = int(np.ceil(GAP * side)) if gap is None else int(gap)
    means = box_means(score, side)
    # Rounding of the summed-area table leaves ~1e-16 where the score is 0: not a difference.
    means[means <= 1e-12 * max(float(np.max(means)), 1.0)] = -np.inf
    out = []
    while len(out) < count:
        k = int(np.argmax(means))
        r, c = divmod(k, means.shape[1])
        if not np.isfinite(means[r, c]) or (out and means[r, c] < share * out[0][2]):
            break
        out.append((r, c, float(means[r, c])))
        # Every window whose box comes closer than ``gap`` to the chosen one in both x and y.
        reach = side + gap
        means[max(r - reach + 1, 0):r + reach, max(c - reach + 1, 0):c + reach] = -np.inf
    return out


def _views(result, names):
    """``(kind, pictures, errors)``: pictures {title: (H, W[, 3])} reference first, errors {name: (H, W)}.

    ``kind`` is ``"shaded"`` (shadow intensities of the receiver pixels, shown
    shaded) or ``"scattering"`` (images of the scattering term, divided by
    ``t_max`` as the report's metric does).
    """
    first = np.asarray(result.shadow[names[0]])
    if first.ndim == 2:
        from ..techniques.scattering import RAYS

        t_max = float(result.values[RAYS][1])
        pictures = {"reference": np.asarray(result.reference[names[0]], np.float64) / t_max}
        pictures.update({n: np.asarray(result.shadow[n], np.float64) / t_max for n in names})
        errors = {n: pictures[n] - np.asarray(result.reference[n], np.float64) / t_max for n in names}
        return "scattering", pictures, errors
    gb = result.gbuffer
    w, h = gb.resolution
    pictures = {"reference": shaded_image(gb, result.reference[names[0]])}
    errors = {}
    for n in names:
        pictures[n] = shaded_image(gb, result.shadow[n])
        img = np.full(h * w, np.nan)
        img[gb.pixel] = np.asarray(result.shadow[n], np.float64) - np.asarray(result.reference[n], np.float64)
        errors[n] = img.reshape(h, w)
    return "shaded", pictures, errors


_WORDS = {"shaded": ("shadow intensity, 1 = fully shadowed", "darker than the reference (more shadow)",
                     "lighter (light leaks)"),
          "scattering": ("scattering term / t_max", "more scattered light than the reference", "less")}


#: The crops figure's layout in inches, fixed (:mod:`moments_ref._panels`: the crops are images in one Axes).
PAD = 0.12  # the figure's edges
TITLES = (0.24, 0.36)  # room above a crop for a one-line (pictures) and a two-line (errors) title, 7 pt
ROW_GAP = 0.16  # between one window's errors and the next window's pictures
BARS = 1.05  # right of the crops: the colour bar(s) and their labels
TOP = 0.6  # the two lines of the figure's title


def _legend_text(kind, side, vmax, reference):
    what, red, blue = _WORDS[kind]
    text = (f"Windows: {side}×{side} camera pixels where the signed\nerrors differ most (the mean over the window "
            "of\nmax − min of the techniques' errors and 0), chosen\ngreedily, half a window apart; "
            "nearest-neighbour magnified.\n\n"
            f"e = technique − {reference} ({what})\nred: {red}\nblue: {blue}\n"
            f"one range ±{vmax:.3g}: the largest |e| in the windows\n(nothing clipped)")
    if kind == "shaded":
        text += "\n\ngrey: no receiver inside the shadow map"
    return text


def _outlined():
    from matplotlib import patheffects

    return [patheffects.withStroke(linewidth=3, foreground="black")]


def _overview(ax, picture, windows, side, kind):
    from matplotlib.patches import Rectangle

    h, w = picture.shape[:2]
    ax.imshow(picture, cmap="magma" if kind == "scattering" else None, vmin=0, vmax=1, interpolation="nearest",
              extent=(0, w, h, 0))
    for i, (r, c, _) in enumerate(windows, 1):
        ax.add_patch(Rectangle((c, r), side, side, fill=False, edgecolor="yellow", linewidth=1.2,
                               path_effects=_outlined()))
        ax.text(c + side + 1, r, str(i), color="yellow", fontsize=8, va="top", ha="left", fontweight="bold",
                path_effects=_outlined())
    ax.set_xlabel("camera pixel x", fontsize=7)
    ax.set_ylabel("camera pixel y", fontsize=7)
    ax.tick_params(labelsize=6)
    ax.set_title("reference, windows outlined and numbered", fontsize=7)


def _geometry(shape, side, ncols, nwin):
    """Inches of the crops figure: ``(width, height, cell, size, top columns, overview (w, h), grid height)``.

    A column of crops is ``cell`` wide (~3 screen pixels per camera pixel at 110 dpi, 1.5–2.4 in), its
    crop ``size`` = 0.8 ``cell`` square; the overview spans the first ``top`` columns of the band above
    the crops, the legend the others.
    """
    cols = max(ncols, 4)
    cell = float(np.clip(3 * side / 110, 1.5, 2.4))
    size = 0.8 * cell
    top = -(-cols // 2)
    h, w = shape[:2]
    ov_w = top * cell - 0.7  # the y label and tick labels on its left
    ov_h = ov_w * h / w
    band = max(0.25 + ov_h + 0.5, 1.6)  # its title above, the x label below; the legend's ~12 lines
    grid = nwin * (2 * size + sum(TITLES) + ROW_GAP) - ROW_GAP
    return PAD + cols * cell + BARS, TOP + band + grid + 2 * PAD, cell, size, top, (ov_w, ov_h), grid


def crop_figure(title, kind, pictures, errors, windows, side, reference="reference"):
    """The crops figure (module docstring): overview, then per window pictures above signed errors."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    names = list(errors)
    shown_e = [e[r:r + side, c:c + side] for e in errors.values() for r, c, _ in windows]
    vmax = max([float(np.nanmax(np.abs(b))) for b in shown_e if np.any(np.isfinite(b))] + [1e-3])
    width, height, cell, size, top, (ov_w, ov_h), grid_h = _geometry(
        pictures["reference"].shape, side, 1 + len(names), len(windows))
    fig = plt.figure(figsize=(width, height))
    y_band = height - TOP  # the band's top, inches from the bottom
    _overview(fig.add_axes(((PAD + 0.6) / width, (y_band - 0.25 - ov_h) / height, ov_w / width, ov_h / height)),
              pictures["reference"], windows, side, kind)
    fig.text((PAD + top * cell + 0.1) / width, (y_band - 0.1) / height, _legend_text(kind, side, vmax, reference),
             va="top", ha="left", fontsize=7)
    ax = panel_axes(fig, (PAD, PAD, max(1 + len(names), 4) * cell, grid_h))
    err_kw = {"cmap": plt.get_cmap("RdBu_r").with_extremes(bad=MASK), "vmin": -vmax, "vmax": vmax}
    pic_kw = {"cmap": "magma", "vmin": 0, "vmax": 1} if kind == "scattering" else {}
    shown = err = None
    boxes = []
    x0 = (cell - size) / 2
    for i, (r, c, mean) in enumerate(windows):
        y_pic = i * (2 * size + sum(TITLES) + ROW_GAP) + TITLES[0]
        y_err = y_pic + size + TITLES[1]
        for j, (label, pic) in enumerate(pictures.items()):
            boxes.append((x0 + j * cell, y_pic, size, size))
            shown = panel(ax, pic[r:r + side, c:c + side], boxes[-1], f"{i + 1}: {label}", **pic_kw)
        ax.text(x0, y_err + 0.05, f"window {i + 1}\nx {c}–{c + side - 1}, y {r}–{r + side - 1}\nmean spread "
                f"{mean:.3g}\n\nbelow each: its\nsigned error e", va="top", ha="left", fontsize=7)
        for j, n in enumerate(names, 1):
            box = errors[n][r:r + side, c:c + side]
            big = float(np.nanmax(np.abs(box))) if np.any(np.isfinite(box)) else 0.0
            boxes.append((x0 + j * cell, y_err, size, size))
            err = panel(ax, box, boxes[-1], f"{n}: e\nmax |e| {big:.2g}", **err_kw)
    frames(ax, boxes)
    fig.suptitle(title, fontsize="medium", y=1 - 0.1 / height, va="top")
    # The bars right of the last column of crops (with fewer than four, the band above is wider).
    _bars(fig, kind, shown, err, ((PAD + (1 + len(names)) * cell + 0.1) / width, PAD / height, grid_h / height))
    return fig


def _bars(fig, kind, shown, err, where):
    """Colour bars right of the crops (``where``: their left edge, bottom and height as figure fractions): the
    signed error, and for scattering the term's values above it."""
    if err is None:
        return
    x, y0, span = where
    w = 0.15 / fig.get_figwidth()
    y1 = y0 + span
    if kind == "scattering" and shown is not None:
        mid = (y0 + y1) / 2
        fig.colorbar(shown, cax=fig.add_axes((x, mid + 0.01, w, y1 - mid - 0.01))).set_label(
            "scattering term / t_max (dimensionless)", fontsize=7)
        y1 = mid - 0.01
    fig.colorbar(err, cax=fig.add_axes((x, y0, w, y1 - y0))).set_label(f"signed error e ({_WORDS[kind][0]})",
                                                                      fontsize=7)


def crop_figures(result, groups):
    """``{crops_<scene>_<reference>.png: Figure}`` for each reference's techniques (``groups``: reference -> names).

    A group whose techniques all equal the reference everywhere has no window
    and no figure.
    """
    out = {}
    for ref_name, names in groups.items():
        kind, pictures, errors = _views(result, list(names))
        first = next(iter(pictures.values()))
        side = window_side((first.shape[1], first.shape[0]))
        windows = choose_windows(spread(errors.values()), side)
        if not windows:
            continue
        label = get_reference(ref_name).label
        title = f"{result.scene.name}: crops where the {label} differ most\n(against reference {ref_name})"
        out[f"crops_{result.scene.name}_{ref_name}.png"] = crop_figure(title, kind, pictures, errors, windows,
                                                                       side, ref_name)
    return out


def crop_lines(paths):
    """The section of report.md showing the crop figures and saying how their windows were chosen."""
    if not paths:
        return []
    lines = ["## Where the techniques differ most", "",
             f"Per scene and reference, up to {MAX_WINDOWS} windows of camera pixels ({WINDOW}×{WINDOW} at "
             f"{WINDOW_ROWS} camera rows, scaled with the camera's height) where the techniques' signed errors "
             "differ most: each pixel's spread of the errors (the largest minus the smallest of the techniques' "
             "signed errors and the reference's 0) is averaged over every window position (a box filter); the "
             "window with the largest mean is taken first, then the largest among those at least half a "
             f"window away from every chosen one and with at least {MIN_SHARE:.0%} of the first's mean "
             "(ties: the first in row-major order). They are outlined and numbered on the "
             "reference; each window shows the reference and every technique, nearest-neighbour magnified, "
             "above each technique's signed error on one colour scale per figure.", ""]
    for p in paths:
        lines += [f"![crops]({p})", ""]
    return lines
