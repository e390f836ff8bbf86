"""Golden cases under an engine profile: inputs converted exactly, expected values derived and cached.

:func:`profile_arrays` turns the arrays of a golden case (the papers' conventions)
into those of the same rows as an engine with a :class:`~.profile.Profile` sees them:

* **inputs** in the engine's depth convention, converted exactly (rational arithmetic,
  :func:`moments_ref.scene.depth.moments_affine_rational`) and rounded once to the
  case's dtype; with ``bias.applied = "before"`` the caller's bias is applied in the
  same exact step, so the port receives the correctly rounded biased moments;
* **expected values and per-row tolerances** from the same spread model
  (:func:`moments_ref.golden.spread.derive`) run on those inputs with the case's
  reference configured for the profile (the bias inside, the clamp offset, the
  texel-format choices, visibility instead of intensity): a 5e-6 clamp gets its own
  tolerances, a [0, 1] port the conditioning of [0, 1] arithmetic;
* **the contract** of each row decided on the papers' inputs with the declared bias
  (:mod:`moments_ref.golden.contract`), so that rounding in the conversion never
  moves a singular row inside.

Results are cached in memory and on disk (:func:`cache_dir`), keyed by the case, the
profile's content, the golden rows and the package's version and sources; a profile
never changes a golden folder.

References
----------
.. [1] HPG17: Christoph Peters. 2017. *Non-Linearly Quantized Moment Shadow Maps*. In Proceedings
       of High Performance Graphics (HPG '17). ACM. The non-linear quantization Φ, Ψ4, Algorithms
       1–3, the texel formats and the compute shader of §4.1.
"""

from __future__ import annotations

import hashlib
import os
from dataclasses import replace
from pathlib import Path

import numpy as np

from .. import __version__
from .._arrays import InputError
from ..scene import depth as _depth
from .cases import CASES
from .contract import rows_inside
from .notes import ROBUSTNESS
from .profile import DEFAULT, Bias, ignored_keys

__all__ = ["profile_arrays", "profiled_arrays", "profiled_case", "neighbourhood_case", "convert_inputs", "contract_mask",
           "cache_dir", "unused_keys"]

#: Receiver keys: the port computes its own receiver from what it is fed (golden.receiver.judged), and the exact
#: values that judge its ill-conditioned rows are taken there.
_RECEIVER_KEYS = ("receiver_offset", "receiver_slope", "receiver_depth")

#: Flags that :func:`~moments_ref.golden.spread.derive` sets; recomputed under a profile.
_DERIVED_FLAGS = (ROBUSTNESS, "wide_spread", "rounding_tie", "printed_hazard")
_MEMO = {}
#: [0, 1] depth: z_unit = z_ndc / 2 + 1/2 (scale, offset), and back.
_TO_UNIT, _TO_NDC = (0.5, 0.5), (2.0, -1.0)


def cache_dir():
    """Where derived goldens are cached: ``$MOMENTS_REF_CACHE`` or ``~/.cache/moments_ref``, ``/profiles``."""
    root = os.environ.get("MOMENTS_REF_CACHE") or Path.home() / ".cache" / "moments_ref"
    return Path(root) / "profiles"


def _contradiction(case, what, why):
    raise InputError(f"profile: {what} contradicts case {case.name!r}: {why} "
                     f"({case.description.split(';')[0]})")


def _check(case, profile):
    from .cells import DEFAULT_CELL, HONOURED_BY

    cell = dict(profile.format).get("v2_cell", DEFAULT_CELL)
    if cell != DEFAULT_CELL and case.name not in HONOURED_BY:
        _contradiction(case, f"format.v2_cell = {cell!r}",
                       f"only {', '.join(HONOURED_BY)} follows a declared √v2 grid")
    if profile.depth not in (None, case.depth) and not case.depth_roles:
        _contradiction(case, f"depth = {profile.depth!r}", f"its quantities are defined for depths in {case.depth}")
    if profile.output == "visibility" and tuple(case.outputs) != ("intensity",):
        _contradiction(case, "output = 'visibility'", "it returns no shadow intensity")
    b = profile.bias
    if b is not None and b.active and "bias" in case.profile_keys:
        width = case.width if case.width else 4
        if len(b.target) != width:
            _contradiction(case, f"bias.target with {len(b.target)} values", f"it takes {width} moments")
        if b.applied == "before" and not case.bias_before:
            _contradiction(case, "bias.applied = 'before'", "its function applies the bias itself")


