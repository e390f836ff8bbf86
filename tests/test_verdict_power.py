"""The power of the verdict tests, kept: for each invariant, one mutant of the code it pins
(written by the mutation tool, moments_ref.tools.mutation) under which its test fails.

A test that cannot fail pins nothing; these examples keep each one's power known as the
code moves (the mutant is found again by its id; a stale id fails here, as the
equivalents file's do in tests/test_mutation_tool.py).
"""

from __future__ import annotations

import pytest

import test_band_edges as edges
import test_band_model as band
import test_compare_tallies as tallies
import test_contract_rows as rows
import test_diagnosis_advice as advice
import test_diagnosis_groups as diag
import test_kernel_judge as judge
import test_spread_model as spread
import test_spread_ties as ties
from _mutants import kept_mutant


CONTRACT = "moments_ref/golden/contract.py"
VERDICT = "moments_ref/conformance/kernel/verdict.py"
COMPARE = "moments_ref/golden/compare.py"
PROFILE = "moments_ref/golden/profile.py"
BANDS = "moments_ref/golden/bands.py"
SPREAD = "moments_ref/golden/spread.py"
DIAGNOSIS = "moments_ref/golden/diagnosis.py"

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
    (BANDS, "_margin::np.maximum -> np.minimum#1",
     band.test_the_margin_is_the_largest_of_four_noises_three_widths_and_eight_ulps, ()),
    (BANDS, "_margin::np.abs(e) -> e#0",
     band.test_the_margins_floor_is_eight_ulps_of_the_magnitude_or_the_scale_in_the_ports_precision, ()),
    (BANDS, "interval_parts::CAP * (case.value_range[1] - case.value_range[0]) -> "
            "CAP / (case.value_range[1] - case.value_range[0])#0",
     band.test_a_bounded_band_is_capped_at_two_percent_of_the_range_unless_ill_conditioned, ()),
    (BANDS, "interval_parts::np.isfinite(h) & c -> np.isfinite(h) | c#1",
     band.test_formulations_widen_only_on_contract_rows_within_the_cap_and_flag_a_hazard_beyond, ()),
    (BANDS, "_componentwise::-sign -> sign#0",
     band.test_the_neighbourhood_is_three_ulps_jointly_and_one_ulp_alternating_per_component, ()),
    (BANDS, "noise_of::np.fmax -> np.maximum#0", band.test_the_noise_is_the_90th_percentile_of_the_random_rows_deviations, ()),
    (BANDS, "confirm_points::PERTURB_ULPS + 1 -> PERTURB_ULPS - 1#0",
     band.test_confirm_explains_the_exact_values_over_three_float32_ulps_each_way, ()),
    (SPREAD, "_float_tolerances::np.isnan -> np.isinf#0",
     spread.test_a_row_without_an_expected_value_gets_an_infinite_tolerance_not_nan, ()),
    (SPREAD, "_check_truth::0 -> -1#0",
     spread.test_a_reference_disagreeing_with_its_truth_names_the_first_row_away_from_a_boundary, ()),
    (DIAGNOSIS, "groups::2 -> 3#0",
     diag.test_levels_are_ordered_target_format_or_convention_contract_robustness_whatever_their_size, ()),
    (DIAGNOSIS, "_narrowed::g.max() <= np.iinfo(want).max -> g.max() < np.iinfo(want).max#0",
     diag.test_readback_words_are_narrowed_to_the_codes_dtype_only_where_they_fit, ()),
    # round three: the band's edges, the tie rule, the noise's neighbourhood, the advice on ports of known cause
    (BANDS, "interval_parts::np.abs(h - e) <= cap -> np.abs(h - e) < cap#0",
     edges.test_a_formulation_exactly_the_cap_away_widens_the_band_and_one_beyond_is_a_hazard, ()),
    (BANDS, "_derived_bands::a.max -> a.min#0",
     edges.test_a_codes_band_spans_the_truths_the_references_and_the_nudged_inputs_codes, ()),
    (BANDS, "case_noise::any -> all#0",
     edges.test_the_noise_takes_component_wise_neighbours_only_where_the_rule_allows_them, ()),
    (BANDS, "confirm_points::-PERTURB_ULPS -> PERTURB_ULPS#0",
     edges.test_confirm_explains_inputs_moved_apart_by_up_to_three_ulps_each_but_not_farther, ()),
    (SPREAD, "_ties::np.float32 -> np.float64#0",
     ties.test_the_acceptable_codes_are_the_truths_the_references_and_the_nudged_inputs_in_float64, ()),
    (DIAGNOSIS, "bound_groups::1 - want -> 1 + want#0",
     advice.test_a_hausdorff_port_is_advised_bound_hausdorff_on_its_failing_rows, ("tmp_path", "visibility")),
    (DIAGNOSIS, "_candidates::'receiver_depth' in usable -> 'receiver_depth' not in usable#0",
     advice.test_a_ports_known_convention_is_named_on_every_failing_row_and_declaring_it_passes,
     ("tmp_path", "receiver in [0, 1]")),
    (DIAGNOSIS, "singular_target_cause::len(support) == 1 -> len(support) != 1#0",
     advice.test_a_singular_target_is_named_on_exactly_the_rows_it_leaves_singular,
     ("[-1,1]", [(0.3, 1.0)], "intensity", "1·δ(0.3), a one-point distribution", 3e-6)),
]


@pytest.mark.parametrize("path, mid, test, args", EXAMPLES, ids=[e[1].split(" ")[0] for e in EXAMPLES])
def test_each_invariant_fails_under_its_kept_mutant(request, path, mid, test, args):
    values = [request.getfixturevalue(a) if isinstance(a, str) and a in ("goldens", "tmp_path") else a for a in args]
    test(*values)  # unmutated: holds
    with kept_mutant(path, mid):
        with pytest.raises(Exception):  # an assertion, or the error the mutant raises
            test(*values)


goldens = judge.goldens
