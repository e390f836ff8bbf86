"""Parameter documentation shared by many functions, written once (scipy's docfiller habit).

A docstring names a shared entry as ``%(zf)s`` on its own line, indented like the
parameter lines around it; :func:`fill_doc` replaces it with the entry of
:data:`PARAMETERS`, each continuation line indented one level deeper (numpydoc).
Lines after the placeholder that are indented deeper continue that parameter's
description: a function adds what is particular to it (its dtype rule, a bias it
expects) without repeating the shared part.

References
----------
.. [1] HPG17: Christoph Peters. 2017. *Non-Linearly Quantized Moment Shadow Maps*. In Proceedings
       of High Performance Graphics (HPG '17). ACM. The non-linear quantization Φ, Ψ4, Algorithms
       1–3, the texel formats and the compute shader of §4.1.
"""

from __future__ import annotations

import re

__all__ = ["PARAMETERS", "fill_doc", "fill"]

#: Shared parameter entries: the first line is ``name : type``, the rest its description.
PARAMETERS = {
    "b": "b : (..., 4) float array\n"
         "    Moments b1..b4 (b0 = 1 implicit) of a depth distribution on [-1, 1], the light's NDC depth.",
    "zf": "zf : (...) float array\n"
          "    Fragment depth in the light's NDC, [-1, 1] like the moments' depths, broadcast against the\n"
          "    leading axes of the moments (or representation).",
    "r": "r : (..., 4) float array\n"
         "    Non-linear representation (y1, y2, v2, ξ4) of HPG17 §3: the output of Φ (Algorithm 2) or of a\n"
         "    texel decoder.",
}

_PLACEHOLDER = re.compile(r"^(?P<indent>[ \t]*)%\((?P<name>\w+)\)s[ \t]*$", re.M)


def fill(doc, parameters=None):
    """``doc`` with every ``%(name)s`` line replaced by the indented entry of ``parameters``."""
    table = PARAMETERS if parameters is None else parameters

    def entry(m):
        text = table[m.group("name")]
        return "\n".join(m.group("indent") + line if line else line for line in text.split("\n"))

    return _PLACEHOLDER.sub(entry, doc)


def fill_doc(fn):
    """Decorator: fill ``fn``'s docstring (:func:`fill`) at import; ``help(fn)`` shows the whole text."""
    if fn.__doc__:
        fn.__doc__ = fill(fn.__doc__)
    return fn
