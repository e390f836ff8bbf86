"""The package's layers, read from its folders: the one definition the docs and the tests use.

Every folder below ``moments_ref`` is a layer or a leaf of the same name; the
flat modules at the top (the stable core and what everything shares) are named in
:data:`FLAT`. Dependencies point down :data:`ORDER`; leaves (:data:`LEAF_FOLDERS`,
:data:`LEAF_MODULES`) import what they measure from any layer and are imported by
nothing but other leaves and the command line. The old paths of moved modules
(:data:`moments_ref._shim.MOVED`) have no file: an import hook serves them, outside the layers.

``python -m moments_ref.tools.apidoc --layout`` prints the table of
docs/architecture.md from :func:`layout_rows` (the README links to it).
"""

from __future__ import annotations

from pathlib import Path

from .._shim import MOVED

__all__ = ["ROOT", "ORDER", "FLAT", "FOLDERS", "LEAF_FOLDERS", "LEAF_MODULES", "TOP", "layer_of", "is_shim",
           "module_names", "layout_rows"]

ROOT = Path(__file__).resolve().parents[1]

#: Layers, bottom first.
ORDER = ("base", "core", "gpu", "scene", "techniques", "pipeline", "report", "api")
#: Folders that are layers (folder name = layer name) or hold package data of a layer.
FOLDERS = {"gpu": "gpu", "scene": "scene", "techniques": "techniques", "pipeline": "pipeline", "report": "report",
           "ports": "api"}
#: Folders of leaves: they import what they measure.
LEAF_FOLDERS = ("golden", "conformance", "sweep", "tools")
#: Flat leaf modules.
LEAF_MODULES = ("oracle",)
#: The command line, on top of everything.
TOP = ("cli", "__main__")
#: The flat modules at the top of the package and their layer.
FLAT = {
    "_arrays": "base", "_io": "base", "_toml": "base", "_shim": "base", "_docs": "base", "_options": "base",
    "_panels": "base",  # image panels of the report's figures in one matplotlib Axes
    "claims": "base",  # the Claim record: techniques and report both write claims
    "_kernels": "core", "_msm6_rows": "core", "_msm6_bound": "core", "moments": "core", "msm": "core", "msm6": "core", "hausdorff": "core", "affine": "core",
    "nonlinear": "core", "packing": "core", "precise": "core",
    "metrics": "scene",  # image metrics over a G-buffer's pixels: techniques use them
    "__init__": "api",
}


def is_shim(name):
    """True for the old path of a moved module (``filtering``, ``vwss.shading``, ...)."""
    return name in MOVED


def layer_of(name):
    """The layer of module ``name`` (``gpu.onchip``, ``msm``): a layer of :data:`ORDER`, ``leaf`` or ``cli``.

    Raises :class:`KeyError` for a module in no layer (a new flat module or folder must be placed).
    """
    top = name.split(".")[0]
    if is_shim(name):
        return "shim"
    if top in TOP:
        return "cli"
    if top in LEAF_FOLDERS or top in LEAF_MODULES:
        return "leaf"
    if top in FLAT and "." not in name:
        return FLAT[top]
    if top in FOLDERS:
        return FOLDERS[top]
    raise KeyError(f"module moments_ref.{name} is in no layer: add its folder or flat module to "
                   "moments_ref/tools/layout.py")


def module_names(root=None):
    """Every module below ``root`` (default: the package) as a dotted name (a package's ``__init__`` is the package)."""
    root = Path(root or ROOT)
    out = []
    for p in sorted(root.rglob("*.py")):
        parts = list(p.relative_to(root).with_suffix("").parts)
        if parts[-1] == "__init__" and len(parts) > 1:
            parts = parts[:-1]
        out.append(".".join(parts))
    return out


def _summary(path):
    import ast

    doc = ast.get_docstring(ast.parse(path.read_text(encoding="utf-8"))) or ""
    return doc.split("\n\n")[0].replace("\n", " ").strip()


def layout_rows(root=None):
    """``[(layer, path, summary)]``: each folder and each flat module, in layer order (leaves, then the CLI)."""
    root = Path(root or ROOT)
    rows = []
    for p in sorted(root.iterdir()):
        name = p.stem if p.suffix == ".py" else p.name
        if name.startswith("__pycache__") or is_shim(name) or not (p.suffix == ".py" or (p / "__init__.py").is_file()):
            continue
        if name == "__main__":
            continue
        layer = layer_of(name)
        path = f"moments_ref/{p.name}" + ("/" if p.is_dir() else "")
        rows.append((layer, path, _summary(p / "__init__.py" if p.is_dir() else p)))
    rank = {k: i for i, k in enumerate(ORDER + ("leaf", "cli"))}
    return sorted(rows, key=lambda r: (rank[r[0]], r[1]))
