"""The sweep's verdict on a row: the goldens' band model (:mod:`moments_ref.golden.bands`).

Everything the sweep knows about right and wrong goes through three functions, so that the
sweep and the goldens judge by one model:

* :func:`legitimate_interval` — per row and output, the interval ``(lo, hi)`` a correct
  port may return (the interval spanned by the legitimate evaluations of the equation,
  widened by the documented margin, capped for bounded outputs), and the ill-conditioned
  rows, which are reported apart and never counted as wrong. No mpmath: it runs on
  chunks of 10^5–10^6 rows.
* :func:`flagged_rows` — the gated rows outside their interval, less the codes the goldens'
  tie rule accepts (:func:`moments_ref.golden.bands.tie_accepted`, the rule :func:`confirm`
  applies): a code on a rounding tie of its own component is not flagged, a wrong code next to it is. The gated
  rows are those whose float32 neighbourhood reaches the case's contract (:func:`contract_rows`;
  there the papers' formulations are legitimate, as on contract rows), all rows under
  ``--strict``: as in the goldens, a robustness row (unbiased singular moments that float32
  rounding left outside the moment space beyond its neighbourhood) is counted, never failed by
  default.
* :func:`confirm` — a flagged row counts as wrong only when the port's output lies outside
  every exact value (:mod:`moments_ref.precise`) over the float32 neighbourhood of its
  inputs and every legitimate evaluation. A flag that mpmath does not confirm is a defect
  of the tolerance model, never the port's.

Engine cases (``engine-*``) are judged by their own derivation, :func:`moments_ref.golden.engine.derive_engine`,
and confirmed with the exact bounds over the legitimate biases (:mod:`.engine`).
"""

from __future__ import annotations

import numpy as np

from ..golden import bands as _bands
from ..golden.diagnosis import PRINTED_ADVICE as _PRINTED_ADVICE
from . import engine as _engine

__all__ = ["legitimate_interval", "contract_rows", "wrong_rows", "flagged_rows", "confirm", "judges_ill",
           "printed_rows", "envelope_rows", "named_rows", "PRINTED_CAUSE", "ENVELOPE_CAUSE"]


def legitimate_interval(case, inputs, port_dtype="float32", contract=None):
    """``(bands, ill_conditioned)`` of the rows: :func:`moments_ref.golden.bands.legitimate_interval`
    (``contract``: the rows inside the case's contract where a profile's conversion decided it)."""
    if _engine.is_engine(case):
        return _engine.interval(case, inputs, port_dtype)
    return _bands.legitimate_interval(case, inputs, port_dtype, contract=contract)


def confirm(case, inputs, got, port_dtype="float32"):
    """``(n,)`` bool, True where mpmath confirms the row wrong: :func:`moments_ref.golden.bands.confirm`."""
    if _engine.is_engine(case):
        return _engine.confirm(case, inputs, got, port_dtype)
    return _bands.confirm(case, inputs, got, port_dtype)


def judges_ill(case):
    """Whether an ill-conditioned row of ``case`` can count as wrong (judged by its neighbourhood): not for the
    engine cases, whose rows flagged ``wide_spread`` by their derivation are reported apart and never wrong."""
    return not _engine.is_engine(case)


def contract_rows(case, inputs, contract=None):
    """``(n,)`` bool: the rows the sweep judges as contract rows: ``contract``, where a profile's conversion
    decided it, else the rows whose float32 neighbourhood reaches the case's contract
    (:func:`moments_ref.golden.bands.contract_reach`)."""
    return _bands.contract_reach(case, inputs) if contract is None else np.asarray(contract, bool)


def wrong_rows(case, bands, ill, got):
    """``(n,)`` bool: rows with an output outside its interval (NaN counts).

    Ill-conditioned rows are judged too, by their neighbourhood: their band is the uncapped
    span of the legitimate evaluations (the float32 reference and the float64 values over the
    float32 neighbourhood of the inputs, :mod:`moments_ref.golden.bands`) widened by the margin,
    and a row flagged there counts as wrong only when :func:`confirm` finds the port's
    output outside every neighbour's exact value (mpmath) and every legitimate evaluation.
    """
    n = len(ill)
    bad = np.zeros(n, bool)
    for o, (lo, hi) in bands.items():
        g = np.asarray(got[o], np.float64).reshape(lo.shape)
        with np.errstate(invalid="ignore", over="ignore"):  # a band wider than the largest float: unbounded
            out = ~((g >= lo) & (g <= hi))
            bad |= (out & np.isfinite(hi - lo)).reshape(n, -1).any(axis=1)
    return bad


