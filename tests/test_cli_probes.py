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

The second table (further down) runs each probe as a real process under a memory
limit and also judges its peak memory and what it left on disk: hostile scene
files (names as paths, ``[params]``, TOML nesting and number sizes), cameras that
shade no receiver pixel, hostile golden folders through ``verify`` and
``conformance --golden``, results files (zip bombs, integer codes of another
width), OBJ files against ``--max-memory``, the API under huge numbers; then the
signals (no orphan worker, no temporary file), a write phase that fails (the
folder marked ``INCOMPLETE``) and warnings that never precede a refusal.
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


def _meta(**meta):
    import json

    return list(json.dumps(meta).encode())


def _record_bomb(tmp):
    """A record whose one output array inflates to 80 MB from a few hundred kB."""
    import numpy as np

    np.savez_compressed(tmp / "r.npz", meta=np.array(_meta(version=1), np.uint8),
                        **{"f|glsl|gl|c|y": np.zeros(20 << 20, np.float32)})


def _npz(tmp, cut=None, **arrays):
    """``tmp/r.npz`` holding ``arrays`` (uint8 lists, or objects, which need a pickle); ``cut`` bytes off its end."""
    import io

    import numpy as np

    buf = io.BytesIO()
    np.savez(buf, **{k: np.array(v, np.uint8 if isinstance(v[0], int) else object) for k, v in arrays.items()})
    data = buf.getvalue()
    (tmp / "r.npz").write_bytes(data[:-cut] if cut else data)


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
    # conformance --all --record / --gpu-record (a record of another machine's run)
    ("conformance-record-without-all", ["conformance", "--glsl", "msm.glsl", "--function", "f", "--case",
                                        "shade-float32", "--record", "{tmp}/r.npz"], None),
    ("conformance-gpu-record-with-kernel", ["conformance", "--kernel", "--glsl", "hpg17_filter_nlq64.glsl", "--entry",
                                            "main", "--case", "kernel-filter-nlq64", "--gpu-record", "{tmp}/r.npz"],
     None),
    ("conformance-record-is-folder", ["conformance", "--all", "--record", "{tmp}"], None),
    ("conformance-record-folder-missing", ["conformance", "--all", "--record", "{tmp}/none/r.npz"], None),
    *[(f"conformance-gpu-record-{kind}", ["conformance", "--all", "--gpu-record", "{tmp}/r.npz"], setup)
      for kind, setup in [("missing", None), ("text", _files(r_DOT_npz="not a zip")),
                          ("no-meta", lambda tmp: _npz(tmp, **{"k|glsl|gl|c": [1, 2]})),
                          ("foreign-array", lambda tmp: _npz(tmp, meta=_meta(version=1), x=[1, 2])),
                          ("zip-bomb", _record_bomb),
                          ("other-version", lambda tmp: _npz(tmp, meta=_meta(version=99))),
                          ("meta-not-json", lambda tmp: _npz(tmp, meta=list(b"{oops"))),
                          ("meta-incomplete", lambda tmp: _npz(tmp, meta=_meta(version=1))),
                          ("truncated", lambda tmp: _npz(tmp, meta=_meta(version=1), cut=40)),
                          ("pickled", lambda tmp: _npz(tmp, meta=_meta(version=1), **{"f|glsl|gl|c|y": [{"a": 1}]}))]],
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


# ===========================================================================
# Real processes: hostile files, interrupted runs, bounded memory
#
# Each probe below runs the ``moments-ref`` command (or a short Python program) as
# its own process under an address-space limit and is judged by its exit code,
# its stderr (one line for a refusal, never a traceback or a warning before it),
# its peak resident memory, and what it left on disk. The process sets its
# limits itself (``resource.setrlimit``) and reports its peak from
# ``/proc/self/status`` (VmHWM) when it exits: the kernel's ``ru_maxrss`` of a
# child counts the pages of the test process it was forked from, which would
# hide a bomb behind the test's own memory. The table's probes are forked from a
# small server process that has imported NumPy and the package once (``Forks``):
# each is still a process of its own, with its own limits, session, exit code,
# files for stdout and stderr and peak memory (which starts at the server's ~40 MB,
# as a fresh interpreter's does once NumPy is imported), without paying for an
# interpreter and NumPy a hundred times. Classes (``Probe.cls``): ``scene``
# (scene files as data), ``camera`` (no shaded receiver pixel), ``golden``
# (hostile golden folders through verify), ``conformance`` (the same through
# conformance --golden), ``results`` (results files), ``obj``, ``api``,
# ``out``, ``corpus``; the signal and partial-write probes are tests of their own
# further down.
# ===========================================================================

import dataclasses  # noqa: E402
import hashlib  # noqa: E402
import io  # noqa: E402
import json  # noqa: E402
import shutil  # noqa: E402
import signal  # noqa: E402
import threading  # noqa: E402
import zipfile  # noqa: E402
from concurrent.futures import ThreadPoolExecutor  # noqa: E402

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
#: Address space of a probe process: far above what a refusal needs, far below a bomb.
AS_LIMIT = 2 << 30
#: Peak resident memory a refusal may reach (the interpreter, NumPy, SciPy and matplotlib take ~150 MB).
RSS_REFUSAL = 400 << 20


