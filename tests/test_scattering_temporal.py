"""Temporal stability of prefiltered single scattering (moments_ref.report.scattering_temporal)."""

import numpy as np
import pytest

from moments_ref import InputError
from moments_ref.report import scattering_temporal as T
from moments_ref.scene import load_scene


def test_light_path_turns_by_equal_small_steps():
    d = np.array([0.45, -0.6, 0.65])
    p = T.light_path(d, steps=16, step_degrees=0.25)
    assert p.shape == (17, 3) and np.allclose(np.linalg.norm(p, axis=1), 1)
    assert np.allclose(p[0], d / np.linalg.norm(d))
    ang = np.degrees(np.arccos(np.clip(np.sum(p[1:] * p[:-1], axis=1), -1, 1)))
    assert np.allclose(ang, 0.25, atol=1e-6)
    total = np.degrees(np.arccos(np.clip(p[0] @ p[-1], -1, 1)))
    assert total == pytest.approx(4.0, abs=1e-6)  # one plane of rotation: the steps add up
    with pytest.raises(InputError, match="steps"):
        T.light_path(d, steps=0)


def test_measure_and_claim_on_a_small_setting():
    m = T.measure(load_scene("scattering"), steps=2, resolution=(32, 18), shadow_map_size=128, msaa=1,
                  epipolar_size=(32, 64), reference_samples=64)
    for n in ("scattering_6m", "scattering_6m_unfiltered"):
        assert set(m[n]) == {"temporal_error", "flicker_ratio", "still_rmse"}
        assert all(np.isfinite(v) and v >= 0 for v in m[n].values())
    assert m["reference_change_rms"] > 0  # the light moved: the converged image changed
    c = T.claim(m)
    assert c.id == "slides-scattering-filtered-temporal" and c.verdict in ("holds", "does not hold")
    assert (c.verdict == "holds") == (m["scattering_6m"]["temporal_error"] < m["scattering_6m_unfiltered"]["temporal_error"])
    with pytest.raises(InputError, match="directional"):
        T.measure(load_scene("knot"))


def test_a_still_light_has_no_temporal_error():
    m = T.measure(load_scene("scattering"), steps=1, step_degrees=0.0, resolution=(24, 14), shadow_map_size=96,
                  msaa=1, epipolar_size=(16, 32), reference_samples=32)
    assert m["reference_change_rms"] == 0
    assert m["scattering_6m"]["temporal_error"] == 0 and m["scattering_6m_unfiltered"]["temporal_error"] == 0
