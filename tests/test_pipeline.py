"""The lazy runner: stage sets per scene, sharing, refusals."""

import dataclasses
import time

import numpy as np
import pytest

from moments_ref import InputError, pipeline
from moments_ref import techniques as T
from moments_ref.scene import load_scene

SMALL = dict(shadow_map_size=48, resolution=(40, 24))


def _run(scene, outputs, area=None, **kw):
    over = {"area": area} if area is not None else None
    return pipeline.run(load_scene(scene), outputs, pipeline.Settings(**{**SMALL, **kw}, overrides=over))


def test_railing_stages_share_resolve_and_blur():
    r = _run("railing", ["msm64", "msm128", "vsm"])
    assert r.stages.count("resolve_moments") == 1 and r.stages.count("blur_moments") == 1
    assert {"raster_shadow_map", "camera_gbuffer", "light_projection", "quantize_affine64", "store_float128",
            "quantize_vsm32", "shade_msm64", "shade_msm128", "shade_vsm"} <= set(r.stages)
    assert not any("translucen" in s or "vwss" in s or "bluenoise" in s or "onchip" in s for s in r.stages)
    # Shared stages count in each technique's texel cost.
    assert r.texel_seconds["msm64"] >= r.seconds["blur_moments"]


def test_clock_chooses_the_timer(monkeypatch):
    # clock="cpu" times each stage with time.process_time: a fake one that ticks 1 per
    # reading makes every timed stage last exactly 1 s; an unknown clock is refused.
    import itertools

    ticks = itertools.count()
    monkeypatch.setattr(time, "process_time", lambda: float(next(ticks)))
    r = _run("facade", ["msm128"], clock="cpu", repeats=2)
    assert r.times and all(set(t) == {1.0} for t in r.times.values()), r.times  # 1 s per timed run
    assert r.times["shade_msm128"] == [1.0, 1.0]  # a cost stage: its 2 timed repeats
    assert r.fragment_seconds["msm128"] == 1.0
    with pytest.raises(InputError, match="clock: expected one of wall, cpu, got 'gpu'"):
        _run("facade", ["msm128"], clock="gpu")


def test_without_warmup_each_cost_stage_runs_repeats_times():
    from moments_ref.techniques import get

    calls = []
    lookup = get("msm128").lookup

    def counting(*a):
        calls.append(1)
        return lookup(*a)

    t = dataclasses.replace(get("msm128"), name="msm128_counted", lookup=counting)
    sc = load_scene("facade")
    for warmup, repeats, runs in ((True, 1, 2), (False, 1, 1), (False, 3, 3), (True, 2, 3)):
        calls.clear()
        r = pipeline.run(sc, [t], pipeline.Settings(**SMALL, warmup=warmup, repeats=repeats, reference=False))
        assert len(calls) == runs and len(r.times["shade_msm128_counted"]) == repeats, (warmup, repeats)


def test_knot_one_sample_map_has_no_resolve_and_no_multiview():
    r = _run("knot", ["msm128", "nlq64"], msaa=1)
    assert "compute_moments" in r.stages and "onchip_blur" in r.stages
    assert not any("resolve" in s for s in r.stages)
    assert not any("vwss" in s or "translucen" in s for s in r.stages)


def test_translucent_scene_runs_translucency_pass_only_there():
    r = _run("translucent", ["translucent_msm", "nlq64_dither"], noise_tiles=1)  # 1 tile: 0.1 s, not 6
    assert "translucency_pass" in r.stages
    assert {"translucency_blend_moments", "translucency_blur_moments", "translucency_quantize_affine64"} <= set(r.stages)
    assert {"bluenoise_textures", "frame_noise"} <= set(r.stages)
    assert any(s.startswith("translucency_reference") for s in r.stages)
    # Without translucent geometry: no translucency work, and translucent_msm is refused with the reason.
    r2 = _run("facade", ["msm64", "pcf"])
    assert not any("translucen" in s for s in r2.stages)
    with pytest.raises(InputError, match="has none"):
        _run("facade", ["translucent_msm"])


