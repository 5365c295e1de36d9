"""Geodesic distances on triangle meshes and point clouds, and the geodesic error of point maps.

Three ways to compute distances from a set of source vertices, all returning an array of
shape ``(n_sources, n_vertices)`` (row ``s`` holds the distance of every vertex to
``sources[s]``, in the mesh's length unit):

* ``method="heat"`` (default): the heat method (Crane, Weischedel & Wardetzky 2013) as
  implemented by ``potpourri3d.MeshHeatMethodDistanceSolver`` (intrinsic-Delaunay
  "robust" Laplacian; the two linear systems are factorised once per mesh and reused for
  every source). Approximate, typically within a few percent of the exact distance; not
  exactly symmetric.
* ``method="graph"``: Dijkstra on the edge graph weighted by Euclidean edge lengths
  (``scipy.sparse.csgraph.dijkstra``). Needs only numpy/scipy. It is an **upper bound** of
  the geodesic distance (a path along edges is a path on the surface); on good meshes it is
  a few percent to ~15 % too long (zig-zag paths across the triangulation).
* ``method="exact"``: the exact polyhedral geodesic (MMP/Surazhsky) via
  ``igl.exact_geodesic`` (libigl's Python bindings). Slow; for checks on few sources.

A :class:`prodmaps.PointCloud` has the heat method only (``potpourri3d.PointCloudHeatSolver``,
the heat method on the point-cloud Laplacian's tufted cover); ``"graph"`` and ``"exact"`` need
edges and raise :class:`prodmaps.NeedsFacesError`. Its area (for :func:`map_error`) is the sum of
its point-cloud Laplacian's lumped mass.

:func:`all_pairs` computes the full ``(n, n)`` matrix with the heat method (symmetrised,
``(D + Dᵀ)/2``) and caches it on disk as float32 ``.npy`` under ``$PRODMAPS_CACHE`` (default
``~/.cache/prodmaps``), keyed by the SHA-256 of the vertex and face bytes.

Error of a point map (Kim et al. 2011 protocol, used by the paper's correspondence plots):
:func:`map_error` takes ``p2p_21`` of shape ``(n2,)`` (for each vertex of shape 2 a vertex of
shape 1: the pull-back direction, as everywhere in the package) and the ground truth
``p2p_21_true`` of the same shape, and returns for each vertex of shape 2 the geodesic
distance **on shape 1** between its mapped image and its true image, divided by
``sqrt(area of shape 1)``. :func:`error_curve` turns those errors into the cumulative
curve (fraction of vertices with error ``<= threshold``).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import scipy.sparse as sp

from .files import atomic_path, sha256_bytes
from .mesh import Mesh, check_mesh, check_vertex_indices, edges, needs_faces
from .operators import laplacian
from .pointcloud import PointCloud

__all__ = ["distances", "DistanceRows", "all_pairs", "map_error", "error_curve", "cache_dir", "mesh_key", "edge_graph",
           "shape_area"]

_METHODS = ("heat", "graph", "exact")


def cache_dir() -> Path:
    """Directory of the on-disk distance cache: ``$PRODMAPS_CACHE`` or ``~/.cache/prodmaps``."""
    env = os.environ.get("PRODMAPS_CACHE")
    return Path(env).expanduser() if env else Path.home() / ".cache" / "prodmaps"


def mesh_key(mesh: Mesh) -> str:
    """SHA-256 (hex) of the mesh's float64 vertex bytes and int64 face bytes (a point cloud: of its points)."""
    if isinstance(mesh, PointCloud):
        return sha256_bytes(b"point cloud|" + np.ascontiguousarray(mesh.points, dtype="<f8").tobytes())
    return sha256_bytes(np.ascontiguousarray(mesh.vertices, dtype="<f8").tobytes()
                        + np.ascontiguousarray(mesh.faces, dtype="<i8").tobytes())


def _check_method(shape, method: str) -> None:
    """``ValueError`` for an unknown method, :class:`prodmaps.NeedsFacesError` for edges on a point cloud."""
    if method not in _METHODS:
        raise ValueError(f"unknown method {method!r}; choose one of {_METHODS}")
    if isinstance(shape, PointCloud) and method != "heat":
        raise needs_faces(f"geodesic distances with method={method!r}", shape,
                          "a point cloud has the heat method, method='heat' (potpourri3d's PointCloudHeatSolver)")
    if not isinstance(shape, PointCloud):
        check_mesh(shape)


def shape_area(shape) -> float:
    """The area of a mesh, or of a point cloud (the sum of its point-cloud Laplacian's lumped mass)."""
    return float(laplacian(shape)[1].sum()) if isinstance(shape, PointCloud) else float(shape.area)


