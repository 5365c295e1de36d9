"""Approximating functions in a (product) basis: the standard projection, Approach A, Approach B.

Holds :func:`approximation_operator` (an :class:`ApproximationOperator`, built once per basis and
applied to any number of functions), :func:`approximate` (that operator applied once; operators of
a ProductBasis are cached on it), :func:`column_weights` (the normalisation ``D``),
:func:`gram_eigenpairs`, :func:`operator_parameters` and the constants :data:`PAPER_RTOL`,
:data:`NORMALIZATIONS`, :data:`DEFAULT_NORMALIZATION`, :data:`RIDGE_PENALTIES`.

Conventions (:mod:`prodmaps.conventions`): a :class:`~prodmaps.Basis` ``Φ`` ``(n, k)`` is
A-orthonormal (``ΦᵀAΦ = I``, ``A`` the lumped mass), column 0 the constant, ``k`` counting it; a
product basis ``B`` ``(n, K)`` holds the base columns, then the products. Every method minimises
in the **area inner product**, ``||f - B a||_A² = (f - B a)ᵀ A (f - B a)``. Functions ``F`` are
``(n,)`` or ``(n, m)`` (one per column); coefficients ``(K,)`` or ``(K, m)`` are always those of
the basis' own columns.

Methods
-------
``"std"``
    The A-orthogonal projection on an orthonormal Basis: ``a = Φᵀ A f``.
``"svd"`` (Approach B, Section 4.2)
    Truncated SVD of ``sqrt(A) B D``: singular values below ``rtol · σ_max`` are dropped
    (:data:`PAPER_RTOL` ``= 1e-3`` in the paper); the minimum-norm solution.
``"ridge"`` (Approach A, p = 2)
    ``argmin ||f - B a||_A² + ε σ_max² ||a||²``; ``penalty="norm"``: Equation 4 as printed (norms).
``"lasso"`` (Approach A, p = 1)
    ``argmin ½||f - B a||_A² + ε λ_max ||a||₁`` with ``λ_max = ||Bᵀ A f||_∞``, by FISTA.

``normalization`` names the diagonal ``D`` the truncation and the penalties see (``"euclidean"``,
the default :data:`DEFAULT_NORMALIZATION`, ``"unit_area"`` and ``"columns"`` are free of the
mesh's units; ``"area"`` and ``"area@<s>"`` are not, kept for studies). ``route`` computes
Approach B by the SVD or the Gram matrix (the same result; ``"auto"`` by ``rtol``). With
``pairs="ordered"`` every solver runs on the scaled unique basis and maps back exactly.

The derivations (Equation 4's ridge path, the lasso's stopping rule, the routes and when the Gram
route is exact enough, the ordered basis, each normalisation and why the mesh's units matter):
``docs/guide/approximation.md``.
"""
from __future__ import annotations

import inspect
from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla

from .basis import Basis
from .checks import check_functions

__all__ = ["ApproximationOperator", "approximation_operator", "approximate", "column_weights", "gram_eigenpairs",
           "is_extended", "NORMALIZATIONS", "DEFAULT_NORMALIZATION", "PAPER_RTOL", "RIDGE_PENALTIES",
           "operator_parameters"]

METHODS = ("std", "svd", "ridge", "lasso")
RIDGE_PENALTIES = ("squared", "norm")  # Approach A, p = 2: ||·||² + ε σ_max² ||a||², or Equation 4's norms
NORMALIZATIONS = ("euclidean", "unit_area", "columns", "area")
DEFAULT_NORMALIZATION = "euclidean"  # the reading that reproduces the paper (study_normalization)
PAPER_RTOL = 1e-3
"""The paper's Approach B threshold (Section 4.2): singular values below ``PAPER_RTOL · σ_max`` are dropped."""


