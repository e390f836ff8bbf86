"""One-change mutants of the shipped GLSL ports, each confined to a small region of engine-like input.

Each entry: ``(name, port file, function, case, old text, new text, region)``. The
``LEGITIMATE`` entries are other correct evaluations (fma, rearranged algebra): a sweep
must pass them. tests/test_sweep_mutants.py runs both lists.
"""

_E = "    // Forward substitution L y = (1, zf, zf^2)"
_Y1 = "if (zf <= y1)\n        return 0.0;"
_XI = "float xip = max(xi4 / (gap2 * gap2), 1.17549435e-38);"
_LOWER = ("msm.glsl", "shadow_intensity_lower", "shadow_intensity-lower-float32")
_UPPER = ("msm.glsl", "shadow_intensity_upper", "shadow_intensity-upper-float32")
_W0 = "float w0 = 1.0 / (1.0 + y2 * y2 / sigma2 + y3 * y3 / xi4);"
_RET = "return (zf <= y2) ? wl : 1.0 - wl;"
_SHADE = ("nonlinear.glsl", "shade", "shade-float32")

MUTANTS = [
    ("msm-acne-relative", *_LOWER, "float l = (zf <= z1) ? 0.0", "float l = (zf <= z1 + 1e-4 * (z2 - z1)) ? 0.0",
     "receivers just behind the first support point"),
    ("msm-acne-relative-3e-4", *_LOWER, "float l = (zf <= z1) ? 0.0", "float l = (zf <= z1 + 3e-4 * (z2 - z1)) ? 0.0",
     "receivers just behind the first support point"),
    ("msm-acne-relative-upper", "msm.glsl", "shadow_intensity_upper", "shadow_intensity-upper-float32",
     "float l = (zf <= z1) ? 0.0", "float l = (zf <= z1 + 1e-4 * (z2 - z1)) ? 0.0",
     "receivers just behind the first support point (upper bound)"),
    ("msm-acne-relative-upper-3e-4", "msm.glsl", "shadow_intensity_upper", "shadow_intensity-upper-float32",
     "float l = (zf <= z1) ? 0.0", "float l = (zf <= z1 + 3e-4 * (z2 - z1)) ? 0.0",
     "receivers just behind the first support point (upper bound)"),
    ("msm-acne-relative-3e-5", *_LOWER, "float l = (zf <= z1) ? 0.0", "float l = (zf <= z1 + 3e-5 * (z2 - z1)) ? 0.0",
     "receivers just behind the first support point"),
    ("msm-chebyshev-3-sigma", *_LOWER, _E, "    if (zf < b.x - 3.0 * sqrt(sigma2)) { lower = 0.0; upper = 0.0; return; }\n" + _E,
     "faint occluders far in front of the mean"),
    ("msm-chebyshev-4-sigma", *_LOWER, _E, "    if (zf < b.x - 4.0 * sqrt(sigma2)) { lower = 0.0; upper = 0.0; return; }\n" + _E,
     "faint occluders far in front of the mean"),
    ("shade-acne-relative", *_SHADE, _Y1, "if (zf <= y1 + 1e-4 * (y2 - y1))\n        return 0.0;",
     "receivers just behind y1"),
    ("shade-acne-relative-3e-5", *_SHADE, _Y1, "if (zf <= y1 + 3e-5 * (y2 - y1))\n        return 0.0;",
     "receivers just behind y1"),
    ("shade-xi4-floor-1e-8", *_SHADE, _XI, "float xip = max(xi4 / (gap2 * gap2), 1.0e-8);", "nearly two-point texels"),
    ("shade-xi4-floor-3e-8", *_SHADE, _XI, "float xip = max(xi4 / (gap2 * gap2), 3.0e-8);", "nearly two-point texels"),
    ("shade-faint-weight", *_SHADE, "return (zf <= y2) ? wl : 1.0 - wl;",
     "return (zf <= y2) ? (wl < 1e-4 ? 0.0 : wl) : 1.0 - wl;", "faint occluders (w_l below 1e-4 dropped)"),
    ("shade-one-sided-early-out", *_SHADE, "    // z'f := (zf - y1)",
     "    if (zf < y1 + 1e-3 * (y2 - y1) && v2 > 0.999) return 0.0;\n    // z'f := (zf - y1)",
     "v2 within 1e-3 of 1, receivers just behind y1"),
    # Round two: the golden edge rows from the sweep (golden._rows, "sweep:") catch the mutants above; these sit in
    # the regions those rows leave: fainter occluders, receivers just behind y2, xi4 guards of the upper bound.
    *[(f"msm-chebyshev-{k}-sigma", *_LOWER, _E,
       f"    if (zf < b.x - {k}.0 * sqrt(sigma2)) {{ lower = 0.0; upper = 0.0; return; }}\n" + _E,
       "fainter occluders far in front of the mean") for k in (5, 8, 12)],
    *[(f"msm-w0-xi4-floor-upper-{c}", *_UPPER, _W0, _W0.replace("y3 * y3 / xi4", f"y3 * y3 / max(xi4, {c})"),
       "nearly two-point texels, receivers at a depth (upper bound)") for c in ("3e-8", "5e-8")],
    *[(f"shade-acne-y2-{c}", *_SHADE, _RET, f"return (zf <= y2 + {c} * (y2 - y1)) ? wl : 1.0 - wl;",
       "receivers just behind y2") for c in ("3e-7", "1e-7", "5e-8", "2e-8")],
    # Round five: an encoder one code off in v2 near 0 and 1 (Algorithm 3's clamp of v2 applied in the encoder, with
    # the offset 1/65535): the per-row tie rule let it through on every row whose nearest component was on a tie
    # (96 % of the sweep's pack64 rows); the per-component rule (golden.texel_codes) catches it (:data:`TIE_RULE`).
    ("pack64-v2-clamp-1/65535", "packing.glsl", "pack64", "pack64-float32", "clamp(r.z, 0.0, 1.0)",
     "clamp(r.z, 1.0 / 65535.0, 1.0 - 1.0 / 65535.0)", "v2 within 1/65535 of 0 or 1 (one code off)"),
    # Round five: y1 rounded with a biased offset, one code off where frac(65535 (y1 + 1)/2) lies in [0.5, 0.6)
    # (+ 0.4) or [0.4, 0.5) (+ 0.6), at most 0.1 code from the boundary: the former tie band (a quarter code)
    # accepted every such code; the band derived from the formula (golden.texel_codes.pack64_tie_band, 0.055 code
    # for y) catches them where they lie beyond it (:data:`TIE_BAND_MUTANTS`). Measured (seed 0, chunk 0, llvmpipe):
    # + 0.4 flags 6 021 of 131 072 rows, the first at row 67, shrunk to r = (-0.71973580, 0.99184334, 0.69772303,
    # 7.1891397e-4); + 0.6 flags 6 119, the first at row 75, shrunk to r = (0.40936702, 0.77635610, 0.95118123,
    # 4.3492764e-7). The quarter code flagged none. The goldens catch both, before (12 and 15 rows failed: their
    # stored codes were the reference's on nudged inputs) and after (4 and 6 rows: they store the derived band).
    *[(f"pack64-y1-round-bias-{c}", "packing.glsl", "pack64", "pack64-float32", "uint(roundEven(s0))",
       f"uint(floor(s0 + {c}))", "y1 within 0.1 code of a rounding boundary") for c in ("0.4", "0.6")],
]

