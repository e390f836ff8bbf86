"""The Slang compiler, called through Slang's C API with ctypes, in a child process.

The slangpy wheel (the optional extra ``slang``: ``pip install -e ".[slang]"``) ships
no ``slangc`` program but the compiler as a library, ``libslang-compiler.so.0.<version>``,
which exports Slang's C API: ``spCreateSession``, ``spCreateCompileRequest``,
``spProcessCommandLineArguments`` (the arguments of ``slangc``), ``spCompile``,
``spGetDiagnosticOutput``, ``spGetEntryPointSource`` (text targets) and
``spGetTargetCodeBlob`` (SPIR-V: ``spGetEntryPointCode`` returns NULL there and
``spGetEntryPointCodeBlob`` crashes). Each compile runs in a child process, as
glslang does (:mod:`._toolchain`): memory and time limits, and a crash of the
library is a :class:`~._source.ShaderError`, never this process's end.

Run as a script (``python _slang.py OUT ARGS...``) it is that child: it imports only
the standard library.
"""

from __future__ import annotations

import ctypes
import glob
import os
import sys

__all__ = ["library_path", "available", "compile_slang", "slang_glsl", "identifiers", "errors", "version", "to_gl", "INSTALL"]

#: What a porter without the extra is told.
INSTALL = 'the Slang compiler is not installed: pip install -e ".[slang]" (or: pip install slangpy)'
_TEXT_TARGETS = ("glsl", "wgsl", "hlsl", "cpp", "cuda", "metal")


def library_path():
    """Path of ``libslang-compiler.so*`` in the slangpy wheel (``MOMENTS_REF_SLANG_LIB`` overrides), or None."""
    env = os.environ.get("MOMENTS_REF_SLANG_LIB")
    if env:
        return env if os.path.isfile(env) else None
    import importlib.util

    try:
        spec = importlib.util.find_spec("slangpy")
    except (ImportError, ValueError):
        return None
    if spec is None or not spec.origin:
        return None
    found = sorted(glob.glob(os.path.join(os.path.dirname(spec.origin), "libslang-compiler.so*")))
    return found[0] if found else None


def available():
    """Whether the Slang compiler library is installed."""
    return library_path() is not None


def _require():
    from ._toolchain import ToolError

    lib = library_path()
    if lib is None:
        raise ToolError(INSTALL)
    return lib


def compile_slang(text, args, what="Slang", binary=False):
    """Compile ``text`` (a Slang module) with ``slangc``-style ``args``; ``(code, diagnostics)``.

    ``code`` is str (text targets) or bytes (``binary``), or None with the
    diagnostics when the compile failed.
    """
    import tempfile
    from pathlib import Path

    from ._toolchain import run_child

    lib = _require()
    with tempfile.TemporaryDirectory(prefix="moments-ref-slang-") as tmp:
        src, out = Path(tmp) / "mr_module.slang", Path(tmp) / "out.bin"
        src.write_text(text)
        code, log = run_child([sys.executable, "-S", __file__, lib, str(out), *args, str(src)], what)
        if code != 0 or not out.is_file():
            return None, log
        data = out.read_bytes()
        return (data if binary else data.decode("utf-8", "replace")), log


def identifiers(text, dirs, seen=None):
    """The identifiers of ``text`` and of the modules it imports (``import name;`` found in ``dirs``).

    These are the porter's names, which Slang's renaming (``name_0``) is mapped back to.
    """
    import re
    from pathlib import Path

    from ._source import strip_comments

    seen = set() if seen is None else seen
    plain = strip_comments(text)
    names = set(re.findall(r"[A-Za-z_]\w*", plain))
    for mod in re.findall(r"^\s*(?:__exported\s+)?import\s+([\w.]+)\s*;", plain, flags=re.M):
        found = next((Path(d) / f"{mod.replace('.', '/')}.slang" for d in dirs
                      if (Path(d) / f"{mod.replace('.', '/')}.slang").is_file()), None)
        if found is not None and found.resolve() not in seen:
            seen.add(found.resolve())
            names |= identifiers(found.read_text(encoding="utf-8", errors="replace"), dirs, seen)
    return names


def errors(log):
    """Slang's diagnostics as one line per error: ``file:line:col: error: what`` (notes and warnings dropped)."""
    import re

    out, head, loc = [], None, None
    for line in log.splitlines():
        m = re.match(r"^(error|warning|note)(\[\w+\])?:\s*(.*)$", line)
        if m:
            head, loc = (m.group(3) if m.group(1) == "error" else None), None
            continue
        m = re.match(r"^\s*-->\s*(.*)$", line)
        if m and head is not None:
            loc = m.group(1).strip()
            continue
        m = re.match(r"^\s*\|\s*\^+\s*(.*)$", line)
        if m and head is not None:
            out.append(f"{loc or '<slang>'}: error: {m.group(1).strip() or head}")
            head = None
    if head is not None:
        out.append(f"{loc or '<slang>'}: error: {head}")
    return out or [x.strip() for x in log.splitlines() if "error" in x.lower()] or [log.strip() or "no message"]


