"""The record of a ``conformance --all`` run and the GPU section built from it (no driver needed).

The outputs here are made up, and the differences planted in them are known by
construction: the section must count exactly those rows, ulps, codes and verdicts.
"""

from __future__ import annotations

import re

import numpy as np
import pytest

from moments_ref._arrays import InputError
from moments_ref.conformance import _probes, _record


def _up(x, steps):
    """``x`` moved ``steps`` float32 values up."""
    for _ in range(steps):
        x = np.nextafter(x, np.float32(np.inf), dtype=np.float32)
    return x


def _target(language, driver, outputs, verdicts):
    rows = [f"| {c} | `f` | 0.1 (3/3 gated) | – | – | max_abs | {v} |" for c, v in verdicts.items()]
    return (language, driver, "a renderer", rows, [0.5, 0.1], outputs, {})


def _mesa_outputs():
    rng = np.random.default_rng(1)
    return {"case-a": {"y": rng.uniform(-1, 1, (10, 2)).astype(np.float32),
                       "z": rng.uniform(-1, 1, (10,)).astype(np.float32)},
            "case-b": {"q": rng.integers(0, 65535, (5, 4)).astype(np.uint16)}}


def _gpu_outputs():
    out = _mesa_outputs()
    y, z, q = out["case-a"]["y"].copy(), out["case-a"]["z"].copy(), out["case-b"]["q"].copy()
    y[3, 1] = _up(y[3, 1], 2)  # one row, two ulps
    y[7] = _up(y[7], 1)  # one row, both columns and the other output too, one ulp: a row counts once
    z[[5, 7]] = _up(z[[5, 7]], 1)  # row 5 differs only here
    q[2, 3] += 1  # one code
    return {"case-a": {"y": y, "z": z}, "case-b": {"q": q}}


def _kernel(output, passed=True):
    return dict(case="kernel-x", language="glsl", driver="gl", renderer="r", passed=passed, note="",
                cells="random 0.1", codes="", output=output)


@pytest.fixture
def record(tmp_path):
    gpu = _gpu_outputs()
    results = [_target("glsl", "gl", gpu, {"case-a": "pass", "case-b": "FAIL"}),
               _target("glsl", "vulkan", _mesa_outputs(), {"case-a": "pass", "case-b": "pass"})]
    texels = np.arange(12, dtype=np.float32).reshape(6, 2)
    texels[4, 0] = _up(texels[4, 0], 3)
    path = tmp_path / "r.npz"
    _record.save(path, results, [_kernel(texels)], "## Floating-point behaviour of the drivers (measured)\n\nx",
                 {"glslangValidator": "11"}, 12.5)
    return path, results


def test_a_record_keeps_every_array_bit_for_bit(record):
    path, results = record
    meta, arrays = _record.load(path)
    assert meta["version"] == _record.RECORD_VERSION and meta["total"] == 12.5
    assert [t["rows"] for t in meta["targets"]] == [r[3] for r in results]
    for lang, drv, _, _, _, outputs, _ in results:
        for case, outs in outputs.items():
            for name, arr in outs.items():
                got = arrays[f"f|{lang}|{drv}|{case}|{name}"]
                assert got.dtype == arr.dtype and got.tobytes() == arr.tobytes()
    assert "output" not in meta["kernels"][0] and "k|glsl|gl|kernel-x" in arrays


def test_the_gpu_section_counts_the_planted_differences(record):
    path, _ = record
    meta, arrays = _record.load(path)
    here = [_target("glsl", "gl", _mesa_outputs(), {"case-a": "pass", "case-b": "pass"}),
            _target("glsl", "vulkan", _mesa_outputs(), {"case-a": "pass", "case-b": "pass"})]
    local_kernel = _kernel(np.arange(12, dtype=np.float32).reshape(6, 2))
    text = "\n".join(_record.gpu_markdown(meta, arrays, here, [local_kernel], "docs/x.npz"))
    # 15 rows (10 + 5); rows 3, 5 and 7 of case-a and row 2 of case-b differ; 2 ulps at most; one code.
    assert "| glsl | gl | 15 | 4 | 2 | 1 | case-b: GPU FAIL, here pass | case-a (3), case-b (1) |" in text
    assert "| glsl | vulkan | 15 | 0 | 0 | 0 | none | – |" in text
    # The GPU's own drivers: gl carries the planted rows, vulkan does not.
    assert "between the GPU's OpenGL and its Vulkan: glsl 4 of 15." in text
    assert "| kernel-x | glsl | gl | pass | random 0.1 | – | pass | 1 | 3 |" in text
    assert "Failing cases on the GPU:" in text and "| glsl | gl | case-b |" in text
    assert "### Floating-point behaviour of the drivers on the GPU (measured)" in text


def test_a_target_or_kernel_missing_here_is_said_so(record):
    path, _ = record
    meta, arrays = _record.load(path)
    text = "\n".join(_record.gpu_markdown(meta, arrays, [], [], "x.npz"))
    assert "| glsl | gl | not run here |||||" in text
    assert "| kernel-x | glsl | gl | pass | random 0.1 | – | not run | – | – |" in text


