"""The report on worker processes (``--jobs``): the same results as the serial run, errors as in it.

Two small scenes at tiny settings are run with ``jobs=1`` (everything in this
process, one after the other) and ``jobs=2`` (two spawned workers); every
column of results.csv but the timings, stages.json but its seconds, claims.json
and the error images must be identical, byte for byte where they are files. A
slow variant adds an area-light scene (the msm_soft artifacts as their own task).
"""

import csv
import json
import os
import time

import pytest

from moments_ref import InputError, report
from moments_ref._arrays import set_max_memory
from moments_ref.report import _jobs

TINY = dict(progress=False, shadow_map_size=48, resolution=(48, 27), noise_tiles=1, repeats=1)
TIMING = {"texel_seconds", "texel_seconds_min", "texel_seconds_max", "fragment_seconds", "fragment_seconds_min",
          "fragment_seconds_max", "own_total_seconds", "own_total_seconds_min", "own_total_seconds_max",
          "pareto"}  # pareto: the front over the costs, so it follows the timings


def _outputs(out):
    """What must not depend on ``jobs``: results.csv without timings, stages without seconds, claims, images."""
    with open(out / "results.csv", newline="") as f:
        rows = [{k: v for k, v in r.items() if k not in TIMING} for r in csv.DictReader(f)]
    stages = {s: [(x["stage"], x["used_by"]) for x in v] for s, v in json.loads((out / "stages.json").read_text()).items()}
    images = {p.name: p.read_bytes() for p in sorted(out.glob("*.png")) if not p.name.startswith("front_")}
    with open(out / "winners.csv", newline="") as f:  # the memory budgets do not depend on timings
        memory = [w for w in csv.DictReader(f) if w["budget_kind"] == "bits_per_texel"]
    return rows, stages, json.loads((out / "claims.json").read_text()), images, memory


def _same(a, b):
    rows_a, stages_a, claims_a, images_a, memory_a = a
    rows_b, stages_b, claims_b, images_b, memory_b = b
    assert rows_a == rows_b and memory_a == memory_b
    assert stages_a == stages_b
    assert claims_a == claims_b  # no claim is measured on the timings
    assert images_a.keys() == images_b.keys() and images_a
    for name in images_a:
        assert images_a[name] == images_b[name], name


def _run_both(tmp_path, scenes, **kw):
    res = {}
    for jobs in (1, 2):
        out = tmp_path / f"jobs{jobs}"
        res[jobs] = report.run(scenes=scenes, out_dir=out, jobs=jobs, **TINY, **kw)
    return res, _outputs(tmp_path / "jobs1"), _outputs(tmp_path / "jobs2")


def test_two_jobs_give_the_serial_results(tmp_path):
    res, serial, parallel = _run_both(tmp_path, ["translucent", "facade"])
    _same(serial, parallel)
    assert len(serial[0]) == 4  # translucent_msm; msm128, nlq64, nlq32
    # the rows come back in scene order, whatever order the workers finished in
    assert [r["scene"] for r in res[2]["rows"]] == ["translucent"] + ["facade"] * 3
    assert list(res[1]["paths"]) == list(res[2]["paths"])
    md = (tmp_path / "jobs2" / "report.md").read_text()
    assert "2 worker processes side by side" in md and "CPU seconds" in md
    assert "one scene at a time" in (tmp_path / "jobs1" / "report.md").read_text()
    # the second batch (the Pareto-front plots, one task per reference) runs on the workers
    assert ("front", "pcf") in res[2]["tasks"] and res[2]["tasks"][("front", "pcf")]["pid"] != os.getpid()
    assert res[2]["tasks"][report.CLAIM_CROPS]["pid"] != os.getpid()  # and the claims' crops
    png = (tmp_path / "jobs2" / "front_pcf.png").read_bytes()
    assert png.startswith(b"\x89PNG") and "front_pcf.png" in md


@pytest.mark.slow
def test_two_jobs_give_the_serial_results_with_an_area_light(tmp_path):
    area = {"map_size": 32, "light_samples": 4, "reference_views": 8}
    res, serial, parallel = _run_both(tmp_path, ["knot", "translucent"], area=area,
                                      techniques=["msm_soft", "pcss", "translucent_msm"])
    _same(serial, parallel)
    assert res[1]["artifacts"] is not None and (tmp_path / "jobs2" / "msm_soft_artifacts.png").read_bytes() == \
        (tmp_path / "jobs1" / "msm_soft_artifacts.png").read_bytes()


def test_a_worker_error_is_the_serial_error_and_nothing_is_written(tmp_path):
    # The shadow map's memory check runs in the worker: the limit must reach it, and its
    # InputError must come back as itself, before any file is written.
    old = set_max_memory(2 ** 30)
    try:
        messages = []
        for jobs in (1, 2):
            out = tmp_path / f"jobs{jobs}"
            with pytest.raises(InputError) as e:
                report.run(scenes=["translucent", "facade"], out_dir=out, jobs=jobs,
                           **{**TINY, "shadow_map_size": 8192, "msaa": 8})
            messages.append(str(e.value))
            assert not out.exists() or not any(out.iterdir())
    finally:
        set_max_memory(old)
    assert messages[0] == messages[1] and "memory limit" in messages[0] and "\n" not in messages[0]


