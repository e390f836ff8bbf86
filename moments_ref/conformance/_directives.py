"""Which lines of a shader file are directives: comments and inactive ``#if`` branches respected.

The harness's one preprocessor (:mod:`._source`) resolves ``#include`` for every
language and driver. An include in a comment (``// #include "Core.shader"``, or a
line inside ``/* ... */``) is no include, and neither is one in a branch the
preprocessor can tell is inactive (``#if 0``, ``#ifdef NAME`` of a name never
defined, ``#ifndef NAME`` of a defined one, their ``#else`` and ``#elif``). A
condition it cannot evaluate (an expression of macros) leaves the branch possibly
active: a missing include there becomes an ``#error`` line that the compiler's own
preprocessor judges, as before.

An ``#include`` left in a comment or an inactive branch is written ``#_include``:
OpenGL's front end (moderngl) expands every ``#include "…"`` of its text, comments
included, and would refuse it.
"""

from __future__ import annotations

import re

__all__ = ["Scanner"]

_COND = re.compile(r"^\s*#\s*(if|ifdef|ifndef|elif|else|endif|define|undef)\b\s*(.*)$")


class Scanner:
    """Line by line: the code of a line (comments removed) and whether the line is in an active branch."""

    def __init__(self, defined=()):
        self.block = False  # inside /* */
        self.stack = []  # per open #if: [state of this branch, some earlier branch was taken]
        self.defined = set(defined)

    def code(self, line):
        """``line`` without its comments (the block-comment state carries to the next line)."""
        out, i, n = [], 0, len(line)
        while i < n:
            if self.block:
                j = line.find("*/", i)
                if j < 0:
                    return "".join(out)
                self.block, i = False, j + 2
                continue
            j, k = line.find("/*", i), line.find("//", i)
            if k >= 0 and (j < 0 or k < j):
                out.append(line[i:k])
                return "".join(out)
            if j < 0:
                out.append(line[i:])
                return "".join(out)
            out.append(line[i:j] + " ")
            self.block, i = True, j + 2
        return "".join(out)

    @property
    def active(self):
        """False when an enclosing branch is known to be inactive; True or None (unknown) otherwise."""
        states = [s for s, _ in self.stack]
        return False if False in states else (None if None in states else True)

    def _value(self, kind, arg):
        name = arg.split()[0] if arg.split() else ""
        if kind == "ifdef":
            return True if name in self.defined else None
        if kind == "ifndef":
            return False if name in self.defined else None
        arg = arg.strip()
        m = re.fullmatch(r"!?\s*defined\s*\(?\s*(\w+)\s*\)?", arg)
        if m and m.group(1) in self.defined:
            return not arg.startswith("!")
        if re.fullmatch(r"\d+", arg):
            return arg != "0"
        return None

    def directive(self, code):
        """Track a conditional or ``#define``/``#undef`` on the code of a line."""
        m = _COND.match(code)
        if not m:
            return
        kind, arg = m.group(1), m.group(2)
        if kind in ("if", "ifdef", "ifndef"):
            v = self._value(kind, arg)
            self.stack.append([v, v is True])
        elif kind in ("elif", "else") and self.stack:
            top = self.stack[-1]
            v = True if kind == "else" else self._value("if", arg)
            if top[1]:
                top[0] = False
            elif top[0] is None:  # an earlier branch may have been taken
                top[0] = None if v is not False else False
            else:
                top[0] = v
            top[1] = top[1] or top[0] is True
        elif kind == "endif" and self.stack:
            self.stack.pop()
        elif kind == "define" and self.active is not False and arg.split():
            self.defined.add(arg.split()[0].split("(")[0])
        elif kind == "undef" and self.active is not False and arg.split():
            self.defined.discard(arg.split()[0])
