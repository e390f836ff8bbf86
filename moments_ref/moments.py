"""Power moments of depth distributions, the Hankel matrix and moment biasing.

HPG17 §2 defines the depth distribution of a filter region as
``Z = sum_l w_l δ_{z_l}`` and its power moments ``b = E_Z(b(z))`` with
``b(z) = (1, z, z², z³, z⁴)``. Moment vectors here hold ``b1..bn`` on the trailing
axis; ``b0 = 1`` is implicit.

References
----------
.. [1] HPG17: Christoph Peters. 2017. *Non-Linearly Quantized Moment Shadow Maps*. In Proceedings
       of High Performance Graphics (HPG '17). ACM. The non-linear quantization Φ, Ψ4, Algorithms
       1–3, the texel formats and the compute shader of §4.1.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._arrays import InputError, as_real, check_axis, check_finite, first_index, real_input

__all__ = [
    "power_moments",
    "hankel",
    "BiasPreset",
    "bias_preset",
    "BIAS_FLOAT32",
    "BIAS_UNORM16",
    "bias_moments",
]


def power_moments(z, weights=None, axis=-1, n=4):
    """Power moments b1..bn of a weighted sum of Dirac deltas.

    Parameters
    ----------
    z : array_like, float
        Depths. The samples of one distribution run along ``axis``.
    weights : array_like, optional
        Non-negative weights broadcastable to ``z``; normalized per distribution
        so they sum to one. Default: equal weights.
    axis : int
        The axis of ``z`` that holds the samples.
    n : int
        Number of moments, 4 (moment shadow mapping) or 6 (single scattering).

    Returns
    -------
    b : (..., n) float array
        ``b_k = sum_l w_l z_l^k / sum_l w_l`` for k = 1..n, the sample axis removed
        and the moments appended as the trailing axis. dtype per the policy.

    Notes
    -----
    HPG17 §2: ``b := E_Z(b) = sum_l w_l b(z_l)``. Depths are not restricted to
    [-1, 1] here; the algorithms that need that range check it themselves.

    Domain: finite depths with ``N·|z|ⁿ`` below the largest finite value of the
    working dtype (N samples per distribution; in float32 with n = 4 and
    N = 16, |z| < 2.2e9), so that no moment overflows; larger depths raise
    :class:`~moments_ref.InputError`. Weights are any finite non-negative
    values with a positive sum per distribution: they are scaled by their
    maximum before normalizing, so 3e38 or subnormal weights do not overflow or
    vanish.

    Examples
    --------
    >>> power_moments([0.5, -0.5])
    array([0.    , 0.25  , 0.    , 0.0625])
    """
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n not in (4, 6):
        raise InputError(f"n: expected 4 or 6, got {n!r}")
    if isinstance(axis, bool) or not isinstance(axis, (int, np.integer)):
        raise InputError(f"axis: expected an integer axis, got {axis!r}")
    z = real_input(z, "z")
    if z.ndim == 0:
        raise InputError("z: expected at least one axis of samples, got a scalar")
    axis = check_axis(axis, z.ndim, "z")
    w = None
    if weights is not None:
        w = real_input(weights, "weights", dtype=z.dtype)
        try:
            w = np.broadcast_to(w, z.shape)
        except ValueError:
            raise InputError(
                f"weights: expected a shape broadcastable to z {z.shape}, got {w.shape}"
            ) from None
        if (w < 0).any():
            idx = first_index(w < 0)
            raise InputError(f"weights: expected non-negative values, got {w[idx]!r} at index {idx}")
    try:
        z = np.moveaxis(z, axis, -1)
        w = None if w is None else np.moveaxis(w, axis, -1)
    except np.exceptions.AxisError:
        raise InputError(f"axis: expected an axis of z with shape {z.shape}, got {axis}") from None
    if z.shape[-1] == 0:
        raise InputError(f"z: expected at least one sample along axis {axis}, got none")
    limit = (float(np.finfo(z.dtype).max) / z.shape[-1]) ** (1.0 / n)
    big = np.abs(z) >= limit
    if big.any():
        idx = first_index(np.moveaxis(big, -1, axis))
        raise InputError(f"z: expected |z| < {limit:.3g} (N·|z|^{n} finite in {z.dtype}), got "
                         f"{np.moveaxis(z, -1, axis)[idx]!r} at index {idx}")
    if w is not None:
        # Scale by the largest weight first: sums of 3e38 (or of subnormals) stay finite and non-zero.
        wmax = w.max(axis=-1)
        if (wmax <= 0).any():
            idx = first_index(wmax <= 0)
            raise InputError(f"weights: expected a positive sum per distribution, got 0 at distribution {idx}")
        with np.errstate(over="ignore"):
            total = w.sum(axis=-1)
        if not np.all(np.isfinite(total) & (total >= np.finfo(w.dtype).tiny)):
            w = w / wmax[..., None]
            total = w.sum(axis=-1)
        w = w / total[..., None]
    out = np.empty(z.shape[:-1] + (n,), dtype=z.dtype)
    power = z.copy()
    for k in range(n):
        out[..., k] = power.mean(axis=-1) if w is None else np.einsum("...i,...i->...", power, w)
        if k + 1 < n:
            power *= z
    return out


def hankel(b):
    """The Hankel matrix B(b) of HPG17 Algorithm 1, step (1).

    Parameters
    ----------
    b : (..., 4) float array
        Moments b1..b4 (b0 = 1 implicit). A (..., 6) vector gives the 4×4 matrix
        used with six moments.

    Returns
    -------
    B : (..., 3, 3) float array (or (..., 4, 4) for six moments)
        ``B[i, j] = b_{i+j}``.
    """
    b = real_input(b, "b", trailing=(4, 6))
    full = np.concatenate([np.ones(b.shape[:-1] + (1,), dtype=b.dtype), b], axis=-1)
    m = b.shape[-1] // 2 + 1
    idx = np.add.outer(np.arange(m), np.arange(m))
    return full[..., idx]


@dataclass(frozen=True)
class BiasPreset:
    """A moment bias ``b' = (1 - alpha) b + alpha b*`` (HPG17 §3.2)."""

    alpha: float
    target: tuple[float, ...]
    name: str = "custom"

    def __post_init__(self):
        a = self.alpha
        if isinstance(a, (bool, str)) or not np.isscalar(a) or not np.isreal(a) or not 0.0 <= float(a) <= 1.0:
            raise InputError(f"alpha: expected a number in [0, 1], got {a!r}")
        try:
            target = tuple(float(t) for t in self.target)
        except (TypeError, ValueError):
            raise InputError(f"target: expected 4 or 6 numbers, got {self.target!r}") from None
        if len(target) not in (4, 6) or not np.all(np.isfinite(target)):
            raise InputError(f"target: expected finite numbers of length 4 or 6, got {self.target!r}")
        if not isinstance(self.name, str):
            raise InputError(f"name: expected a string, got {self.name!r}")
        object.__setattr__(self, "alpha", float(a))
        object.__setattr__(self, "target", target)


