"""Reading and writing triangle meshes: PLY (ASCII and binary), OFF, OBJ; positions only.

Readers are strict: a truncated, malformed or unreadable file raises :class:`MeshError`
with the file name and the reason; the result is validated by :class:`Mesh` (pass
``validate=False`` to get the raw arrays, e.g. to repair them with
:func:`prodmaps.mesh.repair`).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from .mesh import Mesh, MeshError

__all__ = ["load_mesh", "read_mesh_arrays", "save_mesh"]

_PLY_TYPES = {
    "char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1",
    "short": "i2", "int16": "i2", "ushort": "u2", "uint16": "u2",
    "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
    "float": "f4", "float32": "f4", "double": "f8", "float64": "f8",
}


def load_mesh(path, *, validate: bool = True, name: str | None = None) -> Mesh:
    """Load a triangle mesh from ``.ply``, ``.off`` or ``.obj`` (positions and faces only).

    Raises :class:`MeshError` if the file is missing, unreadable, truncated, or if the
    mesh fails validation (see :func:`prodmaps.mesh.validate`).
    """
    v, f = read_mesh_arrays(path)
    try:
        return Mesh(v, f, name=Path(path).stem if name is None else name, validate=validate)
    except MeshError as exc:
        raise MeshError(f"{path}: {exc}") from None


def read_mesh_arrays(path) -> tuple[np.ndarray, np.ndarray]:
    """Return raw ``(vertices (n,3) float64, faces (m,k) int64)`` without validation."""
    path = Path(path)
    if not path.is_file():
        raise MeshError(f"{path}: no such file")
    ext = path.suffix.lower()
    readers = {".ply": _read_ply, ".off": _read_off, ".obj": _read_obj}
    if ext not in readers:
        raise MeshError(f"{path}: unsupported format {ext!r}; use .ply, .off or .obj")
    try:
        data = path.read_bytes()
    except OSError as exc:  # permissions, I/O errors
        raise MeshError(f"{path}: unreadable ({exc})") from exc
    try:
        return readers[ext](data)
    except MeshError as exc:
        raise MeshError(f"{path}: {exc}") from None
    except (ValueError, IndexError, UnicodeDecodeError) as exc:
        raise MeshError(f"{path}: malformed {ext[1:].upper()} file ({exc})") from None


def _faces_array(rows: list[list[int]]) -> np.ndarray:
    if not rows:
        return np.zeros((0, 3), dtype=np.int64)
    lengths = {len(r) for r in rows}
    if len(lengths) > 1 or lengths != {3}:
        # keep polygon information so that validation can name it
        width = max(lengths)
        return np.array([r + [r[-1]] * (width - len(r)) for r in rows], dtype=np.int64)
    return np.asarray(rows, dtype=np.int64)


# ------------------------------------------------------------------------------ PLY
def _read_ply(data: bytes):
    end = data.find(b"end_header")
    if not data.startswith(b"ply") or end < 0:
        raise MeshError("not a PLY file (missing 'ply' magic or 'end_header')")
    nl = data.find(b"\n", end)
    if nl < 0:
        raise MeshError("truncated PLY header")
    header = data[:end].decode("ascii").splitlines()
    body = data[nl + 1:]
    fmt = None
    elements: list[dict] = []
    for line in header:
        tok = line.split()
        if not tok:
            continue
        if tok[0] == "format":
            fmt = tok[1]
        elif tok[0] == "element":
            elements.append({"name": tok[1], "count": int(tok[2]), "props": []})
        elif tok[0] == "property":
            if not elements:
                raise MeshError("PLY property before any element")
            if tok[1] == "list":
                elements[-1]["props"].append((tok[4], "list", _PLY_TYPES[tok[2]], _PLY_TYPES[tok[3]]))
            else:
                elements[-1]["props"].append((tok[2], _PLY_TYPES[tok[1]]))
    if fmt not in ("ascii", "binary_little_endian", "binary_big_endian"):
        raise MeshError(f"unknown PLY format {fmt!r}")
    if fmt == "ascii":
        return _read_ply_ascii(body.decode("ascii"), elements)
    endian = "<" if fmt == "binary_little_endian" else ">"
    return _read_ply_binary(body, elements, endian)


def _read_ply_binary(body: bytes, elements, endian):
    vertices = faces = None
    offset = 0
    for el in elements:
        props = el["props"]
        count = el["count"]
        has_list = any(p[1] == "list" for p in props)
        if not has_list:
            dtype = np.dtype([(p[0], endian + p[1]) for p in props])
            nbytes = dtype.itemsize * count
            if offset + nbytes > len(body):
                raise MeshError(f"truncated file: element '{el['name']}' needs {nbytes} bytes, "
                                f"{len(body) - offset} left")
            arr = np.frombuffer(body, dtype=dtype, count=count, offset=offset)
            offset += nbytes
            if el["name"] == "vertex":
                vertices = np.stack([arr[c].astype(np.float64) for c in ("x", "y", "z")], axis=1)
            continue
        # list element (faces): fast path for one list property with constant length 3
        if len(props) == 1 and el["name"] == "face":
            _, _, ctype, itype = props[0]
            rec = np.dtype([("n", endian + ctype), ("i", endian + itype, (3,))])
            nbytes = rec.itemsize * count
            if offset + nbytes <= len(body):
                arr = np.frombuffer(body, dtype=rec, count=count, offset=offset)
                if np.all(arr["n"] == 3):
                    faces = arr["i"].astype(np.int64)
                    offset += nbytes
                    continue
            faces, offset = _read_ply_lists_slow(body, offset, count, ctype, itype, endian)
            continue
        raise MeshError(f"unsupported PLY element layout for '{el['name']}'")
    if vertices is None or faces is None:
        raise MeshError("PLY file has no vertex or no face element")
    return vertices, faces


def _read_ply_lists_slow(body, offset, count, ctype, itype, endian):
    """Variable-length face lists (polygons); only reached for non-triangle files."""
    cdt, idt = np.dtype(endian + ctype), np.dtype(endian + itype)
    rows = []
    for _ in range(count):
        if offset + cdt.itemsize > len(body):
            raise MeshError("truncated file inside the face list")
        k = int(np.frombuffer(body, cdt, 1, offset)[0])
        offset += cdt.itemsize
        if offset + k * idt.itemsize > len(body):
            raise MeshError("truncated file inside the face list")
        rows.append(np.frombuffer(body, idt, k, offset).astype(np.int64).tolist())
        offset += k * idt.itemsize
    return _faces_array(rows), offset


def _read_ply_ascii(text: str, elements):
    lines = [ln for ln in text.splitlines() if ln.strip()]
    pos = 0
    vertices = faces = None
    for el in elements:
        chunk = lines[pos:pos + el["count"]]
        if len(chunk) < el["count"]:
            raise MeshError(f"truncated file: element '{el['name']}' has {len(chunk)} of {el['count']} rows")
        pos += el["count"]
        if el["name"] == "vertex":
            names = [p[0] for p in el["props"]]
            arr = np.array([ln.split() for ln in chunk], dtype=np.float64)
            vertices = arr[:, [names.index(c) for c in ("x", "y", "z")]]
        elif el["name"] == "face":
            faces = _faces_array([[int(t) for t in ln.split()[1:1 + int(ln.split()[0])]] for ln in chunk])
    if vertices is None or faces is None:
        raise MeshError("PLY file has no vertex or no face element")
    return vertices, faces


# ------------------------------------------------------------------------------ OFF
def _read_off(data: bytes):
    lines = [ln.split("#")[0].strip() for ln in data.decode("ascii").splitlines()]
    lines = [ln for ln in lines if ln]
    if not lines or not lines[0].startswith("OFF"):
        raise MeshError("not an OFF file (missing 'OFF' magic)")
    head = lines[0][3:].split() or lines[1].split()
    start = 1 if lines[0][3:].split() else 2
    nv, nf = int(head[0]), int(head[1])
    vlines = lines[start:start + nv]
    flines = lines[start + nv:start + nv + nf]
    if len(vlines) < nv or len(flines) < nf:
        raise MeshError(f"truncated file: expected {nv} vertices and {nf} faces, "
                        f"found {len(vlines)} and {len(flines)}")
    v = np.array([ln.split()[:3] for ln in vlines], dtype=np.float64)
    rows = []
    for ln in flines:
        tok = ln.split()
        k = int(tok[0])
        if len(tok) < k + 1:
            raise MeshError(f"malformed face line {ln!r}")
        rows.append([int(t) for t in tok[1:k + 1]])
    return v.reshape(-1, 3), _faces_array(rows)


# ------------------------------------------------------------------------------ OBJ
def _read_obj(data: bytes):
    verts, rows = [], []
    for ln in data.decode("utf-8", errors="strict").splitlines():
        tok = ln.split()
        if not tok:
            continue
        if tok[0] == "v":
            if len(tok) < 4:
                raise MeshError(f"malformed vertex line {ln!r}")
            verts.append(tok[1:4])
        elif tok[0] == "f":
            idx = [int(t.split("/")[0]) for t in tok[1:]]
            # OBJ is 1-based; negative indices count back from the latest vertex
            rows.append([i - 1 if i > 0 else len(verts) + i for i in idx])
    if not verts:
        raise MeshError("OBJ file has no vertices")
    return np.array(verts, dtype=np.float64), _faces_array(rows)


# ------------------------------------------------------------------------------ write
def save_mesh(path, mesh_or_vertices, faces=None) -> Path:
    """Write a mesh as binary little-endian PLY (float64 xyz) or ASCII OFF, chosen by suffix.

    The file is written to a temporary name and renamed, so a crash leaves no partial file.
    """
    if isinstance(mesh_or_vertices, Mesh):
        v, f = mesh_or_vertices.vertices, mesh_or_vertices.faces
    else:
        v, f = np.asarray(mesh_or_vertices, np.float64), np.asarray(faces, np.int64)
    path = Path(path)
    tmp = path.with_name(path.name + ".tmp")
    ext = path.suffix.lower()
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
    elif ext == ".off":
        with open(tmp, "w") as fh:
            fh.write(f"OFF\n{v.shape[0]} {f.shape[0]} 0\n")
            np.savetxt(fh, v, fmt="%.17g")
            np.savetxt(fh, np.column_stack([np.full(f.shape[0], 3), f]), fmt="%d")
    else:
        raise MeshError(f"{path}: can only write .ply or .off")
    os.replace(tmp, path)
    return path
