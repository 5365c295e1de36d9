"""Quad meshes from a cross field: a seamless parametrisation and its integer lattice (partial).

Pipeline (on libigl's building blocks and a scipy least-squares solve):

1. the four directions of the cross in every face (``d_0``, ``d_1 = d_0`` rotated by 90°), combed
   with ``igl.comb_cross_field`` and their integer mismatch across every edge
   (``igl.cross_field_mismatch``, a multiple of 90°);
2. a cut graph through the singularities (``igl.cut_mesh_from_singularities``) and the cut mesh
   (``igl.cut_mesh``, disk-like: the seam vertices are duplicated);
3. :func:`seamless_parametrization`: ``(u, v)`` per cut-mesh vertex minimising
   ``Σ_f A_f (|∇u - d_0/h|² + |∇v - d_1/h|²)`` (``h`` the target quad size) subject to the
   transition across every seam edge, ``p_g = R^{-r} p_f + t`` with ``R`` the rotation by 90°
   and ``r`` the mismatch (soft constraints of weight ``weight``, one sparse normal-equation
   solve). With ``integer=True`` the translations ``t`` of the first solve are rounded to
   integers and the singular vertices to integer points, and the problem is solved again with
   those as constraints: then the integer grid lines match across the seams;
4. :func:`lattice_quads` — **partial extraction**: the integer points of the parametrisation
   (one 3D point per lattice point, the seam copies merged) and the quads of four lattice
   neighbours ``(i, j), (i+1, j), (i+1, j+1), (i, j+1)`` found *in the same chart*. Quads that
   straddle a seam are not traced (that needs walking the grid lines across the transitions), so
   the result has holes along the seams and near the singularities: it is not watertight.
   :func:`quad_mesh_stats` reports the quad count, valences, irregular vertices and boundary edges.

Conventions: faces ``(m, 3)`` of a closed manifold mesh; ``z`` a unit 4-power field per face
(:mod:`prodmaps.fields.crossfield`).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ..mesh import Mesh
from .crossfield import field_vectors
from .frames import mesh_frames

__all__ = ["seamless_parametrization", "lattice_quads", "quad_mesh_stats"]

_ROT = np.array([[[1, 0], [0, 1]], [[0, -1], [1, 0]], [[-1, 0], [0, -1]], [[0, 1], [-1, 0]]], dtype=np.float64)


def _seam_edges(F, cuts, mismatch):
    import igl

    TT, TTi = igl.triangle_triangle_adjacency(np.ascontiguousarray(F, dtype=np.int64))
    fs, es = np.nonzero(cuts)
    g, eg = TT[fs, es], TTi[fs, es]
    keep = (g >= 0) & (fs < g)
    return fs[keep], es[keep], g[keep], eg[keep], np.asarray(mismatch)[fs[keep], es[keep]] % 4


def seamless_parametrization(mesh: Mesh, z: np.ndarray, h: float, *, integer: bool = True,
                             weight: float = 1e3) -> dict:
    """Seamless ``(u, v)`` parametrisation of a closed mesh along the cross field ``z`` (module doc).

    ``h`` is the target quad edge length (mesh units). Returns a dict with ``uv`` ``(nc, 2)``,
    the cut mesh ``Vc`` ``(nc, 3)``, ``Fc`` ``(m, 3)`` (same face order as the mesh), ``I``
    ``(nc,)`` (the mesh vertex of each cut vertex), ``singular`` (mesh vertex ids), ``n_seam_edges``,
    ``n_flipped`` (faces with a negative ``uv`` area), ``transition_error`` (largest violation of a
    seam transition) and ``integer_error`` (largest distance of a translation or singular point
    from the integers; ~0 when ``integer``).
    """
    import igl

    V = np.ascontiguousarray(mesh.vertices, dtype=np.float64)
    F = np.ascontiguousarray(mesh.faces, dtype=np.int64)
    if not (np.isfinite(h) and h > 0):
        raise ValueError(f"h (quad size) must be > 0, got {h!r}")
    fr = mesh_frames(mesh)
    d = field_vectors(np.asarray(z), fr, 4)
    P1, P2 = igl.comb_cross_field(V, F, np.ascontiguousarray(d[:, 0]), np.ascontiguousarray(d[:, 1]))
    mm = igl.cross_field_mismatch(V, F, P1, P2, True)
    is_sing, _ = igl.find_cross_field_singularities(V, F, mm)
    cuts = igl.cut_mesh_from_singularities(V, F, mm)
    Vc, Fc, I = igl.cut_mesh(V, F, cuts)
    m, nc = F.shape[0], Vc.shape[0]
    G = igl.grad(Vc, Fc).tocsr()  # (3m, nc): x, y, z blocks
    w = np.sqrt(0.5 * igl.doublearea(Vc, Fc).ravel())
    Z = sp.csr_matrix((m, nc))
    blocks, rhs = [], []
    for c in range(3):
        Gc = sp.diags(w) @ G[c * m:(c + 1) * m]
        blocks += [sp.hstack([Gc, Z]), sp.hstack([Z, Gc])]
        rhs += [w * P1[:, c] / h, w * P2[:, c] / h]
    fs, es, g, eg, r = _seam_edges(F, cuts, mm)
    R = _ROT[(-r) % 4]  # (ne, 2, 2)
    # the two ends of each seam edge: corner e, e+1 of f are corners eg+1, eg of g
    ends = [(Fc[fs, es], Fc[g, (eg + 1) % 3]), (Fc[fs, (es + 1) % 3], Fc[g, eg])]
    ne = fs.size

    def transition_rows():
        """Rows of ``p_g(x) - R p_f(x)`` (2 per end and edge) as a sparse matrix ``(4 ne, 2 nc)``."""
        rr, cc, vv = [], [], []
        for k, (xf, xg) in enumerate(ends):
            for i in range(2):
                row = np.arange(ne) + (2 * k + i) * ne
                rr.append(row)
                cc.append(xg + i * nc)
                vv.append(np.ones(ne))
                for j in range(2):
                    rr.append(row)
                    cc.append(xf + j * nc)
                    vv.append(-R[:, i, j])
        return sp.csr_matrix((np.concatenate(vv), (np.concatenate(rr), np.concatenate(cc))), shape=(4 * ne, 2 * nc))

    T = transition_rows()
    # first solve: the translation of each seam edge free (difference of its two ends' rows)
    D = (T[:2 * ne] - T[2 * ne:]) if ne else sp.csr_matrix((0, 2 * nc))
    pin = sp.csr_matrix(([1.0, 1.0], ([0, 1], [0, nc])), shape=(2, 2 * nc))

    def solve(A, b):
        return spla.spsolve((A.T @ A).tocsc(), A.T @ b)

    A0 = sp.vstack(blocks + [weight * D, weight * pin]).tocsr()
    x = solve(A0, np.concatenate(rhs + [np.zeros(D.shape[0]), np.zeros(2)]))
    sing = np.flatnonzero(np.asarray(is_sing).ravel())
    t = (T[:2 * ne] @ x) if ne else np.zeros(0)  # (2 ne,) translations read at the first end
    int_err = 0.0
    if integer:
        # singular vertices at integer points first (one cut copy each), translations still free
        first = np.full(V.shape[0], -1)
        first[I[::-1]] = np.arange(nc)[::-1]
        sc = first[sing]
        S = sp.csr_matrix((np.ones(2 * sc.size), (np.arange(2 * sc.size), np.concatenate([sc, sc + nc]))),
                          shape=(2 * sc.size, 2 * nc))
        s_target = np.round(np.concatenate([x[sc], x[sc + nc]]))
        p0 = np.round(x[[0, nc]])
        A1 = sp.vstack(blocks + [weight * D, weight * S, weight * pin]).tocsr()
        x = solve(A1, np.concatenate(rhs + [np.zeros(D.shape[0]), weight * s_target, weight * p0]))
        # then the translations rounded to integers and imposed
        tr = np.round(T[:2 * ne] @ x) if ne else np.zeros(0)
        A2 = sp.vstack(blocks + [weight * T, weight * S, weight * pin]).tocsr()
        x = solve(A2, np.concatenate(rhs + [weight * np.concatenate([tr, tr]), weight * s_target, weight * p0]))
        t = T @ x
        int_err = float(max(np.abs(t - np.concatenate([tr, tr])).max(initial=0.0),
                            np.abs(S @ x - s_target).max(initial=0.0)))
        trans_err = float(np.abs(t[:2 * ne] - t[2 * ne:]).max(initial=0.0))
    else:
        trans_err = float(np.abs(D @ x).max(initial=0.0))
        int_err = float(np.abs(t - np.round(t)).max(initial=0.0))
    uv = np.stack([x[:nc], x[nc:]], axis=1)
    U = uv[Fc]
    det = (U[:, 1, 0] - U[:, 0, 0]) * (U[:, 2, 1] - U[:, 0, 1]) - (U[:, 1, 1] - U[:, 0, 1]) * (U[:, 2, 0] - U[:, 0, 0])
    if ne:  # the distinct seam transitions p_g = R p_f + t (rounded t when integer)
        tt = np.stack([t[:ne], t[ne:2 * ne]], axis=1)
        keyt = np.concatenate([((-r) % 4)[:, None].astype(float), np.round(tt, 6)], axis=1)
        _, idx = np.unique(keyt, axis=0, return_index=True)
        trans_R, trans_t = R[idx], np.round(tt[idx]) if integer else tt[idx]
    else:
        trans_R, trans_t = np.zeros((0, 2, 2)), np.zeros((0, 2))
    return {"uv": uv, "Vc": Vc, "Fc": Fc, "I": np.asarray(I), "singular": sing, "n_seam_edges": int(ne),
            "transitions_R": trans_R, "transitions_t": trans_t,
            "n_flipped": int(np.sum(det <= 0)), "transition_error": trans_err, "integer_error": int_err, "h": h}


def lattice_quads(param: dict, *, merge_tol: float = 1e-6) -> dict:
    """Partial quad extraction from a :func:`seamless_parametrization` (see the module doc).

    Lattice points: every integer ``(i, j)`` inside the ``uv`` image of a non-flipped cut face,
    placed in 3D by the barycentric coordinates; copies closer than ``merge_tol·h`` (seam copies,
    points on shared edges) are merged. Quads: four lattice points ``(i, j) … (i, j+1)`` of one
    chart whose 3D corners are within ``3 h`` of each other. Returns ``{"V" (p, 3), "Q" (q, 4)}``
    (counter-clockwise in ``uv``).
    """
    uv, Vc, Fc, h = param["uv"], param["Vc"], param["Fc"], param["h"]
    U = uv[Fc]  # (m, 3, 2)
    lo, hi = np.ceil(U.min(axis=1)).astype(np.int64), np.floor(U.max(axis=1)).astype(np.int64)
    span = np.maximum(hi - lo + 1, 0)
    cnt = span[:, 0] * span[:, 1]
    f = np.repeat(np.arange(Fc.shape[0]), cnt)
    off = np.arange(cnt.sum()) - np.repeat(np.cumsum(cnt) - cnt, cnt)
    ij = lo[f] + np.stack([off % np.maximum(span[f, 0], 1), off // np.maximum(span[f, 0], 1)], axis=1)
    a, b, c = U[f, 0], U[f, 1], U[f, 2]
    e1, e2, p = b - a, c - a, ij - a
    det = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
    ok = det > 0
    l1 = np.where(ok, (p[:, 0] * e2[:, 1] - p[:, 1] * e2[:, 0]) / np.where(ok, det, 1), -1)
    l2 = np.where(ok, (e1[:, 0] * p[:, 1] - e1[:, 1] * p[:, 0]) / np.where(ok, det, 1), -1)
    eps = 1e-9
    inside = ok & (l1 >= -eps) & (l2 >= -eps) & (l1 + l2 <= 1 + eps)
    f, ij, l1, l2 = f[inside], ij[inside], l1[inside], l2[inside]
    X = (1 - l1 - l2)[:, None] * Vc[Fc[f, 0]] + l1[:, None] * Vc[Fc[f, 1]] + l2[:, None] * Vc[Fc[f, 2]]
    # merge copies by 3D position
    key = np.round(X / (merge_tol * h)).astype(np.int64)
    _, pid, inv = np.unique(key, axis=0, return_index=True, return_inverse=True)
    inv = inv.ravel()
    Vq = X[pid]
    # quads within a chart: look up (i+1, j), (i+1, j+1), (i, j+1) by uv key and check 3D proximity
    base = ij.min(axis=0)
    W = int(ij[:, 0].max() - base[0] + 2)
    k = (ij[:, 1] - base[1]) * W + (ij[:, 0] - base[0])
    order = np.argsort(k, kind="stable")
    ks = k[order]
    # the seam transitions (both ways): a grid neighbour across a seam is R q + t in the other chart
    trans = [(np.eye(2), np.zeros(2))]
    for Rm, tv in zip(param.get("transitions_R", []), param.get("transitions_t", [])):
        trans += [(Rm, tv), (Rm.T, -Rm.T @ tv)]

    def find(qij):
        """Index of a lattice point at ``qij`` (per row, in the row's chart) near ``X``, or -1."""
        out = np.full(qij.shape[0], -1)
        for Rm, tv in trans:
            todo = out < 0
            if not todo.any():
                break
            qq = np.rint(qij[todo] @ Rm.T + tv).astype(np.int64)
            q = (qq[:, 1] - base[1]) * W + (qq[:, 0] - base[0])
            inb = (qq[:, 0] >= base[0]) & (qq[:, 0] < base[0] + W - 1) & (qq[:, 1] >= base[1])
            pos = np.minimum(np.searchsorted(ks, q), ks.size - 1)
            hit = inb & (ks[pos] == q)
            j = np.where(hit, order[pos], -1)
            near = hit & (np.linalg.norm(X[np.maximum(j, 0)] - X[todo], axis=1) < 3 * h)
            sub = out[todo]
            sub[near] = j[near]
            out[todo] = sub
        return out

    corners = [find(ij + np.array(dv)) for dv in ((1, 0), (1, 1), (0, 1))]
    c1, c2, c3 = corners
    okq = (c1 >= 0) & (c2 >= 0) & (c3 >= 0)
    Q = np.stack([inv[okq.nonzero()[0]], inv[c1[okq]], inv[c2[okq]], inv[c3[okq]]], axis=1)
    Q = Q[np.all(np.diff(np.sort(Q, axis=1), axis=1) > 0, axis=1)]  # four distinct corners
    Q = np.unique(Q[np.lexsort(np.sort(Q, axis=1).T[::-1])], axis=0) if Q.size else Q
    if Q.size:  # one copy of each quad (the same quad found from two copies of a corner)
        _, first = np.unique(np.sort(Q, axis=1), axis=0, return_index=True)
        Q = Q[np.sort(first)]
    return {"V": Vq, "Q": Q.astype(np.int64)}


def quad_mesh_stats(V: np.ndarray, Q: np.ndarray) -> dict:
    """Counts of a quad mesh: quads, vertices used, boundary edges (0 = watertight), valence
    histogram of the interior vertices and the irregular ones (interior valence != 4)."""
    Q = np.asarray(Q, dtype=np.int64)
    if Q.size == 0:
        return {"n_quads": 0, "n_vertices": 0, "n_boundary_edges": 0, "n_irregular": 0, "valence": {},
                "irregular": np.zeros(0, np.int64)}
    E = np.stack([Q, np.roll(Q, -1, axis=1)], axis=2).reshape(-1, 2)
    Es = np.sort(E, axis=1)
    uniq, cnt = np.unique(Es, axis=0, return_counts=True)
    bnd = uniq[cnt == 1]
    used = np.unique(Q)
    val = np.bincount(uniq.ravel(), minlength=int(Q.max()) + 1)
    on_bnd = np.zeros(val.size, bool)
    on_bnd[bnd.ravel()] = True
    interior = used[~on_bnd[used]]
    irr = interior[val[interior] != 4]
    hist = {int(a): int(b) for a, b in zip(*np.unique(val[interior], return_counts=True))}
    return {"n_quads": int(Q.shape[0]), "n_vertices": int(used.size), "n_boundary_edges": int(bnd.shape[0]),
            "n_nonmanifold_edges": int(np.sum(cnt > 2)), "n_irregular": int(irr.size), "valence": hist,
            "irregular": irr}
