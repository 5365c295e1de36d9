"""Batch regeneration of the registered notebooks: resumable, failure-isolated, parallel.

Parameters passed to a notebook: the registry's ``params.<profile>``, then ``dataset`` (if
given), then the ``-p key=value`` overrides, and always ``profile`` and ``out_dir``. Every name
must be declared in the notebook's ``parameters`` cell (read with ``papermill.inspect_notebook``):
a typo is refused before anything runs, instead of being silently ignored.

Outputs and resumability
------------------------
Run ``X`` of profile ``P`` writes into ``OUT/P/X/``: whatever the notebook writes
(``results.json``, PNGs), the executed notebook ``executed.ipynb`` and its HTML rendering
``executed.html`` (figures embedded, for reading), the kernel's stderr ``kernel.log`` (local
runs) and ``manifest.json``. The manifest records the run hash of
:mod:`prodmaps.pipeline.hashing` (notebook, parameters, importable library code, data, kernel).
A run whose hash is unchanged, whose last execution succeeded and whose outputs still exist is
skipped (``force=True`` redoes it).

Each run executes into a temporary folder beside its target (``OUT/P/.X.tmp-*``) which is then
renamed into place, so ``OUT/P/X`` is never half written. A failing run keeps its executed
notebook (with the traceback in the failing cell), ``error.txt`` and any partial outputs in
``OUT/P/X/``; its manifest says ``"status": "failed"`` so the next invocation retries it. One
failing run never stops the others. Do not run two invocations on the same ``OUT`` at once.

Parallelism (:mod:`prodmaps.pipeline.schedulers`): ``jobs > 1`` runs notebooks in a local
process pool; ``scheduler=ADDRESS`` sends one task per run to a Dask distributed cluster.
Nothing here imports papermill, tqdm or dask at module import.
"""

from __future__ import annotations

import contextlib
import datetime as _dt
import importlib.util
import json
import math
import os
import re
import shutil
import sys
import tempfile
import threading
import time
import traceback
from dataclasses import dataclass
from pathlib import Path

from ..files import read_json, sha256_file, swap_into_place
from .hashing import run_hash
from .notebooks import declared_parameters, export_html, literal, parameter_default
from .registry import PROFILES, RUNS_ENV, BareWord, load_registry, project_root, registry_path
from .schedulers import run_dask, run_pool, thread_env

__all__ = ["RunResult", "run_notebook", "plan_runs", "reproduce", "summary", "ParameterError", "profile_folder",
           "EXTRAS", "install_hint", "require_modules"]


class ParameterError(ValueError):
    """A parameter given to a run that its notebook does not declare."""


# the optional packages the pipeline imports, by the pyproject extra that installs them
EXTRAS = {"papermill": "notebooks", "nbclient": "notebooks", "nbformat": "notebooks", "ipykernel": "notebooks",
          "nbconvert": "notebooks", "nbstripout": "notebooks", "tqdm": "notebooks", "matplotlib": "notebooks",
          "PIL": "notebooks", "dask": "dask", "distributed": "dask"}
NOTEBOOK_MODULES = ("papermill", "nbclient", "nbformat", "ipykernel")  # what running a notebook needs


def install_hint(exc: ModuleNotFoundError) -> str:
    """The error of a missing optional package, naming the extra that installs it (``pip install 'prodmaps[x]'``)."""
    top = (exc.name or "").split(".")[0]
    extra = EXTRAS.get(top)
    return (f"{exc}: it comes with the {extra} extra, pip install 'prodmaps[{extra}]' (or `make venv` in a clone)"
            if extra else str(exc))


def require_modules(what: str, modules=NOTEBOOK_MODULES) -> None:
    """Raise ``ModuleNotFoundError`` naming the extra to install when one of ``modules`` is not installed."""
    missing = [m for m in modules if importlib.util.find_spec(m) is None]
    if missing:
        raise ModuleNotFoundError(
            f"{what} needs {', '.join(missing)}, not installed here (a library-only install): "
            f"pip install 'prodmaps[{EXTRAS.get(missing[0], 'notebooks')}]' (or `make venv` in a clone)",
            name=missing[0])


