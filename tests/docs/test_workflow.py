"""The GitHub Actions workflow: it lints clean and runs what CI must run."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
WORKFLOW = ROOT / ".github" / "workflows" / "ci.yml"


def _actionlint():
    here = Path(sys.executable).parent / "actionlint"
    return str(here) if here.is_file() else shutil.which("actionlint")


def test_workflow_passes_actionlint():
    tool = _actionlint()
    if tool is None:
        pytest.skip("actionlint is not installed (pip install '.[docs]')")
    r = subprocess.run([tool, "-shellcheck=", "-pyflakes=", str(WORKFLOW)], capture_output=True, text=True,
                       timeout=120, cwd=ROOT)
    assert r.returncode == 0, r.stdout + r.stderr


def test_actionlint_catches_a_broken_workflow(tmp_path):
    tool = _actionlint()
    if tool is None:
        pytest.skip("actionlint is not installed (pip install '.[docs]')")
    bad = tmp_path / "bad.yml"
    bad.write_text(WORKFLOW.read_text().replace("runs-on: ubuntu-24.04", "runs-on: ${{ matrix.nope }}", 1))
    r = subprocess.run([tool, "-shellcheck=", "-pyflakes=", str(bad)], capture_output=True, text=True, timeout=120)
    assert r.returncode != 0 and "matrix" in r.stdout


def test_workflow_runs_the_tests_the_smoke_diff_and_the_docs():
    text = WORKFLOW.read_text()
    assert "make test" in text
    assert "prodmaps reproduce --profile smoke" in text
    assert "prodmaps diff results/smoke paper/baselines/smoke" in text
    assert "make docs" in text and "DOCS_RUNS=results/smoke" in text
    failure = text.split("if: failure()", 1)[1]
    assert "actions/upload-artifact" in failure
    for what in ("results/diff/", "executed.ipynb", "executed.html", "REPORT."):
        assert what in failure, what


def test_ci_uploads_junit_and_executed_notebooks_and_tests_both_ends_of_the_ranges():
    text = WORKFLOW.read_text()
    test_job = text.split("\n  test:", 1)[1].split("\n  compat:", 1)[0]
    assert "--junitxml=results/junit.xml" in test_job and "results/smoke_tests/*/executed.ipynb" in test_job
    assert "if: always()" in test_job
    compat = text.split("\n  compat:", 1)[1].split("\n  smoke:", 1)[0]
    for python, resolution in (("3.11", "lowest-direct"), ("3.13", "highest")):
        assert f'python: "{python}"\n            resolution: {resolution}' in compat
    assert "requirements-lock" not in compat  # the ranges, not the lock
    # numpy 1.26 (pyproject's lower bound): the library's own extras, the newest of everything else
    assert 'resolution: highest\n            extras: geometry\n            pins: \'"numpy==1.26.*"' in compat
    assert "${{ matrix.extras || 'notebooks' }}" in compat and "${{ matrix.pins }}" in compat
    assert "requirements-lock.txt" in (ROOT / "Makefile").read_text()  # make venv installs the lock
