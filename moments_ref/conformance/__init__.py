"""Run a GLSL, HLSL or WGSL port on a real driver against the golden vectors.

Slang too (``--slang``, the optional extra ``slang``): :mod:`.languages` holds each
language's facts. ``moments-ref conformance (--glsl | --hlsl | --wgsl | --slang) FILE --function NAME --case CASE
[--golden DIR] [--adapter NAME]`` wraps the function ``NAME`` of the file, unchanged,
in the harness's own compute entry point (:mod:`._wrap`), uploads the case's
inputs, runs one dispatch, reads the outputs back and compares them with the
golden case with :func:`moments_ref.golden.compare.compare`, the one comparator of
``verify`` and ``oracle.check`` (:mod:`.verdict` adapts the readback and summarises):
per-row float32 tolerances stored in the golden file, rounding ties accepting the
codes stored for them; the report lists the failing rows with their error,
tolerance, flags, inputs and reason.

Drivers (:mod:`._run`): GLSL runs on OpenGL through moderngl (EGL, Mesa llvmpipe
without a GPU) or on Vulkan (glslang to SPIR-V, then wgpu; Mesa lavapipe without a
GPU); HLSL goes through glslang's HLSL front end to SPIR-V, which the OpenGL driver
reads itself with every operation as written (the default, :mod:`._glspirv`) or
wgpu runs on Vulkan; WGSL runs through wgpu on Vulkan (the default) or on wgpu's
OpenGL adapter. ``--adapter`` picks the driver (``gl``, ``vulkan``, ``both`` with
the rows where they differ (:mod:`._agree`), ``as-written``) or an adapter by name;
the report names renderer and driver. Compilers and drivers run in child processes
under memory and time limits, one driver process for functions and kernels (:mod:`._supervisor`).

Function contract (:mod:`._slots`): the GLSL one in each language's types, e.g.
``float NAME(vec4 b, float zf)``, ``float NAME(float4 b, float zf)``,
``fn NAME(b: vec4<f32>, zf: f32) -> f32``; six moments as ``float b[6]`` /
``array<f32, 6>``. Files may ``#include "file"`` (resolved by the harness for every
language, :mod:`._source`) and define their own entry points and resources; only the
declarations the function uses are compiled (:mod:`._decls`).

Compute shaders (the shadow-map filter and point-warp kernels) run on the kernel cases with ``--kernel``:
:mod:`moments_ref.conformance.kernel`.

Exit codes of :func:`run_cli`: 0 every row within its tolerance, 1 a tolerance
exceeded, 2 bad usage, a file that does not compile (the compiler's messages, one
line per error, with the user's file and line numbers), no driver, or any failure of
the harness, a compiler or a driver (one line, never a traceback).
"""

from __future__ import annotations

import numpy as np

from ..ports import GLSL_DIR, HLSL_DIR, PORTS_DIR, SLANG_DIR, WGSL_DIR
from ._cases import GoldenCase, load_case
from ._cli import bench_conformance, main, run_cli, summary_markdown
from ._gl import ContextError, create_context, get_context, renderer
from ._report import ConformanceReport
from ._agree import DriverComparison, compare_drivers
from ._supervisor import WATCHDOG_SECONDS, DriverError, set_watchdog, watchdog
from ._run import ALL_LANGUAGES, AS_WRITTEN, DEFAULT_DRIVER, DRIVERS, LANGUAGES, SourceOptions, run_case, run_function
from ._shipped import NOT_AVAILABLE, SHIPPED, SHIPPED_FUNCTIONS, not_available, shipped_cases, shipped_port
from ._slots import Slot, signature
from ._source import ShaderError, defined_functions, load_source
from ._toolchain import ToolError
from .verdict import ulp_distance

__all__ = [
    "ContextError", "ToolError", "ShaderError", "GLSL_DIR", "HLSL_DIR", "WGSL_DIR", "SLANG_DIR", "PORTS_DIR",
    "LANGUAGES", "ALL_LANGUAGES", "DRIVERS", "DEFAULT_DRIVER", "AS_WRITTEN", "SourceOptions", "DriverError", "DriverComparison",
    "WATCHDOG_SECONDS", "set_watchdog", "watchdog",
    "compare_drivers", "SHIPPED", "SHIPPED_FUNCTIONS",
    "create_context", "get_context", "renderer", "load_source", "defined_functions",
    "shipped_port", "shipped_cases", "NOT_AVAILABLE", "not_available",
    "Slot", "signature", "glsl_signature", "run_glsl", "run_function",
    "GoldenCase", "load_case", "run_case", "ConformanceReport", "ulp_distance",
    "run_cli", "main", "summary_markdown", "bench_conformance",
]


def glsl_signature(function, inputs, outputs):
    """The GLSL signature the wrapper calls, e.g. ``float f(vec4 b, float zf)``."""
    return signature("glsl", function, inputs, outputs)


def run_glsl(glsl, function, inputs, outputs, ctx=None):
    """Evaluate a GLSL function once per row on OpenGL (llvmpipe without a GPU).

    ``ctx`` is accepted for compatibility (the process-wide context is used).
    See :func:`run_function` for the other languages and drivers.
    """
    path = glsl.files[0] if hasattr(glsl, "files") else glsl
    outputs = {k: (np.dtype(dt), shape) for k, (dt, shape) in outputs.items()}
    return run_function(path, function, inputs, outputs, "glsl", "gl")
