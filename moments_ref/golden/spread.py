"""Per-row tolerances from the measured spread of legitimate implementations.

For every row, the expected value (mpmath twin, else float64 reference) is compared
with *legitimate* evaluations of the same equation:

* this reference run in the port's precision (float32 emulates a GPU) and in float64;
* the same with every float input scaled by ``1 ± PERTURB_ULPS`` ulps of the port's
  precision (jointly, so exact equalities such as ``zf = y1`` survive): a backward
  error of that size is what operations up to 3 ulps off (GLSL/HLSL division and
  square root, fused multiply-add, rearranged formulas) produce.

The band of a row is the interval those evaluations span, widened by a margin and capped
for bounded outputs (:mod:`moments_ref.golden.bands`, the one model the goldens and the
sweep share); the golden file stores, per output component, the smallest symmetric
tolerance about the expected value that holds it. Metric ``"abs"``
tolerances are absolute, ``"ulps"`` tolerances count units in the last place of the
port's precision. Rows whose value is undefined (flags in
:data:`moments_ref.golden.notes.UNGATED`) get an infinite tolerance and result
``acceptable``.

Integer outputs are exact: the expected code is the ground truth's (the exact code of
the real number the formula gives, :mod:`moments_ref.golden.texel_truth`) where the
case has one. A row whose code differs between the ground truth, the reference in
float32, in float64 and on inputs nudged by ``8 eps(float32)`` sits on a rounding
tie: the codes seen are stored as the row's acceptable set, the row is
``acceptable`` and carries the flag ``rounding_tie``. A tie is legitimate only where
the exact scaled value lies within :data:`TIE_BAND` of the code range from a
rounding boundary (the case's ``margin``); a reference that disagrees with the
ground truth anywhere else is a bug, and :func:`derive` refuses to write the row.
The non-linear texels' encoders (``pack64``, ``pack32``) store instead the per-component tie rule's codes
(:mod:`moments_ref.golden.texel_codes`: a component within its tie band, derived from the formula, of its boundary
may hold the code across it), the rule the sweep and ``confirm`` apply; their reference must hold no other code.
"""

from __future__ import annotations

import functools
import math

import numpy as np

from .bands import TIE_BAND  # noqa: F401 - one constant with bands.confirm (re-exported)
from .bands import FLOOR_ULPS, INDEPENDENT_ULPS, PERTURB_ULPS, STRUCTURED, equal_inputs, evaluations, interval_parts, noise_of
from .cases import CASES, case_table, evaluate_reference, expected_outputs
from .texel_codes import DERIVED_BAND
from .notes import ROBUSTNESS, UNGATED, UNGATED32
from .units import PORT_DTYPES, ceil2, ulp

__all__ = ["derive", "golden_arrays", "gated_summary", "robust_rows", "ceil2", "row_tolerance", "FLOOR_ULPS",
           "PERTURB_ULPS", "INDEPENDENT_ULPS", "STRUCTURED", "ulp", "PORT_DTYPES", "TIE_BAND", "TruthMismatch"]

_NUDGE = 8 * float(np.finfo(np.float32).eps)
_WIDE = 0.1
# TIE_BAND (imported above): where a float implementation may store the neighbouring code: the exact scaled
# value within 64 float32 ulps of the code range (2⁻¹⁸ of it) of a rounding boundary; bands.confirm accepts either
# code there.


class TruthMismatch(AssertionError):
    """The reference's codes disagree with the ground truth away from a rounding boundary."""




