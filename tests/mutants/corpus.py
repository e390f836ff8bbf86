"""The mutant corpus: one-change mutants of the independent ports in ``ports.py``.

``kind`` is ``bug`` (a mistake porters make: the oracle must kill it on contract
rows or engine rows), ``legit`` (a legitimate implementation choice: it must pass),
``robustness`` (legitimate on the algorithm's contract, different beyond it: it
passes the verdict and is killed with ``--strict``) or ``equivalent`` (a change
that cannot alter any output: shown so by :func:`fuzz_equivalent`, an exhaustive
or fuzzed bitwise comparison with the unchanged port, not assumed) or ``within_band``
(a change confined to the band of a conformant GPU's legitimate outputs, a texel code on its own
rounding tie, where a correct port may store the same code: shown so by :func:`fuzz_within_band`;
no verdict can tell it from a correct port, so it must pass).

``moments-ref mutants --corpus tests/mutants`` prints the table; the suite
(tests/test_mutants.py) asserts the score.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

try:  # imported as a package (tests) or by path (moments-ref mutants)
    from . import ports, ports_bilinear
except ImportError:  # pragma: no cover
    import ports  # type: ignore
    import ports_bilinear  # type: ignore

#: Golden cases (float32) each port is checked on.
PORT_CASES = {
    "alg1": ["shadow_intensity-lower-float32", "shadow_intensity-upper-float32", "engine-lower-float32",
             "engine-upper-float32"],
    "bias": ["bias_moments-float32-float32", "bias_moments-unorm16-float32"],
    "alg3": ["shade-float32"],
    "psi4": ["psi4-float32"],
    "psi4_inverse": ["psi4_inverse-float32"],
    "pack64": ["pack64-float32", "reencode64-float32"],
    "unpack64": ["unpack64-float32"],
    "pack32": ["pack32-float32", "reencode32-float32"],
    "unpack32": ["unpack32-float32"],
    "msm6": ["shadow_intensity6-lower-float32", "shadow_intensity6-upper-float32"],
    "bilinear": ["sample_bilinear-float32", "shadow_intensity_bilinear-float32"],
}


def run_port(port, case, inputs, kwargs, m):
    """Outputs ``{name: array}`` of ``port`` with mutation ``m`` on a case's inputs."""
    if port == "alg1":
        return {"intensity": ports.alg1(inputs["b"], inputs["zf"], m, bound=kwargs["bound"])}
    if port == "msm6":
        return {"intensity": ports.msm6(inputs["b"], inputs["zf"], m, bound=kwargs["bound"])}
    if port == "bias":
        p = kwargs["preset"]
        return {"b_biased": ports.bias(inputs["b"], p["alpha"], p["target"], m)}
    if port == "alg3":
        return {"intensity": ports.alg3(inputs["r"], inputs["zf"], m)}
    if port == "psi4":
        return {"u": ports.psi4(inputs["xi4"], m)}
    if port == "psi4_inverse":
        return {"xi4": ports.psi4_inverse(inputs["u"], m)}
    if port in ("pack64", "pack32"):
        key = "q" if port == "pack64" else "p"
        return {key: getattr(ports, port)(inputs["r"], m)}
    if port == "unpack64":
        return {"r": ports.unpack64(inputs["q"], m)}
    if port == "unpack32":
        return {"r": ports.unpack32(inputs["p"], m)}
    if port == "bilinear":
        if "zf" in inputs:
            return {"intensity": ports_bilinear.shadow_intensity(inputs["texels"], inputs["fraction"], inputs["zf"], m)}
        return {"b": ports_bilinear.sample(inputs["texels"], inputs["fraction"], m)}
    raise KeyError(port)


