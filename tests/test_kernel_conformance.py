"""Compute shaders on the kernel cases, on both drivers: the shipped kernels pass, the mutants fail.

Needs moderngl with EGL (llvmpipe), wgpu with a Vulkan driver (lavapipe), glslangValidator,
spirv-cross and spirv-tools. Without them the tests are skipped with the reason, except under
CI (``CI=true``), where a missing driver or tool is a failure.
"""

from __future__ import annotations

import importlib
import io
import math
import re
import time
import types
from pathlib import Path

import numpy as np
import pytest

from moments_ref import InputError, cli
from moments_ref.conformance._cases import load_case
from moments_ref.conformance._source import ShaderError, load_source
from moments_ref.conformance._supervisor import DriverTimeout
from moments_ref.conformance.kernel import BindingError, numpy_times, run_kernel, trace
from moments_ref.conformance.kernel._job import POISON
from moments_ref.conformance.kernel._result import Result
from moments_ref.conformance.kernel.cli import SHIPPED_KERNELS, shipped_kernel
from moments_ref.golden.kernels import KERNEL_CASES
from moments_ref.gpu import banks
from moments_ref.ports import PORTS_DIR

from _harness import need_tool, one_change
from _oracles import golden_folder

FIXTURES = Path(__file__).parent / "fixtures" / "kernels"
LANGUAGES = ("glsl", "hlsl", "wgsl")


@pytest.fixture(scope="module")
def drivers(drivers):
    """conftest's drivers and compilers, and spirv-tools (the kernels' SPIR-V for naga), or skip (fail under CI)."""
    for tool in ("spirv-dis", "spirv-as"):
        need_tool(tool)


@pytest.fixture(scope="module")
def kernel_goldens():
    """The kernel cases' golden folder, written once per test run (the other tests here generate theirs)."""
    return golden_folder(tuple(KERNEL_CASES))


def _ran(report):
    return [r for r in report.runs if not r.skipped]


# --------------------------------------------------------------------------
# The shipped kernels pass every kernel case


@pytest.mark.parametrize("case", KERNEL_CASES)
@pytest.mark.parametrize("language", LANGUAGES)
def test_shipped_kernel_passes(drivers, kernel_goldens, case, language):
    path, entry = shipped_kernel(case, language)
    rep = run_kernel(path, entry, case, language, golden_dir=kernel_goldens, timing=False, shared=False)
    assert rep.passed, rep.format()
    ran = {r.driver for r in _ran(rep)}
    # WGSL with a multisampled input runs on Vulkan only (wgpu's OpenGL back end; docs/ports.md)
    expect = {"vulkan"} if language == "wgsl" and case.startswith("kernel-filter") else {"gl", "vulkan"}
    assert ran == expect, rep.format()
    for r in _ran(rep):
        assert r.unwritten == 0 and r.outside == 0 and r.verdict.passed


@pytest.mark.parametrize("language", LANGUAGES)
def test_trace_of_the_shipped_filter_is_the_bank_simulators_pattern(drivers, language):
    """The simulator's '0 conflicts' refers to the shipped code: its trace is gpu.banks' access pattern."""
    path, entry = shipped_kernel("kernel-filter-moments", language)
    rep = run_kernel(path, entry, "kernel-filter-moments", language, adapter="vulkan", timing=False)
    s = rep.shared
    assert s["pattern"] and s["accesses"] == 104 and s["barriers"] == 4, s
    assert s["conflicts"] == {p: 0 for p in banks.PHASES} and not s["races"], s
    assert banks.simulate("paper") == s["conflicts"]
    assert sum(banks.simulate("row-major").values()) > 0  # the counter can see conflicts


def test_expected_trace_counts_conflicts_like_the_simulator():
    addr, _, names = trace.expected()
    assert addr.shape == (banks.N_WARPS, 104, banks.WARP_SIZE)
    for layout in banks.LAYOUTS:
        pattern = banks.access_pattern()
        a = np.concatenate([np.moveaxis(banks.shared_index(pattern[p].j, pattern[p].x, pattern[p].y, layout),
                                        2 if p in ("resolve", "readout") else 0, 0)
                            .reshape(banks.N_WARPS, -1, banks.WARP_SIZE) for p in banks.PHASES], axis=1)
        got = {p: int(banks.conflicts(a[:, names == p]).sum()) for p in banks.PHASES}
        assert got == banks.simulate(layout)


# --------------------------------------------------------------------------
# Mutants: one change each to a shipped kernel; every one must fail on at least one driver

