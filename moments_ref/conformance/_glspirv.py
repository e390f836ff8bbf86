"""SPIR-V straight to the OpenGL driver (GL_ARB_gl_spirv), and SPIR-V evaluated as written.

moderngl compiles GLSL text only; a SPIR-V module is handed to the driver with the
few OpenGL 4.6 / ARB_gl_spirv entry points it needs (``glShaderBinary``,
``glSpecializeShaderARB``), called through ctypes on the current EGL context, so
that the OpenGL path of HLSL reads the same SPIR-V as Vulkan, without a detour
through GLSL text (whose compiler rebalances and factors expressions).

:func:`exact_everywhere` decorates every floating-point arithmetic result of a
module ``NoContraction`` (what HLSL ``precise`` compiles to), so that the driver
evaluates each operation as the SPIR-V states it: rounded in program order, an
``Fma`` as one operation, no reassociation or factoring.
"""

from __future__ import annotations

import ctypes

import numpy as np

__all__ = ["exact_everywhere", "SpirvProgram", "available"]

# SPIR-V opcodes: float arithmetic whose results NoContraction pins.
_ARITH = {127, 129, 131, 133, 136, 140, 141, 142, 143, 144, 145, 146, 147, 148}  # FNegate .. Dot
_EXT_INST, _DECORATE, _NO_CONTRACTION = 12, 71, 42
_ANNOTATIONS = {71, 72, 73, 74, 75, 332, 5632, 5633}
_TYPE_FLOAT, _TYPE_VECTOR, _TYPE_MATRIX = 22, 23, 24


def _instructions(words):
    i = 5
    while i < len(words):
        count = int(words[i] >> 16)
        yield i, int(words[i] & 0xFFFF), words[i:i + max(count, 1)]
        i += max(count, 1)


def exact_everywhere(spirv):
    """``spirv`` with ``OpDecorate %r NoContraction`` for every float arithmetic result ``%r``."""
    words = np.frombuffer(spirv, np.uint32)
    floats, results, decorated, last_annotation = set(), [], set(), None
    for i, op, ins in _instructions(words):
        if op == _TYPE_FLOAT:
            floats.add(int(ins[1]))
        elif op in (_TYPE_VECTOR, _TYPE_MATRIX) and int(ins[2]) in floats:
            floats.add(int(ins[1]))
        elif op in _ANNOTATIONS:
            last_annotation = i + len(ins)
            if op == _DECORATE and len(ins) >= 3 and ins[2] == _NO_CONTRACTION:
                decorated.add(int(ins[1]))
        elif (op in _ARITH or op == _EXT_INST) and len(ins) >= 3 and int(ins[1]) in floats:
            results.append(int(ins[2]))
    new = [w for r in results if r not in decorated for w in ((3 << 16) | _DECORATE, r, _NO_CONTRACTION)]
    if not new:
        return spirv
    at = last_annotation or next(i for i, op, _ in _instructions(words) if 19 <= op <= 39)
    return np.concatenate([words[:at], np.array(new, np.uint32), words[at:]]).tobytes()


_GL = {}
_COMPUTE_SHADER, _SPIRV_FORMAT, _COMPILE_STATUS, _LINK_STATUS = 0x91B9, 0x9551, 0x8B81, 0x8B82


def _functions():
    """The GL entry points, from ``eglGetProcAddress`` (valid for any current EGL context)."""
    if not _GL:
        egl = ctypes.CDLL("libEGL.so.1")
        egl.eglGetProcAddress.restype = ctypes.c_void_p
        egl.eglGetProcAddress.argtypes = [ctypes.c_char_p]
        u, i, p, s = ctypes.c_uint, ctypes.c_int, ctypes.c_void_p, ctypes.c_char_p
        for name, res, args in (
                ("glCreateShader", u, (u,)), ("glShaderBinary", None, (i, ctypes.POINTER(u), u, p, i)),
                ("glSpecializeShaderARB", None, (u, s, u, p, p)), ("glGetShaderiv", None, (u, u, ctypes.POINTER(i))),
                ("glGetShaderInfoLog", None, (u, i, p, s)), ("glGetProgramInfoLog", None, (u, i, p, s)),
                ("glCreateProgram", u, ()), ("glAttachShader", None, (u, u)), ("glLinkProgram", None, (u,)),
                ("glGetProgramiv", None, (u, u, ctypes.POINTER(i))), ("glUseProgram", None, (u,)),
                ("glDeleteShader", None, (u,)), ("glDispatchCompute", None, (u, u, u)),
                ("glMemoryBarrier", None, (u,))):
            addr = egl.eglGetProcAddress(name.encode())
            if not addr:
                raise OSError(f"{name} is not available")
            _GL[name] = ctypes.CFUNCTYPE(res, *args)(addr)
    return _GL


def available(ctx):
    """Whether the context takes SPIR-V (GL_ARB_gl_spirv) and the entry points load."""
    if "GL_ARB_gl_spirv" not in ctx.extensions:
        return False
    try:
        _functions()
    except OSError:
        return False
    return True


class SpirvProgram:
    """A compute program made from a SPIR-V module on the current context; ``run(gx, gy, gz)``."""

    def __init__(self, spirv, entry):
        gl = _functions()
        shader = gl["glCreateShader"](_COMPUTE_SHADER)
        handle = ctypes.c_uint(shader)
        gl["glShaderBinary"](1, ctypes.byref(handle), _SPIRV_FORMAT, spirv, len(spirv))
        gl["glSpecializeShaderARB"](shader, entry.encode(), 0, None, None)
        ok = ctypes.c_int()
        gl["glGetShaderiv"](shader, _COMPILE_STATUS, ctypes.byref(ok))
        if not ok.value:
            log = ctypes.create_string_buffer(8192)
            gl["glGetShaderInfoLog"](shader, len(log), None, log)
            raise RuntimeError(log.value.decode("utf-8", "replace") or "the driver refused the SPIR-V module")
        self.program = gl["glCreateProgram"]()
        gl["glAttachShader"](self.program, shader)
        gl["glLinkProgram"](self.program)
        gl["glDeleteShader"](shader)
        gl["glGetProgramiv"](self.program, _LINK_STATUS, ctypes.byref(ok))
        if not ok.value:
            log = ctypes.create_string_buffer(8192)
            gl["glGetProgramInfoLog"](self.program, len(log), None, log)
            raise RuntimeError(log.value.decode("utf-8", "replace") or "the driver could not link the SPIR-V module")

    def run(self, gx=1, gy=1, gz=1):
        gl = _functions()
        gl["glUseProgram"](self.program)
        gl["glDispatchCompute"](gx, gy, gz)
        gl["glMemoryBarrier"](0xFFFFFFFF)  # GL_ALL_BARRIER_BITS: the readback sees the writes
        gl["glUseProgram"](0)
