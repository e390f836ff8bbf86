"""``moments-ref conformance``: one case, or ``--all`` shipped ports on every driver."""

from __future__ import annotations

import math
import statistics
import sys
import tempfile
import time
from pathlib import Path


from .._arrays import InputError
from ..ports import PORTS_DIR
from ._cases import load_case
from ._gl import ContextError
from ._report import fmt
from ._run import ALL_LANGUAGES, DRIVERS, SourceOptions, language_of, parse_adapter, run_case, run_function
from ._shipped import not_available, shipped_cases, shipped_port
from ._source import ShaderError
from ._supervisor import using_watchdog
from ._toolchain import ToolError
from .languages import available, compiler_versions, options_phrase

__all__ = ["resolve_port", "run_cli", "harness_failure", "source_options", "main", "summary_markdown", "bench_conformance"]


def resolve_port(path, language):
    """A path as given, or the name of a shipped port (``msm.hlsl``) when no such file exists."""
    p = Path(path)
    shipped = PORTS_DIR / language / p.name
    if not p.exists() and p.parent == Path(".") and shipped.is_file():
        return shipped
    return p


def run_cli(path, function, case, golden_dir=None, out=None, err=None, language=None, adapter=None, options=None,
            profile=None, strict=False, rows=5, json_path=None):
    """Run one case, print the report, return the exit code.

    ``adapter="both"`` runs OpenGL and Vulkan and names the rows on which they
    disagree; ``profile`` (golden.profile.Profile) declares the engine's conventions,
    ``strict`` gates the robustness rows, ``rows`` is the number of failing rows to
    list per category (``"all"``: every one), ``json_path`` receives every row's verdict.

    Returns
    -------
    int
        0 every row within its tolerance (with ``adapter="both"``: on both drivers, which then
        also list the rows where they differ); 1 a tolerance exceeded; 2 no driver or
        compiler (reason on stderr), bad usage (unknown case, missing function, a
        file that does not compile: the compiler's messages, one line per error), or
        any failure of the harness, a compiler or a driver (one line: never a
        traceback, never the exit code of a failing port); a profile it refuses.
    """
    out, err = out or sys.stdout, err or sys.stderr
    try:
        language = language_of(path, language)
        port = resolve_port(path, language)
        keep = None if rows == "all" else rows
        if adapter == "both":
            from ._agree import compare_drivers

            report = compare_drivers(port, function, case, golden_dir, language, options=options, profile=profile,
                                     strict=strict, worst_rows=keep)
            records = [dict(r.record, driver=d) for d, r in report.reports.items()]
        else:
            report = run_case(port, function, case, golden_dir, language, adapter, keep, options=options,
                              profile=profile, strict=strict)
            records = [dict(report.record, driver=report.driver)]
        if json_path is not None:
            from ..golden.diagnosis import write_json

            write_json(json_path, records, {"command": "conformance", "function": function, "path": str(path)})
    except (ContextError, ToolError, InputError) as exc:
        print(f"moments-ref conformance: {exc}", file=err)
        return 2
    except Exception as exc:  # noqa: BLE001 - a harness failure must never read as a failing port
        print(f"moments-ref conformance: {path}: the harness failed ({harness_failure(exc)}); "
              "this is not a verdict on the port", file=err)
        return 2
    print(report.format(), file=out)
    return 0 if report.passed else 1


def harness_failure(exc):
    """One line for an unexpected exception: its type and the first line of its message."""
    first = next((x.strip() for x in str(exc).splitlines() if x.strip()), "")
    return f"{type(exc).__name__}: {first}" if first else type(exc).__name__


def _targets(adapter):
    """``[(language, adapter spec)]`` for ``--all``: every language on every driver, or on ``adapter``.

    ``both`` is every driver, as without ``adapter``. Slang only where its extra is installed
    (:func:`.languages.available`)."""
    adapter = None if adapter == "both" else adapter
    return [(lang, adapter or driver) for lang in ALL_LANGUAGES if available(lang)
            for driver in ((adapter,) if adapter else DRIVERS)]


def _cells(rep):
    cells = []
    for cat in ("random", "edge", "stiff"):
        c = rep.categories.get(cat)
        if c is None or c.rows == 0:
            cells.append("–")
        elif rep.exact:
            cells.append(f"{c.mismatches} differ, {c.ties} ties ({c.rows})")
        else:
            cells.append(f"{fmt(c.worst_score)} ({c.gated}/{c.rows} gated)")
    cells.append(rep.metric)
    return cells


