"""Depth conventions: every depth space the project meets, named once, with the conversions.

A variable carries its space in its name (``z_ndc_light``, ``z_unit``, ``b_unit``), and
each conversion is named ``<to>_from_<from>``, as pbrt-v4 names transforms by their
frames. The spaces:

==============  ==========================================================================
``ndc``         normalized device depth in [-1, 1], near to far (OpenGL clip space divided
                by w). The papers' depth: moment shadow maps store b(z) of the light's
                NDC depth (HPG17 §2; Peters and Klein 2015), and so does this package.
``unit``        [0, 1], near to far: the depth range of Direct3D, Vulkan and WebGPU, and
                OpenGL's window depth with ``glDepthRange(0, 1)``. ``z_unit = (z_ndc + 1) / 2``.
``reversed``    reversed Z, [0, 1] far to near: ``z_reversed = 1 - z_unit``.
``window``      window coordinates of a map or image of ``(H, W)`` pixels: x right, y down,
                the pixel ``(row, col) = (floor(y), floor(x))``.
==============  ==========================================================================

Moment vectors ``b = (b1, ..., bn)`` (b0 = 1 implicit) of a distribution of depths in
one space convert to another affinely related space by the binomial theorem: for
``z' = s z + o``, ``b'_k = sum_j C(k, j) s^j o^(k-j) b_j`` (:func:`moments_affine`).

References
----------
HPG17, Peters and Klein 2015 : see docs/bib.md.
"""

from __future__ import annotations

from math import comb

import numpy as np

from .._arrays import real_input

__all__ = ["z_unit_from_ndc", "z_ndc_from_unit", "z_reversed_from_unit", "z_unit_from_reversed",
           "moments_affine", "moments_affine_rational", "round_rational", "moments_unit_from_ndc", "moments_ndc_from_unit", "moments_reversed_from_unit",
           "moments_unit_from_reversed", "window_from_ndc", "ndc_from_window"]


def _depth(z, name):
    return real_input(z, name, finite=False)


def z_unit_from_ndc(z_ndc):
    """[-1, 1] → [0, 1]: ``(z_ndc + 1) / 2``, rounded once (the sum rounds, the halving is exact)."""
    z = _depth(z_ndc, "z_ndc")
    return (z + 1) * z.dtype.type(0.5)


def z_ndc_from_unit(z_unit):
    """[0, 1] → [-1, 1]: ``2 z_unit - 1``."""
    z = _depth(z_unit, "z_unit")
    return z * z.dtype.type(2) - 1


def z_reversed_from_unit(z_unit):
    """[0, 1] near to far → reversed Z: ``1 - z_unit``."""
    z = _depth(z_unit, "z_unit")
    return 1 - z


def z_unit_from_reversed(z_reversed):
    """Reversed Z → [0, 1] near to far: ``1 - z_reversed``."""
    z = _depth(z_reversed, "z_reversed")
    return 1 - z


def moments_affine(b, scale, offset, exact=False):
    """Power moments of ``scale · z + offset`` from those of ``z``, by the binomial theorem.

    Parameters
    ----------
    b : (..., n) float array
        ``(b1, ..., bn)`` of a distribution of z (b0 = 1 implicit).
    scale, offset : float
    exact : bool
        Evaluate each sum in exact rational arithmetic (the floats given are exact
        binary fractions) and round once: the correctly rounded moments, also for
        float64 input. Element by element in Python; for golden rows, not for maps.

    Returns
    -------
    (..., n) array in the dtype policy of the package (float32 in, float32 out).

    Notes
    -----
    ``b'_k = sum_{j=0..k} C(k, j) scale^j offset^(k-j) b_j``. The sum is evaluated
    in float64 whatever the input and rounded once to the input's dtype, so a
    float32 moment vector is converted as exactly as float32 can hold it (a
    float64 one to within a few float64 roundings; ``exact=True`` for one rounding).

    Examples
    --------
    >>> import numpy as np
    >>> z = np.array([-1.0, 0.5])
    >>> b = np.array([np.mean(z ** k) for k in (1, 2, 3, 4)])
    >>> np.allclose(moments_affine(b, 0.5, 0.5), [np.mean(((z + 1) / 2) ** k) for k in (1, 2, 3, 4)])
    True
    """
    arr = real_input(b, "b")
    if arr.ndim == 0 or arr.shape[-1] == 0:
        from .._arrays import InputError

        raise InputError(f"b: expected moments (..., n) with n >= 1, got shape {arr.shape}")
    n = arr.shape[-1]
    if exact:
        q = moments_affine_rational(arr, scale, offset)
        return np.array([round_rational(x, arr.dtype) for x in q.reshape(-1)]).reshape(arr.shape).astype(arr.dtype)
    x = arr.astype(np.float64)
    out = np.empty_like(x)
    s, o = float(scale), float(offset)
    for k in range(1, n + 1):  # a loop over the n moments, not over texels
        acc = np.full(x.shape[:-1], o ** k)
        for j in range(1, k + 1):
            acc = acc + comb(k, j) * s ** j * o ** (k - j) * x[..., j - 1]
        out[..., k - 1] = acc
    return out.astype(arr.dtype, copy=False)