def is_extended(basis) -> bool:
    """Whether ``basis`` is an extended basis (a :class:`prodmaps.ProductBasis`) rather than a Basis.

    This module sits below :mod:`prodmaps.products` (``ProductBasis.operator`` builds its operators
    here), so it knows a ProductBasis by what it offers: a ``base`` :class:`prodmaps.Basis` and the
    solver products (``solver_gram``, ``solver_rmatmul``, ``expand``, ``unique_index``).
    """
    return not isinstance(basis, Basis) and isinstance(getattr(basis, "base", None), Basis) and all(
        hasattr(basis, a) for a in ("solver_gram", "solver_rmatmul", "expand", "unique_index", "cache"))


def _solver_parts(basis):
    """(B_s or None, base Basis, expand Sᵀ or None, K) for a Basis or ProductBasis.

    For a ProductBasis ``B_s`` is None: use :func:`_gram` / :func:`_rmatmul`, which are
    blocked for large meshes, or ``basis.solver_basis()`` when the matrix is really needed.
    """
    if is_extended(basis):
        E = None if basis.pairs == "unique" else basis.expand()
        return None, basis.base, E, basis.K
    if isinstance(basis, Basis):
        return basis.vecs, basis, None, basis.k
    raise TypeError(f"expected a prodmaps.Basis or ProductBasis, got {type(basis).__name__}")


def column_weights(basis, normalization: str = DEFAULT_NORMALIZATION) -> np.ndarray | None:
    """The diagonal ``D`` ``(K_u,)`` of the solver columns for ``normalization`` (``docs/guide/approximation.md``).

    ``K_u`` counts the solver's columns: the basis' own for a Basis or a ``pairs="unique"``
    ProductBasis, the unique multisets for ``pairs="ordered"`` (where ``(l, m)`` and ``(m, l)``
    share a weight). Returns ``None`` for ``"area"`` (``D = I``).

    Examples
    --------
    >>> import prodmaps as pm
    >>> from prodmaps.mesh import icosphere
    >>> b = pm.eigenbasis(icosphere(2), 4)
    >>> w = column_weights(b, "euclidean")
    >>> bool(np.allclose(np.linalg.norm(b.vecs * w, axis=0), 1.0))
    True
    """
    scale = _area_scale(normalization)
    if normalization == "area":
        return None
    _, base, _, _ = _solver_parts(basis)
    if normalization == "columns":
        G = _gram(basis)
        return 1.0 / np.sqrt(np.maximum(np.diag(G), np.finfo(float).tiny))
    if scale is not None:  # "area@<s>": A-orthonormal factors of the mesh scaled by s are φ / s
        c = np.full(base.k, 1.0 / scale)
    elif normalization == "unit_area":
        c = np.full(base.k, np.sqrt(base.area))  # (k,) per factor
    else:  # euclidean
        c = 1.0 / np.linalg.norm(base.vecs, axis=0)  # (k,) per factor
    if not is_extended(basis):
        return c
    idx = basis.unique_index  # (K_u, order), factors 1-based, 0 pads; row 0 is the constant
    fac = np.where(idx > 0, c[idx], 1.0)
    w = np.prod(fac, axis=1)
    w[0] = c[0]
    return w


def _area_scale(normalization) -> float | None:
    """``s`` of ``"area@<s>"`` (None for the other names); raises ``ValueError`` on unknown names."""
    if isinstance(normalization, str) and normalization.startswith("area@"):
        try:
            s = float(normalization[5:])
        except ValueError:
            s = float("nan")
        if not (np.isfinite(s) and s > 0):
            raise ValueError(f"normalization {normalization!r}: the scale after 'area@' must be a positive number")
        return s
    if normalization not in NORMALIZATIONS:
        raise ValueError(f"normalization must be one of {NORMALIZATIONS} or 'area@<scale>', got {normalization!r}")
    return None


