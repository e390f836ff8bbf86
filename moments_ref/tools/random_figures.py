"""The docs' figures from random rows that no other command writes, with their sample and interval.

``python -m moments_ref.tools.random_figures`` rewrites the marked blocks of docs/msm6.md:
the share of 2×R10G10B10A2-quantized six-moment vectors (the Slides' storage) inside the
moment space after biasing with each α (:func:`moments_ref.msm6.measure_unorm10_bias`), with the
distribution the vectors are drawn from, their count and each share's 95 % Wilson
interval (:func:`moments_ref.tools.intervals.wilson_interval`); and the largest root error of
the three cubic solvers against mpmath (:func:`moments_ref.msm6.cubic_solver_benchmark`), with
the bound on how often a fresh case exceeds it (:func:`moments_ref.tools.intervals.exceedance_bound`);
the worst excess of the float32 six-moment bounds over the true Z on stiff cases for each α,
with the same bound;
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
from ..moments import BiasPreset, bias_moments, power_moments
from ..msm6 import BIAS6_FLOAT32, BIAS6_TARGET, cubic_solver_benchmark, measure_unorm10_bias, shadow_bounds
from .intervals import CONFIDENCE, exceedance_bound, wilson_interval

__all__ = ["UNORM10_MARKERS", "CUBIC_MARKERS", "STIFF_MARKERS", "MIX_MARKERS", "unorm10_block", "cubic_block",
           "stiff_cases", "stiff_block", "mix_block", "rewrite", "main"]

#: The lines between which docs/msm6.md holds the block :func:`unorm10_block` writes.
UNORM10_MARKERS = ("<!-- unorm10-bias: begin -->", "<!-- unorm10-bias: end -->")
#: The lines between which docs/msm6.md holds the block :func:`cubic_block` writes.
CUBIC_MARKERS = ("<!-- cubic-solver: begin -->", "<!-- cubic-solver: end -->")
#: The lines between which docs/msm6.md holds the block :func:`stiff_block` writes.
STIFF_MARKERS = ("<!-- stiff-bracket: begin -->", "<!-- stiff-bracket: end -->")
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
    return (f"* In float32, `x(1 − a) + ya` and `x + a(y − x)` differ on {k} of {n} random inputs "
            f"({100 * k / n:.1f} %; {CONFIDENCE:.0%} Wilson interval {100 * lo:.1f} % to {100 * hi:.1f} %; "
            f"`python -m moments_ref.tools.random_figures`, seed {seed}: "
            "x, y, a uniform in [-2, 2] in float32).")


def stiff_cases(n=4000, seed=0):
    """Stiff six-moment inputs: ``(z, w, zf)``, float32 depths ``(n, 6)``, weights ``(n, 6)``, ``zf`` ``(n, 18)``.

    Per case 1 to 6 depths (the count uniform), clustered: a centre uniform in [-1, 1], or
    at −1 or 1 (a third of the cases), plus an offset of magnitude 10^u, u uniform in
    [-7, -1], clamped to [-1, 1] and rounded to float32; weights uniform in [0.05, 1]
    normalised (zero beyond the count). ``zf``: every depth slot and its two float32
    neighbours, clamped to [-1, 1] (slots beyond the count repeat the first depth).
    """
    rng = np.random.default_rng(seed)
    k = rng.integers(1, 7, n)
    used = np.arange(6) < k[:, None]
    centre = np.where(rng.uniform(0, 1, n) < 1 / 3, rng.choice([-1.0, 1.0], n), rng.uniform(-1, 1, n))
    offset = 10.0 ** rng.uniform(-7, -1, (n, 1)) * rng.uniform(-1, 1, (n, 6))
    z = np.clip(centre[:, None] + offset, -1, 1).astype(np.float32)
    z = np.where(used, z, z[:, :1])
    w = rng.uniform(0.05, 1, (n, 6)) * used
    w /= w.sum(axis=1, keepdims=True)
    zf = np.stack([np.nextafter(z, np.float32(-2)), z, np.nextafter(z, np.float32(2))], axis=-1).reshape(n, 18)
    return z, w, np.clip(zf, np.float32(-1), np.float32(1))


def stiff_block(n=4000, seed=0, alphas=(3e-7, 1e-5, 1e-4, BIAS6_FLOAT32.alpha, 1e-3)):
    """Markdown: per α the worst excess of the float32 six-moment bounds over the true Z on stiff cases."""
    z, w, zf = stiff_cases(n, seed)
    b = power_moments(z.astype(np.float64), w, n=6).astype(np.float32)
    z_lt = (w[:, :, None] * (z[:, :, None] < zf[:, None, :])).sum(axis=1)  # Z(z < zf), exact
    z_le = (w[:, :, None] * (z[:, :, None] <= zf[:, None, :])).sum(axis=1)  # Z(z ≤ zf)
    lines = [f"Sample (`python -m moments_ref.tools.random_figures`, seed {seed}): n = {n} stiff cases "
             "(:func:`moments_ref.tools.random_figures.stiff_cases`: 1 to 6 depths, the count uniform, clustered "
             "within 10^u of a centre, u uniform in [-7, -1], the centre uniform in [-1, 1] or at ±1 in a third "
             "of the cases; weights uniform in [0.05, 1] normalised), zf at every depth and at its two float32 "
             f"neighbours, clamped to [-1, 1] ({zf.shape[1]} per case); moments in float32, biased with α towards "
             "BIAS6_TARGET, "
             "bounds by `msm6.shadow_bounds` in float32. Each figure is the largest over the sample: with "
             f"{CONFIDENCE:.0%} confidence a fresh case's worst exceeds it with probability at most "
             f"{exceedance_bound(n):.2%} (1 − 0.05^(1/n)).", "",
             "| α | worst lower − Z(z < zf) | worst Z(z ≤ zf) − upper |", "|---|---|---|"]
    for a in alphas:
        bb = bias_moments(b, BiasPreset(a, BIAS6_TARGET))
        lower, upper = shadow_bounds(bb[:, None, :], zf)
        lo_excess = float((lower - z_lt).max())
        up_excess = float((z_le - upper).max())
        lines.append(f"| {a:g} | {_figure(lo_excess)} | {_figure(up_excess)} |")
    return "\n".join(lines)


def _figure(x):
    return f"{x:.2g}" if abs(x) >= 0.01 or x == 0 else f"{x:.1e}"


def rewrite(path, block, markers=UNORM10_MARKERS):
    """Replace the text between ``markers`` in the file ``path`` by ``block`` (atomically); return the path."""
    return write_between(path, markers, f"\n{block}\n")


def main(docs="docs"):
    """Rewrite the generated blocks under ``docs``; return the paths written."""
    path = Path(docs) / "msm6.md"
    return [rewrite(path, unorm10_block()), rewrite(path, cubic_block(), CUBIC_MARKERS),
            rewrite(path, stiff_block(), STIFF_MARKERS),
            rewrite(Path(docs) / "ports.md", mix_block(), MIX_MARKERS)]


if __name__ == "__main__":  # pragma: no cover
    for p in main(*sys.argv[1:2]):
        print(f"wrote {p}")
