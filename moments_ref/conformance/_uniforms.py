"""Values for the uniforms, constant-buffer and push-constant members a function reads.

An engine's function often reads a global the engine binds (a moment bias α in a
constant buffer, a light's depth bias in push constants). The harness passes only
the function's arguments; ``--uniform NAME=VALUE`` (repeatable; a vector as
``NAME=a,b,c,d``) gives such a member a value instead, without editing the file:
the declaration the function uses is replaced, in the text the compiler gets, by
constants of the same names and types (GLSL ``const``, HLSL ``static const``, WGSL
``const``; a block with an instance name becomes a constant struct of that name).
Every member of a replaced declaration needs a value; a missing one is an
:class:`~moments_ref.InputError` naming it and the declaration's file and line, and a
value whose name no member of the file has is refused naming the nearest member.

A profile gives the same values in a ``[uniforms]`` table (``alpha = 3e-7``,
``bias_target = [0, 0.375, 0, 0.375]``, ``[uniforms.params]`` for ``params.NAME``);
``--uniform`` wins over the profile for a name given both ways, and the report names
where each value came from.
"""

from __future__ import annotations

import re

from .._arrays import InputError
from ._source import strip_comments

__all__ = ["parse_uniforms", "constant_declaration", "member_names", "check_names", "profile_uniforms",
           "merge_uniforms"]

_SCALAR = {"float": "f", "half": "f", "double": "f", "f32": "f", "int": "i", "i32": "i", "uint": "u", "u32": "u",
           "bool": "b"}


def parse_uniforms(items):
    """``{name: [value text, ...]}`` from ``NAME=VALUE`` strings (a vector: comma-separated values)."""
    out = {}
    for item in items or ():
        name, sep, value = str(item).partition("=")
        name = name.strip()
        if not sep or not re.fullmatch(r"[A-Za-z_]\w*(\.[A-Za-z_]\w*)?", name):
            raise InputError(f"uniform: expected NAME=VALUE (a vector: NAME=a,b,c), got {item!r}")
        vals = [v.strip() for v in value.split(",")]
        for v in vals:
            try:
                float(v)
            except ValueError:
                raise InputError(f"uniform: {name}: expected numbers, got {value!r}") from None
        out[name] = vals
    return out


def _type(language, t):
    """(scalar kind, components) of a member type, or None for a type the harness cannot fill."""
    t = t.strip()
    m = re.fullmatch(r"(?:vec(\d)<(\w+)>|([iu]?)vec(\d)|(float|half|int|uint|bool|f32|i32|u32|double)(\d)?)", t)
    if not m:
        return None
    if m.group(1):
        return _SCALAR.get(m.group(2)), int(m.group(1))
    if m.group(4):
        return {"": "f", "i": "i", "u": "u"}[m.group(3)], int(m.group(4))
    return _SCALAR[m.group(5)], int(m.group(6) or 1)


def _literal(language, t, kind, n, vals, name):
    if len(vals) != n:
        raise InputError(f"uniform: {name} is a {t} ({n} values), got {len(vals)}")

    def one(v):
        if kind == "f":
            x = repr(float(v))
            return x if re.search(r"[.eEn]", x) else x + ".0"
        if kind == "b":
            return "true" if float(v) else "false"
        return str(int(float(v))) + ("u" if kind == "u" else "")

    items = ", ".join(one(v) for v in vals)
    return items if n == 1 else f"{t}({items})"


def _members(text, language):
    """``[(type, name)]`` of a block body (GLSL/HLSL ``type name;``, WGSL ``name: type,``)."""
    body = strip_comments(text)
    if language == "wgsl":
        return [(t.strip(), n) for n, t in re.findall(r"(?:@\w+(?:\([^)]*\))?\s*)*(\w+)\s*:\s*([^,}]+)", body)]
    return [(t, n) for t, n in re.findall(r"(?:\b(?:row_major|column_major|precise|highp|mediump|lowp)\s+)*"
                                          r"(\w+)\s+(\w+)\s*(?::\s*packoffset\([^)]*\))?\s*;", body)]


def _value(values, name, instance):
    for key in ((f"{instance}.{name}", name) if instance else (name,)):
        if key in values:
            return values[key]
    return None


def _declaration(decl_text, language, body):
    """``(members, instance, struct)`` of a value uniform declaration, or None (see :func:`constant_declaration`)."""
    t = strip_comments(decl_text).strip()
    if language == "wgsl":
        m = re.search(r"var\s*<\s*(uniform|push_constant)\s*>\s*(\w+)\s*:\s*([\w<>]+)\s*;", t)
        if not m:
            return None
        inst, typ = m.group(2), m.group(3)
        s = re.search(rf"\bstruct\s+{re.escape(typ)}\s*\{{([^}}]*)\}}", strip_comments(body))
        members = _members(s.group(1), "wgsl") if s else [(typ, inst)]
        return members, inst if s else None, typ if s else None
    m = re.match(r"^(?:layout\s*\([^)]*\)\s*)?uniform\s+(\w+)\s*\{(.*)\}\s*(\w+)?\s*;$", t, re.S)  # GLSL block
    if m and language == "glsl":
        return _members(m.group(2), "glsl"), m.group(3), "mr_u_" + m.group(1)
    m = re.match(r"^(?:cbuffer|tbuffer)\s+(\w+)\s*(?::\s*register\([^)]*\))?\s*\{(.*)\}\s*;?$", t, re.S)  # HLSL
    if m and language == "hlsl":
        return _members(m.group(2), "hlsl"), None, None
    m = re.match(r"^(?:layout\s*\([^)]*\)\s*)?(?:uniform\s+)?(\w+)\s+(\w+)\s*(?::\s*register\([^)]*\))?\s*(=[^;]*)?;$",
                 t)  # one GLSL uniform or HLSL global
    if m and (language == "hlsl" or t.lstrip().startswith(("uniform", "layout"))) and _type(language, m.group(1)):
        return [(m.group(1), m.group(2))], None, None
    return None