#: Encoder mutants within a quarter code of their boundaries: the former tie band (TIE_BAND, 2⁻¹⁸ of the range)
#: accepts every row of them, the derived band (golden.texel_codes) catches them; tests/test_sweep_mutants.py judges
#: one chunk under both.
TIE_BAND_MUTANTS = ["pack64-y1-round-bias-0.4", "pack64-y1-round-bias-0.6"]

#: Mutants of the encoders whose one-code-off rows sit mostly on rows another component's tie made acceptable under
#: the former per-row tie rule: tests/test_sweep_mutants.py sweeps them under both rules.
TIE_RULE = ["pack64-v2-clamp-1/65535"]

#: Mutants the goldens catch, asserted (the sweep still finds them): three that passed every golden case under the
#: earlier tolerance rule (16 × the widest deviation) and that the band model (docs/golden.md) catches on
#: shade-float32's own rows; and those the goldens' edge rows from the sweep's shrunk failures catch
#: (:data:`EDGE_ROWS_CATCH`).
CAUGHT_BY_THE_GOLDENS = {"shade-acne-relative", "shade-acne-relative-3e-5", "shade-faint-weight",
                         "msm-acne-relative", "msm-acne-relative-3e-4", "msm-acne-relative-upper",
                         "msm-acne-relative-upper-3e-4", "msm-acne-relative-3e-5", "msm-chebyshev-3-sigma",
                         "msm-chebyshev-4-sigma", "shade-xi4-floor-3e-8", "shade-one-sided-early-out",
                         "pack64-v2-clamp-1/65535", "pack64-y1-round-bias-0.4", "pack64-y1-round-bias-0.6"}

