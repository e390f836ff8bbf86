"""Floating-point behaviour of the drivers, measured (docs/ports.md, "GPUs are not llvmpipe").

Each probe is a one-line function in each language, run through the same harness
as the ports: is ``fma`` fused, is ``a*b + c`` contracted into a fused
multiply-add, does ``precise`` stop that, what ``clamp`` makes of NaN, and whether
division and ``sqrt`` round correctly (against NumPy's float32 on random inputs),
how far ``exp`` and ``log`` are from correctly rounded, whether denormals survive a store, a
multiplication by one, a product of normals and a comparison;
and how often the shipped ports' ``pack64``/``pack32`` ξ4 code, which goes through the
driver's ``log`` (HPG17 §3.3, Ψ4), differs from ``packing.py``'s.

References
----------
.. [1] HPG17: Christoph Peters. 2017. *Non-Linearly Quantized Moment Shadow Maps*. In Proceedings
       of High Performance Graphics (HPG '17). ACM. The non-linear quantization Φ, Ψ4, Algorithms
       1–3, the texel formats and the compute shader of §4.1.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np

from .. import packing, precise
from .._arrays import InputError
from ..ports import PORTS_DIR
from ..tools.intervals import wilson_interval
from ._gl import ContextError
from ._run import DRIVERS, LANGUAGES, run_function
from .languages import TABLE
from ._toolchain import ToolError
from .verdict import ulp_distance

__all__ = ["PROBES", "measure", "rules", "spirv_counts", "hlsl_contraction", "xi4_codes", "xi4_markdown",
           "probe_markdown", "DENORMAL", "denormal_findings", "transcendental_findings"]

_GLSL = """vec4 p_rules(vec4 x) { return vec4(mix(x.x, x.y, x.z), x.x / 3.0, (1.5 * x.x - 2.0 * x.y) + 0.5,
    x.w * x.w * x.w * x.w); }
vec4 p_round(vec4 x) { precise float r = x.x * x.y + x.z;
    return vec4(fma(x.x, x.y, x.z), x.x * x.y + x.z, r, clamp(x.w, 0.0, 1.0)); }
vec2 p_ops(vec4 x) { return vec2(x.x / x.y, sqrt(x.x)); }
vec2 p_transc(vec4 x) { return vec2(exp(x.x), log(x.y)); }
vec4 p_denorm(vec4 x) { return vec4(x.x, x.x * x.y, x.z * x.w, x.x > 0.0 ? 1.0 : 0.0); }
"""
_HLSL = """float4 p_rules(float4 x) { return float4(lerp(x.x, x.y, x.z), x.x / 3.0, (1.5 * x.x - 2.0 * x.y) + 0.5,
    x.w * x.w * x.w * x.w); }
float4 p_round(float4 x) { precise float r = x.x * x.y + x.z;
    return float4(mad(x.x, x.y, x.z), x.x * x.y + x.z, r, clamp(x.w, 0.0, 1.0)); }
float2 p_ops(float4 x) { return float2(x.x / x.y, sqrt(x.x)); }
float2 p_transc(float4 x) { return float2(exp(x.x), log(x.y)); }
float4 p_denorm(float4 x) { return float4(x.x, x.x * x.y, x.z * x.w, x.x > 0.0 ? 1.0 : 0.0); }
float p_contract(float4 x) { return x.x * x.y + x.z; }
float p_precise(float4 x) { precise float r = x.x * x.y + x.z; return r; }
"""
_WGSL = """fn p_rules(x: vec4<f32>) -> vec4<f32> { return vec4<f32>(mix(x.x, x.y, x.z), x.x / 3.0,
    (1.5 * x.x - 2.0 * x.y) + 0.5, x.w * x.w * x.w * x.w); }
fn p_round(x: vec4<f32>) -> vec4<f32> {
    return vec4<f32>(fma(x.x, x.y, x.z), x.x * x.y + x.z, 0.0, clamp(x.w, 0.0, 1.0)); }
