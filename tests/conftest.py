"""Shared fixtures: small meshes from the embedded data and synthetic shapes."""

from pathlib import Path

import numpy as np
import pytest

import prodmaps as pm
from prodmaps.datasets import dataset_dir as ds_dir
from prodmaps.mesh import subdivide_midpoint

ROOT = Path(__file__).resolve().parents[1]
DATA = ds_dir("anny_humans")
BROKEN = Path(__file__).resolve().parent / "data" / "broken"


def icosphere(subdivisions: int = 2, radius: float = 1.0) -> pm.Mesh:
    """An icosphere of the given radius (closed, genus 0) built here, for fast tests."""
    t = (1 + 5**0.5) / 2
    v = np.array([[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t],
                  [0, -1, -t], [0, 1, -t], [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1]], float)
    f = np.array([[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4],
                  [11, 10, 2], [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8],
                  [3, 8, 9], [4, 9, 5], [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1]])
    v, f = subdivide_midpoint(v, f, levels=subdivisions)
    v = radius * v / np.linalg.norm(v, axis=1, keepdims=True)
    return pm.Mesh(v, f, name="icosphere")


@pytest.fixture(scope="session")
def sphere():
    return icosphere(3)  # 642 vertices


@pytest.fixture(scope="session")
def human_0():
    return pm.load_mesh(DATA / "shapes" / "anny_000.ply")


@pytest.fixture(scope="session")
def human_13():
    return pm.load_mesh(DATA / "shapes" / "anny_013.ply")


@pytest.fixture(scope="session")
def basis_0(human_0):
    return pm.eigenbasis(human_0, 40)


@pytest.fixture(scope="session")
def basis_13(human_13):
    return pm.eigenbasis(human_13, 40)


@pytest.fixture(scope="session")
def smoke_run(tmp_path_factory):
    """``smoke_run(name)``: run a registered notebook's smoke profile once per test session.

    Returns the run's output folder (``results.json``, PNGs, ``executed.ipynb``). The baseline
    diff (tests/test_notebooks.py) and the claim tests share the same execution.
    """
    from prodmaps import reproduce as rp

    runs = rp.load_registry(ROOT / "paper" / "runs.toml")
    cache = {}

    def get(name):
        if name not in cache:
            run = runs[name]
            params = run.parameters("smoke")
            params["profile"] = "smoke"
            out = tmp_path_factory.mktemp("smoke") / name
            try:
                rp.run_notebook(run.notebook, out, params, kernel_name="python3", cwd=ROOT)
                cache[name] = out
            except Exception as exc:  # keep the failure for every test that asks
                cache[name] = exc
        if isinstance(cache[name], Exception):
            pytest.fail(f"{name}: the smoke notebook failed: {cache[name]}")
        return cache[name]

    return get


def smoke_outputs(smoke_run, name):
    """``(output folder, results dict)`` of a run's smoke execution (shared, see smoke_run)."""
    import json

    d = smoke_run(name)
    doc = json.loads((d / "results.json").read_text())
    assert doc["parameters"]["profile"] == "smoke"
    return d, doc["results"]


def smoke_fixture(name):
    """A module-scoped fixture yielding ``(output folder, results)`` of run ``name``'s smoke execution.

    Use as ``fig07 = smoke_fixture("fig07")`` in a test module.
    """

    @pytest.fixture(scope="module")
    def _outputs(smoke_run):
        return smoke_outputs(smoke_run, name)

    return _outputs
