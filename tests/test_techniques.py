"""Techniques against their definitions on small synthetic maps (brute force, hand formulas, bounds)."""

import math

import numpy as np
import pytest
from hypothesis import assume, example, given, settings
from hypothesis import strategies as st

from moments_ref import InputError
from moments_ref import techniques as T
from moments_ref.gpu.filtering import blur, gaussian_weights
from moments_ref.scene.raster import orthographic, rasterize_fragments
from moments_ref.techniques.esm import esm_feature, esm_shadow
from moments_ref.techniques.evsm import evsm_feature, evsm_shadow
from moments_ref.techniques.pcf import pcf_filtered
from moments_ref.techniques.translucent import translucency_pass
from moments_ref.techniques.vsm import VSM_MIN_VARIANCE, cantelli_shadow


def _brute_pcf(z, u, v, zf, layers=None):
    """Literal loop: bilinear footprint (clamped), 9×9 Gaussian taps (clamped), mean over samples."""
    H, W, S = z.shape[:3]
    g = gaussian_weights()

    def footprint(c, n):
        s = c - 0.5
        b = math.floor(s)
        f = s - b
        return [(min(max(b, 0), n - 1), 1 - f), (min(max(b + 1, 0), n - 1), f)]

    total = 0.0
    for bx, wx in footprint(u, W):
        for by, wy in footprint(v, H):
            for dy in range(-4, 5):
                for dx in range(-4, 5):
                    row = min(max(by + dy, 0), H - 1)
                    col = min(max(bx + dx, 0), W - 1)
                    w = wx * wy * g[dy + 4] * g[dx + 4]
                    if layers is None:
                        occ = np.mean(z[row, col] < zf)
                    else:
                        occ = np.mean([1 - np.prod([1 - a for d, a in layers[row][col][s] if d < zf])
                                       for s in range(S)])
                    total += w * occ
    return total


def test_pcf_equals_brute_force_loop():
    rng = np.random.default_rng(1)
    z = rng.uniform(-1, 1, (7, 6, 4)).astype(np.float32)
    uv = np.array([[0.1, 0.2], [3.3, 2.7], [5.99, 6.9], [2.5, 3.5], [-1.0, 8.0]])
    zf = np.array([0.0, 0.3, -0.5, 0.9, 0.1])
    got = pcf_filtered(z, uv, zf)
    want = [_brute_pcf(z, u, v, f) for (u, v), f in zip(uv, zf)]
    np.testing.assert_allclose(got, want, atol=1e-12)
    # Power: a shifted depth changes the answer.
    assert np.abs(pcf_filtered(z, uv, zf + 0.2) - want).max() > 1e-3


@given(st.sampled_from([1, 2, 4, 8]), st.integers(0, 2**32 - 1))
def test_pcf_sample_share_is_the_mean_bit_for_bit(S, seed):
    # PCF counts a tap's occluding samples as the set bits of one word (S = 1, 2, 4, 8);
    # it must equal the mean of the booleans exactly. Against a plain loop over the samples.
    from moments_ref.techniques.pcf import _share

    test = np.random.default_rng(seed).random((5, 3, S)) < 0.5
    got = _share(test)
    want = np.zeros(test.shape[:-1])
    for s in range(S):  # loop over samples: the exact count of true ones, then / S
        want += test[..., s]
    want /= S
    assert got.dtype == np.float64 and got.tobytes() == want.tobytes()


def test_pcf_sample_share_falls_back_to_the_mean(monkeypatch):
    # S = 3, 16 or a strided array take NumPy's mean, not the bit count.
    from moments_ref.techniques import pcf

    monkeypatch.setattr(pcf.np, "bitwise_count", None, raising=True)  # would raise if it were used
    for test in (np.ones((4, 3), bool), np.ones((2, 16), bool), np.ones((3, 8), bool)[:, ::2]):
        got = pcf._share(test)
        assert got.dtype == np.float64 and got.tobytes() == test.mean(axis=-1).tobytes()


