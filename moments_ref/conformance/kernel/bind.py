"""Match a kernel's declarations to the contract's slots; every mismatch is exit 2, naming the binding.

Rule (docs/ports.md, "Kernels"): a declared resource whose name (or its block's
name), compared without case, is a slot's name takes that slot; any other takes
the slot of its set and binding (set 0: 0 input, 1 output, 2 params). A resource
that matches no slot, two resources on one slot, a resource of a kind the slot
does not accept (a sampled texture where a storage image is bound, a wrong
image format, a buffer element of another size), a uniform block whose members
do not lie on the documented layout, and a kernel without an output are refused
with :class:`BindingError` (an :class:`~moments_ref.InputError`: exit 2).
"""

from __future__ import annotations

from dataclasses import dataclass

from ..._arrays import InputError
from .contract import PARAMS
from .reflect import TYPE_BYTES

__all__ = ["BindingError", "Bound", "match"]

#: Bytes per element of each slot's buffer form.
_ELEMENT_BYTES = {"depth": 4, "points": 16, "texels": None, "moments": 16}
_OUT_BYTES = {"rgba32ui": 16, "r32ui": 4, "rgba32f": 16}


class BindingError(InputError):
    """A kernel's declared binding does not fit the contract of the case."""


@dataclass(frozen=True)
class Bound:
    """A contract slot and the kernel's resource bound to it."""

    slot: object  # contract.Slot
    resource: object  # reflect.Resource


def _where(r):
    return f"binding {r.name!r} (set {r.set}, binding {r.binding}: {r.declared})"


def _element_bytes(slot):
    if slot.role == "output" and slot.format is not None:
        return _OUT_BYTES[slot.format]
    if slot.name == "depth" and slot.role == "output":
        return 4
    return _ELEMENT_BYTES.get(slot.name)


def _check_kind(slot, r, case, out_bytes=None):
    if r.kind not in slot.kinds:
        raise BindingError(f"{_where(r)} is bound to {slot.describe()} in {case}; got a {r.kind.replace('_', ' ')}")
    if r.kind == "storage_image" and r.format not in (None, slot.format):
        raise BindingError(f"{_where(r)}: {case} writes {slot.format} texels, the kernel declares {r.format}")
    if r.kind == "storage_image" and r.format is None:
        raise BindingError(f"{_where(r)} has no image format; declare it {slot.format} "
                           "(GLSL layout(rgba32ui), WGSL texture_storage_2d<rgba32uint, write>)")
    if r.kind == "buffer" and slot.role == "output" and out_bytes is not None:
        if r.stride is not None and r.stride not in out_bytes:
            raise BindingError(f"{_where(r)}: elements of {r.stride} bytes; the declared output layout has "
                               f"{' or '.join(map(str, out_bytes))}-byte elements")
    elif r.kind == "buffer":
        want = _element_bytes(slot)
        if r.stride is not None and want is not None and r.stride != want:
            raise BindingError(f"{_where(r)}: elements of {r.stride} bytes, {slot.describe()} has {want}-byte "
                               "elements")
        if slot.role == "input" and r.access != "read":
            pass  # a read-write input is allowed (the harness does not read it back)
    if r.kind == "storage_image" and slot.role == "output" and r.access == "read":
        raise BindingError(f"{_where(r)} is read-only; the output must be writable")


def _check_members(r, case):
    """Every member of the kernel's uniform block lies inside one documented member, of its scalar kind."""
    for m in r.members:
        span = m.stride * m.count if m.count > 1 else m.size
        doc = next((p for p in PARAMS if p[2] <= m.offset < p[2] + _param_bytes(p)), None)
        if doc is None or m.offset + span > doc[2] + _param_bytes(doc):
            raise BindingError(f"{_where(r)}: member {m.name!r} ({m.type}, offset {m.offset}, {span} bytes) is not "
                               f"inside one member of the documented block (Params: "
                               + ", ".join(f"{p[1]} {p[0]} at {p[2]}" for p in PARAMS) + ")")
        dkind = doc[1][0] if doc[1][0] in "ui" else "f"
        mkind = m.type[0] if m.type[0] in "ui" else "f"
        if dkind != mkind or ("mat" in doc[1]) != ("mat" in m.type):
            raise BindingError(f"{_where(r)}: member {m.name!r} is {m.type} at offset {m.offset}; the documented "
                               f"block has {doc[1]} {doc[0]} there")
        if "mat" in m.type and m.row_major:
            raise BindingError(f"{_where(r)}: member {m.name!r} is row-major; the view matrices are stored "
                               "column-major (GLSL/WGSL: a plain mat4; HLSL: the default packing, mul(view[k], p))")


def _param_bytes(p):
    if "[" in p[1]:
        return 64 * int(p[1][p[1].index("[") + 1:-1])
    return TYPE_BYTES[p[1]]


def _slot_of(r, contract):
    names = {r.name.lower(), *(n.lower() for n in r.names if n)}
    by_name = [s for s in contract.slots if s.name in names]
    if by_name:
        return by_name[0]
    by_binding = [s for s in contract.slots if r.set == 0 and r.binding == s.binding]
    if by_binding:
        return by_binding[0]
    raise BindingError(f"{_where(r)} matches no binding of {contract.case}; expected "
                       + "; ".join(s.describe() for s in contract.slots)
                       + " (matched by name, else by set and binding)")


def match(interface, contract, out_bytes=None):
    """``[Bound]`` for every resource the kernel declares, or :class:`BindingError`.

    ``out_bytes``: the element sizes an output buffer may have in a declared layout
    (:func:`.layout.element_bytes`; None: the contract's).

    HLSL's ``row_major`` flag of SPIR-V is inverted (HLSL's default column_major
    packing is SPIR-V RowMajor), so HLSL's default is the documented layout.
    """
    bound, taken = [], {}
    for r in interface.resources:
        if r.name.lower().startswith(("mr_", "mrtrace")):  # the harness's own (the shared-memory trace)
            continue
        if interface.language == "hlsl" and r.kind == "uniform":
            r = type(r)(**{**r.__dict__, "members": tuple(type(m)(**{**m.__dict__, "row_major": not m.row_major})
                                                          for m in r.members)})
        slot = _slot_of(r, contract)
        if slot.name in taken:
            raise BindingError(f"{_where(r)} and {_where(taken[slot.name])} both match {slot.describe()}")
        _check_kind(slot, r, contract.case, out_bytes)
        if r.kind == "uniform":
            _check_members(r, contract.case)
        taken[slot.name] = r
        bound.append(Bound(slot, r))
    if contract.output.name not in taken:
        raise BindingError(f"output: the kernel declares no {contract.output.describe()}; {contract.case} reads its "
                           "result there")
    return bound
