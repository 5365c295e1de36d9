"""Batch regeneration of the paper's notebooks: run registry, resumable runs, failure isolation.

Run registry
------------
Every run is an entry of ``paper/runs.toml`` (another file through ``$PRODMAPS_RUNS`` or the
``registry=`` arguments)::

    [runs.fig04]
    notebook = "notebooks/fig04_coordinate_reconstruction.ipynb"   # relative to the project root
    reproduces = "Figure 4"
    title = "Coordinate reconstruction, k = 9..69"                  # optional
    [runs.fig04.params.smoke]        # papermill parameters of the smoke profile
    [runs.fig04.params.paper]        # ... and of the paper profile
    [runs.fig04.tolerances]          # optional, for prodmaps.diffing (dotted-key globs)
    "results.errors.*" = { rtol = 1e-6, atol = 1e-9 }

Several runs may share one notebook with different parameters (e.g. the six tables). Relative
notebook paths are resolved against the project root: the parent of the folder holding the
registry (``paper/..``), or the folder named by an optional top-level ``root = "..."`` key
(relative to the registry file). Notebooks execute with the project root as working directory.

Parameters passed to a notebook: the registry's ``params.<profile>``, then ``dataset`` (if
given), then the ``-p key=value`` overrides, and always ``profile`` and ``out_dir``.

Outputs and resumability
------------------------
Run ``X`` of profile ``P`` writes into ``OUT/P/X/``: whatever the notebook writes
(``results.json``, PNGs), the executed notebook ``executed.ipynb``, the kernel's stderr
``kernel.log`` (local runs) and ``manifest.json``.
The manifest records a hash over the notebook's bytes, the parameters, the library code
(every ``prodmaps/*.py``), the input data (the dataset's ``SHA256SUMS`` file, or the sizes and
modification times of its files) and the kernel name. A run whose hash is unchanged, whose
last execution succeeded and whose outputs still exist is skipped (``force=True`` redoes it).
Hashes are over contents, not modification times: ``touch`` alone reruns nothing, an edit
(or a fresh clone with other bytes) does. Editing any ``prodmaps/*.py`` reruns every run.

Each run executes into a temporary folder beside its target (``OUT/P/.X.tmp-*``) which is then
renamed into place, so ``OUT/P/X`` is never half written. A failing run keeps its executed
notebook (with the traceback in the failing cell), ``error.txt`` and any partial outputs in
``OUT/P/X/``; its manifest says ``"status": "failed"`` so the next invocation retries it. One
failing run never stops the others. Do not run two invocations on the same ``OUT`` at once.

Parallelism: ``jobs > 1`` runs notebooks in a local process pool; ``scheduler=ADDRESS`` sends
one task per run to a Dask distributed cluster (workers must see the same file system and be
able to import ``prodmaps``). Nothing here imports papermill, tqdm or dask at module import.
"""

from __future__ import annotations

import contextlib
import datetime as _dt
import hashlib
import json
import os
import re
import shutil
import sys
import tempfile
import threading
import time
import traceback
from dataclasses import dataclass, field
from pathlib import Path

__all__ = [
    "REPO_ROOT", "PROFILES", "Run", "RegistryError", "registry_path", "load_registry",
    "parse_param", "parse_params", "run_notebook", "run_hash", "library_hash", "data_hash",
    "plan_runs", "reproduce", "update_baselines", "RunResult",
]

REPO_ROOT = Path(__file__).resolve().parents[1]
PROFILES = ("smoke", "paper")
DEFAULT_DATASET = "anny_humans"
_NAME_RE = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]*$")
_RUN_KEYS = {"notebook", "reproduces", "title", "params", "tolerances", "description"}


class RegistryError(ValueError):
    """A malformed run registry (names the file, the run and the problem)."""