# ------------------------------------------------------------------------------ one notebook
def run_notebook(notebook, out_dir, params=None, kernel_name: str = "python3", *,
                 timeout: float | None = None, cwd=None, executed_name: str = "executed.ipynb",
                 html: bool = True, shown_out_dir: str | None = None, shown_notebook: str | None = None):
    """Execute ``notebook`` with papermill, writing into ``out_dir``; return the executed notebook path.

    ``out_dir`` is passed to the notebook as the ``out_dir`` parameter (absolute path) and the
    executed copy is saved there as ``executed_name``. The working directory is the project
    root (``cwd``). Raises papermill's ``PapermillExecutionError`` if a cell fails (the executed
    notebook with the traceback is still written, and rendered as HTML). ``timeout`` is per
    cell, in seconds. With ``html`` the executed notebook is also written as ``executed.html``.
    The kernel is stopped at once after the last cell (a graceful shutdown waits seconds for
    the worker processes of :mod:`prodmaps.experiments.shared.parallel`). ``shown_out_dir`` replaces
    ``out_dir`` in the executed notebook's injected parameters cell (the batch runner executes
    into a temporary folder and shows the run's own folder), and in papermill's metadata, whose
    ``input_path`` becomes ``shown_notebook`` when given.
    """
    import papermill as pm_

    out = Path(out_dir).resolve()
    out.mkdir(parents=True, exist_ok=True)
    parameters = dict(params or {})
    parameters["out_dir"] = str(out)
    executed = out / executed_name
    try:
        pm_.execute_notebook(
            str(notebook), str(executed), parameters=parameters, kernel_name=kernel_name,
            cwd=str(cwd or Path.cwd()), progress_bar=False, log_output=False,
            execution_timeout=None if timeout is None else math.ceil(timeout),  # nbclient takes whole seconds
            shutdown_kernel="immediate",
        )
    finally:
        if shown_out_dir is not None and executed.is_file():
            _show_out_dir(executed, str(out), shown_out_dir, shown_notebook)
        if html and executed.is_file():
            try:
                export_html(executed)
            except Exception as exc:  # a rendering problem must not hide the notebook's own result
                (out / "executed.html.error.txt").write_text(f"HTML export failed: {exc}\n")
    return executed


def _show_out_dir(executed: Path, actual: str, shown: str, notebook_shown: str | None = None) -> None:
    """``actual`` -> ``shown`` in the executed notebook's parameters cell, outputs, metadata (+ ``notebook_shown``)."""
    import nbformat

    nb = nbformat.read(executed, as_version=4)
    for cell in nb.cells:
        if "injected-parameters" in cell.get("metadata", {}).get("tags", []) and actual in cell.source:
            cell.source = cell.source.replace(actual, shown)
        for i, out in enumerate(cell.get("outputs", [])):  # e.g. a printed or returned path of out_dir
            text = json.dumps(out)
            if actual in text:
                cell.outputs[i] = nbformat.from_dict(json.loads(text.replace(json.dumps(actual)[1:-1],
                                                                             json.dumps(shown)[1:-1])))
    meta = nb.metadata.get("papermill")
    if isinstance(meta, dict):
        if notebook_shown is not None:
            meta["input_path"] = notebook_shown
        meta["output_path"] = f"{shown}/{executed.name}"
        par = meta.get("parameters")
        if isinstance(par, dict) and par.get("out_dir") == actual:
            par["out_dir"] = shown
    nbformat.write(nb, executed)


# ------------------------------------------------------------------------------ run loop
@dataclass
class RunResult:
    """The outcome of one run: name, status (``"ok"``, ``"skipped"``, ``"failed"``), time, folder, error."""

    name: str
    status: str  # "ok", "skipped", "failed"
    seconds: float = 0.0
    run_dir: str = ""
    error: str = ""

    def to_dict(self) -> dict:
        """The fields as a dict (JSON-ready)."""
        return dict(self.__dict__)


