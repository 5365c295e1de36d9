"""Point maps from functional maps (standard and extended conversions) and back (fmap_from_p2p)."""

import numpy as np
import pytest
from scipy.spatial.distance import cdist

import prodmaps as pm
from prodmaps import neighbors
from prodmaps.p2p import (
    extended_embeddings,
    fmap_from_p2p,
    from_fmap,
    heat_square_coefficients,
    point_functions,
)

# the three conversions of the experiments (name -> from_fmap arguments)
CONVERSIONS = {"std": {"method": "std"}, "extended": {"method": "extended"},
               "closed_form": {"method": "extended", "point": "closed_form"}}


def _brute_force(Q, P):
    """Reference: squared distances by direct differences, first index of the minimum."""
    return np.argmin(cdist(Q, P, "sqeuclidean"), axis=1)


def test_std_matches_its_definition(basis_0, basis_13):
    rng = np.random.default_rng(0)
    C = rng.normal(size=(15, 12))
    p2p = from_fmap(C, basis_0, basis_13, method="std")
    # nearest neighbours as on unit-area shapes: Φ2 against (area_1 / area_2) Φ1 Cᵀ
    ref = np.argmin(cdist(basis_13.vecs[:, :15], (basis_0.area / basis_13.area) * basis_0.vecs[:, :12] @ C.T), axis=1)
    assert p2p.shape == (basis_13.n,)
    assert np.array_equal(p2p, ref)


@pytest.mark.parametrize("conversion", CONVERSIONS)
def test_ground_truth_identity_recovered_exactly(basis_0, conversion):
    k = 12
    C = pm.fmap_from_p2p(np.arange(basis_0.n), basis_0.truncate(k), basis_0.truncate(k))
    assert np.array_equal(from_fmap(C, basis_0, basis_0, **CONVERSIONS[conversion]), np.arange(basis_0.n))


def test_closed_form_identity_rectangular(basis_0):
    """Ground-truth (k2, k1) = (16, 10) map on one shape: the closed form is exact (its kernels
    lie in the span of the first 10 eigenfunctions' products on both sides)."""
    C = pm.fmap_from_p2p(np.arange(basis_0.n), basis_0.truncate(10), basis_0.truncate(16))
    assert C.shape == (16, 10)
    assert np.array_equal(from_fmap(C, basis_0, basis_0, "extended", point="closed_form"), np.arange(basis_0.n))


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
    pu = from_fmap(C, basis_0, basis_13, "extended", point="closed_form", pairs="unique")
    po = from_fmap(C, basis_0, basis_13, "extended", point="closed_form", pairs="ordered")
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
        from_fmap(C, basis_0, basis_13, "extended", point="closed_form", n_eig=9)  # above min(k1, k2) = 8
    with pytest.raises(ValueError, match="n_eig"):
        from_fmap(C, basis_0, basis_13, method="extended", n_eig=41)  # above the bases' 40 columns
    with pytest.raises(ValueError, match="point"):
        from_fmap(C, basis_0, basis_13, method="extended", point="gauss")
    with pytest.raises(ValueError, match="dtype"):
        from_fmap(C, basis_0, basis_13, method="extended", dtype="float16")
    with pytest.raises(ValueError, match="point='closed_form'"):
        from_fmap(C, basis_0, basis_13, method="extended_closed_form")  # the spelling of releases before 0.3
    with pytest.raises(ValueError, match="convention"):
        from_fmap(C, basis_0, basis_13, convention="unit")
    with pytest.raises(ValueError, match="convention='pyfm' is the standard conversion's"):
        from_fmap(C, basis_0, basis_13, "extended", convention="pyfm")
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


