"""Quad meshes from a cross field: an integer-grid parametrisation and its quads.

Pipeline (libigl's building blocks, scipy solves, everything else vectorised numpy):

1. **Comb and cut.** The four directions of the cross in every face (``d_0``, ``d_1 = d_0``
   rotated by 90°) are combed with ``igl.comb_cross_field``; their integer mismatch across every
   edge (``igl.cross_field_mismatch``, a multiple of 90°) is zero except on a cut graph through
   the singularities (``igl.cut_mesh_from_singularities``); ``igl.cut_mesh`` duplicates the seam
   vertices (one copy per side).
2. **Seamless parametrisation** (:func:`seamless_parametrization`): ``(u, v)`` per cut-mesh vertex
   minimising ``Σ_f A_f (|∇u - d_0/h|² + |∇v - d_1/h|²)`` (``h`` the quad edge length) with the
   transition ``p_g = R^{-r} p_f + t`` across every seam edge (``R`` the rotation by 90°, ``r`` the
   mismatch, ``t`` constant along a seam *chain*, a path of the cut graph between two *nodes*:
   singular vertices and branch or end points of the cut graph).
3. **Integer rounding** (``integer=True``, after a first solve with free translations): the
   chains form a tree whose vertices are the nodes. Walking it from the leaves to a singular root,
   each node's copies are put at integer points, the first one rounded and the others following
   through the translations of its child chains (already integers); the translation of the chain
   to the node's parent is then read off (an integer again). So every translation is an integer,
   every node but the root sits at an integer point, and no two roundings contradict each other
   (rounding every chain's translation on its own does, around branch points of the cut). The
   final solve has these as hard constraints: the seam copies are eliminated
   (``p_other = R p_ref + t``), the nodes fixed.
   This is a simplified mixed-integer quadrangulation ([BZK09]'s MIQ rounds greedily with
   re-solves and keeps singularities apart); singularities closer than ``h`` fold the
   parametrisation locally (``n_flipped``).
4. **Extraction** (:func:`extract_quads`): the integer iso-lines cut the surface into cells
   (a cell is a connected piece of the surface mapped into one unit square ``[i, i+1]×[j, j+1]``,
   followed across triangles and seams through the transitions). A cell whose four corners are
   four distinct integer points is a quad. Cells that are not (around a singularity that is not
   at an integer point, in folded regions) and quads that would make an edge non-manifold leave
   holes, and every hole is closed by one polygon along its boundary. The result is a watertight
   polygon mesh (on a closed input) that is all quads away from singularities and folds.
   :func:`quad_mesh_stats` reports quads, other polygons, valences, irregular vertices and open
   or non-manifold edges.

Conventions: faces ``(m, 3)`` of a closed, oriented manifold mesh; ``z`` a unit 4-power field per
face (:mod:`prodmaps.fields.crossfield`); ``(u, v)`` counter-clockwise with the face orientation,
so quads come out counter-clockwise seen from outside.

[BZK09] Bommes, Zimmer, Kobbelt. Mixed-integer quadrangulation. SIGGRAPH 2009.
"""

from __future__ import annotations

from functools import partial

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from scipy.sparse.csgraph import breadth_first_order, connected_components

from ..mesh import Mesh, check_mesh, graph_components
from .crossfield import field_vectors
from .frames import mesh_frames

__all__ = ["seamless_parametrization", "extract_quads", "quad_mesh_stats", "comb_and_cut", "continuous_system",
           "integer_solve"]

# rotation by k·90° counter-clockwise, k = 0..3
_ROT = np.array([[[1, 0], [0, 1]], [[0, -1], [1, 0]], [[-1, 0], [0, -1]], [[0, 1], [-1, 0]]], dtype=np.float64)
_CORNERS = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], dtype=np.int64)  # unit-square corners, ccw


def _seam_edges(TT, TTi, cuts, mismatch):
    """Seam edges once each: ``(f, e, g, eg, r)``.

    Face ``f``'s edge ``e`` (corners ``e, e+1``) is face ``g``'s edge ``eg`` (``TT``, ``TTi``: igl's
    triangle-triangle adjacency); ``r`` the mismatch ``(mod 4)`` seen from ``f``.
    """
    fs, es = np.nonzero(cuts)
    g, eg = TT[fs, es], TTi[fs, es]
    keep = (g >= 0) & (fs < g)
    return fs[keep], es[keep], g[keep], eg[keep], np.asarray(mismatch)[fs[keep], es[keep]] % 4


