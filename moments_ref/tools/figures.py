"""Data and images of the paper's figures, computed with the library.

One section per figure: ``figureN_data(...)`` returns the numbers (no plotting),
``write_figureN(out_dir)`` writes ``figureN.csv`` and ``figureN.png`` atomically
(matplotlib's Agg backend) and returns their paths. The command line
(``moments-ref figureN --out DIR``) and the notebooks only call these functions.

References
----------
.. [1] HPG17: Christoph Peters. 2017. *Non-Linearly Quantized Moment Shadow Maps*. In Proceedings
       of High Performance Graphics (HPG '17). ACM. The non-linear quantization Φ, Ψ4, Algorithms
       1–3, the texel formats and the compute shader of §4.1.
"""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np

from .._arrays import InputError
from .._io import save_figure, write_text
from ..nonlinear import shade

__all__ = ["figure3_data", "write_figure3", "FIGURE3_XI4", "figure4_data", "write_figure4", "FIGURE4_SIGMAS",
           "FIGURE4_BINS"]


# ---------------------------------------------------------------------------
# HPG17 Figure 3: lower bounds for y1 = -0.8, y2 = 0.4, v2 = 0.6 and various ξ4

#: The ξ4 values of the curves in HPG17 Figure 3.
FIGURE3_XI4 = (0.0, 1e-6, 1e-5, 1e-4, 1e-3, 1e-2)


def figure3_data(y1=-0.8, y2=0.4, v2=0.6, xi4_values=FIGURE3_XI4, n=1001):
    """The curves of HPG17 Figure 3: Algorithm 1's lower bound as a function of zf.

    Parameters
    ----------
    y1, y2, v2 : float
        The two-point part of the representation (HPG17: −0.8, 0.4, 0.6).
    xi4_values : sequence of float
        One curve per ξ4 ≥ 0.
    n : int
        Number of fragment depths, evenly spaced on [-1, 1].

    Returns
    -------
    zf : (n,) float64 array
    lower : (len(xi4_values), n) float64 array
        ``lower[i] = shade((y1, y2, v2, xi4_values[i]), zf)``, the sharp lower bound
        of Z(z < zf) (HPG17 Algorithm 3, equal to Algorithm 1 on Eq. (4)).

    Notes
    -----
    HPG17 §3.2: for ξ4 = 0 the bound is the exact two-step function with steps of
    height 1 − v2 at y1 and v2 at y2; as ξ4 grows "these steps become less steep
    and the lower bound decreases everywhere".

    Examples
    --------
    >>> zf, lower = figure3_data(xi4_values=(0.0,), n=5)
    >>> zf
    array([-1. , -0.5,  0. ,  0.5,  1. ])
    >>> lower.round(12) + 0.0
    array([[0. , 0.4, 0.4, 1. , 1. ]])
    """
    if int(n) != n or n < 2:
        raise InputError(f"n: expected an integer >= 2, got {n!r}")
    if not (-1 <= y1 < y2 <= 1 and 0 <= v2 <= 1):
        raise InputError(f"y1, y2, v2: expected -1 <= y1 < y2 <= 1 and v2 in [0, 1], got {y1}, {y2}, {v2}")
    xi = np.asarray(xi4_values, dtype=np.float64).reshape(-1)
    if xi.size == 0 or not np.all(np.isfinite(xi)) or np.any(xi < 0):
        raise InputError(f"xi4_values: expected a non-empty list of finite values >= 0, got {xi4_values!r}")
    zf = np.linspace(-1.0, 1.0, int(n))
    r = np.zeros((xi.size, 1, 4))
    r[..., 0], r[..., 1], r[..., 2], r[..., 3] = y1, y2, v2, xi[:, None]
    return zf, shade(r, zf[None, :])


def _format_xi(x):
    return "0" if x == 0 else f"{x:g}"


