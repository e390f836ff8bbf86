"""Bilinear sampling of moment textures: goldens whose tolerance declares the hardware's filter weights.

A shadow function that samples its moment texture (``texture(m, uv)``, ``m.Sample(s, uv)``,
``textureSampleLevel(m, s, uv, 0.0)``) between texel centres gets the bilinear blend of a
2×2 neighbourhood. Moments are linear in the distribution, so the blend is the moments of
the blended distribution (HPG17 §1: filtering moment maps is what makes them prefilterable);
the two cases here check it:

* ``sample_bilinear-float32``: ``texels`` (n, 16), ``fraction`` (n, 2) -> ``b`` (n, 4),
  the filtered moments;
* ``shadow_intensity_bilinear-float32``: ``texels``, ``fraction``, ``zf`` -> ``intensity``:
  the filtered moments biased with ``BIAS_FLOAT32`` (HPG17 §3.2, inside the function, as an
  engine that stores unbiased moments does) and HPG17 Algorithm 1's lower bound.

Row layout: texel (i, j) of a row's neighbourhood (i right, j down) is ``texels[4 (2 j + i)
: 4 (2 j + i) + 4]``; the fraction (fx, fy) is the sample's position between the four
texel centres: B = (1 − fx)(1 − fy) t00 + fx (1 − fy) t10 + (1 − fx) fy t01 + fx fy t11.
Fractions are multiples of 2⁻¹⁶, so a coordinate between the centres of a 256-texel-wide
texture is exact in float32 (:mod:`moments_ref.conformance`).

Expected values: the blend of the float32 texels in exact rational arithmetic, rounded once
(then, for the intensity, the mpmath twins :func:`moments_ref.precise.bias_moments` and
:func:`moments_ref.precise.shadow_intensity`). Tolerances (:func:`weight_interval`):

* hardware weights: GPUs filter with the position snapped to ``q`` bits of sub-texel
  precision (D3D11: at least 8, snapped within 0.6 ulp of the q-bit grid, reference round
  to nearest even; Vulkan: ``subTexelPrecisionBits``, at least 4, no rounding rule stated),
  so a weight is any multiple of 2⁻q within one step of the fraction: ⌊2^q f⌋/2^q or
  ⌈2^q f⌉/2^q (floor, nearest and any directed rounding land on one of the two), or the
  fraction itself (llvmpipe and lavapipe: docs/ports.md). ``q`` is declared in
  the engine profile (``[format] subtexel_bits``, default :data:`SUBTEXEL_BITS`). The blend
  is bilinear in (wx, wy), so over the rectangle of allowed weights its extremes lie at the
  four corners: the moments' spread is the largest distance of a corner's blend from the
  exact one, for any filter with q or more bits. The intensity is not monotone in the
  weights; it is evaluated on the weights of :data:`FINER_BITS` more bits across the
  rectangle (the corners, hence every q-bit filter, among them) and the exact fraction, and
  the spread is the largest distance from the expected value (for a q-bit filter the set
  of legitimate outputs is finite, and this is its exact hull);
* float32 filtering: a filter's lerps round at most :data:`FILTER_ULPS` times in ulps of the
  largest texel component (two levels of a − w a + w b); for the intensity, 16 times the
  deviation of float32 Algorithm 1 (this package, the slides' and the printed code) on the
  corners' blends, rounded and moved by that filter rounding, as every golden tolerance.

References
----------
.. [1] HPG17: Christoph Peters. 2017. *Non-Linearly Quantized Moment Shadow Maps*. In Proceedings
       of High Performance Graphics (HPG '17). ACM. The non-linear quantization Φ, Ψ4, Algorithms
       1–3, the texel formats and the compute shader of §4.1.
.. [2] Direct3D 11.3 functional specification, §3.2.4 (Fixed Point Integers: texture coordinates
       snapped to fixed point; §3.2.4.1, float to fixed within 0.6 ulp) and §7.18.16.1 (Texture
       Addressing and LOD Precision: at least 8 bits of sub-texel precision).
.. [3] Vulkan specification, "Unnormalized Texel Coordinate Operations" (α = frac(u − 0.5), "where
       the number of fraction bits retained is specified by" ``subTexelPrecisionBits``).
"""

