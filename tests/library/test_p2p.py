"""Point-map recovery: exact blocked nearest neighbours, standard and extended conversions."""

import numpy as np
import pytest
from scipy.spatial.distance import cdist

import prodmaps as pm
from prodmaps.p2p import (
    NN_METHODS,
    extended_embeddings,
    from_fmap,
    heat_square_coefficients,
    nearest_neighbors,
    point_functions,
)


@pytest.mark.parametrize("dim", [3, 40, 2500])
@pytest.mark.parametrize("block", [1, 7, None])
def test_blocked_nn_equals_brute_force(dim, block):
    rng = np.random.default_rng(dim)
    P = rng.normal(size=(300, dim))
    Q = rng.normal(size=(123, dim))
    idx, dist = nearest_neighbors(Q, P, block=block, return_distance=True)
    D = cdist(Q, P)
    assert idx.dtype == np.int64 and idx.shape == (123,)
    assert np.array_equal(idx, np.argmin(D, axis=1))
    assert np.allclose(dist, D.min(axis=1), rtol=1e-9)


def test_nn_exact_hits_and_ties():
    P = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 0.0], [5.0, 5.0]])
    for method in NN_METHODS:
        assert np.array_equal(nearest_neighbors(P, P, method=method), [0, 1, 1, 3])  # duplicates: smallest index
    # a query exactly half-way between two points goes to the smaller index, whatever the order
    Q = np.array([[0.5, 0.0], [3.0, 2.5]])
    for method in NN_METHODS:
        assert np.array_equal(nearest_neighbors(Q, P, method=method), [0, 1])
        assert np.array_equal(nearest_neighbors(Q, P[::-1], method=method), [1, 0])


def _brute_force(Q, P):
    """Reference: squared distances by direct differences, first index of the minimum."""
    return np.argmin(cdist(Q, P, "sqeuclidean"), axis=1)


@pytest.mark.parametrize("method", NN_METHODS)
@pytest.mark.parametrize("dim", [1, 2, 5, 30, 33, 64, 300])
def test_nn_methods_equal_brute_force_with_exact_ties(method, dim):
    """Grid points (many duplicates and equidistant neighbours, every distance exact in floating
    point) and half-integer queries: every method returns the brute force's first minimiser."""
    rng = np.random.default_rng(dim)
    P = rng.integers(-2, 3, size=(400, dim)).astype(float)
    Q = rng.integers(-2, 3, size=(250, dim)) + 0.5 * rng.integers(0, 2, size=(250, dim))
    D = cdist(Q, P, "sqeuclidean")
    assert np.sum(D == D.min(axis=1, keepdims=True)) > Q.shape[0]  # the data has exact ties
    for block in (1, 37, None):
        assert np.array_equal(nearest_neighbors(Q, P, method=method, block=block), _brute_force(Q, P))
    Pr, Qr = rng.normal(size=(500, dim)), rng.normal(size=(300, dim))  # generic data, one scale spread out
    Pr *= np.geomspace(1.0, 1e-3, dim)[None, :]
    Qr *= np.geomspace(1.0, 1e-3, dim)[None, :]
    assert np.array_equal(nearest_neighbors(Qr, Pr, method=method), _brute_force(Qr, Pr))


def test_nn_near_ties_are_decided_exactly():
    """Points whose distances differ below float32 resolution: the float32 stage must hand them
    to the exact recheck (a float32-only argmin would pick either)."""
    rng = np.random.default_rng(5)
    base = rng.normal(size=(1, 50))
    P = np.repeat(base, 40, axis=0) + 1e-9 * rng.normal(size=(40, 50))
    P = np.vstack([P, rng.normal(size=(200, 50))])
    Q = base + 1e-9 * rng.normal(size=(30, 50))
    for method in NN_METHODS:
        assert np.array_equal(nearest_neighbors(Q, P, method=method), _brute_force(Q, P))


