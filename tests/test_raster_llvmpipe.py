"""The rasterizer against Mesa's llvmpipe, sample for sample, and against brute force on a small map.

Mid-size triangles (about 150 pixels, the bench's mid case) and long thin ones (railing-like
slivers, hundreds of pixels long and a pixel or two wide) are drawn by both rasterizers into
the same multisampled depth buffer. Vertices lie on the 1/256-pixel grid in float32, so
llvmpipe's float32 viewport transform and our float64 one snap them to the same points: the
coverage must then agree at every sample (same sample pattern, same fill rule), and the depth
within llvmpipe's float32 plane evaluation and its 24-bit depth buffer.

Needs moderngl with EGL (skipped without it, a failure under ``CI=true``, as the conformance
tests). The brute-force test needs nothing: every sample's coverage by the three edge
functions in Python integers, and its depth from the plane solved in exact rationals.
"""

from __future__ import annotations

import os
from fractions import Fraction

import numpy as np
import pytest

from moments_ref.scene.raster import rasterize_depth
from moments_ref.scene.raster._matrices import _D3D11_PATTERN

_VERTEX = "#version 330\nin vec4 p;\nvoid main() { gl_Position = p; }\n"
_FRAGMENT = "#version 330\nvoid main() {}\n"
_QUAD = "#version 330\nin vec2 q;\nvoid main() { gl_Position = vec4(q, 0.0, 1.0); }\n"
# Every sample of the multisampled depth texture, one per colour channel.
_READ = """#version 330
uniform {sampler} depth;
out vec4 colour;
void main() {{
    ivec2 p = ivec2(gl_FragCoord.xy);
    colour = vec4(1.0);
    for (int s = 0; s < {samples}; ++s) colour[s] = texelFetch(depth, p, s).r;
}}
"""


def _gl():
    moderngl = pytest.importorskip("moderngl")
    try:
        return moderngl, moderngl.create_standalone_context(backend="egl", require=330)
    except Exception as exc:  # moderngl raises plain Exception subclasses for EGL failures
        if os.environ.get("CI", "").lower() == "true":
            pytest.fail(f"CI=true but an EGL context is missing: {exc}")
        pytest.skip(f"no EGL context: {exc}")


def _llvmpipe_depth(v_ndc, tris, size, samples):
    """llvmpipe's depth per sample, (size, size, samples) NDC depth, our row order (row 0 at the top)."""
    moderngl, ctx = _gl()
    if "llvmpipe" not in ctx.info.get("GL_RENDERER", ""):
        ctx.release()
        pytest.skip(f"the EGL renderer is {ctx.info.get('GL_RENDERER')!r}, not llvmpipe")
    try:
        # y negated: GL's window y runs up from row 0, ours down from row 0, so with -y the
        # framebuffer's row r is our row r and the sample offsets point the same way.
        clip = np.c_[v_ndc[:, 0], -v_ndc[:, 1], v_ndc[:, 2], np.ones(len(v_ndc))].astype(np.float32)
        prog = ctx.program(vertex_shader=_VERTEX, fragment_shader=_FRAGMENT)
        vao = ctx.vertex_array(prog, [(ctx.buffer(clip.tobytes()), "4f", "p")],
                               index_buffer=ctx.buffer(np.asarray(tris, np.uint32).tobytes()), index_element_size=4)
        depth = ctx.depth_texture((size, size), samples=samples if samples > 1 else 0)
        fbo = ctx.framebuffer(depth_attachment=depth)
        fbo.use()
        ctx.enable(moderngl.DEPTH_TEST)
        ctx.depth_func = "<"
        fbo.clear(depth=1.0)
        vao.render(moderngl.TRIANGLES)
        ctx.disable(moderngl.DEPTH_TEST)
        sampler = "sampler2DMS" if samples > 1 else "sampler2D"
        read = ctx.program(vertex_shader=_QUAD, fragment_shader=_READ.format(sampler=sampler, samples=samples))
        quad = np.array([-1, -1, 1, -1, -1, 1, -1, 1, 1, -1, 1, 1], np.float32)
        qvao = ctx.vertex_array(read, [(ctx.buffer(quad.tobytes()), "2f", "q")])
        out = ctx.texture((size, size), 4, dtype="f4")
        ofbo = ctx.framebuffer(color_attachments=[out])
        ofbo.use()
        depth.use(location=0)
        read["depth"] = 0
        qvao.render(moderngl.TRIANGLES)
        win = np.frombuffer(ofbo.read(components=4, dtype="f4"), np.float32).reshape(size, size, 4)
        return 2.0 * win[..., :samples].astype(np.float64) - 1.0  # window depth [0, 1] -> NDC
    finally:
        ctx.release()


