"""golden.diagnosis: advice on ports whose failing rows have a cause known by construction.

Each port here is written in the test from an independent statement of what it does (the float32
reference at its own receiver zf − 1e-5; a receiver mapped from [0, 1] inside; a result the caller
would clamp; Algorithm 3 with the author's 5e-6 clamp; the Hausdorff bound of depths in [0, 1]),
so the cause of its failures is known before the diagnosis runs. The diagnosis must name exactly
that cause, on exactly the failing rows, and declaring it must make the port pass (the advice is
right, not only given). Ports with another bug on many of their failing rows, or an arithmetic
bug, get no advice. Driver-free and fast: numpy ports, one golden folder per case.
"""

from __future__ import annotations

import numpy as np
import pytest

from moments_ref import golden, hausdorff
from moments_ref.golden.profile import parse_profile
from mutants import ports

from _oracles import golden_folder

CASE = "shadow_intensity-lower-float32"


def _base(name=CASE):
    gdir = golden_folder((name,))
    with np.load(gdir / f"{name}.npz") as g:
        return gdir, {k: g[k] for k in g.files}


def _verify(tmp_path, got, profile=None, name=CASE, output="intensity"):
    gdir, _ = _base(name)
    np.savez(tmp_path / "r.npz", **{f"{name}.{output}": np.asarray(got)})
    return golden.verify(gdir, tmp_path / "r.npz", profile=profile).cases[0]


def _ref(b, zf):
    """The float32 reference of Algorithm 1 (the golden's own port of the slides)."""
    g = golden.CASES[CASE]
    return golden.evaluate_reference(g, {"b": b, "zf": zf}, g.dtype)[0]


def _offset(base):
    return _ref(base["b"], (base["zf"] - np.float32(1e-5)).astype(np.float32))


def _unit_receiver(base):
    # the port maps a receiver it believes in [0, 1] to the moments' [-1, 1] inside: 2 z - 1
    return _ref(base["b"], (np.float32(2) * base["zf"] - np.float32(1)).astype(np.float32))


def _unclamped(base):
    # fully shadowed rows overshoot [0, 1] by 0.01: the caller clamps the result on its next line
    v = _ref(base["b"], base["zf"])
    return np.where(v >= 1 - 1e-6, v + np.float32(0.01), v).astype(np.float32)


#: port, the advice's level and flags, the profile that declares that cause
ADVICE = {
    "receiver offset": (_offset, "convention", "receiver_offset = 1e-05", {"receiver_offset": 1e-5}),
    "receiver in [0, 1]": (_unit_receiver, "convention", "receiver_depth = '[0,1]'", {"receiver_depth": "[0,1]"}),
    "caller's clamp": (_unclamped, "convention", "output_clamp = true", {"output_clamp": True}),
}


@pytest.mark.parametrize("what", list(ADVICE))
def test_a_ports_known_convention_is_named_on_every_failing_row_and_declaring_it_passes(tmp_path, what):
    port, level, flags, declare = ADVICE[what]
    _, base = _base()
    got = port(base)
    case = _verify(tmp_path, got)
    failing = np.flatnonzero(~case.verdict.row_pass).tolist()
    assert case.status == "fail" and failing
    assert (case.groups[0].level, case.groups[0].flags) == (level, flags)
    assert case.groups[0].rows == failing  # exactly the failing rows, no passing one
    assert [g for g in case.groups if g.level == level] == [case.groups[0]]
    # declared, on the goldens written under that profile (the inputs such a port is given): it passes
    declared = parse_profile(declare)
    gdir = tmp_path / "declared"
    golden.write(gdir, [CASE], profile=declared)
    with np.load(gdir / f"{CASE}.npz") as g:
        np.savez(tmp_path / "d.npz", **{f"{CASE}.intensity": port({"b": g["b"], "zf": g["zf"]})})
    assert golden.verify(gdir, tmp_path / "d.npz", profile=declared).cases[0].status == "pass"