def test_nn_auto_agrees_with_kdtree_on_spectral_embeddings(human_0, human_13):
    """The standard conversion's embeddings in both regimes of ``auto`` (kd-tree, products)."""
    from scipy.spatial import cKDTree

    b1, b2 = pm.eigenbasis(human_0, 50), pm.eigenbasis(human_13, 50)
    C = np.random.default_rng(2).normal(size=(50, 50)) * 0.1 + np.eye(50)
    for k in (10, 50):
        P, Q = b1.vecs[:, :k] @ C[:k, :k].T, b2.vecs[:, :k]
        d_kd, i_kd = cKDTree(P).query(Q, k=2)
        assert np.all(d_kd[:, 1] > d_kd[:, 0])  # no near ties: the kd-tree's answer is the exact one
        assert np.array_equal(nearest_neighbors(Q, P), i_kd[:, 0])


def test_nn_bad_inputs():
    with pytest.raises(ValueError, match="dimension"):
        nearest_neighbors(np.zeros((3, 2)), np.zeros((4, 3)))
    with pytest.raises(ValueError, match="2D"):
        nearest_neighbors(np.zeros(3), np.zeros((4, 3)))
    with pytest.raises(ValueError, match="empty"):
        nearest_neighbors(np.zeros((3, 2)), np.zeros((0, 2)))
    with pytest.raises(ValueError, match="block"):
        nearest_neighbors(np.zeros((3, 2)), np.zeros((4, 2)), block=0)
    with pytest.raises(ValueError, match="method"):
        nearest_neighbors(np.zeros((3, 2)), np.zeros((4, 2)), method="ball")


def test_std_matches_its_definition(basis_0, basis_13):
    rng = np.random.default_rng(0)
    C = rng.normal(size=(15, 12))
    p2p = from_fmap(C, basis_0, basis_13, method="std")
    # nearest neighbours as on unit-area shapes: Φ2 against (area_1 / area_2) Φ1 Cᵀ
    ref = np.argmin(cdist(basis_13.vecs[:, :15], (basis_0.area / basis_13.area) * basis_0.vecs[:, :12] @ C.T), axis=1)
    assert p2p.shape == (basis_13.n,)
    assert np.array_equal(p2p, ref)


@pytest.mark.parametrize("method", ["std", "extended", "extended_closed_form"])
def test_ground_truth_identity_recovered_exactly(basis_0, method):
    k = 12
    C = pm.fmap_from_p2p(np.arange(basis_0.n), basis_0.truncate(k), basis_0.truncate(k))
    assert np.array_equal(from_fmap(C, basis_0, basis_0, method=method), np.arange(basis_0.n))


def test_closed_form_identity_rectangular(basis_0):
    """Ground-truth (k2, k1) = (16, 10) map on one shape: the closed form is exact (its kernels
    lie in the span of the first 10 eigenfunctions' products on both sides)."""
    C = pm.fmap_from_p2p(np.arange(basis_0.n), basis_0.truncate(10), basis_0.truncate(16))
    assert C.shape == (16, 10)
    assert np.array_equal(from_fmap(C, basis_0, basis_0, method="extended_closed_form"), np.arange(basis_0.n))


@pytest.mark.parametrize("pairs", ["unique", "ordered"])
def test_heat_square_coefficients_closed_form(basis_0, pairs):
    b = basis_0.truncate(9)
    t = 0.7 / b.evals[-1]
    pts = [0, 17, 4000]
    a = heat_square_coefficients(b, t, 7, pairs, points=pts)  # kernel from 7 eigenpairs
    ext = pm.product_basis(b, 2, pairs)
    assert a.shape == (3, ext.K)
    w = np.exp(-b.evals[:7] * t)
    h = (b.vecs[:, :7] * w) @ b.vecs[pts, :7].T  # (n, 3)
    assert np.allclose(ext.matrix @ a.T, h**2, rtol=0, atol=1e-10 * np.abs(h**2).max())


