"""Function transfer: one registry of methods, each an operator built once per map and applied to many functions.

``T = pm.transfer_operator(C_12, basis_1, basis_2, method, **params)`` builds what depends only on
the map and the bases; ``T(F)`` transfers any number of functions, ``(n1,)`` or the columns of
``(n1, m)``, to shape 2; ``T.approximate(F)`` is the approximation on shape 1 that the transfer
carries. ``pm.transfer(F, C_12, basis_1, basis_2, method, **params)`` is that operator applied once.

Conventions (:mod:`prodmaps.conventions`): bases A-orthonormal with the constant first, ``k``
counts the constant, ``C_12`` is ``(k2, k1)`` and maps coefficients on shape 1 to shape 2. By
Lemma 2, ``B2 C~ a`` is the exact pointwise product of the transferred basis functions for *any* ``C``.

The registry (:data:`REGISTRY`, name -> :class:`TransferMethod`: operator class, parameters with
their defaults, summary) is the one vocabulary of the package: the tables' columns, the studies
and :mod:`prodmaps.fields` name their transfers by registry entry and parameters.

============ ==========================================================================================
``std``      the standard transfer ``Φ2 C_12 Φ1ᵀ A1 F`` (no parameters)
``default``  the library's default extended transfer (:class:`DefaultTransfer`; the rule and its
             measurements: ``docs/guide/default_transfer.md``); never changes what ``std`` carries
``svd``      the paper's Approach B, ``B2 C~ a`` with truncated-SVD coefficients; ``rtol=PAPER_RTOL``
             with ``pairs="ordered"`` is the paper's exactly
``ridge``    the paper's Approach A, p = 2 (``penalty="norm"``: Equation 4 as printed)
``lasso``    the paper's Approach A, p = 1 (FISTA)
``svd_gain`` Approach B with ``rtol`` from the map's transfer gains (:func:`prodmaps.truncation.select_rtol`)
``p2p``      the map converted to a point map (:func:`prodmaps.p2p.from_fmap`), ``F`` pulled back
============ ==========================================================================================

A parameter a method does not take raises ``TypeError`` naming the methods it belongs to. Adding a
method is one :class:`TransferOperator` subclass and one :func:`register` line (``docs/guide/developers.md``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from types import MappingProxyType

import numpy as np
import scipy.linalg as sla

from .approx import PAPER_RTOL
from .basis import Basis
from .checks import check_fmap, check_functions
from .files import sha256_bytes
from .mapping import extend_fmap
from .p2p import from_fmap
from .products import check_pairs, evaluate_products, product_basis, unique_solver_gram
from .truncation import DEFAULT_CANDIDATES, select_rtol

__all__ = ["TransferOperator", "StandardTransfer", "DefaultTransfer", "ExtendedTransfer", "ApproachBTransfer",
           "RidgeTransfer", "LassoTransfer", "GainRuleTransfer", "PointMapTransfer", "TransferMethod", "REGISTRY",
           "register", "transfer_operator", "transfer", "isometry_defect", "PAPER_RTOL", "DEFAULT_RULE"]

DEFAULT_RULE = MappingProxyType({"g0": 1.5, "p": 8, "l0": 0.5, "e0": 0.4, "floor": 1e-3, "h_min": 1e-4})
"""The default rule's parameters and their values (see :class:`DefaultTransfer`)."""

# the product images are formed in one piece up to this size, else by blocks of rows (same
# arithmetic per row; the block sums of the norms differ from one sum at rounding level)
_SINGLE_BLOCK_BYTES = 512 << 20
_BLOCK_ROWS = 1 << 16


def _source_parts(basis_1: Basis):
    """``(H (k1, Kp), σ² (r,), V (Kp, r), g_PP (Kp,), ext_u)`` of the residual stage, cached on the source.

    ``g_PP``: the products' squared area norms ``||φ_l φ_m||²_A1``, from the unique product basis'
    Gram (:func:`prodmaps.products.unique_solver_gram`, which Approach B builds too).
    """
    ext_u = product_basis(basis_1, 2, "unique")

    def parts():
        G = unique_solver_gram(basis_1, 2)  # (K_u, K_u) = [Φ1, P1]ᵀ A1 [Φ1, P1]
        k1 = basis_1.k
        H = np.ascontiguousarray(G[:k1, k1:])  # (k1, Kp)
        S = G[k1:, k1:] - H.T @ H  # (Kp, Kp) Schur complement = QᵀA1Q
        lam, V = sla.eigh(0.5 * (S + S.T), check_finite=False)  # ascending
        return H, lam[::-1].copy(), np.ascontiguousarray(V[:, ::-1]), np.diag(G)[k1:].copy()

    return (*ext_u.cache.get("default_transfer_parts", parts), ext_u)


