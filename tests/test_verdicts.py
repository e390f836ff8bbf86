"""Right verdicts: the contract and its robustness rows, the engine cases, a GPU's float32 filter, diagnosis.

Independent means: brute-force sums of the distributions (engine expected values),
the exact eigenvalues of Hankel matrices (the contract), a float32 on-chip filter
emulation (gpu.onchip) for the block cases, and ports written in tests/mutants.
"""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from moments_ref import golden
from moments_ref.golden.compare import compare
from moments_ref.golden.conventions import profiled_arrays
from moments_ref.golden.diagnosis import groups, target_groups
from moments_ref.golden.profile import parse_profile
from moments_ref.golden.writer import manifest_entry
from mutants import corpus, ports


@pytest.fixture(autouse=True)
def _cache(tmp_path, monkeypatch):
    monkeypatch.setenv("MOMENTS_REF_CACHE", str(tmp_path / "cache"))


def _judge(name, got, profile=None, strict=False):
    case, arrays = profiled_arrays(name, profile) if profile else (golden.CASES[name],
                                                                    golden.golden_arrays(golden.CASES[name]))
    return compare(manifest_entry(case, arrays), arrays, {"intensity": got}, case=name, strict=strict), arrays


def test_the_contract_of_algorithm_1_is_decided_by_the_hankel_matrix():
    arrays = golden.golden_arrays(golden.CASES["shadow_intensity-lower-float32"])
    b = arrays["b"].astype(np.float64)
    full = np.concatenate([np.ones((len(b), 1)), b], axis=1)
    lam = np.linalg.eigvalsh(full[:, np.add.outer(np.arange(3), np.arange(3))])[:, 0]
    robust = np.array(["robustness" in str(f) for f in arrays["flags"]])
    provenance = np.array([("singular_hankel" in str(f)) or ("outside_moment_space" in str(f))
                           for f in arrays["flags"]])
    assert (robust == provenance).all()
    assert lam[~robust].min() > 1e-8 and np.abs(lam[robust & ~np.array(["outside" in str(f) for f in
                                                                         arrays["flags"]])]).max() < 1e-15


def test_the_manifest_counts_rows_per_level():
    case = golden.CASES["shade-float32"]
    arrays = golden.golden_arrays(case)
    levels = manifest_entry(case, arrays)["gated"]["float32"]["levels"]
    assert levels["contract"]["rows"] + levels["robustness"]["rows"] == len(arrays["tc_id"])
    assert levels["contract"]["gated"] == levels["contract"]["rows"]  # every contract row of Algorithm 3 gated
    xi = arrays["r"][:, 3].astype(np.float64)
    assert levels["robustness"]["rows"] == int((xi < 1.2e-7 * (1 - 2**-22)).sum())
    alg1 = manifest_entry(golden.CASES["shadow_intensity-lower-float32"], golden.golden_arrays(
        golden.CASES["shadow_intensity-lower-float32"]))["gated"]["float32"]["levels"]["contract"]
    # A contract row is ungated only with a reason in the notes table.
    assert set(alg1["ungated"]) <= set(golden.NOTES) and alg1["ungated"] == {"near_support_point": 12}


def test_robustness_rows_are_shown_not_failed_unless_strict():
    name = "shadow_intensity-lower-float32"
    arrays = golden.golden_arrays(golden.CASES[name])
    got = ports.alg1(arrays["b"], arrays["zf"], {"no_singular": True})
    v, _ = _judge(name, got)
    assert v.passed and v.robustness_tally()["would_fail"] == 9
    vs, _ = _judge(name, got, strict=True)
    assert not vs.passed and vs.failures == 9 and (vs.robust[~vs.row_pass]).all()
    # A NaN on a robustness row is counted, not failed.
    nan = got.copy()
    nan[v.robust] = np.nan
    vn, _ = _judge(name, nan)
    assert vn.passed and vn.robustness_tally()["nonfinite"] == int(v.robust.sum()) - int(
        (vn.strict_pass & v.robust).sum())


