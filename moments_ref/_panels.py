"""Grids of image panels drawn into one matplotlib Axes whose data unit is the inch.

A figure of many small images, one Axes each (``plt.subplots``) fitted by a tight layout,
spends most of its time creating the Axes (their spines, ticks and tick locators) and
measuring every title with the renderer: the report's crops and error-map figures did (2.2 s
of CPU for the eight crops figures of the default report, 0.5 s in one Axes). Here the panels
are images placed in inches in a single frameless Axes, their titles texts above them and
their frames one collection: the same pictures in a fixed layout, which the figure's
code computes from the panel sizes.
"""

from __future__ import annotations

__all__ = ["panel_axes", "panel", "frames"]


def panel_axes(fig, box):
    """A frameless Axes at ``box = (left, bottom, width, height)`` inches of ``fig``.

    Its data unit is the inch, measured from its top-left corner (y downwards), so a panel at
    ``(x, y, w, h)`` is drawn ``x`` inches right of the Axes' left edge and ``y`` below its top.
    """
    fw, fh = fig.get_size_inches()
    left, bottom, width, height = box
    ax = fig.add_axes((left / fw, bottom / fh, width / fw, height / fh))
    ax.set_axis_off()
    ax.set_xlim(0, width)
    ax.set_ylim(height, 0)
    ax.set_autoscale_on(False)  # an image placed by its extent does not move the limits
    return ax


def panel(ax, img, box, title=None, fontsize=7, **imshow_kw):
    """``img`` (nearest-neighbour) filling ``box = (x, y, width, height)`` inches of ``ax``, ``title`` above it.

    Returns the ``AxesImage`` (for a colour bar).
    """
    x, y, w, h = box
    im = ax.imshow(img, interpolation="nearest", extent=(x, x + w, y + h, y), aspect="auto", **imshow_kw)
    if title:
        ax.text(x + w / 2, y - 0.04, title, ha="center", va="bottom", fontsize=fontsize)
    return im


def frames(ax, boxes, linewidth=0.8):
    """A black frame around each ``(x, y, width, height)`` of ``boxes``, as one collection (not clipped)."""
    from matplotlib.collections import PatchCollection
    from matplotlib.patches import Rectangle

    ax.add_collection(PatchCollection([Rectangle((x, y), w, h) for x, y, w, h in boxes], facecolor="none",
                                      edgecolor="black", linewidth=linewidth, clip_on=False))
