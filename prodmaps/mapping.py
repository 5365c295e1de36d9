"""The extended functional map ``C~`` (Section 4.3): :func:`extend_fmap`.

A functional map from a point map is :func:`prodmaps.p2p.fmap_from_p2p`; function transfer with
these maps is :mod:`prodmaps.transfers` (:func:`prodmaps.transfer_operator`,
:func:`prodmaps.transfer`).

Conventions (``C_12``, ``p2p_21``, the ground truth, ``C~``): :mod:`prodmaps.conventions`. By Lemma 2,
``B2 C~ a`` is the function whose value is the exact pointwise product of the transferred basis
functions, for *any* ``C`` (not only ground-truth maps).
"""

from __future__ import annotations

import itertools

import numpy as np
import scipy.sparse as sp

from .basis import Basis
from .checks import check_fmap
from .products import check_pairs, multi_indices, n_orderings, product_basis

__all__ = ["extend_fmap"]


# ------------------------------------------------------------------------- C~
def extend_fmap(C_12, basis_1: Basis, basis_2: Basis, order: int = 2, pairs: str = "ordered") -> np.ndarray:
    """The extended functional map ``C~`` ``(K2, K1)`` of Section 4.3 / Lemma 2.

    For ``order=2, pairs="ordered"`` this is the paper's formula (Eq. 6): with
    ``c0 = C[0, 1:]``, ``Cb = C[1:, 1:]`` and ``φ0`` the value of the target's constant,

    ``C~ = [[C, φ0·kron(c0, C[:, 1:]) + φ0·kron([0; Cb], c0)], [0, kron(Cb, Cb)]]``.

    Other cases (``pairs="unique"``, any ``order``) use the general product rule: the image
    of ``φ_{i1} ⊙ … ⊙ φ_{id}`` is ``Π_t (Φ2 C e_{it})``, expanded in the target's products;
    for ordered targets the coefficient of a multiset is spread evenly over its orderings.
    ``C`` may be rectangular (``k2 != k1``).

    Parameters
    ----------
    C_12 : (k2, k1) array_like
        Functional map from ``basis_1`` (shape 1) to ``basis_2`` (shape 2).
    basis_1, basis_2 : Basis
        The source and target bases (A-orthonormal, constant first).
    order : int
        Highest product degree, as in :func:`prodmaps.product_basis`.
    pairs : ``"ordered"`` or ``"unique"``, as in :func:`prodmaps.product_basis`.

    Returns
    -------
    (K2, K1) ndarray
        ``K1``, ``K2`` the column counts of ``product_basis(basis_i, order, pairs)``.

    Raises
    ------
    ValueError
        If ``C_12`` is not ``(k2, k1)`` or not finite, ``order < 1`` or ``pairs`` is unknown.
    TypeError
        If a basis is not a :class:`prodmaps.Basis`.

    Examples
    --------
    >>> import numpy as np
    >>> import prodmaps as pm
    >>> from prodmaps.mesh import ellipsoid
    >>> b = pm.eigenbasis(ellipsoid(2), 6)
    >>> Ct = pm.extend_fmap(np.eye(6), b, b)
    >>> Ct.shape, bool(np.allclose(Ct, np.eye(31)))  # the identity map extends to the identity
    ((31, 31), True)
    """
    C = check_fmap(C_12, basis_1, basis_2)
    if order < 1:
        raise ValueError(f"order must be >= 1, got {order}")
    check_pairs(pairs)
    phi0 = basis_2.phi0
    if order == 1:
        return C.copy()
    if order == 2 and pairs == "ordered":
        return _extend_order2_ordered(C, phi0)
    Cu = _extend_unique(C, phi0, order)  # (K2_u, K1_u)
    if pairs == "unique":
        return Cu
    ext1 = product_basis(basis_1, order, "ordered")
    ext2 = product_basis(basis_2, order, "ordered")
    spread = ext2.fold().T @ sp.diags(1.0 / n_orderings(ext2.unique_index))  # (K2_o, K2_u)
    return np.asarray(spread @ (ext1.fold().T @ Cu.T).T)


