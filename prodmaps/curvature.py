"""Discrete curvature of triangle meshes: face frames and principal curvatures [Rus04].

Conventions
-----------
* Face frames: for face ``(i, j, k)`` the unit normal follows the right-hand rule on the face
  order, ``u`` is the unit edge ``i -> j`` and ``v = n x u``, so ``(u, v, n)`` is a right-handed
  orthonormal frame tangent to the face.
* Curvature sign: positive mean curvature on a sphere with outward normals.
* Principal directions are defined up to sign (they are line fields, not vector fields).

References
----------
[Rus04] Rusinkiewicz. Estimating curvatures and their derivatives on triangle meshes. 3DPVT 2004.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from .mesh import Mesh, check_mesh

__all__ = ["face_frames", "principal_curvatures"]


def face_frames(V: np.ndarray, F: np.ndarray):
    """Per-face unit normal ``(m, 3)``, tangent frame ``u, v`` ``(m, 3)`` each, and area ``(m,)``.

    Returns ``(normal, u, v, area)``; see the module doc for the orientation.
    """
    e1 = V[F[:, 1]] - V[F[:, 0]]
    e2 = V[F[:, 2]] - V[F[:, 0]]
    cr = np.cross(e1, e2)
    dbl = np.linalg.norm(cr, axis=1)
    nrm = cr / dbl[:, None]
    u = e1 / np.linalg.norm(e1, axis=1, keepdims=True)
    v = np.cross(nrm, u)
    return nrm, u, v, 0.5 * dbl


def principal_curvatures(mesh: Mesh, smooth: int = 1):
    """Per-face and per-vertex shape operators by per-face fitting [Rus04], vectorised.

    For every face, the symmetric 2x2 second fundamental form ``S`` in the face frame ``(u, v)``
    is the least-squares solution of ``S [e·u, e·v]ᵀ = [Δn·u, Δn·v]ᵀ`` over its three edges ``e``
    (``Δn`` the difference of the area-weighted vertex normals along the edge). The tensors are
    embedded in 3-D (``T = [u v] S [u v]ᵀ``), averaged to the vertices (area-weighted, projected
    on the vertex tangent plane), then smoothed by ``smooth`` rounds of vertex -> face (mean of
    the 3 corners, projected on the face plane) -> vertex averaging. Face directions come from
    the (smoothed) face tensors, vertex curvatures from the vertex tensors.

    Returns a dict with per-face ``dir_max``/``dir_min`` ``(m, 3)`` unit principal directions
    (tangent to the face), ``k_max``/``k_min`` ``(m,)`` and per-vertex ``mean``/``gauss``/
    ``vertex_k_max``/``vertex_k_min`` ``(n,)`` curvatures (convention: positive mean curvature on
    a sphere with outward normals).
    Directions are defined up to sign; everything is invariant to rigid motions.
    """
    mesh = check_mesh(mesh, "principal_curvatures")
    V, F = mesh.vertices, mesh.faces
    n, m = V.shape[0], F.shape[0]
    N = mesh.vertex_normals()
    fn, u, v, area = face_frames(V, F)
    rows, rhs = [], []
    for a, b in ((1, 2), (2, 0), (0, 1)):
        e = V[F[:, b]] - V[F[:, a]]
        dn = N[F[:, b]] - N[F[:, a]]
        eu, ev = np.einsum("ij,ij->i", e, u), np.einsum("ij,ij->i", e, v)
        nu, nv = np.einsum("ij,ij->i", dn, u), np.einsum("ij,ij->i", dn, v)
        # unknowns (s_uu, s_uv, s_vv): [eu ev 0; 0 eu ev] s = [nu; nv]
        rows += [np.stack([eu, ev, np.zeros_like(eu)], 1), np.stack([np.zeros_like(eu), eu, ev], 1)]
        rhs += [nu, nv]
    Amat = np.stack(rows, axis=1)  # (m, 6, 3)
    AtA = np.einsum("fki,fkj->fij", Amat, Amat)
    Atb = np.einsum("fki,fk->fi", Amat, np.stack(rhs, axis=1))  # rhs (m, 6)
    reg = 1e-12 * np.trace(AtA, axis1=1, axis2=2)[:, None, None] * np.eye(3)
    s = np.linalg.solve(AtA + reg, Atb[..., None])[..., 0]
    # sign: on a sphere of radius r with outward normals n = x/r, Δn = e/r and S = I/r, so the
    # mean curvature is positive there.
    S2 = s[:, [0, 1, 1, 2]].reshape(m, 2, 2)
    P = np.stack([u, v], axis=2)  # (m, 3, 2)
    T = np.einsum("fai,fij,fbj->fab", P, S2, P)  # (m, 3, 3) face tensors

    inc = sp.csr_matrix((np.repeat(area, 3), (F.ravel(), np.repeat(np.arange(m), 3))), shape=(n, m))  # vertex <- face
    vsum = np.asarray(inc.sum(axis=1)).ravel()
    Pn = np.eye(3)[None] - N[:, :, None] * N[:, None, :]  # (n, 3, 3) tangent projectors
    Pf = np.eye(3)[None] - fn[:, :, None] * fn[:, None, :]

    def to_vertices(Tf):
        Tv_ = (inc @ Tf.reshape(m, 9)).reshape(n, 3, 3) / vsum[:, None, None]
        return np.einsum("vab,vbc,vcd->vad", Pn, Tv_, Pn)

    Tv = to_vertices(T)
    for _ in range(max(int(smooth), 0)):  # vertex -> face (mean of the corners, projected) -> vertex
        T = np.einsum("fab,fbc,fcd->fad", Pf, (Tv[F[:, 0]] + Tv[F[:, 1]] + Tv[F[:, 2]]) / 3.0, Pf)
        Tv = to_vertices(T)
    # face principal directions from the face tensor in its tangent frame
    S2f = np.einsum("fai,fab,fbj->fij", P, 0.5 * (T + T.transpose(0, 2, 1)), P)
    kf, wf = np.linalg.eigh(S2f)  # ascending
    dir_min = np.einsum("fai,fi->fa", P, wf[:, :, 0])
    dir_max = np.einsum("fai,fi->fa", P, wf[:, :, 1])
    # vertex curvatures from the smoothed vertex tensor, in a vertex tangent frame
    tv = np.cross(N, np.where(np.abs(N[:, [0]]) < 0.9, [[1.0, 0, 0]], [[0, 1.0, 0]]))
    tv /= np.linalg.norm(tv, axis=1, keepdims=True)
    Pv = np.stack([tv, np.cross(N, tv)], axis=2)  # (n, 3, 2)
    S2v = np.einsum("vai,vab,vbj->vij", Pv, 0.5 * (Tv + Tv.transpose(0, 2, 1)), Pv)
    kv = np.linalg.eigvalsh(S2v)
    return {"dir_max": dir_max, "dir_min": dir_min, "k_max": kf[:, 1], "k_min": kf[:, 0], "mean": kv.mean(axis=1),
            "gauss": kv[:, 0] * kv[:, 1], "vertex_k_max": kv[:, 1], "vertex_k_min": kv[:, 0]}


def shape_index(k_max: np.ndarray, k_min: np.ndarray) -> np.ndarray:
    """Koenderink's shape index ``(2/π) atan((κ1 + κ2)/(κ1 − κ2))`` in ``[-1, 1]``, ``κ1 >= κ2``.

    ``+1`` at convex umbilics (a sphere with outward normals, :func:`principal_curvatures`'s sign
    convention), ``-1`` at concave ones, ``0`` at symmetric saddles, ``±1/2`` on cylinders; unit-free.
    Umbilics (``κ1 = κ2``) are well defined (``atan2``); flat points (both 0) give 0.
    """
    k1, k2 = np.asarray(k_max, dtype=np.float64), np.asarray(k_min, dtype=np.float64)
    return (2.0 / np.pi) * np.arctan2(k1 + k2, k1 - k2)
