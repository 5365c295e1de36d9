"""Study: transfers and point maps between discretizations of one surface (meshes, remeshes, clouds).

From a shape of a dataset (the *original* mesh) the study derives, in memory, other
discretizations of the same surface in the same pose (:data:`DISCRETIZATIONS`): ``mesh`` (the
original), ``iso`` and ``nonuniform`` (:func:`remesh`: the recipes of :mod:`prodmaps.prepare.variants`,
pymeshlab), ``cloud`` and ``cloud2`` (:func:`sample_surface`, two seeded samplings uniform by area)
and ``mc`` (:func:`marching_cubes_mesh`: libigl's marching cubes of the signed distance).

Ground truth (:func:`surface_ground_truth`): each target point's closest point on the *source
surface*, read as its nearest source vertex (or cloud point). The source surface is a mesh source's
own triangles; a cloud's is the original mesh it was sampled from. When the target is the source
itself the map is the identity (tested).

Functions on a discretization ``D``: its own coordinates ``X``, ``Y``, ``Z``; ``Indicator`` and
``hk`` columns (the families ``Indicator`` and ``hk_K`` of
:mod:`prodmaps.experiments.shared.families`, made on the original mesh with ``kernel_eig``
eigenpairs) read on ``D`` through the ground truth from ``D`` to the original.

For each pair ``s -> t`` and each ``k`` of ``ks`` (the paper's count of **non-constant**
functions: bases of ``k + 1`` columns), ``C_12 = Φ_tᵀ A_t Φ_s[p2p_ts]`` ``(k + 1, k + 1)``; the
transfers :data:`METHODS` go through the registry (``pm.transfer_operator``; ``svd`` with
``rtol = PAPER_RTOL`` and ordered pairs is the paper's Approach B, ``svd_gain`` the same with the
threshold the gain rule picks from the map). Error: the relative error
(:func:`prodmaps.relative_error`) against the pull-back ``f_s[p2p_ts]`` on the target. Point maps
(:func:`prodmaps.p2p.from_fmap`, ``std`` and ``extended``, the kernel from all ``kernel_eig``
eigenpairs) on ``n_eval`` seeded target points: heat-method geodesic distance on the source
between the recovered and the true image, over ``sqrt(source area)``.
Meshes get the cotangent Laplacian, clouds the point-cloud Laplacian (``pm.eigenbasis``).

The finding (:func:`summary`, :func:`finding_text`) is computed from the numbers: which pairs the
products help (XYZ), which cells Approach B and the default make worse than the standard transfer
by more than :data:`MARGIN` (relative), grouped by the kind of source; the gain rule beside them.
"""

from __future__ import annotations

import time

import numpy as np
from scipy.spatial import cKDTree

from .. import datasets, geodesics
from ..approx import PAPER_RTOL
from ..basis import eigenbasis
from ..mesh import Mesh, face_areas, face_normals, face_radius_ratio, repair
from ..metrics import relative_error
from ..p2p import fmap_from_p2p, from_fmap
from ..pointcloud import PointCloud
from ..prepare.variants import remesh_iso, remesh_nonuniform
from ..transfers import transfer_operator
from .shared import compare
from .shared.anatomy import body_frame
from .shared.families import make_family
from .shared.results import setup_matplotlib

__all__ = ["DISCRETIZATIONS", "PAIRS", "METHODS", "COMPARED", "NAMES", "SHORT", "CONVERSIONS", "FUNCTIONS", "MARGIN",
           "CLEAN", "MC_SPACING", "GROUPS", "spread_shapes", "sample_surface", "remesh", "marching_cubes_mesh",
           "discretizations", "surface_ground_truth", "ground_truth", "discretization_study", "find_cell",
           "pair_group", "summary", "finding_items", "finding_text", "figure", "front_axes", "report_blocks"]

DISCRETIZATIONS = ("mesh", "iso", "nonuniform", "cloud", "cloud2", "mc")
"""The derived discretizations (module doc); ``cloud2`` is a second sampling of the same surface."""
PAIRS = (("mesh", "iso"), ("iso", "mesh"), ("mesh", "nonuniform"), ("nonuniform", "mesh"), ("iso", "nonuniform"),
         ("mesh", "cloud"), ("cloud", "mesh"), ("cloud", "cloud2"), ("mesh", "mc"), ("mc", "mesh"), ("mc", "cloud"))
