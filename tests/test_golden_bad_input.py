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


# ---------------------------------------------------------------------------
# The loader's rules one by one (golden.loader's module docstring): what it accepts, what it refuses and
# with which words, on a hand-made three-row case; no golden folder written.

import hashlib  # noqa: E402
import io  # noqa: E402
import zipfile  # noqa: E402

from moments_ref import InputError  # noqa: E402
from moments_ref.golden import loader  # noqa: E402


def _meta(**over):
    meta = {"file": "c.npz", "compare": ["y"], "inputs": {"x": {"dtype": "float32", "shape": [3]}},
            "outputs": {"y": {"dtype": "float32", "shape": [3]}}, "dtype": "float32", "metric": "abs",
            "exact": False, "count": 3, "sha256": "0" * 64}
    meta.update(over)
    return meta


def _arrays(**over):
    a = {"x": np.zeros(3, np.float32), "y": np.array([0.5, 1.0, 2.0], np.float32),
         "y_tolerance_float32": np.full(3, 1e-6), "y_tolerance_float64": np.full(3, 1e-12),
         "category": np.array(["random", "stiff", "edge"]), "comment": np.array(["a", "b", "c"]),
         "result": np.array(["valid"] * 3), "tc_id": np.array([7, 8, 9], np.int32)}
    a.update(over)
    return {k: v for k, v in a.items() if v is not None}


def _npz(arrays):
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    return buf.getvalue()


def _load(tmp_path, meta, blob):
    (tmp_path / meta["file"]).write_bytes(blob)
    meta = dict(meta, sha256=hashlib.sha256(blob).hexdigest())
    return loader.load_case_arrays(tmp_path, "c", meta)


def _refused(match, fn, *args):
    with pytest.raises(InputError, match=match) as e:
        fn(*args)
    assert "\n" not in str(e.value)
    return str(e.value)


def test_a_well_formed_case_loads_as_written(tmp_path):
    a = _arrays(y=np.asfortranarray(np.arange(6, dtype=np.float32).reshape(3, 2)))
    meta = _meta(outputs={"y": {"dtype": "float32", "shape": [3, 2]}},
                 **{"value_range": [0, 5], "kwargs": {}, "input_order": ["x"]})
    a["y_tolerance_float32"] = a["y_tolerance_float64"] = np.full((3, 2), np.inf)  # +inf: only a finite value
    got = _load(tmp_path, meta, _npz(a))
    assert sorted(got) == sorted(a)
    for k in a:
        np.testing.assert_array_equal(got[k], a[k])
        assert got[k].dtype == a[k].dtype


def test_read_regular_takes_a_file_of_exactly_the_limit_and_refuses_one_byte_more(tmp_path):
    p = tmp_path / "f"
    p.write_bytes(b"x" * 10)
    assert loader.read_regular(p, 10, "what") == b"x" * 10
    assert loader.read_regular(p, 11, "what") == b"x" * 10
    _refused(r"^what: expected at most 9 bytes, got .* with 10 bytes$", loader.read_regular, p, 9, "what")
    _refused(r"^what: expected a file, got .*\(not found\)$", loader.read_regular, tmp_path / "nope", 9, "what")
    _refused(r"^what: expected a regular file, got .*\(a link", loader.read_regular, tmp_path, 9, "what")
    os.symlink(p, tmp_path / "l")
    _refused(r"^what: expected a regular file, got .*\(a link", loader.read_regular, tmp_path / "l", 99, "what")


@pytest.mark.skipif(not os.path.isfile("/proc/self/status"), reason="needs procfs")
def test_read_regular_refuses_a_file_that_holds_more_than_its_stated_size():
    # procfs states size 0 for a file of several hundred bytes (a file growing while read looks the same).
    assert os.lstat("/proc/self/status").st_size == 0
    _refused(r"^what: expected at most 10 bytes, got '/proc/self/status' with more than its stated 0$",
             loader.read_regular, "/proc/self/status", 10, "what")


