"""Golden vectors for ports: write them, verify a foreign implementation's results.

``moments-ref golden --out DIR`` writes one ``.npz`` per case and ``manifest.json``
(design.md, "Golden outputs"). Each case is one public function at one dtype. Its
file holds

* the input arrays under the function's argument names (``b``, ``zf``, ``r`` ...),
  stored in the case's dtype: a float32 case feeds a float32 port exactly the
  values it will see;
* ``category``: per row ``random``, ``stiff`` or ``edge`` and ``comment``: why the
  row is there (Wycheproof style);
* the expected outputs under their names (``intensity``, ``q`` ...): the ground
  truth for the stored inputs (the mpmath twin of :mod:`moments_ref.precise`
  where one exists, else the float64 reference), and for float32 cases also
  ``<name>_float32``, what this reference's own float32 emulation computes.

Integer outputs (texel formats) are compared exactly: the expected value is the
reference evaluated in the case's dtype, and random rows whose code would change
between float32 and float64 evaluation (a rounding tie) are moved to ``stiff``.

Tolerances are measured, not guessed: per category, four times the worst error of
this reference's own float32 (or float64) evaluation against the expected
values, rounded up to one significant digit, and never below a floor of
``1e-6`` (float32) or ``1e-12`` (float64). A port written carefully from the
papers meets the random and edge tolerances; stiff rows show where float32 cannot
follow (see docs/stability.md) and are gated by their own looser tolerance.

Generation is deterministic: the same version writes the same bytes.
"""

from __future__ import annotations

import hashlib
import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

from . import __version__
from ._arrays import InputError
from ._io import save_npz, write_text
from .moments import BIAS_FLOAT32, BIAS_UNORM16, bias_moments, power_moments

__all__ = ["Case", "CASES", "SCHEMA_VERSION", "write", "verify", "case_rows", "VerifyReport", "evaluate_reference",
           "expected_outputs"]

SCHEMA_VERSION = 1
CATEGORIES = ("random", "stiff", "edge")
_FLOOR = {"float32": 1e-6, "float64": 1e-12}
_SAFETY = 4.0
_CAP = 1.0


@dataclass
class Rows:
    """Rows of one case: inputs with a leading row axis, their category and comment."""

    inputs: dict
    category: list
    comment: list

    @staticmethod
    def concat(parts):
        keys = parts[0].inputs.keys()
        return Rows(
            {k: np.concatenate([np.asarray(p.inputs[k]) for p in parts]) for k in keys},
            [c for p in parts for c in p.category],
            [c for p in parts for c in p.comment],
        )


@dataclass(frozen=True)
class Case:
    """One golden case: a public function evaluated at one dtype on labelled rows."""

    name: str
    function: str
    dtype: str
    inputs: tuple
    outputs: tuple
    rows: Callable  # (rng, dtype) -> Rows (inputs in float64 or int, cast later)
    reference: Callable  # (**inputs) -> tuple of outputs, in the inputs' dtype
    truth: Callable | None = None  # (**inputs) -> tuple of float64 outputs
    kwargs: dict = field(default_factory=dict)
    integer_inputs: dict = field(default_factory=dict)  # input name -> unsigned dtype
    description: str = ""

    @property
    def integer_output(self):
        return self.function.split(".")[-1] in _INTEGER_OUTPUT


_INTEGER_OUTPUT = {"encode_unorm16", "encode_r10g10b10a2", "pack64", "pack32"}
_U16, _U32 = {"u": "uint16"}, {"p": "uint32"}


# --------------------------------------------------------------------------
# Row generators
# --------------------------------------------------------------------------


def _random_distributions(rng, n, min_points=3, max_points=8):
    """n distributions on [-1, 1] with min..max points: (z (n, 8), w (n, 8))."""
    z = rng.uniform(-1, 1, (n, max_points))
    w = rng.uniform(0.05, 1, (n, max_points))
    k = rng.integers(min_points, max_points + 1, n)
    w[np.arange(max_points)[None, :] >= k[:, None]] = 0
    return z, w / w.sum(axis=1, keepdims=True)


def _rows(inputs, category, comments):
    n = len(next(iter(inputs.values())))
    if isinstance(comments, str):
        comments = [comments] * n
    return Rows({k: np.asarray(v) for k, v in inputs.items()}, [category] * n, list(comments))


