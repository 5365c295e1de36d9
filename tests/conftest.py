"""Shared fixtures: small meshes from the embedded data and synthetic shapes, and the notebooks'
smoke executions (run once per session, shared by the baseline diffs and the claim tests)."""

import json

import pytest

import prodmaps as pm
from prodmaps.datasets import dataset_dir
from prodmaps.mesh import icosphere


@pytest.fixture(scope="session")
def sphere():
    return icosphere(3)  # 642 vertices


@pytest.fixture(scope="session")
def human_0():
    return pm.load_mesh(dataset_dir("anny_humans") / "shapes" / "anny_000.ply")


@pytest.fixture(scope="session")
def human_13():
    return pm.load_mesh(dataset_dir("anny_humans") / "shapes" / "anny_013.ply")


@pytest.fixture(scope="session")
def basis_0(human_0):
    return pm.eigenbasis(human_0, 40)


@pytest.fixture(scope="session")
def basis_13(human_13):
    return pm.eigenbasis(human_13, 40)


@pytest.fixture(scope="session")
def smoke_run(tmp_path_factory):
    """``smoke_run(name)``: run a registered notebook's smoke profile once per test session.

    Returns the run's output folder (``results.json``, PNGs, ``executed.ipynb``/``.html``). The
    registry is the project's ``paper/runs.toml`` (found from the working directory). The outputs
    are kept in ``results/smoke_tests/<run>/`` of the project, so CI keeps the executed notebooks
    (as HTML) for reading.
    """
    import shutil

    from prodmaps.pipeline import execute, registry

    runs = registry.load_registry()
    root = registry.project_root()
    keep = root / "results" / "smoke_tests"
    shutil.rmtree(keep, ignore_errors=True)
    cache = {}

    def get(name):
        if name not in cache:
            run = runs[name]
            params = run.parameters("smoke")
            params["profile"] = "smoke"
            out = keep / name
            try:
                execute.run_notebook(run.notebook, out, params, kernel_name="python3", cwd=root)
                cache[name] = out
            except Exception as exc:  # keep the failure for every test that asks
                cache[name] = exc
        if isinstance(cache[name], Exception):
            pytest.fail(f"{name}: the smoke notebook failed: {cache[name]}")
        return cache[name]

    return get


@pytest.fixture(scope="session")
def smoke_results(smoke_run):
    """``smoke_results(name)`` -> ``(output folder, results dict)`` of a run's smoke execution."""

    def get(name):
        d = smoke_run(name)
        doc = json.loads((d / "results.json").read_text())
        assert doc["parameters"]["profile"] == "smoke"
        return d, doc["results"]

    return get
