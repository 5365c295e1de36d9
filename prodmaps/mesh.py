"""Triangle meshes: the :class:`Mesh` container, its validation, and explicit repairs.

Conventions
-----------
* ``vertices``: ``(n, 3)`` float64 positions.
* ``faces``: ``(m, 3)`` int64, 0-based vertex indices, one row per triangle.
* A valid mesh is non-empty, finite, triangular, has no degenerate (zero-area) or
  duplicate faces, no unreferenced vertices, only manifold edges (each edge in at most
  two faces) and exactly one connected component.
* Validation also **warns** (:class:`prodmaps.MeshWarning`) about what loads but is probably not
  meant: boundary vertices that coincide within ``COINCIDENT_TOL`` of the bounding-box diagonal (a
  seam or a triangle soup: the surface is cut there, and its spectrum is that of the cut surface;
  coincident vertices inside a closed surface, two sheets touching at a point, are harmless), bowtie
  vertices (separate fans of faces meeting at one vertex) and inconsistently oriented faces
  (harmless to the Laplacian, which uses angles and areas only, but not to normals, curvature,
  SHOT, AWFT or cross fields). Each warning names its repair.
* Open boundaries are allowed. The cotangent Laplacian built on such a mesh
  (:func:`prodmaps.laplacian`) uses the **natural (Neumann) boundary condition**:
  boundary edges simply carry one cotangent weight, so the normal derivative of the
  eigenfunctions vanishes on the boundary and the constant function stays in the kernel.

Validation runs when a :class:`Mesh` is built and raises :class:`MeshError` naming the
problem and the repair helper that fixes it. Repairs are never implicit: call
:func:`repair` (or the individual helpers) yourself, so that vertex indices (and with them
ground-truth correspondences) change only when you ask. A mesh the cotangent Laplacian cannot
use (duplicate faces, non-manifold edges) can still get a basis unrepaired:
``pm.eigenbasis(pm.Mesh(v, f, validate=False), k, kind="robust")`` (intrinsic Delaunay).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import breadth_first_order, connected_components
from scipy.spatial import cKDTree

from .errors import MeshError, MeshWarning, NeedsFacesError
from .pointcloud import PointCloud

__all__ = ["Mesh", "MeshError", "NeedsFacesError", "MeshWarning", "COINCIDENT_TOL", "validate", "face_areas",
           "face_normals", "face_mean_ratio", "face_radius_ratio", "vertex_normals", "check_mesh",
           "check_vertex_indices", "edges", "boundary_edges", "graph_components", "face_components",
           "mean_edge_length", "needs_faces", "coincident_vertices", "boundary_vertices", "bowtie_vertices",
           "misoriented_edges", "triangulate_polygons", "largest_component", "remove_unreferenced_vertices",
           "remove_degenerate_faces", "remove_duplicate_faces", "merge_vertices", "split_bowtie_vertices",
           "orient_faces", "RepairReport", "repair", "subdivide_midpoint", "icosphere", "ellipsoid"]

COINCIDENT_TOL = 1e-7
"""Vertices closer than this fraction of the bounding-box diagonal count as one point (merged by the repair)."""


def face_areas(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Area of every triangle, ``(m,)``."""
    v = np.asarray(vertices, dtype=np.float64)
    e1 = v[faces[:, 1]] - v[faces[:, 0]]  # (m, 3)
    e2 = v[faces[:, 2]] - v[faces[:, 0]]  # (m, 3)
    return 0.5 * np.linalg.norm(np.cross(e1, e2), axis=1)


