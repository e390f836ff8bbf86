"""The one table of shading languages: what the harness needs to know about each.

Every fact that differs between GLSL, HLSL, WGSL and Slang lives here, and the
command line, the wrapper generator, the kernel runner and the reports read it:
the source suffixes, the compiler and how to ask it its version, how an entry
point is named and how the compiler renames the porter's names, how includes,
``--define`` and ``--prelude`` are handled, the route to each driver, and what
each route's compilers do to ``precise`` (the verdict's note). Adding a language
is one :class:`Language` here, its compiler call and its tests (docs/architecture.md,
"Adding a language").
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

from .._arrays import InputError

__all__ = ["Language", "TABLE", "LANGUAGES", "CORE", "DRIVERS", "language", "language_of", "suffixes", "precise_note",
           "unmangle", "compiler_versions", "available", "require",
           "options_phrase"]

#: The drivers every language runs on: OpenGL (moderngl, llvmpipe) and Vulkan (wgpu, lavapipe).
DRIVERS = ("gl", "vulkan")


@dataclass(frozen=True)
class Language:
    """One shading language as the harness sees it.

    ``suffixes``: file suffixes that name it; ``compiler``: the program or library that
    compiles it (``None``: the driver itself) and ``install``: how to get it;
    ``types``: the spelling of the function contract's types (:mod:`._slots`);
    ``entry``: the kernel entry point when fixed (GLSL ``main``), else None (named by
    ``--entry``); ``renames``: a regular expression of the names the compiler gives the
    porter's identifiers (group 1 is the porter's name), mapped back in every message;
    ``line_marks``: the harness's ``#line`` markers (``"number"``, ``"string"`` or None);
    ``defines``: whether ``--define`` is a preprocessor ``#define``; ``routes``: per driver,
    the way from source to the driver, in words; ``default``: the driver used unless
    ``--adapter`` says otherwise; ``precise``: per driver, what the route does to
    ``precise`` (the note a report carries when the file uses it).
    """

    name: str
    suffixes: tuple
    compiler: str | None
    install: str
    types: str
    entry: str | None
    renames: str | None
    line_marks: str | None
    defines: bool
    routes: dict
    default: str
    precise: dict = field(default_factory=dict)
    shipped: tuple = ("msm", "msm6", "nonlinear", "packing", "bilinear")
    probed: bool = True  # measured by conformance's driver probes (docs/conformance.md)


TABLE = {
    "glsl": Language(
        "glsl", (".glsl", ".comp"), "glslangValidator (Vulkan); the OpenGL driver itself",
        "apt-get install glslang-tools", "glsl", "main", None, "number", True,
        {"gl": "moderngl compiles the file (entry main)", "vulkan": "glslang -> SPIR-V -> wgpu"}, "gl",
        {"gl": "kept by the driver", "vulkan": "kept: glslang writes NoContraction"}),
    "hlsl": Language(
        "hlsl", (".hlsl", ".hlsli", ".fx"), "glslangValidator (HLSL front end)", "apt-get install glslang-tools",
        "hlsl", None, None, "number", True,
        {"gl": "glslang HLSL -> SPIR-V read by the driver, every operation as written",
         "vulkan": "glslang HLSL -> SPIR-V -> wgpu"}, "gl",
        {"gl": "kept: glslang writes NoContraction", "vulkan": "kept: glslang writes NoContraction"}),
    "wgsl": Language(
        "wgsl", (".wgsl",), None, "pip install wgpu", "wgsl", None, None, None, False,
        {"gl": "wgpu's OpenGL adapter", "vulkan": "wgpu (naga) on Vulkan"}, "vulkan",
        {"gl": "WGSL has no precise", "vulkan": "WGSL has no precise"}),
    "slang": Language(
        "slang", (".slang",), "the Slang compiler library (libslang-compiler from the slangpy wheel)",
        'pip install -e ".[slang]" (or: pip install slangpy)', "hlsl", None, r"\b(?:block_)?([A-Za-z_]\w*?)_\d+\b", "string",
        True,
        {"gl": "Slang -> GLSL (barriers lowered for OpenGL) -> moderngl",
         "vulkan": "Slang -> GLSL -> glslang -> SPIR-V -> wgpu",
         "cpu": "Slang -> C++ (cpp target) -> the system C++ compiler -> a child process (functions only, optional)"},
        "gl",
        {"gl": "kept: Slang's GLSL writes precise",
         "cpu": "every operation rounded as written (C++ compiled with -ffp-contract=off; Slang's `precise` "
                "defined away)",
         "vulkan": "kept: Slang's GLSL writes precise and glslang NoContraction (Slang's own SPIR-V drops it, "
                   "its WGSL writes `precise var`, which naga refuses: neither is used)"},
        ("msm", "nonlinear", "packing"), False),
}

#: The languages, in the order of the reports.
LANGUAGES = tuple(TABLE)
#: The languages whose shipped ports cover every shipped function (``conformance.LANGUAGES``); Slang ships
#: Algorithm 1, Algorithm 3 and the texel formats (and the §4.1 kernel), and needs an optional extra.
CORE = tuple(k for k, v in TABLE.items() if set(v.shipped) == set(TABLE["glsl"].shipped))


def language(name):
    """The :class:`Language` of ``name`` (an :class:`InputError` naming the known ones otherwise)."""
    if name not in TABLE:
        raise InputError(f"language: expected one of {', '.join(LANGUAGES)}, got {name!r}")
    return TABLE[name]


def suffixes():
    """``{suffix: language}`` over the table."""
    return {s: lang.name for lang in TABLE.values() for s in lang.suffixes}


def language_of(path, name=None):
    """The language named, or the one of the file's suffix."""
    if name is not None:
        return language(name).name
    lang = suffixes().get(Path(path).suffix.lower())
    if lang is None:
        raise InputError(f"source: cannot tell the language of {str(path)!r}; use {options_phrase()}")
    return lang


def options_phrase():
    """``--glsl, --hlsl, --wgsl or --slang``: the command line's file options, from the table."""
    opts = [f"--{x}" for x in LANGUAGES]
    return ", ".join(opts[:-1]) + " or " + opts[-1]


def precise_note(name, driver, body):
    """The report's note on ``precise`` for a file using it on ``driver``, or None."""
    from ._source import strip_comments

    if not re.search(r"\bprecise\b", strip_comments(body or "")):
        return None
    what = TABLE[name].precise.get(driver)
    return f"precise: {what}" if what else None


def unmangle(name, text, known=None):
    """``text`` with the compiler's renamed identifiers of ``name`` mapped back to the porter's.

    ``known``: the porter's identifiers (only those are mapped back); None maps every match.
    """
    pat = TABLE[name].renames
    if not pat or not text:
        return text

    def back(m):
        return m.group(1) if known is None or m.group(1) in known else m.group(0)

    return re.sub(pat, back, text)


def available(name):
    """Whether the compiler ``name`` needs beyond the drivers' own is installed (Slang: the extra)."""
    if name == "slang":
        from ._slang import available as slang_available

        return slang_available()
    return True


def require(name):
    """Raise :class:`~._toolchain.ToolError` (exit 2) with the install line when ``name``'s compiler is missing."""
    if not available(name):
        from ._slang import INSTALL
        from ._toolchain import ToolError

        raise ToolError(INSTALL)


def compiler_versions():
    """``{compiler: version line}`` of the installed compilers of every language (the reports' line)."""
    from ._slang import version
    from ._toolchain import tool_versions

    found = tool_versions()
    slang = version()
    if slang:
        found["slang"] = slang
    return found
