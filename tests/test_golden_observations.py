"""Reproducers of what a porter saw (false passes, false alarms, lax dtypes); each failed before.

Each test builds the results a port would write and runs ``moments-ref verify`` on them.
"""

import numpy as np
import pytest

from moments_ref import golden, oracle
from moments_ref.cli import main
from mutants import ports

CASES = ["bias_moments-float32-float32", "shade-float32", "pack64-float32", "encode_unorm16-float32",
         "unpack32-float32", "unpack64-float32", "pack32-float32", "shadow_intensity-lower-float32"]


GOLDEN_CASES = CASES  # conftest's gdir writes these


def _inputs(gdir, case):
    with np.load(gdir / f"{case}.npz") as g:
        return {k: g[k] for k in golden.CASES[case].inputs}


def _verify(gdir, tmp_path, arrays, *extra):
    path = tmp_path / "results.npz"
    np.savez(path, **arrays)
    return main(["verify", "--golden", str(gdir), "--results", str(path), *extra])


# --------------------------------------------------------------------------
# False passes
# --------------------------------------------------------------------------


def test_float32_biasing_left_out_fails(gdir, tmp_path):
    b = _inputs(gdir, "bias_moments-float32-float32")["b"]
    assert _verify(gdir, tmp_path, {"bias_moments-float32-float32.b_biased": b}) == 1


def test_float32_preset_with_the_16_bit_target_fails(gdir, tmp_path):
    b = _inputs(gdir, "bias_moments-float32-float32")["b"]
    wrong = ports.bias(b, 3e-7, [0.0, 0.628, 0.0, 0.628], {})
    assert _verify(gdir, tmp_path, {"bias_moments-float32-float32.b_biased": wrong}) == 1
    right = ports.bias(b, 3e-7, [0.0, 0.375, 0.0, 0.375], {})
    assert _verify(gdir, tmp_path, {"bias_moments-float32-float32.b_biased": right}) == 0


@pytest.mark.parametrize("change", ["literal_root", "no_v2_clamp", "no_gap_clamp"])
def test_algorithm3_literal_root_or_missing_clamp_fails(gdir, tmp_path, change):
    x = _inputs(gdir, "shade-float32")
    assert _verify(gdir, tmp_path, {"shade-float32.intensity": ports.alg3(x["r"], x["zf"], {})}) == 0
    bad = ports.alg3(x["r"], x["zf"], {change: True})
    assert _verify(gdir, tmp_path, {"shade-float32.intensity": bad}) == 1


def test_shade_has_gated_rows_at_the_clamps(gdir):
    with np.load(gdir / "shade-float32.npz") as g:
        r, tol = g["r"], g["intensity_tolerance_float32"]
        for sel in (r[:, 0] == r[:, 1], r[:, 2] == 0, r[:, 2] == 1):
            assert sel.sum() >= 7 and np.mean(tol[sel] < 0.1) >= 0.9


# --------------------------------------------------------------------------
# Wrong kinds of results: exit 2, naming the array, expected and found
# --------------------------------------------------------------------------


@pytest.mark.parametrize("kind", ["float_codes", "complex", "strings", "float64_for_float32", "bool"])
def test_results_of_the_wrong_dtype_exit_2(gdir, tmp_path, capsys, kind):
    q = golden.evaluate_reference(golden.CASES["pack64-float32"], _inputs(gdir, "pack64-float32"), "float32")[0]
    x = _inputs(gdir, "shade-float32")
    s = ports.alg3(x["r"], x["zf"], {})
    arrays = {
        "float_codes": {"pack64-float32.q": q + 0.9},
        "complex": {"shade-float32.intensity": s.astype(np.complex64)},
        "strings": {"shade-float32.intensity": s.astype(str)},
        "float64_for_float32": {"shade-float32.intensity": s.astype(np.float64)},
        "bool": {"pack64-float32.q": q > 0},
    }[kind]
    assert _verify(gdir, tmp_path, arrays) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "expected" in err and "found dtype" in err
    assert next(iter(arrays)) in err


# --------------------------------------------------------------------------
# False alarms
# --------------------------------------------------------------------------


@pytest.mark.parametrize("case", ["pack64-float32", "encode_unorm16-float32", "pack32-float32"])
def test_reference_encoders_in_float64_pass_the_float32_cases(gdir, tmp_path, case):
    c = golden.CASES[case]
    out = golden.evaluate_reference(c, _inputs(gdir, case), "float64")[0]
    assert _verify(gdir, tmp_path, {f"{case}.{c.outputs[0]}": out}) == 0


@pytest.mark.parametrize("case,port", [("unpack32-float32", ports.unpack32), ("unpack64-float32", ports.unpack64)])
def test_decoder_with_psi4_constants_from_float32_end_points_passes(gdir, tmp_path, case, port):
    code = next(iter(_inputs(gdir, case).values()))
    assert _verify(gdir, tmp_path, {f"{case}.r": port(code, {"const32": True})}) == 0


