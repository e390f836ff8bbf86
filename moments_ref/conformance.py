"""Run a GLSL port on an OpenGL 4.3 compute context against the golden vectors.

``moments-ref conformance --glsl FILE --function NAME --case CASE [--golden DIR]``
wraps the GLSL function ``NAME`` in a compute shader whose buffers follow the
golden case's input and output arrays, uploads the case's inputs, runs one
dispatch, reads the outputs back and compares them with

* the expected values (float64 ground truth, mpmath where the reference has a
  twin): worst absolute error, relative error and float32 ulps per row category,
  gated by the manifest's **float32** tolerance of that category (a GLSL port
  computes in float32);
* the reference's own float32 emulation (``<output>_float32`` in the golden
  file): the same numbers, for information only. A port that agrees with it to a
  few ulps made the same choices as the reference.

Row categories (docs/golden.md): ``random`` and ``edge`` rows gate with the
float32 tolerance; ``stiff`` rows gate only with their own, looser, documented
tolerance and their deviations are always printed, pass or fail. Integer outputs
(packed texels) must match exactly; a ``stiff`` row there is a rounding tie and
also accepts the code the reference computes in the other precision.

Type mapping (golden array -> GLSL), one std430 shader storage buffer each:

=====================  ===========  ==========================================
golden array           GLSL type    upload
=====================  ===========  ==========================================
(n,) float             ``float``    float32 (float64 cases are rounded)
(n, k) float, k = 2..4 ``veck``     float32; vec3 padded to vec4 in the buffer
(n,) uint32            ``uint``     uint32
(n, k) uint16/uint32   ``uveck``    uint32 (uint16 codes widened)
(n,) / (n, k) int      ``int``...   int32
=====================  ===========  ==========================================

A function with one output is called as ``out = NAME(in0, in1, ...)``; with
several outputs as ``NAME(in0, ..., out0, out1)`` (``out`` parameters), in the
manifest's order. The function name need not match the case: ``--function``
names the GLSL function, ``--case`` the golden case.

Source files may use ``#include "file.glsl"`` (resolved relative to the
including file, each file included once), as engines' own shader preprocessors
do; core OpenGL has no include. ``#version`` and ``#extension`` lines are
hoisted; the wrapper uses ``#version 430`` unless the file asks for more.
Compiler messages refer to ``file:line``.

Exit codes of :func:`run_cli`: 0 every row within its tolerance, 1 a tolerance
exceeded (or an output out of range), 2 no OpenGL 4.3 context (with the reason),
or bad usage (unknown case, missing function, a shader that does not compile).

Requirements: ``pip install moderngl`` and an EGL driver; on Debian/Ubuntu
``apt-get install libegl1 libegl-mesa0 libgl1-mesa-dri`` gives Mesa's llvmpipe,
a CPU implementation of OpenGL 4.5 with IEEE-like float32 arithmetic.
"""

from __future__ import annotations

import hashlib
import json
import math
import re
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ._arrays import InputError
from .ports import GLSL_DIR

__all__ = [
    "ContextError",
    "ShaderError",
    "GLSL_DIR",
    "SHIPPED",
    "create_context",
    "get_context",
    "renderer",
    "load_source",
    "defined_functions",
    "shipped_port",
    "glsl_signature",
    "run_glsl",
    "load_case",
    "run_case",
    "ConformanceReport",
    "ulp_distance",
    "run_cli",
    "main",
    "bench_conformance",
]

#: Work-group size of the wrapper (one invocation per golden row).
LOCAL_SIZE = 64
#: Most work groups per dispatch dimension that OpenGL guarantees.
_MAX_GROUPS = 65535
_GATE_DTYPE = "float32"

#: The shipped ports: case prefix -> (file in :data:`GLSL_DIR`, GLSL function).
#: ``run_case`` picks the entry whose prefix the case name starts with.
SHIPPED = {
    "shadow_intensity-lower": ("msm.glsl", "shadow_intensity_lower"),
    "shadow_intensity-upper": ("msm.glsl", "shadow_intensity_upper"),
    "bias_moments-float32": ("msm.glsl", "bias_moments_float32"),
    "bias_moments-unorm16": ("msm.glsl", "bias_moments_unorm16"),
    "to_optimized-": ("msm.glsl", "to_optimized"),
    "from_optimized-": ("msm.glsl", "from_optimized"),
    "decode_unorm16-": ("msm.glsl", "decode_unorm16"),
    "phi-": ("nonlinear.glsl", "phi"),
    "phi_inverse-": ("nonlinear.glsl", "phi_inverse"),
    "psi4-": ("nonlinear.glsl", "psi4"),
    "psi4_inverse-": ("nonlinear.glsl", "psi4_inverse"),
    "shade-": ("nonlinear.glsl", "shade"),
    "pack64-": ("packing.glsl", "pack64"),
    "unpack64-": ("packing.glsl", "unpack64"),
    "pack32-": ("packing.glsl", "pack32"),
    "unpack32-": ("packing.glsl", "unpack32"),
}


