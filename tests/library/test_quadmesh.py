"""Tests of prodmaps.fields.quadmesh: integer-grid parametrisation, quad extraction, hole closing."""

import numpy as np
import pytest

from prodmaps import fields as pf
from prodmaps.fields import quadmesh as qm
from prodmaps.mesh import Mesh, ellipsoid


def _cube():
    V = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], float)
    Q = np.array([[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4], [1, 5, 7, 3]])
    return V, Q


def test_quad_mesh_stats_on_a_cube_and_a_grid():
    V, Q = _cube()
    s = qm.quad_mesh_stats(V, Q)
    assert s["n_quads"] == 6 and s["n_vertices"] == 8 and s["n_boundary_edges"] == 0
    assert s["valence"] == {3: 8} and s["n_irregular"] == 8 and s["n_nonmanifold_edges"] == 0
    assert s["n_polygons"] == 0 and s["quad_fraction"] == 1.0
    # a 2 x 2 grid: one interior vertex of valence 4, 8 boundary edges
    g = np.arange(9).reshape(3, 3)
    Qg = np.array([[g[i, j], g[i, j + 1], g[i + 1, j + 1], g[i + 1, j]] for i in range(2) for j in range(2)])
    s = qm.quad_mesh_stats(np.zeros((9, 3)), Qg)
    assert s["n_boundary_edges"] == 8 and s["valence"] == {4: 1} and s["n_irregular"] == 0


def test_close_holes_gives_one_reversed_polygon_per_hole():
    V, Q = _cube()
    polys = pf.close_holes(Q[1:], 8)  # one face missing: its square comes back, same orientation
    assert len(polys) == 1 and len(polys[0]) == 4
    p = polys[0]
    k = int(np.flatnonzero(p == Q[0][0])[0])
    np.testing.assert_array_equal(np.roll(p, -k), Q[0])
    s = qm.quad_mesh_stats(V, Q[1:], polys)
    assert s["n_boundary_edges"] == 0 and s["n_quads"] == 5 and s["n_polygons"] == 1
    assert [len(p) for p in pf.close_holes(Q[2:], 8)] == [4, 4]  # two opposite faces: two holes
    rest = Q[[1, 3, 4, 5]]  # faces 0 and 2 share the edge 0-1: one hexagon
    polys = pf.close_holes(rest, 8)
    assert [len(p) for p in polys] == [6]
    assert qm.quad_mesh_stats(V, rest, polys)["n_boundary_edges"] == 0
    assert pf.close_holes(Q, 8) == []
    with pytest.raises(ValueError, match="number of vertices"):
        pf.close_holes(Q, 7)
    with pytest.raises(ValueError, match=r"\(q, 4\)"):
        pf.close_holes(Q[:, :3], 8)


@pytest.fixture(scope="module")
def ellipsoid_param():
    m = ellipsoid(4)  # 2562 vertices
    fr = pf.mesh_frames(m)
    z = pf.aligned_field(fr, pf.curvature_guide(m, fr)[0], 4, scale=0.2)
    return m, z, qm.seamless_parametrization(m, z, 0.1)


def test_seamless_parametrization_is_integer_and_follows_the_field(ellipsoid_param):
    m, z, p = ellipsoid_param
    assert p["singular"].size == 8  # eight +1/4 singularities on a genus-0 curvature-aligned field
    assert p["n_seam_edges"] > 0 and p["n_chains"] > 0 and p["n_flipped"] == 0
    # hard constraints: exact transitions, integer translations
    assert p["transition_error"] < 1e-9 and p["integer_error"] < 1e-9
    np.testing.assert_array_equal(p["trans"], np.round(p["trans"]))
    # across every seam edge, both ends obey the same transition p_g = R^rot p_f + t
    import igl

    TT, TTi = igl.triangle_triangle_adjacency(p["F"])
    f, e = np.nonzero(p["rot"] != 0)
    g, eg = TT[f, e], TTi[f, e]
    quarter = np.array([[0.0, -1.0], [1.0, 0.0]])  # the rotation by 90° counter-clockwise
    R = np.stack([np.linalg.matrix_power(quarter, r) for r in p["rot"][f, e] % 4])  # (s, 2, 2) R^rot
    for end_f, end_g in ((e, (eg + 1) % 3), ((e + 1) % 3, eg)):
        pf_ = p["uv"][p["Fc"][f, end_f]]
        pg_ = p["uv"][p["Fc"][g, end_g]]
        np.testing.assert_allclose(np.einsum("sij,sj->si", R, pf_) + p["trans"][f, e], pg_, atol=1e-9)
    # singular vertices at integer points (all but at most the root of the rounding)
    sc = np.isin(p["I"], p["singular"])
    off = np.abs(p["uv"][sc] - np.round(p["uv"][sc])).max(axis=1)
    assert np.sum(off > 1e-9) <= 1
    # gradients of u are (nearly) along the first combed direction, at 1/h
    G = igl.grad(p["Vc"], p["Fc"]).tocsr()
    mF = p["Fc"].shape[0]
    gu = np.stack([G[c * mF:(c + 1) * mF] @ p["uv"][:, 0] for c in range(3)], axis=1)
    assert np.median(np.linalg.norm(gu, axis=1)) * p["h"] == pytest.approx(1.0, abs=0.1)
    # the continuous solve is seamless (soft constraints) but not integer
    q = qm.seamless_parametrization(m, z, 0.1, integer=False)
    assert q["transition_error"] < 1e-4 and q["integer_error"] > 0.1
    with pytest.raises(ValueError, match="h"):
        qm.seamless_parametrization(m, z, 0.0)
    with pytest.raises(ValueError, match="one value per face"):
        qm.seamless_parametrization(m, z[:-1], 0.1)