from __future__ import annotations

from fractions import Fraction

import numpy as np

from .. import precise
from ..moments import BIAS_FLOAT32, bias_moments, power_moments
from ..msm import shadow_intensity
from ._rows import Rows, _random_distributions
from .paper import printed_bound, slides_bound
from .units import PORT_DTYPES, ceil2, ulp

__all__ = ["SUBTEXEL_BITS", "SUBTEXEL_RANGE", "FINER_BITS", "FILTER_ULPS", "FRACTION_BITS", "blend", "blend_exact",
           "quantized", "weight_interval", "case_specs", "derive_bilinear"]

#: Default sub-texel precision (Direct3D 11 requires at least 8 bits; Vulkan's minimum is 4).
SUBTEXEL_BITS = 8
#: Sub-texel precisions a profile may declare (``[format] subtexel_bits``).
SUBTEXEL_RANGE = tuple(range(4, 17))
#: The intensity's hull also covers filters with up to this many more bits than declared.
FINER_BITS = 4
#: Rounding of a float32 filter: ulps of the largest texel component.
FILTER_ULPS = 8
#: Fractions are multiples of 2^-FRACTION_BITS (exact texture coordinates, docs/ports.md).
FRACTION_BITS = 16
_SAFETY = 16.0
_WIDE = 0.1


def _split(texels):
    """``(t00, t10, t01, t11)``, each ``(n, 4)``, of ``(n, 16)`` rows."""
    t = np.asarray(texels).reshape(len(texels), 4, 4)
    return t[:, 0], t[:, 1], t[:, 2], t[:, 3]


def blend(texels, wx, wy, dtype=np.float32):
    """The bilinear blend with weights ``wx``, ``wy`` ((n,) each) in ``dtype``: two levels of lerps,
    ``lerp(a, b, w) = a (1 − w) + b w`` (a texture unit's order: along x, then y)."""
    dt = np.dtype(dtype).type
    t00, t10, t01, t11 = (x.astype(dt) for x in _split(texels))
    wx, wy = np.asarray(wx).astype(dt)[:, None], np.asarray(wy).astype(dt)[:, None]
    one = dt(1)
    top = t00 * (one - wx) + t10 * wx
    bottom = t01 * (one - wx) + t11 * wx
    return top * (one - wy) + bottom * wy


def blend_exact(texels, fraction):
    """The bilinear blend of float texels in exact rational arithmetic, rounded once to float64: ``(n, 4)``."""
    t = np.asarray(texels, np.float64).reshape(len(texels), 4, 4)
    f = np.asarray(fraction, np.float64)
    out = np.empty((len(t), 4))
    for r in range(len(t)):  # rational arithmetic: one row at a time
        fx, fy = Fraction(f[r, 0]), Fraction(f[r, 1])
        w = ((1 - fx) * (1 - fy), fx * (1 - fy), (1 - fx) * fy, fx * fy)
        for c in range(4):
            out[r, c] = float(sum(wk * Fraction(t[r, k, c]) for k, wk in enumerate(w)))
    return out


def quantized(f, bits):
    """``(lower, upper)``: the multiples of 2⁻``bits`` within one step of ``f`` (floor and ceiling)."""
    s = float(2 ** bits)
    f = np.asarray(f, np.float64)
    return np.floor(f * s) / s, np.ceil(f * s) / s


def weight_interval(fraction, bits):
    """Per axis, the allowed weights' rectangle ``((lo_x, hi_x), (lo_y, hi_y))`` of a ``bits``-bit filter."""
    f = np.asarray(fraction, np.float64)
    return quantized(f[:, 0], bits), quantized(f[:, 1], bits)


def _intensity(b, zf, dt):
    """BIAS_FLOAT32 then Algorithm 1's lower bound in ``dt``."""
    return np.asarray(shadow_intensity(bias_moments(np.asarray(b).astype(dt), BIAS_FLOAT32),
                                       np.asarray(zf).astype(dt)), np.float64)