fn p_ops(x: vec4<f32>) -> vec2<f32> { return vec2<f32>(x.x / x.y, sqrt(x.x)); }
fn p_transc(x: vec4<f32>) -> vec2<f32> { return vec2<f32>(exp(x.x), log(x.y)); }
fn p_denorm(x: vec4<f32>) -> vec4<f32> { return vec4<f32>(x.x, x.x * x.y, x.z * x.w, select(0.0, 1.0, x.x > 0.0)); }
"""
#: Probe sources per language (HLSL ``mad`` for ``fma``; WGSL has no ``precise``;
#: HLSL's ``p_contract``/``p_precise`` are compiled alone to count glslang's ``Fma``).
PROBES = {"glsl": _GLSL, "hlsl": _HLSL, "wgsl": _WGSL}


def _fma_row():
    # a = b = 1 + 2^-12, c = -(1 + 2^-11): a*b = 1 + 2^-11 + 2^-24 exactly, rounded to
    # 1 + 2^-11 (a tie to even); fused: 2^-24 = 5.96e-8, unfused: 0.
    a = np.float32(1 + 2.0 ** -12)
    return np.array([[a, a, -(1 + 2.0 ** -11), np.nan]], np.float32)


def _random_rows(n=20000, seed=3):
    rng = np.random.default_rng(seed)
    x = (10.0 ** rng.uniform(-6, 6, (n, 2)) * rng.choice([-1, 1], (n, 2))).astype(np.float32)
    return np.column_stack([np.abs(x[:, 0]), x[:, 1], x[:, 1], x[:, 1]]).astype(np.float32)


#: The denormal probe's row: d = 2^-140 (a float32 denormal), 1, and two normals whose product is d.
DENORMAL = np.array([[2.0 ** -140, 1.0, 2.0 ** -70, 2.0 ** -70]], np.float32)


def _transcendental_rows(n=20000, seed=4):
    # exp's argument uniform in [-87, 88] (its float32 range); log's 10^u with u uniform in [-30, 30] in
    # the first half and uniform in [0.5, 2] in the second, where a small absolute error is many ulps.
    rng = np.random.default_rng(seed)
    lg = np.concatenate([10.0 ** rng.uniform(-30, 30, n - n // 2), rng.uniform(0.5, 2, n // 2)])
    return np.column_stack([rng.uniform(-87, 88, n), lg, np.zeros(n), np.zeros(n)]).astype(np.float32)


def _share(u):
    """``'k of n (max U ulp; 95 % interval lo % to hi %)'``: rows not correctly rounded."""
    k, n = int((u > 0).sum()), len(u)
    lo, hi = wilson_interval(k, n)
    return f"{k} of {n} (max {u.max():.0f} ulp; 95 % interval {100 * lo:.3g} % to {100 * hi:.3g} %)"


def denormal_findings(y):
    """What the denormal probe's four outputs (:data:`DENORMAL`) say, as table cells.

    ``stored``: the input read and written back unchanged; ``x·1``: a denormal operand kept
    by a multiplication; ``product``: a denormal result of two normals kept; ``x > 0``: the
    comparison of a positive denormal.
    """
    d = np.float32(2.0 ** -140)
    kept = lambda v: "kept" if np.float32(v) == d else ("flushed to 0" if np.float32(v) == 0 else f"{float(v):g}")  # noqa: E731
    return {"stored": "unchanged" if np.float32(y[0]) == d else kept(y[0]), "x·1": kept(y[1]), "product": kept(y[2]),
            "x > 0": {1.0: "true", 0.0: "false"}.get(float(y[3]), f"{float(y[3]):g}")}


def transcendental_findings(x, y):
    """Table cells of ``exp`` and ``log`` (columns of :func:`_transcendental_rows`) against float64 rounded to
    float32: rows not correctly rounded, and ``log``'s largest absolute error on its rows in [0.5, 2]."""
    e, lg = np.exp(x[:, 0].astype(np.float64)), np.log(x[:, 1].astype(np.float64))
    near = (x[:, 1] >= 0.5) & (x[:, 1] <= 2)
    return {"p_exp": _share(ulp_distance(y[:, 0], e)), "p_log": _share(ulp_distance(y[:, 1], lg)),
            "p_log_abs": f"{np.abs(y[near, 1].astype(np.float64) - lg[near]).max():.2g}"}


