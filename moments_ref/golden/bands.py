"""The band of a row: the interval spanned by the legitimate evaluations of its equation.

One tolerance model for the goldens (:func:`moments_ref.golden.spread.derive`),
``verify``, ``oracle.check``, ``conformance`` and the sweep. For a row with inputs x
and expected value e (the mpmath twin, else the float64 reference), the
**legitimate evaluations** are

* the reference in the port's precision and in float64 on x;
* the same on the float32 neighbourhood of x: x scaled jointly by ``1 ± PERTURB_ULPS``
  ulps, and component-wise by ``1 ± INDEPENDENT_ULPS`` ulp with alternating signs (rows
  without exactly equal inputs). In the port's precision these stand for operations a few
  ulps off (GLSL/HLSL division and square root, fma, reassociated sums); in float64 they
  stand for the exact value over the neighbourhood (item 2 of the model: where the exact
  value moves under 1-ulp changes of the input, the band covers where it moves);
* the papers' printed formulations and the shipped plain-Cholesky evaluation with and
  without fma (the case's ``spread_hook``), on contract rows, **where their error stays
  within the cap** below. Where a printed formula cancels beyond the cap, or has no value
  (NaN: Algorithm 1's pivot ξ4 rounded to 0 in float32 without fma), it does not widen the
  band; the row is flagged ``printed_hazard`` (a porter who copied that formula fails there,
  and is told why).

The band is ``[lo − m, hi + m]`` with ``lo``, ``hi`` the least and largest of e and the
legitimate evaluations, and the **margin** ``m`` a per-case constant, not a multiple of
the row's deviation: ``MARGIN_NOISE`` times the case's rounding noise (the 90th
percentile of the deviations over the case's random rows) and at least ``FLOOR_ULPS``
ulps of max(|e|, floor scale) in the port's precision. For an output with a bounded
range (intensities, visibility) the band never reaches farther than ``CAP`` times the
range from e. A row whose legitimate evaluations (without the formulations) spread
beyond that is **ill-conditioned**: its band is the whole interval (the exact values over
the neighbourhood included, so a correct port never fails it), it is flagged
``wide_spread`` and reported apart, and it never counts as a pass of the port.

:func:`confirm` decides a flagged row with mpmath (:mod:`moments_ref.precise`): a row is
wrong only when the port's output lies outside every neighbour's exact value and every
legitimate evaluation.
"""

from __future__ import annotations

import numpy as np

from .._arrays import InputError
from .cases import case_table, evaluate_reference, expected_outputs
from .texel_codes import TIE_BAND  # noqa: F401 - one constant (re-exported): the codes' tie band
from .units import ulp

__all__ = ["legitimate_interval", "confirm", "confirm_points", "neighbourhood_interval", "evaluations", "case_noise",
           "tie_codes", "contract_rows", "contract_reach", "on_tie", "tie_accepted", "TIE_NUDGE", "TIE_BAND", "CAP", "MARGIN_NOISE",
           "FLOOR_ULPS", "PERTURB_ULPS", "INDEPENDENT_ULPS", "NEIGHBOURS", "STRUCTURED"]

#: Joint scaling of the float inputs, in ulps of the port's precision.
PERTURB_ULPS = 3
#: Component-wise perturbation: one ulp, the rounding of one operation on an input.
INDEPENDENT_ULPS = 1
#: The margin's floor, in ulps of max(|value|, floor scale) in the port's precision: a chain of a few
#: operations each a few ulps off (a division 3 ulps high feeding a multiply-add) reaches it.
FLOOR_ULPS = 8
#: The margin: at least this many times the case's rounding noise (a constant per case and precision) ...
MARGIN_NOISE = 4.0
#: ... and this many times the width of the row's interval: a port's own operation order is another point of
#: the same neighbourhood, and its forward error reaches a few times what 1–3 ulps of the input give.
MARGIN_WIDTH = 3.0
#: The chained cases (``endtoend.*``, ``kernels.*``: a filter, a quantizer and Algorithm 3 in one shader). Their
#: ``spread_hook`` is the chain as a GPU and its compiler evaluate it (:mod:`moments_ref.golden.gpuspread`: the sums
#: over samples, taps and block in every order, every ``a·b + c`` fused or not, log and exp a few ulps off), so they
#: take the same margin as every case; their hooks are legitimate GPU evaluations, not printed formulas, and widen
#: the band without the cap (beyond it the row is ill-conditioned).
CHAINED = ("endtoend.", "kernels.")
#: No band of a bounded output reaches farther than this fraction of its range from the expected value.
CAP = 0.02
#: Random points of the float32 neighbourhood :func:`confirm` evaluates with mpmath, per row.
NEIGHBOURS = 12


