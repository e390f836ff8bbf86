"""The report's text: results.csv, the measured claims of HPG17 and report.md.

References
----------
.. [1] HPG17: Christoph Peters. 2017. *Non-Linearly Quantized Moment Shadow Maps*. In Proceedings
       of High Performance Graphics (HPG '17). ACM. The non-linear quantization Φ, Ψ4, Algorithms
       1–3, the texel formats and the compute shader of §4.1.
.. [2] FLIP: Pontus Andersson, Jim Nilsson, Tomas Akenine-Möller, Magnus Oskarsson, Kalle Åström
       and Mark D. Fairchild. 2020. *ꟻLIP: A Difference Evaluator for Alternating Images*.
       Proceedings of the ACM on Computer Graphics and Interactive Techniques (HPG 2020) 3, 2. Used
       through the package ``flip-evaluator``.
"""

from __future__ import annotations

import csv
import io
import math

import numpy as np

from .._arrays import InputError
from ..claims import find_row
from ..metrics import LEAK_THRESHOLD
from .. import techniques as _techniques
from ._crops import crop_lines
from ._pareto import FRONT_RULE
from .columns import COLUMNS, parse_row

__all__ = ["COLUMNS", "CLOSE_REL", "CLEARLY_BELOW", "read_results", "evaluate_claims", "markdown", "csv_text"]

#: Relative tolerances of the verdicts (stated in report.md).
CLOSE_REL = 0.10
CLEARLY_BELOW = 0.90


def _fmt(v):
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return "nan" if math.isnan(v) else f"{v:.6g}"
    return str(v)


def csv_text(rows):
    """results.csv: :data:`COLUMNS` and one line per row (numbers to 6 significant digits)."""
    buf = io.StringIO()
    wr = csv.writer(buf, lineterminator="\n")
    wr.writerow(COLUMNS)
    for r in rows:
        wr.writerow([_fmt(r.get(c, "")) for c in COLUMNS])
    return buf.getvalue()


def read_results(path):
    """Read a ``results.csv`` into a list of dicts, each column parsed by its kind (:mod:`.columns`)."""
    with open(path, newline="", encoding="utf-8") as f:
        rows = list(csv.DictReader(f))
    if rows and set(COLUMNS) - set(rows[0]):
        raise InputError(f"results: {path} lacks columns {sorted(set(COLUMNS) - set(rows[0]))}")
    return [parse_row(r) for r in rows]


