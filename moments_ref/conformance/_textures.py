"""Functions that read their moments from a texture: the golden inputs as a texture, one texel a row.

An engine's shadow function often takes the shadow map and a texel coordinate and
loads the moments itself. When the tested function has, in place of a golden
input, a texture parameter followed by an integer coordinate,

======  ==========================================  ===================================
GLSL    ``float f(sampler2D m, ivec2 p, float zf)``  ``texelFetch(m, p, 0)``
HLSL    ``float f(Texture2D<float4> m, int2 p, ...)`` ``m.Load(int3(p, 0))``
WGSL    ``fn f(m: texture_2d<f32>, p: vec2<i32>, ...)`` ``textureLoad(m, p, 0)``
======  ==========================================  ===================================

or a texture, a float coordinate and a noise value (blue-noise dithering, HPG17
§4.2: ``floor(coordinate + noise)`` picks the texel; :func:`_dithered` says how the
coordinates are chosen), or a texture, a sampler and a float coordinate
(``texture(m, uv)``, ``m.Sample(s, uv)``, ``textureSampleLevel(m, s, uv, 0.0)``), the
harness binds a texture holding that input's rows (row ``i`` at texel
``(i mod W, i div W)``, :data:`WIDTH` texels a line) and passes the texture and each
row's texel (for sampling its centre, with a point sampler; bilinear filtering at a
texel centre gives the texel too). The texture's format follows the input and the
texture's sample type: float moments as ``r/rg/rgba32float`` (exact); UNORM16 codes
as ``rgba16unorm`` to a float texture (the texel is code / 65535, what a 64-bit
moment texture holds) or ``rgba16uint`` to an unsigned one; 32-bit codes (NLQ
``pack32``) as ``r32uint``. GLSL ``sampler2D`` arguments run on OpenGL only (wgpu's
SPIR-V reader takes no combined image sampler). A bilinear case's ``texels`` (2×2
neighbourhoods, :mod:`moments_ref.golden.bilinear`) fill 2×2 blocks of an rgba32float
texture, filtered linearly (clamp to edge, one level), and the sampler's coordinate lies at
the row's ``fraction`` between the four centres (:meth:`TextureArg._between`); the
fraction is not passed as an argument.

References
----------
.. [1] HPG17: Christoph Peters. 2017. *Non-Linearly Quantized Moment Shadow Maps*. In Proceedings
       of High Performance Graphics (HPG '17). ACM. The non-linear quantization Φ, Ψ4, Algorithms
       1–3, the texel formats and the compute shader of §4.1.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

from .._arrays import InputError
from ._source import strip_comments

__all__ = ["WIDTH", "TextureArg", "parameters", "texture_args", "texel_bytes", "quad_layout", "consumed", "QUAD_INPUTS"]

#: Texels per line of an input texture.
WIDTH = 256
_TYPES = {"glsl": re.compile(r"^([iu]?)sampler2D$"),
          "hlsl": re.compile(r"^Texture2D(?:\s*<\s*(\w+)\s*>)?$"),
          "wgsl": re.compile(r"^texture_2d\s*<\s*(\w+)\s*>$")}
_COORD = {"glsl": ("ivec2",), "hlsl": ("int2", "uint2"), "wgsl": ("vec2<i32>", "vec2<u32>")}
_UV = {"glsl": ("vec2",), "hlsl": ("float2",), "wgsl": ("vec2<f32>",)}
_SAMPLER = {"hlsl": ("SamplerState",), "wgsl": ("sampler",)}


@dataclass(frozen=True)
class TextureArg:
    """The texture standing for input ``name``: its declared type, format and size in texels."""

    name: str
    type: str  # the parameter's type as written (declared the same way by the harness)
    format: str  # WebGPU format name: rgba32float, rgba16unorm, rgba16uint, r32uint, ...
    width: int
    height: int
    coord: str = "ivec2"  # the coordinate parameter's type
    sampler: str | None = None  # the sampler parameter's type (HLSL, WGSL), or None: texel loads
    sampled: bool = False  # a float coordinate at the texel's centre (Sample / texture)
    dithered: bool = False  # a float coordinate and a noise value (HPG17 §4.2)
    quad: str | None = None  # bilinear case: the input holding each row's sub-texel fraction (linear sampler)

    def declared(self, lang):
        """The parameters standing for the input, as in a signature: ``Texture2D<float4> b, int2 b_texel``."""
        params = [(self.type, self.name)] + ([(self.sampler, f"{self.name}_sampler")] if self.sampler else [])
        params.append((self.coord, f"{self.name}_texel"))
        if self.dithered:
            params.append((self.coord, f"{self.name}_noise"))
        return ", ".join(f"{n}: {t}" if lang == "wgsl" else f"{t} {n}" for t, n in params)

    def arguments(self, lang, i="i"):
        """``(statements or None, argument expressions after the texture)`` for row ``i``."""
        if self.dithered:
            return _dithered(lang, self.name, self.width, i), f"mr_c_{self.name}, mr_u_{self.name}"
        return None, self.texel(lang, i)

    def texel(self, lang, i="i"):
        """The argument expressions after the texture for row ``i``: [sampler,] coordinate."""
        w, h = self.width, self.height
        if self.quad:
            return self._between(lang, i)
        if self.sampled:
            smp = f"mr_smp_{self.name}, " if self.sampler else ""
            x, y = f"(float({i} % {w}u) + 0.5) / {w}.0", f"(float({i} / {w}u) + 0.5) / {h}.0"
            if lang == "wgsl":
                x, y = x.replace("float(", "f32("), y.replace("float(", "f32(")
            if lang == "hlsl":
                x, y = x.replace("u)", ")"), y.replace("u)", ")")
            return smp + {"glsl": "vec2", "hlsl": "float2", "wgsl": "vec2<f32>"}[lang] + f"({x}, {y})"
        if lang == "glsl":
            return f"ivec2(int({i} % {w}u), int({i} / {w}u))"
        if lang == "hlsl":
            return f"{self.coord}({i} % {w}, {i} / {w})"
        scalar = "i32" if "i32" in self.coord else "u32"
        return f"vec2<{scalar}>({scalar}({i} % {w}u), {scalar}({i} / {w}u))"


    def _between(self, lang, i):
        """Row ``i``'s 2×2 block (texels (2 bx, 2 by) .. (2 bx + 1, 2 by + 1)) sampled at its fraction between
        the four centres: ``((2 bx + 0.5 + fx) / W, (2 by + 0.5 + fy) / H)``, exact in float32 (W, H powers of
        two, fractions multiples of 2⁻¹⁶ below 256 texels)."""
        smp = f"mr_smp_{self.name}, " if self.sampler else ""
        blocks, f = self.width // 2, f"mr_in_{self.quad}[{i}]"
        cast = {"glsl": "float", "hlsl": "float", "wgsl": "f32"}[lang]
        u = "" if lang == "hlsl" else "u"
        x = f"({cast}(2{u} * ({i} % {blocks}{u})) + 0.5 + {f}.x) / {self.width}.0"
        y = f"({cast}(2{u} * ({i} / {blocks}{u})) + 0.5 + {f}.y) / {self.height}.0"
        return smp + {"glsl": "vec2", "hlsl": "float2", "wgsl": "vec2<f32>"}[lang] + f"({x}, {y})"


def _pow2(n):
    return 1 << max(0, int(n - 1).bit_length())


def quad_layout(n):
    """``(width, height)`` of the texture holding ``n`` 2×2 blocks: powers of two, at most WIDTH wide."""
    w = min(WIDTH, _pow2(2 * n))
    return w, _pow2(2 * -(-n // (w // 2)))


def parameters(body, function, language):
    """``[(type, name)]`` of the first definition of ``function`` in a source (``[]`` if not found)."""
    text = strip_comments(body)
    pattern = (rf"\bfn\s+{re.escape(function)}\s*\(" if language == "wgsl"
               else rf"[\w>]\s+{re.escape(function)}\s*\(")
    m = re.search(pattern, text)
    if not m:
        return []
    depth, i = 1, m.end()
    while i < len(text) and depth:
        depth += {"(": 1, ")": -1}.get(text[i], 0)
        i += 1
    params, cur, angle = [], "", 0
    for ch in text[m.end():i - 1] + ",":
        angle += {"<": 1, ">": -1}.get(ch, 0)
        if ch == "," and angle == 0:
            if cur.strip():
                params.append(cur.strip())
            cur = ""
        else:
            cur += ch
    out = []
    for p in params:
        if language == "wgsl":
            name, _, typ = p.partition(":")
            out.append((re.sub(r"\s+", "", typ), name.strip()))
        else:
            p = re.sub(r"\b(in|const|uniform|highp|mediump|lowp)\b\s*", "", p).split(":")[0].strip()
            typ, _, name = p.rpartition(" ")
            out.append((re.sub(r"\s+", "", typ) if language == "wgsl" else typ.strip(), name.strip()))
    return out


def _sample_kind(typ, language):
    m = _TYPES[language].match(typ)
    if not m:
        return None
    g = (m.group(1) or "") if language != "glsl" else m.group(1)
    if language == "glsl":
        return {"": "f", "u": "u", "i": "i"}[g]
    return "u" if g.startswith(("u", "uint")) else "i" if g.startswith(("i", "int")) else "f"


def _format(slot, kind, dtype):
    k = slot.components
    if slot.is_array or k == 3 and kind != "f":
        return None
    if kind == "f" and slot.kind == "f":
        return {1: "r32float", 2: "rg32float", 3: "rgba32float", 4: "rgba32float"}[k]
    if kind == "f" and dtype == np.uint16 and k == 4:
        return "rgba16unorm"
    if kind == "u" and slot.kind == "u":
        bits = "16" if dtype == np.uint16 else "32"
        return {1: f"r{bits}uint", 2: f"rg{bits}uint", 4: f"rgba{bits}uint"}.get(k)
    return None


def texture_args(body, function, language, ins, dtypes, n):
    """``{input name: TextureArg}`` for the inputs the function takes as a texture and a coordinate.

    ``dtypes`` are the golden arrays' dtypes. Raises :class:`InputError` for a texture
    parameter the harness cannot fill (a format it does not make, no coordinate after it).
    """
    params = parameters(body, function, language)
    found, k = {}, 0
    for s in ins:
        if s.name in consumed(found):
            continue  # no parameter of its own: the coordinate carries it
        if k >= len(params):
            break
        typ, pname = params[k]
        kind = _sample_kind(typ, language)
        if kind is None:
            k += 1
            continue
        rest = [p[0] for p in params[k + 1:k + 3]] + ["", ""]
        sampler = rest[0] if rest[0] in _SAMPLER.get(language, ()) else None
        coord = rest[1] if sampler else rest[0]
        dithered = sampler is None and rest[0] in _UV[language] and rest[1] in _UV[language]
        sampled = coord in _UV[language] and (sampler is not None or language == "glsl") and not dithered
        quad = _quad(s, ins)
        if quad:
            if not sampled or kind != "f":
                raise InputError(f"function: {function}'s parameter {pname} ({typ}) stands for the 2x2 texel "
                                 f"neighbourhoods {s.name!r} of a bilinear case; the harness binds them as an "
                                 f"rgba32float texture with a linear sampler and passes the sample position as "
                                 f"{' or '.join(_UV[language])} after the {'texture' if language == 'glsl' else 'sampler'}"
                                 " (docs/ports.md, \"Texture arguments\")")
            w, h = quad_layout(n)
            found[s.name] = TextureArg(s.name, typ, "rgba32float", w, h, coord, sampler, True, False, quad)
            k += 3 if sampler else 2
            continue
        fmt = _format(s, kind, np.dtype(dtypes[s.name]))
        if sampled and (fmt is None or not fmt.endswith("float")):
            fmt = None  # sampling: float moments only
        if (coord not in _COORD[language] and not sampled and not dithered) or fmt is None:
            raise InputError(f"function: {function}'s parameter {pname} ({typ}) stands for the input {s.name!r} "
                             f"({np.dtype(dtypes[s.name])}, {s.components} values a row); the harness fills a 2-D "
                             f"texture from it and passes an integer texel coordinate ({' or '.join(_COORD[language])}) "
                             "as the next parameter, or (float moments) a sampler and the texel centre as "
                             f"{' or '.join(_UV[language])}")
        w = min(WIDTH, n)
        found[s.name] = TextureArg(s.name, typ, fmt, w, -(-n // w), coord, sampler, sampled, dithered)
        k += 3 if sampler or dithered else 2
    return found


#: A bilinear case's inputs: 2×2 neighbourhoods (n, 16) and the sub-texel fraction (n, 2) (golden.bilinear).
QUAD_INPUTS = ("texels", "fraction")


def _quad(slot, ins):
    """The fraction input of a bilinear case's neighbourhoods ``slot``, or None."""
    names = [s.name for s in ins]
    if slot.name == QUAD_INPUTS[0] and slot.components == 16 and QUAD_INPUTS[1] in names:
        return QUAD_INPUTS[1]
    return None


