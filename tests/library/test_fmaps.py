"""Functional maps: ground truth, the NO17 energy (gradient, fixed first column, sizes), ZoomOut."""

import numpy as np
import pytest

import prodmaps as pm
from prodmaps import fmaps
from prodmaps.p2p import from_fmap


@pytest.fixture(scope="module")
def demo(human_0, human_13):
    """Bases with 60 columns and the NO17 demo descriptors (5 landmarks) on 000 -> 013."""
    b1, b2 = pm.eigenbasis(human_0, 60), pm.eigenbasis(human_13, 60)
    lm = fmaps.farthest_point_landmarks(human_0.vertices, 5)
    d1, d2 = fmaps.no17_demo_descriptors(b1, b2, lm, n_descr=30, subsample_step=5, k_descr=60)
    return b1, b2, d1, d2, lm


def _rel_fd_error(terms, C, rng, n_dir=4, h=1e-6):
    """Max relative error of the analytic directional derivative vs central differences."""
    _, G = fmaps.energy_and_gradient(C, terms)
    errs = []
    for _ in range(n_dir):
        D = rng.normal(size=C.shape)
        num = (fmaps.energy_and_gradient(C + h * D, terms)[0] - fmaps.energy_and_gradient(C - h * D, terms)[0]) / (
            2 * h
        )
        ana = float(np.sum(G * D))
        errs.append(abs(num - ana) / abs(ana))
    return max(errs)


@pytest.mark.parametrize("lap", ["resolvent", "eigdiff"])
@pytest.mark.parametrize("normalize", ["expected", "sum", None])
def test_gradient_matches_finite_differences(demo, lap, normalize):
    b1, b2, d1, d2, _ = demo
    terms = fmaps.no17_terms(b1.truncate(8), b2.truncate(12), d1, d2, lap=lap, normalize=normalize)
    rng = np.random.default_rng(0)
    C = rng.normal(size=(12, 8)) * 0.3
    assert terms.shape == (12, 8)
    assert _rel_fd_error(terms, C, rng) < 1e-5


@pytest.mark.parametrize("weights", [(1, 0, 0), (0, 1, 0), (0, 0, 1)])
def test_each_term_gradient(demo, weights):
    b1, b2, d1, d2, _ = demo
    w_descr, w_lap, w_dcomm = weights
    terms = fmaps.no17_terms(b1.truncate(10), b2.truncate(7), d1, d2, w_descr=w_descr, w_lap=w_lap, w_dcomm=w_dcomm)
    rng = np.random.default_rng(1)
    assert _rel_fd_error(terms, rng.normal(size=(7, 10)), rng) < 1e-5


def test_terms_match_their_definitions(demo):
    b1, b2, d1, d2, _ = demo
    k1, k2 = 9, 11
    B1, B2 = b1.truncate(k1), b2.truncate(k2)
    rng = np.random.default_rng(2)
    C = rng.normal(size=(k2, k1))
    # Laplacian term, eigdiff form, no normalisation: ½‖Λ2 C − C Λ1‖²
    t = fmaps.no17_terms(B1, B2, d1, d2, w_descr=0, w_lap=1, w_dcomm=0, lap="eigdiff", normalize=None)
    E, _ = fmaps.energy_and_gradient(C, t)
    ref = 0.5 * np.sum((np.diag(B2.evals) @ C - C @ np.diag(B1.evals)) ** 2)
    assert E == pytest.approx(ref, rel=1e-12)
    # descriptor + commutativity terms, explicit projections of the area-normalised descriptors
    n1 = d1 / np.sqrt(np.sum(B1.mass[:, None] * d1**2, axis=0))
    n2 = d2 / np.sqrt(np.sum(B2.mass[:, None] * d2**2, axis=0))
    A, B = B1.vecs.T @ (B1.mass[:, None] * n1), B2.vecs.T @ (B2.mass[:, None] * n2)
    t = fmaps.no17_terms(B1, B2, d1, d2, w_descr=1, w_lap=0, w_dcomm=0, normalize=None)
    assert fmaps.energy_and_gradient(C, t)[0] == pytest.approx(0.5 * np.sum((C @ A - B) ** 2), rel=1e-12)
    t = fmaps.no17_terms(B1, B2, d1, d2, w_descr=0, w_lap=0, w_dcomm=1, normalize=None)
    ref = 0.0
    for q in range(d1.shape[1]):
        M1 = B1.vecs.T @ (B1.mass[:, None] * n1[:, q:q + 1] * B1.vecs)
        M2 = B2.vecs.T @ (B2.mass[:, None] * n2[:, q:q + 1] * B2.vecs)
        ref += 0.5 * np.sum((C @ M1 - M2 @ C) ** 2)
    assert fmaps.energy_and_gradient(C, t)[0] == pytest.approx(ref, rel=1e-10)


