"""The default extended transfer (prodmaps.default_transfer): what holds by construction."""

import numpy as np
import pytest

import prodmaps as pm
from prodmaps.default_transfer import SafeTransfer, isometry_defect, safe_operator


@pytest.fixture(scope="module")
def setting(basis_0, basis_13, human_0):
    b1, b2 = basis_0.truncate(10), basis_13.truncate(12)
    C = pm.fmap_from_p2p(np.arange(b2.n), b1, b2)  # same triangulation: identity correspondence
    return b1, b2, C, human_0.vertices


def test_reduces_exactly_to_the_standard_transfer_when_nothing_passes(setting):
    b1, b2, C, F = setting
    op = SafeTransfer(C, b1, b2, g0=1e-9, l0=1e-9)  # every filter factor below h_min
    assert op.rank == 0
    np.testing.assert_allclose(op(F), pm.transfer(F, C, b1, b2, "std"), rtol=1e-12, atol=1e-12)


def test_heat_kernels_transfer_far_better_with_a_ground_truth_map(basis_0, basis_13):
    # Figure 11's setting: HKS from many eigenfunctions (40), transferred with k = 29 -> 39
    b1, b2 = basis_0.truncate(29), basis_13.truncate(39)
    C = pm.fmap_from_p2p(np.arange(b2.n), b1, b2)  # same triangulation: identity correspondence
    hks = pm.descriptors.hks(basis_0, pm.descriptors.hks_times(basis_0, 4))  # (n, 4), small t first
    e_std = pm.relative_error(pm.transfer(hks, C, b1, b2, "std"), hks, b2.mass)
    e_def = pm.relative_error(pm.transfer(hks, C, b1, b2, "prod"), hks, b2.mass)
    assert e_def[0] < 0.5 * e_std[0]  # the detailed (small-t) kernel: products carry what Φ2 C cannot
    assert np.all(e_def <= e_std + 1e-3)  # the smooth ones: never worse


def test_never_amplifies_and_matches_its_coefficients(setting):
    b1, b2, C, F = setting
    op = safe_operator(C, b1, b2)
    assert op is safe_operator(C, b1, b2)  # cached on the source's product basis
    g = op(F)
    g_std = pm.transfer(F, C, b1, b2, "std")
    # the added part is bounded by ~g0 rho ||r|| (module doc); here far below the residual norm
    r = F - b1.vecs @ b1.project(F)
    add = np.sqrt(np.einsum("ij,ij->j", g - g_std, b2.mass[:, None] * (g - g_std)))
    res = np.sqrt(np.einsum("ij,ij->j", r, b1.mass[:, None] * r))
    rho = np.sqrt(b2.area / b1.area)
    assert np.all(add <= 1.5 * rho * np.sqrt(op.rank) * res)
    # Lemma 2: the transfer is C~ applied to the fit's coefficients in the unique extended basis
    a = op.coefficients(F)
    Ct = pm.extend_fmap(C, b1, b2, order=2, pairs="unique")
    ext2 = pm.product_basis(b2, 2, "unique")
    np.testing.assert_allclose(ext2.evaluate(Ct @ a), g, rtol=1e-9, atol=1e-12 * np.abs(g).max())
    # what the standard transfer carries is never changed: the A2-projection of the output on
    # range(Φ2 C) is the standard transfer, whatever the filter keeps
    U, sv, _ = np.linalg.svd(C, full_matrices=False)
    Q2 = b2.vecs @ U[:, sv > 1e-10 * sv[0]]
    np.testing.assert_allclose(Q2 @ (Q2.T @ (b2.mass[:, None] * g)), g_std, rtol=1e-9, atol=1e-11 * np.abs(g).max())
    assert op.rank > 0 and np.linalg.norm(g - g_std) > 1e-3 * np.linalg.norm(g_std)  # and it does add something


