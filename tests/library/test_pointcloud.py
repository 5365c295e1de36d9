"""Point clouds: the container, the files, their bases, and everything that needs only a basis and a mass.

The pair used throughout: mesh 1 is ``ellipsoid(3)`` (642 vertices, a simple spectrum), cloud 2 a
random subset of 500 of its vertices in random order, so the ground truth is known exactly:
``p2p_21 = sub`` (cloud point ``i`` is mesh vertex ``sub[i]``).
"""

from __future__ import annotations

import numpy as np
import pytest

import prodmaps as pm
from prodmaps.descriptors import hks, hks_times, wks, wks_energies
from prodmaps.fmaps import fit_no17, no17_demo_descriptors, zoomout


@pytest.fixture(scope="module")
def pair():
    mesh = pm.mesh.ellipsoid(3)
    sub = np.random.default_rng(0).choice(mesh.n_vertices, 500, replace=False)
    cloud = pm.PointCloud(mesh.vertices[sub], name="cloud")
    B1, B2 = pm.eigenbasis(mesh, 60), pm.eigenbasis(cloud, 60)
    return mesh, cloud, sub, B1, B2


def fibonacci_sphere(n: int) -> np.ndarray:
    """``n`` nearly uniform points on the unit sphere (a spiral), ``(n, 3)``."""
    i = np.arange(n) + 0.5
    z = 1 - 2 * i / n
    r = np.sqrt(1 - z * z)
    phi = np.pi * (1 + 5**0.5) * i
    return np.column_stack([r * np.cos(phi), r * np.sin(phi), z])


# ------------------------------------------------------------------------------ the container
def test_point_cloud_holds_points_and_unit_normals():
    P = fibonacci_sphere(50)
    c = pm.PointCloud(P, 3.0 * P, name="ball")
    assert (c.n_points, c.n_vertices, c.name) == (50, 50, "ball")
    assert c.vertices is c.points and c.points.dtype == np.float64
    np.testing.assert_allclose(np.linalg.norm(c.normals, axis=1), 1.0, rtol=1e-14)  # normalised
    np.testing.assert_allclose(c.normals, P, atol=1e-14)
    with pytest.raises(ValueError):
        c.points[0, 0] = 1.0  # read-only, like a mesh's arrays
    P[0, 0] = 7.0
    assert c.points[0, 0] != 7.0  # the caller's array stays the caller's
    assert "PointCloud('ball', n_points=50, normals=True)" == repr(c)


@pytest.mark.parametrize("points, normals, message", [
    (np.zeros((10, 2)), None, r"shape \(n, 3\)"),
    (np.zeros((3, 3)), None, "at least 4 points"),
    (np.array([[0.0, 0, 0]] * 4 + [[np.nan, 0, 0]]), None, "non-finite"),
    (np.array([["0", "1", "2"]] * 5), None, "must be numbers"),
    (np.eye(4, 3), np.zeros((4, 3)), "normals are zero"),
    (np.eye(4, 3), np.ones((5, 3)), "normals must be numbers of shape"),
])
def test_point_cloud_refuses_bad_input_by_name(points, normals, message):
    with pytest.raises(pm.MeshError, match=message):
        pm.PointCloud(points, normals)


# ------------------------------------------------------------------------------ files
def _ply(path, P, N=None, binary=True, faces=None):
    props = ["x", "y", "z"] + (["nx", "ny", "nz"] if N is not None else [])
    table = P if N is None else np.hstack([P, N])
    head = ("ply\nformat " + ("binary_little_endian" if binary else "ascii") + " 1.0\n"
            f"element vertex {len(P)}\n" + "".join(f"property double {p}\n" for p in props)
            + (f"element face {len(faces)}\nproperty list uchar int vertex_indices\n" if faces is not None else "")
            + "end_header\n")
    with open(path, "wb") as fh:
        fh.write(head.encode())
        if binary:
            fh.write(np.ascontiguousarray(table, "<f8").tobytes())
            if faces is not None:
                rec = np.zeros(len(faces), dtype=[("n", "u1"), ("i", "<i4", (3,))])
                rec["n"], rec["i"] = 3, faces
                fh.write(rec.tobytes())
        else:
            fh.write("".join(" ".join(repr(float(x)) for x in row) + "\n" for row in table).encode())
            if faces is not None:
                fh.write("".join(f"3 {a} {b} {c}\n" for a, b, c in faces).encode())
    return path