@dataclasses.dataclass
class Probe:
    """One hostile input: ``argv`` of ``moments-ref`` (``{tmp}`` is the probe's folder) or ``code`` for ``python -c``."""

    id: str
    cls: str
    argv: list = None
    setup: object = None  # setup(tmp) writes the files
    code: int = 2  # the exit code expected
    rss: int = RSS_REFUSAL  # peak resident memory allowed
    check: object = None  # check(tmp, result): more assertions
    python: str = None  # a Python program instead of argv
    limit: int = AS_LIMIT


@dataclasses.dataclass
class Run:
    code: int
    out: str
    err: str
    rss: int  # peak resident bytes
    seconds: float


#: The program a probe process runs: limits first, its peak memory reported at exit, then the command.
_LAUNCHER = """\
import atexit, os, resource, signal, sys
limit, fsize, peak = {limit}, {fsize}, {peak!r}
resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
if fsize is not None:
    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # a write past the limit fails with EFBIG, as on a full disk
    resource.setrlimit(resource.RLIMIT_FSIZE, (fsize, fsize))

def report_peak():
    with open("/proc/self/status") as f:
        kib = next(line.split()[1] for line in f if line.startswith("VmHWM"))
    with open(peak, "w") as f:
        f.write(kib)

atexit.register(report_peak)
"""


def _program(cwd, argv=None, code=None, limit=AS_LIMIT, fsize=None):
    """The Python program of a probe process: limits, its peak reported at exit, then the command."""
    body = (f"sys.argv = ['moments-ref', *{list(argv)!r}]\nimport runpy\n"
            "runpy.run_module('moments_ref', run_name='__main__', alter_sys=True)\n") if code is None else code
    return _LAUNCHER.format(limit=limit, fsize=fsize, peak=str(Path(cwd) / ".peak")) + body


def spawn(cwd, argv=None, code=None, limit=AS_LIMIT, fsize=None, root=ROOT):
    """Start ``moments-ref ARGV`` (or the Python ``code``) in ``cwd`` with the package of ``root`` and the limits."""
    program = _program(cwd, argv, code, limit, fsize)
    env = dict(os.environ, PYTHONPATH=str(root), MPLBACKEND="Agg")
    (Path(cwd) / ".peak").unlink(missing_ok=True)
    return subprocess.Popen([sys.executable, "-c", program], cwd=cwd, env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, start_new_session=True)


def finish(p, cwd, timeout=300):
    """Wait for ``p``; its :class:`Run` with the peak resident memory it reported (0 if it could not)."""
    t0 = time.perf_counter()
    outs = {}
    readers = [threading.Thread(target=lambda k, f: outs.__setitem__(k, f.read().decode(errors="replace")),
                                args=(k, f)) for k, f in (("out", p.stdout), ("err", p.stderr))]
    for r in readers:
        r.start()
    try:
        p.wait(timeout)
    except subprocess.TimeoutExpired:
        p.kill()
        p.wait()
    for r in readers:
        r.join(10)  # an orphaned child holding the pipes must not hang the test
    outs = {"out": outs.get("out", ""), "err": outs.get("err", "")}
    peak = Path(cwd) / ".peak"
    rss = int(peak.read_text()) * 1024 if peak.exists() else 0
    peak.unlink(missing_ok=True)
    return Run(p.returncode, outs["out"], outs["err"], rss, time.perf_counter() - t0)


#: A fork server: imports NumPy and the package once, then per request (a JSON line
#: ``{cwd, program}``) forks a child that becomes a probe process of its own (new
#: session, stdin from /dev/null, stdout and stderr to files in ``cwd``) and runs the
#: program at the top level, so that its ``SystemExit`` ends it as it ends a fresh
#: interpreter (atexit handlers, flushed streams, the exit code). The server answers
#: the child's pid, then its exit code (negative: the signal that ended it).
_SERVER = """\
import json, os, sys
import numpy, moments_ref, moments_ref.cli
for line in sys.stdin:
    req = json.loads(line)
    pid = os.fork()
    if pid == 0:
        break
    print(json.dumps({"pid": pid}), flush=True)
    print(json.dumps({"code": os.waitstatus_to_exitcode(os.waitpid(pid, 0)[1])}), flush=True)
else:
    sys.exit(0)
os.setsid()
os.chdir(req["cwd"])
for fd, name, flags in ((0, os.devnull, os.O_RDONLY), (1, ".out", os.O_WRONLY | os.O_CREAT | os.O_TRUNC),
                        (2, ".err", os.O_WRONLY | os.O_CREAT | os.O_TRUNC)):
    f = os.open(name, flags, 0o600)
    os.dup2(f, fd)
    os.close(f)
program = req["program"]
del line, req, pid, fd, name, flags, f
exec(compile(program, "<probe>", "exec"))
"""


