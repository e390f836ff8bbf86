"""A run of ``conformance --all`` kept in a file, and what another machine's run changes against this one's.

``moments-ref conformance --all --record FILE`` (on a GPU, say) writes every golden row's
outputs, every shipped kernel's texels, the verdicts, the timings and the measured
floating-point behaviour into one ``.npz``. ``moments-ref conformance --all --out docs/
--gpu-record FILE`` runs this machine's drivers (Mesa's llvmpipe and lavapipe without a
GPU) as usual and appends a section built from the file: the GPU's verdicts, its probes
(``fma``, division, ``sqrt``, ``exp``/``log``, denormals) and, row by row, where its outputs
differ from this run's. The file holds plain arrays and one JSON document (no pickles).
"""

from __future__ import annotations

import io
import json
import statistics
import sys
import time

import numpy as np

from .._arrays import InputError
from ._report import fmt
from .verdict import ulp_distance

__all__ = ["RECORD_VERSION", "kernel_runs", "save", "load", "gpu_markdown"]

#: The format of a record; a file of another version is refused.
RECORD_VERSION = 1
_SEP = "|"


def kernel_runs(adapter=None, progress=False):
    """Every shipped kernel of every available language on every driver: one dict per driver run.

    Keys: ``case``, ``language``, ``driver``, ``renderer``, ``passed`` (None when not run),
    ``note`` (why not run, or why it failed), ``cells`` (worst error/tolerance per category),
    ``codes`` (the kernel's codes against the global path's) and ``output`` (the judged texels).
    """
    from .kernel.cli import SHIPPED_KERNELS, shipped_kernel
    from .kernel.run import KERNEL_DRIVERS, run_kernel
    from .languages import available

    runs = []
    for case, (_, entries) in SHIPPED_KERNELS.items():
        for language in (x for x in entries if available(x)):
            path, entry = shipped_kernel(case, language)
            for driver in (adapter,) if adapter not in (None, "both") else KERNEL_DRIVERS:
                runs += _kernel_run(path, entry, case, language, driver, run_kernel)
        if progress:
            print(f"  kernels: {case} done", file=sys.stderr)
    return runs


def _kernel_run(path, entry, case, language, driver, run_kernel):
    """:func:`kernel_runs`' dicts of one kernel on one driver (one dict; the report's runs)."""
    try:
        report = run_kernel(path, entry, case, language, driver, timing=False)
    except Exception as exc:  # noqa: BLE001 - no driver, or a kernel this driver refuses: noted, not fatal
        first = next((x.strip() for x in str(exc).splitlines() if x.strip()), type(exc).__name__)
        failed = isinstance(exc, InputError)  # the kernel does not compile or bind here: a failure of the port
        return [dict(case=case, language=language, driver=driver, renderer="", passed=False if failed else None,
                     note=first, cells="", codes="", output=None)]
    race = bool(report.shared and (report.shared.get("races") or report.shared.get("error")))
    out = []
    for r in report.runs:
        v = r.verdict
        cells = "" if v is None else ", ".join(f"{c.category} {fmt(c.worst_score)}" for c in v.categories.values())
        codes = "" if not r.codes else f"{r.codes['exact']} equal, {r.codes['differ']} differ"
        out.append(dict(case=case, language=language, driver=r.driver, renderer=r.renderer,
                        passed=None if r.skipped else bool(r.passed and not race), note=r.skipped or r.reason or
                        ("a race in shared memory" if race else ""), cells=cells, codes=codes,
                        output=None if r.output is None else np.asarray(r.output)))
    return out


def save(path, results, kernels, probe_text, compilers, total):
    """Write a record of a ``--all`` run (``_run_all``'s results and :func:`kernel_runs`) atomically."""
    from .._io import write_bytes

    arrays, targets = {}, []
    for language, driver, renderer, rows, times, outputs, refused in results:
        targets.append(dict(language=language, driver=driver, renderer=renderer, rows=rows, times=times,
                            refused=refused))
        for case, outs in outputs.items():
            for name, arr in outs.items():
                arrays[_SEP.join(("f", language, driver, case, name))] = np.asarray(arr)
    kmeta = []
    for k in kernels:
        kmeta.append({key: v for key, v in k.items() if key != "output"})
        if k["output"] is not None:
            arrays[_SEP.join(("k", k["language"], k["driver"], k["case"]))] = k["output"]
    meta = dict(version=RECORD_VERSION, date=time.strftime("%Y-%m-%d"), targets=targets, kernels=kmeta,
                probes=probe_text, compilers=compilers, total=total)
    buf = io.BytesIO()
    np.savez_compressed(buf, meta=np.frombuffer(json.dumps(meta).encode("utf-8"), np.uint8), **arrays)
    return write_bytes(path, buf.getvalue())


