"""The sweep's measurements for docs/sweep.md: the shipped ports, the mutants, the rows/s of each stage.

``python -m moments_ref.sweep.measure --rows 1e6 --json sweep-measure.json`` sweeps every
shipped port (:func:`moments_ref.conformance.shipped_port`: Algorithm 1's lower and upper
bound, Algorithm 3, the non-linear texels' encoders and decoders, in every language that
ships them) on both Mesa drivers; ``--corpus tests/sweep_mutants/corpus.py`` also sweeps
each one-change mutant of that corpus on llvmpipe and records its first confirmed row and
its shrunk row. ``--doc docs/sweep.md`` writes the tables between the markers
``<!-- measured:begin -->`` and ``<!-- measured:end -->`` (atomically).
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import time
from pathlib import Path

from .result import sweep_port
from .runner import STAGES, Port, SweepSpec

__all__ = ["SHIPPED_CASES", "shipped_runs", "mutant_runs", "tables", "main"]

SHIPPED_CASES = ("shadow_intensity-lower-float32", "shadow_intensity-upper-float32", "shade-float32",
                 "pack64-float32", "pack32-float32", "unpack64-float32", "unpack32-float32")
LANGUAGES = ("glsl", "hlsl", "wgsl", "slang")
_BEGIN, _END = "<!-- measured:begin -->", "<!-- measured:end -->"


def _run(case, path, function, language, drivers, rows, workers, shrink=True, strict=False):
    t0 = time.perf_counter()
    res = sweep_port(SweepSpec(case, Port(str(path), function, language), tuple(drivers), rows=rows, strict=strict),
                     workers, shrink_failures=shrink)
    rec = res.record()
    rec["wall_s"] = time.perf_counter() - t0
    return rec


def shipped_runs(rows, drivers=("gl", "vulkan"), workers=2, cases=SHIPPED_CASES, languages=LANGUAGES, log=print,
                 strict=False):
    """One record per shipped port and case (:meth:`~.result.SweepResult.record`, plus ``language``, ``path`` and
    ``strict``: whether the robustness rows were gated too)."""
    from ..conformance import shipped_port

    out = []
    for language in languages:
        for case in cases:
            try:
                path, function = shipped_port(case, language)
            except Exception:  # noqa: BLE001 - a language that ships no port of the case
                continue
            rec = _run(case, path, function, language, drivers, rows, workers, strict=strict)
            rec.update(language=language, path=Path(path).name, function=function, strict=strict)
            out.append(rec)
            log(f"{language} {case}: {_counts(rec)} ({rec['wall_s']:.0f} s)")
    return out


def _load_corpus(path):
    spec = importlib.util.spec_from_file_location("sweep_corpus", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def mutant_runs(corpus_path, rows, tmp, workers=1, log=print):
    """One record per mutant of the corpus: first confirmed row, confirmed count, the shrunk row (llvmpipe)."""
    from ..conformance import PORTS_DIR

    corpus = _load_corpus(corpus_path)
    out = []
    for name, file, function, case, old, new, region in corpus.MUTANTS:
        src = (PORTS_DIR / "glsl" / file).read_text()
        path = Path(tmp) / f"{name}.glsl"
        path.write_text(src.replace(old, new, 1))
        rec = _run(case, path, function, "glsl", ("gl",), rows, workers)
        d = rec["drivers"]["gl"]
        f = rec["failures"][0] if rec["failures"] else None
        out.append({"name": name, "case": case, "region": region, "flagged": d["flagged"], "confirmed": d["confirmed"],
                    "examined": d["examined"], "first": d["first_confirmed"], "shrunk": f,
                    "caught_by_goldens": name in corpus.CAUGHT_BY_THE_GOLDENS})
        log(f"{name}: first {d['first_confirmed']}, confirmed {d['confirmed']}")
    return out


def _counts(rec):
    return ", ".join(f"{k} {v['flagged']} / {v['confirmed']} / {v['unconfirmed']}" for k, v in rec["drivers"].items())


def _rate(x):
    return "–" if not x else f"{x:.2g}".replace("e+0", "·10^").replace("e+", "·10^")


def tables(shipped, mutants, rows, note="", mutant_rows=None):
    """Markdown of the measurements (``mutant_rows``: the rows of the mutants' sweeps, default ``rows``)."""
    lines = [f"Seed 0, 2 spawned workers; flagged / confirmed wrong / unconfirmed flags per driver (gl = llvmpipe, "
             f"vulkan = lavapipe). {note}".rstrip(), "",
             "| port | function | case | rows per driver | gl | vulkan | ill-conditioned (judged) | robustness rows "
             "(ungated) | wall s |",
             "|---|---|---|---:|---|---|---:|---:|---:|"]
    for r in shipped:
        d = r["drivers"]
        cell = lambda k: f"{d[k]['flagged']} / {d[k]['confirmed']} / {d[k]['unconfirmed']}" if k in d else "–"  # noqa: E731
        ill = sum(v["ill_conditioned"] for v in r["strata"].values())
        strata = r["strata"].values()
        ungated = "gated (--strict)" if r.get("strict") else sum(v.get("ungated", 0) for v in strata)
        lines.append(f"| {r['language']}/{r['path']} | `{r['function']}` | {r['case']} | {r['rows']:.3g} | {cell('gl')} | "
                     f"{cell('vulkan')} | {ill} | {ungated} | {r['wall_s']:.0f} |")
    lines += ["", "Rows/s of each stage (summed over the workers' processes, so one process's rate), the same runs:", "",
              "| port | case | " + " | ".join(STAGES) + " |", "|---|---|" + "---:|" * len(STAGES)]
    for r in shipped:
        lines.append(f"| {r['language']}/{r['path']} | {r['case']} | "
                     + " | ".join(_rate(r["rows_per_s"].get(s)) for s in STAGES) + " |")
    if mutants:
        lines += ["", f"The mutants of `tests/sweep_mutants/corpus.py`, {mutant_rows or rows:.6g} rows on llvmpipe "
                  "(confirmed: at most 64 examined per chunk; goldens: whether every golden case of the function "
                  "passes it):", "",
                  "| mutant | goldens | confirmed (examined) / flagged | first hit (row) | shrunk row "
                  "(depths; weights; zf; texel) | got → band |", "|---|---|---:|---:|---|---|"]
        for m in mutants:
            f = m["shrunk"]
            if f is None:
                shrunk, got = "–", "–"
            else:
                t = f["texel"]
                shrunk = (f"{', '.join(f'{z:.6g}' for z in t['depths'])}; {', '.join(f'{w:.4g}' for w in t['weights'])}; "
                          f"{t['zf']:.8g}; {('float32', '64-bit', '32-bit')[t['format']]}")
                o = next(iter(f["got"]))
                got = f"{f['got'][o]:.6g} → [{f['lo'][o]:.6g}, {f['hi'][o]:.6g}]"
            lines.append(f"| {m['name']} | {'caught' if m['caught_by_goldens'] else 'missed'} | "
                         f"{m['confirmed']} ({m['examined']}) / {m['flagged']} | {m['first']} | {shrunk} | {got} |")
    return "\n".join(lines) + "\n"


def write_doc(doc, text):
    """Replace the measured section of ``doc`` with ``text`` (atomically)."""
    from .._io import write_text

    src = Path(doc).read_text()
    head, _, rest = src.partition(_BEGIN)
    _, _, tail = rest.partition(_END)
    write_text(doc, head + _BEGIN + "\n" + text + _END + tail)


def main(argv=None):
    ap = argparse.ArgumentParser(prog="python -m moments_ref.sweep.measure", description=__doc__.split("\n")[0])
    ap.add_argument("--rows", default="1e6")
    ap.add_argument("--mutant-rows", default="1e6")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--languages", default=",".join(LANGUAGES))
    ap.add_argument("--cases", default=",".join(SHIPPED_CASES))
    ap.add_argument("--strict", action="store_true", help="gate the robustness rows too (sweep --strict)")
    ap.add_argument("--corpus", help="tests/sweep_mutants/corpus.py: also sweep its mutants")
    ap.add_argument("--json", required=True, help="the records (read back with --from-json; there, comma-separated "
                                                  "files are merged)")
    ap.add_argument("--from-json", action="store_true", help="do not sweep: write the tables from --json")
    ap.add_argument("--doc", help="docs/sweep.md: write the tables between its markers")
    ap.add_argument("--note", default="")
    a = ap.parse_args(argv)
    rows = int(float(a.rows))
    if a.from_json:
        parts = [json.loads(Path(f).read_text()) for f in a.json.split(",")]
        data = {"rows": parts[0]["rows"], "shipped": [r for p in parts for r in p["shipped"]],
                "mutants": [m for p in parts for m in p.get("mutants", [])],
                "mutant_rows": next((p["mutant_rows"] for p in parts if "mutant_rows" in p), None)}
    else:
        import tempfile

        data = {"rows": rows, "shipped": shipped_runs(rows, workers=a.workers, cases=a.cases.split(","),
                                                      languages=a.languages.split(","), strict=a.strict)}
        if a.corpus:
            with tempfile.TemporaryDirectory() as tmp:
                data["mutants"] = mutant_runs(a.corpus, int(float(a.mutant_rows)), tmp)
                data["mutant_rows"] = int(float(a.mutant_rows))
        Path(a.json).write_text(json.dumps(data, indent=1, default=float))
    text = tables(data["shipped"], data.get("mutants", []), data["rows"], a.note, data.get("mutant_rows"))
    if a.doc:
        write_doc(a.doc, text)
    else:
        print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
