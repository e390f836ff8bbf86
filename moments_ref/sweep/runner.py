"""Chunked differential runs: draw, judge, run the port, compare, confirm; in order, anywhere.

A sweep is a list of chunks (:data:`~.samplers.CHUNK` rows each, the last truncated).
:func:`run_chunk` is a pure function of ``(spec, chunk)``: it draws the chunk's rows
(:mod:`.samplers`), derives their legitimate intervals (:func:`.judge.legitimate_interval`),
runs the port on every driver of the spec, compares, and confirms the flagged rows
against mpmath (:func:`.judge.confirm`, at most :data:`CONFIRM_CAP` per chunk and driver).
:func:`run_chunks` maps it over the chunks in-process, in spawned worker processes
(one driver context each) or on a Dask cluster, and returns the results in chunk order,
so the merged result does not depend on where a chunk ran.
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..golden.cases import call_implementation
from . import judge
from .samplers import CHUNK, STRATA, draw_chunk

__all__ = ["Port", "SweepSpec", "run_chunk", "run_chunks", "evaluate", "CONFIRM_CAP", "KEEP", "STAGES"]

#: Flagged rows confirmed with mpmath per chunk and driver (the others count as flagged only).
CONFIRM_CAP = 64
#: Failing rows kept per chunk and driver for the report and shrinking.
KEEP = 4
STAGES = ("draw", "reference", "driver", "compare", "confirm")


_CASES = {}


@dataclass(frozen=True)
class Port:
    """What the sweep runs: a shader function (path, language, options) or a Python callable."""

    path: str | None = None
    function: str | None = None
    language: str | None = None
    options: object = None  # conformance.SourceOptions
    fn: object = None  # a Python implementation (oracle.sweep): fn(**inputs) -> output or tuple
    vectorized: bool = True


@dataclass(frozen=True)
class SweepSpec:
    """Everything a chunk depends on (picklable: it travels to worker processes and Dask workers)."""

    case_name: str
    port: Port
    drivers: tuple = (None,)  # adapter specs; (None,) for a Python callable or the language's default
    seed: int = 0
    rows: int = 10**6
    profile_key: str = "default"
    port_dtype: str = "float32"
    strict: bool = False  # also gate the robustness rows (outside the case's contract), as --strict does for goldens
    profile: object = None  # golden.profile.Profile (picklable, unlike a Case)
    fn_case: object = None  # a Case given directly (in-process runs of oracle.sweep only)

    @property
    def case(self):
        """The golden case as the profile shapes it (built once per process)."""
        if self.fn_case is not None:
            return self.fn_case
        key = (self.case_name, self.profile_key)
        if key not in _CASES:
            from ..golden import CASES

            case = CASES[self.case_name]
            if self.profile is not None and not self.profile.is_default:
                from ..golden.conventions import profiled_case

                case = profiled_case(case, self.profile)
            _CASES[key] = case
        return _CASES[key]

    @property
    def shaping(self):
        """The profile that shapes the draw (None for the default profile)."""
        return None if self.profile is None or self.profile.is_default else self.profile

    @property
    def chunks(self):
        return -(-self.rows // CHUNK)

    def chunk_rows(self, i):
        return min(CHUNK, self.rows - i * CHUNK)


def evaluate(spec, inputs, driver):
    """The port's outputs for ``inputs`` on ``driver``: ``{output: array}`` (float32 for float outputs)."""
    case, port = spec.case, spec.port
    n = len(next(iter(inputs.values())))
    if port.fn is not None:
        return call_implementation(port.fn, case, inputs, port.vectorized)
    from ..conformance import run_function

    inputs = {k: inputs[k] for k in case.inputs}  # not an engine case's distribution (its aux arrays)
    shapes = {o: (np.float32 if not case.integer_output else np.uint32, (n,) + _out_shape(case, o)) for o in case.outputs}
    got, _ = run_function(port.path, port.function, inputs, shapes, port.language, driver, port.options)
    return got


def _out_shape(case, o):
    shapes = case.engine.get("shapes") if case.engine else None
    if shapes and o in shapes:
        return tuple(shapes[o])
    return {"b": (4,), "r": (4,), "q": (4,), "b_biased": (4,)}.get(o, ())


def _row(case, params, inputs, got, bands, i):
    """One failing row, JSON-ready: inputs, texel parameters, got and the interval."""
    w = params["w"][i]
    keep = w > 0
    return {"inputs": {k: np.asarray(v[i]).tolist() for k, v in inputs.items()},
            "texel": {"depths": params["z"][i][keep].tolist(), "weights": w[keep].tolist(),
                      "zf": float(params["zf"][i]), "format": int(params["fmt"][i])},
            "stratum": STRATA[params["stratum"][i]],
            "got": {o: np.asarray(got[o][i]).tolist() for o in case.outputs},
            "lo": {o: np.asarray(bands[o][0][i]).tolist() for o in case.outputs},
            "hi": {o: np.asarray(bands[o][1][i]).tolist() for o in case.outputs}}