def _reference_sample(texels, fraction):
    f = np.asarray(fraction)
    return (blend(texels, f[:, 0], f[:, 1], np.asarray(texels).dtype),)


def _reference_intensity(texels, fraction, zf):
    dt = np.asarray(texels).dtype
    return (_intensity(_reference_sample(texels, fraction)[0], zf, dt).astype(dt),)


def _filter_rounding(texels, dt):
    """``(n, 4)``: the rounding bound of a ``dt`` filter, FILTER_ULPS ulps of the largest texel component."""
    t = np.stack(_split(np.asarray(texels, np.float64)), axis=1)
    return FILTER_ULPS * float(np.finfo(dt).eps) * np.abs(t).max(axis=1)


def _labels(category, comment, flags, n):
    joined = [",".join(dict.fromkeys(f)) for f in flags]
    return {"tc_id": np.arange(1, n + 1, dtype=np.int32), "category": np.asarray(category).astype("U6"),
            "comment": np.asarray(comment).astype(f"U{max(1, max(len(c) for c in comment))}"),
            "flags": np.asarray(joined).astype(f"U{max(1, max(len(f) for f in joined))}"),
            "result": np.full(n, "valid", dtype="U10")}


def _corners(fraction, bits):
    (lx, hx), (ly, hy) = weight_interval(fraction, bits)
    f = np.asarray(fraction, np.float64)
    return [(lx, ly), (hx, ly), (lx, hy), (hx, hy), (f[:, 0], f[:, 1])]


def _sample_arrays(texels, fraction, bits):
    exact = blend_exact(texels, fraction)
    spread = np.zeros(exact.shape)
    for wx, wy in _corners(fraction, bits)[:4]:
        spread = np.maximum(spread, np.abs(blend(texels, wx, wy, np.float64) - exact))
    out = {"b": exact, "b_float32": _reference_sample(np.asarray(texels, np.float32), fraction)[0]}
    for d in PORT_DTYPES:
        out[f"b_tolerance_{d}"] = ceil2(np.maximum(spread + _filter_rounding(texels, d), 4 * ulp(exact, d)))
    return out, np.zeros(len(exact), bool)


def _grid(lo, hi, f):
    """Weights of FINER_BITS more bits from ``lo`` to ``hi``, and the exact fraction: ``(n, K)``."""
    k = np.arange(2 ** FINER_BITS + 1) / 2 ** FINER_BITS
    return np.concatenate([lo[:, None] + k[None] * (hi - lo)[:, None], f[:, None]], axis=1)


def _float_spread(texels, zf, corners, dt):
    """Largest deviation of ``dt`` Algorithm 1 evaluations (this package, the slides', the printed) on the
    corners' blends, rounded to ``dt`` and moved by the filter rounding, from float64 on the same blend."""
    r = _filter_rounding(texels, dt)
    sign = np.where(np.arange(4) % 2 == 0, 1.0, -1.0)
    dev = np.zeros(len(zf))
    with np.errstate(all="ignore"):
        for wx, wy in corners:
            b64 = blend(texels, wx, wy, np.float64)
            v64 = _intensity(b64, zf, np.float64)
            for b in (b64, b64 + r * sign, b64 - r * sign):
                biased = bias_moments(b.astype(dt), BIAS_FLOAT32)
                for v in (_intensity(b, zf, dt), slides_bound(biased, zf, "lower", dt),
                          printed_bound(biased, zf, "lower", dt)):
                    d = np.abs(np.clip(np.asarray(v, np.float64), 0, 1) - v64)
                    dev = np.fmax(dev, np.where(np.isnan(d), 0.0, d))
    return dev