#: Largest record file read (bytes), and largest array in it once decompressed.
MAX_RECORD = 256 << 20
_MAX_ARRAY = 64 << 20


class _Member:
    """What a record's array may be (:func:`moments_ref.golden.loader.read_npz`): numbers, at most ``max_bytes``."""

    def __init__(self, max_bytes):
        self.max_bytes = max_bytes

    def refusal(self, dtype, shape):
        if dtype.hasobject or dtype.kind not in "biuf" or dtype.itemsize > 8:
            return f"expected numbers, found dtype {dtype}"
        if len(shape) == 0:
            return "is a single number; expected rows"
        if np.prod(shape, dtype=np.float64) * dtype.itemsize > self.max_bytes:
            return f"holds {tuple(shape)} values of {dtype.itemsize} bytes, more than {self.max_bytes} bytes"
        return None


def _member(key):
    parts = key.split(_SEP)
    if key == "meta" or (parts[0] == "f" and len(parts) == 5) or (parts[0] == "k" and len(parts) == 4):
        return _Member(_MAX_ARRAY)
    return f"{key!r} is no array of a conformance record"


def load(path):
    """``(meta, arrays)`` of a record; a missing, foreign or damaged file is an ``InputError`` naming it.

    Read with the golden loader's guards: a regular file of at most :data:`MAX_RECORD` bytes,
    every array's size checked before it is decompressed, no pickles, JSON nested at most 32 deep.
    """
    from ..golden.loader import parse_json, read_npz, read_regular

    what = f"gpu-record {path}"
    blob = read_regular(path, MAX_RECORD, what)
    arrays = read_npz(blob, what, _member)
    if "meta" not in arrays:
        raise InputError(f"{what}: not a conformance record (no 'meta' array; write one with conformance --all "
                         "--record FILE)")
    meta = parse_json(arrays.pop("meta").tobytes(), what)
    if not isinstance(meta, dict) or meta.get("version") != RECORD_VERSION:
        found = meta.get("version") if isinstance(meta, dict) else None
        raise InputError(f"{what}: a record of version {found!r}; this moments-ref reads version {RECORD_VERSION}")
    kinds = {"targets": list, "kernels": list, "probes": str, "compilers": dict, "total": (int, float), "date": str}
    for key, kind in kinds.items():
        if not isinstance(meta.get(key), kind):
            raise InputError(f"{what}: its meta lacks '{key}' or it is not a {getattr(kind, '__name__', 'number')}")
    _check_entries(meta, what)
    return meta, arrays


def _check_entries(meta, what):
    """Each target and kernel entry holds the fields :func:`gpu_markdown` reads, of their types."""
    fields = {"targets": {"language": str, "driver": str, "renderer": str, "rows": list, "times": list,
                          "refused": dict},
              "kernels": {"case": str, "language": str, "driver": str, "note": str, "cells": str, "codes": str}}
    for group, spec in fields.items():
        for i, entry in enumerate(meta[group]):
            bad = next((k for k, t in spec.items() if not isinstance(entry, dict) or not isinstance(entry.get(k), t)),
                       None)
            if bad is not None:
                raise InputError(f"{what}: {group}[{i}] lacks '{bad}' or it is not a {spec[bad].__name__}")
            if group == "targets" and not (all(isinstance(r, str) for r in entry["rows"])
                                           and all(isinstance(t, (int, float)) for t in entry["times"])):
                raise InputError(f"{what}: targets[{i}] has rows that are not text or times that are not numbers")
            if group == "kernels" and not (entry.get("passed") is None and "passed" in entry
                                           or isinstance(entry.get("passed"), bool)):
                raise InputError(f"{what}: kernels[{i}] has 'passed' {entry.get('passed', 'missing')!r}; expected "
                                 "true, false or null")