def _two_point(z1, z2, v2):
    z = np.stack([np.broadcast_to(z1, np.shape(v2)), np.broadcast_to(z2, np.shape(v2))], axis=-1)
    w = np.stack([1 - np.asarray(v2), np.asarray(v2)], axis=-1)
    return power_moments(z, w)


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
    # Stiff: one depth after the float32 bias (variance at the bias floor).
    offsets = np.array([0.0, 1e-6, -1e-6, 1e-3, -1e-3, 0.1, -0.1])
    for d in (-1.0, -0.5, 0.0, 0.3, 1.0):
        b1 = bias_moments(power_moments([d]), BIAS_FLOAT32)
        zf = np.clip(d + offsets, -2, 2)
        parts.append(_rows({"b": np.repeat(b1[None], len(zf), 0), "zf": zf}, "stiff",
                           [f"one depth {d} after BIAS_FLOAT32 (variance at the bias floor), zf - depth = {o:g}"
                            for o in offsets]))
    # Stiff: two depths after the float32 bias; zf at and next to the support points.
    for (z1, z2, v2) in ((-0.8, 0.4, 0.6), (0.915, 1.0, 0.5), (-0.2, -0.19, 0.3)):
        b2 = bias_moments(_two_point(z1, z2, v2), BIAS_FLOAT32)
        zf = np.array([z1, z2, z1 + 1e-6, z2 - 1e-6, z1 + 1e-4, z2 + 1e-4, 0.5 * (z1 + z2)])
        parts.append(_rows({"b": np.repeat(b2[None], len(zf), 0), "zf": zf}, "stiff",
                           [f"depths {z1}, {z2} (v2 = {v2}) after BIAS_FLOAT32, zf = {x:.9g}" for x in zf]))
    # Stiff: all mass near +-1.
    for zs in ((1 - 1e-4, 1.0, 1 - 5e-5), (-1.0, -1 + 1e-4, -1 + 3e-5)):
        bm = bias_moments(power_moments(np.array(zs)), BIAS_FLOAT32)
        zf = np.array([zs[0], zs[1], zs[2], np.mean(zs), 1.0, -1.0])
        parts.append(_rows({"b": np.repeat(bm[None], len(zf), 0), "zf": zf}, "stiff",
                           [f"three depths within 1e-4 of {round(zs[1])} after BIAS_FLOAT32, zf = {x:.9g}" for x in zf]))
    # Stiff: outside the moment space (b4 lowered), before and after biasing.
    bo = _two_point(-0.3, 0.6, 0.4)
    for delta, biased in ((1e-7, True), (1e-9, False), (1e-5, True)):
        bx = bo.copy()
        bx[3] -= delta
        if biased:
            bx = bias_moments(bx, BIAS_FLOAT32)
        zf = np.array([-0.5, -0.3, 0.0, 0.6, 0.8])
        parts.append(_rows({"b": np.repeat(bx[None], len(zf), 0), "zf": zf}, "stiff",
                           [f"two depths -0.3, 0.6 with b4 lowered by {delta:g} (outside the moment space)"
                            f"{', then BIAS_FLOAT32' if biased else ', unbiased'}, zf = {x}" for x in zf]))
    # Stiff: exactly singular unbiased input (ports are expected to bias first).
    for bs, what in ((power_moments([0.25]), "one depth 0.25"), (_two_point(-0.5, 0.5, 0.5), "depths -0.5, 0.5")):
        zf = np.array([-0.6, -0.5, 0.0, 0.25, 0.5, 0.9])
        parts.append(_rows({"b": np.repeat(bs[None], len(zf), 0), "zf": zf}, "stiff",
                           [f"{what}, unbiased: singular Hankel matrix, exact answer expected, zf = {x}" for x in zf]))
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
                           [f"depths {zends} ({why}), zf = {x}" for x in zf]))
    return Rows.concat(parts)


def _moment_rows(rng, dtype):
    """Rows of moment vectors b: random, near the boundary, at the range ends."""
    z, w = _random_distributions(rng, 120, 1, 8)
    parts = [_rows({"b": power_moments(z, w)}, "random", "1 to 8 random depths in [-1, 1]")]
    ends = power_moments(np.array([[-1.0], [1.0], [0.0], [-1.0 + 1e-6], [1 - 1e-6]]))
    parts.append(_rows({"b": ends}, "edge", [f"one depth at {x:g}" for x in (-1, 1, 0, -1 + 1e-6, 1 - 1e-6)]))
    parts.append(_rows({"b": _two_point(np.array([0.915, -1.0, -1.0]), np.array([1.0, 1.0, -1.0 + 1e-7]),
                                        np.array([0.5, 0.5, 0.5]))},
                       "stiff", ["HPG17 §3.2 extreme case ½δ0.915 + ½δ1", "½δ-1 + ½δ1", "two depths 1e-7 apart at -1"]))
    return Rows.concat(parts)


