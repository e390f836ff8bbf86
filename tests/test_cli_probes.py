"""A table of bad command lines: each must exit 2 with one line on stderr, never a traceback.

Each probe is ``(id, argv, setup)``: ``argv`` may hold ``{tmp}`` (a fresh folder)
and ``setup(tmp)`` writes the files the probe needs. The classes: an unwritable or
invalid ``--out`` (a path under /dev/null, an existing file) for every command that
writes; bad numbers (``bench --size -1``, ``figure4 --samples 3``, ``--max-memory``);
scene files that are not UTF-8, not TOML, an OBJ vertex with w = 0, a camera that
sees no receiver, parameters whose memory exceeds the limit (a 10⁵ × 10⁵ plane, a
huge torus knot, a 20000² camera); missing or special input files; and output
piped into a reader that closes early (BrokenPipeError).

Every probe must fail fast: the outputs and inputs are checked before any work.
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

from moments_ref.cli import main

_CAMERA = "[camera]\neye = [0, 2, 5]\ntarget = [0, 0, 0]\nresolution = [64, 48]\n"
_LIGHT = "[light]\ntype = \"directional\"\ndirection = [0.2, -1.0, 0.3]\n"
_OCC = "[[objects]]\nname = \"box\"\ngenerator = \"box\"\nrole = \"occluder\"\n"
_REC = "[[objects]]\nname = \"ground\"\ngenerator = \"plane\"\nparams = { width = 4, depth = 4 }\nrole = \"receiver\"\n"


def _scene(text, name="s.toml"):
    def setup(tmp):
        (tmp / name).write_text(text)
    return setup


def _files(**files):
    def setup(tmp):
        for name, data in files.items():
            name = name.replace("_DOT_", ".")
            (tmp / name).write_bytes(data if isinstance(data, bytes) else data.encode())
    return setup


def _existing_file(tmp):
    (tmp / "file").write_text("not a folder")


_OBJ_W0 = _files(s_DOT_toml=_LIGHT + _CAMERA + _REC + "[[objects]]\nname = \"m\"\nobj = \"m.obj\"\nrole = \"occluder\"\n",
                 m_DOT_obj="v 0 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
_AWAY = "[camera]\neye = [0, 2, 5]\ntarget = [0, 2, 20]\nresolution = [64, 48]\n"
_BIG_CAM = "[camera]\neye = [0, 2, 5]\ntarget = [0, 0, 0]\nresolution = [20000, 20000]\n"
_BIG_PLANE = "[[objects]]\nname = \"ground\"\ngenerator = \"plane\"\nparams = { nx = 100000, nz = 100000 }\nrole = \"receiver\"\n"
_BIG_KNOT = "[[objects]]\nname = \"knot\"\ngenerator = \"torus_knot\"\nparams = { segments = 1000000, sides = 10000 }\nrole = \"occluder\"\n"
_BIG_RAIL = "[[objects]]\nname = \"r\"\ngenerator = \"railing\"\nparams = { bars = 1000000000 }\nrole = \"occluder\"\n"

#: (id, argv, setup). "report" probes use a scene file of the test so that a
#: probe which wrongly starts work stays short.
PROBES = [
    # --out that cannot be a folder: under /dev/null, or an existing file
    *[(f"{cmd}-out-devnull", [cmd, "--out", "/dev/null/x", *extra], setup)
      for cmd, extra, setup in [
          ("golden", ["--case", "shade-float32"], None),
          ("report", ["--scene", "{tmp}/s.toml"], _scene(_LIGHT + _CAMERA + _OCC + _REC)),
          ("figure3", [], None), ("figure4", ["--size", "16"], None), ("stability", [], None),
          ("banks", [], None), ("bench", ["--quick", "--only", "copy"], None), ("vwss", ["--quick"], None),
          ("conformance", ["--all"], None)]],
    *[(f"{cmd}-out-file", [cmd, "--out", "{tmp}/file", *extra], _existing_file)
      for cmd, extra in [("golden", ["--case", "shade-float32"]), ("report", ["--scene", "railing"]),
                         ("figure3", []), ("figure4", ["--size", "16"]), ("stability", []), ("banks", []),
                         ("bench", ["--quick", "--only", "copy"]), ("vwss", ["--quick"])]],
    ("golden-out-below-file", ["golden", "--out", "{tmp}/file/sub", "--case", "shade-float32"], _existing_file),
    # numbers out of range
    ("bench-size-negative", ["bench", "--size", "-1", "--only", "copy"], None),
    ("bench-size-zero", ["bench", "--size", "0", "--only", "copy"], None),
    ("bench-size-huge", ["bench", "--size", "1000000", "--only", "copy"], None),
    ("figure4-size-negative", ["figure4", "--out", "{tmp}/o", "--size", "-1"], None),
    ("figure4-samples-3", ["figure4", "--out", "{tmp}/o", "--size", "16", "--samples", "3"], None),
    ("figure4-size-huge", ["figure4", "--out", "{tmp}/o", "--size", "16384", "--samples", "8"], None),
    ("vwss-views-zero", ["vwss", "--out", "{tmp}/o", "--views", "0", "--quick"], None),
    ("max-memory-garbage", ["banks", "--max-memory", "lots"], None),
    ("max-memory-negative", ["banks", "--max-memory", "-1G"], None),
    ("verify-worst-negative", ["verify", "--golden", "{tmp}", "--results", "{tmp}/r.npz", "--worst", "-1"], None),
    # scene files
    ("scene-not-utf8", ["report", "--out", "{tmp}/o", "--scene", "{tmp}/s.toml"],
     _files(s_DOT_toml=b"name = \"\xff\xfe\"\n")),
    ("scene-not-toml", ["report", "--out", "{tmp}/o", "--scene", "{tmp}/s.toml"], _scene("[[[\n")),
    ("scene-missing", ["report", "--out", "{tmp}/o", "--scene", "{tmp}/none.toml"], None),
    ("scene-is-folder", ["figure4", "--out", "{tmp}/o", "--scene", "{tmp}", "--size", "16"], None),
    ("scene-is-devnull", ["figure4", "--out", "{tmp}/o", "--scene", "/dev/null", "--size", "16"], None),
    ("scene-obj-w0", ["report", "--out", "{tmp}/o", "--scene", "{tmp}/s.toml"], _OBJ_W0),
    ("scene-obj-not-utf8", ["figure4", "--out", "{tmp}/o", "--scene", "{tmp}/s.toml", "--size", "16"],
     _files(s_DOT_toml=_LIGHT + _CAMERA + _REC + "[[objects]]\nname = \"m\"\nobj = \"m.obj\"\nrole = \"occluder\"\n",
            m_DOT_obj=b"v 0 0 0\xff\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")),
    ("scene-obj-nan", ["figure4", "--out", "{tmp}/o", "--scene", "{tmp}/s.toml", "--size", "16"],
     _files(s_DOT_toml=_LIGHT + _CAMERA + _REC + "[[objects]]\nname = \"m\"\nobj = \"m.obj\"\nrole = \"occluder\"\n",
            m_DOT_obj="v nan 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")),
    ("scene-camera-sees-no-receiver", ["report", "--out", "{tmp}/o", "--scene", "{tmp}/s.toml"],
     _scene(_LIGHT + _AWAY + _OCC + _REC)),
    ("scene-camera-20000", ["report", "--out", "{tmp}/o", "--scene", "{tmp}/s.toml", "--full"],
     _scene(_LIGHT + _BIG_CAM + _OCC + _REC)),
    ("scene-plane-1e5", ["report", "--out", "{tmp}/o", "--scene", "{tmp}/s.toml"],
     _scene(_LIGHT + _CAMERA + _OCC + _BIG_PLANE)),
    ("scene-torus-knot-huge", ["report", "--out", "{tmp}/o", "--scene", "{tmp}/s.toml"],
     _scene(_LIGHT + _CAMERA + _BIG_KNOT + _REC)),
    ("scene-railing-huge", ["figure4", "--out", "{tmp}/o", "--scene", "{tmp}/s.toml", "--size", "16"],
     _scene(_LIGHT + _CAMERA + _BIG_RAIL + _REC)),
    ("scene-huge-within-raised-limit-still-refused",
     ["report", "--out", "{tmp}/o", "--scene", "{tmp}/s.toml", "--max-memory", "8G"],
     _scene(_LIGHT + _CAMERA + _OCC + _BIG_PLANE)),
    ("scene-shadow-map-huge", ["figure4", "--out", "{tmp}/o", "--scene", "{tmp}/s.toml", "--size", "16"],
     _scene("shadow_map_size = 16384\nmsaa = 8\n" + _LIGHT + _CAMERA + _OCC + _REC)),
    ("scene-wrong-types", ["report", "--out", "{tmp}/o", "--scene", "{tmp}/s.toml"],
     _scene(_LIGHT + "[camera]\neye = [0, 2, 5]\ntarget = [0, 0, 0]\nresolution = \"big\"\n" + _OCC + _REC)),
    ("scene-camera-fov-0", ["report", "--out", "{tmp}/o", "--scene", "{tmp}/s.toml"],
     _scene(_LIGHT + _CAMERA + "fov = 0\n" + _OCC + _REC)),
    ("scene-obj-face-out-of-range", ["figure4", "--out", "{tmp}/o", "--scene", "{tmp}/s.toml", "--size", "16"],
     _files(s_DOT_toml=_LIGHT + _CAMERA + _REC + "[[objects]]\nname = \"m\"\nobj = \"m.obj\"\nrole = \"occluder\"\n",
            m_DOT_obj="v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n")),
    ("scene-obj-is-devzero", ["figure4", "--out", "{tmp}/o", "--scene", "{tmp}/s.toml", "--size", "16"],
     _scene(_LIGHT + _CAMERA + _REC + "[[objects]]\nname = \"m\"\nobj = \"/dev/zero\"\nrole = \"occluder\"\n")),
    ("scene-is-fifo", ["figure4", "--out", "{tmp}/o", "--scene", "{tmp}/fifo.toml", "--size", "16"],
     lambda tmp: os.mkfifo(tmp / "fifo.toml")),
    ("scene-unknown-name", ["vwss", "--out", "{tmp}/o", "--scene", "no-such-scene", "--quick"], None),
    ("golden-unknown-case", ["golden", "--out", "{tmp}/o", "--case", "no-such-case"], None),
    ("conformance-unknown-case", ["conformance", "--glsl", "msm.glsl", "--function", "f", "--case", "nope"], None),
    ("bench-only-matches-nothing", ["bench", "--only", "no-such-benchmark", "--quick"], None),
    ("out-under-proc", ["report", "--out", "/proc/no-such/x", "--scene", "railing"], None),
    ("out-under-sys", ["stability", "--out", "/sys/x"], None),
    ("max-memory-zero", ["figure3", "--out", "{tmp}/o", "--max-memory", "0"], None),
    ("max-memory-below-need", ["figure4", "--out", "{tmp}/o", "--size", "16", "--max-memory", "1K"], None),
    # verify inputs (missing or special files)
    ("verify-golden-missing", ["verify", "--golden", "{tmp}/none", "--results", "{tmp}/r.npz"], None),
    ("verify-golden-is-file", ["verify", "--golden", "{tmp}/file", "--results", "{tmp}/file"], _existing_file),
    ("verify-manifest-not-json", ["verify", "--golden", "{tmp}", "--results", "{tmp}/r.npz"],
     _files(manifest_DOT_json="{not json")),
    ("verify-manifest-no-cases", ["verify", "--golden", "{tmp}", "--results", "{tmp}/r.npz"],
     _files(manifest_DOT_json="{}")),
    ("conformance-glsl-missing", ["conformance", "--glsl", "{tmp}/none.glsl", "--function", "f",
                                  "--case", "shade-float32"], None),
]

#: Probes of ``verify``'s manifest parsing; fixed together with the strict verifier.


def run_probe(argv, capsys):
    """Run ``main(argv)`` in-process: (exit code, stderr, traceback text or None, seconds)."""
    import traceback

    t0 = time.perf_counter()
    try:
        code = main(argv)
        tb = None
    except SystemExit as exc:
        code, tb = exc.code, None
    except BaseException:  # noqa: BLE001 - the probe's point is to see what escapes
        code, tb = None, traceback.format_exc()
    err = capsys.readouterr().err
    return code, err, tb, time.perf_counter() - t0


@pytest.mark.parametrize("probe_id, argv, setup", [
    pytest.param(*p, id=p[0]) for p in PROBES])
def test_probe_exits_2_with_one_line(probe_id, argv, setup, tmp_path, capsys, monkeypatch):
    if setup:
        setup(tmp_path)
    argv = [a.replace("{tmp}", str(tmp_path)) for a in argv]
    monkeypatch.chdir(tmp_path)
    code, err, tb, seconds = run_probe(argv, capsys)
    assert tb is None, f"{probe_id}: traceback\n{tb}"
    assert code == 2, f"{probe_id}: exit {code}, stderr {err!r}"
    lines = err.strip("\n").split("\n")
    assert len(lines) == 1 and lines[0], f"{probe_id}: stderr {err!r}"
    assert "Traceback" not in err
    assert seconds < 20, f"{probe_id}: refused only after {seconds:.0f} s"


def test_report_refuses_bad_out_before_work(tmp_path, capsys):
    """The unwritable --out is refused before any scene is rendered (was: after 32 s)."""
    t0 = time.perf_counter()
    code = main(["report", "--out", "/dev/null/x", "--scene", "railing", "--full"])
    assert code == 2 and time.perf_counter() - t0 < 5
    assert "/dev/null/x" in capsys.readouterr().err


def _run_cli(args, **kw):
    env = dict(os.environ, PYTHONPATH=str(Path(__file__).resolve().parents[1]))
    return subprocess.run([sys.executable, "-m", "moments_ref", *args], env=env, **kw)


def test_broken_pipe_is_one_line_exit_2():
    """Output piped into a reader that closes at once (``| head -c0``): exit 2, one line."""
    env = dict(os.environ, PYTHONPATH=str(Path(__file__).resolve().parents[1]))
    p = subprocess.Popen([sys.executable, "-m", "moments_ref", "banks"], env=env,
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    p.stdout.close()  # the reader goes away before the first write
    err = p.stderr.read().decode()
    code = p.wait(timeout=120)
    assert code == 2, (code, err)
    assert err.count("\n") == 1 and "Traceback" not in err and "Exception ignored" not in err, err


def test_bad_out_in_a_real_process_is_one_line(tmp_path):
    r = _run_cli(["golden", "--out", "/dev/null/x", "--case", "shade-float32"], capture_output=True, text=True)
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "Traceback" not in r.stderr, r.stderr