class _Seams:
    """The cut graph's chains, their sides and nodes (see the module doc, steps 2-3).

    Per seam edge ``e``: its mesh end vertices ``x[e], y[e]``, the cut copies of those ends on the
    ``f`` side and the ``g`` side, the rotation index ``rot[e]`` (``p_g = R^rot p_f + t``), its
    chain ``chain[e]`` and whether its ``f`` side is the chain's reference side (``fwd[e]``). Per
    chain ``c``: ``rot_c[c]`` from the reference side to the other side.
    """

    def __init__(self, F, Fc, I, fs, es, g, eg, r, singular):
        n = int(F.max()) + 1 if F.size else 0
        self._singular = np.zeros(n, bool)  # (n,) mesh vertices that are singular
        self._singular[np.asarray(singular, dtype=np.int64)] = True
        self.ne = ne = fs.size
        self.x, self.y = F[fs, es], F[fs, (es + 1) % 3]
        self.xf, self.yf = Fc[fs, es], Fc[fs, (es + 1) % 3]
        self.xg, self.yg = Fc[g, (eg + 1) % 3], Fc[g, eg]
        self.rot = (-r) % 4
        ends, eid = np.concatenate([self.x, self.y]), np.tile(np.arange(ne), 2)
        deg = np.bincount(ends, minlength=n)
        node = ((deg > 0) & (deg != 2)) | self._singular
        while True:
            # chains: seam edges linked through shared non-node vertices (edge ids, then vertex ids + ne)
            link = ~node[ends]
            lab = graph_components(ne + n, eid[link], ne + ends[link])[1][:ne]
            _, chain = np.unique(lab, return_inverse=True)
            nch = int(chain.max()) + 1 if ne else 0
            # a closed loop of regular vertices has no node: make its first vertex one
            has_node = np.zeros(nch, bool)
            np.logical_or.at(has_node, chain, node[self.x] | node[self.y])
            if has_node.all():
                break
            lonely = np.flatnonzero(~has_node[chain])
            first = np.unique(chain[lonely], return_index=True)[1]
            node[self.x[lonely[first]]] = True
        self.node, self.chain, self.n_chains = node, chain.ravel(), nch
        # sides: side-edges s = e (f side), ne + e (g side) linked through their copies of regular vertices
        cp = np.concatenate([self.xf, self.xg, self.yf, self.yg])
        keep = ~node[np.concatenate([self.x, self.x, self.y, self.y])]
        sid = np.tile(np.arange(2 * ne), 2)
        side = graph_components(2 * ne + I.size, sid[keep], 2 * ne + cp[keep])[1][:2 * ne]
        ref = np.full(nch, np.iinfo(np.int64).max)
        np.minimum.at(ref, self.chain, np.minimum(side[:ne], side[ne:]))
        self.fwd = side[:ne] == ref[self.chain]
        self.rot_c = np.zeros(nch, np.int64)
        self.rot_c[self.chain[self.fwd]] = self.rot[self.fwd]
        self.rot_c[self.chain[~self.fwd]] = (-self.rot[~self.fwd]) % 4
    def relations(self):
        """Every seam end once per chain: ``(mesh vertex, ref copy, other copy, chain)``.

        The copies are those on the chain's reference side and on its other side (deduplicated).
        """
        fwd = np.concatenate([self.fwd, self.fwd])
        f_side, g_side = np.concatenate([self.xf, self.yf]), np.concatenate([self.xg, self.yg])
        a, b = np.where(fwd, f_side, g_side), np.where(fwd, g_side, f_side)
        v, c = np.concatenate([self.x, self.y]), np.concatenate([self.chain, self.chain])
        _, idx = np.unique(np.stack([a, b, c], axis=1), axis=0, return_index=True)
        return v[idx], a[idx], b[idx], c[idx]

    def round_nodes(self, uv: np.ndarray, I: np.ndarray, resolve=None, batches: int = 1):
        """Integer chain translations and singular nodes at integer points (module doc, step 3).

        ``uv`` is the continuous solution; with ``resolve`` (a callable taking the constraints so far
        and returning an updated continuous ``uv``) the nodes are rounded in ``batches`` groups of
        heights in the chain tree (leaves first), re-solving in between.

        Returns ``(fixed, rel, t, off)``: ``fixed`` ``{copy: (2,) position}`` (the copies of the
        singular nodes), ``rel`` a list of ``(copy, start, k, tau)`` with ``p(copy) = R^k p(start) + tau``
        (the other copies of a regular node, free with its ``start`` copy), ``t`` ``(n_chains, 2)``
        the integer translations and ``off`` the largest distance of a fixed non-root copy from the
        integers.
        """
        nch = self.n_chains
        v, a, b, c = self.relations()
        at_node = self.node[v]
        nv, na, nb, ncn = v[at_node], a[at_node], b[at_node], c[at_node]
        nodes = np.unique(nv)
        # chain tree: chain c joins its two end nodes
        ends = np.full((nch, 2), -1)
        o = np.lexsort((nv, ncn))
        cc, vv = ncn[o], nv[o]
        brk = np.r_[True, cc[1:] != cc[:-1], True]  # brk[:-1] a chain's first entry, brk[1:] its last
        ends[cc[brk[:-1]], 0] = vv[brk[:-1]]
        ends[cc[brk[1:]], 1] = vv[brk[1:]]
        pos = np.searchsorted(nodes, ends)
        T = sp.csr_matrix((np.ones(nch), (pos[:, 0], pos[:, 1])), shape=(nodes.size, nodes.size))
        deg = np.bincount(pos.ravel(), minlength=nodes.size)
        comp = connected_components(T, directed=False)[1]
        singular = self._singular[nodes]
        # one root per component: a singular leaf if any (its copy closes the cycle exactly)
        order, parent = [], np.full(nodes.size, -9999)
        for k in np.unique(comp):
            members = np.flatnonzero(comp == k)
            cand = members[(deg[members] == 1) & singular[members]]
            root = int(cand[0] if cand.size else members[0])
            o_k, p_k = breadth_first_order(T, root, directed=False, return_predecessors=True)
            order.append(o_k)
            parent[o_k] = p_k[o_k]
        order = np.concatenate(order) if order else np.zeros(0, np.int64)
        height = np.zeros(nodes.size, np.int64)
        for q in order[::-1]:  # children before parents
            if parent[q] >= 0:
                height[parent[q]] = max(height[parent[q]], height[q] + 1)
        pl = pos.tolist()
        pair_chain = {**{(a, b): ch for ch, (a, b) in enumerate(pl)}, **{(b, a): ch for ch, (a, b) in enumerate(pl)}}
        by_node = np.searchsorted(nodes, nv)
        rel_order = np.argsort(by_node, kind="stable")
        starts = np.searchsorted(by_node[rel_order], np.arange(nodes.size + 1))
        copies_order = np.argsort(I, kind="stable")
        c_lo = np.searchsorted(I[copies_order], nodes, side="left")
        c_hi = np.searchsorted(I[copies_order], nodes, side="right")
        t = np.full((nch, 2), np.nan)
        fixed, rels, off = {}, [], 0.0
        proc = order[np.argsort(height[order], kind="stable")]  # by height, leaves first
        cuts = np.searchsorted(height[proc], np.quantile(height[proc], np.arange(1, batches) / batches)
                               if proc.size else [], side="right") if batches > 1 else []
        groups = np.split(proc, np.unique(cuts)) if len(cuts) else [proc]
        # a short loop over the cut graph's nodes (hundreds), never over faces or vertices; plain
        # Python lists and small arrays inside it
        na_l, nb_l, ncn_l, rot_l = na.tolist(), nb.tolist(), ncn.tolist(), self.rot_c.tolist()
        for gi, group in enumerate(groups):
            if gi > 0 and resolve is not None and group.size:
                uv = resolve(fixed, _relation_arrays(rels), t)
            for q in group:
                rel = rel_order[starts[q]:starts[q + 1]].tolist()
                copies = copies_order[c_lo[q]:c_hi[q]]
                par_chain = pair_chain.get((int(q), int(parent[q]))) if parent[q] >= 0 else None
                known = [i for i in rel if ncn_l[i] != par_chain]
                is_root = parent[q] < 0
                # every copy as R^k p(s) + tau from one start copy s, through the known chains
                s0 = int(copies[0])
                sym = {s0: (0, np.zeros(2))}
                stack = [s0]
                while stack:
                    u_ = stack.pop()
                    ku, tu = sym[u_]
                    for i in known:
                        a_i, b_i, c_i = na_l[i], nb_l[i], ncn_l[i]
                        r_ = rot_l[c_i]
                        if a_i == u_ and b_i not in sym:
                            sym[b_i] = ((ku + r_) % 4, _ROT[r_] @ tu + t[c_i])
                            stack.append(b_i)
                        elif b_i == u_ and a_i not in sym:
                            sym[a_i] = ((ku - r_) % 4, _ROT[(-r_) % 4] @ (tu - t[c_i]))
                            stack.append(a_i)
                if singular[q]:
                    if is_root and len(copies) == 1 and known:
                        i = known[0]
                        p0 = np.linalg.solve(np.eye(2) - _ROT[rot_l[ncn_l[i]]], t[ncn_l[i]])
                    else:
                        p0 = np.round(uv[s0])
                    for cp, (kc, tc) in sym.items():
                        fixed[cp] = _ROT[kc] @ p0 + tc
                        if not is_root:
                            off = max(off, float(np.abs(fixed[cp] - np.round(fixed[cp])).max()))
                else:
                    p0 = uv[s0]
                    rels += [(cp, s0, kc, *tc) for cp, (kc, tc) in sym.items() if cp != s0]
                if par_chain is not None:
                    i = next(i for i in rel if ncn_l[i] == par_chain)
                    (ka, ta), (kb, tb) = sym[na_l[i]], sym[nb_l[i]]
                    R = _ROT[self.rot_c[par_chain]]
                    tt = (_ROT[kb] - R @ _ROT[ka]) @ p0 + tb - R @ ta
                    t[par_chain] = np.round(tt)
                    off = max(off, float(np.abs(tt - np.round(tt)).max()))
        return fixed, _relation_arrays(rels), t, off

    def chain_relations(self, t: np.ndarray, chains: np.ndarray, *, at_nodes: bool = True):
        """``(copy, start, k, tau)`` arrays of the seam ends on ``chains`` (a mask over chains, ``t`` known).

        ``p(other) = R^rot_c p(ref) + t_c``; only those at regular vertices unless ``at_nodes``.
        """
        v, a, b, c = self.relations()
        sel = chains[c] if at_nodes else chains[c] & ~self.node[v]
        return b[sel], a[sel], self.rot_c[c[sel]], t[c[sel]]


