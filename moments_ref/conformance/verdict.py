"""Conformance's view of the one comparator: a port's GPU outputs judged by ``golden.compare``.

Pass or fail is decided by :func:`moments_ref.golden.compare.compare`, the
comparator of ``verify`` and ``oracle.check``, with the port's precision
:data:`GATE_DTYPE` (a shader computes in float32, so a float64 case is judged by
its float32 tolerance column): per-row tolerances and metric from the golden file,
rows whose ``result`` is ``acceptable`` accept the codes stored for them (rounding
ties) or any finite value in range (undefined values); nothing is recomputed at
check time. This module only adapts a driver's results to it and summarises:

* readback is 32-bit words: integer outputs are narrowed to the manifest's width
  (a word that does not fit that width is not a code of the format: its row fails);
* per row category: rows, gated rows, failures, the worst error over tolerance;
* the rows a porter reads (:func:`select_worst`): every category's worst failing
  rows, or its closest row when it passes, and accepted ties of integer outputs.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..golden.compare import compare

__all__ = ["GATE_DTYPE", "CategoryResult", "CaseVerdict", "compare_case", "ulp_distance", "select_worst",
           "ill_section"]

#: The precision every shader port is judged in (its tolerance column).
GATE_DTYPE = "float32"
_CATEGORIES = ("random", "edge", "stiff")


@dataclass
class CategoryResult:
    """Summary of one row category (``score`` = error / tolerance, > 1 fails)."""

    category: str
    rows: int
    gated: int
    failures: int
    worst_score: float = 0.0
    worst_error: float = 0.0  # at the worst row, in the case's metric
    worst_tolerance: float = 0.0  # that row's tolerance (0: exact code, inf: ungated)
    mismatches: int = 0  # integer outputs: rows whose codes differ from the golden code
    ties: int = 0  # integer outputs: of those, rows passing on a stored acceptable code


@dataclass
class CaseVerdict:
    """What :func:`compare_case` found: per category, per row, the rows to show."""

    exact: bool
    metric: str
    categories: dict
    worst: list  # dicts: index, tc_id, category, flags, passed, error, tolerance, score, got, expected, ...
    row_pass: np.ndarray
    components: dict | None = None
    notes: list = field(default_factory=list)
    groups: list = field(default_factory=list)  # golden.diagnosis.Group: failing rows by level, flag, cause
    compared: object = None  # the golden.compare.Verdict
    ill: list = field(default_factory=list)  # dicts of the ill-conditioned rows shown (:func:`ill_section`)
    record: dict | None = None  # every row's verdict (golden.diagnosis.json_rows), for --json

    @property
    def passed(self):
        return bool(self.row_pass.all())


def _ordered(x32):
    """float32 -> int64 whose order and differences count float32 values (±0 -> 0)."""
    i = np.asarray(x32, np.float32).view(np.int32).astype(np.int64)
    return np.where(i < 0, -(i & 0x7FFFFFFF), i)


def ulp_distance(got, expected):
    """Number of float32 values between ``got`` (float32) and ``expected`` rounded to float32.

    A measurement for reports and probes (the gate is :mod:`moments_ref.golden.compare`).
    NaN in either gives ``inf``; a float64 value beyond the float32 range rounds to ±inf.
    """
    g = np.asarray(got, np.float32)
    with np.errstate(over="ignore"):
        e = np.asarray(expected, np.float64).astype(np.float32)
    d = np.abs(_ordered(g) - _ordered(e)).astype(np.float64)
    return np.where(np.isnan(g) | np.isnan(e), np.inf, d)


def select_worst(category, score, row_pass, keep, extra=()):
    """Row indices to print: per category the worst failing rows, or its closest passing row.

    Failing rows: up to ``keep``, largest ``score`` first; a passing category shows
    its largest score (three rows for ``stiff``); then the rows ``extra``.
    """
    picked = []
    for c in _CATEGORIES:
        idx = np.flatnonzero(category == c)
        if not idx.size:
            continue
        fails = idx[~row_pass[idx]]
        pool = fails if fails.size else idx[score[idx] > 0]
        k = (keep if keep is not None else len(pool)) if fails.size else (3 if c == "stiff" else 1)
        picked += [int(i) for i in pool[np.argsort(-score[pool], kind="stable")][:k]]
    return picked + [int(i) for i in extra if i not in picked]


def _narrow(meta, got, n):
    """Integer readback words -> the manifest's dtype; also the rows with a word that does not fit."""
    out, misfit = dict(got), np.zeros(n, bool)
    for o in meta["compare"]:
        want = np.dtype(meta["outputs"][o]["dtype"])
        g = np.asarray(got[o])
        if meta["exact"] and g.dtype != want and g.dtype.kind in "ui":
            info = np.iinfo(want)
            g64 = g.astype(np.int64)
            misfit |= ((g64 < info.min) | (g64 > info.max)).reshape(n, -1).any(axis=1)
            out[o] = np.clip(g64, info.min, info.max).astype(want)
    return out, misfit


