"""Discrete Laplace–Beltrami operators: cotangent stiffness ``W`` and mass ``A``.

Conventions
-----------
* ``W`` is the positive semi-definite cotangent stiffness matrix (``W @ 1 == 0``,
  ``f^T W f = ∫|∇f|²`` for piecewise-linear ``f``), so eigenpairs solve ``W φ = λ A φ`` with
  ``λ >= 0``.
* ``A`` is the lumped (barycentric) mass: each vertex gets one third of the area of every
  incident triangle. It is returned as a vector ``(n,)`` (the diagonal). With
  ``mass="full"`` the consistent FEM mass matrix is returned instead, as a sparse ``(n, n)``
  matrix (``area/6`` on the diagonal, ``area/12`` off it, per triangle).
* Boundaries: natural (Neumann) boundary condition; a boundary edge has one cotangent term.
* ``kind="robust"`` uses the intrinsic-Delaunay Laplacian of Sharp & Crane (2020) through
  the ``robust_laplacian`` package (optional dependency), which stays well behaved on
  meshes with thin or obtuse triangles, and is defined on meshes the cotangent Laplacian is
  not (duplicate faces, non-manifold edges and vertices: build them with ``validate=False``);
  its mass is the lumped (Voronoi-free barycentric) mass of the intrinsic mesh.
  ``mass="full"`` is not available there.
* A :class:`prodmaps.PointCloud` has one Laplacian, the point-cloud Laplacian of the same paper
  (``robust_laplacian.point_cloud_laplacian``: the local Delaunay triangulation of each point's
  ``CLOUD_NEIGHBORS`` nearest neighbours, intrinsically mollified), with its lumped mass;
  ``kind=None`` or ``"robust"`` selects it, ``"cotan"`` raises :class:`prodmaps.NeedsFacesError`.
* :func:`anisotropic_laplacian` is the FEM stiffness of ``-div(D ∇f)`` with a per-face
  conductivity aligned with the principal curvature directions [ACR14] (used by AWFT).

[ACR14] Andreux, Rodolà, Aubry, Cremers. Anisotropic Laplace-Beltrami operators for shape
analysis. ECCV workshops 2014.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from .curvature import face_frames, principal_curvatures
from .mesh import Mesh, check_mesh, face_areas, needs_faces
from .pointcloud import PointCloud

__all__ = ["laplacian", "cotan_weights", "lumped_mass", "fem_mass", "anisotropic_laplacian", "KINDS", "CLOUD_NEIGHBORS",
           "MOLLIFY_FACTOR"]

KINDS = ("cotan", "robust")
CLOUD_NEIGHBORS = 30
"""Neighbours of each point in the point-cloud Laplacian (robust-laplacian's default)."""
MOLLIFY_FACTOR = 1e-5
"""Intrinsic mollification of the robust Laplacians, relative to the mean edge length (robust-laplacian's default)."""


def _robust_laplacian():
    try:
        import robust_laplacian
    except ImportError as exc:  # pragma: no cover - depends on the environment
        raise ImportError("kind='robust' and point clouds need the optional package robust-laplacian: "
                          "pip install robust-laplacian (or the extra: pip install 'prodmaps[geometry]')") from exc
    return robust_laplacian


def cotan_weights(vertices: np.ndarray, faces: np.ndarray) -> sp.csr_matrix:
    """PSD cotangent stiffness matrix ``W`` ``(n, n)``: ``W_ij = -(cot α_ij + cot β_ij)/2``."""
    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces, dtype=np.int64)
    n = v.shape[0]
    rows, cols, vals = [], [], []
    for c in range(3):  # corner c is opposite edge (i, j)
        i, j, k = f[:, (c + 1) % 3], f[:, (c + 2) % 3], f[:, c]
        e1 = v[i] - v[k]  # (m, 3)
        e2 = v[j] - v[k]  # (m, 3)
        cross = np.linalg.norm(np.cross(e1, e2), axis=1)
        cot = np.einsum("ij,ij->i", e1, e2) / np.maximum(cross, np.finfo(float).tiny)
        rows += [i, j]
        cols += [j, i]
        vals += [-0.5 * cot, -0.5 * cot]
    off = sp.coo_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(n, n)).tocsr()
    diag = -np.asarray(off.sum(axis=1)).ravel()
    return (off + sp.diags(diag)).tocsr()


