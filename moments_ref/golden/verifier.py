"""Verify a foreign implementation's results against the golden vectors.

Reads only what it must, and only safely: ``manifest.json`` and each case's file
must be regular files (no links, FIFOs or devices) directly inside the golden
folder, no larger than the manifest's shapes imply, with the recorded sha256.
Anything else (malformed JSON, missing keys, a missing or corrupt ``.npz``, missing
arrays, results of the wrong dtype, names matching no case) raises
:class:`~moments_ref.InputError` with one line, which the command line turns into
exit status 2. Differences found by the comparison are the report (exit status 1).
"""

from __future__ import annotations

import hashlib
import io
import json
import os
import stat
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .._arrays import InputError
from .compare import compare
from .spread import ulp
from .writer import CATEGORIES, SCHEMA_VERSION

__all__ = ["verify", "VerifyReport", "CaseResult", "load_manifest", "load_case_arrays", "read_regular"]

#: Largest manifest accepted (bytes).
MAX_MANIFEST = 16 << 20
_ENTRY_KEYS = ("file", "compare", "inputs", "outputs", "dtype", "metric", "count", "sha256")
_ROW_OVERHEAD = 4096  # bytes per row for labels, comments, tolerances and acceptable codes


def read_regular(path, limit, what):
    """The bytes of ``path`` if it is a regular file (not a link) of at most ``limit`` bytes."""
    path = Path(path)
    try:
        st = os.lstat(path)
    except OSError:
        raise InputError(f"{what}: expected a file, got {str(path)!r} (not found)") from None
    if stat.S_ISLNK(st.st_mode) or not stat.S_ISREG(st.st_mode):
        raise InputError(f"{what}: expected a regular file, got {str(path)!r} (a link, device, FIFO or folder)")
    if st.st_size > limit:
        raise InputError(f"{what}: expected at most {limit} bytes, got {str(path)!r} with {st.st_size} bytes")
    flags = os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_NONBLOCK", 0)
    try:
        fd = os.open(path, flags)
    except OSError as exc:
        raise InputError(f"{what}: could not open {str(path)!r}: {exc.strerror}") from None
    with os.fdopen(fd, "rb") as f:
        if not stat.S_ISREG(os.fstat(f.fileno()).st_mode):
            raise InputError(f"{what}: expected a regular file, got {str(path)!r}")
        return f.read(limit + 1)[:limit + 1]


def _check_entry(name, meta):
    if not isinstance(meta, dict):
        raise InputError(f"manifest: case {name!r}: expected an object, got {type(meta).__name__}")
    missing = [k for k in _ENTRY_KEYS if k not in meta]
    if missing:
        raise InputError(f"manifest: case {name!r} lacks the key {missing[0]!r} (expected {', '.join(_ENTRY_KEYS)})")
    f = meta["file"]
    if (not isinstance(f, str) or not f or f in (".", "..") or "/" in f or "\\" in f or os.path.isabs(f)
            or "\0" in f):
        raise InputError(f"manifest: case {name!r}: expected a file name inside the golden folder, got {f!r}")
    for k in ("inputs", "outputs"):
        if not isinstance(meta[k], dict) or not all(isinstance(v, dict) and "shape" in v and "dtype" in v
                                                   for v in meta[k].values()):
            raise InputError(f"manifest: case {name!r}: expected {k!r} as name -> {{dtype, shape}}")
    if not isinstance(meta["compare"], list) or not all(o in meta["outputs"] for o in meta["compare"]):
        raise InputError(f"manifest: case {name!r}: 'compare' must list outputs of the case")


