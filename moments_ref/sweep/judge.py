"""The sweep's verdict on a row: the golden spread model, vectorised, and mpmath confirmation.

Everything the sweep knows about right and wrong is here, in two functions:

* :func:`legitimate_interval` — per row and output, the interval ``(lo, hi)`` a correct
  port may return, and the rows that are ill-conditioned. It is the rule of
  :mod:`moments_ref.golden.spread` (the goldens' tolerances) evaluated for millions of
  rows: the expected value is the float64 reference; the legitimate evaluations are
  the reference in the port's precision and in float64, on inputs scaled jointly by
  ``1 ± PERTURB_ULPS`` ulps and component-wise by ``1 ± INDEPENDENT_ULPS`` ulp (rows
  without exactly equal inputs), and the case's other formulations (``spread_hook``,
  the papers' code) on contract rows; the tolerance is ``SAFETY`` times their largest
  deviation from the expected value (at least the case's rounding noise, measured on
  the golden case's random rows), never below ``FLOOR_ULPS`` ulps. Rows outside the
  case's contract (robustness rows) get an infinite interval, as ungated golden rows.
  Integer outputs (texel encoders) accept the codes of the reference in float32 and
  float64 and on inputs nudged by 8 float32 ulps and by the goldens' rounding-tie band
  (``TIE_BAND``: either code of a tie); for a packed word (pack32) the interval spans the
  codes seen, lenient only on tie rows; the
  exact codes (:mod:`moments_ref.golden.texel_truth`) decide in :func:`confirm`.
* :func:`confirm` — a flagged row counts as wrong only when every exact value
  (:mod:`moments_ref.precise`, the case's ``truth``) over the float32 neighbourhood of its
  inputs is farther from the port's output than the tolerance floor. A flag that
  mpmath does not confirm is a defect of the tolerance model, never the port's.

The golden code's model is used as is; a rewrite of that model replaces the bodies of
these two functions, not their callers.

References
----------
.. [1] Peters and Klein 2015: Christoph Peters and Reinhard Klein. 2015. *Moment Shadow Mapping*.
       In Proceedings of the 19th ACM SIGGRAPH Symposium on Interactive 3D Graphics and Games (i3D
       '15). ACM, 7–14. https://doi.org/10.1145/2699276.2699277
.. [2] HPG17: Christoph Peters. 2017. *Non-Linearly Quantized Moment Shadow Maps*. In Proceedings
       of High Performance Graphics (HPG '17). ACM. The non-linear quantization Φ, Ψ4, Algorithms
       1–3, the texel formats and the compute shader of §4.1.
"""

from __future__ import annotations

import numpy as np

from ..golden.cases import case_table, evaluate_reference
from ..golden.contract import rows_inside
from ..golden.spread import FLOOR_ULPS, INDEPENDENT_ULPS, PERTURB_ULPS, SAFETY, TIE_BAND, ceil2, ulp

__all__ = ["legitimate_interval", "confirm", "WIDE", "NEIGHBOURS"]

#: A band of a bounded output at least this wide marks the row ill-conditioned (golden.spread's rule).
WIDE = 0.1
#: Points of the float32 neighbourhood :func:`confirm` evaluates with mpmath, per row.
NEIGHBOURS = 12
_NUDGE = 8 * float(np.finfo(np.float32).eps)
#: Codes: the goldens' rounding-tie band (golden.spread.TIE_BAND, 64 float32 ulps of the code range) as a
#: relative nudge of the inputs.
_TIE = TIE_BAND


def _float_inputs(case, inputs):
    return [k for k in inputs if k not in case.integer_inputs]


def _scaled(case, inputs, factors):
    """Float inputs times per-input factors (numbers or arrays); values in [−1, 1] stay inside."""
    out = dict(inputs)
    for k in _float_inputs(case, inputs):
        v = np.asarray(inputs[k], np.float64)
        f = factors[k]
        out[k] = np.where((np.abs(v * f) > 1) & (np.abs(v) <= 1), v, v * f)
    return out


def _componentwise(case, inputs, eps, sign, free):
    """Factors ``1 ± eps`` with alternating signs over the components, on the ``free`` rows."""
    factors, offset = {}, 0
    for k in _float_inputs(case, inputs):
        v = np.asarray(inputs[k])
        m = int(np.prod(v.shape[1:], dtype=np.int64))
        s = np.where((np.arange(m) + offset) % 2 == 0, sign, -sign).reshape(v.shape[1:])
        offset += m
        factors[k] = 1 + eps * s[None] * free.reshape((-1,) + (1,) * (v.ndim - 1))
    return factors


