"""Mutation testing of the oracle: which rows kill which mutant of an independent port.

A *corpus* is a Python file ``corpus.py`` (the project's is ``tests/mutants``)
defining ``MUTANTS``: objects with ``name``, ``kind`` (see :data:`KINDS`), ``why``,
``case_names()`` (golden cases to check) and ``run(case, inputs, kwargs) ->
{output: array}``, optionally ``profile`` (a :class:`~moments_ref.golden.profile.Profile`:
the engine conventions the mutant is run with, docs/ports.md). Each mutant is judged
on every listed case by the golden comparator (:mod:`moments_ref.golden.compare`),
exactly as ``moments-ref verify`` judges a port, at two levels: the verdict
(contract rows) and ``--strict`` (robustness rows gated too). The oracle is right
when every mutant gets the verdict its kind demands.
"""

from __future__ import annotations

import importlib.util
import sys
from dataclasses import dataclass
from pathlib import Path

from .._arrays import InputError
from .cases import CASES
from .compare import compare
from .writer import golden_arrays, manifest_entry

__all__ = ["load_corpus", "run_corpus", "format_table", "score", "report", "MutantResult", "default_corpus", "KINDS"]

#: What each kind of mutant must get, at the verdict's level and with --strict.
KINDS = {
    "bug": "a mistake porters make: killed by the verdict (contract rows or engine rows)",
    "legit": "a legitimate implementation choice: passes the verdict",
    "robustness": "legitimate on the algorithm's contract, different beyond it (e.g. no singular branch): "
                  "passes the verdict, killed with --strict",
    "equivalent": "cannot alter any output (shown by a fuzzed bitwise comparison): passes at both levels",
    "within_band": "differs from the prescribed output only inside the band of a conformant GPU's legitimate "
                   "outputs (a texel code on its own rounding tie), where a correct port may return the same: no "
                   "verdict can tell it from a correct port (shown by a fuzzed comparison against the band): "
                   "passes at both levels",
}


@dataclass
class MutantResult:
    name: str
    kind: str
    why: str
    killed: bool  # by the verdict (contract rows)
    killed_by: list  # (case, failing rows, first failing tc_ids, flags of the first failing row)
    error: str = ""
    killed_strict: bool = False  # with --strict (robustness rows gated too)
    killed_by_strict: list = None

    @property
    def correct(self):
        """The oracle's answer is right: every kind gets the verdicts :data:`KINDS` demands."""
        if self.kind == "bug":
            return self.killed
        if self.kind == "robustness":
            return not self.killed and self.killed_strict
        if self.kind in ("equivalent", "within_band"):
            return not self.killed and not self.killed_strict
        return not self.killed


def default_corpus():
    """``tests/mutants`` of a source checkout, if the package runs from one."""
    p = Path(__file__).resolve().parents[2] / "tests" / "mutants"
    return p if (p / "corpus.py").is_file() else None


def load_corpus(path):
    """The ``MUTANTS`` list of ``path/corpus.py`` (or of a ``.py`` file)."""
    path = Path(path)
    file = path / "corpus.py" if path.is_dir() else path
    if not file.is_file() or file.suffix != ".py":
        raise InputError(f"corpus: expected a folder with corpus.py or a .py file, got {str(path)!r}")
    sys.path.insert(0, str(file.parent))
    try:
        spec = importlib.util.spec_from_file_location("moments_ref_mutant_corpus", file)
        module = importlib.util.module_from_spec(spec)
        sys.modules[spec.name] = module
        spec.loader.exec_module(module)
    except (SyntaxError, ImportError, UnicodeDecodeError) as exc:
        raise InputError(f"corpus: could not import {str(file)!r}: {type(exc).__name__}: {exc}") from None
    finally:
        sys.path.remove(str(file.parent))
    mutants = getattr(module, "MUTANTS", None)
    if not mutants or not isinstance(mutants, (list, tuple)):
        raise InputError(f"corpus: {str(file)!r} defines no MUTANTS list")
    return mutants


def _golden(name, cache, profile=None):
    key = (name, None if profile is None else profile.key)
    if key not in cache:
        if name not in CASES:
            raise InputError(f"corpus: unknown golden case {name!r}")
        if profile is None:
            case = CASES[name]
            arrays = golden_arrays(case)
        else:
            from .conventions import profiled_arrays

            case, arrays = profiled_arrays(name, profile)  # from the case's arrays, generated once per process
        cache[key] = (case, arrays, manifest_entry(case, arrays))
    return cache[key]


def _killers(v, arrays, name):
    rows = v.worst_rows(None)
    return (name, len(rows), [int(arrays["tc_id"][i]) for i in rows[:3]],
            str(arrays["flags"][rows[0]]) or str(arrays["category"][rows[0]]))


