"""Hypothesis profiles (``ci``: derandomized, bounded, no deadline; ``thorough``) and the shared fixtures.

CI selects ``ci`` (also the default); run ``pytest --hypothesis-profile thorough``
for long local runs. Fixtures: ``golden_dir`` (every case the shipped ports cover),
``gdir`` (the requesting module's ``GOLDEN_CASES``), ``ctx`` (an OpenGL 4.3 context);
the golden folders are written once per test process (``_oracles.golden_folder``).
"""

import os

import pytest
from hypothesis import HealthCheck, settings

from _oracles import golden_folder

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


# ---------------------------------------------------------------------------
# Shared fixtures


@pytest.fixture(scope="session")
def golden_dir():
    """Goldens of every case a shipped port covers (``conformance.shipped_cases()``), written once."""
    from moments_ref import conformance

    return golden_folder(tuple(conformance.shipped_cases()))


@pytest.fixture(scope="module")
def gdir(request):
    """Goldens of the requesting module's ``GOLDEN_CASES`` (every case when it names none), written once."""
    cases = getattr(request.module, "GOLDEN_CASES", None)
    return golden_folder(None if cases is None else tuple(cases))


@pytest.fixture(scope="module")
def ctx():
    """An OpenGL 4.3 context (moderngl), or a skip; under CI (``CI=true``) its absence fails."""
    from moments_ref import conformance

    try:
        return conformance.get_context()
    except conformance.ContextError as exc:
        if os.environ.get("CI", "").lower() == "true":
            pytest.fail(f"CI=true but no OpenGL 4.3 context: {exc}")
        pytest.skip(f"no OpenGL 4.3 context: {exc}")
