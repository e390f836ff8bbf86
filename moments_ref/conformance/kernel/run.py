"""Run a user's compute shader, unchanged, on a kernel case on both drivers.

=========  ==============================================  ==========================================
language   OpenGL (llvmpipe)                               Vulkan (lavapipe)
=========  ==============================================  ==========================================
GLSL       moderngl compiles the file (entry ``main``)     glslang → SPIR-V → wgpu
HLSL       glslang → SPIR-V → SPIRV-Cross GLSL → moderngl   glslang → SPIR-V → wgpu
WGSL       wgpu's OpenGL adapter                           wgpu
Slang      Slang → GLSL → glslang → SPIRV-Cross → moderngl  Slang → GLSL → glslang → SPIR-V → wgpu
=========  ==============================================  ==========================================

Bindings and work-group size come from reflection (:mod:`.reflect`), are matched
to the case's contract (:mod:`.bind`, :mod:`.contract`) before anything runs, and
the job runs in the driver process under the watchdog (:mod:`.._supervisor`), as
the function harness's dispatches do.

References
----------
.. [1] VWSS: Adam Marrs, Benjamin Watson and Christopher Healey. 2018. *View-warped Multi-view Soft
       Shadowing for Local Area Lights*. Journal of Computer Graphics Techniques (JCGT) 7, 3, 1–28.
       http://jcgt.org/published/0007/03/01/
.. [2] HPG17: Christoph Peters. 2017. *Non-Linearly Quantized Moment Shadow Maps*. In Proceedings
       of High Performance Graphics (HPG '17). ACM. The non-linear quantization Φ, Ψ4, Algorithms
       1–3, the texel formats and the compute shader of §4.1.
"""

from __future__ import annotations

import hashlib
import shutil
import time
from dataclasses import dataclass

import numpy as np

from ..._arrays import InputError
from .. import _supervisor
from .._errors import ContextError
from .._run import language_of, parse_adapter
from ..languages import require
from .._source import ShaderError, load_source, one_line_errors
from .._supervisor import CompileFailed, DriverDied, DriverError, DriverTimeout, watchdog
from . import _spirv, trace
from ._job import POISON, Bind, Job, Output
from .bind import match
from .declared import with_cell
from .layout import buffer_words, check_layout, element_bytes
from .contract import BLOCK, contract, dispatches
from .reflect import from_spirv, from_wgsl
from .verdict import DriverRun, KernelReport, judge

__all__ = ["KERNEL_DRIVERS", "KernelReport", "run_kernel", "prepare", "Prepared", "numpy_times", "shared_memory",
           "output_spec", "bind_list", "execute"]

KERNEL_DRIVERS = ("gl", "vulkan")
_CACHE = {}
#: Why WGSL kernels with a multisampled texture input do not run on wgpu's OpenGL adapter.
GL_MULTISAMPLE = ("wgpu's OpenGL back end cannot read a multisampled texture in a compute shader (measured with wgpu "
                  "0.32 on llvmpipe: textureLoad of a multisampled depth texture is refused by its GLSL writer, the "
                  "same texture through texture_multisampled_2d<f32> reads 0, and R32Float cannot be multisampled "
                  "there); the kernel runs on Vulkan, or on OpenGL with a storage-buffer input")


@dataclass
class Prepared:
    """A kernel compiled for one driver: the code the driver process gets, and what it declares."""

    driver: str
    adapter: str | None
    backend: str
    code: object
    entry: str
    interface: object
    toolchain: str
    source: object = None  # ShaderSource of GLSL/WGSL (names of #line strings for messages)


def _cached(key, make):
    k = hashlib.sha256(repr(key).encode()).hexdigest()
    if k not in _CACHE:
        _CACHE[k] = make()
    return _CACHE[k]


def _load(path, language, options):
    """The kernel's source with its includes resolved and the CLI's ``--include``/``--define``/``--prelude``."""
    o = options
    if o is None:
        return load_source(path, language)
    return load_source(path, language, o.include_dirs, o.defines, o.prelude, o.max_source)