class ContextError(RuntimeError):
    """No OpenGL 4.3 compute context could be made; ``str(exc)`` says why."""


class ShaderError(InputError):
    """The GLSL source is unusable: missing function, include or compile error."""


# --------------------------------------------------------------------------
# Context
# --------------------------------------------------------------------------

_CONTEXT = None


def create_context(require=430):
    """A standalone OpenGL context (EGL, no window) of at least version ``require``.

    Raises
    ------
    ContextError
        moderngl missing, no EGL library or driver, or a version below ``require``;
        the message names the cause and the Debian packages to install.
    """
    hint = ("install the Python package 'moderngl' and an EGL driver "
            "(Debian/Ubuntu: apt-get install libegl1 libegl-mesa0 libgl1-mesa-dri)")
    try:
        import moderngl
    except ImportError as exc:
        raise ContextError(f"moderngl is not importable ({exc}); {hint}") from None
    try:
        ctx = moderngl.create_standalone_context(backend="egl", require=require)
    except Exception as exc:  # moderngl raises plain Exception subclasses for EGL failures
        raise ContextError(f"no OpenGL {require // 100}.{require % 100 // 10} context through EGL: "
                           f"{type(exc).__name__}: {exc}; {hint}") from None
    if ctx.version_code < require:
        version = ctx.version_code
        ctx.release()
        raise ContextError(f"the EGL context offers OpenGL {version}, compute shaders need {require}; {hint}")
    return ctx


def get_context():
    """The process-wide context (created on first use, then reused)."""
    global _CONTEXT
    if _CONTEXT is None:
        _CONTEXT = create_context()
    return _CONTEXT


def renderer(ctx):
    """``'llvmpipe (LLVM 15.0.6, 256 bits), OpenGL 4.5 (Core Profile) Mesa 22.3.6'``."""
    info = ctx.info
    return f"{info.get('GL_RENDERER', '?')}, OpenGL {info.get('GL_VERSION', '?')}"


# --------------------------------------------------------------------------
# Source handling
# --------------------------------------------------------------------------


@dataclass
class GLSLSource:
    """A GLSL file with its includes resolved."""

    body: str  # without #version / #extension lines, with #line directives
    version: int
    extensions: list
    files: list  # source-string number -> path

    def describe(self, text):
        """Replace Mesa's ``N:line(col)`` prefixes by ``file:line:col``."""

        def sub(m):
            k = int(m.group(1))
            name = str(self.files[k - 1]) if 0 < k <= len(self.files) else "<wrapper>"
            return f"{name}:{m.group(2)}:{m.group(3)}"

        return re.sub(r"\b(\d+):(\d+)\((\d+)\)", sub, text)


_INCLUDE = re.compile(r'^\s*#\s*include\s+[<"]([^">]+)[">]\s*$')
_VERSION = re.compile(r"^\s*#\s*version\s+(\d+)")
_EXTENSION = re.compile(r"^\s*#\s*extension\b")


def load_source(path):
    """Read a GLSL file, resolving ``#include "file"`` relative to the including file.

    Returns
    -------
    GLSLSource
        Each file is included once (later includes of the same file are dropped,
        like ``#pragma once``); ``#line 1 k`` marks where file ``k`` (1-based)
        begins so that compiler messages can name it.

    Raises
    ------
    ShaderError
        A missing file or include.
    """
    files, lines = [], []
    version, extensions = 430, []

    def visit(p, origin):
        nonlocal version
        p = Path(p).resolve()
        if p in files:
            return
        if not p.is_file():
            raise ShaderError(f"glsl: expected a GLSL file, got {str(p)!r} (not found{origin})")
        files.append(p)
        k = len(files)
        lines.append(f"#line 1 {k}")
        for no, line in enumerate(p.read_text().splitlines(), 1):
            m = _INCLUDE.match(line)
            if m:
                visit(p.parent / m.group(1), f", included from {p.name}:{no}")
                lines.append(f"#line {no + 1} {k}")
                continue
            m = _VERSION.match(line)
            if m:
                version = max(version, int(m.group(1)))
                lines.append("")  # keep the line numbers
                continue
            if _EXTENSION.match(line):
                extensions.append(line.strip())
                lines.append("")
                continue
            lines.append(line)

    visit(path, "")
    return GLSLSource("\n".join(lines) + "\n", version, extensions, files)


def _strip_comments(text):
    text = re.sub(r"/\*.*?\*/", " ", text, flags=re.S)
    return re.sub(r"//[^\n]*", "", text)


_DEF = re.compile(r"\b([A-Za-z_]\w*)\s+([A-Za-z_]\w*)\s*\(([^;{}]*)\)\s*\{")


def defined_functions(body):
    """Names of the functions defined in a GLSL source (for error messages)."""
    return sorted({m.group(2) for m in _DEF.finditer(_strip_comments(body))
                   if m.group(1) not in ("if", "for", "while", "switch", "return", "else")})


