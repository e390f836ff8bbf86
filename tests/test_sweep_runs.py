"""Where the sweep's chunks run (sweep/runner.py): in this process, in spawned workers, on Dask; the checkpoint.

docs/sweep.md ("Determinism and resumption"): the rows of chunk i depend only on (seed, case, profile, i) and
results are merged in chunk order, so one process, spawned workers or a Dask cluster give the same counts and
failures; ``workers=1`` (or one chunk) runs in this process. (Wrong values are moved by 1/2, not NaN: a
NaN in a kept row would never compare equal to itself.) A checkpoint of the same sweep is resumed (its
chunks are not run again), one of another sweep is ignored and replaced, and a file that is not a checkpoint
is refused before any work and left as it is. The port here records each call it gets in this process.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from moments_ref import msm
from moments_ref._arrays import InputError
from moments_ref.sweep import CHUNK, Port, SweepSpec, run_chunks, runner, samplers
from moments_ref.sweep.runner import checkpoint_key, run_chunk

CASE = "shadow_intensity-lower-float32"
CALLS = []


def recording(b, zf):
    """Algorithm 1, wrong (moved by 1/2) at the first row of each call; records the call's length in this process."""
    CALLS.append(len(zf))
    return _wrong_first(b, zf)


def _wrong_first(b, zf):
    out = msm.shadow_intensity(np.asarray(b, np.float32), np.asarray(zf, np.float32), bound="lower")
    out[0] += np.float32(0.5) if out[0] < 0.5 else np.float32(-0.5)
    return out


def _strip(results):
    return [{k: v for k, v in r.items() if k != "seconds"} for r in results]


@pytest.fixture
def small(monkeypatch):
    monkeypatch.setattr(samplers, "CHUNK", 40)
    monkeypatch.setattr(runner, "CHUNK", 40)
    CALLS.clear()
    return SweepSpec(CASE, Port(fn=recording), (None,), seed=5, rows=100)


def test_one_worker_runs_every_chunk_in_this_process_in_order(small):
    seen = []
    res = run_chunks(small, workers=1, progress=lambda r: seen.append(r["chunk"]))
    assert CALLS == [40, 40, 20] and seen == [0, 1, 2] and [r["chunk"] for r in res] == [0, 1, 2]
    assert [r["drivers"]["None"]["first_confirmed"] for r in res] == [0, 40, 80]


def test_one_chunk_left_runs_in_this_process_even_with_two_workers(small, tmp_path):
    ck = tmp_path / "checkpoint.json"
    ck.write_text(json.dumps({"key": checkpoint_key(small), "chunks": {"0": run_chunk(small, 0),
                                                                          "2": run_chunk(small, 2)}}))
    CALLS.clear()
    seen = []
    res = run_chunks(small, workers=2, checkpoint=ck, progress=lambda r: seen.append(r["chunk"]))
    assert CALLS == [40]  # chunk 1 only, here
    assert sorted(seen) == [0, 1, 2] and [r["chunk"] for r in res] == [0, 1, 2]
    saved = json.loads(ck.read_text())
    assert saved["key"] == checkpoint_key(small) and sorted(saved["chunks"]) == ["0", "1", "2"]
    CALLS.clear()
    again = run_chunks(small, workers=1, checkpoint=ck)
    assert CALLS == [] and _strip(again) == _strip(res)


def test_a_checkpoint_of_another_sweep_is_ignored_and_replaced(small, tmp_path):
    ck = tmp_path / "checkpoint.json"
    other = SweepSpec(CASE, small.port, (None,), seed=6, rows=100)
    bogus = dict(run_chunk(small, 0), rows=-1)
    ck.write_text(json.dumps({"key": checkpoint_key(other), "chunks": {"0": bogus}}))
    CALLS.clear()
    res = run_chunks(small, checkpoint=ck)
    assert CALLS == [40, 40, 20] and res[0]["rows"] == 40
    assert json.loads(ck.read_text())["key"] == checkpoint_key(small)


