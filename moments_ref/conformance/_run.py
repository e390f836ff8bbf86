"""One conformance run: a language front end, a driver backend, the one comparator (:mod:`.verdict`).

=========  ===============================================  ===============================
language   Vulkan (wgpu; lavapipe without a GPU)            OpenGL (EGL; llvmpipe)
=========  ===============================================  ===============================
GLSL       glslang → SPIR-V → wgpu                          moderngl (the default)
HLSL       glslang HLSL → SPIR-V → wgpu                     SPIR-V read by the driver, as written (default)
WGSL       wgpu (the default)                               wgpu's OpenGL adapter
Slang      Slang → GLSL → glslang → SPIR-V → wgpu           Slang → GLSL → moderngl (default)
=========  ===============================================  ===============================

The facts per language (suffixes, compilers, routes, ``precise``) are :mod:`.languages`.
"""

from __future__ import annotations

import hashlib
import re
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from .._arrays import InputError
from ..ports import PORTS_DIR
from . import _gl, _glspirv, _slang, _toolchain, _wgpu
from . import languages as _languages
from ._cases import GoldenCase, load_case
from ._report import ConformanceReport
from ._slots import Slot, signature
from ._decls import keep_used, split_declarations, used_resources
from ._textures import consumed, texture_args
from ._uniforms import check_names, constant_declaration, member_names, parse_uniforms
from ._source import ShaderError, check_identifier, defined_functions, load_source, strip_comments
from ._wrap import LOCAL_SIZE, free_group, glsl_version, wrap_glsl, wrap_hlsl, wrap_slang, wrap_wgsl
from .verdict import compare_case

__all__ = ["LANGUAGES", "ALL_LANGUAGES", "DRIVERS", "AS_WRITTEN", "Target", "SourceOptions", "parse_adapter", "language_of", "run_function", "run_case"]

#: Languages whose shipped ports cover every shipped function; :data:`ALL_LANGUAGES` adds Slang.
LANGUAGES = _languages.CORE
ALL_LANGUAGES = _languages.LANGUAGES
DRIVERS = _languages.DRIVERS
#: The reference evaluation: OpenGL reading glslang's SPIR-V with every operation pinned
#: (``NoContraction``), i.e. each result rounded in program order (GLSL, HLSL).
AS_WRITTEN = "as-written"
#: The optional CPU driver of Slang functions (:mod:`._slangcpu`).
CPU = "cpu"
#: The driver a language runs on unless ``--adapter`` says otherwise (docs/conformance.md says why).
DEFAULT_DRIVER = {k: v.default for k, v in _languages.TABLE.items()}
_SPIRV = {}


@dataclass(frozen=True)
class Target:
    """Where a port runs: ``driver`` (gl or vulkan) and an adapter name to match (or None)."""

    driver: str
    name: str | None = None


def parse_adapter(spec, language):
    """``None`` → the language's default; ``gl``, ``vulkan``, ``vulkan:NAME``, ``as-written`` or ``NAME``
    (a Vulkan adapter)."""
    if spec is None or spec == "":
        return Target(DEFAULT_DRIVER[language])
    if spec == AS_WRITTEN:
        return Target(AS_WRITTEN)
    if spec == CPU:
        if language != "slang":
            raise InputError(f"adapter: cpu runs Slang files (Slang's cpp target and the system C++ compiler); "
                             f"{language} runs on gl or vulkan")
        return Target(CPU)
    driver, _, name = spec.partition(":")
    if driver.lower() in DRIVERS:
        return Target(driver.lower(), name or None)
    return Target("vulkan", spec)


def language_of(path, language=None):
    """The language named, or the one of the file's suffix (:func:`.languages.language_of`)."""
    return _languages.language_of(path, language)


@dataclass(frozen=True)
class SourceOptions:
    """How the harness reads and compiles a file (the CLI's source options).

    ``include_dirs``, ``defines`` (``NAME=VALUE``), ``prelude`` and ``max_source`` (bytes) as
    for :func:`~._source.load_source`; ``keep_unused`` compiles declarations the function
    does not use too; ``exact`` (default) makes OpenGL evaluate every operation of an HLSL
    file as written (each result rounded in program order, no reassociation, as if every
    operation were ``precise``); ``uniforms`` (``NAME=VALUE``, a vector ``NAME=a,b,c``) gives the
    uniform, constant-buffer and push-constant members the function reads a value (:mod:`._uniforms`).
    """

    include_dirs: tuple = ()
    defines: tuple = ()
    prelude: str | None = None
    max_source: int | None = None
    keep_unused: bool = False
    exact: bool = True
    uniforms: tuple = ()  # NAME=VALUE: values of the uniform / constant-buffer members the function reads
    uniform_origins: tuple = ()  # (NAME, where its value came from: "--uniform" or "profile FILE")

    def uniform_note(self):
        """The report's line naming each uniform value and where it came from, or None."""
        if not self.uniforms:
            return None
        origins = dict(self.uniform_origins)
        return "uniforms: " + "; ".join(f"{k} = {','.join(v)} ({origins.get(k, '--uniform')})"
                                        for k, v in parse_uniforms(self.uniforms).items())


