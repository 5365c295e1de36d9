"""Figure 14 (Section 5.4): consistent cross fields through a functional map.

The cross-field library is :mod:`prodmaps.fields`; this module is the experiment of the Figure 14
notebook (layer 2: it reads datasets and compares with a ground truth).

Main experiment, the paper's setting ([ACBCO17] design both fields jointly):
:func:`figure14_joint_pair` / :func:`figure14_joint_study` design the two cross fields of a pair
at once, with the consistency through ``C``, ``C~``, the default transfer and a point-map oracle,
beside baselines (the kinds and baselines: :func:`figure14_joint_pair`); :func:`pair_measures`
holds the measures; :func:`surface_ground_truth` gives remeshed targets a surface ground truth.

Second setting, this package's own (``params["map_only"]``, on by default): **map only**. The
source keeps its no-map field (the ``"independent"`` baseline's, smooth and curvature-aligned) and
the target is designed by consistency and smoothness alone (no alignment on the target), through
the same problems: the map has to carry the field. Every k row carries the no-map result
(``"no_map"``); ``out["map"]`` has the singular values of ``C`` and the ``"ext"`` rows the
Approach-B ranks and the transfer gain of ``C~`` (large where ``k`` cuts a cluster of close
eigenvalues and ``C`` has a nearly zero singular value). :func:`verdict_table` counts, per
setting and k, the pairs where each design beats ``C``.

``k`` is the paper's k: the number of **non-constant** eigenfunctions (``C`` has ``k+1`` rows
and columns); the paper uses ``k = 5`` and a ground-truth functional map.
"""

from __future__ import annotations

import time

import numpy as np
from scipy.optimize import linear_sum_assignment
from scipy.sparse.csgraph import dijkstra
from scipy.spatial import cKDTree

from ... import datasets
from ...approx import PAPER_RTOL
from ...basis import eigenbasis
from ...fields.consistency import consistency_problem, design_consistent_field, design_joint
from ...fields.crossfield import (
    angle_stats,
    closest_point_correspondence,
    cross_angle,
    curvature_guide,
    pushforward_field,
    pushforward_field_barycentric,
    singularities,
)
from ...fields.frames import angle_defect, mesh_frames
from ...fields.quadmesh import extract_quads, quad_mesh_stats, seamless_parametrization
from ...geodesics import distances, edge_graph
from ...mesh import Mesh, mean_edge_length
from ...operators import lumped_mass
from ...p2p import fmap_from_p2p
from ..shared.parallel import map_tasks

__all__ = ["match_singularities", "surface_ground_truth", "low_curvature_vertices", "pair_measures",
           "figure14_joint_pair", "summarize_pairs", "summarize_quads", "figure14_joint_study", "quad_meshes_pair",
           "quad_mesh_of", "study_lines", "verdict_table", "verdict_lines", "setting_summary", "SETTINGS", "PAIRS",
           "JOINT_DEFAULTS", "JOINT_KINDS", "BASELINES"]


def match_singularities(mesh: Mesh, sing_a, index_a, sing_b, index_b, *, radius: float | None = None) -> dict:
    """Match two sets of singular vertices of one mesh (same index only), minimising distances.

    Optimal assignment (Hungarian) on edge-graph distances (:func:`prodmaps.geodesics.distances`,
    ``method="graph"``); pairs of different index are not allowed. Returns counts, the mean/median
    matched distance (mesh units), and the fraction of ``b`` (the reference) matched within
    ``radius`` (default 3 mean edge lengths).
    """
    sa, sb = np.asarray(sing_a), np.asarray(sing_b)
    ia, ib = np.asarray(index_a), np.asarray(index_b)
    if radius is None:
        radius = 3.0 * mean_edge_length(mesh.vertices, mesh.faces)
    out = {"n_a": int(sa.size), "n_b": int(sb.size), "radius": float(radius)}
    if sa.size == 0 or sb.size == 0:
        out.update(n_matched=0, mean_dist=float("nan"), median_dist=float("nan"), recall=0.0)
        return out
    D = distances(mesh, sb, method="graph")[:, sa]  # (nb, na)
    big = 1e6 * (D[np.isfinite(D)].max() + 1.0)
    cost = np.where(ib[:, None] == ia[None, :], D, big)
    r, c = linear_sum_assignment(cost)
    ok = cost[r, c] < big
    d = D[r[ok], c[ok]]
    out.update(n_matched=int(ok.sum()), mean_dist=float(d.mean()) if d.size else float("nan"),
               median_dist=float(np.median(d)) if d.size else float("nan"),
               recall=float(np.sum(d <= radius) / sb.size))
    return out


def _finite_or_none(obj):
    """Replace NaN (e.g. a distance with no matched singularity) by None, recursively (JSON-safe)."""
    if isinstance(obj, dict):
        return {k: _finite_or_none(v) for k, v in obj.items()}
    if isinstance(obj, float) and not np.isfinite(obj):
        return None
    return obj


