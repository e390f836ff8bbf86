"""MSAA resolve of a moment shadow map and the two-pass 9-tap Gaussian reference blur.

HPG17 §4: a multisampled shadow map is turned into moments per sample and averaged
per texel (the resolve); then a separable Gaussian of size 9² and standard
deviation 2.4 texels filters the moments, horizontally then vertically. This module
is the classic multi-pass ("global") path in float64, the oracle that
:mod:`moments_ref.gpu.onchip` (the block-wise shared-memory shader of HPG17 §4.1) is
checked against.

Border rule
-----------
Clamp-to-edge: a tap that falls outside the map reads the nearest texel of the
map, ``m[clip(y, 0, H−1), clip(x, 0, W−1)]``. This is what a GPU texture load with
clamp addressing returns, and it is what the on-chip shader's guard band loads at
the border of the map. Each pass clamps on its own axis, which is the same as
clamping both coordinates of the 9×9 kernel.

References
----------
.. [1] HPG17: Christoph Peters. 2017. *Non-Linearly Quantized Moment Shadow Maps*. In Proceedings
       of High Performance Graphics (HPG '17). ACM. The non-linear quantization Φ, Ψ4, Algorithms
       1–3, the texel formats and the compute shader of §4.1.
"""

from __future__ import annotations

import numpy as np

from .._arrays import InputError, check_finite, first_index, real_input
from .._kernels import FILTER_BAND_BYTES, PATH_BAND_TEXELS, RESOLVE_BYTES
from ..moments import power_moments
from ..packing import nlq_texels

__all__ = [
    "TAPS",
    "SIGMA",
    "resolve_moments",
    "gaussian_weights",
    "blur",
    "check_depth_samples",
    "bench_depth_map",
    "quantize_nlq",
    "global_path_nlq",
]

#: Filter size and standard deviation of HPG17 §4.1 ("9² ... 2.4 texels").
TAPS = 9
SIGMA = 2.4


def check_depth_samples(depth_samples, name="depth_samples") -> np.ndarray:
    """Validate an (H, W, S) array of sample depths in [-1, 1]; dtype per the policy."""
    z = real_input(depth_samples, name, finite=False)
    # Fast path, two reductions and no whole-map masks: NaN or ±inf make min or max
    # fail the test, so passing it proves every depth finite and in [-1, 1]. Otherwise
    # the checks below run in their usual order and name the first bad index.
    if z.ndim == 3 and 0 not in z.shape and z.dtype.kind == "f" and z.min() >= -1 and z.max() <= 1:
        return z
    check_finite(z, name)
    if z.ndim != 3:
        raise InputError(f"{name}: expected an (H, W, S) array of sample depths, got shape {z.shape}")
    if 0 in z.shape:
        raise InputError(f"{name}: expected at least one texel and one sample, got shape {z.shape}")
    bad = (z < -1) | (z > 1)
    if bad.any():
        idx = first_index(bad)
        raise InputError(f"{name}: expected depths in [-1, 1], got {z[idx]!r} at index {idx}")
    return z


def resolve_moments(depth_samples):
    """MSAA resolve: average the moments ``b(z) = (z, z², z³, z⁴)`` of each texel's samples.

    Parameters
    ----------
    depth_samples : (H, W, S) float array
        Depths in [-1, 1] of the S samples of each texel (S = 1 for a map without
        multisampling).

    Returns
    -------
    b : (H, W, 4) float array
        ``b_k = (1/S) Σ_s z_s^k``; float32 for float32 input, else float64.

    Raises
    ------
    InputError
        Not three axes, an empty axis, a non-finite depth or a depth outside
        [-1, 1] (the message gives the first bad index).

    Notes
    -----
    HPG17 §4, first paragraph: "each sample from a multisampled shadow map is
    turned into a vector of moments and the samples are averaged per texel for the
    resolve". Equal weights: the samples of a texel cover equal areas.

    Examples
    --------
    >>> resolve_moments([[[0.5, -0.5]]])
    array([[[0.    , 0.25  , 0.    , 0.0625]]])
    """
    return _resolve(check_depth_samples(depth_samples))


def _resolve(z):
    """:func:`resolve_moments` of checked samples (H, W, S), L2-sized chunks at a time."""
    h, w, n = z.shape
    out = np.empty((h * w, 4), dtype=z.dtype)
    _resolve_planes(z, out.T)
    return out.reshape(h, w, 4)


