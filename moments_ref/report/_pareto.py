"""Which technique wins, and at what cost: the Pareto front over (RMSE, texel cost, fragment cost).

Each (scene, reference) has its own front: errors against different references
(the filtered hard shadow, MVR, ray marching) are not compared with each other.
The costs are timed repeats with a spread (``texel_seconds`` and
``fragment_seconds`` are medians, ``_min`` and ``_max`` their fastest and
slowest repeat), and a technique should not leave the front because of timing
noise. So dominance compares a cost only beyond its spread:

Row ``j`` **dominates** row ``i`` when, in every coordinate, ``j`` is no worse:

* RMSE (measured exactly): ``rmse_j ≤ rmse_i``;
* each cost ``c`` (texel, fragment): ``c_max_j ≤ c_min_i`` (``j``'s slowest repeat
  no slower than ``i``'s fastest), or both have the same median, min and max
  (the same stages, timed once and charged to both);

and in one coordinate strictly better: ``rmse_j < rmse_i`` or
``c_max_j < c_min_i``. A row no other row dominates is on the front. Costs whose
spreads overlap count as a tie, so a technique whose median is slower than
another's only within the spread stays on the front: the noise-aware front
holds every row of the front of the medians and possibly more. With one repeat
(min = median = max) it is the usual Pareto front of the medians. The relation
is a strict partial order (irreflexive, transitive), so every dominated row is
dominated by a row on the front, and the front of a non-empty group is not
empty. A row with a NaN coordinate is neither on the front nor dominates.
"""

from __future__ import annotations

import math

import numpy as np

from .._arrays import InputError
from .. import techniques as _techniques

__all__ = ["pareto_mask", "dominates", "mark_pareto", "groups", "front_lines", "summary_lines", "KEYS", "SPREAD",
           "FRONT_RULE"]

#: The coordinates of the front, each minimized.
KEYS = ("rmse", "texel_seconds", "fragment_seconds")
#: The spread columns of each coordinate (RMSE is exact: none).
SPREAD = {"texel_seconds": ("texel_seconds_min", "texel_seconds_max"),
          "fragment_seconds": ("fragment_seconds_min", "fragment_seconds_max")}


def _intervals(points, low, high):
    p = np.asarray(points, dtype=float).reshape(len(points), -1)
    lo = p if low is None else np.asarray(low, dtype=float).reshape(p.shape)
    hi = p if high is None else np.asarray(high, dtype=float).reshape(p.shape)
    bad = np.argwhere((lo > p) | (p > hi))
    if len(bad):
        i, k = bad[0]
        raise InputError(f"points: expected low <= points <= high, got low {lo[i, k]}, point {p[i, k]}, "
                         f"high {hi[i, k]} at index ({i}, {k})")
    return p, lo, hi


def dominates(points, low=None, high=None):
    """``d[j, i]``: row ``j`` dominates row ``i`` beyond the spreads (see the module docstring).

    ``points`` (n, d): the medians (or exact values); ``low``, ``high`` (n, d):
    the spread of each (default: the points, no spread). NaN rows dominate
    nothing and are dominated by nothing.
    """
    p, lo, hi = _intervals(points, low, high)
    same = (p[:, None] == p[None]) & (lo[:, None] == lo[None]) & (hi[:, None] == hi[None])
    below = hi[:, None] <= lo[None]  # below[j, i, k]: j's slowest no slower than i's fastest
    strict = hi[:, None] < lo[None]
    d = np.all(below | same, axis=2) & np.any(strict, axis=2)
    ok = np.all(np.isfinite(np.stack([p, lo, hi])), axis=(0, 2))
    return d & ok[:, None] & ok[None, :]


def pareto_mask(points, low=None, high=None):
    """True for the rows of ``points`` (n, d) no other row dominates; NaN rows False.

    Without ``low`` and ``high``: the usual front (no other row ≤ in every
    coordinate and < in one). With them (n, d, the spread of each coordinate):
    dominance beyond the spread, :func:`dominates`.
    """
    if len(points) == 0:
        return np.zeros(0, dtype=bool)
    p, lo, hi = _intervals(points, low, high)
    ok = np.all(np.isfinite(np.stack([p, lo, hi])), axis=(0, 2))
    return ok & ~np.any(dominates(p, lo, hi), axis=0)


def truth_of(row):
    """The reference name a row's error is measured against."""
    return _techniques.get(row["technique"]).truth


def groups(rows):
    """``{(scene, reference): [row indices]}`` in row order."""
    out = {}
    for i, r in enumerate(rows):
        out.setdefault((r["scene"], truth_of(r)), []).append(i)
    return out


def _spread(rows):
    """``(points, low, high)`` (n, 3) of ``rows``: the medians and each cost's ``_min``/``_max`` (if given)."""
    p = [[r[k] for k in KEYS] for r in rows]
    lo = [[r.get(SPREAD[k][0], r[k]) if k in SPREAD else r[k] for k in KEYS] for r in rows]
    hi = [[r.get(SPREAD[k][1], r[k]) if k in SPREAD else r[k] for k in KEYS] for r in rows]
    return p, lo, hi


def mark_pareto(rows):
    """Set ``row["pareto"]`` (bool) on every row, per (scene, reference), beyond the timing spread; return ``rows``.

    Rows without ``_min``/``_max`` columns count as timed without spread.
    """
    for idx in groups(rows).values():
        mask = pareto_mask(*_spread([rows[i] for i in idx]))
        for i, m in zip(idx, mask):
            rows[i]["pareto"] = bool(m)
    return rows


def _g(v):
    return "nan" if isinstance(v, float) and math.isnan(v) else f"{v:.3g}"


