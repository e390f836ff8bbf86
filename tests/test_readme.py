"""The README's two commands are what CI runs and what the package provides."""

from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _commands():
    lines = (ROOT / "README.md").read_text().splitlines()
    return [line.strip() for line in lines if line.startswith("    pip install")]


def test_readme_starts_with_two_commands():
    main, tests = _commands()[:2]
    assert main.startswith("pip install -e . && moments-ref report")
    assert tests == 'pip install -e ".[test]" && python -m pytest -q -n auto'  # pytest-xdist: every core


def test_ci_runs_the_readme_test_command():
    tests = _commands()[1]
    assert tests in (ROOT / ".ci" / "run").read_text()


def test_main_job_subcommand_exists():
    from moments_ref.cli import build_parser

    parser = build_parser()
    sub = next(a for a in parser._actions if a.dest == "command")
    for name in ("report", "golden", "verify", "bench", "stability", "figure3", "figure4", "banks", "vwss",
                 "conformance"):
        assert name in sub.choices


def test_readme_is_a_front_door():
    """About 150 lines a newcomer reads in three minutes: no measurement logs, one row per subcommand.

    The run-time logs live in docs/bench.md and docs/testing.md, the report's description in
    docs/report.md, the layout table in docs/architecture.md.
    """
    from moments_ref.cli import build_parser

    text = (ROOT / "README.md").read_text()
    assert len(text.splitlines()) <= 160
    assert "<!-- layout: begin -->" not in text and " runs: " not in text and "load average" not in text
    sub = next(a for a in build_parser()._actions if a.dest == "command")
    table = [line for line in text.splitlines() if line.startswith("| ")]
    missing = [name for name in sub.choices if not any(f"`moments-ref {name}" in line for line in table)]
    assert missing == [], f"subcommands without a row in the README's task table: {missing}"
