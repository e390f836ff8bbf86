"""The one strict reader of golden folders and results files: ``verify``, ``conformance`` and ``oracle`` use it.

Golden folders and results files come from other people: they are read only
after every check that can be made without reading them, and nothing is
decompressed or allocated before its size is known to be what the manifest
implies.

``manifest.json`` (:func:`load_manifest`): a regular file (no link, FIFO or
device) of at most :data:`MAX_MANIFEST` bytes, UTF-8 JSON nested at most
:data:`MAX_JSON_DEPTH` deep (counted before parsing), ``schema_version`` equal to
:data:`~moments_ref.golden.writer.SCHEMA_VERSION`, and per case (:func:`check_entry`):
a plain case name, a file name inside the folder, ``dtype`` float32 or float64,
``metric`` abs, ulps or exact (``exact`` saying the same), an integer ``count`` in
[1, :data:`MAX_ROWS`], inputs and outputs with numeric dtypes and integer shapes
(at most :data:`MAX_ELEMENTS` elements each; the outputs' first axis is ``count``;
the inputs' is not checked: those of kernel cases are whole maps), the
compared outputs of the metric's kind, a finite ``value_range`` with lo ≤ hi,
and a sha256 of 64 hex digits.

A case file (:func:`load_case_arrays`) and a results file (:func:`load_results`):
a regular file within the size the shapes imply (the case file with its
sha256), a zip archive read through its directory first: only stored or deflated
members (the methods ``np.savez`` and ``np.savez_compressed`` use; a bzip2 or
LZMA member decompresses without a bound), each an ``.npy`` of a known name
whose declared uncompressed size fits its expected shape, the sum within
:func:`~moments_ref._arrays.max_memory`; then each member's ``.npy`` header
before its data: a numeric or text dtype (never objects), the shape the
manifest states. The arrays of a case are then checked as the comparator needs
them: tolerances positive and never NaN (``+inf`` marks a row held only to a
finite value in range), finite expected values, categories and results from the
known sets, acceptable codes that the output's integer dtype can hold.

Anything else raises :class:`~moments_ref.InputError` with one line naming the
file, the case, the key or the array, and the first offending row.
"""

from __future__ import annotations

import hashlib
import io
import json
import os
import re
import stat
import zipfile
import zlib
from pathlib import Path

import numpy as np

from .._arrays import InputError, brief, check_memory
from .._io import INCOMPLETE
from .values import check_case_values
from .writer import SCHEMA_VERSION

__all__ = ["MAX_MANIFEST", "MAX_JSON_DEPTH", "MAX_ROWS", "MAX_ELEMENTS", "read_regular", "parse_json", "read_npz",
           "load_manifest",
           "check_entry", "load_case_arrays", "load_case", "load_results", "results_limit"]

#: Largest manifest accepted (bytes).
MAX_MANIFEST = 16 << 20
#: Deepest nesting of objects and arrays in a manifest.
MAX_JSON_DEPTH = 32
#: Most rows a golden case may have (the shipped cases have at most a few hundred).
MAX_ROWS = 1 << 20
#: Most elements of one array of a case.
MAX_ELEMENTS = 1 << 26
#: Most acceptable codes per row (rounding ties).
MAX_ACCEPTABLE = 64
#: Bytes of an ``.npy`` header at most (NumPy's own default limit is 10,000).
_HEADER = 1 << 16
_ENTRY_KEYS = ("file", "compare", "inputs", "outputs", "dtype", "metric", "exact", "count", "sha256")
_LABELS = ("category", "comment", "flags", "result")  # text per row
_NAME = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.+-]{0,127}")
_JSON_TOKENS = re.compile(r'"(?:[^"\\]|\\.)*"|[\[\]{}]')


def read_regular(path, limit, what):
    """The bytes of ``path`` if it is a regular file (not a link) of at most ``limit`` bytes."""
    path = Path(path)
    try:
        st = os.lstat(path)
    except OSError:
        raise InputError(f"{what}: expected a file, got {str(path)!r} (not found)") from None
    if stat.S_ISLNK(st.st_mode) or not stat.S_ISREG(st.st_mode):
        raise InputError(f"{what}: expected a regular file, got {str(path)!r} (a link, device, FIFO or folder)")
    if st.st_size > limit:
        raise InputError(f"{what}: expected at most {limit} bytes, got {str(path)!r} with {st.st_size} bytes")
    flags = os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_NONBLOCK", 0)
    try:
        fd = os.open(path, flags)
    except OSError as exc:
        raise InputError(f"{what}: could not open {str(path)!r}: {exc.strerror}") from None
    with os.fdopen(fd, "rb") as f:
        if not stat.S_ISREG(os.fstat(f.fileno()).st_mode):
            raise InputError(f"{what}: expected a regular file, got {str(path)!r}")
        data = f.read(limit + 1)
    if len(data) > limit:  # it grew since the lstat, or its size lies (procfs)
        raise InputError(f"{what}: expected at most {limit} bytes, got {str(path)!r} with more than its stated "
                         f"{st.st_size}")
    return data


