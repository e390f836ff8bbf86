"""``moments-ref bench``: throughput of the kernels beside a same-run memory copy.

Every kernel is timed on square inputs (2048² by default) and compared with
``np.copyto`` of the same number of bytes (inputs read plus outputs written),
measured in the same run right before it. The ratio ``copy time / kernel time``
says how far a kernel is from being memory bound (1 = as fast as a copy; the
speed targets, :mod:`._targets`, ask float32 ``shadow_intensity`` for 1/8).
Times are the best of a few repetitions (the minimum is the least noisy
estimate of the cost on a shared machine).

References
----------
.. [1] VWSS: Adam Marrs, Benjamin Watson and Christopher Healey. 2018. *View-warped Multi-view Soft
       Shadowing for Local Area Lights*. Journal of Computer Graphics Techniques (JCGT) 7, 3, 1–28.
       http://jcgt.org/published/0007/03/01/
.. [2] HPG17: Christoph Peters. 2017. *Non-Linearly Quantized Moment Shadow Maps*. In Proceedings
       of High Performance Graphics (HPG '17). ACM. The non-linear quantization Φ, Ψ4, Algorithms
       1–3, the texel formats and the compute shader of §4.1.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from ...gpu import filtering
from ...gpu import onchip as _onchip
from ...techniques.vwss import warp
from ._targets import TARGET_GROUPS, agreement_markdown, copier, run_targets, targets_markdown
from ._timing import PAIRS, paired

__all__ = ["Benchmark", "BENCHMARKS", "run", "markdown", "bench_filtering",
           "bench_onchip", "bench_entries", "run_targets", "TARGET_GROUPS", "only_names", "target_groups", "targets_markdown", "agreement_markdown",
           "kernels_markdown", "keep_history", "HISTORY_HEADING"]


@dataclass(frozen=True)
class Benchmark:
    """One timed kernel: ``setup(size, dtype) -> args``; ``fn(*args)``; bytes in and out per element."""

    name: str
    dtype: str
    setup: Callable
    fn: Callable
    bytes_per_element: int
    note: str = ""
    #: Elements for a ``size`` argument (default ``size²``: texels or fragments).
    count: Callable = staticmethod(lambda size: size * size)
    unit: str = "elem"


def _moments_input(size, dtype):
    from ...moments import BIAS_FLOAT32, bias_moments, power_moments

    rng = np.random.default_rng(1)
    z = rng.uniform(-1, 1, (size, size, 4))
    b = bias_moments(power_moments(z), BIAS_FLOAT32).astype(dtype)
    zf = rng.uniform(-1, 1, (size, size)).astype(dtype)
    return b, zf


def _setup_msm(size, dtype):
    return _moments_input(size, dtype)


def _setup_encode(size, dtype):
    return (_moments_input(size, dtype)[0],)


def _setup_decode(size, dtype):
    from ...affine import encode_unorm16

    return encode_unorm16(_moments_input(size, "float64")[0]), np.dtype(dtype)


def _fn_msm(b, zf):
    from ...msm import shadow_intensity

    return shadow_intensity(b, zf)


def _fn_encode(b):
    from ...affine import encode_unorm16

    return encode_unorm16(b)


def _fn_decode(u, dtype):
    from ...affine import decode_unorm16

    return decode_unorm16(u, dtype=dtype)


def _setup_raster(samples):
    def setup(size, dtype):
        from ...scene.raster import small_triangles

        n = size * size // 4
        v, t = small_triangles(n, 1024, 4.0, np.random.default_rng(0))
        return v, t, samples

    return setup


def _fn_raster(v, t, samples):
    from ...scene.raster import rasterize_depth

    return rasterize_depth(v, t, np.eye(4), 1024, samples=samples)


def _setup_representation(size, dtype):
    from ...moments import BIAS_FLOAT32, bias_moments
    from ...nonlinear import phi

    b, zf = _moments_input(size, "float64")
    return phi(bias_moments(b, BIAS_FLOAT32)).astype(dtype), zf.astype(dtype)


def _setup_phi(size, dtype):
    return (_moments_input(size, dtype)[0],)


def _setup_pack(size, dtype):
    return (_setup_representation(size, dtype)[0],)


def _setup_unpack32(size, dtype):
    from ...packing import pack32

    return pack32(_setup_representation(size, "float64")[0]), np.dtype(dtype)


def _fn_phi(b):
    from ...nonlinear import phi

    return phi(b)


def _fn_shade(r, zf):
    from ...nonlinear import shade

    return shade(r, zf)


def _fn_pack32(r):
    from ...packing import pack32

    return pack32(r)


def _fn_unpack32(p, dtype):
    from ...packing import unpack32

    return unpack32(p, dtype=dtype)


def _core_benchmarks():
    out = []
    for dt, w in (("float32", 4), ("float64", 8)):
        out.append(Benchmark("shadow_intensity", dt, _setup_msm, _fn_msm, 6 * w, "4 + 1 floats in, 1 out"))
        out.append(Benchmark("encode_unorm16", dt, _setup_encode, _fn_encode, 4 * w + 8, "4 floats in, 4 uint16 out"))
        out.append(Benchmark("decode_unorm16", dt, _setup_decode, _fn_decode, 8 + 4 * w, "4 uint16 in, 4 floats out"))
    out += [
        Benchmark("phi (Algorithm 2)", "float32", _setup_phi, _fn_phi, 32, "4 floats in, 4 out"),
        Benchmark("shade (Algorithm 3)", "float32", _setup_representation, _fn_shade, 24,
                  "5 floats in, 1 out; target 1/20 of the copy"),
        Benchmark("pack32", "float32", _setup_pack, _fn_pack32, 20, "4 floats in, 1 uint32 out"),
        Benchmark("unpack32", "float32", _setup_unpack32, _fn_unpack32, 20, "1 uint32 in, 4 floats out"),
    ]
    for s in (1, 4):
        # Triangles in: 3 vertices of 4 float32 each; a 1024² map out, amortized per triangle.
        out.append(Benchmark(f"rasterize_depth {s}x MSAA", "float32", _setup_raster(s), _fn_raster, 48 + 16 * s,
                             "size²/4 small triangles (about 4 px wide) into a 1024² map; target 2 M/s",
                             count=lambda size: size * size // 4, unit="tri"))
    return out


# ---------------------------------------------------------------------------
# The filtering, on-chip and VWSS kernels (the bench imports what it measures)


def _timed(fn, *args):
    t0 = time.perf_counter()
    out = fn(*args)
    return out, time.perf_counter() - t0


def bench_filtering(size=2048, samples=4, onchip=True):
    """Time the global path (resolve, then blur) and the on-chip emulation.

    Parameters
    ----------
    size : int
        Side of the square shadow map (HPG17 §5 uses 2048²).
    samples : int
        MSAA samples per texel (4 in HPG17 §5).
    onchip : bool
        Also time :func:`moments_ref.gpu.onchip.filter_moments` per stage.

    Returns
    -------
    results : dict
        ``{"size", "samples", "texels", "global_resolve_s", "global_blur_s",
        "global_total_s", "global_mtexels_per_s"}`` and, with ``onchip``, the
        on-chip stage times ``"onchip_<stage>_s"``, ``"onchip_total_s"``,
        ``"onchip_mtexels_per_s"`` and ``"max_abs_difference"`` between the two
        paths. Wall-clock seconds of one run on this machine (NumPy, CPU).
    """
    depth = filtering.bench_depth_map(size, samples)
    out = {"size": int(size), "samples": int(samples), "texels": int(size) * int(size)}
    b, t_resolve = _timed(filtering.resolve_moments, depth)
    ref, t_blur = _timed(filtering.blur, b)
    out["global_resolve_s"] = t_resolve
    out["global_blur_s"] = t_blur
    out["global_total_s"] = t_resolve + t_blur
    out["global_mtexels_per_s"] = out["texels"] / out["global_total_s"] / 1e6
    if onchip:
        f, times = _onchip_timed(depth)
        out.update(times)
        out["max_abs_difference"] = float(np.max(np.abs(f - ref)))
    return out


def _onchip_timed(depth):
    """:func:`moments_ref.gpu.onchip.filter_moments` of ``depth`` and its ``onchip_*`` timings."""
    stages = {}
    t0 = time.perf_counter()
    f = _onchip.filter_moments(depth, timings=stages)
    total = time.perf_counter() - t0
    out = {f"onchip_{k}_s": v for k, v in stages.items()}
    out["onchip_total_s"] = total
    out["onchip_mtexels_per_s"] = depth.shape[0] * depth.shape[1] / total / 1e6
    return f, out


def _bench_setup_depth(size, dtype):
    return (filtering.bench_depth_map(size, 4, dtype),)


def _bench_setup_moments(size, dtype):
    return (filtering.resolve_moments(filtering.bench_depth_map(size, 4, dtype)),)


def _global_path(z):
    return filtering.blur(filtering.resolve_moments(z))


def _filtering_entries():
    """Benchmarks for ``moments-ref bench`` (:mod:`moments_ref.tools.bench`): resolve, blur, both.

    Inputs are 4× MSAA float32 depth maps of ``size²`` texels; bytes per texel
    count the samples read and the moments written.
    """
    return [
        Benchmark("resolve_moments (4x MSAA)", "float32", _bench_setup_depth, filtering.resolve_moments, 16 + 16,
                  "4 depths in, 4 float32 moments out"),
        Benchmark("blur 9x9 reference", "float64", _bench_setup_moments, filtering.blur, 16 + 32,
                  "float32 moments in, float64 out, two passes, clamp-to-edge"),
        Benchmark("resolve+blur global path", "float32", _bench_setup_depth, _global_path, 16 + 32,
                  "4 depths in, float64 moments out"),
    ]


def bench_onchip(size=2048, samples=4):
    """Seconds per stage of :func:`filter_moments` on the benchmark map of :func:`moments_ref.gpu.filtering.bench_depth_map`."""
    return _onchip_timed(filtering.bench_depth_map(size, samples))[1]


def _bench_nlq64(z):
    return _onchip.filter_and_quantize(z, "nlq64")


def _onchip_entries():
    """Benchmarks for ``moments-ref bench`` (:mod:`moments_ref.tools.bench`): the on-chip emulation.

    4× MSAA float32 depth maps of ``size²`` texels.
    """
    out = [
        Benchmark("onchip filter_moments (4x MSAA)", "float32", _bench_setup_depth, _onchip.filter_moments, 16 + 16,
                  "4 depths in, 4 float32 moments out, block-wise shared-memory emulation"),
    ]
    out.append(Benchmark("onchip filter_and_quantize nlq64", "float32", _bench_setup_depth, _bench_nlq64, 16 + 8,
                         "4 depths in, 64-bit NLQ texel out"))
    return out


def _bench_zbuffer_setup(size, dtype):
    rng = np.random.default_rng(3)
    n = size * size
    n_texels = 16 * 1024 * 1024 if size >= 1024 else 1 << 20
    idx = rng.integers(0, n_texels, n).astype(np.intp)
    z = rng.uniform(0, 1, n).astype(dtype)
    return np.zeros(n_texels, warp.zbuffer_dtype(dtype)), idx, z


def _bench_zbuffer_fn(buf, idx, z):
    buf[:] = 0
    warp.zmax_into(buf, idx, z)


def _bench_warp_setup(size, dtype):
    """size² point-view updates: 16 views of 512², points on a tilted disc in front of them."""
    from ...scene import AreaLight
    from ...techniques.vwss.lights import light_views

    light = AreaLight(center=(0, 4, 0), normal=(0, -1, 0), width=1.0, height=1.0, up=(0, 0, -1), fov=90)
    views = light_views(light, 16, 1.0, 5.0, seed=0)
    n = max(1, size * size // 16)
    rng = np.random.default_rng(4)
    a = rng.uniform(0, 2 * np.pi, n)
    rad = 1.5 * np.sqrt(rng.uniform(0, 1, n))
    pts = np.stack([rad * np.cos(a), 2.0 + 0.2 * rad * np.sin(a), rad * np.sin(a)], -1).astype(dtype)
    return pts, views.clip_from_world, 512


def _bench_warp_fn(pts, vp, res):
    for _ in warp.warp_passes(pts, vp, res, views_per_pass=8):
        pass


def _bench_mvr_setup(size, dtype):
    """size² triangle-views: 4 views of 1024², size²/4 small triangles (about 4 pixels each)."""
    from ...scene import AreaLight, torus_knot
    from ...techniques.vwss.lights import light_views

    light = AreaLight(center=(0, 4, 0), normal=(0, -1, 0), width=1.0, height=1.0, up=(0, 0, -1), fov=90)
    views = light_views(light, 4, 1.0, 5.0, seed=0)
    n_tri = max(64, size * size // 4)
    sides = 32
    segments = max(2, n_tri // (2 * sides))
    knot = torus_knot(p=2, q=3, radius=1.1, tube=0.14, segments=segments, sides=sides)
    v = knot.vertices + np.array([0.0, 1.5, 0.0])
    return v, knot.triangles, views.clip_from_world, 1024, np.dtype(dtype)


def _bench_mvr_fn(v, t, vp, res, dtype):
    from ...techniques.vwss.mvr import mvr

    mvr(v, t, vp, res, dtype=dtype)


def _vwss_entries():
    """Benchmarks for ``moments-ref bench``: z-buffer atomics, full warp, MVR.

    The bench's element count is ``size²``; here an element is one point-view
    update (``zbuffer_max`` / ``warp``) or one triangle-view (``mvr``), so
    ``Melem/s`` reads directly as warp updates or MVR triangles per second.
    """
    return [
        Benchmark("vwss zbuffer_max (np.maximum.at)", "float32", _bench_zbuffer_setup, _bench_zbuffer_fn, 12,
                  "element = 1 update: index 8 B + depth 4 B in, random texel of a 64 MB map"),
        Benchmark("vwss warp (project+snap+zbuffer)", "float32", _bench_warp_setup, _bench_warp_fn, 8,
                  "element = 1 point-view update; 16 views of 512^2, 8 per pass"),
        Benchmark("vwss mvr (rasterize_depth)", "float32", _bench_mvr_setup, _bench_mvr_fn, 4,
                  "element = 1 triangle-view; torus knot, 4 views of 1024^2"),
    ]


def _extra_benchmarks():
    """Benchmarks of the GPU-emulation and VWSS modules."""
    return _filtering_entries() + _onchip_entries() + _vwss_entries()


BENCHMARKS = _core_benchmarks()


def only_names():
    """The names ``moments-ref bench --only`` matches: the benchmarks, the sections and the target groups."""
    return [b.name for b in bench_entries()] + ["end_to_end", "targets", "conformance", "kernels", "sweep"] \
        + [f"targets-{g}" for g in TARGET_GROUPS]


def target_groups(only=None):
    """The target groups ``--only`` names: all for ``targets`` (or none given), else those ``targets-GROUP`` names."""
    return [g for g in TARGET_GROUPS if any(o in f"targets-{g}" for o in only or ["targets"])]


def run(size=2048, quick=False, only=None, progress=None, repeat=None):
    """Run the benchmarks; return one dict per benchmark.

    Parameters
    ----------
    size : int
        Side of the square inputs (elements = size²).
    quick : bool
        One repetition and at most 512² (a smoke run).
    only : list of str, optional
        Run benchmarks whose ``name`` contains one of these strings.
    progress : callable, optional
        ``progress(total)`` returning a context manager with ``update(n)`` (tqdm).
    """
    if quick:
        size = min(size, 512)
    repeat = repeat or (1 if quick else PAIRS)
    benches = bench_entries()
    if only:
        benches = [b for b in benches if any(o in b.name for o in only)]
    rows = []
    bar = progress(len(benches)) if progress else None
    try:
        for bm in benches:
            args = bm.setup(size, bm.dtype)
            n = bm.count(size)
            nbytes = n * bm.bytes_per_element
            # Interleaved with a copy of the same traffic (reads a, writes c: a copy of (a + c)/2 moves a + c).
            r = paired(lambda: bm.fn(*args), copier(nbytes), pairs=repeat)
            t = r.kernel
            rows.append({
                "name": bm.name, "dtype": bm.dtype, "elements": n, "seconds": t,
                "melem_per_s": n / t / 1e6, "mbytes": nbytes / 1e6, "copy_seconds": r.baseline,
                "ratio_to_copy": 1 / r.median, "spread": (1 / r.high, 1 / r.low), "note": bm.note, "unit": bm.unit,
            })
            if bar is not None:
                bar.update(1)
    finally:
        if bar is not None:
            bar.close()
    return rows


#: The hand-kept section of bench.md (dated measurements of kernel changes, floors) that a new run keeps.
HISTORY_HEADING = "## Kernel history"


def keep_history(text, path):
    """``text`` followed by the :data:`HISTORY_HEADING` section of the bench.md at ``path``, if it has one.

    The tables of a run replace the old ones; the history is written by hand and kept.
    """
    from ..._io import read_own

    try:  # only the command's own earlier file: a FIFO, device or link there is refused, never read
        old = (read_own(path, 1 << 22, "out") or b"").decode("utf-8")
    except (OSError, UnicodeDecodeError):
        return text
    at = old.find("\n" + HISTORY_HEADING + "\n")
    return text if at < 0 else text.rstrip("\n") + "\n\n" + old[at + 1:]


def end_to_end(size=2048, samples=4, repeat=1):
    """Time a ``size²`` ``samples``× MSAA depth map -> filtered NLQ64 texture, by stage.

    The global path of HPG17 §4 as the reference computes it: resolve
    (:func:`~moments_ref.gpu.filtering.resolve_moments`, float32), the 9×9 Gaussian
    (:func:`~moments_ref.gpu.filtering.blur`, float64 reference, cast to float32 like
    the shader's registers), bias with ``BIAS_FLOAT32`` and Φ
    (:func:`~moments_ref.nonlinear.phi`), pack (:func:`~moments_ref.packing.pack64`);
    and beside it the on-chip emulation (:func:`~moments_ref._onchip.filter_moments`)
    followed by the same Φ and pack; and the fused paths that the docs show
    (:func:`~moments_ref.gpu.filtering.global_path_nlq` from the samples,
    :func:`~moments_ref.gpu.filtering.quantize_nlq` from the filtered moments: the
    same bits, a band at a time). Returns a list of dicts
    ``{path, stage, seconds, share}``; shares are of the path's total.
    """
    from ...gpu.filtering import bench_depth_map, blur, global_path_nlq, quantize_nlq, resolve_moments
    from ...moments import BIAS_FLOAT32, bias_moments
    from ...nonlinear import phi
    from ...gpu.onchip import filter_moments
    from ...packing import pack64

    z = bench_depth_map(size, samples, np.float32)
    state = {}

    def timed(path, stage, fn):
        best = float("inf")
        for _ in range(repeat):
            t0 = time.perf_counter()
            state[stage] = fn()
            best = min(best, time.perf_counter() - t0)
        return {"path": path, "stage": stage, "seconds": best}

    rows = [
        timed("global", "resolve", lambda: resolve_moments(z)),
        timed("global", "blur", lambda: blur(state["resolve"]).astype(np.float32)),
        timed("global", "bias + phi", lambda: phi(bias_moments(state["blur"], BIAS_FLOAT32))),
        timed("global", "pack64", lambda: pack64(state["bias + phi"])),
        timed("onchip", "filter_moments (resolve + blur in blocks)", lambda: filter_moments(z)),
    ]
    rows.append(timed("onchip", "bias + phi ", lambda: phi(bias_moments(
        state["filter_moments (resolve + blur in blocks)"], BIAS_FLOAT32))))
    rows.append(timed("onchip", "pack64 ", lambda: pack64(state["bias + phi "])))
    fused = {"fused": ("global_path_nlq (resolve, blur, bias + phi, pack64 in bands)",
                       lambda: global_path_nlq(z, "nlq64")),
             "fused from moments": ("quantize_nlq (bias + phi, pack64 in chunks of the blurred map)",
                                    lambda: quantize_nlq(state["blur"], "nlq64"))}
    rows += [timed(path, stage, fn) for path, (stage, fn) in fused.items()]
    # The fused paths are only faster ways to the same bits.
    for stage, _ in fused.values():
        if not np.array_equal(state[stage], state["pack64"]):
            raise RuntimeError(f"bench: {stage} differs from the separate passes")
    for path in ("global", "onchip", "fused", "fused from moments"):
        members = [r for r in rows if r["path"] == path]
        total = sum(r["seconds"] for r in members)
        for r in members:
            r["share"] = r["seconds"] / total
        if len(members) > 1:
            rows.append({"path": path, "stage": "total", "seconds": total, "share": 1.0})
    return rows


def end_to_end_markdown(rows, size, samples):
    lines = [
        f"## End to end: {size}² {samples}× MSAA depth map -> NLQ64 texture (target: 3 s or less on one core)",
        "",
        "| path | stage | seconds | share |",
        "|---|---|---:|---:|",
    ]
    for r in rows:
        lines.append(f"| {r['path']} | {r['stage'].strip()} | {r['seconds']:.3f} | {100 * r['share']:.0f}% |")
    return "\n".join(lines) + "\n"


def conformance_markdown(repeat=3):
    """Timing of one conformance run per golden case on the OpenGL context (llvmpipe here)."""
    from ...conformance import ContextError, bench_conformance

    try:
        rows = bench_conformance(repeat=repeat)
    except ContextError as exc:
        return f"## Conformance runs\n\nskipped: no OpenGL 4.3 context ({exc})\n"
    lines = [f"## Conformance runs per golden case ({rows[0]['renderer'] if rows else '-'}), best of {repeat}", "",
             "| case | function | rows | compile s | upload s | dispatch s | readback s |",
             "|---|---|---:|---:|---:|---:|---:|"]
    for r in rows:
        lines.append(f"| {r['case']} | {r['function']} | {r['rows']} | {r['compile_s']:.4f} | {r['upload_s']:.5f} | "
                     f"{r['dispatch_s']:.5f} | {r['readback_s']:.5f} |")
    return "\n".join(lines) + "\n"


def kernels_markdown(size=2048, samples=4, adapter="vulkan"):
    """The shipped HPG17 §4.1 kernels on lavapipe (NLQ64) beside the NumPy paths, as same-run ratios."""
    from ...conformance import ContextError, ToolError
    from ...conformance.kernel.bench import bench_kernel

    head = (f"## Shipped filter kernels: {size}² {samples}× MSAA -> NLQ64 on {adapter} "
            "(ratio = NumPy seconds / kernel seconds, same run)")
    rows = []
    for language in ("glsl", "hlsl", "wgsl"):
        try:
            rows.append(bench_kernel(language, adapter, size, samples, "nlq64"))
        except (ContextError, ToolError) as exc:
            return f"{head}\n\nskipped: {exc}\n"
    lines = [head, "", f"Renderer: {rows[0]['renderer']}. Kernel time: {rows[0]['timer']} of the "
             f"{rows[0]['dispatches']} dispatches ({rows[0]['blocks']} blocks), after a warm-up dispatch.", "",
             "| kernel | kernel s | wall s | global NumPy path s | ratio | NumPy block emulation s | ratio | "
             "codes = global path | codes = emulation |", "|---|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for r in rows:
        lines.append(f"| hpg17_filter_nlq64.{r['language']} | {r['kernel_s']:.3f} | {r['wall_s']:.3f} | "
                     f"{r['global_s']:.3f} | {r['ratio_global']:.2f} | {r['emulation_s']:.3f} | "
                     f"{r['ratio_emulation']:.2f} | {100 * r['codes_equal']:.0f}% | "
                     f"{100 * r['codes_equal_emulation']:.0f}% |")
    lines += ["", "Codes differ where Φ is ill-conditioned (nearly flat texels of this map); the moments of the "
              "shipped kernels equal the block emulation's bit for bit (tests/test_kernel_conformance.py)."]
    return "\n".join(lines) + "\n"


#: The one convention of "× a copy" in the bench and the docs.
COPY_CONVENTION = (
    "**× a copy** (the one convention of these docs): the kernel's CPU time over the CPU time of `np.copyto` "
    "between two touched buffers moving the same bytes as the kernel (half its bytes read plus written are "
    "copied, so the copy reads and writes as many as the kernel), the median over interleaved pairs "
    "(copy, kernel, copy, kernel, ...) in the same run, the quartiles of the pair ratios as the spread; "
    "1× = as fast as moving its data once. A floor probe is measured against the same copy in the same run."
)


def markdown(rows):
    """A markdown table of :func:`run`'s rows (empty string for no rows)."""
    import platform

    if not rows:
        return ""

    lines = [
        f"# moments-ref bench ({platform.machine()}, numpy {np.__version__}, one thread of Python)",
        "",
        COPY_CONVENTION,
        "",
        "| kernel | dtype | elements | seconds | M/s | MB moved | copy s | × a copy | spread | note |",
        "|---|---|---:|---:|---:|---:|---:|---:|---|---|",
    ]
    for r in rows:
        lines.append(
            f"| {r['name']} | {r['dtype']} | {r['elements']} {r['unit']} | {r['seconds']:.4f} | {r['melem_per_s']:.1f} | "
            f"{r['mbytes']:.1f} | {r['copy_seconds']:.4f} | {1 / r['ratio_to_copy']:.1f}× | "
            f"{1 / r['spread'][1]:.1f}–{1 / r['spread'][0]:.1f} | {r['note']} |"
        )
    return "\n".join(lines) + "\n"


def bench_entries():
    """Every benchmark of ``moments-ref bench``: the core kernels, filtering, on-chip emulation, VWSS."""
    return BENCHMARKS + _extra_benchmarks()
