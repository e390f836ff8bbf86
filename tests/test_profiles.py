"""Engine profiles: declared conventions instead of adapters (golden.profile, golden.conventions).

Checked against independent means: the converted inputs against exact rational
arithmetic, the expected values against the mpmath twin applied to the exact biased
input, and the command line's refusals as real processes (exit 2, one line).
"""

from __future__ import annotations

import hashlib
import json
import math
import subprocess
import sys
from fractions import Fraction

import numpy as np
import pytest

from moments_ref import InputError, golden, precise
from moments_ref.golden.conventions import convert_inputs, profile_arrays, profiled_arrays
from moments_ref.golden.profile import Profile, load_profile, parse_profile, profile_from_args
from moments_ref.moments import BiasPreset

CASES = ["shadow_intensity-lower-float32", "shade-float32", "engine-lower-float32"]
MJP = {"depth": "[0,1]", "output": "visibility", "bias": {"alpha": 3e-6, "target": [0.5] * 4, "applied": "inside"}}


@pytest.fixture(scope="module")
def gdir(tmp_path_factory):
    d = tmp_path_factory.mktemp("golden_profiles")
    golden.write(d, CASES)
    return d


@pytest.fixture(autouse=True)
def _cache(tmp_path, monkeypatch):
    monkeypatch.setenv("MOMENTS_REF_CACHE", str(tmp_path / "cache"))


def _cli(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "moments_ref", *map(str, args)], capture_output=True, text=True,
                          cwd=cwd)


def _reference_results(gdir, path, names=("shadow_intensity-lower-float32", "shade-float32")):
    out = {}
    for name in names:
        case = golden.CASES[name]
        with np.load(gdir / f"{name}.npz") as g:
            inputs = {k: g[k] for k in case.inputs}
        out[f"{name}.intensity"] = golden.evaluate_reference(case, inputs, case.dtype)[0]
    np.savez(path, **out)
    return path


def test_every_key_parses_and_the_file_overrides_per_function(tmp_path):
    f = tmp_path / "engine.toml"
    f.write_text('depth = "[0,1]"\noutput = "visibility"\nclamp = 5e-6\nclamp_test = "clamped"\n'
                 '[bias]\nalpha = 3e-6\ntarget = [0.5, 0.34375, 0.265625, 0.2265625]\napplied = "inside"\n'
                 '[format]\nxi_rounding = "nearest"\n'
                 '[functions.shade]\nbias = "none"\ndepth = "[-1,1]"\n')
    p = load_profile(f)
    assert p.depth == "[0,1]" and p.output == "visibility" and p.clamp == 5e-6 and p.clamp_test == "clamped"
    assert p.bias.alpha == 3e-6 and p.bias.applied == "inside" and dict(p.format) == {"xi_rounding": "nearest"}
    shade = p.for_function("shade")
    assert shade.depth == "[-1,1]" and not shade.bias.active and shade.clamp == 5e-6
    assert p.for_function("other").depth == "[0,1]"
    # Each key has a flag; flags win over the file.
    q = profile_from_args(f, "other", depth="[-1,1]", bias_alpha="1e-4", clamp="1e-6")
    assert q.depth == "[-1,1]" and q.bias.alpha == 1e-4 and q.bias.target == p.bias.target and q.clamp == 1e-6
    # The cache key is the content: the same content in another layout shares it.
    g = tmp_path / "same.toml"
    g.write_text('output = "visibility"\ndepth = "[0,1]"\nclamp_test = "clamped"\nclamp = 0.000005\n'
                 '[format]\nxi_rounding = "nearest"\n[functions.shade]\ndepth = "[-1,1]"\nbias = "none"\n'
                 '[bias]\napplied = "inside"\ntarget = [0.5, 0.34375, 0.265625, 0.2265625]\nalpha = 3e-6\n')
    assert load_profile(g).key == p.key and profile_from_args(f, "x", clamp="2e-6").key != p.key


