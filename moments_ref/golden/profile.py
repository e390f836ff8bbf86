"""Engine profiles: a porter declares the engine's conventions once, instead of writing adapters.

A profile is a TOML file (``--profile FILE.toml`` of ``conformance`` and ``verify``,
``profile=`` of :func:`moments_ref.oracle.check`). Every key is one entry of :data:`KEYS`
(name, values, default, one sentence, its parser, its command-line flags, and which cases
can use it): the parser, the nearest-key refusal of a misspelling, the flags
(:data:`FLAGS`), the key table of docs/ports.md (:func:`keys_markdown`, written by
``python -m moments_ref.tools.apidoc --profile-keys``) and the check of which case ignores
which key (:func:`ignored_keys`) all read it. ``[functions.NAME]`` holds the same keys for
one function of the file, overriding the file's. ``[uniforms]`` gives values of the uniform, constant-buffer and
push-constant members the tested function reads (``NAME = 1.0``, ``NAME = [a, b]``), as
``--uniform`` does (which wins over it; :mod:`moments_ref.conformance._uniforms`).

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
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from .._arrays import InputError
from .._toml import check_values, exact_int, finite_float, load_toml
from .cells import V2_CELLS
from .contract import PD_MIN, hankel_lambda_min

__all__ = ["Profile", "Bias", "Key", "KEYS", "load_profile", "parse_profile", "DEPTHS", "OUTPUTS", "APPLIED",
           "FORMAT_KEYS", "CLAMP_TESTS", "BOUNDS", "FLAGS", "profile_from_args", "DEFAULT", "ignored_keys", "ignored_note",
           "refuse_meaningless", "flag_keys", "keys_markdown", "write_docs"]

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
#: The bounds a shadow_intensity port may compute (key ``bound``; docs/ports.md).
BOUNDS = ("hamburger", "hausdorff")
FORMAT_KEYS = {"depth_decode": _POSITIONS, "v2_decode": _POSITIONS, "xi_decode": _POSITIONS,
               "xi_rounding": ("up", "nearest"), "subtexel_bits": tuple(range(4, 17)),
               "v2_cell": V2_CELLS}  # the 32-bit √v2 grid (golden.cells; kernel-filter-nlq32 only)
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


def _choices(allowed):
    return lambda v, src, key: _choice(v, allowed, src, key)


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


#: Largest receiver offset accepted (depth units): an acne guard, not a change of the receiver.
MAX_RECEIVER_OFFSET = 1e-2


def _offset(v, src, key):
    c = _number(v, src, key)
    if not 0 <= c <= MAX_RECEIVER_OFFSET:
        raise InputError(f"{_where(src, key)}: expected a number in [0, {MAX_RECEIVER_OFFSET:g}] (toward the light), "
                         f"got {c!r}")
    return c or None


def _flag(v, src, key):
    if not isinstance(v, bool):
        raise InputError(f"{_where(src, key)}: expected true or false, got {v!r}")
    return v or None


def _uses(token, why):
    """``case -> None`` (the case uses the key) or the reason it cannot, from the case's ``profile_keys``."""
    return lambda case: None if token in case.profile_keys else why(case)


def _receiver(case):
    return None if "zf" in case.inputs else f"it takes no receiver depth zf (inputs {', '.join(case.inputs)})"


def _bounded(case):
    return None if tuple(case.outputs) == ("intensity",) else \
        f"its outputs ({', '.join(case.outputs)}) are not a shadow intensity in [0, 1]"


def _four_moment_bound(case):
    return None if case.name.startswith(("shadow_intensity-", "hausdorff-")) else \
        "it is not a four-moment shadow_intensity bound (golden.cases.bound_case)"


def _always(case):
    return None  # used by every case, or refused for it (golden.conventions: a contradiction)


def _number_text(text, flag):
    try:
        return float(text)
    except ValueError:
        raise InputError(f"{flag}: expected a number, got {text!r}") from None


def _int_text(text, flag):
    try:
        return int(text)
    except ValueError:
        raise InputError(f"{flag}: expected an integer, got {text!r}") from None


def _list_text(text, flag):
    try:
        return [float(x) for x in str(text).split(",")]
    except ValueError:
        raise InputError(f"{flag}: expected comma-separated numbers, got {text!r}") from None


def _bool_text(text, flag):
    if str(text).lower() not in ("true", "false"):
        raise InputError(f"{flag}: expected true or false, got {text!r}")
    return str(text).lower() == "true"


def _same(text, flag):
    return text


