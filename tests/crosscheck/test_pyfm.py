"""Cross-checks against an independent implementation: pyFM (PyPI ``pyfmaps``, checked with 1.3.1).

pyFM uses the same discretisation as prodmaps' defaults: cotangent stiffness and the lumped
(barycentric, a third of each incident triangle) mass, eigenpairs of ``W φ = λ A φ``. These
tests compare eigenvalues, HKS/WKS under matching sampling, the NO17 demo descriptors, and the
NO17 energy, its gradient and the fitted map (pyFM's ``normalize_weights=True`` "canonical"
weighting with the resolvent Laplacian mask equals our ``normalize="expected"``,
``lap="resolvent"``). Optional dependency: the whole module is skipped without pyFM.
"""

import numpy as np
import pytest

import prodmaps as pm
from prodmaps import fmaps

pyFM = pytest.importorskip("pyFM", reason="optional cross-check dependency pyfmaps (pyFM) is not installed")
from pyFM.functional import FunctionalMapping  # noqa: E402
from pyFM.mesh import TriMesh  # noqa: E402

K = 40


@pytest.fixture(scope="module")
def pair(human_0, human_13):
    """The two humans scaled to unit area: prodmaps fits NO17 on unit-area shapes whatever the input
    (:func:`prodmaps.fmaps.fit_no17`), pyFM on the meshes as given, so only there is it the same problem."""
    m1, m2 = (pm.Mesh(m.vertices / np.sqrt(pm.eigenbasis(m, 2).area), m.faces, name=m.name)
              for m in (human_0, human_13))
    tm1 = TriMesh(m1.vertices.copy(), m1.faces.copy())
    tm2 = TriMesh(m2.vertices.copy(), m2.faces.copy())
    tm1.process(K)
    tm2.process(K)
    return m1, m2, tm1, tm2, pm.eigenbasis(m1, K), pm.eigenbasis(m2, K)


def test_operators_and_eigenvalues_agree(pair):
    m1, _, tm1, _, b1, _ = pair
    W, A = pm.laplacian(m1, kind="cotan", mass="lumped")
    assert np.allclose(tm1.mass.diagonal(), A, rtol=1e-12)
    assert abs(W - tm1.stiffness).max() < 1e-10 * abs(W).max()
    ev = np.sort(tm1.eigenvalues)
    assert abs(ev[0]) < 1e-8 * ev[-1]
    assert np.allclose(b1.evals[1:], ev[1:], rtol=1e-8)


def test_hks_wks_agree(pair):
    _, _, tm1, _, b1, _ = pair
    descriptors = pytest.importorskip("prodmaps.descriptors")
    from pyFM.signatures import HKS_functions as H
    from pyFM.signatures import WKS_functions as Wf

    times = descriptors.hks_times(b1, 20)
    ours = descriptors.hks(b1, times, scaled=True)
    theirs = H.HKS(tm1.eigenvalues, tm1.eigenvectors, times, scaled=True)
    assert np.allclose(ours, theirs, rtol=1e-6, atol=1e-9 * np.abs(theirs).max())
    energies, sigma = descriptors.wks_energies(b1, 50)
    ours = descriptors.wks(b1, energies, sigma)
    theirs = Wf.mesh_WKS(tm1, 50, k=K)  # pyFM's automatic sampling
    assert np.allclose(ours, theirs, rtol=1e-6, atol=1e-9 * np.abs(theirs).max())


def test_demo_descriptors_agree(pair):
    m1, m2, tm1, tm2, b1, b2 = pair
    lm = fmaps.farthest_point_landmarks(m1.vertices, 5)
    d1, d2 = fmaps.no17_demo_descriptors(b1, b2, lm, n_descr=30, subsample_step=5, k_descr=K)
    model = FunctionalMapping(tm1, tm2)
    model.compute_spectral_descriptors(n_descr=30, descr_type="WKS", k_descr=K, landmarks=lm, subsample_step=5)
    n1 = d1 / np.sqrt(np.sum(b1.mass[:, None] * d1**2, axis=0))
    assert n1.shape == model.descr1.shape
    assert np.allclose(n1, model.descr1, rtol=1e-6, atol=1e-8 * np.abs(n1).max())


