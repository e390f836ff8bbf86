"""Error against run time: every technique on every scene, measured against the reference.

``moments-ref report`` (:func:`main`, :func:`run`). What it runs, how it measures
and what it writes is described once, in docs/report.md; the
arguments are :func:`add_arguments` (shared with the command line). Each scene runs
its techniques in one stage graph (:func:`moments_ref.pipeline.run`); each row's
error is its reference's metric (``Technique.truth``,
:class:`~moments_ref.techniques.Reference`), and each reference used adds its
figures and, where it has one, its section of report.md.

Package layout: this module runs and writes; :mod:`._text` holds results.csv
(:data:`COLUMNS`), the claims and report.md, :mod:`._plots` the error-against-cost
plots, :mod:`._pareto` the fronts and the summary, :mod:`._winners` winners.csv, :mod:`._crops` the crops where
the techniques differ most, :mod:`._machine` the machine, :mod:`._jobs` the worker
processes; :mod:`.paper_claims` the papers' claims, :mod:`.vwss` the ``moments-ref
vwss`` comparison, :mod:`.scattering_temporal` the temporal scattering claim.

References
----------
.. [1] HPG17: Christoph Peters. 2017. *Non-Linearly Quantized Moment Shadow Maps*. In Proceedings
       of High Performance Graphics (HPG '17). ACM. The non-linear quantization Φ, Ψ4, Algorithms
       1–3, the texel formats and the compute shader of §4.1.
.. [2] VWSS: Adam Marrs, Benjamin Watson and Christopher Healey. 2018. *View-warped Multi-view Soft
       Shadowing for Local Area Lights*. Journal of Computer Graphics Techniques (JCGT) 7, 3, 1–28.
       http://jcgt.org/published/0007/03/01/
.. [3] Slides: Christoph Peters. *Rendering antialiased shadows with moment shadow mapping*,
       lecture slides (PDF version, with notes) on moment shadow mapping, translucent occluders,
       moment soft shadow mapping and prefiltered single scattering; http://MomentsInGraphics.de/.
       Cited by slide title, e.g. Slides, "Bias the moments".
.. [4] FLIP: Pontus Andersson, Jim Nilsson, Tomas Akenine-Möller, Magnus Oskarsson, Kalle Åström
       and Mark D. Fairchild. 2020. *ꟻLIP: A Difference Evaluator for Alternating Images*.
       Proceedings of the ACM on Computer Graphics and Interactive Techniques (HPG 2020) 3, 2. Used
       through the package ``flip-evaluator``.
"""


from __future__ import annotations

import argparse
import json
import sys
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .._arrays import InputError, one_line
from .._io import REPORT_PNG_LEVEL, figure_png, write_bytes, write_text
from .._options import add_report_arguments
from ..metrics import LEAK_THRESHOLD, flip_available, flip_mean, metrics, shaded_image
from . import paper_claims, scattering_temporal
from .. import pipeline
from .. import techniques as _techniques
from ..scene.gbuffer import check_shaded
from ..techniques._interface import PROJECTION
from ..techniques import REFERENCES, get_reference
from ..techniques.area import soft_statements
from ..techniques.scattering import RAYS
from ._crops import crop_figures
from ._jobs import WorkerDied, Workers, usable_cores
from ._machine import copy_rate, machine, machine_lines
from ._pareto import front_lines, mark_pareto, pareto_mask, summary_lines, truth_of
from ._plots import plot_error_vs_runtime, plot_fronts
from ._winners import own_scale, own_total, winner_lines, winners, winners_csv
from ._text import CLEARLY_BELOW, CLOSE_REL, COLUMNS, csv_text, evaluate_claims, markdown, read_results

__all__ = ["COLUMNS", "LEAK_THRESHOLD", "AREA_ROWS", "run", "main", "metrics", "shaded_image", "flip_mean",
           "evaluate_claims", "soft_statements", "read_results", "plot_error_vs_runtime", "plot_fronts", "build_parser",
           "add_arguments",
           "pareto_mask", "mark_pareto"]

