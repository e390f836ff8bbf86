"""The ``moments-ref`` command: thin subcommands over library functions.

Exit codes: 0 done, 1 a verification found differences, 2 bad usage or bad
input (one-line reason on stderr).

Every expected failure ends in :func:`main`, the one place that turns it into
exit 2 and one line: :class:`InputError`, an ``OSError`` on a path (missing,
unreadable, a folder where a file was expected), a ``MemoryError`` (beyond the
estimates that refuse large parameters up front), and a closed output pipe
(``moments-ref bench | head -1``). Before any work starts, :func:`check_outputs`
makes sure ``--out`` is a folder that can be written, and the numeric options are
range-checked by argparse.

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

import argparse
import contextlib
import os
import signal
import sys
import tempfile
import threading
import warnings
from pathlib import Path

from ._arrays import InputError, format_bytes, one_line, parse_bytes, set_max_memory
from ._options import add_report_arguments, folder_arg


def _progress(total, desc):
    """A tqdm progress bar on stderr (silent when stderr is not a terminal)."""
    from tqdm import tqdm

    return tqdm(total=total, desc=desc, unit="step", file=sys.stderr, disable=None, leave=False)


def _int_in(lo, hi=None):
    """argparse type: an integer in ``lo..hi``."""
    def parse(text):
        try:
            v = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None
        if v < lo or (hi is not None and v > hi):
            want = f">= {lo}" if hi is None else f"in {lo}..{hi}"
            raise argparse.ArgumentTypeError(f"expected an integer {want}, got {v}")
        return v
    return parse


def _memory(text):
    """argparse type of ``--max-memory``: ``8G``, ``512M`` or a byte count."""
    try:
        return parse_bytes(text, "size")
    except InputError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def check_outputs(out) -> None:
    """Refuse an ``--out`` folder that is not a folder or cannot be written, before any work.

    Creates the folder (as the command would) and writes and removes a probe file.
    """
    if out is None:
        return
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise InputError(f"--out: expected a folder, got the existing file {out}")
    try:
        out.mkdir(parents=True, exist_ok=True)
        fd, probe = tempfile.mkstemp(prefix=".write-probe.", dir=out)
        os.close(fd)
        os.unlink(probe)
    except OSError as exc:
        raise InputError(f"--out: cannot write to folder {out} ({exc.strerror or exc})") from None


def _cmd_golden(args):
    from . import golden

    profile = _profile(args)
    names = list(golden.CASES) if not args.case else args.case
    with _progress(len(names), "golden") as bar:
        manifest = golden.write(args.out, names if args.case else None, progress=lambda name: bar.update(1),
                                profile=profile)
    n_rows = sum(c["count"] for c in manifest["cases"].values())
    print(f"wrote {len(manifest['cases'])} cases ({n_rows} rows) and manifest.json to {args.out}")
    if manifest.get("not_written"):
        print(f"not written: {len(manifest['not_written'])} cases whose conventions the profile contradicts")
    return 0


def _profile(args):
    """The profile of ``--profile FILE`` and the per-key flags (golden.profile), for ``--function``."""
    from .golden.profile import FLAGS, profile_from_args

    flags = {f[2:].replace("-", "_"): getattr(args, f[2:].replace("-", "_"), None) for f, _, _ in FLAGS}
    return profile_from_args(getattr(args, "profile", None), getattr(args, "function", None), **flags)


def _add_profile_keys(sp):
    """``--profile FILE`` and one flag per profile key (docs/ports.md)."""
    from .golden.profile import FLAGS

    sp.add_argument("--profile", type=Path, metavar="FILE.toml", help="the engine's conventions (docs/ports.md)")
    for flag, _, text in FLAGS:
        sp.add_argument(flag, metavar="VALUE", help=text)


def _add_profile(sp):
    """``--profile FILE``, one flag per profile key, ``--strict``, ``--rows``, ``--json`` (docs/ports.md)."""
    _add_profile_keys(sp)
    sp.add_argument("--strict", action="store_true",
                    help="gate the rows beyond the algorithm's contract too (robustness rows)")
    sp.add_argument("--rows", type=_rows_arg, default=None, metavar="N|all",
                    help="failing rows to list per case (default 5; all: every one)")
    sp.add_argument("--json", type=Path, metavar="FILE", help="write every row's verdict as JSON")


def _rows_arg(text):
    if text == "all":
        return "all"
    return _int_in(0)(text)


def _cmd_verify(args):
    from . import golden
    from .golden.diagnosis import write_json

    report = golden.verify(args.golden, args.results, port_dtype=args.dtype, strict=args.strict,
                           profile=_profile(args))
    rows = args.rows if args.rows is not None else args.worst
    print(report.format(worst_rows=None if rows == "all" else rows))
    if args.json:
        write_json(args.json, [c.record for c in report.checked], {"command": "verify"})
    return 1 if report.failed else 0


def _cmd_mutants(args):
    from .golden import mutation

    text, ok = mutation.report(args.corpus)
    print(text)
    return 0 if ok else 1


def _cmd_bench(args):
    from .tools import bench

    unknown = [o for o in args.only or () if not any(o in n for n in bench.only_names())]
    if unknown:
        raise InputError(f"--only: no benchmark name contains {unknown[0]!r}; names: {', '.join(bench.only_names())}")
    if args.out:  # a FIFO or a link to /dev/zero named bench.md: refused before any work, never read
        from ._io import check_own

        check_own(Path(args.out) / "bench.md")
        if (Path(args.out) / "bench.md").is_dir():
            raise InputError(f"--out: {Path(args.out) / 'bench.md'} is a folder; bench writes its file there")

    rows = bench.run(size=args.size, quick=args.quick, only=args.only,
                     progress=lambda total: _progress(total, "bench"))
    text = bench.markdown(rows)
    if not args.only or any("end_to_end" in o for o in args.only):
        size = min(args.size, 512) if args.quick else args.size
        text += "\n" + bench.end_to_end_markdown(bench.end_to_end(size, 4), size, 4)
    if not args.only or any("targets" in o for o in args.only):
        runs = [bench.run_targets(quick=args.quick, groups=bench.target_groups(args.only)) for _ in range(args.runs)]
        text += "\n" + bench.targets_markdown(runs[-1])
        if len(runs) > 1:
            text += "\n" + bench.agreement_markdown(runs)
    if not args.only or any("conformance" in o for o in args.only):
        text += "\n" + bench.conformance_markdown(repeat=1 if args.quick else 3)
    if not args.only or any("kernels" in o for o in args.only):
        text += "\n" + bench.kernels_markdown(size=min(args.size, 512) if args.quick else args.size)
    if not args.only or any("sweep" in o for o in args.only):
        from .sweep.timing import sweep_markdown

        text += "\n" + sweep_markdown(chunks=1 if args.quick else 4)
    print(text)
    if args.out:
        from ._io import write_text

        target = Path(args.out) / "bench.md"
        path = write_text(target, bench.keep_history(text, target))
        print(f"wrote {path}")
    return 0


def _cmd_stability(args):
    from .tools import stability

    path = stability.main(args.out)
    print(f"wrote {path}")
    return 0


def _cmd_figure3(args):
    from .tools import figures

    paths = figures.write_figure3(args.out)
    print("wrote " + ", ".join(str(p) for p in paths))
    return 0


def _cmd_figure4(args):
    from .tools import figures

    paths = figures.write_figure4(args.out, scene=args.scene, size=args.size, samples=args.samples)
    print("wrote " + ", ".join(str(p) for p in paths))
    print(paths[2].read_text(encoding="utf-8"))
    return 0


def _cmd_banks(args):
    from .gpu import banks

    text = banks.main()
    print(text)
    if args.out:
        from ._io import write_text

        print(f"wrote {write_text(Path(args.out) / 'banks.md', text)}")
    return 0


def _main_of(module):
    """A command that runs ``module``'s ``main(args)``, imported only when the command runs (a fast --help)."""
    def run(args):
        import importlib

        return importlib.import_module(module, __package__).main(args)
    return run


