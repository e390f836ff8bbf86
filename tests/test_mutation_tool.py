"""The mutation tool (moments_ref.tools.mutation): its mutants, their ids, the code swap, the equivalents file."""

import os
import tempfile
import textwrap
import time
from pathlib import Path

import pytest

from moments_ref.tools.mutation import ROOT, TARGETS, load_equivalents, module_files, mutants_of, score_table
from moments_ref.tools.mutation import _capped, _run_module
from moments_ref.tools.mutation._execute import _forked, run_mutant
from moments_ref.tools.mutation._operators import mutated_code

SOURCE = textwrap.dedent('''
    """Module docstring: never mutated."""
    import numpy as np

    LIMIT = 3  # module level: a setting, never mutated


    def f(a, b=2, *, c: int = 5):
        """Docstring."""
        if a < b and not c:
            return -a
        return np.floor(abs(a) * b) + 1


    def g(x):
        msg = f"{x + 1} is not allowed"
        return x != 0  # pragma: no mutate
''')


def _by_text(mutants):
    return {(m.before, m.after) for m in mutants}


def test_one_change_per_mutant_in_function_bodies_only():
    ms = mutants_of(SOURCE, "m.py")
    got = _by_text(ms)
    assert got == {
        ("a < b", "a <= b"), ("a < b and (not c)", "a < b or not c"), ("not c", "c"), ("-a", "a"),
        ("np.floor", "np.ceil"), ("abs(a)", "a"), ("np.floor(abs(a) * b) + 1", "np.floor(abs(a) * b) - 1"),
        ("abs(a) * b", "abs(a) / b"), ("1", "2"), ("1", "0"),
        # the guard skipped, and its return always taken (an early return)
        ("a < b and (not c)", "False"), ("a < b and (not c)", "True"),
    }
    # the default values, the annotation, the f-string message, the docstrings, the module-level
    # constant and the pragma line give none
    assert all(m.function in ("f", "g") for m in ms) and not any(m.function == "g" for m in ms)


def test_ids_survive_edits_elsewhere_in_the_file():
    moved = SOURCE.replace('import numpy as np\n', 'import numpy as np\n\n\ndef h(y):\n    return y * 2\n')
    old = {m.id for m in mutants_of(SOURCE, "m.py")}
    new = {m.id for m in mutants_of(moved, "m.py")}
    assert old < new and all(i.startswith("m.py::") for i in new)
    lines_old = {m.id: m.lines for m in mutants_of(SOURCE, "m.py")}
    lines_new = {m.id: m.lines for m in mutants_of(moved, "m.py")}
    assert all(lines_new[i][0] == lines_old[i][0] + 4 for i in old)


def test_the_mutated_code_computes_the_mutant():
    namespace = {}
    exec(compile(SOURCE, "m.py", "exec"), namespace)
    f = namespace["f"]
    assert f(3, 4, c=0) == -3
    (m,) = [m for m in mutants_of(SOURCE, "m.py") if m.after == "a <= b"]
    f.__code__ = mutated_code(SOURCE, "m.py", m)
    assert f(4, 4, c=0) == -4  # the boundary moved
    (m,) = [m for m in mutants_of(SOURCE, "m.py") if m.before == "abs(a)"]
    f.__code__ = mutated_code(SOURCE, "m.py", m)
    assert f(-3, 1, c=1) == -2  # floor(-3) + 1, the absolute value dropped


def test_the_score_counts_equivalents_out_and_reports_stale_ones():
    state = {"a.py": {"mutants": {"a.py::f::x -> y#0": ["killed", "t"], "a.py::f::x -> z#0": ["survived", ""],
                                  "a.py::f::u -> v#0": ["survived", ""], "a.py::f::p -> q#0": ["timeout", ""]}}}
    rows, survivors, stale = score_table(state, ["a.py"], {"a.py::f::u -> v#0": "why", "a.py::f::gone#0": "why"})
    assert rows[2] == "| a.py | 4 | 1 | 1 | 1 | 1 | 67% |"
    assert survivors == [("a.py::f::x -> z#0", "survived", "")] and stale == ["a.py::f::gone#0"]
    # measured against fewer tests than the suite (named tests, or a cap per mutant): a lower bound
    state["a.py"]["subset"] = True
    assert score_table(state, ["a.py"], {})[0][2] == "| a.py | 4 | 1 | 1 | 0 | 2 | ≥ 50% |"


