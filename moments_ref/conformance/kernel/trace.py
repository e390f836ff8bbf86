"""Trace a kernel's shared-memory accesses on the driver: bank conflicts of the shipped code, and races.

A kernel that routes its shared-memory accesses through two one-line functions
tagged ``// mr:shared-load`` and ``// mr:shared-store`` (the shipped HPG17 §4.1
kernels do) can be traced: :func:`instrument` adds a call that records every
access of work group (0, 0) in program order, ``(word address, load or store,
barriers passed)``, into a storage buffer the harness binds (``mr_trace``, set 3
binding 7), and counts the barriers (a counter after every ``barrier()``,
``GroupMemoryBarrierWithGroupSync()``, ``workgroupBarrier()``). The kernel's own
arithmetic is unchanged.

From the trace:

* :func:`warp_addresses` groups the accesses as warps issue them (32 consecutive
  invocations, the k-th access of each), so :func:`moments_ref.gpu.banks.conflicts`
  counts the bank conflicts *of the code that ran*; :func:`expected` is the same
  table from :func:`moments_ref.gpu.banks.access_pattern`, which the on-chip
  emulation runs too: equal tables mean the simulator's "0 conflicts" and the
  emulation's arithmetic refer to the shipped kernel;
* :func:`races` finds two invocations touching one word between the same two
  barriers, one of them writing: a missing barrier, whatever order the driver
  happened to run the invocations in. (llvmpipe and lavapipe run a work group 8
  invocations at a time between barriers, so they show most races in the output
  too; a GPU whose 32-lane warps run in lockstep hides a race inside one warp,
  which the trace still sees.)

References
----------
.. [1] HPG17: Christoph Peters. 2017. *Non-Linearly Quantized Moment Shadow Maps*. In Proceedings
       of High Performance Graphics (HPG '17). ACM. The non-linear quantization Φ, Ψ4, Algorithms
       1–3, the texel formats and the compute shader of §4.1.
"""

from __future__ import annotations

import re
import tempfile
from pathlib import Path

import numpy as np

from ..._arrays import InputError
from ...gpu import banks

__all__ = ["RECORDS", "TAG", "instrument", "decode", "warp_addresses", "expected", "phase_conflicts", "races",
           "write_temp"]

#: Accesses recorded per invocation (the HPG17 kernel makes 104).
RECORDS = 192
_BARRIERS = {"glsl": r"\bbarrier\s*\(\s*\)\s*;", "hlsl": r"\bGroupMemoryBarrierWithGroupSync\s*\(\s*\)\s*;",
             "wgsl": r"\bworkgroupBarrier\s*\(\s*\)\s*;"}


TAG = re.compile(r"^\s*[^/\s].*//\s*mr:shared-(load|store)\s*$")


def _decls(language, vulkan):
    if language == "glsl":
        where = "set = 3, binding = 7" if vulkan else "binding = 7"
        return (f"layout(std430, {where}) buffer MrTrace {{ uint mr_trace[]; }};\n"
                "uint mr_seq = 0u;\nuint mr_epoch = 0u;\n"
                "void mr_record(uint a, uint kind) {\n"
                "    if (gl_WorkGroupID == uvec3(0u) && mr_seq < %du)\n"
                "        mr_trace[gl_LocalInvocationIndex * %du + mr_seq] =\n"
                "            (a + 1u) | (kind << 14) | (mr_epoch << 15);\n"
                "    mr_seq++;\n}\n") % (RECORDS, RECORDS)
    if language == "hlsl":
        return ("RWStructuredBuffer<uint> mr_trace : register(u7, space3);\n"
                "static uint mr_seq = 0;\nstatic uint mr_epoch = 0;\n"
                "static uint mr_gi = 0;\nstatic bool mr_on = false;\n"
                "void mr_record(uint a, uint kind) {\n"
                f"    if (mr_on && mr_seq < {RECORDS})\n"
                f"        mr_trace[mr_gi * {RECORDS} + mr_seq] = (a + 1) | (kind << 14) | (mr_epoch << 15);\n"
                "    mr_seq++;\n}\n")
    return ("@group(3) @binding(7) var<storage, read_write> mr_trace: array<u32>;\n"
            "var<private> mr_seq: u32 = 0u;\nvar<private> mr_epoch: u32 = 0u;\n"
            "var<private> mr_gi: u32 = 0u;\nvar<private> mr_on: bool = false;\n"
            "fn mr_record(a: u32, kind: u32) {\n"
            f"    if (mr_on && mr_seq < {RECORDS}u) {{\n"
            f"        mr_trace[mr_gi * {RECORDS}u + mr_seq] = (a + 1u) | (kind << 14u) | (mr_epoch << 15u);\n"
            "    }\n    mr_seq++;\n}\n")


def _record_line(line, language, kind):
    pat = r"\(\s*(\w+)\s*:" if language == "wgsl" else r"\(\s*\w+\s+(\w+)"
    m = re.search(pat, line)
    brace = line.find("{")
    if not m or brace < 0:
        raise InputError(f"trace: cannot instrument {line.strip()!r}: a tagged function must be one line whose "
                         "first parameter is the word address")
    return line[:brace + 1] + f" mr_record({m.group(1)}, {kind}u);" + line[brace + 1:]


