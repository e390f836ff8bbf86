"""The speed targets of ``moments-ref bench``: same-run ratios with a pass/miss mark.

Each target compares the reference with a baseline measured in the same run,
interleaved (baseline, candidate, baseline, candidate, ...): the figure is the
median of the per-pair ratios and its spread their quartiles
(:mod:`moments_ref.tools.bench._timing`); a target is marked pass or miss only
when the spread lies on one side of its limit. The baselines:

* a memory copy (``np.copyto`` between two preallocated, touched buffers) of
  the same traffic: a kernel that reads ``a`` bytes and writes ``c`` copies
  ``(a + c) / 2`` bytes, which moves ``a + c``;
* Mesa's llvmpipe drawing the same triangles with one thread
  (:mod:`moments_ref.tools.bench._llvmpipe`), when moderngl and EGL are present;
* the global path for the on-chip emulation (it does the same arithmetic).

Nothing here is asserted by the tests: targets are read, not enforced.

References
----------
.. [1] HPG17: Christoph Peters. 2017. *Non-Linearly Quantized Moment Shadow Maps*. In Proceedings
       of High Performance Graphics (HPG '17). ACM. The non-linear quantization Φ, Ψ4, Algorithms
       1–3, the texel formats and the compute shader of §4.1.
"""

from __future__ import annotations

import os
import tracemalloc

import numpy as np

from ...gpu import filtering, onchip
from ...moments import BIAS_FLOAT32, bias_moments, power_moments
from ...msm import chunk_texels, shadow_intensity
from ...msm6 import BIAS6_FLOAT32, BOUNDS_CHUNK
from ...nonlinear import phi, shade, shade_chunk
from ...scene.raster import rasterize_depth
from ._cases import raster_case
from ._memory import pipeline_peak_bytes
from ._probes import PASSES, REDUCTIONS, THIRD_ROW, UFUNCS, pass_probe, scatter_probe
from ._timing import PAIRS, Ratio, paired

__all__ = ["raster_case", "copier", "run_targets", "TARGET_GROUPS", "targets_markdown", "agreement_markdown", "GROWTH_LIMIT", "AGREEMENT"]

#: Largest accepted growth of the per-element cost from the smallest to the largest size.
GROWTH_LIMIT = 1.2
#: Largest relative difference of one ratio between consecutive runs that counts as agreement.
AGREEMENT = 0.15