def test_load_point_cloud_reads_every_format(tmp_path):
    P = fibonacci_sphere(40) * [1.0, 2.0, 3.0]
    N = fibonacci_sphere(40)
    txt = "\n".join(" ".join(repr(float(x)) for x in row) for row in P)
    files = {
        "binary.ply": (_ply(tmp_path / "binary.ply", P, N), True),
        "ascii.ply": (_ply(tmp_path / "ascii.ply", P, binary=False), False),
        "cloud.off": ((tmp_path / "cloud.off"), False),
        "normals.off": ((tmp_path / "normals.off"), True),
        "cloud.obj": ((tmp_path / "cloud.obj"), True),
        "cloud.xyz": ((tmp_path / "cloud.xyz"), False),
        "normals.txt": ((tmp_path / "normals.txt"), True),
        "cloud.npy": ((tmp_path / "cloud.npy"), True),
    }
    (tmp_path / "cloud.off").write_text(f"OFF\n40 0 0\n{txt}\n")
    (tmp_path / "normals.off").write_text("NOFF\n40 0 0\n" + "\n".join(
        " ".join(repr(float(x)) for x in row) for row in np.hstack([P, N])) + "\n")
    (tmp_path / "cloud.obj").write_text("# a cloud\n" + "".join(f"v {a!r} {b!r} {c!r}\n" for a, b, c in P.tolist())
                                       + "".join(f"vn {a!r} {b!r} {c!r}\n" for a, b, c in N.tolist()))
    (tmp_path / "cloud.xyz").write_text("# x y z\n" + txt.replace(" ", ", ") + "\n")
    (tmp_path / "normals.txt").write_text("\n".join(" ".join(repr(float(x)) for x in row)
                                                    for row in np.hstack([P, N])) + "\n")
    np.save(tmp_path / "cloud.npy", np.hstack([P, N]))
    for name, (path, has_normals) in files.items():
        c = pm.load_point_cloud(path)
        np.testing.assert_array_equal(c.points, P, err_msg=name)  # exact values, file order
        assert c.name == path.stem
        assert (c.normals is not None) == has_normals, name
        if has_normals:
            np.testing.assert_allclose(c.normals, N, atol=1e-15, err_msg=name)
    assert pm.load_point_cloud(files["binary.ply"][0], normals=False).normals is None


def test_load_point_cloud_of_a_mesh_file_gives_its_vertices(tmp_path):
    mesh = pm.mesh.ellipsoid(1)
    path = pm.save_mesh(tmp_path / "e.ply", mesh)
    c = pm.load_point_cloud(path, name="vertices")
    np.testing.assert_array_equal(c.points, mesh.vertices)
    assert c.name == "vertices" and c.normals is None


@pytest.mark.parametrize("name, content, message", [
    ("four.xyz", "0 0 0 1\n1 0 0 1\n0 1 0 1\n0 0 1 1\n", r"\(n, 3\) \(x y z\) or \(n, 6\)"),
    ("words.xyz", "0 0 zero\n", "malformed XYZ file"),
    ("three.xyz", "0 0 0\n1 0 0\n0 1 0\n", "at least 4 points"),
    ("cloud.las", "LASF", "unsupported point-cloud format '.las'"),
])
def test_load_point_cloud_names_the_file_and_the_problem(tmp_path, name, content, message):
    p = tmp_path / name
    p.write_text(content)
    with pytest.raises(pm.MeshError, match=message) as info:
        pm.load_point_cloud(p)
    assert str(info.value).startswith(f"{p}: ")
    with pytest.raises(pm.MeshError, match="no such file"):
        pm.load_point_cloud(tmp_path / "missing.ply")