def test_resolvent_mask_bounded_and_null_on_equal_eigenvalues():
    lam = np.array([0.0, 1.0, 2.0, 5.0])
    L = fmaps.laplacian_mask(lam, lam, "resolvent")
    assert L.shape == (4, 4)
    assert np.allclose(np.diag(L), 0.0)
    assert np.all(L[~np.eye(4, dtype=bool)] > 0)
    assert L.max() <= 4.0
    assert np.allclose(fmaps.laplacian_mask(lam, lam[:3] + 1, "eigdiff"), (lam[None, :] - lam[:3, None] - 1) ** 2)


def test_first_column_from_area_ratio(human_0):
    """C[0,0] = sqrt(area_2/area_1), C[1:,0] = 0 for any point map (derivation in fmaps doc)."""
    big = pm.Mesh(2.0 * human_0.vertices, human_0.faces)  # area x 4
    b1, b2 = pm.eigenbasis(human_0, 12), pm.eigenbasis(big, 15)
    rng = np.random.default_rng(3)
    p2p = rng.integers(0, human_0.n_vertices, size=big.n_vertices)
    C = pm.fmap_from_p2p(p2p, b1, b2)
    col = fmaps.first_column(b1, b2)
    assert col[0] == pytest.approx(2.0, rel=1e-12)
    assert np.allclose(C[:, 0], col, atol=1e-12)


def test_fit_fixes_first_column_and_is_rectangular(demo):
    b1, b2, d1, d2, _ = demo
    C, info = fmaps.fit_no17(b1.truncate(10), b2.truncate(14), d1, d2, return_info=True)
    assert C.shape == (14, 10)
    assert C[0, 0] == pytest.approx(np.sqrt(b2.area / b1.area), rel=1e-15)
    assert np.all(C[1:, 0] == 0.0)
    assert info["success"]
    # at the optimum the gradient of the free columns is small compared with its value at C = 0; the
    # fit runs on the unit-area shapes, whose map is C / sqrt(area_2 / area_1)
    u1, u2 = (b.truncate(k).scaled(1 / np.sqrt(b.area)) for b, k in ((b1, 10), (b2, 14)))
    terms = fmaps.no17_terms(u1, u2, d1, d2)
    C = C / np.sqrt(b2.area / b1.area)
    C0 = np.zeros((14, 10))
    C0[:, 0] = C[:, 0]
    g_opt = np.abs(fmaps.energy_and_gradient(C, terms)[1][:, 1:]).max()
    g_0 = np.abs(fmaps.energy_and_gradient(C0, terms)[1][:, 1:]).max()
    assert g_opt < 1e-3 * g_0


def test_weights_only_matter_through_ratios(demo):
    b1, b2, d1, d2, _ = demo
    C1 = fmaps.fit_no17(b1.truncate(8), b2.truncate(8), d1, d2, w_descr=1, w_lap=1e-2, w_dcomm=1e-1)
    C2 = fmaps.fit_no17(b1.truncate(8), b2.truncate(8), d1, d2, w_descr=10, w_lap=1e-1, w_dcomm=1)
    # normalised weights equal up to the last bit (1/1.11 vs 10/11.1): same map to round-off
    np.testing.assert_allclose(C1, C2, rtol=0, atol=1e-10)


def test_fit_on_identical_shapes_gives_accurate_map(human_0):
    b = pm.eigenbasis(human_0, 60)
    lm = fmaps.farthest_point_landmarks(human_0.vertices, 5)
    d, _ = fmaps.no17_demo_descriptors(b, b, lm, n_descr=50, subsample_step=5, k_descr=60)
    C = fmaps.fit_no17(b.truncate(20), b.truncate(20), d, d)
    C_true = np.eye(20)
    assert np.linalg.norm(C - C_true) < 0.2 * np.linalg.norm(C_true)
    p2p = from_fmap(C, b, b)
    err = np.linalg.norm(human_0.vertices[p2p] - human_0.vertices, axis=1) / np.sqrt(human_0.area)
    assert err.mean() < 0.03


