"""Helpers of the conformance tests, defined once (the fixtures built on them are in conftest.py).

A missing driver or compiler skips a test with the reason, except under CI
(``CI=true``), where it is a failure: .ci/run installs them so that the ports are
really exercised.
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import numpy as np
import pytest

from _oracles import golden_folder

__all__ = ["need", "need_tool", "shipped_golden_folder", "one_change", "assert_ties_are_the_float32_reference"]


def need(make, what):
    """``make()``, or skip (fail under CI) when it raises ContextError or ToolError (a driver, a compiler)."""
    from moments_ref.conformance import ContextError, ToolError

    try:
        return make()
    except (ContextError, ToolError) as exc:
        if os.environ.get("CI", "").lower() == "true":
            pytest.fail(f"CI=true but {what} is missing: {exc}")
        pytest.skip(f"{what} is missing: {exc}")


def need_tool(name):
    """The command ``name`` on PATH, or skip (fail under CI)."""
    from moments_ref.conformance import ToolError

    def find():
        if shutil.which(name) is None:
            raise ToolError(f"{name} is not installed")
        return name

    return need(find, name)


def shipped_golden_folder():
    """Goldens of every shipped case, written once per test run (shared by the conformance tests)."""
    from moments_ref import conformance

    return golden_folder(tuple(conformance.shipped_cases()))


def one_change(tmp_path, folder, fname, old, new):
    """A copy of ``folder/fname`` with ``old`` (found exactly once) replaced by ``new``, in ``tmp_path`` beside
    copies of the folder's other files of its language (its includes); returns the changed file's path."""
    suffix = Path(fname).suffix
    for f in Path(folder).glob(f"*{suffix}"):
        shutil.copy(f, tmp_path / f.name)
    src = (tmp_path / fname).read_text()
    assert src.count(old) == 1, f"the mutation no longer applies to the shipped {fname}"
    (tmp_path / fname).write_text(src.replace(old, new))
    return tmp_path / fname


def assert_ties_are_the_float32_reference(report, golden_dir, case):
    """An encoder port equals the reference in float32 on every row.

    The expected codes are exact (golden/texel_truth.py); where the reference's float32
    code differs from them the row is a rounding tie, and there the port must store the
    reference's float32 code (a tie used anywhere else is a difference).
    """
    from moments_ref.golden.cases import CASES, evaluate_reference

    text = report.format()
    assert all(c.mismatches == c.ties for c in report.categories.values()), text
    c = CASES[case]
    with np.load(Path(golden_dir) / f"{case}.npz") as g:
        inputs = {k: g[k] for k in c.inputs}
    reference = np.asarray(evaluate_reference(c, inputs, np.float32)[0])
    for r in report.worst:
        if r["tie"]:
            assert np.array_equal(np.asarray(r["got"]), reference[r["index"]]), (r, text)
