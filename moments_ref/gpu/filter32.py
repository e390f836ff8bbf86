"""Legitimate float32 evaluations of the HPG17 §4 filter: the spread a correct GPU kernel may show.

A compute shader resolves the multisampled depths into moments and blurs them with
the 9² Gaussian in float32 (HPG17 §4.1). Two correct kernels, or a kernel and the
float64 reference (:func:`moments_ref.gpu.filtering.blur`), differ by float32
rounding, and by how much depends on choices the paper leaves open:

* **the order of the sums**: the resolve over the samples left to right or as a
  tree; the taps of a pass left to right, right to left, as a tree (Mesa's GL
  compiler turns ``((a+b)+c)+d`` into ``(a+b)+(c+d)``), or symmetric
  (``w₄v₄ + Σ wₜ(vₜ + v₈₋ₜ)``, one multiply per pair of equal weights);
* **the powers**: ``z⁴`` as ``z²·z²`` or ``z³·z``;
* **the weights**: the float64 Gaussian rounded to float32, or computed on the GPU
  in float32 with an ``exp`` a few ulps off (GLSL allows 3 + 2|x| ulps) and
  normalized in float32, by a division or by a multiplication with the
  reciprocal of the sum.

:data:`VARIANTS` names a set of such kernels, each a :class:`Filter32`, and
:func:`filter_float32` runs one on a whole map, vectorized (the clamp-to-edge
border of :mod:`moments_ref.gpu.filtering`). The variant ``"onchip"`` is the
arithmetic of :mod:`moments_ref.gpu.onchip` (the block emulation of the shader),
bit for bit. The golden kernel cases (:mod:`moments_ref.golden.kernels`) take
the spread of their tolerances from these variants, so that a float32 kernel
written either way passes and one with a different filter does not.

References
----------
.. [1] HPG17: Christoph Peters. 2017. *Non-Linearly Quantized Moment Shadow Maps*. In Proceedings
       of High Performance Graphics (HPG '17). ACM. The non-linear quantization Φ, Ψ4, Algorithms
       1–3, the texel formats and the compute shader of §4.1.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._arrays import InputError
from .filtering import SIGMA, TAPS, check_depth_samples, gaussian_weights

__all__ = ["Filter32", "VARIANTS", "SUM_ORDERS", "WEIGHTS", "weights_float32", "resolve_float32",
           "blur_float32", "filter_float32", "variant_moments"]

#: How the taps of one pass (or the samples of the resolve) are summed.
SUM_ORDERS = ("sequential", "reversed", "pairwise", "symmetric")
#: How the Gaussian's weights come to the kernel.
WEIGHTS = ("rounded", "float32", "exp+3ulp", "exp-3ulp", "reciprocal")


@dataclass(frozen=True)
class Filter32:
    """One legitimate float32 filter kernel: resolve order, powers, blur order, weights."""

    name: str
    resolve: str = "sequential"  # "sequential" or "pairwise" over the samples
    z4: str = "z2*z2"  # or "z3*z"
    blur: str = "sequential"  # one of SUM_ORDERS
    weights: str = "rounded"  # one of WEIGHTS


#: The variants the kernel cases' spread is measured on ("onchip" = gpu.onchip's arithmetic).
VARIANTS = (
    Filter32("onchip"),
    Filter32("tree", resolve="pairwise", blur="pairwise", weights="float32"),
    Filter32("reversed", blur="reversed", weights="exp+3ulp"),
    Filter32("symmetric", resolve="pairwise", blur="symmetric", weights="exp-3ulp"),
    Filter32("z3z", z4="z3*z", weights="reciprocal"),
)


def weights_float32(kind="rounded", taps=TAPS, sigma=SIGMA):
    """The 1D Gaussian's weights as a float32 kernel gets them.

    ``"rounded"``: :func:`~moments_ref.gpu.filtering.gaussian_weights` rounded to
    float32. ``"float32"``: ``exp(−i²/(2σ²))`` in float32, divided by their float32
    sum (left to right). ``"exp+3ulp"`` / ``"exp-3ulp"``: the same with every
    ``exp`` 3 ulps high / low on alternate taps (an ``exp`` within GLSL's
    3 + 2|x| ulps). ``"reciprocal"``: float32 ``exp`` times the reciprocal of the sum.
    """
    if kind not in WEIGHTS:
        raise InputError(f"kind: expected one of {WEIGHTS}, got {kind!r}")
    if kind == "rounded":
        return gaussian_weights(taps, sigma).astype(np.float32)
    f = np.float32
    i = np.arange(taps, dtype=f) - f((taps - 1) / 2)
    e = np.exp(-(i * i) / f(2 * sigma * sigma)).astype(f)
    if kind in ("exp+3ulp", "exp-3ulp"):
        sign = np.where(np.arange(taps) % 2 == 0, 1, -1) * (1 if kind == "exp+3ulp" else -1)
        e = (e + sign * 3 * np.spacing(e)).astype(f)
    total = f(0)
    for x in e:  # a shader's loop sums left to right
        total = f(total + x)
    return (e * (f(1) / total)).astype(f) if kind == "reciprocal" else (e / total).astype(f)


def _sum(terms, order):
    """Sum float32 arrays in a given order (``terms`` a list; float32 throughout)."""
    if order == "sequential":
        acc = terms[0].copy()
        for t in terms[1:]:
            acc += t
        return acc
    if order == "reversed":
        acc = terms[-1].copy()
        for t in terms[-2::-1]:
            acc += t
        return acc
    if order == "pairwise":
        level = list(terms)
        while len(level) > 1:
            nxt = [level[k] + level[k + 1] for k in range(0, len(level) - 1, 2)]
            level = nxt + ([level[-1]] if len(level) % 2 else [])
        return level[0]
    raise InputError(f"order: expected one of {SUM_ORDERS[:3]}, got {order!r}")


def resolve_float32(depth_samples, order="sequential", z4="z2*z2"):
    """MSAA resolve in float32: ``(1/S) Σ_s b(z_s)`` with the sum in ``order``, (H, W, 4) float32."""
    z = check_depth_samples(depth_samples).astype(np.float32)
    zs = np.moveaxis(z, -1, 0)  # (S, H, W)
    z2 = zs * zs
    z3 = z2 * zs
    p4 = z2 * z2 if z4 == "z2*z2" else z3 * zs
    s = np.float32(zs.shape[0])
    if order == "sequential":  # from 0, as a shader's accumulator (and gpu.onchip)
        out = [_sum([np.zeros_like(zs[0])] + list(p), "sequential") for p in (zs, z2, z3, p4)]
    else:
        out = [_sum(list(p), order) for p in (zs, z2, z3, p4)]
    return np.stack([o / s for o in out], axis=-1)


def _pass(m, w, axis, order):
    """One pass of the 9-tap filter along ``axis`` of a clamp-padded float32 map."""
    r = (len(w) - 1) // 2
    n = m.shape[axis] - 2 * r
    shifted = [np.take(m, np.arange(t, t + n), axis=axis) for t in range(len(w))]
    if order == "symmetric":
        terms = [w[r] * shifted[r]] + [w[t] * (shifted[t] + shifted[2 * r - t]) for t in range(r)]
        return _sum(terms, "sequential")
    return _sum([w[t] * shifted[t] for t in range(len(w))], order)


def blur_float32(moments, weights, order="sequential"):
    """Horizontal then vertical float32 pass with clamp-to-edge borders, taps summed in ``order``."""
    m = np.asarray(moments, np.float32)
    w = np.asarray(weights, np.float32)
    if order not in SUM_ORDERS:
        raise InputError(f"order: expected one of {SUM_ORDERS}, got {order!r}")
    r = (len(w) - 1) // 2
    padded = np.pad(m, ((r, r), (r, r), (0, 0)), mode="edge")
    return _pass(_pass(padded, w, 1, order), w, 0, order)


def filter_float32(depth_samples, variant=VARIANTS[0]):
    """Resolve and blur a multisampled map as the float32 kernel ``variant`` does: (H, W, 4) float32.

    Parameters
    ----------
    depth_samples : (H, W, S) float array
        Sample depths in [-1, 1] (rounded to float32 first, as a depth texture holds them).
    variant : Filter32 or str
        A kernel of :data:`VARIANTS` or its name.
    """
    if isinstance(variant, str):
        found = [v for v in VARIANTS if v.name == variant]
        if not found:
            raise InputError(f"variant: expected one of {[v.name for v in VARIANTS]}, got {variant!r}")
        variant = found[0]
    m = resolve_float32(depth_samples, variant.resolve, variant.z4)
    return blur_float32(m, weights_float32(variant.weights), variant.blur)


def variant_moments(depth_samples):
    """``{name: filter_float32(depth_samples, v)}`` for every variant of :data:`VARIANTS`."""
    return {v.name: filter_float32(depth_samples, v) for v in VARIANTS}
