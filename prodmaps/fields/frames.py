"""Discrete tangent spaces of a triangle mesh: face frames, complex coordinates, transport.

Conventions
-----------
* **Face frames** are those of :func:`prodmaps.curvature.face_frames`: for face ``(i, j, k)``
  the unit normal ``n`` follows the right-hand rule on the face order, ``u`` is the unit edge
  ``i -> j`` and ``v = n x u``; ``(u, v, n)`` is right-handed.
* A tangent vector ``X`` of face ``f`` is the **complex number** ``<X, u_f> + i <X, v_f>``.
  Multiplying by ``i`` rotates by +90° about the normal (``n x X``).
* **Dual edges** join the two faces of an interior edge. Each is stored once as a pair
  ``(f, g)`` where ``f`` holds the half-edge ``a -> b`` and ``g`` the twin ``b -> a``.
* **Transport** (discrete Levi-Civita, by unfolding the two triangles about their shared edge):
  a vector at angle ``α`` in the frame of ``f`` has angle ``α + ρ_fg`` in the frame of ``g``
  with ``ρ_fg = θ_g(e) - θ_f(e)``, ``θ_h(e)`` the angle of the shared edge vector in the frame
  of ``h``. An ``N``-direction field stored as its ``N``-th power transports by ``exp(i N ρ)``.
  Around a vertex the transport angles add up to the angle defect ``2π - Σ corner angles``
  (mod ``2π``); :func:`vertex_holonomy` returns both so tests can check it.
* The **complex gradient** of a piecewise-linear function ``f`` (values at the vertices) in
  face ``f`` is ``∂_u f + i ∂_v f``: the gradient vector in complex coordinates.
* **Face -> vertex** transfer is the area-weighted average over the incident faces. With the
  lumped mass ``A`` this is the weak form: ``A S h = (1/3) Σ_f A_f h_f`` over the faces of each
  vertex, i.e. ``∫ φ_i h`` with ``h`` constant per face and ``φ_i`` the hat functions integrated
  with the barycentric quadrature.

Everything is vectorised over faces/half-edges; the arrays are plain numpy/scipy.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from ..curvature import face_frames
from ..mesh import Mesh, check_mesh
from ..pointcloud import PointCloud

__all__ = [
    "Frames", "tangent_frames", "mesh_frames", "as_frames", "to_complex", "to_vectors", "halfedges", "dual_edges",
    "transport_angles", "corner_angles", "polygon_corner_degrees", "angle_defect", "vertex_holonomy",
    "complex_gradient", "face_to_vertex", "wrap_angle",
]


def wrap_angle(a):
    """Wrap angles to ``[-π, π)``."""
    return (np.asarray(a) + np.pi) % (2 * np.pi) - np.pi


@dataclass(frozen=True, eq=False)
class Frames:
    """Per-face tangent frames of a mesh (see the module doc).

    Attributes: ``normal``, ``u``, ``v`` ``(m, 3)`` unit; ``area`` ``(m,)``; ``vertices``
    ``(n, 3)`` and ``faces`` ``(m, 3)`` they were built from.
    """

    vertices: np.ndarray
    faces: np.ndarray
    normal: np.ndarray
    u: np.ndarray
    v: np.ndarray
    area: np.ndarray
    n_vertices = Mesh.n_vertices  # the same properties as a mesh's: vertices.shape[0], faces.shape[0]
    n_faces = Mesh.n_faces

    @property
    def centroids(self) -> np.ndarray:
        """Face centroids ``(m, 3)``."""
        return self.vertices[self.faces].mean(axis=1)


def tangent_frames(V: np.ndarray, F: np.ndarray) -> Frames:
    """Face frames of ``(V (n, 3), F (m, 3))`` (see the module doc)."""
    V = np.asarray(V, dtype=np.float64)
    F = np.asarray(F, dtype=np.int64)
    if V.ndim != 2 or V.shape[1] != 3 or F.ndim != 2 or F.shape[1] != 3:
        raise ValueError(f"expected V (n, 3) and F (m, 3); got {V.shape} and {F.shape}")
    n, u, v, area = face_frames(V, F)
    if not np.all(np.isfinite(n)) or np.any(area <= 0):
        raise ValueError("degenerate faces (zero area): repair the mesh (prodmaps.mesh.repair)")
    return Frames(V, F, n, u, v, area)


def mesh_frames(mesh: Mesh) -> Frames:
    """:func:`tangent_frames` of a :class:`prodmaps.Mesh`."""
    mesh = check_mesh(mesh, "mesh_frames (tangent fields)")
    return tangent_frames(mesh.vertices, mesh.faces)


def as_frames(x) -> Frames:
    """``x`` itself if it is :class:`Frames`, the frames of ``x`` if it is a :class:`prodmaps.Mesh`.

    Every function of :mod:`prodmaps.fields` taking frames ``fr`` also accepts a mesh.
    """
    if isinstance(x, Frames):
        return x
    if isinstance(x, (Mesh, PointCloud)):
        return mesh_frames(x)  # a point cloud: NeedsFacesError
    raise TypeError(f"expected prodmaps.fields.Frames or a prodmaps.Mesh, got {type(x).__name__}")


def to_complex(X: np.ndarray, fr: Frames) -> np.ndarray:
    """Complex coordinates ``(m,)`` of tangent vectors ``X`` ``(m, 3)`` (normal part dropped)."""
    X = np.asarray(X, dtype=np.float64)
    if X.shape != fr.u.shape:
        raise ValueError(f"X must have shape {fr.u.shape} (one 3D vector per face); got {X.shape}")
    return np.einsum("ij,ij->i", X, fr.u) + 1j * np.einsum("ij,ij->i", X, fr.v)


def to_vectors(z: np.ndarray, fr: Frames) -> np.ndarray:
    """3D tangent vectors ``(m, 3)`` of complex coordinates ``z`` ``(m,)``."""
    z = np.asarray(z)
    if z.shape != (fr.n_faces,):
        raise ValueError(f"z must have shape ({fr.n_faces},); got {z.shape}")
    return z.real[:, None] * fr.u + z.imag[:, None] * fr.v


def halfedges(F: np.ndarray):
    """Half-edges of a triangle list.

    Returns ``(tail (3m,), head (3m,), face (3m,), twin (3m,))``: half-edge ``h = 3 f + c`` goes
    from ``F[f, c]`` to ``F[f, (c+1) % 3]``; ``twin[h]`` is the opposite half-edge or ``-1``
    on a boundary. Non-manifold edges raise ``ValueError``.
    """
    F = np.asarray(F, dtype=np.int64)
    m = F.shape[0]
    tail = F.ravel()  # (3m,) F[f, c]
    head = F[:, [1, 2, 0]].ravel()  # (3m,) F[f, c+1]
    face = np.repeat(np.arange(m), 3)
    n = int(F.max()) + 1 if m else 0
    key = tail * n + head
    order = np.argsort(key)
    skey = key[order]
    if np.any(skey[1:] == skey[:-1]):
        raise ValueError("a directed edge appears twice: the mesh is non-manifold or badly oriented")
    tkey = head * n + tail
    pos = np.minimum(np.searchsorted(skey, tkey), skey.size - 1)
    return tail, head, face, np.where(skey[pos] == tkey, order[pos], -1)


def dual_edges(fr: Frames):
    """Interior edges as dual edges ``(f, g)`` with their geometry.

    Returns a dict with ``f``, ``g`` ``(E,)`` face indices (``f`` holds half-edge ``a -> b``,
    ``g`` its twin), ``a``, ``b`` ``(E,)`` vertex indices, ``h`` ``(E,)`` the half-edge index
    in ``f`` and ``rho`` ``(E,)`` the transport angle ``f -> g`` (see the module doc).
    """
    tail, head, face, twin = halfedges(fr.faces)
    h = np.flatnonzero((twin >= 0) & (np.arange(twin.size) < np.maximum(twin, 0)))
    return {"f": face[h], "g": face[twin[h]], "a": tail[h], "b": head[h], "h": h, "rho": transport_angles(fr)[h]}


def transport_angles(fr: Frames) -> np.ndarray:
    """Transport angle of every half-edge ``h`` from its face to its twin's face ``(3m,)``.

    ``NaN`` on boundary half-edges.
    """
    tail, head, face, twin = halfedges(fr.faces)
    ok = twin >= 0
    e = fr.vertices[head] - fr.vertices[tail]  # (3m, 3)
    g = np.where(ok, face[np.maximum(twin, 0)], 0)
    th_f, th_g = (np.arctan2(np.einsum("ij,ij->i", e, fr.v[h]), np.einsum("ij,ij->i", e, fr.u[h])) for h in (face, g))
    return np.where(ok, wrap_angle(th_g - th_f), np.nan)


def corner_angles(V: np.ndarray, F: np.ndarray) -> np.ndarray:
    """Interior angle in radians at each corner ``(m, 3)`` (see :func:`polygon_corner_degrees` for polygons)."""
    P = V[F]  # (m, 3, 3)
    e1, e2 = np.roll(P, -1, axis=1) - P, np.roll(P, -2, axis=1) - P  # (m, 3, 3): the two edges at each corner
    return np.arctan2(np.linalg.norm(np.cross(e1, e2), axis=2), np.einsum("mcd,mcd->mc", e1, e2))


def polygon_corner_degrees(P: np.ndarray) -> np.ndarray:
    """Interior angles in **degrees** ``(m, c)`` at the corners of polygons ``P`` ``(m, c, 3)``.

    Corners in cyclic order, any ``c``: the quad measures of Figure 14.

    Unlike :func:`corner_angles` (triangles of a mesh, radians, by ``arctan2``), by ``arccos`` of
    the normalised dot product of the two edges at each corner.
    """
    prev, nxt = np.roll(P, 1, axis=1) - P, np.roll(P, -1, axis=1) - P  # (m, c, 3)
    cos = np.einsum("mcd,mcd->mc", prev, nxt) / (np.linalg.norm(prev, axis=2) * np.linalg.norm(nxt, axis=2) + 1e-300)
    return np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))


def angle_defect(V: np.ndarray, F: np.ndarray) -> np.ndarray:
    """Angle defect ``2π - Σ corner angles`` per vertex ``(n,)`` (discrete Gaussian curvature).

    On a closed mesh the defects sum to ``2π χ`` (Gauss–Bonnet). Boundary vertices get
    ``π - Σ angles`` (geodesic curvature).
    """
    V = np.asarray(V, dtype=np.float64)
    F = np.asarray(F, dtype=np.int64)
    n = V.shape[0]
    s = np.bincount(F.ravel(), weights=corner_angles(V, F).ravel(), minlength=n)
    tail, head, face, twin = halfedges(F)
    on_bd = np.zeros(n, bool)
    on_bd[tail[twin < 0]] = True
    return np.where(on_bd, np.pi, 2 * np.pi) - s


def vertex_holonomy(fr: Frames) -> np.ndarray:
    """Sum of the transport angles of the dual cycle around each vertex, counter-clockwise.

    Going counter-clockwise around vertex ``v`` (about the outward normal) crosses, for every
    half-edge ``x -> v`` of face ``f``, from ``f`` to the face of its twin. Returns ``(n,)``;
    it equals :func:`angle_defect` modulo ``2π`` on interior vertices.
    """
    tail, head, face, twin = halfedges(fr.faces)
    rho = transport_angles(fr)
    ok = twin >= 0
    return np.bincount(head[ok], weights=rho[ok], minlength=fr.n_vertices)


def complex_gradient(fr: Frames) -> sp.csr_matrix:
    """Complex gradient operator ``G`` ``(m, n)``: ``(G f)_face = ∂_u f + i ∂_v f``.

    For face ``(i, j, k)``, ``∇φ_i = n x e_i / (2 A)`` with ``e_i = x_k - x_j`` the edge
    opposite ``i`` (counter-clockwise); ``n x`` is multiplication by ``i`` in complex
    coordinates.
    """
    V, F = fr.vertices, fr.faces
    m, n = F.shape[0], V.shape[0]
    E = V[np.roll(F, -2, axis=1)] - V[np.roll(F, -1, axis=1)]  # (m, 3, 3) the edge opposite each corner
    ec = np.einsum("mcd,md->mc", E, fr.u) + 1j * np.einsum("mcd,md->mc", E, fr.v)
    vals = 1j * ec / (2 * fr.area[:, None])
    return sp.csr_matrix((vals.ravel(), (np.repeat(np.arange(m), 3), F.ravel())), shape=(m, n))


def face_to_vertex(fr: Frames) -> sp.csr_matrix:
    """Area-weighted face -> vertex averaging ``S`` ``(n, m)`` (rows sum to 1)."""
    F = fr.faces
    m, n = F.shape[0], fr.n_vertices
    P = sp.csr_matrix((np.repeat(fr.area, 3), (F.ravel(), np.repeat(np.arange(m), 3))), shape=(n, m))
    s = np.asarray(P.sum(axis=1)).ravel()
    return (sp.diags(1.0 / s) @ P).tocsr()
