"""Transfer operators (prodmaps.transfers): the registry, its methods, the default rule."""

import numpy as np
import pytest
import scipy.sparse as sp

import prodmaps as pm
from prodmaps.mesh import ellipsoid
from prodmaps.p2p import from_fmap
from prodmaps.transfers import (
    DEFAULT_RULE,
    PAPER_RTOL,
    REGISTRY,
    DefaultTransfer,
    PointMapTransfer,
    isometry_defect,
    register,
)
from prodmaps.truncation import select_rtol


@pytest.fixture(scope="module")
def setting(basis_0, basis_13, human_0):
    b1, b2 = basis_0.truncate(10), basis_13.truncate(12)
    C = pm.fmap_from_p2p(np.arange(b2.n), b1, b2)  # same triangulation: identity correspondence
    return b1, b2, C, human_0.vertices


# ------------------------------------------------------------------ the same numbers as before
@pytest.fixture(scope="module")
def small():
    """A perturbed map between bases of 7 and 9 columns on a small ellipsoid, three functions."""
    mesh = ellipsoid(2)
    b1, b2 = pm.eigenbasis(mesh, 7), pm.eigenbasis(mesh, 9)
    C = pm.fmap_from_p2p(np.arange(mesh.n_vertices), b1, b2)
    C = C + 0.05 * np.random.default_rng(3).standard_normal(C.shape)
    x, y, z = mesh.vertices.T
    return b1, b2, C, np.column_stack([x * y, np.exp(z), (x > 0.2).astype(float)])


# column norms, then rows 0, 80 and 161 of pm.transfer(F, C, b1, b2, **old) computed with prodmaps
# 0.2.0 before the transfer operators (the old spellings' numbers, recorded once, OpenBLAS Haswell kernel).
# Other processors run other BLAS kernels, which round differently: Approach B keeps Gram eigenvalues down
# to rtol² = 1e-6 of the largest and ridge regularises at eps = 1e-6, so both amplify rounding by up to
# ~1e6 (SkylakeX against Haswell: 4.7e-10 relative). BEFORE_RTOL covers that with 20x headroom and stays
# four orders below any change of the methods' arithmetic.
BEFORE_RTOL = 1e-8
BEFORE = {
    "std": [1.935746082728675, 14.850740034365884, 7.767302946046483, -0.2620979230237537, 1.1549623964816984,
            -0.0723428515056128, 0.11968881863501617, 0.5701155231481723, 0.35646773226973394,
            0.006075125456303534, 0.712305726198964, -0.16045340452180476],
    "default": [1.9448573994376872, 14.842351285754178, 7.698028221625222, -0.2587601583743205, 1.142844993652034,
                -0.07074581018586865, 0.11246446672378106, 0.5799827825351717, 0.39973867339853897,
                0.0069358498670861485, 0.7104564907379436, -0.14829486726033414],
    "svd": [1.9944478871295126, 14.826227273039299, 12.385006518618768, -0.2533636102728876, 1.1893097899229623,
            -0.2008482772731072, 0.09092483025865142, 0.5436542327606667, 2.63087892751154, 0.006394666700025206,
            0.5689741916613555, 0.07950928880084418],
    "svd_unique": [1.9946669727379323, 14.747802755742262, 7.623282841910148, -0.25324840004369387,
                   1.1232372990557442, 0.01224653426499403, 0.0910922580823834, 0.6258332688890986,
                   0.5560677652879236, 0.006299111052978334, 0.6849469939660495, -0.12356933799757448],
    "ridge": [2.238558324608416, 14.846191914205741, 11.699457953336294, -0.21128932607217077, 1.1976871097841755,
              -0.17534418849758024, 0.15188944364927798, 0.5448568520125733, 2.3533166819832934,
              -0.028429065243992923, 0.5850947333857521, -0.10021570473150204],
    "lasso": [1.9935997036736643, 14.764264353303988, 8.930807255565691, -0.2532913815361808, 1.1289586626385266,
              -0.31188461754836083, 0.0914569775302677, 0.6155950839482097, 1.5227054263837396,
              0.006268741147719353, 0.675802983054643, -0.2536836770525563],
}
CASES = [  # (key of BEFORE, method, keywords)
    ("std", "std", {}),
    ("default", "default", {}),
    ("svd", "svd", {"rtol": 1e-3}),
    ("svd", "svd", {}),  # the paper's threshold is the default
    ("svd_unique", "svd", {"rtol": 1e-2, "pairs": "unique"}),
    ("ridge", "ridge", {"eps": 1e-6}),
    ("lasso", "lasso", {"eps": 1e-4}),
]