@settings(deadline=None)
@given(u=st.floats(-2, 10), v=st.floats(-2, 9), zf=st.floats(-1, 1))
def test_pcf_is_bilinear_fetch_of_blurred_tests(u, v, zf):
    """Z(z < zf) with the same weights as a filterable texture: blur the per-texel test, fetch bilinearly."""
    rng = np.random.default_rng(7)
    z = rng.uniform(-1, 1, (7, 8, 4))
    occ = blur((z < zf).mean(axis=2)[..., None])
    want = T.bilinear_filtered(occ, np.array([u, v]), np.float64)[0]
    assert pcf_filtered(z, np.array([u, v]), zf) == pytest.approx(want, abs=1e-12)


def _translucent_setup():
    """An opaque quad at depth ~0.6 and two overlapping translucent quads at ~-0.2 and ~0.2 (ortho)."""
    vp = orthographic(-1, 1, -1, 1, -1, 1)  # NDC z = -view z; view z = world z (identity view)

    def quad(x0, x1, y0, y1, z):
        v = np.array([[x0, y0, z], [x1, y0, z], [x1, y1, z], [x0, y1, z]], float)
        return v, np.array([[0, 1, 2], [0, 2, 3]])

    vo, to = quad(-0.5, 0.9, -0.9, 0.9, -0.6)
    va, ta = quad(-0.9, 0.3, -0.7, 0.6, 0.2)
    vb, tb = quad(-0.2, 0.8, -0.4, 0.8, -0.2)
    from moments_ref.scene.raster import rasterize_depth

    opaque, _ = rasterize_depth(vo, to, vp, (8, 8), samples=4)
    vt = np.concatenate([va, vb])
    tt = np.concatenate([ta, tb + 4])
    alpha = np.array([0.5, 0.5, 0.3, 0.3])
    return opaque, vt, tt, alpha, vp


def test_translucency_pass_equals_sequential_alpha_blending():
    """Slides: blend α·b(z) + (1 − α)·dst far to near, one fragment at a time, equals the layers' moments."""
    opaque, vt, tt, alpha, vp = _translucent_setup()
    layers = translucency_pass(opaque, vt, tt, alpha, vp)
    np.testing.assert_allclose(layers.weight.sum(-1), 1.0, atol=1e-12)
    frags, _ = rasterize_fragments(vt, tt, vp, (8, 8), samples=4)
    H, W, S = opaque.shape

    def b(z):
        return np.array([z, z**2, z**3, z**4])

    moments = (layers.weight[..., None] * np.moveaxis(b(layers.depth.astype(np.float64)), 0, -1)).sum(axis=3)
    for texel in range(H * W):
        for s in range(S):
            row, col = divmod(texel, W)
            dst = b(float(opaque[row, col, s]))
            sel = (frags.texel == texel) & (frags.sample == s) & (frags.depth < opaque[row, col, s])
            order = np.argsort(-frags.depth[sel])  # far to near
            for d, a in zip(frags.depth[sel][order], alpha[frags.triangle[sel]][order]):
                dst = a * b(float(d)) + (1 - a) * dst
            np.testing.assert_allclose(moments[row, col, s], dst, atol=1e-6)


def test_translucent_reference_is_product_of_transmittances():
    opaque, vt, tt, alpha, vp = _translucent_setup()
    layers = translucency_pass(opaque, vt, tt, alpha, vp)
    frags, _ = rasterize_fragments(vt, tt, vp, (8, 8), samples=4)
    H, W, S = opaque.shape
    # Independent per-sample list of (depth, opacity), opaque surface with opacity 1.
    lists = [[[[(float(opaque[r, c, s]), 1.0)] for s in range(S)] for c in range(W)] for r in range(H)]
    for t, s, d, tri in zip(frags.texel, frags.sample, frags.depth, frags.triangle):
        r, c = divmod(int(t), W)
        if d < opaque[r, c, s]:
            lists[r][c][s].append((float(d), float(alpha[tri])))
    uv = np.array([[1.2, 3.7], [4.5, 4.5], [6.1, 2.2]])
    for zf in (-0.5, 0.0, 0.5, 0.7):
        got = pcf_filtered(layers, uv, zf)
        want = [_brute_pcf(opaque, u, v, zf, layers=lists) for u, v in uv]
        np.testing.assert_allclose(got, want, atol=1e-9)


