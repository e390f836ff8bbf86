"""HPG17 claims from the pipeline's arrays (moments_ref.report.paper_claims)."""

import json

import numpy as np
import pytest

from moments_ref.report import paper_claims
from moments_ref import pipeline
from moments_ref.moments import BIAS_FLOAT32, bias_moments
from moments_ref.msm import shadow_intensity
from moments_ref.nonlinear import shade
from moments_ref.packing import unpack64
from moments_ref.scene import load_scene


@pytest.fixture(scope="module")
def railing():
    sc = load_scene("railing")
    return pipeline.run(sc, ["evsm64", "evsm128", "msm64", "msm128", "nlq64", "nlq32"], pipeline.Settings(shadow_map_size=128, msaa=1, resolution=(96, 54)))


def test_pixel_statistic_is_nearest_neighbour_msm128_against_nlq64(railing):
    st = paper_claims.pixel_statistic(railing)
    gb = railing.gbuffer
    r, c = np.floor(gb.uv[:, 1]).astype(int), np.floor(gb.uv[:, 0]).astype(int)
    zf = (gb.z_ndc_light - 1e-3).astype(np.float32)
    # Independently of the technique lookups: the texel's moments and its 64-bit code.
    tex_m = railing.values["store_float128"]
    tex_n = railing.values["quantize_nlq64"]
    a = shadow_intensity(bias_moments(tex_m[r, c].astype(np.float32), BIAS_FLOAT32), zf)
    b = shade(unpack64(tex_n[r, c], dtype=np.float32), zf)
    d = np.abs(a.astype(np.float64) - b)
    assert st["above_3pct"] == int((d > 0.03).sum()) and st["above_10pct"] == int((d >= 0.10).sum())
    assert st["max"] == pytest.approx(float(d.max()), abs=1e-6)
    assert st["receiver_pixels"] == d.size and st["image_pixels"] == 96 * 54
    assert len(st["worst"]) == 5 and st["worst"][0]["nlq64"] == pytest.approx(float(b[np.argmax(d)]), abs=1e-6)


def test_claims_only_for_scenes_that_ran(railing):
    from moments_ref.report import metrics

    rows = [{"scene": "railing", "technique": n, **metrics(railing.shadow[n], railing.reference[n])}
            for n in railing.techniques]
    measured = {"railing": paper_claims.scene_measurements(railing)}
    text, md = paper_claims.gather(rows, measured, "# report\n")
    ids = [c["id"] for c in json.loads(text)]
    assert ids == ["hpg17-nlq64-vs-msm128-pixels", "hpg17-evsm128-leaks-less", "hpg17-nlq64-close-to-msm128",
                   "hpg17-nlq32-close-to-nlq64"]  # no three-occluders claim: that scene did not run
    assert md.startswith("# report") and "## Paper claims" in md and all(f"`{i}`" in md for i in ids)
    # a run of facade alone says nothing about railing or three-occluders
    facade_rows = [dict(r, scene="facade") for r in rows]
    assert json.loads(paper_claims.gather(facade_rows, {}, "")[0]) == []


def test_three_occluder_claim_counts_footprint_depths():
    # a fake result: one fully shadowed pixel whose 9x9 footprint holds three occluder depths
    class G:
        uv = np.array([[10.5, 10.5], [30.5, 30.5]])
        z_ndc_light = np.array([0.9, 0.9])
        slope = np.zeros(2)  # a receiver facing the light: no slope bias

    maps = np.ones((40, 40, 1), np.float32)
    maps[:, :12] = -0.5
    maps[:, 12:] = 0.0
    maps[:11, :] = 0.3
    maps[25:, 25:] = -0.2  # second pixel: one depth only in its footprint

    class R:
        values = {"raster_shadow_map": maps}
        gbuffer = G()

    n = paper_claims._occluder_layers(R(), np.array([True, True]))
    assert n.tolist() == [3, 1]


def test_claims_name_rows_of_the_implementation_choices_table(railing):
    """Every choice a claim depends on is a row of docs/formats.md's table, and the table has its eight rows."""
    import re
    from pathlib import Path

    from moments_ref.report import metrics

    doc = (Path(__file__).parent.parent / "docs" / "formats.md").read_text(encoding="utf-8")
    section = doc.split("## Implementation-defined choices", 1)[1].split("\n## ", 1)[0]
    rows = [m.group(1).strip() for m in re.finditer(r"^\| ([^|]+) \|", section, re.M)]
    rows = [r for r in rows if r not in ("choice",) and not set(r) <= set("-")]
    assert rows == ["clamp offsets", "decode positions", "code rounding", "bias presets and targets",
                    "depth convention", "10-bit fold edge rows", "sub-texel precision of bilinear filtering",
                    "blur edge handling"]
    named = {c for cs in paper_claims.IMPLEMENTATION_CHOICES.values() for c in cs}
    assert named <= set(rows)
    results = [{"scene": "railing", "technique": n, **metrics(railing.shadow[n], railing.reference[n])}
               for n in railing.techniques]
    claims = json.loads(paper_claims.gather(results, {"railing": paper_claims.scene_measurements(railing)}, "")[0])
    nlq32 = next(c for c in claims if c["id"] == "hpg17-nlq32-close-to-nlq64")
    assert "decode positions" in nlq32["settings"]["implementation_choices"]
    assert all(c["settings"]["implementation_choices"] for c in claims)