def test_dithered_only_with_noise_and_shared_texture():
    r = _run("three-occluders", ["nlq64", "nlq64_dither"], noise_tiles=1)
    assert r.stages.count("quantize_nlq64") == 1
    assert "bluenoise_textures" in r.stages
    assert "bluenoise_textures" not in _run("three-occluders", ["nlq64"]).stages


def test_knot_scene_outputs_run_with_multiview_stages_named_vwss():
    """knot asks for msm_soft, pcss, vwss and mvr: multi-view stages, all named vwss; msm_soft/PCSS on one map."""
    area = {"reference_views": 3, "light_samples": 3}
    r0 = _run("knot", None, area=area)
    assert r0.techniques == ["msm_soft", "pcss", "vwss", "mvr"]
    assert r0.stages.count("area_center_depth_map") == 1 and "raster_shadow_map" not in r0.stages
    r = _run("knot", ["vwss", "mvr"], area=area)
    assert {"vwss_points", "vwss_warp", "shade_vwss", "mvr_vwss", "mvr_reference_vwss"} <= set(r.stages)
    assert not any(s.startswith(("raster_shadow_map", "area_center")) for s in r.stages)  # nothing unasked
    r2 = _run("knot", ["msm_soft", "pcss", "msm64"], area=area)
    assert not any("vwss" in s for s in r2.stages if s != "mvr_reference_vwss")
    assert {"area_center_depth_map", "msm_soft_sat", "shade_msm_soft", "shade_pcss", "raster_shadow_map"} <= set(r2.stages)
    assert r2.stages.count("area_center_depth_map") == 1  # shared by msm_soft and PCSS
    # msm64 keeps its hard-shadow reference (the spot at the light's centre), the soft rows MVR.
    assert "reference_pcf_bias0.001" in r2.stages
    np.testing.assert_array_equal(r2.reference["msm_soft"], r2.reference["pcss"])
    assert r2.area["reference_views"] == 3 and r2.area["map_size"] == 48
    r3 = _run("knot", ["vwss"], area=area, reference=False)
    assert "mvr_reference_vwss" not in r3.stages and r3.reference == {}


def test_scattering_stage_names_follow_the_technique_steps():
    from moments_ref.techniques.scattering import SCATTERING_6M

    st = pipeline.scattering_stages(4)
    assert st[:3] == ["scattering_raster_shadow_map", "scattering_camera_rays", "scattering_raymarch_reference"]
    assert [("scattering_" + s.name).replace("scattering_scattering_", "scattering_")
            for s in SCATTERING_6M.steps(4)] == st[3:3 + len(SCATTERING_6M.steps(4))]
    assert "scattering_compute_moments" in pipeline.scattering_stages(1)
    assert not any("vwss" in s or "translucen" in s for s in st)


def test_without_reference_no_reference_stage():
    r = _run("facade", ["msm128"], reference=False)
    assert not any("reference" in s for s in r.stages)
    assert r.reference == {}


def test_pcf_row_loses_the_references_contact_shadows_and_errors_are_small_for_msm128():
    """PCF's receiver-slope bias moves its test depth below the receiver plane: it only loses shadow
    against the receiver-plane reference (measured here: never more shadow, mean 0.08 less)."""
    r = _run("facade", ["pcf", "msm128"])
    lost = r.reference["pcf"] - r.shadow["pcf"]
    assert lost.min() > -0.02 and lost.mean() > 0.02
    assert r.gbuffer.pixel.size > 100
    assert np.sqrt(np.mean((r.shadow["msm128"] - r.reference["msm128"]) ** 2)) < 0.1


def test_stage_plan_without_running():
    rp = pipeline.plan(load_scene("railing"), ["nlq32_dither"], pipeline.Settings(**SMALL))
    order = rp.graph.order(rp.targets)
    assert order[-1] in rp.targets and "bluenoise_textures" in order
    t = rp.techniques["nlq32_dither"]
    assert t.shade == "shade_nlq32_dither" and t.truth == "pcf" and t.bits == 32 and t.result == "intensity"
    assert set(t.texel) < set(order) and rp.context.size == (48, 48) and rp.context.resolution == (40, 24)


