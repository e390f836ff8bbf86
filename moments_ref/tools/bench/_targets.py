"""The speed targets of ``moments-ref bench``: same-run ratios with a pass/miss mark.

Each target compares the reference with a baseline measured in the same run,
alternating the two (candidate, baseline, candidate, ...) and taking the median
of at least three CPU times (``time.process_time``: on a shared machine wall
time mostly measures the neighbours). The baselines:

* a memory copy (``np.copyto`` between two preallocated, touched buffers) of
  the same traffic: a kernel that reads ``a`` bytes and writes ``c`` copies
  ``(a + c) / 2`` bytes, which moves ``a + c``;
* Mesa's llvmpipe drawing the same triangles with one thread
  (:mod:`moments_ref.tools.bench._llvmpipe`), when moderngl and EGL are present;
* the global path for the on-chip emulation (it does the same arithmetic).

Nothing here is asserted by the tests: targets are read, not enforced.

References
----------
HPG17 : see docs/bib.md.
"""

from __future__ import annotations

import os
import statistics
import time
import tracemalloc

import numpy as np

from ...gpu import filtering, onchip
from ...moments import BIAS_FLOAT32, bias_moments, power_moments
from ...msm import shadow_intensity
from ...msm6 import BIAS6_FLOAT32
from ...nonlinear import phi, shade
from ...report._jobs import usable_cores
from ...scene.raster import rasterize_depth
from ._cases import raster_case

__all__ = ["raster_case", "measure", "run_targets", "targets_markdown", "GROWTH_LIMIT"]

#: Largest accepted growth of the per-element cost from the smallest to the largest size.
GROWTH_LIMIT = 1.2


def measure(fns, repeat=3, least=0.05):
    """Alternate the callables ``fns`` ``repeat`` times; median ``(cpu, wall)`` seconds per call of each.

    A callable returning a dict ``{"cpu", "wall"}`` (the llvmpipe worker) reports
    its own times. Otherwise the call is timed here, after one untimed warm-up
    call, and a call quicker than ``least`` seconds is repeated within each
    sample until the sample lasts about ``least`` (a memory copy of 64 MiB takes
    a few ms, below the noise of one CPU-time reading on a shared machine).
    """
    loops = [1] * len(fns)
    for k, fn in enumerate(fns):
        c0 = time.process_time()
        if not isinstance(fn(), dict):
            loops[k] = min(64, max(1, int(least / max(time.process_time() - c0, 1e-6))))
    cpu = [[] for _ in fns]
    wall = [[] for _ in fns]
    for _ in range(max(3, repeat)):
        for k, fn in enumerate(fns):
            c0, t0 = time.process_time(), time.perf_counter()
            for _ in range(loops[k]):
                got = fn()
            c, w = (time.process_time() - c0) / loops[k], (time.perf_counter() - t0) / loops[k]
            if isinstance(got, dict):
                c, w = got["cpu"], got["wall"]
            cpu[k].append(c)
            wall[k].append(w)
    return [(statistics.median(c), statistics.median(w)) for c, w in zip(cpu, wall)]