def _row(i, meta, arrays, got, v, score, row_pass, differs):
    o = meta["compare"][0]
    r = {"index": i, "tc_id": int(arrays["tc_id"][i]), "category": str(arrays["category"][i]),
         "flags": str(arrays["flags"][i]), "passed": bool(row_pass[i]), "error": float(v.error[i]),
         "tolerance": float(v.tolerance[i]), "score": float(score[i]), "metric": meta["metric"],
         "got": got[o][i], "expected": arrays[o][i], "inputs": {k: arrays[k][i] for k in meta["inputs"]},
         "comment": str(arrays["comment"][i])}
    if meta["exact"]:
        r["tie"] = bool(row_pass[i] and differs[i])
        if str(arrays["result"][i]) == "acceptable" and f"{o}_acceptable" in arrays:
            r["acceptable"] = arrays[f"{o}_acceptable"][i]
    else:
        e, g = np.asarray(arrays[o][i], np.float64), np.asarray(got[o][i], np.float64)
        with np.errstate(invalid="ignore", divide="ignore"):
            a = np.where(np.isnan(g - e), np.inf, np.abs(g - e))
            r["abs"] = float(a.max())
            r["rel"] = float(np.where(a == 0, 0.0, a / np.abs(e)).max())
        r["ulps"] = float(ulp_distance(got[o][i], e).max())
    return r


def _categories(category, v, score, row_pass, differs):
    out = {}
    for c in _CATEGORIES:
        sel = np.flatnonzero(category == c)
        if not sel.size:
            continue
        w = sel[int(np.argmax(score[sel]))]
        gated = v.gated & ~v.ill if v.ill is not None else v.gated  # ill-conditioned rows never count as passes
        out[c] = CategoryResult(c, int(sel.size), int(gated[sel].sum()), int((~row_pass[sel]).sum()),
                                float(score[w]), float(v.error[w]), float(v.tolerance[w]),
                                int(differs[sel].sum()), int((differs & row_pass)[sel].sum()))
    return out


def _components(meta, arrays, got, row_pass):
    o = meta["compare"][0]
    if np.ndim(arrays[o]) != 2:
        return None
    if meta["exact"]:
        diff = np.asarray(got[o]).astype(np.int64) != np.asarray(arrays[o]).astype(np.int64)
        return {"mismatch": [int(x) for x in (diff & ~row_pass[:, None]).sum(axis=0)]}
    u = ulp_distance(got[o], arrays[o]).max(axis=0)
    return {"ulps": "[" + ", ".join(str(int(x)) if x < 1e6 else f"{x:.3g}" for x in u) + "]"}


def _within(meta, lo, hi):
    """The band ``(lo, hi)`` as shown: inside the output's range where it has one (an intensity's [0, 1]; the
    golden file's ``value_range``, so also under a profile, where no unprofiled case is at hand)."""
    r = meta.get("value_range")
    return (lo, hi) if r is None else (max(lo, r[0]), min(hi, r[1]))


def _worst_value(o, arrays, got, i):
    """Index of the row's value (pixel, component) farthest from the expected one, in tolerances."""
    e = np.asarray(arrays[o][i], np.float64).ravel()
    g = np.asarray(got[o][i], np.float64).ravel()
    t = np.asarray(arrays[f"{o}_tolerance_{GATE_DTYPE}"][i], np.float64).ravel()
    with np.errstate(invalid="ignore", divide="ignore"):
        r = np.where(np.isfinite(g), np.abs(g - e) / np.where(t > 0, t, 1), np.inf)
    return int(np.argmax(np.where(np.isnan(r), np.inf, r)))