@pytest.mark.parametrize("text", ["{not json", "[1, 2]", '{"chunks": {}}', '{"key": "k"}',
                                  '{"key": "k", "chunks": {"first": {}}}', '{"key": "k", "chunks": {"0": {}, "x": {}}}',
                                  '{"key": "k", "chunks": []}'])
def test_a_file_that_is_not_a_checkpoint_is_refused_and_kept(small, tmp_path, text):
    ck = tmp_path / "checkpoint.json"
    ck.write_text(text)
    CALLS.clear()
    with pytest.raises(InputError, match="is not a sweep checkpoint"):
        run_chunks(small, checkpoint=ck)
    assert CALLS == [] and ck.read_text() == text


def test_the_checkpoint_key_names_what_a_resumed_sweep_must_share(small, tmp_path):
    base = checkpoint_key(small)
    variants = [SweepSpec(CASE, small.port, (None,), seed=6, rows=100),
                SweepSpec(CASE, small.port, (None,), seed=5, rows=101),
                SweepSpec(CASE, small.port, ("gl",), seed=5, rows=100),
                SweepSpec(CASE, small.port, (None,), seed=5, rows=100, strict=True),
                SweepSpec("shadow_intensity-upper-float32", small.port, (None,), seed=5, rows=100)]
    keys = [checkpoint_key(v) for v in variants]
    assert base not in keys and len(set(keys)) == len(keys)
    shader = tmp_path / "p.glsl"
    shader.write_text("a")
    port = Port(str(shader), "f", "glsl")
    k1 = checkpoint_key(SweepSpec(CASE, port, ("gl",)))
    shader.write_text("b")  # the same path, another source: another key
    assert checkpoint_key(SweepSpec(CASE, port, ("gl",))) != k1


def test_dask_gives_the_local_result_from_a_client_or_an_address(small):
    distributed = pytest.importorskip("dask.distributed")
    local = run_chunks(small)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=False,
                                  dashboard_address=None) as cluster, distributed.Client(cluster) as client:
        by_client = run_chunks(small, scheduler=client)
        seen = []
        by_address = run_chunks(small, scheduler=cluster.scheduler_address, progress=lambda r: seen.append(r["chunk"]))
        assert client.status == "running"  # a client handed in is the caller's: left open
    assert _strip(by_client) == _strip(local) == _strip(by_address) and seen == [0, 1, 2]


def spawned_port(b, zf):
    """Algorithm 1, wrong at the first row of each call (module level: spawned workers import it)."""
    CALLS.append(len(zf))
    return _wrong_first(b, zf)


def test_spawned_workers_give_the_in_process_result():
    """Two spawned workers (each its own process, the package's chunk size) on two chunks, the second of 3 rows."""
    spec = SweepSpec(CASE, Port(fn=spawned_port), (None,), seed=5, rows=CHUNK + 3)
    CALLS.clear()
    pooled = run_chunks(spec, workers=2)
    assert CALLS == []  # not called in this process
    here = run_chunks(spec, workers=1)
    assert CALLS == [CHUNK, 3]
    assert _strip(pooled) == _strip(here)
    assert pooled[1]["rows"] == 3 and pooled[1]["drivers"]["None"]["first_confirmed"] == CHUNK


def test_kept_mutant_the_layout_check_skipped_lets_a_bad_checkpoint_through(small, tmp_path):
    """Without the layout check, a checkpoint with a chunk named "first" is no refusal (exit 2, one line) but a
    ValueError deep in the resumption (a harness failure)."""
    from _mutants import kept_mutant

    ck = tmp_path / "checkpoint.json"
    ck.write_text(json.dumps({"key": checkpoint_key(small), "chunks": {"first": {}}}))
    mid = ("_read_checkpoint::not (isinstance(saved, dict) and 'key' in saved and isinstance(saved.get('chunks'), "
           "dict) and all((str(k).isdigit() for k in saved['chunks']))) -> False#0")
    with kept_mutant("moments_ref/sweep/runner.py", mid), pytest.raises(ValueError) as err:
        run_chunks(small, checkpoint=ck)
    assert not isinstance(err.value, InputError)
