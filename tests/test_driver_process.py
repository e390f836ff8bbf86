"""One driver process for functions and kernels (``conformance._supervisor``): limits, watchdog, replacement.

Drivers absent: skipped, or failed under CI (the ``drivers`` fixture of conftest.py). The
hostile files as real processes (macro bomb, huge local array, endless loops): tests/test_conformance_probes.py
and tests/test_kernel_conformance.py.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from moments_ref import InputError, cli, conformance
from moments_ref._arrays import set_max_memory
from moments_ref.conformance import WATCHDOG_SECONDS, watchdog
from moments_ref.conformance._source import WRAPPER, wrapped_compile_error
from moments_ref.conformance._supervisor import COMPILE_SECONDS, DriverTimeout, driver_pid, using_watchdog
from moments_ref.conformance.kernel import run_kernel
from moments_ref.conformance.kernel._job import Job
from moments_ref.conformance.kernel.cli import shipped_kernel

CASE = "shadow_intensity-lower-float32"
FIXTURES = Path(__file__).parent / "fixtures" / "kernels"
#: 60000 iterations of 20 sin/cos: seconds on llvmpipe (its loop limiter stops at 65535, so it ends by itself).
_SLOW = ("float f(vec4 b, float zf) { float s = b.x; for (int i = 0; i < 60000; i++) { "
         + " ".join(["s = sin(s * 1.7 + zf) + cos(s * 0.3);"] * 20) + " } return s; }\n")


def _shipped_function(golden_dir, language="glsl", adapter="gl"):
    path, function = conformance.shipped_port(CASE, language)
    return conformance.run_case(path, function, CASE, golden_dir, language, adapter)


def _data_limit(pid):
    """The soft RLIMIT_DATA of process ``pid`` in bytes (None: unlimited)."""
    line = next(x for x in Path(f"/proc/{pid}/limits").read_text().splitlines() if x.startswith("Max data size"))
    soft = line.split()[3]
    return None if soft == "unlimited" else int(soft)


def test_functions_and_kernels_run_in_one_driver_process(drivers, golden_dir):
    assert _shipped_function(golden_dir).passed
    pid = driver_pid()
    assert pid is not None
    path, entry = shipped_kernel("kernel-filter-moments", "glsl")
    assert run_kernel(path, entry, "kernel-filter-moments", "glsl", timing=False, shared=False).passed
    assert _shipped_function(golden_dir, "wgsl", "vulkan").passed
    assert driver_pid() == pid  # one process, its OpenGL context and wgpu devices opened once


@pytest.mark.skipif(not Path("/proc/self/limits").exists(), reason="reads /proc/PID/limits (Linux)")
def test_the_memory_limit_holds_in_the_driver_process_of_kernels_and_functions(drivers, golden_dir):
    old = set_max_memory(3 << 30)
    try:
        path, entry = shipped_kernel("kernel-vwss-points", "wgsl")
        assert run_kernel(path, entry, "kernel-vwss-points", "wgsl", "vulkan", timing=False, shared=False).passed
        kernel_limit = _data_limit(driver_pid())
        set_max_memory(5 << 30)
        assert _shipped_function(golden_dir).passed
        function_limit = _data_limit(driver_pid())
    finally:
        set_max_memory(old)
    assert kernel_limit == 3 << 30 and function_limit == 5 << 30


def test_a_dispatch_past_the_watchdog_replaces_the_driver_process(drivers, golden_dir, tmp_path):
    path = tmp_path / "slow.glsl"
    path.write_text(_SLOW)
    assert _shipped_function(golden_dir).passed
    old = driver_pid()
    with using_watchdog(0.5), pytest.raises(DriverTimeout) as exc:
        conformance.run_case(path, "f", CASE, golden_dir, "glsl", "gl")
    assert watchdog() == WATCHDOG_SECONDS  # the block's limit only
    assert isinstance(exc.value, InputError) and exc.value.watchdog and exc.value.step == "the dispatch"
    assert str(exc.value).startswith("the driver did not finish the dispatch within 0.5 s") and "--watchdog" in str(exc.value)
    assert driver_pid() is None
    with pytest.raises(ProcessLookupError):  # killed and reaped: no orphan
        os.kill(old, 0)
    assert _shipped_function(golden_dir).passed and driver_pid() not in (None, old)


def test_the_deprecated_time_limit_is_the_watchdog(drivers, capsys):
    code = cli.main(["conformance", "--kernel", "--glsl", str(FIXTURES / "slow_loop.glsl"), "--entry", "main",
                     "--case", "kernel-filter-moments", "--adapter", "gl", "--time-limit", "1"])
    out = capsys.readouterr().out
    assert code == 1 and "did not finish within 1 s: the watchdog stopped the kernel" in out, out
    assert watchdog() == WATCHDOG_SECONDS  # the command's limit held for its run only


def test_help_documents_one_watchdog_and_the_deprecated_alias(capsys):
    with pytest.raises(SystemExit):
        cli.main(["conformance", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "--watchdog SECONDS longest one dispatch may run" in text and "for functions and kernels (default 10)" in text
    assert "--time-limit SECONDS deprecated alias of --watchdog" in text


@pytest.mark.parametrize("argv,name", [(["--watchdog", "0"], "watchdog"), (["--time-limit", "-1"], "time_limit"),
                                       (["--watchdog", "nan"], "watchdog")])
def test_a_bad_watchdog_is_exit_2_naming_the_flag(argv, name, capsys):
    code = cli.main(["conformance", "--glsl", "msm.glsl", "--function", "f", "--case", CASE, *argv])
    err = capsys.readouterr().err
    assert code == 2 and f"{name}: expected a positive number of seconds" in err and len(err.splitlines()) == 1, err


def test_kernel_steps_and_their_limits():
    job = Job("wgpu", "vulkan", None, "", "CS", [], None, None, [((1, 1, 1), b""), ((2, 1, 1), b"")],
              dispatch_seconds=3.0)
    assert job.target == ("wgpu", "Vulkan", None)
    assert job.step(None) == ("the compile", COMPILE_SECONDS, False)
    assert job.step("compiled") == ("the first dispatch (warm-up, with the driver's compile)", COMPILE_SECONDS + 3.0,
                                    True)
    assert [job.step(d)[0] for d in ("warm-up", "dispatch 0", "dispatch 1")] == \
        ["dispatch 1 of 2", "dispatch 2 of 2", "the readback"]
    assert Job("moderngl", "gl", None, "", "main", [], None, None, []).target == ("gl",)
    assert Job("wgpu", "gl", "llvm", "", "CS", [], None, None, []).target == ("wgpu", "OpenGL", "llvm")


def test_the_signature_hint_only_where_the_wrappers_call_fails():
    sig = "float f(float xi4)"
    inside = wrapped_compile_error("glslang", ["p.glsl:3: 'expression' : Expected"], sig)
    assert str(inside).splitlines()[0] == "the wrapped function does not compile (glslang):"
    at_call = wrapped_compile_error("glslang", [f"{WRAPPER}:9: 'f' : no matching overloaded function found"], sig)
    assert str(at_call).splitlines()[0] == f"the wrapped function does not compile (glslang; expected signature: {sig}):"
    bare = wrapped_compile_error("", [f"{WRAPPER}: call to f: wrong argument count"], sig)
    assert str(bare).splitlines()[0] == f"the wrapped function does not compile (expected signature: {sig}):"