def test_bad_inputs(demo):
    b1, b2, d1, d2, _ = demo
    with pytest.raises(ValueError, match="rows"):
        fmaps.no17_terms(b1, b2, d1[:-1], d2)
    with pytest.raises(ValueError, match="same number of columns"):
        fmaps.no17_terms(b1, b2, d1, d2[:, :-1])
    with pytest.raises(NotImplementedError):
        fmaps.no17_terms(b1, b2, d1, d2, w_orient=1.0)
    with pytest.raises(ValueError, match="lap"):
        fmaps.no17_terms(b1, b2, d1, d2, lap="cot")
    with pytest.raises(ValueError, match="weights"):
        fmaps.no17_terms(b1, b2, d1, d2, w_descr=-1)
    with pytest.raises(ValueError, match="normalize"):
        fmaps.no17_terms(b1, b2, d1, d2, normalize="max")
    with pytest.raises(ValueError, match="init"):
        fmaps.fit_no17(b1.truncate(5), b2.truncate(5), d1, d2, init="random")
    with pytest.raises(ValueError, match="zero"):
        fmaps.no17_terms(b1, b2, np.zeros_like(d1), d2)


def test_demo_descriptors_layout(demo):
    b1, b2, _, _, lm = demo
    E = 30  # energies (more than 2 * margin * variance = 28, so the energy range is not empty)
    d1, d2 = fmaps.no17_demo_descriptors(b1, b2, lm, n_descr=E, subsample_step=1, k_descr=60)
    assert d1.shape == (b1.n, E * 6) and d2.shape == (b2.n, E * 6)
    # the WKS is the diagonal of the wave-kernel map: WKS_e(l) == map_{l,e}(l)
    for j, l in enumerate(lm):
        assert np.allclose(d1[l, :E], d1[l, E * (j + 1):E * (j + 2)], rtol=1e-12)
    # the package's one WKS: the first block is prodmaps.descriptors.wks with the automatic energies
    energies, sigma = pm.descriptors.wks_energies(b1.truncate(60), E)
    np.testing.assert_allclose(d1[:, :E], pm.descriptors.wks(b1.truncate(60), energies, sigma), rtol=1e-12)
    sub, _ = fmaps.no17_demo_descriptors(b1, b2, lm, n_descr=E, subsample_step=5, k_descr=60)
    # the kept columns only are computed (one product whose rounding depends on how many columns
    # the BLAS kernel sees): the same columns to rounding, not bit for bit
    assert sub.shape == d1[:, ::5].shape
    np.testing.assert_allclose(sub, d1[:, ::5], rtol=1e-12, atol=1e-14 * np.abs(d1).max())
    with pytest.raises(ValueError, match="empty energy range"):
        fmaps.no17_demo_descriptors(b1, b2, lm, n_descr=12, k_descr=60)


def test_zoomout_keeps_exact_maps_and_grows(human_0):
    b = pm.eigenbasis(human_0, 30)
    C = pm.fmap_from_p2p(np.arange(b.n), b.truncate(10), b.truncate(10))
    C_zo, p2p = fmaps.zoomout(C, b, b, 25, step=3, return_p2p=True)
    assert C_zo.shape == (25, 25)
    assert np.array_equal(p2p, np.arange(b.n))
    assert np.allclose(C_zo, np.eye(25), atol=1e-10)
    C_r = fmaps.zoomout(C, b, b, (30, 20), step=4)
    assert C_r.shape == (30, 20)
    with pytest.raises(ValueError, match="exceeds"):
        fmaps.zoomout(C, b, b, 31)
    with pytest.raises(ValueError, match="smaller"):
        fmaps.zoomout(C, b, b, 5)


def test_zoomout_reports_progress(human_0, capsys):
    b = pm.eigenbasis(human_0, 20)
    C = pm.fmap_from_p2p(np.arange(b.n), b.truncate(10), b.truncate(10))
    C_p = fmaps.zoomout(C, b, b, 20, step=5, progress=True)  # 10 -> 15 -> 20: three conversions
    err = capsys.readouterr().err
    assert "zoomout" in err and "3/3" in err
    assert np.array_equal(C_p, fmaps.zoomout(C, b, b, 20, step=5, progress=False))
    assert capsys.readouterr().err == ""  # off: silent; default on a short run (not a terminal): silent
    fmaps.zoomout(C, b, b, 20, step=5)
    assert capsys.readouterr().err == ""


def test_zoomout_improves_a_coarse_computed_map(demo, human_0):
    b1, b2, d1, d2, _ = demo
    C = fmaps.fit_no17(b1.truncate(12), b2.truncate(12), d1, d2)
    idn = np.arange(b2.n)
    err = lambda p: np.mean(np.linalg.norm(human_0.vertices[p] - human_0.vertices[idn], axis=1))  # noqa: E731
    e0 = err(from_fmap(C, b1, b2))
    e1 = err(fmaps.zoomout(C, b1, b2, 40, step=7, return_p2p=True)[1])
    assert e1 < e0