class _Parser(argparse.ArgumentParser):
    """argparse with bad usage reported in one line (exit 2), the usage left to ``--help``."""

    def error(self, message):
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def build_parser():
    p = _Parser(
        prog="moments-ref",
        description="Reference implementation and test oracle of moment shadow mapping.",
    )
    sub = p.add_subparsers(dest="command", metavar="COMMAND", required=True)

    _add_jobs(sub)
    _add_oracle(sub)
    _add_measurements(sub)
    _add_common(sub)
    return p


def _add_jobs(sub):
    """The main jobs: the report and the VWSS comparison."""
    rp = sub.add_parser("report", help="error against run time of every technique on the shipped scenes (main job)")
    add_report_arguments(rp)
    rp.set_defaults(func=_main_of(".report"))

    vw = sub.add_parser("vwss", help="view-warped soft shadows against MVR and PCSS (VWSS Tables 1 and 2)")
    vw.add_argument("--scene", default="knot", help="scene name or file with an area light (default knot)")
    vw.add_argument("--views", type=_int_in(1), default=None, help="light samples (default: 24 and 128; --quick: fewer)")
    vw.add_argument("--quick", action="store_true", help="reduced resolution, under a minute on knot")
    vw.add_argument("--near", type=float, default=None,
                    help="the light's near plane z_n in world units (VWSS Listing 1 light.nearZ; default: the "
                         "scene's params.light_near)")
    vw.add_argument("--out", required=True, type=folder_arg, help="output folder")
    vw.set_defaults(func=_main_of(".report.vwss"))