def slang_glsl(text, entry, include_dirs=(), signature=None, rename=None):
    """Slang's (Vulkan) GLSL for the compute entry point ``entry`` of ``text``.

    ``include_dirs`` are searched for ``import``-ed modules; compile errors raise a
    :class:`~._source.ShaderError`, one line per error, with the porter's file,
    line and names (``rename(line)`` maps Slang's renaming ``name_0`` back:
    :func:`.languages.unmangle`).
    """
    from ._source import ShaderError, wrapped_compile_error

    args = ["-target", "glsl", "-profile", "glsl_450", "-entry", entry, "-stage", "compute",
            "-line-directive-mode", "none"]
    for d in include_dirs:
        args += ["-I", str(d)]
    code, log = compile_slang(text, args)
    if code is None:
        lines = [rename(e) if rename else e for e in errors(log)]
        if signature is None:
            raise ShaderError("the Slang file does not compile (Slang):\n" + "\n".join(lines))
        raise wrapped_compile_error("Slang", lines, signature)
    return code


def version():
    """Slang's build tag (``2026.12``), or None without the extra."""
    from ._toolchain import run_child

    lib = library_path()
    if lib is None:
        return None
    code, log = run_child([sys.executable, "-S", __file__, lib, "--version"], "Slang")
    return f"Slang {log.strip()}" if code == 0 else None


def to_gl(glsl):
    """Slang's (Vulkan) GLSL made acceptable to an OpenGL driver.

    ``set = N`` goes (OpenGL has no descriptor sets), and the barrier Slang writes for
    ``GroupMemoryBarrierWithGroupSync()`` (``controlBarrier`` of
    ``GL_KHR_memory_scope_semantics``, which llvmpipe's OpenGL refuses) becomes
    ``memoryBarrierShared(); barrier();``, which is what it means.
    """
    import re

    text = re.sub(r",\s*set\s*=\s*\d+|\bset\s*=\s*\d+\s*,\s*", "", glsl)
    text = re.sub(r"^\s*#extension\s+GL_KHR_memory_scope_semantics\b.*$", "", text, flags=re.M)
    text = re.sub(r"\bcontrolBarrier\s*\([^;]*\)\s*;", "memoryBarrierShared(); barrier();", text)
    return re.sub(r"\bmemoryBarrier\s*\(\s*gl_ScopeWorkgroup[^;]*\)\s*;", "memoryBarrierShared();", text)


# ----------------------------------------------------------------------------------------
# The child process
# ----------------------------------------------------------------------------------------

def _blob_bytes(blob):
    """The bytes of an ISlangBlob (vtable: queryInterface, addRef, release, getBufferPointer, getBufferSize)."""
    vt = ctypes.cast(ctypes.cast(blob, ctypes.POINTER(ctypes.c_void_p))[0], ctypes.POINTER(ctypes.c_void_p))
    ptr = ctypes.CFUNCTYPE(ctypes.c_void_p, ctypes.c_void_p)(vt[3])(blob)
    size = ctypes.CFUNCTYPE(ctypes.c_size_t, ctypes.c_void_p)(vt[4])(blob)
    return ctypes.string_at(ptr, size)


def _child(argv):
    lib = ctypes.CDLL(argv[0])
    lib.spGetBuildTagString.restype = ctypes.c_char_p
    if argv[1] == "--version":
        print(lib.spGetBuildTagString().decode())
        return 0
    vp = ctypes.c_void_p
    lib.spCreateSession.restype, lib.spCreateSession.argtypes = vp, [ctypes.c_char_p]
    lib.spCreateCompileRequest.restype, lib.spCreateCompileRequest.argtypes = vp, [vp]
    lib.spProcessCommandLineArguments.argtypes = [vp, ctypes.POINTER(ctypes.c_char_p), ctypes.c_int]
    lib.spCompile.argtypes = [vp]
    lib.spGetDiagnosticOutput.restype, lib.spGetDiagnosticOutput.argtypes = ctypes.c_char_p, [vp]
    lib.spGetEntryPointSource.restype, lib.spGetEntryPointSource.argtypes = ctypes.c_char_p, [vp, ctypes.c_int]
    lib.spGetTargetCodeBlob.argtypes = [vp, ctypes.c_int, ctypes.POINTER(vp)]
    out, args = argv[1], [a.encode() for a in argv[2:]]
    req = lib.spCreateCompileRequest(lib.spCreateSession(None))
    if lib.spProcessCommandLineArguments(req, (ctypes.c_char_p * len(args))(*args), len(args)) < 0:
        sys.stderr.write((lib.spGetDiagnosticOutput(req) or b"bad arguments").decode("utf-8", "replace"))
        return 1
    failed = lib.spCompile(req) < 0
    sys.stderr.write((lib.spGetDiagnosticOutput(req) or b"").decode("utf-8", "replace"))
    if failed:
        return 1
    target = argv[argv.index("-target") + 1] if "-target" in argv else ""
    if target in _TEXT_TARGETS:
        data = lib.spGetEntryPointSource(req, 0)
    else:
        blob = vp()
        data = _blob_bytes(blob) if lib.spGetTargetCodeBlob(req, 0, ctypes.byref(blob)) >= 0 and blob.value else None
    if not data:
        sys.stderr.write("error: Slang produced no code (a file of functions alone needs an entry point)\n")
        return 1
    with open(out, "wb") as fh:
        fh.write(data)
    return 0


if __name__ == "__main__":
    sys.exit(_child(sys.argv[1:]))
