"""The ``moments-ref`` command: thin subcommands over library functions.

Exit codes: 0 done, 1 a verification found differences, 2 bad usage or bad
input (one-line reason on stderr).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from ._arrays import InputError


def _progress(total, desc):
    """A tqdm progress bar on stderr (silent when stderr is not a terminal)."""
    from tqdm import tqdm

    return tqdm(total=total, desc=desc, unit="step", file=sys.stderr, disable=None, leave=False)


def _cmd_golden(args):
    from . import golden

    names = list(golden.CASES) if not args.case else args.case
    with _progress(len(names), "golden") as bar:
        manifest = golden.write(args.out, names, progress=lambda name: bar.update(1))
    n_rows = sum(c["count"] for c in manifest["cases"].values())
    print(f"wrote {len(manifest['cases'])} cases ({n_rows} rows) and manifest.json to {args.out}")
    return 0


def _cmd_verify(args):
    from . import golden

    report = golden.verify(args.golden, args.results, port_dtype=args.dtype)
    print(report.format(worst_rows=args.worst))
    return 1 if report.failed else 0


def _cmd_bench(args):
    from . import bench

    rows = bench.run(size=args.size, quick=args.quick, only=args.only,
                     progress=lambda total: _progress(total, "bench"))
    text = bench.markdown(rows)
    if not args.only or any("end_to_end" in o for o in args.only):
        size = min(args.size, 512) if args.quick else args.size
        text += "\n" + bench.end_to_end_markdown(bench.end_to_end(size, 4), size, 4)
    if not args.only or any("conformance" in o for o in args.only):
        text += "\n" + bench.conformance_markdown(repeat=1 if args.quick else 3)
    print(text)
    if args.out:
        from ._io import write_text

        path = write_text(Path(args.out) / "bench.md", text)
        print(f"wrote {path}")
    return 0


def _cmd_stability(args):
    from . import stability

    path = stability.main(args.out)
    print(f"wrote {path}")
    return 0


def _cmd_figure3(args):
    from . import figures

    paths = figures.write_figure3(args.out)
    print("wrote " + ", ".join(str(p) for p in paths))
    return 0


def _cmd_figure4(args):
    from . import figures

    paths = figures.write_figure4(args.out, scene=args.scene, size=args.size, samples=args.samples)
    print("wrote " + ", ".join(str(p) for p in paths))
    print(paths[2].read_text())
    return 0


def _cmd_banks(args):
    from . import banks

    text = banks.main()
    print(text)
    if args.out:
        from ._io import write_text

        print(f"wrote {write_text(Path(args.out) / 'banks.md', text)}")
    return 0


def _cmd_report(args):
    from . import report

    argv = ["--out", str(args.out)]
    for s in args.scene or []:
        argv += ["--scene", s]
    if args.full:
        argv.append("--full")
    if args.no_progress:
        argv.append("--no-progress")
    return report.main(argv)


def _cmd_vwss(args):
    from .vwss import compare

    return compare.main(args)


def _cmd_conformance(args):
    from . import conformance

    if args.all:
        from ._io import write_text

        text = conformance.summary_markdown(golden_dir=args.golden)
        print(text)
        if args.out:
            print(f"wrote {write_text(Path(args.out) / 'conformance.md', text)}")
        return 1 if "| FAIL |" in text else 0
    missing = [a for a in ("glsl", "function", "case") if getattr(args, a) is None]
    if missing:
        raise InputError(f"conformance: --{missing[0]} is required (or use --all)")
    return conformance.main(args)


def build_parser():
    p = argparse.ArgumentParser(
        prog="moments-ref",
        description="Reference implementation and test oracle of moment shadow mapping.",
    )
    sub = p.add_subparsers(dest="command", metavar="COMMAND", required=True)

    rp = sub.add_parser("report", help="error against run time of every technique on the shipped scenes (main job)")
    rp.add_argument("--scene", action="append", help="scene name or file (repeatable; default: all shipped scenes)")
    rp.add_argument("--full", action="store_true", help="2048² 4× MSAA shadow maps and full camera resolution")
    rp.add_argument("--out", required=True, type=Path, help="output folder")
    rp.add_argument("--no-progress", action="store_true", help="no progress bar")
    rp.set_defaults(func=_cmd_report)

    vw = sub.add_parser("vwss", help="view-warped soft shadows against MVR and PCSS (VWSS Tables 1 and 2)")
    vw.add_argument("--scene", default="knot", help="scene name or file with an area light (default knot)")
    vw.add_argument("--views", type=int, default=None, help="light samples (default: 24 and 128; --quick: fewer)")
    vw.add_argument("--quick", action="store_true", help="reduced resolution, under a minute on knot")
    vw.add_argument("--near", type=float, default=None,
                    help="the light's near plane z_n in world units (VWSS Listing 1 light.nearZ; default: the "
                         "scene's params.light_near)")
    vw.add_argument("--out", required=True, type=Path, help="output folder")
    vw.set_defaults(func=_cmd_vwss)

    g = sub.add_parser("golden", help="write golden vectors and manifest.json")
    g.add_argument("--out", required=True, type=Path, help="output folder")
    g.add_argument("--case", action="append", help="only this case (repeatable)")
    g.set_defaults(func=_cmd_golden)

    v = sub.add_parser("verify", help="compare a port's results (.npz) with the goldens")
    v.add_argument("--golden", required=True, type=Path, help="folder written by 'golden'")
    v.add_argument("--results", required=True, type=Path, help=".npz with arrays '<case>.<output>'")
    v.add_argument("--dtype", choices=("float32", "float64"), help="the port's precision (default: each case's)")
    v.add_argument("--worst", type=int, default=5, help="worst rows to print per failing case")
    v.add_argument("--out", type=Path, help="unused; accepted for uniformity")
    v.set_defaults(func=_cmd_verify)

    b = sub.add_parser("bench", help="throughput against a same-run memory copy")
    b.add_argument("--out", type=Path, help="also write bench.md here")
    b.add_argument("--size", type=int, default=2048, help="square input side (default 2048)")
    b.add_argument("--quick", action="store_true", help="one repetition, small sizes")
    b.add_argument("--only", action="append", help="only benchmarks whose name contains this")
    b.set_defaults(func=_cmd_bench)

    s = sub.add_parser("stability", help="float32/float64 against mpmath: write stability.md")
    s.add_argument("--out", required=True, type=Path, help="output folder (docs/ in the repo)")
    s.set_defaults(func=_cmd_stability)

    f3 = sub.add_parser("figure3", help="HPG17 Figure 3 as CSV and PNG")
    f3.add_argument("--out", required=True, type=Path, help="output folder")
    f3.set_defaults(func=_cmd_figure3)

    f4 = sub.add_parser("figure4", help="HPG17 Figure 4: histograms of xi4 and Psi4(xi4), CSV and PNG")
    f4.add_argument("--out", required=True, type=Path, help="output folder")
    f4.add_argument("--scene", default="railing", help="shipped scene name or scene file (default railing)")
    f4.add_argument("--size", type=int, default=2048, help="shadow-map side (default 2048, as HPG17)")
    f4.add_argument("--samples", type=int, default=4, help="MSAA samples (default 4)")
    f4.set_defaults(func=_cmd_figure4)

    cf = sub.add_parser("conformance", help="run a GLSL port on an OpenGL 4.3 compute context against a golden case")
    cf.add_argument("--glsl", help="GLSL file, or the name of a shipped port (msm.glsl, nonlinear.glsl, packing.glsl)")
    cf.add_argument("--function", help="the GLSL function to test")
    cf.add_argument("--case", help="golden case, e.g. shade-float32")
    cf.add_argument("--golden", type=Path, default=None, help="golden folder (default: generate the case)")
    cf.add_argument("--all", action="store_true", help="run every shipped port on every case it covers (a table)")
    cf.add_argument("--out", type=Path, help="with --all: also write conformance.md here")
    cf.set_defaults(func=_cmd_conformance)

    bk = sub.add_parser("banks", help="bank conflicts of the 40×32 shared-memory layout (HPG17 Fig. 6)")
    bk.add_argument("--out", type=Path, help="also write banks.md here")
    bk.set_defaults(func=_cmd_banks)
    return p


def main(argv=None):
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return args.func(args)
    except InputError as exc:
        print(f"moments-ref {args.command}: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"moments-ref {args.command}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
