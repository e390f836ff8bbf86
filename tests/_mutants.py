"""The kept mutants of the verdict-power tests: one function's code swapped for a mutant's while a block runs.

Defined once for tests/test_verdict_power.py and tests/test_verdict_power_tolerances.py (the mutants are the
mutation tool's, :mod:`moments_ref.tools.mutation`, named by their ids).
"""

from __future__ import annotations

import importlib
from contextlib import contextmanager

from moments_ref.tools.mutation import ROOT, mutants_of
from moments_ref.tools.mutation._operators import mutated_code

__all__ = ["kept_mutant"]


@contextmanager
def kept_mutant(path, mid):
    """The function ``mid`` changes, with the mutant's code while the block runs."""
    source = (ROOT / path).read_text()
    found = [m for m in mutants_of(source, path) if m.id == f"{path}::{mid}"]
    assert found, f"no mutant {mid} in {path} any more: choose another one for this invariant"
    m = found[0]
    obj = importlib.import_module(path.removesuffix(".py").replace("/", "."))
    for part in m.top.split("."):
        obj = getattr(obj, part)
    fn = getattr(obj, "fget", obj)
    saved = fn.__code__
    fn.__code__ = mutated_code(source, path, m)
    try:
        yield
    finally:
        fn.__code__ = saved