def face_normals(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Unit normal of every triangle (right-hand rule on the face order), ``(m, 3)``."""
    v = np.asarray(vertices, dtype=np.float64)
    n = np.cross(v[faces[:, 1]] - v[faces[:, 0]], v[faces[:, 2]] - v[faces[:, 0]])
    norm = np.linalg.norm(n, axis=1, keepdims=True)
    return n / np.where(norm > 0, norm, 1.0)


def vertex_normals(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Area-weighted unit vertex normals, ``(n, 3)``."""
    v = np.asarray(vertices, dtype=np.float64)
    fn = np.cross(v[faces[:, 1]] - v[faces[:, 0]], v[faces[:, 2]] - v[faces[:, 0]])  # (m,3), |.|=2*area
    vn = np.zeros_like(v)
    for c in range(3):
        np.add.at(vn, faces[:, c], fn)
    norm = np.linalg.norm(vn, axis=1, keepdims=True)
    return vn / np.where(norm > 0, norm, 1.0)


def face_mean_ratio(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Triangle quality ``4·sqrt(3)·area / Σ edge²`` per face, ``(m,)``: 1 equilateral, 0 degenerate.

    The mean-ratio measure, from the area and the squared edge lengths; Figure 9 plots it.
    :func:`face_radius_ratio` is the other common measure (a different number for the same face).

    Examples
    --------
    >>> import numpy as np
    >>> from prodmaps.mesh import face_mean_ratio
    >>> V = np.array([[0.0, 0, 0], [1, 0, 0], [0.5, np.sqrt(3) / 2, 0], [2, 0, 0]])
    >>> np.round(face_mean_ratio(V, np.array([[0, 1, 2], [0, 3, 1]])), 6)  # equilateral, degenerate
    array([1., 0.])
    """
    V, F = np.asarray(vertices, dtype=np.float64), np.asarray(faces)
    e2 = sum(np.sum((V[F[:, i]] - V[F[:, (i + 1) % 3]]) ** 2, axis=1) for i in range(3))
    return 4 * np.sqrt(3) * face_areas(V, F) / e2


def face_radius_ratio(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Triangle quality ``2 r / R`` per face (inradius over circumradius), ``(m,)``: 1 equilateral, 0 degenerate.

    The radius-ratio measure, from the edge lengths (Heron's formula); the variant recipes of
    :mod:`prodmaps.prepare.variants` count their thin triangles with it. :func:`face_mean_ratio` is
    the other common measure.

    Examples
    --------
    >>> import numpy as np
    >>> from prodmaps.mesh import face_mean_ratio, face_radius_ratio
    >>> right = (np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]), np.array([[0, 1, 2]]))  # right isosceles
    >>> print(f"{face_radius_ratio(*right)[0]:.4f} (2r/R) vs {face_mean_ratio(*right)[0]:.4f} (mean ratio)")
    0.8284 (2r/R) vs 0.8660 (mean ratio)
    """
    V, F = np.asarray(vertices), np.asarray(faces)
    a, b, c = (np.linalg.norm(V[F[:, (k + 1) % 3]] - V[F[:, (k + 2) % 3]], axis=1) for k in range(3))  # opposite k
    s = 0.5 * (a + b + c)
    area2 = np.maximum(s * (s - a) * (s - b) * (s - c), 0.0)  # Heron, squared area
    return 8.0 * area2 / np.maximum(s * a * b * c, np.finfo(float).tiny)


def check_mesh(mesh, what: str | None = None) -> Mesh:
    """``mesh`` if it is a :class:`Mesh`, else a ``TypeError`` (the one check of a mesh argument).

    A :class:`prodmaps.PointCloud` raises :class:`prodmaps.NeedsFacesError` naming ``what`` (the
    function that needs faces). The checks of a mesh live here, the lowest module
    (:mod:`prodmaps.operators` and :mod:`prodmaps.curvature` use them); the checks that need a basis
    are in :mod:`prodmaps.checks`.

    Examples
    --------
    >>> check_mesh(ellipsoid(1)).n_vertices
    42
    >>> check_mesh("bunny.ply")
    Traceback (most recent call last):
    ...
    TypeError: expected a prodmaps.Mesh, got str (use pm.load_mesh)
    """
    if isinstance(mesh, PointCloud):
        raise needs_faces(what or "this function", mesh)
    if not isinstance(mesh, Mesh):
        raise TypeError(f"expected a prodmaps.Mesh, got {type(mesh).__name__} (use pm.load_mesh)")
    return mesh


def needs_faces(what: str, cloud=None, instead: str = "") -> NeedsFacesError:
    """The :class:`prodmaps.NeedsFacesError` of ``what`` (a function name) given a point cloud.

    ``instead`` names a point-cloud alternative when there is one; otherwise the message says to
    reconstruct a surface first. Returned, not raised (``raise needs_faces("shot", cloud)``).
    """
    label = f" {cloud.name!r}" if getattr(cloud, "name", "") else ""
    way = instead or ("reconstruct a triangle mesh from the cloud first (e.g. screened Poisson in pymeshlab or "
                      "Open3D) and load it with pm.load_mesh; everything that needs only a basis (pm.eigenbasis "
                      "of the cloud) works on the cloud itself")
    return NeedsFacesError(f"{what} needs a triangle mesh (faces), got a PointCloud{label}: {way}")


def check_vertex_indices(idx, n: int, name: str = "indices") -> np.ndarray:
    """``idx`` (any shape) as int64, after checking it holds integer vertex indices in ``[0, n)``.

    The one check behind point maps (:func:`prodmaps.checks.check_p2p`), geodesic sources and
    sampled vertices; an empty array passes whatever its dtype.
    """
    p = np.asarray(idx)
    if p.size and not np.issubdtype(p.dtype, np.integer):
        raise ValueError(f"{name} must contain integer vertex indices, got dtype {p.dtype}")
    if p.size and (p.min() < 0 or p.max() >= n):
        raise ValueError(f"{name} indices out of range: they must be in [0, {n}), got [{p.min()}, {p.max()}]")
    return p.astype(np.int64)


def edges(faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unique undirected edges ``(e, 2)`` (sorted pairs) and how many faces use each ``(e,)``."""
    faces = np.asarray(faces)
    if faces.size == 0:
        return np.zeros((0, 2), dtype=faces.dtype), np.zeros(0, dtype=np.int64)
    half = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])  # (3m, 2)
    half.sort(axis=1)
    # one int64 key a·n + b per edge (lexicographic order = key order): a 1D unique, ~10x faster
    # than np.unique(axis=0), same answer
    n = np.int64(half.max()) + 1
    key, counts = np.unique(half[:, 0].astype(np.int64) * n + half[:, 1], return_counts=True)
    uniq = np.column_stack([key // n, key % n]).astype(half.dtype, copy=False)
    return uniq, counts


def boundary_edges(faces: np.ndarray) -> np.ndarray:
    """Edges used by exactly one face, ``(b, 2)``."""
    e, c = edges(faces)
    return e[c == 1]


def mean_edge_length(vertices: np.ndarray, faces: np.ndarray) -> float:
    """Mean length of the unique edges (mesh units): the mesh's resolution.

    Parameters
    ----------
    vertices : (n, 3) float array
    faces : (m, 3) int array

    Returns
    -------
    float, the mean over :func:`edges` (each edge counted once however many faces share it).

    Examples
    --------
    >>> import numpy as np
    >>> from prodmaps.mesh import mean_edge_length
    >>> mean_edge_length(np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]), np.array([[0, 1, 2]]))  # (1 + 1 + √2) / 3
    1.1380711874576983
    """
    e, _ = edges(np.asarray(faces))
    vertices = np.asarray(vertices)
    return float(np.linalg.norm(vertices[e[:, 1]] - vertices[e[:, 0]], axis=1).mean())


def graph_components(n: int, a: np.ndarray, b: np.ndarray) -> tuple[int, np.ndarray]:
    """Connected components of the undirected graph on ``n`` nodes with edges ``a[i] - b[i]``.

    Returns ``(count, labels (n,))`` as :func:`scipy.sparse.csgraph.connected_components`: a
    mesh's components (its vertices joined by the face edges), the quad extraction's chains.

    Examples
    --------
    >>> import numpy as np
    >>> from prodmaps.mesh import graph_components
    >>> graph_components(5, np.array([0, 3]), np.array([1, 4]))
    (3, array([0, 0, 1, 2, 2], dtype=int32))
    """
    adj = sp.coo_matrix((np.ones(np.size(a)), (a, b)), shape=(n, n))
    return connected_components(adj, directed=False)


def face_components(n: int, faces: np.ndarray) -> tuple[int, np.ndarray]:
    """:func:`graph_components` of ``n`` vertices joined by the face edges: ``(count, labels (n,))``.

    Examples
    --------
    >>> face_components(5, np.array([[0, 1, 2]]))  # one triangle and two lone vertices
    (3, array([0, 0, 0, 1, 2], dtype=int32))
    """
    return graph_components(n, np.concatenate([faces[:, 0], faces[:, 1], faces[:, 2]]),
                            np.concatenate([faces[:, 1], faces[:, 2], faces[:, 0]]))


_REPAIR = ("use prodmaps.mesh.repair(vertices, faces), which drops them and the vertices they leave unreferenced "
           "(or load the file with pm.io.load_mesh_repaired(path))")
_ROBUST = ("keep the mesh as it is: pm.load_mesh(path, validate=False) (or pm.Mesh(vertices, faces, validate=False)) "
           "and build its basis with pm.eigenbasis(mesh, k, kind='robust') (the intrinsic-Delaunay Laplacian, "
           "defined there)")


def validate(vertices: np.ndarray, faces: np.ndarray, area_tol: float = 1e-14, *,
             coincident_tol: float = COINCIDENT_TOL, warn: bool = True) -> None:
    """Raise :class:`MeshError` if ``(vertices, faces)`` is not a valid triangle mesh.

    ``area_tol`` is relative to the squared bounding-box diagonal: a face whose area is below
    ``area_tol * diag**2`` counts as degenerate. With ``warn``, a valid mesh is also checked for
    what loads but is probably not meant, each a :class:`prodmaps.MeshWarning` naming its repair
    (module doc): boundary vertices within ``coincident_tol`` of the bounding-box diagonal of each
    other (:func:`coincident_vertices`), bowtie vertices (:func:`bowtie_vertices`), inconsistently
    oriented faces (:func:`misoriented_edges`).
    """
    v = np.asarray(vertices)
    f = np.asarray(faces)
    if v.ndim != 2 or v.shape[1] != 3:
        raise MeshError(f"vertices must have shape (n, 3); got {v.shape}")
    if v.shape[0] == 0:
        raise MeshError("empty mesh: no vertices")
    if f.ndim != 2 or f.shape[0] == 0:
        raise MeshError(f"empty mesh: no faces (faces shape {f.shape}); a point cloud (points without faces) is "
                        "pm.PointCloud(vertices), or pm.load_point_cloud(path) for a file")
    if not np.issubdtype(f.dtype, np.integer):
        raise MeshError(f"face indices must be integers; got dtype {f.dtype}")
    if f.shape[1] != 3:
        raise MeshError(f"non-triangular faces: faces have {f.shape[1]} corners; triangulate the mesh first "
                        "(prodmaps.mesh.triangulate_polygons(faces), or pm.load_mesh(path), which triangulates "
                        "polygons unless triangulate=False)")
    if not np.all(np.isfinite(v)):
        bad = np.flatnonzero(~np.all(np.isfinite(v), axis=1))
        raise MeshError(f"non-finite coordinates (NaN or inf) at {bad.size} vertices, first {bad[:5].tolist()}")
    vmax = float(np.max(np.abs(v)))
    if vmax > 1e150:  # squared edge lengths (~4 vmax**2) would overflow float64
        raise MeshError(f"coordinates too large (max |x| = {vmax:.3g}): squared lengths overflow float64; "
                        "rescale the mesh")
    n = v.shape[0]
    if f.min() < 0:
        raise MeshError(f"negative face indices (min {int(f.min())}); indices must be 0-based")
    if f.max() >= n:
        raise MeshError(f"face indices out of range: max index {int(f.max())} but only {n} vertices")
    bad = np.flatnonzero((f[:, 0] == f[:, 1]) | (f[:, 1] == f[:, 2]) | (f[:, 0] == f[:, 2]))
    if bad.size:
        raise MeshError(f"degenerate faces: {bad.size} faces repeat a vertex (first {bad[:5].tolist()}); " + _REPAIR)
    with np.errstate(over="ignore", invalid="ignore"):
        diag2 = float(np.sum((v.max(0) - v.min(0)) ** 2))
        areas = face_areas(v, f)
    if not (np.isfinite(diag2) and np.all(np.isfinite(areas))):  # finite coordinates, see above
        raise MeshError(f"coordinates too large (max |x| = {vmax:.3g}): face areas overflow float64; "
                        "rescale the mesh")
    degen = np.flatnonzero(areas <= area_tol * max(diag2, np.finfo(float).tiny))
    if degen.size:
        raise MeshError(f"degenerate (zero-area) faces: {degen.size} faces, first {degen[:5].tolist()}; " + _REPAIR)
    fs = np.sort(f, axis=1)
    _, counts = np.unique(fs, axis=0, return_counts=True)
    if np.any(counts > 1):
        raise MeshError(f"duplicate faces: {int(np.sum(counts - 1))} faces repeat another face's vertices; " + _REPAIR
                        + "; or " + _ROBUST)
    bad = np.setdiff1d(np.arange(n), f)
    if bad.size:
        raise MeshError(f"unreferenced vertices: {bad.size} vertices belong to no face (first {bad[:5].tolist()}); "
                        "use prodmaps.mesh.remove_unreferenced_vertices(vertices, faces), or load the file with "
                        "pm.io.load_mesh_repaired(path)")
    e, c = edges(f)
    if np.any(c > 2):
        raise _non_manifold(e[c > 2])
    ncomp, labels = face_components(n, f)
    if ncomp > 1:
        sizes = sorted(np.bincount(labels).tolist(), reverse=True)[:5]
        n_merge = int(np.sum(coincident_vertices(v, coincident_tol) != np.arange(n)))
        soup = (f"; {n_merge} vertices coincide with another (a triangle soup or cut seams?): "
                "prodmaps.mesh.repair(vertices, faces) merges them first") if n_merge else ""
        raise MeshError(f"several connected components: {ncomp} (sizes {sizes}); use "
                        "prodmaps.mesh.largest_component(vertices, faces), or load the file with "
                        "pm.io.load_mesh_repaired(path)" + soup)
    if warn:
        for message in _suspicious(v, f, coincident_tol):
            warnings.warn(message, MeshWarning, stacklevel=4)


def _non_manifold(bad: np.ndarray) -> MeshError:
    """The error of non-manifold edges ``bad (b, 2)``, naming the way out."""
    return MeshError(f"non-manifold edges: {bad.shape[0]} edges are shared by more than two faces "
                     f"(first {bad[:3].tolist()}); the cotangent Laplacian is undefined there and no repair splits "
                     "them canonically; " + _ROBUST)


def _suspicious(v: np.ndarray, f: np.ndarray, coincident_tol: float) -> list[str]:
    """The :class:`MeshWarning` messages of a valid mesh (module doc): coincident, bowtie, misoriented."""
    out = []
    rep = coincident_vertices(v, coincident_tol, among=boundary_vertices(f))
    n_merge = int(np.sum(rep != np.arange(v.shape[0])))
    if n_merge:
        out.append(f"{n_merge} boundary vertices coincide with another one (within {coincident_tol:g} of the "
                   "bounding-box diagonal): the surface is cut there (a duplicated seam or a triangle soup), so its "
                   "spectrum is that of the cut surface; merge them with prodmaps.mesh.merge_vertices(vertices, "
                   "faces) or prodmaps.mesh.repair(vertices, faces), or load the file with "
                   "pm.io.load_mesh_repaired(path)")
    bow = bowtie_vertices(f, v.shape[0])
    if bow.size:
        out.append(f"{bow.size} bowtie vertices (first {bow[:5].tolist()}): separate fans of faces meet at one vertex "
                   "(non-manifold), so normals are undefined there and functions leak through a single point; split "
                   "them with prodmaps.mesh.split_bowtie_vertices(vertices, faces) or prodmaps.mesh.repair(vertices, "
                   "faces)")
    bad = misoriented_edges(f)
    if bad:
        out.append(f"inconsistently oriented faces: {bad} edges are traversed in the same direction by their two "
                   "faces. The Laplacian and everything spectral are unaffected (they use angles and areas only); "
                   "normals, curvature, SHOT, AWFT and cross fields are not. Orient the faces with "
                   "prodmaps.mesh.orient_faces(vertices, faces) or prodmaps.mesh.repair(vertices, faces)")
    return out


def coincident_vertices(vertices: np.ndarray, tol: float = COINCIDENT_TOL, among=None) -> np.ndarray:
    """For every vertex the smallest index of the vertices that coincide with it, ``(n,)`` int64.

    Two vertices coincide when they are closer than ``tol`` times the bounding-box diagonal (at
    least exactly equal, when the diagonal is 0); coincidence is made transitive (chains of close
    vertices form one group). A vertex that coincides with no other maps to itself. ``among``
    (vertex indices) restricts the search to those vertices (the others map to themselves).

    Examples
    --------
    >>> import numpy as np
    >>> coincident_vertices(np.array([[0.0, 0, 0], [1, 0, 0], [0, 0, 1e-12], [1, 0, 0]]))
    array([0, 1, 0, 1])
    """
    v = np.asarray(vertices, dtype=np.float64)
    n = v.shape[0]
    out = np.arange(n, dtype=np.int64)
    if n == 0:
        return out
    idx = out if among is None else np.unique(np.asarray(among, dtype=np.int64))
    if idx.size < 2:
        return out
    diag = float(np.linalg.norm(v.max(0) - v.min(0)))
    pairs = cKDTree(v[idx]).query_pairs(float(tol) * diag, output_type="ndarray")  # (p, 2) positions in idx
    if pairs.shape[0] == 0:
        return out
    _, labels = graph_components(idx.size, pairs[:, 0], pairs[:, 1])
    first = np.full(labels.max() + 1, n, dtype=np.int64)
    np.minimum.at(first, labels, idx)
    out[idx] = first[labels]
    return out


def boundary_vertices(faces: np.ndarray) -> np.ndarray:
    """The vertices on boundary edges (edges of one face), sorted ``(b,)`` int64: where a surface is cut or open."""
    return np.unique(boundary_edges(np.asarray(faces))).astype(np.int64)


def _distinct(x: np.ndarray) -> np.ndarray:
    """The sorted distinct values of a 1-D integer array (a sort: plain ``np.unique`` is 30x slower here)."""
    s = np.sort(x)
    return s[np.concatenate([[True], s[1:] != s[:-1]])] if s.size else s


def _corner_fans(faces: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """``(vertex (3m,), fan label (3m,))`` of every corner ``3·face + j``.

    Corners of one vertex are in one fan when their faces are joined around it through manifold
    edges (each used by exactly two faces).
    """
    f = np.asarray(faces, dtype=np.int64)
    m = f.shape[0]
    corner_vertex = f.ravel()  # (3m,), corner 3t + j is vertex f[t, j]
    a, b = f.ravel(), f[:, [1, 2, 0]].ravel()  # half-edge 3t + j runs a -> b (corner 3t+j to corner 3t+(j+1)%3)
    ca = np.arange(3 * m)
    cb = 3 * (ca // 3) + (ca % 3 + 1) % 3
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    key = lo * np.int64(n) + hi
    order = np.argsort(key, kind="stable")
    ks = key[order]
    uniq, start, count = np.unique(ks, return_index=True, return_counts=True)
    two = start[count == 2]
    h1, h2 = order[two], order[two + 1]  # the two half-edges of each manifold edge
    # the corner of vertex lo (and of hi) in each of the two faces
    lo1, hi1 = np.where(a[h1] == lo[h1], ca[h1], cb[h1]), np.where(a[h1] == lo[h1], cb[h1], ca[h1])
    lo2, hi2 = np.where(a[h2] == lo[h2], ca[h2], cb[h2]), np.where(a[h2] == lo[h2], cb[h2], ca[h2])
    _, fan = graph_components(3 * m, np.concatenate([lo1, hi1]), np.concatenate([lo2, hi2]))
    return corner_vertex, fan


def bowtie_vertices(faces: np.ndarray, n: int | None = None) -> np.ndarray:
    """Vertices where two or more separate fans of faces meet (bowties), sorted ``(b,)`` int64.

    A fan is a set of faces around the vertex joined through edges shared by exactly two faces;
    a manifold vertex has one fan (a closed disk, or an open one on the boundary).

    Examples
    --------
    >>> import numpy as np
    >>> bowtie_vertices(np.array([[0, 1, 2], [0, 3, 4]]))  # two triangles touching at vertex 0
    array([0])
    """
    f = np.asarray(faces, dtype=np.int64)
    if f.size == 0:
        return np.zeros(0, dtype=np.int64)
    n = int(f.max()) + 1 if n is None else int(n)
    vert, fan = _corner_fans(f, n)
    pairs = _distinct(vert * np.int64(3 * f.shape[0]) + fan)  # distinct (vertex, fan)
    fans_per_vertex = np.bincount(pairs // (3 * f.shape[0]), minlength=n)
    return np.flatnonzero(fans_per_vertex > 1).astype(np.int64)


def misoriented_edges(faces: np.ndarray) -> int:
    """Number of edges that two faces traverse in the same direction (0 for a consistently oriented mesh).

    Examples
    --------
    >>> import numpy as np
    >>> misoriented_edges(np.array([[0, 1, 2], [0, 2, 3]])), misoriented_edges(np.array([[0, 1, 2], [0, 3, 2]]))
    (0, 1)
    """
    f = np.asarray(faces, dtype=np.int64)
    if f.size == 0:
        return 0
    n = np.int64(f.max()) + 1
    key = f.ravel() * n + f[:, [1, 2, 0]].ravel()  # directed half-edges a -> b
    return int(key.size - _distinct(key).size)


def triangulate_polygons(faces) -> tuple[np.ndarray, np.ndarray]:
    """Fan triangulation of polygon faces: ``(triangles (t, 3) int64, source face of each triangle (t,))``.

    ``faces`` is ``(m, c)`` with ``c >= 3``; rows shorter than ``c`` are padded with their last
    index (as :func:`prodmaps.io.read_mesh_arrays` returns them). A polygon ``(v0, v1, …, v_{p-1})``
    becomes ``(v0, v_i, v_{i+1})`` for ``i = 1 … p-2``: ``p - 2`` triangles, so a quad gives two.
    Fans are right for convex polygons (what quad meshes hold); triangles pass unchanged.

    Examples
    --------
    >>> import numpy as np
    >>> tri, src = triangulate_polygons(np.array([[0, 1, 2, 3], [3, 2, 4, 4]]))  # a quad and a padded triangle
    >>> tri.tolist(), src.tolist()
    ([[0, 1, 2], [0, 2, 3], [3, 2, 4]], [0, 0, 1])
    """
    f = np.asarray(faces)
    if f.ndim != 2 or f.shape[1] < 3 or (f.size and not np.issubdtype(f.dtype, np.integer)):
        raise MeshError(f"faces must be an (m, c) integer array with c >= 3 corners; got shape {f.shape}, "
                        f"dtype {f.dtype}")
    f = f.astype(np.int64)
    c = f.shape[1]
    # true corner count: the width minus the trailing repeats of the last index (the padding)
    same = f[:, 1:] == f[:, -1:]  # (m, c - 1), the last column always True
    trailing = np.cumprod(same[:, ::-1], axis=1).sum(axis=1)  # the last index and its repeats at the end
    length = np.maximum(c + 1 - trailing, 3)
    i = np.arange(1, c - 1)  # fan triangles (v0, v_i, v_{i+1})
    keep = i[None, :] <= (length[:, None] - 2)  # (m, c - 2)
    rows, cols = np.nonzero(keep)
    tri = np.stack([f[rows, 0], f[rows, cols + 1], f[rows, cols + 2]], axis=1)
    return tri, rows.astype(np.int64)


def _first(a: np.ndarray):
    """The first element of ``a`` as a Python object (so that its repr is ``'0'``, not ``np.str_('0')``)."""
    x = a.ravel()[0]
    return x.item() if isinstance(x, np.generic) else x


def _numeric_arrays(vertices, faces) -> tuple[np.ndarray, np.ndarray]:
    """``(vertices float64 copy, faces as given)``, or a :class:`MeshError` for text, objects or ragged lists."""
    try:
        f = np.asarray(faces)
    except ValueError:  # numpy >= 1.24: ragged nested lists
        raise MeshError("faces must be an (m, 3) integer array; got rows of different lengths (polygons?): "
                        "triangulate them with prodmaps.mesh.triangulate_polygons(faces)") from None
    if f.size and f.dtype.kind not in "biuf":
        what = "text" if f.dtype.kind in "US" else f"dtype {f.dtype}"
        raise MeshError(f"face indices must be integers; got {what} (e.g. {_first(f)!r}): convert them with "
                        "np.asarray(faces, dtype=np.int64)")
    v = np.asarray(vertices)
    if v.size and v.dtype.kind not in "biuf":
        what = "text" if v.dtype.kind in "US" else f"dtype {v.dtype}"
        raise MeshError(f"vertex coordinates must be numbers; got {what} (e.g. {_first(v)!r}): convert them with "
                        "np.asarray(vertices, dtype=np.float64)")
    return np.array(v, dtype=np.float64, order="C", copy=True), f


@dataclass(frozen=True, eq=False)
class Mesh:
    """A validated triangle mesh.

    Parameters
    ----------
    vertices : (n, 3) array_like of float
        Vertex positions.
    faces : (m, 3) array_like of int
        Vertex indices of each triangle, 0-based, consistently oriented.
    name : str, optional
        A label used in messages and file names.
    validate : bool
        Run :func:`prodmaps.mesh.validate` (default). Only skip it for meshes you built yourself
        and know: the spectral code assumes a manifold, connected mesh without unreferenced or
        degenerate elements.

    Raises
    ------
    MeshError
        When ``validate`` is true and the mesh fails a check (the message names the repair, e.g.
        :func:`prodmaps.io.load_mesh_repaired`).

    Examples
    --------
    >>> import numpy as np
    >>> import prodmaps as pm
    >>> V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float)
    >>> F = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    >>> mesh = pm.Mesh(V, F, name="tetrahedron")
    >>> mesh.n_vertices, mesh.n_faces, mesh.is_closed
    (4, 4, True)
    """

    vertices: np.ndarray
    faces: np.ndarray
    name: str = ""
    validate: bool = field(default=True, repr=False)

    def __post_init__(self):
        # a copy: the arrays are made read-only below, and the caller's own array must stay writeable
        v, f_in = _numeric_arrays(self.vertices, self.faces)
        if (f_in.size and not np.issubdtype(f_in.dtype, np.integer) and np.all(np.isfinite(f_in))
                and np.all(f_in == np.round(f_in))):  # whole numbers stored as floats
            f_in = f_in.astype(np.int64)
        f = np.ascontiguousarray(f_in.astype(np.int64) if np.issubdtype(f_in.dtype, np.integer) else f_in)
        if f.ndim == 1 and f.size == 0:
            f = f.reshape(0, 3)
        if self.validate:
            validate(v, f)
        for name, arr in (("vertices", v), ("faces", f)):
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)

    @property
    def n_vertices(self) -> int:
        """Number of vertices ``n``."""
        return self.vertices.shape[0]

    @property
    def n_faces(self) -> int:
        """Number of faces ``m``."""
        return self.faces.shape[0]

    @property
    def face_areas(self) -> np.ndarray:
        """Area of every triangle, ``(m,)``."""
        return face_areas(self.vertices, self.faces)

    @property
    def area(self) -> float:
        """Total surface area."""
        return float(self.face_areas.sum())

    @property
    def boundary_edges(self) -> np.ndarray:
        """Edges used by one face only, ``(b, 2)`` (empty for a closed mesh)."""
        return boundary_edges(self.faces)

    @property
    def is_closed(self) -> bool:
        """True when the mesh has no boundary edge."""
        return self.boundary_edges.shape[0] == 0

    def vertex_normals(self) -> np.ndarray:
        """Area-weighted unit vertex normals, ``(n, 3)``."""
        return vertex_normals(self.vertices, self.faces)

    def __repr__(self) -> str:
        label = f"{self.name!r}, " if self.name else ""
        return f"Mesh({label}n_vertices={self.n_vertices}, n_faces={self.n_faces})"


# --------------------------------------------------------------------------- repairs
# Each helper returns (vertices, faces, kept_vertex_index) so that per-vertex data and
# ground-truth maps can be carried along: new vertex i is old vertex kept[i].


def remove_unreferenced_vertices(vertices, faces):
    """Drop vertices used by no face. Returns ``(vertices, faces, kept)``, ``kept`` old indices."""
    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces, dtype=np.int64)
    used = np.zeros(v.shape[0], dtype=bool)
    used[f.ravel()] = True
    kept = np.flatnonzero(used)
    new_index = np.full(v.shape[0], -1, dtype=np.int64)
    new_index[kept] = np.arange(kept.size)
    return v[kept], new_index[f], kept


def remove_degenerate_faces(vertices, faces, area_tol: float = 1e-14):
    """Drop faces that repeat a vertex or have (relative) zero area. Vertices are unchanged."""
    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces, dtype=np.int64)
    rep = (f[:, 0] == f[:, 1]) | (f[:, 1] == f[:, 2]) | (f[:, 0] == f[:, 2])
    diag2 = float(np.sum((v.max(0) - v.min(0)) ** 2))
    small = face_areas(v, f) <= area_tol * max(diag2, np.finfo(float).tiny)
    return v, f[~(rep | small)], np.arange(v.shape[0])


def remove_duplicate_faces(vertices, faces):
    """Keep the first of faces that use the same three vertices (in any order)."""
    f = np.asarray(faces, dtype=np.int64)
    _, first = np.unique(np.sort(f, axis=1), axis=0, return_index=True)
    v = np.asarray(vertices, dtype=np.float64)
    return v, f[np.sort(first)], np.arange(v.shape[0])


def largest_component(vertices, faces):
    """Keep the connected component with the largest surface area; drops the other vertices."""
    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces, dtype=np.int64)
    _, labels = face_components(v.shape[0], f)
    face_label = labels[f[:, 0]]
    comp_area = np.bincount(face_label, weights=face_areas(v, f))
    keep = face_label == int(np.argmax(comp_area))
    return remove_unreferenced_vertices(v, f[keep])


def merge_vertices(vertices, faces, tol: float = COINCIDENT_TOL, *, boundary_only: bool = True):
    """Merge coincident vertices on the boundary (closer than ``tol`` times the bounding-box diagonal).

    Each group keeps its vertex of smallest index (its position unchanged) and the faces are
    re-indexed; a duplicated seam or a triangle soup (every face with its own three vertices, as
    STL files hold) becomes the connected surface. Only vertices on boundary edges are merged
    (``boundary_only``, default): that is where a seam or a soup cuts the surface; coincident
    vertices inside a closed surface (two sheets touching at one point, as some remeshers leave:
    each copy has its own fan of faces) are left alone, since merging them would only make a
    bowtie vertex. ``boundary_only=False`` merges every group (:func:`coincident_vertices`). Faces
    that collapse are left for :func:`remove_degenerate_faces`. Returns ``(vertices, faces, kept)``;
    a mesh without such vertices comes back unchanged (``kept`` the identity).

    Examples
    --------
    >>> import numpy as np
    >>> s = ellipsoid(1)
    >>> soup_v = s.vertices[s.faces.ravel()]  # 80 triangles with their own 3 vertices each
    >>> soup_f = np.arange(soup_v.shape[0]).reshape(-1, 3)
    >>> v, f, kept = merge_vertices(soup_v, soup_f)
    >>> soup_v.shape[0], v.shape[0], Mesh(v, f).is_closed
    (240, 42, True)
    """
    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces, dtype=np.int64)
    rep = coincident_vertices(v, tol, among=boundary_vertices(f) if boundary_only else None)
    kept = np.flatnonzero(rep == np.arange(v.shape[0]))
    new_index = np.full(v.shape[0], -1, dtype=np.int64)
    new_index[kept] = np.arange(kept.size)
    return v[kept], new_index[rep][f], kept


def split_bowtie_vertices(vertices, faces):
    """Give every fan of faces at a bowtie vertex its own copy of the vertex (:func:`bowtie_vertices`).

    The first fan (the one of the smallest corner) keeps the vertex; the copies are appended at
    the end, at the same position. Returns ``(vertices, faces, kept)`` with ``kept[i]`` the input
    vertex of output vertex ``i`` (a bowtie vertex appears once per fan). Two surfaces touching at
    a vertex become two components (:func:`largest_component` then keeps one).

    Examples
    --------
    >>> import numpy as np
    >>> V = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [-1, 0, 0], [0, -1, 0]])
    >>> v, f, kept = split_bowtie_vertices(V, np.array([[0, 1, 2], [0, 3, 4]]))
    >>> f.tolist(), kept.tolist()
    ([[0, 1, 2], [5, 3, 4]], [0, 1, 2, 3, 4, 0])
    """
    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces, dtype=np.int64)
    n = v.shape[0]
    if f.size == 0:
        return v, f, np.arange(n)
    vert, fan = _corner_fans(f, n)
    key = vert * np.int64(3 * f.shape[0]) + fan
    pair, first, inv = np.unique(key, return_index=True, return_inverse=True)  # distinct (vertex, fan)
    pv = pair // (3 * f.shape[0])  # (p,) the vertex of each (vertex, fan)
    # the fan of each vertex with the smallest first corner keeps the vertex, the others become copies
    order = np.lexsort((first, pv))
    is_first = np.ones(order.size, dtype=bool)
    is_first[1:] = pv[order][1:] != pv[order][:-1]
    new_id = np.empty(pair.size, dtype=np.int64)
    new_id[order[is_first]] = pv[order[is_first]]
    extra = order[~is_first]
    new_id[extra] = n + np.arange(extra.size)
    kept = np.concatenate([np.arange(n), pv[extra]])
    return v[kept], new_id[inv].reshape(f.shape), kept


def orient_faces(vertices, faces):
    """Orient the faces of every connected component consistently (each edge traversed both ways).

    Face orientations are propagated through edges shared by two faces (breadth-first, with
    pointer jumping: no loop over faces); in each component the orientation of the majority of its
    faces is kept, so a consistently oriented mesh comes back unchanged. A non-orientable surface
    (a Möbius strip) keeps some misoriented edges: count them with :func:`misoriented_edges`.
    Returns ``(vertices, faces, kept)`` (vertices unchanged, ``kept`` the identity).

    Examples
    --------
    >>> import numpy as np
    >>> s = ellipsoid(1)
    >>> F = s.faces.copy()
    >>> F[:5] = F[:5, ::-1]  # five faces flipped
    >>> _, fixed, _ = orient_faces(s.vertices, F)
    >>> misoriented_edges(F) > 0, misoriented_edges(fixed), bool(np.array_equal(fixed, s.faces))
    (True, 0, True)
    """
    v = np.asarray(vertices, dtype=np.float64)
    f = np.array(faces, dtype=np.int64)
    m = f.shape[0]
    if m == 0:
        return v, f, np.arange(v.shape[0])
    n = np.int64(max(int(f.max()) + 1, v.shape[0]))
    a, b = f.ravel(), f[:, [1, 2, 0]].ravel()
    key = np.minimum(a, b) * n + np.maximum(a, b)
    order = np.argsort(key, kind="stable")
    _, start, count = np.unique(key[order], return_index=True, return_counts=True)
    two = start[count == 2]
    h1, h2 = order[two], order[two + 1]
    t1, t2 = h1 // 3, h2 // 3
    flip = (a[h1] == a[h2]).astype(np.int8)  # 1: the two faces traverse the edge the same way
    # a virtual root (node m) joined to the first face of every component; parity 0 on those links
    ncomp, labels = graph_components(m, t1, t2)
    roots = np.full(ncomp, m, dtype=np.int64)
    np.minimum.at(roots, labels, np.arange(m))
    rows = np.concatenate([t1, t2, np.full(ncomp, m), roots])
    cols = np.concatenate([t2, t1, roots, np.full(ncomp, m)])
    par = np.concatenate([flip, flip, np.zeros(2 * ncomp, np.int8)]) + 1  # stored +1 so that 0 is not dropped
    G = sp.csr_matrix((par.astype(np.int64), (rows, cols)), shape=(m + 1, m + 1))
    G.sum_duplicates()
    _, pred = breadth_first_order(G, m, directed=False, return_predecessors=True)
    pred = pred.astype(np.int64)
    pred[m] = m
    anc = pred.copy()
    acc = np.zeros(m + 1, dtype=np.int8)
    faces_idx = np.arange(m)
    acc[faces_idx] = (np.asarray(G[pred[faces_idx], faces_idx]).ravel() - 1) % 2  # parity of the tree edge
    while np.any(anc != m):  # pointer jumping: acc becomes the parity of the path to the root
        acc ^= acc[anc]
        anc = anc[anc]
    flips = acc[:m].astype(bool)
    # keep each component's majority orientation
    n_flip = np.bincount(labels, weights=flips, minlength=ncomp)
    invert = n_flip > 0.5 * np.bincount(labels, minlength=ncomp)
    flips ^= invert[labels]
    f[flips] = f[flips][:, ::-1]
    return v, f, np.arange(v.shape[0])


@dataclass(frozen=True)
class RepairReport:
    """What :func:`repair` changed, in counts, and where every input vertex went.

    Attributes
    ----------
    n_vertices_in, n_faces_in, n_vertices_out, n_faces_out : sizes before and after.
    polygons_triangulated : polygon faces (more than three corners) split into triangles (fans).
    vertices_merged : vertices merged into a coincident one (:func:`merge_vertices`).
    degenerate_faces, duplicate_faces : faces dropped (:func:`remove_degenerate_faces`,
        :func:`remove_duplicate_faces`).
    bowtie_copies : vertex copies added at bowtie vertices (:func:`split_bowtie_vertices`).
    components_dropped, vertices_dropped : smaller components dropped and the vertices that left
        with them or were unreferenced (:func:`largest_component`).
    faces_reoriented : faces flipped by :func:`orient_faces`.
    vertex_map : ``(n_vertices_in,)`` output vertex of every input vertex (merged vertices map to
        their group's vertex; -1 if dropped; a split bowtie vertex maps to its first copy).
    """

    n_vertices_in: int
    n_faces_in: int
    n_vertices_out: int
    n_faces_out: int
    polygons_triangulated: int
    vertices_merged: int
    degenerate_faces: int
    duplicate_faces: int
    bowtie_copies: int
    components_dropped: int
    vertices_dropped: int
    faces_reoriented: int
    vertex_map: np.ndarray = field(repr=False)

    def __str__(self) -> str:
        parts = [f"{self.n_vertices_in} -> {self.n_vertices_out} vertices, {self.n_faces_in} -> {self.n_faces_out} "
                 "faces"]
        for label, count in (("polygons triangulated", self.polygons_triangulated),
                             ("coincident vertices merged", self.vertices_merged),
                             ("degenerate faces dropped", self.degenerate_faces),
                             ("duplicate faces dropped", self.duplicate_faces),
                             ("bowtie vertex copies added", self.bowtie_copies),
                             ("small components dropped", self.components_dropped),
                             ("faces re-oriented", self.faces_reoriented)):
            if count:
                parts.append(f"{count} {label}")
        return "; ".join(parts)


def repair(vertices, faces, *, name: str = "", coincident_tol: float | None = COINCIDENT_TOL,
           return_report: bool = False):
    """Apply the common repairs in a safe order and return a validated mesh.

    Order: triangulate polygons (fans, :func:`triangulate_polygons`); merge coincident boundary
    vertices (within ``coincident_tol`` of the bounding-box diagonal, :func:`merge_vertices`;
    ``None`` skips it), so that a duplicated seam or a triangle soup becomes the surface it
    describes (coincident vertices inside a closed surface are kept apart); drop
    degenerate faces, then duplicate faces; split bowtie vertices; keep the largest component and
    drop unreferenced vertices; orient the faces consistently. Non-manifold edges are *not*
    repaired (no canonical fix): their error names the way out (the robust Laplacian on the
    unvalidated mesh).

    Parameters
    ----------
    vertices : (n, 3) array_like of float
    faces : (m, c) array_like of int, ``c >= 3`` (polygons padded with their last index).
    name : the mesh's label.
    coincident_tol : relative merge tolerance, or ``None`` to merge nothing.
    return_report : also return a :class:`RepairReport` (counts, and every input vertex's fate).

    Returns
    -------
    mesh : Mesh
        Validated.
    kept : (n_out,) int64
        ``kept[i]`` is the input index of output vertex ``i`` (of a merged group, its smallest).
    report : RepairReport
        Only with ``return_report``.

    Raises
    ------
    MeshError
        For what no repair fixes: arrays of the wrong shape or kind, no faces (a point cloud:
        :func:`prodmaps.load_point_cloud`), face indices outside ``[0, n)``, non-manifold edges.

    Examples
    --------
    >>> import numpy as np
    >>> s = ellipsoid(2)
    >>> soup_v = s.vertices[s.faces.ravel()]  # a triangle soup, as an STL file holds it
    >>> soup_f = np.arange(soup_v.shape[0]).reshape(-1, 3)
    >>> mesh, kept, report = repair(soup_v, soup_f, return_report=True)
    >>> mesh.n_vertices, mesh.n_faces, mesh.is_closed, report.vertices_merged
    (162, 320, True, 798)
    """
    v, f = _numeric_arrays(vertices, faces)
    if v.ndim != 2 or v.shape[1] != 3:
        raise MeshError(f"vertices must have shape (n, 3); got {v.shape}")
    if f.ndim != 2 or f.shape[0] == 0:
        raise MeshError(f"no faces (faces shape {f.shape}): nothing to repair; points without faces are a point "
                        "cloud: pm.PointCloud(vertices), or pm.load_point_cloud(path) for a file")
    if not np.issubdtype(f.dtype, np.integer):
        validate(v, f)  # names the dtype
    if f.min() < 0 or f.max() >= v.shape[0] or f.shape[1] < 3:
        validate(v, f)  # the repairs index vertices by the faces: name the bad indices (MeshError) first
    n_in, m_in = v.shape[0], f.shape[0]
    if not np.all(np.isfinite(v)):
        validate(v, f)
    n_poly = 0
    if f.shape[1] > 3:
        f, src = triangulate_polygons(f)
        n_poly = int(np.sum(np.bincount(src, minlength=m_in) > 1))
    vmap = np.arange(n_in)  # input vertex -> current vertex
    n_merged = 0
    if coincident_tol is not None:
        rep = coincident_vertices(v, coincident_tol, among=boundary_vertices(f))
        v, f, kept_m = merge_vertices(v, f, coincident_tol)
        n_merged = n_in - kept_m.size
        new_index = np.full(n_in, -1, dtype=np.int64)
        new_index[kept_m] = np.arange(kept_m.size)
        vmap = new_index[rep]
        kept = kept_m
    else:
        kept = np.arange(n_in)
    m0 = f.shape[0]
    v, f, _ = remove_degenerate_faces(v, f)
    n_degen = m0 - f.shape[0]
    m0 = f.shape[0]
    v, f, _ = remove_duplicate_faces(v, f)
    n_dup = m0 - f.shape[0]
    if f.shape[0] == 0:
        raise MeshError("no faces left after dropping degenerate and duplicate faces: nothing to repair")
    e, c = edges(f)
    if np.any(c > 2):
        raise _non_manifold(e[c > 2])
    n0 = v.shape[0]
    v, f, kept_b = split_bowtie_vertices(v, f)
    n_bow = v.shape[0] - n0
    kept = kept[kept_b]
    ncomp = face_components(v.shape[0], f)[0]
    v, f, kept_c = largest_component(v, f)
    kept = kept[kept_c]
    where = np.full(kept_b.size, -1, dtype=np.int64)  # vertex after the split -> final vertex
    where[kept_c] = np.arange(kept_c.size)
    alive = where >= 0  # vertex before the split -> its lowest surviving copy
    surviving = np.full(n0, np.iinfo(np.int64).max)
    np.minimum.at(surviving, kept_b[alive], where[alive])
    first_copy = np.where(surviving < np.iinfo(np.int64).max, surviving, -1)
    vmap = np.where(vmap >= 0, first_copy[np.maximum(vmap, 0)], -1)
    f0 = f
    v, f, _ = orient_faces(v, f)
    n_flip = int(np.sum(np.any(f != f0, axis=1)))
    mesh = Mesh(v, f, name=name)
    if not return_report:
        return mesh, kept
    report = RepairReport(n_in, m_in, mesh.n_vertices, mesh.n_faces, n_poly, n_merged, n_degen, n_dup, n_bow,
                          ncomp - 1, int(np.sum(vmap < 0)), n_flip, vmap)
    return mesh, kept, report


def subdivide_midpoint(vertices, faces, levels: int = 1):
    """1-to-4 midpoint subdivision, ``levels`` times (the surface is unchanged).

    Returns ``(vertices, faces)``; the first ``n`` vertices are the input vertices, so a
    point map onto the coarse mesh stays valid for them. A closed mesh grows from ``n`` to
    about ``4**levels * n`` vertices.
    """
    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces, dtype=np.int64)
    for _ in range(levels):
        e = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)  # (3m, 2)
        uniq, inv = np.unique(e, axis=0, return_inverse=True)
        mid = v.shape[0] + inv.reshape(3, -1).T  # (m, 3): midpoints of edges 01, 12, 20
        v = np.vstack([v, 0.5 * (v[uniq[:, 0]] + v[uniq[:, 1]])])
        a, b, c = f.T
        ab, bc, ca = mid.T
        f = np.concatenate([np.stack([a, ab, ca], 1), np.stack([ab, b, bc], 1),
                            np.stack([ca, bc, c], 1), np.stack([ab, bc, ca], 1)])
    return v, f


def icosphere(subdivisions: int = 2, radius: float = 1.0, name: str = "icosphere") -> Mesh:
    """A closed genus-0 sphere mesh: the icosahedron, ``subdivisions`` times midpoint-subdivided, on the sphere.

    ``10·4^s + 2`` vertices: 162 for ``s = 2``, 642 for ``s = 3``.

    Handy for tests and examples: the Laplace–Beltrami spectrum is known (``l(l+1)/radius²`` with
    multiplicity ``2l+1``), every vertex is regular but the 12 original ones.
    """
    t = (1 + 5**0.5) / 2
    v = np.array([[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t],
                  [0, -1, -t], [0, 1, -t], [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1]], float)
    f = np.array([[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4],
                  [11, 10, 2], [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8],
                  [3, 8, 9], [4, 9, 5], [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1]])
    v, f = subdivide_midpoint(v, f, levels=int(subdivisions))
    v = radius * v / np.linalg.norm(v, axis=1, keepdims=True)
    return Mesh(v, f, name=name)


def ellipsoid(subdivisions: int = 2, axes=(1.0, 0.6, 0.4), name: str = "ellipsoid") -> Mesh:
    """A closed genus-0 ellipsoid mesh with a **simple** Laplace–Beltrami spectrum.

    The vertices of :func:`icosphere` ``(subdivisions)`` scaled by ``axes = (a, b, c)`` along
    x, y, z (same faces, same vertex order, so they lie exactly on ``x²/a² + y²/b² + z²/c² = 1``).

    Why: the round icosphere has repeated eigenvalues (multiplicities 3, 5, … from its
    icosahedral symmetry), so the eigenvectors LAPACK returns inside such an eigenspace depend
    on the BLAS/CPU kernel. With three distinct axes only the 8 sign flips of the coordinates
    remain as symmetries; that group is abelian (1-dimensional irreducible representations), so
    no multiplicity is forced, and the eigenvectors are unique up to sign (fixed by
    :func:`prodmaps.basis.fix_signs`). Accidental near-ties still depend on the axes: with the
    default axes the first 26 eigenvalues are separated by at least 0.4 % (relative gap) for
    ``subdivisions`` 1 to 3 (42, 162, 642 vertices); check the gaps you rely on for other axes.
    """
    ax = np.asarray(axes, dtype=np.float64)
    if ax.shape != (3,) or not np.all(np.isfinite(ax)) or np.any(ax <= 0):
        raise ValueError(f"axes must be three positive finite lengths (a, b, c); got {axes!r}")
    s = icosphere(subdivisions)
    return Mesh(s.vertices * ax, s.faces, name=name)