def isometry_defect(C_12: np.ndarray, area_ratio: float = 1.0) -> np.ndarray:
    """``δ_l = ||(I - C_12ᵀ C_12 / ρ²) e_l||_2`` ``(k1,)``, ``ρ² = area_2 / area_1``.

    For the functional map of a point map between near-isometric shapes, ``C_12ᵀ C_12 ≈ ρ² I``
    (norms and orthogonality of the pulled-back eigenfunctions are kept): ``δ_l`` is how far
    column ``l`` is from that. With ``C_12`` the exact projection of a point map, the diagonal part
    is the fraction ``||e_l||² / ρ²`` of the image of ``φ_l`` lost outside ``span Φ2`` (truncation);
    noise or a map that is not a point map adds off-diagonal terms. No ground truth is used.

    Examples
    --------
    >>> import numpy as np
    >>> isometry_defect(np.eye(3)).tolist()  # an isometry between bases of equal areas
    [0.0, 0.0, 0.0]
    """
    C = np.asarray(C_12, dtype=float)
    D = np.eye(C.shape[1]) - (C.T @ C) / float(area_ratio)  # (k1, k1)
    return np.linalg.norm(D, axis=1)


class TransferOperator:
    """A transfer from shape 1 to shape 2, built once for ``(C_12, basis_1, basis_2)`` (module doc).

    Build with :func:`transfer_operator` (or ``cls.build``). ``op(F)`` (or ``op.apply(F)``)
    transfers ``F`` ``(n1,)``/``(n1, m)`` to shape 2, ``(n2,)``/``(n2, m)``; the columns of ``F``
    are independent, so transferring ``F`` in parts gives the same columns (to rounding; the
    lasso's iterations stop when every column meets its tolerance, so there to that tolerance).
    ``op.approximate(F)`` is the approximation of ``F`` on shape 1 that the transfer carries.
    ``method`` and ``params`` (every parameter, defaults filled in) say what was built; ``C`` is
    the validated ``(k2, k1)`` map.

    A subclass implements ``__init__(C_12, basis_1, basis_2, **params)`` (calling
    ``super().__init__(C_12, basis_1, basis_2, params)``), :meth:`apply` and :meth:`approximate`,
    and is registered with :func:`register`.

    Raises
    ------
    ValueError
        From ``op(F)`` for functions of the wrong shape (``(n1,)`` or ``(n1, m)``), complex or
        non-finite values; when built, as :func:`transfer_operator`.

    Examples
    --------
    >>> import numpy as np
    >>> import prodmaps as pm
    >>> from prodmaps.mesh import ellipsoid
    >>> mesh = ellipsoid(2)
    >>> b = pm.eigenbasis(mesh, 6)
    >>> op = pm.transfer_operator(np.eye(6), b, b, "svd", rtol=1e-3)
    >>> isinstance(op, pm.TransferOperator), op.method, op(mesh.vertices).shape
    (True, 'svd', (162, 3))
    """

    method: str = ""

    def __init__(self, C_12, basis_1: Basis, basis_2: Basis, params: dict):
        self.C = check_fmap(C_12, basis_1, basis_2)  # (k2, k1)
        self.basis_1, self.basis_2, self.params = basis_1, basis_2, dict(params)

    @classmethod
    def build(cls, C_12, basis_1: Basis, basis_2: Basis, **params) -> TransferOperator:
        """The operator for these inputs (a subclass may return a cached one)."""
        return cls(C_12, basis_1, basis_2, **params)

    def apply(self, F) -> np.ndarray:
        """The transfer of ``F`` ``(n1,)``/``(n1, m)`` to shape 2, ``(n2,)``/``(n2, m)``."""
        raise NotImplementedError

    def __call__(self, F) -> np.ndarray:
        """The transfer of ``F`` to shape 2 (:meth:`apply`)."""
        return self.apply(F)

    def approximate(self, F) -> np.ndarray:
        """The approximation of ``F`` on shape 1 that this transfer carries, ``(n1,)``/``(n1, m)``."""
        raise NotImplementedError

    def __repr__(self) -> str:
        params = "".join(f", {k}={v!r}" for k, v in self.params.items())
        return f"{type(self).__name__}(method={self.method!r}, k1={self.basis_1.k}, k2={self.basis_2.k}{params})"