@dataclass(frozen=True)
class Mutant:
    name: str
    kind: str  # "bug", "legit", "robustness", "equivalent", "within_band"
    port: str
    change: dict
    why: str
    cases: tuple = field(default=())
    profile_table: tuple = ()  # the engine profile the mutant declares, as sorted TOML items

    def case_names(self):
        return list(self.cases) or PORT_CASES[self.port]

    @property
    def profile(self):
        """The declared conventions (docs/ports.md), or None for the papers' own."""
        if not self.profile_table:
            return None
        from moments_ref.golden.profile import parse_profile

        return parse_profile(_thaw(self.profile_table), self.name)

    def run(self, case, inputs, kwargs):
        return run_port(self.port, case, inputs, kwargs, dict(self.change))


def _freeze(d):
    return tuple(sorted((k, _freeze(v) if isinstance(v, dict) else tuple(v) if isinstance(v, list) else v)
                        for k, v in d.items()))


def _thaw(t):
    return {k: _thaw(v) if isinstance(v, tuple) and v and isinstance(v[0], tuple) else
            list(v) if isinstance(v, tuple) else v for k, v in t}


def _m(name, kind, port, change, why, cases=(), profile=None):
    return Mutant(name, kind, port, change, why, tuple(cases), _freeze(profile or {}))


#: Targets in the [0, 1] convention: the papers' float32 target (0, 0.375, 0, 0.375) mapped exactly, and
#: (0.5, 0.5, 0.5, 0.5) = the moments of ½δ0 + ½δ1, the singular target of the 2015 demo code.
TARGET01 = [0.5, 0.34375, 0.265625, 0.2265625]
SINGULAR01 = [0.5, 0.5, 0.5, 0.5]
#: Found in the wild (docs/ports.md): an engine profile per behaviour.
_HDRP = {"bias": {"alpha": 6e-7, "target": [0.0, 0.628, 0.0, 0.628], "applied": "before"}}
_ENGINE01 = {"depth": "[0,1]", "output": "visibility",
             "bias": {"alpha": 3e-6, "target": TARGET01, "applied": "inside"}}
_SINGULAR = {"depth": "[0,1]", "output": "visibility",
             "bias": {"alpha": 3e-6, "target": SINGULAR01, "applied": "inside"}}
_AUTHOR3 = {"clamp": 5e-6, "clamp_test": "clamped"}


_LEGIT_ARITH = [("fma", {"fma": True}, "fused multiply-add"), ("f64", {"f64": True}, "float64 arithmetic"),
                ("div+3", {"div_ulps": 3}, "every division 3 ulps high"),
                ("div-3", {"div_ulps": -3}, "every division 3 ulps low"),
                ("sqrt+3", {"sqrt_ulps": 3}, "square roots 3 ulps high")]