@pytest.mark.parametrize("suffix", [".ply", ".off", ".obj"])
def test_load_mesh_on_a_cloud_names_load_point_cloud(tmp_path, suffix):
    P = fibonacci_sphere(30)
    path = tmp_path / f"points{suffix}"
    if suffix == ".ply":
        _ply(path, P)
    elif suffix == ".off":
        path.write_text("OFF\n30 0 0\n" + "\n".join(" ".join(map(repr, r)) for r in P.tolist()) + "\n")
    else:
        path.write_text("".join(f"v {a!r} {b!r} {c!r}\n" for a, b, c in P.tolist()))
    for load in (pm.load_mesh, lambda p: pm.io.load_mesh_repaired(p, verbose=False)):
        with pytest.raises(pm.MeshError, match=r"no faces: .*30 points .* pm\.load_point_cloud\(path\)") as info:
            load(path)  # load_mesh_repaired used to crash: "attempt to get argmax of an empty sequence"
        assert str(info.value).startswith(f"{path}: ")
    assert pm.load_point_cloud(path).n_points == 30
    np.savetxt(tmp_path / "points.xyz", P)
    with pytest.raises(pm.MeshError, match=r"unsupported format '\.xyz'.*a point cloud: .*pm\.load_point_cloud"):
        pm.load_mesh(tmp_path / "points.xyz")
    with pytest.raises(pm.MeshError, match="no faces.*pm.PointCloud"):
        pm.mesh.repair(P, np.zeros((0, 3), dtype=int))


# ------------------------------------------------------------------------------ bases
def test_unit_sphere_cloud_first_eigenvalue_within_ten_percent():
    cloud = pm.PointCloud(fibonacci_sphere(2000))
    b = pm.eigenbasis(cloud, 10)
    assert b.kind == "point_cloud" and b.vecs.shape == (2000, 10) and b.mass.shape == (2000,)
    assert abs(b.evals[1] / 2.0 - 1) < 0.10  # λ1 = l(l+1) = 2 on the unit sphere, multiplicity 3
    np.testing.assert_allclose(b.evals[1:4] / 2.0, 1.0, rtol=0.10)
    np.testing.assert_allclose(b.evals[4:9] / 6.0, 1.0, rtol=0.10)  # l = 2: 6, multiplicity 5
    assert abs(b.area / (4 * np.pi) - 1) < 0.02  # the lumped mass sums to the sphere's area


def test_cloud_basis_follows_the_conventions(pair):
    _, cloud, _, _, B2 = pair
    b = B2.truncate(12)
    np.testing.assert_allclose(b.vecs.T @ (b.mass[:, None] * b.vecs), np.eye(12), atol=1e-10)  # A-orthonormal
    np.testing.assert_array_equal(b.vecs[:, 0], 1 / np.sqrt(b.area))  # constant first
    assert b.evals[0] == 0 and np.all(np.diff(b.evals) > 0)
    top = np.abs(b.vecs[:, 1:]).argmax(0)
    assert np.all(b.vecs[top, np.arange(1, 12)] > 0)  # deterministic signs, as meshes
    again = pm.eigenbasis(cloud, 12, kind="robust")  # the same operator by its name
    np.testing.assert_array_equal(again.vecs, pm.eigenbasis(cloud, 12).vecs)
    with pytest.raises(pm.NeedsFacesError, match=r"laplacian\(kind='cotan'\).*kind='robust'"):
        pm.eigenbasis(cloud, 5, kind="cotan")


def test_eigenbases_of_a_mesh_and_a_cloud_are_each_eigenbasis(pair):
    mesh, cloud, _, B1, B2 = pair
    b1, b2 = pm.basis.eigenbases([mesh, cloud], 8, jobs=2)
    for b, alone in ((b1, pm.eigenbasis(mesh, 8)), (b2, pm.eigenbasis(cloud, 8))):
        np.testing.assert_array_equal(b.vecs, alone.vecs)
        np.testing.assert_array_equal(b.mass, alone.mass)
        assert b.kind == alone.kind
    assert (b1.kind, b2.kind) == ("cotan", "point_cloud")


def test_a_cloud_in_two_pieces_is_refused():
    P = fibonacci_sphere(300)
    cloud = pm.PointCloud(np.vstack([P, P + [10.0, 0, 0]]))
    with pytest.raises(pm.MeshError, match="falls apart into several pieces"):
        pm.eigenbasis(cloud, 5)


# ------------------------------------------------------------------------------ everything that needs a basis
def test_ground_truth_map_of_a_cloud_sampled_from_a_mesh(pair):
    _, _, sub, B1, B2 = pair
    C = pm.fmap_from_p2p(sub, B1.truncate(8), B2.truncate(8))  # (8, 8) mesh -> cloud
    # the cloud's eigenfunctions are the mesh's (the same surface, sampled): C is diagonal, ±1
    np.testing.assert_allclose(np.abs(np.diag(C)), 1.0, atol=0.02)
    assert np.abs(C - np.diag(np.diag(C))).max() < 0.05
    np.testing.assert_allclose(B2.evals[1:8] / B1.evals[1:8], 1.0, atol=0.05)