@dataclass(frozen=True, eq=False)
class ApproximationOperator:
    """Reusable approximation operator for one basis (build with :func:`approximation_operator`).

    ``coefficients(F)`` returns coefficients in the basis' own column convention; for
    Approach B, ``canonical(a)`` returns the canonical coefficients ``ã = Σ Vᵀ a`` of
    Section 4.4 (``||B a||_A = ||ã||₂`` for any ``a``).

    Raises
    ------
    ValueError
        From ``coefficients`` for functions of the wrong shape, complex or non-finite values.

    Examples
    --------
    >>> import prodmaps as pm
    >>> from prodmaps.mesh import ellipsoid
    >>> mesh = ellipsoid(2)
    >>> pb = pm.product_basis(pm.eigenbasis(mesh, 6))
    >>> op = pm.approximation_operator(pb, "svd", rtol=1e-3)
    >>> F = mesh.vertices  # three functions at once, (n, 3)
    >>> op.coefficients(F).shape, op.reconstruct(F).shape, op.rank <= 31
    ((31, 3), (162, 3), True)
    """

    basis: object
    method: str
    params: dict
    _M: np.ndarray | None = None  # (K_u, K_u): a_s = M @ (B_sᵀ A f)        [gram, ridge]
    _P: np.ndarray | None = None  # (K_u, r):   a_s = P @ (U_rᵀ sqrt(A) f)   [svd route]
    _U: np.ndarray | None = None  # (n, r)
    _sV: np.ndarray | None = None  # (r, K_u):  ã = (Σ_r V_rᵀ) @ (S a)
    _G: np.ndarray | None = None  # (K_u, K_u) Gram of the scaled columns, lasso
    _d: np.ndarray | None = None  # (K_u,) column weights D of the lasso (None: D = I)
    _svd: tuple | None = None  # ((U (n, r), s (r,), Vt (r, K_u)), d or None, ε): ridge, penalty="norm"

    @property
    def rank(self) -> int | None:
        """Number of singular values kept (Approach B)."""
        return None if self._sV is None else self._sV.shape[0]

    def coefficients(self, F) -> np.ndarray:
        """Coefficients ``(K,)`` or ``(K, m)`` of ``F`` ``(n,)`` or ``(n, m)``."""
        B_s, base, E, K = _solver_parts(self.basis)
        F = check_functions(F, base.n)
        if self.method == "std":
            return base.project(F)
        if self.method == "lasso":
            return _fista(self, F)
        if self._svd is not None:  # ridge, penalty="norm"
            a = _norm_ridge(*self._svd, np.sqrt(base.mass)[:, None] * (F[:, None] if F.ndim == 1 else F))
            a = a[:, 0] if F.ndim == 1 else a
            return a if E is None else E @ a
        AF = base.apply_mass(F)
        if self._M is not None:
            a = self._M @ _rmatmul(self.basis, AF)
        else:  # SVD route: U_rᵀ sqrt(A) f, written as U_rᵀ (A f / sqrt(A))
            sqrt_mass = np.sqrt(base.mass)
            a = self._P @ (self._U.T @ (AF / (sqrt_mass[:, None] if F.ndim == 2 else sqrt_mass)))
        return a if E is None else E @ a

    __call__ = coefficients

    def canonical(self, coefs) -> np.ndarray:
        """Canonical coefficients ``Σ_r V_rᵀ a`` ``(r,)`` or ``(r, m)`` (Approach B only)."""
        if self._sV is None:
            raise ValueError("canonical coefficients need an Approach B operator (method='svd')")
        coefs = np.asarray(coefs, dtype=np.float64)
        if is_extended(self.basis) and self.basis.pairs == "ordered":
            coefs = self.basis.expand().T @ coefs  # S a: ordered -> scaled unique
        return self._sV @ coefs

    def span_factors(self) -> np.ndarray:
        """``P`` ``(K, r)`` such that ``B P`` is an A-orthonormal basis of the span Approach B keeps.

        ``P = D V_r Σ_r⁻¹`` (Approach B only), in the basis' own column convention: the columns
        of ``B P`` are ``U_r / sqrt(A)``, so ``canonical(coefficients(f)) = (B P)ᵀ A f`` are the
        coordinates of ``f``'s approximation in that basis.
        """
        if self._sV is None:
            raise ValueError("span_factors needs an Approach B operator (method='svd')")
        P = self._P if self._P is not None else self._M @ self._sV.T  # (K_u, r); M sVᵀ = D V Σ⁻¹
        if is_extended(self.basis) and self.basis.pairs == "ordered":
            P = self.basis.expand() @ P  # Sᵀ P: B_o Sᵀ P = B_s P (S has orthonormal rows)
        return np.asarray(P)

    def reconstruct(self, F) -> np.ndarray:
        """The approximation ``B a`` of ``F`` in the basis."""
        a = self.coefficients(F)
        return self.basis.evaluate(a) if is_extended(self.basis) else self.basis.vecs @ a


