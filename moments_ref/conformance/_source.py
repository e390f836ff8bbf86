"""Shader source files as users ship them: includes, line numbers, function names.

GLSL and WGSL have no include in their core languages; engines resolve
``#include "file"`` with their own preprocessors, and so does the harness: relative
to the including file, then among the shipped ports of the language (``#include
"msm.glsl"``), each file once (like ``#pragma once``). HLSL includes are resolved
by glslang itself, with the same two folders. Compiler messages are rewritten to ``file:line:col``
of the user's files, one line per error.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

from .._arrays import InputError
from ..ports import PORTS_DIR

__all__ = ["ShaderError", "ShaderSource", "load_source", "defined_functions", "strip_comments", "one_line_errors"]


class ShaderError(InputError):
    """The shader source is unusable: missing function, include or compile error."""


_INCLUDE = re.compile(r'^\s*#\s*include\s+[<"]([^">]+)[">]\s*$')
_VERSION = re.compile(r"^\s*#\s*version\s+(\d+)")
_EXTENSION = re.compile(r"^\s*#\s*extension\b")


@dataclass
class ShaderSource:
    """A GLSL or WGSL file with its includes resolved.

    ``body`` has ``#line 1 k`` markers (GLSL) or none (WGSL); ``lines`` maps each
    line of ``body`` (0-based) to ``(file index, line)`` so that messages can name the
    user's file and line.
    """

    body: str
    version: int
    extensions: list
    files: list  # source-string number - 1 -> path
    lines: list  # body line (0-based) -> (file index, 1-based line) or None

    def locate(self, line):
        """``file:line`` of ``body`` line ``line`` (1-based), or ``<harness wrapper>``."""
        if 1 <= line <= len(self.lines) and self.lines[line - 1] is not None:
            k, no = self.lines[line - 1]
            return f"{self.files[k]}:{no}"
        return "<harness wrapper>"

    def name(self, k):
        """Path of source string ``k`` (1-based), ``<harness wrapper>`` for 0."""
        return str(self.files[k - 1]) if 0 < k <= len(self.files) else "<harness wrapper>"


def load_source(path, language="glsl"):
    """Read a GLSL or WGSL file, resolving ``#include "file"`` relative to the including file.

    Returns
    -------
    ShaderSource
        GLSL: ``#version`` and ``#extension`` lines are hoisted (blank lines keep the
        numbering) and ``#line 1 k`` marks where file ``k`` (1-based) begins.

    Raises
    ------
    ShaderError
        A missing file or include.
    """
    files, lines, where = [], [], []
    version, extensions = 430, []
    glsl = language == "glsl"

    def emit(text, loc):
        lines.append(text)
        where.append(loc)

    def visit(p, origin):
        nonlocal version
        p = Path(p).resolve()
        if p in files:
            return
        if not p.is_file():
            raise ShaderError(f"{language}: expected a {language.upper()} file, got {str(p)!r} (not found{origin})")
        files.append(p)
        k = len(files)
        if glsl:
            emit(f"#line 1 {k}", None)
        for no, line in enumerate(p.read_text().splitlines(), 1):
            m = _INCLUDE.match(line)
            if m:
                inc = p.parent / m.group(1)
                if not inc.is_file() and (PORTS_DIR / language / m.group(1)).is_file():
                    inc = PORTS_DIR / language / m.group(1)  # a shipped port by name
                visit(inc, f", included from {p.name}:{no}")
                emit(f"#line {no + 1} {k}" if glsl else "", None)
                continue
            m = _VERSION.match(line) if glsl else None
            if m:
                version = max(version, int(m.group(1)))
                line = ""  # keep the line numbers
            elif glsl and _EXTENSION.match(line):
                extensions.append(line.strip())
                line = ""
            emit(line, (k - 1, no))

    visit(path, "")
    return ShaderSource("\n".join(lines) + "\n", version, extensions, files, where)


def strip_comments(text):
    """The source without ``/* */`` and ``//`` comments."""
    text = re.sub(r"/\*.*?\*/", " ", text, flags=re.S)
    return re.sub(r"//[^\n]*", "", text)


_DEF = re.compile(r"\b([A-Za-z_][\w<>, ]*?)\s+([A-Za-z_]\w*)\s*\(([^;{}]*)\)\s*(?:->\s*[\w<>, ]+\s*)?\{")
_KEYWORDS = ("if", "for", "while", "switch", "return", "else")


def defined_functions(body):
    """Names of the functions defined in a GLSL, HLSL or WGSL source (for error messages)."""
    return sorted({m.group(2) for m in _DEF.finditer(strip_comments(body))
                   if m.group(1).split()[-1] not in _KEYWORDS})


def one_line_errors(log, pattern, rename):
    """Error lines of a compiler log, one per error, locations rewritten by ``rename(match)``.

    ``pattern`` finds a location in a line; ``rename`` turns its match into ``file:line``.
    Lines that are not errors (warnings, summaries) are dropped unless nothing is left.
    """
    out = []
    for line in log.splitlines():
        low = line.lower()
        if "error" not in low or re.search(r"\d+ compilation errors|no code generated", low):
            continue
        out.append(re.sub(pattern, rename, line.replace("ERROR: ", "").strip()))
    if not out:
        return [re.sub(pattern, rename, log.strip())]
    # Errors in the user's files make the harness's own lines fail too: drop those echoes.
    own = [x for x in out if "<harness wrapper>" not in x and not x.startswith("Linking")]
    return own or out
