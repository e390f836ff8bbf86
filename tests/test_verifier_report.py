"""golden.verify's per-case report on a folder of one case, with failures placed by hand.

Rows perturbed by a known multiple of their own tolerance: the report must count them per
category, give each category's largest error/tolerance, list the failing rows worst first with
their tc_id, category, flags, error and tolerance, and say how many rows fail.
"""

from __future__ import annotations

import numpy as np
import pytest

from moments_ref import golden

CASE = "psi4-float32"


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    d = tmp_path_factory.mktemp("g")
    golden.write(d, [CASE])
    with np.load(d / f"{CASE}.npz") as g:
        return d, {k: g[k] for k in g.files}


def _results(tmp_path, g, moves):
    e, t = g["u"].astype(np.float64), g["u_tolerance_float32"]
    got = e.copy()
    for i, k in moves.items():
        got[i] = e[i] + k * t[i]
    p = tmp_path / "r.npz"
    np.savez(p, **{f"{CASE}.u": got.astype(np.float32)})
    return p


def test_the_report_counts_failures_per_category_and_names_the_worst_rows(folder, tmp_path):
    d, g = folder
    cat = np.asarray(g["category"])
    random, edge = np.flatnonzero(cat == "random"), np.flatnonzero(cat == "edge")
    assert random.size >= 2 and edge.size >= 1
    moves = {int(random[0]): 10.0, int(random[1]): -5.0, int(edge[0]): 3.0}
    c = golden.verify(d, _results(tmp_path, g, moves)).cases[0]
    assert c.status == "fail" and c.message == f"3 of {len(cat)} rows fail"
    rows, fails, worst = c.per_category["random"]
    assert (rows, fails) == (random.size, 2) and 9.5 < worst < 10.5
    rows, fails, worst = c.per_category["edge"]
    assert (rows, fails) == (edge.size, 1) and 2.5 < worst < 3.5
    assert sum(v[1] for v in c.per_category.values()) == 3
    assert sum(v[0] for v in c.per_category.values()) == len(cat)
    # the failing rows, worst first, each once, with their labels and numbers
    assert [w["index"] for w in c.worst] == [int(random[0]), int(random[1]), int(edge[0])]
    w = c.worst[0]
    i = int(random[0])
    assert w["tc_id"] == int(g["tc_id"][i]) and w["category"] == "random" and w["flags"] == str(g["flags"][i])
    assert w["tolerance"] == float(g["u_tolerance_float32"][i]) and 9.5 < w["error"] / w["tolerance"] < 10.5
    for w, k in zip(c.worst, (10.0, 5.0, 3.0)):  # errors are distances: positive, |k| tolerances
        assert abs(w["error"] / w["tolerance"] - k) < 0.5
    w = c.worst[0]
    assert w["comment"] == str(g["comment"][i]) and float(w["inputs"]["xi4"]) == float(g["xi4"][i])


def test_a_passing_port_has_no_message_and_every_category_its_rows(folder, tmp_path):
    d, g = folder
    c = golden.verify(d, _results(tmp_path, g, {})).cases[0]
    assert c.status == "pass" and c.message == "" and c.worst == []
    cat = np.asarray(g["category"])
    assert {k: v[0] for k, v in c.per_category.items()} == {k: int((cat == k).sum()) for k in set(cat.tolist())}
    assert all(v[1] == 0 and v[2] <= 1 for v in c.per_category.values())