def test_the_old_keywords_and_the_meta_triple_still_work_with_a_warning():
    sc = load_scene("railing")
    with pytest.warns(DeprecationWarning, match="Settings"):
        rp = pipeline.plan(sc, ["pcf"], shadow_map_size=48, resolution=(40, 24), given={"msaa": None})
    assert rp.context.size == (48, 48)
    with pytest.warns(DeprecationWarning, match="graph, targets, meta"):
        g, targets, meta = rp
    assert meta["info"]["pcf"]["shade"] == "shade_pcf" and meta["size"] == (48, 48)
    with pytest.warns(DeprecationWarning), pytest.raises(InputError, match="scattering: unknown settings"):
        pipeline.plan(load_scene("scattering"), ["scattering_6m"], settings={"scattering": {"typo": 1}})
    with pytest.raises(TypeError, match="unexpected keyword"):
        pipeline.plan(sc, ["pcf"], shadow_map=48)


def test_the_depth_gbuffer_serves_only_techniques_that_shade_world_positions():
    sc = load_scene("knot")
    st = pipeline.Settings(shadow_map_size=32, resolution=(32, 18), gbuffer="depth",
                           overrides={"area": {"light_samples": 2, "reference_views": 2}})
    with pytest.raises(InputError, match="looks its texture up"):
        pipeline.plan(sc, ["msm64"], st)
    rp = pipeline.plan(sc, ["vwss", "pcss"], st)
    assert rp.context.receivers == "camera_depth_gbuffer"
    assert "light_projection" not in rp.graph.order(rp.targets)
    with pytest.raises(InputError, match="gbuffer"):
        pipeline.plan(sc, ["vwss"], st.replace(gbuffer="pixels"))


def test_unknown_output_lists_known():
    with pytest.raises(InputError, match="known techniques: pcf"):
        _run("railing", ["msm_soft_typo"])


def test_scene_without_receiver_or_camera_refused(tmp_path):
    p = tmp_path / "nor.toml"
    p.write_text('[light]\ntype = "directional"\ndirection = [0, -1, 0]\n[camera]\neye = [0, 2, 3]\n'
                 'target = [0, 0, 0]\n[[objects]]\nname = "b"\ngenerator = "box"\nrole = "occluder"\n')
    with pytest.raises(InputError, match="receiver"):
        pipeline.run(str(p), ["pcf"])
    p2 = tmp_path / "nocam.toml"
    p2.write_text('[light]\ntype = "directional"\ndirection = [0, -1, 0]\n[[objects]]\nname = "g"\n'
                  'generator = "plane"\nrole = "receiver"\n')
    with pytest.raises(InputError, match="camera"):
        pipeline.run(str(p2), ["pcf"])
    s = load_scene("facade")
    with pytest.raises(InputError, match="no receiver"):
        pipeline.check_scene(dataclasses.replace(s, receiver=s.occluder_mesh(exclude=[o.name for o in s.objects])))
    with pytest.raises(InputError, match="no camera"):
        pipeline.check_scene(dataclasses.replace(s, camera=None))


def test_multiview_technique_needs_area_light():
    t = T.Technique(name="test_multiview", bits_per_texel=0, depth_bias=0.0, make_steps=lambda s, l: (),
                    lookup=lambda tex, uv, zf, noise: np.zeros(zf.shape), multiview=True, light_kinds=("area",))
    T.register(t)
    try:
        with pytest.raises(InputError, match="area"):
            _run("railing", ["test_multiview"])
    finally:
        T.TECHNIQUES.pop("test_multiview", None)


def test_receiver_slope_is_the_depth_change_per_texel():
    """Plane z = a·x seen through the identity projection into a 100² map: 50 texels per unit."""
    from moments_ref.scene.gbuffer import _depth_slope, _plane_gradient

    rng = np.random.default_rng(0)
    for a in (0.0, 0.3, -2.0):
        p = rng.uniform(-0.5, 0.5, (20, 3))
        p[:, 2] = a * p[:, 0]
        n = np.tile(np.array([-a, 0.0, 1.0]) / np.hypot(a, 1.0), (20, 1))
        slope = _depth_slope(_plane_gradient(p, n, np.eye(4), (100, 100)))
        np.testing.assert_allclose(slope, abs(a) / 50, atol=1e-9)