def copier(nbytes):
    """A callable copying ``nbytes / 2`` bytes between touched buffers (moves ``nbytes``)."""
    src = np.ones(max(1, int(nbytes) // 2), np.uint8)
    dst = np.zeros_like(src)
    return lambda: np.copyto(dst, src)


def _row(target, ratio, limit, detail, seconds=None):
    """One target: the :class:`~._timing.Ratio` (or None, not measured) against ``limit``."""
    row = {"target": target, "limit": float(limit), "detail": detail, "seconds": seconds,
           "ratio": None, "low": None, "high": None, "mark": "not measured", "passed": None}
    if ratio is not None:
        mark = ratio.mark(limit)
        row.update(ratio=float(ratio.median), low=float(ratio.low), high=float(ratio.high), mark=mark,
                   passed={"pass": True, "miss": False}.get(mark))
    return row


# ---------------------------------------------------------------------------
# rasterizer against llvmpipe


def _raster_rows(cases, repeat):
    from ._llvmpipe import Llvmpipe, LlvmpipeUnavailable

    try:
        lp = Llvmpipe()
    except LlvmpipeUnavailable as exc:
        return [_row(f"rasterizer {label} vs llvmpipe", None, limit, f"not measured: {exc}")
                for _, label, limit in cases]
    rows = []
    with lp:
        for name, label, limit in cases:
            v, t, vp, size, samples = raster_case(name)
            lp.case(name)
            r = paired(lambda: rasterize_depth(v, t, vp, size, samples=samples), lp.time, repeat)
            rows.append(_row(f"rasterizer {label} vs llvmpipe", r, limit,
                             f"CPU {r.kernel:.3f} s vs {r.baseline:.3f} s (wall {r.kernel_wall:.3f} / "
                             f"{r.baseline_wall:.3f} s); {lp.renderer}, LP_NUM_THREADS=0", r.kernel))
            probe, covered = scatter_probe(v, t, vp, size, samples)
            p = paired(probe, lp.time, repeat)
            del probe
            rows.append(_row("  floor probe: map clear + scatter-min of the covered samples", p, limit,
                             f"CPU {p.kernel:.3f} s: fill of a kept {size}² × {samples} map and np.minimum.at of "
                             f"{covered / 1e6:.2f} M samples (indices and depths given)", p.kernel))
    return rows


# ---------------------------------------------------------------------------
# 2048² 4× -> NLQ64 / NLQ32


def global_nlq(z, fmt="nlq64"):
    """The global path of HPG17 §4: resolve, 9² blur (float64, cast to float32), bias, Φ, pack.

    :func:`moments_ref.gpu.filtering.global_path_nlq`: the same values as the passes one
    after the other, a band of rows at a time.
    """
    return filtering.global_path_nlq(z, fmt)


#: Limits of the global path in copies of the samples (the issue's target for NLQ64; NLQ32 keeps the earlier one).
NLQ_LIMITS = {"nlq64": 45, "nlq32": 60}


def _nlq_rows(size, repeat):
    z = filtering.bench_depth_map(size, 4, np.float32)
    copy = copier(2 * z.nbytes)
    rows = []
    for fmt in ("nlq64", "nlq32"):
        mib = z.nbytes / 2**20
        g = paired(lambda: global_nlq(z, fmt), copy, repeat)
        rows.append(_row(f"{size}² 4× → {fmt.upper()} global path vs copy of the samples", g, NLQ_LIMITS[fmt],
                         f"CPU {g.kernel:.3f} s vs copy of {mib:.0f} MiB {g.baseline:.3g} s", g.kernel))
        o = paired(lambda: onchip.filter_and_quantize(z, fmt), lambda: global_nlq(z, fmt), repeat)
        rows.append(_row(f"{size}² 4× → {fmt.upper()} on-chip vs global path", o, 1.5,
                         f"CPU {o.kernel:.3f} s vs {o.baseline:.3f} s", o.kernel))
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


#: The issue's targets, in copies of the kernel's traffic.
KERNEL_LIMITS = {"shadow_intensity float32": 8, "shadow_intensity float64": 9, "shade float32": 7,
                 "shadow_intensity six moments float32": 12}
_CHUNKS = {"shadow_intensity float32": chunk_texels(np.float32), "shadow_intensity float64": chunk_texels(np.float64),
           "shade float32": shade_chunk(np.float32),
           "shadow_intensity six moments float32": BOUNDS_CHUNK}


def _probe_rows(name, args, copy, repeat):
    """The floors of ``name`` measured against the same copy: data movement alone, and with the kernel's passes.

    With the kernel's ufuncs and reductions where :data:`~._probes.UFUNCS` counts them (Algorithms
    1 and 3), else as many multiplications and additions.
    """
    b, zf = args
    key = name if name in PASSES else name.replace("float64", "float32")
    passes, third = PASSES[key], THIRD_ROW.get(key)
    ufuncs, reductions = UFUNCS.get(key), REDUCTIONS.get(name, REDUCTIONS.get(key, 0))
    rows = []
    for p, what in ((0, "transposing copy + output"), (passes, f"+ {passes} passes")):
        kind = dict(ufuncs=ufuncs, reductions=reductions) if p and ufuncs else {}
        r = paired(pass_probe(b, zf, p, _CHUNKS[name], third, **kind), copy, repeat)
        into = f" ({min(third, p)} into a third row)" if third is not None and p else ""
        if kind:
            what += f" and {reductions} reductions"
            into += ", the kernel's ufuncs (" + ", ".join(f"{c} {u}" for u, c in ufuncs.items()) + ")"
        rows.append(_row(f"  floor probe: {what}", r, KERNEL_LIMITS[name],
                         f"CPU {r.kernel:.4f} s: {what}{into} per chunk of {_CHUNKS[name]}", r.kernel))
    return rows


def _kernel_rows(size, repeat):
    rows = []
    inputs = kernel_inputs(size * size)
    fn, (b, zf), traffic = inputs["shadow_intensity float32"]
    inputs = {"shadow_intensity float32": inputs["shadow_intensity float32"],
              "shadow_intensity float64": (fn, (b.astype(np.float64), zf.astype(np.float64)), 2 * traffic),
              **{k: v for k, v in inputs.items() if k != "shadow_intensity float32"}}
    for name, (fn, args, traffic) in inputs.items():
        copy = copier(traffic)
        r = paired(lambda: fn(*args), copy, repeat)
        rows.append(_row(f"{name} vs copy of its traffic ({size}²)", r, KERNEL_LIMITS[name],
                         f"CPU {r.kernel:.4f} s vs copy of {traffic / 2**20:.0f} MiB moved {r.baseline:.3g} s",
                         r.kernel))
        rows += _probe_rows(name, args, copy, repeat)
        if "six" in name:
            peak, out = peak_memory(fn, *args)
            exact = Ratio(peak / out, peak / out, peak / out, 0.0, 0.0, 0.0, 0.0, 1)  # a count, not a timing
            rows.append(_row(f"{name} peak memory / output", exact, 2,
                             f"{peak / 2**20:.1f} MiB allocated at peak for a {out / 2**20:.1f} MiB result"))
    return rows


# ---------------------------------------------------------------------------
# the report pipeline's memory


#: Peak resident bytes per shadow-map texel of the report's pipeline at 2048² 4× MSAA (issue 41).
PIPELINE_BYTES_LIMIT = 100


def _memory_row(size):
    """Peak RSS per texel of the report's pipeline on railing at ``size``² 4× (a count in bytes, not a ratio)."""
    per, peak, base = pipeline_peak_bytes("railing", size, 4)
    exact = Ratio(per, per, per, 0.0, 0.0, 0.0, 0.0, 1) if per > 0 else None  # None: within the baseline's noise
    return _row(f"report pipeline peak memory per shadow-map texel, railing {size}² 4× (bytes, not ×)", exact,
                PIPELINE_BYTES_LIMIT, ("" if per > 0 else "not measured: no larger than the baseline at this size; ") +
                f"peak RSS {peak / 2**20:.0f} MiB of a child process, {base / 2**20:.0f} MiB "
                f"the same run at 64² (interpreter, imports, camera-sized arrays); camera 480×270")


# ---------------------------------------------------------------------------
# linear growth


def _growth_rows(sizes, triangles, repeat):
    """Per-element CPU cost of the largest size over the smallest, interleaved, for each kernel and the rasterizer."""
    calls = {}
    for s in sizes:
        for name, (fn, args, _) in kernel_inputs(s * s).items():
            calls.setdefault(name, []).append((s * s, (lambda fn=fn, args=args: fn(*args))))
        z = filtering.bench_depth_map(s, 4, np.float32)
        calls.setdefault("4× MSAA map → NLQ64 (global path)", []).append((s * s, (lambda z=z: global_nlq(z))))
    for n in triangles:
        v, t, vp, size, samples = raster_case(f"small-{n}-1x")
        calls.setdefault("rasterizer 1× (small triangles, 1024²)", []).append(
            (n, (lambda v=v, t=t, vp=vp, size=size, samples=samples: rasterize_depth(v, t, vp, size, samples=samples))))
    rows = []
    for name, pts in calls.items():
        (n0, small), (n1, large) = pts[0], pts[-1]
        r = paired(large, small, repeat)
        per = n0 / n1  # ratio of totals -> ratio of per-element costs
        g = Ratio(r.median * per, r.low * per, r.high * per, r.kernel, r.baseline, r.kernel_wall, r.baseline_wall,
                  r.pairs)
        rows.append(_row(f"linear growth: {name}", g, GROWTH_LIMIT,
                         f"per element {_count(n0)}: {1e9 * r.baseline / n0:.1f} ns, "
                         f"{_count(n1)}: {1e9 * r.kernel / n1:.1f} ns"))
    return rows


def _count(n):
    return f"{n // 2**20} M" if n >= 2**20 else f"{n // 2**10} k"


#: The target groups ``moments-ref bench --only targets-GROUP`` picks (``--only targets``: all of them).
TARGET_GROUPS = ("raster", "nlq", "algorithms", "growth", "memory")


def run_targets(quick=False, repeat=None, raster=True, groups=TARGET_GROUPS):
    """Measure every target of ``groups`` (:data:`TARGET_GROUPS`); one dict per target.

    ``ratio`` is None where a target could not be measured. ``repeat``: pairs per ratio
    (default :data:`._timing.PAIRS`, 3 with ``quick``). ``quick`` shrinks every size (a smoke
    run whose numbers mean little). ``raster=False`` leaves out the llvmpipe comparisons.
    """
    unknown = [g for g in groups if g not in TARGET_GROUPS]
    if unknown:
        raise ValueError(f"groups: no target group {unknown[0]!r}; groups: {', '.join(TARGET_GROUPS)}")
    big = 256 if quick else 2048
    n_small = 16_384 if quick else 1 << 20
    cases = [(f"small-{n_small}-1x", f"{_count(n_small)} small triangles 1×", 1.25),
             (f"small-{n_small}-4x", f"{_count(n_small)} small triangles 4×", 1.25),
             ("mid-4096-4x", "4k triangles of about 150 px, 2048² 4×", 2.5),
             ("railing-4x", "railing 2048² 4×", 2.5)]
    if quick:
        cases = cases[:1]
    repeat = repeat or (3 if quick else PAIRS)
    load = os.getloadavg()
    rows = _raster_rows(cases, repeat) if raster and "raster" in groups else []
    rows += _nlq_rows(big, repeat) if "nlq" in groups else []
    rows += _kernel_rows(big, repeat) if "algorithms" in groups else []
    if "growth" in groups:
        sizes = (64, 128, 256) if quick else (512, 1024, 2048)
        tris = (4096, 16_384, 65_536) if quick else (1 << 18, 1 << 20, 1 << 22)
        rows += _growth_rows(sizes, tris, repeat)
    if "memory" in groups:
        rows.append(_memory_row(big))
    for r in rows:
        r["load"] = (load, os.getloadavg())
    return rows


def targets_markdown(rows):
    """The targets as a markdown table with the load average before and after."""
    if not rows:
        return ""
    (a, _, _), (b, _, _) = rows[0]["load"]
    lines = [f"## Speed targets (same-run ratios: median of interleaved pairs, quartiles as the spread; "
             f"load average {a:.2f} before, {b:.2f} after)", "",
             "A target is marked pass or miss only when its whole spread lies on one side of the limit.", "",
             "| target | ratio | spread | limit | mark | measured |", "|---|---:|---|---:|---|---|"]
    for r in rows:
        if r["ratio"] is None:
            lines.append(f"| {r['target']} | - | - | {r['limit']:g}× | not measured | {r['detail']} |")
            continue
        lines.append(f"| {r['target']} | {r['ratio']:.2f}× | {r['low']:.2f}–{r['high']:.2f} | {r['limit']:g}× | "
                     f"{r['mark']} | {r['detail']} |")
    lines += ["", "The default `moments-ref report`'s run time belongs to the report and pipeline, not to this bench."]
    return "\n".join(lines) + "\n"


def agreement_markdown(runs):
    """Consecutive runs of :func:`run_targets` side by side: does every ratio agree within :data:`AGREEMENT`,
    and in how many runs is it under its limit?

    The ratios drift between runs with the machine's state by more than one run's quartiles show
    (docs/bench.md), so a target is read by its share of runs under the limit.
    """
    if not runs:
        return ""
    names = [r["target"] for r in runs[0]]
    lines = [f"## {len(runs)} consecutive runs of the targets (agreement: largest / smallest ratio ≤ "
             f"{1 + AGREEMENT:g})", "",
             "| target | " + " | ".join(f"run {i + 1}" for i in range(len(runs))) +
             " | largest / smallest | agree | runs under the limit |",
             "|---|" + "---:|" * len(runs) + "---:|---|---:|"]
    for k, name in enumerate(names):
        vals = [run[k]["ratio"] for run in runs]
        if any(v is None for v in vals):
            lines.append(f"| {name} | " + " | ".join("-" for _ in vals) + " | - | not measured | - |")
            continue
        spread = max(vals) / min(vals)
        limit = runs[0][k].get("limit")
        under = "-" if limit is None else f"{sum(v < limit for v in vals)} of {len(vals)}"
        lines.append(f"| {name} | " + " | ".join(f"{v:.2f}×" for v in vals) +
                     f" | {spread:.3f} | {'yes' if spread <= 1 + AGREEMENT else 'NO'} | {under} |")
    return "\n".join(lines) + "\n"
