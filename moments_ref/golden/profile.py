"""Engine profiles: a porter declares the engine's conventions once, instead of writing adapters.

A profile is a TOML file (``--profile FILE.toml`` of ``conformance`` and ``verify``,
``profile=`` of :func:`moments_ref.oracle.check`); every key also has a command-line
flag (:data:`FLAGS`). The keys (docs/ports.md):

=====================  ==========================================================
``depth``              ``"[-1,1]"`` (the papers', default) or ``"[0,1]"`` (Direct3D,
                       Vulkan, WebGPU): the depth convention of the tested function's
                       moments and depths (:mod:`moments_ref.scene.depth`).
``output``             ``"intensity"`` (default: 1 = fully shadowed) or
                       ``"visibility"`` (1 − intensity: the light that arrives).
``[bias]``             the engine's moment bias b' = (1 − α) b + α b* (HPG17 §3.2):
                       ``alpha``, ``target`` (b*, in the engine's own depth
                       convention), ``applied = "inside"`` (the tested function biases)
                       or ``"before"`` (its caller does, just before the call: the
                       harness then biases the inputs). ``bias = "none"``: no bias.
``clamp``              Algorithm 3's clamp offset (HPG17 §3.4; default 1e-6), inside
                       :data:`moments_ref.nonlinear.CLAMP_BAND`.
``clamp_test``         the y2 that Algorithm 3's case test ``zf ≤ y2`` compares with:
                       ``"stored"`` (default) or ``"clamped"`` (max(y2, y1 + clamp), the
                       author's demo code); the paper does not say.
``[format]``           the texel-format choices the paper leaves open
                       (:data:`FORMAT_KEYS`: decode positions, the rounding of the ξ4
                       code at 64 bits; docs/formats.md).
``[uniforms]``         values of the uniform, constant-buffer and push-constant
                       members the tested function reads (``NAME = 1.0``, a vector
                       ``NAME = [a, b]``): as ``--uniform``, which wins over it.
``[functions.NAME]``   the same keys for one function of the file, overriding the
                       file's (one file often holds a function that biases and one
                       that does not).
=====================  ==========================================================

Refused with :class:`~moments_ref.InputError` (exit status 2, one line naming the
key): unknown keys, values of the wrong type, a bias target whose Hankel matrix is
not positive semidefinite (no distribution on ℝ has it; a singular target, on the
boundary of the moment space, is allowed and judged by its outputs), ``alpha``
outside [0, 1), a clamp outside the band, and (when applied to a case,
:mod:`moments_ref.golden.conventions`) a depth convention or output that
contradicts the case.

References
----------
.. [1] HPG17: Christoph Peters. 2017. *Non-Linearly Quantized Moment Shadow Maps*. In Proceedings
       of High Performance Graphics (HPG '17). ACM. The non-linear quantization Φ, Ψ4, Algorithms
       1–3, the texel formats and the compute shader of §4.1.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from .._arrays import InputError
from .._toml import check_values, exact_int, finite_float, load_toml
from .cells import V2_CELLS
from .contract import PD_MIN, hankel_lambda_min

__all__ = ["Profile", "Bias", "load_profile", "parse_profile", "DEPTHS", "OUTPUTS", "APPLIED", "FORMAT_KEYS",
           "CLAMP_TESTS",
           "FLAGS", "profile_from_args", "DEFAULT"]

DEPTHS = ("[-1,1]", "[0,1]")
OUTPUTS = ("intensity", "visibility")
CLAMP_TESTS = ("stored", "clamped")
APPLIED = ("inside", "before")
#: Texel-format choices the paper leaves open (docs/formats.md), with their allowed values; unset
#: keys keep the format's own choices (:mod:`moments_ref.packing`). ``*_decode``: where the 32-bit
#: decoder reads a cell (its lower end, centre or upper end); ``xi_rounding``: the 64-bit Ψ4 code
#: rounded up (the lower-bound guarantee) or to nearest (a UNORM render-target write).
_POSITIONS = ("lower", "centre", "upper")
#: ``subtexel_bits``: the sub-texel precision of the engine's texture filter (bilinear cases,
#: golden.bilinear; D3D11 at least 8 bits, Vulkan at least 4). ``v2_cell``: the 32-bit √v2 grid
#: (:mod:`moments_ref.golden.cells`), honoured by the 32-bit kernel case.
FORMAT_KEYS = {"depth_decode": _POSITIONS, "v2_decode": _POSITIONS, "xi_decode": _POSITIONS,
               "xi_rounding": ("up", "nearest"), "subtexel_bits": tuple(range(4, 17)),
               "v2_cell": V2_CELLS}  # the 32-bit √v2 grid (golden.cells; kernel-filter-nlq32 only)
_KEYS = ("depth", "output", "bias", "clamp", "clamp_test", "format")
_BIAS_KEYS = ("alpha", "target", "applied")
#: Largest profile file accepted (bytes).
MAX_PROFILE = 1 << 20


@dataclass(frozen=True)
class Bias:
    """The engine's moment bias: ``alpha``, ``target`` (engine convention), where it is applied."""

    alpha: float
    target: tuple
    applied: str

    @property
    def active(self):
        return self.alpha > 0