@pytest.mark.parametrize("swap", ["link", "fifo"])
def test_read_regular_refuses_what_is_swapped_in_after_its_check(tmp_path, monkeypatch, swap):
    # A race: the path passes the lstat as a regular file, then is a link or a FIFO when opened. The open
    # neither follows the link nor waits for a FIFO's writer.
    (tmp_path / "real").write_bytes(b"secret")
    p = tmp_path / "p"
    os.symlink(tmp_path / "real", p) if swap == "link" else os.mkfifo(p)
    regular = os.lstat(tmp_path / "real")
    monkeypatch.setattr(os, "lstat", lambda path, *a, **k: regular)
    why = "could not open .*: Too many levels of symbolic links" if swap == "link" else "expected a regular file"
    _refused(rf"^what: {why}", loader.read_regular, p, 99, "what")


def test_read_regular_opens_a_fifo_never(tmp_path):
    # Not even the open: a FIFO without a writer would block it.
    os.mkfifo(tmp_path / "p")
    _refused(r"a link, device, FIFO or folder", loader.read_regular, tmp_path / "p", 99, "what")


def _manifest(tmp_path, text):
    (tmp_path / "manifest.json").write_text(text) if isinstance(text, str) else (
        tmp_path / "manifest.json").write_bytes(text)
    return loader.load_manifest(tmp_path)


def _nested(depth):
    return '{"x": ' + "[" * (depth - 1) + "]" * (depth - 1) + "}"


@pytest.mark.parametrize("depth", [loader.MAX_JSON_DEPTH, loader.MAX_JSON_DEPTH + 1])
def test_json_nesting_is_counted_before_parsing(tmp_path, depth):
    text = _nested(depth)
    if depth > loader.MAX_JSON_DEPTH:
        _refused(rf"^manifest: objects or arrays nested more than {loader.MAX_JSON_DEPTH} deep \(offset "
                 rf"{6 + loader.MAX_JSON_DEPTH - 1}\)$", loader.parse_json, text.encode(), "manifest")
    else:
        assert loader.parse_json(text.encode(), "manifest") == json.loads(text)


def test_json_brackets_in_strings_and_closed_siblings_do_not_count():
    deep_string = '{"x": "' + "[{" * 100 + '\\"]"}'
    assert loader.parse_json(deep_string.encode(), "m") == {"x": "[{" * 100 + '"]'}
    siblings = "[" + ",".join(["[[]]"] * 100) + "]"  # depth 3, a hundred times
    assert loader.parse_json(siblings.encode(), "m") == [[[]]] * 100
    deep_after_siblings = "[" + "[]," * 40 + "[" * loader.MAX_JSON_DEPTH + "]" * loader.MAX_JSON_DEPTH + "]"
    _refused(r"nested more than 32 deep", loader.parse_json, deep_after_siblings.encode(), "m")


def test_json_that_is_no_utf8_or_no_json_is_named():
    _refused(r"^m: expected UTF-8 JSON, got byte 0xff at offset 2$", loader.parse_json, b'{"\xff"}', "m")
    _refused(r"^m: expected JSON, could not parse", loader.parse_json, b"{not json", "m")
    _refused(r"^m: expected JSON, could not parse", loader.parse_json, ("[" + "9" * 5000 + "]").encode(), "m")


def _with(entry):
    return json.dumps({"schema_version": loader.SCHEMA_VERSION, "cases": {"c": entry}})


def test_load_manifest_refuses_what_is_no_manifest(tmp_path):
    _refused(r"^golden_dir: expected a folder", loader.load_manifest, tmp_path / "nope")
    for text in ("[]", '{"cases": []}', '{"x": 1}'):
        _refused(r"^manifest: expected an object with a 'cases' object$", _manifest, tmp_path, text)
    for v in ("true", str(loader.SCHEMA_VERSION - 1), f'"{loader.SCHEMA_VERSION}"', "null"):
        _refused(rf"^manifest: expected schema_version {loader.SCHEMA_VERSION}, got ", _manifest, tmp_path,
                 f'{{"schema_version": {v}, "cases": {{"c": {{}}}}}}')
    _refused(r"^manifest: 'cases' is empty$", _manifest, tmp_path,
             f'{{"schema_version": {loader.SCHEMA_VERSION}, "cases": {{}}}}')
    _refused(r"^manifest: case 'c' lacks the key 'file'", _manifest, tmp_path, _with({}))
    assert _manifest(tmp_path, _with(_meta()))["cases"]["c"] == _meta()


