"""golden.bilinear's tolerances on hand-made rows, against the rule of its docstring computed here.

The moments' tolerance of a q-bit filter (per component, per port precision d): the largest
distance of a corner's blend (weights ⌊2^q f⌋/2^q or ⌈2^q f⌉/2^q per axis) from the exact blend,
plus FILTER_ULPS = 8 ulps (eps of d) of the largest texel component, at least 4 ulps of the exact
value, rounded up to two digits; blends here in exact rationals. The intensity's: the largest
distance of the exact intensity (mpmath twins) at the weights of 4 more bits across the rectangle
from the expected value, plus 16 times the deviation of the float32 formulations from float64 on the
corners' blends, at least 4 ulps of 1, at most 1; a tolerance of 0.1 or more is a wide spread.
"""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np
import pytest

from moments_ref import precise
from moments_ref.golden import bilinear
from moments_ref.golden.cases import CASES
from moments_ref.golden.paper import printed_bound, slides_bound
from moments_ref.golden.units import ceil2
from moments_ref.moments import BIAS_FLOAT32, bias_moments
from moments_ref.msm import shadow_intensity

# row 0: the fraction 2^-16·(19738, 50000): just above 77/256 along x, 195.3125/256 along y
# row 1: component 2 zero in all four texels (a texel of depths ±d: b3 = 0); fraction (0.5 + 2^-16, 0.25)
# row 2: row 0's texels on the 8-bit grid, fraction (77/256, 1/2): only the filter's rounding is allowed
TEXELS = np.array([[0.1, 0.3, -0.7, 0.9, 0.8, 0.2, 0.4, -0.5, -0.6, 0.9, 0.1, 0.3, 0.4, -0.8, 0.7, 0.6],
                   [0.5, 0.25, 0.0, 0.0625, -0.25, 0.5, 0.0, 0.25, 0.125, 0.75, 0.0, 0.5, 1.0, 1.0, 0.0, 1.0],
                   [0.1, 0.3, -0.7, 0.9, 0.8, 0.2, 0.4, -0.5, -0.6, 0.9, 0.1, 0.3, 0.4, -0.8, 0.7, 0.6]])
FRACTION = np.array([[19738, 50000], [32769, 16384], [19712, 32768]]) / 65536.0


def _blend(t, wx, wy):
    """The blend of one row's four texels (rationals) with rational weights: 4 rationals."""
    w = ((1 - wx) * (1 - wy), wx * (1 - wy), (1 - wx) * wy, wx * wy)
    return [sum(w[k] * t[k][c] for k in range(4)) for c in range(4)]


def _rational(r):
    return [[Fraction(float(x)) for x in TEXELS[r, 4 * k: 4 * k + 4]] for k in range(4)]


def _steps(f, bits):
    s = 2 ** bits
    return Fraction(math.floor(f * s), s), Fraction(math.ceil(f * s), s)


def _ulp(x, dt):
    """Spacing of dt at |x| (rounded to dt), at least the smallest normal's: a power of two."""
    fi = np.finfo(dt)
    a = abs(float(np.asarray(x).astype(dt)))
    if a < fi.tiny:
        return 2.0 ** (fi.minexp - fi.nmant)
    return 2.0 ** (math.frexp(a)[1] - 1 - fi.nmant)


def _moment_tolerance(r, bits, dt):
    t = _rational(r)
    fx, fy = (Fraction(float(x)) for x in FRACTION[r])
    exact = _blend(t, fx, fy)
    spread = [Fraction(0)] * 4
    for wx in _steps(fx, bits):
        for wy in _steps(fy, bits):
            spread = [max(s, abs(v - e)) for s, v, e in zip(spread, _blend(t, wx, wy), exact)]
    eps = float(np.finfo(dt).eps)
    out = []
    for c in range(4):
        big = max(abs(t[k][c]) for k in range(4))
        out.append(max(float(spread[c]) + bilinear.FILTER_ULPS * eps * float(big), 4 * _ulp(float(exact[c]), dt)))
    return exact, np.array(out)