def _extend_order2_ordered(C: np.ndarray, phi0: float) -> np.ndarray:
    k2, k1 = C.shape[0] - 1, C.shape[1] - 1
    c0 = C[0:1, 1:]  # (1, k1)
    Cb = C[1:, 1:]  # (k2, k1)
    K1, K2 = 1 + k1 + k1 * k1, 1 + k2 + k2 * k2
    Ct = np.zeros((K2, K1))
    Ct[: k2 + 1, : k1 + 1] = C
    Cb0 = np.vstack([np.zeros((1, k1)), Cb])  # (k2+1, k1)
    Ct[: k2 + 1, k1 + 1:] = phi0 * (np.kron(c0, C[:, 1:]) + np.kron(Cb0, c0))  # (k2+1, k1²)
    Ct[k2 + 1:, k1 + 1:] = np.kron(Cb, Cb)  # (k2², k1²)
    return Ct


def _monomial_tables(k: int, order: int):
    """Unique monomials per degree and the multiplication tables degree d -> d+1."""
    monos = [[()]] + [list(itertools.combinations_with_replacement(range(1, k + 1), d))
                      for d in range(1, order + 1)]
    pos = [{m: i for i, m in enumerate(ms)} for ms in monos]
    # mul[d]: (Q_d, k) index in degree d+1 of sorted(m + (l,))
    mul = [np.array([[pos[d + 1][tuple(sorted(m + (l,)))] for l in range(1, k + 1)] for m in monos[d]],
                    dtype=np.int64) for d in range(order)]
    return monos, mul


def _extend_unique(C: np.ndarray, phi0: float, order: int) -> np.ndarray:
    """``C~`` between unique (multiset) extended bases of any order, by the product rule."""
    k2, k1 = C.shape[0] - 1, C.shape[1] - 1
    monos2, mul = _monomial_tables(k2, order)
    Q = [len(m) for m in monos2]  # target monomials per degree
    # linear form of the image of φ_l (l >= 1): a_l·1 + Σ b_l[m] φ_m, with 1 = φ0-column / φ0
    a = phi0 * C[0, 1:]  # (k1,)
    b = C[1:, 1:]  # (k2, k1)
    idx1 = multi_indices(k1, order, "unique")
    deg1 = (idx1 > 0).sum(axis=1)
    offsets2 = np.concatenate([[0], np.cumsum(Q)])  # degree-0 monomial <-> column 0
    Ct = np.zeros((offsets2[-1], idx1.shape[0]))
    Ct[: k2 + 1, : k1 + 1] = C
    scatters = [sp.csr_matrix((np.ones(mul[s].size), (mul[s].ravel(), np.arange(mul[s].size))),
                              shape=(Q[s + 1], mul[s].size)) for s in range(order)]
    for d in range(2, order + 1):
        cols = np.flatnonzero(deg1 == d)
        J = idx1[cols, :d] - 1  # (P, d) 0-based non-constant factors
        poly = [a[J[:, 0]][None, :], b[:, J[:, 0]]]  # degree 0: (1, P), degree 1: (k2, P)
        for t in range(1, d):
            at, bt = a[J[:, t]], b[:, J[:, t]]  # (P,), (k2, P)
            new = [p * at for p in poly] + [np.zeros((Q[len(poly)], cols.size))]
            for s, X in enumerate(poly):
                Z = (X[:, None, :] * bt[None, :, :]).reshape(-1, cols.size)  # (Q_s*k2, P)
                new[s + 1] += scatters[s] @ Z
            poly = new
        for s, X in enumerate(poly):
            Ct[offsets2[s]: offsets2[s + 1], cols] = X
        Ct[0, cols] /= phi0  # the function 1 is the constant column divided by φ0
    return Ct
