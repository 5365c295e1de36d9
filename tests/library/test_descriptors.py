"""Tests for prodmaps.descriptors: HKS, WKS, heat kernels, SHOT, AWFT."""

from pathlib import Path

import numpy as np
import pytest

import prodmaps as pm
import prodmaps.descriptors as D
from prodmaps.datasets import dataset_dir as ds_dir
from prodmaps.mesh import icosphere

ROOT = Path(__file__).resolve().parents[1]
ANNY = ds_dir("anny_humans") / "shapes" / "anny_000.ply"


def rigid(mesh: pm.Mesh, seed: int = 3, scale: float = 1.0) -> pm.Mesh:
    rng = np.random.default_rng(seed)
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    if np.linalg.det(q) < 0:
        q[:, 0] *= -1
    return pm.Mesh(scale * mesh.vertices @ q.T + rng.normal(size=3) * 5.0, mesh.faces)


@pytest.fixture(scope="module")
def anny():
    return pm.load_mesh(ANNY)


@pytest.fixture(scope="module")
def anny_moved(anny):
    return rigid(anny)


@pytest.fixture(scope="module")
def sphere():
    return icosphere(3)  # 642 vertices


@pytest.fixture(scope="module")
def sb(sphere):
    return pm.eigenbasis(sphere, 40)


# ----------------------------------------------------------------------------- HKS / WKS / heat kernel
def test_hks_is_heat_kernel_diagonal(sphere, sb):
    b = sb.truncate(30)
    times = D.hks_times(b, 7)
    H = D.hks(b, times)
    assert H.shape == (sphere.n_vertices, 7)
    idx = np.arange(0, sphere.n_vertices, 5)
    for j, t in enumerate(times):
        K = D.heat_kernel(b, idx, t)  # (n, s)
        np.testing.assert_allclose(K[idx, np.arange(idx.size)], H[idx, j], rtol=1e-12)


def test_heat_kernel_symmetric_and_conserves_heat(sphere, sb):
    b = sb
    idx = np.array([0, 10, 100, 300])
    K = D.heat_kernel(b, idx, 0.05)
    assert K.shape == (sphere.n_vertices, 4)
    np.testing.assert_allclose(K[idx], K[idx].T, atol=1e-12)
    # ∫ h_t(x_s, y) dy = 1 (only the constant mode carries mass)
    np.testing.assert_allclose(b.mass @ K, np.ones(4), rtol=1e-10)
    # truncating the basis changes the kernel (test can fail if k is ignored)
    K10 = D.heat_kernel(b.truncate(10), idx, 0.05)
    assert np.abs(K10 - K).max() > 1e-3 * np.abs(K).max()


def test_default_sampling_matches_definitions(sb):
    b = sb.truncate(20)
    t = D.hks_times(b, 5)
    lam = b.evals[1:]
    np.testing.assert_allclose([t[0], t[-1]], [4 * np.log(10) / lam.max(), 4 * np.log(10) / lam.min()])
    np.testing.assert_allclose(np.diff(np.log(t)), np.diff(np.log(t))[0])
    e, sigma = D.wks_energies(b, 100)
    emin, emax = np.log(lam.min()), np.log(lam.max())
    assert sigma == pytest.approx(7 * (emax - emin) / 100)
    assert e[0] == pytest.approx(emin + 2 * sigma) and e[-1] == pytest.approx(emax - 2 * sigma)
    with pytest.raises(ValueError, match="empty energy range"):
        D.wks_energies(b, 10)  # 10 energies cannot hold 2x2 sigma margins with variance 7


def test_wks_scaling_and_formula(sb):
    b = sb.truncate(25)
    e, sigma = D.wks_energies(b, 50)
    W = D.wks(b, e, sigma)
    Wn = D.wks(b, e, sigma, scaled=False)
    lam, phi = b.evals[1:], b.vecs[:, 1:]
    filt = np.exp(-((e[None] - np.log(lam)[:, None]) ** 2) / (2 * sigma**2))  # (k-1, E)
    np.testing.assert_allclose(Wn, phi**2 @ filt, rtol=1e-12)
    np.testing.assert_allclose(W, Wn / filt.sum(0), rtol=1e-12)
    # ∫ WKS dA = 1 for the scaled version (each φ_i² integrates to 1)
    np.testing.assert_allclose(b.mass @ W, 1.0, rtol=1e-10)