@pytest.mark.parametrize("conversion", CONVERSIONS)
def test_from_fmap_on_sampled_vertices_is_the_full_map_sampled(basis_0, basis_13, conversion):
    kw = CONVERSIONS[conversion]
    b1, b2 = (basis_0.truncate(12), basis_13.truncate(16)) if conversion != "extended" else (basis_0, basis_13)
    C = np.random.default_rng(2).normal(size=(16, 12))
    full = from_fmap(C, b1, b2, **kw)  # (n2,)
    ev = np.sort(np.random.default_rng(3).choice(b2.n, 300, replace=False))
    np.testing.assert_array_equal(from_fmap(C, b1, b2, vertices=ev, **kw), full[ev])
    assert from_fmap(C, b1, b2, vertices=ev[:0], **kw).shape == (0,)
    if conversion != "std":  # the sampled target embedding is the full one's rows (computed on those rows only)
        point = {k: v for k, v in kw.items() if k == "point"}
        e1, e2, _ = extended_embeddings(C, b1, b2, **point)
        s1, s2, _ = extended_embeddings(C, b1, b2, vertices=ev, **point)
        assert s2.shape == (ev.size, e2.shape[1]) and np.array_equal(s1, e1)
        tol = 1e-13 if conversion == "closed_form" else 1e-6  # float32 products by blocks of points
        np.testing.assert_allclose(s2, e2[ev], rtol=0, atol=tol * np.abs(e2).max())
    with pytest.raises(ValueError, match="vertices indices out of range"):
        from_fmap(C, b1, b2, vertices=np.array([b2.n]), **kw)
    with pytest.raises(ValueError, match="integer"):
        from_fmap(C, b1, b2, vertices=ev.astype(float), **kw)


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


@pytest.mark.parametrize("point, k1, k2", [("heat", 9, 12), ("delta", 9, 12), ("heat", 38, 40)])
def test_extended_equals_dense_computation(point, k1, k2):
    """Both sides of the Gram matrix: 9/12 products (K = 45, 78) against 642 vertices, and 38/40 (K = 741,
    820: more columns than vertices on the target, the n x n side), by blocks of a few columns."""
    b1, b2 = _ellipsoid_pair()
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


@pytest.mark.parametrize("k", [12, 40])
def test_extended_ordered_pairs_keep_the_operators_span(k):
    """The paper's ordered products (the Gram's K x K side at 12, its n x n side at 40 on 642 vertices):
    the canonical coefficients of a target point are the area norm of its Approach B fit by the library's
    operator of the same ordered basis, and the dimension is that operator's rank."""
    _, b2 = _ellipsoid_pair()
    C = np.eye(k)
    e1, e2, info = extended_embeddings(C, b2, b2, pairs="ordered", dtype="float64", block_bytes=40_000)
    op = pm.product_basis(b2.truncate(k), 2, "ordered").operator("svd", rtol=1e-3)
    assert info["dim"] == op.rank
    F = point_functions(b2, [3, 50, 400], t=info["t"])
    np.testing.assert_allclose(np.linalg.norm(e2[[3, 50, 400]], axis=1),
                               np.sqrt(b2.mass @ op.reconstruct(F) ** 2) / np.sqrt(b2.area), rtol=1e-8)
    np.testing.assert_allclose(e1, e2, rtol=0, atol=1e-8 * np.abs(e2).max())  # the identity map


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
    assert digest(from_fmap(C, basis_0, basis_13, "extended", point="closed_form")) == "faff928a3646df91"
    C2 = np.random.default_rng(2).normal(size=(16, 12))
    assert digest(from_fmap(C2, basis_0, basis_13, "extended", point="closed_form")) == "987aeb3c7451b7d6"


