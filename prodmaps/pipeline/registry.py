"""The run registry: every notebook run that reproduces a figure or table of the paper.

Every run is an entry of ``paper/runs.toml`` (another file through ``$PRODMAPS_RUNS`` or the
``registry=`` arguments)::

    [runs.fig04]
    notebook = "notebooks/fig04_coordinate_reconstruction.ipynb"   # relative to the project root
    reproduces = "Figure 4"
    title = "Coordinate reconstruction, k = 9..69"                  # optional
    claims = ["fig04.products_improve"]                             # optional: ledger entries judged on it
    report = "prodmaps.experiments.study_default_transfer"          # optional: the module owning its report section
    dataset_figures = true                                          # optional: its figures in every dataset's section
    [runs.fig04.params.smoke]        # the smoke profile's values of the notebook's knobs
    ks = [9, 19]
    [runs.fig04.params.paper]        # ... and the paper profile's
    ks = [9, 29, 49, 69]
    [runs.fig04.tolerances]          # optional, for prodmaps.pipeline.diffing (dotted-key globs)
    "results.errors.*" = { rtol = 1e-6, atol = 1e-9 }
    [runs.fig04.datasets.faust]      # optional: values for one dataset, over every profile's
    shape_id = "tr_reg_000"

Profiles live here, nowhere else: a knob a notebook declares ``None`` takes the run's
``params.<profile>`` value (:func:`run_parameters`; TOML has no null, so a profile leaves out a
knob that stays ``None``), overridden for a dataset by its ``datasets.<dataset>`` table (the
data's own values: a shape id, a region's centre in that dataset's frame). A knob declared with a
value of its own (``dataset``, ``seed``, ``table``) is set in a table only to choose among the runs
that share a notebook (``table``).

A run with ``report`` has a section of its own in the report: the module's
``report_blocks(results, dataset, *, main=True)`` returns it as ``(kind, *args)`` blocks
(``("h", level, text)``, ``("p", text)``, ``("table", header, rows)``, ``("ul", items)``), for the
report's own results (``main``) and for each prepared dataset's (``main=False``); the report
adds the run's figures after them.

Several runs may share one notebook with different parameters (e.g. the six tables). Relative
notebook paths are resolved against the project root: the parent of the folder holding the
registry (``paper/..``), or the folder named by an optional top-level ``root = "..."`` key
(relative to the registry file). Without an explicit registry, the project is found by looking
for ``paper/runs.toml`` in the working directory and its parents.
"""

from __future__ import annotations

import ast
import json
import os
import re
from dataclasses import dataclass, field
from pathlib import Path

from ..files import parse_toml
from .notebooks import parameters_cell

__all__ = ["PROFILES", "REGISTRY", "RUNS_ENV", "Run", "RegistryError", "find_project_root", "registry_path",
           "project_root", "load_registry", "run_parameters", "parse_param", "parse_params", "BareWord"]

PROFILES = ("smoke", "paper")
REGISTRY = Path("paper") / "runs.toml"
RUNS_ENV = "PRODMAPS_RUNS"  # another registry file than the project's paper/runs.toml
_NAME_RE = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]*$")
_RUN_KEYS = {"notebook", "reproduces", "title", "params", "tolerances", "description", "claims", "report",
             "dataset_figures", "datasets"}
_MODULE_RE = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*(\.[A-Za-z_][A-Za-z0-9_]*)*$")


class RegistryError(ValueError):
    """A malformed run registry (names the file, the run and the problem)."""


@dataclass(frozen=True)
class Run:
    """One registry entry. ``notebook`` is an absolute path; ``params[profile]`` a dict."""

    name: str
    notebook: Path
    reproduces: str = ""
    title: str = ""
    description: str = ""
    params: dict = field(default_factory=dict)
    tolerances: dict = field(default_factory=dict)
    claims: tuple = ()
    report: str = ""  # module with report_blocks(results, dataset, *, main) (see the module doc)
    dataset_figures: bool = False  # its figures shown in every dataset's section of the report
    datasets: dict = field(default_factory=dict)  # dataset -> values over the profile's

    def parameters(self, profile: str, dataset: str | None = None) -> dict:
        """A copy of this run's parameters under ``profile``, with ``dataset``'s values over them."""
        return {**self.params.get(profile, {}), **self.datasets.get(dataset, {})}


# ------------------------------------------------------------------------------ registry
def find_project_root(start=None) -> Path:
    """The project root: the nearest folder at or above ``start`` (default: cwd) holding ``paper/runs.toml``."""
    here = Path(start or Path.cwd()).resolve()
    for folder in (here, *here.parents):
        if (folder / REGISTRY).is_file():
            return folder
    raise RegistryError(
        f"no {REGISTRY} in {here} or its parents: run from the project's folder (the clone of the "
        "repository), or pass --registry / set PRODMAPS_RUNS")


