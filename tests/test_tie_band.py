"""The encoders' tie band (golden.texel_codes.pack64_tie_band, pack32_tie_band) bounds every legitimate float32
encoder: brute force over the float32 neighbourhood of the input, the printed formulations with and without fma, and
a GPU's log off by the most GLSL/Vulkan allow, each compared with the exact scaled value (float64, 10⁻¹⁰ code)."""

from __future__ import annotations

import math

import numpy as np

from moments_ref.golden import bands, texel_codes

F32 = np.float32
_C0 = math.log(math.log(1.2))
_C1 = math.log(math.log(0.25e7)) - _C0


def _neighbourhood(x, ulps=texel_codes.INPUT_ULPS):
    """float32 points within ``ulps`` ulps of float64 ``x`` (rounded to float32 first, then stepped)."""
    x32 = x.astype(F32)
    out = [x32]
    for _ in range(ulps):
        out = [np.nextafter(p, F32(np.inf)) for p in out[:1]] + out + [np.nextafter(p, F32(-np.inf)) for p in out[-1:]]
    return out


def _fma(a, b, c):
    """float32 fma: the product of two float32 values is exact in float64 (48 bits), one rounding of the sum."""
    return (a.astype(np.float64) * np.float64(b) + np.float64(c)).astype(F32)


def _affine_formulations(x, a, b):
    """float32 evaluations of a·x + b: multiply-add with and without fma, (x + b/a)·a, and each + 0.5 − 0.5 (a
    floor(s + 0.5) rounding), as float64 for the comparison."""
    a32, b32 = F32(a), F32(b)
    forms = [x * a32 + b32, _fma(x, a, b), (x + F32(b / a)) * a32, (x * F32(0.5) + F32(0.5)) * F32(2 * a)
             if b == a else x * a32]
    out = []
    for s in forms:
        out += [s.astype(np.float64), (s + F32(0.5)).astype(np.float64) - 0.5]
    return out


def _worst(exact, evaluations):
    return np.max([np.abs(e - exact) for e in evaluations], axis=0)


def test_the_y_and_v2_bands_bound_every_legitimate_float32_encoder():
    rng = np.random.default_rng(7)
    y, v2 = rng.uniform(-1, 1, 20000), rng.uniform(0, 1, 20000)
    r = np.c_[y, y, v2, np.full(len(y), 1e-3)]
    bound64 = texel_codes.pack64_tie_band(r) * 65535 / texel_codes.SAFETY
    bound32 = texel_codes.pack32_tie_band(r) * np.array([1023, 1023, 128, 64]) / texel_codes.SAFETY
    dev_y = np.max([_worst(32767.5 * (y + 1), _affine_formulations(p, 32767.5, 32767.5)) for p in _neighbourhood(y)],
                   axis=0)
    dev_v = np.max([_worst(65535 * v2, _affine_formulations(p, 65535.0, 0.0)) for p in _neighbourhood(v2)], axis=0)
    dev_y32 = np.max([_worst(511.5 * (y + 1), _affine_formulations(p, 511.5, 511.5)) for p in _neighbourhood(y)],
                     axis=0)
    sq = [np.sqrt(p) * F32(128) for p in _neighbourhood(v2)]
    dev_sq = np.max([np.abs(s.astype(np.float64) * (1 + k * 2.0**-23) - 128 * np.sqrt(v2))  # sqrt a few ulps off
                     for s in sq for k in (-texel_codes.SQRT_ULPS, texel_codes.SQRT_ULPS)], axis=0)
    for dev, bound in ((dev_y, bound64[:, 0]), (dev_v, bound64[:, 2]), (dev_y32, bound32[:, 0]),
                       (dev_sq, bound32[:, 2])):
        assert np.all(dev <= bound)
        assert dev.max() >= 0.2 * bound.max()  # the bound is not loose beyond its derivation's rounding count
    assert bound64[0, 0] * texel_codes.SAFETY < 0.1  # never the former quarter code
    assert texel_codes.INPUT_ULPS == bands.PERTURB_ULPS


def _gpu_log(x, sign):
    """float32 log off by the most GLSL 4.30 / Vulkan allow: 3 ulp, or 2⁻²¹ absolutely for x in [0.5, 2]."""
    v = np.log(x.astype(np.float64))
    step = np.where((x >= 0.5) & (x <= 2), 2.0**-21, 3 * np.spacing(np.abs(v).astype(F32)).astype(np.float64))
    return (v + sign * step).astype(F32)


def test_the_psi4_band_bounds_a_gpu_log_off_by_the_most_allowed():
    rng = np.random.default_rng(8)
    xi = np.concatenate([10 ** rng.uniform(np.log10(1.2e-7), np.log10(0.25), 20000), 1.2e-7 * (1 + 2.0**-20 *
                                                                                               np.arange(1, 200))])
    r = np.c_[np.zeros((len(xi), 3)), xi]
    bound = texel_codes.pack64_tie_band(r)[:, 3] * 65535 / texel_codes.SAFETY
    exact = 65535 * (np.log(np.log(xi * 1e7)) - _C0) / _C1
    c0, inv_c1 = F32(_C0), F32(1 / _C1)
    devs = []
    for p in _neighbourhood(xi):
        for s_in in (-1, 1):
            for s_out in (-1, 1):
                u = (_gpu_log(_gpu_log(p * F32(1e7), s_in), s_out) - c0) * inv_c1 * F32(65535)
                devs.append(np.abs(u.astype(np.float64) - exact))
    dev = np.max(devs, axis=0)
    assert np.all(dev <= bound)
    assert dev.max() >= 0.3 * bound.max()


def test_the_sweeps_extra_tie_codes_lie_within_the_derived_band():
    """``bands.tie_accepted`` also accepts the reference's codes in float32, float64 and on inputs nudged by 8 eps
    (``bands.tie_codes``); the goldens of these cases store only the rule's codes. Both accept one set: every such
    code is, per component, the exact code or the one across that component's own tie."""
    from moments_ref.golden.cases import CASES

    rng = np.random.default_rng(9)
    r = np.c_[np.sort(rng.uniform(-1, 1, (4000, 2)), axis=1), rng.uniform(0, 1, 4000), 10 ** rng.uniform(-7, -0.6, 4000)]
    for name, ties in (("pack64-float32", texel_codes.pack64_ties), ("pack32-float32", texel_codes.pack32_ties)):
        case = CASES[name]
        extra = bands.tie_codes(case, {"r": r.astype(F32)})
        codes, _, across = ties(r.astype(F32))
        if name.startswith("pack32"):
            from moments_ref.golden.texel_truth import fold32

            allowed = [fold32(np.where([[(m >> i) & 1 for i in range(4)]], across, codes)) for m in range(16)]
        else:
            allowed = [codes, across]
        differs = False
        for t in extra:
            got = np.asarray(t[0]).astype(np.int64).reshape(len(r), -1)
            ok = np.zeros(got.shape, bool)
            for a in allowed:
                ok |= got == np.asarray(a, np.int64).reshape(len(r), -1)
            assert ok.all(), name
            differs |= bool((got != np.asarray(allowed[0], np.int64).reshape(len(r), -1)).any())
        assert differs, name  # the extra codes hold ties: the test is not vacuous
