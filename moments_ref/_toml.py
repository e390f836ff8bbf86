"""A TOML reader for files other people write (engine profiles): bounded before and after parsing.

``tomllib`` parses any text it is given: arrays or inline tables nested thousands
deep end in a ``RecursionError``, an integer of more than 4300 digits in a
``ValueError`` (Python's digit limit), an integer beyond float range
(``clamp = 1e400`` written out as digits) in an ``OverflowError`` where it is
later turned into a float. :func:`load_toml` refuses each of them as an
:class:`~moments_ref.InputError` naming the file and the key or line:

1. before parsing: at most ``max_bytes`` bytes, UTF-8 (a BOM is refused as TOML
   itself does), arrays and inline tables nested at most :data:`MAX_NESTING` deep
   (counted over the text with strings and comments skipped), no numeric
   literal longer than :data:`MAX_DIGITS` characters;
2. after parsing: every number finite and of magnitude at most
   :data:`MAX_MAGNITUDE` (walked without recursion, the message naming the key
   path, ``functions.f.bias.target[2]``).

:func:`finite_float` and :func:`exact_int` convert one checked value for the
reader of a key (a float where a number is expected; an integer, never a float
such as ``8.0`` nor a bool, where an integer is expected).
"""

from __future__ import annotations

import math
import re
import tomllib

from ._arrays import InputError

__all__ = ["load_toml", "check_values", "finite_float", "exact_int", "MAX_NESTING", "MAX_DIGITS", "MAX_MAGNITUDE"]

#: Deepest nesting of arrays and inline tables accepted (a profile needs 3).
MAX_NESTING = 16
#: Longest numeric literal accepted (characters, sign, exponent and underscores included).
MAX_DIGITS = 1000
#: Largest magnitude of a number (far beyond any meaningful profile value; float64 holds it).
MAX_MAGNITUDE = 1e300

_TOKENS = re.compile(r'"""(?:[^\\]|\\[\s\S])*?"""|\'\'\'[\s\S]*?\'\'\'|"(?:[^"\\\n]|\\.)*"|\'[^\'\n]*\'|#[^\n]*'
                     r'|[\[\]{}]|(?<![\w.-])[+-]?[0-9][0-9_.eE+\-xXoObBa-fA-F:TZ ]*')
_NUMBER = re.compile(r"[+-]?[0-9][0-9_]*(\.[0-9_]+)?([eE][+-]?[0-9_]+)?|[+-]?0[xob][0-9a-fA-F_]+")


def _line(text, at):
    """``line N`` of offset ``at``, with the key assigned on that line (``line 3 (bias.alpha)``)."""
    n = text.count("\n", 0, at) + 1
    start = text.rfind("\n", 0, at) + 1
    key = re.match(r"\s*([A-Za-z0-9_.\-\"' ]+?)\s*=", text[start:at])
    return f"line {n}" + (f" ({key.group(1)})" if key else "")


def _scan(text, what):
    """Refuse nesting beyond :data:`MAX_NESTING` and numeric literals beyond :data:`MAX_DIGITS`, before parsing."""
    depth = 0
    for m in _TOKENS.finditer(text):
        tok = m.group()
        if tok in ("[", "{"):
            depth += 1
            if depth > MAX_NESTING:
                raise InputError(f"{what}: {_line(text, m.start())}: arrays or tables nested more than "
                                 f"{MAX_NESTING} deep")
        elif tok in ("]", "}"):
            depth = max(depth - 1, 0)
        elif tok[0] in "+-0123456789":
            lit = tok.strip()
            num = _NUMBER.match(lit)
            if num is not None and len(num.group()) > MAX_DIGITS:
                raise InputError(f"{what}: {_line(text, m.start())}: a number of {len(num.group())} "
                                 f"characters (at most {MAX_DIGITS})")


def _short(v):
    s = repr(v)
    return s if len(s) <= 40 else f"{s[:20]}... ({len(s)} characters)"


def check_values(doc, what):
    """Refuse nesting beyond :data:`MAX_NESTING` and numbers that are not finite or beyond :data:`MAX_MAGNITUDE`.

    ``doc``: parsed TOML or the same structure from the API (dicts, lists, numbers,
    strings). Walks without recursion; the message names the key path.
    """
    stack = [("", doc, 0)]
    while stack:
        where, v, depth = stack.pop()
        where = where if len(where) <= 120 else f"{where[:100]}... ({len(where)} characters)"
        if depth > MAX_NESTING + 1:
            raise InputError(f"{what}: {where or 'the document'}: nested more than {MAX_NESTING} deep")
        if isinstance(v, dict):
            stack += [(f"{where}.{k}" if where else str(k), x, depth + 1) for k, x in v.items()]
        elif isinstance(v, (list, tuple)):
            stack += [(f"{where}[{i}]", x, depth + 1) for i, x in enumerate(v)]
        elif isinstance(v, (int, float)) and not isinstance(v, bool):
            if isinstance(v, int) and abs(v) > MAX_MAGNITUDE or isinstance(v, float) and not abs(v) <= MAX_MAGNITUDE:
                raise InputError(f"{what}: {where}: expected a finite number of magnitude at most "
                                 f"{MAX_MAGNITUDE:g}, got {_short(v)}")
    return doc


def load_toml(blob, what, max_bytes):
    """The parsed TOML of ``blob`` (bytes), bounded before and after parsing (module docstring)."""
    if len(blob) > max_bytes:
        raise InputError(f"{what}: expected at most {max_bytes} bytes, got {len(blob)}")
    try:
        text = blob.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise InputError(f"{what}: not a TOML file: not UTF-8 (byte {blob[exc.start]:#04x} at offset "
                         f"{exc.start})") from None
    _scan(text, what)
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"{what}: not a TOML file: {exc}") from None
    except (RecursionError, ValueError, OverflowError, MemoryError) as exc:  # what the scan could not see
        raise InputError(f"{what}: not a TOML file this reader accepts ({str(exc)[:80]})") from None
    return check_values(doc, what)


def finite_float(v, where):
    """``v`` as a float if it is a finite number (not a bool) of magnitude at most :data:`MAX_MAGNITUDE`."""
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise InputError(f"{where}: expected a finite number, got {_short(v)}")
    if isinstance(v, int) and abs(v) > MAX_MAGNITUDE:
        raise InputError(f"{where}: expected a finite number of magnitude at most {MAX_MAGNITUDE:g}, got {_short(v)}")
    f = float(v)
    if not math.isfinite(f) or abs(f) > MAX_MAGNITUDE:
        raise InputError(f"{where}: expected a finite number of magnitude at most {MAX_MAGNITUDE:g}, got {_short(v)}")
    return f


def exact_int(v, where):
    """``v`` if it is an integer (never a bool, nor a float such as ``8.0``)."""
    if isinstance(v, bool) or not isinstance(v, int):
        raise InputError(f"{where}: expected an integer, got {_short(v)} ({type(v).__name__})")
    return v
