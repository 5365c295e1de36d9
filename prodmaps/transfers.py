"""Function transfer: one family of operators, built once per map and applied to many functions.

``T = pm.transfer_operator(C_12, basis_1, basis_2, method=...)`` builds everything that depends
only on the map and the bases (the source's approximation operator, the extended map ``C~`` and
the target's extended basis, or the default rule's filtered directions); ``T(F)`` (or
``T.apply(F)``) then transfers any number of functions, ``(n1,)`` or the columns of
``(n1, m)``, to shape 2. ``pm.transfer(F, C_12, basis_1, basis_2, method=...)`` is that
operator applied once.

Conventions (bases, ``k``, ``C_12`` ``(k2, k1)``, ``C~``): :mod:`prodmaps.conventions`; by Lemma 2,
``B2 C~ a`` is the exact pointwise product of the transferred basis functions for *any* ``C``.

Methods, each with its own keyword parameters (:data:`PARAMETERS`)
-------------------------------------------------------------------
``"std"`` (no parameters)
    The standard transfer ``Φ2 C_12 Φ1ᵀ A1 F``: A-orthogonal projection, then the map.
``"default"`` (``g0``, ``p``, ``l0``, ``e0``, ``floor``, ``h_min``; :data:`DEFAULT_RULE`)
    **The library's default extended transfer** (:class:`DefaultTransfer`, the rule below): the
    standard transfer plus the product directions the map carries faithfully, tested without
    ground truth. Never changes what the standard transfer carries and reduces to it exactly when
    no direction passes. Pairwise products (order 2); the unique and ordered products span the
    same space, so it has no ``order``/``pairs``.
``"svd"`` (``order=2``, ``pairs="ordered"``, ``rtol=1e-3``, ``route``, ``normalization``)
    **The paper's Approach B**: ``B2 C~ a`` with ``a`` the truncated-SVD coefficients of ``F`` in
    the source's extended basis; ``rtol=1e-3`` with the ordered pairs is the paper's exactly.
``"ridge"``, ``"lasso"`` (``order``, ``pairs``, ``eps``, ``normalization``; ``penalty``; ``tol``, ``max_iter``)
    **The paper's Approach A** (p = 2, p = 1): ``B2 C~ a`` with ``a`` the penalised fit; the ridge
    also takes ``penalty`` (``"norm"``: Equation 4 as printed), the lasso ``tol`` and ``max_iter``.

The solver parameters are those of :func:`prodmaps.approx.approximation_operator` (where they are
defined); a parameter of another method raises ``TypeError``.

Old spellings (deprecated for one release: they warn, name the new spelling, give the same numbers)
----------------------------------------------------------------------------------------------------
* ``transfer(F, C, b1, b2, "prod")`` and ``safe_transfer(F, C, b1, b2)``:
  ``transfer(F, C, b1, b2, "default")``;
* ``transfer(..., "prod", rtol=r, order=o, pairs=p)`` (``approx`` None or ``"svd"``):
  ``transfer(..., "svd", rtol=r, order=o, pairs=p)``;
* ``transfer(..., "prod", approx="ridge", eps=e)`` (or ``"lasso"``): ``transfer(..., "ridge", eps=e)``;
* ``prodmaps.default_transfer.safe_operator(C, b1, b2, **rule)``:
  ``transfer_operator(C, b1, b2, "default", **rule)``; ``default_transfer.SafeTransfer`` and
  ``DEFAULTS``: :class:`DefaultTransfer` and :data:`DEFAULT_RULE`.

The default rule
----------------
The paper's Approach B (fixed threshold ``rtol = 1e-3`` on the singular values of the extended
basis) keeps every singular direction above the threshold, including directions of the source
whose products nearly cancel there; a truncated or computed ``C`` does not preserve products
exactly, the cancellation is lost on the target and such directions are amplified (how many
the threshold keeps depends on the normalisation of the basis, :mod:`prodmaps.approx`). The
default needs no threshold and no normalisation (measurements: ``docs/guide/default_transfer.md``).

The rule (two-stage, gain- and leak-filtered fit; only ``f``, ``C_12`` and the two bases):

Notation: ``Φ1`` ``(n1, k1)``; ``P1`` ``(n1, Kp)`` the products ``φ_l φ_m``, ``1 <= l <= m < k1``
(multisets, ``Kp = k(k+1)/2``); ``Ψ = Φ2 C_12`` ``(n2, k1)`` the transferred basis functions and
``Z = [ψ_l ψ_m]`` ``(n2, Kp)`` their products — by Lemma 2, ``B2 C~ [x; b] = Ψ x + Z b`` exactly,
for any ``C``.

1. **Standard stage**: ``a0 = Φ1ᵀ A1 f``; the residual ``r = f - Φ1 a0`` is A1-orthogonal to
   span Φ1. The standard transfer is ``Ψ a0``.
2. **Residual stage**: the products made A1-orthogonal to span Φ1, ``Q = P1 - Φ1 H`` with
   ``H = Φ1ᵀ A1 P1``; their Gram ``S = QᵀA1Q = G_PP - HᵀH`` comes from the source's cached product
   Gram (the one Approach B builds). ``S = V diag(σ²) Vᵀ``: direction ``i`` has source function
   ``Q v_i`` (area norm ``σ_i``) and target image ``y_i = (Z - Ψ H) v_i``.
3. **Three tests per direction, no ground truth** (``Π`` the A2-projection on
   ``range(Ψ) = Φ2 range(C)``, the span of the standard transfer):

   * leak ``λ_i = ||Π y_i||_A2 / ||y_i||_A2``: a point map sends functions A1-orthogonal to
     span Φ1 (as ``Q v_i`` is) to functions nearly orthogonal to the image of span Φ1; a map that
     is not multiplicative can keep norms yet move products into that image ("moves products to
     the wrong place"). That part ``Π y_i`` is error by this argument and is removed: the
     direction's image is ``y'_i = (I - Π) y_i``;
   * transfer gain ``γ_i = ||y'_i||_A2 / (ρ σ_i)``, ``ρ = sqrt(area_2 / area_1)`` (a near-isometric
     point map scales L2 norms by ``ρ``, so ``γ_i ≈ 1`` for a map that preserves products);
   * truncation error ``ê_i``: even the exact projection of a point map carries only the part of
     each ``φ_l∘T`` inside ``span Φ2``; the products of these truncated images miss
     ``ψ_l e_m + e_l ψ_m`` (``e_l`` the lost part). ``C`` itself tells how much is lost:
     for a near-isometric point map ``CᵀC ≈ ρ² I``, and the row defect
     ``δ_l = ||(I - CᵀC/ρ²) e_l||`` (:func:`isometry_defect`; ``||e_l||²/ρ²`` for an exact
     projection, plus whatever noise or a non-point map adds) gives the model
     ``ê_i² = Σ_(l,m) V_(lm),i² (δ_l + δ_m) ||φ_l φ_m||²_A1 / σ_i²``: directions that are
     near-cancellations of products (small ``σ_i``) amplify the truncation error.

   Filter factors ``h_i = 1/(1 + (γ_i/g0)^p) · 1/(1 + (λ_i/l0)^p) · 1/(1 + (ê_i/e0)²)`` (the
   last is the Wiener factor of an image with relative error ``ê_i/e0``), directions with
   ``σ_i <= floor · σ_max`` (numerically dependent products) dropped.
4. ``g = Ψ a0 + Σ_i h_i y'_i (v_iᵀ q) / σ_i²`` with ``q = Qᵀ A1 r = P1ᵀ A1 f - Hᵀ a0``.

By construction: every ``h_i = 0`` gives exactly the standard transfer; the products add
nothing inside the standard transfer's span (``Π g = Ψ a0`` exactly, for any filter: what the
standard transfer carries is never changed); each kept direction adds at most
``h_i γ_i ρ |u_iᵀ√A1 r|`` (``h γ <= 0.91 g0`` for ``p = 8``) and ``Σ (u_iᵀ√A1 r)² <= ||r||²``, so
the added part is bounded by about ``g0 ρ ||r||`` times the coherence of the images. Measured,
not guaranteed: that the added part *reduces* the error (it needs the kept images to be right).

Cost: one ``Kp x Kp`` symmetric eigendecomposition (as Approach B) on the source, reusing the
product Gram, plus ``Z`` and ``Y = (Z - ΨH) V`` on the target (``n2 · Kp · r`` flops) per map. The
operator is built once per ``(C_12, basis_1, basis_2)`` and applied to any number of functions.
"""

