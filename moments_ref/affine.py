"""Affine quantization of moments: the optimized basis, UNORM16 and the 6-moment basis.

Storing ``z, z², z³, z⁴`` directly in four 16-bit channels wastes most of the
representable range and gives too much rounding error. Moment shadow mapping
therefore stores the moments in an *optimized basis* of quartic polynomials whose
values for every depth ``z ∈ [-1, 1]`` fill [0, 1] well (Slides, "Quantization"):

    R = 1.5 z − 2 z³ + 0.5
    G = 4 z² − 4 z⁴
    B = (√3/2) z − (2√3/9) z³ + 0.5
    A = 0.5 z² + 0.5 z⁴

By linearity the filtered texel holds the same affine map applied to the moments
``b = (b1, b2, b3, b4)`` (Slides, "Compute moments in resolve"); shading undoes it
with the inverse matrix (Slides, "Retrieve moments"). Each polynomial maps
[-1, 1] into [0, 1], so by convexity the moments of *every* depth distribution on
[-1, 1] map into [0, 1]⁴.

Texel formats
-------------
* 64 bits per texel: the optimized basis in R16G16B16A16_UNORM,
  :func:`encode_unorm16` / :func:`decode_unorm16`.
* 128 bits per texel: the plain moments b1..b4 in R32G32B32A32_FLOAT. No transform
  is needed; ``b.astype(np.float32)`` is the texel and the float32 dtype policy of
  the other modules emulates the shader reading it.
* Six moments (prefiltered single scattering): two R10G10B10A2_UNORM texels,
  64 bits with 4 bits unused (Slides, "6 moments: ... Quantization transform"),
  :func:`to_optimized6`, :func:`encode_r10g10b10a2`.

The pipeline of a caller is ``b → encode → (hardware filtering) → decode →
bias_moments(b, BIAS_UNORM16) → shadow_intensity``. Biasing (HPG17 §3.2, Slides
"Bias the moments") is *not* part of encode or decode: it is the caller's step,
done after decoding and after any filtering, because it must act on the rounded
moments that reach the shader.

Rounding rule
-------------
Float → UNORM conversion follows the Direct3D data conversion rules ("FLOAT ->
UNORM Integer Conversion"): clamp to [0, 1], multiply by ``2ⁿ − 1``, add 0.5 and
drop the fraction, i.e. **round to nearest, ties up** (to the larger code).
Vulkan ("Fixed-Point Data Conversions") lets the implementation pick either of
the two nearest codes and recommends rounding to nearest, so this rule is one
Vulkan permits. The reference evaluates the rule in exact arithmetic (see
:func:`float_to_unorm`); the only exact tie in [0, 1] is 0.5 → 2ⁿ⁻¹, where
round-half-even (``np.rint``) happens to agree. UNORM → float is ``u / (2ⁿ − 1)``
correctly rounded in the requested dtype. NaN (which Direct3D maps to 0) is
refused as bad input here.

Values outside [0, 1] after the transform (moments outside the moment space, or
depths outside [-1, 1]) are clamped by the encoder, as the hardware does when it
writes a UNORM render target; they are not an error.

The 6-moment matrices
---------------------
The slide prints two 3×3 matrices with a transpose mark that the text extraction
lost. Read with the rows as printed,

    (R0, G0, B0) = M0ᵀ · (z, z³, z⁵) + (0.5, 0.5, 0.5),
    M0 = [[2.5, −1.87499864, 1.26583039], [−10, 4.20757543, −1.47644883],
          [8, −1.83257679, 0.71061660]],
    (R1, G1, B1) = M1ᵀ · (z², z⁴, z⁶) + (0, 0, 0.018888946),
    M1 = [[4, 9, −0.57759806], [−4, −24, 4.61936648], [0, 16, −3.07953907]],

is the orientation under which every ``z ∈ [-1, 1]`` maps into [0, 1]³ for both
triples (up to the 8 printed decimals, |error| < 2e-8); without the transpose R0(1)
would be 2.39. With it, R0 = (T5(z) + 1)/2, G1 = (T6(z) + 1)/2 and
R1 = (1 − T4(z))/2 are Chebyshev polynomials, a further sign the reading is right.

References
----------
.. [1] Slides: Christoph Peters. *Rendering antialiased shadows with moment shadow mapping*,
       lecture slides (PDF version, with notes) on moment shadow mapping, translucent occluders,
       moment soft shadow mapping and prefiltered single scattering; http://MomentsInGraphics.de/.
       Cited by slide title, e.g. Slides, "Bias the moments".
.. [2] HPG17: Christoph Peters. 2017. *Non-Linearly Quantized Moment Shadow Maps*. In Proceedings
       of High Performance Graphics (HPG '17). ACM. The non-linear quantization Φ, Ψ4, Algorithms
       1–3, the texel formats and the compute shader of §4.1.
.. [3] Direct3D programming guide, "Data Conversion Rules" (FLOAT -> UNORM, UNORM -> FLOAT;
       tolerance D3D11_FLOAT32_TO_INTEGER_TOLERANCE_IN_ULP = 0.6).
.. [4] Vulkan specification, "Fixed-Point Data Conversions".
.. [5] DXGI_FORMAT_R10G10B10A2_UNORM (R in the least significant bits).
"""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np

