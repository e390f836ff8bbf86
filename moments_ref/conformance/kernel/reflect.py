"""What a kernel declares: its resources, their set and binding, its uniform block and work group.

GLSL and HLSL are compiled to SPIR-V with glslang and reflected by SPIRV-Cross
(``--reflect``), so that the bindings are the ones the compiler assigned; WGSL,
for which no reflection tool is at hand, is read from its declarations
(``@group(g) @binding(b) var<…> name: type;``, structs, ``@workgroup_size``),
with WGSL's own layout rules for the uniform block.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

from ..._arrays import InputError
from .._source import ShaderError, defined_functions, strip_comments

__all__ = ["Resource", "Member", "Interface", "from_spirv", "from_wgsl", "TYPE_BYTES"]

#: Bytes of the scalar, vector and matrix types a uniform block may hold.
TYPE_BYTES = {"uint": 4, "int": 4, "float": 4, "uvec2": 8, "ivec2": 8, "vec2": 8, "uvec3": 12, "ivec3": 12,
              "vec3": 12, "uvec4": 16, "ivec4": 16, "vec4": 16, "mat4": 64}


@dataclass(frozen=True)
class Member:
    """A member of the kernel's uniform block: name, type (GLSL spelling), offset, bytes, row-major flag."""

    name: str
    type: str
    offset: int
    size: int
    count: int = 1  # array length (1: not an array)
    stride: int = 0
    row_major: bool = False


@dataclass(frozen=True)
class Resource:
    """One declared binding of a kernel."""

    name: str  # variable, or block name (GLSL blocks, HLSL cbuffers)
    set: int
    binding: int
    kind: str  # texture_ms, texture, storage_image, buffer, uniform, sampler, other
    declared: str  # the declaration as the reflection or source spells it (for messages)
    format: str | None = None  # storage images: rgba32ui, r32ui, rgba32f ...
    access: str = "read"  # read, write, read_write
    depth: bool = False  # a depth texture type (WGSL texture_depth_*)
    stride: int | None = None  # buffers: bytes per element
    members: tuple = ()  # uniform blocks: Member tuples
    names: tuple = ()  # other names that identify it (instance and type names)


@dataclass
class Interface:
    """A kernel's resources and work group size at one entry point."""

    language: str
    entry: str
    workgroup: tuple
    resources: list = field(default_factory=list)


def _members(types, tid):
    out = []
    for m in types.get(tid, {}).get("members", []):
        count = int(m["array"][0]) if m.get("array") else 1
        size = TYPE_BYTES.get(m["type"], 0)
        out.append(Member(m["name"], m["type"], int(m["offset"]), size, count, int(m.get("array_stride", 0)),
                          bool(m.get("row_major", False))))
    return tuple(out)


def _stride(types, tid):
    ms = types.get(tid, {}).get("members", [])
    if len(ms) == 1 and ms[0].get("array") is not None:
        return int(ms[0].get("array_stride", 0)) or None
    return None


def from_spirv(reflection, language, entry):
    """An :class:`Interface` from SPIRV-Cross's JSON reflection."""
    points = reflection.get("entryPoints", [])
    ep = next((e for e in points if e["name"] == entry), points[0] if points else None)
    if ep is None or ep.get("mode") != "comp":
        raise ShaderError(f"entry: {entry!r} is not a compute entry point")
    types = reflection.get("types", {})
    res = []
    for r in reflection.get("textures", []) + reflection.get("separate_images", []):
        ms = "MS" in r["type"]
        res.append(Resource(r["name"], r.get("set", 0), r.get("binding", 0), "texture_ms" if ms else "texture",
                            f"{r['type']} {r['name']}"))
    for r in reflection.get("images", []):
        access = "read" if r.get("readonly") else ("write" if r.get("writeonly") else "read_write")
        res.append(Resource(r["name"], r.get("set", 0), r.get("binding", 0), "storage_image",
                            f"{r['type']} {r['name']} ({r.get('format', 'no format')})", r.get("format"), access))
    for r in reflection.get("ssbos", []):
        access = "read" if r.get("readonly") else "read_write"
        tname = types.get(r["type"], {}).get("name", "")
        res.append(Resource(r["name"], r.get("set", 0), r.get("binding", 0), "buffer", f"buffer {r['name']}",
                            access=access, stride=_stride(types, r["type"]), names=(tname,)))
    for r in reflection.get("ubos", []):
        tname = types.get(r["type"], {}).get("name", "")
        res.append(Resource(r["name"], r.get("set", 0), r.get("binding", 0), "uniform",
                            f"uniform block {r['name']} ({r.get('block_size', 0)} bytes)",
                            members=_members(types, r["type"]), names=(tname,)))
    for key in ("separate_samplers", "push_constants", "acceleration_structures", "subpass_inputs"):
        for r in reflection.get(key, []):
            res.append(Resource(r["name"], r.get("set", 0), r.get("binding", 0),
                                "sampler" if key == "separate_samplers" else "other", f"{key[:-1]} {r['name']}"))
    return Interface(language, ep["name"], tuple(int(v) for v in ep["workgroup_size"]), res)