"""The default (source, target) pairs: both directions where a direction tells something new."""
METHODS = {"std": ("std", {}), "svd": ("svd", {"rtol": PAPER_RTOL}), "gain": ("svd_gain", {}),
           "default": ("default", {})}
"""Label -> (registry method, parameters): the standard transfer, the paper's Approach B, Approach B at the
threshold of the gain rule (no ground truth: beside the paper), the library's default."""
COMPARED = ("svd", "gain", "default")
"""The methods judged against ``std`` in :func:`summary`."""
NAMES = {"svd": "Approach B (the paper's threshold)", "gain": "Approach B with the gain rule",
         "default": "The default transfer"}
"""Display names of :data:`COMPARED` in the finding."""
SHORT = {"std": "std", "svd": "B", "gain": "B gain", "default": "default"}
"""Column labels of the figure and the report's tables."""
CONVERSIONS = ("std", "extended")
"""The point-map conversions of :func:`prodmaps.p2p.from_fmap`."""
FUNCTIONS = ("X", "Y", "Z", "Indicator", "hk")
"""Function labels of the results (``Indicator`` and ``hk``: means over their columns)."""
MARGIN = 0.01
"""A method is *worse* than the standard transfer on a function when its error exceeds std's by more than 1 %."""
CLEAN = ("mesh", "iso", "nonuniform")
"""Discretizations that are clean meshes (the rest: clouds and the marching-cubes mesh)."""
MC_SPACING = 0.016
"""Marching-cubes grid spacing over ``sqrt(area)`` (about as many vertices as a 5k-vertex human)."""


def spread_shapes(dataset: str, n: int) -> list[str]:
    """``n`` shape ids of ``dataset`` spread evenly over its list (subjects and poses): ``ids[::len // n][:n]``."""
    ids = datasets.shape_ids(dataset)
    if not 1 <= int(n) <= len(ids):
        raise ValueError(f"n must be in [1, {len(ids)}] (the shapes of {dataset!r}), got {n}")
    return ids[:: len(ids) // int(n)][: int(n)]


def sample_surface(mesh: Mesh, n: int, *, seed: int = 0, normals: bool = True, name: str = "") -> PointCloud:
    """``n`` points uniform by area on ``mesh`` (a face drawn by area, a uniform point in it), seeded.

    Returns a :class:`prodmaps.PointCloud` (normals: those of the faces drawn, or none).
    """
    if int(n) < 4:
        raise ValueError(f"n must be at least 4 points, got {n}")
    V, F = mesh.vertices, mesh.faces
    rng = np.random.default_rng(seed)
    a = face_areas(V, F)
    face = rng.choice(F.shape[0], size=int(n), p=a / a.sum())  # (n,)
    r1, r2 = rng.random((2, int(n)))
    s = np.sqrt(r1)
    w = np.stack([1.0 - s, s * (1.0 - r2), s * r2], axis=1)  # (n, 3) barycentric, uniform in the triangle
    P = np.einsum("nc,ncd->nd", w, V[F[face]])  # (n, 3)
    N = face_normals(V, F)[face] if normals else None
    return PointCloud(P, N, name=name or f"{mesh.name}_cloud{seed}")


def remesh(mesh: Mesh, recipe: str, *, name: str = "") -> Mesh:
    """``recipe`` (``"iso"`` or ``"nonuniform"``) of :mod:`prodmaps.prepare.variants` applied to ``mesh``, repaired.

    Where the surface touches itself (FAUST_r's hands on thighs, feet), the remesher can join
    the sheets through edges of more than two faces: those faces are removed (pymeshlab), which
    leaves at most a few tiny holes, then :func:`prodmaps.mesh.repair`. A manifold remesh is
    unchanged by the removal.
    """
    import pymeshlab

    recipes = {"iso": remesh_iso, "nonuniform": remesh_nonuniform}
    if recipe not in recipes:
        raise ValueError(f"recipe must be one of {sorted(recipes)}, got {recipe!r}")
    v, f = recipes[recipe](mesh.vertices, mesh.faces)
    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(vertex_matrix=v, face_matrix=np.asarray(f, dtype=np.int32)))
    ms.meshing_repair_non_manifold_edges(method="Remove Faces")
    m = ms.current_mesh()
    out, _ = repair(m.vertex_matrix().astype(np.float64), m.face_matrix().astype(np.int64),
                    name=name or f"{mesh.name}_{recipe}")
    return out