def lumped_mass(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Barycentric lumped mass ``(n,)``: a third of each incident triangle's area."""
    a = face_areas(vertices, faces) / 3.0
    n = np.asarray(vertices).shape[0]
    return np.bincount(np.asarray(faces).ravel(), weights=np.repeat(a, 3), minlength=n)


def fem_mass(vertices: np.ndarray, faces: np.ndarray) -> sp.csr_matrix:
    """Consistent (full) piecewise-linear FEM mass matrix ``(n, n)``."""
    f = np.asarray(faces, dtype=np.int64)
    a = face_areas(vertices, f)
    n = np.asarray(vertices).shape[0]
    rows = np.concatenate([f[:, i] for i in range(3) for _ in range(3)])
    cols = np.concatenate([f[:, j] for _ in range(3) for j in range(3)])
    w = np.concatenate([a / (6.0 if i == j else 12.0) for i in range(3) for j in range(3)])
    return sp.coo_matrix((w, (rows, cols)), shape=(n, n)).tocsr()


def laplacian(mesh, kind: str | None = None, mass: str = "lumped"):
    """Stiffness and mass of a mesh or a point cloud: returns ``(W, A)``.

    The weak Laplace–Beltrami problem is ``W φ = λ A φ`` with ``W`` positive semi-definite
    (natural boundary condition on open meshes).

    Parameters
    ----------
    mesh : Mesh or PointCloud
        The surface (a mesh built with ``validate=False`` is accepted: ``kind="robust"`` is
        defined on duplicate faces and non-manifold edges).
    kind : ``None`` (default: ``"cotan"`` on a mesh, the point-cloud Laplacian on a cloud),
        ``"cotan"`` or ``"robust"`` (intrinsic Delaunay on a mesh, the point-cloud Laplacian on a
        cloud; needs ``robust_laplacian``). See the module doc.
    mass : ``"lumped"`` (default, ``A`` is an ``(n,)`` vector) or ``"full"`` (sparse FEM mass,
        ``kind="cotan"`` only).

    Returns
    -------
    W : (n, n) scipy.sparse.csr_matrix
        Symmetric stiffness (cotangent weights), ``W @ 1 = 0``.
    A : (n,) ndarray or (n, n) scipy.sparse.csr_matrix
        Lumped vertex areas (one third of the adjacent triangles' areas), or the FEM mass.

    Raises
    ------
    TypeError
        If ``mesh`` is neither a :class:`prodmaps.Mesh` nor a :class:`prodmaps.PointCloud`.
    ValueError
        For an unknown ``kind`` or ``mass``.
    NeedsFacesError
        For ``kind="cotan"`` on a point cloud.
    ImportError
        For ``kind="robust"`` or a point cloud without the ``robust_laplacian`` package.

    Examples
    --------
    >>> import numpy as np
    >>> import prodmaps as pm
    >>> from prodmaps.mesh import ellipsoid
    >>> mesh = ellipsoid(2)
    >>> W, A = pm.laplacian(mesh)
    >>> W.shape, A.shape
    ((162, 162), (162,))
    >>> bool(np.allclose(W @ np.ones(162), 0)), bool(np.isclose(A.sum(), mesh.area))
    (True, True)
    >>> Wc, Ac = pm.laplacian(pm.PointCloud(mesh.vertices))  # the point-cloud Laplacian
    >>> Wc.shape, bool(np.allclose(Wc @ np.ones(162), 0)), bool(abs(Ac.sum() / mesh.area - 1) < 0.05)
    ((162, 162), True, True)
    """
    if mass not in ("lumped", "full"):
        raise ValueError(f"mass must be 'lumped' or 'full', got {mass!r}")
    if kind is not None and kind not in KINDS:
        raise ValueError(f"kind must be 'cotan' or 'robust' (or None), got {kind!r}")
    if isinstance(mesh, PointCloud):
        if kind == "cotan":
            raise needs_faces("laplacian(kind='cotan')", mesh, "a point cloud has the point-cloud Laplacian, "
                              "kind=None or kind='robust'")
        if mass != "lumped":
            raise ValueError("a point cloud's Laplacian provides only the lumped mass")
        L, M = _robust_laplacian().point_cloud_laplacian(np.asarray(mesh.points), mollify_factor=MOLLIFY_FACTOR,
                                                         n_neighbors=CLOUD_NEIGHBORS)
        return sp.csr_matrix(L), np.asarray(M.diagonal(), dtype=np.float64)
    mesh = check_mesh(mesh)
    if kind in (None, "cotan"):
        W = cotan_weights(mesh.vertices, mesh.faces)
        A = lumped_mass(mesh.vertices, mesh.faces) if mass == "lumped" else fem_mass(mesh.vertices, mesh.faces)
        return W, A
    if mass != "lumped":
        raise ValueError("kind='robust' provides only the lumped mass")
    L, M = _robust_laplacian().mesh_laplacian(np.asarray(mesh.vertices), np.asarray(mesh.faces),
                                              mollify_factor=MOLLIFY_FACTOR)
    return sp.csr_matrix(L), np.asarray(M.diagonal(), dtype=np.float64)


def anisotropic_laplacian(mesh: Mesh, angle: float, alpha: float,
                          curvature: dict | None = None) -> tuple[sp.csr_matrix, np.ndarray]:
    """Anisotropic stiffness ``W_αθ`` (PSD, ``(n, n)``) and lumped mass ``A`` ``(n,)``.

    Linear FEM for ``-div(D ∇f)`` with a constant-per-face conductivity tensor
    ``D = w wᵀ + (1/(1+α)) w⊥ w⊥ᵀ``, ``w = cos θ d_max + sin θ d_min`` the maximal principal
    curvature direction rotated by ``θ`` in the face plane, ``w⊥ = n × w`` (ACR14/MRCB16 with a
    constant anisotropy: diffusion slowed by ``1+α`` across ``w``). ``W_ij = Σ_f area_f ∇b_iᵀ D ∇b_j``
    (``b_i`` the hat functions); ``α = 0`` gives the cotangent Laplacian exactly. ``θ`` in radians.
    """
    mesh = check_mesh(mesh, "anisotropic_laplacian")
    if not np.isfinite(alpha) or alpha < 0:
        raise ValueError(f"alpha must be >= 0, got {alpha!r}")
    if not np.isfinite(angle):
        raise ValueError(f"angle must be finite, got {angle!r}")
    V, F = mesh.vertices, mesh.faces
    n = V.shape[0]
    curv = principal_curvatures(mesh) if curvature is None else curvature
    fn, _, _, area = face_frames(V, F)
    w1 = np.cos(angle) * curv["dir_max"] + np.sin(angle) * curv["dir_min"]  # (m, 3)
    w2 = np.cross(fn, w1)
    # gradient of the hat function at corner c: n × (opposite edge) / (2 area), along w1 and w2
    grads = [np.cross(fn, V[F[:, (c + 2) % 3]] - V[F[:, (c + 1) % 3]]) / (2.0 * area[:, None]) for c in range(3)]
    g = [(np.einsum("ij,ij->i", gc, w1), np.einsum("ij,ij->i", gc, w2)) for gc in grads]
    d_perp = 1.0 / (1.0 + alpha)
    ab = [(a, b) for a in range(3) for b in range(3)]
    vals = [area * (g[a][0] * g[b][0] + d_perp * g[a][1] * g[b][1]) for a, b in ab]
    rows, cols = np.concatenate([F[:, a] for a, _ in ab]), np.concatenate([F[:, b] for _, b in ab])
    W = sp.coo_matrix((np.concatenate(vals), (rows, cols)), shape=(n, n)).tocsr()
    W = 0.5 * (W + W.T)
    return W.tocsr(), lumped_mass(V, F)

