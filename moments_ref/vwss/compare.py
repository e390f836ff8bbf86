"""Moved to :mod:`moments_ref.report.vwss`; this old path warns and will be removed in the next release."""

from .._shim import forward

__getattr__, __dir__ = forward('vwss.compare')