def _on_grid(rng, centre, offsets, size):
    """NDC vertices at ``centre + offsets`` (pixels), rounded to the 1/256-pixel grid (exact in float32)."""
    win = np.round((centre + offsets) * 256) / 256
    ndc = win / size * 2 - 1
    z = rng.uniform(-0.9, 0.9, (win.shape[0], 1, 1)) + rng.uniform(-0.05, 0.05, (win.shape[0], 3, 1))
    return np.concatenate([ndc, z], axis=-1).reshape(-1, 3)


def _slivers(rng, n, size, length, width):
    """n long thin triangles (``length`` and ``width`` ranges in pixels) inside the map, on the grid."""
    a = rng.uniform(0, 2 * np.pi, n)
    d = np.stack([np.cos(a), np.sin(a)], -1) * rng.uniform(*length, n)[:, None]
    nrm = np.stack([-np.sin(a), np.cos(a)], -1) * rng.uniform(*width, n)[:, None]
    off = np.stack([np.zeros_like(d), d, d / 2 + nrm], 1)
    # Start where the whole sliver lies inside the map.
    lo, hi = -off.min(axis=1), size - off.max(axis=1)
    return _on_grid(rng, rng.uniform(lo, hi)[:, None], off, size)


def _mid_and_thin(seed, size):
    """Mid-size triangles (vertices within 21 px of a centre, about 150 px) and long thin slivers (60 to 240 px
    long, 0.3 to 2.5 px wide), all inside the map: llvmpipe clips geometry beyond the viewport, and its
    clipped vertices (float32) would leave the grid."""
    rng = np.random.default_rng(seed)
    n_mid = 300
    mid = _on_grid(rng, rng.uniform(21, size - 21, (n_mid, 1, 2)), rng.uniform(-21, 21, (n_mid, 3, 2)), size)
    v = np.concatenate([mid, _slivers(rng, 200, size, (60, 240), (0.3, 2.5))])
    return v, np.arange(len(v)).reshape(-1, 3)


@pytest.mark.parametrize("samples", [1, 4])
def test_tile_path_matches_llvmpipe_sample_for_sample(monkeypatch, samples):
    # Every triangle whose box allows it drawn tile by tile (scene/raster/_tiles.py; by default
    # only large ones are), the same scene against llvmpipe and against the span path.
    from moments_ref.scene import raster

    size = 256
    v, t = _mid_and_thin(7 + samples, size)
    ref = _llvmpipe_depth(v, t, size, samples)
    monkeypatch.setattr(raster._tiles, "TILE_MIN_BOX", 1)
    monkeypatch.setattr(raster._tiles, "TILE_MIN_INRADIUS", 0.0)
    got, stats = rasterize_depth(v, t, np.eye(4), size, samples=samples)
    covered_gl, covered = ref < 1, got < 1
    bad = np.argwhere(covered_gl != covered)
    assert bad.size == 0, f"{len(bad)} samples differ in coverage, first (row, col, sample) {bad[0].tolist()}"
    np.testing.assert_allclose(got[covered], ref[covered], rtol=0, atol=2e-6)
    monkeypatch.setattr(raster, "_TILES", False)
    spans, stats_spans = rasterize_depth(v, t, np.eye(4), size, samples=samples)
    assert got.tobytes() == spans.tobytes() and stats == stats_spans


@pytest.mark.parametrize("samples", [1, 4])
def test_mid_size_and_long_thin_triangles_match_llvmpipe_sample_for_sample(samples):
    size = 256
    v, t = _mid_and_thin(7 + samples, size)
    ref = _llvmpipe_depth(v, t, size, samples)
    got, stats = rasterize_depth(v, t, np.eye(4), size, samples=samples)
    covered_gl, covered = ref < 1, got < 1
    assert stats.rasterized == t.shape[0] and covered.mean() > 0.2
    # Coverage: the same samples, every one (a sample on an edge decided by the same rule).
    bad = np.argwhere(covered_gl != covered)
    assert bad.size == 0, f"{len(bad)} samples differ in coverage, first (row, col, sample) {bad[0].tolist()}"
    # Depth: llvmpipe interpolates in float32 and stores 24 bits (steps of 2^-23 in NDC).
    np.testing.assert_allclose(got[covered], ref[covered], rtol=0, atol=2e-6)