def _glsl(path, entry, target, options=None):
    src = _load(path, "glsl", options)
    if entry != "main":
        raise ShaderError(f"entry: a GLSL compute shader's entry point is main(), got --entry {entry!r}")
    ext = "\n".join(src.extensions)
    vk_text = f"#version {max(src.version, 450)}\n{ext}\n{src.body}"
    spv = _cached(("glsl", vk_text), lambda: _spirv.glsl_to_spirv(vk_text, src.name))
    iface = from_spirv(_cached(("reflect", spv), lambda: _spirv.reflect_spirv(spv)), "glsl", "main")
    if target.driver == "gl":
        text = f"#version {max(src.version, 430)}\n{ext}\n{src.body}"
        return Prepared("gl", None, "moderngl", text, "main", iface, "GLSL through moderngl", src)
    code = _cached(("naga", spv), lambda: _spirv.for_naga(spv))
    iface = from_spirv(_cached(("reflect", code), lambda: _spirv.reflect_spirv(code)), "glsl", "main")
    return Prepared("vulkan", target.name, "wgpu", code, "main", iface, "GLSL through glslang and wgpu", src)


def _hlsl(path, entry, target, options=None):
    if options is not None and (options.include_dirs or options.defines or options.prelude):
        # The harness's one preprocessor resolves includes, defines and the prelude; glslang gets one text.
        body = _load(path, "hlsl", options).body
        spv = _cached(("hlsl-text", body, entry), lambda: _hlsl_text(body, entry))
    else:
        body = open(path, encoding="utf-8", errors="replace").read()
        spv = _cached(("hlsl", str(path), body, entry), lambda: _spirv.hlsl_to_spirv(path, entry))
    iface = from_spirv(_cached(("reflect", spv), lambda: _spirv.reflect_spirv(spv, entry)), "hlsl", entry)
    if target.driver == "gl":
        text = _cached(("spirv-cross", spv, entry), lambda: _spirv.spirv_to_gl(spv, entry))
        return Prepared("gl", None, "moderngl", text, "main", iface, "HLSL through glslang and SPIRV-Cross")
    code = _cached(("naga", spv), lambda: _spirv.for_naga(spv))
    iface = from_spirv(_cached(("reflect", code, entry), lambda: _spirv.reflect_spirv(code, entry)), "hlsl", entry)
    return Prepared("vulkan", target.name, "wgpu", code, entry, iface, "HLSL through glslang and wgpu")


def _hlsl_text(body, entry):
    tmp = trace.write_temp(body, ".hlsl")
    try:
        return _spirv.hlsl_to_spirv(tmp, entry)
    finally:
        shutil.rmtree(tmp.parent, ignore_errors=True)


def _wgsl(path, entry, target, options=None):
    src = _load(path, "wgsl", options)
    iface = from_wgsl(src.body, entry)
    adapter = "wgpu's OpenGL adapter" if target.driver == "gl" else "wgpu"
    return Prepared(target.driver, target.name, "wgpu", src.body, entry, iface, f"WGSL through {adapter}", src)


def _slang(path, entry, target, options=None):
    from .slang import slang_kernel

    o = options
    code, iface, toolchain, _ = slang_kernel(path, entry, target.driver, _cached, *(
        (o.include_dirs, o.defines, o.prelude) if o is not None else ()))
    backend = "moderngl" if target.driver == "gl" else "wgpu"
    return Prepared(target.driver, target.name if backend == "wgpu" else None, backend, code, "main", iface, toolchain)


def prepare(path, entry, language, target, options=None):
    """Compile (cached) and reflect a kernel for one :class:`~moments_ref.conformance._run.Target`.

    ``options``: a :class:`~moments_ref.conformance.SourceOptions` (``--include``, ``--define``,
    ``--prelude``, ``--max-source``), resolved by the harness's one preprocessor.
    """
    front = {"glsl": _glsl, "hlsl": _hlsl, "wgsl": _wgsl, "slang": _slang}[language]
    return front(path, entry, target, options)


