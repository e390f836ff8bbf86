"""golden.verify's report, section by section, on a hand-built golden folder with failures placed by hand.

Independent statements: the printed lines are written out here from the report's documented layout;
a row's error is |got − expected| (in ulps of the expected value for an ``ulps`` case, the code
difference for an ``exact`` one), computed here in exact rationals; a NaN output is an infinite
error; a vector row's error is its worst component's and its tolerance its narrowest component's; a
declared profile is used (a 4-bit filter passes under it and fails without), refused when no
verified case can use it, and named where a case ignores it.
"""

from __future__ import annotations

import json
import math
import re
from fractions import Fraction
from types import SimpleNamespace

import numpy as np
import pytest

from moments_ref import InputError, golden
from moments_ref.golden.diagnosis import group_lines
from moments_ref.golden.profile import parse_profile

PSI, INV, CODES, PHI, BIL = ("psi4-float32", "psi4_inverse-float32", "encode_unorm16-float32", "phi-float32",
                             "sample_bilinear-float32")


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    d = tmp_path_factory.mktemp("g")
    golden.write(d, [PSI, INV, CODES, PHI, BIL])
    g = {}
    for name in (PSI, INV, CODES, PHI, BIL):
        with np.load(d / f"{name}.npz") as z:
            g[name] = {k: z[k] for k in z.files}
    return d, g


def _save(tmp_path, arrays, name="r.npz"):
    p = tmp_path / name
    np.savez(p, **arrays)
    return p


def _exact_port(g, name, out):
    """Expected values in the port's dtype (float32 rounding of a float64 expected value, else the codes)."""
    e = g[name][out]
    return e.astype(np.float32) if e.dtype.kind == "f" else e.copy()


def test_the_printed_report_has_each_section_of_each_case(folder, tmp_path):
    d, g = folder
    e, t = g[PSI]["u"], g[PSI]["u_tolerance_float32"]
    cat = g[PSI]["category"]
    rnd = np.flatnonzero(cat == "random")
    got = e.copy()
    for i, k in zip(rnd[:3], (10.0, -6.0, 3.0)):
        got[i] = e[i] + k * t[i]
    p = _save(tmp_path, {f"{PSI}.u": got.astype(np.float32), f"{INV}.xi4": _exact_port(g, INV, "xi4")})
    report = golden.verify(d, p)
    by = {c.name: c for c in report.cases}
    assert [by[n].status for n in (PSI, INV, CODES, PHI, BIL)] == ["fail", "pass", "missing", "missing", "missing"]
    assert by[CODES].port_dtype == "float32" and by[CODES].worst == [] and by[CODES].per_category == {}
    assert report.failed and {c.name for c in report.checked} == {PSI, INV}
    n = len(cat)
    text = report.format(worst_rows=2)
    lines = text.splitlines()
    assert lines[0] == f"FAIL  {PSI} (port dtype float32): 3 of {n} rows fail"
    r_rows = int((cat == "random").sum())
    assert f"      random rows {r_rows:4d}  failures    3  worst error/tolerance 10" in lines
    for c in set(cat.tolist()) - {"random"}:
        assert re.search(rf"^      {c:6} rows {int((cat == c).sum()):4d}  failures    0  worst error/tolerance ",
                         text, re.M)
    row_lines = [x for x in lines if x.startswith("      row ")]
    assert len(row_lines) == 2 and row_lines[0].startswith(
        f"      row {rnd[0]} (tc_id {g[PSI]['tc_id'][rnd[0]]}) [random] error ")
    assert f" > {by[PSI].worst[0]['tolerance']:.3g}: got " in row_lines[0] and "; xi4=" in row_lines[0]
    assert lines[lines.index(row_lines[0]) + 1] == f"        ({g[PSI]['comment'][rnd[0]]})"
    # the diagnosis' group lines of the failing case, indented under it
    gl = group_lines(by[PSI].groups, 3)
    assert gl and all(f"      {x}" in lines for x in gl) and any(re.match(r"\d+ of 3 failures", x) for x in gl)
    assert f"PASS  {INV} (port dtype float32)" in lines
    assert lines[-2:] == ["not in the results (not checked): 3 cases", "1 passed, 1 failed"]
    every = report.format(worst_rows=None).splitlines()
    assert len([x for x in every if x.startswith("      row ")]) == 3
    assert len([x for x in every if x.startswith("        (")]) == 3
    # the same results with every row right: nothing fails
    ok = _save(tmp_path, {f"{PSI}.u": _exact_port(g, PSI, "u"), f"{INV}.xi4": _exact_port(g, INV, "xi4")}, "ok.npz")
    good = golden.verify(d, ok)
    assert not good.failed and good.format().splitlines()[-1] == "2 passed, 0 failed"


