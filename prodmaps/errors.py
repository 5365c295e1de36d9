"""The package's shape errors and warnings, one home for all of them (the lowest module).

* :class:`MeshError` (a ``ValueError``): a shape the library cannot work with; the message names
  the problem and the fix.
* :class:`NeedsFacesError` (a ``MeshError``): a function that needs a triangle mesh (geodesics
  on edges, curvature, SHOT, AWFT, cross fields, quad meshing) was given a point cloud; the
  message names the function and what to do instead.
* :class:`MeshWarning` (a ``UserWarning``): a mesh that loads but is probably not what you meant
  (coincident vertices, bowtie vertices, inconsistent orientation, triangulated polygons); the
  message names the repair. Silence one with ``warnings.filterwarnings("ignore", category=pm.MeshWarning)``.
"""

from __future__ import annotations

__all__ = ["MeshError", "NeedsFacesError", "MeshWarning"]


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


class NeedsFacesError(MeshError):
    """A function that needs faces (a triangle mesh) was given a point cloud.

    A subclass of :class:`MeshError` (so of ``ValueError``). The message names the function and
    the way out: a cloud variant where one exists (heat-method geodesics,
    :func:`prodmaps.geodesics.distances`), else a surface reconstructed from the cloud.

    Examples
    --------
    >>> import numpy as np
    >>> import prodmaps as pm
    >>> cloud = pm.PointCloud(pm.mesh.ellipsoid(1).vertices)
    >>> try:
    ...     pm.curvature.principal_curvatures(cloud)
    ... except pm.NeedsFacesError as err:
    ...     print(str(err)[:68])
    principal_curvatures needs a triangle mesh (faces), got a PointCloud
    """


class MeshWarning(UserWarning):
    """A mesh that loads but is probably not what was meant; the message names the repair.

    Warned by :func:`prodmaps.mesh.validate` (so by :class:`prodmaps.Mesh` and
    :func:`prodmaps.load_mesh`) for coincident boundary vertices (a seam or a triangle soup: the
    surface is cut there), bowtie vertices and inconsistently oriented faces, and by
    :func:`prodmaps.load_mesh` when it triangulates polygons.

    Examples
    --------
    >>> import warnings
    >>> import numpy as np
    >>> import prodmaps as pm
    >>> s = pm.mesh.icosphere(1)
    >>> V = np.vstack([s.vertices, s.vertices[:1]])  # vertex 42 sits on vertex 0
    >>> F = np.where(s.faces == 0, 42, s.faces)  # the faces around vertex 0 use the copy
    >>> F[0] = s.faces[0]  # ... except one: the surface is cut at vertex 0
    >>> with warnings.catch_warnings(record=True) as caught:
    ...     warnings.simplefilter("always")
    ...     _ = pm.Mesh(V, F)
    >>> caught[0].category.__name__, "merge_vertices" in str(caught[0].message)
    ('MeshWarning', True)
    """
