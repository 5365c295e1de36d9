"""Mesh validation, I/O and repairs; every broken mesh in tests/data/broken must be named."""

from pathlib import Path

import numpy as np
import pytest

import prodmaps as pm
from prodmaps import mesh as pmesh

BROKEN = Path(__file__).resolve().parents[1] / "data" / "broken"


@pytest.mark.parametrize(
    "name, message",
    [
        ("empty.off", "empty mesh"),
        ("nonfinite.off", "non-finite coordinates"),
        ("index_out_of_range.off", "out of range"),
        ("negative_index.off", "negative face indices"),
        ("quad.off", "non-triangular"),
        ("degenerate.off", "degenerate"),
        ("duplicate.off", "duplicate faces"),
        ("unreferenced.off", "unreferenced vertices"),
        ("nonmanifold_edge.off", "non-manifold edges"),
        ("two_components.off", "several connected components"),
        ("truncated.ply", "truncated"),
        ("truncated.off", "truncated"),
        ("not_a_mesh.ply", "not a PLY file"),
    ],
)
def test_broken_corpus_errors_name_the_problem(name, message):
    with pytest.raises(pm.MeshError, match=message) as info:
        pm.load_mesh(BROKEN / name, triangulate=False)  # quad.off: load_mesh triangulates by default
    assert name in str(info.value)  # the file is named too


def test_missing_and_unsupported_files(tmp_path):
    with pytest.raises(pm.MeshError, match="no such file"):
        pm.load_mesh(tmp_path / "nope.ply")
    p = tmp_path / "mesh.stl"
    p.write_text("solid")
    with pytest.raises(pm.MeshError, match="unsupported format"):
        pm.load_mesh(p)


def test_valid_files_load():
    m = pm.load_mesh(BROKEN / "tetra_ok.off")
    assert (m.n_vertices, m.n_faces) == (4, 4) and m.is_closed
    obj = pm.load_mesh(BROKEN / "tetra_vt.obj")
    np.testing.assert_array_equal(obj.faces, m.faces)
    opened = pm.load_mesh(BROKEN / "open_boundary.off")  # open boundaries are allowed
    assert not opened.is_closed and opened.boundary_edges.shape == (3, 2)


def test_human_ply_counts_and_area(human_0):
    assert (human_0.n_vertices, human_0.n_faces) == (5002, 10000)
    assert human_0.is_closed
    assert 1.0 < human_0.area < 2.5  # an adult body surface in m²


@pytest.mark.parametrize("suffix", [".ply", ".off"])
def test_save_load_roundtrip(tmp_path, human_0, suffix):
    path = pm.save_mesh(tmp_path / f"h{suffix}", human_0)
    back = pm.load_mesh(path)
    np.testing.assert_allclose(back.vertices, human_0.vertices, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(back.faces, human_0.faces)
    assert not list(tmp_path.glob("*.tmp"))


def test_repairs_fix_the_common_cases():
    for name in ("duplicate.off", "unreferenced.off", "two_components.off", "degenerate.off"):
        v, f = pm.io.read_mesh_arrays(BROKEN / name)
        if name == "degenerate.off":  # removing the zero-area face also removes the non-manifold edge
            pass
        mesh, kept = pmesh.repair(v, f)
        assert mesh.n_faces == 4, name
        np.testing.assert_array_equal(mesh.vertices, v[kept])


@pytest.mark.parametrize("name, message", [("index_out_of_range.off", "out of range"),
                                           ("negative_index.off", "negative face indices")])
def test_repair_names_bad_face_indices(name, message):
    """Indices outside [0, n) cannot be repaired: a MeshError naming them, not numpy's IndexError."""
    v, f = pm.io.read_mesh_arrays(BROKEN / name)
    with pytest.raises(pm.MeshError, match=message):
        pmesh.repair(v, f)
    with pytest.raises(pm.MeshError, match="cannot be repaired automatically: .*" + message):
        pm.io.load_mesh_repaired(BROKEN / name, verbose=False)


def test_largest_component_keeps_bigger_area():
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1.0]])
    f = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    v2, f2 = np.vstack([v, 3 * v + 10]), np.vstack([f, f + 4])
    out_v, out_f, kept = pmesh.largest_component(v2, f2)
    np.testing.assert_array_equal(kept, [4, 5, 6, 7])
    np.testing.assert_allclose(out_v, 3 * v + 10)


def test_mesh_arrays_are_read_only(human_0):
    with pytest.raises(ValueError):
        human_0.vertices[0, 0] = 1.0


def test_mesh_leaves_the_callers_arrays_writeable():
    """The Mesh freezes its own copy, not the caller's array (``V -= V.mean(0)`` after ``pm.Mesh(V, F)``)."""
    s = pmesh.ellipsoid(1)
    V, F = np.array(s.vertices), np.array(s.faces)
    mesh = pm.Mesh(V, F)
    assert V.flags.writeable and F.flags.writeable
    V -= 1.0  # the caller's array is theirs to change ...
    np.testing.assert_array_equal(mesh.vertices, s.vertices)  # ... and the mesh does not change with it


def test_vertices_shape_error():
    with pytest.raises(pm.MeshError, match=r"shape \(n, 3\)"):
        pm.Mesh(np.zeros((4, 2)), np.array([[0, 1, 2]]))


