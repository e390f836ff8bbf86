"""Verify a foreign implementation's results against the golden vectors.

Reads only what it must, and only through the one strict loader
(:mod:`moments_ref.golden.loader`, shared with ``conformance`` and ``oracle``):
``manifest.json`` and each case's file must be regular files directly inside the
golden folder, every entry well-formed, every archive within the size its shapes
imply before anything is decompressed, with the recorded sha256. Anything else
(malformed JSON, missing keys, a missing or corrupt ``.npz``, missing arrays, NaN
tolerances, results of the wrong dtype or shape, names matching no case) raises
:class:`~moments_ref.InputError` with one line, which the command line turns into
exit status 2. Differences found by the comparison are the report (exit status 1).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .._arrays import InputError
from .cases import CASES
from .compare import compare
from .loader import load_case_arrays, load_manifest, load_results, read_regular
from .spread import ulp
from .writer import CATEGORIES

__all__ = ["verify", "VerifyReport", "CaseResult", "load_manifest", "load_case_arrays", "read_regular"]

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
    groups: list = None  # diagnosis.Group: failing rows by level and flag, with their cause
    record: dict = None  # every row's verdict (diagnosis.json_rows), for --json


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
        """The report; ``worst_rows=None`` lists every failing row (``--rows all``)."""
        from .diagnosis import group_lines

        lines = []
        for c in self.cases:
            if c.status == "missing":
                continue
            head = f"{c.status.upper():5} {c.name} (port dtype {c.port_dtype})"
            lines.append(head + (f": {c.message}" if c.message else ""))
            for cat, (rows, fails, score) in c.per_category.items():
                lines.append(f"      {cat:6} rows {rows:4d}  failures {fails:4d}  worst error/tolerance {score:.3g}")
            lines += [f"      {x}" for x in group_lines(c.groups or [], c.verdict.failures, c.verdict.strict)]
            lines += [f"      {x}" for x in _robustness_line(c.verdict)]
            for r in c.worst[:worst_rows] if worst_rows is not None else c.worst:
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


def _robustness_line(v):
    t = v.robustness_tally()
    if not t["rows"]:
        return []
    mode = "gated (--strict)" if v.strict else "not gated; --strict gates them"
    return [f"beyond the algorithm's contract: {t['rows']} rows, {t['would_fail']} outside their tolerance "
            f"({t['nonfinite']} NaN or infinite, {t['outside_range']} out of range); {mode}"]


def _case_result(name, meta, gold, got, port_dtype, keep, strict=False, extra=None, plain=None):
    from .diagnosis import groups, json_rows

    verdict = compare(meta, gold, got, port_dtype, case=name, strict=strict, neighbourhood=plain)
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
    gs = groups(verdict, gold, extra(verdict) if extra else ())
    return CaseResult(name, "pass" if verdict.passed else "fail", verdict.port_dtype, worst, per_cat, msg, verdict,
                      gs, json_rows(name, meta, gold, got, verdict, gs))


def _causes(name, base, got, profile, target, port_dtype):
    """``verdict -> [diagnosis.Group]``: a singular bias target, another convention or texel format."""
    from .diagnosis import convention_groups
    from .profile import DEFAULT

    def extra(v):
        found = target(v) if target is not None else []
        return found or convention_groups(name, v, base, got, profile or DEFAULT, port_dtype)

    return extra


def _profiled(name, meta, gold, profile):
    """The case's manifest entry and arrays under ``profile``, and its target diagnosis."""
    from .conventions import profiled_arrays
    from .diagnosis import target_groups
    from .writer import manifest_entry

    pcase, arrays = profiled_arrays(name, profile, arrays=gold)
    entry = dict(meta, **{k: v for k, v in manifest_entry(pcase, arrays).items() if k not in ("sha256", "size")})
    return entry, arrays, (lambda v: target_groups(v, arrays, profile.bias, pcase.engine))


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


def verify(golden_dir, results_path, port_dtype=None, worst_rows=None, strict=False, profile=None):
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
    strict : bool
        Robustness rows (beyond the algorithm's contract) fail the verdict too.
    profile : moments_ref.golden.profile.Profile, optional
        The engine's declared conventions: the results were computed on the case's
        inputs converted for it (``moments-ref golden --profile``), and expected
        values and tolerances are derived for it (golden.conventions; cached).

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
    declared = profile  # the caller's clamp applies also where the folder holds this profile's expected values
    if manifest.get("profile_key") is not None and profile is not None and not profile.is_default:
        if profile.key != manifest["profile_key"]:
            raise InputError("profile: the golden folder was written for another profile "
                             f"({manifest.get('profile')}); verify it without --profile or with that one")
        profile = None  # the folder's expected values are already this profile's
    results = load_results(results_path, manifest)
    from .profile import ignored_note, refuse_meaningless

    if profile is not None and not profile.is_default:  # a key no verified case can use is refused, not dropped
        refuse_meaningless([CASES[n] for n, meta in manifest["cases"].items() if n in CASES and any(
            f"{n}.{o}" in results for o in meta["compare"])], profile)
    report = []
    for name, meta in manifest["cases"].items():
        keys = {o: f"{name}.{o}" for o in meta["compare"]}
        if not any(k in results for k in keys.values()):
            report.append(CaseResult(name, "missing", port_dtype or meta["dtype"], [], {}))
            continue
        gold = load_case_arrays(golden_dir, name, meta)
        base, target = gold, None
        if profile is not None and not profile.is_default:
            meta, gold, target = _profiled(name, meta, gold, profile)
        got = {o: results[k] for o, k in keys.items() if k in results}
        said = []
        if declared is not None and name in CASES:  # a declared caller's clamp, applied first (golden.receiver)
            from .receiver import clamp_outputs

            got, said = clamp_outputs(CASES[name], declared, got)
        # ill-conditioned rows are judged by their neighbourhood: the exact values of the shipped case, or of the
        # profiled case the rows were converted for (none for a folder written under a profile not given here)
        plain = None
        if name in CASES and target is not None:
            from .conventions import neighbourhood_case

            plain = neighbourhood_case(CASES[name], profile)
        elif name in CASES and manifest.get("profile_key") is None:
            plain = CASES[name]
        result = _case_result(name, meta, gold, got, port_dtype, worst_rows, strict,
                              _causes(name, base, got, profile, target, port_dtype or meta["dtype"]), plain)
        if profile is not None and name in CASES:  # the declared keys this case ignores, and why
            result.message = "; ".join([result.message] * bool(result.message) + ignored_note(CASES[name], profile)
                                       + said)
        report.append(result)
    if not report or all(c.status == "missing" for c in report):
        raise InputError("results: no array matches a golden case output ('<case>.<output>')")
    return VerifyReport(report)
