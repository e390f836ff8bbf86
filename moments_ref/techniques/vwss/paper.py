"""The VWSS paper's own figures (Tables 1 and 2, §3.2, Figures 4, 6, 12) and the claims measured against them.

:func:`claims` turns a :class:`moments_ref.report.vwss.Comparison` (``moments-ref vwss``) into
:class:`moments_ref.claims.Claim` records with the ids ``vwss-below-pcss-24``,
``vwss-below-pcss-128``, ``vwss-hole-free``, ``vwss-naive-leaks``,
``vwss-depth-speedup`` and ``vwss-warp-triangle-independent``.

The paper's numbers (GeForce GTX Titan X, 1024² maps, reference MVR with 512
maps, RMSE against it; ×Faster Depth = MVR depth-map time / (VWSS point
generation + depth maps)):

==========  =================  ===================  =================  ===================
scene       VWSS/PCSS RMSE 24  ×depth, ×total 24    VWSS/PCSS RMSE 128 ×depth, ×total 128
==========  =================  ===================  =================  ===================
Challenger  1.801/2.753 = 0.65  2.15, 1.26          0.774/2.753 = 0.28  4.38, 1.46
Volund      1.428/2.503 = 0.57  3.67, 1.53          0.772/2.503 = 0.31  8.16, 2.02
Warriors    1.627/3.608 = 0.45  5.04, 2.48          0.702/3.608 = 0.19  12.82, 3.30
Cliffside   1.316/3.232 = 0.41  3.73, 2.15          1.129/3.232 = 0.35  8.29, 3.37
==========  =================  ===================  =================  ===================

Verdicts compare with these figures. The RMSE claims are the captions' own
(:data:`TABLE_CLAIMS`): VWSS's RMSE below PCSS's, a ratio below 1, with the paper's
four ratios beside ours (they span scenes we do not have; not a bound). A speedup
"holds" when it is at least the weakest the paper reports (the smallest speedup):
the paper's scenes all show at least that much. Times here are NumPy on a CPU,
not GPU times: a speedup measures the algorithms' work on this platform, which
the ``why`` of the claim says.

References
----------
.. [1] VWSS: Adam Marrs, Benjamin Watson and Christopher Healey. 2018. *View-warped Multi-view Soft
       Shadowing for Local Area Lights*. Journal of Computer Graphics Techniques (JCGT) 7, 3, 1–28.
       http://jcgt.org/published/0007/03/01/
"""

from __future__ import annotations

import math

import numpy as np

from ...claims import Claim, verdict_of

__all__ = ["TABLES", "TABLE_CLAIMS", "TABLE1_DIFFERENCES", "claims", "exponent"]

#: Per view count, per scene of the paper: (VWSS RMSE, PCSS RMSE, ×faster depth, ×faster total).
TABLES = {
    24: {"Challenger": (1.801, 2.753, 2.15, 1.26), "Volund": (1.428, 2.503, 3.67, 1.53),
         "Warriors": (1.627, 3.608, 5.04, 2.48), "Cliffside": (1.316, 3.232, 3.73, 2.15)},
    128: {"Challenger": (0.774, 2.753, 4.38, 1.46), "Volund": (0.772, 2.503, 8.16, 2.02),
          "Warriors": (0.702, 3.608, 12.82, 3.30), "Cliffside": (1.129, 3.232, 8.29, 3.37)},
}
_TABLE_NAME = {24: "VWSS Table 1", 128: "VWSS Table 2"}


def exponent(t1, t2, x1, x2):
    """``log(t2 / t1) / log(x2 / x1)``: the growth exponent between two measurements (NaN if undefined)."""
    if t1 <= 0 or t2 <= 0 or x1 == x2:
        return float("nan")
    return math.log(t2 / t1) / math.log(x2 / x1)


def _paper_ratios(n):
    return {s: round(v[0] / v[1], 3) for s, v in TABLES[n].items()}


def _settings(res, n=None):
    c = res.settings
    out = {"scene": c["scene"], "map_size": c["map_size"], "reference_views": c["reference_views"],
           "near": c["near"], "near_rule": c["near_rule"], "source_resolution": c.get("source_resolution"),
           "camera": list(c["camera"]), "bias": c["bias"]}
    if n is not None:
        out["views"] = n
    return out


def _rows(res):
    return {(r["technique"], r["views"]): r for r in res.rows}


