"""The sweep's power: one-change mutants of the shipped GLSL ports that every golden case of their function
passes are found by a sweep of at most 10^6 rows and shrunk to a row of at most two depths; the legitimate
variants (fma) pass. The corpus: tests/sweep_mutants/corpus.py."""

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).parent))
from sweep_mutants.corpus import (CAUGHT_BY_THE_GOLDENS, EDGE_ROWS_CATCH, LEGITIMATE, MUTANTS,  # noqa: E402
                                  TIE_BAND_MUTANTS, TIE_RULE)

from moments_ref.conformance import PORTS_DIR, run_case  # noqa: E402
from moments_ref.sweep import CHUNK, Port, SweepSpec, sweep_port  # noqa: E402

pytestmark = pytest.mark.skipif(not (PORTS_DIR / "glsl" / "msm.glsl").is_file(), reason="no shipped ports")

#: Every mutant of the corpus is hit within the first chunk (measured: docs/sweep.md); the tests sweep one.
ROWS = CHUNK


def _port(tmp_path, entry):
    name, file, function, case, old, new, _ = entry
    src = (PORTS_DIR / "glsl" / file).read_text()
    assert old in src, f"{name}: the shipped port changed; update the corpus"
    path = tmp_path / f"{name.replace('/', '_')}.glsl"
    path.write_text(src.replace(old, new, 1))
    return path, function, case


@pytest.mark.slow
@pytest.mark.parametrize("entry", MUTANTS, ids=[m[0] for m in MUTANTS])
def test_mutant_passes_the_goldens_and_the_sweep_finds_and_shrinks_it(ctx, tmp_path, entry):
    path, function, case = _port(tmp_path, entry)
    caught = entry[0] in CAUGHT_BY_THE_GOLDENS
    assert run_case(path, function, case, language="glsl", adapter="gl").passed != caught, \
        "the goldens catch it now: list it in CAUGHT_BY_THE_GOLDENS" if not caught else "the goldens miss it again"
    res = sweep_port(SweepSpec(case, Port(str(path), function, "glsl"), ("gl",), rows=ROWS))
    assert not res.passed
    # a y1 code wrong only within 0.045 code of a tie (TIE_BAND_MUTANTS): the shrinker keeps the texel's four
    # depths where removing one moves y1 out of that window (measured: docs/sweep.md)
    assert len(res.failures[0]["texel"]["depths"]) <= (4 if entry[0] in TIE_BAND_MUTANTS else 2)


@pytest.mark.parametrize("entry", LEGITIMATE[:1], ids=[m[0] for m in LEGITIMATE[:1]])
def test_legitimate_variant_passes(ctx, tmp_path, entry):
    path, function, case = _port(tmp_path, entry)
    res = sweep_port(SweepSpec(case, Port(str(path), function, "glsl"), ("gl",), rows=ROWS), shrink_failures=False)
    assert res.passed


@pytest.mark.slow
@pytest.mark.parametrize("entry", LEGITIMATE[1:], ids=[m[0] for m in LEGITIMATE[1:]])
def test_other_legitimate_variants_pass(ctx, tmp_path, entry):
    test_legitimate_variant_passes(ctx, tmp_path, entry)


def test_the_corpus_has_ten_mutants_of_both_algorithms_that_the_goldens_miss():
    missed = [m for m in MUTANTS if m[0] not in CAUGHT_BY_THE_GOLDENS]
    assert len(missed) >= 10 and {m[3] for m in missed} >= {"shadow_intensity-lower-float32", "shade-float32"}


@pytest.mark.parametrize("case, prefix, mutant", EDGE_ROWS_CATCH, ids=[f"{e[1]}-{e[2]}" for e in EDGE_ROWS_CATCH])
def test_each_golden_edge_row_from_the_sweep_catches_a_mutant_and_passes_the_shipped_port(ctx, tmp_path, case, prefix,
                                                                                         mutant):
    from moments_ref.golden.conventions import profiled_arrays

    _, arrays = profiled_arrays(case)
    rows = [i for i, c in enumerate(arrays["comment"]) if str(c).startswith(prefix)]
    assert len(rows) == 1 and arrays["category"][rows[0]] == "edge"
    entry = next(m for m in MUTANTS if m[0] == mutant)
    assert entry[3] == case
    path, function, _ = _port(tmp_path, entry)
    assert not run_case(path, function, case, language="glsl", adapter="gl").row_pass[rows[0]]
    shipped = run_case(PORTS_DIR / "glsl" / entry[1], function, case, language="glsl", adapter="gl")
    assert shipped.passed and shipped.row_pass[rows[0]]