class Forks:
    """One fork server per thread of the probe pool (each runs one probe at a time)."""

    def __init__(self, root=ROOT):
        self._env = dict(os.environ, PYTHONPATH=str(root), MPLBACKEND="Agg")
        self._local = threading.local()
        self._all = []

    def _server(self):
        srv = getattr(self._local, "server", None)
        if srv is None or srv.poll() is not None:
            srv = subprocess.Popen([sys.executable, "-c", _SERVER], env=self._env, stdin=subprocess.PIPE,
                                   stdout=subprocess.PIPE, text=True)
            self._local.server = srv
            self._all.append(srv)
        return srv

    def run(self, cwd, program, timeout=300):
        """Run ``program`` in a child of the server with ``cwd`` as its folder; its :class:`Run`."""
        srv = self._server()
        t0 = time.perf_counter()
        for name in (".peak", ".out", ".err"):
            (Path(cwd) / name).unlink(missing_ok=True)
        srv.stdin.write(json.dumps({"cwd": str(cwd), "program": program}) + "\n")
        srv.stdin.flush()
        pid = json.loads(srv.stdout.readline())["pid"]
        timer = threading.Timer(timeout, lambda: os.killpg(pid, signal.SIGKILL))
        timer.start()
        try:
            code = json.loads(srv.stdout.readline())["code"]
        finally:
            timer.cancel()
        files = {n: Path(cwd) / n for n in (".out", ".err", ".peak")}
        out, err = (files[n].read_text(errors="replace") for n in (".out", ".err"))
        rss = int(files[".peak"].read_text()) * 1024 if files[".peak"].exists() else 0
        for f in files.values():
            f.unlink(missing_ok=True)
        return Run(code, out, err, rss, time.perf_counter() - t0)

    def close(self):
        for srv in self._all:
            srv.stdin.close()
            srv.wait(60)


def run_real(probe, tmp, forks):
    """Set the probe up in ``tmp`` and run it as its own process (forked by ``forks``); its :class:`Run`."""
    if probe.setup:
        probe.setup(tmp)
    if probe.python is not None:
        program = _program(tmp, code=probe.python.replace("{tmp}", str(tmp)), limit=probe.limit)
    else:
        program = _program(tmp, [a.replace("{tmp}", str(tmp)) for a in probe.argv], limit=probe.limit)
    return forks.run(tmp, program)


def verdict(probe, run):
    """What is wrong with ``run`` (a list of problems; empty when the probe ended clean)."""
    bad = []
    if "Traceback" in run.err:
        bad.append("traceback: " + run.err.strip().splitlines()[-1][:200])
    if run.code != probe.code:
        bad.append(f"exit {run.code}, expected {probe.code}: {run.err.strip()[-200:]!r}")
    if probe.code == 2 and (run.err.count("\n") != 1 or not run.err.startswith("moments-ref")) and probe.python is None:
        bad.append(f"stderr is not one line: {run.err[-300:]!r}")
    if run.rss == 0:
        bad.append("no peak memory reported (the process did not exit normally)")
    if run.rss > probe.rss:
        bad.append(f"peak memory {run.rss >> 20} MiB, allowed {probe.rss >> 20} MiB")
    return bad


# --- scene files -----------------------------------------------------------

_SMALL = _LIGHT + _CAMERA + _OCC + _REC


def _with(text, **files):
    def setup(tmp):
        for name, data in {"s.toml": text, **files}.items():
            p = tmp / name
            p.parent.mkdir(parents=True, exist_ok=True)
            p.write_bytes(data if isinstance(data, bytes) else data.encode())
    return setup


def _nothing_outside(expected_dir):
    """A check: the probe wrote no file under ``{tmp}`` outside ``expected_dir`` (relative)."""
    def check(tmp, run):
        scene_files = {".toml", ".obj"}
        stray = [p for p in tmp.rglob("*") if p.is_file() and p.suffix not in scene_files
                 and expected_dir not in p.relative_to(tmp).parts[:1]]
        assert not stray, f"written outside --out: {stray}"
    return check


def _camera(eye, target, fov=45):
    return f"[camera]\neye = {eye}\ntarget = {target}\nresolution = [64, 48]\nfov = {fov}\n"


_FLAT_OBJ = "v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n"  # three collinear points: a receiver of zero area
_REPORT = ["report", "--scene", "{tmp}/s.toml", "--out", "{tmp}/o", "--no-progress", "--repeats", "1"]
_CAMERAS = {
    "fov-179.999": _LIGHT + _camera("[0, 2, 5]", "[0, 0, 0]", 179.999) + _OCC + _REC,
    "fov-1e-9-at-the-occluder": _LIGHT + _camera("[0, 2, 5]", "[0, 0.5, 0]", 1e-9) + _OCC + _REC,
    "eye-inside-the-occluder": _LIGHT + _camera("[0, 0.5, 0]", "[0, 0.5, 1]") + _OCC + _REC,
    "eye-on-the-floor-plane": _LIGHT + _camera("[0, 0, 5]", "[0, 0, 0]") + _OCC + _REC,
    "zero-area-receiver": _LIGHT + _camera("[0, 2, 5]", "[0, 0, 0]") + _OCC
    + "[[objects]]\nname = \"flat\"\nobj = \"flat.obj\"\nrole = \"receiver\"\n",
}


def _name(name):
    return _with(f"name = {json.dumps(name)}\n" + _SMALL)