MUTANTS = [
    # name, case, language, file, old, new
    ("missing barrier (horizontal -> vertical)", "kernel-filter-nlq64", "glsl", "hpg17_filter.glsl",
     "hpg17_horizontal(warp, lane);\n    memoryBarrierShared();\n    barrier();", "hpg17_horizontal(warp, lane);"),
    ("missing barrier (horizontal -> vertical)", "kernel-filter-moments", "hlsl", "hpg17_filter.hlsl",
     "hpg17_horizontal(warp, lane);\n    GroupMemoryBarrierWithGroupSync();", "hpg17_horizontal(warp, lane);"),
    ("guard band 3", "kernel-filter-nlq32", "hlsl", "hpg17_filter.hlsl",
     "static const int HPG17_GUARD = 4;", "static const int HPG17_GUARD = 3;"),
    ("block origin off by one", "kernel-filter-msm64", "glsl", "hpg17_filter.glsl",
     "hpg17_resolve(out_origin - HPG17_GUARD, warp, lane);",
     "hpg17_resolve(out_origin - HPG17_GUARD + ivec2(1, 0), warp, lane);"),
    ("Gaussian weights not normalized", "kernel-filter-moments", "hlsl", "hpg17_filter.hlsl",
     "{ 0.044044435, 0.08086959, 0.12481912, 0.16194914, 0.17663543,\n"
     "                                        0.16194914, 0.12481912, 0.08086959, 0.044044435 }",
     "{ 0.24935221, 0.45783336, 0.70664828, 0.91685536, 1.0,\n"
     "                                        0.91685536, 0.70664828, 0.45783336, 0.24935221 }"),
    ("resolve ignoring a sample", "kernel-filter-nlq64", "glsl", "hpg17_filter.glsl",
     "for (int s = 0; s < int(params.size.z); ++s) {", "for (int s = 0; s < int(params.size.z) - 1; ++s) {"),
    ("InterlockedMax on float bits without the sign transform", "kernel-vwss-points", "wgsl", "vwss_points.wgsl",
     "return select(u | 0x80000000u, ~u, (u >> 31u) != 0u);", "return u | 0x80000000u;"),
    ("InterlockedMax on float bits without the sign transform", "kernel-vwss-points", "hlsl", "vwss_points.hlsl",
     "return (u >> 31) != 0 ? ~u : (u | 0x80000000u);", "return u;"),
    ("a view index swapped", "kernel-vwss-points", "hlsl", "vwss_points.hlsl",
     "InterlockedMax(depth[(uint(v) * h", "InterlockedMax(depth[((uint(v) ^ 1) * h"),
]


def mutant_file(tmp_path, language, fname, old, new, case):
    """The shipped kernel of ``case`` with one change in ``fname``, in a folder with its includes."""
    one_change(tmp_path, PORTS_DIR / language, fname, old, new)
    path, entry = shipped_kernel(case, language)
    return tmp_path / path.name, entry


@pytest.mark.parametrize("name,case,language,fname,old,new", MUTANTS, ids=[f"{m[0]} ({m[2]})" for m in MUTANTS])
def test_kernel_mutant_fails(drivers, kernel_goldens, tmp_path, name, case, language, fname, old, new):
    path, entry = mutant_file(tmp_path, language, fname, old, new, case)
    rep = run_kernel(path, entry, case, language, golden_dir=kernel_goldens, timing=False, shared="barrier" in name)
    assert not rep.passed, rep.format()
    failed = [r.driver for r in _ran(rep) if not r.passed]
    assert failed, rep.format()
    if "barrier" in name:  # the trace finds the race whatever order the driver ran the invocations in
        assert rep.shared["races"], rep.format()
        assert "FAIL race" in rep.format()


# --------------------------------------------------------------------------
# Bad kernels: a clear reason, exit 2 for what breaks the contract, nothing hangs


def _cli(args):
    out, err = io.StringIO(), io.StringIO()
    import contextlib

    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = cli.main(["conformance", "--kernel", *args])
    return code, out.getvalue(), err.getvalue()


def test_a_binding_outside_the_contract_is_exit_2_naming_it(drivers):
    code, out, err = _cli(["--glsl", str(FIXTURES / "extra_binding.glsl"), "--entry", "main",
                           "--case", "kernel-filter-moments"])
    assert code == 2 and "'lut'" in err and "binding 5" in err and "matches no binding" in err, err
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1


