"""What a profile may declare for a kernel: its ``[kernel]`` table.

A kernel case fixes the engine conventions a function profile declares (depth range,
bias, clamp: the case's uniform block carries them), so a profile given with
``--kernel`` may hold only a ``[kernel]`` table. Its keys (:data:`KERNEL_KEYS`):

* ``layout``: how an output buffer holds the texels, ``interleaved`` (default),
  ``planar`` or ``packed16`` (:mod:`.layout`).

and a ``[format]`` table with the one texel-format key that a kernel's codes carry,
``v2_cell`` (:data:`moments_ref.golden.profile.FORMAT_KEYS`, as for functions): the √v2
grid of a 32-bit texel, ``floor128`` (the format's) or ``round127``
(:mod:`moments_ref.golden.cells`). :func:`with_cell` then judges the kernel against the
texels of the declared grid. Any other key or table is refused with exit 2, naming it.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..._arrays import InputError
from .layout import LAYOUTS

__all__ = ["KERNEL_KEYS", "KERNEL_FORMAT_KEYS", "kernel_profile", "with_cell", "explaining_cell"]

#: The keys of a profile's ``[kernel]`` table and their allowed values.
KERNEL_KEYS = {"layout": LAYOUTS}
#: The keys of the ``[format]`` table a kernel profile may hold (those of FORMAT_KEYS a kernel's codes carry).
KERNEL_FORMAT_KEYS = ("v2_cell",)


def kernel_profile(path):
    """``{key: value}`` of the ``[kernel]`` table of the TOML file ``path`` (checked; exit 2 otherwise)."""
    import tomllib

    p = Path(path)
    try:
        doc = tomllib.loads(p.read_text(encoding="utf-8"))
    except OSError as exc:
        raise InputError(f"profile: cannot read {p}: {exc.strerror or exc}") from None
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"profile: {p} is not TOML: {exc}") from None
    other = [k for k in doc if k not in ("kernel", "format")]
    if other:
        raise InputError(f"profile: {p}: {other[0]!r} is a function convention; with --kernel a profile holds only "
                         "a [kernel] table (the kernel cases fix the others)")
    table = doc.get("kernel", {})
    if not isinstance(table, dict):
        raise InputError(f"profile: {p}: [kernel] must be a table")
    return {**_check_table(p, table), **_format_table(p, doc.get("format", {}))}


def _format_table(p, table):
    from ...golden.profile import FORMAT_KEYS

    if not isinstance(table, dict):
        raise InputError(f"profile: {p}: [format] must be a table")
    for k, v in table.items():
        if k not in KERNEL_FORMAT_KEYS:
            raise InputError(f"profile: {p}: format.{k} is a function's decoder choice; with --kernel the [format] "
                             f"table holds only {', '.join(KERNEL_FORMAT_KEYS)}")
        if v not in FORMAT_KEYS[k]:
            raise InputError(f"profile: {p}: format.{k} = {v!r}; expected one of {', '.join(FORMAT_KEYS[k])}")
    return dict(table)


def _check_table(p, table):
    for k, v in table.items():
        if k not in KERNEL_KEYS:
            raise InputError(f"profile: {p}: unknown key kernel.{k} (known: {', '.join(KERNEL_KEYS)})")
        if v not in KERNEL_KEYS[k]:
            raise InputError(f"profile: {p}: kernel.{k} = {v!r}; expected one of {', '.join(KERNEL_KEYS[k])}")
    return dict(table)


def with_cell(gc, cell):
    """The kernel case ``gc`` (a GoldenCase) judged for a declared √v2 grid ``cell``: its expected
    intensities, tolerances and codes derived again from the global path with that grid
    (:func:`moments_ref.golden.conventions.profiled_arrays`), not widened."""
    from dataclasses import replace

    from ...golden.cells import DEFAULT_CELL, HONOURED_BY
    from ...golden.conventions import profiled_arrays
    from ...golden.profile import Profile

    if cell in (None, DEFAULT_CELL):
        return gc
    if gc.name not in HONOURED_BY:
        raise InputError(f"profile: format.v2_cell = {cell!r} is the sqrt(v2) grid of a 32-bit texel; case "
                         f"{gc.name!r} has none (cases: {', '.join(HONOURED_BY)})")
    _, arrays = profiled_arrays(gc.name, Profile(format=(("v2_cell", cell),)), arrays=gc.arrays)
    meta = {**gc.meta, "kwargs": {**gc.meta["kwargs"], "v2_cell": cell}}
    return replace(gc, meta=meta, arrays={**gc.arrays, **arrays})


def explaining_cell(gc_name, arrays, codes, failing):
    """The √v2 grid other than the format's whose expected codes explain every failing texel of a 32-bit
    kernel (each failing code is that grid's global-path code or a legitimate kernel's), or None."""
    from ...golden.cells import DEFAULT_CELL, HONOURED_BY, V2_CELLS
    from ...golden.conventions import profiled_arrays
    from ...golden.profile import Profile

    failing = np.asarray(failing, bool)
    if gc_name not in HONOURED_BY or not failing.any():
        return None
    c = np.asarray(codes, np.uint32).reshape(-1)[failing]
    for cell in V2_CELLS:
        if cell == DEFAULT_CELL:
            continue
        _, other = profiled_arrays(gc_name, Profile(format=(("v2_cell", cell),)), arrays=arrays)
        alts = np.asarray(other["texels_acceptable"], np.uint32).reshape(len(failing), -1)[failing]
        if (alts == c[:, None]).any(axis=1).all():
            return cell
    return None
