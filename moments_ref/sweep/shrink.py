"""Greedy shrinking of a failing row to the simplest texel the port still fails (hypothesis-style).

A row is a texel (depths and weights), a receiver zf and a texel format. Each step
builds every simpler neighbour of the current row (:func:`candidates`, simplest first:
the plain float32 texel instead of a non-linear one, one depth fewer, equal weights,
depths, weights and zf rounded to fewer decimals, zf at a round offset from a depth),
runs them all in **one dispatch**, judges them with :func:`.judge.legitimate_interval`,
and keeps the first that is still wrong and confirmed by :func:`.judge.confirm`: of the
flagged neighbours the first 8 are confirmed in turn (mpmath is costly), each alone, so that
its confirmation depends on that row only (as when its row file is rerun). It stops when no
neighbour fails (or after :data:`MAX_STEPS` steps). Rows are the same when their depths and
weights (where the weight is positive) agree to 17 decimals, their zf and format exactly.
"""

from __future__ import annotations

import numpy as np

from . import judge
from .runner import evaluate
from .samplers import build_inputs

__all__ = ["shrink", "candidates", "MAX_STEPS"]

MAX_STEPS = 40
_W = 6


def _row(z, w, zf, fmt):
    z = np.asarray(z, np.float64)
    w = np.asarray(w, np.float64)
    w = w / w.sum()
    pz = np.full(_W, z[0])
    pw = np.zeros(_W)
    pz[:len(z)], pw[:len(w)] = z, w
    return pz, pw, float(np.clip(zf, -1, 1)), int(fmt)


def _key(row):
    z, w, zf, fmt = row
    return (tuple(np.round(z[w > 0], 17)), tuple(np.round(w[w > 0], 17)), zf, fmt)


def candidates(texel, seen=None):
    """Simpler neighbours of ``texel`` (``depths``, ``weights``, ``zf``, ``format``), simplest first.

    ``seen``: a set of rows already tried (updated): they are not offered again, so that
    shrinking never cycles between two equally simple rows.
    """
    z, w = np.asarray(texel["depths"], np.float64), np.asarray(texel["weights"], np.float64)
    zf, fmt = float(texel["zf"]), int(texel["format"])
    out = []
    if fmt != 0:
        out.append(_row(z, w, zf, 0))
    for k in range(len(z)):
        if len(z) > 1:
            out.append(_row(np.delete(z, k), np.delete(w, k), zf, fmt))
    if len(z) > 1 and np.ptp(w) > 0:
        out.append(_row(z, np.ones(len(z)), zf, fmt))
    for d in range(0, 8):
        if np.any(np.round(z, d) != z):
            out.append(_row(np.round(z, d), w, zf, fmt))
    for d in range(1, 6):
        if len(z) > 1 and np.any(np.round(w, d) != w) and np.all(np.round(w, d) > 0):
            out.append(_row(z, np.round(w, d), zf, fmt))
    near = z[np.argmin(np.abs(z - zf))]
    off = zf - near
    if off != 0:
        for e in range(-8, 1):
            cand = near + np.sign(off) * 10.0**e
            if abs(cand - near) < abs(off) or e == round(np.log10(abs(off))):
                out.append(_row(z, w, cand, fmt))
    for d in range(0, 8):
        if np.round(zf, d) != zf:
            out.append(_row(z, w, np.round(zf, d), fmt))
    seen = set() if seen is None else seen
    seen.add(_key(_row(z, w, zf, fmt)))
    unique = []
    for c in out:
        if _key(c) not in seen:
            seen.add(_key(c))
            unique.append(c)
    return unique


def _texel(row):
    z, w, zf, fmt = row
    keep = w > 0
    return {"depths": z[keep].tolist(), "weights": w[keep].tolist(), "zf": zf, "format": fmt}


def shrink(spec, driver, texel):
    """The simplest texel near ``texel`` that the port still fails on ``driver``.

    Returns ``(texel, row, dispatches)``: the shrunk texel, its judged row (``inputs``,
    ``got``, ``lo``, ``hi``) and the number of dispatches it took.
    """
    case, current, dispatches, row, seen = spec.case, texel, 0, None, set()
    for _ in range(MAX_STEPS):
        cands = candidates(current, seen)
        if not cands:
            break
        params = {"z": np.stack([c[0] for c in cands]), "w": np.stack([c[1] for c in cands]),
                  "zf": np.array([c[2] for c in cands]), "fmt": np.array([c[3] for c in cands])}
        inputs = build_inputs(case, params, spec.shaping)
        got = evaluate(spec, inputs, driver)
        dispatches += 1
        contract = judge.contract_rows(case, inputs, params.get("contract"))
        bands, ill = judge.legitimate_interval(case, inputs, spec.port_dtype, contract)
        gated = None if spec.strict else contract
        flagged = np.flatnonzero(judge.flagged_rows(case, inputs, bands, ill, got, gated, spec.port_dtype, contract))
        step = None
        for i in flagged[:8]:
            one = lambda d: {k: np.asarray(v)[i:i + 1] for k, v in d.items()}  # noqa: E731
            if judge.confirm(case, one(inputs), one(got), spec.port_dtype)[0]:
                step = i
                break
        if step is None:
            break
        current = _texel(cands[step])
        row = {"inputs": {k: np.asarray(v[step]).tolist() for k, v in inputs.items()},
               "got": {o: np.asarray(got[o][step]).tolist() for o in case.outputs},
               "lo": {o: np.asarray(bands[o][0][step]).tolist() for o in case.outputs},
               "hi": {o: np.asarray(bands[o][1][step]).tolist() for o in case.outputs}}
    return current, row, dispatches
