"""The old import paths of modules that moved into their layer's folder, and the old names of renamed names.

Each old path (``moments_ref.filtering``, ``moments_ref.vwss.shading``, ...) is served by
one import hook, :class:`MovedFinder` on :data:`sys.meta_path` (installed by
``moments_ref/__init__.py``), that reads :data:`MOVED`: importing an old path imports the
new module, binds it under the old name too (the same module object, so
``from moments_ref.filtering import blur`` and ``moments_ref.filtering.blur`` both work)
and warns once with a :class:`DeprecationWarning`, for one release. There is no file
per old path; NumPy moved ``numpy.core`` to ``numpy._core`` the same way.

Names renamed so that they say which space or frame they hold (``view_proj`` ->
``clip_from_world``, ``linear_depth`` -> ``d_view_from_ndc``, ...) keep their old
spelling for one release too, warning the same way: module names through
:data:`RENAMED` and :func:`renamed` (a module-level ``__getattr__``), methods and
attributes through :func:`alias`, keyword arguments through :func:`renamed_keywords`, keys of
parameter dicts through :func:`renamed_keys`.
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.machinery
import sys
import warnings

__all__ = ["MOVED", "new_path", "MovedFinder", "install", "old_attribute", "RENAMED", "renamed", "alias", "renamed_keywords", "renamed_keys", "warn_renamed"]

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


def new_path(fullname):
    """The new dotted path of the old path ``fullname`` (``moments_ref.raster._matrices`` ->
    ``moments_ref.scene.raster._matrices``), or None when ``fullname`` did not move.

    The longest old path of :data:`MOVED` that is ``fullname`` or a package above it decides.
    """
    if not fullname.startswith("moments_ref."):
        return None
    parts = fullname[len("moments_ref."):].split(".")
    for n in range(len(parts), 0, -1):
        new = MOVED.get(".".join(parts[:n]))
        if new is not None:
            return ".".join(["moments_ref", new] + parts[n:])
    return None


class _Alias(importlib.abc.Loader):
    """Loads an old path as the module at its new path (the same object), warning once."""

    def __init__(self, new):
        self.new = new

    def create_module(self, spec):
        return None  # a placeholder module; exec_module replaces it in sys.modules

    def exec_module(self, module):
        old = module.__name__
        target = importlib.import_module(self.new)
        sys.modules[old] = target  # the import system returns what sys.modules holds after exec_module
        warnings.warn(f"{old} moved to {self.new}; the old path will be removed in the next release",
                      DeprecationWarning, stacklevel=2)


class MovedFinder(importlib.abc.MetaPathFinder):
    """The meta-path finder of the old paths of :data:`MOVED` (no file per old path)."""

    def find_spec(self, fullname, path=None, target=None):
        new = new_path(fullname)
        if new is None:
            return None
        return importlib.machinery.ModuleSpec(fullname, _Alias(new))


def install():
    """Put one :class:`MovedFinder` first on :data:`sys.meta_path` (idempotent)."""
    if not any(isinstance(f, MovedFinder) for f in sys.meta_path):
        sys.meta_path.insert(0, MovedFinder())


def old_attribute(name):
    """The module at the old top-level path ``moments_ref.<name>`` (for the package's ``__getattr__``)."""
    if name not in MOVED or "." in name:
        raise AttributeError(f"module 'moments_ref' has no attribute {name!r}")
    return importlib.import_module(f"moments_ref.{name}")


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