def parse_json(blob, what):
    """The JSON document ``blob`` (UTF-8 bytes), nested at most :data:`MAX_JSON_DEPTH` deep."""
    try:
        text = blob.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise InputError(f"{what}: expected UTF-8 JSON, got byte {blob[exc.start]:#04x} at offset {exc.start}") from None
    depth = 0
    for m in _JSON_TOKENS.finditer(text):
        tok = m.group()
        if tok in "[{":
            depth += 1
            if depth > MAX_JSON_DEPTH:
                raise InputError(f"{what}: objects or arrays nested more than {MAX_JSON_DEPTH} deep "
                                 f"(offset {m.start()})")
        elif tok in "]}":
            depth -= 1
    try:
        return json.loads(text)
    except (ValueError, RecursionError) as exc:  # JSONDecodeError, an integer of over 4300 digits
        raise InputError(f"{what}: expected JSON, could not parse it: {str(exc)[:100]}") from None


def load_manifest(golden_dir):
    """The parsed and checked ``manifest.json`` of ``golden_dir`` (module docstring)."""
    golden_dir = Path(golden_dir)
    if not golden_dir.is_dir():
        raise InputError(f"golden_dir: expected a folder with manifest.json, got {str(golden_dir)!r}")
    if os.path.lexists(golden_dir / INCOMPLETE):
        raise InputError(f"golden_dir: {str(golden_dir)!r} is incomplete: its writing was interrupted or is under "
                         f"way ({INCOMPLETE} marks it); rerun moments-ref golden --out on it")
    manifest = parse_json(read_regular(golden_dir / "manifest.json", MAX_MANIFEST, "golden_dir"), "manifest")
    if not isinstance(manifest, dict) or not isinstance(manifest.get("cases"), dict):
        raise InputError("manifest: expected an object with a 'cases' object")
    version = manifest.get("schema_version")
    if isinstance(version, bool) or version != SCHEMA_VERSION:
        raise InputError(f"manifest: expected schema_version {SCHEMA_VERSION}, got {brief(version)} "
                         "(regenerate with 'moments-ref golden')")
    if not manifest["cases"]:
        raise InputError("manifest: 'cases' is empty")
    for name, meta in manifest["cases"].items():
        check_entry(name, meta)
    return manifest


def _is_int(v):
    return isinstance(v, int) and not isinstance(v, bool)


def _is_number(v):
    """A finite JSON number (an integer beyond 1e300 in magnitude, near float64's end, is not one)."""
    return (_is_int(v) and abs(v) <= 1e300) or (isinstance(v, float) and np.isfinite(v))


def _spec(where, spec, count, rows=True):
    """An input's or output's ``{dtype, shape}``: a numeric dtype and an integer shape, starting with ``count``
    for ``rows`` (outputs; inputs too except those of kernel cases, which hold whole maps or views)."""
    if not isinstance(spec, dict) or "shape" not in spec or "dtype" not in spec:
        raise InputError(f"{where}: expected {{'dtype': ..., 'shape': [...]}}, got {brief(spec)}")
    try:
        dt = np.dtype(spec["dtype"]) if isinstance(spec["dtype"], str) else None
    except (TypeError, ValueError):
        dt = None
    if dt is None or dt.kind not in "biuf" or dt.itemsize > 8:
        raise InputError(f"{where}.dtype: expected a numeric dtype name (float32, uint16, ...), "
                         f"got {brief(spec['dtype'])}")
    shape = spec["shape"]
    if (not isinstance(shape, list) or not 1 <= len(shape) <= 4
            or not all(_is_int(s) and 0 <= s <= MAX_ELEMENTS for s in shape)
            or (rows and shape[0] != count) or np.prod(shape, dtype=np.float64) > MAX_ELEMENTS):
        start = f" starting with the count {count}" if rows else ""
        raise InputError(f"{where}.shape: expected a list of 1 to 4 integers{start}, at most {MAX_ELEMENTS} "
                         f"elements, got {brief(shape)}")
    return dt