def _float_tolerances(case, inputs, expected, n, flags, category):
    """``({output: {port dtype: tolerance}}, {port dtype: (n,) ill-conditioned}, (n,) hazard)``.

    The band of :mod:`moments_ref.golden.bands` (one model for goldens and the sweep), stored as
    the smallest symmetric tolerance about the expected value that holds it. Other formulations
    (``spread_hook``: the papers' own code) count only on contract rows: beyond the contract they
    are not legitimate implementations of anything.
    """
    contract = np.array([ROBUSTNESS not in fl for fl in flags], bool)
    random_rows = np.asarray(category) == "random"
    free = np.array([not any(f in STRUCTURED for f in fl) for fl in flags], bool)
    free = free & ~equal_inputs(case, inputs, n) if case.row_inputs else np.zeros(n, bool)
    tol, ill, hazard = {o: {} for o in case.outputs}, {}, np.zeros(n, bool)
    expected = [np.asarray(e, np.float64) for e in expected]
    for dt in PORT_DTYPES:
        core, hooks = evaluations(case, inputs, np.dtype(dt), free)
        noise = noise_of(case, np.dtype(dt), expected, core, random_rows)
        ill[dt] = np.zeros(n, bool)
        for o, e, (lo, hi, wide, haz, _) in zip(case.outputs, expected, interval_parts(
                case, np.dtype(dt), expected, contract, noise, core, hooks)):
            with np.errstate(invalid="ignore"):
                half = np.fmax(e - lo, hi - e)
            half = np.where(np.isnan(half), np.inf, half)
            if case.metric == "ulps":
                t = np.ceil(half / ulp(e, dt) * (1 - 1e-12))
            else:
                t = ceil2(half)
            tol[o][dt] = t
            ill[dt] |= wide.reshape(n, -1).any(axis=1)
            if dt == "float32":
                hazard |= haz.reshape(n, -1).any(axis=1)
    return tol, ill, hazard


def _ties(case, inputs, expected, n, category, comment, flags):
    """Acceptable code sets of integer outputs: ``{output: (n, K, ...) array}``.

    The non-linear texels' encoders (:data:`moments_ref.golden.texel_codes.DERIVED_BAND`) store the per-component
    tie rule's codes, the ones the sweep and ``confirm`` accept (their tie band is derived from the formula); the
    other integer cases the codes of the reference in float32, float64 and on inputs nudged by ``8 eps``."""
    variants = [evaluate_reference(case, inputs, np.float64), evaluate_reference(case, inputs, np.float32)]
    derived = case.tie_neighbours is not None and case.function in DERIVED_BAND
    if derived:
        neighbours = list(case.tie_neighbours(**{k: inputs[k] for k in case.inputs}))
        _check_neighbours(case, inputs, expected, variants, neighbours)
        variants += neighbours
    else:
        for f in (1 + _NUDGE, 1 - _NUDGE):
            nudged = {}
            for k, v in inputs.items():
                v = np.asarray(v, np.float64)
                # Values stay in [-1, 1] if they were (every input domain here is inside it).
                nudged[k] = np.where((np.abs(v * f) > 1) & (np.abs(v) <= 1), v, v * f)
            variants.append(evaluate_reference(case, nudged, np.float64))
    acceptable = {}
    tie = np.zeros(n, bool)
    for i, o in enumerate(case.outputs):
        e = np.asarray(expected[i])
        alts = [e] + [np.asarray(v[i]).astype(e.dtype) for v in variants]
        stack = np.stack(alts, axis=1)  # (n, K, ...)
        tie |= np.any((stack != e[:, None]).reshape(n, -1), axis=1)
        acceptable[o] = stack
    if case.margin is not None and not derived:
        _check_truth(case, inputs, tie)
    for r in np.flatnonzero(tie):
        flags[r] = tuple(flags[r]) + ("rounding_tie",)
        if category[r] != "stiff":
            category[r] = "stiff"
            comment[r] = comment[r] + " [on a rounding boundary: the code changes within float32 rounding of the inputs]"
    return acceptable, tie


def _check_neighbours(case, inputs, expected, refs, neighbours):
    """Raise :class:`TruthMismatch` where the reference (float32, float64) holds, in some component, a code that is
    neither the truth's nor the one across that component's own tie (the per-component rule)."""
    for i, o in enumerate(case.outputs):
        e = np.asarray(expected[i])
        allowed = [e] + [np.asarray(v[i]).astype(e.dtype) for v in neighbours]
        for ref in refs:
            g = np.asarray(ref[i]).astype(e.dtype)
            ok = np.zeros(g.shape, bool)
            for a in allowed:
                ok |= g == a
            bad = np.flatnonzero(~ok.reshape(len(g), -1).all(axis=1))
            if bad.size:
                j = int(bad[0])
                raise TruthMismatch(
                    f"{case.name}: the reference holds a code outside the per-component tie rule on {bad.size} rows; "
                    f"first row {j}: inputs {[np.asarray(v)[j].tolist() for v in inputs.values()]}, reference "
                    f"{g[j].tolist()}, truth {e[j].tolist()}")


