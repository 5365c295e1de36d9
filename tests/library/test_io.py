"""Mesh I/O on real-world file variants (tests/data/variants, see its README.md).

The broken corpus (tests/data/broken) and its named problems are tested in test_mesh.py
(``test_broken_corpus_errors_name_the_problem``); here we add that every message starts
with the file path, and test the variants, polygons, overflow, malformed files and writing.
"""

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import prodmaps as pm
from prodmaps.io import read_mesh_arrays

DATA = Path(__file__).resolve().parents[1] / "data"
BROKEN = DATA / "broken"
VARIANTS = DATA / "variants"
REF = np.load(VARIANTS / "reference.npz")
MESH_FILES = sorted(p.name for p in VARIANTS.iterdir() if p.suffix in (".ply", ".off", ".obj"))
SAME_MESH = [n for n in MESH_FILES if not n.startswith("polygons_")]
POLYGONS = [n for n in MESH_FILES if n.startswith("polygons_")]


def test_variant_corpus_is_complete():
    expected = {
        "trimesh_binary.ply", "trimesh_ascii.ply", "trimesh_colors_normals.ply", "trimesh.off",
        "trimesh_normals.obj", "trimesh_uv.obj", "meshio_binary.ply", "meshio_ascii.ply",
        "meshio.off", "meshio.obj", "meshlab_binary.ply", "meshlab_ascii.ply", "meshlab.off",
        "meshlab.obj", "blender4.obj", "blender293.obj", "blender4.ply", "blender293_ascii.ply",
        "crlf_normals.obj", "negative_indices.obj", "coff.off", "noff.off", "cnoff.off",
        "comments_crlf.off", "counts_on_header.off", "vertex_index_ascii.ply",
        "vertex_index_int32.ply", "uint32_types.ply", "uchar_indices.ply", "int_count.ply",
        "face_props_around_list.ply",
        "big_endian.ply", "crlf_ascii.ply", "crlf_header_binary.ply", "extra_elements.ply",
    }
    assert expected <= set(SAME_MESH)
    assert {"polygons_blender_quads.obj", "polygons_mixed_binary.ply",
            "polygons_meshlab_mixed.obj", "polygons_meshlab_mixed.off"} <= set(POLYGONS)


@pytest.mark.parametrize("name", SAME_MESH)
def test_variant_gives_exact_reference_mesh(name):
    v, f = read_mesh_arrays(VARIANTS / name)
    assert v.dtype == np.float64 and f.dtype == np.int64
    np.testing.assert_array_equal(v, REF["vertices"])  # exact values, exact vertex order
    np.testing.assert_array_equal(f, REF["faces"])
    m = pm.load_mesh(VARIANTS / name)
    assert (m.n_vertices, m.n_faces, m.name) == (42, 80, Path(name).stem) and m.is_closed


@pytest.mark.parametrize("name", POLYGONS)
def test_polygon_files_reach_validation(name):
    v, f = read_mesh_arrays(VARIANTS / name)
    assert f.shape[1] == 4  # kept as polygons (padded), not triangulated behind our back
    with pytest.raises(pm.MeshError, match="non-triangular faces.*triangulate the mesh first") as info:
        pm.load_mesh(VARIANTS / name, triangulate=False)
    assert str(info.value).startswith(str(VARIANTS / name))
    assert "triangulate_polygons" in str(info.value)  # the message names the helper


@pytest.mark.parametrize("name", POLYGONS)
def test_polygon_files_are_triangulated_on_load_with_a_warning(name):
    v, f = read_mesh_arrays(VARIANTS / name)
    n_corners = 4 - (f[:, 3] == f[:, 2])  # padded triangles repeat their last index
    with pytest.warns(pm.MeshWarning, match=r"(\d+) polygon faces .* triangulated into (\d+) triangles") as rec:
        m = pm.load_mesh(VARIANTS / name)
    n_quads = int(np.sum(n_corners == 4))
    assert m.n_faces == f.shape[0] + n_quads  # every quad becomes two triangles
    msg = str(rec[0].message)
    assert msg.startswith(str(VARIANTS / name)) and f"{n_quads} polygon faces" in msg
    assert f"into {2 * n_quads} triangles" in msg and "triangulate=False" in msg
    np.testing.assert_array_equal(m.vertices, v)  # vertices untouched, in file order
    assert m.is_closed  # a closed surface: the fans close it as the polygons did