def _check_sources(mesh: Mesh, sources) -> np.ndarray:
    src = np.atleast_1d(np.asarray(sources))
    if src.ndim != 1:
        raise ValueError(f"sources must be a vertex index or a 1-D array of indices; got shape {src.shape}")
    return check_vertex_indices(src, mesh.n_vertices, "source")


def edge_graph(mesh: Mesh) -> sp.csr_matrix:
    """The mesh's edges as a symmetric sparse graph ``(n, n)`` weighted by their lengths."""
    e, _ = edges(check_mesh(mesh, "edge_graph").faces)  # (E, 2)
    w = np.linalg.norm(mesh.vertices[e[:, 0]] - mesh.vertices[e[:, 1]], axis=1)  # (E,)
    n = mesh.n_vertices
    return sp.csr_matrix((np.concatenate([w, w]), (np.concatenate([e[:, 0], e[:, 1]]),
                                                    np.concatenate([e[:, 1], e[:, 0]]))), shape=(n, n))


class _HeatSolver:
    """potpourri3d heat-method solver, factorised once; one solve per source."""

    def __init__(self, mesh: Mesh, t_coef: float = 1.0):
        try:
            import potpourri3d as pp3d
        except ImportError as exc:  # pragma: no cover - depends on the environment
            raise ImportError(
                "method='heat' needs potpourri3d (pip install potpourri3d); "
                "use method='graph' for a scipy-only upper bound"
            ) from exc
        if isinstance(mesh, PointCloud):
            self.solver = pp3d.PointCloudHeatSolver(np.asarray(mesh.points), t_coef=t_coef)
        else:
            self.solver = pp3d.MeshHeatMethodDistanceSolver(
                np.asarray(mesh.vertices), np.asarray(mesh.faces), t_coef=t_coef, use_robust=True
            )
        self.n = mesh.n_vertices

    def __call__(self, sources: np.ndarray, dtype=np.float64) -> np.ndarray:
        out = np.empty((sources.size, self.n), dtype=dtype)  # (s, n)
        for row, s in enumerate(sources.tolist()):  # one prefactorised solve per source (C++)
            out[row] = self.solver.compute_distance(int(s))
        return out