@dataclass(frozen=True)
class Key:
    """One profile key: what the parser, the flags, the docs' table and the case check read.

    ``parse(value, source, key_path)`` returns the :class:`Profile` field's value (``None``:
    the default); ``ignored_by(case)`` is ``None`` where the case uses the key, else the reason
    it cannot; ``flags`` are ``(flag, key path, help, text -> value)``; ``rows`` are the docs
    table's ``(key, values, default)`` rows (the key's own first).
    """

    name: str
    parse: object
    doc: str
    rows: tuple
    ignored_by: object = _always
    flags: tuple = ()


_NOT_BIASED = _uses("bias", lambda c: f"it biases no moments: its inputs ({', '.join(c.inputs)}) are taken as given")
_NO_CLAMP = _uses("clamp", lambda c: "it has no Algorithm 3 clamp (HPG17 §3.4)")
_NO_TEXEL = _uses("format", lambda c: "it reads or writes no texel format whose choices the paper leaves open")

#: The profile keys, in the docs' order. Adding a key: its entry here, its field on :class:`Profile`,
#: its consumer (golden.conventions), its test (docs/architecture.md, "Add a profile key").
KEYS = (
    Key("depth", _choices(DEPTHS), "the depth convention of the tested function's moments and depths "
        "(moments_ref.scene.depth); the inputs are converted exactly",
        (("depth", "`\"[-1,1]\"`, `\"[0,1]\"`", "`\"[-1,1]\"` (the papers')"),),
        flags=(("--depth", "depth", "depth convention of the tested function: [-1,1] (the papers') or [0,1]", _same),)),
    Key("output", _choices(OUTPUTS), "what the function returns: the shadow intensity (1 = fully shadowed) or the "
        "visibility 1 - intensity", (("output", "`\"intensity\"`, `\"visibility\"`", "`\"intensity\"`"),),
        flags=(("--output", "output", "what it returns: intensity (1 = shadowed) or visibility (1 - intensity)",
                _same),)),
    Key("bias", _bias, "the engine's moment bias b' = (1 - alpha) b + alpha b* (HPG17 §3.2), applied inside the "
        "tested function or by its caller (the harness then biases the inputs)",
        (("bias", "a table `[bias]`, or `\"none\"`", "each case's own bias (the papers' presets; docs/golden.md)"),
         ("bias.alpha", "a number in [0, 1) (0: no bias)", "none: required in a `[bias]` table"),
         ("bias.target", "4 (or 6) numbers, a moment vector in the engine's depth convention",
          "none: required in a `[bias]` table"),
         ("bias.applied", "`\"inside\"` (the tested function biases) or `\"before\"` (its caller does; the harness "
          "biases the inputs)", "none: required in a `[bias]` table")),
        _NOT_BIASED,
        (("--bias-alpha", "bias.alpha", "the engine's bias alpha (0: none)", _number_text),
         ("--bias-target", "bias.target", "the bias target b*, comma-separated, in the engine's depth convention",
          _list_text),
         ("--bias-applied", "bias.applied", "where the bias is applied: inside the tested function or before the call",
          _same))),
    Key("clamp", _clamp, "Algorithm 3's clamp offset (HPG17 §3.4), inside moments_ref.nonlinear.CLAMP_BAND",
        (("clamp", "1e-7 .. 1/65535", "1e-6 (HPG17 §3.4)"),), _NO_CLAMP,
        (("--clamp", "clamp", "Algorithm 3's clamp offset (default 1e-6; allowed 1e-7 .. 1/65535)", _number_text),)),
    Key("clamp_test", _choices(CLAMP_TESTS), "the y2 that Algorithm 3's case test zf <= y2 compares with: the stored "
        "one or max(y2, y1 + clamp) (the author's demo code); the paper does not say",
        (("clamp_test", "`\"stored\"`, `\"clamped\"`", "`\"stored\"`"),), _NO_CLAMP,
        (("--clamp-test", "clamp_test", "the y2 of Algorithm 3's case test: stored (default) or clamped", _same),)),
    Key("format", _format, "the texel-format choices the paper leaves open (docs/formats.md)",
        (("format", "a table `[format]` of the keys below", "each format's own choices"),
         ("format.depth_decode`, `format.v2_decode`, `format.xi_decode", "`\"lower\"`, `\"centre\"`, `\"upper\"`",
          "the format's own (docs/formats.md)"),
         ("format.xi_rounding", "`\"up\"`, `\"nearest\"`", "`\"up\"`"),
         ("format.subtexel_bits", "4 .. 16", "exact weights"),
         ("format.v2_cell", "`\"floor128\"`, `\"round127\"` (the 32-bit √v2 grid; the 32-bit kernel case only)",
          "`\"floor128\"` (min(⌊128·√v2⌋, 127))")), _NO_TEXEL,
        tuple((f"--format-{k.replace('_', '-')}", f"format.{k}", f"texel format: {k} ({' or '.join(map(str, v))})",
               _int_text if k == "subtexel_bits" else _same) for k, v in FORMAT_KEYS.items())),
    Key("receiver_offset", _offset, "a constant offset the function subtracts from the receiver depth zf (toward the "
        "light, in the moments' depth convention) before the bound: the expected value is the bound at zf - offset",
        (("receiver_offset", f"0 .. {MAX_RECEIVER_OFFSET:g}", "0"),), _receiver,
        (("--receiver-offset", "receiver_offset", "constant receiver offset toward the light, inside the function",
          _number_text),)),
    Key("receiver_slope", _offset, "a slope-scaled receiver offset c: the function takes the receiver's slope as its "
        "last argument and subtracts c * slope from zf; the golden rows gain a `slope` input",
        (("receiver_slope", f"0 .. {MAX_RECEIVER_OFFSET:g}", "0 (no `slope` argument)"),), _receiver,
        (("--receiver-slope", "receiver_slope", "slope-scaled receiver offset: the function subtracts c * slope",
          _number_text),)),
    Key("receiver_depth", _choices(DEPTHS), "the depth convention of the receiver zf when it differs from the moments' "
        "(a [0,1] receiver mapped inside to the moments' [-1,1]); fed rounded to float32 as an engine does",
        (("receiver_depth", "`\"[-1,1]\"`, `\"[0,1]\"`", "the moments' (`depth`)"),), _receiver,
        (("--receiver-depth", "receiver_depth", "depth convention of the receiver zf, if not the moments'", _same),)),
    Key("output_clamp", _flag, "the caller clamps the result to [0, 1]: the port's output is clamped before the "
        "comparison, and the verdict says so", (("output_clamp", "`true`, `false`", "`false`"),), _bounded,
        (("--output-clamp", "output_clamp", "the caller clamps the result to [0, 1] (true or false)", _bool_text),)),
    Key("bound", _choices(BOUNDS), "the bound a shadow_intensity port computes: Algorithm 1's (Hamburger) or Peters "
        "and Klein 2015's Hausdorff bound (depths in [0, 1]), judged by the hausdorff-* cases",
        (("bound", "`\"hamburger\"`, `\"hausdorff\"`", "`\"hamburger\"` (Algorithm 1)"),), _four_moment_bound,
        (("--bound", "bound", "the bound a shadow_intensity port computes: hamburger (default) or hausdorff", _same),)),
)
_BY_NAME = {k.name: k for k in KEYS}
_KEYS = tuple(_BY_NAME)


