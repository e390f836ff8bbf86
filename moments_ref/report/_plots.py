"""The report's plot: error against run time (HPG17 Figure 10's split of texel and fragment cost).

References
----------
.. [1] HPG17: Christoph Peters. 2017. *Non-Linearly Quantized Moment Shadow Maps*. In Proceedings
       of High Performance Graphics (HPG '17). ACM. The non-linear quantization Φ, Ψ4, Algorithms
       1–3, the texel formats and the compute shader of §4.1.
"""

from __future__ import annotations

import numpy as np

__all__ = ["plot_error_vs_runtime"]


def plot_error_vs_runtime(rows, fig=None):
    """Scatter of RMSE against texel and fragment seconds (HPG17 Figure 10's split).

    Parameters
    ----------
    rows : list of dict (as :func:`read_results` returns)
    fig : matplotlib Figure, optional

    Returns
    -------
    fig : matplotlib Figure with two axes
    """
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    if fig is None:
        fig = plt.figure(figsize=(11, 4.5))
    axes = fig.subplots(1, 2, sharey=True)
    techs = list(dict.fromkeys(r["technique"] for r in rows))
    scenes = list(dict.fromkeys(r["scene"] for r in rows))
    cmap = plt.get_cmap("tab20")
    markers = "osD^v<>pP*hX"
    for ax, key, label in ((axes[0], "texel_seconds", "texel cost (s, NumPy)"),
                           (axes[1], "fragment_seconds", "fragment cost (s, NumPy)")):
        for r in rows:
            x = max(r[key], 1e-6)
            y = r["rmse"]
            if not np.isfinite(y):
                continue
            ax.scatter(x, max(y, 1e-6), color=cmap(techs.index(r["technique"]) % 20),
                       marker=markers[scenes.index(r["scene"]) % len(markers)], s=36)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel(label)
        ax.grid(True, which="both", alpha=0.3)
    axes[0].set_ylabel("RMSE of shadow intensity vs reference")
    handles = [plt.Line2D([], [], color=cmap(i % 20), marker="o", ls="", label=t) for i, t in enumerate(techs)]
    handles += [plt.Line2D([], [], color="k", marker=markers[i % len(markers)], ls="", label=s)
                for i, s in enumerate(scenes)]
    axes[1].legend(handles=handles, fontsize="x-small", loc="center left", bbox_to_anchor=(1.0, 0.5))
    fig.tight_layout()
    return fig


#: Figure titles per reference name (others: the reference's label).
TITLES = {"pcf": "hard shadows, error against the filtered hard shadow (9×9 Gaussian PCF)",
          "mvr": "soft shadows, error against multi-view rasterization (MVR)",
          "raymarch": "single scattering, error against converged ray marching"}


def _scale(values):
    """``(scale, kwargs)`` of an axis for non-negative ``values``: linear unless they span over a decade."""
    v = np.asarray([x for x in values if np.isfinite(x)], dtype=float)
    pos = v[v > 0]
    if len(pos) == 0 or pos.max() / pos.min() < 10:
        return "linear", {}
    if np.any(v == 0):  # a zero is drawn at zero: linear up to the decade below the smallest positive value
        # (a decade boundary, so that the ticks 0 and 10^k do not overlap)
        return "symlog", {"linthresh": float(10 ** np.floor(np.log10(pos.min()))), "linscale": 1.0}
    return "log", {}


def _front_2d(xs, ys):
    """Indices of the points no other beats in both x and y, by increasing x."""
    idx = sorted(range(len(xs)), key=lambda i: (xs[i], ys[i]))
    out, best = [], np.inf
    for i in idx:
        if ys[i] < best:
            out.append(i)
            best = ys[i]
    return out


_OFFSETS = ((4, 3, "left"), (4, -10, "left"), (-4, 3, "right"), (-4, -10, "right"), (4, 14, "left"),
            (4, -21, "left"), (-4, 14, "right"), (-4, -21, "right"))


def _labels(ax, points):
    """Name each point beside it, moving a label to a free side where it would cover another."""
    ax.autoscale_view()
    placed = []
    for x, y, text, color in points:
        px, py = ax.transData.transform((x, y))
        width = 5.5 * len(text)
        for dx, dy, ha in _OFFSETS:
            x0 = px + dx - (width if ha == "right" else 0)
            box = (x0, py + dy, x0 + width, py + dy + 9)
            if not any(box[0] < b[2] and b[0] < box[2] and box[1] < b[3] and b[1] < box[3] for b in placed):
                break
        placed.append(box)
        ax.annotate(text, (x, y), xytext=(dx, dy), textcoords="offset points", fontsize=7, color=color, ha=ha)


