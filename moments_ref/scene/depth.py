"""Depth conventions: every depth space the project meets, named once, with the conversions.

A variable carries its space in its name (``z_ndc_light``, ``z_unit``, ``d_view``,
``xy_window``), and each conversion is named ``<to>_from_<from>``, as pbrt-v4 names
transforms by their frames (matrices too: ``clip_from_world`` maps world points to clip
coordinates). The spaces:

==============  ==========================================================================
``ndc``         normalized device depth in [-1, 1], near to far (OpenGL clip space divided
                by w). The papers' depth: moment shadow maps store b(z) of the light's
                NDC depth (HPG17 §2; Peters and Klein 2015), and so does this package.
``unit``        [0, 1], near to far: the depth range of Direct3D, Vulkan and WebGPU, and
                OpenGL's window depth with ``glDepthRange(0, 1)``. ``z_unit = (z_ndc + 1) / 2``.
``reversed``    reversed Z, [0, 1] far to near: ``z_reversed = 1 - z_unit = (1 - z_ndc) / 2``
                (VWSS Listing 2 z-buffers it with an integer max).
``view``        ``d_view``: distance in front of the eye along its viewing direction, world
                units (``w_clip`` of a perspective view). Perspective maps store
                ``z_ndc = ((f + n) - 2 f n / d_view) / (f - n)``, orthographic maps
                ``2 (d_view - n) / (f - n) - 1`` (:func:`d_view_from_ndc`,
                :func:`z_ndc_from_view`).
``warped``      EVSM's exponential warps of NDC depth, ``x⁺ = exp(c⁺ z)`` and
                ``x⁻ = −exp(−c⁻ z)`` (Lauritzen and McCool 2008; ESM stores ``x⁺``).
``window``      window coordinates of a map or image of ``(H, W)`` pixels: x right, y down,
                ``x_window = (x_ndc + 1) W / 2``, ``y_window = (1 - y_ndc) H / 2``; the
                point lies in pixel ``(row, col) = (floor(y), floor(x))``, pixel centres at
                ``(col + ½, row + ½)``.
==============  ==========================================================================

Moment vectors ``b = (b1, ..., bn)`` (b0 = 1 implicit) of a distribution of depths in
one space convert to another affinely related space by the binomial theorem: for
``z' = s z + o``, ``b'_k = sum_j C(k, j) s^j o^(k-j) b_j`` (:func:`moments_affine`).

Each formula is written once, here; the rasterizer, the warp, the ray marcher and the
shading passes call these functions (``tests/test_architecture.py`` fails on a second
copy of the window transform). The window and reversed-depth conversions keep the dtype
of their input (float32 in, float32 arithmetic: a shader's) and take ``out=`` for the hot
loops that convert in place; the view-distance conversions work in float64.

References
----------
.. [1] HPG17: Christoph Peters. 2017. *Non-Linearly Quantized Moment Shadow Maps*. In Proceedings
       of High Performance Graphics (HPG '17). ACM. The non-linear quantization Φ, Ψ4, Algorithms
       1–3, the texel formats and the compute shader of §4.1.
.. [2] Peters and Klein 2015: Christoph Peters and Reinhard Klein. 2015. *Moment Shadow Mapping*.
       In Proceedings of the 19th ACM SIGGRAPH Symposium on Interactive 3D Graphics and Games (i3D
       '15). ACM, 7–14. https://doi.org/10.1145/2699276.2699277
.. [3] VWSS: Adam Marrs, Benjamin Watson and Christopher Healey. 2018. *View-warped Multi-view Soft
       Shadowing for Local Area Lights*. Journal of Computer Graphics Techniques (JCGT) 7, 3, 1–28.
       http://jcgt.org/published/0007/03/01/
.. [4] Lauritzen and McCool 2008: Andrew Lauritzen and Michael McCool. 2008. *Layered Variance
       Shadow Maps*. In Proceedings of Graphics Interface 2008 (GI '08). 139–146.
       https://doi.org/10.20380/GI2008.18 (exponential variance shadow maps, EVSM)
"""

from __future__ import annotations

from math import comb

import numpy as np

from .._arrays import real_input

__all__ = ["z_unit_from_ndc", "z_ndc_from_unit", "z_reversed_from_unit", "z_unit_from_reversed", "z_reversed_from_ndc",
           "z_ndc_from_reversed", "d_view_from_ndc", "z_ndc_from_view", "PROJECTIONS", "warped_positive",
           "warped_negative", "moments_affine", "moments_affine_rational", "round_rational", "moments_unit_from_ndc",
           "moments_ndc_from_unit", "moments_reversed_from_unit", "moments_unit_from_reversed", "x_window_from_ndc",
           "y_window_from_ndc", "window_from_ndc", "x_ndc_from_window", "y_ndc_from_window", "ndc_from_window",
           "window_scale"]

#: The projections of :func:`d_view_from_ndc` and :func:`z_ndc_from_view`.
PROJECTIONS = ("perspective", "orthographic")


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


def z_reversed_from_ndc(z_ndc, out=None):
    """[-1, 1] → reversed Z: ``0.5 − 0.5 z_ndc`` (1 on the near plane, 0 on the far; one rounding).

    No validation (a hot loop's conversion): ``z_ndc`` is a float array or scalar; the
    result has its dtype and goes to ``out`` when given (``out=z_ndc`` converts in place).
    """
    r = np.multiply(z_ndc, 0.5, out=out)
    return np.subtract(0.5, r, out=r) if isinstance(r, np.ndarray) else 0.5 - r