def _fail(x):
    raise InputError(f"x: expected something else, got {x}")


def _sleep(x):
    time.sleep(x)
    return os.getpid()


def _run(tasks, jobs):
    with _jobs.Workers(jobs) as workers:
        return workers.run(tasks)


def test_workers_keep_the_order_and_stop_the_others_on_error():
    tasks = [(("a",), _sleep, (0.5,)), (("b",), _sleep, (0.0,)), (("c",), _sleep, (0.0,))]
    done = _run(tasks, jobs=2)
    assert list(done) == [("a",), ("b",), ("c",)]
    assert os.getpid() not in done.values()  # they ran in workers
    assert set(_run(tasks[1:], jobs=1).values()) == {os.getpid()}  # jobs 1: here
    t0 = time.perf_counter()
    with pytest.raises(InputError, match="^x: expected something else, got 1$"):
        _run([(("long",), _sleep, (60,)), (("bad",), _fail, (1,))], jobs=2)
    assert time.perf_counter() - t0 < 30  # the long task was stopped, not waited for


def test_workers_keep_their_processes_for_a_second_batch():
    with _jobs.Workers(2) as workers:
        first = workers.run([(("a",), _sleep, (0.3,)), (("b",), _sleep, (0.3,))])
        second = workers.run([(("c",), _sleep, (0.0,)), (("d",), _sleep, (0.0,)), (("e",), _sleep, (0.0,))])
    assert len(set(first.values())) == 2 and os.getpid() not in first.values()
    assert set(second.values()) <= set(first.values())  # the same two workers, no new start-up
    with _jobs.Workers(1) as workers:
        assert set(workers.run([(("a",), _sleep, (0.0,))] * 2).values()) == {os.getpid()}


@pytest.mark.parametrize("error", [False, True])
def test_leaving_the_workers_leaves_no_pool_thread(error):
    # A pool thread still running at exit races CPython 3.11's exit hook, which then prints
    # a traceback after the one-line refusal (a camera probe of test_cli_probes.py, 1 run in 20).
    import threading

    before = set(threading.enumerate())
    try:
        with _jobs.Workers(2) as workers:
            workers.start(4, "moments_ref.report")  # started early, still importing
            if error:
                raise InputError("camera: shades no pixel")
    except InputError:
        assert error
    assert [t.name for t in threading.enumerate() if t not in before and t.is_alive()] == []


def test_jobs_on_the_command_line(tmp_path, capsys):
    assert report.main(["--scene", "translucent", "--jobs", "0", "--out", str(tmp_path)]) == 2
    assert "--jobs" in capsys.readouterr().err
    assert report.build_parser().parse_args(["--out", "x"]).jobs is None  # default: the usable cores
    assert _jobs.usable_cores() == len(os.sched_getaffinity(0))


@pytest.mark.parametrize("full", [False, True])
def test_tasks_are_ordered_longest_first_by_their_measured_costs(full, monkeypatch):
    """The shipped scenes' tasks in the order of their measured CPU costs (report._tasks' docstring):
    knot (MVR reference), railing (8 techniques), chair, the temporal claim, then the small ones."""
    from moments_ref.report import _Collected, _scene_plan, _tasks
    from moments_ref.scene import list_scenes, load_scene

    # the check that a camera shades a receiver (the camera probes of test_cli_probes.py) renders
    # a 1920×1080 G-buffer per scene at full settings: 7 CPU seconds that say nothing of the order
    monkeypatch.setattr(report, "check_shaded", lambda *args: None)

    acc = _Collected(full=full, repeats=3)
    given = {"shadow_map_size": None, "msaa": None, "resolution": None}
    plans = []
    for name in list_scenes():
        sc = load_scene(name)
        names, st, _ = _scene_plan(acc, sc, full, given, None, {}, 64)
        plans.append((sc, (names, st)))
    keys = [key[-1] for key, _, _ in _tasks(plans, full, jobs=2, progress=False)]
    assert keys[:4] == ["knot", "railing", "chair", "temporal"]
    assert keys.index("artifacts") < keys.index("translucent") == len(keys) - 1
    serial = [key[-1] for key, _, _ in _tasks(plans, full, jobs=1, progress=False)]
    assert serial[:len(plans)] == [sc.name for sc, _ in plans]  # one job: the scenes in the order given


def _openmp_threads(_):
    return os.environ.get("OMP_NUM_THREADS")