from ._arrays import InputError, first_index, real_input
from ._docs import fill_doc
from ._kernels import CHUNK

__all__ = [
    "OPTIMIZED_MATRIX",
    "OPTIMIZED_OFFSET",
    "OPTIMIZED_INVERSE",
    "SIX_MOMENT_M0",
    "SIX_MOMENT_M1",
    "SIX_MOMENT_OFFSET0",
    "SIX_MOMENT_OFFSET1",
    "to_optimized",
    "from_optimized",
    "float_to_unorm",
    "unorm_to_float",
    "encode_unorm16",
    "decode_unorm16",
    "to_optimized6",
    "from_optimized6",
    "encode_r10g10b10a2",
    "decode_r10g10b10a2",
]

_SQRT3 = math.sqrt(3.0)


def _frozen(a) -> np.ndarray:
    a = np.array(a, dtype=np.float64)
    a.setflags(write=False)
    return a


#: Optimized basis (Slides, "Compute moments in resolve"): ``q = M·b + c``.
OPTIMIZED_MATRIX = _frozen(
    [
        [1.5, 0.0, -2.0, 0.0],
        [0.0, 4.0, 0.0, -4.0],
        [_SQRT3 / 2.0, 0.0, -2.0 * _SQRT3 / 9.0, 0.0],
        [0.0, 0.5, 0.0, 0.5],
    ]
)
#: The offset ``c`` of the optimized basis.
OPTIMIZED_OFFSET = _frozen([0.5, 0.0, 0.5, 0.0])
#: Exact inverse (Slides, "Retrieve moments"): ``b = M⁻¹·(q − c)``. Derived by hand
#: from the 2×2 blocks (b1, b3 | R, B) and (b2, b4 | G, A); checked with sympy in
#: the tests.
OPTIMIZED_INVERSE = _frozen(
    [
        [-1.0 / 3.0, 0.0, _SQRT3, 0.0],
        [0.0, 0.125, 0.0, 1.0],
        [-0.75, 0.0, 0.75 * _SQRT3, 0.0],
        [0.0, -0.125, 0.0, 1.0],
    ]
)

# The 6-moment constants exactly as printed on the slide (decimal strings, so the
# exact inverse below is the inverse of the printed matrix, not of its float).
_M0_TEXT = (
    ("2.5", "-1.87499864", "1.26583039"),
    ("-10", "4.20757543", "-1.47644883"),
    ("8", "-1.83257679", "0.71061660"),
)
_M1_TEXT = (
    ("4", "9", "-0.57759806"),
    ("-4", "-24", "4.61936648"),
    ("0", "16", "-3.07953907"),
)
#: Slides, 6-moment "Quantization transform", rows as printed; applied transposed.
SIX_MOMENT_M0 = _frozen([[float(Fraction(v)) for v in row] for row in _M0_TEXT])
#: Slides, 6-moment "Quantization transform", rows as printed; applied transposed.
SIX_MOMENT_M1 = _frozen([[float(Fraction(v)) for v in row] for row in _M1_TEXT])
#: Offset of (R0, G0, B0).
SIX_MOMENT_OFFSET0 = _frozen([0.5, 0.5, 0.5])
#: Offset of (R1, G1, B1).
SIX_MOMENT_OFFSET1 = _frozen([0.0, 0.0, 0.018888946])