def _relation_arrays(rels):
    """A list of ``(copy, start, k, tau_u, tau_v)`` as arrays ``(copy, start, k, tau (r, 2))``."""
    R = np.array(rels, dtype=np.float64).reshape(-1, 5)
    i = R[:, :3].astype(np.int64)
    return i[:, 0], i[:, 1], i[:, 2], R[:, 3:]


def _concat_relations(*parts):
    """Concatenate ``(copy, start, k, tau)`` tuples of arrays."""
    return tuple(np.concatenate(x) for x in zip(*parts))


def _gradient_system(Vc, Fc, P1, P2, h):
    """``(A (6m, 2nc), b (6m,))`` with ``||A uv - b||²`` the field-alignment energy (area-weighted)."""
    import igl

    G = igl.grad(Vc, Fc).tocsr()  # (3m, nc): x, y, z blocks
    w = np.sqrt(0.5 * igl.doublearea(Vc, Fc).ravel())
    Wg = sp.diags(np.tile(w, 3)) @ G
    A = sp.block_diag([Wg, Wg]).tocsr()
    b = np.concatenate([np.tile(w, 3) * P1.T.ravel() / h, np.tile(w, 3) * P2.T.ravel() / h])
    return A, b


def _solve_normal(A, b):
    """Least squares ``min ||A x - b||`` by the normal equations (sparse LU, COLAMD ordering)."""
    M = (A.T @ A).tocsc()
    return spla.splu(M, permc_spec="COLAMD").solve(A.T @ b)


def comb_and_cut(mesh: Mesh, z: np.ndarray) -> dict:
    """Step 1 (module doc): comb the cross field ``z`` and cut the mesh through its singularities.

    Returns a dict: ``V``, ``F`` (the mesh), ``P1``, ``P2`` ``(m, 3)`` (the combed directions
    ``d_0``, ``d_1``), ``mismatch`` ``(m, 3)`` (quarter turns across every edge), ``singular``
    (mesh vertex ids), ``cuts`` ``(m, 3)`` (the seam edges), the cut mesh ``Vc``, ``Fc``, ``I``
    (the mesh vertex of each cut vertex) and igl's triangle-triangle adjacency ``TT``, ``TTi``.
    """
    import igl

    fr = mesh_frames(check_mesh(mesh, "comb_and_cut"))
    V, F = mesh.vertices, mesh.faces  # contiguous float64 and int64 (Mesh)
    d = field_vectors(z, fr, 4)
    P1, P2 = igl.comb_cross_field(V, F, np.ascontiguousarray(d[:, 0]), np.ascontiguousarray(d[:, 1]))
    mm = igl.cross_field_mismatch(V, F, P1, P2, True)
    is_sing, _ = igl.find_cross_field_singularities(V, F, mm)
    sing = np.flatnonzero(np.asarray(is_sing).ravel())
    cuts = igl.cut_mesh_from_singularities(V, F, mm)
    Vc, Fc, I = igl.cut_mesh(V, F, cuts)
    I = np.asarray(I, dtype=np.int64).ravel()
    TT, TTi = igl.triangle_triangle_adjacency(F)
    return {"V": V, "F": F, "P1": P1, "P2": P2, "mismatch": mm, "singular": sing, "cuts": cuts, "Vc": Vc,
            "Fc": Fc, "I": I, "TT": TT, "TTi": TTi}