def _pyfm_energy_args(model, k1, k2, w):
    """pyFM's own pieces of the energy (weights normalised, canonical taus, resolvent mask)."""
    from pyFM.optimize.weights import canonical_taus, resolvent_mask

    model._set_k((k1, k2))
    w = np.array(w, float) / np.sum(w)
    D1 = model.mesh1.project(model.descr1, k=k1)
    D2 = model.mesh2.project(model.descr2, k=k2)
    ops = model._compute_descr_op()
    mask = resolvent_mask(model.mesh1.eigenvalues[:k1], model.mesh2.eigenvalues[:k2], gamma=0.5)
    t = canonical_taus(D1, D2, ops, [], mask)
    return (w[0] / t[0], w[1] / t[1], w[2] / t[2], 0.0, D1, D2, ops, [], mask)


def test_no17_energy_and_gradient_agree(pair):
    m1, m2, tm1, tm2, b1, b2 = pair
    from pyFM.optimize.base_functions import energy_and_grad_std

    lm = fmaps.farthest_point_landmarks(m1.vertices, 5)
    d1, d2 = fmaps.no17_demo_descriptors(b1, b2, lm, n_descr=30, subsample_step=5, k_descr=K)
    k1, k2 = 20, 25
    model = FunctionalMapping(tm1, tm2)
    # give pyFM our eigenpairs so that only the energy code differs (its signs differ from ours)
    for mesh, b in ((model.mesh1, b1), (model.mesh2, b2)):
        mesh.eigenvalues, mesh.eigenvectors = b.evals.copy(), b.vecs.copy()
    model.add_descriptors(d1, d2, normalize=True)
    w = (1.0, 1e-2, 1e-1)
    args = _pyfm_energy_args(model, k1, k2, w)
    terms = fmaps.no17_terms(b1.truncate(k1), b2.truncate(k2), d1, d2, w_descr=w[0], w_lap=w[1], w_dcomm=w[2])
    rng = np.random.default_rng(0)
    for _ in range(3):
        C = rng.normal(size=(k2, k1))
        E_ours, G_ours = fmaps.energy_and_gradient(C, terms)
        E_py, G_py = energy_and_grad_std(C.ravel(), *args)
        G_py = G_py.reshape(k2, k1)
        assert E_ours == pytest.approx(E_py, rel=1e-10)
        # pyFM zeroes the gradient of the fixed first column; compare the free columns
        assert np.allclose(G_ours[:, 1:], G_py[:, 1:], rtol=1e-10, atol=1e-12 * np.abs(G_py).max())