_NOT_OUTPUTS = ("manifest.json", "executed.ipynb", "executed.html", "executed.html.error.txt", "error.txt",
                "kernel.log")
_ANSI = re.compile(r"\x1b\[[0-9;]*[A-Za-z]")


def _shown_path(final: Path, root: Path, outside: str | None = "<out>") -> str:
    """A run folder or notebook as the records name it: relative to ``root``, else no machine path.

    Outside ``root`` a run folder is ``<out>/<profile folder>/<run>``, a file (``outside=None``) its name.
    """
    final, root = Path(final).resolve(), Path(root).resolve()
    try:
        return final.relative_to(root).as_posix()
    except ValueError:
        return final.name if outside is None else f"{outside}/{final.parent.name}/{final.name}"


def _relocate_out_dir(results: Path, tmp: Path, final: Path, root: Path) -> None:
    """Rewrite ``parameters.out_dir`` in results.json from the temporary to the final folder."""
    doc = read_json(results)
    par = doc.get("parameters") if isinstance(doc, dict) else None
    if isinstance(par, dict) and isinstance(par.get("out_dir"), str) and Path(par["out_dir"]) == tmp:
        par["out_dir"] = _shown_path(final, root)
        results.write_text(json.dumps(doc, indent=2, sort_keys=True) + "\n")


def mkdtemp_beside(target: Path, name: str) -> Path:
    """A fresh hidden folder next to ``target`` with the usual (umask) permissions."""
    tmp = Path(tempfile.mkdtemp(prefix=f".{name}.tmp-", dir=target.parent))
    os.chmod(tmp, 0o755)  # mkdtemp makes it 0700
    return tmp


@contextlib.contextmanager
def _environment(env: dict):
    """A run's environment variables (its registry, thread caps) set while its kernel runs.

    Restored after the run in a main thread (this process, a pool worker). A Dask worker's threads share
    one environment and run the tasks of one invocation, hence the same values: there they stay set, as
    restoring them could take them away from a kernel another thread is starting.
    """
    old = {k: os.environ.get(k) for k in env}
    os.environ.update(env)
    try:
        yield
    finally:
        if threading.current_thread() is threading.main_thread():
            for k, v in old.items():
                if v is None:
                    os.environ.pop(k, None)
                else:
                    os.environ[k] = v


