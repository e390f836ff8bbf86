"""Which technique wins, and at what cost: the Pareto front over (RMSE, texel cost, fragment cost).

A technique is on the front of its scene when no other technique of the same
scene measured against the same reference is at least as good in all three
(RMSE, ``texel_seconds``, ``fragment_seconds``) and better in one. Errors against
different references (the filtered hard shadow, MVR, ray marching) are not
compared with each other: each (scene, reference) has its own front. A row with
a NaN coordinate is neither on the front nor dominates.
"""

from __future__ import annotations

import math

import numpy as np

from .. import techniques as _techniques

__all__ = ["pareto_mask", "mark_pareto", "groups", "front_lines", "summary_lines", "KEYS"]

#: The coordinates of the front, each minimized.
KEYS = ("rmse", "texel_seconds", "fragment_seconds")


def pareto_mask(points):
    """True for the rows of ``points`` (n, d) that no other row dominates (all ≤, one <); NaN rows False."""
    p = np.asarray(points, dtype=float).reshape(len(points), -1)
    ok = np.all(np.isfinite(p), axis=1)
    out = np.zeros(len(p), dtype=bool)
    q = p[ok]
    if len(q):
        le = np.all(q[:, None, :] <= q[None, :, :], axis=2)  # le[j, i]: j ≤ i everywhere
        lt = np.any(q[:, None, :] < q[None, :, :], axis=2)
        out[np.flatnonzero(ok)] = ~np.any(le & lt, axis=0)
    return out


def truth_of(row):
    """The reference name a row's error is measured against."""
    return _techniques.get(row["technique"]).truth


def groups(rows):
    """``{(scene, reference): [row indices]}`` in row order."""
    out = {}
    for i, r in enumerate(rows):
        out.setdefault((r["scene"], truth_of(r)), []).append(i)
    return out


def mark_pareto(rows):
    """Set ``row["pareto"]`` (bool) on every row, per (scene, reference); return ``rows``."""
    for idx in groups(rows).values():
        mask = pareto_mask([[rows[i][k] for k in KEYS] for i in idx])
        for i, m in zip(idx, mask):
            rows[i]["pareto"] = bool(m)
    return rows


def _g(v):
    return "nan" if isinstance(v, float) and math.isnan(v) else f"{v:.3g}"


def _dominator(r, front):
    """The front row dominating ``r`` with the smallest RMSE, and the ratios."""
    better = [f for f in front if all(f[k] <= r[k] for k in KEYS)]
    if not better or not all(np.isfinite([r[k] for k in KEYS])):
        return "—"
    f = min(better, key=lambda x: (x["rmse"], x["texel_seconds"] + x["fragment_seconds"]))
    parts = []
    for k, label in zip(KEYS, ("RMSE", "texel", "fragment")):
        parts.append(f"{label} {_g(r[k])} vs {_g(f[k])}")
    return f"{f['technique']} ({', '.join(parts)})"


def front_lines(rows):
    """The "Pareto front" section of report.md: per scene and reference, every row, winners first."""
    lines = ["## Pareto front", "",
             "Per scene and reference, the techniques no other one beats in RMSE, texel cost and fragment "
             "cost together (`pareto` in results.csv), ordered by texel cost: going down the front, each "
             "buys a lower error with more time. Below them the dominated techniques with the front "
             "technique that beats them in all three and by how much. Costs are medians of the timed "
             "repeats in seconds.", ""]
    for (scene, ref), idx in groups(rows).items():
        rs = [rows[i] for i in idx]
        front = sorted((r for r in rs if r.get("pareto")), key=lambda r: (r["texel_seconds"], r["rmse"]))
        rest = [r for r in rs if not r.get("pareto")]
        lines += [f"**{scene}**, {_techniques.get_reference(ref).label} (reference `{ref}`)", "",
                  "| technique | front | RMSE | texel s | fragment s | beaten by |", "|---|---|---|---|---|---|"]
        for r in front:
            lines.append(f"| **{r['technique']}** | yes | {_g(r['rmse'])} | {_g(r['texel_seconds'])} | "
                         f"{_g(r['fragment_seconds'])} | |")
        for r in rest:
            lines.append(f"| {r['technique']} | no | {_g(r['rmse'])} | {_g(r['texel_seconds'])} | "
                         f"{_g(r['fragment_seconds'])} | {_dominator(r, front)} |")
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
