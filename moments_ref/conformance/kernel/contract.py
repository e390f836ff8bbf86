"""The kernel contract: what the harness binds, the uniform block, the work groups and the dispatches.

Every kernel case has three bindings in descriptor set / bind group 0, matched to
the kernel's declarations by name (the resource's or its block's name, any case)
or, failing that, by set and binding:

===========================  =======  ==================================================================
slot                         binding  what the harness binds
===========================  =======  ==================================================================
``depth`` (filter cases)     0        the 4× MSAA map: a multisampled depth texture (``Texture2DMS<float>``,
                                      ``texture_depth_multisampled_2d``, ``sampler2DMS``) holding window
                                      depth d = (z + 1)/2, or a read-only storage buffer of floats
                                      ``d[(y·W + x)·S + s]``
``points`` (VWSS)            0        storage buffer of N ``vec4`` (x, y, z, 1)
``texels`` / ``moments``     1        the output: a storage image (``RWTexture2D<uint4>`` rgba32ui for
                                      nlq64 and msm64, ``<uint>`` r32ui for nlq32, ``<float4>`` rgba32f
                                      for moments) or a storage buffer, one element per texel at y·W + x
``depth`` (VWSS)             1        storage buffer of V·H·W ``uint`` keys (atomics), cleared to 0
``params``                   2        the uniform block :data:`PARAMS` (std140 = WGSL uniform = cbuffer)
===========================  =======  ==================================================================

The output is larger than the map (a block more to the right and below, or a
block row more in a buffer) and filled with a poison value: texels still
poisoned were never written, a changed texel beyond the map is a write outside it.

References
----------
.. [1] VWSS: Adam Marrs, Benjamin Watson and Christopher Healey. 2018. *View-warped Multi-view Soft
       Shadowing for Local Area Lights*. Journal of Computer Graphics Techniques (JCGT) 7, 3, 1–28.
       http://jcgt.org/published/0007/03/01/
.. [2] HPG17: Christoph Peters. 2017. *Non-Linearly Quantized Moment Shadow Maps*. In Proceedings
       of High Performance Graphics (HPG '17). ACM. The non-linear quantization Φ, Ψ4, Algorithms
       1–3, the texel formats and the compute shader of §4.1.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..._arrays import InputError

__all__ = ["Slot", "Contract", "Dispatch", "PARAMS", "PARAMS_BYTES", "MAX_VIEWS", "contract", "dispatches",
           "params_block", "OUTPUT_FORMATS", "BLOCK", "THREADS"]

#: Output block of one work group of the filter kernel (HPG17 §4.1) and its threads.
BLOCK = (32, 24)
THREADS = 256
#: Light views the uniform block holds (VWSS Listing 2: LIGHT_SAMPLES 32).
MAX_VIEWS = 32
#: The uniform block: (member, type, byte offset, meaning). std140, WGSL uniform and HLSL cbuffer agree.
PARAMS = (
    ("size", "uvec4", 0, "map width W, height H, MSAA samples S, light views V"),
    ("origin", "ivec4", 16, "xy: texel of work group (0, 0) of this dispatch (filter); z: first view of this "
                            "dispatch, w: views in it (VWSS)"),
    ("count", "uvec4", 32, "x: points N (VWSS)"),
    ("bias", "vec4", 48, "x: alpha of the moment bias the case applies before Phi (HPG17 §3.2), 0 if none"),
    ("bias_target", "vec4", 64, "b* of the bias"),
    ("view", f"mat4[{MAX_VIEWS}]", 80, "clip-from-world matrix of each light view, column-major: clip = view[k] * "
                                       "(x, y, z, 1) in GLSL and WGSL, mul(view[k], p) in HLSL (VWSS)"),
)
PARAMS_BYTES = 80 + 64 * MAX_VIEWS
#: Output image format of each filter format and the texel type a kernel writes.
OUTPUT_FORMATS = {"nlq64": ("rgba32ui", "uint4"), "nlq32": ("r32ui", "uint"), "msm64": ("rgba32ui", "uint4"),
                  "moments": ("rgba32f", "float4")}


@dataclass(frozen=True)
class Slot:
    """One binding of the contract: name, role, default binding (set 0) and the resource kinds accepted."""

    name: str
    role: str  # "input", "output" or "params"
    binding: int
    kinds: tuple  # of "texture_ms", "buffer", "storage_image", "uniform"
    format: str | None = None  # storage image format of an output
    element: str = ""  # buffer element type (for messages)

    def describe(self):
        kinds = {"texture_ms": "a multisampled depth texture", "buffer": f"a storage buffer of {self.element}",
                 "storage_image": f"a {self.format} storage image", "uniform": "the uniform block Params"}
        return f"{self.name} (set 0, binding {self.binding}: " + " or ".join(kinds[k] for k in self.kinds) + ")"


@dataclass(frozen=True)
class Contract:
    """What one kernel case binds and dispatches."""

    case: str
    slots: tuple
    threads: int | None  # invocations per work group the case needs (None: any)
    one_dimensional: bool  # work groups must be N×1×1
    workgroup_note: str

    def slot(self, name):
        return next(s for s in self.slots if s.name == name)

    @property
    def output(self):
        return next(s for s in self.slots if s.role == "output")

    @property
    def input(self):
        return next(s for s in self.slots if s.role == "input")

    def check_workgroup(self, size, where):
        """Raise InputError unless the kernel's work group ``size`` (x, y, z) fits the case."""
        x, y, z = (int(v) for v in size)
        bad = (self.threads is not None and x * y * z != self.threads) or (self.one_dimensional and (y, z) != (1, 1))
        if bad:
            raise InputError(f"work group: {where} declares {x}×{y}×{z} ({x * y * z} threads); {self.case} "
                             f"expects {self.workgroup_note}")


