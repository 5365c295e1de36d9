"""Tests of prodmaps.fields.quadmesh: seamless parametrisation and the (partial) lattice quads."""

import numpy as np
import pytest

from prodmaps import fields as pf
from prodmaps.fields import quadmesh as qm
from prodmaps.mesh import ellipsoid


def test_quad_mesh_stats_on_a_cube_and_a_grid():
    V = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], float)
    Q = np.array([[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4], [1, 5, 7, 3]])
    s = qm.quad_mesh_stats(V, Q)
    assert s["n_quads"] == 6 and s["n_vertices"] == 8 and s["n_boundary_edges"] == 0
    assert s["valence"] == {3: 8} and s["n_irregular"] == 8 and s["n_nonmanifold_edges"] == 0
    # a 2 x 2 grid: one interior vertex of valence 4, 8 boundary edges
    g = np.arange(9).reshape(3, 3)
    Qg = np.array([[g[i, j], g[i, j + 1], g[i + 1, j + 1], g[i + 1, j]] for i in range(2) for j in range(2)])
    s = qm.quad_mesh_stats(np.zeros((9, 3)), Qg)
    assert s["n_boundary_edges"] == 8 and s["valence"] == {4: 1} and s["n_irregular"] == 0


@pytest.fixture(scope="module")
def ellipsoid_param():
    m = ellipsoid(4)  # 2562 vertices
    fr = pf.mesh_frames(m)
    z = pf.aligned_field(fr, pf.curvature_guide(m, fr)[0], 4, scale=0.2)
    return m, z, qm.seamless_parametrization(m, z, 0.1)


def test_seamless_parametrization_is_integer_and_follows_the_field(ellipsoid_param):
    m, z, p = ellipsoid_param
    assert p["singular"].size == 8  # eight +1/4 singularities on a genus-0 curvature-aligned field
    assert p["n_seam_edges"] > 0 and p["n_flipped"] == 0
    assert p["transition_error"] < 1e-4 and p["integer_error"] < 1e-4
    np.testing.assert_allclose(p["transitions_t"], np.round(p["transitions_t"]))
    # gradients of u are (nearly) along the first combed direction, at 1/h
    import igl

    G = igl.grad(p["Vc"], p["Fc"]).tocsr()
    mF = p["Fc"].shape[0]
    gu = np.stack([G[c * mF:(c + 1) * mF] @ p["uv"][:, 0] for c in range(3)], axis=1)
    assert np.median(np.linalg.norm(gu, axis=1)) * p["h"] == pytest.approx(1.0, abs=0.1)
    # the continuous solve is seamless but not integer
    q = qm.seamless_parametrization(m, z, 0.1, integer=False)
    assert q["transition_error"] < 1e-4 and q["integer_error"] > 0.1
    with pytest.raises(ValueError, match="h"):
        qm.seamless_parametrization(m, z, 0.0)


def test_lattice_quads_on_an_ellipsoid(ellipsoid_param):
    m, _, p = ellipsoid_param
    L = qm.lattice_quads(p)
    s = qm.quad_mesh_stats(L["V"], L["Q"])
    expected = m.area / p["h"] ** 2
    assert 0.75 * expected < s["n_quads"] < 1.25 * expected
    assert s["valence"].get(4, 0) > 0.9 * sum(s["valence"].values())
    assert s["n_irregular"] <= 8  # only near the singularities
    # partial extraction: holes remain where a cell meets two seams, far fewer edges than the quads'
    assert s["n_boundary_edges"] < 0.3 * 4 * s["n_quads"]
    # the lattice points lie on the surface
    from scipy.spatial import cKDTree

    d, _ = cKDTree(m.vertices).query(L["V"])
    assert d.max() < 0.1