@pytest.mark.parametrize("text,key", [
    ('depht = "[0,1]"\n', "depht"),
    ('[bias]\nalpha = 1e-4\ntarget = [0.0, 0.1, 0.0, 0.005]\napplied = "inside"\n', "bias.target"),  # b4 < b2²
    ('[bias]\nalpha = 1e-4\ntarget = [0.5, 0.2, 0.5, 0.5]\napplied = "inside"\n', "bias.target"),  # b2 < b1²
    ("clamp = 1e-4\n", "clamp"),
    ("clamp = 5e-8\n", "clamp"),
    ('[bias]\nalpha = 1.0\ntarget = [0, 0.375, 0, 0.375]\napplied = "before"\n', "bias.alpha"),
    ('[bias]\nalpha = 1e-4\ntarget = [0, 0.375, 0, 0.375]\n', "bias.applied"),
    ('[format]\ndepth_decode = "middle"\n', "format.depth_decode"),
    ('[functions.f]\nfoo = 1\n', "functions.f.foo"),
    ('depth = [0, 1\n', "not a TOML file"),
])
def test_a_refused_profile_is_exit_2_and_one_line_naming_the_key(gdir, tmp_path, text, key):
    f = tmp_path / "p.toml"
    f.write_text(text)
    res = _reference_results(gdir, tmp_path / "r.npz")
    r = _cli("verify", "--golden", gdir, "--results", res, "--profile", f)
    assert r.returncode == 2 and r.stdout == "", (r.stdout, r.stderr)
    assert r.stderr.count("\n") == 1 and key in r.stderr and "Traceback" not in r.stderr


def test_a_singular_target_is_allowed():
    p = parse_profile(MJP)
    assert p.bias.target == (0.5, 0.5, 0.5, 0.5)


def test_a_depth_range_that_contradicts_the_case_is_refused(gdir, tmp_path):
    # shade's representation comes from a texel format that fixes depths in [-1, 1].
    res = _reference_results(gdir, tmp_path / "r.npz")
    r = _cli("verify", "--golden", gdir, "--results", res, "--depth", "[0,1]")
    assert r.returncode == 2 and r.stderr.count("\n") == 1
    assert "depth" in r.stderr and "shade-float32" in r.stderr
    # visibility on a case without an intensity, and a 'before' bias where the function biases itself
    with pytest.raises(InputError, match="visibility"):
        profiled_arrays("psi4-float32", parse_profile({"output": "visibility"}))
    with pytest.raises(InputError, match="before"):
        profiled_arrays("bias_moments-float32-float32", parse_profile(
            {"bias": {"alpha": 1e-4, "target": [0, 0.375, 0, 0.375], "applied": "before"}}))


def test_inputs_are_converted_exactly_and_rounded_once():
    case = golden.CASES["shadow_intensity-lower-float32"]
    arrays = golden.golden_arrays(case)
    ins = {k: arrays[k] for k in case.inputs}
    p = parse_profile({"depth": "[0,1]", "bias": {"alpha": 6e-7, "target": [0.5, 0.3, 0.2, 0.15],
                                                    "applied": "before"}})
    conv = convert_inputs(case, ins, p)
    a, t = Fraction(6e-7), [Fraction(x) for x in (0.5, 0.3, 0.2, 0.15)]
    for i in range(0, len(ins["zf"]), 37):
        b = [Fraction(1)] + [Fraction(float(x)) for x in ins["b"][i]]
        for k in range(1, 5):  # moments of u = (z + 1)/2, then the caller's bias, exactly
            u = sum(Fraction(math.comb(k, j)) * b[j] for j in range(k + 1)) / 2**k
            exact = (1 - a) * u + a * t[k - 1]
            got = Fraction(float(conv["b"][i, k - 1]))
            below = Fraction(float(np.nextafter(np.float32(conv["b"][i, k - 1]), np.float32(-1))))
            above = Fraction(float(np.nextafter(np.float32(conv["b"][i, k - 1]), np.float32(2))))
            assert abs(got - exact) <= min(abs(below - exact), abs(above - exact))
        u = (Fraction(float(ins["zf"][i])) + 1) / 2  # rounded once, to nearest
        got = np.float32(conv["zf"][i])
        near = [Fraction(float(x)) for x in (got, np.nextafter(got, np.float32(-1)), np.nextafter(got, np.float32(2)))]
        assert abs(near[0] - u) <= min(abs(near[1] - u), abs(near[2] - u))