def check_entry(name, meta):
    """Raise :class:`InputError` unless ``meta`` is a well-formed manifest entry of case ``name``."""
    if not isinstance(name, str) or not _NAME.fullmatch(name):
        raise InputError(f"manifest: expected case names of letters, digits and _.+-, got {brief(name)}")
    where = f"manifest: case {name!r}"
    if not isinstance(meta, dict):
        raise InputError(f"{where}: expected an object, got {type(meta).__name__}")
    missing = [k for k in _ENTRY_KEYS if k not in meta]
    if missing:
        raise InputError(f"manifest: case {name!r} lacks the key {missing[0]!r} (expected {', '.join(_ENTRY_KEYS)})")
    f = meta["file"]
    if (not isinstance(f, str) or not f or f in (".", "..") or "/" in f or "\\" in f or os.path.isabs(f)
            or "\0" in f):
        raise InputError(f"{where}: expected a file name inside the golden folder, got {f!r}")
    if meta["dtype"] not in ("float32", "float64"):
        raise InputError(f"{where}: dtype: expected float32 or float64, got {brief(meta['dtype'])}")
    if meta["metric"] not in ("abs", "ulps", "exact") or meta["exact"] is not (meta["metric"] == "exact"):
        raise InputError(f"{where}: metric: expected abs, ulps or exact (and 'exact' saying the same), "
                         f"got {brief(meta['metric'])}")
    count = meta["count"]
    if not _is_int(count) or not 1 <= count <= MAX_ROWS:
        raise InputError(f"{where}: count: expected an integer in [1, {MAX_ROWS}], got {brief(count)}")
    for k in ("inputs", "outputs"):
        if not isinstance(meta[k], dict) or not meta[k] or not all(isinstance(x, str) and _NAME.fullmatch(x)
                                                                   for x in meta[k]):
            raise InputError(f"{where}: expected {k!r} as a non-empty object name -> {{dtype, shape}}")
        for x, spec in meta[k].items():
            _spec(f"{where}: {k}.{x}", spec, count, rows=k == "outputs")
    _check_compare(where, meta)
    rng = meta.get("value_range")
    if rng is not None and (not isinstance(rng, list) or len(rng) != 2 or not all(map(_is_number, rng))
                            or rng[0] > rng[1]):
        raise InputError(f"{where}: value_range: expected null or [lo, hi], finite numbers with lo <= hi, "
                         f"got {brief(rng)}")
    sha = meta["sha256"]
    if not isinstance(sha, str) or not re.fullmatch(r"[0-9a-f]{64}", sha):
        raise InputError(f"{where}: sha256: expected 64 hexadecimal digits, got {brief(sha)}")
    if "kwargs" in meta and not isinstance(meta["kwargs"], dict):
        raise InputError(f"{where}: kwargs: expected an object, got {brief(meta['kwargs'])}")
    if "input_order" in meta and (not isinstance(meta["input_order"], list)
                                  or sorted(map(str, meta["input_order"])) != sorted(meta["inputs"])):
        raise InputError(f"{where}: input_order: expected the input names {sorted(meta['inputs'])}, "
                         f"got {brief(meta['input_order'])}")


def _check_compare(where, meta):
    cmp = meta["compare"]
    if (not isinstance(cmp, list) or not cmp or len(set(map(str, cmp))) != len(cmp)
            or not all(isinstance(o, str) and o in meta["outputs"] for o in cmp)):
        raise InputError(f"{where}: 'compare' must list outputs of the case (each once), got {brief(cmp)}")
    kind = "iu" if meta["metric"] == "exact" else "f"
    for o in cmp:
        if np.dtype(meta["outputs"][o]["dtype"]).kind not in kind:
            raise InputError(f"{where}: output {o!r} has dtype {meta['outputs'][o]['dtype']}, but metric "
                             f"{meta['metric']!r} compares {'integer codes' if kind == 'iu' else 'floats'}")


# ---------------------------------------------------------------------------
# .npz archives: directory first, then each header, then the data