#: Per view count, the caption's own words: what its tables claim of VWSS's RMSE against PCSS's.
TABLE_CLAIMS = {
    24: "\"Although VWSS uses fewer total visibility samples [24 maps x 5 PCF taps = 120 per pixel, against "
        "PCSS's 64 + 96 = 160], it matches PCSS performance while producing images with less total error "
        "(RMSE)\"",
    128: "\"Despite being slower than PCSS, the increased light-sample counts of VWSS significantly improves "
         "RMSE\" (128 maps x 5 taps = 640 per pixel)",
}


def _below_pcss(res, n):
    """VWSS Table 1 (24 maps) or 2 (128): VWSS's RMSE below PCSS's on the scene, the paper's ratios beside.

    The tables' claim is the caption's "less total error (RMSE)" than PCSS on each of
    its scenes: a ratio below 1. Its four ratios (0.41 to 0.65 at 24 maps) are the
    paper's measurements on four scenes we do not have, shown beside ours, not a
    threshold: a ratio outside their range says how this scene compares with those.
    """
    rows = _rows(res)
    ratios = _paper_ratios(n)
    lo, hi = min(ratios.values()), max(ratios.values())
    paper = (f"{TABLE_CLAIMS[n]}: VWSS/PCSS RMSE {lo:.2f}-{hi:.2f} with {n} maps on its four scenes ("
             + ", ".join(f"{s} {r:.2f}" for s, r in ratios.items()) + "), below 1 on every one")
    claim = Claim(id=f"vwss-below-pcss-{n}", source=_TABLE_NAME[n],
                  statement=f"With {n} depth maps VWSS has a lower RMSE against the 512-map MVR reference than PCSS "
                            "(64-tap blocker search, 96-tap PCF)",
                  paper=paper, settings={**_settings(res, n), "metric": "RMSE of the receiver pixels' visibility "
                                         "against MVR with the reference's light samples; verdict: VWSS/PCSS < 1"})
    if ("vwss", n) not in rows:
        claim.why = f"this run used {sorted({v for t, v in rows if t == 'vwss'})} light samples, not {n}"
        return claim
    a, b = rows[("vwss", n)]["rmse"], rows[("pcss", 1)]["rmse"]
    ratio = a / b if b > 0 else float("nan")
    place = ("inside" if lo <= ratio <= hi else "below (better than)" if ratio < lo else "above (worse than)")
    claim.measured = {"ours": f"VWSS/PCSS RMSE {ratio:.3f} on {res.settings['scene']} ({place} the paper's "
                              f"{lo:.2f}-{hi:.2f})", "vwss_rmse": a, "pcss_rmse": b, "ratio": ratio,
                      "paper_ratios": ratios}
    if not math.isfinite(ratio):
        claim.why = "PCSS's RMSE is zero or not finite: no ratio"
        return claim
    claim.verdict = verdict_of(ratio < 1)
    claim.why = (f"VWSS's RMSE {a:.4f} against PCSS's {b:.4f}: ratio {ratio:.3f}, {place} the range "
                 f"{lo:.2f}-{hi:.2f} of the paper's four scenes. Holds means below 1, the caption's \"less total "
                 f"error\", here with {n} maps of {res.settings['map_size']}², 5 PCF taps per map, PCSS 64 + 96 taps "
                 f"and an MVR reference of {res.settings['reference_views']} maps (the paper's: 1024², 512); the "
                 "range is the spread over scenes, not a bound the paper states. Both use the "
                 f"light's near plane z_n = {res.settings['near']:.3g}, which sets VWSS's source resolution, "
                 "(z_n + d)/z_n; PCSS searches for blockers on the plane of the nearest depth in its map (no nearer "
                 "blocker exists), so its error does not depend on z_n. Varying the parameters the paper leaves "
                 "open (z_n from 0.1 to 0.5, the bias from 0.001 to 0.004 of far, the light-sample seed) moves the "
                 "ratio (knot 0.674 to 0.820, chair 0.42 to 0.60) but never to 1 (docs/formats.md, \"Parameters "
                 "the papers leave open\"). " + TABLE1_DIFFERENCES)
    return claim