def test_expected_values_are_the_exact_bound_of_what_the_port_computes():
    # MJP's engine: [0, 1], visibility, bias inside: expected = 1 - bound(exact bias of the received moments).
    p = parse_profile(MJP)
    _, arrays = profiled_arrays("shadow_intensity-lower-float32", p)
    idx = np.arange(0, len(arrays["zf"]), 29)
    b = precise.bias_moments(arrays["b"][idx].astype(np.float64), BiasPreset(3e-6, (0.5,) * 4))
    truth = 1 - precise.shadow_intensity(b, arrays["zf"][idx].astype(np.float64))
    np.testing.assert_allclose(arrays["intensity"][idx], truth, rtol=0, atol=1e-15)
    assert json.dumps(golden.manifest_entry(golden.CASES["shadow_intensity-lower-float32"], arrays)["kwargs"])


def test_a_5e6_clamp_gets_its_own_expected_values_and_tolerances():
    p = parse_profile({"clamp": 5e-6, "clamp_test": "clamped"})
    case = golden.CASES["shade-float32"]
    base = golden.golden_arrays(case)
    _, arrays = profiled_arrays("shade-float32", p)
    clamp_rows = np.array(["clamp" in str(f) for f in base["flags"]])
    changed = arrays["intensity"] != base["intensity"]
    assert changed[clamp_rows].sum() >= 10 and not changed[~clamp_rows].any()
    assert (arrays["intensity_tolerance_float32"] != base["intensity_tolerance_float32"]).any()
    from moments_ref.golden.truth import shade_clamped

    r, zf = base["r"][clamp_rows], base["zf"][clamp_rows]
    np.testing.assert_array_equal(arrays["intensity"][clamp_rows],
                                  shade_clamped(r, zf, clamp=5e-6, case_test="clamped"))


def test_a_profile_never_changes_the_golden_folder_and_is_cached_by_content(gdir, tmp_path):
    before = {f.name: hashlib.sha256(f.read_bytes()).hexdigest() for f in gdir.iterdir()}
    res = _reference_results(gdir, tmp_path / "r.npz", ("shadow_intensity-lower-float32",))
    f = tmp_path / "hdrp.toml"
    f.write_text('[bias]\nalpha = 6e-7\ntarget = [0.0, 0.628, 0.0, 0.628]\napplied = "inside"\n')
    for _ in range(2):
        r = _cli("verify", "--golden", gdir, "--results", res, "--profile", f)
        assert r.returncode in (0, 1) and r.stderr == "", r.stderr
    after = {f.name: hashlib.sha256(f.read_bytes()).hexdigest() for f in gdir.iterdir()}
    assert before == after
    cached = list((tmp_path / "cache" / "profiles").glob("*.npz"))
    assert len(cached) == 1  # one derivation, reused by the second process


def test_profiles_apply_to_the_golden_folders_rows(gdir):
    # Derived from the folder's rows and labels, not regenerated: the same rows whatever the source.
    name = "shadow_intensity-lower-float32"
    meta = golden.load_manifest(gdir)["cases"][name]
    gold = golden.load_case_arrays(gdir, name, meta)
    p = parse_profile(MJP)
    _, a = profile_arrays(golden.CASES[name], gold, p)
    _, b = profiled_arrays(name, p, arrays=gold)
    np.testing.assert_array_equal(a["intensity"], b["intensity"])
    assert list(a["tc_id"]) == list(gold["tc_id"])