# ============================================================================ joint design (main)
JOINT_DEFAULTS = {
    "smoothness": 1e-3,  # μ on both shapes (dimensionless, see design_joint)
    "align": 1.0,  # α, curvature alignment on both shapes
    "consistency": 1.0,  # β, weight of the consistency term through the map
    "tests": "pairs",  # the same test functions for every kind: base functions and pairwise sums
    "rtol": PAPER_RTOL,  # Approach B threshold (the paper's)
    "sing_quantile": 0.8,  # singularities are compared at vertices below this quantile of |Gaussian curvature|
    "sing_radius": 0.05,  # matching radius of singularities / sqrt(area_2)
    "regular_radius": 3.0,  # faces within this many mean edge lengths of a singularity are excluded
    "quad_size": 0.03,  # target quad edge / sqrt(area) of the quad meshes (0: no quad meshes)
    "quad_kinds": ("std", "ext", "default", "p2p"),  # designs quadrangulated at every k (p2p: the oracle),
    # plus the baselines "independent" and "pushforward"
    "map_only": True,  # also the map-only setting: the source's no-map field fixed, the target designed
    # by consistency and smoothness alone (no alignment on the target), through the same problems
}
JOINT_KINDS = ("std", "ext", "default", "p2p")
BASELINES = ("independent", "copy", "pushforward")


def surface_ground_truth(dataset: str, id_1: str, id_2: str) -> dict:
    """Ground truth of a dataset pair for evaluating fields (never used by a design).

    Returns ``{"p2p_21" (n2,), "p2p_12" (n1,), "same_triangulation": bool, "face_21" (n2,) or
    None, "bary_21" (n2, 3) or None}``: the vertex maps of :func:`prodmaps.datasets.ground_truth`
    both ways and, when shape 2 is a remeshed variant of a shape with shape 1's triangulation,
    the surface correspondence: each variant vertex's closest point on its base shape as (face,
    barycentric coordinates), which name the same point on shape 1 (same triangulation). The
    push-forward of a field then goes through those points
    (:func:`prodmaps.fields.crossfield.pushforward_field_barycentric`), not through the nearest
    vertex. A variant as shape 1 is not supported.
    """
    if id_1 in datasets.variants(dataset):
        raise ValueError(f"{id_1!r} is a remeshed variant; put it as shape 2")
    m1, m2 = datasets.load_shape(dataset, id_1), datasets.load_shape(dataset, id_2)
    out = {"p2p_21": np.asarray(datasets.ground_truth(dataset, id_1, id_2), dtype=np.int64),
           "p2p_12": np.asarray(datasets.ground_truth(dataset, id_2, id_1), dtype=np.int64),
           "same_triangulation": bool(m1.faces.shape == m2.faces.shape and np.array_equal(m1.faces, m2.faces)),
           "face_21": None, "bary_21": None}
    if id_2 in datasets.variants(dataset):
        base = datasets.load_shape(dataset, datasets.base_shape(dataset, id_2))
        out["face_21"], out["bary_21"] = closest_point_correspondence(m2.vertices, base.vertices, base.faces)
    return out


def _pushforward(fr1, z1, fr2, gt):
    if gt.get("face_21") is not None:
        return pushforward_field_barycentric(fr1, z1, fr2, gt["face_21"], gt["bary_21"])
    return pushforward_field(fr1, z1, fr2, gt["p2p_21"])


def _far_from(mesh: Mesh, vertices, radius):
    """Vertex mask: edge-graph distance to every vertex of ``vertices`` larger than ``radius``."""
    if len(vertices) == 0:
        return np.ones(mesh.n_vertices, bool)
    d = dijkstra(edge_graph(mesh), directed=False, indices=np.asarray(vertices, dtype=np.int64), min_only=True,
                 limit=radius * 1.01)
    return d > radius


def low_curvature_vertices(mesh: Mesh, quantile: float = 0.8) -> np.ndarray:
    """Vertex mask ``(n,)``: curvature density ``|angle defect| / lumped area`` below its ``quantile``."""
    K = np.abs(angle_defect(mesh.vertices, mesh.faces)) / lumped_mass(mesh.vertices, mesh.faces)
    return K < np.quantile(K, quantile)