def _reading(G):
    return np.concatenate([np.linalg.norm(G, axis=0), G[[0, 80, 161]].ravel()])


@pytest.mark.parametrize("key, method, params", CASES)
def test_every_method_gives_the_numbers_recorded_before_the_registry(small, key, method, params):
    b1, b2, C, F = small
    new = pm.transfer(F, C, b1, b2, method, **params)
    op = pm.transfer_operator(C, b1, b2, method, **params)
    np.testing.assert_allclose(_reading(new), BEFORE[key], rtol=BEFORE_RTOL, atol=1e-13)
    np.testing.assert_array_equal(op(F), new)


def test_the_removed_spellings_are_errors(small):
    b1, b2, C, F = small
    with pytest.raises(ValueError, match="method must be one of"):
        pm.transfer(F, C, b1, b2, "prod")
    with pytest.raises(TypeError, match="'approx' is no method's"):
        pm.transfer(F, C, b1, b2, "svd", approx="ridge")
    assert not hasattr(pm, "safe_transfer")
    with pytest.raises(ImportError):
        import prodmaps.default_transfer  # noqa: F401


# ------------------------------------------------------------------ the registry
def test_the_registry_names_every_method_with_its_defaults():
    assert list(REGISTRY) == ["std", "default", "svd", "ridge", "lasso", "svd_gain", "p2p"]
    assert REGISTRY["svd"].parameters["rtol"] == PAPER_RTOL == 1e-3
    assert REGISTRY["svd"].parameters["pairs"] == "ordered"  # the paper's convention
    assert dict(REGISTRY["default"].parameters) == dict(DEFAULT_RULE)
    assert REGISTRY["std"].parameters == {} and REGISTRY["p2p"].operator is PointMapTransfer
    with pytest.raises(TypeError):
        REGISTRY["svd"].parameters["rtol"] = 1.0  # read-only defaults


def test_a_registered_method_is_one_class_and_one_line(small):
    b1, b2, C, F = small

    class Halved(pm.TransferOperator):
        method = "halved"

        def __init__(self, C_12, basis_1, basis_2, *, factor):
            super().__init__(C_12, basis_1, basis_2, {"factor": factor})
            self.inner = pm.transfer_operator(C_12, basis_1, basis_2, "std")

        def apply(self, F):
            return self.params["factor"] * self.inner(F)

    register("halved", Halved, {"factor": 0.5}, "the standard transfer, halved")
    try:
        np.testing.assert_array_equal(pm.transfer(F, C, b1, b2, "halved"), 0.5 * pm.transfer(F, C, b1, b2))
        assert pm.transfer_operator(C, b1, b2, "halved", factor=2.0).params == {"factor": 2.0}
        with pytest.raises(TypeError, match=r"method='halved' takes no parameter 'rtol'.*of 'svd'"):
            pm.transfer(F, C, b1, b2, "halved", rtol=1e-3)
    finally:
        del REGISTRY["halved"]
    with pytest.raises(TypeError, match="TransferOperator subclass"):
        register("bad", object, {})


def test_the_gain_rule_is_approach_b_at_the_selected_threshold(small):
    b1, b2, C, F = small
    op = pm.transfer_operator(C, b1, b2, "svd_gain", max_gain=2.0)
    r = select_rtol(b1, method="gain", C_12=C, basis_2=b2, max_gain=2.0)
    assert op.rtol == r and op.method == "svd_gain"
    np.testing.assert_array_equal(op(F), pm.transfer(F, C, b1, b2, "svd", rtol=r))
    assert op.rank == pm.transfer_operator(C, b1, b2, "svd", rtol=r).rank


def test_the_point_map_transfer_pulls_back_through_the_standard_conversion(small):
    b1, b2, C, F = small
    op = pm.transfer_operator(C, b1, b2, "p2p")
    p2p_21 = from_fmap(C, b1, b2, "std")
    np.testing.assert_array_equal(op.p2p_21, p2p_21)
    np.testing.assert_array_equal(op(F), F[p2p_21])
    np.testing.assert_array_equal(op.approximate(F), pm.transfer_operator(C, b1, b2).approximate(F))