def _traced(path, entry, language, target, options=None):
    """The kernel with its shared-memory accesses traced (:mod:`.trace`), prepared for ``target``; None if untagged."""
    if language == "slang":
        return None  # the trace instruments GLSL, HLSL and WGSL text
    text = _load(path, language, options).body  # includes resolved (HLSL too: its guards keep it valid)
    if not any(trace.TAG.search(x) for x in text.splitlines()):
        return None
    if language == "wgsl":
        code = trace.instrument(text, "wgsl", entry)
        return Prepared(target.driver, target.name, "wgpu", code, entry, from_wgsl(code, entry), "traced WGSL")
    if language == "glsl":
        src = _load(path, "glsl", options)
        head = lambda v: f"#version {max(src.version, v)}\n" + "\n".join(src.extensions) + "\n"  # noqa: E731
        spv = _spirv.glsl_to_spirv(head(450) + trace.instrument(text, "glsl", entry, vulkan=True), src.name)
        if target.driver == "gl":
            code = head(430) + trace.instrument(text, "glsl", entry)
            return Prepared("gl", None, "moderngl", code, "main",
                            from_spirv(_spirv.reflect_spirv(spv), "glsl", "main"), "traced GLSL", src)
        code = _spirv.for_naga(spv)
        return Prepared("vulkan", target.name, "wgpu", code, "main",
                        from_spirv(_spirv.reflect_spirv(code), "glsl", "main"), "traced GLSL")
    tmp = trace.write_temp(trace.instrument(text, "hlsl", entry), ".hlsl")
    try:
        spv = _spirv.hlsl_to_spirv(tmp, entry)
    finally:
        shutil.rmtree(tmp.parent, ignore_errors=True)
    if target.driver == "gl":
        return Prepared("gl", None, "moderngl", _spirv.spirv_to_gl(spv, entry), "main",
                        from_spirv(_spirv.reflect_spirv(spv, entry), "hlsl", entry), "traced HLSL")
    code = _spirv.for_naga(spv)
    return Prepared("vulkan", target.name, "wgpu", code, entry,
                    from_spirv(_spirv.reflect_spirv(code, entry), "hlsl", entry), "traced HLSL")


def shared_memory(path, entry, language, target, case, gc, c, time_limit=None, options=None, layout="interleaved"):
    """Trace the shared memory of work group (0, 0) of a tagged kernel: accesses, bank conflicts, races.

    Returns None for a kernel without tagged accesses, else a dict: ``driver``,
    ``accesses`` (the most of one invocation), ``barriers``, ``pattern`` (the trace is
    :func:`moments_ref.gpu.banks.access_pattern` in program order; filter cases),
    ``conflicts`` (per phase of gpu.banks, from the trace), ``races`` (:func:`.trace.races`).
    """
    prep = _traced(path, entry, language, target, options)
    if prep is None:
        return None
    kw = gc.meta["kwargs"]
    bound = match(prep.interface, c, _out_bytes(kw, layout))
    threads = int(np.prod(prep.interface.workgroup))
    views = gc.arrays["views"] if case == "kernel-vwss-points" else None
    plan = dispatches(case, kw, views, prep.interface.workgroup[0])
    job = Job(prep.backend, prep.driver, prep.adapter, prep.code, prep.entry, bind_list(bound), _data(case, gc),
              output_spec(case, kw, bound, POISON[0], layout), [(d.groups, d.params) for d in plan],
              dispatch_seconds=watchdog() if time_limit is None else float(time_limit),
              trace_words=threads * trace.RECORDS)
    try:
        result = execute(prep, job)
    except DriverTimeout as exc:
        if not exc.watchdog:
            raise
        return {"driver": prep.driver, "error": str(exc)}
    addr, store, epoch = trace.decode(result.trace, threads)
    info = {"driver": prep.driver, "accesses": int((addr >= 0).sum(axis=1).max()), "barriers": int(epoch.max()),
            "races": trace.races(addr, store, epoch)}
    if case.startswith("kernel-filter") and threads == 256:
        exp, _, names = trace.expected()
        w = trace.warp_addresses(addr)
        info["pattern"] = bool(w[:, : len(names)].shape == exp.shape and np.array_equal(w[:, : len(names)], exp)
                               and info["accesses"] == len(names))
        info["conflicts"] = trace.phase_conflicts(addr)
    return info