@pytest.mark.parametrize("what, which", [("receiver offset", 0), ("receiver offset", -1), ("caller's clamp", -1)])
def test_no_advice_when_one_failing_row_has_another_cause(tmp_path, what, which):
    # the convention explains every failing row but one, which is wrong for another reason (its value mirrored, or
    # 0): declaring the convention would leave that failure, so it is not advised; the first failing row, or the
    # last (beyond the few rows a candidate is tried on first, diagnosis.SAMPLE_ROWS, where only the judgement on
    # every row sees it)
    from moments_ref.golden.diagnosis import SAMPLE_ROWS

    port, level, flags, declare = ADVICE[what]
    _, base = _base()
    got = port(base)
    failing = np.flatnonzero(~_verify(tmp_path, got).verdict.row_pass)
    assert len(failing) > SAMPLE_ROWS or what == "caller's clamp"
    bug = got.copy()
    # a row flagged printed_hazard keeps its own cause (the papers' formula cancels there) and may stay failing
    # beside an advised convention: the row made wrong here is another
    hazard = np.char.find(base["flags"].astype(str), "printed_hazard") >= 0
    i = failing[~hazard[failing]][which]
    bug[i] = np.float32(1) - bug[i] if abs(bug[i] - 0.5) > 0.1 else np.float32(0)
    case = _verify(tmp_path, bug)
    assert case.status == "fail" and case.verdict.failures == len(failing)
    assert all(g.level != level for g in case.groups)
    assert _verify(tmp_path, bug, parse_profile(declare)).verdict.failures == 1


def test_the_authors_clamp_in_algorithm_3_is_named_a_convention(tmp_path):
    name = "shade-float32"
    _, base = _base(name)
    got = ports.alg3(base["r"], base["zf"], {"clamp": 5e-6, "no_xi_guard": True})
    case = _verify(tmp_path, got, name=name)
    assert case.status == "fail" and case.groups[0].level == "convention"
    assert case.groups[0].flags.startswith("clamp = 5e-06, clamp_test = ")
    assert case.groups[0].rows == np.flatnonzero(~case.verdict.row_pass).tolist()


def test_a_convention_is_found_under_a_declared_slope_whose_feed_depends_on_the_rows(tmp_path):
    # receiver_slope declared and honoured; the caller's clamp not: the advice names output_clamp
    from moments_ref.golden.conventions import profiled_arrays

    declared = parse_profile({"receiver_slope": 1e-4})
    _, base = _base()
    slope = profiled_arrays(CASE, declared, arrays=base)[1]["slope"]
    v = _ref(base["b"], (base["zf"] - np.float32(1e-4) * slope).astype(np.float32))
    assert _verify(tmp_path, v, declared).status == "pass"
    got = np.where(v >= 1 - 1e-6, v + np.float32(0.01), v).astype(np.float32)
    case = _verify(tmp_path, got, declared)
    assert case.status == "fail"
    assert (case.groups[0].level, case.groups[0].flags) == ("convention", "output_clamp = true")
    assert case.groups[0].rows == np.flatnonzero(~case.verdict.row_pass).tolist()


def test_an_arithmetic_bug_gets_no_convention_or_format_advice(tmp_path):
    _, base = _base()
    case = _verify(tmp_path, ports.alg1(base["b"], base["zf"], {"factor": 1.03}))
    assert case.status == "fail"
    assert {g.level for g in case.groups} <= {"contract", "robustness"}


# ---------------------------------------------------------------------------
# bound = "hausdorff": Peters and Klein's bound of depths in [0, 1], judged as Algorithm 1


UNIT = {"depth": "[0,1]"}


def _unit_inputs(base, profile):
    """What a port under ``profile`` receives: the golden's moments and receivers in [0, 1]."""
    from moments_ref.golden.conventions import convert_inputs

    ins = convert_inputs(golden.CASES[CASE], {"b": base["b"], "zf": base["zf"]}, profile)
    return np.asarray(ins["b"], np.float64), np.asarray(ins["zf"], np.float64)


def _hausdorff_port(base, profile, bound="lower"):
    b, zf = _unit_inputs(base, profile)
    return hausdorff.shadow_intensity(b, zf, bound)


@pytest.mark.parametrize("output", ["intensity", "visibility"])
def test_a_hausdorff_port_is_advised_bound_hausdorff_on_its_failing_rows(tmp_path, output):
    profile = parse_profile(dict(UNIT, output=output))
    got = _hausdorff_port(_base()[1], profile)
    got = 1 - got if output == "visibility" else got
    case = _verify(tmp_path, got.astype(np.float32), profile)
    failing = np.flatnonzero(~case.verdict.row_pass).tolist()
    assert case.status == "fail" and len(failing) > 10
    advice = [g for g in case.groups if g.flags == 'bound = "hausdorff"']
    assert len(advice) == 1 and advice[0].level == "convention"
    assert advice[0].rows == failing  # the exact bound explains every failing row, and only failing rows


