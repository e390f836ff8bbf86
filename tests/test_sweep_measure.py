"""The sweep's measurements for docs/sweep.md (sweep/measure.py): what each table cell says, from records made here.

``tables`` turns the records of ``shipped_runs`` and ``mutant_runs`` into the docs' tables; ``main
--from-json`` merges several record files; ``shipped_runs`` and ``mutant_runs`` sweep what they list. The
sweeps themselves are replaced here by a recorder (``measure._run``) that returns records whose numbers are
chosen by hand, so every cell can be checked against them; the real sweeps are measured by tests/test_sweep.py
and the docs' own run.
"""

from __future__ import annotations

import json

import pytest

from moments_ref.sweep import measure

CASE = "shadow_intensity-lower-float32"


def _record(gl=(3, 1, 2), vulkan=None, ill=(5, 4), ungated=(7, 1), wall=2.4, rows=10**6, rates=None, strict=False):
    drivers = {"gl": dict(zip(("flagged", "confirmed", "unconfirmed"), gl))}
    if vulkan is not None:
        drivers["vulkan"] = dict(zip(("flagged", "confirmed", "unconfirmed"), vulkan))
    strata = {"one/near": {"ill_conditioned": ill[0], "ungated": ungated[0]},
              "two/end": {"ill_conditioned": ill[1], "ungated": ungated[1]}}
    return {"language": "glsl", "path": "msm.glsl", "function": "shadow_intensity_lower", "case": CASE,
            "drivers": drivers, "wall_s": wall, "rows": rows, "strata": strata, "strict": strict,
            "rows_per_s": rates or {"draw": 2.5e6, "reference": 31000.0, "driver": None}}


def _cells(line):
    return [c.strip() for c in line.strip().strip("|").split("|")]


def test_a_shipped_ports_row_sums_the_strata_and_names_each_driver():
    text = measure.tables([_record(vulkan=(4, 0, 4))], [], 10**6, note="Loaded machine.")
    lines = text.splitlines()
    assert lines[0].endswith("(gl = llvmpipe, vulkan = lavapipe). Loaded machine.")
    row = next(l for l in lines if l.startswith("| glsl/msm.glsl | `shadow_intensity_lower`"))
    assert _cells(row) == ["glsl/msm.glsl", "`shadow_intensity_lower`", CASE, "1e+06", "3 / 1 / 2", "4 / 0 / 4",
                           "9", "8", "2"]
    rate = next(l for l in lines if l.startswith("| glsl/msm.glsl | " + CASE))
    assert _cells(rate) == ["glsl/msm.glsl", CASE, "2.5·10^6", "3.1·10^4", "–", "–", "–"]


def test_a_driver_that_did_not_run_and_a_strict_run():
    text = measure.tables([_record(strict=True, rows=131072, wall=61.6)], [], 131072)
    row = next(l for l in text.splitlines() if l.startswith("| glsl/msm.glsl | `"))
    assert _cells(row) == ["glsl/msm.glsl", "`shadow_intensity_lower`", CASE, "1.31e+05", "3 / 1 / 2", "–", "9",
                           "gated (--strict)", "62"]


def _mutant(name="m1", shrunk=True, caught=False):
    f = {"texel": {"depths": [0.25, -0.5], "weights": [0.75, 0.25], "zf": 0.2500001, "format": 1},
         "got": {"intensity": 0.9}, "lo": {"intensity": 0.1}, "hi": {"intensity": 0.2}} if shrunk else None
    return {"name": name, "case": CASE, "region": "r", "flagged": 12, "confirmed": 7, "examined": 9, "first": 4242,
            "shrunk": f, "caught_by_goldens": caught}


def test_the_mutants_table_shows_counts_first_hit_and_the_shrunk_row():
    text = measure.tables([], [_mutant(), _mutant("m2", shrunk=False, caught=True)], 10**6, mutant_rows=2 * 10**5)
    lines = text.splitlines()
    assert any("200000 rows on llvmpipe" in l for l in lines)
    m1 = next(l for l in lines if l.startswith("| m1 |"))
    assert _cells(m1) == ["m1", "missed", "7 (9) / 12", "4242", "0.25, -0.5; 0.75, 0.25; 0.2500001; 64-bit",
                          "0.9 → [0.1, 0.2]"]
    m2 = next(l for l in lines if l.startswith("| m2 |"))
    assert _cells(m2) == ["m2", "caught", "7 (9) / 12", "4242", "–", "–"]
    assert "mutants of" not in measure.tables([_record()], [], 10**6)  # no mutants: no table


def test_from_json_merges_several_record_files(tmp_path, capsys):
    a, b = tmp_path / "a.json", tmp_path / "b.json"
    a.write_text(json.dumps({"rows": 10**6, "shipped": [_record()]}))
    b.write_text(json.dumps({"rows": 5, "shipped": [dict(_record(), language="hlsl", path="msm.hlsl")],
                             "mutants": [_mutant()], "mutant_rows": 300000}))
    doc = tmp_path / "sweep.md"
    doc.write_text("x\n<!-- measured:begin -->\nold\n<!-- measured:end -->\ny\n")
    assert measure.main(["--json", f"{a},{b}", "--from-json", "--doc", str(doc), "--note", "N."]) == 0
    out = doc.read_text()
    assert out.startswith("x\n<!-- measured:begin -->\n") and out.endswith("<!-- measured:end -->\ny\n")
    assert "| glsl/msm.glsl |" in out and "| hlsl/msm.hlsl |" in out and "| m1 |" in out
    assert "300000 rows on llvmpipe" in out and "| 1e+06 |" in out and " N." in out
    assert measure.main(["--json", str(a), "--from-json"]) == 0  # no --doc: printed
    assert "| glsl/msm.glsl |" in capsys.readouterr().out


