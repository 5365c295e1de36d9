"""Eigenbases: A-orthonormality, signs, determinism, errors, the Fourier basis, the one eigensolver."""

from pathlib import Path

import numpy as np
import pytest

import prodmaps as pm

BROKEN = Path(__file__).resolve().parents[1] / "data" / "broken"


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


def test_from_arrays_leaves_the_callers_arrays_writeable():
    """``from_arrays`` keeps a frozen copy: pyFM's ``TriMesh.eigenvectors`` (passed whole) stay writeable."""
    b = pm.eigenbasis(pm.mesh.ellipsoid(2), 6)
    vecs, evals, mass = np.array(b.vecs), np.array(b.evals), np.array(b.mass)
    out = pm.basis.from_arrays(vecs, evals, mass)
    assert vecs.flags.writeable and evals.flags.writeable
    vecs[:, 1] *= -1.0
    np.testing.assert_array_equal(out.vecs, b.vecs)


def test_eigenbasis_is_deterministic(human_0, basis_0):
    again = pm.eigenbasis(human_0, 40)
    np.testing.assert_array_equal(again.vecs[:, :30], basis_0.vecs[:, :30])


@pytest.mark.parametrize("k", [0, -1, 5002, 10**6])
def test_eigenbasis_k_out_of_range(human_0, k):
    with pytest.raises(ValueError, match="out of range"):
        pm.eigenbasis(human_0, k)


def test_eigenbasis_rejects_non_mesh():
    with pytest.raises(TypeError):
        pm.eigenbasis(np.zeros((3, 3)), 2)


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


def test_truncations_share_the_cache_and_find_the_same_product_basis(basis_0):
    a, b = basis_0.truncate(10), basis_0.truncate(10)
    assert a is not b and a.cache is b.cache is basis_0.cache
    assert pm.product_basis(a) is pm.product_basis(b)  # survives truncate(): keyed by k
    assert pm.product_basis(basis_0.truncate(11)) is not pm.product_basis(a)
    fresh = pm.Basis(a.vecs, a.evals, a.mass)  # new arrays, new cache
    assert pm.product_basis(fresh) is not pm.product_basis(a)


def test_one_eigensolver_dense_and_sparse_routes_agree(human_0):
    from prodmaps import eigensolver

    W, A = pm.laplacian(human_0)
    ev_s, V_s = eigensolver.smallest_eigenpairs(W, A, 8)  # n > DENSE_MAX_N: shift-invert Lanczos
    small = W[:1200, :1200]  # a principal block is still PSD-like; compare routes on one problem
    Asmall = A[:1200]
    ev_d, V_d = eigensolver.smallest_eigenpairs(small, Asmall, 5)  # dense LAPACK route
    assert human_0.n_vertices > eigensolver.DENSE_MAX_N >= 1200
    np.testing.assert_allclose(np.einsum("ij,i,ij->j", V_s, A, V_s), 1.0, rtol=1e-12)  # A-normalised
    np.testing.assert_allclose(np.einsum("ij,i,ij->j", V_d, Asmall, V_d), 1.0, rtol=1e-12)
    assert np.all(np.diff(ev_s) >= 0) and abs(ev_s[0]) < 1e-8 * ev_s[-1]
    with pytest.raises(ValueError, match="1 <= k"):
        eigensolver.smallest_eigenpairs(W, A, human_0.n_vertices)
    assert eigensolver.shift(W, A) < 0


def test_eigenbasis_refuses_a_disconnected_mesh_loaded_without_validation():
    from prodmaps.mesh import icosphere

    a, b = icosphere(1), icosphere(1)
    v = np.vstack([a.vertices, b.vertices + 3.0])
    f = np.vstack([a.faces, b.faces + a.n_vertices])
    m = pm.Mesh(v, f, validate=False)
    with pytest.raises(pm.MeshError, match="2 connected components.*largest_component.*load_mesh_repaired"):
        pm.eigenbasis(m, 5)


def test_unreferenced_vertices_error_names_both_fixes():
    from prodmaps.mesh import icosphere

    s = icosphere(1)
    with pytest.raises(pm.MeshError, match="remove_unreferenced_vertices.*load_mesh_repaired"):
        pm.Mesh(np.vstack([s.vertices, [[5.0, 5.0, 5.0]]]), s.faces)