@contextlib.contextmanager
def _stderr_to(path: Path):
    """Send fd 2 (the kernel's ipykernel/VTK chatter) to ``path``; in the main thread only (Dask uses threads)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    sys.stderr.flush()
    saved = os.dup(2)
    try:
        with open(path, "ab") as fh:
            os.dup2(fh.fileno(), 2)
            yield
    finally:
        sys.stderr.flush()
        os.dup2(saved, 2)
        os.close(saved)


def _execute_task(task: dict) -> dict:
    """Execute one planned run (in this process, a pool worker or a Dask worker)."""
    name, target = task["name"], Path(task["run_dir"])
    target.parent.mkdir(parents=True, exist_ok=True)
    for stale in target.parent.glob(f".{name}.tmp-*"):  # left by an interrupted invocation
        shutil.rmtree(stale, ignore_errors=True)
    tmp = mkdtemp_beside(target, name)
    root = Path(task.get("cwd") or Path.cwd())  # the project root (the notebooks' working directory)
    shown_notebook = _shown_path(Path(task["notebook"]), root, outside=None)
    t0 = time.perf_counter()
    error = ""
    try:
        with _stderr_to(tmp / "kernel.log"), _environment(task.get("env") or {}):
            run_notebook(task["notebook"], tmp, task["params"], task.get("kernel_name", "python3"),
                         timeout=task.get("timeout"), cwd=task.get("cwd"),
                         shown_out_dir=_shown_path(target, root), shown_notebook=shown_notebook)
        _relocate_out_dir(tmp / "results.json", tmp, target, root)
        if not (tmp / "results.json").is_file():
            raise RuntimeError("the notebook finished but wrote no results.json into out_dir")
    except BaseException as exc:  # failure isolation: record everything, never raise
        if not isinstance(exc, Exception):  # Ctrl-C / SystemExit: leave no temporary folder behind
            shutil.rmtree(tmp, ignore_errors=True)
            raise
        if exc.__class__.__name__ == "PapermillExecutionError":
            tb = "\n".join(getattr(exc, "traceback", []) or [])
            error = f"{getattr(exc, 'ename', 'Error')}: {getattr(exc, 'evalue', exc)}\n\n{_ANSI.sub('', tb)}"
            error = f"cell {getattr(exc, 'exec_count', '?')} failed\n" + error
        else:  # the exception first: the summary shows the first two lines (e.g. a cell timeout)
            error = f"{type(exc).__name__}: {exc}\n\n" + "".join(
                traceback.format_exception(type(exc), exc, exc.__traceback__))
        (tmp / "error.txt").write_text(error)
    seconds = time.perf_counter() - t0
    status = "failed" if error else "ok"
    manifest = {
        "run": name, "profile": task["profile"], "status": status, "hash": task["hash"],
        "inputs": task["inputs"], "notebook": shown_notebook, "seconds": round(seconds, 3),
        "finished": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
        "python": sys.version.split()[0],
        "outputs": {p.name: sha256_file(p) for p in sorted(tmp.iterdir())
                    if p.is_file() and p.name not in _NOT_OUTPUTS},
        "overrides": task.get("overrides") or {}, **run_environment(root),
    }
    (tmp / "manifest.json").write_text(json.dumps(manifest, indent=2, sort_keys=True, default=str) + "\n")
    swap_into_place(tmp, target)
    first = error.strip().splitlines()[:2]
    return RunResult(name, status, seconds, str(target), " | ".join(first)).to_dict()


MANIFEST_PACKAGES = ("numpy", "scipy", "trimesh", "threadpoolctl", "robust-laplacian", "potpourri3d", "matplotlib",
                     "pyvista", "vtk", "pymeshlab", "libigl", "papermill", "nbclient", "ipykernel")


def run_environment(root=None) -> dict:
    """What a run's numbers depend on beyond its inputs: package versions, the BLAS in use, the git commit."""
    versions = package_versions(("prodmaps", *MANIFEST_PACKAGES))
    try:
        import numpy  # noqa: F401  (loads the BLAS threadpoolctl reports)
        from threadpoolctl import threadpool_info

        blas = [{k: i.get(k) for k in ("internal_api", "version", "architecture", "num_threads", "threading_layer")}
                for i in threadpool_info() if i.get("user_api") == "blas"]
    except Exception:  # threadpoolctl missing or failing: the manifest says so, the run goes on
        blas = []
    return {"versions": versions, "blas": blas, "commit": git_commit(root)}


def package_versions(names) -> dict:
    """``{package: version}`` of the installed packages among ``names``."""
    from importlib import metadata

    versions = {}
    for name in names:
        with contextlib.suppress(metadata.PackageNotFoundError):
            versions[name] = metadata.version(name)
    return versions


def git_commit(root=None) -> str:
    """The project's ``git rev-parse HEAD`` (``+dirty`` with uncommitted changes), or ``"unknown"``."""
    import subprocess

    cwd = str(root or Path.cwd())
    try:
        r = subprocess.run(["git", "rev-parse", "HEAD"], cwd=cwd, capture_output=True, text=True, timeout=10)
        if r.returncode != 0:
            return "unknown"
        d = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], cwd=cwd, capture_output=True,
                           text=True, timeout=20)
        return r.stdout.strip() + ("+dirty" if d.returncode == 0 and d.stdout.strip() else "")
    except (OSError, subprocess.TimeoutExpired):
        return "unknown"


def _is_current(run_dir: Path, h: str) -> bool:
    m = read_json(run_dir / "manifest.json", {})
    if m.get("hash") != h or m.get("status") != "ok":
        return False
    outs = m.get("outputs", {})
    return "results.json" in outs and all((run_dir / f).is_file() for f in outs)