def _equal_inputs(case, inputs, n):
    """Rows where two nonzero float inputs are exactly equal (perturbed only jointly)."""
    cols = [np.asarray(inputs[k], np.float64).reshape(n, -1) for k in _float_inputs(case, inputs)]
    x = np.sort(np.abs(np.concatenate(cols, axis=1)), axis=1)
    if x.shape[1] < 2:
        return np.zeros(n, bool)
    return np.any((np.diff(x, axis=1) == 0) & (x[:, 1:] != 0) & (x[:, 1:] != 1), axis=1)


def _contract(case, inputs, n):
    if case.contract is None:
        return np.ones(n, bool)
    return np.asarray(rows_inside(case.contract, inputs), bool)


def _deviations(case, inputs, dt, expected, contract):
    """Per output, the largest deviation of a legitimate evaluation from ``expected``."""
    n = len(contract)
    eps = float(np.finfo(dt).eps)
    found = [evaluate_reference(case, inputs, dt), evaluate_reference(case, inputs, np.float64)]
    if case.perturb and _float_inputs(case, inputs):
        for f in (1 + PERTURB_ULPS * eps, 1 - PERTURB_ULPS * eps):
            found.append(evaluate_reference(case, _scaled(case, inputs, dict.fromkeys(inputs, f)), dt))
        free = ~_equal_inputs(case, inputs, n)
        for sign in (1, -1):
            found.append(evaluate_reference(case, _scaled(case, inputs, _componentwise(
                case, inputs, INDEPENDENT_ULPS * eps, sign, free)), dt))
    found = [(v, False) for v in found]
    if case.spread_hook is not None:
        found += [(v, True) for v in case.spread_hook(inputs, np.dtype(dt))]
    devs = []
    for i, e in enumerate(expected):
        dev = np.zeros(e.shape)
        for v, optional in found:
            with np.errstate(invalid="ignore"):
                d = np.abs(np.asarray(v[i], np.float64) - e)
            if optional:
                d = np.where(contract.reshape((n,) + (1,) * (d.ndim - 1)) & ~np.isnan(d), d, 0.0)
            dev = np.maximum(dev, np.where(np.isnan(d), np.inf, d))
        devs.append(dev)
    return devs


_NOISE = {}


def _noise(case, dt):
    """The case's rounding noise: the 90th percentile of deviations over its golden random rows."""
    key = (case.name, repr(case.kwargs), dt)
    if key not in _NOISE:
        _NOISE[key] = _measure_noise(case, dt)
    return _NOISE[key]


def _measure_noise(case, dt):
    inputs, category, _, _ = case_table(case)
    inputs = {k: inputs[k] for k in case.inputs}
    random_rows = np.asarray(category) == "random"
    n = len(category)
    expected = [np.asarray(x, np.float64) for x in evaluate_reference(case, inputs, np.float64)]
    out = []
    for dev in _deviations(case, inputs, np.dtype(dt), expected, _contract(case, inputs, n)):
        d = dev[random_rows] if random_rows.any() else dev
        d = d[np.isfinite(d)]
        out.append(float(np.quantile(d, 0.9)) if d.size else 0.0)
    return tuple(out)


def _integer_bands(case, inputs, n):
    variants = [evaluate_reference(case, inputs, np.float64), evaluate_reference(case, inputs, np.float32)]
    for f in (1 + _NUDGE, 1 - _NUDGE, 1 + _TIE, 1 - _TIE):
        variants.append(evaluate_reference(case, _scaled(case, inputs, dict.fromkeys(inputs, f)), np.float64))
    bands = {}
    for i, o in enumerate(case.outputs):
        # The exact codes (texel_truth) are too slow for 10^6 rows: confirm() consults them.
        stack = np.stack([np.asarray(v[i], np.float64) for v in variants])
        bands[o] = (stack.min(axis=0), stack.max(axis=0))
    return bands, np.zeros(n, bool)


