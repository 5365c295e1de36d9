"""Regenerate the mesh-file variants of this folder (see README.md).

Every file encodes the same reference mesh (``reference.npz``): a once-subdivided
icosahedron (42 vertices, 80 faces) whose coordinates are multiples of 1/64, so that they
are exact in float32 and in any ASCII writer that prints 6 significant digits; a reader
must return exactly these vertices in exactly this order, and exactly these faces.

Tool-made files need the tools (``pip install trimesh meshio pymeshlab``); the others
imitate the output of Blender and of other writers byte for byte and need only numpy::

    python tests/data/variants/make_variants.py            # all files
    python tests/data/variants/make_variants.py --hand     # only the hand-made ones
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent


def reference_mesh() -> tuple[np.ndarray, np.ndarray]:
    t = (1 + 5**0.5) / 2
    v = np.array([[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t],
                  [0, -1, -t], [0, 1, -t], [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1]], float)
    f = [[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4],
         [11, 10, 2], [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8],
         [3, 8, 9], [4, 9, 5], [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1]]
    verts, faces, mid = list(v), [], {}

    def midpoint(a, b):
        key = (min(a, b), max(a, b))
        if key not in mid:
            mid[key] = len(verts)
            verts.append((verts[a] + verts[b]) / 2)
        return mid[key]

    for a, b, c in f:
        ab, bc, ca = midpoint(a, b), midpoint(b, c), midpoint(c, a)
        faces += [[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]
    v = np.array(verts)
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    return np.round(v * 64) / 64, np.array(faces, dtype=np.int64)


V, F = reference_mesh()
N = V.shape[0]
COLORS = (np.arange(N * 3).reshape(N, 3) * 37) % 256  # arbitrary per-vertex colours
NORMALS = V / np.linalg.norm(V, axis=1, keepdims=True)
UV = np.column_stack([np.arctan2(V[:, 1], V[:, 0]) / (2 * np.pi) + 0.5, V[:, 2] / 2 + 0.5])


def g(x) -> str:
    """Format like a C ``%g`` writer (exact for the reference coordinates)."""
    return f"{x:g}"


def f6(x) -> str:
    return f"{x:.6f}"


def write(name: str, data: str | bytes, crlf: bool = False) -> None:
    if isinstance(data, str):
        data = data.encode("ascii")
    if crlf:
        data = data.replace(b"\r\n", b"\n").replace(b"\n", b"\r\n")
    (HERE / name).write_bytes(data)


# ------------------------------------------------------------------------------ hand-made
def ply_header(fmt: str, vprops: list[str], fprops: list[str], comments=(), nl="\n") -> str:
    lines = ["ply", f"format {fmt} 1.0", *[f"comment {c}" for c in comments],
             f"element vertex {N}", *[f"property {p}" for p in vprops],
             f"element face {F.shape[0]}", *[f"property {p}" for p in fprops], "end_header"]
    return nl.join(lines) + nl


def hand_made() -> None:
    # --- OBJ, Blender 4.x exporter: header, mtllib, o, v, vn (per face), vt (per corner), s 0,
    # usemtl, f v/vt/vn (vt/vn indices differ from v indices)
    fn = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    fn /= np.linalg.norm(fn, axis=1, keepdims=True)
    out = ["# Blender 4.1.1", "# www.blender.org", "mtllib icosphere.mtl", "o Icosphere"]
    out += [f"v {f6(x)} {f6(y)} {f6(z)}" for x, y, z in V]
    out += [f"vn {a:.4f} {b:.4f} {c:.4f}" for a, b, c in fn]
    corner_uv = UV[F.ravel()]
    out += [f"vt {a:.6f} {b:.6f}" for a, b in corner_uv]
    out += ["s 0", "usemtl Material"]
    out += [f"f {a + 1}/{3 * i + 1}/{i + 1} {b + 1}/{3 * i + 2}/{i + 1} {c + 1}/{3 * i + 3}/{i + 1}"
            for i, (a, b, c) in enumerate(F)]
    write("blender4.obj", "\n".join(out) + "\n")

    # --- OBJ, Blender 2.8-3.x legacy exporter: 'Blender v2.93 OBJ File', vt before vn, s off
    out = ["# Blender v2.93.1 OBJ File: ''", "# www.blender.org", "mtllib icosphere.mtl",
           "o Icosphere"]
    out += [f"v {f6(x)} {f6(y)} {f6(z)}" for x, y, z in V]
    out += [f"vt {a:.6f} {b:.6f}" for a, b in corner_uv]
    out += [f"vn {a:.4f} {b:.4f} {c:.4f}" for a, b, c in fn]
    out += ["usemtl None", "s off"]
    out += [f"f {a + 1}/{3 * i + 1}/{i + 1} {b + 1}/{3 * i + 2}/{i + 1} {c + 1}/{3 * i + 3}/{i + 1}"
            for i, (a, b, c) in enumerate(F)]
    write("blender293.obj", "\n".join(out) + "\n")

    # --- OBJ, f v//vn with per-vertex normals, groups, comments, CRLF
    out = ["# exported on Windows: CRLF line endings", "mtllib shape.mtl", "g body"]
    out += [f"v {g(x)} {g(y)} {g(z)}" for x, y, z in V]
    out += [f"vn {a:.6f} {b:.6f} {c:.6f}" for a, b, c in NORMALS]
    out += ["usemtl skin", "s 1"]
    out += [f"f {a + 1}//{a + 1} {b + 1}//{b + 1} {c + 1}//{c + 1}" for a, b, c in F]
    write("crlf_normals.obj", "\n".join(out) + "\n", crlf=True)

    # --- OBJ, negative (relative) indices, vertices and faces interleaved (each vertex is
    # written just before the first face that uses it), so that a relative index depends on
    # how many vertices were read so far; 'g'/'usemtl' switch half-way
    out, written = ["# negative indices count back from the latest vertex", "g part1"], 0
    for i, face in enumerate(F):
        if i == F.shape[0] // 2:
            out += ["g part2", "usemtl other"]
        while written <= face.max():
            out.append("v " + " ".join(g(c) for c in V[written]))
            written += 1
        out.append("f " + " ".join(str(int(k) - written) for k in face))
    write("negative_indices.obj", "\n".join(out) + "\n")

    # --- OFF family
    write("coff.off", "COFF\n" + f"{N} {F.shape[0]} 0\n"
          + "".join(f"{g(x)} {g(y)} {g(z)} {r} {gg} {b} 255\n" for (x, y, z), (r, gg, b) in zip(V, COLORS))
          + "".join(f"3 {a} {b} {c}\n" for a, b, c in F))
    write("noff.off", "NOFF\n" + f"{N} {F.shape[0]} 0\n"
          + "".join(f"{g(x)} {g(y)} {g(z)} {a:.6f} {b:.6f} {c:.6f}\n" for (x, y, z), (a, b, c) in zip(V, NORMALS))
          + "".join(f"3 {a} {b} {c}\n" for a, b, c in F))
    write("cnoff.off", "CNOFF\n" + f"{N} {F.shape[0]} 0\n"
          + "".join(f"{g(x)} {g(y)} {g(z)} {a:.6f} {b:.6f} {c:.6f} {r / 255:.6f} {gg / 255:.6f} {bb / 255:.6f} 1\n"
                    for (x, y, z), (a, b, c), (r, gg, bb) in zip(V, NORMALS, COLORS))
          + "".join(f"3 {a} {b} {c} 0.5 0.5 0.5\n" for a, b, c in F))
    write("comments_crlf.off", "OFF # Princeton shape benchmark style\r\n# a comment line\r\n\r\n"
          + f"{N} {F.shape[0]} {3 * F.shape[0] // 2}\r\n"
          + "".join(f"{float(x)!r} {float(y)!r} {float(z)!r}\r\n" for x, y, z in V)
          + "\r\n".join(f"3  {a} {b} {c}" for a, b, c in F) + "\r\n")
    write("counts_on_header.off", f"OFF {N} {F.shape[0]} 0\n"
          + "".join(f"{g(x)} {g(y)} {g(z)}\n" for x, y, z in V)
          + "".join(f"3 {a} {b} {c}\n" for a, b, c in F))

    # --- PLY family
    vid = "".join(f"{g(x)} {g(y)} {g(z)}\n" for x, y, z in V)
    fid = "".join(f"3 {a} {b} {c}\n" for a, b, c in F)
    write("vertex_index_ascii.ply",
          ply_header("ascii", ["float x", "float y", "float z"], ["list uchar int vertex_index"],
                     ["made by a range scanner"]) + vid + fid)
    write("crlf_ascii.ply",
          ply_header("ascii", ["float x", "float y", "float z"], ["list uchar int vertex_indices"],
                     nl="\r\n") + vid + fid, crlf=True)
    # Blender 2.9x legacy Python exporter (ascii, normals + uv + colours, uint indices)
    write("blender293_ascii.ply",
          ply_header("ascii", ["float x", "float y", "float z", "float nx", "float ny", "float nz",
                               "float s", "float t", "uchar red", "uchar green", "uchar blue"],
                     ["list uchar uint vertex_indices"], ["Created by Blender 2.93.1 - www.blender.org"])
          + "".join(f"{f6(x)} {f6(y)} {f6(z)} {a:.6f} {b:.6f} {c:.6f} {s:.6f} {t:.6f} {r} {gg} {bb}\n"
                    for (x, y, z), (a, b, c), (s, t), (r, gg, bb) in zip(V, NORMALS, UV, COLORS))
          + fid)

    # --- polygon files (Blender keeps quads unless 'Triangulate faces' is ticked): a cube of
    # quads as OBJ, a pyramid with one quad and four triangles as binary PLY (uint indices)
    cube = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], dtype=float)
    quads = [[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4], [1, 5, 7, 3]]
    out = ["# Blender 4.1.1", "# www.blender.org", "o Cube"]
    out += [f"v {f6(x)} {f6(y)} {f6(z)}" for x, y, z in cube]
    out += ["vn -0.0000 1.0000 -0.0000", "vt 0.625000 0.500000", "s 0"]
    out += ["f " + " ".join(f"{k + 1}/1/1" for k in q) for q in quads]
    write("polygons_blender_quads.obj", "\n".join(out) + "\n")
    pyramid = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0.5, 0.5, 1.0]], dtype="<f4")
    polys = [[0, 3, 2, 1], [0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4]]
    header = ("ply\nformat binary_little_endian 1.0\ncomment Created in Blender version 4.1.1\n"
              "element vertex 5\nproperty float x\nproperty float y\nproperty float z\n"
              "element face 5\nproperty list uchar uint vertex_indices\nend_header\n")
    body = pyramid.tobytes() + b"".join(np.uint8(len(p)).tobytes() + np.array(p, "<u4").tobytes()
                                        for p in polys)
    write("polygons_mixed_binary.ply", header.encode("ascii") + body)

    xyz32 = [("float x", "<f4", V[:, 0]), ("float y", "<f4", V[:, 1]), ("float z", "<f4", V[:, 2])]

    # Blender 4.x C++ exporter: binary LE, x y z nx ny nz s t, 'list uchar uint vertex_indices'
    blender4 = xyz32 + [("float nx", "<f4", NORMALS[:, 0]), ("float ny", "<f4", NORMALS[:, 1]),
                        ("float nz", "<f4", NORMALS[:, 2]), ("float s", "<f4", UV[:, 0]),
                        ("float t", "<f4", UV[:, 1]), ("uchar red", "|u1", COLORS[:, 0]),
                        ("uchar green", "|u1", COLORS[:, 1]), ("uchar blue", "|u1", COLORS[:, 2]),
                        ("uchar alpha", "|u1", 255)]
    _binary_faces("blender4.ply", "binary_little_endian", blender4,
                  [("list uchar uint vertex_indices", "u1", "u4")], ["Created in Blender version 4.1.1"])
    _binary_faces("uint32_types.ply", "binary_little_endian",
                  [("float32 x", "<f4", V[:, 0]), ("float32 y", "<f4", V[:, 1]), ("float32 z", "<f4", V[:, 2])],
                  [("list uint8 uint32 vertex_indices", "u1", "u4")])
    _binary_faces("vertex_index_int32.ply", "binary_little_endian", xyz32,
                  [("list uint8 int32 vertex_index", "u1", "i4")])
    _binary_faces("uchar_indices.ply", "binary_little_endian", xyz32,  # small meshes: 1-byte indices
                  [("list uchar uchar vertex_indices", "u1", "u1")])
    _binary_faces("int_count.ply", "binary_little_endian", xyz32,
                  [("list int int vertex_indices", "i4", "i4")])
    _binary_faces("face_props_around_list.ply", "binary_little_endian", xyz32,
                  [("uchar flags", "u1", 7), ("list uchar int vertex_indices", "u1", "i4"),
                   ("float quality", "f4", 0.25), ("uchar red", "u1", 200)])
    _binary_faces("big_endian.ply", "binary_big_endian",
                  [("double x", "<f8", V[:, 0]), ("double y", "<f8", V[:, 1]), ("double z", "<f8", V[:, 2]),
                   ("ushort flags", "<u2", 3)],
                  [("list uchar int vertex_indices", "u1", "i4")], ["big-endian, e.g. from a Mac PPC scanner"])
    _binary_faces("crlf_header_binary.ply", "binary_little_endian", xyz32,
                  [("list uchar int vertex_indices", "u1", "i4")], header_nl="\r\n")
    _binary_faces("extra_elements.ply", "binary_little_endian", xyz32,
                  [("list uchar int vertex_indices", "u1", "i4")], extra_edges=True)


def _binary_faces(name, fmt, vfields, fdecl, comments=(), header_nl="\n",
                  extra_edges=False):
    """Write a binary PLY whose face element has the properties ``fdecl`` (in order):
    ``(declaration, count dtype, index dtype)`` for the list, ``(declaration, dtype, value)``
    for scalars."""
    e = "<" if fmt == "binary_little_endian" else ">"
    fprops, fdt, fvals = [], [], []
    for i, (decl, a, b) in enumerate(fdecl):
        fprops.append(decl)
        if decl.startswith("list"):
            fdt += [(f"n{i}", e + a), (f"i{i}", e + b, (3,))]
            fvals += [(f"n{i}", 3), (f"i{i}", F)]
        else:
            fdt.append((f"s{i}", e + a))
            fvals.append((f"s{i}", b))
    vdt = np.dtype([(f"p{i}", e + dt[1:]) for i, (_, dt, _) in enumerate(vfields)])
    vrec = np.zeros(N, dtype=vdt)
    for i, (_, _, val) in enumerate(vfields):
        vrec[f"p{i}"] = val
    frec = np.zeros(F.shape[0], dtype=np.dtype(fdt))
    for key, val in fvals:
        frec[key] = val
    header = ply_header(fmt, [d for d, _, _ in vfields], fprops, comments, nl=header_nl)
    tail = b""
    if extra_edges:  # an 'edge' element after the faces, as some scanners write
        header = header.replace(f"end_header{header_nl}",
                                f"element edge 2{header_nl}property int vertex1{header_nl}"
                                f"property int vertex2{header_nl}end_header{header_nl}")
        tail = np.array([[0, 1], [1, 2]], dtype=e + "i4").tobytes()
    write(name, header.encode("ascii") + vrec.tobytes() + frec.tobytes() + tail)


# ------------------------------------------------------------------------------ tool-made
def tool_made() -> None:
    import meshio
    import pymeshlab
    import trimesh

    tm = trimesh.Trimesh(V, F, process=False)
    write("trimesh_binary.ply", tm.export(file_type="ply"))
    write("trimesh_ascii.ply", tm.export(file_type="ply", encoding="ascii"))
    tmc = trimesh.Trimesh(V, F, process=False, vertex_colors=np.column_stack([COLORS, np.full(N, 255)]),
                          vertex_normals=NORMALS)
    write("trimesh_colors_normals.ply", tmc.export(file_type="ply", vertex_normal=True))
    write("trimesh.off", tm.export(file_type="off"))
    write("trimesh_normals.obj", tm.export(file_type="obj", include_normals=True))
    tmuv = trimesh.Trimesh(V, F, process=False,
                           visual=trimesh.visual.TextureVisuals(uv=UV))
    write("trimesh_uv.obj", tmuv.export(file_type="obj", include_normals=True, write_texture=False))

    cells = [("triangle", F)]
    meshio.write(str(HERE / "meshio_binary.ply"), meshio.Mesh(V, cells), binary=True)
    meshio.write(str(HERE / "meshio_ascii.ply"), meshio.Mesh(V, cells), binary=False)
    meshio.write(str(HERE / "meshio.off"), meshio.Mesh(V, cells))
    meshio.write(str(HERE / "meshio.obj"), meshio.Mesh(V, cells))

    m = pymeshlab.Mesh(V, F, v_normals_matrix=NORMALS,
                       v_color_matrix=np.column_stack([COLORS / 255, np.ones(N)]),
                       v_scalar_array=V[:, 2].copy(), v_tex_coords_matrix=UV,
                       f_color_matrix=np.tile([0.0, 0.0, 1.0, 1.0], (F.shape[0], 1)),
                       w_tex_coords_matrix=UV[F.ravel()])
    ms = pymeshlab.MeshSet()
    ms.add_mesh(m)
    every = dict(save_vertex_color=True, save_vertex_normal=True, save_vertex_quality=True,
                 save_vertex_coord=True, save_face_color=True)
    # binary PLY with per-wedge texture coordinates: 'property list uchar float texcoord'
    ms.save_current_mesh(str(HERE / "meshlab_binary.ply"), binary=True, save_wedge_texcoord=True, **every)
    ms.save_current_mesh(str(HERE / "meshlab_ascii.ply"), binary=False, **every)
    ms.save_current_mesh(str(HERE / "meshlab.off"), **{k: v for k, v in every.items() if "quality" not in k})
    ms.save_current_mesh(str(HERE / "meshlab.obj"), save_vertex_color=True, save_vertex_normal=True,
                         save_wedge_texcoord=True)
    # polygonal files (MeshLab keeps faux edges as polygons): must be refused as non-triangular
    pyramid = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0.5, 0.5, 1.0]])
    polys = [np.array(p, dtype=np.uint32) for p in ([0, 3, 2, 1], [0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4])]
    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(pyramid, polys))
    ms.save_current_mesh(str(HERE / "polygons_meshlab_mixed.obj"), save_polygonal=True)
    ms.save_current_mesh(str(HERE / "polygons_meshlab_mixed.off"), save_polygonal=True)
    for extra in HERE.glob("*.mtl"):  # material files referenced by the OBJ exports
        extra.unlink()


if __name__ == "__main__":
    np.savez(HERE / "reference.npz", vertices=V, faces=F)
    hand_made()
    if "--hand" not in sys.argv:
        tool_made()