def test_canonical_distances_are_area_distances(basis_0):
    """‖ã_y − ã_y'‖ equals the area-L2 distance of the squared kernels (no truncation)."""
    b = basis_0.truncate(8)
    C = np.eye(8)
    e1, e2, info = extended_embeddings(C, b, b, rtol=1e-12, point="closed_form")
    assert info["dim"] == 1 + 7 + 28  # full rank, unique products
    t = info["t"]
    w = np.exp(-b.evals * t)
    ys = [5, 900, 3000]
    h2 = ((b.vecs * w) @ b.vecs[ys].T) ** 2  # (n, 3)
    for i, j in [(0, 1), (1, 2)]:
        d_fun = np.sqrt(np.sum(b.mass * (h2[:, i] - h2[:, j]) ** 2))
        assert np.linalg.norm(e2[ys[i]] - e2[ys[j]]) == pytest.approx(d_fun, rel=1e-6)
    assert np.allclose(e1, e2, atol=1e-9 * np.abs(e2).max())  # identity map transfers exactly


def test_pairs_conventions_agree(basis_0, basis_13):
    """The closed form's canonical coefficients do not depend on the pair convention."""
    rng = np.random.default_rng(4)
    C = pm.fmap_from_p2p(np.arange(basis_13.n), basis_0.truncate(8), basis_13.truncate(10))
    C = C + 0.05 * rng.normal(size=C.shape)
    pu = from_fmap(C, basis_0, basis_13, method="extended_closed_form", pairs="unique")
    po = from_fmap(C, basis_0, basis_13, method="extended_closed_form", pairs="ordered")
    assert np.mean(pu == po) > 0.999  # identical up to floating-point near-ties


def test_from_fmap_bad_inputs(basis_0, basis_13):
    C = np.zeros((10, 8))
    with pytest.raises(ValueError, match="method"):
        from_fmap(C, basis_0, basis_13, method="icp")
    with pytest.raises(ValueError, match="rows of C_12 index shape 2"):
        from_fmap(np.zeros((50, 8)), basis_0, basis_13)
    with pytest.raises(ValueError, match="2D"):
        from_fmap(np.zeros(8), basis_0, basis_13)
    with pytest.raises(TypeError, match="std"):
        from_fmap(C, basis_0, basis_13, method="std", t=1.0)
    with pytest.raises(TypeError, match="unknown"):
        from_fmap(C, basis_0, basis_13, method="extended", time=1.0)
    with pytest.raises(ValueError, match="n_eig"):
        from_fmap(C, basis_0, basis_13, method="extended_closed_form", n_eig=9)  # above min(k1, k2) = 8
    with pytest.raises(ValueError, match="n_eig"):
        from_fmap(C, basis_0, basis_13, method="extended", n_eig=41)  # above the bases' 40 columns
    with pytest.raises(ValueError, match="point"):
        from_fmap(C, basis_0, basis_13, method="extended", point="gauss")
    with pytest.raises(ValueError, match="dtype"):
        from_fmap(C, basis_0, basis_13, method="extended", dtype="float16")
    with pytest.raises(TypeError, match="unknown"):
        from_fmap(C, basis_0, basis_13, method="extended_closed_form", point="heat")
    with pytest.raises(ValueError, match="t must"):
        from_fmap(C, basis_0, basis_13, method="extended", t=-1.0)
    with pytest.raises(TypeError):
        from_fmap(C, basis_0.vecs, basis_13)


@pytest.mark.parametrize("point", ["heat", "delta"])
def test_extended_names_a_full_mass(point):
    """Bases built with mass="full": points as functions on the mesh need lumped masses, and say so (the
    sparse matrix was indexed and failed inside scipy); the standard conversion works."""
    b = pm.eigenbasis(pm.mesh.ellipsoid(2), 20, mass="full")
    with pytest.raises(ValueError, match="lumped"):
        from_fmap(np.eye(8), b, b, "extended", point=point)
    np.testing.assert_array_equal(from_fmap(np.eye(8), b, b), np.arange(b.n))



