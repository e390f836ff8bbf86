"""The verdict of a conformance run: a port's outputs against one golden case.

Everything that decides pass or fail lives here, behind :func:`compare_case`, so
that every language and driver shares one comparison (and so that it can be
replaced by the shared comparator of ``verify`` and ``oracle`` without touching
the front ends or the backends).

Rules (docs/ports.md, "Tolerances"):

* float outputs: per row the worst absolute error over its components against
  the expected values (float64 ground truth), gated by the manifest's **float32**
  tolerance of the row's category (a shader computes in float32); relative
  error and float32 ulps are reported beside it, and the same numbers against the
  reference's own float32 emulation (``<output>_float32``) for information.
  A NaN is an infinite error.
* integer outputs (packed texels): exact. A ``stiff`` row is a rounding tie and
  also accepts the code the reference computes in the other precision (the tie
  rule); a float64 case accepts the reference's float32 code on every row.
* rows listed in the report: per category the worst by error/tolerance, stiff
  rows always (:func:`select_worst`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["GATE_DTYPE", "CategoryResult", "CaseVerdict", "compare_case", "ulp_distance", "select_worst"]

#: The manifest's tolerance column every shader port is gated by.
GATE_DTYPE = "float32"
_CATEGORIES = ("random", "stiff", "edge")


@dataclass
class CategoryResult:
    """Summary of one row category."""

    category: str
    rows: int
    tolerance: float
    failures: int
    worst_abs: float = 0.0
    worst_rel: float = 0.0
    worst_ulps: float = 0.0
    ref_abs: float | None = None
    ref_rel: float | None = None
    ref_ulps: float | None = None
    mismatches: int = 0  # integer outputs: rows differing from the golden code
    ties: int = 0  # integer outputs: rows accepted as the other precision's rounding


@dataclass
class CaseVerdict:
    """What :func:`compare_case` found: per category, the rows to show, per component."""

    exact: bool
    categories: dict
    worst: list  # dicts: index, category, error, tolerance, got, expected, reference, inputs, comment
    components: dict | None = None
    notes: list = field(default_factory=list)

    @property
    def passed(self):
        return all(c.failures == 0 for c in self.categories.values())


def _ordered(x32):
    """float32 -> int64 whose order and differences count float32 values (±0 -> 0)."""
    i = np.asarray(x32, np.float32).view(np.int32).astype(np.int64)
    return np.where(i < 0, -(i & 0x7FFFFFFF), i)


def ulp_distance(got, expected):
    """Number of float32 values between ``got`` (float32) and ``expected`` rounded to float32.

    NaN in either gives ``inf``; a float64 value beyond the float32 range rounds to ±inf.
    """
    g = np.asarray(got, np.float32)
    with np.errstate(over="ignore"):
        e = np.asarray(expected, np.float64).astype(np.float32)
    d = np.abs(_ordered(g) - _ordered(e)).astype(np.float64)
    return np.where(np.isnan(g) | np.isnan(e), np.inf, d)


def _float_metrics(got, expected, n):
    """Per-row worst abs, rel and ulps (over the row's components)."""
    g = np.asarray(got, np.float64).reshape(n, -1)
    e = np.asarray(expected, np.float64).reshape(n, -1)
    with np.errstate(invalid="ignore", divide="ignore"):
        a = np.abs(g - e)
        a = np.where(np.isnan(a), np.inf, a)
        r = np.where(a == 0, 0.0, a / np.abs(e))
    u = ulp_distance(np.asarray(got, np.float32).reshape(n, -1), e)
    return a.max(axis=1), r.max(axis=1), u.max(axis=1)


def select_worst(category, err, tol, keep):
    """Row indices to print: per category the worst by err/tol; stiff rows always."""
    picked = []
    with np.errstate(divide="ignore", invalid="ignore"):
        score = np.where(tol > 0, err / np.where(tol > 0, tol, 1), np.where(err > 0, np.inf, 0))
    for c in ("random", "edge", "stiff"):
        idx = np.flatnonzero(category == c)
        if not idx.size:
            continue
        order = idx[np.argsort(-score[idx], kind="stable")]
        fails = int((err[idx] > tol[idx]).sum())
        k = keep if fails else (3 if c == "stiff" else 1)
        picked += [int(i) for i in order[: max(k, min(fails, keep))] if c == "stiff" or err[i] > 0 or fails]
    return picked


def _reference(case_name, inputs, out_name, dtype):
    """The reference's output ``out_name`` on ``inputs`` cast to ``dtype`` (None: unknown case)."""
    from .. import golden

    case = golden.CASES.get(case_name)
    if case is None:
        return None
    cast = {k: (v if k in case.integer_inputs else np.asarray(v).astype(dtype)) for k, v in inputs.items()}
    out = case.reference(**cast)
    return np.asarray(out[case.outputs.index(out_name)])


def _other_precision_codes(case_name, meta, inputs, out_name):
    """Integer outputs of the reference in the precision the golden did not use, or None."""
    return _reference(case_name, inputs, out_name, np.float64 if meta["dtype"] == "float32" else np.float32)


def _float32_reference(case_name, arrays, inputs, out_name):
    """The reference's float32 emulation: from the golden file, or computed for float64 cases."""
    key = f"{out_name}_float32"
    if key in arrays:
        return arrays[key]
    return _reference(case_name, inputs, out_name, np.float32)


def _row(i, category, err, tol, got, expected, reference, inputs, comment, **extra):
    return {"index": i, "category": category[i], "error": float(err[i]), "tolerance": float(tol[i]), **extra,
            "got": got[i], "expected": expected[i], "reference": None if reference is None else reference[i],
            "inputs": {k: v[i] for k, v in inputs.items()}, "comment": str(comment[i])}


def _compare_exact(name, meta, arrays, inputs, got, category, tol, tol_table, worst_rows):
    n = len(category)
    err, ties = np.zeros(n), np.zeros(n, bool)
    alt_codes = {o: _other_precision_codes(name, meta, inputs, o) for o in meta["compare"]}
    for o in meta["compare"]:
        exp = np.asarray(arrays[o]).astype(np.int64).reshape(n, -1)
        g = np.asarray(got[o]).astype(np.int64).reshape(n, -1)
        differs = (g != exp).any(axis=1)
        alt = alt_codes[o]
        if alt is not None:
            alt_ok = (g == np.asarray(alt).astype(np.int64).reshape(n, -1)).all(axis=1)
            # A stiff row is a rounding tie; a float64 case's codes are float64
            # roundings that a float32 port need not reproduce.
            accept = alt_ok & differs & ((category == "stiff") | (meta["dtype"] == "float64"))
            ties |= accept
            differs &= ~accept
        err = np.maximum(err, np.where(differs, np.abs(g - exp).max(axis=1), 0).astype(np.float64))
    categories = {}
    for c in _CATEGORIES:
        sel = category == c
        if sel.any():
            categories[c] = CategoryResult(c, int(sel.sum()), float(tol_table[c]), int((err[sel] > tol[sel]).sum()),
                                           worst_abs=float(err[sel].max()),
                                           mismatches=int(((err > 0) | ties)[sel].sum()), ties=int(ties[sel].sum()))
    o = meta["compare"][0]
    picked = [int(i) for i in np.flatnonzero(err > tol)[:worst_rows * 3]] + [int(i) for i in np.flatnonzero(ties)[:3]]
    worst = [_row(i, category, err, tol, got[o], arrays[o], alt_codes[o], inputs, arrays["comment"]) for i in picked]
    components = None
    if np.ndim(arrays[o]) == 2:
        diff = np.asarray(got[o]).astype(np.int64) != np.asarray(arrays[o]).astype(np.int64)
        components = {"mismatch": [int(x) for x in (diff & ~ties[:, None]).sum(axis=0)]}
    return CaseVerdict(True, categories, worst, components)


def _max_or_none(acc, new):
    return new if acc is None else np.maximum(acc, new)


def _compare_float(name, meta, arrays, inputs, got, category, tol, tol_table, worst_rows):
    n = len(category)
    err, rel, ulp = np.zeros(n), np.zeros(n), np.zeros(n)
    rerr = rrel = rulp = None
    for o in meta["compare"]:
        a, r, u = _float_metrics(got[o], arrays[o], n)
        err, rel, ulp = np.maximum(err, a), np.maximum(rel, r), np.maximum(ulp, u)
        ref = _float32_reference(name, arrays, inputs, o)
        if ref is not None:
            ra, rr, ru = _float_metrics(got[o], ref, n)
            rerr, rrel, rulp = _max_or_none(rerr, ra), _max_or_none(rrel, rr), _max_or_none(rulp, ru)
    categories = {}
    for c in _CATEGORIES:
        sel = category == c
        if not sel.any():
            continue
        categories[c] = CategoryResult(
            c, int(sel.sum()), float(tol_table[c]), int((err[sel] > tol[sel]).sum()),
            float(err[sel].max()), float(rel[sel].max()), float(ulp[sel].max()),
            *(None if x is None else float(x[sel].max()) for x in (rerr, rrel, rulp)))
    o = meta["compare"][0]
    ref0 = _float32_reference(name, arrays, inputs, o)
    components = None
    if np.ndim(arrays[o]) == 2:
        def per_component(ref):
            return "[" + ", ".join(_fmt_ulps(float(x)) for x in ulp_distance(got[o], ref).max(axis=0)) + "]"

        components = {"ulps": per_component(arrays[o]), "ref_ulps": None if ref0 is None else per_component(ref0)}
    worst = [_row(i, category, err, tol, got[o], arrays[o], ref0, inputs, arrays["comment"],
                  rel=float(rel[i]), ulps=float(ulp[i]))
             for i in select_worst(category, err, tol, worst_rows)]
    return CaseVerdict(False, categories, worst, components)


def _fmt_ulps(x):
    return str(x) if not np.isfinite(x) else (f"{int(x)}" if x < 1e6 else f"{x:.3g}")


def compare_case(name, meta, arrays, got, worst_rows=5):
    """Compare a port's outputs with one golden case.

    Parameters
    ----------
    name : str
        The case name (``shade-float32``); the reference is looked up by it for the
        tie rule and the float32 emulation of float64 cases.
    meta : dict
        The case's manifest entry (``compare``, ``exact``, ``dtype``, ``tolerances``).
    arrays : dict name -> array
        The golden file: inputs, expected outputs, ``category`` and ``comment``.
    got : dict name -> array
        The port's outputs named as in ``meta["compare"]``.
    worst_rows : int
        Rows to list per failing category.

    Returns
    -------
    CaseVerdict
    """
    category = np.asarray(arrays["category"]).astype(str)
    tol_table = meta["tolerances"][GATE_DTYPE]
    tol = np.array([float(tol_table[c]) for c in category])
    inputs = {k: arrays[k] for k in meta["inputs"]}
    compare = _compare_exact if meta["exact"] else _compare_float
    verdict = compare(name, meta, arrays, inputs, got, category, tol, tol_table, worst_rows)
    if meta["dtype"] == "float64" and any(np.asarray(v).dtype.kind == "f" for v in inputs.values()):
        verdict.notes.append("float64 case: inputs rounded to float32 for upload; gated by the manifest's "
                             "float32 column")
    return verdict
