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
    categories: dict
    worst: list  # dicts: index, category, error, tolerance, got, expected, reference, inputs, comment
    timings: dict
    notes: list = field(default_factory=list)
    components: dict | None = None  # vector outputs: per-component worst ulps / mismatch counts
    language: str = "glsl"
    driver: str = "gl"
    outputs: dict = field(default_factory=dict, repr=False)  # the port's outputs, by name

    @property
    def passed(self):
        return all(c.failures == 0 for c in self.categories.values())

    @property
    def failures(self):
        return sum(c.failures for c in self.categories.values())

    def _table(self):
        if self.exact:
            lines = ["      category  rows | mismatches  accepted ties | failures   (integer output: exact)"]
            for c in self.categories.values():
                lines.append(f"      {c.category:8} {c.rows:5d} | {c.mismatches:10d}  {c.ties:13d} | {c.failures:8d}")
            if self.components is not None:
                lines.append(f"      rows differing per component: {self.components['mismatch']}")
            return lines
        lines = ["      category  rows |  vs expected (float64)       | tolerance  fails |  vs reference float32 (info)",
                 "                     |       abs       rel     ulps |                  |       abs       rel     ulps"]
        for c in self.categories.values():
            lines.append(
                f"      {c.category:8} {c.rows:5d} | {fmt(c.worst_abs):>9} {fmt(c.worst_rel):>9} "
                f"{fmt(c.worst_ulps):>8} | {fmt(c.tolerance):>9} {c.failures:6d} | "
                f"{fmt(c.ref_abs):>9} {fmt(c.ref_rel):>9} {fmt(c.ref_ulps):>8}")
        if self.components is not None:
            lines.append(f"      worst ulps per component: vs expected {self.components['ulps']}"
                         + (f", vs reference float32 {self.components['ref_ulps']}"
                            if self.components.get("ref_ulps") is not None else ""))
        return lines

    def _row(self, r):
        verdict = "FAIL" if r["error"] > r["tolerance"] else "ok"
        ins = "; ".join(f"{k}={_arr(v, np.asarray(v).dtype.kind in 'ui')}" for k, v in r["inputs"].items())
        integer = self.exact
        head = (f"      {verdict:4} row {r['index']} [{r['category']}] "
                + (f"got {_arr(r['got'], integer)}, expected {_arr(r['expected'], integer)}"
                   if integer else
                   f"abs {fmt(r['error'])} (tol {fmt(r['tolerance'])}), rel {fmt(r['rel'])}, "
                   f"ulps {fmt(r['ulps'])}: got {_arr(r['got'])}, expected {_arr(r['expected'])}"))
        if r.get("reference") is not None:
            head += f", {'other-precision code' if integer else 'reference float32'} {_arr(r['reference'], integer)}"
        return [head, f"           inputs: {ins}", f"           ({r['comment']})"]

    def format(self):
        """The report as printed by ``moments-ref conformance``."""
        lines = [f"{'PASS' if self.passed else 'FAIL'}  {self.function} ({self.path}, {self.language}) on "
                 f"{self.case}: {self.rows} rows" + ("" if self.passed else f", {self.failures} exceed the tolerance"),
                 f"      driver: {self.driver}; renderer: {self.renderer}"]
        lines += [f"      note: {n}" for n in self.notes]
        lines += self._table()
        if self.worst:
            lines.append("      worst rows (stiff rows always shown; gate: error > tolerance):")
        for r in self.worst:
            lines += self._row(r)
        lines.append("      timings: " + ", ".join(f"{k} {v * 1e3:.2f} ms" for k, v in self.timings.items()))
        return "\n".join(lines)
