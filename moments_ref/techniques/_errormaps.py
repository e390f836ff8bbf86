"""Error maps of the report: the shaded reference, each technique's shaded image and its signed error.

Shared by the references whose values are shadow intensities of the receiver
pixels (``pcf``: :mod:`.references`, ``mvr``: :mod:`.area`). The signed error is
``e = shadow − reference`` (shadow intensity, 1 = fully shadowed): red where a
technique is darker than the reference (over-darkening), blue where it is
lighter (light leaking). One symmetric colour range for all panels of a figure,
chosen from the data: the largest 99th percentile of ``|e|`` over the
techniques (so that one technique with errors of 1 does not wash out the
others); each panel states its own largest ``|e|`` and the share of its pixels
beyond the range (drawn in the end colours, clipped). :data:`MASK` grey marks
pixels that are not receivers inside the shadow map (background, occluders,
receivers outside the light's map).

:func:`visibility_maps` draws the visibility ``1 − intensity`` of the reference
and each technique on a grey scale with its colour bar; there, pixels without
a value are :data:`VISIBILITY_MASK` (light blue, not a grey of the scale) and
occluders :data:`OCCLUDER_COLOUR` (orange).

References
----------
.. [1] HPG17: Christoph Peters. 2017. *Non-Linearly Quantized Moment Shadow Maps*. In Proceedings
       of High Performance Graphics (HPG '17). ACM. The non-linear quantization Φ, Ψ4, Algorithms
       1–3, the texel formats and the compute shader of §4.1.
"""

from __future__ import annotations

import numpy as np

from .._panels import frames, panel, panel_axes
from ..metrics import shaded_image

__all__ = ["MASK", "VISIBILITY_MASK", "OCCLUDER_COLOUR", "error_maps", "visibility_maps"]

#: Colour of the pixels without an error: not a receiver inside the shadow map.
MASK = (0.55, 0.55, 0.55)
#: Colour of the pixels without a visibility (background, receivers outside the light's map) on a grey scale.
VISIBILITY_MASK = (0.62, 0.78, 0.92)
#: Colour of the occluders on a grey scale of visibility.
OCCLUDER_COLOUR = (0.85, 0.55, 0.3)


def _range(errors):
    p = [np.percentile(np.abs(e[np.isfinite(e)]), 99) for e in errors if np.any(np.isfinite(e))]
    return max(max(p, default=0.0), 1e-3)


def _legend_text(reference, vmax):
    return (f"signed error e = technique − {reference}\n(shadow intensity, 1 = fully shadowed)\n"
            "red: darker than the reference\nblue: lighter (light leaks)\n"
            f"range ±{vmax:.3g}: the largest 99th\npercentile of |e|; beyond it clipped\n"
            "grey: no receiver inside the shadow\nmap (background, occluder, outside it)")


#: Layout of the error and visibility figures in inches (:mod:`moments_ref._panels`: the panels are
#: images in one Axes): a panel's title above it, the figure's title, the colour bar on the right.
TITLE, HEAD, BAR = 0.26, 0.62, 1.3


