"""The one comparator of golden rows: ``verify``, ``oracle.check`` and ``conformance`` use it.

Entry point: :func:`compare(entry, expected, candidate, port_dtype=None)
<compare>` with

* ``entry``: the case's manifest entry (``compare``, ``outputs``, ``dtype``,
  ``metric``, ``value_range``);
* ``expected``: the arrays of the case's golden ``.npz`` (expected outputs,
  ``<output>_tolerance_<float32|float64>``, ``<output>_acceptable``, ``result``,
  ``tc_id``);
* ``candidate``: ``{output name: array}`` from the port.

It returns a :class:`Verdict`: per row pass/fail (``row_pass``), a per-row score
(worst error over tolerance, ``inf`` for NaN or a wrong code), and the error and
tolerance at each row's worst value. The rule, the same for every harness:

* the candidate's dtype must have the manifest's kind: integer outputs any
  integer dtype, float outputs a real float dtype of the port's precision
  (``port_dtype``, default the case's dtype); anything else is an
  :class:`~moments_ref.InputError` naming the array, the expected and the found dtype;
* integer codes compare by value in the manifest's width: a signed array of
  that width holds the codes' bits (an int32 array of uint32 codes, as a shader's
  ``int`` buffer does); any other integer array holds the codes' values (uint32,
  int64, ...). A negative value there is no code (a sign extension?): an
  :class:`~moments_ref.InputError` naming the array and the row. A value beyond
  the width is a wrong code;
* integer outputs: every component equals the expected code or, on rows whose
  ``result`` is ``acceptable``, one of the codes stored for it in
  ``<output>_acceptable`` (rounding ties);
* float outputs: every value is finite and within its tolerance of the expected
  value, measured as the case's ``metric`` says: ``abs`` (absolute difference) or
  ``ulps`` (units in the last place of the port's precision at the expected
  value). Rows with an infinite tolerance (``result`` acceptable: the value is
  undefined there) need only a finite value within the case's ``value_range``;
* rows flagged ``wide_spread`` (ill-conditioned, :mod:`moments_ref.golden.bands`) are judged by their
  band like every row, are marked in ``Verdict.ill``, and never count as passes (the harnesses
  report them in their own section);
* rows flagged ``robustness`` (beyond the algorithm's contract,
  :mod:`moments_ref.golden.contract`) are judged by the same rule, but only
  ``strict=True`` lets them fail the verdict; otherwise what they would fail for
  (``strict_pass``, ``nonfinite``, ``outside_range``) is counted and shown.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._arrays import InputError
from .spread import robust_rows
from .units import ulp

__all__ = ["compare", "Verdict", "check_dtypes", "port_precision", "ill_rows", "confirm_ill"]


@dataclass
class Verdict:
    """Result of :func:`compare` for one case."""

    case: str
    port_dtype: str
    row_pass: np.ndarray  # (n,) bool
    score: np.ndarray  # (n,) float: max error / tolerance over the row's values
    error: np.ndarray | None = None  # (n,) the error (metric's unit) at each row's worst value
    tolerance: np.ndarray | None = None  # (n,) its tolerance (0: exact codes, inf: ungated)
    gated: np.ndarray | None = None  # (n,) bool: the row is held to an expected value (not only a range)
    robust: np.ndarray | None = None  # (n,) bool: robustness rows (beyond the algorithm's contract)
    strict: bool = False  # robustness rows gate the verdict
    strict_pass: np.ndarray | None = None  # (n,) bool: the row passes when robustness rows are gated too
    nonfinite: np.ndarray | None = None  # (n,) bool: a NaN or infinite output value
    outside_range: np.ndarray | None = None  # (n,) bool: a finite value outside the case's value_range
    ill: np.ndarray | None = None  # (n,) bool: ill-conditioned rows (flag wide_spread), judged by their band

    def ill_tally(self):
        """Ill-conditioned rows (flag ``wide_spread``): how many, inside their band, outside it (failing).

        They are judged by their band (the exact values over the float32 neighbourhood and every legitimate
        evaluation), but never count as passes of the port: a row whose answer moves under 1-ulp changes of the
        input cannot tell a correct port from a wrong one that lands in the band."""
        ill = np.zeros(len(self.row_pass), bool) if self.ill is None else self.ill
        if self.gated is not None:
            ill = ill & self.gated  # an ungated row (undefined value) has no band to lie in
        return {"rows": int(ill.sum()), "inside": int((ill & self.strict_pass).sum()),
                "outside": int((ill & ~self.strict_pass).sum())}

    @property
    def passed(self):
        return bool(self.row_pass.all())

    @property
    def failures(self):
        return int((~self.row_pass).sum())

    @property
    def level(self):
        """``(n,)`` str: ``contract`` or ``robustness`` per row."""
        robust = np.zeros(len(self.row_pass), bool) if self.robust is None else self.robust
        return np.where(robust, "robustness", "contract")

    def robustness_tally(self):
        """Robustness rows: how many, how many would fail with ``strict``, NaN and out-of-range among them."""
        robust = np.zeros(len(self.row_pass), bool) if self.robust is None else self.robust
        fail = robust & ~self.strict_pass
        return {"rows": int(robust.sum()), "would_fail": int(fail.sum()),
                "nonfinite": int((fail & self.nonfinite).sum()), "outside_range": int((fail & self.outside_range).sum())}

    def worst_rows(self, k):
        """Indices of the ``k`` failing rows with the largest score (all failing rows if k is None)."""
        bad = np.flatnonzero(~self.row_pass)
        order = bad[np.argsort(-self.score[bad], kind="stable")]
        return [int(i) for i in (order if k is None else order[:k])]


def port_precision(entry, port_dtype=None):
    """The precision a port is judged in: ``port_dtype`` or the case's dtype."""
    dt = port_dtype or entry["dtype"]
    if dt not in ("float32", "float64"):
        raise InputError(f"port_dtype: expected float32 or float64, got {dt!r}")
    return dt