# ---------------------------------------------------------------------------------------------
# WGSL

_WGSL_FORMATS = {"rgba32uint": "rgba32ui", "r32uint": "r32ui", "rgba32float": "rgba32f", "r32float": "r32f",
                 "rgba32sint": "rgba32i", "r32sint": "r32i", "rgba16uint": "rgba16ui", "rgba8unorm": "rgba8"}
_WGSL_SCALARS = {"u32": "uint", "i32": "int", "f32": "float"}
_DECL = re.compile(r"((?:@\w+\s*\(\s*\w+\s*\)\s*){2,})var\s*(<[^>]*>)?\s*(\w+)\s*:\s*([^;]+);")


def _wgsl_type(t):
    """WGSL type -> (GLSL spelling, size, align), for the uniform block's layout."""
    t = re.sub(r"\s+", "", t)
    if t in _WGSL_SCALARS:
        return _WGSL_SCALARS[t], 4, 4
    m = re.fullmatch(r"vec([234])<(\w+)>", t) or re.fullmatch(r"vec([234])([uif])", t)
    if m:
        n, s = int(m.group(1)), m.group(2)
        base = {"u32": "u", "i32": "i", "f32": "", "u": "u", "i": "i", "f": ""}.get(s, "?")
        return f"{base}vec{n}", 4 * n, 16 if n >= 3 else 8
    if t in ("mat4x4<f32>", "mat4x4f"):
        return "mat4", 64, 16
    return t, 0, 16