def test_one_function_or_many_and_argument_checks(setting):
    b1, b2, C, F = setting
    op = safe_operator(C, b1, b2)
    np.testing.assert_allclose(op(F[:, 0]), op(F)[:, 0], rtol=1e-10, atol=1e-13)
    with pytest.raises(ValueError, match="shape"):
        op(F[:10])
    with pytest.raises(TypeError, match="unknown parameters"):
        pm.transfer(F, C, b1, b2, "prod", eps=1e-3)
    with pytest.raises(ValueError, match="order=2"):
        pm.transfer(F, C, b1, b2, "prod", order=3)
    with pytest.raises(ValueError, match="g0"):
        SafeTransfer(C, b1, b2, g0=0)
    with pytest.raises(TypeError, match="method='std' takes no"):
        pm.transfer(F, C, b1, b2, "std", rtol=1e-3)


def test_paper_approach_b_is_unchanged_with_an_explicit_threshold(setting):
    b1, b2, C, F = setting
    ext1, ext2 = pm.product_basis(b1), pm.product_basis(b2)
    a = ext1.operator("svd", rtol=1e-3).coefficients(F)
    expected = ext2.evaluate(pm.extend_fmap(C, b1, b2) @ a)
    np.testing.assert_allclose(pm.transfer(F, C, b1, b2, "prod", rtol=1e-3), expected, rtol=1e-12)


def test_isometry_defect_reads_truncation_loss_and_is_unit_free():
    C = np.eye(6)
    C[:, 4] *= 0.8  # 36 % of the squared norm of φ_4's image lost
    d = isometry_defect(C)
    np.testing.assert_allclose(d, [0, 0, 0, 0, 0.36, 0], atol=1e-15)
    # a shape 10x larger in area scales a point map's C by sqrt(10): same defect with the area ratio
    np.testing.assert_allclose(isometry_defect(np.sqrt(10.0) * C, 10.0), d, atol=1e-14)
    # off-diagonal (non-orthogonal) columns count too
    R = np.eye(3)
    R[0, 1] = 0.1
    assert isometry_defect(R)[0] > 0 and isometry_defect(R)[1] > 0


def test_truncation_test_is_the_stated_wiener_factor_and_filters_lost_functions(basis_0, basis_13):
    # the target basis is smaller: the images of three source functions are lost (δ ≈ 1; which
    # three is decided by near-degenerate pairs around φ_9), so directions built
    # from their products carry a large expected error and the truncation test removes them
    b1, b2 = basis_0.truncate(12), basis_13.truncate(9)
    C = pm.fmap_from_p2p(np.arange(b2.n), b1, b2)  # (9, 12)
    with_e = SafeTransfer(C, b1, b2)
    without = SafeTransfer(C, b1, b2, e0=None)
    e0 = with_e.params["e0"]
    np.testing.assert_allclose(with_e.filter, without.filter / (1 + (with_e.error / e0) ** 2), rtol=1e-12)
    np.testing.assert_allclose(with_e.gain, without.gain, rtol=1e-12)
    d = isometry_defect(C, b2.area / b1.area)
    assert (d > 0.9).sum() == b1.k - b2.k and (d[d <= 0.9] < 0.2).all()
    assert with_e.error.max() > 5 * e0 and with_e.rank < without.rank
    with pytest.raises(ValueError, match="e0"):
        SafeTransfer(C, b1, b2, e0=-1.0)


def test_blocks_of_rows_give_the_one_piece_result(setting, monkeypatch):
    """A large target is processed by blocks of rows (one (n2, r) array, no temporaries of that
    size): the same transfer to rounding, the same kept directions."""
    import prodmaps.default_transfer as dt

    b1, b2, C, F = setting
    Cn = C + 0.01 * np.random.default_rng(0).standard_normal(C.shape)  # some directions filtered out
    one = SafeTransfer(Cn, b1, b2)
    monkeypatch.setattr(dt, "_SINGLE_BLOCK_BYTES", 1)
    monkeypatch.setattr(dt, "_BLOCK_ROWS", 997)  # uneven blocks, the last one short
    blk = SafeTransfer(Cn, b1, b2)
    assert blk.rank == one.rank and 0 < one.rank < one.sigma.size
    np.testing.assert_allclose(blk.gain, one.gain, rtol=1e-10)
    np.testing.assert_allclose(blk.leak, one.leak, rtol=1e-10, atol=1e-14)
    np.testing.assert_allclose(blk(F), one(F), rtol=1e-10, atol=1e-12 * np.abs(one(F)).max())
