"""Shader source files as users ship them: bounded reads, includes, line numbers.

GLSL and WGSL have no include in their core languages; engines resolve
``#include "file"`` with their own preprocessors, and so does the harness, for
HLSL too, so that no compiler ever opens a file: an include is searched relative
to the including file, then in each ``--include DIR`` (a leading ``/`` is taken
as relative to the folder, like the virtual paths of engines), then as an
absolute path, then among the shipped ports of the language (``#include
"msm.glsl"``). Each file is read once (like ``#pragma once``), so an include
cycle ends where a file would come again; chains deeper than
:data:`MAX_INCLUDE_DEPTH` are refused. An include in a comment or in a branch
known to be inactive (``#if 0``; :mod:`._directives`) is not followed, in every
language and on every driver. An include that is not found becomes an ``#error``
line naming the file and line (GLSL, HLSL, Slang), so that the compiler's own
preprocessor decides whether it matters (a branch whose condition only it can
evaluate); in WGSL, which has no preprocessor, it is an error at once.

Reads are bounded: every file (source, prelude, includes) counts towards one
budget of :data:`MAX_SOURCE_BYTES` (``--max-source`` raises it), checked before a
file is read. Text is UTF-8 (a UTF-8 or UTF-16 byte-order mark is honoured;
other bytes that are not UTF-8 are read as Latin-1, which is what a compiler
sees of them in a comment); a NUL byte is refused. Compiler messages are
rewritten to ``file:line`` of the user's files, one line per error.
"""

from __future__ import annotations

import codecs
import re
from dataclasses import dataclass, field
from pathlib import Path

from .._arrays import InputError
from ..ports import PORTS_DIR
from ._directives import Scanner

__all__ = ["ShaderError", "ShaderSource", "MAX_SOURCE_BYTES", "MAX_INCLUDE_DEPTH", "load_source", "read_text",
           "defined_functions", "strip_comments", "one_line_errors", "wrapped_compile_error", "check_identifier", "WRAPPER"]

#: Default budget for a source file with its prelude and includes (``--max-source``).
MAX_SOURCE_BYTES = 4 << 20
#: Deepest include chain accepted (a file that includes a file ... 64 times).
MAX_INCLUDE_DEPTH = 64
#: How compiler messages name the harness's own lines (the wrapper that calls the function).
WRAPPER = "<harness wrapper>"


class ShaderError(InputError):
    """The shader source is unusable: missing function, include or compile error."""


_INCLUDE = re.compile(r'^\s*#\s*include\s+[<"]([^">]+)[">]\s*$')
_VERSION = re.compile(r"^\s*#\s*version\s+(\d+)(\s+\w+)?")
_EXTENSION = re.compile(r"^\s*#\s*extension\b")
_IDENT = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")


@dataclass
class ShaderSource:
    """A shader file with its prelude and includes resolved into one text.

    ``body`` has ``#line N k`` markers (GLSL, HLSL) or none (WGSL); ``lines`` maps
    each line of ``body`` (0-based) to ``(file index, line)`` so that messages can
    name the user's file and line. ``version`` is the GLSL ``#version`` asked for
    (0: none) and ``version_at`` where.
    """

    body: str
    version: int
    extensions: list
    files: list  # source-string number - 1 -> path
    lines: list  # body line (0-based) -> (file index, 1-based line) or None
    language: str = "glsl"
    version_at: str = ""
    notes: list = field(default_factory=list)

    def locate(self, line):
        """``file:line`` of ``body`` line ``line`` (1-based), or :data:`WRAPPER`."""
        if 1 <= line <= len(self.lines) and self.lines[line - 1] is not None:
            k, no = self.lines[line - 1]
            return f"{self.files[k]}:{no}"
        return WRAPPER

    def name(self, k):
        """Path of source string ``k`` (1-based), :data:`WRAPPER` for 0."""
        return str(self.files[k - 1]) if 0 < k <= len(self.files) else WRAPPER


def check_identifier(name, what="function"):
    """``name`` if it is an identifier the harness may call, else :class:`InputError`."""
    if not isinstance(name, str) or not _IDENT.fullmatch(name):
        raise InputError(f"{what}: expected an identifier (letters, digits, '_', not starting with a digit), "
                         f"got {name!r}")
    if name.startswith("mr_"):
        raise InputError(f"{what}: names starting with 'mr_' are the harness's own, got {name!r}")
    return name


