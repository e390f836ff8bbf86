"""OpenGL backend: moderngl on EGL (Mesa llvmpipe without a GPU).

Requirements: ``pip install moderngl`` and an EGL driver; on Debian/Ubuntu
``apt-get install libegl1 libegl-mesa0 libgl1-mesa-dri``.
"""

from __future__ import annotations

import hashlib
import time

import numpy as np

from ._slots import as_buffer
from ._source import ShaderError, one_line_errors

__all__ = ["ContextError", "create_context", "get_context", "renderer", "run_program"]

#: Most work groups per dispatch dimension that every driver guarantees.
MAX_GROUPS = 65535
_CONTEXT = None
_PROGRAMS = {}
_HINT = ("install the Python package 'moderngl' and an EGL driver "
         "(Debian/Ubuntu: apt-get install libegl1 libegl-mesa0 libgl1-mesa-dri)")


class ContextError(RuntimeError):
    """No driver (OpenGL 4.3 compute context, Vulkan adapter or compiler); ``str(exc)`` says why."""


def create_context(require=430):
    """A standalone OpenGL context (EGL, no window) of at least version ``require``.

    Raises
    ------
    ContextError
        moderngl missing, no EGL library or driver, or a version below ``require``;
        the message names the cause and the Debian packages to install.
    """
    try:
        import moderngl
    except ImportError as exc:
        raise ContextError(f"moderngl is not importable ({exc}); {_HINT}") from None
    try:
        ctx = moderngl.create_standalone_context(backend="egl", require=require)
    except Exception as exc:  # moderngl raises plain Exception subclasses for EGL failures
        raise ContextError(f"no OpenGL {require // 100}.{require % 100 // 10} context through EGL: "
                           f"{type(exc).__name__}: {exc}; {_HINT}") from None
    if ctx.version_code < require:
        version = ctx.version_code
        ctx.release()
        raise ContextError(f"the EGL context offers OpenGL {version}, compute shaders need {require}; {_HINT}")
    return ctx


def get_context():
    """The process-wide context (created on first use, then reused)."""
    global _CONTEXT
    if _CONTEXT is None:
        _CONTEXT = create_context()
    return _CONTEXT


def renderer(ctx):
    """``'llvmpipe (LLVM 15.0.6, 256 bits), OpenGL 4.5 (Core Profile) Mesa 22.3.6'``."""
    with ctx:  # wgpu's OpenGL adapter may have made its own context current
        info = ctx.info
    return f"{info.get('GL_RENDERER', '?')}, OpenGL {info.get('GL_VERSION', '?')}"


def _mesa_errors(log, name_of):
    """Mesa's ``k:line(col): error: ...`` lines as ``file:line:col: error: ...``."""
    return one_line_errors(log, r"\b(\d+):(\d+)\((\d+)\)",
                           lambda m: f"{name_of(int(m.group(1)))}:{m.group(2)}:{m.group(3)}")


def _program(ctx, text, name_of, signature):
    key = (id(ctx), hashlib.sha256(text.encode()).hexdigest())
    if key not in _PROGRAMS:
        try:
            _PROGRAMS[key] = ctx.compute_shader(text)
        except Exception as exc:
            raise ShaderError(f"the wrapped function does not compile (expected signature: {signature}):\n"
                              + "\n".join(_mesa_errors(str(exc), name_of))) from None
    return _PROGRAMS[key]


def groups(n, local_size):
    """``(gx, gy)`` work groups covering ``n`` rows (2-D beyond MAX_GROUPS)."""
    total = -(-n // local_size)
    gx = min(total, MAX_GROUPS)
    return gx, -(-total // gx)


def run_program(text, name_of, signature, ins, outs, arrays, n, local_size, ctx=None):
    """Compile (cached) and dispatch a wrapped GLSL compute shader; see :mod:`._wrap`.

    Returns ``(results, timings)``; ``timings`` has ``compile``, ``upload``,
    ``dispatch`` and ``readback`` seconds.
    """
    ctx = ctx or get_context()
    # wgpu's OpenGL adapter makes its own EGL context current: make ours current again.
    with ctx:
        return _run(ctx, text, name_of, signature, ins, outs, arrays, n, local_size)


def _run(ctx, text, name_of, signature, ins, outs, arrays, n, local_size):
    timings = {}
    t0 = time.perf_counter()
    program = _program(ctx, text, name_of, signature)
    timings["compile"] = time.perf_counter() - t0
    gx, gy = groups(n, local_size)
    params = np.array([n, gx * local_size], np.uint32)
    buffers = []
    try:
        t0 = time.perf_counter()
        for s in ins:
            buffers.append(ctx.buffer(as_buffer(arrays[s.name], s).tobytes()))
        out_bufs = [ctx.buffer(reserve=n * s.width * 4) for s in outs]
        buffers += out_bufs + [ctx.buffer(params.tobytes())]
        for b, buf in enumerate(buffers):
            buf.bind_to_storage_buffer(b)
        ctx.finish()
        timings["upload"] = time.perf_counter() - t0
        t0 = time.perf_counter()
        program.run(group_x=gx, group_y=gy)
        ctx.finish()
        timings["dispatch"] = time.perf_counter() - t0
        t0 = time.perf_counter()
        results = {s.name: np.frombuffer(buf.read(), dtype=s.upload).reshape(n, s.width)[:, : s.components].copy()
                   for s, buf in zip(outs, out_bufs)}
        timings["readback"] = time.perf_counter() - t0
    finally:
        for buf in buffers:
            buf.release()
    return results, timings

