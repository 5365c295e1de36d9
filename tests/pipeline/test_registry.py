"""prodmaps.pipeline.registry: the real paper/runs.toml, malformed registries, -p parsing, the project root,
the profile values a notebook reads (run_parameters) and their agreement with the notebooks."""

from __future__ import annotations

import ast
import datetime
import json
import re
from pathlib import Path

import pytest

from prodmaps.experiments.shared.claims import load_ledger
from prodmaps.pipeline import registry
from prodmaps.pipeline.notebooks import declared_parameters, parameters_cell
from prodmaps.pipeline.registry import (
    PROFILES,
    RegistryError,
    Run,
    find_project_root,
    load_registry,
    parse_param,
    parse_params,
    project_root,
    registry_path,
    run_parameters,
)

ROOT = find_project_root(Path(__file__).resolve().parent)  # the project these tests belong to
REAL = ROOT / "paper" / "runs.toml"


# ------------------------------------------------------------------------------ the real registry
@pytest.fixture(scope="module")
def real_runs():
    return load_registry(REAL)


def test_real_registry_loads_runs_in_file_order(real_runs):
    headers = re.findall(r"^\[runs\.([A-Za-z0-9_-]+)\]\s*$", REAL.read_text(encoding="utf-8"), flags=re.M)
    assert len(headers) == len(set(headers)), "a run is declared twice"
    assert list(real_runs) == headers
    assert len(real_runs) >= 20
    for name in ("fig02", "tab01", "tab06", "study_truncation"):
        assert name in real_runs
    assert all(isinstance(r, Run) and r.name == n for n, r in real_runs.items())


def test_real_registry_every_notebook_exists_inside_the_project(real_runs):
    for name, run in real_runs.items():
        assert run.notebook.is_absolute(), name
        assert run.notebook.is_file(), f"{name}: {run.notebook} missing"
        assert run.notebook.suffix == ".ipynb", name
        assert run.notebook.relative_to(ROOT).parts[0] == "notebooks", name


def test_real_registry_profiles_and_fields(real_runs):
    for name, run in real_runs.items():
        assert run.reproduces, f"{name}: empty `reproduces`"
        assert set(run.params) == set(PROFILES), f"{name}: profiles {sorted(run.params)}"
        for prof in PROFILES:
            assert not {"profile", "out_dir"} & set(run.parameters(prof)), name
    # the six table runs share one notebook and differ by the `table` parameter
    tabs = [real_runs[f"tab0{i}"] for i in range(1, 7)]
    assert len({r.notebook for r in tabs}) == 1
    assert [r.parameters("paper")["table"] for r in tabs] == [f"T{i}" for i in range(1, 7)]


def test_real_registry_claims_refer_to_ledger_and_ledger_to_runs(real_runs):
    ledger = load_ledger()
    for name, run in real_runs.items():
        assert isinstance(run.claims, tuple), name
        unknown = set(run.claims) - set(ledger)
        assert not unknown, f"{name}: claims {sorted(unknown)} are not in the ledger"
    for cid, claim in ledger.items():  # every claim is decided by registered runs
        missing = set(claim.runs) - set(real_runs)
        assert not missing, f"claim {cid}: runs {sorted(missing)} are not registered"


def test_real_registry_report_modules_own_their_sections(real_runs):
    import importlib
    import inspect

    owners = {name: run.report for name, run in real_runs.items() if run.report}
    assert {"study_truncation", "study_default", "study_normalization", "study_family_readings"} <= set(owners)
    for name, module in owners.items():
        blocks = importlib.import_module(module).report_blocks
        assert list(inspect.signature(blocks).parameters) == ["results", "dataset", "main"], name
        assert blocks({}, "embedded humans", main=False) == [], name  # no results, no section
    assert {n for n, r in real_runs.items() if r.dataset_figures} >= {"fig08", "fig11", "fig12_13"}


def test_project_root_of_real_registry():
    assert project_root(REAL) == ROOT
    assert (ROOT / "prodmaps" / "pipeline" / "registry.py").is_file()


# ------------------------------------------------------------------------------ synthetic registries
def _write(tmp_path: Path, text: str, name: str = "runs.toml") -> Path:
    paper = tmp_path / "paper"
    paper.mkdir(parents=True, exist_ok=True)
    p = paper / name
    p.write_text(text, encoding="utf-8")
    return p