def test_the_cap_runs_the_cheapest_tests_within_the_seconds_and_at_least_one():
    durations = {"a": 1.0, "b": 2.0, "c": 4.0}
    tests = ["a", "b", "c"]
    assert _capped(tests, durations, None) == tests
    assert _capped(tests, durations, 3.0) == ["a", "b"]  # 1 + 2 <= 3 < 1 + 2 + 4
    assert _capped(tests, durations, 2.9) == ["a"]
    assert _capped(["c", "a"], durations, 0.5) == ["c"]  # one test even over the cap, in the order given
    assert _capped(["x"], durations, 0.5) == ["x"]  # a test without a measured time counts 1 s


def test_a_capped_survivor_says_how_many_of_its_tests_ran(tmp_path):
    """End to end: a mutant reached by a killing test and a cheaper passing one survives a cap
    that stops before the killing test, and its result names the cap."""
    path = "moments_ref/report/_winners.py"
    src = (ROOT / path).read_text()
    (m,) = [m for m in mutants_of(src, path) if m.id.endswith("own_scale::oh * ow / (h * w) -> oh * ow * (h * w)#0")]
    killer = "tests/test_report_winners.py::test_costs_scale_to_the_scenes_own_size"
    cheap = "tests/test_mutation_tool.py::test_modules_are_named_by_path_or_dotted_name[moments_ref.golden.compare]"
    lines = {ln: [cheap, killer] for ln in range(m.lines[0], m.lines[1] + 1)}
    durations = {cheap: 0.01, killer: 1.0}
    results = {}
    _run_module(path, lines, durations, [m.id], results, max_seconds=0.5)
    assert results[m.id] == ["survived", "(ran 1 of the 2 tests that reach it)"]
    _run_module(path, lines, durations, [m.id], results)
    assert results[m.id] == ["killed", killer]


def test_every_equivalent_names_a_mutant_of_a_measured_module_with_its_reason():
    equivalents = load_equivalents()
    ids = {m.id for p in module_files(TARGETS) for m in mutants_of((ROOT / p).read_text(), p)}
    stale = sorted(set(equivalents) - ids)
    assert not stale, f"equivalents naming no mutant (the code changed: re-judge them): {stale[:5]}"
    assert all(len(why.strip()) > 20 for why in equivalents.values())


def test_a_swapped_function_is_seen_through_every_reference():
    """End to end on a real module: the unmutated code passes its test, a mutant of it is killed."""
    path = "moments_ref/report/_winners.py"
    src = (ROOT / path).read_text()
    test = ["tests/test_report_winners.py::test_costs_scale_to_the_scenes_own_size"]
    (m,) = [m for m in mutants_of(src, path) if m.id.endswith("own_scale::oh * ow / (h * w) -> oh * ow * (h * w)#0")]
    assert run_mutant("moments_ref.report._winners", "", None, test, 300)[0] == "survived"
    status, by = run_mutant("moments_ref.report._winners", m.top, mutated_code(src, path, m), test, 300)
    assert (status, by) == ("killed", test[0])


@pytest.mark.parametrize("name", ["moments_ref.golden.compare", "moments_ref/golden/compare.py"])
def test_modules_are_named_by_path_or_dotted_name(name):
    assert module_files([name]) == ["moments_ref/golden/compare.py"]


def test_a_mutant_of_a_cached_function_is_not_hidden_by_the_parents_cache():
    """An lru_cache'd table filled by the unmutated code before the fork must not answer for the mutant."""
    import numpy as np

    from moments_ref import packing

    for dt in (np.float32, np.float64):  # the parent's cache holds the unmutated tables (keyed as pack64 asks)
        packing._decoded_xi64(np.dtype(dt))
    path = "moments_ref/packing.py"
    src = (ROOT / path).read_text()
    (m,) = [m for m in mutants_of(src, path) if m.id.endswith("_decoded_xi64::_U16 + 1 -> _U16 - 1#0")]
    test = ["tests/test_packing.py::test_xi4_at_and_beyond_the_clamp_gets_the_top_code"]
    assert run_mutant("moments_ref.packing", m.top, mutated_code(src, path, m), test, 300)[0] == "killed"


def test_a_mutant_of_a_decorated_function_swaps_the_body_behind_the_wrapper():
    """A decorator that records what it wraps (functools.wraps): the mutant replaces the wrapped
    function's code, the one the source's def holds, and every call through the wrapper computes it."""
    import types

    from moments_ref.tools.mutation._execute import _live_function

    source = textwrap.dedent('''
        import functools


        def logged(fn):
            @functools.wraps(fn)
            def call(*args):
                return fn(*args)
            return call


        @logged
        def h(a):
            return a - 1
    ''')
    mod = types.ModuleType("m")
    exec(compile(source, "m.py", "exec"), mod.__dict__)
    (m,) = [m for m in mutants_of(source, "m.py") if m.function == "h" and m.after == "a + 1"]
    fn = _live_function(mod, m.top)
    assert fn is mod.h.__wrapped__
    fn.__code__ = mutated_code(source, "m.py", m)
    assert mod.h(5) == 6


