"""Rows per second of each stage of the sweep, for ``moments-ref bench`` (section "Sweep")."""

from __future__ import annotations

import time

from .runner import STAGES, Port, SweepSpec, run_chunks
from .samplers import CHUNK

__all__ = ["bench_sweep", "sweep_markdown", "BENCH_CASES"]

#: The cases ``moments-ref bench`` times: Algorithm 1 and Algorithm 3 with their shipped GLSL ports.
BENCH_CASES = ("shadow_intensity-lower-float32", "shadow_intensity-upper-float32", "shade-float32")


def bench_sweep(cases=BENCH_CASES, chunks=2, adapter="gl", language="glsl"):
    """Per case: rows, wall seconds and rows/s end to end and per stage (one process, ``chunks`` chunks)."""
    from ..conformance import shipped_port

    out = []
    for name in cases:
        path, function = shipped_port(name, language)
        spec = SweepSpec(name, Port(str(path), function, language), (adapter,), rows=chunks * CHUNK)
        run_chunks(SweepSpec(name, spec.port, (adapter,), rows=1000))  # compile, context, case noise: not timed
        t0 = time.perf_counter()
        res = run_chunks(spec)
        wall = time.perf_counter() - t0
        sec = {k: sum(r["seconds"][k] for r in res) for k in STAGES}
        out.append({"case": name, "rows": spec.rows, "wall_s": wall, "rows_per_s": spec.rows / wall,
                    **{f"{k}_rows_per_s": (spec.rows / v if v > 0 else float("inf")) for k, v in sec.items()}})
    return out


def sweep_markdown(chunks=2):
    """The table of :func:`bench_sweep` (skipped without an OpenGL driver)."""
    from ..conformance import ContextError

    try:
        rows = bench_sweep(chunks=chunks)
    except ContextError as exc:
        return f"## Sweep\n\nskipped: no OpenGL context ({exc})\n"
    lines = [f"## Sweep: rows/s per stage (shipped GLSL ports on gl, one process, {chunks} chunks of {CHUNK} rows)", "",
             "| case | rows | end to end rows/s | " + " | ".join(STAGES) + " |",
             "|---|---:|---:|" + "---:|" * len(STAGES)]
    for r in rows:
        lines.append(f"| {r['case']} | {r['rows']} | {r['rows_per_s']:.3g} | "
                     + " | ".join(f"{r[k + '_rows_per_s']:.3g}" for k in STAGES) + " |")
    return "\n".join(lines) + "\n"