def operator_parameters(**params) -> dict:
    """Every keyword of :func:`approximation_operator`, ``params`` over its defaults (``normalization`` resolved).

    Two calls with the same result (one naming a default, one not) get the same dictionary, the key
    of the cached operators (:meth:`prodmaps.ProductBasis.operator`). Unknown names raise ``TypeError``.

    >>> operator_parameters(rtol=1e-2)["rtol"], operator_parameters()["normalization"]
    (0.01, 'euclidean')
    """
    unknown = set(params) - set(_OPERATOR_DEFAULTS)
    if unknown:
        raise TypeError(f"approximation_operator() got unexpected keyword arguments {sorted(unknown)}")
    full = {**_OPERATOR_DEFAULTS, **params}
    if full["normalization"] is None:
        full["normalization"] = DEFAULT_NORMALIZATION
    return full


def approximation_operator(basis, method: str = "svd", *, rtol: float = PAPER_RTOL, eps: float = 1e-4,
                           route: str = "auto", tol: float = 1e-6, max_iter: int = 5000,
                           normalization: str | None = None, penalty: str = "squared") -> ApproximationOperator:
    """Build the approximation operator of ``basis`` for ``method`` (module doc; ``docs/guide/approximation.md``).

    Parameters
    ----------
    basis : Basis or ProductBasis
    method : ``"svd"`` (Approach B, default) | ``"ridge"`` | ``"lasso"`` (Approach A) | ``"std"``.
    rtol : Approach B threshold relative to σ_max (paper: 1e-3), on ``sqrt(A) B D``.
    eps : Approach A weight, relative (ridge: to σ_max²; lasso: to ||Bᵀ A f||_∞).
    route : Approach B route, ``"auto"`` | ``"svd"`` | ``"gram"``.
    tol, max_iter : lasso stopping rule.
    normalization : ``D`` of Approaches A and B (``docs/guide/approximation.md``; default
        :data:`DEFAULT_NORMALIZATION`).
    penalty : ridge only: ``"squared"`` (default) or ``"norm"`` (Equation 4 as printed; ``eps``
        then relative to σ_max; ``docs/guide/approximation.md``).

    Returns
    -------
    ApproximationOperator
        ``coefficients(F)`` maps ``(n,)``/``(n, m)`` functions to ``(K,)``/``(K, m)`` coefficients.

    Raises
    ------
    ValueError
        For an unknown method, route or normalisation, or a threshold out of range.
    TypeError
        For a ``basis`` that is neither a Basis nor a ProductBasis.

    Examples
    --------
    >>> import prodmaps as pm
    >>> from prodmaps.mesh import ellipsoid
    >>> pb = pm.product_basis(pm.eigenbasis(ellipsoid(2), 6))
    >>> op = pm.approximation_operator(pb, "svd", rtol=1e-3)
    >>> op.method, op.coefficients(pb.base.vecs[:, 1]).shape
    ('svd', (31,))
    """
    if method not in METHODS:
        raise ValueError(f"method must be one of {METHODS}, got {method!r}")
    if penalty not in RIDGE_PENALTIES or (penalty != "squared" and method != "ridge"):
        raise ValueError(f"penalty must be one of {RIDGE_PENALTIES} (the ridge's; other methods take none), "
                         f"got {penalty!r} for method={method!r}")
    normalization = DEFAULT_NORMALIZATION if normalization is None else normalization
    _, base, _, _ = _solver_parts(basis)  # (a TypeError for anything but a Basis or ProductBasis)
    if method == "std":
        if is_extended(basis):
            raise ValueError("method='std' projects on an orthonormal Basis; pass ext.base, "
                             "or use 'svd'/'ridge'/'lasso' for a ProductBasis")
        return ApproximationOperator(basis, method, {})
    if isinstance(rtol, (str, bytes)) or isinstance(eps, (str, bytes)):
        raise TypeError(f"rtol and eps are numbers; got rtol={rtol!r}, eps={eps!r}")
    d = column_weights(basis, normalization)  # (K_u,) or None for D = I
    params = {"rtol": rtol, "eps": eps, "route": route, "tol": tol, "max_iter": max_iter,
              "normalization": normalization, "penalty": penalty}
    if method == "ridge" and eps <= 0:
        raise ValueError(f"ridge needs eps > 0, got {eps}")
    if method == "ridge" and penalty == "norm":
        if not base.mass_is_diagonal:
            raise ValueError("penalty='norm' needs a lumped (diagonal) mass")
        svd = (basis.cache.get(("scaled_svd", normalization), lambda: _scaled_svd(basis, d)) if is_extended(basis)
               else _scaled_svd(basis, d))  # one SVD per basis and normalisation serves every ε
        return ApproximationOperator(basis, method, params, _svd=(svd, d, float(eps)))
    if method == "svd":
        if not (0 <= rtol < 1):
            raise ValueError(f"rtol must be in [0, 1), got {rtol}")
        if route == "auto":
            route = "gram" if (rtol >= 1e-6 or not base.mass_is_diagonal) else "svd"
        if route == "svd":
            if not base.mass_is_diagonal:
                raise ValueError("route='svd' needs a lumped (diagonal) mass; use route='gram'")
            U, s, Vt = _scaled_svd(basis, d)
            r = int(np.sum(s > rtol * s[0]))
            P, sV, U = Vt[:r].T / s[:r], s[:r, None] * Vt[:r], U[:, :r]  # (K_u, r), (r, K_u) in the scaled columns
            route_info = {"route": "svd"}
        elif route == "gram":
            w, V, side = gram_eigenpairs(basis, normalization)
            s = np.sqrt(np.maximum(w, 0.0))
            r = int(np.sum(s > rtol * s[0]))
            Vr = V[:, :r]
            if side == "primal":  # V: right singular vectors (K_u, K_u) of sqrt(A) B_s D
                M, sV = (Vr / s[:r] ** 2) @ Vr.T, s[:r, None] * Vr.T
                if d is not None:
                    M, sV = d[:, None] * M * d, sV / d
                return ApproximationOperator(basis, method, params | {"route": "gram"}, _M=M, _sV=sV)
            XtU = _scaled_columns(basis, d).T @ Vr  # (K_u, r) = V_r Σ_r; V: left vectors (n, n)
            P, sV, U = XtU / s[:r] ** 2, XtU.T.copy(), Vr
            route_info = {"route": "gram", "side": "dual"}
        else:
            raise ValueError(f"route must be 'auto', 'svd' or 'gram', got {route!r}")
        if d is not None:
            P, sV = d[:, None] * P, sV / d
        return ApproximationOperator(basis, method, params | route_info, _P=P, _U=np.ascontiguousarray(U), _sV=sV)
    G = _gram(basis)
    if d is not None:
        G = d[:, None] * G * d  # Gram of the scaled columns
    if method == "ridge":
        smax2 = sla.eigh(G, eigvals_only=True, subset_by_index=[G.shape[0] - 1] * 2)[0]
        M = sla.solve(G + eps * smax2 * np.eye(G.shape[0]), np.eye(G.shape[0]), assume_a="pos")
        if d is not None:
            M = d[:, None] * M * d
        return ApproximationOperator(basis, method, params, _M=M)
    # lasso
    if eps <= 0:
        raise ValueError(f"lasso needs eps > 0, got {eps}")
    return ApproximationOperator(basis, method, params, _G=G, _d=d)