def _check_defined(src, path, function, sig):
    if not re.search(rf"\b{re.escape(function)}\s*\(", strip_comments(src.body)):
        names = ", ".join(defined_functions(src.body)) or "none"
        raise ShaderError(f"function: {function!r} is not defined in {path} (functions defined: {names}); "
                          f"expected signature: {sig}")


def _only_used(src, function, language, keep_unused, uniforms=(), origins=()):
    """Blank the declarations ``function`` does not use; give uniforms their ``--uniform`` values; refuse
    resources it needs bound."""
    if keep_unused and not uniforms:
        return src
    body, kept = keep_used(src.body, language, function)
    if keep_unused:
        body = src.body
    values = parse_uniforms(uniforms)
    if values:  # a name no member of the file has: exit 2 naming the nearest member
        decls, _ = split_declarations(src.body, language)
        known = [n for d, _ in used_resources(decls, language)
                 for n in member_names(src.body[d.start:d.end], language, src.body)]
        check_names(values, known, dict(origins))
    for d, what in sorted(used_resources(kept, language), key=lambda x: -x[0].start):
        line = src.body.count("\n", 0, d.start) + 1
        text = src.body[d.start:d.end]
        const = constant_declaration(text, language, values, src.body, src.locate(line)) if values else None
        if const is not None:  # the same lines, so that messages keep their numbers
            body = body[:d.start] + const + "\n" * text.count("\n") + body[d.end:]
            continue
        way = ("take the texture as an argument, followed by an integer texel coordinate (docs/ports.md, "
               "\"Texture arguments\")" if re.search(r"texture|Texture|sampler", what) else
               "give its members values with --uniform NAME=VALUE, read it in an adapter function that takes it as "
               "an argument, or make it a constant" + (" (`static const`)" if language == "hlsl" else ""))
        raise ShaderError(f"{src.locate(line)}: {function} uses {what} {d.name!r} declared here, which the harness "
                          f"does not bind (it passes only the function's arguments): {way}")
    return replace(src, body=body)


def _cached(key_parts, make):
    key = hashlib.sha256("\0".join(key_parts).encode()).hexdigest()
    if key not in _SPIRV:
        _SPIRV[key] = make()
    return _SPIRV[key]


def _device(target, backend="Vulkan"):
    return _wgpu.get_device("OpenGL" if target.driver == "gl" else backend, target.name)


def _prepare(language, target, path, function, ins, outs, options=None, inputs=None):
    """``(execute(arrays, n) -> (results, timings), renderer, notes)`` for one language on one driver.

    ``inputs`` (the arrays) let the harness fill the textures a function reads (:mod:`._textures`).
    """
    options = options or SourceOptions()
    _languages.require(language)  # before any file is read: the install line, not a parse error
    check_identifier(function)
    src = load_source(path, language, options.include_dirs, options.defines, options.prelude, options.max_source)
    sig = signature(language, function, ins, outs)
    _check_defined(src, path, function, sig)
    if language == "slang":  # Slang keeps only what the entry point uses; modules are its own
        return _slang_route(target, src, path, function, sig, ins, outs, options)
    src = _only_used(src, function, language, options.keep_unused, options.uniforms, options.uniform_origins)
    tex = {} if inputs is None else texture_args(src.body, function, language, ins,
                                                  {k: np.asarray(v).dtype for k, v in inputs.items()},
                                                  len(next(iter(inputs.values()))))
    if tex:  # the signature the wrapper calls, with the texture arguments
        sig = signature(language, function, ins, outs, {**{k: t.declared(language) for k, t in tex.items()},
                                                         **{k: "" for k in consumed(tex)}})
    if target.driver == AS_WRITTEN:
        return _as_written(language, src, function, sig, ins, outs, tex)
    if language == "glsl":
        return _glsl(target, src, function, sig, ins, outs, tex)
    if language == "wgsl":
        dev = _device(target)
        group = free_group(src.body, r"@group\s*\(\s*(\d+)\s*\)")
        code = wrap_wgsl(src, function, ins, outs, group, tex)
        return (lambda a, n: _wgpu.run_module(dev, code, group, src.locate, sig, ins, outs, a, n, LOCAL_SIZE, tex=tex)), \
            dev.renderer, []
    return _hlsl(target, src, function, sig, ins, outs, options.exact, tex)