NO_BIAS = Bias(0.0, (), "inside")


@dataclass(frozen=True)
class Profile:
    """Declared conventions; ``None`` keys leave each case's own (the papers') convention."""

    depth: str | None = None
    output: str | None = None
    bias: Bias | None = None
    clamp: float | None = None
    clamp_test: str | None = None
    format: tuple = ()  # sorted (key, value) pairs
    functions: tuple = ()  # sorted (name, Profile) pairs
    source: str = "profile"

    def for_function(self, name):
        """This profile with the keys of ``[functions.NAME]`` applied (the file's, if none)."""
        table = dict(self.functions).get(name)
        if table is None:
            return replace(self, functions=())
        merged = {k: getattr(table, k) if getattr(table, k) not in (None, ()) else getattr(self, k) for k in _KEYS}
        if table.format:
            merged["format"] = tuple(sorted({**dict(self.format), **dict(table.format)}.items()))
        return replace(self, functions=(), **merged)

    @property
    def canonical(self):
        """The profile's content as plain JSON values (what the cache key hashes)."""
        bias = None if self.bias is None else {"alpha": self.bias.alpha, "target": list(self.bias.target),
                                                "applied": self.bias.applied}
        return {"depth": self.depth, "output": self.output, "bias": bias, "clamp": self.clamp,
                "clamp_test": self.clamp_test, "format": dict(self.format),
                "functions": {k: v.canonical for k, v in self.functions}}

    @property
    def key(self):
        """sha256 of :attr:`canonical`: two profiles with the same content share derived goldens."""
        return hashlib.sha256(json.dumps(self.canonical, sort_keys=True).encode()).hexdigest()

    @property
    def is_default(self):
        return self.canonical == Profile().canonical

    def describe(self):
        """One line for reports."""
        c = self.canonical
        parts = [f"{k} {c[k]}" for k in ("depth", "output", "clamp", "clamp_test") if c[k] is not None]
        if self.bias is not None:
            b = self.bias
            parts.append("no bias" if not b.active else f"bias alpha {b.alpha:g} toward {list(b.target)} ({b.applied})")
        parts += [f"{k} {v}" for k, v in self.format]
        return ", ".join(parts) or "the papers' conventions"


DEFAULT = Profile()


def _where(src, key):
    return f"profile {src}: {key}"


def _unknown(src, key, name, known):
    """The refusal of an unknown key: names it and the nearest valid key (a misspelling is never ignored)."""
    import difflib

    near = difflib.get_close_matches(name, known, n=1, cutoff=0.5)
    hint = f"did you mean {near[0]!r}? " if near else ""
    return InputError(f"{_where(src, key)}: unknown key ({hint}known: {', '.join(known)})")


def _number(v, src, key):
    return finite_float(v, _where(src, key))  # bounded: an integer beyond float range is refused (_toml)


def _choice(v, allowed, src, key):
    if v not in allowed:
        raise InputError(f"{_where(src, key)}: expected one of {', '.join(repr(a) for a in allowed)}, got {v!r}")
    return v