_ = (CLOSE_REL, CLEARLY_BELOW)  # re-exported
#: Area-light outputs in the default run (those measured against reference ``mvr``).
AREA_ROWS = pipeline.AREA_OUTPUTS


def _check_names(requested, loaded):
    """Refuse unknown technique names (listing every known one) and names no scene can run (with the reason)."""
    known = _techniques.names()
    for n in requested:
        if n not in known:
            raise InputError(f"technique: unknown technique {n!r}; known techniques: {', '.join(known)}")
        reasons = [_techniques.get(n).refusal(sc) for sc in loaded]
        if reasons and all(reasons):
            raise InputError(f"technique: {reasons[0]}")


def _check_overrides(overrides):
    """Per reference option its overrides, each key checked against the reference's settings."""
    out = {}
    for option, values in overrides.items():
        if not values:
            continue
        ref = next(r for r in REFERENCES.values() if r.option == option)
        unknown = set(values) - set(ref.settings_keys)
        if unknown:
            raise InputError(f"{option}: unknown settings {sorted(unknown)}; known: {', '.join(ref.settings_keys)}")
        out[option] = dict(values)
    return out


def _scene_techniques(scene, requested=None, all_techniques=False):
    """The techniques of a scene: the requested ones, else all (``all_techniques``) or the scene's ``outputs``.

    Requested names and ``all_techniques`` keep those that can run on the scene
    (``Technique.refusal``); a scene's own ``outputs`` are run as listed (a name
    it cannot run is refused by the pipeline with the reason); a scene without
    ``outputs`` runs every technique that can run on it.
    """
    if requested is None and not all_techniques and scene.outputs:
        return list(dict.fromkeys(scene.outputs))
    names = _techniques.names() if requested is None else list(requested)
    return [n for n in names if _techniques.get(n).refusal(scene) is None]


def _own_settings(sc):
    return tuple(sc.shadow_map_size), int(sc.msaa), tuple(sc.camera.resolution)


def _scene_settings(sc, full, given):
    """Map size, MSAA and camera resolution of a run: the scene's own with ``full``, else reduced; ``given`` wins."""
    if full:
        size, samples, res = _own_settings(sc)
    else:
        size, samples, res = pipeline.reduced_settings(sc)
    if given["shadow_map_size"] is not None:
        s = given["shadow_map_size"]
        size = (s, s) if np.isscalar(s) else tuple(s)
    samples = samples if given["msaa"] is None else int(given["msaa"])
    res = res if given["resolution"] is None else tuple(given["resolution"])
    return size, samples, res


@dataclass
class _Collected:
    """What the scenes contributed, written at the end."""

    full: bool = False
    repeats: int = 1
    machine: list = field(default_factory=list)
    rows: list = field(default_factory=list)
    stages: dict = field(default_factory=dict)
    settings: dict = field(default_factory=dict)
    references: dict = field(default_factory=dict)  # reference name -> scene -> settings
    pngs: dict = field(default_factory=dict)  # file name -> PNG bytes of the scenes' figures
    measured: dict = field(default_factory=dict)  # scene -> numbers the paper claims need
    images: dict = field(default_factory=dict)  # reference name -> [file names]


def _value(v):
    if isinstance(v, (tuple, list)):
        return "×".join(_value(x) for x in v)
    return f"{v:.4g}" if isinstance(v, float) else str(v)


def _reference_text(ref_name, cfg):
    ref = get_reference(ref_name)
    if not cfg:
        return f"{ref_name} ({ref.label})"
    items = ", ".join(f"{k} {_value(v)}" for k, v in cfg.items())
    return f"{ref_name} ({items})"


