"""The printed conformance report: one case, one port, one driver."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

__all__ = ["ConformanceReport", "fmt"]


def fmt(x):
    """A number for a table: integers as integers, others with three digits."""
    if x is None:
        return "-"
    if isinstance(x, float) and (math.isinf(x) or math.isnan(x)):
        return str(x)
    if float(x) == int(x) and abs(x) < 1e6:
        return f"{int(x)}"
    return f"{x:.3g}"


def _arr(x, integer=False):
    a = np.asarray(x)
    if integer:
        if a.dtype.itemsize >= 4 and a.ndim == 0:
            return f"0x{int(a):08x}"
        return np.array2string(a, separator=", ")
    return np.array2string(a.astype(np.float64), precision=9, separator=", ")


@dataclass
class ConformanceReport:
    """Result of :func:`run_case`; ``passed`` and ``format()``."""

    case: str
    function: str
    path: str
    renderer: str
    rows: int
    exact: bool
    categories: dict  # category -> verdict.CategoryResult
    worst: list  # dicts: index, tc_id, category, flags, passed, error, tolerance, got, expected, inputs, comment
    timings: dict
    notes: list = field(default_factory=list)
    components: dict | None = None  # vector outputs: per-component worst ulps / failing rows
    language: str = "glsl"
    driver: str = "gl"
    outputs: dict = field(default_factory=dict, repr=False)  # the port's outputs, by name
    metric: str = "abs"
    row_pass: np.ndarray | None = field(default=None, repr=False)  # per row, from golden.compare
    groups: list = field(default_factory=list)  # golden.diagnosis.Group: failing rows by level, flag and cause
    verdict: object = field(default=None, repr=False)  # the golden.compare.Verdict
    record: dict | None = field(default=None, repr=False)  # every row's verdict, for --json
    ill: list = field(default_factory=list)  # the ill-conditioned rows shown (conformance.verdict.ill_section)

    @property
    def passed(self):
        return all(c.failures == 0 for c in self.categories.values())

    @property
    def failures(self):
        return sum(c.failures for c in self.categories.values())

    def _table(self):
        if self.exact:
            lines = ["      category  rows | differ  accepted ties | failures   (integer codes: exact, or a stored "
                     "acceptable code on tie rows)"]
            for c in self.categories.values():
                lines.append(f"      {c.category:8} {c.rows:5d} | {c.mismatches:6d}  {c.ties:13d} | {c.failures:8d}")
            if self.components is not None:
                lines.append(f"      failing rows per component: {self.components['mismatch']}")
            return lines
        lines = [f"      category  rows  gated | fails | worst error/tolerance: ratio  error ({self.metric})  tolerance"]
        for c in self.categories.values():
            lines.append(f"      {c.category:8} {c.rows:5d} {c.gated:6d} | {c.failures:5d} | {fmt(c.worst_score):>28} "
                         f"{fmt(c.worst_error):>14} {fmt(c.worst_tolerance):>10}")
        if self.components is not None:
            lines.append(f"      worst float32 ulps per component: {self.components['ulps']}")
        return lines

    def _row(self, r):
        verdict = "ok" if r["passed"] else "FAIL"
        ins = "; ".join(f"{k}={_arr(v, np.asarray(v).dtype.kind in 'ui')}" for k, v in r["inputs"].items())
        if self.exact:
            head = f"got {_arr(r['got'], True)}, expected {_arr(r['expected'], True)}"
            if "acceptable" in r:
                head += f", acceptable (tie) {_arr(r['acceptable'], True)}"
        else:
            also = "" if self.metric == "abs" else f", abs {fmt(r['abs'])}"
            head = (f"{self.metric} {fmt(r['error'])} (tol {fmt(r['tolerance'])}){also}, rel {fmt(r['rel'])}, "
                    f"ulps {fmt(r['ulps'])}: got {_arr(r['got'])}, expected {_arr(r['expected'])}")
        flags = f"; flags {r['flags']}" if r["flags"] else ""
        return [f"      {verdict:4} row {r['index']} [{r['category']}] {head}",
                f"           inputs: {ins}", f"           ({r['comment']})", f"           tc_id {r['tc_id']}{flags}"]

    def _ill_lines(self):
        """The ill-conditioned rows' own section: judged by their band, never counted as passes."""
        t = self.verdict.ill_tally()
        if not t["rows"]:
            return []
        lines = [f"      ill-conditioned (flag wide_spread: the exact value moves under 1-ulp changes of the input): "
                 f"{t['rows']} rows, {t['inside']} explained by their neighbourhood, {t['outside']} outside every "
                 f"neighbour's exact value and legitimate evaluation (fail); never counted as passes"]
        for r in self.ill:
            at = "" if r["value"] is None else f" (value {r['value']})"
            ins = "; ".join(f"{k}={_arr(v, np.asarray(v).dtype.kind in 'ui')}" for k, v in r["inputs"].items()
                            if np.size(v) <= 8)
            exact = f", exact over the neighbourhood [{r['exact'][0]:.9g}, {r['exact'][1]:.9g}]" if "exact" in r else ""
            lines.append(f"      {'ok' if r['passed'] else 'FAIL':4} row {r['index']}{at}: got {r['got']:.9g}, band "
                         f"[{r['band'][0]:.9g}, {r['band'][1]:.9g}]{exact}" + (f"; {ins}" if ins else ""))
        return lines

    def format(self):
        """The report as printed by ``moments-ref conformance``."""
        lines = [f"{'PASS' if self.passed else 'FAIL'}  {self.function} ({self.path}, {self.language}) on "
                 f"{self.case}: {self.rows} rows" + ("" if self.passed else f", {self.failures} exceed the tolerance"),
                 f"      driver: {self.driver}; renderer: {self.renderer}"]
        lines += [f"      note: {n}" for n in self.notes]
        lines += self._table()
        if self.verdict is not None:
            from ..golden.diagnosis import group_lines

            lines += [f"      {x}" for x in group_lines(self.groups, self.failures, self.verdict.strict)]
            t = self.verdict.robustness_tally()
            if t["rows"]:
                mode = "gated (--strict)" if self.verdict.strict else "not gated; --strict gates them"
                lines.append(f"      beyond the algorithm's contract: {t['rows']} rows, {t['would_fail']} outside "
                             f"their tolerance ({t['nonfinite']} NaN or infinite, {t['outside_range']} out of range); "
                             f"{mode}")
            lines += self._ill_lines()
        if self.worst:
            lines.append("      worst rows (failing rows first by error/tolerance; per-row tolerances of the "
                         "golden file, verdict by golden.compare):")
        for r in self.worst:
            lines += self._row(r)
        lines.append("      timings: " + ", ".join(f"{k} {v * 1e3:.2f} ms" for k, v in self.timings.items()))
        return "\n".join(lines)