def marching_cubes_mesh(mesh: Mesh, spacing: float = MC_SPACING, *, name: str = "") -> Mesh:
    """Marching cubes (libigl) of ``mesh``'s signed distance on a grid of ``spacing · sqrt(area)``, repaired.

    The sign is libigl's pseudonormal test (a closed, consistently oriented mesh); the grid spans
    the bounding box plus two cells. :func:`prodmaps.mesh.repair` merges what the extraction
    duplicates, drops degenerate faces and keeps the largest piece.
    """
    import igl

    if not spacing > 0:
        raise ValueError(f"spacing must be > 0 (a fraction of sqrt(area)), got {spacing}")
    h = float(spacing) * np.sqrt(mesh.area)
    lo, hi = mesh.vertices.min(0) - 2 * h, mesh.vertices.max(0) + 2 * h
    n = (np.ceil((hi - lo) / h).astype(int) + 1).tolist()
    axes = [lo[i] + h * np.arange(n[i]) for i in range(3)]
    GV = np.stack(np.meshgrid(*axes, indexing="ij"), -1).transpose(2, 1, 0, 3).reshape(-1, 3)  # x fastest
    GV = np.ascontiguousarray(GV)
    S, _, _, _ = igl.signed_distance(GV, mesh.vertices, np.ascontiguousarray(mesh.faces, dtype=np.int64),
                                     sign_type=igl.SignedDistanceType.SIGNED_DISTANCE_TYPE_PSEUDONORMAL)
    V, F, _ = igl.marching_cubes(np.ascontiguousarray(S, dtype=np.float64), GV, n[0], n[1], n[2], 0.0)
    out, _ = repair(V, F, name=name or f"{mesh.name}_mc")
    return out


def discretizations(mesh: Mesh, names=DISCRETIZATIONS, *, seed: int = 0, cloud_points: int | None = None,
                    mc_spacing: float = MC_SPACING) -> dict:
    """The discretizations ``names`` of ``mesh`` (module doc): ``{name: Mesh or PointCloud}``.

    ``cloud`` uses ``seed``, ``cloud2`` ``seed + 1``; both have ``cloud_points`` points (default
    the mesh's vertex count).
    """
    bad = set(names) - set(DISCRETIZATIONS)
    if bad:
        raise ValueError(f"unknown discretizations {sorted(bad)}; choose from {DISCRETIZATIONS}")
    n = mesh.n_vertices if cloud_points is None else int(cloud_points)
    make = {"mesh": lambda: mesh,
            "iso": lambda: remesh(mesh, "iso"),
            "nonuniform": lambda: remesh(mesh, "nonuniform"),
            "cloud": lambda: sample_surface(mesh, n, seed=seed, name=f"{mesh.name}_cloud"),
            "cloud2": lambda: sample_surface(mesh, n, seed=seed + 1, name=f"{mesh.name}_cloud2"),
            "mc": lambda: marching_cubes_mesh(mesh, mc_spacing, name=f"{mesh.name}_mc")}
    return {d: make[d]() for d in names}