def test_the_default_profile_is_the_golden_file():
    case, arrays = profiled_arrays("shade-float32", Profile())
    base = golden.golden_arrays(golden.CASES["shade-float32"])
    for k in base:
        np.testing.assert_array_equal(arrays[k], base[k])


def test_golden_writes_a_folder_for_a_profile_that_verify_judges(tmp_path):
    # A porter running offline: the converted inputs come from `golden --profile`, the port runs on them.
    f = tmp_path / "mjp.toml"
    f.write_text('depth = "[0,1]"\noutput = "visibility"\n[bias]\nalpha = 3e-6\ntarget = [0.5, 0.34375, 0.265625, '
                 '0.2265625]\napplied = "inside"\n')
    out = tmp_path / "g"
    r = _cli("golden", "--out", out, "--profile", f)
    assert r.returncode == 0 and "not written" in r.stdout
    m = json.loads((out / "manifest.json").read_text())
    assert m["profile"]["depth"] == "[0,1]" and "shade-float32" in m["not_written"]
    name = "shadow_intensity-lower-float32"
    with np.load(out / f"{name}.npz") as g:
        b, zf = g["b"], g["zf"]
    import mutants.ports as ports

    got = ports.alg1(b, zf, {"visibility": True, "bias": (3e-6, [0.5, 0.34375, 0.265625, 0.2265625])})
    np.savez(tmp_path / "r.npz", **{f"{name}.intensity": got})
    assert _cli("verify", "--golden", out, "--results", tmp_path / "r.npz").returncode == 0
    assert _cli("verify", "--golden", out, "--results", tmp_path / "r.npz", "--profile", f).returncode == 0
    other = _cli("verify", "--golden", out, "--results", tmp_path / "r.npz", "--profile", f, "--clamp", "5e-6")
    assert other.returncode == 2 and "another profile" in other.stderr and other.stderr.count("\n") == 1


@pytest.mark.parametrize("args,key", [
    (["--profile", "BAD"], "depht"),
    (["--depth", "[0,1]"], "depth"),  # contradicts shade's texel-format depths
    (["--clamp", "0.5"], "clamp"),
    (["--bias-alpha", "1e-4", "--bias-target", "0,0.1,0,0.005", "--bias-applied", "inside"], "bias.target"),
])
def test_conformance_refuses_a_profile_with_exit_2_and_one_line(tmp_path, args, key):
    bad = tmp_path / "bad.toml"
    bad.write_text('depht = "[0,1]"\n')
    args = [str(bad) if a == "BAD" else a for a in args]
    r = _cli("conformance", "--glsl", "nonlinear.glsl", "--function", "shade", "--case", "shade-float32", *args)
    assert r.returncode == 2 and r.stdout == "", (r.stdout, r.stderr)
    assert r.stderr.count("\n") == 1 and key in r.stderr and "Traceback" not in r.stderr


def test_oracle_check_takes_a_profile_for_golden_and_drawn_rows():
    from moments_ref import oracle
    from mutants import corpus, ports

    engine = {"literal_root": True, "no_singular": True, "visibility": True, "bias": (3e-6, corpus.TARGET01)}
    port = lambda b, zf: ports.alg1(b, zf, engine)  # noqa: E731
    path = str(__import__("pathlib").Path(__file__).parent / "fixtures" / "wild" / "engine01.toml")
    with_profile = oracle.check(port, "shadow_intensity-lower", dtype="float32", n_hypothesis=20, profile=path)
    assert with_profile.passed and with_profile.rows == 407
    assert not oracle.check(port, "shadow_intensity-lower", dtype="float32", n_hypothesis=20).passed


# ---------------------------------------------------------------------------
# The parser's edges, each stated by the rule in golden.profile's docstring


def test_numbers_are_finite_non_boolean_numbers():
    for bad in (True, "0.5", float("inf"), float("nan")):
        with pytest.raises(InputError, match="bias.alpha: expected a finite number"):
            parse_profile({"bias": {"alpha": bad, "target": [0, 0.5, 0, 0.5], "applied": "inside"}})


