"""Reading and writing triangle meshes (PLY, OFF, OBJ) and point clouds (also XYZ text, ``.npy``).

* PLY: the header is parsed here (strictly). Binary triangle meshes of fixed-size records are
  read as numpy structured views of the file; ASCII triangle meshes with
  `trimesh <https://github.com/mikedh/trimesh>`_ (MIT, pinned in pyproject.toml, imported on the
  first such read) through :func:`trimesh.exchange.ply.load_ply` with ``fix_texture=False``
  (vertices stay in file order), trusted only once every face list is known to hold 3 indices (it
  silently triangulates polygons); everything else goes to the small numpy/struct reader here,
  which keeps polygons as written and names what is wrong with a broken file. Every format
  (ASCII, binary little/big-endian), every property type name (``uchar``/``uint8``, ``int``/
  ``int32``, ...), any extra vertex or face property (normals, colours, texture coordinates,
  quality, flags, before or after the index list), face lists named ``vertex_indices`` or
  ``vertex_index``, extra elements (edges, materials) and CRLF headers are read.
* OFF and OBJ are plain line-based text formats, read here (mesh libraries' OBJ readers
  split or merge vertices because of texture coordinates and normals, and some triangulate
  polygons; see tests/data/variants/README.md). OFF: ``OFF`` with any of the ``ST``/``C``/
  ``N`` prefixes (``COFF``, ``NOFF``, ``CNOFF``, MeshLab's ``NCSTOFF``), comments, counts on
  the header line. OBJ: ``f v``, ``f v/vt``, ``f v//vn``, ``f v/vt/vn``, negative (relative)
  indices, and ``o``/``g``/``s``/``usemtl``/``mtllib``/``vn``/``vt`` lines are ignored.
  Any line ending (LF, CRLF) is accepted.

Vertices are returned in file order, exactly (ground-truth correspondences index them), and
faces as written by :func:`read_mesh_arrays` (polygons padded); :func:`load_mesh` triangulates
polygons (fans, with a :class:`prodmaps.MeshWarning` saying how many) unless ``triangulate=False``.
:func:`load_point_cloud` reads positions and, when the file has them, normals (PLY ``nx ny nz``,
``NOFF``, OBJ ``vn`` lines, a text or ``.npy`` table of 6 columns); a file without faces given to
:func:`load_mesh` raises an error that names :func:`load_point_cloud`.

Readers are strict: a missing, unreadable, truncated or malformed file raises
:class:`MeshError` whose message starts with the file path and names the problem; the result
is validated by :class:`Mesh` (pass ``validate=False`` to get the raw arrays, e.g. to repair
them with :func:`prodmaps.mesh.repair`).
"""

from __future__ import annotations

import io
import itertools
import os
import re
import struct
import warnings
from pathlib import Path
from typing import NamedTuple

import numpy as np

from .errors import MeshError, MeshWarning
from .mesh import COINCIDENT_TOL, Mesh, repair, triangulate_polygons
from .pointcloud import PointCloud

__all__ = ["load_mesh", "read_mesh_arrays", "save_mesh", "load_mesh_repaired", "file_to_mesh_index",
           "load_point_cloud", "read_point_arrays", "POINT_CLOUD_SUFFIXES"]

POINT_CLOUD_SUFFIXES = (".ply", ".off", ".obj", ".xyz", ".txt", ".pts", ".npy")
"""The files :func:`load_point_cloud` reads (``.xyz``, ``.txt``, ``.pts``: one point per line)."""


def load_mesh(path, *, validate: bool = True, name: str | None = None, triangulate: bool = True) -> Mesh:
    """Load a triangle mesh from ``.ply``, ``.off`` or ``.obj`` (positions and faces only).

    Parameters
    ----------
    path : str or pathlib.Path
        The mesh file; the format is chosen by its suffix.
    validate : bool
        Validate the mesh (see :func:`prodmaps.mesh.validate`); default true. Validation also
        warns (:class:`prodmaps.MeshWarning`, the message starting with the path) about coincident
        vertices, bowtie vertices and inconsistent orientation, naming the repair.
    name : str, optional
        The mesh's label (default: the file's stem).
    triangulate : bool
        Split polygon faces (quads and larger) into triangles (fans,
        :func:`prodmaps.mesh.triangulate_polygons`), with a :class:`prodmaps.MeshWarning` saying
        how many (default); ``False`` refuses them (``MeshError`` "non-triangular faces").

    Returns
    -------
    Mesh
        ``vertices`` ``(n, 3)`` float64, ``faces`` ``(m, 3)`` int.

    Raises
    ------
    MeshError
        If the file is missing, unreadable, truncated, not a text OBJ, holds no faces (a point
        cloud: the message names :func:`prodmaps.load_point_cloud`), or if the mesh fails
        validation (the message names the fix, e.g. :func:`prodmaps.io.load_mesh_repaired`).

    Examples
    --------
    >>> import tempfile, pathlib
    >>> import prodmaps as pm
    >>> from prodmaps.mesh import ellipsoid
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "ellipsoid.ply"
    >>> _ = pm.save_mesh(path, ellipsoid(2))
    >>> mesh = pm.load_mesh(path)
    >>> mesh.vertices.shape, mesh.faces.shape, mesh.name
    ((162, 3), (320, 3), 'ellipsoid')
    """
    v, f = read_mesh_arrays(path)
    _refuse_points(path, v, f)
    if triangulate and f.ndim == 2 and f.shape[1] > 3:
        tri, src = triangulate_polygons(f)
        per_face = np.bincount(src, minlength=f.shape[0])  # triangles of each face (1 for a triangle)
        poly = per_face > 1
        warnings.warn(f"{path}: {int(poly.sum())} polygon faces (quads or larger) triangulated into "
                      f"{int(per_face[poly].sum())} triangles (fans), {tri.shape[0]} triangles in all; pass "
                      "triangulate=False to refuse polygons", MeshWarning, stacklevel=2)
        f = tri
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", MeshWarning)
            mesh = Mesh(v, f, name=Path(path).stem if name is None else name, validate=validate)
    except MeshError as exc:
        raise MeshError(f"{path}: {exc}") from None
    for w in caught:  # the validation's warnings, with the file named
        if issubclass(w.category, MeshWarning):
            warnings.warn(f"{path}: {w.message}", MeshWarning, stacklevel=2)
        else:
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    return mesh


