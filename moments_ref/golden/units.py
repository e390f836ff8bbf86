"""Units of the golden tolerances: ulps of a port's precision, and the rounding of a tolerance.

Shared by the spread model (:mod:`moments_ref.golden.spread`), the engine cases
(:mod:`moments_ref.golden.engine`) and the comparator.
"""

from __future__ import annotations

import numpy as np

__all__ = ["ulp", "ceil2", "PORT_DTYPES"]

#: The precisions a port may have (one tolerance column each).
PORT_DTYPES = ("float32", "float64")


def ulp(x, dtype):
    """Spacing of ``dtype`` at ``|x|`` (float64 array; at least the smallest normal's spacing)."""
    fi = np.finfo(dtype)
    x = np.abs(np.asarray(x, np.float64))
    with np.errstate(over="ignore"):
        return np.spacing(np.maximum(x, fi.tiny).astype(dtype)).astype(np.float64)


def ceil2(t):
    """Round a tolerance array up to two significant digits (reads well, stays above).

    An excess of at most 10⁻¹² of the value above two digits is a representation error,
    not a digit (3.0000000000000004 -> 3.0). Zero, infinite values and values at or below
    1e-290, where the power of ten nears float64's smallest normals, are left as they are.
    """
    t = np.asarray(t, np.float64)
    out = t.copy()
    ok = np.isfinite(t) & (t > 1e-290)
    e = np.floor(np.log10(t[ok])) - 1
    out[ok] = np.ceil(t[ok] / 10**e * (1 - 1e-12)) * 10**e
    return out