def write_figure3(out_dir, **kwargs):
    """Write HPG17 Figure 3 as ``figure3.csv`` and ``figure3.png`` in ``out_dir``.

    Parameters
    ----------
    out_dir : path
        Created if missing.
    **kwargs
        Passed to :func:`figure3_data`.

    Returns
    -------
    paths : tuple of Path
        ``(csv_path, png_path)``.

    Notes
    -----
    CSV columns: ``zf`` then one column per ξ4, named ``xi4=<value>``
    (``xi4=0``, ``xi4=1e-06``, ...), 17 significant digits. Both files are
    written atomically (temporary file, then rename).
    """
    zf, lower = figure3_data(**kwargs)
    xi = np.asarray(kwargs.get("xi4_values", FIGURE3_XI4), dtype=np.float64).reshape(-1)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    header = ",".join(["zf"] + [f"xi4={_format_xi(x)}" for x in xi])
    buf = io.StringIO()
    np.savetxt(buf, np.column_stack([zf, lower.T]), delimiter=",", fmt="%.17g", header=header, comments="")
    csv_path = write_text(out / "figure3.csv", buf.getvalue())

    # A bare Figure (no pyplot): rendered by Agg, leaves the user's backend alone.
    from matplotlib.figure import Figure

    fig = Figure(figsize=(6, 4), dpi=100)
    ax = fig.add_subplot()
    for x, curve in zip(xi, lower):
        ax.plot(zf, curve, label=f"ξ4 = {_format_xi(x)}")
    y1, y2, v2 = kwargs.get("y1", -0.8), kwargs.get("y2", 0.4), kwargs.get("v2", 0.6)
    ax.set_xlabel("fragment depth $z_f$")
    ax.set_ylabel("lower bound of $Z(z < z_f)$")
    ax.set_title(f"HPG17 Fig. 3: $y_1$ = {y1}, $y_2$ = {y2}, $v_2$ = {v2}")
    ax.set_xlim(-1, 1)
    ax.set_ylim(-0.02, 1.02)
    ax.legend(loc="upper left", fontsize="small")
    fig.tight_layout()
    png_path = save_figure(fig, out / "figure3.png")
    return Path(csv_path), Path(png_path)


# ---------------------------------------------------------------------------
# HPG17 Figure 4: histograms of ξ4 and Ψ4(ξ4) over a filtered shadow map

#: Standard deviations (texels) of the Gaussian filters of the histograms.
FIGURE4_SIGMAS = (1.0, 2.4, 4.0, 8.0)
#: Histogram bins (the 6-bit code of the 32-bit format has 64 values).
FIGURE4_BINS = 64


def _entropy_bits(counts):
    p = counts[counts > 0] / counts.sum()
    return float(-(p * np.log2(p)).sum()) + 0.0  # + 0.0: no '-0.00' for a single bin


