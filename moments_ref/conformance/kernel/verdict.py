"""A kernel's output judged by the one comparator, and the report printed per driver.

The output read back is turned into the case's compared output and handed to
:func:`moments_ref.conformance.verdict.compare_case` (``golden.compare`` with the
float32 tolerance column), texel by texel:

* filter cases: the texel's codes are decoded and shaded at its four fragment
  depths in float64 (:func:`moments_ref.golden.kernels.decode_intensity`), so the
  intensity measures the codes alone; ``-moments`` compares the moments. The
  codes are also compared with the global path's (``texels``) and with those of
  the legitimate float32 kernels (``texels_acceptable``): reported, the intensity
  decides (Φ's conditioning lets correct kernels store other codes);
* ``kernel-vwss-points``: the keys are decoded to reversed depths
  (:func:`moments_ref.techniques.vwss.warp.key_depth`), the clear key to
  :data:`~moments_ref.golden.kernels.EMPTY_DEPTH`.

Before that, the poison around and inside the map tells what a kernel did outside
its contract: texels still holding the poison were never written (their rows
fail), changed words beyond the map are writes outside the output (the run fails).

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

from dataclasses import dataclass, field

import numpy as np

from ...golden.cells import DEFAULT_CELL
from ...golden.kernels import EMPTY_DEPTH, decode_intensity
from ...packing import unpack64
from .._report import fmt
from ..verdict import compare_case

__all__ = ["DriverRun", "KernelReport", "judge", "format_run"]


@dataclass
class DriverRun:
    """One kernel on one driver: verdict, what went wrong outside the rows, timings."""

    driver: str
    renderer: str
    toolchain: str
    passed: bool = False
    reason: str | None = None  # a run-level failure (time limit, writes outside the output)
    skipped: str | None = None  # why this driver cannot run the kernel (a driver limitation, not a verdict)
    verdict: object = None  # conformance.verdict.CaseVerdict
    outside: int = 0
    unwritten: int = 0
    first_outside: tuple | None = None
    first_unwritten: tuple | None = None
    codes: dict | None = None  # exact, accepted, differ, differ_passing
    timings: dict = field(default_factory=dict)
    units: int = 0  # blocks (filter) or views (VWSS) the dispatches covered
    output: np.ndarray | None = field(default=None, repr=False)  # what the case compares, per texel


def _first(mask):
    idx = np.argwhere(mask)
    return tuple(int(v) for v in idx[0]) if idx.size else None


def _filter_candidate(kw, fmt_name, raw, out_kind, fill, layout="interleaved"):
    """(candidate array (n, ...) or codes, unwritten (H, W), outside mask) of a filter case's readback."""
    from .layout import split

    h, w = kw["height"], kw["width"]
    comps = 1 if fmt_name == "nlq32" else 4
    if out_kind != "storage_image":
        return split(raw, fmt_name, layout, h, w, fill)
    mapped = raw[:h, :w, :comps]
    outside = np.ones(raw.shape[:2], bool)
    outside[:h, :w] = False
    outside &= (raw != fill).any(axis=-1)
    unwritten = (mapped == fill).all(axis=-1)
    return mapped.reshape(h * w, comps), unwritten, outside


def _codes_summary(codes, arrays, row_pass, fmt_name=None, width=1, case=None, cell=DEFAULT_CELL):
    from .declared import explaining_cell
    from .fields import field_hints

    e = arrays["texels"].reshape(len(codes), -1).astype(np.int64)
    c = codes.reshape(len(codes), -1).astype(np.int64)
    exact = (c == e).all(axis=1)
    alts = arrays["texels_acceptable"].reshape(len(codes), arrays["texels_acceptable"].shape[1], -1).astype(np.int64)
    accepted = (alts == c[:, None, :]).all(axis=2).any(axis=1) & ~exact
    differ = ~exact & ~accepted
    hints = field_hints(fmt_name, codes, arrays["texels"], differ & ~row_pass, width)
    if cell == DEFAULT_CELL and any(h["field"].startswith("sqrt(v2)") for h in hints):
        other = explaining_cell(case, arrays, codes, ~row_pass)
        for h in hints:
            if other and h["field"].startswith("sqrt(v2)"):
                h["suggest"] = f'[format] v2_cell = "{other}"'
    return {"exact": int(exact.sum()), "accepted": int(accepted.sum()), "differ": int(differ.sum()),
            "differ_passing": int((differ & row_pass).sum()), "fields": hints}


