"""Approaches A and B: exactness on representable functions, routes, limits, optimality."""

import numpy as np
import pytest

import prodmaps as pm
from prodmaps.approx import column_weights


def hks(basis, times):
    return (basis.vecs**2) @ np.exp(-np.outer(basis.evals, times))  # (n, len(times))


@pytest.fixture(scope="module")
def b10(basis_0):
    return basis_0.truncate(10)


def test_std_is_projection(b10, basis_0):
    f = basis_0.vecs[:, :10] @ np.arange(10.0)
    np.testing.assert_allclose(pm.approximate(f, b10, "std"), np.arange(10.0), atol=1e-10)
    with pytest.raises(ValueError, match="std"):
        pm.approximate(f, pm.product_basis(b10), "std")


# (bound on the error at rtol = 1e-3, how many times below the standard projection): measured on
# anny_000, k = 9: "area" 1.3e-5..1.9e-5 (std 0.05..0.2); "euclidean" (the default) 5.7e-3..6.4e-3:
# with unit-norm eigenvectors the product columns are ~sqrt(area / n) smaller, so 1e-3 cuts more of them
PAPER_THRESHOLD = {"area": (1e-4, 100.0), "euclidean": (1e-2, 5.0)}


@pytest.mark.parametrize("pairs", ["ordered", "unique"])
@pytest.mark.parametrize("normalization", sorted(PAPER_THRESHOLD))
def test_hks_reproduced_by_products(b10, pairs, normalization):
    F = hks(b10, [1e-3, 1e-2, 1e-1])
    ext = pm.product_basis(b10, 2, pairs)
    exact = ext.evaluate(pm.approximate(F, ext, "svd", rtol=1e-9, normalization=normalization))
    err = pm.relative_error(exact, F, b10.mass)
    assert np.all(err < 1e-8), err
    paper = ext.evaluate(pm.approximate(F, ext, "svd", rtol=1e-3, normalization=normalization))
    err3 = pm.relative_error(paper, F, b10.mass)
    bound, factor = PAPER_THRESHOLD[normalization]
    assert np.all(err3 < bound), err3
    std = b10.vecs @ pm.approximate(F, b10, "std")
    assert np.all(pm.relative_error(std, F, b10.mass) > factor * err3)


def test_svd_and_gram_routes_agree(basis_0):
    ext = pm.product_basis(basis_0.truncate(20), 2, "ordered")
    F = np.random.default_rng(0).normal(size=(basis_0.n, 4))
    a_svd = pm.approximation_operator(ext, "svd", rtol=1e-3, route="svd").coefficients(F)
    a_gram = pm.approximation_operator(ext, "svd", rtol=1e-3, route="gram").coefficients(F)
    assert np.abs(a_svd - a_gram).max() <= 1e-8 * np.abs(a_svd).max()


def test_ordered_solution_equals_direct_pseudoinverse(basis_0):
    b = basis_0.truncate(12)
    ext = pm.product_basis(b, 2, "ordered")
    f = np.random.default_rng(2).normal(size=b.n)
    # the default normalisation: unit-Euclidean factors, D = their products (per ordered column)
    c = 1.0 / np.linalg.norm(b.vecs, axis=0)
    d = np.where(ext.index > 0, c[ext.index], 1.0).prod(axis=1)
    d[0] = c[0]
    for norm, D in (("area", np.ones(ext.K)), ("euclidean", d)):
        X = np.sqrt(b.mass)[:, None] * ext.matrix * D  # the paper's sqrt(A) B D, both ordered pairs
        U, s, Vt = np.linalg.svd(X, full_matrices=False)
        r = int(np.sum(s > 1e-3 * s[0]))
        direct = D * (Vt[:r].T @ ((U[:, :r].T @ (np.sqrt(b.mass) * f)) / s[:r]))
        ours = pm.approximate(f, ext, "svd", rtol=1e-3, normalization=norm)
        np.testing.assert_allclose(ours, direct, rtol=0, atol=1e-9 * np.abs(direct).max(), err_msg=norm)
    assert pm.approx.DEFAULT_NORMALIZATION == "euclidean"
    np.testing.assert_array_equal(pm.approximate(f, ext, "svd", rtol=1e-3),
                                  pm.approximate(f, ext, "svd", rtol=1e-3, normalization="euclidean"))