def _announce(acc, sc, names, used, ref_settings, full):
    """Record the settings a scene runs with and print them on stderr, saying what was reduced."""
    size, samples, res = used
    own = _own_settings(sc)
    kind = getattr(sc.light, "kind", "directional")
    refs = "; ".join(_reference_text(n, c) for n, c in ref_settings.items())
    reduced = [f"{what} {a} (scene: {b})" for what, a, b in
               (("shadow map", "×".join(map(str, size)), "×".join(map(str, own[0]))),
                ("MSAA", f"{samples}×", f"{own[1]}×"),
                ("camera", "×".join(map(str, res)), "×".join(map(str, own[2])))) if a != b]
    acc.settings[sc.name] = {"size": size, "msaa": samples, "resolution": res, "own": own, "references": refs,
                             "light": "area (spot from its centre)" if kind == "area" else kind,
                             "techniques": list(names), "reduced": reduced}
    note = (f"not the scene's own: {', '.join(reduced)}; --full runs the scene's own settings"
            if reduced else "the scene's own settings")
    print(f"{sc.name}: {', '.join(names)}; shadow map {'×'.join(map(str, size))}, MSAA {samples}×, camera "
          f"{'×'.join(map(str, res))}, reference {refs}, {acc.repeats} timed repeats ({note})", file=sys.stderr)


def _scene_plan(acc, sc, full, given, requested, overrides, noise_tiles, all_techniques=False):
    """``(techniques, pipeline.Settings, what to announce)`` of a scene; ``None`` when nothing runs on it.

    A scene whose camera would shade no receiver pixel at the run's settings is
    refused here, before any work (:func:`moments_ref.scene.gbuffer.check_shaded`);
    its settings are announced (:func:`_announce`) once every scene passed.
    """
    size, samples, res = _scene_settings(sc, full, given)
    acc.stages[sc.name] = []
    names = _scene_techniques(sc, requested, all_techniques)
    if not names:
        return None
    st = pipeline.Settings(shadow_map_size=size, msaa=samples, resolution=res, noise_tiles=noise_tiles,
                           overrides=overrides, full=full, repeats=acc.repeats, clock="cpu")
    p = pipeline.plan(sc, names, st)
    if PROJECTION in p.graph.order(p.targets):
        g = check_shaded(sc, res, sc.light_clip_from_world(), size)
        if g is not None and p.context.scene is sc:  # the run's own G-buffer: handed to it, not rendered again
            st = st.replace(camera_gbuffer=g)
    return names, st, (names, (size, samples, res), p.settings, full)


def _check_unique(scenes, loaded):
    """Refuse two scenes of the same name: their rows, stages and images would overwrite each other."""
    given = {}
    for arg, sc in zip(scenes, loaded):
        if sc.name in given:
            first = given[sc.name]
            what = (f"scene {str(arg)!r} is given twice" if str(first) == str(arg) else
                    f"two scenes are named {sc.name!r} ({first} and {arg}); give one of them another name "
                    "(name = \"...\" in its file)")
            raise InputError(f"scene: {what}: their rows and images would overwrite each other")
        given[sc.name] = arg


def _png(fig):
    """The PNG bytes of ``fig`` (dpi 110, no timestamp, zlib level :data:`~moments_ref._io.REPORT_PNG_LEVEL`); closes ``fig``."""
    import matplotlib.pyplot as plt

    try:
        return figure_png(fig, dpi=110, compress_level=REPORT_PNG_LEVEL)
    finally:
        plt.close(fig)


def _scene_task(sc, names, settings, progress):
    """A scene's share of the report, here or in a worker: rows, stages, claim numbers, figures as PNG bytes.

    Timed stages are measured in CPU seconds of this process (``settings.clock``, "cpu").
    Everything returned is plain data (picklable); nothing is written.
    """
    keep = (*paper_claims.stages_read(settings.msaa), RAYS)  # every other stage's value goes after its last use
    result = pipeline.run(sc, names, settings.replace(progress=progress, keep=keep))
    part = {"rows": result.rows(), "stages": result.stage_table(), "references": {}, "images": {}, "pngs": {},
            "measured": None if result.gbuffer is None else paper_claims.scene_measurements(result)}
    # (a scattering-only run shades no receiver pixels: nothing the claims need)
    groups = {}
    for n in result.techniques:
        groups.setdefault(result.truth[n], []).append(n)
    for ref_name, ref_names in groups.items():
        ref = get_reference(ref_name)
        part["references"][ref_name] = result.settings[ref_name]
        for fname, fig in (ref.figures(result, ref_names) if ref.figures else {}).items():
            part["pngs"][fname] = _png(fig)
            part["images"].setdefault(ref_name, []).append(fname)
    crops = crop_figures(result, groups)  # the insets where the techniques differ most (._crops)
    for fname, fig in crops.items():
        part["pngs"][fname] = _png(fig)
        part["images"].setdefault("crops", []).append(fname)
    return part


