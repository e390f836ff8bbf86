"""Diagnosis by cause: failing rows grouped by level and flag, each group with its one-line cause.

``verify`` and ``conformance`` print the same groups (a porter sees why 17 rows fail,
not only the worst five), ``--rows all`` lists every failing row, and ``--json FILE``
writes every row's verdict for dashboards (:func:`json_rows`). Two causes are told
by the port's outputs, not by rules:

* **the bias target** (engine cases): when the declared target is singular (the
  moments of a one- or two-point distribution) and the failing rows are the ones whose
  moments it leaves (nearly) singular, the group names the target and its support;
* **format** (texel-format choices, docs/formats.md): when the port's outputs on the
  failing rows match the expected values of another choice the paper leaves open,
  the group says which (``format``), apart from arithmetic failures.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field

import numpy as np

from .notes import ROBUSTNESS, cause

__all__ = ["bound_groups", "Group", "groups", "group_lines", "json_rows", "write_json", "target_groups",
           "convention_groups", "hazard_groups", "PRINTED_MATCH", "PRINTED_ADVICE", "singular_target_cause",
           "unchanged_band", "OFFSET_CANDIDATES", "SAMPLE_ROWS",
           "CLAMP_CANDIDATES"]


@dataclass
class Group:
    """Failing rows with one level and one set of flags."""

    level: str  # "contract", "robustness" (fails only with --strict), "format", "target"
    flags: str
    rows: list = field(default_factory=list)
    cause: str = ""

    @property
    def count(self):
        return len(self.rows)


def _flags(arrays, i):
    fl = [f for f in str(np.asarray(arrays["flags"])[i]).split(",") if f and f != ROBUSTNESS]
    return ",".join(fl) or str(np.asarray(arrays["category"])[i])


def groups(verdict, arrays, extra=()):
    """Failing rows (of the verdict) and robustness rows that would fail with --strict, grouped.

    ``extra``: groups found by :func:`target_groups` or a format check, whose rows are
    taken out of the plain groups. Largest groups first, per level.
    """
    taken = {i for g in extra for i in g.rows}
    fail = ~verdict.row_pass
    would = np.zeros_like(fail) if verdict.strict_pass is None else (~verdict.strict_pass & ~fail)
    out = {}
    for i in np.flatnonzero(fail | would):
        if int(i) in taken:
            continue
        robust = verdict.robust is not None and verdict.robust[i]
        level = "robustness" if robust else "contract"
        key = (level, _flags(arrays, i))
        g = out.setdefault(key, Group(level, key[1], [], cause(np.asarray(arrays["flags"])[i],
                                                                np.asarray(arrays["category"])[i])))
        g.rows.append(int(i))
    order = {"target": 0, "format": 1, "convention": 1, "contract": 2, "robustness": 3}
    return sorted(list(extra) + list(out.values()), key=lambda g: (order[g.level], -g.count))


def group_lines(gs, failures, strict=False):
    """One line per group: "12 of 17 failures: flags (level): cause"."""
    lines = []
    for g in gs:
        if g.level == "robustness" and not strict:
            lines.append(f"{g.count} beyond the algorithm's contract would fail with --strict: {g.flags}: {g.cause}")
        else:
            lines.append(f"{g.count} of {failures} failures: {g.flags} ({g.level}): {g.cause}")
    return lines


def _fails_with(arrays, preset, ctx, tol, expected):
    """Rows on which the papers' own formulation with bias ``preset`` (float32) misses the expected value."""
    from .engine import papers_chain32

    n = len(np.asarray(arrays["zf"]))
    v = papers_chain32(arrays, preset, ctx, n)
    if ctx.get("visibility"):
        v = 1 - v
    with np.errstate(invalid="ignore"):
        return ~(np.abs(v - expected) <= tol)


def target_groups(verdict, arrays, declared, ctx):
    """A ``target`` group when a singular declared target explains the failing rows of an engine case.

    Told by outputs: the rows it explains are failing rows on which the papers' own
    formulation (the slides' Algorithm 1, or the NLQ chain) in float32, biased with the
    declared α and target, misses the expected value too, while the same with the papers'
    float32 target (same α, an interior point) does not.
    """
    from ..moments import BIAS_FLOAT32, BiasPreset
    from ..scene.depth import moments_affine
    from .engine import target_support

    if declared is None or not getattr(declared, "active", False) or "support" not in arrays:
        return []
    support = target_support(declared.target)
    fail = ~verdict.row_pass
    if support is None or not fail.any():
        return []
    ref = np.asarray(BIAS_FLOAT32.target, np.float64)
    ref = moments_affine(ref, 0.5, 0.5) if ctx.get("unit") else ref
    expected = np.asarray(arrays["intensity"], np.float64)
    tol = np.asarray(arrays["intensity_tolerance_float32"], np.float64)
    own = _fails_with(arrays, BiasPreset(declared.alpha, tuple(declared.target), "declared"), ctx, tol, expected)
    legit = _fails_with(arrays, BiasPreset(declared.alpha, tuple(ref), "papers"), ctx, tol, expected)
    hit = [int(i) for i in np.flatnonzero(fail & own & ~legit)]
    if not hit:
        return []
    return [Group("target", f"bias target {list(declared.target)}", hit, singular_target_cause(support))]