def test_a_work_group_of_128_is_exit_2_stating_the_expectation(drivers):
    code, _, err = _cli(["--hlsl", str(FIXTURES / "workgroup_128.hlsl"), "--entry", "filter_moments",
                         "--case", "kernel-filter-moments"])
    assert code == 2 and "128×1×1" in err and "256 threads per work group" in err and "32×24" in err, err


def test_a_uniform_block_off_the_documented_layout_is_exit_2(drivers):
    code, _, err = _cli(["--wgsl", str(FIXTURES / "wrong_params.wgsl"), "--entry", "CS",
                         "--case", "kernel-vwss-points", "--adapter", "vulkan"])
    assert code == 2 and "'params'" in err and "member 'size'" in err and "uvec4 size" in err, err


def test_a_buffer_of_the_wrong_element_is_exit_2(drivers):
    code, _, err = _cli(["--glsl", str(FIXTURES / "points_as_floats.glsl"), "--entry", "main",
                         "--case", "kernel-vwss-points"])
    assert code == 2 and "'Points'" in err and "4 bytes" in err and "16-byte" in err, err


def test_a_compile_error_is_exit_2_with_file_and_line(drivers):
    code, _, err = _cli(["--glsl", str(FIXTURES / "syntax_error.glsl"), "--entry", "main",
                         "--case", "kernel-filter-moments"])
    assert code == 2 and "syntax_error.glsl:" in err and "does not compile" in err, err


@pytest.mark.parametrize("args,text", [
    (["--glsl", "hpg17_filter_nlq64.glsl", "--entry", "filter", "--case", "kernel-filter-nlq64"], "main()"),
    (["--wgsl", "vwss_points.wgsl", "--entry", "main", "--case", "kernel-vwss-points"], "compute entry points: CS"),
    (["--glsl", "vwss_points.glsl", "--entry", "main", "--case", "shade-float32"], "not a kernel case"),
    (["--glsl", "vwss_points.glsl", "--case", "kernel-vwss-points"], "--entry"),
    (["--glsl", "vwss_points.glsl", "--entry", "main", "--case", "kernel-vwss-points", "--time-limit", "0"],
     "time_limit"),
])
def test_bad_usage_is_exit_2(drivers, args, text):
    code, _, err = _cli(args)
    assert code == 2 and text in err and "Traceback" not in err, err


def test_a_kernel_past_its_time_limit_is_stopped_by_the_watchdog(drivers):
    # From the second row of blocks on (the first row is the warm-up dispatch) each dispatch takes seconds.
    rep = run_kernel(FIXTURES / "slow_loop.glsl", "main", "kernel-filter-moments", "glsl", time_limit=1, timing=False,
                     shared=False)
    assert not rep.passed
    for r in rep.runs:
        assert not r.passed and "watchdog" in r.reason and "did not finish within 1 s" in r.reason, r.reason
    # the next kernel runs on a fresh driver process
    path, entry = shipped_kernel("kernel-filter-moments", "glsl")
    assert run_kernel(path, entry, "kernel-filter-moments", "glsl", timing=False, shared=False).passed


def test_writes_outside_the_map_and_unwritten_texels_fail_with_the_reason(drivers, tmp_path):
    path, entry = mutant_file(tmp_path, "glsl", "hpg17_filter_moments.glsl",
                              "if (texel[i].x < int(params.size.x) && texel[i].y < int(params.size.y))\n"
                              "            imageStore", "imageStore", "kernel-filter-moments")
    rep = run_kernel(path, entry, "kernel-filter-moments", "glsl", timing=False, shared=False)
    for r in rep.runs:
        assert not r.passed and r.outside > 0 and "writes outside the output" in r.reason
    (tmp_path / "two").mkdir()
    path, entry = mutant_file(tmp_path / "two", "hlsl", "hpg17_filter_nlq64.hlsl", "for (int i = 0; i < 3; ++i) {",
                              "for (int i = 0; i < 2; ++i) {", "kernel-filter-nlq64")
    rep = run_kernel(path, entry, "kernel-filter-nlq64", "hlsl", timing=False, shared=False)
    for r in rep.runs:
        assert not r.passed and r.unwritten > 0
        assert "were never written" in rep.format()


def test_the_report_times_the_driver_beside_numpy(drivers):
    path, entry = shipped_kernel("kernel-filter-nlq64", "glsl")
    code, out, _ = _cli(["--glsl", str(path), "--entry", entry, "--case", "kernel-filter-nlq64"])
    assert code == 0, out
    assert out.startswith("PASS") and "[gl] PASS" in out and "[vulkan] PASS" in out
    assert "per block" in out and "NumPy emulation (gpu.onchip)" in out and "NumPy global path" in out
    assert "no bank conflicts in phase resolve" in out and "shared-memory races: none" in out
    assert "NO" not in out.split("shared-memory accesses:")[1].split("\n")[0]  # a finding, not a verdict