def _relative_gaps(mesh, k):
    """Relative gaps ``(λ_{i+1} - λ_i) / λ_{i+1}`` of the first ``k`` non-zero eigenvalues (dense LAPACK)."""
    import scipy.linalg as sla

    W, A = pm.laplacian(mesh)
    w = sla.eigh(W.toarray(), np.diag(A), eigvals_only=True, subset_by_index=[0, k])
    return np.diff(w[1:]) / w[2:]


@pytest.mark.parametrize("subdivisions, n", [(1, 42), (2, 162), (3, 642)])
def test_ellipsoid_is_a_scaled_icosphere_with_a_simple_spectrum(subdivisions, n):
    m = pmesh.ellipsoid(subdivisions)
    s = pmesh.icosphere(subdivisions)
    assert m.n_vertices == n and m.is_closed and m.name == "ellipsoid"
    np.testing.assert_array_equal(m.faces, s.faces)  # same triangulation and vertex order
    a, b, c = 1.0, 0.6, 0.4  # the documented default axes
    np.testing.assert_array_equal(m.vertices, s.vertices * [a, b, c])
    np.testing.assert_allclose(((m.vertices / [a, b, c]) ** 2).sum(1), 1.0, rtol=1e-12)
    # simple spectrum (what the tests that compare individual eigenvectors rely on): the first 26
    # eigenvalues are clearly apart; the round icosphere has exact multiplicities (3, 5, ...)
    assert _relative_gaps(m, 25).min() > 1e-3
    assert _relative_gaps(s, 25).min() < 1e-9
    np.testing.assert_array_equal(pmesh.ellipsoid(2, axes=(2.0, 1.0, 0.5)).vertices,
                                  pmesh.icosphere(2).vertices * [2.0, 1.0, 0.5])


@pytest.mark.parametrize("axes", [(1.0, 0.5), (1.0, 0.0, 0.5), (1.0, -1.0, 0.5), (1.0, np.nan, 0.5)])
def test_ellipsoid_rejects_bad_axes(axes):
    with pytest.raises(ValueError, match="axes"):
        pmesh.ellipsoid(2, axes=axes)


def test_repair_advice_names_functions_that_exist_and_do_the_whole_fix():
    """Every fix an error names resolves to a real function; degenerate or duplicate faces lead to
    ``mesh.repair``, which also drops the vertices they leave unreferenced (issue 35)."""
    import re

    import prodmaps.io
    import prodmaps.mesh
    from prodmaps.mesh import icosphere

    s = icosphere(1)
    v_extra = np.vstack([s.vertices, [[5.0, 5.0, 5.0]]])
    repeat = s.faces.copy()
    repeat[0, 1] = repeat[0, 0]
    flat = np.vstack([s.vertices, s.vertices[:1]])  # a zero-area face on a duplicated point
    cases = [(s.vertices, repeat), (s.vertices, np.vstack([s.faces, s.faces[:1]])),
             (flat, np.vstack([s.faces, [[0, 1, s.n_vertices]]])), (v_extra, s.faces)]
    for v, f in cases:
        with pytest.raises(pm.MeshError) as e:
            pm.Mesh(v, f)
        msg = str(e.value)
        for name in re.findall(r"\b(?:pm|prodmaps)\.[\w.]+(?=\()", msg):
            obj = {"pm": pm, "prodmaps": pm}[name.split(".")[0]]
            for part in name.split(".")[1:]:
                obj = getattr(obj, part)  # raises AttributeError for a name that does not exist
            assert callable(obj), name
        assert "pm.load_mesh_repaired" not in msg
        if "unreferenced" not in msg:
            assert "prodmaps.mesh.repair(vertices, faces)" in msg, msg
            fixed, kept = prodmaps.mesh.repair(v, f)  # the advice works on its own: a valid mesh
            assert fixed.n_vertices == kept.size
    assert prodmaps.io.load_mesh_repaired is pm.io.load_mesh_repaired


def test_mean_edge_length_counts_each_edge_once_and_scales_with_the_mesh():
    V = np.array([[0.0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]])
    F = np.array([[0, 1, 2], [0, 2, 3]])  # a unit square: 4 sides and 1 shared diagonal
    assert pmesh.mean_edge_length(V, F) == pytest.approx((4 + np.sqrt(2)) / 5, rel=1e-15)
    assert pmesh.mean_edge_length(2.5 * V, F) == pytest.approx(2.5 * (4 + np.sqrt(2)) / 5, rel=1e-15)


def test_the_two_triangle_qualities_agree_at_the_ends_and_differ_between():
    V = np.array([[0.0, 0, 0], [1, 0, 0], [0.5, np.sqrt(3) / 2, 0], [2, 0, 0], [0, 1, 0]])
    F = np.array([[0, 1, 2], [0, 3, 1], [0, 1, 4]])  # equilateral, degenerate, right isosceles
    for quality, right_isosceles in ((pmesh.face_mean_ratio, np.sqrt(3) / 2),  # 4√3 (1/2) / (1 + 1 + 2)
                                     (pmesh.face_radius_ratio, 2 * (np.sqrt(2) - 1))):  # 2r/R, R = √2/2
        q = quality(V, F)
        np.testing.assert_allclose(q, [1.0, 0.0, right_isosceles], rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(quality(7.0 * V, F), q, rtol=1e-12, atol=1e-12)  # free of units
