"""One conformance run: a language front end, a driver backend, the one comparator (:mod:`.verdict`).

=========  ===============================================  ===============================
language   Vulkan (wgpu; lavapipe without a GPU)            OpenGL (EGL; llvmpipe)
=========  ===============================================  ===============================
GLSL       glslang → SPIR-V → wgpu                          moderngl (the default)
HLSL       glslang HLSL → SPIR-V → wgpu                     SPIR-V → SPIRV-Cross → moderngl (the default)
WGSL       wgpu (the default)                               wgpu's OpenGL adapter
=========  ===============================================  ===============================
"""

from __future__ import annotations

import hashlib
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .._arrays import InputError
from . import _gl, _toolchain, _wgpu
from ._cases import GoldenCase, load_case
from ._report import ConformanceReport
from ._slots import Slot, signature
from ._source import ShaderError, defined_functions, load_source, strip_comments
from ._wrap import LOCAL_SIZE, free_group, wrap_glsl, wrap_hlsl, wrap_wgsl
from .verdict import compare_case

__all__ = ["LANGUAGES", "DRIVERS", "Target", "parse_adapter", "language_of", "run_function", "run_case"]

LANGUAGES = ("glsl", "hlsl", "wgsl")
DRIVERS = ("gl", "vulkan")
#: The driver a language runs on unless ``--adapter`` says otherwise (docs/conformance.md says why).
DEFAULT_DRIVER = {"glsl": "gl", "hlsl": "gl", "wgsl": "vulkan"}
_SUFFIX = {".glsl": "glsl", ".comp": "glsl", ".hlsl": "hlsl", ".hlsli": "hlsl", ".fx": "hlsl", ".wgsl": "wgsl"}
_SPIRV = {}


@dataclass(frozen=True)
class Target:
    """Where a port runs: ``driver`` (gl or vulkan) and an adapter name to match (or None)."""

    driver: str
    name: str | None = None


def parse_adapter(spec, language):
    """``None`` → the language's default; ``gl``, ``vulkan``, ``vulkan:NAME`` or ``NAME`` (a Vulkan adapter)."""
    if spec is None or spec == "":
        return Target(DEFAULT_DRIVER[language])
    driver, _, name = spec.partition(":")
    if driver.lower() in DRIVERS:
        return Target(driver.lower(), name or None)
    return Target("vulkan", spec)


def language_of(path, language=None):
    """The language named, or the one of the file's suffix."""
    if language is not None:
        if language not in LANGUAGES:
            raise InputError(f"language: expected one of {', '.join(LANGUAGES)}, got {language!r}")
        return language
    lang = _SUFFIX.get(Path(path).suffix.lower())
    if lang is None:
        raise InputError(f"source: cannot tell the language of {str(path)!r}; use --glsl, --hlsl or --wgsl")
    return lang


def _check_defined(src, path, function, sig):

    if not re.search(rf"\b{re.escape(function)}\s*\(", strip_comments(src.body)):
        names = ", ".join(defined_functions(src.body)) or "none"
        raise ShaderError(f"function: {function!r} is not defined in {path} (functions defined: {names}); "
                          f"expected signature: {sig}")


def _cached(key_parts, make):
    key = hashlib.sha256("\0".join(key_parts).encode()).hexdigest()
    if key not in _SPIRV:
        _SPIRV[key] = make()
    return _SPIRV[key]


def _device(target, backend="Vulkan"):
    return _wgpu.get_device("OpenGL" if target.driver == "gl" else backend, target.name)