def test_translucent_msm_follows_the_transmittance_and_msm64_does_not():
    """One translucent sheet (α = 0.5) over an empty map: a two-point distribution, exact for MSM."""
    _, vt, tt, alpha, vp = _translucent_setup()
    opaque = np.ones((32, 32, 4), np.float32)
    layers = translucency_pass(opaque, vt[:4], tt[:2], alpha[:2], vp)
    uv = np.array([[11.2, 16.8], [17.5, 9.1], [26.0, 4.0]])
    zf = np.full(3, 0.9)
    ref = pcf_filtered(layers, uv, zf - 1e-3)
    assert ref[0] == pytest.approx(0.5, abs=1e-9)  # inside the sheet: 1 − (1 − α)
    tm = T.get("translucent_msm")
    got = tm.shadow(tm.prepare(layers), uv, zf)
    np.testing.assert_allclose(got, ref, atol=0.02)
    opaque_only = T.get("msm64").shadow(T.get("msm64").prepare(opaque), uv, zf)
    assert np.abs(opaque_only - ref).max() > 0.4  # ignoring the sheet is measurably wrong


def test_vsm_equals_cantelli_by_hand():
    rng = np.random.default_rng(3)
    z = np.where(rng.random((12, 12, 4)) < 0.5, -0.4, 0.3).astype(np.float32)
    vsm = T.get("vsm")
    tex = vsm.prepare(z)
    assert tex.dtype == np.uint16 and tex.shape == (12, 12, 2)
    # Filtered moments of d = (z + 1)/2 straight from the definition.
    d = (z.astype(np.float64) + 1) / 2
    md = blur(np.stack([d.mean(2), (d * d).mean(2)], axis=-1))
    np.testing.assert_allclose(tex / 65535.0, md, atol=1 / 65535)
    for (row, col), zf in (((5, 6), 0.0), ((3, 3), 0.5), ((8, 2), -0.45)):
        m1, m2 = tex[row, col] / 65535.0
        t = ((zf - 1e-3) + 1) / 2
        var = max(m2 - m1 * m1, VSM_MIN_VARIANCE)
        want = (t - m1) ** 2 / (var + (t - m1) ** 2) if t > m1 else 0.0
        got = vsm.shadow(tex, np.array([col + 0.5, row + 0.5]), zf)
        assert float(got) == pytest.approx(want, abs=2e-5)


dists = st.lists(st.tuples(st.floats(-1, 1), st.floats(0.01, 1)), min_size=1, max_size=6)


@settings(deadline=None)
@given(d=dists, zf=st.floats(-1, 1))
@example(d=[(0.0, 0.75), (-1.860193499512739e-09, 1.0)], zf=0.0)
def test_cantelli_esm_evsm_are_lower_bounds(d, zf):
    z = np.array([x for x, _ in d])
    # A depth under 1e-150 squares below float64's normal range: the test's own moments w @ z**2 then lose it
    # (the thorough profile drew −8.1e-232 and −1.7e-259), so the moments are not those of the distribution judged.
    # The bound's behaviour there is the test below. And all the mass at zf (within 1e-9): with no minimum variance
    # the bounds are steps at the mean, which the moments' rounding puts an ulp on either side of zf (the thorough
    # profile drew three depths −0.0234375 at zf, and three at 0 for EVSM, both bounds 1 against Z = 0).
    assume(np.all((z == 0) | (np.abs(z) > 1e-150)) and np.max(np.abs(z - zf)) > 1e-9)
    w = np.array([y for _, y in d])
    w /= w.sum()
    exact = w[z < zf].sum()
    if _resolved(z, w, 1e-9):
        assert cantelli_shadow(w @ z, w @ z**2, zf, 0.0) <= exact + 1e-9
    for c in (5.5, 40.0, 80.0):
        assert esm_shadow(w @ esm_feature(z, c)[:, 0], zf, c) <= exact + 1e-9
    x = evsm_feature(z, 40.0, 5.5)
    if _resolved(x[:, 0], w, 1e-6) and _resolved(x[:, 2], w, 1e-6):
        assert evsm_shadow(w @ x, zf, 40.0, 5.5) <= exact + 1e-6


