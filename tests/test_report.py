"""The report on a tiny scene: files, columns, plot, claims, refusals, interruption, notebook."""

import csv
import json
import math
import shutil
from pathlib import Path

import numpy as np
import pytest

from moments_ref import report

ROOT = Path(__file__).resolve().parents[1]
# jobs=1: everything in this process (the workers' own results are test_report_parallel's)
TINY = dict(progress=False, shadow_map_size=48, resolution=(48, 27), noise_tiles=1, repeats=2, jobs=1)


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    out = tmp_path_factory.mktemp("report")
    return out, report.run(scenes=["translucent"], out_dir=out, all_techniques=True, **TINY)


def test_files_columns_and_plot(tiny):
    out, res = tiny
    assert {p.name for p in out.iterdir()} == {"results.csv", "stages.json", "report.md", "front_pcf.png",
                                               "errors_translucent.png", "claims.json", "crops_translucent_pcf.png",
                                               "winners.csv"}
    with open(out / "results.csv", newline="") as f:
        rows = list(csv.reader(f))
    assert tuple(rows[0]) == report.COLUMNS
    techs = [r[1] for r in rows[1:]]
    assert "pcf" in techs and "translucent_msm" in techs and "nlq32_dither" in techs
    assert (out / "front_pcf.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    md = (out / "report.md").read_text()
    assert "| scene | technique | bits_per_texel" in md and "front_pcf.png" in md and "errors_translucent.png" in md
    assert "## Where the techniques differ most" in md and "![crops](crops_translucent_pcf.png)" in md
    stages = json.loads((out / "stages.json").read_text())
    assert "translucency_pass" in [s["stage"] for s in stages["translucent"]]
    assert report.read_results(out / "results.csv")[0].keys() == set(report.COLUMNS)


def test_winners_name_the_lowest_rmse_of_results_within_each_budget(tiny):
    """winners.csv and report.md's answer, checked against results.csv by a plain search."""
    out, _ = tiny
    rows = report.read_results(out / "results.csv")
    with open(out / "winners.csv", newline="") as f:
        found = list(csv.DictReader(f))
    assert found and {w["budget_kind"] for w in found} == {"bits_per_texel", "total_seconds"}
    for w in found:
        b = float(w["budget"])
        key = "bits_per_texel" if w["budget_kind"] == "bits_per_texel" else "own_total_seconds"
        fit = [r for r in rows if r["scene"] == w["scene"] and float(r[key]) <= b * (1 + 1e-5)]
        assert min(float(r["rmse"]) for r in fit) == pytest.approx(float(w["rmse"]), rel=1e-5)
        assert w["technique"] in {r["technique"] for r in fit if float(r["rmse"]) == pytest.approx(float(w["rmse"]),
                                                                                                   rel=1e-5)}
    pcf = next(r for r in rows if r["technique"] == "pcf")
    assert int(pcf["bits_per_texel"]) == 32 * 4  # every MSAA sample of the 4× map is read
    md = (out / "report.md").read_text()
    assert "## The answer: lowest RMSE at each budget" in md and "**translucent** (reference `pcf`)" in md


def test_claims_are_the_papers_terms_only(tiny):
    """report.md and run() give claims.json's verdicts; the fixed 10 %/90 % criteria are not printed."""
    out, res = tiny
    assert res["claims"] == json.loads((out / "claims.json").read_text())
    md = (out / "report.md").read_text()
    assert "## Paper claims (claims.json)" in md
    assert "Headline claims" not in md and "close = RMSE within" not in md


def test_metrics_against_the_reference(tiny):
    _, res = tiny
    rows = {r["technique"]: r for r in res["rows"]}
    assert rows["translucent_msm"]["rmse"] < rows["msm64"]["rmse"]  # the sheet's shadow is only in translucent_msm
    assert rows["msm64"]["leak_fraction"] > 0
    for r in res["rows"]:
        assert r["texel_seconds"] >= 0 and r["fragment_seconds"] > 0
    pytest.importorskip("flip_evaluator")
    assert all(np.isfinite(r["flip_mean"]) for r in res["rows"])


def test_metrics_by_hand():
    s = np.array([0.0, 0.5, 1.0, 0.2])
    r = np.array([0.1, 0.5, 0.9, 0.2])
    m = report.metrics(s, r)
    assert m["rmse"] == pytest.approx(math.sqrt(0.02 / 4))
    assert m["max_error"] == pytest.approx(0.1)
    assert m["leak_fraction"] == 0.25  # only the first pixel is lit more than 0.05 above
    assert report.metrics(s, s)["leak_fraction"] == 0.0


def test_light_metrics_by_hand():
    """Scattered light leaks where it is brighter than the reference (by more than 0.05 of t_max)."""
    from moments_ref.metrics import light_metrics

    light = np.array([2.0, 1.0, 0.0, 1.5])
    ref = np.array([1.0, 1.0, 0.5, 1.45])  # errors / t_max: +0.5, 0, -0.25, +0.025
    m = light_metrics(light, ref, 2.0)
    assert m["rmse"] == pytest.approx(math.sqrt((0.25 + 0.0625 + 0.025 ** 2) / 4))
    assert m["max_error"] == pytest.approx(0.5)
    assert m["leak_fraction"] == 0.25  # only the first is brighter by more than 0.05; the last by 0.025


def test_flip_of_identical_images_is_zero(monkeypatch):
    flip_evaluator = pytest.importorskip("flip_evaluator")
    img = np.random.default_rng(0).random((20, 30, 3)).astype(np.float32)
    # ꟻLIP's own value for equal images, which flip_mean returns without calling it
    for pair in ((img, img.copy()), (np.zeros_like(img), np.zeros_like(img)), (np.ones_like(img), np.ones_like(img))):
        assert flip_evaluator.evaluate(*pair, "LDR", applyMagma=False)[1] == 0.0
    calls = []
    evaluate = flip_evaluator.evaluate
    monkeypatch.setattr(flip_evaluator, "evaluate", lambda *a, **k: calls.append(1) or evaluate(*a, **k))
    assert report.flip_mean(img, img.copy()) == 0.0 and not calls
    one = img.copy()
    one[3, 4, 1] += 0.25  # one channel of one pixel differs: ꟻLIP is asked, and sees it
    assert report.flip_mean(img, one) > 0 and len(calls) == 1
    assert report.flip_mean(img, 1 - img) > 0.1


def _rows(values):
    out = []
    for (scene, tech), (rmse, leak) in values.items():
        out.append({"scene": scene, "technique": tech, "bits_per_texel": 64, "rmse": rmse, "max_error": rmse,
                    "p99_error": rmse, "leak_fraction": leak, "flip_mean": 0.0, "texel_seconds": 1.0,
                    "fragment_seconds": 1.0})
    return out


def test_claims_verdicts():
    good = {("railing", "nlq64"): (0.010, 0.0), ("railing", "msm128"): (0.0102, 0.0),
            ("railing", "msm64"): (0.03, 0.0), ("railing", "vsm"): (0.1, 0.0),
            ("railing", "nlq32"): (0.0105, 0.0), ("facade", "nlq64"): (0.01, 0.0), ("facade", "nlq32"): (0.02, 0.0),
            ("three-occluders", "msm64"): (0.01, 0.01), ("three-occluders", "nlq64"): (0.01, 0.002)}
    verdicts = [v for _, v, _ in report.evaluate_claims(_rows(good), four_moment=["msm64", "nlq64"])]
    assert verdicts == [True, True, True]
    bad = dict(good)
    bad[("railing", "msm64")] = (0.0105, 0.0)
    bad[("facade", "nlq32")] = (0.0101, 0.0)
    bad[("three-occluders", "nlq64")] = (0.01, 0.0)
    verdicts = [v for _, v, _ in report.evaluate_claims(_rows(bad), four_moment=["msm64", "nlq64"])]
    assert verdicts == [False, False, False]
    assert [v for _, v, _ in report.evaluate_claims([])] == [None, None, None]


def test_unknown_names_list_known_ones(tmp_path, capsys):
    from moments_ref import InputError

    with pytest.raises(InputError, match="known scenes: chair, facade"):
        report.run(scenes=["nope"], out_dir=tmp_path / "a", **TINY)
    with pytest.raises(InputError, match="known techniques"):
        report.run(scenes=["facade"], out_dir=tmp_path / "b", techniques=["zzz"], **TINY)
    assert report.main(["--scene", "nope", "--out", str(tmp_path / "c")]) == 2
    assert "known scenes" in capsys.readouterr().err
    assert report.main([]) == 2  # --out is required
    assert not (tmp_path / "a").exists() and not (tmp_path / "c").exists()


def test_interrupted_run_leaves_no_partial_files(tmp_path, monkeypatch):
    calls = {"n": 0}
    real = report.pipeline.run

    def interrupted(*a, **k):
        calls["n"] += 1
        if calls["n"] == 2:
            raise KeyboardInterrupt
        return real(*a, **k)

    monkeypatch.setattr(report.pipeline, "run", interrupted)
    with pytest.raises(KeyboardInterrupt):  # jobs=1: the patch reaches the scenes (worker processes import afresh)
        report.run(scenes=["translucent", "facade"], out_dir=tmp_path / "r", **TINY)
    assert not (tmp_path / "r").exists() or not any((tmp_path / "r").iterdir())
    monkeypatch.setattr(report.pipeline, "run", real)

    # Interrupted while writing: the files written are complete, no temporary file is left.
    real_write = report.write_text

    def write_then_stop(path, text):
        if Path(path).name == "report.md":
            raise KeyboardInterrupt
        return real_write(path, text)

    monkeypatch.setattr(report, "write_text", write_then_stop)
    with pytest.raises(KeyboardInterrupt):
        report.run(scenes=["translucent"], out_dir=tmp_path / "s", **TINY)
    names = {p.name for p in (tmp_path / "s").iterdir()}
    assert "report.md" not in names and not any(n.startswith(".") for n in names)
    assert "INCOMPLETE" in names  # the folder says that its report was not completely written
    assert report.read_results(tmp_path / "s" / "results.csv")


def test_notebook_executes_on_a_tiny_report(tiny, tmp_path, monkeypatch):
    import nbclient
    import nbformat

    out, _ = tiny
    monkeypatch.setenv("MOMENTS_REF_RESULTS", str(out / "results.csv"))
    work = tmp_path / "error_vs_runtime.ipynb"
    shutil.copy(ROOT / "notebooks" / "error_vs_runtime.ipynb", work)
    nb = nbformat.read(work, as_version=4)
    nbclient.NotebookClient(nb, timeout=120, kernel_name="python3",
                            resources={"metadata": {"path": str(tmp_path)}}).execute()
    outputs = [o for c in nb.cells if c.cell_type == "code" for o in c.get("outputs", [])]
    assert not [o for o in outputs if o.get("output_type") == "error"]
    assert any("translucent" in o.get("data", {}).get("text/plain", "") for o in outputs)


def test_the_copy_rate_is_the_best_of_its_cpu_times(monkeypatch):
    # The report measures it while its workers start: a wall clock would count their start-up.
    from moments_ref.report import _machine

    ticks = iter([0.0, 0.25, 1.0, 1.125, 2.0, 2.5])  # copies of 0.25, 0.125 and 0.5 CPU seconds
    monkeypatch.setattr(_machine.time, "process_time", lambda: next(ticks))
    monkeypatch.setattr(_machine.time, "perf_counter", lambda: pytest.fail("timed by the wall clock"))
    assert _machine.copy_rate(nbytes=2 ** 20, repeat=3) == 2 ** 23
    text = " ".join(_machine.machine_lines(_machine.machine(), 5.25e9))
    assert "128 MiB, best of 3 in CPU seconds): 5.25 GB/s" in text


def test_the_column_table_of_docs_report_is_generated():
    """docs/report.md lists results.csv's columns from moments_ref/report/columns.py, the one list."""
    from pathlib import Path

    from moments_ref.report.columns import COLUMN_TABLE, COLUMNS, FLOAT_COLUMNS, columns_markdown

    text = (Path(__file__).resolve().parents[1] / "docs" / "report.md").read_text()
    table = text.split("<!-- columns: begin -->\n", 1)[1].split("\n<!-- columns: end -->", 1)[0]
    assert table == columns_markdown(), "regenerate: python -m moments_ref.tools.apidoc --columns"
    assert report.COLUMNS == COLUMNS and len(set(COLUMNS)) == len(COLUMNS)
    assert {"rmse", "flip_mean", "own_total_seconds_max"} <= set(FLOAT_COLUMNS)
    assert not {"scene", "bits_per_texel", "repeats", "pareto"} & set(FLOAT_COLUMNS)
    assert {c.kind for c in COLUMN_TABLE} == {"text", "int", "float", "bool"}


def test_results_csv_reads_back_by_column_kind(tmp_path):
    """csv_text then read_results gives each column back in its kind (by name, not by position)."""
    from moments_ref.report._text import csv_text, read_results
    from moments_ref.report.columns import COLUMNS

    row = {c: 0.25 for c in COLUMNS}
    row.update(scene="s", technique="msm64", bits_per_texel=64, repeats=3, pareto=True, flip_mean=float("nan"))
    (tmp_path / "results.csv").write_text(csv_text([row]))
    back = read_results(tmp_path / "results.csv")[0]
    assert back.pop("bits_per_texel") == 64 and back.pop("repeats") == 3 and back.pop("pareto") is True
    assert back.pop("scene") == "s" and back.pop("technique") == "msm64" and math.isnan(back.pop("flip_mean"))
    assert back == {c: 0.25 for c in back} and len(back) == len(COLUMNS) - 6