def robust_rows(arrays, n=None):
    """``(n,)`` bool: the rows flagged ``robustness`` (beyond the algorithm's contract)."""
    flags = arrays.get("flags") if hasattr(arrays, "get") else None
    if flags is None:
        return np.zeros(len(arrays["result"]) if n is None else n, bool)
    return np.array([ROBUSTNESS in str(f).split(",") for f in np.asarray(flags).reshape(-1)], bool)


def _contract_flags(case, inputs, flags, inside):
    """Add ``robustness`` to the flags of rows outside the case's contract (``inside``, else case.contract)."""
    if inside is None and case.contract is not None:
        from .contract import rows_inside

        inside = rows_inside(case.contract, inputs)
    if inside is None:
        return flags
    inside = np.asarray(inside, bool)
    return [fl if ok or ROBUSTNESS in fl else fl + (ROBUSTNESS,) for fl, ok in zip(flags, inside)]


def _check_truth(case, inputs, tie):
    """Raise :class:`TruthMismatch` where a tie (a code other than the truth's) is not near a boundary."""
    margin = np.asarray(case.margin(**inputs), np.float64)
    bad = np.flatnonzero(tie & (margin > TIE_BAND))
    if bad.size:
        ref = evaluate_reference(case, inputs, case.dtype)
        i = int(bad[0])
        raise TruthMismatch(
            f"{case.name}: the reference disagrees with the ground truth on {bad.size} rows away from a rounding "
            f"boundary; first row {i}: inputs {[np.asarray(v)[i].tolist() for v in inputs.values()]}, reference "
            f"{[np.asarray(o)[i].tolist() for o in ref]}, truth {[np.asarray(o)[i].tolist() for o in case.truth(**inputs)]}, "
            f"margin {margin[i]:.3g} > {TIE_BAND:.3g}")


def derive(case, inputs, category, comment, flags, contract=None):
    """Expected outputs, per-row tolerances, flags and results for rows of ``case``.

    ``contract``: optional ``(n,)`` bool, the rows inside the algorithm's contract
    (default: ``case.contract(inputs)``); the others get the flag ``robustness``.

    Returns
    -------
    arrays : dict
        ``<output>`` (expected), for float outputs ``<output>_tolerance_<port dtype>``
        (output's shape) and for float32 cases ``<output>_float32`` (the
        reference's own float32 result, informational); for integer outputs
        ``<output>_acceptable`` ``(n, K, ...)``; ``tc_id``, ``category``,
        ``comment``, ``flags`` (comma-separated names), ``result``.
    """
    n = len(category)
    category = np.asarray(category).astype("U6").copy()
    comment = list(comment)
    flags = _contract_flags(case, inputs, [tuple(f) for f in flags], contract)
    expected = expected_outputs(case, inputs)
    arrays = {}
    ungated = np.array([any(f in UNGATED for f in fl) for fl in flags], bool)
    ungated32 = np.array([any(f in UNGATED32 for f in fl) for fl in flags], bool)
    result = np.where(ungated, "acceptable", "valid").astype("U10")
    if case.integer_output:
        acceptable, tie = _ties(case, inputs, expected, n, category, comment, flags)
        for i, o in enumerate(case.outputs):
            arrays[o] = np.asarray(expected[i])
            arrays[f"{o}_acceptable"] = acceptable[o]
        result = np.where(tie, "acceptable", result).astype("U10")
    else:
        tol, ill, hazard = _float_tolerances(case, inputs, expected, n, flags, category)
        ref = evaluate_reference(case, inputs, case.dtype) if case.dtype == "float32" else None
        for i, o in enumerate(case.outputs):
            arrays[o] = np.asarray(expected[i], np.float64)
            for dt in PORT_DTYPES:
                t = tol[o][dt]
                t[ungated] = np.inf
                if dt == "float32":
                    t[ungated32] = np.inf
                arrays[f"{o}_tolerance_{dt}"] = t
            if ref is not None:
                arrays[f"{o}_float32"] = np.asarray(ref[i])
        for r in np.flatnonzero(ill["float32"] & ~ungated):
            flags[r] = flags[r] + ("wide_spread",)
        for r in np.flatnonzero(hazard & ~ungated):
            flags[r] = flags[r] + ("printed_hazard",)
    arrays["tc_id"] = np.arange(1, n + 1, dtype=np.int32)
    arrays["category"] = category
    arrays["comment"] = np.asarray(comment).astype(f"U{max(1, max(len(c) for c in comment))}")
    joined = [",".join(dict.fromkeys(f)) for f in flags]
    arrays["flags"] = np.asarray(joined).astype(f"U{max(1, max(len(f) for f in joined))}")
    arrays["result"] = result
    return arrays