def _optimized_rows(rng, dtype):
    """Rows of optimized-basis vectors q in [0, 1]^4 (inputs of from_optimized)."""
    from .affine import to_optimized

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
    from .msm6 import BIAS6_FLOAT32, BIAS6_FLOAT64

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
                       [f"three depths -1, 0, 1 (nearly singular 4×4 Hankel matrix), zf = {x:g}" for x in zf]))
    z, w = _random_distributions(rng, 4, 5, 8)
    be = bias_moments(power_moments(z, w, n=6), bias)
    zf = np.array([-1.0, 1.0, -3.0, 3.0])
    parts.append(_rows({"b": np.repeat(be, len(zf), 0), "zf": np.tile(zf, len(be))}, "edge",
                       [f"random distribution, zf = {x:g} at or beyond the depth range" for x in np.tile(zf, len(be))]))
    return Rows.concat(parts)


def _random_representations(rng, n):
    y = np.sort(rng.uniform(-1, 1, (n, 2)), axis=1)
    v2 = rng.uniform(0.01, 0.99, n)
    xi4 = 10 ** rng.uniform(-7, np.log10(0.25), n)
    return np.column_stack([y, v2, xi4])


_STIFF_REPRESENTATIONS = [
    ((-0.8, 0.4, 0.6, 1.2e-7), "ξ4 at the Ψ4 clamp 1.2e-7"),
    ((-0.8, 0.4, 0.6, 1.3e-7), "ξ4 just above the Ψ4 clamp"),
    ((0.1, 0.1 + 1e-6, 0.5, 1e-7), "y2 - y1 = 1e-6 (Algorithm 3 clamp)"),
    ((0.1, 0.1 + 1e-4, 0.5, 1e-9), "y2 - y1 = 1e-4, tiny ξ4"),
    ((-0.5, 0.5, 1e-6, 1e-5), "v2 = 1e-6 (Algorithm 3 clamp)"),
    ((-0.5, 0.5, 1 - 1e-6, 1e-5), "v2 = 1 - 1e-6 (Algorithm 3 clamp)"),
    ((-0.3, 0.2, 0.4, 0.0), "ξ4 = 0 (two-point distribution)"),
    ((0.2, 0.6, 0.0, 1e-3), "v2 = 0 (one depth plus ξ4; Algorithm 3 clamps v2 to 1e-6)"),
    ((0.2, 0.6, 1.0, 1e-3), "v2 = 1 (one depth plus ξ4; Algorithm 3 clamps v2 to 1 - 1e-6)"),
]
_EDGE_REPRESENTATIONS = [
    ((-1.0, 1.0, 0.5, 0.25), "depths at ±1, ξ4 at its maximum 0.25"),
    ((-1.0, -1.0 + 2 / 1023, 0.5, 1e-4), "depths in the lowest 32-bit cells"),
    ((1.0 - 2 / 1023, 1.0, 0.5, 1e-4), "depths in the highest 32-bit cells"),
    ((-0.0005, 0.0005, 0.5, 1e-6), "depths around the 32-bit fold at ỹ = 511.5"),
]


def _representation_rows(rng, dtype):
    parts = [_rows({"r": _random_representations(rng, 150)}, "random",
                   "y1 < y2 uniform in [-1, 1], v2 in [0.01, 0.99], ξ4 log-uniform in [1e-7, 0.25]")]
    for cat, table in (("stiff", _STIFF_REPRESENTATIONS), ("edge", _EDGE_REPRESENTATIONS)):
        for r, what in table:
            parts.append(_rows({"r": np.array([r])}, cat, what))
    return Rows.concat(parts)


def _shade_rows(rng, dtype):
    r = _random_representations(rng, 200)
    parts = [_rows({"r": r, "zf": rng.uniform(-1, 1, 200)}, "random",
                   "random representation (see case phi_inverse) and zf uniform in [-1, 1]")]
    for cat, table in (("stiff", _STIFF_REPRESENTATIONS), ("edge", _EDGE_REPRESENTATIONS)):
        for rep, what in table:
            y1, y2 = rep[0], rep[1]
            zf = np.array([y1, y2, y1 + 1e-6, y2 + 1e-6, 0.5 * (y1 + y2), min(1.0, y2 + 0.1)])
            parts.append(_rows({"r": np.repeat(np.array([rep]), len(zf), 0), "zf": zf}, cat,
                               [f"{what}, zf = {x:.9g}" for x in zf]))
    return Rows.concat(parts)