def pair_measures(fr1, fr2, mesh_1, mesh_2, z1, z2, gt, g1, g2, *, params=None) -> dict:
    """The discriminating measures of one pair of fields ``(z1 on shape 1, z2 on shape 2)``.

    * ``angle_mean_deg`` / ``angle_p90_deg``: area-weighted angle (modulo 90°) of ``z2`` to the
      ground-truth push-forward of ``z1`` (the consistency of the two fields), on every valid face;
    * ``angle_regular_deg``: the same mean on the *regular* faces only: anisotropic (curvature
      guide weight > 0 on shape 2) and farther than ``regular_radius`` mean edge lengths from every
      singularity of either field (umbilic and singular regions, where a cross is ill-defined, out);
    * ``align_1_deg`` / ``align_2_deg``: guide-weighted angle of each field to its own shape's
      curvature directions (what the alignment term asks);
    * singularities: counts of the raw fields (``n_sing_1``, ``n_sing_2``, most forced by the angle
      defects); the comparison keeps those at **low-curvature** vertices of shape 2 (``|K_v|/A_v``
      below its ``sing_quantile`` quantile, :func:`low_curvature_vertices`), ``z1``'s carried to
      shape 2 by ``gt["p2p_12"]``: ``sing_recall`` is the
      fraction of ``z1``'s matched (same index, :func:`match_singularities`) to one of ``z2``'s
      within ``sing_radius·sqrt(area_2)``, ``sing_mean_dist`` the mean matched distance over
      ``sqrt(area_2)`` and ``sing_extra`` the unmatched ones of both.
    """
    P = {**JOINT_DEFAULTS, **(params or {})}
    (q1, w1), (q2, w2) = g1, g2
    ref, valid = _pushforward(fr1, z1, fr2, gt)
    V2, F2 = mesh_2.vertices, mesh_2.faces
    st = angle_stats(z2, ref, fr2.area, 4, valid)
    s_ref, _ = singularities(fr2, ref, 4)
    v1, i1 = singularities(fr1, z1, 4)
    v2, i2 = singularities(fr2, z2, 4)
    h = mean_edge_length(V2, F2)
    far = _far_from(mesh_2, np.union1d(s_ref, v2), P["regular_radius"] * h)
    regular = valid & (w2 > 0) & far[F2].all(axis=1)
    reg = angle_stats(z2, ref, fr2.area, 4, regular) if regular.any() else {"mean_deg": float("nan")}
    a1 = np.degrees(cross_angle(z1, q1, 4))
    a2 = np.degrees(cross_angle(z2, q2, 4))
    out = {"angle_mean_deg": st["mean_deg"], "angle_p90_deg": st["p90_deg"], "angle_regular_deg": reg["mean_deg"],
           "regular_fraction": float(np.sum(fr2.area * regular) / fr2.area.sum()),
           "align_1_deg": float(np.sum(fr1.area * w1 * a1) / np.sum(fr1.area * w1)),
           "align_2_deg": float(np.sum(fr2.area * w2 * a2) / np.sum(fr2.area * w2)),
           "n_sing_1": int(v1.size), "n_sing_2": int(v2.size)}
    low = low_curvature_vertices(mesh_2, P["sing_quantile"])
    v1m = gt["p2p_12"][v1]
    k1, k2 = low[v1m], low[v2]
    L = np.sqrt(fr2.area.sum())
    m = match_singularities(mesh_2, v2[k2], i2[k2], v1m[k1], i1[k1], radius=P["sing_radius"] * L)
    n_hit = int(round(m["recall"] * int(k1.sum())))
    out.update(n_sing_low_1=int(k1.sum()), n_sing_low_2=int(k2.sum()), sing_recall=float(m["recall"]),
               sing_mean_dist=float(m["mean_dist"] / L) if m["n_matched"] else float("nan"),
               sing_extra=int(k1.sum() + k2.sum() - 2 * n_hit))
    return out


def quad_mesh_of(mesh: Mesh, z, size: float):
    """Quad mesh of one shape from its cross field ``z`` at quad edge ``size·sqrt(area)``.

    Returns ``(stats, (V, Q, polygons, irregular), irregular valences)`` (:mod:`prodmaps.fields.quadmesh`),
    the stats being :func:`~prodmaps.fields.quadmesh.quad_mesh_stats`' without the vertex lists plus
    the parametrisation's flipped faces, integer error, ``h``, the field's singularities and
    ``polygons_near_singularities`` (non-quad faces with a corner within 2 quad sizes of one).
    """
    h = size * np.sqrt(mesh.area)
    par = seamless_parametrization(mesh, z, h)
    q = extract_quads(par)
    st = quad_mesh_stats(q["V"], q["Q"], q["polygons"])
    irr, val = st.pop("irregular"), st.pop("irregular_valence")
    near = 0
    if q["polygons"] and par["singular"].size:
        d, _ = cKDTree(mesh.vertices[par["singular"]]).query(q["V"])
        near = int(sum(d[p].min() <= 2 * h for p in q["polygons"]))
    st.update(n_flipped=par["n_flipped"], integer_error=par["integer_error"], h=float(h),
              n_field_singularities=int(par["singular"].size), polygons_near_singularities=near)
    return st, (q["V"], q["Q"], q["polygons"], irr), val