def bind_list(bound):
    """What the driver process binds for each matched resource."""
    return [Bind(b.slot.name, b.slot.role, b.resource.kind, b.resource.set, b.resource.binding, b.resource.name,
                 b.resource.access, b.resource.depth, b.resource.format or b.slot.format) for b in bound]


def output_spec(case, kw, bound, fill, layout="interleaved"):
    """The output the harness binds: the map padded by a block (image) or a block row (buffer), pre-filled;
    a buffer in the declared ``layout`` (:mod:`.layout`)."""
    out = next(b for b in bound if b.slot.role == "output")
    if case == "kernel-vwss-points":
        n = kw["views"] * kw["height"] * kw["width"]
        return Output("buffer", "uint", (n + kw["height"] * kw["width"],), 0)
    h, w = kw["height"], kw["width"]
    comps = 1 if kw["format"] == "nlq32" else 4
    if out.resource.kind == "storage_image":
        return Output("storage_image", out.slot.format, (h + BLOCK[1], w + BLOCK[0], comps), fill)
    return Output("buffer", "uint", (buffer_words(kw["format"], layout, h * w, BLOCK[1] * w + BLOCK[0]),), fill)


def _data(case, gc):
    kw = gc.meta["kwargs"]
    if case == "kernel-vwss-points":
        return np.asarray(gc.arrays["points"], np.float32)
    z = np.asarray(gc.arrays["depth"], np.float64).reshape(kw["height"], kw["width"], kw["samples"])
    return ((z + 1) / 2).astype(np.float32)  # window depth; exact for the case's depths


def _errors(prep, text):
    """The compile message of the driver process, one line per error, with the user's file and line."""
    if prep.backend == "moderngl" and prep.source is not None:
        lines = one_line_errors(text, r"\b(\d+):(\d+)\((\d+)\)",
                                lambda m: f"{prep.source.name(int(m.group(1)))}:{m.group(2)}:{m.group(3)}")
    else:
        lines = [" ".join(x.strip() for x in text.splitlines() if x.strip())]
    return ShaderError(f"the kernel does not compile on {prep.driver} ({prep.toolchain}):\n" + "\n".join(lines))


def execute(prep, job):
    """Run a job in the driver process (:func:`.._supervisor.run`), its errors named for the kernel's driver.

    A compile error is a ShaderError with the user's files and lines, a driver that
    dies or fails a DriverError naming the driver (both exit 2); a step past its limit
    stays a DriverTimeout (the caller decides: a dispatch stopped by the watchdog fails
    the kernel).
    """
    try:
        return _supervisor.run(job)
    except CompileFailed as exc:
        raise _errors(prep, exc.args[0]) from None
    except DriverDied as exc:
        raise DriverDied(f"{prep.driver}: {exc} (a kernel that reads or writes out of bounds can crash the "
                         "driver; the harness cannot tell)") from None
    except DriverTimeout:
        raise
    except DriverError as exc:
        raise DriverError(f"{prep.driver}: {exc}") from None