def figure4_data(scene="railing", size=2048, samples=4, sigmas=FIGURE4_SIGMAS, bins=FIGURE4_BINS):
    """Histograms of ξ4 and Ψ4(ξ4) of a filtered moment shadow map (HPG17 Fig. 4, §3.3).

    Parameters
    ----------
    scene : str or path
        A shipped scene name or a scene file (its light's shadow map is used).
    size : int
        Shadow-map side (HPG17: 2048).
    samples : int
        MSAA samples per texel (HPG17: 4).
    sigmas : sequence of float
        Standard deviations of the Gaussian filters, in texels. The kernel has
        ``2·⌈3σ⌉ + 1`` taps (σ = 2.4 gives 17 taps here, not the shader's 9:
        the histograms should show the filter, not its truncation).
    bins : int
        Bins of each histogram.

    Returns
    -------
    dict
        ``xi4_edges`` (bins + 1, log-spaced from 1.2e-7 to 0.25, with values
        below the clamp counted in the first bin as in HPG17's cut-off left-most
        bar), ``psi4_edges`` (bins + 1 on [0, 1]), and per σ:
        ``xi4_counts[i]``, ``psi4_counts[i]``, ``linear_counts[i]`` (ξ4 in uniform
        bins on [0, 0.25], the 64-bit affine alternative), and the entropies in bits
        ``psi4_entropy``, ``linear_entropy`` against ``log2(bins)`` for a uniform
        histogram; ``below_clamp`` the share of texels with ξ4 < 1.2e-7;
        ``texels`` per σ.

    Notes
    -----
    The steps of §3.3: rasterize the scene from the light with MSAA, resolve to
    moments (:func:`~moments_ref.gpu.filtering.resolve_moments`), filter
    (:func:`~moments_ref.gpu.filtering.blur`), cast to float32 and bias with
    ``BIAS_FLOAT32``, Φ (:func:`~moments_ref.nonlinear.phi`) in float32, Ψ4. Texels
    that no geometry covers (depth 1 everywhere in the filter) are left out:
    they carry no information.
    """
    from ..gpu.filtering import blur, gaussian_weights, resolve_moments
    from ..moments import BIAS_FLOAT32, bias_moments
    from ..nonlinear import PSI4_XI_MAX, PSI4_XI_MIN, phi, psi4
    from ..scene.raster import rasterize_depth
    from ..scene import load_scene, merge

    sc = load_scene(scene)
    mesh, _ = merge([sc.receiver, sc.occluder_mesh(translucent=False)])
    depth, _ = rasterize_depth(mesh.vertices, mesh.triangles, sc.light_clip_from_world(), int(size),
                               samples=int(samples))
    moments = resolve_moments(depth)
    covered = (depth < 1).any(axis=-1)
    xi_edges = np.geomspace(PSI4_XI_MIN, PSI4_XI_MAX, bins + 1)
    psi_edges = np.linspace(0.0, 1.0, bins + 1)
    lin_edges = np.linspace(0.0, PSI4_XI_MAX, bins + 1)
    out = {"xi4_edges": xi_edges, "psi4_edges": psi_edges, "sigmas": np.asarray(sigmas, float),
           "xi4_counts": [], "psi4_counts": [], "linear_counts": [], "psi4_entropy": [],
           "linear_entropy": [], "below_clamp": [], "texels": [], "scene": sc.name, "size": int(size),
           "samples": int(samples), "uniform_entropy": float(np.log2(bins))}
    for sigma in sigmas:
        taps = 2 * int(np.ceil(3 * sigma)) + 1
        w = gaussian_weights(taps, sigma)
        filtered = blur(moments, w).astype(np.float32)
        keep = blur(covered[..., None].astype(np.float32), w)[..., 0] > 0
        r = phi(bias_moments(filtered[keep], BIAS_FLOAT32))
        xi4 = r[:, 3].astype(np.float64)
        xi_counts, _ = np.histogram(np.clip(xi4, PSI4_XI_MIN, PSI4_XI_MAX), xi_edges)
        psi_counts, _ = np.histogram(psi4(r[:, 3]), psi_edges)
        lin_counts, _ = np.histogram(np.clip(xi4, 0, PSI4_XI_MAX), lin_edges)
        out["xi4_counts"].append(xi_counts)
        out["psi4_counts"].append(psi_counts)
        out["linear_counts"].append(lin_counts)
        out["psi4_entropy"].append(_entropy_bits(psi_counts))
        out["linear_entropy"].append(_entropy_bits(lin_counts))
        out["below_clamp"].append(float((xi4 < PSI4_XI_MIN).mean()))
        out["texels"].append(int(keep.sum()))
    for k in ("xi4_counts", "psi4_counts", "linear_counts"):
        out[k] = np.array(out[k])
    return out