def evaluate_claims(rows, four_moment=None):
    """Coarse RMSE comparisons of HPG17's headline techniques on ``rows`` (fixed criteria, not the paper's).

    Returns a list of ``(claim, verdict, evidence)`` with verdict True, False or
    None (not measurable: a scene or technique missing, or a NaN).
    Criteria: "close" = RMSE within 10 % (relative, plus 1e-3 absolute);
    "clearly below" = RMSE at most 90 % of the other; "leaks" = leak_fraction > 0.
    These thresholds are this function's, not HPG17's (which states none), so
    report.md does not print these verdicts: it judges the claims in the paper's
    own terms with :func:`moments_ref.report.paper_claims.claims` (``claims.json``).
    Kept for scripts that compare rows quickly.
    """
    if four_moment is None:
        four_moment = [n for n in _techniques.names() if _techniques.get(n).four_moments]
    out = []

    def close(a, b):
        return abs(a - b) <= CLOSE_REL * b + 1e-3

    # 1. railing: NLQ 64 close to MSM 128, clearly below MSM 64 and VSM.
    claim = "railing: NLQ 64-bit error close to MSM 128-bit and clearly below MSM 64-bit and VSM"
    r = {t: find_row(rows, "railing", t) for t in ("nlq64", "msm128", "msm64", "vsm")}
    if all(r.values()) and all(np.isfinite(v["rmse"]) for v in r.values()):
        a, b, c, d = (r[t]["rmse"] for t in ("nlq64", "msm128", "msm64", "vsm"))
        verdict = close(a, b) and a <= CLEARLY_BELOW * c and a <= CLEARLY_BELOW * d
        out.append((claim, verdict, f"RMSE nlq64 {a:.4g}, msm128 {b:.4g}, msm64 {c:.4g} (ratio {a / c:.3f}), "
                                    f"vsm {d:.4g} (ratio {a / d:.3f})"))
    else:
        out.append((claim, None, "railing with nlq64, msm128, msm64, vsm not measured (or NaN)"))

    # 2. NLQ 32 close to NLQ 64 except banding on facade.
    claim = "NLQ 32-bit close to NLQ 64-bit except banding on facade"
    pairs = [(r["scene"], r["rmse"], find_row(rows, r["scene"], "nlq64")) for r in rows if r["technique"] == "nlq32"]
    pairs = [(s, a, b["rmse"]) for s, a, b in pairs if b is not None]
    if pairs and any(s == "facade" for s, _, _ in pairs):
        ok, notes, nan = True, [], False
        for s, a, b in pairs:
            if not (np.isfinite(a) and np.isfinite(b)):
                nan = True
                notes.append(f"{s}: NaN (nlq32 {a}, nlq64 {b})")
                continue
            notes.append(f"{s}: nlq32 {a:.4g} vs nlq64 {b:.4g}")
            if s == "facade":
                ok &= a > (1 + CLOSE_REL) * b  # banding: clearly worse there
            else:
                ok &= close(a, b)
        out.append((claim, None if nan else ok, "; ".join(notes)))
    else:
        out.append((claim, None, "facade with nlq32 and nlq64 not measured"))

    # 3. Every four-moment technique leaks on three-occluders.
    claim = "every four-moment technique leaks on three-occluders"
    rs = [r for r in rows if r["scene"] == "three-occluders" and r["technique"] in four_moment]
    if rs:
        leaks = {r["technique"]: r["leak_fraction"] for r in rs}
        if not all(np.isfinite(v) for v in leaks.values()):
            out.append((claim, None, f"NaN leak fractions {leaks}"))
        else:
            out.append((claim, all(v > 0 for v in leaks.values()),
                        ", ".join(f"{k} {v:.3%}" for k, v in leaks.items())))
    else:
        out.append((claim, None, "three-occluders with four-moment techniques not measured"))
    return out


def _intro(flip_ok, sections):
    text = ("Each technique shades the receiver pixels of each scene's camera view; errors are against the "
            "reference (9×9 Gaussian PCF over the MSAA samples against the receiver plane's depth at each tap = "
            "the exact filtered hard shadow of the planar receiver; with translucent occluders, the filtered "
            "product of transmittances). Shadow intensity: 1 = fully shadowed. `leak_fraction`: share of receiver "
            f"pixels lit more than {LEAK_THRESHOLD} above the reference. Times are CPU seconds of NumPy "
            "on this machine (texture stages / lookups, the split of HPG17 Figure 10), not GPU times. "
            + _techniques.references.depth_bias_text())  # the bias of each technique: techniques/references.py
    if sections:
        text += (" Exceptions, described in their sections below: the rows measured against another reference "
                 "(" + "; ".join(sections) + ").")
    lines = ["# Shadow techniques: error against run time", "", text, ""]
    if not flip_ok:
        lines += ["`flip_mean` is NaN: the package `flip-evaluator` (NVIDIA ꟻLIP) is not installed.", ""]
    return lines