def _transition_rows(rot, a_f, a_g, b_f, b_g, nc: int) -> sp.csr_matrix:
    """Rows ``(2 ne, 2 nc)`` of ``(p_g(x) - R p_f(x)) - (p_g(y) - R p_f(y))``.

    The transition of every seam edge holds with the same translation at its two ends ``x``, ``y``
    (copies ``a``, ``b``).
    """
    ne = rot.size
    R = _ROT[rot]
    blocks = []  # (rows, cols, values) of row i: the g copies' coordinate i, then R's row i on the f copies
    for i in range(2):
        row = np.arange(ne) + i * ne
        blocks += [(row, cp + i * nc, np.full(ne, sgn)) for cp, sgn in ((a_g, 1.0), (b_g, -1.0))]
        blocks += [(row, cp + j * nc, sgn * R[:, i, j]) for j in range(2) for cp, sgn in ((a_f, -1.0), (b_f, 1.0))]
    rr, cc, vv = (np.concatenate(x) for x in zip(*blocks))
    return sp.csr_matrix((vv, (rr, cc)), shape=(2 * ne, 2 * nc))


def continuous_system(A, b, seams, nc: int, weight: float):
    """Step 2 (module doc): the continuous problem ``(A0, b0, pin)``.

    The field alignment ``(A, b)`` plus, with ``weight``, the seam transitions as soft constraints with
    free translations per edge, and ``pin`` fixing the first cut vertex at the origin (the solution's
    translation).
    """
    pin = sp.csr_matrix(([1.0, 1.0], ([0, 1], [0, nc])), shape=(2, 2 * nc))
    if seams is None:
        return sp.vstack([A, pin]).tocsr(), np.concatenate([b, np.zeros(2)]), pin
    D = _transition_rows(seams.rot, seams.xf, seams.xg, seams.yf, seams.yg, nc)
    return sp.vstack([A, weight * D, weight * pin]).tocsr(), np.concatenate([b, np.zeros(2 * seams.ne + 2)]), pin


def _solve_uv(A, b, nc: int) -> np.ndarray:
    """``(u, v)`` per cut vertex ``(nc, 2)`` of the least-squares problem ``(A, b)``."""
    x = _solve_normal(A, b)
    return np.stack([x[:nc], x[nc:]], axis=1)


def _resolve(fixed: dict, rels, t, *, seams, A0, b0, nc: int, weight: float) -> np.ndarray:
    """The continuous solve again, pulled by soft rows towards the roundings so far (``round_nodes``' ``resolve``)."""
    fc = np.fromiter(fixed.keys(), dtype=np.int64, count=len(fixed))
    fp = np.array(list(fixed.values())).reshape(-1, 2)
    cp, st, kk, tau = _concat_relations(rels, seams.chain_relations(t, np.isfinite(t[:, 0])))
    nf_, nr = fc.size, cp.size
    Rk = _ROT[kk]  # (nr, 2, 2)
    rows, cols, vals = [np.arange(2 * nf_)], [np.concatenate([fc, fc + nc])], [np.ones(2 * nf_)]  # the fixed copies
    for i in range(2):  # p(cp) - R^k p(st) = tau, coordinate i
        r0 = 2 * nf_ + i * nr + np.arange(nr)
        rows += [r0, r0, r0]
        cols += [cp + i * nc, st, st + nc]
        vals += [np.ones(nr), -Rk[:, i, 0], -Rk[:, i, 1]]
    M = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                      shape=(2 * nf_ + 2 * nr, 2 * nc))
    r_ = np.concatenate([fp[:, 0], fp[:, 1], tau[:, 0], tau[:, 1]])
    return _solve_uv(sp.vstack([A0, weight * M]).tocsr(), np.concatenate([b0, weight * r_]), nc)


def _hard_constraints(seams, fixed_d: dict, node_rels, t_c, nc: int):
    """The final solve's variables: ``(Smat (2nc, 2nf), s0 (2nc,), any_fixed)``.

    The cut vertices' ``(u, v) = Smat y + s0`` for the free unknowns ``y``: the singular node copies
    fixed, every other copy of a seam vertex eliminated through its chain (regular vertices) or its
    node's chains (regular nodes).
    """
    elim_c, elim_ref, elim_k, elim_t = _concat_relations(
        seams.chain_relations(t_c, np.ones(seams.n_chains, bool), at_nodes=False), node_rels)
    fc = np.fromiter(fixed_d.keys(), dtype=np.int64, count=len(fixed_d))
    fixed, elim = np.zeros(nc, bool), np.zeros(nc, bool)
    fixed[fc], elim[elim_c] = True, True
    free = ~fixed & ~elim
    nf = int(free.sum())
    idx = np.full(nc, -1)
    idx[free] = np.arange(nf)
    if np.any(idx[elim_ref] < 0):
        raise RuntimeError("a seam copy is related to a fixed or eliminated copy; the cut graph is not a tree")
    rows, cols, vals = [np.flatnonzero(free), nc + np.flatnonzero(free)], [idx[free], nf + idx[free]], \
        [np.ones(nf), np.ones(nf)]
    Ro = _ROT[elim_k]
    for i, j in np.ndindex(2, 2):
        rows.append(i * nc + elim_c)
        cols.append(j * nf + idx[elim_ref])
        vals.append(Ro[:, i, j])
    Smat = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                         shape=(2 * nc, 2 * nf))
    s0 = np.zeros((2, nc))  # (u, v) of the fixed copies, the translations of the eliminated ones
    s0[:, fc] = np.array(list(fixed_d.values())).reshape(-1, 2).T
    s0[:, elim_c] = elim_t.T
    return Smat, s0.ravel(), bool(fc.size)