def flagged_rows(case, inputs, bands, ill, got, gated=None, port_dtype="float32", contract=None):
    """``(n,)`` bool: the rows the sweep flags (then confirms).

    A ``gated`` row (default: every row) is flagged where an output lies outside its interval (:func:`wrong_rows`),
    an ill-conditioned one only where the case judges its ill rows (:func:`judges_ill`: not the engine cases).
    A flagged row of a case with a band model of its own evaluations (not the codes, engine or bilinear cases)
    is judged again by its band over the whole neighbourhood :func:`confirm` values exactly
    (:func:`moments_ref.golden.bands.legitimate_interval` with ``full``, ``contract`` as for the chunk): a row
    whose exact values spread beyond the cap there is ill-conditioned and judged by that wider band, so a flag
    that the confirmation's own neighbourhood explains is no flag. The full band only widens the default one,
    so computing it on the flagged rows gives the verdicts of computing it on every row.
    Integer outputs: a row whose codes are not its band's single codes is flagged unless the goldens' tie rule
    (:func:`moments_ref.golden.bands.tie_accepted`, per component for the encoders) accepts every code; the
    same function :func:`confirm` applies.
    """
    judged = judges_ill(case) | ~np.asarray(ill, bool)
    if gated is not None:
        judged &= np.asarray(gated, bool)
    sub = lambda d, rows: {k: np.asarray(v)[rows] for k, v in d.items()}  # noqa: E731
    if not case.integer_output:
        flagged = wrong_rows(case, bands, ill, got) & judged
        if flagged.any() and not (case.deriver is not None or _engine.is_engine(case)):
            look = np.flatnonzero(flagged)
            c = None if contract is None else np.asarray(contract, bool)[look]
            full, full_ill = _bands.legitimate_interval(case, sub(inputs, look), port_dtype, contract=c, full=True)
            flagged[look] = wrong_rows(case, full, full_ill, sub(got, look))
        return flagged
    # Codes: every row whose code is not the band's single code goes to the tie rule (vectorised: the exact codes
    # in float64, mpmath only near a boundary), which accepts a code only where it is one of the acceptable codes of
    # that component; the band's interval alone would pass a word between two acceptable words.
    n = len(judged)
    settled = np.ones(n, bool)
    for o, (lo, hi) in bands.items():
        g = np.asarray(got[o], np.float64).reshape(lo.shape)
        settled &= ((g == lo) & (g == hi)).reshape(n, -1).all(axis=1)
    flagged = judged & ~settled
    look = np.flatnonzero(flagged)
    if look.size:
        flagged[look[_bands.tie_accepted(case, sub(inputs, look), sub(got, look))]] = False
    return flagged


#: The cause the sweep prints beside a confirmed row on which the port returns a printed formulation's value.
PRINTED_CAUSE = ("the papers' printed formulation (the slides' code or the algorithm as printed, in float32 on this "
                 "input) returns this value too: it cancels on this row, a hazard of the formulation, not a slip of "
                 "the port; a correct port must not return it (the verdict stands): " + _PRINTED_ADVICE)


def printed_rows(case, inputs, got, bands, port_dtype="float32"):
    """``(n,)`` bool: the rows on which a float32 port returns the value of one of the papers' printed formulations.

    Applied to the rows mpmath confirmed wrong, it says which of them are the printed formulation's own
    cancellation (docs/sweep.md, "Printed formulations that cancel"): the goldens' rule for their
    ``printed_hazard`` rows (:func:`moments_ref.golden.diagnosis.hazard_groups`): within the row's tolerance
    (half its band) of the formulation's value, or, where the formulation has no value (NaN), NaN or an end of
    the output's range (what ``saturate`` or ``clamp`` make of it). The formulations: for an engine case
    :func:`moments_ref.sweep.engine.printed_values`, else the case's ``spread_hook.printed`` (Algorithms 1 and
    3); none for other cases or a float64 port.
    """
    n = len(np.asarray(next(iter(inputs.values()))))
    out = np.zeros(n, bool)
    if n == 0 or np.dtype(port_dtype) != np.float32 or len(case.outputs) != 1 or case.integer_output:
        return out
    if _engine.is_engine(case):
        values = _engine.printed_values(case, inputs)
    else:
        hook = getattr(case.spread_hook, "printed", None)
        with np.errstate(all="ignore"):
            values = [] if hook is None else [v[0] for v in hook({k: np.asarray(inputs[k]) for k in case.inputs},
                                                                   np.dtype(np.float32))]
    o = case.outputs[0]
    g = np.asarray(got[o], np.float64).reshape(n, -1)[:, 0]
    lo, hi = (np.asarray(x, np.float64).reshape(n, -1)[:, 0] for x in bands[o])
    ends = np.asarray(case.value_range or (0, 1), np.float64)
    with np.errstate(invalid="ignore"):
        for h in values:
            h = np.asarray(h, np.float64).reshape(n, -1)[:, 0]
            none = ~np.isfinite(h)
            out |= (~none & (np.abs(g - h) <= (hi - lo) / 2)) | (none & (~np.isfinite(g) | np.isin(g, ends)))
    return out


