"""Quad-dominant meshes and their transport through point maps (Figure 14, second section).

This is *not* the paper's Figure 14 pipeline (which designs consistent cross fields through the
functional map and quadrangulates each surface along its own field, never using a point map; see
:mod:`prodmaps.fields`). It answers a simpler question with the same ``k = 5`` map: how well does a
point map recovered from ``C`` carry a coarse quad mesh of the source onto the target? Conversions
(:func:`prodmaps.p2p.from_fmap`): ``"std"`` [OBCS*12], ``"extended"`` (Section 4.4: squared heat
kernels on the mesh from 200 eigenpairs, the experiments store's big basis, fitted in the extended
basis of the map's ``k + 1`` functions) and ``"extended_closed_form"`` (``point="closed_form"``: the
kernel from the map's own eigenpairs).

Steps: :func:`coarse_remesh` (pymeshlab quadric decimation, then isotropic remeshing),
:func:`pair_triangles` (greedy pairing of adjacent triangles into quads), snapping the quad vertices
to source vertices, then each quad vertex goes to ``p2p_12[s_i]``; the reference is the ground-truth
transfer. :func:`quad_measures` counts flipped and degenerate quads and corner-angle deviations.
"""

from __future__ import annotations

import time

import numpy as np
from scipy.spatial import cKDTree

from ... import datasets, geodesics
from ...fields.frames import polygon_corner_degrees
from ...mesh import Mesh
from ...p2p import DEFAULT_KERNEL_EIG, fmap_from_p2p, from_fmap
from ..fig12_13_p2p import CONVERSIONS
from ..shared.store import ShapeStore

__all__ = ["coarse_remesh", "pair_triangles", "quad_measures", "polygon_soup",
           "point_map_quad_transport"]


def coarse_remesh(mesh: Mesh, edge_length: float, target_faces: int = 800, iterations: int = 5,
                  max_surface_distance: float = 0.01) -> Mesh:
    """Coarse, fairly regular triangle mesh of ``mesh`` with pymeshlab (GPL; imported here only).

    Quadric edge-collapse decimation to ``target_faces`` faces (topology and normals preserved),
    then isotropic explicit remeshing towards edges of ``edge_length`` (mesh units), ``iterations``
    rounds, vertices kept within ``max_surface_distance`` of the surface (without the check the arms
    and legs shrink away).
    """
    import pymeshlab

    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(np.asarray(mesh.vertices, dtype=np.float64), np.asarray(mesh.faces, dtype=np.int32)))
    ms.meshing_decimation_quadric_edge_collapse(targetfacenum=int(target_faces), preservetopology=True,
                                                preservenormal=True)
    ms.meshing_isotropic_explicit_remeshing(iterations=int(iterations), checksurfdist=True,
                                            targetlen=pymeshlab.PureValue(float(edge_length)),
                                            maxsurfdist=pymeshlab.PureValue(float(max_surface_distance)))
    out = ms.current_mesh()
    return Mesh(out.vertex_matrix(), out.face_matrix().astype(np.int64), name=mesh.name + "_coarse")