class StandardTransfer(TransferOperator):
    """``method="std"``: ``Φ2 C_12 Φ1ᵀ A1 F``, the A-orthogonal projection then the map.

    Examples
    --------
    >>> import numpy as np
    >>> import prodmaps as pm
    >>> from prodmaps.mesh import ellipsoid
    >>> b = pm.eigenbasis(ellipsoid(2), 6)
    >>> op = pm.transfer_operator(np.eye(6), b, b)
    >>> bool(np.allclose(op(b.vecs[:, 2]), b.vecs[:, 2]))  # a basis function goes through the identity
    True
    """

    method = "std"

    def __init__(self, C_12, basis_1: Basis, basis_2: Basis):
        super().__init__(C_12, basis_1, basis_2, {})

    def coefficients(self, F) -> np.ndarray:
        """The coefficients ``Φ1ᵀ A1 F`` ``(k1,)``/``(k1, m)`` on shape 1."""
        return self.basis_1.project(check_functions(F, self.basis_1.n))

    def apply(self, F) -> np.ndarray:
        """``Φ2 C_12 Φ1ᵀ A1 F``: the transfer of ``F`` to shape 2 (:meth:`TransferOperator.apply`)."""
        return self.basis_2.vecs @ (self.C @ self.coefficients(F))

    def approximate(self, F) -> np.ndarray:
        """``Φ1 Φ1ᵀ A1 F``: the A-orthogonal projection of ``F`` on ``span Φ1``."""
        return self.basis_1.vecs @ self.coefficients(F)


class ExtendedTransfer(TransferOperator):
    """``B2 C~ a``: the extended transfers (Approaches A and B); ``solver`` names the fit of ``a``.

    ``a`` ``(K1,)``/``(K1, m)`` are the coefficients of ``F`` in the source's extended basis
    (:attr:`extended_basis_1`, ``order`` and ``pairs`` of :func:`prodmaps.product_basis`) by the
    approximation operator :attr:`approximation` (``solver`` with the solver parameters, defined by
    :func:`prodmaps.approx.approximation_operator`, cached on that basis); :attr:`extended_map`
    is ``C~`` ``(K2, K1)`` and :attr:`extended_basis_2` the target's extended basis. All are built
    here, once. Subclasses: :class:`ApproachBTransfer`, :class:`RidgeTransfer`, :class:`LassoTransfer`.

    Examples
    --------
    >>> import numpy as np
    >>> import prodmaps as pm
    >>> from prodmaps.mesh import ellipsoid
    >>> b = pm.eigenbasis(ellipsoid(2), 6)
    >>> op = pm.transfer_operator(np.eye(6), b, b, "ridge", eps=1e-6)
    >>> op.extended_map.shape, op.approximation.method  # C~ between the ordered extended bases
    ((31, 31), 'ridge')
    """

    solver: str = ""

    def __init__(self, C_12, basis_1: Basis, basis_2: Basis, *, order: int, pairs: str, **solver):
        super().__init__(C_12, basis_1, basis_2, {"order": order, "pairs": pairs, **solver})
        check_pairs(pairs)
        self.extended_basis_1 = product_basis(basis_1, order, pairs)
        self.extended_basis_2 = product_basis(basis_2, order, pairs)
        self.approximation = self.extended_basis_1.operator(self.solver, **solver)
        self.extended_map = extend_fmap(self.C, basis_1, basis_2, order, pairs)  # (K2, K1)

    def coefficients(self, F) -> np.ndarray:
        """The coefficients ``a`` ``(K1,)``/``(K1, m)`` of ``F`` in :attr:`extended_basis_1`."""
        return self.approximation.coefficients(check_functions(F, self.basis_1.n))

    def transfer_coefficients(self, a) -> np.ndarray:
        """``B2 C~ a``: the target function of source coefficients ``a`` ``(K1,)``/``(K1, m)`` (Lemma 2)."""
        return self.extended_basis_2.evaluate(self.extended_map @ np.asarray(a, dtype=np.float64))

    def apply(self, F) -> np.ndarray:
        """``B2 C~ a``: the transfer of ``F`` to shape 2 (:meth:`TransferOperator.apply`)."""
        return self.transfer_coefficients(self.coefficients(F))

    def approximate(self, F) -> np.ndarray:
        """``B1 a``: the fit of ``F`` in the source's extended basis."""
        return self.extended_basis_1.evaluate(self.coefficients(F))


class ApproachBTransfer(ExtendedTransfer):
    """``method="svd"``: the paper's Approach B (truncated SVD at ``rtol``, relative to ``σ_max``).

    ``rank`` is the number of singular directions kept.

    Examples
    --------
    >>> import numpy as np
    >>> import prodmaps as pm
    >>> from prodmaps.mesh import ellipsoid
    >>> b = pm.eigenbasis(ellipsoid(2), 6)
    >>> op = pm.transfer_operator(np.eye(6), b, b, "svd")  # rtol = PAPER_RTOL, ordered pairs: the paper's
    >>> op.params["rtol"] == PAPER_RTOL, op.rank <= op.extended_basis_1.K
    (True, True)
    """

    method = solver = "svd"

    @property
    def rank(self) -> int:
        """Number of singular directions kept by the truncation."""
        return int(self.approximation.rank)


