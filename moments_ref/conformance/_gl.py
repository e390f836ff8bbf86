"""OpenGL backend: moderngl on EGL (Mesa llvmpipe without a GPU), in the driver process.

The context lives in the driver process of :mod:`._supervisor`; :func:`get_context`
returns its description and :func:`run_program` sends it work. :func:`dispatch`
is the general backend function there (any storage buffers, any grid).

Requirements: ``pip install moderngl`` and an EGL driver; on Debian/Ubuntu
``apt-get install libegl1 libegl-mesa0 libgl1-mesa-dri``.
"""

from __future__ import annotations

import hashlib
import time

import numpy as np

from ._errors import ContextError, LocalCompileError
from ._slots import as_buffer
from ._source import one_line_errors, wrapped_compile_error

__all__ = ["ContextError", "create_context", "get_context", "renderer", "run_program", "dispatch", "open_local",
           "LocalGL", "LocalCompileError", "RemoteContext", "case_bindings", "case_results"]

#: Most work groups per dispatch dimension that every driver guarantees.
MAX_GROUPS = 65535
_CONTEXT = None
_PROGRAMS = {}
_HINT = ("install the Python package 'moderngl' and an EGL driver "
         "(Debian/Ubuntu: apt-get install libegl1 libegl-mesa0 libgl1-mesa-dri)")


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


def renderer(ctx):
    """``'llvmpipe (LLVM 15.0.6, 256 bits), OpenGL 4.5 (Core Profile) Mesa 22.3.6'``."""
    if isinstance(ctx, RemoteContext):
        return ctx.renderer
    with ctx:  # wgpu's OpenGL adapter may have made its own context current
        info = ctx.info
    return f"{info.get('GL_RENDERER', '?')}, OpenGL {info.get('GL_VERSION', '?')}"


class RemoteContext:
    """The OpenGL context of the driver process (:mod:`._supervisor`): renderer, version, SPIR-V support."""

    def __init__(self, renderer, version_code, spirv=False):
        self.renderer, self.version_code, self.spirv = renderer, version_code, spirv


def get_context():
    """The OpenGL context of the driver process (started on first use, then reused).

    Raises :class:`ContextError` without a driver (the reason and the packages).
    """
    global _CONTEXT
    if _CONTEXT is None:
        from ._dispatch import open_target

        _CONTEXT = RemoteContext(*open_target(("gl",)))
    return _CONTEXT


def _mesa_errors(log, name_of):
    """Mesa's ``k:line(col): error: ...`` lines as ``file:line:col: error: ...``."""
    return one_line_errors(log, r"\b(\d+):(\d+)\((\d+)\)",
                           lambda m: f"{name_of(int(m.group(1)))}:{m.group(2)}:{m.group(3)}")