@pytest.mark.parametrize("direction", ["mesh_to_cloud", "cloud_to_mesh"])
def test_transfers_on_mixed_pairs_products_beat_std_on_xyz(pair, direction):
    from scipy.spatial import cKDTree

    mesh, cloud, sub, B1, B2 = pair
    b_m, b_c = B1.truncate(10), B2.truncate(10)
    if direction == "mesh_to_cloud":
        src, dst, f, truth = b_m, b_c, mesh.vertices, mesh.vertices[sub]
        C = pm.fmap_from_p2p(sub, src, dst)
    else:
        nearest = cKDTree(cloud.points).query(mesh.vertices)[1]  # each mesh vertex's nearest cloud point
        src, dst, f, truth = b_c, b_m, cloud.points, mesh.vertices  # the coordinates, sampled on the mesh
        C = pm.fmap_from_p2p(nearest, src, dst)
    err = {m: pm.relative_error(pm.transfer(f, C, src, dst, method=m), truth, dst.mass)
           for m in ("std", "default", "svd", "ridge")}
    for m, e in err.items():
        assert e.shape == (3,) and np.all(np.isfinite(e)), m
    assert np.all(err["std"] > 0.03)  # ten eigenfunctions leave the coordinates visibly smoothed ...
    for m in ("default", "svd", "ridge"):  # ... products carry much more of them (measured: 2-5x smaller)
        assert np.all(err[m] < 0.6 * err["std"]), (m, err)
    T = pm.transfer_operator(C, src, dst, method="default")
    np.testing.assert_array_equal(T(f), pm.transfer(f, C, src, dst, method="default"))


def test_products_and_extended_map_on_a_cloud(pair):
    _, _, sub, B1, B2 = pair
    b1, b2 = B1.truncate(6), B2.truncate(6)
    ext = pm.product_basis(b2, order=2, pairs="unique")
    assert ext.matrix.shape == (500, 6 + 15)
    # HKS of the cloud's own eigenpairs is a sum of φ_i²: exactly in the span of the products
    h = hks(b2, hks_times(b2, 4))
    coef = pm.approximate(h, ext, method="svd", rtol=1e-9)
    assert pm.relative_error(ext.evaluate(coef), h, b2.mass).max() < 1e-8
    # Lemma 2 on a mesh -> cloud map, any C: B2 C~ a is the product of the transferred functions
    C = pm.fmap_from_p2p(sub, b1, b2) + 0.05 * np.random.default_rng(1).normal(size=(6, 6))
    Ct = pm.extend_fmap(C, b1, b2, order=2, pairs="ordered")
    ext1, ext2 = pm.product_basis(b1, order=2, pairs="ordered"), pm.product_basis(b2, order=2, pairs="ordered")
    a = np.zeros(Ct.shape[1])
    a[6 + 1 * 5 + 2] = 1.0  # the product column (l, m) = (2, 3): φ2 φ3 on the mesh
    g1, g2 = b2.vecs @ C[:, 2], b2.vecs @ C[:, 3]  # the images of φ2 and φ3 on the cloud
    np.testing.assert_allclose(ext2.matrix @ (Ct @ a), g1 * g2, rtol=0, atol=1e-12 * np.abs(g1 * g2).max())
    assert ext1.matrix.shape[1] == Ct.shape[1]


def test_approaches_a_and_b_on_a_cloud(pair):
    _, cloud, _, _, B2 = pair
    b = B2.truncate(10)
    ext = pm.product_basis(b)
    X = cloud.points
    std = pm.relative_error(b.vecs @ b.project(X), X, b.mass)
    for method in ("svd", "ridge"):
        fit = ext.evaluate(pm.approximate(X, ext, method=method))
        assert np.all(pm.relative_error(fit, X, b.mass) < 0.5 * std), method


def test_hks_and_wks_of_a_cloud_match_the_mesh(pair):
    _, _, sub, B1, B2 = pair
    b1, b2 = B1.truncate(30), B2.truncate(30)
    times, (energies, sigma) = hks_times(b1, 5), wks_energies(b1, 50)
    for f, args in ((hks, (times,)), (wks, (energies, sigma))):
        d1, d2 = f(b1, *args), f(b2, *args)
        assert d2.shape == (500, len(args[0])) and np.all(np.isfinite(d2))
        rel = np.linalg.norm(d2 - d1[sub], axis=0) / np.linalg.norm(d1[sub], axis=0)
        assert rel.max() < 0.1, (f.__name__, rel)  # the same descriptors on the sampled points