class RidgeTransfer(ExtendedTransfer):
    """``method="ridge"``: the paper's Approach A with p = 2 (``eps`` relative to ``σ_max²``; ``penalty``)."""

    method = solver = "ridge"


class LassoTransfer(ExtendedTransfer):
    """``method="lasso"``: the paper's Approach A with p = 1 (FISTA; ``eps``, ``tol``, ``max_iter``)."""

    method = solver = "lasso"


class GainRuleTransfer(ApproachBTransfer):
    """``method="svd_gain"``: Approach B at the ``rtol`` the gain rule picks from the map (no ground truth).

    ``rtol`` is the largest candidate whose kept directions have transfer gains below ``max_gain``
    (:func:`prodmaps.truncation.select_rtol` with ``method="gain"``); :attr:`rtol` holds it.

    Examples
    --------
    >>> import numpy as np
    >>> import prodmaps as pm
    >>> from prodmaps.mesh import ellipsoid
    >>> b = pm.eigenbasis(ellipsoid(2), 6)
    >>> op = pm.transfer_operator(np.eye(6), b, b, "svd_gain")
    >>> op.rtol in op.params["candidates"]
    True
    """

    method = "svd_gain"

    def __init__(self, C_12, basis_1: Basis, basis_2: Basis, *, order: int, pairs: str, max_gain: float,
                 candidates, normalization=None, route: str = "auto"):
        C = check_fmap(C_12, basis_1, basis_2)
        self.rtol = float(select_rtol(basis_1, method="gain", C_12=C, basis_2=basis_2, candidates=candidates,
                                      max_gain=max_gain, order=order, pairs=pairs, normalization=normalization))
        super().__init__(C, basis_1, basis_2, order=order, pairs=pairs, rtol=self.rtol, route=route,
                         normalization=normalization)
        self.params = {"order": order, "pairs": pairs, "max_gain": max_gain, "candidates": candidates,
                       "normalization": normalization, "route": route}


class PointMapTransfer(TransferOperator):
    """``method="p2p"``: ``C_12`` converted to a point map, then ``F`` pulled back (Section 5.1's remark).

    The point map is the standard conversion (:func:`prodmaps.p2p.from_fmap`, nearest neighbours
    of the spectral embeddings), :attr:`p2p_21` ``(n2,)``; ``op(F) = F[p2p_21]``. The point map is
    read from the standard embedding, so :meth:`approximate` is the standard projection.

    Examples
    --------
    >>> import numpy as np
    >>> import prodmaps as pm
    >>> from prodmaps.mesh import ellipsoid
    >>> mesh = ellipsoid(2)
    >>> b = pm.eigenbasis(mesh, 10)
    >>> op = pm.transfer_operator(pm.fmap_from_p2p(np.arange(b.n), b, b), b, b, "p2p")
    >>> bool(np.array_equal(op(mesh.vertices), mesh.vertices[op.p2p_21]))
    True
    """

    method = "p2p"

    def __init__(self, C_12, basis_1: Basis, basis_2: Basis):
        super().__init__(C_12, basis_1, basis_2, {})
        self.p2p_21 = from_fmap(self.C, basis_1, basis_2, "std")  # (n2,)

    def apply(self, F) -> np.ndarray:
        """``F[p2p_21]``: ``F`` pulled back through the point map."""
        return check_functions(F, self.basis_1.n)[self.p2p_21]

    def approximate(self, F) -> np.ndarray:
        """``Φ1 Φ1ᵀ A1 F``: the standard projection (the embedding the point map is read from)."""
        return self.basis_1.vecs @ self.basis_1.project(check_functions(F, self.basis_1.n))