def _judge(mu, name, cache):
    """``(killer at the verdict's level or None, killer with strict or None, error)`` of one case."""
    case, arrays, entry = _golden(name, cache, getattr(mu, "profile", None))
    inputs = {k: arrays[k] for k in case.inputs}
    try:
        got = mu.run(name, inputs, entry["kwargs"])
        plain = None if getattr(mu, "profile", None) is not None else CASES.get(name)  # golden.compare.confirm_ill
        v = compare(entry, arrays, got, case=name, neighbourhood=plain)
        vs = compare(entry, arrays, got, case=name, strict=True, neighbourhood=plain)
    except Exception as exc:  # a crash or a wrong dtype kills the mutant
        crash = (name, -1, [], "")
        return crash, crash, f"{type(exc).__name__}: {exc}"
    return (None if v.passed else _killers(v, arrays, name)), (None if vs.passed else _killers(vs, arrays, name)), ""


def run_corpus(mutants, progress=None, cache=None):
    """Judge every mutant at both levels; returns a list of :class:`MutantResult`."""
    cache = {} if cache is None else cache
    results = []
    for mu in mutants:
        killed_by, strict_by, error = [], [], ""
        for name in mu.case_names():
            k, ks, err = _judge(mu, name, cache)
            error = error or err
            killed_by += [k] if k else []
            strict_by += [ks] if ks else []
        results.append(MutantResult(mu.name, mu.kind, mu.why, bool(killed_by), killed_by, error,
                                    bool(strict_by), strict_by))
        if progress is not None:
            progress(mu.name)
    return results


def score(results):
    """Counts per kind: bugs killed, legit passing, robustness mutants passing and killed with --strict, ..."""
    count = lambda kind, pred: sum(1 for r in results if r.kind == kind and pred(r))  # noqa: E731
    return {
        "bugs": count("bug", lambda r: True), "bugs_killed": count("bug", lambda r: r.killed),
        "legit": count("legit", lambda r: True), "legit_passing": count("legit", lambda r: not r.killed),
        "robustness": count("robustness", lambda r: True),
        "robustness_right": count("robustness", lambda r: not r.killed and r.killed_strict),
        "equivalent": count("equivalent", lambda r: True),
        "equivalent_passing": count("equivalent", lambda r: not r.killed and not r.killed_strict),
        "within_band": count("within_band", lambda r: True),
        "within_band_passing": count("within_band", lambda r: not r.killed and not r.killed_strict),
    }


def _by(killers):
    return "; ".join(f"{c}: {n if n >= 0 else 'crash'} rows {ids} {fl}".rstrip() for c, n, ids, fl in killers)


def format_table(results):
    """A Markdown table per level: the verdict (contract rows) and --strict; then the score."""
    lines = ["| mutant | kind | verdict (contract rows) | --strict (robustness rows too) | killed by "
             "(case: failing rows, first tc_ids, flags) |", "|---|---|---|---|---|"]
    for r in results:
        v = "killed" if r.killed else "passes"
        st = "killed" if r.killed_strict else "passes"
        if not r.correct:
            v += " (WRONG)"
        by = _by(r.killed_by) if r.killed else ("(strict) " + _by(r.killed_by_strict) if r.killed_strict else "")
        lines.append(f"| {r.name} | {r.kind} | {v} | {st} | {by or '-'} |")
    s = score(results)
    lines.append("")
    lines.append(f"contract level: bugs killed {s['bugs_killed']}/{s['bugs']}, legitimate variants passing "
                 f"{s['legit_passing']}/{s['legit']}, robustness variants passing "
                 f"{sum(1 for r in results if r.kind == 'robustness' and not r.killed)}/{s['robustness']}, "
                 f"equivalent mutants passing {s['equivalent_passing']}/{s['equivalent']}, "
                 f"within-band mutants passing {s['within_band_passing']}/{s['within_band']}")
    lines.append(f"strict level: robustness variants killed "
                 f"{sum(1 for r in results if r.kind == 'robustness' and r.killed_strict)}/{s['robustness']}, "
                 f"bugs killed {sum(1 for r in results if r.kind == 'bug' and r.killed_strict)}/{s['bugs']}, "
                 f"legitimate variants passing {sum(1 for r in results if r.kind == 'legit' and not r.killed_strict)}"
                 f"/{s['legit']}")
    return "\n".join(lines)


def report(corpus=None, progress=None):
    """``(table text, all verdicts right)`` for the corpus at ``corpus`` (default :func:`default_corpus`)."""
    path = corpus if corpus is not None else default_corpus()
    if path is None:
        raise InputError("corpus: no mutant corpus found; pass --corpus DIR (a folder with corpus.py)")
    results = run_corpus(load_corpus(path), progress=progress)
    return format_table(results), all(r.correct for r in results)