def _refused(language, spec, name, path, function, golden_dir, gc):
    """The declared reason (:data:`NOT_AVAILABLE`) when the harness refuses ``name`` as declared, else None."""
    reason = not_available(name, language, parse_adapter(spec, language).driver)
    if reason is None:
        return None
    try:
        run_case(path, function, name, golden_dir, language, spec, gc=gc)
    except (InputError, ContextError):
        return reason
    return None  # declared but it ran: counted as run, so that the stale declaration shows


def _renderer(renderers):
    """The renderer of a target's runs: the first one, and any other with the cases that ran on it."""
    (first, _), *others = renderers.items() if renderers else ((None, []),)
    return "; ".join([str(first)] + [f"{r} for {', '.join(names)}" for r, names in others])


def _run_all(golden_dir, adapter, progress):
    """Per target: renderer, rows of the table, wall times, outputs per case, refused cases."""
    cases = shipped_cases()
    results = []
    for language, spec in _targets(adapter):
        rows, times, renderers, outputs, refused = [], [], {}, {}, {}
        for name in cases:
            if shipped_port(name, language) is None:
                continue  # no shipped port of this function in this language (languages.TABLE)
            path, function = shipped_port(name, language)
            gc = load_case(name, golden_dir)
            reason = _refused(language, spec, name, path, function, golden_dir, gc)
            if reason is not None:
                refused[name] = reason
                rows.append(f"| {name} | `{function}` | – | – | – | – | not available on this driver: {reason} |")
                continue
            t0 = time.perf_counter()
            try:
                rep = run_case(path, function, name, golden_dir, language, spec, gc=gc)
            except (ContextError, ToolError) as exc:  # no driver or compiler here: the rest of the target still runs
                rows.append(f"| {name} | `{function}` | – | – | – | – | not run: {harness_failure(exc)} |")
                continue
            except ShaderError as exc:  # a shipped port this driver does not compile: a failure of the port
                rows.append(f"| {name} | `{function}` | – | – | – | {harness_failure(exc)} | FAIL |")
                continue
            except Exception as exc:  # noqa: BLE001 - a harness failure is no verdict on the port
                rows.append(f"| {name} | `{function}` | – | – | – | – | not run: the harness failed "
                            f"({harness_failure(exc)}) |")
                continue
            times.append(time.perf_counter() - t0)
            renderers.setdefault(rep.renderer, []).append(name)
            outputs[name] = rep.outputs
            rows.append(f"| {name} | `{function}` | {' | '.join(_cells(rep))} | {'pass' if rep.passed else 'FAIL'} |")
        results.append((language, parse_adapter(spec, language).driver, _renderer(renderers), rows, times, outputs,
                        refused))
        if progress:
            print(f"  {language} on {results[-1][1]}: {len(times)} cases in {sum(times):.1f} s, {len(refused)} not "
                  "available", file=sys.stderr)
    return results


def _differing_rows(a, b):
    """Rows whose outputs differ in any bit between two runs, over the cases both ran (a row counts once)."""
    from ._record import _rows_differing

    counts = {}
    for name in (n for n in a if n in b):
        d = int(_rows_differing(a[name], b[name]).sum())
        if d:
            counts[name] = d
    return counts


def _agreement_table(results):
    """Per language: how many golden rows the two drivers compute bit-identically."""
    by = {(lang, drv): out for lang, drv, _, _, _, out, _ in results}
    lines = ["| language | rows | differing between gl and vulkan | in cases |", "|---|---:|---:|---|"]
    for lang in ALL_LANGUAGES:
        if (lang, "gl") not in by or (lang, "vulkan") not in by:
            continue
        gl = by[(lang, "gl")]
        total = sum(len(next(iter(v.values()))) for k, v in gl.items() if k in by[(lang, "vulkan")])
        d = _differing_rows(gl, by[(lang, "vulkan")])
        cells = ", ".join(f"{k} ({v})" for k, v in d.items()) or "–"
        lines.append(f"| {lang} | {total} | {sum(d.values())} | {cells} |")
    return lines