def _collect(acc, sc, part):
    """Add a scene's :func:`_scene_task` result to ``acc`` (called in scene order)."""
    acc.stages[sc.name] = part["stages"]
    if part["measured"] is not None:
        acc.measured[sc.name] = part["measured"]
    scale = own_scale(acc.settings[sc.name])
    for row in part["rows"]:
        for suffix in ("", "_min", "_max"):
            row[f"own_total_seconds{suffix}"] = own_total(row, scale, suffix)
    acc.rows += part["rows"]
    for ref_name, cfg in part["references"].items():
        acc.references.setdefault(ref_name, {})[sc.name] = cfg
    for ref_name, fnames in part["images"].items():
        acc.images.setdefault(ref_name, []).extend(fnames)
    acc.pngs.update(part["pngs"])


def _artifacts_task(names):
    """Each technique of ``names`` with measured artifacts: (first measurements, markdown lines, file bytes).

    The artifacts write their own files; they are written to a temporary folder
    here and their bytes returned, so that the report's folder is written only
    at the end.
    """
    first, lines, files = None, [], {}
    with tempfile.TemporaryDirectory(prefix="moments-ref-artifacts-") as tmp:
        for n in names:
            m, more, written = _techniques.get(n).artifacts(Path(tmp))
            first = m if first is None else first
            lines += more
            files.update({Path(x).name: Path(x).read_bytes() for x in written})
    return first, lines, files


def _tasks(plans, full, jobs, progress):
    """The report's tasks ``(key, function, args)``: each scene, the artifacts, the temporal claim.

    With more than one job the longest go first (longest-processing-time order), so
    that a short task ends the run, not a long one started last. A task's weight is
    its cost in techniques: a scene counts its techniques, plus four for a multi-view
    (MVR) reference; the temporal claim counts five, the artifacts two. Measured (CPU
    seconds per task, default and ``--full``): knot 19 and 167 (4 techniques and the
    MVR reference), railing 13 and 115 (8), chair 8 and 77 (2 and the reference),
    temporal claim 7 and 43, facade and three-occluders 5–6 and 45–48 (3), scattering
    4.5 and 22, artifacts 3 and 2.4, translucent 1.7 and 10 (1): in this order two
    workers end within a few seconds of each other.
    """
    others, weight = [], {("artifacts",): (2, 0), ("temporal",): (5, 0)}
    ran = [n for _, (names, _) in plans for n in names]
    with_artifacts = [n for n in dict.fromkeys(ran) if _techniques.get(n).artifacts is not None]
    if with_artifacts:
        others.append((("artifacts",), _artifacts_task, (with_artifacts,)))
    scene = paper_claims.temporal_scene([sc.name for sc, (names, _) in plans if "scattering_6m" in names])
    if scene is not None:
        others.append((("temporal",), paper_claims.temporal_claim, (scene, full)))
    serial = min(jobs, len(plans) + len(others)) == 1  # per-stage bars only in this process
    tasks = []
    for sc, (names, settings) in plans:
        truths = {_techniques.get(n).truth for n in names}
        tasks.append((("scene", sc.name), _scene_task, (sc, names, settings, progress and serial)))
        multi_view = "mvr" in truths
        weight[tasks[-1][0]] = (len(names) + 4 * multi_view, multi_view)
    tasks += others
    if not serial:
        tasks.sort(key=lambda t: weight[t[0]], reverse=True)
    return tasks


def _fronts_task(rows):
    """``{front_<reference>.png: PNG bytes}`` of :func:`plot_fronts` (``rows`` marked by :func:`mark_pareto`)."""
    return {name: _png(fig) for name, fig in plot_fronts(rows).items()}


