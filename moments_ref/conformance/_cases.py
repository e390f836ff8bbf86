"""Golden cases read from disk (sha256 checked) or generated on the fly."""

from __future__ import annotations

import hashlib
import json
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .._arrays import InputError

__all__ = ["GoldenCase", "load_case"]


@dataclass
class GoldenCase:
    """One golden case read from disk: manifest entry and arrays."""

    name: str
    meta: dict
    arrays: dict
    source: str  # the folder, or "generated"

    @property
    def inputs(self):
        return {k: self.arrays[k] for k in self.meta["inputs"]}

    @property
    def category(self):
        return self.arrays["category"]

    def output_specs(self):
        """``{output: (dtype, shape)}`` a port writes: float32 for float outputs."""
        exact = self.meta["exact"]
        return {o: (self.arrays[o].dtype if exact else np.float32, self.arrays[o].shape)
                for o in self.meta["compare"]}


def load_case(case, golden_dir=None):
    """Read ``case`` from ``golden_dir`` (checking its sha256), or generate it.

    Without ``golden_dir`` the case alone is written to a temporary folder with
    :func:`moments_ref.golden.write` and read back.
    """
    from .. import golden

    if golden_dir is None:
        if case not in golden.CASES:
            raise InputError(f"case: unknown case {case!r}; known: {', '.join(golden.CASES)}")
        with tempfile.TemporaryDirectory(prefix="moments-ref-golden-") as tmp:
            golden.write(tmp, [case])
            loaded = load_case(case, tmp)
        loaded.source = "generated"
        return loaded
    golden_dir = Path(golden_dir)
    mpath = golden_dir / "manifest.json"
    if not mpath.is_file():
        raise InputError(f"golden: expected a folder with manifest.json, got {str(golden_dir)!r}")
    manifest = json.loads(mpath.read_text())
    if case not in manifest["cases"]:
        raise InputError(f"case: {case!r} is not in {mpath}; it has: {', '.join(manifest['cases'])}")
    meta = manifest["cases"][case]
    path = golden_dir / meta["file"]
    if not path.is_file() or path.resolve().parent != golden_dir.resolve():
        raise InputError(f"golden: {meta['file']!r} is not a regular file inside {str(golden_dir)!r}")
    blob = path.read_bytes()
    if hashlib.sha256(blob).hexdigest() != meta["sha256"]:
        raise InputError(f"golden: {meta['file']} does not match the sha256 in {mpath}")
    with np.load(path, allow_pickle=False) as g:
        arrays = {k: g[k] for k in g.files}
    return GoldenCase(case, meta, arrays, str(golden_dir))