def judge(case, meta, arrays, raw, out_kind, fill, worst_rows=5, strict=False, layout="interleaved"):
    """Judge a readback: ``(CaseVerdict, unwritten (count, first), outside (count, first), codes summary)``."""
    kw = meta["kwargs"]
    if case == "kernel-vwss-points":
        n = kw["views"] * kw["height"] * kw["width"]
        keys = raw[:n]
        outside = raw[n:] != fill
        from ...techniques.vwss.warp import EMPTY_KEY, key_depth

        depth = np.where(keys == EMPTY_KEY, np.float32(EMPTY_DEPTH), key_depth(keys)).astype(np.float32)
        v = compare_case(case, {**meta, "inputs": []}, arrays, {"depth": depth}, worst_rows, strict)
        return v, (0, None), (int(outside.sum()), _first(outside)), None, depth
    fmt_name = kw["format"]
    mapped, unwritten, outside = _filter_candidate(kw, fmt_name, raw, out_kind, fill, layout)
    bad = unwritten.reshape(-1)
    codes = None
    if fmt_name == "moments":
        got = mapped.view(np.float32).copy()
        got[bad] = np.nan
        out = {"moments": got}
    else:
        misfit = bad | (mapped > 0xFFFF).any(axis=1) if fmt_name != "nlq32" else bad
        codes = np.clip(mapped, 0, 0xFFFF).astype(np.uint16) if fmt_name != "nlq32" else mapped[:, 0].copy()
        if fmt_name == "nlq64":  # y1's code above y2's: no decoder input (Algorithm 3 refuses it); the row fails
            r = unpack64(codes)
            misfit = misfit | (r[:, 0] > r[:, 1])
        # misfit rows are decoded from the global path's codes (Algorithm 3 takes any of those), then failed
        expected = np.asarray(arrays["texels"]).reshape(codes.shape).astype(codes.dtype)
        safe = np.where(misfit.reshape((-1,) + (1,) * (codes.ndim - 1)), expected, codes)
        cell = kw.get("v2_cell", DEFAULT_CELL)
        intensity = decode_intensity(fmt_name, safe, arrays["zf"], cell).astype(np.float32)
        intensity[misfit] = np.nan
        out = {"intensity": intensity}
    v = compare_case(case, meta, arrays, out, worst_rows, strict)
    summary = None if codes is None else _codes_summary(codes, arrays, v.row_pass, fmt_name, kw["width"], case,
                                                        kw.get("v2_cell", DEFAULT_CELL))
    return (v, (int(unwritten.sum()), _first(unwritten)), (int(outside.sum()), _first(outside)), summary,
            next(iter(out.values())))


def json_records(report):
    """One JSON record per driver of a :class:`KernelReport`: the function records' keys (every texel's
    verdict, from ``golden.diagnosis.json_rows``) and the kernel's own: driver, renderer, toolchain, passed,
    reason, skipped, unwritten and outside counts, and the codes summary with its per-field hints
    (:mod:`.fields`)."""
    out = []
    for r in report.runs:
        rec = dict(r.verdict.record or {}) if r.verdict is not None else {}
        rec.update(driver=r.driver, renderer=r.renderer, toolchain=r.toolchain, passed=bool(r.passed),
                   reason=r.reason, skipped=r.skipped, unwritten=int(r.unwritten), outside=int(r.outside),
                   codes=r.codes)
        out.append(rec)
    return out


def _position(case, kw, i):
    if case == "kernel-vwss-points":
        view, rest = divmod(i, kw["height"] * kw["width"])
        y, x = divmod(rest, kw["width"])
        return f"view {view}, texel (x {x}, y {y})"
    y, x = divmod(i, kw["width"])
    return f"texel (x {x}, y {y}), block ({x // 32}, {y // 24})"