#: What differs between Table 1's setup and ours, beyond the parameters varied (:func:`claims`).
TABLE1_DIFFERENCES = (
    "What differs from Table 1 (map size 1024², 24 Poisson light samples, 5-tap PCF per map, PCSS with 64 + 96 "
    "taps and the 512-map MVR reference are the paper's): the scenes (Table 1's four Blacksmith scenes are not "
    "available; the ratio spans 0.41 to 0.65 across them, so it depends on the scene as much as on the method, "
    "and knot and chair fall on either side of the range's top), the error (Table 1's RMSE is of the final "
    "image, where each pixel's visibility error is weighted by its albedo and unshadowed irradiance; ours is of "
    "the visibility of the receiver pixels, weighted alike, and a ratio of RMSEs does not cancel that weight), "
    "and the draw (one Poisson set of light samples per run: with z_n, the bias and the seed varied at reduced "
    "settings knot's ratio spans 0.674 to 0.820, the seed moving it most). A ratio just above 0.65 on one scene "
    "and one draw is therefore no evidence against the paper; the verdict is the caption's claim, VWSS below PCSS")


def _hole_free(res):
    n = max(res.settings["views"])
    h = res.holes.get(("vwss", n))
    claim = Claim(id="vwss-hole-free", source="VWSS §3.2, Figure 6",
                  statement="Points from the enlarged source view (Eqs. (1)-(3)), each splatted to one texel, give "
                            "hole-free depth maps with very slight bloating against multi-view rasterization",
                  paper="hole-free; \"a very slight bloating of shadow results when compared to the multi-view "
                        "rasterization reference\" (no number)",
                  settings=_settings(res, n))
    if h is None:
        claim.why = "no warped map was compared with MVR"
        return claim
    o = h["views"].index(h["outermost"])
    diff = res.leaks["vwss"]["mean_difference"]
    m = {"holes_mean": float(np.mean(h["holes"])), "holes_outermost": h["holes"][o],
         "bloat_mean": float(np.mean(h["bloat"])), "bloat_outermost": h["bloat"][o],
         "mean_visibility_minus_mvr": diff, "views_compared": len(h["views"])}
    claim.measured = m
    holds = (m["holes_mean"] < m["bloat_mean"] and m["holes_outermost"] < m["bloat_outermost"] and diff <= 0)
    claim.verdict = verdict_of(holds)
    claim.why = (f"fractions of MVR's covered texels: missing {m['holes_mean']:.2%} (outermost sample "
                 f"{m['holes_outermost']:.2%}), extra {m['bloat_mean']:.2%}; visibility {diff:+.4f} vs MVR. Read as: "
                 "the coverage differences of point splatting and rasterization at silhouettes (Figure 6) go "
                 "mostly towards bloat and the shadow is not lighter than MVR's; "
                 + ("that is what we see" if holds else "that is not what we see"))
    return claim


def _naive_leaks(res):
    n = max(res.settings["views"])
    claim = Claim(id="vwss-naive-leaks", source="VWSS Figure 4, Figure 5",
                  statement="Naive image warping of the light centre's depth map leaks light at disocclusions and at "
                            "the borders of the light samples' fields of view; the layered points of the enlarged "
                            "source view do not",
                  paper="Figure 4 (images, no number): leaks (a)-(c) with naive warping, \"eliminated using our "
                        "approach\"", settings=_settings(res, n))
    lk = res.leaks
    if "vwss_naive" not in lk:
        claim.why = "naive warping did not run"
        return claim
    hn, hv = res.holes.get(("vwss_naive", n)), res.holes.get(("vwss", n))
    m = {"naive_mean_excess_visibility": lk["vwss_naive"]["mean_excess"],
         "vwss_mean_excess_visibility": lk["vwss"]["mean_excess"],
         "naive_pixels_over_0.1": lk["vwss_naive"]["pixels_over_0.1"],
         "vwss_pixels_over_0.1": lk["vwss"]["pixels_over_0.1"]}
    if hn and hv:
        m["naive_holes_mean"], m["vwss_holes_mean"] = float(np.mean(hn["holes"])), float(np.mean(hv["holes"]))
    claim.measured = m
    holds = (m["naive_mean_excess_visibility"] > m["vwss_mean_excess_visibility"]
             and m.get("naive_holes_mean", 1) > m.get("vwss_holes_mean", 0))
    claim.verdict = verdict_of(holds)
    claim.why = ("excess visibility over MVR with the same light samples (light that MVR blocks) and missing texels: "
                 f"naive {m['naive_mean_excess_visibility']:.4f} vs VWSS {m['vwss_mean_excess_visibility']:.4f}")
    return claim