def _check_declared(run, params: dict, where: str) -> None:
    """Refuse parameters the notebook does not declare (a typo would silently do nothing)."""
    if not run.notebook.is_file():
        return  # reported as a failed run, with the path
    declared = declared_parameters(run.notebook)
    unknown = sorted(set(params) - set(declared))
    if unknown:
        raise ParameterError(
            f"run {run.name!r}: {where} {unknown} not declared in the parameters cell of "
            f"{run.notebook.name}; it declares {sorted(declared)}")
    for k, v in params.items():
        default, text = literal(declared[k]["default"]), declared[k]["default"]
        _check_value(run.name, k, v, default, f"its default in {run.notebook.name} is {text}",
                     f"its default {text} ({type(default).__name__}) in {run.notebook.name}")


def _check_value(run: str, k: str, v, ref, where: str, ref_kind: str) -> None:
    """Refuse a bare word where ``ref`` (a default, a registry value) is no string, and a value of another kind."""
    if isinstance(v, BareWord) and not isinstance(ref, str):
        raise ParameterError(f"run {run!r}: parameter {k}={v!s} is not a literal (number, list, quoted string, ...) "
                             f"and {where}: give a literal (e.g. -p '{k}=[4, 8]'), or quote a string "
                             f"(-p '{k}=\"{v!s}\"')")
    if not _same_kind(v, ref):
        raise ParameterError(f"run {run!r}: parameter {k}={v!r} ({type(v).__name__}) does not match the type of "
                             + ref_kind + f": {k} expects {_kind(ref)} (e.g. -p '{k}={json.dumps(ref)}')")


def _kind(value) -> str:
    """What a parameter of ``value``'s type expects, in words (``"an integer"``, ``"a list of integers"``)."""
    if isinstance(value, (list, tuple)):
        kinds = {_kind(x) for x in value}
        return "a list" + (f" of {kinds.pop().split(' ', 1)[1]}s" if len(kinds) == 1 else "")
    return {bool: "a boolean", int: "an integer", float: "a number", str: "a string", dict: "a table"}.get(
        type(value), f"a {type(value).__name__}")


def _same_kind(value, default) -> bool:
    """Whether ``value`` may replace ``default`` (a default, a registry value).

    Either is None, or both are bools, strings, tables, integers or numbers (an integer for a float,
    never a float for an integer), or lists whose items are each of the kind of a homogeneous default's.
    """
    if default is None or value is None:
        return True
    if isinstance(default, bool) or isinstance(value, bool):
        return isinstance(default, bool) and isinstance(value, bool)
    if isinstance(default, int):  # counts, sizes, seeds: 2.5 (or 2.0) is not one
        return isinstance(value, int)
    if isinstance(default, (list, tuple)) and isinstance(value, (list, tuple)):
        kinds = {type(x) for x in default}  # a homogeneous list decides its items' kind
        return len(kinds) != 1 or not default or all(_same_kind(x, default[0]) for x in value)
    kinds = ((int, float), (str,), (list, tuple), (dict,))
    return any(isinstance(default, k) and isinstance(value, k) for k in kinds)


DEFAULT_DATASET = "anny_humans"


def profile_folder(out, profile: str, dataset: str | None = None) -> Path:
    """``OUT/<profile>`` for the default data, else ``OUT/<profile>-<dataset>`` (beside those, never over them)."""
    out = Path(out).resolve()
    return out / (profile if dataset in (None, DEFAULT_DATASET) else f"{profile}-{dataset}")


