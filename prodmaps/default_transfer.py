"""The library's default extended transfer: products only where the map carries them faithfully.

Why
---
The paper's Approach B (fixed threshold ``rtol = 1e-3`` on the singular values of the extended
basis) keeps every singular direction above the threshold, including directions of the source
whose products nearly cancel there; a truncated or computed ``C`` does not preserve products
exactly, the cancellation is lost on the target and such directions are amplified. How many the
threshold keeps depends on the normalisation of the basis (:mod:`prodmaps.approx`): under the
metre reading (A-orthonormal eigenfunctions of meshes in metres) gains of 20 with ground-truth
maps and 100+ with computed ones made coordinates, indicators, SHOT and AWFT transfer 2–30x worse
than the standard transfer on the embedded humans; under the default unit-Euclidean reading the
kept directions have gains near 1 at ``rtol = 1e-3``. This default needs no threshold and no
normalisation: it is never worse than the standard transfer in our measurements (it reduces to the
standard transfer exactly when no product direction passes its tests).

The rule (two-stage, gain- and leak-filtered fit; only ``f``, ``C_12`` and the two bases)
------------------------------------------------------------------------------------------
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
Measured (``study_default``; a single function is one column of one pair): on the eight public
FAUST registrations — every one of the 56 ordered pairs with ground-truth and perturbed maps at
9/9, 29/39, 27/35 and 6/7, and the paper profile's 8 pairs with NO17 maps as well (6972
functions) — no single function was worse than the standard transfer by more than 0.01 (worst
+0.0088 with the earlier NO17 maps, +0.0025 with the paper profiles' ICP-refined recipe), with a
mean error 0.89 (0.83) times the standard transfer's; on the embedded humans' smoke
conditions (2158 functions) worst +0.0022, 0.85 times. Without the truncation test the rule was
safe per family but not per function (20 of 4648 functions above std + 0.01 with ground-truth maps
at 9/9 on the 56 FAUST pairs, worst +0.10 on a coordinate; up to +0.12 with NO17 maps), with a
lower mean (0.73-0.78 times std): the test trades part of the average gain for that guarantee.
Known limit: the truncation test reads the map's losses from ``CᵀC``; a map orthogonalised
afterwards (ICP's projection on orthogonal matrices, as the paper profiles' NO17 recipe does) has
``CᵀC = I`` whatever it lost, and the test is blind. With such maps on the embedded humans'
smoke conditions 2 of 2158 single functions (heat kernels from 200 eigenpairs, one intra pair, at
27/35 and 29/39) came out above std + 0.01 (worst +0.36); per family none did.

Cost: one ``Kp x Kp`` symmetric eigendecomposition (as Approach B) on the source, reusing the
product Gram, plus ``Z`` and ``Y = (Z - ΨH) V`` on the target (``n2 · Kp · r`` flops) per map. The
operator is built once per ``(C_12, basis_1, basis_2)`` and applied to any number of functions.

Conventions: :mod:`prodmaps.conventions` (``C_12`` ``(k2, k1)``, A-orthonormal bases with the
constant first, ``k`` counts the constant); lumped (diagonal) masses.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg as sla

from .approx import check_functions
from .basis import Basis
from .files import sha256_bytes
from .products import evaluate_products, product_basis

__all__ = ["SafeTransfer", "safe_transfer", "isometry_defect", "DEFAULTS"]

DEFAULTS = {"g0": 1.5, "p": 8, "l0": 0.5, "e0": 0.4, "floor": 1e-3, "h_min": 1e-4}
# the product images are formed in one piece up to this size, else by blocks of rows (same
# arithmetic per row; the block sums of the norms differ from one sum at rounding level)
_SINGLE_BLOCK_BYTES = 512 << 20
_BLOCK_ROWS = 1 << 16


def _source_parts(basis_1: Basis):
    """``(H (k1, Kp), σ² (r,), V (Kp, r), g_PP (Kp,), ext_u)`` of the residual stage, cached on the
    source; ``g_PP`` holds the squared area norms ``||φ_l φ_m||²_A1`` of the products.

    The unique product Gram is the one Approach B uses; if only the ordered (paper's) one is
    cached it is recovered exactly (the ordered solver basis is the unique basis scaled by
    ``sqrt(#orderings)``).
    """
    ext_u = product_basis(basis_1, 2, "unique")
    ext_o = product_basis(basis_1, 2, "ordered")

    def gram():
        if "gram" not in ext_u.cache and "gram" in ext_o.cache:
            s = ext_o._solver_scale()
            return ext_o.solver_gram() / np.outer(s, s)
        return ext_u.solver_gram()  # (K_u, K_u) = [Φ1, P1]ᵀ A1 [Φ1, P1]

    def parts():
        G = gram()
        k1 = basis_1.k
        H = np.ascontiguousarray(G[:k1, k1:])  # (k1, Kp)
        S = G[k1:, k1:] - H.T @ H  # (Kp, Kp) Schur complement = QᵀA1Q
        lam, V = sla.eigh(0.5 * (S + S.T), check_finite=False)  # ascending
        return H, lam[::-1].copy(), np.ascontiguousarray(V[:, ::-1]), np.diag(G)[k1:].copy()

    H, lam, V, gpp = ext_u.cache.get("safe_transfer_parts", parts)
    return H, lam, V, gpp, ext_u


def isometry_defect(C_12: np.ndarray, area_ratio: float = 1.0) -> np.ndarray:
    """``δ_l = ||(I - C_12ᵀ C_12 / ρ²) e_l||_2`` ``(k1,)``, ``ρ² = area_2 / area_1``.

    For the functional map of a point map between near-isometric shapes, ``C_12ᵀ C_12 ≈ ρ² I``
    (norms and orthogonality of the pulled-back eigenfunctions are kept): ``δ_l`` is how far
    column ``l`` is from that. With ``C_12`` the exact projection of a point map, the diagonal part
    is the fraction ``||e_l||² / ρ²`` of the image of ``φ_l`` lost outside ``span Φ2`` (truncation);
    noise or a map that is not a point map adds off-diagonal terms. No ground truth is used.
    """
    C = np.asarray(C_12, dtype=float)
    D = np.eye(C.shape[1]) - (C.T @ C) / float(area_ratio)  # (k1, k1)
    return np.linalg.norm(D, axis=1)


class SafeTransfer:
    """The default extended transfer operator for one ``(C_12, basis_1, basis_2)`` (module doc).

    ``op(F)`` transfers ``F`` ``(n1,)``/``(n1, m)`` to shape 2; ``op.approximate(F)`` is the
    corresponding approximation on shape 1; ``op.coefficients(F)`` the coefficients in the
    unique-pair extended basis of shape 1 (``op.extended_basis``).

    Parameters
    ----------
    C_12 : ``(basis_2.k, basis_1.k)`` functional map from shape 1 to shape 2.
    g0, p : gain scale and order of the filter ``1/(1 + (γ/g0)^p)`` (defaults 1.5 and 8: a soft
        cut at 1.5 times the area-ratio-corrected norm a point map would give).
    l0 : leak scale (default 0.5; ``None`` switches the leak test off).
    e0 : scale of the truncation test (default 0.4; ``None`` switches it off): the expected relative
        error of direction ``i``'s image, ``ê_i² = Σ_(l,m) V_(lm),i² (δ_l + δ_m) ||φ_l φ_m||²_A1 / σ_i²``
        from :func:`isometry_defect` (a first-order model: ``ψ_l ψ_m`` misses
        ``ψ_l e_m + e_l ψ_m`` when ``ψ_l = φ_l∘T - e_l``), enters as ``1/(1 + (ê_i/e0)²)`` (the
        Wiener factor of an estimate with relative error ``ê_i/e0``).
    floor : directions with ``σ_i <= floor · σ_max`` of the residual Gram are ignored (1e-3: never a
        direction the paper's threshold would drop).
    h_min : directions with ``h_i < h_min`` are not stored (cost only).
    pairs : accepted for symmetry with :func:`prodmaps.transfer`; the rule works on the unique
        (multiset) products, whose span is the same in both conventions.
    """

    def __init__(self, C_12, basis_1: Basis, basis_2: Basis, *, g0: float = DEFAULTS["g0"], p: float = DEFAULTS["p"],
                 l0: float | None = DEFAULTS["l0"], e0: float | None = DEFAULTS["e0"],
                 floor: float = DEFAULTS["floor"],
                 h_min: float = DEFAULTS["h_min"], pairs: str = "unique"):
        from .mapping import check_fmap

        C = check_fmap(C_12, basis_1, basis_2)
        if not (basis_1.mass_is_diagonal and basis_2.mass_is_diagonal):
            raise ValueError("the default extended transfer needs lumped (diagonal) masses; build the bases with "
                             "mass='lumped' or pass rtol=... for the paper's Approach B")
        for name, v in (("g0", g0), ("p", p), ("floor", floor), ("h_min", h_min)):
            if not (np.isfinite(v) and v > 0):
                raise ValueError(f"{name} must be finite and > 0, got {v!r}")
        for name, v in (("l0", l0), ("e0", e0)):
            if v is not None and not (np.isfinite(v) and v > 0):
                raise ValueError(f"{name} must be finite and > 0 (or None), got {v!r}")
        self.C, self.basis_1, self.basis_2 = C, basis_1, basis_2
        self.params = {"g0": g0, "p": p, "l0": l0, "e0": e0, "floor": floor, "h_min": h_min}
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

    def __call__(self, F) -> np.ndarray:
        """The transfer of ``F`` to shape 2, ``(n2,)`` or ``(n2, m)``."""
        one, a0, c = self._stages(F)
        g = self._Psi @ a0 + self._Y @ c
        return g[:, 0] if one else g

    transfer = __call__

    def coefficients(self, F) -> np.ndarray:
        """Coefficients ``(K_u,)``/``(K_u, m)`` in :attr:`extended_basis` (unique pairs) of the fit on
        shape 1; ``pm.extend_fmap(C, b1, b2, pairs="unique") @ coefficients`` transfers them."""
        one, a0, c = self._stages(F)
        w = self._V @ c  # (Kp, m) product coefficients
        coefs = np.vstack([a0 - self._D @ c - self.H @ w, w])  # Φ1 (a0 - D c) + Q w = Φ1 (a0 - D c - H w) + P1 w
        return coefs[:, 0] if one else coefs

    def approximate(self, F) -> np.ndarray:
        """The approximation of ``F`` on shape 1 that this transfer carries, ``(n1,)``/``(n1, m)``."""
        return self.extended_basis.evaluate(self.coefficients(F))

    def __repr__(self) -> str:
        return (f"SafeTransfer(k1={self.basis_1.k}, k2={self.basis_2.k}, kept {self.rank} of "
                f"{self.sigma.size} product directions, g0={self.params['g0']}, l0={self.params['l0']})")


def _key(C, basis_2: Basis, params: dict) -> tuple:
    digest = sha256_bytes(np.ascontiguousarray(C).tobytes() + np.ascontiguousarray(basis_2.vecs).tobytes()
                          + np.ascontiguousarray(basis_2.mass).tobytes())[:24]
    return ("safe_transfer", digest, tuple(sorted(params.items())))


def safe_operator(C_12, basis_1: Basis, basis_2: Basis, **params) -> SafeTransfer:
    """The :class:`SafeTransfer` of ``(C_12, basis_1, basis_2)``, cached on basis_1's product basis
    (keyed by the bytes of ``C_12`` and ``basis_2``), so repeated calls reuse it."""
    from .mapping import check_fmap

    C = check_fmap(C_12, basis_1, basis_2)
    if basis_1.k < 2:
        raise ValueError(f"the default extended transfer needs a non-constant function in basis_1 (k >= 2, the "
                         f"constant counts); got k = {basis_1.k}: there are no products to add, use method='std'")
    full = {**DEFAULTS, **params}
    full.pop("pairs", None)
    ext_u = product_basis(basis_1, 2, "unique")
    return ext_u.cache.get(_key(C, basis_2, full), lambda: SafeTransfer(C, basis_1, basis_2, **full))


def safe_transfer(F, C_12, basis_1: Basis, basis_2: Basis, **params) -> np.ndarray:
    """Transfer ``F`` ``(n1,)``/``(n1, m)`` with the default extended rule (module doc).

    The same as ``pm.transfer(F, C_12, basis_1, basis_2, method="prod")`` without ``rtol``.

    Parameters
    ----------
    F : (n1,) or (n1, m) array_like of float
        Function(s) on shape 1.
    C_12 : (k2, k1) array_like
        Functional map, coefficients on shape 1 to shape 2.
    basis_1, basis_2 : Basis
        A-orthonormal bases, constant first.
    **params
        The rule's ``g0``, ``p``, ``l0``, ``floor``, ``h_min`` (defaults in
        :data:`prodmaps.default_transfer.DEFAULTS`).

    Returns
    -------
    (n2,) or (n2, m) ndarray
        The transferred function(s) on shape 2.

    Raises
    ------
    ValueError
        For functions or maps of the wrong shape, complex or non-finite values.
    TypeError
        For a basis that is not a :class:`prodmaps.Basis` or an unknown parameter.

    Examples
    --------
    >>> import numpy as np
    >>> import prodmaps as pm
    >>> from prodmaps.mesh import ellipsoid
    >>> mesh = ellipsoid(2)
    >>> b = pm.eigenbasis(mesh, 6)
    >>> f = mesh.vertices[:, 0] * mesh.vertices[:, 1]
    >>> g = pm.safe_transfer(f, np.eye(6), b, b)
    >>> g.shape
    (162,)
    >>> std = pm.transfer(f, np.eye(6), b, b)  # the products recover more of f than the standard transfer
    >>> bool(pm.relative_error(g, f, b.mass) < pm.relative_error(std, f, b.mass))
    True
    """
    return safe_operator(C_12, basis_1, basis_2, **params)(F)
