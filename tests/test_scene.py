"""Tests of moments_ref.scene: generators, OBJ, scene files, shipped scenes cast shadows."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from moments_ref import InputError
from moments_ref.scene.raster import project_points
from moments_ref.scene import (
    GENERATORS,
    AreaLight,
    DirectionalLight,
    Mesh,
    list_scenes,
    load_scene,
    read_obj,
    rotate,
    scale,
    translate,
)
from moments_ref.scene import mesh as mesh_mod

SHIPPED = ["chair", "facade", "knot", "patio", "railing", "scattering", "three-occluders", "translucent"]


def _object_mesh(scene, name):
    i = [k for k, o in enumerate(scene.objects) if o.name == name][0]
    return Mesh(scene.receiver.vertices, scene.receiver.triangles[scene.receiver_object == i])


def _shadowed(scene, receiver, occluders, size=128, n=3000, bias=1e-3):
    """Which random points of object `receiver` lie farther from the light than the depth map
    of `occluders` (object names): the independent check projects the points itself."""
    others = [o.name for o in scene.objects if o.name not in occluders]
    d, _ = scene.shadow_map(size=size, samples=1, exclude=others, translucent=None)
    vp = scene.light_clip_from_world()
    pts, _ = _object_mesh(scene, receiver).sample_points(n, 1)
    xy, z = project_points(pts, vp, size)
    inside = (xy >= 0).all(1) & (xy < size).all(1) & np.isfinite(z)
    r = np.clip(np.floor(xy[:, 1]).astype(int), 0, size - 1)
    c = np.clip(np.floor(xy[:, 0]).astype(int), 0, size - 1)
    return pts, inside & (z > d[r, c, 0] + bias)


def test_list_scenes():
    assert list_scenes() == SHIPPED


@pytest.mark.parametrize("name", [s for s in SHIPPED if s not in ("knot", "chair")])  # area lights
def test_shipped_scene_loads_and_casts_shadow(name):
    s = load_scene(name)
    assert s.name == name and s.receiver.n_triangles > 0 and s.occluder.n_triangles > 0
    assert s.msaa in (1, 4, 8) and len(s.shadow_map_size) == 2 and s.outputs
    assert isinstance(s.light, DirectionalLight)
    # every occluder triangle lies inside the fitted orthographic map (fitted to the scene)
    xy, z = project_points(s.occluder.vertices, s.light_clip_from_world(), 64)
    assert (xy >= 0).all() and (xy <= 64).all() and (np.abs(z) <= 1).all()
    d, st_ = s.shadow_map(size=96, samples=4)
    assert d.shape == (96, 96, 4) and st_.rasterized > 0 and (d < 1).any()
    receivers = [o.name for o in s.objects if o.role in ("receiver", "both")]
    occluders = [o.name for o in s.objects if o.role in ("occluder", "both")]
    total = 0
    for r in receivers:
        _, sh = _shadowed(s, r, [o for o in occluders if o != r])
        total += sh.sum()
        assert sh.mean() < 0.9  # not everything in shadow either
    assert total > 0


def test_railing_scene_figure1():
    s = load_scene("railing")
    # the railing shadows the banner ...
    _, sh = _shadowed(s, "banner", ["railing"], size=256)
    assert sh.mean() > 0.05
    # ... and the banner (hem 0.1 above the ground at z = 0.12) shadows the ground over a
    # short range: shadowed ground points lie within 0.15 of its foot; the whole shadow
    # ends where its top edge (y = 0.9) projects, z = 0.12 + 0.9 · 0.55 ≈ 0.62
    pts, sh = _shadowed(s, "ground", ["banner"], size=256)
    dz = pts[sh, 2] - 0.12
    assert (dz < 0.15).any() and dz.min() > 0 and dz.max() < 0.9 * 0.55 + 0.05


def test_facade_scene_figure8_short_range():
    s = load_scene("facade")
    pts, sh = _shadowed(s, "wall", ["ledge", "sill"], size=256)
    assert sh.sum() > 0
    # Shadows lie just below the protrusions (very short range): within 0.3 below the top
    # of the ledge (y 1.85) or of the sill (y 1.025); the light drops 0.8 per 0.5 of depth,
    # so a 0.12-deep ledge shadows about 0.19 of wall below its bottom.
    y = pts[sh, 1]
    below = np.minimum(np.where(y <= 1.85, 1.85 - y, 9), np.where(y <= 1.025, 1.025 - y, 9))
    assert below.max() < 0.1 + 0.12 * 0.8 / 0.5 + 0.02


def test_three_occluders_scene_figure9_share_a_line():
    s = load_scene("three-occluders")
    x0 = s.params["line_x"]
    for occ in ("roof", "umbrella", "railing"):
        pts, sh = _shadowed(s, "ground", [occ], size=256, n=20000)
        near = np.abs(pts[:, 0] - x0) < 0.3
        assert (sh & near).sum() > 0, occ  # each occluder shadows ground near the line


def test_translucent_scene_flags():
    s = load_scene("translucent")
    assert s.occluder_translucent.any() and not s.occluder_translucent.all()
    assert np.all(s.occluder_opacity[s.occluder_translucent] == 0.5)
    assert np.all(s.occluder_opacity[~s.occluder_translucent] == 1.0)
    opaque = s.occluder_mesh(translucent=False)
    assert opaque.n_triangles == 12  # the box
    pts, sh = _shadowed(s, "ground", ["sheet"])
    assert sh.sum() > 0


def test_knot_scene_low_resolution():
    s = load_scene("knot")
    assert isinstance(s.light, AreaLight)
    assert 100_000 <= s.occluder.n_triangles <= 500_000
    d, st_ = s.shadow_map(size=48, samples=1)
    assert st_.triangles == s.occluder.n_triangles and (d < 1).any()
    pts, sh = _shadowed(s, "ground", ["knot"], size=48)
    assert 0 < sh.mean() < 0.9
    # a view from a corner of the light works too
    vp = s.light_clip_from_world(eye=s.light.corners()[0])
    assert np.isfinite(vp).all()


# ---------------------------------------------------------------------------
# Meshes and transforms


@pytest.mark.parametrize("name", sorted(GENERATORS))
def test_generators_make_valid_meshes(name):
    kw = {"torus_knot": {"segments": 64, "sides": 8}}.get(name, {})
    m = GENERATORS[name](**kw)
    assert m.n_triangles > 0 and np.isfinite(m.vertices).all()
    assert (m.areas() > 0).all()  # no degenerate triangles
    if name in ("box", "cylinder", "railing", "torus_knot"):
        # closed and outward: positive enclosed volume (divergence theorem)
        p = m.vertices[m.triangles]
        vol = np.einsum("ij,ij->i", p[:, 0], np.cross(p[:, 1], p[:, 2])).sum() / 6
        assert vol > 0


def test_box_volume_and_plane_normal():
    m = mesh_mod.box((1.0, 2.0, 3.0))
    p = m.vertices[m.triangles]
    assert np.isclose(np.einsum("ij,ij->i", p[:, 0], np.cross(p[:, 1], p[:, 2])).sum() / 6, 6.0)
    n = mesh_mod.plane(2, 3).face_normals()
    assert (n[:, 1] > 0).all() and np.isclose(mesh_mod.plane(2, 3).areas().sum(), 6.0)


def test_torus_knot_triangle_count():
    m = mesh_mod.torus_knot(segments=100, sides=12)
    assert m.n_triangles == 2 * 100 * 12
    # the tube is closed: every edge is shared by exactly two triangles
    e = np.sort(m.triangles[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    _, cnt = np.unique(e, axis=0, return_counts=True)
    assert (cnt == 2).all()


@given(st.floats(-360, 360), st.lists(st.floats(-2, 2), min_size=3, max_size=3),
       st.lists(st.floats(-5, 5), min_size=3, max_size=3))
@settings(max_examples=40)
def test_transforms_against_definitions(deg, axis, offset):
    axis = np.asarray(axis)
    if np.linalg.norm(axis) < 1e-3:
        return
    r = rotate(axis, deg)[:3, :3]
    np.testing.assert_allclose(r @ r.T, np.eye(3), atol=1e-12)
    assert np.isclose(np.linalg.det(r), 1)
    # the axis is fixed, and a perpendicular vector turns by `deg` (right-hand rule)
    a = axis / np.linalg.norm(axis)
    np.testing.assert_allclose(r @ a, a, atol=1e-12)
    u = np.cross(a, [1.0, 0, 0]) if abs(a[0]) < 0.9 else np.cross(a, [0, 1.0, 0])
    u /= np.linalg.norm(u)
    ru = r @ u
    th = np.radians(deg)
    np.testing.assert_allclose(ru, np.cos(th) * u + np.sin(th) * np.cross(a, u), atol=1e-12)
    m = Mesh(np.eye(3), [[0, 1, 2]])
    moved = m.transformed(translate(offset) @ scale(2.0))
    np.testing.assert_allclose(moved.vertices, 2 * np.eye(3) + offset)


def test_mirror_transform_keeps_outward_winding():
    m = mesh_mod.box()
    mir = m.transformed(scale((-1.0, 1.0, 1.0)))
    p = mir.vertices[mir.triangles]
    assert np.einsum("ij,ij->i", p[:, 0], np.cross(p[:, 1], p[:, 2])).sum() > 0


# ---------------------------------------------------------------------------
# OBJ


def test_obj_round_trip(tmp_path):
    m = mesh_mod.umbrella(segments=7, rings=3)
    lines = ["# written by the test", "o umbrella"]
    lines += [f"v {x!r} {y!r} {z!r}" for x, y, z in m.vertices.tolist()]
    lines += ["vn 0 1 0", "vt 0 0"]
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in m.triangles.tolist()]
    (tmp_path / "u.obj").write_text("\n".join(lines) + "\n")
    back = read_obj(tmp_path / "u.obj")
    np.testing.assert_array_equal(back.vertices, m.vertices)
    np.testing.assert_array_equal(back.triangles, m.triangles)


def test_obj_polygons_negative_indices_and_slashes(tmp_path):
    text = """v 0 0 0
