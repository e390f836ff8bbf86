"""What a profile may declare for a kernel: its ``[kernel]`` table.

A kernel case fixes the engine conventions a function profile declares (depth range,
bias, clamp: the case's uniform block carries them), so a profile given with
``--kernel`` may hold only a ``[kernel]`` table. Its keys (:data:`KERNEL_KEYS`):

* ``layout``: how an output buffer holds the texels, ``interleaved`` (default),
  ``planar`` or ``packed16`` (:mod:`.layout`).

Any other key or table is refused with exit 2, naming it.
"""

from __future__ import annotations

from pathlib import Path

from ..._arrays import InputError
from .layout import LAYOUTS

__all__ = ["KERNEL_KEYS", "kernel_profile"]

#: The keys of a profile's ``[kernel]`` table and their allowed values.
KERNEL_KEYS = {"layout": LAYOUTS}


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
    other = [k for k in doc if k != "kernel"]
    if other:
        raise InputError(f"profile: {p}: {other[0]!r} is a function convention; with --kernel a profile holds only "
                         "a [kernel] table (the kernel cases fix the others)")
    table = doc.get("kernel", {})
    if not isinstance(table, dict):
        raise InputError(f"profile: {p}: [kernel] must be a table")
    for k, v in table.items():
        if k not in KERNEL_KEYS:
            raise InputError(f"profile: {p}: unknown key kernel.{k} (known: {', '.join(KERNEL_KEYS)})")
        if v not in KERNEL_KEYS[k]:
            raise InputError(f"profile: {p}: kernel.{k} = {v!r}; expected one of {', '.join(KERNEL_KEYS[k])}")
    return dict(table)