def plan_runs(runs: dict, *, only=None, profile: str = "paper", dataset=None, overrides=None,
              out="results", kernel_name: str = "python3", timeout=None, cwd=None) -> list[dict]:
    """Resolve the selected runs into task dicts (parameters, target folder, input hash).

    Raises :class:`ParameterError` if a registry parameter or an override is not declared by
    the run's notebook, ``ValueError`` for an unknown run or profile.
    """
    if profile not in PROFILES:
        raise ValueError(f"unknown profile {profile!r}; choose one of {PROFILES}")
    names = list(runs) if not only else list(only)
    unknown = [n for n in names if n not in runs]
    if unknown:
        raise ValueError(f"unknown run(s) {unknown}; registered runs: {list(runs)}")
    reserved = sorted(set(overrides or {}) & {"out_dir", "profile"})
    if reserved:
        raise ParameterError(f"parameter(s) {reserved} are set by the pipeline, not by -p: use --out for the "
                             "output root (runs go to OUT/<profile>/<run>) and --profile for the profile")
    out = Path(out).resolve()
    tasks = []
    for n in dict.fromkeys(names):
        run = runs[n]
        params = run.parameters(profile, dataset)
        _check_declared(run, params, f"registry parameters (params.{profile}"
                        + (f" and datasets.{dataset})" if dataset in run.datasets else ")"))
        if dataset is not None:
            params["dataset"] = dataset
        for k, v in (overrides or {}).items():  # a default of None leaves the kind to the registry's value
            ref = params.get(k)
            if ref is not None:
                _check_value(n, k, v, ref, f"its value in params.{profile} is {ref!r}",
                             f"the registry's params.{profile}.{k} = {ref!r} ({type(ref).__name__})")
        params.update(overrides or {})
        _check_declared(run, {k: v for k, v in params.items() if k not in run.parameters(profile, dataset)},
                        "parameters")
        params["profile"] = profile
        ds = params.get("dataset") or (parameter_default(run.notebook, "dataset") if run.notebook.is_file() else None)
        h, inputs = run_hash(run.notebook, params, ds, kernel_name, cwd=cwd)
        tasks.append({
            "name": n, "notebook": str(run.notebook), "params": params, "profile": profile,
            "run_dir": str(profile_folder(out, profile, dataset) / n), "hash": h, "inputs": inputs,
            "kernel_name": kernel_name, "timeout": timeout, "cwd": str(cwd or Path.cwd()),
            "overrides": dict(overrides or {}),
        })
    return tasks


class _Progress:
    """tqdm progress bar when available, plain lines otherwise."""

    def __init__(self, total: int, enabled: bool, stream):
        self.bar, self.stream = None, stream
        with contextlib.suppress(ModuleNotFoundError):
            if enabled:
                from tqdm import tqdm

                self.bar = tqdm(total=total, desc="reproduce", unit="run", file=stream, dynamic_ncols=True)

    def done(self, res: dict) -> None:
        line = f"  {res['status']:<8} {res['name']:<28} {res['seconds']:8.1f} s"
        if res["status"] == "failed":
            line += f"   {res['error']}"
        if self.bar is not None:
            self.bar.write(line)
            self.bar.set_postfix_str(res["name"])
            self.bar.update(1)
        else:
            print(line, file=self.stream, flush=True)

    def close(self):
        if self.bar is not None:
            self.bar.close()


def reproduce(*, registry=None, only=None, profile: str = "paper", dataset=None, overrides=None,
              out="results", jobs: int = 1, force: bool = False, scheduler=None,
              kernel_name: str = "python3", timeout=None, progress: bool = True,
              stream=None) -> list[RunResult]:
    """Run the selected registry entries; returns one :class:`RunResult` per run (registry order).

    Skips runs whose inputs are unchanged (see the module doc) unless ``force``. ``jobs`` > 1
    uses a local process pool; ``scheduler`` (a Dask scheduler address, or a
    ``distributed.Client``) sends one task per run to a Dask cluster instead
    (:mod:`prodmaps.pipeline.schedulers`).
    """
    own_stream = None
    if stream is None:
        # a duplicate of the terminal's stderr: fd 2 itself is redirected during runs
        try:
            own_stream = stream = os.fdopen(os.dup(sys.stderr.fileno()), "w", buffering=1)
        except (AttributeError, OSError, ValueError):  # e.g. a captured stream without a file descriptor
            stream = sys.stderr
    runs = load_registry(registry)
    tasks = plan_runs(runs, only=only, profile=profile, dataset=dataset, overrides=overrides,
                      out=out, kernel_name=kernel_name, timeout=timeout, cwd=project_root(registry))
    skipped = [t for t in tasks if not force and _is_current(Path(t["run_dir"]), t["hash"])]
    # the kernels' run_parameters read the registry the runs came from (--registry too)
    env = {**thread_env(jobs if scheduler is None else 1), RUNS_ENV: str(registry_path(registry)),
           **absolute_path_env()}
    todo = [dict(t, env=env) for t in tasks if t not in skipped]
    results = {t["name"]: RunResult(t["name"], "skipped", 0.0, t["run_dir"]).to_dict() for t in skipped}
    bar = _Progress(len(tasks), progress, stream)
    for r in results.values():
        bar.done(r)
    try:
        if scheduler is not None:
            results_iter = run_dask(todo, scheduler, _execute_task, _collect)
        elif jobs <= 1 or len(todo) <= 1:
            results_iter = (_safe_execute(t) for t in todo)
        else:
            results_iter = run_pool(todo, jobs, _execute_task, _collect)
        for r in results_iter:
            results[r["name"]] = r
            bar.done(r)
    finally:
        bar.close()
        if own_stream is not None:
            own_stream.close()
    return [RunResult(**results[t["name"]]) for t in tasks]