SCENE_PROBES = [
    Probe("name-path-traversal", "scene", ["report", "--scene", "{tmp}/s.toml", "--out", "{tmp}/a/b/o"],
          _name("x/../../../escaped"), check=_nothing_outside("a")),
    Probe("name-backslash", "scene", _REPORT, _name("a\\b")),
    Probe("name-dotdot", "scene", _REPORT, _name("..")),
    Probe("name-nul", "scene", _REPORT, _name("a\0b")),
    Probe("name-escape-sequence", "scene", _REPORT, _name("\x1b[31mred")),
    Probe("name-300-characters", "scene", _REPORT, _name("x" * 300)),
    Probe("file-stem-with-newline", "scene", ["report", "--scene", "{tmp}/a\nb.toml", "--out", "{tmp}/o"],
          lambda tmp: (tmp / "a\nb.toml").write_text(_SMALL)),
    Probe("two-scenes-one-name", "scene", [*_REPORT, "--scene", "{tmp}/t.toml"],
          _with(_SMALL, **{"t.toml": "name = \"s\"\n" + _SMALL.replace("-1.0, 0.3", "-1.0, -0.3")})),
    Probe("same-scene-twice", "scene", [*_REPORT, "--scene", "{tmp}/s.toml"], _with(_SMALL)),
    Probe("params-light-samples-many", "scene", _REPORT, _with("[params]\nlight_samples = \"many\"\n" + _SMALL)),
    Probe("params-raymarch-samples-x", "scene", _REPORT, _with("[params]\nraymarch_samples = \"x\"\n" + _SMALL)),
    Probe("params-light-near-negative", "scene", _REPORT, _with("[params]\nlight_near = -1\n" + _SMALL)),
    Probe("params-unknown-key", "scene", _REPORT, _with("[params]\nlight_smaples = 24\n" + _SMALL)),
    Probe("medium-fog", "scene", _REPORT, _with("[params]\nmedium = \"fog\"\n" + _SMALL)),
    Probe("toml-arrays-50000-deep", "scene", _REPORT, _with("x = " + "[" * 50000 + "]" * 50000 + "\n" + _SMALL)),
    Probe("toml-dotted-table-5000-deep", "scene", _REPORT,
          _with(_SMALL + "[params." + ".".join(["a"] * 5000) + "]\nb = 1\n")),
    Probe("toml-fov-30-digits", "scene", _REPORT, _with(_SMALL.replace("resolution", "fov = " + "9" * 30 + "\nresolution"))),
    Probe("toml-eye-400-digits", "scene", _REPORT, _with(_SMALL.replace("eye = [0, 2, 5]", f"eye = [1{'0' * 400}, 2, 5]"))),
    Probe("toml-integer-5000-digits", "scene", _REPORT, _with("x = 1" + "0" * 5000 + "\n" + _SMALL)),
    Probe("toml-direction-1e300", "scene", _REPORT, _with(_SMALL.replace("[0.2, -1.0, 0.3]", "[1e300, -1.0, 0.3]"))),
    Probe("toml-eye-1e300", "scene", _REPORT, _with(_SMALL.replace("eye = [0, 2, 5]", "eye = [1e300, 2, 5]"))),
    Probe("toml-translate-nan", "scene", _REPORT,
          _with(_SMALL.replace("role = \"occluder\"", "role = \"occluder\"\ntransform = [{ translate = [nan, 0, 0] }]"))),
    Probe("toml-generator-is-a-list", "scene", _REPORT, _with(_SMALL.replace("generator = \"box\"", "generator = [1]"))),
    # Every camera with one job; two of them with two, whose refusal must also stop the workers that
    # started while the scenes were planned (the camera check itself runs in the parent either way).
    *[Probe(f"camera-{name}-jobs{jobs}", "camera", [*_REPORT, "--jobs", str(jobs)],
            _with(text, **{"flat.obj": _FLAT_OBJ})) for name, text in _CAMERAS.items()
      for jobs in ((1, 2) if name in ("fov-179.999", "zero-area-receiver") else (1,))],
    Probe("out-empty", "out", ["golden", "--out", "", "--case", "shade-float32"],
          check=lambda tmp, run: not list(tmp.iterdir()) or pytest.fail(f"wrote {list(tmp.iterdir())}")),
    Probe("corpus-txt", "corpus", ["mutants", "--corpus", "{tmp}/c.txt"], lambda tmp: (tmp / "c.txt").write_text("x")),
    Probe("corpus-syntax-error", "corpus", ["mutants", "--corpus", "{tmp}/c.py"],
          lambda tmp: (tmp / "c.py").write_text("def (")),
]

# --- the API under huge numbers -----------------------------------------------------

_API = ("import numpy as np, moments_ref as mr\nfrom moments_ref import InputError, precise, msm6\n"
        "try:\n    {call}\n    print('no error')\nexcept InputError:\n    print('InputError')\n")
