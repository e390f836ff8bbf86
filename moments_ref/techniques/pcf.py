"""Percentage-closer filtering with the 9×9 Gaussian: the exact filtered hard shadow.

PCF [Reeves et al. 1987] filters the *results* of shadow tests instead of the
depths. Here every fragment applies to the unfiltered MSAA samples exactly the
weights that a filterable technique applies to its texture: the bilinear weights
of the 2×2 texels around ``uv`` (the texture unit), times the 9×9 Gaussian
(σ = 2.4, HPG17 §4.1) around each of them with clamp-to-edge borders (the rule of
:func:`moments_ref.gpu.filtering.blur`), times 1/S per sample (the resolve). The result

    Z(z < zf) = Σ_taps weight · (1/S) Σ_s [z_s < zf]

is the filtered hard shadow that every filterable technique approximates: with a
filterable texture the same weights act on b(z) instead of on the test. With one
``zf`` for the whole footprint it is the PCF technique (with HPG17 §5's
receiver-slope bias in ``zf``).

With a receiver plane (``gradient``, receiver-plane depth [Isidoro 2006]) each
tap compares its sample with the plane's depth at that sample's position instead
of one ``zf`` for the whole footprint,

    Z_plane = Σ_taps weight · (1/S) Σ_s [z_s < zf + g · (p_tap,s − uv)],

with ``p_tap,s`` the tap's texel centre plus the MSAA offset of sample s
(:func:`moments_ref.scene.raster.sample_positions`): the exact filtered visibility of
a planar receiver. A lit plane then does not shadow itself at any angle and
contact shadows are kept: the reference of :mod:`moments_ref.report`.

For a :class:`~moments_ref.techniques.LayeredSamples` map (translucent occluders)
the test of a sample is ``Σ_k weight_k [z_k < zf]``, one minus the product of the
transmittances in front of ``zf`` (or of the receiver plane there): the
reference for translucent occluders.

References
----------
.. [1] Reeves et al. 1987: William T. Reeves, David H. Salesin and Robert L. Cook. 1987. *Rendering
       Antialiased Shadows with Depth Maps*. In Proceedings of SIGGRAPH '87. ACM, 283–291.
       https://doi.org/10.1145/37401.37435 (percentage-closer filtering, PCF)
.. [2] HPG17: Christoph Peters. 2017. *Non-Linearly Quantized Moment Shadow Maps*. In Proceedings
       of High Performance Graphics (HPG '17). ACM. The non-linear quantization Φ, Ψ4, Algorithms
       1–3, the texel formats and the compute shader of §4.1.
.. [3] Isidoro 2006: John R. Isidoro. 2006. *Shadow Mapping: GPU-based Tips and Techniques*. Game
       Developers Conference 2006 (receiver plane depth bias: the receiver's depth at each filter
       tap from its depth gradient in shadow-map space)
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from .._kernels import PCF_CHUNK
from ..gpu.filtering import gaussian_weights
from ..scene.raster import SAMPLE_COUNTS, sample_positions
from ._interface import Technique, is_layered, register, texture_stages

__all__ = ["pcf_filtered", "tap_weights", "tap_centres", "PCF"]

#: Fragments per chunk (each gathers 10 × 10 texels × S samples × K layers; moments_ref._kernels' table).
CHUNK = PCF_CHUNK


def tap_weights(coord, size, taps=None):
    """Texel indices and weights along one axis: bilinear ⊗ Gaussian, clamp to edge.

    Parameters
    ----------
    coord : (N,) float64 array
        Texel coordinate (centres at ``i + 0.5``).
    size : int
        Map extent along the axis.
    taps : (9,) float array, optional
        Gaussian weights (default :func:`moments_ref.gpu.filtering.gaussian_weights`).

    Returns
    -------
    index : (N, 10) intp array
        ``clamp(i0 − 4 + t)`` for t = 0..9, with ``i0 = clamp(floor(coord − ½))``.
    weight : (N, 10) float64 array
        Summing to 1: ``(1 − f)·g`` on the taps of texel i0, ``f·g`` on those of
        texel ``i1 = clamp(i0 + 1)`` (which coincide with i0's at the border).

    Notes
    -----
    The bilinear footprint is clamped first, then each texel's Gaussian taps
    are clamped, exactly as a hardware bilinear fetch of the blurred texture.
    """
    g = gaussian_weights() if taps is None else np.asarray(taps, dtype=np.float64)
    r = (len(g) - 1) // 2
    s, base, first = _first_texel(coord, size)
    f = s - base
    i0 = first.astype(np.intp)
    i1 = np.clip(base + 1, 0, size - 1).astype(np.intp)
    n = len(g) + 1
    weight = np.zeros(s.shape + (n,))
    weight[:, : n - 1] += (1 - f)[:, None] * g
    shifted = i1 != i0
    # i1 = i0 + 1 inside the map: its taps start one later; at the border i1 = i0.
    weight[:, 1:] += np.where(shifted, f, 0.0)[:, None] * g
    weight[:, : n - 1] += np.where(shifted, 0.0, f)[:, None] * g
    index = np.clip(i0[:, None] - r + np.arange(n), 0, size - 1)
    return index, weight


def tap_centres(coord, size, taps=9):
    """Positions along one axis that the 10 taps of :func:`tap_weights` stand for.

    ``i0 − 4 + t + ½`` for t = 0..9 (the texel centres before clamping to the
    edge; :func:`tap_weights` fetches the clamped index), ``i0 = clamp(floor(coord − ½))``.
    Returns an (N, 10) float64 array.
    """
    r = (taps - 1) // 2
    i0 = _first_texel(coord, size)[2]
    return i0[:, None] - r + np.arange(taps + 1) + 0.5


def _first_texel(coord, size):
    """``s = coord − ½``, ``floor(s)`` and the footprint's first texel ``clamp(floor(s), 0, size − 1)`` (float64)."""
    s = np.asarray(coord, dtype=np.float64) - 0.5
    base = np.floor(s)
    return s, base, np.clip(base, 0, size - 1)


def _sample_offsets(S):
    """MSAA sample offsets (S, 2) of the map; the texel centre when S is not a rasterizer count."""
    return sample_positions(S) if S in SAMPLE_COUNTS else np.zeros((S, 2))


def pcf_filtered(samples, uv, zf, gradient=None):
    """Gaussian-weighted percentage-closer filtering of the MSAA samples, float64.

    Parameters
    ----------
    samples : (H, W, S) float array or LayeredSamples
        Unfiltered shadow map.
    uv : (..., 2) float array
        Texel coordinates (u = column, v = row, centres at ``i + 0.5``).
    zf : (...) float array
        Fragment depth (already biased), broadcast against ``uv[..., 0]``.
    gradient : (..., 2) float array, optional
        Receiver plane: depth change per texel ``(∂z/∂u, ∂z/∂v)``
        (:attr:`moments_ref.scene.gbuffer.GBuffer.gradient`). Sample s of the tap at
        texel centre ``c`` (:func:`tap_centres`) is compared with
        ``min(zf + gradient · (c + o_s − uv), 1)``, ``o_s`` its MSAA offset
        (the far plane bounds the plane: the clear depth 1 occludes nothing).
        Default: ``zf`` for every tap.

    Returns
    -------
    intensity : (...) float64 array in [0, 1]
        ``Σ_{rows, cols} wy · wx · (1/S) Σ_s Σ_k weight_k [z_k < zf_tap,s]`` with the
        weights of :func:`tap_weights`.
    """
    layered = is_layered(samples)
    depth = samples.depth if layered else np.asarray(samples)[..., None]
    lw = samples.weight if layered else None
    H, W, S, K = depth.shape
    uv = np.asarray(uv, dtype=np.float64)
    zf = np.asarray(zf, dtype=np.float64)
    shape = np.broadcast_shapes(uv.shape[:-1], zf.shape)
    uvf = np.broadcast_to(uv, shape + (2,)).reshape(-1, 2)
    zff = np.broadcast_to(zf, shape).reshape(-1)
    if gradient is not None:
        grad = np.broadcast_to(np.asarray(gradient, dtype=np.float64), shape + (2,)).reshape(-1, 2)
        off = _sample_offsets(S)
    out = np.empty(zff.shape[0])
    flat = depth.reshape(H * W, S, K)
    for lo in range(0, zff.shape[0], CHUNK):
        hi = lo + CHUNK
        ci, cw = tap_weights(uvf[lo:hi, 0], W)
        ri, rw = tap_weights(uvf[lo:hi, 1], H)
        texel = ri[:, :, None] * W + ci[:, None, :]  # (n, 10, 10)
        d = flat.take(texel, axis=0)  # (n, 10, 10, S, K): a flat gather, not a 2-D fancy index
        z = zff[lo:hi, None, None, None]  # (n, 1, 1, 1): one depth for the footprint
        if gradient is not None:
            z = _receiver_plane(z, grad[lo:hi], uvf[lo:hi], off, W, H)
        # Compare in float64: the float32 depths are exact there.
        test = d < z[..., None]
        if layered:
            occluded = (test * lw.reshape(H * W, S, K).take(texel, axis=0)).sum(axis=-1).mean(axis=-1)
        else:
            occluded = _share(test[..., 0])
        out[lo:hi] = np.einsum("nij,ni,nj->n", occluded, rw, cw)
    return np.clip(out, 0.0, 1.0).reshape(shape)


def _receiver_plane(z, grad, uv, off, W, H):
    """``min(zf + gx·(x − u) + gy·(y − v) + gx·o_x + gy·o_y, 1)`` per tap and sample (Isidoro 2006), (n, 10, 10, S).

    The sums in this order, the full-size ones in place (the far plane, depth 1,
    bounds the plane: the map's clear depth 1 occludes nothing). The sample terms are
    added one sample at a time into that sample's strided slice (long passes of 100 n
    values) instead of broadcasting the (n, 10, 10, 1) rows against (n, 1, 1, S), whose
    inner loops are S values long: the same operations on the same operands.
    """
    gx, gy = grad[:, 0], grad[:, 1]
    dx = tap_centres(uv[:, 0], W) - uv[:, :1]  # (n, 10) columns
    dy = tap_centres(uv[:, 1], H) - uv[:, 1:]  # (n, 10) rows
    rows = z[..., 0] + (gx[:, None] * dx)[:, None, :] + (gy[:, None] * dy)[:, :, None]  # (n, 10, 10)
    sx, sy = gx[:, None] * off[:, 0], gy[:, None] * off[:, 1]  # (n, S)
    out = np.empty(rows.shape + (off.shape[0],))
    for s in range(off.shape[0]):  # loop over the MSAA samples
        np.add(rows, sx[:, s, None, None], out=out[..., s])
        out[..., s] += sy[:, s, None, None]
    return np.minimum(out, 1.0, out=out)


#: Unsigned integer holding S booleans, for the sample counts whose share is a bit count.
_SAMPLE_WORDS = {1: np.uint8, 2: np.uint16, 4: np.uint32, 8: np.uint64}


def _share(test):
    """``test.mean(axis=-1)`` of a C-contiguous boolean (..., S) array, exactly (float64).

    For S in 1, 2, 4, 8 the S booleans of a tap are one unsigned word whose set
    bits count the true ones (a boolean is the byte 0 or 1); the count over S is
    what the mean's exact sum of zeros and ones divided by S gives.
    """
    S = test.shape[-1]
    word = _SAMPLE_WORDS.get(S)
    if word is None or not test.flags.c_contiguous:
        return test.mean(axis=-1)
    count = np.bitwise_count(test.view(word)[..., 0])
    return np.divide(count, S, dtype=np.float64)


def _steps(samples, layered):
    return ()  # the texture is the unfiltered shadow map itself


def _lookup(texture, uv, zf, noise):
    return pcf_filtered(texture, uv, zf)


def _stages(technique, ctx, settings=None):
    """:func:`texture_stages`, storing every MSAA sample: 32 bits per depth sample, ``32 S`` bits per texel."""
    return replace(texture_stages(technique, ctx, settings), bits=32 * ctx.samples)


#: PCF: 32-bit depth per MSAA sample (``32 S`` bits per texel), no filtered texture; cost is per fragment.
PCF = register(Technique(
    name="pcf",
    bits_per_texel=32,
    stages=_stages,
    depth_bias=1e-3,
    slope_bias=True,  # HPG17 §5: PCF "with a higher depth bias" (moments_ref.scene.gbuffer.z_ndc_lookup)
    make_steps=_steps,
    lookup=_lookup,
    description="percentage-closer filtering, 9x9 Gaussian (sigma 2.4) x bilinear over the MSAA samples "
                "(32 bits per depth sample)",
    reference="Reeves et al. 1987; HPG17 §5 (the reference of the comparison)",
))
