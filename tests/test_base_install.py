"""The base install (``pip install -e .``, no extras) can use the oracle.

A virtual environment with only the base dependencies of pyproject.toml (no
hypothesis, no pytest) is built once under the temporary folder and reused
while the dependency list stays the same; the package itself runs from this
checkout. The README's oracle snippet must run there, and a check that draws
rows with hypothesis must say in one line that they need the ``test`` extra.
Where the dependencies cannot be installed (no package index reachable), the
test is skipped with pip's reason.
"""

from __future__ import annotations

import fcntl
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
VENV = Path(tempfile.gettempdir()) / "moments-ref-base-venv"


def _base_dependencies():
    return tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["dependencies"]


def _pip(python, *args, timeout=900):
    return subprocess.run([str(python), "-m", "pip", "install", "--disable-pip-version-check", "--retries", "1",
                           "--timeout", "30", *args], capture_output=True, text=True, timeout=timeout,
                          env=dict(os.environ, PIP_NO_INPUT="1"))


@pytest.fixture(scope="module")
def base_python():
    """The interpreter of the base-dependency environment (built on first use, then reused).

    Test runs side by side (xdist workers, several checkouts) build and reuse it under a lock.
    """
    with open(str(VENV) + ".lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # released when the file closes
        return _base_python()


def _base_python():
    deps = _base_dependencies()
    python, marker = VENV / "bin" / "python", VENV / "moments-ref-base.json"
    if python.exists() and marker.exists() and json.loads(marker.read_text()) == deps:
        return python
    shutil.rmtree(VENV, ignore_errors=True)
    made = subprocess.run([sys.executable, "-m", "venv", str(VENV)], capture_output=True, text=True)
    if made.returncode:
        pytest.skip(f"cannot create a virtual environment: {made.stderr.strip()[-300:]}")
    r = _pip(python, *deps)
    if r.returncode:
        shutil.rmtree(VENV, ignore_errors=True)
        pytest.skip(f"the base dependencies cannot be installed here: {r.stderr.strip()[-300:]}")
    marker.write_text(json.dumps(deps))
    return python


def _run(python, code):
    # The package from this checkout, on top of the environment's base dependencies only.
    env = {k: v for k, v in os.environ.items() if not k.startswith(("PYTHON", "VIRTUAL_ENV"))}
    return subprocess.run([str(python), "-c", f"import sys; sys.path.insert(0, {str(ROOT)!r})\n{code}"],
                          capture_output=True, text=True, env=env, cwd=tempfile.gettempdir(), timeout=600)


def _readme_snippet():
    text = (ROOT / "README.md").read_text()
    blocks = re.findall(r"```python\n(.*?)```", text, re.S)
    snippet = next(b for b in blocks if "oracle.check" in b)
    return snippet


def test_the_environment_has_no_test_extra(base_python):
    r = _run(base_python, "import importlib.util as u; print(u.find_spec('hypothesis'), u.find_spec('pytest'))")
    assert r.returncode == 0 and r.stdout.split() == ["None", "None"], r.stdout + r.stderr


def test_readme_oracle_snippet_runs_with_the_base_install(base_python):
    r = _run(base_python, _readme_snippet())
    assert r.returncode == 0, r.stderr
    assert r.stdout.startswith("PASS shadow_intensity-lower-float32"), r.stdout


def test_drawing_rows_without_hypothesis_names_the_test_extra(base_python):
    code = ("import moments_ref.oracle as o\nfrom moments_ref import InputError, shadow_intensity\n"
            "try:\n    o.check(lambda b, zf: shadow_intensity(b, zf), 'shadow_intensity-lower')\n"
            "except InputError as e:\n    print(e)\n")
    r = _run(base_python, code)
    assert r.returncode == 0 and r.stdout.count("\n") == 1, r.stdout + r.stderr
    assert "test extra" in r.stdout and "n_hypothesis=0" in r.stdout
