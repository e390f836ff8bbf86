"""glslang (GLSL and HLSL to SPIR-V) and SPIRV-Cross (SPIR-V to GLSL), as subprocesses.

Each runs as a child process with a memory limit (``max_memory()``, the
``--max-memory`` of the CLI, 4 GiB by default: its data segment) and a time limit
(:data:`COMPILE_SECONDS`), so that a macro that expands without bound ends as a
:class:`~._source.ShaderError` naming the limit, not as a machine out of memory.
The compilers never open a file of the user's: the harness hands them one text
with its includes resolved (:mod:`._source`).

Debian/Ubuntu: ``apt-get install glslang-tools spirv-cross``. A missing tool is a
:class:`ToolError` (a missing driver, exit code 2), a compile error a
:class:`~._source.ShaderError` holding glslang's messages, one line per error, with
the user's file names and line numbers.
"""

from __future__ import annotations

import re
import shutil
import subprocess
import tempfile
from pathlib import Path

from ._source import ShaderError, one_line_errors, wrapped_compile_error

__all__ = ["ToolError", "COMPILE_SECONDS", "limit_memory", "run_child", "glslang_glsl", "glslang_hlsl", "spirv_to_glsl", "tool_versions"]


class ToolError(RuntimeError):
    """A compiler the path needs is not installed; ``str(exc)`` names the package."""


_PACKAGES = {"glslangValidator": "glslang-tools", "spirv-cross": "spirv-cross"}


def _tool(name):
    path = shutil.which(name)
    if path is None:
        raise ToolError(f"{name} is not installed (Debian/Ubuntu: apt-get install {_PACKAGES[name]})")
    return path


#: Seconds a compiler (glslang, SPIRV-Cross, a driver's) may take for one shader.
COMPILE_SECONDS = 60


def limit_memory(nbytes):
    """Cap this process's data segment (heap and private mappings) at ``nbytes``."""
    import resource

    _, hard = resource.getrlimit(resource.RLIMIT_DATA)
    soft = nbytes if hard == resource.RLIM_INFINITY else min(nbytes, hard)
    resource.setrlimit(resource.RLIMIT_DATA, (soft, hard))  # the soft limit only: a later call may raise it


def _run(cmd, what="the compiler"):
    from .._arrays import format_bytes, max_memory

    mem = max_memory()
    try:
        proc = subprocess.run(cmd, capture_output=True, timeout=COMPILE_SECONDS,
                              preexec_fn=lambda: limit_memory(mem))
    except subprocess.TimeoutExpired:
        raise ShaderError(f"{what} did not finish within {COMPILE_SECONDS} s (a macro that expands without "
                          "bound?)") from None
    log = (proc.stdout + proc.stderr).decode("utf-8", "replace")
    if proc.returncode < 0 or "bad_alloc" in log or "out of memory" in log.lower():
        raise ShaderError(f"{what} stopped ({_signal(proc.returncode)}) within its memory limit of "
                          f"{format_bytes(mem)} (--max-memory): a macro that expands without bound?")
    return proc.returncode, log


def run_child(cmd, what="the compiler"):
    """Run a compiler as a child process under the memory and time limits; ``(exit code, log)``."""
    return _run(cmd, what)


def _signal(code):
    import signal

    if code is not None and code < 0:
        try:
            return f"signal {signal.Signals(-code).name}"
        except ValueError:
            return f"signal {-code}"
    return f"exit {code}"


def glslang_glsl(text, describe_string, signature):
    """Compile a GLSL compute shader (the wrapper) to SPIR-V for Vulkan.

    ``describe_string(k)`` names source string ``k`` (the ``#line N k`` markers).
    """
    with tempfile.TemporaryDirectory(prefix="moments-ref-glsl-") as tmp:
        src, out = Path(tmp) / "mr_wrapper.comp", Path(tmp) / "out.spv"
        src.write_text(text, encoding="utf-8")
        code, log = _run([_tool("glslangValidator"), "-V", "-S", "comp", "-o", str(out), str(src)], "glslang")
        if code != 0 or not out.is_file():
            errors = one_line_errors(log, r"\b(\d+):(\d+):",
                                     lambda m: f"{describe_string(int(m.group(1)))}:{m.group(2)}:")
            errors = [e for e in errors if not e.startswith(str(src))]
            raise wrapped_compile_error("glslang", errors, signature)
        return out.read_bytes()


