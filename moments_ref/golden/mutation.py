"""Mutation testing of the oracle: which rows kill which mutant of an independent port.

A *corpus* is a Python file ``corpus.py`` (the project's is ``tests/mutants``)
defining ``MUTANTS``: objects with ``name``, ``kind`` (``bug``, ``legit`` or
``equivalent``), ``why``, ``case_names()`` (golden cases to check) and
``run(case, inputs, kwargs) -> {output: array}``. Each mutant is judged on every
listed case by the golden comparator (:mod:`moments_ref.golden.compare`), exactly
as ``moments-ref verify`` judges a port. The oracle is right when every ``bug`` is
killed and every ``legit`` and ``equivalent`` mutant passes.
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

__all__ = ["load_corpus", "run_corpus", "format_table", "score", "report", "MutantResult", "default_corpus"]


@dataclass
class MutantResult:
    name: str
    kind: str
    why: str
    killed: bool
    killed_by: list  # (case, failing rows, first failing tc_ids, flags of the first failing row)
    error: str = ""

    @property
    def correct(self):
        """The oracle's answer is right: bugs killed, the others passing."""
        return self.killed == (self.kind == "bug")


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


def _golden(name, cache):
    if name not in cache:
        if name not in CASES:
            raise InputError(f"corpus: unknown golden case {name!r}")
        case = CASES[name]
        arrays = golden_arrays(case)
        cache[name] = (case, arrays, manifest_entry(case, arrays))
    return cache[name]


def run_corpus(mutants, progress=None, cache=None):
    """Judge every mutant; returns a list of :class:`MutantResult`."""
    cache = {} if cache is None else cache
    results = []
    for mu in mutants:
        killed_by, error = [], ""
        for name in mu.case_names():
            case, arrays, entry = _golden(name, cache)
            inputs = {k: arrays[k] for k in case.inputs}
            try:
                got = mu.run(name, inputs, entry["kwargs"])
                v = compare(entry, arrays, got, case=name)
            except Exception as exc:  # a crash or a wrong dtype kills the mutant
                killed_by.append((name, -1, [], ""))
                error = f"{type(exc).__name__}: {exc}"
                continue
            if not v.passed:
                rows = v.worst_rows(None)
                killed_by.append((name, len(rows), [int(arrays["tc_id"][i]) for i in rows[:3]],
                                  str(arrays["flags"][rows[0]]) or str(arrays["category"][rows[0]])))
        results.append(MutantResult(mu.name, mu.kind, mu.why, bool(killed_by), killed_by, error))
        if progress is not None:
            progress(mu.name)
    return results


def score(results):
    """Counts: bugs, bugs killed, legit, legit passing (no false alarm), equivalents passing."""
    count = lambda kind, pred: sum(1 for r in results if r.kind == kind and pred(r))  # noqa: E731
    return {
        "bugs": count("bug", lambda r: True), "bugs_killed": count("bug", lambda r: r.killed),
        "legit": count("legit", lambda r: True), "legit_passing": count("legit", lambda r: not r.killed),
        "equivalent": count("equivalent", lambda r: True),
        "equivalent_passing": count("equivalent", lambda r: not r.killed),
    }


def format_table(results):
    """A Markdown table: mutant, kind, verdict, which rows killed it; and the score."""
    lines = ["| mutant | kind | verdict | killed by (case: failing rows, first tc_ids, flags) |",
             "|---|---|---|---|"]
    for r in results:
        verdict = "killed" if r.killed else "passes"
        if not r.correct:
            verdict += " (WRONG)"
        by = "; ".join(f"{c}: {n if n >= 0 else 'crash'} rows {ids} {fl}".rstrip() for c, n, ids, fl in r.killed_by)
        lines.append(f"| {r.name} | {r.kind} | {verdict} | {by or '-'} |")
    s = score(results)
    lines.append("")
    lines.append(f"bugs killed {s['bugs_killed']}/{s['bugs']}, legitimate variants passing "
                 f"{s['legit_passing']}/{s['legit']}, equivalent mutants passing "
                 f"{s['equivalent_passing']}/{s['equivalent']}")
    return "\n".join(lines)


def report(corpus=None, progress=None):
    """``(table text, all verdicts right)`` for the corpus at ``corpus`` (default :func:`default_corpus`)."""
    path = corpus if corpus is not None else default_corpus()
    if path is None:
        raise InputError("corpus: no mutant corpus found; pass --corpus DIR (a folder with corpus.py)")
    results = run_corpus(load_corpus(path), progress=progress)
    return format_table(results), all(r.correct for r in results)