def integer_solve(A, b, seams, uv: np.ndarray, I: np.ndarray, A0, b0, pin, *, weight: float, batches: int):
    """Step 3 (module doc): round the nodes and translations, then solve the alignment with them fixed.

    Rounding follows the chain tree (re-solving the continuous problem ``(A0, b0)`` between
    ``batches``); the alignment ``(A, b)`` takes them as hard constraints. Returns ``(uv (nc, 2), off)``:
    ``off`` the largest distance of a rounded non-root node or translation from the integers.
    """
    nc = uv.shape[0]
    resolve = partial(_resolve, seams=seams, A0=A0, b0=b0, nc=nc, weight=weight)
    fixed_d, node_rels, t_c, off = seams.round_nodes(uv, I, resolve=resolve, batches=batches)
    Smat, s0, any_fixed = _hard_constraints(seams, fixed_d, node_rels, t_c, nc)
    AS, rhs = (A @ Smat).tocsr(), b - A @ s0
    if not any_fixed:  # nothing fixes the translation: pin the first cut vertex
        AS, rhs = sp.vstack([AS, pin @ Smat]).tocsr(), np.concatenate([rhs, np.zeros(2)])
    xx = Smat @ _solve_normal(AS, rhs) + s0
    return np.stack([xx[:nc], xx[nc:]], axis=1), off


def seamless_parametrization(mesh: Mesh, z: np.ndarray, h: float, *, integer: bool = True,
                             weight: float = 1e3, batches: int = 4) -> dict:
    """Seamless ``(u, v)`` parametrisation of a closed mesh along the cross field ``z`` (module doc).

    ``h`` is the target quad edge length (mesh units); ``weight`` that of the soft transition
    constraints of the first (continuous) solve. With ``integer`` (default) the translations are
    integers, the nodes of the cut graph at integer points and the transitions exact (hard
    constraints). Returns a dict with ``uv`` ``(nc, 2)``, the cut mesh ``Vc`` ``(nc, 3)``, ``Fc``
    ``(m, 3)`` (same face order as the mesh), ``I`` ``(nc,)`` (the mesh vertex of each cut
    vertex), ``singular`` (mesh vertex ids), ``n_seam_edges``, ``n_chains``, ``n_flipped`` (faces
    with a non-positive ``uv`` area), ``transition_error`` (largest violation of a seam transition),
    ``integer_error`` (largest distance of a translation or a node from the integers, the root's
    position excepted), ``rot`` and ``trans`` (per face and local edge: the transition to the
    neighbour's chart, ``p_g = R^rot p_f + trans``; identity off the seams) and ``h``.

    The steps: :func:`comb_and_cut`, :func:`continuous_system` and its solve, :func:`integer_solve`
    (rounding and the hard-constrained solve); :func:`extract_quads` is the last.
    """
    F = check_mesh(mesh, "seamless_parametrization").faces
    if not (np.isfinite(h) and h > 0):
        raise ValueError(f"h (quad size) must be > 0, got {h!r}")
    z = np.asarray(z)
    if z.shape != (F.shape[0],):
        raise ValueError(f"z must hold one value per face, shape ({F.shape[0]},); got {z.shape}")
    cut = comb_and_cut(mesh, z)
    F, Fc, I = cut["F"], cut["Fc"], cut["I"]
    m, nc = F.shape[0], cut["Vc"].shape[0]
    A, b = _gradient_system(cut["Vc"], Fc, cut["P1"], cut["P2"], h)
    fs, es, g, eg, r = _seam_edges(cut["TT"], cut["TTi"], cut["cuts"], cut["mismatch"])
    ne = fs.size
    S = _Seams(F, Fc, I, fs, es, g, eg, r, cut["singular"]) if ne else None
    A0, b0, pin = continuous_system(A, b, S, nc, weight)
    uv = _solve_uv(A0, b0, nc)
    if ne and integer:
        uv, off = integer_solve(A, b, S, uv, I, A0, b0, pin, weight=weight, batches=batches)
    # per face and local edge the transition into the neighbour's chart, p_g = R^rot p_f + trans
    rot, trans = np.zeros((m, 3), np.int64), np.zeros((m, 3, 2))  # identity off the seams
    trans_err = int_err = 0.0
    if ne:
        Rm = _ROT[S.rot]  # the translation of every seam edge read at its two ends
        t_edge = uv[S.xg] - np.einsum("eij,ej->ei", Rm, uv[S.xf])
        t_end = uv[S.yg] - np.einsum("eij,ej->ei", Rm, uv[S.yf])
        trans_err = float(np.abs(t_edge - t_end).max(initial=0.0))
        int_err = float(np.abs(t_edge - np.round(t_edge)).max(initial=0.0))
        if integer:
            int_err = float(max(off, int_err))
            t_edge = np.round(t_edge)
        rot[fs, es], trans[fs, es] = S.rot, t_edge
        rot[g, eg], trans[g, eg] = (-S.rot) % 4, -np.einsum("eij,ej->ei", _ROT[(-S.rot) % 4], t_edge)
    U = uv[Fc]
    det = (U[:, 1, 0] - U[:, 0, 0]) * (U[:, 2, 1] - U[:, 0, 1]) - (U[:, 1, 1] - U[:, 0, 1]) * (U[:, 2, 0] - U[:, 0, 0])
    return {"uv": uv, "Vc": cut["Vc"], "Fc": Fc, "I": I, "F": F, "TT": cut["TT"], "singular": cut["singular"],
            "n_seam_edges": int(ne), "n_chains": int(S.n_chains if S is not None else 0),
            "n_flipped": int(np.sum(det <= 0)), "transition_error": trans_err, "integer_error": int_err,
            "rot": rot, "trans": trans, "h": float(h)}