def test_hks_wks_exactly_in_product_span(anny):
    b = pm.eigenbasis(anny, 10)
    k = b.k
    l, m = np.triu_indices(k)
    P = b.vecs[:, l] * b.vecs[:, m]  # (n, k(k+1)/2): all φ_l φ_m, l <= m, constant included
    sq = np.sqrt(b.mass)[:, None]
    e, s = D.wks_energies(b, 40)
    for F in (D.hks(b, D.hks_times(b, 5)), D.wks(b, e[::8], s)):
        coef, *_ = np.linalg.lstsq(sq * P, sq * F, rcond=None)
        res = np.linalg.norm(sq * (P @ coef - F), axis=0) / np.linalg.norm(sq * F, axis=0)
        assert res.max() < 1e-10
        # ...whereas the plain basis leaves a residual (this is the point of the paper)
        res_b = np.linalg.norm(sq * (b.vecs @ b.project(F) - F), axis=0) / np.linalg.norm(sq * F, axis=0)
        assert res_b.max() > 1e-3
    # a non-product function is not in the span
    x = anny.vertices[:, :1] ** 3
    coef, *_ = np.linalg.lstsq(sq * P, sq * x, rcond=None)
    assert np.linalg.norm(sq * (P @ coef - x)) / np.linalg.norm(sq * x) > 1e-2


def test_hks_wks_rigid_and_scale_invariance(anny, anny_moved):
    b0 = pm.eigenbasis(anny, 30)
    b1 = pm.eigenbasis(anny_moved, 30)
    s = 2.5
    b2 = pm.eigenbasis(rigid(anny, seed=5, scale=s), 30)
    H0 = D.hks(b0, D.hks_times(b0, 8))
    e0, s0 = D.wks_energies(b0, 40)
    W0 = D.wks(b0, e0, s0)
    for bb, fac in ((b1, 1.0), (b2, s**2)):
        H = fac * D.hks(bb, D.hks_times(bb, 8))
        e, sg = D.wks_energies(bb, 40)
        W = fac * D.wks(bb, e, sg)
        np.testing.assert_allclose(H, H0, rtol=1e-8, atol=1e-8 * np.abs(H0).max())
        np.testing.assert_allclose(W, W0, rtol=1e-8, atol=1e-8 * np.abs(W0).max())
    # unscaled-sampling HKS is NOT scale invariant: the test can tell
    H_fixed = D.hks(b2, D.hks_times(b0, 8))
    assert np.abs(s**2 * H_fixed - H0).max() > 1e-2 * np.abs(H0).max()


@pytest.mark.parametrize(
    "call, match",
    [
        (lambda b: D.hks(b, [0.1, 0.0]), "times must be > 0"),
        (lambda b: D.hks(b, [0.1, -1.0]), "times must be > 0"),
        (lambda b: D.hks(b, [np.nan]), "non-finite"),
        (lambda b: D.hks(b, []), "non-empty"),
        (lambda b: D.wks(b, [1.0], 0.0), "sigma"),
        (lambda b: D.wks(b, [np.inf], 1.0), "non-finite"),
        (lambda b: D.wks(b.truncate(1), [1.0], 1.0), "no non-zero eigenvalue"),
        (lambda b: D.heat_kernel(b, [0, 10_000], 0.1), "vertex indices"),
        (lambda b: D.heat_kernel(b, [0], 0.0), "t must be"),
        (lambda b: D.heat_kernel(b, [0.5], 0.1), "integer"),
        (lambda b: D.hks_times(b, 0), "num"),
    ],
)
def test_spectral_bad_input(sb, call, match):
    b = sb.truncate(10)
    with pytest.raises(ValueError, match=match):
        call(b)


def test_spectral_type_errors(sphere):
    with pytest.raises(TypeError, match="Basis"):
        D.hks(np.zeros((3, 3)), [1.0])
    with pytest.raises(TypeError, match="Mesh"):
        D.shot(np.zeros((3, 3)))


# ----------------------------------------------------------------------------- SHOT
@pytest.fixture(scope="module")
def shot_anny(anny):
    return D.shot(anny)


def test_shot_shape_and_normalisation(anny, shot_anny):
    S = shot_anny
    assert S.shape == (anny.n_vertices, 352) == (anny.n_vertices, D.SHOT_DIM)
    assert np.all(np.isfinite(S)) and np.all(S >= 0)
    np.testing.assert_allclose(np.linalg.norm(S, axis=1), 1.0, rtol=1e-12)
    # descriptors discriminate: rows are not all alike
    assert np.std(S, axis=0).max() > 0.05
    # other layouts give the product of the grid sizes
    S2 = D.shot(anny, n_bins=5, n_azimuth=4, n_elevation=1, n_radial=1, radius_frac=0.05)
    assert S2.shape == (anny.n_vertices, 20)