def _panel(ax, rows, key, label, colors):
    for axis, vals in (("x", [r[key] for r in rows]), ("y", [r["rmse"] for r in rows])):
        scale, kw = _scale(vals)
        (ax.set_xscale if axis == "x" else ax.set_yscale)(scale, **kw)
        if scale == "log":  # matplotlib labels every minor tick of a short log axis, and they overlap
            from matplotlib.ticker import FuncFormatter

            def _minor(v, _pos):
                m = v / 10 ** np.floor(np.log10(v))
                return f"{v:g}" if np.isclose(m, 2) or np.isclose(m, 5) else ""

            (ax.xaxis if axis == "x" else ax.yaxis).set_minor_formatter(FuncFormatter(_minor))
    scenes = list(dict.fromkeys(r["scene"] for r in rows))
    points = []
    for si, s in enumerate(scenes):
        rs = [r for r in rows if r["scene"] == s and np.isfinite(r["rmse"])]
        xs, ys = [r[key] for r in rs], [r["rmse"] for r in rs]
        c = colors[si % len(colors)]
        for r, x, y in zip(rs, xs, ys):
            lo, hi = r.get(f"{key}_min", x), r.get(f"{key}_max", x)
            if hi > lo:  # the spread of the timed repeats
                ax.errorbar(x, y, xerr=[[x - lo], [hi - x]], fmt="none", ecolor=c, elinewidth=1, capsize=2,
                            alpha=0.6, zorder=2)
            ax.scatter(x, y, s=40, color=c if r.get("pareto") else "white", edgecolors=c, zorder=3)
            points.append((x, y, r["technique"], c))
        f = _front_2d(xs, ys)
        if f:
            ax.step([xs[i] for i in f], [ys[i] for i in f], where="post", color=c, lw=1, alpha=0.6, label=s)
    ax.margins(x=0.1, y=0.06)  # room for the labels at the edges
    _labels(ax, points)
    ax.set_xlabel(label)
    ax.grid(True, which="both", alpha=0.3)


def plot_fronts(rows):
    """Per reference one figure ``front_<reference>.png``: the two two-objective fronts of each scene.

    Left: RMSE against bits per texel (memory, the papers' axis: hardware-independent).
    Right: RMSE against the total cost, texel + fragment seconds at the scene's own
    resolution (``own_total_seconds``, :mod:`._winners`), with the min–max of the
    timed repeats as horizontal bars. The line of each scene is its front in that
    plane (the winners of winners.csv are its steps). Filled markers: on the
    scene's three-objective front over (RMSE, texel, fragment), judged beyond the
    timing spread (:mod:`._pareto`); hollow: dominated there. Axes linear unless
    the data span over a decade (then log, or symlog with a zero drawn at zero).
    """
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    from ._pareto import truth_of

    colors = plt.get_cmap("tab10").colors
    out = {}
    for ref in dict.fromkeys(truth_of(r) for r in rows):
        rs = [r for r in rows if truth_of(r) == ref]
        fig, axes = plt.subplots(1, 2, figsize=(12, 5), sharey=True)
        _panel(axes[0], rs, "bits_per_texel", "memory: bits per shadow-map texel (what the lookup reads)", colors)
        bits = sorted({float(r["bits_per_texel"]) for r in rs if float(r["bits_per_texel"]) > 0})
        if bits and bits[-1] / bits[0] >= 2:  # powers of two: a log2 axis with a tick at each storage size
            axes[0].set_xscale("log", base=2)
            axes[0].set_xticks(bits, [f"{b:g}" for b in bits])
            axes[0].minorticks_off()
        _panel(axes[1], rs, "own_total_seconds",
               "time: texel + fragment s at the scene's own resolution (NumPy, median)", colors)
        axes[0].set_ylabel("RMSE of the result against the reference")
        axes[1].legend(fontsize="small", loc="best")
        fig.suptitle(TITLES.get(ref, ref) + "\nline: each scene's front in the plane (the lowest RMSE within a "
                     "budget); bars: min–max of the timed repeats\nfilled: on the scene's front over (RMSE, texel, "
                     "fragment) beyond the timing spread; hollow: dominated there", fontsize="medium")
        fig.tight_layout()
        out[f"front_{ref}.png"] = fig
    return out