def _add_oracle(sub):
    """Golden vectors, verification, the mutation score and the driver harness."""
    g = sub.add_parser("golden", help="write golden vectors and manifest.json")
    g.add_argument("--out", required=True, type=folder_arg, help="output folder")
    g.add_argument("--case", action="append", help="only this case (repeatable)")
    g.add_argument("--function", help="the tested function: selects the profile's [functions.NAME] table")
    g.add_argument("--profile", type=Path, metavar="FILE.toml", help="write the cases for an engine's conventions")
    from .golden.profile import FLAGS

    for flag, _, text in FLAGS:
        g.add_argument(flag, metavar="VALUE", help=text)
    g.set_defaults(func=_cmd_golden)

    v = sub.add_parser("verify", help="compare a port's results (.npz) with the goldens")
    v.add_argument("--golden", required=True, type=Path, help="folder written by 'golden'")
    v.add_argument("--results", required=True, type=Path, help=".npz with arrays '<case>.<output>'")
    v.add_argument("--dtype", choices=("float32", "float64"), help="the port's precision (default: each case's)")
    v.add_argument("--worst", type=_int_in(0), default=5, help="worst rows to print per failing case")
    v.add_argument("--function", help="the tested function: selects the profile's [functions.NAME] table")
    _add_profile(v)
    v.add_argument("--out", type=folder_arg, help="unused; accepted for uniformity")
    v.set_defaults(func=_cmd_verify)

    mu = sub.add_parser("mutants", help="mutation score of the oracle: which golden rows kill which port mutant")
    mu.add_argument("--corpus", type=Path, help="folder with corpus.py (default: tests/mutants of the source tree)")
    mu.add_argument("--out", type=folder_arg, help="unused; accepted for uniformity")
    mu.set_defaults(func=_cmd_mutants)

    cf = sub.add_parser("conformance", help="run a GLSL, HLSL, WGSL or Slang port (a function, or with --kernel a compute "
                                            "shader) on a real driver against a golden case")
    _add_port(cf)
    cf.add_argument("--golden", type=Path, default=None, help="golden folder (default: generate the case)")
    cf.add_argument("--kernel", action="store_true",
                    help="FILE is a compute shader to run on a kernel case (kernel-filter-*, kernel-vwss-points)")
    cf.add_argument("--entry", help="with --kernel: the compute entry point (GLSL: main)")
    cf.add_argument("--kernel-layout", choices=("interleaved", "planar", "packed16"), default=None,
                    help="with --kernel: how an output buffer holds the texels (default interleaved; docs/ports.md)")
    cf.add_argument("--time-limit", type=float, default=None, metavar="SECONDS",
                    help="deprecated alias of --watchdog (kept for old scripts)")
    cf.add_argument("--all", action="store_true", help="every shipped port of every language on every driver")
    _add_profile(cf)
    cf.add_argument("--out", type=folder_arg, help="with --all: also write conformance.md here")
    for flag, text in (("--record", "also write this run, kernels and probes included, to FILE (.npz)"),
                       ("--gpu-record", "a --record FILE of a GPU: its run and its differences from this one")):
        cf.add_argument(flag, type=Path, metavar="FILE", help=f"with --all: {text} (docs/ports.md)")
    _add_source_options(cf)
    cf.set_defaults(func=_main_of(".conformance"))

    sw = sub.add_parser("sweep", help="judge a port on millions of engine-like rows; confirm and shrink each failure "
                                      "(docs/sweep.md)")
    _add_port(sw)
    _add_profile_keys(sw)
    from .sweep.command import add_options

    add_options(sw, _int_in, folder_arg)
    sw.add_argument("--json", type=Path, metavar="FILE", help="write the result as JSON")
    _add_source_options(sw)
    sw.set_defaults(func=_main_of(".sweep.command"))


