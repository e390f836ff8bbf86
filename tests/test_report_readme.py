"""The "Your own scene" example of docs/report.md loads, names every scene key, and runs in the report."""

import re
from pathlib import Path

from moments_ref import report
from moments_ref.scene import files, load_scene

ROOT = Path(__file__).resolve().parents[1]


def _example():
    text = (ROOT / "docs" / "report.md").read_text()
    section = text[text.index("## Your own scene"):]
    toml = re.search(r"```toml\n(.*?)```", section, re.S).group(1)
    obj = re.search(r"`block\.obj`.*?```\n(.*?)```", section, re.S).group(1)
    return toml, obj


def test_the_example_names_every_key():
    toml, _ = _example()
    keys = set(re.findall(r"^\s*(\w+)\s*=", toml, re.M)) | set(re.findall(r"^\[+(\w+)\]+", toml, re.M))
    assert files._TOP_KEYS <= keys
    assert files._OBJ_KEYS <= keys | {"generator", "obj"}
    assert {"eye", "target", "up", "fov", "resolution", "near", "far", "type", "direction"} <= keys


def test_the_example_scene_runs_in_the_report(tmp_path, capsys):
    toml, obj = _example()
    (tmp_path / "my-scene.toml").write_text(toml)
    (tmp_path / "block.obj").write_text(obj)
    sc = load_scene(tmp_path / "my-scene.toml")
    assert sc.outputs == ("pcf", "msm64", "nlq64") and sc.occluder.n_triangles == 12
    res = report.run(scenes=[str(tmp_path / "my-scene.toml")], out_dir=tmp_path / "out", progress=False,
                     noise_tiles=1, repeats=1, jobs=1)
    assert [r["technique"] for r in res["rows"]] == ["pcf", "msm64", "nlq64"]  # the scene's outputs
    assert any(r["pareto"] for r in res["rows"])
    err = capsys.readouterr().err  # the reduction is stated, with the way to the scene's own settings
    assert "shadow map 128×128 (scene: 256×256)" in err and "camera 80×45 (scene: 320×180)" in err
    assert "--full" in err
    md = (tmp_path / "out" / "report.md").read_text()
    assert "## Pareto front" in md and "128×128 (256×256)" in md