def _float_keys(case, inputs):
    return [k for k in inputs if k not in case.integer_inputs]


def _scaled(case, inputs, factor):
    """Float inputs times ``factor`` (a number, or per input an array); values in [−1, 1] stay inside."""
    out = {}
    for k, v in inputs.items():
        if k in case.integer_inputs:
            out[k] = v
            continue
        v = np.asarray(v, np.float64)
        f = factor[k] if isinstance(factor, dict) else factor
        out[k] = np.where((np.abs(v * f) > 1) & (np.abs(v) <= 1), v, v * f)
    return out


def _componentwise(case, inputs, eps, sign, free):
    """Per-component factors ``1 ± eps`` (alternating signs) on the ``free`` rows."""
    factors, offset = {}, 0
    for k in _float_keys(case, inputs):
        v = np.asarray(inputs[k])
        m = int(np.prod(v.shape[1:], dtype=np.int64))
        s = np.where((np.arange(m) + offset) % 2 == 0, sign, -sign).reshape(v.shape[1:])
        offset += m
        factors[k] = 1 + eps * s[None] * free.reshape((-1,) + (1,) * (v.ndim - 1))
    return factors


def equal_inputs(case, inputs, n):
    """Rows where two nonzero float inputs are exactly equal (zf = y1, y1 = y2, ...): perturbed only jointly."""
    cols = [np.asarray(inputs[k], np.float64).reshape(n, -1) for k in _float_keys(case, inputs)]
    if not cols:
        return np.zeros(n, bool)
    x = np.sort(np.abs(np.concatenate(cols, axis=1)), axis=1)
    if x.shape[1] < 2:
        return np.zeros(n, bool)
    return np.any((np.diff(x, axis=1) == 0) & (x[:, 1:] != 0) & (x[:, 1:] != 1), axis=1)


def _neighbours(case, inputs, dt, free):
    """The float32 (``dt``) neighbourhood of the rows: jointly scaled and component-wise perturbed inputs."""
    eps = float(np.finfo(dt).eps)
    if not (case.perturb and _float_keys(case, inputs)):
        return []
    pts = [_scaled(case, inputs, 1 + PERTURB_ULPS * eps), _scaled(case, inputs, 1 - PERTURB_ULPS * eps)]
    if free.any():
        pts += [_scaled(case, inputs, _componentwise(case, inputs, INDEPENDENT_ULPS * eps, s, free)) for s in (1, -1)]
    return pts


def evaluations(case, inputs, dt, free=None, full=False):
    """Legitimate evaluations of the rows: ``(core, formulations)``, lists of output tuples.

    ``core``: the reference in ``dt`` and float64 on the rows and their neighbourhood; with ``full``, also
    the float64 reference on every point :func:`confirm` values exactly (:func:`confirm_points`), the exact
    value's stand-in there. ``formulations``: the case's other formulations (``spread_hook``) in ``dt``; with
    ``full``, also its ``full`` attribute's where it has one (``e2e-msm64``: the chain on every texel the row's
    code ties admit, :func:`moments_ref.golden.gpuspread.msm_spread`).
    """
    n = len(next(iter(inputs.values())))
    if free is None:
        free = ~equal_inputs(case, inputs, n) if case.row_inputs else np.zeros(n, bool)
    core = [evaluate_reference(case, inputs, dt), evaluate_reference(case, inputs, np.float64)]
    if full and case.perturb:
        for p in confirm_points(case, inputs)[1:]:
            try:
                core.append(evaluate_reference(case, p, np.float64))
            except InputError:  # a neighbour outside the function's domain: none
                pass
    for p in _neighbours(case, inputs, dt, free):
        # The exact value over the neighbourhood: float64 on the neighbour's float32 values.
        p32 = {k: (v if k in case.integer_inputs else np.asarray(v).astype(dt)) for k, v in p.items()}
        for point, prec in ((p, dt), (p32, np.float64)):
            try:
                core.append(evaluate_reference(case, point, prec))
            except InputError:  # a neighbour outside the function's domain (y1 > y2 after rounding): none
                pass
    hooks = list(case.spread_hook(inputs, np.dtype(dt))) if case.spread_hook is not None else []
    if full and getattr(case.spread_hook, "full", None) is not None:  # the hook's own neighbourhood (tie texels)
        hooks += list(case.spread_hook.full(inputs, np.dtype(dt)))
    return core, hooks