def _exact_inverse3(rows) -> list[list[Fraction]]:
    """Inverse of a 3×3 matrix of Fractions by the adjugate (exact)."""
    m = [[Fraction(v) for v in row] for row in rows]

    def cof(i, j):
        r = [k for k in range(3) if k != i]
        c = [k for k in range(3) if k != j]
        minor = m[r[0]][c[0]] * m[r[1]][c[1]] - m[r[0]][c[1]] * m[r[1]][c[0]]
        return minor if (i + j) % 2 == 0 else -minor

    det = sum(m[0][j] * cof(0, j) for j in range(3))
    return [[cof(j, i) / det for j in range(3)] for i in range(3)]


def _transpose(rows):
    return [list(col) for col in zip(*rows)]


# Forward maps are q = Mᵀ·x + c, so the inverses are x = (Mᵀ)⁻¹·(q − c), computed
# exactly from the printed decimals and rounded once to float64.
_M0T_INV = _frozen([[float(v) for v in row] for row in _exact_inverse3(_transpose(_M0_TEXT))])
_M1T_INV = _frozen([[float(v) for v in row] for row in _exact_inverse3(_transpose(_M1_TEXT))])


def _affine(x, matrix, offset, dtype):
    """``matrix·x + offset`` over the trailing axis as explicit sums in ``dtype``.

    Written as elementwise multiply-adds in a fixed order rather than ``matmul``
    so that float32 results do not depend on the BLAS build (golden outputs must
    be reproducible); exact zero coefficients are skipped.
    """
    m = np.asarray(matrix, dtype=dtype)
    c = np.asarray(offset, dtype=dtype)
    out = np.empty(x.shape[:-1] + (m.shape[0],), dtype=dtype)
    for i in range(m.shape[0]):
        acc = None
        for j in range(m.shape[1]):
            if m[i, j] == 0:
                continue
            term = m[i, j] * x[..., j]
            acc = term if acc is None else acc + term
        out[..., i] = c[i] if acc is None else acc + c[i]
    return out


def _float_arg(q, name, size, inverse_of):
    """Validate a float argument that must not be raw integer codes."""
    try:
        kind = np.asarray(q).dtype.kind
    except Exception:
        kind = None  # let real_input report the unconvertible object
    if kind == "u":
        arr = np.asarray(q)
        raise InputError(
            f"{name}: expected normalized floats in [0, 1], got unsigned integer codes "
            f"(array of shape {arr.shape} and dtype {arr.dtype}); decode them with {inverse_of}"
        )
    return real_input(q, name, trailing=size)


def _check_dtype(dtype) -> np.dtype:
    try:
        dt = np.dtype(dtype)
    except TypeError:
        raise InputError(f"dtype: expected float32 or float64, got {dtype!r}") from None
    if dt not in (np.dtype(np.float32), np.dtype(np.float64)):
        raise InputError(f"dtype: expected float32 or float64, got {dt}")
    return dt


def _code_input(u, name, dtype, size):
    try:
        arr = np.asarray(u)
    except Exception as exc:
        raise InputError(
            f"{name}: expected a {np.dtype(dtype)} array, got {type(u).__name__} ({exc})"
        ) from None
    if arr.dtype != np.dtype(dtype):
        raise InputError(
            f"{name}: expected an array of dtype {np.dtype(dtype)}, got array of shape "
            f"{arr.shape} and dtype {arr.dtype}"
        )
    if arr.ndim == 0 or arr.shape[-1] != size:
        raise InputError(
            f"{name}: expected a trailing axis of length {size}, got array of shape "
            f"{arr.shape} and dtype {arr.dtype}"
        )
    return arr


# ---------------------------------------------------------------------------
# Four moments, 64 bits per texel
# ---------------------------------------------------------------------------