def test_extract_quads_on_an_ellipsoid_is_a_closed_pure_quad_mesh(ellipsoid_param):
    m, _, p = ellipsoid_param
    L = qm.extract_quads(p)
    s = qm.quad_mesh_stats(L["V"], L["Q"], L["polygons"])
    expected = m.area / p["h"] ** 2
    assert 0.85 * expected < s["n_quads"] < 1.15 * expected
    assert s["n_polygons"] == 0 and s["n_boundary_edges"] == 0 and s["n_nonmanifold_edges"] == 0
    assert s["valence"][3] == 8 and set(s["valence"]) == {3, 4}  # the 8 singularities, nothing else
    E = s["n_quads"] * 4 // 2
    assert s["n_vertices"] - E + s["n_quads"] == 2  # a sphere
    # the integer points lie on the surface, at their recorded barycentric location
    X = np.einsum("pk,pkd->pd", L["bary"], m.vertices[m.faces[L["location"]]])
    np.testing.assert_allclose(X, L["V"], atol=1e-12)
    # quads are counter-clockwise seen from outside (the ellipsoid is centred at the origin)
    C = L["V"][L["Q"]]
    nrm = np.cross(C[:, 2] - C[:, 0], C[:, 3] - C[:, 1])
    assert np.all(np.einsum("qd,qd->q", nrm, C.mean(axis=1)) > 0)
    # the irregular vertices sit at the field's singularities
    d = np.linalg.norm(L["V"][s["irregular"]][:, None] - m.vertices[p["singular"]][None], axis=2).min(axis=1)
    assert d.max() < 1e-9


def test_quad_meshes_are_free_of_the_units(ellipsoid_param):
    m, z, p = ellipsoid_param
    ref = qm.quad_mesh_stats(**{k: v for k, v in zip(("V", "Q", "polygons"), _vqp(qm.extract_quads(p)))})
    for s in (0.01, 100.0):
        ms = Mesh(m.vertices * s, m.faces)
        q = qm.seamless_parametrization(ms, z, 0.1 * s)
        np.testing.assert_allclose(q["uv"], p["uv"], atol=1e-8)
        st = qm.quad_mesh_stats(*_vqp(qm.extract_quads(q)))
        assert (st["n_quads"], st["n_polygons"], st["valence"]) == (ref["n_quads"], ref["n_polygons"], ref["valence"])


def _vqp(L):
    return L["V"], L["Q"], L["polygons"]


def test_quads_on_a_human_with_many_singularities_are_watertight():
    from prodmaps import datasets

    m = datasets.load_shape("anny_humans", "anny_000")
    z = pf.cross_field(m)  # ~230 singularities, many closer together than a quad
    h = 0.03 * np.sqrt(m.area)
    p = qm.seamless_parametrization(m, z, h, batches=4)
    assert p["singular"].size > 150
    assert p["transition_error"] < 1e-9 and p["integer_error"] < 1e-9
    L = qm.extract_quads(p)
    s = qm.quad_mesh_stats(*_vqp(L))
    assert s["n_boundary_edges"] == 0 and s["n_nonmanifold_edges"] == 0  # watertight, manifold edges
    assert s["quad_fraction"] > 0.95 and s["n_quads"] > 0.6 * m.area / h ** 2
    # the other polygons close holes next to the field's singularities (clusters at face, hands, feet)
    from scipy.spatial import cKDTree

    d, _ = cKDTree(m.vertices[p["singular"]]).query(L["V"])
    near = [d[poly].min() <= 2 * h for poly in L["polygons"]]
    assert np.mean(near) >= 0.9
