"""Row flags: defined once, written to the manifest's ``notes`` table.

Every flag a row carries (the ``flags`` array of a golden file, comma separated)
is a key of :data:`NOTES`, with a description of what is special about the row and
its *effect* on the verdict, as Project Wycheproof's test vectors do.

References
----------
.. [1] HPG17: Christoph Peters. 2017. *Non-Linearly Quantized Moment Shadow Maps*. In Proceedings
       of High Performance Graphics (HPG '17). ACM. The non-linear quantization Φ, Ψ4, Algorithms
       1–3, the texel formats and the compute shader of §4.1.
"""

from __future__ import annotations

__all__ = ["CATEGORIES", "NOTES", "RESULTS", "UNGATED", "UNGATED32", "ROBUSTNESS", "CAUSES", "cause", "register"]

#: The flag of rows beyond the algorithm's contract (:mod:`moments_ref.golden.contract`).
ROBUSTNESS = "robustness"

#: Values of a row's ``result``.
#: The kinds of golden rows (each row's ``category``).
CATEGORIES = ("random", "stiff", "edge")
RESULTS = {
    "valid": "the output must match the expected value within the row's tolerance",
    "acceptable": "more than one answer is right: any code of the row's acceptable set (rounding ties), or "
                  "any finite value in the output's range (rows whose value is undefined)",
}

NOTES = {
    ROBUSTNESS: {
        "description": "beyond the algorithm's contract: an input the published algorithm does not define or an "
                       "engine that follows the paper never hands it (Algorithm 1: unbiased singular moments, "
                       "moments outside the moment space; Algorithm 3: xi4 below the range of Psi4^-1, "
                       "HPG17 §3.2, §3.3); the manifest's 'contract' of the case says which",
        "effect": "counted and shown in its own section ('beyond the algorithm's contract'); never fails the "
                  "verdict unless --strict (strict=True), which gates it like a contract row",
    },
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
        "effect": "robustness row (outside Algorithm 1's contract: the paper biases first); gated only with "
                  "--strict, which holds a port to the exact answer of the unique distribution",
    },
    "shadow_edge": {
        "description": "a 2x2 neighbourhood across a shadow edge (an occluder's depths over a receiver's): the "
                       "sampled moments, and the intensity, change steeply with the filter weights",
        "effect": "gated; the tolerance holds the declared spread of hardware filter weights (sub-texel "
                  "precision, docs/formats.md), which is widest here",
    },
    "weight_grid": {
        "description": "a sub-texel fraction on the 8-bit grid (a multiple of 1/256): a filter with 8 bits of "
                       "sub-texel precision weights with the fraction itself",
        "effect": "gated; with the default 8 bits the tolerance is the rounding of a float32 filter alone",
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
        "effect": "robustness row, result acceptable: ungated (the value is undefined; with --strict the output "
                  "must be finite and in [0, 1])",
    },
    "near_far": {
        "description": "engine case: a mixture of the near and far planes (and a third depth): the moments of a "
                       "distribution on the ends of the depth range, which a bias toward a two-point target on the "
                       "same ends keeps singular",
        "effect": "gated with the deviation of correct biased bounds from the exact Z(z < zf)",
    },
    "cluster": {
        "description": "engine case: depths within 1e-4 or 1e-3 of each other (variance below the bias)",
        "effect": "gated with the deviation of correct biased bounds from the exact Z(z < zf)",
    },
    "footprint": {
        "description": "engine case: the 9×9 Gaussian footprint of 4× MSAA depths from a shipped scene's shadow map "
                       "(HPG17 §4.1)",
        "effect": "gated with the deviation of correct biased bounds from the exact Z(z < zf)",
    },
    "wide_spread": {
        "description": "ill-conditioned row: legitimate evaluations (float32, float64, operations a few ulps off, "
                       "the exact value over the float32 neighbourhood of the input) differ here by more than "
                       "golden.bands.CAP of the output's range",
        "effect": "gated at the whole interval of legitimate values (a correct port never fails it); reported "
                  "apart and never counted as a pass of the port",
    },
    "printed_hazard": {
        "description": "a printed formulation of the papers (the slides' root -p/2 - sqrt(p^2/4 - q), HPG17's "
                       "printed Algorithm 1 or 3, Cholesky from the raw moments without a guard) cancels here in "
                       "float32 beyond golden.bands.CAP of the range, or has no value (NaN)",
        "effect": "the formula does not widen the band: a port that copied it fails this row",
    },
}