def _resolved(x, w, tol):
    """Whether float64 moments ``(w @ x, w @ x**2)`` fix the Cantelli bound ``σ²/(σ² + (t − μ)²)`` to within ``tol``.

    The bound is a lower bound of Z for the exact moments; its σ² = E[x²] − E[x]² from moments rounded to
    float64 (sums of at most six terms) is off by up to about 8 eps E[x²], which moves the bound by up to
    2 eps E[x²]/σ² (its derivative in σ² is at most 1/(4σ²)); μ's error moves it by far less. So the test asks
    for the bound only where that is under half its tolerance. The thorough profile drew depths 0 and −1.9e-9
    with zf = 0: EVSM's positive warp maps them to 1 and 1 − 7.4e-8, a variance of 1.4e-15 against E[x²] = 1,
    and the bound from the rounded moments rose 0.0043 above Z.
    """
    var = w @ (x - w @ x) ** 2
    return var > 4 * float(np.finfo(np.float64).eps) * (w @ x**2) / tol


def test_cantelli_at_zero_variance_is_the_step_even_where_the_distance_squared_underflows():
    """σ² = 0: the bound d²/(σ² + d²) is 1 for every d > 0, also where d² underflows to 0 (d < 1e-162 in float64,
    1e-23 in float32); 0 for d ≤ 0."""
    for dt, tiny in ((np.float64, 1e-200), (np.float32, 1e-30)):
        mean = np.array([-tiny, -1e-3, 0.0, tiny], dt)
        with np.errstate(under="ignore"):
            got = cantelli_shadow(mean, mean * mean, dt(0), dt(0))
        assert got.dtype == dt and got.tolist() == [1.0, 1.0, 0.0, 0.0]


@settings(deadline=None)
@given(occ=st.lists(st.floats(0.0, 0.3), min_size=1, max_size=4), w_occ=st.floats(0.05, 0.95))
def test_evsm_approaches_esm_and_the_exact_shadow_as_c_grows(occ, w_occ):
    """Depths Δ ∈ [0.1, 0.4] in front of zf = 0.4 or at zf: both → Z(z < zf) = w_occ, errors O(exp(−cΔ))."""
    zf = 0.4
    z = np.array(occ + [zf])
    w = np.r_[np.full(len(occ), w_occ / len(occ)), 1 - w_occ]
    errs = []
    for c in (5.5, 40.0, 200.0):
        e = esm_shadow(w @ esm_feature(z, c)[:, 0], zf, c)
        v = evsm_shadow(w @ evsm_feature(z, c, 5.5), zf, c, 5.5)
        errs.append((abs(e - w_occ), abs(v - w_occ), abs(v - e)))
    assert errs[-1][0] < 1e-6 and errs[-1][1] < 1e-6 and errs[-1][2] < 1e-6
    assert errs[0][0] > 1e-3  # at c = 5.5 ESM leaks measurably (≥ 0.05·exp(−2.2))


def _two_depth_map(n=24, occluder=-0.3, seed=0):
    """Texels either at the occluder depth or empty (1): every filter region holds a two-point distribution."""
    rng = np.random.default_rng(seed)
    mask = np.zeros((n, n, 4), bool)
    mask[6:18, 5:14] = True
    mask[..., 1] &= rng.random((n, n)) < 0.8
    return np.where(mask, occluder, 1.0).astype(np.float32)


@pytest.mark.parametrize("name,tol", [("msm128", 2e-3), ("msm64", 2e-2), ("nlq64", 2e-2), ("nlq32", 3e-2)])
def test_two_point_regions_are_exact_against_pcf(name, tol):
    """One occluder depth and the far plane per filter region: a two-point distribution, for which
    Algorithm 1's lower bound is exact (B(b) singular), up to the bias α and the quantization."""
    z = _two_depth_map()
    t = T.get(name)
    rng = np.random.default_rng(5)
    uv = rng.uniform(2, 22, (300, 2))
    zf = np.full(300, 0.5)
    ref = T.get("pcf").shadow(z, uv, zf)
    got = t.shadow(t.prepare(z), uv, zf)
    assert got.shape == ref.shape
    assert np.abs(got - ref).max() < tol
    assert (ref > 0.5).mean() > 0.1  # the test covers shadowed pixels