def _scaled_svd(basis, d):
    """Thin SVD ``(U (n, r), s (r,), Vt (r, K_u))`` of the scaled columns ``X = sqrt(A) B_s D``."""
    return tuple(sla.svd(_scaled_columns(basis, d), full_matrices=False, lapack_driver="gesdd"))


def _norm_ridge(svd: tuple, d, eps: float, G: np.ndarray, steps: int = 100) -> np.ndarray:
    """``argmin ||f - B a||_A + ε σ_max ||a'||`` for every column (``penalty="norm"``, ``docs/guide/approximation.md``).

    ``svd = (U, s, Vt)`` of the scaled columns ``X = sqrt(A) B_s D`` (``d`` the diagonal of ``D``
    or None), ``G`` ``(n, m)`` the functions times ``sqrt(A)``. On the ridge path
    ``a'(λ) = Vtᵀ (s c / (s² + λ))`` (``c = Uᵀ g``, ``a = D a'``) the residual is
    ``||g - U c||² + Σ (λ c / (s² + λ))²``, without cancellation, and ``λ ||a'(λ)|| / ||r(λ)||`` grows
    with ``λ``: ``steps`` bisections on ``log λ`` find where it reaches ``ε σ_max``. The problem is
    1-homogeneous in ``f``: each column is solved at unit norm and scaled back. Columns in the dead
    zone (``||Xᵀ g|| <= ε σ_max ||g||``) get exactly 0.
    """
    U, s, Vt = svd
    w = eps * s[0]  # ε σ_max
    peak = np.max(np.abs(G), axis=0, initial=0.0)  # (m,): columns scaled by their peak first (no overflow)
    live = peak > 0
    Gu = G[:, live] / peak[live]
    norm = np.sqrt(np.sum(Gu ** 2, axis=0))
    Gu /= norm  # unit columns
    c = U.T @ Gu  # (r, m)
    outside = np.sqrt(np.sum((s[:, None] * c) ** 2, axis=0)) <= w  # the dead zone: ||Xᵀ g|| <= ε σ_max ||g||
    Gu, c, norm = Gu[:, ~outside], c[:, ~outside], (norm * peak[live])[~outside]
    live[live] = ~outside
    a = np.zeros((Vt.shape[1], G.shape[1]))
    if not live.any():
        return a if d is None else d[:, None] * a
    perp2 = np.sum((Gu - U @ c) ** 2, axis=0)  # the part of g outside the span of X
    s2 = (s ** 2)[:, None]
    top = np.log(max(s[0] ** 2, 1e-300))
    lo, hi = np.full(Gu.shape[1], top - 80.0), np.full(Gu.shape[1], top + 40.0)
    for _ in range(steps):
        lam = np.exp(0.5 * (lo + hi))
        q = 1.0 / (s2 + lam)  # (r, m)
        below = lam * np.sqrt(np.sum((s[:, None] * c * q) ** 2, axis=0)) < w * np.sqrt(
            perp2 + np.sum((lam * c * q) ** 2, axis=0))
        lo, hi = np.where(below, 0.5 * (lo + hi), lo), np.where(below, hi, 0.5 * (lo + hi))
    a[:, live] = (Vt.T @ (s[:, None] * c / (s2 + np.exp(0.5 * (lo + hi))))) * norm  # (K_u, m), scaled back
    return a if d is None else d[:, None] * a