def _psi4_rows(rng, dtype):
    return Rows.concat([
        _rows({"xi4": 10 ** rng.uniform(-7, np.log10(0.25), 120)}, "random", "ξ4 log-uniform in [1e-7, 0.25]"),
        _rows({"xi4": np.array([1.2e-7 * (1 + 1e-6), 1.2e-7 * (1 - 1e-6)])}, "stiff",
              ["just above the clamp 1.2e-7", "just below the clamp 1.2e-7"]),
        _rows({"xi4": np.array([0.0, 1e-7, 1.2e-7, 0.25])}, "edge",
              ["ξ4 = 0 (clamped)", "ξ4 = 1e-7 (clamped)", "ξ4 at the clamp: Ψ4 = 0", "ξ4 = 0.25: Ψ4 = 1"]),
    ])


def _psi4_inverse_rows(rng, dtype):
    return Rows.concat([
        _rows({"u": rng.uniform(0, 1, 120)}, "random", "u uniform in [0, 1]"),
        _rows({"u": np.array([0.0, 1.0, 0.5])}, "edge", ["u = 0", "u = 1", "u = 0.5"]),
    ])


def _pack64_input_rows(rng, dtype):
    from .packing import pack64

    r = _representation_rows(rng, dtype)
    return Rows({"q": pack64(r.inputs["r"])}, r.category, [f"pack64 of: {c}" for c in r.comment])


def _pack32_input_rows(rng, dtype):
    from .packing import pack32

    r = _representation_rows(rng, dtype)
    return Rows({"p": pack32(r.inputs["r"])}, r.category, [f"pack32 of: {c}" for c in r.comment])


# --------------------------------------------------------------------------
# References and ground truth
# --------------------------------------------------------------------------


def _precise_msm(bound):
    def truth(b, zf):
        from . import precise

        return (precise.shadow_intensity(b, zf, bound=bound),)

    return truth


def _msm_reference(bound):
    def ref(b, zf):
        from .msm import shadow_intensity

        return (shadow_intensity(b, zf, bound=bound),)

    return ref


def _precise(name, **kwargs):
    def truth(*args, **kw):
        from . import precise

        out = getattr(precise, name)(*args, **kw, **kwargs)
        return out if isinstance(out, tuple) else (out,)

    return truth


def _wrap(path, **kwargs):
    """A reference calling ``moments_ref.<path>`` and returning a tuple."""
    module, name = path.rsplit(".", 1)

    def ref(*args, **kw):
        import importlib

        fn = getattr(importlib.import_module(f"moments_ref.{module}"), name)
        out = fn(*args, **kw, **kwargs)
        return out if isinstance(out, tuple) else (out,)

    return ref


