"""GLSL ports on an OpenGL 4.3 compute context (Mesa llvmpipe) against the goldens.

The tests need an EGL driver and moderngl. Without them they are skipped with the
reason, except under CI (``CI=true``), where a missing context is a failure: .ci/run
installs the Mesa packages so that the ports are really exercised. HLSL, WGSL and the
Vulkan driver: tests/test_conformance_languages.py (same rule).
"""

from __future__ import annotations

import io
import math
import os
import re

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from moments_ref import InputError, conformance, golden, packing
from moments_ref.conformance import GLSL_DIR, SHIPPED, ContextError, ShaderError

from _harness import assert_ties_are_the_float32_reference

FIXTURES = os.path.join(os.path.dirname(__file__), "fixtures", "glsl")


def fixture(name):
    return os.path.join(FIXTURES, name)


# Every case a shipped port covers, at both dtypes (float64 cases: inputs rounded to float32).
SHIPPED_CASES = conformance.shipped_cases()


def _run(ctx, golden_dir, path, function, case, **kw):
    return conformance.run_case(path, function, case, golden_dir, "glsl", "gl", **kw)


# --------------------------------------------------------------------------
# The shipped ports pass their cases
# --------------------------------------------------------------------------


def test_every_shipped_entry_names_a_defined_function():
    for prefix, (fname, function) in SHIPPED.items():
        src = conformance.load_source(GLSL_DIR / fname)
        assert function in conformance.defined_functions(src.body), (prefix, fname, function)


def test_shipped_ports_cover_the_issue_functions():
    covered = {n.rsplit("-", 1)[0].split("-")[0] for n in SHIPPED_CASES}
    assert {"shadow_intensity", "shadow_intensity6", "from_optimized", "bias_moments", "phi", "phi_inverse",
            "psi4", "psi4_inverse", "shade", "pack64", "unpack64", "pack32", "unpack32"} <= covered


@pytest.mark.parametrize("case", SHIPPED_CASES)
def test_shipped_port_passes(ctx, golden_dir, case):
    path, function = conformance.shipped_port(case)
    report = _run(ctx, golden_dir, path, function, case, worst_rows=1000)
    assert report.passed, report.format()
    text = report.format()
    assert text.startswith("PASS")
    if report.exact:
        # Packing: bit-exact with the reference in float32 on every row. The expected codes are
        # exact (golden/texel_truth.py); where the reference's float32 code differs from them,
        # the row is a rounding tie and the port must store the reference's code.
        assert all(c.mismatches == c.ties for c in report.categories.values()), text
        assert_ties_are_the_float32_reference(report, golden_dir, case)
    if "stiff" in report.categories and not report.exact:
        # Stiff rows are reported, never hidden: they appear among the listed rows.
        assert any(r["category"] == "stiff" for r in report.worst), text
        assert "[stiff]" in text


# --------------------------------------------------------------------------
# Packing: bit-exact beyond the golden rows
# --------------------------------------------------------------------------


def _psi4_exact(xi):
    x = np.clip(np.asarray(xi, np.float64), 1.2e-7, 0.25)
    c0 = math.log(math.log(1.2))
    return (np.log(np.log(x * 1e7)) - c0) / (math.log(math.log(0.25e7)) - c0)


def _random_representations(n, seed):
    rng = np.random.default_rng(seed)
    y = np.sort(rng.uniform(-1, 1, (n, 2)), axis=1)
    return np.column_stack([y, rng.uniform(0, 1, n), 10 ** rng.uniform(-8, np.log10(0.25), n)]).astype(np.float32)


def test_pack64_bit_exact_on_random_texels(ctx):
    n = 40000
    r = _random_representations(n, 7)
    got, _ = conformance.run_glsl(GLSL_DIR / "packing.glsl", "pack64", {"r": r}, {"q": (np.uint16, (n, 4))}, ctx)
    q = got["q"].astype(np.int64)
    ref = packing.pack64(r).astype(np.int64)
    # Depths and v2: integer rounding of exactly rounded float32 products, bit-exact.
    assert np.array_equal(q[:, :3], ref[:, :3])
    # Psi4 channel: log() is the GPU's; a code may differ by one only where the exact
    # 65535 Psi4(xi4) lies within float32 resolution (0.01 code) of an integer.
    diff = np.flatnonzero(q[:, 3] != ref[:, 3])
    assert np.all(np.abs(q[diff, 3] - ref[diff, 3]) == 1)
    s = 65535 * _psi4_exact(r[diff, 3])
    assert np.all(np.abs(s - np.round(s)) < 0.01), s
    assert len(diff) < 2e-3 * n