@dataclass(frozen=True)
class Profile:
    """Declared conventions (one field per entry of :data:`KEYS`); ``None`` keeps each case's own."""

    depth: str | None = None
    output: str | None = None
    bias: Bias | None = None
    clamp: float | None = None
    clamp_test: str | None = None
    format: tuple = ()  # sorted (key, value) pairs
    receiver_offset: float | None = None
    receiver_slope: float | None = None
    receiver_depth: str | None = None
    output_clamp: bool | None = None
    bound: str | None = None  # "hamburger" or "hausdorff" (BOUNDS)
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
    def declared(self):
        """The keys this profile sets (not left at their default)."""
        return tuple(k for k in _KEYS if getattr(self, k) not in (None, ()))

    @property
    def canonical(self):
        """The profile's content as plain JSON values (what the cache key hashes)."""
        out = {k: getattr(self, k) for k in _KEYS}
        b = self.bias
        out["bias"] = None if b is None else {"alpha": b.alpha, "target": list(b.target), "applied": b.applied}
        out["format"] = dict(self.format)
        out["functions"] = {k: v.canonical for k, v in self.functions}
        return out

    @property
    def key(self):
        """sha256 of :attr:`canonical`: two profiles with the same content share derived goldens."""
        return hashlib.sha256(json.dumps(self.canonical, sort_keys=True).encode()).hexdigest()

    @property
    def is_default(self):
        return self.canonical == Profile().canonical

    def describe(self):
        """One line for reports."""
        parts = []
        for k in self.declared:
            if k == "bias":
                b = self.bias
                parts.append("no bias" if not b.active else
                             f"bias alpha {b.alpha:g} toward {list(b.target)} ({b.applied})")
            elif k == "format":
                parts += [f"{f} {v}" for f, v in self.format]
            else:
                parts.append(f"{k} {getattr(self, k)}")
        return ", ".join(parts) or "the papers' conventions"


