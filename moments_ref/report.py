"""Error against run time: every technique on every scene, measured against the reference.

``moments-ref report [--scene NAME|FILE]... [--full] --out DIR`` (:func:`main`)
renders each scene's camera view, shades its receiver pixels with each
technique (:mod:`moments_ref.pipeline`) and writes to DIR:

* ``results.csv``: one row per (scene, technique), columns :data:`COLUMNS`;
* ``stages.json``: per scene the stages that ran (:attr:`moments_ref.pipeline.RunResult.stages`);
* ``claims.json``: the paper claims measured on the scenes that ran
  (:mod:`moments_ref.paper_claims`), also appended to report.md as a table;
* ``report.md``: the table, the measured verdict on HPG17's headline claims,
  the error-against-run-time scatter plot ``scatter.png`` and the error images
  ``errors_<scene>.png``.

Metrics over the receiver pixels inside the shadow map, with
``e = shadow − reference`` (shadow intensities, 1 = fully shadowed; the
reference is the 9×9-Gaussian PCF at the technique's own depth bias, the exact
filtered hard shadow, or with translucent occluders the filtered product of
transmittances): ``rmse``, ``max_error = max |e|``, ``p99_error`` (99th
percentile of ``|e|``), ``leak_fraction`` (share of pixels lit more than 0.05
above the reference, ``e < −0.05``) and ``flip_mean``, the mean of NVIDIA ꟻLIP
(package ``flip-evaluator``, LDR) between the shaded image and the image shaded
with the reference. ``texel_seconds`` is the wall-clock time of the technique's
texture stages (shared stages counted fully for each technique: its cost
alone), ``fragment_seconds`` that of its lookups for all receiver pixels, the
split of HPG17 Figure 10. Both are NumPy times on this machine, not GPU times.

Without ``--full`` each scene runs at reduced resolution
(:func:`moments_ref.pipeline.reduced_settings`: shadow map halved per side,
camera a quarter per side); ``--full`` uses 2048² maps with 4× MSAA and the
scene's camera resolution (HPG17 §5). ``knot`` has an area light: the
hard-shadow techniques here use its centre as a spot light (their reference is
the filtered hard shadow of that spot).

Area lights (any scene whose light is an :class:`~moments_ref.scene.AreaLight`)
also get the soft-shadow rows ``msm_soft`` (moment soft shadow mapping),
``pcss``, ``vwss`` and ``mvr`` (MVR with the same N light samples as VWSS: the
error of the light sampling alone), run by the pipeline's area-light path
(:data:`moments_ref.pipeline.AREA_OUTPUTS`) over the same receiver pixels. Their
reference is multi-view rasterization with many light samples (64 reduced, 512
with ``--full``; :func:`moments_ref.pipeline.area_settings`), shadow intensity
``1 − visibility``; ``texel_seconds`` counts their depth-map and texture stages,
``fragment_seconds`` their lookups. The run then also writes
:func:`moments_ref.techniques.msm_soft.artifact_images` (``msm_soft_artifacts.png``
and ``.md``: the artifacts the slides name) and ``soft_<scene>.png``
(visibility images), and report.md states the measured soft-shadow results.

Scenes whose ``outputs`` name the scattering techniques
(:data:`moments_ref.pipeline.SCATTERING_OUTPUTS`: shipped ``scattering``) get the
rows of :func:`moments_ref.techniques.scattering.report_rows`
(:func:`moments_ref.pipeline.run_scattering`): the error there is that of the
scattering term normalized by ``t_max`` against ray marching with 4096 samples
per ray; images ``scattering_<scene>.png``.
"""

from __future__ import annotations

import argparse
import csv
import io
import json
import math
import sys
from pathlib import Path

import numpy as np

from ._arrays import InputError
from ._io import save_figure, write_text
from . import paper_claims, pipeline
from . import techniques as _techniques

__all__ = ["COLUMNS", "LEAK_THRESHOLD", "AREA_ROWS", "run", "main", "metrics", "shaded_image", "flip_mean",
           "evaluate_claims", "soft_statements", "read_results", "plot_error_vs_runtime", "build_parser"]

#: Columns of results.csv, in order.
COLUMNS = ("scene", "technique", "bits_per_texel", "rmse", "max_error", "p99_error", "leak_fraction",
           "flip_mean", "texel_seconds", "fragment_seconds")