def _cost(r, k):
    """``median (min–max)`` of cost ``k`` of row ``r`` (the median alone without a spread)."""
    lo, hi = (r.get(c, r[k]) for c in SPREAD[k])
    return _g(r[k]) if lo == hi else f"{_g(r[k])} ({_g(lo)}–{_g(hi)})"


def _dominator(i, rs, d, front=True):
    """The row dominating row ``i`` of ``rs`` with the smallest RMSE, compared (``d``: :func:`dominates`).

    ``front``: only rows on the front (``pareto``) count.
    """
    better = [j for j in np.flatnonzero(d[:, i]) if rs[j].get("pareto") or not front]
    if not better:
        return ""
    f = rs[min(better, key=lambda j: (rs[j]["rmse"], rs[j]["texel_seconds"] + rs[j]["fragment_seconds"]))]
    r = rs[i]
    parts = [f"RMSE {_g(r['rmse'])} vs {_g(f['rmse'])}"]
    parts += [f"{label} {_cost(r, k)} vs {_cost(f, k)}" for k, label in zip(KEYS[1:], ("texel", "fragment"))]
    return f"{f['technique']} ({', '.join(parts)})"


def _beaten_by(i, rs, d, medians):
    """The last cell of a front table's row: who beats a dominated row; who beats a front row on the medians only."""
    if not rs[i].get("pareto"):
        return _dominator(i, rs, d) or "—"
    who = _dominator(i, rs, medians, front=False)
    return f"on the medians only (within the spread): {who}" if who else ""


#: The caption of the front tables (report.md) and of ``pareto`` (results.csv).
FRONT_RULE = ("A technique is beaten (dominated) by another of the same scene and reference whose RMSE is no "
              "larger and whose texel and fragment costs are each no slower beyond the timing spread (its "
              "slowest repeat, `_max`, no slower than this one's fastest, `_min`; the same stages timed once "
              "and charged to both count as equal), and which is better in one of the three beyond the "
              "spread (lower RMSE, or `_max` below this one's `_min`). Costs whose min–max spreads overlap "
              "are a tie, so timing noise does not take a technique off the front; with one repeat this is "
              "the usual Pareto front of the medians.")


def front_lines(rows):
    """The "Pareto front" section of report.md: per scene and reference, every row, winners first."""
    lines = ["## Pareto front", "",
             "Per scene and reference, the techniques no other one beats in RMSE, texel cost and fragment "
             "cost together (`pareto` in results.csv), ordered by texel cost: going down the front, each "
             "buys a lower error with more time. Below them the dominated techniques with the front "
             "technique that beats them and by how much; for a technique on the front, the one that would "
             "beat it on the medians alone, where one would (it is ahead only within the timing spread). "
             + FRONT_RULE + " Costs in seconds: the median of the timed repeats (min–max).", ""]
    for (scene, ref), idx in groups(rows).items():
        rs = [rows[i] for i in idx]
        p, lo, hi = _spread(rs)
        d, medians = dominates(p, lo, hi), dominates(p)
        front = sorted((i for i, r in enumerate(rs) if r.get("pareto")),
                       key=lambda i: (rs[i]["texel_seconds"], rs[i]["rmse"]))
        order = front + [i for i, r in enumerate(rs) if not r.get("pareto")]
        lines += [f"**{scene}**, {_techniques.get_reference(ref).label} (reference `{ref}`)", "",
                  "| technique | front | RMSE | texel s | fragment s | beaten by |", "|---|---|---|---|---|---|"]
        for i in order:
            r = rs[i]
            on = bool(r.get("pareto"))
            name = f"**{r['technique']}**" if on else r["technique"]
            cell = _beaten_by(i, rs, d, medians)
            lines.append(f"| {name} | {'yes' if on else 'no'} | {_g(r['rmse'])} | {_cost(r, 'texel_seconds')} | "
                         f"{_cost(r, 'fragment_seconds')} |" + (f" {cell}" if cell else "") + " |")
        lines.append("")
    return lines


def _best(values):
    finite = [v for v in values if v is not None and np.isfinite(v)]
    return min(finite) if finite else None


def summary_lines(rows):
    """Cross-scene summary: per reference a technique × scene table of RMSE and cost, best per column bold."""
    lines = ["## Summary across scenes", "",
             "RMSE and cost (texel + fragment seconds, medians) of each technique on each scene, one table per "
             "reference; the best of each column in bold, — where the technique did not run.", ""]
    refs = list(dict.fromkeys(truth_of(r) for r in rows))
    for ref in refs:
        rs = [r for r in rows if truth_of(r) == ref]
        scenes = list(dict.fromkeys(r["scene"] for r in rs))
        techs = list(dict.fromkeys(r["technique"] for r in rs))
        cell = {(r["technique"], r["scene"]): r for r in rs}
        cost = {k: r["texel_seconds"] + r["fragment_seconds"] for k, r in cell.items()}
        best_e = {s: _best([cell[(t, s)]["rmse"] for t in techs if (t, s) in cell]) for s in scenes}
        best_c = {s: _best([cost[(t, s)] for t in techs if (t, s) in cell]) for s in scenes}
        lines += [f"**{_techniques.get_reference(ref).label}** (reference `{ref}`)", "",
                  "| technique | " + " | ".join(f"{s} RMSE | {s} cost s" for s in scenes) + " |",
                  "|---|" + "---|---|" * len(scenes)]
        for t in techs:
            cells = []
            for s in scenes:
                if (t, s) not in cell:
                    cells += ["—", "—"]
                    continue
                e, c = cell[(t, s)]["rmse"], cost[(t, s)]
                cells += [f"**{_g(e)}**" if e == best_e[s] else _g(e), f"**{_g(c)}**" if c == best_c[s] else _g(c)]
            lines.append(f"| {t} | " + " | ".join(cells) + " |")
        lines.append("")
    return lines