def _write(tmp_path, name, text, mode="w"):
    p = tmp_path / name
    if mode == "wb":
        p.write_bytes(text)
    else:
        p.write_text(text)
    return p


TETRA_V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1.0]])
TETRA_F = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])


@pytest.mark.parametrize("scale, problem", [(1e200, "squared lengths"), (1e100, "face areas")])
def test_overflowing_coordinates_are_named(tmp_path, scale, problem):
    v = TETRA_V * scale
    p = _write(tmp_path, "huge.off", "OFF\n4 4 0\n"
               + "".join(f"{x!r} {y!r} {z!r}\n" for x, y, z in v.tolist())
               + "".join(f"3 {a} {b} {c}\n" for a, b, c in TETRA_F))
    with pytest.raises(pm.MeshError, match=rf"coordinates too large \(max \|x\| = 1e\+{int(np.log10(scale))}\): "
                                            rf"{problem} overflow float64; rescale the mesh") as info:
        pm.load_mesh(p)
    assert str(info.value).startswith(str(p))
    assert "degenerate" not in str(info.value)
    pm.Mesh(TETRA_V * 1e70, TETRA_F)  # large but safe coordinates still pass


def test_broken_corpus_messages_start_with_the_path():
    # which problem each file is refused for: test_mesh.py::test_broken_corpus_errors_name_the_problem
    valid = {"tetra_ok.off", "tetra_vt.obj", "open_boundary.off"}
    for p in sorted(BROKEN.iterdir()):
        if p.name in valid:
            pm.load_mesh(p)
            continue
        with pytest.raises(pm.MeshError) as info:
            pm.load_mesh(p, triangulate=False)
        assert str(info.value).startswith(f"{p}: "), str(info.value)


PLY_HEAD = ("ply\nformat binary_little_endian 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
            "property float z\nelement face 4\nproperty list uchar uint vertex_index\nend_header\n")


def _tetra_ply_bytes(head=PLY_HEAD):
    rec = np.zeros(4, dtype=[("n", "u1"), ("i", "<u4", (3,))])
    rec["n"], rec["i"] = 3, TETRA_F
    return head.encode() + TETRA_V.astype("<f4").tobytes() + rec.tobytes()


@pytest.mark.parametrize(
    "name, content, message",
    [
        ("cut.ply", _tetra_ply_bytes()[:-7], "truncated"),
        ("cut_header.ply", PLY_HEAD[:60].encode(), "truncated file: the PLY header ends early"),
        ("badformat.ply", PLY_HEAD.replace("binary_little_endian", "binary_middle_endian").encode(),
         "malformed PLY header"),
        ("badtype.ply", PLY_HEAD.replace("float x", "real x").encode(), "malformed PLY header"),
        ("ascii_cut.ply", b"ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
         b"property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n",
         "truncated"),
        ("ascii_text.ply", b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
         b"property float z\nelement face 0\nproperty list uchar int vertex_indices\nend_header\n0 zero 0\n",
         "malformed PLY data"),
        ("points.ply", b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
         b"property float z\nend_header\n0 0 0\n", r"no faces: .*a point cloud; load it with pm\.load_point_cloud"),
        ("strips.ply", b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
         b"property float z\nelement tristrips 0\nproperty list int int vertex_indices\nend_header\n0 0 0\n",
         "triangle strips are not supported"),
        ("scalarlist.ply", b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
         b"property float z\nelement face 1\nproperty int vertex_indices\nend_header\n0 0 0\n0\n",
         "no 'vertex_indices' list property"),
        ("noz.ply", b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
         b"element face 0\nproperty list uchar int vertex_indices\nend_header\n0 0\n", "no z property"),
        ("4d.off", b"4OFF\n1 0 0\n0 0 0 1\n", "unsupported OFF variant '4OFF'"),
        ("binary.off", b"OFF BINARY\n", "binary OFF is not supported"),
        ("nocounts.off", b"OFF\n", "truncated"),
        ("badcounts.off", b"OFF\n4\n", "malformed counts line"),
        ("shortvertex.off", b"OFF\n1 0 0\n0 0\n", "fewer than 3 coordinates"),
        ("badface.off", b"OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1\n", "malformed face line"),
        ("floatindex.off", b"OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2.5\n", "malformed OFF file"),
        ("zero.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n", "OBJ indices start at 1"),
        ("shortv.obj", b"v 0 0\n", "fewer than 3 coordinates"),
        ("empty.obj", b"# nothing\n", "no vertices"),
        ("letters.obj", b"v 0 0 zero\n", "malformed OBJ file"),
    ],
)
def test_malformed_files_name_path_and_problem(tmp_path, name, content, message):
    p = _write(tmp_path, name, content, mode="wb")
    with pytest.raises(pm.MeshError, match=message) as info:
        pm.load_mesh(p)
    assert str(info.value).startswith(f"{p}: ")