def test_shot_votes_sum_and_interpolation():
    # a flat grid: every neighbour normal equals the LRF z up to sign -> all mass in the end bins
    xs, ys = np.meshgrid(np.linspace(0, 1, 25), np.linspace(0, 1, 25))
    V = np.stack([xs.ravel(), ys.ravel(), np.zeros(xs.size)], 1)
    idx = np.arange(625).reshape(25, 25)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel()
    F = np.concatenate([np.stack([a, b, d], 1), np.stack([a, d, c], 1)])
    mesh = pm.Mesh(V, F)
    S = D.shot(mesh, radius=0.2)
    H = S.reshape(625, 32, 11).sum(axis=1)  # (n, bins): cosine histogram over all sectors
    assert np.allclose(H[:, 1:-1], 0.0)  # cos = ±1 exactly
    centre = 12 * 25 + 12
    # centre vertex: planar support -> elevation exactly 0 -> votes split equally between hemispheres
    Sc = S[centre].reshape(8, 2, 2, 11)
    np.testing.assert_allclose(Sc[:, 0], Sc[:, 1], atol=1e-12)


def test_shot_rigid_and_scale_invariance(anny, anny_moved, shot_anny):
    for other in (D.shot(anny_moved), D.shot(rigid(anny, seed=7, scale=0.3))):
        diff = np.abs(other - shot_anny).max(axis=1)  # (n,)
        # all but a handful of vertices (a neighbour exactly at distance R) agree to round-off
        assert np.mean(diff > 1e-8) < 0.005
        assert np.median(diff) < 1e-10


def test_shot_bad_input(anny):
    with pytest.raises(ValueError, match="radius"):
        D.shot(anny, radius=-1.0)
    with pytest.raises(ValueError, match="n_bins"):
        D.shot(anny, n_bins=0)
    with pytest.raises(ValueError, match="normals"):
        D.shot(anny, normals=np.full((anny.n_vertices, 3), np.nan))


# ----------------------------------------------------------------------------- curvature / AWFT
def test_principal_curvatures_on_sphere():
    m = icosphere(4, radius=2.0)
    c = pm.curvature.principal_curvatures(m)
    np.testing.assert_allclose(np.median(c["mean"]), 0.5, rtol=0.02)
    np.testing.assert_allclose(np.median(c["gauss"]), 0.25, rtol=0.04)
    assert np.abs(c["mean"] - 0.5).max() < 0.05
    # principal directions are unit and tangent to their face
    fn = np.cross(
        m.vertices[m.faces[:, 1]] - m.vertices[m.faces[:, 0]], m.vertices[m.faces[:, 2]] - m.vertices[m.faces[:, 0]]
    )
    fn /= np.linalg.norm(fn, axis=1, keepdims=True)
    np.testing.assert_allclose(np.linalg.norm(c["dir_max"], axis=1), 1.0, rtol=1e-12)
    assert np.abs(np.einsum("ij,ij->i", c["dir_max"], fn)).max() < 1e-10
    assert np.abs(np.einsum("ij,ij->i", c["dir_max"], c["dir_min"])).max() < 1e-10


def test_anisotropic_laplacian_properties(anny):
    W0, A0 = pm.laplacian(anny)
    Wi, Ai = pm.operators.anisotropic_laplacian(anny, 0.7, 0.0)
    assert abs(Wi - W0).max() < 1e-10 * abs(W0).max()  # alpha = 0 is the cotangent Laplacian
    np.testing.assert_allclose(Ai, A0)
    Wa, _ = pm.operators.anisotropic_laplacian(anny, 0.0, 10.0)
    assert abs(Wa - W0).max() > 0.1 * abs(W0).max()
    assert abs(Wa - Wa.T).max() == 0
    np.testing.assert_allclose(Wa @ np.ones(anny.n_vertices), 0.0, atol=1e-9 * abs(Wa).max())
    x = np.random.default_rng(0).normal(size=(anny.n_vertices, 5))
    assert np.all(np.einsum("ij,ij->j", x, Wa @ x) > 0)  # PSD (on random vectors)
    # rotating by π gives the same operator (D depends on w wᵀ)
    Wpi, _ = pm.operators.anisotropic_laplacian(anny, np.pi, 10.0)
    assert abs(Wpi - Wa).max() < 1e-10 * abs(Wa).max()


AWFT_KW = dict(k=40)


