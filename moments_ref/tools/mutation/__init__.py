"""Mutation score of the package's own modules: one-change mutants against the tests that reach them.

``python -m moments_ref.tools.mutation [MODULE ...]`` (from a source checkout, with the
``mutation`` extra: coverage.py) generates the one-change mutants of each module
(:mod:`._operators`), finds by per-test coverage which tests execute each mutated
statement, runs each mutant against those tests only (:mod:`._execute`) and prints per
module the mutants, killed, timed out, equivalent and surviving ones and the score
``(killed + timed out) / (mutants - equivalent)``, then every survivor. A survivor that
no test can kill, because the change does not alter what the function computes, is
marked *equivalent* in ``tests/mutation_equivalents.toml`` by its id, with the reason.

Without MODULE it measures :data:`TARGETS`, the verdict engine and its neighbours.
``--report`` prints the table of the last runs (``.mutation/results.json``) again, with
the equivalents file as it is now; ``--update-docs`` also writes it into docs/testing.md
between its ``<!-- scores: begin -->`` and ``<!-- scores: end -->`` lines (:func:`write_doc_table`),
so the table there is the command's output, never typed.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
import tomllib
from pathlib import Path

from ._operators import Mutant, mutants_of, mutated_code
from ._execute import baseline, collect_coverage, import_tests, module_name_of, run_mutant

__all__ = ["TARGETS", "VERDICT_MODULES", "write_doc_table", "Mutant", "mutants_of", "load_equivalents", "module_files", "score_table", "main"]

ROOT = Path(__file__).resolve().parents[3]
#: The modules every verdict depends on (the golden modules that shape one, the conformance
#: verdicts, the kernel judge and its contract, the sweep's package once it exists), then neighbours.
VERDICT_MODULES = (
    "moments_ref/golden/compare.py", "moments_ref/golden/spread.py", "moments_ref/golden/units.py",
    "moments_ref/golden/bands.py",
    "moments_ref/golden/loader.py", "moments_ref/golden/engine.py", "moments_ref/golden/_ddmoments.py",
    "moments_ref/golden/profile.py",
    "moments_ref/golden/contract.py", "moments_ref/golden/conventions.py", "moments_ref/golden/bilinear.py",
    "moments_ref/golden/diagnosis.py", "moments_ref/golden/verifier.py",
    # the truth a verdict is measured against: the mpmath chains and confirm_truth (truth), the exact texel codes
    # (texel_truth), the golden files' values (values, through loader), the legitimate GPU evaluations (gpuspread)
    # and the papers' formulations as legitimate variants (paper), each reached from bands, compare or verifier
    "moments_ref/golden/truth.py", "moments_ref/golden/texel_truth.py", "moments_ref/golden/values.py",
    "moments_ref/golden/gpuspread.py", "moments_ref/golden/paper.py",
    "moments_ref/conformance/verdict.py", "moments_ref/conformance/kernel/verdict.py",
    "moments_ref/conformance/kernel/contract.py",
)
NEIGHBOURS = (
    "moments_ref/report/_pareto.py", "moments_ref/report/_winners.py", "moments_ref/packing.py",
    "moments_ref/techniques/vwss/shading.py", "moments_ref/scene/raster/_spans.py",
    "moments_ref/conformance/kernel/trace.py", "moments_ref/conformance/kernel/run.py",
)


def _sweep_modules():
    """The sweep's modules (``moments_ref/sweep/``, its subfolders too) where the package exists."""
    folder = ROOT / "moments_ref" / "sweep"
    return tuple(sorted(str(f.relative_to(ROOT)) for f in folder.rglob("*.py")
                        if f.name != "__main__.py")) if folder.is_dir() else ()


#: The modules measured by default: :data:`VERDICT_MODULES`, the sweep's, then :data:`NEIGHBOURS`.
TARGETS = VERDICT_MODULES + _sweep_modules() + NEIGHBOURS
EQUIVALENTS = ROOT / "tests" / "mutation_equivalents.toml"
DOC = ROOT / "docs" / "testing.md"
DOC_MARKS = ("<!-- scores: begin -->", "<!-- scores: end -->")
STATE = ROOT / ".mutation"


