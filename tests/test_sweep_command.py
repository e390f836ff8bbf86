"""``moments-ref sweep`` in this process (sweep/command.py): exit codes 0, 1 and 2, the JSON file, the row folders.

docs/sweep.md: **0** no confirmed wrong row; **1** confirmed wrong rows, each distinct failure shrunk, printed
and written under ``--out``; **2** bad usage or input (one line on stderr), a shader that does not compile, or
any failure of the harness (never a verdict on the port). The shipped GLSL Algorithm 3 passes; the same file
with its last two branches swapped (``wl`` for ``1 − wl``, wrong wherever the receiver lies behind y2) fails.
Run in this process (``cli.main``), so that the command's own code is what runs.
"""

from __future__ import annotations

import json

import pytest

from moments_ref import cli
from moments_ref.sweep.command import MAX_ROWS, parse_rows
from moments_ref._arrays import InputError

RET = "return (zf <= y2) ? wl : 1.0 - wl;"


def _port():
    from moments_ref.conformance import shipped_port

    return shipped_port("shade-float32", "glsl")


def _argv(path, function, *extra):
    return ["sweep", "--glsl", str(path), "--function", function, "--case", "shade-float32", "--rows", "300",
            "--adapter", "gl", *extra]


def _one_line(capsys):
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    return err


def test_the_shipped_port_exits_0_and_writes_its_record(ctx, tmp_path, capsys):
    path, function = _port()
    code = cli.main(_argv(path, function, "--json", str(tmp_path / "s.json"), "--out", str(tmp_path / "out")))
    assert code == 0
    rec = json.loads((tmp_path / "s.json").read_text())
    assert rec["passed"] is True and rec["rows"] == 300 and rec["case"] == "shade-float32"
    assert rec["drivers"]["gl"]["confirmed"] == 0 and rec["failures"] == []
    assert sum(v["rows"] for v in rec["strata"].values()) == 300
    assert (tmp_path / "out" / "checkpoint.json").is_file() and not list((tmp_path / "out").glob("failure-*"))
    assert "sweep shade-float32: 300 rows, seed 0" in capsys.readouterr().out


def test_a_port_with_swapped_branches_exits_1_with_its_shrunk_rows(ctx, tmp_path, capsys):
    path, function = _port()
    src = path.read_text()
    assert src.count(RET) == 1
    mutant = tmp_path / "nonlinear.glsl"
    mutant.write_text(src.replace(RET, "return (zf <= y2) ? 1.0 - wl : wl;"))
    code = cli.main(_argv(mutant, function, "--json", str(tmp_path / "s.json"), "--out", str(tmp_path / "out")))
    assert code == 1
    rec = json.loads((tmp_path / "s.json").read_text())
    assert rec["passed"] is False and rec["drivers"]["gl"]["confirmed"] > 0 and rec["failures"]
    folders = sorted(p.name for p in (tmp_path / "out").glob("failure-*"))
    assert folders == [f"failure-{k}" for k in range(len(rec["failures"]))]
    assert "confirmed wrong (mpmath)" in capsys.readouterr().out


def test_a_shader_that_does_not_compile_exits_2_never_a_verdict(ctx, tmp_path, capsys):
    path, function = _port()
    broken = tmp_path / "nonlinear.glsl"
    broken.write_text(path.read_text().replace(RET, "return (zf <= y2) ? wl : 1.0 - wl"))  # a missing semicolon
    assert cli.main(_argv(broken, function, "--json", str(tmp_path / "s.json"))) == 2
    err = capsys.readouterr().err  # the line, then the compiler's own diagnostic
    assert err.startswith("moments-ref sweep: the wrapped function does not compile") and "Traceback" not in err
    assert not (tmp_path / "s.json").exists()


@pytest.mark.parametrize("edit, text", [
    (("--rows", "0"), "--rows"), (("--rows", "1e11"), "--rows"), (("--rows", "abc"), "--rows"),
    (("--rows", "1.5"), "--rows"), (("--case", "nope-float32"), "--case"),
    (("--case", "shade-float64"), "no sampler"), (("--function", None), "--function is required"),
    (("--glsl", "no-such-file.glsl"), "no such file"), (("--glsl", None), "expected one of"),
    (("--receiver-offset", "1e-4"), "receiver_offset: the sweep does not honour")])
def test_bad_input_exits_2_with_one_line(edit, text, capsys, tmp_path):
    path, function = _port()
    argv = _argv(path, function)
    key, value = edit
    if key in argv and value is None:  # drop the option
        i = argv.index(key)
        del argv[i:i + 2]
    elif key in argv:
        argv[argv.index(key) + 1] = value
    else:
        argv += [key, value]
    assert cli.main(argv) == 2
    assert text in _one_line(capsys)


@pytest.mark.parametrize("text, rows", [("1", 1), ("1000", 1000), ("1e8", 10**8), ("1E6", 10**6),
                                        (f"{MAX_ROWS}", MAX_ROWS), ("1e10", 10**10)])
def test_rows_read_as_whole_numbers_up_to_the_limit(text, rows):
    assert parse_rows(text) == rows and type(parse_rows(text)) is int