def load_manifest(golden_dir):
    """The parsed, checked ``manifest.json`` of ``golden_dir``."""
    golden_dir = Path(golden_dir)
    if not golden_dir.is_dir():
        raise InputError(f"golden_dir: expected a folder with manifest.json, got {str(golden_dir)!r}")
    blob = read_regular(golden_dir / "manifest.json", MAX_MANIFEST, "golden_dir")
    try:
        manifest = json.loads(blob.decode("utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise InputError(f"manifest: expected JSON, could not parse manifest.json: {exc}") from None
    if not isinstance(manifest, dict) or not isinstance(manifest.get("cases"), dict):
        raise InputError("manifest: expected an object with a 'cases' object")
    if manifest.get("schema_version") != SCHEMA_VERSION:
        raise InputError(f"manifest: expected schema_version {SCHEMA_VERSION}, got "
                         f"{manifest.get('schema_version')!r} (regenerate with 'moments-ref golden')")
    for name, meta in manifest["cases"].items():
        _check_entry(name, meta)
    return manifest


def _size_limit(meta):
    """Bytes a case file may have at most, from the manifest's shapes."""
    total = 0
    for spec in list(meta["inputs"].values()) + list(meta["outputs"].values()):
        try:
            count = int(np.prod([int(s) for s in spec["shape"]], dtype=np.int64))
            total += count * np.dtype(spec["dtype"]).itemsize
        except (TypeError, ValueError):
            raise InputError(f"manifest: a shape or dtype is malformed: {spec!r}") from None
    # Expected values, tolerances (2 columns) and acceptable codes: at most ~8 times the outputs.
    return 8 * total + _ROW_OVERHEAD * int(meta["count"]) + (1 << 16)


def load_case_arrays(golden_dir, name, meta):
    """The arrays of one case file, after the file and sha256 checks."""
    blob = read_regular(Path(golden_dir) / meta["file"], _size_limit(meta), f"golden file of {name}")
    if hashlib.sha256(blob).hexdigest() != meta["sha256"]:
        raise InputError(f"golden: {meta['file']} does not match the sha256 in manifest.json")
    try:
        with np.load(io.BytesIO(blob), allow_pickle=False) as g:
            arrays = {k: g[k] for k in g.files}
    except Exception as exc:  # zipfile, format and value errors of a corrupt file
        raise InputError(f"golden: {meta['file']} is not a readable .npz: {exc}") from None
    need = list(meta["inputs"]) + list(meta["compare"]) + ["category", "comment", "result", "tc_id"]
    missing = [k for k in need if k not in arrays]
    if missing:
        raise InputError(f"golden: {meta['file']} lacks the array {missing[0]!r}")
    return arrays


def _results_limit(manifest):
    """Bytes a results file may have: every compared output at 8 bytes a value, twice, plus 1 MiB."""
    total = 0
    try:
        for meta in manifest["cases"].values():
            for o in meta["compare"]:
                total += 8 * int(np.prod([int(x) for x in meta["outputs"][o]["shape"]], dtype=np.int64))
    except (TypeError, ValueError):
        raise InputError("manifest: an output shape is malformed (expected a list of integers)") from None
    return 2 * total + (1 << 20)


def _load_results(path, limit):
    blob = read_regular(path, limit, "results")
    try:
        with np.load(io.BytesIO(blob), allow_pickle=False) as data:
            return {k: data[k] for k in data.files}
    except Exception as exc:
        raise InputError(f"results: expected an .npz file, could not read {str(path)!r}: {exc}") from None


@dataclass
class CaseResult:
    """Verdict of one case: ``status`` is "pass", "fail" or "missing"."""

    name: str
    status: str
    port_dtype: str
    worst: list  # failing rows: dict(index, tc_id, category, flags, score, error, tolerance, comment, inputs, got,
    #              expected)
    per_category: dict  # category -> (rows, failures, worst score)
    message: str = ""
    verdict: object = None  # the compare.Verdict


@dataclass
class VerifyReport:
    cases: list

    @property
    def failed(self):
        return any(c.status == "fail" for c in self.cases)

    @property
    def checked(self):
        return [c for c in self.cases if c.status in ("pass", "fail")]

    def format(self, worst_rows=5):
        lines = []
        for c in self.cases:
            if c.status == "missing":
                continue
            head = f"{c.status.upper():5} {c.name} (port dtype {c.port_dtype})"
            lines.append(head + (f": {c.message}" if c.message else ""))
            for cat, (rows, fails, score) in c.per_category.items():
                lines.append(f"      {cat:6} rows {rows:4d}  failures {fails:4d}  worst error/tolerance {score:.3g}")
            for r in c.worst[:worst_rows]:
                ins = ", ".join(f"{k}={np.array2string(np.asarray(v), precision=9)}" for k, v in r["inputs"].items())
                lines.append(f"      row {r['index']} (tc_id {r['tc_id']}) [{r['category']}"
                             f"{'; ' + r['flags'] if r['flags'] else ''}] error {r['error']:.3g} > {r['tolerance']:.3g}: "
                             f"got {np.array2string(np.asarray(r['got']), precision=9)}, "
                             f"expected {np.array2string(np.asarray(r['expected']), precision=9)}; {ins}")
                lines.append(f"        ({r['comment']})")
        missing = [c.name for c in self.cases if c.status == "missing"]
        if missing:
            lines.append(f"not in the results (not checked): {len(missing)} cases")
        n_fail = sum(c.status == "fail" for c in self.cases)
        lines.append(f"{len(self.checked) - n_fail} passed, {n_fail} failed")
        return "\n".join(lines)


def _case_result(name, meta, gold, got, port_dtype, keep):
    verdict = compare(meta, gold, got, port_dtype, case=name)
    category = gold["category"]
    o = meta["compare"][0]
    worst = []
    for i in verdict.worst_rows(keep):
        e_row = np.asarray(got[o])[i]
        worst.append({
            "index": i, "tc_id": int(gold["tc_id"][i]), "category": str(category[i]),
            "flags": str(gold["flags"][i]) if "flags" in gold else "", "score": float(verdict.score[i]),
            "error": _row_error(meta, gold, got, o, i, verdict.port_dtype),
            "tolerance": _row_tolerance(meta, gold, o, i, verdict.port_dtype),
            "comment": str(gold["comment"][i]), "inputs": {k: gold[k][i] for k in meta["inputs"]},
            "got": e_row, "expected": gold[o][i], "metric": meta["metric"],
        })
    per_cat = {}
    for c in CATEGORIES:
        sel = category == c
        if sel.any():
            per_cat[c] = (int(sel.sum()), int((~verdict.row_pass[sel]).sum()), float(verdict.score[sel].max()))
    msg = f"{verdict.failures} of {len(category)} rows fail" if not verdict.passed else ""
    return CaseResult(name, "pass" if verdict.passed else "fail", verdict.port_dtype, worst, per_cat, msg, verdict)


def _row_error(meta, gold, got, o, i, dt):
    g = np.asarray(got[o])[i].astype(np.float64)
    e = np.asarray(gold[o])[i].astype(np.float64)
    with np.errstate(invalid="ignore"):
        d = np.abs(g - e)
        if meta["metric"] == "ulps":
            d = d / ulp(e, dt)
    return float(np.nanmax(np.where(np.isnan(d), np.inf, d))) if d.size else 0.0


def _row_tolerance(meta, gold, o, i, dt):
    if meta["metric"] == "exact":
        return 0.0
    return float(np.min(gold[f"{o}_tolerance_{dt}"][i]))


def verify(golden_dir, results_path, port_dtype=None, worst_rows=None):
    """Compare a foreign implementation's outputs with the goldens.

    Parameters
    ----------
    golden_dir : path
        A folder written by :func:`moments_ref.golden.write`.
    results_path : path
        An ``.npz`` whose arrays are named ``<case>.<output>`` (for example
        ``shadow_intensity-lower-float32.intensity``), each with the case's rows in
        order and the dtype the manifest states. Cases absent from the file are
        listed as not checked.
    port_dtype : {"float32", "float64"}, optional
        The port's precision (which tolerance column applies and which float
        dtype the results must have); default: each case's own dtype.
    worst_rows : int, optional
        Failing rows to keep per case (default: all).

    Returns
    -------
    VerifyReport
        ``report.failed`` is True when any row fails; ``report.format()`` lists
        the worst rows with inputs.

    Raises
    ------
    InputError
        Bad manifest or golden file, unreadable results, results of the wrong
        dtype or shape, or arrays matching no case output.
    """
    golden_dir = Path(golden_dir)
    if port_dtype not in (None, "float32", "float64"):
        raise InputError(f"port_dtype: expected float32 or float64, got {port_dtype!r}")
    manifest = load_manifest(golden_dir)
    results = _load_results(results_path, _results_limit(manifest))
    known = {f"{n}.{o}" for n, m in manifest["cases"].items() for o in m["compare"]}
    stray = sorted(set(results) - known)
    if stray:
        raise InputError(f"results: {stray[0]!r} matches no golden case output; known: {', '.join(sorted(known))}")
    report = []
    for name, meta in manifest["cases"].items():
        keys = {o: f"{name}.{o}" for o in meta["compare"]}
        if not any(k in results for k in keys.values()):
            report.append(CaseResult(name, "missing", port_dtype or meta["dtype"], [], {}))
            continue
        gold = load_case_arrays(golden_dir, name, meta)
        got = {o: results[k] for o, k in keys.items() if k in results}
        report.append(_case_result(name, meta, gold, got, port_dtype, worst_rows))
    if not report or all(c.status == "missing" for c in report):
        raise InputError("results: no array matches a golden case output ('<case>.<output>')")
    return VerifyReport(report)
