"""Input validation and the dtype policy shared by every module.

The policy of design.md, in one place:

* float32 in -> float32 arithmetic and float32 out (this emulates a GPU port);
* float64 in -> float64 out;
* integers, booleans, Python floats and other real floating types -> float64;
* complex, object, string and other non-numeric dtypes are refused.

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
    "first_index",
    "real_input",
]


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
    """The dtype the policy assigns to ``x`` (float32 or float64)."""
    dt = np.asarray(x).dtype if not isinstance(x, np.dtype) else x
    return np.dtype(np.float32) if dt == np.float32 else np.dtype(np.float64)


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
    try:
        arr = np.asarray(x)
    except Exception as exc:  # ragged lists and the like
        raise InputError(f"{name}: expected a real array, got {type(x).__name__} ({exc})") from None
    kind = arr.dtype.kind
    if kind not in "biuf":
        raise InputError(
            f"{name}: expected a real (integer or floating) array, got {_describe(arr)}"
        )
    target = working_dtype(arr) if dtype is None else np.dtype(dtype)
    return arr.astype(target, copy=False)


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
        return np.broadcast_shapes(a.shape, b.shape)
    except ValueError:
        raise InputError(
            f"{name_b}: expected a shape broadcastable with {name_a} {a.shape}, got {b.shape}"
        ) from None


def real_input(x, name: str, trailing=None, dtype=None, finite: bool = True) -> np.ndarray:
    """The common path: convert, check the trailing axis, check finiteness."""
    arr = as_real(x, name, dtype)
    if trailing is not None:
        check_trailing(arr, name, trailing)
    if finite:
        check_finite(arr, name)
    return arr


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
