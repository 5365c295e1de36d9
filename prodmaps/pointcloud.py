"""Point clouds: the :class:`PointCloud` container (points, optional normals), no faces.

Conventions
-----------
* ``points``: ``(n, 3)`` float64 positions; ``normals``: ``(n, 3)`` float64 unit vectors or
  ``None``. ``vertices`` is the same array as ``points`` and ``n_vertices`` the same count as
  ``n_points``, so code that needs only positions (plots, landmarks, point maps) takes a mesh or a
  cloud alike.
* Everything that needs only a basis and a mass works on a cloud as on a mesh: build the basis
  with :func:`prodmaps.eigenbasis` (the point-cloud Laplacian of Sharp & Crane 2020, package
  ``robust-laplacian``: a local Delaunay triangulation of every point's neighbours, mollified,
  with its lumped mass), then products, maps, transfers, descriptors, NO17, ZoomOut and point maps
  are unchanged. Functions that need faces raise :class:`prodmaps.NeedsFacesError`; geodesic
  distances have a point-cloud variant (:func:`prodmaps.geodesics.distances`, heat method).
* Validation (at construction): the shape of the arrays, finite values, at least
  ``MIN_POINTS`` points, normals of non-zero length (they are normalised to unit length).
  Coincident points are allowed (the point-cloud Laplacian handles them).

Load one with :func:`prodmaps.load_point_cloud` (PLY, OFF/OBJ without faces, XYZ text, ``.npy``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .errors import MeshError

__all__ = ["PointCloud", "MIN_POINTS"]

MIN_POINTS = 4
"""The fewest points a cloud may have (a tetrahedron's worth: fewer span no surface)."""


@dataclass(frozen=True, eq=False)
class PointCloud:
    """A point cloud: positions ``(n, 3)`` and optional unit normals ``(n, 3)``, no faces.

    Parameters
    ----------
    points : (n, 3) array_like of float
        Positions.
    normals : (n, 3) array_like of float, optional
        Normals; normalised to unit length (none may be zero).
    name : str, optional
        A label used in messages and file names.

    Raises
    ------
    MeshError
        For arrays of the wrong shape, non-finite values, fewer than ``MIN_POINTS`` points, or a
        zero normal.

    Examples
    --------
    >>> import numpy as np
    >>> import prodmaps as pm
    >>> cloud = pm.PointCloud(pm.mesh.ellipsoid(2).vertices, name="ellipsoid points")
    >>> cloud.n_points, cloud.normals is None, cloud.vertices is cloud.points
    (162, True, True)
    >>> b = pm.eigenbasis(cloud, 6)  # the point-cloud Laplacian (robust-laplacian)
    >>> b.vecs.shape, bool(np.allclose(b.vecs.T @ (b.mass[:, None] * b.vecs), np.eye(6)))
    ((162, 6), True)
    """

    points: np.ndarray
    normals: np.ndarray | None = None
    name: str = ""

    def __post_init__(self):
        p = np.asarray(self.points)
        if p.dtype.kind not in "biuf":
            raise MeshError(f"points must be numbers, got dtype {p.dtype} (convert with np.asarray(points, float))")
        p = np.array(p, dtype=np.float64, order="C", copy=True)
        if p.ndim != 2 or p.shape[1] != 3:
            raise MeshError(f"points must have shape (n, 3); got {p.shape}")
        if p.shape[0] < MIN_POINTS:
            raise MeshError(f"a point cloud needs at least {MIN_POINTS} points; got {p.shape[0]}")
        if not np.all(np.isfinite(p)):
            bad = np.flatnonzero(~np.all(np.isfinite(p), axis=1))
            raise MeshError(f"non-finite coordinates (NaN or inf) at {bad.size} points, first {bad[:5].tolist()}")
        nrm = None
        if self.normals is not None:
            q = np.asarray(self.normals)
            if q.dtype.kind not in "biuf" or q.shape != p.shape:
                raise MeshError(f"normals must be numbers of shape {p.shape}; got {q.shape} of dtype {q.dtype}")
            q = q.astype(np.float64)
            length = np.linalg.norm(q, axis=1)
            if not np.all(np.isfinite(length)) or np.any(length == 0):
                bad = np.flatnonzero(~(np.isfinite(length) & (length > 0)))
                raise MeshError(f"{bad.size} normals are zero or not finite (first {bad[:5].tolist()}); "
                                "pass normals=None to load the points alone")
            nrm = np.ascontiguousarray(q / length[:, None])
            nrm.setflags(write=False)
        p.setflags(write=False)
        object.__setattr__(self, "points", p)
        object.__setattr__(self, "normals", nrm)

    @property
    def n_points(self) -> int:
        """Number of points ``n``."""
        return self.points.shape[0]

    @property
    def n_vertices(self) -> int:
        """Number of points ``n`` (the name meshes use, so code takes either)."""
        return self.points.shape[0]

    @property
    def vertices(self) -> np.ndarray:
        """The positions ``(n, 3)``: the same array as :attr:`points` (the name meshes use)."""
        return self.points

    def __repr__(self) -> str:
        label = f"{self.name!r}, " if self.name else ""
        return f"PointCloud({label}n_points={self.n_points}, normals={self.normals is not None})"