def quad_meshes_pair(mesh_1: Mesh, mesh_2: Mesh, z1, z2, gt: dict, size: float, *, sides=None) -> dict:
    """Quad meshes of both shapes from their cross fields, and how their irregular vertices correspond.

    :mod:`prodmaps.fields.quadmesh`: an integer-grid parametrisation, its quads and one polygon per hole;
    the correspondence is through the ground truth.

    ``size`` is the quad edge over ``sqrt(area)`` (of each shape). Returns ``{"stats": {"source",
    "target": :func:`quad_mesh_of`'s stats}, "irregular_matched": irregular vertices of the
    two meshes paired one to one (same valence, optimal assignment) with the source's ground-truth
    image within 2 quad sizes of the target's, "irregular_matched_of": the source's irregular
    count, "irregular_target": the target's, "irregular_match_fraction": matched over the mean of
    the two counts, and the same restricted to irregular vertices at low-curvature places of the
    target (:func:`low_curvature_vertices`, the source's through the ground truth):
    "irregular_low_matched", "irregular_low_source", "irregular_low_target",
    "irregular_low_match_fraction"}, "meshes": ((V, Q, polygons, irregular) source, (...) target)}``.
    ``sides``: the two :func:`quad_mesh_of` results when already computed (then ``z1``, ``z2`` are
    not used).
    """
    if sides is None:
        sides = (quad_mesh_of(mesh_1, z1, size), quad_mesh_of(mesh_2, z2, size))
    (st1, mesh_q1, val1), (st2, mesh_q2, val2) = sides
    stats, valences = {"source": st1, "target": st2}, (val1, val2)
    (V1, _, _, I1), (V2, _, _, I2) = mesh_q1, mesh_q2
    # the source's irregular vertices carried to the target (nearest source vertex, then p2p_12)
    tree2 = cKDTree(mesh_2.vertices)
    img = mesh_2.vertices[gt["p2p_12"][cKDTree(mesh_1.vertices).query(V1[I1])[1]]] if len(I1) else np.zeros((0, 3))
    low = low_curvature_vertices(mesh_2, JOINT_DEFAULTS["sing_quantile"])
    low_1 = low[tree2.query(img)[1]] if len(I1) else np.zeros(0, bool)
    low_2 = low[tree2.query(V2[I2])[1]] if len(I2) else np.zeros(0, bool)
    radius = 2 * stats["target"]["h"]

    def paired(a, b):
        if not (a.any() and b.any()):
            return 0
        D = np.linalg.norm(img[a][:, None, :] - V2[I2[b]][None, :, :], axis=2)  # (a, b)
        big = 1e6 * (radius + D.max())
        cost = np.where((D <= radius) & (valences[0][a][:, None] == valences[1][b][None, :]), D, big)
        r, c = linear_sum_assignment(cost)
        return int(np.sum(cost[r, c] < big))

    every_1, every_2 = np.ones(len(I1), bool), np.ones(len(I2), bool)
    n_match, n_low = paired(every_1, every_2), paired(low_1, low_2)
    denom, denom_low = 0.5 * (len(I1) + len(I2)), 0.5 * (low_1.sum() + low_2.sum())
    return {"stats": {**stats, "irregular_matched": n_match, "irregular_matched_of": int(len(I1)),
                      "irregular_target": int(len(I2)),
                      "irregular_match_fraction": float(n_match / denom) if denom else float("nan"),
                      "irregular_low_matched": n_low, "irregular_low_source": int(low_1.sum()),
                      "irregular_low_target": int(low_2.sum()),
                      "irregular_low_match_fraction": float(n_low / denom_low) if denom_low else float("nan")},
            "meshes": (mesh_q1, mesh_q2)}


