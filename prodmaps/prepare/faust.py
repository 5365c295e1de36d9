"""Prepare MPI-FAUST (training registrations) from the user's own download, or from any subset of it.

Get the archive: register at https://faust.is.tue.mpg.de, accept the licence (scientific
research only, no redistribution) and download ``MPI-FAUST.zip``. Then:

    python -m prodmaps.prepare faust --archive MPI-FAUST.zip [--data-root DIR] [--force]

``--archive`` may also be an unpacked folder, and may be given several times: every
``tr_reg_XXX.ply`` or ``tr_reg_XXX.off`` found anywhere below the sources is a registration
(``XXX`` in 000..099). The full set is 100; **any subset is accepted** and prepared as such (the
command says it is a subset, and ``manifest.json`` records ``"subset": true`` and the ids present).
A shape found twice (in two sources, or as ``.ply`` and ``.off``) must be the same mesh. Every shape
must have 6890 vertices and 13776 triangles, all in one shared triangulation (the ground truth is
then the identity). Writes ``<data-root>/faust/shapes/tr_reg_XXX.ply`` (binary PLY) plus
``manifest.json`` and ``SHA256SUMS``. The data root defaults to ``$PRODMAPS_DATA``, else
``~/.local/share/prodmaps``. Nothing is written unless every shape passes the checks.

Eight registrations are public in two GitHub repositories (FAUST's licence still applies to
them: use them in place, never redistribute them). Clone ``erodola/FundCG-s1-2018`` and
``IvanDzanija/Laplacian-Mesh``, then::

    python -m prodmaps.prepare faust --archive FundCG-s1-2018 --archive Laplacian-Mesh

prepares ``tr_reg_000``, ``001``, ``002``, ``003`` (subject 0), ``010``, ``025``, ``031`` and
``095`` (subjects 1, 2, 3 and 9).
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

import numpy as np

from .. import datasets
from ..errors import MeshError
from .archive import (
    Archive,
    PrepareError,
    argument_parser,
    parse_mesh_bytes,
    run_cli,
    sha256_file,
    staged_folder,
    write_manifest_and_sums,
    write_shape,
)

N_SHAPES = 100
N_VERTICES = 6890
N_FACES = 13776
SAME_VERTICES_ATOL = 1e-5  # two copies of a shape (OFF text vs PLY float32) agree to this, in metres
_MEMBER = re.compile(r"(?:^|/)tr_reg_(\d{3})\.(ply|off)$", re.IGNORECASE)


def prepare_faust(archive, data_root=None, *, force: bool = False, n_shapes: int = N_SHAPES,
                  n_vertices: int = N_VERTICES, n_faces: int = N_FACES, verbose: bool = True) -> Path:
    """Read, verify and write the FAUST registrations; returns the dataset folder.

    Parameters
    ----------
    archive : path or sequence of paths
        ``MPI-FAUST.zip``, an unpacked folder, or several of either; every ``tr_reg_XXX.ply``/``.off``
        below them is read. Any subset of the ``n_shapes`` registrations is accepted.
    data_root : path, optional
        Where ``faust/`` is written (default ``$PRODMAPS_DATA``, else ``~/.local/share/prodmaps``).
    force : bool
        Replace an existing ``faust/`` folder.
    n_shapes, n_vertices, n_faces : int
        The expected id range and counts (the real dataset's by default; tests pass smaller ones).

    Returns
    -------
    Path
        ``<data_root>/faust``.

    Raises
    ------
    PrepareError
        No registration found, an id outside ``0..n_shapes-1``, two different copies of one shape,
        wrong counts, a triangulation that differs, a damaged archive or member (nothing is written).
    """
    say = print if verbose else (lambda *a, **k: None)
    sources = [Path(archive)] if isinstance(archive, (str, Path)) else [Path(a) for a in archive]
    if not sources:
        raise PrepareError("no source given: pass --archive (a zip or a folder), once or several times")
    root = Path(data_root) if data_root is not None else datasets.data_root()
    target = root / "faust"
    if target.exists() and not force:
        raise PrepareError(f"{target} already exists; pass --force to replace it")
    arcs = [Archive(src) for src in sources]
    try:
        found: dict[int, list[tuple[Archive, str]]] = {}
        for arc in arcs:
            for name in arc.names:
                m = _MEMBER.search(name)
                if m:
                    found.setdefault(int(m.group(1)), []).append((arc, name))
        where = " + ".join(str(s) for s in sources)
        if not found:
            raise PrepareError(f"{where}: no tr_reg_XXX.ply or .off found (MPI-FAUST keeps them in "
                               "training/registrations/); is this MPI-FAUST.zip or a folder holding some of them?")
        extra = sorted(set(found) - set(range(n_shapes)))
        if extra:
            raise PrepareError(f"{where}: registrations are tr_reg_000..tr_reg_{n_shapes - 1:03d}; "
                               f"unexpected {[f'{i:03d}' for i in extra][:10]}")
        subset = len(found) < n_shapes
        ids = sorted(found)
        if subset:
            say(f"found {len(found)} of the {n_shapes} registrations in {where}: a subset "
                f"({', '.join(f'{i:03d}' for i in ids)}); pairs and tables use these only")
        else:
            say(f"found all {len(found)} registrations in {where}")
        faces0, first = None, None
        manifest_shapes = []
        with staged_folder(target, force=force) as tmp:
            (tmp / "shapes").mkdir()
            for k, i in enumerate(ids):
                sid = f"tr_reg_{i:03d}"
                copies = []
                for arc, member in found[i]:
                    label = f"{arc.path.name}/{member}"
                    try:
                        v, f = parse_mesh_bytes(arc.read(member), Path(member).suffix.lower(), tmp)
                    except MeshError as exc:
                        raise PrepareError(f"{label}: {exc}") from None
                    copies.append((label, v, f))
                label, v, f = copies[0]
                for other, v2, f2 in copies[1:]:
                    if v2.shape != v.shape or not np.array_equal(f2, f) or np.abs(v2 - v).max() > SAME_VERTICES_ATOL:
                        raise PrepareError(f"{label} and {other}: two different meshes named {sid}; keep one")
                if v.shape[0] != n_vertices or f.shape[0] != n_faces:
                    raise PrepareError(f"{label}: {v.shape[0]} vertices and {f.shape[0]} faces; "
                                       f"FAUST registrations have {n_vertices} and {n_faces}")
                if faces0 is None:
                    faces0, first = f, label
                elif not np.array_equal(f, faces0):
                    raise PrepareError(f"{label}: triangulation differs from {first}; "
                                       "FAUST registrations share one triangulation")
                manifest_shapes.append(write_shape(tmp, sid, v, f, label, str(i // 10), "0"))
                if verbose and ((k + 1) % 10 == 0 or k + 1 == len(ids)):
                    say(f"  verified and converted {k + 1}/{len(ids)}")
            write_manifest_and_sums(tmp, {
                "dataset": "faust", "format_version": 1, "prepared_by": "python -m prodmaps.prepare faust",
                "source": [{"archive": src.name, "sha256": sha256_file(src) if src.is_file() else None}
                           for src in sources],
                "subset": subset, "n_shapes_full": n_shapes, "n_vertices": n_vertices, "n_faces": n_faces,
                "ground_truth": "identity within the dataset (one triangulation); class = subject = XXX // 10",
                "shapes": manifest_shapes})
    finally:
        for arc in arcs:
            arc.close()
    say(f"wrote {len(manifest_shapes)} shapes to {target}" + (" (a subset of FAUST)" if subset else ""))
    return target


def main(argv=None) -> None:
    """Command line of the FAUST preparation (``python -m prodmaps.prepare faust``)."""
    ap = argument_parser(__doc__, "replace an existing prepared faust/ folder")
    ap.add_argument("--archive", required=True, action="append",
                    help="MPI-FAUST.zip, an unpacked folder, or a folder holding some tr_reg_XXX.ply/.off; "
                         "repeat for several sources")
    args = ap.parse_args(argv)
    prepare_faust(args.archive, args.data_root, force=args.force)


if __name__ == "__main__":
    sys.exit(run_cli(main))