@fill_doc
def to_optimized(b):
    """Map moments b1..b4 to the optimized basis (R, G, B, A).

    Parameters
    ----------
    %(b)s

    Returns
    -------
    q : (..., 4) float array
        ``R = 1.5 b1 − 2 b3 + 0.5``, ``G = 4 b2 − 4 b4``,
        ``B = (√3/2) b1 − (2√3/9) b3 + 0.5``, ``A = 0.5 b2 + 0.5 b4``.
        dtype per the policy (float32 in, float32 out).

    Notes
    -----
    Slides, "Compute moments in resolve": ``q = M·(z, z², z³, z⁴) + c`` per
    depth; averaging commutes with the affine map, so applying it to the mean
    moments gives the filtered texel. For moments of a distribution on [-1, 1]
    every channel lies in [0, 1] (up to rounding). No clamping here; see
    :func:`encode_unorm16`.

    Examples
    --------
    >>> to_optimized([0.0, 0.25, 0.0, 0.0625])
    array([0.5    , 0.75   , 0.5    , 0.15625])
    """
    b = real_input(b, "b", trailing=4)
    t = b.dtype.type
    b1, b2, b3, b4 = b[..., 0], b[..., 1], b[..., 2], b[..., 3]
    q = np.empty_like(b)
    q[..., 0] = t(1.5) * b1 - t(2.0) * b3 + t(0.5)
    q[..., 1] = t(4.0) * b2 - t(4.0) * b4
    q[..., 2] = t(OPTIMIZED_MATRIX[2, 0]) * b1 + t(OPTIMIZED_MATRIX[2, 2]) * b3 + t(0.5)
    q[..., 3] = t(0.5) * b2 + t(0.5) * b4
    return q


def from_optimized(q):
    """Undo the quantization transform: optimized basis (R, G, B, A) -> b1..b4.

    Parameters
    ----------
    q : (..., 4) float array
        Values in the optimized basis, e.g. a filtered texel in [0, 1].
        Unsigned integer codes are refused (use :func:`decode_unorm16`).

    Returns
    -------
    b : (..., 4) float array
        ``b1 = −R'/3 + √3 B'``, ``b2 = G/8 + A``, ``b3 = −0.75 R' + 0.75√3 B'``,
        ``b4 = −G/8 + A`` with ``R' = R − 0.5``, ``B' = B − 0.5``.

    Notes
    -----
    Slides, "Retrieve moments". The exact inverse of :func:`to_optimized`; no
    biasing (call :func:`moments_ref.moments.bias_moments` afterwards).

    Examples
    --------
    >>> from_optimized([0.5, 0.75, 0.5, 0.15625])
    array([0.    , 0.25  , 0.    , 0.0625])
    """
    q = _float_arg(q, "q", 4, "decode_unorm16")
    t = q.dtype.type
    r = q[..., 0] - t(0.5)
    g = q[..., 1]
    bb = q[..., 2] - t(0.5)
    a = q[..., 3]
    b = np.empty_like(q)
    b[..., 0] = t(OPTIMIZED_INVERSE[0, 0]) * r + t(_SQRT3) * bb
    b[..., 1] = t(0.125) * g + a
    b[..., 2] = t(-0.75) * r + t(OPTIMIZED_INVERSE[2, 2]) * bb
    b[..., 3] = t(-0.125) * g + a
    return b