def _rows(case, kw, verdict):
    lines = []
    for r in verdict.worst:
        state = "ok" if r["passed"] else "FAIL"
        got = np.array2string(np.asarray(r["got"], np.float64), precision=7, separator=", ")
        exp = np.array2string(np.asarray(r["expected"], np.float64), precision=7, separator=", ")
        lines.append(f"        {state:4} row {r['index']} [{r['category']}] {_position(case, kw, r['index'])}: "
                     f"error {fmt(r['error'])} (tol {fmt(r['tolerance'])}): got {got}, expected {exp}")
        if r["inputs"]:
            ins = "; ".join(f"{k}={np.array2string(np.asarray(v, np.float64), precision=7, separator=', ')}"
                            for k, v in r["inputs"].items())
            lines.append(f"             inputs: {ins}")
        lines.append(f"             ({r['comment']})")
    return lines


def format_run(case, kw, run, numpy_times, unit):
    """The lines of one driver's part of the report."""
    if run.skipped:
        return [f"  [{run.driver}] NOT RUN  ({run.toolchain}): {run.skipped}"]
    state = "PASS" if run.passed else "FAIL"
    lines = [f"  [{run.driver}] {state}  renderer: {run.renderer} ({run.toolchain})"]
    if run.reason:
        lines.append(f"      FAIL: {run.reason}")
    v = run.verdict
    if v is not None:
        lines.append("      category  texels  gated | fails | worst error/tolerance: ratio  error (abs)  tolerance")
        for c in v.categories.values():
            lines.append(f"      {c.category:8} {c.rows:6d} {c.gated:6d} | {c.failures:5d} | {fmt(c.worst_score):>28} "
                         f"{fmt(c.worst_error):>12} {fmt(c.worst_tolerance):>10}")
        lines += [f"      note: {n}" for n in v.notes]
        if run.unwritten:
            lines.append(f"      {run.unwritten} texels were never written (first at x {run.first_unwritten[1]}, "
                         f"y {run.first_unwritten[0]}): their rows fail")
        if run.codes:
            c = run.codes
            lines.append(f"      codes: {c['exact']} equal the global path's, {c['accepted']} another legitimate "
                         f"kernel's, {c['differ']} differ ({c['differ_passing']} of them within the intensity "
                         "tolerance: the intensity decides)")
            from .fields import format_hint

            lines += [f"      {format_hint(h)}" for h in c.get("fields", [])]
        if v.worst:
            lines.append("      worst texels (failing first, by error/tolerance; per-texel tolerances of the golden "
                         "case, verdict by golden.compare):")
            lines += _rows(case, kw, v)
    lines.append("      " + _timing_line(run, numpy_times, unit))
    return lines


def _timing_line(run, numpy_times, unit):
    t = run.timings
    disp, drv = t.get("dispatch", []), t.get("driver", [])
    parts = [f"compile {t['compile'] * 1e3:.0f} ms"] if "compile" in t else []
    if disp and run.units:
        if drv:
            parts.append(f"driver {sum(drv) / run.units * 1e3:.3f} ms per {unit} (timer queries)")
        parts.append(f"wall {sum(disp) / run.units * 1e3:.3f} ms per {unit} ({len(disp)} dispatches, "
                     f"{sum(disp) * 1e3:.1f} ms)")
    for name, sec in numpy_times.items():
        parts.append(f"{name} {sec * 1e3:.3f} ms per {unit}")
    return "time: " + "; ".join(parts) if parts else "time: -"