def _front_tasks(rows):
    """One :func:`_fronts_task` per reference (each plot needs only its own scenes' rows)."""
    refs = dict.fromkeys(truth_of(r) for r in rows)
    return [(("front", ref), _fronts_task, ([r for r in rows if truth_of(r) == ref],)) for ref in refs]


def _write(acc, out, flip_ok, done, fronts, claim_crops):
    """Write every file of the report to ``out``; ``done``: the results of :func:`_tasks`; ``fronts`` and
    ``claim_crops`` (side-by-side crops of the claims about images): PNG bytes by file name."""
    statements = {name: {s: get_reference(name).statements(acc.rows, s) for s in scenes}
                  for name, scenes in acc.references.items() if get_reference(name).statements}
    refs = [(get_reference(n), cfg, statements.get(n, {})) for n, cfg in acc.references.items()]
    artifacts, lines, files = done.get(("artifacts",), (None, [], {}))
    temporal = done.get(("temporal",))
    # Every text and image is complete before the first file is written; each file is
    # written atomically (temporary file, then rename), so an interrupted run
    # leaves no half-written file.
    found = winners(acc.rows, truth_of)
    own = {s: f"{'×'.join(map(str, cfg['own'][0]))} map, {'×'.join(map(str, cfg['own'][2]))} camera"
           for s, cfg in acc.settings.items()}
    texts = {"results.csv": csv_text(acc.rows), "stages.json": json.dumps(acc.stages, indent=2) + "\n",
             "winners.csv": winners_csv(found),
             "report.md": markdown(acc.rows, acc.stages, acc.settings,
                                   {"fronts": list(fronts), **acc.images}, flip_ok, refs, lines,
                                   answer=acc.machine + winner_lines(found, own) + front_lines(acc.rows)
                                   + summary_lines(acc.rows), repeats=acc.repeats)}
    texts["claims.json"], texts["report.md"] = paper_claims.gather(
        acc.rows, acc.measured, texts["report.md"], acc.full, extra=() if temporal is None else (temporal,),
        temporal=False, images=tuple(claim_crops))
    paths = _write_set(out, {**files, **acc.pngs, **fronts, **claim_crops, **texts})
    return {"rows": acc.rows, "stages": acc.stages, "claims": json.loads(texts["claims.json"]),
            "soft": statements.get("mvr", {}),
            "artifacts": artifacts, "paths": paths, "settings": acc.references}


#: The file that marks a report folder whose writing did not finish (see :func:`_write_set`).
INCOMPLETE = "INCOMPLETE"


def _write_set(out, blobs):
    """Write ``{file name: bytes or text}`` into ``out``, marked :data:`INCOMPLETE` until the last file is written.

    Each file is written atomically; the set is not: the marker is written first
    and removed after the last file, so that a folder whose writing failed (a full
    disk, a folder in the way) or was killed says so. A failure is an
    :class:`InputError` naming the file, the reason and how many files were written.
    """
    bad = [n for n in blobs if Path(n).name != n or n in (".", "..", INCOMPLETE)]
    if bad:  # names are made from checked scene names; this guards the folder anyway
        raise InputError(f"out: refusing to write {bad[0]!r} (not a plain file name inside {out})")
    marker, paths, name = out / INCOMPLETE, {}, INCOMPLETE
    try:
        write_text(marker, f"This report was not completely written: {len(blobs)} files were to be written, "
                           f"{', '.join(blobs)}. Rerun moments-ref report to replace it.\n")
        for name, data in blobs.items():
            paths[name] = (write_text if isinstance(data, str) else write_bytes)(out / name, data)
        marker.unlink()
    except OSError as exc:
        state = ("nothing was written" if name == INCOMPLETE else
                 f"the report in {out} is incomplete ({len(paths)} of {len(blobs)} files written; {marker} says so)")
        raise InputError(f"out: could not write {out / name} ({exc.strerror or exc}); {state}") from None
    return paths


