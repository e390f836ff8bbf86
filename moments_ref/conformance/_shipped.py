"""The shipped reference ports: which file and function cover which golden case."""

from __future__ import annotations

from ..ports import PORTS_DIR

__all__ = ["SHIPPED_FUNCTIONS", "SHIPPED", "NOT_AVAILABLE", "shipped_port", "shipped_cases", "not_available"]

#: Case prefix -> (file stem, function); the same in every language (``msm.glsl``,
#: ``msm.hlsl``, ``msm.wgsl``). The first prefix a case name starts with wins.
SHIPPED_FUNCTIONS = {
    "shadow_intensity6-lower": ("msm6", "shadow_intensity6_lower"),
    "shadow_intensity6-upper": ("msm6", "shadow_intensity6_upper"),
    "shadow_intensity_bilinear-": ("bilinear", "shadow_intensity_bilinear"),
    "sample_bilinear-": ("bilinear", "sample_moments"),
    "shadow_intensity-lower": ("msm", "shadow_intensity_lower"),
    "shadow_intensity-upper": ("msm", "shadow_intensity_upper"),
    "bias_moments-float32": ("msm", "bias_moments_float32"),
    "bias_moments-unorm16": ("msm", "bias_moments_unorm16"),
    "to_optimized-": ("msm", "to_optimized"),
    "from_optimized-": ("msm", "from_optimized"),
    "decode_unorm16-": ("msm", "decode_unorm16"),
    "phi-": ("nonlinear", "phi"),
    "phi_inverse-": ("nonlinear", "phi_inverse"),
    "psi4-": ("nonlinear", "psi4"),
    "psi4_inverse-": ("nonlinear", "psi4_inverse"),
    "shade-": ("nonlinear", "shade"),
    "pack64-": ("packing", "pack64"),
    "unpack64-": ("packing", "unpack64"),
    "pack32-": ("packing", "pack32"),
    "unpack32-": ("packing", "unpack32"),
}

#: Shipped cases a language cannot run on a driver, and why: (language, driver) -> {case prefix: reason}.
#: The harness refuses these runs with one line (exit 2), never a verdict; ``conformance --all``
#: lists them as not available and the suite checks that each is refused as declared.
NOT_AVAILABLE = {
    ("glsl", "vulkan"): dict.fromkeys(
        ("sample_bilinear-", "shadow_intensity_bilinear-"),
        "GLSL's sampler2D is a combined image sampler, which wgpu's SPIR-V reader does not take"),
    ("wgsl", "gl"): dict.fromkeys(
        ("sample_bilinear-", "shadow_intensity_bilinear-"),
        "wgpu's OpenGL adapter lacks the WebGPU feature float32-filterable (a linear sampler on rgba32float)"),
}

#: The shipped GLSL ports: case prefix -> (file in ``GLSL_DIR``, function).
SHIPPED = {prefix: (f"{stem}.glsl", fn) for prefix, (stem, fn) in SHIPPED_FUNCTIONS.items()}


def shipped_port(case, language="glsl"):
    """``(path, function)`` of the shipped port of ``language`` for a case name, or None."""
    from .languages import TABLE

    for prefix, (stem, function) in SHIPPED_FUNCTIONS.items():
        if case.startswith(prefix):
            if language in TABLE and stem not in TABLE[language].shipped:
                return None
            return PORTS_DIR / language / f"{stem}.{language}", function
    return None


def shipped_cases(dtypes=("float32", "float64")):
    """Every golden case a shipped port covers, in the golden order."""
    from .. import golden

    return [n for n in golden.CASES if n.endswith(tuple(f"-{d}" for d in dtypes)) and shipped_port(n) is not None]


def not_available(case, language, driver):
    """Why ``language`` cannot run ``case`` on ``driver`` (:data:`NOT_AVAILABLE`), or None where it can."""
    for prefix, reason in NOT_AVAILABLE.get((language, driver), {}).items():
        if case.startswith(prefix):
            return reason
    return None