PATH_ENVS = ("PRODMAPS_CACHE", "PRODMAPS_DATA")


def absolute_path_env() -> dict:
    """``PRODMAPS_CACHE`` / ``PRODMAPS_DATA`` set to a relative path, made absolute against this process's folder.

    The kernels run in the project root: left relative, ``PRODMAPS_CACHE=cache`` would put the cache
    into the checkout and ``PRODMAPS_DATA=data`` would name another folder than the one checked here.
    """
    out = {}
    for name in PATH_ENVS:
        value = os.environ.get(name, "")
        if value.strip() and not Path(value).expanduser().is_absolute():
            out[name] = str(Path.cwd() / Path(value).expanduser())
    return out


def absolute_param_files(overrides: dict, root: Path | None = None) -> dict:
    """``-p`` string values that name a file relative to this process's folder (and not in ``root``), made absolute.

    As :func:`absolute_path_env`: the notebooks run in the project root ``root``, and a user who types
    ``-p mesh_1=scan.ply`` in their own folder means that folder's file. A value that names a file
    relative to ``root`` keeps its meaning (and the run its hash); other values are left as given.
    """
    out = dict(overrides)
    for key, value in overrides.items():
        if isinstance(value, str) and value.strip() and not Path(value).expanduser().is_absolute():
            rel = Path(value).expanduser()
            if (Path.cwd() / rel).is_file() and not (root is not None and (root / rel).is_file()):
                out[key] = str((Path.cwd() / rel).resolve())
    return out


def _safe_execute(task) -> dict:
    """:func:`_execute_task` in this process; an unexpected error fails that run only."""
    try:
        return _execute_task(task)
    except Exception as exc:  # e.g. the output folder is not writable
        return _failed(task, "could not run", exc)


def _collect(fut, task) -> dict:
    """Result of a pool/Dask future; a crashed worker becomes a failed run, not an exception."""
    try:
        return fut.result()
    except Exception as exc:  # worker died (e.g. killed by the OOM killer)
        return _failed(task, "worker crashed", exc)


def _failed(task, what: str, exc: Exception) -> dict:
    return RunResult(task["name"], "failed", 0.0, task["run_dir"], f"{what}: {type(exc).__name__}: {exc}").to_dict()


def summary(results: list[RunResult]) -> str:
    """Plain-text summary: counts, then one line per failure naming its error file."""
    n = {s: sum(r.status == s for r in results) for s in ("ok", "skipped", "failed")}
    total = sum(r.seconds for r in results)
    lines = [f"{len(results)} run(s): {n['ok']} ran, {n['skipped']} skipped (unchanged), "
             f"{n['failed']} failed; {total:.1f} s of notebook time"]
    for r in results:
        if r.status == "failed":
            lines.append(f"FAILED {r.name}: {r.error}")
            lines.append(f"       see {Path(r.run_dir) / 'error.txt'} and {Path(r.run_dir) / 'executed.ipynb'}")
    return "\n".join(lines)