def test_effective_dimension_and_auto_on_extended_embeddings(basis_0, basis_13, monkeypatch):
    """effective_dimension counts the coordinates that carry the spread; on the extended
    conversion's embeddings (more than KDTREE_MAX_DIM coordinates, a few carry the spread)
    ``auto`` takes the kd-tree and returns the brute force's answer."""
    from prodmaps import p2p

    rng = np.random.default_rng(4)
    assert p2p.effective_dimension(rng.normal(size=(4000, 50))) == pytest.approx(50, rel=0.05)
    assert p2p.effective_dimension(np.c_[rng.normal(size=(100, 1)), np.zeros((100, 9))]) == pytest.approx(1.0)
    assert p2p.effective_dimension(np.ones((5, 3))) == 0.0
    C = rng.normal(size=(40, 30)) * 0.05 + np.eye(40, 30)
    e1, e2, _ = extended_embeddings(C, basis_0.truncate(30), basis_13.truncate(40), point="closed_form")
    assert e1.shape[1] > p2p.KDTREE_MAX_DIM and p2p.effective_dimension(e1) <= p2p.KDTREE_MAX_EFFECTIVE_DIM
    calls = []
    real = p2p._nn_kdtree
    monkeypatch.setattr(p2p, "_nn_kdtree", lambda *a: calls.append(1) or real(*a))
    assert np.array_equal(nearest_neighbors(e2, e1), _brute_force(e2, e1))
    assert len(calls) >= 1  # the kd-tree, alone or checked by the probe (e2 has thousands of rows)
    calls.clear()
    Q, P = rng.normal(size=(50, 60)), rng.normal(size=(80, 60))  # isotropic: the products
    assert np.array_equal(nearest_neighbors(Q, P), _brute_force(Q, P)) and calls == []


@pytest.mark.parametrize("kd_faster", [True, False])
def test_auto_probe_finishes_with_the_faster_method(monkeypatch, kd_faster):
    """Above PROBE_MIN_DIM with enough queries, a kd-tree pick is checked on PROBE_QUERIES queries
    per method (timed) and the faster one answers the rest; the answer is the brute force's
    either way (clock replaced so that both outcomes are exercised)."""
    from prodmaps import p2p

    rng = np.random.default_rng(7)
    P = rng.normal(size=(600, 12)) * np.r_[np.ones(3), 1e-3 * np.ones(9)]  # effective dimension ~3
    Q = rng.normal(size=(4 * p2p.PROBE_QUERIES + 37, 12)) * np.r_[np.ones(3), 1e-3 * np.ones(9)]
    ticks = iter([0.0, 1.0 if kd_faster else 5.0, 3.0 if kd_faster else 6.0])  # t1, t2, t3
    monkeypatch.setattr(p2p, "_clock", lambda: next(ticks))
    used = {"kdtree": [], "gemm": []}
    real_kd, real_mm = p2p._nn_kdtree, p2p._nn_gemm
    monkeypatch.setattr(p2p, "_nn_kdtree", lambda Q_, *a: used["kdtree"].append(len(Q_)) or real_kd(Q_, *a))
    monkeypatch.setattr(p2p, "_nn_gemm", lambda Q_, *a: used["gemm"].append(len(Q_)) or real_mm(Q_, *a))
    assert np.array_equal(nearest_neighbors(Q, P), _brute_force(Q, P))
    s, rest = p2p.PROBE_QUERIES, len(Q) - 2 * p2p.PROBE_QUERIES
    winner, loser = ("kdtree", "gemm") if kd_faster else ("gemm", "kdtree")
    assert used[winner][0] == s and rest in used[winner] and used[loser][0] == s