def test_vsm_bleeds_light_on_two_point_regions():
    """Cantelli's bound is not exact when the receiver lies in front of the far depth: VSM leaks (HPG17 Fig. 1)."""
    z = _two_depth_map()
    rng = np.random.default_rng(5)
    uv = rng.uniform(2, 22, (300, 2))
    zf = np.full(300, 0.5)
    ref = T.get("pcf").shadow(z, uv, zf)
    got = T.get("vsm").shadow(T.get("vsm").prepare(z), uv, zf)
    assert np.all(got <= ref + 1e-3)
    assert (ref - got).max() > 0.2


def test_three_occluders_make_four_moments_leak():
    """HPG17 §5: three occluder depths in a filter region, receiver behind: the lower bound leaks."""
    rng = np.random.default_rng(2)
    z = np.choose(rng.integers(0, 4, (24, 24, 4)), [-0.8, -0.1, 0.5, 1.0]).astype(np.float32)
    uv = rng.uniform(4, 20, (200, 2))
    zf = np.full(200, 0.9)
    ref = T.get("pcf").shadow(z, uv, zf)
    got = T.get("msm128").shadow(T.get("msm128").prepare(z), uv, zf)
    assert np.all(got <= ref + 1e-3)
    assert (ref - got).max() > 0.05


def test_nlq_texture_is_filter_and_quantize():
    from moments_ref.gpu.onchip import filter_and_quantize

    z = _two_depth_map(40, seed=3)
    for fmt in ("nlq64", "nlq32"):
        np.testing.assert_array_equal(T.get(fmt).prepare(z), filter_and_quantize(z, fmt))
        np.testing.assert_array_equal(T.get(fmt + "_dither").prepare(z), filter_and_quantize(z, fmt))


def test_dithered_average_equals_bilinear():
    """HPG17 §4.2: over uniform noise the dithered fetch has the bilinear weights."""
    z = _two_depth_map()
    t = T.get("nlq64_dither")
    tex = t.prepare(z)
    uv = np.array([[9.3, 11.8], [13.6, 6.2]])
    zf = np.array([0.5, 0.5])
    k = (np.arange(32) + 0.5) / 32
    noise = np.stack(np.meshgrid(k, k), axis=-1).reshape(-1, 1, 2)
    dithered = t.shadow(tex, np.broadcast_to(uv, (1024, 2, 2)), np.broadcast_to(zf, (1024, 2)), noise=noise)
    bilinear = T.get("nlq64").shadow(tex, uv, zf)
    np.testing.assert_allclose(dithered.mean(axis=0), bilinear, atol=2e-3)


def test_every_technique_states_bits_and_bias():
    bits = {"pcf": 32, "vsm": 32, "esm": 32, "evsm64": 64, "evsm128": 128, "msm64": 64, "msm128": 128,
            "nlq64": 64, "nlq32": 32, "nlq64_dither": 64, "nlq32_dither": 32, "translucent_msm": 64}
    for name, b in bits.items():
        t = T.get(name)
        assert t.bits_per_texel == b
        assert t.depth_bias == 1e-3  # HPG17 §5 for NLQ, the same for all
    assert [n for n in T.names() if T.get(n).needs_noise] == ["nlq64_dither", "nlq32_dither"]


def test_texture_storage_formats():
    z = _two_depth_map(16)
    assert T.get("evsm64").prepare(z).dtype == np.float16
    assert T.get("evsm128").prepare(z).dtype == np.float32
    assert T.get("msm64").prepare(z).dtype == np.uint16
    assert T.get("nlq32").prepare(z).dtype == np.uint32
    # evsm64's exponent keeps (x+)² below float16's maximum.
    assert np.isfinite(T.get("evsm64").prepare(np.full((4, 4, 1), 1.0, np.float32))).all()


def test_unknown_technique_lists_known_ones():
    with pytest.raises(InputError, match="known techniques: pcf, vsm"):
        T.get("msm96")


