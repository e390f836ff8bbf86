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