ENTRY_REFUSALS = [  # (change, what the one line names)
    (dict(file=""), "expected a file name inside the golden folder"),
    (dict(file="."), "expected a file name inside the golden folder"),
    (dict(file=".."), "expected a file name inside the golden folder"),
    (dict(file="a\\b.npz"), "expected a file name inside the golden folder"),
    (dict(file="a\0.npz"), "expected a file name inside the golden folder"),
    (dict(file=3), "expected a file name inside the golden folder"),
    (dict(dtype="float16"), "dtype: expected float32 or float64, got 'float16'"),
    (dict(metric="rel"), "metric: expected abs, ulps or exact"),
    (dict(exact=True), "metric: expected abs, ulps or exact"),
    (dict(exact=0), "metric: expected abs, ulps or exact"),
    (dict(count=0), r"count: expected an integer in \[1, 1048576\], got 0"),
    (dict(count=loader.MAX_ROWS + 1), "count: expected an integer in"),
    (dict(count=True), "count: expected an integer in"),
    (dict(count=3.0), "count: expected an integer in"),
    (dict(inputs={}), "expected 'inputs' as a non-empty object"),
    (dict(outputs=[]), "expected 'outputs' as a non-empty object"),
    (dict(inputs={"a b": {"dtype": "float32", "shape": [3]}}), "expected 'inputs' as a non-empty object"),
    (dict(inputs={"x": {"dtype": "float32", "shape": [3]}, "a b": {"dtype": "float32", "shape": [3]}}),
     "expected 'inputs' as a non-empty object"),
    (dict(inputs={"x": [3]}), r"inputs.x: expected \{'dtype'"),
    (dict(inputs={"x": {"dtype": "float32"}}), r"inputs.x: expected \{'dtype'"),
    (dict(inputs={"x": {"shape": [3]}}), r"inputs.x: expected \{'dtype'"),
    (dict(inputs={"x": {"dtype": "object", "shape": [3]}}), "inputs.x.dtype: expected a numeric dtype"),
    (dict(inputs={"x": {"dtype": "complex64", "shape": [3]}}), "inputs.x.dtype: expected a numeric dtype"),
    (dict(inputs={"x": {"dtype": "float128", "shape": [3]}}), "inputs.x.dtype: expected a numeric dtype"),
    (dict(inputs={"x": {"dtype": "no-such-type", "shape": [3]}}), "inputs.x.dtype: expected a numeric dtype"),
    (dict(inputs={"x": {"dtype": 4, "shape": [3]}}), "inputs.x.dtype: expected a numeric dtype"),
    (dict(inputs={"x": {"dtype": "float32", "shape": 3}}), "inputs.x.shape: expected a list"),
    (dict(inputs={"x": {"dtype": "float32", "shape": []}}), "inputs.x.shape: expected a list"),
    (dict(inputs={"x": {"dtype": "float32", "shape": [3, 1, 1, 1, 1]}}), "inputs.x.shape: expected a list"),
    (dict(inputs={"x": {"dtype": "float32", "shape": [3, -1]}}), "inputs.x.shape: expected a list"),
    (dict(inputs={"x": {"dtype": "float32", "shape": [3, True]}}), "inputs.x.shape: expected a list"),
    (dict(inputs={"x": {"dtype": "float32", "shape": [3, 2.0]}}), "inputs.x.shape: expected a list"),
    (dict(inputs={"x": {"dtype": "float32", "shape": [3, loader.MAX_ELEMENTS + 1]}}), "expected a list"),
    (dict(inputs={"x": {"dtype": "float32", "shape": [3, 1 << 13, 1 << 13]}}), "expected a list"),
    (dict(inputs={"x": {"dtype": "float32", "shape": [(1 << 24) + 1, 4]}}), "expected a list"),  # not in float32
    (dict(outputs={"y": {"dtype": "float32", "shape": [2]}}), r"outputs.y.shape: .* starting with the count 3"),
    (dict(compare=[]), "'compare' must list outputs of the case"),
    (dict(compare="y"), "'compare' must list outputs of the case"),
    (dict(compare=["y", "y"]), "'compare' must list outputs of the case"),
    (dict(compare=["x"]), "'compare' must list outputs of the case"),
    (dict(compare=["y", "x"]), "'compare' must list outputs of the case"),
    (dict(compare=["y", 3]), "'compare' must list outputs of the case"),
    (dict(metric="exact", exact=True), "output 'y' has dtype float32, but metric 'exact' compares integer codes"),
    (dict(outputs={"y": {"dtype": "int32", "shape": [3]}}), "but metric 'abs' compares floats"),
    (dict(value_range=[1, 0]), "value_range: expected null or"),
    (dict(value_range=[0]), "value_range: expected null or"),
    (dict(value_range=(0, 1)), "value_range: expected null or"),
    (dict(value_range=[0, float("inf")]), "value_range: expected null or"),
    (dict(value_range=[float("nan"), 1]), "value_range: expected null or"),
    (dict(value_range=[0, 10 ** 301]), "value_range: expected null or"),
    (dict(value_range=[0, int(1e300) + 1]), "value_range: expected null or"),
    (dict(value_range=[-(10 ** 301), 0]), "value_range: expected null or"),
    (dict(value_range=[False, 1]), "value_range: expected null or"),
    (dict(value_range=["0", 1]), "value_range: expected null or"),
    (dict(sha256="A" * 64), "sha256: expected 64 hexadecimal digits"),
    (dict(sha256="0" * 63), "sha256: expected 64 hexadecimal digits"),
    (dict(sha256=None), "sha256: expected 64 hexadecimal digits"),
    (dict(kwargs=[]), "kwargs: expected an object"),
    (dict(input_order=["y"]), r"input_order: expected the input names \['x'\]"),
    (dict(input_order="x"), r"input_order: expected the input names"),
]


