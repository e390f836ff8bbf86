"""The Hausdorff bound: moment shadow mapping with depths known to lie in [0, 1].

Peters and Klein 2015 offer two
bounds of the shadow intensity ``Z(z < zf)`` from four moments ``b = (b1, b2, b3, b4)``
(b0 = 1): the Hamburger bound (:func:`moments_ref.msm.shadow_intensity`, any real depths)
and the Hausdorff bound, which also uses that every depth lies in the closed interval
[0, 1] (the ``unit`` depth space of :mod:`moments_ref.scene.depth`: Direct3D, Vulkan and
WebGPU window depth). Its moments are moments of ``z_unit``; this module takes ``b`` and
``zf`` in that space (never the light's NDC).

The bound is the Markov–Krein bound of the Hausdorff moment problem (derived here from the
moment problem itself; the section of the paper that prints it is not cited by number). Among all
distributions on [0, 1] with the moments b, the smallest ``Z(z < zf)`` is attained by the
canonical representation that has zf as a point of support, and it is one of two kinds:

1. **Three points** ``(zf, z1, z2)`` with ``z1, z2`` in [0, 1]: Algorithm 1's canonical
   representation (HPG17 Algorithm 1 steps (2)–(4)). The bound is then the Hamburger
   bound.
2. **Four points** ``(0, zf, x, 1)`` otherwise (a root of step (3) outside [0, 1]): both ends
   of the interval carry mass, and the free point ``x`` follows from
   ``E[Z (Z − zf)(Z − x)(Z − 1)] = 0`` (the polynomial vanishes on the support),
   a linear equation in x::

       x = ((b3 − b2) zf + b3 − b4) / ((b2 − b1) zf + b2 − b3)

   The weights are Lagrange's, ``w_s = E[Π_{t≠s}(Z − t)] / Π_{t≠s}(s − t)``:

       w_0 = −(b3 − (zf + x + 1) b2 + (zf x + zf + x) b1 − zf x) / (zf x)
       w_x = (b3 − (zf + 1) b2 + zf b1) / (x (x − zf)(x − 1))
       w_zf = (b3 − (x + 1) b2 + x b1) / (zf (zf − x)(zf − 1))

   ``lower = w_0 + [x < zf] w_x`` and ``upper = lower + w_zf``.

The four-point weights divide by ``zf`` and by ``zf − 1``: at a receiver at depth 0 (or 1)
two points of support coincide. The bound itself is defined there and needs no limit:
no mass of a distribution on [0, 1] lies below 0, so ``lower = 0`` at ``zf ≤ 0``, and all
of it lies at or below 1, so ``upper = 1`` at ``zf ≥ 1``; the other bound at the ends is
the three-point one (the representation through an end of the interval is the principal
one, Algorithm 1's, with its roots inside). A port that takes the four-point branch at
``zf = 0`` divides by zero: that is a bug, not a convention (docs/golden.md, the
``hausdorff-*`` cases).

The Hausdorff bound is never below the Hamburger bound (it knows more about the
distribution) and equals the sharp bound of a linear program over distributions on a
fine grid of [0, 1] (``tests/test_hausdorff.py``).

dtype policy as in :mod:`moments_ref.msm`: float32 in, float32 arithmetic throughout
(Algorithm 1's canonical representation in float32, the four-point weights in float32);
float64 in, float64 out. The mpmath twin is :func:`moments_ref.precise.hausdorff_bounds`.

References
----------
.. [1] Peters and Klein 2015: Christoph Peters and Reinhard Klein. 2015. *Moment Shadow Mapping*.
       In Proceedings of the 19th ACM SIGGRAPH Symposium on Interactive 3D Graphics and Games (i3D
       '15). ACM, 7–14. https://doi.org/10.1145/2699276.2699277
.. [2] HPG17: Christoph Peters. 2017. *Non-Linearly Quantized Moment Shadow Maps*. In Proceedings
       of High Performance Graphics (HPG '17). ACM. The non-linear quantization Φ, Ψ4, Algorithms
       1–3, the texel formats and the compute shader of §4.1.
"""

from __future__ import annotations

import numpy as np

from ._arrays import InputError, lookup_inputs, refuse_lookup
from .msm import canonical_representation

__all__ = ["shadow_intensity", "shadow_bounds", "free_point"]


def free_point(b, zf):
    """The free support point x of the four-point representation ``(0, zf, x, 1)``, in b's dtype.

    ``x = ((b3 − b2) zf + b3 − b4) / ((b2 − b1) zf + b2 − b3)`` from
    ``E[Z (Z − zf)(Z − x)(Z − 1)] = 0`` (module docstring, kind 2).
    """
    b1, b2, b3, b4 = (b[..., k] for k in range(4))
    return ((b3 - b2) * zf + b3 - b4) / ((b2 - b1) * zf + b2 - b3)


