"""Laplacian and eigenbases: PSD stiffness, A-orthonormality, signs, errors, Fourier basis."""

import numpy as np
import pytest
import scipy.sparse as sp
from conftest import BROKEN

import prodmaps as pm


def test_cotan_laplacian_is_psd_with_constant_kernel(sphere):
    W, A = pm.laplacian(sphere)
    assert abs(W - W.T).max() < 1e-12
    np.testing.assert_allclose(W @ np.ones(sphere.n_vertices), 0, atol=1e-10)
    x = np.random.default_rng(0).normal(size=sphere.n_vertices)
    assert x @ (W @ x) > 0
    assert A.shape == (sphere.n_vertices,)
    np.testing.assert_allclose(A.sum(), sphere.area, rtol=1e-12)


def test_full_mass_matches_area_and_lumps_to_barycentric(sphere):
    _, M = pm.laplacian(sphere, mass="full")
    _, A = pm.laplacian(sphere)
    assert sp.issparse(M)
    np.testing.assert_allclose(np.asarray(M.sum(axis=1)).ravel(), A, rtol=1e-12)


def test_sphere_eigenvalues_approach_l_times_l_plus_1(sphere):
    b = pm.eigenbasis(sphere, 9)
    # unit sphere: 0, then 2 (x3), then 6 (x5); coarse mesh within 3 %
    np.testing.assert_allclose(b.evals, [0, 2, 2, 2, 6, 6, 6, 6, 6], rtol=0.03, atol=1e-10)


def test_eigenbasis_conventions(basis_0, human_0):
    b = basis_0
    assert b.vecs.shape == (human_0.n_vertices, 40) and b.k == 40
    G = b.vecs.T @ (b.mass[:, None] * b.vecs)
    np.testing.assert_allclose(G, np.eye(40), atol=1e-10)
    assert np.all(np.diff(b.evals) >= 0) and b.evals[0] == 0
    np.testing.assert_allclose(b.vecs[:, 0], 1 / np.sqrt(human_0.area), rtol=1e-12)
    idx = np.argmax(np.abs(b.vecs[:, 1:]), axis=0)
    assert np.all(b.vecs[idx, np.arange(1, 40)] > 0)  # deterministic signs


def test_eigenbasis_is_deterministic(human_0, basis_0):
    again = pm.eigenbasis(human_0, 40)
    np.testing.assert_array_equal(again.vecs[:, :30], basis_0.vecs[:, :30])


def test_open_mesh_uses_neumann_condition():
    m = pm.load_mesh(BROKEN / "open_boundary.off")
    W, A = pm.laplacian(m)
    np.testing.assert_allclose(W @ np.ones(4), 0, atol=1e-12)  # constants stay in the kernel


@pytest.mark.parametrize("k", [0, -1, 5002, 10**6])
def test_eigenbasis_k_out_of_range(human_0, k):
    with pytest.raises(ValueError, match="out of range"):
        pm.eigenbasis(human_0, k)


def test_eigenbasis_rejects_non_mesh():
    with pytest.raises(TypeError):
        pm.eigenbasis(np.zeros((3, 3)), 2)


def test_robust_laplacian_close_to_cotan_on_good_mesh(human_0, basis_0):
    r = pm.eigenbasis(human_0, 10, kind="robust")
    np.testing.assert_allclose(r.evals[1:], basis_0.evals[1:10], rtol=0.01)


def test_fourier_basis_orthonormal_and_eigen():
    b = pm.fourier_basis(256, 9)
    G = b.vecs.T @ (b.mass[:, None] * b.vecs)
    np.testing.assert_allclose(G, np.eye(9), atol=1e-12)
    np.testing.assert_allclose(b.evals, [0, 1, 1, 4, 4, 9, 9, 16, 16])
    with pytest.raises(ValueError):
        pm.fourier_basis(16, 9)


def test_basis_validation():
    with pytest.raises(ValueError, match="non-finite"):
        pm.Basis(np.full((4, 2), np.nan), np.zeros(2), np.ones(4))
    with pytest.raises(ValueError, match="mass"):
        pm.Basis(np.zeros((4, 2)), np.zeros(2), np.ones(3))
