"""Defective meshes: seams, triangle soups, quads, duplicate faces with non-manifold edges, bowties, orientation.

Each defect is a small synthetic mesh built here (the real files that showed them, pyFM's
``camel-gallop-01.off`` and FAUST_r shapes, are not redistributable test data): what
``pm.load_mesh`` says, what the repair does (counts), and the spectrum after (the unit sphere's
first eigenvalue is 2).
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import prodmaps as pm
from prodmaps import mesh as pmesh


def uv_sphere_with_seam(nu: int = 48, nv: int = 24):
    """A unit UV sphere whose seam is duplicated: the last meridian repeats the first, vertex for vertex."""
    th = np.linspace(0, np.pi, nv + 1)[1:-1]
    ph = np.linspace(0, 2 * np.pi, nu + 1)  # ph[-1] = 2π: the seam's copy
    T, P = np.meshgrid(th, ph, indexing="ij")
    ring = np.stack([np.sin(T) * np.cos(P), np.sin(T) * np.sin(P), np.cos(T)], -1).reshape(-1, 3)
    V = np.vstack([[0.0, 0, 1], ring, [0.0, 0, -1]])
    idx = 1 + np.arange((nv - 1) * (nu + 1)).reshape(nv - 1, nu + 1)
    a, b, c, d = idx[:-1, :-1], idx[:-1, 1:], idx[1:, 1:], idx[1:, :-1]
    band = np.concatenate([np.stack([a, d, c], -1).reshape(-1, 3), np.stack([a, c, b], -1).reshape(-1, 3)])
    top = np.stack([np.zeros(nu, int), idx[0, :-1], idx[0, 1:]], -1)
    bottom = np.stack([np.full(nu, len(V) - 1), idx[-1, 1:], idx[-1, :-1]], -1)
    return V, np.concatenate([top, band, bottom])


def soup(mesh):
    """The mesh as a triangle soup (STL-style): every face with its own three vertices."""
    return mesh.vertices[mesh.faces.ravel()], np.arange(3 * mesh.n_faces).reshape(-1, 3)


def torus_quads(nu: int = 24, nv: int = 12, R: float = 1.0, r: float = 0.35):
    """A closed quad mesh of a torus: ``(vertices (nu·nv, 3), quads (nu·nv, 4))``."""
    u, v = np.meshgrid(np.arange(nu) * 2 * np.pi / nu, np.arange(nv) * 2 * np.pi / nv, indexing="ij")
    V = np.stack([(R + r * np.cos(v)) * np.cos(u), (R + r * np.cos(v)) * np.sin(u), r * np.sin(v)], -1).reshape(-1, 3)
    i, j = np.meshgrid(np.arange(nu), np.arange(nv), indexing="ij")
    at = lambda a, b: (a % nu) * nv + (b % nv)  # noqa: E731
    Q = np.stack([at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)], -1).reshape(-1, 4)
    return V, Q


def write_off(path, V, F):
    rows = "".join(f"{len(f)} " + " ".join(map(str, f)) + "\n" for f in np.asarray(F).tolist())
    path.write_text(f"OFF\n{len(V)} {len(F)} 0\n" + "\n".join(" ".join(map(repr, v)) for v in V.tolist()) + "\n" + rows)
    return path


def caught(fn, *args, **kw):
    """``(result, [MeshWarning messages])`` of a call."""
    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        out = fn(*args, **kw)
    return out, [str(w.message) for w in rec if issubclass(w.category, pm.MeshWarning)]


# ------------------------------------------------------------------------------ seams and soups
def test_a_duplicated_seam_warns_and_the_repair_restores_the_sphere(tmp_path):
    V, F = uv_sphere_with_seam()
    assert pmesh.misoriented_edges(F) == 0
    path = write_off(tmp_path / "uv.off", V, F)
    mesh, msgs = caught(pm.load_mesh, path)
    assert not mesh.is_closed  # the seam is a boundary: the surface is cut there
    assert len(msgs) == 1 and msgs[0].startswith(f"{path}: 23 boundary vertices coincide with another one")
    assert "prodmaps.mesh.merge_vertices(vertices, faces)" in msgs[0] and "load_mesh_repaired" in msgs[0]
    cut = pm.eigenbasis(mesh, 4).evals[1]
    assert cut < 0.9  # the cut sphere's spectrum (measured 0.77): silently wrong before this warning
    fixed, kept, report = pm.io.load_mesh_repaired(path, verbose=False, return_report=True)
    assert fixed.is_closed and fixed.n_vertices == len(V) - 23 and report.vertices_merged == 23
    assert (report.degenerate_faces, report.duplicate_faces, report.faces_reoriented) == (0, 0, 0)
    np.testing.assert_array_equal(fixed.vertices, V[kept])
    np.testing.assert_allclose(fixed.vertices[report.vertex_map], V, atol=1e-12)  # every file vertex, merged too
    lam = pm.eigenbasis(fixed, 5).evals
    assert abs(lam[1] / 2.0 - 1) < 0.05
    np.testing.assert_allclose(lam[1:4] / 2.0, 1.0, rtol=0.05)


def test_a_triangle_soup_is_repaired_into_the_closed_surface(tmp_path):
    sphere = pm.mesh.icosphere(3)
    Vs, Fs = soup(sphere)
    with pytest.raises(pm.MeshError, match=r"several connected components: 1280 .*3198 vertices coincide .* "
                                           r"prodmaps\.mesh\.repair\(vertices, faces\) merges them"):
        pm.Mesh(Vs, Fs)
    mesh, kept, report = pmesh.repair(Vs, Fs, return_report=True)
    # the root cause of "4560 -> 3 vertices": the largest component was taken before any merge
    assert (mesh.n_vertices, mesh.n_faces) == (642, 1280) and mesh.is_closed
    assert report.vertices_merged == 3840 - 642 and report.components_dropped == 0
    assert str(report) == "3840 -> 642 vertices, 1280 -> 1280 faces; 3198 coincident vertices merged"
    np.testing.assert_array_equal(np.sort(mesh.faces, axis=1)[np.lexsort(np.sort(mesh.faces, 1).T[::-1])].shape,
                                  sphere.faces.shape)
    lam = pm.eigenbasis(mesh, 5).evals
    assert abs(lam[1] / 2.0 - 1) < 0.05
    path = write_off(tmp_path / "soup.off", Vs, Fs)
    again, kept2 = pm.io.load_mesh_repaired(path, verbose=False)
    np.testing.assert_array_equal(again.vertices, mesh.vertices)
    np.testing.assert_array_equal(kept2, kept)


def test_the_merge_tolerance_is_relative_to_the_mesh_size():
    base = pm.mesh.ellipsoid(2)
    for scale in (1e-3, 1.0, 1e4):
        Vs, Fs = soup(base)
        v, f, kept = pmesh.merge_vertices(scale * Vs, Fs)
        assert v.shape[0] == 162, scale  # the same merge in millimetres and in kilometres
    V = np.vstack([base.vertices, base.vertices[:1] + [1e-5 * 2.0, 0, 0]])  # 1e-5 of the diagonal (2.0) away
    F = np.where(base.faces == 0, 162, base.faces)
    F[0] = base.faces[0]  # vertex 0 keeps one face: the surface is cut at it
    assert pmesh.coincident_vertices(V)[162] == 162  # not within the default 1e-7
    assert pmesh.coincident_vertices(V, tol=1e-4)[162] == 0
    mesh, kept = pmesh.repair(V, F, coincident_tol=1e-4)
    assert mesh.n_vertices == 162 and mesh.is_closed


def test_a_valid_mesh_is_returned_unchanged_by_the_repair(human_0):
    mesh, kept, report = pmesh.repair(human_0.vertices, human_0.faces, return_report=True)
    np.testing.assert_array_equal(mesh.vertices, human_0.vertices)
    np.testing.assert_array_equal(mesh.faces, human_0.faces)
    np.testing.assert_array_equal(kept, np.arange(human_0.n_vertices))
    assert str(report) == "5002 -> 5002 vertices, 10000 -> 10000 faces"
    np.testing.assert_array_equal(report.vertex_map, np.arange(human_0.n_vertices))


# ------------------------------------------------------------------------------ polygons
def test_a_quad_mesh_gives_twice_its_faces_in_triangles(tmp_path):
    V, Q = torus_quads()
    path = write_off(tmp_path / "torus.off", V, Q)
    mesh, msgs = caught(pm.load_mesh, path)
    assert mesh.n_faces == 2 * len(Q) and mesh.n_vertices == len(V) and mesh.is_closed
    assert len(msgs) == 1 and f"{len(Q)} polygon faces (quads or larger) triangulated into {2 * len(Q)}" in msgs[0]
    assert pmesh.misoriented_edges(mesh.faces) == 0  # fans keep the quads' orientation
    np.testing.assert_allclose(mesh.area, 4 * np.pi**2 * 1.0 * 0.35, rtol=0.02)  # the torus' area 4π²Rr
    with pytest.raises(pm.MeshError, match="non-triangular faces: faces have 4 corners"):
        pm.load_mesh(path, triangulate=False)
    tri, src = pmesh.triangulate_polygons(Q)
    np.testing.assert_array_equal(src, np.repeat(np.arange(len(Q)), 2))
    fixed, _, report = pmesh.repair(V, Q, return_report=True)
    assert report.polygons_triangulated == len(Q) and fixed.n_faces == 2 * len(Q)


# ------------------------------------------------------------------------------ duplicate faces, non-manifold edges
def finned_ellipsoid():
    """An ellipsoid with a duplicated face (reversed, as pyFM's camel has it) and a small fin on one edge.

    The fin is one triangle on edge (a, b): that edge is then shared by three faces (non-manifold).
    """
    e = pm.mesh.ellipsoid(2)
    a, b, c = e.faces[10]
    tip = 0.5 * (e.vertices[a] + e.vertices[b]) * 1.05  # just outside the surface
    V = np.vstack([e.vertices, tip])
    F = np.vstack([e.faces, e.faces[5][::-1], [[a, b, e.n_vertices]]])
    return e, V, F


def test_duplicate_faces_and_non_manifold_edges_name_the_ways_out_and_get_a_robust_basis(tmp_path):
    clean, V, F = finned_ellipsoid()
    path = pm.save_mesh(tmp_path / "finned.ply", V, F)
    with pytest.raises(pm.MeshError, match="duplicate faces: 1 faces") as info:
        pm.load_mesh(path)
    for way in ("prodmaps.mesh.repair(vertices, faces)", "pm.load_mesh(path, validate=False)",
                "pm.eigenbasis(mesh, k, kind='robust')"):
        assert way in str(info.value)
    with pytest.raises(pm.MeshError, match=r"cannot be repaired automatically: non-manifold edges: 1 edges") as info:
        pm.io.load_mesh_repaired(path, verbose=False)
    assert "validate=False" in str(info.value) and "kind='robust'" in str(info.value)
    raw = pm.load_mesh(path, validate=False)  # the way out, followed
    b = pm.eigenbasis(raw, 10, kind="robust")
    assert b.kind == "robust" and b.vecs.shape == (163, 10)
    np.testing.assert_allclose(b.vecs.T @ (b.mass[:, None] * b.vecs), np.eye(10), atol=1e-10)
    assert b.evals[0] == 0 and np.all(np.diff(b.evals) > 0)
    ref = pm.eigenbasis(clean, 10, kind="robust").evals
    np.testing.assert_allclose(b.evals[1:] / ref[1:], 1.0, rtol=0.05)  # a small fin barely moves the spectrum


def test_the_robust_basis_refuses_vertices_without_area():
    e = pm.mesh.ellipsoid(1)
    raw = pm.Mesh(np.vstack([e.vertices, [[5.0, 5, 5]]]), e.faces, validate=False)
    with pytest.raises(pm.MeshError, match="1 vertices have no area.*remove_unreferenced_vertices"):
        pm.eigenbasis(raw, 5, kind="robust")


# ------------------------------------------------------------------------------ bowties and orientation
def bowtie():
    """A big and a small ellipsoid touching at one vertex (vertex 0 of both): one bowtie vertex."""
    big, small = pm.mesh.ellipsoid(1), pm.mesh.ellipsoid(1)
    Vs = 0.5 * small.vertices
    Vs = Vs - Vs[0] + big.vertices[0]  # the small one's vertex 0 on the big one's vertex 0 ...
    Vs[0] = big.vertices[0]
    V = np.vstack([big.vertices, Vs[1:]])
    Fs = np.where(small.faces == 0, 0, small.faces + big.n_vertices - 1)  # ... shared: a bowtie
    return big, V, np.vstack([big.faces, Fs])


def test_a_bowtie_vertex_warns_and_the_repair_splits_it():
    big, V, F = bowtie()
    np.testing.assert_array_equal(pmesh.bowtie_vertices(F), [0])
    mesh, msgs = caught(pm.Mesh, V, F)
    assert len(msgs) == 1 and msgs[0].startswith("1 bowtie vertices (first [0])")
    assert "prodmaps.mesh.split_bowtie_vertices(vertices, faces)" in msgs[0]
    assert pm.eigenbasis(mesh, 3).evals[1] < 0.5 * pm.eigenbasis(big, 3).evals[1]  # two shapes joined at a point
    fixed, kept, report = pmesh.repair(V, F, return_report=True)
    assert report.bowtie_copies == 1 and report.components_dropped == 1
    np.testing.assert_array_equal(fixed.vertices, big.vertices)  # the big one is kept, vertices in order
    np.testing.assert_array_equal(fixed.faces, big.faces)
    v, f, k = pmesh.split_bowtie_vertices(V, F)
    assert v.shape[0] == V.shape[0] + 1 and k[-1] == 0 and pmesh.bowtie_vertices(f).size == 0


def test_inconsistent_orientation_warns_spares_the_laplacian_and_is_fixed():
    e = pm.mesh.ellipsoid(2)
    F = e.faces.copy()
    F[:7] = F[:7, ::-1]
    mesh, msgs = caught(pm.Mesh, e.vertices, F)
    assert len(msgs) == 1 and msgs[0].startswith("inconsistently oriented faces: ")
    assert "The Laplacian and everything spectral are unaffected" in msgs[0] and "orient_faces" in msgs[0]
    np.testing.assert_allclose(pm.eigenbasis(mesh, 8).evals, pm.eigenbasis(e, 8).evals, rtol=1e-12)
    assert np.abs(mesh.vertex_normals() - e.vertex_normals()).max() > 0.1  # normals are not spared
    _, fixed, _ = pmesh.orient_faces(e.vertices, F)
    np.testing.assert_array_equal(fixed, e.faces)  # the majority's orientation, face for face
    _, all_flipped, _ = pmesh.orient_faces(e.vertices, e.faces[:, ::-1])
    np.testing.assert_array_equal(all_flipped, e.faces[:, ::-1])  # consistent already: unchanged
    repaired, _, report = pmesh.repair(e.vertices, F, return_report=True)
    assert report.faces_reoriented == 7 and pmesh.misoriented_edges(repaired.faces) == 0


def test_a_clean_mesh_loads_without_a_word(human_0, tmp_path):
    path = pm.save_mesh(tmp_path / "h.ply", human_0)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # any warning fails
        pm.load_mesh(path)
        mesh, kept = pm.io.load_mesh_repaired(path, verbose=False)
    np.testing.assert_array_equal(kept, np.arange(human_0.n_vertices))


# ------------------------------------------------------------------------------ bad arrays
@pytest.mark.parametrize("vertices, faces, message", [
    (np.eye(3), [["0", "1", "2"]], r"face indices must be integers; got text \(e\.g\. '0'\).*np\.asarray"),
    (np.eye(3), np.array([[0, 1, 2]], dtype=object), "face indices must be integers; got dtype object"),
    (np.eye(4, 3), [[0, 1, 2], [0, 2, 3, 1]], r"rows of different lengths .*triangulate_polygons"),
    ([["0", "0", "x"]] * 3, [[0, 1, 2]], "vertex coordinates must be numbers; got text"),
])
def test_faces_or_vertices_of_the_wrong_kind_raise_a_mesh_error(vertices, faces, message):
    with pytest.raises(pm.MeshError, match=message):
        pm.Mesh(vertices, faces)
    with pytest.raises(pm.MeshError, match=message):
        pmesh.repair(vertices, faces)


def test_coincident_vertices_inside_a_closed_surface_are_left_alone():
    """Two sheets touching at one point (as the remeshed FAUST_r shapes have, 1 to 4 pairs per shape): no cut,
    so no warning, and the repair keeps both copies (merging would only make a bowtie)."""
    e = pm.mesh.ellipsoid(2)
    V = e.vertices.copy()
    target = int(np.argmax(np.linalg.norm(e.vertices - V[0], axis=1)))  # the far side
    V[0] = e.vertices[target]  # vertex 0 pulled onto a vertex of the far side: two sheets touch there
    assert pmesh.coincident_vertices(V)[target] == 0  # they do coincide ...
    mesh, msgs = caught(pm.Mesh, V, e.faces)
    assert mesh.is_closed and msgs == []  # ... but the surface is not cut: no warning
    fixed, kept, report = pmesh.repair(V, e.faces, return_report=True)
    assert report.vertices_merged == 0 and fixed.n_vertices == 162
    np.testing.assert_array_equal(kept, np.arange(162))
    v, f, k = pmesh.merge_vertices(V, e.faces, boundary_only=False)  # asked for: merged (a bowtie)
    assert v.shape[0] == 161 and pmesh.bowtie_vertices(f).size == 1
