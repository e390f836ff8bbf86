"""verify, oracle.check and conformance reach the same verdict on every case a GLSL port covers.

The GLSL ports (shipped, and one-change mutants of them) run on a real OpenGL driver
through ``conformance.run_case``; the same GPU outputs (captured with
``conformance.run_glsl``) go through ``golden.verify`` and ``oracle.check``. The three
agree row by row (conformance judges through ``golden.compare``, the one comparator,
which the spy test below checks). Skipped without an OpenGL 4.3 context (unless CI=true).
"""

from pathlib import Path

import numpy as np
import pytest

from moments_ref import conformance, golden, oracle

from _harness import one_change

FIXTURES = Path(__file__).parent / "fixtures" / "glsl"
CASES = conformance.shipped_cases()  # float32 and float64 cases (a shader computes in float32)
FLOAT32_CASES = [n for n in CASES if n.endswith("-float32")]

# One-change mutants of the shipped GLSL: (name, case, file, function, old text, new text); all bugs.
GLSL_MUTANTS = [
    ("no-v2-clamp", "shade-float32", "nonlinear.glsl", "shade",
     "float v2 = clamp(r.z, 1.0e-6, 1.0 - 1.0e-6);", "float v2 = r.z;"),
    ("no-gap-clamp", "shade-float32", "nonlinear.glsl", "shade",
     "float gap = max(y2 - y1, 1.0e-6);", "float gap = y2 - y1;"),
    ("target-0628", "bias_moments-float32-float32", "msm.glsl", "bias_moments_float32",
     "3.0e-7, vec4(0.0, 0.375, 0.0, 0.375)", "3.0e-7, vec4(0.0, 0.628, 0.0, 0.628)"),
    ("no-bias", "bias_moments-float32-float32", "msm.glsl", "bias_moments_float32",
     "return bias_moments(b, 3.0e-7,", "return bias_moments(b, 0.0,"),
    ("cell-corner", "unpack32-float32", "packing.glsl", "unpack32",
     "precise float y1 = (float(f1) + 1.0) / 511.5 - 1.0;", "precise float y1 = float(f1) / 511.5 - 1.0;"),
    ("cell-centre", "unpack32-float32", "packing.glsl", "unpack32",
     "precise float y1 = (float(f1) + 1.0) / 511.5 - 1.0;", "precise float y1 = (float(f1) + 0.5) / 511.5 - 1.0;"),
    ("xi-nearest", "pack32-float32", "packing.glsl", "pack32",
     "uint x = min(uint(floor(sx)), 63u);", "uint x = min(uint(roundEven(sx)), 63u);"),
    ("v-centre-127", "unpack32-float32", "packing.glsl", "unpack32",
     "precise float sv = (float(v) + 0.5) / 128.0;", "precise float sv = float(v) / 127.0;"),
]
FIXTURE_MUTANTS = [
    ("paper-literal", "shade-float32", "shade_paper_literal.glsl", "shade_paper_literal"),
    ("root-sign", "shade-float32", "shade_root_sign_flipped.glsl", "shade_root_sign_flipped"),
    ("xi-multiplied", "shade-float32", "shade_xi_multiplied.glsl", "shade_xi_multiplied"),
    ("xi-rounded", "pack64-float32", "pack64_xi_rounded.glsl", "pack64_xi_rounded"),
]
#: The papers' printed formulation: killed by all three on the rows flagged printed_hazard alone (issue 37).
PRINTED = [
    ("slides-verbatim", "shadow_intensity-lower-float32", "msm_slides_verbatim.glsl", "ComputeMSMShadowIntensity"),
]


