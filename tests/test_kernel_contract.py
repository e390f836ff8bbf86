"""The kernel contract (conformance.kernel.contract) against its own tables, without a driver:
the uniform block's bytes at the documented std140 offsets, dispatches that cover every block
or view exactly once, and the work-group rules of each case."""

import numpy as np
import pytest

from moments_ref import InputError
from moments_ref.conformance.kernel.contract import (BLOCK, MAX_VIEWS, OUTPUT_FORMATS, PARAMS, PARAMS_BYTES, THREADS,
                                                     contract, dispatches, params_block)


def _member(block, name):
    """A member of the uniform block read back at its documented offset (std140: vec4 = 16 bytes)."""
    (_, typ, off, _), = [p for p in PARAMS if p[0] == name]
    dt = {"uvec4": np.uint32, "ivec4": np.int32, "vec4": np.float32}.get(typ, np.float32)
    n = 4 if typ.endswith("4") else 16 * MAX_VIEWS
    return np.frombuffer(block, dt, count=n, offset=off)


def test_the_uniform_block_holds_each_member_at_its_offset():
    views = np.arange(2 * 16, dtype=np.float32).reshape(2, 4, 4)
    b = params_block((7, 5, 4, 2), (-32, 24, 3, 9), (1000, 0, 0, 0), 6e-5, (0.0, 0.628, 0.0, 0.628), views)
    assert len(b) == PARAMS_BYTES == 80 + 64 * MAX_VIEWS
    assert _member(b, "size").tolist() == [7, 5, 4, 2]
    assert _member(b, "origin").tolist() == [-32, 24, 3, 9]
    assert _member(b, "count").tolist() == [1000, 0, 0, 0]
    np.testing.assert_array_equal(_member(b, "bias"), np.float32([6e-5, 0, 0, 0]))
    np.testing.assert_array_equal(_member(b, "bias_target"), np.float32([0.0, 0.628, 0.0, 0.628]))
    m = _member(b, "view").reshape(MAX_VIEWS, 4, 4)  # column-major: m[k, c] is column c of view k
    np.testing.assert_array_equal(m[:2].transpose(0, 2, 1), views)
    assert not m[2:].any()
    assert params_block() == bytes(PARAMS_BYTES)


@pytest.mark.parametrize("h, w", [(24, 32), (48, 96), (50, 70), (1, 1), (25, 33), (72, 160)])
def test_filter_dispatches_cover_every_block_once(h, w):
    kw = {"height": h, "width": w, "samples": 4, "bias": {"alpha": 3e-7, "target": [0, 0.375, 0, 0.375]}}
    ds = dispatches("kernel-filter-nlq64", kw)
    covered = []
    bx = -(-w // BLOCK[0])
    for d in ds:
        assert d.groups[1:] == (1, 1) and d.blocks == d.groups[0]
        assert _member(d.params, "size").tolist() == [w, h, 4, 0]
        np.testing.assert_array_equal(_member(d.params, "bias"), np.float32([3e-7, 0, 0, 0]))
        ox, oy = _member(d.params, "origin")[:2]
        assert ox % BLOCK[0] == 0 and oy % BLOCK[1] == 0
        covered += [(oy // BLOCK[1], ox // BLOCK[0] + g) for g in range(d.groups[0])]
    want = [(r, c) for r in range(-(-h // BLOCK[1])) for c in range(bx)]
    assert sorted(covered) == want  # each block once, none beyond the map
    # tiles of half the grid's width: a kernel ignoring the origin writes the wrong blocks
    assert max(d.groups[0] for d in ds) == -(-bx // 2)
    for d in ds:  # members the filter does not use are zero
        assert _member(d.params, "origin")[2:].tolist() == [0, 0] and not _member(d.params, "count").any()
        np.testing.assert_array_equal(_member(d.params, "bias_target"), np.float32([0, 0.375, 0, 0.375]))
    # no bias in the case: alpha 0 and a zero target
    plain = dispatches("kernel-filter-nlq64", {"height": h, "width": w, "samples": 4})
    assert all(not _member(d.params, "bias").any() and not _member(d.params, "bias_target").any() for d in plain)


@pytest.mark.parametrize("views, per", [(8, 8), (9, 4), (32, 5), (1, 3)])
@pytest.mark.parametrize("local_x", [1, 64, 100])
def test_vwss_dispatches_cover_every_view_once(views, per, local_x):
    kw = {"views": views, "height": 16, "width": 20, "points": 1000, "views_per_dispatch": per}
    ds = dispatches("kernel-vwss-points", kw, local_x=local_x)
    seen = []
    for d in ds:
        first, count = _member(d.params, "origin")[2:]
        assert d.blocks == count and 1 <= count <= per
        seen += list(range(first, first + count))
        assert d.groups == (-(-1000 // local_x), 1, 1) and d.groups[0] * local_x >= 1000
        assert _member(d.params, "size").tolist() == [20, 16, 0, views]
        assert _member(d.params, "count").tolist() == [1000, 0, 0, 0]
        assert _member(d.params, "origin")[:2].tolist() == [0, 0]
    assert seen == list(range(views))


def test_each_case_binds_its_slots_and_checks_its_work_groups():
    for fmt, (image, element) in OUTPUT_FORMATS.items():
        c = contract(f"kernel-filter-{fmt}")
        assert [s.binding for s in c.slots] == [0, 1, 2]
        assert c.output.name == ("moments" if fmt == "moments" else "texels") and c.output.format == image
        assert c.input.name == "depth" and c.slot("params").role == "params"
        for size in [(THREADS, 1, 1), (16, 16, 1), (8, 8, 4)]:
            c.check_workgroup(size, "k")
        for size in [(THREADS // 2, 1, 1), (16, 16, 2), (1, 1, 1)]:
            with pytest.raises(InputError, match="256 threads"):
                c.check_workgroup(size, "k")
        assert "32×24 output block" in c.workgroup_note
    v = contract("kernel-vwss-points")
    assert v.input.name == "points" and v.output.name == "depth" and [s.binding for s in v.slots] == [0, 1, 2]
    for size in [(1, 1, 1), (64, 1, 1), (100, 1, 1)]:
        v.check_workgroup(size, "k")
    for size in [(8, 8, 1), (64, 1, 2)]:
        with pytest.raises(InputError, match="N×1×1"):
            v.check_workgroup(size, "k")
    assert "multisampled" in contract("kernel-filter-nlq32").input.describe()
    for bad in ["kernel-filter-nlq16", "filter-nlq64", "kernel-vwss", "nlq64", ""]:
        with pytest.raises(InputError, match="not a kernel case"):
            contract(bad)
