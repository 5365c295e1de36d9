"""Localized Manifold Harmonics (LMH) and the "MH + LMH" bases of Figure 10.

Reference: S. Melzi, E. Rodolà, U. Castellani, M. M. Bronstein, "Localized Manifold Harmonics
for Spectral Shape Analysis", Computer Graphics Forum 2018, doi:10.1111/cgf.13309 (arXiv 1707.02596).

Formulation (as implemented here)
---------------------------------
Given a region ``R`` of the surface described by a (soft) indicator ``u: V -> [0, 1]``
(``u = 1`` inside), and the first ``k_global`` global Laplace–Beltrami eigenfunctions
``Φ`` ``(n, k_global)`` (A-orthonormal, constant included), the ``k`` localized harmonics
``Ψ`` ``(n, k)`` minimise::

    E(Ψ) = trace(Ψᵀ W Ψ)                        Dirichlet energy (smoothness)
         + μ_R · trace(Ψᵀ A diag(1 - u) Ψ)      region penalty: L² mass outside R
         + μ_⊥ · ||Φᵀ A Ψ||_F²                  orthogonality penalty against Φ
    subject to  Ψᵀ A Ψ = I                      (A-orthonormal, area inner product)

``W`` is the PSD cotangent stiffness and ``A`` the lumped mass (see
:func:`prodmaps.laplacian`). All three terms are quadratic forms, so the minimisers are the
eigenvectors of the ``k`` smallest eigenvalues of the generalised symmetric problem::

    Q ψ = λ A ψ,   Q = W + μ_R · diag(A (1 - u)) + μ_⊥ · (A Φ)(A Φ)ᵀ.

This is the operator of the LMH paper (its Eq. for the "modified Laplacian"); we write the
region term with the mass, ``∫ (1-u) ψ²``, i.e. ``diag(A(1-u))``, which is the consistent
discretisation of the continuous penalty and makes the basis independent of the sampling
density. The numeric values of μ below are our choice.

Solver: ``Q`` is never formed densely; the eigenpairs come from the package's one eigensolver
(:func:`prodmaps.eigensolver.smallest_eigenpairs`, with its shift). ``Q = S0 + μ_⊥ U Uᵀ`` with sparse
``S0 = W + μ_R diag(A(1-u))`` and the thin ``U = A Φ`` ``(n, k_global)``. Shift-invert
Lanczos (:func:`scipy.sparse.linalg.eigsh`) needs ``(Q - σA)⁻¹``: with ``S = S0 - σA``
(``σ < 0`` slightly, so ``S`` is positive definite even when ``u ≡ 1``) and one sparse LU of
``S``, the Sherman–Morrison–Woodbury identity gives

    (S + μ_⊥ U Uᵀ)⁻¹ x = S⁻¹x - S⁻¹U (I/μ_⊥ + Uᵀ S⁻¹ U)⁻¹ Uᵀ S⁻¹ x,

a ``k_global x k_global`` dense system. Memory is O(nnz(W) + n·k_global).

Scale and default penalties
---------------------------
``W`` is scale invariant while ``A`` scales with area, so eigenvalues scale as
``1/area``. To make the basis independent of the shape's size, the user-facing weights are
given **for a shape of unit area**: the operator uses ``μ = mu / area``. Defaults
``mu_region = mu_orth = 1e4``:

* ``mu_orth`` must exceed the (unit-area) eigenvalues of the localized functions we keep,
  otherwise the penalised global functions (eigenvalues ``λ_j + μ_⊥``) re-enter the
  spectrum. For a region covering ~5 % of the area, the ``j``-th localized eigenvalue is
  about ``4πj/0.05 ≈ 250 j`` (Weyl), i.e. ~2.5e3 for ``j = 10``: ``1e4`` keeps up to ~30–40
  localized functions clean while staying well conditioned.
* ``mu_region``: outside ``R`` the functions decay like ``exp(-sqrt(μ_R)·d)``; with
  ``μ_R = 1e4`` on a unit-area shape the decay length is 1 % of the shape's size, so almost
  all of the L² mass stays in ``R`` (the test asserts > 90 %), while the penalty stays
  finite (a soft boundary, as in the LMH paper, unlike Dirichlet eigenfunctions of ``R``).

Conventions
-----------
``k`` of :func:`localized_harmonics` counts localized functions; ``k_global`` counts global
eigenfunctions **including the constant** (as :func:`prodmaps.eigenbasis`). Signs are fixed
like the eigenbasis' (entry of largest magnitude positive).

"MH + LMH" basis (Figure 10)
----------------------------
Products need a basis whose column 0 is the constant (``pm.Basis`` convention). LMH
functions are not constant-first, so :func:`lmh_basis` concatenates the global basis
``Φ`` (``k_global`` columns, constant first) with the ``k`` localized functions, made
*exactly* A-orthogonal to ``Φ`` (one Gram–Schmidt step ``Ψ - Φ ΦᵀAΨ``, tiny because of the
penalty) and then A-orthonormalised symmetrically (Löwdin, ``Ψ G^{-1/2}``, the orthonormal
set closest to ``Ψ``). The result is an A-orthonormal :class:`prodmaps.Basis` of
``k_global + k`` columns usable with :func:`prodmaps.product_basis`; its ``evals`` are the
global eigenvalues followed by the Dirichlet energies ``ψᵀWψ`` of the localized columns (so
they are not globally sorted).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp

from .basis import Basis, eigenbasis, fix_signs
from .eigensolver import shift, smallest_eigenpairs
from .mesh import Mesh, check_mesh
from .operators import laplacian

__all__ = ["LocalizedHarmonics", "localized_harmonics", "lmh_basis", "lmh_operator_parts"]

DEFAULT_MU_REGION = 1e4
DEFAULT_MU_ORTH = 1e4


@dataclass(frozen=True, eq=False)
class LocalizedHarmonics:
    """Result of :func:`localized_harmonics`.

    Attributes
    ----------
    vecs : (n, k) localized functions, A-orthonormal (``vecs.T @ A @ vecs = I``).
    evals : (k,) ascending eigenvalues of ``Q ψ = λ A ψ`` (penalties included).
    mass : (n,) lumped area weights ``A``.
    region : (n,) the indicator ``u`` used (float in [0, 1]).
    global_basis : the :class:`Basis` ``Φ`` penalised against (``k_global`` columns).
    mu_region, mu_orth : the effective weights used in ``Q`` (already divided by the area).
    """

    vecs: np.ndarray
    evals: np.ndarray
    mass: np.ndarray
    region: np.ndarray
    global_basis: Basis
    mu_region: float
    mu_orth: float

    @property
    def k(self) -> int:
        """Number of localized functions."""
        return self.vecs.shape[1]

    def mass_inside(self) -> np.ndarray:
        """Fraction of each function's L² mass ``∫ u ψ²`` inside the region, ``(k,)``."""
        return np.einsum("i,ij->j", self.mass * self.region, self.vecs**2)