#: A pixel leaks when it is lit more than this above the reference.
LEAK_THRESHOLD = 0.05
#: Relative tolerances of the verdicts (stated in report.md).
CLOSE_REL = 0.10
CLEARLY_BELOW = 0.90


def metrics(shadow, reference):
    """Error statistics of shadow intensities against the reference.

    Returns a dict with ``rmse``, ``max_error``, ``p99_error``, ``leak_fraction``
    (NaN propagates: a non-finite intensity makes the statistics NaN).
    """
    s = np.asarray(shadow, dtype=np.float64)
    r = np.asarray(reference, dtype=np.float64)
    if s.size == 0:
        return {"rmse": math.nan, "max_error": math.nan, "p99_error": math.nan, "leak_fraction": math.nan}
    e = s - r
    a = np.abs(e)
    finite = bool(np.isfinite(e).all())
    return {
        "rmse": float(np.sqrt(np.mean(e * e))),
        "max_error": float(a.max()) if finite else math.nan,
        "p99_error": float(np.percentile(a, 99)) if finite else math.nan,
        "leak_fraction": float(np.mean(e < -LEAK_THRESHOLD)) if finite else math.nan,
    }


def shaded_image(gbuffer, shadow):
    """An LDR grey image of the camera view: ``0.1 + 0.8 |n·l| (1 − shadow)`` on receivers.

    Occluders are flat grey (0.35), the background black, receivers outside the
    shadow map unshadowed. Returns (H, W, 3) float32 in [0, 1].
    """
    w, h = gbuffer.resolution
    kind = gbuffer.kind.reshape(-1)
    img = np.zeros(h * w)
    img[kind == pipeline.OCCLUDER] = 0.35
    # Receivers outside the map: Lambert unknown here, shade them mid-grey unshadowed.
    img[kind == pipeline.OUTSIDE_LIGHT] = 0.5
    lit = 1.0 - np.clip(np.nan_to_num(np.asarray(shadow, dtype=np.float64), nan=1.0), 0, 1)
    img[gbuffer.pixel] = 0.1 + 0.8 * gbuffer.lambert * lit
    return np.repeat(np.clip(img, 0, 1).reshape(h, w, 1), 3, axis=2).astype(np.float32)


def flip_mean(reference_image, test_image):
    """Mean ꟻLIP (LDR) of ``test_image`` against ``reference_image``; NaN if flip-evaluator is missing."""
    try:
        import flip_evaluator
    except ImportError:
        return math.nan
    _, mean, _ = flip_evaluator.evaluate(np.ascontiguousarray(reference_image), np.ascontiguousarray(test_image),
                                         "LDR", applyMagma=False)
    return float(mean)


def _flip_available():
    try:
        import flip_evaluator  # noqa: F401
        return True
    except ImportError:
        return False


#: Area-light outputs in the default run (pipeline.AREA_OUTPUTS, msm_soft first as registered).
AREA_ROWS = ("msm_soft", "pcss", "vwss", "mvr")


def _check_names(requested):
    """Refuse unknown technique names, listing every known one."""
    known = list(dict.fromkeys(_techniques.names() + list(pipeline.AREA_OUTPUTS)
                               + list(pipeline.SCATTERING_OUTPUTS)))
    for n in requested:
        if n not in known:
            raise InputError(f"technique: unknown technique {n!r}; known techniques: {', '.join(known)}")


def _scene_scattering(scene, requested=None):
    """Scattering outputs the scene names (and the run asks for)."""
    names = [n for n in pipeline.SCATTERING_OUTPUTS if n in tuple(scene.outputs or ())]
    if requested is not None:
        names = [n for n in names if n in requested]
    return names


def _scene_techniques(scene, requested=None):
    """Pipeline outputs for a scene: registered techniques that apply, plus the area-light rows."""
    kind = getattr(scene.light, "kind", "directional")
    if requested is None:
        names = _techniques.names() + ([n for n in AREA_ROWS if n not in _techniques.TECHNIQUES]
                                       if kind == "area" else [])
    else:
        names = [n for n in requested if n not in pipeline.SCATTERING_OUTPUTS]
    translucent = bool(np.any(scene.occluder_translucent))
    out = []
    for n in names:
        if n in pipeline.AREA_OUTPUTS:
            if kind == "area" or requested is not None:
                out.append(n)  # the pipeline refuses them without an area light, with the reason
            continue
        t = _techniques.get(n)
        if t.requires_translucency and not translucent and requested is None:
            continue
        if kind not in t.light_kinds or (t.multiview and kind != "area"):
            if requested is None:
                continue
        out.append(t.name)
    return out