# --------------------------------------------------------------------------
# Types and the wrapper shader
# --------------------------------------------------------------------------


@dataclass(frozen=True)
class Slot:
    """One golden array as a GLSL value: name, GLSL type, buffer element type."""

    name: str
    glsl: str  # float, vec4, uint, uvec4 ...
    element: str  # buffer element type (vec3 is padded to vec4)
    components: int
    upload: np.dtype  # float32, uint32 or int32

    @staticmethod
    def of(name, dtype, shape):
        dtype = np.dtype(dtype)
        if len(shape) == 1:
            k = 1
        elif len(shape) == 2 and 2 <= shape[1] <= 4:
            k = shape[1]
        else:
            raise InputError(f"{name}: expected shape (n,) or (n, 2..4) to map to a GLSL type, got {tuple(shape)}")
        if dtype.kind == "f":
            scalar, prefix, up = "float", "vec", np.float32
        elif dtype.kind == "u":
            scalar, prefix, up = "uint", "uvec", np.uint32
        elif dtype.kind in "ib":
            scalar, prefix, up = "int", "ivec", np.int32
        else:
            raise InputError(f"{name}: expected a float or integer array, got dtype {dtype}")
        glsl = scalar if k == 1 else f"{prefix}{k}"
        element = scalar if k == 1 else f"{prefix}{4 if k == 3 else k}"
        return Slot(name, glsl, element, k, np.dtype(up))


def glsl_signature(function, inputs, outputs):
    """The GLSL signature the wrapper calls, e.g. ``float f(vec4 b, float zf)``."""
    args = [f"{s.glsl} {s.name}" for s in inputs]
    if len(outputs) == 1:
        return f"{outputs[0].glsl} {function}({', '.join(args)})"
    args += [f"out {s.glsl} {s.name}" for s in outputs]
    return f"void {function}({', '.join(args)})"


def _wrapper(src: GLSLSource, function, inputs, outputs):
    lines = [f"#version {src.version}", *src.extensions, src.body, "#line 1 0",
             f"layout(local_size_x = {LOCAL_SIZE}) in;"]
    binding = 0
    for s in inputs:
        lines.append(f"layout(std430, binding = {binding}) readonly buffer mr_In_{s.name} "
                     f"{{ {s.element} mr_in_{s.name}[]; }};")
        binding += 1
    for s in outputs:
        lines.append(f"layout(std430, binding = {binding}) writeonly buffer mr_Out_{s.name} "
                     f"{{ {s.element} mr_out_{s.name}[]; }};")
        binding += 1
    lines += ["uniform uint mr_count;", "void main() {",
              f"    uint i = gl_GlobalInvocationID.x + gl_GlobalInvocationID.y * gl_NumWorkGroups.x * {LOCAL_SIZE}u;",
              "    if (i >= mr_count) return;"]

    def load(s):
        return f"mr_in_{s.name}[i]" + (".xyz" if s.components == 3 else "")

    def store(s, value):
        if s.components == 3:
            return f"    mr_out_{s.name}[i] = {s.element}({value}, 0);"
        return f"    mr_out_{s.name}[i] = {value};"

    args = ", ".join(load(s) for s in inputs)
    if len(outputs) == 1:
        lines.append(store(outputs[0], f"{function}({args})"))
    else:
        for s in outputs:
            lines.append(f"    {s.glsl} mr_v_{s.name};")
        call = ", ".join([*(load(s) for s in inputs), *(f"mr_v_{s.name}" for s in outputs)])
        lines.append(f"    {function}({call});")
        lines += [store(s, f"mr_v_{s.name}") for s in outputs]
    lines.append("}")
    return "\n".join(lines) + "\n"


def _as_buffer(arr, slot):
    a = np.asarray(arr)
    if a.dtype.kind == "u" and slot.upload == np.uint32 and a.size and a.max() > np.iinfo(np.uint32).max:
        raise InputError(f"{slot.name}: values do not fit uint32")
    a = a.astype(slot.upload).reshape(len(a), -1)
    if slot.components == 3:
        a = np.concatenate([a, np.zeros((len(a), 1), a.dtype)], axis=1)
    return np.ascontiguousarray(a)