def _copier(nbytes):
    """A callable copying ``nbytes / 2`` bytes between touched buffers (moves ``nbytes``)."""
    src = np.ones(max(1, int(nbytes) // 2), np.uint8)
    dst = np.zeros_like(src)
    return lambda: np.copyto(dst, src)


def _row(target, ratio, limit, detail, seconds=None):
    return {"target": target, "ratio": float(ratio), "limit": float(limit), "passed": bool(ratio <= limit),
            "detail": detail, "seconds": seconds}


# ---------------------------------------------------------------------------
# rasterizer against llvmpipe


def _raster_rows(cases, repeat):
    from ._llvmpipe import Llvmpipe, LlvmpipeUnavailable

    try:
        lp = Llvmpipe()
    except LlvmpipeUnavailable as exc:
        return [{"target": f"rasterizer {label} vs llvmpipe", "ratio": None, "limit": limit, "passed": None,
                 "detail": f"not measured: {exc}", "seconds": None} for _, label, limit in cases]
    rows = []
    with lp:
        for name, label, limit in cases:
            v, t, vp, size, samples = raster_case(name)
            lp.case(name)
            (c_ref, w_ref), (c_lp, w_lp) = measure(
                [lambda: rasterize_depth(v, t, vp, size, samples=samples), lp.time], repeat)
            rows.append(_row(f"rasterizer {label} vs llvmpipe", c_ref / c_lp, limit,
                             f"CPU {c_ref:.3f} s vs {c_lp:.3f} s (wall {w_ref:.3f} / {w_lp:.3f} s); "
                             f"{lp.renderer}, LP_NUM_THREADS=0", c_ref))
    return rows


# ---------------------------------------------------------------------------
# 2048² 4× -> NLQ64 / NLQ32


def global_nlq(z, fmt="nlq64"):
    """The global path of HPG17 §4: resolve, 9² blur (float64, cast to float32), bias, Φ, pack.

    :func:`moments_ref.gpu.filtering.global_path_nlq`: the same values as the passes one
    after the other, a band of rows at a time.
    """
    return filtering.global_path_nlq(z, fmt)


def _nlq_rows(size, repeat):
    z = filtering.bench_depth_map(size, 4, np.float32)
    copy = _copier(2 * z.nbytes)
    rows = []
    for fmt in ("nlq64", "nlq32"):
        (cg, _), (cc, _), (co, _) = measure(
            [lambda: global_nlq(z, fmt), copy, lambda: onchip.filter_and_quantize(z, fmt)], repeat)
        mib = z.nbytes / 2**20
        rows.append(_row(f"{size}² 4× → {fmt.upper()} global path vs copy of the samples", cg / cc, 60,
                         f"CPU {cg:.3f} s vs copy of {mib:.0f} MiB {cc:.4f} s", cg))
        rows.append(_row(f"{size}² 4× → {fmt.upper()} on-chip vs global path", co / cg, 1.5,
                         f"CPU {co:.3f} s vs {cg:.3f} s", co))
    return rows


# ---------------------------------------------------------------------------
# shading kernels


def kernel_inputs(n):
    """Inputs of the shading kernels for ``n`` texels: ``{name: (fn, args, traffic bytes)}``."""
    rng = np.random.default_rng(1)
    z = rng.uniform(-1, 1, (n, 4))
    zf = rng.uniform(-1, 1, n).astype(np.float32)
    b4 = bias_moments(power_moments(z), BIAS_FLOAT32).astype(np.float32)
    r = phi(b4)
    b6 = bias_moments(power_moments(rng.uniform(-1, 1, (n, 4)), n=6), BIAS6_FLOAT32).astype(np.float32)
    return {
        "shadow_intensity float32": (shadow_intensity, (b4, zf), 24 * n),
        "shade float32": (shade, (r, zf), 24 * n),
        "shadow_intensity six moments float32": (shadow_intensity, (b6, zf), 32 * n),
    }


def peak_memory(fn, *args):
    """Peak bytes NumPy allocates during ``fn(*args)`` (tracemalloc), and the result's bytes."""
    tracemalloc.start()
    try:
        out = fn(*args)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    return peak, out.nbytes


def _kernel_rows(size, repeat):
    rows = []
    limits = {"shadow_intensity float32": 8, "shade float32": 8, "shadow_intensity six moments float32": 16}
    for name, (fn, args, traffic) in kernel_inputs(size * size).items():
        copy = _copier(traffic)
        (ck, _), (cc, _) = measure([lambda: fn(*args), copy], repeat)
        rows.append(_row(f"{name} vs copy of its traffic ({size}²)", ck / cc, limits[name],
                         f"CPU {ck:.4f} s vs copy of {traffic / 2**20:.0f} MiB moved {cc:.4f} s", ck))
        if "six" in name:
            peak, out = peak_memory(fn, *args)
            rows.append(_row(f"{name} peak memory / output", peak / out, 2,
                             f"{peak / 2**20:.1f} MiB allocated at peak for a {out / 2**20:.1f} MiB result"))
    return rows


# ---------------------------------------------------------------------------
# linear growth


def _growth_rows(sizes, triangles, repeat):
    """Per-element CPU cost at three sizes for each kernel and the rasterizer."""
    costs = {}
    for s in sizes:
        for name, (fn, args, _) in kernel_inputs(s * s).items():
            costs.setdefault(name, []).append((s * s, measure([lambda: fn(*args)], repeat)[0][0] / (s * s)))
        z = filtering.bench_depth_map(s, 4, np.float32)
        costs.setdefault("4× MSAA map → NLQ64 (global path)", []).append(
            (s * s, measure([lambda: global_nlq(z)], repeat)[0][0] / (s * s)))
    for n in triangles:
        v, t, vp, size, samples = raster_case(f"small-{n}-1x")
        c = measure([lambda: rasterize_depth(v, t, vp, size, samples=samples)], repeat)[0][0]
        costs.setdefault("rasterizer 1× (small triangles, 1024²)", []).append((n, c / n))
    rows = []
    for name, pts in costs.items():
        growth = pts[-1][1] / pts[0][1]
        per = ", ".join(f"{_count(n)}: {1e9 * c:.1f} ns" for n, c in pts)
        rows.append(_row(f"linear growth: {name}", growth, GROWTH_LIMIT, f"per element {per}"))
    return rows


def _count(n):
    return f"{n // 2**20} M" if n >= 2**20 else f"{n // 2**10} k"


def run_targets(quick=False, repeat=3, raster=True):
    """Measure every target; one dict per target (``ratio`` None where it could not be measured).

    ``quick`` shrinks every size (a smoke run whose numbers mean little).
    """
    big = 256 if quick else 2048
    n_small = 16_384 if quick else 1 << 20
    cases = [(f"small-{n_small}-1x", f"{_count(n_small)} small triangles 1×", 1.25),
             (f"small-{n_small}-4x", f"{_count(n_small)} small triangles 4×", 1.25),
             ("railing-4x", "railing 2048² 4×", 2.0)]
    if quick:
        cases = cases[:1]
    load = os.getloadavg()
    rows = _raster_rows(cases, repeat) if raster else []
    rows += _nlq_rows(big, repeat) + _kernel_rows(big, repeat)
    sizes = (64, 128, 256) if quick else (512, 1024, 2048)
    tris = (4096, 16_384, 65_536) if quick else (1 << 18, 1 << 20, 1 << 22)
    rows += _growth_rows(sizes, tris, repeat)
    for r in rows:
        r["load"] = (load, os.getloadavg())
    return rows


def targets_markdown(rows):
    """The targets as a markdown table with the load average before and after."""
    if not rows:
        return ""
    (a, _, _), (b, _, _) = rows[0]["load"]
    lines = [f"## Speed targets (same-run ratios, medians of CPU time; load average {a:.2f} before, "
             f"{b:.2f} after, {usable_cores()} usable cores)", "",
             "| target | ratio | limit | mark | measured |", "|---|---:|---:|---|---|"]
    for r in rows:
        if r["ratio"] is None:
            lines.append(f"| {r['target']} | - | {r['limit']:g}× | not measured | {r['detail']} |")
            continue
        mark = "pass" if r["passed"] else "MISS"
        lines.append(f"| {r['target']} | {r['ratio']:.2f}× | {r['limit']:g}× | {mark} | {r['detail']} |")
    lines += ["", "The target that the default `moments-ref report` runs within 45 s using both cores "
              "belongs to the report and pipeline, not to this bench."]
    return "\n".join(lines) + "\n"