def _run_one(prep, case, gc, c, time_limit, worst_rows, strict=False, layout="interleaved"):
    kw = gc.meta["kwargs"]
    bound = match(prep.interface, c, _out_bytes(kw, layout))
    c.check_workgroup(prep.interface.workgroup, f"{prep.interface.entry}")
    views = gc.arrays["views"] if case == "kernel-vwss-points" else None
    plan = dispatches(case, kw, views, prep.interface.workgroup[0])
    run = DriverRun(prep.driver, "", prep.toolchain, units=sum(d.blocks for d in plan))
    if prep.backend == "wgpu" and prep.driver == "gl" and any(b.resource.kind == "texture_ms" for b in bound):
        run.skipped = GL_MULTISAMPLE
        return run
    job = Job(prep.backend, prep.driver, prep.adapter, prep.code, prep.entry, bind_list(bound), _data(case, gc),
              output_spec(case, kw, bound, POISON[0], layout), [(d.groups, d.params) for d in plan],
              dispatch_seconds=float(time_limit))
    try:
        result = execute(prep, job)
    except DriverTimeout as exc:
        if not exc.watchdog:  # the compile: the harness cannot judge the kernel
            raise
        run.reason = (f"{exc.step} did not finish within {exc.seconds:g} s: the watchdog stopped the kernel (an "
                      "infinite loop, or a kernel far slower than the case needs; --watchdog sets the limit)")
        return run
    run.renderer, run.timings = result.renderer, result.timings
    verdict, unwritten, outside, codes, out = judge(case, gc.meta, gc.arrays, result.output, job.output.kind,
                                                    job.output.fill, worst_rows, strict, layout)
    if unwritten[0] and case != "kernel-vwss-points" and kw["format"] == "nlq32":
        # Any 32-bit word is a valid nlq32 code: a texel is unwritten only if it holds either poison.
        job.output.fill = POISON[1]
        again = execute(prep, job)
        v2 = judge(case, gc.meta, gc.arrays, again.output, job.output.kind, job.output.fill, worst_rows, strict,
                   layout)
        if v2[1][0] < unwritten[0]:
            verdict, unwritten, outside, codes, out = v2
    run.verdict, run.codes, run.output = verdict, codes, out
    run.unwritten, run.first_unwritten = unwritten
    run.outside, run.first_outside = outside
    if outside[0]:
        where = outside[1]
        run.reason = (f"writes outside the output: {outside[0]} words beyond the map changed (first at "
                      f"{'index' if len(where) == 1 else 'row, column'} {', '.join(map(str, where))})")
    run.passed = verdict.passed and not outside[0] and not unwritten[0]
    return run


def _out_bytes(kw, layout):
    return None if "format" not in kw else element_bytes(kw["format"], layout)


def numpy_times(case, gc):
    """Seconds per block (filter) or per view (VWSS) of the NumPy paths on the case's map, measured now."""
    from ...gpu import filtering, onchip
    from ...golden.kernels import vwss_reference

    kw = gc.meta["kwargs"]
    out = {}
    if case == "kernel-vwss-points":
        t0 = time.perf_counter()
        vwss_reference(gc.arrays["points"], gc.arrays["views"])
        out["NumPy np.maximum.at"] = (time.perf_counter() - t0) / kw["views"]
        return out
    z = np.asarray(gc.arrays["depth"], np.float32).reshape(kw["height"], kw["width"], kw["samples"])
    blocks = int(np.prod(onchip.block_grid(kw["height"], kw["width"])))
    fmt = kw["format"]
    t0 = time.perf_counter()
    if fmt in ("nlq64", "nlq32"):
        onchip.filter_and_quantize(z, fmt)
    else:
        onchip.filter_and_quantize(z, "float128" if fmt == "moments" else "affine64")
    out["NumPy emulation (gpu.onchip)"] = (time.perf_counter() - t0) / blocks
    t0 = time.perf_counter()
    if fmt in ("nlq64", "nlq32"):
        filtering.global_path_nlq(z, fmt)
    else:
        filtering.blur(filtering.resolve_moments(z))
    out["NumPy global path"] = (time.perf_counter() - t0) / blocks
    return out