def test_the_robustness_line_counts_and_says_whether_it_is_gated():
    from moments_ref.golden.verifier import _robustness_line

    def verdict(rows, strict):
        t = {"rows": rows, "would_fail": 4, "nonfinite": 1, "outside_range": 2}
        return SimpleNamespace(strict=strict, robustness_tally=lambda: t)

    assert _robustness_line(verdict(0, False)) == []
    assert _robustness_line(verdict(7, False)) == [
        "beyond the algorithm's contract: 7 rows, 4 outside their tolerance (1 NaN or infinite, 2 out of range); "
        "not gated; --strict gates them"]
    assert _robustness_line(verdict(7, True))[0].endswith("out of range); gated (--strict)")


def test_a_rows_error_is_exact_in_its_metric_and_a_nan_is_infinite(folder, tmp_path):
    d, g = folder
    # abs: |got - expected| with expected in float64 (not rounded to float32 first)
    e, t = g[PSI]["u"], g[PSI]["u_tolerance_float32"]
    i, j = np.flatnonzero(e != e.astype(np.float32))[:2]
    got = _exact_port(g, PSI, "u")
    got[i] = np.float32(e[i] + 7 * t[i])
    got[j] = np.nan
    # ulps: in ulps of the expected value, here in float32 (2^(floor(log2 |e|) − 23) for a normal e)
    ei = g[INV]["xi4"]
    k = int(np.flatnonzero((np.abs(ei) > 1e-3) & (ei != ei.astype(np.float32)))[0])
    step = 2.0 ** (np.floor(np.log2(abs(ei[k]))) - 23)
    inv = _exact_port(g, INV, "xi4")
    inv[k] = np.float32(ei[k] + 3 * step * max(1.0, g[INV]["xi4_tolerance_float32"][k]))
    # exact: the largest code difference of the row's four codes; the tolerance is 0
    codes = _exact_port(g, CODES, "u")
    codes[5, 2] += 3
    codes[5, 0] -= 1
    # a vector row: the worst component's error, the narrowest component's tolerance
    r, rt = g[PHI]["r"], g[PHI]["r_tolerance_float32"]
    m = int(np.flatnonzero(np.ptp(rt, axis=1) > 0)[0])
    phi = _exact_port(g, PHI, "r")
    phi[m, 1] = np.float32(r[m, 1] + 50 * rt[m].max())
    rep = golden.verify(d, _save(tmp_path, {f"{PSI}.u": got, f"{INV}.xi4": inv, f"{CODES}.u": codes,
                                            f"{PHI}.r": phi}))
    by = {c.name: {w["index"]: w for w in c.worst} for c in rep.cases}
    assert by[PSI][i]["error"] == float(abs(Fraction(float(got[i])) - Fraction(float(e[i]))))
    assert by[PSI][j]["error"] == np.inf and by[PSI][i]["tolerance"] == t[i]
    want = abs(Fraction(float(inv[k])) - Fraction(float(ei[k]))) / Fraction(step)
    assert by[INV][k]["error"] == pytest.approx(float(want), rel=1e-12)
    assert by[CODES][5]["error"] == 3.0 and by[CODES][5]["tolerance"] == 0.0
    w = by[PHI][m]
    assert w["error"] == pytest.approx(float(abs(Fraction(float(phi[m, 1])) - Fraction(float(r[m, 1])))), rel=1e-12)
    assert w["tolerance"] == rt[m].min() < rt[m].max()
    assert w["flags"] == str(g[PHI]["flags"][m]) and w["category"] == str(g[PHI]["category"][m])