def _add_port(sp):
    """The port arguments of ``conformance`` and ``sweep``: the file, the function, the case, the driver."""
    lang = sp.add_mutually_exclusive_group()
    lang.add_argument("--glsl", metavar="FILE", help="GLSL file, or a shipped port's name (msm.glsl, nonlinear.glsl ...)")
    lang.add_argument("--hlsl", metavar="FILE", help="HLSL file, or a shipped port's name (msm.hlsl ...)")
    lang.add_argument("--wgsl", metavar="FILE", help="WGSL file, or a shipped port's name (msm.wgsl ...)")
    lang.add_argument("--slang", metavar="FILE", help="Slang file, or a shipped port's name (msm.slang ...); "
                                                     'needs the extra: pip install -e ".[slang]"')
    sp.add_argument("--function", help="the function to test")
    sp.add_argument("--case", help="golden case, e.g. shade-float32")
    sp.add_argument("--adapter", help="driver: gl, vulkan, vulkan:NAME, an adapter name, both (gl and vulkan, "
                                      "and the rows where they differ), as-written or cpu (Slang functions via C++)")


def _add_source_options(cf):
    """How ``conformance`` reads a shader file (docs/ports.md, "What your file may contain")."""
    cf.add_argument("--include", action="append", metavar="DIR", type=Path,
                    help="also search includes here (after the including file's folder; repeatable)")
    cf.add_argument("--define", action="append", metavar="NAME=VALUE",
                    help="#define NAME VALUE before the file (engine macros; repeatable; GLSL, HLSL)")
    cf.add_argument("--prelude", metavar="FILE", type=Path, help="a file placed before yours (engine macros)")
    cf.add_argument("--uniform", action="append", metavar="NAME=VALUE",
                    help="a value for a uniform, constant-buffer or push-constant member the function reads "
                         "(a vector: NAME=a,b,c,d; repeatable)")
    cf.add_argument("--max-source", type=_memory, default=None, metavar="SIZE",
                    help="largest source with its prelude and includes (default 4M)")
    cf.add_argument("--keep-unused", action="store_true",
                    help="compile every declaration of the file, not only those the function uses")
    cf.add_argument("--watchdog", type=float, default=None, metavar="SECONDS",
                    help="longest one dispatch may run before the driver process is stopped, for functions and "
                         "kernels (default 10)")