API_PROBES = [Probe(f"api-{name}", "api", python=_API.format(call=call), code=0, rss=RSS_REFUSAL,
                    check=lambda tmp, run: run.out.strip() == "InputError" or pytest.fail(run.out + run.err))
              for name, call in [
                  ("broadcast-bomb-shadow-intensity",
                   "mr.shadow_intensity(np.tile([0, .5, 0, .5], (100000, 1, 1)), np.zeros((1, 100000)))"),
                  ("broadcast-bomb-shade", "mr.shade(np.tile([.1, .5, .5, .2], (100000, 1, 1)), np.zeros((1, 100000)))"),
                  ("broadcast-bomb-msm6", "msm6.shadow_intensity(np.tile([0, .5, 0, .5, 0, .4], (100000, 1, 1)), "
                                          "np.zeros((1, 100000)))"),
                  ("broadcast-bomb-solve-cubic", "msm6.solve_cubic(np.ones((100000, 1)), np.ones((1, 100000)), 1., 1.)"),
                  ("reduce-light-leaking-10**400", "mr.reduce_light_leaking(np.zeros(3), 10**400)"),
                  ("power-moments-axis-10**400", "mr.power_moments(np.zeros(3), axis=10**400)"),
                  ("precise-axis-10**400", "precise.power_moments(np.zeros(3), axis=10**400)"),
                  ("precise-dps-10**400", "precise.shadow_intensity([0, .5, 0, .5], 0.1, dps=10**400)"),
                  ("precise-dps-10**20", "precise.phi([0.1, .5, 0.05, .4], dps=10**20)"),
                  ("msm6-measure-n-10**400", "msm6.measure_unorm10_bias(n=10**400)"),
                  ("singular-thresholds-10**400", "mr.msm.singular_thresholds(10**400)"),
                  ("oracle-n-hypothesis-10**400",
                   "from moments_ref import oracle; oracle.check(mr.shadow_intensity, 'shadow_intensity-lower', "
                   "n_hypothesis=10**400)"),
              ]]


# --- golden folders, results and conformance ----------------------------------------

CASE, CODES = "shadow_intensity-lower-float32", "pack32-float32"


@pytest.fixture(scope="module")
def golden_dir(tmp_path_factory):
    from moments_ref import golden

    d = tmp_path_factory.mktemp("golden_clean")
    golden.write(d, [CASE, CODES])
    return d


def _manifest(g, fn):
    m = json.loads((g / "manifest.json").read_text())
    fn(m)
    (g / "manifest.json").write_text(json.dumps(m))


def _set(key, value, case=CASE):
    return lambda g: _manifest(g, lambda m: m["cases"][case].__setitem__(key, value))


def _rewrite(fn, case=CASE, compressed=False):
    """Replace a case file by ``fn(arrays)`` (a dict) and fix its sha256 in the manifest."""
    def setup(g):
        with np.load(g / f"{case}.npz") as z:
            arrays = fn({k: z[k] for k in z.files})
        buf = io.BytesIO()
        (np.savez_compressed if compressed else np.savez)(buf, **arrays)
        _raw(buf.getvalue(), case)(g)
    return setup


def _raw(data, case=CASE):
    """A case file of bytes ``data``, its sha256 fixed up."""
    def setup(g):
        (g / f"{case}.npz").write_bytes(data)
        _set("sha256", hashlib.sha256(data).hexdigest(), case)(g)
    return setup


def _bomb(path_or_buf, key, nbytes, extra=None):
    """An .npz whose member ``key`` declares ``nbytes`` of zeros, deflated on the fly (about 1 KB per MB)."""
    header = io.BytesIO()
    np.lib.format.write_array_header_1_0(header, {"descr": "|u1", "fortran_order": False, "shape": (nbytes,)})
    with zipfile.ZipFile(path_or_buf, "w", compression=zipfile.ZIP_DEFLATED) as zf:
        for k, v in (extra or {}).items():
            b = io.BytesIO()
            np.save(b, v)
            zf.writestr(f"{k}.npy", b.getvalue())
        info = zipfile.ZipInfo(f"{key}.npy")
        info.compress_type = zipfile.ZIP_DEFLATED
        with zf.open(info, "w", force_zip64=True) as f:
            f.write(header.getvalue())
            zero = bytes(1 << 20)
            for _ in range(nbytes >> 20):
                f.write(zero)


_BOMBS = {}


def _golden_bomb(nbytes, count=None):
    """The case file with an extra member ``junk`` of ``nbytes`` zeros (made once per size and folder)."""
    def setup(g):
        key = (nbytes, (g / f"{CASE}.npz").read_bytes())
        if key not in _BOMBS:
            with np.load(g / f"{CASE}.npz") as z:
                arrays = {k: z[k] for k in z.files}
            buf = io.BytesIO()
            _bomb(buf, "junk", nbytes, extra=arrays)
            _BOMBS[key] = buf.getvalue()
        _raw(_BOMBS[key])(g)
        if count is not None:
            _set("count", count)(g)
    return setup


def _nested(g):
    text = (g / "manifest.json").read_text()
    (g / "manifest.json").write_text(text[:-2] + ', "deep": ' + "[" * 100000 + "]" * 100000 + "}\n")


def _pickled(g):
    buf = io.BytesIO()
    np.save(buf, np.array([{"a": 1}], dtype=object), allow_pickle=True)
    _raw(buf.getvalue())(g)


def _bzip2(g):
    with np.load(g / f"{CASE}.npz") as z:
        arrays = {k: z[k] for k in z.files}
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", compression=zipfile.ZIP_BZIP2) as zf:
        for k, v in arrays.items():
            b = io.BytesIO()
            np.save(b, v)
            zf.writestr(f"{k}.npy", b.getvalue())
    _raw(buf.getvalue())(g)