def test_shift_inside_the_spectrum_gives_the_safe_shifts_eigenpairs(human_0, monkeypatch):
    """The default (checked) shift inside the wanted spectrum and the safe shift below 0 give the
    same eigenpairs; a shift too high to return the k smallest is detected and redone safely."""
    from scipy.sparse.linalg import eigsh as real_eigsh

    from prodmaps import eigensolver
    from prodmaps.basis import fix_signs

    W, A = pm.laplacian(human_0)
    k = 60
    ev_safe, V_safe = eigensolver.smallest_eigenpairs(W, A, k, sigma=eigensolver.shift(W, A))
    shifts = []

    def spy(*a, **kw):
        shifts.append(kw["sigma"])
        return real_eigsh(*a, **kw)

    monkeypatch.setattr("scipy.sparse.linalg.eigsh", spy)
    for mid, calls in ((eigensolver.MID_SHIFT, 1), (5.0, 2)):  # 5 x Weyl: far above lambda_k, must fall back
        monkeypatch.setattr(eigensolver, "MID_SHIFT", mid)
        shifts.clear()
        ev, V = eigensolver.smallest_eigenpairs(W, A, k)
        assert len(shifts) == calls and shifts[0] > 0
        np.testing.assert_allclose(ev[1:], ev_safe[1:], rtol=1e-10)
        np.testing.assert_allclose(fix_signs(V[:, 1:]), fix_signs(V_safe[:, 1:]), atol=1e-8 * np.abs(V_safe).max())


def test_fix_signs_settles_mirror_ties_by_index_not_rounding():
    """An odd eigenfunction of a mirror-symmetric shape has +m and -m at mirrored vertices; which
    magnitude is larger is rounding, so the sign must not depend on it (it did with argmax)."""
    from prodmaps.basis import fix_signs
    from prodmaps.mesh import ellipsoid

    V = pm.eigenbasis(ellipsoid(2), 6).vecs[:, 1:]  # (162, 5), odd functions among them
    a = np.abs(V)
    top = a.max(axis=0)
    opposite_tie = [
        j
        for j in range(V.shape[1])
        if np.any((a[:, j] > top[j] * (1 - 1e-12)) & (np.sign(V[:, j]) != np.sign(V[np.argmax(a[:, j]), j])))
    ]
    assert opposite_tie, "the ellipsoid should have an exact mirror tie to test"
    rng = np.random.default_rng(0)
    for _ in range(20):  # perturbations at rounding level reorder the tied magnitudes
        W = V * (1 + 1e-14 * rng.standard_normal(V.shape))
        np.testing.assert_array_equal(np.sign(fix_signs(W)), np.sign(fix_signs(V)))
    # the smallest-index tied entry is the positive one
    F = fix_signs(V)
    for j in opposite_tie:
        i = int(np.flatnonzero(a[:, j] >= top[j] * (1 - 1e-6))[0])
        assert F[i, j] > 0


def test_fix_signs_without_ties_is_the_largest_entry_rule():
    from prodmaps.basis import fix_signs

    rng = np.random.default_rng(1)
    V = rng.standard_normal((500, 8))
    F = fix_signs(V)
    idx = np.argmax(np.abs(V), axis=0)
    assert np.all(F[idx, np.arange(8)] > 0)
    np.testing.assert_array_equal(np.abs(F), np.abs(V))


def test_truncated_and_longer_eigenbases_agree_on_a_symmetric_shape():
    """The doctest's premise: k=4 and the first 4 of k=6 are the same functions with the same signs."""
    from prodmaps.mesh import ellipsoid

    b4, b6 = pm.eigenbasis(ellipsoid(2), 4), pm.eigenbasis(ellipsoid(2), 6)
    np.testing.assert_allclose(b4.vecs, b6.vecs[:, :4], atol=1e-8)


def test_eigenbases_in_worker_processes_equal_eigenbasis_bit_for_bit():
    from prodmaps.basis import eigenbases
    from prodmaps.mesh import ellipsoid

    e = ellipsoid(4)  # 2562 vertices: the sparse (shift-invert Lanczos) route
    meshes = [e, pm.Mesh(e.vertices * [1.0, 1.2, 0.9], e.faces, name="b")]
    serial = [pm.eigenbasis(m, 12) for m in meshes]
    for jobs in (1, 2):
        got = eigenbases(meshes, 12, jobs=jobs)
        for a, b in zip(got, serial):
            np.testing.assert_array_equal(a.vecs, b.vecs)
            np.testing.assert_array_equal(a.evals, b.evals)
            np.testing.assert_array_equal(a.mass, b.mass)
    assert got[1].name == "b"
    with pytest.raises(ValueError, match="jobs"):
        eigenbases(meshes, 12, jobs=0)
    with pytest.raises(TypeError, match="Mesh"):
        eigenbases([meshes[0].vertices], 12)
    with pytest.raises(ValueError, match="out of range"):
        eigenbases(meshes, 10_000, jobs=2)  # the worker's error reaches the caller