def test_missing_directory_and_unsupported_name_the_path(tmp_path):
    for p, message in [(tmp_path / "nope.off", "no such file"), (tmp_path, "no such file"),
                       (_write(tmp_path, "m.stl", "solid"), "unsupported format '.stl'")]:
        with pytest.raises(pm.MeshError, match=message) as info:
            read_mesh_arrays(p)
        assert str(info.value).startswith(f"{p}: ")


def test_text_oddities_are_read(tmp_path):
    body = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4 # inline comment\nf 1 4 3\nf 2 \\\n 3 4\n"
    obj = _write(tmp_path, "odd.obj", b"\xef\xbb\xbf# caf\xe9 (latin-1 comment)\n" + body.encode(), mode="wb")
    np.testing.assert_array_equal(pm.load_mesh(obj).faces, TETRA_F)  # BOM, latin-1, continuation
    off = _write(tmp_path, "odd.off", b"\xef\xbb\xbfOFF\n# \xe9\n4 4 0\n" + b"\n".join(
        " ".join(map(str, r)).encode() for r in TETRA_V.tolist()) + b"\n"
        + b"".join(f"3 {a} {b} {c}\n".encode() for a, b, c in TETRA_F), mode="wb")
    np.testing.assert_array_equal(pm.load_mesh(off).vertices, TETRA_V)


def test_mixed_polygons_in_every_format(tmp_path):
    v = "0 0 0\n1 0 0\n1 1 0\n0 1 0\n0.5 0.5 1\n"
    off = _write(tmp_path, "mixed.off", "OFF\n5 5 0\n" + v + "4 0 3 2 1\n3 0 1 4\n3 1 2 4\n3 2 3 4\n3 3 0 4\n")
    obj = _write(tmp_path, "mixed.obj", "".join("v " + ln + "\n" for ln in v.splitlines())
                 + "f 1 4 3 2\nf 1 2 5\nf 2 3 5\nf 3 4 5\nf 4 1 5\n")
    ply = _write(tmp_path, "mixed.ply", "ply\nformat ascii 1.0\nelement vertex 5\nproperty float x\n"
                 "property float y\nproperty float z\nelement face 5\nproperty list uchar int vertex_indices\n"
                 "end_header\n" + v + "4 0 3 2 1\n3 0 1 4\n3 1 2 4\n3 2 3 4\n3 3 0 4\n")
    for p in (off, obj, ply):
        _, f = read_mesh_arrays(p)
        np.testing.assert_array_equal(f[0], [0, 3, 2, 1])
        np.testing.assert_array_equal(f[1], [0, 1, 4, 4])  # triangles padded with their last index
        with pytest.raises(pm.MeshError, match="non-triangular faces"):
            pm.load_mesh(p, triangulate=False)
        with pytest.warns(pm.MeshWarning, match="1 polygon faces .* into 2 triangles .* 6 triangles in all"):
            m = pm.load_mesh(p)
        np.testing.assert_array_equal(m.faces[:2], [[0, 3, 2], [0, 2, 1]])  # the quad's fan, in place
        assert m.n_faces == 6 and m.is_closed