def consumed(tex):
    """Inputs the texture arguments stand in for besides their own (a bilinear case's fraction)."""
    return {t.quad for t in tex.values() if t.quad}


def _dithered(lang, name, w, i):
    """Statements giving row ``i``'s noise ``mr_u`` and coordinate ``mr_c`` (texel units).

    The noise has 8 bits a channel, in (0, 1), as HPG17's blue-noise tiles; the
    coordinate is chosen so that ``floor(c + u)`` is the row's texel: on even rows
    ``t − u/2`` (a function that ignores the noise fetches the texel before), on odd
    rows ``t + (1 − u)/2`` (one that rounds instead of flooring fetches the next).
    Every value is a dyadic fraction, exact in float32.
    """
    u, tt, c = f"mr_u_{name}", f"mr_t_{name}", f"mr_c_{name}"
    if lang == "glsl":
        return [f"vec2 {u} = vec2(float(({i} * 73u + 41u) % 255u + 1u), float(({i} * 151u + 7u) % 255u + 1u)) / 256.0;",
                f"vec2 {tt} = vec2(float({i} % {w}u), float({i} / {w}u));",
                f"vec2 {c} = {tt} + ((1.0 - {u}) - step(vec2(0.5), {tt}) * float(1u - {i} % 2u)) * 0.5;"]
    if lang == "hlsl":
        return [f"float2 {u} = float2(({i} * 73 + 41) % 255 + 1, ({i} * 151 + 7) % 255 + 1) / 256.0;",
                f"float2 {tt} = float2({i} % {w}, {i} / {w});",
                f"float2 {c} = {tt} + ((1.0 - {u}) - step(0.5, {tt}) * (float)(1 - {i} % 2)) * 0.5;"]
    return [f"let {u} = vec2<f32>(f32(({i} * 73u + 41u) % 255u + 1u), f32(({i} * 151u + 7u) % 255u + 1u)) / 256.0;",
            f"let {tt} = vec2<f32>(f32({i} % {w}u), f32({i} / {w}u));",
            f"let {c} = {tt} + ((vec2<f32>(1.0) - {u}) - step(vec2<f32>(0.5), {tt}) * f32(1u - {i} % 2u)) * 0.5;"]


