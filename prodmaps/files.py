"""File helpers shared by the whole package: SHA-256 digests, atomic writes, TOML, JSON.

One implementation each: dataset checksums (:func:`prodmaps.datasets.verify_checksums`), the
preparation scripts, the pipeline's run hashes and every writer of results or caches use them;
the claims ledger and the run registry read their TOML with :func:`parse_toml`.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import shutil
import time
from pathlib import Path

__all__ = ["sha256_file", "sha256_bytes", "atomic_path", "swap_into_place", "parse_toml", "read_json"]

_CHUNK = 1 << 20


def sha256_bytes(data: bytes) -> str:
    """Hex SHA-256 of ``data``."""
    return hashlib.sha256(data).hexdigest()


def sha256_file(path) -> str:
    """Hex SHA-256 of a file's bytes, read in 1 MiB chunks."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for chunk in iter(lambda: fh.read(_CHUNK), b""):
            h.update(chunk)
    return h.hexdigest()


@contextlib.contextmanager
def atomic_path(path, suffix: str | None = None):
    """Yield a temporary path beside ``path``; on success it replaces ``path`` atomically.

    ``suffix`` (default: ``path``'s own) is kept on the temporary name so that writers which
    choose the format by extension (``np.save``, ``savefig``) behave. On an exception the
    temporary file is removed and ``path`` is untouched.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    suffix = path.suffix if suffix is None else suffix
    tmp = path.with_name(f".{path.stem}.{os.getpid()}.tmp{suffix}")
    try:
        yield tmp
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()


def swap_into_place(tmp: Path, target: Path) -> None:
    """Replace the folder ``target`` by ``tmp`` (same parent) with renames; never leaves a half folder."""
    old = None
    if target.exists():
        old = target.with_name(f".{target.name}.old-{os.getpid()}-{time.monotonic_ns()}")
        os.replace(target, old)
    os.replace(tmp, target)
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)


def parse_toml(text: str) -> dict:
    """The TOML document ``text`` as a dict (``tomllib``; ``tomli`` on Python 3.10).

    Examples
    --------
    >>> from prodmaps.files import parse_toml
    >>> parse_toml('fig02 = {notebook = "fig02.ipynb", params = {}}')
    {'fig02': {'notebook': 'fig02.ipynb', 'params': {}}}
    """
    try:
        import tomllib  # Python >= 3.11
    except ModuleNotFoundError:  # pragma: no cover - Python 3.10: the `tomli` dependency
        import tomli as tomllib
    return tomllib.loads(text)


def read_json(path, default=None):
    """The JSON document at ``path``, or ``default`` when it is missing or not JSON."""
    try:
        return json.loads(Path(path).read_text())
    except (OSError, ValueError):
        return default