def _timing_table(results, total):
    lines = ["| language | driver | renderer | cases | run | not available on this driver | failed | first run s | "
             "later runs: median s | max s |", "|---|---|---|---:|---:|---:|---:|---:|---:|---:|"]
    for language, driver, renderer, rows, times, _, refused in results:
        failed = sum(r.endswith("| FAIL |") for r in rows)
        later = times[1:] or times or [math.nan]
        lines.append(f"| {language} | {driver} | {renderer} | {len(rows)} | {len(times)} | {len(refused)} | {failed} | "
                     f"{(times or later)[0]:.3f} | {statistics.median(later):.3f} | {max(later):.3f} |")
    later = [t for r in results if r[1] == "vulkan" for t in r[4][1:]]
    lines += ["", f"Whole run (golden generation included): {total:.1f} s (target: under 60 s). One case after "
              f"the first on lavapipe: at most {max(later, default=math.nan):.3f} s (target: under 2 s). The first "
              "run on a driver creates its context or adapter; HLSL on Vulkan reuses the SPIR-V compiled for OpenGL."]
    return lines


def _refusal_lines(results):
    """The shipped cases a language cannot run on a driver, as declared and as the harness refused them."""
    refused = [(lang, drv, name, why) for lang, drv, _, _, _, _, r in results for name, why in r.items()]
    if not refused:
        return []
    lines = ["", "## Not available on a driver", "",
             "Shipped cases a language cannot run on a driver (`conformance.NOT_AVAILABLE`): the harness refuses",
             "them with one line before any verdict, and each was refused so in this run. They count in",
             "`cases`, not in `run`; the same port passes them on the other driver.", "",
             "| language | driver | case | why |", "|---|---|---|---|"]
    return lines + [f"| {lang} | {drv} | {name} | {why} |" for lang, drv, name, why in refused]


def summary_markdown(golden_dir=None, adapter=None, progress=False, probes=True, record=None, gpu_record=None):
    """Run every shipped port of every language on every driver; docs/conformance.md as text.

    ``moments-ref conformance --all --out docs/`` writes it, so that the numbers are
    regenerated, never typed. ``record``: also write this run, with every shipped kernel's,
    to that file (:mod:`._record`); ``gpu_record``: such a file from another machine (a GPU),
    whose verdicts, probes and differences from this run become a last section.
    """
    from .. import golden
    from . import _record

    gpu = _record.load(gpu_record) if gpu_record is not None else None  # refused before the long run
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="moments-ref-all-") as tmp:
        if golden_dir is None:
            golden.write(tmp, shipped_cases())
            golden_dir = tmp
        results = _run_all(golden_dir, adapter, progress)
    probe_lines = []
    if probes:
        from ._probes import probe_markdown

        probe_lines = ["", probe_markdown()]
    total = time.perf_counter() - t0  # the run the timing table states, without the kernels
    kernels = _record.kernel_runs(adapter, progress) if record is not None or gpu is not None else []
    if record is not None:
        _record.save(record, results, kernels, probe_lines[-1] if probes else "", compiler_versions(),
                     time.perf_counter() - t0)
    tools = ", ".join(f"{k}: {v}" for k, v in compiler_versions().items()) or "none found"
    command = f" --gpu-record {Path(gpu_record).as_posix()}" if gpu is not None else ""
    lines = ["# Conformance of the shipped ports", "",
             f"Generated by `moments-ref conformance --all --out docs/{command}`; do not edit by hand. Every shipped",
             "port (`moments_ref/ports/glsl|hlsl|wgsl|slang/`) runs on every golden case it covers, on every driver",
             "that can run it (\"Not available on a driver\" lists the others and why). Slang ships Algorithm 1,",
             "Algorithm 3 and the texel formats (msm, nonlinear, packing) and runs where its optional extra is",
             "installed (`pip install -e \".[slang]\"`; docs/ports.md, \"Slang\").",
             "The verdict is `moments_ref.golden.compare`, the comparator of `verify` and `oracle.check`:",
             "per-row float32 tolerances stored in the golden files, rounding ties accepting the codes stored",
             "for them. Per row category: the worst error/tolerance ratio (above 1 fails) and how many rows",
             "are gated (the others only need a finite value in range); integer outputs: rows whose codes",
             "differ from the golden code, and of those the rounding ties accepted. docs/ports.md explains",
             "the toolchain and what these drivers do not show; a GPU's run, recorded there with `--record FILE`,",
             "becomes a last section with `--gpu-record FILE`, row by row against this one.", "",
             f"Compilers: {tools}.", "", "## Timings", "",
             "Wall time of one `run_case` (compile, upload, dispatch, readback, compare); compiled",
             "programs are cached per process, so a later run of the same function skips the compile.", ""]
    lines += _timing_table(results, total)
    lines += _refusal_lines(results)
    lines += ["", "## The two drivers agree", "",
              "Golden rows whose outputs differ in any bit between OpenGL and Vulkan (same source file; both",
              "pass). For HLSL this compares OpenGL reading glslang's SPIR-V as written with wgpu's SPIR-V",
              "reader; the suite pins that every row agrees (docs/ports.md, \"Toolchain\").", ""]
    lines += _agreement_table(results)
    lines += probe_lines
    for language, driver, renderer, rows, _, _, _ in results:
        lines += ["", f"## {language.upper()} on {driver}", "", f"Renderer: {renderer}.", "",
                  "| case | function | random | edge | stiff | metric | result |",
                  "|---|---|---|---|---|---|---|", *rows]
    if gpu is not None:
        lines += _record.gpu_markdown(*gpu, results, kernels, Path(gpu_record).as_posix())
    return "\n".join(lines) + "\n"