class DefaultTransfer(TransferOperator):
    """``method="default"``: the library's default extended transfer (the rule: ``docs/guide/default_transfer.md``).

    ``op(F)`` transfers ``F`` ``(n1,)``/``(n1, m)`` to shape 2; ``op.approximate(F)`` is the
    corresponding approximation on shape 1; ``op.coefficients(F)`` the coefficients in the
    unique-pair extended basis of shape 1 (``op.extended_basis``). :func:`transfer_operator`
    caches it on the source's extended basis (keyed by the bytes of ``C_12`` and ``basis_2``).

    Parameters
    ----------
    C_12 : ``(basis_2.k, basis_1.k)`` functional map from shape 1 to shape 2.
    g0, p : gain scale and order of the filter ``1/(1 + (γ/g0)^p)`` (defaults 1.5 and 8: a soft
        cut at 1.5 times the area-ratio-corrected norm a point map would give).
    l0 : leak scale (default 0.5; ``None`` switches the leak test off).
    e0 : scale of the truncation test (default 0.4; ``None`` switches it off): the expected relative
        error ``ê_i`` of direction ``i``'s image (from :func:`isometry_defect`; the guide) enters
        as ``1/(1 + (ê_i/e0)²)``.
    floor : directions with ``σ_i <= floor · σ_max`` of the residual Gram are ignored (1e-3: never a
        direction the paper's threshold would drop).
    h_min : directions with ``h_i < h_min`` are not stored (cost only).

    The rule works on the unique (multiset) pairwise products, whose span is the paper's ordered
    pairs' span.

    Raises
    ------
    ValueError
        For ``basis_1.k < 2`` (no non-constant function: nothing to multiply, use ``"std"``), masses
        that are not lumped, or parameters out of range.

    Examples
    --------
    >>> import numpy as np
    >>> import prodmaps as pm
    >>> from prodmaps.mesh import ellipsoid
    >>> mesh = ellipsoid(2)
    >>> b = pm.eigenbasis(mesh, 6)
    >>> op = pm.transfer_operator(np.eye(6), b, b, "default")
    >>> f = mesh.vertices[:, 0] * mesh.vertices[:, 1]
    >>> std = pm.transfer(f, np.eye(6), b, b, "std")
    >>> bool(pm.relative_error(op(f), f, b.mass) < pm.relative_error(std, f, b.mass))
    True
    """

    method = "default"

    def __init__(self, C_12, basis_1: Basis, basis_2: Basis, *, g0: float = DEFAULT_RULE["g0"],
                 p: float = DEFAULT_RULE["p"], l0: float | None = DEFAULT_RULE["l0"],
                 e0: float | None = DEFAULT_RULE["e0"], floor: float = DEFAULT_RULE["floor"],
                 h_min: float = DEFAULT_RULE["h_min"]):
        super().__init__(C_12, basis_1, basis_2, {"g0": g0, "p": p, "l0": l0, "e0": e0, "floor": floor, "h_min": h_min})
        C = self.C
        if basis_1.k < 2:
            raise ValueError(f"the default extended transfer needs a non-constant function in basis_1 (k >= 2, the "
                             f"constant counts); got k = {basis_1.k}: there are no products to add, use method='std'")
        if not (basis_1.mass_is_diagonal and basis_2.mass_is_diagonal):
            raise ValueError("the default extended transfer needs lumped (diagonal) masses; build the bases with "
                             "mass='lumped', or use method='svd' (the paper's Approach B)")
        for name, v in (("g0", g0), ("p", p), ("floor", floor), ("h_min", h_min)):
            if not (np.isfinite(v) and v > 0):
                raise ValueError(f"{name} must be finite and > 0, got {v!r}")
        for name, v in (("l0", l0), ("e0", e0)):
            if v is not None and not (np.isfinite(v) and v > 0):
                raise ValueError(f"{name} must be finite and > 0 (or None), got {v!r}")
        k1 = basis_1.k
        H, lam, V, gpp, ext_u = _source_parts(basis_1)
        ok = lam > (floor**2) * lam[0]  # σ_i > floor σ_max
        lam, V = lam[ok], V[:, ok]
        self.H, self.extended_basis = H, ext_u
        m2 = basis_2.mass
        Psi = basis_2.vecs @ C  # (n2, k1) transferred basis functions
        rho = np.sqrt(basis_2.area / basis_1.area)
        U, s, Vt = np.linalg.svd(C, full_matrices=False)
        rk = s > 1e-10 * s[0]
        Uc = U[:, rk]  # (k2, rank) orthonormal basis of range(C)
        Q2 = basis_2.vecs @ Uc  # (n2, rank) A2-orthonormal basis of range(Ψ)
        n2, r = Psi.shape[0], V.shape[1]
        # images y_i = (Z - Ψ H) v_i of the directions, Z the products of Ψ (Lemma 2), by blocks of
        # rows when Z would be large (a million-vertex target): one (n2, r) array instead of several
        step = n2 if n2 * H.shape[1] * 8 <= _SINGLE_BLOCK_BYTES else _BLOCK_ROWS
        Y = np.empty((n2, r))  # (n2, r)
        T = np.zeros((int(rk.sum()), r))  # (rank, r) coordinates of Π y_i
        raw2 = np.zeros(r)  # ||y_i||²_A2
        for a in range(0, n2, step):
            b_ = slice(a, min(a + step, n2))
            Yb = (evaluate_products(Psi[b_], ext_u.index)[:, k1:] - Psi[b_] @ H) @ V  # (rows, r)
            MYb = m2[b_, None] * Yb
            T += Q2[b_].T @ MYb
            raw2 += np.einsum("ij,ij->j", Yb, MYb)
            Y[b_] = Yb
        raw = np.sqrt(raw2)  # (r,) ||y_i||_A2
        leak = np.minimum(np.linalg.norm(T, axis=0) / np.maximum(raw, np.finfo(float).tiny), 1.0)
        sigma = np.sqrt(lam)
        norm2 = np.zeros(r)
        for a in range(0, n2, step):  # y'_i = (I - Π) y_i, in place, and its norm
            b_ = slice(a, min(a + step, n2))
            Y[b_] -= Q2[b_] @ T
            norm2 += np.einsum("ij,ij->j", Y[b_], m2[b_, None] * Y[b_])
        gain = np.sqrt(norm2) / (rho * sigma)
        delta = isometry_defect(C, rho**2)  # (k1,)
        pl = ext_u.index[k1:]  # (Kp, 2) the pair (l, m) of each product column
        err = np.sqrt(((V**2) * ((delta[pl[:, 0]] + delta[pl[:, 1]]) * gpp)[:, None]).sum(axis=0) / lam)  # (r,) ê_i
        h = 1.0 / (1.0 + (gain / g0) ** p)
        if l0 is not None:
            h = h / (1.0 + (leak / l0) ** p)
        if e0 is not None:
            h = h / (1.0 + (err / e0) ** 2)
        keep = h >= h_min
        self.sigma, self.gain, self.leak, self.error, self.filter = sigma, gain, leak, err, h
        self._Psi = Psi
        self._Y = Y if keep.all() else np.ascontiguousarray(Y[:, keep])  # (n2, r_kept)
        self._W = np.ascontiguousarray(V[:, keep] * (h[keep] / lam[keep]))  # (Kp, r_kept): filtered pseudo-inverse
        self._V = np.ascontiguousarray(V[:, keep])
        # the removed parts Π y_i = Φ2 Uc T_i = Φ2 C d_i with d_i = C⁺ Uc T_i = V_c Σ_c⁻¹ T_i (same SVD)
        self._D = np.ascontiguousarray((Vt[rk].T / s[rk]) @ T[:, keep])  # (k1, r_kept)

    @classmethod
    def build(cls, C_12, basis_1: Basis, basis_2: Basis, **params) -> DefaultTransfer:
        """The operator, cached on the source's extended basis (keyed by ``C_12``, ``basis_2`` and ``params``)."""
        C = check_fmap(C_12, basis_1, basis_2)
        ext_u = product_basis(basis_1, 2, "unique")
        return ext_u.cache.get(_default_key(C, basis_2, params), lambda: cls(C, basis_1, basis_2, **params))

    @property
    def rank(self) -> int:
        """Number of product directions kept (``h_i >= h_min``)."""
        return self._Y.shape[1]

    def _stages(self, F):
        F = check_functions(F, self.basis_1.n)
        F2 = F[:, None] if F.ndim == 1 else F
        BtAF = self.extended_basis.solver_rmatmul(self.basis_1.mass[:, None] * F2)  # (K_u, m) [Φ1, P1]ᵀ A1 F
        k1 = self.basis_1.k
        a0 = BtAF[:k1]  # (k1, m) standard coefficients Φ1ᵀ A1 F
        q = BtAF[k1:] - self.H.T @ a0  # (Kp, m) Qᵀ A1 r
        return F.ndim == 1, a0, self._W.T @ q  # (r_kept, m) filtered direction coefficients

    def apply(self, F) -> np.ndarray:
        """The standard transfer plus the filtered product directions (``docs/guide/default_transfer.md``, step 4)."""
        one, a0, c = self._stages(F)
        g = self._Psi @ a0 + self._Y @ c
        return g[:, 0] if one else g

    def coefficients(self, F) -> np.ndarray:
        """Coefficients ``(K_u,)``/``(K_u, m)`` in :attr:`extended_basis` (unique pairs) of the fit on shape 1.

        ``pm.extend_fmap(C, b1, b2, pairs="unique") @ coefficients`` transfers them.
        """
        one, a0, c = self._stages(F)
        w = self._V @ c  # (Kp, m) product coefficients
        coefs = np.vstack([a0 - self._D @ c - self.H @ w, w])  # Φ1 (a0 - D c) + Q w = Φ1 (a0 - D c - H w) + P1 w
        return coefs[:, 0] if one else coefs

    def approximate(self, F) -> np.ndarray:
        """The fit on shape 1 that the transfer carries: ``B1`` times :meth:`coefficients`."""
        return self.extended_basis.evaluate(self.coefficients(F))

    def __repr__(self) -> str:
        return (f"DefaultTransfer(k1={self.basis_1.k}, k2={self.basis_2.k}, kept {self.rank} of "
                f"{self.sigma.size} product directions, g0={self.params['g0']}, l0={self.params['l0']})")