def test_a_declared_profile_is_used_refused_or_named(folder, tmp_path):
    d, g = folder
    a = g[BIL]
    f = np.asarray(a["fraction"], np.float64)
    s = 16.0  # a 4-bit filter: weights on the 1/16 grid (nearest), lerps in float64 then rounded once
    wx, wy = np.floor(f[:, 0] * s + 0.5) / s, np.floor(f[:, 1] * s + 0.5) / s
    t = np.asarray(a["texels"], np.float64).reshape(-1, 4, 4)
    b = ((1 - wx) * (1 - wy))[:, None] * t[:, 0] + (wx * (1 - wy))[:, None] * t[:, 1] + \
        ((1 - wx) * wy)[:, None] * t[:, 2] + (wx * wy)[:, None] * t[:, 3]
    p = _save(tmp_path, {f"{BIL}.b": b.astype(np.float32), f"{PSI}.u": _exact_port(g, PSI, "u")})
    plain = {c.name: c for c in golden.verify(d, p).cases}
    assert plain[BIL].status == "fail" and plain[PSI].message == ""
    four = parse_profile({"format": {"subtexel_bits": 4}})
    declared = {c.name: c for c in golden.verify(d, p, profile=four).cases}
    assert declared[BIL].status == "pass" and declared[PSI].status == "pass"
    assert declared[PSI].message.startswith("profile keys this case ignores: ") and "format (" in \
        declared[PSI].message and declared[BIL].message == ""
    # the default profile is no declaration
    same = {c.name: c for c in golden.verify(d, p, profile=parse_profile({})).cases}
    assert same[BIL].status == "fail" and same[PSI].message == ""
    # a key that no verified case can use is refused, naming it
    with pytest.raises(InputError, match="format: no selected case can use it"):
        golden.verify(d, _save(tmp_path, {f"{PSI}.u": _exact_port(g, PSI, "u")}, "psi.npz"), profile=four)


def test_a_folder_written_for_a_profile_is_verified_with_it_or_without_and_refused_with_another(tmp_path):
    d = tmp_path / "four"
    golden.write(d, [BIL], profile=parse_profile({"format": {"subtexel_bits": 4}}))
    assert json.loads((d / "manifest.json").read_text())["profile_key"] is not None
    with np.load(d / f"{BIL}.npz") as z:
        e, tol = z["b"], z["b_tolerance_float32"]
    got = e + 0.9 * tol  # within the 4-bit tolerance (which a default folder's would not hold)
    p = _save(tmp_path, {f"{BIL}.b": got.astype(np.float32)})
    assert golden.verify(d, p).cases[0].status == "pass"
    assert golden.verify(d, p, profile=parse_profile({"format": {"subtexel_bits": 4}})).cases[0].status == "pass"
    with pytest.raises(InputError, match="another profile"):
        golden.verify(d, p, profile=parse_profile({"format": {"subtexel_bits": 6}}))


def test_bad_arguments_and_results_matching_nothing_are_refused(folder, tmp_path):
    d, g = folder
    p = _save(tmp_path, {f"{PSI}.u": _exact_port(g, PSI, "u")})
    with pytest.raises(InputError, match="port_dtype"):
        golden.verify(d, p, port_dtype="float16")
    with pytest.raises(InputError):
        golden.verify(d, _save(tmp_path, {"x": np.zeros(3)}, "none.npz"))


def test_a_float64_port_is_judged_in_float64_and_its_ulps_are_float64_ulps(tmp_path):
    d = tmp_path / "g64"
    golden.write(d, ["psi4-float64", "psi4_inverse-float64"])
    with np.load(d / "psi4-float64.npz") as z:
        e, t = z["u"], z["u_tolerance_float64"]
    with np.load(d / "psi4_inverse-float64.npz") as z:
        ei, ti = z["xi4"], z["xi4_tolerance_float64"]
    i = int(np.flatnonzero((e > 0.1) & (t < 1e-9))[0])
    got = e.copy()
    got[i] = e[i] + 5 * t[i]  # a float64 error far below float32's resolution
    k = int(np.flatnonzero(np.abs(ei) > 1e-3)[0])
    step = 2.0 ** (math.frexp(abs(float(ei[k])))[1] - 1 - 52)  # a float64 ulp of the expected value
    inv = ei.copy()
    inv[k] = ei[k] + 3 * max(1.0, float(ti[k])) * step
    rep = golden.verify(d, _save(tmp_path, {"psi4-float64.u": got, "psi4_inverse-float64.xi4": inv}),
                        port_dtype="float64")
    by = {c.name: {w["index"]: w for w in c.worst} for c in rep.cases}
    assert by["psi4-float64"][i]["error"] == float(abs(Fraction(float(got[i])) - Fraction(float(e[i]))))
    want = abs(Fraction(float(inv[k])) - Fraction(float(ei[k]))) / Fraction(step)
    assert by["psi4_inverse-float64"][k]["error"] == pytest.approx(float(want), rel=1e-9)


