"""Check a foreign Python implementation against the reference.

``check(candidate, case, dtype=...)`` runs a callable on the golden rows of a case
(the rows ``moments-ref golden`` writes, built in memory) and on rows drawn by
hypothesis, and judges its outputs with the same comparator as ``moments-ref
verify`` (:mod:`moments_ref.golden.compare`): hypothesis rows get per-row
tolerances by the same rule as golden rows (:mod:`moments_ref.golden.spread`) and
are classified like them (``stiff`` where legitimate implementations differ by
1e-3 or more, ``edge`` where an input sits at a domain end, else ``random``).
The draws are derandomized (the same rows for a case and count, whichever call),
so a process draws them once and checks every candidate on the same rows.
``golden_dir`` takes the golden rows from a folder ``moments-ref golden`` wrote
instead, read by the one strict loader of ``verify`` and ``conformance``
(:mod:`moments_ref.golden.loader`).

hypothesis comes with the ``test`` extra, not with the base install: it is
imported only when rows are drawn (``n_hypothesis > 0``), so ``import
moments_ref.oracle`` and ``check(..., n_hypothesis=0)`` work without it, and a
check that draws rows without it raises an :class:`~moments_ref.InputError`
naming the extra.

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

import functools
from dataclasses import dataclass, field

import numpy as np

from ._arrays import InputError, brief
from .golden.cases import CASES, call_implementation
from .golden.loader import load_case
from .golden.compare import compare
from .golden.spread import derive, row_tolerance
from .golden.writer import golden_arrays, manifest_entry

__all__ = ["check", "sweep", "OracleReport", "input_strategy", "MAX_HYPOTHESIS"]

#: Most rows :func:`check` draws with hypothesis.
MAX_HYPOTHESIS = 100_000


@dataclass
class OracleReport:
    """What :func:`check` found."""

    case: str
    dtype: str
    rows: int
    failures: int
    worst_score: float  # error / tolerance of the worst row (> 1 fails)
    worst_abs: float
    worst_rel: float
    worst_input: dict
    worst_category: str
    worst_got: object
    worst_expected: object
    per_category: dict = field(default_factory=dict)  # category -> dict(rows, failures, score, abs)
    passed: bool = True

    def __str__(self):
        lines = [f"{'PASS' if self.passed else 'FAIL'} {self.case} ({self.dtype}, {self.rows} rows, "
                 f"{self.failures} fail): worst error/tolerance {self.worst_score:.3g}, worst abs "
                 f"{self.worst_abs:.3g}, rel {self.worst_rel:.3g} [{self.worst_category}]"]
        for c, d in self.per_category.items():
            lines.append(f"  {c:10} rows {d['rows']:5d}  failures {d['failures']:4d}  "
                         f"error/tolerance {d['score']:.3g}  abs {d['abs']:.3g}")
        lines.append(f"  worst input: {self.worst_input}; got {self.worst_got}, expected {self.worst_expected}")
        return "\n".join(lines)


def input_strategy(case):
    """The hypothesis strategy of one input row of ``case`` (:func:`moments_ref.tools.strategies.input_strategy`)."""
    return _strategies().input_strategy(case)


def _strategies():
    try:
        from .tools import strategies
    except ModuleNotFoundError as exc:
        if exc.name != "hypothesis":
            raise
        raise InputError("n_hypothesis: rows drawn by hypothesis need the test extra (pip install "
                         "'moments_ref[test]', in a checkout pip install -e '.[test]'); pass n_hypothesis=0 to "
                         "check the golden rows alone") from None
    return strategies


@functools.lru_cache(maxsize=32)
def _hypothesis_rows(case, n):
    """The ``n`` rows hypothesis draws for ``case`` (derandomized: the same rows every call, so they
    are drawn once per process; read-only, as they are shared)."""
    strategies = _strategies()
    from hypothesis import HealthCheck, Phase, given, settings

    drawn = []

    @settings(max_examples=n, derandomize=True, database=None, deadline=None,
              suppress_health_check=list(HealthCheck), phases=[Phase.explicit, Phase.reuse, Phase.generate])
    @given(strategies.input_strategy(case))
    def collect(row):
        drawn.append(row)

    collect()
    for row in drawn:
        for v in row.values():
            if isinstance(v, np.ndarray):
                v.setflags(write=False)
    return tuple(drawn[:n])


def _classify(c, inputs, arrays):
    """Categories of hypothesis rows, by the golden rule (see the module docstring)."""
    n = len(arrays["category"])
    cat = np.full(n, "random", dtype="U10")
    for k, v in inputs.items():
        if k in c.integer_inputs:
            continue
        v = np.asarray(v, np.float64).reshape(n, -1)
        cat[np.any((np.abs(v) == 1) | (v == 0), axis=1)] = "edge"
    if not c.integer_output:
        cat[row_tolerance(c, arrays, c.dtype) >= 1e-3] = "stiff"
    return cat


def _hypothesis_arrays(c, n):
    extra = _hypothesis_rows(c.name, n)
    inputs = {}
    for k in c.inputs:
        dt = c.integer_inputs.get(k, c.dtype)
        inputs[k] = np.stack([np.asarray(r[k]) for r in extra]).astype(dt)
    m = len(extra)
    arrays = dict(inputs)
    labels = (["random"] * m, ["drawn by hypothesis"] * m, [()] * m)
    # The case's own deriver where it has one (the bilinear cases' declared filter spread), as golden rows get.
    arrays.update((c.deriver or derive)(c, inputs, *labels))
    arrays["category"] = _classify(c, inputs, arrays)
    return arrays


def _concat(a, b):
    out = {}
    for k in a:
        x, y = np.asarray(a[k]), np.asarray(b[k])
        if x.dtype.kind == "U":
            width = max(x.dtype.itemsize, y.dtype.itemsize) // 4
            x, y = x.astype(f"U{width}"), y.astype(f"U{width}")
        if x.ndim >= 2 and x.shape[1:] != y.shape[1:]:  # acceptable sets of different sizes
            k_max = max(x.shape[1], y.shape[1])
            pad = lambda z: np.concatenate([z] + [z[:, :1]] * (k_max - z.shape[1]), axis=1)  # noqa: E731
            x, y = pad(x), pad(y)
        out[k] = np.concatenate([x, y])
    return out


def check(candidate, case, dtype="float32", n_hypothesis=200, seed=0, vectorized=True, profile=None, strict=False,
          golden_dir=None):
    """Run ``candidate`` on golden and hypothesis rows and judge it like ``verify``.

    Parameters
    ----------
    candidate : callable
        Called as ``candidate(*inputs)`` with the case's input arrays in order
        (``b`` (n, 4) and ``zf`` (n,) for Algorithm 1); returns the output array
        (or a tuple for several outputs) with the dtype ``verify`` demands.
        ``vectorized=False`` calls it once per row instead.
    case : str
        A golden case without its dtype suffix (``"shadow_intensity-lower"``) or with it.
    dtype : {"float32", "float64"}
        The candidate's precision: the case of that dtype is used, inputs come in
        it and its tolerance column applies.
    n_hypothesis : int
        Extra rows drawn by hypothesis (derandomized: reproducible), 0 to
        :data:`MAX_HYPOTHESIS`. Kernel cases (``kernel-*``: whole maps, one row per
        texel) get none: a texel depends on its neighbours.
    seed : int
        Unused (kept for compatibility; the draws are derandomized).
    profile : moments_ref.golden.profile.Profile or path, optional
        The engine's declared conventions (depth convention, output, bias, clamp,
        texel format; docs/ports.md): the candidate gets the rows converted for them,
        expected values and tolerances are derived for them.
    strict : bool
        Robustness rows (beyond the algorithm's contract) fail the verdict too.
    golden_dir : path, optional
        Take the golden rows from this folder (``moments-ref golden --out``),
        checked by :func:`moments_ref.golden.loader.load_case`, instead of
        building them in memory.

    Returns
    -------
    OracleReport
    """
    if dtype not in ("float32", "float64"):
        raise InputError(f"dtype: expected 'float32' or 'float64', got {dtype!r}")
    if profile is not None and not hasattr(profile, "is_default"):
        from .golden.profile import load_profile

        profile = load_profile(profile)
    if profile is not None and profile.bound is not None:
        from .golden.cases import bound_case

        case = bound_case(case, profile.bound)  # bound = "hausdorff": judged by the Hausdorff cases
    name = case if case in CASES else f"{case}-{dtype}"
    if name not in CASES:
        stems = sorted({n.rsplit("-", 1)[0] for n in CASES})
        raise InputError(f"case: unknown case {case!r}; known: {', '.join(stems)}")
    if isinstance(n_hypothesis, bool) or not isinstance(n_hypothesis, (int, np.integer)) or not (
            0 <= n_hypothesis <= MAX_HYPOTHESIS):
        raise InputError(f"n_hypothesis: expected an integer in [0, {MAX_HYPOTHESIS}], got {brief(n_hypothesis)}")
    c = CASES[name]
    arrays = golden_arrays(c) if golden_dir is None else _folder_rows(c, golden_dir)
    # Engine cases are distributions (aux arrays), kernel cases whole maps (a texel depends on its neighbours):
    # no draws. Every other case, the bilinear ones included, gets drawn rows.
    if n_hypothesis and not c.aux and not c.function.startswith("kernels."):
        arrays = _concat(arrays, _hypothesis_arrays(c, int(n_hypothesis)))
    plain = c  # no profile: ill-conditioned rows are judged by their neighbourhood (golden.compare.confirm_ill)
    if profile is not None and not profile.is_default:
        from .golden.conventions import profile_arrays
        from .golden.profile import refuse_meaningless

        refuse_meaningless([c], profile)  # the one case checked: a key it cannot use is refused, not dropped
        from .golden.conventions import neighbourhood_case

        plain = neighbourhood_case(c, profile)  # the profiled case's exact values, where they carry the profile
        c, arrays = profile_arrays(c, arrays, profile)
    got = call_implementation(candidate, c, arrays, vectorized, argument="candidate")
    if profile is not None and profile.output_clamp:  # the caller's clamp, declared (golden.receiver)
        from .golden.receiver import clamp_outputs

        got, _ = clamp_outputs(c, profile, got)
    verdict = compare(manifest_entry(c, arrays), arrays, got, dtype, case=name, strict=strict, neighbourhood=plain)
    return _report(c, name, dtype, arrays, got, verdict)


def _folder_rows(c, golden_dir):
    """The rows of case ``c`` from a golden folder, through the strict loader; the case must match this version's."""
    meta, arrays = load_case(golden_dir, c.name)
    order = list(meta.get("input_order", meta["inputs"]))
    if order != list(c.inputs) or list(meta["compare"]) != list(c.outputs):
        raise InputError(f"golden_dir: case {c.name!r} has inputs {order} and outputs "
                         f"{meta['compare']}, this version's has {list(c.inputs)} and {list(c.outputs)}")
    return dict(arrays)


def _report(c, name, dtype, arrays, got, verdict):
    o = c.outputs[0]
    n = len(arrays["category"])
    e = np.asarray(arrays[o], np.float64).reshape(n, -1)
    g = np.asarray(got[o], np.float64).reshape(n, -1)
    with np.errstate(invalid="ignore", divide="ignore"):
        a = np.abs(g - e)
        a = np.where(np.isnan(a), np.inf, a).max(axis=1)
        r = np.where(a == 0, 0.0, a / np.maximum(np.abs(e).max(axis=1), np.finfo(np.float64).tiny))
    i = int(np.argmax(verdict.score)) if verdict.score.max() > 0 else int(np.argmax(a))
    per = {}
    for cat in dict.fromkeys(arrays["category"]):
        sel = arrays["category"] == cat
        per[str(cat)] = {"rows": int(sel.sum()), "failures": int((~verdict.row_pass[sel]).sum()),
                         "score": float(verdict.score[sel].max()), "abs": float(a[sel].max())}
    return OracleReport(
        case=name, dtype=dtype, rows=n, failures=verdict.failures, worst_score=float(verdict.score[i]),
        worst_abs=float(a[i]), worst_rel=float(r[i]), worst_input={k: arrays[k][i] for k in c.inputs if c.row_inputs},
        worst_category=str(arrays["category"][i]), worst_got=np.asarray(got[o])[i],
        worst_expected=np.asarray(arrays[o])[i], per_category=per, passed=verdict.passed)


def sweep(fn, case, rows=10**6, seed=0, vectorized=True, out=None, shrink=True, profile=None, strict=False):
    """Judge a Python implementation on ``rows`` engine-like rows, as ``moments-ref sweep`` judges a port.

    Parameters
    ----------
    fn : callable
        Called as ``fn(*inputs)`` with the case's float32 input arrays in order (as
        :func:`check`); returns the output array (or a tuple).
    case : str
        A float32 case the sweep samples (``"shadow_intensity-lower"`` or with ``-float32``);
        :data:`moments_ref.sweep.samplers.SAMPLERS` lists them.
    rows, seed : int
        Rows drawn (in chunks of :data:`moments_ref.sweep.CHUNK`) and the draw's seed.
    out : path, optional
        Folder for the checkpoint and one golden folder per shrunk failure.
    profile : moments_ref.golden.profile.Profile or path, optional
        The engine's declared conventions (as for :func:`check`): they shape the rows drawn
        ([0, 1] depths, a bias applied before the call) and the expected values.
    strict : bool
        Also fail rows outside the case's contract (robustness rows: counted as ``ungated`` and
        never failed by default, as in the goldens).

    Returns
    -------
    moments_ref.sweep.SweepResult
        ``passed`` is False when mpmath confirmed a wrong row; ``failures`` holds each
        distinct failure shrunk to a small row. Runs in this process.
    """
    from .golden import CASES
    from .sweep import Port, sweep_port

    name = case if case in CASES else f"{case}-float32"
    if name not in CASES:
        raise InputError(f"case: unknown case {case!r}")
    from .sweep.command import make_spec

    if profile is not None and not hasattr(profile, "is_default"):
        from .golden.profile import load_profile

        profile = load_profile(profile)
    spec = make_spec(name, Port(fn=fn, vectorized=vectorized), None, profile, seed, int(rows), strict)
    return sweep_port(spec, 1, None, out, None, shrink)