def module_files(names):
    """Repository-relative ``.py`` paths of ``names`` (files, folders or dotted module names)."""
    out = []
    for name in names:
        p = Path(name.replace(".", "/") + ".py") if not name.endswith((".py", "/")) and "/" not in name else Path(name)
        full = p if p.is_absolute() else ROOT / p
        if full.is_dir():
            out += sorted(str(f.relative_to(ROOT)) for f in full.glob("*.py"))
        elif full.is_file():
            out.append(str(full.relative_to(ROOT)))
        else:
            raise SystemExit(f"mutation: no module {name!r}")
    return out


def load_equivalents(path=None):
    """``{mutant id: reason}`` from the equivalents file (default ``tests/mutation_equivalents.toml``).

    The file holds ``[[equivalent]]`` tables with ``id`` and ``why``.
    """
    path = EQUIVALENTS if path is None else path
    if not Path(path).is_file():
        return {}
    with open(path, "rb") as f:
        data = tomllib.load(f)
    out = {}
    for entry in data.get("equivalent", []):
        if not entry.get("why", "").strip():
            raise SystemExit(f"mutation: equivalent {entry.get('id')!r} has no reason")
        out[entry["id"]] = entry["why"]
    return out


def _sha(text):
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def _load_state():
    f = STATE / "results.json"
    return json.loads(f.read_text()) if f.is_file() else {}


def _save_state(state):
    STATE.mkdir(exist_ok=True)
    (STATE / "results.json").write_text(json.dumps(state, indent=1, sort_keys=True))


def _by_file(lines, durations, failed):
    """Split one coverage run by test file: ``{test file: {"lines", "durations", "failed"}}``."""
    out = {}
    for t, sec in durations.items():
        out.setdefault(t.split("::")[0], {"lines": {}, "durations": {}, "failed": []})["durations"][t] = sec
    for t in failed:
        out.setdefault(t.split("::")[0], {"lines": {}, "durations": {}, "failed": []})["failed"].append(t)
    for path, by_line in lines.items():
        for line, tests in by_line.items():
            for t in tests:
                f = out.setdefault(t.split("::")[0], {"lines": {}, "durations": {}, "failed": []})
                f["lines"].setdefault(path, {}).setdefault(str(line), []).append(t)
    return out


def _merged(cache, files):
    lines, durations, failed = {p: {} for p in files}, {}, []
    for entry in cache["by_file"].values():
        durations.update(entry["durations"])
        failed += entry["failed"]
        for p in files:
            for line, tests in entry["lines"].get(p, {}).items():
                lines[p].setdefault(int(line), []).extend(tests)
    return lines, durations, failed


def _coverage(files, pytest_args, reuse):
    """Per-test coverage of ``files``: from the cache (``reuse``, the files unchanged), where
    ``pytest_args`` name test files only those recollected; else over ``pytest_args``.

    Returns ``(lines, durations, failed, subset)``; ``subset``: the coverage run named its
    tests (not the whole suite), so a score measured on it is a lower bound.
    """
    f = STATE / "coverage.json"
    shas = {p: _sha((ROOT / p).read_text()) for p in files}
    cache = json.loads(f.read_text()) if reuse and f.is_file() else None
    if cache is not None and any(cache["modules"].get(p) != sha for p, sha in shas.items()):
        print("mutation: a module changed since the cached coverage: collecting it again", file=sys.stderr)
        cache = None
    if cache is None or pytest_args:
        print(f"mutation: per-test coverage of {len(files)} module(s) over pytest "
              f"{' '.join(pytest_args) or '(testpaths)'}", file=sys.stderr)
        fresh = _by_file(*collect_coverage(list(cache["modules"]) if cache else files, pytest_args))
        if cache is None:
            cache = {"modules": shas, "by_file": {}, "subset": bool(pytest_args)}
        else:
            for arg in pytest_args:  # the named test files are replaced whole
                cache["by_file"] = {k: v for k, v in cache["by_file"].items() if not k.startswith(arg.split("::")[0])}
        cache["by_file"].update(fresh)
        STATE.mkdir(exist_ok=True)
        f.write_text(json.dumps(cache))
    return (*_merged(cache, files), cache.get("subset", False))