def _cases():
    cases = []
    for dt in ("float32", "float64"):
        for bound in ("lower", "upper"):
            cases.append(Case(
                f"shadow_intensity-{bound}-{dt}", "msm.shadow_intensity", dt, ("b", "zf"), ("intensity",),
                _msm_rows, _msm_reference(bound), _precise_msm(bound), {"bound": bound},
                description=f"HPG17 Algorithm 1, {bound} bound; expected values from the mpmath twin",
            ))
        for preset in (BIAS_FLOAT32, BIAS_UNORM16):
            cases.append(Case(
                f"bias_moments-{preset.name}-{dt}", "moments.bias_moments", dt, ("b",), ("b_biased",),
                _moment_rows, _wrap("moments.bias_moments", preset=preset), None,
                {"preset": f"BIAS_{preset.name.upper()}"},
                description=f"HPG17 §3.2 biasing, alpha = {preset.alpha:g}, target {preset.target}",
            ))
        cases += [
            Case(f"to_optimized-{dt}", "affine.to_optimized", dt, ("b",), ("q",), _moment_rows,
                 _wrap("affine.to_optimized"), description="Slides, 'Compute moments in resolve'"),
            Case(f"from_optimized-{dt}", "affine.from_optimized", dt, ("q",), ("b",), _optimized_rows,
                 _wrap("affine.from_optimized"), description="Slides, 'Retrieve moments'"),
            Case(f"encode_unorm16-{dt}", "affine.encode_unorm16", dt, ("b",), ("u",), _moment_rows,
                 _wrap("affine.encode_unorm16"), description="64-bit affine texel: four UNORM16 of the optimized basis"),
            Case(f"decode_unorm16-{dt}", "affine.decode_unorm16", dt, ("u",), ("b",), _unorm16_rows,
                 _wrap("affine.decode_unorm16"), integer_inputs=_U16,
                 description="64-bit affine texel decode"),
            Case(f"to_optimized6-{dt}", "affine.to_optimized6", dt, ("b",), ("q",), _moment6_rows,
                 _wrap("affine.to_optimized6"), description="Slides, six-moment 'Quantization transform'"),
            Case(f"encode_r10g10b10a2-{dt}", "affine.encode_r10g10b10a2", dt, ("b",), ("p",), _moment6_rows,
                 _wrap("affine.encode_r10g10b10a2"), description="six moments in 2×R10G10B10A2_UNORM"),
            Case(f"decode_r10g10b10a2-{dt}", "affine.decode_r10g10b10a2", dt, ("p",), ("b",), _r10_rows,
                 _wrap("affine.decode_r10g10b10a2"), integer_inputs=_U32,
                 description="six moments from 2×R10G10B10A2_UNORM"),
            *[Case(f"shadow_intensity6-{bound}-{dt}", "msm.shadow_intensity", dt, ("b", "zf"), ("intensity",),
                   _msm6_rows, _msm_reference(bound), _precise("shadow_intensity6", bound=bound), {"bound": bound},
                   description=f"six-moment {bound} bound (slides, 'Prefiltered single scattering'); b (n, 6); "
                               "expected from the mpmath twin")
              for bound in ("lower", "upper")],
            Case(f"phi-{dt}", "nonlinear.phi", dt, ("b",), ("r",), _phi_rows, _wrap("nonlinear.phi"),
                 _precise("phi"), description="HPG17 Algorithm 2 on BIAS_FLOAT32-biased moments; expected from mpmath"),
            Case(f"phi_inverse-{dt}", "nonlinear.phi_inverse", dt, ("r",), ("b",), _representation_rows,
                 _wrap("nonlinear.phi_inverse"), _precise("phi_inverse"), description="HPG17 Eq. (4)"),
            Case(f"psi4-{dt}", "nonlinear.psi4", dt, ("xi4",), ("u",), _psi4_rows, _wrap("nonlinear.psi4"),
                 _precise("psi4"), description="HPG17 §3.3 warp of ξ4, clamped at 1.2e-7"),
            Case(f"psi4_inverse-{dt}", "nonlinear.psi4_inverse", dt, ("u",), ("xi4",), _psi4_inverse_rows,
                 _wrap("nonlinear.psi4_inverse"), _precise("psi4_inverse"), description="inverse of Ψ4"),
            Case(f"shade-{dt}", "nonlinear.shade", dt, ("r", "zf"), ("intensity",), _shade_rows,
                 _wrap("nonlinear.shade"), _precise("shade"),
                 description="HPG17 Algorithm 3; expected: Algorithm 1 on the moments of Eq. (4) in mpmath "
                             "(no clamps), so stiff rows show the effect of the §3.4 clamps"),
            Case(f"pack64-{dt}", "packing.pack64", dt, ("r",), ("q",), _representation_rows,
                 _wrap("packing.pack64"), description="64-bit texel, docs/formats.md"),
            Case(f"unpack64-{dt}", "packing.unpack64", dt, ("q",), ("r",), _pack64_input_rows,
                 _wrap("packing.unpack64"), integer_inputs={"q": "uint16"},
                 description="64-bit texel decode, docs/formats.md"),
            Case(f"pack32-{dt}", "packing.pack32", dt, ("r",), ("p",), _representation_rows,
                 _wrap("packing.pack32"), description="32-bit texel with the triangle fold, docs/formats.md"),
            Case(f"unpack32-{dt}", "packing.unpack32", dt, ("p",), ("r",), _pack32_input_rows,
                 _wrap("packing.unpack32"), integer_inputs={"p": "uint32"},
                 description="32-bit texel decode (ξ4 rounded up), docs/formats.md"),
        ]
    return cases


CASES = {c.name: c for c in _cases()}


# --------------------------------------------------------------------------
# Generation
# --------------------------------------------------------------------------


def _seed(name):
    return int.from_bytes(hashlib.sha256(name.encode()).digest()[:8], "little")