@pytest.mark.parametrize("change,message", ENTRY_REFUSALS, ids=range(len(ENTRY_REFUSALS)))
def test_check_entry_refuses_each_malformed_key_in_one_line(change, message):
    text = _refused(message, loader.check_entry, "c", _meta(**change))
    assert text.startswith("manifest: case 'c': ")


def test_check_entry_accepts_the_edges_of_each_rule():
    one = {"dtype": "float32", "shape": [1]}
    ok = [dict(count=1, inputs={"x": one}, outputs={"y": one}),
          dict(count=loader.MAX_ROWS, inputs={"x": {"dtype": "uint8", "shape": [loader.MAX_ROWS]}},
               outputs={"y": {"dtype": "float64", "shape": [loader.MAX_ROWS]}}),
          dict(metric="ulps"), dict(metric="exact", exact=True, outputs={"y": {"dtype": "uint16", "shape": [3]}}),
          dict(metric="exact", exact=True, outputs={"y": {"dtype": "int8", "shape": [3]}}),
          dict(inputs={"x": {"dtype": "bool", "shape": [3, 1, 2, 0]}}),
          dict(inputs={"x": {"dtype": "float32", "shape": [5, 5]}}),  # inputs may hold whole maps (kernel cases)
          dict(value_range=None), dict(value_range=[1, 1]), dict(value_range=[-(10 ** 300), 10 ** 300]),
          dict(value_range=[-1.5, 2]), dict(file="c.d.npz"), dict(name_extra=1),
          dict(value_range=[-int(1e300), int(1e300)]),  # an integer up to 1e300 in magnitude is a number
          dict(inputs={"x": {"dtype": "float32", "shape": [loader.MAX_ELEMENTS]}}),
          dict(inputs={"x": {"dtype": "float32", "shape": [1 << 13, 1 << 13]}})]
    for change in ok:
        loader.check_entry("c", _meta(**change))
    loader.check_entry("a" * 128, _meta())
    for name in ("a" * 129, "-a", "", 3, "a/b"):
        _refused(r"^manifest: expected case names of letters, digits and _\.\+-", loader.check_entry, name, _meta())
    _refused(r"^manifest: case 'c': expected an object, got list$", loader.check_entry, "c", [])


def _zip(members, method=zipfile.ZIP_STORED):
    import warnings

    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", method) as z, warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # a name twice, on purpose
        for name, data in members:
            z.writestr(name, data)
    return buf.getvalue()


def _npy(array, version=None):
    buf = io.BytesIO()
    np.lib.format.write_array(buf, array, version=version)
    return buf.getvalue()