def singular_target_cause(support):
    """Why a bias toward a singular target fails: ``support`` is its unique distribution ((z, w) pairs,
    :func:`moments_ref.golden.engine.target_support`)."""
    what = " + ".join(f"{w:.3g}·δ({round(z, 9):.3g})" for z, w in support)
    kind = "a one-point" if len(support) == 1 else "a two-point"
    return (f"the bias target is singular: the moments of {what}, {kind} distribution on the boundary of the "
            "moment space; distributions on or near its support stay (nearly) singular after biasing, where "
            "the bound divides by zero (with a target strictly inside the moment space these rows pass)")


def _plain(x):
    a = np.asarray(x)
    if a.dtype.kind == "f":
        return [None if not np.isfinite(v) else float(v) for v in a.reshape(-1)] if a.ndim else (
            None if not np.isfinite(a) else float(a))
    if a.dtype.kind in "iu":
        return a.tolist()
    return str(a) if a.ndim == 0 else [str(v) for v in a.reshape(-1)]


def json_rows(name, meta, arrays, got, verdict, gs=()):
    """Every row's verdict of one case as plain JSON values."""
    o = meta["compare"][0]
    label = {i: g.level for g in gs for i in g.rows}
    n = len(verdict.row_pass)
    per_row = [k for k in meta["input_order"] if np.ndim(arrays[k]) and len(arrays[k]) == n]  # not whole-case arrays
    level = verdict.level  # a property computed over every row: once, not per row (was quadratic in the rows)
    rows = []
    for i in range(len(verdict.row_pass)):
        rows.append({
            "tc_id": int(np.asarray(arrays["tc_id"])[i]), "level": str(level[i]),
            "category": str(np.asarray(arrays["category"])[i]), "flags": str(np.asarray(arrays["flags"])[i]),
            "passed": bool(verdict.row_pass[i]),
            "passed_strict": bool(verdict.strict_pass[i]) if verdict.strict_pass is not None else None,
            "error": _plain(verdict.error[i]), "tolerance": _plain(verdict.tolerance[i]),
            "got": _plain(np.asarray(got[o])[i]), "expected": _plain(np.asarray(arrays[o])[i]),
            "inputs": {k: _plain(np.asarray(arrays[k])[i]) for k in per_row},
            "cause": label.get(i, ""), "comment": str(np.asarray(arrays["comment"])[i]),
        })
    return {"case": name, "passed": bool(verdict.passed), "strict": bool(verdict.strict),
            "failures": int(verdict.failures), "robustness": verdict.robustness_tally(),
            "groups": [{"level": g.level, "flags": g.flags, "rows": g.count, "cause": g.cause} for g in gs],
            "rows": rows}


def write_json(path, cases, extra=None):
    """Write ``{"cases": [...]}`` (and ``extra`` keys) to the ``--json`` target ``path``.

    Atomically to a file; through as a stream to a device, FIFO or pipe (never
    replacing it): :func:`moments_ref._io.write_output`.
    """
    from .._io import write_output

    doc = dict(extra or {})
    doc["cases"] = list(cases)
    return write_output(path, json.dumps(doc, indent=1, allow_nan=False) + "\n", "--json")


#: Choices a port may have made without declaring them, tried by :func:`convention_groups`.
CLAMP_CANDIDATES = (1e-6, 5e-6, 1e-5, 1 / 65535)
#: Constant receiver offsets (toward the light) engines use as acne guards, tried likewise.
OFFSET_CANDIDATES = (1e-6, 1e-5, 1e-4, 1e-3)


