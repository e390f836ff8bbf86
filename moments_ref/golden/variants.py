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
.. [1] HPG17: Christoph Peters. 2017. *Non-Linearly Quantized Moment Shadow Maps*. In Proceedings
       of High Performance Graphics (HPG '17). ACM. The non-linear quantization Φ, Ψ4, Algorithms
       1–3, the texel formats and the compute shader of §4.1.
.. [2] Slides: Christoph Peters. *Rendering antialiased shadows with moment shadow mapping*,
       lecture slides (PDF version, with notes) on moment shadow mapping, translucent occluders,
       moment soft shadow mapping and prefiltered single scattering; http://MomentsInGraphics.de/.
       Cited by slide title, e.g. Slides, "Bias the moments".
"""

from __future__ import annotations

import numpy as np

from .. import precise

__all__ = ["alg1_variant", "bias_variant", "phi_variant", "shade_variant", "shade_reference", "shade_truth", "preset_of",
           "unpack32_variant", "pack64_variant", "decode32", "rounding64", "xi_decode_spread"]


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
        from .paper import cholesky_bound, printed_bound, slides_bound

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
            return [(slides_bound(biased, inputs["zf"], bound, dt),), (printed_bound(biased, inputs["zf"], bound, dt),),
                    (cholesky_bound(biased, inputs["zf"], bound, dt),),
                    (cholesky_bound(biased, inputs["zf"], bound, dt, fma=True),)]

        return {"reference": reference, "truth": truth, "spread_hook": hook}

    return variant


def phi_variant():
    """Φ (HPG17 Algorithm 2) behind the engine's own bias, applied inside the function (as the author's demo
    does): the golden moments are biased once already (BIAS_FLOAT32), the port biases them again."""

    def variant(bias=None, clamp=None, fmt=None, **_):
        if bias is None:
            return {}
        from ..moments import bias_moments
        from ..nonlinear import phi

        p = preset_of(bias)
        return {"reference": lambda b: (phi(bias_moments(b, p)),),
                "truth": lambda b: (precise.phi(precise.bias_moments(b, p)),)}

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


def decode32(fmt):
    """unpack32's keyword arguments for the declared decode positions (the format's own for the rest)."""
    return {k: v for k, v in (fmt or {}).items() if k in ("depth_decode", "v2_decode", "xi_decode")}


def rounding64(fmt):
    """pack64's keyword arguments for the declared rounding of the ξ4 code."""
    return {"xi_rounding": fmt["xi_rounding"]} if fmt and "xi_rounding" in fmt else {}


def unpack32_variant():
    """The 32-bit decoder reading its cells at the declared positions (docs/formats.md)."""

    def variant(bias=None, clamp=None, fmt=None, **_):
        kw = decode32(fmt)
        if not kw:
            return {}
        from fractions import Fraction

        from ..packing import unpack32
        from . import texel_truth

        offsets = {{"depth_decode": "depth", "v2_decode": "v", "xi_decode": "xi"}[k]:
                   {"lower": Fraction(0), "centre": Fraction(1, 2), "upper": Fraction(1)}[v] for k, v in kw.items()}
        return {"reference": lambda p, dtype=np.float64: (unpack32(p, dtype=dtype, **kw),),
                "truth": lambda p: texel_truth.unpack32(p, offsets), "spread_hook": xi_decode_spread("32", kw)}

    return variant


def pack64_variant():
    """The 64-bit encoder rounding the ξ4 code as declared (docs/formats.md)."""

    def variant(bias=None, clamp=None, fmt=None, **_):
        kw = rounding64(fmt)
        if not kw:
            return {}
        from ..packing import pack64
        from . import texel_codes

        rounding = kw["xi_rounding"]
        return {"reference": lambda r: (pack64(r, **kw),), "truth": lambda r: texel_codes.pack64(r, rounding),
                "margin": lambda r: texel_codes.pack64(r, rounding, margin=True)[1],
                "tie_neighbours": lambda r: texel_codes.pack64_neighbours(r, rounding)}

    return variant


def xi_decode_spread(fmt, decode=None):
    """Decoders: ξ4 with the Ψ4⁻¹ constants off by 3 ulps (c1 from float32 end points is 1 ulp off).

    ``decode``: unpack32's decode positions (``depth_decode``, ``v2_decode``, ``xi_decode``) when a
    profile declares other ones than the format's.
    """
    decode = dict(decode or {})

    def hook(inputs, dt):
        from ..nonlinear import PSI4_C0, PSI4_C1, psi4_inverse
        from ..packing import DECODE32, DECODE_POSITIONS, XI_BITS, XI_CELLS, XI_SHIFT, unpack32, unpack64

        code = inputs["q"] if fmt == "64" else inputs["p"]
        r = unpack64(code, dtype=dt) if fmt == "64" else unpack32(code, dtype=dt, **decode)
        if fmt == "64":
            u = code[..., 3].astype(np.float64) / 65535
        else:
            xcode = (code.astype(np.int64) >> XI_SHIFT) & ((1 << XI_BITS) - 1)
            u = (xcode + DECODE_POSITIONS[decode.get("xi_decode", DECODE32["xi"])]) / XI_CELLS
        eps = 3 * float(np.finfo(dt).eps)
        out = []
        for s1, s0 in ((1, 1), (1, -1), (-1, 1), (-1, -1)):
            v = r.copy()
            shifted = (u * (1 + s1 * eps) + s0 * eps * abs(PSI4_C0) / PSI4_C1).astype(dt)
            with np.errstate(over="ignore"):
                v[..., 3] = psi4_inverse(np.clip(shifted, 0, 1))
            out.append((v,))
        return out

    return hook
