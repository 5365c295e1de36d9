"""What Figures 4, 5, 6 and 10 share: coordinate errors and the Approach B fit of functions on one shape.

Conventions: ``k`` in the paper's sense counts the non-constant eigenfunctions (bases of
``k + 1`` columns, cotangent Laplacian, lumped mass); products are approximated with Approach B
(``rtol``, the paper's ``1e-3``); errors are the paper's area-weighted relative L2 errors, and for
coordinates the mean over x, y, z.
"""

from __future__ import annotations

import numpy as np

from ...approx import PAPER_RTOL
from ...metrics import relative_error
from ...products import product_basis

__all__ = ["COORDINATE_ERROR", "coordinate_errors", "extended_reconstruction"]


COORDINATE_ERROR = "mean over x,y,z of sqrt(int (xhat_c-x_c)^2)/sqrt(int x_c^2), area-weighted"
"""How :func:`coordinate_errors` measures (the results' ``error_definition``)."""


def coordinate_errors(X_rec: np.ndarray, X: np.ndarray, mass: np.ndarray, region=None) -> dict:
    """Relative error of reconstructed coordinates ``(n, 3)``: per axis and their mean.

    With ``region`` (boolean ``(n,)``) also ``region_mean``, the mean error restricted to it.
    """
    e = relative_error(X_rec, X, mass)  # (3,)
    out = {"mean": float(e.mean()), "x": e[0], "y": e[1], "z": e[2]}
    if region is not None:
        out["region_mean"] = float(relative_error(X_rec[region], X[region], mass[region]).mean())
    return out


def extended_reconstruction(basis, F, pairs: str, rtol: float = PAPER_RTOL, order: int = 2):
    """``(ext, op, B a)``: ``F`` ``(n,)``/``(n, m)`` fitted in the extended basis of ``basis`` by Approach B.

    ``ext`` the product basis (``order``, ``pairs``), ``op`` its cached Approach B operator at
    ``rtol``, ``B a`` the fit ``(n,)``/``(n, m)``.
    """
    ext = product_basis(basis, order=order, pairs=pairs)
    op = ext.operator("svd", rtol=rtol)  # Approach B (cached, reusable)
    return ext, op, ext.evaluate(op.coefficients(F))