def _default_key(C: np.ndarray, basis_2: Basis, params: dict) -> tuple:
    digest = sha256_bytes(np.ascontiguousarray(C).tobytes() + np.ascontiguousarray(basis_2.vecs).tobytes()
                          + np.ascontiguousarray(basis_2.mass).tobytes())[:24]
    return ("default_transfer", digest, tuple(sorted(params.items())))


@dataclass(frozen=True)
class TransferMethod:
    """One entry of :data:`REGISTRY`: a transfer method's operator class, parameters and summary.

    ``operator.build(C_12, basis_1, basis_2, **parameters)`` builds it; ``parameters`` maps every
    parameter the method takes to its default (read-only).
    """

    name: str
    operator: type
    parameters: MappingProxyType = field(default_factory=lambda: MappingProxyType({}))
    summary: str = ""


REGISTRY: dict[str, TransferMethod] = {}
"""The transfer methods by name (module doc): ``REGISTRY[name].parameters`` are their defaults."""


def register(name: str, operator: type, parameters: dict | None = None, summary: str = "") -> TransferMethod:
    """Add a transfer method to :data:`REGISTRY`; returns its entry.

    ``operator`` is a :class:`TransferOperator` subclass whose ``__init__`` takes ``(C_12, basis_1,
    basis_2, **parameters)``; ``parameters`` maps every parameter it takes to its default.

    Examples
    --------
    >>> class Zero(TransferOperator):
    ...     method = "zero"
    ...     def __init__(self, C_12, basis_1, basis_2):
    ...         super().__init__(C_12, basis_1, basis_2, {})
    ...     def apply(self, F):
    ...         return np.zeros((self.basis_2.n,) + np.shape(F)[1:])
    >>> register("zero", Zero, {}, "nothing at all").name
    'zero'
    >>> del REGISTRY["zero"]
    """
    if not (isinstance(operator, type) and issubclass(operator, TransferOperator)):
        raise TypeError(f"operator must be a TransferOperator subclass, got {operator!r}")
    entry = TransferMethod(str(name), operator, MappingProxyType(dict(parameters or {})), summary)
    REGISTRY[entry.name] = entry
    return entry


