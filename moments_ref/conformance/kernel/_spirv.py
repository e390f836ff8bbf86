"""SPIR-V for kernels: glslang (GLSL, HLSL), SPIRV-Cross (reflection, GLSL for OpenGL), and two naga fixes.

wgpu's shader translator (naga) refuses two things glslang emits for ordinary
kernels, and both are rewritten here without changing what the kernel computes:

* a storage image without ``NonReadable`` is read-write, which WebGPU allows only
  for single-channel formats: an image the kernel never reads (no ``OpImageRead``,
  no atomic texel pointer) gets the decoration (HLSL has no write-only
  ``RWTexture2D``);
* a combined image sampler of a multisampled image (GLSL ``sampler2DMS``) is not
  supported: a multisampled image can only be fetched, so the sampled-image type
  is replaced by the image type and every ``OpImage`` of it by its operand.

The tools run as subprocesses with a time limit; a missing tool is a
:class:`~moments_ref.conformance.ToolError` (exit 2), a compile error a
:class:`~moments_ref.conformance.ShaderError` with the compiler's lines.
"""

from __future__ import annotations

import json
import re
import shutil
import subprocess
import tempfile
from pathlib import Path

from ...ports import PORTS_DIR
from .._source import ShaderError, one_line_errors
from .._toolchain import ToolError

__all__ = ["glsl_to_spirv", "hlsl_to_spirv", "reflect_spirv", "for_naga", "spirv_to_gl"]

#: Seconds a compiler may run before the harness gives up (exit 2).
TOOL_SECONDS = 120
_PACKAGES = {"glslangValidator": "glslang-tools", "spirv-cross": "spirv-cross", "spirv-dis": "spirv-tools",
             "spirv-as": "spirv-tools"}


def _run(cmd):
    path = shutil.which(cmd[0])
    if path is None:
        raise ToolError(f"{cmd[0]} is not installed (Debian/Ubuntu: apt-get install {_PACKAGES[cmd[0]]})")
    try:
        proc = subprocess.run([path, *cmd[1:]], capture_output=True, text=True, encoding="utf-8",
                              errors="replace", timeout=TOOL_SECONDS)
    except subprocess.TimeoutExpired:
        raise ToolError(f"{cmd[0]} did not finish within {TOOL_SECONDS} s (the harness's limit)") from None
    return proc.returncode, proc.stdout + proc.stderr


def glsl_to_spirv(text, name_of):
    """Compile a GLSL compute shader (resolved source text) to SPIR-V for Vulkan.

    ``name_of(k)`` names source string ``k`` of the ``#line`` markers, for messages.
    """
    with tempfile.TemporaryDirectory(prefix="moments-ref-kernel-") as tmp:
        src, out = Path(tmp) / "kernel.comp", Path(tmp) / "kernel.spv"
        src.write_text(text, encoding="utf-8")
        code, log = _run(["glslangValidator", "-V", "-S", "comp", "-o", str(out), str(src)])
        if code != 0 or not out.is_file():
            errors = one_line_errors(log, r"\b(\d+):(\d+):", lambda m: f"{name_of(int(m.group(1)))}:{m.group(2)}:")
            raise ShaderError("the kernel does not compile (glslang, Vulkan GLSL):\n"
                              + "\n".join(e for e in errors if not e.startswith(str(src))))
        return out.read_bytes()


def hlsl_to_spirv(path, entry):
    """Compile an HLSL file at compute entry point ``entry`` to SPIR-V (includes: its folder, the shipped ports)."""
    path = Path(path).resolve()
    with tempfile.TemporaryDirectory(prefix="moments-ref-kernel-") as tmp:
        out = Path(tmp) / "kernel.spv"
        code, log = _run(["glslangValidator", "-D", "-V", "-S", "comp", "-e", entry, f"-I{path.parent}",
                          f"-I{PORTS_DIR / 'hlsl'}", "-o", str(out), str(path)])
        if code != 0 or not out.is_file():
            errors = [e for e in one_line_errors(log, r"^$", lambda m: "") if e != str(path)]
            raise ShaderError("the kernel does not compile (glslang HLSL):\n" + "\n".join(errors))
        return out.read_bytes()


def _with_spv(spv, args):
    with tempfile.TemporaryDirectory(prefix="moments-ref-kernel-") as tmp:
        src = Path(tmp) / "in.spv"
        src.write_bytes(spv)
        return _run([args[0], str(src), *args[1:]])


