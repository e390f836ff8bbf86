"""golden.bilinear's case specifications and its wide-spread boundary, against its docstring.

The two cases: ``sample_bilinear-float32`` (texels, fraction -> b) and
``shadow_intensity_bilinear-float32`` (texels, fraction, zf -> intensity on [0, 1]), float32, with
the profile's ``[format] subtexel_bits`` (default 8) and the weights' rule in their descriptions;
a tolerance of 0.1 or more is a wide spread (exactly 0.1 included).
"""

from __future__ import annotations

import numpy as np

from moments_ref.golden import bilinear


def test_the_two_cases_state_their_inputs_outputs_and_rule():
    sample, intensity = bilinear.case_specs()
    assert (sample["name"], sample["function"], sample["inputs"], sample["outputs"]) == (
        "sample_bilinear-float32", "bilinear.sample", ("texels", "fraction"), ("b",))
    assert (intensity["name"], intensity["function"], intensity["inputs"], intensity["outputs"]) == (
        "shadow_intensity_bilinear-float32", "bilinear.shadow_intensity", ("texels", "fraction", "zf"), ("intensity",))
    assert intensity["value_range"] == (0, 1) and "value_range" not in sample
    for spec in (sample, intensity):
        assert spec["dtype"] == "float32" and spec["kwargs"] == {"subtexel_bits": 8}
        assert spec["profile_keys"] == ("format",) and spec["truth"] is None
        assert "weights: any multiple of 2^-q within one step of the fraction" in spec["description"]
        assert "default 8); plus the rounding of a float32 filter" in spec["description"]
    assert sample["description"].startswith("bilinear sample of a 2x2 neighbourhood")
    assert intensity["description"].endswith(", and 16 x the float32 spread of Algorithm 1")
    assert intensity["description"].startswith("HPG17 Algorithm 1 (lower bound) on the bilinear sample")
    # the profile's format table sets the sub-texel bits, its absence keeps the default
    variant = sample["variant"]
    assert variant(fmt={"subtexel_bits": 5})["kwargs"] == {"subtexel_bits": 5}
    assert variant(fmt=None)["kwargs"] == {"subtexel_bits": 8} == variant()["kwargs"]


def test_a_tolerance_of_exactly_one_tenth_is_a_wide_spread():
    # one depth 0.3 in all four texels, the receiver 0.0033 behind it (a float32 value found by bisection
    # on the receiver's offset, where the tolerance rounds up to 0.1 exactly)
    texels = np.tile(0.3 ** np.arange(1, 5), (1, 4)).astype(np.float32).astype(np.float64)
    out, wide = bilinear._intensity_arrays(texels, np.full((1, 2), 0.3), np.array([0.30330076813697815]), 8)
    assert out["intensity_tolerance_float32"][0] == 0.1 and wide.tolist() == [True]
