"""Block-wise emulation of the HPG17 §4.1 compute shader against the global reference."""

import dataclasses

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from moments_ref import InputError
from moments_ref.gpu import banks
from moments_ref.gpu.filtering import blur, resolve_moments
from moments_ref.gpu.onchip import block_grid, filter_and_quantize, filter_moments, tolerance


def random_depths(h, w, s, seed=0, dtype=np.float32):
    return np.random.default_rng(seed).uniform(-1, 1, (h, w, s)).astype(dtype)


def assert_matches_reference(z):
    got = filter_moments(z)
    assert got.dtype == np.float32 and got.shape == z.shape[:2] + (4,)
    ref = blur(resolve_moments(z))
    err = np.abs(got - ref).max()
    assert err <= tolerance(z.shape[2]), err
    return got, ref


@pytest.mark.parametrize(
    "shape",
    [
        (50, 77, 4),  # neither side a multiple of the block: partial blocks on the right and bottom
        (50, 77, 1),  # no MSAA
        (48, 64, 4),  # exact multiple: 2×2 blocks
        (24, 32, 2),  # exactly one block
        (1, 1, 1),  # one texel: every tap clamps to it
        (3, 100, 4),  # thinner than the guard band
        (97, 5, 3),
    ],
)
def test_filter_moments_equals_resolve_then_blur(shape):
    got, ref = assert_matches_reference(random_depths(*shape))
    # Borders included: the first and last rows and columns are inside the bound.
    for edge in (got[0], got[-1], got[:, 0], got[:, -1]):
        assert np.isfinite(edge).all()


def test_float64_input_is_filtered_in_float32():
    z = random_depths(30, 41, 4, seed=3, dtype=np.float64)
    got = filter_moments(z)
    assert got.dtype == np.float32
    assert np.abs(got - blur(resolve_moments(z))).max() <= tolerance(4)


@given(
    st.tuples(st.integers(1, 60), st.integers(1, 70), st.integers(1, 4)).flatmap(
        lambda s: hnp.arrays(np.float32, s, elements=st.floats(-1, 1, width=32))
    )
)
def test_filter_moments_within_tolerance_for_any_map(z):
    assert_matches_reference(z)


@given(st.integers(1, 7), st.sampled_from(["paper", "row-major"]))
def test_result_independent_of_batching_and_layout(batch, layout):
    z = random_depths(50, 77, 2, seed=5)
    base = filter_moments(z)
    assert np.array_equal(filter_moments(z, blocks_per_batch=batch, layout=layout), base)


@given(st.integers(0, 49), st.integers(0, 76))
def test_one_texel_influences_exactly_its_9x9_window(y, x):
    # Independent check of the block coverage and guard band: changing one input
    # texel must change the output exactly where the 9×9 kernel reaches it, also
    # across block boundaries (a missing guard band would leave a gap).
    z = np.zeros((50, 77, 1), dtype=np.float32)
    z2 = z.copy()
    z2[y, x, 0] = 1
    diff = np.abs(filter_moments(z2) - filter_moments(z)).max(axis=-1) > 0
    yy, xx = np.indices(diff.shape)
    assert np.array_equal(diff, (np.abs(yy - y) <= 4) & (np.abs(xx - x) <= 4))


@pytest.mark.parametrize("layout", ["paper", "row-major"])
def test_resolve_and_readout_touch_each_word_once(layout):
    """The premise of the emulation's single gather and scatter per phase: the resolve's
    5 rounds × 4 moments write distinct words, and the readout's 3 rows × 4 moments of
    all threads read distinct words (each texel's moment is stored once)."""
    pattern = banks.access_pattern()
    for phase in ("resolve", "readout"):
        p = pattern[phase]
        words = banks.shared_index(p.j, p.x, p.y, layout)
        assert np.unique(words).size == words.size == 4 * len(np.unique(p.texel_y * banks.BLOCK_IN[0] + p.texel_x))


def test_block_grid():
    assert block_grid(50, 77) == (3, 3)
    assert block_grid(48, 64) == (2, 2)
    assert block_grid(1, 1) == (1, 1)
    assert block_grid(2048, 2048) == (86, 64)


def test_timings_are_reported_per_stage():
    t = {}
    filter_moments(random_depths(30, 40, 2), timings=t)
    assert set(t) == {"resolve", "horizontal", "vertical", "readout"}
    assert all(v >= 0 for v in t.values())


def test_tolerance_has_power_against_a_mutated_access_pattern(monkeypatch):
    # Mutant: the left-half warps of the horizontal pass write their 16 results
    # rotated by one column (x -> x + 1 mod 16), away from where the vertical pass
    # and the readout expect them. The emulation must miss the reference by far
    # more than the tolerance.
    original = banks.access_pattern

    def mutated():
        p = original()
        hw = p["horizontal write"]
        p["horizontal write"] = dataclasses.replace(hw, x=np.where(hw.x < 16, (hw.x + 1) % 16, hw.x))
        return p

    z = random_depths(50, 77, 4, seed=7)
    ref = blur(resolve_moments(z))
    monkeypatch.setattr(banks, "access_pattern", mutated)
    assert np.abs(filter_moments(z) - ref).max() > 100 * tolerance(4)