def test_search_auto_is_exact_below_the_threshold_and_approximate_above(basis_0, basis_13, monkeypatch):
    """from_fmap's search="auto" keeps the exact path below APPROX_MIN_PAIRS (every existing number
    unchanged) and takes the approximate one (neighbors.ivf_neighbors) above it when faiss imports;
    "approximate" without faiss is an ImportError that names the package."""
    import sys

    b1, b2 = basis_0.truncate(20), basis_13.truncate(30)
    C = pm.fmap_from_p2p(np.arange(b2.n), b1, b2) + 0.05 * np.random.default_rng(6).normal(size=(30, 20))
    calls = []
    real = neighbors.ivf_neighbors

    def spy(Q, P, **kw):
        calls.append(Q.shape[0])
        return real(Q, P, **kw)

    monkeypatch.setattr(neighbors, "ivf_neighbors", spy)
    exact = from_fmap(C, b1, b2, search="exact")
    assert b1.n * b2.n < neighbors.APPROX_MIN_PAIRS
    np.testing.assert_array_equal(from_fmap(C, b1, b2), exact)  # auto, small: exact, bit for bit
    assert calls == []
    monkeypatch.setattr(neighbors, "APPROX_MIN_PAIRS", b1.n * b2.n - 1)  # this pair counts as large
    if neighbors.have_faiss():
        got = from_fmap(C, b1, b2)
        assert calls == [b2.n] and np.mean(got == exact) >= 0.99
        np.testing.assert_array_equal(from_fmap(C, b1, b2, search="approximate"), got)
    calls.clear()
    monkeypatch.setitem(sys.modules, "faiss", None)  # not installed
    np.testing.assert_array_equal(from_fmap(C, b1, b2), exact)  # auto without faiss: exact
    assert calls == []
    with pytest.raises(ImportError, match="pip install faiss-cpu"):
        from_fmap(C, b1, b2, search="approximate")
    with pytest.raises(ValueError, match="search must be one of"):
        from_fmap(C, b1, b2, search="ivf")


def test_fmap_from_p2p_is_the_pulled_back_projection(basis_0, basis_13):
    """``C_12 = Φ2ᵀ A2 Φ1[p2p_21]`` for any point map, rectangular; the top-level name is this function
    (both conversions live in prodmaps.p2p; the round trip of the identity: test_ground_truth_identity...)."""
    assert pm.fmap_from_p2p is fmap_from_p2p
    p2p = np.random.default_rng(0).permutation(basis_0.n)[: basis_13.n]  # any point map 13 -> 0
    C = fmap_from_p2p(p2p, basis_0.truncate(20), basis_13.truncate(30))  # (30, 20)
    assert C.shape == (30, 20)
    ref = basis_13.vecs[:, :30].T @ (basis_13.mass[:, None] * basis_0.vecs[p2p, :20])
    np.testing.assert_allclose(C, ref, rtol=0, atol=1e-12 * np.abs(ref).max())


def test_std_convention_area_is_exact_on_scaled_shapes_and_pyfm_is_not(basis_0):
    """The same shape scaled (areas 4x and 1/4x): the ground-truth map gives the identity exactly with
    the area convention; pyFM's convention compares deltas at the wrong scale. With equal areas the
    two conventions are the same map."""
    k = 20
    for s in (0.5, 2.0):
        b2 = basis_0.scaled(s)
        C = fmap_from_p2p(np.arange(basis_0.n), basis_0.truncate(k), b2.truncate(k))  # = s·I (up to rounding)
        np.testing.assert_allclose(C, s * np.eye(k), atol=1e-9)
        np.testing.assert_array_equal(from_fmap(C, basis_0, b2), np.arange(basis_0.n))
        assert np.mean(from_fmap(C, basis_0, b2, convention="pyfm") == np.arange(basis_0.n)) < 0.5
        ref = np.argmin(cdist(b2.vecs[:, :k], basis_0.vecs[:, :k] @ C.T), axis=1)  # pyFM's definition
        np.testing.assert_array_equal(from_fmap(C, basis_0, b2, convention="pyfm"), ref)
    C = np.random.default_rng(1).normal(size=(k, k))
    np.testing.assert_array_equal(from_fmap(C, basis_0, basis_0, convention="pyfm"), from_fmap(C, basis_0, basis_0))


def test_extended_conversion_reports_its_progress(capsys):
    """progress=True: a bar on stderr that reaches its total (decompositions, blocks of point functions,
    the search); progress=False and the default on a non-terminal: nothing. The map is the same."""
    import re

    from prodmaps.mesh import ellipsoid

    b = pm.eigenbasis(ellipsoid(3), 40)
    C = pm.fmap_from_p2p(np.arange(b.n), b.truncate(10), b.truncate(12))
    capsys.readouterr()
    quiet = from_fmap(C, b, b, "extended", progress=False)
    assert capsys.readouterr().err == ""
    np.testing.assert_array_equal(from_fmap(C, b, b, "extended"), quiet)  # default, stderr not a terminal
    assert capsys.readouterr().err == ""
    shown = from_fmap(C, b, b, "extended", progress=True, block_bytes=8 * b.n * 100)  # blocks of 100 points
    err = capsys.readouterr().err
    np.testing.assert_array_equal(shown, quiet)
    assert "point map (extended)" in err
    n_steps = 2 + 2 * int(np.ceil(b.n / 100)) + 1  # two frames, source and target blocks, the search
    assert re.search(rf"\b{n_steps}/{n_steps}\b", err), err[-500:]


