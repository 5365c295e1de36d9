"""Prepare MPI-FAUST (training registrations) from the user's own download.

Get the archive: register at https://faust.is.tue.mpg.de, accept the licence (scientific
research only, no redistribution) and download ``MPI-FAUST.zip``. Then, from the repository:

    python data_scripts/prepare_faust.py --archive MPI-FAUST.zip [--data-root DIR] [--force]

``--archive`` may also be the already unpacked ``MPI-FAUST`` folder. Reads
``training/registrations/tr_reg_000.ply .. tr_reg_099.ply`` (anywhere below the archive
root), checks that there are exactly 100, each with 6890 vertices and 13776 triangles, all in
one shared triangulation, and writes ``<data-root>/faust/shapes/tr_reg_XXX.ply`` (binary PLY)
plus ``manifest.json`` and ``SHA256SUMS``. The data root defaults to ``$PRODMAPS_DATA``, else
``~/.local/share/prodmaps``. Nothing is written unless every shape passes the checks.
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

import numpy as np

from .archive import (
    Archive,
    PrepareError,
    argument_parser,
    default_data_root,
    parse_mesh_bytes,
    run_cli,
    sha256_file,
    staged_folder,
    write_manifest_and_sums,
)

N_SHAPES = 100
N_VERTICES = 6890
N_FACES = 13776
_MEMBER = re.compile(r"(?:^|/)training/registrations/tr_reg_(\d{3})\.ply$")


def prepare_faust(archive, data_root=None, *, force: bool = False, n_shapes: int = N_SHAPES,
                  n_vertices: int = N_VERTICES, n_faces: int = N_FACES, verbose: bool = True) -> Path:
    """Read, verify and write the FAUST registrations; returns the dataset folder.

    ``n_shapes``, ``n_vertices`` and ``n_faces`` are the expected counts (the real dataset's
    values by default; tests may pass smaller ones). Raises :class:`PrepareError`.
    """
    import prodmaps as pm

    say = print if verbose else (lambda *a, **k: None)
    root = Path(data_root) if data_root is not None else default_data_root()
    target = root / "faust"
    if target.exists() and not force:
        raise PrepareError(f"{target} already exists; pass --force to replace it")
    with Archive(archive) as arc:
        found: dict[int, str] = {}
        for name in arc.names:
            m = _MEMBER.search(name)
            if m:
                i = int(m.group(1))
                if i in found:
                    raise PrepareError(f"archive has two copies of tr_reg_{i:03d}.ply: {found[i]!r} and {name!r}")
                found[i] = name
        expected = set(range(n_shapes))
        if not found:
            raise PrepareError(f"{archive}: no training/registrations/tr_reg_XXX.ply found; is this MPI-FAUST.zip?")
        missing = sorted(expected - set(found))
        extra = sorted(set(found) - expected)
        if missing or extra:
            raise PrepareError(f"{archive}: expected tr_reg_000..tr_reg_{n_shapes - 1:03d}; "
                               f"missing {[f'{i:03d}' for i in missing][:10]}, unexpected {extra[:10]}")
        say(f"found {len(found)} registrations in {archive}")
        faces0 = None
        manifest_shapes = []
        with staged_folder(target, force=force) as tmp:
            (tmp / "shapes").mkdir()
            for k, i in enumerate(sorted(found)):
                member = found[i]
                sid = f"tr_reg_{i:03d}"
                try:
                    v, f = parse_mesh_bytes(arc.read(member), ".ply", tmp)
                except pm.MeshError as exc:
                    raise PrepareError(f"{member}: {exc}") from None
                if v.shape[0] != n_vertices or f.shape[0] != n_faces:
                    raise PrepareError(f"{member}: {v.shape[0]} vertices and {f.shape[0]} faces; "
                                       f"FAUST registrations have {n_vertices} and {n_faces}")
                if faces0 is None:
                    faces0 = f
                elif not np.array_equal(f, faces0):
                    raise PrepareError(f"{member}: triangulation differs from {found[min(found)]}; "
                                       "FAUST registrations share one triangulation")
                try:
                    mesh = pm.Mesh(v, f, name=sid)
                except pm.MeshError as exc:
                    raise PrepareError(f"{member}: invalid mesh: {exc}") from None
                pm.save_mesh(tmp / "shapes" / f"{sid}.ply", mesh)
                manifest_shapes.append({"id": sid, "file": f"shapes/{sid}.ply", "class": str(i // 10),
                                        "triangulation": "0", "n_vertices": int(v.shape[0]),
                                        "n_faces": int(f.shape[0])})
                if verbose and ((k + 1) % 10 == 0 or k + 1 == len(found)):
                    say(f"  verified and converted {k + 1}/{len(found)}")
            src = Path(archive)
            manifest = {
                "dataset": "faust",
                "format_version": 1,
                "prepared_by": "python -m prodmaps.prepare faust",
                "source": {"archive": src.name,
                           "sha256": sha256_file(src) if src.is_file() else None},
                "n_vertices": n_vertices,
                "n_faces": n_faces,
                "ground_truth": "identity within the dataset (one triangulation); class = subject = XXX // 10",
                "shapes": manifest_shapes,
            }
            write_manifest_and_sums(tmp, manifest)
    say(f"wrote {len(manifest_shapes)} shapes to {target}")
    return target


def main(argv=None) -> None:
    ap = argument_parser(__doc__, "replace an existing prepared faust/ folder")
    ap.add_argument("--archive", required=True, help="MPI-FAUST.zip (or the unpacked MPI-FAUST folder)")
    args = ap.parse_args(argv)
    prepare_faust(args.archive, args.data_root, force=args.force)


if __name__ == "__main__":
    sys.exit(run_cli(main))
