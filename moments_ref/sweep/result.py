"""A sweep's result: counts per stratum and driver, seconds per stage, the shrunk failures."""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .runner import STAGES, run_chunks
from .samplers import STRATA
from .shrink import shrink

__all__ = ["SweepResult", "sweep_port", "MAX_SHRUNK"]

#: Distinct failures (driver and stratum) shrunk per sweep.
MAX_SHRUNK = 4
_FORMATS = ("float32 moments", "64-bit non-linear texel", "32-bit non-linear texel")


@dataclass
class SweepResult:
    """Rows per stratum; flagged, confirmed and unconfirmed rows per driver; the shrunk failures."""

    case: str
    rows: int
    seed: int
    strata: dict
    drivers: dict
    seconds: dict
    failures: list = field(default_factory=list)
    unconfirmed_examples: list = field(default_factory=list)
    wall_s: float = 0.0
    notes: list = field(default_factory=list)  # causes that hold for the whole sweep (a singular bias target)

    @property
    def confirmed(self):
        return sum(d["confirmed"] for d in self.drivers.values())

    @property
    def passed(self):
        return self.confirmed == 0

    def record(self):
        """JSON-ready dict (``--json``)."""
        rate = {k: (self.rows / v if v > 0 else None) for k, v in self.seconds.items()}
        return {"case": self.case, "rows": self.rows, "seed": self.seed, "passed": self.passed,
                "strata": self.strata, "drivers": self.drivers, "seconds": self.seconds, "rows_per_s": rate,
                "wall_s": self.wall_s, "failures": self.failures, "unconfirmed_examples": self.unconfirmed_examples,
                "notes": self.notes}

    def format(self):
        lines = [f"sweep {self.case}: {self.rows} rows, seed {self.seed}, {self.wall_s:.1f} s"]
        why = "unconfirmed flags (a defect of the tolerance model, not of the port)"
        for d, c in self.drivers.items():
            named = [f"{c['printed']} of them the papers' printed formulation's own value, which cancels there"
                     ] if c.get("printed") else []
            if c.get("envelope"):
                named.append(f"{c['envelope']} within the slides' code's rounding envelope: the tolerance model's "
                             "known gap")
            hazard = f" ({'; '.join(named)})" if named else ""
            lines.append(f"  driver {d}: {c['flagged']} flagged, {c['confirmed']} confirmed wrong (mpmath){hazard}, "
                         f"{c['unconfirmed']} {why}, "
                         f"{c['flagged'] - c['examined']} flagged beyond the confirmation cap; first confirmed row "
                         f"{c['first_confirmed']}")
        lines.append("  stratum              rows   ill  ungated " + " ".join(f"{d[:10]:>10}" for d in self.drivers))
        for s, v in self.strata.items():
            cells = " ".join(f"{self.drivers[d]['per_stratum'][s]['confirmed']:>10}" for d in self.drivers)
            lines.append(f"  {s:<16} {v['rows']:>8} {v['ill_conditioned']:>5} {v['ungated']:>8} {cells}")
        lines.append("  seconds: " + ", ".join(f"{k} {v:.2f} ({self.rows / v:.3g} rows/s)" if v > 0 else f"{k} 0"
                                               for k, v in self.seconds.items()))
        for f in self.failures:
            lines += ["", describe(f)]
        if any(c.get("printed") for c in self.drivers.values()):
            from .judge import PRINTED_CAUSE

            lines += ["", "printed formulation: on the rows counted above as its own value, " + PRINTED_CAUSE]
        if any(c.get("envelope") for c in self.drivers.values()):
            from .judge import ENVELOPE_CAUSE

            lines += ["", "rounding envelope: on the rows counted above as within it, " + ENVELOPE_CAUSE]
        if self.notes and not self.passed:
            lines += [""] + [f"cause: {n}" for n in self.notes]
        for f in self.unconfirmed_examples[:2]:
            lines += ["", "unconfirmed flag (tolerance model): " + describe(f)]
        return "\n".join(lines)


def describe(f):
    """A failure as a golden-style row a porter can read."""
    t = f["texel"]
    depths = " and ".join(f"{z:.9g}" for z in t["depths"])
    weights = ", ".join(f"{w:.6g}" for w in t["weights"])
    texel = "the distribution's moments" if "support" in f["inputs"] else _FORMATS[t["format"]]  # an engine case
    out = [f"[{f.get('driver')}] {f.get('stratum', '')}: {len(t['depths'])} depth(s) {depths}, weights {weights}, "
           f"{texel}, zf = {t['zf']:.9g}"]
    for o, g in f["got"].items():
        lo, hi = np.asarray(f["lo"][o], float), np.asarray(f["hi"][o], float)
        out.append(f"  {f.get('labels', {}).get(o, o)}: got {g}, expected {((lo + hi) / 2).tolist()}, tolerance {((hi - lo) / 2).tolist()}")
    out.append(f"  inputs: {f['inputs']}")
    if f.get("printed"):
        out.append("  cause: the papers' printed formulation returns this value too (a hazard of the formulation, below)")
    elif f.get("envelope"):
        out.append("  cause: within the slides' code's rounding envelope (the tolerance model's known gap, below)")
    if "dispatches" in f:
        out.append(f"  shrunk in {f['dispatches']} dispatches; rerun: {f.get('row_file', '')}")
    return "\n".join(out)