def test_extended_conversions_from_one_source_reuse_its_work_with_the_same_numbers(basis_0, basis_13):
    """A second map from the same source (its canonical frame and points' coefficients cached in the
    basis) gives exactly the map that fresh bases give, for the unique and the ordered products."""
    rng = np.random.default_rng(8)
    C0 = pm.fmap_from_p2p(np.arange(basis_13.n), basis_0.truncate(12), basis_13.truncate(16))
    C1, C2 = C0 + 0.02 * rng.normal(size=C0.shape), C0 + 0.05 * rng.normal(size=C0.shape)
    ev = np.sort(rng.choice(basis_13.n, 500, replace=False))
    for pairs in ("unique", "ordered"):
        b1 = pm.Basis(basis_0.vecs, basis_0.evals, basis_0.mass)
        b2 = pm.Basis(basis_13.vecs, basis_13.evals, basis_13.mass)
        from_fmap(C1, b1, b2, "extended", pairs=pairs, vertices=ev)  # fills the caches
        again = from_fmap(C2, b1, b2, "extended", pairs=pairs, vertices=ev)
        fresh = from_fmap(C2, pm.Basis(basis_0.vecs, basis_0.evals, basis_0.mass),
                          pm.Basis(basis_13.vecs, basis_13.evals, basis_13.mass), "extended", pairs=pairs, vertices=ev)
        np.testing.assert_array_equal(again, fresh)


@pytest.mark.parametrize("pairs", ["unique", "ordered"])
def test_extended_subspace_iteration_equals_lapacks_eigenpairs(monkeypatch, pairs):
    """Above ``SUBSPACE_MIN_SIZE`` rows the kept eigenpairs of the Gram matrix come from the subspace
    iteration; on 2562 vertices with 60 x 72 products (K = 1830: the source's K x K side; K = 2628: the
    target's n x n side, the Hadamard-square Gram) it gives LAPACK's embeddings: the same dimension and
    the same distances to 1e-8, and LAPACK's eigensolver is not called."""
    from prodmaps import p2p

    m1 = pm.mesh.ellipsoid(4)
    v = m1.vertices * np.array([1.1, 0.9, 1.0]) + 0.08 * np.sin(2.0 * m1.vertices[:, [1, 2, 0]])
    b1, b2 = pm.eigenbasis(m1, 90), pm.eigenbasis(pm.Mesh(v, m1.faces), 90)
    rng = np.random.default_rng(2)
    C = pm.fmap_from_p2p(np.arange(b2.n), b1.truncate(60), b2.truncate(72)) + 0.02 * rng.normal(size=(72, 60))
    ev = np.sort(rng.choice(b2.n, 300, replace=False))
    kw = {"pairs": pairs, "dtype": "float64", "vertices": ev}
    monkeypatch.setattr(p2p, "SUBSPACE_MIN_SIZE", 10**9)
    r1, r2, ref = extended_embeddings(C, b1, b2, **kw)
    monkeypatch.setattr(p2p, "SUBSPACE_MIN_SIZE", 1000)

    def no_lapack(*args, **kwargs):
        raise AssertionError("LAPACK's eigensolver was called")

    monkeypatch.setattr(p2p.sla, "eigh", no_lapack)
    e1, e2, info = extended_embeddings(C, b1, b2, **kw)
    assert info["dim"] == ref["dim"] and 0 < info["dim"] < b2.n // 2
    D = cdist(r2, r1)
    np.testing.assert_allclose(cdist(e2, e1), D, rtol=0, atol=1e-8 * D.max())
    assert np.array_equal(np.argmin(cdist(e2, e1), axis=1), np.argmin(D, axis=1))