def _rows_shape(mask, like):
    return mask.reshape((len(mask),) + (1,) * (like.ndim - 1))


def _span(e, values):
    """Least and largest of ``e`` and the finite ``values``; ``bad``: where some value is NaN/infinite."""
    lo, hi, bad = e.copy(), e.copy(), np.zeros(e.shape, bool)
    for v in values:
        v = np.asarray(v, np.float64)
        fin = np.isfinite(v)
        bad |= ~fin
        lo = np.where(fin, np.minimum(lo, v), lo)
        hi = np.where(fin, np.maximum(hi, v), hi)
    return lo, hi, bad


def _margin(case, e, dt, noise, width):
    scale = np.broadcast_to(np.asarray(case.floor_scale, np.float64), e.shape)
    if case.metric == "ulps":
        return np.maximum(FLOOR_ULPS * ulp(e, dt), MARGIN_WIDTH * width)
    return np.maximum.reduce([np.broadcast_to(MARGIN_NOISE * noise, e.shape), MARGIN_WIDTH * width,
                              FLOOR_ULPS * ulp(np.maximum(np.abs(e), scale), dt)])


def contract_rows(case, inputs, n=None):
    """``(n,)`` bool: the rows inside the case's contract (:mod:`moments_ref.golden.contract`); all True without one."""
    n = len(next(iter(inputs.values()))) if n is None else n
    if case.contract is None:
        return np.ones(n, bool)
    from .contract import rows_inside

    return np.asarray(rows_inside(case.contract, inputs), bool)


def contract_reach(case, inputs):
    """``(n,)`` bool: rows inside the case's contract at the row or at a point of its float32 neighbourhood.

    The neighbourhood is that of the legitimate evaluations (:func:`evaluations`: the float inputs
    scaled jointly by ``1 ± PERTURB_ULPS`` ulps and component-wise by ``1 ± INDEPENDENT_ULPS`` ulp,
    rounded to float32). A row the contract misses only by the rounding of its inputs (biased
    moments that float32 storage left just outside the moment space, B(b) indefinite by 10⁻⁸) is an
    input a port receives from a contract texel: the papers' formulations are legitimate there too.
    """
    inputs = {k: inputs[k] for k in case.inputs}
    n = len(next(iter(inputs.values())))
    inside = contract_rows(case, inputs, n)
    if case.contract is None or inside.all():
        return inside
    # Row by row: only the rows outside the contract look at their neighbours (in a sweep's chunk, a few in 10^4).
    rows = np.flatnonzero(~inside)
    inputs, m = {k: np.asarray(v)[rows] for k, v in inputs.items()}, rows.size
    free = ~equal_inputs(case, inputs, m) if case.row_inputs else np.zeros(m, bool)
    reach = np.zeros(m, bool)
    for p in _neighbours(case, inputs, np.float32, free):
        p32 = {k: (v if k in case.integer_inputs else np.asarray(v).astype(np.float32)) for k, v in p.items()}
        reach |= contract_rows(case, p32, m)
    inside[rows] = reach
    return inside


