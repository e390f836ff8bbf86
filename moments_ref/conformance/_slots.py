"""Golden arrays as shader values: one type mapping for GLSL, HLSL and WGSL.

=====================  ===========  ===========  ================  =====================
golden array           GLSL         HLSL         WGSL              buffer element
=====================  ===========  ===========  ================  =====================
(n,) float             ``float``    ``float``    ``f32``           float32
(n, k) float, k 2..4   ``veck``     ``floatk``   ``veck<f32>``     float32 ×k (×4 for k 3)
(n, k) float, k 5..16  ``float[k]`` ``float[k]`` ``array<f32,k>``  float32 ×k
(n,) uint32            ``uint``     ``uint``     ``u32``           uint32
(n, k) uint16/uint32   ``uveck``    ``uintk``    ``veck<u32>``     uint32 (uint16 widened)
int                    ``int``...   ``int``...   ``i32``...        int32
=====================  ===========  ===========  ================  =====================

A function with one output returns it; with several, the outputs follow the inputs
as ``out`` parameters (GLSL, HLSL) or ``ptr<function, T>`` (WGSL), in the manifest's
order.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._arrays import InputError

__all__ = ["Slot", "signature", "as_buffer"]

_SCALARS = {"f": ("float", "vec", "float", "f32", np.float32),
            "u": ("uint", "uvec", "uint", "u32", np.uint32),
            "i": ("int", "ivec", "int", "i32", np.int32)}


@dataclass(frozen=True)
class Slot:
    """One golden array as a shader value: name, scalar kind, components, upload dtype."""

    name: str
    kind: str  # "f", "u" or "i"
    components: int
    upload: np.dtype

    @staticmethod
    def of(name, dtype, shape):
        dtype = np.dtype(dtype)
        if len(shape) == 1:
            k = 1
        elif len(shape) == 2 and 2 <= shape[1] <= 16:
            k = shape[1]
        else:
            raise InputError(f"{name}: expected shape (n,) or (n, 2..16) to map to a shader type, got {tuple(shape)}")
        kind = {"f": "f", "u": "u", "i": "i", "b": "i"}.get(dtype.kind)
        if kind is None:
            raise InputError(f"{name}: expected a float or integer array, got dtype {dtype}")
        if k > 4 and kind != "f":
            raise InputError(f"{name}: integer rows of more than 4 values are not supported, got {tuple(shape)}")
        return Slot(name, kind, k, np.dtype(_SCALARS[kind][4]))

    @property
    def is_array(self):
        return self.components > 4

    @property
    def width(self):
        """32-bit words per row in the buffer (a vec3 is padded to 4)."""
        return 4 if self.components == 3 else self.components

    def type(self, lang):
        """The value's type in ``lang`` (``glsl``, ``hlsl``, ``wgsl``)."""
        glsl, vec, hlsl, wgsl, _ = _SCALARS[self.kind]
        k = self.components
        if lang == "wgsl":
            return wgsl if k == 1 else (f"array<{wgsl}, {k}>" if k > 4 else f"vec{k}<{wgsl}>")
        if k == 1 or k > 4:
            return glsl
        return f"{vec}{k}" if lang == "glsl" else f"{hlsl}{k}"

    def element(self, lang):
        """The buffer element type (arrays are stored flat, vec3 padded to vec4)."""
        if self.is_array or self.components == 1:
            return Slot(self.name, self.kind, 1, self.upload).type(lang)
        return Slot(self.name, self.kind, self.width, self.upload).type(lang)

    def declare(self, lang, name=None):
        """``vec4 b`` / ``float b[6]`` / ``b: vec4<f32>``."""
        name = name or self.name
        if lang == "wgsl":
            return f"{name}: {self.type(lang)}"
        return f"{self.type(lang)} {name}" + (f"[{self.components}]" if self.is_array else "")

    @property
    def glsl(self):
        return self.type("glsl")


def signature(lang, function, inputs, outputs, replaced=None):
    """The signature the harness calls, e.g. ``float f(vec4 b, float zf)``.

    ``replaced`` maps an input to the parameters written in its place (texture arguments).
    """
    from .languages import TABLE

    lang = TABLE[lang].types if lang in TABLE else lang  # the contract's spelling (Slang: HLSL's)
    replaced = replaced or {}
    # A replaced input is written as its parameters; "" drops it (carried by another's coordinate).
    args = [replaced[s.name] if s.name in replaced else s.declare(lang) for s in inputs]
    args = [a for a in args if a]
    if lang == "wgsl":
        if len(outputs) == 1:
            return f"fn {function}({', '.join(args)}) -> {outputs[0].type(lang)}"
        args += [f"{s.name}: ptr<function, {s.type(lang)}>" for s in outputs]
        return f"fn {function}({', '.join(args)})"
    if len(outputs) == 1:
        return f"{outputs[0].type(lang)} {function}({', '.join(args)})"
    args += [f"out {s.declare(lang)}" for s in outputs]
    return f"void {function}({', '.join(args)})"


def as_buffer(arr, slot):
    """Rows of ``arr`` as a contiguous (n, width) array of the slot's upload dtype."""
    a = np.asarray(arr)
    if a.dtype.kind == "u" and slot.upload == np.uint32 and a.size and a.max() > np.iinfo(np.uint32).max:
        raise InputError(f"{slot.name}: values do not fit uint32")
    a = a.astype(slot.upload).reshape(len(a), -1)
    if slot.components == 3:
        a = np.concatenate([a, np.zeros((len(a), 1), a.dtype)], axis=1)
    return np.ascontiguousarray(a)