@pytest.mark.parametrize("suffix", [".ply", ".off"])
def test_save_load_roundtrip_is_bit_exact(tmp_path, suffix):
    # test_mesh.py::test_save_load_roundtrip covers a real mesh; here every float64 bit counts
    rng = np.random.default_rng(0)
    v = REF["vertices"] * (1 + rng.standard_normal((42, 1)) * 1e-3) + np.array([1e3, -2e-7, 3.0])
    path = pm.save_mesh(tmp_path / f"m{suffix}", v, REF["faces"])
    assert path == tmp_path / f"m{suffix}" and not list(tmp_path.glob("*.tmp"))
    back_v, back_f = read_mesh_arrays(path)
    np.testing.assert_array_equal(back_v, v)
    np.testing.assert_array_equal(back_f, REF["faces"])
    mesh = pm.load_mesh(path)
    again = pm.save_mesh(tmp_path / f"again{suffix}", mesh)
    assert again.read_bytes() == path.read_bytes()


def test_saved_ply_is_standard(tmp_path):
    from trimesh.exchange.ply import load_ply  # another reader than ours

    path = pm.save_mesh(tmp_path / "m.ply", REF["vertices"], REF["faces"])
    header = path.read_bytes().split(b"end_header\n")[0].decode("ascii").splitlines()
    assert header[:2] == ["ply", "format binary_little_endian 1.0"]
    assert [ln for ln in header if ln.startswith("property")] == [
        "property double x", "property double y", "property double z",
        "property list uchar int vertex_indices"]
    with open(path, "rb") as fh:
        ply = load_ply(fh, fix_texture=False, skip_materials=True)
    assert ply["vertices"].dtype == np.float64
    np.testing.assert_array_equal(ply["vertices"], REF["vertices"])
    np.testing.assert_array_equal(ply["faces"], REF["faces"])


def test_save_errors_name_the_path(tmp_path):
    with pytest.raises(pm.MeshError, match="can only write .ply or .off") as info:
        pm.save_mesh(tmp_path / "m.obj", REF["vertices"], REF["faces"])
    assert str(info.value).startswith(str(tmp_path / "m.obj"))
    with pytest.raises(pm.MeshError, match="cannot write"):
        pm.save_mesh(tmp_path / "no_dir" / "m.ply", REF["vertices"], REF["faces"])
    with pytest.raises(pm.MeshError, match="triangle meshes"):
        pm.save_mesh(tmp_path / "q.off", REF["vertices"], np.zeros((2, 4), int))
    assert sorted(p.name for p in tmp_path.iterdir()) == []


def test_import_prodmaps_does_not_import_mesh_readers():
    code = ("import sys, prodmaps\n"
            "print([m for m in sys.modules if m.split('.')[0] in ('plyfile', 'trimesh', 'meshio')])\n")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == "[]"


def test_save_mesh_swapped_arguments_folder_and_binary_obj_say_what_is_wrong(tmp_path):
    from prodmaps.mesh import icosphere

    m = icosphere(1)
    with pytest.raises(TypeError, match="the path comes first"):
        pm.save_mesh(m, tmp_path / "a.ply")
    with pytest.raises(pm.MeshError, match="is a folder"):
        pm.save_mesh(tmp_path, m)
    junk = tmp_path / "junk.obj"
    junk.write_bytes(np.random.default_rng(0).integers(0, 256, 2000, dtype=np.uint8).tobytes())
    with pytest.raises(pm.MeshError, match="not a text OBJ file"):
        pm.load_mesh(junk)