@pytest.mark.parametrize("preset", [None, "3"])
def test_workers_get_their_share_of_the_cores_for_openmp(preset, monkeypatch):
    # Two workers on the usable cores: each its share for OpenMP code loaded later (ꟻLIP's
    # libgomp reads it then), unless the user set OMP_NUM_THREADS; the parent is left alone.
    if preset is None:
        monkeypatch.delenv("OMP_NUM_THREADS", raising=False)
    else:
        monkeypatch.setenv("OMP_NUM_THREADS", preset)
    done = _run([(("a",), _openmp_threads, (0,)), (("b",), _openmp_threads, (0,))], jobs=2)
    want = preset or str(max(1, _jobs.usable_cores() // 2))
    assert list(done.values()) == [want, want]
    assert os.environ.get("OMP_NUM_THREADS") == preset


_ORPHAN = """
import os, sys, time
from moments_ref.report import _jobs

def pid_then_sleep(path):
    with open(path, "a") as f:
        f.write(f"{os.getpid()}\\n")
    time.sleep(60)

if __name__ == "__main__":
    with _jobs.Workers(2) as workers:
        workers.start(2, "moments_ref.report")
        workers.run([(("a",), pid_then_sleep, (sys.argv[1],)), (("b",), pid_then_sleep, (sys.argv[1],))])
"""


def _running(pid):
    """Whether ``pid`` is a process that is not a zombie (Linux: /proc/PID/stat)."""
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[0] != "Z"
    except FileNotFoundError:
        return False


@pytest.mark.skipif(not os.path.isdir("/proc/self"), reason="reads /proc")
def test_workers_end_when_the_parent_is_killed(tmp_path):
    # A parent killed by SIGKILL runs no clean-up: the workers must notice on their own
    # (the kernel's parent-death signal, the watching thread) and end.
    import signal
    import subprocess
    import sys

    script, pids = tmp_path / "orphan.py", tmp_path / "pids"
    script.write_text(_ORPHAN)
    p = subprocess.Popen([sys.executable, str(script), str(pids)], cwd=tmp_path)
    try:
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline and (not pids.exists() or len(pids.read_text().split()) < 2):
            time.sleep(0.1)
        workers = [int(x) for x in pids.read_text().split()]
        assert len(workers) == 2 and p.pid not in workers and all(map(_running, workers))
    finally:
        p.send_signal(signal.SIGKILL)
        p.wait()
    deadline = time.monotonic() + 10
    while time.monotonic() < deadline and any(map(_running, workers)):
        time.sleep(0.1)
    assert not any(map(_running, workers))


def _environment(name):
    return os.environ.get(name)


def test_workers_see_the_parents_environment_when_the_pool_is_made(monkeypatch):
    # The workers of each pool see the parent's environment of when the pool was made
    # (a start method that forked from an earlier state would not).
    monkeypatch.setenv("MOMENTS_REF_TEST_VARIABLE", "before")
    _run([(("a",), _sleep, (0.0,)), (("b",), _sleep, (0.0,))], jobs=2)
    monkeypatch.setenv("MOMENTS_REF_TEST_VARIABLE", "after")
    monkeypatch.setenv("MOMENTS_REF_TEST_OTHER", "set")
    tasks = [(("a",), _environment, ("MOMENTS_REF_TEST_VARIABLE",)),
             (("b",), _environment, ("MOMENTS_REF_TEST_OTHER",))]
    assert list(_run(tasks, jobs=2).values()) == ["after", "set"]
    monkeypatch.delenv("MOMENTS_REF_TEST_OTHER")
    assert list(_run(tasks, jobs=2).values()) == ["after", None]


def _gc_young(_):
    import gc

    return gc.get_threshold()[0]


def test_workers_collect_garbage_less_often_and_the_parent_is_left_alone():
    import gc

    before = gc.get_threshold()
    done = _run([(("a",), _gc_young, (0,)), (("b",), _gc_young, (0,))], jobs=2)
    assert list(done.values()) == [_jobs.GC_YOUNG] * 2 and _jobs.GC_YOUNG > 700  # Python's default
    assert gc.get_threshold() == before


def test_the_checked_camera_gbuffer_is_handed_to_the_scene_run_with_the_same_outputs(tmp_path, monkeypatch):
    """The report's check renders each scene's camera G-buffer; the scene's run takes it (Settings.camera_gbuffer)
    instead of rendering it again, and writes what a run that renders it writes."""
    from moments_ref.pipeline import planner
    from moments_ref.scene.gbuffer import check_shaded

    handed = []

    def check(*args):
        g = check_shaded(*args)
        handed.append(g)
        return g

    monkeypatch.setattr(report, "check_shaded", check)
    rendered = []
    render = planner.camera_gbuffer
    monkeypatch.setattr(planner, "camera_gbuffer", lambda *a, **k: rendered.append(1) or render(*a, **k))
    report.run(scenes=["facade", "translucent"], out_dir=tmp_path / "given", jobs=1, **TINY)
    assert len(handed) == 2 and all(g is not None for g in handed) and rendered == []
    monkeypatch.setattr(report, "check_shaded", lambda *args: check_shaded(*args) and None)  # checked, not handed
    report.run(scenes=["facade", "translucent"], out_dir=tmp_path / "rendered", jobs=1, **TINY)
    assert len(rendered) == 2
    _same(_outputs(tmp_path / "given"), _outputs(tmp_path / "rendered"))