def groups(n, local_size):
    """``(gx, gy)`` work groups covering ``n`` rows (2-D beyond MAX_GROUPS)."""
    total = -(-n // local_size)
    gx = min(total, MAX_GROUPS)
    return gx, -(-total // gx)


def case_bindings(ins, outs, arrays, n, local_size, tex=None):
    """The harness's buffers (and textures, :mod:`._textures`) of one case: inputs, outputs, ``mr_params``;
    and the grid."""
    from ._dispatch import Binding
    from ._textures import texel_bytes

    gx, gy = groups(n, local_size)
    tex = tex or {}
    b = [Binding(k, texel_bytes(arrays[s.name], tex[s.name]), 0, "texture",
                 (tex[s.name].width, tex[s.name].height, tex[s.name].format) + (("linear",) if tex[s.name].quad else ()))
         if s.name in tex else Binding(k, as_buffer(arrays[s.name], s).tobytes(), 0, "read") for k, s in enumerate(ins)]
    b += [Binding(len(ins) + k, None, max(16, n * s.width * 4), "write") for k, s in enumerate(outs)]
    b.append(Binding(len(ins) + len(outs), np.array([n, gx * local_size, 0, 0], np.uint32).tobytes(), 0, "read"))
    nb = len(ins) + len(outs) + 1  # samplers of sampled textures follow mr_params (:mod:`._wrap`)
    b += [Binding(nb + k, None, 0, "sampler:linear" if tex[s.name].quad else "sampler") for k, s in enumerate(ins)
          if s.name in tex and tex[s.name].sampler]
    return b, (gx, gy, 1)


def case_results(outs, ins, raw, n):
    """Readback bytes of the output bindings as ``{name: (n, components) array}``."""
    return {s.name: np.frombuffer(raw[len(ins) + k], dtype=s.upload)[: n * s.width]
            .reshape(n, s.width)[:, : s.components].copy() for k, s in enumerate(outs)}


def run_program(text, name_of, signature, ins, outs, arrays, n, local_size, ctx=None, entry="main", tex=None):
    """Compile (cached) and dispatch a wrapped compute shader in the driver process; see :mod:`._wrap`.

    ``text`` is GLSL, or a SPIR-V module (bytes) with its entry point ``entry``.

    Returns ``(results, timings)``; ``timings`` has ``compile``, ``upload``,
    ``dispatch`` and ``readback`` seconds.
    """
    from ._dispatch import dispatch

    get_context() if ctx is None else ctx
    bindings, grid = case_bindings(ins, outs, arrays, n, local_size, tex)

    def failed(log):
        return wrapped_compile_error("", _mesa_errors(log, name_of), signature)

    raw, timings = dispatch(("gl",), text, bindings, grid, entry, on_compile_error=failed)
    return case_results(outs, ins, raw, n), timings


# ----------------------------------------------------------------------------------------
# In the driver process
# ----------------------------------------------------------------------------------------

class LocalGL:
    """The OpenGL context inside the driver process: compile and dispatch."""

    def __init__(self, ctx):
        from ._glspirv import available

        self.ctx = ctx
        self.renderer, self.version_code = renderer(ctx), ctx.version_code
        with ctx:
            self.spirv = available(ctx)

    def compile(self, code, entry=None, group=None, modes=None):
        """A program from GLSL text (moderngl) or a SPIR-V module (bytes, entry point ``entry``)."""
        from ._glspirv import SpirvProgram

        key = (entry, hashlib.sha256(code if isinstance(code, bytes) else code.encode()).hexdigest())
        if key not in _PROGRAMS:
            with self.ctx:
                try:
                    _PROGRAMS[key] = (SpirvProgram(code, entry or "main") if isinstance(code, bytes)
                                      else self.ctx.compute_shader(code))
                except Exception as exc:
                    raise LocalCompileError(str(exc)) from None
        return _PROGRAMS[key]

    def dispatch(self, program, bindings, grid, group=None):
        with self.ctx:
            return dispatch(self.ctx, program, bindings, grid)


def open_local():
    """A :class:`LocalGL` on a new EGL context (in the driver process)."""
    return LocalGL(create_context())


#: moderngl's (components, dtype) of the texture formats of :mod:`._textures`.
_TEXTURE_FORMATS = {"r32float": (1, "f4"), "rg32float": (2, "f4"), "rgba32float": (4, "f4"), "r32uint": (1, "u4"),
                    "rg32uint": (2, "u4"), "rgba32uint": (4, "u4"), "r16uint": (1, "u2"), "rg16uint": (2, "u2"),
                    "rgba16uint": (4, "u2"), "rgba16unorm": (4, "nu2")}


def _texture(ctx, b):
    """A texture at unit ``b.binding`` holding ``b.data``: nearest filtering (texel loads), or linear
    (a bilinear case), clamped to the edge, one mipmap level."""
    import moderngl

    w, h, fmt = b.texture[:3]
    comps, dtype = _TEXTURE_FORMATS[fmt]
    tex = ctx.texture((w, h), comps, b.data, dtype=dtype)
    f = moderngl.LINEAR if b.texture[3:] == ("linear",) else moderngl.NEAREST
    tex.filter = (f, f)
    tex.repeat_x = tex.repeat_y = False
    tex.use(location=b.binding)
    return tex


def dispatch(ctx, program, bindings, grid):
    """Bind storage buffers (:class:`~._dispatch.Binding`), dispatch ``grid`` work groups, read back.

    Returns ``({binding: bytes} of the "write" buffers, timings)``.
    """
    timings, buffers = {"compile": 0.0}, []
    try:
        t0 = time.perf_counter()
        for b in bindings:
            if b.mode.startswith("sampler"):
                continue  # OpenGL: the texture's own filtering (nearest, or linear for a bilinear case)
            if b.mode == "texture":
                buffers.append((b, _texture(ctx, b)))
                continue
            buf = ctx.buffer(b.data) if b.data is not None else ctx.buffer(reserve=b.size)
            buf.bind_to_storage_buffer(b.binding)
            buffers.append((b, buf))
        ctx.finish()
        timings["upload"] = time.perf_counter() - t0
        t0 = time.perf_counter()
        program.run(*grid)
        ctx.finish()
        timings["dispatch"] = time.perf_counter() - t0
        t0 = time.perf_counter()
        out = {b.binding: buf.read() for b, buf in buffers if b.mode == "write"}
        timings["readback"] = time.perf_counter() - t0
    finally:
        for _, buf in buffers:
            buf.release()
    return out, timings
