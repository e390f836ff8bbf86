"""The sweep's rows/s for ``moments-ref bench`` (sweep/timing.py), with the chunks' runs replaced by a recorder
whose stage seconds the test chooses: the rates are rows over seconds, per stage summed over the chunks."""

from __future__ import annotations

import math

import pytest

from moments_ref.sweep import CHUNK, timing
from moments_ref.sweep.runner import STAGES


class _Chunks:
    def __init__(self, seconds):
        self.seconds, self.specs = seconds, []

    def __call__(self, spec):
        self.specs.append(spec)
        return [{"seconds": dict(self.seconds)} for _ in range(spec.chunks)]


@pytest.fixture
def chunks(monkeypatch):
    fake = _Chunks({"draw": 0.5, "reference": 2.0, "driver": 0.25, "compare": 0.0, "confirm": 1.0})
    monkeypatch.setattr(timing, "run_chunks", fake)
    return fake


def test_the_rates_are_rows_over_the_summed_stage_seconds(chunks):
    (row,) = timing.bench_sweep(cases=("shade-float32",), chunks=2)
    warm, timed = chunks.specs
    assert warm.rows == 1000 and timed.rows == 2 * CHUNK and timed.drivers == ("gl",)
    assert timed.port.language == "glsl" and timed.port.function == "shade" and timed.case_name == "shade-float32"
    assert row["rows"] == 2 * CHUNK and row["case"] == "shade-float32"
    assert row["draw_rows_per_s"] == 2 * CHUNK / 1.0 and row["reference_rows_per_s"] == 2 * CHUNK / 4.0
    assert row["confirm_rows_per_s"] == 2 * CHUNK / 2.0 and math.isinf(row["compare_rows_per_s"])
    assert row["rows_per_s"] == pytest.approx(row["rows"] / row["wall_s"]) and row["wall_s"] > 0


def test_the_markdown_table_has_a_row_per_case(chunks):
    text = timing.sweep_markdown(chunks=1)
    lines = text.splitlines()
    assert lines[0] == f"## Sweep: rows/s per stage (shipped GLSL ports on gl, one process, 1 chunks of {CHUNK} rows)"
    assert lines[2] == "| case | rows | end to end rows/s | " + " | ".join(STAGES) + " |"
    body = [l for l in lines if l.startswith("| shadow") or l.startswith("| shade")]
    assert [l.split("|")[1].strip() for l in body] == list(timing.BENCH_CASES)
    cells = [c.strip() for c in body[0].strip("|").split("|")]
    assert cells[1] == str(CHUNK) and cells[3:] == [f"{CHUNK / s:.3g}" if s else "inf" for s in (0.5, 2.0, 0.25, 0, 1.0)]


def test_no_opengl_context_skips_the_section(monkeypatch):
    from moments_ref.conformance import ContextError

    def no_context(**_):
        raise ContextError("no display")

    monkeypatch.setattr(timing, "bench_sweep", no_context)
    assert timing.sweep_markdown() == "## Sweep\n\nskipped: no OpenGL context (no display)\n"