def main(args):
    """Entry for the CLI: ``args`` has ``glsl``/``hlsl``/``wgsl``, ``function``, ``case``,
    ``golden``, ``adapter``, ``all`` and ``out`` (absent ones count as None); ``watchdog``
    (or its old name ``time_limit``) holds for this run only."""
    get = lambda k: getattr(args, k, None)  # noqa: E731
    with using_watchdog(get("watchdog")), using_watchdog(get("time_limit"), "time_limit"):
        return _main(args)


def _main(args):
    get = lambda k: getattr(args, k, None)  # noqa: E731
    loose = [f"--{k.replace('_', '-')}" for k in ("record", "gpu_record") if get(k) is not None and not get("all")]
    if loose:
        raise InputError(f"conformance: {loose[0]} is for --all (a record holds every shipped port's run)")
    if get("kernel"):
        from .kernel.cli import kernel_cli

        files = [(lang, get(lang)) for lang in ALL_LANGUAGES if get(lang) is not None]
        if len(files) != 1:
            raise InputError(f"conformance: --kernel expects one of {options_phrase()} FILE, got {len(files)}")
        language, path = files[0]
        _refuse_for_kernels(args)
        declared = _kernel_declared(args)
        return kernel_cli(resolve_port(path, language), get("entry"), get("case"), language, get("golden"),
                          get("adapter"), rows=get("rows") if get("rows") is not None else 5, json_path=get("json"),
                          options=source_options(args), strict=bool(get("strict")), layout=declared["layout"],
                          v2_cell=declared.get("v2_cell"))
    if get("all"):
        from .._io import write_text

        given = [f"--{lang}" for lang in ALL_LANGUAGES if get(lang) is not None]
        if given:  # --all runs the shipped ports: a port named beside it would silently go untested
            raise InputError(f"conformance: --all runs the shipped ports; {given[0]} FILE cannot be given with it "
                             f"(drop --all to test {get(given[0][2:])})")

        try:
            text = summary_markdown(golden_dir=get("golden"), adapter=get("adapter"), progress=True,
                                    record=get("record"), gpu_record=get("gpu_record"))
        except (ContextError, ToolError, InputError) as exc:
            print(f"moments-ref conformance: {exc}", file=sys.stderr)
            return 2
        except Exception as exc:  # noqa: BLE001 - a harness failure is exit 2, one line
            print(f"moments-ref conformance: the harness failed ({harness_failure(exc)})", file=sys.stderr)
            return 2
        print(text)
        if get("out"):
            print(f"wrote {write_text(Path(get('out')) / 'conformance.md', text)}")
        return 2 if "| not run: " in text else 1 if "| FAIL |" in text else 0
    if get("kernel_layout"):
        raise InputError("conformance: --kernel-layout is the output layout of a kernel (with --kernel)")
    files = [(lang, get(lang)) for lang in ALL_LANGUAGES if get(lang) is not None]
    if len(files) != 1:
        raise InputError(f"conformance: expected one of {options_phrase()} FILE (or --all), got {len(files)}")
    missing = [a for a in ("function", "case") if get(a) is None]
    if missing:
        raise InputError(f"conformance: --{missing[0]} is required (or use --all)")
    language, path = files[0]
    from ..golden.cases import CASES
    from ..golden.profile import FLAGS, flag_keys, profile_from_args, refuse_meaningless

    flags = {f[2:].replace("-", "_"): get(f[2:].replace("-", "_")) for f, _, _ in FLAGS}
    profile = profile_from_args(get("profile"), get("function"), **flags)
    if get("case") in CASES:  # a flag is this run's declaration: refused where the case cannot use it
        refuse_meaningless([CASES[get("case")]], profile, flag_keys(flags))
    return run_cli(path, get("function"), get("case"), get("golden"), language=language, adapter=get("adapter"),
                   options=source_options(args), profile=profile, strict=bool(get("strict")),
                   rows=get("rows") if get("rows") is not None else 5, json_path=get("json"))


