"""``moments-ref sweep``: the port arguments of ``conformance``, rows, seed, workers, a Dask scheduler.

Exit codes: 0 no confirmed wrong row; 1 confirmed wrong rows (each shrunk and printed,
and written under ``--out``); 2 bad usage or input, no driver, or a harness failure (one
line, never a traceback, never a verdict on the port).
"""

from __future__ import annotations

import json
import sys

from .._arrays import InputError
from ..conformance import ALL_LANGUAGES as LANGUAGES
from ..conformance._cli import harness_failure, resolve_port, source_options

__all__ = ["main", "parse_rows", "MAX_ROWS", "make_spec", "add_options"]

#: The most rows one sweep draws (refused above, before any work).
MAX_ROWS = 10**10


def add_options(sw, positive_int, folder_arg):
    """The sweep's own options (after the port, profile and source options the command shares with
    ``conformance``); ``positive_int`` and ``folder_arg`` are the command line's argument types."""
    sw.add_argument("--rows", default="1e6", metavar="N", help="rows to draw (default 1e6; accepts 1e8)")
    sw.add_argument("--seed", type=positive_int(0), default=0, help="seed of the draw (default 0)")
    sw.add_argument("--workers", type=positive_int(1), default=None, metavar="N",
                    help="spawned worker processes, one driver context each (default: 2, 1 below two chunks)")
    sw.add_argument("--scheduler", metavar="ADDRESS", help="run the chunks on this Dask scheduler (tcp://host:8786)")
    sw.add_argument("--strict", action="store_true",
                    help="also fail rows outside the case's contract (robustness rows), as verify --strict does")
    sw.add_argument("--out", type=folder_arg, help="checkpoint (resumed) and one golden folder per shrunk failure")


def parse_rows(text):
    """``--rows``: an integer or a float literal such as ``1e8``, 1 to :data:`MAX_ROWS`."""
    try:
        value = float(text)
    except (TypeError, ValueError):
        raise InputError(f"--rows: expected a number of rows such as 1000000 or 1e8, got {text!r}") from None
    if not value.is_integer() or not 1 <= value <= MAX_ROWS:
        raise InputError(f"--rows: expected a whole number from 1 to {MAX_ROWS:.0e}, got {text!r}")
    return int(value)


def make_spec(case_name, port, adapter=None, profile=None, seed=0, rows=10**6, strict=False):
    """The :class:`~.runner.SweepSpec` of a case (profiled) and a port, after checking both."""
    from ..golden import CASES
    from .runner import SweepSpec
    from .samplers import SAMPLERS, sweepable

    if case_name not in CASES:
        raise InputError(f"--case: unknown case {case_name!r}")
    if not sweepable(case_name):
        raise InputError(f"--case: the sweep has no sampler for {case_name!r} (kernel, bilinear and "
                         "block cases derive their expected values row by row, too slowly for millions of rows: "
                         f"judge them with conformance); it sweeps the float32 cases of {', '.join(SAMPLERS)}")
    key = "default"
    if profile is not None and not profile.is_default:
        engine = [k for k in ("receiver_offset", "receiver_slope", "receiver_depth", "output_clamp")
                  if getattr(profile, k) is not None]
        if profile.bound == "hausdorff":
            engine.append("bound")
        if engine:  # judged by conformance and verify (golden.receiver), not yet by the sweep's rows
            raise InputError(f"--profile: {engine[0]}: the sweep does not honour the receiver, output-clamp and bound "
                             "keys yet; run conformance with the profile")
        key = profile.key
    if adapter is None and port.language is not None:
        from ..conformance import DEFAULT_DRIVER

        adapter = DEFAULT_DRIVER.get(port.language)
    drivers = ("gl", "vulkan") if adapter == "both" else (adapter,)
    spec = SweepSpec(case_name, port, drivers, seed, rows, key, profile=profile, strict=bool(strict))
    spec.case  # noqa: B018 - a profile the case contradicts is refused now (InputError), before any work
    return spec


def _progress(total):
    from tqdm import tqdm

    bar = tqdm(total=total, desc="sweep", unit="row", unit_scale=True, file=sys.stderr, disable=None, leave=False)
    wrong = [0]

    def step(r):
        wrong[0] += sum(sum(d["confirmed"]) for d in r["drivers"].values())
        bar.update(r["rows"])
        bar.set_postfix(wrong=wrong[0])
        if bar.n >= total:
            bar.close()

    return step


def main(args):
    """Entry of the CLI (``args`` from ``moments-ref sweep``); returns the exit code."""
    get = lambda k: getattr(args, k, None)  # noqa: E731
    files = [(lang, get(lang)) for lang in LANGUAGES if get(lang) is not None]
    if len(files) != 1:
        raise InputError(f"sweep: expected one of {', '.join('--' + x for x in LANGUAGES)} FILE, got {len(files)}")
    missing = [a for a in ("function", "case") if get(a) is None]
    if missing:
        raise InputError(f"sweep: --{missing[0]} is required")
    rows = parse_rows(get("rows"))
    language, path = files[0]
    port_path = resolve_port(path, language)
    if not port_path.is_file():
        raise InputError(f"--{language}: no such file {path}")
    from ..golden.profile import FLAGS, profile_from_args
    from .result import sweep_port
    from .runner import Port
    from .samplers import CHUNK

    flags = {f[2:].replace("-", "_"): get(f[2:].replace("-", "_")) for f, _, _ in FLAGS}
    profile = profile_from_args(get("profile"), get("function"), **flags)
    port = Port(str(port_path), get("function"), language, source_options(args))
    spec = make_spec(get("case"), port, get("adapter"), profile, get("seed"), rows, get("strict"))
    workers = get("workers") or (2 if rows > CHUNK else 1)
    from ..conformance import ContextError, ToolError

    try:
        result = sweep_port(spec, workers, get("scheduler"), get("out"), _progress(rows))
    except (InputError, ContextError, ToolError) as exc:
        print(f"moments-ref sweep: {exc}", file=sys.stderr)
        return 2
    except Exception as exc:  # noqa: BLE001 - a harness failure is exit 2, never a verdict on the port
        print(f"moments-ref sweep: {path}: the harness failed ({harness_failure(exc)}); this is not a verdict on the "
              "port", file=sys.stderr)
        return 2
    print(result.format())
    if get("json") is not None:
        from .._io import write_text

        write_text(get("json"), json.dumps(result.record(), indent=1, default=float) + "\n")
    return 0 if result.passed else 1