# ------------------------------------------------------------------ the family and its parameters
def test_every_method_has_its_own_parameters_and_others_are_refused(small):
    b1, b2, C, F = small
    with pytest.raises(TypeError, match=r"method='std' takes no parameter 'rtol' \(its parameters: none\); "
                                        r"'rtol' is a parameter of 'svd'"):
        pm.transfer(F, C, b1, b2, "std", rtol=1e-3)
    with pytest.raises(TypeError, match=r"method='svd' takes no parameter 'eps'.*'eps' is a parameter of 'ridge', "
                                        r"'lasso'"):
        pm.transfer_operator(C, b1, b2, "svd", eps=1e-6)
    with pytest.raises(TypeError, match=r"method='default' takes no parameter 'pairs', 'rtol'"):
        pm.transfer_operator(C, b1, b2, "default", rtol=1e-3, pairs="unique")
    with pytest.raises(TypeError, match=r"method='ridge' takes no parameter 'max_iter'.*of 'lasso'"):
        pm.transfer_operator(C, b1, b2, "ridge", max_iter=10)
    with pytest.raises(TypeError, match=r"'foo' is no method's"):
        pm.transfer_operator(C, b1, b2, "lasso", foo=1)
    with pytest.raises(ValueError, match="method must be one of"):
        pm.transfer(F, C, b1, b2, "nearest")
    with pytest.raises(ValueError, match="rtol must be in"):  # values are validated when the operator is built
        pm.transfer_operator(C, b1, b2, "svd", rtol=2.0)
    with pytest.raises(ValueError, match="ridge needs eps > 0"):
        pm.transfer_operator(C, b1, b2, "ridge", eps=0.0)
    with pytest.raises(ValueError, match="g0"):
        pm.transfer_operator(C, b1, b2, "default", g0=0)
    with pytest.raises(ValueError, match="pairs must be 'ordered'"):
        pm.transfer_operator(C, b1, b2, "svd", pairs="foo")


@pytest.mark.parametrize("method, params", [("std", {}), ("default", {}), ("svd", {"rtol": 1e-3}),
                                            ("svd", {"rtol": 1e-2, "order": 3, "pairs": "unique"}),
                                            ("ridge", {"eps": 1e-6}), ("lasso", {"eps": 1e-4}),
                                            ("svd_gain", {}), ("p2p", {})])
def test_built_once_applied_to_parts_equals_applied_to_all(small, method, params):
    b1, b2, C, F = small
    op = pm.transfer_operator(C, b1, b2, method, **params)
    assert op.method == method and isinstance(op, pm.TransferOperator)
    G = op(F)
    halves = np.column_stack([op.apply(F[:, :2]), op.apply(F[:, 2])])
    # the columns are independent: the same to rounding (GEMM vs GEMV), which ridge at eps = 1e-6
    # amplifies by up to ~1/eps (6.5e-12 relative under OpenBLAS's Prescott kernel), except that the
    # lasso's iterations stop together, when every column meets its tolerance (tol=1e-6)
    atol = (1e-6 if method == "lasso" else 1e-12) * np.abs(G).max()
    rtol = 1e-10 if method == "ridge" else 1e-12
    np.testing.assert_allclose(halves, G, rtol=rtol, atol=atol)
    np.testing.assert_allclose(op(F[:, 1]), G[:, 1], rtol=rtol, atol=atol)
    assert G.shape == (b2.n, 3) and op.approximate(F).shape == (b1.n, 3)
    assert op(F[:, :0]).shape == (b2.n, 0)  # no functions: no columns (the lasso failed in its stopping test)
    with pytest.raises(ValueError, match="shape"):
        op(F[:10])
    with pytest.raises(ValueError, match="complex"):
        op(F + 1j)


def test_an_extended_operator_holds_its_parts(small):
    b1, b2, C, F = small
    op = pm.transfer_operator(C, b1, b2, "svd", rtol=1e-3)
    ext1, ext2 = pm.product_basis(b1), pm.product_basis(b2)
    assert op.extended_basis_1 is ext1 and op.extended_basis_2 is ext2
    assert op.approximation is ext1.operator("svd", rtol=1e-3)  # the source's cached operator
    np.testing.assert_array_equal(op.extended_map, pm.extend_fmap(C, b1, b2))
    a = ext1.operator("svd", rtol=1e-3).coefficients(F)
    np.testing.assert_array_equal(op(F), ext2.evaluate(pm.extend_fmap(C, b1, b2) @ a))  # B2 C~ a, the paper's B
    np.testing.assert_array_equal(op.approximate(F), ext1.evaluate(a))
    assert "svd" in repr(op) and "rtol=0.001" in repr(op)


