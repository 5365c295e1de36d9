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
                                            ("lasso", {"eps": 1e-4, "max_iter": 50000})])
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
        # lasso: FISTA stopped on its optimality conditions; 5000 iterations (the default) are not
        # enough to converge here (4e-4 apart at any scale), 50000 agree to ~1e-5
        tol = 5e-5 if method == "lasso" else 1e-6
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