def check_dtypes(entry, candidate, port_dtype=None, prefix=""):
    """Raise :class:`InputError` unless every compared output has the manifest's kind and width."""
    dt = port_precision(entry, port_dtype)
    for o in entry["compare"]:
        name = f"{prefix}{o}"
        if o not in candidate:
            raise InputError(f"results: output {name!r} is missing (the case compares {', '.join(entry['compare'])})")
        got = np.asarray(candidate[o]).dtype
        want = np.dtype(entry["outputs"][o]["dtype"])
        if entry["metric"] == "exact":
            ok = got.kind in "ui"
            expect = f"an integer dtype ({want} codes)"
        else:
            ok = got.kind == "f" and got.itemsize == np.dtype(dt).itemsize
            expect = f"a real {dt} array (the port's precision)"
        if not ok:
            raise InputError(f"results: {name!r} expected {expect}, found dtype {got}")


def _codes(cand, want, name, n):
    """The candidate's integer codes as uint64 values in the manifest's width (module docstring)."""
    c = np.asarray(cand)
    if c.dtype.kind == "i" and c.dtype.itemsize == want.itemsize:
        return c.astype(f"u{want.itemsize}").astype(np.uint64)  # the same bits, read unsigned
    if c.dtype.kind == "i" and (c < 0).any():
        row = int(np.flatnonzero((c < 0).reshape(n, -1).any(axis=1))[0])
        raise InputError(f"results: {name!r} row {row} holds the negative code {int(c.reshape(n, -1)[row].min())} "
                         f"({c.dtype}); codes are {want} values: save them as {want} (or as "
                         f"int{want.itemsize * 8} holding the same bits)")
    return c.astype(np.uint64)


def _exact(o, expected, cand, n, acceptable_rows, want, name):
    e = np.asarray(expected[o]).astype(np.uint64)
    c = _codes(cand, want, name, n)
    ok = c == e
    alts = expected.get(f"{o}_acceptable")
    if alts is not None:
        a = np.asarray(alts).astype(np.uint64)
        alt_ok = (a == c[:, None]).any(axis=1)
        ok |= alt_ok & acceptable_rows.reshape((n,) + (1,) * (c.ndim - 1))
    err = np.abs(c.astype(np.float64) - e.astype(np.float64)).reshape(n, -1).max(axis=1)
    row_ok = ok.reshape(n, -1).all(axis=1)
    score = np.where(row_ok, 0.0, np.inf)
    return row_ok, score, err, np.zeros(n)


def _float(o, entry, expected, cand, n, dt):
    e = np.asarray(expected[o], np.float64)
    tol = np.asarray(expected[f"{o}_tolerance_{dt}"], np.float64)
    c = np.asarray(cand, np.float64)
    with np.errstate(invalid="ignore", over="ignore"):
        err = np.abs(c - e)
        if entry["metric"] == "ulps":
            err = err / ulp(e, dt)
    finite = np.isfinite(c)
    rng = entry.get("value_range")
    inside = np.ones(c.shape, bool) if rng is None else (c >= rng[0]) & (c <= rng[1])
    gated = np.isfinite(tol)
    with np.errstate(invalid="ignore", divide="ignore"):
        ratio = np.where(gated, err / np.where(gated, tol, 1), 0.0)  # tolerances are > 0 (floor)
    ok = finite & np.where(gated, err <= tol, inside)
    ratio = np.where(~finite | (~gated & ~inside), np.inf, ratio)
    flat = lambda x: x.reshape(n, -1)  # noqa: E731
    k = np.argmax(flat(ratio), axis=1)
    rows = np.arange(n)
    bad = (~flat(finite).all(axis=1), (flat(finite) & ~flat(inside)).any(axis=1))
    return (flat(ok).all(axis=1), flat(ratio).max(axis=1), flat(err)[rows, k], flat(tol)[rows, k]), bad


