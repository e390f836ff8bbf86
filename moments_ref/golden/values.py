"""The value checks of a golden case's arrays, shared by the strict loader and the derived-golden cache.

What the comparator relies on: the arrays a case needs are there, categories and
results from the known sets, finite expected values within the case's ``value_range``
(where the manifest states one), tolerances positive and never NaN (``+inf`` marks a
row held only to a finite value in range), acceptable codes that the output's integer
dtype can hold. Anything else raises
:class:`~moments_ref.InputError` naming the array and the first offending row.
"""

from __future__ import annotations

import numpy as np

from .._arrays import InputError, first_index
from .notes import CATEGORIES, RESULTS

__all__ = ["check_case_values"]


def _row_error(what, name, mask, problem, arrays):
    idx = first_index(mask)
    row = idx[0]
    tc = f" (tc_id {int(arrays['tc_id'][row])})" if "tc_id" in arrays else ""
    return InputError(f"{what}: {name} {problem} at row {row}{tc}")


def check_case_values(meta, arrays, what):
    """The checks of a case's values the comparator relies on (module docstring), on ``arrays`` of any
    source (a golden file, a derived-golden cache entry); ``meta`` is its manifest entry (``inputs``,
    ``compare``, ``metric``, ``outputs``)."""
    need = list(meta["inputs"]) + list(meta["compare"]) + ["category", "comment", "result", "tc_id"]
    if meta["metric"] != "exact":
        need += [f"{o}_tolerance_{dt}" for o in meta["compare"] for dt in ("float32", "float64")]
    missing = [k for k in need if k not in arrays]
    if missing:
        raise InputError(f"{what} lacks the array {missing[0]!r}")
    for key, allowed in (("category", CATEGORIES), ("result", tuple(RESULTS))):
        bad = ~np.isin(arrays[key], allowed)
        if bad.any():
            raise _row_error(what, key, bad, f"is {str(arrays[key][first_index(bad)])!r}, not one of "
                                             f"{', '.join(allowed)},", arrays)
    for o in meta["compare"]:
        if meta["metric"] == "exact":
            acc = arrays.get(f"{o}_acceptable")
            if acc is not None:
                info = np.iinfo(np.dtype(meta["outputs"][o]["dtype"]))
                out = (acc < info.min) | (acc > info.max)
                if acc.ndim < 2 or acc.shape[2:] != arrays[o].shape[1:] or out.any():
                    raise InputError(f"{what}: {o}_acceptable must hold {info.dtype} codes of shape "
                                     f"(rows, K) + {arrays[o].shape[1:]}, got {acc.shape} {acc.dtype}")
            continue
        e = arrays[o]
        if not np.isfinite(e).all():
            raise _row_error(what, o, ~np.isfinite(e), "is not finite", arrays)
        rng = meta.get("value_range")  # the manifest's [lo, hi] (checked by loader.check_entry); a cache entry has none
        if rng is not None and ((e < rng[0]) | (e > rng[1])).any():
            out = (e < rng[0]) | (e > rng[1])
            raise _row_error(what, o, out, f"is {float(e[first_index(out)])!r}, beyond the case's value_range "
                                           f"{list(rng)},", arrays)
        for dt in ("float32", "float64"):
            t = arrays[f"{o}_tolerance_{dt}"]
            bad = np.isnan(t) | (t <= 0)
            if bad.any():
                raise _row_error(what, f"{o}_tolerance_{dt}", bad, f"is {float(t[first_index(bad)])!r} (a tolerance "
                                 "must be positive, +inf where only a finite value in range is required)", arrays)