#: (id, edit of the golden folder): each must be refused by verify and by conformance --golden.
GOLDEN_EDITS = [
    ("count-abc", _set("count", "abc")),
    ("count-10**30", _set("count", 10**30)),
    ("count-bool", _set("count", True)),
    ("shape-1e30", lambda g: _manifest(g, lambda m: m["cases"][CASE]["outputs"]["intensity"].__setitem__("shape", [1e30]))),
    ("value-range-x", _set("value_range", "x")),
    ("value-range-nan", lambda g: (g / "manifest.json").write_text(
        (g / "manifest.json").read_text().replace('"value_range": [', '"value_range": [NaN, '))),
    ("metric-unknown", _set("metric", "rel")),
    ("schema-999", lambda g: _manifest(g, lambda m: m.__setitem__("schema_version", 999))),
    ("manifest-100000-deep", _nested),
    ("manifest-malformed", lambda g: (g / "manifest.json").write_text("{\"cases\": ")),
    ("missing-key", lambda g: _manifest(g, lambda m: m["cases"][CASE].pop("compare"))),
    ("no-tolerance-float32", _rewrite(lambda a: {k: v for k, v in a.items() if k != "intensity_tolerance_float32"})),
    ("tolerance-wrong-shape", _rewrite(lambda a: {**a, "intensity_tolerance_float32": a["intensity_tolerance_float32"][:5]})),
    ("tolerance-nan", _rewrite(lambda a: {**a, "intensity_tolerance_float32": np.full_like(
        a["intensity_tolerance_float32"], np.nan), "intensity_tolerance_float64": np.full_like(
        a["intensity_tolerance_float64"], np.nan)})),
    ("tolerance-negative", _rewrite(lambda a: {**a, "intensity_tolerance_float32": -a["intensity_tolerance_float32"]})),
    ("category-short", _rewrite(lambda a: {**a, "category": a["category"][:-1]})),
    ("category-unknown", _rewrite(lambda a: {**a, "category": np.full_like(a["category"], "easy")})),
    ("expected-nan", _rewrite(lambda a: {**a, "intensity": np.full_like(a["intensity"], np.nan)})),
    ("case-pickled", _pickled),
    ("case-text", _raw(b"intensity,tolerance\n0.5,1e-3\n")),
    ("case-bzip2-member", _bzip2),
    ("zip-bomb-within-size-limit", _golden_bomb(512 << 20)),
    ("zip-bomb-count-raised", _golden_bomb(1 << 30, count=10**6)),
]




def _golden_probe(kind, edit_id, edit, clean):
    def setup(tmp):
        shutil.copytree(clean, tmp / "g")
        np.savez(tmp / "r.npz", **{f"{CASE}.intensity": np.zeros(len(_clean_rows(clean)), np.float32)})
        edit(tmp / "g")
    argv = (["verify", "--golden", "{tmp}/g", "--results", "{tmp}/r.npz"] if kind == "golden" else
            ["conformance", "--glsl", "msm.glsl", "--function", "shadow_intensity_lower", "--case", CASE,
             "--golden", "{tmp}/g"])
    return Probe(f"{kind}-{edit_id}", kind, argv, setup)


def _clean_rows(clean):
    return range(json.loads((clean / "manifest.json").read_text())["cases"][CASE]["count"])


def _results_probes(clean):
    def results(fn):
        def setup(tmp):
            shutil.copytree(clean, tmp / "g")
            fn(tmp / "r.npz", clean)
        return setup

    def codes(view):
        def write(p, g):
            with np.load(g / f"{CODES}.npz") as z:
                np.savez(p, **{f"{CODES}.p": view(z["p"])})
        return write

    verify = ["verify", "--golden", "{tmp}/g", "--results", "{tmp}/r.npz"]
    return [
        # 960 MiB of zeros in 0.98 MB: within the file-size limit the shapes imply.
        Probe("results-zip-bomb", "results", verify, results(lambda p, g: _bomb(p, f"{CODES}.p", 960 << 20))),
        Probe("results-int32-codes-pass", "results", verify, results(codes(lambda p: p.view(np.int32))), code=0),
        Probe("results-int64-codes-pass", "results", verify, results(codes(lambda p: p.astype(np.int64))), code=0),
        Probe("results-sign-extended-codes", "results", verify,
              results(codes(lambda p: p.view(np.int32).astype(np.int64))),
              check=lambda tmp, run: "row" in run.err or pytest.fail(run.err)),
        Probe("results-pickled", "results", verify, results(lambda p, g: np.save(
            open(p, "wb"), np.array([1], dtype=object), allow_pickle=True))),
    ]


#: Peak resident memory of the interpreter with NumPy, SciPy and matplotlib, beyond which a
#: command's own allocations count against ``--max-memory``.
INTERPRETER = 100 << 20


