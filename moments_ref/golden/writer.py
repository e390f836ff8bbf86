"""Write the golden vectors: one ``.npz`` per case and ``manifest.json``.

Deterministic: the same version writes the same bytes (seeded rows, deterministic
zip entries, sorted JSON). Every file is written atomically (temporary file, fsync,
rename), so an interrupted run never leaves a half-written file; the folder is locked
against a second writer and marked ``INCOMPLETE`` until its manifest is written, so
an interrupted rewrite leaves a folder the loader names as incomplete.

References
----------
.. [1] HPG17 demo: The demo code accompanying HPG17 (Direct3D; C. Peters), whose 32-bit texel
       functions ``QuantizeMomentsNonLinear32Bit`` and ``UnpackMomentsNonLinear32Bit`` are public
       in engine code ported from it, e.g. the repository kingofthebongo2008/UCEngine,
       ``src/uc_dev/private/gx/dx12/shaders/shadows/moment_shadow_maps_32.hlsli`` and
       ``shadows.hlsli`` (cited for their behaviour; no code is copied). Its 64-bit format is a
       UNORM16 render-target write (``moment_shadow_maps_64.hlsli``).
.. [2] HPG17: Christoph Peters. 2017. *Non-Linearly Quantized Moment Shadow Maps*. In Proceedings
       of High Performance Graphics (HPG '17). ACM. The non-linear quantization Φ, Ψ4, Algorithms
       1–3, the texel formats and the compute shader of §4.1.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np

from .. import __version__
from .._arrays import InputError
from .._io import folder_lock, marked_incomplete, save_npz, write_text
from .cases import CASES
from .notes import CATEGORIES, NOTES, RESULTS
from . import bands
from .spread import gated_summary, golden_arrays, ulp

__all__ = ["write", "write_rows", "SCHEMA_VERSION", "SCHEMA_HISTORY", "CATEGORIES", "golden_arrays", "manifest_entry"]

SCHEMA_VERSION = 3
#: What each schema version changed (the manifest's ``schema_history``; docs/golden.md). Golden
#: vectors of an older version hold that version's formats: regenerate them, do not mix.
SCHEMA_HISTORY = {
    "2": "per-row tolerances, acceptable code sets for rounding ties, the notes table",
    "3": "32-bit NLQ texel (pack32, unpack32, reencode32, e2e-nlq32, e2e-block-nlq32): √v2 and Ψ4 are stored "
         "in cells of 1/128 and 1/64 (⌊128 √v2⌋ and ⌊64 Ψ4(ξ4)⌋, at most 127 and 63) instead of round(127 √v2) "
         "and round(63 Ψ4(ξ4)), and decoded at the HPG17 demo's positions: depths (ỹ + 1)/511.5 − 1 instead of "
         "(ỹ + 1/2)/511.5 − 1, √v2 (c + 1/2)/128 instead of c/127, Ψ4 (c + 1)/64 instead of min(1, (c + 1/2)/63); "
         "goldens of schema 2 use the old grid. The expected values of the texel and affine cases (pack64, "
         "unpack64, pack32, unpack32, reencode64, reencode32, to_optimized, from_optimized, encode_unorm16, "
         "decode_unorm16, to_optimized6, encode_r10g10b10a2, decode_r10g10b10a2) come from an independent "
         "ground truth (exact arithmetic and mpmath from the formats' tables and the slides' matrices) instead "
         "of the package's own functions: float values move by up to a few ulps, and on rounding-tie rows the "
         "expected code is the exact one (the acceptable set still holds the codes legitimate float "
         "implementations store). Also: the contract of each case (manifest `contract`) and the flag `robustness` on "
         "the rows beyond it (counted per level in `gated`, gated only with --strict); the engine cases' "
         "distributions (`aux`)",
}


def _legacy_tolerances(case, arrays):
    """Per category, the largest finite absolute tolerance (a summary; the gate is per row)."""
    out = {}
    cat = arrays["category"]
    n = len(cat)
    for dt in ("float32", "float64"):
        out[dt] = {}
        for c in CATEGORIES:
            sel = cat == c
            if case.integer_output or not sel.any():
                out[dt][c] = 0.0 if case.integer_output else 1e-6
                continue
            worst = 0.0
            for o in case.outputs:
                t = arrays[f"{o}_tolerance_{dt}"]
                if case.metric == "ulps":
                    t = t * ulp(arrays[o], dt)
                t = t.reshape(n, -1)[sel]
                t = t[np.isfinite(t)]
                worst = max(worst, float(t.max()) if t.size else 0.0)
            out[dt][c] = min(worst, 1.0) if worst > 0 else 1e-6
    return out


def manifest_entry(case, arrays, data=None):
    """The manifest entry of ``case`` (``data``: the file's bytes, for size and sha256)."""
    n = len(arrays["category"])
    entry = {
        "file": f"{case.name}.npz",
        "function": f"moments_ref.{case.function}",
        "kwargs": case.kwargs,
        "description": case.description,
        "contract": case.contract_text,
        "dtype": case.dtype,
        "input_order": list(case.inputs),
        "inputs": {k: {"dtype": str(arrays[k].dtype), "shape": list(arrays[k].shape)} for k in case.inputs},
        "outputs": {k: {"dtype": str(arrays[k].dtype), "shape": list(arrays[k].shape)} for k in case.outputs},
        "aux": {k: {"dtype": str(arrays[k].dtype), "shape": list(arrays[k].shape)} for k in case.aux},
        "compare": list(case.outputs),
        "metric": case.metric,
        "value_range": list(case.value_range) if case.value_range else None,
        "exact": bool(case.integer_output),
        "count": int(n),
        "categories": {c: int((arrays["category"] == c).sum()) for c in CATEGORIES},
        "results": {r: int((arrays["result"] == r).sum()) for r in RESULTS},
        "gated": gated_summary(case, arrays),
        "tolerances": _legacy_tolerances(case, arrays),
    }
    if data is not None:
        entry["sha256"] = hashlib.sha256(data).hexdigest()
        entry["size"] = len(data)
    return entry


def write(out_dir, cases=None, progress=None, profile=None):
    """Write the golden vectors and ``manifest.json`` to ``out_dir``.

    Parameters
    ----------
    out_dir : path
        Target folder (created). Every file is written atomically.
    cases : iterable of str, optional
        Case names (default: all of :data:`CASES`).
    progress : callable, optional
        Called with each case name as it is written (the CLI's progress bar).
    profile : moments_ref.golden.profile.Profile, optional
        Write the cases as an engine with these conventions sees them (inputs
        converted, expected values and tolerances derived: golden.conventions); the
        manifest records the profile. Without explicit ``cases``, the cases whose
        conventions the profile contradicts are left out (``manifest["not_written"]``).

    Returns
    -------
    manifest : dict
    """
    with folder_lock(out_dir, "golden"):  # from the start: a second writer into the folder is refused at once
        return _write(Path(out_dir), cases, progress, profile)


def _write(out_dir, cases, progress, profile):
    """:func:`write` under the folder's lock."""
    names = list(CASES) if cases is None else list(cases)
    unknown = [n for n in names if n not in CASES]
    if unknown:
        raise InputError(f"cases: unknown case {unknown[0]!r}; known: {', '.join(CASES)}")
    derived, skipped = {}, []
    if profile is not None and not profile.is_default:
        from .conventions import profiled_arrays
        from .profile import refuse_meaningless

        refuse_meaningless([CASES[n] for n in names], profile)  # a key no written case can use: exit 2, at once
        for name in list(names):
            try:
                derived[name] = profiled_arrays(name, profile)
            except InputError:
                if cases is not None:
                    raise
                names.remove(name)
                skipped.append(name)
    manifest = {
        "schema_version": SCHEMA_VERSION,
        "schema_history": SCHEMA_HISTORY,
        "package": "moments_ref",
        "package_version": __version__,
        "numpy_version": np.__version__,
        "tolerance_rule": "per row and output component: the interval spanned by the legitimate evaluations "
                          "(reference in float32 and float64, on inputs scaled jointly by 1 +- "
                          f"{bands.PERTURB_ULPS} ulps and per component by 1 +- {bands.INDEPENDENT_ULPS} ulp, "
                          "the papers' formulations within the cap), widened by a margin (the largest of "
                          f"{bands.MARGIN_NOISE:g} x the case's rounding noise, {bands.MARGIN_WIDTH:g} x the "
                          f"interval's width, {bands.FLOOR_ULPS} ulps), bounded outputs capped at {bands.CAP:g} of "
                          "their range (wider: ill-conditioned, flag wide_spread); stored as the smallest "
                          "symmetric tolerance that holds the band; integer outputs exact, ties accept the "
                          "stored acceptable codes",
        "notes": NOTES,
        "results": RESULTS,
        "cases": {},
    }
    if derived or skipped:
        manifest["profile"] = profile.canonical
        manifest["profile_key"] = profile.key
        manifest["not_written"] = skipped
    # The folder marked INCOMPLETE until its manifest matches its files: an interrupted rewrite is named
    # as such by the loader, never half-valid.
    with marked_incomplete(
            out_dir, f"This golden folder was not completely written ({len(names)} cases were to be written). "
                     "Rerun moments-ref golden --out on it.\n"):
        for name in names:
            case, arrays = derived[name] if name in derived else (CASES[name], golden_arrays(CASES[name]))
            data = save_npz(out_dir / f"{name}.npz", arrays)
            manifest["cases"][name] = manifest_entry(case, arrays, data)
            if progress is not None:
                progress(name)
        write_text(out_dir / "manifest.json", json.dumps(manifest, indent=2, sort_keys=True) + "\n")
    return manifest


def write_rows(out_dir, case, inputs, comments):
    """Write rows of ``case`` (a :class:`~moments_ref.golden.cases.Case`) as a golden folder.

    The rows are labelled ``edge`` with their ``comments``; expected values and
    tolerances are derived as for every golden case (:func:`~moments_ref.golden.spread.derive`),
    so ``moments-ref verify --golden DIR`` and ``moments-ref conformance --golden DIR``
    rerun exactly these rows (the sweep's shrunk failures). Returns the manifest.
    """
    from .spread import derive

    out_dir = Path(out_dir)
    n = len(comments)
    given = inputs
    inputs = {k: np.asarray(given[k]).astype(case.integer_inputs.get(k, case.dtype)) for k in case.inputs}
    arrays = dict(inputs)
    if case.deriver is not None:  # an engine case: its distributions (aux, stored as given) derive the row
        arrays.update({k: np.asarray(given[k]) for k in case.aux})
        arrays.update(case.deriver(case, dict(arrays), ["edge"] * n, list(comments), [()] * n))
    else:
        arrays.update(derive(case, inputs, ["edge"] * n, list(comments), [()] * n))
    manifest = {"schema_version": SCHEMA_VERSION, "schema_history": SCHEMA_HISTORY, "package": "moments_ref",
                "package_version": __version__, "numpy_version": np.__version__, "notes": NOTES, "results": RESULTS,
                "cases": {}}
    data = save_npz(out_dir / f"{case.name}.npz", arrays)
    manifest["cases"][case.name] = manifest_entry(case, arrays, data)
    write_text(out_dir / "manifest.json", json.dumps(manifest, indent=2, sort_keys=True) + "\n")
    return manifest
