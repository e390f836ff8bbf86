"""The decisive answer: per scene and reference, the technique with the lowest RMSE at each budget.

Two budgets matter to someone choosing a shadow technique, and each is one axis
of a two-objective front:

* **memory**: bits per texel of the filtered shadow map, the papers' headline
  axis (HPG17 compares 32-, 64- and 128-bit techniques). At each budget of
  :data:`MEMORY_BUDGETS` the winner is the technique of lowest RMSE among those
  storing at most that many bits per texel.
* **time**: the total cost, texel plus fragment seconds (medians of the timed
  repeats), at the scene's own shadow-map size and camera resolution
  (:func:`own_total`). The budgets are the steps of the front of (total cost,
  RMSE): every cost at which a more accurate technique becomes affordable.
  Below the first step nothing fits.

A tie in RMSE goes to the cheaper technique (fewer bits, lower cost), then to
the name. Rows without a finite RMSE or cost take no part.

References
----------
.. [1] HPG17: Christoph Peters. 2017. *Non-Linearly Quantized Moment Shadow Maps*. In Proceedings
       of High Performance Graphics (HPG '17). ACM. The non-linear quantization Φ, Ψ4, Algorithms
       1–3, the texel formats and the compute shader of §4.1.
"""

from __future__ import annotations

import csv
import io
import math

__all__ = ["MEMORY_BUDGETS", "WINNER_COLUMNS", "own_scale", "own_total", "winners", "winner_lines", "winners_csv"]

#: Bits per texel of the memory budgets (HPG17's 32-, 64- and 128-bit techniques).
MEMORY_BUDGETS = (32, 64, 128)
#: Columns of ``winners.csv``.
WINNER_COLUMNS = ("scene", "reference", "budget_kind", "budget", "technique", "rmse")


def own_scale(settings):
    """``(texel factor, fragment factor)`` from a run's sizes to the scene's own.

    ``settings``: the report's per-scene settings (``size``, ``resolution`` and
    ``own`` = (size, msaa, resolution)). Texel stages are taken to grow linearly
    with the shadow map's texels and fragment stages with the camera's pixels
    (``moments-ref bench`` measures that growth); a ``--full`` run has factors 1.
    """
    (h, w), (rw, rh) = settings["size"], settings["resolution"]
    (oh, ow), _, (orw, orh) = settings["own"]
    return (oh * ow) / (h * w), (orw * orh) / (rw * rh)


def own_total(row, scale, suffix=""):
    """Texel + fragment seconds of ``row`` at the scene's own resolution (``suffix`` ``_min``/``_max`` for the spread)."""
    ft, ff = scale
    return ft * float(row[f"texel_seconds{suffix}"]) + ff * float(row[f"fragment_seconds{suffix}"])


def _key(r):
    return r["reference"], r["scene"]


def _ok(x):
    return x is not None and math.isfinite(float(x))


def winners(rows, reference_of):
    """One dict per (scene, reference, budget): :data:`WINNER_COLUMNS`.

    ``rows``: results rows with ``rmse``, ``bits_per_texel`` and ``own_total_seconds``;
    ``reference_of(row)``: the name of the reference the row's RMSE is measured against.
    """
    groups = {}
    for r in rows:
        groups.setdefault((reference_of(r), r["scene"]), []).append(r)
    out = []
    for (ref, scene), rs in groups.items():
        rs = [r for r in rs if _ok(r.get("rmse")) and _ok(r.get("own_total_seconds"))]
        for budget in MEMORY_BUDGETS:
            fit = [r for r in rs if float(r["bits_per_texel"]) <= budget]
            if fit:
                best = min(fit, key=lambda r: (float(r["rmse"]), float(r["bits_per_texel"]), r["technique"]))
                out.append(dict(scene=scene, reference=ref, budget_kind="bits_per_texel", budget=budget,
                                technique=best["technique"], rmse=float(best["rmse"])))
        best_rmse = math.inf
        for r in sorted(rs, key=lambda r: (float(r["own_total_seconds"]), float(r["rmse"]), r["technique"])):
            if float(r["rmse"]) < best_rmse:  # a step of the (cost, RMSE) front
                best_rmse = float(r["rmse"])
                out.append(dict(scene=scene, reference=ref, budget_kind="total_seconds",
                                budget=float(r["own_total_seconds"]), technique=r["technique"], rmse=best_rmse))
    return out


def _g(x):
    return f"{x:.3g}"


def _and(items):
    items = [str(x) for x in items]
    return items[0] if len(items) == 1 else ", ".join(items[:-1]) + " and " + items[-1]


def winner_lines(found, resolutions):
    """report.md's section: per scene and reference two sentences, memory then time.

    ``resolutions``: scene -> text naming the scene's own map size and camera resolution.
    """
    lines = ["## The answer: lowest RMSE at each budget", "",
             "Per scene and reference, the technique with the lowest RMSE among those within a budget (winners.csv). "
             "Memory: bits per shadow-map texel that the lookup reads (PCF: every MSAA sample; multi-view techniques: one map per light sample). Time: texel + fragment seconds (medians, NumPy on "
             "this machine) at the scene's own shadow-map size and camera resolution, extrapolated linearly in "
             "texels and pixels from the run's sizes; the budgets are the costs at which a more accurate technique "
             "becomes affordable. The three-objective front below keeps texel and fragment cost apart.", ""]
    by = {}
    for w in found:
        by.setdefault((w["scene"], w["reference"]), []).append(w)
    for (scene, ref), ws in by.items():
        mem = [w for w in ws if w["budget_kind"] == "bits_per_texel"]
        cost = [w for w in ws if w["budget_kind"] == "total_seconds"]
        merged = []  # consecutive memory budgets with the same winner read as one
        for w in mem:
            if merged and merged[-1][1]["technique"] == w["technique"]:
                merged[-1][0].append(w["budget"])
            else:
                merged.append(([w["budget"]], w))
        m = "; ".join(f"{_and(bs)} bits: **{w['technique']}** (RMSE {_g(w['rmse'])})" for bs, w in merged)
        none = [b for b in MEMORY_BUDGETS if b not in {w["budget"] for w in mem}]  # the smallest budgets
        m = (f"Lowest RMSE at {m}" + (f" (nothing fits in {_and(none)} bits)" if none else "") if merged
             else f"No technique fits in {MEMORY_BUDGETS[-1]} bits per texel")
        c = "; ".join(f"within {_g(w['budget'])} s: **{w['technique']}** (RMSE {_g(w['rmse'])})" for w in cost)
        lines.append(f"- **{scene}** (reference `{ref}`). {m}. At the scene's own resolution "
                     f"({resolutions.get(scene, '?')}), {c or 'no technique has a finite cost'}.")
    return lines + [""]


def winners_csv(found):
    """``winners.csv``: :data:`WINNER_COLUMNS`, one row per winner."""
    buf = io.StringIO()
    wr = csv.writer(buf, lineterminator="\n")
    wr.writerow(WINNER_COLUMNS)
    for w in found:
        wr.writerow([w["scene"], w["reference"], w["budget_kind"], f"{w['budget']:.6g}", w["technique"],
                     f"{w['rmse']:.6g}"])
    return buf.getvalue()