# ============================================================================ extraction
def _enumerate_boxes(lo: np.ndarray, hi: np.ndarray):
    """All integer points of the boxes ``[lo_f, hi_f]`` (inclusive, ``(m, 2)``): ``(f, ij)``."""
    span = np.maximum(hi - lo + 1, 0)
    cnt = span[:, 0] * span[:, 1]
    f = np.repeat(np.arange(lo.shape[0]), cnt)
    off = np.arange(cnt.sum()) - np.repeat(np.cumsum(cnt) - cnt, cnt)
    w = np.maximum(span[f, 0], 1)
    return f, lo[f] + np.stack([off % w, off // w], axis=1)


class _Keys:
    """Lookup of integer triples ``(f, i, j)`` by a sorted int64 key."""

    def __init__(self, f, ij, base, W, H):
        self.base, self.W, self.H = base, W, H
        self.k = self.key(f, ij)
        self.order = np.argsort(self.k, kind="stable")
        self.sorted = self.k[self.order]

    def key(self, f, ij):
        i, j = ij[:, 0] - self.base[0], ij[:, 1] - self.base[1]
        ok = (i >= 0) & (i < self.W) & (j >= 0) & (j < self.H)
        return np.where(ok, (f.astype(np.int64) * self.W + i) * self.H + j, -1)

    def find(self, f, ij):
        """Index of each ``(f, ij)`` among the stored ones, or -1."""
        q = self.key(f, ij)
        if self.sorted.size == 0:
            return np.full(q.size, -1)
        p = np.minimum(np.searchsorted(self.sorted, q), self.sorted.size - 1)
        return np.where((self.sorted[p] == q) & (q >= 0), self.order[p], -1)


def _apply(rot, t, p):
    """``R^rot p + t`` row-wise (``rot (k,)``, ``t, p (k, 2)``)."""
    return np.einsum("kij,kj->ki", _ROT[rot % 4], p) + t


def _cells(U: np.ndarray, ok: np.ndarray, grid, eps: float):
    """The cells (unit squares overlapping a non-folded triangle) as fragments ``(cf, cij)``, and their lookup."""
    lo = np.floor(U.min(axis=1)).astype(np.int64)
    hi = np.ceil(U.max(axis=1)).astype(np.int64) - 1
    lo[~ok], hi[~ok] = 0, -1
    cf, cij = _enumerate_boxes(lo, hi)
    Uc = U[cf]  # (c, 3, 2)
    keep = np.all((Uc.max(1) > cij + eps) & (Uc.min(1) < cij + 1 - eps), axis=1)  # bounding boxes overlap
    sq = cij[:, None, :] + _CORNERS[None]  # (c, 4, 2)
    for k in range(3):
        a, b = Uc[:, k], Uc[:, (k + 1) % 3]
        nrm = np.stack([b[:, 1] - a[:, 1], a[:, 0] - b[:, 0]], axis=1)
        nrm /= np.linalg.norm(nrm, axis=1, keepdims=True) + 1e-300
        pt = np.einsum("cvd,cd->cv", Uc, nrm)
        ps = np.einsum("cvd,cd->cv", sq, nrm)
        keep &= (pt.max(1) > ps.min(1) + eps) & (ps.max(1) > pt.min(1) + eps)
    cf, cij = cf[keep], cij[keep]
    return cf, cij, _Keys(cf, cij, *grid)


def _cell_links(U: np.ndarray, ok: np.ndarray, TT: np.ndarray, rot, trans, cells: "_Keys", eps: float):
    """The cell fragments across every edge (once); returns ``(ia, ib, r, t)``.

    Those crossed by the open edge, each paired with the fragment in the neighbour's chart: fragment
    ``ib``'s chart is ``R^r (fragment ia's chart) + t``.
    """
    m = U.shape[0]
    ef, ee = np.nonzero((TT > np.arange(m)[:, None]))
    eg = TT[ef, ee]
    both = ok[ef] & ok[eg]
    ef, ee, eg = ef[both], ee[both], eg[both]
    A, B = U[ef, ee], U[ef, (ee + 1) % 3]
    lo_e = np.floor(np.minimum(A, B)).astype(np.int64)
    hi_e = np.ceil(np.maximum(A, B)).astype(np.int64) - 1
    sf, sij = _enumerate_boxes(lo_e, hi_e)
    a, b = A[sf], B[sf]
    cross = np.all((np.maximum(a, b) > sij + eps) & (np.minimum(a, b) < sij + 1 - eps), axis=1)
    nrm = np.stack([b[:, 1] - a[:, 1], a[:, 0] - b[:, 0]], axis=1)
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True) + 1e-300
    ps = np.einsum("cvd,cd->cv", sij[:, None, :] + _CORNERS[None], nrm)
    pa = np.einsum("cd,cd->c", a, nrm)
    cross &= (ps.min(1) < pa - eps) & (ps.max(1) > pa + eps)
    sf, sij = sf[cross], sij[cross]
    f_, g_, e_ = ef[sf], eg[sf], ee[sf]
    r_, t_ = rot[f_, e_], trans[f_, e_]
    gij = np.floor(_apply(r_, t_, sij + 0.5)).astype(np.int64)
    ia, ib = cells.find(f_, sij), cells.find(g_, gij)
    good = (ia >= 0) & (ib >= 0)
    return ia[good], ib[good], r_[good], t_[good]


def _cell_charts(nfr: int, cls: np.ndarray, n_cls: int, links, cij: np.ndarray):
    """The chart of every cell fragment relative to its class's first fragment, ``p_root = R^k p + tau``.

    Walked along the ``links`` (:func:`_cell_links`). Returns ``(kk (c,), tau (c, 2), ref_cell (c, 2),
    bad_cls (n_cls,))``: ``ref_cell`` the unit square of its class in the root chart, ``bad_cls`` the
    classes whose fragments name different squares (not a proper cell).
    """
    ia, ib, r_, t_ = links
    kk = np.full(nfr, -1)
    tau = np.zeros((nfr, 2))
    roots = np.unique(cls, return_index=True)[1]
    kk[roots] = 0
    # both directions of every link: chart_b = R^r chart_a + t  and  chart_a = R^-r chart_b - R^-r t
    la, lb = np.concatenate([ia, ib]), np.concatenate([ib, ia])
    lr = np.concatenate([r_, (-r_) % 4])
    lt = np.concatenate([t_, -_apply((-r_) % 4, np.zeros_like(t_), t_)])
    for _ in range(nfr):
        step = (kk[la] >= 0) & (kk[lb] < 0)
        if not step.any():
            break
        new, first = np.unique(lb[step], return_index=True)  # each newly reached fragment once
        src = la[step][first]
        k_new = (kk[src] - lr[step][first]) % 4
        kk[new] = k_new
        tau[new] = tau[src] - _apply(k_new, np.zeros((new.size, 2)), lt[step][first])
    root_cell = np.floor(_apply(kk, tau, cij + 0.5)).astype(np.int64)
    # a class is a proper cell when all its fragments name the same unit square of the root chart
    ref_cell = root_cell[roots][cls]
    bad_cls = np.zeros(n_cls, bool)
    bad_cls[cls[np.any(root_cell != ref_cell, axis=1)]] = True
    return kk, tau, ref_cell, bad_cls


def _integer_points(U, e1, e2, det, ok, TT, rot, trans, grid, eps: float):
    """The integer points of the closed (non-folded) triangles, merged across edges into point ids.

    Returns ``(pts, pf, pid, n_pts, first, lam)``: ``pts`` the lookup of the per-face points, ``pf``
    their face, ``pid`` their point id, ``first`` one per-face point of every id and ``lam``
    ``(p, 3)`` the barycentric coordinates of the per-face points.
    """
    plo = np.ceil(U.min(axis=1) - eps).astype(np.int64)
    phi = np.floor(U.max(axis=1) + eps).astype(np.int64)
    plo[~ok], phi[~ok] = 0, -1
    pf_, pij = _enumerate_boxes(plo, phi)
    d = pij - U[pf_, 0]
    l1 = (d[:, 0] * e2[pf_, 1] - d[:, 1] * e2[pf_, 0]) / det[pf_]
    l2 = (e1[pf_, 0] * d[:, 1] - e1[pf_, 1] * d[:, 0]) / det[pf_]
    lam = np.stack([1 - l1 - l2, l1, l2], axis=1)
    tol = eps / np.sqrt(np.abs(det[pf_]))[:, None]  # barycentric tolerance for eps in uv
    inside = np.all(lam >= -tol, axis=1)
    pf_, pij, lam, tol = pf_[inside], pij[inside], lam[inside], tol[inside]
    pts = _Keys(pf_, pij, *grid)
    la_, lb_ = [np.zeros(0, np.int64)], [np.zeros(0, np.int64)]
    for k in range(3):  # on the edge opposite corner k: local edge (k+1) % 3
        on = np.flatnonzero(lam[:, k] <= tol[:, 0])
        e = (k + 1) % 3
        g = TT[pf_[on], e]
        on, g = on[g >= 0], g[g >= 0]
        q = np.rint(_apply(rot[pf_[on], e], trans[pf_[on], e], pij[on])).astype(np.int64)
        j = pts.find(g, q)
        la_.append(on[j >= 0])
        lb_.append(j[j >= 0])
    n_pts, pid = graph_components(pf_.size, np.concatenate(la_), np.concatenate(lb_))
    first = np.unique(pid, return_index=True)[1]
    return pts, pf_, pid, n_pts, first, lam


def _quads_of_cells(cf, cij, cls, n_cls: int, charts, pts: "_Keys", pid) -> np.ndarray:
    """The quads ``(q, 4)``: consistent cell classes with exactly one integer point per corner slot, all distinct."""
    kk, tau, ref_cell, bad_cls = charts
    fr_idx = np.repeat(np.arange(cf.size), 4)
    corner = (cij[:, None, :] + _CORNERS[None]).reshape(-1, 2)
    j = pts.find(cf[fr_idx], corner)
    has = j >= 0
    fr_idx, corner, j = fr_idx[has], corner[has], j[has]
    rc = np.rint(_apply(kk[fr_idx], tau[fr_idx], corner.astype(float))).astype(np.int64) - ref_cell[fr_idx]
    slot = np.full(rc.shape[0], -1)
    for s, c in enumerate(_CORNERS):
        slot[np.all(rc == c, axis=1)] = s
    triples = np.unique(np.stack([cls[fr_idx], slot, pid[j]], axis=1), axis=0)
    triples = triples[triples[:, 1] >= 0]
    cs = triples[:, 0] * 4 + triples[:, 1]
    cnt_slot = np.bincount(cs, minlength=4 * n_cls).reshape(n_cls, 4)
    quad_cls = np.flatnonzero(np.all(cnt_slot == 1, axis=1) & ~bad_cls)
    Qall = np.full((n_cls, 4), -1)
    one = cnt_slot.ravel()[cs] == 1
    Qall[triples[one, 0], triples[one, 1]] = triples[one, 2]
    Q = Qall[quad_cls]
    return Q[np.all(np.diff(np.sort(Q, axis=1), axis=1) > 0, axis=1)]


def _manifold_quads(Q: np.ndarray, n_pts: int):
    """Drop quads that reuse a directed edge or make an edge non-manifold, until none does: ``(Q, n_dropped)``."""
    n_dropped = 0
    while Q.size:
        E = np.stack([Q, np.roll(Q, -1, axis=1)], axis=2).reshape(-1, 2)
        key = E[:, 0] * n_pts + E[:, 1]
        ukey = np.minimum(E[:, 0], E[:, 1]) * n_pts + np.maximum(E[:, 0], E[:, 1])
        _, dinv, dcnt = np.unique(key, return_inverse=True, return_counts=True)
        _, uinv, ucnt = np.unique(ukey, return_inverse=True, return_counts=True)
        bad_e = (dcnt[dinv] > 1) | (ucnt[uinv] > 2)
        bad_q = bad_e.reshape(-1, 4).any(axis=1)
        if not bad_q.any():
            break
        n_dropped += int(bad_q.sum())
        Q = Q[~bad_q]
    return Q, n_dropped


def extract_quads(param: dict, *, eps: float = 1e-7) -> dict:
    """Quads of a :func:`seamless_parametrization` and the polygons closing its holes (module doc, step 4).

    ``eps`` (in ``uv`` units) is the tolerance under which a cell touching a triangle or an edge
    only along a line or at a point does not count as crossing it, and a point on a triangle's
    edge counts as on it. Returns a dict:

    * ``V`` ``(p, 3)`` the integer points on the surface, ``location`` ``(p,)`` their face and
      ``bary`` ``(p, 3)`` barycentric coordinates in it (mesh faces, for carrying points by a map);
    * ``Q`` ``(q, 4)`` quads, counter-clockwise seen from outside;
    * ``polygons`` (list of int arrays) the faces that close the holes, each counter-clockwise;
    * ``n_cells`` (cells of the iso-line partition), ``n_inconsistent`` (cells not a unit square:
      singular or folded), ``n_dropped`` (quads removed to keep every edge manifold).
    """
    uv, Fc, rot, trans, TT = param["uv"], param["Fc"], param["rot"], param["trans"], param["TT"]
    U = uv[Fc]  # (m, 3, 2)
    e1, e2 = U[:, 1] - U[:, 0], U[:, 2] - U[:, 0]
    det = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
    ok = det > eps * eps
    base = np.floor(uv.min(axis=0)).astype(np.int64) - 2
    W, H = (np.ceil(uv.max(axis=0)).astype(np.int64) - base + 3).tolist()
    grid = (base, W, H)
    cf, cij, cells = _cells(U, ok, grid, eps)
    links = _cell_links(U, ok, TT, rot, trans, cells, eps)
    n_cls, cls = graph_components(cf.size, links[0], links[1])
    charts = _cell_charts(cf.size, cls, n_cls, links, cij)
    pts, pf_, pid, n_pts, first, lam = _integer_points(U, e1, e2, det, ok, TT, rot, trans, grid, eps)
    lam_c = np.clip(lam[first], 0.0, None)
    lam_c /= lam_c.sum(axis=1, keepdims=True)
    location = pf_[first]
    Xp = np.einsum("pk,pkd->pd", lam_c, param["Vc"][Fc[location]])
    Q, n_dropped = _manifold_quads(_quads_of_cells(cf, cij, cls, n_cls, charts, pts, pid), n_pts)
    return {"V": Xp, "location": location, "bary": lam_c, "Q": Q.astype(np.int64), "polygons": _close_holes(Q, n_pts),
            "n_cells": int(n_cls), "n_inconsistent": int(charts[3].sum()), "n_dropped": n_dropped}


def _close_holes(Q: np.ndarray, n: int) -> list:
    """Polygons closing the holes of a quad set with manifold edges: every boundary loop, reversed.

    At a vertex where several holes meet, incoming and outgoing boundary edges are paired in a
    fixed order, so every boundary edge gets exactly one closing polygon.
    """
    E = np.stack([Q, np.roll(Q, -1, axis=1)], axis=2).reshape(-1, 2)
    bnd = E[~np.isin(E[:, 1] * n + E[:, 0], E[:, 0] * n + E[:, 1])]  # reverse edge not in the quads
    if bnd.size == 0:
        return []
    H = bnd[:, ::-1]  # hole half-edges a -> b, each hole traversed counter-clockwise from outside
    # next half-edge: one starting where this one ends; pair in-edges and out-edges per vertex
    o_out = np.lexsort((np.arange(H.shape[0]), H[:, 0]))
    o_in = np.lexsort((np.arange(H.shape[0]), H[:, 1]))
    nxt = np.empty(H.shape[0], np.int64)
    nxt[o_in] = o_out  # the i-th in-edge at v continues with the i-th out-edge at v (same counts)
    seen = np.zeros(H.shape[0], bool)
    polys = []
    for s in range(H.shape[0]):  # one pass over the boundary half-edges (a hole's length each)
        if seen[s]:
            continue
        loop, e = [], s
        while not seen[e]:
            seen[e] = True
            loop.append(H[e, 0])
            e = nxt[e]
        polys.append(np.array(loop, dtype=np.int64))
    return polys


def quad_mesh_stats(V: np.ndarray, Q: np.ndarray, polygons=()) -> dict:
    """Counts of a polygon mesh of quads ``Q`` ``(q, 4)`` and other ``polygons`` (list of index arrays).

    ``n_quads``, ``n_polygons`` (the non-quad faces) and ``polygon_sizes`` (histogram),
    ``quad_fraction`` (quads over faces), ``n_vertices`` (used), ``n_boundary_edges`` (0: watertight),
    ``n_nonmanifold_edges`` (edges of more than two faces), the valence histogram of the interior
    vertices, ``n_irregular`` (interior valence != 4), the list ``irregular`` and their valences
    ``irregular_valence``.
    """
    Q = np.asarray(Q, dtype=np.int64).reshape(-1, 4)
    faces = [Q] + [np.asarray(p, dtype=np.int64)[None] for p in polygons]
    if sum(f.size for f in faces) == 0:
        return {"n_quads": 0, "n_polygons": 0, "polygon_sizes": {}, "quad_fraction": 0.0, "n_vertices": 0,
                "n_boundary_edges": 0, "n_nonmanifold_edges": 0, "n_irregular": 0, "valence": {},
                "irregular": np.zeros(0, np.int64), "irregular_valence": np.zeros(0, np.int64)}
    E = np.concatenate([np.stack([f, np.roll(f, -1, axis=1)], axis=2).reshape(-1, 2) for f in faces if f.size])
    uniq, cnt = np.unique(np.sort(E, axis=1), axis=0, return_counts=True)
    bnd = uniq[cnt == 1]
    used = np.unique(np.concatenate([f.ravel() for f in faces]))
    val = np.bincount(uniq.ravel(), minlength=int(used.max()) + 1)
    interior = used[~np.isin(used, bnd)]
    irr = interior[val[interior] != 4]
    hist = {int(a): int(b) for a, b in zip(*np.unique(val[interior], return_counts=True))}
    sizes = np.array([len(p) for p in polygons], dtype=np.int64)
    n_faces = Q.shape[0] + sizes.size
    return {"n_quads": int(Q.shape[0]), "n_polygons": int(sizes.size),
            "polygon_sizes": {int(a): int(b) for a, b in zip(*np.unique(sizes, return_counts=True))},
            "quad_fraction": float(Q.shape[0] / n_faces) if n_faces else 0.0,
            "n_vertices": int(used.size), "n_boundary_edges": int(bnd.shape[0]),
            "n_nonmanifold_edges": int(np.sum(cnt > 2)), "n_irregular": int(irr.size), "valence": hist,
            "irregular": irr, "irregular_valence": val[irr]}