MUTANTS = [
    _m("port-alg1", "legit", "alg1", {}, "the port as written from HPG17 Algorithm 1"),
    *[_m(f"alg1-{n}", "legit", "alg1", c, w) for n, c, w in _LEGIT_ARITH],
    _m("alg1-recip", "legit", "alg1", {"recip": True}, "p, q by one reciprocal of c2 and two products"),
    _m("alg1-sum-weights", "legit", "alg1", {"sum_weights": True}, "lower bound as w1 + w2 instead of 1 - w0"),
    _m("alg1-swap-bound", "bug", "alg1", {"swap_bound": True}, "upper bound returned for the lower and vice versa"),
    _m("alg1-no-singular", "bug", "alg1", {"no_singular": True},
       "paper-faithful: no singular branch (biased inputs only), the printed formulation: its pivot xi4 rounds to "
       "0 on the sweep's one-depth texel after BIAS_FLOAT32 (0 for 0.99985; issue 37), killed only on the rows "
       "flagged printed_hazard; also divides by zero on unbiased singular B(b), outside the contract"),
    _m("alg1-literal-root", "legit", "alg1", {"literal_root": True},
       "roots as -p/2 ∓ sqrt(p²/4 - q), as the slides and Peters' demo code (HDRP's HDIMS.hlsl) print them"),
    _m("alg1-swap-roots", "bug", "alg1", {"swap_roots": True}, "z1 and z2 swapped (z1 > z2)"),
    _m("alg1-d22-sign", "bug", "alg1", {"d22_sign": True}, "D22 = b2 + b1² (sign error)"),
    _m("alg1-no-l32", "bug", "alg1", {"no_l32": True}, "forward substitution forgets L32 c1"),
    _m("alg1-quarter", "bug", "alg1", {"quarter": True}, "discriminant p²/2 - q instead of p²/4 - q"),
    _m("alg1-le", "robustness", "alg1", {"le": True},
       "z_l <= zf in the lower bound (strict < expected): on positive definite B(b) no root equals zf, so it "
       "differs only at a singular input's support point"),
    _m("alg1-half", "bug", "alg1", {"half": True}, "moments read as float16"),
    _m("alg1-depth01", "bug", "alg1", {"depth01": True}, "fragment depth mapped to [0, 1] (the papers use [-1, 1])"),
    _m("alg1-bias-inside", "bug", "alg1", {"bias_inside": True}, "biases inside Algorithm 1 although the caller did"),
    # Found in the wild, each with the profile its engine declares (docs/ports.md).
    _m("alg1-paper-bias-before", "legit", "alg1", {"literal_root": True, "no_singular": True},
       "paper-faithful Algorithm 1 (the slides' roots, no singular branch) behind its caller's bias "
       "(HDRP's HDIMS.hlsl: alpha 6e-7 toward (0, 0.628, 0, 0.628), applied before)", profile=_HDRP),
    _m("alg1-engine01", "legit", "alg1", {"literal_root": True, "no_singular": True, "visibility": True,
                                          "bias": (3e-6, TARGET01)},
       "a [0, 1]-convention port returning visibility, biasing inside toward the papers' target mapped to [0, 1], "
       "run through its profile", profile=_ENGINE01),
    _m("alg1-singular-target", "bug", "alg1", {"literal_root": True, "no_singular": True, "visibility": True,
                                               "bias": (3e-6, SINGULAR01)},
       "bias toward (0.5, 0.5, 0.5, 0.5) in [0, 1], the moments of ½δ0 + ½δ1 (MJP's MSM.hlsl, Unity's "
       "ShadowMoments.hlsl): near/far-plane mixtures stay singular and shade lit", profile=_SINGULAR),
    _m("alg1-factor-1.03", "bug", "alg1", {"factor": 1.03}, "the bound times 1.03 (a light-leak hack)"),
    _m("alg1-early-exit", "bug", "alg1", {"early_exit": True}, "early exit: receiver at or before the mean b1 is lit"),
    _m("alg1-pivot-floor", "bug", "alg1", {"pivot_floor": 1e-5}, "pivots D22 and D33 floored at 1e-5"),
    _m("alg1-nan-guard", "bug", "alg1", {"cholesky": True, "unclamped": True, "bias": (1e-7, TARGET01)},
       "textbook Cholesky with square roots in a [0, 1] engine biasing by 1e-7 (a point-light setting in the "
       "wild): a pivot that rounds below 0 gives NaN, which the d <= 0 guards let through",
       profile={"depth": "[0,1]", "bias": {"alpha": 1e-7, "target": TARGET01, "applied": "inside"}}),
    _m("alg1-unclamped", "bug", "alg1", {"literal_root": True, "no_singular": True, "unclamped": True},
       "paper-faithful Algorithm 1 without the final saturate: the bound leaves [0, 1]"),

    _m("port-bias", "legit", "bias", {}, "the port as written from HPG17 §3.2"),
    _m("bias-rearranged", "legit", "bias", {"rearranged": True}, "b + alpha (b* - b)"),
    _m("bias-fma", "legit", "bias", {"fma": True}, "fused multiply-add"),
    _m("bias-f64", "legit", "bias", {"f64": True}, "float64 arithmetic"),
    _m("bias-missing", "bug", "bias", {"missing": True}, "biasing left out"),
    _m("bias-target-0628", "bug", "bias", {"target": [0.0, 0.628, 0.0, 0.628]},
       "float32 preset with the 16-bit target 0.628", ["bias_moments-float32-float32"]),
    _m("bias-target-0375", "bug", "bias", {"target": [0.0, 0.375, 0.0, 0.375]},
       "16-bit preset with the float32 target 0.375", ["bias_moments-unorm16-float32"]),
    _m("bias-alpha-6e-5", "bug", "bias", {"alpha": 6e-5}, "alpha of the 16-bit preset for float32 moments",
       ["bias_moments-float32-float32"]),
    _m("bias-sign", "bug", "bias", {"sign": True}, "(1 + alpha) b - alpha b*"),
    _m("bias-odd-target", "bug", "bias", {"target": [0.375, 0.0, 0.375, 0.0]}, "target shifted by one moment"),
    _m("bias-neg-zero-target", "equivalent", "bias", {"target": [-0.0, 0.375, -0.0, 0.375]},
       "target with -0 in the odd moments", ["bias_moments-float32-float32"]),

    _m("port-alg3", "legit", "alg3", {}, "the port as written from HPG17 Algorithm 3 and §3.4"),
    *[_m(f"alg3-{n}", "legit", "alg3", c, w) for n, c, w in _LEGIT_ARITH],
    _m("alg3-gap-pow", "legit", "alg3", {"gap_pow": True}, "(y2 - y1)^4 as four products instead of two squares"),
    _m("alg3-literal-root", "bug", "alg3", {"literal_root": True},
       "z_l = -q1/2 - sqrt(q1²/4 - q0) with the case test zf <= y2: NaN at zf = y2 (q1 = ±inf), saturated to 0 "
       "(its cancellation below y2 is the printed formula's, part of the spread)"),
    _m("alg3-no-v2-clamp", "bug", "alg3", {"no_v2_clamp": True}, "v2 not clamped to [1e-6, 1 - 1e-6]"),
    _m("alg3-no-upper-v2-clamp", "bug", "alg3", {"no_upper_v2_clamp": True}, "v2 clamped below only"),
    _m("alg3-no-gap-clamp", "bug", "alg3", {"no_gap_clamp": True}, "y2 - y1 not clamped to 1e-6"),
    _m("alg3-clamp-1e-5", "bug", "alg3", {"clamp": 1e-5}, "clamp constant 1e-5 instead of 1e-6"),
    _m("alg3-xi-times", "bug", "alg3", {"xi_times": True}, "xi'4 (1 - z)² z² instead of xi'4⁻¹ (the misprint)"),
    _m("alg3-gap-cubed", "bug", "alg3", {"gap_cubed": True}, "xi'4 = xi4 / (y2 - y1)³"),
    _m("alg3-no-early-return", "bug", "alg3", {"no_early_return": True}, "no 'return 0 if zf <= y1'"),
    _m("alg3-lt-y2", "bug", "alg3", {"lt_y2": True}, "case test zf < y2 instead of zf <= y2"),
    _m("alg3-half", "bug", "alg3", {"half": True}, "z'f in float16"),
    _m("alg3-depth01", "bug", "alg3", {"depth01": True}, "fragment depth mapped to [0, 1]"),
    _m("alg3-swap-weights", "bug", "alg3", {"swap_weights": True}, "(1 - v2) and v2 swapped in w_l"),
    _m("alg3-author", "bug", "alg3", {"clamp": 5e-6, "zp_test": True, "literal_root": True, "no_xi_guard": True,
                                      "unclamped": True},
       "the author's demo code: clamps at 5e-6, case test z'f < 1 on the clamped gap, the printed root "
       "-q1/2 - sqrt(q1²/4 - q0), no guard for xi4 = 0, no final clamp; run with its profile. The printed root "
       "cancels: 0.99998 where the exact value is 0.0154 (issue 37)", profile=_AUTHOR3),
    _m("alg3-author-stable-root", "legit", "alg3", {"clamp": 5e-6, "zp_test": True, "no_xi_guard": True,
                                                    "unclamped": True},
       "the author's demo code with the root taken without cancellation: clamps at 5e-6, case test z'f < 1 on the "
       "clamped gap, no guard for xi4 = 0, no final clamp; run with its profile", profile=_AUTHOR3),
    _m("alg3-no-xi-guard", "robustness", "alg3", {"no_xi_guard": True},
       "no guard for xi4 = 0 (division by zero), which no texel decoder produces"),

    _m("port-psi4", "legit", "psi4", {}, "the port as written from HPG17 §3.3"),
    _m("psi4-const32", "legit", "psi4", {"const32": True}, "constants from float32 end points"),
    _m("psi4-f64", "legit", "psi4", {"f64": True}, "float64 arithmetic"),
    _m("psi4-log-sum", "legit", "psi4", {"log_sum": True}, "ln(xi·1e7) as ln xi + ln 1e7"),
    _m("psi4-clamp-1e-7", "equivalent", "psi4", {"clamp": 1e-7},
       "xi4 clamped at 1e-7 instead of 1.2e-7: Psi4 < 0 below 1.2e-7 and the output is clipped to [0, 1]"),
    _m("psi4-log10", "bug", "psi4", {"log10": True}, "outer logarithm base 10"),
    _m("psi4-hi-0.5", "bug", "psi4", {"psi_hi": 0.5}, "upper end 0.5 instead of the proved bound 0.25"),
    _m("psi4-half", "bug", "psi4", {"half": True}, "xi4 in float16"),
    _m("psi4-clamp-order", "equivalent", "psi4", {"clamp_order": True},
       "clamp of xi4 as min(max(.)) instead of max(min(.)) (lo < hi, so the order cannot matter)"),
    _m("port-psi4-inverse", "legit", "psi4_inverse", {}, "the port as written"),
    _m("psi4-inverse-const32", "legit", "psi4_inverse", {"const32": True}, "constants from float32 end points"),
    _m("psi4-inverse-f64", "legit", "psi4_inverse", {"f64": True}, "float64 arithmetic"),
    _m("psi4-inverse-fma", "legit", "psi4_inverse", {"fma": True}, "fused multiply-add"),
    _m("psi4-inverse-exp-once", "bug", "psi4_inverse", {"exp_once": True}, "one exp instead of two"),
    _m("psi4-inverse-swap-c", "bug", "psi4_inverse", {"swap_c": True}, "c0 and c1 swapped"),
    _m("psi4-inverse-lo-1e-7", "bug", "psi4_inverse", {"psi_lo": 1e-7}, "lower end 1e-7 instead of 1.2e-7"),

    _m("port-pack64", "legit", "pack64", {}, "the port as written from HPG17 §3.3"),
    _m("pack64-f64", "legit", "pack64", {"f64": True}, "float64 arithmetic"),
    _m("pack64-floor-depth", "bug", "pack64", {"floor_depth": True}, "depths truncated instead of rounded"),
    # These two differ from the rounded-up code only where 65535 Psi4 lies within float rounding of an integer,
    # inside the Psi4 tie band a conformant GPU's log and exp need (golden.texel_codes.pack64_tie_band): killed
    # while the goldens accepted only the codes of inputs nudged by 8 ulps, which a correct port on such a GPU
    # could fail.
    _m("pack64-round-xi", "within_band", "pack64", {"round_xi": True},
       "Psi4 code rounded to nearest plus the decode check, not rounded up as the format prescribes: the decode "
       "check restores the rounded-up code except within float rounding of the boundary"),
    _m("pack64-no-bump", "within_band", "pack64", {"no_bump": True},
       "no decode check: float rounding can leave the decoded xi4 below the stored one, within float rounding "
       "of the boundary"),
    _m("pack64-swap-y", "bug", "pack64", {"swap_y": True}, "y1 and y2 channels swapped"),
    _m("pack64-nearest-declared", "legit", "pack64", {"round_xi": True, "no_bump": True},
       "Psi4 code rounded to nearest as a UNORM render-target write does (the HPG17 demo), as its profile "
       "declares (format.xi_rounding = nearest)", profile={"format": {"xi_rounding": "nearest"}}),
    _m("pack64-depth01", "bug", "pack64", {"depth01": True}, "depths stored as if in [0, 1]"),
    _m("port-unpack64", "legit", "unpack64", {}, "the port as written"),
    _m("unpack64-f64", "legit", "unpack64", {"f64": True}, "float64 arithmetic"),
    _m("unpack64-recip", "legit", "unpack64", {"recip": True}, "codes times 1/65535"),
    _m("unpack64-const32", "legit", "unpack64", {"const32": True}, "Psi4 constants from float32 end points"),
    _m("unpack64-scale-65536", "bug", "unpack64", {"scale_65536": True}, "codes divided by 65536"),
    _m("unpack64-y-half", "bug", "unpack64", {"y_half": True}, "y = u - 1 instead of 2u - 1"),
    _m("unpack64-v2-square", "bug", "unpack64", {"v2_square": True}, "v2 squared as in the 32-bit format"),

    _m("port-pack32", "legit", "pack32", {}, "the port as written from HPG17 §3.5"),
    _m("pack32-f64", "legit", "pack32", {"f64": True}, "float64 arithmetic"),
    _m("pack32-fold-511", "bug", "pack32", {"fold_511": True}, "fold at 511 instead of 512 (off by one)"),
    _m("pack32-fold-1023", "bug", "pack32", {"fold_1023": True}, "folded y2 = 1023 - y2 instead of 1022 - y2"),
    _m("pack32-round-depth", "bug", "pack32", {"round_depth": True}, "depth cells rounded instead of floored"),
    _m("pack32-no-clip-1023", "bug", "pack32", {"no_clip_1023": True}, "y = 1 stored as cell 1023"),
    _m("pack32-v-linear", "bug", "pack32", {"v_linear": True}, "v2 stored instead of sqrt(v2)"),
    _m("pack32-xi-63", "bug", "pack32", {"xi_63": True}, "Psi4 rounded on 63 steps instead of cells of 1/64"),
    _m("pack32-v-127", "bug", "pack32", {"v_127": True}, "sqrt(v2) rounded on 127 steps instead of cells of 1/128"),
    _m("port-unpack32", "legit", "unpack32", {}, "the port as written"),
    _m("unpack32-f64", "legit", "unpack32", {"f64": True}, "float64 arithmetic"),
    _m("unpack32-recip", "legit", "unpack32", {"recip": True}, "cell ends times 1/511.5"),
    _m("unpack32-mad", "legit", "unpack32", {"mad": True},
       "depths as t·(1/511.5) + (−1 + 2/1023), the HPG17 demo's multiply-add"),
    _m("unpack32-const32", "legit", "unpack32", {"const32": True},
       "Psi4⁻¹ slope from float32 end points (1 ulp off)"),
    _m("unpack32-div+3", "legit", "unpack32", {"div_ulps": 3}, "divisions 3 ulps high"),
    _m("unpack32-no-unfold", "bug", "unpack32", {"no_unfold": True}, "fold not undone"),
    _m("unpack32-unfold-le", "bug", "unpack32", {"unfold_le": True}, "unfold if f2 <= f1 (off by one)"),
    _m("unpack32-corner", "bug", "unpack32", {"corner": True}, "depth at the lower end of its cell, not the upper"),
    _m("unpack32-centre", "bug", "unpack32", {"centre": True},
       "depth at the centre of its cell (the decode before schema 3: over-shadows, docs/formats.md)"),
    _m("unpack32-xi-no-roundup", "bug", "unpack32", {"xi_no_roundup": True}, "xi4 code read at c/64, not rounded up"),
    _m("unpack32-xi-centre", "bug", "unpack32", {"xi_centre": True}, "xi4 code read at (c + 1/2)/64"),
    # Texel-format choices the paper leaves open, declared in the profile (docs/formats.md): legitimate.
    _m("unpack32-centre-declared", "legit", "unpack32", {"centre": True},
       "depths read at the centre of their cell, as its profile declares (format.depth_decode = centre)",
       profile={"format": {"depth_decode": "centre"}}),
    _m("unpack32-xi-centre-declared", "legit", "unpack32", {"xi_centre": True},
       "xi4 code read at (c + 1/2)/64, as its profile declares (format.xi_decode = centre)",
       profile={"format": {"xi_decode": "centre"}}),
    _m("unpack32-v-127", "bug", "unpack32", {"v_127": True}, "sqrt(v2) = c/127 (the grid before schema 3)"),
    _m("unpack32-v-linear", "bug", "unpack32", {"v_linear": True}, "v2 = (c + 1/2)/128 (not squared)"),
    _m("unpack32-step-511", "bug", "unpack32", {"step_511": True}, "cell width 1/511 instead of 1/511.5"),

    _m("port-msm6", "legit", "msm6", {}, "the port as written from the slides (six moments)"),
    _m("msm6-f64", "legit", "msm6", {"f64": True}, "float64 arithmetic"),
    _m("msm6-inverse", "legit", "msm6", {"inverse": True}, "B⁻¹ times the right-hand side instead of a solve"),
    _m("msm6-swap-bound", "bug", "msm6", {"swap_bound": True}, "upper bound for the lower and vice versa"),
    _m("msm6-rhs-zf2", "bug", "msm6", {"rhs_zf2": True}, "right-hand side (1, zf, zf², zf²)"),
    _m("msm6-rhs-sign", "bug", "msm6", {"rhs_sign": True}, "right-hand side (1, -zf, zf², -zf³)"),
    _m("msm6-hankel-shift", "bug", "msm6", {"hankel_shift": True}, "Hankel matrix shifted by one moment"),

    # Bilinear sampling of a moment texture (golden.bilinear): each judged on the sample and on the intensity.
    _m("port-bilinear", "legit", "bilinear", {}, "the port as written: mix along x, then along y, exact weights"),
    _m("bilinear-f64", "legit", "bilinear", {"f64": True}, "float64 arithmetic"),
    _m("bilinear-hand", "legit", "bilinear", {"hand": True},
       "by hand from four loads: (1 - fx)(1 - fy) t00 + fx (1 - fy) t10 + (1 - fx) fy t01 + fx fy t11"),
    _m("bilinear-lerp-delta", "legit", "bilinear", {"lerp_delta": True}, "each lerp as a + w (b - a)"),
    _m("bilinear-weights8-floor", "legit", "bilinear", {"weight_bits": 8},
       "a texture unit with 8 bits of sub-texel precision, position truncated (Vulkan states no rounding rule)"),
    _m("bilinear-weights8-nearest", "legit", "bilinear", {"weight_bits": 8, "weight_round": "nearest"},
       "a texture unit with 8 bits of sub-texel precision, position rounded to nearest (D3D11's reference)"),
    _m("bilinear-weights4-declared", "legit", "bilinear", {"weight_bits": 4},
       "4 bits of sub-texel precision (Vulkan's minimum), as its profile declares (format.subtexel_bits = 4)",
       profile={"format": {"subtexel_bits": 4}}),
    _m("bilinear-weights4", "bug", "bilinear", {"weight_bits": 4},
       "4 bits of sub-texel precision, undeclared (the default profile declares 8)"),
    _m("bilinear-half-texel", "bug", "bilinear", {"half_texel": True},
       "half a texel off: the texel's corner taken for its centre (uv + 0.5 / size)"),
    _m("bilinear-point", "bug", "bilinear", {"point": True}, "a point sampler: the nearest texel, unfiltered"),
    _m("bilinear-swap-xy", "bug", "bilinear", {"swap_xy": True}, "fx and fy swapped"),
    _m("bilinear-swap-weights", "bug", "bilinear", {"swap_weights": True},
       "weights swapped: a w + b (1 - w) instead of a (1 - w) + b w"),
]