def _resolve_planes(z, planes):
    """:func:`resolve_moments` of checked samples (H, W, S) into ``planes[k − 1]`` (4, H·W), chunk by chunk.

    ``planes`` may be the transposed view of (H·W, 4) texels or four contiguous planes
    (the global path's bands): the same values, only their layout differs.
    """
    flat = z.reshape(-1, z.shape[-1])
    step = max(1, _RESOLVE_BYTES // (z.itemsize * z.shape[-1]))
    for lo in range(0, flat.shape[0], step):
        _resolve_chunk(flat[lo : lo + step], planes[:, lo : lo + step])


#: Input bytes of one chunk of the resolve (moments_ref._kernels' table, with the reason).
_RESOLVE_BYTES = RESOLVE_BYTES


def _resolve_chunk(z, out):
    """``out[k-1] = mean_s z[:, s]^k`` for k = 1..4 (out: (4, N)), bit for bit as :func:`power_moments`.

    The samples are transposed to one contiguous row per sample (structure of
    arrays), so every power and every partial sum is one contiguous ufunc call.
    ``power_moments`` takes ``mean(axis=-1)`` of z, z·z, (z·z)·z, ...; NumPy sums
    fewer than 8 values left to right and exactly 8 pairwise (its unrolled
    pairwise sum), which is what is done here; more than 8 samples go through
    ``power_moments`` itself, a chunk at a time.
    """
    n = z.shape[1]
    if n > 8:
        out[:] = power_moments(z, axis=-1, n=4).T
        return
    # The mean's division by n; for n a power of two as the product with 1/n (exact:
    # both round the same real value acc · 2^-k, subnormals included), a cheaper pass.
    inv = 1.0 / n if n & (n - 1) == 0 else None
    zs = np.ascontiguousarray(z.T)
    p = zs  # the powers z^(k+1), one row per sample; z itself is not copied
    acc = np.empty(z.shape[0], z.dtype)
    tmp = np.empty_like(acc)
    for k in range(4):
        if n < 8:
            # NumPy's sum starts from +0: -0.0 samples sum to +0.0. Only odd powers can
            # be -0.0 (z = -0.0, or z³ underflowing from a tiny negative z); an even
            # power is +0.0 or positive, so +0 + p[0] is p[0] and its sum starts there.
            first = 1 if k % 2 == 0 or n == 1 else 2
            np.add(p[0], 0.0 if first == 1 else p[1], out=acc)
            for s in range(first, n):
                acc += p[s]
        else:
            np.add(p[0], p[1], out=acc)
            acc += np.add(p[2], p[3], out=tmp)
            pair = np.add(p[4], p[5])
            pair += np.add(p[6], p[7], out=tmp)
            acc += pair
            acc += 0.0
        if inv is None:
            np.divide(acc, n, out=out[k])
        else:
            np.multiply(acc, inv, out=out[k])
        if k == 0:
            p = zs * zs
        elif k < 3:
            p *= zs


def gaussian_weights(taps=TAPS, sigma=SIGMA):
    """Normalized 1D Gaussian filter weights.

    Parameters
    ----------
    taps : int
        Odd number of taps (9 in HPG17 §4.1).
    sigma : float
        Standard deviation in texels (2.4 in HPG17 §4.1).

    Returns
    -------
    w : (taps,) float64 array
        ``w_i ∝ exp(−i² / (2σ²))`` for ``i = −(taps−1)/2 .. (taps−1)/2``, summing to 1.

    Notes
    -----
    HPG17 §4.1: "The Gaussian filter has size 9² and a standard deviation of 2.4
    texels." The truncated kernel is renormalized so that a constant map stays
    constant (b0 = 1 is preserved by filtering).

    Examples
    --------
    >>> w = gaussian_weights()
    >>> w.shape, bool(np.isclose(w.sum(), 1.0))
    ((9,), True)
    """
    if isinstance(taps, bool) or not isinstance(taps, (int, np.integer)) or taps < 1 or taps % 2 == 0:
        raise InputError(f"taps: expected a positive odd integer, got {taps!r}")
    sigma = float(sigma)
    if not np.isfinite(sigma) or sigma <= 0:
        raise InputError(f"sigma: expected a positive finite number, got {sigma!r}")
    i = np.arange(taps, dtype=np.float64) - (taps - 1) / 2
    w = np.exp(-(i * i) / (2.0 * sigma * sigma))
    return w / w.sum()


def _correlate(p, w, out, tmp, axis):
    """``out = Σ_t w[t] · p[t : t + n]`` along ``axis`` (``n = out.shape[axis]``), term by term in order of t.

    On a C-contiguous ``p`` each window is a contiguous block (axis 0) or rows of
    contiguous runs of ``n · C`` values (axis 1), so each term is one multiply and
    one in-place add with no temporary beyond ``tmp``; the terms and their order
    are those of the straightforward sum, so the result does not depend on it.
    """
    n = out.shape[axis]

    def window(t):
        return p[t : t + n] if axis == 0 else p[:, t : t + n]

    np.multiply(window(0), w[0], out=out)
    for t in range(1, len(w)):
        np.multiply(window(t), w[t], out=tmp)
        out += tmp


def _symmetric(w):
    """Whether the kernel is exactly symmetric (then :func:`_correlate_symmetric` and scipy.ndimage sum it)."""
    return bool(np.array_equal(w, w[::-1]))


def _correlate_symmetric(p, w, out, tmp, axis, final=None):
    """``out = w[r]·p_r + Σ_{j=0}^{r−1} w[j]·(p_j + p_{2r−j})``, j ascending (windows as in :func:`_correlate`).

    A symmetric kernel (``w[j] = w[2r − j]``) folded: 1 + 3r passes instead of 4r + 1.
    The terms and their order are those of ``scipy.ndimage.correlate1d`` for a
    symmetric kernel (centre first, then the pairs from the outermost in), so the
    horizontal pass (that C loop) and this vertical pass sum alike. ``final``, when
    given, receives the last sum instead of ``out`` (a float32 array: the float64 sum
    rounded once on store, as ``.astype(np.float32)`` of it).
    """
    n = out.shape[axis]
    r = (len(w) - 1) // 2

    def window(t):
        return p[t : t + n] if axis == 0 else p[:, t : t + n]

    np.multiply(window(r), w[r], out=out)
    for j in range(r):
        np.add(window(j), window(2 * r - j), out=tmp)
        tmp *= w[j]
        np.add(out, tmp, out=out if final is None or j < r - 1 else final, casting="same_kind")
    if r == 0 and final is not None:
        final[...] = out


#: Bytes of one band of rows (moments_ref._kernels' table, with the measurement). Results do not depend on it.
_BAND_BYTES = FILTER_BAND_BYTES
#: Bytes of float64 horizontal-pass rows per band of :func:`blur` (its halo of 8 rows is recomputed per band).
_BLUR_BAND_BYTES = 4 * FILTER_BAND_BYTES


def blur(moments, weights=None):
    """Two-pass separable Gaussian blur with clamp-to-edge borders, in float64.

    Parameters
    ----------
    moments : (H, W, C) float array
        A moment map (C = 4 for moment shadow maps; any C, e.g. 2 for VSM).
    weights : (taps,) float array, optional
        Odd-length 1D kernel; default :func:`gaussian_weights` (9 taps, σ = 2.4).

    Returns
    -------
    filtered : (H, W, C) float64 array
        ``Σ_{s,t} w_s w_t m[clip(y + s), clip(x + t)]``: horizontal pass first,
        then vertical. Always float64, whatever the input dtype: this is the
        reference that float32 implementations (:mod:`moments_ref.gpu.onchip`, GPU
        ports) are measured against.

    Notes
    -----
    HPG17 §4: "two more passes apply a horizontal and vertical Gaussian filter".
    Border rule: clamp-to-edge (module docstring).

    Summation order (it fixes the float64 bits): an exactly symmetric kernel
    (``w[j] = w[taps − 1 − j]``, as the Gaussian is) is summed folded in each pass,
    ``w[r]·m_r + Σ_{j=0}^{r−1} w[j]·(m_j + m_{2r−j})`` with j ascending, the order of
    ``scipy.ndimage.correlate1d`` (which does the horizontal pass); so the result is
    bit for bit ``correlate1d(correlate1d(m, w, axis=1, mode="nearest"), w, axis=0,
    mode="nearest")``. Other kernels are summed term by term, ``t = 0 .. taps − 1``.
    The folded sum rounds fewer times: on random and on filtered depth maps its largest
    distance to the exact 2D sum was 0.65 of the term-by-term sum's (docs/bench.md,
    Kernel history), and the float32 values cast from either were the same.
    """
    m = real_input(moments, "moments")
    if m.ndim != 3 or 0 in m.shape:
        raise InputError(f"moments: expected a non-empty (H, W, C) array, got shape {m.shape}")
    w = gaussian_weights() if weights is None else real_input(weights, "weights").astype(np.float64)
    if w.ndim != 1 or len(w) % 2 == 0:
        raise InputError(f"weights: expected a 1D kernel of odd length, got shape {w.shape}")
    return _banded_blur(m, w)


def _banded_blur(m, w):
    """:func:`blur` a band of output rows at a time: no whole-map intermediate (only the float64 result).

    Each band's horizontal pass covers its rows and ``(taps − 1)/2`` clamped rows
    above and below; every output value is the same sum in the same order as with
    one whole-map horizontal pass (the halo rows are recomputed, not approximated).
    """
    r = (len(w) - 1) // 2
    h, wd, c = m.shape
    out = np.empty((h, wd, c))
    rows = max(4 * r, _BLUR_BAND_BYTES // (8 * wd * c))
    hp = np.empty((min(rows, h) + 2 * r, wd, c))
    tmp = np.empty((min(rows, h), wd, c))
    correlate = _correlate_symmetric if _symmetric(w) else _correlate
    for y in range(0, h, rows):
        k = min(rows, h - y)
        src = np.clip(np.arange(y - r, y + k + r), 0, h - 1)
        band = _horizontal_pass(m[src], w, hp=hp[: k + 2 * r])
        correlate(band, w, out[y : y + k], tmp[:k], axis=0)
    return out


def _horizontal_pass(m, w, hp=None):
    """The horizontal pass of :func:`blur` (float64, clamp-to-edge columns) into ``hp`` (a new array unless given).

    A band of rows at a time: the band goes, cast to float64, into a clamp-to-edge
    padded buffer, and the output into the rows of ``hp``.
    """
    h, wd, c = m.shape
    r = (len(w) - 1) // 2
    if hp is None:
        hp = np.empty((h, wd, c))
    if _symmetric(w):
        # One C loop per row (scipy.ndimage, mode "nearest" = clamp-to-edge): it reads
        # float32 or float64 rows into float64 line buffers and writes float64.
        from scipy import ndimage  # ~0.3 s to import: only once a map is blurred

        ndimage.correlate1d(m, w, axis=1, output=hp[:h], mode="nearest")
        return hp
    rows = max(1, _BAND_BYTES // (8 * (wd + 2 * r) * c))
    band = np.empty((min(rows, h), wd + 2 * r, c))
    tmp = np.empty((min(rows, h), wd, c))
    for y in range(0, h, rows):
        k = min(rows, h - y)
        b = band[:k]
        b[:, r : r + wd] = m[y : y + k]
        b[:, :r] = b[:, r : r + 1]
        b[:, r + wd :] = b[:, r + wd - 1 : r + wd]
        _correlate(b, w, hp[y : y + k], tmp[:k], axis=1)
    return hp


#: Texels per band of :func:`global_path_nlq` (moments_ref._kernels' table, with the reason).
_PATH_BAND_TEXELS = PATH_BAND_TEXELS
#: Bands of :func:`global_path_nlq`'s horizontal-pass rows kept one after the other.
_HP_BANDS = 4


def _quantized(b, fmt, out=None):
    """``pack(phi(bias_moments(b, BIAS_FLOAT32)))`` of a float32 moment band; ``fmt`` "nlq64" or "nlq32"; into ``out`` if given."""
    return nlq_texels(b, fmt, out=out)


def quantize_nlq(moments, fmt="nlq64"):
    """Bias with ``BIAS_FLOAT32``, Φ (HPG17 Algorithm 2) and pack (§3.3 / §3.5) a float32 moment map.

    Parameters
    ----------
    moments : (H, W, 4) float array
        Filtered moments (float32 in the shader).
    fmt : {"nlq64", "nlq32"}

    Returns
    -------
    texture : (H, W, 4) uint16 (nlq64) or (H, W) uint32 (nlq32)
        ``pack64(phi(bias_moments(moments, BIAS_FLOAT32)))`` (or pack32), bit for bit.

    Notes
    -----
    Speed: :func:`moments_ref.packing.nlq_texels`, an L2 chunk at a time, so that
    the biased moments and Φ's output never exist as whole maps (their cost per
    texel does not grow with the map); every step works texel by texel, so the
    chunks change no value.
    """
    m = real_input(moments, "moments")
    if m.ndim != 3 or m.shape[-1] != 4:
        raise InputError(f"moments: expected an (H, W, 4) array, got shape {m.shape}")
    if fmt not in ("nlq64", "nlq32"):
        raise InputError(f"fmt: expected 'nlq64' or 'nlq32', got {fmt!r}")
    return _quantized(m, fmt)


def global_path_nlq(depth_samples, fmt="nlq64"):
    """The global path of HPG17 §4 from MSAA samples to NLQ texels, a band of rows at a time.

    Parameters
    ----------
    depth_samples : (H, W, S) float array
        Sample depths in [-1, 1].
    fmt : {"nlq64", "nlq32"}

    Returns
    -------
    texture : (H, W, 4) uint16 (nlq64) or (H, W) uint32 (nlq32)
        ``pack(phi(bias_moments(blur(resolve_moments(z)).astype(float32), BIAS_FLOAT32)))``
        bit for bit: resolve, the 9² Gaussian in float64 (clamp-to-edge), the cast
        to float32 registers, the float32 bias, Φ (Algorithm 2) and pack64/pack32.

    Notes
    -----
    Speed: each band of output rows resolves and blurs horizontally its rows and
    the 4 rows above and below (clamped at the border, as :func:`blur` pads), blurs
    them vertically and quantizes them, so no whole-map float64 intermediate
    exists and the cost per texel stays flat as the map grows (the 8 guard rows
    of a band are the previous band's last rows, kept). A band's moments stay four
    planes b1..b4 from the resolve to Φ (``nlq_texels(..., planar=True)``). Every
    value is computed by the same operations in the same order as in the separate passes.
    """
    z = check_depth_samples(depth_samples)
    if fmt not in ("nlq64", "nlq32"):
        raise InputError(f"fmt: expected 'nlq64' or 'nlq32', got {fmt!r}")
    from scipy import ndimage  # ~0.3 s to import: only once a map is blurred

    h, wd, _ = z.shape
    w = gaussian_weights()  # exactly symmetric: both passes sum it folded (blur's Notes)
    r = (len(w) - 1) // 2
    out = np.empty((h, wd, 4) if fmt == "nlq64" else (h, wd), np.uint16 if fmt == "nlq64" else np.uint32)
    rows = min(h, max(1, _PATH_BAND_TEXELS // wd))
    # The band's moments as four planes (4, rows, W) from the resolve to Φ: the
    # resolve stores contiguous rows, the horizontal pass reads contiguous lines and
    # the quantization reads its chunks without a transposition.
    res = np.empty(4 * (rows + 2 * r) * wd, z.dtype)
    # The horizontal pass's rows: _HP_BANDS bands one after the other, so that a band's
    # 2r guard rows (the previous band's last rows) are moved up once every _HP_BANDS bands.
    hp = np.empty((4, _HP_BANDS * rows + 2 * r, wd))
    top = 0  # hp's row of map row y − r
    acc, tmp = np.empty((4, rows, wd)), np.empty((4, rows, wd))
    f32 = np.empty(4 * rows * wd, np.float32)
    done = 0  # rows of hp that hold the horizontal pass of this band's first rows
    for y in range(0, h, rows):
        k = min(rows, h - y)
        # Horizontal pass of map rows y − r .. y + k + r − 1 (clamped); the first 2r of
        # them are the previous band's last 2r rows, moved up instead of recomputed.
        lo, hi = y - r + done, y + k + r
        # A view of the rows where none is clamped (no copy of the samples), else gathered.
        band = z[lo:hi] if lo >= 0 and hi <= h else z[np.clip(np.arange(lo, hi), 0, h - 1)]
        planes = res[: 4 * (hi - lo) * wd].reshape(4, hi - lo, wd)
        _resolve_planes(band, planes.reshape(4, -1))
        if top + k + 2 * r > hp.shape[1]:
            hp[:, : 2 * r] = hp[:, top : top + 2 * r]  # NumPy buffers the copy where they overlap
            top = 0
        ndimage.correlate1d(planes, w, axis=2, output=hp[:, top + done : top + k + 2 * r], mode="nearest")
        b32 = f32[: 4 * k * wd].reshape(4, k, wd)
        _correlate_symmetric(hp[:, top : top + k + 2 * r], w, acc[:, :k], tmp[:, :k], axis=1, final=b32)
        nlq_texels(b32, fmt, out=out[y : y + k], planar=True)
        top, done = top + k, 2 * r
    return out


def bench_depth_map(size=2048, samples=4, dtype=np.float32, seed=0):
    """A deterministic (size, size, samples) depth map for benchmarks: smooth terrain plus steps."""
    rng = np.random.default_rng(seed)
    u = (np.arange(size) + 0.5) / size
    base = 0.5 * np.sin(7 * u)[:, None] * np.cos(5 * u)[None, :]
    steps = np.where((np.add.outer(np.arange(size) // 64, np.arange(size) // 64) % 2) == 0, 0.3, -0.3)
    jitter = rng.uniform(-0.01, 0.01, size=(size, size, samples))
    return np.clip(base[..., None] + steps[..., None] + jitter, -1, 1).astype(dtype)
