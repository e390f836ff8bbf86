"""One file on both drivers: both verdicts, and the rows where the drivers disagree, and why.

A harness that gives two answers for one file cannot be trusted on the rows where
they differ, so ``--adapter both`` runs the file on OpenGL and on Vulkan, prints
both reports, and lists the rows whose outputs differ in any bit, those whose
verdict differs first. It says how many differing rows have both values in the row's
band (:meth:`DriverComparison.explain`: the band holds the chain as either compiler may
evaluate it, :mod:`moments_ref.golden.gpuspread`, so the difference is legitimate) and
names each row with a value outside it: both values and the band. For GLSL and HLSL it also runs the *as-written* evaluation
(``--adapter as-written``: glslang's SPIR-V on OpenGL with every operation pinned
``NoContraction``, i.e. each result rounded in program order) and names, per row,
the driver whose compiler departed from it. The departures measured on Mesa 22.3
(docs/ports.md, "What the drivers' compilers change"): Vulkan through wgpu drops
``precise`` and reassociates sums; Mesa's GLSL compiler rebalances products and
expands ``mix`` as ``x + a(y − x)``; OpenGL's SPIR-V path expands ``FMix`` the same
way and factors ``fma(−n, lo, fma(−n, hi, x))`` into ``x − n(hi + lo)``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .._arrays import InputError
from ._run import AS_WRITTEN, DRIVERS, language_of, run_case

__all__ = ["DriverComparison", "compare_drivers"]


def _words(outputs, n):
    return np.concatenate([np.asarray(v).reshape(n, -1).view(np.uint32) for v in outputs.values()], axis=1)


@dataclass
class DriverComparison:
    """Both reports, the rows that differ, and per differing row the driver(s) off the as-written value."""

    reports: dict  # driver -> ConformanceReport
    differ: np.ndarray  # row indices whose outputs differ in some bit
    flips: np.ndarray  # of those, rows whose verdict differs
    departed: dict = field(default_factory=dict)  # row -> "gl", "vulkan", "both" (None: no as-written run)
    reference: object = None  # the as-written report, or None
    arrays: dict | None = field(default=None, repr=False)  # the golden file judged (expected values, tolerances)

    def explain(self):
        """Per differing row: both values and the band at the value where they differ most, and whether both
        lie in it (the compilers' legitimate reassociation and contraction explain the difference) or not.

        Returns a list of dicts ``row, value (None for a scalar row), gl, vulkan, band (lo, hi) or None,
        explained``; ``band`` is None for integer outputs (codes: a stored acceptable code or not).
        """
        gl, vk = self.reports["gl"], self.reports["vulkan"]
        o = next(iter(gl.outputs))
        out = []
        for i in self.differ:
            i = int(i)
            a = np.asarray(gl.outputs[o][i]).ravel()
            b = np.asarray(vk.outputs[o][i]).ravel()
            with np.errstate(invalid="ignore", over="ignore"):
                d = np.abs(a.astype(np.float64) - b.astype(np.float64))
            k = int(np.argmax(np.where(np.isnan(d), np.inf, d)))
            band = None
            if self.arrays is not None and f"{o}_tolerance_float32" in self.arrays:
                e = float(np.asarray(self.arrays[o][i], np.float64).ravel()[k])
                t = float(np.asarray(self.arrays[f"{o}_tolerance_float32"][i], np.float64).ravel()[k])
                band = (e - t, e + t)
            out.append({"row": i, "value": k if a.size > 1 else None, "gl": a[k], "vulkan": b[k], "band": band,
                        "explained": bool(gl.row_pass[i] and vk.row_pass[i])})
        return out

    @property
    def passed(self):
        return all(r.passed for r in self.reports.values())

    def format(self, rows=10):
        """Both reports, then the disagreement."""
        lines = [r.format() for r in self.reports.values()]
        gl, vk = self.reports["gl"], self.reports["vulkan"]
        if not len(self.differ):
            lines.append(f"AGREE  gl and vulkan give identical bits on all {gl.rows} rows")
            return "\n".join(lines)
        lines.append(f"DISAGREE  gl and vulkan differ on {len(self.differ)} of {gl.rows} rows; the verdict differs "
                     f"on {len(self.flips)}" + (f" (rows {', '.join(map(str, self.flips[:20]))})" if len(self.flips)
                                                 else ""))
        why = self.explain()
        inside = sum(w["explained"] for w in why)
        lines.append(f"      {inside} of them with both values in the band (the compilers' reassociation and "
                     f"contraction: legitimate); {len(why) - inside} with a value outside it")
        for w in [w for w in why if not w["explained"]][:rows]:
            at = "" if w["value"] is None else f" (value {w['value']})"
            band = "" if w["band"] is None else f", band [{w['band'][0]:.9g}, {w['band'][1]:.9g}]"
            lines.append(f"      outside the band: row {w['row']}{at}: gl {_val(w['gl'])}, vulkan {_val(w['vulkan'])}"
                         f"{band}")
        if self.departed:
            counts = {k: sum(v == k for v in self.departed.values()) for k in ("gl", "vulkan", "both")}
            lines.append(f"      off the as-written value (each operation rounded in program order): gl on "
                         f"{counts['gl']} rows, vulkan on {counts['vulkan']}, both on {counts['both']}")
        o = next(iter(gl.outputs))
        shown = list(self.flips[:rows]) + [i for i in self.differ if i not in self.flips][:max(0, rows - len(self.flips))]
        for i in shown:
            who = self.departed.get(int(i))
            why = f"; {who} off the as-written value" if who else ""
            ref = f", as written {_val(self.reference.outputs[o][i])}" if self.reference is not None else ""
            lines.append(f"      row {i}: gl {_val(gl.outputs[o][i])} ({'ok' if gl.row_pass[i] else 'FAIL'}), vulkan "
                         f"{_val(vk.outputs[o][i])} ({'ok' if vk.row_pass[i] else 'FAIL'}){ref}{why}")
        return "\n".join(lines)


def _val(x):
    a = np.asarray(x)
    return np.array2string(a, precision=9, separator=", ") if a.ndim else f"{float(a):.9g}" if a.dtype.kind == "f" \
        else str(int(a))


def compare_drivers(path, function, case, golden_dir=None, language=None, gc=None, options=None, **verdict):
    """Run ``function`` on both drivers (and as written, for GLSL and HLSL); see the module doc.

    ``verdict``: ``profile``, ``strict`` and ``worst_rows`` of :func:`run_case`, for every run.

    Returns
    -------
    DriverComparison
    """
    from ._cases import load_case

    language = language_of(path, language)
    if verdict.get("profile") is not None and verdict["profile"].bound is not None:
        from ..golden.cases import bound_case

        case = bound_case(case, verdict["profile"].bound)  # the case run_case judges (bound = "hausdorff")
    gc = gc or load_case(case, golden_dir)
    reports = {d: run_case(path, function, case, golden_dir, language, d, gc=gc, options=options, **verdict)
               for d in DRIVERS}
    n = reports["gl"].rows
    a, b = _words(reports["gl"].outputs, n), _words(reports["vulkan"].outputs, n)
    differ = np.flatnonzero((a != b).any(axis=1))
    flips = np.flatnonzero(reports["gl"].row_pass != reports["vulkan"].row_pass)
    cmp = DriverComparison(reports, differ, flips, arrays=gc.arrays)
    if len(differ) and language != "wgsl":
        try:
            ref = run_case(path, function, case, golden_dir, language, AS_WRITTEN, gc=gc, options=options, **verdict)
        except InputError:
            return cmp  # no SPIR-V on this OpenGL driver: the rows are named, not explained
        w = _words(ref.outputs, n)
        off_gl, off_vk = (a != w).any(axis=1), (b != w).any(axis=1)
        cmp.reference = ref
        cmp.departed = {int(i): "both" if off_gl[i] and off_vk[i] else "gl" if off_gl[i] else "vulkan"
                        for i in differ}
    return cmp