def _decode(data, path):
    """Bytes of a source file as text (BOMs honoured, Latin-1 for bytes that are not UTF-8)."""
    for bom, enc in ((codecs.BOM_UTF8, "utf-8"), (codecs.BOM_UTF16_LE, "utf-16-le"),
                     (codecs.BOM_UTF16_BE, "utf-16-be")):
        if data.startswith(bom):
            try:
                return data[len(bom):].decode(enc)
            except UnicodeDecodeError as exc:
                raise ShaderError(f"{path}: not valid {enc.upper()} after its byte-order mark "
                                  f"(byte {exc.start + len(bom)})") from None
    if b"\0" in data:
        line = data[: data.index(b"\0")].count(b"\n") + 1
        odd = data[1::2].count(0) > len(data) // 4 or data[0::2].count(0) > len(data) // 4
        hint = "UTF-16 without a byte-order mark? save it as UTF-8" if odd else "a binary file?"
        raise ShaderError(f"{path}:{line}: NUL byte in a shader source ({hint})")
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError:
        return data.decode("latin-1")


def read_text(path, budget, what="source"):
    """Read a source file, refusing it before reading when it exceeds ``budget[0]`` bytes.

    ``budget`` is a one-item list of the bytes left, decremented by the file's size.
    """
    p = Path(path)
    try:
        if not p.is_file():
            raise ShaderError(f"{what}: expected a shader file, got {str(p)!r} "
                              f"({'a folder' if p.is_dir() else 'not a regular file' if p.exists() else 'not found'})")
        size = p.stat().st_size
        if size > budget[0]:
            raise ShaderError(f"{what}: {p} is {size} bytes, over what is left of the source limit "
                              f"({budget[0]} of {budget[1]} bytes); raise it with --max-source")
        with open(p, "rb") as fh:
            data = fh.read(budget[0] + 1)  # bounded even if the file grows while read
    except OSError as exc:
        raise ShaderError(f"{what}: cannot read {p}: {exc.strerror or exc}") from None
    if len(data) > budget[0]:
        raise ShaderError(f"{what}: {p} is over the source limit of {budget[1]} bytes; raise it with --max-source")
    budget[0] -= len(data)
    return _decode(data, p)


def _resolve(name, parent, language, include_dirs):
    """Candidates for ``#include "name"`` in search order: relative, --include, absolute, shipped."""
    rel = name.lstrip("/\\")
    found = [] if Path(name).is_absolute() else [parent / name]
    found += [Path(d) / rel for d in include_dirs]
    found += [Path(name)] if Path(name).is_absolute() else []
    found.append(PORTS_DIR / language / rel)
    return found


def _real(p):
    try:
        return Path(p).resolve(strict=False)
    except (RuntimeError, OSError) as exc:  # a symlink loop
        raise ShaderError(f"include: cannot resolve {p} ({exc})") from None


def load_source(path, language="glsl", include_dirs=(), defines=(), prelude=None, max_bytes=None):
    """Read a GLSL, HLSL or WGSL file, resolving its includes (see the module doc).

    Parameters
    ----------
    path : path
    language : {"glsl", "hlsl", "wgsl"}
    include_dirs : paths
        Folders searched for includes after the including file's folder.
    defines : sequence of ``NAME=VALUE`` or ``NAME``
        ``#define`` lines placed before the file (GLSL, HLSL).
    prelude : path, optional
        A file placed before the file (engine macros such as Unity's ``real``).
    max_bytes : int, optional
        Budget of all files read (default :data:`MAX_SOURCE_BYTES`).

    Returns
    -------
    ShaderSource
        GLSL: ``#version`` and ``#extension`` lines are hoisted (blank lines keep the
        numbering); GLSL, HLSL: ``#line 1 k`` marks where file ``k`` (1-based) begins.

    Raises
    ------
    ShaderError
        A missing or unreadable file, a source over the limit, an include chain
        deeper than :data:`MAX_INCLUDE_DEPTH`.
    """
    limit = MAX_SOURCE_BYTES if max_bytes is None else int(max_bytes)
    budget = [limit, limit]
    marks = language != "wgsl"
    st = _State(language, include_dirs, budget, marks)
    if defines:
        if language == "wgsl":
            raise InputError("define: WGSL has no preprocessor; put `const NAME = VALUE;` in a --prelude file")
        st.files.append(Path("<--define>"))
        st.emit(f"#line 1 {len(st.files)}" if marks else "", None)
        for no, d in enumerate(defines, 1):
            name, _, value = str(d).partition("=")
            check_identifier(name.strip(), "define")
            st.defined.add(name.strip())
            st.emit(f"#define {name.strip()} {value}", (len(st.files) - 1, no))
    if prelude is not None:
        st.visit(Path(prelude), "", 0, "prelude")
    st.visit(Path(path), "", 0, "source")
    return ShaderSource("\n".join(st.lines) + "\n", st.version, st.extensions, st.files, st.where, language,
                        st.version_at)