@pytest.mark.parametrize("text", ["0", "-5", "2.5", "1e-3", f"{MAX_ROWS + 1}", "1e11", "inf", "nan", "", "ten"])
def test_rows_refused_outside_one_to_the_limit(text):
    with pytest.raises(InputError, match="--rows"):
        parse_rows(text)


# --- the command's plumbing, the sweep itself replaced by a recorder ------------------------------------------------

class _Recorder:
    """Stands in for ``result.sweep_port``: records what the command asks for and returns a result with
    ``confirmed`` wrong rows (or raises ``error``)."""

    def __init__(self, confirmed=0, error=None):
        self.confirmed, self.error, self.calls = confirmed, error, []

    def __call__(self, spec, workers, scheduler, out, progress):
        from moments_ref.sweep.result import SweepResult
        from moments_ref.sweep.runner import STAGES

        self.calls.append(dict(spec=spec, workers=workers, scheduler=scheduler, out=out))
        if self.error is not None:
            raise self.error
        drivers = {str(d): {"flagged": self.confirmed, "confirmed": self.confirmed, "unconfirmed": 0, "examined":
                            self.confirmed, "first_confirmed": None, "per_stratum": {}} for d in spec.drivers}
        return SweepResult(spec.case.name, spec.rows, spec.seed, {}, drivers, dict.fromkeys(STAGES, 0.0))


@pytest.fixture
def recorder(monkeypatch):
    from moments_ref.sweep import result

    def make(**kw):
        r = _Recorder(**kw)
        monkeypatch.setattr(result, "sweep_port", r)
        return r

    return make


@pytest.mark.parametrize("rows, extra, workers", [("300", [], 1), ("131072", [], 1), ("131073", [], 2),
                                                  ("1e6", ["--workers", "3"], 3), ("300", ["--workers", "4"], 4)])
def test_workers_default_to_two_above_one_chunk(recorder, rows, extra, workers):
    from moments_ref.sweep import CHUNK

    assert CHUNK == 131072
    rec = recorder()
    path, function = _port()
    argv = _argv(path, function) + extra
    argv[argv.index("--rows") + 1] = rows
    assert cli.main(argv) == 0
    (call,) = rec.calls
    assert call["workers"] == workers and call["spec"].rows == int(float(rows))


def test_the_spec_carries_the_seed_drivers_strictness_and_scheduler(recorder, tmp_path):
    rec = recorder()
    path, function = _port()
    argv = _argv(path, function, "--seed", "9", "--strict", "--scheduler", "tcp://nowhere:1", "--out", str(tmp_path))
    argv[argv.index("--adapter") + 1] = "both"
    assert cli.main(argv) == 0
    (call,) = rec.calls
    spec = call["spec"]
    assert (spec.seed, spec.strict, spec.drivers, spec.case_name) == (9, True, ("gl", "vulkan"), "shade-float32")
    assert call["scheduler"] == "tcp://nowhere:1" and str(call["out"]) == str(tmp_path)
    assert spec.port.language == "glsl" and spec.port.function == function
    argv = _argv(path, function)
    del argv[argv.index("--adapter"):argv.index("--adapter") + 2]
    assert cli.main(argv) == 0
    from moments_ref.conformance import DEFAULT_DRIVER

    assert rec.calls[-1]["spec"].drivers == (DEFAULT_DRIVER["glsl"],) and rec.calls[-1]["spec"].seed == 0
    assert rec.calls[-1]["spec"].strict is False


def test_confirmed_rows_exit_1_and_the_json_is_written(recorder, tmp_path, capsys):
    recorder(confirmed=2)
    path, function = _port()
    assert cli.main(_argv(path, function, "--json", str(tmp_path / "s.json"))) == 1
    rec = json.loads((tmp_path / "s.json").read_text())
    assert rec["passed"] is False and rec["drivers"]["gl"]["confirmed"] == 2
    assert "2 confirmed wrong" in capsys.readouterr().out


@pytest.mark.parametrize("error, text", [(RuntimeError("boom"), "the harness failed"),
                                         (InputError("--out: not writable"), "--out: not writable")])
def test_a_failure_of_the_harness_exits_2_with_one_line(recorder, error, text, capsys, tmp_path):
    recorder(error=error)
    path, function = _port()
    assert cli.main(_argv(path, function, "--json", str(tmp_path / "s.json"))) == 2
    err = _one_line(capsys)
    assert text in err and err.startswith("moments-ref sweep: ")
    if isinstance(error, RuntimeError):
        assert "not a verdict on the port" in err
    assert not (tmp_path / "s.json").exists()


def test_an_out_folder_holding_something_else_as_its_checkpoint_is_refused(tmp_path, capsys):
    """docs/sweep.md: a checkpoint.json that is not a checkpoint is refused before any work (exit 2), never
    overwritten."""
    path, function = _port()
    (tmp_path / "checkpoint.json").write_text("my notes")
    assert cli.main(_argv(path, function, "--out", str(tmp_path))) == 2
    assert "is not a sweep checkpoint" in _one_line(capsys)
    assert (tmp_path / "checkpoint.json").read_text() == "my notes"
