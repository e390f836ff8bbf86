"""Compute shaders on the kernel cases, on both drivers: the shipped kernels pass, the mutants fail.

Needs moderngl with EGL (llvmpipe), wgpu with a Vulkan driver (lavapipe), glslangValidator,
spirv-cross and spirv-tools. Without them the tests are skipped with the reason, except under
CI (``CI=true``), where a missing driver or tool is a failure.
"""

from __future__ import annotations

import io
import re
from pathlib import Path

import numpy as np
import pytest

from moments_ref import cli
from moments_ref.conformance.kernel import BindingError, run_kernel, trace
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
    assert "bank conflicts from the trace: resolve 0" in out and "races: none" in out


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
