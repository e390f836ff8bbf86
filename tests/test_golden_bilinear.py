"""The bilinear golden cases (golden.bilinear): exact expected values, the declared weight spread, its power.

No driver needed: the filters here are NumPy simulations of hardware (llvmpipe and lavapipe
filter with the exact fraction, so a quantizing filter can only be simulated);
tests/test_conformance_bilinear.py runs the shaders.
"""

from __future__ import annotations

import mpmath
import numpy as np
import pytest

from moments_ref.golden import CASES, bilinear
from moments_ref.golden.compare import compare
from moments_ref.golden.spread import golden_arrays
from moments_ref.golden.writer import manifest_entry
from moments_ref.moments import BIAS_FLOAT32, bias_moments
from moments_ref.msm import shadow_intensity

SAMPLE, INTENSITY = "sample_bilinear-float32", "shadow_intensity_bilinear-float32"
_ARRAYS = {}


def _arrays(name, profile=None):
    key = (name, profile)
    if key not in _ARRAYS:
        if profile is None:
            _ARRAYS[key] = (CASES[name], golden_arrays(CASES[name]))
        else:
            from moments_ref.golden.conventions import profiled_arrays
            from moments_ref.golden.profile import parse_profile

            _ARRAYS[key] = profiled_arrays(name, parse_profile({"format": {"subtexel_bits": profile}}))
    return _ARRAYS[key]


def _quantize(f, bits, mode):
    s = 2.0 ** bits
    return ({"nearest": np.floor(f * s + 0.5), "floor": np.floor(f * s), "ceil": np.ceil(f * s)}[mode] / s)


#: NumPy filters: name -> fraction (n, 2) float64 -> weights (wx, wy); all in float32 lerps.
FILTERS = {
    "exact": lambda f: (f[:, 0], f[:, 1]),
    "8-bit nearest": lambda f: (_quantize(f[:, 0], 8, "nearest"), _quantize(f[:, 1], 8, "nearest")),
    "8-bit floor": lambda f: (_quantize(f[:, 0], 8, "floor"), _quantize(f[:, 1], 8, "floor")),
    "8-bit ceil x, floor y": lambda f: (_quantize(f[:, 0], 8, "ceil"), _quantize(f[:, 1], 8, "floor")),
    "12-bit nearest": lambda f: (_quantize(f[:, 0], 12, "nearest"), _quantize(f[:, 1], 12, "nearest")),
}
BUGS = {
    "4-bit nearest (undeclared)": lambda f: (_quantize(f[:, 0], 4, "nearest"), _quantize(f[:, 1], 4, "nearest")),
    "swapped x/y": lambda f: (f[:, 1], f[:, 0]),
    "weights 1 - f and f swapped": lambda f: (1 - f[:, 0], 1 - f[:, 1]),
    "half-texel offset": lambda f: (np.minimum(f[:, 0] + 0.5, 1), np.minimum(f[:, 1] + 0.5, 1)),
    "point sampler": lambda f: (np.floor(f[:, 0] + 0.5), np.floor(f[:, 1] + 0.5)),
}


def _run(name, weights, arrays):
    wx, wy = weights(np.asarray(arrays["fraction"], np.float64))
    b = bilinear.blend(np.asarray(arrays["texels"], np.float32), wx, wy, np.float32)
    if name == SAMPLE:
        return {"b": b}
    return {"intensity": shadow_intensity(bias_moments(b, BIAS_FLOAT32), np.asarray(arrays["zf"], np.float32))}


def _verdict(name, weights, profile=None):
    case, arrays = _arrays(name, profile)
    return compare(manifest_entry(case, arrays), arrays, _run(name, weights, arrays), "float32", case=name)


@pytest.mark.parametrize("name", [SAMPLE, INTENSITY])
@pytest.mark.parametrize("filt", list(FILTERS))
def test_filters_within_the_declared_weights_pass(name, filt):
    v = _verdict(name, FILTERS[filt])
    assert v.row_pass.all(), (filt, int((~v.row_pass).sum()))


@pytest.mark.parametrize("name", [SAMPLE, INTENSITY])
@pytest.mark.parametrize("bug", list(BUGS))
def test_filter_mistakes_fail(name, bug):
    v = _verdict(name, BUGS[bug])
    assert (~v.row_pass).sum() > 100, (bug, int((~v.row_pass).sum()))


