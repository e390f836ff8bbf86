"""The scattering outputs' view of :func:`~moments_ref.pipeline.run` (public since the first release)."""

from __future__ import annotations

import time
from dataclasses import dataclass

from .. import techniques as _techniques
from .planner import SCATTERING_OUTPUTS
from .records import Settings
from .runner import run

__all__ = ["ScatteringResult", "scattering_stages", "run_scattering"]


@dataclass
class ScatteringResult:
    """What :func:`run_scattering` computed.

    Attributes
    ----------
    rows : list of dict with the columns of :data:`moments_ref.report.COLUMNS`
    images : dict name -> (H, W) scattering term (``reference`` included)
    t_max : float, the normalization of the scattering term (longest view ray)
    stages : list of str, the stages that ran
    seconds : float, wall-clock seconds of the whole call
    settings : dict, the settings used
    """

    rows: list
    images: dict
    t_max: float
    stages: list
    seconds: float
    settings: dict


def scattering_stages(samples):
    """Keys of the stages of the scattering outputs for a map with ``samples`` MSAA samples.

    ``scattering_raster_shadow_map``, ``scattering_camera_rays``,
    ``scattering_raymarch_reference``, per six-moment technique its texture steps
    (the shared moment steps with the prefix ``scattering_``) and
    ``shade_<technique>``, then ``scattering_raymarch``.
    """
    from ..techniques.scattering import MAP, RAYS, REFERENCE

    out = [MAP, RAYS, REFERENCE]
    for name in SCATTERING_OUTPUTS:
        steps = _techniques.get(name).steps(int(samples), False)
        for step in steps:
            out.append(step.key if step.key.startswith("scattering_") else "scattering_" + step.key)
        if steps:
            out.append(f"shade_{name}")
    out.append("scattering_raymarch")
    return out


def run_scattering(scene, *, shadow_map_size=None, msaa=None, resolution=None, epipolar_size=None,
                   reference_samples=None, raymarch_samples=None):
    """Rows of the scattering outputs of a scene: :func:`run` on :data:`SCATTERING_OUTPUTS`.

    Parameters as :func:`run` (defaults: the scene's); ``epipolar_size``,
    ``reference_samples`` and ``raymarch_samples`` as the settings of reference
    ``raymarch`` (:func:`moments_ref.techniques.scattering.configure`).

    Returns
    -------
    ScatteringResult
    """
    if not hasattr(scene, "receiver"):
        from ..scene import load_scene

        scene = load_scene(scene)
    t0 = time.perf_counter()
    over = {"epipolar_size": epipolar_size, "reference_samples": reference_samples,
            "raymarch_samples": raymarch_samples}
    r = run(scene, list(SCATTERING_OUTPUTS), Settings(shadow_map_size=shadow_map_size, msaa=msaa, resolution=resolution,
                                                      overrides={"scattering": {k: v for k, v in over.items()
                                                                                if v is not None}}))
    seconds = time.perf_counter() - t0
    first = r.techniques[0]
    images = {"reference": r.reference[first], **{n: r.shadow[n] for n in r.techniques}}
    from ..techniques.scattering import RAYS

    return ScatteringResult(rows=r.rows(), images=images, t_max=float(r.values[RAYS][1]), stages=r.stages,
                            seconds=seconds, settings=r.settings["raymarch"])