_PARAMS_SLOT = Slot("params", "params", 2, ("uniform",))


def contract(case, kwargs=None):
    """The :class:`Contract` of a kernel case (``kernel-filter-*`` or ``kernel-vwss-points``)."""
    if case == "kernel-vwss-points":
        return Contract(case, (Slot("points", "input", 0, ("buffer",), element="vec4 (x, y, z, 1)"),
                               Slot("depth", "output", 1, ("buffer",), element="uint (atomic keys)"),
                               _PARAMS_SLOT), None, True,
                        "one-dimensional work groups (N×1×1, any N): one thread per point, "
                        f"ceil(points / N) groups per dispatch")
    fmt = case.rsplit("-", 1)[-1]
    if not case.startswith("kernel-filter-") or fmt not in OUTPUT_FORMATS:
        raise InputError(f"case: {case!r} is not a kernel case (kernel-filter-nlq64, -nlq32, -msm64, -moments, "
                         "kernel-vwss-points)")
    image, element = OUTPUT_FORMATS[fmt]
    out = "moments" if fmt == "moments" else "texels"
    return Contract(case, (Slot("depth", "input", 0, ("texture_ms", "buffer"), element="float (window depth)"),
                           Slot(out, "output", 1, ("storage_image", "buffer"), image, element),
                           _PARAMS_SLOT), THREADS, False,
                    f"{THREADS} threads per work group in any shape (256×1×1, 16×16×1, ...): one work group per "
                    f"{BLOCK[0]}×{BLOCK[1]} output block (HPG17 §4.1)")


@dataclass(frozen=True)
class Dispatch:
    """One dispatch: work groups (x, y, z), the uniform block's bytes, and what it covers."""

    groups: tuple
    params: bytes
    blocks: int  # filter: blocks; VWSS: views


def params_block(size=(0, 0, 0, 0), origin=(0, 0, 0, 0), count=(0, 0, 0, 0), bias=0.0, target=(0, 0, 0, 0),
                 views=None):
    """The bytes of the uniform block :data:`PARAMS`."""
    b = bytearray(PARAMS_BYTES)
    b[0:16] = np.asarray(size, np.uint32).tobytes()
    b[16:32] = np.asarray(origin, np.int32).tobytes()
    b[32:48] = np.asarray(count, np.uint32).tobytes()
    b[48:64] = np.asarray([bias, 0, 0, 0], np.float32).tobytes()
    b[64:80] = np.asarray(target, np.float32).tobytes()
    if views is not None:
        v = np.asarray(views, np.float32)
        # Column-major: column c of view k at 80 + 64 k + 16 c.
        b[80:80 + 64 * len(v)] = np.ascontiguousarray(v.transpose(0, 2, 1)).tobytes()
    return bytes(b)


def dispatches(case, kwargs, views=None, local_x=1):
    """The dispatches of a case: the filter's block grid in tiles (origin in the uniform block),
    VWSS's views in passes of ``views_per_dispatch`` (first view and count in the uniform block).

    Tiles are half the grid's width and one block row, so that a kernel that ignores
    the origin writes the wrong blocks.
    """
    if case == "kernel-vwss-points":
        v, h, w, n = kwargs["views"], kwargs["height"], kwargs["width"], kwargs["points"]
        k = kwargs["views_per_dispatch"]
        groups = (-(-n // int(local_x)), 1, 1)
        return [Dispatch(groups, params_block((w, h, 0, v), (0, 0, v0, min(k, v - v0)), (n, 0, 0, 0), views=views),
                         min(k, v - v0)) for v0 in range(0, v, k)]
    h, w, s = kwargs["height"], kwargs["width"], kwargs["samples"]
    bias = kwargs.get("bias", {"alpha": 0.0, "target": [0, 0, 0, 0]})
    bx, by = -(-w // BLOCK[0]), -(-h // BLOCK[1])
    tile = max(1, -(-bx // 2))
    out = []
    for row in range(by):
        for c0 in range(0, bx, tile):
            n = min(tile, bx - c0)
            out.append(Dispatch((n, 1, 1), params_block((w, h, s, 0), (BLOCK[0] * c0, BLOCK[1] * row, 0, 0),
                                                        bias=bias["alpha"], target=bias["target"]), n))
    return out