@pytest.mark.parametrize("bits", [8, 4])
def test_the_moments_tolerance_is_the_farthest_corner_plus_eight_ulps_at_least_four_ulps(bits):
    out, wide = bilinear._sample_arrays(TEXELS, FRACTION, bits)
    assert not wide.any() and out["b"].dtype == np.float64
    for r in range(3):
        exact, _ = _moment_tolerance(r, bits, np.float32)
        assert out["b"][r].tolist() == [float(e) for e in exact]
        for d in ("float32", "float64"):
            _, want = _moment_tolerance(r, bits, np.dtype(d))
            got = out[f"b_tolerance_{d}"][r]
            if r < 2:
                assert np.all(got >= want) and np.array_equal(got, ceil2(want)), (r, d, got, want)
            else:  # on the grid the corners' float64 blends are a rounding (< 2^-53 of a texel) off the exact one
                assert np.all((got >= want) & (got <= 1.25 * want)), (r, d, got, want)
    # the zero component: exactly the floor, 4 ulps of 0 (4 × 2^-149 in float32, 4 × 2^-1074 in float64)
    assert out["b_tolerance_float32"][1, 2] == ceil2(4 * 2.0**-149) and 4 * 2.0**-149 <= \
        out["b_tolerance_float32"][1, 2] < 5 * 2.0**-149
    assert out["b_tolerance_float64"][1, 2] == 4 * 2.0**-1074
    # the float32 reference: float32 lerps within the filter's 8 ulps of the exact blend
    ref = out["b_float32"]
    assert ref.dtype == np.float32
    allowance = 8 * 2.0**-23 * np.abs(TEXELS.reshape(3, 4, 4)).max(axis=1)
    assert np.all(np.abs(ref - out["b"]) <= allowance)


def test_a_value_four_ulps_from_an_all_zero_component_passes_and_five_fail():
    from moments_ref.golden.compare import compare
    from moments_ref.golden.writer import manifest_entry

    case = CASES["sample_bilinear-float32"]
    arrays = {"texels": TEXELS.astype(np.float32), "fraction": FRACTION.astype(np.float32)}
    out = bilinear.derive_bilinear()(case, arrays, ["edge"] * 3, ["a", "b", "c"], [()] * 3)
    arrays.update(out)
    got = out["b"].astype(np.float32)
    for k, passes in ((4, True), (5, False)):
        g = got.copy()
        g[1, 2] = np.float32(k * 2.0**-149)
        v = compare(manifest_entry(case, arrays), arrays, {"b": g}, "float32", case=case.name)
        assert v.row_pass.tolist() == [True, passes, True], k


def test_the_finer_weights_are_sixteen_steps_across_the_rectangle_and_the_fraction():
    lo, hi, f = np.array([0.25, 0.5]), np.array([0.5, 0.5]), np.array([0.3, 0.5])
    g = bilinear._grid(lo, hi, f)
    assert g.shape == (2, 18)
    assert g[0].tolist() == [0.25 + k / 64 for k in range(17)] + [0.3]
    assert g[1].tolist() == [0.5] * 17 + [0.5]


def test_the_deriver_labels_rows_numbered_from_one_with_their_flags():
    case = CASES["sample_bilinear-float32"]
    arrays = {"texels": TEXELS.astype(np.float32), "fraction": FRACTION.astype(np.float32)}
    out = bilinear.derive_bilinear(8)(case, arrays, ["random", "edge", "edge"], ["first row", "the second row", ""],
                                      [("shadow_edge", "shadow_edge"), ("weight_grid",), ()])
    assert out["tc_id"].tolist() == [1, 2, 3] and out["tc_id"].dtype == np.int32
    assert out["category"].tolist() == ["random", "edge", "edge"] and out["result"].tolist() == ["valid"] * 3
    assert out["comment"].tolist() == ["first row", "the second row", ""]
    assert out["flags"].tolist() == ["shadow_edge", "weight_grid", ""]


# ---------------------------------------------------------------------------
# The intensity


def _exact_intensity(b, zf):
    return float(np.asarray(precise.shadow_intensity(precise.bias_moments(np.array([b], np.float64), BIAS_FLOAT32),
                                                     np.array([zf])), np.float64)[0])


