"""Shared-memory layout and bank-conflict simulator of the HPG17 compute shader (Figure 6).

The on-chip filter of HPG17 §4.1 keeps the moments of one 40×32 input block in a
flat array of 4-byte words in shared memory. A warp of 32 threads issues each
shared-memory instruction for all its lanes at once; the memory has 32 banks and
word ``a`` lives in bank ``a mod 32``. Lanes hitting *different* words of one bank
are served one after the other (a bank conflict); lanes hitting the *same* word are
served by one broadcast. HPG17 §4.1, "Memory layout", stores moment ``b_j`` of
block cell ``(x, y)`` at

    (40·32 + 7)·(j − 1) + 40·y + ⌊y/4⌋ + (2·x if x < 20 else 2·x − 39)

and states that an offline simulation found no conflict in any phase. This module
is that simulation: :func:`access_pattern` writes down which cell every lane of
every warp touches in every phase, :func:`simulate` replays the instructions
against a layout and counts conflicts. :mod:`moments_ref.gpu.onchip` runs its emulation
from the same access pattern, so the accesses counted here are exactly the ones
the emulation performs (and an access pattern that misplaced a value would make
the emulation disagree with the reference blur).

Block coordinates: ``x ∈ 0..39`` runs to the right, ``y ∈ 0..31`` downwards; the
32×24 output texels of a block are the input cells ``x ∈ 4..35, y ∈ 4..27`` (a
guard band of 4 cells on every side, HPG17 §4.1 "Resolve").

Access pattern derived from HPG17 §4.1 and the caption of Figure 6
-------------------------------------------------------------------
256 threads = 8 warps ``w ∈ 0..7`` of 32 lanes ``l ∈ 0..31``. All lanes of one
instruction touch the same moment ``j``. Where the text leaves a choice open (the
order of warps over workloads, the stride of a loop, where the vertical pass puts
its results) this module fixes one and says so. The order of warps and the loop
strides change no conflict count in any layout, because the multiset of warp-wide
instructions stays the same; writing the vertical results to rows 0..23 instead
of in place would keep every instruction's two rows 12 apart, so the paper layout
stays conflict-free with that choice too.

``resolve``  (writes; Figure 6a) 5 rounds ``r ∈ 0..4``; in round ``r`` warp ``w``
    handles column ``x = 8·r + w`` (loop stride 8 over the 40 columns) and lane
    ``l`` the texel in row ``y = l``: it averages the moments of all samples and
    issues 4 writes, one per moment ``j``. 5·4 instructions per warp.
``horizontal read``  (Figure 6b) warp ``w`` blurs moment ``j = w mod 4 + 1`` in half
    ``h = w div 4`` (left ``h = 0``, right ``h = 1``); lane ``l`` owns row ``y = l``
    and loads the 24 consecutive cells ``x = 16·h + k``, ``k ∈ 0..23`` (left: columns
    0..23, right: 16..39), one instruction per ``k``, so each instruction reads one
    complete column. 24 instructions per warp.
``horizontal write``  the 16 results, centred on columns ``16·h + k + 4`` (left
    4..19, right 20..35), go to the part of the row that is not read only:
    ``x = 24·h + k``, ``k ∈ 0..15`` (left columns 0..15, right 24..39). The 8 middle
    columns 16..23 are only read, so the left and right warps of one moment never
    race. 16 instructions per warp.
``vertical read``  (Figure 6c) warp ``w`` keeps its moment and half and now blurs
    the 16×32 strip of columns ``24·h + c``, ``c ∈ 0..15``. Lane ``l`` takes column
    ``c = l mod 16``; lanes 0..15 take the upper half (rows 0..19), lanes 16..31 the
    lower half (rows 12..31). Instruction ``k ∈ 0..19`` reads row ``k`` (upper lanes)
    and row ``12 + k`` (lower lanes): two rows 12 apart. 20 instructions per warp.
``vertical write``  the 12 results of a lane are centred on rows ``4 + 12·v + k``
    (``v`` = 0 upper, 1 lower, ``k ∈ 0..11``) and are written back in place into the
    source strip: upper lanes rows 4..15, lower lanes rows 16..27, again two rows 12
    apart per instruction. (Within one warp all 20 loads precede the writes; this is
    the read/write hazard for which §4.1 needs an extra barrier on narrower warps.)
    12 instructions per warp.
``readout``  (Figure 6d) warp ``w`` reads output rows ``v = w + 8·i``, ``i ∈ 0..2``
    (loop stride 8 over the 24 rows), one row at a time: lane ``l`` is output column
    ``u = l`` and reads the complete vector (4 instructions, one per ``j``) at cell
    ``x = u`` if ``u < 16`` else ``u + 8``, ``y = v + 4``. Each thread thus reads three
    vectors. 3·4 instructions per warp.

The per-phase counts are per block; every block of the shadow map repeats them.

The shipped compute shaders (``moments_ref/ports/*/hpg17_filter.*``) perform exactly
these accesses: ``moments-ref conformance --kernel`` runs them with every shared-memory
access of a work group recorded in program order, and the suite checks that the trace
is this access pattern through :func:`shared_index` and that the conflicts counted on
the trace are the ones :func:`simulate` gives (tests/test_kernel_conformance.py), so the
"0 conflicts" of the paper layout refers to the shipped code.

References
----------
.. [1] HPG17: Christoph Peters. 2017. *Non-Linearly Quantized Moment Shadow Maps*. In Proceedings
       of High Performance Graphics (HPG '17). ACM. The non-linear quantization Φ, Ψ4, Algorithms
       1–3, the texel formats and the compute shader of §4.1.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._arrays import InputError

__all__ = [
    "WARP_SIZE",
    "N_BANKS",
    "N_WARPS",
    "BLOCK_IN",
    "BLOCK_OUT",
    "GUARD",
    "MOMENT_STRIDE",
    "SHARED_WORDS",
    "LAYOUTS",
    "PHASES",
    "Phase",
    "shared_index",
    "access_pattern",
    "conflicts",
    "layout_words",
    "simulate",
    "table",
    "main",
]

WARP_SIZE = 32
N_BANKS = 32
N_WARPS = 8
#: Input block with guard band, (width, height) in texels.
BLOCK_IN = (40, 32)
#: Output block, (width, height) in texels.
BLOCK_OUT = (32, 24)
#: Guard band on each side (half the 9-tap filter).
GUARD = 4
#: Words between the blocks of two consecutive moments in the paper layout.
MOMENT_STRIDE = 40 * 32 + 7
#: Words of shared memory used by the paper layout (4 moments, 7 padding words each).
SHARED_WORDS = 4 * MOMENT_STRIDE

LAYOUTS = ("paper", "row-major")
PHASES = (
    "resolve",
    "horizontal read",
    "horizontal write",
    "vertical read",
    "vertical write",
    "readout",
)


def shared_index(j, x, y, layout="paper"):
    """Word index in shared memory of moment ``b_j`` at block cell ``(x, y)``.

    Parameters
    ----------
    j : int array_like
        Moment index, 1..4.
    x, y : int array_like
        Cell in the 40×32 input block, ``x ∈ 0..39``, ``y ∈ 0..31``; broadcast
        with ``j``.
    layout : {"paper", "row-major"}
        ``"paper"``: HPG17 §4.1, ``(40·32 + 7)(j − 1) + 40y + ⌊y/4⌋ + (2x if x < 20
        else 2x − 39)``: left 20 moments of a row on even words, right 20 on odd
        words, one padding word after every 4 rows to swap parities.
        ``"row-major"``: the naive ``40·32·(j − 1) + 40y + x``, for comparison.

    Returns
    -------
    index : int64 array, broadcast shape of the inputs
    """
    j = np.asarray(j, dtype=np.int64)
    x = np.asarray(x, dtype=np.int64)
    y = np.asarray(y, dtype=np.int64)
    for name, arr, lo, hi in (("j", j, 1, 4), ("x", x, 0, 39), ("y", y, 0, 31)):
        bad = (arr < lo) | (arr > hi)
        if bad.any():
            idx = tuple(int(i) for i in np.argwhere(bad)[0]) if arr.ndim else ()
            raise InputError(f"{name}: expected integers in {lo}..{hi}, got {arr[idx]!r} at index {idx}")
    if layout == "paper":
        column = np.where(x < 20, 2 * x, 2 * x - 39)
        return MOMENT_STRIDE * (j - 1) + 40 * y + y // 4 + column
    if layout == "row-major":
        return 40 * 32 * (j - 1) + 40 * y + x
    raise InputError(f"layout: expected one of {LAYOUTS}, got {layout!r}")


def layout_words(layout="paper") -> int:
    """Number of 4-byte words a layout needs for the 4 moment blocks."""
    if layout == "paper":
        return SHARED_WORDS
    if layout == "row-major":
        return 4 * 40 * 32
    raise InputError(f"layout: expected one of {LAYOUTS}, got {layout!r}")


@dataclass(frozen=True)
class Phase:
    """The cells one phase of the compute shader touches.

    ``j``, ``x``, ``y`` are int arrays of one shape whose last axis (length 32) is
    the lane of a warp; every index over the leading axes is one warp-wide
    shared-memory instruction. ``texel_x``, ``texel_y`` (same shape), where given,
    name the texel a lane handles: relative to the input block origin for the
    resolve, relative to the output block origin for the readout.
    """

    name: str
    kind: str  # "read" or "write"
    j: np.ndarray
    x: np.ndarray
    y: np.ndarray
    texel_x: np.ndarray | None = None
    texel_y: np.ndarray | None = None

    def instructions(self) -> int:
        return int(np.prod(self.j.shape[:-1]))


def _grid(*shape):
    return np.indices(shape, dtype=np.int64)


def access_pattern() -> dict[str, Phase]:
    """Every lane's cell in every phase of the HPG17 §4.1 shader (see module docstring).

    Returns
    -------
    pattern : dict str -> Phase
        Keys are :data:`PHASES`. Leading axes: resolve ``(round 5, moment 4,
        warp 8)``; horizontal read ``(warp 8, k 24)``; horizontal write ``(warp 8,
        k 16)``; vertical read ``(warp 8, k 20)``; vertical write ``(warp 8, k 12)``;
        readout ``(row i 3, moment 4, warp 8)``; then the lane axis of 32.
    """
    pattern = {}

    # Resolve: round r, moment j, warp w writes column 8r + w, lane l is row l.
    r, jm, w, lane = _grid(5, 4, N_WARPS, WARP_SIZE)
    x = 8 * r + w
    pattern["resolve"] = Phase("resolve", "write", jm + 1, x, lane, texel_x=x, texel_y=lane)

    # Horizontal blur: warp w -> moment w mod 4 + 1, half w div 4; lane = row.
    w, k, lane = _grid(N_WARPS, 24, WARP_SIZE)
    pattern["horizontal read"] = Phase("horizontal read", "read", w % 4 + 1, 16 * (w // 4) + k, lane)
    w, k, lane = _grid(N_WARPS, 16, WARP_SIZE)
    pattern["horizontal write"] = Phase("horizontal write", "write", w % 4 + 1, 24 * (w // 4) + k, lane)

    # Vertical blur on the strip of columns 24h..24h+15; lane l: column l mod 16,
    # upper half (rows 0..19) for l < 16, lower half (rows 12..31) otherwise.
    w, k, lane = _grid(N_WARPS, 20, WARP_SIZE)
    half = lane // 16
    pattern["vertical read"] = Phase(
        "vertical read", "read", w % 4 + 1, 24 * (w // 4) + lane % 16, 12 * half + k
    )
    w, k, lane = _grid(N_WARPS, 12, WARP_SIZE)
    half = lane // 16
    pattern["vertical write"] = Phase(
        "vertical write", "write", w % 4 + 1, 24 * (w // 4) + lane % 16, 4 + 12 * half + k
    )

    # Readout: warp w reads output rows w, w + 8, w + 16; lane = output column.
    i, jm, w, lane = _grid(3, 4, N_WARPS, WARP_SIZE)
    v = w + 8 * i
    x = np.where(lane < 16, lane, lane + 8)
    pattern["readout"] = Phase("readout", "read", jm + 1, x, v + GUARD, texel_x=lane, texel_y=v)
    return pattern


def conflicts(addresses) -> np.ndarray:
    """Extra serialized transactions of each warp-wide shared-memory instruction.

    Parameters
    ----------
    addresses : (..., 32) int array
        Word addresses of the 32 lanes of each instruction.

    Returns
    -------
    extra : (...) int64 array
        ``max over banks of (number of distinct addresses in the bank) − 1``; lanes
        on the same word share one broadcast and do not conflict. 0 means the
        instruction is served in one transaction.
    """
    a = np.asarray(addresses, dtype=np.int64)
    if a.ndim == 0 or a.shape[-1] != WARP_SIZE:
        raise InputError(f"addresses: expected a trailing axis of {WARP_SIZE} lanes, got shape {a.shape}")
    flat = np.sort(a.reshape(-1, WARP_SIZE), axis=1)
    # A lane counts once per distinct word: drop repeats of the sorted neighbour.
    distinct = np.ones(flat.shape, dtype=bool)
    distinct[:, 1:] = flat[:, 1:] != flat[:, :-1]
    counts = np.zeros((flat.shape[0], N_BANKS), dtype=np.int64)
    rows = np.broadcast_to(np.arange(flat.shape[0])[:, None], flat.shape)
    np.add.at(counts, (rows[distinct], flat[distinct] % N_BANKS), 1)
    return (counts.max(axis=1) - 1).reshape(a.shape[:-1])


def simulate(layout="paper") -> dict[str, int]:
    """Replay the shared-memory accesses of one block and count bank conflicts.

    Parameters
    ----------
    layout : {"paper", "row-major"}
        The storage pattern, see :func:`shared_index`.

    Returns
    -------
    counts : dict phase -> int
        For each phase of :data:`PHASES`, the sum over all warp-wide instructions
        of all 8 warps of :func:`conflicts` (extra serialized transactions). Per
        block; every block of a shadow map repeats the same accesses.

    Notes
    -----
    HPG17 §4.1, "Memory layout", and Figure 6. The paper layout gives 0 in every
    phase, which is the paper's claim; the row-major layout does not (a column
    access hits only banks 0, 8, 16, 24 because 40 ≡ 8 mod 32).

    Examples
    --------
    >>> simulate("paper")["vertical read"]
    0
    """
    if layout not in LAYOUTS:
        raise InputError(f"layout: expected one of {LAYOUTS}, got {layout!r}")
    out = {}
    for name, phase in access_pattern().items():
        out[name] = int(conflicts(shared_index(phase.j, phase.x, phase.y, layout)).sum())
    return out


def table() -> str:
    """The conflict counts of both layouts as a plain-text table."""
    pattern = access_pattern()
    results = {lay: simulate(lay) for lay in LAYOUTS}
    head = f"{'phase':<18} {'kind':<6} {'instructions':>12}" + "".join(f" {lay:>10}" for lay in LAYOUTS)
    lines = [
        "Shared-memory bank conflicts per 40x32 block (HPG17 Sec. 4.1, Figure 6)",
        "32 banks of 4-byte words, 8 warps of 32 lanes; count = sum over warp-wide",
        "instructions of (max distinct words in one bank - 1).",
        "",
        head,
        "-" * len(head),
    ]
    for name in PHASES:
        ph = pattern[name]
        lines.append(
            f"{name:<18} {ph.kind:<6} {ph.instructions():>12}"
            + "".join(f" {results[lay][name]:>10}" for lay in LAYOUTS)
        )
    lines.append("-" * len(head))
    total = sum(p.instructions() for p in pattern.values())
    lines.append(
        f"{'total':<18} {'':<6} {total:>12}" + "".join(f" {sum(results[lay].values()):>10}" for lay in LAYOUTS)
    )
    lines.append("")
    lines.append(
        f"paper layout: {SHARED_WORDS} words ({SHARED_WORDS * 4} bytes) per thread group; "
        f"row-major: {layout_words('row-major')} words"
    )
    return "\n".join(lines)


def main() -> str:
    """Text for ``moments-ref banks``: the table for both layouts."""
    return table()
