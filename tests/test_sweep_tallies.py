"""The sweep's tallies, counted by hand on small sweeps of Python ports with bugs placed by hand.

The chunk size is made small here (40 rows; ``samplers.CHUNK`` and ``runner.CHUNK``) so that a sweep of 100
rows has three chunks, the last one partial (40, 40, 20). Each port is this package's Algorithm 1 in float32
(``msm.shadow_intensity``, which every row's band holds) except at positions of each call that the test
chooses: there it answers the reference moved by 1/2 (or NaN), which no band of the case reaches and mpmath
confirms. A call is one chunk (the port is called once per chunk and driver, vectorised), so the positions
place the bugs at chunk boundaries, in the partial chunk, or beyond the confirmation cap. The tallies the
runner and the merge report (rows, flagged, examined, confirmed, unconfirmed, per stratum, the first
confirmed row's global index, the kept rows) are compared with the counts of those positions, the strata
read from the draw itself (``draw_rows``, the rows the port received).
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from moments_ref import golden
from moments_ref.sweep import STRATA, Port, SweepSpec, run_chunks, runner, samplers, sweep_port
from moments_ref.sweep.result import describe
from moments_ref.sweep.samplers import draw_rows

from _sweep_small import CASE, small_chunks  # noqa: F401 (an autouse fixture: chunks of 40 rows)
from _sweep_small import reference as _reference


def _moved(v):
    return np.where(v < 0.5, v + 0.5, v - 0.5).astype(np.float32)


def port_at(positions, nan=False, sizes=None):
    """The reference, wrong at ``positions`` of each call (negative: from the end) whose length is in ``sizes``."""

    def port(b, zf):
        out = _reference(b, zf)
        if sizes is None or len(zf) in sizes:
            idx = [p % len(zf) for p in positions]
            out[idx] = np.nan if nan else _moved(out[idx])
        return out

    return port


def _strata(seed, chunk, rows, positions):
    s = draw_rows(golden.CASES[CASE], seed, chunk, rows)["stratum"]
    return np.bincount(s[[p % rows for p in positions]], minlength=len(STRATA))


def _spec(port, rows=100, seed=3, strict=True):
    return SweepSpec(CASE, Port(fn=port), (None,), seed=seed, rows=rows, strict=strict)


def test_the_chunks_are_full_but_the_last_which_is_truncated():
    spec = _spec(_reference)
    assert spec.chunks == 3 and [spec.chunk_rows(i) for i in range(3)] == [40, 40, 20]
    res = run_chunks(spec)
    assert [r["chunk"] for r in res] == [0, 1, 2] and [r["rows"] for r in res] == [40, 40, 20]
    assert [sum(r["strata"]["rows"]) for r in res] == [40, 40, 20]
    exact = _spec(_reference, rows=80)
    assert exact.chunks == 2 and [exact.chunk_rows(i) for i in range(2)] == [40, 40]


def test_rows_flagged_and_confirmed_are_counted_exactly_at_the_chunk_boundaries():
    """Wrong at the first and last row of every chunk: 2 per chunk, 6 in all, each flagged and confirmed."""
    positions = [0, -1]
    res = sweep_port(_spec(port_at(positions)), shrink_failures=False)
    d = res.drivers["None"]
    assert (d["flagged"], d["examined"], d["confirmed"], d["unconfirmed"]) == (6, 6, 6, 0)
    assert d["first_confirmed"] == 0
    want = sum(_strata(3, c, n, positions) for c, n in ((0, 40), (1, 40), (2, 20)))
    for s, k in zip(STRATA, want):
        assert d["per_stratum"][s] == {"flagged": k, "confirmed": k, "unconfirmed": 0, "printed": 0, "envelope": 0}
    assert sum(v["rows"] for v in res.strata.values()) == 100
    rows = [sum(r) for r in zip(*(np.bincount(draw_rows(golden.CASES[CASE], 3, c, n)["stratum"],
                                              minlength=len(STRATA)) for c, n in ((0, 40), (1, 40), (2, 20))))]
    assert [res.strata[s]["rows"] for s in STRATA] == rows
    assert res.confirmed == 6 and not res.passed


def test_the_first_confirmed_row_is_its_index_in_the_whole_sweep():
    """Wrong only in the last, partial chunk (calls of 20 rows), at its 7th row: the first confirmed row is 80 + 6."""
    res = sweep_port(_spec(port_at([6], sizes={20})), shrink_failures=False)
    d = res.drivers["None"]
    assert (d["flagged"], d["confirmed"], d["first_confirmed"]) == (1, 1, 86)
    per_chunk = run_chunks(_spec(port_at([6], sizes={20})))
    assert [r["drivers"]["None"]["first_confirmed"] for r in per_chunk] == [None, None, 86]
    assert [sum(r["drivers"]["None"]["confirmed"]) for r in per_chunk] == [0, 0, 1]


def test_a_nan_output_is_flagged_and_confirmed():
    res = sweep_port(_spec(port_at([3], nan=True)), shrink_failures=False)
    d = res.drivers["None"]
    assert (d["flagged"], d["confirmed"], d["unconfirmed"]) == (3, 3, 0)


def test_the_confirmation_cap_and_the_kept_rows(monkeypatch):
    """Wrong at 7 rows of each chunk, at most 5 confirmed per chunk (CONFIRM_CAP patched), 4 rows kept per chunk
    (KEEP); the flags beyond the cap stay flagged, neither confirmed nor unconfirmed."""
    monkeypatch.setattr(runner, "CONFIRM_CAP", 5)
    positions = [0, 2, 3, 4, 5, 6, 7]  # not row 1 of the last chunk: ill-conditioned, its neighbourhood spans 1/2
    chunks = run_chunks(_spec(port_at(positions)))
    for r in chunks:
        d = r["drivers"]["None"]
        assert (sum(d["flagged"]), d["examined"], sum(d["confirmed"]), sum(d["unconfirmed"])) == (7, 5, 5, 0)
        assert len(d["confirmed_rows"]) == runner.KEEP == 4 and d["unconfirmed_rows"] == []
        kept = [row["inputs"]["zf"] for row in d["confirmed_rows"]]
        zf = draw_rows(golden.CASES[CASE], 3, r["chunk"], r["rows"])["zf"].astype(np.float32)
        assert kept == zf[[0, 2, 3, 4]].tolist()  # the first four confirmed rows, in order
    res = sweep_port(_spec(port_at(positions)), shrink_failures=False)
    d = res.drivers["None"]
    assert (d["flagged"], d["examined"], d["confirmed"]) == (21, 15, 15)
    assert "6 flagged beyond the confirmation cap" in res.format()


def test_a_kept_row_carries_its_texel_got_and_band():
    res = sweep_port(_spec(port_at([5]), rows=40), shrink_failures=False)
    (f,) = res.failures
    params = draw_rows(golden.CASES[CASE], 3, 0, 40)
    keep = params["w"][5] > 0
    assert f["texel"]["depths"] == params["z"][5][keep].tolist()
    assert f["texel"]["weights"] == params["w"][5][keep].tolist()
    assert f["texel"]["zf"] == float(params["zf"][5]) and f["texel"]["format"] == int(params["fmt"][5])
    assert f["stratum"] == STRATA[params["stratum"][5]] and f["driver"] == "None"
    b = np.asarray(f["inputs"]["b"], np.float32)[None]
    right = float(_reference(b, np.float32([f["inputs"]["zf"]]))[0])
    assert f["got"]["intensity"] == float(_moved(np.float32([right]))[0])
    assert f["lo"]["intensity"] <= right <= f["hi"]["intensity"]
    assert f["hi"]["intensity"] - f["lo"]["intensity"] < 0.1
    assert "got" in describe(f) and f"zf = {f['texel']['zf']:.9g}" in describe(f)


def test_one_failure_per_stratum_and_driver_at_most_max_shrunk():
    from moments_ref.sweep.result import MAX_SHRUNK

    positions = list(range(40))
    res = sweep_port(_spec(port_at(positions), rows=80), shrink_failures=False)
    strata = [f["stratum"] for f in res.failures]
    assert len(strata) == len(set(strata)) == MAX_SHRUNK == 4
    firsts = []
    for c in (0, 1):
        for s in draw_rows(golden.CASES[CASE], 3, c, 40)["stratum"]:
            if STRATA[s] not in firsts:
                firsts.append(STRATA[s])
    assert strata == firsts[:4]  # the first confirmed row of each stratum, in the order the chunks found them


def test_robustness_rows_are_counted_ungated_and_failed_only_when_strict():
    """The 64-bit MSM chain (seed 7, one chunk of 40 rows): rows outside its contract (a texel whose float32
    neighbourhood leaves the moment space: golden.bands.contract_reach, the goldens' definition) are counted as
    ungated and never flagged by default; with ``strict`` every row is gated. A port wrong on every row."""
    from moments_ref.golden.bands import contract_reach

    name = "e2e-msm64-float32"
    case = golden.CASES[name]
    inputs, _ = samplers.draw_chunk(case, 7, 0, 40)
    outside = np.flatnonzero(~contract_reach(case, inputs))
    assert len(outside) >= 3

    def port(b, zf):
        return _moved(np.asarray(case.reference(b=b, zf=zf), np.float32).reshape(-1))

    spec = lambda strict: SweepSpec(name, Port(fn=port), (None,), seed=7, rows=40, strict=strict)  # noqa: E731
    lax, strict = (sweep_port(spec(x), shrink_failures=False) for x in (False, True))
    assert sum(v["ungated"] for v in lax.strata.values()) == len(outside)
    assert sum(v["ungated"] for v in strict.strata.values()) == 0
    assert lax.drivers["None"]["flagged"] == 40 - len(outside) and strict.drivers["None"]["flagged"] == 40
    assert strict.drivers["None"]["confirmed"] == 40


def test_a_seed_reproduces_its_sweep_and_another_seed_draws_other_rows():
    a = sweep_port(_spec(port_at([0, 9]), seed=11), shrink_failures=False).record()
    b = sweep_port(_spec(port_at([0, 9]), seed=11), shrink_failures=False).record()
    c = sweep_port(_spec(port_at([0, 9]), seed=12), shrink_failures=False).record()
    strip = lambda r: {k: v for k, v in r.items() if k not in ("seconds", "rows_per_s", "wall_s")}  # noqa: E731
    assert strip(a) == strip(b)
    assert [f["inputs"] for f in a["failures"]] != [f["inputs"] for f in c["failures"]]


def test_the_record_is_json_and_reads_back_equal():
    res = sweep_port(_spec(port_at([0, -1])), shrink_failures=False)
    rec = res.record()
    back = json.loads(json.dumps(rec, default=float))
    assert back == json.loads(json.dumps(rec, default=float, sort_keys=True))
    assert back["passed"] is False and back["rows"] == 100 and back["seed"] == 3 and back["case"] == CASE
    assert back["drivers"]["None"]["confirmed"] == 6
    for stage, seconds in rec["seconds"].items():
        assert back["rows_per_s"][stage] == (100 / seconds if seconds > 0 else None)
    assert set(rec["seconds"]) == set(runner.STAGES)
    assert back["failures"][0]["got"] == rec["failures"][0]["got"]


def test_a_passing_sweep_passes():
    res = sweep_port(_spec(_reference), shrink_failures=False)
    assert res.passed and res.confirmed == 0 and res.failures == []
    assert res.drivers["None"]["first_confirmed"] is None


@pytest.mark.parametrize("path, mid", [
    ("moments_ref/sweep/runner.py", "run_chunk::int(confirmed[0]) + chunk * CHUNK -> int(confirmed[0]) - chunk * CHUNK#0"),
    ("moments_ref/sweep/result.py", "_merge::m['first_confirmed'] is None -> m['first_confirmed'] is not None#0"),
    ("moments_ref/sweep/runner.py", "SweepSpec.chunk_rows::self.rows - i * CHUNK -> self.rows + i * CHUNK#0")])
def test_kept_mutant_the_first_confirmed_row_or_the_partial_chunk_moved(path, mid):
    """The first confirmed row's global index (80 + 6, in the partial chunk only) is lost when the chunk's offset is
    subtracted, when the merge keeps the first chunk's None, or when the last chunk is not truncated."""
    from _mutants import kept_mutant

    with kept_mutant(path, mid):
        try:
            d = sweep_port(_spec(port_at([6], sizes={20})), shrink_failures=False).drivers["None"]
        except Exception:  # noqa: BLE001 - a mutant may also break the run: seen all the same
            return
    assert (d["confirmed"], d["first_confirmed"]) != (1, 86)


def test_kept_mutant_one_more_row_confirmed_than_the_cap(monkeypatch):
    from _mutants import kept_mutant

    monkeypatch.setattr(runner, "CONFIRM_CAP", 5)
    with kept_mutant("moments_ref/sweep/runner.py", "run_chunk:::CONFIRM_CAP -> :CONFIRM_CAP + 1#0"):
        (r, *_) = run_chunks(_spec(port_at([0, 2, 3, 4, 5, 6, 7])))
    assert r["drivers"]["None"]["examined"] == 6