def test_binding_error_is_an_input_error():
    assert issubclass(BindingError, ValueError)
    assert set(SHIPPED_KERNELS) == set(KERNEL_CASES)


@pytest.mark.parametrize("language", LANGUAGES)
def test_shipped_filter_moments_are_the_block_emulations_bit_for_bit(drivers, language):
    """The shipped kernels repeat gpu.onchip's float32 arithmetic: equal bits on every driver that runs them."""
    from moments_ref.conformance._cases import load_case
    from moments_ref.gpu import onchip

    gc = load_case("kernel-filter-moments")
    kw = gc.meta["kwargs"]
    z = gc.arrays["depth"].reshape(kw["height"], kw["width"], -1)
    expect = onchip.filter_moments(z).reshape(-1, 4)
    path, entry = shipped_kernel("kernel-filter-moments", language)
    rep = run_kernel(path, entry, "kernel-filter-moments", language, timing=False, shared=False, gc=gc)
    for r in _ran(rep):
        assert np.array_equal(r.output.view(np.uint32), expect.view(np.uint32)), r.driver


PORTS_MD = (Path(__file__).resolve().parents[1] / "docs" / "ports.md").read_text()
KERNEL_EXAMPLE = re.findall(r"<!-- kernel-example: (\S+) entry=(\S+) case=(\S+) -->\s*```\w+\n(.*?)```", PORTS_MD,
                            re.S)


def test_the_worked_example_runs_as_printed(drivers, tmp_path):
    (name, entry, case, code), = KERNEL_EXAMPLE
    path = tmp_path / name
    path.write_text(code)
    rep = run_kernel(path, entry, case, timing=False)
    assert rep.passed and {r.driver for r in rep.runs} == {"gl", "vulkan"}, rep.format()
    old = "int2(index % 32, index / 32 + 8 * i)"
    assert code.count(old) == 1
    path.write_text(code.replace(old, "int2(index % 32 + 1, index / 32 + 8 * i)"))
    rep = run_kernel(path, entry, case, timing=False)
    for r in rep.runs:
        assert not r.passed and r.unwritten == 49 and r.first_unwritten == (0, 0)
    assert "49 texels were never written (first at x 0, y 0): their rows fail" in rep.format()


# --------------------------------------------------------------------------
# The runner itself, against a stand-in for the driver process (no driver runs: what the runner sends,
# and what it makes of each answer)

kernel_run = importlib.import_module("moments_ref.conformance.kernel.run")


@pytest.mark.parametrize("limit", [0.5, 1, math.inf])
def test_any_positive_time_limit_is_accepted(tmp_path, limit):
    """The limit is checked before anything runs: a positive one passes on to the next step (here the missing file)."""
    gc = types.SimpleNamespace(meta={"kwargs": {}})
    with pytest.raises(ShaderError, match="absent.glsl"):
        run_kernel(tmp_path / "absent.glsl", "main", "kernel-filter-moments", gc=gc, time_limit=limit)


@pytest.mark.parametrize("limit", [0, -1.0, math.nan, -math.inf])
def test_a_time_limit_not_positive_is_refused_naming_it(tmp_path, limit):
    gc = types.SimpleNamespace(meta={"kwargs": {}})
    with pytest.raises(InputError, match=r"^time_limit: expected a positive number of seconds"):
        run_kernel(tmp_path / "absent.glsl", "main", "kernel-filter-moments", gc=gc, time_limit=limit)


_NAP = 0.01


@pytest.mark.parametrize("fmt,emulated,global_path", [
    ("nlq64", "nlq64", "nlq64"), ("nlq32", "nlq32", "nlq32"),
    ("moments", "float128", "blur"), ("msm64", "affine64", "blur")])