def _prepare(language, target, path, function, ins, outs):
    """``(execute(arrays, n) -> (results, timings), renderer)`` for one language on one driver."""
    src = load_source(path, language)
    sig = signature(language, function, ins, outs)
    _check_defined(src, path, function, sig)
    if language == "glsl" and target.driver == "gl":
        ctx = _gl.get_context()
        text, local = wrap_glsl(src, function, ins, outs)
        return (lambda a, n: _gl.run_program(text, src.name, sig, ins, outs, a, n, local, ctx)), _gl.renderer(ctx)
    if language == "wgsl":
        dev = _device(target)
        group = free_group(src.body, r"@group\s*\(\s*(\d+)\s*\)")
        code = wrap_wgsl(src, function, ins, outs, group)
        return (lambda a, n: _wgpu.run_module(dev, code, group, src.locate, sig, ins, outs, a, n, LOCAL_SIZE)), \
            dev.renderer
    if language == "glsl":
        dev = _device(target)
        group = free_group(src.body, r"\bset\s*=\s*(\d+)")
        text, local = wrap_glsl(src, function, ins, outs, vulkan=True, group=group)
        spv = _cached(["glsl", text], lambda: _toolchain.glslang_glsl(text, src.name, sig))
        return (lambda a, n: _wgpu.run_module(dev, spv, group, src.locate, sig, ins, outs, a, n, local, "main")), \
            dev.renderer
    space = free_group(src.body, r"\bspace(\d+)")
    wrapper = wrap_hlsl(Path(path).name, function, ins, outs, space)
    spv = _cached(["hlsl", str(Path(path).resolve()), src.body, wrapper],
                  lambda: _toolchain.glslang_hlsl(path, wrapper, sig))
    if target.driver == "vulkan":
        dev = _device(target)
        return (lambda a, n: _wgpu.run_module(dev, spv, space, src.locate, sig, ins, outs, a, n, LOCAL_SIZE)), \
            dev.renderer
    ctx = _gl.get_context()
    glsl = _cached(["spirv-cross", hashlib.sha256(spv).hexdigest()], lambda: _toolchain.spirv_to_glsl(spv))
    return (lambda a, n: _gl.run_program(glsl, lambda k: "<spirv-cross output>", sig, ins, outs, a, n,
                                         LOCAL_SIZE, ctx)), _gl.renderer(ctx) + " (HLSL through SPIRV-Cross)"


def run_function(path, function, inputs, outputs, language=None, adapter=None):
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
    execute, _ = _prepare(language, parse_adapter(adapter, language), path, function, ins, outs)
    results, timings = execute(inputs, n)
    return {k: v.reshape(outputs[k][1]) for k, v in results.items()}, timings


def _profiled(gc, profile):
    """The golden case as an engine with ``profile`` sees it, the target diagnosis and report notes."""
    from ..golden.conventions import profiled_arrays, unused_keys
    from ..golden.diagnosis import target_groups
    from ..golden.writer import manifest_entry

    pcase, arrays = profiled_arrays(gc.name, profile, arrays=gc.arrays)
    meta = dict(gc.meta, **{k: v for k, v in manifest_entry(pcase, arrays).items() if k not in ("sha256", "size")})
    notes = [f"profile: {profile.describe()}"]
    unused = unused_keys(pcase, profile)
    if unused:
        notes.append(f"profile keys not used by this case: {', '.join(unused)}")
    extra = lambda v: target_groups(v, arrays, profile.bias, pcase.engine)  # noqa: E731
    return GoldenCase(gc.name, meta, arrays, gc.source), extra, notes


def run_case(path, function, case, golden_dir=None, language=None, adapter=None, worst_rows=5, gc=None,
             profile=None, strict=False):
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
    language, adapter : see :func:`run_function`.
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
    gc = gc or load_case(case, golden_dir)
    from ..golden.diagnosis import convention_groups
    from ..golden.profile import DEFAULT

    base, by_target, notes = gc.arrays, None, []
    if profile is not None and not profile.is_default:
        gc, by_target, notes = _profiled(gc, profile)
    ins = [Slot.of(k, np.asarray(v).dtype, np.shape(v)) for k, v in gc.inputs.items()]
    specs = gc.output_specs()
    outs = [Slot.of(k, dt, shape) for k, (dt, shape) in specs.items()]
    execute, renderer = _prepare(language, target, path, function, ins, outs)
    got, timings = execute(gc.inputs, len(gc.category))
    got = {k: v.reshape(specs[k][1]) for k, v in got.items()}

    def extra(v):  # causes told by outputs: a singular bias target, another clamp or texel format
        found = by_target(v) if by_target is not None else []
        return found or convention_groups(case, v, base, got, profile or DEFAULT)

    v = compare_case(case, gc.meta, gc.arrays, got, worst_rows, strict, extra)
    return ConformanceReport(case, function, str(path), renderer, len(gc.category), v.exact, v.categories, v.worst,
                             timings, notes + v.notes, v.components, language, target.driver, got, v.metric,
                             v.row_pass, v.groups, v.compared, v.record)