def _tests_of(mutant, lines):
    tests = set()
    for line in range(mutant.lines[0], mutant.lines[1] + 1):
        tests.update(lines.get(line, ()))
    return tests


def _cheapest_first(tests, durations):
    """Test ids grouped by file, the file whose tests take least time first, then by duration."""
    per_file = {}
    for t in tests:
        f = t.split("::")[0]
        per_file[f] = per_file.get(f, 0.0) + durations.get(t, 1.0)
    return sorted(tests, key=lambda t: (per_file[t.split("::")[0]], t.split("::")[0], durations.get(t, 1.0)))


def _capped(tests, durations, max_seconds):
    """The first of ``tests`` (in the order given: the quickest first) whose measured times sum to
    at most ``max_seconds`` (at least one test; all of them when ``max_seconds`` is None)."""
    if max_seconds is None:
        return tests
    out, spent = [], 0.0
    for t in tests:
        spent += durations.get(t, 1.0)
        if out and spent > max_seconds:
            break
        out.append(t)
    return out


def _run_module(path, lines, durations, only, results, save=lambda: None, max_seconds=None):
    source = (ROOT / path).read_text()
    mutants = [m for m in mutants_of(source, path) if not only or any(o in m.id for o in only)]
    name = module_name_of(path)
    # per mutant: the tests that reach it, and those it runs (under the cap: the quickest, from any file)
    plans = {}
    for m in mutants:
        reaching = _tests_of(m, lines)
        quickest = sorted(reaching, key=lambda t: (durations.get(t, 1.0), t))
        plans[m.id] = (len(reaching), _cheapest_first(_capped(quickest, durations, max_seconds), durations))
    # the unmutated module must pass every test a mutant will run
    reached = sorted({t for _, ts in plans.values() for t in ts})
    ok, first, seconds = baseline(name, reached, 600 + 10 * sum(durations.get(t, 1) for t in reached))
    if not ok:
        raise SystemExit(f"mutation: {path}: the unmutated module fails its tests ({first})")
    for i, m in enumerate(mutants):
        n_reaching, tests = plans[m.id]
        if not tests:
            results[m.id] = ["no tests", ""]
        else:
            files = len({t.split("::")[0] for t in tests})
            timeout = 30 * files + 10 * sum(durations.get(t, 1.0) for t in tests)
            results[m.id] = list(run_mutant(name, m.top, mutated_code(source, path, m), tests, timeout, durations))
            if results[m.id][0] == "survived" and len(tests) < n_reaching:
                results[m.id][1] = f"(ran {len(tests)} of the {n_reaching} tests that reach it)"
        print(f"[{i + 1}/{len(mutants)}] {results[m.id][0]:8s} {m.id}", file=sys.stderr)
        save()  # an interrupted run keeps what it measured
    return mutants


def score_table(state, files, equivalents):
    """Markdown table per module and the surviving mutants (``(rows, survivors, stale)``)."""
    rows, survivors, known = [], [], set()
    for path in files:
        entry = state.get(path)
        if entry is None or not entry["mutants"]:  # unmeasured, or no mutant to make (sweep/judge.py: two calls)
            continue
        counts = dict.fromkeys(["killed", "timeout", "equivalent", "survived"], 0)
        for mid, (status, by) in entry["mutants"].items():
            known.add(mid)
            if status in ("killed", "timeout"):
                counts[status] += 1
            elif mid in equivalents:
                counts["equivalent"] += 1
            else:
                counts["survived"] += 1
                survivors.append((mid, status, by))
        n = len(entry["mutants"])
        live = n - counts["equivalent"]
        score = 100.0 * (counts["killed"] + counts["timeout"]) / live if live else 100.0
        bound = "≥ " if entry.get("subset") else ""  # fewer tests than the suite: a lower bound
        rows.append(f"| {path.removeprefix('moments_ref/')} | {n} | {counts['killed']} | {counts['timeout']} | "
                    f"{counts['equivalent']} | {counts['survived']} | {bound}{score:.0f}% |")
    head = ["| module | mutants | killed | timed out | equivalent | survived | score |", "|---|---|---|---|---|---|---|"]
    prefixes = tuple(f"{p}::" for p in files)
    stale = sorted(e for e in equivalents if e.startswith(prefixes) and e not in known)
    return head + rows, survivors, stale


