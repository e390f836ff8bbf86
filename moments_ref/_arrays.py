"""Input validation and the dtype policy shared by every module.

The input policy (docs/input.md; docs/architecture.md), in one place:

* float32 in -> float32 arithmetic and float32 out (this emulates a GPU port);
* float64 in -> float64 out;
* integers, booleans, Python floats and other real floating types -> float64;
* the byte order does not matter: ``'>f4'`` is float32 and comes back as native
  float32, ``'>f8'`` as native float64;
* complex, object, string and other non-numeric dtypes are refused, and so are
  ragged nested lists;
* masked arrays (:class:`numpy.ma.MaskedArray`) with any masked element are
  refused rather than computed with the hidden values: fill them
  (``np.ma.filled``) or drop the masked entries (``.compressed()``) first; a
  masked array with nothing masked is its data.

Shapes. A 0-d array is refused where a vector (a trailing axis of 4 or 6) is
required; empty arrays are valid and give empty results of the policy's dtype.

Memory. Functions whose allocation follows from their parameters (scene
generators, the camera image, OBJ files) estimate it first and refuse more than
:func:`max_memory` bytes (default :data:`MAX_MEMORY_DEFAULT` = 4 GiB) with an
:class:`InputError`; :func:`set_max_memory` (the command line's ``--max-memory``)
changes the limit.

A function with several array arguments lets its *primary* argument (the moments
or the representation) decide the working dtype; secondary arguments such as the
fragment depth are cast to it, the way a shader converts a constant.

Every refusal raises :class:`InputError`, a :class:`ValueError` whose message names
the argument, what was expected, what came and the first offending index.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "InputError",
    "as_real",
    "working_dtype",
    "check_finite",
    "check_trailing",
    "broadcast_pair",
    "check_broadcast",
    "check_axis",
    "brief",
    "one_line",
    "first_index",
    "real_input",
    "lookup_inputs",
    "refuse_lookup",
    "MAX_MEMORY_DEFAULT",
    "max_memory",
    "set_max_memory",
    "check_memory",
    "format_bytes",
    "parse_bytes",
]

#: Default limit (bytes) for allocations estimated from parameters: 4 GiB.
MAX_MEMORY_DEFAULT = 4 << 30
_limit = {"bytes": MAX_MEMORY_DEFAULT}


class InputError(ValueError):
    """Bad input to a public function of :mod:`moments_ref`.

    The message names the argument, the expectation, what was received and,
    where one exists, the first offending index (in C order).
    """


def first_index(mask: np.ndarray) -> tuple[int, ...] | None:
    """The first True index of ``mask`` in C order, as a tuple, or None."""
    mask = np.asarray(mask)
    if mask.ndim == 0:
        return () if bool(mask) else None
    flat = np.flatnonzero(mask)
    if flat.size == 0:
        return None
    return tuple(int(i) for i in np.unravel_index(flat[0], mask.shape))


def _describe(x: np.ndarray) -> str:
    return f"array of shape {x.shape} and dtype {x.dtype}"


def working_dtype(x) -> np.dtype:
    """The dtype the policy assigns to ``x`` (native float32 or float64), whatever its byte order."""
    dt = np.asarray(x).dtype if not isinstance(x, np.dtype) else np.dtype(x)
    return np.dtype(np.float32) if (dt.kind == "f" and dt.itemsize == 4) else np.dtype(np.float64)


def as_array(x, name: str, what: str = "a real array") -> np.ndarray:
    """``np.asarray(x)`` refusing masked values and ragged lists (:class:`InputError`).

    The first step of :func:`as_real`, shared with the integer inputs of
    :mod:`moments_ref.packing` (``what`` names the expected array in the message).
    """
    if isinstance(x, np.ma.MaskedArray):
        if np.ma.is_masked(x):
            idx = first_index(np.ma.getmaskarray(x))
            raise InputError(f"{name}: expected an array without masked values (fill them with np.ma.filled "
                             f"or drop them with .compressed()), got a masked value at index {idx}")
        x = np.ma.getdata(x)
    try:
        return np.asarray(x)
    except Exception as exc:  # ragged lists and the like
        raise InputError(f"{name}: expected {what}, got a ragged or non-numeric "
                         f"{type(x).__name__} ({str(exc).split('.')[0]})") from None


def as_real(x, name: str, dtype=None) -> np.ndarray:
    """Convert ``x`` to a real float array following the dtype policy.

    Parameters
    ----------
    x : array_like
        The argument.
    name : str
        Its name, for error messages.
    dtype : numpy dtype, optional
        Force this working dtype (used for secondary arguments). By default the
        policy decides from ``x`` itself.
    """
    arr = as_array(x, name)
    kind = arr.dtype.kind
    if kind not in "biuf":
        raise InputError(
            f"{name}: expected a real (integer or floating) array, got {_describe(arr)}"
        )
    target = working_dtype(arr) if dtype is None else np.dtype(dtype)
    return arr.astype(target, copy=False)


def float_dtype(dtype) -> np.dtype:
    """A ``dtype`` argument: float32 or float64 (any byte order) as a native dtype, or InputError."""
    try:
        dt = np.dtype(dtype)
    except (TypeError, ValueError):
        raise InputError(f"dtype: expected float32 or float64, got {dtype!r}") from None
    if dt.kind != "f" or dt.itemsize not in (4, 8):
        raise InputError(f"dtype: expected float32 or float64, got {dt}")
    return np.dtype(np.float32 if dt.itemsize == 4 else np.float64)


def check_finite(arr: np.ndarray, name: str) -> None:
    """Raise :class:`InputError` if ``arr`` holds NaN or inf, naming the first."""
    if arr.dtype.kind != "f":
        return
    ok = np.isfinite(arr)
    if not ok.all():
        idx = first_index(~ok)
        raise InputError(
            f"{name}: expected finite values, got {arr[idx]!r} at index {idx}"
        )


def check_trailing(arr: np.ndarray, name: str, sizes) -> None:
    """Require the trailing axis of ``arr`` to have one of ``sizes`` entries."""
    sizes = (sizes,) if isinstance(sizes, int) else tuple(sizes)
    if arr.ndim == 0 or arr.shape[-1] not in sizes:
        want = " or ".join(str(s) for s in sizes)
        raise InputError(
            f"{name}: expected a trailing axis of length {want}, got {_describe(arr)}"
        )


def broadcast_pair(a: np.ndarray, name_a: str, b: np.ndarray, name_b: str) -> tuple[int, ...]:
    """The broadcast shape of ``a`` and ``b`` or an :class:`InputError`."""
    try:
        shape = np.broadcast_shapes(a.shape, b.shape)
    except ValueError:
        raise InputError(
            f"{name_b}: expected a shape broadcastable with {name_a} {a.shape}, got {b.shape}"
        ) from None
    check_broadcast(shape, (a.shape, b.shape), f"{name_a} {a.shape} with {name_b} {b.shape}")
    return shape


#: Bytes per element of a broadcast result estimated before a lookup allocates it:
#: eight float64 values (the result, up to six for the canonical representation,
#: and the per-element share of the chunks' temporaries).
BROADCAST_BYTES_PER_ELEMENT = 64


def check_broadcast(shape, given, what: str) -> None:
    """Refuse a broadcast ``shape`` larger than every ``given`` shape whose result would exceed :func:`max_memory`.

    A call whose inputs already hold as many elements as the result is not
    estimated (its arrays exist); a broadcast that multiplies them (``(10⁵, 1, 4)``
    with ``(1, 10⁵)``: 10¹⁰ elements) is refused with an :class:`InputError`
    instead of NumPy's ``MemoryError``.
    """
    n = int(np.prod(shape, dtype=np.float64)) if len(shape) else 1
    if n > max(int(np.prod(s, dtype=np.float64)) for s in given):
        check_memory(BROADCAST_BYTES_PER_ELEMENT * n, f"broadcasting {what} to {tuple(shape)}")


def real_input(x, name: str, trailing=None, dtype=None, finite: bool = True) -> np.ndarray:
    """The common path: convert, check the trailing axis, check finiteness."""
    arr = as_real(x, name, dtype)
    if trailing is not None:
        check_trailing(arr, name, trailing)
    if finite:
        check_finite(arr, name)
    return arr


def refuse_lookup(x: np.ndarray, name: str, zf: np.ndarray) -> None:
    """Raise the :class:`InputError` of a lookup's full checks, in their order.

    Finite ``x`` (first bad index), finite ``zf``, then ``zf`` broadcastable
    with ``x[..., 0]``. Returns only if all of them pass.
    """
    check_finite(x, name)
    check_finite(zf, "zf")
    broadcast_pair(x[..., 0], f"{name}[..., 0]", zf, "zf")


def lookup_inputs(x, name: str, zf, trailing: int = 4):
    """``(x, zf, shape)`` of a chunked lookup, finiteness left to the chunks.

    ``x`` with ``trailing`` entries on its last axis and ``zf`` in ``x``'s dtype,
    converted and shape-checked; the kernels check NaN and inf per chunk while it
    is in cache and call :func:`refuse_lookup` for the error of the full checks,
    so messages and their order are those of checking everything up front.
    """
    x = real_input(x, name, trailing=trailing, finite=False)
    try:
        zf = real_input(zf, "zf", dtype=x.dtype, finite=False)
    except InputError:
        check_finite(x, name)  # the first check of the full order
        raise
    try:
        shape = np.broadcast_shapes(x.shape[:-1], zf.shape)
    except ValueError:
        refuse_lookup(x, name, zf)
        raise
    check_broadcast(shape, (x.shape[:-1], zf.shape), f"{name}[..., 0] {x.shape[:-1]} with zf {zf.shape}")
    return x, zf, shape


def brief(value, width: int = 80) -> str:
    """``repr(value)`` for a one-line message: a huge integer as its first digits and its length, anything
    else cut to ``width`` characters."""
    text = repr(value)
    if isinstance(value, (int, np.integer)) and not isinstance(value, bool) and len(text) > 24:
        return f"{text[:12]}… ({len(text.lstrip('-'))} digits)"
    return text if len(text) <= width else text[:width - 1] + "…"


def one_line(text, limit=2000) -> str:
    """``text`` as one line: line breaks and other unprintable characters as escapes (a path may hold them),
    at most ``limit`` characters (the middle of a longer one elided: a hostile file's 900 KB key)."""
    text = "".join(c if c.isprintable() else repr(c)[1:-1] for c in str(text))
    if len(text) <= limit:
        return text
    return f"{text[:limit // 2]} ... ({len(text) - limit} characters elided) ... {text[-limit // 2:]}"


def check_axis(axis, ndim: int, of: str) -> int:
    """``axis`` as an int in ``[-ndim, ndim)`` (an axis of the array ``of``), or :class:`InputError`.

    Checked before NumPy sees it: ``np.moveaxis`` raises ``OverflowError`` for an
    axis beyond a C long (``10**400``).
    """
    if isinstance(axis, bool) or not isinstance(axis, (int, np.integer)) or not -ndim <= axis < ndim:
        raise InputError(f"axis: expected an axis of {of} (an integer in [{-ndim}, {ndim})), got {brief(axis)}")
    return int(axis)


def positive_int(value, name: str, context: str = None) -> int:
    """``value`` as an int ≥ 1, or an :class:`InputError` naming ``name`` (within ``context``).

    Integral floats (``3.0``) are accepted, as ``int(value) == value``; booleans, strings,
    fractions and values below 1 are refused.
    """
    try:
        v = int(value)
        ok = v == value and v >= 1 and not isinstance(value, (bool, str))
    except (TypeError, ValueError, OverflowError):
        ok = False
    if not ok:
        where = f"{context}: expected {name} to be" if context else f"{name}: expected"
        raise InputError(f"{where} a positive integer, got {value!r}")
    return v


def format_bytes(n) -> str:
    """``n`` bytes as a short human-readable string (``'74.5 GiB'``)."""
    n = float(n)
    for unit in ("B", "KiB", "MiB", "GiB", "TiB"):
        if n < 1024 or unit == "TiB":
            return f"{n:.0f} B" if unit == "B" else f"{n:.1f} {unit}"
        n /= 1024
    return f"{n:.1f} TiB"  # pragma: no cover


_UNITS = {"": 1, "b": 1, "k": 1 << 10, "kb": 1 << 10, "kib": 1 << 10, "m": 1 << 20, "mb": 1 << 20,
          "mib": 1 << 20, "g": 1 << 30, "gb": 1 << 30, "gib": 1 << 30, "t": 1 << 40, "tb": 1 << 40, "tib": 1 << 40}


def parse_bytes(text, name="max_memory") -> int:
    """Parse ``'8G'``, ``'512MiB'``, ``'1.5 GB'`` or a plain byte count (binary units)."""
    import re

    m = re.fullmatch(r"\s*([0-9]*\.?[0-9]+(?:[eE][0-9]+)?)\s*([A-Za-z]*)\s*", str(text))
    if not m or m.group(2).lower() not in _UNITS:
        raise InputError(f"{name}: expected a size such as 4G, 512M or a byte count, got {text!r}")
    n = float(m.group(1)) * _UNITS[m.group(2).lower()]
    if not (np.isfinite(n) and n >= 1):
        raise InputError(f"{name}: expected a positive size, got {text!r}")
    return int(n)


def max_memory() -> int:
    """The current limit (bytes) for allocations estimated from parameters."""
    return _limit["bytes"]


def set_max_memory(nbytes) -> int:
    """Set the limit of :func:`check_memory` (bytes, or a string like ``'8G'``); return the old one."""
    n = parse_bytes(nbytes) if isinstance(nbytes, str) else nbytes
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
        raise InputError(f"max_memory: expected a positive number of bytes, got {nbytes!r}")
    old, _limit["bytes"] = _limit["bytes"], int(n)
    return old


def check_memory(nbytes, what: str) -> None:
    """Refuse (:class:`InputError`) an estimated allocation of ``nbytes`` above :func:`max_memory`.

    ``what`` names the request and the parameters it follows from, e.g.
    ``"plane(nx=100000, nz=100000)"``.
    """
    if nbytes > _limit["bytes"]:
        raise InputError(f"{what}: needs about {format_bytes(nbytes)}, above the memory limit of "
                         f"{format_bytes(_limit['bytes'])} (raise it with --max-memory or "
                         "moments_ref.set_max_memory)")