def interval_parts(case, dt, expected, contract, noise, core, hooks):
    """Per output ``(lo, hi, ill, hazard, bad)`` of the band (module docstring), from the evaluations
    ``core`` and ``hooks`` (:func:`evaluations`); ``noise`` per output."""
    out = []
    for i, e in enumerate(expected):
        e = np.asarray(e, np.float64)
        lo, hi, bad = _span(e, [v[i] for v in core])
        ill = np.zeros(e.shape, bool)
        hazard = np.zeros(e.shape, bool)
        c = _rows_shape(contract, e)
        if case.value_range is not None:
            cap = CAP * (case.value_range[1] - case.value_range[0])
            ill = (e - lo > cap) | (hi - e > cap)
            chained = case.function.startswith(CHAINED)  # its hooks are the GPU's own chains, not printed formulas
            for v in hooks:
                h = np.asarray(v[i], np.float64)
                fine = np.isfinite(h) & c & ((np.abs(h - e) <= cap) | chained)
                # beyond the cap, or no value at all (NaN: a pivot rounded to 0) where the exact value is finite
                hazard |= c & ~fine & (np.isfinite(h) | (np.isfinite(e) & (not chained)))
                lo, hi = np.where(fine, np.minimum(lo, h), lo), np.where(fine, np.maximum(hi, h), hi)
            m = _margin(case, e, dt, noise[i], hi - lo)
            if chained:  # the GPU's own chains (every order and contraction) span beyond the cap: ill
                ill |= (e - (lo - m) > cap) | ((hi + m) - e > cap)
            lo = np.where(ill, lo - m, np.maximum(lo - m, e - cap))
            hi = np.where(ill, hi + m, np.minimum(hi + m, e + cap))
        else:
            for v in hooks:
                h = np.asarray(v[i], np.float64)
                fine = np.isfinite(h) & c
                lo, hi = np.where(fine, np.minimum(lo, h), lo), np.where(fine, np.maximum(hi, h), hi)
            m = _margin(case, e, dt, noise[i], hi - lo)
            lo, hi = lo - m, hi + m
        lo, hi = np.where(bad, -np.inf, lo), np.where(bad, np.inf, hi)
        out.append((lo, hi, ill, hazard, bad))
    return out


def noise_of(case, dt, expected, core, random_rows):
    """Per output, the case's rounding noise: the 90th percentile of the core evaluations' deviations over
    ``random_rows``."""
    out = []
    for i, e in enumerate(expected):
        e = np.asarray(e, np.float64)
        dev = np.zeros(e.shape)
        for v in core:
            with np.errstate(invalid="ignore"):
                dev = np.fmax(dev, np.abs(np.asarray(v[i], np.float64) - e))
        d = dev[random_rows] if random_rows.any() else dev
        d = d[np.isfinite(d)]
        out.append(float(np.quantile(d, 0.9)) if d.size else 0.0)
    return tuple(out)


#: Rows whose meaning rests on exact relations between inputs: perturbed only jointly.
STRUCTURED = ("support_point", "fold", "code_boundary", "singular_hankel")
_NOISE = {}


def case_noise(case, dt):
    """The case's rounding noise per output in precision ``dt`` (measured on its golden rows, cached per case
    object)."""
    key = (case.name, id(case), str(np.dtype(dt)))
    if key not in _NOISE:
        inputs, category, _, flags = case_table(case)
        inputs = {k: inputs[k] for k in case.inputs}
        n = len(category)
        free = np.array([not any(f in STRUCTURED for f in fl) for fl in flags], bool)
        free = free & ~equal_inputs(case, inputs, n) if case.row_inputs else np.zeros(n, bool)
        expected = expected_outputs(case, inputs)
        core, _ = evaluations(case, inputs, np.dtype(dt), free)
        _NOISE[key] = (case, noise_of(case, np.dtype(dt), expected, core, np.asarray(category) == "random"))
    return _NOISE[key][1]