def constant_declaration(decl_text, language, values, body, where):
    """The constants replacing one uniform declaration, or None when ``decl_text`` is no value uniform.

    ``body`` is the whole source (WGSL: the struct of a ``var<uniform>``); ``where`` names the
    declaration's file and line for messages.
    """
    found = _declaration(decl_text, language, body)
    return None if found is None else _build(language, *found, values, where)


def member_names(decl_text, language, body):
    """The names a value may be given under for one declaration (``member`` and ``instance.member``)."""
    found = _declaration(decl_text, language, body)
    if found is None:
        return []
    members, instance, _ = found
    return [n for _, n in members] + ([f"{instance}.{n}" for _, n in members] if instance else [])


def check_names(values, known, origins=None):
    """Refuse (exit 2) a value whose name no uniform member of the file has, naming the nearest member."""
    import difflib

    for name in values:
        if name not in known:
            near = difflib.get_close_matches(name, sorted(set(known)), n=1, cutoff=0.5)
            hint = f"; did you mean {near[0]!r}?" if near else (
                f" (members: {', '.join(sorted(set(known)))})" if known else " (the file declares no uniform member)")
            where = f" (from {origins[name]})" if origins and name in origins else ""
            raise InputError(f"uniform: {name!r}{where} is no uniform, constant-buffer or push-constant member of the "
                             f"file{hint}")


def profile_uniforms(path):
    """``(items, origin)``: the ``[uniforms]`` table of the profile ``path`` as ``NAME=VALUE`` strings (``NAME =
    number``, ``NAME = [a, b, c]`` for a vector, ``[uniforms.INSTANCE]`` for ``INSTANCE.NAME``)."""
    from pathlib import Path

    from .._toml import load_toml

    name = Path(path).name
    data = load_toml(Path(path).read_bytes(), f"profile {name}", 1 << 20)
    table = data.get("uniforms", {})
    if not isinstance(table, dict):
        raise InputError(f"profile {name}: uniforms: expected a table NAME = value")
    items = []
    for key, v in table.items():
        pairs = [(f"{key}.{k}", x) for k, x in v.items()] if isinstance(v, dict) else [(key, v)]
        for n, x in pairs:
            vals = x if isinstance(x, list) else [x]
            if not vals or not all(isinstance(e, (int, float)) and not isinstance(e, bool) for e in vals):
                raise InputError(f"profile {name}: uniforms.{n}: expected a number or an array of numbers, got {x!r}")
            items.append(f"{n}={','.join(repr(e) for e in vals)}")
    return tuple(items), f"profile {name}"


def merge_uniforms(given, from_profile, profile_origin):
    """``(items, origins)``: the profile's values with the command line's on top (the command line wins);
    ``origins`` maps each name to ``--uniform`` or the profile it came from."""
    cli = parse_uniforms(given)
    prof = parse_uniforms(from_profile)
    origins = {**{k: profile_origin for k in prof}, **{k: "--uniform" for k in cli}}
    merged = {**prof, **cli}
    return tuple(f"{k}={','.join(v)}" for k, v in merged.items()), origins


def _build(language, members, instance, struct, values, where):
    missing = [n for _, n in members if _value(values, n, instance) is None]
    if missing:
        raise InputError(f"{where}: give {', '.join(missing)} a value with --uniform NAME=VALUE (the harness binds "
                         "no uniform; every member of the declaration the function reads needs one)")
    lits = []
    for t, n in members:
        k = _type(language, t)
        if k is None or k[0] is None:
            raise InputError(f"{where}: {n} is a {t}; --uniform fills scalars and vectors only")
        lits.append((t, n, _literal(language, t, k[0], k[1], _value(values, n, instance), n)))
    if instance and struct:  # a constant struct of the instance's name
        if language == "wgsl":
            return f"const {instance} = {struct}({', '.join(v for _, _, v in lits)});"
        fields = " ".join(f"{t} {n};" for t, n, _ in lits)
        return f"struct {struct} {{ {fields} }}; const {struct} {instance} = {struct}({', '.join(v for _, _, v in lits)});"
    if language == "wgsl":
        return " ".join(f"const {n}: {t} = {v};" for t, n, v in lits)
    const = "static const" if language == "hlsl" else "const"
    return " ".join(f"{const} {t} {n} = {v};" for t, n, v in lits)