class _State:
    """Include resolution state of :func:`load_source`."""

    def __init__(self, language, include_dirs, budget, marks):
        self.language, self.include_dirs, self.budget, self.marks = language, list(include_dirs), budget, marks
        self.files, self.lines, self.where, self.seen = [], [], [], set()
        self.version, self.version_at, self.extensions = 0, "", []
        self.defined = set()  # macros defined so far (--define, prelude, files): see _directives

    def emit(self, text, loc):
        self.lines.append(text)
        self.where.append(loc)

    def visit(self, p, origin, depth, what="include"):
        real = _real(p)
        if real in self.seen:
            return  # once per file: an include cycle ends here
        if depth > MAX_INCLUDE_DEPTH:
            raise ShaderError(f"include: chain deeper than {MAX_INCLUDE_DEPTH} files at {p}{origin}")
        text = read_text(real, self.budget, what)
        self.seen.add(real)
        self.files.append(p if what == "source" else real)
        k = len(self.files)
        if self.marks:
            self.emit(f"#line 1 {k}", None)
        scan = Scanner()
        scan.defined = self.defined  # one set of macros across the files, in reading order
        for no, line in enumerate(text.splitlines(), 1):
            code = scan.code(line)
            scan.directive(code)
            if self._directive(line, code, scan.active, p, real, k, no, depth):
                continue
            self.emit(line, (k - 1, no))

    def _directive(self, line, code, active, p, real, k, no, depth):
        """Handle an include, version or extension line; True when it was consumed.

        ``code`` is the line without comments, ``active`` whether its branch is active
        (False: known inactive). An include in a comment or an inactive branch is kept
        as text, written ``#_include`` (OpenGL's front end would expand it).
        """
        glsl = self.language == "glsl"
        m = _INCLUDE.match(code)
        if m is None or active is False:
            if "#include" in line or re.search(r"#\s+include", line):
                self.emit(re.sub(r"#(\s*)include", r"#\1_include", line), (k - 1, no))
                return True
            m = None
        if m:
            found = next((c for c in _resolve(m.group(1), real.parent, self.language, self.include_dirs)
                          if c.is_file()), None)
            if found is None:
                cands = _resolve(m.group(1), real.parent, self.language, self.include_dirs)
                where = ", ".join(["the including folder", *(str(d) for d in self.include_dirs)])
                msg = f'include "{m.group(1)}" not found (searched {where}; add a folder with --include)'
                if any(c.is_symlink() for c in cands):
                    msg = f'include "{m.group(1)}" is a broken symbolic link or a symbolic link loop'
                if self.language == "wgsl":
                    raise ShaderError(f"{p}:{no}: {msg}")
                self.emit(f"#error {p}:{no}: {msg}", (k - 1, no))
                return True
            self.visit(found, f", included from {p}:{no}", depth + 1)
            self.emit(f"#line {no + 1} {k}" if self.marks else "", None)
            return True
        m = _VERSION.match(code) if glsl else None
        if m:
            if int(m.group(1)) > self.version:
                self.version, self.version_at = int(m.group(1)), f"{p}:{no}"
            self.emit("", (k - 1, no))  # keep the line numbers
            return True
        if glsl and _EXTENSION.match(code):
            self.extensions.append(line.strip())
            self.emit("", (k - 1, no))
            return True
        return False


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


def one_line_errors(log, pattern, rename, noise=None):
    """Error lines of a compiler log, one per error, locations rewritten by ``rename(match)``.

    ``pattern`` finds a location in a line; ``rename`` turns its match into ``file:line``.
    Lines that are not errors (warnings, summaries, and lines matching the regex ``noise``:
    a compiler's repetitions without a location) are dropped unless nothing is left.
    """
    out = []
    for line in log.splitlines():
        low = line.lower()
        if "error" not in low or re.search(r"\d+ compilation errors|no code generated", low):
            continue
        if noise and re.search(noise, line.replace("ERROR: ", "").strip()):
            continue
        out.append(re.sub(pattern, rename, line.replace("ERROR: ", "").strip()))
    if not out:
        return [re.sub(pattern, rename, log.strip())]
    # Errors in the user's files make the harness's own lines fail too: drop those echoes.
    own = [x for x in out if WRAPPER not in x and not x.startswith("Linking")]
    return own or out


def wrapped_compile_error(compiler, errors, signature):
    """The :class:`ShaderError` of a wrapped function that does not compile: a head line, then ``errors``.

    The head names the signature the wrapper calls only where an error is on the
    wrapper's own lines (the call: a signature that does not match, a function the
    file does not define as expected); an error inside the user's file says nothing
    about the signature, and a hint there would send the porter to the wrong line.
    """
    notes = [compiler] if compiler else []
    if any(WRAPPER in e for e in errors):
        notes.append(f"expected signature: {signature}")
        params = signature.partition("(")[2]
        if re.search(r"\bzf\b", params) and not re.search(r"\bslope\b", params):  # the slope as one more argument
            notes.append("a function that also takes the receiver's slope declares receiver_slope (docs/ports.md)")
    head = "the wrapped function does not compile" + (f" ({'; '.join(notes)})" if notes else "")
    return ShaderError(head + ":\n" + "\n".join(errors))