def test_awft_shape_invariance(anny, anny_moved):
    A0 = D.awft(anny, **AWFT_KW)
    assert A0.shape == (anny.n_vertices, 30)
    assert np.all(np.isfinite(A0)) and np.all(A0 >= 0)
    mass = pm.laplacian(anny)[1]
    np.testing.assert_allclose(mass @ A0**2, mass.sum(), rtol=1e-10)
    # different operators give different columns (anisotropy matters)
    assert np.abs(A0[:, 0] - A0[:, 4]).max() > 1e-3 * A0[:, 0].max()
    for other, _ in ((anny_moved, "rigid"), (rigid(anny, seed=11, scale=3.0), "scaled")):
        A1 = D.awft(other, **AWFT_KW)
        np.testing.assert_allclose(A1, A0, rtol=1e-8, atol=1e-8 * np.abs(A0).max())


def test_awft_options_and_errors(anny):
    A = D.awft(anny, k=20, angles_deg=(0.0, 90.0), include_isotropic=False, taus=(0.01,), freqs0=(3,),
               functions=("constant", "mean_curvature", "hks"))
    assert A.shape == (anny.n_vertices, 1 * 2 * 3)
    with pytest.raises(ValueError, match="functions"):
        D.awft(anny, k=20, functions=("nope",))
    with pytest.raises(ValueError, match="freqs0"):
        D.awft(anny, k=20, taus=(0.01, 0.02), freqs0=(0,))
    with pytest.raises(ValueError, match="k must be"):
        D.awft(anny, k=1)
    with pytest.raises(ValueError, match="taus"):
        D.awft(anny, k=20, taus=(-0.1,), freqs0=(0,))
    with pytest.raises(ValueError, match="alpha"):
        pm.operators.anisotropic_laplacian(anny, 0.0, -1.0)


def test_geometry_vectors_are_cubic_bspline_bands_of_the_squared_eigenfunctions():
    """Band ``j`` (0-based here) weighs ``φ_i²`` by ``β3((λ_i − jΔ)/Δ)``: 2/3 at its centre, 1/6 one
    band away, 0 from two bands on; interior eigenvalues get total weight 1 (partition of unity)."""
    bands = 11
    evals = np.array([0.0, 1.0, 2.5, 4.0, 10.0])  # Δ = 1
    evecs = np.eye(5)  # vertex i carries φ_i only: row i of the result is eigenvalue i's band weights
    G = D.geometry_vectors(evals, evecs, bands=bands)
    assert G.shape == (5, bands)
    np.testing.assert_allclose(G[1, :4], [1 / 6, 2 / 3, 1 / 6, 0.0], atol=1e-15)
    np.testing.assert_allclose(G[2, 1:5], [1 / 48, 23 / 48, 23 / 48, 1 / 48], atol=1e-15)  # halfway
    np.testing.assert_allclose(G[:4].sum(axis=1)[1:], 1.0, atol=1e-14)  # interior: partition of unity
    assert G[0, 0] == pytest.approx(2 / 3) and G[4, -1] == pytest.approx(2 / 3)  # the end bands
    # unit-free: scaling the eigenvalues (the mesh's size) changes nothing; signs of φ do not matter
    np.testing.assert_allclose(D.geometry_vectors(7.0 * evals, -evecs, bands=bands), G, atol=1e-15)


def test_awft_release_signals_and_several_anisotropies(anny, anny_moved, sphere):
    kw = dict(k=30, angles_deg=(45.0, 90.0), taus=(0.002, 0.05), freqs0=(0, 0),
              functions=("geovec3", "geovec4", "shape_index", "fiedler", "constant"), curvature_smooth=3)
    A0 = D.awft(anny, alpha=(100.0, 300.0), **kw)
    assert A0.shape == (anny.n_vertices, 2 * (2 * 2 + 1) * 5)  # taus x (alphas x angles + isotropic) x signals
    assert np.all(np.isfinite(A0)) and np.all(A0 >= 0)
    # one operator list per alpha, in order: the columns of single-alpha runs without the isotropic one
    one = dict(kw, taus=(0.05,), freqs0=(0,), functions=("shape_index",), include_isotropic=False)
    both = D.awft(anny, alpha=(100.0, 300.0), **one)
    np.testing.assert_array_equal(both, np.hstack([D.awft(anny, alpha=a, **one) for a in (100.0, 300.0)]))
    # rigid motions and scaling change nothing (every signal is intrinsic or scale-free)
    for other in (anny_moved, rigid(anny, seed=11, scale=3.0)):
        np.testing.assert_allclose(D.awft(other, alpha=(100.0, 300.0), **kw), A0, rtol=1e-7, atol=1e-7 * A0.max())
    # shape index: +1 on a sphere (convex, nearly umbilic once discretised), the textbook values elsewhere
    from prodmaps.curvature import principal_curvatures, shape_index

    c = principal_curvatures(sphere)
    assert np.all(c["vertex_k_max"] >= c["vertex_k_min"])
    np.testing.assert_allclose(shape_index(c["vertex_k_max"], c["vertex_k_min"]), 1.0, atol=0.02)
    np.testing.assert_allclose(shape_index([1.0, 1.0, 1.0, 2.0, 0.0, 0.0], [1.0, -1.0, 0.0, 2.0, -1.0, 0.0]),
                               [1.0, 0.0, 0.5, 1.0, -0.5, 0.0], atol=1e-15)
    for bad in ("geovec0", "geovec151", "geovec", "shape"):
        with pytest.raises(ValueError, match="functions"):
            D.awft(anny, k=20, functions=(bad,))
    with pytest.raises(ValueError, match="alpha"):
        D.awft(anny, k=20, alpha=(10.0, -1.0))