class _Runs:
    def __init__(self):
        self.calls = []

    def __call__(self, case, path, function, language, drivers, rows, workers, shrink=True, strict=False):
        self.calls.append(dict(case=case, path=str(path), function=function, language=language, drivers=drivers,
                               rows=rows, workers=workers, strict=strict))
        rec = dict(_record(), case=case)
        rec["drivers"] = {d: {"flagged": 1, "confirmed": 0, "unconfirmed": 1, "examined": 1,
                              "first_confirmed": None} for d in drivers}
        rec["failures"] = []
        return rec


def test_shipped_runs_sweep_every_shipped_port_on_both_drivers(monkeypatch):
    from moments_ref.conformance import shipped_port

    runs = _Runs()
    monkeypatch.setattr(measure, "_run", runs)
    logged = []
    out = measure.shipped_runs(1000, cases=("shade-float32", "pack64-float32"), languages=("glsl", "wgsl"),
                               log=logged.append, strict=True)
    want = []
    for language in ("glsl", "wgsl"):
        for case in ("shade-float32", "pack64-float32"):
            try:
                want.append((language, case, shipped_port(case, language)))
            except Exception:  # noqa: BLE001 - a language without that port is skipped
                pass
    assert [(c["language"], c["case"]) for c in runs.calls] == [(w[0], w[1]) for w in want]
    assert all(c["drivers"] == ("gl", "vulkan") and c["rows"] == 1000 and c["workers"] == 2 and c["strict"]
               for c in runs.calls)
    assert [(r["language"], r["case"], r["function"], r["strict"]) for r in out] == [
        (w[0], w[1], w[2][1], True) for w in want]
    assert [r["path"] for r in out] == [w[2][0].name for w in want]
    assert len(logged) == len(want) and logged[0].startswith(f"{want[0][0]} {want[0][1]}: gl 1 / 0 / 1")


def test_mutant_runs_sweep_each_mutant_of_a_corpus_on_llvmpipe(monkeypatch, tmp_path):
    from moments_ref.conformance import PORTS_DIR

    corpus = tmp_path / "corpus.py"
    corpus.write_text(
        'RET = "return (zf <= y2) ? wl : 1.0 - wl;"\n'
        'MUTANTS = [("swap", "nonlinear.glsl", "shade", "shade-float32", RET, '
        '"return (zf <= y2) ? 1.0 - wl : wl;", "everywhere"),\n'
        '           ("none", "nonlinear.glsl", "shade", "shade-float32", "no such text", "x", "nowhere")]\n'
        'CAUGHT_BY_THE_GOLDENS = ["swap"]\n')
    seen = {}

    def run(case, path, function, language, drivers, rows, workers, shrink=True, strict=False):
        seen[path.name] = path.read_text()
        confirmed = 5 if path.name == "swap.glsl" else 0
        return {"drivers": {"gl": {"flagged": 6, "confirmed": confirmed, "examined": 6,
                                   "first_confirmed": 17 if confirmed else None}},
                "failures": [{"texel": {}}] if confirmed else []}

    monkeypatch.setattr(measure, "_run", run)
    out = measure.mutant_runs(corpus, 4096, tmp_path, log=lambda s: None)
    src = (PORTS_DIR / "glsl" / "nonlinear.glsl").read_text()
    assert seen["swap.glsl"] == src.replace("return (zf <= y2) ? wl : 1.0 - wl;", "return (zf <= y2) ? 1.0 - wl : wl;", 1)
    assert seen["none.glsl"] == src
    assert out[0] == {"name": "swap", "case": "shade-float32", "region": "everywhere", "flagged": 6, "confirmed": 5,
                      "examined": 6, "first": 17, "shrunk": {"texel": {}}, "caught_by_goldens": True}
    assert out[1]["shrunk"] is None and out[1]["first"] is None and out[1]["caught_by_goldens"] is False


def test_run_sweeps_one_port_and_records_its_wall_time(monkeypatch):
    calls = []

    class Result:
        def record(self):
            return {"wall_s": -1.0}

    def sweep(spec, workers, shrink_failures=True):
        calls.append((spec, workers, shrink_failures))
        return Result()

    monkeypatch.setattr(measure, "sweep_port", sweep)
    rec = measure._run(CASE, "p.glsl", "f", "glsl", ["gl"], 77, 3, shrink=False, strict=True)
    (spec, workers, shrink), = calls
    assert (spec.case_name, spec.port.path, spec.port.function, spec.port.language) == (CASE, "p.glsl", "f", "glsl")
    assert spec.drivers == ("gl",) and spec.rows == 77 and spec.strict and workers == 3 and shrink is False
    assert rec["wall_s"] >= 0


@pytest.mark.parametrize("x, text", [(2.5e6, "2.5·10^6"), (31000.0, "3.1·10^4"), (1.2e10, "1.2·10^10"), (None, "–"),
                                     (0, "–"), (512.0, "5.1·10^2")])
def test_rates_are_written_with_two_digits(x, text):
    assert measure._rate(x) == text