def _obj_probes():
    def vertices(tmp):  # 300,000 vertices: 48 MB by the generators' estimate (160 B per vertex and triangle)
        (tmp / "m.obj").write_text("v 0 0 0\n" * 300_000 + "f 1 2 3\n")
        (tmp / "s.toml").write_text("shadow_map_size = 64\n" + _LIGHT + _CAMERA + _REC + _MESH)

    def fans(tmp):  # 1,000 polygons of 2,001 corners: 2 million triangles from 4 MB (the old estimate: 64 MB)
        (tmp / "m.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\n" + ("f" + " 1 2 3" * 667 + "\n") * 1000)
        (tmp / "s.toml").write_text("shadow_map_size = 64\n" + _LIGHT + _CAMERA + _REC + _MESH)

    fig4 = ["figure4", "--out", "{tmp}/o", "--scene", "{tmp}/s.toml", "--size", "16"]
    return [Probe("obj-300k-vertices-under-32M", "obj", [*fig4, "--max-memory", "32M"], vertices,
                  rss=INTERPRETER + (32 << 20)),
            Probe("obj-300k-vertices-under-64M", "obj", [*fig4, "--max-memory", "64M"], vertices, code=0,
                  rss=INTERPRETER + (64 << 20)),
            Probe("obj-2M-fan-triangles-under-128M", "obj", [*fig4, "--max-memory", "128M"], fans,
                  rss=INTERPRETER + (128 << 20))]


_MESH = "[[objects]]\nname = \"m\"\nobj = \"m.obj\"\nrole = \"occluder\"\n"


def all_probes(clean):
    """Every probe of the real-process table (``clean``: a golden folder of CASE and CODES)."""
    golden = [_golden_probe(kind, i, e, clean) for kind in ("golden", "conformance") for i, e in GOLDEN_EDITS]
    return SCENE_PROBES + API_PROBES + golden + _results_probes(clean) + _obj_probes()


_IDS = ([p.id for p in SCENE_PROBES + API_PROBES] + [f"{k}-{i}" for k in ("golden", "conformance") for i, _ in GOLDEN_EDITS]
        + ["results-zip-bomb", "results-int32-codes-pass", "results-int64-codes-pass", "results-sign-extended-codes",
           "results-pickled", "obj-300k-vertices-under-32M", "obj-300k-vertices-under-64M",
           "obj-2M-fan-triangles-under-128M"])


@pytest.fixture(scope="module")
def probe_runs(golden_dir, tmp_path_factory):
    """Every probe run once, two at a time (each is its own process): ``{id: (probe, tmp, run)}``."""
    probes = all_probes(golden_dir)
    assert [p.id for p in probes] == _IDS

    forks = Forks()

    def one(p):
        tmp = tmp_path_factory.mktemp("probe")
        return p.id, (p, tmp, run_real(p, tmp, forks))

    try:
        with ThreadPoolExecutor(2) as pool:
            runs = dict(pool.map(one, probes))
    finally:
        forks.close()
    slow = sorted(runs.items(), key=lambda kv: -kv[1][2].seconds)[:8]
    print("slowest probes: " + ", ".join(f"{k} {r.seconds:.1f} s" for k, (_, _, r) in slow))
    return runs


@pytest.mark.parametrize("probe_id", _IDS)
def test_real_process_probe_ends_clean(probe_runs, probe_id):
    probe, tmp, run = probe_runs[probe_id]
    assert verdict(probe, run) == []
    if probe.check:
        probe.check(tmp, run)


# --- signals: no orphan, no temporary --------------------------------------------------


def _children(pid):
    """Pids of the processes whose parent is ``pid`` (Linux /proc)."""
    kids = set()
    for task in Path(f"/proc/{pid}/task").glob("*"):
        try:
            kids |= {int(k) for k in (task / "children").read_text().split()}
        except OSError:
            pass
    return kids


def _alive(pids):
    return [p for p in pids if Path(f"/proc/{p}").exists() and "Z" not in _state(p)]


def _state(pid):
    try:
        return next(line for line in Path(f"/proc/{pid}/status").read_text().splitlines() if line.startswith("State"))
    except (OSError, StopIteration):
        return "Z"


_SLOW = _LIGHT + _CAMERA.replace("[64, 48]", "[640, 480]") + _OCC + _REC  # a few seconds per scene


@pytest.mark.skipif(not Path("/proc/self/task").exists(), reason="reads the process tree from /proc")
@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGKILL], ids=["SIGTERM", "SIGKILL"])
def test_report_workers_die_with_the_parent(tmp_path, sig):
    """``report --jobs 2`` killed while its workers compute: none of its processes is left (was: all, 60 s later)."""
    for name in ("a", "b"):
        (tmp_path / f"{name}.toml").write_text(f"name = \"{name}\"\n" + _SLOW)
    p = spawn(tmp_path, ["report", "--scene", "a.toml", "--scene", "b.toml", "--jobs", "2", "--out", "o",
                         "--no-progress", "--full", "--technique", "pcf", "--technique", "msm64"])
    deadline = time.monotonic() + 120
    while len(_children(p.pid)) < 3 and p.poll() is None and time.monotonic() < deadline:
        time.sleep(0.05)  # the resource tracker and two workers
    kids = _children(p.pid)
    assert len(kids) >= 3, "the workers did not start"
    time.sleep(0.5)
    p.send_signal(sig)
    run = finish(p, tmp_path)
    deadline = time.monotonic() + 5
    while _alive(kids) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert _alive(kids) == [], [Path(f"/proc/{k}/cmdline").read_text() for k in _alive(kids)]
    if sig == signal.SIGTERM:
        assert run.code == 128 + signal.SIGTERM and run.err.splitlines()[-1] == "moments-ref report: terminated (SIGTERM)"
        assert "Traceback" not in run.err
    assert not [f for f in (tmp_path / "o").glob(".*") if f.name != ".write-probe"] if (tmp_path / "o").exists() else True


