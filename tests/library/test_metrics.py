"""Errors of approximation and transfer (Section 5.1): relative error, pointwise error, area curves."""

import numpy as np
import pytest

import prodmaps as pm
from prodmaps.metrics import pointwise_error


def test_relative_error_and_area_curve():
    mass = np.array([1.0, 1.0, 2.0])
    g = np.array([1.0, 1.0, 1.0])
    assert pm.relative_error(g, g, mass) == 0
    np.testing.assert_allclose(pm.relative_error(2 * g, g, mass), 1.0)
    curve = pm.area_fraction_curve(np.array([1.0, 1.0, 3.0]), g, mass, [0.0, 1.0, 3.0])
    # (f-g)² = [0, 0, 4] ; sqrt(∫g²) = 2 -> threshold γ·2
    np.testing.assert_allclose(curve, [0.0, 0.5, 1.0])


def test_relative_error_is_area_weighted_per_column():
    mass = np.array([3.0, 1.0])
    g = np.array([[1.0, 2.0], [1.0, 0.0]])
    f = np.array([[1.0, 2.0], [0.0, 1.0]])  # column 0 off on the light vertex, column 1 too
    e = pm.relative_error(f, g, mass)
    assert e.shape == (2,)
    np.testing.assert_allclose(e, [np.sqrt(1 / 4), np.sqrt(1 / 12)])
    assert isinstance(pm.relative_error(f[:, 0], g[:, 0], mass), float)


def test_pointwise_error_and_curves_per_column():
    mass = np.ones(4)
    g = np.ones((4, 2))
    f = g + np.array([[0.0, 1.0], [1.0, 1.0], [0.0, 0.0], [2.0, 0.0]])
    e = pointwise_error(f, g, mass)  # (f-g)² / sqrt(∫g²) with sqrt(∫g²) = 2
    np.testing.assert_allclose(e[:, 0], [0, 0.5, 0, 2])
    curve = pm.area_fraction_curve(f, g, mass, [0.1, 1.0, 5.0])
    assert curve.shape == (3, 2)
    np.testing.assert_allclose(curve[:, 0], [0.5, 0.75, 1.0])
    assert np.all(np.diff(curve, axis=0) >= 0)  # non-decreasing in the threshold


def test_bad_inputs_raise():
    mass = np.ones(3)
    g = np.ones(3)
    with pytest.raises(ValueError, match="zero"):
        pm.relative_error(g, 0 * g, mass)
    with pytest.raises(ValueError, match="same shape"):
        pm.relative_error(np.ones(4), g, mass)
    with pytest.raises(ValueError, match="mass must have shape"):
        pm.relative_error(g, g, np.ones(2))
    with pytest.raises(ValueError, match="non-finite"):
        pm.relative_error(np.array([np.nan, 1, 1]), g, mass)


def test_relative_error_takes_the_mass_of_any_basis():
    """``basis.mass`` goes straight in, also for ``mass="full"`` (sparse): the integral is ``hᵀ M h``;
    a sparse diagonal is the lumped case, and the per-point measures name what they need."""
    import scipy.sparse as sp

    mesh = pm.mesh.ellipsoid(2)
    b = pm.eigenbasis(mesh, 8, mass="full")
    f = mesh.vertices[:, 0] ** 2
    g = pm.transfer(f, np.eye(8), b, b)
    M = b.mass
    expect = np.sqrt((f - g) @ (M @ (f - g)) / (f @ (M @ f)))
    np.testing.assert_allclose(pm.relative_error(g, f, M), expect, rtol=1e-12)
    np.testing.assert_allclose(pm.relative_error(np.c_[g, 2 * g], np.c_[f, f], M)[0], expect, rtol=1e-12)
    lumped = np.asarray(M.sum(axis=1)).ravel()
    assert pm.relative_error(g, f, sp.diags(lumped)) == pm.relative_error(g, f, lumped)
    with pytest.raises(ValueError, match="lumped area weights"):
        pm.area_fraction_curve(g, f, M, [0.1])