def test_pack32_bit_exact_on_random_texels(ctx):
    n = 40000
    r = _random_representations(n, 8)
    got, _ = conformance.run_glsl(GLSL_DIR / "packing.glsl", "pack32", {"r": r}, {"p": (np.uint32, (n,))}, ctx)
    p = got["p"].astype(np.int64)
    ref = packing.pack32(r).astype(np.int64)
    low26 = (1 << 26) - 1
    assert np.array_equal(p & low26, ref & low26)  # folded depths and the sqrt(v2) code
    dx = (p >> 26) - (ref >> 26)
    assert np.all(np.abs(dx) <= 1) and np.count_nonzero(dx) <= 5e-4 * n


def test_unpack_exhaustive_depth_and_weight_codes(ctx):
    src = conformance.load_source(GLSL_DIR / "packing.glsl")
    codes = np.arange(65536, dtype=np.uint16)
    q = np.stack([codes, codes[::-1], codes, codes], axis=1)
    got, _ = conformance.run_glsl(src, "unpack64", {"q": q}, {"r": (np.float32, (65536, 4))}, ctx)
    ref = packing.unpack64(q, dtype=np.float32)
    assert np.array_equal(got["r"][:, :3].view(np.int32), ref[:, :3].view(np.int32))
    assert conformance.ulp_distance(got["r"][:, 3], ref[:, 3]).max() <= 64
    # All 2^19 folded depth pairs, each v2 code, and a few Psi4 codes.
    pairs = np.arange(1 << 19, dtype=np.uint32)
    p = pairs | ((pairs % 128) << 19) | ((pairs % 64) << 26)
    got, _ = conformance.run_glsl(src, "unpack32", {"p": p}, {"r": (np.float32, (len(p), 4))}, ctx)
    ref = packing.unpack32(p, dtype=np.float32)
    assert np.array_equal(got["r"][:, :3].view(np.int32), ref[:, :3].view(np.int32))
    assert conformance.ulp_distance(got["r"][:, 3], ref[:, 3]).max() <= 64


# --------------------------------------------------------------------------
# Deliberately broken ports are caught with a clear report
# --------------------------------------------------------------------------


@pytest.mark.parametrize("mutant", ["shade_root_sign_flipped", "shade_xi_multiplied"])
def test_algorithm3_mutants_are_caught(ctx, golden_dir, mutant):
    report = _run(ctx, golden_dir, fixture(f"{mutant}.glsl"), mutant, "shade-float32")
    assert not report.passed
    assert report.categories["random"].failures > 10
    text = report.format()
    assert text.startswith(f"FAIL  {mutant}")
    # The worst rows carry their inputs, the expected values and the row's reason.
    first = next(r for r in report.worst if not r["passed"])
    line = f"FAIL row {first['index']} [{first['category']}]"
    assert line in text
    assert "r=[" in text and "zf=" in text and "random representation" in text


def test_mutant_exits_1_through_the_cli(ctx, golden_dir):
    out, err = io.StringIO(), io.StringIO()
    code = conformance.run_cli(fixture("shade_xi_multiplied.glsl"), "shade_xi_multiplied", "shade-float32",
                               golden_dir, out=out, err=err)
    assert code == 1 and "FAIL" in out.getvalue() and err.getvalue() == ""


def test_packing_mutant_is_caught(ctx, golden_dir):
    report = _run(ctx, golden_dir, fixture("pack64_xi_rounded.glsl"), "pack64_xi_rounded", "pack64-float32",
                  worst_rows=1000)
    assert not report.passed and report.components["mismatch"][3] > 0
    # Only the Ψ4 channel is wrong: the others differ from the exact expected code only on
    # rounding-tie rows, where they are the codes the reference stores in float32.
    with np.load(golden_dir / "pack64-float32.npz") as g:
        acceptable = g["q_acceptable"]
    for r in report.worst:
        if not r["passed"]:
            assert any(np.array_equal(np.asarray(r["got"])[:3], a[:3]) for a in acceptable[r["index"]]), r


def test_paper_literal_algorithm3_is_nan_only_at_zf_equal_y2(ctx, golden_dir):
    # The printed formula: q1 = +-inf at zf = y2 and z_l = inf - inf. Random rows pass
    # (the tolerances do not demand more than float32 gives); each failure is such a NaN,
    # or the cancellation of the literal root where the gap y2 - y1 is small (the decoders'
    # one-cell rows, the fold, the §3.4 gap clamp), where zf is within 1e-5 of y2 (v2 - v2 zp
    # cancels) or where v2 is the 32-bit decoder's smallest, (0.5/128)², which the per-row
    # tolerances gate.
    report = _run(ctx, golden_dir, fixture("shade_paper_literal.glsl"), "shade_paper_literal", "shade-float32",
                  worst_rows=100)
    assert report.categories["random"].failures == 0
    failing = [r for r in report.worst if not r["passed"]]
    assert failing and len(failing) == report.failures
    for r in failing:
        # NaN at zf = y2, or cancellation where y2 - y1 is at most two 32-bit cells (1 / 511.5),
        # zf is next to y2 or v2 is the smallest 32-bit v2.
        y1, y2, v2 = (np.float32(x) for x in r["inputs"]["r"][:3])
        zf = np.float32(r["inputs"]["zf"])
        assert ((np.isnan(r["got"]) and zf == y2) or y2 - y1 <= 2 / 511.5 or abs(zf - y2) <= 1e-5
                or v2 <= np.float32((0.5 / 128) ** 2)), r
    assert "got nan" in report.format()


