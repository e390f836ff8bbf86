"""The differential sweep: a port judged on millions of engine-like rows.

:mod:`.samplers` draws engine-like rows per chunk, :mod:`.judge` holds the verdict
(the golden spread model, vectorised, and mpmath confirmation), :mod:`.runner` runs the
chunks in-process, in spawned workers or on a Dask cluster, :mod:`.shrink` turns each
distinct failure into one small row and writes it as a golden folder, and
:mod:`.command` is ``moments-ref sweep``. docs/sweep.md describes the distributions.
"""

from .samplers import CHUNK, STRATA, draw_chunk, sweepable
from .runner import Port, SweepSpec, run_chunks
from .result import SweepResult, sweep_port

__all__ = ["CHUNK", "STRATA", "draw_chunk", "sweepable", "Port", "SweepSpec", "run_chunks", "SweepResult", "sweep_port"]