@dataclass
class KernelReport:
    """What :func:`run_kernel` found, per driver; ``passed`` and ``format()``."""

    case: str
    path: str
    entry: str
    language: str
    kwargs: dict
    runs: list = field(default_factory=list)
    numpy: dict = field(default_factory=dict)
    interface: object = None
    bindings: list = field(default_factory=list)
    shared: dict | None = None  # run.shared_memory's trace of work group (0, 0)

    @property
    def passed(self):
        ran = [r for r in self.runs if not r.skipped]
        race = bool(self.shared and (self.shared.get("races") or self.shared.get("error")))
        return bool(ran) and all(r.passed for r in ran) and not race

    def format(self):
        """The report as ``moments-ref conformance --kernel`` prints it."""
        kw = self.kwargs
        unit = "view" if self.case == "kernel-vwss-points" else "block"
        if unit == "block":
            what = (f"{kw['height']}×{kw['width']} map, {-(-kw['width'] // 32) * -(-kw['height'] // 24)} blocks of "
                    f"32×24")
        else:
            what = f"{kw['points']} points, {kw['views']} views of {kw['height']}×{kw['width']}"
        drivers = " and ".join(r.driver for r in self.runs if not r.skipped)
        wg = "×".join(map(str, self.interface.workgroup))
        lines = [f"{'PASS' if self.passed else 'FAIL'}  kernel {self.entry} ({self.path}, {self.language}) on "
                 f"{self.case}: {what}; on {drivers}",
                 f"      work group {wg}; bindings: " + "; ".join(
                     f"{b.slot.name} <- {b.resource.declared} (set {b.resource.set}, binding {b.resource.binding})"
                     for b in self.bindings)]
        if kw.get("v2_cell", DEFAULT_CELL) != DEFAULT_CELL:
            lines.append(f"      declared by the profile: [format] v2_cell = {kw['v2_cell']!r}; expected texels and "
                         "intensities are the global path's on that sqrt(v2) grid")
        if self.shared:
            lines += _shared_lines(self.shared)
        for r in self.runs:
            lines += format_run(self.case, kw, r, self.numpy, unit)
        return "\n".join(lines)


def _cell(a):
    """Moment and block cell of an HPG17 §4.1 shared-memory word."""
    from ...gpu.banks import MOMENT_STRIDE

    j, rest = divmod(a, MOMENT_STRIDE)
    y = min(rest // 40, 31)
    while y > 0 and 40 * y + y // 4 > rest:
        y -= 1
    col = rest - 40 * y - y // 4
    x = col // 2 if col % 2 == 0 else (col + 39) // 2
    return f"b{j + 1} cell (x {x}, y {y})"


def _conflicts(counts):
    """The trace's bank conflicts per phase as a finding: "no bank conflicts in phase resolve, ...; 3 in ..."."""
    clean = [k for k, v in counts.items() if not v]
    some = [f"{v} bank conflicts in phase {k}" for k, v in counts.items() if v]
    parts = ([f"no bank conflicts in phase {', '.join(clean)}"] if clean else []) + some
    return "; ".join(parts) or "no phases traced"


def _shared_lines(s):
    if "error" in s:
        return [f"      FAIL shared memory (traced on {s['driver']}): {s['error']}"]
    head = (f"      shared memory (traced on {s['driver']}, work group (0, 0)): {s['accesses']} accesses per "
            f"invocation, "
            f"{s['barriers']} barriers")
    lines = [head]
    if "pattern" in s:
        lines.append("        shared-memory accesses: " + ("the access pattern of gpu.banks (HPG17 Figure 6), in program "
                                                            "order" if s["pattern"] else
                                                            "another order than gpu.banks' pattern (HPG17 Figure 6); "
                                                            "the counts below are this kernel's own"))
        lines.append("        shared-memory accesses: " + _conflicts(s["conflicts"]) + " (HPG17 §4.1: none)")
    if s["races"]:
        a, e, w, o = s["races"][0]
        where = _cell(a) if "pattern" in s else f"word {a}"
        lines.append(f"      FAIL race: {len(s['races'])} shared words are written and touched by other invocations "
                     f"with no barrier between; first: invocation {w} stores {where} and invocation {o} accesses it "
                     f"after barrier {e} (a missing barrier; this trace does not depend on the driver's schedule)")
    else:
        lines.append("        shared-memory races: none (every word written by one invocation between two barriers is "
                     "touched by no other)")
    return lines