def test_no17_fit_agrees(pair):
    """Both optimisers reach the minimum of the same energy, within what their stopping rule allows.

    Two L-BFGS-B runs stopped on ``max|projected gradient| <= pgtol`` (1e-5 in both, scipy's
    meaning) need not have the same iterates: the energy is ill-conditioned (smallest Hessian
    eigenvalue ~3e-4 on the free columns), so both stop ~4e-3 (relative) from the exact minimiser
    and the place where they stop moves with the BLAS kernel (7.7e-4 apart under
    ``OPENBLAS_CORETYPE=Prescott``, 3e-7 under SkylakeX). What both must reach is the optimum: the
    energy is quadratic, ``E(C) - E* = ½ gᵀ H⁻¹ g <= |g|²/(2μ)`` with ``|g|² <= n pgtol²`` at their
    stop, and each map lies within ``sqrt(2 (E - E*)/μ)`` of the exact minimiser ``C*``
    (:func:`prodmaps.fmaps.fit_no17` with ``solver="direct"``).
    """
    m1, m2, tm1, tm2, b1, b2 = pair
    lm = fmaps.farthest_point_landmarks(m1.vertices, 5)
    d1, d2 = fmaps.no17_demo_descriptors(b1, b2, lm, n_descr=30, subsample_step=5, k_descr=K)
    k1 = k2 = 20
    pgtol = 1e-5  # both: pyFM's fit default and fit_no17's
    model = FunctionalMapping(tm1, tm2)
    for mesh, b in ((model.mesh1, b1), (model.mesh2, b2)):
        mesh.eigenvalues, mesh.eigenvectors = b.evals.copy(), b.vecs.copy()
    model.add_descriptors(d1, d2, normalize=True)
    model.fit(K=(k1, k2), w_descr=1.0, w_lap=1e-2, w_dcomm=1e-1, w_orient=0, pgtol=pgtol)
    w = dict(w_descr=1.0, w_lap=1e-2, w_dcomm=1e-1)
    B1, B2 = b1.truncate(k1), b2.truncate(k2)
    C = fmaps.fit_no17(B1, B2, d1, d2, pgtol=pgtol, **w)
    C_star = fmaps.fit_no17(B1, B2, d1, d2, solver="direct", **w)
    assert C[0, 0] == pytest.approx(model.FM_12[0, 0], rel=1e-12)  # the fixed first column
    assert np.allclose(C[:, 0], C_star[:, 0], rtol=0, atol=1e-14) and np.allclose(model.FM_12[:, 0], C[:, 0])
    # the energy fit_no17 minimises: both shapes at unit area (the pair already is, up to rounding)
    ratio = np.sqrt(B2.area / B1.area)
    terms = fmaps.no17_terms(B1.scaled(1 / np.sqrt(B1.area)), B2.scaled(1 / np.sqrt(B2.area)), d1, d2, **w)
    H, _ = fmaps.quadratic_form(terms)
    free = np.ones((k2, k1), dtype=bool)
    free[:, 0] = False
    mu = np.linalg.eigvalsh(H[np.ix_(free.ravel(), free.ravel())])[0]  # strong convexity on the free columns
    n = int(free.sum())
    E_star = fmaps.energy_and_gradient(C_star / ratio, terms)[0]
    gaps = {}
    for name, X in (("ours", C), ("pyFM", model.FM_12)):
        E, G = fmaps.energy_and_gradient(X / ratio, terms)
        # pyFM's map is a stationary point of *our* energy (the cross-check), as its stopping rule says
        assert np.abs(G[free]).max() <= pgtol * (1 + 1e-6), (name, np.abs(G[free]).max())
        gap = E - E_star
        assert -1e-12 * E_star <= gap <= n * pgtol**2 / (2 * mu), (name, gap)  # measured: 1.1e-4 of E*
        # the map is within what that energy gap allows of the exact minimiser (strong convexity)
        assert np.linalg.norm((X - C_star) / ratio) <= np.sqrt(2 * gap / mu) * (1 + 1e-6) + 1e-12, name
        gaps[name] = gap
    # hence the two fits agree within the sum of those radii (measured 3e-7 to 7.7e-4 relative)
    bound = sum(np.sqrt(2 * g / mu) for g in gaps.values()) * ratio
    assert np.linalg.norm(C - model.FM_12) <= bound * (1 + 1e-6) + 1e-12
    assert bound < 0.05 * np.linalg.norm(C_star)  # a meaningful bound: near the minimiser, not anywhere


# ----------------------------------------------------------------------------- pyFM users
def test_pyfm_bases_and_map_go_straight_into_transfer(pair):
    """A pyFM pipeline gains products in three lines: bases from pyFM's arrays, pyFM's FM_12."""
    import pyFM.spectral as spectral

    m1, m2, tm1, tm2, _, _ = pair
    p2p_21 = np.arange(m2.n_vertices)
    FM_12 = spectral.p2p_to_FM(p2p_21, tm1.eigenvectors[:, :10], tm2.eigenvectors[:, :15], A2=tm2.A)  # (15, 10)
    b1 = pm.basis.from_arrays(tm1.eigenvectors[:, :10], tm1.eigenvalues[:10], tm1.vertex_areas)
    b2 = pm.basis.from_arrays(tm2.eigenvectors[:, :15], tm2.eigenvalues[:15], tm2.A)  # sparse diagonal mass too
    assert np.array_equal(pm.fmap_from_p2p(p2p_21, b1, b2), FM_12)  # same convention: FM_12 is our C_12
    assert b1.phi0 < 0 or b1.phi0 > 0  # pyFM's constant may be negative; nothing is re-signed
    f = m1.vertices
    std = pm.relative_error(pm.transfer(f, FM_12, b1, b2, "std"), f[p2p_21], b2.mass)
    prod = pm.relative_error(pm.transfer(f, FM_12, b1, b2, "default"), f[p2p_21], b2.mass)
    # measured: mean 0.312 against 0.336 for std (the default's truncation test keeps only the
    # product directions this 10 -> 15 map carries reliably)
    assert np.all(prod <= std + 1e-12) and prod.mean() < 0.95 * std.mean()


