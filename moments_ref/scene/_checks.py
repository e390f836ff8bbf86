"""Checks a scene file passes before anything is built from it (scene-private).

Scene files come from other people, so their text is bounded before it is parsed
and every value is checked before it is used:

* **nesting**: arrays and inline tables at most :data:`MAX_NESTING` deep (the TOML
  parser recurses once per level, and a file of 50,000 ``[`` would exhaust the
  interpreter's stack), counted on the text before parsing; tables made from
  dotted keys at most as deep, counted on the parsed document;
* **numbers**: every number finite and at most :data:`MAX_MAGNITUDE` in
  magnitude, so that no later ``float()``, norm or product overflows (a 30-digit
  field of view, a 400-digit coordinate, a direction of 1e300);
* **the name**: a scene's name becomes part of output file names
  (``errors_<name>.png``): it is data, not a path. :func:`check_name` refuses an
  empty name, ``/``, ``\\``, ``..``, NUL and other control or format characters,
  and names over :data:`MAX_NAME_BYTES` bytes of UTF-8;
* **parameters**: every key of ``[params]`` is one of :data:`PARAMS`, each value
  of its type and in its range.

References
----------
.. [1] VWSS: Adam Marrs, Benjamin Watson and Christopher Healey. 2018. *View-warped Multi-view Soft
       Shadowing for Local Area Lights*. Journal of Computer Graphics Techniques (JCGT) 7, 3, 1–28.
       http://jcgt.org/published/0007/03/01/
"""

from __future__ import annotations

import math
import re
import unicodedata

import numpy as np

from .._arrays import InputError

__all__ = ["MAX_NESTING", "MAX_MAGNITUDE", "MAX_NAME_BYTES", "PARAMS", "Ctx", "check_text", "check_document",
           "check_name", "check_params"]

#: Deepest nesting of arrays, inline tables and tables in a scene file.
MAX_NESTING = 16
#: Largest magnitude of any number in a scene file (world units, degrees, counts).
MAX_MAGNITUDE = 1e9
#: Longest scene name in bytes of UTF-8: the longest output name built from it
#: (``errors_soft_<name>.png`` written through a temporary ``.<file>.<pid>.<random>.png``)
#: stays far below the usual 255-byte limit of a file name.
MAX_NAME_BYTES = 100

# Strings and comments (whose brackets do not nest) or one bracket.
_TOKENS = re.compile(r'"""(?:[^\\]|\\[\s\S])*?"""|\'\'\'[\s\S]*?\'\'\'|"(?:[^"\\\n]|\\.)*"|\'[^\'\n]*\'|#[^\n]*'
                     r'|[\[\]{}]')


class Ctx:
    """Error messages of one scene file: ``scene file PATH: KEY: PROBLEM``."""

    def __init__(self, path):
        self.path = path

    def error(self, key, problem):
        return InputError(f"scene file {self.path}: {key}: {problem}")

    def number(self, table, key, where, default=None, positive=False):
        if key not in table:
            if default is None:
                raise self.error(f"{where}{key}", "missing (expected a number)")
            return default
        v = table[key]
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not _finite(v):
            raise self.error(f"{where}{key}", f"wrong type: expected a finite number, got {_short(v)}")
        if positive and v <= 0:
            raise self.error(f"{where}{key}", f"expected a positive number, got {v!r}")
        return float(v)

    def vec3(self, table, key, where, default=None):
        if key not in table:
            if default is None:
                raise self.error(f"{where}{key}", "missing (expected a list of 3 numbers)")
            return np.asarray(default, dtype=np.float64)
        v = table[key]
        if (not isinstance(v, list) or len(v) != 3
                or not all(isinstance(x, (int, float)) and not isinstance(x, bool) and _finite(x) for x in v)):
            raise self.error(f"{where}{key}", f"wrong type: expected a list of 3 finite numbers, got {_short(v)}")
        return np.asarray(v, dtype=np.float64)

    def table(self, doc, key, where="", required=True):
        if key not in doc:
            if required:
                raise self.error(f"{where}{key}", "missing table")
            return {}
        v = doc[key]
        if not isinstance(v, dict):
            raise self.error(f"{where}{key}", f"wrong type: expected a table, got {type(v).__name__}")
        return v

    def unknown(self, table, allowed, where):
        extra = sorted(set(table) - set(allowed))
        if extra:
            raise self.error(f"{where}{extra[0]}", f"unknown key (allowed: {', '.join(sorted(allowed))})")


def _finite(v):
    return isinstance(v, int) or math.isfinite(v)


def _short(v, width=60):
    """``repr(v)`` cut to ``width`` characters (a 400-digit number stays one short line)."""
    text = repr(v)
    if isinstance(v, int) and not isinstance(v, bool) and len(text) > 24:
        return f"{text[:12]}… ({len(text.lstrip('-'))} digits)"
    return text if len(text) <= width else text[:width - 1] + "…"


