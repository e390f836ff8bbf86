"""Golden vectors: deterministic bytes, manifest, verify catches differences, atomic output."""

import hashlib
import json

import numpy as np
import pytest

from moments_ref import golden
from moments_ref._arrays import InputError
from moments_ref.cli import main

SMALL = ["shadow_intensity-lower-float32", "shadow_intensity-upper-float64", "encode_unorm16-float32",
         "to_optimized-float64"]


@pytest.fixture(scope="module")
def gdir(tmp_path_factory):
    out = tmp_path_factory.mktemp("golden")
    golden.write(out)
    return out


def _reference_results(gdir, names=None):
    """What this reference itself computes on the golden inputs (a port that is this code)."""
    manifest = json.loads((gdir / "manifest.json").read_text())
    res = {}
    for name, meta in manifest["cases"].items():
        if names and name not in names:
            continue
        case = golden.CASES[name]
        with np.load(gdir / meta["file"]) as g:
            inputs = {k: g[k] for k in case.inputs}
        for out, val in zip(case.outputs, golden.evaluate_reference(case, inputs, case.dtype)):
            res[f"{name}.{out}"] = val
    return res


def test_same_version_writes_same_bytes(gdir, tmp_path):
    golden.write(tmp_path)
    for f in sorted(gdir.iterdir()):
        assert (tmp_path / f.name).read_bytes() == f.read_bytes(), f.name


def test_manifest_describes_every_file(gdir):
    m = json.loads((gdir / "manifest.json").read_text())
    assert m["schema_version"] == golden.SCHEMA_VERSION
    assert m["numpy_version"] == np.__version__
    assert set(m["cases"]) == set(golden.CASES)
    for name, meta in m["cases"].items():
        data = (gdir / meta["file"]).read_bytes()
        assert hashlib.sha256(data).hexdigest() == meta["sha256"]
        with np.load(gdir / meta["file"]) as g:
            cat = g["category"]
            assert len(cat) == meta["count"] == len(g["comment"])
            assert set(cat) <= set(golden.CATEGORIES)
            assert sum(meta["categories"].values()) == meta["count"]
            for k, spec in meta["inputs"].items():
                assert g[k].dtype == np.dtype(spec["dtype"]) and list(g[k].shape) == spec["shape"]
            for k in meta["compare"]:
                assert len(g[k]) == meta["count"]
            assert all(len(c) > 0 for c in g["comment"])
        assert meta["categories"]["random"] > 0
        for dt in ("float32", "float64"):
            assert set(meta["tolerances"][dt]) == set(golden.CATEGORIES)


def test_algorithm1_cases_cover_all_categories(gdir):
    m = json.loads((gdir / "manifest.json").read_text())
    for name in ("shadow_intensity-lower-float32", "shadow_intensity-upper-float64"):
        assert all(m["cases"][name]["categories"][c] > 0 for c in golden.CATEGORIES)
        # float64 random rows must be held tightly, float32 within float32 rounding.
        assert m["cases"][name]["tolerances"]["float64"]["random"] <= 1e-9
        assert m["cases"][name]["tolerances"]["float32"]["random"] <= 1e-3


def test_expected_intensities_bracket_the_true_distribution(gdir):
    """Independent check of the stored expectations: rows built from unbiased distributions.

    For unbiased moments of a real distribution the expected lower bound must not
    exceed the exact PCF value and the upper bound must not be below it. The
    random rows are such moments; we rebuild nothing from the code under test but
    check the bracket against the sharp bounds' defining property with scipy's LP.
    """
    from scipy.optimize import linprog

    grid = np.linspace(-1, 1, 401)
    with np.load(gdir / "shadow_intensity-lower-float64.npz") as g:
        b, zf, lo, cat = g["b"], g["zf"], g["intensity"], g["category"]
    rows = np.flatnonzero(cat == "random")[:12]
    for i in rows:
        a_eq = np.vstack([grid**k for k in range(5)])
        b_eq = np.concatenate([[1.0], b[i]])
        c = (grid < zf[i]).astype(float)
        res = linprog(c, A_eq=a_eq, b_eq=b_eq, bounds=(0, None), method="highs")
        if res.status == 0:  # a feasible grid distribution has Z(z < zf) >= the sharp lower bound
            assert lo[i] <= res.fun + 1e-7


def test_verify_passes_for_the_reference(gdir, capsys):
    res = _reference_results(gdir)
    path = gdir.parent / "ref_results.npz"
    np.savez(path, **res)
    assert main(["verify", "--golden", str(gdir), "--results", str(path)]) == 0
    out = capsys.readouterr().out
    assert "0 failed" in out


@pytest.mark.parametrize("case,key", [("shadow_intensity-lower-float32", "intensity"),
                                      ("encode_unorm16-float32", "u")])
def test_verify_catches_a_perturbed_row(gdir, tmp_path, capsys, case, key):
    res = _reference_results(gdir, [case])
    arr = res[f"{case}.{key}"].copy()
    row = 7
    if arr.dtype.kind == "u":
        arr[row, 0] ^= 1
    else:
        arr[row] = min(arr[row] + 0.01, 1.0) if arr[row] < 0.5 else arr[row] - 0.01
    res[f"{case}.{key}"] = arr
    path = tmp_path / "bad.npz"
    np.savez(path, **res)
    assert main(["verify", "--golden", str(gdir), "--results", str(path)]) == 1
    out = capsys.readouterr().out
    assert f"FAIL  {case}" in out
    assert f"row {row} " in out  # the worst row is named, with its inputs
    assert "b=[" in out


def test_verify_reports_shape_errors_and_unknown_arrays(gdir, tmp_path):
    path = tmp_path / "shape.npz"
    np.savez(path, **{"shadow_intensity-lower-float32.intensity": np.zeros(3)})
    report = golden.verify(gdir, path)
    assert report.failed
    assert any("shape" in c.message for c in report.cases)
    path2 = tmp_path / "none.npz"
    np.savez(path2, something=np.zeros(3))
    with pytest.raises(InputError, match="results"):
        golden.verify(gdir, path2)
    assert main(["verify", "--golden", str(gdir), "--results", str(path2)]) == 2


def test_verify_refuses_a_tampered_golden_file(gdir, tmp_path):
    import shutil

    g2 = tmp_path / "g"
    shutil.copytree(gdir, g2)
    f = g2 / "to_optimized-float64.npz"
    data = bytearray(f.read_bytes())
    data[-100] ^= 0xFF
    f.write_bytes(bytes(data))
    res = _reference_results(gdir, ["to_optimized-float64"])
    path = tmp_path / "r.npz"
    np.savez(path, **res)
    report = golden.verify(g2, path)
    assert report.failed and "sha256" in report.cases[[c.name for c in report.cases].index("to_optimized-float64")].message


def test_interrupted_write_leaves_no_partial_files(tmp_path):
    calls = []

    def boom(name):
        calls.append(name)
        if len(calls) == 2:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        golden.write(tmp_path, SMALL, progress=boom)
    names = sorted(p.name for p in tmp_path.iterdir())
    assert names == sorted(f"{n}.npz" for n in calls)  # complete files only, no temporaries, no manifest
    for n in names:
        with np.load(tmp_path / n) as g:
            assert "category" in g.files


def test_unknown_case_is_refused(tmp_path):
    with pytest.raises(InputError, match="unknown case"):
        golden.write(tmp_path, ["no-such-case"])