def _add_measurements(sub):
    """Benchmarks, numerical-honesty tables and the paper figures."""
    b = sub.add_parser("bench", help="throughput against a same-run memory copy")
    b.add_argument("--out", type=folder_arg, help="also write bench.md here")
    b.add_argument("--size", type=_int_in(1, 16384), default=2048, help="square input side, 1..16384 (default 2048)")
    b.add_argument("--quick", action="store_true", help="one repetition, small sizes")
    b.add_argument("--only", action="append",
                   help="only benchmarks whose name contains this (targets-raster: one group of the targets)")
    b.add_argument("--runs", type=_int_in(1, 10), default=1,
                   help="measure the speed targets this many times in a row and say whether they agree (default 1)")
    b.set_defaults(func=_cmd_bench)

    s = sub.add_parser("stability", help="float32/float64 against mpmath: write stability.md")
    s.add_argument("--out", required=True, type=folder_arg, help="output folder (docs/ in the repo)")
    s.set_defaults(func=_cmd_stability)

    f3 = sub.add_parser("figure3", help="HPG17 Figure 3 as CSV and PNG")
    f3.add_argument("--out", required=True, type=folder_arg, help="output folder")
    f3.set_defaults(func=_cmd_figure3)

    f4 = sub.add_parser("figure4", help="HPG17 Figure 4: histograms of xi4 and Psi4(xi4), CSV and PNG")
    f4.add_argument("--out", required=True, type=folder_arg, help="output folder")
    f4.add_argument("--scene", default="railing", help="shipped scene name or scene file (default railing)")
    f4.add_argument("--size", type=_int_in(1, 16384), default=2048, help="shadow-map side (default 2048, as HPG17)")
    f4.add_argument("--samples", type=int, choices=(1, 4, 8), default=4, help="MSAA samples (default 4)")
    f4.set_defaults(func=_cmd_figure4)

    bk = sub.add_parser("banks", help="bank conflicts of the 40×32 shared-memory layout (HPG17 Fig. 6)")
    bk.add_argument("--out", type=folder_arg, help="also write banks.md here")
    bk.set_defaults(func=_cmd_banks)


def _add_common(sub):
    """Options every subcommand takes."""
    for sp in sub.choices.values():
        sp.add_argument("--max-memory", type=_memory, default=None, metavar="SIZE",
                        help="refuse work estimated to need more memory than this (e.g. 8G; default 4G)")


def _fail(args, reason) -> int:
    print(one_line(f"moments-ref {getattr(args, 'command', '')}: {reason}"), file=sys.stderr)
    return 2


def _os_reason(exc: OSError) -> str:
    where = f" {exc.filename}" if exc.filename else ""
    return f"cannot use{where}: {exc.strerror or exc}"


def _run(args) -> int:
    """Set the memory limit, check the outputs and inputs, run the subcommand."""
    if args.max_memory is not None:
        set_max_memory(args.max_memory)
    if args.command == "figure4":
        from .scene.files import shadow_map_memory
        from ._arrays import check_memory

        check_memory(shadow_map_memory(args.size, args.samples), f"figure4 --size {args.size} --samples {args.samples}")
    check_outputs(getattr(args, "out", None))
    from ._io import check_output

    for name in ("json", "record"):  # a folder, socket or dangling link: refused before any work
        if getattr(args, name, None) is not None:
            check_output(getattr(args, name), f"--{name}")
    if getattr(args, "json", None) is not None:
        _json_is_no_input(args)
    code = args.func(args)
    sys.stdout.flush()  # a closed pipe shows here, inside the handler, not at exit
    return code


def _json_is_no_input(args):
    """Refuse a ``--json`` target that is one of the command's inputs (``--json r.npz`` with ``--results r.npz``
    would replace the port's results by the verdicts)."""
    golden = getattr(args, "golden", None)
    inputs = [getattr(args, k, None) for k in ("results", "profile", "glsl", "hlsl", "wgsl", "prelude")]
    inputs += [Path(golden) / "manifest.json"] if golden else []
    for p in inputs:
        with contextlib.suppress(OSError, TypeError):
            if p is not None and os.path.samefile(p, args.json):
                raise InputError(f"--json: {args.json} is an input of the command ({p}); refusing to overwrite it")


class Terminated(BaseException):
    """SIGTERM or SIGHUP, raised where the command is (like ``KeyboardInterrupt`` for SIGINT), so that its
    temporaries are removed and its workers stopped before it exits."""


def _raise_terminated(signum, frame):
    raise Terminated(signum)