def check_text(ctx, text):
    """Refuse arrays and inline tables nested deeper than :data:`MAX_NESTING`, before parsing."""
    depth = 0
    for m in _TOKENS.finditer(text):
        tok = m.group()
        if tok in "[{":
            depth += 1
            if depth > MAX_NESTING:
                line = text.count("\n", 0, m.start()) + 1
                raise ctx.error(f"line {line}", f"arrays or tables nested more than {MAX_NESTING} deep")
        elif tok in "]}":
            depth = max(depth - 1, 0)


def check_document(ctx, doc):
    """Refuse nesting beyond :data:`MAX_NESTING` and numbers that are not finite or exceed :data:`MAX_MAGNITUDE`.

    Walks the parsed document without recursion; the message names the key path
    (``camera.fov``, ``objects[1].params.width``).
    """
    stack = [("", doc, 0)]
    while stack:
        where, v, depth = stack.pop()
        if depth > MAX_NESTING:
            raise ctx.error(where, f"nested more than {MAX_NESTING} deep")
        if isinstance(v, dict):
            stack += [(f"{where}.{k}" if where else str(k), x, depth + 1) for k, x in v.items()]
        elif isinstance(v, list):
            stack += [(f"{where}[{i}]", x, depth + 1) for i, x in enumerate(v)]
        elif isinstance(v, (int, float)) and not isinstance(v, bool):
            if not _finite(v):
                raise ctx.error(where, f"expected a finite number, got {v!r}")
            if abs(v) > MAX_MAGNITUDE:
                raise ctx.error(where, f"expected a number of magnitude at most {MAX_MAGNITUDE:g}, got {_short(v)}")


def check_name(ctx, name, key="name"):
    """``name`` if it can be part of a file name (module docstring), else :class:`InputError` naming the reason."""
    if not isinstance(name, str):
        raise ctx.error(key, f"wrong type: expected a string, got {_short(name)}")
    bad = next((c for c in name if unicodedata.category(c).startswith("C")), None)
    reason = ("expected a non-empty name" if not name.strip() else
              f"contains the control or format character U+{ord(bad):04X}" if bad is not None else
              "contains '/' or '\\' (a scene name is not a path)" if "/" in name or "\\" in name else
              "contains '..' (a scene name is not a path)" if ".." in name else
              f"longer than {MAX_NAME_BYTES} bytes of UTF-8 ({len(name.encode('utf-8'))} bytes)"
              if len(name.encode("utf-8")) > MAX_NAME_BYTES else None)
    if reason:
        raise ctx.error(key, f"{reason}; output files are named after the scene, got {_short(name)}")
    return name


def _integer(lo, hi):
    def check(v):
        if isinstance(v, bool) or not isinstance(v, int) or not lo <= v <= hi:
            return f"an integer in [{lo}, {hi}]"
        return None
    return check


def _positive(v):
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not v > 0:
        return "a positive number"
    return None


def _real(v):
    return "a number" if isinstance(v, bool) or not isinstance(v, (int, float)) else None


def _one_of(*choices):
    def check(v):
        return None if isinstance(v, str) and v in choices else f"one of {', '.join(map(repr, choices))}"
    return check


def _pair(lo, hi):
    one = _integer(lo, hi)

    def check(v):
        if not isinstance(v, list) or len(v) != 2 or any(one(x) for x in v):
            return f"[rows, columns], integers in [{lo}, {hi}]"
        return None
    return check


#: The keys of ``[params]``: ``name -> (check, what it sets)``; ``check(value)``
#: returns None or what was expected.
PARAMS = {
    "light_samples": (_integer(1, 1024), "area lights: light samples N of VWSS, MVR and PCSS (default 24)"),
    "light_near": (_positive, "area lights: the light's near plane z_n in world units (VWSS Listing 1)"),
    "medium": (_one_of("homogeneous"), "the participating medium of the scattering techniques"),
    "epipolar_size": (_pair(1, 4096), "scattering: rows (azimuths) and columns (radii) of the epipolar map"),
    "reference_samples": (_integer(1, 65536), "scattering: samples per ray of the converged reference"),
    "raymarch_samples": (_integer(1, 65536), "scattering: samples per ray of the ray-marching technique"),
    "max_kernel": (_integer(1, 4096), "msm_soft: the largest filter region's side in texels"),
    "msm_soft_depth": (_one_of("linear", "ndc"), "msm_soft: the depth its moments are of"),
    "line_x": (_real, "three-occluders: the ground line x = line_x where the three shadow edges meet"),
}


def check_params(ctx, params):
    """``params`` with every key known and every value of its type and range (:data:`PARAMS`)."""
    for key, value in params.items():
        if key not in PARAMS:
            raise ctx.error(f"params.{key}", f"unknown parameter (known: {', '.join(PARAMS)})")
        expected = PARAMS[key][0](value)
        if expected:
            raise ctx.error(f"params.{key}", f"expected {expected} ({PARAMS[key][1]}), got {_short(value)}")
    return dict(params)
