"""Results do not depend on the mesh's units: scaling a mesh by 0.01 or 100 changes a result
only by its obvious units (eigenvalues by 1/s², A-orthonormal eigenfunctions by 1/s, …), never
which directions a relative threshold keeps.

Each test computes the same thing on a shape and on copies scaled by ``s`` and compares the
functions (or maps) that come out.
"""

import numpy as np
import pytest

import prodmaps as pm
from prodmaps.approx import NORMALIZATIONS

SCALES = (0.01, 100.0)


@pytest.fixture(scope="module")
def shapes(human_0):
    """``{s: (mesh scaled by s, its eigenbasis with 10 columns)}``, s = 1 included."""
    out = {}
    for s in (1.0,) + SCALES:
        m = pm.Mesh(human_0.vertices * s, human_0.faces, name=f"x{s:g}")
        out[s] = (m, pm.eigenbasis(m, 10))
    return out


def _smooth_rough(mesh):
    x = mesh.vertices
    return np.stack([np.sin(9 * x[:, 0]) * x[:, 2], np.abs(x[:, 1]) > 0.05], axis=1).astype(float)


def test_eigenbasis_scales_as_its_units(shapes):
    m1, b1 = shapes[1.0]
    for s in SCALES:
        _, b = shapes[s]
        np.testing.assert_allclose(b.evals * s**2, b1.evals, rtol=1e-7, atol=1e-9 * b1.evals[-1])
        # same functions up to 1/s (signs are fixed by the package's rule, so no sign ambiguity)
        np.testing.assert_allclose(b.vecs * s, b1.vecs, atol=1e-6 * np.abs(b1.vecs).max())


@pytest.mark.parametrize("normalization", [n for n in NORMALIZATIONS if n != "area"])
@pytest.mark.parametrize("method, params", [("svd", {"rtol": 1e-3}), ("svd", {"rtol": 3e-2}),
                                            ("ridge", {"eps": 1e-6}),
                                            ("lasso", {"eps": 1e-4, "tol": 1e-10, "max_iter": 200000})])
def test_approaches_a_and_b_are_unit_free(shapes, normalization, method, params):
    m1, b1 = shapes[1.0]
    F = _smooth_rough(m1)  # the same values at the same vertices on every copy
    ext1 = pm.product_basis(b1, 2, "ordered")
    op1 = ext1.operator(method, normalization=normalization, **params)
    g1 = ext1.evaluate(op1(F))
    for s in SCALES:
        ext = pm.product_basis(shapes[s][1], 2, "ordered")
        op = ext.operator(method, normalization=normalization, **params)
        if method == "svd":
            assert op.rank == op1.rank, (s, op.rank, op1.rank)
        g = ext.evaluate(op(F))
        # lasso: FISTA converges slowly on this ill-conditioned Gram matrix; at 50000 iterations
        # the scaled copies are still up to 4e-5 apart (more where the BLAS rounds differently),
        # run to tight optimality they agree to ~4e-6 on every normalisation
        tol = 1e-5 if method == "lasso" else 1e-6
        np.testing.assert_allclose(g, g1, atol=tol * np.abs(F).max())


def test_area_normalization_depends_on_units_and_says_so(shapes):
    """The old reading (A-orthonormal factors in the mesh's units) keeps other directions at x100."""
    ranks = {s: pm.product_basis(shapes[s][1], 2, "ordered").operator("svd", rtol=1e-3, normalization="area").rank
             for s in (1.0, 100.0)}
    assert ranks[1.0] != ranks[100.0], ranks


def test_column_weights_of_each_normalization(shapes):
    from prodmaps.approx import column_weights

    m, b = shapes[1.0]
    ext = pm.product_basis(b, 2, "unique")
    X = np.sqrt(b.mass)[:, None] * ext.matrix
    w = column_weights(ext, "columns")
    np.testing.assert_allclose(np.linalg.norm(X * w, axis=0), 1.0, rtol=1e-10)
    w = column_weights(ext, "euclidean")
    np.testing.assert_allclose(np.linalg.norm(b.vecs, axis=0)[1:4] * w[1:4], 1.0)
    i, j = ext.index[b.k + 5]  # a product column: the product of two unit-norm factors
    np.testing.assert_allclose(w[b.k + 5], w[i] * w[j])
    w = column_weights(ext, "unit_area")
    np.testing.assert_allclose(w[: b.k], np.sqrt(b.area))
    np.testing.assert_allclose(w[b.k:], b.area)
    assert column_weights(ext, "area") is None
    with pytest.raises(ValueError, match="normalization must be one of"):
        column_weights(ext, "metres")