from __future__ import annotations

import warnings

import numpy as np
import scipy.linalg as sla

from .basis import Basis
from .checks import check_fmap, check_functions
from .files import sha256_bytes
from .mapping import extend_fmap
from .products import check_pairs, evaluate_products, product_basis, unique_solver_gram

__all__ = ["TransferOperator", "StandardTransfer", "DefaultTransfer", "ExtendedTransfer", "transfer_operator",
           "transfer", "isometry_defect", "safe_transfer", "METHODS", "PARAMETERS", "DEFAULT_RULE"]

METHODS = ("std", "default", "svd", "ridge", "lasso")
DEFAULT_RULE = {"g0": 1.5, "p": 8, "l0": 0.5, "e0": 0.4, "floor": 1e-3, "h_min": 1e-4}
"""The default rule's parameters and their values (see :class:`DefaultTransfer`)."""
PARAMETERS = {
    "std": (),
    "default": tuple(DEFAULT_RULE),
    "svd": ("order", "pairs", "rtol", "route", "normalization"),
    "ridge": ("order", "pairs", "eps", "normalization", "penalty"),
    "lasso": ("order", "pairs", "eps", "tol", "max_iter", "normalization"),
}
"""The keyword parameters each method takes (any other raises ``TypeError``)."""

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


def _not_a_parameter(method: str, names) -> str:
    """The message for parameters ``names`` that ``method`` does not take."""
    names = sorted(names)
    owners = {n: [m for m in METHODS if n in PARAMETERS[m]] for n in names}
    where = "; ".join(f"{n!r} is a parameter of {', '.join(repr(m) for m in ms)}" if ms else f"{n!r} is no method's"
                      for n, ms in owners.items())
    takes = ", ".join(PARAMETERS[method]) or "none"
    return f"method={method!r} takes no parameter {', '.join(map(repr, names))} (its parameters: {takes}); {where}"