def _slang_cpu(wrapper, dirs, known, sig, ins, outs, note=None):
    """Slang → C++ → the system compiler → a child process (:mod:`._slangcpu`)."""
    from . import _slangcpu
    from ._source import wrapped_compile_error
    from ._supervisor import watchdog

    reason = _slangcpu.not_available()
    if reason:
        raise InputError(reason)

    def failed(errors):
        return wrapped_compile_error("Slang", [_languages.unmangle("slang", e, known) for e in errors], sig)

    def execute(a, n):
        res, timings, _ = _slangcpu.run_cpu(wrapper, dirs, failed, ins, outs, a, n, LOCAL_SIZE, watchdog())
        return res, timings

    name = Path(_slangcpu.compiler()).name
    return execute, f"CPU: Slang's cpp target and {name} -O2 -ffp-contract=off", [note] if note else []


def _slang_route(target, src, path, function, sig, ins, outs, options):
    """Slang → GLSL; OpenGL runs it (barriers lowered), Vulkan gets glslang's SPIR-V of it (keeps ``precise``)."""
    if target.driver == AS_WRITTEN:
        raise InputError(f"adapter: {AS_WRITTEN} needs GLSL or HLSL; Slang runs on gl or vulkan")
    if options.uniforms:
        raise InputError("uniform: uniform values (--uniform, a profile's [uniforms]) are for GLSL, HLSL and WGSL "
                         "files; in Slang, pass the value as an argument of an adapter function")
    space = free_group(src.body, r"(?:\bspace|vk::binding\s*\(\s*\d+\s*,\s*)(\d+)")
    wrapper = wrap_slang(src, function, ins, outs, space)
    dirs = [Path(path).resolve().parent, *options.include_dirs, PORTS_DIR / "slang"]
    known = _slang.identifiers(src.body, dirs)
    if target.driver == CPU:
        return _slang_cpu(wrapper, dirs, known, sig, ins, outs, _languages.precise_note("slang", CPU, src.body))
    glsl = _cached(["slang", wrapper, *map(str, dirs)],
                   lambda: _slang.slang_glsl(wrapper, "mr_main", dirs, sig,
                                             lambda e: _languages.unmangle("slang", e, known)))
    note = _languages.precise_note("slang", target.driver, src.body)
    notes = [note] if note else []
    if target.driver == "gl":
        ctx = _gl.get_context()
        text = _slang.to_gl(glsl)
        return (lambda a, n: _gl.run_program(text, lambda k: "<Slang's GLSL>", sig, ins, outs, a, n, LOCAL_SIZE,
                                             ctx)), _gl.renderer(ctx) + " (Slang through its GLSL)", notes
    dev = _device(target)
    spv = _cached(["slang-spirv", glsl], lambda: _toolchain.glslang_glsl(glsl, lambda k: "<Slang's GLSL>", sig))
    return (lambda a, n: _wgpu.run_module(dev, spv, space, src.locate, sig, ins, outs, a, n, LOCAL_SIZE, "main")), \
        dev.renderer + " (Slang through its GLSL and glslang)", notes


def _glsl(target, src, function, sig, ins, outs, tex):
    if target.driver == "gl":
        ctx = _gl.get_context()
        gl_max = min(ctx.version_code, 460)
        text, local = wrap_glsl(src, function, ins, outs, gl_max=gl_max, tex=tex)
        note = glsl_version(src, False, gl_max)[1]
        return (lambda a, n: _gl.run_program(text, src.name, sig, ins, outs, a, n, local, ctx, tex=tex)), \
            _gl.renderer(ctx), [note] if note else []
    if tex:
        raise InputError(f"function: {function} takes a texture (GLSL sampler2D), which runs on OpenGL only: wgpu's "
                         "SPIR-V reader takes no combined image sampler; use --adapter gl")
    dev = _device(target)
    spv, group, local, note = _glsl_spirv(src, function, sig, ins, outs, tex)
    return (lambda a, n: _wgpu.run_module(dev, spv, group, src.locate, sig, ins, outs, a, n, local, "main", tex)), \
        dev.renderer, [note] if note else []


