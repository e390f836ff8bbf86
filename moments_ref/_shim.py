"""The old import paths of modules that moved into their layer's folder.

Each old path (``moments_ref.filtering``, ``moments_ref.vwss.shading``, ...) is a
two-line module that forwards attribute access to the new path and warns with a
:class:`DeprecationWarning`, for one release; NumPy moved ``numpy.core`` to
``numpy._core`` the same way. :data:`MOVED` is the one list of them
(``tests/test_architecture.py`` checks that every entry has its shim and no
shim is missing from it).
"""

from __future__ import annotations

import importlib
import warnings

__all__ = ["MOVED", "forward"]

#: Old path -> new path, both below ``moments_ref`` (the old paths go in the release after next).
MOVED = {
    "filtering": "gpu.filtering",
    "onchip": "gpu.onchip",
    "banks": "gpu.banks",
    "bluenoise": "gpu.bluenoise",
    "sat": "gpu.sat",
    "raster": "scene.raster",
    "gbuffer": "scene.gbuffer",
    "vwss": "techniques.vwss",
    "vwss.lights": "techniques.vwss.lights",
    "vwss.points": "techniques.vwss.points",
    "vwss.warp": "techniques.vwss.warp",
    "vwss.mvr": "techniques.vwss.mvr",
    "vwss.shading": "techniques.vwss.shading",
    "vwss.compare": "techniques.vwss.compare",
    "vwss.paper": "techniques.vwss.paper",
    "paper_claims": "report.paper_claims",
    "scattering_temporal": "report.scattering_temporal",
    "bench": "tools.bench",
    "stability": "tools.stability",
    "figures": "tools.figures",
    "strategies": "tools.strategies",
}


def forward(old):
    """``(__getattr__, __dir__)`` for the shim module at ``moments_ref.<old>``."""
    new = f"moments_ref.{MOVED[old]}"

    def __getattr__(name):
        if name.startswith("__"):
            raise AttributeError(name)
        value = getattr(importlib.import_module(new), name)
        warnings.warn(f"moments_ref.{old} moved to {new}; the old path will be removed in the next release",
                      DeprecationWarning, stacklevel=2)
        return value

    def __dir__():
        return dir(importlib.import_module(new))

    return __getattr__, __dir__
