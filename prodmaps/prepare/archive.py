"""Safe archive reading and atomic output for the dataset preparation (FAUST, TOSCA, variants).

Safety rules implemented here:

* archive members are only *read* into memory and parsed as numbers; nothing from the
  archive is executed, imported, unpickled or extracted under its own name;
* an archive with any member name that would land outside a target folder (absolute
  path, ``..`` component, drive letter, backslash path, NUL byte) or with a symbolic-link
  member is refused as a whole (zip-slip protection);
* members larger than ``MAX_MEMBER_BYTES`` are refused (zip-bomb protection);
* the output folder is assembled in a temporary sibling folder and renamed into place only
  when everything has been read and verified, so a crash or a refusal leaves no
  half-prepared dataset.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import posixpath
import shutil
import stat
import sys
import tempfile
import zipfile
from pathlib import Path, PurePosixPath

from ..errors import MeshError
from ..files import sha256_file, swap_into_place
from ..io import read_mesh_arrays, save_mesh
from ..mesh import Mesh

MAX_MEMBER_BYTES = 1 << 30  # 1 GiB per member


class PrepareError(Exception):
    """A refusal with a message meant for the user (printed by the scripts, exit code 2)."""


def check_member_name(name: str, target: Path = Path("/nonexistent/target")) -> None:
    """Raise :class:`PrepareError` if ``name`` would land outside ``target`` when extracted."""
    if "\x00" in name or "\\" in name:
        raise PrepareError(f"refusing archive: member {name!r} has a NUL byte or a backslash path")
    p = PurePosixPath(name)
    if p.is_absolute() or (p.parts and p.parts[0].endswith(":")) or ".." in p.parts:
        raise PrepareError(
            f"refusing archive: member {name!r} would be written outside the target folder "
            "(absolute path or '..'); the archive is malformed or malicious"
        )
    joined = posixpath.normpath(posixpath.join(str(target), name))
    if not (joined == str(target) or joined.startswith(str(target) + "/")):
        raise PrepareError(f"refusing archive: member {name!r} escapes the target folder")


class Archive(contextlib.AbstractContextManager):
    """Read-only view of a ``.zip`` archive or of an already unpacked folder."""

    def __init__(self, path):
        self.path = Path(path)
        if not self.path.exists():
            raise PrepareError(f"{self.path}: no such file or folder")
        self._zip = None
        if self.path.is_dir():
            base, self.names = self.path.resolve(), []
            for p in sorted(self.path.rglob("*")):
                if p.is_symlink() and base not in p.resolve().parents:
                    raise PrepareError(f"refusing folder: {p} is a symbolic link pointing outside {base}")
                if p.is_file():
                    self.names.append(p.relative_to(self.path).as_posix())
        else:
            try:
                self._zip = zipfile.ZipFile(self.path)
            except (zipfile.BadZipFile, OSError) as exc:
                raise PrepareError(
                    f"{self.path}: not a readable zip archive ({exc}); the download may be "
                    "incomplete or truncated: download it again"
                ) from None
            infos = self._zip.infolist()
            for info in infos:
                check_member_name(info.filename)
                if stat.S_ISLNK(info.external_attr >> 16):
                    raise PrepareError(f"refusing archive: member {info.filename!r} is a symbolic link")
                if info.file_size > MAX_MEMBER_BYTES:
                    raise PrepareError(f"refusing archive: member {info.filename!r} is "
                                       f"{info.file_size} bytes (> {MAX_MEMBER_BYTES})")
            self.names = [i.filename for i in infos if not i.is_dir()]

    def read(self, name: str) -> bytes:
        """Bytes of one member; damaged members raise :class:`PrepareError`."""
        if self._zip is None:
            p = self.path / name
            if p.stat().st_size > MAX_MEMBER_BYTES:
                raise PrepareError(f"{p}: larger than {MAX_MEMBER_BYTES} bytes")
            return p.read_bytes()
        try:
            return self._zip.read(name)
        except (zipfile.BadZipFile, EOFError, OSError, ValueError) as exc:
            raise PrepareError(
                f"{self.path}: member {name!r} is damaged or truncated ({exc}); download the archive again"
            ) from None

    def close(self):
        """Close the archive (nothing to do for a folder)."""
        if self._zip is not None:
            self._zip.close()

    def __exit__(self, *exc):
        self.close()


@contextlib.contextmanager
def staged_folder(target: Path, *, force: bool = False):
    """Yield a temporary sibling folder of ``target``; on success rename it to ``target``.

    On any exception the temporary folder is removed and ``target`` is left untouched. An
    existing ``target`` is only replaced with ``force=True`` (the old folder is renamed aside
    first and deleted after the new one is in place).
    """
    target = Path(target)
    if target.exists() and not force:
        raise PrepareError(f"{target} already exists; pass --force to replace it")
    target.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{target.name}.partial-", dir=target.parent))
    try:
        yield tmp
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    swap_into_place(tmp, target)


def write_manifest_and_sums(folder: Path, manifest: dict) -> None:
    """Write ``manifest.json`` and a ``SHA256SUMS`` (sha256sum format) of every file."""
    (folder / "manifest.json").write_text(json.dumps(manifest, indent=1) + "\n")
    lines = [f"{sha256_file(p)}  ./{p.relative_to(folder).as_posix()}" for p in sorted(folder.rglob("*"))
             if p.is_file() and p.name != "SHA256SUMS"]
    (folder / "SHA256SUMS").write_text("\n".join(lines) + "\n")


def write_shape(folder: Path, sid: str, vertices, faces, label: str, cls: str, triangulation: str) -> dict:
    """Validate one shape, write it as ``<folder>/shapes/<sid>.ply`` and return its manifest entry."""
    try:
        mesh = Mesh(vertices, faces, name=sid)
    except MeshError as exc:
        raise PrepareError(f"{label}: invalid mesh: {exc}") from None
    save_mesh(folder / "shapes" / f"{sid}.ply", mesh)
    return {"id": sid, "file": f"shapes/{sid}.ply", "class": cls, "triangulation": triangulation,
            "n_vertices": mesh.n_vertices, "n_faces": mesh.n_faces}


def parse_mesh_bytes(data: bytes, suffix: str, scratch: Path):
    """Parse mesh bytes with the package's strict reader (no validation); returns (V, F)."""
    tmp = scratch / f"_member{suffix}"
    tmp.write_bytes(data)
    try:
        return read_mesh_arrays(tmp)
    finally:
        tmp.unlink()


def argument_parser(doc: str, force_help: str) -> argparse.ArgumentParser:
    """The prepare scripts' parser: the first paragraph of ``doc``, ``--data-root`` and ``--force``."""
    ap = argparse.ArgumentParser(description=doc.split("\n\n")[0])
    ap.add_argument("--data-root", default=None, help="default: $PRODMAPS_DATA, else ~/.local/share/prodmaps")
    ap.add_argument("--force", action="store_true", help=force_help)
    return ap


def run_cli(main_fn, argv=None) -> int:
    """Call ``main_fn(argv)``; print refusals as one clear line and return exit code 2."""
    try:
        main_fn(argv)
    except PrepareError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    return 0