def fuzz_equivalent(mutant, n=20000, seed=0):
    """Largest bitwise difference between an ``equivalent`` mutant and its unchanged port on fuzzed inputs.

    Inputs cover the port's whole domain (and beyond it for clamps); 0 means no
    output differs in any bit.
    """
    rng = np.random.default_rng(seed)
    if mutant.port == "bias":
        z = rng.uniform(-1, 1, (n, 4))
        b = np.stack([z, z**2, z**3, z**4], axis=-1).mean(axis=1).astype(np.float32)
        kw = {"preset": {"alpha": 3e-7, "target": [0.0, 0.375, 0.0, 0.375]}}
        inputs = {"b": b}
    elif mutant.port == "pack64":
        y = np.sort(rng.uniform(-1, 1, (n, 2)), axis=1)
        xi = np.concatenate([10 ** rng.uniform(-8, np.log10(0.25), n - 2000), rng.uniform(0, 0.25, 2000)])
        inputs = {"r": np.column_stack([y, rng.uniform(0, 1, n), xi]).astype(np.float32)}
        kw = {}
    elif mutant.port == "psi4":
        inputs = {"xi4": np.concatenate([rng.uniform(0, 1, n), 10 ** rng.uniform(-9, 0, n)]).astype(np.float32)}
        kw = {}
    else:
        raise KeyError(mutant.port)
    a = run_port(mutant.port, None, inputs, kw, {})
    b = mutant.run(None, inputs, kw)
    if mutant.port == "pack64":
        # Up to rounding ties: only rows whose code is stable when xi4 moves by 8 float32 ulps count
        # (the golden accepts either code on a tie, by the same 8-ulp rule).
        stable = np.ones(n, bool)
        for f in (1 + 8 * 2.0**-23, 1 - 8 * 2.0**-23):
            r = inputs["r"].copy()
            r[:, 3] = (r[:, 3].astype(np.float64) * f).astype(np.float32)
            stable &= (run_port("pack64", None, {"r": r}, kw, {})["q"] == a["q"]).all(axis=1)
        return int(np.count_nonzero((a["q"] != b["q"]).any(axis=1) & stable))
    return max(int(np.count_nonzero(a[k].view(np.uint32) != b[k].view(np.uint32))) for k in a)