def test_engine_expected_values_are_the_exact_z_of_the_distribution():
    arrays = golden.golden_arrays(golden.CASES["engine-lower-float32"])
    upper = golden.golden_arrays(golden.CASES["engine-upper-float32"])
    sup, mass, zf = arrays["support"], arrays["mass"], arrays["zf"]
    for i in range(0, len(zf), 7):
        w = mass[i] / mass[i].sum()  # padded with points of mass 0
        assert arrays["intensity"][i] == pytest.approx(w[sup[i] < zf[i]].sum(), abs=1e-12)
        assert upper["intensity"][i] == pytest.approx(w[sup[i] <= zf[i]].sum(), abs=1e-12)
    flags = " ".join(map(str, arrays["flags"]))
    for what in ("near_far", "cluster", "footprint"):
        assert what in flags
    assert any("three occluders" in str(c) for c in arrays["comment"])
    # The port's input: the moments biased with BIAS_FLOAT32 (the default engine), rounded once.
    from moments_ref.moments import BIAS_FLOAT32, power_moments

    b = (1 - BIAS_FLOAT32.alpha) * power_moments(sup[0], mass[0]) + BIAS_FLOAT32.alpha * np.array(
        BIAS_FLOAT32.target)
    np.testing.assert_allclose(arrays["b"][0], b, rtol=1e-7)


def test_the_shipped_reference_passes_every_engine_case():
    for name in ("engine-lower-float32", "engine-upper-float32", "engine-nlq64-float32", "engine-nlq32-float32",
                 "engine-lower-float64"):
        case = golden.CASES[name]
        arrays = golden.golden_arrays(case)
        got = golden.evaluate_reference(case, {k: arrays[k] for k in case.inputs}, case.dtype)[0]
        v = compare(manifest_entry(case, arrays), arrays, {"intensity": got}, case=name)
        assert v.passed, (name, v.failures)


def test_a_singular_bias_target_fails_the_engine_rows_and_is_named():
    p = parse_profile({"depth": "[0,1]", "output": "visibility",
                       "bias": {"alpha": 3e-6, "target": corpus.SINGULAR01, "applied": "inside"}})
    case, arrays = profiled_arrays("engine-lower-float32", p)
    bad = ports.alg1(arrays["b"], arrays["zf"], {"literal_root": True, "no_singular": True, "visibility": True,
                                                  "bias": (3e-6, corpus.SINGULAR01)})
    v = compare(manifest_entry(case, arrays), arrays, {"intensity": bad}, case=case.name)
    assert not v.passed
    failing = np.flatnonzero(~v.row_pass)
    assert all("near_far" in str(arrays["flags"][i]) or "one depth -1" in str(arrays["comment"][i]) for i in failing)
    gs = target_groups(v, arrays, p.bias, case.engine)
    assert gs and gs[0].count == len(failing) and "0.5·δ(0) + 0.5·δ(1)" in gs[0].cause
    assert groups(v, arrays, gs)[0].level == "target"
    # The same code toward a target strictly inside the moment space passes (verdicts from outputs).
    good_p = parse_profile({"depth": "[0,1]", "output": "visibility",
                            "bias": {"alpha": 3e-6, "target": corpus.TARGET01, "applied": "inside"}})
    case, arrays = profiled_arrays("engine-lower-float32", good_p)
    good = ports.alg1(arrays["b"], arrays["zf"], {"literal_root": True, "no_singular": True, "visibility": True,
                                                   "bias": (3e-6, corpus.TARGET01)})
    assert compare(manifest_entry(case, arrays), arrays, {"intensity": good}, case=case.name).passed


@pytest.mark.parametrize("fmt", ["64", "32"])
def test_a_float32_on_chip_filter_passes_the_block_cases(fmt):
    # Reproduces the report: filter each block with onchip.filter_and_quantize, unpack, shade, verify.
    from moments_ref import nonlinear, packing
    from moments_ref.gpu import onchip

    name = f"e2e-block-nlq{fmt}-float32"
    arrays = golden.golden_arrays(golden.CASES[name])
    out = np.empty(arrays["zf"].shape, np.float32)
    for i in range(len(arrays["depth"])):
        tex = onchip.filter_and_quantize(arrays["depth"][i], fmt=f"nlq{fmt}")
        r = packing.unpack64(tex, dtype=np.float32) if fmt == "64" else packing.unpack32(tex, dtype=np.float32)
        out[i] = nonlinear.shade(r[4:-4, 4:-4], arrays["zf"][i])
    v, _ = _judge(name, out)
    assert v.passed, v.score.max()
    # A filter that is not HPG17's (a box instead of the Gaussian) still fails.
    box = out.copy()
    from moments_ref.gpu.filtering import resolve_moments

    for i in range(len(arrays["depth"])):
        m = resolve_moments(arrays["depth"][i].astype(np.float32))
        k = np.ones(9, np.float32) / 9
        m = np.apply_along_axis(lambda x: np.convolve(np.pad(x, 4, mode="edge"), k, "valid"), 0, m)
        m = np.apply_along_axis(lambda x: np.convolve(np.pad(x, 4, mode="edge"), k, "valid"), 1, m)
        tex = packing.nlq_texels(m.astype(np.float32), f"nlq{fmt}")
        r = packing.unpack64(tex, dtype=np.float32) if fmt == "64" else packing.unpack32(tex, dtype=np.float32)
        box[i] = nonlinear.shade(r[4:-4, 4:-4], arrays["zf"][i])
    assert not _judge(name, box)[0].passed