def _fmt(v):
    if isinstance(v, float):
        return "nan" if math.isnan(v) else f"{v:.6g}"
    return str(v)


def _csv_text(rows):
    buf = io.StringIO()
    wr = csv.writer(buf, lineterminator="\n")
    wr.writerow(COLUMNS)
    for r in rows:
        wr.writerow([_fmt(r[c]) for c in COLUMNS])
    return buf.getvalue()


def read_results(path):
    """Read a ``results.csv`` into a list of dicts (numbers as float, bits as int)."""
    with open(path, newline="", encoding="utf-8") as f:
        rows = list(csv.DictReader(f))
    if rows and set(COLUMNS) - set(rows[0]):
        raise InputError(f"results: {path} lacks columns {sorted(set(COLUMNS) - set(rows[0]))}")
    out = []
    for r in rows:
        d = {"scene": r["scene"], "technique": r["technique"], "bits_per_texel": int(r["bits_per_texel"])}
        for c in COLUMNS[3:]:
            d[c] = float(r[c])
        out.append(d)
    return out


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


def _error_figure(result, scene_name):
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    names = result.techniques
    ncols = min(4, len(names))
    nrows = -(-len(names) // ncols)
    w, h = result.gbuffer.resolution
    fig, axes = plt.subplots(nrows, ncols, figsize=(3.2 * ncols, 3.2 * nrows * h / w + 0.6), squeeze=False)
    im = None
    for ax in axes.ravel():
        ax.axis("off")
    for ax, n in zip(axes.ravel(), names):
        img = np.full(h * w, np.nan)
        img[result.gbuffer.pixel] = np.abs(result.shadow[n] - result.reference[n])
        im = ax.imshow(img.reshape(h, w), cmap="magma", vmin=0, vmax=0.5, interpolation="nearest")
        ax.set_title(n, fontsize="small")
    soft = [n for n in names if n in pipeline.AREA_OUTPUTS]
    fig.suptitle(f"{scene_name}: |shadow − reference|"
                 + (f" (reference of {', '.join(soft)}: MVR; of the others: the hard shadow)" if soft else ""))
    if im is not None:
        fig.colorbar(im, ax=axes.ravel().tolist(), shrink=0.8)
    return fig


def _soft_figure(result, scene_name, names):
    """Visibility (1 − intensity) of the MVR reference and of each area-light row on the camera view."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    w, h = result.gbuffer.resolution
    kind = result.gbuffer.kind.reshape(-1)
    first = names[0]
    panels = [("MVR reference", result.reference.get(first))] + [(n, result.shadow[n]) for n in names]
    panels = [(t, v) for t, v in panels if v is not None]
    fig, axes = plt.subplots(1, len(panels), figsize=(3.2 * len(panels), 3.2 * h / w + 0.7), squeeze=False)
    for ax, (title, inten) in zip(axes[0], panels):
        rgb = np.zeros((h * w, 3))
        rgb[kind == pipeline.OCCLUDER] = (0.85, 0.55, 0.3)
        rgb[kind == pipeline.OUTSIDE_LIGHT] = 0.5
        rgb[result.gbuffer.pixel] = (1.0 - np.clip(np.asarray(inten, np.float64), 0, 1))[:, None]
        ax.imshow(rgb.reshape(h, w, 3), interpolation="nearest")
        ax.set_title(title, fontsize="small")
        ax.axis("off")
    fig.suptitle(f"{scene_name}: visibility under the area light")
    fig.tight_layout()
    return fig


def soft_statements(rows, scene):
    """Measured statements on the area-light rows of ``scene`` (RMSE against the MVR reference).

    Returns a list of strings, empty when the scene has no such rows. Every
    number comes from ``rows``; comparisons are stated as measured (ratios),
    not assumed.
    """
    r = {t: _row(rows, scene, t) for t in pipeline.AREA_OUTPUTS}
    r = {t: v for t, v in r.items() if v is not None}
    if not r:
        return []
    out = []
    rm = {t: v["rmse"] for t, v in r.items()}
    out.append("RMSE of the shadow intensity against the MVR reference: "
               + ", ".join(f"{t} {v:.4g}" for t, v in rm.items())
               + "; ranked from lowest: " + " < ".join(sorted((t for t in rm if np.isfinite(rm[t])), key=rm.get))
               + ".")

    def ratio(a, b, text):
        if a in rm and b in rm and np.isfinite(rm[a]) and np.isfinite(rm[b]) and rm[b] > 0:
            q = rm[a] / rm[b]
            word = "below" if q < 1 else ("equal to" if q == 1 else "above")
            out.append(f"{a}'s RMSE is {word} {b}'s (ratio {q:.2f}){text}.")

    ratio("msm_soft", "pcss", ": moment soft shadow mapping against PCSS from the same single centre map")
    ratio("vwss", "pcss", " (VWSS §4 reports VWSS well below PCSS)")
    ratio("msm_soft", "vwss", "")
    ratio("vwss", "mvr", ": the error VWSS adds to MVR with the same light samples, whose own RMSE is the "
          "error of the light sampling alone")
    out.append("Seconds (texel + fragment, NumPy): "
               + ", ".join(f"{t} {v['texel_seconds']:.3g} + {v['fragment_seconds']:.3g}" for t, v in r.items())
               + ".")
    return out


def _row(rows, scene, tech):
    for r in rows:
        if r["scene"] == scene and r["technique"] == tech:
            return r
    return None


def evaluate_claims(rows, four_moment=None):
    """HPG17's headline claims, measured on ``rows``.

    Returns a list of ``(claim, verdict, evidence)`` with verdict True, False or
    None (not measurable: a scene or technique missing, or a NaN).
    Criteria: "close" = RMSE within 10 % (relative, plus 1e-3 absolute);
    "clearly below" = RMSE at most 90 % of the other; "leaks" = leak_fraction > 0.
    """
    if four_moment is None:
        four_moment = [n for n in _techniques.names() if _techniques.get(n).four_moments]
    out = []

    def close(a, b):
        return abs(a - b) <= CLOSE_REL * b + 1e-3

    # 1. railing: NLQ 64 close to MSM 128, clearly below MSM 64 and VSM.
    claim = "railing: NLQ 64-bit error close to MSM 128-bit and clearly below MSM 64-bit and VSM"
    r = {t: _row(rows, "railing", t) for t in ("nlq64", "msm128", "msm64", "vsm")}
    if all(r.values()) and all(np.isfinite(v["rmse"]) for v in r.values()):
        a, b, c, d = (r[t]["rmse"] for t in ("nlq64", "msm128", "msm64", "vsm"))
        verdict = close(a, b) and a <= CLEARLY_BELOW * c and a <= CLEARLY_BELOW * d
        out.append((claim, verdict, f"RMSE nlq64 {a:.4g}, msm128 {b:.4g}, msm64 {c:.4g} (ratio {a / c:.3f}), "
                                    f"vsm {d:.4g} (ratio {a / d:.3f})"))
    else:
        out.append((claim, None, "railing with nlq64, msm128, msm64, vsm not measured (or NaN)"))

    # 2. NLQ 32 close to NLQ 64 except banding on facade.
    claim = "NLQ 32-bit close to NLQ 64-bit except banding on facade"
    pairs = [(r["scene"], r["rmse"], _row(rows, r["scene"], "nlq64")) for r in rows if r["technique"] == "nlq32"]
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


def _pipeline_slope():
    from .pipeline import SLOPE_BIAS_TEXELS

    return f"{SLOPE_BIAS_TEXELS:.3g} (4.5√2)"


def _markdown(rows, stages, settings, claims, images, flip_ok, area=None, soft=None, scattering=None,
              artifacts=None):
    lines = ["# Shadow techniques: error against run time", ""]
    lines.append("Each technique shades the receiver pixels of each scene's camera view; errors are against the "
                 "reference at the technique's depth bias (9×9 Gaussian PCF over the MSAA samples = the exact "
                 "filtered hard shadow Z(z < zf); with translucent occluders, the filtered product of "
                 "transmittances). Shadow intensity: 1 = fully shadowed. `leak_fraction`: share of receiver "
                 f"pixels lit more than {LEAK_THRESHOLD} above the reference. Times are wall-clock NumPy seconds "
                 "on this machine (texture stages / lookups, the split of HPG17 Figure 10), not GPU times. "
                 "Depth bias: each technique's constant (1e-3, as HPG17 uses for NLQ) plus a receiver-slope term "
                 f"of {_pipeline_slope()} texels times the receiver's depth change per texel, the same for every "
                 "technique and the reference (without it the exact 9×9 PCF shades a plane lit at an angle as "
                 "half shadowed, which would be charged to the techniques as error).")
    if area or scattering:
        lines[-1] += (" Exceptions, described in their sections below: the soft-shadow rows under area lights "
                      "(reference: multi-view rasterization) and the single-scattering rows (error of the "
                      "normalized scattering term against converged ray marching).")
    lines.append("")
    if not flip_ok:
        lines.append("`flip_mean` is NaN: the package `flip-evaluator` (NVIDIA ꟻLIP) is not installed.")
        lines.append("")
    lines.append("## Settings")
    lines.append("")
    lines.append("| scene | shadow map | MSAA | camera | light |")
    lines.append("|---|---|---|---|---|")
    for s, v in settings.items():
        lines.append(f"| {s} | {v['size'][0]}×{v['size'][1]} | {v['msaa']}× | {v['resolution'][0]}×"
                     f"{v['resolution'][1]} | {v['light']} |")
    lines.append("")
    if any(v["light"].startswith("area") for v in settings.values()):
        lines.append("Area lights: the hard-shadow techniques use the light's centre as a spot light "
                     "(perspective shadow map), and their reference is the filtered hard shadow of that spot. "
                     "The soft-shadow rows (msm_soft, pcss, vwss, mvr) are measured against multi-view "
                     "rasterization (MVR) with many light samples instead; see below.")
        lines.append("")
    if area:
        lines.append("| scene | soft-shadow maps | light samples (vwss, mvr) | MVR reference samples | "
                     "near | far | bias (world) | receiver pixels |")
        lines.append("|---|---|---|---|---|---|---|---|")
        for s, a in area.items():
            lines.append(f"| {s} | {a['map_size']}² | {a['light_samples']} | {a['reference_views']} | "
                         f"{a['near']:.4g} | {a['far']:.4g} | {a['bias']:.3g} | {a['pixels']} |")
        lines.append("")
    if scattering:
        lines.append("| scene | scattering shadow map | MSAA | camera | epipolar map | reference ray march | "
                     "ray march row |")
        lines.append("|---|---|---|---|---|---|---|")
        for s, v in scattering.items():
            sm = v["shadow_map_size"]
            sm = f"{sm[0]}×{sm[1]}" if not np.isscalar(sm) else f"{sm}²"
            lines.append(f"| {s} | {sm} | {v['msaa']}× | {v['resolution'][0]}×{v['resolution'][1]} | "
                         f"{v['epipolar_size'][0]}×{v['epipolar_size'][1]} | {v['reference_samples']} samples | "
                         f"{v['raymarch_samples']} samples |")
        lines.append("")
    lines.append("## Headline claims of HPG17 (measured)")
    lines.append("")
    lines.append(f"Criteria: close = RMSE within {CLOSE_REL:.0%} (+1e-3); clearly below = at most "
                 f"{CLEARLY_BELOW:.0%} of the other's RMSE; leaks = leak_fraction > 0.")
    lines.append("")
    for claim, verdict, evidence in claims:
        word = {True: "**holds**", False: "**does not hold**", None: "**not measurable**"}[verdict]
        lines.append(f"- {claim}: {word}. {evidence}")
    lines.append("")
    lines.append("## Results")
    lines.append("")
    lines.append("| " + " | ".join(COLUMNS) + " |")
    lines.append("|" + "---|" * len(COLUMNS))
    for r in rows:
        lines.append("| " + " | ".join(_fmt(r[c]) for c in COLUMNS) + " |")
    lines.append("")
    if soft:
        lines.append("## Soft shadows under area lights (measured)")
        lines.append("")
        lines.append("Rows msm_soft (moment soft shadow mapping: one map from the light's centre, summed-area "
                     "table of moments, moment-based blocker search; Slides, 'Moment soft shadow mapping'), "
                     "pcss (the same centre map, 64-tap blocker search, 96-tap PCF), vwss (layered points from "
                     "the enlarged source view warped into N light-sample maps, 5-tap PCF in each; VWSS §3) and "
                     "mvr (the same N maps rasterized). Error: shadow intensity 1 − visibility against MVR with "
                     "the reference's own Poisson set of light samples, over the receiver pixels of the camera "
                     "view (the same pixels as the hard-shadow rows). texel_seconds: depth-map and texture "
                     "stages; fragment_seconds: lookups.")
        lines.append("")
        for s, st in soft.items():
            a = (area or {}).get(s, {})
            head = (f"**{s}** ({a.get('map_size', '?')}² maps, N = {a.get('light_samples', '?')}, reference MVR "
                    f"with {a.get('reference_views', '?')} light samples):")
            lines.append(head + " " + " ".join(st))
            lines.append("")
        for s, p in images.get("soft", {}).items():
            lines.append(f"![{s}: visibility]({p})")
            lines.append("")
    if artifacts is not None:
        a = artifacts
        lines.append("### Artifacts of moment soft shadow mapping (Slides, 'Results for soft shadows')")
        lines.append("")
        lines.append(f"![msm_soft artifacts]({images['artifacts'].get('.png', 'msm_soft_artifacts.png')}) "
                     f"(details: [{images['artifacts'].get('.md', 'msm_soft_artifacts.md')}]"
                     f"({images['artifacts'].get('.md', 'msm_soft_artifacts.md')}))")
        lines.append("")
        lines.append(f"- Light through a small hole takes the light's rectangular shape: lit-spot aspect "
                     f"{a['hole_aspect_msm']:.3f} (reference {a['hole_aspect_reference']:.3f}), fill of its "
                     f"bounding box {a['hole_fill_msm']:.3f} (1 = rectangle, 0.785 = ellipse).")
        lines.append(f"- A distant wall in the blocker-search region softens a near column's shadow: 10–90 % "
                     f"width {a['width_column']:.4f} without the wall, {a['width_column_wall']:.4f} with it; "
                     f"reference {a['width_reference']:.4f} in both (the wall changes the reference by at most "
                     f"{a['wall_changes_reference']:.3g}).")
        lines.append("")
    if scattering:
        lines.append("## Prefiltered single scattering")
        lines.append("")
        refs = sorted({v["reference_samples"] for v in scattering.values()})
        lines.append("Rows scattering_6m (six moments, filtered epipolar resampling), scattering_6m_unfiltered "
                     "(resampling the plain depth map) and raymarch (the slides' ray marching, "
                     f"{', '.join(str(v['raymarch_samples']) for v in scattering.values())} samples per ray): "
                     "for these rows the error is that of the scattering term (the integral of the light's "
                     "visibility along the view ray) normalized by t_max, the longest view ray, against ray "
                     f"marching with {', '.join(map(str, refs))} samples per ray; leak_fraction is the share of "
                     "pixels brighter than that reference by more than 0.05, flip_mean compares LDR images of "
                     "the normalized term (moments_ref.techniques.scattering.report_rows).")
        lines.append("")
        for s, p in images.get("scattering", {}).items():
            lines.append(f"![{s}: scattering]({p})")
            lines.append("")
    lines.append("## Error against run time")
    lines.append("")
    lines.append(f"![error against run time]({images['scatter']})")
    lines.append("")
    lines.append("## Error images")
    lines.append("")
    for s, p in images["errors"].items():
        lines.append(f"![{s}]({p})")
        lines.append("")
    lines.append("## Stages that ran")
    lines.append("")
    for s, st in stages.items():
        lines.append(f"- {s}: " + ", ".join(f"`{x}`" for x in st))
    lines.append("")
    return "\n".join(lines)


def run(scenes=None, full=False, out_dir="report", progress=True, *, techniques=None, shadow_map_size=None,
        msaa=None, resolution=None, noise_tiles=64, area=None, scattering=None):
    """Run the report and write its files to ``out_dir``.

    Parameters
    ----------
    scenes : list of str or Path, optional
        Shipped scene names or scene files; default all shipped scenes
        (:func:`moments_ref.scene.list_scenes`).
    full : bool
        2048² maps with 4× MSAA and the scenes' camera resolution (HPG17 §5);
        otherwise :func:`moments_ref.pipeline.reduced_settings`. The area-light
        rows then use :func:`moments_ref.pipeline.area_settings` with ``full``
        (the scene's map size, a 512-view MVR reference), the scattering rows
        the scene's own settings.
    out_dir : path
        Output folder (created).
    progress : bool
        tqdm progress bars (scenes, and stages per scene) on stderr.
    techniques : list of str, optional
        Only these techniques (default: every registered technique that applies
        to the scene: its light kind, translucency; plus the area-light rows
        under an area light and the scattering rows where the scene asks for them).
    shadow_map_size, msaa, resolution : optional
        Override the settings for every scene (tests, notebooks);
        ``shadow_map_size`` also sets the maps of the area-light rows.
    noise_tiles : int
        Blue-noise tiles (HPG17: 64).
    area : dict, optional
        Overrides of :func:`moments_ref.pipeline.area_settings` (``map_size``,
        ``light_samples``, ``reference_views``).
    scattering : dict, optional
        Overrides passed to :func:`moments_ref.pipeline.run_scattering`
        (``epipolar_size``, ``reference_samples``, ``raymarch_samples``).

    Returns
    -------
    dict with ``rows`` (list of dict, :data:`COLUMNS`), ``stages`` (scene -> list),
    ``claims``, ``soft`` (scene -> measured soft-shadow statements),
    ``artifacts`` (the measurements of ``msm_soft.artifact_images`` or None) and
    ``paths`` (name -> Path).

    Raises
    ------
    InputError
        Unknown scene or technique names (listing the known ones), a scene
        without receiver or camera (with the reason).
    """
    from .scene import list_scenes, load_scene

    out = Path(out_dir)
    names = list_scenes() if not scenes else list(scenes)
    loaded = [load_scene(s) for s in names]  # refuse bad names before any work
    for sc in loaded:
        pipeline.check_scene(sc)
    if techniques is not None:
        _check_names(techniques)
    area = dict(area or {})
    unknown = set(area) - {"map_size", "light_samples", "reference_views"}
    if unknown:
        raise InputError(f"area: unknown settings {sorted(unknown)}; known: map_size, light_samples, reference_views")
    flip_ok = _flip_available()
    rows, stages, settings, images = [], {}, {}, {"errors": {}, "soft": {}, "scattering": {}}
    figs, deferred, soft, area_settings, scat_settings, measured = {}, [], {}, {}, {}, {}
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=len(loaded), desc="report", unit="scene", file=sys.stderr, leave=False)
    try:
        for sc in loaded:
            if full:
                size, samples, res = (2048, 2048), 4, tuple(sc.camera.resolution)
            else:
                size, samples, res = pipeline.reduced_settings(sc)
            if shadow_map_size is not None:
                size = (shadow_map_size, shadow_map_size) if np.isscalar(shadow_map_size) else tuple(shadow_map_size)
            samples = samples if msaa is None else int(msaa)
            res = res if resolution is None else tuple(resolution)
            kind = getattr(sc.light, "kind", "directional")
            settings[sc.name] = {"size": size, "msaa": samples, "resolution": res,
                                 "light": "area (spot from its centre)" if kind == "area" else kind}
            stages[sc.name] = []
            techs = _scene_techniques(sc, techniques)
            if techs:
                acfg = None
                if any(n in pipeline.AREA_OUTPUTS for n in techs) and kind == "area":
                    ms = area.get("map_size") or (max(size) if shadow_map_size is not None else None)
                    acfg = pipeline.area_settings(sc, full, map_size=ms, light_samples=area.get("light_samples"),
                                                  reference_views=area.get("reference_views"))
                result = pipeline.run(sc, techs, shadow_map_size=size, msaa=samples, resolution=res,
                                      noise_tiles=noise_tiles, area=acfg, progress=progress)
                stages[sc.name] += list(result.stages)
                measured[sc.name] = paper_claims.scene_measurements(result)
                for n in result.techniques:
                    m = metrics(result.shadow[n], result.reference[n])
                    fl = math.nan
                    if flip_ok:
                        fl = flip_mean(shaded_image(result.gbuffer, result.reference[n]),
                                       shaded_image(result.gbuffer, result.shadow[n]))
                    rows.append({"scene": sc.name, "technique": n, "bits_per_texel": result.bits_per_texel[n], **m,
                                 "flip_mean": fl, "texel_seconds": result.texel_seconds[n],
                                 "fragment_seconds": result.fragment_seconds[n]})
                figs[f"errors_{sc.name}.png"] = _error_figure(result, sc.name)
                images["errors"][sc.name] = f"errors_{sc.name}.png"
                if result.area:
                    area_settings[sc.name] = {**result.area, "pixels": int(result.gbuffer.pixel.size)}
                    soft_names = [n for n in result.techniques if n in pipeline.AREA_OUTPUTS]
                    figs[f"soft_{sc.name}.png"] = _soft_figure(result, sc.name, soft_names)
                    images["soft"][sc.name] = f"soft_{sc.name}.png"
            scat = _scene_scattering(sc, techniques)
            if scat:
                sr = pipeline.run_scattering(sc, shadow_map_size=None if full and shadow_map_size is None else size,
                                             msaa=None if full and msaa is None else samples,
                                             resolution=None if full and resolution is None else res,
                                             **(scattering or {}))
                stages[sc.name] += sr.stages
                rows += [r for r in sr.rows if r["technique"] in scat]
                scat_settings[sc.name] = sr.settings
                deferred.append((sr.images, sr.t_max, f"scattering_{sc.name}.png"))
                images["scattering"][sc.name] = f"scattering_{sc.name}.png"
            if bar is not None:
                bar.update(1)
    finally:
        if bar is not None:
            bar.close()

    import matplotlib.pyplot as plt

    for s in area_settings:
        soft[s] = soft_statements(rows, s)
    figs["scatter.png"] = plot_error_vs_runtime(rows)
    images["scatter"] = "scatter.png"
    claims = evaluate_claims(rows)
    paths = {}
    artifacts = None
    try:
        if any(r["technique"] == "msm_soft" for r in rows):
            # The artifacts the slides name, on synthetic scenes with exact references (writes its
            # own two files atomically; report.md states its measurements).
            from .techniques import msm_soft

            artifacts, apaths = msm_soft.artifact_images(out)
            paths.update({Path(x).name: Path(x) for x in apaths})
            images["artifacts"] = {Path(x).suffix: Path(x).name for x in apaths}
        # Every text is complete before the report's own files are written; each file is
        # written atomically (temporary file, then rename), so an interrupted run
        # leaves no half-written file.
        texts = {"results.csv": _csv_text(rows), "stages.json": json.dumps(stages, indent=2) + "\n",
                 "report.md": _markdown(rows, stages, settings, claims, images, flip_ok, area_settings, soft,
                                        scat_settings, artifacts)}
        texts["claims.json"], texts["report.md"] = paper_claims.gather(rows, measured, texts["report.md"], full)
        for name, fig in figs.items():
            paths[name] = save_figure(fig, out / name, dpi=110)
    finally:
        for fig in figs.values():
            plt.close(fig)
    from .techniques.scattering import write_images

    for imgs, t_max, name in deferred:
        paths[name] = Path(write_images(imgs, t_max, out / name))
    for name, text in texts.items():
        paths[name] = write_text(out / name, text)
    return {"rows": rows, "stages": stages, "claims": claims, "soft": soft, "artifacts": artifacts, "paths": paths}


def build_parser():
    """The argument parser of ``moments-ref report``."""
    p = argparse.ArgumentParser(prog="moments-ref report",
                                description="Error against run time of the shadow techniques (HPG17 §5).")
    p.add_argument("--scene", action="append", metavar="NAME|FILE",
                   help="shipped scene name or scene file (repeatable; default: all shipped scenes)")
    p.add_argument("--full", action="store_true", help="2048² shadow maps with 4× MSAA at the camera's resolution")
    p.add_argument("--out", required=True, type=Path, help="output folder")
    p.add_argument("--no-progress", action="store_true", help="no progress bars")
    return p


def main(argv=None) -> int:
    """``moments-ref report``; returns the exit code (0 done, 2 bad usage or input)."""
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:
        return int(exc.code or 0)
    try:
        res = run(scenes=args.scene, full=args.full, out_dir=args.out, progress=not args.no_progress)
    except InputError as exc:
        print(f"moments-ref report: {exc}", file=sys.stderr)
        return 2
    print(f"wrote {', '.join(str(p) for p in res['paths'].values())}")
    for claim, verdict, evidence in res["claims"]:
        print(f"{claim}: {({True: 'holds', False: 'does not hold', None: 'not measurable'})[verdict]} ({evidence})")
    return 0