def fuzz_within_band(mutant, n=20000, seed=0):
    """``(rows that differ, rows outside the band)`` of a ``within_band`` pack64 mutant on fuzzed inputs.

    A row differs where any code differs from the unchanged port's; it is outside the band where a code is
    neither the exact code nor, on that component's own tie (its exact scaled value within
    :func:`moments_ref.golden.texel_codes.pack64_tie_band` of the boundary), the code across it. The inputs are
    :func:`fuzz_equivalent`'s, plus ξ4 placed on code boundaries of Ψ4 (where such mutants act).
    """
    from moments_ref.golden import texel_codes
    from moments_ref.nonlinear import psi4_inverse

    rng = np.random.default_rng(seed)
    y = np.sort(rng.uniform(-1, 1, (n, 2)), axis=1)
    xi = np.concatenate([10 ** rng.uniform(-8, np.log10(0.25), n // 2 - 2000), rng.uniform(0, 0.25, 2000),
                         psi4_inverse(rng.integers(1, 65535, n - n // 2) / 65535.0)])
    r = np.column_stack([y, rng.uniform(0, 1, n), xi]).astype(np.float32)
    a = run_port("pack64", None, {"r": r}, {}, {})["q"].astype(np.int64)
    b = mutant.run(None, {"r": r}, {})["q"].astype(np.int64)
    codes, margins, across = texel_codes.pack64_ties(r)
    band = texel_codes.pack64_tie_band(r)
    ok = (b == codes) | ((b == across) & (margins <= band))
    return int(np.count_nonzero((a != b).any(axis=1))), int(np.count_nonzero(~ok.all(axis=1)))