def test_register_hook_and_duplicate_refused():
    t = T.Technique(name="test_constant", bits_per_texel=0, depth_bias=0.0, make_steps=lambda s, l: (),
                    lookup=lambda tex, uv, zf, noise: np.zeros(zf.shape))
    try:
        T.register(t)
        assert "test_constant" in T.names()
        assert T.get("test_constant").shadow(np.zeros((2, 2, 1)), [[0.5, 0.5]], [0.0]).shape == (1,)
        with pytest.raises(InputError, match="already registered"):
            T.register(T.Technique(**{**t.__dict__}))
    finally:
        T.TECHNIQUES.pop("test_constant", None)


def test_bad_inputs():
    z = _two_depth_map(8)
    with pytest.raises(InputError, match="noise"):
        T.get("nlq64_dither").shadow(T.get("nlq64").prepare(z), [[1.0, 1.0]], [0.0])
    opaque, vt, tt, alpha, vp = _translucent_setup()
    with pytest.raises(InputError, match="translucent"):
        T.get("msm128").prepare(translucency_pass(opaque, vt, tt, alpha, vp))
    with pytest.raises(InputError, match="depth_samples"):
        T.get("vsm").prepare(np.full((4, 4, 1), 2.0))
    with pytest.raises(InputError, match="uv"):
        T.get("pcf").shadow(z, [[1.0, 2.0, 3.0]], [0.0])
    with pytest.raises(InputError, match="opacity"):
        translucency_pass(opaque, vt, tt, np.zeros(4), vp)


def test_float32_shading_dtype():
    z = _two_depth_map(16)
    for name in ("vsm", "esm", "evsm64", "msm64", "msm128", "nlq64", "nlq32"):
        t = T.get(name)
        assert t.shadow(t.prepare(z), [[3.0, 4.0]], [0.5]).dtype == np.float32
    assert T.get("pcf").shadow(z, [[3.0, 4.0]], [0.5]).dtype == np.float64


def test_every_shadow_names_the_depth_space_it_takes():
    """``Technique.shadow``'s depth argument is named by its space: ``z_ndc_light`` (the shadow-map
    techniques) or ``z_epipolar`` (the scattering techniques); ``depth=`` still works, warning."""
    import inspect

    from moments_ref.techniques.scattering import SCATTERING_TECHNIQUES

    techs = {**T.TECHNIQUES, **SCATTERING_TECHNIQUES}
    for name, t in techs.items():
        third = list(inspect.signature(t.shadow).parameters)[2]
        assert third == t.depth_space, name
    assert {t.depth_space for t in techs.values()} == {"z_ndc_light", "z_epipolar"}
    assert all(t.depth_space == "z_epipolar" for t in SCATTERING_TECHNIQUES.values())
    pcf = T.get("pcf")
    z = np.zeros((4, 4, 1), np.float32)
    with pytest.warns(DeprecationWarning, match=r"shadow\(depth=...\) is now shadow\(z_ndc_light=...\)"):
        old = pcf.shadow(z, [[1.0, 1.0]], depth=[0.5])
    assert old == pcf.shadow(z, [[1.0, 1.0]], z_ndc_light=[0.5])
    with pytest.raises(InputError, match="z_ndc_light"):
        pcf.shadow(z, [[1.0, 1.0]], ["a"])


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_bilinear_filtered_fetches_the_footprints_texels(dtype):
    """Each result is the einsum of the bilinear weights with the four texels fetched one by one in plain Python
    (clamped to the edge), for strided textures, 1 to 4 channels, points outside and a batch shape."""
    from moments_ref.gpu.bluenoise import bilinear_footprint

    rng = np.random.default_rng(3)
    for c in (1, 3, 4):
        tex = rng.random((9, 7, c)).astype(np.float32).transpose(1, 0, 2)[::-1]  # (7, 9, c), not contiguous
        uv = rng.uniform(-2, 11, (2, 5, 2)).astype(dtype)
        got = T.bilinear_filtered(tex, uv, dtype)
        rows, cols, w = bilinear_footprint(uv, tex.shape)
        assert got.shape == (2, 5, c) and got.dtype == dtype
        for i in range(2):
            for j in range(5):
                texels = np.array([[float(tex[rows[i, j, k], cols[i, j, k], ch]) for ch in range(c)] for k in range(4)],
                                  dtype)
                want = np.einsum("k,kc->c", w[i, j].astype(dtype), texels)
                assert np.array_equal(got[i, j], want), (c, i, j)