class _Expect:
    """What one member of an archive may be: ``kind`` (dtype kinds), ``shape`` or ``rows`` and a size bound."""

    def __init__(self, kind, shape=None, rows=None, dtype=None, row_elements=None, itemsize=8):
        """Either ``shape``, or ``rows`` with at most ``row_elements`` values a row."""
        self.kind, self.shape, self.rows, self.dtype = kind, shape, rows, dtype
        self.row_elements = row_elements
        elements = int(np.prod(shape, dtype=np.int64)) if shape is not None else rows * row_elements
        self.max_bytes = elements * itemsize + _HEADER

    def refusal(self, dtype, shape):
        """Why a member with this ``.npy`` header is refused, or None."""
        if dtype.hasobject or dtype.kind not in self.kind or (dtype.kind != "U" and dtype.itemsize > 8):
            return f"expected {self._kinds()}, found dtype {dtype}"
        if self.dtype is not None and dtype != self.dtype:
            return f"expected dtype {self.dtype}, found dtype {dtype}"
        if self.shape is not None and tuple(shape) != tuple(self.shape):
            return f"has shape {tuple(shape)}, expected {tuple(self.shape)}"
        if self.shape is None and (len(shape) == 0 or shape[0] != self.rows or len(shape) > 4
                                   or np.prod(shape[1:], dtype=np.int64) > self.row_elements):
            return f"has shape {tuple(shape)}, expected {self.rows} rows"
        if np.prod(shape, dtype=np.float64) * dtype.itemsize > self.max_bytes:
            return f"holds {tuple(shape)} values of {dtype.itemsize} bytes, more than expected"
        return None

    def _kinds(self):
        return " or ".join({"f": "floats", "i": "integers", "u": "integers", "b": "booleans", "U": "text"}[k]
                           for k in dict.fromkeys(self.kind.replace("u", "i")))


def read_npz(blob, what, expect):
    """``{name: array}`` of the ``.npz`` bytes ``blob``; ``expect(name)`` is the member's :class:`_Expect` (or an
    object with its ``max_bytes`` and ``refusal(dtype, shape)``) or a message why the name is refused.

    Nothing is decompressed before every member's declared size is checked, and no pickle is read."""
    try:
        zf = zipfile.ZipFile(io.BytesIO(blob))
        infos = zf.infolist()
    except (zipfile.BadZipFile, zipfile.LargeZipFile, OSError, ValueError, EOFError) as exc:
        raise InputError(f"{what}: expected an .npz (zip) archive, could not read its directory: {exc}") from None
    plan, total = [], 0
    for info in infos:
        key = info.filename[:-4] if info.filename.endswith(".npy") else None
        exp = expect(key) if key is not None else f"{info.filename!r} is not an .npy member"
        if isinstance(exp, str):
            raise InputError(f"{what}: {exp}")
        if info.flag_bits & 0x1:
            raise InputError(f"{what}: array {key!r} is encrypted (zip flag bit 0); expected a plain .npz member")
        if info.compress_type not in (zipfile.ZIP_STORED, zipfile.ZIP_DEFLATED):
            raise InputError(f"{what}: array {key!r} is compressed with method {info.compress_type}; expected "
                             "stored or deflated (np.savez, np.savez_compressed)")
        if info.file_size > exp.max_bytes:
            raise InputError(f"{what}: array {key!r} declares {info.file_size} bytes uncompressed, more than its "
                             f"expected shape allows ({exp.max_bytes}); not decompressed")
        plan.append((info, key, exp))
        total += info.file_size
    if len({key for _, key, _ in plan}) != len(plan):
        raise InputError(f"{what}: an array name occurs twice in the archive")
    check_memory(total, f"{what} ({len(plan)} arrays, {total} bytes uncompressed)")
    try:
        return {key: _read_member(zf, info, key, exp, what) for info, key, exp in plan}
    except (zipfile.BadZipFile, zlib.error, OSError, EOFError, ValueError, NotImplementedError, RuntimeError) as exc:
        if isinstance(exc, InputError):
            raise
        raise InputError(f"{what}: a corrupt or truncated array in the archive: {str(exc)[:100]}") from None


def _read_member(zf, info, key, exp, what):
    with zf.open(info) as f:
        version = np.lib.format.read_magic(f)
        if version == (1, 0):
            shape, fortran, dtype = np.lib.format.read_array_header_1_0(f, max_header_size=_HEADER)
        elif version == (2, 0):
            shape, fortran, dtype = np.lib.format.read_array_header_2_0(f, max_header_size=_HEADER)
        else:
            raise InputError(f"{what}: array {key!r} is .npy version {version}; expected 1.0 or 2.0")
        why = exp.refusal(dtype, shape)
        if why:
            raise InputError(f"{what}: array {key!r} {why}")
        nbytes = int(np.prod(shape, dtype=np.int64)) * dtype.itemsize
        if nbytes != info.file_size - f.tell():
            raise InputError(f"{what}: array {key!r} holds {info.file_size - f.tell()} bytes of data, its header "
                             f"says {nbytes}")
        data = bytearray(f.read(nbytes))  # exactly nbytes, or zipfile raises (a short or corrupt member)
    return np.frombuffer(data, dtype).reshape(shape, order="F" if fortran else "C")


