"""The machine the report's timings come from, and a same-run memory-copy rate.

The seconds in results.csv are NumPy CPU times on one machine. To compare
them across machines, report.md states the cores, the NumPy version, the BLAS it
is built with (``numpy.show_config``; the threads in use via ``threadpoolctl``
where installed) and the rate of a plain memory copy measured in the same run
(``np.copyto`` between two preallocated buffers, best of three in CPU seconds,
the measurement of ``moments-ref bench``): a technique's seconds divided by the
copy's seconds of the same byte count is a ratio that travels between machines.
"""

from __future__ import annotations

import os
import platform
import time

import numpy as np

__all__ = ["machine", "copy_rate", "machine_lines"]

#: Bytes copied for the memory-copy rate (large enough to leave the caches).
COPY_BYTES = 128 * 2 ** 20


def copy_rate(nbytes=COPY_BYTES, repeat=3):
    """Bytes per CPU second of ``np.copyto`` between two preallocated ``nbytes`` buffers (best of ``repeat``).

    A copy of n bytes reads n and writes n; the rate counts the n bytes copied. CPU
    seconds of this process (``time.process_time``), as the report's stages and
    ``moments-ref bench`` are timed: the report measures it while its workers start,
    and their start-up would stretch a wall-clock time.
    """
    src = np.ones(int(nbytes), dtype=np.uint8)
    dst = np.empty_like(src)
    best = float("inf")
    for _ in range(max(int(repeat), 1)):
        t0 = time.process_time()
        np.copyto(dst, src)
        best = min(best, time.process_time() - t0)
    return nbytes / max(best, 1e-9)


def _blas():
    try:
        cfg = np.show_config(mode="dicts")
        b = cfg.get("Build Dependencies", {}).get("blas", {})
        text = f"{b.get('name', '?')} {b.get('version', '')}".strip()
    except Exception:  # older NumPy: no dict mode
        text = "unknown (numpy.show_config has no dict mode)"
    try:
        from threadpoolctl import threadpool_info
    except ImportError:
        return text + " (threads: threadpoolctl not installed)"
    pools = [f"{p.get('internal_api')} {p.get('num_threads')} threads" for p in threadpool_info()]
    return text + (f" ({', '.join(pools)})" if pools else "")


def machine():
    """``{"cores", "cpu", "python", "numpy", "blas", "load"}`` of this machine now."""
    try:
        load = "%.2f %.2f %.2f" % os.getloadavg()
    except (AttributeError, OSError):
        load = "unknown"
    return {"cores": os.cpu_count(), "cpu": platform.processor() or platform.machine(),
            "python": platform.python_version(), "numpy": np.__version__, "blas": _blas(), "load": load}


def machine_lines(info, rate):
    """The "Machine" section of report.md from :func:`machine` and :func:`copy_rate`."""
    return ["## Machine", "",
            f"{info['cores']} cores ({info['cpu']}), Python {info['python']}, NumPy {info['numpy']}, "
            f"BLAS {info['blas']}; load average at the start {info['load']} (1, 5, 15 min: other processes "
            f"on the machine slow the timings down). Memory copy in the same run (`np.copyto`, "
            f"{COPY_BYTES // 2 ** 20} MiB, best of 3 in CPU seconds): {rate / 1e9:.2f} GB/s. Divide a time by "
            "the time of copying the same bytes at this rate to compare machines by ratios.", ""]