def legitimate_interval(case, inputs, port_dtype="float32"):
    """Per row, the interval of outputs a correct port may return.

    Parameters
    ----------
    case : moments_ref.golden.Case
    inputs : dict name -> (n, ...) array
        The rows as the port receives them.
    port_dtype : str
        The port's precision (``"float32"`` for a shader).

    Returns
    -------
    bands : dict output -> (lo, hi)
        float64 arrays of the output's shape; ``(−inf, inf)`` on rows outside the contract.
    ill_conditioned : (n,) bool
        Rows whose legitimate evaluations disagree by :data:`WIDE` or more (bounded outputs):
        reported apart, never counted as wrong.
    """
    n = len(next(iter(inputs.values())))
    if case.integer_output:
        return _integer_bands(case, inputs, n)
    dt = np.dtype(port_dtype)
    contract = _contract(case, inputs, n)
    expected = [np.asarray(x, np.float64) for x in evaluate_reference(case, inputs, np.float64)]
    noise = _noise(case, str(dt))
    bands, ill = {}, np.zeros(n, bool)
    for i, (o, e, dev) in enumerate(zip(case.outputs, expected, _deviations(case, inputs, dt, expected, contract))):
        scale = np.broadcast_to(np.asarray(case.floor_scale, np.float64), e.shape)
        if case.metric == "ulps":
            t = np.ceil(np.maximum(SAFETY * dev / ulp(e, dt), FLOOR_ULPS)) * ulp(e, dt)
        else:
            t = ceil2(np.maximum(SAFETY * np.maximum(dev, noise[i]),
                                 FLOOR_ULPS * ulp(np.maximum(np.abs(e), scale), dt)))
        t = np.where(contract.reshape((n,) + (1,) * (e.ndim - 1)), t, np.inf)
        if case.value_range is not None:
            ill |= np.asarray(np.where(np.isfinite(t), t, 0) >= WIDE).reshape(n, -1).any(axis=1)
        bands[o] = (e - t, e + t)
    return bands, ill


def _neighbourhood(case, inputs, rng, k):
    """The row's inputs and ``k`` + 2 points within PERTURB_ULPS float32 ulps of them, component-wise.

    Codes (integer outputs): within the goldens' rounding-tie band instead, 2 TIE_BAND / eps
    float32 ulps, where either code is acceptable (golden.spread).
    """
    eps = float(np.finfo(np.float32).eps)
    ulps = int(round(TIE_BAND / eps)) if case.integer_output else PERTURB_ULPS
    pts = [inputs, _scaled(case, inputs, dict.fromkeys(inputs, 1 + ulps * eps)),
           _scaled(case, inputs, dict.fromkeys(inputs, 1 - ulps * eps))]
    for _ in range(k):
        f = {key: 1 + eps * rng.integers(-ulps, ulps + 1, np.shape(inputs[key]))
             for key in _float_inputs(case, inputs)}
        pts.append(_scaled(case, inputs, f))
    return pts


def _ldl_bounds(b, zf):
    """Algorithm 1 as the shipped ports evaluate it in float32: LDLᵀ of B(b), Peters and Klein 2015, Prop. 10.

    B = L D Lᵀ with D = diag(1, σ², ξ4) (HPG17 Eq. (3)); the roots of q2 z² + q1 z + q0
    without cancellation; w_l = 1 / (1 + u2²/σ² + u3²/ξ4). Returns ``(lower, upper)`` in
    float32; NaN on the singular rows (σ² ≤ 0 or ξ4 ≤ 0), where this formulation
    contributes nothing. Used by :func:`confirm` only: a legitimate float32 evaluation the
    golden spread model does not contain (near singular texels its z2 lands just above zf).
    """
    f = np.float32
    b = np.asarray(b, f)
    zf = np.asarray(zf, f)
    b1, b2, b3, b4 = (b[..., k] for k in range(4))
    with np.errstate(all="ignore"):
        s2 = b2 - b1 * b1
        l32 = (b3 - b1 * b2) / s2
        xi4 = b4 - b2 * b2 - l32 * l32 * s2
        y2 = zf - b1
        y3 = zf * zf - b2 - l32 * y2
        q2 = y3 / xi4
        q1 = y2 / s2 - l32 * q2
        q0 = f(1) - b1 * q1 - b2 * q2
        disc = np.sqrt(np.maximum(q1 * q1 - f(4) * q2 * q0, f(0)))
        t = f(-0.5) * (q1 + np.where(q1 < 0, -disc, disc))
        z1, z2 = np.minimum(t / q2, q0 / t), np.maximum(t / q2, q0 / t)
        w0 = f(1) / (f(1) + y2 * y2 / s2 + y3 * y3 / xi4)
        u2 = z1 - b1
        u3 = z1 * z1 - b2 - l32 * u2
        w1 = np.where(np.abs(z1) <= np.finfo(f).max, f(1) / (f(1) + u2 * u2 / s2 + u3 * u3 / xi4), f(0))
        low = np.where(zf <= z1, f(0), np.where(zf <= z2, w1, f(1) - w0))
        ok = (s2 > 0) & (xi4 > 0)
        return (np.where(ok, np.clip(low, 0, 1), np.nan).astype(f),
                np.where(ok, np.clip(low + w0, 0, 1), np.nan).astype(f))


