"""golden.diagnosis.target_groups: a singular declared target explains only the rows the papers' target would pass.

The rule (HPG17 §3.2's bias toward an interior point; the diagnosis' docstring): a failing row
belongs to the ``target`` group when the papers' own formulation biased with the declared target
misses its expected value while the same formulation with the papers' interior target does not.
Perturbed input: rows whose expected value is moved by 0.5 (which no bias target explains: the
papers' target misses them too) fail, and must stay out of the group.
"""

from __future__ import annotations

import numpy as np
import pytest

from moments_ref.golden.compare import compare
from moments_ref.golden.conventions import profiled_arrays
from moments_ref.golden.diagnosis import groups, target_groups
from moments_ref.golden.profile import parse_profile
from moments_ref.golden.writer import manifest_entry
from mutants import corpus, ports

CASE = "engine-lower-float32"


@pytest.fixture(scope="module")
def singular():
    p = parse_profile({"depth": "[0,1]", "output": "visibility",
                       "bias": {"alpha": 3e-6, "target": corpus.SINGULAR01, "applied": "inside"}})
    case, arrays = profiled_arrays(CASE, p)
    bad = ports.alg1(arrays["b"], arrays["zf"], {"literal_root": True, "no_singular": True, "visibility": True,
                                                  "bias": (3e-6, corpus.SINGULAR01)})
    return p, case, arrays, bad


def test_rows_the_papers_target_misses_too_are_not_the_targets(singular):
    p, case, arrays, bad = singular
    entry = manifest_entry(case, arrays)
    v = compare(entry, arrays, {"intensity": bad}, case=case.name)
    target = set(target_groups(v, arrays, p.bias, case.engine)[0].rows)
    assert target and target == set(np.flatnonzero(~v.row_pass).tolist())
    # move the expected value of five contract rows the port gets right (tolerance below 0.1) by 0.5 (inside
    # [0, 1]): they fail now, but the papers' formulation with the papers' target misses them as much: no target
    # explains them
    moved = dict(arrays)
    e = np.asarray(arrays["intensity"], np.float64).copy()
    tol = np.asarray(arrays["intensity_tolerance_float32"], np.float64)
    ok = np.flatnonzero(v.row_pass & ~v.robust & (tol < 0.1))[:5]
    assert len(ok) == 5
    e[ok] = np.where(e[ok] < 0.5, e[ok] + 0.5, e[ok] - 0.5)
    moved["intensity"] = e
    vm = compare(entry, moved, {"intensity": bad}, case=case.name)
    assert set(np.flatnonzero(~vm.row_pass).tolist()) == target | set(ok.tolist())
    gs = target_groups(vm, moved, p.bias, case.engine)
    assert len(gs) == 1 and set(gs[0].rows) == target
    # the moved rows are grouped apart from the target's, by their own level
    rest = [g for g in groups(vm, moved, gs) if g.level != "target"]
    assert set().union(*(set(g.rows) for g in rest)) == set(ok.tolist())