def test_area_at_scale_is_the_area_reading_of_the_scaled_mesh(shapes):
    """``"area@100"`` on the mesh = ``"area"`` on the mesh scaled by 100 (ranks and functions)."""
    m1, b1 = shapes[1.0]
    F = _smooth_rough(m1)
    ext1 = pm.product_basis(b1, 2, "ordered")
    ext100 = pm.product_basis(shapes[100.0][1], 2, "ordered")
    op1 = ext1.operator("svd", rtol=1e-3, normalization="area@100")
    op100 = ext100.operator("svd", rtol=1e-3, normalization="area")
    assert op1.rank == op100.rank
    np.testing.assert_allclose(ext1.evaluate(op1(F)), ext100.evaluate(op100(F)), atol=1e-6)
    for bad in ("area@", "area@-1", "area@x", "metres"):
        with pytest.raises(ValueError, match="normalization"):
            ext1.operator("svd", rtol=1e-3, normalization=bad)


# ------------------------------------------------------------------ a pair, one mesh rescaled
@pytest.fixture(scope="module")
def pair(human_0, human_13):
    """``{s: (b1, b2)}``: bases of anny_000 and of anny_013 scaled by ``s`` (the target only)."""
    b1 = pm.eigenbasis(human_0, 20)
    out = {}
    for s in (1.0,) + SCALES:
        m2 = pm.Mesh(human_13.vertices * s, human_13.faces)
        out[s] = (b1, pm.eigenbasis(m2, 20))
    return out


def _gt(b1, b2, k1=10, k2=12):
    """The ground-truth map (the embedded humans share one triangulation: the identity)."""
    return pm.fmap_from_p2p(np.arange(b2.n), b1.truncate(k1), b2.truncate(k2))


@pytest.mark.parametrize("how", [{"method": "std"}, {"method": "default"}, {"method": "svd", "rtol": 1e-3},
                                 {"method": "ridge", "eps": 1e-6}])
def test_transfer_is_unit_free(pair, human_0, how):
    b1, b2 = pair[1.0]
    F = _smooth_rough(human_0)
    g1 = pm.transfer(F, _gt(b1, b2), b1.truncate(10), b2.truncate(12), **how)
    for s in SCALES:
        c1, c2 = pair[s]
        g = pm.transfer(F, _gt(c1, c2), c1.truncate(10), c2.truncate(12), **how)
        np.testing.assert_allclose(g, g1, atol=1e-6 * np.abs(F).max(), err_msg=f"{how} x{s}")


@pytest.mark.parametrize("method", ["std", "extended"])
def test_point_map_conversion_is_unit_free(pair, method):
    from prodmaps.p2p import from_fmap

    b1, b2 = pair[1.0]
    C = _gt(b1, b2, 10, 12) + 0.02 * np.random.default_rng(0).standard_normal((12, 10))  # a map that is not exact
    p1 = from_fmap(C, b1.truncate(10), b2.truncate(12), method)
    for s in SCALES:
        c1, c2 = pair[s]
        Cs = C * s  # the same map: C_12 scales as sqrt(area_2 / area_1) = s
        p = from_fmap(Cs, c1.truncate(10), c2.truncate(12), method)
        assert np.mean(p == p1) > 0.999, (method, s, np.mean(p == p1))


def test_no17_and_zoomout_are_unit_free(pair):
    from prodmaps.fmaps import no17_demo_descriptors
    from prodmaps.fmaps.no17 import fit_no17
    from prodmaps.fmaps.refinement import zoomout
    from prodmaps.p2p import from_fmap

    def run(b1, b2):
        d1, d2 = no17_demo_descriptors(b1, b2, k_descr=20, n_descr=30)
        C = fit_no17(b1.truncate(8), b2.truncate(8), d1, d2, solver="direct")
        Cz = zoomout(C, b1, b2, 16)
        return C, from_fmap(Cz, b1.truncate(16), b2.truncate(16))

    C1, p1 = run(*pair[1.0])
    for s in SCALES:
        C, p = run(*pair[s])
        np.testing.assert_allclose(C / s, C1, atol=1e-6)
        assert np.mean(p == p1) > 0.999, (s, np.mean(p == p1))


def test_descriptors_are_unit_free(human_0):
    from prodmaps.descriptors import spectral

    b = pm.eigenbasis(human_0, 30)
    for s in SCALES:
        bs = b.scaled(s)
        np.testing.assert_allclose(spectral.hks_times(bs) / s**2, spectral.hks_times(b), rtol=1e-12)
        e, sig = spectral.wks_energies_from_evals(b.evals, 30)
        es, sigs = spectral.wks_energies_from_evals(bs.evals, 30)
        np.testing.assert_allclose(np.exp(es) * s**2, np.exp(e), rtol=1e-9)
        # the descriptors themselves scale with 1/area (they are sums of squared A-normalised functions)
        np.testing.assert_allclose(spectral.hks(bs, spectral.hks_times(bs)) * s**2,
                                   spectral.hks(b, spectral.hks_times(b)), rtol=1e-9)