GOOD = """
[runs.a]
notebook = "notebooks/a.ipynb"
reproduces = "Figure 1"
title = "A"
claims = ["fig02.rank"]
[runs.a.params.smoke]
k = 3
[runs.a.params.paper]
k = 30
ks = [1, 2]
[runs.a.tolerances]
"results.x" = { rtol = 1e-3 }
[runs.a.datasets.faust]
ks = [5]
shape = "tr_reg_000"

[runs."b.2-x"]
notebook = "/abs/elsewhere/b.ipynb"
"""


def test_load_registry_fields_and_path_resolution(tmp_path):
    runs = load_registry(_write(tmp_path, GOOD))
    assert list(runs) == ["a", "b.2-x"]
    a, b = runs["a"], runs["b.2-x"]
    assert a.notebook == (tmp_path / "notebooks" / "a.ipynb").resolve()  # relative to paper/..
    assert b.notebook == Path("/abs/elsewhere/b.ipynb")
    assert (a.reproduces, a.title, a.claims) == ("Figure 1", "A", ("fig02.rank",))
    assert (b.reproduces, b.title, b.claims, b.params, b.tolerances) == ("", "", (), {}, {})
    assert a.parameters("smoke") == {"k": 3}
    assert a.parameters("paper") == {"k": 30, "ks": [1, 2]}
    assert a.parameters("other") == {}
    # a dataset's values go over every profile's; other datasets keep the profile's
    assert a.parameters("paper", "faust") == {"k": 30, "ks": [5], "shape": "tr_reg_000"}
    assert a.parameters("smoke", "faust") == {"k": 3, "ks": [5], "shape": "tr_reg_000"}
    assert a.parameters("paper", "anny_humans") == a.parameters("paper") and b.datasets == {}
    assert a.tolerances == {"results.x": {"rtol": 1e-3}}
    # parameters() is a copy: changing it leaves the run unchanged
    p = a.parameters("smoke")
    p["k"] = 99
    p["new"] = 1
    assert a.parameters("smoke") == {"k": 3}
    with pytest.raises(AttributeError):
        a.name = "other"  # frozen


def test_root_key_relative_to_registry_file(tmp_path):
    reg = _write(tmp_path, 'root = "proj"\n[runs.a]\nnotebook = "nb/a.ipynb"\n')
    assert load_registry(reg)["a"].notebook == (tmp_path / "paper" / "proj" / "nb" / "a.ipynb").resolve()
    assert project_root(reg) == (tmp_path / "paper" / "proj").resolve()
    # default: the parent of the registry's folder
    assert project_root(_write(tmp_path / "other", "[runs]\n")) == (tmp_path / "other").resolve()


def test_empty_registry_has_no_runs(tmp_path):
    assert load_registry(_write(tmp_path, "")) == {}
    assert load_registry(_write(tmp_path, "[runs]\n")) == {}


