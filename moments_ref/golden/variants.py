"""How a declared profile configures a case's reference, ground truth and spread (golden.conventions).

Each function returns a case's ``variant``: called with ``bias`` (the
:class:`~moments_ref.golden.profile.Bias` applied *inside* the tested function, in
the engine's depth convention, or None), ``clamp`` (Algorithm 3's offset, or None)
and ``fmt`` (texel-format choices), it returns the replacements of the case's
``reference``, ``truth`` and ``spread_hook``: the same equations with the engine's
choices, evaluated by the same means (this package in the port's precision, the
mpmath twin for the truth). The algorithms of Algorithm 1 and of biasing do not
depend on the depth convention, so a [0, 1] engine is judged by the same code on
its own inputs.

References
----------
HPG17, Slides : see docs/bib.md.
"""

from __future__ import annotations

import numpy as np

from .. import precise

__all__ = ["alg1_variant", "bias_variant", "shade_variant", "shade_reference", "shade_truth", "preset_of"]


def preset_of(bias):
    """The :class:`moments_ref.moments.BiasPreset` of a declared bias."""
    from ..moments import BiasPreset

    return BiasPreset(bias.alpha, tuple(bias.target), "declared")


def alg1_variant(bound, six=False, base_hook=None):
    """Algorithm 1 (four or six moments) with the engine's bias applied inside the function.

    ``base_hook``: the case's own spread hook (other formulations), run on the biased moments.
    """

    def variant(bias=None, clamp=None, fmt=None, **_):
        if bias is None:
            return {}
        from ..moments import bias_moments
        from ..msm import shadow_intensity
        from .paper import printed_bound, slides_bound

        p = preset_of(bias)
        exact = precise.shadow_intensity6 if six else precise.shadow_intensity

        def reference(b, zf):
            return (shadow_intensity(bias_moments(b, p), zf, bound=bound),)

        def truth(b, zf):
            return (exact(precise.bias_moments(b, p), zf, bound=bound),)

        def hook(inputs, dt):
            if six:
                biased = bias_moments(np.asarray(inputs["b"]).astype(dt), p)
                return base_hook({"b": biased, "zf": inputs["zf"]}, dt) if base_hook else []
            biased = bias_moments(np.asarray(inputs["b"]).astype(dt), p)
            return [(slides_bound(biased, inputs["zf"], bound, dt),), (printed_bound(biased, inputs["zf"], bound, dt),)]

        return {"reference": reference, "truth": truth, "spread_hook": hook}

    return variant


def bias_variant():
    """Biasing with the engine's α and target instead of the case's preset."""

    def variant(bias=None, clamp=None, fmt=None, **_):
        if bias is None:
            return {}
        from ..moments import bias_moments

        p = preset_of(bias)
        return {"reference": lambda b: (bias_moments(b, p),), "truth": lambda b: (precise.bias_moments(b, p),),
                "kwargs": {"preset": {"alpha": p.alpha, "target": list(p.target)}}}

    return variant


def shade_variant():
    """Algorithm 3 with the engine's clamp offset and case test (HPG17 §3.4); the printed formula in the spread."""

    def variant(bias=None, clamp=None, fmt=None, clamp_test=None, **_):
        if clamp is None and clamp_test is None:
            return {}
        from ..nonlinear import SHADE_TOLERANCE
        from .paper import alg3_paper_spread

        c = SHADE_TOLERANCE if clamp is None else clamp
        test = clamp_test or "stored"
        return {"reference": shade_reference(c, test), "truth": shade_truth(c, test),
                "spread_hook": alg3_paper_spread(c, test)}

    return variant


def shade_reference(clamp, case_test="stored"):
    """This package's Algorithm 3 with ``clamp``; the clamped case test by raising y2 to y1 + clamp first."""
    from ..nonlinear import shade

    def reference(r, zf):
        r = np.array(r, copy=True)
        if case_test == "clamped":
            r[..., 1] = np.maximum(r[..., 1], r[..., 0] + r.dtype.type(clamp))
        return (shade(r, zf, clamp=clamp),)

    return reference


def shade_truth(clamp, case_test="stored"):
    from .truth import shade_clamped

    return lambda r, zf: (shade_clamped(r, zf, clamp=clamp, case_test=case_test),)