def _float_deviation(r, texels, fraction, zf, bits):
    """The float32 formulations' largest deviation from float64 Algorithm 1 on the corners' and the fraction's
    blends, the blend moved by ± the filter rounding (signs alternating over the components)."""
    t = np.asarray(texels[r], np.float64).reshape(4, 4)
    move = bilinear.FILTER_ULPS * 2.0**-23 * np.abs(t).max(axis=0) * np.array([1, -1, 1, -1])
    fx, fy = (Fraction(float(x)) for x in fraction[r])
    points = [(wx, wy) for wy in _steps(fy, bits) for wx in _steps(fx, bits)] + [(fx, fy)]
    dev = 0.0
    with np.errstate(all="ignore"):
        for wx, wy in points:
            b64 = np.array([float(x) for x in _blend([[Fraction(float(v)) for v in tk] for tk in t], wx, wy)])
            v64 = float(shadow_intensity(bias_moments(b64[None], BIAS_FLOAT32), np.array([zf]))[0])
            for b in (b64, b64 + move, b64 - move):
                b32 = b[None].astype(np.float32)
                biased = bias_moments(b32, BIAS_FLOAT32)
                z32 = np.array([zf], np.float32)
                for v in (shadow_intensity(biased, z32), slides_bound(biased, z32, "lower", np.float32),
                          printed_bound(biased, z32, "lower", np.float32)):
                    x = float(np.asarray(v, np.float64)[0])
                    if not math.isnan(x):
                        dev = max(dev, abs(min(max(x, 0.0), 1.0) - v64))
    return dev


#: two shadow-edge rows (texel depths: one occluder depth per texel, a receiver behind) and a lit one
Z = np.array([[-0.4, 0.6, -0.4, 0.6], [0.6, 0.6, 0.6, -0.35], [0.5, 0.5, 0.5, 0.5]])
EDGE_TEXELS = (Z[:, :, None] ** np.arange(1, 5)).reshape(3, 16).astype(np.float32).astype(np.float64)
EDGE_FRACTION = np.array([[32801, 20000], [40000, 65000], [30000, 1000]]) / 65536.0
EDGE_ZF = np.array([0.55, 0.55, -0.9])


def test_the_intensity_tolerance_covers_the_finer_weights_exact_values_plus_sixteen_float_deviations():
    bits = 8
    out, wide = bilinear._intensity_arrays(EDGE_TEXELS, EDGE_FRACTION, EDGE_ZF, bits)
    assert not wide.any() and out["intensity_float32"].dtype == np.float32
    for r in range(3):
        t = [[Fraction(float(v)) for v in EDGE_TEXELS[r, 4 * k: 4 * k + 4]] for k in range(4)]
        fx, fy = (Fraction(float(x)) for x in EDGE_FRACTION[r])
        truth = _exact_intensity([float(x) for x in _blend(t, fx, fy)], EDGE_ZF[r])
        assert out["intensity"].dtype == np.float64 and abs(float(out["intensity"][r]) - truth) <= 1e-15
        (lx, hx), (ly, hy) = _steps(fx, bits), _steps(fy, bits)
        hull = 0.0
        for k in range(17):  # 4 more bits: 16 steps across the rectangle, corners included
            for m in (0, 5, 16):
                b = _blend(t, lx + (hx - lx) * Fraction(k, 16), ly + (hy - ly) * Fraction(m, 16))
                hull = max(hull, abs(_exact_intensity([float(x) for x in b], EDGE_ZF[r]) - truth))
        dev = _float_deviation(r, EDGE_TEXELS, EDGE_FRACTION, EDGE_ZF[r], bits)
        want = max(hull + 16 * dev, 4 * 2.0**-23)
        got = out["intensity_tolerance_float32"][r]
        assert want * (1 - 1e-9) <= got <= 1.1 * want + 1e-15, (r, got, hull, dev)
        if r < 2:
            assert hull > 1e-4  # the edge rows' weights matter
    # the lit row: every evaluation 0, so the floor of 4 ulps of 1 (float32: 2^-23 each; float64: 2^-52)
    assert out["intensity"][2] == 0 and 4 * 2.0**-23 <= out["intensity_tolerance_float32"][2] < 5 * 2.0**-23
    assert 4 * 2.0**-52 <= out["intensity_tolerance_float64"][2] < 5 * 2.0**-52