def test_no_bound_advice_where_another_bug_fails_most_rows(tmp_path):
    # the exact Hausdorff bound, but 0.25 too low on 100 rows it would pass: 54 of 154 failing rows (35 %)
    # are Hausdorff's; the rest another bug, below the bound (a check without |.| would take them)
    profile = parse_profile(UNIT)
    _, base = _base()
    got = _hausdorff_port(base, profile)
    v = _verify(tmp_path, got.astype(np.float32), profile).verdict
    passing = np.flatnonzero(v.row_pass & ~v.robust)  # contract rows it passes
    bug = got.copy()
    bug[passing[:100]] -= 0.25
    case = _verify(tmp_path, bug.astype(np.float32), profile)
    assert case.status == "fail" and case.verdict.failures == 154
    assert not [g for g in case.groups if "hausdorff" in g.flags]


def test_no_bound_advice_for_the_upper_hausdorff_bound_on_the_lower_case(tmp_path):
    profile = parse_profile(UNIT)
    case = _verify(tmp_path, _hausdorff_port(_base()[1], profile, "upper").astype(np.float32), profile)
    assert case.status == "fail"
    assert not [g for g in case.groups if "hausdorff" in g.flags]


# ---------------------------------------------------------------------------
# A singular bias target (engine cases): the rows whose biased moments stay singular, named with the target


def _engine(depth, target, output="intensity", alpha=3e-6):
    """``(verdict, arrays, declared bias, ctx)`` of an Algorithm 1 port without the singular branch, biased
    inside toward ``target`` as the profile declares."""
    from moments_ref.golden.compare import compare
    from moments_ref.golden.conventions import profiled_arrays
    from moments_ref.golden.writer import manifest_entry

    p = parse_profile({"depth": depth, "output": output,
                       "bias": {"alpha": alpha, "target": list(target), "applied": "inside"}})
    case, arrays = profiled_arrays("engine-lower-float32", p)
    got = ports.alg1(arrays["b"], arrays["zf"], {"literal_root": True, "no_singular": True,
                                                  "visibility": output == "visibility", "bias": (alpha, target)})
    v = compare(manifest_entry(case, arrays), arrays, {"intensity": got}, case=case.name)
    return v, arrays, p.bias, case.engine


def _moments(points):
    return [sum(w * z ** k for z, w in points) for k in range(1, 5)]


@pytest.mark.parametrize("depth, points, output, words, alpha", [
    ("[-1,1]", [(0.3, 1.0)], "intensity", "1·δ(0.3), a one-point distribution", 3e-6),
    ("[-1,1]", [(-1.0, 0.5), (1.0, 0.5)], "intensity", "0.5·δ(-1) + 0.5·δ(1), a two-point distribution", 3e-6),
    ("[0,1]", [(0.0, 0.5), (1.0, 0.5)], "visibility", "0.5·δ(0) + 0.5·δ(1), a two-point distribution", 3e-6),
    # the 16-bit α: large enough that the papers' own target, the comparison, must be read in the profile's frame
    ("[0,1]", [(0.0, 0.5), (1.0, 0.5)], "visibility", "0.5·δ(0) + 0.5·δ(1), a two-point distribution", 6e-5),
])
def test_a_singular_target_is_named_on_exactly_the_rows_it_leaves_singular(depth, points, output, words, alpha):
    from moments_ref.golden.diagnosis import target_groups

    target = _moments(points)
    v, arrays, bias, ctx = _engine(depth, target, output, alpha)
    failing = np.flatnonzero(~v.row_pass).tolist()
    assert failing
    gs = target_groups(v, arrays, bias, ctx)
    assert len(gs) == 1 and gs[0].level == "target" and gs[0].rows == failing
    assert gs[0].flags == f"bias target {target}" and words in gs[0].cause
    # independently: each such row's distribution, biased toward the target, stays (nearly) singular: the
    # smallest eigenvalue of its 3x3 Hankel matrix is of the order of α (a distribution of one or two depth
    # clusters plus the target's points; a generic distribution's is orders above α). Float64 sums, numpy's
    # eigvalsh: not the diagnosis's code.
    for i in failing:
        m = np.asarray(arrays["mass"][i], np.float64)
        z = np.asarray(arrays["support"][i], np.float64)
        b = [float((m * z ** k).sum() / m.sum()) for k in range(1, 5)]
        b = [(1 - alpha) * x + alpha * t for x, t in zip(b, target)]
        h = np.array([[1, b[0], b[1]], [b[0], b[1], b[2]], [b[1], b[2], b[3]]])
        assert np.linalg.eigvalsh(h)[0] <= 4 * alpha, (i, np.linalg.eigvalsh(h)[0])