def _candidates(case, profile):
    """``(profile', level, what)``: profiles differing from ``profile`` in one declaration the case can use.

    The clamp (with its case test), one texel-format key, a constant receiver offset, the
    receiver's depth convention, a caller's clamp; the slope-scaled offset is not tried (it
    changes the function's arguments).
    """
    from dataclasses import replace

    from .profile import CLAMP_TESTS, DEPTHS, FORMAT_KEYS, KEYS

    usable = {k.name for k in KEYS if k.ignored_by(case) is None}
    out = []
    if "clamp" in usable:
        out += [(replace(profile, clamp=c, clamp_test=t), "convention", f"clamp = {c:g}, clamp_test = {t!r}")
                for c in CLAMP_CANDIDATES for t in CLAMP_TESTS]
    if "format" in usable:
        current = dict(profile.format)
        out += [(replace(profile, format=tuple(sorted({**current, k: v}.items()))), "format", f"format.{k} = {v!r}")
                for k, values in FORMAT_KEYS.items() for v in values if current.get(k) != v]
    if "receiver_offset" in usable:
        out += [(replace(profile, receiver_offset=c), "convention", f"receiver_offset = {c:g}")
                for c in OFFSET_CANDIDATES]
    if "receiver_depth" in usable:
        from .receiver import receiver_convention

        out += [(replace(profile, receiver_depth=d), "convention", f"receiver_depth = {d!r}") for d in DEPTHS
                if d != receiver_convention(case, profile)]
    if "output_clamp" in usable:
        out.append((replace(profile, output_clamp=True), "convention", "output_clamp = true"))
    return [(p, level, what) for p, level, what in out if p.key != profile.key]


def _narrowed(got, arrays):
    """Integer readback words as the codes' dtype (where they fit), as the comparator wants them."""
    out = {}
    for o, g in got.items():
        g = np.asarray(g)
        want = np.asarray(arrays[o]).dtype if o in arrays else g.dtype
        if g.dtype.kind in "ui" and want.kind in "ui" and g.dtype != want and g.size and \
                g.min() >= np.iinfo(want).min and g.max() <= np.iinfo(want).max:
            g = g.astype(want)
        out[o] = g
    return out


def unchanged_band(arrays, declared, port_dtype):
    """``arrays`` (a candidate's) with each row's band no wider than under the ``declared`` arrays.

    The band is kept around the candidate's expected value, its half-width the smaller of the
    two: a candidate declaration explains a row only within the band the row already had.
    """
    out = dict(arrays)
    for k in arrays:
        if k.endswith(f"_tolerance_{port_dtype}") and k in declared:
            out[k] = np.minimum(np.asarray(arrays[k]), np.asarray(declared[k]))
    return out


#: Failing rows a candidate is first judged on (derived alone, cheaply) before all rows are.
SAMPLE_ROWS = 8


def _judge(name, p, rows, base_arrays, declared, got, profile, port_dtype, strict):
    """The candidate ``p``'s verdict on ``rows`` (all rows: None) with each row's unchanged band."""
    from .cases import CASES
    from .compare import compare
    from .conventions import profile_arrays, profiled_arrays
    from .receiver import clamp_outputs
    from .writer import manifest_entry

    from .conventions import neighbourhood_case

    case = CASES[name]
    judge = neighbourhood_case(case, p)  # the ill-conditioned rows judged as the verdict judged them
    if rows is None:
        pcase, arrays = profiled_arrays(name, p, arrays=base_arrays, disk=False, fed=profile)
    else:
        n = len(np.asarray(base_arrays["category"]))
        pick = lambda d: {k: (np.asarray(v)[rows] if np.ndim(v) and len(v) == n else v)  # noqa: E731
                          for k, v in d.items()}
        pcase, arrays = profile_arrays(case, pick(base_arrays), p, profile)
        declared, got = pick(declared), pick(got)
    arrays = unchanged_band(arrays, declared, port_dtype)
    seen, _ = clamp_outputs(case, p, got)
    v = compare(manifest_entry(pcase, arrays), arrays, seen, port_dtype, case=name, strict=strict, neighbourhood=judge)
    v.ill_judged = judge is not None
    return v


def convention_groups(name, verdict, base_arrays, got, profile, port_dtype="float32"):
    """Groups told by the port's outputs: an explaining declaration, and printed formulations on hazard rows.

    A declaration that explains the failing rows (:func:`_declaration_groups`), and the failing
    ``printed_hazard`` rows where the output is a printed formulation's (:func:`hazard_groups`).
    """
    found = _declaration_groups(name, verdict, base_arrays, got, profile, port_dtype)
    taken = {i for g in found for i in g.rows}
    return found + hazard_groups(name, verdict, base_arrays, got, profile, taken)


