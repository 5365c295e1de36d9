"""Saved maps: functional maps and point maps in checked files, with the sizes of their shapes.

* :func:`save_map` writes a functional map ``C_12`` ``(k2, k1)`` or a point map ``p2p_21``
  ``(n2,)`` (values in ``[0, n1)``) to an ``.npz`` with a metadata record: the kind of map,
  ``k1``, ``k2`` (functional maps), the vertex counts ``n1``, ``n2`` and the names of the two
  shapes when given (a :class:`prodmaps.Basis`, :class:`prodmaps.Mesh`,
  :class:`prodmaps.PointCloud`, or a vertex count), the library version and a SHA-256 checksum
  of the array (:func:`prodmaps.files.write_checked_npz`).
* :func:`load_map` returns the array after checking the file (its kind, its checksum, the
  array against the metadata) and, when given, the shapes or bases it is loaded against (vertex
  counts, columns, index range); :func:`map_info` returns the metadata alone.

Conventions (:mod:`prodmaps.conventions`): ``C_12`` maps coefficients on shape 1 to shape 2;
``p2p_21`` gives for each vertex of shape 2 a vertex of shape 1. In both, "shape 1" and "shape
2" are the ``shape_1`` and ``shape_2`` arguments. Saved bases: :meth:`prodmaps.Basis.save` and
:func:`prodmaps.load_basis`.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .basis import FILE_READERS, Basis
from .files import read_checked_npz, write_checked_npz

__all__ = ["save_map", "load_map", "map_info", "FMAP_FORMAT", "P2P_FORMAT"]

FMAP_FORMAT = "prodmaps.fmap"
P2P_FORMAT = "prodmaps.p2p"


def _describe(shape, which: str) -> dict:
    """``{"n": …, "k": …, "name": …}`` of a Basis, Mesh, PointCloud or vertex count (``{}`` for None)."""
    if shape is None:
        return {}
    if isinstance(shape, Basis):
        return {"n": shape.n, "k": shape.k, "name": shape.name}
    if isinstance(shape, (int, np.integer)) and not isinstance(shape, bool):
        if shape < 1:
            raise ValueError(f"shape_{which}: a vertex count must be positive, got {shape}")
        return {"n": int(shape)}
    n = getattr(shape, "n_vertices", None)
    if not isinstance(n, (int, np.integer)):
        raise TypeError(f"shape_{which} must be a prodmaps.Basis, Mesh, PointCloud or a vertex count; got "
                        f"{type(shape).__name__}")
    return {"n": int(n), "name": getattr(shape, "name", "")}


def _as_map(m) -> tuple[str, np.ndarray]:
    """``("fmap" | "p2p", array)``: a 2-D float array is a functional map, a 1-D integer array a point map."""
    a = np.asarray(m)
    if a.ndim == 2 and a.dtype.kind in "f" and a.size:
        if not np.all(np.isfinite(a)):
            raise ValueError("the functional map contains non-finite values")
        return FMAP_FORMAT, a.astype(np.float64, copy=False)
    if a.ndim == 1 and a.dtype.kind in "iu" and a.size:
        if a.min() < 0:
            raise ValueError(f"a point map holds vertex indices >= 0; got {int(a.min())}")
        return P2P_FORMAT, a.astype(np.int64, copy=False)
    raise ValueError(f"expected a functional map C_12 (a 2-D float array (k2, k1)) or a point map p2p_21 (a 1-D "
                     f"integer array (n2,)); got shape {a.shape}, dtype {a.dtype}")


def save_map(path, map_, shape_1=None, shape_2=None) -> Path:
    """Save a functional map ``C_12`` or a point map ``p2p_21`` with the sizes of its two shapes.

    Parameters
    ----------
    path : str or pathlib.Path
        The file (an ``.npz``; written atomically, exactly that name).
    map_ : ndarray
        ``C_12`` ``(k2, k1)`` float (coefficients on shape 1 to shape 2), or ``p2p_21`` ``(n2,)``
        integer (for each vertex of shape 2 a vertex of shape 1).
    shape_1, shape_2 : Basis, Mesh, PointCloud or int, optional
        Shape 1 and shape 2 (or their bases, or vertex counts): their vertex counts and names
        (and a basis' column count) are recorded and checked against the map. A point map needs
        ``shape_1`` (its values are vertices of shape 1).

    Returns
    -------
    pathlib.Path
        The path written.

    Raises
    ------
    ValueError
        For an array that is neither kind of map, a map that contradicts the shapes (a ``C_12``
        with more columns than ``basis_1`` or rows than ``basis_2``; a ``p2p_21`` whose length is
        not ``n2`` or whose values reach ``n1``), or a point map without ``shape_1``.
    TypeError
        For shapes of another type.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> import numpy as np
    >>> import prodmaps as pm
    >>> mesh = pm.mesh.ellipsoid(2)
    >>> b1, b2 = pm.eigenbasis(mesh, 8), pm.eigenbasis(mesh, 10)
    >>> C_12 = pm.fmap_from_p2p(np.arange(mesh.n_vertices), b1, b2)  # (10, 8)
    >>> path = pm.save_map(pathlib.Path(tempfile.mkdtemp()) / "C_12.npz", C_12, b1, b2)
    >>> bool(np.array_equal(pm.load_map(path, b1, b2), C_12)), pm.storage.map_info(path)["k"]
    (True, [8, 10])
    """
    fmt, a = _as_map(map_)
    s1, s2 = _describe(shape_1, "1"), _describe(shape_2, "2")
    if fmt == P2P_FORMAT and "n" not in s1:
        raise ValueError("a point map p2p_21 needs shape_1 (a mesh, cloud, basis or vertex count): its values are "
                         "vertices of shape 1")
    meta = {"n": [s1.get("n"), s2.get("n")], "names": [s1.get("name", ""), s2.get("name", "")]}
    if fmt == FMAP_FORMAT:
        meta["k"] = [int(a.shape[1]), int(a.shape[0])]
    _check(a, fmt, meta, s1, s2, f"{path}: the map")
    return write_checked_npz(path, fmt, {"map": a}, meta)


def _check(a: np.ndarray, fmt: str, meta: dict, s1: dict, s2: dict, what: str) -> None:
    """Raise ``ValueError`` if the map ``a`` contradicts the shapes described by ``s1``, ``s2``."""
    n1, n2 = meta["n"]
    for which, s, n in (("1", s1, n1), ("2", s2, n2)):
        if "n" in s and n is not None and s["n"] != n:
            raise ValueError(f"{what} belongs to a shape {which} of {n} vertices, not {s['n']}"
                             + (f" ({s['name']!r})" if s.get("name") else ""))
    if fmt == FMAP_FORMAT:
        k1, k2 = a.shape[1], a.shape[0]
        for which, s, k in (("1", s1, k1), ("2", s2, k2)):
            if "k" in s and s["k"] < k:
                raise ValueError(f"{what} C_12 {a.shape} (k2, k1) needs at least {k} columns in basis_{which}, which "
                                 f"has {s['k']}")
    else:
        n1 = s1.get("n", n1)
        n2 = s2.get("n", n2)
        if n2 is not None and a.shape[0] != n2:
            raise ValueError(f"{what} p2p_21 has {a.shape[0]} entries but shape 2 has {n2} vertices (a map of the "
                             "other direction, p2p_12?)")
        if n1 is not None and int(a.max()) >= n1:
            raise ValueError(f"{what} p2p_21 points to vertex {int(a.max())} but shape 1 has {n1} vertices")


def load_map(path, shape_1=None, shape_2=None) -> np.ndarray:
    """The map saved by :func:`save_map` at ``path``, checked: ``C_12`` ``(k2, k1)`` or ``p2p_21`` ``(n2,)``.

    Parameters
    ----------
    path : str or pathlib.Path
        The ``.npz`` file.
    shape_1, shape_2 : Basis, Mesh, PointCloud or int, optional
        The shapes (or bases, or vertex counts) the map is loaded against: their vertex counts
        must be the recorded ones, bases must have at least ``C``'s columns, a point map's values
        must be vertices of shape 1.

    Returns
    -------
    ndarray
        ``C_12`` float64 or ``p2p_21`` int64, bit for bit as saved.

    Raises
    ------
    FileNotFoundError
        For a missing file.
    ValueError
        Naming the path: not a prodmaps archive, a saved basis instead of a map (naming
        :func:`prodmaps.load_basis`), a checksum that does not match (a changed or damaged file),
        an array that contradicts the metadata, or shapes of other sizes than the map's.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> import numpy as np
    >>> import prodmaps as pm
    >>> mesh = pm.mesh.ellipsoid(1)
    >>> path = pm.save_map(pathlib.Path(tempfile.mkdtemp()) / "p2p_21.npz", np.arange(42)[::-1], mesh, mesh)
    >>> pm.load_map(path, mesh, mesh)[:3]
    array([41, 40, 39])
    >>> try:
    ...     pm.load_map(path, pm.mesh.ellipsoid(2), mesh)
    ... except ValueError as err:
    ...     print(str(err).split(": ", 1)[1])
    the map belongs to a shape 1 of 42 vertices, not 162 ('ellipsoid')
    """
    fmt, arrays, meta = _read(path)
    a = arrays["map"]
    _check(a, fmt, meta, _describe(shape_1, "1"), _describe(shape_2, "2"), f"{path}: the map")
    return a


def _read(path) -> tuple[str, dict, dict]:
    """``(format, arrays, metadata)`` of a saved map, the array checked against the metadata."""
    path = Path(path)
    try:
        arrays, meta = read_checked_npz(path, FMAP_FORMAT, FILE_READERS)
        fmt = FMAP_FORMAT
    except ValueError as exc:
        if f"a {P2P_FORMAT} file" not in str(exc):
            raise
        arrays, meta = read_checked_npz(path, P2P_FORMAT, FILE_READERS)
        fmt = P2P_FORMAT
    a = arrays.get("map")
    try:
        n1, n2 = meta["n"]
        k = meta.get("k")
    except (KeyError, TypeError, ValueError):
        raise ValueError(f"{path}: a damaged map file (malformed metadata)") from None
    if a is None:
        raise ValueError(f"{path}: a damaged map file (no 'map' array)")
    if fmt == FMAP_FORMAT and (a.ndim != 2 or k is None or list(a.shape) != [k[1], k[0]]):
        raise ValueError(f"{path}: the array {a.shape} contradicts the metadata (k1, k2) = {k}")
    if fmt == P2P_FORMAT and (a.ndim != 1 or a.dtype.kind not in "iu" or (n2 is not None and a.shape[0] != n2)
                              or (n1 is not None and a.size and (a.min() < 0 or a.max() >= n1))):
        raise ValueError(f"{path}: the point map (shape {a.shape}, values in [{a.min()}, {a.max()}]) contradicts the "
                         f"metadata (n1, n2) = ({n1}, {n2})")
    return fmt, arrays, meta


def map_info(path) -> dict:
    """The metadata of a saved map: ``format``, ``n`` ``[n1, n2]``, ``k`` ``[k1, k2]`` (functional maps), ``names``.

    Also ``prodmaps_version``, ``archive_version`` and ``checksum``; the file is checked as by
    :func:`load_map`.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> import numpy as np
    >>> import prodmaps as pm
    >>> path = pm.save_map(pathlib.Path(tempfile.mkdtemp()) / "p.npz", np.zeros(5, dtype=int), 3)
    >>> info = pm.storage.map_info(path)
    >>> info["format"], info["n"]
    ('prodmaps.p2p', [3, None])
    """
    return _read(path)[2]