def _timing_line(jobs, cores, repeats):
    """The machine section's sentence on how the timings were taken."""
    side = ("one scene at a time" if jobs == 1 else
            f"{jobs} worker processes side by side, so a timed stage shared the memory bandwidth (and, with "
            "more workers than cores or other load, the cores) with the other workers; `--jobs 1` times each "
            "stage alone")
    return (f"Timings are CPU seconds of the process that ran the stage (`time.process_time`, all its threads: "
            f"not inflated while other processes wait for a core), each the median of {repeats} timed runs "
            f"after a warm-up. The scenes ran {side} ({cores} usable cores).")


def run(scenes=None, full=False, out_dir="report", progress=True, *, techniques=None, shadow_map_size=None,
        msaa=None, resolution=None, noise_tiles=64, area=None, scattering=None, all_techniques=False, repeats=3,
        jobs=None):
    """Run the report and write its files to ``out_dir``.

    Parameters
    ----------
    scenes : list of str or Path, optional
        Shipped scene names or scene files; default all shipped scenes
        (:func:`moments_ref.scene.list_scenes`).
    full : bool
        The scenes' own map size, MSAA and camera resolution (the shipped
        hard-shadow scenes: 2048² with 4× MSAA at 1920×1080, HPG17 §5);
        otherwise :func:`moments_ref.pipeline.reduced_settings`. The references
        then use their paper-scale settings (area lights: the scene's map size, a
        512-view MVR reference; scattering: the scene's own settings).
    out_dir : path
        Output folder (created).
    progress : bool
        tqdm progress bars (scenes, and stages per scene) on stderr.
    techniques : list of str, optional
        Only these techniques, on each scene that can run them (default: the
        scene's ``outputs``). A name no scene can run is refused with the reason.
    all_techniques : bool
        Every registered technique that can run on each scene (light kind,
        translucency, medium) instead of the scene's ``outputs``.
    repeats : int
        Timed repeats of every stage of a technique's cost, after a warm-up run
        (results.csv: median, min, max; CPU seconds of the process running the
        stage, ``time.process_time``).
    jobs : int, optional
        Worker processes running the scenes, the temporal scattering claim and
        the artifacts side by side (:mod:`._jobs`; default the usable cores,
        ``len(os.sched_getaffinity(0))``); 1 runs everything in this process, one
        after the other. The results do not depend on it, only the timings'
        competition for the machine (stated in report.md).
    shadow_map_size, msaa, resolution : optional
        Override the settings for every scene (tests, notebooks);
        ``shadow_map_size`` also sets the maps of the area-light rows.
    noise_tiles : int
        Blue-noise tiles (HPG17: 64).
    area : dict, optional
        Overrides of the area-light settings (``map_size``, ``light_samples``,
        ``reference_views``, ...: :func:`moments_ref.techniques.area.configure`).
    scattering : dict, optional
        Overrides of the scattering settings (``epipolar_size``,
        ``reference_samples``, ``raymarch_samples``).

    Returns
    -------
    dict with ``rows`` (list of dict, :data:`COLUMNS`), ``stages`` (scene -> list),
    ``claims``, ``soft`` (scene -> measured soft-shadow statements),
    ``artifacts`` (the measurements of ``msm_soft.artifact_images`` or None),
    ``settings`` (reference -> scene -> its settings), ``paths`` (name -> Path)
    and ``tasks`` (task key -> the pid, CPU and wall seconds of the process that
    ran it, :meth:`._jobs.Workers.run`; the scenes, the temporal claim, the
    artifacts, then one ``("front", reference)`` plot each).

    Raises
    ------
    InputError
        Unknown scene or technique names (listing the known ones), two scenes of
        the same name, a scene without receiver or camera or whose camera shades
        no receiver pixel (with the reason), a write that failed (the folder is
        then marked incomplete, :func:`_write`).
    """
    from ..scene import list_scenes, load_scene

    if isinstance(out_dir, str) and not out_dir.strip():
        raise InputError(f"out_dir: expected a folder, got {out_dir!r}")
    out = Path(out_dir)
    scenes = list_scenes() if not scenes else list(scenes)
    loaded = [load_scene(s) for s in scenes]  # refuse bad names first
    _check_unique(scenes, loaded)
    for sc in loaded:
        pipeline.check_scene(sc)
    if techniques is not None:
        _check_names(techniques, loaded)
    overrides = _check_overrides({"area": area, "scattering": scattering})
    given = {"shadow_map_size": shadow_map_size, "msaa": msaa, "resolution": resolution}
    flip_ok = flip_available()
    jobs = usable_cores() if jobs is None else int(jobs)
    if jobs < 1:
        raise InputError(f"jobs: expected a positive integer, got {jobs}")
    acc = _Collected(full=full, repeats=max(int(repeats), 1))
    timings = {}
    with Workers(jobs) as workers:
        # They import the package while the copy rate is measured (in CPU seconds) and the scenes are planned.
        workers.start(len(loaded) + 2, __name__)
        acc.machine = machine_lines(machine(), copy_rate())
        plans = [(sc, plan) for sc in loaded if (plan := _scene_plan(acc, sc, full, given, techniques, overrides,
                                                                      noise_tiles, all_techniques)) is not None]
        for sc, (_, _, announce) in plans:  # every scene checked first: no line precedes a refusal
            _announce(acc, sc, *announce)
        plans = [(sc, (names, st)) for sc, (names, st, _) in plans]
        tasks = _tasks(plans, full, jobs, progress)
        acc.machine[-1:] = [_timing_line(min(jobs, len(tasks)) or 1, usable_cores(), acc.repeats), ""]
        done = workers.run(tasks, progress=progress, timings=timings)
        for sc, _ in plans:
            _collect(acc, sc, done[("scene", sc.name)])
        mark_pareto(acc.rows)
        # The front plots need every scene's rows, the claims' crops every scene's crops: a second batch on
        # the same (warm) workers, which have matplotlib loaded (this process then never imports it).
        second = _front_tasks(acc.rows) + [(CLAIM_CROPS, paper_claims.crop_pngs, (_claim_crops_only(acc.measured),))]
        fronts, claim_crops = {}, {}
        for key, part in workers.run(second, timings=timings).items():
            (claim_crops if key == CLAIM_CROPS else fronts).update(part)
    return {**_write(acc, out, flip_ok, done, fronts, claim_crops), "tasks": timings}