def float_to_unorm(x, bits=16):
    """Convert floats to ``bits``-bit UNORM codes: clamp, scale, round half up.

    Parameters
    ----------
    x : array_like, float
        Values; those outside [0, 1] are clamped (not an error).
    bits : int
        Bits per channel, 1..16.

    Returns
    -------
    u : uint16 array, shape of ``x``
        The code nearest to the real number ``c·(2ⁿ − 1)``, ``c = clamp(x, 0, 1)``;
        ties go up (``floor(c·(2ⁿ − 1) + 0.5)`` in exact arithmetic).

    Notes
    -----
    Direct3D data conversion rules, "FLOAT -> UNORM Integer Conversion": clamp,
    scale by ``2ⁿ − 1``, add 0.5, drop the fraction. This reference evaluates the
    rule exactly for float32 and float64 ``x`` (no rounding of the product), so it
    is the ideal conversion of the value a shader writes. Because ``2ⁿ − 1`` is
    odd, the only float in [0, 1] whose product is exactly halfway is 0.5
    (0.5 → 2ⁿ⁻¹, e.g. 32768); it occurs in practice for R and B of every
    symmetric depth distribution (b1 = b3 = 0). Hardware computes the product in
    float32 and Direct3D allows 0.6 ULP of error, so a GPU may differ by one code
    when the product is within about 0.1 of a half-integer.

    Examples
    --------
    >>> float_to_unorm([0.5, 1.5, -0.1, 1 / 3], bits=2)
    array([2, 3, 0, 1], dtype=uint16)
    >>> float_to_unorm([0.5])
    array([32768], dtype=uint16)
    """
    if isinstance(bits, bool) or not isinstance(bits, (int, np.integer)) or not 1 <= bits <= 16:
        raise InputError(f"bits: expected an integer in 1..16, got {bits!r}")
    x = real_input(x, "x")
    if x.dtype.kind == "f" and x.dtype.itemsize <= 4:
        return _unorm_from_float32(x, bits)
    c = np.clip(x.astype(np.float64), 0.0, 1.0)  # float32 -> float64 is exact
    # c·(2ⁿ − 1) = c·2ⁿ − c: the first product is exact, the difference is split
    # by TwoSum into s + err exactly (|err| ≤ ulp(s)/2).
    y = c * float(2**bits)
    s = y - c
    bv = s - y
    err = (y - (s - bv)) + (-c - bv)
    whole = np.floor(s)
    # Round half up: compare frac(s) + err with 0.5. s − whole is exact and so is
    # (s − whole) − 0.5 where it matters (Sterbenz); the sign of a float sum is
    # always that of the exact sum. (floor(s + 0.5) would misround near-ties.)
    code = whole + (((s - whole) - 0.5) + err >= 0.0)
    return code.astype(np.uint16)


def _unorm_from_float32(x, bits):
    """:func:`float_to_unorm` of a float32 (or float16) array, a cache-sized chunk at a time.

    Here the rule's product is exact: for ``c = m·2^e`` (``m < 2^24``) in [0, 1],
    ``s = c·(2ⁿ − 1)`` has at most 24 + 16 significant bits, so float64 holds it, and
    ``floor(s + 0.5)`` is the rule's code: ``s + 0.5`` is exact unless ``e < −37``; it
    can only round across an integer ``k`` if ``s`` is within 2⁻⁵¹ of ``k − ½`` (its
    rounding error in [0.5, 4.5)), which needs ``c`` above 2⁻¹⁷, hence ``e ≥ −41``, and
    ``s − (k − ½)``, a multiple of ``2^e``, is then 0 (an exact tie, rounded up as the
    rule says) or at least 2⁻⁴¹. (A float64 ``c`` has no such margin: its product is
    rounded, hence the TwoSum path of :func:`float_to_unorm`.)
    """
    flat = x.reshape(-1)
    out = np.empty(flat.shape, np.uint16)
    buf = np.empty(min(CHUNK, flat.size), np.float64)
    top = float(2**bits - 1)
    for i in range(0, flat.size, CHUNK):
        b = buf[: min(CHUNK, flat.size - i)]
        b[...] = flat[i : i + b.size]  # exact
        np.clip(b, 0.0, 1.0, out=b)
        b *= top
        b += 0.5
        np.floor(b, out=b)
        out[i : i + b.size] = b
    return out.reshape(x.shape)


def unorm_to_float(u, bits=16, dtype=np.float64):
    """Convert ``bits``-bit UNORM codes to floats ``u / (2ⁿ − 1)`` in ``dtype``.

    Parameters
    ----------
    u : array_like, unsigned integer
        Codes in ``0 .. 2ⁿ − 1``.
    bits : int
        Bits per channel, 1..16.
    dtype : {numpy.float64, numpy.float32}
        Output dtype; float32 emulates a GPU texture fetch.

    Returns
    -------
    x : float array, shape of ``u``

    Notes
    -----
    Direct3D data conversion rules, "UNORM -> FLOAT": ``c / (2ⁿ − 1)``, here
    correctly rounded in ``dtype``.

    Examples
    --------
    >>> unorm_to_float(np.array([0, 1, 3], dtype=np.uint16), bits=2)
    array([0.        , 0.33333333, 1.        ])
    """
    if isinstance(bits, bool) or not isinstance(bits, (int, np.integer)) or not 1 <= bits <= 16:
        raise InputError(f"bits: expected an integer in 1..16, got {bits!r}")
    dt = _check_dtype(dtype)
    arr = np.asarray(u)
    if arr.dtype.kind != "u":
        raise InputError(
            f"u: expected unsigned integer codes, got array of shape {arr.shape} and dtype {arr.dtype}"
        )
    top = 2**bits - 1
    if arr.size and arr.max() > top:
        idx = first_index(arr > top)
        raise InputError(f"u: expected codes in 0..{top}, got {arr[idx]!r} at index {idx}")
    return arr.astype(dt) / dt.type(top)


