"""Issue 37, item 6: a chained float32 case gets the same verdict on both drivers, with the normal margin.

The chain of ``e2e-nlq32``/``e2e-nlq64`` written from the shipped ports (bias, Φ, pack, unpack, Algorithm 3:
four functions a GPU compiler contracts and reassociates together) runs on llvmpipe (GLSL) and lavapipe
(SPIR-V through wgpu). Its bands come from the enumerated evaluations (golden.gpuspread, gpu.fused32), not
from a 16 × margin; the chain passes on both, and ``--adapter both`` explains every differing row.
A chain with one wrong step (Algorithm 3 given ξ4 · 1.5) fails on both.
"""

from __future__ import annotations

import pytest

from moments_ref import conformance
from moments_ref.ports import PORTS_DIR

CHAIN = """
#include "{p}/msm.glsl"
#include "{p}/nonlinear.glsl"
#include "{p}/packing.glsl"
float e2e_nlq32(vec4 b, float zf) {{ return shade({r32}, zf); }}
float e2e_nlq64(vec4 b, float zf) {{ return shade({r64}, zf); }}
"""
R32 = "unpack32(pack32(phi(bias_moments_float32(b))))"
R64 = "unpack64(pack64(phi(bias_moments_float32(b))))"


def _file(tmp_path, wrong=False):
    scale = " * vec4(1.0, 1.0, 1.0, 1.5)" if wrong else ""
    f = tmp_path / ("wrong.glsl" if wrong else "chain.glsl")
    f.write_text(CHAIN.format(p=(PORTS_DIR / "glsl").as_posix(), r32=f"({R32}){scale}", r64=f"({R64}){scale}"))
    return f


@pytest.mark.parametrize("fmt", ["32", "64"])
def test_the_shipped_chain_passes_on_both_drivers(drivers, tmp_path, fmt):
    cmp = conformance.compare_drivers(_file(tmp_path), f"e2e_nlq{fmt}", f"e2e-nlq{fmt}-float32")
    assert cmp.passed, cmp.format()
    assert all(w["explained"] for w in cmp.explain())  # any row the drivers differ on lies in both bands


@pytest.mark.parametrize("fmt", ["32", "64"])
def test_a_wrong_step_in_the_chain_fails_on_both_drivers(drivers, tmp_path, fmt):
    cmp = conformance.compare_drivers(_file(tmp_path, wrong=True), f"e2e_nlq{fmt}", f"e2e-nlq{fmt}-float32")
    assert all(not r.passed for r in cmp.reports.values())
    assert all(r.categories["random"].failures > 0 for r in cmp.reports.values())