def moments_affine_rational(b, scale, offset):
    """:func:`moments_affine` in exact rational arithmetic: an object array of ``Fraction`` (b's shape).

    The floats given are exact binary fractions, so nothing is rounded; round each
    value once with :func:`round_rational`. Element by element in Python: for golden
    rows, not for maps.
    """
    from fractions import Fraction

    arr = np.asarray(b)
    n = arr.shape[-1]
    s, o = Fraction(float(scale)), Fraction(float(offset))
    coef = [[comb(k, j) * s ** j * o ** (k - j) for j in range(k + 1)] for k in range(1, n + 1)]
    flat = arr.reshape(-1, n)
    out = np.empty(flat.shape, dtype=object)
    for i, row in enumerate(flat.tolist()):  # exact sums, element by element
        x = [Fraction(1)] + [Fraction(v) for v in row]
        for k in range(n):
            out[i, k] = sum(c * x[j] for j, c in enumerate(coef[k]))
    return out.reshape(arr.shape)


def round_rational(q, dtype):
    """The rational ``q`` rounded once (to nearest, ties to even) to ``dtype``: a Python float.

    float64 by Python's correctly rounded ``int / int``; float32 by choosing among the
    float32 neighbours of that float64 the one nearest to ``q``, so that no double
    rounding can occur.
    """
    from fractions import Fraction

    q = Fraction(q)
    near = q.numerator / q.denominator
    if np.dtype(dtype) == np.float64:
        return near
    x = np.float32(near)
    cands = [x, np.nextafter(x, np.float32(-np.inf)), np.nextafter(x, np.float32(np.inf))]
    best = min(cands, key=lambda c: (abs(Fraction(float(c)) - q), int(np.float32(c).view(np.int32)) & 1))
    return float(best)


def moments_unit_from_ndc(b_ndc):
    """Moments of z_unit = (z_ndc + 1)/2 from moments of z_ndc."""
    return moments_affine(b_ndc, 0.5, 0.5)


def moments_ndc_from_unit(b_unit):
    """Moments of z_ndc = 2 z_unit - 1 from moments of z_unit."""
    return moments_affine(b_unit, 2.0, -1.0)


def moments_reversed_from_unit(b_unit):
    """Moments of 1 - z_unit (reversed Z) from moments of z_unit."""
    return moments_affine(b_unit, -1.0, 1.0)


def moments_unit_from_reversed(b_reversed):
    """Moments of z_unit = 1 - z_reversed from moments of z_reversed."""
    return moments_affine(b_reversed, -1.0, 1.0)


def window_from_ndc(xy_ndc, size):
    """Window coordinates (x right, y down, in pixels) of NDC positions in a map of ``size`` = (H, W).

    ``x_window = (x_ndc + 1) W / 2``, ``y_window = (1 - y_ndc) H / 2``: NDC y points up,
    window rows go down; the point lies in pixel ``(floor(y_window), floor(x_window))``.
    """
    h, w = size
    p = np.asarray(xy_ndc)
    return np.stack([(p[..., 0] + 1) * (w / 2), (1 - p[..., 1]) * (h / 2)], axis=-1)


def ndc_from_window(xy_window, size):
    """Inverse of :func:`window_from_ndc`."""
    h, w = size
    p = np.asarray(xy_window)
    return np.stack([p[..., 0] * (2 / w) - 1, 1 - p[..., 1] * (2 / h)], axis=-1)