def gram_eigenpairs(basis, normalization: str):
    """Eigenpairs, descending, of the smaller Gram matrix of ``X = sqrt(A) B_s D``.

    ``D`` the column weights of ``normalization`` (:func:`column_weights`; pass
    :data:`DEFAULT_NORMALIZATION` for the library's reading). Approach B's operator
    (route ``"gram"``) and :func:`prodmaps.truncation.singular_directions` share this one
    decomposition.

    Returns ``(w, V, side)``: ``side="primal"``: ``XᵀX = V diag(w) Vᵀ`` (``K_u x K_u``);
    ``side="dual"`` when ``K_u > n`` (e.g. order-4 products): ``XXᵀ = U diag(w) Uᵀ``
    (``n x n``), far cheaper than the ``K_u x K_u`` problem. The eigenpairs do not depend on
    ``rtol``, so a ProductBasis caches them and every threshold reuses one decomposition.
    """
    def compute():
        base = basis.base if is_extended(basis) else basis
        K_u = basis.unique_index.shape[0] if is_extended(basis) else basis.k
        d = column_weights(basis, normalization)
        if is_extended(basis) and K_u > base.n and base.mass_is_diagonal:
            X = _scaled_columns(basis, d)
            w, V = sla.eigh(X @ X.T, driver="evd")  # all eigenpairs: divide and conquer, ~2.5x MRRR
            side = "dual"
        else:
            G = _gram(basis)
            w, V = sla.eigh(G if d is None else d[:, None] * G * d, driver="evd")
            side = "primal"
        return w[::-1], V[:, ::-1], side

    if is_extended(basis):
        return basis.cache.get("gram_eig" if normalization == "area" else ("gram_eig", normalization), compute)
    return compute()