@pytest.mark.parametrize("method", ["std", "extended", "extended_closed_form"])
def test_from_fmap_on_sampled_vertices_is_the_full_map_sampled(basis_0, basis_13, method):
    b1, b2 = (basis_0.truncate(12), basis_13.truncate(16)) if method != "extended" else (basis_0, basis_13)
    C = np.random.default_rng(2).normal(size=(16, 12))
    full = from_fmap(C, b1, b2, method)  # (n2,)
    ev = np.sort(np.random.default_rng(3).choice(b2.n, 300, replace=False))
    np.testing.assert_array_equal(from_fmap(C, b1, b2, method, vertices=ev), full[ev])
    assert from_fmap(C, b1, b2, method, vertices=ev[:0]).shape == (0,)
    if method != "std":  # the sampled target embedding is the full one's rows (computed on those rows only)
        kw = {"point": "closed_form"} if method == "extended_closed_form" else {}
        e1, e2, _ = extended_embeddings(C, b1, b2, **kw)
        s1, s2, _ = extended_embeddings(C, b1, b2, vertices=ev, **kw)
        assert s2.shape == (ev.size, e2.shape[1]) and np.array_equal(s1, e1)
        tol = 1e-13 if method == "extended_closed_form" else 1e-6  # float32 products by blocks of points
        np.testing.assert_allclose(s2, e2[ev], rtol=0, atol=tol * np.abs(e2).max())
    with pytest.raises(ValueError, match="vertices indices out of range"):
        from_fmap(C, b1, b2, method, vertices=np.array([b2.n]))
    with pytest.raises(ValueError, match="integer"):
        from_fmap(C, b1, b2, method, vertices=ev.astype(float))


# --------------------------------------------- the extended conversion of Section 4.4 (issue 33)
def _ellipsoid_pair():
    """Two small shapes with the same connectivity and simple spectra: an ellipsoid and a smooth
    deformation of it (identity correspondence), 60 eigenpairs each."""
    from prodmaps.mesh import ellipsoid

    m1 = ellipsoid(3)
    v = m1.vertices.copy()
    v = v * np.array([1.1, 0.9, 1.0]) + 0.08 * np.sin(2.0 * v[:, [1, 2, 0]])
    m2 = pm.Mesh(v, m1.faces)
    return pm.eigenbasis(m1, 60), pm.eigenbasis(m2, 60)


def _dense_reference(C, b1, b2, k1, k2, rtol, point="heat"):
    """The extended conversion written out densely with numpy: point functions as full (n, n)
    matrices, Approach B by the SVD of sqrt(A) B D ("euclidean" D: unit Euclidean norm factors),
    the fit a = D V Σ⁻¹ Uᵀ sqrt(A) f, the transfer C~ a and the canonical coefficients Σ Vᵀ D⁻¹ a."""
    def svd_parts(b, k):
        ext = pm.product_basis(b.truncate(k), 2, "unique")
        c = 1.0 / np.linalg.norm(b.vecs[:, :k], axis=0)
        d = np.where(ext.index > 0, c[ext.index], 1.0).prod(axis=1)
        d[0] = c[0]
        U, s, Vt = np.linalg.svd(np.sqrt(b.mass)[:, None] * ext.matrix * d, full_matrices=False)
        r = int(np.sum(s > rtol * s[0]))
        return U[:, :r], s[:r], Vt[:r], d

    def functions(b, t):
        if point == "delta":
            return b.area * np.diag(1.0 / b.mass)
        H = (b.vecs * np.exp(-b.evals * t)) @ b.vecs.T * b.area  # (n, n) area · h_t(x, y), 60 eigenpairs
        return H**2

    t = 1.0 / b1.evals[k1 - 1]
    U1, s1, V1, d1 = svd_parts(b1, k1)
    U2, s2, V2, d2 = svd_parts(b2, k2)
    F1, F2 = functions(b1, t), functions(b2, t * b2.area / b1.area)
    a1 = d1[:, None] * (V1.T @ ((U1.T @ (np.sqrt(b1.mass)[:, None] * F1)) / s1[:, None]))  # (K1, n1)
    Ct = pm.extend_fmap(C, b1.truncate(k1), b2.truncate(k2), order=2, pairs="unique")
    e1 = (s2[:, None] * V2 / d2) @ (Ct @ a1)  # (r2, n1)
    e2 = U2.T @ (np.sqrt(b2.mass)[:, None] * F2)  # (r2, n2) = Σ Vᵀ D⁻¹ of the target functions' fits
    return e1.T / np.sqrt(b2.area), e2.T / np.sqrt(b2.area)