class DistanceRows:
    """Rows of one mesh's geodesic distance matrix, computed on demand and kept for reuse.

    ``rows(sources)`` returns the ``(s, n)`` float64 array of :func:`distances` (``method``),
    row for row the same numbers (each source is one independent solve), but a source seen
    before is not solved again. Pass one instance to :func:`map_error` for every map evaluated
    on the same shape (e.g. all pairs with the same source shape): the union of their true
    images is solved once. Memory: ``8 n`` bytes per kept row; beyond ``max_bytes`` the kept
    rows are dropped and the cache starts over (results unchanged).
    """

    def __init__(self, mesh: Mesh, method: str = "heat", *, max_bytes: float = 1e9):
        _check_method(mesh, method)
        self.mesh, self.method, self.n = mesh, method, mesh.n_vertices
        self.max_rows = max(1, int(max_bytes // (8 * self.n)))
        self._solver = _HeatSolver(mesh) if method == "heat" else None
        self._slot = np.full(self.n, -1, dtype=np.int64)  # (n,) row of each kept source, -1 if none
        self._data = np.empty((0, self.n))  # (capacity, n); rows [0, _count) are kept
        self._count = 0
        self.n_solved = 0

    def __call__(self, sources) -> np.ndarray:
        """Distance rows ``(s, n)`` of ``sources``, as :func:`distances`, solving only sources not kept."""
        src = _check_sources(self.mesh, sources)
        need = np.unique(src[self._slot[src] < 0])
        if need.size:
            if self._count + need.size > self.max_rows:  # start over
                self._slot[:] = -1
                self._count = 0
                need = np.unique(src)
            new = self._solver(need) if self._solver is not None else distances(self.mesh, need, self.method)
            end = self._count + need.size
            if end > self._data.shape[0]:  # grow geometrically: kept rows are copied O(log) times, not per call
                grown = np.empty((max(end, min(2 * self._data.shape[0], self.max_rows)), self.n))
                grown[: self._count] = self._data[: self._count]
                self._data = grown
            self._data[self._count : end] = new
            self._slot[need] = self._count + np.arange(need.size)
            self._count = end
            self.n_solved += int(need.size)
        return self._data[self._slot[src]]


def _exact(mesh: Mesh, sources: np.ndarray) -> np.ndarray:
    try:
        import igl
    except ImportError as exc:  # pragma: no cover
        raise ImportError("method='exact' needs libigl's Python bindings (pip install libigl)") from exc
    v, f = mesh.vertices, mesh.faces  # contiguous float64 and int64 (Mesh)
    vt = np.arange(mesh.n_vertices, dtype=np.int64)
    empty = np.zeros(0, dtype=np.int64)
    return np.stack([igl.exact_geodesic(v, f, np.array([s], dtype=np.int64), empty, vt, empty)
                     for s in sources.tolist()]) if sources.size else np.zeros((0, mesh.n_vertices))


def distances(mesh: Mesh, sources, method: str = "heat", *, t_coef: float = 1.0) -> np.ndarray:
    """Geodesic distances from each source vertex to every vertex.

    Parameters
    ----------
    mesh : pm.Mesh or pm.PointCloud
    sources : int or (s,) int array of vertex indices (0-based)
    method : "heat" (potpourri3d heat method, default; the only one for a point cloud), "graph"
        (Dijkstra on edges; an upper bound, scipy only) or "exact" (libigl exact polyhedral
        geodesics; slow).
    t_coef : heat-method time step multiplier (``t = t_coef * mean_edge_length**2``).

    Returns
    -------
    (s, n) float64 array; row ``i`` = distances to ``sources[i]``. A scalar ``sources``
    still gives a ``(1, n)`` array.

    Raises
    ------
    NeedsFacesError
        For ``method="graph"`` or ``"exact"`` on a point cloud.

    Examples
    --------
    >>> import numpy as np
    >>> import prodmaps as pm
    >>> sphere = pm.mesh.icosphere(3)
    >>> d_mesh = distances(sphere, 0)[0]
    >>> d_cloud = distances(pm.PointCloud(sphere.vertices), 0)[0]  # the same points, no faces
    >>> round(float(d_mesh.max()), 1), round(float(d_cloud.max()), 1)  # the antipode: π
    (3.1, 3.1)
    """
    _check_method(mesh, method)
    src = _check_sources(mesh, sources)
    if method == "graph":
        from scipy.sparse.csgraph import dijkstra

        return np.atleast_2d(dijkstra(edge_graph(mesh), directed=False, indices=src)).reshape(src.size, -1)
    if method == "exact":
        return _exact(mesh, src)
    return _HeatSolver(mesh, t_coef)(src)


def all_pairs(mesh: Mesh, *, cache: bool = True, method: str = "heat", verbose: bool = False) -> np.ndarray:
    """All-pairs geodesic distance matrix ``(n, n)`` float32, symmetrised ``(D + Dᵀ)/2``.

    Cached on disk (``cache_dir()/geodesics_<method>_<sha256>.npy``, float32) so that
    notebooks do not recompute it; the key is :func:`mesh_key` (vertex and face bytes), so
    any change of the mesh gives a new entry. Pass ``cache=False`` to neither read nor write.
    Memory: ``4 n²`` bytes (100 MB for 5k vertices, 190 MB for FAUST's 6890).
    """
    if method not in ("heat", "graph"):
        raise ValueError("all_pairs supports method='heat' or 'graph' ('exact' is far too slow)")
    _check_method(mesh, method)
    path = cache_dir() / f"geodesics_{method}_{mesh_key(mesh)}.npy"
    if cache and path.is_file():
        d = np.load(path, allow_pickle=False)
        if d.shape == (mesh.n_vertices, mesh.n_vertices):
            return d
    n = mesh.n_vertices
    if method == "graph":
        d = distances(mesh, np.arange(n), method="graph").astype(np.float32)
    else:
        solver = _HeatSolver(mesh)
        d = np.empty((n, n), dtype=np.float32)  # (n, n)
        step = 512
        for start in range(0, n, step):
            d[start:start + step] = solver(np.arange(start, min(n, start + step)), dtype=np.float32)
            if verbose:
                print(f"all_pairs: {min(n, start + step)}/{n} sources", flush=True)
    d += d.T
    d *= 0.5
    np.fill_diagonal(d, 0.0)
    if cache:
        with atomic_path(path) as tmp:
            np.save(tmp, d, allow_pickle=False)
    return d


def map_error(mesh_1: Mesh, p2p_21, p2p_21_true, *, method: str = "heat", dist=None,
              batch: int = 256, rows: DistanceRows | None = None) -> np.ndarray:
    """Geodesic error of a point map, normalised by ``sqrt(area of shape 1)``.

    Parameters
    ----------
    mesh_1 : pm.Mesh or pm.PointCloud, the **target of the point map** (shape 1; ``p2p_21``
        maps vertices of shape 2 to vertices of shape 1). A point cloud takes ``method="heat"``.
    p2p_21 : (n2,) int array of vertex indices of shape 1, or (m, n2) for m maps evaluated
        against the same truth (the distances are then computed once for all of them).
    p2p_21_true : (n2,) int array of vertex indices of shape 1.
    method : distance method used when ``dist`` is not given (see :func:`distances`).
    dist : optional precomputed ``(n1, n1)`` distance matrix of shape 1 (e.g. from
        :func:`all_pairs`; pass it when evaluating many maps onto the same shape); then no
        distance is computed.
    batch : number of sources per solver batch (memory ``batch * n1`` floats).
    rows : optional :class:`DistanceRows` of shape 1 (same ``method``) shared between calls, the
        numbers are the same: sources solved by an earlier call are not solved again.

    Returns
    -------
    (n2,) float64: ``d_1(p2p_21[i], p2p_21_true[i]) / sqrt(area_1)``. Only the distinct true
    images are used as sources, so a sparse evaluation is cheap. Heat-method distances are
    not exactly zero at the source; entries where the map is exactly right are set to 0.

    Accuracy: the heat method smooths at the scale of about one edge, so it underestimates
    distances of a few edges (``docs/benchmarks.md``). Use ``method="exact"`` (slow) or
    ``"graph"`` (upper bound) to bracket small errors when that matters.
    """
    p = np.asarray(p2p_21)
    q = np.asarray(p2p_21_true)
    stacked = p.ndim == 2  # several maps against the same truth: one distance computation
    P = p if stacked else p[None, :]  # (m, n2)
    if q.ndim != 1 or P.shape[1] != q.shape[0] or P.ndim != 2:
        raise ValueError(
            "p2p_21 ((n2,) or (m, n2)) and p2p_21_true ((n2,)) must have the same length n2; "
            f"got {p.shape} and {q.shape}"
        )
    if dist is None:
        _check_method(mesh_1, method)
    P = np.stack([_check_sources(mesh_1, row) for row in P])
    q = _check_sources(mesh_1, q)
    err = np.zeros(P.shape, dtype=np.float64)  # (m, n2)
    if dist is not None:
        if dist.shape != (mesh_1.n_vertices, mesh_1.n_vertices):
            raise ValueError(f"dist must be ({mesh_1.n_vertices}, {mesh_1.n_vertices}); got {dist.shape}")
        err[:] = dist[q[None, :], P]
    else:
        wrong = np.any(P != q[None, :], axis=0)  # (n2,) vertices some map gets wrong
        src, inv = np.unique(q[wrong], return_inverse=True)  # sources = distinct true images
        targets = P[:, wrong]  # (m, w)
        vals = np.empty(targets.shape)
        order = np.argsort(inv, kind="stable")
        bounds = np.searchsorted(inv[order], np.arange(0, src.size + batch, batch))
        if rows is not None and rows.mesh is not mesh_1 and (
                rows.n != mesh_1.n_vertices or mesh_key(rows.mesh) != mesh_key(mesh_1)):
            raise ValueError("rows (DistanceRows) belong to another mesh than mesh_1")
        if rows is not None and rows.method != method:
            raise ValueError(f"rows compute {rows.method!r} distances but method={method!r}")
        solver = rows if rows is not None else (_HeatSolver(mesh_1) if method == "heat" else None)
        for b, start in enumerate(range(0, src.size, batch)):
            chunk = src[start:start + batch]
            d = solver(chunk) if solver is not None else distances(mesh_1, chunk, method=method)  # (b, n1)
            sel = order[bounds[b]:bounds[b + 1]]
            rows = d[inv[sel] - start]  # (|sel|, n1): distances from each needed true image
            vals[:, sel] = rows[np.arange(sel.size)[None, :], targets[:, sel]]
        err[:, wrong] = vals
    err[P == q[None, :]] = 0.0
    err = np.maximum(err, 0.0) / np.sqrt(shape_area(mesh_1))
    return err if stacked else err[0]


def error_curve(errors, thresholds) -> np.ndarray:
    """Cumulative error curve: for each threshold, the fraction of errors ``<= threshold``.

    ``errors`` (any shape, flattened) are e.g. the output of :func:`map_error`;
    ``thresholds`` (t,) gives a ``(t,)`` array of fractions in [0, 1], non-decreasing in the
    threshold.
    """
    e = np.sort(np.asarray(errors, dtype=np.float64).ravel())
    if e.size == 0:
        raise ValueError("errors is empty")
    if np.any(np.isnan(e)):
        raise ValueError("errors contain NaN")
    t = np.asarray(thresholds, dtype=np.float64)
    return np.searchsorted(e, t, side="right") / e.size