#: Biasing for moments stored in single-precision floats (HPG17 §3.2, input of Alg. 2).
BIAS_FLOAT32 = BiasPreset(3e-7, (0.0, 0.375, 0.0, 0.375), "float32")
#: Biasing for the affine 64-bit UNORM16 quantization (HPG17 §3.2; slides "Bias the moments").
BIAS_UNORM16 = BiasPreset(6e-5, (0.0, 0.628, 0.0, 0.628), "unorm16")


def bias_preset(preset) -> BiasPreset:
    """``preset`` as a :class:`BiasPreset`: a preset itself, or an ``(alpha, target)`` pair (InputError otherwise)."""
    if isinstance(preset, BiasPreset):
        return preset
    try:
        alpha, target = preset
    except (TypeError, ValueError):
        raise InputError(
            f"preset: expected a BiasPreset or an (alpha, target) pair, got {preset!r}"
        ) from None
    try:
        return BiasPreset(alpha, target)
    except InputError as exc:
        raise InputError(f"preset: {exc}") from None


def bias_moments(b, preset=BIAS_FLOAT32):
    """Pull moments towards a fixed interior point: ``b' = (1 − α)·b + α·b*``.

    Parameters
    ----------
    b : (..., 4) or (..., 6) float array
        Moments b1..bn.
    preset : BiasPreset or (alpha, target)
        ``BIAS_FLOAT32`` (α = 3e-7, b* = (0, 0.375, 0, 0.375)) for float moments,
        ``BIAS_UNORM16`` (α = 6e-5, b* = (0, 0.628, 0, 0.628)) for the 64-bit
        affine quantization, or any α in [0, 1] with a target of b's length.

    Returns
    -------
    b_biased : float array, same shape and dtype as ``b``

    Notes
    -----
    HPG17 §3.2 and slides "Bias the moments". b0 = 1 is unchanged because the
    target's b0* = 1. Moment vectors slightly outside the moment space after
    rounding are valid input: pulling them inside is the purpose of this step.
    """
    p = bias_preset(preset)
    b = real_input(b, "b", trailing=(4, 6))
    if not (0.0 <= p.alpha <= 1.0):
        raise InputError(f"preset: expected alpha in [0, 1], got {p.alpha!r}")
    target = np.asarray(p.target, dtype=b.dtype)
    if target.shape != (b.shape[-1],):
        raise InputError(
            f"preset: expected a target of length {b.shape[-1]} to match b, got {len(p.target)}"
        )
    check_finite(target, "preset.target")
    alpha = b.dtype.type(p.alpha)
    # In place on the one new array (IEEE products commute, so b·(1 − α) is (1 − α)·b bit for bit).
    out = np.multiply(b, b.dtype.type(1) - alpha)
    out += alpha * target
    return out
