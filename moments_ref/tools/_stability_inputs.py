"""The input families of :mod:`moments_ref.tools.stability`: seeded categories that hit the hard cases.

Each Algorithm 1 family returns float64 ``(b (n, 4) unbiased, zf (n,))``; each family of the
non-linear representation returns ``r (n, 4)`` = ``(y1, y2, v2, ξ4)``. :data:`DISTRIBUTIONS`
says in words what each draws (docs/stability.md prints it).

References
----------
.. [1] HPG17: Christoph Peters. 2017. *Non-Linearly Quantized Moment Shadow Maps*. In Proceedings
       of High Performance Graphics (HPG '17). ACM. The non-linear quantization Φ, Ψ4, Algorithms
       1–3, the texel formats and the compute shader of §4.1.
"""

from __future__ import annotations

import numpy as np

from .. import precise
from ..moments import power_moments

__all__ = ["MSM_CATEGORIES", "NONLINEAR_CATEGORIES", "DISTRIBUTIONS", "OFFSETS", "category_rng", "shade_zf"]

#: Offsets of zf from a support point in the "zf next to a support point" categories.
OFFSETS = (1e-6, 1e-4, 1e-2)


def category_rng(seed, label):
    """An independent generator per (seed, category): categories do not shift each other."""
    key = [seed] + [ord(c) for c in label]
    return np.random.default_rng(np.random.SeedSequence(key))


# ---------------------------------------------------------------------------
# input families for Algorithm 1: each returns float64 (b (n, 4) unbiased, zf (n,))


def _random_points(rng, n, kmax=8):
    k = rng.integers(1, kmax + 1, n)
    z = rng.uniform(-1, 1, (n, kmax))
    w = rng.uniform(1e-3, 1, (n, kmax)) * (np.arange(kmax) < k[:, None])
    return z, w / w.sum(axis=1, keepdims=True)


def _support_choice(rng, z, w):
    """One support point (with positive weight) per row."""
    p = (w > 0) / (w > 0).sum(axis=1, keepdims=True)
    idx = (rng.random(len(z))[:, None] > np.cumsum(p, axis=1)).sum(axis=1)
    return z[np.arange(len(z)), np.minimum(idx, z.shape[1] - 1)]


def _few_points(rng, n):
    return _random_points(rng, n, kmax=3)


def _cat_random(rng, n):
    z, w = _random_points(rng, n)
    return power_moments(z, w), rng.uniform(-1, 1, n)


def _cat_variance_floor(rng, n):
    # All mass within 0..1e-4 of a centre: the biased variance sits at its floor α·(b2* − …).
    centre = rng.uniform(-1, 1, n)
    spread = rng.choice([0.0, 1e-8, 1e-6, 1e-4], n)
    z = np.clip(centre[:, None] + spread[:, None] * rng.uniform(-1, 1, (n, 4)), -1, 1)
    w = rng.uniform(1e-3, 1, (n, 4))
    w /= w.sum(axis=1, keepdims=True)
    off = rng.choice([0.0, 1.0], n) * np.sign(rng.uniform(-1, 1, n)) * 10.0 ** rng.uniform(-8, -1, n)
    return power_moments(z, w), np.clip(centre + off, -1, 1)


def _cat_at_support(rng, n):
    z, w = _few_points(rng, n)
    return power_moments(z, w), _support_choice(rng, z, w)


def _cat_next_to_support(offset):
    def gen(rng, n):
        z, w = _few_points(rng, n)
        zf = _support_choice(rng, z, w) + offset * rng.choice([-1.0, 1.0], n)
        return power_moments(z, w), np.clip(zf, -1, 1)

    return gen


def _cat_near_pm1(rng, n):
    special = np.array([-1.0, -1.0 + 1e-6, 1.0 - 1e-6, 1.0, 1.0 - 1e-3])
    z = np.where(rng.random((n, 4)) < 0.75, rng.choice(special, (n, 4)), rng.uniform(-1, 1, (n, 4)))
    w = rng.uniform(1e-3, 1, (n, 4))
    w /= w.sum(axis=1, keepdims=True)
    zf = np.where(rng.random(n) < 0.5, rng.uniform(-1, 1, n),
                  rng.choice([-1.0, 1.0], n) * (1 - 10.0 ** rng.uniform(-7, -1, n)))
    return power_moments(z, w), zf


def _cat_zf_at_pm1(rng, n):
    # A depth at an end of the range (1: the far plane a cleared map stores) and the receiver on it or one
    # float32 step inside. The bias target's atoms at ±1 (HPG17 §3.2) sit on that depth and lift the last pivot
    # ξ4 least, so on some texels ξ4 falls below float32's resolution of b4 (docs/testing.md, the thorough profile).
    k = rng.integers(2, 4, n)
    z = rng.uniform(-1, 1, (n, 3))
    w = rng.uniform(1e-3, 1, (n, 3)) * (np.arange(3) < k[:, None])
    w /= w.sum(axis=1, keepdims=True)
    end = rng.choice([-1.0, 1.0], n)
    z[:, 0] = end
    return power_moments(z, w), end - end * rng.choice([0.0, 2.0**-24], n)