def measure(language, adapter):
    """``{probe: finding}`` of one language on one driver (strings for the table)."""
    with tempfile.TemporaryDirectory(prefix="moments-ref-probe-") as tmp:
        path = Path(tmp) / f"probe.{language}"
        path.write_text(PROBES[language], encoding="utf-8")
        got, _ = run_function(path, "p_round", {"x": _fma_row()}, {"y": (np.float32, (1, 4))}, language, adapter)
        y = got["y"][0]
        found = {fn: "fused" if float(v) != 0 else "unfused" for fn, v in zip(("p_fma", "p_contract", "p_precise"), y)}
        if language == "wgsl":
            found["p_precise"] = "n/a"
        found["p_clamp"] = f"{float(y[3]):g}"
        x = _random_rows()
        got, _ = run_function(path, "p_ops", {"x": x}, {"y": (np.float32, (len(x), 2))}, language, adapter)
        for k, (fn, ref) in enumerate((("p_div", x[:, 0] / x[:, 1]), ("p_sqrt", np.sqrt(x[:, 0])))):
            u = ulp_distance(got["y"][:, k], ref)
            k = int((u > 0).sum())
            lo, hi = wilson_interval(k, len(x))
            found[fn] = f"{k} of {len(x)} (max {int(u.max())} ulp; 95 % interval {100 * lo:.2g} % to {100 * hi:.2g} %)"
        x = _transcendental_rows()
        got, _ = run_function(path, "p_transc", {"x": x}, {"y": (np.float32, (len(x), 2))}, language, adapter)
        found.update(transcendental_findings(x, got["y"]))
        got, _ = run_function(path, "p_denorm", {"x": DENORMAL}, {"y": (np.float32, (1, 4))}, language, adapter)
        found["denormal"] = denormal_findings(got["y"][0])
    return found


#: The rewrites :func:`rules` tells apart: per probe, candidate evaluations in float32.
_RULES = {
    "mix": {"x(1-a)+ya": lambda x, y, a, w: x * (np.float32(1) - a) + y * a,
            "x+a(y-x)": lambda x, y, a, w: x + a * (y - x)},
    "x/3": {"division": lambda x, y, a, w: x / np.float32(3),
            "x*(1/3)": lambda x, y, a, w: x * (np.float32(1) / np.float32(3))},
    "(1.5x-2y)+0.5": {"as written": lambda x, y, a, w: (np.float32(1.5) * x - np.float32(2) * y) + np.float32(0.5),
                      "(1.5x+0.5)-2y": lambda x, y, a, w: (np.float32(1.5) * x + np.float32(0.5)) - np.float32(2) * y},
    "w*w*w*w": {"left to right": lambda x, y, a, w: ((w * w) * w) * w,
                "(w*w)*(w*w)": lambda x, y, a, w: (w * w) * (w * w)},
}


def rules(language, adapter):
    """``{probe: candidate}``: which evaluation each driver's compiler chose (``mixed`` if none fits every row)."""
    rng = np.random.default_rng(5)
    x = rng.uniform(-2, 2, (4096, 4)).astype(np.float32)
    with tempfile.TemporaryDirectory(prefix="moments-ref-probe-") as tmp:
        path = Path(tmp) / f"probe.{language}"
        path.write_text(PROBES[language], encoding="utf-8")
        got = run_function(path, "p_rules", {"x": x}, {"y": (np.float32, (len(x), 4))}, language, adapter)[0]["y"]
    found = {}
    for k, (probe, cands) in enumerate(_RULES.items()):
        with np.errstate(all="ignore"):
            fits = [name for name, f in cands.items() if np.array_equal(f(*x.T), got[:, k])]
        found[probe] = fits[0] if fits else "mixed"
    return found


def spirv_counts(spirv):
    """``(Fma instructions, NoContraction decorations)`` in a SPIR-V module."""
    words = np.frombuffer(spirv, np.uint32)
    i, fma, exact = 5, 0, 0
    while i < len(words):
        count, op = int(words[i] >> 16), int(words[i] & 0xFFFF)
        if op == 12 and count >= 5 and words[i + 4] == 50:  # OpExtInst GLSL.std.450 Fma
            fma += 1
        if op == 71 and count >= 3 and words[i + 2] == 42:  # OpDecorate NoContraction
            exact += 1
        i += max(count, 1)
    return fma, exact