@dataclass(frozen=True)
class Run:
    """One registry entry. ``notebook`` is an absolute path; ``params[profile]`` a dict."""

    name: str
    notebook: Path
    reproduces: str = ""
    title: str = ""
    params: dict = field(default_factory=dict)
    tolerances: dict = field(default_factory=dict)

    def parameters(self, profile: str) -> dict:
        return dict(self.params.get(profile, {}))


# ------------------------------------------------------------------------------ registry
def _toml():
    try:
        import tomllib  # Python >= 3.11
    except ModuleNotFoundError:  # pragma: no cover - Python 3.10
        try:
            import tomli as tomllib
        except ModuleNotFoundError as exc:
            raise ModuleNotFoundError("reading paper/runs.toml on Python 3.10 needs `pip install tomli`") from exc
    return tomllib


def registry_path(path=None) -> Path:
    """``path`` if given, else ``$PRODMAPS_RUNS``, else ``<repo>/paper/runs.toml``."""
    if path is not None:
        return Path(path).expanduser().resolve()
    env = os.environ.get("PRODMAPS_RUNS")
    if env:
        return Path(env).expanduser().resolve()
    return REPO_ROOT / "paper" / "runs.toml"


def load_registry(path=None) -> dict[str, Run]:
    """Read the run registry (see the module doc) into ``{name: Run}`` in file order."""
    path = registry_path(path)
    if not path.is_file():
        raise RegistryError(f"run registry {path} not found (set PRODMAPS_RUNS or pass --registry)")
    try:
        doc = _toml().loads(path.read_text(encoding="utf-8"))
    except Exception as exc:  # tomllib.TOMLDecodeError
        raise RegistryError(f"{path}: not valid TOML: {exc}") from exc
    root = (path.parent / doc.get("root", "..")).resolve()
    runs = doc.get("runs", {})
    if not isinstance(runs, dict):
        raise RegistryError(f"{path}: [runs] must be a table of runs")
    out: dict[str, Run] = {}
    for name, entry in runs.items():
        where = f"{path}: run {name!r}"
        if not _NAME_RE.match(name):
            raise RegistryError(f"{where}: run names may use letters, digits, '_', '-', '.'")
        if not isinstance(entry, dict):
            raise RegistryError(f"{where}: must be a table")
        unknown = set(entry) - _RUN_KEYS
        if unknown:
            raise RegistryError(f"{where}: unknown keys {sorted(unknown)}; allowed {sorted(_RUN_KEYS)}")
        if "notebook" not in entry:
            raise RegistryError(f"{where}: missing `notebook = \"notebooks/....ipynb\"`")
        params = entry.get("params", {})
        if not isinstance(params, dict) or not all(isinstance(v, dict) for v in params.values()):
            raise RegistryError(f"{where}: params must be tables [runs.{name}.params.<profile>]")
        for prof, p in params.items():
            reserved = {"profile", "out_dir"} & set(p)
            if reserved:
                raise RegistryError(f"{where}: params.{prof} must not set {sorted(reserved)} (added by the runner)")
        tol = entry.get("tolerances", {})
        if not isinstance(tol, dict):
            raise RegistryError(f"{where}: tolerances must be a table of key-glob = {{rtol, atol}}")
        nb = Path(entry["notebook"])
        out[name] = Run(
            name=name, notebook=(nb if nb.is_absolute() else root / nb).resolve(),
            reproduces=str(entry.get("reproduces", "")), title=str(entry.get("title", "")),
            params={k: dict(v) for k, v in params.items()}, tolerances=dict(tol),
        )
    return out


def parse_param(text: str):
    """``key=value`` -> ``(key, value)``; value read as JSON, else a TOML literal, else a string."""
    if "=" not in text:
        raise ValueError(f"parameter {text!r} must look like key=value")
    key, raw = text.split("=", 1)
    key = key.strip()
    if not key.isidentifier():
        raise ValueError(f"parameter name {key!r} is not a valid Python identifier")
    try:
        return key, json.loads(raw)
    except ValueError:
        pass
    try:
        return key, _toml().loads(f"v = {raw}")["v"]
    except Exception:
        return key, raw