def _cat_outside(rng, n):
    # Two- and three-point moments pushed just outside the moment space before biasing:
    # ξ4 < 0 (b4 lowered) or σ² < 0 (b2 lowered below b1²).
    z, w = _few_points(rng, n)
    b = power_moments(z, w)
    sigma2 = b[:, 1] - b[:, 0] ** 2
    l32 = (b[:, 2] - b[:, 0] * b[:, 1]) / np.where(sigma2 > 0, sigma2, 1)
    xi4 = b[:, 3] - b[:, 1] ** 2 - l32**2 * sigma2
    mode = rng.integers(0, 2, n)
    delta = 10.0 ** rng.uniform(-9, -5, n)
    b[:, 3] = np.where(mode == 0, b[:, 3] - xi4 - delta, b[:, 3])
    b[:, 1] = np.where(mode == 1, b[:, 0] ** 2 - delta, b[:, 1])
    zf = _support_choice(rng, z, w) + rng.choice([0.0, 1e-6, -1e-4, 1e-2, 0.3], n)
    return b, np.clip(zf, -1, 1)


MSM_CATEGORIES = {
    "random": _cat_random,
    "variance near the bias floor": _cat_variance_floor,
    "zf at a support point": _cat_at_support,
    **{f"zf next to a support point ({o:g})": _cat_next_to_support(o) for o in OFFSETS},
    "mass near ±1": _cat_near_pm1,
    "zf at a depth at ±1": _cat_zf_at_pm1,
    "outside the moment space before biasing": _cat_outside,
}


#: What each category draws (per dtype the same ``n`` rows, seeded per (seed, category)).
DISTRIBUTIONS = {"msm": {
    "random": "1 to 8 depths uniform in [-1, 1], weights uniform in [1e-3, 1] normalised; zf uniform in [-1, 1]",
    "variance near the bias floor": "4 depths within 0, 1e-8, 1e-6 or 1e-4 of a uniform centre; zf at the centre "
                                    "or 1e-8 to 0.1 (log-uniform) from it",
    "zf at a support point": "1 to 3 depths as in random; zf one of them",
    **{f"zf next to a support point ({o:g})": f"1 to 3 depths as in random; zf one of them ± {o:g}" for o in OFFSETS},
    "mass near ±1": "4 depths, each with probability 3/4 one of -1, -1+1e-6, 1-1e-6, 1, 1-1e-3, else uniform; zf "
                    "uniform or within 1e-7 to 0.1 of ±1",
    "zf at a depth at ±1": "2 or 3 depths, the first -1 or 1, the others uniform, weights as in random; zf at the "
                           "first or one float32 step (2^-24) inside",
    "outside the moment space before biasing": "1 to 3 depths; ξ4 or σ² pushed 1e-9 to 1e-5 (log-uniform) below 0; "
                                               "zf a depth + 0, 1e-6, -1e-4, 1e-2 or 0.3"}, "nonlinear": {
    "random": "y1 < y2 uniform in [-1, 1], v2 uniform in [0.01, 0.99], Ψ4(ξ4) uniform in [0, 1]; shade's zf uniform "
              "(2/5) or y1 or y2 + 0, ±1e-6, ±1e-4, ±1e-2 (3/5)",
    "zf at y1 or y2": "the random representations; zf y1 or y2", "ξ4 at the clamp 1.2e-7": "random with ξ4 = 1.2e-7",
    "y2 − y1 ≈ 1e-6": "random with y2 = y1 + 1e-6", "v2 ≈ 1e-6": "random with v2 = 1e-6",
    "v2 ≈ 1 − 1e-6": "random with v2 = 1 - 1e-6", "depths at ±1": "random with y1 = -1, y2 = 1 or both"}}


# ---------------------------------------------------------------------------
# input families of the non-linear representation (moments_ref.nonlinear): each returns r (n, 4)


def _rep_random(rng, n):
    y1 = rng.uniform(-1, 1, n)
    y2 = rng.uniform(-1, 1, n)
    y1, y2 = np.minimum(y1, y2), np.maximum(y1, y2) + 1e-3 * rng.random(n)
    y2 = np.minimum(y2, 1.0)
    v2 = rng.uniform(0.01, 0.99, n)
    xi4 = precise.psi4_inverse(rng.uniform(0, 1, n))
    return np.stack([y1, y2, v2, xi4], axis=1)


def _rep_modified(column, values):
    def gen(rng, n):
        r = _rep_random(rng, n)
        if column == "gap":
            r[:, 1] = np.where(r[:, 0] + values <= 1, r[:, 0] + values, r[:, 0])
            r[:, 0] = np.where(r[:, 0] + values <= 1, r[:, 0], r[:, 0] - values)
        elif column == "pm1":
            pick = rng.integers(0, 3, n)
            r[:, 0] = np.where(pick != 1, -1.0, r[:, 0])
            r[:, 1] = np.where(pick != 0, 1.0, r[:, 1])
        else:
            r[:, column] = values
        return r

    return gen


NONLINEAR_CATEGORIES = {
    "random": _rep_random,
    "ξ4 at the clamp 1.2e-7": _rep_modified(3, 1.2e-7),
    "y2 − y1 ≈ 1e-6": _rep_modified("gap", 1e-6),
    "v2 ≈ 1e-6": _rep_modified(2, 1e-6),
    "v2 ≈ 1 − 1e-6": _rep_modified(2, 1 - 1e-6),
    "depths at ±1": _rep_modified("pm1", None),
}


def shade_zf(rng, r):
    """shade's receivers for representations ``r``: uniform (2/5), or y1 or y2 moved by 0, ±1e-6, ±1e-4, ±1e-2."""
    n = len(r)
    support = np.where(rng.random(n) < 0.5, r[:, 0], r[:, 1])
    off = rng.choice([0.0, 1e-6, -1e-6, 1e-4, -1e-4, 1e-2, -1e-2], n)
    return np.where(rng.random(n) < 0.4, rng.uniform(-1, 1, n), np.clip(support + off, -1, 1))