def hlsl_contraction():
    """What glslang's HLSL front end makes of ``a*b + c``, plain and ``precise``."""
    from ._slots import Slot, signature
    from ._source import load_source
    from ._toolchain import glslang_hlsl
    from ._wrap import wrap_hlsl

    ins, outs = [Slot.of("x", np.float32, (1, 4))], [Slot.of("y", np.float32, (1,))]
    with tempfile.TemporaryDirectory(prefix="moments-ref-probe-") as tmp:
        path = Path(tmp) / "probe.hlsl"
        path.write_text(_HLSL, encoding="utf-8")
        found = {}
        src = load_source(path, "hlsl")
        for fn in ("p_contract", "p_precise"):
            wrapper = wrap_hlsl(src, fn, ins, outs)
            found[fn] = spirv_counts(glslang_hlsl(wrapper, src.name, signature("hlsl", fn, ins, outs)))
        return found


def _random_representations(n, seed):
    # y1 <= y2 two sorted uniform draws in [-1, 1], v2 uniform in [0, 1], xi4 = 10^u, u uniform in [-8, log10 0.25].
    rng = np.random.default_rng(seed)
    y = np.sort(rng.uniform(-1, 1, (n, 2)), axis=1)
    return np.column_stack([y, rng.uniform(0, 1, n), 10 ** rng.uniform(-8, np.log10(0.25), n)]).astype(np.float32)


def xi4_codes(language, adapter, n=40000):
    """``{function: (other codes differing, ξ4 codes differing, largest ξ4 difference, farthest from an integer)}``.

    The shipped port's ``pack64`` (rows of seed 7) and ``pack32`` (seed 8) against
    :mod:`moments_ref.packing` on ``n`` random representations; "farthest" is, over the
    pack64 rows whose ξ4 code differs, the largest distance of the exact ``65535·Ψ4(ξ4)``
    (:func:`moments_ref.precise.psi4`) from an integer (``nan`` where none differs or for pack32).
    """
    path = PORTS_DIR / language / f"packing.{language}"
    found = {}
    for fn, seed, shape, dtype in (("pack64", 7, (n, 4), np.uint16), ("pack32", 8, (n,), np.uint32)):
        r = _random_representations(n, seed)
        name = "q" if fn == "pack64" else "p"
        got = run_function(path, fn, {"r": r}, {name: (dtype, shape)}, language, adapter)[0][name].astype(np.int64)
        ref = getattr(packing, fn)(r).astype(np.int64)
        if fn == "pack64":
            other, d = np.count_nonzero(got[:, :3] != ref[:, :3]), got[:, 3] - ref[:, 3]
            s = 65535 * precise.psi4(r[d != 0, 3])
            far = float(np.abs(s - np.round(s)).max()) if s.size else float("nan")
        else:
            other, d, far = np.count_nonzero((got ^ ref) & ((1 << 26) - 1)), (got >> 26) - (ref >> 26), float("nan")
        found[fn] = (int(other), int(np.count_nonzero(d)), int(np.abs(d).max()), far)
    return found


def xi4_markdown(n=40000):
    """The table of :func:`xi4_codes` for docs/conformance.md."""
    lines = ["## The ξ4 code through `log` (measured)", "",
             f"The shipped ports' `pack64` (seed 7) and `pack32` (seed 8) on {n} random representations (y1 ≤ y2",
             "two sorted draws uniform in [-1, 1], v2 uniform in [0, 1], ξ4 = 10^u with u uniform in",
             "[-8, log10 0.25], in float32) against `packing.py`: depth and v2 codes differing, ξ4 codes",
             "differing (they go through the driver's `log`) with the 95 % Wilson interval of their share, the",
             "largest difference of a ξ4 code, and over the differing pack64 rows the farthest the exact",
             "65535·Ψ4(ξ4) (mpmath) lies from an integer.", "",
             "| language | driver | function | other codes differing | ξ4 codes differing | 95 % interval |"
             " largest ξ4 difference | farthest from an integer |", "|---|---|---|---|---|---|---|---|"]
    for language in (x for x in LANGUAGES if TABLE[x].probed):
        for driver in DRIVERS:
            try:
                f = xi4_codes(language, driver, n)
            except (ContextError, ToolError) as exc:
                lines.append(f"| {language} | {driver} | skipped: {exc} ||||||")
                continue
            for fn, (other, k, big, far) in f.items():
                lo, hi = wilson_interval(k, n)
                farthest = "–" if np.isnan(far) else f"{far:.2g}"
                lines.append(f"| {language} | {driver} | {fn} | {other} | {k} of {n} ({100 * k / n:.2g} %) | "
                             f"{100 * lo:.2g} % to {100 * hi:.2g} % | {big} | {farthest} |")
    return lines


