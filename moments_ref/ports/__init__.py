"""Ports of the core functions to shading languages, shipped as package data.

``glsl/`` holds GLSL compute-shader ports written from the papers (HPG17, the
slides); :mod:`moments_ref.conformance` runs any of their functions on an OpenGL
4.3 context against the golden vectors. See docs/ports.md.
"""

from pathlib import Path

#: Folder of the shipped GLSL ports (``msm.glsl``, ``nonlinear.glsl``, ``packing.glsl``).
GLSL_DIR = Path(__file__).resolve().parent / "glsl"

__all__ = ["GLSL_DIR"]
