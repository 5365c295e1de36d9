"""Content hashes that decide whether a run must be redone.

A run's hash covers what can change its outputs, and nothing else:

* the notebook's bytes and the parameters it is given (without ``out_dir``);
* the code a notebook can import: every file of the installed ``prodmaps`` package — the math
  library and :mod:`prodmaps.experiments` with its data files (claims ledger, published tables)
  — **except** :mod:`prodmaps.pipeline` (this subpackage: registry, execution, diffing, report,
  CLI) and the embedded datasets (hashed separately), so editing the report reruns nothing;
* the input data (the dataset's ``SHA256SUMS`` file, or the sizes and modification times of its
  files), and the contents of every file a string parameter names (``-p mesh_1=/my/scan.ply``;
  absolute, or relative to the notebooks' working directory, the project root), so editing one's
  own mesh reruns the run that reads it;
* the kernel name.

Hashes are over contents, not modification times: ``touch`` alone reruns nothing.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

from .. import datasets
from ..files import sha256_bytes, sha256_file

__all__ = ["library_hash", "library_files", "data_hash", "run_hash"]

_PACKAGE = Path(__file__).resolve().parents[1]  # the installed prodmaps package
_SKIP = ("pipeline", "data")  # subfolders of the package that do not enter the library hash
_SUFFIXES = (".py", ".toml", ".csv", ".json")


def library_files() -> list[Path]:
    """The package files a notebook can import or read (sorted), see the module doc."""
    return [p for p in sorted(_PACKAGE.rglob("*")) if p.is_file() and p.suffix in _SUFFIXES
            and (rel := p.relative_to(_PACKAGE)).parts[0] not in _SKIP and "__pycache__" not in rel.parts]


def library_hash() -> str:
    """Hash of the bytes of :func:`library_files` (with their relative names)."""
    h = hashlib.sha256()
    for p in library_files():
        h.update(p.relative_to(_PACKAGE).as_posix().encode() + b"\0" + p.read_bytes() + b"\0")
    return h.hexdigest()


def data_hash(dataset: str | None) -> str:
    """Cheap fingerprint of a dataset's files: ``SHA256SUMS``, else paths, sizes and times (``"none"`` if none)."""
    if not dataset:
        return "none"
    try:
        d = datasets.dataset_dir(str(dataset))
    except ValueError:  # not a registered dataset name
        d = datasets.data_root() / str(dataset)
    sums = d / "SHA256SUMS"
    if sums.is_file():
        return "sha256sums:" + sha256_file(sums)
    if not d.is_dir():
        return "missing:" + str(dataset)
    h = hashlib.sha256()
    for p in sorted(q for q in d.rglob("*") if q.is_file()):
        st = p.stat()
        h.update(f"{p.relative_to(d).as_posix()}\0{st.st_size}\0{st.st_mtime_ns}\0".encode())
    return "stat:" + h.hexdigest()


def parameter_files(params: dict, cwd=None) -> dict:
    """``{name: sha256}`` of the string parameters that name an existing file (absolute or relative to ``cwd``).

    A relative name that is no file under ``cwd`` (e.g. a default relative to the dataset's folder) is
    left out: the dataset's own fingerprint (:func:`data_hash`) covers it.
    """
    base = Path(cwd) if cwd is not None else Path.cwd()
    files = {}
    for k, v in sorted(params.items()):
        if k in ("out_dir", "profile", "dataset") or not isinstance(v, str) or not v.strip() or "\0" in v:
            continue
        try:
            p = base / Path(v).expanduser()
            if p.is_file():
                files[k] = sha256_file(p)
        except (OSError, ValueError):  # not a path this system can name
            continue
    return files


def run_hash(notebook: Path, params: dict, dataset: str | None, kernel_name: str = "python3", *,
             cwd=None) -> tuple[str, dict]:
    """``(hash, inputs)`` of one run (see the module doc); ``cwd``: the notebooks' working directory."""
    inputs = {"notebook": sha256_file(notebook) if Path(notebook).is_file() else "missing",
              "parameters": {k: v for k, v in sorted(params.items()) if k != "out_dir"},
              "library": library_hash(), "data": data_hash(dataset), "kernel": kernel_name}
    files = parameter_files(params, cwd)
    if files:  # only then: the hashes of runs that read no file of their own stay as they were
        inputs["files"] = files
    blob = json.dumps(inputs, sort_keys=True, default=str).encode()
    return sha256_bytes(blob), inputs