def _merge(spec, chunks):
    strata = {s: {"rows": 0, "ill_conditioned": 0, "ungated": 0} for s in STRATA}
    seconds = dict.fromkeys(STAGES, 0.0)
    drivers = {}
    for c in chunks:
        for k, counts in c["strata"].items():
            for s, v in zip(STRATA, counts):
                strata[s][k] += v
        for k, v in c["seconds"].items():
            seconds[k] += v
        for d, r in c["drivers"].items():
            m = drivers.setdefault(d, {"flagged": 0, "confirmed": 0, "unconfirmed": 0, "printed": 0, "envelope": 0,
                                       "examined": 0,
                                       "first_confirmed": None, "per_stratum": {s: dict.fromkeys(
                                           ("flagged", "confirmed", "unconfirmed", "printed", "envelope"), 0)
                                           for s in STRATA},
                                       "rows": [], "unconfirmed_rows": []})
            for k in ("flagged", "confirmed", "unconfirmed", "printed", "envelope"):
                m[k] += sum(r.get(k, ()))  # "printed": not in a checkpoint written before the hazard diagnosis
                for s, v in zip(STRATA, r.get(k, ())):
                    m["per_stratum"][s][k] += v
            m["examined"] += r["examined"]
            if m["first_confirmed"] is None:
                m["first_confirmed"] = r["first_confirmed"]
            m["rows"] += [dict(x, driver=d) for x in r["confirmed_rows"]]
            m["unconfirmed_rows"] += [dict(x, driver=d) for x in r["unconfirmed_rows"]]
    return strata, drivers, seconds


def sweep_port(spec, workers=1, scheduler=None, out=None, progress=None, shrink_failures=True):
    """Run ``spec``'s chunks, merge them, shrink each distinct failure and write its row folder under ``out``."""
    t0 = time.perf_counter()
    checkpoint = None if out is None else Path(out) / "checkpoint.json"
    if out is not None:
        Path(out).mkdir(parents=True, exist_ok=True)
    chunks = run_chunks(spec, workers, scheduler, checkpoint, progress)
    strata, drivers, seconds = _merge(spec, chunks)
    failures, unconfirmed = [], []
    for d, m in drivers.items():
        unconfirmed += m.pop("unconfirmed_rows")[:2]
        seen = set()
        for row in m.pop("rows"):
            if row["stratum"] in seen or len(failures) >= MAX_SHRUNK:
                continue
            seen.add(row["stratum"])
            failures.append(_shrunk(spec, d, row, out, len(failures)) if shrink_failures else row)
    profile = getattr(spec, "profile", None)
    if profile is not None and profile.output == "visibility":  # the values are the port's: name them so
        for f in failures + unconfirmed:
            f["labels"] = {"intensity": "visibility"}
    return SweepResult(spec.case.name, spec.rows, spec.seed, strata, drivers, seconds, failures, unconfirmed,
                       time.perf_counter() - t0, _notes(spec.case))


def _notes(case):
    """The causes that hold for every row of the sweep: a declared bias target that is singular (the goldens'
    diagnosis, :func:`moments_ref.golden.diagnosis.target_groups`), which the band replaces by the legitimate ones."""
    ctx = case.engine or {}
    inside = ctx.get("inside")
    if not case.name.startswith("engine-") or inside is None:
        return []
    from ..golden.diagnosis import singular_target_cause
    from ..golden.engine import target_support

    support = target_support(inside.target)  # in the engine's frame, as the goldens' diagnosis names it
    return [] if support is None else [f"bias target {list(inside.target)}: " + singular_target_cause(support)]


def _shrunk(spec, driver, row, out, k):
    drv = None if driver == "None" else driver
    texel, judged, dispatches = shrink(spec, drv, row["texel"])
    f = dict(row, **(judged or {}), texel=texel, dispatches=dispatches, original=row["texel"])
    if judged:  # the shrunk row's own diagnosis
        from .judge import named_rows

        one = lambda d: {k: np.asarray([v]) for k, v in d.items()}  # noqa: E731
        cut = {o: (np.asarray([judged["lo"][o]]), np.asarray([judged["hi"][o]])) for o in judged["lo"]}
        printed, envelope = named_rows(spec.case, one(judged["inputs"]), one(judged["got"]), cut, spec.port_dtype)
        f["printed"], f["envelope"] = bool(printed[0]), bool(envelope[0])
    if out is not None:
        from ..golden.writer import write_rows

        folder = Path(out) / f"failure-{k}"
        comment = f"sweep: shrunk failure ({row['stratum']}, driver {driver}): {describe(f).splitlines()[0]}"
        write_rows(folder, spec.case, {key: np.asarray([v]) for key, v in f["inputs"].items()}, [comment[:400]])
        f["row_file"] = str(folder)
    return f
