"""The report pipeline's peak resident memory per shadow-map texel (issue 41, item 3).

A child process runs :func:`moments_ref.pipeline.run` on one scene as the report
does (``Settings.keep``: every stage's value released after its last use, except
what the report's claims read) and reports its peak resident set
(``VmHWM`` where Linux gives it: ``ru_maxrss`` survives ``fork`` and ``exec``, so a child of a
large bench process reported the parent's peak at every size); the same child at a 64² map is the baseline (the interpreter,
the imports and the camera-sized arrays, which do not grow with the map). The
figure is ``(peak − baseline) / texels``.
"""

from __future__ import annotations

import json
import subprocess
import sys

__all__ = ["pipeline_peak_bytes"]

_CHILD = """
import json, resource, sys
from moments_ref import pipeline
from moments_ref.report import paper_claims
from moments_ref.scene import load_scene
from moments_ref.techniques.scattering import RAYS
scene, size, msaa, w, h = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), int(sys.argv[4]), int(sys.argv[5])
st = pipeline.Settings(shadow_map_size=size, msaa=msaa, resolution=(w, h), clock="cpu", repeats=1,
                       keep=(*paper_claims.stages_read(msaa), RAYS))
pipeline.run(load_scene(scene), None, st)
try:  # VmHWM: this process image's own peak (ru_maxrss keeps the parent's peak across fork and exec)
    with open("/proc/self/status") as f:
        peak = next(int(line.split()[1]) for line in f if line.startswith("VmHWM:"))
except (OSError, StopIteration):
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
print(json.dumps({"maxrss_kib": peak}))
"""


def _child_peak(scene, size, msaa, resolution):
    args = [sys.executable, "-c", _CHILD, scene, str(size), str(msaa), *map(str, resolution)]
    out = subprocess.run(args, capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])["maxrss_kib"] * 1024


def pipeline_peak_bytes(scene="railing", size=2048, msaa=4, resolution=(480, 270), baseline_size=64):
    """``(bytes per texel, peak bytes, baseline bytes)`` of the pipeline run on ``scene`` at ``size``² ``msaa``×."""
    base = _child_peak(scene, baseline_size, msaa, resolution)
    peak = _child_peak(scene, size, msaa, resolution)
    return (peak - base) / (size * size), peak, base