def _wgsl_struct(text, name):
    m = re.search(rf"\bstruct\s+{re.escape(name)}\s*\{{([^}}]*)\}}", text)
    if not m:
        return ()
    out, offset = [], 0
    for decl in re.split(r"[,;]", m.group(1)):
        if ":" not in decl:
            continue
        mname, mtype = (x.strip() for x in decl.split(":", 1))
        mname = re.sub(r"@\w+\s*(\([^)]*\))?", "", mname).strip()
        arr = re.fullmatch(r"array<(.+),\s*(\d+)u?>", re.sub(r"\s+", " ", mtype).strip())
        count = int(arr.group(2)) if arr else 1
        tname, size, align = _wgsl_type(arr.group(1) if arr else mtype)
        stride = -(-size // 16) * 16 if arr else 0  # uniform arrays: stride rounded up to 16
        align = max(align, 16) if arr else align
        offset = -(-offset // align) * align
        out.append(Member(mname, tname, offset, size, count, stride))
        offset += stride * count if arr else size
    return tuple(out)


def _wgsl_stride(t):
    m = re.fullmatch(r"array<(.+?)(?:,\s*\d+u?)?>", re.sub(r"\s+", "", t))
    if not m:
        return None
    inner = re.sub(r"atomic<(\w+)>", r"\1", m.group(1))
    _, size, align = _wgsl_type(inner)
    return -(-size // align) * align if size else None


def _wgsl_resource(text, attrs, space, name, t):
    nums = dict(re.findall(r"@(\w+)\s*\(\s*(\d+)\s*\)", attrs))
    g, b = int(nums.get("group", 0)), int(nums.get("binding", 0))
    t = t.strip()
    decl = f"var{space or ''} {name}: {t}"
    if t.startswith("texture_depth_multisampled") or t.startswith("texture_multisampled"):
        return Resource(name, g, b, "texture_ms", decl, depth="depth" in t)
    if t.startswith("texture_storage"):
        parts = [x.strip() for x in t[t.index("<") + 1:t.rindex(">")].split(",")]
        access = {"write": "write", "read": "read", "read_write": "read_write"}.get(parts[1] if len(parts) > 1
                                                                                      else "write", "write")
        return Resource(name, g, b, "storage_image", decl, _WGSL_FORMATS.get(parts[0], parts[0]), access)
    if t.startswith("texture"):
        return Resource(name, g, b, "texture", decl, depth="depth" in t)
    if t.startswith("sampler"):
        return Resource(name, g, b, "sampler", decl)
    sp = (space or "").strip("<>").replace(" ", "").split(",")
    if sp[0] == "uniform":
        return Resource(name, g, b, "uniform", decl, members=_wgsl_struct(text, t), names=(t,))
    if sp[0] == "storage":
        access = "read_write" if len(sp) > 1 and sp[1] == "read_write" else "read"
        return Resource(name, g, b, "buffer", decl, access=access, stride=_wgsl_stride(t))
    return Resource(name, g, b, "other", decl)


def _wgsl_value(text, token, entry):
    token = token.strip()
    m = re.fullmatch(r"(\d+)[ui]?", token)
    if m:
        return int(m.group(1))
    c = re.search(rf"\b(?:const|override)\s+{re.escape(token)}\s*(?::\s*\w+\s*)?=\s*(\d+)[ui]?\s*;", text)
    if c:
        return int(c.group(1))
    raise InputError(f"work group: cannot read the size {token!r} of @workgroup_size of {entry!r} (use a literal "
                     "or a const)")


def from_wgsl(source_text, entry):
    """An :class:`Interface` read from WGSL source (includes already resolved)."""
    text = strip_comments(source_text)
    m = re.search(rf"((?:@\w+(?:\s*\([^)]*\))?\s*)+)fn\s+{re.escape(entry)}\s*\(", text)
    if not m or "@compute" not in m.group(1):
        fns = [f for f in defined_functions(text)]
        computes = re.findall(r"@compute[^{]*?fn\s+(\w+)", text)
        raise ShaderError(f"entry: {entry!r} is not a compute entry point of the file (compute entry points: "
                          f"{', '.join(computes) or 'none'}; functions: {', '.join(fns) or 'none'})")
    ws = re.search(r"@workgroup_size\s*\(([^)]*)\)", m.group(1))
    if not ws:
        raise ShaderError(f"entry: {entry!r} has no @workgroup_size")
    sizes = [_wgsl_value(text, t, entry) for t in ws.group(1).split(",") if t.strip()]
    sizes += [1] * (3 - len(sizes))
    used = _reachable(text, entry)
    res = [_wgsl_resource(text, attrs, space, name, t) for attrs, space, name, t in _DECL.findall(text)
           if re.search(rf"\b{re.escape(name)}\b", used)]
    return Interface("wgsl", entry, tuple(sizes), res)


def _bodies(text):
    """``{function name: body text}`` of a WGSL module (braces matched)."""
    out = {}
    for m in re.finditer(r"\bfn\s+(\w+)\s*\(", text):
        start = text.find("{", m.end())
        depth, i = 0, start
        while i < len(text):
            depth += {"{": 1, "}": -1}.get(text[i], 0)
            if depth == 0:
                break
            i += 1
        out[m.group(1)] = text[start:i + 1]
    return out


def _reachable(text, entry):
    """The bodies of ``entry`` and of every function it calls, transitively (what it statically uses)."""
    bodies = _bodies(text)
    seen, todo = set(), [entry]
    while todo:
        f = todo.pop()
        if f in seen or f not in bodies:
            continue
        seen.add(f)
        todo += [g for g in bodies if g not in seen and re.search(rf"\b{re.escape(g)}\s*\(", bodies[f])]
    return "\n".join(bodies[f] for f in seen)
