"""The harness's own entry point around the user's unchanged function.

Per language the wrapper declares one storage buffer per golden input and output
(binding = argument order, then the outputs, then ``mr_params`` = (row count,
threads per dispatch row)), and an entry point that calls the user's function once
per row. Every harness name starts with ``mr_``. The user's file is included as it
is (text with line markers, its includes resolved by :mod:`._source`, the
declarations the function does not use blanked by :mod:`._decls`), so its own
entry point and helpers may stay; in GLSL a user ``main`` is
renamed with ``#define main mr_user_main`` around the file, and a user
``layout(local_size_x = N) in;`` is kept and used.
"""

from __future__ import annotations

import re

from .._arrays import InputError
from ._source import WRAPPER, strip_comments

__all__ = ["LOCAL_SIZE", "glsl_version", "wrap_glsl", "wrap_hlsl", "wrap_slang", "wrap_wgsl", "free_group", "user_local_size"]

#: Work-group size of the wrapper (one invocation per golden row).
LOCAL_SIZE = 64
_ZERO = {"f": "0.0", "u": "0u", "i": "0"}


def free_group(text, pattern, candidates=(3, 2, 1, 0)):
    """A descriptor set / bind group / register space the user's file does not use."""
    used = {int(g) for g in re.findall(pattern, strip_comments(text))}
    for g in candidates:
        if g not in used:
            return g
    raise InputError("source: every bind group 0..3 is used by the file; the harness needs one")


def user_local_size(text):
    """The work-group size the file declares (``layout(local_size_x = N) in;``), or None."""
    m = re.search(r"layout\s*\(([^)]*local_size_x[^)]*)\)\s*in\s*;", strip_comments(text))
    if not m:
        return None
    sizes = dict(re.findall(r"local_size_([xyz])\s*=\s*(\d+)", m.group(1)))
    if int(sizes.get("y", 1)) != 1 or int(sizes.get("z", 1)) != 1:
        raise InputError(f"source: expected a one-dimensional work group, got layout({m.group(1)})")
    return int(sizes["x"])


def _load(lang, s, idx="i", tex=None):
    """(statement or None, expression) loading row ``idx`` of input ``s``."""
    if tex and s.name in tex:  # the texture and the row's texel (:mod:`._textures`)
        stmts, args = tex[s.name].arguments(lang, idx)
        return stmts, f"mr_tex_{s.name}, {args}"
    buf = f"mr_in_{s.name}"
    if s.is_array:
        k = s.components
        u = "" if lang == "hlsl" else "u"
        items = ", ".join(f"{buf}[{k}{u} * {idx} + {j}{u}]" for j in range(k))
        local = f"mr_a_{s.name}"
        stmt = {"glsl": f"float {local}[{k}] = float[{k}]({items});",
                "hlsl": f"float {local}[{k}] = {{{items}}};",
                "wgsl": f"let {local} = array<f32, {k}>({items});"}[lang]
        return stmt, local
    return None, f"{buf}[{idx}]" + (".xyz" if s.components == 3 else "")


def _store(lang, s, value):
    if s.is_array:
        raise InputError(f"{s.name}: array outputs (more than 4 values a row) are not supported")
    if s.components == 3:
        value = f"{s.element(lang)}({value}, {_ZERO[s.kind]})"
    return f"mr_out_{s.name}[i] = {value};"


def _body(lang, function, ins, outs, tex=None):
    """Statements of the entry point after ``i`` is known."""
    lines, args = [], []
    skip = {t.quad for t in (tex or {}).values() if t.quad}  # carried by a texture's coordinate
    for s in ins:
        if s.name in skip:
            continue
        stmt, expr = _load(lang, s, tex=tex)
        if stmt:
            lines += stmt if isinstance(stmt, list) else [stmt]
        args.append(expr)
    if len(outs) == 1:
        return lines + [_store(lang, outs[0], f"{function}({', '.join(args)})")]
    for s in outs:
        lines.append(f"var mr_v_{s.name}: {s.type(lang)};" if lang == "wgsl" else f"{s.type(lang)} mr_v_{s.name};")
    args += [("&" if lang == "wgsl" else "") + f"mr_v_{s.name}" for s in outs]
    lines.append(f"{function}({', '.join(args)});")
    return lines + [_store(lang, s, f"mr_v_{s.name}") for s in outs]