def test_slides_verbatim_algorithm1_fails_only_on_singular_rows(ctx, golden_dir):
    # The slides' HLSL, translated line by line: within the float32 tolerance on every
    # random row. It fails only where B(b) is singular (unbiased two-point moments),
    # where it divides by zero; biasing first is the slides' own instruction.
    report = _run(ctx, golden_dir, fixture("msm_slides_verbatim.glsl"), "ComputeMSMShadowIntensity",
                  "shadow_intensity-lower-float32", worst_rows=100)
    assert report.categories["random"].failures == 0
    for r in report.worst:
        if not r["passed"]:
            b = np.asarray(r["inputs"]["b"], np.float64)
            hankel = np.array([[1, b[0], b[1]], [b[0], b[1], b[2]], [b[1], b[2], b[3]]])
            assert abs(np.linalg.det(hankel)) < 1e-6, r


# --------------------------------------------------------------------------
# Harness mechanics
# --------------------------------------------------------------------------


def test_type_mapping():
    assert conformance.Slot.of("zf", np.float64, (5,)).glsl == "float"
    assert conformance.Slot.of("b", np.float32, (5, 4)).glsl == "vec4"
    s = conformance.Slot.of("u", np.uint16, (5, 4))
    assert (s.glsl, s.upload) == ("uvec4", np.dtype(np.uint32))
    assert conformance.Slot.of("p", np.uint32, (5,)).glsl == "uint"
    assert conformance.Slot.of("v", np.float32, (5, 3)).element("glsl") == "vec4"  # std430 pads vec3
    b6 = conformance.Slot.of("b", np.float32, (5, 6))
    assert (b6.declare("glsl"), b6.declare("hlsl"), b6.declare("wgsl")) == (
        "float b[6]", "float b[6]", "b: array<f32, 6>")
    with pytest.raises(InputError, match="shape"):
        conformance.Slot.of("m", np.float32, (5, 4, 4))
    sig = conformance.glsl_signature("f", [conformance.Slot.of("b", np.float32, (5, 4)),
                                           conformance.Slot.of("zf", np.float32, (5,))],
                                     [conformance.Slot.of("i", np.float32, (5,))])
    assert sig == "float f(vec4 b, float zf)"


def test_wrapper_bounds_vec3_and_out_parameters(ctx, tmp_path):
    src = tmp_path / "f.glsl"
    src.write_text("#version 430\n"
                   "vec3 twice(vec3 a, uint k) { return a * 2.0 + float(k); }\n"
                   "void split(uvec4 q, out uint lo, out vec2 hi) { lo = q.x + q.y; hi = vec2(q.zw) * 0.5; }\n")
    n = 130  # not a multiple of the work-group size
    a = np.arange(3 * n, dtype=np.float32).reshape(n, 3)
    k = np.arange(n, dtype=np.uint32)
    got, t = conformance.run_glsl(src, "twice", {"a": a, "k": k}, {"o": (np.float32, (n, 3))}, ctx)
    assert np.array_equal(got["o"], a * 2 + k[:, None])
    assert set(t) == {"compile", "upload", "dispatch", "readback"}
    q = np.arange(4 * n, dtype=np.uint16).reshape(n, 4)
    got, _ = conformance.run_glsl(src, "split", {"q": q}, {"lo": (np.uint32, (n,)), "hi": (np.float32, (n, 2))}, ctx)
    assert np.array_equal(got["lo"], q[:, 0].astype(np.uint32) + q[:, 1])
    assert np.array_equal(got["hi"], q[:, 2:].astype(np.float32) * 0.5)


