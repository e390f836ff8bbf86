"""docs/ports.md: every adapter example runs, as printed, on both drivers; docs/conformance.md is sane.

Drivers absent: skipped, or failed under CI (the `drivers` fixture of conftest.py).
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from moments_ref import conformance
from moments_ref.conformance import _cli, languages

from test_conformance_languages import COMBOS

ROOT = Path(__file__).resolve().parents[1]
PORTS_MD = (ROOT / "docs" / "ports.md").read_text()
EXAMPLES = re.findall(r"<!-- example: (\S+) function=(\S+) case=(\S+)(?: profile=(\S+))? -->\s*```\w+\n(.*?)```",
                      PORTS_MD, re.S)
PROFILES = dict(re.findall(r"<!-- profile: (\S+) -->\s*```toml\n(.*?)```", PORTS_MD, re.S))


def test_the_examples_are_a_profile_and_glue():
    names = [e[0] for e in EXAMPLES]
    assert names == ["engine01.hlsl", "out_params.wgsl", "depth01.wgsl"]
    engine = EXAMPLES[0]
    assert engine[3] == "engine01.toml" and engine[3] in PROFILES
    # In the style of the slides' "Compute the shadow intensity": its names and steps, no adapter.
    for word in ("L32D22", "D33D22", "InvD22", "float4 Switch", "Quotient", "saturate"):
        assert word in engine[4]


def _profile(tmp_path, name):
    from moments_ref.golden.profile import load_profile

    if not name:
        return None
    path = tmp_path / name
    path.write_text(PROFILES[name])
    return load_profile(path)


@pytest.mark.parametrize("driver", ["gl", "vulkan"])
@pytest.mark.parametrize("name,function,case,profile,code", EXAMPLES, ids=[e[0] for e in EXAMPLES])
def test_example_passes(drivers, tmp_path, name, function, case, profile, code, driver):
    path = tmp_path / name
    path.write_text(code)
    cases = [case, "engine-lower-float32"] if profile else [case]
    for c in cases:
        report = conformance.run_case(path, function, c, None, None, driver, profile=_profile(tmp_path, profile))
        assert report.passed, report.format()


@pytest.mark.parametrize("name,engine,case", [("engine01.hlsl", "EngineVisibility", "shadow_intensity-lower-float32"),
                                               ("depth01.wgsl", "engine_unpack64", "unpack64-float32")])
def test_engine_function_without_its_profile_or_glue_fails(drivers, tmp_path, name, engine, case):
    # The conventions matter: the unchanged engine function alone is told apart.
    code = dict((e[0], e[4]) for e in EXAMPLES)[name]
    path = tmp_path / name
    path.write_text(code)
    report = conformance.run_case(path, engine, case)
    assert not report.passed and report.categories["random"].failures > 0


def test_generated_conformance_md_passes_everywhere_within_the_time_limits():
    text = (ROOT / "docs" / "conformance.md").read_text()
    assert "| FAIL |" not in text
    rows = re.findall(r"^\| (glsl|hlsl|wgsl) \| (gl|vulkan) \| .*? \| (\d+) \| (\d+) \| (\d+) \| (\d+) \| ([\d.]+) \| "
                      r"([\d.]+) \| ([\d.]+) \|$", text, re.M)
    assert {(r[0], r[1]) for r in rows} == set(COMBOS)
    shipped = conformance.shipped_cases()
    for lang, drv, cases, run, refused, failed, first, median, worst in rows:
        # Every shipped case is listed; those declared not available on this pair are refused, the rest run.
        declared = [c for c in shipped if conformance.not_available(c, lang, drv)]
        assert int(cases) == len(shipped) and int(refused) == len(declared) and int(run) == len(shipped) - len(declared)
        assert int(failed) == 0
        assert float(worst) < 2.0  # one case after the first: under 2 s
        for c in declared:
            why = conformance.not_available(c, lang, drv)
            assert f"| {lang} | {drv} | {c} | {why} |" in text
            section = text.split(f"## {lang.upper()} on {drv}\n", 1)[1].split("\n## ", 1)[0]
            assert f"| {c} | " in section and f"not available on this driver: {why} |" in section
    total = float(re.search(r"Whole run \(golden generation included\): ([\d.]+) s", text).group(1))
    assert total < 60


def test_summary_markdown_on_two_cases(drivers, monkeypatch):
    monkeypatch.setattr(_cli, "shipped_cases", lambda: ["psi4-float32", "pack32-float32", "sample_bilinear-float32"])
    text = _cli.summary_markdown(probes=False)
    # Every language on both drivers; Slang (psi4 and pack32, no bilinear port) where its extra is installed.
    pairs = 2 * len([x for x in conformance.ALL_LANGUAGES if languages.available(x)])
    assert text.count("| psi4-float32 | `psi4` |") == pairs and "| FAIL |" not in text
    assert "## The two drivers agree" in text and "Whole run" in text
    # The bilinear case is listed on all six pairs: run on four, refused as declared on two.
    refused = [(lang, drv) for lang, drv in COMBOS if conformance.not_available("sample_bilinear-float32", lang, drv)]
    assert len(refused) == 2 and text.count("| sample_bilinear-float32 | `sample_moments` |") == 6
    assert text.count("not available on this driver: ") == 2 and "## Not available on a driver" in text
    for lang, drv in refused:
        assert f"| {lang} | {drv} | sample_bilinear-float32 | " in text
        assert re.search(rf"^\| {lang} \| {drv} \| .*? \| 3 \| 2 \| 1 \| 0 \| ", text, re.M)


def test_a_record_compared_with_its_own_run_differs_nowhere(drivers, monkeypatch, tmp_path):
    """``--all --record`` then ``--all --gpu-record`` on the same drivers: the section finds no difference."""
    from moments_ref.conformance.kernel import cli as kernel_cli

    monkeypatch.setattr(_cli, "shipped_cases", lambda: ["psi4-float32", "pack32-float32"])
    monkeypatch.setattr(kernel_cli, "SHIPPED_KERNELS", {"kernel-vwss-points": ("vwss_points", {"glsl": "main"})})
    record = tmp_path / "r.npz"
    first = _cli.summary_markdown(probes=False, record=record)
    assert "## On a GPU" not in first and record.is_file()
    text = _cli.summary_markdown(probes=False, gpu_record=record)
    assert f"--gpu-record {record.as_posix()}`" in text.splitlines()[2]
    section = text.split("## On a GPU\n", 1)[1]
    for lang in (x for x in conformance.ALL_LANGUAGES if languages.available(x)):
        for drv in ("gl", "vulkan"):
            assert re.search(rf"^\| {lang} \| {drv} \| \d+ \| 0 \| 0 \| 0 \| none \| – \|$", section, re.M), lang
    for drv in ("gl", "vulkan"):
        assert f"| kernel-vwss-points | glsl | {drv} | pass | " in section
        assert re.search(rf"^\| kernel-vwss-points \| glsl \| {drv} \| pass \| .* \| pass \| 0 \| 0 \|$", section, re.M)


def test_all_keeps_running_when_a_driver_is_missing_or_a_port_does_not_compile(drivers, monkeypatch):
    """A target without its driver leaves its rows "not run" (exit 2 from the CLI); the others still run; a
    shipped port a driver refuses to compile is a failing row, not the end of the run."""
    from moments_ref.conformance import ContextError
    from moments_ref.conformance._source import ShaderError

    real = _cli.run_case

    def run_case(path, function, name, golden_dir, language, spec, **kw):
        if spec == "vulkan":
            raise ContextError("no Vulkan adapter here")
        if language == "hlsl":
            raise ShaderError("port.hlsl:3: 'expression' : Expected")
        return real(path, function, name, golden_dir, language, spec, **kw)

    monkeypatch.setattr(_cli, "shipped_cases", lambda: ["psi4-float32"])
    monkeypatch.setattr(_cli, "run_case", run_case)
    text = _cli.summary_markdown(probes=False)
    assert text.count("| psi4-float32 | `psi4` | – | – | – | – | not run: ContextError: no Vulkan adapter here |") \
        == len([x for x in conformance.ALL_LANGUAGES if languages.available(x)])
    assert "| psi4-float32 | `psi4` | – | – | – | ShaderError: port.hlsl:3: 'expression' : Expected | FAIL |" in text
    gl = text.split("## GLSL on gl\n", 1)[1].split("\n## ", 1)[0]
    assert re.search(r"^\| psi4-float32 \| `psi4` \| .* \| pass \|$", gl, re.M)


@pytest.mark.parametrize("row, code", [("| c | `f` | 0.1 | – | – | m | pass |", 0), ("| c | `f` | 2 | – | – | m | FAIL |", 1),
                                       ("| c | `f` | – | – | – | – | not run: ContextError: none |", 2)])
def test_the_exit_status_of_all(monkeypatch, capsys, row, code):
    import argparse

    monkeypatch.setattr(_cli, "summary_markdown", lambda **kw: f"# x\n\n{row}\n")
    assert _cli.main(argparse.Namespace(all=True)) == code