def _glsl_buffers(ins, outs, set_prefix, tex=None):
    lines, b = [], 0
    access = "" if set_prefix else "writeonly "  # naga rejects writeonly storage
    for s in ins:
        if tex and s.name in tex:
            lines.append(f"layout({set_prefix}binding = {b}) uniform {tex[s.name].type} mr_tex_{s.name};")
            b += 1
            continue
        lines.append(f"layout(std430, {set_prefix}binding = {b}) readonly buffer mr_In_{s.name} "
                     f"{{ {s.element('glsl')} mr_in_{s.name}[]; }};")
        b += 1
    for s in outs:
        lines.append(f"layout(std430, {set_prefix}binding = {b}) {access}buffer mr_Out_{s.name} "
                     f"{{ {s.element('glsl')} mr_out_{s.name}[]; }};")
        b += 1
    lines.append(f"layout(std430, {set_prefix}binding = {b}) readonly buffer mr_Params {{ uint mr_params[]; }};")
    return lines


def glsl_version(src, vulkan=False, gl_max=450):
    """``(version, note)``: the ``#version`` the wrapper uses on a driver.

    The file's own ``#version`` says what it needs, not which driver runs it, so
    the harness picks one each driver offers: at least 430 (OpenGL compute) or 450
    (Vulkan), at most the OpenGL context's (Mesa 22.3: 450) or 460 (glslang).
    An ES version (``310 es``) is compiled as desktop GLSL.
    """
    want = src.version or 0
    lo, hi = (450, 460) if vulkan else (430, gl_max)
    use = min(max(want, lo), hi)
    note = None
    if want > hi:
        note = f"#version {want} ({src.version_at}) compiled as {use}, the highest this driver offers"
    return use, note


def wrap_glsl(src, function, ins, outs, vulkan=False, group=3, gl_max=450, tex=None):
    """GLSL compute shader: the user's resolved source, then the harness (``#line 1 0``)."""
    user_main = re.search(r"\bvoid\s+main\s*\(", strip_comments(src.body)) is not None
    local = user_local_size(src.body)
    version, _ = glsl_version(src, vulkan, gl_max)
    lines = [f"#version {version}", *src.extensions]
    lines += ["#define main mr_user_main"] if user_main else []
    lines += [src.body, "#undef main"] if user_main else [src.body]
    lines.append("#line 1 0")
    if local is None:
        lines.append(f"layout(local_size_x = {LOCAL_SIZE}) in;")
    lines += _glsl_buffers(ins, outs, f"set = {group}, " if vulkan else "", tex)
    lines += ["void main() {",
              "    uint i = gl_GlobalInvocationID.x + gl_GlobalInvocationID.y * mr_params[1];",
              "    if (i >= mr_params[0]) return;"]
    lines += ["    " + x for x in _body("glsl", function, ins, outs, tex)] + ["}"]
    return "\n".join(lines) + "\n", local or LOCAL_SIZE