@pytest.mark.parametrize("mutant", TIE_RULE)
def test_the_per_component_tie_rule_catches_what_the_per_row_rule_let_through(ctx, tmp_path, mutant):
    """One chunk of the mutant on llvmpipe, judged by the per-component rule and by the former per-row rule (the
    case without its ``tie_neighbours``): the per-row rule lets nearly all its wrong rows through."""
    from dataclasses import replace

    import numpy as np

    from moments_ref.golden import CASES
    from moments_ref.sweep import judge, runner
    from moments_ref.sweep.samplers import draw_chunk

    entry = next(m for m in MUTANTS if m[0] == mutant)
    path, function, case_name = _port(tmp_path, entry)
    case = CASES[case_name]
    spec = SweepSpec(case_name, Port(str(path), function, "glsl"), ("gl",), rows=ROWS)
    inputs, _ = draw_chunk(case, 0, 0)
    got = runner.evaluate(spec, inputs, "gl")
    flagged = {}
    for rule, c in (("component", case), ("row", replace(case, tie_neighbours=None))):
        b, ill = judge.legitimate_interval(c, inputs)
        flagged[rule] = judge.flagged_rows(c, inputs, b, ill, got)
    n_comp, n_row = int(flagged["component"].sum()), int(flagged["row"].sum())
    assert n_comp >= 1000 and n_comp >= 20 * n_row, (n_comp, n_row)
    assert not (flagged["row"] & ~flagged["component"]).any()
    first = np.flatnonzero(flagged["component"])[:8]
    assert judge.confirm(case, {k: v[first] for k, v in inputs.items()}, {k: v[first] for k, v in got.items()}).all()


@pytest.mark.parametrize("mutant", TIE_BAND_MUTANTS)
def test_the_derived_tie_band_catches_what_the_quarter_code_let_through(ctx, tmp_path, mutant):
    """One chunk of the mutant (y1 rounded with a biased offset, at most 0.1 code off its boundary) on llvmpipe,
    judged with the tie band derived from the formula and with the former quarter code (golden.texel_codes.TIE_BAND
    for every component): the quarter code accepts every row, the derived band flags the rows beyond it, and
    mpmath confirms them."""
    from dataclasses import replace

    import numpy as np

    from moments_ref.golden import CASES, texel_codes
    from moments_ref.sweep import judge, runner
    from moments_ref.sweep.samplers import draw_chunk

    entry = next(m for m in MUTANTS if m[0] == mutant)
    path, function, case_name = _port(tmp_path, entry)
    case = CASES[case_name]
    quarter = replace(case, tie_neighbours=lambda r: [(texel_codes.pack64_ties(r, band=texel_codes.TIE_BAND)[2]
                                                       .astype(np.uint16),)])
    inputs, _ = draw_chunk(case, 0, 0)
    got = runner.evaluate(SweepSpec(case_name, Port(str(path), function, "glsl"), ("gl",), rows=ROWS), inputs, "gl")
    flagged = {}
    for rule, c in (("derived", case), ("quarter", quarter)):
        b, ill = judge.legitimate_interval(c, inputs)
        flagged[rule] = judge.flagged_rows(c, inputs, b, ill, got)
    n = int(flagged["derived"].sum())
    assert n >= 1000 and not flagged["quarter"].any(), (n, int(flagged["quarter"].sum()))
    first = np.flatnonzero(flagged["derived"])[:8]
    assert judge.confirm(case, {k: v[first] for k, v in inputs.items()}, {k: v[first] for k, v in got.items()}).all()
