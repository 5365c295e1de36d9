"""Triangle meshes: the :class:`Mesh` container, its validation, and explicit repairs.

Conventions
-----------
* ``vertices``: ``(n, 3)`` float64 positions.
* ``faces``: ``(m, 3)`` int64, 0-based vertex indices, one row per triangle.
* A valid mesh is non-empty, finite, triangular, has no degenerate (zero-area) or
  duplicate faces, no unreferenced vertices, only manifold edges (each edge in at most
  two faces) and exactly one connected component.
* Open boundaries are allowed. The cotangent Laplacian built on such a mesh
  (:func:`prodmaps.laplacian`) uses the **natural (Neumann) boundary condition**:
  boundary edges simply carry one cotangent weight, so the normal derivative of the
  eigenfunctions vanishes on the boundary and the constant function stays in the kernel.

Validation runs when a :class:`Mesh` is built and raises :class:`MeshError` naming the
problem and the repair helper that fixes it. Repairs are never implicit: call
:func:`repair` (or the individual helpers) yourself, so that vertex indices (and with them
ground-truth correspondences) change only when you ask.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

__all__ = ["Mesh", "MeshError", "validate", "face_areas", "face_normals", "face_mean_ratio", "face_radius_ratio",
           "vertex_normals", "check_mesh", "check_vertex_indices", "edges", "boundary_edges", "graph_components",
           "face_components", "mean_edge_length", "largest_component", "remove_unreferenced_vertices",
           "remove_degenerate_faces", "remove_duplicate_faces", "repair", "subdivide_midpoint", "icosphere",
           "ellipsoid"]


class MeshError(ValueError):
    """A mesh that the library cannot work with; the message names the problem and the fix.

    A subclass of ``ValueError``, raised by :class:`prodmaps.Mesh`, :func:`prodmaps.load_mesh`,
    :func:`prodmaps.save_mesh` and :func:`prodmaps.eigenbasis`.

    Examples
    --------
    >>> import numpy as np
    >>> import prodmaps as pm
    >>> V = np.zeros((4, 3))  # four vertices at one point: every face is degenerate
    >>> try:
    ...     pm.Mesh(V, [[0, 1, 2], [0, 2, 3]])
    ... except pm.MeshError as err:
    ...     print(type(err).__name__, isinstance(err, ValueError))
    MeshError True
    """


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


def check_mesh(mesh) -> Mesh:
    """``mesh`` if it is a :class:`Mesh`, else a ``TypeError`` (the one check of a mesh argument).

    The checks of a mesh live here, the lowest module (:mod:`prodmaps.operators` and
    :mod:`prodmaps.curvature` use them); the checks that need a basis are in :mod:`prodmaps.checks`.

    Examples
    --------
    >>> check_mesh(ellipsoid(1)).n_vertices
    42
    >>> check_mesh("bunny.ply")
    Traceback (most recent call last):
    ...
    TypeError: expected a prodmaps.Mesh, got str (use pm.load_mesh)
    """
    if not isinstance(mesh, Mesh):
        raise TypeError(f"expected a prodmaps.Mesh, got {type(mesh).__name__} (use pm.load_mesh)")
    return mesh


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


def validate(vertices: np.ndarray, faces: np.ndarray, area_tol: float = 1e-14) -> None:
    """Raise :class:`MeshError` if ``(vertices, faces)`` is not a valid triangle mesh.

    ``area_tol`` is relative to the squared bounding-box diagonal: a face whose area is below
    ``area_tol * diag**2`` counts as degenerate.
    """
    v = np.asarray(vertices)
    f = np.asarray(faces)
    if v.ndim != 2 or v.shape[1] != 3:
        raise MeshError(f"vertices must have shape (n, 3); got {v.shape}")
    if v.shape[0] == 0:
        raise MeshError("empty mesh: no vertices")
    if f.ndim != 2 or f.shape[0] == 0:
        raise MeshError(f"empty mesh: no faces (faces shape {f.shape})")
    if f.shape[1] != 3:
        raise MeshError(f"non-triangular faces: faces have {f.shape[1]} corners; triangulate the mesh first")
    if not np.issubdtype(f.dtype, np.integer):
        raise MeshError(f"face indices must be integers; got dtype {f.dtype}")
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
        raise MeshError(f"duplicate faces: {int(np.sum(counts - 1))} faces repeat another face's vertices; " + _REPAIR)
    bad = np.setdiff1d(np.arange(n), f)
    if bad.size:
        raise MeshError(f"unreferenced vertices: {bad.size} vertices belong to no face (first {bad[:5].tolist()}); "
                        "use prodmaps.mesh.remove_unreferenced_vertices(vertices, faces), or load the file with "
                        "pm.io.load_mesh_repaired(path)")
    e, c = edges(f)
    if np.any(c > 2):
        bad = e[c > 2]
        raise MeshError(f"non-manifold edges: {bad.shape[0]} edges are shared by more than two faces "
                        f"(first {bad[:3].tolist()}); the Laplacian is undefined there")
    ncomp, labels = face_components(n, f)
    if ncomp > 1:
        sizes = sorted(np.bincount(labels).tolist(), reverse=True)[:5]
        raise MeshError(f"several connected components: {ncomp} (sizes {sizes}); use "
                        "prodmaps.mesh.largest_component(vertices, faces), or load the file with "
                        "pm.io.load_mesh_repaired(path)")


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
        v = np.array(self.vertices, dtype=np.float64, order="C", copy=True)
        f_in = np.asarray(self.faces)
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


def repair(vertices, faces, *, name: str = "") -> tuple[Mesh, np.ndarray]:
    """Apply the common repairs in a safe order and return a validated mesh.

    Order: drop degenerate faces, drop duplicate faces, keep the largest component, drop
    unreferenced vertices. Non-manifold edges are *not* repaired (no canonical fix).

    Returns ``(mesh, kept)`` where ``kept[i]`` is the input index of output vertex ``i``.

    Raises :class:`MeshError` for what no repair fixes: arrays of the wrong shape or kind, face
    indices outside ``[0, n)``, non-manifold edges, non-triangular faces.
    """
    v, f = np.asarray(vertices), np.asarray(faces)
    if (v.ndim == 2 and v.shape[1] == 3 and f.ndim == 2 and f.size and np.issubdtype(f.dtype, np.integer)
            and (f.min() < 0 or f.max() >= v.shape[0])):
        validate(v, f)  # the repairs index vertices by the faces: name the bad indices (MeshError) first
    v, f, _ = remove_degenerate_faces(vertices, faces)
    v, f, _ = remove_duplicate_faces(v, f)
    v, f, kept = largest_component(v, f)
    return Mesh(v, f, name=name), kept


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