def case_rows(case: Case):
    """The rows of ``case``: (inputs dict cast to the case's dtypes, category, comment)."""
    rng = np.random.default_rng(_seed(case.name))
    rows = case.rows(rng, np.dtype(case.dtype))
    inputs = {}
    for k in case.inputs:
        v = np.asarray(rows.inputs[k])
        if k in case.integer_inputs:
            inputs[k] = v.astype(case.integer_inputs[k])
        else:
            inputs[k] = v.astype(case.dtype)
    return inputs, np.asarray(rows.category), np.asarray(rows.comment)


def _ceil1(x):
    """Round up to one significant digit (tolerances read well and stay above x)."""
    if x <= 0:
        return 0.0
    e = math.floor(math.log10(x))
    m = math.ceil(x / 10**e - 1e-9)
    return float(f"{m}e{e}")


def evaluate_reference(case, inputs, dtype):
    """The reference's outputs (tuple) for ``inputs`` evaluated in ``dtype``.

    Float inputs are cast to ``dtype``; decoders (integer inputs) get ``dtype=``.
    """
    args = {k: (v if k in case.integer_inputs else np.asarray(v).astype(dtype)) for k, v in inputs.items()}
    if case.integer_inputs:
        return case.reference(**args, dtype=np.dtype(dtype))
    return case.reference(**args)


def expected_outputs(case, inputs):
    """Expected values: exact codes for encoders (in the case's dtype), else the ground truth."""
    if case.integer_output:
        return evaluate_reference(case, inputs, case.dtype)
    if case.truth is not None:
        as64 = {k: (v if k in case.integer_inputs else np.asarray(v).astype(np.float64)) for k, v in inputs.items()}
        return case.truth(**as64)
    return evaluate_reference(case, inputs, np.float64)


_NUDGE = 8 * float(np.finfo(np.float32).eps)


def _evaluate(case):
    inputs, category, comment = case_rows(case)
    n = len(category)
    outputs = {}
    ref = evaluate_reference(case, inputs, case.dtype)
    if case.integer_output:
        # A code that changes when the inputs move by a few float32 ulps, or between
        # float32 and float64 evaluation, sits on a rounding boundary: a port may
        # legitimately land on either side (different log/exp, fma), so it is stiff.
        variants = [evaluate_reference(case, inputs, np.float64), evaluate_reference(case, inputs, np.float32)]
        for f in (1 + _NUDGE, 1 - _NUDGE):
            nudged = {}
            for k, v in inputs.items():
                v = np.asarray(v, np.float64)
                # Values stay in [-1, 1] if they were (every input domain here is inside it).
                nudged[k] = np.where((np.abs(v * f) > 1) & (np.abs(v) <= 1), v, v * f)
            variants.append(evaluate_reference(case, nudged, np.float64))
        for i, name in enumerate(case.outputs):
            outputs[name] = ref[i]
            tie = np.zeros(n, bool)
            for v in variants:
                tie |= np.any((v[i] != ref[i]).reshape(n, -1), axis=1)
            moved = tie & (category != "stiff")
            category = np.where(moved, "stiff", category)
            comment = np.where(moved, np.char.add(comment, " [on a rounding boundary: the code changes within "
                                                           "float32 rounding of the inputs]"), comment)
        tolerances = {dt: {c: 0 for c in CATEGORIES} for dt in ("float32", "float64")}
        return inputs, category, comment, outputs, tolerances
    truth = expected_outputs(case, inputs)
    r32 = evaluate_reference(case, inputs, np.float32)
    r64 = evaluate_reference(case, inputs, np.float64)
    tolerances = {"float32": {}, "float64": {}}
    for i, name in enumerate(case.outputs):
        t = np.asarray(truth[i], dtype=np.float64)
        outputs[name] = t
        if case.dtype == "float32":
            outputs[f"{name}_float32"] = np.asarray(ref[i])
        errs = {dt: np.abs(np.asarray(r[i], np.float64) - t).reshape(n, -1).max(axis=1)
                for dt, r in (("float32", r32), ("float64", r64))}
        for c in CATEGORIES:
            sel = category == c
            for dt, err in errs.items():
                worst = float(err[sel].max()) if sel.any() else 0.0
                # An error of 1 is the whole range of a shadow intensity: cap there.
                tol = min(max(_ceil1(_SAFETY * worst), _FLOOR[dt]), _CAP)
                tolerances[dt][c] = max(tolerances[dt].get(c, 0.0), tol)
    return inputs, category, comment, outputs, tolerances


