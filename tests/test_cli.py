"""The command line: --help everywhere, exit code 2 with one line on bad input."""

import subprocess
import sys

import pytest

from moments_ref.cli import build_parser, main

SUBCOMMANDS = sorted(next(a for a in build_parser()._actions if a.dest == "command").choices)


@pytest.mark.parametrize("name", SUBCOMMANDS)
def test_help(name, capsys):
    with pytest.raises(SystemExit) as exc:
        main([name, "--help"])
    assert exc.value.code == 0
    assert "usage: moments-ref" in capsys.readouterr().out


def test_bad_usage_exits_2():
    with pytest.raises(SystemExit) as exc:
        main(["golden"])  # --out missing
    assert exc.value.code == 2


def test_bad_input_is_one_line_on_stderr(tmp_path):
    r = subprocess.run([sys.executable, "-m", "moments_ref", "verify", "--golden", str(tmp_path),
                        "--results", str(tmp_path / "none.npz")], capture_output=True, text=True)
    assert r.returncode == 2
    assert r.stderr.count("\n") == 1 and "golden_dir" in r.stderr


def test_unknown_scene_lists_known(capsys):
    assert main(["figure4", "--out", "/tmp/unused-figure4", "--scene", "no-such-scene"]) == 2
    err = capsys.readouterr().err
    assert "railing" in err and err.count("\n") == 1


def test_report_gets_the_parsed_arguments(monkeypatch, tmp_path):
    """The command line hands the report its parsed values (no argv rebuilt), defined once for both parsers."""
    from moments_ref import report

    seen = {}

    def fake_run(**kw):
        seen.update(kw)
        return {"paths": {}, "claims": []}

    monkeypatch.setattr(report, "run", fake_run)
    assert main(["report", "--scene", "facade", "--scene", "knot", "--repeats", "2", "--jobs", "1",
                 "--technique", "pcf", "--out", str(tmp_path)]) == 0
    assert seen["scenes"] == ["facade", "knot"] and seen["repeats"] == 2 and seen["jobs"] == 1
    assert seen["techniques"] == ["pcf"] and seen["out_dir"] == tmp_path and seen["full"] is False
    cli_report = next(a for a in build_parser()._actions if a.dest == "command").choices["report"]
    ours = {s for a in report.build_parser()._actions for s in a.option_strings}
    assert ours <= {s for a in cli_report._actions for s in a.option_strings}