def parse_params(items) -> dict:
    return dict(parse_param(t) for t in (items or []))


# ------------------------------------------------------------------------------ hashing
def _sha256_bytes(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def _sha256_file(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for chunk in iter(lambda: fh.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def library_hash() -> str:
    """Hash of the bytes of every ``prodmaps/*.py`` (sorted by name)."""
    h = hashlib.sha256()
    for p in sorted(Path(__file__).resolve().parent.glob("*.py")):
        h.update(p.name.encode() + b"\0" + p.read_bytes() + b"\0")
    return h.hexdigest()


def _data_root() -> Path:
    env = os.environ.get("PRODMAPS_DATA")
    return Path(env).expanduser().resolve() if env else REPO_ROOT / "data"


def data_hash(dataset: str | None) -> str:
    """Cheap fingerprint of a dataset's files: its ``SHA256SUMS`` bytes if present, else the
    relative paths, sizes and modification times of its files. ``"none"`` if no dataset."""
    if not dataset:
        return "none"
    d = _data_root() / str(dataset)
    sums = d / "SHA256SUMS"
    if sums.is_file():
        return "sha256sums:" + _sha256_file(sums)
    if not d.is_dir():
        return "missing:" + str(dataset)
    h = hashlib.sha256()
    for p in sorted(q for q in d.rglob("*") if q.is_file()):
        st = p.stat()
        h.update(f"{p.relative_to(d).as_posix()}\0{st.st_size}\0{st.st_mtime_ns}\0".encode())
    return "stat:" + h.hexdigest()


def _notebook_default(notebook: Path, name: str):
    """Default of a variable assigned a simple literal in the notebook's ``parameters`` cell."""
    try:
        nb = json.loads(notebook.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    for cell in nb.get("cells", []):
        if "parameters" in cell.get("metadata", {}).get("tags", []):
            src = "".join(cell.get("source", []))
            m = re.search(rf"^\s*{re.escape(name)}\s*=\s*(['\"])(.*?)\1", src, re.M)
            return m.group(2) if m else None
    return None


def run_hash(notebook: Path, params: dict, dataset: str | None, kernel_name: str = "python3") -> tuple[str, dict]:
    """``(hash, inputs)`` of one run: notebook bytes, parameters (without ``out_dir``),
    library code, input data and kernel name."""
    inputs = {
        "notebook": _sha256_file(notebook) if notebook.is_file() else "missing",
        "parameters": {k: v for k, v in sorted(params.items()) if k != "out_dir"},
        "library": library_hash(),
        "data": data_hash(dataset),
        "kernel": kernel_name,
    }
    blob = json.dumps(inputs, sort_keys=True, default=str).encode()
    return _sha256_bytes(blob), inputs


# ------------------------------------------------------------------------------ one notebook
def run_notebook(notebook, out_dir, params=None, kernel_name: str = "python3", *,
                 timeout: float | None = None, cwd=None, executed_name: str = "executed.ipynb"):
    """Execute ``notebook`` with papermill, writing into ``out_dir``; return the executed notebook path.

    ``out_dir`` is passed to the notebook as the ``out_dir`` parameter (absolute path) and the
    executed copy is saved there as ``executed_name``. The working directory is the project
    root (``cwd``). Raises papermill's ``PapermillExecutionError`` if a cell fails (the executed
    notebook with the traceback is still written). ``timeout`` is per cell, in seconds.
    """
    import papermill as pm_

    out = Path(out_dir).resolve()
    out.mkdir(parents=True, exist_ok=True)
    parameters = dict(params or {})
    parameters["out_dir"] = str(out)
    executed = out / executed_name
    pm_.execute_notebook(
        str(notebook), str(executed), parameters=parameters, kernel_name=kernel_name,
        cwd=str(cwd or REPO_ROOT), progress_bar=False, log_output=False,
        execution_timeout=timeout,
    )
    return executed


# ------------------------------------------------------------------------------ run loop
@dataclass
class RunResult:
    name: str
    status: str  # "ok", "skipped", "failed"
    seconds: float = 0.0
    run_dir: str = ""
    error: str = ""

    def to_dict(self) -> dict:
        return dict(self.__dict__)


_NOT_OUTPUTS = ("manifest.json", "executed.ipynb", "error.txt", "kernel.log")
_ANSI = re.compile(r"\x1b\[[0-9;]*[A-Za-z]")


def _output_files(folder: Path) -> dict:
    return {
        p.name: _sha256_file(p) for p in sorted(folder.iterdir())
        if p.is_file() and p.name not in _NOT_OUTPUTS
    }


def _relocate_out_dir(results: Path, tmp: Path, final: Path) -> None:
    """Rewrite ``parameters.out_dir`` in results.json from the temporary to the final folder."""
    if not results.is_file():
        return
    try:
        doc = json.loads(results.read_text())
    except ValueError:
        return
    par = doc.get("parameters")
    if isinstance(par, dict) and isinstance(par.get("out_dir"), str) and Path(par["out_dir"]) == tmp:
        try:
            par["out_dir"] = final.relative_to(REPO_ROOT).as_posix()
        except ValueError:
            par["out_dir"] = str(final)
        results.write_text(json.dumps(doc, indent=2, sort_keys=True) + "\n")


def _mkdtemp_beside(target: Path, name: str) -> Path:
    """A fresh hidden folder next to ``target`` with the usual (umask) permissions."""
    tmp = Path(tempfile.mkdtemp(prefix=f".{name}.tmp-", dir=target.parent))
    os.chmod(tmp, 0o755)  # mkdtemp makes it 0700
    return tmp


@contextlib.contextmanager
def _stderr_to(path: Path):
    """Send file descriptor 2 (inherited by the Jupyter kernel) to ``path`` while running.

    Keeps kernel chatter (ipykernel/VTK warnings) out of the progress display and in the run
    folder as ``kernel.log``. Only in the main thread (Dask runs tasks in threads: no redirect).
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    sys.stderr.flush()
    saved = os.dup(2)
    try:
        with open(path, "ab") as fh:
            os.dup2(fh.fileno(), 2)
            try:
                yield
            finally:
                sys.stderr.flush()
                os.dup2(saved, 2)
    finally:
        os.close(saved)


def _swap_into_place(tmp: Path, target: Path) -> None:
    """Replace ``target`` by ``tmp`` (same parent) with renames; never leaves a half folder."""
    old = None
    if target.exists():
        old = target.with_name(f".{target.name}.old-{os.getpid()}-{time.monotonic_ns()}")
        os.replace(target, old)
    os.replace(tmp, target)
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)


def _execute_task(task: dict) -> dict:
    """Execute one planned run (in this process, a pool worker or a Dask worker)."""
    name, target = task["name"], Path(task["run_dir"])
    target.parent.mkdir(parents=True, exist_ok=True)
    for env, val in (task.get("env") or {}).items():
        os.environ.setdefault(env, val)
    for stale in target.parent.glob(f".{name}.tmp-*"):  # left by an interrupted invocation
        shutil.rmtree(stale, ignore_errors=True)
    tmp = _mkdtemp_beside(target, name)
    t0 = time.perf_counter()
    error = ""
    try:
        with _stderr_to(tmp / "kernel.log"):
            run_notebook(task["notebook"], tmp, task["params"], task.get("kernel_name", "python3"),
                         timeout=task.get("timeout"), cwd=task.get("cwd"))
        _relocate_out_dir(tmp / "results.json", tmp, target)
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
        else:
            error = "".join(traceback.format_exception(type(exc), exc, exc.__traceback__))
        (tmp / "error.txt").write_text(error)
    seconds = time.perf_counter() - t0
    status = "failed" if error else "ok"
    manifest = {
        "run": name, "profile": task["profile"], "status": status, "hash": task["hash"],
        "inputs": task["inputs"], "notebook": task["notebook"], "seconds": round(seconds, 3),
        "finished": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
        "python": sys.version.split()[0], "outputs": _output_files(tmp),
    }
    (tmp / "manifest.json").write_text(json.dumps(manifest, indent=2, sort_keys=True, default=str) + "\n")
    _swap_into_place(tmp, target)
    first = error.strip().splitlines()[:2]
    return RunResult(name, status, seconds, str(target), " | ".join(first)).to_dict()


def _is_current(run_dir: Path, h: str) -> bool:
    man = run_dir / "manifest.json"
    if not man.is_file():
        return False
    try:
        m = json.loads(man.read_text())
    except ValueError:
        return False
    if m.get("hash") != h or m.get("status") != "ok":
        return False
    outs = m.get("outputs", {})
    return "results.json" in outs and all((run_dir / f).is_file() for f in outs)


def plan_runs(runs: dict, *, only=None, profile: str = "paper", dataset=None, overrides=None,
              out="results", kernel_name: str = "python3", timeout=None) -> list[dict]:
    """Resolve the selected runs into task dicts (parameters, target folder, input hash)."""
    if profile not in PROFILES:
        raise ValueError(f"unknown profile {profile!r}; choose one of {PROFILES}")
    names = list(runs) if not only else list(only)
    unknown = [n for n in names if n not in runs]
    if unknown:
        raise ValueError(f"unknown run(s) {unknown}; registered runs: {list(runs)}")
    out = Path(out).resolve()
    tasks = []
    for n in dict.fromkeys(names):
        run = runs[n]
        params = run.parameters(profile)
        if dataset is not None:
            params["dataset"] = dataset
        params.update(overrides or {})
        params["profile"] = profile
        ds = params.get("dataset") or _notebook_default(run.notebook, "dataset")
        h, inputs = run_hash(run.notebook, params, ds, kernel_name)
        tasks.append({
            "name": n, "notebook": str(run.notebook), "params": params, "profile": profile,
            "run_dir": str(out / profile / n), "hash": h, "inputs": inputs,
            "kernel_name": kernel_name, "timeout": timeout, "cwd": str(REPO_ROOT),
        })
    return tasks


class _Progress:
    """tqdm progress bar when available, plain lines otherwise."""

    def __init__(self, total: int, enabled: bool, stream):
        self.bar = None
        self.stream = stream
        if enabled:
            try:
                from tqdm import tqdm

                self.bar = tqdm(total=total, desc="reproduce", unit="run", file=stream, dynamic_ncols=True)
            except ModuleNotFoundError:
                self.bar = None

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


def _thread_env(jobs: int) -> dict:
    """With several notebooks at once, cap BLAS threads so they do not oversubscribe the CPUs."""
    if jobs <= 1:
        return {}
    n = str(max(1, (os.cpu_count() or 1) // jobs))
    return {k: n for k in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")}


def reproduce(*, registry=None, only=None, profile: str = "paper", dataset=None, overrides=None,
              out="results", jobs: int = 1, force: bool = False, scheduler=None,
              kernel_name: str = "python3", timeout=None, progress: bool = True,
              stream=None) -> list[RunResult]:
    """Run the selected registry entries; returns one :class:`RunResult` per run (registry order).

    Skips runs whose inputs are unchanged (see the module doc) unless ``force``. ``jobs`` > 1
    uses a local process pool; ``scheduler`` (a Dask scheduler address, or a
    ``distributed.Client``) sends one task per run to a Dask cluster instead.
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
                      out=out, kernel_name=kernel_name, timeout=timeout)
    results: dict[str, dict] = {}
    todo = []
    for t in tasks:
        if not force and _is_current(Path(t["run_dir"]), t["hash"]):
            results[t["name"]] = RunResult(t["name"], "skipped", 0.0, t["run_dir"]).to_dict()
        else:
            todo.append(t)
    bar = _Progress(len(tasks), progress, stream)
    for r in results.values():
        bar.done(r)
    env = _thread_env(jobs if scheduler is None else 1)
    for t in todo:
        t["env"] = env
    try:
        if scheduler is not None:
            for r in _run_dask(todo, scheduler):
                results[r["name"]] = r
                bar.done(r)
        elif jobs <= 1 or len(todo) <= 1:
            for t in todo:
                r = _safe_execute(t)
                results[r["name"]] = r
                bar.done(r)
        else:
            import multiprocessing as mp
            from concurrent.futures import ProcessPoolExecutor, as_completed

            with ProcessPoolExecutor(max_workers=min(jobs, len(todo)), mp_context=mp.get_context("spawn")) as ex:
                futs = {ex.submit(_execute_task, t): t for t in todo}
                for fut in as_completed(futs):
                    r = _collect(fut, futs[fut])
                    results[r["name"]] = r
                    bar.done(r)
    finally:
        bar.close()
        if own_stream is not None:
            own_stream.close()
    return [RunResult(**results[t["name"]]) for t in tasks]


def _safe_execute(task) -> dict:
    """:func:`_execute_task` in this process; an unexpected error fails that run only."""
    try:
        return _execute_task(task)
    except Exception as exc:  # e.g. the output folder is not writable
        msg = f"could not run: {type(exc).__name__}: {exc}"
        return RunResult(task["name"], "failed", 0.0, task["run_dir"], msg).to_dict()


def _collect(fut, task) -> dict:
    """Result of a pool/Dask future; a crashed worker becomes a failed run, not an exception."""
    try:
        return fut.result()
    except Exception as exc:  # worker died (e.g. killed by the OOM killer)
        msg = f"worker crashed: {type(exc).__name__}: {exc}"
        return RunResult(task["name"], "failed", 0.0, task["run_dir"], msg).to_dict()


def _run_dask(tasks: list[dict], scheduler):
    """Submit one task per run to a Dask cluster and yield results as they finish."""
    if not tasks:
        return
    try:
        from dask.distributed import Client, as_completed
    except ModuleNotFoundError as exc:
        raise ModuleNotFoundError("--scheduler needs Dask: pip install 'prodmaps[dask]'") from exc
    own = not hasattr(scheduler, "submit")
    client = Client(scheduler) if own else scheduler
    try:
        futs = {}
        for t in tasks:
            f = client.submit(_execute_task, t, key=f"prodmaps-{t['name']}-{t['hash'][:12]}-{time.time_ns()}",
                              pure=False, retries=0)
            futs[f] = t
        for f in as_completed(list(futs)):
            yield _collect(f, futs[f])
    finally:
        if own:
            client.close()


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


def baselines_dir(registry=None, profile: str = "smoke") -> Path:
    """``<folder of the registry>/baselines/<profile>`` (``paper/baselines/smoke`` by default)."""
    return registry_path(registry).parent / "baselines" / profile


def update_baselines(results: list[RunResult], dest) -> list[str]:
    """Copy ``results.json`` and PNGs of successful runs into ``dest/<run>/`` (replacing it)."""
    dest = Path(dest)
    done = []
    for r in results:
        if r.status not in ("ok", "skipped"):
            continue
        src = Path(r.run_dir)
        files = [src / "results.json"] + sorted(src.glob("*.png"))
        _mkdir(dest)
        tmp = _mkdtemp_beside(dest / r.name, r.name)
        for f in files:
            shutil.copy2(f, tmp / f.name)
        _swap_into_place(tmp, dest / r.name)
        done.append(r.name)
    return done


def _mkdir(p: Path) -> Path:
    p.mkdir(parents=True, exist_ok=True)
    return p
