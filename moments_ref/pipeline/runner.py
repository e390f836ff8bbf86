"""Running a plan: compute the stages the techniques and their references need, time their costs."""

from __future__ import annotations

from .graph import clock_named, cost, spread, used_by
from .planner import plan
from .records import RunResult, settings_of

__all__ = ["run"]


def _intensity(value, kind):
    """Shadow intensity of a stage value that holds ``kind`` ("intensity" or "visibility", ``1 − intensity``)."""
    return 1.0 - value if kind == "visibility" else value


def _grouped(plans, keep):
    """The run's targets, those of techniques sharing their first texture stage next to each other.

    With values released after their last use (``Settings.keep``), a texture stage
    shared by several techniques (the blurred moments of vsm, msm64 and msm128) then
    goes before the next technique's stages start, not at the end of the run. Groups
    holding a stage of ``keep`` go last (their kept texture does not add to the
    other groups' live values).
    """
    groups, kept = {}, set(keep)
    for t in plans.values():
        g = groups.setdefault(t.texel[0] if t.texel else t.name, [False])
        g[0] = g[0] or bool(kept & set(t.texel))
        g += [k for k in (t.shade, t.reference) if k]
    ordered = sorted(groups.values(), key=lambda g: g[0])  # stable: groups with a kept texture last
    return list(dict.fromkeys(k for g in ordered for k in g[1:]))


def run(scene, outputs=None, settings=None, **old) -> RunResult:
    """Compute the requested techniques' results on a scene's camera view, lazily.

    Parameters
    ----------
    scene : Scene or str
        A loaded scene, a shipped scene name or a scene file path.
    outputs : list of str or Technique, optional
        Registered technique names (default: the scene's ``outputs``), or
        techniques built by the caller. Unknown names raise
        :class:`~moments_ref.InputError` listing the known ones; techniques that
        cannot run on the scene raise it with the reason.
    settings : Settings, optional
        Sizes, references, repeats and clock (:class:`Settings`; default the
        scene's own). The old keyword arguments (``shadow_map_size=``, ``msaa=``,
        ..., ``area=``, ``settings={option: overrides}``, ``given=``) still work
        for one release, with a DeprecationWarning.

    Returns
    -------
    RunResult
    """
    if not hasattr(scene, "receiver"):
        from ..scene import load_scene

        scene = load_scene(scene)
    st = settings_of(settings, old, "run")
    rp = plan(scene, outputs, st)
    plans = rp.techniques
    timed = {k for t in plans.values() for k in (*t.texel, t.shade)}
    repeats = max(int(st.repeats), 1)
    targets = rp.targets if st.keep is None else _grouped(plans, st.keep)
    order, values, times = rp.graph.run(targets, progress=st.progress, desc=scene.name, timed=timed,
                                        repeats=repeats, clock=clock_named(st.clock), warmup=st.warmup,
                                        keep=None if st.keep is None else (rp.context.receivers, *st.keep))
    seconds = {k: spread(v)[0] for k, v in times.items()}
    spreads = {n: {"texel": spread(cost(times, t.texel, repeats)),
                   "fragment": spread(cost(times, [t.shade], repeats))} for n, t in plans.items()}
    ctx = rp.context
    return RunResult(scene=ctx.scene, techniques=list(plans), stages=order, seconds=seconds,
                     gbuffer=values.get(ctx.receivers),
                     shadow={n: _intensity(values[t.shade], t.result) for n, t in plans.items()},
                     reference={n: _intensity(values[t.reference], t.reference_result)
                                for n, t in plans.items() if t.reference},
                     texel_seconds={n: v["texel"][0] for n, v in spreads.items()},
                     fragment_seconds={n: v["fragment"][0] for n, v in spreads.items()},
                     shadow_map_size=ctx.size, msaa=ctx.samples, values=values,
                     bits_per_texel={n: t.bits for n, t in plans.items()}, area=rp.settings.get("mvr", {}),
                     settings=rp.settings, truth={n: t.truth for n, t in plans.items()}, times=times,
                     repeats=repeats, used_by=used_by(rp.graph, plans, order), spread=spreads, plans=plans)