@pytest.mark.parametrize("name", [SAMPLE, INTENSITY])
def test_a_4_bit_filter_passes_once_declared(name):
    # Vulkan's minimum subTexelPrecisionBits: declared in the profile, the spread widens.
    v = _verdict(name, BUGS["4-bit nearest (undeclared)"], profile=4)
    assert v.row_pass.all(), int((~v.row_pass).sum())
    case, _ = _arrays(name, 4)
    assert case.kwargs["subtexel_bits"] == 4


def test_expected_blend_is_the_exact_rational_blend():
    # An independent evaluation: mpmath at 60 digits of the four products, rounded once.
    _, a = _arrays(SAMPLE)
    t, f = np.asarray(a["texels"], np.float64).reshape(-1, 4, 4), np.asarray(a["fraction"], np.float64)
    with mpmath.workdps(60):
        for r in range(0, len(t), 7):
            fx, fy = mpmath.mpf(f[r, 0]), mpmath.mpf(f[r, 1])
            w = ((1 - fx) * (1 - fy), fx * (1 - fy), (1 - fx) * fy, fx * fy)
            want = [float(mpmath.fsum(w[k] * mpmath.mpf(t[r, k, c]) for k in range(4))) for c in range(4)]
            assert np.array_equal(a["b"][r], want), r


def test_moment_tolerance_is_the_corner_spread_plus_the_filter_rounding():
    # On the 8-bit grid the weights are exact: only the rounding of a float32 filter is allowed.
    _, a = _arrays(SAMPLE)
    grid = np.array(["weight_grid" in str(x) for x in a["flags"]])
    t = np.abs(np.asarray(a["texels"], np.float64).reshape(-1, 4, 4)).max(axis=1)
    rounding = bilinear.FILTER_ULPS * 2.0 ** -23 * t
    assert grid.sum() >= 18
    assert np.all(a["b_tolerance_float32"][grid] <= 1.1 * np.maximum(rounding[grid], 4 * 2.0 ** -23))
    # Off the grid, at least the distance to a one-step weight change along x.
    off = ~grid & (np.asarray(a["fraction"])[:, 0] * 256 % 1 > 0)
    tt = np.asarray(a["texels"], np.float64).reshape(-1, 4, 4)
    step_x = np.abs((tt[:, 1] - tt[:, 0]) * (1 - a["fraction"][:, 1:2]) + (tt[:, 3] - tt[:, 2]) * a["fraction"][:, 1:2])
    lo, hi = bilinear.quantized(np.asarray(a["fraction"])[:, 0], 8)
    dist = np.maximum(a["fraction"][:, 0] - lo, hi - a["fraction"][:, 0])[:, None] * step_x
    assert np.all(a["b_tolerance_float32"][off] >= dist[off] * (1 - 1e-9))


def test_fractions_are_exact_texture_coordinates():
    # (2 bx + 0.5 + f) / W in float32 and back to texel space gives f exactly (W a power of two <= 256).
    from moments_ref.conformance._textures import quad_layout

    _, a = _arrays(SAMPLE)
    n = len(a["fraction"])
    w, h = quad_layout(n)
    assert (w, h) == (256, 8) and w & (w - 1) == 0 and h & (h - 1) == 0
    i = np.arange(n)
    f = np.asarray(a["fraction"], np.float32)
    x = (np.float32(2) * (i % (w // 2)).astype(np.float32) + np.float32(0.5) + f[:, 0]) / np.float32(w)
    y = (np.float32(2) * (i // (w // 2)).astype(np.float32) + np.float32(0.5) + f[:, 1]) / np.float32(h)
    back_x = x.astype(np.float64) * w - 0.5
    back_y = y.astype(np.float64) * h - 0.5
    assert np.array_equal(back_x - np.floor(back_x), f[:, 0]) and np.array_equal(back_y - np.floor(back_y), f[:, 1])


def test_rows_and_labels():
    for name in (SAMPLE, INTENSITY):
        _, a = _arrays(name)
        cats = {c: int((a["category"] == c).sum()) for c in ("random", "stiff", "edge")}
        assert cats == {"random": 128, "stiff": 128, "edge": 72}
        assert all("shadow_edge" in str(f) for f in a["flags"][a["category"] == "stiff"])
        assert np.all(np.asarray(a["fraction"]) * 2 ** bilinear.FRACTION_BITS % 1 == 0)


def test_profile_refuses_a_subtexel_precision_below_vulkans_minimum():
    from moments_ref import InputError
    from moments_ref.golden.profile import parse_profile, profile_from_args

    with pytest.raises(InputError, match="subtexel_bits"):
        parse_profile({"format": {"subtexel_bits": 3}})
    assert dict(profile_from_args(format_subtexel_bits="6").format) == {"subtexel_bits": 6}