def registry_path(path=None) -> Path:
    """``path`` if given, else ``$PRODMAPS_RUNS``, else ``paper/runs.toml`` of :func:`find_project_root`."""
    if path is not None:
        return Path(path).expanduser().resolve()
    env = os.environ.get(RUNS_ENV)
    if env:
        return Path(env).expanduser().resolve()
    return find_project_root() / REGISTRY


def project_root(registry=None) -> Path:
    """The project root of a registry: its ``root = "..."`` key, else the parent of ``paper/``."""
    path = registry_path(registry)
    try:
        doc = parse_toml(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        doc = {}
    return (path.parent / doc.get("root", "..")).resolve()


def _need(where: str, ok, problem: str) -> None:
    if not ok:
        raise RegistryError(f"{where}: {problem}")


def load_registry(path=None) -> dict[str, Run]:
    """Read the run registry (see the module doc) into ``{name: Run}`` in file order."""
    path = registry_path(path)
    if not path.is_file():
        raise RegistryError(f"run registry {path} not found (set PRODMAPS_RUNS or pass --registry)")
    try:
        doc = parse_toml(path.read_text(encoding="utf-8"))
    except Exception as exc:  # tomllib.TOMLDecodeError
        raise RegistryError(f"{path}: not valid TOML: {exc}") from exc
    root = (path.parent / doc.get("root", "..")).resolve()
    runs = doc.get("runs", {})
    if not isinstance(runs, dict):
        raise RegistryError(f"{path}: [runs] must be a table of runs")
    out: dict[str, Run] = {}
    for name, entry in runs.items():
        where = f"{path}: run {name!r}"
        _need(where, _NAME_RE.match(name), "run names may use letters, digits, '_', '-', '.'")
        _need(where, isinstance(entry, dict), "must be a table")
        unknown = set(entry) - _RUN_KEYS
        _need(where, not unknown, f"unknown keys {sorted(unknown)}; allowed {sorted(_RUN_KEYS)}")
        _need(where, "notebook" in entry, "missing `notebook = \"notebooks/....ipynb\"`")
        params = entry.get("params", {})
        _need(where, isinstance(params, dict) and all(isinstance(v, dict) for v in params.values()),
              f"params must be tables [runs.{name}.params.<profile>]")
        for prof, p in params.items():
            reserved = {"profile", "out_dir"} & set(p)
            _need(where, not reserved, f"params.{prof} must not set {sorted(reserved)} (added by the runner)")
        tol = entry.get("tolerances", {})
        _need(where, isinstance(tol, dict), "tolerances must be a table of key-glob = {rtol, atol}")
        claims = entry.get("claims", [])
        _need(where, isinstance(claims, list) and all(isinstance(c, str) for c in claims),
              f"claims must be a list of claim ids of the ledger, got {claims!r}")
        report = entry.get("report", "")
        _need(where, isinstance(report, str) and (report == "" or _MODULE_RE.match(report)),
              f"report must name a module (\"prodmaps.experiments.study_default_transfer\"), got {report!r}")
        _need(where, isinstance(entry.get("dataset_figures", False), bool), "dataset_figures must be true or false")
        per_ds = entry.get("datasets", {})
        _need(where, isinstance(per_ds, dict) and all(isinstance(v, dict) for v in per_ds.values()),
              f"datasets must be tables [runs.{name}.datasets.<dataset>]")
        for ds, p in per_ds.items():
            reserved = {"profile", "out_dir", "dataset"} & set(p)
            _need(where, not reserved, f"datasets.{ds} must not set {sorted(reserved)}")
        nb = Path(entry["notebook"])
        out[name] = Run(
            name=name, notebook=(nb if nb.is_absolute() else root / nb).resolve(),
            reproduces=str(entry.get("reproduces", "")), title=str(entry.get("title", "")),
            params={k: dict(v) for k, v in params.items()}, tolerances=dict(tol),
            description=str(entry.get("description", "")), claims=tuple(claims), report=report,
            dataset_figures=entry.get("dataset_figures", False), datasets={k: dict(v) for k, v in per_ds.items()},
        )
    return out


def run_parameters(run: str, profile: str, namespace: dict, *, registry=None) -> dict:
    r"""The values of a notebook's profile knobs: ``P = registry.run_parameters("fig04", profile, globals())``.

    The knobs are the names the run's notebook declares ``None`` in its ``parameters`` cell (read
    from the notebook file, :func:`prodmaps.pipeline.notebooks.parameters_cell`). Each one's value
    is ``namespace[name]`` if that is not None (set in the cell by the user, or injected by
    papermill: the runner passes ``params.<profile>`` and ``-p`` values that way), else the run's
    ``params.<profile>`` entry in the registry, else ``None`` (a knob the profile leaves out: the
    notebook's ``None`` stands, meaning what its comment says). A notebook run by hand and the
    same notebook run by ``prodmaps reproduce`` therefore get the same values.

    The registry is ``registry``, else ``$PRODMAPS_RUNS``, else ``paper/runs.toml`` found from the
    working directory and its parents (:func:`registry_path`): from ``notebooks/`` when the
    notebook is opened by hand, from the project root under papermill. Raises
    :class:`RegistryError` for an unknown run, a profile the run has no table for, or a
    ``params.<profile>`` key that the notebook does not declare (a typo would do nothing).

    Examples
    --------
    A project with one run; its notebook declares ``ks`` and ``rtol`` as profile knobs and
    ``seed`` with a value of its own:

    >>> import json, shutil, tempfile
    >>> from pathlib import Path
    >>> root = Path(tempfile.mkdtemp())
    >>> (root / "paper").mkdir()
    >>> _ = (root / "paper" / "runs.toml").write_text(
    ...     '[runs.demo]\nnotebook = "demo.ipynb"\n'
    ...     '[runs.demo.params.smoke]\nks = [9, 19]\nrtol = 1e-3\n'
    ...     '[runs.demo.params.paper]\nks = [9, 29, 49]\n')      # rtol left out: None
    >>> cell = {"cell_type": "code", "metadata": {"tags": ["parameters"]}, "outputs": [], "execution_count": None,
    ...         "source": 'profile = "smoke"\nks = None    # the paper\'s k\nrtol = None\nseed = 0\n'}
    >>> _ = (root / "demo.ipynb").write_text(json.dumps({"cells": [cell], "metadata": {}, "nbformat": 4,
    ...                                                  "nbformat_minor": 5}))
    >>> reg = root / "paper" / "runs.toml"
    >>> run_parameters("demo", "smoke", {"ks": None, "rtol": None, "seed": 0}, registry=reg)
    {'ks': [9, 19], 'rtol': 0.001}
    >>> run_parameters("demo", "smoke", {"ks": [4, 8], "rtol": None}, registry=reg)  # set in the cell, or by -p
    {'ks': [4, 8], 'rtol': 0.001}
    >>> run_parameters("demo", "paper", {"ks": None, "rtol": None}, registry=reg)
    {'ks': [9, 29, 49], 'rtol': None}
    >>> try:
    ...     run_parameters("demo", "quick", {}, registry=reg)
    ... except RegistryError as exc:
    ...     print(exc)
    run 'demo' has no params.quick table; its profiles: ['paper', 'smoke']
    >>> shutil.rmtree(root)
    """
    path = registry_path(registry)
    runs = load_registry(path)
    if run not in runs:
        raise RegistryError(f"unknown run {run!r} in {path}; its runs: {', '.join(runs)}")
    entry = runs[run]
    if profile not in entry.params:
        raise RegistryError(f"run {run!r} has no params.{profile} table; its profiles: {sorted(entry.params)}")
    values = entry.parameters(profile, namespace.get("dataset"))
    try:
        declared = parameters_cell(entry.notebook)
    except OSError as exc:
        raise RegistryError(f"run {run!r}: cannot read its notebook {entry.notebook}: {exc}") from exc
    undeclared = sorted(set(values) - set(declared))
    if undeclared:
        raise RegistryError(f"{path}: params.{profile} of run {run!r} sets {undeclared}, which the parameters cell "
                            f"of {entry.notebook.name} does not declare; it declares {list(declared)}")
    knobs = [name for name, default in declared.items() if default == "None"]
    return {name: namespace[name] if namespace.get(name) is not None else values.get(name) for name in knobs}


class BareWord(str):
    """A ``-p key=value`` value that parses as no literal, kept as a string (only where the default is one)."""


def parse_param(text: str):
    """``key=value`` -> ``(key, value)``: JSON, else TOML, else Python literal, else a :class:`BareWord` string."""
    if "=" not in text:
        raise ValueError(f"parameter {text!r} must look like key=value")
    key, raw = text.split("=", 1)
    key = key.strip()
    if not key.isidentifier():
        raise ValueError(f"parameter name {key!r} is not a valid Python identifier")
    for parse in (json.loads, lambda s: parse_toml(f"v = {s}")["v"], lambda s: ast.literal_eval(s.strip())):
        try:
            return key, parse(raw)
        except Exception:  # not this syntax: try the next
            continue
    if raw.strip()[:1] in "[{(\"'" and raw.strip():
        raise ValueError(f"parameter {key}={raw!r} looks like a list, table or quoted string but does not parse "
                         "as JSON or TOML (e.g. -p 'k_values=[4, 8]', -p 'name=\"x\"')")
    return key, BareWord(raw)


def parse_params(items) -> dict:
    """``{name: value}`` of ``name=value`` items (``-p``), each by :func:`parse_param`."""
    return dict(parse_param(t) for t in (items or []))


