"""Laplace–Beltrami operators: cotangent stiffness and masses, robust and anisotropic variants."""

from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp

import prodmaps as pm
from prodmaps.operators import anisotropic_laplacian, cotan_weights, fem_mass, lumped_mass

BROKEN = Path(__file__).resolve().parents[1] / "data" / "broken"


def test_laplacian_is_the_function_of_the_operators_module(sphere):
    import prodmaps.operators as ops

    assert pm.laplacian is ops.laplacian and callable(pm.laplacian)
    W1, A1 = pm.laplacian(sphere)
    W2, A2 = ops.laplacian(sphere)
    assert (W1 != W2).nnz == 0 and np.array_equal(A1, A2)


def test_cotan_laplacian_is_psd_with_constant_kernel(sphere):
    W, A = pm.laplacian(sphere)
    assert abs(W - W.T).max() < 1e-12
    np.testing.assert_allclose(W @ np.ones(sphere.n_vertices), 0, atol=1e-10)
    x = np.random.default_rng(0).normal(size=sphere.n_vertices)
    assert x @ (W @ x) > 0
    assert A.shape == (sphere.n_vertices,)
    np.testing.assert_allclose(A.sum(), sphere.area, rtol=1e-12)


def test_cotan_weights_of_one_right_triangle():
    V = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]])
    F = np.array([[0, 1, 2]])
    W = cotan_weights(V, F).toarray()
    # angles: 90° at vertex 0 (opposite edge 1-2: cot 0), 45° at 1 and 2 (cot 1)
    assert W[1, 2] == pytest.approx(0.0, abs=1e-15)
    assert W[0, 1] == pytest.approx(-0.5) and W[0, 2] == pytest.approx(-0.5)
    np.testing.assert_allclose(np.diag(W), [1.0, 0.5, 0.5])
    np.testing.assert_allclose(lumped_mass(V, F), [1 / 6] * 3)


def test_dirichlet_energy_of_a_linear_function_is_exact():
    """``fᵀ W f = ∫|∇f|²`` for a piecewise-linear f: exact for a linear function on a flat mesh."""
    g = np.linspace(0, 2, 9)
    X, Y = np.meshgrid(g, np.linspace(0, 1, 5))
    V = np.column_stack([X.ravel(), Y.ravel(), np.zeros(X.size)])
    n = X.shape[1]
    F = []
    for r in range(X.shape[0] - 1):
        for c in range(n - 1):
            a, b, d, e = r * n + c, r * n + c + 1, (r + 1) * n + c, (r + 1) * n + c + 1
            F += [[a, b, e], [a, e, d]]
    mesh = pm.Mesh(V, np.array(F))
    W, A = pm.laplacian(mesh)
    f = 3.0 * V[:, 0] - 2.0 * V[:, 1]  # |∇f|² = 13 on an area of 2
    assert f @ (W @ f) == pytest.approx(13.0 * 2.0, rel=1e-12)
    np.testing.assert_allclose(A.sum(), 2.0, rtol=1e-12)


def test_scaling_leaves_W_and_scales_A(sphere):
    W, A = pm.laplacian(sphere)
    W3, A3 = pm.laplacian(pm.Mesh(3.0 * sphere.vertices, sphere.faces))
    assert abs(W3 - W).max() < 1e-12  # cotangents are scale invariant
    np.testing.assert_allclose(A3, 9.0 * A, rtol=1e-12)


def test_full_mass_matches_area_and_lumps_to_barycentric(sphere):
    _, M = pm.laplacian(sphere, mass="full")
    _, A = pm.laplacian(sphere)
    assert sp.issparse(M)
    np.testing.assert_allclose(np.asarray(M.sum(axis=1)).ravel(), A, rtol=1e-12)
    np.testing.assert_allclose(fem_mass(sphere.vertices, sphere.faces).diagonal(), M.diagonal())


def test_open_mesh_uses_neumann_condition():
    m = pm.load_mesh(BROKEN / "open_boundary.off")
    W, A = pm.laplacian(m)
    np.testing.assert_allclose(W @ np.ones(4), 0, atol=1e-12)  # constants stay in the kernel


def test_robust_laplacian_close_to_cotan_on_good_mesh(human_0, basis_0):
    r = pm.eigenbasis(human_0, 10, kind="robust")
    np.testing.assert_allclose(r.evals[1:], basis_0.evals[1:10], rtol=0.01)


def test_bad_arguments_name_the_choice(sphere):
    with pytest.raises(ValueError, match="'cotan' or 'robust'"):
        pm.laplacian(sphere, kind="fem")
    with pytest.raises(ValueError, match="'lumped' or 'full'"):
        pm.laplacian(sphere, mass="diagonal")
    with pytest.raises(ValueError, match="only the lumped mass"):
        pm.laplacian(sphere, kind="robust", mass="full")
    with pytest.raises(TypeError, match="prodmaps.Mesh"):
        pm.laplacian(np.zeros((3, 3)))


def test_anisotropic_laplacian_reduces_to_cotan_without_anisotropy(sphere):
    W, A = pm.laplacian(sphere)
    Wa, Aa = anisotropic_laplacian(sphere, 0.3, 0.0)
    assert abs(Wa - W).max() < 1e-10 and np.allclose(Aa, A)
    Wb, _ = anisotropic_laplacian(sphere, 0.3, 5.0)
    np.testing.assert_allclose(Wb @ np.ones(sphere.n_vertices), 0, atol=1e-10)
