"""Localized Manifold Harmonics: orthonormality, localisation, orthogonality, dense reference."""

import numpy as np
import pytest
import scipy.linalg as sla
import scipy.sparse as sp

import prodmaps as pm
import prodmaps.lmh as lmh
from prodmaps.mesh import icosphere


@pytest.fixture(scope="module")
def bumpy():
    """A deterministic, asymmetric small closed surface (distinct eigenvalues), 642 vertices."""
    s = icosphere(3)
    rng = np.random.default_rng(3)
    v = s.vertices * (1.0 + 0.08 * rng.random((s.n_vertices, 1)))
    v[:, 0] *= 1.6  # elongate: breaks the remaining symmetry of the spectrum
    return pm.Mesh(v, s.faces, name="bumpy")


@pytest.fixture(scope="module")
def bumpy_region(bumpy):
    return bumpy.vertices[:, 0] > 0.7  # a cap at one end


@pytest.fixture(scope="module")
def human_region(human_0):
    z = human_0.vertices[:, 2]
    return z > z.max() - 0.12 * (z.max() - z.min())  # the head (~8.5 % of the area)


@pytest.fixture(scope="module")
def human_lmh(human_0, human_region):
    gb = pm.eigenbasis(human_0, 10)
    return lmh.localized_harmonics(human_0, human_region, 12, global_basis=gb)


def _dense_reference(mesh, region, k, k_global, mu_region, mu_orth):
    W, A = pm.laplacian(mesh)
    gb = pm.eigenbasis(mesh, k_global)
    area = A.sum()
    U = A[:, None] * gb.vecs
    Q = W.toarray() + np.diag(mu_region / area * A * (1.0 - region)) + (mu_orth / area) * U @ U.T
    w, V = sla.eigh(Q, np.diag(A), subset_by_index=[0, k])  # one extra to check the gap
    return w, V, A


def test_matches_dense_reference(bumpy, bumpy_region):
    k, kg, mr, mo = 8, 6, 3e3, 2e3
    w, V, A = _dense_reference(bumpy, bumpy_region.astype(float), k, kg, mr, mo)
    gaps = np.diff(w) / w[-1]
    assert gaps.min() > 1e-4, "test mesh must have a simple spectrum for eigenvector comparison"
    L = lmh.localized_harmonics(bumpy, bumpy_region, k, k_global=kg, mu_region=mr, mu_orth=mo)
    np.testing.assert_allclose(L.evals, w[:k], rtol=1e-9)
    ref = pm.basis.fix_signs(V[:, :k])
    np.testing.assert_allclose(L.vecs, ref, atol=1e-7)
    # effective weights are divided by the area
    assert L.mu_region == pytest.approx(mr / A.sum())
    assert L.mu_orth == pytest.approx(mo / A.sum())


def test_operator_parts_reproduce_dense_operator(bumpy, bumpy_region):
    W, A = pm.laplacian(bumpy)
    gb = pm.eigenbasis(bumpy, 5)
    S0, U = lmh.lmh_operator_parts(W, A, bumpy_region, gb.vecs, 7.0, 11.0)
    assert sp.issparse(S0) and U.shape == (bumpy.n_vertices, 5)
    x = np.random.default_rng(0).standard_normal(bumpy.n_vertices)
    dense = W.toarray() + np.diag(7.0 * A * (1 - bumpy_region)) + 11.0 * np.outer(A, A) * (gb.vecs @ gb.vecs.T)
    np.testing.assert_allclose(S0 @ x + 11.0 * U @ (U.T @ x), dense @ x, rtol=1e-10, atol=1e-10)


def test_a_orthonormal_and_sorted(human_lmh):
    L = human_lmh
    G = L.vecs.T @ (L.mass[:, None] * L.vecs)
    np.testing.assert_allclose(G, np.eye(L.k), atol=1e-10)
    assert np.all(np.diff(L.evals) >= 0)
    assert L.vecs.shape == (5002, 12)