_BYTES = {"float": (np.float32, 4), "uint": (np.uint32, 4), "16uint": (np.uint16, 2), "16unorm": (np.uint16, 2)}


def texel_bytes(arr, tex):
    """The texture's texels (padded rows, zero beyond the last row) as bytes for the driver."""
    if tex.quad:  # row r's texel (i, j) at (2 (r mod B) + i, 2 (r div B) + j), B blocks a line
        a = np.asarray(arr, np.float32).reshape(len(arr), 2, 2, 4)  # (row, j, i, component)
        blocks = tex.width // 2
        out = np.zeros((tex.height, tex.width, 4), np.float32)
        r = np.arange(len(a))
        for j in range(2):
            for i in range(2):
                out[2 * (r // blocks) + j, 2 * (r % blocks) + i] = a[:, j, i]
        return out.tobytes()
    key = "16unorm" if tex.format.endswith("16unorm") else "16uint" if "16uint" in tex.format else (
        "float" if tex.format.endswith("float") else "uint")
    dtype, _ = _BYTES[key]
    comps = {"r": 1, "rg": 2, "rgba": 4}[re.match(r"[a-z]+?(?=\d)", tex.format).group()]
    a = np.asarray(arr).reshape(len(arr), -1).astype(dtype)
    out = np.zeros((tex.width * tex.height, comps), dtype)
    out[: len(a), : a.shape[1]] = a
    return out.tobytes()