def write_doc_table(rows, path=None):
    """Replace the table between :data:`DOC_MARKS` in ``path`` (default docs/testing.md) by ``rows``.

    Rows of modules the state does not hold stay as they are (measured before, by an earlier run);
    the measured ones are replaced or added, in the order of ``rows``.
    """
    path = DOC if path is None else Path(path)
    text = path.read_text()
    begin, end = DOC_MARKS
    if text.count(begin) != 1 or text.count(end) != 1 or text.index(begin) > text.index(end):
        raise SystemExit(f"mutation: {path} needs one {begin} ... {end} block")
    head, rest = text.split(begin)
    old, tail = rest.split(end)
    new = {r.split("|")[1].strip(): r for r in rows[2:]}
    kept = [r for r in old.strip().splitlines()[2:] if r.split("|")[1].strip() not in new]
    body = "\n".join(rows[:2] + kept + list(new.values()))
    path.write_text(f"{head}{begin}\n{body}\n{end}{tail}")


def _args(argv):
    ap = argparse.ArgumentParser(prog="python -m moments_ref.tools.mutation", description=__doc__.split("\n\n")[0])
    ap.add_argument("modules", nargs="*", help="files, folders or dotted names (default: TARGETS)")
    ap.add_argument("--tests", nargs="+", default=[], metavar="ARG",
                    help="pytest arguments of the coverage run (default: the whole suite, pyproject's testpaths)")
    ap.add_argument("--reuse-coverage", action="store_true",
                    help="reuse .mutation/coverage.json while the modules are unchanged; with --tests, collect only "
                         "those test files again and merge them in")
    ap.add_argument("--max-seconds", type=float, default=None, metavar="S",
                    help="per mutant, run only the quickest tests that reach it (from any file) whose measured times "
                         "sum to at most S seconds (at least one): the score is then a lower bound, marked ≥")
    ap.add_argument("--only", nargs="+", default=[], metavar="TEXT", help="only mutants whose id contains TEXT")
    ap.add_argument("--list", action="store_true", help="list the mutants and stop")
    ap.add_argument("--report", action="store_true", help="print the table of the last runs, run nothing")
    ap.add_argument("--update-docs", action="store_true",
                    help="write the table into docs/testing.md (between its scores markers)")
    return ap.parse_args(argv)


def main(argv=None):
    """``python -m moments_ref.tools.mutation``: measure, print the table and the survivors; returns 0."""
    args = _args(argv)
    files = module_files(args.modules or TARGETS)
    if args.list:
        for p in files:
            for m in mutants_of((ROOT / p).read_text(), p):
                print(m.id)
        return 0
    state = _load_state()
    if not args.report:
        import os

        os.chdir(ROOT)
        os.environ.setdefault("HYPOTHESIS_PROFILE", "ci")
        lines, durations, failed, subset = _coverage(files, args.tests, args.reuse_coverage)
        for t in failed:
            print(f"mutation: {t} fails unmutated; not used", file=sys.stderr)
        lines = {p: {k: [t for t in v if t not in failed] for k, v in d.items()} for p, d in lines.items()}
        import_tests({t for d in lines.values() for v in d.values() for t in v})
        for p in files:
            sha, old = _sha((ROOT / p).read_text()), state.get(p, {})
            keep = args.only and old.get("sha") == sha
            results = dict(old["mutants"]) if keep else {}
            lower = bool(subset or args.max_seconds is not None or (keep and old.get("subset")))
            state[p] = {"sha": sha, "mutants": results, "subset": lower}
            _run_module(p, lines.get(p, {}), durations, args.only, results, lambda: _save_state(state),
                        args.max_seconds)
    rows, survivors, stale = score_table(state, files, load_equivalents())
    print("\n".join(rows))
    if args.update_docs:
        write_doc_table(rows)
    for mid, status, note in survivors:
        print(f"{status}: {mid}" + (f" {note}" if note else ""))
    for mid in stale:
        print(f"stale equivalent (no such mutant): {mid}")
    return 0