# ---------------------------------------------------------------------------
# golden case files


def _case_expect(meta):
    """The :class:`_Expect` of each array name a case file may hold (unknown names: per-row arrays)."""
    n = meta["count"]
    known = {}
    for group in ("inputs", "outputs"):
        for k, spec in meta[group].items():
            known[k] = _Expect("biuf", shape=spec["shape"], dtype=np.dtype(spec["dtype"]))
    for o in meta["compare"]:
        shape = meta["outputs"][o]["shape"]
        if meta["metric"] == "exact":
            per_row = MAX_ACCEPTABLE * int(np.prod(shape[1:], dtype=np.int64))
            known[f"{o}_acceptable"] = _Expect("iu", rows=n, row_elements=per_row)
        else:
            for dt in ("float32", "float64"):
                known[f"{o}_tolerance_{dt}"] = _Expect("f", shape=shape)
            known[f"{o}_float32"] = _Expect("f", shape=shape)
    known.update({k: _Expect("U", rows=n, row_elements=1, itemsize=4096) for k in _LABELS})
    known["tc_id"] = _Expect("iu", shape=[n])
    return lambda key: known.get(key) or _Expect("biufU", rows=n, row_elements=1024, itemsize=8)


def case_file_limit(meta):
    """Bytes a case file may have at most, from the manifest's shapes."""
    expect = _case_expect(meta)
    names = (list(meta["inputs"]) + list(meta["outputs"]) + list(_LABELS) + ["tc_id"]
             + [f"{o}_{s}" for o in meta["compare"] for s in ("acceptable", "tolerance_float32",
                                                               "tolerance_float64", "float32")])
    return sum(expect(k).max_bytes for k in names) + (1 << 20)


def load_case_arrays(golden_dir, name, meta):
    """The arrays of case ``name``'s file, after the file, sha256, archive and value checks (module docstring)."""
    check_entry(name, meta)
    what = f"golden file {meta['file']}"
    blob = read_regular(Path(golden_dir) / meta["file"], case_file_limit(meta), f"golden file of {name}")
    if hashlib.sha256(blob).hexdigest() != meta["sha256"]:
        raise InputError(f"golden: {meta['file']} does not match the sha256 in manifest.json")
    arrays = read_npz(blob, what, _case_expect(meta))
    check_case_values(meta, arrays, what)
    return arrays


def load_case(golden_dir, case):
    """``(manifest entry, arrays)`` of ``case`` in ``golden_dir``, both checked; the case must be in the manifest."""
    manifest = load_manifest(golden_dir)
    if case not in manifest["cases"]:
        raise InputError(f"case: {case!r} is not in {Path(golden_dir) / 'manifest.json'}; it has: "
                         f"{', '.join(manifest['cases'])}")
    meta = manifest["cases"][case]
    return meta, load_case_arrays(golden_dir, case, meta)


# ---------------------------------------------------------------------------
# results files


def results_limit(manifest):
    """Bytes a results file may have: every compared output at 8 bytes a value, twice, plus 1 MiB."""
    total = sum(8 * int(np.prod(meta["outputs"][o]["shape"], dtype=np.int64))
                for meta in manifest["cases"].values() for o in meta["compare"])
    return 2 * total + (1 << 20)


def load_results(path, manifest):
    """``{"<case>.<output>": array}`` of a port's results ``.npz``, every array a compared output of its shape.

    Integer or float arrays only (the comparator judges their dtype further); a
    name that matches no case output is refused with the known names.
    """
    known = {f"{n}.{o}": meta["outputs"][o]["shape"] for n, meta in manifest["cases"].items()
             for o in meta["compare"]}

    def expect(key):
        if key not in known:
            return (f"{key!r} matches no golden case output; known: {', '.join(sorted(known))}")
        return _Expect("biuf", shape=known[key])

    blob = read_regular(path, results_limit(manifest), "results")
    return read_npz(blob, f"results {str(path)!r}", expect)