def test_numpy_times_are_seconds_per_block_of_the_cases_own_paths(monkeypatch, fmt, emulated, global_path):
    """Each NumPy path of the case's format runs once on the case's map (H x W x samples, float32 as the kernel
    reads it) and is reported in seconds per 32 x 24 output block: a 48 x 70 map has 2 x 3 blocks."""
    from moments_ref.gpu import filtering, onchip

    calls = []

    def spy(name):
        def call(z, *args):
            calls.append((name, z.dtype, z.shape, *args))
            time.sleep(_NAP)
            return z
        return call

    monkeypatch.setattr(onchip, "filter_and_quantize", spy("onchip"))
    monkeypatch.setattr(filtering, "global_path_nlq", spy("global"))
    monkeypatch.setattr(filtering, "resolve_moments", lambda z: calls.append(("resolve", z.dtype, z.shape)) or z)
    monkeypatch.setattr(filtering, "blur", spy("blur"))
    h, w, s = 48, 70, 3
    gc = types.SimpleNamespace(meta={"kwargs": {"height": h, "width": w, "samples": s, "format": fmt}},
                               arrays={"depth": np.linspace(-1, 1, h * w * s)})
    t0 = time.perf_counter()
    got = numpy_times(f"kernel-filter-{fmt}", gc)
    elapsed = time.perf_counter() - t0
    f32 = np.dtype(np.float32)
    second = [("global", f32, (h, w, s), fmt)] if global_path != "blur" else \
        [("resolve", f32, (h, w, s)), ("blur", f32, (h, w, s))]
    assert calls == [("onchip", f32, (h, w, s), emulated)] + second
    assert set(got) == {"NumPy emulation (gpu.onchip)", "NumPy global path"}
    assert all(_NAP <= t * 6 <= elapsed for t in got.values()), (got, elapsed)


def test_numpy_times_of_the_vwss_case_are_seconds_per_view(monkeypatch):
    from moments_ref.golden import kernels

    calls = []

    def spy(points, views):
        calls.append((points, views))
        time.sleep(_NAP)

    monkeypatch.setattr(kernels, "vwss_reference", spy)
    gc = types.SimpleNamespace(meta={"kwargs": {"views": 4}}, arrays={"points": "P", "views": "V"})
    t0 = time.perf_counter()
    got = numpy_times("kernel-vwss-points", gc)
    elapsed = time.perf_counter() - t0
    assert calls == [("P", "V")] and list(got) == ["NumPy np.maximum.at"]
    assert _NAP <= got["NumPy np.maximum.at"] * 4 <= elapsed, (got, elapsed)


def _driver(monkeypatch, outcome):
    """Replace the driver process: ``outcome(job)`` answers each job sent to it; returns the list of jobs."""
    from moments_ref.conformance import _supervisor

    jobs = []

    def run(job):
        jobs.append(job)
        return outcome(job)

    monkeypatch.setattr(_supervisor, "run", run)
    return jobs


def test_a_dispatch_stopped_by_the_watchdog_fails_the_run_and_the_trace_says_so(monkeypatch, kernel_goldens):
    """Every job, the traced one too, runs under the time limit given; a dispatch the watchdog stops fails
    the kernel (the run's reason, the trace's error), it is not raised."""
    def stop(job):
        raise DriverTimeout("dispatch 2 of 6", job.dispatch_seconds, True)

    jobs = _driver(monkeypatch, stop)
    path, entry = shipped_kernel("kernel-filter-moments", "wgsl")
    gc = load_case("kernel-filter-moments", kernel_goldens)
    rep = run_kernel(path, entry, "kernel-filter-moments", "wgsl", adapter="vulkan", time_limit=0.25, gc=gc,
                     timing=False)
    (r,) = rep.runs
    assert not rep.passed and not r.passed
    assert "dispatch 2 of 6 did not finish within 0.25 s: the watchdog stopped the kernel" in r.reason, r.reason
    assert rep.shared == {"driver": "vulkan", "error": str(DriverTimeout("dispatch 2 of 6", 0.25, True))}
    assert [j.dispatch_seconds for j in jobs] == [0.25, 0.25]
    # the traced job is the judged one (same input, output and dispatches) with a trace buffer of one
    # record block per invocation of the 256-thread work group
    judged, traced = jobs
    assert [judged.trace_words, traced.trace_words] == [0, 256 * trace.RECORDS]
    assert traced.output == judged.output and traced.dispatches == judged.dispatches
    assert np.array_equal(traced.data, judged.data)


def test_a_compile_past_its_limit_is_raised_not_judged(monkeypatch, kernel_goldens):
    def slow_compile(job):
        raise DriverTimeout("the compile", 60, False)

    _driver(monkeypatch, slow_compile)
    path, entry = shipped_kernel("kernel-filter-moments", "wgsl")
    with pytest.raises(DriverTimeout, match="the compile time limit"):
        run_kernel(path, entry, "kernel-filter-moments", "wgsl", adapter="vulkan",
                   gc=load_case("kernel-filter-moments", kernel_goldens), timing=False)