def _settings(settings, repeats=1):
    lines = ["## Settings", "",
             "What ran: each scene's `outputs` (`--technique NAME` or `--all-techniques` instead). Map size, "
             "MSAA and camera as used; where they differ from the scene's own, the scene's follow in "
             "parentheses: run with `--full` for those.", "",
             "| scene | techniques | shadow map | MSAA | camera | reference | light |", "|---|---|---|---|---|---|---|"]
    for s, v in settings.items():
        own = v.get("own", (v["size"], v["msaa"], v["resolution"]))

        def cell(a, b, fmt):
            return fmt(a) + ("" if tuple(np.atleast_1d(a)) == tuple(np.atleast_1d(b)) else f" ({fmt(b)})")

        lines.append(f"| {s} | {', '.join(v.get('techniques', []))} | {cell(v['size'], own[0], _x)} | "
                     f"{cell(v['msaa'], own[1], lambda m: f'{m}×')} | {cell(v['resolution'], own[2], _x)} | "
                     f"{v.get('references', '')} | {v['light']} |")
    lines.append("")
    if any(v.get("reduced") for v in settings.values()):
        lines += ["**Reduced settings**: the scenes marked with the scene's own values in parentheses ran "
                  "smaller than they ask for (shadow map halved per side, camera a quarter per side); "
                  "`moments-ref report --full` runs the scenes' own settings.", ""]
    lines += [f"Timings: every stage of a technique's cost ran once as a warm-up and then {repeats} times, timed; "
              "`texel_seconds` and `fragment_seconds` are the medians (`_min`, `_max`: the spread) and "
              "`stages.json` lists each stage's median, min and max with the techniques using it. A stage "
              "shared by several techniques (msm64, msm128 and vsm share the resolve and the blur) is "
              "charged in full to every technique that needs it: each technique's cost is its cost alone, "
              "and the costs of several techniques do not add up.", ""]
    if any(v["light"].startswith("area") for v in settings.values()):
        lines += ["Area lights: the hard-shadow techniques use the light's centre as a spot light "
                  "(perspective shadow map), and their reference is the filtered hard shadow of that spot. "
                  "The soft-shadow rows (msm_soft, pcss, vwss, mvr) are measured against multi-view "
                  "rasterization (MVR) with many light samples instead; see below.", ""]
    return lines


def _x(v):
    return "×".join(str(int(x)) for x in v)


def _results(rows):
    # HPG17's claims are judged in the paper's own terms in the claims table at the end
    # (paper_claims, claims.json); the fixed criteria of evaluate_claims are not the
    # paper's, so report.md does not print their verdicts.
    lines = ["The paper claims, each with the paper's figure beside ours, are in the section "
             "[Paper claims (claims.json)](#paper-claims-claimsjson) at the end.", ""]
    lines += ["`pareto`: on the Pareto front of its scene and reference (see above), dominance judged beyond "
              "the timing spread: " + FRONT_RULE, ""]
    lines += ["", "## Results", "", "| " + " | ".join(COLUMNS) + " |", "|" + "---|" * len(COLUMNS)]
    lines += ["| " + " | ".join(_fmt(r[c]) for c in COLUMNS) + " |" for r in rows]
    return lines + [""]


def markdown(rows, stages, settings, images, flip_ok, references, artifacts=(), answer=(), repeats=1):
    """report.md.

    ``references``: per reference used (in order) ``(reference, settings per scene,
    statements per scene)``; ``images``: ``{"fronts": [paths], "crops": [paths], reference name: [paths]}``;
    ``artifacts``: markdown lines of the techniques' measured artifacts; ``answer``:
    the lines of the machine, the Pareto fronts and the summary, after the settings.
    """
    sections = [r.label for r, _, _ in references if r.section is not None]
    lines = _intro(flip_ok, sections) + _settings(settings, repeats) + list(answer)
    lines += _results(rows)
    plain = []
    for ref, cfg, statements in references:
        paths = images.get(ref.name, [])
        if ref.section is None:
            plain += paths
            continue
        lines += ref.section(cfg, statements, paths)
    lines += list(artifacts)
    lines += ["## Error against run time", "",
              "One figure per reference. Filled markers are on their scene's Pareto front (judged beyond the "
              "timing spread, above); the horizontal bars are the min–max of the timed repeats; the line is "
              "the lower envelope of the medians in the plane of the panel.", ""]
    lines += [f"![error against run time]({p})" for p in images.get("fronts", [])] + ["", "## Error images", ""]
    for p in plain:
        lines += [f"![{p}]({p})", ""]
    lines += crop_lines(images.get("crops", []))
    lines += ["## Stages that ran", "", "Median seconds of each stage (min–max over the timed repeats; one run for "
              "stages outside the techniques' costs) and the techniques that need it.", ""]
    for s, st in stages.items():
        lines.append(f"- {s}: " + ", ".join(
            f"`{x['stage']}` {x['seconds']:.3g} s ({x['min']:.3g}–{x['max']:.3g}; {', '.join(x['used_by'])})"
            if isinstance(x, dict) else f"`{x}`" for x in st))
    lines.append("")
    return "\n".join(lines)