def test_std_is_the_projection_then_the_map(small):
    b1, b2, C, F = small
    op = pm.transfer_operator(C, b1, b2)
    assert op.method == "std" and op.params == {}
    np.testing.assert_array_equal(op(F), b2.vecs @ (C @ b1.project(F)))
    np.testing.assert_array_equal(op.approximate(F), b1.vecs @ b1.project(F))


def test_one_constant_column_is_a_clear_error_for_the_default_and_the_projection_for_the_rest():
    m = ellipsoid(2)
    b = pm.eigenbasis(m, 4)
    b1 = b.truncate(1)
    f = m.vertices[:, 0] * m.vertices[:, 1]
    C1 = pm.fmap_from_p2p(np.arange(m.n_vertices), b1, b1)
    for build in (lambda: pm.transfer_operator(C1, b1, b1, "default"), lambda: DefaultTransfer(C1, b1, b1),
                  lambda: pm.transfer(f, C1, b1, b1, "default")):
        with pytest.raises(ValueError, match="k >= 2.*method='std'"):
            build()
    std = pm.transfer(f, C1, b1, b1, "std")  # the constant part only
    for method in ("svd", "ridge", "lasso"):  # no product to add: the extended basis is the constant
        np.testing.assert_allclose(pm.transfer(f, C1, b1, b1, method), std, rtol=1e-6, atol=1e-15)


def test_complex_and_sparse_maps(small):
    b1, b2, C, F = small
    f = F[:, 0]
    with pytest.raises(ValueError, match="C_12 is complex"):
        pm.transfer(f, C + 1e-3j, b1, b2)
    with pytest.raises(ValueError, match="C_12 is complex"):
        pm.transfer_operator(C.astype(complex), b1, b2, "default")
    with pytest.raises(ValueError, match="non-finite"):
        pm.transfer(f, np.full(C.shape, np.nan), b1, b2, "svd")
    with pytest.raises(ValueError, match=r"\(9, 7\)"):
        pm.transfer_operator(C.T, b1, b2, "ridge")
    with pytest.raises(ValueError, match=r"smaller than the bases: pass basis_1.truncate\(5\) and basis_2.trunc"):
        pm.transfer(f, C[:6, :5], b1, b2)  # a pyFM-size map on larger bases: the error says how to cut them
    with pytest.raises(ValueError) as err:
        pm.transfer(f, C.T, b1, b2)  # transposed: no truncation hint
    assert "truncate" not in str(err.value)
    assert pm.transfer(f, C[:6, :5], b1.truncate(5), b2.truncate(6)).shape == (b2.n,)  # the hint works
    for method in REGISTRY:
        assert np.array_equal(pm.transfer(f, sp.csr_matrix(C), b1, b2, method), pm.transfer(f, C, b1, b2, method))


def test_identity_transfer_is_approximation(basis_0):
    b = basis_0.truncate(10)
    C = np.eye(10)
    F = np.random.default_rng(1).normal(size=(b.n, 2))
    ext = pm.product_basis(b, 2, "ordered")
    approx = ext.evaluate(pm.approximate(F, ext, "svd"))
    np.testing.assert_allclose(pm.transfer(F, C, b, b, "svd", rtol=1e-3), approx, atol=1e-10)  # the paper's B
    np.testing.assert_allclose(pm.transfer(F, C, b, b, "std"), b.vecs @ b.project(F), atol=1e-12)
    # the default: the map is exact, every product direction has gain 1 and no leak, h = 1/(1 + 1.5^-8)
    op = pm.transfer_operator(C, b, b, "default")
    np.testing.assert_allclose(op.gain, 1.0, atol=1e-8)
    np.testing.assert_allclose(op.leak, 0.0, atol=1e-8)
    np.testing.assert_allclose(op.filter, 1 / (1 + 1.5**-8), rtol=1e-8)
    assert np.all(pm.relative_error(op(F), F, b.mass) < pm.relative_error(b.vecs @ b.project(F), F, b.mass))


# ------------------------------------------------------------------ the default rule, by construction
def test_reduces_exactly_to_the_standard_transfer_when_nothing_passes(setting):
    b1, b2, C, F = setting
    op = DefaultTransfer(C, b1, b2, g0=1e-9, l0=1e-9)  # every filter factor below h_min
    assert op.rank == 0
    np.testing.assert_allclose(op(F), pm.transfer(F, C, b1, b2, "std"), rtol=1e-12, atol=1e-12)


