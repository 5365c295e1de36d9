"""The input checks of the public functions, one implementation each.

Every public function validates what the user passes and raises a specific error that names the
problem and the fix (``TypeError`` for the wrong kind of object, ``ValueError`` for a wrong
shape or value); nothing returns NaN silently. The checks live here, below every module that
uses them (this module imports only :mod:`prodmaps.mesh` and :mod:`prodmaps.basis`). The checks
of a mesh and of vertex indices (:func:`prodmaps.mesh.check_mesh`,
:func:`prodmaps.mesh.check_vertex_indices`) live in :mod:`prodmaps.mesh` itself, because
:mod:`prodmaps.operators` and :mod:`prodmaps.curvature`, below :mod:`prodmaps.basis`, need them.

Conventions checked (:mod:`prodmaps.conventions`): a function is ``(n,)``, several are the
columns of ``(n, m)``; a functional map ``C_12`` is ``(k2, k1)`` (``k`` counts the constant);
a point map ``p2p_21`` is ``(n2,)`` with values in ``[0, n1)``.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from .basis import Basis
from .mesh import check_vertex_indices

__all__ = ["check_basis", "check_functions", "check_fmap", "check_p2p", "check_symmetry_order"]


def check_basis(basis, name: str = "basis") -> Basis:
    """``basis`` if it is a :class:`prodmaps.Basis`, else a ``TypeError`` naming the argument.

    Examples
    --------
    >>> import numpy as np
    >>> check_basis(np.eye(3), "basis_1")
    Traceback (most recent call last):
    ...
    TypeError: basis_1 must be a prodmaps.Basis, got ndarray (build one with pm.eigenbasis(mesh, k))
    """
    if not isinstance(basis, Basis):
        raise TypeError(f"{name} must be a prodmaps.Basis, got {type(basis).__name__} "
                        "(build one with pm.eigenbasis(mesh, k))")
    return basis


def check_functions(F, n: int, what: str = "f") -> np.ndarray:
    """Validate a function ``(n,)`` or the columns of ``(n, m)``; returns float64.

    Raises ``ValueError`` for a wrong shape, complex values (transfer the real and imaginary
    parts separately) or non-finite values, ``TypeError`` for values that are not numbers.

    Examples
    --------
    >>> check_functions([1, 2, 3], 3).dtype
    dtype('float64')
    >>> check_functions([1.0, 2.0], 3)
    Traceback (most recent call last):
    ...
    ValueError: f must have shape (3,) or (3, m); got (2,)
    """
    F = np.asarray(F)
    if np.iscomplexobj(F):
        raise ValueError(f"{what} is complex; functions are real: transfer F.real and F.imag separately")
    if F.dtype.kind not in "biuf":
        raise TypeError(f"{what} must be a real numeric array; got dtype {F.dtype}")
    F = F.astype(np.float64, copy=False)
    if F.ndim not in (1, 2) or F.shape[0] != n:
        raise ValueError(f"{what} must have shape ({n},) or ({n}, m); got {F.shape}")
    if not np.all(np.isfinite(F)):
        raise ValueError(f"{what} contains non-finite values (NaN or inf)")
    return F


def check_p2p(p2p_21, n1: int, n2: int) -> np.ndarray:
    """Validate a point map ``(n2,)`` into ``[0, n1)``; returns int64.

    Examples
    --------
    >>> check_p2p([0, 2, 1], 3, 3)
    array([0, 2, 1])
    >>> check_p2p([0, 1], 3, 3)
    Traceback (most recent call last):
    ...
    ValueError: p2p_21 must have shape (n2,) = (3,): one vertex of shape 1 per vertex of shape 2; got (2,)
    """
    p = np.asarray(p2p_21)
    if p.shape != (n2,):
        raise ValueError(f"p2p_21 must have shape (n2,) = ({n2},): one vertex of shape 1 per "
                         f"vertex of shape 2; got {p.shape}")
    return check_vertex_indices(p, n1, "p2p_21")


def check_fmap(C_12, basis_1: Basis, basis_2: Basis, allow_truncation: bool = False) -> np.ndarray:
    """Validate ``C_12`` against the bases: shape ``(k2, k1)``, real, finite; returns a dense float64 array.

    A scipy sparse matrix is densified (functional maps are small). Complex values raise
    ``ValueError`` (a functional map between real function spaces is real), values that are not
    numbers ``TypeError``. With ``allow_truncation`` the map may be smaller than the bases
    (``k1 <= basis_1.k``, ``k2 <= basis_2.k``): callers then use the first ``k1`` / ``k2`` columns.

    Examples
    --------
    >>> import numpy as np
    >>> import prodmaps as pm
    >>> from prodmaps.mesh import ellipsoid
    >>> b1, b2 = pm.eigenbasis(ellipsoid(1), 4), pm.eigenbasis(ellipsoid(1), 3)
    >>> check_fmap(np.eye(3, 4), b1, b2).shape
    (3, 4)
    >>> check_fmap(np.eye(4, 3), b1, b2)  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    ValueError: C_12 must have shape (basis_2.k, basis_1.k) = (3, 4); got (4, 3). C_12 maps coefficients on ...
    """
    check_basis(basis_1, "basis_1")
    check_basis(basis_2, "basis_2")
    C = np.asarray(C_12.toarray() if sp.issparse(C_12) else C_12)
    if np.iscomplexobj(C):
        raise ValueError("C_12 is complex; a functional map between real function spaces is real (if the imaginary "
                         "part is round-off, pass C_12.real)")
    if C.dtype.kind not in "biuf":
        raise TypeError(f"C_12 must be a real numeric (k2, k1) array or a scipy sparse matrix; got dtype {C.dtype}")
    C = C.astype(np.float64, copy=False)
    if C.ndim != 2:
        raise ValueError(f"C_12 must be a 2D array (k2, k1); got shape {C.shape}")
    if allow_truncation:
        if C.shape[1] > basis_1.k or C.shape[0] > basis_2.k:
            raise ValueError(f"C_12 has shape (k2, k1) = {C.shape} but basis_1 has {basis_1.k} columns and basis_2 "
                             f"{basis_2.k}: rows of C_12 index shape 2, columns index shape 1 (transpose it or "
                             "pass the bases in the other order?)")
    elif C.shape != (basis_2.k, basis_1.k):
        raise ValueError(f"C_12 must have shape (basis_2.k, basis_1.k) = ({basis_2.k}, {basis_1.k}); got {C.shape}. "
                         "C_12 maps coefficients on shape 1 to shape 2"
                         + (f" (a map smaller than the bases: pass basis_1.truncate({C.shape[1]}) and "
                            f"basis_2.truncate({C.shape[0]}))"
                            if C.shape[1] <= basis_1.k and C.shape[0] <= basis_2.k else ""))
    if not np.all(np.isfinite(C)):
        raise ValueError("C_12 contains non-finite values")
    return C


def check_symmetry_order(N) -> int:
    """The symmetry order ``N`` of an ``N``-direction field (4 for crosses) as an ``int``.

    Examples
    --------
    >>> check_symmetry_order(4)
    4
    >>> check_symmetry_order(0)
    Traceback (most recent call last):
    ...
    ValueError: N (the symmetry order, 4 for crosses) must be a positive integer; got 0
    """
    if not isinstance(N, (int, np.integer)) or N < 1:
        raise ValueError(f"N (the symmetry order, 4 for crosses) must be a positive integer; got {N!r}")
    return int(N)
