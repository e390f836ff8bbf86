"""The statements of a Wavefront OBJ file as exporters write it: encodings, line ends, continuations, keywords.

Exporters differ in what surrounds the geometry: a UTF-8 byte-order mark (Windows
tools), UTF-16 text (some Windows exporters), CRLF line ends, ``\\`` line
continuations (the OBJ specification), and statements that are not geometry
(``vt``, ``vn``, ``vp``, ``l``, ``p``, ``o``, ``g``, ``s``, ``usemtl``, ``usemap``,
``mtllib``, free-form curve statements). :func:`obj_statements` yields each
statement's line number and tokens, so that a BOM never hides the first ``v``
and a UTF-16 file reads as the text it is. A file that is not OBJ text is refused
with :class:`~moments_ref.InputError` before any statement is read: binary data
(a binary STL named ``.obj``: NUL bytes that are not UTF-16 text), an ASCII STL
(``solid``), or a line whose keyword no OBJ statement has.

No well-kept OBJ loader fits better: trimesh, meshio and PyWavefront are each a
new dependency for ~100 lines of text handling, merge or re-order vertices (the
face indices of this reader must stay the file's), and accept what this reader
refuses (unknown keywords, binary data); the package's dependency policy is
NumPy and SciPy.

References
----------
.. [1] Wavefront Technologies. *Object Files (.obj)*, Advanced Visualizer manual, Appendix B1 (the
       statement keywords, ``\\`` continuation, relative indices).
"""

from __future__ import annotations

import codecs

from .._arrays import InputError

__all__ = ["OBJ_KEYWORDS", "obj_statements", "MAX_OBJ_LINE"]

#: Longest line of an OBJ file (characters): a polygon of thousands of vertices fits.
MAX_OBJ_LINE = 1 << 16
#: Every statement keyword of the OBJ specification (the geometry reader uses ``v`` and ``f``).
OBJ_KEYWORDS = frozenset(
    "v vt vn vp f l p o g s usemtl usemap mtllib maplib cstype deg bmat step curv curv2 surf parm trim hole "
    "scrv sp end con mg bevel c_interp d_interp lod shadow_obj trace_obj ctech stech call csh".split())
_HEAD = 4096


def _encoding(path, head):
    """The text encoding of an OBJ file from its first bytes; refuses binary data."""
    if head.startswith(codecs.BOM_UTF8):
        return "utf-8-sig"
    if head.startswith((codecs.BOM_UTF32_LE, codecs.BOM_UTF32_BE)):  # before UTF-16: FF FE 00 00 starts both
        return "utf-32"
    if head.startswith((codecs.BOM_UTF16_LE, codecs.BOM_UTF16_BE)):
        return "utf-16"
    if b"\0" in head:
        even, odd = head[0::2], head[1::2]
        if head and len(head) % 2 == 0 and odd.count(0) == len(odd) and 0 not in even:
            return "utf-16-le"
        if head and len(head) % 2 == 0 and even.count(0) == len(even) and 0 not in odd:
            return "utf-16-be"
        raise InputError(f"{path}: not an OBJ file: binary data (NUL bytes; a binary STL or another binary "
                         "format named .obj?)")
    if head.lstrip().lower().startswith(b"solid"):
        raise InputError(f"{path}: not an OBJ file: it begins with 'solid' (an ASCII STL file)")
    return "utf-8"


def obj_statements(path):
    """Yield ``(where, tokens, line)`` for each statement of the OBJ file ``path`` (module docstring).

    ``where`` is ``path:line``; comments and blank lines are skipped, ``\\``
    continuations joined, a BOM and the line ends removed.
    """
    with open(path, "rb") as f:
        head = f.read(_HEAD)
    encoding = _encoding(path, head)
    with open(path, encoding=encoding, errors="replace", newline=None) as f:
        pending, start = "", 0
        for lineno, line in enumerate(iter(lambda: f.readline(MAX_OBJ_LINE + 1), ""), 1):
            where = f"{path}:{lineno}"
            if len(line) > MAX_OBJ_LINE or len(pending) + len(line) > MAX_OBJ_LINE:
                raise InputError(f"{where}: a line longer than {MAX_OBJ_LINE} characters")
            text = line.split("#", 1)[0].rstrip()
            if text.endswith("\\"):
                pending, start = pending + text[:-1] + " ", start or lineno
                continue
            text, first, pending, start = pending + text, start or lineno, "", 0
            tokens = text.split()
            if not tokens:
                continue
            where = f"{path}:{first}"
            if tokens[0] not in OBJ_KEYWORDS:
                shown = tokens[0] if tokens[0].isprintable() and len(tokens[0]) <= 20 else repr(tokens[0][:20])
                raise InputError(f"{where}: not an OBJ statement: {shown!s} (expected a keyword such as v, f, vt, "
                                 "vn, o, g, usemtl)")
            yield where, tokens, line