#: Each golden edge row from the sweep (case, the start of its comment) and a mutant of this corpus that the goldens
#: missed before that row was added and that fails it (tests/test_sweep_mutants.py).
EDGE_ROWS_CATCH = [
    ("shadow_intensity-lower-float32", "sweep: one depth -0.006", "msm-acne-relative-3e-5"),
    ("shadow_intensity-upper-float32", "sweep: one depth -0.006", "msm-acne-relative-upper"),
    ("shadow_intensity-lower-float32", "sweep: a faint occluder", "msm-chebyshev-4-sigma"),
    ("shade-float32", "sweep: a nearly two-point texel", "shade-xi4-floor-3e-8"),
    ("shade-float32", "sweep: v2 within 1e-3 of 1", "shade-one-sided-early-out"),
]

LEGITIMATE = [
    ("msm-fma-discriminant", "msm.glsl", "shadow_intensity_lower", "shadow_intensity-lower-float32",
     "float disc = sqrt(max(q1 * q1 - 4.0 * q2 * q0, 0.0));", "float disc = sqrt(max(fma(q1, q1, -4.0 * q2 * q0), 0.0));",
     "fma"),
    ("msm-fma-upper", "msm.glsl", "shadow_intensity_upper", "shadow_intensity-upper-float32",
     "float disc = sqrt(max(q1 * q1 - 4.0 * q2 * q0, 0.0));", "float disc = sqrt(max(fma(q1, q1, -4.0 * q2 * q0), 0.0));",
     "fma"),
    ("shade-fma-root", "nonlinear.glsl", "shade", "shade-float32",
     "sqrt(h * h + p)", "sqrt(fma(h, h, p))", "fma"),
    # The encoders' legitimate formulations, within the derived tie band (golden.texel_codes): y1 scaled by one fma,
    # y·0.5 + 0.5 (the [0, 1] value an UNORM16 target receives) then scaled, and round half up for roundEven.
    ("pack64-fma-y1", "packing.glsl", "pack64", "pack64-float32", "precise float s0 = (r.x + 1.0) * 0.5 * 65535.0;",
     "float s0 = fma(r.x, 32767.5, 32767.5);", "fma"),
    ("pack64-unorm-y1", "packing.glsl", "pack64", "pack64-float32", "precise float s0 = (r.x + 1.0) * 0.5 * 65535.0;",
     "float s0 = (r.x * 0.5 + 0.5) * 65535.0;", "y·0.5 + 0.5 in [0, 1], then scaled"),
    ("pack64-round-half-up-v2", "packing.glsl", "pack64", "pack64-float32", "uint(roundEven(s2))",
     "uint(floor(s2 + 0.5))", "round half up"),
]