def legitimate_interval(case, inputs, port_dtype="float32", noise=None, contract=None, full=False):
    """Per row and output, the band a correct port's value lies in, and the ill-conditioned rows.

    Parameters
    ----------
    case : moments_ref.golden.cases.Case
    inputs : dict name -> (n, ...) array
        The rows as the port receives them (the case's dtypes).
    port_dtype : {"float32", "float64"}
    noise : tuple of float, optional
        The case's rounding noise per output (default: measured on the case's golden rows).
    contract : (n,) bool, optional
        The rows inside the case's contract, where they were decided elsewhere (under a profile, on the
        papers' inputs: :func:`moments_ref.golden.conventions.contract_mask`); default: from ``inputs``.
    full : bool
        Also the float64 reference on every point of the float32 neighbourhood :func:`confirm` values
        exactly (:func:`confirm_points`: the joint ``1 ± k`` ulp scalings and the :data:`NEIGHBOURS`
        component-wise points), so that a row whose exact values spread beyond the cap over them is
        ill-conditioned and its band holds them. A band only widens with ``full`` (its points are a
        superset), so the sweep computes it on the rows the default band flags
        (:func:`moments_ref.sweep.judge.flagged_rows`): the same verdicts as on every row, at the
        speed of the default.

    Returns
    -------
    bands : dict output -> (lo, hi)
        float64 arrays of the output's shape (module docstring). Integer outputs: the least and
        largest acceptable code (the goldens' rounding-tie rule). Cases with their own deriver
        (engine, bilinear): expected ± their tolerance.
    ill_conditioned : (n,) bool
    """
    n = len(next(iter(inputs.values())))
    dt = np.dtype(port_dtype)
    if case.integer_output or case.deriver is not None:
        return _derived_bands(case, inputs, str(dt), n)
    inputs = {k: inputs[k] for k in case.inputs}
    # The centre is the float64 reference (no mpmath for millions of rows); the band holds the mpmath value
    # wherever the float64 reference is within the margin of it, which the goldens check row by row.
    expected = [np.asarray(x, np.float64) for x in evaluate_reference(case, inputs, np.float64)]
    noise = case_noise(case, dt) if noise is None else noise
    core, hooks = evaluations(case, inputs, dt, full=full)
    contract = contract_rows(case, inputs, n) if contract is None else np.asarray(contract, bool)
    parts = interval_parts(case, dt, expected, contract, noise, core, hooks)
    bands, ill = {}, np.zeros(n, bool)
    for o, (lo, hi, wide, _, _) in zip(case.outputs, parts):
        bands[o] = (lo, hi)
        ill |= wide.reshape(n, -1).any(axis=1)
    return bands, ill


def _derived_bands(case, inputs, dt, n):
    """Bands of cases whose arrays come from their own code (codes, engine and bilinear derivers)."""
    labels = (np.full(n, "random"), [""] * n, [()] * n)
    if case.deriver is not None:
        arrays = case.deriver(case, inputs, *labels)
    else:  # codes: the goldens' tie rule (the truth's, the reference's in float32 and float64, nudged)
        inputs = {k: inputs[k] for k in case.inputs}
        codes = [expected_outputs(case, inputs)] + tie_codes(case, inputs)
        arrays = {"flags": np.full(n, "")}
        for i, o in enumerate(case.outputs):
            arrays[o] = np.asarray(codes[0][i])
            arrays[f"{o}_acceptable"] = np.stack([np.asarray(c[i]) for c in codes], axis=1)
    bands = {}
    for o in case.outputs:
        e = np.asarray(arrays[o], np.float64)
        if case.integer_output:
            a = np.asarray(arrays[f"{o}_acceptable"], np.float64)
            bands[o] = (np.minimum(e, a.min(axis=1)), np.maximum(e, a.max(axis=1)))
        else:
            t = np.asarray(arrays[f"{o}_tolerance_{dt}"], np.float64)
            bands[o] = (e - t, e + t)
    flags = np.asarray(arrays["flags"])
    return bands, np.array(["wide_spread" in str(f).split(",") for f in flags], bool)


#: The goldens' rounding-tie nudge (:mod:`moments_ref.golden.spread`): inputs scaled by 1 ± 8 float32 eps.
TIE_NUDGE = 8 * float(np.finfo(np.float32).eps)


def tie_codes(case, inputs):
    """The codes the goldens' tie rule accepts besides the truth's: the reference in float32 and float64, and in
    float64 on the inputs scaled by ``1 ± TIE_NUDGE`` (values in [−1, 1] stay inside)."""
    out = [evaluate_reference(case, inputs, np.float32), evaluate_reference(case, inputs, np.float64)]
    for f in (1 + TIE_NUDGE, 1 - TIE_NUDGE):
        out.append(evaluate_reference(case, _scaled(case, inputs, f), np.float64))
    return out


def on_tie(case, inputs):
    """``(n,)`` bool: rows whose exact scaled value lies within :data:`TIE_BAND` of a rounding boundary (the
    case's ``margin``, :mod:`moments_ref.golden.texel_truth` in mpmath); all False for a case without one."""
    n = len(next(iter(inputs.values())))
    if case.margin is None or n == 0:
        return np.zeros(n, bool)
    return np.asarray(case.margin(**{k: inputs[k] for k in case.inputs}), np.float64).reshape(n) <= TIE_BAND


