"""Shadow techniques: one module per technique, one shared interface, one registry.

The interface is :class:`Technique`: its attributes (documented there, once) are
its storage and depth bias, the steps that build its filtered texture
(``prepare``), its lookup (``shadow``: the shadow intensity, 0 = lit, 1 = fully
shadowed), the stages it adds to the pipeline's graph (``stages``, a :class:`Plan`)
and ``truth``, the :class:`Reference` its error is measured against.

:mod:`moments_ref.pipeline` adds every requested technique's stages and its
reference's stage to one graph and runs what the targets need, each stage key
once (two techniques whose chains start with the same step keys share those
results); :mod:`moments_ref.report` iterates over the techniques and their
references without special cases.

Conventions
-----------
``depth_samples`` is an ``(H, W, S)`` float array of sample depths in [-1, 1]
(:func:`moments_ref.scene.raster.rasterize_depth`), or a :class:`LayeredSamples` (the
output of the translucency pass, :func:`moments_ref.techniques.translucent.translucency_pass`):
per sample a depth distribution of K layers with weights summing to 1. An opaque
map is the special case K = 1, weight 1.

``uv`` is ``(..., 2)`` in texels, u = x (column) and v = y (row), texel centres at
``i + 0.5`` (the convention of :mod:`moments_ref.gpu.bluenoise` and of the window
coordinates of :func:`moments_ref.scene.raster.project_points`). ``depth`` is the
fragment's NDC depth in the light's view, broadcast against ``uv[..., 0]``.

Registering a technique
-----------------------
A further module builds a :class:`Technique` and calls :func:`register`; the
pipeline and the report pick it up by name (docs/architecture.md lists the files
to touch). A technique that needs a light of a particular kind says so in
``light_kinds``; one that needs several views sets ``multiview`` (its stage
names must contain ``vwss`` for multi-view work, as ``stages.json`` promises).

Registered here, in this order (the report's row order): ``pcf``, ``vsm``, ``esm``,
``evsm64``, ``evsm128``, ``msm64``, ``msm128``, ``nlq64``, ``nlq32``,
``nlq64_dither``, ``nlq32_dither``, ``translucent_msm`` (all measured against
the filtered hard shadow, reference ``pcf``); ``msm_soft`` (moment soft shadow
mapping, :mod:`.msm_soft`), ``pcss``, ``vwss`` and ``mvr`` (:mod:`.soft`; reference in :mod:`.area`), area
lights only, measured against multi-view rasterization (reference ``mvr``);
``scattering_6m``, ``scattering_6m_unfiltered`` and ``raymarch``
(:mod:`.scattering`), scenes with a participating medium only, measured against
converged ray marching (reference ``raymarch``).

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

from ._interface import (  # noqa: F401
    REFERENCES,
    TECHNIQUES,
    LayeredSamples,
    Plan,
    PlanContext,
    Reference,
    Stage,
    Step,
    Technique,
    bilinear_filtered,
    check_uv_depth,
    get,
    get_reference,
    is_layered,
    names,
    register,
    register_reference,
    sample_count,
    stage_key,
    reduced_settings,
    texture_stages,
)

from ._interface import __all__  # the package re-exports the interface as it is

# Register the shipped references and techniques (order = the report's row order).
from . import references  # noqa: E402,F401
from . import pcf, vsm, esm, evsm, msm, nlq, translucent  # noqa: E402,F401
from . import area, msm_soft, soft  # noqa: E402,F401
from . import scattering  # noqa: E402,F401