register("std", StandardTransfer, {}, "the standard transfer: A-orthogonal projection, then the map")
register("default", DefaultTransfer, DEFAULT_RULE, "the library's default extended transfer (no threshold)")
register("svd", ApproachBTransfer, {"order": 2, "pairs": "ordered", "rtol": PAPER_RTOL, "route": "auto",
                                    "normalization": None}, "the paper's Approach B (truncated SVD)")
register("ridge", RidgeTransfer, {"order": 2, "pairs": "ordered", "eps": 1e-4, "penalty": "squared",
                                  "normalization": None}, "the paper's Approach A, p = 2")
register("lasso", LassoTransfer, {"order": 2, "pairs": "ordered", "eps": 1e-4, "tol": 1e-6, "max_iter": 5000,
                                  "normalization": None}, "the paper's Approach A, p = 1")
register("svd_gain", GainRuleTransfer, {"order": 2, "pairs": "ordered", "max_gain": 2.0,
                                        "candidates": DEFAULT_CANDIDATES, "normalization": None, "route": "auto"},
         "Approach B at the threshold the gain rule picks from the map")
register("p2p", PointMapTransfer, {}, "the map converted to a point map, the function pulled back")


def _not_a_parameter(method: str, names) -> str:
    """The message for parameters ``names`` that ``method`` does not take."""
    names = sorted(names)
    owners = {n: [m for m, e in REGISTRY.items() if n in e.parameters] for n in names}
    where = "; ".join(f"{n!r} is a parameter of {', '.join(repr(m) for m in ms)}" if ms else f"{n!r} is no method's"
                      for n, ms in owners.items())
    takes = ", ".join(REGISTRY[method].parameters) or "none"
    return f"method={method!r} takes no parameter {', '.join(map(repr, names))} (its parameters: {takes}); {where}"