def ill_section(meta, arrays, got, v, case=None, rows=10):
    """The ill-conditioned rows (flag ``wide_spread``) a porter reads: failing rows first, at most ``rows``.

    Each: index, tc_id, inputs, the port's value and the band at the row's worst value (pixel, component),
    whether it lies in the band, and where ``case`` (the :class:`~moments_ref.golden.cases.Case` the golden file
    was generated from, no profile) is given, the interval of exact values over the input's float32
    neighbourhood there (:func:`moments_ref.golden.bands.neighbourhood_interval`).
    """
    if v.ill is None or meta["exact"] or not v.ill.any():
        return []
    o = meta["compare"][0]
    sel = np.flatnonzero(v.ill & v.gated)  # an ungated row (undefined value) needs no band
    sel = np.concatenate([sel[~v.strict_pass[sel]], sel[v.strict_pass[sel]]])[:rows]
    exact = None
    if case is not None and case.deriver is None and not case.integer_output:
        from ..golden.bands import neighbourhood_interval

        exact = neighbourhood_interval(case, {k: np.asarray(arrays[k])[sel] for k in case.inputs})[o]
    out = []
    for j, i in enumerate(sel):
        k = _worst_value(o, arrays, got, i)
        e = float(np.asarray(arrays[o][i], np.float64).ravel()[k])
        t = float(np.asarray(arrays[f"{o}_tolerance_{GATE_DTYPE}"][i], np.float64).ravel()[k])
        r = {"index": int(i), "tc_id": int(arrays["tc_id"][i]), "value": k if np.ndim(arrays[o][i]) else None,
             "inputs": {n: arrays[n][i] for n in meta["inputs"]}, "got": float(np.asarray(got[o][i]).ravel()[k]),
             "band": _within(meta, e - t, e + t), "passed": bool(v.strict_pass[i])}
        if exact is not None:
            r["exact"] = tuple(float(np.asarray(x[j], np.float64).ravel()[k]) for x in exact)
        out.append(r)
    return out


def compare_case(name, meta, arrays, got, worst_rows=5, strict=False, extra=None, case=None):
    """Judge a port's outputs on one golden case with :func:`moments_ref.golden.compare.compare`.

    Parameters
    ----------
    name : str
        The case name (``shade-float32``), for messages.
    meta : dict
        The case's manifest entry.
    arrays : dict name -> array
        The golden file (inputs, expected outputs, tolerances, acceptable codes,
        ``result``, ``tc_id``, ``category``, ``flags``, ``comment``).
    got : dict name -> array
        The port's outputs named as in ``meta["compare"]``: float32 values, or
        integer codes (32-bit readback words are narrowed to the manifest's width).
    worst_rows : int or None
        Failing rows to list per category (None: every failing row).
    strict : bool
        Robustness rows (beyond the algorithm's contract) fail the verdict too.
    extra : callable, optional
        ``verdict -> [diagnosis.Group]``: causes told by outputs (a singular bias target).
    case : moments_ref.golden.cases.Case, optional
        The case the golden file holds, without a profile: its ill-conditioned rows are shown with the
        interval of exact values over their neighbourhood (:func:`ill_section`).

    Returns
    -------
    CaseVerdict
    """
    from ..golden.diagnosis import groups, json_rows

    category = np.asarray(arrays["category"]).astype(str)
    n = len(category)
    got, misfit = _narrow(meta, got, n)
    v = compare(meta, arrays, got, GATE_DTYPE, case=name, strict=strict, neighbourhood=case)
    v.row_pass &= ~misfit
    row_pass = v.row_pass
    score = np.where(misfit, np.inf, v.score)
    differs = np.zeros(n, bool)
    if meta["exact"]:
        for o in meta["compare"]:
            g, e = np.asarray(got[o]).astype(np.int64), np.asarray(arrays[o]).astype(np.int64)
            differs |= (g != e).reshape(n, -1).any(axis=1)
    ties = np.flatnonzero(differs & row_pass)[:3]
    worst = [_row(i, meta, arrays, got, v, score, row_pass, differs)
             for i in select_worst(category, score, row_pass, worst_rows, ties)]
    verdict = CaseVerdict(meta["exact"], meta["metric"], _categories(category, v, score, row_pass, differs), worst,
                          row_pass, _components(meta, arrays, got, row_pass))
    verdict.groups = groups(v, arrays, extra(v) if extra else ())
    verdict.compared = v
    verdict.record = json_rows(name, meta, arrays, got, v, verdict.groups)
    verdict.ill = ill_section(meta, arrays, got, v, case)
    verdict.record["ill_conditioned"] = dict(v.ill_tally(), shown=[_plain_ill(r) for r in verdict.ill])
    if meta["dtype"] == "float64" and any(np.asarray(arrays[k]).dtype.kind == "f" for k in meta["inputs"]):
        verdict.notes.append("float64 case: inputs rounded to float32 for upload; judged by the golden file's "
                             "float32 tolerance column")
    if misfit.any():
        verdict.notes.append(f"{int(misfit.sum())} rows hold a word wider than the format's "
                             f"{meta['outputs'][meta['compare'][0]]['dtype']} codes (failed)")
    return verdict


def _plain_ill(r):
    """An :func:`ill_section` row as plain JSON values."""
    out = {k: v for k, v in r.items() if k != "inputs"}
    out["inputs"] = {k: np.asarray(v).tolist() for k, v in r["inputs"].items()}
    finite = lambda x: [float(a) if np.isfinite(a) else None for a in x]  # noqa: E731 (JSON has no inf)
    out["band"] = finite(r["band"])
    out["got"] = finite([r["got"]])[0]
    if "exact" in r:
        out["exact"] = finite(r["exact"])
    return out
