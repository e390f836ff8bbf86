"""The stage graph of a run: stages under their keys, computed on demand, each once, timed.

:class:`StageGraph` is where a run's stages are shared (equal keys are one stage) and
cached (each value computed once and handed to every stage that depends on it);
:func:`spread`, :func:`cost` and :func:`used_by` turn its per-stage seconds into the
records of :mod:`moments_ref.pipeline.records`.
"""

from __future__ import annotations

import time

import numpy as np

from .._arrays import InputError
from ..techniques import Stage

__all__ = ["StageGraph", "clock_named", "spread", "cost", "used_by"]


class StageGraph:
    """Stages under their keys, with dependencies, evaluated on demand, each once."""

    def __init__(self):
        self.nodes = {}

    def add(self, stage: Stage) -> str:
        """Add ``stage`` under its key; an equal stage again is shared, a different one raises."""
        key = stage.key
        old = self.nodes.get(key)
        if old is None:
            self.nodes[key] = stage
        elif not old.same_as(stage):
            raise ValueError(f"stage {key!r} added twice with different steps (dependencies {old.deps} and "
                             f"{stage.deps}); give one of them its own name or parameters")
        return key

    def order(self, targets):
        """Topological order of the stages ``targets`` need (dependencies first)."""
        seen, out = set(), []

        def visit(n, stack=()):
            if n in seen:
                return
            if n in stack:
                raise RuntimeError(f"cycle through stage {n}")
            for d in self.nodes[n].deps:
                visit(d, stack + (n,))
            seen.add(n)
            out.append(n)

        for t in targets:
            visit(t)
        return out

    def run(self, targets, progress=False, desc="stages", timed=(), repeats=1, clock=time.perf_counter,
            warmup=True, keep=None):
        """Compute the stages ``targets`` need; return ``(order, values, times)``.

        A stage in ``timed`` runs once as a warm-up (its value is kept) and then
        ``repeats`` times more, each timed; ``times[stage]`` lists those seconds
        (one entry, the single run, for the other stages), read from ``clock``.
        Without ``warmup`` the first run is the first of the ``repeats``.
        ``keep=None`` returns every stage's value; otherwise a value is released
        once the last stage that depends on it has run, unless it is a target or
        named in ``keep`` (``values`` then holds only those): the run's peak memory
        is its largest live set, not the sum of its stages.
        """
        order = self.order(targets)
        values, times = {}, {}
        last = None if keep is None else _last_use(self.nodes, order, set(targets) | set(keep))
        bar = _stage_bar(progress, len(order), desc)
        try:
            for name in order:
                stage = self.nodes[name]
                if bar is not None:
                    bar.set_postfix_str(name, refresh=False)
                args = [values[d] for d in stage.deps]
                t0 = clock()
                values[name] = stage(*args)
                times[name] = [clock() - t0]
                if name in timed:
                    more = [_timed(stage, args, clock, values, name, keep is not None)
                            for _ in range(max(int(repeats), 1) - (not warmup))]
                    times[name] = more if warmup else times[name] + more
                args = None
                for d in () if last is None else last.get(name, ()):
                    del values[d]
                if bar is not None:
                    bar.update(1)
        finally:
            if bar is not None:
                bar.close()
        return order, values, times


def _last_use(nodes, order, kept):
    """Stage -> the dependencies whose value can go once it has run (their last use; ``kept`` never)."""
    last = {}
    for name in order:
        for d in nodes[name].deps:
            last[d] = name
    out = {}
    for d, name in last.items():
        if d not in kept:
            out.setdefault(name, []).append(d)
    return out


def _timed(stage, args, clock, values, name, replace):
    """Seconds of one more run of ``stage``; with ``replace`` its value takes the place of the previous run's.

    Replacing (when values are released after their last use, ``keep``) frees the
    previous run's value before the timed run instead of holding both: the stages
    are deterministic, so the value is the same, and a texture stage's timed run no
    longer doubles its output at the run's peak (docs/bench.md, "The report
    pipeline's memory"). The freeing happens outside the clock.
    """
    if replace:
        values[name] = None
    t0 = clock()
    value = stage(*args)
    elapsed = clock() - t0
    if replace:
        values[name] = value
    return elapsed


def _stage_bar(progress, total, desc):
    if not progress:
        return None
    import sys

    from tqdm import tqdm

    return tqdm(total=total, desc=desc, unit="stage", file=sys.stderr, leave=False)


def clock_named(name):
    """The timer of ``run(clock=name)``."""
    clocks = {"wall": time.perf_counter, "cpu": time.process_time}
    if name not in clocks:
        raise InputError(f"clock: expected one of {', '.join(clocks)}, got {name!r}")
    return clocks[name]


def spread(per_repeat):
    """(median, min, max) of a list of seconds."""
    a = np.asarray(per_repeat, dtype=float)
    return float(np.median(a)), float(a.min()), float(a.max())


def cost(times, keys, repeats):
    """Per repeat the sum of the stages ``keys`` (a stage run once counts its one time in each)."""
    if not keys:
        return [0.0] * repeats
    return [float(sum(times[k][min(i, len(times[k]) - 1)] for k in keys)) for i in range(repeats)]


def used_by(graph, plans, order):
    """Stage -> the techniques whose result or reference depends on it (run order)."""
    out = {k: [] for k in order}
    for n, t in plans.items():
        for k in graph.order([x for x in (t.shade, t.reference) if x]):
            out[k].append(n)
    return out