def glslang_hlsl(text, describe_string, signature):
    """Compile the HLSL wrapper (the user's resolved source and the harness's entry ``mr_main``) to SPIR-V."""
    with tempfile.TemporaryDirectory(prefix="moments-ref-hlsl-") as tmp:
        src, out = Path(tmp) / "mr_wrapper.hlsl", Path(tmp) / "out.spv"
        src.write_text(text, encoding="utf-8")
        cmd = [_tool("glslangValidator"), "-D", "-V", "-S", "comp", "-e", "mr_main", "-o", str(out), str(src)]
        code, log = _run(cmd, "glslang")
        if code != 0 or not out.is_file():
            # "(9): error at column 34, HLSL parsing failed." repeats the error before it, without the file
            errors = one_line_errors(log, r"\b(\d+):(\d+):",
                                     lambda m: f"{describe_string(int(m.group(1)))}:{m.group(2)}:",
                                     noise=r"^\(\d+\): error at column|Entry point not found")
            errors = [e for e in errors if e != str(src) and not e.startswith(str(src))]
            # glslang's HLSL parser repeats a syntax error as "'declaration' : Expected" on its line.
            errors = [e for e in errors if not e.endswith("'declaration' : Expected")] or errors
            raise wrapped_compile_error("glslang HLSL", errors, signature)
        return out.read_bytes()


def _as_spirv_states(types=("float", "vec2", "vec3", "vec4")):
    """GLSL helpers that evaluate ``fma`` and ``mix`` the way SPIR-V defines ``Fma`` and ``FMix``.

    Measured on Mesa 22.3: its GLSL compiler splits a non-``precise`` ``fma`` into a
    product and a sum and then factors ``fma(-n, lo, fma(-n, hi, x))`` into
    ``x - n*(hi + lo)`` (Cody-Waite reduction undone), and lowers ``mix(x, y, a)`` to
    ``x + a*(y - x)``; Mesa's SPIR-V reader (Vulkan) keeps ``Fma`` one operation and
    evaluates ``FMix`` as GLSL.std.450 defines it, ``x*(1 - a) + y*a``. ``precise``
    helpers give OpenGL the same. ``mix`` with a boolean selector stays a select.
    """
    lines = []
    for t in types:
        lines.append(f"{t} mr_fma({t} a, {t} b, {t} c) {{ precise {t} r = fma(a, b, c); return r; }}")
        lines.append(f"{t} mr_mix({t} x, {t} y, {t} a) {{ precise {t} r = x * (1.0 - a) + y * a; return r; }}")
        b = "bool" if t == "float" else f"bvec{t[-1]}"
        lines.append(f"{t} mr_mix({t} x, {t} y, {b} a) {{ return mix(x, y, a); }}")
        if t != "float":
            lines.append(f"{t} mr_mix({t} x, {t} y, float a) {{ precise {t} r = x * (1.0 - a) + y * a; return r; }}")
    return lines


def spirv_to_glsl(spirv, version=430):
    """SPIR-V to desktop GLSL with SPIRV-Cross, evaluated as the SPIR-V states it on Mesa.

    ``precise`` comes from NoContraction; ``fma`` and ``mix`` go through the helpers of
    :func:`_as_spirv_states`, so that OpenGL computes what Vulkan computes.
    """
    with tempfile.TemporaryDirectory(prefix="moments-ref-spvc-") as tmp:
        src, out = Path(tmp) / "in.spv", Path(tmp) / "out.glsl"
        src.write_bytes(spirv)
        code, log = _run([_tool("spirv-cross"), "--version", str(version), "--no-es", str(src),
                          "--output", str(out)], "spirv-cross")
        if code != 0 or not out.is_file():
            raise ShaderError(f"spirv-cross could not translate the SPIR-V: {log.strip()}")
        text = re.sub(r"\b(fma|mix)\(", r"mr_\1(", out.read_text(encoding="utf-8"))
        head, _, rest = text.partition("\n")
        return "\n".join([head, *_as_spirv_states(), rest])


def tool_versions():
    """``{tool: first line of its version output}`` of the installed tools (missing: absent)."""
    found = {}
    for name, arg in (("glslangValidator", "--version"), ("spirv-cross", "--revision")):
        if shutil.which(name):
            _, log = _run([name, arg])
            line = next((x for x in log.splitlines() if x.strip()), "")
            found[name] = re.sub(r"\s+", " ", line.strip())
    return found