def test_localised_in_region(human_lmh, human_region):
    inside = human_lmh.mass_inside()
    assert inside.shape == (12,)
    assert np.all(inside > 0.9), inside
    # a global eigenfunction is not localised: the contrast is what the penalty buys
    gb = human_lmh.global_basis
    glob = np.einsum("i,ij->j", gb.mass * human_region, gb.vecs[:, 1:] ** 2)
    assert glob.max() < 0.5


def test_nearly_orthogonal_to_global(human_lmh):
    gb = human_lmh.global_basis
    C = gb.vecs.T @ (gb.mass[:, None] * human_lmh.vecs)  # (k_global, k)
    assert np.abs(C).max() < 0.05


def test_lmh_basis_is_orthonormal_constant_first_and_products_work(human_0, human_region):
    gb = pm.eigenbasis(human_0, 8)
    B = lmh.lmh_basis(human_0, human_region, 6, global_basis=gb)
    assert isinstance(B, pm.Basis) and B.k == 14
    G = B.vecs.T @ (B.mass[:, None] * B.vecs)
    np.testing.assert_allclose(G, np.eye(14), atol=1e-10)
    np.testing.assert_allclose(B.vecs[:, :8], gb.vecs)  # global part untouched, constant first
    np.testing.assert_allclose(B.vecs[:, 0], 1 / np.sqrt(B.area))
    assert np.all(B.evals[8:] > 0)
    # products of the combined basis represent the coordinates better than the basis alone
    X = human_0.vertices
    e_std = pm.relative_error(B.vecs @ B.project(X), X, B.mass).mean()
    ext = pm.product_basis(B, order=2, pairs="unique")
    e_prod = pm.relative_error(ext.evaluate(pm.approximate(X, ext, method="svd")), X, B.mass).mean()
    assert e_prod < e_std


def test_without_orthogonality_penalty_recovers_region_modes(bumpy, bumpy_region):
    # mu_orth = 0 and a region covering everything: the plain Laplacian eigenproblem
    L = lmh.localized_harmonics(bumpy, np.ones(bumpy.n_vertices, bool), 5, k_global=3, mu_orth=0.0)
    ref = pm.eigenbasis(bumpy, 5)
    np.testing.assert_allclose(L.evals, ref.evals, atol=1e-8)
    np.testing.assert_allclose(np.abs(L.vecs[:, 1:]), np.abs(ref.vecs[:, 1:]), atol=1e-6)


def test_deterministic(bumpy, bumpy_region):
    a = lmh.localized_harmonics(bumpy, bumpy_region, 6, k_global=4)
    b = lmh.localized_harmonics(bumpy, bumpy_region, 6, k_global=4)
    np.testing.assert_array_equal(a.vecs, b.vecs)


def test_bad_input(bumpy, bumpy_region):
    n = bumpy.n_vertices
    with pytest.raises(ValueError, match="empty"):
        lmh.localized_harmonics(bumpy, np.zeros(n, bool), 4)
    with pytest.raises(ValueError, match="shape"):
        lmh.localized_harmonics(bumpy, bumpy_region[:-1], 4)
    with pytest.raises(ValueError, match=r"\[0, 1\]"):
        lmh.localized_harmonics(bumpy, 2.0 * bumpy_region, 4)
    with pytest.raises(ValueError, match="k must be"):
        lmh.localized_harmonics(bumpy, bumpy_region, 0)
    with pytest.raises(ValueError, match=">= 0"):
        lmh.localized_harmonics(bumpy, bumpy_region, 3, mu_region=-1.0)
    with pytest.raises(ValueError, match="k_global >= 1"):
        lmh.lmh_basis(bumpy, bumpy_region, 3, k_global=0)
    with pytest.raises(TypeError):
        lmh.localized_harmonics(bumpy.vertices, bumpy_region, 3)