@pytest.mark.parametrize("point", ["heat", "delta"])
def test_extended_equals_dense_computation(point):
    b1, b2 = _ellipsoid_pair()
    k1, k2 = 9, 12
    rng = np.random.default_rng(1)
    C = pm.fmap_from_p2p(np.arange(b2.n), b1.truncate(k1), b2.truncate(k2)) + 0.03 * rng.normal(size=(k2, k1))
    r1, r2 = _dense_reference(C, b1, b2, k1, k2, 1e-3, point)
    e1, e2, info = extended_embeddings(C, b1, b2, point=point, dtype="float64", block_bytes=40_000)  # several blocks
    assert info["n_eig"] == 60 and info["dim"] == r1.shape[1]
    # canonical coordinates are defined up to the singular vectors' signs: compare what the search
    # sees, the distances between every target point and every transferred source point
    D = cdist(r2, r1)  # (n2, n1)
    np.testing.assert_allclose(cdist(e2, e1), D, rtol=0, atol=1e-8 * D.max())
    np.testing.assert_allclose(np.linalg.norm(e1, axis=1), np.linalg.norm(r1, axis=1), rtol=1e-8)
    f1, f2, _ = extended_embeddings(C, b1, b2, point=point)  # float32 products
    np.testing.assert_allclose(cdist(f2, f1), D, rtol=0, atol=1e-5 * D.max())
    assert np.array_equal(from_fmap(C, b1, b2, "extended", point=point, dtype="float64"), _brute_force(r2, r1))
    # the canonical coefficients are area-L2 norms of the fitted functions (Section 4.4)
    F = point_functions(b2, [3, 50], point=point, t=info["t"] * b2.area / b1.area)
    ext = pm.product_basis(b2.truncate(k2), 2, "unique")
    fit = ext.operator("svd", rtol=1e-3).reconstruct(F)
    np.testing.assert_allclose(np.linalg.norm(e2[[3, 50]], axis=1),
                               np.sqrt(b2.mass @ fit**2) / np.sqrt(b2.area), rtol=1e-8)


def test_point_functions_kernel(basis_0):
    """Squared heat kernels from the basis' eigenpairs, unit-area scaled; δ integrates to the area."""
    t = 1.0 / basis_0.evals[29]
    F = point_functions(basis_0, [7, 4000], t=t)
    h = (basis_0.vecs * np.exp(-basis_0.evals * t)) @ basis_0.vecs[[7, 4000]].T  # (n, 2) from 40 eigenpairs
    np.testing.assert_allclose(F, (basis_0.area * h) ** 2, rtol=0, atol=1e-12 * F.max())
    D = point_functions(basis_0, [7], point="delta", t=t)
    assert D[7, 0] * basis_0.mass[7] == pytest.approx(basis_0.area) and np.count_nonzero(D) == 1
    F10 = point_functions(basis_0, [7], t=t, n_eig=10)
    h10 = (basis_0.vecs[:, :10] * np.exp(-basis_0.evals[:10] * t)) @ basis_0.vecs[7, :10]
    np.testing.assert_allclose(F10[:, 0], (basis_0.area * h10) ** 2, rtol=0, atol=1e-12 * F10.max())