def test_tolerance_has_power_against_a_wrong_border_rule():
    # A reference with zero padding instead of clamp-to-edge differs at the border
    # by far more than the tolerance: the comparison checks the border rule.
    from scipy import ndimage

    from moments_ref.gpu.filtering import gaussian_weights

    z = np.full((30, 40, 1), 0.5, dtype=np.float32)
    b = resolve_moments(z).astype(np.float64)
    w = gaussian_weights()
    zero_pad = ndimage.correlate1d(ndimage.correlate1d(b, w, axis=1, mode="constant"), w, axis=0, mode="constant")
    assert np.abs(filter_moments(z) - zero_pad).max() > 100 * tolerance(1)


def test_bad_input():
    with pytest.raises(InputError, match=r"\(0, 1, 0\)"):
        filter_moments(np.array([[[0.0], [1.5]]]))
    with pytest.raises(InputError, match="fmt"):
        filter_and_quantize(np.zeros((2, 2, 1)), "rgba8")
    with pytest.raises(InputError, match="blocks_per_batch"):
        filter_moments(np.zeros((2, 2, 1)), blocks_per_batch=0)
    with pytest.raises(InputError, match="layout"):
        filter_moments(np.zeros((2, 2, 1)), layout="z-order")


# ---------------------------------------------------------------- texture formats


def smooth_depths(h=40, w=70, s=4, seed=11):
    """Two surfaces with an edge between them and some per-sample jitter."""
    rng = np.random.default_rng(seed)
    yy, xx = np.indices((h, w))
    base = np.where(xx + 0.5 * yy < 40, -0.3, 0.4) + 0.2 * np.sin(xx / 9.0)
    return np.clip(base[..., None] + rng.uniform(-0.02, 0.02, (h, w, s)), -1, 1).astype(np.float32)


def test_float128_is_the_filtered_moments():
    z = smooth_depths()
    tex = filter_and_quantize(z, "float128")
    assert tex.dtype == np.float32 and tex.shape == z.shape[:2] + (4,)
    assert np.array_equal(tex, filter_moments(z))


def test_affine64_is_the_unbiased_unorm16_code_of_the_reference():
    affine = pytest.importorskip("moments_ref.affine")
    z = smooth_depths()
    tex = filter_and_quantize(z, "affine64")
    assert tex.dtype == np.uint16 and tex.shape == z.shape[:2] + (4,)
    # Against the float64 reference, not against filter_moments: codes differ by
    # at most one step (float32 rounding can only cross one rounding boundary).
    want = affine.encode_unorm16(blur(resolve_moments(z)))
    assert np.abs(tex.astype(np.int64) - want).max() <= 1
    # No bias: a biased encoding would differ from the unbiased one somewhere.
    from moments_ref.moments import BIAS_UNORM16, bias_moments

    biased = affine.encode_unorm16(bias_moments(blur(resolve_moments(z)), BIAS_UNORM16))
    assert np.abs(tex.astype(np.int64) - biased).max() > 1


@pytest.mark.parametrize("fmt", ["nlq64", "nlq32"])
def test_nlq_texture_is_bias_phi_pack_of_the_filtered_moments(fmt):
    packing = pytest.importorskip("moments_ref.packing")
    from moments_ref.moments import BIAS_FLOAT32, bias_moments
    from moments_ref.nonlinear import phi

    z = smooth_depths()
    tex = filter_and_quantize(z, fmt)
    pack = packing.pack64 if fmt == "nlq64" else packing.pack32
    assert np.array_equal(tex, pack(phi(bias_moments(filter_moments(z), BIAS_FLOAT32))))
    if fmt == "nlq64":
        assert tex.dtype == np.uint16 and tex.shape == z.shape[:2] + (4,)
    else:
        assert tex.dtype == np.uint32 and tex.shape == z.shape[:2]


@pytest.mark.parametrize("fmt,atol", [("nlq64", 2e-4), ("nlq32", 2e-2)])
def test_nlq_texture_decodes_to_the_reference_moments(fmt, atol):
    # Independent of the emulation: decode the texel (unpack, Φ⁻¹ of HPG17 Eq. (4))
    # and compare with the float64 reference. For this scene ξ4 is small, so the
    # depth and weight steps dominate: a depth step (2/65535 at 64 bits, 2/1023 at
    # 32 bits) moves a moment by at most 4× the step, a 7-bit √v2 step by about
    # 2√v2/127 times the spread of the two depths. atol is about twice that.
    packing = pytest.importorskip("moments_ref.packing")
    from moments_ref.nonlinear import phi_inverse

    z = smooth_depths()
    tex = filter_and_quantize(z, fmt)
    r = packing.unpack64(tex) if fmt == "nlq64" else packing.unpack32(tex)
    b = phi_inverse(np.asarray(r, dtype=np.float64))
    ref = blur(resolve_moments(z))
    assert np.abs(b - ref).max() <= atol