def _target(v, src, key):
    if not isinstance(v, (list, tuple)) or len(v) not in (4, 6):
        raise InputError(f"{_where(src, key)}: expected a list of 4 (or 6) numbers, got {v!r}")
    t = tuple(_number(x, src, key) for x in v)
    lam = float(hankel_lambda_min(np.asarray(t)[None])[0])
    if lam < -PD_MIN:
        raise InputError(f"{_where(src, key)}: {list(t)} is not a moment vector: its Hankel matrix has the "
                         f"negative eigenvalue {lam:.3g} (outside the moment space on the real line)")
    return t


def _bias(v, src, key="bias"):
    if v == "none":
        return NO_BIAS
    if not isinstance(v, dict):
        raise InputError(f"{_where(src, key)}: expected a table (alpha, target, applied) or \"none\", got {v!r}")
    unknown = [k for k in v if k not in _BIAS_KEYS]
    if unknown:
        raise _unknown(src, f"{key}.{unknown[0]}", unknown[0], _BIAS_KEYS)
    missing = [k for k in _BIAS_KEYS if k not in v]
    if missing:
        raise InputError(f"{_where(src, f'{key}.{missing[0]}')}: missing (a bias needs {', '.join(_BIAS_KEYS)})")
    alpha = _number(v["alpha"], src, f"{key}.alpha")
    if not 0 <= alpha < 1:
        raise InputError(f"{_where(src, f'{key}.alpha')}: expected a number in [0, 1), got {alpha!r}")
    if alpha == 0:
        return NO_BIAS
    return Bias(alpha, _target(v["target"], src, f"{key}.target"),
                _choice(v["applied"], APPLIED, src, f"{key}.applied"))


def _clamp(v, src, key="clamp"):
    from ..nonlinear import CLAMP_BAND

    c = _number(v, src, key)
    if not CLAMP_BAND[0] <= c <= CLAMP_BAND[1]:
        raise InputError(f"{_where(src, key)}: {c:g} is outside the allowed band [{CLAMP_BAND[0]:g}, 1/65535] "
                         "(beyond it the clamp changes the bound by more than one 64-bit step of v2, HPG17 §3.4)")
    return c


def _format(v, src, key="format"):
    if not isinstance(v, dict):
        raise InputError(f"{_where(src, key)}: expected a table of texel-format choices, got {v!r}")
    out = {}
    for k, x in v.items():
        if k not in FORMAT_KEYS:
            raise _unknown(src, f"{key}.{k}", k, tuple(FORMAT_KEYS))
        if isinstance(FORMAT_KEYS[k][0], int):  # 8.0 or true is not the integer 8 or 1
            exact_int(x, _where(src, f"{key}.{k}"))
        out[k] = _choice(x, FORMAT_KEYS[k], src, f"{key}.{k}")
    return tuple(sorted(out.items()))


def _table(data, src, prefix=""):
    """A Profile from one TOML table (the file's top level or one [functions.NAME])."""
    fields = {}
    for k, v in data.items():
        key = f"{prefix}{k}"
        if k == "depth":
            fields["depth"] = _choice(v, DEPTHS, src, key)
        elif k == "output":
            fields["output"] = _choice(v, OUTPUTS, src, key)
        elif k == "bias":
            fields["bias"] = _bias(v, src, key)
        elif k == "clamp":
            fields["clamp"] = _clamp(v, src, key)
        elif k == "clamp_test":
            fields["clamp_test"] = _choice(v, CLAMP_TESTS, src, key)
        elif k == "format":
            fields["format"] = _format(v, src, key)
        elif k == "functions" and not prefix or k == "uniforms" and not prefix:
            continue  # [uniforms]: the values of a port's uniform members (conformance._uniforms)
        else:
            raise _unknown(src, key, k, _KEYS + (() if prefix else ("functions", "uniforms")))
    return Profile(**fields, source=src)


def parse_profile(data, source="profile"):
    """A :class:`Profile` from the parsed TOML ``data`` (a dict)."""
    if not isinstance(data, dict):
        raise InputError(f"profile {source}: expected a table of keys")
    check_values(data, f"profile {source}")  # the API's dicts too: nesting and number bounds (_toml)
    top = _table(data, source)
    funcs = data.get("functions", {})
    if not isinstance(funcs, dict) or not all(isinstance(v, dict) for v in funcs.values()):
        raise InputError(f"{_where(source, 'functions')}: expected tables [functions.NAME]")
    tables = tuple(sorted((name, _table(v, source, f"functions.{name}.")) for name, v in funcs.items()))
    return replace(top, functions=tables)


