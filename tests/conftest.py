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
    """A folder of the test run that its xdist workers share (golden folders, derived goldens).

    The controller (or a run without workers) makes it; the workers inherit it through the
    environment. Derived goldens of engine profiles go there too, not to the user's cache.
    """
    import tempfile

    if not hasattr(config, "workerinput"):
        run = tempfile.mkdtemp(prefix="moments-ref-test-run-")
        os.environ[RUN_FOLDER] = run
        config._moments_ref_run = run
        if not os.environ.get("MOMENTS_REF_CACHE"):
            os.environ["MOMENTS_REF_CACHE"] = os.path.join(run, "cache")


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
