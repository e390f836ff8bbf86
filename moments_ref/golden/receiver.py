"""The receiver as the tested function sees it: its depth convention, its offset toward the light, a caller's clamp.

Real ports move the receiver before Algorithm 1 (HPG17 Algorithm 1 / Slides, "Compute the
shadow intensity" take zf as given): a constant acne offset (``zf - 1e-6``) or one scaled by
the receiver's slope (``zf - c * slope``), or they take the receiver in another depth
convention than their moments (a [0, 1] receiver mapped inside to the moments' [-1, 1]);
their caller may clamp the result to [0, 1]. Declared in a profile (``receiver_offset``,
``receiver_slope``, ``receiver_depth``, ``output_clamp``; :data:`~.profile.KEYS`), these are
part of the legitimate input, not a widening of any band:

* **feed** (:func:`feed`): the receiver the port is given, in its declared convention and
  rounded once to the case's dtype, as an engine's float32 varying holds it; with
  ``receiver_slope`` the rows gain a ``slope`` input (a deterministic spread of tangents);
* **judged receiver** (:func:`judged`): what the function computes from it, in the case's
  dtype as a port does (``2 r - 1``, then ``- offset``, then ``- c * slope``): the expected
  value and band are derived at that receiver, whose float32 neighbourhood the band covers
  (:mod:`moments_ref.golden.bands`);
* **clamp** (:func:`clamp_outputs`): a declared caller's clamp clamps the port's output to
  [0, 1] before the comparison, and the verdict says so.

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

import zlib

import numpy as np

__all__ = ["moments_convention", "receiver_convention", "slopes", "feed", "judged", "clamp_outputs", "SLOPE_MAX"]

#: Largest receiver slope of the rows (tan 85°): grazing receivers included, vertical ones not.
SLOPE_MAX = float(np.tan(np.radians(85.0)))


def moments_convention(case, profile):
    """The depth convention of the case's zf as converted for ``profile`` (that of its moments)."""
    return "[0,1]" if profile.depth == "[0,1]" and case.depth_roles.get("zf") == "depth" else "[-1,1]"


def receiver_convention(case, profile):
    """The convention the port receives zf in: ``receiver_depth`` if declared, else the moments'."""
    return profile.receiver_depth or moments_convention(case, profile)


def slopes(name, n, dtype):
    """``(n,)`` receiver slopes of case ``name``: tangents of angles uniform in [0°, 85°], a tenth exactly 0."""
    rng = np.random.default_rng(zlib.crc32(f"slope:{name}".encode()))
    s = np.tan(np.radians(rng.uniform(0.0, 85.0, n)))
    s[rng.random(n) < 0.1] = 0.0
    return s.astype(dtype)


def feed(case, conv, profile):
    """The receiver inputs the port is given: ``{"zf": ..., "slope": ...}`` (only what changes).

    ``conv``: the case's inputs in the moments' convention (:func:`~.conventions.convert_inputs`).
    """
    if "zf" not in case.inputs:
        return {}
    zf = np.asarray(conv["zf"])
    out = {}
    src, dst = moments_convention(case, profile), receiver_convention(case, profile)
    if src != dst:
        z = zf.astype(np.float64)  # exact; the conversion rounds once, to the port's dtype
        out["zf"] = ((z + 1) * 0.5 if dst == "[0,1]" else z * 2 - 1).astype(zf.dtype)
    if profile.receiver_slope:
        out["slope"] = slopes(case.name, len(zf), zf.dtype)
    return out


def judged(case, fed, profile):
    """``{"zf": ...}``: the receiver the function computes from what it was ``fed``, in the case's dtype.

    The port maps a receiver of another convention to its moments' (``2 r - 1`` or
    ``r / 2 + 1/2``), then subtracts its offsets toward the light; each step rounds in the
    port's dtype, as the port's arithmetic does.
    """
    if "zf" not in case.inputs or "zf" not in fed:
        return {}
    z = np.asarray(fed["zf"])
    dt = z.dtype.type
    src, dst = receiver_convention(case, profile), moments_convention(case, profile)
    if src != dst:
        z = z * dt(2) - dt(1) if dst == "[-1,1]" else (z + dt(1)) * dt(0.5)
    if profile.receiver_offset:
        z = z - dt(profile.receiver_offset)
    if profile.receiver_slope and "slope" in fed:
        z = z - dt(profile.receiver_slope) * np.asarray(fed["slope"], z.dtype)
    return {"zf": np.asarray(z, np.asarray(fed["zf"]).dtype)}


def clamp_outputs(case, profile, got):
    """``(got', notes)``: with ``output_clamp`` declared, the float outputs clamped to [0, 1] as the caller does.

    NaN becomes 0, as HLSL's ``saturate`` and SPIR-V's ``NClamp`` define it (GLSL leaves it
    open): what the caller shades with. The note counts the values the clamp changed.
    """
    if not profile.output_clamp or tuple(case.outputs) != ("intensity",):
        return got, []
    out = dict(got)
    changed = 0
    for o in case.outputs:
        if o in out and np.asarray(out[o]).dtype.kind == "f":
            g = np.asarray(out[o])
            # HLSL's saturate and SPIR-V's NClamp: NaN becomes 0 (what the caller shades with)
            c = np.where(np.isnan(g), 0, np.clip(g, 0, 1))
            changed += int(np.count_nonzero(~(c == g)))
            out[o] = c.astype(g.dtype)
    return out, [f"output_clamp: the port's output clamped to [0, 1] before the comparison, as its caller does "
                 f"({changed} values changed)"]
