"""File helpers shared by the whole package: SHA-256 digests, atomic writes, TOML, JSON, checked archives.

One implementation each: dataset checksums (:func:`prodmaps.datasets.verify_checksums`), the
preparation scripts, the pipeline's run hashes and every writer of results or caches use them;
the claims ledger and the run registry read their TOML with :func:`parse_toml`; saved bases and
maps (:meth:`prodmaps.Basis.save`, :func:`prodmaps.save_map`) are checked archives
(:func:`write_checked_npz`, :func:`read_checked_npz`): an ``.npz`` of arrays plus a JSON metadata
record holding the file's format, the library version and a SHA-256 checksum of the arrays.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import shutil
import time
from pathlib import Path

__all__ = ["sha256_file", "sha256_bytes", "atomic_path", "swap_into_place", "parse_toml", "read_json",
           "arrays_checksum", "write_checked_npz", "read_checked_npz", "library_version", "ARCHIVE_VERSION"]

ARCHIVE_VERSION = 1
"""Version of the checked-archive layout (:func:`write_checked_npz`); files of a newer version are refused."""
_META = "__metadata__"

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


def library_version() -> str:
    """The version of the prodmaps package this module belongs to (``prodmaps.__version__``).

    Read from the package object, which is always imported before its modules (an import here
    would close a cycle: the package imports this module).
    """
    import sys

    return str(getattr(sys.modules.get(__package__ or "prodmaps"), "__version__", "unknown"))


def arrays_checksum(arrays: dict) -> str:
    """SHA-256 (hex) of named arrays: for each name in sorted order its name, dtype, shape and C-order bytes.

    Examples
    --------
    >>> import numpy as np
    >>> a = arrays_checksum({"x": np.arange(3.0)})
    >>> a == arrays_checksum({"x": np.arange(3.0)}), a == arrays_checksum({"x": np.arange(3.0) + [0, 0, 1e-9]})
    (True, False)
    """
    import numpy as np

    h = hashlib.sha256()
    for name in sorted(arrays):
        arr = np.ascontiguousarray(arrays[name])
        h.update(f"{name}|{arr.dtype.str}|{arr.shape}|".encode())
        h.update(arr.tobytes())
    return h.hexdigest()


def write_checked_npz(path, fmt: str, arrays: dict, metadata: dict) -> Path:
    """Write ``arrays`` and ``metadata`` to ``path`` (an ``.npz``, exactly that name), atomically.

    The metadata record gains ``format`` (``fmt``, e.g. ``"prodmaps.basis"``), ``archive_version``,
    ``prodmaps_version`` and ``checksum`` (:func:`arrays_checksum`). Arrays are stored as given,
    memory order included (no compression: loads are bit-exact and fast, and a loaded array
    meets the same BLAS kernels as the saved one). Returns the path.
    """
    import numpy as np

    path = Path(path)
    if path.is_dir():
        raise ValueError(f"{path}: is a folder; give a file name (e.g. ending in .npz)")
    meta = dict(metadata, format=fmt, archive_version=ARCHIVE_VERSION, prodmaps_version=library_version(),
                checksum=arrays_checksum(arrays))
    payload = {name: np.asarray(a) for name, a in arrays.items()}  # memory order kept (C or Fortran)
    payload[_META] = np.array(json.dumps(meta, sort_keys=True))
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as fh:  # a file object: numpy would append .npz to a name without it
            np.savez(fh, **payload)
    return path


def read_checked_npz(path, fmt: str, hint: dict | None = None) -> tuple[dict, dict]:
    """``(arrays, metadata)`` of a file written by :func:`write_checked_npz` as ``fmt``, checked.

    Raises ``ValueError`` naming the path and the problem: not such an archive (another kind of
    file), another format (``hint`` maps format names to the function that reads them), a newer
    archive version, missing arrays, or a checksum that does not match the arrays (a changed or
    damaged file). ``FileNotFoundError`` for a missing file.
    """
    import zipfile

    import numpy as np

    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such file")
    try:
        z = np.load(path, allow_pickle=False)
        if not isinstance(z, np.lib.npyio.NpzFile):
            raise ValueError("a single .npy array, not a prodmaps archive")
        with z:
            arrays = {name: z[name] for name in z.files}
    except (OSError, ValueError, zipfile.BadZipFile, EOFError) as exc:
        raise ValueError(f"{path}: not a prodmaps {fmt} file (cannot be read as an .npz archive: {exc})") from None
    raw = arrays.pop(_META, None)
    try:
        meta = json.loads(str(raw)) if raw is not None else None
    except ValueError:
        meta = None
    if not isinstance(meta, dict) or "format" not in meta:
        raise ValueError(f"{path}: not a prodmaps {fmt} file (an .npz without prodmaps metadata)")
    if meta["format"] != fmt:
        use = (hint or {}).get(meta["format"])
        raise ValueError(f"{path}: a {meta['format']} file, not a {fmt} file"
                         + (f"; read it with {use}" if use else ""))
    if int(meta.get("archive_version", 0)) > ARCHIVE_VERSION:
        raise ValueError(f"{path}: written by a newer prodmaps ({meta.get('prodmaps_version')}, archive version "
                         f"{meta.get('archive_version')}); upgrade prodmaps to read it")
    if arrays_checksum(arrays) != meta.get("checksum"):
        raise ValueError(f"{path}: checksum mismatch: the arrays were changed or damaged after the file was saved")
    return arrays, meta