def _entry_hook(text, language, entry):
    """HLSL and WGSL see the group and invocation index only in the entry point: copy them to globals."""
    if language == "glsl":
        return text
    m = re.search(rf"\b{re.escape(entry)}\s*\(", text)
    if not m:
        raise InputError(f"trace: entry point {entry!r} not found")
    depth, i = 1, m.end()
    while depth and i < len(text):  # the parameter list, parentheses balanced (WGSL attributes have their own)
        depth += {"(": 1, ")": -1}.get(text[i], 0)
        i += 1
    args = text[m.end():i - 1]
    m = re.compile(r"[^{]*\{").match(text, i)
    if language == "hlsl":
        gid = re.search(r"(\w+)\s*:\s*SV_GroupID", args)
        gi = re.search(r"(\w+)\s*:\s*SV_GroupIndex", args)
        hook = f" mr_gi = {gi.group(1) if gi else 0}; mr_on = all({gid.group(1)} == 0);" if gid and gi else None
    else:
        gid = re.search(r"@builtin\(workgroup_id\)\s*(\w+)", args)
        gi = re.search(r"@builtin\(local_invocation_index\)\s*(\w+)", args)
        hook = (f" mr_gi = {gi.group(1)}; mr_on = all({gid.group(1)} == vec3<u32>(0u));" if gid and gi else None)
    if hook is None:
        raise InputError("trace: the entry point must take the group id and the local invocation index "
                         "(SV_GroupID, SV_GroupIndex; @builtin(workgroup_id), @builtin(local_invocation_index))")
    return text[:m.end()] + hook + text[m.end():]


def instrument(text, language, entry, vulkan=False):
    """The kernel source with tracing added (see the module docstring); InputError if nothing is tagged."""
    lines = text.splitlines()
    tagged = [i for i, x in enumerate(lines) if TAG.search(x)]
    if not tagged:
        raise InputError("trace: the kernel has no lines tagged mr:shared-load / mr:shared-store")
    for i in tagged:
        lines[i] = _record_line(lines[i], language, 0 if TAG.search(lines[i]).group(1) == "load" else 1)
    lines.insert(tagged[0], _decls(language, vulkan))
    out = "\n".join(lines) + "\n"
    out = re.sub(_BARRIERS[language], lambda m: m.group(0) + " mr_epoch++;" if language != "wgsl"
                 else m.group(0) + " mr_epoch += 1u;", out)
    return _entry_hook(out, language, entry)


def write_temp(text, suffix):
    """A temporary copy of a source (the caller removes its folder)."""
    d = Path(tempfile.mkdtemp(prefix="moments-ref-trace-"))
    p = d / f"kernel_traced{suffix}"
    p.write_text(text, encoding="utf-8")
    return p


def decode(words, threads):
    """``(address, store, epoch)`` arrays (threads, records) of a trace buffer; address −1 where unused."""
    w = np.asarray(words, np.uint32)[: threads * RECORDS].reshape(threads, RECORDS).astype(np.int64)
    addr = (w & 0x3FFF) - 1
    return addr, (w >> 14) & 1, w >> 15


def warp_addresses(addr, warp=banks.WARP_SIZE):
    """The trace as warp-wide instructions: (warps, accesses, lanes); the k-th access of each lane."""
    t, k = addr.shape
    return addr.reshape(t // warp, warp, k).transpose(0, 2, 1)


def expected():
    """``(addresses (8, 104, 32), store flags (104,), phase names (104,))`` of banks.access_pattern in program order."""
    pattern = banks.access_pattern()
    parts, kinds, names = [], [], []
    for name in banks.PHASES:
        p = pattern[name]
        a = banks.shared_index(p.j, p.x, p.y)  # leading axes, then lanes
        if name in ("resolve", "readout"):  # (round|row, moment, warp, lane) -> (warp, round*moment, lane)
            a = a.transpose(2, 0, 1, 3).reshape(banks.N_WARPS, -1, banks.WARP_SIZE)
        parts.append(a)
        kinds += [p.kind == "write"] * a.shape[1]
        names += [name] * a.shape[1]
    return np.concatenate(parts, axis=1), np.array(kinds), np.array(names)


def phase_conflicts(addr):
    """Bank conflicts per phase of banks.PHASES of a traced HPG17 kernel (its accesses in program order)."""
    w = warp_addresses(addr)
    _, _, names = expected()
    extra = banks.conflicts(w[:, : len(names)])
    return {p: int(extra[:, names == p].sum()) for p in banks.PHASES}


def races(addr, store, epoch):
    """Conflicting accesses between the same two barriers: ``[(address, epoch, writer, other invocation)]``.

    Two accesses race when different invocations touch one word with the same
    number of barriers passed and at least one of them stores.
    """
    inv = np.broadcast_to(np.arange(addr.shape[0])[:, None], addr.shape)
    used = addr >= 0
    a, s, e, i = addr[used], store[used], epoch[used], inv[used]
    key = e * 16384 + a
    order = np.lexsort((-s, key))  # per word and epoch, stores first
    a, s, e, i, key = a[order], s[order], e[order], i[order], key[order]
    if not key.size:
        return []
    starts = np.flatnonzero(np.r_[True, key[1:] != key[:-1]])
    stored = np.maximum.reduceat(s, starts) == 1
    lo, hi = np.minimum.reduceat(i, starts), np.maximum.reduceat(i, starts)
    hit = starts[stored & (lo != hi)]
    writer = i[hit]
    other = np.where(lo[stored & (lo != hi)] != writer, lo[stored & (lo != hi)], hi[stored & (lo != hi)])
    return [(int(x), int(y), int(w), int(o)) for x, y, w, o in zip(a[hit], e[hit], writer, other)]