def test_tie_rows_accept_either_code_by_the_stored_rule(gdir):
    with np.load(gdir / "pack64-float32.npz") as g:
        ties = g["result"] == "acceptable"
        assert ties.any()
        alts = g["q_acceptable"]
        assert (alts[ties] != g["q"][ties][:, None]).any()


# --------------------------------------------------------------------------
# oracle.check
# --------------------------------------------------------------------------


@pytest.mark.parametrize("case,fn", [
    ("shade", lambda r, zf: ports.alg3(r, zf, {})),
    ("pack32", lambda r: ports.pack32(r, {})),
    ("unpack32", lambda p: ports.unpack32(p, {})),
    ("pack64", lambda r: ports.pack64(r, {})),
])
def test_oracle_checks_cases_with_r_and_p_inputs(case, fn):
    rep = oracle.check(fn, case, dtype="float32", n_hypothesis=40)
    assert rep.passed, str(rep)
    assert rep.rows > 150


def test_oracle_gates_hypothesis_rows_per_row():
    """Drawn rows get per-row tolerances (not the largest category tolerance, 1.0 for Algorithm 1)."""
    from moments_ref.msm import shadow_intensity

    n_golden = golden.case_rows(golden.CASES["shadow_intensity-lower-float32"])[1].size

    def off_on_drawn_rows(b, zf):
        out = shadow_intensity(b, zf).copy()
        out[n_golden:] = np.clip(out[n_golden:] + np.float32(0.02), 0, 1) - np.float32(0.01)
        return out

    rep = oracle.check(off_on_drawn_rows, "shadow_intensity-lower", dtype="float32", n_hypothesis=60)
    # By default only the drawn rows inside Algorithm 1's contract are gated (which of the 60 are depends
    # on the draws); with strict every drawn row is, and nearly all of them are off by more than their tolerance.
    strict = oracle.check(off_on_drawn_rows, "shadow_intensity-lower", dtype="float32", n_hypothesis=60, strict=True)
    assert not rep.passed and rep.failures >= 10, str(rep)
    assert strict.failures >= 50 and strict.failures > rep.failures, str(strict)
    assert oracle.check(lambda b, zf: shadow_intensity(b, zf), "shadow_intensity-lower", dtype="float32",
                        n_hypothesis=60).passed


# --------------------------------------------------------------------------
# End-to-end cases: a whole float32 chain of independent ports, and one bug in it
# --------------------------------------------------------------------------


def _chain(b, zf, fmt, m):
    from moments_ref.nonlinear import phi  # Algorithm 2 has no independent port here

    r = phi(ports.bias(b, 3e-7, [0.0, 0.375, 0.0, 0.375], {}))
    if fmt == "64":
        r = ports.unpack64(ports.pack64(r, {}), m.get("unpack", {}))
    else:
        r = ports.unpack32(ports.pack32(r, {}), m.get("unpack", {}))
    return ports.alg3(r, zf, {})


def _filter_block(depth):
    """MSAA resolve of b(z), 9-tap Gaussian (sigma 2.4) with clamp-to-edge, guard band 4 cropped (numpy)."""
    b = np.stack([depth ** k for k in range(1, 5)], axis=-1).mean(axis=2, dtype=np.float64)
    w = np.exp(-np.arange(-4, 5) ** 2 / (2 * 2.4 ** 2))
    w /= w.sum()
    for axis in (1, 0):
        pad = [(0, 0)] * 3
        pad[axis] = (4, 4)
        p = np.pad(b, pad, mode="edge")
        b = sum(wk * np.take(p, np.arange(k, k + b.shape[axis]), axis=axis) for k, wk in enumerate(w))
    return b[4:-4, 4:-4].astype(np.float32)


@pytest.mark.parametrize("fmt", ["64", "32"])
def test_end_to_end_chain_of_ports_passes_and_a_decode_bug_fails(tmp_path, fmt):
    case = f"e2e-nlq{fmt}-float32"
    g = tmp_path / "g"
    golden.write(g, [case, f"e2e-block-nlq{fmt}-float32"])
    with np.load(g / f"{case}.npz") as z:
        b, zf = z["b"], z["zf"]
    ok = _chain(b, zf, fmt, {})
    bug = _chain(b, zf, fmt, {"unpack": {"y_half": True} if fmt == "64" else {"corner": True}})
    assert _verify(g, tmp_path, {f"{case}.intensity": ok}) == 0
    assert _verify(g, tmp_path, {f"{case}.intensity": bug}) == 1
    block = f"e2e-block-nlq{fmt}-float32"
    with np.load(g / f"{block}.npz") as z:
        depth, zfb = z["depth"], z["zf"]
    out = np.stack([_chain(_filter_block(d).reshape(-1, 4), f.reshape(-1), fmt, {}).reshape(f.shape)
                    for d, f in zip(depth, zfb)])
    assert _verify(g, tmp_path, {f"{block}.intensity": out}) == 0
