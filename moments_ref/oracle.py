"""Check a foreign Python implementation against the reference.

``check(candidate, case, dtype=...)`` runs a callable on the golden inputs of a
case (the same rows ``moments-ref golden`` writes, built in memory) and on inputs
drawn by hypothesis, compares with the expected values of the reference and
returns the worst absolute and relative error and the input that produced them.

Example
-------
>>> import numpy as np
>>> from moments_ref import oracle, shadow_intensity
>>> report = oracle.check(lambda b, zf: shadow_intensity(b, zf), "shadow_intensity-lower",
...                       dtype="float64", n_hypothesis=20)
>>> report.passed
True
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ._arrays import InputError
from .golden import CASES, CATEGORIES, _evaluate, case_rows, expected_outputs

__all__ = ["check", "OracleReport", "input_strategy"]


@dataclass
class OracleReport:
    """What :func:`check` found."""

    case: str
    dtype: str
    rows: int
    worst_abs: float
    worst_rel: float
    worst_input: dict
    worst_category: str
    worst_got: object
    worst_expected: object
    per_category: dict = field(default_factory=dict)  # category -> dict(abs, rel, rows, tolerance)
    passed: bool = True

    def __str__(self):
        lines = [f"{'PASS' if self.passed else 'FAIL'} {self.case} ({self.dtype}, {self.rows} rows): "
                 f"worst abs {self.worst_abs:.3g}, worst rel {self.worst_rel:.3g} [{self.worst_category}]"]
        for c, d in self.per_category.items():
            lines.append(f"  {c:10} rows {d['rows']:5d}  abs {d['abs']:.3g}  rel {d['rel']:.3g}  "
                         f"tolerance {d['tolerance']:.3g}")
        lines.append(f"  worst input: {self.worst_input}; got {self.worst_got}, expected {self.worst_expected}")
        return "\n".join(lines)


def input_strategy(case):
    """A hypothesis strategy of one input row (dict of arrays) for ``case``."""
    from hypothesis import strategies as st

    from .strategies import depth_distributions, depths, moment_vectors

    c = CASES[case]
    stem = c.name.split("-")[0]
    n6 = stem.endswith("6") or "r10g10b10a2" in stem
    parts = {}
    for name in c.inputs:
        if name == "b":
            parts[name] = moment_vectors(n=6 if n6 else 4, distributions=depth_distributions())
        elif name == "zf":
            parts[name] = depths(-1.5, 1.5).map(np.float64)
        elif name == "q":
            from .affine import to_optimized

            parts[name] = moment_vectors().map(to_optimized)
        elif name == "u":
            parts[name] = st.lists(st.integers(0, 65535), min_size=4, max_size=4).map(np.array)
        elif name == "p":
            parts[name] = st.lists(st.integers(0, (1 << 30) - 1), min_size=2, max_size=2).map(np.array)
        else:
            raise InputError(f"case: no input strategy for argument {name!r} of {case!r}")
    return st.fixed_dictionaries(parts)


def _hypothesis_rows(case, n, seed):
    from hypothesis import HealthCheck, Phase, given, settings

    drawn = []

    @settings(max_examples=n, derandomize=True, database=None, deadline=None,
              suppress_health_check=list(HealthCheck),
              phases=[Phase.explicit, Phase.reuse, Phase.generate])
    @given(input_strategy(case))
    def collect(row):
        drawn.append(row)

    collect()
    return drawn[:n]


def check(candidate, case, dtype="float32", n_hypothesis=200, seed=0, vectorized=True):
    """Run ``candidate`` on golden and hypothesis inputs and compare with the reference.

    Parameters
    ----------
    candidate : callable
        Called as ``candidate(*inputs)`` with the case's input arrays in order
        (for example ``(b, zf)`` with ``b`` (n, 4) and ``zf`` (n,)); returns the
        output array (or a tuple when the function has several outputs).
        ``vectorized=False`` calls it once per row instead.
    case : str
        A golden case without its dtype suffix (``"shadow_intensity-lower"``) or
        with it (``"shadow_intensity-lower-float32"``).
    dtype : {"float32", "float64"}
        The candidate's precision: inputs are given in this dtype and the case's
        tolerances for this dtype apply.
    n_hypothesis : int
        Extra rows drawn by hypothesis (derandomized: reproducible).

    Returns
    -------
    OracleReport
    """
    if dtype not in ("float32", "float64"):
        raise InputError(f"dtype: expected 'float32' or 'float64', got {dtype!r}")
    name = case if case in CASES else f"{case}-{dtype}"
    if name not in CASES:
        stems = sorted({n.rsplit("-", 1)[0] for n in CASES})
        raise InputError(f"case: unknown case {case!r}; known: {', '.join(stems)}")
    c = CASES[name]
    inputs, category, comment = case_rows(c)
    if n_hypothesis:
        extra = _hypothesis_rows(name, n_hypothesis, seed)
        for k in c.inputs:
            add = np.stack([np.asarray(r[k]) for r in extra]).astype(inputs[k].dtype)
            inputs[k] = np.concatenate([inputs[k], add])
        category = np.concatenate([category, np.full(len(extra), "hypothesis")])
    inputs = {k: (v if k in c.integer_inputs else v.astype(dtype)) for k, v in inputs.items()}
    expected = expected_outputs(c, inputs)
    args = [inputs[k] for k in c.inputs]
    if vectorized:
        got = candidate(*args)
    else:
        rows = [candidate(*[a[i] for a in args]) for i in range(len(category))]
        got = tuple(np.stack([np.asarray(r[j]) for r in rows]) for j in range(len(c.outputs))) \
            if len(c.outputs) > 1 else np.stack([np.asarray(r) for r in rows])
    got = got if isinstance(got, tuple) else (got,)
    if len(got) != len(c.outputs):
        raise InputError(f"candidate: expected {len(c.outputs)} output(s) {c.outputs}, got {len(got)}")
    n = len(category)
    abs_err = np.zeros(n)
    rel_err = np.zeros(n)
    for g, e, out in zip(got, expected, c.outputs):
        g = np.asarray(g)
        e = np.asarray(e)
        if g.shape != e.shape:
            raise InputError(f"candidate: output {out!r} expected shape {e.shape}, got {g.shape}")
        with np.errstate(invalid="ignore", divide="ignore"):
            d = np.abs(g.astype(np.float64) - e.astype(np.float64)).reshape(n, -1)
            d = np.where(np.isnan(d), np.inf, d)
            r = d / np.maximum(np.abs(e.astype(np.float64)).reshape(n, -1), np.finfo(np.float64).tiny)
        abs_err = np.maximum(abs_err, d.max(axis=1))
        rel_err = np.maximum(rel_err, r.max(axis=1))
    _, _, _, _, tolerances = _evaluate(c)
    tol = tolerances[dtype]
    per_cat = {}
    passed = True
    for cat in list(CATEGORIES) + ["hypothesis"]:
        sel = category == cat
        if not sel.any():
            continue
        # Hypothesis rows include singular and clustered distributions: the stiff tolerance.
        t = tol.get(cat, max(tol["random"], tol["stiff"]))
        a = float(abs_err[sel].max())
        per_cat[cat] = {"abs": a, "rel": float(rel_err[sel].max()), "rows": int(sel.sum()),
                        "tolerance": t}
        passed &= a <= t
    i = int(np.argmax(abs_err))
    return OracleReport(
        case=name, dtype=dtype, rows=n, worst_abs=float(abs_err[i]), worst_rel=float(rel_err[i]),
        worst_input={k: inputs[k][i] for k in c.inputs}, worst_category=str(category[i]),
        worst_got=[np.asarray(g)[i] for g in got], worst_expected=[np.asarray(e)[i] for e in expected],
        per_category=per_cat, passed=passed,
    )
