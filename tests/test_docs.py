"""docs/api.md lists every public name; the generated docs are what their generators write."""

import importlib
import pkgutil
from pathlib import Path

import moments_ref
from moments_ref import _apidoc

ROOT = Path(__file__).resolve().parents[1]


def test_api_doc_is_current():
    assert (ROOT / "docs" / "api.md").read_text().strip() == _apidoc.render().strip(), \
        "regenerate: python -m moments_ref._apidoc > docs/api.md"


def test_every_public_module_is_documented():
    documented = set(_apidoc.MODULES)
    for m in pkgutil.walk_packages(moments_ref.__path__, "moments_ref."):
        name = m.name.removeprefix("moments_ref.")
        if any(part.startswith("_") for part in name.split(".")) or m.ispkg and name in ("ports", "vwss"):
            continue
        mod = importlib.import_module(m.name)
        if name in ("cli", "ports", "scene.camera", "scene.files", "scene.lights", "scene.mesh") or \
                name.startswith("techniques.") and name not in documented:
            continue  # the CLI; scene and technique internals re-exported by their package
        assert name in documented, f"moments_ref.{name} is missing from docs/api.md (_apidoc.MODULES)"
        assert hasattr(mod, "__all__"), f"moments_ref.{name} has no __all__"


def test_design_table_names_are_exported():
    for name in ("power_moments", "hankel", "bias_moments", "BIAS_FLOAT32", "BIAS_UNORM16", "shadow_intensity",
                 "canonical_representation", "to_optimized", "from_optimized", "encode_unorm16", "decode_unorm16",
                 "phi", "phi_inverse", "psi4", "psi4_inverse", "shade", "pack64", "unpack64", "pack32", "unpack32"):
        assert name in moments_ref.__all__
    from moments_ref import golden, oracle

    assert callable(golden.write) and callable(golden.verify) and callable(oracle.check)
