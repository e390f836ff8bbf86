"""Time a shipped filter kernel on a large map against the NumPy paths of the same run.

``moments-ref bench`` runs the shipped HPG17 §4.1 kernel (default: GLSL on lavapipe,
2048², 4× MSAA, NLQ64) on :func:`moments_ref.gpu.filtering.bench_depth_map` and
reports the driver's time (timer queries where the driver has them, else the
dispatches' wall time, after one warm-up dispatch) as a ratio to the global NumPy
path (:func:`~moments_ref.gpu.filtering.global_path_nlq`) and to the block
emulation (:func:`moments_ref.gpu.onchip.filter_and_quantize`) measured in the same
process, so that the ratio holds across machines.

References
----------
.. [1] HPG17: Christoph Peters. 2017. *Non-Linearly Quantized Moment Shadow Maps*. In Proceedings
       of High Performance Graphics (HPG '17). ACM. The non-linear quantization Φ, Ψ4, Algorithms
       1–3, the texel formats and the compute shader of §4.1.
"""

from __future__ import annotations

import time

import numpy as np

from ..._arrays import InputError
from ...gpu import filtering, onchip
from ...moments import BIAS_FLOAT32
from .._run import parse_adapter
from .._supervisor import watchdog
from ._job import POISON, Job
from .bind import match
from .cli import shipped_kernel
from .contract import contract, dispatches
from .run import bind_list, execute, output_spec, prepare

__all__ = ["bench_kernel"]


def bench_kernel(language="glsl", adapter="vulkan", size=2048, samples=4, fmt="nlq64"):
    """Run the shipped filter kernel on a ``size``² map and time it beside the NumPy paths.

    Returns
    -------
    dict
        ``language``, ``renderer``, ``size``, ``samples``, ``format``, ``blocks``,
        ``dispatches``, ``kernel_s`` (driver time of all dispatches), ``timer`` (what
        measured it), ``wall_s``, ``global_s`` and ``emulation_s`` (NumPy, same run),
        ``ratio_global`` = ``global_s / kernel_s`` (how many times faster the kernel
        is), ``ratio_emulation``, ``codes_equal`` (fraction of texels whose codes equal
        the global path's; Φ's conditioning makes many differ legitimately) and
        ``codes_equal_emulation`` (the same against the block emulation, whose float32
        arithmetic the shipped kernel repeats).
    """
    if fmt not in ("nlq64", "nlq32"):
        raise InputError(f"fmt: expected 'nlq64' or 'nlq32', got {fmt!r}")
    case = f"kernel-filter-{fmt}"
    z = filtering.bench_depth_map(size, samples)
    path, entry = shipped_kernel(case, language)
    target = parse_adapter(adapter, language)
    prep = prepare(path, entry, language, target)
    c = contract(case)
    bound = match(prep.interface, c)
    kw = {"height": size, "width": size, "samples": samples, "format": fmt,
          "bias": {"alpha": BIAS_FLOAT32.alpha, "target": list(BIAS_FLOAT32.target)}}
    plan = dispatches(case, kw)
    job = Job(prep.backend, prep.driver, prep.adapter, prep.code, prep.entry, bind_list(bound),
              ((z.astype(np.float64) + 1) / 2).astype(np.float32), output_spec(case, kw, bound, POISON[0]),
              [(d.groups, d.params) for d in plan], dispatch_seconds=watchdog())
    result = execute(prep, job)
    driver, wall = result.timings.get("driver", []), result.timings["dispatch"]
    kernel_s, timer = (sum(driver), "timer queries") if driver and sum(driver) > 0 else (sum(wall), "wall clock")
    t0 = time.perf_counter()
    ref = filtering.global_path_nlq(z, fmt)
    global_s = time.perf_counter() - t0
    t0 = time.perf_counter()
    emu = onchip.filter_and_quantize(z, fmt)
    emulation_s = time.perf_counter() - t0
    out = result.output[:size, :size]
    codes = (out if fmt == "nlq64" else out[..., 0]).reshape(size, size, -1)
    equal = (codes == ref.reshape(size, size, -1)).all(axis=-1).mean()
    same = (codes == emu.reshape(size, size, -1)).all(axis=-1).mean()
    return {"language": language, "renderer": result.renderer, "size": size, "samples": samples, "format": fmt,
            "blocks": sum(d.blocks for d in plan), "dispatches": len(plan), "kernel_s": kernel_s, "timer": timer,
            "wall_s": sum(wall), "global_s": global_s, "emulation_s": emulation_s,
            "ratio_global": global_s / kernel_s, "ratio_emulation": emulation_s / kernel_s,
            "codes_equal": float(equal), "codes_equal_emulation": float(same)}