def run_chunk(spec, chunk):
    """Judge chunk ``chunk`` of ``spec``: counts per stratum, kept rows and seconds per stage."""
    case, t = spec.case, dict.fromkeys(STAGES, 0.0)
    t0 = time.perf_counter()
    inputs, params = draw_chunk(case, spec.seed, chunk, spec.chunk_rows(chunk), spec.profile_key, spec.shaping)
    t["draw"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    contract = judge.contract_rows(case, inputs, params.get("contract"))
    bands, ill = judge.legitimate_interval(case, inputs, spec.port_dtype, contract)
    t["reference"] = time.perf_counter() - t0
    n, strata = len(ill), params["stratum"]
    gated = np.ones(n, bool) if spec.strict else contract  # robustness rows: shown, failed only under --strict
    ungated = ~gated
    with np.errstate(over="ignore"):  # a band wider than the largest float is unbounded: inf, as meant
        for lo, hi in bands.values():
            ungated |= ~np.isfinite(hi - lo).reshape(n, -1).all(axis=1)
    out = {"chunk": chunk, "rows": n, "drivers": {}}
    count = lambda m: np.bincount(strata[m], minlength=len(STRATA)).tolist()  # noqa: E731
    out["strata"] = {"rows": count(np.ones(n, bool)), "ill_conditioned": count(ill), "ungated": count(ungated)}
    for driver in spec.drivers:
        t0 = time.perf_counter()
        got = evaluate(spec, inputs, driver)
        t["driver"] += time.perf_counter() - t0
        t0 = time.perf_counter()
        flagged = judge.flagged_rows(case, inputs, bands, ill, got, gated, spec.port_dtype, contract)
        t["compare"] += time.perf_counter() - t0
        t0 = time.perf_counter()
        idx = np.flatnonzero(flagged)
        look = idx[:CONFIRM_CAP]
        sub = lambda d: {k: np.asarray(v)[look] for k, v in d.items()}  # noqa: E731
        confirmed = look[judge.confirm(case, sub(inputs), sub(got), spec.port_dtype)] if look.size else look
        unconfirmed = np.setdiff1d(look, confirmed)
        t["confirm"] += time.perf_counter() - t0
        mask = np.zeros(n, bool)
        mask[confirmed] = True
        # confirmed rows on which the port returns a printed formulation's value, or one within the slides' code's
        # rounding envelope (the tolerance model's known gap)
        printed, envelope = np.zeros(n, bool), np.zeros(n, bool)
        if confirmed.size:
            pick = lambda d: {k: np.asarray(v)[confirmed] for k, v in d.items()}  # noqa: E731
            cut = {o: tuple(np.asarray(x)[confirmed] for x in lohi) for o, lohi in bands.items()}
            printed[confirmed], envelope[confirmed] = judge.named_rows(case, pick(inputs), pick(got), cut,
                                                                       spec.port_dtype)
        umask = np.zeros(n, bool)
        umask[unconfirmed] = True
        out["drivers"][str(driver)] = {
            "flagged": count(flagged), "examined": int(look.size), "confirmed": count(mask), "unconfirmed": count(umask),
            "printed": count(printed), "envelope": count(envelope),
            "confirmed_rows": [dict(_row(case, params, inputs, got, bands, i), printed=bool(printed[i]),
                                    envelope=bool(envelope[i])) for i in confirmed[:KEEP]],
            "unconfirmed_rows": [_row(case, params, inputs, got, bands, i) for i in unconfirmed[:KEEP]],
            "first_confirmed": int(confirmed[0]) + chunk * CHUNK if confirmed.size else None}
    out["seconds"] = t
    return out


def _local(spec, todo, workers, done):
    if workers <= 1 or len(todo) <= 1:
        for i in todo:
            done(run_chunk(spec, i))
        return
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    with ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("spawn")) as pool:
        for r in pool.map(run_chunk, [spec] * len(todo), todo):
            done(r)


def _dask(spec, todo, scheduler, done):
    from dask.distributed import Client

    client = Client(scheduler) if isinstance(scheduler, str) else scheduler
    try:
        futures = client.map(run_chunk, [spec] * len(todo), todo, pure=False)
        for f in futures:  # in chunk order
            done(f.result())
    finally:
        if isinstance(scheduler, str):
            client.close()


def run_chunks(spec, workers=1, scheduler=None, checkpoint=None, progress=None):
    """Every chunk's result, in chunk order; chunks recorded in ``checkpoint`` are not run again."""
    results = {}
    key = checkpoint_key(spec)
    if checkpoint is not None and Path(checkpoint).is_file():
        saved = _read_checkpoint(checkpoint)
        if saved["key"] == key:
            results = {int(k): v for k, v in saved["chunks"].items()}
    todo = [i for i in range(spec.chunks) if i not in results]

    def done(r):
        results[r["chunk"]] = r
        if checkpoint is not None:
            from .._io import write_text

            write_text(checkpoint, json.dumps({"key": key, "chunks": results}))
        if progress is not None:
            progress(r)

    for r in results.values():
        if progress is not None:
            progress(r)
    if scheduler is not None:
        _dask(spec, todo, scheduler, done)
    else:
        _local(spec, todo, workers, done)
    return [results[i] for i in range(spec.chunks)]


def _read_checkpoint(path):
    """A checkpoint's ``{key, chunks}``; anything else (not JSON, another layout) is refused, never resumed or
    overwritten."""
    from .._arrays import InputError

    try:
        saved = json.loads(Path(path).read_text())
    except (ValueError, UnicodeDecodeError) as exc:
        raise InputError(f"--out: {path} is not a sweep checkpoint ({type(exc).__name__}); move it away") from None
    if not (isinstance(saved, dict) and "key" in saved and isinstance(saved.get("chunks"), dict)
            and all(str(k).isdigit() for k in saved["chunks"])):
        raise InputError(f"--out: {path} is not a sweep checkpoint (no key and numbered chunks); move it away")
    return saved


def checkpoint_key(spec):
    """What a checkpoint must match to be resumed: case, port, drivers, seed, rows, profile."""
    port = spec.port
    src = ""
    if port.path is not None and Path(port.path).is_file():
        import hashlib

        src = hashlib.sha256(Path(port.path).read_bytes()).hexdigest()
    return json.dumps([spec.case.name, str(port.path), port.function, port.language, src, list(map(str, spec.drivers)),
                       spec.seed, spec.rows, spec.profile_key, CHUNK] + (["strict"] if spec.strict else []))
