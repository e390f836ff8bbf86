"""The docs' figures from random rows that no other command writes, with their sample and interval.

``python -m moments_ref.tools.random_figures`` rewrites the marked blocks of docs/msm6.md:
the share of 2×R10G10B10A2-quantized six-moment vectors (the Slides' storage) inside the
moment space after biasing with each α (:func:`moments_ref.msm6.measure_unorm10_bias`), with the
distribution the vectors are drawn from, their count and each share's 95 % Wilson
interval (:func:`moments_ref.tools.intervals.wilson_interval`); and the largest root error of
the three cubic solvers against mpmath (:func:`moments_ref.msm6.cubic_solver_benchmark`), with
the bound on how often a fresh case exceeds it (:func:`moments_ref.tools.intervals.exceedance_bound`);
and in docs/ports.md the share of random float32 inputs on which SPIR-V's ``FMix``,
``x(1 − a) + ya``, and Mesa's ``x + a(y − x)`` differ, with its Wilson interval.
tests/test_docs.py checks that each block in the docs is what this writes.

References
----------
.. [1] Slides: Christoph Peters. *Rendering antialiased shadows with moment shadow mapping*,
       lecture slides (PDF version, with notes) on moment shadow mapping, translucent occluders,
       moment soft shadow mapping and prefiltered single scattering; http://MomentsInGraphics.de/.
       Cited by slide title, e.g. Slides, "Bias the moments".
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from .._io import write_between
from ..msm6 import cubic_solver_benchmark, measure_unorm10_bias
from .intervals import CONFIDENCE, exceedance_bound, wilson_interval

__all__ = ["UNORM10_MARKERS", "CUBIC_MARKERS", "MIX_MARKERS", "unorm10_block", "cubic_block", "mix_block",
           "rewrite", "main"]

#: The lines between which docs/msm6.md holds the block :func:`unorm10_block` writes.
UNORM10_MARKERS = ("<!-- unorm10-bias: begin -->", "<!-- unorm10-bias: end -->")
#: The lines between which docs/msm6.md holds the block :func:`cubic_block` writes.
CUBIC_MARKERS = ("<!-- cubic-solver: begin -->", "<!-- cubic-solver: end -->")
#: The lines between which docs/ports.md holds the block :func:`mix_block` writes.
MIX_MARKERS = ("<!-- mix-share: begin -->", "<!-- mix-share: end -->")


def unorm10_block(n=4000, seed=0, alphas=(1e-3, 2e-3, 3e-3, 5e-3)):
    """Markdown: per α the share inside the moment space, its count and its Wilson interval."""
    shares = measure_unorm10_bias(alphas, n=n, seed=seed)
    lines = [f"Sample (`python -m moments_ref.tools.random_figures`, seed {seed}): n = {n} distributions of 1 "
             "to 6 depths uniform in [-1, 1] (the count uniform), weights uniform in [0.05, 1] normalised; their "
             "six moments encoded to 2×R10G10B10A2 and decoded, then biased with α towards BIAS6_TARGET. "
             f"Inside: every Hankel pivot positive; {CONFIDENCE:.0%} Wilson interval of the share.", "",
             "| α | inside the moment space | share | 95 % interval |", "|---|---|---|---|"]
    for a, share in shares.items():
        k = int(round(share * n))
        lo, hi = wilson_interval(k, n)
        lines.append(f"| {a:g} | {k} of {n} | {100 * share:.1f} % | {100 * lo:.1f} % to {100 * hi:.1f} % |")
    return "\n".join(lines)


def cubic_block(n=20000, seed=0, reference=200):
    """Markdown: the largest root error of each cubic solver against mpmath, with its exceedance bound."""
    m = cubic_solver_benchmark(n=n, seed=seed, reference=reference)
    k = min(reference, n)
    lines = [f"Sample (`python -m moments_ref.tools.random_figures`, seed {seed}): n = {n} six-moment vectors of 5 "
             "depths uniform in [-1, 1] with weights uniform in [0.05, 1] normalised, biased with BIAS6_FLOAT64, "
             "and a fragment depth zf uniform in [-1, 1]; the kernel's reversed cubic of each, solved in float64. "
             f"The first {k} are compared with `mpmath.polyroots` (40 digits): the largest error of the three "
             f"roots relative to the largest |root|. That is the largest of the sample: with {CONFIDENCE:.0%} "
             f"confidence a fresh case exceeds it with probability at most {exceedance_bound(k):.1%} "
             "(1 − 0.05^(1/n)).", "",
             f"| solver | largest relative error ({k} cases) |", "|---|---|"]
    for key, name in (("closed", "trig-free closed form (two Newton steps)"),
                      ("trig", "trigonometric method (two Newton steps)"),
                      ("eig", "`np.linalg.eigvals` of the companion matrix")):
        lines.append(f"| {name} | {float(m[f'{key}_max_rel_err']):.2g} |")
    return "\n".join(lines)


def mix_block(n=20000, seed=1):
    """Markdown: how often the two expansions of ``mix(x, y, a)`` differ in float32, with its Wilson interval."""
    x, y, a, _ = np.random.default_rng(seed).uniform(-2, 2, (n, 4)).astype(np.float32).T
    fmix = x * (np.float32(1) - a) + y * a  # SPIR-V's FMix, GLSL's definition
    mesa = x + a * (y - x)  # Mesa's GLSL compiler without `precise`
    k = int(np.count_nonzero(fmix.view(np.int32) != mesa.view(np.int32)))
    lo, hi = wilson_interval(k, n)
    return (f"* In float32, `x(1 − a) + ya` and `x + a(y − x)` differ on {k} of {n} random inputs ({100 * k / n:.1f} %; {CONFIDENCE:.0%} Wilson "
            f"interval {100 * lo:.1f} % to {100 * hi:.1f} %; `python -m moments_ref.tools.random_figures`, seed {seed}: "
            "x, y, a uniform in [-2, 2] in float32).")


def rewrite(path, block, markers=UNORM10_MARKERS):
    """Replace the text between ``markers`` in the file ``path`` by ``block`` (atomically); return the path."""
    return write_between(path, markers, f"\n{block}\n")


def main(docs="docs"):
    """Rewrite the generated blocks under ``docs``; return the paths written."""
    path = Path(docs) / "msm6.md"
    return [rewrite(path, unorm10_block()), rewrite(path, cubic_block(), CUBIC_MARKERS),
            rewrite(Path(docs) / "ports.md", mix_block(), MIX_MARKERS)]


if __name__ == "__main__":  # pragma: no cover
    for p in main(*sys.argv[1:2]):
        print(f"wrote {p}")