def _intensity_arrays(texels, fraction, zf, bits):
    n = len(zf)
    exact = blend_exact(texels, fraction)
    truth = np.asarray(precise.shadow_intensity(precise.bias_moments(exact, BIAS_FLOAT32), zf), np.float64)
    (lx, hx), (ly, hy) = weight_interval(fraction, bits)
    f = np.asarray(fraction, np.float64)
    gx, gy = _grid(lx, hx, f[:, 0]), _grid(ly, hy, f[:, 1])
    hull = np.zeros(n)
    for a in range(gx.shape[1]):  # loops over weight candidates, vectorized over rows
        for c in range(gy.shape[1]):
            v = _intensity(blend(texels, gx[:, a], gy[:, c], np.float64), zf, np.float64)
            hull = np.maximum(hull, np.abs(v - truth))
    corners = _corners(fraction, bits)
    t32 = np.asarray(texels, np.float32)
    out = {"intensity": truth,
           "intensity_float32": _reference_intensity(t32, fraction, np.asarray(zf, np.float32))[0]}
    for d in PORT_DTYPES:
        t = hull + _SAFETY * _float_spread(texels, zf, corners, np.dtype(d))
        out[f"intensity_tolerance_{d}"] = np.minimum(ceil2(np.maximum(t, 4 * ulp(np.ones(n), d))), 1.0)
    return out, out["intensity_tolerance_float32"] >= _WIDE


def derive_bilinear(bits=SUBTEXEL_BITS):
    """A ``deriver`` (golden.spread.golden_arrays) for the bilinear cases with ``bits`` of sub-texel precision."""

    def deriver(case, arrays, category, comment, flags, contract=None):
        texels, fraction = np.asarray(arrays["texels"], np.float64), np.asarray(arrays["fraction"], np.float64)
        if "zf" in case.inputs:
            out, wide = _intensity_arrays(texels, fraction, np.asarray(arrays["zf"], np.float64), bits)
        else:
            out, wide = _sample_arrays(texels, fraction, bits)
        flags = [tuple(f) + (("wide_spread",) if w else ()) for f, w in zip(flags, wide)]
        out.update(_labels(category, comment, flags, len(category)))
        return out

    return deriver


# ---------------------------------------------------------------------------
# Rows


def _moments32(z, w):
    """Unbiased moments of distributions, rounded once to float32 (what a moment texture holds)."""
    return power_moments(z, w).astype(np.float32).astype(np.float64)


def _fractions(rng, n):
    return rng.integers(0, 2 ** FRACTION_BITS, (n, 2)) / 2.0 ** FRACTION_BITS


def _cluster(rng, centre, n, spread=1e-2):
    """Moments of 2-4 depths within ``spread`` of ``centre`` (an occluder or receiver surface): ``(n, 4)``."""
    z = np.clip(centre + rng.uniform(-spread, spread, (n, 4)), -1, 1)
    w = rng.uniform(0.2, 1, (n, 4)) * (np.arange(4)[None] < rng.integers(2, 5, n)[:, None])
    return _moments32(z, w / w.sum(axis=1, keepdims=True))


#: Which texels of the 2×2 see the occluder at a shadow edge (t00, t10, t01, t11).
_EDGES = {"vertical edge (left column occluded)": (1, 0, 1, 0), "horizontal edge (top row occluded)": (1, 1, 0, 0),
          "corner (one texel occluded)": (1, 0, 0, 0), "corner (three texels occluded)": (1, 1, 1, 0)}


def _random_quads(rng, n):
    z, w = _random_distributions(rng, 4 * n)
    return _moments32(z, w).reshape(n, 16)


def _edge_quads(rng, n):
    """Shadow edges: an occluder near depth z_o over a receiver at z_r across the 2×2; ``(texels, zf, what)``."""
    texels, zf, what = [], [], []
    names = list(_EDGES)
    for k in range(n):
        z_o, z_r = rng.uniform(-0.9, -0.1), rng.uniform(0.2, 0.9)
        name = names[k % len(names)]
        quad = [_cluster(rng, z_o if occ else z_r, 1)[0] for occ in _EDGES[name]]
        texels.append(np.concatenate(quad))
        zf.append(z_r + (0.03, 0.015, -0.015, 0.5 * (z_o - z_r))[k % 4])
        what.append(f"shadow edge, {name}: occluder near {z_o:.3f}, receiver near {z_r:.3f}")
    return np.array(texels), np.array(zf), what


