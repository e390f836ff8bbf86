"""The text of report.md's claims section: the claims table, the largest pixel differences, notes.

Split from :mod:`.paper_claims` (which measures and decides): per claim the
paper's figure, ours, the metric, the setting, the verdict and the side-by-side
crop of :mod:`._claim_crops`; then each claim's ``why``.

References
----------
.. [1] HPG17: Christoph Peters. 2017. *Non-Linearly Quantized Moment Shadow Maps*. In Proceedings
       of High Performance Graphics (HPG '17). ACM. The non-linear quantization Φ, Ψ4, Algorithms
       1–3, the texel formats and the compute shader of §4.1.
"""

from __future__ import annotations

from . import _claim_crops

__all__ = ["claims_table", "worst_table", "pixel_notes"]


def _setting(c, measured):
    st = c.settings
    scene = st.get("scene")
    run = measured.get(scene, {}).get("settings", {}) if scene else {}
    parts = [f"`{scene}`"] if scene else []
    if run.get("shadow_map_size"):
        parts.append(f"{'x'.join(map(str, run['shadow_map_size']))} map, {run.get('msaa')}x MSAA")
    if run.get("resolution"):
        parts.append(f"{'x'.join(map(str, run['resolution']))} camera")
    return ", ".join(parts) or "see settings"


def _cell(x):
    return str(x).replace("|", "\\|").replace("\n", " ")


def claims_table(cs, measured, images=()):
    """report.md's claims table: per claim the paper's figure, ours, the metric, the setting, the verdict, a crop.

    ``images``: the crop files written beside report.md (:func:`._claim_crops.crop_pngs`);
    each claim's ``why`` follows the table.
    """
    lines = ["| claim | paper (figure) | ours | metric | setting | verdict | crop |", "|---|---|---|---|---|---|---|"]
    for c in cs:
        ours = c.measured.get("ours") if isinstance(c.measured, dict) else None
        if ours is None:
            ours = _cell(c.as_dict()["measured"])[:160]
        f = _claim_crops.file_name(c.id)
        crop = f"![{c.id}]({f})" if f in images else ""
        v = c.verdict if c.verdict == "holds" else f"**{c.verdict}**"
        lines.append(f"| `{c.id}` ({_cell(c.source)}) | {_cell(c.paper)} | {_cell(ours)} | "
                     f"{_cell(c.settings.get('metric', 'see why'))} | {_setting(c, measured)} | {v} | {crop} |")
    lines += ["", "Why, per claim:", ""] + [f"* `{c.id}`: {_cell(c.why)}" for c in cs]
    return "\n".join(lines) + "\n"


def worst_table(measured):
    """Markdown lines: the largest NLQ64 / MSM128 nearest-neighbour differences per scene."""
    lines = []
    for s, m in measured.items():
        p = m.get("pixels")
        if not p or not p["worst"]:
            continue
        lines += ["", f"Largest NLQ64 / MSM128 nearest-neighbour differences on `{s}`:", "",
                  "| camera pixel | world position | texel | nlq64 | msm128 | reference |", "|---|---|---|---|---|---|"]
        for x in p["worst"]:
            ref = "n/a" if x["reference"] is None else f"{x['reference']:.3f}"
            lines.append(f"| {x['pixel']} | {x['position']} | {x['texel']} | {x['nlq64']:.3f} | "
                         f"{x['msm128']:.3f} | {ref} |")
    return lines


def pixel_notes(measured):
    """Markdown lines: why the rendered lookups of NLQ64 and MSM128 differ more than the nearest-neighbour ones."""
    lines = []
    for s, m in measured.items():
        p = m.get("pixels")
        r = p and p.get("as_rendered")
        if not r:
            continue
        head = (f"On `{s}` the paper's nearest-neighbour comparison finds {p['above_3pct']} pixels above 3 % and "
                f"{p['above_10pct']} at 10 % or more (max {p['max']:.4f})")
        if r["above_3pct"] == 0:
            lines += ["", head + f"; the report's own lookups differ by at most {r['max']:.3f}."]
            continue
        w = r["worst"]
        lower = "MSM128 is the lighter one there: it leaks" if w["msm128"] < w["nlq64"] else "NLQ64 is the lighter one there"
        ref = "n/a" if w["reference"] is None else f"{w['reference']:.3f}"
        lines += ["", head + ": the non-linear quantization itself changes the reconstruction very little. The "
                  f"report's own lookups differ more ({r['above_3pct']} pixels above 3 %, {r['above_10pct']} at 10 % "
                  f"or more, max {r['max']:.3f}) because they interpolate different things: NLQ64 reconstructs the "
                  "four nearest texels and interpolates the intensities (HPG17 §4.2), MSM128 interpolates the "
                  "moments and reconstructs once. Interpolated moments of neighbouring texels describe a mixture "
                  "of their depth distributions, with more distinct depths than four moments represent exactly. "
                  f"The largest such difference is at {w['position']}: NLQ64 {w['nlq64']:.3f}, MSM128 "
                  f"{w['msm128']:.3f}, reference {ref}; {lower}."]
    return lines