def _check_region(region, n: int) -> np.ndarray:
    u = np.asarray(region)
    if u.shape != (n,):
        raise ValueError(f"region must be a per-vertex mask of shape ({n},); got {u.shape}")
    u = u.astype(np.float64)
    if not np.all(np.isfinite(u)) or u.min() < 0 or u.max() > 1:
        raise ValueError("region must be boolean or a soft indicator with values in [0, 1]")
    if not np.any(u > 0):
        raise ValueError("region is empty: mark at least one vertex inside it (u > 0)")
    return u


def lmh_operator_parts(W, A, region, global_vecs, mu_region, mu_orth):
    """``(S0, U)`` with ``Q = S0 + mu_orth · U Uᵀ``: sparse ``S0 = W + mu_region·diag(A(1-u))``, ``U = A Φ``.

    ``mu_region``/``mu_orth`` are the effective weights (not divided by the area here).
    Exposed for tests (dense reference solves) and for users building their own solver.
    """
    A = np.asarray(A, dtype=np.float64)
    u = _check_region(region, A.shape[0])
    S0 = (sp.csr_matrix(W) + sp.diags(mu_region * A * (1.0 - u))).tocsc()
    U = A[:, None] * np.asarray(global_vecs, dtype=np.float64)  # (n, k_global)
    return S0, U


