"""Errors of approximation and transfer, as the paper measures them (Section 5.1).

All integrals use the lumped area weights ``mass`` ``(n,)`` of the shape the functions live on;
:func:`relative_error` also takes the sparse mass matrix of a basis built with ``mass="full"``.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from .basis import diagonal_if_lumped

__all__ = ["relative_error", "area_fraction_curve", "pointwise_error"]


def _prep(f, g, mass, full_ok: bool = False):
    """``f, g`` as float64 and ``mass`` as ``(n,)`` weights, or a sparse ``(n, n)`` matrix when ``full_ok``."""
    f, g = (np.asarray(x, dtype=np.float64) for x in (f, g))
    # basis.mass of a basis built with mass="full" (or a pyFM-style sparse A): a diagonal one is lumped weights
    mass = diagonal_if_lumped(mass) if sp.issparse(mass) else np.asarray(mass, dtype=np.float64)
    if sp.issparse(mass) and not full_ok:
        raise ValueError("this measure weighs every point by its own area: it needs the lumped area weights (n,), "
                         "not a full mass matrix; build the basis with mass='lumped' (the default) or pass the "
                         "row sums np.asarray(mass.sum(axis=1)).ravel()")
    if f.shape != g.shape:
        raise ValueError(f"f and g must have the same shape; got {f.shape} and {g.shape}")
    n = f.shape[0]
    if mass.shape != ((n, n) if sp.issparse(mass) else (n,)):
        raise ValueError(f"mass must have shape ({n},)" + (f" or ({n}, {n})" if full_ok else "")
                         + f"; got {mass.shape}")
    if not (np.all(np.isfinite(f)) and np.all(np.isfinite(g))):
        raise ValueError("functions contain non-finite values")
    return f, g, mass


def relative_error(f, g_true, mass) -> np.ndarray | float:
    """``sqrt(∫(f-g)²) / sqrt(∫g²)`` with area weights; per column for ``(n, m)`` inputs.

    Parameters
    ----------
    f : (n,) or (n, m) array_like
        The approximation.
    g_true : (n,) or (n, m) array_like
        The reference, same shape.
    mass : (n,) array_like or sparse (n, n)
        Lumped area weights (``basis.mass``), or the full mass matrix of a basis built with
        ``mass="full"`` (the integrals are then ``hᵀ M h``).

    Returns
    -------
    float or (m,) ndarray

    Raises
    ------
    ValueError
        When the reference ``g_true`` is zero (the error is undefined), or shapes disagree.

    Examples
    --------
    >>> import numpy as np
    >>> import prodmaps as pm
    >>> mass = np.full(4, 0.25)
    >>> g = np.array([1.0, 1.0, 1.0, 1.0])
    >>> round(float(pm.relative_error(g * 1.1, g, mass)), 6)
    0.1
    >>> pm.relative_error(np.c_[g, 2 * g], np.c_[g, g], mass).tolist()
    [0.0, 1.0]
    """
    f, g, mass = _prep(f, g_true, mass, full_ok=True)
    if sp.issparse(mass):
        num = np.sqrt(np.maximum(np.einsum("i...,i...->...", f - g, mass @ (f - g)), 0.0))
        den = np.sqrt(np.maximum(np.einsum("i...,i...->...", g, mass @ g), 0.0))
    else:
        num = np.sqrt(np.einsum("i,i...->...", mass, (f - g) ** 2))
        den = np.sqrt(np.einsum("i,i...->...", mass, g**2))
    if np.any(den == 0):
        raise ValueError("relative error undefined: the reference function is zero")
    out = num / den
    return float(out) if np.ndim(out) == 0 else out


def pointwise_error(f, g_true, mass) -> np.ndarray:
    """``(f(x) - g(x))² / sqrt(∫g²)``: the per-point quantity thresholded in Figure 8."""
    f, g, mass = _prep(f, g_true, mass)
    den = np.sqrt(np.einsum("i,i...->...", mass, g**2))
    if np.any(den == 0):
        raise ValueError("undefined: the reference function is zero")
    return (f - g) ** 2 / den


def area_fraction_curve(f, g_true, mass, thresholds) -> np.ndarray:
    """Fraction of the surface area where ``(f-g)² < γ·sqrt(∫g²)``, for each ``γ``.

    Parameters
    ----------
    f : (n,) or (n, m) array_like
        The transferred function(s).
    g_true : (n,) or (n, m) array_like
        The reference, same shape.
    mass : (n,) array_like
        Lumped area weights (``basis.mass``).
    thresholds : (t,) array_like
        The values of ``γ``.

    Returns
    -------
    ndarray
        ``(len(thresholds),)`` for 1D inputs, ``(len(thresholds), m)`` per column otherwise
        (average the columns for the paper's curves); non-decreasing in ``γ``, in ``[0, 1]``.

    Raises
    ------
    ValueError
        If the shapes of ``f``, ``g_true`` and ``mass`` disagree.

    Examples
    --------
    >>> import numpy as np
    >>> import prodmaps as pm
    >>> from prodmaps.mesh import ellipsoid
    >>> mesh = ellipsoid(2)
    >>> b = pm.eigenbasis(mesh, 6)
    >>> f = mesh.vertices[:, 0] ** 2
    >>> curve = pm.area_fraction_curve(pm.transfer(f, np.eye(6), b, b), f, b.mass, [0.0, 0.1, 10.0])
    >>> curve.shape, round(float(curve[0]), 6), round(float(curve[-1]), 6)
    ((3,), 0.0, 1.0)
    """
    e = pointwise_error(f, g_true, mass)  # (n,) or (n, m)
    gam = np.asarray(thresholds, dtype=np.float64)
    below = e[None, ...] < gam.reshape((-1,) + (1,) * e.ndim)  # (t, n[, m])
    return np.einsum("i,ti...->t...", mass, below.astype(np.float64)) / mass.sum()