@pytest.mark.parametrize(
    "text, message",
    [
        ('[runs.a]\nreproduces = "Figure 1"\n', "missing `notebook"),
        ('[runs.a]\nnotebook = "a.ipynb"\nnotbook = "typo"\n', "unknown keys ['notbook']"),
        ('[runs.a]\nnotebook = "a.ipynb"\n[runs.a]\nnotebook = "b.ipynb"\n', "not valid TOML"),
        ('[runs.a]\nnotebook = "a.ipynb"\n[runs.b]\nnotebook = "b.ipynb"\n[runs.a.params.smoke]\n[runs.a]\n',
         "not valid TOML"),
        ("[runs.a\nnotebook = 1\n", "not valid TOML"),
        ("runs = 3\n", "[runs] must be a table"),
        ("[runs]\na = 3\n", "must be a table"),
        ('[runs."bad name"]\nnotebook = "a.ipynb"\n', "run names may use"),
        ('[runs."-a"]\nnotebook = "a.ipynb"\n', "run names may use"),
        ('[runs.a]\nnotebook = "a.ipynb"\nparams = 3\n', "params must be tables"),
        ('[runs.a]\nnotebook = "a.ipynb"\n[runs.a.params]\nsmoke = 3\n', "params must be tables"),
        ('[runs.a]\nnotebook = "a.ipynb"\n[runs.a.params.smoke]\nprofile = "paper"\n', "must not set ['profile']"),
        ('[runs.a]\nnotebook = "a.ipynb"\n[runs.a.params.paper]\nout_dir = "x"\n', "must not set ['out_dir']"),
        ('[runs.a]\nnotebook = "a.ipynb"\ntolerances = 1e-3\n', "tolerances must be a table"),
        ('[runs.a]\nnotebook = "a.ipynb"\nreport = "not a module"\n', "report must name a module"),
        ('[runs.a]\nnotebook = "a.ipynb"\ndataset_figures = "yes"\n', "dataset_figures must be true or false"),
        ('[runs.a]\nnotebook = "a.ipynb"\ndatasets = 3\n', "datasets must be tables"),
        ('[runs.a]\nnotebook = "a.ipynb"\n[runs.a.datasets.faust]\ndataset = "tosca"\n', "must not set ['dataset']"),
    ],
)
def test_malformed_registries_raise_registry_error(tmp_path, text, message):
    reg = _write(tmp_path, text)
    with pytest.raises(RegistryError) as exc:
        load_registry(reg)
    assert message in str(exc.value)
    assert str(reg) in str(exc.value)  # names the file


@pytest.mark.parametrize("value", ['"fig02.rank"', "3"])
def test_claims_must_be_a_list_of_strings(tmp_path, value):
    with pytest.raises(RegistryError, match="claims"):
        load_registry(_write(tmp_path, f'[runs.a]\nnotebook = "a.ipynb"\nclaims = {value}\n'))


def test_error_names_the_run(tmp_path):
    with pytest.raises(RegistryError, match=r"run 'second'.*unknown keys \['colour'\]"):
        load_registry(_write(tmp_path, '[runs.first]\nnotebook = "a.ipynb"\n[runs.second]\nnotebook = "b.ipynb"\n'
                                       'colour = "red"\n'))


def test_missing_registry_file(tmp_path):
    with pytest.raises(RegistryError, match="not found"):
        load_registry(tmp_path / "nope.toml")
    assert issubclass(RegistryError, ValueError)


def test_registry_error_is_not_raised_for_a_missing_notebook_file(tmp_path):
    # load_registry checks the `notebook` key, not the file: the runner reports a missing file as a failed run
    runs = load_registry(_write(tmp_path, '[runs.a]\nnotebook = "notebooks/missing.ipynb"\n'))
    assert not runs["a"].notebook.exists()


# ------------------------------------------------------------------------------ registry_path / project root
def test_registry_path_precedence(tmp_path, monkeypatch):
    reg = _write(tmp_path / "proj", "[runs]\n")
    other = _write(tmp_path / "env", "[runs]\n")
    sub = tmp_path / "proj" / "notebooks" / "deep"
    sub.mkdir(parents=True)
    monkeypatch.chdir(sub)
    monkeypatch.delenv("PRODMAPS_RUNS", raising=False)
    assert registry_path() == reg.resolve()  # found from the working directory
    monkeypatch.setenv("PRODMAPS_RUNS", str(other))
    assert registry_path() == other.resolve()  # the environment wins over the working directory
    assert project_root() == (tmp_path / "env").resolve()
    assert registry_path(reg) == reg.resolve()  # an explicit path wins over both


def test_find_project_root_from_subfolder(tmp_path, monkeypatch):
    _write(tmp_path / "proj", "[runs]\n")
    deep = tmp_path / "proj" / "a" / "b" / "c"
    deep.mkdir(parents=True)
    assert find_project_root(deep) == (tmp_path / "proj").resolve()
    assert find_project_root(tmp_path / "proj") == (tmp_path / "proj").resolve()
    assert find_project_root(str(deep)) == (tmp_path / "proj").resolve()
    monkeypatch.chdir(deep)
    assert find_project_root() == (tmp_path / "proj").resolve()


def test_find_project_root_nearest_wins(tmp_path):
    _write(tmp_path / "outer", "[runs]\n")
    _write(tmp_path / "outer" / "inner", "[runs]\n")
    deep = tmp_path / "outer" / "inner" / "x"
    deep.mkdir(parents=True)
    assert find_project_root(deep) == (tmp_path / "outer" / "inner").resolve()