def _refuse_points(path, v, f) -> None:
    """A ``MeshError`` naming :func:`load_point_cloud` for a file without faces."""
    if len(v) and (f.ndim != 2 or f.shape[0] == 0):
        raise MeshError(f"{path}: no faces: the file holds {len(v)} points without faces, a point cloud; load it "
                        "with pm.load_point_cloud(path) (its basis: pm.eigenbasis(cloud, k))")


def load_mesh_repaired(path, *, name: str | None = None, verbose: bool = True,
                       coincident_tol: float | None = COINCIDENT_TOL, return_report: bool = False):
    """Load a mesh, applying the standard repairs if validation fails or warns: ``(mesh, kept)``.

    ``kept[i]`` is the vertex of the *file* that mesh vertex ``i`` came from (the identity when
    nothing was repaired), so landmark indices and ground-truth files written for the file can be
    translated with :func:`file_to_mesh_index`. The repairs (:func:`prodmaps.mesh.repair`)
    triangulate polygons, merge coincident vertices (within ``coincident_tol`` of the bounding-box
    diagonal; a duplicated seam or a triangle soup becomes the closed surface), drop degenerate and
    duplicate faces, split bowtie vertices, drop small floating components and unreferenced
    vertices, and orient the faces consistently; they run when validation fails or warns
    (:class:`prodmaps.MeshWarning`). A problem they cannot fix (non-manifold edges) raises
    ``MeshError`` "cannot be repaired automatically: ..." naming the way out (the robust Laplacian
    on the unrepaired mesh); a file without faces raises ``MeshError`` naming
    :func:`prodmaps.load_point_cloud`. With ``verbose`` the problem found and what changed (the
    :class:`prodmaps.mesh.RepairReport`) are printed; ``return_report`` also returns the report
    (``None`` when nothing was repaired), whose ``vertex_map`` gives every file vertex's mesh vertex
    (merged vertices included).
    """
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", MeshWarning)
            mesh = load_mesh(path, name=name, triangulate=False)
        found = [str(w.message) for w in caught if issubclass(w.category, MeshWarning)]
        if not found:
            ident = np.arange(mesh.n_vertices)
            return (mesh, ident, None) if return_report else (mesh, ident)
        problem = found[0]
    except MeshError as exc:
        problem = str(exc)
    if verbose:
        print(f"needs cleaning -> {problem}")
    v, f = read_mesh_arrays(path)  # raw arrays; raises MeshError if the file is unreadable
    _refuse_points(path, v, f)
    try:
        mesh, kept, report = repair(v, f, name=Path(path).stem if name is None else name,
                                    coincident_tol=coincident_tol, return_report=True)
    except MeshError as exc:
        raise MeshError(f"{path}: cannot be repaired automatically: {exc}") from None
    if verbose:
        print(f"repaired: {report}")
    return (mesh, kept, report) if return_report else (mesh, kept)


def file_to_mesh_index(kept: np.ndarray, n_file: int) -> np.ndarray:
    """Inverse of ``kept`` (:func:`load_mesh_repaired`): for each file vertex its mesh vertex, -1 if dropped."""
    inv = np.full(int(n_file), -1, dtype=np.int64)
    inv[np.asarray(kept)] = np.arange(len(kept))
    return inv