def _scaled_columns(basis, d) -> np.ndarray:
    """``X = sqrt(A) B_s D`` ``(n, K_u)`` (lumped mass; ``d`` None: ``D = I``)."""
    B_s, base, _, _ = _solver_parts(basis)
    X = np.sqrt(base.mass)[:, None] * (basis.solver_basis()[0] if B_s is None else B_s)
    return X if d is None else X * d


def _rmatmul(basis, Y):
    """``B_sᵀ Y`` for a Basis or ProductBasis."""
    return basis.solver_rmatmul(Y) if is_extended(basis) else basis.vecs.T @ Y


def _gram(basis) -> np.ndarray:
    """``B_sᵀ A B_s`` (symmetric) for a Basis or ProductBasis (cached and blocked there)."""
    return basis.solver_gram() if is_extended(basis) else mass_gram(basis.vecs, basis)


def mass_gram(B: np.ndarray, base: Basis) -> np.ndarray:
    """``Bᵀ A B`` ``(K, K)``, symmetrised, for the columns ``B`` ``(n, K)`` and the mass of ``base``."""
    if base.mass_is_diagonal:
        X = np.sqrt(base.mass)[:, None] * B
        G = X.T @ X
    else:
        G = B.T @ (base.mass @ B)
    return 0.5 * (G + G.T)


def _fista(op: ApproximationOperator, F: np.ndarray) -> np.ndarray:
    """Lasso by FISTA on the Gram matrix, all functions at once (columns independent).

    Objective per column: ``½ aᵀ G a - bᵀ a + λ ||a||₁`` with ``b = Bᵀ A f`` (equal to the
    area-weighted least squares up to a constant). In the ordered convention the Gram matrix
    of the ordered basis is ``Sᵀ G_s S``, formed once (``K x K``, dense). One product with it per
    iteration: ``G y`` follows from ``G x`` by linearity (``y`` is a combination of the last two
    iterates). The optimality conditions are checked every ``_FISTA_CHECK`` iterations and at
    the last one, so a run stops at most that many iterations after they first hold.
    """
    basis = op.basis
    B_s, base, E, K = _solver_parts(basis)
    G_s, d = op._G, op._d  # Gram of the scaled columns B_s D; the solution is a = D x
    one = F.ndim == 1
    F2 = F[:, None] if one else F
    b_s = _rmatmul(basis, base.apply_mass(F2))  # (K_u, m)
    if d is not None:
        b_s = d[:, None] * b_s
    if E is None:
        G, b = G_s, b_s
    else:
        EG = np.asarray(E @ G_s)  # (K, K_u)
        G = np.asarray(E @ EG.T)  # (K, K) = E G_s Eᵀ
        G = 0.5 * (G + G.T)
        b = E @ b_s
    L = sla.eigh(G_s, eigvals_only=True, subset_by_index=[G_s.shape[0] - 1] * 2)[0]
    lam = op.params["eps"] * np.max(np.abs(b), axis=0)  # (m,)
    lam = np.where(lam > 0, lam, 1.0)
    tol, max_iter = op.params["tol"], op.params["max_iter"]
    x, Gx = np.zeros_like(b), np.zeros_like(b)
    y, Gy = x, Gx
    t = 1.0
    for it in range(max_iter if b.shape[1] else 0):  # no functions (F of shape (n, 0)): nothing to fit
        z = y - (Gy - b) / L
        x_new = np.sign(z) * np.maximum(np.abs(z) - lam / L, 0.0)
        Gx_new = G @ x_new
        t_new = 0.5 * (1 + np.sqrt(1 + 4 * t * t))
        beta = (t - 1) / t_new
        y = x_new + beta * (x_new - x)
        Gy = Gx_new + beta * (Gx_new - Gx)
        x, Gx, t = x_new, Gx_new, t_new
        if ((it + 1) % _FISTA_CHECK == 0 or it + 1 == max_iter) and _lasso_violation(Gx - b, x, lam) < tol:
            break
    if d is not None:
        x = (d[:, None] if E is None else (abs(E).sign() @ d)[:, None]) * x  # back to the basis' columns
    return x[:, 0] if one else x