def test_a_receiver_just_behind_a_single_depth_is_a_wide_spread_capped_at_the_range():
    # all four texels the moments of one depth 0.3 (float32): behind it by 0.01 float32 Algorithm 1 stays close;
    # by 0.003 its formulations spread beyond 0.1/16 (wide); by 0.001 beyond 1/16: the tolerance is the range
    case = CASES["shadow_intensity_bilinear-float32"]
    texels = np.tile(0.3 ** np.arange(1, 5), (3, 4)).astype(np.float32)
    arrays = {"texels": texels, "fraction": np.full((3, 2), 0.3, np.float32),
              "zf": np.array([0.31, 0.303, 0.301], np.float32)}
    out = bilinear.derive_bilinear(8)(case, arrays, ["stiff"] * 3, ["a", "b", "c"], [("near",)] * 3)
    t = out["intensity_tolerance_float32"]
    assert out["flags"].tolist() == ["near", "near,wide_spread", "near,wide_spread"]
    assert t[0] < 0.1 <= t[1] < 1 and t[2] == 1.0
    dev = [_float_deviation(r, texels.astype(np.float64), arrays["fraction"].astype(np.float64),
                            float(arrays["zf"][r]), 8) for r in range(3)]
    assert dev[1] > 0.1 / 16 and 16 * dev[2] > 1


def test_the_float_deviation_is_the_largest_over_corners_fraction_moves_and_formulations():
    # the last row: one depth 0.9 and the receiver at it, where the slides' formulation divides by zero (NaN: left out)
    single = np.concatenate([np.tile(0.3 ** np.arange(1, 5), (3, 4)), np.tile(0.9 ** np.arange(1, 5), (1, 4))])
    texels = np.concatenate([EDGE_TEXELS, single.astype(np.float32)]).astype(np.float64)
    fraction = np.concatenate([EDGE_FRACTION, np.full((4, 2), 0.3)])
    zf = np.concatenate([EDGE_ZF, np.array([0.31, 0.303, 0.301, 0.9], np.float32)]).astype(np.float64)
    got = bilinear._float_spread(texels, zf, bilinear._corners(fraction, 8), np.dtype(np.float32))
    want = [_float_deviation(r, texels, fraction, zf[r], 8) for r in range(7)]
    assert got.shape == (7,) and np.allclose(got, want, rtol=1e-6, atol=1e-12), (got, want)
    b = bias_moments(texels[6:, :4].astype(np.float32), BIAS_FLOAT32)
    assert np.isnan(slides_bound(b, np.array([0.9], np.float32), "lower", np.float32)[0]) and want[6] < 0.5
    assert min(want) >= 0 and max(want) > 0.01


def test_a_float64_ports_tolerance_on_the_weight_grid_is_float64_sized():
    # On the 8-bit grid the weights are exact (the rectangle is the fraction), so the float64 column holds only
    # float64 roundings: the exact hull's evaluations and the float64 formulations' deviation, each a few float64
    # ulps on these well-conditioned shadow-edge rows (16 times: still below 2^-30), while the float32 column
    # holds float32 ones (at least 4 float32 ulps of 1). Intensities strictly inside (0, 1): a value rounded to
    # float32 would move.
    fraction = np.array([[128, 80], [200, 40], [64, 192]]) / 256.0
    out, wide = bilinear._intensity_arrays(EDGE_TEXELS[[0, 1, 0]], fraction, np.array([0.55, 0.55, 0.55]), 8)
    assert not wide.any() and np.all((out["intensity"] > 0.05) & (out["intensity"] < 0.95)), out["intensity"]
    t64, t32 = out["intensity_tolerance_float64"], out["intensity_tolerance_float32"]
    assert np.all((4 * 2.0**-52 <= t64) & (t64 < 2.0**-30)), t64
    assert np.all(t32 >= 4 * 2.0**-23)