def test_find_project_root_fails_outside_a_project(tmp_path, monkeypatch):
    assert not any((p / "paper" / "runs.toml").is_file() for p in (tmp_path, *tmp_path.parents))
    # a paper/ folder without runs.toml, or runs.toml in the wrong place, is not a project
    (tmp_path / "paper").mkdir()
    (tmp_path / "runs.toml").write_text("[runs]\n")
    with pytest.raises(RegistryError, match=r"no paper/runs\.toml in"):
        find_project_root(tmp_path)
    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv("PRODMAPS_RUNS", raising=False)
    with pytest.raises(RegistryError):
        find_project_root()
    with pytest.raises(RegistryError):
        registry_path()


# ------------------------------------------------------------------------------ -p key=value
@pytest.mark.parametrize(
    "text, key, value",
    [
        ("k=3", "k", 3),
        ("k = 3", "k", 3),
        ("rtol=1e-3", "rtol", 1e-3),
        ("x=2.5", "x", 2.5),
        ("x=-4", "x", -4),
        ("ks=[4, 8, 12]", "ks", [4, 8, 12]),
        ("sizes=[[9, 9], [29, 39]]", "sizes", [[9, 9], [29, 39]]),
        ("names=['a', 'b']", "names", ["a", "b"]),  # not JSON, a TOML array
        ('dataset="faust"', "dataset", "faust"),
        ("dataset='faust'", "dataset", "faust"),  # TOML literal string
        ("dataset=faust", "dataset", "faust"),  # bare word: kept as a string
        ("flag=true", "flag", True),
        ("flag=false", "flag", False),
        ("opt=null", "opt", None),
        ("d={\"a\": 1}", "d", {"a": 1}),
        ("d={a = 1}", "d", {"a": 1}),  # TOML inline table
        ("day=2024-01-02", "day", datetime.date(2024, 1, 2)),
        ("expr=a=b", "expr", "a=b"),  # split at the first '='
        ("empty=", "empty", ""),
        ("path=results/paper", "path", "results/paper"),
    ],
)
def test_parse_param(text, key, value):
    k, v = parse_param(text)
    assert k == key
    assert v == value
    assert type(v) is type(value) or (type(value) is str and isinstance(v, str))  # a bare word: BareWord(str)


@pytest.mark.parametrize("text, message", [
    ("k3", "must look like key=value"),
    ("", "must look like key=value"),
    ("=3", "not a valid Python identifier"),
    ("1k=3", "not a valid Python identifier"),
    ("a-b=3", "not a valid Python identifier"),
    ("a.b=3", "not a valid Python identifier"),
])
def test_parse_param_bad_input(text, message):
    with pytest.raises(ValueError, match=re.escape(message)):
        parse_param(text)


def test_parse_params():
    assert parse_params(None) == {}
    assert parse_params([]) == {}
    assert parse_params(["k=3", "rtol=1e-3", "dataset=faust", "ks=[1,2]"]) == {
        "k": 3, "rtol": 1e-3, "dataset": "faust", "ks": [1, 2]}
    assert parse_params(["k=1", "k=2"]) == {"k": 2}  # the last one wins
    with pytest.raises(ValueError):
        parse_params(["k=1", "oops"])


def test_module_exports():
    for name in registry.__all__:
        assert hasattr(registry, name), name
    assert PROFILES == ("smoke", "paper")


# ------------------------------------------------------------------------------ run_parameters
def _notebook(path: Path, cell: str, more: str = "P = None\n") -> Path:
    cells = [{"cell_type": "markdown", "metadata": {}, "source": "# Demo\n"},
             {"cell_type": "code", "metadata": {"tags": ["parameters"]}, "outputs": [], "execution_count": None,
              "source": cell},
             {"cell_type": "code", "metadata": {}, "outputs": [], "execution_count": None, "source": more}]
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps({"cells": cells, "metadata": {}, "nbformat": 4, "nbformat_minor": 5}))
    return path