def compare(entry, expected, candidate, port_dtype=None, case="", strict=False, neighbourhood=None):
    """Judge a port's outputs on one golden case; see the module docstring.

    Parameters
    ----------
    entry : dict
        The case's manifest entry.
    expected : mapping of str to array
        The arrays of the case's golden file.
    candidate : mapping of str to array
        The port's outputs by name (each with the expected shape).
    port_dtype : {"float32", "float64"}, optional
        The port's precision (which tolerance column applies); default the case's.
    case : str
        The case name, for messages.
    strict : bool
        Robustness rows (flag ``robustness``) fail the verdict too.
    neighbourhood : moments_ref.golden.cases.Case, optional
        The case the golden arrays hold, without a profile: its ill-conditioned rows inside their stored
        (symmetric) band are judged by their neighbourhood (:func:`confirm_ill`). ``verify``, ``oracle.check``,
        ``conformance`` and the mutation runner pass it where no profile applies, so the rule stays one.

    Returns
    -------
    Verdict
    """
    dt = port_precision(entry, port_dtype)
    check_dtypes(entry, candidate, dt, prefix=f"{case}." if case else "")
    n = len(expected["result"])
    acceptable_rows = np.asarray(expected["result"]) == "acceptable"
    row_pass = np.ones(n, bool)
    score = np.full(n, -1.0)
    row_err, row_tol, row_gated = np.zeros(n), np.zeros(n), ~acceptable_rows
    nonfinite, outside = np.zeros(n, bool), np.zeros(n, bool)
    robust = robust_rows(expected, n)
    lenient = robust & (not strict)  # robustness rows do not decide the verdict unless strict
    for o in entry["compare"]:
        cand = np.asarray(candidate[o])
        want = np.asarray(expected[o]).shape
        if cand.shape != want:
            raise InputError(f"results: {case + '.' if case else ''}{o!r} has shape {cand.shape}, expected {want}")
        if entry["metric"] == "exact":
            ok, s, err, tol = _exact(o, expected, cand, n, acceptable_rows, np.dtype(entry["outputs"][o]["dtype"]),
                                     f"{case}.{o}" if case else o)
        else:
            (ok, s, err, tol), (nf, out) = _float(o, entry, expected, cand, n, dt)
            nonfinite, outside = nonfinite | nf, outside | out
            finite = np.isfinite(np.asarray(expected[f"{o}_tolerance_{dt}"]).reshape(n, -1)).all(axis=1)
            row_gated = row_gated & finite
        row_pass &= ok
        worse = s > score
        row_err, row_tol = np.where(worse, err, row_err), np.where(worse, tol, row_tol)
        score = np.maximum(score, s)
    verdict_pass = row_pass | lenient
    v = Verdict(case, dt, verdict_pass, np.maximum(score, 0.0), row_err, row_tol, row_gated, robust,
                bool(strict), row_pass, nonfinite, outside, ill_rows(expected, n))
    if neighbourhood is not None:
        confirm_ill(v, neighbourhood, entry, expected, candidate)
    return v


def confirm_ill(v, case, entry, expected, candidate):
    """Judge the ill-conditioned rows inside their stored band by their neighbourhood, in place on ``v``.

    The stored tolerance is symmetric about the expected value, so on a row whose exact value jumps it holds
    values on one side that no neighbour has. A row fails whose value lies outside every neighbour's exact value
    and every legitimate evaluation (:func:`moments_ref.golden.bands.confirm`: mpmath over the float32
    neighbourhood; issue 37, item 2). ``case``: the plain case the arrays hold (no profile). Only rows of one
    value each (not kernel maps, blocks or vectors: the flag is per row, the band per value).
    """
    if case.deriver is not None or case.integer_output or entry["metric"] == "exact" or v.ill is None:
        return
    if case.function.startswith("kernels."):  # a kernel case's rows are the texels of one map: none stands alone
        return
    if any(np.ndim(expected[o]) != 1 for o in entry["compare"]):
        # The flag is per row, the band per value: on a row of many values (a block's pixels, a vector) the values
        # that are not ill-conditioned keep their band's margin, which confirm's span has not.
        return
    sel = np.flatnonzero(v.ill & v.gated & v.strict_pass)
    if not sel.size:
        return
    from .bands import confirm

    wrong = confirm(case, {k: np.asarray(expected[k])[sel] for k in case.inputs},
                    {o: np.asarray(candidate[o])[sel] for o in entry["compare"]}, v.port_dtype)
    bad = sel[wrong]
    v.strict_pass[bad] = False
    v.row_pass[bad] = v.robust[bad] & (not v.strict)
    v.score[bad] = np.maximum(v.score[bad], np.nextafter(1.0, 2.0))


def ill_rows(arrays, n):
    """``(n,)`` bool: the rows flagged ``wide_spread`` (ill-conditioned) in a golden file's ``flags``."""
    flags = arrays.get("flags") if hasattr(arrays, "get") else None
    if flags is None:
        return np.zeros(n, bool)
    return np.array(["wide_spread" in str(f).split(",") for f in np.asarray(flags).reshape(-1)], bool)