#: Why a printed formulation cancels, and the remedy (:data:`PRINTED_MATCH`; the sweep's ``PRINTED_CAUSE``).
PRINTED_ADVICE = ("in float32 the printed root -p/2 - sqrt(p^2/4 - q) or Algorithm 1's pivot xi4 from the raw moments "
                  "(below float32's resolution of b4 after the bias) loses every digit; take the root without "
                  "cancellation (t = -(q1 + sign(q1) sqrt(disc))/2, z = t/q2 and q0/t) and give xi4 <= 0 the "
                  "singular branch (or compute the pivots with fma)")

#: The cause of a failing ``printed_hazard`` row whose output is a printed formulation's value there.
PRINTED_MATCH = ("your result matches the papers' printed formulation, which cancels on this row (hazard): "
                 + PRINTED_ADVICE)


def hazard_groups(name, verdict, base_arrays, got, profile, taken=()):
    """The failing ``printed_hazard`` rows on which the port returns a printed formulation's value, as one group.

    A ``contract`` group of the failing rows flagged ``printed_hazard`` (under ``profile``) on which the
    port's output is the value of one of the case's printed formulations (its ``spread_hook``, in the
    port's precision, on the inputs the port was given): within the row's tolerance of it, or, where
    the formulation has no value (NaN), NaN or an end of the output's range (what ``saturate`` or
    ``clamp`` make of it). The other failing hazard rows keep the flag's own cause."""
    from .cases import CASES
    from .conventions import profiled_arrays

    case = CASES.get(name)
    if case is None or case.spread_hook is None or len(case.outputs) != 1 or case.integer_output:
        return []
    pcase, arrays = profiled_arrays(name, profile, arrays=base_arrays)
    n, o = len(np.asarray(arrays["category"])), case.outputs[0]
    rows = [int(i) for i in np.flatnonzero(~verdict.row_pass) if int(i) not in taken
            and "printed_hazard" in str(np.asarray(arrays["flags"])[i]).split(",")]
    if not rows or pcase.spread_hook is None or f"{o}_tolerance_{verdict.port_dtype}" not in arrays:
        return []
    g = np.asarray(got[o], np.float64).reshape(n, -1)[rows, 0]
    tol = np.asarray(arrays[f"{o}_tolerance_{verdict.port_dtype}"], np.float64).reshape(n, -1)[rows, 0]
    ends = np.asarray(case.value_range or (), np.float64)
    match = np.zeros(len(rows), bool)
    with np.errstate(invalid="ignore"):
        for v in pcase.spread_hook({k: np.asarray(arrays[k])[rows] for k in case.inputs}, np.dtype(verdict.port_dtype)):
            h = np.asarray(v[0], np.float64).reshape(len(rows), -1)[:, 0]
            none = ~np.isfinite(h)
            match |= (~none & (np.abs(g - h) <= tol)) | (none & (~np.isfinite(g) | np.isin(g, ends)))
    if not match.any():
        return []
    return [Group("contract", "printed_hazard", [r for r, m in zip(rows, match) if m], PRINTED_MATCH)]