def surface_ground_truth(points_2, points_1, surface_vertices, surface_faces) -> np.ndarray:
    """``p2p_21`` ``(n2,)``: each point of shape 2's closest point on the surface, read as the nearest point of shape 1.

    ``points_2`` ``(n2, 3)``, ``points_1`` ``(n1, 3)``; the surface ``(V, F)`` is shape 1's
    (its mesh, or the mesh a cloud was sampled from). Shape 1's own points give the identity.
    """
    import igl

    P2 = np.ascontiguousarray(points_2, dtype=np.float64)
    V = np.ascontiguousarray(surface_vertices, dtype=np.float64)
    F = np.ascontiguousarray(surface_faces, dtype=np.int64)
    _, _, Q = igl.point_mesh_squared_distance(P2, V, F)  # (n2, 3) closest points on the surface
    _, p2p_21 = cKDTree(np.asarray(points_1, dtype=np.float64)).query(np.asarray(Q))
    return np.asarray(p2p_21, dtype=np.int64)


def ground_truth(target, source, original: Mesh) -> np.ndarray:
    """:func:`surface_ground_truth` from shape ``target`` to ``source`` (a cloud source uses ``original``'s surface)."""
    surf = source if isinstance(source, Mesh) else original
    return surface_ground_truth(target.vertices, source.vertices, surf.vertices, surf.faces)


def _describe(shape, original: Mesh, gt_to_original: np.ndarray) -> dict:
    """Size, area and ground-truth distance to the original (over ``sqrt(area)``) of one discretization."""
    d = np.linalg.norm(shape.vertices - original.vertices[gt_to_original], axis=1) / np.sqrt(original.area)
    out = {"kind": "mesh" if isinstance(shape, Mesh) else "cloud", "n_vertices": int(shape.n_vertices),
           "gt_distance_mean": float(d.mean()), "gt_distance_max": float(d.max())}
    if isinstance(shape, Mesh):
        q = face_radius_ratio(shape.vertices, shape.faces)  # (m,) 2r/R
        out.update({"n_faces": int(shape.n_faces), "area_ratio": float(shape.area / original.area),
                    "faces_radius_ratio_below_0.1": float(np.mean(q < 0.1))})
    return out


def _functions(shape, F_original: np.ndarray, gt_to_original: np.ndarray) -> np.ndarray:
    """``(n, 3 + m)``: the shape's own coordinates, then the original's functions read through the ground truth."""
    return np.hstack([shape.vertices, F_original[gt_to_original]])


def _pair_key(s: str, t: str) -> str:
    return f"{s}->{t}"