def load_point_cloud(path, *, name: str | None = None, normals: bool = True) -> PointCloud:
    """Load a point cloud: positions and, when the file has them, normals.

    Formats (by suffix): ``.ply`` (the vertex element's ``x y z`` and ``nx ny nz``; ASCII or
    binary; faces, if any, ignored), ``.off`` (``NOFF`` carries normals; in ``NCOFF`` and the other
    variants writers disagree on the order of normals and colours, so they are not read), ``.obj``
    (``v`` lines; ``vn`` lines as normals when there is one per ``v``), ``.xyz`` / ``.txt`` /
    ``.pts`` (one point per line, ``x y z`` or ``x y z nx ny nz``, whitespace or commas, ``#``
    comments) and ``.npy`` (an ``(n, 3)`` or ``(n, 6)`` array). A mesh file gives the cloud of its
    vertices, in file order.

    Parameters
    ----------
    path : str or pathlib.Path
        The file.
    name : str, optional
        The cloud's label (default: the file's stem).
    normals : bool
        Read the normals when the file has them (default); ``False`` drops them.

    Returns
    -------
    PointCloud
        ``points`` ``(n, 3)`` float64 in file order, ``normals`` ``(n, 3)`` unit or ``None``.

    Raises
    ------
    MeshError
        Naming the path: a missing, unreadable or malformed file, an unsupported suffix, a table
        that is neither 3 nor 6 columns wide, or points the cloud refuses (:class:`prodmaps.PointCloud`).

    Examples
    --------
    >>> import tempfile, pathlib
    >>> import numpy as np
    >>> import prodmaps as pm
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "cloud.xyz"
    >>> P = pm.mesh.ellipsoid(2).vertices
    >>> np.savetxt(path, np.hstack([P, P / np.linalg.norm(P, axis=1, keepdims=True)]))
    >>> cloud = pm.load_point_cloud(path)
    >>> cloud.n_points, cloud.normals.shape, cloud.name, bool(np.allclose(cloud.points, P))
    (162, (162, 3), 'cloud', True)
    """
    points, nrm = read_point_arrays(path)
    try:
        return PointCloud(points, nrm if normals else None, name=Path(path).stem if name is None else name)
    except MeshError as exc:
        raise MeshError(f"{path}: {exc}") from None


def read_point_arrays(path) -> tuple[np.ndarray, np.ndarray | None]:
    """Return raw ``(points (n, 3) float64, normals (n, 3) float64 or None)`` of a point-cloud file, unchecked.

    See :func:`load_point_cloud` for the formats.
    """
    path = Path(path)
    if not path.is_file():
        raise MeshError(f"{path}: no such file")
    ext = path.suffix.lower()
    if ext not in POINT_CLOUD_SUFFIXES:
        raise MeshError(f"{path}: unsupported point-cloud format {ext!r}; use {', '.join(POINT_CLOUD_SUFFIXES)}")
    try:
        if ext == ".npy":
            table = np.load(path, allow_pickle=False)
            return _point_table(table)
        if ext in (".xyz", ".txt", ".pts"):
            text = path.read_text(encoding="utf-8-sig", errors="replace").replace(",", " ")
            table = np.loadtxt(io.StringIO(text), dtype=np.float64, comments="#", ndmin=2)
            return _point_table(table)
        readers = {".ply": _read_ply_points, ".off": _read_off_points, ".obj": _read_obj_points}
        with open(path, "rb") as fh:
            return readers[ext](fh)
    except MeshError as exc:
        raise MeshError(f"{path}: {exc}") from None
    except OSError as exc:
        raise MeshError(f"{path}: unreadable ({exc})") from None
    except (ValueError, IndexError, KeyError, UnicodeDecodeError, OverflowError) as exc:
        raise MeshError(f"{path}: malformed {ext[1:].upper()} file ({exc})") from None