def test_no_target_group_without_a_singular_target_or_for_rows_it_does_not_explain():
    from moments_ref.golden.diagnosis import target_groups

    v, arrays, bias, ctx = _engine("[-1,1]", [0.0, 0.375, 0.0, 0.375])  # the papers' float32 target: interior
    assert target_groups(v, arrays, None, ctx) == []  # no declaration
    # the port biased toward the interior target passes; the same verdict with one row failing for another cause
    assert v.passed
    v.row_pass[np.flatnonzero(arrays["category"] == "random")[0]] = False
    assert target_groups(v, arrays, bias, ctx) == []
    # a singular target declared, but the only failing row is one whose distribution it does not leave singular
    target = _moments([(-1.0, 0.5), (1.0, 0.5)])
    v, arrays, bias, ctx = _engine("[-1,1]", target)
    explained = set(np.flatnonzero(~v.row_pass).tolist())
    other = next(i for i in range(len(v.row_pass)) if i not in explained and arrays["category"][i] == "random")
    v.row_pass[:] = True
    v.row_pass[other] = False
    assert target_groups(v, arrays, bias, ctx) == []


@pytest.mark.parametrize("offset", [1e-6, 1e-5, 1e-4, 1e-3])
def test_each_documented_receiver_offset_is_told_by_its_outputs(tmp_path, offset):
    # the acne guards engines use (diagnosis.OFFSET_CANDIDATES, docs/ports.md): a port at zf - offset is advised that
    # offset, not a neighbouring one
    _, base = _base()
    got = _ref(base["b"], (base["zf"] - np.float32(offset)).astype(np.float32))
    case = _verify(tmp_path, got)
    assert case.status == "fail"
    assert (case.groups[0].level, case.groups[0].flags) == ("convention", f"receiver_offset = {offset:g}")
    assert case.groups[0].rows == np.flatnonzero(~case.verdict.row_pass).tolist()


def test_a_passing_port_and_a_case_the_package_does_not_know_get_no_advice(tmp_path):
    from moments_ref.golden.diagnosis import convention_groups
    from moments_ref.golden.profile import DEFAULT

    _, base = _base()
    got = _ref(base["b"], base["zf"])  # the golden's own float32 reference: passes
    case = _verify(tmp_path, got)
    assert case.status == "pass" and case.groups == []
    assert convention_groups(CASE, case.verdict, base, {"intensity": got}, DEFAULT) == []
    # a failing verdict of a case name outside the package's cases: nothing to try
    failing = _verify(tmp_path, _offset(base)).verdict
    assert convention_groups("foreign-case", failing, base, {"intensity": _offset(base)}, DEFAULT) == []


def test_the_bound_advice_on_a_single_failing_row_needs_that_row_explained(tmp_path):
    # the expected values themselves (a passing port) with one row replaced: by the Hausdorff bound there (a row
    # where it differs from Algorithm 1's beyond the band), advised on that row; by another wrong value, not
    from moments_ref.golden.conventions import profiled_arrays

    profile = parse_profile(UNIT)
    _, base = _base()
    expected = np.asarray(profiled_arrays(CASE, profile, arrays=base)[1]["intensity"], np.float64)
    h = _hausdorff_port(base, profile)
    i = np.flatnonzero(~_verify(tmp_path, h.astype(np.float32), profile).verdict.row_pass)[0]
    one = expected.copy()
    one[i] = h[i]
    case = _verify(tmp_path, one.astype(np.float32), profile)
    assert np.flatnonzero(~case.verdict.row_pass).tolist() == [i]
    advice = [g for g in case.groups if "hausdorff" in g.flags]
    assert len(advice) == 1 and advice[0].rows == [i]
    wrong = expected.copy()
    wrong[i] = h[i] + (0.3 if h[i] < 0.5 else -0.3)
    case = _verify(tmp_path, wrong.astype(np.float32), profile)
    assert np.flatnonzero(~case.verdict.row_pass).tolist() == [i]
    assert not [g for g in case.groups if "hausdorff" in g.flags]


