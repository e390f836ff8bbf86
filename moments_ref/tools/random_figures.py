"""The docs' figures from random rows that no other command writes, with their sample and interval.

``python -m moments_ref.tools.random_figures`` rewrites the marked block of docs/msm6.md:
the share of 2×R10G10B10A2-quantized six-moment vectors (the Slides' storage) inside the
moment space after biasing with each α (:func:`moments_ref.msm6.measure_unorm10_bias`), with the
distribution the vectors are drawn from, their count and each share's 95 % Wilson
interval (:func:`moments_ref.tools.intervals.wilson_interval`). tests/test_docs.py
checks that the block in the docs is what this writes.

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

from .._io import write_between
from ..msm6 import measure_unorm10_bias
from .intervals import CONFIDENCE, wilson_interval

__all__ = ["UNORM10_MARKERS", "unorm10_block", "rewrite", "main"]

#: The lines between which docs/msm6.md holds the block :func:`unorm10_block` writes.
UNORM10_MARKERS = ("<!-- unorm10-bias: begin -->", "<!-- unorm10-bias: end -->")


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


def rewrite(path, block, markers=UNORM10_MARKERS):
    """Replace the text between ``markers`` in the file ``path`` by ``block`` (atomically); return the path."""
    return write_between(path, markers, f"\n{block}\n")


def main(docs="docs"):
    """Rewrite the generated blocks under ``docs``; return the paths written."""
    return [rewrite(Path(docs) / "msm6.md", unorm10_block())]


if __name__ == "__main__":  # pragma: no cover
    for p in main(*sys.argv[1:2]):
        print(f"wrote {p}")