def write(out_dir, cases=None, progress=None):
    """Write the golden vectors and ``manifest.json`` to ``out_dir``.

    Parameters
    ----------
    out_dir : path
        Target folder (created). Every file is written atomically.
    cases : iterable of str, optional
        Case names (default: all of :data:`CASES`).
    progress : callable, optional
        Called with each case name as it is written (the CLI's progress bar).

    Returns
    -------
    manifest : dict
    """
    out_dir = Path(out_dir)
    names = list(CASES) if cases is None else list(cases)
    unknown = [n for n in names if n not in CASES]
    if unknown:
        raise InputError(f"cases: unknown case {unknown[0]!r}; known: {', '.join(CASES)}")
    manifest = {
        "schema_version": SCHEMA_VERSION,
        "package": "moments_ref",
        "package_version": __version__,
        "numpy_version": np.__version__,
        "tolerance_metric": "maximum absolute difference per row over the row's output values; "
                            "integer outputs: exact",
        "cases": {},
    }
    for name in names:
        case = CASES[name]
        inputs, category, comment, outputs, tolerances = _evaluate(case)
        arrays = dict(inputs)
        arrays.update(outputs)
        arrays["category"] = category.astype("U6")
        arrays["comment"] = comment.astype(f"U{max(1, max(len(c) for c in comment))}")
        data = save_npz(out_dir / f"{name}.npz", arrays)
        manifest["cases"][name] = {
            "file": f"{name}.npz",
            "function": f"moments_ref.{case.function}",
            "kwargs": {k: str(v) for k, v in case.kwargs.items()},
            "description": case.description,
            "dtype": case.dtype,
            "inputs": {k: {"dtype": str(inputs[k].dtype), "shape": list(inputs[k].shape)} for k in case.inputs},
            "outputs": {k: {"dtype": str(v.dtype), "shape": list(v.shape)} for k, v in outputs.items()},
            "compare": list(case.outputs),
            "count": int(len(category)),
            "categories": {c: int((category == c).sum()) for c in CATEGORIES},
            "sha256": hashlib.sha256(data).hexdigest(),
            "tolerances": tolerances,
            "exact": bool(case.integer_output),
        }
        if progress is not None:
            progress(name)
    write_text(out_dir / "manifest.json", json.dumps(manifest, indent=2, sort_keys=True) + "\n")
    return manifest


# --------------------------------------------------------------------------
# Verification
# --------------------------------------------------------------------------


@dataclass
class CaseResult:
    name: str
    status: str  # "pass", "fail", "missing", "error"
    port_dtype: str
    worst: list  # rows: dict(index, category, error, tolerance, comment, inputs, got, expected)
    per_category: dict  # category -> (worst error, tolerance, rows)
    message: str = ""


@dataclass
class VerifyReport:
    cases: list

    @property
    def failed(self):
        return any(c.status in ("fail", "error") for c in self.cases)

    @property
    def checked(self):
        return [c for c in self.cases if c.status in ("pass", "fail")]

    def format(self, worst_rows=5):
        lines = []
        for c in self.cases:
            if c.status == "missing":
                continue
            head = f"{c.status.upper():5} {c.name} (port dtype {c.port_dtype})"
            if c.message:
                head += f": {c.message}"
            lines.append(head)
            for cat, (err, tol, n) in c.per_category.items():
                lines.append(f"      {cat:6} rows {n:4d}  worst error {err:.3g}  tolerance {tol:.3g}")
            if c.status == "fail":
                for r in c.worst[:worst_rows]:
                    ins = ", ".join(f"{k}={np.array2string(np.asarray(v), precision=9)}" for k, v in r["inputs"].items())
                    lines.append(f"      row {r['index']} [{r['category']}] error {r['error']:.3g} > {r['tolerance']:.3g}: "
                                 f"got {np.array2string(np.asarray(r['got']), precision=9)}, "
                                 f"expected {np.array2string(np.asarray(r['expected']), precision=9)}; {ins}")
                    lines.append(f"        ({r['comment']})")
        missing = [c.name for c in self.cases if c.status == "missing"]
        if missing:
            lines.append(f"not in the results (not checked): {len(missing)} cases")
        n_fail = sum(c.status in ("fail", "error") for c in self.cases)
        lines.append(f"{len(self.checked) - sum(c.status == 'fail' for c in self.checked)} passed, {n_fail} failed")
        return "\n".join(lines)


def _load_results(path):
    path = Path(path)
    if not path.is_file():
        raise InputError(f"results: expected an .npz file, got {str(path)!r} (not found)")
    try:
        with np.load(path, allow_pickle=False) as data:
            return {k: data[k] for k in data.files}
    except Exception as exc:
        raise InputError(f"results: expected an .npz file, could not read {str(path)!r}: {exc}") from None


