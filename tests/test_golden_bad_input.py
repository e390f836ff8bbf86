"""``verify`` on bad golden folders and results: exit 2, one line on stderr, nothing read that should not be."""

import json
import os
import shutil

import numpy as np
import pytest

from moments_ref import golden
from moments_ref.cli import main

CASE = "psi4-float32"


@pytest.fixture(scope="module")
def clean(tmp_path_factory):
    d = tmp_path_factory.mktemp("golden_clean")
    golden.write(d, [CASE, "psi4_inverse-float32"])
    with np.load(d / f"{CASE}.npz") as g:
        u = golden.evaluate_reference(golden.CASES[CASE], {"xi4": g["xi4"]}, "float32")[0]
    np.savez(d.parent / "results.npz", **{f"{CASE}.u": u})
    return d


def _copy(clean, tmp_path):
    g = tmp_path / "g"
    shutil.copytree(clean, g)
    return g


def _edit(g, fn):
    m = json.loads((g / "manifest.json").read_text())
    fn(m)
    (g / "manifest.json").write_text(json.dumps(m))


def _run(g, results, capsys):
    code = main(["verify", "--golden", str(g), "--results", str(results)])
    err = capsys.readouterr().err
    return code, err


def _file(name):
    return lambda m: m["cases"][CASE].__setitem__("file", name)


def _fifo(g):
    os.mkfifo(g / "fifo.npz")
    _edit(g, _file("fifo.npz"))


def _link(g):
    os.symlink(g / f"{CASE}.npz", g / "link.npz")
    _edit(g, _file("link.npz"))


def _large(g):
    data = (g / f"{CASE}.npz").read_bytes()
    (g / f"{CASE}.npz").write_bytes(data + b"\0" * (50 << 20))


def _corrupt(g):
    data = bytearray((g / f"{CASE}.npz").read_bytes())
    data[10:200] = b"\0" * 190
    (g / f"{CASE}.npz").write_bytes(bytes(data))
    import hashlib

    _edit(g, lambda m: m["cases"][CASE].__setitem__("sha256", hashlib.sha256(bytes(data)).hexdigest()))


def _missing_array(g):
    import hashlib
    import io

    with np.load(g / f"{CASE}.npz") as z:
        arrays = {k: z[k] for k in z.files if k != "u"}
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    (g / f"{CASE}.npz").write_bytes(buf.getvalue())
    _edit(g, lambda m: m["cases"][CASE].__setitem__("sha256", hashlib.sha256(buf.getvalue()).hexdigest()))


PROBES = {
    "dotdot": lambda g: _edit(g, _file("../x.npz")),
    "absolute": lambda g: _edit(g, _file("/etc/passwd")),
    "subfolder": lambda g: _edit(g, _file("sub/x.npz")),
    "dev_zero": lambda g: _edit(g, _file("/dev/zero")),
    "fifo": _fifo,
    "link": _link,
    "folder": lambda g: ((g / "d.npz").mkdir(), _edit(g, _file("d.npz"))),
    "larger_than_shapes": _large,
    "corrupt_npz": _corrupt,
    "wrong_sha256": lambda g: _edit(g, lambda m: m["cases"][CASE].__setitem__("sha256", "0" * 64)),
    "malformed_json": lambda g: (g / "manifest.json").write_text("{not json"),
    "not_utf8": lambda g: (g / "manifest.json").write_bytes(b"\xff\xfe{}"),
    "missing_cases": lambda g: _edit(g, lambda m: m.pop("cases")),
    "cases_not_object": lambda g: _edit(g, lambda m: m.__setitem__("cases", [1, 2])),
    "missing_key": lambda g: _edit(g, lambda m: m["cases"][CASE].pop("compare")),
    "entry_not_object": lambda g: _edit(g, lambda m: m["cases"].__setitem__(CASE, "x")),
    "old_schema": lambda g: _edit(g, lambda m: m.__setitem__("schema_version", 1)),
    "missing_npz": lambda g: (g / f"{CASE}.npz").unlink(),
    "missing_array": _missing_array,
    "manifest_is_link": lambda g: ((g / "manifest.json").rename(g / "m.json"),
                                   os.symlink(g / "m.json", g / "manifest.json")),
    "no_manifest": lambda g: (g / "manifest.json").unlink(),
    "bad_shape": lambda g: _edit(g, lambda m: m["cases"][CASE]["outputs"]["u"].__setitem__("shape", ["x"])),
}


@pytest.mark.parametrize("probe", sorted(PROBES))
def test_bad_golden_folder_exits_2_with_one_line(clean, tmp_path, capsys, probe):
    g = _copy(clean, tmp_path)
    PROBES[probe](g)
    code, err = _run(g, clean.parent / "results.npz", capsys)
    assert code == 2, err
    assert err.count("\n") == 1 and "Traceback" not in err, err


RESULT_PROBES = {
    "strings": lambda p: np.savez(p, **{f"{CASE}.u": np.array(["a"] * 130)}),
    "unknown_name": lambda p: np.savez(p, **{"nope.u": np.zeros(3, np.float32)}),
    "not_npz": lambda p: p.write_bytes(b"hello"),
    "object_array": lambda p: np.savez(p, **{f"{CASE}.u": np.array([None, 1], dtype=object)}),
    "missing": lambda p: None,
    "fifo": lambda p: os.mkfifo(p),
    "larger_than_the_cases_imply": lambda p: np.savez(p, **{f"{CASE}.u": np.zeros(400000, np.float32)}),
}


@pytest.mark.parametrize("probe", sorted(RESULT_PROBES))
def test_bad_results_exit_2_with_one_line(clean, tmp_path, capsys, probe):
    p = tmp_path / "r.npz"
    RESULT_PROBES[probe](p)
    code, err = _run(clean, p, capsys)
    assert code == 2, err
    assert err.count("\n") == 1 and "Traceback" not in err, err


def test_unknown_result_name_lists_the_known_ones(clean, tmp_path, capsys):
    p = tmp_path / "r.npz"
    np.savez(p, **{"psi4-float32.x": np.zeros(3, np.float32)})
    code, err = _run(clean, p, capsys)
    assert code == 2 and "psi4-float32.u" in err and "psi4_inverse-float32.xi4" in err


def test_the_clean_folder_passes(clean, capsys):
    code, err = _run(clean, clean.parent / "results.npz", capsys)
    assert code == 0, err