def discretization_study(dataset: str, shape_ids, *, pairs=PAIRS, ks=(10, 20), n_indicators: int = 3,
                         n_heat: int = 3, kernel_eig: int = 100, n_eval: int = 300, seed: int = 0,
                         cloud_points: int | None = None, mc_spacing: float = MC_SPACING,
                         picture=("mesh", "cloud"), verbose: bool = True) -> dict:
    """Run the study (module doc) on the shapes ``shape_ids`` of ``dataset``.

    ``ks``: the paper's ``k`` (non-constant functions; bases of ``k + 1`` columns). Returns
    ``{"results": ..., "picture": {...}}``: ``results["errors"]["k<k>"][pair][function][method]``
    (relative transfer errors, means over shapes and over a function's columns), the same per
    shape in ``errors_per_shape``, ``point_maps["k<k>"][pair][conversion]`` (mean geodesic error),
    ``discretizations[shape][name]`` (sizes, quality), ``cells`` (every single function: shape,
    k, pair, function column, the three errors), ``summary`` (:func:`summary`) and ``seconds``.
    ``picture``: the pair whose fields on the first shape at the largest ``k`` are returned
    (``{"source", "target", "functions", "labels", "truth", <method>: (n_t, m)}``).
    """
    pairs = [tuple(p) for p in pairs]
    ks = [int(k) for k in ks]
    names = list(dict.fromkeys(d for p in pairs for d in p))
    if max(ks) + 1 > kernel_eig:
        raise ValueError(f"kernel_eig={kernel_eig} must be at least max(ks) + 1 = {max(ks) + 1}")
    labels = ["X", "Y", "Z"] + [f"Indicator {i}" for i in range(n_indicators)] + [f"hk {i}" for i in range(n_heat)]
    group = np.array(["X", "Y", "Z"] + ["Indicator"] * n_indicators + ["hk"] * n_heat)
    t_all = time.perf_counter()
    seconds = {"discretizations": 0.0, "bases": 0.0, "transfers": 0.0, "point_maps": 0.0}
    per_shape, p2p_shape, described, cells, pic = {}, {}, {}, [], None
    for i_shape, sid in enumerate(shape_ids):
        t0 = time.perf_counter()
        original = datasets.load_shape(dataset, sid)
        shapes = discretizations(original, names, seed=seed, cloud_points=cloud_points, mc_spacing=mc_spacing)
        seconds["discretizations"] += time.perf_counter() - t0
        t0 = time.perf_counter()
        bases = {d: eigenbasis(s, kernel_eig) for d, s in shapes.items()}
        b0 = bases["mesh"] if "mesh" in bases else eigenbasis(original, kernel_eig)
        F0 = np.hstack([make_family("Indicator", original, b0, k_M=max(ks), seed=seed, m=n_indicators)[0],
                        make_family("hk_K", original, b0, k_M=max(ks), seed=seed, m=n_heat, n_eig_K=kernel_eig)[0]])
        seconds["bases"] += time.perf_counter() - t0
        to_original = {d: ground_truth(s, original, original) for d, s in shapes.items()}
        described[sid] = {d: _describe(s, original, to_original[d]) for d, s in shapes.items()}
        funcs = {d: _functions(s, F0, to_original[d]) for d, s in shapes.items()}
        rows = {d: geodesics.DistanceRows(s) for d, s in shapes.items()}
        per_shape[sid], p2p_shape[sid] = {}, {}
        for s, t in pairs:
            key = _pair_key(s, t)
            p2p = ground_truth(shapes[t], shapes[s], original)  # (n_t,) target point -> source point
            F1, G2 = funcs[s], funcs[s][p2p]  # (n_s, m), the truth (n_t, m)
            ev = np.sort(np.random.default_rng([seed, i_shape, names.index(t)]).choice(
                shapes[t].n_vertices, min(int(n_eval), shapes[t].n_vertices), replace=False))
            for k in ks:
                t0 = time.perf_counter()
                b1, b2 = bases[s].truncate(k + 1), bases[t].truncate(k + 1)
                C = fmap_from_p2p(p2p, b1, b2)  # (k + 1, k + 1)
                out = {}
                for label, (method, params) in METHODS.items():
                    out[label] = transfer_operator(C, b1, b2, method, **params)(F1)  # (n_t, m)
                err = {m: np.atleast_1d(relative_error(g, G2, b2.mass)) for m, g in out.items()}  # (m,) each
                per_shape[sid].setdefault(f"k{k}", {})[key] = {
                    fn: {m: float(err[m][group == fn].mean()) for m in METHODS} for fn in FUNCTIONS}
                cells += [{"shape": sid, "k": k, "pair": key, "function": labels[j],
                           **{m: float(err[m][j]) for m in METHODS}} for j in range(len(labels))]
                seconds["transfers"] += time.perf_counter() - t0
                t0 = time.perf_counter()
                P = np.stack([from_fmap(C, bases[s], bases[t], c, vertices=ev) for c in CONVERSIONS])  # (2, n_ev)
                E = geodesics.map_error(shapes[s], P, p2p[ev], rows=rows[s])  # (2, n_ev)
                p2p_shape[sid].setdefault(f"k{k}", {})[key] = {c: float(e.mean()) for c, e in zip(CONVERSIONS, E)}
                seconds["point_maps"] += time.perf_counter() - t0
                if i_shape == 0 and (s, t) == tuple(picture) and k == max(ks):
                    pic = {"source": shapes[s], "target": shapes[t], "functions": F1, "labels": labels,
                           "truth": G2, "k": k, "shape": sid, **out}
        if verbose:
            print(f"{sid}: " + ", ".join(f"{d} {v['n_vertices']}" for d, v in described[sid].items())
                  + f" [{time.perf_counter() - t_all:.1f} s]", flush=True)
    errors = _mean_over_shapes(per_shape)
    point_maps = _mean_over_shapes(p2p_shape)
    results = {"dataset": dataset, "shapes": list(shape_ids), "ks": ks, "pairs": [_pair_key(*p) for p in pairs],
               "functions": list(FUNCTIONS), "function_columns": labels, "methods": list(METHODS),
               "conversions": list(CONVERSIONS), "kernel_eig": int(kernel_eig), "n_eval": int(n_eval),
               "discretizations": described, "errors": errors, "errors_per_shape": per_shape,
               "point_maps": point_maps, "point_maps_per_shape": p2p_shape, "cells": cells,
               "error_definition": "sqrt(int (g - f o T)^2) / sqrt(int (f o T)^2) on the target, area-weighted; "
                                   "point maps: heat-method geodesic error on the source / sqrt(source area)"}
    results["summary"] = summary(results)
    seconds["total"] = time.perf_counter() - t_all
    results["seconds"] = seconds
    return {"results": results, "picture": pic}


