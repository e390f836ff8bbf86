"""The sweep's rows as an engine with a profile receives them: the goldens' conversion, vectorised.

:func:`moments_ref.golden.conventions.convert_inputs` turns a golden row (the papers'
[-1, 1] depths, the harness's bias) into what an engine with a
:class:`~moments_ref.golden.profile.Profile` hands its port: moments in the engine's
depth convention, with ``bias.applied = "before"`` biased by the caller in the same exact
step, each value rounded once; depths through
:func:`moments_ref.scene.depth.z_unit_from_ndc`. It does so in rational arithmetic,
element by element, which is right for a few hundred golden rows and far too slow for
10^6 sweep rows. :func:`convert_inputs` computes the same values bit for bit, vectorised:

* the converted moment b'_k = Σ_j C(k, j) s^j o^(k−j) b_j (b_0 = 1; s = o = 1/2 for
  [0, 1]) is a sum of products of float32 values with small binary fractions, each term
  exact in float64;
* the caller's bias (Slides, "Bias the moments": b'' = (1 − α) b' + α b*) adds the
  products α·term and α·b*_k, each split exactly into two float64 numbers (Dekker's
  product);
* the terms are summed in three-fold working precision (Ogita, Rump and Oishi's SumK,
  K = 3, built from error-free TwoSum) and rounded once to float32, ties to even, the
  sign of the residual deciding a float64 sum that lies on a float32 midpoint.

The contract of a row is decided as the goldens decide it
(:func:`moments_ref.golden.conventions.contract_mask`: on the papers' inputs with the
declared bias), so rounding in the conversion never moves a row across it.
``tests/test_sweep_profiles.py`` checks the conversion against the rational one.

References
----------
.. [1] Slides: Christoph Peters. *Rendering antialiased shadows with moment shadow mapping*,
       lecture slides (PDF version, with notes) on moment shadow mapping, translucent occluders,
       moment soft shadow mapping and prefiltered single scattering; http://MomentsInGraphics.de/.
       Cited by slide title, e.g. Slides, "Bias the moments".
.. [2] T. Ogita, S. M. Rump, S. Oishi. 2005. *Accurate sum and dot product*. SIAM J. Sci. Comput.
       26(6), 1955–1988 (TwoSum, SumK).
"""

from __future__ import annotations

from math import comb

import numpy as np

from ..golden._ddmoments import two_prod as _two_product, two_sum as _two_sum
from ..scene.depth import z_unit_from_ndc

__all__ = ["convert_inputs", "harness_bias", "unit_depth"]

def unit_depth(case):
    """Whether the profiled ``case`` receives [0, 1] depths (its profile declares ``depth = "[0,1]"``)."""
    return (case.kwargs.get("profile") or {}).get("depth") == "[0,1]"


def harness_bias(case):
    """``(alpha, target)`` of the bias the harness applies just before the call (engine frame), or None."""
    kw = case.kwargs.get("harness_bias")
    return None if kw is None else (float(kw["alpha"]), tuple(float(t) for t in kw["target"]))


def _sum_rounded(terms):
    """Σ ``terms`` (float64 arrays), rounded once to float32 (SumK with K = 3, then a residual-aware rounding)."""
    x = [np.asarray(t, np.float64) for t in terms]
    for _ in range(2):  # K - 1 error-free passes
        for i in range(1, len(x)):
            x[i], x[i - 1] = _two_sum(x[i], x[i - 1])
    rest = np.sum(x[:-1], axis=0) if len(x) > 1 else np.zeros_like(x[-1])
    hi, lo = _two_sum(x[-1], rest)
    r = hi.astype(np.float32)
    r64 = r.astype(np.float64)
    other = np.nextafter(r, np.where(hi > r64, np.float32(np.inf), np.float32(-np.inf))).astype(np.float32)
    tie = (hi != r64) & (hi == (r64 + other.astype(np.float64)) / 2) & (lo != 0)
    toward = np.where(lo > 0, np.maximum(r, other), np.minimum(r, other))
    return np.where(tie, toward, r).astype(np.float32)


def _moments(b, unit, bias):
    """Moments ``b`` (n, m) float32 in the papers' frame -> the engine's, biased before the call, rounded once."""
    b = np.asarray(b, np.float64)
    s, o = (0.5, 0.5) if unit else (1.0, 0.0)
    out = np.empty(b.shape, np.float32)
    for k in range(1, b.shape[-1] + 1):  # a loop over the moments, not over rows
        terms = [np.full(b.shape[:-1], o ** k)] + [comb(k, j) * s ** j * o ** (k - j) * b[..., j - 1]
                                                  for j in range(1, k + 1)]
        if bias is not None:
            alpha, target = bias
            for t in list(terms):
                p, e = _two_product(-alpha, t)
                terms += [p, e]
            terms += list(_two_product(alpha, np.full(b.shape[:-1], target[k - 1])))
        out[..., k - 1] = _sum_rounded(terms)
    return out


def convert_inputs(case, inputs):
    """The rows ``inputs`` (the papers' frame, float32) as the profiled ``case``'s port receives them.

    Bit for bit :func:`moments_ref.golden.conventions.convert_inputs` under the case's
    profile (its ``depth`` and a bias applied before the call), vectorised.
    """
    unit, bias = unit_depth(case), harness_bias(case)
    out = {}
    for k, v in inputs.items():
        role = case.depth_roles.get(k)
        if role == "moments" and (unit or bias is not None):
            out[k] = _moments(v, unit, bias)
        elif role == "depth" and unit:
            out[k] = z_unit_from_ndc(np.asarray(v, np.float32)).astype(np.float32)
        else:
            out[k] = v
    return out
