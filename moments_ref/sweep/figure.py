"""Histograms of what the sweep's samplers draw (docs/sweep.md's figure).

``python -m moments_ref.sweep.figure --out docs/sweep_samplers.png [--rows N]`` draws
chunk 0 of ``shade-float32`` (seed 0) and plots the depths, the receivers' distance to
the nearest depth, the smallest weight of a texel, the spread of clusters, v2 of the
representation and the rows per stratum.
"""

from __future__ import annotations

import argparse

import numpy as np

from .._io import figure_png, write_bytes
from .samplers import CHUNK, STRATA, TEXELS, build_inputs, draw_rows

__all__ = ["sampler_figure", "main"]


def sampler_figure(rows=CHUNK, seed=0):
    """A matplotlib figure of chunk 0's draw for ``shade-float32``: six histograms."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ..golden import CASES

    case = CASES["shade-float32"]
    p = draw_rows(case, seed, 0, rows)
    r = build_inputs(case, p)["r"].astype(np.float64)
    used = p["w"] > 0
    texel = p["stratum"] // 3
    receiver = p["stratum"] % 3
    fig, ax = plt.subplots(2, 3, figsize=(12, 6.5))
    ax[0, 0].hist(p["z"][used], bins=200, color="0.3")
    ax[0, 0].set(title="depths z_i (weight > 0)", xlabel="z", yscale="log")
    dist = np.min(np.where(used, np.abs(p["z"] - p["zf"][:, None]), np.inf), axis=1)
    for k, name in enumerate(("uniform", "near", "end")):
        d = dist[receiver == k]
        ax[0, 1].hist(np.log10(np.maximum(d, 1e-12)), bins=120, histtype="step", label=name)
    ax[0, 1].set(title="log10 |zf − nearest depth| (0 → 1e-12)", xlabel="log10 distance")
    ax[0, 1].legend()
    wmin = np.min(np.where(used, p["w"], np.inf), axis=1)
    ax[0, 2].hist(np.log10(wmin[texel > 0]), bins=120, color="0.3")
    ax[0, 2].set(title="log10 smallest weight (≥ 2 depths)", xlabel="log10 w")
    cl = texel == TEXELS.index("cluster")
    z3, u3 = p["z"][cl, :3], used[cl, :3]
    spread = np.max(np.where(u3, z3, -np.inf), axis=1) - np.min(np.where(u3, z3, np.inf), axis=1)
    ax[1, 0].hist(np.log10(spread[spread > 0]), bins=100, color="0.3")
    ax[1, 0].set(title="cluster: log10 spread of the first cluster", xlabel="log10 spread")
    v2 = r[:, 2]
    ax[1, 1].hist(np.log10(np.maximum(np.minimum(v2, 1 - v2), 1e-12)), bins=120, color="0.3")
    ax[1, 1].set(title="shade: log10 min(v2, 1 − v2)", xlabel="log10")
    ax[1, 2].barh(range(len(STRATA)), np.bincount(p["stratum"], minlength=len(STRATA)), color="0.3")
    ax[1, 2].set(yticks=range(len(STRATA)), yticklabels=STRATA, title="rows per stratum")
    fig.suptitle(f"What the sweep draws: chunk 0 of shade-float32, seed {seed}, {rows} rows")
    fig.tight_layout()
    return fig


def main(argv=None):
    ap = argparse.ArgumentParser(prog="python -m moments_ref.sweep.figure", description=__doc__.splitlines()[0])
    ap.add_argument("--out", required=True, help="PNG file to write")
    ap.add_argument("--rows", type=int, default=CHUNK)
    args = ap.parse_args(argv)
    path = write_bytes(args.out, figure_png(sampler_figure(args.rows)))
    print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
