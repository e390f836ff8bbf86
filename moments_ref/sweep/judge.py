"""The sweep's verdict on a row: the goldens' band model (:mod:`moments_ref.golden.bands`).

Everything the sweep knows about right and wrong goes through two functions, so that the
sweep and the goldens judge by one model:

* :func:`legitimate_interval` — per row and output, the interval ``(lo, hi)`` a correct
  port may return (the interval spanned by the legitimate evaluations of the equation,
  widened by the documented margin, capped for bounded outputs), and the ill-conditioned
  rows, which are reported apart and never counted as wrong. No mpmath: it runs on
  chunks of 10^5–10^6 rows.
* :func:`confirm` — a flagged row counts as wrong only when the port's output lies outside
  every exact value (:mod:`moments_ref.precise`) over the float32 neighbourhood of its
  inputs and every legitimate evaluation. A flag that mpmath does not confirm is a defect
  of the tolerance model, never the port's.

Engine cases (``engine-*``) are judged by their own derivation, :func:`moments_ref.golden.engine.derive_engine`,
and confirmed with the exact bounds over the legitimate biases (:mod:`.engine`).
"""

from __future__ import annotations

from ..golden import bands as _bands
from . import engine as _engine

__all__ = ["legitimate_interval", "confirm", "judges_ill"]


def legitimate_interval(case, inputs, port_dtype="float32", contract=None):
    """``(bands, ill_conditioned)`` of the rows: :func:`moments_ref.golden.bands.legitimate_interval`
    (``contract``: the rows inside the case's contract where a profile's conversion decided it)."""
    if _engine.is_engine(case):
        return _engine.interval(case, inputs, port_dtype)
    return _bands.legitimate_interval(case, inputs, port_dtype, contract=contract)


def confirm(case, inputs, got, port_dtype="float32"):
    """``(n,)`` bool, True where mpmath confirms the row wrong: :func:`moments_ref.golden.bands.confirm`."""
    if _engine.is_engine(case):
        return _engine.confirm(case, inputs, got, port_dtype)
    return _bands.confirm(case, inputs, got, port_dtype)


def judges_ill(case):
    """Whether an ill-conditioned row of ``case`` can count as wrong (judged by its neighbourhood): not for the
    engine cases, whose rows flagged ``wide_spread`` by their derivation are reported apart and never wrong."""
    return not _engine.is_engine(case)