_FISTA_CHECK = 10  # FISTA iterations between two checks of the lasso optimality conditions


def _lasso_violation(g: np.ndarray, x: np.ndarray, lam: np.ndarray) -> float:
    """Largest violation of the lasso optimality conditions, relative to λ.

    ``g = Gx - b`` is the gradient of the smooth part: ``g_j = -λ sign(x_j)`` where
    ``x_j != 0`` and ``|g_j| <= λ`` where ``x_j = 0``.
    """
    nz = x != 0
    v_nz = np.where(nz, np.abs(g + lam * np.sign(x)), 0.0)
    v_z = np.where(~nz, np.maximum(np.abs(g) - lam, 0.0), 0.0)
    return float(np.max(np.maximum(v_nz, v_z) / lam))


def approximate(F, basis, method: str = "svd", **params) -> np.ndarray:
    """Coefficients of ``F`` ``(n,)``/``(n, m)`` in ``basis`` (a Basis or ProductBasis).

    ``method``: ``"std"`` | ``"ridge"`` | ``"lasso"`` | ``"svd"`` (Approach B, default);
    ``params`` as in :func:`approximation_operator` (``rtol=1e-3`` as in the paper). Operators
    of a ProductBasis are cached on it, so repeated calls reuse the factorisation.

    Parameters
    ----------
    F : (n,) or (n, m) array_like of float
        Function(s) on the ``n`` points of the basis.
    basis : Basis or ProductBasis
    method : str
        The approximation; ``"std"`` is the A-orthogonal projection ``Φᵀ A F``.
    **params
        Passed to :func:`approximation_operator`.

    Returns
    -------
    (K,) or (K, m) ndarray
        Coefficients in the basis' column order (``basis.K`` or ``basis.k`` columns).

    Raises
    ------
    ValueError
        For an unknown method, functions of the wrong shape, complex or non-finite values.
    TypeError
        For parameters the method does not take.

    Examples
    --------
    >>> import numpy as np
    >>> import prodmaps as pm
    >>> from prodmaps.mesh import ellipsoid
    >>> mesh = ellipsoid(2)
    >>> b = pm.eigenbasis(mesh, 6)
    >>> f = mesh.vertices[:, 0] * mesh.vertices[:, 1]  # a product of two coordinates
    >>> a = pm.approximate(f, pm.product_basis(b), rtol=1e-3)
    >>> a.shape
    (31,)
    >>> std = pm.approximate(f, b, "std")
    >>> bool(np.allclose(std, b.vecs.T @ (b.mass * f)))
    True
    """
    op = basis.operator(method, **params) if is_extended(basis) else approximation_operator(basis, method, **params)
    return op.coefficients(F)


_OPERATOR_DEFAULTS = {name: p.default for name, p in inspect.signature(approximation_operator).parameters.items()
                      if p.kind is inspect.Parameter.KEYWORD_ONLY}
