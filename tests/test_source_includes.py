"""The harness's one include preprocessor: comments and inactive ``#if`` branches are respected in
every language and on every driver, and an include that is not found names its file and line."""

from __future__ import annotations

import pytest

from moments_ref import conformance
from moments_ref.conformance._source import ShaderError, load_source
from moments_ref.ports import PORTS_DIR


def _file(tmp_path, name, text):
    p = tmp_path / name
    p.write_text(text)
    return p


@pytest.mark.parametrize("language", ["glsl", "hlsl", "wgsl", "slang"])
def test_includes_in_comments_are_not_followed(tmp_path, language):
    _file(tmp_path, f"real.{language}", "// the real one\n")
    src = _file(tmp_path, f"p.{language}", '// #include "Core.shader"\n/*\n#include "Core.shader"\n*/\n'
                '/* a */ #include "real.' + language + '"\n')
    s = load_source(src, language)
    assert "Core.shader" in s.body and '#include "Core' not in s.body  # kept as text, written #_include
    assert "// the real one" in s.body  # an include after a closed comment is one


@pytest.mark.parametrize("language", ["glsl", "hlsl", "slang"])
def test_inactive_branches_are_not_followed(tmp_path, language):
    _file(tmp_path, f"once.{language}", "int once_marker;\n")
    src = _file(tmp_path, f"p.{language}", f'#if 0\n#include "missing.{language}"\n#include "once.{language}"\n'
                f'#endif\n#define HAVE_X 1\n#ifndef HAVE_X\n#include "missing.{language}"\n#else\n'
                f'#include "once.{language}"\n#endif\n')
    s = load_source(src, language)
    assert "#error" not in s.body and s.body.count("int once_marker;") == 1
    lines = s.body.splitlines()
    # The file included in the inactive branch is included where the branch is active.
    assert lines.index("int once_marker;") > next(i for i, x in enumerate(lines) if x.startswith("#else"))


def test_a_missing_include_in_an_undecidable_branch_is_an_error_line_naming_file_and_line(tmp_path):
    src = _file(tmp_path, "p.glsl", "#ifdef ENGINE_MACRO\n#include \"missing.glsl\"\n#endif\n")
    body = load_source(src, "glsl").body
    assert f"#error {src}:2: include \"missing.glsl\" not found" in body
    wgsl = _file(tmp_path, "p.wgsl", '// fine\n#include "missing.wgsl"\n')
    with pytest.raises(ShaderError, match=rf"{wgsl}:2: include \"missing.wgsl\" not found"):
        load_source(wgsl, "wgsl")


def test_a_commented_include_runs_on_opengl(drivers, golden_dir, tmp_path):
    # moderngl expands every #include "..." of its text, comments included: before, this exited 2
    # with 'cannot include "Core.shader"' and no file or line; Vulkan ran the same file.
    text = (PORTS_DIR / "glsl" / "nonlinear.glsl").read_text()
    src = _file(tmp_path, "nonlinear.glsl", '// #include "Core.shader"\n' + text)
    for driver in ("gl", "vulkan"):
        report = conformance.run_case(src, "psi4", "psi4-float32", golden_dir, "glsl", driver)
        assert report.passed, report.format()