@contextlib.contextmanager
def _signals_raise():
    """SIGTERM and SIGHUP raise :class:`Terminated` during the block (in the main thread only)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    old = {s: signal.signal(s, _raise_terminated) for s in (signal.SIGTERM, signal.SIGHUP)}
    try:
        yield
    finally:
        for s, handler in old.items():
            signal.signal(s, handler)


#: ASCII for the non-ASCII characters of the command's output (labels, tables), on a stream that cannot encode them.
_ASCII = {"²": "^2", "³": "^3", "×": "x", "ξ": "xi", "Ψ": "Psi", "ψ": "psi", "Φ": "Phi", "φ": "phi", "σ": "sigma",
          "α": "alpha", "β": "beta", "λ": "lambda", "μ": "mu", "Δ": "Delta", "δ": "delta", "ε": "eps", "θ": "theta",
          "π": "pi", "≤": "<=", "≥": ">=", "≈": "~", "−": "-", "–": "-", "—": "-", "…": "...", "±": "+-", "→": "->",
          "·": "*", "√": "sqrt", "∞": "inf", "‖": "||", "’": "'", "“": '"', "”": '"', "°": " deg", "⁴": "^4"}


def _ascii_fallback(exc):
    """codecs error handler: the ASCII spelling of characters the stream's encoding lacks (``?`` for others)."""
    return "".join(_ASCII.get(c, "?") for c in exc.object[exc.start:exc.end]), exc.end


def _usable_streams():
    """Closed standard streams (``>&-``) become /dev/null, and a stream that cannot encode the output (a C
    locale, ``PYTHONIOENCODING=ascii``) writes its ASCII spelling: the output degrades, never crashes."""
    import codecs

    codecs.register_error("moments_ref_ascii", _ascii_fallback)
    for fd, name in ((0, "stdin"), (1, "stdout"), (2, "stderr")):
        try:
            os.fstat(fd)
        except OSError:  # closed: plug it, so that no file the command opens takes its number
            new = os.open(os.devnull, os.O_RDWR)
            if new != fd:
                os.dup2(new, fd)
                os.close(new)
        stream = getattr(sys, name)
        if stream is None:
            setattr(sys, name, open(fd, "r" if fd == 0 else "w", closefd=False, encoding="utf-8"))
        elif fd and hasattr(stream, "reconfigure") and (stream.encoding or "").lower().replace("-", "") != "utf8":
            with contextlib.suppress(Exception):
                stream.reconfigure(errors="moments_ref_ascii")


def main(argv=None):
    """Run ``moments-ref`` with ``argv``; return the exit code.

    Warnings raised during the command are held and printed after it, and only
    when it did not end in the one-line refusal (exit 2): no NumPy warning
    precedes that line. SIGTERM and SIGHUP end the command like Ctrl-C, with its
    temporaries removed (exit 128 + the signal).
    """
    _usable_streams()
    parser = build_parser()
    args = parser.parse_args(argv)
    with warnings.catch_warnings(record=True) as caught:
        # PYTHONWARNINGS=error: a NumPy warning (an overflow the rasterizer handles) is held and shown like
        # any other, never raised out of the computation as a traceback.
        warnings.filters[:] = [("always", *f[1:]) if f[0] == "error" else f for f in warnings.filters]
        code = _exit_code(args)
    if code != 2:
        for w in caught:
            warnings.showwarning(w.message, w.category, w.filename, w.lineno)
    return code


def _exit_code(args) -> int:
    """:func:`_run` with every expected failure turned into its exit code and one line."""
    from ._arrays import max_memory
    from ._io import remove_temporaries

    limit = max_memory()
    try:
        with _signals_raise():
            return _run(args)
    except InputError as exc:
        return _fail(args, exc)
    except BrokenPipeError:
        # The reader (``| head``) went away: no more output, one line, exit 2.
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return _fail(args, "output closed before the command finished (broken pipe)")
    except OSError as exc:
        return _fail(args, _os_reason(exc))
    except MemoryError:
        return _fail(args, f"out of memory (limit {format_bytes(max_memory())}); use smaller parameters")
    except KeyboardInterrupt:
        print(f"moments-ref {args.command}: interrupted", file=sys.stderr)
        return 130
    except Terminated as exc:
        signum = exc.args[0]
        print(f"moments-ref {args.command}: terminated ({signal.Signals(signum).name})", file=sys.stderr)
        return 128 + signum
    finally:
        set_max_memory(limit)
        remove_temporaries()


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