def figure14_joint_pair(mesh_1: Mesh, mesh_2: Mesh, gt: dict, ks, *, kinds=JOINT_KINDS, params=None,
                        keep_fields: bool = False) -> dict:
    """Figure 14 in the paper's setting ([ACBCO17]'s joint design) on one pair, for every k in ``ks``.

    Both cross fields are designed at once (:func:`prodmaps.fields.consistency.design_joint`):
    smoothness and curvature alignment on each shape plus the consistency of their actions on
    functions through the map, with the same test functions (``params["tests"]``) for every kind:
    ``"std"`` (``C``), ``"ext"`` (``C~``, Approach B at ``rtol``), ``"default"`` (the library's
    default extended transfer of ``C``) and ``"p2p"`` (the exact point-map transfer of functions,
    an oracle). ``C`` is the ground-truth functional map (``fmap_from_p2p`` of ``gt["p2p_21"]``).
    Baselines (no k): ``"independent"`` (the same design with ``β = 0``: no map), ``"copy"``
    (the source's independent field copied face by face, only on one triangulation) and
    ``"pushforward"`` (the source's independent field pushed through the ground truth: consistent
    by construction, its alignment to shape 2 is the price).

    ``gt`` is :func:`surface_ground_truth`'s dict. Returns ``{"k<k>": {kind: measures},
    "baselines": {name: measures}, "seconds": ..., "fields": {...} (with keep_fields)}``; the
    measures are :func:`pair_measures`'.
    """
    P = {**JOINT_DEFAULTS, **(params or {})}
    t0 = time.perf_counter()
    fr1, fr2 = mesh_frames(mesh_1), mesh_frames(mesh_2)
    g1, g2 = curvature_guide(mesh_1, fr1), curvature_guide(mesh_2, fr2)
    kmax = max(int(k) for k in ks) + 1
    B1, B2 = eigenbasis(mesh_1, kmax), eigenbasis(mesh_2, kmax)
    out, fields = {}, {}

    measure = lambda z1, z2: _finite_or_none(pair_measures(fr1, fr2, mesh_1, mesh_2, z1, z2, gt, g1, g2, params=P))
    # baselines first: no map (each shape's own smooth curvature-aligned field); its source field is
    # also the fixed source field of the map-only setting
    b1, b2 = B1.truncate(2), B2.truncate(2)
    pr = consistency_problem(fr1, b1, fr2, b2, fmap_from_p2p(gt["p2p_21"], b1, b2), kind="std", tests="base")
    z1_ind, z2_ind, _ = design_joint(pr, g1[0], g2[0], smoothness=P["smoothness"], align=P["align"], consistency=0.0)
    no_map = measure(z1_ind, z2_ind)
    map_only = {} if P["map_only"] else None
    quad_fields = {}
    for k in ks:
        b1, b2 = B1.truncate(int(k) + 1), B2.truncate(int(k) + 1)
        C = fmap_from_p2p(gt["p2p_21"], b1, b2)
        row, row_m = {}, {}
        for kd in kinds:
            pr = consistency_problem(fr1, b1, fr2, b2, C, kind=kd, tests=P["tests"], rtol=P["rtol"],
                                     p2p_21=gt["p2p_21"])
            z1, z2, inf = design_joint(pr, g1[0], g2[0], smoothness=P["smoothness"], align=P["align"],
                                       consistency=P["consistency"])
            row[kd] = {**measure(z1, z2), **_design_info(inf)}
            if keep_fields:
                fields[(int(k), kd)] = (z1, z2)
            if kd in P["quad_kinds"]:
                quad_fields[(f"k{k}", kd)] = (z1, z2)
            if map_only is not None:  # the same problem, the source field fixed, no alignment on the target
                zm, infm = design_consistent_field(pr, z1_ind, smoothness=P["smoothness"], align=0.0)
                row_m[kd] = {**measure(z1_ind, zm), **_design_info(infm)}
                if keep_fields:
                    fields[(int(k), "map_only", kd)] = (z1_ind, zm)
        out[f"k{k}"] = {**row, "no_map": no_map}
        # how far C is from orthogonal: a k that cuts a cluster of close eigenvalues leaves a nearly
        # zero singular value (the cluster's other half is outside the basis), and C~ then amplifies
        sv = np.linalg.svd(C, compute_uv=False)
        out.setdefault("map", {})[f"k{k}"] = {"C_sigma_min": float(sv.min()), "C_sigma_max": float(sv.max())}
        if map_only is not None:
            map_only[f"k{k}"] = {**row_m, "no_map": no_map}
    z1, z2 = z1_ind, z2_ind
    zp, _ = _pushforward(fr1, z1, fr2, gt)
    base_fields = {"independent": (z1, z2), **({"copy": (z1, z1.copy())} if gt["same_triangulation"] else {}),
                   "pushforward": (z1, np.where(np.abs(zp) > 0, zp, z2))}  # invalid faces: the independent field
    fields.update(base_fields)
    out["baselines"] = {n: no_map if n == "independent" else measure(*zz) for n, zz in base_fields.items()}
    if P["quad_size"] > 0:
        quad_fields.update({("baselines", n): base_fields[n] for n in ("independent", "pushforward")})
        qs, qm, side = {}, {}, {}

        def quad_side(i, mesh, z):  # a field shared by two settings (the baselines' source) once
            if (i, id(z)) not in side:
                side[(i, id(z))] = quad_mesh_of(mesh, z, P["quad_size"])
            return side[(i, id(z))]

        for (group, name), (a, b) in quad_fields.items():
            r = quad_meshes_pair(mesh_1, mesh_2, a, b, gt, P["quad_size"],
                                 sides=(quad_side(0, mesh_1, a), quad_side(1, mesh_2, b)))
            qs.setdefault(group, {})[name] = _finite_or_none(r["stats"])
            qm[(group, name)] = r["meshes"]
        out["quads"] = {"size": P["quad_size"], **qs}
        if keep_fields:
            fields["quad_meshes"] = qm
    if map_only is not None:
        map_only["baselines"] = {"independent": no_map}
        out["map_only"] = map_only
    out["seconds"] = time.perf_counter() - t0
    if keep_fields:
        out["fields"] = fields
    return out