def _compare(a, b):
    """``(rows differing in any bit (a mask), largest float32 ulp distance or None, integer rows differing)``."""
    a, b = np.asarray(a), np.asarray(b)
    n = len(a)
    if a.shape != b.shape:
        return np.ones(n, bool), None, 0
    if a.dtype.kind == "f":
        diff = (a.reshape(n, -1).view(np.uint32) != b.reshape(n, -1).view(np.uint32)).any(axis=1)
        u = ulp_distance(a, b.astype(np.float64)) if diff.any() else np.zeros(1)
        return diff, float(np.max(u)), 0
    diff = (a.reshape(n, -1) != b.reshape(n, -1)).any(axis=1)
    return diff, None, int(diff.sum())


def _rows_differing(x, y):
    """Rows of a case whose outputs (``{name: array}`` on both sides) differ in any bit, over every output: a mask."""
    rows = np.zeros(len(next(iter(x.values()))), bool)
    for name in (k for k in x if k in y):
        rows |= _compare(x[name], y[name])[0]
    return rows


def _verdicts(rows):
    """``{case: 'pass' | 'FAIL'}`` from a target's table rows (refused cases left out)."""
    out = {}
    for r in rows:
        cells = [c.strip() for c in r.strip("|").split("|")]
        if cells[-1] in ("pass", "FAIL"):
            out[cells[0]] = cells[-1]
    return out


def _outputs(arrays, kind, language, driver):
    """``{case: {name: array}}`` (functions) or ``{case: array}`` (kernels) of one target in a record."""
    out = {}
    for key, arr in arrays.items():
        parts = key.split(_SEP)
        if parts[0] == kind and parts[1] == language and parts[2] == driver:
            if kind == "f":
                out.setdefault(parts[3], {})[parts[4]] = arr
            else:
                out[parts[3]] = arr
    return out


def _disagreement_lines(meta, arrays, results):
    local = {(lang, drv): (rows, outs) for lang, drv, _, rows, _, outs, _ in results}
    lines = ["| language | driver | rows compared | rows differing in any bit | largest float difference (ulp) | "
             "integer codes differing | verdicts differing | cases with differing rows |",
             "|---|---|---:|---:|---:|---:|---|---|"]
    for t in meta["targets"]:
        lang, drv = t["language"], t["driver"]
        if (lang, drv) not in local:
            lines.append(f"| {lang} | {drv} | not run here |||||")
            continue
        rows, mesa = local[(lang, drv)]
        gpu = _outputs(arrays, "f", lang, drv)
        compared, differing, worst, codes, cases = 0, 0, 0.0, 0, []
        for case in (c for c in gpu if c in mesa):
            for name in (k for k in gpu[case] if k in mesa[case]):
                _, u, c = _compare(gpu[case][name], mesa[case][name])
                worst = max(worst, u or 0.0)
                codes += c
            n_case = int(_rows_differing(gpu[case], mesa[case]).sum())
            compared += len(next(iter(gpu[case].values())))
            differing += n_case
            if n_case:
                cases.append(f"{case} ({n_case})")
        va, vb = _verdicts(t["rows"]), _verdicts(rows)
        verdicts = ", ".join(f"{c}: GPU {va[c]}, here {vb[c]}" for c in va if c in vb and va[c] != vb[c]) or "none"
        lines.append(f"| {lang} | {drv} | {compared} | {differing} | {worst:.0f} | {codes} | {verdicts} | "
                     f"{', '.join(cases) or '–'} |")
    return lines


def _agreement(arrays, meta):
    """Per language of the record: ``'glsl 0 of 7736'``, rows differing between its two drivers."""
    cells = []
    for lang in dict.fromkeys(t["language"] for t in meta["targets"]):
        gl, vk = _outputs(arrays, "f", lang, "gl"), _outputs(arrays, "f", lang, "vulkan")
        both = [c for c in gl if c in vk]
        if not both:
            continue
        rows = sum(len(next(iter(gl[c].values()))) for c in both)
        diff = sum(int(_rows_differing(gl[c], vk[c]).sum()) for c in both)
        cells.append(f"{lang} {diff} of {rows}")
    return cells or ["no language ran on both"]