#: Flags whose rows are not gated against the expected value (value undefined).
UNGATED = ("outside_moment_space",)

#: Flags whose rows are not gated for float32 ports (undefined at float32 resolution).
UNGATED32 = ("near_support_point",)


#: One line per flag: why rows carrying it fail, for the diagnosis of a failing port.
CAUSES = {
    ROBUSTNESS: "input outside the algorithm's contract (the paper never hands it to this function)",
    "singular_hankel": "unbiased singular moments (one or two depths): outside Algorithm 1's contract; the "
                       "published shader divides by zero here",
    "outside_moment_space": "moments outside the moment space: no distribution has them",
    "bias_floor": "one depth after the float32 bias: variance at the bias floor, where float32 loses digits",
    "near_support_point": "zf at a support point of biased moments: the side of the jump is decided by rounding",
    "support_point": "zf exactly at a support point: the comparison zf <= y (or z < zf) decides the branch",
    "clamp": "a clamp of HPG17 §3.4 applies: the port's clamp offset differs from the declared one, or it "
             "lacks the clamp",
    "fold": "a boundary of the 32-bit triangle fold (HPG17 Figure 5)",
    "code_boundary": "a quantity on a code boundary of a fixed-point field",
    "rounding_tie": "an integer code on a rounding tie",
    "wide_spread": "ill-conditioned row: legitimate evaluations differ beyond the band's cap; the port's value "
                   "lies outside all of them",
    "printed_hazard": "a printed formulation of the papers cancels on this row in float32 (hazard), and your "
                      "result is not its value either: an arithmetic or algorithmic error (where a port copied "
                      "that formula, the verdict says so)",
    "near_far": "near- and far-plane mixture (depths on the ends of the depth range)",
    "cluster": "a tight cluster of depths: variance below the bias",
    "footprint": "a footprint of a shipped scene: an engine's ordinary input",
    "shadow_edge": "a shadow edge across the 2x2 texels: a wrong sample position or weight changes the result most",
    "weight_grid": "a fraction on the 8-bit weight grid: only the filter's rounding is allowed",
}


def register(flag, description, effect, cause=None):
    """Add a flag that one case's rows introduce (its ``Case(notes=...)`` entry in golden/cases.py).

    The flag joins :data:`NOTES` (the manifest's notes table) and, with ``cause``, :data:`CAUSES`
    (the diagnosis's line), so that a new case is one registry entry, not three lists. A flag
    registered twice must say the same thing (``ValueError`` otherwise).
    """
    note = {"description": description, "effect": effect}
    if NOTES.setdefault(flag, note) != note or (cause is not None and CAUSES.setdefault(flag, cause) != cause):
        raise ValueError(f"golden note {flag!r} is registered twice with different text")


def cause(flags, category):
    """The one-line cause of failing rows with ``flags`` (a comma-separated string) in ``category``."""
    names = [f for f in str(flags).split(",") if f]
    for name in names:
        if name in CAUSES and name != ROBUSTNESS:
            return CAUSES[name]
    if ROBUSTNESS in names:
        return CAUSES[ROBUSTNESS]
    return {"random": "ordinary inputs: an arithmetic or algorithmic error",
            "edge": "inputs at the ends of their ranges",
            "stiff": "an ill-conditioned input"}.get(str(category), "")
