"""Shared-memory layout and bank-conflict simulator of HPG17 §4.1 / Figure 6."""

import dataclasses
import itertools

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from moments_ref import InputError
from moments_ref.gpu import banks

CELLS = list(itertools.product(range(1, 5), range(40), range(32)))  # (j, x, y)


def paper_index(j, x, y):
    """HPG17 §4.1, typed again from the paper: (40·32+7)(j−1) + 40y + ⌊y/4⌋ + (2x | 2x−39)."""
    return (40 * 32 + 7) * (j - 1) + 40 * y + y // 4 + (2 * x if x < 20 else 2 * x - 39)


def row_major_index(j, x, y):
    return 40 * 32 * (j - 1) + 40 * y + x


# ---------------------------------------------------------------- layout


def test_paper_layout_is_injective_and_fits():
    idx = [int(banks.shared_index(j, x, y)) for j, x, y in CELLS]
    assert idx == [paper_index(j, x, y) for j, x, y in CELLS]
    assert len(set(idx)) == 4 * 40 * 32
    assert min(idx) >= 0 and max(idx) < 4 * (40 * 32 + 7) == banks.SHARED_WORDS
    # The 4·(40·32 + 7) words are exactly what the last index needs.
    assert max(idx) + 1 == banks.SHARED_WORDS