@fill_doc
def encode_unorm16(b):
    """Quantize moments to a 64-bit R16G16B16A16_UNORM texel.

    Parameters
    ----------
    %(b)s
        Biasing is not applied here.

    Returns
    -------
    u : (..., 4) uint16 array
        ``round_half_up(clamp(to_optimized(b), 0, 1) · 65535)``.

    Notes
    -----
    Slides, "Compute moments in resolve". The transform runs in the dtype of
    ``b`` (float32 emulates a shader writing the render target); the conversion
    to UNORM follows Direct3D's rule (ties round up, see the module docstring).
    Values outside [0, 1] (moments outside the moment space) are clamped.

    Examples
    --------
    >>> encode_unorm16([0.0, 0.25, 0.0, 0.0625])
    array([32768, 49151, 32768, 10240], dtype=uint16)
    """
    return float_to_unorm(to_optimized(b), 16)


def decode_unorm16(u, dtype=np.float64):
    """Recover moments b1..b4 from a 64-bit R16G16B16A16_UNORM texel.

    Parameters
    ----------
    u : (..., 4) uint16 array
        Codes as written by :func:`encode_unorm16`. Other dtypes are refused.
    dtype : {numpy.float64, numpy.float32}
        Working and output dtype; float32 emulates a GPU decode.

    Returns
    -------
    b : (..., 4) float array
        ``from_optimized(u / 65535)``, unbiased: apply
        ``bias_moments(b, BIAS_UNORM16)`` before computing shadows.

    Notes
    -----
    Slides, "Retrieve moments". A filtered texture holds non-code values; decode
    them with :func:`from_optimized` directly.

    Examples
    --------
    >>> u = np.array([32768, 49151, 32768, 10240], dtype=np.uint16)
    >>> decode_unorm16(u).round(4)
    array([0.    , 0.25  , 0.    , 0.0625])
    """
    dt = _check_dtype(dtype)
    u = _code_input(u, "u", np.uint16, 4)
    return from_optimized(u.astype(dt) / dt.type(65535))


# ---------------------------------------------------------------------------
# Six moments, 2 × R10G10B10A2_UNORM
# ---------------------------------------------------------------------------


def to_optimized6(b):
    """Map moments b1..b6 to the 6-moment basis (R0, G0, B0, R1, G1, B1).

    Parameters
    ----------
    b : (..., 6) float array
        Moments b1..b6.

    Returns
    -------
    q : (..., 6) float array
        ``(R0, G0, B0) = M0ᵀ·(b1, b3, b5) + (0.5, 0.5, 0.5)`` and
        ``(R1, G1, B1) = M1ᵀ·(b2, b4, b6) + (0, 0, 0.018888946)``.

    Notes
    -----
    Slides, "6 moments: 2×R10G10B10A2 ... Quantization transform". The
    orientation (transpose) is the one under which every depth in [-1, 1] maps
    into [0, 1]⁶; see the module docstring.

    Examples
    --------
    >>> to_optimized6([1.0, 1.0, 1.0, 1.0, 1.0, 1.0]).round(6)
    array([1.      , 1.      , 0.999998, 0.      , 1.      , 0.981118])
    """
    b = real_input(b, "b", trailing=6)
    dt = b.dtype
    q = np.empty_like(b)
    q[..., 0:3] = _affine(b[..., 0::2], SIX_MOMENT_M0.T, SIX_MOMENT_OFFSET0, dt)
    q[..., 3:6] = _affine(b[..., 1::2], SIX_MOMENT_M1.T, SIX_MOMENT_OFFSET1, dt)
    return q