def test_operator_single_equals_batch(b10):
    ext = pm.product_basis(b10, 2, "ordered")
    F = np.random.default_rng(3).normal(size=(b10.n, 5))
    op = ext.operator("svd", rtol=1e-3)
    assert op is ext.operator("svd", rtol=1e-3)  # cached and reused
    batch = op.coefficients(F)
    for j in range(F.shape[1]):
        # same operator; only the BLAS kernel (GEMV vs GEMM) differs -> round-off level
        np.testing.assert_allclose(op.coefficients(F[:, j]), batch[:, j], rtol=0,
                                   atol=1e-10 * np.abs(batch[:, j]).max())


@pytest.mark.parametrize("pairs", ["ordered", "unique"])
def test_canonical_coefficients_preserve_norm(b10, pairs):
    ext = pm.product_basis(b10, 2, pairs)
    op = ext.operator("svd", rtol=1e-3)
    a = np.random.default_rng(4).normal(size=(ext.K, 3))
    f = ext.evaluate(a)
    norm_A = np.sqrt(np.einsum("i,ij->j", b10.mass, f**2))
    np.testing.assert_allclose(np.linalg.norm(op.canonical(a), axis=0), norm_A, rtol=1e-3)
    # exact for functions in the kept subspace
    a2 = op.coefficients(f)
    g = ext.evaluate(a2)
    np.testing.assert_allclose(np.linalg.norm(op.canonical(a2), axis=0),
                               np.sqrt(np.einsum("i,ij->j", b10.mass, g**2)), rtol=1e-9)


@pytest.mark.parametrize("pairs", ["unique", "ordered"])
def test_ridge_tends_to_min_norm_least_squares(basis_0, pairs):
    b = basis_0.truncate(7)  # σ_min²/σ_max² ≈ 1.4e-9 for this unique basis
    ext = pm.product_basis(b, 2, pairs)
    f = np.random.default_rng(5).normal(size=b.n)
    # D = I ("area"): the conditioning quoted above; the limit holds for any D with its own ε scale
    target = pm.approximate(f, ext, "svd", rtol=1e-12, route="svd", normalization="area")  # min-norm LSQ
    gaps = [np.linalg.norm(pm.approximate(f, ext, "ridge", eps=e, normalization="area") - target)
            / np.linalg.norm(target) for e in (1e-10, 1e-13, 1e-16)]
    # the ridge bias is ≈ ε σ_max² / σ_min²: it shrinks ~1000x per step of ε
    assert gaps[1] < 1e-2 * gaps[0] and gaps[2] < 1e-2 * gaps[1]
    assert gaps[2] < 1e-6