#: The cause the sweep prints beside a confirmed row whose value lies in the printed formulation's rounding envelope.
ENVELOPE_CAUSE = ("the slides' code, with each operation rounded one ulp either way as another arrangement of it (a "
                  "compiler's reassociation, a reciprocal for a quotient) may round it, spans this value: on this row "
                  "the formulation, not the input, is ill-conditioned, and the band does not hold those arrangements "
                  "yet (docs/sweep.md, \"Known gap\"). For a port of the slides' code the row may be a wrong verdict; "
                  "any port's deviation here is no larger than that code's own rounding. The verdict stands")


def envelope_rows(case, inputs, got, port_dtype="float32"):
    """``(n,)`` bool: the rows on which a float32 port's value lies within the rounding envelope of the slides' code.

    The envelope (:func:`moments_ref.golden.paper.slides_envelope`, widened by the confirmation's margin) spans the
    code as written and 256 arrangements with each operation's result one float32 ulp up, down or unchanged, on
    the port's own input (an engine case's bias inside applied). Applied to the confirmed rows that are not a
    printed formulation's own value (:func:`printed_rows`), it tells the known gap of the tolerance model from a
    port's deviation. An arrangement counts only within the band's cap of this package's float64 value on that
    input (the band model's rule: one that cancels beyond it explains nothing). Algorithm 1's cases only (the
    engine cases of Algorithm 1, ``shadow_intensity-*``).
    """
    n = len(np.asarray(next(iter(inputs.values()))))
    out = np.zeros(n, bool)
    if n == 0 or np.dtype(port_dtype) != np.float32:
        return out
    span = _engine.rounding_envelope(case, inputs) if _engine.is_engine(case) else _moment_envelope(case, inputs)
    if span is None:
        return out
    m = _engine.MARGIN_ULPS * float(np.finfo(np.float32).eps)
    g = np.asarray(got[case.outputs[0]], np.float64).reshape(n)
    with np.errstate(invalid="ignore"):
        return (g >= span[0] - m) & (g <= span[1] + m)


def _moment_envelope(case, inputs):
    """:func:`envelope_rows`' envelope for ``shadow_intensity-*`` (the moments as given, the cap about this package's
    float64 bound), None for other cases."""
    if not (case.name.startswith("shadow_intensity-") and getattr(case.spread_hook, "printed", None) is not None):
        return None
    from ..golden.paper import slides_envelope
    from ..msm import shadow_intensity

    bound = "upper" if "-upper" in case.name else "lower"
    ref = shadow_intensity(np.asarray(inputs["b"], np.float64), np.asarray(inputs["zf"], np.float64), bound)
    return slides_envelope(inputs["b"], inputs["zf"], bound, ref=ref, cap=_bands.CAP)


def named_rows(case, inputs, got, bands, port_dtype="float32"):
    """``(printed, envelope)``, ``(n,)`` bool each, of confirmed rows: the printed formulation's own value
    (:func:`printed_rows`), else within the slides' code's rounding envelope (:func:`envelope_rows`)."""
    printed = printed_rows(case, inputs, got, bands, port_dtype)
    envelope = np.zeros_like(printed)
    rest = np.flatnonzero(~printed)
    if rest.size:
        pick = lambda d: {k: np.asarray(v)[rest] for k, v in d.items()}  # noqa: E731
        envelope[rest] = envelope_rows(case, pick(inputs), pick(got), port_dtype)
    return printed, envelope