def test_alpha_lies_in_zero_to_one_and_zero_is_no_bias():
    target = [0.0, 0.375, 0.0, 0.375]
    p = parse_profile({"bias": {"alpha": 0, "target": target, "applied": "inside"}})
    assert p.bias is not None and not p.bias.active and p.bias.target == ()
    assert parse_profile({"bias": {"alpha": 0.5, "target": target, "applied": "before"}}).bias.alpha == 0.5
    for bad in (1, 1.5, -0.1):
        with pytest.raises(InputError, match=r"bias.alpha: expected a number in \[0, 1\)"):
            parse_profile({"bias": {"alpha": bad, "target": target, "applied": "inside"}})


def test_a_target_holds_four_or_six_moments():
    six = [0.5 ** k for k in range(1, 7)]  # a point mass at 0.5: a moment vector
    assert parse_profile({"bias": {"alpha": 0.1, "target": six, "applied": "inside"}}).bias.target == tuple(six)
    for bad in ([0.1] * 5, [0.1] * 7, "0.1"):
        with pytest.raises(InputError, match=r"expected a list of 4 \(or 6\) numbers"):
            parse_profile({"bias": {"alpha": 0.1, "target": bad, "applied": "inside"}})


def test_the_clamp_band_is_closed():
    from moments_ref.nonlinear import CLAMP_BAND

    for c in CLAMP_BAND:
        assert parse_profile({"clamp": c}).clamp == c
    for c in (CLAMP_BAND[0] * 0.99, CLAMP_BAND[1] * 1.01):
        with pytest.raises(InputError, match="clamp: .* outside the allowed band"):
            parse_profile({"clamp": c})


def test_function_tables_take_the_keys_but_no_functions_of_their_own():
    p = parse_profile({"depth": "[-1,1]", "functions": {"f": {"depth": "[0,1]"}}})
    assert p.for_function("f").depth == "[0,1]" and p.for_function("g").depth == "[-1,1]"
    with pytest.raises(InputError, match="functions.f.functions: unknown key"):
        parse_profile({"functions": {"f": {"functions": {}}}})
    for bad in (3, {"f": 3}):
        with pytest.raises(InputError, match="functions: expected tables"):
            parse_profile({"functions": bad})


def test_a_profile_file_of_the_largest_size_is_read_whole(tmp_path):
    from moments_ref.golden.profile import MAX_PROFILE

    tail = '\ndepth = "[0,1]"'  # the key last, its closing quote the last byte: a file read short breaks it
    f = tmp_path / "big.toml"
    f.write_text("#" * (MAX_PROFILE - len(tail)) + tail)
    assert f.stat().st_size == MAX_PROFILE and load_profile(f).depth == "[0,1]"
    f.write_text("#" * (MAX_PROFILE + 1 - len(tail)) + tail)
    with pytest.raises(InputError, match="at most"):
        load_profile(f)


def test_flags_without_a_file_and_the_description():
    p = profile_from_args(None, depth="[0,1]", clamp="5e-6")
    assert (p.depth, p.clamp, p.bias) == ("[0,1]", 5e-6, None)
    assert Profile().describe() == "the papers' conventions"
    assert p.describe() == "depth [0,1], clamp 5e-06"
    q = profile_from_args(None, bias_alpha="0.25", bias_target="0,0.375,0,0.375", bias_applied="inside",
                          format_xi_rounding="nearest")
    assert q.describe() == "bias alpha 0.25 toward [0.0, 0.375, 0.0, 0.375] (inside), xi_rounding nearest"
    assert parse_profile({"bias": "none"}).describe() == "no bias"


