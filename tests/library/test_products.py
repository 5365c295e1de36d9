"""Product bases: layout, counts, the ordered/unique bridge, and the 1D Fourier rank."""

import math

import numpy as np
import pytest

import prodmaps as pm
from prodmaps.products import multi_indices, n_columns


@pytest.mark.parametrize("k, order", [(4, 2), (5, 3), (3, 4)])
def test_column_counts(k, order):
    assert (
        multi_indices(k, order, "ordered").shape[0]
        == n_columns(k, order, "ordered")
        == sum(k**d for d in range(order + 1))
    )
    assert multi_indices(k, order, "unique").shape[0] == n_columns(k, order, "unique") == math.comb(k + order, order)


def test_paper_index_convention(basis_0):
    b = basis_0.truncate(10)
    ext = pm.product_basis(b, 2, "ordered")
    k = 9
    assert ext.K == 1 + k + k * k == 91
    l, m = 3, 7  # 1-based non-constant functions -> column k + 1 + (l-1) k + (m-1)
    col = k + 1 + (l - 1) * k + (m - 1)
    np.testing.assert_array_equal(ext.index[col], [l, m])
    np.testing.assert_allclose(ext.matrix[:, col], b.vecs[:, l] * b.vecs[:, m])
    np.testing.assert_array_equal(ext.matrix[:, : k + 1], b.vecs)


def test_ordered_equals_scaled_unique_times_S(basis_0):
    b = basis_0.truncate(8)
    ext = pm.product_basis(b, 3, "ordered")
    B_s, scale = ext.solver_basis()
    S = ext.expand().T  # (K_u, K_o)
    np.testing.assert_allclose(B_s @ S, ext.matrix, atol=1e-13)
    np.testing.assert_allclose((S @ S.T).toarray(), np.eye(S.shape[0]), atol=1e-14)
    s_o = np.linalg.svd(np.sqrt(b.mass)[:, None] * ext.matrix, compute_uv=False)
    s_s = np.linalg.svd(np.sqrt(b.mass)[:, None] * B_s, compute_uv=False)
    np.testing.assert_allclose(s_o[: s_s.size], s_s, rtol=1e-10, atol=1e-12 * s_s[0])


def test_fold_and_evaluate(basis_0):
    b = basis_0.truncate(6)
    o = pm.product_basis(b, 2, "ordered")
    u = pm.product_basis(b, 2, "unique")
    a = np.random.default_rng(1).normal(size=(o.K, 3))
    np.testing.assert_allclose(o.evaluate(a), o.matrix @ a, atol=1e-12)
    np.testing.assert_allclose(u.matrix @ (o.fold() @ a), o.matrix @ a, atol=1e-12)


def test_product_basis_is_cached(basis_0):
    assert pm.product_basis(basis_0, 2, "unique") is pm.product_basis(basis_0, 2, "unique")


@pytest.mark.parametrize("k", [2, 4, 8, 12])
def test_fourier_products_rank_is_2k_plus_1(k):
    b = pm.fourier_basis(512, k + 1)
    ext = pm.product_basis(b, 2, "unique")
    s = np.linalg.svd(np.sqrt(b.mass)[:, None] * ext.matrix, compute_uv=False)
    assert int(np.sum(s > 1e-10 * s[0])) == 2 * k + 1


def test_bad_arguments(basis_0):
    with pytest.raises(ValueError, match="pairs"):
        pm.product_basis(basis_0, 2, "both")
    with pytest.raises(ValueError, match="order"):
        pm.product_basis(basis_0, 0)
    with pytest.raises(TypeError):
        pm.product_basis(np.zeros((3, 3)))


@pytest.mark.parametrize("pairs", ["ordered", "unique"])
def test_blocked_route_equals_materialised(basis_0, pairs):
    """Large meshes never hold the extended basis: blocked Gram/products give the same numbers."""
    from prodmaps.products import ProductBasis

    b = basis_0.truncate(15)
    full = pm.product_basis(b, 2, pairs)
    full.solver_basis()  # materialised route: the solver basis is held in the cache
    assert "solver" in full.cache
    blocked = ProductBasis(b, 2, pairs, full.index, block_bytes=1 << 16)  # many small blocks
    assert "solver" not in blocked.cache
    np.testing.assert_allclose(blocked.solver_gram(), full.solver_gram(), rtol=1e-12, atol=1e-12)
    F = np.random.default_rng(0).normal(size=(b.n, 3))
    a_full = full.operator("svd", rtol=1e-3).coefficients(F)
    a_blk = blocked.operator("svd", rtol=1e-3).coefficients(F)
    np.testing.assert_allclose(a_blk, a_full, rtol=0, atol=1e-9 * np.abs(a_full).max())
    np.testing.assert_allclose(blocked.evaluate(a_blk), full.evaluate(a_full), atol=1e-9)
    assert "solver" not in blocked.cache  # nothing materialised


def test_a_one_block_extended_basis_is_formed_once_and_gives_the_same_products(basis_0, monkeypatch):
    import prodmaps.products as pr

    ext = pm.product_basis(basis_0.truncate(8), order=2)
    assert 8 * ext.n * ext.unique_index.shape[0] <= ext.block_bytes  # one block: kept
    ext.kept_block.clear()
    X = np.random.default_rng(0).standard_normal((ext.unique_index.shape[0], 3))
    first = ext.solver_matmul(X)
    calls = []
    real = pr.evaluate_products
    monkeypatch.setattr(pr, "evaluate_products", lambda *a: calls.append(1) or real(*a))
    assert np.array_equal(ext.solver_matmul(X), first) and calls == []  # the kept block, not formed again
    B_s, _ = ext.solver_basis()
    np.testing.assert_allclose(first, B_s @ X, rtol=1e-12, atol=1e-12)
    kept = ext.kept_block.get("B_s", lambda: None)
    assert not kept.flags.writeable  # shared: read-only