def test_receiver_gradient_is_the_signed_depth_change_per_texel():
    """Plane z = a·x + b·y through the identity projection into a 100² map: (a/50, −b/50) (v runs down)."""
    from moments_ref.scene.gbuffer import _depth_gradient, _plane_gradient

    rng = np.random.default_rng(0)
    for a, b in ((0.0, 0.0), (0.3, -0.7), (-2.0, 0.4)):
        p = rng.uniform(-0.5, 0.5, (20, 3))
        p[:, 2] = a * p[:, 0] + b * p[:, 1]
        n = np.tile(np.array([-a, -b, 1.0]) / np.linalg.norm([a, b, 1.0]), (20, 1))
        np.testing.assert_allclose(_depth_gradient(_plane_gradient(p, n, np.eye(4), (100, 100))),
                                   np.tile([a / 50, -b / 50], (20, 1)), atol=1e-9)

TILTED = """
name = "tilted"
shadow_map_size = 256
msaa = 1
outputs = ["pcf"]
[light]
type = "directional"
direction = [0.0, -1.0, 0.0]
[camera]
eye = [0.0, 3.0, 3.0]
target = [0.0, 0.0, 0.0]
fov = 40
resolution = [96, 54]
[[objects]]
name = "slope"
generator = "plane"
params = { width = 2.0, depth = 2.0 }
transform = [ { rotate = { axis = [1, 0, 0], degrees = 60 } } ]
role = "both"
[[objects]]
name = "pebble"
generator = "box"
params = { size = [0.05, 0.05, 0.05] }
transform = [ { translate = [3.0, 3.0, 3.0] } ]
role = "occluder"
"""


def test_lit_plane_is_unshadowed_by_reference_and_slope_biased_pcf(tmp_path):
    """A plane in the shadow map (role both) lit at 60°: lit in the receiver-plane reference and in PCF;
    one unbiased depth for the whole 9×9 footprint self-shadows it."""
    from moments_ref.techniques.pcf import pcf_filtered

    path = tmp_path / "tilted.toml"
    path.write_text(TILTED)
    r = pipeline.run(str(path), ["pcf"])
    gb, maps = r.values["light_projection"], r.values["raster_shadow_map"]
    assert r.reference["pcf"].max() == 0.0  # receiver-plane depth: exact on the plane
    assert r.shadow["pcf"].max() < 0.02  # PCF's receiver-slope bias
    acne = pcf_filtered(maps, gb.uv, gb.z_ndc_light - 1e-3)
    assert np.median(acne) > 0.3  # surface acne: about half of the footprint lies in front


def test_depth_bias_is_the_papers_slope_for_pcf_constant_for_filterable(tmp_path):
    """HPG17 §5: PCF adds the receiver-slope bias, filterable techniques use 1e-3 alone; the reference the
    receiver plane and 1e-3."""
    from moments_ref.scene.gbuffer import SLOPE_BIAS_TEXELS
    from moments_ref.techniques.pcf import pcf_filtered

    path = tmp_path / "tilted.toml"
    path.write_text(TILTED)
    r = pipeline.run(str(path), ["pcf", "msm128", "vsm"])
    gb, maps = r.values["light_projection"], r.values["raster_shadow_map"]
    assert gb.slope.min() > 0  # the plane is tilted against the light: the two setups differ
    slope_biased = gb.z_ndc_light - SLOPE_BIAS_TEXELS * gb.slope - 1e-3
    np.testing.assert_array_equal(r.reference["pcf"], pcf_filtered(maps, gb.uv, gb.z_ndc_light - 1e-3, gradient=gb.gradient))
    np.testing.assert_array_equal(r.shadow["pcf"], pcf_filtered(maps, gb.uv, slope_biased))
    for name in ("msm128", "vsm"):
        t = T.get(name)
        tex = r.values[t.steps(r.msaa)[-1].name]
        np.testing.assert_array_equal(r.shadow[name], t.shadow(tex, gb.uv, gb.z_ndc_light))  # constant bias only
    # power: on this plane lit at 60° MSM128 self-shadows a little at the constant bias (measured median 0.14)
    # and not with the slope bias, so the two setups are told apart
    assert np.median(r.shadow["msm128"]) > 0.05 > r.shadow["pcf"].max()
    text = T.references.depth_bias_text()
    assert "PCF (pcf)" in text and "(vsm, esm," in text and "only the constant 0.001" in text