def _grid(ncols, nrows, aspect, pitch, below=0.0):
    """``(figure size, panel (w, h), slot(k) -> (x, y), grid (w, h))``: ``nrows × ncols`` panels ``pitch`` inches
    apart (``aspect`` = height / width), the grid ``0.1 + below`` inches above the figure's bottom."""
    pw = pitch - 0.2
    ph = pw * aspect
    gw, gh = ncols * pitch, nrows * (TITLE + ph) + (nrows - 1) * 0.1

    def slot(k):
        return (k % ncols) * pitch + 0.1, (k // ncols) * (TITLE + ph + 0.1) + TITLE

    return (0.1 + gw + BAR, HEAD + gh + 0.1 + below), (pw, ph), slot, (gw, gh)


def _bar_axes(fig, size, bottom, gw, gh):
    """The colour bar's Axes right of a grid ``gw × gh`` inches at ``bottom``: as tall as its panels (no title)."""
    fw, fh = size
    cax = fig.add_axes(((0.25 + gw) / fw, bottom / fh, 0.15 / fw, (gh - TITLE) / fh))
    cax.tick_params(labelsize=8)
    return cax


def error_maps(result, names, reference="reference", title=""):
    """Figure: the shaded reference, then per technique its shaded image and its signed error map."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    gb = result.gbuffer
    w, h = gb.resolution
    errors = [np.asarray(result.shadow[n], np.float64) - np.asarray(result.reference[n], np.float64) for n in names]
    vmax = _range(errors)
    cmap = plt.get_cmap("RdBu_r").with_extremes(bad=MASK)
    ncols = 4
    nrows = -(-(2 + 2 * len(names)) // ncols)
    size, (pw, ph), slot, (gw, gh) = _grid(ncols, nrows, h / w, 2.6)
    fig = plt.figure(figsize=size)
    ax = panel_axes(fig, (0.1, 0.1, gw, gh))
    boxes = [(*slot(0), pw, ph)]
    panel(ax, shaded_image(gb, result.reference[names[0]]), boxes[0], f"{reference} (shaded)")
    x, y = slot(1)
    ax.text(x, y - TITLE, _legend_text(reference, vmax), va="top", ha="left", fontsize=7)
    im = None
    for i, (n, e) in enumerate(zip(names, errors)):
        boxes += [(*slot(2 + 2 * i), pw, ph), (*slot(3 + 2 * i), pw, ph)]
        panel(ax, shaded_image(gb, result.shadow[n]), boxes[-2], f"{n} (shaded)")
        img = np.full(h * w, np.nan)
        img[gb.pixel] = e
        big = float(np.nanmax(np.abs(e))) if e.size else 0.0
        beyond = float(np.mean(np.abs(e) > vmax)) if e.size else 0.0
        im = panel(ax, img.reshape(h, w), boxes[-1], f"{n}: e, max |e| {big:.2g}, {beyond:.1%} clipped", cmap=cmap,
                   vmin=-vmax, vmax=vmax)
    frames(ax, boxes)  # a frame: a white floor (lit, or e = 0) reaches the edge
    fig.suptitle((title or f"{result.scene.name}: signed error against {reference}")
                 + f"\ncamera view, {w}×{h} pixels", fontsize="medium", y=1 - 0.08 / size[1], va="top")
    if im is not None:
        fig.colorbar(im, cax=_bar_axes(fig, size, 0.1, gw, gh)).set_label("signed error e\n(shadow intensity)",
                                                                          fontsize=8)
    return fig


def _visibility_rgb(gb, intensity, cmap):
    """(H, W, 3): ``cmap`` of ``1 − intensity`` on the receivers, the documented colours elsewhere."""
    from ..scene.gbuffer import OCCLUDER

    w, h = gb.resolution
    rgb = np.empty((h * w, 3))
    rgb[:] = VISIBILITY_MASK
    rgb[gb.kind.reshape(-1) == OCCLUDER] = OCCLUDER_COLOUR
    rgb[gb.pixel] = cmap(1.0 - np.clip(np.asarray(intensity, np.float64), 0, 1))[:, :3]
    return rgb.reshape(h, w, 3)


def visibility_maps(result, names, reference="reference", title=""):
    """Figure: the visibility ``1 − shadow intensity`` of the reference and of each technique, one grey scale.

    Receiver pixels inside the shadow map on the grey scale of the colour bar (0
    black = fully shadowed, 1 white = fully lit); occluders :data:`OCCLUDER_COLOUR`,
    other pixels :data:`VISIBILITY_MASK`, both named in the legend.
    """
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt
    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import Normalize
    from matplotlib.patches import Patch

    gb = result.gbuffer
    w, h = gb.resolution
    cmap = plt.get_cmap("gray")
    shown = [(reference, result.reference.get(names[0]))] + [(n, result.shadow[n]) for n in names]
    shown = [(t, v) for t, v in shown if v is not None]
    ncols = min(len(shown), 3)
    nrows = -(-len(shown) // ncols)
    size, (pw, ph), slot, (gw, gh) = _grid(ncols, nrows, h / w, 3.4, below=0.35)
    fig = plt.figure(figsize=size)
    ax = panel_axes(fig, (0.1, 0.45, gw, gh))
    boxes = [(*slot(k), pw, ph) for k in range(len(shown))]
    for box, (t, inten) in zip(boxes, shown):
        panel(ax, _visibility_rgb(gb, inten, cmap), box, t, fontsize="small")
    frames(ax, boxes)  # a frame: the lit floor is white up to the edge
    fig.suptitle((title or f"{result.scene.name}: visibility (camera view, {w}×{h} pixels)")
                 + "\nvisibility = 1 − shadow intensity", fontsize="medium", y=1 - 0.08 / size[1], va="top")
    fig.legend(handles=[Patch(color=OCCLUDER_COLOUR, label="occluder"),
                        Patch(color=VISIBILITY_MASK, label="no receiver inside the shadow map "
                              "(background, outside the light's map)")],
               loc="lower center", ncol=2, fontsize="small", frameon=False)
    fig.colorbar(ScalarMappable(Normalize(0, 1), cmap), cax=_bar_axes(fig, size, 0.45, gw, gh)).set_label(
        "visibility\n(1 = fully lit)", fontsize=8)
    return fig