class TransferOperator:
    """A transfer from shape 1 to shape 2, built once for ``(C_12, basis_1, basis_2)`` (module doc).

    Build with :func:`transfer_operator`. ``op(F)`` (or ``op.apply(F)``) transfers ``F``
    ``(n1,)``/``(n1, m)`` to shape 2, ``(n2,)``/``(n2, m)``; the columns of ``F`` are independent,
    so transferring ``F`` in parts gives the same columns (to rounding; the lasso's iterations stop
    when every column meets its tolerance, so there to that tolerance). ``op.approximate(F)`` is the
    approximation of ``F`` on shape 1 that the transfer carries. ``method`` and ``params`` (the
    method's parameters as given) say what was built; ``C`` is the validated ``(k2, k1)`` map.

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
    """``method="svd"`` (Approach B), ``"ridge"`` or ``"lasso"`` (Approach A): ``B2 C~ a``.

    ``a`` ``(K1,)``/``(K1, m)`` are the coefficients of ``F`` in the source's extended basis
    (:attr:`extended_basis_1`, ``order`` and ``pairs`` of :func:`prodmaps.product_basis`) by the
    approximation operator :attr:`approximation` (cached on that basis,
    :meth:`prodmaps.ProductBasis.operator`); :attr:`extended_map` is ``C~`` ``(K2, K1)`` and
    :attr:`extended_basis_2` the target's extended basis. All are built here, once.

    Parameters
    ----------
    C_12 : (k2, k1) array_like
    basis_1, basis_2 : Basis
    method : ``"svd"`` | ``"ridge"`` | ``"lasso"``
    order, pairs : the extended bases (the paper's: 2, ``"ordered"``).
    **solver
        The approximation's parameters (:data:`PARAMETERS`; defined by
        :func:`prodmaps.approx.approximation_operator`); ``"svd"`` uses ``rtol=1e-3`` unless given.

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

    def __init__(self, C_12, basis_1: Basis, basis_2: Basis, method: str = "svd", *, order: int = 2,
                 pairs: str = "ordered", **solver):
        if method not in ("svd", "ridge", "lasso"):
            raise ValueError(f"ExtendedTransfer's method is 'svd', 'ridge' or 'lasso', got {method!r}")
        unknown = set(solver) - set(PARAMETERS[method])
        if unknown:
            raise TypeError(_not_a_parameter(method, unknown))
        if method == "svd" and "rtol" not in solver:
            solver["rtol"] = 1e-3  # the paper's threshold
        super().__init__(C_12, basis_1, basis_2, {"order": order, "pairs": pairs, **solver})
        check_pairs(pairs)
        self.method = method
        self.extended_basis_1 = product_basis(basis_1, order, pairs)
        self.extended_basis_2 = product_basis(basis_2, order, pairs)
        self.approximation = self.extended_basis_1.operator(method, **solver)
        self.extended_map = extend_fmap(self.C, basis_1, basis_2, order, pairs)  # (K2, K1)

    def coefficients(self, F) -> np.ndarray:
        """The coefficients ``a`` ``(K1,)``/``(K1, m)`` of ``F`` in :attr:`extended_basis_1`."""
        return self.approximation.coefficients(check_functions(F, self.basis_1.n))

    def apply(self, F) -> np.ndarray:
        """``B2 C~ a``: the transfer of ``F`` to shape 2 (:meth:`TransferOperator.apply`)."""
        return self.extended_basis_2.evaluate(self.extended_map @ self.coefficients(F))

    def approximate(self, F) -> np.ndarray:
        """``B1 a``: the fit of ``F`` in the source's extended basis."""
        return self.extended_basis_1.evaluate(self.coefficients(F))


