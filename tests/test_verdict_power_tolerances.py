"""The power of the tests of golden/bilinear.py, golden/verifier.py, sweep/shrink.py, golden/engine.py and the diagnosis'
target group, kept: for each invariant, one mutant (written by moments_ref.tools.mutation) under which
its test fails. As in tests/test_verdict_power.py, a mutant is found again by its id: a stale id fails.
"""

from __future__ import annotations

import pytest

import test_bilinear_rows as bil_rows
import test_bilinear_tolerances as bil
import test_diagnosis_target as target
import test_engine_precision as eng_precision
import test_engine_rows as eng_rows
import test_shrink_steps as shrink
import test_verifier_sections as ver
from _mutants import kept_mutant

BILINEAR = "moments_ref/golden/bilinear.py"
VERIFIER = "moments_ref/golden/verifier.py"
SHRINK = "moments_ref/sweep/shrink.py"
DIAGNOSIS = "moments_ref/golden/diagnosis.py"
ENGINE = "moments_ref/golden/engine.py"

# (module, mutant, the test that must fail under it, its fixtures by name, its other arguments)
EXAMPLES = [
    (BILINEAR, "_sample_arrays::4 * ulp(exact, d) -> 4 / ulp(exact, d)#0",
     bil.test_a_value_four_ulps_from_an_all_zero_component_passes_and_five_fail, (), ()),
    (BILINEAR, "_sample_arrays::np.maximum -> np.minimum#0",
     bil.test_the_moments_tolerance_is_the_farthest_corner_plus_eight_ulps_at_least_four_ulps, (), (8,)),
    (BILINEAR, "_grid::2 ** FINER_BITS -> 2 * FINER_BITS#0",
     bil.test_the_finer_weights_are_sixteen_steps_across_the_rectangle_and_the_fraction, (), ()),
    (BILINEAR, "_intensity_arrays::_SAFETY * _float_spread(texels, zf, corners, np.dtype(d)) -> "
               "_SAFETY / _float_spread(texels, zf, corners, np.dtype(d))#0",
     bil.test_the_intensity_tolerance_covers_the_finer_weights_exact_values_plus_sixteen_float_deviations, (), ()),
    (BILINEAR, "_edge_quads::0.015 -> 0.0075#0",
     lambda: bil_rows.test_stiff_rows_are_the_shadow_edges_their_comments_name(bil_rows.fresh_rows()), (), ()),
    (VERIFIER, "_row_error::np.nanmax -> np.nanmin#0",
     ver.test_a_rows_error_is_exact_in_its_metric_and_a_nan_is_infinite, ("folder", "tmp_path"), ()),
    (VERIFIER, "VerifyReport.format:::worst_rows -> :worst_rows + 1#0",
     ver.test_the_printed_report_has_each_section_of_each_case, ("folder", "tmp_path"), ()),
    (VERIFIER, "verify::refuse_meaningless([CASES[n] for n, meta in manifest['cases'].items() if n in CASES and "
               "any((f'{n}.{o}' in results for o in meta['compare']))], profile) -> pass#0",
     ver.test_a_declared_profile_is_used_refused_or_named, ("folder", "tmp_path"), ()),
    (SHRINK, "candidates::abs(cand - near) -> cand - near#0",
     shrink.test_the_receiver_offsets_are_powers_of_ten_from_the_nearest_depth_on_the_receivers_side, (), ()),
    (SHRINK, "shrink::judge.confirm(case, one(inputs), one(got), spec.port_dtype)[0] -> False#0",
     shrink.test_a_port_failing_below_a_receiver_depth_shrinks_to_round_numbers, (), ()),
    (SHRINK, "candidates::8 -> 7#0",
     shrink.test_depths_and_zf_are_rounded_to_0_to_7_decimals_and_weights_to_1_to_5, (), ()),
    (BILINEAR, "_rows::20170724 -> 20170725#0",
     lambda: bil_rows.test_the_rows_are_the_draws_docs_golden_states(bil_rows.fresh_rows()), (), ()),
    (BILINEAR, "_intensity_arrays::np.float64 -> np.float32#2",
     bil.test_a_float64_ports_tolerance_on_the_weight_grid_is_float64_sized, (), ()),
    (SHRINK, "shrink::3 -> 2#0", shrink.test_a_texel_of_another_format_shrinks_to_the_plain_float32_texel_first, (), ()),
    (SHRINK, "_key::np.round(w[w > 0], 17) -> w[w > 0]#0", shrink.test_weights_are_told_apart_to_17_decimals_too, (), ()),
    (SHRINK, "shrink::8 -> 9#0", shrink.test_a_step_confirms_the_first_eight_flagged_candidates_one_row_each,
     ("monkeypatch",), (9,)),
    (ENGINE, "_legit_values::np.float32 -> np.float64#0",
     eng_precision.test_a_float64_port_computing_in_float32_fails_the_float64_engine_case, (), ("engine-lower-float64",)),
    (ENGINE, "_footprints::0 -> 1#2",
     lambda: eng_rows.test_the_engine_rows_are_the_recipes_distributions_and_receivers(eng_rows.engine._engine_rows(
         None, "float32")), (), ()),
    (DIAGNOSIS, "target_groups::~legit -> legit#0",
     target.test_rows_the_papers_target_misses_too_are_not_the_targets, ("singular",), ()),
]


@pytest.mark.parametrize("path, mid, test, fixtures, args", EXAMPLES,
                         ids=[f"{e[0].rsplit('/', 1)[1]}:{e[1].split(' ')[0]}" for e in EXAMPLES])
def test_each_invariant_fails_under_its_kept_mutant(request, path, mid, test, fixtures, args):
    values = [request.getfixturevalue(f) for f in fixtures] + list(args)
    test(*values)  # unmutated: holds
    with kept_mutant(path, mid):
        with pytest.raises((Exception, pytest.fail.Exception)):  # an assertion, the error it raises, a pytest.raises
            test(*values)


folder = ver.folder
singular = target.singular