def _glsl_spirv(src, function, sig, ins, outs, tex=None):
    group = free_group(src.body, r"\bset\s*=\s*(\d+)")
    text, local = wrap_glsl(src, function, ins, outs, vulkan=True, group=group, tex=tex)
    note = glsl_version(src, True)[1]
    return _cached(["glsl", text], lambda: _toolchain.glslang_glsl(text, src.name, sig)), group, local, note


def _hlsl_spirv(src, function, sig, ins, outs, tex=None):
    space = free_group(src.body, r"\bspace(\d+)")
    wrapper = wrap_hlsl(src, function, ins, outs, space, tex)
    return _cached(["hlsl", wrapper], lambda: _toolchain.glslang_hlsl(wrapper, src.name, sig)), space


def _hlsl(target, src, function, sig, ins, outs, exact, tex):
    spv, space = _hlsl_spirv(src, function, sig, ins, outs, tex)
    if target.driver == "vulkan":
        dev = _device(target)
        return (lambda a, n: _wgpu.run_module(dev, spv, space, src.locate, sig, ins, outs, a, n, LOCAL_SIZE,
                                              tex=tex)), dev.renderer, []
    ctx = _gl.get_context()
    code = _glspirv.exact_everywhere(spv) if exact else spv
    how = "every operation as written" if exact else "the SPIR-V Vulkan gets"
    if ctx.spirv and not tex:  # the driver reads the module itself (GL_ARB_gl_spirv): no GLSL text in between
        return (lambda a, n: _gl.run_program(code, src.name, sig, ins, outs, a, n, LOCAL_SIZE, ctx, "mr_main")), \
            _gl.renderer(ctx) + f" (HLSL as SPIR-V: {how})", []
    # OpenGL's SPIR-V has no texture without a sampler: SPIRV-Cross combines them.
    glsl = _cached(["spirv-cross", hashlib.sha256(code).hexdigest()], lambda: _toolchain.spirv_to_glsl(code))
    return (lambda a, n: _gl.run_program(glsl, lambda k: "<spirv-cross output>", sig, ins, outs, a, n,
                                         LOCAL_SIZE, ctx, tex=tex)), _gl.renderer(ctx) + " (HLSL through SPIRV-Cross)", []


def _as_written(language, src, function, sig, ins, outs, tex):
    """OpenGL reading glslang's SPIR-V with every float operation ``NoContraction`` (GLSL, HLSL)."""
    ctx = _gl.get_context()
    if language == "wgsl" or not ctx.spirv or tex:
        raise InputError(f"adapter: {AS_WRITTEN} needs GLSL or HLSL without texture arguments and an OpenGL "
                         "driver with GL_ARB_gl_spirv")
    if language == "glsl":
        spv, _, local, _ = _glsl_spirv(src, function, sig, ins, outs)
        entry = "main"
    else:
        (spv, _), local, entry = _hlsl_spirv(src, function, sig, ins, outs), LOCAL_SIZE, "mr_main"
    code = _glspirv.exact_everywhere(spv)
    return (lambda a, n: _gl.run_program(code, src.name, sig, ins, outs, a, n, local, ctx, entry)), \
        _gl.renderer(ctx) + " (SPIR-V, every operation as written)", []


def run_function(path, function, inputs, outputs, language=None, adapter=None, options=None):
    """Evaluate a shader function once per row on a driver.

    Parameters
    ----------
    path : path
        The file holding ``function`` (GLSL, HLSL or WGSL; includes allowed).
    function : str
    inputs : dict name -> array
        Arrays with a leading row axis, in argument order (types: :mod:`._slots`).
    outputs : dict name -> (dtype, shape)
        Float outputs come back as float32, unsigned as uint32, signed as int32.
    language : {"glsl", "hlsl", "wgsl"}, optional
        Default: from the file's suffix.
    adapter : str, optional
        ``gl``, ``vulkan``, ``vulkan:NAME`` or an adapter name; default per language.
    options : SourceOptions, optional
        Include folders, defines, prelude, source size budget (see :class:`SourceOptions`).

    Returns
    -------
    results : dict name -> array
    timings : dict
        Seconds for ``compile``, ``upload``, ``dispatch``, ``readback`` (and ``renderer``
        is not a timing: see :func:`run_case`).
    """
    language = language_of(path, language)
    ins = [Slot.of(k, np.asarray(v).dtype, np.shape(v)) for k, v in inputs.items()]
    outs = [Slot.of(k, dt, shape) for k, (dt, shape) in outputs.items()]
    n = len(next(iter(inputs.values())))
    if n == 0:
        raise InputError("inputs: expected at least one row, got 0")
    execute, _, _ = _prepare(language, parse_adapter(adapter, language), path, function, ins, outs, options, inputs)
    results, timings = execute(inputs, n)
    return {k: v.reshape(outputs[k][1]) for k, v in results.items()}, timings