def test_quadratic_form_matches_energy_and_gradient(demo):
    b1, b2, d1, d2, _ = demo
    terms = fmaps.no17_terms(b1.truncate(8), b2.truncate(10), d1, d2)
    H, b = fmaps.quadratic_form(terms)
    C = np.random.default_rng(3).normal(size=(10, 8))
    E, G = fmaps.energy_and_gradient(C, terms)
    E0, _ = fmaps.energy_and_gradient(np.zeros_like(C), terms)
    np.testing.assert_allclose(H @ C.ravel() - b, G.ravel(), rtol=0, atol=1e-12 * np.abs(G).max())
    assert abs(0.5 * C.ravel() @ H @ C.ravel() - b @ C.ravel() + E0 - E) < 1e-12 * abs(E)


def test_quadratic_form_with_non_symmetric_operators(demo):
    """The form's shortcut for symmetric multiplication operators (Σ M2ᵀ ⊗ M1ᵀ = Σ M2 ⊗ M1) must
    not be taken for general operators: the gradient still matches with random non-symmetric M."""
    from dataclasses import replace

    b1, b2, d1, d2, _ = demo
    terms = fmaps.no17_terms(b1.truncate(8), b2.truncate(10), d1, d2)
    rng = np.random.default_rng(5)
    bent = replace(terms, M1=rng.normal(size=terms.M1.shape), M2=rng.normal(size=terms.M2.shape))
    C = rng.normal(size=(10, 8))
    _, G = fmaps.energy_and_gradient(C, bent)
    H, b = fmaps.quadratic_form(bent)
    np.testing.assert_allclose(H @ C.ravel() - b, G.ravel(), rtol=0, atol=1e-12 * np.abs(G).max())
    # operators as built by no17_terms are exactly symmetric, and then the general formula's second
    # product is bit for bit its first: the shortcut changes no number
    M1, M2, p = terms.M1, terms.M2, terms.M1.shape[0]
    assert np.array_equal(M1, M1.transpose(0, 2, 1)) and np.array_equal(M2, M2.transpose(0, 2, 1))
    X = M2.reshape(p, -1).T @ M1.reshape(p, -1)
    Xt = M2.transpose(0, 2, 1).reshape(p, -1).T @ M1.transpose(0, 2, 1).reshape(p, -1)
    assert np.array_equal(X, Xt)


def test_direct_solver_is_the_exact_minimiser(demo):
    b1, b2, d1, d2, _ = demo
    B1, B2 = b1.truncate(8), b2.truncate(10)
    C_dir = fmaps.fit_no17(B1, B2, d1, d2, solver="direct")
    C_lbfgs = fmaps.fit_no17(B1, B2, d1, d2, factr=10, pgtol=1e-13)
    np.testing.assert_allclose(C_dir[:, 0], fmaps.first_column(B1, B2, 10), rtol=1e-15, atol=0)
    # both solve the unit-area problem (fit_no17's units); compare there
    r = np.sqrt(B2.area / B1.area)
    terms = fmaps.no17_terms(B1.scaled(1 / np.sqrt(B1.area)), B2.scaled(1 / np.sqrt(B2.area)), d1, d2)
    C_dir, C_lbfgs = C_dir / r, C_lbfgs / r
    E_dir, G_dir = fmaps.energy_and_gradient(C_dir, terms)
    assert np.abs(G_dir[:, 1:]).max() < 1e-10  # stationary in the free columns
    assert E_dir <= fmaps.energy_and_gradient(C_lbfgs, terms)[0] + 1e-14
    assert np.linalg.norm(C_dir - C_lbfgs) < 1e-5 * np.linalg.norm(C_dir)