@pytest.mark.parametrize("normalization", ["area", "euclidean", "columns"])
def test_norm_penalty_ridge_is_equation_4_minimiser(b10, normalization):
    # penalty="norm": argmin ||f - B a||_A + ε σ_max ||a'|| (a' = a / D the scaled coefficients), norms not squared
    ext = pm.product_basis(b10, 2, "unique")
    rng = np.random.default_rng(8)
    F = np.c_[ext.matrix @ rng.normal(size=ext.K) + 0.3 * rng.normal(size=b10.n), rng.normal(size=b10.n)]
    d = column_weights(ext, normalization)
    d = np.ones(ext.K) if d is None else d
    X = np.sqrt(b10.mass)[:, None] * ext.matrix * d  # (n, K) scaled columns
    smax = np.linalg.norm(X, 2)
    for eps in (1e-3, 3e-2):
        op = pm.approximation_operator(ext, "ridge", eps=eps, penalty="norm", normalization=normalization)
        a = op.coefficients(F)
        for j in range(F.shape[1]):
            x, g = a[:, j] / d, np.sqrt(b10.mass) * F[:, j]
            if eps * smax * np.linalg.norm(g) >= np.linalg.norm(X.T @ g):  # the dead zone: a = 0
                assert not np.any(x)
                continue
            r = X @ x - g
            grad = X.T @ r / np.linalg.norm(r) + eps * smax * x / np.linalg.norm(x)
            assert np.linalg.norm(grad) < 1e-7 * np.linalg.norm(X.T @ g) / np.linalg.norm(g)  # stationary
            J = lambda y: np.linalg.norm(X @ y - g) + eps * smax * np.linalg.norm(y)
            assert all(J(x) <= J(x + 1e-4 * np.linalg.norm(x) * rng.normal(size=x.size)) for _ in range(20))
    # its weight is its own per function: not the squared ridge at any one ε
    sq = pm.approximate(F, ext, "ridge", eps=1e-6, normalization=normalization)
    assert not np.allclose(a, sq)
    # a weight above ||Xᵀ g|| / (σ_max ||g||) gives a = 0 (the norm penalty's dead zone)
    big = pm.approximation_operator(ext, "ridge", eps=1.0, penalty="norm", normalization=normalization)
    assert not np.any(big.coefficients(F))
    single = pm.approximation_operator(ext, "ridge", eps=1e-3, penalty="norm", normalization=normalization)
    np.testing.assert_allclose(single.coefficients(F[:, 1]), single.coefficients(F)[:, 1], rtol=1e-10, atol=1e-14)


def test_norm_penalty_ordered_pairs_scale_and_full_mass(b10, basis_0, human_0):
    ordr = pm.product_basis(b10, 2, "ordered")
    F = np.c_[b10.vecs[:, 2] * b10.vecs[:, 5] + 0.1 * b10.vecs[:, 7], np.random.default_rng(9).normal(size=b10.n)]
    # ordered pairs (the solver runs on the scaled unique basis): the minimiser of the ordered problem itself
    a_o = pm.approximate(F, ordr, "ridge", eps=3e-3, penalty="norm", normalization="area")
    assert a_o.shape == (ordr.K, 2)
    X = np.sqrt(b10.mass)[:, None] * ordr.matrix  # (n, K) ordered columns, D = I
    smax = np.linalg.norm(X, 2)
    for j in range(2):
        g, x = np.sqrt(b10.mass) * F[:, j], a_o[:, j]
        r = X @ x - g
        grad = X.T @ r / np.linalg.norm(r) + 3e-3 * smax * x / np.linalg.norm(x)
        assert np.linalg.norm(grad) < 1e-7 * np.linalg.norm(X.T @ g) / np.linalg.norm(g)
    a_o = pm.approximate(F, ordr, "ridge", eps=3e-3, penalty="norm")
    # 1-homogeneous in f: any scale of the function, the same fit scaled (no overflow at 1e200)
    with np.errstate(all="raise"):
        big = pm.approximate(1e200 * F, ordr, "ridge", eps=3e-3, penalty="norm")
    np.testing.assert_allclose(big / 1e200, a_o, rtol=1e-9, atol=1e-15)
    zero = pm.approximate(np.zeros((b10.n, 1)), ordr, "ridge", eps=3e-3, penalty="norm")
    assert zero.shape == (ordr.K, 1) and not np.any(zero)
    full = pm.product_basis(pm.eigenbasis(human_0, 6, mass="full"))
    with pytest.raises(ValueError, match="lumped"):
        pm.approximation_operator(full, "ridge", eps=1e-3, penalty="norm")
    # one SVD per basis and normalisation serves every ε
    ordr.operator("ridge", eps=1e-2, penalty="norm")
    assert ("scaled_svd", "euclidean") in ordr.cache