#: The key of the task drawing the claims' side-by-side crops (:func:`paper_claims.crop_pngs`).
CLAIM_CROPS = ("claim crops",)


def _claim_crops_only(measured):
    """The part of each scene's claim measurements that :func:`paper_claims.crop_pngs` reads (sent to a worker)."""
    return {s: {"crops": m.get("crops")} for s, m in measured.items()}


#: The arguments of ``moments-ref report`` on a parser (their one definition, shared with the command line).
add_arguments = add_report_arguments


def build_parser():
    """The argument parser of ``moments-ref report`` (:func:`add_arguments`)."""
    return add_arguments(argparse.ArgumentParser(prog="moments-ref report",
                                                 description="Error against run time of the shadow techniques (HPG17 §5)."))


def main(args=None) -> int:
    """``moments-ref report``; returns the exit code (0 done, 2 bad usage or input).

    ``args``: the parsed arguments of :func:`add_arguments` (what ``moments-ref report``
    passes), or a list of command-line strings (parsed here).
    """
    if args is None or isinstance(args, (list, tuple)):
        try:
            args = build_parser().parse_args(args)
        except SystemExit as exc:
            return int(exc.code or 0)
    try:
        if args.technique and args.all_techniques:
            raise InputError("technique: give --technique or --all-techniques, not both")
        res = run(scenes=args.scene, full=args.full, out_dir=args.out, progress=not args.no_progress,
                  techniques=args.technique, all_techniques=args.all_techniques, repeats=args.repeats,
                  jobs=args.jobs)
    except InputError as exc:
        print(one_line(f"moments-ref report: {exc}"), file=sys.stderr)
        return 2
    print(f"wrote {', '.join(str(p) for p in res['paths'].values())}")
    # The paper claims as claims.json judges them (the paper's own figures; report.md has the table).
    for c in res["claims"]:
        print(f"{c['id']} ({c['source']}): {c['verdict']}")
    return 0
