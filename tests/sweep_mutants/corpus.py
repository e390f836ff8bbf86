"""One-change mutants of the shipped GLSL ports, each confined to a small region of engine-like input.

Each entry: ``(name, port file, function, case, old text, new text, region)``. The
``LEGITIMATE`` entries are other correct evaluations (fma, rearranged algebra): a sweep
must pass them. tests/test_sweep_mutants.py runs both lists.
"""

_E = "    // Forward substitution L y = (1, zf, zf^2)"
_Y1 = "if (zf <= y1)\n        return 0.0;"
_XI = "float xip = max(xi4 / (gap2 * gap2), 1.17549435e-38);"
_LOWER = ("msm.glsl", "shadow_intensity_lower", "shadow_intensity-lower-float32")
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
]

#: Mutants that passed every golden case under the earlier tolerance rule (16 × the widest deviation) and that
#: the band model (docs/golden.md: the interval of legitimate evaluations plus a margin) now catches on
#: shade-float32's own rows; the sweep still finds them, and the goldens' catch is asserted.
CAUGHT_BY_THE_GOLDENS = {"shade-acne-relative", "shade-acne-relative-3e-5", "shade-faint-weight"}

LEGITIMATE = [
    ("msm-fma-discriminant", "msm.glsl", "shadow_intensity_lower", "shadow_intensity-lower-float32",
     "float disc = sqrt(max(q1 * q1 - 4.0 * q2 * q0, 0.0));", "float disc = sqrt(max(fma(q1, q1, -4.0 * q2 * q0), 0.0));",
     "fma"),
    ("msm-fma-upper", "msm.glsl", "shadow_intensity_upper", "shadow_intensity-upper-float32",
     "float disc = sqrt(max(q1 * q1 - 4.0 * q2 * q0, 0.0));", "float disc = sqrt(max(fma(q1, q1, -4.0 * q2 * q0), 0.0));",
     "fma"),
    ("shade-fma-root", "nonlinear.glsl", "shade", "shade-float32",
     "sqrt(h * h + p)", "sqrt(fma(h, h, p))", "fma"),
]
