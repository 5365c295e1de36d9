"""Prepare TOSCA high-resolution from the user's own download.

Get the archive: ``toscahires-asci.zip`` from the TOSCA page
(http://tosca.cs.technion.ac.il/book/resources_data.html; when the site is down an archived
copy exists on web.archive.org). It is not redistributable, so the project does not ship it.
Then (from an install or a checkout; ``python data_scripts/prepare_tosca.py`` in a checkout is the same):

    python -m prodmaps.prepare tosca --archive toscahires-asci.zip [--data-root DIR] [--force]

``--archive`` may also be the unpacked folder. Reads the flat ``<class><i>.vert`` (one
``x y z`` per line) / ``<class><i>.tri`` (one 1-based triangle per line) pairs of the classes
cat, centaur, david, dog, gorilla, horse, michael, victoria, wolf; checks every file (row
widths, finite numbers, 1-based indices in range), that all members of a class share one
triangulation and one vertex count, the known vertex counts (wolf: 4344), and that each
shape is a valid mesh; writes ``<data-root>/tosca/shapes/<class><i>.ply`` (0-based, binary
PLY), ``manifest.json`` and ``SHA256SUMS``. Nothing is written unless everything passes.

If a class's shared triangulation has defects that the package refuses (duplicate faces,
several components, unreferenced vertices) the script stops and names them; with
``--repair`` it repairs the first member of the class with ``prodmaps.mesh.repair`` and
applies the same vertex subset and faces to every member (so identity ground truth still
holds inside the class), recording the kept original vertex indices in
``shapes/<class>.kept_vertices.txt``.
"""

from __future__ import annotations

import re
import sys
from collections import defaultdict
from pathlib import Path

import numpy as np

from .. import datasets
from ..errors import MeshError
from ..mesh import Mesh
from ..mesh import repair as repair_mesh
from .archive import (
    Archive,
    PrepareError,
    argument_parser,
    run_cli,
    sha256_file,
    staged_folder,
    write_manifest_and_sums,
    write_shape,
)

CLASSES = ("cat", "centaur", "david", "dog", "gorilla", "horse", "michael", "victoria", "wolf")
EXPECTED_VERTICES = {"wolf": 4344}  # confirmed counts only; other classes are checked for consistency
_MEMBER = re.compile(r"(?:^|/)([a-z]+)(\d+)\.(vert|tri)$")


def _parse_table(data: bytes, member: str, width: int, dtype) -> np.ndarray:
    try:
        text = data.decode("ascii")
    except UnicodeDecodeError:
        raise PrepareError(f"{member}: not an ASCII text file") from None
    rows = [ln.split() for ln in text.splitlines() if ln.strip()]
    if not rows:
        raise PrepareError(f"{member}: empty file")
    bad = [k for k, r in enumerate(rows) if len(r) != width]
    if bad:
        raise PrepareError(f"{member}: line {bad[0] + 1} has {len(rows[bad[0]])} numbers, expected {width} "
                           "(truncated or malformed file)")
    try:
        arr = np.array(rows, dtype=np.float64)
    except ValueError as exc:
        raise PrepareError(f"{member}: non-numeric entry ({exc})") from None
    if not np.all(np.isfinite(arr)):
        raise PrepareError(f"{member}: non-finite numbers")
    if dtype is np.int64:
        if not np.all(arr == np.round(arr)):
            raise PrepareError(f"{member}: triangle indices must be integers")
        return arr.astype(np.int64)
    return arr