def verify(golden_dir, results_path, port_dtype=None):
    """Compare a foreign implementation's outputs with the goldens.

    Parameters
    ----------
    golden_dir : path
        A folder written by :func:`write`.
    results_path : path
        An ``.npz`` whose arrays are named ``<case>.<output>`` (for example
        ``shadow_intensity-lower-float32.intensity``), each with the case's rows in
        order. Cases absent from the file are listed as not checked.
    port_dtype : {"float32", "float64"}, optional
        Which tolerance column applies; default: each case's own dtype.

    Returns
    -------
    VerifyReport
        ``report.failed`` is True when any row exceeds its tolerance or an output
        has the wrong shape; ``report.format()`` lists the worst rows with inputs.
    """
    golden_dir = Path(golden_dir)
    mpath = golden_dir / "manifest.json"
    if not mpath.is_file():
        raise InputError(f"golden_dir: expected a folder with manifest.json, got {str(golden_dir)!r}")
    manifest = json.loads(mpath.read_text())
    if port_dtype not in (None, "float32", "float64"):
        raise InputError(f"port_dtype: expected float32 or float64, got {port_dtype!r}")
    results = _load_results(results_path)
    known = {f"{n}.{o}" for n, m in manifest["cases"].items() for o in m["compare"]}
    stray = sorted(set(results) - known)
    report = []
    for name, meta in manifest["cases"].items():
        dt = port_dtype or meta["dtype"]
        keys = [f"{name}.{o}" for o in meta["compare"]]
        if not any(k in results for k in keys):
            report.append(CaseResult(name, "missing", dt, [], {}))
            continue
        blob = (golden_dir / meta["file"]).read_bytes()
        if hashlib.sha256(blob).hexdigest() != meta["sha256"]:
            report.append(CaseResult(name, "error", dt, [], {}, "golden file does not match its sha256"))
            continue
        with np.load(golden_dir / meta["file"], allow_pickle=False) as g:
            gold = {k: g[k] for k in g.files}
        category = gold["category"]
        n = len(category)
        err = np.zeros(n)
        msg = ""
        for out, key in zip(meta["compare"], keys):
            if key not in results:
                msg = f"output {key!r} missing"
                break
            got = np.asarray(results[key])
            exp = gold[out]
            if got.shape != exp.shape:
                msg = f"output {key!r} has shape {got.shape}, expected {exp.shape}"
                break
            if meta["exact"]:
                diff = (got.astype(np.int64) != exp.astype(np.int64)).astype(np.float64)
            else:
                with np.errstate(invalid="ignore"):
                    diff = np.abs(got.astype(np.float64) - exp.astype(np.float64))
                diff = np.where(np.isnan(diff), np.inf, diff)
            err = np.maximum(err, diff.reshape(n, -1).max(axis=1))
        if msg:
            report.append(CaseResult(name, "error", dt, [], {}, msg))
            continue
        tol = np.array([meta["tolerances"][dt][c] for c in category])
        bad = err > tol
        order = np.argsort(-(err - tol), kind="stable")
        worst = []
        for i in order[: max(5, 1)]:
            if not bad[i]:
                break
            worst.append({
                "index": int(i), "category": str(category[i]), "error": float(err[i]), "tolerance": float(tol[i]),
                "comment": str(gold["comment"][i]),
                "inputs": {k: gold[k][i] for k in meta["inputs"]},
                "got": np.asarray(results[keys[0]])[i],  # the first output (the only one in every case)
                "expected": gold[meta["compare"][0]][i],
            })
        per_cat = {}
        for c in CATEGORIES:
            sel = category == c
            if sel.any():
                per_cat[c] = (float(err[sel].max()), float(meta["tolerances"][dt][c]), int(sel.sum()))
        report.append(CaseResult(name, "fail" if bad.any() else "pass", dt, worst, per_cat,
                                 f"{int(bad.sum())} of {n} rows exceed the tolerance" if bad.any() else ""))
    if not any(c.status != "missing" for c in report):
        raise InputError(f"results: no array matches a golden case output ('<case>.<output>'), "
                         f"e.g. {next(iter(sorted(known)))!r}")
    if stray:
        report.append(CaseResult("(results file)", "error", "-", [], {},
                                 f"arrays matching no golden case output: {', '.join(stray[:5])}"))
    return VerifyReport(report)
