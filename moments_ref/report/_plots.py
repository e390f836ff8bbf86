"""The report's plot: error against run time (HPG17 Figure 10's split of texel and fragment cost).

References
----------
HPG17 : see docs/bib.md.
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
