"""The reproduction pipeline: registry, CLI, resumability, --force, failure isolation, atomic
outputs, declared parameters, run hashes, baselines, Dask. Uses tiny throwaway notebooks in tmp_path."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path  # noqa: F401  (fixture paths)

import nbformat
import pytest

from prodmaps.pipeline import baselines, cli, execute, hashing
from prodmaps.pipeline import registry as rp
from prodmaps.pipeline.diffing import diff_runs

PY = sys.executable

TINY_PARAMS = """profile = "smoke"
out_dir = "results/tiny"
dataset = "tinyset"
seed = 0
value = 1.0
fail = False
"""

TINY_BODY = """import numpy as np
from PIL import Image
from prodmaps.experiments.shared import results as nbr
if fail:
    raise RuntimeError("injected failure for the test")
rng = np.random.default_rng(seed)
x = rng.standard_normal(5)
results = {"value_twice": 2 * value, "draws": x, "sum": float(x.sum() * value)}
nbr.write_results(out_dir, results, {"profile": profile, "seed": seed, "value": value, "dataset": dataset})
img = (np.outer(np.linspace(0, 255, 24), np.ones(32)) * value % 256).astype(np.uint8)
Image.fromarray(np.stack([img, img[::-1], img], axis=-1)).save(f"{out_dir}/ramp.png")
print("tiny done", results["sum"])
"""


def write_notebook(path: Path, params: str, *cells: str, title: str | None = None) -> Path:
    """A python3 notebook at ``path``: an optional Markdown title, the ``parameters`` cell, then code cells."""
    nb = nbformat.v4.new_notebook()
    nb.metadata["kernelspec"] = {"name": "python3", "display_name": "Python 3", "language": "python"}
    nb.cells = ([nbformat.v4.new_markdown_cell(title)] if title is not None else []) + [
        nbformat.v4.new_code_cell(params, metadata={"tags": ["parameters"]})] + [
        nbformat.v4.new_code_cell(c) for c in cells]
    path.parent.mkdir(parents=True, exist_ok=True)
    nbformat.write(nb, str(path))
    return path


def write_tiny_notebook(path: Path, extra: str = "") -> Path:
    return write_notebook(path, TINY_PARAMS, TINY_BODY, title="# Tiny test notebook" + extra)


def write_registry(tmp: Path, entries: dict) -> Path:
    """entries: {name: (notebook relative path, {profile: params})}."""
    lines = ['root = ".."', ""]
    for name, (nb, params) in entries.items():
        lines += [f"[runs.{name}]", f'notebook = "{nb}"', f'reproduces = "Test {name}"']
        for prof in ("smoke", "paper"):
            lines.append(f"[runs.{name}.params.{prof}]")
            for k, v in params.get(prof, {}).items():
                lines.append(f"{k} = {json.dumps(v)}")
        lines.append("")
    reg = tmp / "paper" / "runs.toml"
    reg.parent.mkdir(parents=True, exist_ok=True)
    reg.write_text("\n".join(lines))
    return reg


@pytest.fixture()
def project(tmp_path, monkeypatch):
    """A throwaway project: two tiny notebooks, a registry, a data root with one dataset."""
    write_tiny_notebook(tmp_path / "notebooks" / "tiny_a.ipynb")
    write_tiny_notebook(tmp_path / "notebooks" / "tiny_b.ipynb")
    reg = write_registry(tmp_path, {
        "tiny_a": ("notebooks/tiny_a.ipynb", {"smoke": {"value": 1.5}, "paper": {"value": 3.0}}),
        "tiny_b": ("notebooks/tiny_b.ipynb", {"smoke": {"value": 2.0}}),
    })
    data = tmp_path / "data" / "tinyset"
    data.mkdir(parents=True)
    (data / "SHA256SUMS").write_text("0000  shape.ply\n")
    monkeypatch.setenv("PRODMAPS_RUNS", str(reg))
    monkeypatch.setenv("PRODMAPS_DATA", str(tmp_path / "data"))
    return tmp_path


def _statuses(capsys_text: str) -> str:
    return [l for l in capsys_text.splitlines() if l.startswith(("2 run", "3 run", "1 run"))][0]


def _main(args, capsys):
    rc = cli.main(args + ["--no-progress", "--no-report"])
    out = capsys.readouterr()
    return rc, out.out + out.err


# ----------------------------------------------------------------------------- registry
def test_registry_loads_and_resolves_paths(project):
    runs = rp.load_registry()  # through $PRODMAPS_RUNS
    assert list(runs) == ["tiny_a", "tiny_b"]
    assert runs["tiny_a"].notebook == (project / "notebooks" / "tiny_a.ipynb").resolve()
    assert runs["tiny_a"].parameters("smoke") == {"value": 1.5}
    assert runs["tiny_b"].parameters("paper") == {}
    assert baselines.baselines_dir() == project / "paper" / "baselines" / "smoke"
    assert rp.project_root() == project.resolve()


def test_default_registry_lists_the_paper_runs(monkeypatch):
    monkeypatch.delenv("PRODMAPS_RUNS", raising=False)
    runs = rp.load_registry()
    assert {"fig02", "fig03"} <= set(runs)
    for r in runs.values():
        assert r.notebook.is_file(), f"{r.name}: {r.notebook} does not exist"
        assert r.reproduces


@pytest.mark.parametrize("body, message", [
    ('[runs.x]\nreproduces = "F1"\n', "missing `notebook"),
    ('[runs.x]\nnotebook = "a.ipynb"\ncolour = 1\n', "unknown keys"),
    ('[runs.x]\nnotebook = "a.ipynb"\n[runs.x.params.smoke]\nout_dir = "z"\n', "must not set"),
    ('[runs."bad name"]\nnotebook = "a.ipynb"\n', "run names"),
    ('[runs.x\nnotebook = "a.ipynb"\n', "not valid TOML"),
])
def test_registry_errors_name_the_problem(tmp_path, body, message):
    reg = tmp_path / "runs.toml"
    reg.write_text(body)
    with pytest.raises(rp.RegistryError, match=message):
        rp.load_registry(reg)
    with pytest.raises(rp.RegistryError, match="not found"):
        rp.load_registry(tmp_path / "nope.toml")


def test_parse_param_literals():
    assert rp.parse_param("k=3") == ("k", 3)
    assert rp.parse_param("rtol=1e-3") == ("rtol", 1e-3)
    assert rp.parse_param("ks=[4, 8]") == ("ks", [4, 8])
    assert rp.parse_param("flag=true") == ("flag", True)
    assert rp.parse_param("name=hello world") == ("name", "hello world")
    assert rp.parse_param("name='quoted'") == ("name", "quoted")  # TOML literal string
    assert rp.parse_param("opts={a = 1}") == ("opts", {"a": 1})  # TOML inline table
    assert rp.parse_param("s=a=b") == ("s", "a=b")
    with pytest.raises(ValueError, match="key=value"):
        rp.parse_param("novalue")
    with pytest.raises(ValueError, match="identifier"):
        rp.parse_param("1x=2")


def test_run_hash_tracks_notebook_params_and_data(project):
    runs = rp.load_registry()
    (h0,) = [t["hash"] for t in execute.plan_runs(runs, only=["tiny_a"], profile="smoke", out=project / "o")]
    again = execute.plan_runs(runs, only=["tiny_a"], profile="smoke", out=project / "elsewhere")[0]
    assert again["hash"] == h0  # the output folder is not an input
    assert again["inputs"]["data"].startswith("sha256sums:")
    assert execute.plan_runs(runs, only=["tiny_a"], profile="paper", out=project / "o")[0]["hash"] != h0
    assert execute.plan_runs(runs, only=["tiny_a"], profile="smoke", out=project / "o",
                        overrides={"seed": 1})[0]["hash"] != h0
    (project / "data" / "tinyset" / "SHA256SUMS").write_text("1111  shape.ply\n")
    assert execute.plan_runs(runs, only=["tiny_a"], profile="smoke", out=project / "o")[0]["hash"] != h0
    t = execute.plan_runs(runs, only=["tiny_a"], profile="smoke", out=project / "o", dataset="other")[0]
    assert t["params"]["dataset"] == "other" and t["inputs"]["data"] == "missing:other"
    with pytest.raises(ValueError, match="unknown run"):
        execute.plan_runs(runs, only=["nope"], profile="smoke")
    with pytest.raises(ValueError, match="unknown profile"):
        execute.plan_runs(runs, profile="huge")


def test_run_hash_tracks_the_contents_of_a_file_a_parameter_names(project, tmp_path_factory):
    # `-p mesh_1=/my/scan.ply`: editing the user's own file must rerun the run, not skip it
    runs = rp.load_registry()
    plain = execute.plan_runs(runs, only=["tiny_a"], profile="smoke", out=project / "o", cwd=project)[0]
    assert "files" not in plain["inputs"]  # runs that name no file keep their hash
    mine = tmp_path_factory.mktemp("user") / "scan.off"
    mine.write_text("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n")
    # absolute, or relative to the notebooks' working directory (the project root); never `dataset`
    (project / "notebooks" / "rel.off").write_text(mine.read_text())
    assert hashing.parameter_files({"mesh_1": str(mine), "mesh_2": "notebooks/rel.off", "k": 3,
                                    "dataset": str(mine), "missing": "no/such.ply"}, project) == {
        "mesh_1": hashing.sha256_file(mine), "mesh_2": hashing.sha256_file(project / "notebooks" / "rel.off")}
    h0, _ = hashing.run_hash(project / "notebooks" / "tiny_a.ipynb", {"mesh_1": str(mine)}, None, cwd=project)
    mine.write_text(mine.read_text().replace("1 0 0", "2 0 0"))
    h1, inputs = hashing.run_hash(project / "notebooks" / "tiny_a.ipynb", {"mesh_1": str(mine)}, None,
                                  cwd=project)
    assert h1 != h0 and inputs["files"] == {"mesh_1": hashing.sha256_file(mine)}


# ----------------------------------------------------------------------------- running
@pytest.mark.slow
def test_cli_runs_resumes_forces_and_reruns_only_changed(project, capsys):
    out = project / "results"
    (out / "smoke" / ".tiny_a.tmp-interrupted").mkdir(parents=True)  # left by a killed invocation
    args = ["reproduce", "--profile", "smoke", "--out", str(out)]
    rc, text = _main(args, capsys)
    assert rc == 0, text
    assert "2 ran, 0 skipped" in _statuses(text)
    a = json.loads((out / "smoke" / "tiny_a" / "results.json").read_text())
    assert a["results"]["value_twice"] == 3.0  # registry smoke params reached the notebook
    assert a["parameters"]["profile"] == "smoke"
    for name in ("tiny_a", "tiny_b"):
        d = out / "smoke" / name
        assert {"results.json", "ramp.png", "executed.ipynb", "manifest.json"} <= {p.name for p in d.iterdir()}
        m = json.loads((d / "manifest.json").read_text())
        assert m["status"] == "ok" and m["seconds"] > 0 and set(m["outputs"]) == {"results.json", "ramp.png"}
    assert not [p for p in (out / "smoke").iterdir() if p.name.startswith(".")]  # no temp folders left

    rc, text = _main(args, capsys)  # unchanged: everything skipped
    assert rc == 0 and "0 ran, 2 skipped" in _statuses(text)

    write_tiny_notebook(project / "notebooks" / "tiny_b.ipynb", extra=" (edited)")  # change one notebook
    rc, text = _main(args, capsys)
    assert rc == 0 and "1 ran, 1 skipped" in _statuses(text)
    assert "ok       tiny_b" in text and "skipped  tiny_a" in text

    (out / "smoke" / "tiny_a" / "ramp.png").unlink()  # a missing output forces a rerun
    rc, text = _main(args + ["--only", "tiny_a"], capsys)
    assert "1 ran, 0 skipped" in _statuses(text) and (out / "smoke" / "tiny_a" / "ramp.png").is_file()

    rc, text = _main(args + ["--only", "tiny_a", "--force", "-p", "value=4"], capsys)
    assert rc == 0 and "1 ran" in _statuses(text)
    a = json.loads((out / "smoke" / "tiny_a" / "results.json").read_text())
    assert a["results"]["value_twice"] == 8.0

    rc, text = _main(args + ["--only", "tiny_a", "--force", "-p", "value=4"], capsys)
    b = json.loads((out / "smoke" / "tiny_a" / "results.json").read_text())
    assert b == a  # reruns give identical numbers


def test_registry_outside_the_project_reaches_the_kernels_run_parameters(tmp_path, monkeypatch, capsys):
    # a run only a registry of the user's own holds (no paper/runs.toml anywhere); its notebook reads its
    # knobs with run_parameters, which must read the registry given on the command line
    write_notebook(tmp_path / "own.ipynb",
                   'profile = "smoke"\nout_dir = "results/own"\nknob = None\n',
                   "from prodmaps.experiments.shared import results as nbr\n"
                   "from prodmaps.pipeline import registry\n"
                   'P = registry.run_parameters("own_run", profile, globals())\n'
                   'nbr.write_results(out_dir, {"knob_twice": 2 * P["knob"]}, P)\n')
    reg = tmp_path / "elsewhere" / "my_runs.toml"
    reg.parent.mkdir()
    reg.write_text('root = ".."\n[runs.own_run]\nnotebook = "own.ipynb"\n[runs.own_run.params.smoke]\nknob = 21\n')
    monkeypatch.delenv("PRODMAPS_RUNS", raising=False)
    monkeypatch.chdir(tmp_path)
    args = ["reproduce", "--registry", str(reg), "--profile", "smoke", "--out", str(tmp_path / "res")]
    rc, text = _main(args, capsys)
    assert rc == 0, text
    assert json.loads((tmp_path / "res" / "smoke" / "own_run" / "results.json").read_text())["results"] == {
        "knob_twice": 42}
    assert "PRODMAPS_RUNS" not in os.environ  # the runner's setting is undone after the run


def test_relative_cache_and_data_folders_are_the_invoking_folders_not_the_project(tmp_path, monkeypatch, capsys):
    # the kernels run in the project root: PRODMAPS_CACHE=cache from another folder must not put the
    # cache into the checkout, nor PRODMAPS_DATA=data name another data folder than the one checked
    (tmp_path / "project" / "paper").mkdir(parents=True)
    write_notebook(tmp_path / "project" / "own.ipynb",
                   'profile = "smoke"\nout_dir = "results/own"\n',
                   "import os\nfrom prodmaps.experiments.shared import results as nbr\n"
                   "nbr.write_results(out_dir, {k: os.path.abspath(os.environ[k]) for k in "
                   "('PRODMAPS_CACHE', 'PRODMAPS_DATA')}, {})\n")
    reg = tmp_path / "project" / "paper" / "runs.toml"
    reg.write_text('[runs.own]\nnotebook = "own.ipynb"\n[runs.own.params.smoke]\n')
    (tmp_path / "user").mkdir()
    monkeypatch.chdir(tmp_path / "user")
    monkeypatch.setenv("PRODMAPS_CACHE", "cache")
    monkeypatch.setenv("PRODMAPS_DATA", "data")
    rc, text = _main(["reproduce", "--registry", str(reg), "--profile", "smoke", "--out", "res"], capsys)
    assert rc == 0, text
    got = json.loads((tmp_path / "user" / "res" / "smoke" / "own" / "results.json").read_text())["results"]
    assert got == {"PRODMAPS_CACHE": str(tmp_path / "user" / "cache"), "PRODMAPS_DATA": str(tmp_path / "user" / "data")}
    assert os.environ["PRODMAPS_CACHE"] == "cache"  # this process's setting is restored


@pytest.mark.slow
def test_failure_is_isolated_kept_and_summarised(project, capsys):
    write_tiny_notebook(project / "notebooks" / "tiny_c.ipynb")
    write_registry(project, {
        "tiny_a": ("notebooks/tiny_a.ipynb", {"smoke": {"value": 1.5}}),
        "broken": ("notebooks/tiny_c.ipynb", {"smoke": {"fail": True}}),
        "tiny_b": ("notebooks/tiny_b.ipynb", {"smoke": {"value": 2.0}}),
    })
    out = project / "results"
    rc, text = _main(["reproduce", "--profile", "smoke", "--out", str(out), "--jobs", "2"], capsys)
    assert rc == 1
    assert "2 ran, 0 skipped (unchanged), 1 failed" in text
    assert "FAILED broken: cell" in text and "injected failure for the test" in text
    for name in ("tiny_a", "tiny_b"):
        assert (out / "smoke" / name / "results.json").is_file()
    bad = out / "smoke" / "broken"
    assert "RuntimeError: injected failure for the test" in (bad / "error.txt").read_text()
    executed = nbformat.read(str(bad / "executed.ipynb"), as_version=4)
    errors = [o for c in executed.cells if c.cell_type == "code" for o in c.get("outputs", [])
              if o.get("output_type") == "error"]
    assert errors and errors[0]["evalue"] == "injected failure for the test"
    assert json.loads((bad / "manifest.json").read_text())["status"] == "failed"

    # next invocation retries only the failure; fixing it (params) makes it pass
    rc, text = _main(["reproduce", "--profile", "smoke", "--out", str(out)], capsys)
    assert rc == 1 and "0 ran, 2 skipped (unchanged), 1 failed" in text
    rc, text = _main(["reproduce", "--profile", "smoke", "--out", str(out), "--only", "broken",
                      "-p", "fail=false"], capsys)
    assert rc == 0 and (bad / "results.json").is_file() and not (bad / "error.txt").exists()


def test_missing_notebook_fails_that_run_only(project, capsys):
    write_registry(project, {
        "ghost": ("notebooks/does_not_exist.ipynb", {}),
        "tiny_a": ("notebooks/tiny_a.ipynb", {"smoke": {"value": 1.5}}),
    })
    out = project / "results"
    rc, text = _main(["reproduce", "--profile", "smoke", "--out", str(out)], capsys)
    assert rc == 1 and "FAILED ghost" in text
    assert "does_not_exist.ipynb" in (out / "smoke" / "ghost" / "error.txt").read_text()
    assert (out / "smoke" / "tiny_a" / "results.json").is_file()


def test_usage_errors_exit_2(project, capsys):
    assert cli.main(["reproduce", "--only", "nope", "--no-progress"]) == 2
    assert "unknown run" in capsys.readouterr().err
    assert cli.main(["reproduce", "--profile", "paper", "--update-baselines"]) == 2
    assert "--profile smoke" in capsys.readouterr().err
    assert cli.main(["reproduce", "--jobs", "0"]) == 2


def test_swap_into_place_replaces_atomically(tmp_path):
    target = tmp_path / "run"
    target.mkdir()
    (target / "old.txt").write_text("old")
    new = tmp_path / ".run.tmp-1"
    new.mkdir()
    (new / "new.txt").write_text("new")
    execute.swap_into_place(new, target)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run"]
    assert [p.name for p in target.iterdir()] == ["new.txt"]


def test_update_baselines_then_diff_passes_and_detects_drift(project, capsys):
    out = project / "results"
    rc, text = _main(["reproduce", "--profile", "smoke", "--out", str(out), "--only", "tiny_a",
                      "--update-baselines"], capsys)
    assert rc == 0 and "baselines updated for 1 run(s)" in text
    base = project / "paper" / "baselines" / "smoke" / "tiny_a"
    assert sorted(p.name for p in base.iterdir()) == ["ramp.png", "results.json"]
    assert cli.main(["diff", str(out / "smoke" / "tiny_a"), str(base)]) == 0
    assert "diff PASS" in capsys.readouterr().out
    # a run with other parameters drifts: the diff names the key and the image
    rc, _ = _main(["reproduce", "--profile", "smoke", "--out", str(out), "--only", "tiny_a",
                   "-p", "value=1.6"], capsys)
    assert rc == 0
    rep = diff_runs(out / "smoke" / "tiny_a", base)
    keys = {f.key for f in rep.failures}
    assert {"results.value_twice", "results.sum", "parameters.value", "ramp.png"} <= keys
    assert "results.draws.0" not in keys  # same seed, same draws
    assert cli.main(["diff", str(out / "smoke" / "tiny_a"), str(base)]) == 1
    assert "diff FAIL" in capsys.readouterr().out


@pytest.mark.slow
def test_dask_localcluster_gives_the_local_numbers(project, capsys):
    distributed = pytest.importorskip("distributed")  # part of prodmaps[dask], installed by `make test`
    local = project / "local"
    rc, text = _main(["reproduce", "--profile", "smoke", "--out", str(local)], capsys)
    assert rc == 0, text
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster:
        rc, text = _main(["reproduce", "--profile", "smoke", "--out", str(project / "dask"),
                          "--scheduler", cluster.scheduler_address], capsys)
        assert rc == 0, text
        assert "2 ran, 0 skipped" in text
        with distributed.Client(cluster) as client:  # both workers were available
            assert len(client.scheduler_info()["workers"]) == 2
    for name in ("tiny_a", "tiny_b"):
        a = json.loads((local / "smoke" / name / "results.json").read_text())
        b = json.loads((project / "dask" / "smoke" / name / "results.json").read_text())
        assert a["results"] == b["results"] and a["parameters"] == b["parameters"]
        assert diff_runs(project / "dask" / "smoke" / name, local / "smoke" / name).ok


def test_python_m_prodmaps_entry_point(project):
    r = subprocess.run([PY, "-m", "prodmaps", "reproduce", "--list"], cwd=project, capture_output=True,
                       text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    assert "tiny_a" in r.stdout and "tiny_b" in r.stdout  # PRODMAPS_RUNS is inherited
    r = subprocess.run([PY, "-m", "prodmaps", "frobnicate"], cwd=project, capture_output=True, text=True)
    assert r.returncode == 2


# ----------------------------------------------------------------------------- parameters, hashes
def test_undeclared_parameters_are_refused_before_running(project, capsys):
    runs = rp.load_registry()
    with pytest.raises(execute.ParameterError, match=r"\['valeu'\] not declared"):
        execute.plan_runs(runs, only=["tiny_a"], profile="smoke", overrides={"valeu": 2})
    rc, text = _main(["reproduce", "--profile", "smoke", "--out", str(project / "r"), "-p", "valeu=2"], capsys)
    assert rc == 2 and "not declared" in text and "value" in text  # lists the declared names
    assert not (project / "r").exists()  # nothing ran
    write_registry(project, {"tiny_a": ("notebooks/tiny_a.ipynb", {"smoke": {"vlaue": 1.5}})})
    with pytest.raises(execute.ParameterError, match="registry parameters"):
        execute.plan_runs(rp.load_registry(), profile="smoke")


def test_repeated_only_adds_runs(project, capsys):
    rc, text = _main(["reproduce", "--profile", "smoke", "--out", str(project / "r"),
                      "--only", "tiny_a", "--only", "tiny_b"], capsys)
    assert rc == 0 and "2 ran" in _statuses(text)


def test_library_hash_covers_importable_code_not_the_pipeline():
    files = {p.relative_to(hashing._PACKAGE).as_posix() for p in hashing.library_files()}
    assert {"mapping.py", "experiments/shared/protocol.py", "experiments/shared/claims.toml",
            "experiments/shared/published_tables.csv"} <= files
    assert not [f for f in files if f.startswith(("pipeline/", "data/"))]


def test_executed_notebook_is_kept_as_html(project, capsys):
    out = project / "results"
    rc, _ = _main(["reproduce", "--profile", "smoke", "--out", str(out), "--only", "tiny_a"], capsys)
    html = (out / "smoke" / "tiny_a" / "executed.html").read_text()
    assert rc == 0 and "tiny done" in html and "<html" in html.lower()


FIGURE_BODY = """from prodmaps.experiments.shared import results as nbr
plt = nbr.setup_matplotlib()
fig, ax = plt.subplots(figsize=(2, 1.5))
ax.plot([0, 1, 2], [0, 1, 0])
nbr.save_figure(fig, out_dir, "tiny_figure")
nbr.write_results(out_dir, {"n": 3}, {"profile": profile, "out_dir": out_dir})
plt.show()
"""


def test_executed_notebook_shows_its_figures_and_its_own_output_folder(project, capsys):
    write_notebook(project / "notebooks" / "tiny_fig.ipynb",
                   'profile = "smoke"\nout_dir = "results/x"',
                   FIGURE_BODY)
    write_registry(project, {"tiny_fig": ("notebooks/tiny_fig.ipynb", {})})
    out = project / "results"
    rc, text = _main(["reproduce", "--profile", "smoke", "--out", str(out), "--only", "tiny_fig"], capsys)
    run = out / "smoke" / "tiny_fig"
    assert rc == 0, text
    executed = nbformat.read(str(run / "executed.ipynb"), as_version=4)
    outputs = [o for c in executed.cells if c.cell_type == "code" for o in c.get("outputs", [])]
    assert sum("image/png" in o.get("data", {}) for o in outputs) == 1  # inline, not swallowed by Agg
    assert (run / "tiny_figure.png").is_file()  # and still saved for diffing
    assert not [o for o in outputs if o.get("name") == "stderr"]
    injected = [c.source for c in executed.cells if "injected-parameters" in c.metadata.get("tags", [])]
    # the run's folder, relative to the project root as results.json records it; not the temporary folder
    assert len(injected) == 1 and 'out_dir = "results/smoke/tiny_fig"' in injected[0], injected
    assert json.loads((run / "results.json").read_text())["parameters"]["out_dir"] == "results/smoke/tiny_fig"
    assert "<img" in (run / "executed.html").read_text()


def test_records_of_a_run_outside_the_project_hold_no_machine_path(project, tmp_path_factory, capsys):
    """--out outside the project: manifest, results.json and the executed notebook (its injected
    cell and papermill's metadata) name the run as <out>/<profile>/<run> and the notebook relative
    to the project, never the machine's folders."""
    write_notebook(project / "notebooks" / "tiny_fig.ipynb",
                   'profile = "smoke"\nout_dir = "results/x"',
                   FIGURE_BODY,
                   "print(out_dir)\nimport pathlib; pathlib.Path(out_dir) / 'results.json'")
    write_registry(project, {"tiny_fig": ("notebooks/tiny_fig.ipynb", {})})
    elsewhere = tmp_path_factory.mktemp("elsewhere")
    out = elsewhere / "runs"
    rc, text = _main(["reproduce", "--profile", "smoke", "--out", str(out), "--only", "tiny_fig"], capsys)
    run = out / "smoke" / "tiny_fig"
    assert rc == 0, text
    manifest = json.loads((run / "manifest.json").read_text())
    assert manifest["notebook"] == "notebooks/tiny_fig.ipynb"
    assert json.loads((run / "results.json").read_text())["parameters"]["out_dir"] == "<out>/smoke/tiny_fig"
    meta = nbformat.read(str(run / "executed.ipynb"), as_version=4).metadata["papermill"]
    assert meta["input_path"] == "notebooks/tiny_fig.ipynb"
    assert meta["output_path"] == "<out>/smoke/tiny_fig/executed.ipynb"
    for f in ("manifest.json", "results.json", "executed.ipynb", "executed.html"):
        text = (run / f).read_text()
        assert str(elsewhere) not in text and str(project) not in text, f
    last = nbformat.read(str(run / "executed.ipynb"), as_version=4).cells[-1].outputs
    assert last[0]["text"].strip() == "<out>/smoke/tiny_fig"  # the printed folder, shown as recorded


def test_setup_matplotlib_outside_a_kernel_is_agg():
    code = ("from prodmaps.experiments.shared.results import setup_matplotlib; import matplotlib; "
            "setup_matplotlib(); print(matplotlib.get_backend())")
    r = subprocess.run([PY, "-c", code], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0 and r.stdout.strip().lower() == "agg", r.stderr


def test_a_value_that_does_not_parse_or_has_the_wrong_type_is_refused_up_front():
    with pytest.raises(ValueError, match="does not parse as JSON or TOML"):
        rp.parse_param("k_values=[4,")
    with pytest.raises(ValueError, match="does not parse"):
        rp.parse_param("opts={a = ")
    runs = rp.load_registry()
    with pytest.raises(execute.ParameterError, match=r"seed='x' \(str\) does not match the type of its default 0"):
        execute.plan_runs(runs, profile="smoke", only=["fig04"], overrides={"seed": "x"})
    with pytest.raises(execute.ParameterError, match="disk_cache"):
        execute.plan_runs(runs, profile="smoke", only=["tab01"], overrides={"disk_cache": 1})
    assert execute.plan_runs(runs, profile="smoke", only=["fig04"], overrides={"seed": 3})[0]["params"]["seed"] == 3



def test_a_float_for_an_integer_parameter_is_refused_naming_the_parameter_and_its_type(tmp_path, capsys):
    # fig02's n_samples is None in the notebook and 512 in the registry: 2.5 used to reach the notebook and fail
    # with a message about k (fourier_basis: k must be in [1, n//2])
    runs = rp.load_registry()
    with pytest.raises(execute.ParameterError, match=r"n_samples=2\.5 \(float\) does not match the type of the "
                       r"registry's params\.smoke\.n_samples = 512 \(int\): n_samples expects an integer"):
        execute.plan_runs(runs, profile="smoke", only=["fig02"], overrides={"n_samples": 2.5})
    with pytest.raises(execute.ParameterError, match="n_samples expects an integer"):
        execute.plan_runs(runs, profile="smoke", only=["fig02"], overrides={"n_samples": 2.0})
    with pytest.raises(execute.ParameterError, match=r"k_values expects a list of integers"):
        execute.plan_runs(runs, profile="paper", only=["fig03"], overrides={"k_values": [4, 8.5]})
    assert execute.plan_runs(runs, profile="smoke", only=["fig02"], overrides={"n_samples": 4096})[0]["params"][
        "n_samples"] == 4096
    assert execute.plan_runs(runs, profile="smoke", only=["tab01"], overrides={"rtol": 1})[0]["params"]["rtol"] == 1
    out = tmp_path / "o"  # the command line: refused before anything runs
    assert cli.main(["reproduce", "--only", "fig02", "-p", "n_samples=2.5", "--out", str(out), "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert "parameter n_samples=2.5" in err and "expects an integer (e.g. -p 'n_samples=2048')" in err
    assert not out.exists()


def test_reproduce_without_the_notebooks_extra_names_the_extra_to_install(tmp_path, monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "papermill", None)  # a library-only install: papermill is not there
    out = tmp_path / "o"
    assert cli.main(["reproduce", "--only", "fig02", "--out", str(out), "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert "needs papermill" in err and "pip install 'prodmaps[notebooks]'" in err and not out.exists()
    assert cli.main(["reproduce", "--list"]) == 0  # listing the runs needs no notebook tools
    # a missing optional package met later (matplotlib for an image diff, dask for a scheduler) names its extra
    assert "pip install 'prodmaps[dask]'" in execute.install_hint(ModuleNotFoundError("No module named 'dask'",
                                                                                       name="dask"))
    assert execute.install_hint(ModuleNotFoundError("No module named 'x'", name="x")) == "No module named 'x'"


# ----------------------------------------------------------------------------- command-line rough edges
def test_version_flag(capsys):
    with pytest.raises(SystemExit) as e:
        cli.main(["--version"])
    assert e.value.code == 0
    assert capsys.readouterr().out.strip() == f"prodmaps {__import__('prodmaps').__version__}"


def test_a_bare_word_for_a_non_string_parameter_is_refused_up_front(tmp_path, capsys):
    runs = rp.load_registry()
    with pytest.raises(execute.ParameterError, match=r"k_values=abc is not a literal.*k_values=\[4, 8\]"):
        execute.plan_runs(runs, profile="paper", only=["fig03"], overrides=rp.parse_params(["k_values=abc"]))
    assert execute.plan_runs(runs, profile="paper", only=["fig03"],
                             overrides=rp.parse_params(["k_values=[4,8]"]))[0]["params"]["k_values"] == [4, 8]
    assert rp.parse_param("k=(1, 2)") == ("k", (1, 2)) and rp.parse_param("x=None") == ("x", None)
    out = tmp_path / "o"
    assert cli.main(["reproduce", "--only", "fig03", "-p", "k_values=abc", "--out", str(out), "--no-progress"]) == 2
    assert "not a literal" in capsys.readouterr().err and not out.exists()


@pytest.mark.parametrize("args, message", [
    (["--dataset", "nope"], "unknown dataset 'nope'"),
    (["--timeout", "-5"], "positive number of seconds"),
    (["-p", "out_dir=/tmp/x"], "use --out"),
    (["-p", "profile=paper"], "--profile"),
])
def test_bad_command_lines_fail_early_and_leave_no_results_folder(tmp_path, capsys, args, message):
    out = tmp_path / "results"
    try:
        rc = cli.main(["reproduce", "--only", "fig02", "--out", str(out), "--no-progress", *args])
    except SystemExit as e:  # argparse's own usage errors
        rc = e.code
    assert rc == 2
    assert message in capsys.readouterr().err
    assert not out.exists()


@pytest.mark.parametrize("value", ["abc", "0", "-2"])
def test_a_bad_prodmaps_workers_is_refused_before_anything_runs(tmp_path, monkeypatch, capsys, value):
    monkeypatch.setenv("PRODMAPS_WORKERS", value)
    out = tmp_path / "results"
    assert cli.main(["reproduce", "--only", "fig02", "--out", str(out), "--no-progress"]) == 2
    assert f"PRODMAPS_WORKERS must be a positive integer, got {value!r}" in capsys.readouterr().err
    assert not out.exists()


def test_a_fractional_timeout_runs_and_a_cell_timeout_is_named_in_the_summary(tmp_path, monkeypatch, capsys):
    (tmp_path / "paper").mkdir()
    write_notebook(tmp_path / "own.ipynb",
                   'profile = "smoke"\nout_dir = "results/own"\nnap = 0.0\n',
                   "import time\nfrom prodmaps.experiments.shared import results as nbr\ntime.sleep(nap)\n"
                   "nbr.write_results(out_dir, {'nap': nap}, {})\n")
    reg = tmp_path / "paper" / "runs.toml"
    reg.write_text('[runs.own]\nnotebook = "own.ipynb"\n[runs.own.params.smoke]\n')
    monkeypatch.setenv("PRODMAPS_RUNS", str(reg))
    args = ["reproduce", "--profile", "smoke", "--out", str(tmp_path / "res")]
    rc, text = _main(args + ["--timeout", "30.5"], capsys)  # nbclient takes whole seconds only
    assert rc == 0, text
    rc, text = _main(args + ["--timeout", "0.5", "-p", "nap=5.0"], capsys)
    assert rc == 1 and "FAILED own: CellTimeoutError: A cell timed out" in text, text


def test_an_unreachable_scheduler_is_a_clear_error(project, capsys):
    import time as _time

    t0 = _time.perf_counter()
    rc, text = _main(["reproduce", "--profile", "smoke", "--out", str(project / "r"), "--force",
                      "--scheduler", "tcp://127.0.0.1:1"], capsys)
    assert rc == 2 and "no Dask scheduler reachable at tcp://127.0.0.1:1" in text and "Traceback" not in text
    assert _time.perf_counter() - t0 < 20


def test_manifest_records_versions_blas_commit_and_overrides(project, capsys):
    out = project / "results"
    rc, text = _main(["reproduce", "--profile", "smoke", "--out", str(out), "--only", "tiny_a", "-p", "value=2.5"],
                     capsys)
    assert rc == 0, text
    man = json.loads((out / "smoke" / "tiny_a" / "manifest.json").read_text())
    assert man["overrides"] == {"value": 2.5}
    assert {"prodmaps", "numpy", "scipy", "threadpoolctl"} <= set(man["versions"])
    assert man["blas"] and man["blas"][0]["internal_api"] and man["blas"][0]["num_threads"] >= 1
    assert man["commit"]  # the throwaway project is no git checkout: "unknown"
    env = execute.run_environment(Path(__file__).resolve().parents[2])
    assert env["commit"] != "unknown" and len(env["commit"].split("+")[0]) == 40


def test_param_files_are_read_from_the_invoking_folder(tmp_path, monkeypatch):
    """``-p mesh_1=scan.ply`` typed in one's own folder names that folder's file (the kernels run elsewhere)."""
    (tmp_path / "scan.ply").write_text("ply\n")
    (tmp_path / "sub").mkdir()
    monkeypatch.chdir(tmp_path)
    given = {"mesh_1": "scan.ply", "mesh_2": "missing.ply", "k": 30, "dataset": "faust", "folder": "sub",
             "abs": str(tmp_path / "scan.ply"), "empty": ""}
    out = execute.absolute_param_files(given)
    assert out["mesh_1"] == str((tmp_path / "scan.ply").resolve())
    assert {k: out[k] for k in given if k != "mesh_1"} == {k: v for k, v in given.items() if k != "mesh_1"}
    # a value that names a file in the project root keeps its meaning (and its run's hash)
    root = tmp_path / "project"
    root.mkdir()
    (root / "scan.ply").write_text("ply\n")
    assert execute.absolute_param_files(given, root) == given


def test_the_cli_module_runs_as_a_script():
    """``python -m prodmaps.pipeline.cli``: every helper is defined before the module's ``__main__`` block runs."""
    p = subprocess.run([sys.executable, "-m", "prodmaps.pipeline.cli", "reproduce", "--only", "nope", "--no-progress"],
                       capture_output=True, text=True)
    assert p.returncode == 2 and "nope" in p.stderr and "NameError" not in p.stderr


def test_importing_the_command_line_loads_no_notebook_tool_plotting_or_dask():
    # the pipeline's own modules are imported at module level; the heavy optional packages only where used
    heavy = ("papermill", "nbclient", "nbformat", "nbconvert", "ipykernel", "dask", "distributed", "tqdm", "matplotlib",
             "PIL", "pyvista", "vtk")
    code = ("import sys, prodmaps.pipeline.cli\n"
            f"print([m for m in sys.modules if m.split('.')[0] in {heavy!r}])\n")
    r = subprocess.run([PY, "-c", code], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == "[]", r.stdout
