"""N-direction fields (cross fields for ``N = 4``) on faces as power fields [KCPS13].

Representation
--------------
An ``N``-direction field assigns to every face a set of ``N`` unit tangent vectors at angles
``α + 2πj/N``. It is stored as its **power field** ``z_f = r_f exp(i N α_f)`` (complex, one per
face, in the face frame of :mod:`prodmaps.fields.frames`): the directions are the ``N``-th
roots of ``z_f / |z_f|``. The power removes the ``N``-fold symmetry, so smoothness and
alignment become quadratic. ``N = 4`` is a cross field (4-RoSy), ``N = 1`` a vector field,
``N = 2`` a line field. Changing the frame of a face by ``β`` multiplies ``z_f`` by
``exp(-i N β)``.

Energies (all Hermitian, sparse)
--------------------------------
* Smoothness: the connection Laplacian on the dual graph,
  ``E(z) = Σ_{dual edges fg} w_fg |z_g - exp(i N ρ_fg) z_f|² = zᴴ L z`` with ``ρ_fg`` the
  transport angle (:func:`prodmaps.fields.frames.dual_edges`) and the dual cotangent-like
  weight ``w_fg = |e| / |c_f - c_g|`` (shared edge length over centroid distance). The mass is
  ``M = diag(face areas)``; ``zᴴ L z / zᴴ M z`` has units ``1/length²``.
* Smoothest field: the eigenvector of the smallest eigenvalue of ``L z = λ M z`` [KCPS13 §5].
* Alignment: ``(L - λ M) z = M q/ℓ²`` with ``λ = -1/ℓ²`` (``λ < λ_min``, so the system is
  positive definite): the screened-Poisson smoothing of a guide ``q`` at the length scale ``ℓ``;
  ``ℓ -> ∞`` gives the smoothest field, ``ℓ -> 0`` the guide itself [KCPS13 §6].
  The guide of :func:`curvature_guide` is ``q_f = w_f exp(i N θ_f)`` with ``θ_f`` the angle of
  the maximal principal direction and ``w_f ∈ [0, 1]`` a reliability weight from the
  curvature anisotropy ``|k_max - k_min|``.

Singularities
-------------
The index of vertex ``v`` is ``(Σ δ + N K_v) / (2π N)``: ``δ`` the jumps
``wrap(arg z_g - arg z_f - N ρ_fg)`` along the dual cycle around ``v`` (counter-clockwise),
``K_v`` the angle defect. It is a multiple of ``1/N`` (±1/4 for crosses) and on a closed
surface the indices sum to the Euler characteristic (Poincaré–Hopf).

[KCPS13] Knöppel, Crane, Pinkall, Schröder. Globally optimal direction fields. SIGGRAPH 2013.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ..checks import check_p2p, check_symmetry_order
from ..curvature import face_frames, principal_curvatures
from ..mesh import Mesh, vertex_normals
from .frames import Frames, angle_defect, as_frames, dual_edges, halfedges, mesh_frames, transport_angles, wrap_angle

__all__ = [
    "connection_laplacian", "smoothest_field", "curvature_guide", "aligned_field", "cross_field",
    "normalize_field", "rotate_field", "field_angles", "field_vectors", "cross_angle",
    "weighted_quantile", "angle_stats", "singularity_index", "singularities", "vertex_power_field",
    "pushforward_field", "pushforward_field_barycentric", "closest_point_correspondence",
]


def _checked_field(fr, z, N: int, name="z") -> tuple[Frames, np.ndarray, int]:
    """``(frames of fr, z as complex128, N)``, after checking ``N`` and that ``z`` holds one finite value per face."""
    N = check_symmetry_order(N)
    fr = as_frames(fr)
    z = np.asarray(z)
    if z.shape != (fr.n_faces,):
        raise ValueError(f"{name} must be a power field of shape (m,) = ({fr.n_faces},); got {z.shape}")
    if not np.all(np.isfinite(z)):
        raise ValueError(f"{name} contains non-finite values")
    return fr, z.astype(np.complex128), N


# ----------------------------------------------------------------------------- energies
def connection_laplacian(fr: Frames, N: int = 4):
    """Connection Laplacian of ``N``-power fields on the dual graph.

    Returns ``(L, mass)``: ``L`` ``(m, m)`` complex Hermitian positive semi-definite sparse
    (CSR) with ``zᴴ L z = Σ w_fg |z_g - exp(iNρ_fg) z_f|²`` and ``mass`` ``(m,)`` the face areas.
    """
    fr = as_frames(fr)
    N = check_symmetry_order(N)
    de = dual_edges(fr)
    f, g = de["f"], de["g"]
    c = fr.centroids
    elen = np.linalg.norm(fr.vertices[de["b"]] - fr.vertices[de["a"]], axis=1)
    w = elen / np.linalg.norm(c[g] - c[f], axis=1)  # (E,)
    r = np.exp(1j * N * de["rho"])  # (E,) transport f -> g of the N-th power
    m = fr.n_faces
    diag = np.bincount(f, weights=w, minlength=m) + np.bincount(g, weights=w, minlength=m)
    rows = np.concatenate([g, f, np.arange(m)])
    cols = np.concatenate([f, g, np.arange(m)])
    vals = np.concatenate([-w * r, -w * np.conj(r), diag.astype(np.complex128)])
    return sp.csr_matrix((vals, (rows, cols)), shape=(m, m)), fr.area.copy()


def smoothest_field(fr: Frames, N: int = 4, *, L=None):
    """The smoothest unit-norm power field: smallest eigenpair of ``L z = λ M z``.

    Returns ``(z (m,), λ)`` with ``zᴴ M z = area`` and the phase fixed so that
    ``Σ A_f z_f`` is real positive (deterministic). Needs a closed surface of nonzero Euler
    characteristic or a boundary for ``λ > 0``; otherwise ``λ ≈ 0`` and the field is parallel.
    """
    fr = as_frames(fr)
    N = check_symmetry_order(N)
    if L is None:
        L, _ = connection_laplacian(fr, N)
    M = sp.diags(fr.area)
    v0 = np.ones(fr.n_faces, dtype=np.complex128)
    shift = -1e-8 * float(abs(L.diagonal()).mean() / fr.area.mean())
    lam, vec = spla.eigsh(L, k=1, M=M, sigma=shift, which="LM", v0=v0, tol=1e-10)
    z = vec[:, 0]
    s = np.sum(fr.area * z)
    z = z * (np.conj(s) / abs(s) if abs(s) > 0 else 1.0)
    z = z * np.sqrt(fr.area.sum() / np.real(np.vdot(z, fr.area * z)))
    return z, float(lam[0])


def curvature_guide(mesh: Mesh, fr: Frames | None = None, N: int = 4, *, smooth: int = 1,
                    scale_quantile: float = 0.9, min_weight: float = 0.1, curvature: dict | None = None):
    """Alignment guide ``q`` ``(m,)`` from the principal curvature directions.

    ``q_f = w_f exp(i N θ_f)`` with ``θ_f`` the angle of ``dir_max`` in the face frame (for
    ``N = 4`` maximal and minimal directions give the same ``q``; for ``N = 1`` the sign of a
    principal direction is arbitrary, so use ``N`` even). The weight is the anisotropy
    ``|k_max - k_min|`` divided by its ``scale_quantile`` quantile, clipped to ``[0, 1]``; faces
    below ``min_weight`` (umbilic, unreliable directions) get weight 0.

    Returns ``(q, weight)``.
    """
    N = check_symmetry_order(N)
    if fr is None:
        fr = mesh_frames(mesh)
    pc = curvature if curvature is not None else principal_curvatures(mesh, smooth=smooth)
    d = pc["dir_max"]
    theta = np.arctan2(np.einsum("ij,ij->i", d, fr.v), np.einsum("ij,ij->i", d, fr.u))
    aniso = np.abs(pc["k_max"] - pc["k_min"])
    s = np.quantile(aniso, scale_quantile)
    w = np.clip(aniso / (s if s > 0 else 1.0), 0.0, 1.0)
    w[w < min_weight] = 0.0
    return w * np.exp(1j * N * theta), w


def aligned_field(fr: Frames, q: np.ndarray, N: int = 4, *, scale: float = 0.05, L=None,
                  normalize: bool = True) -> np.ndarray:
    """Smooth power field aligned to the guide ``q``: ``(L + M/ℓ²) z = M q/ℓ²``.

    ``scale`` is ``ℓ / sqrt(total area)``: small values follow the guide, large ones give the
    smoothest field. This is [KCPS13]'s ``(L - λM) z = M q`` with ``λ = -1/ℓ²`` (up to the
    scale of ``q``). Returns the unit power field (``normalize``) or the raw solution.
    """
    fr, q, N = _checked_field(fr, q, N, "q")
    if L is None:
        L, _ = connection_laplacian(fr, N)
    ell2 = (scale ** 2) * fr.area.sum()
    z = spla.spsolve((L + sp.diags(fr.area / ell2)).tocsc(), fr.area * q / ell2)
    return normalize_field(z) if normalize else z


def cross_field(mesh: Mesh, N: int = 4, *, scale: float = 0.05, smooth: int = 1,
                min_weight: float = 0.1) -> np.ndarray:
    """Curvature-aligned smooth unit ``N``-power field of a mesh (``N = 4``: a cross field).

    Convenience for :func:`curvature_guide` + :func:`aligned_field`; see them for the knobs.
    Returns ``z`` ``(m,)``, ``|z| = 1`` (cross = 4th roots of ``z`` in the face frames).
    """
    fr = mesh_frames(mesh)
    q, _ = curvature_guide(mesh, fr, N, smooth=smooth, min_weight=min_weight)
    return aligned_field(fr, q, N, scale=scale)


# ----------------------------------------------------------------------------- helpers
def normalize_field(z: np.ndarray, eps: float = 1e-300) -> np.ndarray:
    """``z / |z|`` (zeros stay zero)."""
    z = np.asarray(z, dtype=np.complex128)
    a = np.abs(z)
    return np.where(a > eps, z / np.maximum(a, eps), 0.0)


def rotate_field(z: np.ndarray, angle, N: int = 4) -> np.ndarray:
    """Rotate every direction of the field by ``angle`` (radians, scalar or ``(m,)``)."""
    return np.asarray(z) * np.exp(1j * check_symmetry_order(N) * np.asarray(angle))


def field_angles(z: np.ndarray, N: int = 4) -> np.ndarray:
    """Angle ``(m,)`` of one representative direction in each face frame (``arg z / N``)."""
    return np.angle(z) / check_symmetry_order(N)


def field_vectors(z: np.ndarray, fr: Frames, N: int = 4) -> np.ndarray:
    """The ``N`` unit directions of every face as 3D vectors ``(m, N, 3)``."""
    fr, z, N = _checked_field(fr, z, N)
    a = field_angles(z, N)[:, None] + 2 * np.pi * np.arange(N)[None, :] / N  # (m, N)
    return np.cos(a)[..., None] * fr.u[:, None, :] + np.sin(a)[..., None] * fr.v[:, None, :]


def cross_angle(z1: np.ndarray, z2: np.ndarray, N: int = 4) -> np.ndarray:
    """Angle between two ``N``-direction fields per face, modulo ``2π/N``: in ``[0, π/N]``.

    For crosses (``N = 4``) this is the angle modulo 90°, in ``[0°, 45°]`` (radians).
    Both fields must be in the same face frames.
    """
    N = check_symmetry_order(N)
    return np.abs(np.angle(np.asarray(z1) * np.conj(np.asarray(z2)))) / N


def weighted_quantile(x: np.ndarray, w: np.ndarray, q: float) -> float:
    """The ``q``-quantile of ``x`` under weights ``w`` (inverse of the weighted CDF)."""
    x = np.asarray(x, dtype=np.float64)
    w = np.asarray(w, dtype=np.float64)
    o = np.argsort(x)
    cw = np.cumsum(w[o])
    if cw[-1] <= 0:
        raise ValueError("weights sum to zero")
    i = np.searchsorted(cw, q * cw[-1])
    return float(x[o][min(i, x.size - 1)])


def angle_stats(z1, z2, area, N: int = 4, mask=None) -> dict:
    """Area-weighted mean and 90th percentile of :func:`cross_angle`, in degrees."""
    a = np.degrees(cross_angle(z1, z2, N))
    w = np.asarray(area, dtype=np.float64)
    if mask is not None:
        w = w * np.asarray(mask, dtype=bool)
    return {"mean_deg": float(np.sum(w * a) / np.sum(w)), "p90_deg": weighted_quantile(a, w, 0.9)}


# ----------------------------------------------------------------------------- singularities
def singularity_index(fr: Frames, z: np.ndarray, N: int = 4) -> np.ndarray:
    """Index of every vertex ``(n,)``, a multiple of ``1/N`` (see the module doc).

    Boundary vertices get 0 (their dual cycle is open).
    """
    fr, z, N = _checked_field(fr, z, N)
    tail, head, face, twin = halfedges(fr.faces)
    ok = twin >= 0
    rho = transport_angles(fr)
    g = face[np.maximum(twin, 0)]
    jump = wrap_angle(np.angle(z[g]) - np.angle(z[face]) - N * np.nan_to_num(rho))  # (3m,)
    s = np.bincount(head[ok], weights=jump[ok], minlength=fr.n_vertices)
    K = angle_defect(fr.vertices, fr.faces)
    idx = np.round((s + N * K) / (2 * np.pi)) / N
    idx[tail[~ok]] = 0.0  # boundary vertices
    return idx


def singularities(fr: Frames, z: np.ndarray, N: int = 4):
    """Singular vertices and their indices: ``(vertex ids (s,), indices (s,))``."""
    idx = singularity_index(fr, z, N)
    v = np.flatnonzero(np.abs(idx) > 1e-9)
    return v, idx[v]


# ----------------------------------------------------------------------------- vertices, maps
def vertex_power_field(fr: Frames, z: np.ndarray, N: int = 4):
    """Average a face power field to the vertices.

    Each incident face's representative direction is projected on the vertex tangent plane
    (area-weighted vertex normal), raised to the ``N``-th power in the vertex frame and
    averaged with weights ``A_f |z_f|``. Returns ``(zv (n,), normal, t, b)`` with the vertex
    frames ``(t, b, normal)`` ``(n, 3)`` each; ``|zv|`` is small near singularities.
    """
    fr, z, N = _checked_field(fr, z, N)
    V, F = fr.vertices, fr.faces
    nv = vertex_normals(V, F)  # vertex frames (t, b, nv)
    t = np.cross(nv, np.where(np.abs(nv[:, [0]]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]]))
    t /= np.linalg.norm(t, axis=1, keepdims=True)
    b = np.cross(nv, t)
    d = field_vectors(z, fr, N)[:, 0, :]  # (m, 3)
    fi = np.repeat(np.arange(fr.n_faces), 3)
    vi = F.ravel()
    dd = d[fi]  # (3m, 3)
    ang = np.arctan2(np.einsum("ij,ij->i", dd, b[vi]), np.einsum("ij,ij->i", dd, t[vi]))
    w = (fr.area * np.abs(z))[fi]
    zv = np.bincount(vi, weights=w * np.cos(N * ang), minlength=fr.n_vertices) + 1j * np.bincount(
        vi, weights=w * np.sin(N * ang), minlength=fr.n_vertices)
    tot = np.bincount(vi, weights=fr.area[fi], minlength=fr.n_vertices)
    return zv / tot, nv, t, b


def _face_lookup(F1: np.ndarray, n1: int, tri: np.ndarray) -> np.ndarray:
    """Index of the face of ``F1`` equal to each row of ``tri`` up to a cyclic shift, or -1."""
    R = np.concatenate([np.roll(F1, -s, axis=1) for s in range(3)])  # every cyclic shift of every face
    keys = (R[:, 0] * n1 + R[:, 1]) * n1 + R[:, 2]
    ids = np.tile(np.arange(F1.shape[0]), 3)
    o = np.argsort(keys)
    keys, ids = keys[o], ids[o]
    q = (tri[:, 0] * n1 + tri[:, 1]) * n1 + tri[:, 2]
    pos = np.minimum(np.searchsorted(keys, q), keys.size - 1)
    return np.where(keys[pos] == q, ids[pos], -1)


def pushforward_field(fr1: Frames, z1: np.ndarray, fr2: Frames, p2p_21: np.ndarray, N: int = 4,
                      *, min_area_ratio: float = 1e-3):
    """Push an ``N``-direction field from shape 1 to shape 2 through a point map (evaluation only).

    ``p2p_21`` ``(n2,)`` gives for every vertex of shape 2 a vertex of shape 1. Face ``(a, b, c)``
    of shape 2 corresponds to the triangle ``P = (p[a], p[b], p[c])`` of shape 1; the affine map
    ``P -> face`` has differential ``dT`` (2x2 in the frames). The source directions at ``P`` are
    the directions of the face of shape 1 equal to ``P`` when there is one (same triangulation),
    otherwise the vertex-averaged field (:func:`vertex_power_field`) at the three corners,
    projected on the plane of ``P`` and averaged in the power domain. Each of the ``N``
    directions ``w`` is mapped to ``dT w`` and the result is the normalised mean of
    ``(dT w / |dT w|)^N`` (exact for conformal ``dT``).

    Returns ``(z2 (m2,) unit, valid (m2,) bool)``; faces whose image triangle is degenerate
    (area below ``min_area_ratio`` times the mean face area) are invalid and get 0.
    """
    fr1, z1, N = _checked_field(fr1, z1, N, "z1")
    fr2 = as_frames(fr2)
    p = check_p2p(p2p_21, fr1.n_vertices, fr2.n_vertices)
    tri = p[fr2.faces]  # (m2, 3) vertices of shape 1
    P = fr1.vertices[tri]  # (m2, 3, 3)
    valid, Pu, Pv = _image_frames(P, fr1, fr2, min_area_ratio)
    # source representative angle in the frame of P
    hit = _face_lookup(fr1.faces, fr1.n_vertices, tri)
    d_face = field_vectors(z1, fr1, N)[:, 0, :]  # (m1, 3)
    zv, nv, tv, bv = vertex_power_field(fr1, z1, N)
    av = np.angle(zv) / N
    dv = np.cos(av)[:, None] * tv + np.sin(av)[:, None] * bv  # (n1, 3) vertex representatives
    ang_face = np.arctan2(np.einsum("ij,ij->i", d_face[np.maximum(hit, 0)], Pv),
                          np.einsum("ij,ij->i", d_face[np.maximum(hit, 0)], Pu))
    D = dv[tri]  # (m2, 3, 3) at the corners
    a = np.arctan2(np.einsum("fcd,fd->fc", D, Pv), np.einsum("fcd,fd->fc", D, Pu))
    zc = np.sum(np.abs(zv[tri]) * np.exp(1j * N * a), axis=1)
    alpha = np.where(hit >= 0, ang_face, np.angle(zc) / N)  # (m2,)
    return _mapped_directions(alpha, P, Pu, Pv, valid, fr2, N), valid


def _image_frames(P: np.ndarray, fr1: Frames, fr2: Frames, min_area_ratio: float):
    """The non-degenerate image triangles ``P`` ``(m2, 3, 3)`` and the frames of their planes.

    ``P`` are the images on shape 1 of the faces of shape 2; returns ``(valid (m2,), Pu, Pv)``
    (a degenerate triangle gets its face's frame).
    """
    dbl = np.linalg.norm(np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0]), axis=1)
    valid = dbl > 2 * min_area_ratio * fr1.area.mean()
    _, Pu, Pv, _ = face_frames(np.where(valid[:, None, None], P, fr2.vertices[fr2.faces]).reshape(-1, 3),
                               np.arange(3 * fr2.n_faces).reshape(-1, 3))
    return valid, Pu, Pv


def _mapped_directions(alpha, P, Pu, Pv, valid, fr2: Frames, N: int) -> np.ndarray:
    """Unit power field of shape 2: the directions at ``alpha`` in the frames of ``P`` through ``dT`` (0 if invalid)."""
    # dT in frame coordinates: E2 = dT E1 with the two edge vectors as columns
    Q = fr2.vertices[fr2.faces]
    e1 = np.stack([P[:, 1] - P[:, 0], P[:, 2] - P[:, 0]], axis=2)  # (m2, 3, 2)
    e2 = np.stack([Q[:, 1] - Q[:, 0], Q[:, 2] - Q[:, 0]], axis=2)
    E1 = np.stack([np.einsum("ij,ijk->ik", Pu, e1), np.einsum("ij,ijk->ik", Pv, e1)], axis=1)  # (m2, 2, 2)
    E2 = np.stack([np.einsum("ij,ijk->ik", fr2.u, e2), np.einsum("ij,ijk->ik", fr2.v, e2)], axis=1)
    E1 = np.where(valid[:, None, None], E1, np.eye(2)[None])
    dT = E2 @ np.linalg.inv(E1)  # (m2, 2, 2)
    out = np.zeros(fr2.n_faces, dtype=np.complex128)
    for j in range(N):
        a = alpha + 2 * np.pi * j / N
        x = np.einsum("fij,fj->fi", dT, np.stack([np.cos(a), np.sin(a)], axis=1))  # (m2, 2)
        out += normalize_field(x[:, 0] + 1j * x[:, 1]) ** N
    return np.where(valid, normalize_field(out), 0.0)


def pushforward_field_barycentric(fr1: Frames, z1: np.ndarray, fr2: Frames, face_21: np.ndarray,
                                  bary_21: np.ndarray, N: int = 4, *, min_area_ratio: float = 1e-3):
    """Push an ``N``-direction field through a **surface** correspondence (evaluation only).

    The correspondence gives every vertex ``v`` of shape 2 a point of shape 1: the face
    ``face_21[v]`` of shape 1 and barycentric coordinates ``bary_21[v]`` ``(3,)`` in it (e.g.
    the closest point of a remeshed surface on its original triangulation, carried to another
    pose of that triangulation). Unlike :func:`pushforward_field` through a vertex-to-vertex
    map, nothing is snapped to the vertices of shape 1, so the image triangles are not distorted
    on a different triangulation.

    Face ``(a, b, c)`` of shape 2 corresponds to the triangle ``P`` of the three image points;
    the affine map ``P -> face`` has differential ``dT``. The source directions are those of the
    faces ``face_21[a], face_21[b], face_21[c]`` (their representative vectors projected on the
    plane of ``P``, averaged in the power domain); each of the ``N`` directions ``w`` is mapped to
    ``dT w`` and the result is the normalised mean of ``(dT w / |dT w|)^N``.

    Returns ``(z2 (m2,) unit, valid (m2,) bool)``; faces whose image triangle is degenerate
    (area below ``min_area_ratio`` times the mean face area of shape 1) are invalid and get 0.
    """
    fr1, z1, N = _checked_field(fr1, z1, N, "z1")
    fr2 = as_frames(fr2)
    fa = np.asarray(face_21, dtype=np.int64)
    bw = np.asarray(bary_21, dtype=np.float64)
    if fa.shape != (fr2.n_vertices,) or bw.shape != (fr2.n_vertices, 3):
        raise ValueError(f"face_21 must be (n2,) and bary_21 (n2, 3) with n2 = {fr2.n_vertices}; "
                         f"got {fa.shape} and {bw.shape}")
    if fa.min() < 0 or fa.max() >= fr1.n_faces:
        raise ValueError(f"face_21 indices must be in [0, {fr1.n_faces})")
    if not np.allclose(bw.sum(axis=1), 1.0, atol=1e-6) or bw.min() < -1e-6:
        raise ValueError("bary_21 rows must be barycentric coordinates (non-negative, summing to 1)")
    X = np.einsum("vc,vcd->vd", bw, fr1.vertices[fr1.faces[fa]])  # (n2, 3) image points on shape 1
    P = X[fr2.faces]  # (m2, 3, 3)
    valid, Pu, Pv = _image_frames(P, fr1, fr2, min_area_ratio)
    d_face = field_vectors(z1, fr1, N)[:, 0, :]  # (m1, 3)
    D = d_face[fa[fr2.faces]]  # (m2, 3, 3) the directions of the source faces at the corners
    a = np.arctan2(np.einsum("fcd,fd->fc", D, Pv), np.einsum("fcd,fd->fc", D, Pu))
    return _mapped_directions(np.angle(np.sum(np.exp(1j * N * a), axis=1)) / N, P, Pu, Pv, valid, fr2, N), valid


def closest_point_correspondence(V_query: np.ndarray, V: np.ndarray, F: np.ndarray):
    """Closest points of ``V_query`` ``(q, 3)`` on the mesh ``(V, F)``: ``(face (q,), bary (q, 3))``.

    Barycentric coordinates are clipped to the triangle (the closest point lies in it) and sum to 1.
    With ``(V, F)`` one pose of a triangulation, the same ``(face, bary)`` names the corresponding
    point on every other pose of it (the surface ground truth of a remeshed variant).
    """
    import igl

    V_query, V = (np.ascontiguousarray(x, dtype=np.float64) for x in (V_query, V))
    F = np.ascontiguousarray(F, dtype=np.int64)
    _, face, C = igl.point_mesh_squared_distance(V_query, V, F)
    face = np.asarray(face, dtype=np.int64).ravel()
    T = V[F[face]]  # (q, 3, 3)
    e0, e1, d = T[:, 1] - T[:, 0], T[:, 2] - T[:, 0], np.asarray(C) - T[:, 0]
    d00, d01, d11 = (e0 * e0).sum(1), (e0 * e1).sum(1), (e1 * e1).sum(1)
    d20, d21 = (d * e0).sum(1), (d * e1).sum(1)
    den = d00 * d11 - d01 ** 2
    b1 = (d11 * d20 - d01 * d21) / den
    b2 = (d00 * d21 - d01 * d20) / den
    B = np.clip(np.stack([1 - b1 - b2, b1, b2], axis=1), 0.0, 1.0)
    return face, B / B.sum(axis=1, keepdims=True)
