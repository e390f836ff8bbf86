"""The sweep under a profile: rows drawn in the papers' frame and converted exactly as the golden rows are
([0, 1] depths, a bias applied before the call), a correct [0, 1] port passing and a mutant found."""

import subprocess
import sys

import numpy as np
import pytest

from moments_ref import golden, moments, msm, oracle
from moments_ref.golden.conventions import convert_inputs as golden_convert, profiled_case
from moments_ref.golden.profile import Bias, Profile
from moments_ref.sweep import CHUNK, profiled
from moments_ref.sweep.samplers import build_inputs, draw_rows

CASE = "shadow_intensity-lower-float32"
UNIT_BEFORE = Profile(depth="[0,1]", bias=Bias(6e-5, (0.5, 0.3125, 0.2, 0.15), "before"))
PROFILES = [Profile(depth="[0,1]"), Profile(bias=Bias(3e-7, (0.0, 0.375, 0.0, 0.375), "before")), UNIT_BEFORE]


def _papers_rows(params, biased):
    """The rows in the papers' frame: the texel's float32 moments, harness-biased in float32 unless ``biased`` is
    False (a profile that declares the bias starts from the texel's moments)."""
    b = moments.power_moments(params["z"], params["w"]).astype(np.float32)
    if biased:
        b = moments.bias_moments(b, moments.BIAS_FLOAT32)
    return {"b": b, "zf": params["zf"].astype(np.float32)}


@pytest.mark.parametrize("profile", PROFILES, ids=lambda p: p.describe())
def test_conversion_equals_the_goldens_rational_one_bit_for_bit(profile):
    base = golden.CASES[CASE]
    case = profiled_case(base, profile)
    params = draw_rows(case, 3, 0, rows=1500, profile_key=profile.key)
    # Rows with few significant bits (depths 0, ±1, ±1/2, equal weights): sums on float32 midpoints.
    simple = np.array([0.0, 1.0, -1.0, 0.5, -0.5, 0.25])
    params["z"][:36, :2] = np.stack(np.meshgrid(simple, simple), -1).reshape(-1, 2)
    params["w"][:36] = 0
    params["w"][:36, :2] = 0.5
    params["zf"][:36] = np.resize(simple, 36)
    # What the sweep's port receives, against the goldens' rational conversion of the same rows in the papers'
    # frame (a profile bias starts from the texel's moments; otherwise from the harness-biased ones).
    got = build_inputs(case, dict(params), profile)
    want = golden_convert(base, _papers_rows(params, profile.bias is None), profile)
    for k in ("b", "zf"):
        assert got[k].dtype == np.float32
        assert np.array_equal(got[k].view(np.uint32), np.asarray(want[k], np.float32).view(np.uint32)), k


def test_the_contract_is_decided_on_the_papers_inputs():
    case = profiled_case(golden.CASES[CASE], UNIT_BEFORE)
    params = draw_rows(case, 0, 0, rows=4000, profile_key=UNIT_BEFORE.key)
    build_inputs(case, params, UNIT_BEFORE)
    assert params["contract"].dtype == bool and params["contract"].mean() > 0.99  # the bias moves texels inside


def _unit_port(b, zf):
    """A correct [0, 1] port: Algorithm 1 does not depend on the depth convention (golden.variants)."""
    return msm.shadow_intensity(np.asarray(b, np.float32), np.asarray(zf, np.float32), bound="lower")


def _acne_unit(b, zf):
    """One-change mutant: an acne offset of 1e-4 (an engine's [0, 1] depth epsilon) subtracted from zf."""
    return msm.shadow_intensity(np.asarray(b, np.float32), np.asarray(zf, np.float32) - np.float32(1e-4),
                                bound="lower")


def test_a_correct_unit_port_passes_and_a_mutant_is_found_under_a_before_bias(tmp_path):
    assert oracle.sweep(_unit_port, CASE, rows=CHUNK // 2, profile=UNIT_BEFORE).passed
    res = oracle.sweep(_acne_unit, CASE, rows=CHUNK // 2, profile=UNIT_BEFORE, out=tmp_path)
    assert not res.passed and len(res.failures[0]["texel"]["depths"]) <= 2
    # The papers' port (depths in [-1, 1]) fails a [0, 1] profile at once.
    wrong = oracle.sweep(lambda b, zf: _unit_port(b, zf * 2 - 1), CASE, rows=2000, profile=UNIT_BEFORE, shrink=False)
    assert not wrong.passed


def test_conversion_helpers_are_the_profiles():
    case = profiled_case(golden.CASES[CASE], UNIT_BEFORE)
    assert profiled.unit_depth(case) and profiled.harness_bias(case)[0] == 6e-5
    assert not profiled.unit_depth(golden.CASES[CASE]) and profiled.harness_bias(golden.CASES[CASE]) is None


def test_cli_sweeps_a_unit_profile_instead_of_refusing_it(tmp_path):
    from moments_ref.conformance import PORTS_DIR

    if not (PORTS_DIR / "glsl" / "msm.glsl").is_file():
        pytest.skip("no shipped ports")
    pytest.importorskip("moderngl")
    args = ["--glsl", "msm.glsl", "--function", "shadow_intensity_lower", "--case", CASE, "--rows", "3000",
            "--depth", "[0,1]", "--bias-alpha", "6e-5", "--bias-target", "0.5,0.3125,0.2,0.15", "--bias-applied",
            "before", "--adapter", "gl", "--json", str(tmp_path / "s.json")]
    p = subprocess.run([sys.executable, "-m", "moments_ref", "sweep", *args], capture_output=True, text=True)
    assert p.returncode in (0, 1) and "Traceback" not in p.stderr, p.stderr
    assert p.returncode == 0, p.stdout + p.stderr


def test_six_moments_convert_to_unit_depth_as_the_goldens_do():
    profile = Profile(depth="[0,1]")
    base = golden.CASES["shadow_intensity6-lower-float32"]
    case = profiled_case(base, profile)
    params = draw_rows(case, 0, 0, rows=600, profile_key=profile.key)
    got = build_inputs(case, dict(params), profile)
    want = golden_convert(base, build_inputs(base, dict(params)), profile)
    assert got["b"].shape == (600, 6)
    for k in ("b", "zf"):
        assert np.array_equal(got[k].view(np.uint32), np.asarray(want[k], np.float32).view(np.uint32)), k


def test_a_visibility_port_s_failures_are_named_visibility():
    """Under ``output = "visibility"`` the values the sweep prints are the port's visibilities: so named."""
    vis = Profile(depth="[0,1]", output="visibility", bias=UNIT_BEFORE.bias)
    res = oracle.sweep(lambda b, zf: 1 - _acne_unit(b, zf), CASE, rows=CHUNK // 2, profile=vis, shrink=False)
    assert not res.passed
    text = res.format()
    assert "  visibility: got " in text and "  intensity: got " not in text
    plain = oracle.sweep(_acne_unit, CASE, rows=CHUNK // 2, profile=UNIT_BEFORE, shrink=False)
    assert "  intensity: got " in plain.format()