def _words(records):
    """Trace words (trace.decode's layout): ``records[t]`` = [(address, store, epoch), ...] of invocation t."""
    w = np.zeros((256, trace.RECORDS), np.uint32)
    for t, recs in records.items():
        for k, (a, st, ep) in enumerate(recs):
            w[t, k] = (a + 1) | (st << 14) | (ep << 15)
    return w.reshape(-1)


def test_the_trace_counts_the_busiest_invocation_and_the_barriers(monkeypatch, kernel_goldens):
    """``accesses``: the most records of one invocation, address 0 included; ``barriers``: the last epoch;
    ``pattern`` only where the trace is gpu.banks' pattern (here it is not, though it has its shape)."""
    from moments_ref.conformance.kernel.contract import contract
    from moments_ref.conformance._run import parse_adapter
    from moments_ref.conformance.kernel.run import shared_memory

    records = {t: [(0, 0, 0)] * 104 for t in range(256)}  # every invocation reads word 0, 104 times
    records[3] = [(0, 0, 0), (0, 1, 1)] + [(0, 0, 2)] * 104  # one reads it 106 times, after 2 barriers
    jobs = _driver(monkeypatch, lambda job: Result(trace=_words(records)))
    case = "kernel-filter-moments"
    path, entry = shipped_kernel(case, "wgsl")
    info = shared_memory(path, entry, "wgsl", parse_adapter("vulkan", "wgsl"), case, load_case(case, kernel_goldens),
                         contract(case), time_limit=3.5)
    assert (info["driver"], info["accesses"], info["barriers"], info["pattern"]) == ("vulkan", 106, 2, False)
    assert set(info) == {"driver", "accesses", "barriers", "races", "pattern", "conflicts"}
    assert [j.dispatch_seconds for j in jobs] == [3.5]


TRACED_POINTS = (
    ("@group(0) @binding(2) var<uniform> params: Params;\n",
     "@group(0) @binding(2) var<uniform> params: Params;\nvar<workgroup> scratch: array<u32, 256>;\n"
     "fn put(a: u32, v: u32) { scratch[a] = v; }   // mr:shared-store\n"),
    ("@workgroup_size(128) fn CS(@builtin(global_invocation_id) thread_id: vec3<u32>)",
     "@workgroup_size(256) fn CS(@builtin(global_invocation_id) thread_id: vec3<u32>, "
     "@builtin(workgroup_id) gid: vec3<u32>, @builtin(local_invocation_index) gi: u32)"),
    ("    let i = thread_id.x;\n", "    let i = thread_id.x;\n    put(gi, 1u);\n"),
)


def test_a_traced_vwss_kernel_runs_the_cases_dispatches_without_the_filters_pattern(monkeypatch, tmp_path,
                                                                                    kernel_goldens):
    """A tagged VWSS kernel of 256 threads: the trace runs the case's dispatches for its own work-group width,
    and the filter's bank pattern and phases are not asked of it."""
    from moments_ref.conformance.kernel.contract import contract, dispatches
    from moments_ref.conformance._run import parse_adapter
    from moments_ref.conformance.kernel.run import shared_memory
    from moments_ref.ports import PORTS_DIR

    src = (PORTS_DIR / "wgsl" / "vwss_points.wgsl").read_text()
    for old, new in TRACED_POINTS:
        assert src.count(old) == 1
        src = src.replace(old, new)
    path = tmp_path / "traced_points.wgsl"
    path.write_text(src)
    jobs = _driver(monkeypatch, lambda job: Result(trace=_words({0: [(0, 1, 0)], 1: [(1, 1, 0)]})))
    case = "kernel-vwss-points"
    gc = load_case(case, kernel_goldens)
    info = shared_memory(path, "CS", "wgsl", parse_adapter("vulkan", "wgsl"), case, gc, contract(case))
    assert info == {"driver": "vulkan", "accesses": 1, "barriers": 0, "races": info["races"]}
    plan = dispatches(case, gc.meta["kwargs"], gc.arrays["views"], 256)
    (job,) = jobs
    assert [g for g, _ in job.dispatches] == [d.groups for d in plan]