def tie_accepted(case, inputs, got, codes=None):
    """``(n,)`` bool: rows whose every integer output the goldens' tie rule accepts.

    A code is accepted where it equals the truth's code or one of :func:`tie_codes`, compared per component (as the
    goldens compare codes), or lies on a rounding tie. The rule is **per component** where the case gives its
    ``tie_neighbours`` (the encoders, :mod:`moments_ref.golden.texel_codes`): a component may hold the code across
    its boundary only where *its own* exact scaled value lies within its tie band of it (derived from the formula
    for the non-linear texels, :func:`moments_ref.golden.texel_codes.pack64_tie_band`; :data:`TIE_BAND` for the
    affine encoders); a component one code
    off on a row where another component is on a tie is wrong. A case without them keeps the per-row rule: on a row
    whose nearest component is on a tie (:func:`on_tie`) every code may be one off. One definition for
    :func:`confirm` and the sweep's flagging (:func:`moments_ref.sweep.judge.flagged_rows`). ``codes``: the truth's
    codes first, then any others already computed (default: the truth and :func:`tie_codes`).
    """
    inputs = {k: inputs[k] for k in case.inputs}
    n = len(next(iter(inputs.values())))
    if codes is None:
        codes = list(_exact(case, inputs))  # one tuple, or lo and hi from a confirm_truth
    codes = list(codes) + tie_codes(case, inputs)
    per_component = case.tie_neighbours is not None
    if per_component:
        codes += list(case.tie_neighbours(**inputs))
    near = np.zeros(n, bool) if per_component else on_tie(case, inputs)
    ok_rows = np.ones(n, bool)
    for i, o in enumerate(case.outputs):
        g = np.asarray(got[o], np.float64)
        ok = np.zeros(g.shape, bool)
        for v in codes:
            ok |= g == np.asarray(v[i], np.float64)
        t = near.reshape((n,) + (1,) * (g.ndim - 1))
        ok |= t & (np.abs(g - np.asarray(codes[0][i], np.float64)) <= 1)
        ok_rows &= ok.reshape(n, -1).all(axis=1)
    return ok_rows


def _exact(case, point):
    """The exact values at ``point``: a list of output tuples (one; two, lo and hi, from a ``confirm_truth``)."""
    as64 = {k: (v if k in case.integer_inputs else np.asarray(v, np.float64)) for k, v in point.items()}
    if case.confirm_truth is not None:
        pairs = case.confirm_truth(**as64)
        return [tuple(p[0] for p in pairs), tuple(p[1] for p in pairs)]
    if case.truth is None:
        return [evaluate_reference(case, point, np.float64)]
    return [case.truth(**as64)]


def _within_cap(case, hook, exact):
    """A formulation's outputs, NaN where it errs beyond the cap (a cancelling printed formula explains nothing).

    ``exact``: the row's exact output tuples (one; lo and hi from a ``confirm_truth``), the cap measured from the
    nearest."""
    if case.value_range is None:
        return hook
    cap = CAP * (case.value_range[1] - case.value_range[0])
    out = []
    for i, h in enumerate(hook):
        h = np.asarray(h, np.float64)
        with np.errstate(invalid="ignore"):
            err = np.min([np.abs(h - np.asarray(e[i], np.float64)) for e in exact], axis=0)
            out.append(np.where(err <= cap, h, np.nan))
    return tuple(out)


def confirm_points(case, inputs, seed=12345):
    """The float32 neighbourhood :func:`confirm` values exactly: a list of input dicts, the rows first.

    The rows; their float inputs scaled jointly by ``1 ± k`` float32 ulps (k = 1 … PERTURB_ULPS); and
    :data:`NEIGHBOURS` points whose float inputs are scaled per component by ``1 + j·ulp``, j drawn once from
    {−PERTURB_ULPS … PERTURB_ULPS} per point and component (``seed``): the same points for every row, so a
    row's neighbourhood does not depend on the other rows of a call. Each is rounded to the inputs' dtype (a
    neighbour is an input the port could have received).
    """
    rng = np.random.default_rng(seed)
    eps = float(np.finfo(np.float32).eps)

    def rounded(p):
        return {k: (v if k in case.integer_inputs else np.asarray(v).astype(np.asarray(inputs[k]).dtype))
                for k, v in p.items()}

    pts = [inputs] + [rounded(_scaled(case, inputs, 1 + s * k * eps)) for k in range(1, PERTURB_ULPS + 1)
                      for s in (1, -1)]
    for _ in range(NEIGHBOURS):
        pts.append(rounded(_scaled(case, inputs, {
            k: 1 + eps * rng.integers(-PERTURB_ULPS, PERTURB_ULPS + 1, np.shape(inputs[k])[1:])[None]
            for k in _float_keys(case, inputs)})))
    return pts


