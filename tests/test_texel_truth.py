"""The golden ground truth of the texel formats and affine bases is independent and used.

``moments_ref.golden.texel_truth`` types the bit layouts and the slides' matrices again
and computes exactly; these tests check that it imports nothing it judges, that the
tables agree with the constants of the modules under test, and that the golden writer
refuses to write codes from a reference that disagrees with it.
"""

from __future__ import annotations

import ast
import dataclasses
from pathlib import Path

import numpy as np
import pytest

from moments_ref import affine, packing
from moments_ref.golden import cases as gcases, texel_codes, texel_truth as T
from moments_ref.golden.spread import TIE_BAND, TruthMismatch, derive

SOURCE = Path(T.__file__)


def test_truth_imports_neither_packing_nor_affine():
    tree = ast.parse(SOURCE.read_text(encoding="utf-8"))
    names = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            names.add(node.module or "")
            names.update(a.name for a in node.names)
        elif isinstance(node, ast.Import):
            names.update(a.name for a in node.names)
    assert not any("packing" in n or "affine" in n or n.startswith("moments_ref") for n in names), names
    assert not any(isinstance(n, ast.ImportFrom) and n.level > 0 for n in ast.walk(tree))


def test_tables_agree_with_the_modules():
    assert T.LAYOUT32 == {"y2": (packing.Y2_SHIFT, packing.Y2_BITS), "y1": (packing.Y1_SHIFT, packing.Y1_BITS),
                          "v": (packing.V_SHIFT, packing.V_BITS), "xi": (packing.XI_SHIFT, packing.XI_BITS)}
    assert T.CELLS32["v"] == packing.V_CELLS and T.CELLS32["xi"] == packing.XI_CELLS
    assert float(T.CELLS32["depth"]) == 1 / packing.DEPTH_STEP32
    for field, key in (("depth", "depth"), ("v", "v2"), ("xi", "xi")):
        assert float(T.DECODE_OFFSETS32[field]) == packing.DECODE_POSITIONS[packing.DECODE32[key]]
    def as_float(m):
        return np.array([[float(x) for x in row] for row in m.tolist()])

    np.testing.assert_allclose(as_float(T._matrix(T._OPTIMIZED)), affine.OPTIMIZED_MATRIX, rtol=0, atol=1e-16)
    np.testing.assert_array_equal(as_float(T._matrix(T._M0)), affine.SIX_MOMENT_M0)
    np.testing.assert_array_equal(as_float(T._matrix(T._M1)), affine.SIX_MOMENT_M1)


def test_the_affine_and_texel_cases_use_the_truth():
    names = ("to_optimized", "from_optimized", "encode_unorm16", "decode_unorm16", "to_optimized6",
             "encode_r10g10b10a2", "decode_r10g10b10a2", "pack64", "reencode64", "unpack64", "pack32",
             "reencode32", "unpack32")
    for dt in ("float32", "float64"):
        for n in names:
            c = gcases.CASES[f"{n}-{dt}"]
            # the encoders of the non-linear texels take texel_truth's codes vectorised (golden.texel_codes, equal to
            # texel_truth's: tests/test_texel_codes.py)
            assert c.truth is not None and c.truth.__module__ in (T.__name__, texel_codes.__name__), c.name
            assert (c.tie_neighbours is not None) == c.integer_output, c.name  # the per-component tie rule
            assert (c.margin is not None) == c.integer_output, c.name


def test_worked_example_and_decode_by_hand():
    """docs/formats.md's worked example, and its decode, from the truth alone."""
    y1, y2 = 600.5 / 511.5 - 1, 900.5 / 511.5 - 1
    p = T.pack32(np.array([[y1, y2, (5.5 / 128) ** 2, 1e-3]]))[0]
    assert int(p[0]) & ((1 << 26) - 1) == 0x02E_9C7A  # ỹ2 = 122, ỹ1 = 423 (folded), √v2 code 5
    r = T.unpack32(np.array([0x242E_9C7A], np.uint32))[0][0]
    np.testing.assert_allclose(r[:3], [601 / 511.5 - 1, 901 / 511.5 - 1, (5.5 / 128) ** 2], rtol=1e-15, atol=0)


def _with_reference(case, fn):
    return dataclasses.replace(case, reference=fn)


@pytest.mark.parametrize("name,mutant", [
    ("pack32-float32", lambda r: packing.pack32(r) & ~np.uint32(0x7F << 19)
     | (np.rint(np.sqrt(np.clip(np.asarray(r)[..., 2], 0, 1)) * 127).astype(np.uint32) << 19)),
    ("pack64-float32", lambda r: packing.pack64(r, xi_rounding="nearest")),
    ("encode_unorm16-float32", lambda b: affine.float_to_unorm(affine.to_optimized(b) * np.float32(0.9999), 16)),
])
def test_writer_refuses_a_reference_that_disagrees_with_the_truth(name, mutant):
    """A broken reference cannot hide behind the tie rule: its codes differ from the truth off the boundaries."""
    case = _with_reference(gcases.CASES[name], lambda *a, **k: (mutant(*a, **k),))
    inputs, category, comment, flags = gcases.case_table(case)
    with pytest.raises(TruthMismatch, match=name):
        derive(case, inputs, category, comment, flags)
    # The unchanged reference writes, with its few ties all near a rounding boundary.
    inputs, category, comment, flags = gcases.case_table(gcases.CASES[name])
    arrays = derive(gcases.CASES[name], inputs, category, comment, flags)
    tie = np.char.find(arrays["flags"].astype(str), "rounding_tie") >= 0
    if gcases.CASES[name].function in texel_codes.DERIVED_BAND:  # a component within its own derived tie band
        layout = "64" if "64" in name else "32"
        _, margins, _ = getattr(texel_codes, f"pack{layout}_ties")(inputs["r"])
        near = (margins <= getattr(texel_codes, f"pack{layout}_tie_band")(inputs["r"])).any(axis=1)
        assert tie.any() and np.all(near[tie])
        return
    margin = gcases.CASES[name].margin(**inputs)
    assert tie.sum() < 0.25 * len(tie) and np.all(margin[tie] <= TIE_BAND)
