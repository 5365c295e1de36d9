r"""Derived meshes with different connectivity and a ground-truth map to the original.

For a prepared dataset (``anny_humans``, ``faust``, ``tosca``) and chosen family shapes, writes
``<root>/<dataset>/remeshed/<id>_<recipe>.ply`` and ``<id>_<recipe>.gt_to_family.txt`` (one
0-based family vertex index per variant vertex: the closest vertex of the original shape,
Euclidean), which is the layout ``prodmaps.datasets`` reads. Recipes (targets follow the
shipped anny variants, see ``prodmaps/data/anny_humans/SOURCE.md``):

* ``remesh_iso``: pymeshlab isotropic explicit remeshing, target edge length
  ``--iso-scale`` (default 1.15) x the mean edge length, giving ~0.8 x as many vertices;
* ``remesh_nonuniform``: fine isotropic remesh (0.8 x mean edge), then quadric decimation
  of the faces on one side of the median along ``--axis`` to ``--coarse-ratio`` (default 1/4)
  of their count: one part much coarser (non-uniform sampling);
* ``thin``: 85 % of the faces split 1-to-3 at a point 1-3 % (barycentric) away from one
  corner (NumPy, seeded); surface unchanged, the first n vertices are the original ones;
  about 60 % of the faces then have quality 2r/R < 0.1 (pathological thin triangles).

Usage (from the repository):

    python data_scripts/make_variants.py --dataset faust --shapes tr_reg_000 tr_reg_001 \
        [--recipes remesh_iso remesh_nonuniform thin] [--data-root DIR] [--seed 0] [--force]
"""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path
from unittest import mock

import numpy as np

from .. import datasets as ds
from ..files import atomic_path
from ..io import save_mesh
from ..mesh import face_radius_ratio, mean_edge_length, repair
from .archive import PrepareError, argument_parser, run_cli

RECIPES = ("remesh_iso", "remesh_nonuniform", "thin")


def _meshset(v, f):
    import pymeshlab

    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(vertex_matrix=np.asarray(v, np.float64), face_matrix=np.asarray(f, np.int32)))
    return ms, pymeshlab


def _current(ms):
    m = ms.current_mesh()
    return m.vertex_matrix().astype(np.float64), m.face_matrix().astype(np.int64)


def _iso(v, f, scale, iterations=10):
    ms, pml = _meshset(v, f)
    ms.meshing_isotropic_explicit_remeshing(targetlen=pml.PureValue(scale * mean_edge_length(v, f)),
                                            iterations=iterations)
    return _current(ms)


def remesh_iso(v, f, *, scale=1.15, **_):
    """Recipe ``remesh_iso``: isotropic remeshing at ``scale`` x the mean edge length (module doc)."""
    return _iso(v, f, scale)


def remesh_nonuniform(v, f, *, axis=0, coarse_ratio=0.25, **_):
    """Recipe ``remesh_nonuniform``: a fine remesh, one side of the median decimated (module doc)."""
    v1, f1 = _iso(v, f, 0.8)
    cut = float(np.median(v1[:, axis]))
    c = "xyz"[axis]
    side = np.all(v1[f1][:, :, axis] < cut, axis=1)  # (m,) faces entirely on the coarse side
    ms, _ = _meshset(v1, f1)
    ms.compute_selection_by_condition_per_face(condselect=f"({c}0 < {cut!r}) && ({c}1 < {cut!r}) && ({c}2 < {cut!r})")
    target = max(4, int(side.sum() * coarse_ratio))  # pymeshlab: with selected=True the target counts selected faces
    ms.meshing_decimation_quadric_edge_collapse(targetfacenum=target, selected=True, preservetopology=True,
                                                preservenormal=True, planarquadric=True, qualitythr=0.3,
                                                autoclean=True)
    return _current(ms)


def thin(v, f, *, seed=0, fraction=0.85, **_):
    """Recipe ``thin``: a ``fraction`` of the faces split 1-to-3 near a corner (module doc)."""
    rng = np.random.default_rng(seed)
    m = f.shape[0]
    split = rng.random(m) < fraction  # (m,)
    fs = f[split]
    corner = rng.integers(0, 3, size=fs.shape[0])
    rows = np.arange(fs.shape[0])
    a, b, c = (fs[rows, (corner + s) % 3] for s in range(3))  # a: the near corner
    wb, wc = rng.uniform(0.01, 0.03, size=(2, fs.shape[0]))
    p = (1 - wb - wc)[:, None] * v[a] + wb[:, None] * v[b] + wc[:, None] * v[c]  # (s, 3)
    new = v.shape[0] + rows
    faces = np.concatenate([f[~split],
                            np.stack([a, b, new], 1), np.stack([b, c, new], 1), np.stack([c, a, new], 1)])
    return np.concatenate([v, p]), faces


_FUNCS = {"remesh_iso": remesh_iso, "remesh_nonuniform": remesh_nonuniform, "thin": thin}