def _exact_values(case, inputs, seed=12345):
    """The exact values (:func:`_exact`) on the rows and on their float32 neighbourhood (:func:`confirm_points`)."""
    values = []
    for p in confirm_points(case, inputs, seed):
        try:
            values.extend(_exact(case, p))
        except InputError:  # a neighbour outside the function's domain
            pass
    return values


def neighbourhood_interval(case, inputs, seed=12345):
    """Per output ``(lo, hi)``: the least and largest exact value over the rows' float32 neighbourhood.

    The points of :func:`confirm` (the row, its float inputs scaled by ``1 ± k`` float32 ulps, and
    :data:`NEIGHBOURS` random points within PERTURB_ULPS ulps per component), each valued by the case's mpmath
    ``truth`` (:mod:`moments_ref.precise`), else its float64 reference. Meant for the few ill-conditioned rows a
    report shows: where the exact value jumps under 1-ulp changes of the input, this is where it jumps.
    """
    inputs = {k: inputs[k] for k in case.inputs}
    values = _exact_values(case, inputs, seed)
    out = {}
    for i, o in enumerate(case.outputs):
        e = np.asarray(values[0][i], np.float64)
        lo, hi, _ = _span(e, [v[i] for v in values])
        out[o] = (lo, hi)
    return out


def confirm(case, inputs, got, port_dtype="float32", seed=12345):
    """``(n,)`` bool: rows whose ``got`` lies outside every neighbour's exact value and every legitimate evaluation.

    The exact values (the case's mpmath ``truth``, :mod:`moments_ref.precise`) are computed on
    the row, on its float inputs scaled by ``1 ± k`` float32 ulps (k = 1 … PERTURB_ULPS) and on
    :data:`NEIGHBOURS` points whose float inputs differ by at most PERTURB_ULPS float32 ulps per
    component, each rounded to the inputs' dtype (a neighbour is an input the port could have
    received). ``got`` is explained where it lies within the span of those exact values and of
    the legitimate evaluations (formulations only within the cap), widened by ``FLOOR_ULPS``
    ulps of max(|value|, scale) in ``port_dtype``. Integer outputs must equal one of the codes.
    Meant for the few flagged rows of a sweep, not for millions. NaN is never explained.
    """
    n = len(next(iter(inputs.values())))
    if n == 0:
        return np.zeros(0, bool)
    inputs = {k: inputs[k] for k in case.inputs}
    dt = np.dtype(port_dtype)
    values = _exact_values(case, inputs, seed)
    if case.integer_output:  # the codes of the goldens' tie rule, one definition with the sweep's flagging
        return ~tie_accepted(case, inputs, got, values)
    core, hooks = evaluations(case, inputs, dt, full=True)  # every evaluation a band may hold (its full one)
    row = values[:2] if case.confirm_truth is not None else values[:1]  # the row's own exact values
    values += core + [_within_cap(case, h, row) for h in hooks]
    wrong = np.zeros(n, bool)
    for i, o in enumerate(case.outputs):
        g = np.asarray(got[o], np.float64)
        e = np.asarray(values[0][i], np.float64)
        lo, hi, _ = _span(e, [v[i] for v in values])
        scale = np.broadcast_to(np.asarray(case.floor_scale, np.float64), e.shape)
        f = FLOOR_ULPS * ulp(np.maximum(np.abs(e), scale), dt)
        with np.errstate(invalid="ignore"):
            ok = (g >= lo - f) & (g <= hi + f)
        wrong |= ~np.asarray(ok).reshape(n, -1).all(axis=1)
    return wrong