def _design_info(info: dict) -> dict:
    """A design's consistency energy, CG iterations, kept Approach-B ranks and largest ``"ext"`` gain."""
    out = {"consistency_energy": info["consistency"], "cg_iterations": info["cg_iterations"],
           **{key: int(info[key]) for key in ("rank_1", "rank_2") if key in info}}
    if "gain_max" in info:
        out["gain_max"] = float(info["gain_max"])
    return out


def summarize_pairs(per_pair: dict, ks, kinds=JOINT_KINDS, measure: str = "angle_regular_deg") -> dict:
    """Across pairs, per k and kind: mean, sd, min, max of ``measure``, and the pairs it beats ``"std"`` on.

    ``n_better`` of ``n_pairs``, for each extended kind.

    Also ``cells``: ``{kind: {"<pair>|k<k>": value}}`` (every pair and k, for the claims ledger) and
    ``pooled``: ``{kind: mean, std, min, max over all cells}``.
    """
    out = {"measure": measure, "cells": {kd: {} for kd in kinds}}
    for k in ks:
        row = {}
        for kd in kinds:
            v = np.array([p[f"k{k}"][kd][measure] for p in per_pair.values()], dtype=float)
            row[kd] = _stats(v, finite=False)
            if kd != "std":
                s = np.array([p[f"k{k}"]["std"][measure] for p in per_pair.values()], dtype=float)
                row[kd].update(n_better=int(np.sum(v < s)), n_pairs=int(v.size))
            out["cells"][kd].update({f"{name}|k{k}": float(p[f"k{k}"][kd][measure]) for name, p in per_pair.items()})
        out[f"k{k}"] = row
    out["pooled"] = {kd: {**_stats(np.array(list(c.values())), finite=False), "n_cells": len(c)}
                     for kd, c in out["cells"].items()}
    return out


def summarize_quads(per_pair: dict) -> dict:
    """Across pairs, per group (``"k<k>"`` or ``"baselines"``) and design: summaries of the quad meshes.

    Mean, sd, min and max of the irregular-vertex match fractions (all, and at low-curvature places:
    ``..._low_...``), the quad count and quad fraction (source and target meshes pooled), the totals of
    open and non-manifold edges; ``n_better`` / ``n_better_low``: pairs on which an extended design pairs
    more irregular vertices than ``"std"`` at the same k; ``cells`` / ``cells_low``:
    ``{design: {"<pair>|<group>": fraction}}`` for the ledger, ``pooled`` / ``pooled_low`` over them.
    """
    groups, cells, cells_low = {}, {}, {}
    first = next(iter(per_pair.values()))["quads"]
    F, FL = "irregular_match_fraction", "irregular_low_match_fraction"
    for grp, row in first.items():
        if grp == "size":
            continue
        groups[grp] = {}
        for name in row:
            qs = [p["quads"][grp][name] for p in per_pair.values()]
            frac = np.array([np.nan if q[F] is None else q[F] for q in qs], dtype=float)
            frac_low = np.array([np.nan if q.get(FL) is None else q[FL] for q in qs], dtype=float)
            sides = [q[s] for q in qs for s in ("source", "target")]  # both meshes of every pair
            r = {F: _stats(frac), FL: _stats(frac_low), **{key: _stats([x[key] for x in sides])
                                                             for key in ("n_quads", "quad_fraction")},
                 **{f"{key}_total": int(sum(x[key] for x in sides))
                    for key in ("n_boundary_edges", "n_nonmanifold_edges")}}
            if grp != "baselines" and name != "std" and "std" in row:
                for key, v, out in ((F, frac, "n_better"), (FL, frac_low, "n_better_low")):
                    s_ = np.array([p["quads"][grp]["std"][key] for p in per_pair.values()], dtype=float)
                    r[out] = int(np.sum(v > s_))
                r["n_pairs"] = int(frac.size)
            groups[grp][name] = r
            for pn, a, b in zip(per_pair, frac, frac_low):
                cells.setdefault(name, {})[f"{pn}|{grp}"] = float(a)
                cells_low.setdefault(name, {})[f"{pn}|{grp}"] = float(b)
    pooled, pooled_low = ({n: _stats(np.array(list(c.values()))) for n, c in cc.items()} for cc in (cells, cells_low))
    return {"size": first["size"], "groups": groups, "cells": cells, "pooled": pooled, "cells_low": cells_low,
            "pooled_low": pooled_low}


def _stats(v: np.ndarray, finite: bool = True) -> dict:
    """Mean, sd, min, max (over the finite values with ``finite``; None when there are none)."""
    v = np.asarray(v, dtype=float)
    if finite:
        v = v[np.isfinite(v)]
    if v.size == 0:
        return {"mean": None, "std": None, "min": None, "max": None}
    return {"mean": float(np.mean(v)), "std": float(np.std(v)), "min": float(np.min(v)), "max": float(np.max(v))}