def test_no17_zoomout_and_point_maps_on_a_mixed_pair(pair):
    mesh, _, sub, B1, B2 = pair
    b1, b2 = B1.truncate(10), B2.truncate(10)
    lm = np.column_stack([sub[:100:20], np.arange(0, 100, 20)])  # 5 landmark pairs [mesh vertex, cloud point]
    d1, d2 = no17_demo_descriptors(B1.truncate(30), B2.truncate(30), lm)
    C = fit_no17(b1, b2, d1, d2)
    assert C.shape == (10, 10)
    p_std = pm.p2p.from_fmap(C, b1, b2)
    assert np.mean(p_std == sub) > 0.9
    assert pm.geodesics.map_error(mesh, p_std, sub).mean() < 0.01
    Cz, p_zo = zoomout(C, B1, B2, 30, return_p2p=True)
    assert Cz.shape == (30, 30) and np.mean(p_zo == sub) > 0.99
    p_ext = pm.p2p.from_fmap(pm.fmap_from_p2p(sub, b1, b2), B1, B2, method="extended")
    assert p_ext.shape == (500,) and np.mean(p_ext == sub) > 0.99


# ------------------------------------------------------------------------------ geodesics and faces
def test_heat_geodesics_on_a_cloud_match_the_mesh(pair):
    mesh, cloud, sub, _, _ = pair
    d_mesh = pm.geodesics.distances(mesh, sub[:3])[:, sub]
    d_cloud = pm.geodesics.distances(cloud, [0, 1, 2])
    assert d_cloud.shape == (3, 500)
    assert np.abs(d_cloud - d_mesh).max() < 0.05 * d_mesh.max()
    rows = pm.geodesics.DistanceRows(cloud)
    np.testing.assert_array_equal(rows([1]), d_cloud[1:2])
    # a point map onto the cloud, and its geodesic error on it (area from the point-cloud mass)
    p2p_12 = np.argsort(sub)[np.arange(500)]  # not the truth: a permutation of the cloud's points
    err = pm.geodesics.map_error(cloud, p2p_12, np.arange(500))
    assert err.shape == (500,) and np.all(np.isfinite(err)) and err.max() > 0
    assert pm.geodesics.map_error(cloud, np.arange(500), np.arange(500)).max() == 0
    for method in ("graph", "exact"):
        with pytest.raises(pm.NeedsFacesError, match=f"method='{method}'.*method='heat'"):
            pm.geodesics.distances(cloud, [0], method=method)


def _needs_faces_calls(cloud):
    from prodmaps.descriptors import awft, shot
    from prodmaps.fields import cross_field, mesh_frames
    from prodmaps.fields.quadmesh import seamless_parametrization
    from prodmaps.lmh import localized_harmonics

    z = np.ones(10)
    return {
        "principal_curvatures": lambda: pm.curvature.principal_curvatures(cloud),
        "shot": lambda: shot(cloud),
        "awft": lambda: awft(cloud),
        "mesh_frames": lambda: mesh_frames(cloud),
        "mesh_frames (cross_field)": lambda: cross_field(cloud),
        "seamless_parametrization": lambda: seamless_parametrization(cloud, z, 0.1),
        "localized_harmonics": lambda: localized_harmonics(cloud, np.ones(cloud.n_points, bool), 5),
        "anisotropic_laplacian": lambda: pm.operators.anisotropic_laplacian(cloud, 0.0, 1.0),
        "edge_graph": lambda: pm.geodesics.edge_graph(cloud),
    }


def test_what_needs_faces_names_itself_and_the_way_out():
    cloud = pm.PointCloud(fibonacci_sphere(100), name="ball")
    for name, call in _needs_faces_calls(cloud).items():
        with pytest.raises(pm.NeedsFacesError) as info:
            call()
        msg = str(info.value)
        assert msg.startswith(name.split(" ")[0]) and "needs a triangle mesh (faces), got a PointCloud 'ball'" in msg
        assert "pm.load_mesh" in msg and "pm.eigenbasis" in msg  # the ways out
        assert isinstance(info.value, pm.MeshError) and isinstance(info.value, ValueError)