def _point_table(table: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
    """``(points, normals or None)`` of an ``(n, 3)`` or ``(n, 6)`` table."""
    t = np.asarray(table)
    if t.dtype.kind not in "biuf" or t.ndim != 2 or t.shape[1] not in (3, 6):
        raise MeshError(f"a point table must be (n, 3) (x y z) or (n, 6) (x y z nx ny nz) numbers; got shape "
                        f"{t.shape}, dtype {t.dtype}")
    t = t.astype(np.float64)
    return t[:, :3], (t[:, 3:] if t.shape[1] == 6 else None)


def read_mesh_arrays(path) -> tuple[np.ndarray, np.ndarray]:
    """Return raw ``(vertices (n,3) float64, faces (m,k) int64)`` without validation.

    Faces with fewer or more than three corners are kept, padded with their last index to
    the widest face, so that :func:`prodmaps.mesh.validate` names them.
    """
    path = Path(path)
    if not path.is_file():
        raise MeshError(f"{path}: no such file")
    ext = path.suffix.lower()
    readers = {".ply": _read_ply, ".off": _read_off, ".obj": _read_obj}
    if ext not in readers:
        cloud = (f"; a {ext} file holds points without faces, a point cloud: load it with pm.load_point_cloud(path)"
                 if ext in POINT_CLOUD_SUFFIXES else "")
        raise MeshError(f"{path}: unsupported format {ext!r}; use .ply, .off or .obj" + cloud)
    try:
        with open(path, "rb") as fh:
            return readers[ext](fh)
    except MeshError as exc:
        raise MeshError(f"{path}: {exc}") from None
    except OSError as exc:  # permissions, I/O errors
        raise MeshError(f"{path}: unreadable ({exc})") from None
    except (ValueError, IndexError, KeyError, UnicodeDecodeError, OverflowError) as exc:
        raise MeshError(f"{path}: malformed {ext[1:].upper()} file ({exc})") from None


def _faces_array(rows) -> np.ndarray:
    """``(m, 3)`` int64 for triangles; polygons padded with their last index (kept for validation)."""
    if len(rows) == 0:
        return np.zeros((0, 3), dtype=np.int64)
    if isinstance(rows, np.ndarray) and rows.ndim == 2:  # fixed-length lists, read as one array
        return rows.astype(np.int64)
    lengths = {len(r) for r in rows}
    if lengths == {3}:
        return np.asarray(rows, dtype=np.int64).reshape(-1, 3)
    width = max(lengths)
    return np.array([list(r) + [r[-1]] * (width - len(r)) if len(r) else [-1] * width
                     for r in rows], dtype=np.int64)


# ------------------------------------------------------------------------------ PLY
_FACE_LISTS = ("vertex_indices", "vertex_index")  # names used by MeshLab/Blender/trimesh/scanners
# PLY 1.0 type names and the sized aliases in the wild (the set plyfile and MeshLab accept)
_PLY_TYPES = {"char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "i2", "int16": "i2",
              "ushort": "u2", "uint16": "u2", "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
              "float": "f4", "float32": "f4", "double": "f8", "float64": "f8"}
_PLY_FORMATS = {"ascii": "", "binary_little_endian": "<", "binary_big_endian": ">"}
_NOT_INTEGER = re.compile(rb"[^0-9 \t+-]")


class _PlyProp(NamedTuple):
    name: str
    type: str  # numpy type code without byte order ('u1', 'f4', ...): scalar value or list items
    count: str | None = None  # list properties: type code of the item count


class _PlyElement(NamedTuple):
    name: str
    count: int
    props: tuple


def _ply_header(buf: bytes):
    """Parse the ASCII header: ``(byte order '' (ASCII) / '<' / '>', elements, data offset)``."""
    if not buf.startswith(b"ply"):
        raise MeshError("not a PLY file (missing 'ply' magic)")
    pos, fmt, elements = 0, None, []
    name = count = props = None
    for n_line in itertools.count(1):
        end = buf.find(b"\n", pos)
        if end < 0:
            raise MeshError("truncated file: the PLY header ends early (no 'end_header' line)")
        raw = buf[pos:end].decode("latin-1")  # comments may hold any byte
        pos = end + 1
        tok = raw.split()
        if n_line == 1:
            if raw.strip() != "ply":
                raise MeshError("not a PLY file (missing 'ply' magic)")
            continue
        if not tok or tok[0] in ("comment", "obj_info"):
            continue

        def bad(why):
            return MeshError(f"malformed PLY header (line {n_line} {raw.strip()!r}: {why})")

        key = tok[0]
        if key == "format":
            if fmt is not None or elements or name is not None:
                raise bad("'format' must come once, before the elements")
            if len(tok) != 3 or tok[1] not in _PLY_FORMATS:
                raise bad("expected 'format ascii|binary_little_endian|binary_big_endian 1.0'")
            fmt = _PLY_FORMATS[tok[1]]
        elif key == "element":
            if len(tok) != 3 or not tok[2].isdigit():
                raise bad("expected 'element <name> <count>'")
            if name is not None:
                elements.append(_PlyElement(name, count, tuple(props)))
            name, count, props = tok[1], int(tok[2]), []
        elif key == "property":
            if name is None:
                raise bad("property before any element")
            if len(tok) == 3 and tok[1] in _PLY_TYPES:
                props.append(_PlyProp(tok[2], _PLY_TYPES[tok[1]]))
            elif len(tok) == 5 and tok[1] == "list" and tok[3] in _PLY_TYPES \
                    and _PLY_TYPES.get(tok[2], "f")[0] in "iu":
                props.append(_PlyProp(tok[4], _PLY_TYPES[tok[3]], _PLY_TYPES[tok[2]]))
            else:
                raise bad(f"expected 'property <type> <name>' or 'property list <integer type> "
                          f"<type> <name>' with types {'/'.join(_PLY_TYPES)}")
        elif key == "end_header":
            break
        else:
            raise bad(f"unknown keyword {key!r}")
    if fmt is None:
        raise MeshError("malformed PLY header (no 'format' line)")
    if name is not None:
        elements.append(_PlyElement(name, count, tuple(props)))
    return fmt, elements, pos


def _ply_vertex_element(elements):
    """The vertex element (with scalar x, y, z), or a named error."""
    names = [el.name for el in elements]
    if "vertex" not in names:
        hint = " (triangle strips are not supported)" if "tristrips" in names else ""
        raise MeshError(f"PLY file has no vertex element (elements: {names}){hint}")
    vert = elements[names.index("vertex")]
    scalars = {p.name for p in vert.props if p.count is None}
    missing = [c for c in "xyz" if c not in scalars]
    if missing:
        raise MeshError(f"PLY vertex element has no {'/'.join(missing)} property")
    return vert


def _ply_mesh_elements(elements):
    """The vertex element, the face element (None if absent) and the face's index-list property, or a named error."""
    names = [el.name for el in elements]
    vert = _ply_vertex_element(elements)
    if "face" not in names:
        if "tristrips" in names:
            raise MeshError(f"PLY file has no face element (elements: {names}); triangle strips are not supported")
        return vert, None, None
    face = elements[names.index("face")]
    lists = [p.name for p in face.props if p.count is not None]
    lists = [n for n in lists if n in _FACE_LISTS] or lists  # else: a single list of another name
    if len(lists) != 1:
        raise MeshError("PLY face element has no 'vertex_indices' list property")
    return vert, face, lists[0]


def _ply_vertex_columns(buf, fmt, elements, start, vert, cols) -> np.ndarray:
    """The vertex properties ``cols`` as an ``(n, len(cols))`` float64 array (ASCII rounded to the declared type)."""
    read = _ply_ascii_rows if fmt == "" else _ply_binary_rows
    data = read(buf, start, elements, fmt, wanted={"vertex": tuple(cols)})
    types = {p.name: p.type for p in vert.props}
    if vert.count == 0:
        return np.zeros((0, len(cols)))
    return np.column_stack([np.asarray(data["vertex"][c], dtype=types[c]).astype(np.float64) for c in cols])


def _read_ply(fh):
    buf = fh.read()
    fmt, elements, start = _ply_header(buf)
    vert, face, index = _ply_mesh_elements(elements)
    if face is None:  # points only: load_mesh names load_point_cloud
        return _ply_vertex_columns(buf, fmt, elements, start, vert, "xyz"), np.zeros((0, 3), dtype=np.int64)
    # binary: structured views (every file trimesh could read); ASCII triangles: trimesh
    out = (_ply_binary_triangles if fmt else _ply_trimesh)(buf, fmt, elements, start, vert, face, index)
    if out is None:  # polygons, or a layout neither reads: our reader (names the problem)
        read = _ply_ascii_rows if fmt == "" else _ply_binary_rows
        data = read(buf, start, elements, fmt, wanted={"vertex": ("x", "y", "z"), "face": (index,)})
        types = {p.name: p.type for p in vert.props}  # ASCII: round to the declared type (float)
        vertices = np.column_stack([np.asarray(data["vertex"][c], dtype=types[c]).astype(np.float64)
                                    for c in "xyz"])
        out = vertices, _faces_array(data["face"][index])
    return out


def _read_ply_points(fh):
    """``(points (n, 3), normals (n, 3) or None)`` of a PLY file's vertex element (faces ignored)."""
    buf = fh.read()
    fmt, elements, start = _ply_header(buf)
    vert = _ply_vertex_element(elements)
    scalars = {p.name for p in vert.props if p.count is None}
    cols = ("x", "y", "z") + (("nx", "ny", "nz") if {"nx", "ny", "nz"} <= scalars else ())
    table = _ply_vertex_columns(buf, fmt, elements, start, vert, cols)
    return table[:, :3], (table[:, 3:6] if len(cols) == 6 else None)


def _ply_binary_triangles(buf, fmt, elements, start, vert, face, index):
    """``(vertices, faces)`` of a binary all-triangle PLY of fixed-size records, read as structured views.

    Elements up to the mesh's must be fixed-size records; no per-record work, no trimesh import. None
    otherwise (then the record-by-record reader).
    """
    recs, pos = {}, start
    for el in elements:
        rec = _ply_fixed_records(buf, pos, el, fmt)
        if rec is None:
            return None
        recs[el.name], pos = rec, pos + rec.nbytes
        if vert.name in recs and face.name in recs:
            break
    fidx = recs[face.name][index]  # (F, m) for lists of m indices
    if vert.count == 0 or face.count == 0 or fidx.ndim != 2 or fidx.shape[1] != 3:
        return None
    vertices = np.column_stack([recs[vert.name][c].astype(np.float64) for c in "xyz"])  # (V, 3)
    return vertices, fidx.astype(np.int64)


def _ply_trimesh(buf, fmt, elements, start, vert, face, index):
    """``(vertices, faces)`` of an ASCII PLY read by trimesh, or None if it has polygons or trimesh fails.

    trimesh silently triangulates ASCII polygons, so the list lengths are checked first
    (``_ply_all_triangles``).
    """
    if vert.count == 0 or face.count == 0 or not _ply_all_triangles(buf, elements, start, face, index):
        return None
    from trimesh.exchange.ply import load_ply  # imported here: `import prodmaps` stays light

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # np.fromstring on malformed ASCII; we check below
            kw = load_ply(io.BytesIO(buf), fix_texture=False, skip_materials=True)
        vertices = np.asarray(kw["vertices"], dtype=np.float64)  # file order (no processing)
        faces = np.asarray(kw["faces"], dtype=np.int64)
    except Exception:  # noqa: BLE001 -- any trimesh failure: our reader names the problem
        return None
    if vertices.shape != (vert.count, 3) or faces.shape != (face.count, 3):
        return None
    return vertices, faces


def _ply_all_triangles(buf, elements, start, face, index) -> bool:
    """Whether every face list of an ASCII PLY has 3 indices, read cheaply (one token per face line).

    False also when only a full parse can tell (truncated file, blank lines, lists before the index
    list), and for non-integers in integer face properties (trimesh would truncate '2.5' to 2).
    """
    k = [p.name for p in face.props].index(index)
    if any(p.count is not None for p in face.props[:k]):  # the count follows the scalars before the list
        return False
    skip = sum(el.count for el in elements[:elements.index(face)])
    lines = buf[start:].splitlines()
    if not all(map(bytes.strip, lines[:skip + face.count])):  # a blank line shifts trimesh's rows
        return False
    rows = lines[skip:skip + face.count]
    try:
        if len(rows) != face.count or {r.split(None, k + 1)[k] for r in rows} != {b"3"}:
            return False
    except IndexError:
        return False
    ints = all(np.dtype(t).kind in "iu" for p in face.props for t in (p.type, p.count) if t)
    return not (ints and _NOT_INTEGER.search(b" ".join(rows)))


def _ply_fixed_records(buf, pos, el, fmt):
    """A binary element as a structured view, or None if its lists vary in length.

    Fields ``name``, and ``name.n`` for a list's count, if every list in it is as long as in its first
    record (checked); None for variable-length lists, negative counts, or not enough bytes.
    """
    lengths, off = {}, pos
    for p in el.props:  # the first record's list lengths
        if p.count is not None:
            c = np.dtype(fmt + p.count)
            if el.count == 0:
                lengths[p.name] = 0
                continue
            if off + c.itemsize > len(buf):
                return None
            lengths[p.name] = n = int(np.frombuffer(buf, c, 1, off)[0])
            if n < 0:
                return None
            off += c.itemsize + n * np.dtype(p.type).itemsize
        else:
            off += np.dtype(p.type).itemsize
        if off > len(buf):
            return None
    dt = np.dtype([field for p in el.props for field in ([(p.name, fmt + p.type)] if p.count is None else
                   [(f"{p.name}.n", fmt + p.count), (p.name, fmt + p.type, (lengths[p.name],))])])
    if pos + el.count * dt.itemsize > len(buf):
        return None
    rec = np.frombuffer(buf, dt, el.count, pos)
    if any(np.any(rec[f"{n}.n"] != m) for n, m in lengths.items()):
        return None
    return rec


def _ply_binary_rows(buf, start, elements, fmt, wanted):
    """Read the wanted properties of binary elements (lists of any length); MeshError if cut or a count < 0."""
    codes = {"i1": "b", "u1": "B", "i2": "h", "u2": "H", "i4": "i", "u4": "I", "f4": "f", "f8": "d"}
    out, pos = {}, start
    for el in elements:
        want = wanted.get(el.name, ())
        rec = _ply_fixed_records(buf, pos, el, fmt)
        if rec is not None:  # fixed-size records: one view
            out[el.name] = {n: rec[n] for n in want}
            pos += rec.nbytes
        else:  # record by record
            cols = {n: [] for n in want}
            layout = [(p.name, codes[p.type], np.dtype(p.type).itemsize,
                       p.count and (fmt + codes[p.count]), p.count and np.dtype(p.count).itemsize)
                      for p in el.props]
            for i in range(el.count):
                for name, code, size, count_code, count_size in layout:
                    try:
                        if count_code is None:
                            val = struct.unpack_from(fmt + code, buf, pos)[0]
                            pos += size
                        else:
                            m = struct.unpack_from(count_code, buf, pos)[0]
                            if m < 0:
                                raise MeshError(f"malformed PLY data ({el.name} {i}: negative "
                                                f"list length {m} for {name!r})")
                            pos += count_size
                            val = struct.unpack_from(f"{fmt}{m}{code}", buf, pos)
                            pos += m * size
                    except struct.error:
                        raise MeshError(f"truncated file: the data ends in {el.name} {i} of "
                                        f"{el.count} ({len(buf) - start} bytes after the header)") from None
                    if name in cols:
                        cols[name].append(val)
            out[el.name] = cols
        if wanted.keys() <= out.keys():
            break
    return out


def _ply_ascii_rows(buf, start, elements, fmt, wanted):
    """Read the wanted properties of ASCII elements (one per line); named MeshError for missing or bad values."""
    lines = [ln for ln in buf[start:].decode("latin-1").splitlines() if ln.strip()]
    out, row = {}, 0
    for el in elements:
        want = wanted.get(el.name, ())
        cols = {n: [] for n in want}
        if row + el.count > len(lines):
            raise MeshError(f"truncated file: the {el.name} element has {el.count} lines, "
                            f"found {max(len(lines) - row, 0)}")
        for i in range(el.count):
            ln, tok, t = lines[row], lines[row].split(), 0
            row += 1
            try:
                for p in el.props:
                    conv = float if p.type[0] == "f" else int
                    if p.count is None:
                        val, t = conv(tok[t]), t + 1
                    else:
                        m = int(tok[t])
                        if m < 0:
                            raise ValueError(m)
                        if t + 1 + m > len(tok):
                            raise IndexError(m)
                        val, t = [conv(x) for x in tok[t + 1:t + 1 + m]], t + 1 + m
                    if p.name in cols:
                        cols[p.name].append(val)
            except (IndexError, ValueError) as exc:
                if isinstance(exc, IndexError) and row == len(lines):  # too few values at the end
                    raise MeshError(f"truncated file: the last line {ln.strip()!r} "
                                    f"({el.name} {i}) is incomplete") from None
                raise MeshError(f"malformed PLY data ({el.name} {i}: {ln.strip()!r} does not "
                                f"match the header's properties)") from None
        out[el.name] = cols
        if wanted.keys() <= out.keys():
            break
    return out


# ------------------------------------------------------------------------------ OFF
_OFF_MAGIC = re.compile(r"(?:ST|C|N)*OFF")  # [ST][C][N]OFF in any order (MeshLab: NCSTOFF)


def _read_off(fh):
    vertices, faces, _ = _off_parts(fh)
    return vertices, faces


def _read_off_points(fh):
    vertices, _, normals = _off_parts(fh)
    return vertices, normals


def _off_parts(fh):
    """``(vertices, faces, normals or None)`` of an OFF file; normals from the N prefix (``x y z nx ny nz ...``)."""
    text = fh.read().decode("utf-8-sig", errors="replace")  # names/comments may be latin-1
    lines = [ln for ln in (raw.partition("#")[0].strip() for raw in text.splitlines()) if ln]  # no comments, blanks
    head = lines[0].split() if lines else []
    if not head or not _OFF_MAGIC.fullmatch(head[0]):
        if head and head[0].endswith("OFF"):
            raise MeshError(f"unsupported OFF variant {head[0]!r} (only 3D [ST][C][N]OFF is read)")
        raise MeshError("not an OFF file (missing 'OFF' magic)")
    if len(head) > 1 and head[1].upper() == "BINARY":
        raise MeshError("binary OFF is not supported; convert it to ASCII OFF or PLY")
    counts, start = head[1:], 1
    if not counts:
        if len(lines) < 2:
            raise MeshError("truncated file: no vertex/face counts after the 'OFF' line")
        counts, start = lines[1].split(), 2
    if len(counts) < 2:
        raise MeshError(f"malformed counts line {' '.join(counts)!r}; expected 'n_vertices n_faces n_edges'")
    nv, nf = int(counts[0]), int(counts[1])
    if nv < 0 or nf < 0:
        raise MeshError(f"negative counts ({nv} vertices, {nf} faces)")
    vlines = lines[start:start + nv]
    flines = lines[start + nv:start + nv + nf]
    if len(vlines) < nv or len(flines) < nf:
        raise MeshError(f"truncated file: expected {nv} vertices and {nf} faces, "
                        f"found {len(vlines)} and {len(flines)}")
    vtok = [ln.split()[:3] for ln in vlines]
    short = [i for i, t in enumerate(vtok) if len(t) < 3]
    if short:
        raise MeshError(f"malformed vertex line {vlines[short[0]]!r}: fewer than 3 coordinates")
    vertices = np.array(vtok, dtype=np.float64).reshape(nv, 3)
    normals = None
    if head[0] == "NOFF":  # the normal follows the position (with colours, writers disagree on the order: skipped)
        ntok = [ln.split()[3:6] for ln in vlines]
        if any(len(t) < 3 for t in ntok):
            raise MeshError(f"{head[0]} file with vertex lines of fewer than 6 numbers (x y z nx ny nz)")
        normals = np.array(ntok, dtype=np.float64).reshape(nv, 3)
    rows = []
    for ln in flines:
        tok = ln.split()
        k = int(tok[0])
        if k < 0 or len(tok) < k + 1:
            raise MeshError(f"malformed face line {ln!r}")
        rows.append([int(t) for t in tok[1:k + 1]])  # colours may follow the indices
    return vertices, _faces_array(rows), normals


# ------------------------------------------------------------------------------ OBJ
def _read_obj(fh):
    vertices, faces, _ = _obj_parts(fh)
    return vertices, faces


def _read_obj_points(fh):
    vertices, _, normals = _obj_parts(fh)
    return vertices, normals


def _obj_parts(fh):
    """``(vertices, faces, normals or None)`` of an OBJ file: normals when there are as many ``vn`` as ``v`` lines."""
    raw = fh.read()
    head = raw[:4096]
    if b"\x00" in head or (head and sum(c < 9 or 13 < c < 32 for c in head) > 0.05 * len(head)):
        raise MeshError("not a text OBJ file: its first bytes are binary (a different format, or a damaged file)")
    text = raw.decode("utf-8-sig", errors="replace")
    verts, rows, vn, pending = [], [], [], ""
    for ln in text.splitlines():
        if ln.endswith("\\"):  # line continuation
            pending += ln[:-1] + " "
            continue
        if pending:
            ln, pending = pending + ln, ""
        tok = ln.split()
        if not tok:
            continue
        key = tok[0]
        if key == "v":
            if len(tok) < 4:
                raise MeshError(f"malformed vertex line {ln.strip()!r}: fewer than 3 coordinates")
            verts.append(tok[1:4])  # a 4th (w) or colour values (r g b) may follow
        elif key == "f":
            n = len(verts)
            face = []
            for t in tok[1:]:
                if t.startswith("#"):
                    break
                i = int(t.split("/", 1)[0])
                if i == 0:
                    raise MeshError(f"malformed face line {ln.strip()!r}: OBJ indices start at 1")
                face.append(i - 1 if i > 0 else n + i)  # negative: relative to the latest vertex
            rows.append(face)
        elif key == "vn" and len(tok) >= 4:
            vn.append(tok[1:4])
        # vt, vp, o, g, s, usemtl, mtllib, l, p, comments: nothing to do for positions
    if not verts:
        raise MeshError("OBJ file has no vertices")
    normals = np.array(vn, dtype=np.float64) if len(vn) == len(verts) else None
    return np.array(verts, dtype=np.float64), _faces_array(rows), normals


# ------------------------------------------------------------------------------ write
def save_mesh(path, mesh_or_vertices, faces=None) -> Path:
    """Write a mesh as binary little-endian PLY (float64 xyz) or ASCII OFF, chosen by suffix.

    The file is written to a temporary name and renamed, so a crash leaves no partial file.

    Parameters
    ----------
    path : str or pathlib.Path
        Target file, ending in ``.ply`` or ``.off``.
    mesh_or_vertices : Mesh or (n, 3) array_like
        A mesh, or its vertex positions (then ``faces`` is required).
    faces : (m, 3) array_like of int, optional
        The triangles when ``mesh_or_vertices`` is an array.

    Returns
    -------
    pathlib.Path
        The path written.

    Raises
    ------
    TypeError
        When the arguments are swapped (``save_mesh(path, mesh)`` is the order).
    MeshError
        For a folder, an unknown suffix or a non-triangle mesh.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> import prodmaps as pm
    >>> from prodmaps.mesh import ellipsoid
    >>> path = pm.save_mesh(pathlib.Path(tempfile.mkdtemp()) / "e.off", ellipsoid(1))
    >>> path.suffix, pm.load_mesh(path).n_vertices
    ('.off', 42)
    """
    if isinstance(path, Mesh):
        raise TypeError("save_mesh(path, mesh): the path comes first, the mesh second")
    if not isinstance(path, (str, Path)) and not hasattr(path, "__fspath__"):
        raise TypeError(f"save_mesh(path, mesh): path must be a file name, got {type(path).__name__}")
    if Path(path).is_dir():
        raise MeshError(f"{path}: is a folder; give a file name ending in .ply or .off")
    if isinstance(mesh_or_vertices, Mesh):
        v, f = mesh_or_vertices.vertices, mesh_or_vertices.faces
    else:
        v, f = np.asarray(mesh_or_vertices, np.float64), np.asarray(faces, np.int64)
    path = Path(path)
    ext = path.suffix.lower()
    if ext not in (".ply", ".off"):
        raise MeshError(f"{path}: can only write .ply or .off")
    if v.ndim != 2 or v.shape[1] != 3 or f.ndim != 2 or f.shape[1] != 3:
        raise MeshError(f"{path}: can only write triangle meshes; got vertices {v.shape}, faces {f.shape}")
    tmp = path.with_name(path.name + ".tmp")
    try:
        if ext == ".ply":
            header = (
                "ply\nformat binary_little_endian 1.0\n"
                f"element vertex {v.shape[0]}\nproperty double x\nproperty double y\nproperty double z\n"
                f"element face {f.shape[0]}\nproperty list uchar int vertex_indices\nend_header\n"
            ).encode("ascii")
            rec = np.zeros(f.shape[0], dtype=[("n", "u1"), ("i", "<i4", (3,))])
            rec["n"] = 3
            rec["i"] = f
            with open(tmp, "wb") as fh:
                fh.write(header)
                fh.write(np.ascontiguousarray(v, dtype="<f8").tobytes())
                fh.write(rec.tobytes())
        else:
            with open(tmp, "w", newline="\n") as fh:
                fh.write(f"OFF\n{v.shape[0]} {f.shape[0]} 0\n")
                np.savetxt(fh, v, fmt="%.17g")
                np.savetxt(fh, np.column_stack([np.full(f.shape[0], 3), f]), fmt="%d")
        os.replace(tmp, path)
    except OSError as exc:
        tmp.unlink(missing_ok=True)
        raise MeshError(f"{path}: cannot write ({exc})") from None
    return path