def find_cell(results: dict, *, shape: str, k: int, pair: str, function: str) -> dict:
    """The entry of ``results["cells"]`` of one single function (its three errors); ``KeyError`` if none."""
    for c in results["cells"]:
        if (c["shape"], c["k"], c["pair"], c["function"]) == (shape, int(k), pair, function):
            return c
    raise KeyError(f"no cell {shape}/k{k}/{pair}/{function} in the results")


def _mean_over_shapes(per_shape: dict) -> dict:
    """The mean over shapes of nested ``{k: {pair: {...: value}}}`` dicts of the same layout."""
    first = next(iter(per_shape.values()))

    def mean(path):
        vals = []
        for d in per_shape.values():
            for p in path:
                d = d[p]
            vals.append(d)
        return float(np.mean(vals))

    def walk(node, path):
        return {k: walk(v, (*path, k)) if isinstance(v, dict) else mean((*path, k)) for k, v in node.items()}

    return walk(first, ())


GROUPS = {"clean": "clean mesh to clean mesh", "to_rough": "clean mesh to a cloud or the marching-cubes mesh",
          "from_rough": "from a cloud or the marching-cubes mesh"}
"""The pair groups of :func:`summary` (clean: :data:`CLEAN`)."""


def pair_group(pair_key: str) -> str:
    """The group (:data:`GROUPS`) of a pair ``"<source>-><target>"``."""
    s, t = pair_key.split("->")
    return "from_rough" if s not in CLEAN else ("clean" if t in CLEAN else "to_rough")


def summary(results: dict) -> dict:
    """The finding, from ``results`` (:func:`discretization_study`).

    ``worse``: per method (:data:`COMPARED`) and group of pairs (``all`` and :data:`GROUPS`),
    the single functions (``cells``) whose error exceeds std's by more than :data:`MARGIN`
    (relative; a tie by :func:`prodmaps.experiments.shared.compare.is_tie` never counts), the
    worst ratio to std and its cell, the pairs with such cells. ``xyz_better``: per k and method,
    the pairs whose mean XYZ error is below std's (beyond a tie). ``point_maps_better``: per k,
    the pairs where the extended conversion beats the standard one.
    """
    cells = results["cells"]
    worse = {}
    for m in (m for m in COMPARED if m in results["methods"]):
        worse[m] = {}
        for grp in ("all", *GROUPS):
            sel = [c for c in cells if grp == "all" or pair_group(c["pair"]) == grp]
            if not sel:
                continue
            ratio = [c[m] / c["std"] for c in sel]
            bad = [r > 1 + MARGIN and not compare.is_tie(c[m], c["std"]) for c, r in zip(sel, ratio)]
            j = int(np.argmax(ratio))
            worse[m][grp] = {"cells": len(sel), "worse_by_more_than_margin": int(sum(bad)),
                             "worst_ratio": float(ratio[j]),
                             "worst_cell": f"{sel[j]['shape']}/k{sel[j]['k']}/{sel[j]['pair']}/{sel[j]['function']}",
                             "pairs_with_worse_cells": sorted({c["pair"] for c, b in zip(sel, bad) if b})}
    xyz, pmaps = {}, {}
    for kk in (f"k{k}" for k in results["ks"]):
        E, Pm = results["errors"][kk], results["point_maps"][kk]
        xyz[kk] = {m: [p for p in results["pairs"] if compare.lower(np.mean([E[p][c][m] for c in "XYZ"]),
                                                                    np.mean([E[p][c]["std"] for c in "XYZ"]))]
                   for m in COMPARED if m in results["methods"]}
        pmaps[kk] = [p for p in results["pairs"] if compare.lower(Pm[p]["extended"], Pm[p]["std"])]
    return {"margin": MARGIN, "worse": worse, "xyz_better": xyz, "point_maps_better": pmaps,
            "n_pairs": len(results["pairs"])}


