"""Lemma 2 (C~ transfers exact pointwise products for ANY C), ground-truth maps, argument checks."""

import numpy as np
import pytest

import prodmaps as pm


def product_images(C, basis_2, index):
    """Π_t (Φ2 C e_{i_t}) for every multi-index row: the exact image of each product column."""
    T = basis_2.vecs @ C  # (n2, k1): images of the basis functions
    padded = np.concatenate([np.ones((T.shape[0], 1)), T[:, 1:]], axis=1)
    img = np.prod(padded[:, index], axis=2)
    img[:, 0] = T[:, 0]
    return img


@pytest.mark.parametrize("pairs", ["ordered", "unique"])
@pytest.mark.parametrize("order, k1, k2", [(2, 10, 10), (2, 7, 12), (2, 12, 7), (3, 6, 8), (4, 4, 5)])
def test_lemma2_any_C(basis_0, basis_13, pairs, order, k1, k2):
    b1, b2 = basis_0.truncate(k1), basis_13.truncate(k2)
    C = np.random.default_rng(order * 100 + k1).normal(size=(k2, k1))  # not a ground-truth map
    Ct = pm.extend_fmap(C, b1, b2, order=order, pairs=pairs)
    e1, e2 = pm.product_basis(b1, order, pairs), pm.product_basis(b2, order, pairs)
    assert Ct.shape == (e2.K, e1.K)
    a = np.random.default_rng(7).normal(size=(e1.K, 3))
    got = e2.evaluate(Ct @ a)
    want = product_images(C, b2, e1.index) @ a  # Σ_j a_j Π(Φ2 C e_i)
    assert np.abs(got - want).max() <= 1e-10 * np.abs(want).max()


def test_order2_ordered_is_the_papers_block_formula(basis_0, basis_13):
    b1, b2 = basis_0.truncate(5), basis_13.truncate(6)
    C = np.random.default_rng(0).normal(size=(6, 5))
    Ct = pm.extend_fmap(C, b1, b2)
    k1, k2 = 4, 5
    np.testing.assert_array_equal(Ct[:6, :5], C)
    np.testing.assert_array_equal(Ct[k2 + 1:, :k1 + 1], 0)
    np.testing.assert_allclose(Ct[k2 + 1:, k1 + 1:], np.kron(C[1:, 1:], C[1:, 1:]))


def test_ground_truth_identity_map(basis_0):
    p = np.arange(basis_0.n)
    C = pm.fmap_from_p2p(p, basis_0, basis_0)
    np.testing.assert_allclose(C, np.eye(basis_0.k), atol=1e-10)


def test_mismatched_shapes_are_rejected(basis_0, basis_13):
    b1, b2 = basis_0.truncate(10), basis_13.truncate(12)
    with pytest.raises(ValueError, match=r"\(12, 10\)"):
        pm.extend_fmap(np.zeros((10, 12)), b1, b2)
    with pytest.raises(ValueError, match="pairs must be 'ordered'"):
        pm.extend_fmap(np.zeros((12, 10)), b1, b2, pairs="foo")
    with pytest.raises(ValueError, match="p2p_21"):
        pm.fmap_from_p2p(np.arange(5), b1, b2)
    with pytest.raises(ValueError, match="indices"):
        pm.fmap_from_p2p(np.full(b2.n, b1.n), b1, b2)
    with pytest.raises(TypeError, match="basis_1 must be a prodmaps.Basis"):
        pm.extend_fmap(np.zeros((12, 10)), b1.vecs, b2)