v 1 0 0
v 1 1 0
v 0 1 0
v 0.5 0.5 1 2
f 1/1/1 2/2/2 3/3/3 4/4/4
f -5//1 -4//1 -1//1
"""
    (tmp_path / "q.obj").write_text(text)
    m = read_obj(tmp_path / "q.obj")
    np.testing.assert_array_equal(m.triangles, [[0, 1, 2], [0, 2, 3], [0, 1, 4]])
    np.testing.assert_allclose(m.vertices[4], [0.25, 0.25, 0.5])  # w divides
    assert np.isclose(m.areas()[:2].sum(), 1.0)


@pytest.mark.parametrize("text, match", [
    ("v 0 0 0\nv 1 0 0\nf 1 2 3\n", ":3: vertex index 3 out of range"),
    ("v 0 0\n", ":1: expected 'v x y z"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2\n", ":4: expected a face with at least 3"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 b 3\n", "expected an integer vertex index"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n", "out of range"),
])
def test_obj_errors_name_file_and_line(tmp_path, text, match):
    p = tmp_path / "bad.obj"
    p.write_text(text)
    with pytest.raises(InputError, match=match) as exc:
        read_obj(p)
    assert "bad.obj" in str(exc.value)


# ---------------------------------------------------------------------------
# Scene files


GOOD = """
shadow_map_size = [64, 32]
msaa = 4
outputs = ["msm"]
[light]
type = "directional"
direction = [0, -1, 0.2]
[camera]
eye = [0, 2, 4]
target = [0, 0, 0]
[[objects]]
name = "ground"
generator = "plane"
params = { width = 2, depth = 2 }
role = "receiver"
[[objects]]
name = "mesh"
obj = "tri.obj"
transform = [ { translate = [0, 1, 0] } ]
role = "occluder"
"""


def _write(tmp_path, text):
    (tmp_path / "tri.obj").write_text("v -0.5 0 -0.5\nv 0.5 0 -0.5\nv 0 0 0.5\nf 1 3 2\n")
    p = tmp_path / "s.toml"
    p.write_text(text)
    return p


def test_scene_file_with_obj(tmp_path):
    s = load_scene(_write(tmp_path, GOOD))
    assert s.name == "s" and s.shadow_map_size == (64, 32) and s.msaa == 4 and s.outputs == ("msm",)
    assert s.occluder.n_triangles == 1 and np.allclose(s.occluder.vertices[:, 1], 1.0)
    assert s.camera.resolution == (1280, 720)
    d, _ = s.shadow_map()
    assert d.shape == (64, 32, 4)
    _, sh = _shadowed(s, "ground", ["mesh"], size=64)
    assert sh.sum() > 0


@pytest.mark.parametrize("old, new, key, problem", [
    ('generator = "plane"', 'generator = "plain"', "objects[0].generator", "unknown generator 'plain'"),
    ("[camera]\neye = [0, 2, 4]\ntarget = [0, 0, 0]\n", "", "camera", "missing table"),
    ("msaa = 4", "msaa = 2", "msaa", r"\(1, 4, 8\)"),
    ("msaa = 4", 'msaa = "4"', "msaa", "supported sample counts"),
    ("direction = [0, -1, 0.2]", "direction = [0, -1]", "light.direction", "wrong type"),
    ('type = "directional"', 'type = "spot"', "light.type", "expected 'directional' or 'area'"),
    ('role = "receiver"', 'role = "shadow"', "objects[0].role", "expected one of"),
    ('role = "receiver"', "", "objects[0].role", "missing"),
    ("width = 2,", 'width = "2",', "objects[0].params", "width"),
    ("width = 2,", "widht = 2,", "objects[0].params", "widht"),
    ('obj = "tri.obj"', 'obj = "missing.obj"', "objects[1].obj", "not found"),
    ("shadow_map_size = [64, 32]", "shadow_map_size = 0", "shadow_map_size", "expected an integer"),
    ('outputs = ["msm"]', "outputs = \"msm\"", "outputs", "list of strings"),
    ("eye = [0, 2, 4]", "eye = [0, 0, 0]", "camera", "target"),
    ('role = "occluder"', 'role = "receiver"', "objects", "no object with role occluder"),
    ('role = "occluder"', 'role = "occluder"\ncolour = "red"', "objects[1].colour", "unknown key"),
    ('role = "occluder"', 'role = "occluder"\ntranslucent = true', "objects[1].opacity", "missing"),
    ("{ translate = [0, 1, 0] }", "{ shear = 1 }", "objects[1].transform[0].shear", "unknown transform"),
    ("msaa = 4", "msaa = 4\nmsaa = 1", "", "not valid TOML"),
    ('role = "occluder"', 'role = "occluder"\ntexel_offset = [1, 0]', "objects[1].texel_offset", "3 finite numbers"),
])
def test_bad_scene_files_name_file_key_problem(tmp_path, old, new, key, problem):
    assert old in GOOD
    p = _write(tmp_path, GOOD.replace(old, new, 1))
    with pytest.raises(InputError, match=problem) as exc:
        load_scene(p)
    msg = str(exc.value)
    assert str(p) in msg and key in msg


def test_unknown_scene_lists_known():
    with pytest.raises(InputError) as exc:
        load_scene("no-such-scene")
    for name in SHIPPED:
        assert name in str(exc.value)


def test_area_light_frame():
    light = AreaLight([0, 3, 0], [0, -1, 0], 2.0, 1.0, up=[0, 0, 1])
    c = light.corners()
    assert np.allclose(np.linalg.norm(c[1] - c[0]), 2.0) and np.allclose(np.linalg.norm(c[2] - c[1]), 1.0)
    assert np.allclose((c - light.center) @ light.normal, 0)
    assert np.allclose(np.cross(light.tangent, light.bitangent), light.normal)
    with pytest.raises(InputError, match="up"):
        AreaLight([0, 3, 0], [0, -1, 0], 2.0, 1.0, up=[0, 2, 0])


@pytest.mark.slow
def test_knot_fragments_with_back_face_culling_match_depth_map():
    # VWSS §3.1 point generation: back-face culled fragments of the central view; their
    # per-sample minimum is the depth map rendered with the same culling.
    from moments_ref.scene.raster import rasterize_depth, rasterize_fragments

    s = load_scene("knot")
    vp = s.light_clip_from_world()
    occ = s.occluder
    frags, st_ = rasterize_fragments(occ.vertices, occ.triangles, vp, 128, cull="back")
    d, _ = rasterize_depth(occ.vertices, occ.triangles, vp, 128, cull="back")
    m = np.ones(128 * 128, np.float32)
    np.minimum.at(m, frags.texel, frags.depth)
    np.testing.assert_array_equal(m.reshape(128, 128, 1), d)
    assert st_.culled > 0.3 * occ.n_triangles


def _nearest_texels(scene, size, name, row_point):
    """Texels of the map row through ``row_point`` where object ``name`` is the nearest occluder (rasterized)."""
    others = [o.name for o in scene.objects if o.name != name]
    d_all, _ = scene.shadow_map(size=size, samples=1)
    d_one, _ = scene.shadow_map(size=size, samples=1, exclude=others)
    xy, _ = project_points(np.asarray([row_point, np.add(row_point, [1.0, 0, 0])]), scene.light_clip_from_world(), size)
    r, c = np.floor(xy[0]).astype(int)[::-1]
    assert abs(xy[1, 0] - xy[0, 0]) > abs(xy[1, 1] - xy[0, 1])  # world x runs along the map's rows (reversed)
    mine = (d_one[r, :, 0] < 1) & (d_all[r, :, 0] == d_one[r, :, 0])
    return np.flatnonzero(mine), c


@pytest.mark.parametrize("size", [256, 1024, 2048])
def test_patio_gap_is_four_texels_at_every_map_size(size):
    """HPG17 Figure 9 in texels: the hand rail is the nearest occluder on 4 texels between roof and umbrella.

    Measured on the rasterized map (not the offsets' arithmetic): on the row through the
    ground line, the rail's texels lie between the roof's last and the umbrella's first,
    and a 9x9 footprint centred on a rail texel reaches both.
    """
    sc = load_scene("patio").at_shadow_map(size)
    assert sc.texel_shift == pytest.approx(sc.texel_size(size)) and sc.texel_shift > 0
    rail, c = _nearest_texels(sc, size, "railing", [0.0, 0.5, 0.0])
    roof, _ = _nearest_texels(sc, size, "roof", [0.0, 0.5, 0.0])
    umbrella, _ = _nearest_texels(sc, size, "umbrella", [0.0, 0.5, 0.0])
    near = rail[np.abs(rail - c) <= 8]
    assert 3 <= near.size <= 5 and np.all(np.diff(near) == 1)
    # the rail's neighbours on the row are a roof texel on one side, an umbrella texel on the other
    sides = {near[0] - 1, near[-1] + 1}
    assert len(sides & set(roof)) == 1 and len(sides & set(umbrella)) == 1
    assert near[-1] + 1 - (near[0] - 1) <= 8  # both within ±4 texels of a rail texel


def test_texel_offsets_resolve_per_map_and_need_a_directional_light(tmp_path):
    text = GOOD.replace('role = "occluder"', 'role = "occluder"\ntexel_offset = [2, 0, 0]', 1)
    sc = load_scene(_write(tmp_path, text))
    plain = load_scene(_write(tmp_path, GOOD))
    # loaded: resolved for the scene's own [64, 32] map (the texel is the larger of its two sides)
    t = sc.texel_size()
    assert sc.texel_shift == t and sc.objects[1].texel_offset == (2.0, 0.0, 0.0)
    assert np.allclose(sc.occluder.vertices - plain.occluder.vertices, [2 * t, 0, 0])
    assert np.array_equal(sc.receiver.vertices, plain.receiver.vertices)
    moved = sc.at_shadow_map(256)  # resolving for another map moves by the difference
    assert np.allclose(moved.occluder.vertices - plain.occluder.vertices, [2 * sc.texel_size(256), 0, 0])
    assert np.allclose(moved.at_shadow_map((64, 32)).occluder.vertices, sc.occluder.vertices)
    # the depth map of another size is rasterized with the objects placed for it
    assert np.array_equal(sc.shadow_map(size=256, samples=1)[0], moved.shadow_map(size=256, samples=1)[0])
    assert not np.array_equal(sc.shadow_map(size=256, samples=1)[0], plain.shadow_map(size=256, samples=1)[0])
    assert load_scene("railing").at_shadow_map(64) is not None  # no offsets: the scene itself
    area = text.replace('type = "directional"\ndirection = [0, -1, 0.2]',
                        'type = "area"\ncenter = [0, 3, 0]\nnormal = [0, -1, 0]\nwidth = 1\nheight = 1')
    with pytest.raises(InputError, match=r"objects\[1\]\.texel_offset.*directional"):
        load_scene(_write(tmp_path, area))
