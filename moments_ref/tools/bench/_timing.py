"""Same-run ratios that hold still: a kernel interleaved with its baseline, one ratio per pair.

A machine's speed drifts (frequency, neighbours, the memory bus), so two medians taken
at different moments differ by more than the kernels do: one run measured a 64 MiB
copy at 0.022 s and the next at 0.0117 s. Here every sample of the kernel is taken
right after a sample of its baseline (baseline, kernel, baseline, kernel, ...) and the
ratio is formed per pair; the median of the pair ratios is the figure, their
quartiles its spread. A target is marked pass or miss only when the whole spread lies
on one side of the limit (:meth:`Ratio.mark`); otherwise it is "undecided (noisy)".

Times are CPU seconds of this process (``time.process_time``): on a shared machine
wall time mostly measures the neighbours. A callable that returns a dict
``{"cpu", "wall"}`` (the llvmpipe worker, which times itself) reports its own times; it is
repeated within a sample like any other call (a 2048² railing draw takes 30 ms, so one
draw alone is too short a sample to hold still).
"""

from __future__ import annotations

import statistics
import time
from dataclasses import dataclass

import numpy as np

__all__ = ["Ratio", "paired", "sample", "calibrate", "PAIRS", "LEAST"]

#: Pairs per ratio (an odd count: the median is a measured pair).
PAIRS = 9
#: Shortest sample in seconds: a quicker call is repeated within one sample (one CPU-time
#: reading has a resolution of about a millisecond; a 64 MiB copy takes a few, and its
#: bandwidth moves from one copy to the next: 0.05 s samples left ratios 20 % apart
#: from one run to the next).
LEAST = 0.1


@dataclass(frozen=True)
class Ratio:
    """The median of per-pair ratios kernel / baseline, with the quartiles as its spread."""

    median: float
    low: float  # first quartile of the pair ratios
    high: float  # third quartile
    kernel: float  # median CPU seconds per call of the kernel
    baseline: float  # median CPU seconds per call of the baseline
    kernel_wall: float
    baseline_wall: float
    pairs: int

    @property
    def spread(self):
        """Relative half-width of the quartile range: (high - low) / (2 median)."""
        return (self.high - self.low) / (2 * self.median) if self.median > 0 else float("inf")

    def mark(self, limit):
        """``pass`` when the whole quartile range is at or below ``limit``, ``miss`` when above, else undecided."""
        if self.high <= limit:
            return "pass"
        if self.low > limit:
            return "miss"
        return "undecided (noisy)"


def calibrate(fn, least=LEAST):
    """Calls per sample so that one sample lasts about ``least`` seconds (after one warm-up call)."""
    c0 = time.process_time()
    got = fn()
    took = got["cpu"] if isinstance(got, dict) else time.process_time() - c0
    return min(64, max(1, int(least / max(took, 1e-6))))


def sample(fn, loops):
    """``(cpu, wall)`` seconds per call over ``loops`` calls (or the times ``fn`` reports itself)."""
    c0, t0 = time.process_time(), time.perf_counter()
    own = []  # times a call reports of its own (another process's), not its results
    for _ in range(loops):
        got = fn()
        if isinstance(got, dict):
            own.append(got)
        del got  # a kernel's result is freed before the next call, as in a single call
    if own:
        return sum(g["cpu"] for g in own) / loops, sum(g["wall"] for g in own) / loops
    return (time.process_time() - c0) / loops, (time.perf_counter() - t0) / loops


def paired(kernel, baseline, pairs=PAIRS, least=LEAST):
    """Interleave ``baseline`` and ``kernel`` ``pairs`` times; the ratio kernel / baseline per pair.

    Returns
    -------
    Ratio
    """
    lk, lb = calibrate(kernel, least), calibrate(baseline, least)
    ks, bs = [], []
    for _ in range(max(1, pairs)):
        bs.append(sample(baseline, lb))
        ks.append(sample(kernel, lk))
    r = np.array([k[0] / max(b[0], 1e-12) for k, b in zip(ks, bs)])
    q1, med, q3 = (float(x) for x in np.quantile(r, [0.25, 0.5, 0.75]))
    return Ratio(med, q1, q3, statistics.median(k[0] for k in ks), statistics.median(b[0] for b in bs),
                 statistics.median(k[1] for k in ks), statistics.median(b[1] for b in bs), len(r))