def _engine_frame(target, profile):
    """A target given in the papers' frame, in the profile's depth convention (float64)."""
    if profile.depth != "[0,1]":
        return tuple(float(t) for t in target)
    return tuple(float(x) for x in _depth.moments_affine(np.asarray(target, np.float64), *_TO_UNIT))


def _canonical_frame(target, profile):
    if profile.depth != "[0,1]":
        return np.asarray(target, np.float64)
    return _depth.moments_affine(np.asarray(target, np.float64), *_TO_NDC)


def _biases(case, profile):
    """``(bias the harness applies before the call, bias inside the function)``, engine frame (or None)."""
    b = profile.bias
    if "bias" not in case.profile_keys:
        return None, None
    if b is None:
        if case.default_bias is None:
            return None, None
        applied, preset = case.default_bias
        bias = Bias(preset.alpha, _engine_frame(preset.target, profile), applied)
        return (bias, None) if applied == "before" else (None, bias)
    if not b.active:
        return None, None
    return (b, None) if b.applied == "before" else (None, b)


def unused_keys(case, profile):
    """The profile keys ``case`` cannot use (named in its verdict; :func:`~.profile.ignored_keys` gives why)."""
    return [k for k, _ in ignored_keys(case, profile)]


def _visibility(fn):
    def wrapped(**inputs):
        return tuple(1 - np.asarray(x) for x in fn(**inputs))

    return wrapped


def _visibility_pairs(fn):
    def wrapped(**inputs):
        return tuple((1 - np.asarray(hi), 1 - np.asarray(lo)) for lo, hi in fn(**inputs))

    return wrapped


def profiled_case(case, profile):
    """The :class:`~moments_ref.golden.cases.Case` an engine with ``profile`` is judged by."""
    _check(case, profile)
    before, inside = _biases(case, profile)
    changes = {}
    if case.variant is not None:
        changes = case.variant(bias=inside, clamp=profile.clamp if "clamp" in case.profile_keys else None,
                               clamp_test=profile.clamp_test if "clamp" in case.profile_keys else None,
                               fmt=dict(profile.format) if "format" in case.profile_keys else {},
                               before=before, profile=profile)
    out = replace(case, **changes)
    if profile.output == "visibility" and out.deriver is None:
        hook = out.spread_hook
        out = replace(out, reference=_visibility(out.reference),
                      truth=None if out.truth is None else _visibility(out.truth),
                      confirm_truth=None if out.confirm_truth is None else _visibility_pairs(out.confirm_truth),
                      spread_hook=None if hook is None else
                      (lambda ins, dt: [tuple(1 - np.asarray(x) for x in v) for v in hook(ins, dt)]))
    if profile.receiver_slope and "zf" in case.inputs:  # the port takes the receiver's slope as its last argument
        out = replace(out, inputs=tuple(out.inputs) + ("slope",))
    kwargs = dict(out.kwargs)
    if not profile.is_default:
        kwargs["profile"] = {k: v for k, v in profile.canonical.items() if v not in (None, {}, [])}
        if before is not None:
            kwargs["harness_bias"] = {"alpha": before.alpha, "target": list(before.target)}
    return replace(out, kwargs=kwargs)


def neighbourhood_case(case, profile):
    """The case whose exact values judge a golden's ill-conditioned rows by their neighbourhood, or None.

    Without a profile, ``case`` itself; under one, :func:`profiled_case` (its exact values take the
    inputs as the engine receives them: a [0, 1] depth range, a bias inside or before, the output),
    as the sweep judges and confirms profiled rows; with a receiver key, its exact values, reference
    and formulations are taken at the receiver the port computes from what it is fed
    (:func:`moments_ref.golden.receiver.judged`), so the neighbourhood of the fed receiver maps to
    the port's own. None for an Algorithm 1 case under ``bound = "hausdorff"`` (a Hausdorff port is
    judged by the hausdorff-* cases, whose exact values are its own): those rows keep their stored
    band alone. (The caller's clamp changes the port's outputs, which are clamped before
    they are judged, not the exact values.)
    """
    if profile is None or profile.is_default:
        return case
    if profile.bound == "hausdorff" and case.contract != "hausdorff":
        return None  # an Algorithm 1 case under the Hausdorff declaration: its exact values are not the port's
    out = profiled_case(case, profile)
    if "zf" in case.inputs and any(getattr(profile, k) for k in _RECEIVER_KEYS):
        out = _at_judged_receiver(out, profile)
    return out