def _speedup(res):
    rows = _rows(res)
    ns = [n for n in sorted(res.settings["views"]) if n in TABLES and ("vwss", n) in rows]
    paper = "; ".join(f"{n} maps: depth {min(v[2] for v in TABLES[n].values()):.2f}-"
                      f"{max(v[2] for v in TABLES[n].values()):.2f}x, total "
                      f"{min(v[3] for v in TABLES[n].values()):.2f}-{max(v[3] for v in TABLES[n].values()):.2f}x"
                      for n in TABLES)
    claim = Claim(id="vwss-depth-speedup", source="VWSS Tables 1 and 2",
                  statement="VWSS renders the multi-view depth maps faster than MVR (point generation + warp "
                            "against rasterizing every map), and the whole frame too",
                  paper=paper, settings=_settings(res))
    measured = {}
    for n in sorted(res.settings["views"]):
        v, mv = rows.get(("vwss", n)), rows.get(("mvr", n))
        if v and mv:
            d = mv["seconds_depth"] / max(v["seconds_points"] + v["seconds_depth"], 1e-12)
            t = mv["seconds_total"] / max(v["seconds_total"], 1e-12)
            measured[f"{n}_maps"] = {"depth_speedup": d, "total_speedup": t, "points": v["points"],
                                     "warp_ns_per_point_view": 1e9 * v["seconds_depth"] / max(v["points"] * n, 1),
                                     "mvr_seconds_per_map": mv["seconds_depth"] / n}
    claim.measured = measured
    if not ns:
        claim.why = "no run with 24 or 128 light samples, the paper's counts"
        return claim
    ok = all(measured[f"{n}_maps"]["depth_speedup"] >= min(v[2] for v in TABLES[n].values()) for n in ns)
    claim.verdict = verdict_of(ok)
    claim.why = ("NumPy on a CPU, not a GPU: the ratio of the two algorithms' work here (triangle rasterization "
                 "per map against one rasterization plus a scatter of every point into every map, np.maximum.at "
                 "in place of the GPU's atomic max); holds means at least the paper's smallest depth-map speedup "
                 "for each of its view counts")
    return claim


def _triangles(res):
    claim = Claim(id="vwss-warp-triangle-independent", source="VWSS §4, Figure 12",
                  statement="VWSS's depth-map cost depends on the number of points and target maps, not on the "
                            "triangle count (MVR's grows linearly with it)",
                  paper="Figure 12: VWSS time nearly flat from 90 k to 673 k triangles, MVR linear (no exponent "
                        "given)", settings=_settings(res))
    if not res.scaling:
        claim.why = "the triangle-count experiment did not run"
        return claim
    s = {(x["level"], x["views"]): x for x in res.scaling}
    n = max(x["views"] for x in res.scaling)
    a, b = s[(0, n)], s[(1, n)]
    per = [(x["seconds_warp"] / (x["points"] * n), x["seconds_warp_max"] / (x["points"] * n)) for x in (a, b)]
    flat = per[1][0] <= per[0][1]  # the fastest repeat at 4x triangles is no slower than the slowest at 1x
    claim.measured = {"triangles": [a["triangles"], b["triangles"]], "points": [a["points"], b["points"]],
                      "warp_ns_per_point_view": [1e9 * per[0][0], 1e9 * per[1][0]],
                      "warp_seconds_min_max": [[a["seconds_warp"], a["seconds_warp_max"]],
                                               [b["seconds_warp"], b["seconds_warp_max"]]],
                      "mvr_exponent_in_triangles": exponent(a["seconds_mvr"], b["seconds_mvr"], a["triangles"],
                                                            b["triangles"]),
                      "points_seconds": [a["seconds_points"], b["seconds_points"]]}
    claim.verdict = verdict_of(flat)
    claim.why = ("only the warp is comparable on a CPU (point generation runs on the GPU rasterizer in the paper, "
                 "here on a NumPy rasterizer whose per-triangle cost dominates, so its triangle dependence is not "
                 "measurable here); holds means the warp's time per point and view does not grow with 4x triangles "
                 "(fastest of three repeats at 4x no slower than the slowest at 1x)")
    return claim


def claims(res):
    """The VWSS claims measured by a comparison (module docstring), in a fixed order."""
    return [_below_pcss(res, 24), _below_pcss(res, 128), _hole_free(res), _naive_leaks(res), _speedup(res),
            _triangles(res)]