def reflect_spirv(spv, entry=None):
    """SPIRV-Cross's JSON reflection of a module (resources, block layouts, work group size)."""
    code, log = _with_spv(spv, ["spirv-cross", "--reflect"] + (["--entry", entry] if entry else []))
    if code != 0:
        raise ShaderError(f"spirv-cross could not reflect the kernel: {log.strip()}")
    return json.loads(log[log.index("{"):])


def spirv_to_gl(spv, entry=None):
    """Desktop GLSL 4.30 of a SPIR-V module (SPIRV-Cross), for OpenGL."""
    with tempfile.TemporaryDirectory(prefix="moments-ref-kernel-") as tmp:
        src, out = Path(tmp) / "in.spv", Path(tmp) / "out.glsl"
        src.write_bytes(spv)
        cmd = ["spirv-cross", str(src), "--version", "430", "--no-es", "--output", str(out)]
        code, log = _run(cmd + (["--entry", entry] if entry else []))
        if code != 0 or not out.is_file():
            raise ShaderError(f"spirv-cross could not translate the kernel to GLSL: {log.strip()}")
        return out.read_text(encoding="utf-8")


_INSTR = re.compile(r"^\s*(?:(%\w+)\s*=\s*)?(Op\w+)(.*)$")


def _parse(text):
    """Disassembly lines as ``[(result id or None, opcode, operands str, line)]``."""
    out = []
    for line in text.splitlines():
        m = _INSTR.match(line)
        out.append((m.group(1), m.group(2), m.group(3).split(), line) if m else (None, None, [], line))
    return out


def _non_readable(lines):
    """``OpDecorate %var NonReadable`` for storage images the kernel never reads."""
    images = {r for r, op, a, _ in lines if op == "OpTypeImage" and len(a) >= 6 and a[5] == "2"}
    pointers = {r for r, op, a, _ in lines if op == "OpTypePointer" and a[0] == "UniformConstant" and a[1] in images}
    variables = {r for r, op, a, _ in lines if op == "OpVariable" and a[0] in pointers}
    loads = {}
    for r, op, a, _ in lines:
        if op == "OpLoad" and a[1] in variables:
            loads[r] = a[1]
    read = {loads[a[1]] for r, op, a, _ in lines if op == "OpImageRead" and a[1] in loads}
    read |= {a[1] for r, op, a, _ in lines if op == "OpImageTexelPointer"}
    decorated = {a[0] for r, op, a, _ in lines if op == "OpDecorate" and a[1:2] == ["NonReadable"]}
    return [f"OpDecorate {v} NonReadable" for v in sorted(variables - read - decorated)]


def _split_sampled(text):
    """Replace combined samplers of multisampled images by the images (their only use is OpImage)."""
    lines = _parse(text)
    ms = {r for r, op, a, _ in lines if op == "OpTypeImage" and len(a) >= 6 and a[4] == "1"}
    sampled = {r: a[0] for r, op, a, _ in lines if op == "OpTypeSampledImage" and a[0] in ms}
    if not sampled:
        return text
    alias, kept = {}, []
    for r, op, a, line in lines:
        if op == "OpImage" and a and a[0] in ms:
            alias[r] = a[1]  # the image of a combined image: the value itself, once retyped
            continue
        if op == "OpTypeSampledImage" and r in sampled:
            continue
        kept.append(line)
    out = "\n".join(kept)
    for s, img in sampled.items():
        out = re.sub(rf"{re.escape(s)}\b", img, out)
    for i, v in alias.items():
        out = re.sub(rf"{re.escape(i)}\b", v, out)
    return out


def for_naga(spv):
    """The module with the two rewrites of the module docstring (unchanged if neither applies)."""
    code, text = _with_spv(spv, ["spirv-dis", "--raw-id"])
    if code != 0:
        raise ShaderError(f"spirv-dis could not read the kernel's SPIR-V: {text.strip()}")
    extra = _non_readable(_parse(text))
    patched = _split_sampled(text)
    if not extra and patched == text:
        return spv
    if extra:  # decorations go before the first type declaration
        lines = patched.splitlines()
        at = next(i for i, x in enumerate(lines) if re.search(r"=\s*OpType", x))
        patched = "\n".join(lines[:at] + extra + lines[at:])
    with tempfile.TemporaryDirectory(prefix="moments-ref-kernel-") as tmp:
        src, out = Path(tmp) / "in.spvasm", Path(tmp) / "out.spv"
        src.write_text(patched + "\n", encoding="utf-8")
        code, log = _run(["spirv-as", "--target-env", "spv1.0", "-o", str(out), str(src)])
        if code != 0 or not out.is_file():
            raise ShaderError(f"spirv-as could not reassemble the kernel for wgpu: {log.strip()}")
        return out.read_bytes()
