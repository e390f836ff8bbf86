"""The report's area-light rows (msm_soft, pcss, vwss, mvr against MVR) and scattering rows.

The area-light scene is a square occluder parallel to a rectangular light over a
ground plane parallel to it: its exact visibility is the fraction of the light
rectangle seen past the square, computed here by brute-force ray casting
(:func:`moments_ref.techniques.msm_soft.ray_cast_visibility`, 64² light samples),
independently of rasterization, of the MVR reference and of the techniques.
"""

import csv
import dataclasses
import json
import math

import numpy as np
import pytest

from moments_ref import InputError, pipeline, report
from moments_ref.scene import load_scene
from moments_ref.techniques import msm_soft

SQUARE = """
name = "square"
shadow_map_size = 64
msaa = 1
outputs = ["vwss", "mvr"]

[light]
type = "area"
center = [0.0, 3.0, 0.0]
normal = [0.0, -1.0, 0.0]
width = 0.8
height = 0.5
up = [0.0, 0.0, -1.0]
fov = 90

[camera]
eye = [0.0, 2.6, 1.6]
target = [0.0, 0.0, 0.0]
fov = 40
resolution = [64, 36]

[[objects]]
name = "ground"
generator = "plane"
params = { width = 2.0, depth = 2.0 }
role = "receiver"

[[objects]]
name = "square"
generator = "plane"
params = { width = 0.6, depth = 0.6 }
transform = [ { translate = [0.0, 1.0, 0.0] } ]
role = "occluder"
"""

AREA = {"reference_views": 48, "light_samples": 8}
# jobs=1: everything in this process (the workers' own results are test_report_parallel's)
TINY = dict(progress=False, shadow_map_size=96, noise_tiles=1, repeats=1, jobs=1)


@pytest.fixture(scope="module")
def square(tmp_path_factory):
    path = tmp_path_factory.mktemp("scene") / "square.toml"
    path.write_text(SQUARE)
    return path


@pytest.fixture(scope="module")
def area_run(square):
    """Pipeline run of all area-light outputs on the square scene, and the exact intensity."""
    sc = load_scene(square)
    r = pipeline.run(sc, list(pipeline.AREA_OUTPUTS), pipeline.Settings(shadow_map_size=96, overrides={"area": AREA}))
    light = sc.light
    v = sc.occluder.vertices - light.center
    x, y, d = v @ light.tangent, v @ light.bitangent, v @ light.normal
    rect = [[x.min(), x.max(), y.min(), y.max(), d.mean()]]
    exact = 1.0 - msm_soft.ray_cast_visibility(light, rect, r.gbuffer.position, samples=64)
    return sc, r, rect, exact


@pytest.fixture(scope="module")
def area_report(square, tmp_path_factory):
    out = tmp_path_factory.mktemp("report_area")
    return out, report.run(scenes=[str(square)], out_dir=out, area=AREA, resolution=(64, 36), all_techniques=True,
                           **TINY)


def _rmse(a, b):
    return float(np.sqrt(np.mean((np.asarray(a) - np.asarray(b)) ** 2)))


def test_mvr_reference_matches_ray_casting_and_a_moved_light_does_not(area_run):
    sc, r, rect, exact = area_run
    penumbra = (exact > 0.02) & (exact < 0.98)
    assert penumbra.sum() > 50 and (exact > 0.98).sum() > 20  # the view holds umbra and penumbra
    ref = r.reference["vwss"]
    for n in pipeline.AREA_OUTPUTS:
        np.testing.assert_array_equal(r.reference[n], ref)  # one reference for all soft rows
    # Measured 0.025 and 0.043 (48 light samples, 96² maps): sampling and texel error.
    assert _rmse(ref, exact) < 0.035
    assert _rmse(ref[penumbra], exact[penumbra]) < 0.06
    # Mutant: the exact shadow of a light moved by 0.15 is far from the reference: the check has power.
    moved = dataclasses.replace(sc.light, center=sc.light.center + np.array([0.15, 0.0, 0.0]))
    wrong = 1.0 - msm_soft.ray_cast_visibility(moved, rect, r.gbuffer.position, samples=64)
    assert _rmse(ref, wrong) > 3 * 0.035


