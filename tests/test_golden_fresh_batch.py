"""The fresh hand-written batch's survivors in golden/ (issue 38, round six): one statement each.

Each test states what the docs promise, against hand-built inputs or an independent computation,
not the code's own output.
"""

from __future__ import annotations

import numpy as np
import pytest

from moments_ref import InputError, golden
from moments_ref.golden.profile import Profile, parse_profile, profile_from_args

MJP_BIAS = {"alpha": 3e-6, "target": [0.5, 0.34375, 0.265625, 0.2265625], "applied": "inside"}


@pytest.mark.parametrize("value", [8.0, True, 16.0])
def test_subtexel_bits_is_an_integer_not_a_float_or_bool_that_compares_equal(value):
    # 8.0 == 8 and True == 1 in Python: a membership test alone would accept them (docs/ports.md: an integer).
    with pytest.raises(InputError, match=r"format\.subtexel_bits.*integer"):
        parse_profile({"format": {"subtexel_bits": value}})
    assert dict(parse_profile({"format": {"subtexel_bits": 8}}).format) == {"subtexel_bits": 8}


def test_a_functions_table_is_part_of_the_key():
    # Two profiles differing only in [functions.shade] derive different goldens: different keys, not default.
    p = parse_profile({"functions": {"shade": {"depth": "[0,1]"}}})
    q = parse_profile({"functions": {"shade": {"depth": "[-1,1]", "output": "visibility"}}})
    assert len({p.key, q.key, Profile().key}) == 3 and not p.is_default


def test_a_bias_flag_keeps_the_files_other_bias_keys(tmp_path):
    f = tmp_path / "p.toml"
    f.write_text('[bias]\nalpha = 3e-6\ntarget = [0.5, 0.34375, 0.265625, 0.2265625]\napplied = "inside"\n')
    q = profile_from_args(f, "x", bias_alpha="1e-4")
    assert (q.bias.alpha, q.bias.target, q.bias.applied) == (1e-4, (0.5, 0.34375, 0.265625, 0.2265625), "inside")
    r = profile_from_args(f, "x", bias_applied="before")
    assert (r.bias.alpha, r.bias.target, r.bias.applied) == (3e-6, (0.5, 0.34375, 0.265625, 0.2265625), "before")


def test_a_profiled_folder_verified_without_the_profile_keeps_its_ill_rows(tmp_path):
    # A folder written under a profile holds the profile's exact values; verified without --profile, its
    # ill-conditioned rows must not be re-judged by the plain case's neighbourhood (other depths, no bias).
    name = "shadow_intensity-lower-float32"
    p = parse_profile({"depth": "[0,1]", "output": "visibility", "bias": MJP_BIAS})
    golden.write(tmp_path / "g", [name], profile=p)
    with np.load(tmp_path / "g" / f"{name}.npz") as g:
        got, flags = g["intensity_float32"], g["flags"]
    assert sum("wide_spread" in str(f) for f in flags) >= 5  # the statement has rows to bite on
    np.savez(tmp_path / "r.npz", **{f"{name}.intensity": got})
    case = golden.verify(tmp_path / "g", tmp_path / "r.npz").cases[0]
    assert case.status == "pass" and case.verdict.row_pass.all()