def test_awft_cache_shares_the_eigenpairs_between_readings_with_the_same_numbers(anny, monkeypatch):
    """With a cache of the mesh, a second reading (other windows, other functions) solves no eigenproblem."""
    from prodmaps.cache import Cache
    from prodmaps.descriptors import windowed_fourier

    calls = []
    solve = windowed_fourier.smallest_eigenpairs
    monkeypatch.setattr(windowed_fourier, "smallest_eigenpairs", lambda *a, **k: calls.append(1) or solve(*a, **k))
    readings = [{}, {"functions": ("mean_curvature",)}, {"taus": (0.001, 0.002, 0.005)},
                {"include_isotropic": False, "functions": ("hks", "constant")}]
    plain = [D.awft(anny, **AWFT_KW, **r) for r in readings]
    assert len(calls) == 4 * 5  # four angles and the isotropic operator (the HKS needs it) per call
    calls.clear()
    cache = Cache(max_entries=16)
    shared = [D.awft(anny, **AWFT_KW, **r, cache=cache) for r in readings]
    assert len(calls) == 5  # once for all four readings
    for a, b in zip(plain, shared):
        assert np.array_equal(a, b)
    calls.clear()
    D.awft(anny, k=30, cache=cache)  # another k: its own eigenpairs
    assert len(calls) == 5
    # every parameter the operators depend on is in the key: the cached result equals a fresh one
    for other in ({"alpha": 3.0}, {"curvature_smooth": 2}, {"angles_deg": (0.0, 30.0)}):
        assert np.array_equal(D.awft(anny, **AWFT_KW, **other, cache=cache), D.awft(anny, **AWFT_KW, **other))


def test_anisotropic_eigenpairs_first_shift_from_weyls_law_with_the_conductivity(anny, monkeypatch):
    """AWFT's anisotropic operators have Weyl area sqrt(1 + α)·area: the shift placed with it is
    accepted at once (one Lanczos run, not two) and gives the eigenpairs of the safe shift."""
    import scipy.sparse.linalg as spla

    from prodmaps.eigensolver import shift, smallest_eigenpairs
    from prodmaps.operators import anisotropic_laplacian

    alpha, k = 10.0, 60
    W, A = anisotropic_laplacian(anny, 0.3, alpha)
    calls = []
    real = spla.eigsh
    monkeypatch.setattr(spla, "eigsh", lambda *a, **kw: calls.append(kw["sigma"]) or real(*a, **kw))
    ev, vecs = smallest_eigenpairs(W, A, k, weyl_area=float(A.sum()) * np.sqrt(1 + alpha))
    assert len(calls) == 1 and calls[0] > 0
    calls.clear()
    ev_area, _ = smallest_eigenpairs(W, A, k)  # Weyl with the plain area: shift too high, solved twice
    assert len(calls) == 2 and calls[1] < 0
    ev_safe, vecs_safe = smallest_eigenpairs(W, A, k, sigma=shift(W, A))
    np.testing.assert_allclose(ev, ev_safe, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(ev_area, ev_safe, rtol=1e-9, atol=1e-9)
    gram = vecs.T @ (A[:, None] * vecs_safe)  # (k, k): same eigenspaces up to sign
    np.testing.assert_allclose(np.abs(np.diag(gram))[:k - 5], 1.0, atol=1e-6)
    with pytest.raises(ValueError, match="weyl_area"):
        smallest_eigenpairs(W, A, k, weyl_area=-1.0)