def test_sample_pattern_and_fill_rule_are_llvmpipes_on_edges_through_samples():
    # Edges through sample positions: vertices on the sample grid itself, so ties of the fill
    # rule are everywhere (two triangles of a shared diagonal, horizontal and vertical edges).
    size, samples = 32, 4
    rng = np.random.default_rng(3)
    n = 200
    pat = np.asarray(_D3D11_PATTERN[samples], np.float64) / 16
    pick = rng.integers(0, samples, (n, 3))
    win = rng.integers(0, size, (n, 3, 2)) + 0.5 + pat[pick]
    win[: n // 4, 1, 1] = win[: n // 4, 0, 1]  # horizontal edges
    win[n // 4: n // 2, 2, 0] = win[n // 4: n // 2, 0, 0]  # vertical edges
    ndc = win / size * 2 - 1
    z = rng.uniform(-0.9, 0.9, (n, 3, 1))
    v = np.concatenate([ndc, z], -1).reshape(-1, 3)
    t = np.arange(3 * n).reshape(n, 3)
    for k in range(n):  # one triangle at a time: every sample of it, not just the nearest
        ref = _llvmpipe_depth(v, t[k:k + 1], size, samples)
        got, _ = rasterize_depth(v, t[k:k + 1], np.eye(4), size, samples=samples)
        assert np.array_equal(ref < 1, got < 1), (k, win[k].tolist())
        if k >= 40:
            break


def _brute_force(v_ndc, tris, size, samples):
    """Depth per sample by definition: snapped vertices, the three edge functions with the top-left
    rule in Python integers at every sample, the plane through the vertices in exact rationals."""
    pat = [(int(a) * 16, int(b) * 16) for a, b in _D3D11_PATTERN[samples]]
    X = [int(x) for x in np.rint((v_ndc[:, 0] + 1) * size / 2 * 256)]
    Y = [int(y) for y in np.rint((1 - v_ndc[:, 1]) * size / 2 * 256)]
    depth = np.ones((size, size, samples))
    for i0, i1, i2 in tris.tolist():
        P = [(X[i], Y[i], Fraction(float(v_ndc[i, 2]))) for i in (i0, i1, i2)]
        area = (P[1][0] - P[0][0]) * (P[2][1] - P[0][1]) - (P[1][1] - P[0][1]) * (P[2][0] - P[0][0])
        if area == 0:
            continue
        if area < 0:
            P = [P[0], P[2], P[1]]
            area = -area
        edges = []
        for e in range(3):
            (ax, ay, _), (bx, by, _) = P[e], P[(e + 1) % 3]
            dx, dy = bx - ax, by - ay
            top_left = dy < 0 or (dy == 0 and dx > 0)
            edges.append((dx, dy, ax, ay, top_left))
        for r in range(size):
            for c in range(size):
                for s, (ox, oy) in enumerate(pat):
                    x, y = c * 256 + 128 + ox, r * 256 + 128 + oy
                    E = [dx * (y - ay) - dy * (x - ax) for dx, dy, ax, ay, _ in edges]
                    if all(e > 0 or (e == 0 and tl) for e, (*_, tl) in zip(E, edges)):
                        # Barycentrics: edge e is opposite vertex e + 2.
                        z = (E[1] * P[0][2] + E[2] * P[1][2] + E[0] * P[2][2]) / area
                        if -1 <= z <= 1:
                            depth[r, c, s] = min(depth[r, c, s], float(z))
    return depth


@pytest.mark.parametrize("samples", [1, 4])
def test_mid_size_and_long_thin_triangles_match_brute_force_on_a_small_map(samples):
    # Coverage exact; depth within float64 rounding of the exact plane (the map stores float32
    # in both, so a float64 rounding can move a float32 value by one step at most).
    size = 24
    rng = np.random.default_rng(samples)
    mid = _on_grid(rng, rng.uniform(4, size - 4, (12, 1, 2)), rng.uniform(-5, 5, (12, 3, 2)), size)
    v = np.concatenate([mid, _slivers(rng, 12, size, (10, 22), (0.3, 1.5))])
    t = np.arange(len(v)).reshape(-1, 3)
    want = _brute_force(v, t, size, samples)
    got, _ = rasterize_depth(v, t, np.eye(4), size, samples=samples, dtype=np.float64)
    assert np.array_equal(got < 1, want < 1)
    assert (got < 1).mean() > 0.2
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-12)