def test_soft_rows_are_intensities_close_to_the_exact_shadow(area_run):
    """Intensity = 1 − visibility: a swap (visibility) would be off by ~0.9 on the ground."""
    _, r, _, exact = area_run
    for n in ("msm_soft", "pcss", "vwss", "mvr"):
        s = r.shadow[n]
        assert s.shape == exact.shape and np.isfinite(s).all()
        assert s.min() >= 0 and s.max() <= 1
        assert _rmse(s, exact) < 0.07, n  # measured 0.024 (msm_soft) to 0.051 (vwss, 8 light samples)
        assert r.texel_seconds[n] > 0 and r.fragment_seconds[n] > 0
    # one 32-bit depth map per light sample for the multi-view techniques (8 here)
    assert r.bits_per_texel == {"msm_soft": 128, "pcss": 32, "vwss": 32 * 8, "mvr": 32 * 8}


def test_area_stage_names(area_run):
    _, r, _, _ = area_run
    multiview = {"mvr_reference_vwss", "vwss_light_samples", "vwss_points", "vwss_warp", "shade_vwss",
                 "mvr_vwss", "shade_mvr_vwss"}
    assert multiview <= set(r.stages)
    assert {s for s in r.stages if "vwss" in s} == multiview
    # Single-map work (msm_soft, PCSS) is not named multi-view.
    assert {"area_center_depth_map", "msm_soft_sat", "shade_msm_soft", "shade_pcss"} <= set(r.stages)
    # Texel costs: the centre map and SAT for msm_soft, the centre map for PCSS, points + warp for VWSS.
    sec = r.seconds
    assert r.texel_seconds["msm_soft"] == pytest.approx(sec["area_center_depth_map"] + sec["msm_soft_sat"])
    assert r.texel_seconds["pcss"] == pytest.approx(sec["area_center_depth_map"])
    assert r.texel_seconds["vwss"] == pytest.approx(sec["vwss_points"] + sec["vwss_warp"])
    assert r.fragment_seconds["vwss"] == pytest.approx(sec["shade_vwss"])


def test_area_outputs_refused_without_an_area_light():
    with pytest.raises(InputError, match="area light"):
        pipeline.run(load_scene("railing"), ["vwss"], pipeline.Settings(shadow_map_size=32, resolution=(32, 18)))
    with pytest.raises(InputError, match="area-light outputs: msm_soft, pcss"):
        pipeline.run(load_scene("railing"), ["vwss_typo"], pipeline.Settings(shadow_map_size=32, resolution=(32, 18)))


def test_report_has_the_area_rows(area_report, area_run, square):
    out, res = area_report
    with open(out / "results.csv", newline="") as f:
        rows = {r["technique"]: r for r in csv.DictReader(f) if r["scene"] == "square"}
    assert {"msm_soft", "pcss", "vwss", "mvr", "pcf", "msm64"} <= set(rows)  # hard rows stay
    for n in ("msm_soft", "pcss", "vwss", "mvr"):
        assert rows[n]["pareto"] in ("true", "false") and int(rows[n]["repeats"]) >= 1
        for c in report.COLUMNS[3:-2]:
            v = float(rows[n][c])
            assert math.isfinite(v) or (c == "flip_mean" and not report.flip_available()), (n, c)
        assert float(rows[n]["texel_seconds"]) > 0 and float(rows[n]["fragment_seconds"]) > 0
    # The report's metrics are those of the pipeline's intensities against the MVR reference.
    _, r, _, _ = area_run
    got = {x["technique"]: x for x in res["rows"]}
    for n in ("msm_soft", "vwss"):  # computed here, not by the report's own metrics()
        e = np.asarray(r.shadow[n], np.float64) - np.asarray(r.reference[n], np.float64)
        assert got[n]["rmse"] == pytest.approx(_rmse(r.shadow[n], r.reference[n]), rel=1e-12)
        assert got[n]["leak_fraction"] == pytest.approx(float(np.mean(e < -0.05)), abs=1e-15)
    assert got["msm_soft"]["bits_per_texel"] == 128