def test_arrays_that_are_not_per_row_stay_whole_when_a_candidate_is_tried_on_a_few_rows(tmp_path):
    # golden.diagnosis tries a candidate first on a few failing rows (SAMPLE_ROWS), picking those rows of every
    # per-row array; a whole-case array (a scalar, a table of another length) is kept as it is, and the advice
    # is the same as without it
    from moments_ref.golden.diagnosis import convention_groups
    from moments_ref.golden.profile import DEFAULT

    _, base = _base()
    got = _offset(base)
    v = _verify(tmp_path, got).verdict
    arrays = dict(base, whole=np.array(0.5), table=np.arange(5.0))
    gs = convention_groups(CASE, v, arrays, {"intensity": got}, DEFAULT)
    assert [(g.flags, g.rows) for g in gs] == [("receiver_offset = 1e-05", np.flatnonzero(~v.row_pass).tolist())]


def test_an_undeclared_offset_is_found_under_a_declared_slope(tmp_path):
    # receiver_slope declared (zf - 1e-4 slope), and a constant 1e-5 on top undeclared: the advice is the offset,
    # judged on every row with the slopes the port was given (a few rows derived alone would get other slopes:
    # receiver.slopes draws them for the row count)
    from moments_ref.golden.conventions import profiled_arrays

    declared = parse_profile({"receiver_slope": 1e-4})
    _, base = _base()
    slope = profiled_arrays(CASE, declared, arrays=base)[1]["slope"]
    got = _ref(base["b"], (base["zf"] - np.float32(1e-4) * slope - np.float32(1e-5)).astype(np.float32))
    case = _verify(tmp_path, got, declared)
    assert case.status == "fail"
    assert (case.groups[0].level, case.groups[0].flags) == ("convention", "receiver_offset = 1e-05")
    assert case.groups[0].rows == np.flatnonzero(~case.verdict.row_pass).tolist()


def test_a_float64_hausdorff_port_is_advised_within_its_float64_band(tmp_path):
    # the float64 case: the port's band is a few float64 ulps, so the bound must be computed in float64 on the
    # inputs the port was given to explain its rows. (Where the bound has no value, NaN on a bias_floor row, the
    # port returns Algorithm 1's expected value: it passes there.)
    from moments_ref.golden.conventions import convert_inputs, profiled_arrays

    name = "shadow_intensity-lower-float64"
    profile = parse_profile(UNIT)
    _, base = _base(name)
    ins = convert_inputs(golden.CASES[name], {"b": base["b"], "zf": base["zf"]}, profile)
    h = hausdorff.shadow_intensity(np.asarray(ins["b"], np.float64), np.asarray(ins["zf"], np.float64), "lower")
    expected = np.asarray(profiled_arrays(name, profile, arrays=base)[1]["intensity"], np.float64)
    got = np.where(np.isfinite(h), h, expected)
    case = _verify(tmp_path, got, profile, name=name)
    failing = np.flatnonzero(~case.verdict.row_pass).tolist()
    assert case.verdict.port_dtype == "float64" and len(failing) > 10
    advice = [g for g in case.groups if g.flags == 'bound = "hausdorff"']
    assert len(advice) == 1 and advice[0].rows == failing


def test_json_rows_give_a_rows_text_and_float_inputs_flat_and_its_integer_codes_as_they_are():
    # --json rows: float and text values of a row are listed flat (a (2, 2) entry as four values), integer codes
    # keep their shape (readback words per texel)
    from types import SimpleNamespace

    from moments_ref.golden.diagnosis import json_rows

    arrays = {"tc_id": np.array([1]), "category": np.array(["random"]), "flags": np.array([""]),
              "comment": np.array([""]), "t": np.array([[["a", "b"], ["c", "d"]]]),
              "f": np.array([[[0.5, 1.5], [2.5, 3.5]]]), "q": np.array([[[1, 2], [3, 4]]], np.uint16),
              "y": np.array([1.0])}
    v = SimpleNamespace(row_pass=np.array([True]), strict_pass=None, robust=None, level=np.array(["contract"]),
                        error=np.array([0.0]), tolerance=np.array([1.0]), passed=True, strict=False, failures=0,
                        robustness_tally=lambda: {})
    doc = json_rows("toy", {"compare": ["y"], "input_order": ["t", "f", "q"]}, arrays, {"y": np.array([1.0])}, v)
    assert doc["rows"][0]["inputs"] == {"t": ["a", "b", "c", "d"], "f": [0.5, 1.5, 2.5, 3.5], "q": [[1, 2], [3, 4]]}