def figure14_joint_study(dataset: str, pairs, ks, *, params=None, shown: int = 0, verbose: bool = True,
                         workers: int | None = None) -> dict:
    """:func:`figure14_joint_pair` on every pair ``(id_1, id_2)`` of ``dataset`` and every k.

    Returns ``{"pairs": {"<id_1>-><id_2>": per-pair results}, "summary": {measure: summarize_pairs},
    "shown": (mesh_1, mesh_2, fields) of pair number ``shown``, "kinds": ...}``. ``workers``:
    processes computing the pairs (:func:`prodmaps.experiments.shared.parallel.map_tasks`; the same
    numbers for any number).
    """
    pairs = [tuple(p) for p in pairs]
    tasks = [(dataset, a, b, list(ks), params, i == shown) for i, (a, b) in enumerate(pairs)]
    per, shown_out = {}, None
    for i, ((a, b), r) in enumerate(zip(pairs, map_tasks(_joint_pair_task, tasks, workers=workers))):
        if i == shown:
            shown_out = (datasets.load_shape(dataset, a), datasets.load_shape(dataset, b), r.pop("fields"))
        per[f"{a}->{b}"] = r
        if verbose:
            k0 = f"k{ks[0]}"
            print(f"{a} -> {b} ({r['seconds']:.0f} s), {k0} regular-face angle: " + ", ".join(
                f"{kd} {r[k0][kd]['angle_regular_deg']:.2f}°" for kd in JOINT_KINDS)
                + f", independent {r['baselines']['independent']['angle_regular_deg']:.2f}°")
    kinds = JOINT_KINDS + ("no_map",)
    measures = ("angle_regular_deg", "angle_mean_deg", "sing_recall")
    summary = {m: summarize_pairs(per, ks, kinds, measure=m) for m in measures}
    if all("quads" in p for p in per.values()):
        summary["quads"] = summarize_quads(per)
    if all("map_only" in p for p in per.values()):
        mo = {n: p["map_only"] for n, p in per.items()}
        summary["map_only"] = {m: summarize_pairs(mo, ks, kinds, measure=m) for m in measures}
    return {"pairs": per, "summary": summary, "shown": shown_out, "kinds": list(JOINT_KINDS)}


def _joint_pair_task(dataset: str, a: str, b: str, ks, params, keep_fields: bool) -> dict:
    """:func:`figure14_joint_pair` of the pair ``a -> b`` of ``dataset`` (one task of the study)."""
    gt = surface_ground_truth(dataset, a, b)
    m1, m2 = datasets.load_shape(dataset, a), datasets.load_shape(dataset, b)
    return figure14_joint_pair(m1, m2, gt, ks, params=params, keep_fields=keep_fields)


PAIRS = {
    "anny_humans": {
        "smoke": [["anny_000", "anny_003"], ["anny_000", "anny_013_remesh_iso"]],
        "paper": [["anny_000", "anny_003"], ["anny_000", "anny_009"], ["anny_010", "anny_016"],  # intra subject
                  ["anny_000", "anny_013"], ["anny_020", "anny_041"],  # inter subject
                  ["anny_000", "anny_013_remesh_iso"]],  # remeshed target (surface ground truth)
    },
    "faust": {
        "smoke": [["tr_reg_000", "tr_reg_001"]],
        "paper": [["tr_reg_000", "tr_reg_001"], ["tr_reg_000", "tr_reg_002"], ["tr_reg_000", "tr_reg_003"],
                  ["tr_reg_000", "tr_reg_010"], ["tr_reg_000", "tr_reg_025"], ["tr_reg_010", "tr_reg_031"]],
    },
}
"""The Figure 14 pairs per dataset and profile (``[id_1, id_2]``; shape 2 may be a remeshed variant)."""


SETTINGS = {"joint": "joint design (the paper's setting: alignment on both shapes)",
            "map_only": "map only (the source's no-map field fixed, no alignment on the target)"}
"""The two Figure 14 settings and their summaries' place in a study (``summary`` / ``summary["map_only"]``)."""


def setting_summary(study: dict, setting: str) -> dict:
    """The per-measure summaries of one setting (``"joint"`` or ``"map_only"``) of a study."""
    return study["summary"] if setting == "joint" else study["summary"][setting]


def verdict_table(study: dict, ks, measures=("angle_regular_deg", "angle_mean_deg")) -> list[dict]:
    """Per setting, measure and k: on how many pairs ``C~``, the default, the oracle and no map beat ``C``.

    ``C~`` is ``"ext"``, the oracle ``"p2p"``; beating is a lower angle; with their means. The ledger's
    Figure 14 verdicts are judged on this (a claim is judged only where the oracle beats ``C``).
    """
    rows = []
    for setting in SETTINGS:
        if setting != "joint" and setting not in study["summary"]:
            continue
        S = setting_summary(study, setting)
        for m in measures:
            for k in ks:
                r = S[m][f"k{k}"]
                rows.append({"setting": setting, "measure": m, "k": int(k), "n_pairs": r["ext"]["n_pairs"],
                             **{f"{kd}_beats_std": r[kd]["n_better"] for kd in ("ext", "default", "p2p", "no_map")},
                             **{f"{kd}_mean": r[kd]["mean"] for kd in ("std", "ext", "default", "p2p", "no_map")}})
    return rows