def test_a_failing_rows_flags_are_its_goldens(folder, tmp_path):
    d, g = folder
    a = g[BIL]
    flagged = np.flatnonzero(np.char.str_len(a["flags"].astype(str)) > 0)
    got = a["b"].astype(np.float32)
    got[flagged[:3], 0] += np.float32(0.5)
    c = {c.name: c for c in golden.verify(d, _save(tmp_path, {f"{BIL}.b": got})).cases}[BIL]
    assert sorted(w["index"] for w in c.worst) == sorted(flagged[:3].tolist())
    assert all(w["flags"] == str(a["flags"][w["index"]]) != "" for w in c.worst)


def test_a_declared_callers_clamp_is_applied_to_the_ports_output_and_said(tmp_path):
    d = tmp_path / "shade"
    golden.write(d, ["shade-float32"])
    with np.load(d / "shade-float32.npz") as z:
        e = z["intensity"]
    got = e.astype(np.float32)
    zero = np.flatnonzero(e == 0.0)
    got[zero] = np.float32(-0.5)  # below the range: the caller's clamp makes it 0
    p = _save(tmp_path, {"shade-float32.intensity": got})
    assert golden.verify(d, p).cases[0].status == "fail"
    c = golden.verify(d, p, profile=parse_profile({"output_clamp": True})).cases[0]
    assert c.status == "pass" and c.message.endswith(f"({len(zero)} values changed)") and len(zero) > 100


def test_results_for_no_case_are_refused_and_a_bad_port_dtype_first(folder, tmp_path):
    d, _ = folder
    empty = _save(tmp_path, {}, "empty.npz")
    with pytest.raises(InputError, match="no array matches a golden case output"):
        golden.verify(d, empty)
    with pytest.raises(InputError, match="port_dtype: expected float32 or float64, got 'float16'"):
        golden.verify(d, empty, port_dtype="float16")


def _two_outputs(tmp_path):
    """A hand-edited golden folder: psi4's case with a second compared output ``w`` (u's values, ten times u's
    tolerances), as a foreign writer may produce: the report's worst rows show the first compared output."""
    import hashlib

    d = tmp_path / "two"
    golden.write(d, [PSI])
    with np.load(d / f"{PSI}.npz") as z:
        a = {k: z[k] for k in z.files}
    a["w"] = a["u"].copy()
    for dt in ("float32", "float64"):
        a[f"w_tolerance_{dt}"] = 10 * a[f"u_tolerance_{dt}"]
    np.savez(d / f"{PSI}.npz", **a)
    m = json.loads((d / "manifest.json").read_text())
    e = m["cases"][PSI]
    e["outputs"]["w"] = dict(e["outputs"]["u"])
    e["compare"] = ["u", "w"]
    data = (d / f"{PSI}.npz").read_bytes()
    e["sha256"], e["size"] = hashlib.sha256(data).hexdigest(), len(data)
    (d / "manifest.json").write_text(json.dumps(m))
    return d, a


def test_with_two_compared_outputs_the_rows_show_the_first_and_both_are_required(tmp_path):
    d, a = _two_outputs(tmp_path)
    e, t = a["u"], a["u_tolerance_float32"]
    u = e.astype(np.float32)
    u[3] = np.float32(e[3] + 5 * t[3])  # fails u's tolerance, within w's
    w = e.astype(np.float32)
    w[3] = np.float32(e[3] + 20 * t[3])  # fails both: the row's error shown is u's
    c = golden.verify(d, _save(tmp_path, {f"{PSI}.u": u, f"{PSI}.w": w})).cases[0]
    assert c.status == "fail" and [x["index"] for x in c.worst] == [3]
    assert c.worst[0]["got"] == u[3] and c.worst[0]["tolerance"] == t[3]
    assert c.worst[0]["error"] == float(abs(Fraction(float(u[3])) - Fraction(float(e[3]))))
    # one output without the other is refused (results hold all of a case's compared outputs or none)
    with pytest.raises(InputError, match="'psi4-float32.w' is missing"):
        golden.verify(d, _save(tmp_path, {f"{PSI}.u": u}, "u.npz"))
