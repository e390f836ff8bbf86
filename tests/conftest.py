"""Hypothesis profiles, and the fixtures the test modules share.

Hypothesis: ``ci`` (derandomized, bounded, no deadline) and ``thorough``. CI selects
``ci`` (also the default); run ``pytest --hypothesis-profile thorough`` for long
local runs. Conformance: the drivers, the compilers and the shipped goldens, built
on tests/_harness.py. Goldens: ``gdir``, the requesting module's ``GOLDEN_CASES``
(every case when it names none); every golden folder is written once per test
run, shared by the xdist workers (tests/_oracles.py). Derived goldens of engine
profiles (golden.conventions) are cached in the run's folder (``MOMENTS_REF_CACHE``).
"""

import os

import pytest
from hypothesis import HealthCheck, settings

from _harness import need, need_tool, shipped_golden_folder
from _oracles import RUN_FOLDER, golden_folder

settings.register_profile(
    "ci",
    derandomize=True,
    max_examples=60,
    deadline=None,
    print_blob=True,
    suppress_health_check=[HealthCheck.too_slow],
)
settings.register_profile(
    "thorough",
    max_examples=5000,
    deadline=None,
    print_blob=True,
    suppress_health_check=[HealthCheck.too_slow],
)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci"))


def pytest_configure(config):
    """A folder of the test run that its xdist workers share.

    The controller (or a run without workers) makes it; the workers inherit it through
    the environment. It holds the golden folders and the derived goldens of engine
    profiles (not the user's cache).
    """
    import tempfile

    if not hasattr(config, "workerinput"):
        run = tempfile.mkdtemp(prefix="moments-ref-test-run-")
        os.environ[RUN_FOLDER] = run
        config._moments_ref_run = run
        if not os.environ.get("MOMENTS_REF_CACHE"):
            os.environ["MOMENTS_REF_CACHE"] = os.path.join(run, "cache")


#: Modules whose tests share an expensive module fixture (or a module-level cache): under
#: xdist one worker runs each of them whole, so the fixture is made once, not once per worker.
WHOLE_MODULES = {
    "tests/test_cli_probes.py": "probe_runs: every real-process probe",
    "tests/test_report.py": "tiny: one report the tests inspect",
    "tests/test_report_area.py": "area_run, area_report, scattering_report",
    "tests/test_mutants.py": "results: the corpus judged",
    "tests/test_msm_soft.py": "artifacts: the measurements",
    "tests/test_scattering.py": "small_scene",
    "tests/test_evsm_scene.py": "railing: one pipeline run",
    "tests/test_paper_claims.py": "railing: one pipeline run",
    "tests/test_golden_kernels.py": "arrays: the kernel cases generated",
    "tests/test_golden.py": "gdir: every case (a second worker would wait for it)",
    "tests/test_golden_bad_input.py": "clean: a golden folder",
    "tests/test_conformance_probes.py": "golden_dir: a golden folder",
    "tests/test_profiles.py": "gdir: a golden folder",
    "tests/test_conformance_languages.py": "_RUNS: each shipped port's run",
    "tests/test_base_install.py": "base_python: an environment",
    "tests/test_bluenoise.py": "small_textures",
    "tests/test_architecture.py": "_tree, _tokens: each module parsed and tokenized once",
}


@pytest.hookimpl(optionalhook=True)  # an xdist hook: unknown without xdist (-p no:xdist)
def pytest_xdist_make_scheduler(config, log):
    """Under ``-n`` without an explicit ``--dist``: the modules of :data:`WHOLE_MODULES` as one unit each.

    Every other test is a unit of its own (as with xdist's ``load``). The units are handed
    out largest first (xdist's loadscope order: the whole modules), so that the single
    tests fill the end of the run evenly. (xdist's own ``loadgroup`` marks do not reach
    the scheduler under pytest 9, which ignores the node ids that xdist rewrites.)
    """
    args = list(config.invocation_params.args) + os.environ.get("PYTEST_ADDOPTS", "").split()
    if config.getoption("dist") != "load" or any(a in ("--dist", "-d") or a.startswith("--dist=") for a in args):
        return None  # xdist's own scheduler for the --dist asked for
    from xdist.scheduler import LoadScopeScheduling

    class WholeModules(LoadScopeScheduling):
        def _split_scope(self, nodeid):
            module = nodeid.split("::", 1)[0]
            return module if module in WHOLE_MODULES else nodeid

    return WholeModules(config, log)


def pytest_unconfigure(config):
    """The controller removes the run's shared folder."""
    import shutil

    run = getattr(config, "_moments_ref_run", None)
    if run is not None:
        shutil.rmtree(run, ignore_errors=True)


# --------------------------------------------------------------------------
# Conformance: the drivers, the compilers and the shipped goldens

@pytest.fixture(scope="session")
def ctx():
    """The OpenGL 4.3 context of the driver process, or skip (fail under CI)."""
    from moments_ref import conformance

    return need(conformance.get_context, "an OpenGL 4.3 context")


@pytest.fixture(scope="session")
def drivers(ctx):
    """Both drivers (OpenGL; Vulkan and wgpu's OpenGL adapter) and both compilers, or skip (fail under CI)."""
    from moments_ref.conformance import _wgpu

    need(lambda: _wgpu.get_device("Vulkan"), "a Vulkan adapter")
    need(lambda: _wgpu.get_device("OpenGL"), "wgpu's OpenGL adapter")
    for tool in ("glslangValidator", "spirv-cross"):
        need_tool(tool)


@pytest.fixture(scope="session")
def golden_dir():
    """Goldens of every shipped case (written once per test run)."""
    return shipped_golden_folder()


@pytest.fixture(scope="module")
def gdir(request):
    """Goldens of the requesting module's ``GOLDEN_CASES`` (every case when it names none), written once."""
    cases = getattr(request.module, "GOLDEN_CASES", None)
    return golden_folder(None if cases is None else tuple(cases))