def test_a_kernel_the_driver_refuses_is_a_shader_error_with_the_users_files_and_lines(drivers, monkeypatch,
                                                                                      kernel_goldens):
    """OpenGL compiles GLSL itself: its log's source-string numbers become the user's files, one line per
    error (warnings dropped); another toolchain's log is kept whole, on one line."""
    from moments_ref.conformance._supervisor import CompileFailed

    logs = {"gl": "0:1(10): warning: extension `GL_x' unsupported\n1:12(5): error: `x' undeclared\n"
                  "2:3(1): error: syntax error, unexpected '}'\n",
            "vulkan": "error: unknown identifier 'x'\n  at line 12\nerror: 1 compilation errors"}

    def refuse(job):
        raise CompileFailed(logs[job.driver])

    _driver(monkeypatch, refuse)
    case = "kernel-filter-moments"
    for language, adapter in (("glsl", "gl"), ("wgsl", "vulkan")):
        path, entry = shipped_kernel(case, language)
        with pytest.raises(ShaderError) as err:
            run_kernel(path, entry, case, language, adapter=adapter, gc=load_case(case, kernel_goldens), timing=False)
        head, *lines = str(err.value).splitlines()
        assert head.startswith(f"the kernel does not compile on {adapter} ("), head
        if adapter == "gl":
            files = load_source(path, "glsl").files
            assert lines == [f"{files[0]}:12:5: error: `x' undeclared", f"{files[1]}:3:1: error: syntax error, "
                             "unexpected '}'"], lines
        else:
            assert lines == ["error: unknown identifier 'x' at line 12 error: 1 compilation errors"], lines