def run_kernel(path, entry, case, language=None, adapter=None, golden_dir=None, time_limit=None, gc=None,
               worst_rows=5, timing=True, shared=True, options=None, strict=False, layout="interleaved",
               v2_cell=None):
    """Run a compute shader on a kernel case and judge it with the one comparator, on each driver.

    Parameters
    ----------
    path : path
        The kernel's GLSL, HLSL or WGSL file, as shipped (includes allowed).
    entry : str
        Its compute entry point (GLSL: ``main``).
    case : str
        A kernel case: ``kernel-filter-nlq64``, ``-nlq32``, ``-msm64``, ``-moments``, ``kernel-vwss-points``.
    language : {"glsl", "hlsl", "wgsl", "slang"}, optional
        Default: from the file's suffix.
    adapter : str, optional
        ``gl``, ``vulkan``, ``vulkan:NAME`` or an adapter name; default (or ``both``) both drivers.
    golden_dir : path, optional
        A folder written by ``moments-ref golden``; default: generate the case.
    time_limit : float, optional
        Seconds one dispatch may run; default the watchdog of the driver process
        (:func:`~moments_ref.conformance.set_watchdog`, ``--watchdog``: 10 s).
    gc : GoldenCase, optional
        The case already loaded (what ``golden_dir`` would give); ``golden_dir`` is then not read.
    worst_rows : int
        Rows shown per failing verdict.
    timing : bool
        Time the NumPy paths on the same map for the report.
    shared : bool
        Trace the shared memory of a kernel with tagged accesses (:mod:`.trace`): bank
        conflicts, and races between barriers (a race fails the report).
    options : SourceOptions, optional
        Include folders, defines, prelude and source budget, as for functions.
    strict : bool
        Texels beyond the algorithm's contract fail the verdict too.
    layout : {"interleaved", "planar", "packed16"}
        How a filter kernel's output buffer holds its texels (:mod:`.layout`).
    v2_cell : {"floor128", "round127"}, optional
        The √v2 grid of a 32-bit texel a profile declares (``[format] v2_cell``,
        :mod:`moments_ref.golden.cells`): the kernel is judged against that grid's texels.

    Returns
    -------
    KernelReport
    """
    from .._cases import load_case
    from ...golden.kernels import KERNEL_CASES

    language = language_of(path, language)
    require(language)
    if case not in KERNEL_CASES:
        raise InputError(f"case: {case!r} is not a kernel case; kernel cases: {', '.join(KERNEL_CASES)}")
    if adapter == "cpu":
        from .._slangcpu import KERNEL_REFUSAL

        raise InputError(KERNEL_REFUSAL)
    limit = watchdog() if time_limit is None else float(time_limit)
    if not limit > 0:
        raise InputError(f"time_limit: expected a positive number of seconds, got {time_limit!r}")
    targets = [parse_adapter(d, language) for d in KERNEL_DRIVERS] if adapter in (None, "both") else \
        [parse_adapter(adapter, language)]
    c = contract(case)
    gc = with_cell(gc or load_case(case, golden_dir), v2_cell)
    if layout != "interleaved":
        if case == "kernel-vwss-points":
            raise InputError("kernel layout: kernel-vwss-points writes one key per pixel; layouts are for filter cases")
        check_layout(layout, gc.meta["kwargs"]["format"])
    report = KernelReport(case, str(path), entry, language, gc.meta["kwargs"])
    preps = [prepare(path, entry, language, t, options) for t in targets]
    report.interface = preps[0].interface
    report.bindings = match(preps[0].interface, c, _out_bytes(gc.meta["kwargs"], layout))
    c.check_workgroup(preps[0].interface.workgroup, entry)
    for prep in preps:
        report.runs.append(_run_one(prep, case, gc, c, limit, worst_rows, strict, layout))
    if not any(not r.skipped for r in report.runs):
        raise ContextError(f"{report.runs[0].driver}: {report.runs[0].skipped}")
    ran = next(p for p, r in zip(preps, report.runs) if not r.skipped)
    if shared:
        report.shared = shared_memory(path, entry, language, targets[preps.index(ran)], case, gc, c, limit, options,
                                      layout)
    if timing:
        report.numpy = numpy_times(case, gc)
    return report