def row_tolerance(case, arrays, dt):
    """Per row, the largest tolerance of ``dt`` over the float case's output values: ``(n,)``."""
    n = len(arrays["category"])
    return np.max([arrays[f"{o}_tolerance_{dt}"].reshape(n, -1).max(axis=1) for o in case.outputs], axis=0)


def _ungated_reasons(arrays, rows):
    """``{flag: count}`` of the UNGATED/UNGATED32 flags that leave ``rows`` ungated."""
    out = {}
    for f in np.asarray(arrays["flags"])[rows]:
        names = [x for x in str(f).split(",") if x in UNGATED + UNGATED32] or ["unflagged"]
        out[names[0]] = out.get(names[0], 0) + 1
    return out


def gated_summary(case, arrays):
    """Per port dtype: rows gated (finite tolerance, result valid), and rows gated below 0.1 (abs metric).

    ``levels`` counts the rows per level (``contract``, ``robustness``): rows, gated
    rows, and the ungated rows by the flag whose note gives the reason.
    """
    n = len(arrays["category"])
    valid = arrays["result"] == "valid"
    robust = robust_rows(arrays, n)
    out = {"rows": int(n)}
    for dt in PORT_DTYPES:
        if case.integer_output:
            out[dt] = {"gated": int(valid.sum()), "exact": int(valid.sum())}
            gate = np.ones(n, bool)  # ties are gated too: to their acceptable set
        else:
            t = row_tolerance(case, arrays, dt)
            entry = {"gated": int((valid & np.isfinite(t)).sum())}
            if case.metric == "abs":
                entry["gated_below_0.1"] = int((valid & (t < _WIDE)).sum())
            tmax = t[np.isfinite(t)]
            entry["median_tolerance"] = float(np.median(tmax)) if tmax.size else math.inf
            out[dt] = entry
            gate = valid & np.isfinite(t)
        out[dt]["levels"] = {
            level: {"rows": int(sel.sum()), "gated": int((sel & gate).sum()),
                    "ungated": _ungated_reasons(arrays, sel & ~gate)}
            for level, sel in (("contract", ~robust), ("robustness", robust))}
    return out


def golden_arrays(case):
    """All arrays of ``case``'s golden file (inputs, expected outputs, tolerances, row labels).

    A shipped case (the object in :data:`~moments_ref.golden.cases.CASES`) is generated once
    per process: its rows are seeded, so every call would give the same arrays. The arrays
    are shared read-only (a fresh dict each call); any other case is generated each call.
    """
    if CASES.get(case.name) is case:
        return dict(_shipped_arrays(case.name))
    return _generate(case)


@functools.lru_cache(maxsize=None)
def _shipped_arrays(name):
    """The arrays of shipped case ``name``, generated on the first call, read-only."""
    arrays = _generate(CASES[name])
    for a in arrays.values():
        a.flags.writeable = False  # shared by every caller
    return arrays


def _generate(case):
    inputs, category, comment, flags = case_table(case)
    arrays = dict(inputs)
    if case.deriver is not None:
        arrays.update(case.deriver(case, inputs, category, comment, flags))
    else:
        arrays.update(derive(case, {k: inputs[k] for k in case.inputs}, category, comment, flags))
    if case.extra is not None:  # a kernel case's expected codes
        arrays.update(case.extra(inputs))
    return arrays
