"""``moments-ref conformance --kernel (--glsl | --hlsl | --wgsl | --slang) FILE --entry NAME --case CASE``."""

from __future__ import annotations

import sys

from ..._arrays import InputError
from .._gl import ContextError
from .._toolchain import ToolError
from .run import run_kernel

__all__ = ["kernel_cli", "SHIPPED_KERNELS", "shipped_kernel"]

#: Kernel case -> (file stem, entry point per language) of the shipped kernels in moments_ref/ports/.
SHIPPED_KERNELS = {
    **{f"kernel-filter-{f}": (f"hpg17_filter_{f}", {"glsl": "main", "hlsl": f"filter_{f}", "wgsl": f"filter_{f}",
                                                    **({"slang": f"filter_{f}"} if f.startswith("nlq") else {})})
       for f in ("nlq64", "nlq32", "msm64", "moments")},
    "kernel-vwss-points": ("vwss_points", {"glsl": "main", "hlsl": "CS", "wgsl": "CS"}),
}


def shipped_kernel(case, language):
    """``(path, entry)`` of the shipped kernel of a kernel case in ``language``."""
    from ...ports import PORTS_DIR

    if case not in SHIPPED_KERNELS:
        raise InputError(f"case: no shipped kernel for {case!r}; kernel cases: {', '.join(SHIPPED_KERNELS)}")
    stem, entries = SHIPPED_KERNELS[case]
    if language not in entries:
        raise InputError(f"case: no shipped {language} kernel for {case!r}; {language} ships "
                         f"{', '.join(k for k, (_, e) in SHIPPED_KERNELS.items() if language in e) or 'none'}")
    return PORTS_DIR / language / f"{stem}.{language}", entries[language]


def kernel_cli(path, entry, case, language, golden_dir=None, adapter=None, time_limit=None, out=None, err=None,
               rows=5, json_path=None, options=None, strict=False, layout="interleaved", v2_cell=None):
    """Run a kernel on a case, print the report, return the exit code (0 pass, 1 fail, 2 bad usage or no driver).

    ``path``: the file (a shipped kernel's bare name is resolved by the caller); ``rows``:
    failing texels listed per driver (``"all"``: every one); ``json_path`` receives every
    texel's verdict per driver (the format of function conformance's ``--json``, one record
    per driver); ``options``: ``--include``/``--define``/``--prelude``; ``strict`` gates the
    texels beyond the algorithm's contract; ``layout`` is the declared output layout of a buffer
    (:mod:`.layout`); ``v2_cell`` the declared √v2 grid of a 32-bit texel (:mod:`.declared`).
    """
    out, err = out or sys.stdout, err or sys.stderr
    try:
        if entry is None:
            raise InputError("conformance: --entry NAME is required with --kernel (GLSL: main)")
        if case is None:
            raise InputError("conformance: --case CASE is required with --kernel")
        keep = 10 ** 9 if rows == "all" else rows
        report = run_kernel(path, entry, case, language, adapter, golden_dir, time_limit, worst_rows=keep,
                            options=options, strict=strict, layout=layout, v2_cell=v2_cell)
        if json_path is not None:
            from ...golden.diagnosis import write_json
            from .verdict import json_records

            write_json(json_path, json_records(report), {"command": "conformance --kernel", "entry": entry,
                                                         "case": case, "path": str(path), "language": language,
                                                         "layout": layout, "v2_cell": v2_cell or "floor128",
                                                         "passed": report.passed})
    except (ContextError, ToolError, InputError) as exc:
        print(f"moments-ref conformance: {exc}", file=err)
        return 2
    except Exception as exc:  # noqa: BLE001 - a harness failure must never read as a failing kernel
        first = next((x.strip() for x in str(exc).splitlines() if x.strip()), "")
        print(f"moments-ref conformance: {path}: the harness failed ({type(exc).__name__}: {first}); "
              "this is not a verdict on the kernel", file=err)
        return 2
    print(report.format(), file=out)
    return 0 if report.passed else 1
