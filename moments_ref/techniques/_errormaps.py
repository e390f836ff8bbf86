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

from .._io import tight_layout
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


def _legend(ax, reference, vmax):
    ax.axis("off")
    ax.text(0.02, 1.0, f"signed error e = technique − {reference}\n(shadow intensity, 1 = fully shadowed)\n"
            "red: darker than the reference\nblue: lighter (light leaks)\n"
            f"range ±{vmax:.3g}: the largest 99th\npercentile of |e|; beyond it clipped\n"
            "grey: no receiver inside the shadow\nmap (background, occluder, outside it)",
            va="top", fontsize=7, transform=ax.transAxes)


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
    slots = 2 + 2 * len(names)
    ncols = 4
    nrows = -(-slots // ncols)
    fig, axes = plt.subplots(nrows, ncols, figsize=(2.6 * ncols + 1.0, 2.6 * nrows * h / w + 0.9), squeeze=False)
    ax = axes.ravel()
    for a in ax:
        a.axis("off")
    ax[0].imshow(shaded_image(gb, result.reference[names[0]]), interpolation="nearest")
    ax[0].set_title(f"{reference} (shaded)", fontsize=7)
    _legend(ax[1], reference, vmax)
    im = None
    for i, (n, e) in enumerate(zip(names, errors)):
        ax[2 + 2 * i].imshow(shaded_image(gb, result.shadow[n]), interpolation="nearest")
        ax[2 + 2 * i].set_title(f"{n} (shaded)", fontsize=7)
        img = np.full(h * w, np.nan)
        img[gb.pixel] = e
        im = ax[3 + 2 * i].imshow(img.reshape(h, w), cmap=cmap, vmin=-vmax, vmax=vmax, interpolation="nearest")
        big = float(np.nanmax(np.abs(e))) if e.size else 0.0
        beyond = float(np.mean(np.abs(e) > vmax)) if e.size else 0.0
        ax[3 + 2 * i].set_title(f"{n}: e, max |e| {big:.2g}, {beyond:.1%} clipped", fontsize=7)
    for a in ax:
        if a.get_images():  # a frame: a white floor (lit, or e = 0) reaches the edge
            a.axis("on")
            a.set_xticks([])
            a.set_yticks([])
    fig.suptitle((title or f"{result.scene.name}: signed error against {reference}")
                 + f"\ncamera view, {w}×{h} pixels", fontsize="medium")
    tight_layout(fig, rect=(0, 0, 0.86, 1))
    if im is not None:
        cax = fig.add_axes((0.88, 0.15, 0.015, 0.7))
        fig.colorbar(im, cax=cax).set_label("signed error e (shadow intensity)", fontsize=8)
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
    panels = [(reference, result.reference.get(names[0]))] + [(n, result.shadow[n]) for n in names]
    panels = [(t, v) for t, v in panels if v is not None]
    ncols = min(len(panels), 3)
    nrows = -(-len(panels) // ncols)
    fig, axes = plt.subplots(nrows, ncols, figsize=(3.4 * ncols + 1.2, 3.4 * nrows * h / w + 1.3), squeeze=False)
    for ax in axes.ravel():
        ax.axis("off")
    for ax, (t, inten) in zip(axes.ravel(), panels):
        ax.axis("on")  # a frame: the lit floor is white up to the edge
        ax.set(xticks=[], yticks=[])
        ax.imshow(_visibility_rgb(gb, inten, cmap), interpolation="nearest")
        ax.set_title(t, fontsize="small")
    fig.suptitle((title or f"{result.scene.name}: visibility (camera view, {w}×{h} pixels)")
                 + "\nvisibility = 1 − shadow intensity", fontsize="medium")
    fig.legend(handles=[Patch(color=OCCLUDER_COLOUR, label="occluder"),
                        Patch(color=VISIBILITY_MASK, label="no receiver inside the shadow map "
                              "(background, outside the light's map)")],
               loc="lower center", ncol=2, fontsize="small", frameon=False)
    tight_layout(fig, rect=(0, 0.05, 0.88, 1))
    cax = fig.add_axes((0.9, 0.2, 0.015, 0.6))
    fig.colorbar(ScalarMappable(Normalize(0, 1), cmap), cax=cax).set_label("visibility (1 = fully lit)", fontsize=8)
    return fig