def test_a_forked_childs_temporary_files_are_removed_however_it_ends(tmp_path):
    """A mutant's child ends without its exit handlers (os._exit, or killed at its timeout): the
    temporary files it leaves (a driver process's log was left in /tmp by each) are removed."""
    where = tmp_path / "where"

    def leave(then_hang):
        def child():
            fd, path = tempfile.mkstemp(prefix="left-")  # as the driver supervisor makes its log
            os.close(fd)
            where.write_text(path)
            if then_hang:
                time.sleep(60)
            return b"done"
        return child

    for hang in (False, True):
        where.unlink(missing_ok=True)  # each child names its own file: never the previous one's
        status, data, timed_out = _forked(leave(hang), 5)
        assert (status == 0 and data == b"done" and not timed_out) if not hang else timed_out
        left = Path(where.read_text())
        assert left.name.startswith("left-") and left.parent != Path(tempfile.gettempdir())  # a folder of its own
        assert not left.exists() and not left.parent.exists(), left


STYLES = textwrap.dedent('''
    import numpy as np


    def h(x, n, flag, strict=False):
        check(x)
        y = x[1:n] * 0.5
        if flag:
            y = y[::-1]
        if strict:
            raise ValueError("strict")
        ok = np.isfinite(y)
        spread = np.nanmax(y) + np.fmax(y, 0).max()
        return np.where(ok, y, -1.0).astype(np.float64), spread
''')


def test_the_styles_a_one_token_swap_rarely_writes():
    """Slices one off, constants doubled and halved, flags inverted, guards skipped, a check dropped,
    NaN handling changed, float64 narrowed, max averaged, where's branches swapped."""
    got = _by_text(mutants_of(STYLES, "s.py"))
    for pair in [("1:n", "1:n + 1"), ("1:n", "1:n - 1"), ("0.5", "1.0"), ("0.5", "0.25"), ("flag", "not flag"),
                 ("strict", "False"), ("check(x)", "pass"), ("np.isfinite(y)", "~np.isnan(y)"),
                 ("np.nanmax", "np.max"), ("np.fmax", "np.maximum"), ("np.float64", "np.float32"),
                 ("np.fmax(y, 0).max", "np.fmax(y, 0).mean"), ("1", "0"), ("-1", "1"),
                 ("np.where(ok, y, -1.0)", "np.where(ok, -1.0, y)")]:
        assert pair in got, pair
    # a raise guard is skipped, never forced (that mutant dies on every call: it measures nothing)
    assert ("strict", "True") not in got
    ids = [m.id for m in mutants_of(STYLES, "s.py")]
    assert len(ids) == len(set(ids))


@pytest.mark.parametrize("before, after, args, want", [
    ("1:n", "1:n + 1", ([1.0, 2.0, 4.0, 8.0], 2, False), 2.0),  # unmutated: 1.0
    ("flag", "not flag", ([1.0, 2.0, 4.0, 8.0], 3, False), 1.0),  # unmutated: 2.0
    ("check(x)", "pass", ([1.0, 2.0, 4.0], 3, False), 2.0),  # unmutated: check raises
    ("np.isfinite(y)", "~np.isnan(y)", ([1.0, 2.0, 8.0, float("inf")], 4, False), float("inf")),  # unmutated: -1
])
def test_each_style_computes_its_mutant(before, after, args, want):
    import numpy as np

    namespace = {"check": lambda x: (_ for _ in ()).throw(ValueError("checked"))}
    exec(compile(STYLES, "s.py", "exec"), namespace)
    h = namespace["h"]
    (m,) = [m for m in mutants_of(STYLES, "s.py") if (m.before, m.after) == (before, after)]
    h.__code__ = mutated_code(STYLES, "s.py", m)
    if before != "check(x)":
        namespace["check"] = lambda x: None
    x, n, flag = args
    got, _ = h(np.array(x), n, flag)
    assert float(got[-1]) == want