def verdict_lines(study: dict, ks) -> list[str]:
    """Text lines of :func:`verdict_table` and of the instability diagnostics per pair.

    The table: per setting, measure and k, the pairs on which C~, the oracle, the default transfer and
    no map beat C; the diagnostics: smallest singular value of C, largest transfer gain of C~'s kept
    source directions.
    """
    lines = ["per setting, measure and k: pairs on which each design beats C (lower angle to the ground-truth "
             "push-forward)"]
    for r in verdict_table(study, ks):
        n = r["n_pairs"]
        lines.append(f"{r['setting']:>8} {r['measure']:<17} k = {r['k']:>2}: C~ {r['ext_beats_std']}/{n}, "
                     f"oracle {r['p2p_beats_std']}/{n}, default {r['default_beats_std']}/{n}, "
                     f"no map {r['no_map_beats_std']}/{n}; means C {r['std_mean']:.2f}, C~ {r['ext_mean']:.2f}, "
                     f"oracle {r['p2p_mean']:.2f}, no map {r['no_map_mean']:.2f}")
    lines.append("C~ instability: smallest singular value of the ground-truth C and the largest transfer gain of a "
                 "kept source direction (||B2 C~ q||_A for unit q; 1 = products preserved)")
    for name, p in study["pairs"].items():
        lines.append(f"  {name}: " + "; ".join(
            f"k = {k}: σ_min(C) {p['map'][f'k{k}']['C_sigma_min']:.3f}, gain {p[f'k{k}']['ext']['gain_max']:.1f}"
            for k in ks))
    return lines


def study_lines(study: dict, ks) -> list[str]:
    """Text lines of a :func:`figure14_joint_study`: summary per setting and k, baselines, quad meshes per pair."""
    lines = []
    for setting, title in SETTINGS.items():
        if setting != "joint" and setting not in study["summary"]:
            continue
        lines.append(f"== {title}")
        for m, what in (("angle_regular_deg", "regular faces"), ("angle_mean_deg", "all faces")):
            S = setting_summary(study, setting)[m]
            lines.append(f"angle to the reference on {what} (degrees), over {len(study['pairs'])} pairs: "
                         "mean ± sd [min, max] (oracle = p2p, the exact point-map transfer; no_map = each "
                         "shape's own field)")
            for k in ks:
                r = S[f"k{k}"]
                lines.append(f"k = {k}: " + "; ".join(
                    f"{kd} {r[kd]['mean']:.2f} ± {r[kd]['std']:.2f} [{r[kd]['min']:.2f}, {r[kd]['max']:.2f}]"
                    + (f" (beats std on {r[kd]['n_better']}/{r[kd]['n_pairs']})" if kd != "std" else "")
                    for kd in [*study["kinds"], "no_map"]))
    ranks = {}
    for p in study["pairs"].values():
        for k in ks:
            x = p[f"k{k}"]["ext"]
            ranks.setdefault(k, set()).add((x.get("rank_1"), x.get("rank_2")))
    lines.append("Approach-B ranks kept by C~ (source, target) per k: " + "; ".join(
        f"k = {k}: " + ", ".join(f"{a}/{b}" for a, b in sorted(v, key=str)) for k, v in ranks.items()))
    lines.append("baselines per pair (regular angle, alignment on shape 2, singularity recall):")
    for name, p in study["pairs"].items():
        lines.append(f"  {name} " + ", ".join(
            f"{n} ({m['angle_regular_deg']:.2f}, {m['align_2_deg']:.2f}, {m['sing_recall']:.2f})"
            for n, m in p["baselines"].items()))
    Q = study["summary"].get("quads")
    if Q:
        lines.append("quad meshes over all pairs (mean ± sd): fraction of irregular vertices paired through the "
                     "ground truth (all / at low-curvature places), quads per mesh, quad fraction of the faces, "
                     "open edges (0: watertight)")
        for grp, row in Q["groups"].items():
            lines.append(f"  {grp}: " + "; ".join(
                f"{n} {r['irregular_match_fraction']['mean']:.2f} ± {r['irregular_match_fraction']['std']:.2f} / "
                f"{r['irregular_low_match_fraction']['mean']:.2f} ± {r['irregular_low_match_fraction']['std']:.2f}"
                + (f" (beats std on {r['n_better_low']}/{r['n_pairs']})" if "n_better_low" in r else "")
                + f", {r['n_quads']['mean']:.0f} quads, {r['quad_fraction']['mean']:.3f}, "
                  f"{r['n_boundary_edges_total']} open"
                for n, r in row.items()))
    return lines