def _kernel_lines(meta, arrays, kernels):
    here = {(k["case"], k["language"], k["driver"]): k for k in kernels}
    state = lambda p: {True: "pass", False: "FAIL", None: "not run"}[p]  # noqa: E731
    lines = ["| case | language | driver | GPU | worst error/tolerance | codes (against the global path) | here | "
             "texels differing from here | largest difference (ulp) |", "|---|---|---|---|---|---|---|---:|---:|"]
    for k in meta["kernels"]:
        key = (k["case"], k["language"], k["driver"])
        mine = here.get(key)
        gpu = arrays.get(_SEP.join(("k", k["language"], k["driver"], k["case"])))
        other = None if mine is None else mine["output"]
        if gpu is not None and other is not None:
            d, u, _ = _compare(gpu.reshape(len(gpu), -1), other.reshape(len(other), -1))
            diff, ulp = str(int(d.sum())), "–" if u is None else f"{u:.0f}"
        else:
            diff, ulp = "–", "–"
        note = f" ({k['note'].split(' (')[0]})" if k["note"] else ""  # the reason's first clause
        lines.append(f"| {k['case']} | {k['language']} | {k['driver']} | {state(k['passed'])}{note} | "
                     f"{k['cells'] or '–'} | {k['codes'] or '–'} | {state(None if mine is None else mine['passed'])} | "
                     f"{diff} | {ulp} |")
    return lines


def gpu_markdown(meta, arrays, results, kernels, source):
    """The section of docs/conformance.md about the record ``source`` against this run (lines)."""
    renderers = sorted({t["renderer"] for t in meta["targets"] if t["renderer"]})
    lines = ["", "## On a GPU", "",
             f"Measured on {meta['date']} by `moments-ref conformance --all --record FILE` on a machine with a GPU, "
             f"kept in `{source}` and compared here with this machine's run above. Renderers: "
             f"{'; '.join(renderers) or 'none'}. Compilers there: "
             f"{', '.join(f'{k}: {v}' for k, v in meta['compilers'].items()) or 'none found'}. Whole run there "
             f"(goldens, ports, probes and kernels): {meta['total']:.1f} s.", "",
             "### Verdicts on the GPU", "",
             "| language | driver | cases | run | failed | first run s | later runs: median s |",
             "|---|---|---:|---:|---:|---:|---:|"]
    failing = []
    for t in meta["targets"]:
        times = t["times"] or [float("nan")]
        failed = [r for r in t["rows"] if r.endswith("| FAIL |")]
        failing += [f"| {t['language']} | {t['driver']} " + r for r in failed]
        lines.append(f"| {t['language']} | {t['driver']} | {len(t['rows'])} | {len(t['times'])} | {len(failed)} | "
                     f"{times[0]:.3f} | {statistics.median(times[1:] or times):.3f} |")
    lines += ["", "Golden rows whose outputs differ in any bit between the GPU's OpenGL and its Vulkan: "
              + "; ".join(_agreement(arrays, meta)) + "."]
    if failing:
        lines += ["", "Failing cases on the GPU:", "", "| language | driver | case | function | random | edge | stiff | "
                  "metric | result |", "|---|---|---|---|---|---|---|---|---|", *failing]
    lines += ["", "### Where the GPU's outputs differ from this machine's", "",
              "Per language and driver, over the golden rows both ran: rows whose outputs differ in any bit (a row",
              "counts once), the largest difference of a float output in float32 ulps, rows whose integer codes",
              "differ, and cases whose verdict differs.", ""]
    lines += _disagreement_lines(meta, arrays, results)
    lines += ["", "### The shipped kernels on the GPU", "",
              "Every shipped kernel on every kernel case and driver (`conformance --kernel`), the GPU's verdict",
              "beside this machine's, and the judged texels that differ in any bit.", ""]
    lines += _kernel_lines(meta, arrays, kernels)
    probes = ("\n" + meta["probes"]).replace("\n## ", "\n### ").replace("(measured)", "on the GPU (measured)")
    lines += [probes]
    return lines