def test_paper_layout_parity_swaps_every_four_rows():
    # "the left 20 moments use all even indices and the right 20 ... odd indices.
    # After four consecutive rows, there is one empty array entry to swap".
    for y in range(32):
        left = {paper_index(1, x, y) % 2 for x in range(20)}
        right = {paper_index(1, x, y) % 2 for x in range(20, 40)}
        assert len(left) == len(right) == 1 and left != right
        assert left == {(y // 4) % 2}


def test_row_major_layout_is_injective():
    idx = banks.shared_index(*np.array(CELLS).T, layout="row-major")
    assert np.array_equal(idx, [row_major_index(*c) for c in CELLS])
    assert len(np.unique(idx)) == len(CELLS) and idx.max() < banks.layout_words("row-major")


def test_shared_index_rejects_bad_cells():
    with pytest.raises(InputError, match="x"):
        banks.shared_index(1, [0, 40], 0)
    with pytest.raises(InputError, match="j"):
        banks.shared_index(0, 0, 0)
    with pytest.raises(InputError, match="layout"):
        banks.shared_index(1, 0, 0, layout="z-order")
    with pytest.raises(InputError, match="layout"):
        banks.simulate("z-order")


# ---------------------------------------------------------------- conflict counter


def brute_conflicts(addresses):
    """Extra transactions of one warp instruction, by the definition, with sets."""
    per_bank = {}
    for a in addresses:
        per_bank.setdefault(int(a) % 32, set()).add(int(a))
    return max(len(s) for s in per_bank.values()) - 1


@given(st.lists(st.integers(0, 300), min_size=32, max_size=32))
def test_conflicts_matches_definition(addresses):
    assert int(banks.conflicts(np.array(addresses))) == brute_conflicts(addresses)


def test_conflicts_extremes():
    assert banks.conflicts(np.full(32, 7)) == 0  # broadcast
    assert banks.conflicts(np.arange(32)) == 0
    assert banks.conflicts(32 * np.arange(32)) == 31  # 32 words in bank 0
    assert banks.conflicts(np.repeat(32 * np.arange(2), 16)) == 1
    assert np.array_equal(banks.conflicts(np.stack([np.arange(32), 64 * np.arange(32)])), [0, 31])
    with pytest.raises(InputError):
        banks.conflicts(np.arange(31))


# ---------------------------------------------------------------- independent replay


def independent_schedule(index):
    """Every warp instruction of every phase, derived again from HPG17 §4.1 with plain loops.

    Returns phase -> list of 32-address lists. Written without the module's
    arrays: each loop is the sentence of the paper it implements.
    """
    sched = {p: [] for p in banks.PHASES}
    for warp in range(8):
        # Resolve: 5 rounds, each warp one column at a time, lane = row.
        for rnd in range(5):
            column = 8 * rnd + warp
            for j in range(1, 5):
                sched["resolve"].append([index(j, column, lane) for lane in range(32)])
        # Horizontal: moment and half per warp; lane = row; 24 loads, 16 stores.
        j, half = warp % 4 + 1, warp // 4
        first_read = 0 if half == 0 else 16
        first_write = 0 if half == 0 else 24
        for k in range(24):
            sched["horizontal read"].append([index(j, first_read + k, lane) for lane in range(32)])
        for k in range(16):
            sched["horizontal write"].append([index(j, first_write + k, lane) for lane in range(32)])
        # Vertical: strip of 16 columns; lanes 0..15 upper half, 16..31 lower half.
        for k in range(20):
            sched["vertical read"].append(
                [index(j, first_write + c, k) for c in range(16)]
                + [index(j, first_write + c, 12 + k) for c in range(16)]
            )
        for k in range(12):
            sched["vertical write"].append(
                [index(j, first_write + c, 4 + k) for c in range(16)]
                + [index(j, first_write + c, 16 + k) for c in range(16)]
            )
        # Readout: one output row at a time, three rows per warp; lane = output column.
        for row in (warp, warp + 8, warp + 16):
            for j in range(1, 5):
                cells = [(u if u < 16 else u + 8, row + 4) for u in range(32)]
                sched["readout"].append([index(j, x, y) for x, y in cells])
    return sched


@pytest.mark.parametrize("layout,index", [("paper", paper_index), ("row-major", row_major_index)])
def test_simulate_matches_brute_force_replay(layout, index):
    expected = {p: sum(brute_conflicts(i) for i in instr) for p, instr in independent_schedule(index).items()}
    assert banks.simulate(layout) == expected


def test_module_schedule_equals_independent_schedule():
    # Same instructions as multisets per phase (the order of warps is a free choice).
    ours = independent_schedule(paper_index)
    pattern = banks.access_pattern()
    for name, phase in pattern.items():
        addr = banks.shared_index(phase.j, phase.x, phase.y).reshape(-1, 32)
        assert sorted(map(tuple, addr.tolist())) == sorted(map(tuple, ours[name]))


def test_paper_layout_is_conflict_free_and_row_major_is_not():
    paper = banks.simulate("paper")
    naive = banks.simulate("row-major")
    assert set(paper) == set(naive) == set(banks.PHASES)
    assert all(v == 0 for v in paper.values())
    assert all(v > 0 for v in naive.values())
    # A column access in row-major hits 4 banks only (40 ≡ 8 mod 32): 8-way, 7 extra.
    assert naive["resolve"] == 7 * 5 * 4 * 8


def test_mutant_layout_without_padding_word_conflicts():
    # Drop the ⌊y/4⌋ padding: columns collapse onto 4 banks again.
    pattern = banks.access_pattern()
    for name in ("resolve", "horizontal read", "vertical read"):
        p = pattern[name]
        addr = banks.shared_index(p.j, p.x, p.y) - p.y // 4
        assert banks.conflicts(addr).sum() > 0, name


def test_mutant_pattern_rows_eight_apart_conflicts():
    # The vertical pass is conflict-free because its two rows are 12 apart (3
    # padding words between them: opposite parity); rows 8 apart are 2 padding
    # words apart, same parity, and collide.
    p = banks.access_pattern()["vertical read"]
    moved = dataclasses.replace(p, y=np.where(np.arange(32) >= 16, p.y - 4, p.y))
    assert banks.conflicts(banks.shared_index(moved.j, moved.x, moved.y)).sum() > 0


# ---------------------------------------------------------------- coverage of the pattern


def cells_of(phase):
    return sorted(zip(phase.j.ravel().tolist(), phase.x.ravel().tolist(), phase.y.ravel().tolist()))


def test_resolve_writes_every_cell_once_and_readout_reads_the_output_block():
    pattern = banks.access_pattern()
    assert cells_of(pattern["resolve"]) == sorted(CELLS)
    out_cells = sorted(
        (j, x, y) for j in range(1, 5) for x in list(range(16)) + list(range(24, 40)) for y in range(4, 28)
    )
    assert cells_of(pattern["readout"]) == out_cells
    ro = pattern["readout"]
    texels = sorted(zip(ro.texel_x[:, 0].ravel().tolist(), ro.texel_y[:, 0].ravel().tolist()))
    assert texels == sorted((u, v) for u in range(32) for v in range(24))


def test_middle_columns_are_read_only_and_writes_are_disjoint_between_warps():
    pattern = banks.access_pattern()
    hw = pattern["horizontal write"]
    assert not np.isin(hw.x, np.arange(16, 24)).any()
    for name in ("horizontal write", "vertical write"):
        p = pattern[name]
        cells = cells_of(p)
        assert len(set(cells)) == len(cells), name
    # A warp never reads a cell that another warp writes in the same pass.
    for rd, wr in (("horizontal read", "horizontal write"), ("vertical read", "vertical write")):
        r, w = pattern[rd], pattern[wr]
        for a in range(8):
            for b in range(8):
                if a == b:
                    continue
                read = set(zip(r.j[a].ravel(), r.x[a].ravel(), r.y[a].ravel()))
                written = set(zip(w.j[b].ravel(), w.x[b].ravel(), w.y[b].ravel()))
                assert not read & written, (rd, a, b)


def test_main_prints_both_layouts():
    text = banks.main()
    assert "paper" in text and "row-major" in text
    naive = banks.simulate("row-major")
    for name in banks.PHASES:
        line = next(line for line in text.splitlines() if line.startswith(name + " "))
        assert line.split()[-2:] == ["0", str(naive[name])]