DEFAULT = Profile()


def ignored_keys(case, profile):
    """``[(key, reason)]``: the keys ``profile`` declares that ``case`` cannot use, each with why (:data:`KEYS`)."""
    out = []
    for name in profile.declared:
        why = _BY_NAME[name].ignored_by(case)
        if why is not None:
            out.append((name, why))
    return out


def ignored_note(case, profile):
    """The verdict's note naming the declared keys ``case`` ignores and why (``[]`` if none)."""
    found = ignored_keys(case, profile)
    if not found:
        return []
    return ["profile keys this case ignores: " + "; ".join(f"{k} ({why})" for k, why in found)]


def refuse_meaningless(cases, profile, keys=None):
    """:class:`InputError` when a declared key (of ``keys``, default every declared one) can mean nothing for any
    of ``cases``: a declaration is used or refused, never silently dropped."""
    cases = list(cases)
    for name in keys if keys is not None else profile.declared:
        if name not in profile.declared or not cases:
            continue
        why = [_BY_NAME[name].ignored_by(c) for c in cases]
        if all(w is not None for w in why):
            raise InputError(f"profile {profile.source}: {name}: no selected case can use it "
                             f"({cases[0].name}: {why[0]}{'' if len(cases) == 1 else ', and the others'})")


def _table(data, src, prefix=""):
    """A Profile from one TOML table (the file's top level or one [functions.NAME])."""
    fields = {}
    for k, v in data.items():
        if k in _BY_NAME:
            fields[k] = _BY_NAME[k].parse(v, src, f"{prefix}{k}")
        elif (k == "functions" or k == "uniforms") and not prefix:
            continue  # [uniforms]: the values of a port's uniform members (conformance._uniforms)
        else:
            raise _unknown(src, f"{prefix}{k}", k, _KEYS + (() if prefix else ("functions", "uniforms")))
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


#: Command-line flags, one per key (from :data:`KEYS`): (flag, key path, help).
FLAGS = tuple(f[:3] for k in KEYS for f in k.flags)
_CONVERT = {f[1]: f[3] for k in KEYS for f in k.flags}


def flag_keys(flags):
    """The profile keys named by the flags given (``flags`` as for :func:`profile_from_args`)."""
    return tuple(dict.fromkeys(p.partition(".")[0] for f, p, _ in FLAGS
                               if flags.get(f[2:].replace("-", "_")) is not None))


def profile_from_args(path=None, function=None, **flags):
    """The profile of ``--profile FILE`` for ``function``, with the per-key flags on top.

    ``flags`` are keyword arguments named after :data:`FLAGS` (``depth``,
    ``bias_alpha``, ``format_depth_decode``, ...); ``None`` values are not given.
    """
    base = load_profile(path) if path is not None else DEFAULT
    base = base.for_function(function) if function else replace(base, functions=())
    given = {p: _CONVERT[p](flags[f[2:].replace("-", "_")], f) for f, p, _ in FLAGS
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


#: The markers of the key table in docs/ports.md.
MARKERS = ("<!-- profile keys: begin -->\n", "\n<!-- profile keys: end -->")


def keys_markdown():
    """The key table of docs/ports.md: every key of :data:`KEYS` with its values, default and sentence."""
    lines = ["| key | values | default | what |", "|---|---|---|---|"]
    for k in KEYS:
        for i, (name, values, default) in enumerate(k.rows):
            lines.append(f"| `{name}` | {values} | {default} | {k.doc.replace('|', '/') if i == 0 else ''} |")
    lines.append("| `[functions.NAME]` | any key above, for one function | the file's keys | "
                 "one function of the file, chosen by `--function` |")
    lines.append("| `[uniforms]` | `NAME = number`, `NAME = [numbers]`, `[uniforms.INSTANCE]` | none | values of the "
                 "uniform, constant-buffer and push-constant members the function reads, as `--uniform` (which wins) |")
    return "\n".join(lines)


def write_docs(path):
    """Rewrite the key table between :data:`MARKERS` in ``path`` (docs/ports.md); return the path."""
    from .._io import write_between

    return write_between(path, MARKERS, keys_markdown())