def z_ndc_from_reversed(z_reversed):
    """Reversed Z → [-1, 1]: ``1 − 2 z_reversed`` (exact inverse of :func:`z_reversed_from_ndc` up to its rounding)."""
    return 1 - 2 * z_reversed


def _projection(projection):
    if projection not in PROJECTIONS:
        from .._arrays import InputError

        raise InputError(f"projection: expected one of {', '.join(PROJECTIONS)}, got {projection!r}")
    return projection


def d_view_from_ndc(z_ndc, near, far, projection="perspective"):
    """View distance (world units in front of the eye) of NDC depth in a map with clip planes ``near``, ``far``.

    Perspective: ``d = 2 f n / ((f + n) − z (f − n))`` (the inverse of the depth row of
    :func:`moments_ref.scene.raster.frustum`); orthographic: ``d = n + (z + 1)(f − n)/2``.
    float64 whatever the input; NDC 1 is the far plane, −1 the near plane.
    """
    z = np.asarray(z_ndc, dtype=np.float64)
    n, f = float(near), float(far)
    if _projection(projection) == "perspective":
        return 2 * f * n / ((f + n) - z * (f - n))
    return n + (z + 1) * (f - n) / 2


def z_ndc_from_view(d_view, near, far, projection="perspective"):
    """NDC depth of view distance ``d_view``: the inverse of :func:`d_view_from_ndc` (float64).

    Perspective: ``((f + n) − 2 f n / d) / (f − n)``; orthographic: ``2 (d − n)/(f − n) − 1``,
    which is also the depth "linear in the view distance" on [−1, 1] that a
    perspective map's depths are remapped to (:mod:`moments_ref.techniques.msm_soft`).
    """
    d = np.asarray(d_view, dtype=np.float64)
    n, f = float(near), float(far)
    if _projection(projection) == "perspective":
        return ((f + n) - 2 * f * n / d) / (f - n)
    return 2 * (d - n) / (f - n) - 1


def _warp_exponent(z, c):
    return z.dtype.type(c) if z.dtype.kind == "f" else c


def warped_positive(z_ndc, c):
    """EVSM's positive warp ``x⁺ = exp(c z)`` (ESM's stored depth), in the dtype of ``z_ndc`` (float32 stays float32)."""
    z = np.asarray(z_ndc)
    return np.exp(_warp_exponent(z, c) * z)


def warped_negative(z_ndc, c):
    """EVSM's negative warp ``x⁻ = −exp(−c z)`` (increasing in z), in the dtype of ``z_ndc``."""
    z = np.asarray(z_ndc)
    return -np.exp(-_warp_exponent(z, c) * z)


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


def x_window_from_ndc(x_ndc, width, out=None):
    """Window x (pixels, right) of NDC x in a map ``width`` pixels wide: ``(x_ndc + 1) W / 2``.

    No validation; keeps the dtype of ``x_ndc`` (float32 arithmetic for float32 input);
    ``out`` as :func:`z_reversed_from_ndc`. A ``width`` of ``W · 2^k`` gives coordinates in
    units of ``2^-k`` pixels, exactly (the rasterizer's sub-pixel grid).
    """
    if out is None:
        return (x_ndc + 1) * (width / 2)
    np.add(x_ndc, 1, out=out)
    return np.multiply(out, width / 2, out=out)


def y_window_from_ndc(y_ndc, height, out=None):
    """Window y (pixels, down) of NDC y (up) in a map ``height`` pixels high: ``(1 − y_ndc) H / 2``."""
    if out is None:
        return (1 - y_ndc) * (height / 2)
    np.subtract(1, y_ndc, out=out)
    return np.multiply(out, height / 2, out=out)


def window_from_ndc(xy_ndc, size):
    """Window coordinates (x right, y down, in pixels) of NDC positions in a map of ``size`` = (H, W).

    :func:`x_window_from_ndc` and :func:`y_window_from_ndc` stacked: NDC y points up,
    window rows go down; the point lies in pixel ``(floor(y_window), floor(x_window))``.
    """
    h, w = size
    p = np.asarray(xy_ndc)
    return np.stack([x_window_from_ndc(p[..., 0], w), y_window_from_ndc(p[..., 1], h)], axis=-1)


def x_ndc_from_window(x_window, width):
    """NDC x of window x: ``x (2 / W) − 1`` (exact at pixel centres of power-of-two maps)."""
    return x_window * (2 / width) - 1


def y_ndc_from_window(y_window, height):
    """NDC y of window y: ``1 − y (2 / H)``."""
    return 1 - y_window * (2 / height)


def ndc_from_window(xy_window, size):
    """Inverse of :func:`window_from_ndc`."""
    h, w = size
    p = np.asarray(xy_window)
    return np.stack([x_ndc_from_window(p[..., 0], w), y_ndc_from_window(p[..., 1], h)], axis=-1)


def window_scale(size):
    """``(∂x_window/∂x_ndc, ∂y_window/∂y_ndc) = (W / 2, −H / 2)``: how directions map (a ray's step)."""
    h, w = size
    return w / 2, -h / 2