def probe_markdown():
    """The measured table for docs/conformance.md."""
    lines = ["## Floating-point behaviour of the drivers (measured)", "",
             "`fma`: the built-in (HLSL `mad`); `a*b + c`: contracted into one rounding or not; `precise`:",
             "the same expression marked `precise` (WGSL has none); `clamp(NaN, 0, 1)`; division and `sqrt`:",
             "results differing from correctly rounded float32 on 20 000 random inputs (seed 3: x > 0 and y of",
             "random sign, magnitudes 10^u, u uniform in [-6, 6]), with the 95 % Wilson interval of the share.", "",
             "| language | driver | fma | a*b + c | precise a*b + c | clamp(NaN, 0, 1) | x / y not correctly rounded |"
             " sqrt not correctly rounded |", "|---|---|---|---|---|---|---|---|"]
    more = ["", "## exp, log and denormals (measured)", "",
            "`exp` on 20 000 arguments uniform in [-87, 88] and `log` on 20 000 (seed 4: 10 000 of 10^u, u uniform",
            "in [-30, 30], and 10 000 uniform in [0.5, 2]): results differing from float64 rounded to float32,",
            "with the 95 % Wilson interval of the share, and `log`'s largest absolute error on [0.5, 2] (near 1",
            "a small absolute error is many ulps; HPG17's Ψ4 takes `log` of values near 1). Denormals:",
            "d = 2^-140 read and written back, d·1, the product 2^-70·2^-70 (a denormal result of normals),",
            "and d > 0.", "",
            "| language | driver | exp not correctly rounded | log not correctly rounded | log on [0.5, 2]: largest absolute error |"
            " d stored | d·1 | 2^-70·2^-70 | d > 0 |", "|---|---|---|---|---|---|---|---|---|"]
    for language in (x for x in LANGUAGES if TABLE[x].probed):
        for driver in DRIVERS:
            try:
                f = measure(language, driver)
            except (ContextError, ToolError) as exc:
                lines.append(f"| {language} | {driver} | skipped: {exc} ||||||")
                more.append(f"| {language} | {driver} | skipped: {exc} |||||||")
                continue
            lines.append(f"| {language} | {driver} | {f['p_fma']} | {f['p_contract']} | {f['p_precise']} | "
                         f"{f['p_clamp']} | {f['p_div']} | {f['p_sqrt']} |")
            d = f["denormal"]
            more.append(f"| {language} | {driver} | {f['p_exp']} | {f['p_log']} | {f['p_log_abs']} | {d['stored']} | "
                        f"{d['x·1']} | {d['product']} | {d['x > 0']} |")
    lines += more
    lines += ["", "## What the drivers' compilers change (measured)", "",
              "Which evaluation each path gives, on 4096 random inputs in [-2, 2] (`mixed`: none of the two",
              "fits every row). `as-written` is glslang's SPIR-V on OpenGL with every operation `NoContraction`",
              "(the default for HLSL on OpenGL; `--adapter as-written` for GLSL).", "",
              "| language | driver | mix / lerp | x / 3.0 | (1.5x − 2y) + 0.5 | w·w·w·w |", "|---|---|---|---|---|---|"]
    for language in (x for x in LANGUAGES if TABLE[x].probed):
        for driver in DRIVERS + (("as-written",) if language != "wgsl" else ()):
            try:
                f = rules(language, driver)
            except (ContextError, ToolError, InputError) as exc:
                lines.append(f"| {language} | {driver} | skipped: {exc} ||||")
                continue
            lines.append(f"| {language} | {driver} | " + " | ".join(f.values()) + " |")
    try:
        c = hlsl_contraction()
        lines += ["", "In the SPIR-V glslang makes of the HLSL probe, `a*b + c` holds "
                  f"{c['p_contract'][0]} `Fma` and {c['p_contract'][1]} `NoContraction`; the `precise` one "
                  f"{c['p_precise'][0]} `Fma` and {c['p_precise'][1]} `NoContraction`: glslang contracts, "
                  "llvmpipe and lavapipe evaluate the `Fma` unfused, a GPU fuses it."]
    except (ToolError, ContextError) as exc:
        lines += ["", f"glslang's contraction of HLSL: not measured ({exc})."]
    return "\n".join(lines + [""] + xi4_markdown())