def pair_triangles(V: np.ndarray, F: np.ndarray, max_deviation: float = 40.0, max_dihedral: float = 40.0):
    """Greedy pairing of adjacent triangles into quads (a quad-dominant mesh).

    Candidates: every interior edge ``(u, v)`` shared by faces ``(a, u, v)`` and ``(b, v, u)`` gives the
    quad ``(a, u, b, v)``, consistently oriented; score = max |corner angle - 90°|, kept below
    ``max_deviation`` with a dihedral angle below ``max_dihedral``. Rounds of *mutual best* choices,
    vectorised per round. Returns ``(quads (q, 4), leftover triangles (t, 3))``.
    """
    m = F.shape[0]
    half = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])  # (3m, 2) directed edges u->v
    opp = np.concatenate([F[:, 2], F[:, 0], F[:, 1]])  # opposite vertex of each half-edge
    face = np.tile(np.arange(m), 3)
    key = np.minimum(half[:, 0], half[:, 1]) * V.shape[0] + np.maximum(half[:, 0], half[:, 1])
    order = np.argsort(key, kind="stable")
    ks = key[order]
    same = np.flatnonzero(ks[1:] == ks[:-1])  # consecutive half-edges of one edge
    h1, h2 = order[same], order[same + 1]  # (E,) the two half-edges
    fa, fb = face[h1], face[h2]
    quads = np.stack([opp[h1], half[h1, 0], opp[h2], half[h1, 1]], axis=1)  # (E, 4) a, u, b, v; face a: a -> u -> v
    score = np.abs(polygon_corner_degrees(V[quads]) - 90.0).max(axis=1)  # (E,)
    n = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    dihedral = np.degrees(np.arccos(np.clip(np.einsum("ed,ed->e", n[fa], n[fb]), -1, 1)))
    alive = (score < max_deviation) & (dihedral < max_dihedral) & (fa != fb)
    paired = np.zeros(m, dtype=bool)
    chosen = []
    while alive.any():
        idx = np.flatnonzero(alive)
        best = np.full(m, np.inf)
        np.minimum.at(best, fa[idx], score[idx])
        np.minimum.at(best, fb[idx], score[idx])
        ok = idx[(score[idx] == best[fa[idx]]) & (score[idx] == best[fb[idx]])]  # best of both faces
        cnt = np.bincount(np.concatenate([fa[ok], fb[ok]]), minlength=m)
        keep = (cnt[fa[ok]] == 1) & (cnt[fb[ok]] == 1)  # drop edges sharing a face in this round
        if not keep.any():  # only ties left: take the lowest index
            keep = np.arange(ok.size) == 0
        ok = ok[keep]
        chosen.append(ok)
        paired[fa[ok]] = paired[fb[ok]] = True
        alive &= ~(paired[fa] | paired[fb])
    chosen = np.concatenate(chosen) if chosen else np.zeros(0, dtype=np.int64)
    return quads[chosen], F[~paired]


def quad_measures(target_vertices: np.ndarray, tv: np.ndarray, V_ref: np.ndarray, quads: np.ndarray):
    """Flip / degeneracy / angle measures of quads whose corners are the target vertices ``tv`` ``(m,)``.

    ``V_ref`` ``(m, 3)``: the reference (ground-truth) positions. A quad is *degenerate* if two corners
    land on one target vertex or its area is below 10 % of the reference quad's, *flipped* if its
    normal (cross product of the diagonals) opposes the reference's. Returns
    ``(measures dict, flipped (q,) bool, degenerate (q,) bool)``.
    """
    Q, R = target_vertices[tv][quads], V_ref[quads]  # (q, 4, 3)
    nq = np.cross(Q[:, 2] - Q[:, 0], Q[:, 3] - Q[:, 1])  # 2 x vector area (diagonals)
    nr = np.cross(R[:, 2] - R[:, 0], R[:, 3] - R[:, 1])
    aq, ar = 0.5 * np.linalg.norm(nq, axis=1), 0.5 * np.linalg.norm(nr, axis=1)
    ids = tv[quads]  # (q, 4)
    i, j = np.triu_indices(4, 1)
    collapsed = (ids[:, i] == ids[:, j]).any(axis=1)
    degenerate = collapsed | (aq < 0.1 * ar)
    flipped = (np.einsum("qd,qd->q", nq, nr) < 0) & ~degenerate
    ang = polygon_corner_degrees(Q)
    ok = ~collapsed
    res = {"flipped": int(flipped.sum()), "degenerate": int(degenerate.sum()),
           "angle_dev_mean": float(np.abs(ang[ok] - 90).mean()) if ok.any() else 0.0,
           "angle_diff_to_truth": float(np.abs(ang[ok] - polygon_corner_degrees(R)[ok]).mean()) if ok.any() else 0.0}
    return res, flipped, degenerate


def polygon_soup(Vq: np.ndarray, quads: np.ndarray, tris: np.ndarray, values: np.ndarray):
    """Triangles with per-polygon flat colours for rendering: quads split along (0, 2), vertices duplicated.

    Returns ``(vertices, faces, per-vertex values)``.
    """
    T = np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]], tris])  # (2q + t, 3)
    vals = np.concatenate([values[:len(quads)], values[:len(quads)], values[len(quads):]])
    Vd = Vq[T].reshape(-1, 3)
    return Vd, np.arange(Vd.shape[0]).reshape(-1, 3), np.repeat(vals, 3)


