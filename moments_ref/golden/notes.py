"""Row flags: defined once, written to the manifest's ``notes`` table.

Every flag a row carries (the ``flags`` array of a golden file, comma separated)
is a key of :data:`NOTES`, with a description of what is special about the row and
its *effect* on the verdict, as Project Wycheproof's test vectors do.

References
----------
HPG17 : see docs/bib.md.
"""

from __future__ import annotations

__all__ = ["NOTES", "RESULTS", "UNGATED", "UNGATED32"]

#: Values of a row's ``result``.
RESULTS = {
    "valid": "the output must match the expected value within the row's tolerance",
    "acceptable": "more than one answer is right: any code of the row's acceptable set (rounding ties), or "
                  "any finite value in the output's range (rows whose value is undefined)",
}

NOTES = {
    "rounding_tie": {
        "description": "an integer output whose code changes within float32 rounding of the inputs or between "
                       "float32 and float64 evaluation: a correct port may land on either side",
        "effect": "result acceptable: any code stored in <output>_acceptable passes (same rule in verify, "
                  "oracle.check and conformance); no harness recomputes the reference",
    },
    "support_point": {
        "description": "zf exactly at a support point of the distribution: Z(z < zf) jumps there; the stored "
                       "float inputs are exact, so the comparison zf <= y (or z < zf) decides the branch",
        "effect": "gated with the row's measured tolerance",
    },
    "near_support_point": {
        "description": "zf at a depth of the distribution whose moments were biased: the support point of the "
                       "biased moments lies within float32 rounding of zf, on either side",
        "effect": "float32 column ungated (the side of the jump is decided by rounding); float64 gated",
    },
    "singular_hankel": {
        "description": "B(b) exactly singular (unbiased moments of one or two depths): the distribution is unique "
                       "and its exact Z(z < zf) is expected; the published shader divides by zero here",
        "effect": "gated: a port must bias first or handle the singular case",
    },
    "bias_floor": {
        "description": "one depth after BIAS_FLOAT32: the variance sits at the bias floor (about 1e-7), where "
                       "float32 loses digits of b2 - b1²",
        "effect": "gated with the measured spread of legitimate float32 implementations",
    },
    "clamp": {
        "description": "a clamp of HPG17 §3.4 applies (v2 to [1e-6, 1 - 1e-6], y2 - y1 to at least 1e-6, "
                       "ξ4 to at least 1.2e-7 in Ψ4), as the decoders produce such representations",
        "effect": "gated: the clamped value is the expected value (the clamps are part of the algorithm)",
    },
    "fold": {
        "description": "a boundary of the 32-bit triangle fold (HPG17 Figure 5): ỹ1 = 511/512, y = ±1, "
                       "ỹ1 = ỹ2 in either half",
        "effect": "gated",
    },
    "code_boundary": {
        "description": "a quantity on or next to a code boundary of a fixed-point field (Ψ4 in 6 or 16 bits, √v2 "
                       "in 7 bits), or every code of a field",
        "effect": "gated (integer outputs there are usually also rounding_tie)",
    },
    "outside_moment_space": {
        "description": "moments just outside the moment space (unbiased, or biased too little to enter it: "
                       "det B(b) < 0): no distribution has them, so the bound is "
                       "not defined and float32 and float64 implementations legitimately disagree by up to 1",
        "effect": "result acceptable: ungated (the output must only be finite and in [0, 1])",
    },
    "wide_spread": {
        "description": "legitimate implementations (float32, float64, operations a few ulps off) differ here by "
                       "0.1 or more: the value is ill-conditioned at this row",
        "effect": "gated at the measured spread (informational flag)",
    },
}

#: Flags whose rows are not gated against the expected value (value undefined).
UNGATED = ("outside_moment_space",)

#: Flags whose rows are not gated for float32 ports (undefined at float32 resolution).
UNGATED32 = ("near_support_point",)