def make_variant(mesh, recipe: str, **params):
    """Return ``(variant pm.Mesh, gt_to_family (n_variant,) int64, stats dict)``."""
    from scipy.spatial import cKDTree

    if recipe not in _FUNCS:
        raise PrepareError(f"unknown recipe {recipe!r}; choose from {RECIPES}")
    v, f = _FUNCS[recipe](np.asarray(mesh.vertices), np.asarray(mesh.faces), **params)
    out, _ = repair(v, f, name=f"{mesh.name}_{recipe}")  # drops slivers/debris the remesher may leave
    dist, gt = cKDTree(mesh.vertices).query(out.vertices)
    q = face_radius_ratio(out.vertices, out.faces)
    stats = {"n_vertices": out.n_vertices, "n_faces": out.n_faces,
             "gt_distance_mean": float(dist.mean()), "gt_distance_max": float(dist.max()),
             "thin_fraction_q_lt_0.1": float(np.mean(q < 0.1)),
             "area_ratio": float(out.area / mesh.area)}
    if recipe == "remesh_nonuniform":
        axis = params.get("axis", 0)
        cut = float(np.median(mesh.vertices[:, axis]))
        stats["n_vertices_coarse_side"] = int(np.sum(out.vertices[:, axis] < cut))
        stats["n_vertices_fine_side"] = int(np.sum(out.vertices[:, axis] >= cut))
    return out, np.asarray(gt, dtype=np.int64), stats


def make_variants(dataset: str, shape_ids, recipes=RECIPES, data_root=None, *, seed: int = 0, axis: int = 0,
                  coarse_ratio: float = 0.25, iso_scale: float = 1.15, force: bool = False,
                  verbose: bool = True) -> list[Path]:
    """Write the ``recipes`` variants of ``shape_ids`` and their ground truth; returns the files written."""
    root = Path(data_root) if data_root is not None else ds.data_root()
    with mock.patch.dict(os.environ, PRODMAPS_DATA=str(root)):  # restored afterwards
        folder = ds.dataset_dir(dataset)
        if folder.resolve() != (root / dataset).resolve():  # the embedded copy: variants beside it are never read
            raise PrepareError(f"{dataset!r} is read from {folder} (shipped with the package, with its variants), "
                               f"not from {root / dataset}: variants written there would never be read. Copy "
                               f"{folder} to {root / dataset} first (then PRODMAPS_DATA={root} reads that copy)")
        try:
            ids = ds.shape_ids(dataset)
        except ds.DatasetNotPreparedError as exc:
            raise PrepareError(str(exc)) from None
        for sid in shape_ids:
            if sid not in ids:
                raise PrepareError(f"unknown shape {sid!r} in {dataset!r} (first ids: {ids[:3]})")
        out_dir = root / dataset / "remeshed"
        out_dir.mkdir(parents=True, exist_ok=True)
        written = []
        for sid in shape_ids:
            mesh = ds.load_shape(dataset, sid)
            for r in recipes:
                stem = f"{sid}_{r}"
                ply, gtf = out_dir / f"{stem}.ply", out_dir / f"{stem}.gt_to_family.txt"
                if (ply.exists() or gtf.exists()) and not force:
                    raise PrepareError(f"{ply} exists; pass --force to replace it")
                if verbose:
                    print(f"{dataset}/{sid}: {r} ...", flush=True)
                var, gt, stats = make_variant(mesh, r, seed=seed, axis=axis, coarse_ratio=coarse_ratio,
                                              scale=iso_scale)
                save_mesh(ply, var)  # atomic (temporary name + rename), as the two below
                with atomic_path(gtf) as tmp:
                    np.savetxt(tmp, gt, fmt="%d")
                meta = {"base": sid, "recipe": r, "seed": seed, "axis": axis, "coarse_ratio": coarse_ratio,
                        "iso_scale": iso_scale, **stats}
                with atomic_path(out_dir / f"{stem}.json") as tmp:
                    tmp.write_text(json.dumps(meta, indent=1) + "\n")
                if verbose:
                    print("   " + ", ".join(f"{k}={v:.4g}" if isinstance(v, float) else f"{k}={v}"
                                            for k, v in stats.items()), flush=True)
                written.append(ply)
        ds.clear_cache()
        return written


def main(argv=None) -> None:
    """Command line of the variants (``python -m prodmaps.prepare variants``)."""
    ap = argument_parser(__doc__, "replace existing variant files")
    ap.add_argument("--dataset", required=True, choices=("anny_humans", "faust", "tosca"))
    ap.add_argument("--shapes", nargs="+", required=True, help="family shape ids, e.g. tr_reg_000")
    ap.add_argument("--recipes", nargs="+", default=list(RECIPES), choices=RECIPES)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--axis", type=int, default=0, choices=(0, 1, 2), help="coarse side: coordinate < median")
    ap.add_argument("--coarse-ratio", type=float, default=0.25)
    ap.add_argument("--iso-scale", type=float, default=1.15)
    args = ap.parse_args(argv)
    make_variants(args.dataset, args.shapes, args.recipes, args.data_root, seed=args.seed, axis=args.axis,
                  coarse_ratio=args.coarse_ratio, iso_scale=args.iso_scale, force=args.force)


if __name__ == "__main__":
    sys.exit(run_cli(main))