def _at_judged_receiver(case, profile):
    """``case`` with its exact values, reference and formulations evaluated at the port's own receiver."""
    from .receiver import judged

    def mapped(ins):
        ins = dict(ins)
        ins.update(judged(case, {k: ins[k] for k in ("zf", "slope") if k in ins}, profile))
        ins.pop("slope", None)
        return ins

    def wrap(f):
        return None if f is None else (lambda **ins: f(**mapped(ins)))

    hook = case.spread_hook
    return replace(case, truth=wrap(case.truth), confirm_truth=wrap(case.confirm_truth),
                   reference=wrap(case.reference),
                   spread_hook=None if hook is None else (lambda ins, dt: hook(mapped(ins), dt)))


def convert_inputs(case, inputs, profile):
    """The case's inputs as the engine receives them: converted exactly, biased if the caller biases, rounded once."""
    before, _ = _biases(case, profile)
    unit = profile.depth == "[0,1]"
    out = {}
    for k, v in inputs.items():
        role = case.depth_roles.get(k)
        arr = np.asarray(v)
        if role == "moments" and (unit or before is not None):
            scale, offset = _TO_UNIT if unit else (1.0, 0.0)
            q = _depth.moments_affine_rational(arr, scale, offset)
            if before is not None:
                q = _bias_rational(q, before)
            out[k] = np.array([_depth.round_rational(x, arr.dtype) for x in q.reshape(-1)],
                              np.float64).reshape(arr.shape).astype(arr.dtype)
        elif role == "depth" and unit:
            out[k] = _depth.z_unit_from_ndc(arr).astype(arr.dtype)
        else:
            out[k] = arr
    return out


def _bias_rational(q, bias):
    """``(1 − α) q + α b*`` in rational arithmetic (α and b* as the floats given)."""
    from fractions import Fraction

    a = Fraction(bias.alpha)
    t = [Fraction(x) for x in bias.target]
    flat = q.reshape(-1, q.shape[-1])
    out = np.empty(flat.shape, dtype=object)
    for i in range(flat.shape[0]):
        for k in range(flat.shape[1]):
            out[i, k] = (1 - a) * flat[i, k] + a * t[k]
    return out.reshape(q.shape)


def contract_mask(case, inputs, profile):
    """Rows inside the case's contract under ``profile``: judged on the papers' inputs with its bias."""
    if case.contract is None:
        return None
    before, inside = _biases(case, profile)
    bias = before or inside
    if bias is not None:
        bias = (bias.alpha, _canonical_frame(bias.target, profile))
    return rows_inside(case.contract, inputs, bias)


def _strip(flags, biased=False):
    """The rows' own flags (without those derive sets); under a bias, singular rows are bias-floor rows.

    A bias makes the moments of one or two depths those of a distribution at the bias
    floor, whose support points are computed: ``singular_hankel`` becomes ``bias_floor``
    and ``support_point`` there ``near_support_point`` (their notes say what follows).
    """
    out = []
    for fl in np.asarray(flags):
        names = [f for f in str(fl).split(",") if f and f not in _DERIVED_FLAGS]
        if biased and "singular_hankel" in names:
            names = [{"singular_hankel": "bias_floor", "support_point": "near_support_point"}.get(f, f)
                     for f in names]
        out.append(tuple(dict.fromkeys(names)))
    return out


def profile_arrays(case, arrays, profile, fed=None):
    """``(case', arrays')``: the rows of ``arrays`` (a golden case's) as an engine with ``profile`` sees them.

    The port is fed the inputs of ``fed`` (default ``profile``) and judged at what a function
    with ``profile`` computes from them (:mod:`.receiver`: its receiver offset and convention):
    the diagnosis judges a port's outputs under another declaration with the inputs it was given.
    """
    from .receiver import feed, judged
    from .spread import derive

    pcase = profiled_case(case, profile)
    judge = replace(pcase, inputs=case.inputs)  # the reference takes the receiver, not its slope
    fed = profile if fed is None else fed
    inputs = {k: np.asarray(arrays[k]) for k in tuple(case.inputs) + tuple(case.aux)}
    inside = contract_mask(case, inputs, profile)
    conv = convert_inputs(case, inputs, fed)
    fed_receiver = feed(case, conv, fed)
    conv.update(fed_receiver)
    own = judged(case, conv, profile)
    seen = {**conv, **own}
    before, inside_bias = _biases(case, profile)
    biased = (before is not None or inside_bias is not None) and case.contract == "moments_inside"
    labels = (np.asarray(arrays["category"]), list(np.asarray(arrays["comment"])), _strip(arrays["flags"], biased))
    if pcase.deriver is not None:
        derived = pcase.deriver(judge, seen, *labels, contract=inside)
    else:
        derived = derive(judge, {k: seen[k] for k in case.inputs}, *labels, contract=inside)
    # the port's receiver inputs are what it is fed, not the receiver it computes from them
    out = {**conv, **derived, **{k: conv[k] for k in {**fed_receiver, **own}}}
    if pcase.extra is not None:  # a kernel case's expected codes, under the declared format
        out.update(pcase.extra(conv))
    return pcase, out