def _members(**over):
    return [(f"{k}.npy", _npy(v)) for k, v in _arrays(**over).items()]


ARCHIVE_REFUSALS = [  # (archive bytes, what the one line names)
    (b"PK\x03\x04 not a zip", "expected an .npz \\(zip\\) archive, could not read its directory"),
    (_zip(_members() + [("notes.txt", b"hi")]), "'notes.txt' is not an .npy member"),
    (_zip(_members() + [("x.npy", _npy(np.zeros(3, np.float32)))]), "an array name occurs twice in the archive"),
    (_zip(_members(), zipfile.ZIP_BZIP2), "is compressed with method 12; expected stored or deflated"),
    (_zip(_members(), zipfile.ZIP_LZMA), "is compressed with method 14; expected stored or deflated"),
    (_zip(_members(x=None) + [("x.npy", _npy(np.zeros(3, np.float32))[:-1])]),
     "array 'x' holds 11 bytes of data, its header says 12"),
    (_zip(_members(x=None) + [("x.npy", _npy(np.zeros(3, np.float32)) + b"\0")]),
     "array 'x' holds 13 bytes of data, its header says 12"),
    (_zip(_members(x=None) + [("x.npy", b"\x93NUMPY\x03\x00" + _npy(np.zeros(3, np.float32))[8:])]),
     r"array 'x' is .npy version \(3, 0\); expected 1.0 or 2.0"),
    (_zip(_members(x=np.zeros(3, np.float64))), "array 'x' expected dtype float32, found dtype float64"),
    (_zip(_members(x=np.zeros(4, np.float32))), r"array 'x' has shape \(4,\), expected \(3,\)"),
    (_zip(_members(x=np.zeros(3, np.complex64))),
     "array 'x' expected booleans or integers or floats, found dtype complex64"),
    (_zip(_members(x=np.zeros(3, "U1"))), "array 'x' expected booleans or integers or floats, found dtype <U1"),
    (_zip(_members(category=np.zeros(3, np.float32))), "array 'category' expected text, found dtype float32"),
    (_zip(_members(tc_id=np.zeros(3, np.float32))), "array 'tc_id' expected integers, found dtype float32"),
    (_zip(_members(tc_id=np.zeros(4, np.int32))), r"array 'tc_id' has shape \(4,\), expected \(3,\)"),
    (_zip(_members(comment=np.array(["a"] * 4))), r"array 'comment' has shape \(4,\), expected 3 rows"),
    (_zip(_members(comment=np.array("abc"))), r"array 'comment' has shape \(\), expected 3 rows"),
    (_zip(_members(comment=np.array([["a", "b"]] * 3))), r"array 'comment' has shape \(3, 2\), expected 3 rows"),
    (_zip(_members(comment=None) + [("comment.npy", _npy(np.array(["a" * 6500] * 3))[:200])]),  # header only
     r"array 'comment' holds \(3,\) values of 26000 bytes, more than expected"),
    (_zip(_members(extra=np.zeros((3, 1025)))), r"array 'extra' has shape \(3, 1025\), expected 3 rows"),
    (_zip(_members(extra=np.zeros((3, 1, 1, 1, 1)))), r"array 'extra' has shape \(3, 1, 1, 1, 1\), expected 3"),
    (_zip(_members(extra=np.zeros(3, object))),
     "array 'extra' expected booleans or integers or floats or text, found dtype object"),
    (_zip(_members(extra=np.zeros(3, np.longdouble))),  # 16 bytes on x86-64
     "array 'extra' expected booleans or integers or floats or text, found dtype float128"),
]


@pytest.mark.parametrize("blob,message", ARCHIVE_REFUSALS, ids=range(len(ARCHIVE_REFUSALS)))
def test_an_archive_is_refused_by_its_directory_and_headers_in_one_line(tmp_path, blob, message):
    text = _refused(message, _load, tmp_path, _meta(), blob)
    assert text.startswith("golden file c.npz: ")


