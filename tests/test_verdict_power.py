"""The power of the verdict tests, kept: for each invariant, one mutant of the code it pins
(written by the mutation tool, moments_ref.tools.mutation) under which its test fails.

A test that cannot fail pins nothing; these examples keep each one's power known as the
code moves (the mutant is found again by its id; a stale id fails here, as the
equivalents file's do in tests/test_mutation_tool.py).
"""

from __future__ import annotations

import importlib
from contextlib import contextmanager

import pytest

import test_compare_tallies as tallies
import test_contract_rows as rows
import test_kernel_judge as judge
from moments_ref.tools.mutation import ROOT, mutants_of
from moments_ref.tools.mutation._operators import mutated_code


@contextmanager
def _mutant(path, mid):
    """The function ``mid`` changes, with the mutant's code while the block runs."""
    source = (ROOT / path).read_text()
    found = [m for m in mutants_of(source, path) if m.id == f"{path}::{mid}"]
    assert found, f"no mutant {mid} in {path} any more: choose another one for this invariant"
    m = found[0]
    module = importlib.import_module(path.removesuffix(".py").replace("/", "."))
    obj = module
    for part in m.top.split("."):
        obj = getattr(obj, part)
    fn = getattr(obj, "fget", obj)
    saved = fn.__code__
    fn.__code__ = mutated_code(source, path, m)
    try:
        yield
    finally:
        fn.__code__ = saved


CONTRACT = "moments_ref/golden/contract.py"
VERDICT = "moments_ref/conformance/kernel/verdict.py"
COMPARE = "moments_ref/golden/compare.py"
PROFILE = "moments_ref/golden/profile.py"

# (module, mutant, the test that must fail under it, its arguments)
EXAMPLES = [
    (CONTRACT, "_biased::1 - alpha -> 1 + alpha#0",
     rows.test_a_row_just_outside_stays_outside_under_the_smallest_bias, ()),
    (CONTRACT, "representation_inside::y1 >= -1 -> y1 > -1#0",
     rows.test_algorithm3s_contract_includes_the_ends_of_the_nonlinear_domain, ()),
    (CONTRACT, "rows_inside::kind == 'distribution' -> False#0",
     rows.test_the_chains_contract_judges_the_unbiased_distribution, ()),
    (VERDICT, "judge::bad | (mapped > 65535).any(axis=1) -> bad & (mapped > 65535).any(axis=1)#0",
     judge.test_a_code_above_16_bits_fails_its_row_even_when_clipping_or_wrapping_would_restore_it, ("goldens",)),
    (VERDICT, "judge::misfit | (r[:, 0] > r[:, 1]) -> misfit & (r[:, 0] > r[:, 1])#0",
     judge.test_codes_of_y1_above_y2_fail_their_row_instead_of_stopping_the_judge, ("goldens",)),
    (VERDICT, "_filter_candidate:::h -> :h + 1#0",
     judge.test_one_row_and_one_texel_past_an_image_output_are_writes_outside, ("goldens", "kernel-filter-nlq64")),
    (VERDICT, "_codes_summary::~accepted -> accepted#0",
     judge.test_another_legitimate_kernels_code_is_counted_as_accepted_and_a_wrong_one_as_differing, ("goldens",)),
    (VERDICT, "KernelReport.passed::self.shared.get('races') or self.shared.get('error') -> "
              "self.shared.get('races') and self.shared.get('error')#0",
     judge.test_a_watchdog_stopped_trace_is_a_failure_of_the_report_not_a_pass, ()),
    (COMPARE, "_codes::c.dtype.kind == 'i' and c.dtype.itemsize == want.itemsize -> False#0",
     tallies.test_signed_codes_of_the_manifests_width_are_read_as_their_bits, ()),
    (COMPARE, "Verdict.robustness_tally::fail & self.outside_range -> fail | self.outside_range#0",
     tallies.test_the_robustness_tally_counts_each_kind_of_failure_exactly, ()),
    (PROFILE, "Profile.for_function::table.format -> not table.format#0",
     rows.test_a_functions_format_keys_override_the_files_and_keep_the_others, ()),
]


@pytest.mark.parametrize("path, mid, test, args", EXAMPLES, ids=[e[1].split(" ")[0] for e in EXAMPLES])
def test_each_invariant_fails_under_its_kept_mutant(request, path, mid, test, args):
    values = [request.getfixturevalue(a) if a == "goldens" else a for a in args]
    test(*values)  # unmutated: holds
    with _mutant(path, mid):
        with pytest.raises(Exception):  # an assertion, or the error the mutant raises
            test(*values)


goldens = judge.goldens