class DefaultTransfer(TransferOperator):
    """``method="default"``: the library's default extended transfer (module doc, "The default rule").

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
        error ``ê_i`` of direction ``i``'s image (module doc, from :func:`isometry_defect`) enters as
        ``1/(1 + (ê_i/e0)²)``.
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
        """The standard transfer plus the filtered product directions (module doc, step 4)."""
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
    method : ``"std"`` (default) | ``"default"`` | ``"svd"`` | ``"ridge"`` | ``"lasso"``
        The standard transfer; the library's default extended transfer; the paper's Approach B;
        Approach A (p = 2, p = 1).
    **params
        The method's own parameters, :data:`PARAMETERS` (``"default"``: the rule's :data:`DEFAULT_RULE`).

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
    if method not in METHODS:
        hint = (" (method='prod' is transfer()'s deprecated spelling: 'default' without a threshold, 'svd' with rtol, "
                "'ridge'/'lasso' for approx=...)" if method == "prod" else "")
        raise ValueError(f"method must be one of {METHODS}, got {method!r}{hint}")
    unknown = set(params) - set(PARAMETERS[method])
    if unknown:
        raise TypeError(_not_a_parameter(method, unknown))
    if method == "std":
        return StandardTransfer(C_12, basis_1, basis_2)
    if method == "default":
        C = check_fmap(C_12, basis_1, basis_2)
        full = {**DEFAULT_RULE, **params}
        ext_u = product_basis(basis_1, 2, "unique")
        return ext_u.cache.get(_default_key(C, basis_2, full), lambda: DefaultTransfer(C, basis_1, basis_2, **full))
    return ExtendedTransfer(C_12, basis_1, basis_2, method, **params)


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
    method : ``"std"`` (default) | ``"default"`` | ``"svd"`` | ``"ridge"`` | ``"lasso"``
        As in :func:`transfer_operator`. The old ``"prod"`` (with ``rtol``, ``approx``, ``order``,
        ``pairs`` and the rule's parameters) still works, with a ``DeprecationWarning`` that names
        the new spelling (module doc).
    **params
        The method's own parameters (:data:`PARAMETERS`).

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
    if method == "prod":
        method, params = _prod_spelling(params)
    elif "approx" in params:
        raise TypeError(f"approx= belongs to the deprecated method='prod'; pass method='svd', 'ridge' or 'lasso' "
                        f"(got method={method!r})")
    return transfer_operator(C_12, basis_1, basis_2, method, **params)(F)


_SOLVER_KEYWORDS = ("rtol", "eps", "route", "tol", "max_iter", "normalization")  # approximation_operator's


def _prod_spelling(params: dict) -> tuple[str, dict]:
    """The new method and parameters of ``transfer(..., method="prod", **params)``, with a warning.

    The old meaning: without ``rtol`` and ``approx`` the default rule (``order=2``; ``pairs``
    checked, then unused); else Approach B (``approx`` None or ``"svd"``, ``rtol=1e-3`` unless
    given) or Approach A (``approx="ridge"``/``"lasso"``), where the solver keywords the method
    does not use were accepted and had no effect (they are dropped: the same numbers).
    """
    params = dict(params)
    approx, rtol = params.pop("approx", None), params.pop("rtol", None)
    order, pairs = params.pop("order", 2), params.pop("pairs", "ordered")
    check_pairs(pairs)
    if rtol is None and approx is None:
        if order != 2:
            raise ValueError("the default extended transfer uses pairwise products (order=2); pass rtol=... "
                             "for the paper's Approach B with higher orders")
        unknown = set(params) - set(DEFAULT_RULE)
        if unknown:
            raise TypeError(f"unknown parameters {sorted(unknown)} for the default extended transfer "
                            f"(allowed: {sorted(DEFAULT_RULE)}); pass rtol=... for Approach B")
        new, new_params = "default", params
    else:
        new = approx or "svd"
        if new not in ("svd", "ridge", "lasso"):
            raise ValueError(f"approx must be 'svd', 'ridge' or 'lasso', got {approx!r}")
        if new == "svd":
            rtol = 1e-3 if rtol is None else rtol
        elif rtol is not None:
            raise TypeError(f"rtol is Approach B's threshold; approx={approx!r} takes eps=...")
        unused = {k for k in params if k in _SOLVER_KEYWORDS and k not in PARAMETERS[new]}
        new_params = {"order": order, "pairs": pairs, **({"rtol": rtol} if new == "svd" else {}),
                      **{k: v for k, v in params.items() if k not in unused}}
    shown = ", ".join(f"{k}={v!r}" for k, v in new_params.items())
    warnings.warn(f"transfer(..., method='prod') is deprecated: use transfer(..., method={new!r}"
                  f"{', ' + shown if shown else ''}) (the same numbers), or transfer_operator(C_12, basis_1, basis_2, "
                  f"{new!r}, ...) to build it once", DeprecationWarning, stacklevel=3)
    return new, new_params


def safe_transfer(F, C_12, basis_1: Basis, basis_2: Basis, **params) -> np.ndarray:
    """Deprecated: ``transfer(F, C_12, basis_1, basis_2, method="default", **params)``.

    Warns (``DeprecationWarning``) and gives the same numbers; ``pairs`` is accepted and unused,
    as before.

    Examples
    --------
    >>> import warnings
    >>> import numpy as np
    >>> import prodmaps as pm
    >>> from prodmaps.mesh import ellipsoid
    >>> b = pm.eigenbasis(ellipsoid(2), 6)
    >>> f = b.vecs[:, 1] * b.vecs[:, 2]
    >>> with warnings.catch_warnings():
    ...     warnings.simplefilter("ignore", DeprecationWarning)
    ...     old = pm.safe_transfer(f, np.eye(6), b, b)
    >>> bool(np.array_equal(old, pm.transfer(f, np.eye(6), b, b, "default")))
    True
    """
    warnings.warn("safe_transfer(F, C_12, basis_1, basis_2, ...) is deprecated: use transfer(F, C_12, basis_1, "
                  "basis_2, method='default', ...) (the same numbers)", DeprecationWarning, stacklevel=2)
    params.pop("pairs", None)
    return transfer_operator(C_12, basis_1, basis_2, "default", **params)(F)