def _declaration_groups(name, verdict, base_arrays, got, profile, port_dtype="float32"):
    """A ``format`` (texel-format choice) or ``convention`` (clamp, receiver, caller's clamp) group when
    another declaration explains the port's failing rows: told by outputs, and checked.

    Each candidate (:func:`_candidates`) is judged on the inputs the port was given, with the
    candidate's expected values and each row's unchanged band (:func:`unchanged_band`): first on
    a few failing rows alone (:data:`SAMPLE_ROWS`, a cheap refusal of most candidates; never of one the judge
    on every row accepts: rows that may keep their own cause are not sampled), then on every row. It is suggested only if every failing row then passes and no passing row fails:
    advice never names a declaration under which a failing row passes for another cause (issue
    37 item 5). Failing rows flagged ``printed_hazard`` may still fail under the candidate (a
    copied printed formula fails them under any declaration): those keep their own cause, and
    the advice names the rows it explains.
    """
    from .._arrays import InputError
    from .cases import CASES
    from .conventions import profiled_arrays

    fail = ~verdict.row_pass
    case = CASES.get(name)
    if case is not None and fail.any() and name.startswith("shadow_intensity-") and profile.bound != "hausdorff":
        bound = bound_groups(case, verdict, base_arrays, got, profile)
        if bound:
            return bound
    if case is None or not fail.any():
        return []
    got = _narrowed(got, base_arrays)
    declared = profiled_arrays(name, profile, arrays=base_arrays)[1]
    # Rows flagged printed_hazard keep their own cause (a copied printed formula fails them under any
    # declaration): a candidate must explain every other failing row; those may still fail with it.
    hazard = np.array(["printed_hazard" in str(f).split(",") for f in np.asarray(declared["flags"])], bool)
    other = fail & ~hazard
    # The sample holds only failing rows the judge on every row cannot leave to their own cause: not the hazard
    # rows, nor the ill-conditioned ones (a candidate that leaves them unjudged keeps them failing), so a
    # sampled refusal is one the judge on every row would make too. Rows derive alone unless the case's arrays
    # are whole-case or the feed depends on the row count (slopes).
    ill = np.zeros_like(fail) if verdict.ill is None else np.asarray(verdict.ill, bool)
    sampled = np.flatnonzero(other & ~ill)[:SAMPLE_ROWS]
    sample = sampled if sampled.size and case.row_inputs and not profile.receiver_slope else None
    for p, level, what in _candidates(case, profile):
        try:
            if sample is not None and _judge(name, p, sample, base_arrays, declared, got, profile, port_dtype,
                                             verdict.strict).failures:
                continue
            v = _judge(name, p, None, base_arrays, declared, got, profile, port_dtype, verdict.strict)
        except (InputError, TypeError, ValueError, KeyError):  # a choice this version cannot evaluate
            continue
        keep = hazard & fail  # failing rows that keep their own cause and may still fail under the candidate
        if not v.ill_judged and verdict.ill is not None:
            # a key the exact values do not carry (a receiver convention) leaves the ill-conditioned rows their
            # stored band alone: a row failing by its neighbourhood is not explained by the declaration (it keeps
            # its cause), though the stored band would hold it
            unjudged = fail & np.asarray(verdict.ill, bool)
            v.row_pass = v.row_pass & ~unjudged
            keep = keep | unjudged
        explained = fail & v.row_pass
        if explained.any() and not (~v.row_pass & ~keep).any():  # only failing hazard (or unjudged ill) rows may fail
            return [Group(level, what, [int(i) for i in np.flatnonzero(explained)],
                          f"the outputs are those of {what}: every failing row passes with it, within its "
                          "unchanged band (rows flagged printed_hazard apart); a convention, not an arithmetic "
                          "error: declare it in the profile (docs/ports.md)")]
    return []


def bound_groups(case, verdict, base_arrays, got, profile):
    """A ``convention`` group advising ``bound = "hausdorff"`` when that explains the failing rows.

    Checked, not guessed: on the inputs the port received (the profile's conversions), the
    Hausdorff bound (:mod:`moments_ref.hausdorff`, float64) must lie within each row's *own*
    tolerance of the port's output (the band is not widened), on at least half of the failing
    rows not flagged ``printed_hazard`` under the profile (a cancelling printed formula returns 0 there,
    which the Hausdorff bound can match by coincidence: such rows alone never bring the advice), and
    the group holds every failing row it explains. Rows it does not explain (a NaN at a receiver at
    depth 0) stay failures.
    """
    from ..hausdorff import shadow_intensity
    from .conventions import convert_inputs, profiled_arrays

    fail = ~verdict.row_pass
    flags = profiled_arrays(case.name, profile, arrays=base_arrays)[1]["flags"]
    hazard = np.array(["printed_hazard" in str(f).split(",") for f in flags], bool)
    if verdict.tolerance is None or "intensity" not in got:
        return []
    ins = convert_inputs(case, {k: base_arrays[k] for k in case.inputs}, profile)
    want = shadow_intensity(np.asarray(ins["b"], np.float64), np.asarray(ins["zf"], np.float64),
                            case.kwargs.get("bound", "lower"))
    if profile.output == "visibility":
        want = 1 - want
    with np.errstate(invalid="ignore"):
        explained = fail & (np.abs(np.asarray(got["intensity"], np.float64) - want) <= verdict.tolerance)
    # counted on the failing rows not flagged printed_hazard (there a cancelling printed formula returns 0, which
    # the Hausdorff bound can match by coincidence); a hazard row the bound explains joins the group
    if (explained & ~hazard).sum() < max(1, (fail & ~hazard).sum() // 2):
        return []
    return [Group("convention", 'bound = "hausdorff"', [int(i) for i in np.flatnonzero(explained)],
                  "the outputs on these rows are Peters and Klein's Hausdorff bound (depths in [0, 1]) within "
                  "the rows' own tolerance, not Algorithm 1's: declare bound = \"hausdorff\" in the profile "
                  "(docs/ports.md) to be judged by the hausdorff-* cases")]