def _pairs_text(pairs) -> str:
    return ", ".join(f"`{p}`" for p in pairs) if pairs else "none"


def finding_items(results: dict) -> list[str]:
    """The finding as Markdown sentences, computed from ``results["summary"]`` (:func:`summary`)."""
    s = results["summary"]
    n, pct, out = s["n_pairs"], f"{100 * s['margin']:g} %", []
    for kk in (f"k{k}" for k in results["ks"]):
        by_m = s["xyz_better"][kk]
        both = [p for p in by_m["svd"] if p in by_m["default"]]
        gain = f", with the gain rule in {len(by_m['gain'])}" if "gain" in by_m else ""
        out.append(f"**{kk.replace('k', 'k = ')}**: products lower the mean XYZ error in {len(both)} of {n} pairs "
                   f"with both Approach B and the default ({_pairs_text(both)}); with Approach B in "
                   f"{len(by_m['svd'])}{gain}, with the default in {len(by_m['default'])}. The extended point map "
                   f"beats the standard one in {len(s['point_maps_better'][kk])} of {n} pairs.")
    for m in (m for m in COMPARED if m in s["worse"]):
        name, w = NAMES[m], s["worse"][m]
        a = w["all"]
        text = (f"**{name}** is worse than the standard transfer by more than {pct} on "
                f"{a['worse_by_more_than_margin']} of {a['cells']} single functions (worst {a['worst_ratio']:.3f} "
                f"times std, `{a['worst_cell']}`): ")
        text += "; ".join(f"{w[g]['worse_by_more_than_margin']} of {w[g]['cells']} {GROUPS[g]} "
                          f"(worst {w[g]['worst_ratio']:.3f})" for g in GROUPS if g in w)
        if a["pairs_with_worse_cells"]:
            text += f"; in the pairs {_pairs_text(a['pairs_with_worse_cells'])}"
        out.append(text + ".")
    return out


def finding_text(results: dict) -> str:
    """:func:`finding_items` as a Markdown list."""
    return "\n".join(f"- {item}" for item in finding_items(results))


def figure(results: dict):
    """Grid of mean errors per pair (rows) and function (columns), the methods side by side; a panel per k.

    Colour: the method's error over std's (log scale, blue below std); the text: the error.
    """
    import matplotlib.colors as mcolors

    plt = setup_matplotlib()
    errors, pmaps = results["errors"], results["point_maps"]
    pairs, fns, ms = results["pairs"], results["functions"], results["methods"]
    cols = [(f, m) for f in fns for m in ms] + [("p2p", c) for c in results["conversions"]]
    fig, axes = plt.subplots(len(errors), 1, figsize=(0.62 * len(cols) + 1.6, (0.3 * len(pairs) + 1.5) * len(errors)),
                             squeeze=False)
    for ax, kk in zip(axes[:, 0], (f"k{k}" for k in results["ks"])):
        by_pair = errors[kk]
        E = np.array([[by_pair[p][f][m] for f, m in cols[:-2]] + [pmaps[kk][p][c] for _, c in cols[-2:]]
                      for p in pairs])  # (pairs, columns)
        ref = np.array([[by_pair[p][f]["std"] for f, _ in cols[:-2]] + [pmaps[kk][p]["std"]] * 2 for p in pairs])
        ax.imshow(np.log2(E / ref), cmap="RdBu_r", norm=mcolors.TwoSlopeNorm(vmin=-2, vcenter=0, vmax=2),
                  aspect="auto", interpolation="nearest")
        for i in range(E.shape[0]):
            for j in range(E.shape[1]):
                ax.text(j, i, f"{E[i, j]:.3f}"[1:] if E[i, j] < 1 else f"{E[i, j]:.2f}", ha="center", va="center",
                        fontsize=5.5, color="white" if abs(np.log2(E[i, j] / ref[i, j])) > 1.3 else "black")
        ax.set_xticks(range(len(cols)), [f"{f} {SHORT.get(m, m)}" for f, m in cols], fontsize=6,
                      rotation=60, ha="right")
        for j in range(len(ms), len(cols) - 2, len(ms)):
            ax.axvline(j - 0.5, color="k", lw=0.6)
        ax.axvline(len(cols) - 2.5, color="k", lw=1.2)
        ax.set_yticks(range(len(pairs)), pairs, fontsize=7)
        ax.set_title(f"{kk.replace('k', 'k = ')} (bases of {int(kk[1:]) + 1} columns)", fontsize=8)
    fig.suptitle(f"Transfer error per discretization pair (source -> target) on {len(results['shapes'])} shape(s) "
                 "of " + results["dataset"] + "; colour: error / std's (blue: below), p2p: geodesic error", fontsize=8)
    fig.tight_layout()
    return fig


