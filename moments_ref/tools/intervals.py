"""Intervals for figures drawn from random rows: what a sample's quantile and maximum say of its distribution.

A largest error or a percentile over seeded random rows describes the sample, not the
distribution the rows were drawn from. :func:`quantile_interval` gives a
distribution-free confidence interval for a quantile from the sample's order
statistics; :func:`exceedance_bound` says how often a fresh row may exceed the
sample's maximum. ``moments-ref stability`` writes both beside its figures
(docs/stability.md).

References
----------
.. [1] W. J. Conover. 1999. *Practical Nonparametric Statistics*, 3rd ed., Wiley, §3.2: confidence
       intervals for a quantile from order statistics and the binomial distribution.
"""

from __future__ import annotations

import numpy as np

from .._arrays import InputError

__all__ = ["CONFIDENCE", "quantile_interval", "exceedance_bound", "wilson_interval"]

#: Confidence of the intervals the reports state.
CONFIDENCE = 0.95


def quantile_interval(x, q=0.99, confidence=CONFIDENCE):
    """Distribution-free confidence interval ``(lo, hi)`` for the ``q``-quantile of the sampled distribution.

    Order statistics ``x_(l) ≤ x_(u)`` (1-based ranks) with ``P(l ≤ B < u) ≥ confidence``,
    ``B ~ Binomial(n, q)`` the number of draws below the quantile, split evenly between
    the tails. ``hi`` is ``inf`` where ``u > n``: the sample is too small to bound
    the quantile from above (n = 300 cannot for the 99th percentile). ``x`` may hold
    ±inf (an infinite error), not NaN.

    Examples
    --------
    >>> quantile_interval(np.arange(1.0, 301.0), 0.5)
    (133.0, 168.0)
    """
    from scipy.stats import binom

    x = np.sort(np.asarray(x, np.float64).ravel())
    _check(x, q, confidence)
    n, tail = x.size, (1 - confidence) / 2
    lo_rank = int(binom.ppf(tail, n, q))  # P(B < lo_rank) <= tail
    hi_rank = int(binom.ppf(1 - tail, n, q)) + 1  # P(B >= hi_rank) <= tail
    lo = x[lo_rank - 1] if lo_rank >= 1 else -np.inf
    hi = x[hi_rank - 1] if hi_rank <= n else np.inf
    return float(lo), float(hi)


def exceedance_bound(n, confidence=CONFIDENCE):
    """One-sided bound on P(a fresh draw exceeds the largest of ``n``): ``1 − (1 − confidence)^(1/n)``.

    The largest of n independent draws is exceeded by a fresh one with probability
    at most p unless an event of probability (1 − p)^n happened.
    """
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
        raise InputError(f"n: expected a positive integer, got {n!r}")
    _check(np.zeros(1), 0.5, confidence)
    return 1.0 - (1.0 - confidence) ** (1.0 / n)


def wilson_interval(k, n, confidence=CONFIDENCE):
    """The Wilson score interval ``(lo, hi)`` of a share ``k / n`` (Wilson 1927).

    The proportions p whose normal test does not reject ``k / n``:
    ``|k/n − p| ≤ z √(p (1 − p) / n)``, z the two-sided normal quantile of ``confidence``.
    """
    from scipy.stats import norm

    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
        raise InputError(f"n: expected a positive integer, got {n!r}")
    if isinstance(k, bool) or not isinstance(k, (int, np.integer)) or not 0 <= k <= n:
        raise InputError(f"k: expected an integer in [0, n = {n}], got {k!r}")
    _check(np.zeros(1), 0.5, confidence)
    z = float(norm.ppf(0.5 + confidence / 2))
    p = k / n
    half = z * np.sqrt(p * (1 - p) / n + z * z / (4 * n * n))
    c = p + z * z / (2 * n)
    return float(max((c - half) / (1 + z * z / n), 0.0)), float(min((c + half) / (1 + z * z / n), 1.0))


def _check(x, q, confidence):
    if x.size == 0:
        raise InputError("x: expected at least one value, got none")
    nan = np.flatnonzero(np.isnan(x))
    if nan.size:
        raise InputError(f"x: expected numbers, got NaN (first at sorted index {int(nan[0])})")
    for name, v in (("q", q), ("confidence", confidence)):
        if not 0 < float(v) < 1:
            raise InputError(f"{name}: expected a value in (0, 1), got {v!r}")