def _profiled(gc, profile):
    """The golden case as an engine with ``profile`` sees it, the target diagnosis and report notes."""
    from ..golden.conventions import profiled_arrays
    from ..golden.diagnosis import target_groups
    from ..golden.profile import ignored_note
    from ..golden.writer import manifest_entry

    pcase, arrays = profiled_arrays(gc.name, profile, arrays=gc.arrays)
    meta = dict(gc.meta, **{k: v for k, v in manifest_entry(pcase, arrays).items() if k not in ("sha256", "size")})
    notes = [f"profile: {profile.describe()}"]
    notes += ignored_note(pcase, profile)
    extra = lambda v: target_groups(v, arrays, profile.bias, pcase.engine)  # noqa: E731
    return GoldenCase(gc.name, meta, arrays, gc.source), extra, notes


def run_case(path, function, case, golden_dir=None, language=None, adapter=None, worst_rows=5, gc=None,
             options=None, profile=None, strict=False):
    """Run a shader function on a golden case and judge it with the one comparator (``golden.compare``).

    Parameters
    ----------
    path : path
        GLSL, HLSL or WGSL file as shipped (includes allowed).
    function : str
        The function to call.
    case : str
        Golden case name, e.g. ``shadow_intensity-lower-float32``.
    golden_dir : path, optional
        A folder written by ``moments-ref golden``; default: generate the case.
    language, adapter, options : see :func:`run_function`.
    worst_rows : int
        Failing rows to list per category.
    gc : GoldenCase, optional
        The case already loaded (skips reading it again).
    profile : moments_ref.golden.profile.Profile, optional
        The engine's declared conventions (docs/ports.md): the port gets the case's
        inputs converted for them, and expected values and tolerances are derived
        for them (cached).
    strict : bool
        Robustness rows (beyond the algorithm's contract) fail the verdict too.

    Returns
    -------
    ConformanceReport
    """
    language = language_of(path, language)
    target = parse_adapter(adapter, language)
    if profile is not None and profile.bound is not None:
        from ..golden.cases import bound_case

        case = bound_case(case, profile.bound)  # bound = "hausdorff": judged by the Hausdorff cases
    gc = gc if gc is not None and gc.name == case else load_case(case, golden_dir)
    from ..golden.diagnosis import convention_groups
    from ..golden.profile import DEFAULT

    base, by_target, notes = gc.arrays, None, []
    if profile is not None and not profile.is_default:
        gc, by_target, notes = _profiled(gc, profile)
    ins = [Slot.of(k, np.asarray(v).dtype, np.shape(v)) for k, v in gc.inputs.items()]
    specs = gc.output_specs()
    outs = [Slot.of(k, dt, shape) for k, (dt, shape) in specs.items()]
    execute, renderer, prepared = _prepare(language, target, path, function, ins, outs, options, gc.inputs)
    notes = notes + prepared + ([options.uniform_note()] if options is not None and options.uniforms else [])
    got, timings = execute(gc.inputs, len(gc.category))
    got = {k: v.reshape(specs[k][1]) for k, v in got.items()}
    if profile is not None and profile.output_clamp:  # the caller's clamp, declared: applied first, and said
        from ..golden.cases import CASES
        from ..golden.receiver import clamp_outputs

        got, said = clamp_outputs(CASES[case], profile, got) if case in CASES else (got, [])
        notes = notes + said

    def extra(v):  # causes told by outputs: a singular bias target, another clamp or texel format
        found = by_target(v) if by_target is not None else []
        return found or convention_groups(case, v, base, got, profile or DEFAULT)

    from ..golden import CASES

    from ..golden.conventions import neighbourhood_case

    # the exact values that judge the ill-conditioned rows: the shipped case's, or the profiled case's
    plain = neighbourhood_case(CASES[case], profile) if case in CASES else None
    v = compare_case(case, gc.meta, gc.arrays, got, worst_rows, strict, extra, plain)
    return ConformanceReport(case, function, str(path), renderer, len(gc.category), v.exact, v.categories, v.worst,
                             timings, notes + v.notes, v.components, language, target.driver, got, v.metric,
                             v.row_pass, v.groups, v.compared, v.record, v.ill)