def wrap_hlsl(src, function, ins, outs, space=3, tex=None):
    """HLSL compute shader: the user's resolved source, then the harness (``#line 1 0``); entry ``mr_main``."""
    lines = [src.body, "#line 1 0"]
    b = 0
    for s in ins:
        if tex and s.name in tex:
            lines.append(f"{tex[s.name].type} mr_tex_{s.name} : register(t{b}, space{space});")
        else:
            lines.append(f"StructuredBuffer<{s.element('hlsl')}> mr_in_{s.name} : register(t{b}, space{space});")
        b += 1
    for s in outs:
        lines.append(f"RWStructuredBuffer<{s.element('hlsl')}> mr_out_{s.name} : register(u{b}, space{space});")
        b += 1
    lines.append(f"StructuredBuffer<uint> mr_params : register(t{b}, space{space});")
    lines += [f"SamplerState mr_smp_{s.name} : register(s{b + 1 + k}, space{space});"
              for k, s in enumerate(ins) if tex and s.name in tex and tex[s.name].sampler]
    lines += [f"[numthreads({LOCAL_SIZE}, 1, 1)]", "void mr_main(uint3 mr_id : SV_DispatchThreadID)", "{",
              "    uint i = mr_id.x + mr_id.y * mr_params[1];", "    if (i >= mr_params[0]) return;"]
    lines += ["    " + x for x in _body("hlsl", function, ins, outs, tex)] + ["}"]
    return "\n".join(lines) + "\n"


def wrap_slang(src, function, ins, outs, space=3):
    """Slang module: the user's resolved source, then the harness; entry ``mr_main``.

    The harness's buffers carry ``[[vk::binding(b, space)]]`` (Slang maps them to
    GLSL's ``binding``/``set`` as declared); the call is HLSL, which Slang reads.
    ``#line`` markers name files by their path (Slang's diagnostics then name the
    porter's file and line).
    """
    body = re.sub(r"^#line (\d+) (\d+)$", lambda m: f'#line {m.group(1)} "{src.name(int(m.group(2)))}"', src.body,
                  flags=re.M)
    lines = [body, f'#line 1 "{WRAPPER}"']
    b = 0
    for s in ins:
        lines.append(f"[[vk::binding({b}, {space})]] StructuredBuffer<{s.element('hlsl')}> mr_in_{s.name};")
        b += 1
    for s in outs:
        lines.append(f"[[vk::binding({b}, {space})]] RWStructuredBuffer<{s.element('hlsl')}> mr_out_{s.name};")
        b += 1
    lines.append(f"[[vk::binding({b}, {space})]] StructuredBuffer<uint> mr_params;")
    lines += ['[shader("compute")]', f"[numthreads({LOCAL_SIZE}, 1, 1)]",
              "void mr_main(uint3 mr_id : SV_DispatchThreadID)", "{",
              "    uint i = mr_id.x + mr_id.y * mr_params[1];", "    if (i >= mr_params[0]) return;"]
    lines += ["    " + x for x in _body("hlsl", function, ins, outs)] + ["}"]
    return "\n".join(lines) + "\n"


def wrap_wgsl(src, function, ins, outs, group=3, tex=None):
    """WGSL module: the user's resolved source, then the harness; entry point ``mr_main``."""
    lines = [src.body]
    b = 0
    for s in ins:
        if tex and s.name in tex:
            lines.append(f"@group({group}) @binding({b}) var mr_tex_{s.name}: {tex[s.name].type};")
        else:
            lines.append(f"@group({group}) @binding({b}) var<storage, read> mr_in_{s.name}: "
                         f"array<{s.element('wgsl')}>;")
        b += 1
    for s in outs:
        lines.append(f"@group({group}) @binding({b}) var<storage, read_write> mr_out_{s.name}: "
                     f"array<{s.element('wgsl')}>;")
        b += 1
    lines.append(f"@group({group}) @binding({b}) var<storage, read> mr_params: array<u32>;")
    lines += [f"@group({group}) @binding({b + 1 + k}) var mr_smp_{s.name}: sampler;"
              for k, s in enumerate(ins) if tex and s.name in tex and tex[s.name].sampler]
    lines += [f"@compute @workgroup_size({LOCAL_SIZE})",
              "fn mr_main(@builtin(global_invocation_id) mr_id: vec3<u32>) {",
              "    let i = mr_id.x + mr_id.y * mr_params[1];", "    if (i >= mr_params[0]) { return; }"]
    lines += ["    " + x for x in _body("wgsl", function, ins, outs, tex)] + ["}"]
    return "\n".join(lines) + "\n"