def test_report_stages_images_and_text(area_report):
    out, res = area_report
    stages = [s["stage"] for s in json.loads((out / "stages.json").read_text())["square"]]
    assert "mvr_reference_vwss" in stages and "vwss_warp" in stages
    assert not any("translucen" in s for s in stages)
    names = {p.name for p in out.iterdir()}
    assert {"msm_soft_artifacts.png", "msm_soft_artifacts.md", "soft_square.png", "errors_square.png"} <= names
    md = (out / "report.md").read_text()
    assert "## Soft shadows under area lights (measured)" in md
    assert "msm_soft_artifacts.png" in md and "soft_square.png" in md
    rm = {x["technique"]: x["rmse"] for x in res["rows"]}
    assert f"msm_soft {rm['msm_soft']:.4g}" in md and f"vwss {rm['vwss']:.4g}" in md  # measured numbers
    assert res["artifacts"] is not None and res["soft"]["square"]


def test_directional_scene_has_no_multiview_work(tmp_path):
    res = report.run(scenes=["three-occluders"], out_dir=tmp_path, techniques=["pcf", "msm64"],
                     resolution=(32, 18), **TINY)
    st = [s["stage"] for s in res["stages"]["three-occluders"]]
    assert st and not any("vwss" in s or "mvr" in s or "scattering" in s for s in st)
    assert {r["technique"] for r in res["rows"]} == {"pcf", "msm64"}
    assert not (tmp_path / "msm_soft_artifacts.png").exists()


def test_soft_statements_state_the_measured_order():
    def rows(values):
        return [{"scene": "k", "technique": t, "rmse": v, "texel_seconds": 1.0, "fragment_seconds": 2.0}
                for t, v in values.items()]

    st = " ".join(report.soft_statements(rows({"msm_soft": 0.02, "pcss": 0.04, "vwss": 0.01}), "k"))
    assert "msm_soft's RMSE is below pcss's (ratio 0.50)" in st
    assert "ranked from lowest: vwss < msm_soft < pcss" in st
    st = " ".join(report.soft_statements(rows({"msm_soft": 0.08, "pcss": 0.04, "vwss": 0.01}), "k"))
    assert "msm_soft's RMSE is above pcss's (ratio 2.00)" in st
    assert report.soft_statements(rows({"msm64": 0.1}), "k") == []


@pytest.fixture(scope="module")
def scattering_report(tmp_path_factory):
    out = tmp_path_factory.mktemp("report_scattering")
    with pytest.MonkeyPatch.context() as mp:
        # The slides' temporal claim runs at its own settings (17 frames, 5 CPU seconds) whenever the
        # shipped scattering scene does; tests/test_scattering_temporal.py tests it, these tests the rows.
        mp.setattr(report.paper_claims, "temporal_scene", lambda names: None)
        res = report.run(scenes=["scattering"], out_dir=out, techniques=list(pipeline.SCATTERING_OUTPUTS),
                         progress=False, shadow_map_size=64, resolution=(32, 18), repeats=1, jobs=1,
                         scattering={"epipolar_size": (32, 64), "reference_samples": 256, "raymarch_samples": 256})
    return out, res


def test_scattering_rows(scattering_report):
    out, res = scattering_report
    rows = {r["technique"]: r for r in res["rows"]}
    assert set(rows) == set(pipeline.SCATTERING_OUTPUTS)
    for r in rows.values():
        assert set(r) == set(report.COLUMNS)
        assert all(math.isfinite(r[c]) for c in ("rmse", "max_error", "p99_error", "leak_fraction"))
        assert r["fragment_seconds"] > 0
    # Ray marching with the reference's own sample count is the reference: zero error.
    assert rows["raymarch"]["rmse"] == 0.0
    assert rows["scattering_6m"]["rmse"] > 0
    assert report.read_results(out / "results.csv")[0].keys() == set(report.COLUMNS)


def test_scattering_stages_and_text(scattering_report):
    out, res = scattering_report
    st = [s["stage"] for s in json.loads((out / "stages.json").read_text())["scattering"]]
    assert {"scattering_raymarch_reference", "scattering_resample_filtered", "scattering_resample_unfiltered",
            "shade_scattering_6m", "scattering_raymarch"} <= set(st)
    assert all(s.startswith(("scattering_", "shade_scattering")) for s in st)
    assert not any("vwss" in s or "translucen" in s for s in st)
    assert (out / "scattering_scattering.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    md = (out / "report.md").read_text()
    assert "normalized by t_max" in md and "ray marching with 256 samples per ray" in md
    assert "scattering_scattering.png" in md
