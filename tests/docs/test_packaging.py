"""Packaging: the library installs into an existing environment (ranges, not pins), the lock file holds
the exact versions behind the baselines and satisfies those ranges, and `requires-python` is true."""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

packaging = pytest.importorskip("packaging")
from packaging.requirements import Requirement  # noqa: E402
from packaging.specifiers import SpecifierSet  # noqa: E402


def _project():
    return tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]


def _lock() -> dict:
    out = {}
    for line in (ROOT / "requirements-lock.txt").read_text().splitlines():
        line = line.split("#", 1)[0].strip()
        if line:
            name, _, version = line.partition("==")
            out[re.sub(r"[-_.]+", "-", name).lower()] = version
    return out


def _requirements(extra_names=None):
    proj = _project()
    reqs = [Requirement(r) for r in proj["dependencies"]]
    for name, items in proj["optional-dependencies"].items():
        if extra_names is None or name in extra_names:
            reqs += [Requirement(r) for r in items if not r.startswith("prodmaps[")]
    return reqs


def test_library_dependencies_are_ranges_with_bounds():
    for r in _requirements(extra_names=()):
        if r.marker is not None:
            continue
        ops = {s.operator for s in r.specifier}
        assert "==" not in ops, f"{r}: a library install must not force an exact version on the environment"
        assert ">=" in ops and "<" in ops, f"{r}: give a tested lower bound and a sensible upper bound"


def test_lock_file_pins_every_dependency_within_its_range():
    lock = _lock()
    assert len(lock) > 50 and lock.get("numpy") and lock.get("scipy")
    for r in _requirements():
        if r.marker is not None and not r.marker.evaluate():
            continue
        name = re.sub(r"[-_.]+", "-", r.name).lower()
        assert name in lock, f"{name} is not in requirements-lock.txt"
        assert SpecifierSet(str(r.specifier)).contains(lock[name], prereleases=True), (name, lock[name], r)


def test_requires_python_and_libigl_where_figure_14_needs_it():
    proj = _project()
    assert SpecifierSet(proj["requires-python"]).contains("3.10")  # the ranges install there (numpy 2.0, scipy 1.13)
    assert any(Requirement(r).name == "libigl" for r in proj["optional-dependencies"]["notebooks"])
    mk = (ROOT / "Makefile").read_text()
    assert "-c requirements-lock.txt" in mk


@pytest.mark.parametrize("target", ["report", "claims"])
def test_make_report_and_claims_read_the_profile_reproduce_wrote(target):
    # `make reproduce PROFILE=smoke` writes OUT/smoke: `make report` / `make claims` with the same PROFILE read it
    if shutil.which("make") is None:
        pytest.skip("make is not installed")
    r = subprocess.run(["make", "-n", "-o", "venv", target, "OUT=somewhere", "PROFILE=smoke"], capture_output=True,
                       text=True, cwd=ROOT, timeout=60)
    assert r.returncode == 0, r.stderr
    assert f"-m prodmaps {target} somewhere/smoke" in r.stdout