def test_includes_resolved_once_and_errors_name_the_file(ctx, tmp_path):
    (tmp_path / "a.glsl").write_text("float one() { return 1.0; }\n")
    (tmp_path / "b.glsl").write_text('#include "a.glsl"\n#include "a.glsl"\n'
                                     "float f(float x) { return x + one(); }\n")
    src = conformance.load_source(tmp_path / "b.glsl")
    assert src.body.count("float one()") == 1
    x = np.linspace(0, 1, 5, dtype=np.float32)
    got, _ = conformance.run_glsl(src, "f", {"x": x}, {"y": (np.float32, (5,))}, ctx)
    assert np.array_equal(got["y"], x + 1)
    # A missing include is an #error line at the include, so that the compiler's own
    # preprocessor decides (inside `#if 0` it does not matter); it names the file and line.
    (tmp_path / "c.glsl").write_text('#if 0\n#include "unused.glsl"\n#endif\n#include "missing.glsl"\n'
                                     "float f(float x) { return x; }\n")
    with pytest.raises(ShaderError, match=r"c\.glsl:4:.*missing\.glsl\" not found"):
        conformance.run_glsl(tmp_path / "c.glsl", "f", {"x": x}, {"y": (np.float32, (5,))}, ctx)
    (tmp_path / "d.glsl").write_text("float g(float x)\n{\n    return x +;\n}\n")
    with pytest.raises(ShaderError) as exc:
        conformance.run_glsl(tmp_path / "d.glsl", "g", {"x": x}, {"y": (np.float32, (5,))}, ctx)
    # the error is inside the file and the signature is right: the message names no signature
    assert re.search(r"d\.glsl:3:", str(exc.value)) and "float g(float x)" not in str(exc.value)


def test_cli_exit_codes_and_messages(ctx, golden_dir, monkeypatch):
    out, err = io.StringIO(), io.StringIO()
    assert conformance.run_cli("msm.glsl", "shadow_intensity_lower", "shadow_intensity-lower-float32",
                               golden_dir, out=out, err=err) == 0
    assert out.getvalue().startswith("PASS") and "renderer:" in out.getvalue()
    err = io.StringIO()
    assert conformance.run_cli("msm.glsl", "no_such_function", "shadow_intensity-lower-float32",
                               golden_dir, out=io.StringIO(), err=err) == 2
    assert "shadow_intensity_lower" in err.getvalue() and "float no_such_function(vec4 b, float zf)" in err.getvalue()
    err = io.StringIO()
    assert conformance.run_cli("msm.glsl", "from_optimized", "no-such-case", None, out=io.StringIO(), err=err) == 2
    assert "unknown case" in err.getvalue()
    # The wrong signature for the case: a compile error naming the expected signature.
    err = io.StringIO()
    assert conformance.run_cli("msm.glsl", "from_optimized", "shadow_intensity-lower-float32", golden_dir,
                               out=io.StringIO(), err=err) == 2
    assert "float from_optimized(vec4 b, float zf)" in err.getvalue()

    def no_context():
        raise ContextError("EGL: no display (test)")

    monkeypatch.setattr(conformance._gl, "get_context", no_context)
    err = io.StringIO()
    assert conformance.run_cli("msm.glsl", "shadow_intensity_lower", "shadow_intensity-lower-float32",
                               golden_dir, out=io.StringIO(), err=err) == 2
    assert "no display" in err.getvalue()


def test_golden_dir_checked_and_generated_when_absent(ctx, golden_dir, tmp_path):
    a = conformance.run_case(GLSL_DIR / "nonlinear.glsl", "psi4", "psi4-float32", None)
    b = conformance.run_case(GLSL_DIR / "nonlinear.glsl", "psi4", "psi4-float32", golden_dir)
    assert a.categories == b.categories
    golden.write(tmp_path, ["psi4-float32"])
    f = tmp_path / "psi4-float32.npz"
    data = bytearray(f.read_bytes())
    data[len(data) // 2] ^= 0xFF
    f.write_bytes(bytes(data))
    with pytest.raises(InputError, match="sha256"):
        conformance.run_case(GLSL_DIR / "nonlinear.glsl", "psi4", "psi4-float32", tmp_path)


def test_bench_conformance(ctx):
    rows = conformance.bench_conformance(["psi4-float32", "pack32-float32"], repeat=1, ctx=ctx)
    assert [r["case"] for r in rows] == ["psi4-float32", "pack32-float32"]
    for r in rows:
        assert r["rows"] > 0
        assert all(r[k] >= 0 for k in ("compile_s", "upload_s", "dispatch_s", "readback_s"))


# --------------------------------------------------------------------------
# ulp distance against brute-force enumeration
# --------------------------------------------------------------------------


@given(st.floats(width=32, allow_nan=False, allow_infinity=False), st.integers(-40, 40))
def test_ulp_distance_counts_nextafter_steps(x, k):
    # nextafter visits every float32 in order, zero once (+0 or -0): k steps = distance k.
    y = np.float32(x)
    toward = np.float32(np.inf if k > 0 else -np.inf)
    for _ in range(abs(k)):
        y = np.nextafter(y, toward)
    if np.isfinite(y):
        assert conformance.ulp_distance(np.array([y]), np.array([x], np.float64))[0] == abs(k)


def test_ulp_distance_nan_is_inf():
    assert conformance.ulp_distance(np.float32([np.nan]), np.array([1.0]))[0] == np.inf