def test_an_archive_declaring_more_bytes_than_its_shape_allows_is_not_decompressed(tmp_path):
    big = np.zeros(3 + (1 << 16) // 4, np.float32)  # one header's worth beyond the three values
    blob = bytearray(_zip(_members(x=None) + [("x.npy", _npy(big))]))
    _refused(rf"array 'x' declares {len(_npy(big))} bytes uncompressed, more than its expected shape allows "
             rf"\({3 * 8 + (1 << 16)}\); not decompressed", _load, tmp_path, _meta(), bytes(blob))
    assert len(_npy(np.zeros(3, np.float32))) <= 3 * 8 + (1 << 16)


def test_a_truncated_or_corrupt_member_is_refused(tmp_path):
    blob = _zip(_members(), zipfile.ZIP_DEFLATED)
    i = blob.index(b"x.npy") + 5  # the deflated data of the member named first
    bad = blob[:i + 20] + bytes(b ^ 0xFF for b in blob[i + 20:i + 40]) + blob[i + 40:]
    _refused(r"^golden file c.npz: (a corrupt or truncated array|array)", _load, tmp_path, _meta(), bad)


def test_the_archives_total_is_checked_against_the_memory_limit(tmp_path):
    from moments_ref._arrays import set_max_memory

    blob = _npz(_arrays(extra=np.zeros((3, 1, 2, 1))))  # a per-row array of four dimensions is fine
    total = sum(i.file_size for i in zipfile.ZipFile(io.BytesIO(blob)).infolist())
    old = set_max_memory(total)
    try:
        assert _load(tmp_path, _meta(), blob)["extra"].shape == (3, 1, 2, 1)
        set_max_memory(total - 1)
        _refused(rf"^golden file c.npz \(9 arrays, {total} bytes uncompressed\): needs about", _load, tmp_path,
                 _meta(), blob)
    finally:
        set_max_memory(old)


def _npy2(array, size):
    """An .npy 2.0 member of ``size`` bytes in all: ``array``'s header padded with spaces (as NumPy pads)."""
    head = np.lib.format.header_data_from_array_1_0(array)
    text = repr({"descr": head["descr"], "fortran_order": False, "shape": array.shape})
    n = size - 12 - array.nbytes  # magic 8, header length 4
    return b"\x93NUMPY\x02\x00" + n.to_bytes(4, "little") + (text + " " * (n - len(text) - 1) + "\n").encode() + (
        array.tobytes())


def test_a_member_may_declare_exactly_its_bound(tmp_path):
    # x: three float32 values, at most 3 * 8 bytes and a 64 KiB header: a 2.0 member of exactly that size loads.
    bound = 3 * 8 + (1 << 16)
    x = np.arange(3, dtype=np.float32)
    blob = _zip(_members(x=None) + [("x.npy", _npy2(x, bound))])
    np.testing.assert_array_equal(_load(tmp_path, _meta(), blob)["x"], x)
    blob = _zip(_members(x=None) + [("x.npy", _npy2(x, bound + 1))])
    _refused(rf"array 'x' declares {bound + 1} bytes uncompressed", _load, tmp_path, _meta(), blob)


@pytest.mark.parametrize("count,key,chars,over", [(4, "comment", 5120, False), (4, "comment", 5121, True),
                                                  (16385, "extra", 2049, True)])
def test_a_headers_values_are_bounded_before_its_data_is_read(tmp_path, count, key, chars, over):
    # The header alone and 12 bytes: its shape times the item size is checked against the bound first (text:
    # 4096 bytes a row; an unknown per-row array 1024 values of 8 bytes a row; a 64 KiB header), exactly.
    # 4 rows of 5120 characters are the bound; 16385 rows of 2049 characters 4 bytes beyond it.
    bound = count * (4096 if key == "comment" else 8 * 1024) + (1 << 16)
    assert (4 * chars * count > bound) is over
    buf = io.BytesIO()
    np.lib.format.write_array_header_1_0(buf, {"descr": f"<U{chars}", "fortran_order": False, "shape": (count,)})
    meta = _meta(count=count, outputs={"y": {"dtype": "float32", "shape": [count]}})
    why = (rf"holds \({count},\) values of {4 * chars} bytes, more than expected" if over
           else rf"holds 12 bytes of data, its header says {4 * chars * count}")
    _refused(rf"^golden file c.npz: array '{key}' {why}$", _load, tmp_path, meta,
             _zip([(f"{key}.npy", buf.getvalue() + b"\0" * 12)]))


def test_a_member_shorter_than_its_directory_says_is_refused(tmp_path):
    # A stored member with a true CRC, a header of 4 values and 3 values of data, its size in the central
    # directory raised by 4: zipfile reads the short data without an error.
    head = _npy(np.zeros(4, np.float32))[:-4]
    blob = bytearray(_zip(_members(x=None) + [("x.npy", head)]))
    cd = blob.rindex(b"PK\x01\x02")
    size = int.from_bytes(blob[cd + 24:cd + 28], "little")
    blob[cd + 24:cd + 28] = (size + 4).to_bytes(4, "little")
    meta = _meta(inputs={"x": {"dtype": "float32", "shape": [4]}})
    _refused(r"^golden file c.npz: a corrupt or truncated array", _load, tmp_path, meta, bytes(blob))


VALUE_REFUSALS = [  # (arrays changed, what the one line names: the array and the first bad row with its tc_id)
    (dict(category=np.array(["random", "wild", "nope"])),
     r"category is 'wild', not one of random, stiff, edge, at row 1 \(tc_id 8\)$"),
    (dict(result=np.array(["valid", "valid", "maybe"])),
     r"result is 'maybe', not one of valid, acceptable, at row 2 \(tc_id 9\)$"),
    (dict(y=np.array([0.5, np.inf, np.nan], np.float32)), r"y is not finite at row 1 \(tc_id 8\)$"),
    (dict(y_tolerance_float32=np.array([1, 1, np.nan])), r"y_tolerance_float32 is nan .* at row 2 \(tc_id 9\)$"),
    (dict(y_tolerance_float64=np.array([1, 0.0, -1])),
     r"y_tolerance_float64 is 0.0 \(a tolerance must be positive.* at row 1 \(tc_id 8\)$"),
    (dict(y_tolerance_float64=np.array([-np.inf, 1, 1])), r"y_tolerance_float64 is -inf .* at row 0 \(tc_id 7\)$"),
    (dict(y_tolerance_float32=None), r"^golden file c.npz lacks the array 'y_tolerance_float32'$"),
    (dict(tc_id=None), r"^golden file c.npz lacks the array 'tc_id'$"),
    (dict(x=None), r"^golden file c.npz lacks the array 'x'$"),
    (dict(y=None), r"^golden file c.npz lacks the array 'y'$"),
]


@pytest.mark.parametrize("over,message", VALUE_REFUSALS, ids=range(len(VALUE_REFUSALS)))
def test_a_cases_values_are_checked_naming_the_first_bad_row(tmp_path, over, message):
    _refused(message, _load, tmp_path, _meta(), _npz(_arrays(**over)))


def _exact_case(acceptable, dtype="uint8"):
    meta = _meta(metric="exact", exact=True, outputs={"y": {"dtype": dtype, "shape": [3]}})
    a = _arrays(y=np.array([1, 2, 3], dtype), y_tolerance_float32=None, y_tolerance_float64=None)
    if acceptable is not None:
        a["y_acceptable"] = np.asarray(acceptable)
    return meta, _npz(a)


def test_the_acceptable_codes_of_an_exact_case_fit_the_outputs_dtype(tmp_path):
    for acc, dtype in (([[0, 255]] * 3, "uint8"), ([[-128, 127]] * 3, "int8"), (None, "uint8"),
                       (np.zeros((3, loader.MAX_ACCEPTABLE), np.int64), "uint8")):
        got = _load(tmp_path, *_exact_case(acc, dtype))
        assert ("y_acceptable" in got) is (acc is not None)
    for acc, dtype in (([[0, 256]] * 3, "uint8"), ([[-1, 0]] * 3, "uint8"), ([[-129, 0]] * 3, "int8"),
                       ([[0, 128]] * 3, "int8"), ([0, 1, 2], "uint8")):
        _refused(r"y_acceptable must hold (uint8|int8) codes of shape \(rows, K\) \+ \(\)", _load, tmp_path,
                 *_exact_case(acc, dtype))
    _refused(r"array 'y_acceptable' has shape \(3, 65\), expected 3 rows", _load, tmp_path,
             *_exact_case(np.zeros((3, loader.MAX_ACCEPTABLE + 1), np.int64)))
    _refused(r"array 'y_acceptable' expected integers, found dtype float64", _load, tmp_path,
             *_exact_case(np.zeros((3, 2))))


def test_the_acceptable_codes_of_a_vector_output_have_its_components(tmp_path):
    meta = _meta(metric="exact", exact=True, outputs={"y": {"dtype": "uint16", "shape": [3, 4]}})
    a = _arrays(y=np.zeros((3, 4), np.uint16), y_tolerance_float32=None, y_tolerance_float64=None)
    a["y_acceptable"] = np.zeros((3, loader.MAX_ACCEPTABLE, 4), np.int64)  # at most 64 codes per component
    assert _load(tmp_path, meta, _npz(a))["y_acceptable"].shape == (3, loader.MAX_ACCEPTABLE, 4)
    a["y_acceptable"] = np.zeros((3, 2, 3), np.int64)
    _refused(r"y_acceptable must hold uint16 codes of shape \(rows, K\) \+ \(4,\), got \(3, 2, 3\)", _load,
             tmp_path, meta, _npz(a))


def test_a_case_file_is_read_only_under_its_sha256_and_size(tmp_path):
    blob = _npz(_arrays())
    (tmp_path / "c.npz").write_bytes(blob)
    _refused(r"^golden: c.npz does not match the sha256 in manifest.json$", loader.load_case_arrays, tmp_path, "c",
             _meta(sha256=hashlib.sha256(blob + b"\0").hexdigest()))
    limit = loader.case_file_limit(_meta())
    # Each array it may hold at most its elements at 8 bytes (text: 4096 bytes a row; an unknown per-row array
    # 1024 values a row) and a 64 KiB header, plus 1 MiB: x, y, tc_id, y's two tolerances and y_float32 of
    # 3 values, four text labels, y_acceptable (unknown to an abs case).
    per_array = 3 * 8 + (1 << 16)
    assert limit == 6 * per_array + 4 * (3 * 4096 + (1 << 16)) + (3 * 1024 * 8 + (1 << 16)) + (1 << 20)
    (tmp_path / "c.npz").write_bytes(b"\0" * (limit + 1))
    _refused(rf"^golden file of c: expected at most {limit} bytes", loader.load_case_arrays, tmp_path, "c", _meta())


def test_load_case_names_the_cases_the_manifest_has(tmp_path):
    blob = _npz(_arrays())
    (tmp_path / "c.npz").write_bytes(blob)
    (tmp_path / "manifest.json").write_text(_with(_meta(sha256=hashlib.sha256(blob).hexdigest())))
    meta, arrays = loader.load_case(tmp_path, "c")
    assert meta["file"] == "c.npz" and sorted(arrays) == sorted(_arrays())
    _refused(r"^case: 'd' is not in .*manifest.json; it has: c$", loader.load_case, tmp_path, "d")


def test_a_results_file_holds_compared_outputs_of_their_shapes_within_its_limit(tmp_path):
    manifest = {"cases": {"c": _meta(), "v": _meta(outputs={"y": {"dtype": "float32", "shape": [3, 4]},
                                                            "z": {"dtype": "float32", "shape": [3]}})}}
    # Every compared output at 8 bytes a value, twice, plus 1 MiB: (3 + 12) values.
    assert loader.results_limit(manifest) == 2 * 8 * (3 + 12) + (1 << 20)
    p = tmp_path / "r.npz"
    np.savez(p, **{"c.y": np.ones(3, np.float64), "v.y": np.ones((3, 4), np.int16)})
    got = loader.load_results(p, manifest)
    assert sorted(got) == ["c.y", "v.y"] and got["v.y"].dtype == np.int16
    np.savez(p, **{"v.z": np.ones(3)})
    _refused(r"^results '.*r.npz': 'v.z' matches no golden case output; known: c.y, v.y$", loader.load_results, p,
             manifest)
    np.savez(p, **{"v.y": np.ones((3, 3))})
    _refused(r"^results '.*': array 'v.y' has shape \(3, 3\), expected \(3, 4\)$", loader.load_results, p, manifest)
    p.write_bytes(b"\0" * (loader.results_limit(manifest) + 1))
    _refused(r"^results: expected at most", loader.load_results, p, manifest)