@pytest.mark.parametrize("text,key,near", [
    ('depht = "[0,1]"\n', "depht", "depth"),
    ('clamp_tset = "clamped"\n', "clamp_tset", "clamp_test"),
    ('[bias]\nalpha = 1e-4\ntarget = [0, 0.375, 0, 0.375]\napplid = "inside"\n', "bias.applid", "applied"),
    ('[format]\nxi_round = "up"\n', "format.xi_round", "xi_rounding"),
])
def test_a_misspelled_key_is_refused_naming_the_nearest_valid_key(text, key, near):
    import tomllib

    with pytest.raises(InputError, match=f"{key}: unknown key \\(did you mean '{near}'\\?"):
        parse_profile(tomllib.loads(text))


# ---------------------------------------------------------------------------
# One registry of keys (golden.profile.KEYS): parser, flags, docs and the case check read it


def test_the_key_table_of_docs_ports_is_generated():
    """docs/ports.md's key table is what KEYS writes, and KEYS, Profile's fields and the flags name the same keys."""
    import dataclasses
    from pathlib import Path

    from moments_ref.golden.profile import FLAGS, KEYS, MARKERS, keys_markdown

    text = (Path(__file__).resolve().parents[1] / "docs" / "ports.md").read_text()
    table = text.split(MARKERS[0], 1)[1].split(MARKERS[1], 1)[0]
    assert table == keys_markdown(), "regenerate: python -m moments_ref.tools.apidoc --profile-keys"
    names = [k.name for k in KEYS]
    assert [f.name for f in dataclasses.fields(Profile) if f.name not in ("functions", "source")] == names
    assert {p.partition(".")[0] for _, p, _ in FLAGS} == set(names)
    assert all(f"`{n}`" in table for n in names)


def test_a_key_a_case_ignores_is_named_with_why_and_one_no_case_can_use_is_refused(gdir, tmp_path):
    from moments_ref.golden.cases import CASES as ALL
    from moments_ref.golden.profile import ignored_keys, ignored_note, refuse_meaningless

    biased = parse_profile({"bias": {"alpha": 1e-4, "target": [0, 0.375, 0, 0.375], "applied": "inside"},
                            "receiver_offset": 1e-6})
    # shade takes biased, quantized moments: bias means nothing for it, the receiver offset does
    assert [k for k, _ in ignored_keys(ALL["shade-float32"], biased)] == ["bias"]
    assert "biases no moments" in ignored_note(ALL["shade-float32"], biased)[0]
    assert ignored_keys(ALL["shadow_intensity-lower-float32"], biased) == []
    assert [k for k, _ in ignored_keys(ALL["pack64-float32"], biased)] == ["bias", "receiver_offset"]
    refuse_meaningless([ALL["shade-float32"], ALL["shadow_intensity-lower-float32"]], biased)  # one uses each
    with pytest.raises(InputError, match="bias: no selected case can use it"):
        refuse_meaningless([ALL["shade-float32"]], biased)
    # the command line: a flag no case of the run can use is exit 2, a file's key the case ignores is named
    r = _cli("conformance", "--glsl", "nonlinear.glsl", "--function", "shade", "--case", "shade-float32",
             "--bias-alpha", "1e-4", "--bias-target", "0,0.375,0,0.375", "--bias-applied", "inside", "--golden", gdir)
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "bias: no selected case can use it" in r.stderr
    f = tmp_path / "engine.toml"
    f.write_text('[bias]\nalpha = 1e-4\ntarget = [0, 0.375, 0, 0.375]\napplied = "inside"\n')
    r = _cli("conformance", "--glsl", "nonlinear.glsl", "--function", "shade", "--case", "shade-float32",
             "--profile", f, "--golden", gdir)
    assert r.returncode == 0, r.stdout + r.stderr
    assert "profile keys this case ignores: bias (it biases no moments" in r.stdout
    # verify: the keys no verified case can use are refused
    res = _reference_results(gdir, tmp_path / "r.npz", names=("shade-float32",))
    r = _cli("verify", "--golden", gdir, "--results", res, "--profile", f)
    assert r.returncode == 2 and "bias: no selected case can use it" in r.stderr