def test_heat_kernels_transfer_far_better_with_a_ground_truth_map(basis_0, basis_13):
    # Figure 11's setting: HKS from many eigenfunctions (40), transferred with k = 29 -> 39
    b1, b2 = basis_0.truncate(29), basis_13.truncate(39)
    C = pm.fmap_from_p2p(np.arange(b2.n), b1, b2)  # same triangulation: identity correspondence
    hks = pm.descriptors.hks(basis_0, pm.descriptors.hks_times(basis_0, 4))  # (n, 4), small t first
    e_std = pm.relative_error(pm.transfer(hks, C, b1, b2, "std"), hks, b2.mass)
    e_def = pm.relative_error(pm.transfer(hks, C, b1, b2, "default"), hks, b2.mass)
    assert e_def[0] < 0.5 * e_std[0]  # the detailed (small-t) kernel: products carry what Φ2 C cannot
    assert np.all(e_def <= e_std + 1e-3)  # the smooth ones: never worse


def test_products_beat_std_for_hks_transfer(human_0, human_13):
    """Same triangulation -> identity ground truth; HKS transfer with products is far better."""
    b1 = pm.eigenbasis(human_0, 10)
    b2 = pm.eigenbasis(human_13, 30)
    p2p = np.arange(human_13.n_vertices)
    C = pm.fmap_from_p2p(p2p, b1, b2)
    F = (b1.vecs**2) @ np.exp(-np.outer(b1.evals, [0.01, 0.05]))
    G_true = F[p2p]
    e_std = pm.relative_error(pm.transfer(F, C, b1, b2, "std"), G_true, b2.mass)
    e_prod = pm.relative_error(pm.transfer(F, C, b1, b2, "default"), G_true, b2.mass)
    assert np.all(e_prod < 0.6 * e_std), (e_std, e_prod)
    # the price of the truncation test: the two bodies differ, C's columns are 2-8 % from an
    # isometry's, and the default keeps only part of the product directions; without that test
    # the same map carries these in-span kernels almost exactly
    e_no_trunc = pm.relative_error(pm.transfer(F, C, b1, b2, "default", e0=None), G_true, b2.mass)
    assert np.all(e_no_trunc < 0.2 * e_std), (e_std, e_no_trunc)


def test_never_amplifies_and_matches_its_coefficients(setting):
    b1, b2, C, F = setting
    op = pm.transfer_operator(C, b1, b2, "default")
    assert op is pm.transfer_operator(C, b1, b2, "default")  # cached on the source's product basis
    assert op is not pm.transfer_operator(C, b1, b2, "default", e0=None)
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
    with_e = DefaultTransfer(C, b1, b2)
    without = DefaultTransfer(C, b1, b2, e0=None)
    e0 = with_e.params["e0"]
    np.testing.assert_allclose(with_e.filter, without.filter / (1 + (with_e.error / e0) ** 2), rtol=1e-12)
    np.testing.assert_allclose(with_e.gain, without.gain, rtol=1e-12)
    d = isometry_defect(C, b2.area / b1.area)
    assert (d > 0.9).sum() == b1.k - b2.k and (d[d <= 0.9] < 0.2).all()
    assert with_e.error.max() > 5 * e0 and with_e.rank < without.rank
    with pytest.raises(ValueError, match="e0"):
        DefaultTransfer(C, b1, b2, e0=-1.0)


def test_blocks_of_rows_give_the_one_piece_result(setting, monkeypatch):
    """A large target is processed by blocks of rows (one (n2, r) array, no temporaries of that
    size): the same transfer to rounding, the same kept directions."""
    import prodmaps.transfers as tr

    b1, b2, C, F = setting
    Cn = C + 0.01 * np.random.default_rng(0).standard_normal(C.shape)  # some directions filtered out
    one = DefaultTransfer(Cn, b1, b2)
    monkeypatch.setattr(tr, "_SINGLE_BLOCK_BYTES", 1)
    monkeypatch.setattr(tr, "_BLOCK_ROWS", 997)  # uneven blocks, the last one short
    blk = DefaultTransfer(Cn, b1, b2)
    assert blk.rank == one.rank and 0 < one.rank < one.sigma.size
    np.testing.assert_allclose(blk.gain, one.gain, rtol=1e-10)
    np.testing.assert_allclose(blk.leak, one.leak, rtol=1e-10, atol=1e-14)
    np.testing.assert_allclose(blk(F), one(F), rtol=1e-10, atol=1e-12 * np.abs(one(F)).max())