def test_norm_penalty_only_for_the_ridge(b10):
    ext = pm.product_basis(b10, 2, "unique")
    with pytest.raises(ValueError, match="penalty must be one of"):
        pm.approximation_operator(ext, "ridge", eps=1e-3, penalty="l1")
    with pytest.raises(ValueError, match="other methods take none"):
        pm.approximation_operator(ext, "svd", penalty="norm")
    with pytest.raises(ValueError, match="penalty must be one of"):
        pm.approximation_operator(b10, "std", penalty="bogus")
    f = b10.vecs[:, 3] ** 2
    C = np.eye(b10.k)  # the transfer takes the penalty as a ridge parameter
    np.testing.assert_allclose(pm.transfer(f, C, b10, b10, "ridge", eps=1e-3, penalty="norm"),
                               pm.product_basis(b10).evaluate(pm.approximate(f, pm.product_basis(b10), "ridge",
                                                                             eps=1e-3, penalty="norm")),
                               rtol=1e-8, atol=1e-12)


def test_lasso_meets_optimality_conditions(b10):
    ext = pm.product_basis(b10, 2, "unique")
    rng = np.random.default_rng(6)
    F = ext.matrix @ rng.normal(size=(ext.K, 2)) + 0.1 * rng.normal(size=(b10.n, 2))
    op = pm.approximation_operator(ext, "lasso", eps=1e-2, tol=1e-6)
    a = op.coefficients(F)
    # the lasso runs on the normalised columns B D (the default D): optimality holds for x = a / D
    D = column_weights(ext)
    B = ext.matrix * D
    G = B.T @ (b10.mass[:, None] * B)
    b = B.T @ (b10.mass[:, None] * F)
    lam = 1e-2 * np.abs(b).max(axis=0)  # (m,) the weight eps * ||Bᵀ A f||_inf per function
    x = a / D[:, None]
    g = G @ x - b  # gradient of the smooth part: -lam sign(x_j) where x_j != 0, |g_j| <= lam where x_j = 0
    nz = x != 0
    assert nz.any(axis=0).all() and (~nz).any(axis=0).all()  # both conditions are exercised
    violation = np.where(nz, np.abs(g + lam * np.sign(x)), np.maximum(np.abs(g) - lam, 0.0)) / lam  # relative to λ
    assert violation.max() < 1e-6
    nnz_small = np.count_nonzero(a)
    nnz_big = np.count_nonzero(pm.approximate(F, ext, "lasso", eps=1e-1))
    assert nnz_big < nnz_small  # stronger weight, sparser solution


@pytest.mark.parametrize("bad", [np.nan, np.inf])
def test_non_finite_functions_are_rejected(b10, bad):
    f = np.zeros(b10.n)
    f[3] = bad
    with pytest.raises(ValueError, match="non-finite"):
        pm.approximate(f, pm.product_basis(b10), "svd")


def test_wrong_length_is_rejected(b10):
    with pytest.raises(ValueError, match="shape"):
        pm.approximate(np.zeros(b10.n + 1), b10, "std")
    with pytest.raises(ValueError, match="method"):
        pm.approximate(np.zeros(b10.n), b10, "magic")


def test_dual_gram_route_when_more_columns_than_points():
    """K_u > n (order-4 products on a coarse sphere): the n x n route equals the SVD route."""
    from prodmaps.mesh import icosphere

    sphere = icosphere(2)  # 162 vertices
    b = pm.eigenbasis(sphere, 9)
    ext = pm.product_basis(b, 4, "unique")  # 495 columns > 162 points
    assert ext.K > b.n
    F = np.column_stack([sphere.vertices, np.random.default_rng(8).normal(size=(b.n, 2))])
    op_gram = pm.approximation_operator(ext, "svd", rtol=1e-3, route="gram")
    assert op_gram.params.get("side") == "dual"
    op_svd = pm.approximation_operator(ext, "svd", rtol=1e-3, route="svd")
    a_g, a_s = op_gram.coefficients(F), op_svd.coefficients(F)
    assert np.abs(a_g - a_s).max() <= 1e-8 * np.abs(a_s).max()
    a = np.random.default_rng(9).normal(size=(ext.K, 2))
    # canonical coefficients are defined up to a rotation within repeated singular values:
    # compare what is invariant, their norms and their Gram matrix
    cg, cs = op_gram.canonical(a), op_svd.canonical(a)
    np.testing.assert_allclose(cg.T @ cg, cs.T @ cs, rtol=1e-8)