def from_optimized6(q):
    """Inverse of :func:`to_optimized6`: (R0, G0, B0, R1, G1, B1) -> b1..b6.

    Parameters
    ----------
    q : (..., 6) float array
        Values in the 6-moment basis. Unsigned integer codes are refused (use
        :func:`decode_r10g10b10a2`).

    Returns
    -------
    b : (..., 6) float array
        Moments b1..b6.

    Notes
    -----
    The inverse matrices are computed exactly (rational arithmetic) from the
    printed decimals and rounded once to float64.

    Examples
    --------
    >>> from_optimized6(to_optimized6([0.5, 0.25, 0.125, 0.0625, 0.03125, 0.015625])).round(12)
    array([0.5     , 0.25    , 0.125   , 0.0625  , 0.03125 , 0.015625])
    """
    q = _float_arg(q, "q", 6, "decode_r10g10b10a2")
    dt = q.dtype
    b = np.empty_like(q)
    b[..., 0::2] = _affine(q[..., 0:3] - SIX_MOMENT_OFFSET0.astype(dt), _M0T_INV, (0, 0, 0), dt)
    b[..., 1::2] = _affine(q[..., 3:6] - SIX_MOMENT_OFFSET1.astype(dt), _M1T_INV, (0, 0, 0), dt)
    return b


def encode_r10g10b10a2(b):
    """Quantize six moments to two R10G10B10A2_UNORM texels (64 bits).

    Parameters
    ----------
    b : (..., 6) float array
        Moments b1..b6.

    Returns
    -------
    p : (..., 2) uint32 array
        ``p[..., 0]`` packs (R0, G0, B0), ``p[..., 1]`` packs (R1, G1, B1). Bit
        layout as DXGI_FORMAT_R10G10B10A2_UNORM read as a little-endian 32-bit
        word: R in bits 0–9, G in 10–19, B in 20–29, A = 0 in bits 30–31.

    Notes
    -----
    Slides, "6 moments: 2×R10G10B10A2 normalized uint". 10-bit codes use the
    same rule as :func:`float_to_unorm` (clamp, ×1023, ties round up).

    Examples
    --------
    >>> p = encode_r10g10b10a2([0.0, 0.0, 0.0, 0.0, 0.0, 0.0])
    >>> p
    array([537395712,  19922944], dtype=uint32)
    >>> [[int(w >> s) & 0x3FF for s in (0, 10, 20, 30)] for w in p]  # R, G, B, A codes
    [[512, 512, 512, 0], [0, 0, 19, 0]]
    """
    codes = float_to_unorm(to_optimized6(b), 10).astype(np.uint32)
    shifts = np.array([0, 10, 20], dtype=np.uint32)
    texel0 = np.bitwise_or.reduce(codes[..., 0:3] << shifts, axis=-1)
    texel1 = np.bitwise_or.reduce(codes[..., 3:6] << shifts, axis=-1)
    return np.stack([texel0, texel1], axis=-1)


def decode_r10g10b10a2(p, dtype=np.float64):
    """Recover moments b1..b6 from two R10G10B10A2_UNORM texels.

    Parameters
    ----------
    p : (..., 2) uint32 array
        Packed texels as written by :func:`encode_r10g10b10a2`. The alpha bits
        (30–31) are ignored, as a shader reading ``.rgb`` does.
    dtype : {numpy.float64, numpy.float32}
        Working and output dtype; float32 emulates a GPU decode.

    Returns
    -------
    b : (..., 6) float array
        ``from_optimized6(codes / 1023)``.

    Examples
    --------
    >>> from moments_ref import power_moments
    >>> b = power_moments([0.5, -0.5], n=6)
    >>> b
    array([0.      , 0.25    , 0.      , 0.0625  , 0.      , 0.015625])
    >>> decode_r10g10b10a2(encode_r10g10b10a2(b)).round(2)
    array([0.  , 0.25, 0.  , 0.06, 0.  , 0.02])
    """
    dt = _check_dtype(dtype)
    p = _code_input(p, "p", np.uint32, 2)
    shifts = np.array([0, 10, 20], dtype=np.uint32)
    codes = (p[..., :, None] >> shifts) & np.uint32(0x3FF)  # (..., 2, 3)
    q = codes.reshape(p.shape[:-1] + (6,)).astype(dt) / dt.type(1023)
    return from_optimized6(q)