def test_extended_is_unit_free(basis_0, basis_13):
    """Scaling either mesh (or both) by 0.01 or 100 gives the same map."""
    rng = np.random.default_rng(0)
    C = pm.fmap_from_p2p(np.arange(basis_13.n), basis_0.truncate(12), basis_13.truncate(16))
    C = C + 0.02 * rng.normal(size=C.shape)
    ev = np.sort(rng.choice(basis_13.n, 400, replace=False))
    p1 = from_fmap(C, basis_0, basis_13, "extended", vertices=ev)
    for s in (0.01, 100.0):
        for s1, s2 in ((1.0, s), (s, s)):
            Cs = C * s2 / s1  # C_12 scales as sqrt(area_2 / area_1)
            p = from_fmap(Cs, basis_0.scaled(s1), basis_13.scaled(s2), "extended", vertices=ev)
            assert np.mean(p == p1) > 0.999, (s1, s2, np.mean(p == p1))


def test_closed_form_is_the_mesh_reading_with_the_maps_own_eigenpairs():
    """Why the closed form cannot beat the standard conversion, as a computation: a kernel built
    from the map's own k eigenpairs lies in the span of their products, and the mesh reading
    with that kernel (fitted exactly: rtol 1e-10) gives the closed form's embeddings up to one
    global factor, hence its map. Only eigenpairs beyond k bring information the products lack."""
    b1, b2 = _ellipsoid_pair()
    k = 10
    rng = np.random.default_rng(2)
    C = pm.fmap_from_p2p(np.arange(b2.n), b1.truncate(k), b2.truncate(k)) + 0.05 * rng.normal(size=(k, k))
    c1, c2, _ = extended_embeddings(C, b1, b2, point="closed_form", rtol=1e-10)
    with pytest.warns(UserWarning, match="closed form"):
        m1, m2, _ = extended_embeddings(C, b1, b2, n_eig=k, rtol=1e-10, dtype="float64")
    g = b2.area**2 / np.sqrt(b2.area)  # unit-area kernels (area·h)² over sqrt(area_2) against h²
    # (the source fit at rtol 1e-10 sees the products' conditioning: agreement to ~1e-6)
    np.testing.assert_allclose(m1, g * c1, rtol=0, atol=1e-5 * np.abs(m1).max())
    np.testing.assert_allclose(m2, g * c2, rtol=0, atol=1e-9 * np.abs(m2).max())
    assert np.mean(_brute_force(m2, m1) == _brute_force(c2, c1)) > 0.99


def test_closed_form_reproduces_the_previous_release(basis_0, basis_13):
    """The closed form is the extended conversion of the releases before issue 33, unchanged: its
    maps on two configurations hash to the values computed with that code (commit cc2b118)."""
    import hashlib

    def digest(p):
        return hashlib.sha256(np.asarray(p, dtype=np.int64).tobytes()).hexdigest()[:16]

    rng = np.random.default_rng(4)
    C = pm.fmap_from_p2p(np.arange(basis_13.n), basis_0.truncate(12), basis_13.truncate(16))
    C = C + 0.05 * rng.normal(size=C.shape)
    assert digest(from_fmap(C, basis_0, basis_13, "extended_closed_form")) == "faff928a3646df91"
    C2 = np.random.default_rng(2).normal(size=(16, 12))
    assert digest(from_fmap(C2, basis_0, basis_13, "extended_closed_form")) == "987aeb3c7451b7d6"


