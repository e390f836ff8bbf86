"""Small sweeps for the sweep's tests: chunks of 40 rows and the float32 reference port.

Shared by tests/test_sweep_tallies.py and tests/test_sweep_batch.py (a sweep of a few chunks,
with bugs placed at known rows, is counted by hand there).
"""

from __future__ import annotations

import numpy as np
import pytest

from moments_ref import msm
from moments_ref.sweep import runner, samplers

__all__ = ["CASE", "SMALL", "small_chunks", "reference"]

CASE = "shadow_intensity-lower-float32"
SMALL = 40


@pytest.fixture(autouse=True)
def small_chunks(monkeypatch):
    """Chunks of SMALL rows in the samplers and the runner, for every test of a module that imports it."""
    monkeypatch.setattr(samplers, "CHUNK", SMALL)
    monkeypatch.setattr(runner, "CHUNK", SMALL)


def reference(b, zf):
    """Algorithm 1's lower bound in float32: the port every placed bug is moved from."""
    return msm.shadow_intensity(np.asarray(b, np.float32), np.asarray(zf, np.float32), bound="lower")