def test_sigterm_while_a_file_is_written_leaves_no_temporary(tmp_path):
    """SIGTERM the moment a temporary file exists: it is removed, the command ends in one line (exit 143)."""
    for attempt in range(3):
        out = tmp_path / f"o{attempt}"
        p = spawn(tmp_path, ["figure3", "--out", str(out)])
        seen = None
        while p.poll() is None and seen is None:
            seen = next((f for f in out.glob(".figure3*") if ".write-probe" not in f.name), None) if out.exists() else None
            time.sleep(0.005)
        if seen is None:
            finish(p, tmp_path)
            continue  # finished before a temporary was seen: try again
        p.send_signal(signal.SIGTERM)
        run = finish(p, tmp_path)
        left = [f.name for f in out.glob(".*")]
        assert left == [], f"temporaries left: {left}"
        assert run.code in (0, 128 + signal.SIGTERM), run.err
        assert run.code == 0 or run.err.splitlines()[-1] == "moments-ref figure3: terminated (SIGTERM)"
        return
    pytest.skip("figure3 finished three times before its temporary file could be seen")


def test_sigint_between_creating_and_guarding_a_temporary(tmp_path):
    """A SIGINT that arrives while the temporary is created (mkstemp) leaves no temporary behind.

    The signal is sent from inside ``mkstemp``: before, it was raised as soon as
    ``mkstemp`` returned, before the ``try`` that removes the file; now it is held
    until the file is registered, and the registry is emptied at exit.
    """
    code = f"""\
import signal, tempfile, threading
from moments_ref import _io
signal.signal(signal.SIGINT, signal.default_int_handler)  # an xdist worker's children inherit SIGINT ignored
make = tempfile.mkstemp
def mkstemp(*a, **k):
    r = make(*a, **k)
    # to this thread, so that it is delivered before the call returns: a process-wide
    # os.kill may reach another thread (OpenBLAS's) after the script has ended
    signal.pthread_kill(threading.get_ident(), signal.SIGINT)
    return r
tempfile.mkstemp = mkstemp
with _io.atomic_path({str(tmp_path / 'x.png')!r}) as tmp:
    tmp.write_bytes(b"data")
"""
    run = finish(spawn(tmp_path, code=code), tmp_path)
    assert "KeyboardInterrupt" in run.err
    assert [f.name for f in tmp_path.iterdir()] == [], "a temporary was left"


# --- a write phase that fails: the folder says so ----------------------------------------


@pytest.mark.parametrize("how", ["results.csv-is-a-folder", "file-size-limit"])
def test_report_whose_writing_fails_marks_its_folder(tmp_path, how):
    (tmp_path / "s.toml").write_text(_SMALL)
    out = tmp_path / "o"
    fsize = None
    if how == "results.csv-is-a-folder":
        (out / "results.csv").mkdir(parents=True)
    else:
        fsize = 16 << 10  # files over 16 KiB fail with EFBIG, as writes to a full disk fail with ENOSPC
    p = spawn(tmp_path, ["report", "--scene", "s.toml", "--out", "o", "--jobs", "1", "--no-progress",
                         "--technique", "pcf", "--repeats", "1"], fsize=fsize)
    run = finish(p, tmp_path)
    assert run.code == 2 and "Traceback" not in run.err, run.err
    last = run.err.splitlines()[-1]
    assert last.startswith("moments-ref report: out: could not write") and "INCOMPLETE" in last, last
    assert (out / "INCOMPLETE").is_file() and "not completely written" in (out / "INCOMPLETE").read_text()
    assert [f.name for f in out.glob(".*") if f.name != ".write-probe"] == []


def test_no_warning_precedes_the_one_line_refusal(monkeypatch, capsys):
    """A command that warns and then refuses prints the refusal alone (the warnings are dropped)."""
    import warnings

    from moments_ref import InputError, cli

    def warn_then_refuse(args):
        warnings.warn("overflow encountered in dot", RuntimeWarning)
        raise InputError("direction: expected a finite direction")

    monkeypatch.setattr(cli, "_cmd_banks", warn_then_refuse)
    assert cli.main(["banks"]) == 2
    err = capsys.readouterr().err
    assert err == "moments-ref banks: direction: expected a finite direction\n"


def test_warnings_of_a_command_that_succeeds_are_printed_after_it(monkeypatch, capsys):
    import warnings

    from moments_ref import cli

    def warn(args):
        warnings.warn("a harmless warning", RuntimeWarning)
        print("done")
        return 0

    monkeypatch.setattr(cli, "_cmd_banks", warn)
    with warnings.catch_warnings(record=True) as shown:
        warnings.simplefilter("always")
        assert cli.main(["banks"]) == 0
    assert capsys.readouterr().out == "done\n"
    assert [str(w.message) for w in shown] == ["a harmless warning"]