def test_cholesky_route_gives_the_superlu_eigenpairs(human_0):
    """The optional sparse Cholesky route (safe shift) and today's SuperLU route (checked shift inside the
    spectrum): eigenvalues to 1e-10 relative, the k-dimensional eigenspaces to 1e-8 (principal angles), and
    with the basis' signs fixed the same vectors to 1e-8; small meshes keep SuperLU under solver="auto"."""
    pytest.importorskip("cholespy")  # an optional extra; `make venv` installs it ([fast] in the lock file)
    from prodmaps import eigensolver

    W, A = pm.laplacian(human_0)
    k = 30
    ev_lu, V_lu = eigensolver.smallest_eigenpairs(W, A, k, solver="superlu")
    ev_ch, V_ch = eigensolver.smallest_eigenpairs(W, A, k, solver="cholesky")
    np.testing.assert_allclose(ev_ch[1:], ev_lu[1:], rtol=1e-10)
    cos = np.linalg.svd(V_lu.T @ (A[:, None] * V_ch), compute_uv=False)  # cosines of the principal angles
    assert cos.min() > 1 - 1e-8 and cos.max() < 1 + 1e-8
    b_lu = pm.eigenbasis(human_0, k, solver="superlu")
    b_ch = pm.eigenbasis(human_0, k, solver="cholesky")
    np.testing.assert_allclose(b_ch.vecs, b_lu.vecs, atol=1e-8 * np.abs(b_lu.vecs).max())
    # auto below CHOLESKY_MIN_N: SuperLU, bit for bit
    assert human_0.n_vertices < eigensolver.CHOLESKY_MIN_N
    b_auto = pm.eigenbasis(human_0, k)
    np.testing.assert_array_equal(b_auto.vecs, b_lu.vecs)
    np.testing.assert_array_equal(b_auto.evals, b_lu.evals)


def test_cholesky_route_chosen_by_size_and_its_fallbacks(human_0, monkeypatch):
    """solver="auto" takes the Cholesky route from CHOLESKY_MIN_N unknowns when cholespy imports, SuperLU
    otherwise; an explicit "cholesky" without cholespy, or with an indefinite shift, is a clear error."""
    import sys

    from prodmaps import eigensolver

    W, A = pm.laplacian(human_0)
    calls = []  # the sizes of the sparse Cholesky factorisations cholespy was asked for
    ev_lu, _ = eigensolver.smallest_eigenpairs(W, A, 8, solver="superlu")
    monkeypatch.setattr(eigensolver, "CHOLESKY_MIN_N", human_0.n_vertices)  # this mesh counts as large
    if eigensolver.have_cholesky():
        import cholespy

        real = cholespy.CholeskySolverD

        def spy(n, *args):
            calls.append(n)
            return real(n, *args)

        monkeypatch.setattr(cholespy, "CholeskySolverD", spy)
        ev, _ = eigensolver.smallest_eigenpairs(W, A, 8)
        assert calls == [human_0.n_vertices]
        np.testing.assert_allclose(ev[1:], ev_lu[1:], rtol=1e-10)
        mid = 0.5 * float(ev_lu[4])  # a shift inside the spectrum: W - sigma A indefinite
        with pytest.raises(ValueError, match="positive definite.*superlu"):
            eigensolver.smallest_eigenpairs(W, A, 8, sigma=mid, solver="cholesky")
        calls.clear()
        ev_mid, _ = eigensolver.smallest_eigenpairs(W, A, 8, sigma=mid)  # auto: tries, falls back to SuperLU
        assert calls == [human_0.n_vertices]
        np.testing.assert_array_equal(ev_mid, eigensolver.smallest_eigenpairs(W, A, 8, sigma=mid, solver="superlu")[0])
    calls.clear()
    monkeypatch.setitem(sys.modules, "cholespy", None)  # not installed
    assert not eigensolver.have_cholesky()
    ev, _ = eigensolver.smallest_eigenpairs(W, A, 8)  # auto: SuperLU
    assert calls == []
    np.testing.assert_array_equal(ev, ev_lu)
    with pytest.raises(ImportError, match="pip install cholespy"):
        eigensolver.smallest_eigenpairs(W, A, 8, solver="cholesky")
    with pytest.raises(ValueError, match="solver must be one of"):
        eigensolver.smallest_eigenpairs(W, A, 8, solver="lu")


def test_lumped_mass_is_the_diagonal_or_the_row_sums():
    from prodmaps.mesh import icosphere

    lumped = pm.eigenbasis(icosphere(2), 6)
    full = pm.eigenbasis(icosphere(2), 6, mass="full")
    assert lumped.mass_is_diagonal and not full.mass_is_diagonal
    assert lumped.lumped_mass is lumped.mass  # no copy
    np.testing.assert_allclose(full.lumped_mass, np.asarray(full.mass.sum(axis=1)).ravel(), rtol=0, atol=0)
    assert full.lumped_mass.shape == (full.n,)
    # the FEM mass's row sums are the barycentric lumped areas
    np.testing.assert_allclose(full.lumped_mass, lumped.mass, rtol=1e-12)