def test_verify_groups_failures_lists_every_row_and_writes_json(tmp_path):
    gdir = tmp_path / "g"
    golden.write(gdir, ["shadow_intensity-lower-float32"])
    name = "shadow_intensity-lower-float32"
    with np.load(gdir / f"{name}.npz") as g:
        b, zf = g["b"], g["zf"]
    got = ports.alg1(b, zf, {"factor": 1.03})
    np.savez(tmp_path / "r.npz", **{f"{name}.intensity": got})
    out = tmp_path / "rows.json"
    cmd = [sys.executable, "-m", "moments_ref", "verify", "--golden", str(gdir), "--results", str(tmp_path / "r.npz"),
           "--rows", "all", "--json", str(out)]
    r = subprocess.run(cmd, capture_output=True, text=True)
    assert r.returncode == 1 and r.stderr == ""
    n_fail = int(r.stdout.split(": ")[1].split(" of ")[0])
    assert r.stdout.count("(tc_id ") == n_fail  # --rows all: every failing row
    assert f"of {n_fail} failures: random (contract): ordinary inputs" in r.stdout
    doc = json.loads(out.read_text())
    rows = doc["cases"][0]["rows"]
    assert len(rows) == len(zf) and sum(not x["passed"] for x in rows) == n_fail
    assert {"tc_id", "level", "flags", "error", "tolerance", "got", "expected", "inputs"} <= set(rows[0])
    # --strict gates the robustness rows: a port without the singular branch passes, then fails.
    np.savez(tmp_path / "p.npz", **{f"{name}.intensity": ports.alg1(b, zf, {"no_singular": True})})
    base = cmd[:7] + [str(tmp_path / "p.npz")]
    plain = subprocess.run(base, capture_output=True, text=True)
    strict = subprocess.run(base + ["--strict"], capture_output=True, text=True)
    assert plain.returncode == 0 and "beyond the algorithm's contract: 35 rows, 9 outside" in plain.stdout
    assert strict.returncode == 1 and "(robustness)" in strict.stdout


def test_an_undeclared_clamp_convention_is_labelled_not_counted_as_arithmetic(tmp_path):
    # The author's Algorithm 3 without its profile: every failing row is explained by clamp = 5e-6 with the
    # case test on the clamped y2, and the report says so (format/convention failures apart from arithmetic).
    gdir = tmp_path / "g"
    golden.write(gdir, ["shade-float32"])
    with np.load(gdir / "shade-float32.npz") as g:
        r, zf = g["r"], g["zf"]
    got = ports.alg3(r, zf, {"clamp": 5e-6, "zp_test": True, "literal_root": True, "no_xi_guard": True,
                             "unclamped": True})
    np.savez(tmp_path / "r.npz", **{"shade-float32.intensity": got})
    case = golden.verify(gdir, tmp_path / "r.npz").cases[0]
    assert case.status == "fail" and case.groups[0].level == "convention"
    assert case.groups[0].count == case.verdict.failures and "clamp = 5e-06" in case.groups[0].flags
    # An arithmetic bug is not explained by any convention.
    bad = ports.alg3(r, zf, {"swap_weights": True})
    np.savez(tmp_path / "b.npz", **{"shade-float32.intensity": bad})
    case = golden.verify(gdir, tmp_path / "b.npz").cases[0]
    assert all(g.level in ("contract", "robustness") for g in case.groups)


def test_an_undeclared_texel_format_choice_is_labelled_format(tmp_path):
    # An unpack32 reading depths at the centre of their cell (a legitimate reading of HPG17 §3.5, declared
    # with format.depth_decode = "centre") fails without its profile; the report says which choice it made.
    gdir = tmp_path / "g"
    golden.write(gdir, ["unpack32-float32"])
    with np.load(gdir / "unpack32-float32.npz") as g:
        p = g["p"]
    np.savez(tmp_path / "r.npz", **{"unpack32-float32.r": ports.unpack32(p, {"centre": True})})
    case = golden.verify(gdir, tmp_path / "r.npz").cases[0]
    assert case.status == "fail" and case.groups[0].level == "format"
    assert case.groups[0].flags == "format.depth_decode = 'centre'" and case.groups[0].count == case.verdict.failures
    declared = parse_profile({"format": {"depth_decode": "centre"}})
    assert golden.verify(gdir, tmp_path / "r.npz", profile=declared).cases[0].status == "pass"