def front_axes(frame=None) -> np.ndarray:
    """Camera axes ``(3, 3)`` for :func:`prodmaps.plot` (rows: up, across, towards the camera): a body from the front.

    ``frame``: the dataset's body frame (:data:`prodmaps.experiments.shared.anatomy.FRAMES`; None:
    z up, facing -y, as the embedded humans).
    """
    R = body_frame(frame)  # rows: the body frame's x, y, z in the dataset's coordinates
    return np.stack([R[2], R[0], -R[1]])


def _fmt(v: float) -> str:
    return f"{v:.3f}"


def report_blocks(results: dict, dataset: str, *, main: bool = True) -> list:
    """The study's section of the report: ``("h", level, text)``, ``("p", text)``, ``("table", header, rows)`` blocks.

    Per k, a table of the mean errors per pair (XYZ mean, Indicator and hk: the methods of the run;
    point maps: std / extended), then the finding (:func:`finding_text`). ``dataset``: the
    display name, in the heading of a per-dataset section (``main=False``).
    """
    if not results.get("summary"):
        return []
    on = "" if main else f" on {dataset}"
    d0 = results["discretizations"][results["shapes"][0]]
    sizes = ", ".join(f"{d} {d0[d]['n_vertices']}" for d in DISCRETIZATIONS if d in d0)
    out = [("h", 2 if main else 3, f"Study: transfer and point maps across discretizations{on}"),
           ("p", f"Discretizations derived from {len(results['shapes'])} shape(s) (vertices or points on the first: "
                 f"{sizes}); ground truth: nearest point on the source surface, read as the nearest source vertex; "
                 "ground-truth maps; Approach B at the paper's threshold and with the gain rule "
                 "(`study_discretizations`).")]
    for kk in (f"k{k}" for k in results["ks"]):
        rows = []
        for p in results["pairs"]:
            e = results["errors"][kk][p]
            ms = results["methods"]
            xyz = {m: np.mean([e[c][m] for c in "XYZ"]) for m in ms}
            pm_ = results["point_maps"][kk][p]
            rows.append([f"`{p}`", " / ".join(_fmt(xyz[m]) for m in ms),
                         " / ".join(_fmt(e["Indicator"][m]) for m in ms),
                         " / ".join(_fmt(e["hk"][m]) for m in ms),
                         f"{_fmt(pm_['std'])} / {_fmt(pm_['extended'])}"])
        out.append(("p", f"{kk.replace('k', 'k = ')} (bases of {int(kk[1:]) + 1} columns): relative transfer errors "
                         f"{' / '.join(SHORT.get(m, m) for m in results['methods'])}; point maps: mean geodesic "
                         "error std / extended."))
        out.append(("table", ["pair", "XYZ", "Indicator", "hk", "point map"], rows))
    out.append(("p", "Finding, computed from the numbers:"))
    out.append(("ul", finding_items(results)))
    return out