@pytest.mark.parametrize("edit, message", [
    (lambda m: m["targets"][0].pop("rows"), "targets[0] lacks 'rows'"),
    (lambda m: m["targets"][0].__setitem__("times", ["x"]), "times that are not numbers"),
    (lambda m: m["kernels"][0].__setitem__("case", 3), "kernels[0] lacks 'case'"),
    (lambda m: m.__setitem__("probes", None), "lacks 'probes'"),
    (lambda m: m.__setitem__("targets", [1]), "targets[0] lacks 'language'"),
    (lambda m: m["kernels"][0].__setitem__("passed", "yes"), "kernels[0] has 'passed' 'yes'"),
    (lambda m: m["kernels"][0].pop("passed"), "kernels[0] has 'passed' 'missing'"),
    (lambda m: m["kernels"][0].__setitem__("passed", 0), "kernels[0] has 'passed' 0"),
])
def test_a_record_with_a_malformed_meta_is_refused(record, tmp_path, edit, message):
    import json

    path, _ = record
    with np.load(path) as z:
        arrays = {k: z[k] for k in z.files}
    meta = json.loads(arrays["meta"].tobytes())
    edit(meta)
    arrays["meta"] = np.frombuffer(json.dumps(meta).encode(), np.uint8)
    np.savez(tmp_path / "bad.npz", **arrays)
    with pytest.raises(InputError, match=re.escape(message)):
        _record.load(tmp_path / "bad.npz")


def test_the_verdicts_are_read_from_the_table_rows():
    rows = ["| a | `f` | 0.1 | – | – | m | pass |", "| b | `g` | – | – | – | – | not available on this driver: x |",
            "| c | `h` | 2 | – | – | m | FAIL |"]
    assert _record._verdicts(rows) == {"a": "pass", "c": "FAIL"}


# --------------------------------------------------------------------------
# The classifiers of the exp, log and denormal probes
# --------------------------------------------------------------------------


def test_denormal_findings_tell_kept_from_flushed():
    d = np.float32(2.0 ** -140)
    assert _probes.denormal_findings(np.array([d, d, d, 1], np.float32)) == {
        "stored": "unchanged", "x·1": "kept", "product": "kept", "x > 0": "true"}
    assert _probes.denormal_findings(np.array([d, 0, 0, 0], np.float32)) == {
        "stored": "unchanged", "x·1": "flushed to 0", "product": "flushed to 0", "x > 0": "false"}
    assert _probes.denormal_findings(np.array([0, 0, 1, 0.5], np.float32)) == {
        "stored": "flushed to 0", "x·1": "flushed to 0", "product": "1", "x > 0": "0.5"}
    # The probe's row: d·1 is d, and 2^-70·2^-70 is d exactly.
    x = _probes.DENORMAL[0]
    assert x[0] * x[1] == d and x[2] * x[3] == d and 0 < d < np.finfo(np.float32).tiny


def test_transcendental_findings_count_rows_off_correct_rounding():
    x = _probes._transcendental_rows(2000)
    exact = np.column_stack([np.exp(x[:, 0].astype(np.float64)), np.log(x[:, 1].astype(np.float64))]).astype(
        np.float32)
    found = _probes.transcendental_findings(x, exact)
    assert found["p_exp"].startswith("0 of 2000 (max 0 ulp") and found["p_log"].startswith("0 of 2000 (max 0 ulp")
    off = exact.copy()
    off[:7, 0] = _up(off[:7, 0], 1)
    near = np.flatnonzero((x[:, 1] >= 0.5) & (x[:, 1] <= 2))
    off[near[0], 1] = _up(off[near[0], 1], 5)
    found = _probes.transcendental_findings(x, off)
    assert found["p_exp"].startswith("7 of 2000 (max 1 ulp") and found["p_log"].startswith("1 of 2000 (max 5 ulp")
    err = abs(float(off[near[0], 1]) - np.log(float(x[near[0], 1])))
    assert found["p_log_abs"] == f"{err:.2g}"


def test_a_record_array_that_is_a_single_number_is_refused(record, tmp_path):
    path, _ = record
    with np.load(path) as z:
        arrays = {k: z[k] for k in z.files}
    arrays["f|glsl|gl|case-a|y"] = np.float32(1.0)
    np.savez(tmp_path / "bad.npz", **arrays)
    with pytest.raises(InputError, match="is a single number; expected rows"):
        _record.load(tmp_path / "bad.npz")


def test_the_two_drivers_table_counts_a_row_once_over_its_outputs():
    from moments_ref.conformance import _cli

    a, b = _mesa_outputs(), _gpu_outputs()
    assert _cli._differing_rows(a, b) == {"case-a": 3, "case-b": 1}
    assert _cli._differing_rows(a, _mesa_outputs()) == {}
