"""VWSS in the paper's setup: the light's near plane (Listing 1), Eq. (3), holes/bloat, the naive source."""

import json

import numpy as np
import pytest

from moments_ref import InputError
from moments_ref.claims import Claim, markdown_table, to_json, verdict_of
from moments_ref.scene import load_scene
from moments_ref.techniques.vwss import center_view, depth_range, light_near, light_views, naive_points, source_view
from moments_ref.report.vwss import coverage_difference
from moments_ref.techniques.vwss.paper import TABLES


def test_light_near_is_the_scene_parameter_and_sets_eq3():
    sc = load_scene("knot")
    zn = light_near(sc)
    assert zn == 0.2
    near, far = depth_range(sc.light, sc.occluder.vertices, sc.receiver.vertices, near=zn)
    assert near == 0.2
    ls = light_views(sc.light, 4, near, far)
    src = source_view(ls, 1024)
    # Eq. (1): 1.2 / (2 tan 45°) = 0.6; Eq. (3): 1024 (0.2 + 0.6) / 0.2 = 4096 per side.
    assert src.distance == pytest.approx(0.6)
    assert src.resolution == 4096
    chair = load_scene("chair")
    assert light_near(chair) == 0.2
    # 1.0 / (2 tan 45°) = 0.5: 1024 (0.2 + 0.5) / 0.2 = 3584
    n, f = depth_range(chair.light, chair.occluder.vertices, chair.receiver.vertices, near=light_near(chair))
    assert source_view(light_views(chair.light, 2, n, f), 1024).resolution == 3584


def test_light_near_refuses_clipping_and_bad_values():
    sc = load_scene("knot")
    with pytest.raises(InputError, match="clips occluder vertex"):
        depth_range(sc.light, sc.occluder.vertices, sc.receiver.vertices, near=2.5)
    with pytest.raises(InputError, match="near"):
        depth_range(sc.light, sc.occluder.vertices, near=-1.0)

    class S:
        params = {"light_near": "far"}
    with pytest.raises(InputError, match="light_near"):
        light_near(S())
    S.params = {}
    assert light_near(S()) is None


def test_naive_points_come_from_the_centre_view():
    sc = load_scene("chair")
    n, f = depth_range(sc.light, sc.occluder.vertices, near=0.2)
    ls = light_views(sc.light, 3, n, f)
    cen = center_view(ls, 64)
    pc = naive_points(sc.occluder.vertices, sc.occluder.triangles, cen)
    assert pc.source.distance == 0.0 and pc.source.resolution == 64
    assert np.allclose(pc.source.eye, sc.light.center)
    assert not pc.layered and len(pc) <= 64 * 64


def test_coverage_difference_counts_by_hand():
    near, far = 1.0, 10.0
    # NDC depth of view distance d: z = ((f + n) - 2 f n / d) / (f - n)
    z = lambda d: ((far + near) - 2 * far * near / d) / (far - near)  # noqa: E731
    r = np.ones((1, 4, 4))
    w = np.ones((1, 4, 4))
    r[0, :2, :2] = z(5.0)          # 4 texels covered by rasterization
    w[0, :2, :2] = z(5.0)
    w[0, 0, 0] = 1.0               # hole: empty in the warped map
    w[0, 0, 1] = z(6.0)            # hole: farther than the bias
    w[0, 1, 0] = z(5.05)           # within the bias: neither
    w[0, 3, 3] = z(4.0)            # bloat: a surface where rasterization has none
    w[0, 1, 1] = z(4.0)            # bloat: nearer than the bias
    d = coverage_difference(w, r, near, far, bias=0.1)
    assert d["holes"].tolist() == [0.5] and d["bloat"].tolist() == [0.5]


def test_paper_tables_match_the_printed_ratios():
    # VWSS Tables 1 and 2 as printed: 24 maps 0.41-0.65, 128 maps 0.19-0.35 (VWSS/PCSS RMSE)
    r24 = [v[0] / v[1] for v in TABLES[24].values()]
    r128 = [v[0] / v[1] for v in TABLES[128].values()]
    assert min(r24) == pytest.approx(0.407, abs=1e-3) and max(r24) == pytest.approx(0.654, abs=1e-3)
    assert min(r128) == pytest.approx(0.195, abs=1e-3) and max(r128) == pytest.approx(0.349, abs=1e-3)
    assert [v[2] for v in TABLES[24].values()] == [2.15, 3.67, 5.04, 3.73]


def test_claim_records_json_and_markdown():
    c = Claim(id="x-1", source="HPG17 §5", statement="s", paper="16 pixels > 3 %", measured={"a": np.float32(2.5),
              "b": float("nan"), "c": np.arange(2)}, settings={"k": 1}, verdict="holds", why="w")
    out = json.loads(to_json([c]))
    assert out == [{"id": "x-1", "source": "HPG17 §5", "statement": "s", "paper": "16 pixels > 3 %",
                    "measured": {"a": 2.5, "b": None, "c": [0, 1]}, "settings": {"k": 1}, "verdict": "holds",
                    "why": "w"}]
    assert "| `x-1` |" in markdown_table([c])
    with pytest.raises(InputError, match="verdict"):
        Claim(id="y", source="", statement="", paper="", verdict="maybe")
    with pytest.raises(InputError, match="unique"):
        to_json([c, c])
    assert [verdict_of(v) for v in (True, False, None)] == ["holds", "does not hold", "not measurable here"]