def _formulations(case, point, dt):
    """Legitimate evaluations in the port's precision: the reference, the papers' code, the shipped LDLᵀ."""
    out = [evaluate_reference(case, point, dt)]
    if case.spread_hook is not None:
        out += list(case.spread_hook(point, np.dtype(dt)))
    bound = case.kwargs.get("bound")
    if case.function == "msm.shadow_intensity" and bound in ("lower", "upper") and point["b"].shape[-1] == 4:
        out.append((_ldl_bounds(point["b"], point["zf"])[bound == "upper"],))
    return out


def _exact(case, point):
    if case.truth is None:  # no mpmath twin: the float64 reference is the case's expected value
        return evaluate_reference(case, point, np.float64)
    return case.truth(**{k: (v if k in case.integer_inputs else np.asarray(v, np.float64)) for k, v in point.items()})


def confirm(case, inputs, got, port_dtype="float32"):
    """``(n,)`` bool: rows whose ``got`` no exact value over the inputs' float32 neighbourhood explains.

    The exact value (mpmath, :mod:`moments_ref.precise`) is computed on the row and on
    :data:`NEIGHBOURS` + 2 points whose float inputs differ from it by at most
    ``PERTURB_ULPS`` float32 ulps per component (the backward error of a correct float32
    evaluation). A row is confirmed wrong when every one of them is farther from ``got``
    than ``FLOOR_ULPS`` ulps of max(|value|, 1) in ``port_dtype`` (or, for codes, differs),
    on some output. NaN outputs are confirmed wrong.
    """
    n = len(next(iter(inputs.values())))
    if n == 0:
        return np.zeros(0, bool)
    rng = np.random.default_rng(12345)
    dt = np.dtype(port_dtype)
    explained = np.zeros((len(case.outputs), n), bool)
    for point in _neighbourhood(case, inputs, rng, NEIGHBOURS):
        values = [_exact(case, point)]
        if not case.integer_output:
            values += _formulations(case, point, dt)
        for exact in values:
            for i, o in enumerate(case.outputs):
                e = np.asarray(exact[i], np.float64)
                g = np.asarray(got[o], np.float64).reshape(e.shape)
                if case.integer_output:
                    ok = g == e
                else:
                    scale = np.broadcast_to(np.asarray(case.floor_scale, np.float64), e.shape)
                    ok = np.abs(g - e) <= FLOOR_ULPS * ulp(np.maximum(np.abs(e), scale), dt)
                explained[i] |= np.asarray(ok).reshape(n, -1).all(axis=1)
    if case.integer_output and case.margin is not None:
        explained |= _ties(case, inputs, got)[None]
    return ~explained.all(axis=0)


def _ties(case, inputs, got):
    """Rows on a rounding tie (golden.spread: the exact scaled value within TIE_BAND of a boundary) whose
    codes are within one of the exact codes: either code is acceptable there."""
    args = {k: (v if k in case.integer_inputs else np.asarray(v, np.float64)) for k, v in inputs.items()}
    n = len(next(iter(inputs.values())))
    tie = np.asarray(case.margin(**args), np.float64).reshape(n) <= TIE_BAND
    near = np.ones(n, bool)
    for i, o in enumerate(case.outputs):
        e = np.asarray(case.truth(**args)[i], np.int64)
        near &= (np.abs(np.asarray(got[o], np.int64).reshape(e.shape) - e) <= 1).reshape(n, -1).all(axis=1)
    return tie & near