CELL = """profile = "smoke"
out_dir = "results/demo"
seed = 0                 # a value of its own: not a profile knob
ks = None                # the paper's k
rtol = None              # Approach B threshold
sweep = None             # {"sizes", "rtols"}; None: no sweep
"""

DEMO = """
[runs.demo]
notebook = "notebooks/demo.ipynb"
[runs.demo.params.smoke]
ks = [9, 19]
rtol = 1e-3
sweep = { sizes = [[20, 15]], rtols = [1e-6] }
[runs.demo.params.paper]
ks = [9, 29, 49]
rtol = 1e-3
# sweep left out: None
"""


@pytest.fixture()
def demo(tmp_path, monkeypatch):
    monkeypatch.delenv("PRODMAPS_RUNS", raising=False)
    reg = _write(tmp_path / "proj", DEMO)
    _notebook(tmp_path / "proj" / "notebooks" / "demo.ipynb", CELL)
    return reg


def _defaults(notebook: Path) -> dict:
    """The namespace of a notebook whose parameters cell has just run (declared defaults)."""
    return {k: ast.literal_eval(v) for k, v in parameters_cell(notebook).items()}


def test_run_parameters_gives_the_profile_values_of_the_knobs_declared_none(demo):
    ns = _defaults(demo.parent.parent / "notebooks" / "demo.ipynb")
    smoke = run_parameters("demo", "smoke", ns, registry=demo)
    assert smoke == {"ks": [9, 19], "rtol": 1e-3, "sweep": {"sizes": [[20, 15]], "rtols": [1e-6]}}
    assert list(smoke) == ["ks", "rtol", "sweep"]  # the cell's order; seed, profile, out_dir are not knobs
    # a knob the profile leaves out keeps the notebook's None
    assert run_parameters("demo", "paper", ns, registry=demo) == {"ks": [9, 29, 49], "rtol": 1e-3, "sweep": None}


def test_run_parameters_a_value_set_in_the_notebook_or_by_papermill_wins(demo):
    ns = {**_defaults(demo.parent.parent / "notebooks" / "demo.ipynb"), "ks": [4], "sweep": {}}
    assert run_parameters("demo", "paper", ns, registry=demo) == {"ks": [4], "rtol": 1e-3, "sweep": {}}
    injected = {**ns, **load_registry(demo)["demo"].parameters("smoke")}  # what the runner passes
    assert run_parameters("demo", "smoke", injected, registry=demo) == run_parameters(
        "demo", "smoke", _defaults(demo.parent.parent / "notebooks" / "demo.ipynb"), registry=demo)
    # a knob missing from the namespace (a cell edited by hand) reads as None
    assert run_parameters("demo", "smoke", {}, registry=demo)["ks"] == [9, 19]


def test_run_parameters_finds_the_registry_from_the_notebooks_folder_or_the_environment(demo, tmp_path, monkeypatch):
    monkeypatch.chdir(demo.parent.parent / "notebooks")  # a notebook opened by hand
    assert run_parameters("demo", "smoke", {})["rtol"] == 1e-3
    other = _write(tmp_path / "other", DEMO.replace("rtol = 1e-3", "rtol = 1e-2"))
    _notebook(tmp_path / "other" / "notebooks" / "demo.ipynb", CELL)
    monkeypatch.setenv("PRODMAPS_RUNS", str(other))
    assert run_parameters("demo", "smoke", {})["rtol"] == 1e-2


def test_run_parameters_errors_name_the_problem(demo, tmp_path):
    with pytest.raises(RegistryError, match=r"unknown run 'dem0' in .*runs\.toml; its runs: demo"):
        run_parameters("dem0", "smoke", {}, registry=demo)
    with pytest.raises(RegistryError, match=r"no params\.quick table; its profiles: \['paper', 'smoke'\]"):
        run_parameters("demo", "quick", {}, registry=demo)
    typo = _write(tmp_path / "typo", DEMO.replace("rtol = 1e-3\nsweep", "rtoll = 1e-3\nsweep"))
    _notebook(tmp_path / "typo" / "notebooks" / "demo.ipynb", CELL)
    with pytest.raises(RegistryError, match=r"params\.smoke of run 'demo' sets \['rtoll'\], which the parameters "
                                            r"cell of demo\.ipynb does not declare"):
        run_parameters("demo", "smoke", {}, registry=typo)
    assert run_parameters("demo", "paper", {}, registry=typo)["rtol"] == 1e-3  # the paper table has no typo
    gone = _write(tmp_path / "gone", DEMO)
    with pytest.raises(RegistryError, match="cannot read its notebook"):
        run_parameters("demo", "smoke", {}, registry=gone)
    _notebook(tmp_path / "gone" / "notebooks" / "demo.ipynb", CELL).write_text(json.dumps(
        {"cells": [], "metadata": {}, "nbformat": 4, "nbformat_minor": 5}))
    with pytest.raises(ValueError, match="no code cell tagged `parameters`"):
        run_parameters("demo", "smoke", {}, registry=gone)