def test_frobenius_normalisation_and_source_descriptor_norms(demo):
    b1, b2, d1, d2, _ = demo
    B1, B2 = b1.truncate(8), b2.truncate(10)
    t = fmaps.no17_terms(B1, B2, d1, d2, lap="eigdiff", normalize="frobenius")
    assert t.taus[0] == 1.0 and t.taus[2] == 1.0
    assert np.isclose(t.taus[1], np.sum(t.L**2), rtol=1e-14) and t.taus[1] != np.sum(t.L)
    s = fmaps.no17_terms(B1, B2, d1, d2, normalize=None, normalize_descr="source")
    n1 = np.sqrt(np.einsum("nq,nq->q", d1, b1.mass[:, None] * d1))  # the source norms divide both shapes
    np.testing.assert_allclose(s.D1, B1.project(d1 / n1), rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(s.D2, B2.project(d2 / n1), rtol=1e-12, atol=1e-14)
    own = fmaps.no17_terms(B1, B2, d1, d2, normalize=None)  # each shape its own norms: D2 differs
    assert not np.allclose(own.D2, s.D2, rtol=1e-6)
    with pytest.raises(ValueError, match="normalize_descr"):
        fmaps.no17_terms(B1, B2, d1, d2, normalize_descr="target")


def test_demo_descriptors_per_shape_counts_and_unscaled_filter(demo):
    b1, b2, _, _, lm = demo
    a1, a2 = fmaps.no17_demo_descriptors(b1, b2, lm, n_descr=30, subsample_step=5, k_descr=(20, 40))
    r1, _ = fmaps.no17_demo_descriptors(b1, b2, lm, n_descr=30, subsample_step=5, k_descr=20)
    _, r2 = fmaps.no17_demo_descriptors(b1, b2, lm, n_descr=30, subsample_step=5, k_descr=40)
    assert np.array_equal(a1, r1) and np.array_equal(a2, r2) and not np.allclose(a1, r2[: a1.shape[0]])
    u1, _ = fmaps.no17_demo_descriptors(b1, b2, lm, n_descr=30, subsample_step=1, k_descr=20, scaled=False)
    s1, _ = fmaps.no17_demo_descriptors(b1, b2, lm, n_descr=30, subsample_step=1, k_descr=20)
    ratio = u1[:, :30] / s1[:, :30]  # WKS columns (positive): one factor per energy (the filter's sum)
    assert np.all(ratio > 0) and np.allclose(ratio, ratio[:1], rtol=1e-10)
    assert not np.allclose(ratio[0], 1.0)
    np.testing.assert_allclose(u1[:, 30:60], s1[:, 30:60] * ratio[:1], rtol=1e-9, atol=1e-12)  # same factors
    with pytest.raises(ValueError, match="k_descr"):
        fmaps.no17_demo_descriptors(b1, b2, lm, k_descr=(10, 20, 30))


def test_icp_refine_recovers_the_identity_and_returns_partial_isometries(human_0):
    b = pm.eigenbasis(human_0, 30)
    B = b.truncate(12)
    rng = np.random.default_rng(1)
    C0 = np.eye(12) + 0.05 * rng.normal(size=(12, 12))  # a slightly wrong self-map
    before = np.mean(from_fmap(C0, B, B) == np.arange(b.n))
    assert before < 0.5  # the initial point map is mostly wrong
    C, p2p = fmaps.icp_refine(C0, B, B, 10, return_p2p=True)
    assert np.array_equal(p2p, np.arange(b.n))
    np.testing.assert_allclose(C, np.eye(12), atol=1e-10)
    B2 = b.truncate(16)
    R = fmaps.icp_refine(np.eye(16, 12) + 0.05 * rng.normal(size=(16, 12)), B, B2, 2)
    assert R.shape == (16, 12)
    np.testing.assert_allclose(R.T @ R, np.eye(12), atol=1e-12)  # orthonormal columns (k2 > k1)
    W = fmaps.icp_refine(C0, B, B, 1, orthogonal=False)  # the induced map, not orthogonalised
    np.testing.assert_allclose(W, B.project(B.vecs[from_fmap(C0, B, B)]), rtol=1e-12, atol=1e-14)
    assert np.array_equal(fmaps.icp_refine(C0, B, B, 0), C0)
    with pytest.raises(ValueError, match="n_iter"):
        fmaps.icp_refine(C0, B, B, -1)


def test_demo_descriptors_are_kept_per_shape_and_equal_a_fresh_computation(basis_0, basis_13):
    """A second fit from the same source shape reuses its descriptors (the same read-only
    array), and a kept array equals what a new computation gives; other landmarks, another."""
    from prodmaps.fmaps import demo

    lm = np.array([[1, 2], [300, 400], [1000, 900]])
    demo._memo.clear()
    d1, d2 = fmaps.no17_demo_descriptors(basis_0, basis_13, lm, n_descr=40, subsample_step=3, k_descr=30)
    e1, e2 = fmaps.no17_demo_descriptors(basis_0, basis_13, lm, n_descr=40, subsample_step=3, k_descr=30)
    assert e1 is d1 and e2 is d2 and not d1.flags.writeable
    demo._memo.clear()
    f1, f2 = fmaps.no17_demo_descriptors(basis_0, basis_13, lm, n_descr=40, subsample_step=3, k_descr=30)
    np.testing.assert_array_equal(f1, d1)
    np.testing.assert_array_equal(f2, d2)
    g1, _ = fmaps.no17_demo_descriptors(basis_0, basis_13, lm[:2], n_descr=40, subsample_step=3, k_descr=30)
    assert g1 is not d1 and g1.shape[1] < d1.shape[1]