def _rows(rng, dtype):
    rng = np.random.default_rng(20170724)  # the same neighbourhoods in both cases
    n_random, n_stiff = 128, 128
    t_r = _random_quads(rng, n_random)
    f_r = _fractions(rng, n_random)
    t_s, zf_s, what = _edge_quads(rng, n_stiff)
    f_s = _fractions(rng, n_stiff)
    # Half of them near the middle (within 1/32), where the edge is steepest.
    f_s[: n_stiff // 2] = 0.5 + rng.integers(-2048, 2048, (n_stiff // 2, 2)) / 2.0 ** FRACTION_BITS
    near = 1 - 2.0 ** -FRACTION_BITS
    edges = [0.0, 0.5, near, 2.0 ** -FRACTION_BITS, 77 / 256, 77.5 / 256]
    pairs = [(a, b) for a in edges for b in edges]
    base_t = np.concatenate([np.repeat(t_r[:1], len(pairs), 0), np.repeat(t_s[:1], len(pairs), 0)])
    f_e = np.array(pairs * 2)
    zf_e = np.concatenate([np.full(len(pairs), 0.1), np.full(len(pairs), zf_s[0])])
    texels = np.concatenate([t_r, t_s, base_t])
    fraction = np.concatenate([f_r, f_s, f_e])
    zf = np.concatenate([rng.uniform(-1, 1, n_random), zf_s, zf_e])
    cat = ["random"] * n_random + ["stiff"] * n_stiff + ["edge"] * len(f_e)
    com = ["four texels of 3 to 8 random depths each, unbiased float32 moments"] * n_random + what + [
        f"{'random texels' if k < len(pairs) else 'shadow-edge texels'}, fraction {tuple(float(x) for x in p)}"
        for k, p in enumerate(f_e)]
    grid = np.all(np.isin(fraction * 256, np.arange(257)), axis=1)
    edge = np.r_[np.zeros(n_random, bool), np.ones(n_stiff, bool), np.zeros(len(pairs), bool), np.ones(len(pairs), bool)]
    flags = [(("shadow_edge",) if e else ()) + (("weight_grid",) if g else ()) for e, g in zip(edge, grid)]
    return Rows({"texels": texels, "fraction": fraction, "zf": zf}, cat, com, flags)


def _variant(bits_default=SUBTEXEL_BITS):
    """The profile's ``[format] subtexel_bits``: the declared sub-texel precision of the engine's hardware."""

    def variant(fmt=None, **_):
        bits = int(dict(fmt or {}).get("subtexel_bits", bits_default))
        return {"deriver": derive_bilinear(bits), "kwargs": {"subtexel_bits": bits}}

    return variant


def case_specs():
    """Keyword dicts for :class:`moments_ref.golden.cases.Case`, one per bilinear case (float32 textures)."""
    why = (f"weights: any multiple of 2^-q within one step of the fraction, or the fraction (q = [format] "
           f"subtexel_bits of the profile, default {SUBTEXEL_BITS}); plus the rounding of a float32 filter")
    common = dict(dtype="float32", rows=_rows, truth=None, deriver=derive_bilinear(), variant=_variant(),
                  profile_keys=("format",), kwargs={"subtexel_bits": SUBTEXEL_BITS})
    return [
        dict(**common, name="sample_bilinear-float32", function="bilinear.sample", inputs=("texels", "fraction"),
             outputs=("b",), reference=_reference_sample,
             description="bilinear sample of a 2x2 neighbourhood of float32 moments (texels (n, 16): texel (i, j) at "
                         "4(2j + i)) at fraction (fx, fy); expected: the exact blend; " + why),
        dict(**common, name="shadow_intensity_bilinear-float32", function="bilinear.shadow_intensity",
             inputs=("texels", "fraction", "zf"), outputs=("intensity",), reference=_reference_intensity,
             value_range=(0, 1),
             description="HPG17 Algorithm 1 (lower bound) on the bilinear sample biased with BIAS_FLOAT32 "
                         "(alpha 3e-7, inside the function); expected from the exact blend and the mpmath twins; "
                         + why + ", and 16 x the float32 spread of Algorithm 1"),
    ]