@pytest.mark.parametrize("h,w", [(1, 1), (5, 5), (24, 32), (25, 33), (49, 66)])
@pytest.mark.parametrize("fmt,slot_format,comps", [("moments", "rgba32f", 4), ("nlq32", "r32ui", 1)])
@pytest.mark.parametrize("kind", ["buffer", "storage_image"])
def test_a_filter_output_holds_every_texel_a_whole_block_can_write(h, w, fmt, slot_format, comps, kind):
    """A kernel that writes whole 32 x 24 blocks without checking the map's edge must write into the output's
    padding, where the harness sees it (outside the map), never past its end: an image holds the blocks'
    rows and columns, a buffer (row-major, W texels a row) the last block's last texel."""
    from moments_ref.conformance.kernel.run import output_spec

    out = types.SimpleNamespace(slot=types.SimpleNamespace(role="output", format=slot_format),
                                resource=types.SimpleNamespace(kind=kind))
    other = types.SimpleNamespace(slot=types.SimpleNamespace(role="input", format=None),
                                  resource=types.SimpleNamespace(kind="texture_ms"))
    kw = {"height": h, "width": w, "format": fmt}
    spec = output_spec(f"kernel-filter-{fmt}", kw, [other, out], 0x1234)
    rows, cols = -(-h // 24) * 24, -(-w // 32) * 32  # the whole blocks over the map
    assert spec.fill == 0x1234
    if kind == "storage_image":
        assert (spec.kind, spec.format) == ("storage_image", slot_format)
        assert spec.shape[0] >= rows and spec.shape[1] >= cols and spec.shape[2] == comps
    else:
        assert (spec.kind, spec.format, len(spec.shape)) == ("buffer", "uint", 1)
        assert spec.shape[0] % comps == 0 and spec.shape[0] // comps >= (rows - 1) * w + cols


def _stopped(job):
    """The watchdog stops the job's first dispatch (nothing to judge: the test is about the job sent)."""
    raise DriverTimeout("dispatch 1", job.dispatch_seconds, True)


def test_each_driver_runs_the_toolchain_of_its_column(drivers, monkeypatch, kernel_goldens):
    """The module's table: GLSL on OpenGL through moderngl, HLSL through SPIRV-Cross and moderngl, WGSL through
    wgpu's OpenGL adapter; on Vulkan all three through wgpu. The runs are reported gl, then vulkan."""
    jobs = _driver(monkeypatch, _stopped)
    case = "kernel-vwss-points"
    gc = load_case(case, kernel_goldens)
    want = {"glsl": [("moderngl", "gl", "moderngl"), ("wgpu", "vulkan", "glslang and wgpu")],
            "hlsl": [("moderngl", "gl", "SPIRV-Cross"), ("wgpu", "vulkan", "glslang and wgpu")],
            "wgsl": [("wgpu", "gl", "wgpu's OpenGL adapter"), ("wgpu", "vulkan", "WGSL through wgpu")]}
    for language, expect in want.items():
        jobs.clear()
        path, entry = shipped_kernel(case, language)
        rep = run_kernel(path, entry, case, language, gc=gc, timing=False, shared=False)
        assert [r.driver for r in rep.runs] == ["gl", "vulkan"] and not any(r.skipped for r in rep.runs)
        assert [(j.backend, j.driver) for j in jobs] == [e[:2] for e in expect], language
        for r, (_, _, words) in zip(rep.runs, expect):
            assert words in r.toolchain, r.toolchain


def test_the_verdict_run_dispatches_the_contracts_groups(monkeypatch, kernel_goldens):
    from moments_ref.conformance.kernel.contract import dispatches

    jobs = _driver(monkeypatch, _stopped)
    case = "kernel-vwss-points"
    gc = load_case(case, kernel_goldens)
    path, entry = shipped_kernel(case, "wgsl")
    rep = run_kernel(path, entry, case, "wgsl", adapter="gl", gc=gc, timing=False, shared=False)
    (r,) = rep.runs
    assert r.skipped is None and not r.passed and "watchdog" in r.reason
    plan = dispatches(case, gc.meta["kwargs"], gc.arrays["views"], 128)  # the kernel's 128 × 1 × 1
    assert [g for g, _ in jobs[0].dispatches] == [d.groups for d in plan] and r.units == sum(d.blocks for d in plan)


def test_wgsl_with_a_multisampled_input_is_refused_on_gl_before_it_runs(monkeypatch, kernel_goldens):
    from moments_ref.conformance._errors import ContextError

    jobs = _driver(monkeypatch, _stopped)
    case = "kernel-filter-moments"
    path, entry = shipped_kernel(case, "wgsl")
    with pytest.raises(ContextError, match="cannot read a multisampled texture"):
        run_kernel(path, entry, case, "wgsl", adapter="gl", gc=load_case(case, kernel_goldens), timing=False)
    assert jobs == []


_P0, _P1 = POISON


@pytest.mark.parametrize("case,words,fills_sent,found", [
    ("kernel-filter-nlq32", {(0, 1): _P0}, [_P0, _P1], (1, (2, 0))),  # (0, 1) written with the first poison's word
    ("kernel-filter-nlq32", {(0, 1): _P1}, [_P0, _P1], (1, (2, 0))),  # ... with the second's: the first run judged
    ("kernel-filter-nlq32", {(0, 1): _P0, (1, 0): _P1}, [_P0, _P1], (2, (0, 1))),  # a tie: the first run
    ("kernel-filter-moments", {(0, 1): _P0}, [_P0], (2, (0, 1))),  # one run: (0, 1) holds the poison, unwritten
])
def test_an_nlq32_kernel_is_judged_on_the_run_with_fewer_texels_holding_its_poison(monkeypatch, kernel_goldens, case,
                                                                                   words, fills_sent, found):
    """Any 32-bit word is an nlq32 code, so one run cannot tell a texel left unwritten from one written with the
    poison's word: the kernel runs again on the other poison, and the run with fewer texels holding its poison
    is judged (the first on a tie). Other formats run once: there the poison is no valid texel."""
    gc = load_case(case, kernel_goldens)
    h, w = gc.meta["kwargs"]["height"], gc.meta["kwargs"]["width"]
    fills = []

    def kernel(job):
        fills.append(job.output.fill)
        out = np.full(job.output.shape, job.output.fill, np.uint32)
        out[:h, :w] = 7 if case.endswith("nlq32") else 0x3F000000  # a code; 0.5 in every moment
        out[2, 0] = job.output.fill  # (row 2, column 0) never written
        for texel, word in words.items():
            out[texel] = word
        return Result(output=out)

    _driver(monkeypatch, kernel)
    path, entry = shipped_kernel(case, "wgsl")
    rep = run_kernel(path, entry, case, "wgsl", adapter="vulkan", gc=gc, timing=False, shared=False)
    (r,) = rep.runs
    assert fills == fills_sent and (r.unwritten, r.first_unwritten) == found, (fills, r.unwritten)
    assert not r.passed and r.outside == 0


@pytest.mark.parametrize("language", ["glsl", "hlsl"])
def test_the_trace_on_gl_runs_the_opengl_toolchain(drivers, monkeypatch, kernel_goldens, language):
    """The traced kernel is prepared for the driver asked, as the judged one is (the module's table)."""
    from moments_ref.conformance._run import parse_adapter
    from moments_ref.conformance.kernel.contract import contract
    from moments_ref.conformance.kernel.run import shared_memory

    jobs = _driver(monkeypatch, lambda job: Result(trace=_words({0: [(0, 0, 0)]})))
    case = "kernel-filter-moments"
    path, entry = shipped_kernel(case, language)
    info = shared_memory(path, entry, language, parse_adapter("gl", language), case, load_case(case, kernel_goldens),
                         contract(case))
    assert info["driver"] == "gl" and [(j.backend, j.driver) for j in jobs] == [("moderngl", "gl")]