def test_approximate_search_recall_against_exact(basis_0, basis_13):
    """search="approximate" (faiss inverted-file index, candidates re-ranked exactly): on the standard
    conversion of a computed-like map between the two humans (5002 vertices, 40 dimensions), with lists of
    ~32 points and 2 probed (the defaults would scan every list here), it agrees with the exact search on
    at least 99% of vertices (measured 99.7%), a miss is a farther point (never a closer one), and it is
    deterministic."""
    pytest.importorskip("faiss")  # an optional extra; `make venv` installs it ([fast] in the lock file)
    from prodmaps import p2p

    C = pm.fmap_from_p2p(np.arange(basis_13.n), basis_0, basis_13)  # (40, 40) ground truth
    C = C + 0.02 * np.random.default_rng(5).normal(size=C.shape)  # a computed map's kind of error
    Q, P = basis_13.vecs, (basis_0.area / basis_13.area) * (basis_0.vecs @ C.T)
    exact, d_ex = nearest_neighbors(Q, P, return_distance=True)
    approx = p2p._nn_approximate(Q, P, None, list_size=32, nprobe=2)
    recall = float(np.mean(approx == exact))
    assert recall >= 0.99, recall
    assert recall < 1.0  # the index is really approximate at these settings (else the test proves nothing)
    d_ap = np.linalg.norm(Q - P[approx], axis=1)
    assert np.all(d_ap >= d_ex * (1 - 1e-12))  # never closer than the exact nearest
    assert np.all(d_ap[approx != exact] > d_ex[approx != exact])  # a miss is a farther point, not a tie
    np.testing.assert_array_equal(p2p._nn_approximate(Q, P, None, list_size=32, nprobe=2), approx)
    # the defaults (lists of ~512 points: 10 lists here, 4 probed, 16 candidates re-ranked)
    assert np.mean(nearest_neighbors(Q, P, search="approximate") == exact) >= 0.99
    np.testing.assert_array_equal(from_fmap(C, basis_0, basis_13, search="approximate"),
                                  nearest_neighbors(Q, P, search="approximate"))


def test_search_auto_is_exact_below_the_threshold_and_approximate_above(basis_0, basis_13, monkeypatch):
    """search="auto" keeps the exact path below APPROX_MIN_PAIRS (every existing number unchanged) and
    takes the approximate one above it when faiss imports; "approximate" without faiss is an ImportError
    that names the package; "exact" never touches faiss."""
    import sys

    from prodmaps import p2p

    b1, b2 = basis_0.truncate(20), basis_13.truncate(30)
    C = pm.fmap_from_p2p(np.arange(b2.n), b1, b2) + 0.05 * np.random.default_rng(6).normal(size=(30, 20))
    calls = []
    real = p2p._nn_approximate

    def spy(Q, P, block, **kw):
        calls.append(Q.shape[0])
        return real(Q, P, block, **kw)

    monkeypatch.setattr(p2p, "_nn_approximate", spy)
    exact = from_fmap(C, b1, b2, search="exact")
    assert b1.n * b2.n < p2p.APPROX_MIN_PAIRS
    np.testing.assert_array_equal(from_fmap(C, b1, b2), exact)  # auto, small: exact, bit for bit
    assert calls == []
    monkeypatch.setattr(p2p, "APPROX_MIN_PAIRS", b1.n * b2.n - 1)  # this pair counts as large
    if p2p.have_faiss():
        got = from_fmap(C, b1, b2)
        assert calls == [b2.n] and np.mean(got == exact) >= 0.99
    calls.clear()
    monkeypatch.setitem(sys.modules, "faiss", None)  # not installed
    assert not p2p.have_faiss()
    np.testing.assert_array_equal(from_fmap(C, b1, b2), exact)  # auto without faiss: exact
    assert calls == []
    with pytest.raises(ImportError, match="pip install faiss-cpu"):
        from_fmap(C, b1, b2, search="approximate")
    with pytest.raises(ImportError, match="pip install faiss-cpu"):
        nearest_neighbors(b2.vecs[:, :20], b1.vecs, search="approximate")
    with pytest.raises(ValueError, match="search must be one of"):
        from_fmap(C, b1, b2, search="ivf")
    with pytest.raises(ValueError, match="search must be one of"):
        nearest_neighbors(b2.vecs[:, :20], b1.vecs, search="fast")