def _refuse_for_kernels(args):
    """Exit 2 (an :class:`InputError`) for the options of function conformance that a kernel cannot take."""
    from ..golden.profile import FLAGS

    get = lambda k: getattr(args, k, None)  # noqa: E731
    if get("function") is not None:
        raise InputError("conformance: --function is for functions; a kernel's entry point is --entry NAME")
    if get("all"):
        raise InputError("conformance: --all runs the shipped functions; run each kernel with --kernel")
    if get("uniform"):
        raise InputError("conformance: --uniform gives values to a function's uniforms; a kernel's uniform block is "
                         "the case's own (docs/ports.md, \"Kernels\")")
    if get("adapter") == "as-written":
        raise InputError("conformance: --adapter as-written is for functions; kernels run on gl, vulkan or both")
    flags = [f for f, _, _ in FLAGS if get(f[2:].replace("-", "_")) is not None and f != "--format-v2-cell"]
    if flags:
        raise InputError(f"conformance: {flags[0]} declares an engine's convention for functions; the kernel cases "
                         "fix theirs (a kernel profile declares only its [kernel] table and [format] v2_cell: "
                         "docs/ports.md, \"Kernels\")")


def _kernel_declared(args):
    """``{"layout": ..., "v2_cell": ...}``: the output layout declared by ``--kernel-layout`` or the ``[kernel]``
    table of ``--profile``, and the √v2 grid of its ``[format]`` table (exit 2 for any other profile key: the
    kernel cases fix the engine's other conventions)."""
    from ..golden.cells import V2_CELLS
    from .kernel.declared import kernel_profile

    get = lambda k: getattr(args, k, None)  # noqa: E731
    declared = kernel_profile(get("profile")) if get("profile") is not None else {}
    cell = get("format_v2_cell") or declared.get("v2_cell")
    if cell is not None and cell not in V2_CELLS:
        raise InputError(f"conformance: --format-v2-cell: expected one of {', '.join(V2_CELLS)}, got {cell!r}")
    return {**declared, "layout": get("kernel_layout") or declared.get("layout", "interleaved"), "v2_cell": cell}


def source_options(args):
    """:class:`SourceOptions` from the CLI's ``--include``, ``--define``, ``--prelude``, ``--max-source``,
    ``--keep-unused`` and ``--uniform`` (absent ones take their defaults); a function's ``--profile`` adds its
    ``[uniforms]`` table, under the command line's values."""
    from ._uniforms import merge_uniforms, profile_uniforms

    get = lambda k: getattr(args, k, None)  # noqa: E731
    items, origin = profile_uniforms(get("profile")) if get("profile") and not get("kernel") else ((), "")
    uniforms, origins = merge_uniforms(tuple(get("uniform") or ()), items, origin)
    return SourceOptions(tuple(get("include") or ()), tuple(get("define") or ()), get("prelude"),
                         get("max_source"), bool(get("keep_unused")), uniforms=uniforms,
                         uniform_origins=tuple(origins.items()))


def bench_conformance(cases=None, repeat=3, ctx=None, language="glsl", adapter=None):
    """Time the shipped ports on their golden cases: compile, upload, dispatch, readback.

    Returns
    -------
    list of dict
        Per case ``case``, ``function``, ``rows``, ``compile_s``, ``upload_s``,
        ``dispatch_s``, ``readback_s`` (seconds, best of ``repeat``) and
        ``renderer``. Raises :class:`ContextError` without a driver.
    """
    from .. import golden

    names = list(cases) if cases is not None else shipped_cases(("float32",))
    rows = []
    with tempfile.TemporaryDirectory(prefix="moments-ref-bench-") as tmp:
        golden.write(tmp, names)
        for name in names:
            port = shipped_port(name, language)
            if port is None:
                raise InputError(f"cases: no shipped {language.upper()} port for {name!r}")
            gc = load_case(name, tmp)
            best = {}
            for _ in range(max(1, repeat)):
                _, t = run_function(port[0], port[1], gc.inputs, gc.output_specs(), language, adapter)
                for k, v in t.items():
                    best[k] = min(best.get(k, math.inf), v)
            rep = run_case(port[0], port[1], name, tmp, language, adapter, gc=gc)
            rows.append({"case": name, "function": port[1], "rows": len(gc.category),
                         **{f"{k}_s": v for k, v in best.items()}, "renderer": rep.renderer})
    return rows