def run_glsl(glsl, function, inputs, outputs, ctx=None):
    """Evaluate a GLSL function once per row on the GPU (or llvmpipe).

    Parameters
    ----------
    glsl : path or GLSLSource
        The file holding ``function`` (includes resolved by :func:`load_source`).
    function : str
        Name of the GLSL function.
    inputs : dict name -> array
        Arrays with a leading row axis, in argument order; their dtypes and shapes
        give the GLSL types (see the module docstring).
    outputs : dict name -> (dtype, shape)
        The outputs, in order: ``float`` outputs come back as float32, unsigned
        ones as uint32, signed as int32; shape ``(n,)`` or ``(n, k)``.
    ctx : moderngl.Context, optional
        Default: :func:`get_context`.

    Returns
    -------
    results : dict name -> array
    timings : dict
        Seconds for ``compile``, ``upload``, ``dispatch`` and ``readback``.

    Raises
    ------
    ShaderError
        The function is not defined or the shader does not compile; the message
        holds the compiler log with file names and the expected signature.
    ContextError
        No context could be made.
    """
    src = glsl if isinstance(glsl, GLSLSource) else load_source(glsl)
    ins = [Slot.of(k, np.asarray(v).dtype, np.shape(v)) for k, v in inputs.items()]
    outs = [Slot.of(k, dt, shape) for k, (dt, shape) in outputs.items()]
    n = len(next(iter(inputs.values())))
    if n == 0:
        raise InputError("inputs: expected at least one row, got 0")
    signature = glsl_signature(function, ins, outs)
    if not re.search(rf"\b{re.escape(function)}\s*\(", _strip_comments(src.body)):
        names = ", ".join(defined_functions(src.body)) or "none"
        raise ShaderError(f"function: {function!r} is not defined in {src.files[0]} "
                          f"(functions defined: {names}); expected signature: {signature}")
    ctx = ctx or get_context()
    timings = {}
    t0 = time.perf_counter()
    try:
        program = ctx.compute_shader(_wrapper(src, function, ins, outs))
    except Exception as exc:
        raise ShaderError(f"the wrapped function does not compile (expected signature: {signature}):\n"
                          f"{src.describe(str(exc)).strip()}") from None
    timings["compile"] = time.perf_counter() - t0
    buffers = []
    try:
        t0 = time.perf_counter()
        for b, s in enumerate(ins):
            buf = ctx.buffer(_as_buffer(inputs[s.name], s).tobytes())
            buf.bind_to_storage_buffer(b)
            buffers.append(buf)
        out_bufs = []
        for b, s in enumerate(outs, start=len(ins)):
            width = 4 if s.components == 3 else s.components
            buf = ctx.buffer(reserve=n * width * 4)
            buf.bind_to_storage_buffer(b)
            buffers.append(buf)
            out_bufs.append(buf)
        ctx.finish()
        timings["upload"] = time.perf_counter() - t0
        program["mr_count"].value = n
        groups = -(-n // LOCAL_SIZE)
        gx = min(groups, _MAX_GROUPS)
        gy = -(-groups // gx)
        t0 = time.perf_counter()
        program.run(group_x=gx, group_y=gy)
        ctx.finish()
        timings["dispatch"] = time.perf_counter() - t0
        t0 = time.perf_counter()
        results = {}
        for s, buf in zip(outs, out_bufs):
            width = 4 if s.components == 3 else s.components
            a = np.frombuffer(buf.read(), dtype=s.upload).reshape(n, width)[:, : s.components]
            results[s.name] = a.reshape(outputs[s.name][1]).copy()
        timings["readback"] = time.perf_counter() - t0
    finally:
        for buf in buffers:
            buf.release()
        program.release()
    return results, timings


# --------------------------------------------------------------------------
# Golden cases
# --------------------------------------------------------------------------


@dataclass
class GoldenCase:
    """One golden case read from disk: manifest entry and arrays."""

    name: str
    meta: dict
    arrays: dict
    source: str  # the folder, or "generated"

    @property
    def inputs(self):
        return {k: self.arrays[k] for k in self.meta["inputs"]}

    @property
    def category(self):
        return self.arrays["category"]


def load_case(case, golden_dir=None):
    """Read ``case`` from ``golden_dir`` (checking its sha256), or generate it.

    Without ``golden_dir`` the case alone is written to a temporary folder with
    :func:`moments_ref.golden.write` and read back.
    """
    from . import golden

    if golden_dir is None:
        if case not in golden.CASES:
            raise InputError(f"case: unknown case {case!r}; known: {', '.join(golden.CASES)}")
        with tempfile.TemporaryDirectory(prefix="moments-ref-golden-") as tmp:
            golden.write(tmp, [case])
            loaded = load_case(case, tmp)
        loaded.source = "generated"
        return loaded
    golden_dir = Path(golden_dir)
    mpath = golden_dir / "manifest.json"
    if not mpath.is_file():
        raise InputError(f"golden: expected a folder with manifest.json, got {str(golden_dir)!r}")
    manifest = json.loads(mpath.read_text())
    if case not in manifest["cases"]:
        raise InputError(f"case: {case!r} is not in {mpath}; it has: {', '.join(manifest['cases'])}")
    meta = manifest["cases"][case]
    blob = (golden_dir / meta["file"]).read_bytes()
    if hashlib.sha256(blob).hexdigest() != meta["sha256"]:
        raise InputError(f"golden: {meta['file']} does not match the sha256 in {mpath}")
    with np.load(golden_dir / meta["file"], allow_pickle=False) as g:
        arrays = {k: g[k] for k in g.files}
    return GoldenCase(case, meta, arrays, str(golden_dir))


def shipped_port(case):
    """``(path, function)`` of the shipped GLSL port for a case name, or None."""
    for prefix, (fname, function) in SHIPPED.items():
        if case.startswith(prefix):
            return GLSL_DIR / fname, function
    return None


# --------------------------------------------------------------------------
# Metrics
# --------------------------------------------------------------------------


def _ordered(x32):
    """float32 -> int64 whose order and differences count float32 values (±0 -> 0)."""
    i = np.asarray(x32, np.float32).view(np.int32).astype(np.int64)
    return np.where(i < 0, -(i & 0x7FFFFFFF), i)


def ulp_distance(got, expected):
    """Number of float32 values between ``got`` (float32) and ``expected`` rounded to float32.

    NaN in either gives ``inf``; a float64 value beyond the float32 range rounds to ±inf.
    """
    g = np.asarray(got, np.float32)
    with np.errstate(over="ignore"):
        e = np.asarray(expected, np.float64).astype(np.float32)
    d = np.abs(_ordered(g) - _ordered(e)).astype(np.float64)
    return np.where(np.isnan(g) | np.isnan(e), np.inf, d)


def _float_metrics(got, expected, n):
    """Per-row worst abs, rel and ulps (over the row's components)."""
    g = np.asarray(got, np.float64).reshape(n, -1)
    e = np.asarray(expected, np.float64).reshape(n, -1)
    with np.errstate(invalid="ignore", divide="ignore"):
        a = np.abs(g - e)
        a = np.where(np.isnan(a), np.inf, a)
        r = np.where(a == 0, 0.0, a / np.abs(e))
    u = ulp_distance(np.asarray(got, np.float32).reshape(n, -1), e)
    return a.max(axis=1), r.max(axis=1), u.max(axis=1)


def _fmt(x):
    if x is None:
        return "-"
    if isinstance(x, float) and (math.isinf(x) or math.isnan(x)):
        return str(x)
    if float(x) == int(x) and abs(x) < 1e6:
        return f"{int(x)}"
    return f"{x:.3g}"


def _arr(x, integer=False):
    a = np.asarray(x)
    if integer:
        if a.dtype.itemsize >= 4 and a.ndim == 0:
            return f"0x{int(a):08x}"
        return np.array2string(a, separator=", ")
    return np.array2string(a.astype(np.float64), precision=9, separator=", ")


# --------------------------------------------------------------------------
# Report
# --------------------------------------------------------------------------


@dataclass
class CategoryResult:
    """Summary of one row category."""

    category: str
    rows: int
    tolerance: float
    failures: int
    worst_abs: float = 0.0
    worst_rel: float = 0.0
    worst_ulps: float = 0.0
    ref_abs: float | None = None
    ref_rel: float | None = None
    ref_ulps: float | None = None
    mismatches: int = 0  # integer outputs: rows differing from the golden code
    ties: int = 0  # integer outputs: rows accepted as the other precision's rounding


@dataclass
class ConformanceReport:
    """Result of :func:`run_case`; ``passed`` and ``format()``."""

    case: str
    function: str
    glsl: str
    renderer: str
    rows: int
    exact: bool
    categories: dict
    worst: list  # dicts: index, category, error, tolerance, got, expected, reference, inputs, comment
    timings: dict
    notes: list = field(default_factory=list)
    components: dict | None = None  # vector outputs: per-component worst ulps / mismatch counts

    @property
    def passed(self):
        return all(c.failures == 0 for c in self.categories.values())

    @property
    def failures(self):
        return sum(c.failures for c in self.categories.values())

    def format(self):
        lines = [f"{'PASS' if self.passed else 'FAIL'}  {self.function} ({self.glsl}) on {self.case}: "
                 f"{self.rows} rows" + ("" if self.passed else f", {self.failures} exceed the tolerance"),
                 f"      renderer: {self.renderer}"]
        lines += [f"      note: {n}" for n in self.notes]
        if self.exact:
            lines.append("      category  rows | mismatches  accepted ties | failures   (integer output: exact)")
            for c in self.categories.values():
                lines.append(f"      {c.category:8} {c.rows:5d} | {c.mismatches:10d}  {c.ties:13d} | {c.failures:8d}")
            if self.components is not None:
                lines.append(f"      rows differing per component: {self.components['mismatch']}")
        else:
            lines.append("      category  rows |  vs expected (float64)       | tolerance  fails |"
                         "  vs reference float32 (info)")
            lines.append("                     |       abs       rel     ulps |                  |"
                         "       abs       rel     ulps")
            for c in self.categories.values():
                lines.append(
                    f"      {c.category:8} {c.rows:5d} | {_fmt(c.worst_abs):>9} {_fmt(c.worst_rel):>9} "
                    f"{_fmt(c.worst_ulps):>8} | {_fmt(c.tolerance):>9} {c.failures:6d} | "
                    f"{_fmt(c.ref_abs):>9} {_fmt(c.ref_rel):>9} {_fmt(c.ref_ulps):>8}")
            if self.components is not None:
                lines.append(f"      worst ulps per component: vs expected {self.components['ulps']}"
                             + (f", vs reference float32 {self.components['ref_ulps']}"
                                if self.components.get("ref_ulps") is not None else ""))
        if self.worst:
            lines.append("      worst rows (stiff rows always shown; gate: error > tolerance):")
        for r in self.worst:
            verdict = "FAIL" if r["error"] > r["tolerance"] else "ok"
            ins = "; ".join(f"{k}={_arr(v, np.asarray(v).dtype.kind in 'ui')}" for k, v in r["inputs"].items())
            integer = self.exact
            head = (f"      {verdict:4} row {r['index']} [{r['category']}] "
                    + (f"got {_arr(r['got'], integer)}, expected {_arr(r['expected'], integer)}"
                       if integer else
                       f"abs {_fmt(r['error'])} (tol {_fmt(r['tolerance'])}), rel {_fmt(r['rel'])}, "
                       f"ulps {_fmt(r['ulps'])}: got {_arr(r['got'])}, expected {_arr(r['expected'])}"))
            if r.get("reference") is not None:
                label = "other-precision code" if integer else "reference float32"
                head += f", {label} {_arr(r['reference'], integer)}"
            lines.append(head)
            lines.append(f"           inputs: {ins}")
            lines.append(f"           ({r['comment']})")
        lines.append("      timings: " + ", ".join(f"{k} {v * 1e3:.2f} ms" for k, v in self.timings.items()))
        return "\n".join(lines)


def _select_worst(category, err, tol, keep):
    """Row indices to print: per category the worst by err/tol; stiff rows always."""
    picked = []
    with np.errstate(divide="ignore", invalid="ignore"):
        score = np.where(tol > 0, err / np.where(tol > 0, tol, 1), np.where(err > 0, np.inf, 0))
    for c in ("random", "edge", "stiff"):
        idx = np.flatnonzero(category == c)
        if not idx.size:
            continue
        order = idx[np.argsort(-score[idx], kind="stable")]
        fails = int((err[idx] > tol[idx]).sum())
        k = keep if fails else (3 if c == "stiff" else 1)
        picked += [int(i) for i in order[: max(k, min(fails, keep))] if c == "stiff" or err[i] > 0 or fails]
    return picked


def _other_precision_codes(case_name, inputs, out_name):
    """Integer outputs of the reference in the precision the golden did not use, or None."""
    from . import golden

    case = golden.CASES.get(case_name)
    if case is None:
        return None
    other = np.float64 if case.dtype == "float32" else np.float32
    cast = {k: (v if k in case.integer_inputs else np.asarray(v).astype(other)) for k, v in inputs.items()}
    out = case.reference(**cast)
    return np.asarray(out[case.outputs.index(out_name)])


def _float32_reference(gc, out_name):
    """The reference's float32 emulation: from the golden file, or computed for float64 cases."""
    key = f"{out_name}_float32"
    if key in gc.arrays:
        return gc.arrays[key]
    from . import golden

    case = golden.CASES.get(gc.name)
    if case is None:
        return None
    cast = {k: (v if k in case.integer_inputs else np.asarray(v).astype(np.float32)) for k, v in gc.inputs.items()}
    out = case.reference(**cast)
    return np.asarray(out[case.outputs.index(out_name)])


def run_case(glsl, function, case, golden_dir=None, ctx=None, worst_rows=5):
    """Run a GLSL function on a golden case and compare; see the module docstring.

    Parameters
    ----------
    glsl : path
        GLSL file (``#include`` allowed).
    function : str
        GLSL function to call.
    case : str
        Golden case name, e.g. ``shadow_intensity-lower-float32``.
    golden_dir : path, optional
        A folder written by ``moments-ref golden``; default: generate the case.
    ctx : moderngl.Context, optional
    worst_rows : int
        Rows to list per failing category.

    Returns
    -------
    ConformanceReport
    """
    gc = load_case(case, golden_dir)
    meta = gc.meta
    category = np.asarray(gc.category).astype(str)
    n = len(category)
    exact = bool(meta["exact"])
    out_specs = {}
    for o in meta["compare"]:
        exp = gc.arrays[o]
        out_specs[o] = (exp.dtype if exact else np.float32, exp.shape)
    ctx = ctx or get_context()
    src = load_source(glsl)
    got, timings = run_glsl(src, function, gc.inputs, out_specs, ctx=ctx)
    tol_table = meta["tolerances"][_GATE_DTYPE]
    tol = np.array([float(tol_table[c]) for c in category])
    notes = []
    if meta["dtype"] == "float64" and any(np.asarray(v).dtype.kind == "f" for v in gc.inputs.values()):
        notes.append("float64 case: inputs rounded to float32 for upload; gated by the manifest's float32 column")
    categories, worst, components = {}, [], None
    if exact:
        err = np.zeros(n)
        ties = np.zeros(n, bool)
        alt_codes = {o: _other_precision_codes(case, gc.inputs, o) for o in meta["compare"]}
        for o in meta["compare"]:
            exp = np.asarray(gc.arrays[o]).astype(np.int64).reshape(n, -1)
            g = np.asarray(got[o]).astype(np.int64).reshape(n, -1)
            differs = (g != exp).any(axis=1)
            alt = alt_codes[o]
            if alt is not None:
                alt_ok = (g == np.asarray(alt).astype(np.int64).reshape(n, -1)).all(axis=1)
                # A stiff row is a rounding tie; a float64 case's codes are float64
                # roundings that a float32 port need not reproduce.
                accept = alt_ok & differs & ((category == "stiff") | (meta["dtype"] == "float64"))
                ties |= accept
                differs &= ~accept
            err = np.maximum(err, np.where(differs, np.abs(g - exp).max(axis=1), 0).astype(np.float64))
        for c in ("random", "stiff", "edge"):
            sel = category == c
            if sel.any():
                categories[c] = CategoryResult(c, int(sel.sum()), float(tol_table[c]), int((err[sel] > tol[sel]).sum()),
                                               worst_abs=float(err[sel].max()),
                                               mismatches=int(((err > 0) | ties)[sel].sum()), ties=int(ties[sel].sum()))
        picked = [int(i) for i in np.flatnonzero(err > tol)[:worst_rows * 3]]
        picked += [int(i) for i in np.flatnonzero(ties)[:3]]
        for i in picked:
            o = meta["compare"][0]
            worst.append({"index": i, "category": category[i], "error": float(err[i]), "tolerance": float(tol[i]),
                          "got": got[o][i], "expected": gc.arrays[o][i],
                          "reference": None if alt_codes[o] is None else alt_codes[o][i],
                          "inputs": {k: v[i] for k, v in gc.inputs.items()}, "comment": str(gc.arrays["comment"][i])})
        o = meta["compare"][0]
        if np.ndim(gc.arrays[o]) == 2:
            diff = np.asarray(got[o]).astype(np.int64) != np.asarray(gc.arrays[o]).astype(np.int64)
            components = {"mismatch": [int(x) for x in (diff & ~ties[:, None]).sum(axis=0)]}
    else:
        err = np.zeros(n)
        rel = np.zeros(n)
        ulp = np.zeros(n)
        rerr = rrel = rulp = None
        for o in meta["compare"]:
            a, r, u = _float_metrics(got[o], gc.arrays[o], n)
            err, rel, ulp = np.maximum(err, a), np.maximum(rel, r), np.maximum(ulp, u)
            ref = _float32_reference(gc, o)
            if ref is not None:
                ra, rr, ru = _float_metrics(got[o], ref, n)
                rerr = ra if rerr is None else np.maximum(rerr, ra)
                rrel = rr if rrel is None else np.maximum(rrel, rr)
                rulp = ru if rulp is None else np.maximum(rulp, ru)
        for c in ("random", "stiff", "edge"):
            sel = category == c
            if not sel.any():
                continue
            categories[c] = CategoryResult(
                c, int(sel.sum()), float(tol_table[c]), int((err[sel] > tol[sel]).sum()),
                float(err[sel].max()), float(rel[sel].max()), float(ulp[sel].max()),
                None if rerr is None else float(rerr[sel].max()),
                None if rrel is None else float(rrel[sel].max()),
                None if rulp is None else float(rulp[sel].max()))
        o = meta["compare"][0]
        ref0 = _float32_reference(gc, o)
        if np.ndim(gc.arrays[o]) == 2:
            def per_component(ref):
                return "[" + ", ".join(_fmt(float(x)) for x in ulp_distance(got[o], ref).max(axis=0)) + "]"

            components = {"ulps": per_component(gc.arrays[o]),
                          "ref_ulps": None if ref0 is None else per_component(ref0)}
        for i in _select_worst(category, err, tol, worst_rows):
            worst.append({"index": i, "category": category[i], "error": float(err[i]), "tolerance": float(tol[i]),
                          "rel": float(rel[i]), "ulps": float(ulp[i]),
                          "got": got[o][i], "expected": gc.arrays[o][i],
                          "reference": None if ref0 is None else ref0[i],
                          "inputs": {k: v[i] for k, v in gc.inputs.items()}, "comment": str(gc.arrays["comment"][i])})
    return ConformanceReport(case, function, str(glsl), renderer(ctx), n, exact, categories, worst, timings, notes,
                             components)


# --------------------------------------------------------------------------
# Command line and benchmark
# --------------------------------------------------------------------------


def _resolve_glsl(glsl):
    """A path as given, or the name of a shipped port (``msm.glsl``) when no such file exists."""
    p = Path(glsl)
    if not p.exists() and (GLSL_DIR / p.name).is_file() and p.parent == Path("."):
        return GLSL_DIR / p.name
    return p


def run_cli(glsl, function, case, golden_dir=None, out=None, err=None):
    """``moments-ref conformance``: run, print the report, return the exit code.

    Returns
    -------
    int
        0 every row within its tolerance; 1 a tolerance exceeded; 2 no OpenGL 4.3
        context (reason on stderr) or bad usage (unknown case, missing function,
        compile error: reason on stderr).
    """
    out = out or sys.stdout
    err = err or sys.stderr
    try:
        ctx = get_context()
    except ContextError as exc:
        print(f"moments-ref conformance: {exc}", file=err)
        return 2
    try:
        report = run_case(_resolve_glsl(glsl), function, case, golden_dir, ctx=ctx)
    except InputError as exc:
        print(f"moments-ref conformance: {exc}", file=err)
        return 2
    print(report.format(), file=out)
    return 0 if report.passed else 1


def main(args):
    """Entry for the CLI: ``args`` has ``glsl``, ``function``, ``case`` and ``golden`` (or None)."""
    return run_cli(args.glsl, args.function, args.case, getattr(args, "golden", None))


def bench_conformance(cases=None, repeat=3, ctx=None):
    """Time the shipped ports on their golden cases: upload, dispatch, readback.

    Parameters
    ----------
    cases : iterable of str, optional
        Case names (default: the float32 case of every shipped port).
    repeat : int
        Runs per case; the best time of each phase is kept.

    Returns
    -------
    list of dict
        Per case ``case``, ``function``, ``rows``, ``compile_s``, ``upload_s``,
        ``dispatch_s``, ``readback_s`` (seconds, best of ``repeat``) and
        ``renderer``. Raises :class:`ContextError` without a context.
    """
    from . import golden

    names = list(cases) if cases is not None else [
        n for n in golden.CASES if n.endswith("-float32") and shipped_port(n) is not None]
    ctx = ctx or get_context()
    rows = []
    with tempfile.TemporaryDirectory(prefix="moments-ref-bench-") as tmp:
        golden.write(tmp, names)
        for name in names:
            port = shipped_port(name)
            if port is None:
                raise InputError(f"cases: no shipped GLSL port for {name!r}")
            path, function = port
            gc = load_case(name, tmp)
            src = load_source(path)
            specs = {o: ((gc.arrays[o].dtype if gc.meta["exact"] else np.float32), gc.arrays[o].shape)
                     for o in gc.meta["compare"]}
            best = {}
            for _ in range(max(1, repeat)):
                _, t = run_glsl(src, function, gc.inputs, specs, ctx=ctx)
                for k, v in t.items():
                    best[k] = min(best.get(k, math.inf), v)
            rows.append({"case": name, "function": function, "rows": len(gc.category),
                         **{f"{k}_s": v for k, v in best.items()}, "renderer": renderer(ctx)})
    return rows


def summary_markdown(dtypes=("float32", "float64"), golden_dir=None, ctx=None):
    """Run every shipped port on every golden case it covers; a markdown table of the results.

    ``moments-ref conformance --all --out docs/`` writes it to ``docs/conformance.md``
    (docs/ports.md refers to it), so the measured numbers are regenerated, never typed.
    """
    from . import golden

    ctx = ctx or get_context()
    lines = ["# Conformance of the shipped GLSL ports", "",
             "Generated by `moments-ref conformance --all --out docs/`; do not edit by hand. Each shipped port",
             "(`moments_ref/ports/glsl/`) runs on every golden case it covers; per row category the worst",
             "absolute error against the expected values with the case's float32 tolerance in parentheses",
             "(integer outputs: rows differing from the golden code, and rounding ties accepted), and the",
             "worst float32 ulps to this reference's own float32 emulation on random rows.", ""]
    renderer = None
    body = ["| case | function | random | edge | stiff | ulps to reference (random) | result |",
            "|---|---|---|---|---|---|---|"]
    for name in golden.CASES:
        if not name.endswith(tuple(f"-{d}" for d in dtypes)):
            continue
        port = shipped_port(name)
        if port is None:
            continue
        rep = run_case(port[0], port[1], name, golden_dir=golden_dir, ctx=ctx)
        renderer = rep.renderer
        cells = []
        for cat in ("random", "edge", "stiff"):
            c = rep.categories.get(cat)
            if c is None or c.rows == 0:
                cells.append("–")
            elif rep.exact:
                cells.append(f"{c.mismatches} differ, {c.ties} ties ({c.rows} rows)")
            else:
                cells.append(f"{_fmt(c.worst_abs)} ({_fmt(c.tolerance)})")
        rnd = rep.categories.get("random")
        ulps = "–" if rep.exact or rnd is None or rnd.ref_ulps is None else _fmt(rnd.ref_ulps)
        body.append(f"| {name} | `{port[1]}` | {' | '.join(cells)} | {ulps} | {'pass' if rep.passed else 'FAIL'} |")
    lines += [f"Renderer: {renderer}.", ""] + body
    return "\n".join(lines) + "\n"
