"""Only the tested function and what it uses: top-level declarations and their references.

Engine files carry entry points, samplers, constant buffers, input attachments and
helpers for other passes beside the function under test; a driver that cannot
compile one of them (an ``InputAttachment`` on Vulkan, an engine struct defined in
another file) would stop a function that never uses it. The harness therefore
splits the resolved source into its top-level declarations (functions, structs,
variables, blocks, prototypes), follows the identifiers the tested function
uses through them (and through the bodies of ``#define`` macros), and blanks
every declaration it does not reach, keeping the line numbers. Preprocessor
lines are always kept, so conditional compilation is left to the compiler. An
empty declaration (the ``;`` after a function body that glslang refuses before
GLSL 4.60) is dropped too. When the declarations cannot be told apart (braces
that do not balance outside the preprocessor), the file is compiled whole.

:func:`used_resources` names what the kept declarations need from outside the
shader (uniforms, buffers, textures, samplers, constant buffers): the harness
binds only the function's arguments, so a function that reads one is refused
with the declaration's file and line and the way out.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

__all__ = ["Decl", "split_declarations", "keep_used", "used_resources"]

_TOKEN = re.compile(r"[A-Za-z_]\w*|\d[\w.]*|::|->|\S")
_NOT_NAMES = {"layout", "register", "packoffset", "vk", "binding", "location", "set", "group", "numthreads",
              "workgroup_size", "if", "for", "while", "switch", "return", "sizeof"}
_KEYWORDS = {"in", "out", "inout", "uniform", "buffer", "shared", "const", "static", "precision", "highp",
             "mediump", "lowp", "float", "int", "uint", "bool", "void", "readonly", "writeonly", "coherent",
             "volatile", "restrict", "invariant", "precise", "flat", "smooth", "noperspective", "groupshared",
             "extern", "row_major", "column_major"}
_ENDS_AT_BRACE = {"cbuffer", "tbuffer", "namespace"}
_HLSL_RESOURCE = re.compile(r"^(RW|RasterizerOrdered|Append|Consume)?(Texture\w*|Buffer|StructuredBuffer|"
                            r"ByteAddressBuffer|ConstantBuffer|TextureBuffer|SamplerState|SamplerComparisonState|"
                            r"sampler\w*|SubpassInput\w*|texture\w*)$")
_GLSL_OPAQUE = re.compile(r"^[iu]?(sampler|image|texture|subpassInput)\w*$|^atomic_uint$|^sampler(Shadow)?$")


@dataclass
class Decl:
    """One top-level declaration: character span, kind, names it declares, identifiers it uses."""

    start: int
    end: int
    kind: str  # function, prototype, struct, block, variable, macro-use, empty, other
    names: set
    refs: set
    tokens: list = field(repr=False, default_factory=list)

    @property
    def name(self):
        return sorted(self.names)[0] if self.names else ""


def _blank(text, spans):
    """``text`` with the characters of ``spans`` replaced by spaces (newlines kept)."""
    chars = list(text)
    for a, b in spans:
        for i in range(a, b):
            if chars[i] != "\n":
                chars[i] = " "
    return "".join(chars)


def _code_and_directives(text):
    """(text with comments and preprocessor lines blanked, ``{macro: identifiers of its body}``)."""
    spans = [m.span() for m in re.finditer(r"/\*.*?\*/|//[^\n]*|\"(?:\\.|[^\"\\\n])*\"", text, flags=re.S)]
    code = _blank(text, [s for s in spans if text[s[0]] == "/"])
    macros, pre, pos = {}, [], 0
    for line in code.splitlines(keepends=True):
        pre.append((pos, pos + len(line), line))
        pos += len(line)
    directive, dspans, body = False, [], ""
    for a, b, line in pre:
        if directive or line.lstrip().startswith("#"):
            dspans.append((a, b))
            body += line
            directive = line.rstrip().endswith("\\")
            if not directive:
                m = re.match(r"\s*#\s*define\s+([A-Za-z_]\w*)(.*)", body, flags=re.S)
                if m:
                    macros[m.group(1)] = set(re.findall(r"[A-Za-z_]\w*", m.group(2)))
                body = ""
    return _blank(code, dspans), macros


def _match(tokens, i):
    """Index of the token closing the bracket at ``tokens[i]``."""
    pairs = {"(": ")", "[": "]", "{": "}"}
    stack = []
    for j in range(i, len(tokens)):
        t = tokens[j][0]
        if t in pairs:
            stack.append(pairs[t])
        elif stack and t == stack[-1]:
            stack.pop()
            if not stack:
                return j
    return len(tokens) - 1


def _is_function(toks, brace, language):
    """Whether the item whose first top-level ``{`` is at ``brace`` is a function definition."""
    words = [t for t, _ in toks[:brace] if t not in ("@",)]
    if not words:
        return False
    if language == "wgsl":
        return "fn" in words
    if words[0] in ("struct", "cbuffer", "tbuffer", "namespace", "enum", "class", "interface"):
        return False
    j = brace - 1
    if j >= 1 and toks[j - 1][0] == ":" and re.match(r"[A-Za-z_]", toks[j][0]):
        j -= 2  # an HLSL semantic: float4 f(...) : SV_Target {
    if j >= 0 and toks[j][0] == "const":
        j -= 1
    if j < 0 or toks[j][0] != ")":
        return False
    depth = 0
    for k in range(j, -1, -1):
        depth += {")": 1, "(": -1}.get(toks[k][0], 0)
        if depth == 0:
            return k > 0 and re.match(r"[A-Za-z_]", toks[k - 1][0]) is not None and toks[k - 1][0] not in _NOT_NAMES
    return False


def _function_name(toks, brace):
    j = brace - 1
    while j >= 0 and toks[j][0] != ")":
        j -= 1
    depth = 0
    for k in range(j, -1, -1):
        depth += {")": 1, "(": -1}.get(toks[k][0], 0)
        if depth == 0:
            return toks[k - 1][0]
    return ""


def _strip_groups(toks, heads=("layout", "register", "packoffset")):
    """Tokens without ``layout(...)``, ``register(...)``, attributes ``[...]``/``[[...]]`` and WGSL ``@x(...)``."""
    out, i = [], 0
    while i < len(toks):
        t = toks[i][0]
        if (t in heads or (t == "@" and i + 1 < len(toks))) and i + 1 < len(toks):
            k = i + 2 if t == "@" else i + 1
            i = _match(toks, k) + 1 if k < len(toks) and toks[k][0] == "(" else k
            continue
        if t == "[" and not out:
            i = _match(toks, i) + 1
            continue
        out.append(toks[i])
        i += 1
    return out


def _declarator(part):
    """The name declared by ``type name [= ...]`` / ``name[3] : register(...)``."""
    names = []
    for t, _ in part:
        if t in ("=", "[", ":", "("):
            break
        if re.match(r"[A-Za-z_]", t):
            names.append(t)
    names = [n for n in names if n not in _KEYWORDS]
    return names[-1] if names else None


def _split_commas(toks):
    parts, depth, cur = [], 0, []
    for tok in toks:
        depth += {"(": 1, "[": 1, "{": 1, ")": -1, "]": -1, "}": -1}.get(tok[0], 0)
        if tok[0] == "," and depth == 0:
            parts.append(cur)
            cur = []
        else:
            cur.append(tok)
    return parts + [cur]


def _names(toks, kind, language, macros):
    """Names a declaration introduces."""
    idents = {t for t, _ in toks if re.match(r"[A-Za-z_]", t)}
    if toks and toks[0][0] in macros:
        return idents - set(macros) - _KEYWORDS  # a macro that declares: keep whatever it may declare
    body = _strip_groups(toks[:-1] if toks[-1][0] == ";" else toks)
    words = [t for t, _ in body]
    if not words:
        return set()
    if kind == "function":
        return {_function_name(body, next(i for i, t in enumerate(words) if t == "{"))}
    if language == "wgsl":
        for i, w in enumerate(words):
            if w in ("var", "const", "override", "let", "alias", "struct", "fn"):
                rest = words[i + 1:]
                if rest and rest[0] == "<":
                    rest = rest[rest.index(">") + 1:] if ">" in rest else []
                return {rest[0]} if rest and re.match(r"[A-Za-z_]", rest[0]) else set()
        return set()
    if "{" in words:
        o = words.index("{")
        c = _match(body, o)
        head = [w for w in words[:o] if re.match(r"[A-Za-z_]", w) and w not in _KEYWORDS]
        names = {head[-1]} if head else set()
        tail = [_declarator(p) for p in _split_commas(body[c + 1:])]
        names |= {n for n in tail if n}
        if words[0] not in ("struct",) and not any(tail):
            inner = [p for p in _split_semicolons(toks, body[o + 1:c])]
            names |= {n for n in (_declarator(p) for p in inner) if n}
        return names
    if words[0] == "typedef":
        return {words[-1]}
    for i, w in enumerate(words[:-1]):
        if words[i + 1] == "(" and re.match(r"[A-Za-z_]", w) and "=" not in words[:i]:
            return {w}  # a prototype
    return {n for n in (_declarator(p) for p in _split_commas(body)) if n}


def _split_semicolons(_toks, inner):
    parts, cur = [], []
    for tok in inner:
        if tok[0] == ";":
            parts.append(cur)
            cur = []
        else:
            cur.append(tok)
    return [p for p in parts + [cur] if p]


def split_declarations(text, language):
    """``(declarations, macros)`` of a resolved source, or ``(None, macros)`` when braces do not balance."""
    code, macros = _code_and_directives(text)
    toks = [(m.group(), m.start()) for m in _TOKEN.finditer(code)]
    decls, i, n = [], 0, len(toks)
    while i < n:
        j, depth, kind = i, 0, None
        while j < n:
            t = toks[j][0]
            if t in "([{":
                if t == "{" and depth == 0 and kind is None:
                    kind = "function" if _is_function(toks[i:j + 1], j - i, language) else "block"
                depth += 1
            elif t in ")]}":
                depth -= 1
                if depth < 0:
                    return None, macros
                if t == "}" and depth == 0 and (kind == "function" or (kind == "block" and (
                        language == "wgsl" or toks[i][0] in _ENDS_AT_BRACE))):
                    break
            elif t == ";" and depth == 0:
                break
            j += 1
        if j >= n and depth != 0:
            return None, macros
        item = toks[i:min(j, n - 1) + 1]
        end = item[-1][1] + len(item[-1][0])
        if [t for t, _ in item] == [";"]:
            kind = "empty"
        elif kind == "block" and item[0][0] == "struct":
            kind = "struct"
        elif kind is None:
            kind = "variable"
        refs = {t for t, _ in item if re.match(r"[A-Za-z_]", t)}
        decls.append(Decl(item[0][1], end, kind, _names(item, kind, language, macros), refs, item))
        i = j + 1
    return decls, macros


def keep_used(text, language, function):
    """``(text, kept declarations)``: ``text`` with the declarations ``function`` does not use blanked.

    Returns ``(text, None)`` unchanged when the declarations cannot be told apart.
    """
    decls, macros = split_declarations(text, language)
    if decls is None:
        return text, None
    by_name = {}
    for d in decls:
        for nm in d.names:
            by_name.setdefault(nm, []).append(d)
    keep, todo, seen = set(), [function], set()
    while todo:
        nm = todo.pop()
        if nm in seen:
            continue
        seen.add(nm)
        todo += list(macros.get(nm, ()))
        for d in by_name.get(nm, ()):
            if id(d) not in keep:
                keep.add(id(d))
                todo += list(d.refs)
    kept = [d for d in decls if id(d) in keep or (not d.names and d.kind not in ("empty", "function"))]
    ids = {id(d) for d in kept}
    drop = [(d.start, d.end) for d in decls if id(d) not in ids]
    return _blank(text, drop), kept


def _resource(d, language):
    """A description of what ``d`` needs bound from outside the shader, or None."""
    if d.kind in ("function", "prototype", "struct", "empty") or not d.names:
        return None
    words = [t for t, _ in _strip_groups(d.tokens, ("register", "packoffset"))]
    if language == "wgsl":
        if "var" in words:
            k = words.index("var")
            space = words[k + 2] if k + 1 < len(words) and words[k + 1] == "<" else None
            if space not in ("private", "workgroup", "function"):
                return f"the resource var<{space}>" if space else "the texture or sampler"
        return None
    if language == "hlsl":
        if words[0] in ("cbuffer", "tbuffer"):
            return f"the constant buffer {words[1] if len(words) > 1 else ''}".rstrip()
        if "static" in words or "groupshared" in words or words[0] in ("typedef", "struct"):
            return None
        typ = next((w for w in words if w not in _KEYWORDS and w not in ("uniform",)), "")
        if _HLSL_RESOURCE.match(typ):
            return f"the resource ({typ})"
        if "const" in words and "=" in words:
            return None
        return "the global (a uniform in HLSL unless `static`)"
    quals = set(words[:words.index("{")] if "{" in words else words)
    opaque = [w for w in words if _GLSL_OPAQUE.match(w)]
    if opaque:
        return f"the {opaque[0]}"
    for q, what in (("uniform", "the uniform"), ("buffer", "the buffer"), ("in", "the input"), ("out", "the output")):
        if q in quals:
            return what
    return None


def used_resources(kept, language):
    """``[(decl, description)]`` of kept declarations that need a binding the harness does not make."""
    found = []
    for d in kept or ():
        what = _resource(d, language)
        if what:
            found.append((d, what))
    return found