def localized_harmonics(mesh: Mesh, region, k: int, *, k_global: int = 10,
                        mu_region: float = DEFAULT_MU_REGION, mu_orth: float = DEFAULT_MU_ORTH,
                        global_basis: Basis | None = None, kind: str = "cotan",
                        tol: float = 0.0) -> LocalizedHarmonics:
    """The first ``k`` Localized Manifold Harmonics of ``mesh`` on ``region`` (see module doc).

    Parameters
    ----------
    region : (n,) boolean mask or soft indicator in [0, 1] (1 inside the region).
    k : number of localized functions.
    k_global : number of global eigenfunctions (constant included) penalised against; ignored
        (taken from it) when ``global_basis`` is given. ``0`` switches the penalty off.
    mu_region, mu_orth : penalty weights for a **unit-area** shape (divided by the area).
    global_basis : optional precomputed :func:`prodmaps.eigenbasis` of the mesh (lumped mass).
    kind : Laplacian discretisation (``"cotan"`` | ``"robust"``).
    tol : ARPACK tolerance (0 = machine precision).
    """
    from scipy.sparse.linalg import LinearOperator, splu

    mesh = check_mesh(mesh, "localized_harmonics")
    n = mesh.n_vertices
    if not isinstance(k, (int, np.integer)) or isinstance(k, bool) or not 1 <= k < n - 1:
        raise ValueError(f"k must be an integer in [1, {n - 2}], got {k!r}")
    if mu_region < 0 or mu_orth < 0:
        raise ValueError(f"penalty weights must be >= 0; got mu_region={mu_region}, mu_orth={mu_orth}")
    W, A = laplacian(mesh, kind=kind, mass="lumped")
    u = _check_region(region, n)
    if global_basis is None:
        global_basis = eigenbasis(mesh, int(k_global), kind=kind) if k_global > 0 else None
    elif global_basis.n != n or not global_basis.mass_is_diagonal:
        raise ValueError("global_basis must be a lumped-mass basis of the same mesh")
    area = float(A.sum())
    mu_r, mu_o = float(mu_region) / area, float(mu_orth) / area
    Phi = global_basis.vecs if global_basis is not None else np.zeros((n, 0))
    S0, U = lmh_operator_parts(W, A, u, Phi, mu_r, mu_o)
    # the package's shift (prodmaps.eigensolver): S = S0 - σA is positive definite even if the
    # region is everything
    sigma = shift(W, A)
    lu = splu((S0 + sp.diags(-sigma * A)).tocsc())
    kg = U.shape[1]
    woodbury = kg > 0 and mu_o > 0
    if woodbury:
        Z = lu.solve(U)  # (n, kg) = S⁻¹ U
        cap = np.eye(kg) / mu_o + U.T @ Z  # (kg, kg) capacitance matrix, SPD
        cap_f = sla.cho_factor(0.5 * (cap + cap.T))

    def solve(x):  # (Q - σA)⁻¹ x, by Woodbury when the orthogonality penalty is on
        y = lu.solve(np.asarray(x, dtype=np.float64).ravel())
        return y - Z @ sla.cho_solve(cap_f, U.T @ y) if woodbury else y

    def matvec(x):  # Q x without forming U Uᵀ
        x = np.asarray(x, dtype=np.float64).ravel()
        return S0 @ x + mu_o * (U @ (U.T @ x)) if woodbury else S0 @ x

    Qop = LinearOperator((n, n), matvec=matvec, dtype=np.float64)
    OPinv = LinearOperator((n, n), matvec=solve, dtype=np.float64)
    evals, vecs = smallest_eigenpairs(W, A, int(k), operator=Qop, opinv=OPinv, sigma=sigma, tol=tol)
    if global_basis is None:
        global_basis = Basis(np.full((n, 1), 1 / np.sqrt(area)), np.zeros(1), A, name=mesh.name)
    return LocalizedHarmonics(fix_signs(vecs), evals, A, u, global_basis, mu_r, mu_o)


def lmh_basis(mesh: Mesh, region, k: int, *, k_global: int = 10,
              mu_region: float = DEFAULT_MU_REGION, mu_orth: float = DEFAULT_MU_ORTH,
              global_basis: Basis | None = None, kind: str = "cotan") -> Basis:
    """The "MH + LMH" basis: ``k_global`` global eigenfunctions then ``k`` localized ones.

    Returns an A-orthonormal :class:`prodmaps.Basis` with ``k_global + k`` columns, column 0
    the constant (so :func:`prodmaps.product_basis` applies). The localized columns are
    made exactly A-orthogonal to the global ones and Löwdin-orthonormalised (module doc).
    ``k_global`` counts the constant (``k_global = 10`` is the paper's ``k_M = 9`` MH).
    """
    if k_global < 1:
        raise ValueError("lmh_basis needs k_global >= 1 (the constant must be column 0)")
    lm = localized_harmonics(mesh, region, k, k_global=k_global, mu_region=mu_region,
                             mu_orth=mu_orth, global_basis=global_basis, kind=kind)
    Phi, A = lm.global_basis.vecs, lm.mass
    Psi = lm.vecs - Phi @ (Phi.T @ (A[:, None] * lm.vecs))  # (n, k) exactly A-orthogonal to Φ
    G = Psi.T @ (A[:, None] * Psi)  # (k, k)
    w, V = sla.eigh(0.5 * (G + G.T))
    if w[0] < 1e-8 * max(w[-1], 1.0):
        raise ValueError("localized functions are (nearly) in the span of the global basis; "
                         "increase mu_orth or decrease k")
    Psi = fix_signs(Psi @ (V / np.sqrt(w)) @ V.T)  # Löwdin: Ψ G^{-1/2}
    W, _ = laplacian(mesh, kind=kind, mass="lumped")
    energy = np.einsum("ij,ij->j", Psi, W @ Psi)  # (k,) Dirichlet energies ψᵀWψ
    vecs = np.concatenate([Phi, Psi], axis=1)
    evals = np.concatenate([lm.global_basis.evals, energy])
    return Basis(vecs, evals, A, name=f"{mesh.name}+lmh" if mesh.name else "mh+lmh")