def _four_point(b, zf):
    """``(lower, upper)`` of the four-point representation ``(0, zf, x, 1)`` (module docstring)."""
    b1, b2, b3 = (b[..., k] for k in range(3))
    x = free_point(b, zf)
    w0 = -(b3 - (zf + x + 1) * b2 + (zf * x + zf + x) * b1 - zf * x) / (zf * x)
    wx = (b3 - (zf + 1) * b2 + zf * b1) / (x * (x - zf) * (x - 1))
    wz = (b3 - (x + 1) * b2 + x * b1) / (zf * (zf - x) * (zf - 1))
    lower = w0 + np.where(x < zf, wx, 0).astype(b.dtype)
    return lower, lower + wz


def shadow_bounds(b, zf):
    """Both Hausdorff bounds, ``(lower, upper)``: sharp bounds of Z(z < zf) and Z(z ≤ zf) on [0, 1].

    Parameters
    ----------
    b : (..., 4) float array
        Moments b1..b4 (b0 = 1 implicit) of a depth distribution on [0, 1] (``z_unit``),
        normally biased so that they lie inside the moment space.
    zf : (...) float array
        Receiver depth in [0, 1] (``z_unit``), broadcast against the moments' leading axes.

    Returns
    -------
    lower, upper : (...) float arrays in [0, 1], dtype of ``b``

    Notes
    -----
    Peters and Klein 2015, the Hausdorff bound (module docstring): Algorithm 1's
    three-point representation where its roots lie in [0, 1], else the four-point one
    ``(0, zf, x, 1)``. At ``zf ≤ 0`` the lower bound is 0 and at ``zf ≥ 1`` the upper
    bound is 1 exactly (no division by zf or 1 − zf). Clamped to [0, 1] like
    ``saturate``.
    """
    b, zf, shape = lookup_inputs(b, "b", zf)
    b = np.broadcast_to(b, shape + (4,)).reshape(-1, 4)
    zf = np.broadcast_to(zf, shape).reshape(-1)
    if not (np.isfinite(b).all() and np.isfinite(zf).all()):
        refuse_lookup(b, "b", zf)
    depths, weights = canonical_representation(b, zf)
    below = depths[..., 1:] < depths[..., :1]
    lower3 = (weights[..., 1:] * below).sum(axis=-1, dtype=b.dtype)
    upper3 = lower3 + weights[..., 0]
    roots = depths[..., 1:]
    inside = (roots >= 0).all(axis=-1) & (roots <= 1).all(axis=-1)
    four = ~inside & (zf > 0) & (zf < 1)
    lower, upper = lower3, upper3
    if four.any():
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            lower4, upper4 = _four_point(b[four], zf[four])
        lower, upper = lower3.copy(), upper3.copy()
        lower[four], upper[four] = lower4, upper4
    zero, one = b.dtype.type(0), b.dtype.type(1)
    lower = np.where(zf <= 0, zero, lower)
    upper = np.where(zf >= 1, one, upper)
    return (np.clip(lower, zero, one).astype(b.dtype).reshape(shape),
            np.clip(upper, zero, one).astype(b.dtype).reshape(shape))


def shadow_intensity(b, zf, bound="lower"):
    """The Hausdorff bound of the shadow intensity Z(z < zf) from four moments of depths in [0, 1].

    Parameters
    ----------
    b : (..., 4) float array
        Moments b1..b4 (b0 = 1 implicit) of ``z_unit`` in [0, 1], normally biased.
    zf : (...) float array
        Receiver depth ``z_unit`` in [0, 1].
    bound : {"lower", "upper"}
        ``"lower"``: the sharp lower bound of Z(z < zf) over distributions on [0, 1];
        ``"upper"``: the sharp upper bound of Z(z ≤ zf).

    Returns
    -------
    intensity : (...) float array in [0, 1], dtype of ``b``

    Notes
    -----
    Peters and Klein 2015, the Hausdorff bound; see :func:`shadow_bounds` and the module
    docstring for the two representations and the receivers at depth 0 and 1.

    Examples
    --------
    Moments of depths 0.2, 0.5 and 0.9 with equal weights; at the middle depth the
    Hausdorff bound lies above the Hamburger bound (it knows the depths are in [0, 1]):

    >>> import numpy as np
    >>> from moments_ref import msm
    >>> from moments_ref.moments import power_moments
    >>> b = power_moments([0.2, 0.5, 0.9])
    >>> bool(shadow_intensity(b, 0.6) >= msm.shadow_intensity(b, 0.6))
    True
    >>> shadow_intensity(b, [0.0, 1.0], bound="upper")[1]
    np.float64(1.0)
    """
    if bound not in ("lower", "upper"):
        raise InputError(f"bound: expected 'lower' or 'upper', got {bound!r}")
    lower, upper = shadow_bounds(b, zf)
    return lower if bound == "lower" else upper