def write_figure4(out_dir, **kwargs):
    """Write HPG17 Figure 4 as ``figure4.csv``, ``figure4.png`` and ``figure4.md``.

    ``figure4.csv`` has one row per (σ, bin): ``sigma, bin, xi4_lo, xi4_hi,
    xi4_count, psi4_lo, psi4_hi, psi4_count, linear_count``; ``figure4.md``
    states the entropy of each 64-bin histogram against the uniform one
    (6 bits). Returns ``(csv_path, png_path, md_path)``; all written atomically.
    """
    d = figure4_data(**kwargs)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    nb = len(d["psi4_edges"]) - 1
    rows = []
    for i, s in enumerate(d["sigmas"]):
        for k in range(nb):
            rows.append([s, k, d["xi4_edges"][k], d["xi4_edges"][k + 1], d["xi4_counts"][i, k],
                         d["psi4_edges"][k], d["psi4_edges"][k + 1], d["psi4_counts"][i, k], d["linear_counts"][i, k]])
    buf = io.StringIO()
    np.savetxt(buf, np.array(rows, dtype=np.float64), delimiter=",", fmt="%.10g",
               header="sigma,bin,xi4_lo,xi4_hi,xi4_count,psi4_lo,psi4_hi,psi4_count,linear_count", comments="")
    csv_path = write_text(out / "figure4.csv", buf.getvalue())

    from matplotlib.figure import Figure

    fig = Figure(figsize=(10, 4), dpi=100)
    ax1, ax2 = fig.subplots(1, 2)
    centres = np.sqrt(d["xi4_edges"][:-1] * d["xi4_edges"][1:])
    for i, s in enumerate(d["sigmas"]):
        ax1.step(centres, d["xi4_counts"][i] / d["texels"][i], where="mid", label=f"σ = {s:g}")
        ax2.step(0.5 * (d["psi4_edges"][:-1] + d["psi4_edges"][1:]), d["psi4_counts"][i] / d["texels"][i],
                 where="mid", label=f"σ = {s:g} ({d['psi4_entropy'][i]:.2f} bits)")
    ax1.set_xscale("log")
    ax1.set_xlabel("ξ4 (clamped to [1.2e-7, 0.25])")
    ax1.set_ylabel("share of texels")
    ax1.set_title(f"ξ4, {d['scene']} {d['size']}² {d['samples']}× MSAA")
    ax2.set_xlabel("Ψ4(ξ4)")
    ax2.set_title(f"Ψ4(ξ4), 64 bins (uniform: {d['uniform_entropy']:.0f} bits)")
    for ax in (ax1, ax2):
        ax.legend(fontsize="small")
    fig.tight_layout()
    png_path = save_figure(fig, out / "figure4.png")

    lines = [f"# HPG17 Figure 4 on `{d['scene']}` ({d['size']}² shadow map, {d['samples']}× MSAA)", "",
             "Entropy of the 64-bin histograms in bits (a uniform histogram has "
             f"{d['uniform_entropy']:.0f} bits; the more, the better the 64 codes are used):", "",
             "| σ (texels) | texels | ξ4 < 1.2e-7 | Ψ4(ξ4) bins | ξ4 in uniform bins on [0, 0.25] |",
             "|---:|---:|---:|---:|---:|"]
    for i, s in enumerate(d["sigmas"]):
        lines.append(f"| {s:g} | {d['texels'][i]} | {100 * d['below_clamp'][i]:.1f}% | "
                     f"{d['psi4_entropy'][i]:.2f} | {d['linear_entropy'][i]:.2f} |")
    best = int(np.argmax(d["psi4_entropy"]))
    lines += ["", f"Ψ4 spreads ξ4 over the codes: {min(d['psi4_entropy']):.2f} to {max(d['psi4_entropy']):.2f} bits "
              f"of {d['uniform_entropy']:.0f} (σ = {d['sigmas'][best]:g} most uniform), against "
              f"{max(d['linear_entropy']):.2f} bits or less when ξ4 is quantized uniformly. As in HPG17 Fig. 4 "
              "the histograms are not uniform and differ between filter sizes, and small values dominate.", ""]
    md_path = write_text(out / "figure4.md", "\n".join(lines))
    return Path(csv_path), Path(png_path), Path(md_path)