def test_graph_shares_equal_stages_and_refuses_a_different_step_under_one_key():
    from moments_ref.techniques import Stage, stage_key

    g = pipeline.graph.StageGraph()
    assert g.add(Stage("zeros", np.zeros, params=(("shape", 3),))) == "zeros_shape3" == stage_key("zeros", {"shape": 3})
    assert g.add(Stage("zeros", np.zeros, params=(("shape", 3),))) == "zeros_shape3"  # equal: shared
    assert g.add(Stage("zeros", np.zeros, params=(("shape", 4),))) == "zeros_shape4"  # a parameter: its own key
    with pytest.raises(ValueError, match="added twice with different steps"):
        g.add(Stage("zeros", np.ones, params=(("shape", 3),)))

    def make(value):
        return lambda: value

    g.add(Stage("const", make(1.0)))
    g.add(Stage("const", make(1.0)))  # same code, equal captured value: the same step
    with pytest.raises(ValueError, match="different steps"):
        g.add(Stage("const", make(2.0)))
    with pytest.raises(ValueError, match="different steps"):
        g.add(Stage("zeros", np.zeros, deps=("const",), params=(("shape", 3),)))
    order, values, _ = g.run(["zeros_shape4"])
    assert order == ["zeros_shape4"] and values["zeros_shape4"].shape == (4,)


def test_reference_stage_keys_carry_the_bias():
    rp = pipeline.plan(load_scene("railing"), ["pcf", "msm64", "nlq64"], pipeline.Settings(**SMALL))
    g = rp.graph
    refs = {t.reference for t in rp.techniques.values()}
    assert refs == {"reference_pcf_bias0.001"}  # one bias, one shared reference stage
    assert g.nodes["reference_pcf_bias0.001"].params == (("bias", 1e-3),)


def test_a_given_camera_gbuffer_replaces_the_rendered_one_with_the_same_results(monkeypatch):
    """Settings.camera_gbuffer (the G-buffer check_shaded rendered): the run does not render it again and
    its results are the bytes of a run that renders it; one of another resolution is refused."""
    from moments_ref.pipeline import planner
    from moments_ref.scene.gbuffer import camera_gbuffer, check_shaded

    sc = load_scene("facade")
    st = pipeline.Settings(**SMALL)
    ctx_scene = pipeline.plan(sc, ["pcf", "msm128"], st).context.scene
    assert ctx_scene is sc  # no texel offsets: the run's scene is the checked one
    rendered = pipeline.run(sc, ["pcf", "msm128"], st)
    given = check_shaded(sc, SMALL["resolution"], sc.light_clip_from_world(), (48, 48))
    fresh = camera_gbuffer(sc, SMALL["resolution"])
    for f in dataclasses.fields(fresh):
        a, b = getattr(given, f.name), getattr(fresh, f.name)
        assert (a is None and b is None) or np.array_equal(np.asarray(a), np.asarray(b)), f.name

    def no_render(*a, **k):
        raise AssertionError("the camera G-buffer was rendered again")

    monkeypatch.setattr(planner, "camera_gbuffer", no_render)
    r = pipeline.run(sc, ["pcf", "msm128"], st.replace(camera_gbuffer=given))
    assert r.values["camera_gbuffer"] is given
    for name in ("pcf", "msm128"):
        assert r.shadow[name].tobytes() == rendered.shadow[name].tobytes()
        assert r.reference[name].tobytes() == rendered.reference[name].tobytes()
    with pytest.raises(InputError, match="camera_gbuffer: expected the camera G-buffer of the run's resolution"):
        pipeline.plan(sc, ["pcf"], st.replace(resolution=(40, 25), camera_gbuffer=given))