# ------------------------------------------------------------------------------ runs.toml and the notebooks
NOTEBOOKS = sorted({r.notebook for r in load_registry(REAL).values()})
# the key that chooses among the runs sharing a notebook: declared with a value, set in every table
RUN_SELECTORS = {"tables_transfer": {"table"}}


@pytest.mark.parametrize("path", NOTEBOOKS, ids=[p.stem for p in NOTEBOOKS])
def test_parameters_cell_reads_what_papermill_reads(path):
    assert parameters_cell(path) == {k: v["default"] for k, v in declared_parameters(path).items()}


def test_every_profile_value_is_a_knob_its_notebook_declares_none(real_runs):
    problems = []
    for name, run in real_runs.items():
        cell = parameters_cell(run.notebook)
        for prof, values in run.params.items():
            for key in values:
                if key not in cell:
                    problems.append(f"{name}: params.{prof}.{key} is not declared in {run.notebook.name}")
                elif cell[key] != "None" and key not in RUN_SELECTORS.get(run.notebook.stem, ()):
                    problems.append(f"{name}: params.{prof}.{key} is declared `{key} = {cell[key]}` in "
                                    f"{run.notebook.name}: a value there would win over the profile's when the "
                                    "notebook is run by hand; declare it None")
    assert problems == []
    tables = [r for r in real_runs.values() if r.notebook.stem == "tables_transfer"]
    assert all({"table"} <= set(r.params[p]) for r in tables for p in PROFILES)


@pytest.mark.parametrize("path", NOTEBOOKS, ids=[p.stem for p in NOTEBOOKS])
def test_notebook_reads_its_profiles_from_the_registry(path, real_runs):
    code = "\n".join("".join(c["source"]) for c in json.loads(path.read_text(encoding="utf-8"))["cells"]
                     if c["cell_type"] == "code")
    assert "PROFILES" not in code and "resolve_profile" not in code, "profile values belong in paper/runs.toml"
    calls = re.findall(r"registry\.run_parameters\(([^,]+),", code)
    assert len(calls) == 1, f"{path.name}: call registry.run_parameters(<run>, profile, globals()) once"
    own = {n for n, r in real_runs.items() if r.notebook == path}
    named = re.findall(r'"([A-Za-z0-9_.-]+)"', calls[0]) or re.findall(r'"(tab0)\{', code)
    assert named and all(n in own or f"{n}1" in own for n in named), (calls[0], sorted(own))


@pytest.mark.parametrize("profile", PROFILES)
def test_a_notebook_run_by_hand_gets_the_values_papermill_gets(real_runs, profile, monkeypatch):
    """From ``notebooks/`` (a notebook opened by hand) with the declared defaults, and from the project
    root with the registry's values injected as papermill does: the same profile values."""
    monkeypatch.delenv("PRODMAPS_RUNS", raising=False)
    for name, run in real_runs.items():
        defaults = _defaults(run.notebook)
        if "table" in run.params[profile]:  # the tables notebook picks its run by `table`
            defaults["table"] = run.params[profile]["table"]
        monkeypatch.chdir(ROOT / "notebooks")
        by_hand = run_parameters(name, profile, defaults)
        monkeypatch.chdir(ROOT)
        injected = run_parameters(name, profile, {**defaults, **run.parameters(profile)})
        assert by_hand == injected, name
        set_here = {k for k, v in by_hand.items() if v is not None}
        assert set_here >= set(run.params[profile]) - {"table"}, name
