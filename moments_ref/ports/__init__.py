"""Ports of the core functions to shading languages, shipped as package data.

``glsl/``, ``hlsl/``, ``wgsl/`` and ``slang/`` hold compute-shader ports written from the
papers (HPG17, the slides), one file per concept (``msm``, ``msm6``,
``nonlinear``, ``packing``) with the same function names in every language;
:mod:`moments_ref.conformance` runs any of their functions on a real driver
against the golden vectors. See docs/ports.md.

References
----------
.. [1] HPG17: Christoph Peters. 2017. *Non-Linearly Quantized Moment Shadow Maps*. In Proceedings
       of High Performance Graphics (HPG '17). ACM. The non-linear quantization Φ, Ψ4, Algorithms
       1–3, the texel formats and the compute shader of §4.1.
"""

from pathlib import Path

#: Folder holding ``glsl/``, ``hlsl/`` and ``wgsl/``.
PORTS_DIR = Path(__file__).resolve().parent
#: Folder of the shipped GLSL ports (``msm.glsl``, ``msm6.glsl``, ``nonlinear.glsl``, ``packing.glsl``).
GLSL_DIR = PORTS_DIR / "glsl"
#: Folder of the shipped HLSL ports.
HLSL_DIR = PORTS_DIR / "hlsl"
#: Folder of the shipped WGSL ports.
WGSL_DIR = PORTS_DIR / "wgsl"
#: Folder of the shipped Slang ports (``msm``, ``nonlinear``, ``packing``, the §4.1 kernel).
SLANG_DIR = PORTS_DIR / "slang"

__all__ = ["PORTS_DIR", "GLSL_DIR", "HLSL_DIR", "WGSL_DIR", "SLANG_DIR"]
