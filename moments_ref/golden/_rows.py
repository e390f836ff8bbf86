"""Golden rows, part 1: moments, Algorithm 1, biasing, the affine formats, six moments.

Each generator returns :class:`Rows`: inputs with a leading row axis (float64 or
integer, cast to the case's dtype later), and per row a category (``random``,
``stiff``, ``edge``), a comment saying why the row is there, and flags (names from
:data:`moments_ref.golden.notes.NOTES`) that say what is special about it.

References
----------
.. [1] HPG17: Christoph Peters. 2017. *Non-Linearly Quantized Moment Shadow Maps*. In Proceedings
       of High Performance Graphics (HPG '17). ACM. The non-linear quantization Φ, Ψ4, Algorithms
       1–3, the texel formats and the compute shader of §4.1.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..moments import BIAS_FLOAT32, BIAS_UNORM16, bias_moments, power_moments

@dataclass
class Rows:
    """Rows of one case: inputs with a leading row axis, category, comment and flags per row."""

    inputs: dict
    category: list
    comment: list
    flags: list = field(default_factory=list)  # per row: a tuple of flag names

    def __post_init__(self):
        if not self.flags:
            self.flags = [()] * len(self.category)

    @staticmethod
    def concat(parts):
        keys = parts[0].inputs.keys()
        return Rows(
            {k: np.concatenate([np.asarray(p.inputs[k]) for p in parts]) for k in keys},
            [c for p in parts for c in p.category],
            [c for p in parts for c in p.comment],
            [f for p in parts for f in p.flags],
        )


def _random_distributions(rng, n, min_points=3, max_points=8):
    """n distributions on [-1, 1] with min..max points: (z (n, 8), w (n, 8))."""
    z = rng.uniform(-1, 1, (n, max_points))
    w = rng.uniform(0.05, 1, (n, max_points))
    k = rng.integers(min_points, max_points + 1, n)
    w[np.arange(max_points)[None, :] >= k[:, None]] = 0
    return z, w / w.sum(axis=1, keepdims=True)


def _rows(inputs, category, comments, flags=()):
    n = len(next(iter(inputs.values())))
    if isinstance(comments, str):
        comments = [comments] * n
    flags = [tuple(flags)] * n if not flags or isinstance(flags[0], str) else [tuple(f) for f in flags]
    return Rows({k: np.asarray(v) for k, v in inputs.items()}, [category] * n, list(comments), flags)


def _two_point(z1, z2, v2):
    z = np.stack([np.broadcast_to(z1, np.shape(v2)), np.broadcast_to(z2, np.shape(v2))], axis=-1)
    w = np.stack([1 - np.asarray(v2), np.asarray(v2)], axis=-1)
    return power_moments(z, w)


def _at_support(zf, support):
    """Flags of a row whose zf is a support point: exact (y = b1, no arithmetic) or computed."""
    kind, points = support
    if zf not in points:
        return ()
    return ("support_point",) if kind == "exact" else ("near_support_point",)


def _hankel_det(b):
    """det of the Hankel matrix B(b) of four moments, in float64."""
    b = np.asarray(b, np.float64)
    return float(np.linalg.det(np.array([[1, b[0], b[1]], [b[0], b[1], b[2]], [b[1], b[2], b[3]]])))


def _msm_unbiased_rows():
    """Algorithm 1 rows outside the moment space and with exactly singular B(b)."""
    parts = []
    # Stiff: outside the moment space (b4 lowered), before and after biasing.
    bo = _two_point(-0.3, 0.6, 0.4)
    for delta, biased in ((1e-7, True), (1e-9, False), (1e-5, True)):
        bx = bo.copy()
        bx[3] -= delta
        if biased:
            bx = bias_moments(bx, BIAS_FLOAT32)
        # Still outside after biasing (det B(b) < 0: the bias of 3e-7 does not make up for
        # 1e-5): no distribution has these moments, so the bound is undefined there.
        outside = not biased or _hankel_det(bx) < 0
        zf = np.array([-0.5, -0.3, 0.0, 0.6, 0.8])
        parts.append(_rows({"b": np.repeat(bx[None], len(zf), 0), "zf": zf}, "stiff",
                           [f"two depths -0.3, 0.6 with b4 lowered by {delta:g} (outside the moment space)"
                            f"{', then BIAS_FLOAT32' if biased else ', unbiased'}"
                            f"{' (still outside)' if biased and outside else ''}, zf = {x}" for x in zf],
                           ("outside_moment_space",) if outside else ()))
    # Stiff: exactly singular unbiased input (ports are expected to bias first).
    for bs, what, support in ((power_moments([0.25]), "one depth 0.25", ("exact", [0.25])),
                              (_two_point(-0.5, 0.5, 0.5), "depths -0.5, 0.5", ("near", [-0.5, 0.5]))):
        zf = np.array([-0.6, -0.5, 0.0, 0.25, 0.5, 0.9])
        parts.append(_rows({"b": np.repeat(bs[None], len(zf), 0), "zf": zf}, "stiff",
                           [f"{what}, unbiased: singular Hankel matrix, exact answer expected, zf = {x}" for x in zf],
                           [("singular_hankel",) + _at_support(x, support) for x in zf]))
    return parts


def _msm_rows(rng, dtype):
    """Rows for Algorithm 1: (b, zf)."""
    parts = []
    z, w = _random_distributions(rng, 160)
    b = power_moments(z, w)
    parts.append(_rows({"b": b, "zf": rng.uniform(-1, 1, 160)}, "random",
                       "3 to 8 random depths in [-1, 1], random weights, unbiased"))
    bb = bias_moments(power_moments(*_random_distributions(rng, 40)), BIAS_UNORM16)
    parts.append(_rows({"b": bb, "zf": rng.uniform(-1, 1, 40)}, "random",
                       "3 to 8 random depths, BIAS_UNORM16 applied"))
    bf = bias_moments(power_moments(*_random_distributions(rng, 40)), BIAS_FLOAT32)
    parts.append(_rows({"b": bf, "zf": rng.uniform(-1, 1, 40)}, "random",
                       "3 to 8 random depths, BIAS_FLOAT32 applied (float moments, HPG17 §3.2)"))
    # Stiff: one depth after the float32 bias (variance at the bias floor).
    offsets = np.array([0.0, 1e-6, -1e-6, 1e-3, -1e-3, 0.1, -0.1])
    for d in (-1.0, -0.5, 0.0, 0.3, 1.0):
        b1 = bias_moments(power_moments([d]), BIAS_FLOAT32)
        zf = np.clip(d + offsets, -2, 2)
        parts.append(_rows({"b": np.repeat(b1[None], len(zf), 0), "zf": zf}, "stiff",
                           [f"one depth {d} after BIAS_FLOAT32 (variance at the bias floor), zf - depth = {o:g}"
                            for o in offsets], ("bias_floor",)))
    # Stiff: two depths after the float32 bias; zf at and next to the support points.
    for (z1, z2, v2) in ((-0.8, 0.4, 0.6), (0.915, 1.0, 0.5), (-0.2, -0.19, 0.3)):
        b2 = bias_moments(_two_point(z1, z2, v2), BIAS_FLOAT32)
        zf = np.array([z1, z2, z1 + 1e-6, z2 - 1e-6, z1 + 1e-4, z2 + 1e-4, 0.5 * (z1 + z2)])
        parts.append(_rows({"b": np.repeat(b2[None], len(zf), 0), "zf": zf}, "stiff",
                           [f"depths {z1}, {z2} (v2 = {v2}) after BIAS_FLOAT32, zf = {x:.9g}" for x in zf],
                           [("near_support_point",)] * 4 + [()] * 3))
    # Stiff: all mass near +-1.
    for zs in ((1 - 1e-4, 1.0, 1 - 5e-5), (-1.0, -1 + 1e-4, -1 + 3e-5)):
        bm = bias_moments(power_moments(np.array(zs)), BIAS_FLOAT32)
        zf = np.array([zs[0], zs[1], zs[2], np.mean(zs), 1.0, -1.0])
        parts.append(_rows({"b": np.repeat(bm[None], len(zf), 0), "zf": zf}, "stiff",
                           [f"three depths within 1e-4 of {round(zs[1])} after BIAS_FLOAT32, zf = {x:.9g}" for x in zf]))
    parts += _msm_unbiased_rows()
    # Edge: fragment depths at and beyond the depth range; depths at the range ends.
    z, w = _random_distributions(rng, 6)
    be = power_moments(z, w)
    zf = np.array([-1.0, 1.0, -2.0, 2.0, -10.0, 10.0])
    parts.append(_rows({"b": np.repeat(be, len(zf), 0), "zf": np.tile(zf, len(be))}, "edge",
                       [f"random distribution, zf = {x} at or beyond the depth range" for x in np.tile(zf, len(be))]))
    zf = np.array([-1.0, 0.0, 1.0, 0.5])
    for zends, cat, why in (([-1.0, 0.0, 1.0], "edge", "range ends"),
                            ([-1.0, -1.0, 1.0], "stiff", "range ends, two distinct depths: singular"),
                            ([-1.0, 1.0, 1.0], "stiff", "range ends, two distinct depths: singular")):
        bends = power_moments(np.array(zends))
        parts.append(_rows({"b": np.repeat(bends[None], len(zf), 0), "zf": zf}, cat,
                           [f"depths {zends} ({why}), zf = {x}" for x in zf],
                           [("singular_hankel",) + _at_support(x, ("near", zends)) if cat == "stiff" else ()
                            for x in zf]))
    return Rows.concat(parts)


#: Edge rows from the sweep's shrunk failures (docs/sweep.md, "What it finds"): regions of engine-like input that
#: the rows above missed, each catching one-change porting bugs (tests/sweep_mutants/corpus.py) the other rows pass.
_ALG1_SWEEP_EDGES = [
    ((-0.006,), (1.0,), -0.006 + 1e-4,
     "sweep: one depth -0.006 after BIAS_FLOAT32, zf 1e-4 behind it (a relative acne epsilon 1e-4·(z2 - z1) at z1 "
     "shadows nothing here)"),
    ((1.0, -1.0), (0.99, 0.01), 0.0,
     "sweep: a faint occluder far in front of the mean (weight 0.01 at -1, 0.99 at 1) after BIAS_FLOAT32, zf = 0 "
     "(a Chebyshev k·sigma early out returns 0 here)"),
]


#: Texels from the sweep given as the float32 moments an engine stores (not as depths: the hazard lies in their
#: rounding). Each gives two edge rows: the stored moments (for a function that biases inside; unbiased, they lie
#: just outside the moment space, a robustness row for the others) and the same moments after BIAS_FLOAT32 rounded
#: to float32 (what a function receives whose caller biases). HPG17 Algorithm 1's third pivot ξ4 of the biased
#: moments is 0.7 float32 ulp of b4 here: Cholesky from the raw moments in float32 without fma rounds it to 0 or
#: below, and the printed formulations (the slides' code, the printed algorithm) return 0 or NaN where the exact
#: value is 0.99985 (docs/golden.md, "Printed formulations that cancel").
_ALG1_SWEEP_STORED = [
    ((-0.9908193349838257, 0.9817230105400085, -0.9727101922035217, 0.9637800455093384), -0.98,
     "the float32-stored moments of one depth -0.9908, zf = -0.98 behind it; xi4 after BIAS_FLOAT32 is 0.7 "
     "float32 ulp of b4 (printed Cholesky without a guard cancels to 0: the demo's Algorithm 1 returns 0 "
     "for 0.99985)"),
]


def _alg1_rows(rng, dtype):
    """Rows for Algorithm 1: those of :func:`_msm_rows` and the sweep's edge rows (:data:`_ALG1_SWEEP_EDGES`,
    :data:`_ALG1_SWEEP_STORED`)."""
    parts = [_msm_rows(rng, dtype)]
    for zs, ws, zf, why in _ALG1_SWEEP_EDGES:
        b = bias_moments(power_moments(np.array(zs), np.array(ws)), BIAS_FLOAT32)
        parts.append(_rows({"b": b[None], "zf": np.array([zf])}, "edge", why))
    for stored, zf, why in _ALG1_SWEEP_STORED:
        b = np.array(stored, np.float32)
        biased = bias_moments(b, BIAS_FLOAT32).astype(np.float64)  # float32 arithmetic, as the shader biases
        parts.append(_rows({"b": np.stack([b.astype(np.float64), biased]), "zf": np.array([zf, zf])}, "edge",
                           [f"sweep, as stored (a function that biases inside): {why}",
                            f"sweep, after BIAS_FLOAT32 in float32 (a function whose caller biases): {why}"]))
    return Rows.concat(parts)


def _moment_rows(rng, dtype):
    """Rows of moment vectors b: random, near the boundary, at the range ends."""
    z, w = _random_distributions(rng, 120, 1, 8)
    parts = [_rows({"b": power_moments(z, w)}, "random", "1 to 8 random depths in [-1, 1]")]
    z, w = _random_distributions(rng, 40, 1, 8)
    parts.append(_rows({"b": power_moments(0.1 * z, w)}, "random",
                       "1 to 8 random depths in [-0.1, 0.1]: small moments, which biasing moves by many ulps"))
    ends = power_moments(np.array([[-1.0], [1.0], [0.0], [-1.0 + 1e-6], [1 - 1e-6]]))
    parts.append(_rows({"b": ends}, "edge", [f"one depth at {x:g}" for x in (-1, 1, 0, -1 + 1e-6, 1 - 1e-6)]))
    parts.append(_rows({"b": _two_point(np.array([0.915, -1.0, -1.0]), np.array([1.0, 1.0, -1.0 + 1e-7]),
                                        np.array([0.5, 0.5, 0.5]))},
                       "stiff", ["HPG17 §3.2 extreme case ½δ0.915 + ½δ1", "½δ-1 + ½δ1", "two depths 1e-7 apart at -1"]))
    return Rows.concat(parts)


def _optimized_rows(rng, dtype):
    """Rows of optimized-basis vectors q in [0, 1]^4 (inputs of from_optimized)."""
    from ..affine import to_optimized

    b = _moment_rows(rng, dtype)
    q = to_optimized(b.inputs["b"])
    corners = np.array([[0.0, 0, 0, 0], [1.0, 1, 1, 1], [0.5, 0.5, 0.5, 0.5]])
    return Rows.concat([
        Rows({"q": q}, b.category, [f"optimized basis of: {c}" for c in b.comment]),
        _rows({"q": corners}, "edge", ["all zero", "all one", "all one half"]),
    ])


def _unorm16_rows(rng, dtype):
    u = rng.integers(0, 65536, (120, 4))
    edge = np.array([[0, 0, 0, 0], [65535] * 4, [32767, 32768, 32767, 32768], [0, 65535, 0, 65535]])
    return Rows.concat([
        _rows({"u": u}, "random", "uniformly random codes"),
        _rows({"u": edge}, "edge", ["all codes 0", "all codes 65535", "codes around one half", "alternating 0 and 65535"]),
    ])


def _moment6_rows(rng, dtype):
    z, w = _random_distributions(rng, 100, 1, 8)
    parts = [_rows({"b": power_moments(z, w, n=6)}, "random", "1 to 8 random depths in [-1, 1]")]
    parts.append(_rows({"b": power_moments(np.array([[-1.0], [1.0], [0.0]]), n=6)}, "edge",
                       ["one depth at -1", "one depth at 1", "one depth at 0"]))
    return Rows.concat(parts)


def _r10_rows(rng, dtype):
    p = rng.integers(0, 1 << 30, (100, 2))
    edge = np.array([[0, 0], [(1 << 30) - 1] * 2])
    return Rows.concat([
        _rows({"p": p}, "random", "uniformly random 10-bit codes, alpha bits zero"),
        _rows({"p": edge}, "edge", ["all codes 0", "all codes 1023"]),
    ])


def _phi_rows(rng, dtype):
    """Moments for Algorithm 2, biased with BIAS_FLOAT32 as HPG17 §3.1 prescribes."""
    z, w = _random_distributions(rng, 150, 2, 8)
    b = bias_moments(power_moments(z, w), BIAS_FLOAT32)
    # Φ is ill-conditioned when the variance is small (y1, y2 barely determined): such
    # draws are stiff, not random.
    close = b[:, 1] - b[:, 0] ** 2 < 1e-3
    parts = [_rows({"b": b[~close]}, "random", "2 to 8 random depths in [-1, 1], BIAS_FLOAT32 applied"),
             _rows({"b": b[close]}, "stiff", "random draw with variance below 1e-3 (depths close together), "
                                             "BIAS_FLOAT32 applied")]
    stiff = [
        ((-0.2, -0.2 + 1e-6, 0.5), "two depths 1e-6 apart (y2 - y1 ~ 1e-6)"),
        ((-0.5, 0.5, 1e-6), "v2 = 1e-6"),
        ((-0.5, 0.5, 1 - 1e-6), "v2 = 1 - 1e-6"),
        ((0.3, 0.3 + 1e-3, 0.5), "two depths 1e-3 apart"),
        ((-1.0, -1.0 + 1e-5, 0.5), "two depths within 1e-5 of -1"),
    ]
    for (z1, z2, v2), what in stiff:
        parts.append(_rows({"b": bias_moments(_two_point(z1, z2, v2), BIAS_FLOAT32)[None]}, "stiff",
                           f"{what}, BIAS_FLOAT32 applied"))
    for d in (-1.0, 0.0, 0.7, 1.0):
        parts.append(_rows({"b": bias_moments(power_moments([d]), BIAS_FLOAT32)[None]}, "stiff",
                           f"one depth {d}, BIAS_FLOAT32 applied (variance at the bias floor)"))
    edge = [((0.915, 1.0, 0.5), "HPG17 §3.2 extreme case ½δ0.915 + ½δ1"), ((-1.0, 1.0, 0.5), "½δ-1 + ½δ1"),
            ((-1.0, 1.0, 0.25), "depths at both ends, v2 = 0.25")]
    for (z1, z2, v2), what in edge:
        parts.append(_rows({"b": bias_moments(_two_point(z1, z2, v2), BIAS_FLOAT32)[None]}, "edge",
                           f"{what}, BIAS_FLOAT32 applied"))
    return Rows.concat(parts)


def _msm6_rows(rng, dtype):
    """Rows for the six-moment bounds (slides, prefiltered single scattering): (b (n, 6), zf)."""
    from ..msm6 import BIAS6_FLOAT32, BIAS6_FLOAT64

    bias = BIAS6_FLOAT32 if dtype == np.float32 else BIAS6_FLOAT64
    z, w = _random_distributions(rng, 150, 5, 8)
    parts = [_rows({"b": bias_moments(power_moments(z, w, n=6), bias), "zf": rng.uniform(-1, 1, 150)}, "random",
                   f"5 to 8 random depths, {bias.name} bias (alpha = {bias.alpha:g})")]
    for spread in (0.0, 1e-4, 1e-2):
        zc = np.clip(0.3 + spread * rng.uniform(-1, 1, (4, 6)), -1, 1)
        b = bias_moments(power_moments(zc, n=6), bias)
        parts.append(_rows({"b": b, "zf": b[:, 0]}, "stiff",
                           f"six depths within {spread:g} of 0.3, {bias.name} bias, zf = b1"))
    zs = np.array([-1.0, 0.0, 1.0])
    b3 = bias_moments(power_moments(zs, n=6), bias)
    zf = np.array([-1.0, 0.0, 1.0, 1e-6, -0.5])
    parts.append(_rows({"b": np.repeat(b3[None], len(zf), 0), "zf": zf}, "stiff",
                       [f"three depths -1, 0, 1 (nearly singular 4×4 Hankel matrix), zf = {x:g}" for x in zf],
                       [("near_support_point",) if x in (-1.0, 0.0, 1.0) else () for x in zf]))
    z, w = _random_distributions(rng, 4, 5, 8)
    be = bias_moments(power_moments(z, w, n=6), bias)
    zf = np.array([-1.0, 1.0, -3.0, 3.0])
    parts.append(_rows({"b": np.repeat(be, len(zf), 0), "zf": np.tile(zf, len(be))}, "edge",
                       [f"random distribution, zf = {x:g} at or beyond the depth range" for x in np.tile(zf, len(be))]))
    return Rows.concat(parts)




#: The endpoints' moments (equal mass at 0 and 1): the target toward which the Hausdorff rows are biased.
_ENDS_TARGET = np.full(4, 0.5)


def _hausdorff_rows(rng, dtype):
    """Rows for the Hausdorff bound (moments_ref.hausdorff): (b, zf), depths and receivers in [0, 1]."""
    parts = []
    z, w = _random_distributions(rng, 120)
    z = 0.5 * (z + 1)
    parts.append(_rows({"b": power_moments(z, w), "zf": rng.uniform(0, 1, 120)}, "random",
                       "3 to 8 random depths in [0, 1], random weights (inside the moment space)"))
    z, w = _random_distributions(rng, 40)
    b = 0.99994 * power_moments(0.5 * (z + 1), w) + 6e-5 * _ENDS_TARGET
    parts.append(_rows({"b": b, "zf": rng.uniform(0, 1, 40)}, "random",
                       "3 to 8 random depths in [0, 1], mixed 6e-5 toward the ends' moments (0.5, 0.5, 0.5, 0.5)"))
    # Stiff: one depth mixed toward the ends (a flat receiver's texel): the distribution {0, d, 1} is unique.
    for d in (0.1, 0.35, 0.5, 0.9):
        b1 = 0.99994 * power_moments([d]) + 6e-5 * _ENDS_TARGET
        zf = np.array([0.0, 0.5 * d, d - 1e-3, d + 1e-3, 0.5 * (d + 1), 1.0])
        parts.append(_rows({"b": np.repeat(b1[None], len(zf), 0), "zf": zf}, "stiff",
                           [f"one depth {d} mixed 6e-5 toward the ends (mass at 0, {d} and 1), zf = {x:.9g}"
                            for x in zf], [("receiver_at_depth_0",) if x == 0 else () for x in zf]))
    # Stiff: mass at the near and far planes and one depth between (a texel straddling both ends): on the
    # boundary of the moment space of [0, 1]; at zf = 0 Algorithm 1's roots d and 1 round to either side of 1,
    # and a port that then takes the four-point branch divides by zf.
    for d in np.linspace(0.05, 0.95, 12):
        b3 = power_moments(np.array([0.0, d, 1.0]), rng.dirichlet(np.ones(3)))
        zf = np.array([0.0, 0.5 * d, 0.5 * (d + 1)])
        parts.append(_rows({"b": np.repeat(b3[None], len(zf), 0), "zf": zf}, "stiff",
                           [f"depths 0, {d:.3g} and 1 (near plane, one depth, far plane), zf = {x:.9g}" for x in zf],
                           [("receiver_at_depth_0",) if x == 0 else () for x in zf]))
    # Edge: receivers at the ends of the depth range, where the four-point formula divides by zf or 1 - zf.
    z, w = _random_distributions(rng, 10)
    be = power_moments(0.5 * (z + 1), w)
    for x in (0.0, 1.0):
        parts.append(_rows({"b": be, "zf": np.full(len(be), x)}, "edge",
                           f"random distribution in [0, 1], receiver at depth {x:g}",
                           ("receiver_at_depth_0",) if x == 0 else ()))
    # Robustness: moments of depths in [-1, 1] (outside the interval's moment space), receivers beyond [0, 1].
    z, w = _random_distributions(rng, 8)
    z[:, 0] = -0.5  # one depth below the interval, with weight at least 0.05 / 8
    parts.append(_rows({"b": power_moments(z, w), "zf": rng.uniform(0, 1, 8)}, "edge",
                       "3 to 8 depths in [-1, 1], one at -0.5: moments outside the moment space of [0, 1]",
                       ("outside_moment_space",)))
    parts.append(_rows({"b": be[:4], "zf": np.array([-0.5, -1e-3, 1.001, 2.0])}, "edge",
                       "random distribution in [0, 1], receiver beyond [0, 1]"))
    return Rows.concat(parts)