def transfer_operator(C_12, basis_1: Basis, basis_2: Basis, method: str = "std", **params) -> TransferOperator:
    """The transfer operator of ``method`` for ``(C_12, basis_1, basis_2)``, built once (module doc).

    Conventions: :mod:`prodmaps.conventions`.

    Parameters
    ----------
    C_12 : (k2, k1) array_like
        Functional map from ``basis_1`` (shape 1) to ``basis_2`` (shape 2); a scipy sparse matrix
        is densified.
    basis_1, basis_2 : Basis
        Bases on shape 1 (``n1`` points, ``k1`` columns) and shape 2 (``n2``, ``k2``).
    method : str
        A name of :data:`REGISTRY` (module doc): ``"std"`` (default), ``"default"``, ``"svd"``
        (the paper's Approach B), ``"ridge"``, ``"lasso"`` (Approach A), ``"svd_gain"``, ``"p2p"``.
    **params
        The method's own parameters; defaults ``REGISTRY[method].parameters``.

    Returns
    -------
    TransferOperator
        ``op(F)`` maps ``(n1,)``/``(n1, m)`` functions to ``(n2,)``/``(n2, m)``. The
        ``"default"`` operator is cached on the source's extended basis (keyed by the bytes of
        ``C_12`` and ``basis_2`` and the parameters): asking again returns the same object.

    Raises
    ------
    ValueError
        For an unknown ``method``, a map that does not match the bases, complex or non-finite
        values, parameter values out of range, or ``basis_1.k < 2`` with ``"default"``.
    TypeError
        For a parameter the method does not take (the message names the method it belongs to) or
        a basis that is not a :class:`prodmaps.Basis`.

    Examples
    --------
    >>> import numpy as np
    >>> import prodmaps as pm
    >>> from prodmaps.mesh import ellipsoid
    >>> mesh = ellipsoid(2)
    >>> b1, b2 = pm.eigenbasis(mesh, 6), pm.eigenbasis(mesh, 8)
    >>> C = pm.fmap_from_p2p(np.arange(mesh.n_vertices), b1, b2)  # (k2, k1) = (8, 6)
    >>> op = pm.transfer_operator(C, b1, b2, "svd", rtol=1e-3)  # the paper's Approach B, built once
    >>> F = mesh.vertices  # (n1, 3): three functions
    >>> G = op(F)
    >>> G.shape, bool(np.allclose(np.column_stack([op(F[:, j]) for j in range(3)]), G))
    ((162, 3), True)
    >>> pm.transfer_operator(C, b1, b2, "svd", g0=2.0)  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    TypeError: method='svd' takes no parameter 'g0' (its parameters: ...); 'g0' is a parameter of 'default'
    """
    entry = REGISTRY.get(method) if isinstance(method, str) else None
    if entry is None:
        raise ValueError(f"method must be one of {tuple(REGISTRY)}, got {method!r}")
    unknown = set(params) - set(entry.parameters)
    if unknown:
        raise TypeError(_not_a_parameter(method, unknown))
    return entry.operator.build(C_12, basis_1, basis_2, **{**entry.parameters, **params})


def transfer(F, C_12, basis_1: Basis, basis_2: Basis, method: str = "std", **params) -> np.ndarray:
    """Transfer function(s) ``F`` ``(n1,)``/``(n1, m)`` from shape 1 to shape 2 with ``C_12``.

    ``transfer_operator(C_12, basis_1, basis_2, method, **params)(F)``: the operator applied
    once. To transfer many functions with one map, build the operator once
    (:func:`transfer_operator`) or pass them as the columns of ``F``. Conventions: :mod:`prodmaps.conventions`.

    Parameters
    ----------
    F : (n1,) or (n1, m) array_like of float
        Function(s) on shape 1, real and finite.
    C_12 : (k2, k1) array_like
        Functional map from ``basis_1`` to ``basis_2``.
    basis_1, basis_2 : Basis
        Bases on shape 1 (``n1`` points, ``k1`` columns) and shape 2 (``n2``, ``k2``).
    method : str
        A name of :data:`REGISTRY`, as in :func:`transfer_operator`.
    **params
        The method's own parameters (``REGISTRY[method].parameters``).

    Returns
    -------
    (n2,) or (n2, m) ndarray
        The transferred function(s) on shape 2.

    Raises
    ------
    ValueError
        For an unknown ``method``, shapes that do not match the bases, complex or non-finite
        values, or parameter values out of range.
    TypeError
        For parameters the chosen method does not take (e.g. ``rtol`` with ``method="std"``).

    Examples
    --------
    >>> import numpy as np
    >>> import prodmaps as pm
    >>> from prodmaps.mesh import ellipsoid
    >>> mesh = ellipsoid(2)
    >>> b = pm.eigenbasis(mesh, 6)
    >>> C = pm.fmap_from_p2p(np.arange(mesh.n_vertices), b, b)  # (k2, k1) = (6, 6)
    >>> f = mesh.vertices[:, 0] * mesh.vertices[:, 1]
    >>> std = pm.transfer(f, C, b, b)                             # Φ2 C Φ1ᵀ A1 f
    >>> ext = pm.transfer(f, C, b, b, method="default")           # the default extended transfer
    >>> paper = pm.transfer(f, C, b, b, method="svd", rtol=1e-3)  # the paper's Approach B
    >>> std.shape, ext.shape, paper.shape
    ((162,), (162,), (162,))
    >>> errors = [pm.relative_error(g, f, b.mass) for g in (std, ext, paper)]
    >>> bool(errors[1] < errors[0] and errors[2] < errors[0])  # products help on a product
    True
    """
    return transfer_operator(C_12, basis_1, basis_2, method, **params)(F)