def test_the_default_list_holds_every_module_a_verdict_depends_on():
    from moments_ref.tools.mutation import VERDICT_MODULES, _sweep_modules

    for need in ("golden/contract.py", "golden/conventions.py", "golden/bilinear.py", "golden/compare.py",
                 "golden/profile.py", "golden/spread.py", "golden/bands.py", "golden/engine.py", "golden/loader.py",
                 "conformance/verdict.py", "conformance/kernel/verdict.py", "conformance/kernel/contract.py"):
        assert f"moments_ref/{need}" in VERDICT_MODULES and f"moments_ref/{need}" in TARGETS
    sweep = ROOT / "moments_ref" / "sweep"
    assert set(_sweep_modules()) == ({str(f.relative_to(ROOT)) for f in sweep.rglob("*.py") if f.name != "__main__.py"}
                                     if sweep.is_dir() else set())
    assert set(_sweep_modules()) <= set(TARGETS)


def test_the_docs_table_is_written_by_the_command(tmp_path):
    from moments_ref.tools.mutation import DOC_MARKS, write_doc_table

    doc = tmp_path / "t.md"
    doc.write_text(f"intro\n{DOC_MARKS[0]}\n| module | a |\n|---|---|\n| x.py | 1 |\n| y.py | 2 |\n{DOC_MARKS[1]}\nend\n")
    write_doc_table(["| module | a |", "|---|---|", "| y.py | 3 |", "| z.py | 4 |"], doc)
    assert doc.read_text() == (f"intro\n{DOC_MARKS[0]}\n| module | a |\n|---|---|\n| x.py | 1 |\n| y.py | 3 |\n"
                               f"| z.py | 4 |\n{DOC_MARKS[1]}\nend\n")


def test_the_docs_table_is_the_tools_arithmetic():
    """Each row of docs/testing.md's table: killed + timed out + equivalent + survived = mutants, and the
    score is (killed + timed out) / (mutants − equivalent), as score_table writes it."""
    import re

    from moments_ref.tools.mutation import DOC, DOC_MARKS

    block = DOC.read_text().split(DOC_MARKS[0])[1].split(DOC_MARKS[1])[0].strip().splitlines()
    assert block[0] == "| module | mutants | killed | timed out | equivalent | survived | score |"
    for row in block[2:]:
        name, n, k, t, e, s, score = [c.strip() for c in row.strip("|").split("|")]
        n, k, t, e, s = map(int, (n, k, t, e, s))
        assert k + t + e + s == n, row
        assert re.fullmatch(r"(≥ )?\d+%", score) and int(score.strip("≥ %")) == round(100 * (k + t) / (n - e)), row


def _golden_imports(path):
    """The golden modules ``path`` imports, at the top or inside a function (``from .x import``, ``from . import x``,
    ``from ..golden.x import``, ``from ..golden import x``)."""
    import ast

    out = set()
    for node in ast.walk(ast.parse((ROOT / path).read_text())):
        if not isinstance(node, ast.ImportFrom):
            continue
        here = path.startswith("moments_ref/golden/")
        mod = node.module or ""
        if node.level == 1 and here:
            names = [mod] if mod else [a.name for a in node.names]
        elif node.level == 2 and mod.startswith("golden"):
            names = [mod.removeprefix("golden").lstrip(".")] if mod != "golden" else [a.name for a in node.names]
        else:
            continue
        out |= {f"moments_ref/golden/{n.split('.')[0]}.py" for n in names
                if n and (ROOT / "moments_ref" / "golden" / f"{n.split('.')[0]}.py").is_file()}
    return out


def test_the_golden_truth_a_verdict_depends_on_is_measured():
    """Every one of the truth modules (the mpmath chains, the exact texel codes, the files' values, the legitimate GPU
    and paper evaluations) is reached by imports from the verdict's modules (bands, compare, verifier, the sweep's
    judge) and is in VERDICT_MODULES, so that the tool measures it by default."""
    from moments_ref.tools.mutation import VERDICT_MODULES

    seen, todo = set(), ["moments_ref/golden/bands.py", "moments_ref/golden/compare.py",
                         "moments_ref/golden/verifier.py", "moments_ref/sweep/judge.py", "moments_ref/sweep/engine.py"]
    while todo:
        p = todo.pop()
        if p not in seen:
            seen.add(p)
            todo += sorted(_golden_imports(p))
    for need in ("truth", "texel_truth", "values", "gpuspread", "paper"):
        assert f"moments_ref/golden/{need}.py" in seen, need
        assert f"moments_ref/golden/{need}.py" in VERDICT_MODULES and f"moments_ref/golden/{need}.py" in TARGETS
    assert "moments_ref/golden/writer.py" in seen and "moments_ref/golden/casedoc.py" not in seen  # the walk's reach