def point_map_quad_transport(dataset: str, source_id: str, target_id: str, ks, *, edge_length: float = 0.06,
                             target_faces: int = 800, verbose: bool = True) -> dict:
    """Transport a coarse quad-dominant mesh of the source to the target through recovered point maps.

    The point maps come from the ground-truth ``C_21`` of size ``(k+1, k+1)``, by every conversion of
    :data:`prodmaps.experiments.fig12_13_p2p.CONVERSIONS` (module doc).

    Sending source points to the target needs, for each *source* vertex, a target vertex ``p2p_12``
    ``(n1,)``: ``from_fmap(C_21, basis_2, basis_1)`` with ``C_21 = Φ1ᵀ A1 Φ2[p2p_12]`` (the map from
    target to source). Returns ``{"results": {quad_mesh, measures}, ...}`` with the placed vertices at
    ``ks[0]`` for rendering.
    """
    mesh_1, mesh_2 = datasets.load_shape(dataset, source_id), datasets.load_shape(dataset, target_id)
    coarse = coarse_remesh(mesh_1, edge_length, target_faces)
    quads, tris = pair_triangles(coarse.vertices, coarse.faces)
    dist_snap, snap = cKDTree(mesh_1.vertices).query(coarse.vertices)  # coarse vertex -> nearest source vertex
    src_v = snap.astype(np.int64)  # (m,) quad vertices as source vertices
    if verbose:
        print(f"coarse remesh: {coarse.n_vertices} vertices, {coarse.faces.shape[0]} triangles -> {quads.shape[0]} "
              f"quads + {tris.shape[0]} triangles; snapping {dist_snap.mean() * 1000:.1f} mm mean")
    p2p_12_true = datasets.ground_truth(dataset, target_id, source_id)  # (n1,) source vertex -> target vertex
    # the big bases: C uses their first k + 1 columns, the extended conversion's heat kernel all of them
    store = ShapeStore(dataset, max(max(ks) + 1, DEFAULT_KERNEL_EIG))
    B1, B2 = store.basis(source_id), store.basis(target_id)
    V_true = mesh_2.vertices[p2p_12_true[src_v]]  # ground-truth transfer of the quad vertices
    measures = {side: {"angle_dev_mean": float(np.abs(polygon_corner_degrees(P) - 90).mean())}
                for side, P in (("source", mesh_1.vertices[src_v][quads]), ("truth", V_true[quads]))}
    placed = {}
    for kk in ks:
        b1, b2 = B1.truncate(kk + 1), B2.truncate(kk + 1)
        C_21 = fmap_from_p2p(p2p_12_true, b2, b1)  # (k1, k2): target -> source, ground truth
        for method in CONVERSIONS:
            t0 = time.perf_counter()
            tv = from_fmap(C_21, B2, B1, vertices=src_v, **CONVERSIONS[method])  # target vertex of each quad vertex
            verr = geodesics.map_error(mesh_2, tv, p2p_12_true[src_v])  # (m,) on the target
            m_, _, _ = quad_measures(mesh_2.vertices, tv, V_true, quads)
            m_.update({"vertex_error_mean": float(verr.mean()), "vertex_error_median": float(np.median(verr)),
                       "vertex_error_max": float(verr.max()), "distinct_target_vertices": int(np.unique(tv).size),
                       "seconds": time.perf_counter() - t0})
            measures.setdefault(f"k{kk}", {})[method] = m_
            if kk == ks[0]:
                placed[method] = mesh_2.vertices[tv]
    results = {
        "pair": f"{source_id}->{target_id}",
        "quad_mesh": {"n_vertices": int(src_v.size), "n_quads": int(quads.shape[0]), "n_triangles": int(tris.shape[0]),
                      "snap_mean_m": float(dist_snap.mean()), "snap_max_m": float(dist_snap.max())},
        "error_definition": "vertex error: geodesic distance on the target between the transported and the "
                            "ground-truth position / sqrt(area of the target) (heat method); angles in degrees",
        "measures": measures,
    }
    return {"results": results, "meshes": (mesh_1, mesh_2), "quads": quads, "tris": tris, "src_v": src_v,
            "V_true": V_true, "placed": placed}