def load_profile(path):
    """Read and check a profile file (TOML); :class:`InputError` on anything it refuses."""
    # Size, nesting and number literals bounded before parsing, numbers after (_toml).
    data = load_toml(_read(path), f"profile {Path(path).name}", MAX_PROFILE)
    return parse_profile(data, Path(path).name)


def _read(path):
    """The bytes of a regular file of at most :data:`MAX_PROFILE` bytes (no links, FIFOs, devices)."""
    import os
    import stat

    try:
        st = os.lstat(path)
    except OSError:
        raise InputError(f"profile: expected a file, got {str(path)!r} (not found)") from None
    if not stat.S_ISREG(st.st_mode):
        raise InputError(f"profile: expected a regular file, got {str(path)!r} (a link, device, FIFO or folder)")
    if st.st_size > MAX_PROFILE:
        raise InputError(f"profile: expected at most {MAX_PROFILE} bytes, got {str(path)!r} with {st.st_size}")
    with open(path, "rb") as f:
        return f.read(MAX_PROFILE + 1)


#: Command-line flags, one per key: (flag, key path, help).
FLAGS = (
    ("--depth", "depth", "depth convention of the tested function: [-1,1] (the papers') or [0,1]"),
    ("--output", "output", "what it returns: intensity (1 = shadowed) or visibility (1 - intensity)"),
    ("--bias-alpha", "bias.alpha", "the engine's bias alpha (0: none)"),
    ("--bias-target", "bias.target", "the bias target b*, comma-separated, in the engine's depth convention"),
    ("--bias-applied", "bias.applied", "where the bias is applied: inside the tested function or before the call"),
    ("--clamp", "clamp", "Algorithm 3's clamp offset (default 1e-6; allowed 1e-7 .. 1/65535)"),
    ("--clamp-test", "clamp_test", "the y2 of Algorithm 3's case test: stored (default) or clamped"),
    *[(f"--format-{k.replace('_', '-')}", f"format.{k}", f"texel format: {k} ({' or '.join(map(str, v))})")
      for k, v in FORMAT_KEYS.items()],
)


def _flag_value(path, text):
    if path in ("bias.alpha", "clamp"):
        try:
            return float(text)
        except ValueError:
            raise InputError(f"--{path.replace('.', '-')}: expected a number, got {text!r}") from None
    if path == "format.subtexel_bits":
        try:
            return int(text)
        except ValueError:
            raise InputError(f"--format-subtexel-bits: expected an integer, got {text!r}") from None
    if path == "bias.target":
        try:
            return [float(x) for x in str(text).split(",")]
        except ValueError:
            raise InputError(f"--bias-target: expected comma-separated numbers, got {text!r}") from None
    return text


def profile_from_args(path=None, function=None, **flags):
    """The profile of ``--profile FILE`` for ``function``, with the per-key flags on top.

    ``flags`` are keyword arguments named after :data:`FLAGS` (``depth``,
    ``bias_alpha``, ``format_depth_decode``, ...); ``None`` values are not given.
    """
    base = load_profile(path) if path is not None else DEFAULT
    base = base.for_function(function) if function else replace(base, functions=())
    given = {p: _flag_value(p, flags[f[2:].replace("-", "_")]) for f, p, _ in FLAGS
             if flags.get(f[2:].replace("-", "_")) is not None}
    if not given:
        return base
    data = {}
    bias = dict(base.canonical["bias"] or {}) if base.bias is not None and base.bias.active else {}
    for p, v in given.items():
        head, _, tail = p.partition(".")
        if head == "bias":
            bias[tail] = v
        elif head == "format":
            data.setdefault("format", dict(base.format))[tail] = v
        else:
            data[head] = v
    if bias:
        data["bias"] = bias
    flagged = _table(data, "flags")
    return replace(base, **{k: getattr(flagged, k) for k in _KEYS if getattr(flagged, k) not in (None, ())})
