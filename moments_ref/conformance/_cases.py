"""Golden cases read from disk or generated on the fly, both through the one strict loader.

A golden folder is read by :mod:`moments_ref.golden.loader`, the reader of
``verify`` and ``oracle``: schema version, types and ranges of the manifest,
sizes before decompressing, sha256, finite tolerances. A generated case is
written to a temporary folder and read back the same way.
"""

from __future__ import annotations

import tempfile
from dataclasses import dataclass

import numpy as np

from .._arrays import InputError
from ..golden.loader import load_case as _load_checked

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
        # The argument order (the manifest's ``inputs`` table is sorted by name).
        return {k: self.arrays[k] for k in self.meta.get("input_order", self.meta["inputs"])}

    @property
    def category(self):
        return self.arrays["category"]

    def output_specs(self):
        """``{output: (dtype, shape)}`` a port writes: float32 for float outputs."""
        exact = self.meta["exact"]
        return {o: (self.arrays[o].dtype if exact else np.float32, self.arrays[o].shape)
                for o in self.meta["compare"]}


def load_case(case, golden_dir=None):
    """Read ``case`` from ``golden_dir`` (:func:`moments_ref.golden.loader.load_case`), or generate it.

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
    meta, arrays = _load_checked(golden_dir, case)
    return GoldenCase(case, meta, arrays, str(golden_dir))