def _three_verdicts(ctx, golden_dir, tmp_path, glsl, function, case, strict=False):
    """``(conformance, verify, oracle.check)`` pass/fail; asserts they fail the same rows."""
    report = conformance.run_case(glsl, function, case, golden_dir=golden_dir, strict=strict)
    meta = golden.load_manifest(golden_dir)["cases"][case]
    arrays = golden.load_case_arrays(golden_dir, case, meta)
    specs = {o: (arrays[o].dtype if meta["exact"] else np.float32, arrays[o].shape) for o in meta["compare"]}
    inputs = {k: arrays[k] for k in meta["input_order"]}  # argument order (``inputs`` is sorted by name)
    got, _ = conformance.run_glsl(conformance.load_source(glsl), function, inputs, specs, ctx=ctx)
    for o in meta["compare"]:  # a porter writes codes in the manifest's dtype (GPU readback: 32-bit words)
        want = arrays[o].dtype
        if meta["exact"] and got[o].dtype != want and got[o].max() <= np.iinfo(want).max:
            got[o] = got[o].astype(want)
    path = tmp_path / "gpu.npz"
    np.savez(path, **{f"{case}.{o}": v for o, v in got.items()})
    result = next(c for c in golden.verify(golden_dir, path, port_dtype="float32", strict=strict).cases
                  if c.name == case)
    # The same GPU outputs, the same rows: a float64 case gives verify the float32 column too.
    assert np.array_equal(report.row_pass, result.verdict.row_pass), (case, report.format())
    outs = tuple(got[o] for o in meta["compare"])
    checked = oracle.check(lambda *a: outs if len(outs) > 1 else outs[0], case, dtype="float32", n_hypothesis=0,
                           strict=strict)
    assert checked.failures == report.failures == int((~result.verdict.row_pass).sum())
    return report.passed, result.status == "pass", checked.passed


def _killed_by_all(verdicts, what):
    assert verdicts == (False, False, False), what


@pytest.mark.parametrize("case", CASES)
def test_shipped_ports_same_verdict(ctx, golden_dir, tmp_path, case):
    path, function = conformance.shipped_port(case)
    assert _three_verdicts(ctx, golden_dir, tmp_path, path, function, case) == (True, True, True)


@pytest.mark.parametrize("name,case,fname,function,old,new", GLSL_MUTANTS, ids=[m[0] for m in GLSL_MUTANTS])
def test_glsl_mutants_killed_by_all_three(ctx, golden_dir, tmp_path, name, case, fname, function, old, new):
    mutant = one_change(tmp_path, conformance.GLSL_DIR, fname, old, new)  # beside the file's includes
    _killed_by_all(_three_verdicts(ctx, golden_dir, tmp_path, mutant, function, case), name)


@pytest.mark.parametrize("name,case,fname,function", FIXTURE_MUTANTS, ids=[m[0] for m in FIXTURE_MUTANTS])
def test_glsl_fixture_mutants_killed_by_all_three(ctx, golden_dir, tmp_path, name, case, fname, function):
    _killed_by_all(_three_verdicts(ctx, golden_dir, tmp_path, FIXTURES / fname, function, case), name)


@pytest.mark.parametrize("name,case,fname,function", PRINTED, ids=[m[0] for m in PRINTED])
def test_glsl_printed_formulation_killed_by_all_three_on_hazard_rows_only(ctx, golden_dir, tmp_path, name, case,
                                                                          fname, function):
    _killed_by_all(_three_verdicts(ctx, golden_dir, tmp_path, FIXTURES / fname, function, case), name)
    report = conformance.run_case(FIXTURES / fname, function, case, golden_dir=golden_dir, worst_rows=50)
    bad = [r for r in report.worst if not r["passed"]]
    assert report.failures == len(bad) and bad and all("printed_hazard" in r["flags"] for r in bad), bad


def test_conformance_judges_through_golden_compare(ctx, golden_dir, monkeypatch):
    # No second set of rules: conformance's verdict is golden.compare's, whatever that says.
    from moments_ref.conformance import verdict
    from moments_ref.golden.compare import compare as real_compare

    calls = []

    def spy(entry, expected, candidate, port_dtype=None, case="", strict=False, neighbourhood=None):
        calls.append((case, port_dtype))
        v = real_compare(entry, expected, candidate, port_dtype, case, strict, neighbourhood)
        v.row_pass[:] = False
        v.score[:] = np.inf
        return v

    monkeypatch.setattr(verdict, "compare", spy)
    path, function = conformance.shipped_port("psi4-float32")
    report = conformance.run_case(path, function, "psi4-float32", golden_dir=golden_dir)
    assert calls == [("psi4-float32", "float32")]
    assert not report.passed and report.failures == report.rows