_CODE = []


def _code_hash():
    """sha256 of the package's sources: derived goldens change with the code that derives them."""
    if not _CODE:
        h = hashlib.sha256()
        root = Path(__file__).resolve().parents[1]
        for f in sorted(root.rglob("*.py")):
            h.update(f.relative_to(root).as_posix().encode() + b"\0" + f.read_bytes())
        _CODE.append(h.hexdigest())
    return _CODE[0]


def _key(case, arrays, profile):
    h = hashlib.sha256()
    for part in (case.name, profile.key, __version__, _code_hash(), str(case.dtype)):
        h.update(part.encode() + b"\0")
    for k in list(case.inputs) + list(case.aux) + ["category", "flags", "comment"]:
        a = np.ascontiguousarray(arrays[k])
        h.update(str(a.dtype).encode() + str(a.shape).encode() + a.tobytes())
    return h.hexdigest()


def _trusted(path):
    """Whether a cache entry may be read: a regular file (no link) owned by this user that no other user can
    write, in a folder no other user can write into (unless sticky, like /tmp). Anything else is rebuilt."""
    import stat

    try:
        st, folder = os.lstat(path), os.stat(path.parent)
    except OSError:
        return False
    uid = os.getuid()
    own = stat.S_ISREG(st.st_mode) and st.st_uid == uid and not st.st_mode & 0o022
    shared = folder.st_mode & 0o022 and not folder.st_mode & stat.S_ISVTX
    return own and (folder.st_uid in (uid, 0)) and not shared


def _load_cached(path, key, pcase):
    """The cached derived arrays at ``path``, or None (derive again): not there, not trusted (:func:`_trusted`), a
    foreign key, or arrays the strict loader's value checks refuse (a poisoned entry: NaN expected values,
    tolerances that are not positive, unknown categories)."""
    from .values import check_case_values

    if not _trusted(path):
        return None
    try:
        with np.load(path, allow_pickle=False) as g:
            data = {k: g[k] for k in g.files}
        if str(data.pop("cache_key", "")) != key:
            return None
        meta = {"inputs": list(pcase.inputs), "compare": list(pcase.outputs), "metric": pcase.metric,
                "outputs": {o: {"dtype": str(data[o].dtype)} for o in pcase.outputs}}
        check_case_values(meta, data, f"cache entry {path.name}")
    except Exception:  # a partial, foreign or poisoned file: derive again (and overwrite it)  # noqa: BLE001
        return None
    return data


def profiled_arrays(name, profile=DEFAULT, arrays=None, disk=True, fed=None):
    """``(case', arrays')`` of golden case ``name`` under ``profile``, cached.

    ``arrays``: the case's golden arrays (from a golden folder); default: generated.
    The default profile returns the golden arrays themselves. ``fed``: the profile whose
    inputs the port was given, if not ``profile`` (:func:`profile_arrays`).
    """
    if name not in CASES:
        raise InputError(f"case: unknown case {name!r}")
    case = CASES[name]
    # The profile is checked against the case before any array is generated: a case the profile
    # contradicts is refused at once (``golden --profile`` leaves most cases out).
    pcase = None if profile.is_default and fed is None else profiled_case(case, profile)
    if arrays is None:
        from .spread import golden_arrays

        arrays = golden_arrays(case)
    if profile.is_default and fed is None:
        return case, arrays
    key = _key(case, arrays, profile) + ("" if fed is None else ":fed:" + fed.key)
    if key in _MEMO:
        return pcase, _MEMO[key]
    path = cache_dir() / f"{key.replace(':fed:', '-')}.npz"
    data = _load_cached(path, key, pcase) if disk else None
    if data is None:
        _, data = profile_arrays(case, arrays, profile, fed)
        if disk:
            from .._io import save_npz

            try:
                save_npz(path, {**data, "cache_key": np.array(key)})
            except OSError:  # an unwritable cache only costs the derivation next time
                pass
    _MEMO[key] = data
    return pcase, data
