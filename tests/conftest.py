"""Hypothesis profiles: ``ci`` (derandomized, bounded, no deadline) and ``thorough``.

CI selects ``ci`` (also the default); run ``pytest --hypothesis-profile thorough``
for long local runs. Derived goldens of engine profiles (golden.conventions) are cached
in a temporary folder of the run (``MOMENTS_REF_CACHE``).
"""

import os

from hypothesis import HealthCheck, settings

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
    """Derived goldens of engine profiles go to a folder of the test run, not to the user's cache."""
    import tempfile

    if not os.environ.get("MOMENTS_REF_CACHE"):
        os.environ["MOMENTS_REF_CACHE"] = tempfile.mkdtemp(prefix="moments-ref-test-cache-")
