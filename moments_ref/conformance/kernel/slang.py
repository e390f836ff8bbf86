"""Slang kernels: the porter's file through Slang's GLSL, on OpenGL and (through glslang) on Vulkan.

Slang (:mod:`.._slang`) compiles the file at ``--entry`` to Vulkan GLSL, which
glslang compiles to SPIR-V (Slang's own SPIR-V drops ``precise``): wgpu runs it on
Vulkan, and OpenGL gets SPIRV-Cross's GLSL of it, as for HLSL kernels (Slang's GLSL
reads textures without samplers and waits at barriers with
``GL_KHR_memory_scope_semantics``, neither of which llvmpipe's OpenGL takes). Slang renames the porter's names (``depth`` becomes
``depth_0``, a ``cbuffer Params`` block ``Params_0``); the reflection is mapped back
(:func:`.._languages.unmangle`), so that bindings match the contract by the porter's
names and every message names them as the file does.
"""

from __future__ import annotations

import re
from dataclasses import replace
from pathlib import Path

from ...ports import PORTS_DIR
from .. import _slang
from .._source import load_source
from ..languages import unmangle
from . import _spirv
from .reflect import from_spirv

__all__ = ["slang_kernel", "unmangled"]


def unmangled(iface, known):
    """The interface with Slang's renamed resource, block and member names mapped back to ``known`` names."""
    back = lambda s: unmangle("slang", s, known)  # noqa: E731
    res = [replace(r, name=back(r.name), declared=back(r.declared), names=tuple(back(n) for n in r.names),
                   members=tuple(replace(m, name=back(m.name)) for m in r.members)) for r in iface.resources]
    return replace(iface, resources=res)


def slang_kernel(path, entry, driver, cached, include_dirs=(), defines=(), prelude=None):
    """``(code, interface, toolchain, source)`` of a Slang kernel for ``driver`` (``gl`` or ``vulkan``).

    ``cached(key, make)`` memoises the compiles (the kernel runner's cache).
    """
    src = load_source(path, "slang", include_dirs, defines, prelude)
    body = re.sub(r"^#line (\d+) (\d+)$", lambda m: f'#line {m.group(1)} "{src.name(int(m.group(2)))}"', src.body,
                  flags=re.M)
    dirs = [Path(path).resolve().parent, *include_dirs, PORTS_DIR / "slang"]
    known = _slang.identifiers(src.body, dirs)
    glsl = cached(("slang", body, entry, tuple(map(str, dirs))),
                  lambda: _slang.slang_glsl(body, entry, dirs, None, lambda e: unmangle("slang", e, known)))
    spv = cached(("slang-glsl", glsl), lambda: _spirv.glsl_to_spirv(glsl, lambda k: "<Slang's GLSL>"))
    if driver == "gl":
        iface = from_spirv(cached(("reflect", spv), lambda: _spirv.reflect_spirv(spv)), "slang", "main")
        text = cached(("spirv-cross", spv), lambda: _spirv.spirv_to_gl(spv))
        return text, unmangled(iface, known), "Slang through its GLSL, glslang, SPIRV-Cross and moderngl", src
    code = cached(("naga", spv), lambda: _spirv.for_naga(spv))
    iface = from_spirv(cached(("reflect", code), lambda: _spirv.reflect_spirv(code)), "slang", "main")
    return code, unmangled(iface, known), "Slang through its GLSL, glslang and wgpu", src