def prepare_tosca(archive, data_root=None, *, force: bool = False, repair: bool = False,
                  expected_vertices: dict | None = None, classes=CLASSES, verbose: bool = True) -> Path:
    """Read, verify and write TOSCA; returns the dataset folder. Raises :class:`PrepareError`."""
    say = print if verbose else (lambda *a, **k: None)
    expected_vertices = EXPECTED_VERTICES if expected_vertices is None else expected_vertices
    root = Path(data_root) if data_root is not None else datasets.data_root()
    target = root / "tosca"
    if target.exists() and not force:
        raise PrepareError(f"{target} already exists; pass --force to replace it")
    with Archive(archive) as arc:
        members: dict[tuple[str, int], dict[str, str]] = defaultdict(dict)
        ignored = set()
        for name in arc.names:
            m = _MEMBER.search(name)
            if not m:
                continue
            cls, i, ext = m.group(1), int(m.group(2)), m.group(3)
            if cls not in classes:
                ignored.add(cls)
                continue
            if ext in members[(cls, i)]:
                raise PrepareError(f"archive has two copies of {cls}{i}.{ext}: "
                                   f"{members[(cls, i)][ext]!r} and {name!r}")
            members[(cls, i)][ext] = name
        if ignored:
            say(f"ignoring files of classes not in the protocol: {sorted(ignored)}")
        incomplete = [f"{c}{i}" for (c, i), d in members.items() if len(d) != 2]
        if incomplete:
            raise PrepareError(f"{archive}: shapes with a .vert but no .tri or the reverse: {sorted(incomplete)[:10]}")
        by_class = defaultdict(list)
        for c, i in sorted(members):
            by_class[c].append(i)
        absent = [c for c in classes if c not in by_class]
        if absent:
            raise PrepareError(f"{archive}: no shapes of classes {absent}; is this toscahires-asci.zip?")
        say(f"found {len(members)} shapes in {len(by_class)} classes: "
            + ", ".join(f"{c} {len(by_class[c])}" for c in classes))
        manifest_shapes, class_info = [], {}
        with staged_folder(target, force=force) as tmp:
            (tmp / "shapes").mkdir()
            for c in classes:
                faces0 = kept = faces_out = nv0 = None
                for i in by_class[c]:
                    sid = f"{c}{i}"
                    vname, tname = members[(c, i)]["vert"], members[(c, i)]["tri"]
                    v = _parse_table(arc.read(vname), vname, 3, np.float64)
                    t = _parse_table(arc.read(tname), tname, 3, np.int64)
                    if t.min() < 1:
                        raise PrepareError(f"{tname}: index {int(t.min())} found; TOSCA triangles are 1-based")
                    if t.max() > v.shape[0]:
                        raise PrepareError(f"{tname}: index {int(t.max())} but {vname} has only {v.shape[0]} "
                                           "vertices (truncated or mismatched .vert)")
                    f = t - 1
                    if c in expected_vertices and v.shape[0] != expected_vertices[c]:
                        raise PrepareError(f"{vname}: {v.shape[0]} vertices; TOSCA {c} shapes have "
                                           f"{expected_vertices[c]}")
                    if faces0 is None:
                        faces0, nv0 = f, v.shape[0]
                        try:
                            Mesh(v, f)
                            kept, faces_out = np.arange(nv0), f
                        except MeshError as exc:
                            if not repair:
                                raise PrepareError(f"{sid}: invalid mesh: {exc}. Re-run with --repair to apply "
                                                   "the same topological repair to the whole class") from None
                            fixed, kept = repair_mesh(v, f)
                            faces_out = np.asarray(fixed.faces)
                            say(f"  {c}: repaired shared triangulation ({exc}); kept {kept.size} of {nv0} vertices")
                    elif v.shape[0] != nv0 or not np.array_equal(f, faces0):
                        raise PrepareError(f"{sid}: {v.shape[0]} vertices / {f.shape[0]} faces, triangulation "
                                           f"differs from {c}{by_class[c][0]} ({nv0} vertices); members of a "
                                           "TOSCA class share one triangulation")
                    manifest_shapes.append(write_shape(tmp, sid, v[kept], faces_out, sid, c, c))
                if kept.size != nv0:
                    np.savetxt(tmp / "shapes" / f"{c}.kept_vertices.txt", kept, fmt="%d")
                class_info[c] = {"n_shapes": len(by_class[c]), "n_vertices": int(kept.size),
                                 "n_faces": int(faces_out.shape[0]), "original_n_vertices": int(nv0),
                                 "repaired": bool(kept.size != nv0 or faces_out.shape[0] != faces0.shape[0])}
                say(f"  verified and converted {c}: {len(by_class[c])} shapes, {kept.size} vertices")
            src = Path(archive)
            write_manifest_and_sums(tmp, {
                "dataset": "tosca", "format_version": 1, "prepared_by": "python -m prodmaps.prepare tosca",
                "source": {"archive": src.name, "sha256": sha256_file(src) if src.is_file() else None},
                "ground_truth": "identity within a class (shared triangulation); none across classes",
                "classes": class_info, "shapes": manifest_shapes})
    say(f"wrote {len(manifest_shapes)} shapes to {target}")
    return target


def main(argv=None) -> None:
    """Command line of the TOSCA preparation (``python -m prodmaps.prepare tosca``)."""
    ap = argument_parser(__doc__, "replace an existing prepared tosca/ folder")
    ap.add_argument("--archive", required=True, help="toscahires-asci.zip (or the unpacked folder)")
    ap.add_argument("--repair", action="store_true",
                    help="repair a class's shared triangulation once and apply it to all members")
    args = ap.parse_args(argv)
    prepare_tosca(args.archive, args.data_root, force=args.force, repair=args.repair)


if __name__ == "__main__":
    sys.exit(run_cli(main))