def test_pyfm_arrays_that_break_the_conventions_are_refused(pair):
    _, _, tm1, _, _, _ = pair
    V, ev, a = tm1.eigenvectors[:, :10], tm1.eigenvalues[:10], tm1.vertex_areas
    with pytest.raises(ValueError, match="transposed"):
        pm.basis.from_arrays(V.T, ev, a)
    with pytest.raises(ValueError, match="not constant"):
        pm.basis.from_arrays(V[:, ::-1], ev[::-1], a)
    with pytest.raises(ValueError, match="area inner product"):
        pm.basis.from_arrays(V, ev, np.ones_like(a))  # the Euclidean inner product instead of the area one
    b = pm.basis.from_arrays(V, ev, a)
    with pytest.raises(ValueError, match="shape 1 to shape 2"):
        pm.transfer(np.zeros(b.n), np.zeros((10, 12)), b, b, "default")


def test_pyfm_point_map_convention_is_pyfms_exactly(human_0, human_13):
    """``from_fmap(..., convention="pyfm")`` is pyFM's ``FM_to_p2p`` / ``get_p2p`` for the same bases and map,
    vertex for vertex, on two shapes of unequal area (an embedded human and another one scaled by 0.5: a
    quarter of its area), where the library's default (the area rule) is a different map."""
    import pyFM.spectral as spectral

    k = 30
    small = pm.Mesh(human_13.vertices * 0.5, human_13.faces)
    tm1 = TriMesh(human_0.vertices.copy(), human_0.faces.copy())
    tm2 = TriMesh(small.vertices.copy(), small.faces.copy())
    tm1.process(k)
    tm2.process(k)
    b1 = pm.basis.from_arrays(tm1.eigenvectors[:, :k], tm1.eigenvalues[:k], tm1.vertex_areas)
    b2 = pm.basis.from_arrays(tm2.eigenvectors[:, :k], tm2.eigenvalues[:k], tm2.vertex_areas)
    assert b2.area / b1.area == pytest.approx(0.25, rel=0.02)
    gt = np.arange(small.n_vertices)  # one triangulation: ground truth the identity
    C = spectral.p2p_to_FM(gt, tm1.eigenvectors[:, :k], tm2.eigenvectors[:, :k], A2=tm2.A)  # (k, k)
    C = C + 0.05 * np.linalg.norm(C, 2) / np.sqrt(k) * np.random.default_rng(0).normal(size=C.shape)
    theirs = spectral.FM_to_p2p(C, tm1.eigenvectors, tm2.eigenvectors)
    model = FunctionalMapping(tm1, tm2)
    np.testing.assert_array_equal(model.get_p2p(FM=C), theirs)
    ours = pm.p2p.from_fmap(C, b1, b2, convention="pyfm")
    np.testing.assert_array_equal(ours, theirs)  # 100 %: no ties on these data
    area = pm.p2p.from_fmap(C, b1, b2)  # the default: the shapes compared at unit area
    assert np.mean(area == theirs) < 0.5
    err = {name: np.linalg.norm(human_0.vertices[p] - human_0.vertices[gt], axis=1).mean()
           for name, p in (("area", area), ("pyfm", ours))}
    assert err["area"] < 0.7 * err["pyfm"], err  # the area rule is the better one here (measured 0.5x)


def test_the_readmes_pyfm_snippet_runs_against_pyfm(tmp_path, monkeypatch, human_0, human_13):
    """The README's "Coming from pyFM or geomfum" block, as written, with its two mesh files filled by
    embedded humans: pyFM's FunctionalMapping fit, our bases from the model's meshes, the default
    transfer and pyFM's point map through convention="pyfm"."""
    import re
    from pathlib import Path

    readme = (Path(__file__).resolve().parents[2] / "README.md").read_text(encoding="utf-8")
    blocks = re.findall(r"^```python\n(.*?)^```", readme, flags=re.S | re.M)
    block = next(b for b in blocks if "FunctionalMapping(" in b)
    for name, mesh in (("shape_1.off", human_0), ("shape_2.off", human_13)):
        pm.save_mesh(tmp_path / name, mesh)
    assert '"shape_1.off"' in block and '"shape_2.off"' in block
    ns: dict = {}
    monkeypatch.chdir(tmp_path)  # the block's relative file names
    exec(compile(block, "README.md", "exec"), ns)
    model = ns["model"]
    assert model.FM_12.shape == (30, 30) and ns["b1"].k == 30 and ns["b2"].k == 30
    assert ns["g"].shape == (human_13.n_vertices, 3) and np.all(np.isfinite(ns["g"]))
    np.testing.assert_array_equal(ns["p2p_21"], model.get_p2p())
