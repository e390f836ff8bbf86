"""Data and images of the paper's figures, computed with the library.

One section per figure: ``figureN_data(...)`` returns the numbers (no plotting),
``write_figureN(out_dir)`` writes ``figureN.csv`` and ``figureN.png`` atomically
(matplotlib's Agg backend) and returns their paths. The command line
(``moments-ref figureN --out DIR``) and the notebooks only call these functions.
"""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np

from ._arrays import InputError
from ._io import save_figure, write_text
from .nonlinear import shade

__all__ = ["figure3_data", "write_figure3", "FIGURE3_XI4"]


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
