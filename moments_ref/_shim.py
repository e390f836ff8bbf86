"""The old import paths of modules that moved into their layer's folder, and the old names of renamed names.

Each old path (``moments_ref.filtering``, ``moments_ref.vwss.shading``, ...) is a
two-line module that forwards attribute access to the new path and warns with a
:class:`DeprecationWarning`, for one release; NumPy moved ``numpy.core`` to
``numpy._core`` the same way. :data:`MOVED` is the one list of them
(``tests/test_architecture.py`` checks that every entry has its shim and no
shim is missing from it).

Names renamed so that they say which space or frame they hold (``view_proj`` ->
``clip_from_world``, ``linear_depth`` -> ``d_view_from_ndc``, ...) keep their old
spelling for one release too, warning the same way: module names through
:data:`RENAMED` and :func:`renamed` (a module-level ``__getattr__``), methods and
attributes through :func:`alias`, keyword arguments through :func:`renamed_keywords`, keys of
parameter dicts through :func:`renamed_keys`.
"""

from __future__ import annotations

import importlib
import warnings

__all__ = ["MOVED", "forward", "RENAMED", "renamed", "alias", "renamed_keywords", "renamed_keys", "warn_renamed"]

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
    "vwss.compare": "report.vwss",
    "techniques.vwss.compare": "report.vwss",
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


#: Module -> {old name: new home ``module.name``}, all below ``moments_ref``: renamed public names.
RENAMED = {
    "scene.gbuffer": {"receiver_depth": "scene.gbuffer.z_ndc_lookup"},
    "techniques.vwss.shading": {"linear_depth": "scene.depth.d_view_from_ndc",
                                "gbuffer": "scene.gbuffer.depth_gbuffer", "GBuffer": "scene.gbuffer.GBuffer"},
    "techniques.vwss": {"linear_depth": "scene.depth.d_view_from_ndc",
                        "gbuffer": "scene.gbuffer.depth_gbuffer", "GBuffer": "scene.gbuffer.GBuffer"},
}


def warn_renamed(old, new):
    """Warn (DeprecationWarning, at the caller's caller) that ``old`` is now ``new``."""
    warnings.warn(f"{old} is now {new}; the old name will be removed in the next release", DeprecationWarning,
                  stacklevel=3)


def renamed(module):
    """The module-level ``__getattr__`` of ``moments_ref.<module>`` that serves its :data:`RENAMED` old names."""
    table = RENAMED[module]

    def __getattr__(name):
        if name not in table:
            raise AttributeError(f"module 'moments_ref.{module}' has no attribute {name!r}")
        home, _, new = table[name].rpartition(".")
        warn_renamed(f"moments_ref.{module}.{name}", f"moments_ref.{home}.{new}")
        return getattr(importlib.import_module(f"moments_ref.{home}"), new)

    return __getattr__


def alias(new):
    """A class attribute that serves the attribute or method ``new`` under an old name, warning."""

    class _Alias:
        def __set_name__(self, owner, name):
            self.old = f"{owner.__name__}.{name}"

        def __get__(self, obj, owner=None):
            warn_renamed(self.old, f"{owner.__name__}.{new}")
            return getattr(owner if obj is None else obj, new)

    return _Alias()


def renamed_keywords(**old_to_new):
    """Decorator: the keyword arguments ``old=...`` still work as ``new=...``, warning."""
    import functools

    def wrap(fn):
        @functools.wraps(fn)
        def call(*args, **kwargs):
            for old, new in old_to_new.items():
                if old in kwargs:
                    if new in kwargs:
                        raise TypeError(f"{fn.__name__}() got both {old!r} (the old name) and {new!r}")
                    warn_renamed(f"{fn.__name__}({old}=...)", f"{fn.__name__}({new}=...)")
                    kwargs[new] = kwargs.pop(old)
            return fn(*args, **kwargs)

        return call

    return wrap


def renamed_keys(mapping, what, **old_to_new):
    """``mapping`` with its old keys under their new names (a copy; warns once per old key found)."""
    if not isinstance(mapping, dict) or not any(k in mapping for k in old_to_new):
        return mapping
    out = dict(mapping)
    for old, new in old_to_new.items():
        if old in out:
            warn_renamed(f"{what}[{old!r}]", f"{what}[{new!r}]")
            out.setdefault(new, out.pop(old))
    return out
