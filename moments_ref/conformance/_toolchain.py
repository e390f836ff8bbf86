"""glslang (GLSL and HLSL to SPIR-V) and SPIRV-Cross (SPIR-V to GLSL), as subprocesses.

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

from ..ports import PORTS_DIR
from ._source import ShaderError, one_line_errors

__all__ = ["ToolError", "glslang_glsl", "glslang_hlsl", "spirv_to_glsl", "tool_versions"]


class ToolError(RuntimeError):
    """A compiler the path needs is not installed; ``str(exc)`` names the package."""


_PACKAGES = {"glslangValidator": "glslang-tools", "spirv-cross": "spirv-cross"}


def _tool(name):
    path = shutil.which(name)
    if path is None:
        raise ToolError(f"{name} is not installed (Debian/Ubuntu: apt-get install {_PACKAGES[name]})")
    return path


def _run(cmd):
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    return proc.returncode, (proc.stdout + proc.stderr)


def glslang_glsl(text, describe_string, signature):
    """Compile a GLSL compute shader (the wrapper) to SPIR-V for Vulkan.

    ``describe_string(k)`` names source string ``k`` (the ``#line N k`` markers).
    """
    with tempfile.TemporaryDirectory(prefix="moments-ref-glsl-") as tmp:
        src, out = Path(tmp) / "mr_wrapper.comp", Path(tmp) / "out.spv"
        src.write_text(text)
        code, log = _run([_tool("glslangValidator"), "-V", "-S", "comp", "-o", str(out), str(src)])
        if code != 0 or not out.is_file():
            errors = one_line_errors(log, r"\b(\d+):(\d+):",
                                     lambda m: f"{describe_string(int(m.group(1)))}:{m.group(2)}:")
            errors = [e for e in errors if not e.startswith(str(src))]
            raise ShaderError(f"the wrapped function does not compile (glslang; expected signature: {signature}):\n"
                              + "\n".join(errors))
        return out.read_bytes()


def glslang_hlsl(path, wrapper_text, signature):
    """Compile the HLSL wrapper (which includes the user's ``path``) to SPIR-V, entry ``mr_main``."""
    path = Path(path).resolve()
    with tempfile.TemporaryDirectory(prefix="moments-ref-hlsl-") as tmp:
        src, out = Path(tmp) / "mr_wrapper.hlsl", Path(tmp) / "out.spv"
        src.write_text(wrapper_text)
        cmd = [_tool("glslangValidator"), "-D", "-V", "-S", "comp", "-e", "mr_main", f"-I{path.parent}", f"-I{PORTS_DIR / 'hlsl'}",
               "-o", str(out), str(src)]
        code, log = _run(cmd)
        if code != 0 or not out.is_file():
            log = log.replace(str(src), "<harness wrapper>")
            errors = one_line_errors(log, r"^$", lambda m: "")
            errors = [e for e in errors if e != str(src) and "Entry point not found" not in e]
            raise ShaderError(f"the wrapped function does not compile (glslang HLSL; expected signature: "
                              f"{signature}):\n" + "\n".join(errors))
        return out.read_bytes()


def spirv_to_glsl(spirv, version=430):
    """SPIR-V to desktop GLSL with SPIRV-Cross (``precise`` kept from NoContraction)."""
    with tempfile.TemporaryDirectory(prefix="moments-ref-spvc-") as tmp:
        src, out = Path(tmp) / "in.spv", Path(tmp) / "out.glsl"
        src.write_bytes(spirv)
        code, log = _run([_tool("spirv-cross"), "--version", str(version), "--no-es", str(src),
                          "--output", str(out)])
        if code != 0 or not out.is_file():
            raise ShaderError(f"spirv-cross could not translate the SPIR-V: {log.strip()}")
        return out.read_text()


def tool_versions():
    """``{tool: first line of its version output}`` of the installed tools (missing: absent)."""
    found = {}
    for name, arg in (("glslangValidator", "--version"), ("spirv-cross", "--revision")):
        if shutil.which(name):
            _, log = _run([name, arg])
            line = next((x for x in log.splitlines() if x.strip()), "")
            found[name] = re.sub(r"\s+", " ", line.strip())
    return found
