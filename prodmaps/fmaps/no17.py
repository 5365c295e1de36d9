"""The NO17 functional-map energy, its explicit quadratic form and two solvers (L-BFGS, direct).

Conventions (bases, ``k``, ``C_12`` ``(k2, k1)``, ``p2p_21`` ``(n2,)``): :mod:`prodmaps.conventions`.

The NO17 energy (Nogneng & Ovsjanikov 2017, "Informative descriptor preservation via
commutativity for shape matching")
---------------------------------------------------------------------------------------------
With ``D1 = Φ1ᵀA1 d``, ``D2 = Φ2ᵀA2 d'`` the coefficient matrices ``(k1, p)``, ``(k2, p)`` of
``p`` paired descriptors and ``M1_q = Φ1ᵀ A1 diag(d_q) Φ1`` ``(k1, k1)``,
``M2_q = Φ2ᵀ A2 diag(d'_q) Φ2`` ``(k2, k2)`` their multiplication operators::

    E(C) = w_descr/τ_descr · ½‖C D1 − D2‖²_F                    (descriptor preservation)
         + w_dcomm/τ_dcomm · ½ Σ_q ‖C M1_q − M2_q C‖²_F           (commutativity with products)
         + w_lap  /τ_lap   · ½ Σ_ij L_ij C_ij²                    (Laplacian commutativity)

* Laplacian term, ``lap="eigdiff"``: ``L_ij = (μ_i − λ_j)²`` with ``μ`` the eigenvalues of
  shape 2 and ``λ`` those of shape 1, so the term is exactly ``½‖Λ2 C − C Λ1‖²_F``.
  ``lap="resolvent"`` (default, Ren et al. 2019 "Structured regularization of functional map
  computations"): the commutator with the bounded operator ``R = (Δ^γ − i)⁻¹`` instead of
  ``Δ``: ``L_ij = |r(μ_i) − r(λ_j)|²`` with ``r(x) = 1/(x^γ − i)``, both spectra first divided by
  the same number ``max(λ_max, μ_max)``; ``γ = resolvent_gamma`` (0.5). The unbounded
  ``eigdiff`` mask grows like ``λ_k²`` and makes the weight depend on ``k``; the resolvent
  mask is bounded by 4 and has the same null set (``L_ij = 0`` iff ``λ_j = μ_i``).
* Descriptor normalisation (``normalize_descr=True``): every descriptor column is divided by
  its area L2 norm on its own shape, ``d_q / sqrt(d_qᵀ A d_q)``, before projection;
  ``normalize_descr="source"``: both columns of a pair are divided by the **source** column's
  norm ``sqrt(d_qᵀ A1 d_q)`` (the NO17 authors' MATLAB demo), so a descriptor whose magnitude
  differs between the shapes keeps that difference.
* Weights: only ratios matter; ``(w_descr, w_lap, w_dcomm)`` are divided by their sum.
* Term normalisation ``normalize="expected"`` (default): each term is divided by its expected
  value ``τ`` when ``C`` has i.i.d. centred entries of variance ``m/(k1 k2)``, ``m = min(k1, k2)``
  (so ``E‖C‖²_F = m``, the squared norm of a partial isometry of rank ``m``). For a Gaussian
  ``C`` with entry variance ``σ²``: ``E‖C X‖² = σ² k2 ‖X‖²``, ``E‖Y C‖² = σ² k1 ‖Y‖²``,
  ``E tr(XᵀCᵀYC) = σ² tr X tr Y``, hence (the factor ½ common to all terms dropped)::

      τ_descr = (m/k1) ‖D1[1:]‖²_F / p_eff          (constant row excluded: column 0 of C is fixed)
      τ_lap   = (m/(k1 k2)) Σ_ij L_ij
      τ_dcomm = (m/(k1 k2)) Σ_q (k2‖M1_q‖² + k1‖M2_q‖² − 2 tr M1_q tr M2_q) / p_eff

  where ``p_eff = (tr G)²/‖G‖²_F``, ``G = D[1:]ᵀ D[1:]`` (averaged over the two shapes) is the
  effective number of linearly independent descriptors, so that adding redundant descriptor
  columns does not change the balance between descriptor and Laplacian terms. A degenerate
  ``τ`` (zero) is replaced by 1. This is the normalisation pyFM >= 1.3 calls "canonical", so
  the same ``w_*`` mean the same energy in both packages (checked in
  ``tests/test_pyfmaps_crosscheck.py``). ``normalize="sum"``: ``τ_descr = τ_dcomm = 1`` and
  ``τ_lap = Σ_ij L_ij`` (pyFM's ``normalize_weights=False``); ``normalize="frobenius"``:
  ``τ_descr = τ_dcomm = 1`` and ``τ_lap = ‖L‖²_F`` (the NO17 authors' MATLAB demo divides its
  ``eigdiff`` mask by its squared Frobenius norm); ``normalize=None``: all ``τ = 1``.
* First column: ``C[0, 0] = s·sqrt(area_2/area_1)`` and ``C[1:, 0] = 0`` with
  ``s = sign(φ0¹ φ0²)`` (= +1 with prodmaps bases). Derivation: for any point map ``T``,
  ``T φ0¹`` is the constant ``1/sqrt(area_1)`` on shape 2, so
  ``C[i, 0] = ⟨φ_i², T φ0¹⟩_A2 = (1/sqrt(area_1)) ∫ φ_i²``, which is 0 for ``i ≥ 1``
  (orthogonal to the constant) and ``area_2/(sqrt(area_1) sqrt(area_2)) = sqrt(area_2/area_1)``
  for ``i = 0``. (The ratio is area_2 over area_1, not the reverse.) The optimisation runs
  over ``C[:, 1:]`` only; the energy still includes column 0.
* Optimiser: ``scipy.optimize.minimize(method="L-BFGS-B")`` with the analytic gradient,
  started from zeros (``init="zeros"``) or the rectangular identity (``init="identity"``) in
  the free columns; ``factr``/``pgtol`` as scipy's ``fmin_l_bfgs_b`` (defaults 1e7, 1e-5).
* Rectangular maps are allowed: ``k1 = basis_1.k``, ``k2 = basis_2.k`` (e.g. 30 and 40
  columns for the paper's Table 2 ``k_M = 29, k_N = 39``).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from ..basis import Basis
from ..checks import check_basis
from ..progress import progress_bar

__all__ = ["first_column", "laplacian_mask", "multiplication_operators", "NO17Terms", "no17_terms",
           "energy_and_gradient", "quadratic_form", "fit_no17", "PROGRESS_MIN_WORK", "TYPICAL_ITERATIONS"]

PROGRESS_MIN_WORK = 1e10
"""``progress=None``: a bar when the estimated multiply-adds of a fit exceed this (several seconds)."""
TYPICAL_ITERATIONS = 200
"""L-BFGS iterations assumed by the work estimate behind ``progress=None`` (fits take tens to hundreds)."""

LAP_FORMS = ("resolvent", "eigdiff")
NORMALIZATIONS = ("expected", "sum", "frobenius", None)
DESCR_NORMALIZATIONS = (True, False, "source")


def first_column(basis_1: Basis, basis_2: Basis, k2: int | None = None) -> np.ndarray:
    """The fixed first column of every point-map-induced ``C_12``: ``(k2,)``.

    ``[s·sqrt(area_2/area_1), 0, …, 0]`` with ``s = sign(φ0¹ φ0²)`` (see module doc).
    """
    k2 = basis_2.k if k2 is None else k2
    col = np.zeros(k2)
    s = np.sign(basis_1.vecs[0, 0] * basis_2.vecs[0, 0]) or 1.0
    col[0] = s * np.sqrt(basis_2.area / basis_1.area)
    return col


def _column_norms(descr: np.ndarray, basis: Basis) -> np.ndarray:
    """``(p,)`` area L2 norms ``sqrt(d_qᵀ A d_q)`` of the columns; raises if one is zero."""
    sq = np.einsum("nq,nq->q", descr, basis.apply_mass(descr))  # (p,)
    if np.any(sq <= 0):
        bad = np.flatnonzero(sq <= 0)[:5]
        raise ValueError(f"descriptor columns {bad.tolist()} are zero; drop them before fitting")
    return np.sqrt(sq)


def multiplication_operators(basis: Basis, descr: np.ndarray) -> np.ndarray:
    """``Φᵀ A diag(d_q) Φ`` for every descriptor column: ``(p, k, k)`` (lumped mass only)."""
    if not basis.mass_is_diagonal:
        raise ValueError("multiplication operators need a lumped (diagonal) mass; build the basis with mass='lumped'")
    n, k = basis.vecs.shape
    iu, ju = np.triu_indices(k)  # the operators are symmetric: compute i <= j only
    pairs = (basis.vecs[:, iu] * basis.mass[:, None]) * basis.vecs[:, ju]  # (n, k(k+1)/2): A φ_i φ_j
    upper = np.asarray(descr).T @ pairs  # (p, k(k+1)/2), one GEMM
    out = np.empty((upper.shape[0], k, k))
    out[:, iu, ju] = upper
    out[:, ju, iu] = upper
    return out  # (p, k, k)


def laplacian_mask(evals_1: np.ndarray, evals_2: np.ndarray, lap: str = "resolvent", gamma: float = 0.5) -> np.ndarray:
    """Mask ``L`` ``(k2, k1)`` of the Laplacian term ``½ Σ L_ij C_ij²`` (module doc)."""
    lam = np.abs(np.asarray(evals_1, dtype=np.float64))
    mu = np.abs(np.asarray(evals_2, dtype=np.float64))
    if lap == "eigdiff":
        return np.square(mu[:, None] - lam[None, :])
    if lap == "resolvent":
        if not 0 < gamma <= 1:
            raise ValueError(f"resolvent_gamma must be in (0, 1], got {gamma}")
        scale = max(lam.max(), mu.max())
        scale = scale if scale > 0 else 1.0
        r1 = 1.0 / ((lam / scale) ** gamma - 1j)  # (k1,) complex resolvent symbols
        r2 = 1.0 / ((mu / scale) ** gamma - 1j)  # (k2,)
        return np.abs(r2[:, None] - r1[None, :]) ** 2
    raise ValueError(f"lap must be one of {LAP_FORMS}, got {lap!r}")


def _effective_p(*coefs: np.ndarray) -> float:
    grams = [F[1:].T @ F[1:] for F in coefs]  # (p, p) each
    return float(np.mean([float(np.trace(G)) ** 2 / float(np.sum(G * G)) if np.sum(G * G) > 0 else 1.0
                          for G in grams]))


@dataclass
class NO17Terms:
    """Precomputed pieces of the NO17 energy (see module doc); build with :func:`no17_terms`.

    Attributes: ``D1 (k1, p)``, ``D2 (k2, p)`` descriptor coefficients; ``M1 (p, k1, k1)``,
    ``M2 (p, k2, k2)`` multiplication operators (None if ``mu_dcomm == 0``); ``L (k2, k1)``
    Laplacian mask; ``mu_descr, mu_lap, mu_dcomm`` the final multipliers ``w/τ``; ``col0 (k2,)``
    the fixed first column.
    """

    D1: np.ndarray
    D2: np.ndarray
    M1: np.ndarray | None
    M2: np.ndarray | None
    L: np.ndarray
    mu_descr: float
    mu_lap: float
    mu_dcomm: float
    col0: np.ndarray
    taus: tuple

    @property
    def shape(self) -> tuple[int, int]:
        """Shape ``(k2, k1)`` of the maps this energy is defined on."""
        return (self.D2.shape[0], self.D1.shape[0])


def no17_terms(basis_1: Basis, basis_2: Basis, descr_1: np.ndarray, descr_2: np.ndarray, *, w_descr: float = 1.0,
               w_lap: float = 1e-2, w_dcomm: float = 1e-1, w_orient: float = 0.0, lap: str = "resolvent",
               resolvent_gamma: float = 0.5, normalize: str | None = "expected",
               normalize_descr: bool | str = True) -> NO17Terms:
    """Precompute the NO17 energy terms for ``C_12`` of shape ``(basis_2.k, basis_1.k)``.

    ``descr_1`` ``(n1, p)`` and ``descr_2`` ``(n2, p)`` are paired descriptor columns
    (column q on shape 1 corresponds to column q on shape 2). See the module doc for every
    weight and normalisation. ``w_orient`` (the orientation term of Ren et al. 2018) is not
    implemented: it must be 0.
    """
    check_basis(basis_1, "basis_1")
    check_basis(basis_2, "basis_2")
    if w_orient != 0:
        raise NotImplementedError("w_orient != 0: the orientation-preserving term is not implemented; use w_orient=0")
    d1, d2 = (np.asarray(d, dtype=np.float64) for d in (descr_1, descr_2))
    d1, d2 = (d[:, None] if d.ndim == 1 else d for d in (d1, d2))
    if d1.shape[0] != basis_1.n or d2.shape[0] != basis_2.n:
        raise ValueError(f"descr_1 must have {basis_1.n} rows (shape 1) and descr_2 {basis_2.n} rows (shape 2); "
                         f"got {d1.shape} and {d2.shape}")
    if d1.shape[1] != d2.shape[1]:
        raise ValueError(f"descr_1 and descr_2 must have the same number of columns; got {d1.shape[1]} and "
                         f"{d2.shape[1]}")
    if not (np.all(np.isfinite(d1)) and np.all(np.isfinite(d2))):
        raise ValueError("descriptors contain non-finite values")
    ws = np.array([w_descr, w_lap, w_dcomm], dtype=np.float64)
    if np.any(ws < 0) or ws.sum() <= 0:
        raise ValueError(f"weights must be >= 0 with a positive sum; got w_descr={w_descr}, w_lap={w_lap}, "
                         f"w_dcomm={w_dcomm}")
    if normalize not in NORMALIZATIONS:
        raise ValueError(f"normalize must be one of {NORMALIZATIONS}, got {normalize!r}")
    if not isinstance(normalize_descr, (bool, np.bool_, str)) or normalize_descr not in DESCR_NORMALIZATIONS:
        raise ValueError(f"normalize_descr must be one of {DESCR_NORMALIZATIONS}, got {normalize_descr!r}")
    ws = ws / ws.sum()
    if normalize_descr == "source":
        norms = _column_norms(d1, basis_1)  # (p,) the source norms divide both shapes' columns
        d1, d2 = d1 / norms[None, :], d2 / norms[None, :]
    elif normalize_descr:  # every column divided by its own area L2 norm
        d1, d2 = d1 / _column_norms(d1, basis_1)[None, :], d2 / _column_norms(d2, basis_2)[None, :]
    k1, k2 = basis_1.k, basis_2.k
    D1 = basis_1.project(d1)  # (k1, p)
    D2 = basis_2.project(d2)  # (k2, p)
    L = laplacian_mask(basis_1.evals, basis_2.evals, lap=lap, gamma=resolvent_gamma)  # (k2, k1)
    M1 = M2 = None
    if ws[2] > 0:
        M1 = multiplication_operators(basis_1, d1)  # (p, k1, k1)
        M2 = multiplication_operators(basis_2, d2)  # (p, k2, k2)
    if normalize == "expected":
        m = min(k1, k2)
        p_eff = max(_effective_p(D1, D2), 1e-12)
        t_descr = m * float(np.sum(D1[1:] ** 2)) / k1 / p_eff
        t_lap = m * float(L.sum()) / (k1 * k2)
        t_dcomm = 1.0
        if M1 is not None:
            pos = k2 * float(np.sum(M1**2)) + k1 * float(np.sum(M2**2))
            tot = pos - 2.0 * float(np.sum(np.trace(M1, axis1=1, axis2=2) * np.trace(M2, axis1=1, axis2=2)))
            t_dcomm = tot * m / (k1 * k2) / p_eff if tot > 1e-12 * pos else 1.0
        taus = tuple(t if t > 0 else 1.0 for t in (t_descr, t_lap, t_dcomm))
    else:  # only the Laplacian term is normalised: by the sum or the squared Frobenius norm of its mask
        t_lap = {"sum": float(L.sum()), "frobenius": float(np.sum(L * L)), None: 1.0}[normalize]
        taus = (1.0, t_lap if t_lap > 0 else 1.0, 1.0)
    mus = ws / np.array(taus)
    return NO17Terms(D1, D2, M1, M2, L, float(mus[0]), float(mus[1]), float(mus[2]), first_column(basis_1, basis_2),
                     taus)


def energy_and_gradient(C: np.ndarray, terms: NO17Terms) -> tuple[float, np.ndarray]:
    """NO17 energy ``E(C)`` and its full gradient ``∂E/∂C`` ``(k2, k1)`` (column 0 included).

    ``C`` is ``(k2, k1)`` (or its row-major ravel). Gradients of the three terms:
    ``(C D1 − D2) D1ᵀ``; ``L ∘ C``; ``Σ_q R_q M1_qᵀ − M2_qᵀ R_q`` with ``R_q = C M1_q − M2_q C``.
    """
    k2, k1 = terms.shape
    C = np.asarray(C, dtype=np.float64).reshape(k2, k1)
    E = 0.0
    G = np.zeros_like(C)
    if terms.mu_descr > 0:
        R = C @ terms.D1 - terms.D2  # (k2, p)
        E += terms.mu_descr * 0.5 * float(np.sum(R * R))
        G += terms.mu_descr * (R @ terms.D1.T)
    if terms.mu_lap > 0:
        E += terms.mu_lap * 0.5 * float(np.sum(terms.L * C * C))
        G += terms.mu_lap * (terms.L * C)
    if terms.mu_dcomm > 0 and terms.M1 is not None:
        R = np.matmul(C, terms.M1) - np.matmul(terms.M2, C)  # (p, k2, k1)
        E += terms.mu_dcomm * 0.5 * float(np.sum(R * R))
        G += terms.mu_dcomm * (np.einsum("qab,qcb->ac", R, terms.M1) - np.einsum("qba,qbc->ac", terms.M2, R))
    return E, G


def _symmetric(M: np.ndarray) -> bool:
    """Whether every ``M[q]`` of ``(p, k, k)`` equals its transpose exactly (bit for bit)."""
    return bool(np.array_equal(M, M.transpose(0, 2, 1)))


def quadratic_form(terms: NO17Terms) -> tuple[np.ndarray, np.ndarray]:
    """The NO17 energy as an explicit quadratic: ``E(C) = ½ cᵀ H c − bᵀ c + const``.

    ``c = C.ravel()`` (row-major, ``(k2·k1,)``), ``H`` ``(k2·k1, k2·k1)`` symmetric PSD, ``b``
    ``(k2·k1,)``; the gradient of :func:`energy_and_gradient` is ``H c − b``. With
    ``vec(X C Y) = (X ⊗ Yᵀ) vec(C)`` (row-major vec) the three terms give::

        H = μ_descr · I ⊗ D1D1ᵀ  +  μ_lap · diag(vec L)
          + μ_dcomm · Σ_q [ I ⊗ M1_q M1_qᵀ + M2_qᵀ M2_q ⊗ I − M2_q ⊗ M1_q − M2_qᵀ ⊗ M1_qᵀ ]
        b = μ_descr · vec(D2 D1ᵀ)

    The ``Σ_q`` Kronecker sums are one GEMM over the descriptors (no loop over ``q``).
    """
    k2, k1 = terms.shape
    n = k1 * k2
    H = np.zeros((n, n))
    I1, I2 = np.eye(k1), np.eye(k2)
    if terms.mu_descr > 0:
        H += terms.mu_descr * np.kron(I2, terms.D1 @ terms.D1.T)
    if terms.mu_lap > 0:
        H[np.diag_indices(n)] += terms.mu_lap * terms.L.ravel()
    if terms.mu_dcomm > 0 and terms.M1 is not None:
        M1, M2 = terms.M1, terms.M2  # (p, k1, k1), (p, k2, k2)
        p = M1.shape[0]
        P1 = np.einsum("qab,qcb->ac", M1, M1)  # Σ M1 M1ᵀ (k1, k1)
        P2 = np.einsum("qba,qbc->ac", M2, M2)  # Σ M2ᵀ M2 (k2, k2)
        X = M2.reshape(p, -1).T @ M1.reshape(p, -1)  # (k2², k1²): Σ_q M2[a,c] M1[b,d]
        cross = X.reshape(k2, k2, k1, k1).transpose(0, 2, 1, 3).reshape(n, n)  # Σ M2 ⊗ M1
        if _symmetric(M1) and _symmetric(M2):  # multiplication operators: Σ M2ᵀ ⊗ M1ᵀ is the same array
            cross_t = cross
        else:
            Xt = M2.transpose(0, 2, 1).reshape(p, -1).T @ M1.transpose(0, 2, 1).reshape(p, -1)
            cross_t = Xt.reshape(k2, k2, k1, k1).transpose(0, 2, 1, 3).reshape(n, n)  # Σ M2ᵀ ⊗ M1ᵀ
        H += terms.mu_dcomm * (np.kron(I2, P1) + np.kron(P2, I1) - cross - cross_t)
    b = terms.mu_descr * (terms.D2 @ terms.D1.T).ravel() if terms.mu_descr > 0 else np.zeros(n)
    return 0.5 * (H + H.T), b


def fit_no17(basis_1: Basis, basis_2: Basis, descr_1: np.ndarray, descr_2: np.ndarray, *, w_descr: float = 1.0,
             w_lap: float = 1e-2, w_dcomm: float = 1e-1, w_orient: float = 0.0, lap: str = "resolvent",
             resolvent_gamma: float = 0.5, normalize: str | None = "expected", normalize_descr: bool | str = True,
             init: str = "zeros", factr: float = 1e7, pgtol: float = 1e-5, maxiter: int = 15000, solver: str = "lbfgs",
             return_info: bool = False, progress: bool | None = None):
    """Functional map ``C_12`` ``(basis_2.k, basis_1.k)`` minimising the NO17 energy.

    Parameters
    ----------
    basis_1, basis_2 : bases of shape 1 (source) and 2 (target); their column counts set the
        map size ``(k2, k1)`` (constant included; truncate them with ``basis.truncate``).
    descr_1, descr_2 : ``(n1, p)``, ``(n2, p)`` paired descriptors.
    w_descr, w_lap, w_dcomm : relative weights of descriptor preservation, Laplacian
        commutativity and descriptor-operator commutativity (divided by their sum).
        Defaults are the NO17 demo weights of pyFM (1, 1e-2, 1e-1).
    w_orient : must be 0 (orientation term not implemented).
    lap, resolvent_gamma, normalize, normalize_descr : see the module doc.
    init : ``"zeros"`` or ``"identity"`` for the free columns ``C[:, 1:]``.
    factr, pgtol, maxiter : L-BFGS-B stopping rules (scipy ``fmin_l_bfgs_b`` meaning).
    solver : ``"lbfgs"`` (default; L-BFGS-B with the analytic gradient, as NO17 and pyFM) or
        ``"direct"``: the energy is quadratic in ``C`` (:func:`quadratic_form`), so its exact
        minimiser with the first column fixed solves one ``k2(k1-1)``-dimensional SPD linear
        system (Cholesky; least squares if singular). Same energy, no iteration tolerance,
        typically tens of times faster.
    return_info : also return a dict (energy, iterations, time, taus, message).
    progress : a progress bar on stderr, one step per L-BFGS iteration (``True``), none
        (``False``), or when the fit is long (estimated multiply-adds above ``PROGRESS_MIN_WORK``)
        and stderr is a terminal (``None``, default).

    Returns
    -------
    C_12 : ``(k2, k1)``, first column fixed to :func:`first_column`.

    Raises
    ------
    TypeError
        If a basis is not a :class:`prodmaps.Basis`.
    ValueError
        For descriptors of the wrong shape or not finite, zero descriptor columns, weights that
        are negative or sum to zero, and unknown ``lap``, ``normalize``, ``init`` or ``solver``.

    Notes
    -----
    Units: the energy is built and minimised on both shapes scaled to unit area
    (:meth:`prodmaps.Basis.scaled`), and the map of the given bases is returned
    (``sqrt(area_2/area_1)`` times the unit-area map), so scaling either mesh changes nothing but
    that factor. ``info["energy"]`` and ``info["taus"]`` are those of the unit-area problem.
    Everything works on bases of point clouds as on bases of meshes.

    Examples
    --------
    Two ellipsoids with the same triangulation (so the true map is the identity), WKS and
    wave-kernel maps at five landmark pairs (:func:`prodmaps.fmaps.no17_demo_descriptors`):

    >>> import numpy as np
    >>> import prodmaps as pm
    >>> from prodmaps.fmaps import fit_no17, no17_demo_descriptors
    >>> m1, m2 = pm.mesh.ellipsoid(2), pm.mesh.ellipsoid(2, axes=(1.1, 0.6, 0.35))
    >>> B1, B2 = pm.eigenbasis(m1, 30), pm.eigenbasis(m2, 30)  # descriptors from 30 eigenpairs
    >>> d1, d2 = no17_demo_descriptors(B1, B2, [[i, i] for i in (0, 20, 40, 60, 80)])
    >>> b1, b2 = B1.truncate(8), B2.truncate(8)  # ... and a map of 8 columns
    >>> C_12 = fit_no17(b1, b2, d1, d2)
    >>> C_12.shape
    (8, 8)
    >>> truth = pm.fmap_from_p2p(np.arange(m2.n_vertices), b1, b2)  # (k2, k1)
    >>> bool(np.linalg.norm(C_12 - truth) < 0.2 * np.linalg.norm(truth))
    True
    >>> p2p_21 = pm.p2p.from_fmap(C_12, b1, b2)  # the point map it gives: every vertex right
    >>> float(np.mean(p2p_21 == np.arange(m2.n_vertices)))
    1.0
    """
    from scipy.optimize import minimize

    t0 = time.perf_counter()
    check_basis(basis_1, "basis_1")
    check_basis(basis_2, "basis_2")
    p = 1 if np.ndim(descr_1) == 1 else np.shape(descr_1)[1]
    k1, k2 = basis_1.k, basis_2.k
    work = (basis_1.n * k1 * k1 + basis_2.n * k2 * k2) * p / 2 + TYPICAL_ITERATIONS * 4.0 * p * k1 * k2 * (k1 + k2)
    bar = progress_bar(None if solver == "lbfgs" else 1, "NO17", progress=progress, work=work,
                       min_work=PROGRESS_MIN_WORK, unit="iteration")
    # Fit on both shapes scaled to unit area, so that the map does not depend on the meshes' units
    # nor on their area ratio (eigenvalues, descriptor norms and the fixed first column all change
    # with it); the map of the given bases is sqrt(area_2 / area_1) times the unit-area map.
    area_ratio = np.sqrt(basis_2.area / basis_1.area)
    basis_1, basis_2 = basis_1.scaled(1.0 / np.sqrt(basis_1.area)), basis_2.scaled(1.0 / np.sqrt(basis_2.area))
    terms = no17_terms(basis_1, basis_2, descr_1, descr_2, w_descr=w_descr, w_lap=w_lap, w_dcomm=w_dcomm,
                       w_orient=w_orient, lap=lap, resolvent_gamma=resolvent_gamma, normalize=normalize,
                       normalize_descr=normalize_descr)
    k2, k1 = terms.shape
    if solver not in ("lbfgs", "direct"):
        raise ValueError(f"solver must be 'lbfgs' or 'direct', got {solver!r}")
    if solver == "direct":
        C = _solve_direct(terms)
        bar.update(1)
        info = {"energy": energy_and_gradient(C, terms)[0], "nit": 0, "message": "direct solve", "success": True}
    elif init not in ("zeros", "identity"):
        raise ValueError(f"init must be 'zeros' or 'identity', got {init!r}")
    else:
        C = np.empty((k2, k1))
        C[:, 0] = terms.col0

        def fun(x):
            C[:, 1:] = x.reshape(k2, k1 - 1)
            E, G = energy_and_gradient(C, terms)
            return E, G[:, 1:].ravel()

        if k1 > 1:
            free0 = np.zeros((k2, k1 - 1)) if init == "zeros" else np.eye(k2, k1)[:, 1:]
            res = minimize(fun, free0.ravel(), jac=True, method="L-BFGS-B", callback=lambda *_: bar.update(1),
                           options={"ftol": factr * np.finfo(float).eps, "gtol": pgtol, "maxiter": maxiter,
                                    "maxfun": 10 * maxiter})
            C[:, 1:] = res.x.reshape(k2, k1 - 1)
            info = {"energy": float(res.fun), "nit": int(res.nit), "message": str(res.message),
                    "success": bool(res.success)}
        else:
            info = {"energy": energy_and_gradient(C, terms)[0], "nit": 0, "message": "nothing to fit", "success": True}
    bar.close()
    info.update(time=time.perf_counter() - t0, taus=terms.taus)
    C = area_ratio * C
    return (C, info) if return_info else C


def _solve_direct(terms: NO17Terms) -> np.ndarray:
    """Exact minimiser of the quadratic NO17 energy over ``C[:, 1:]`` with ``C[:, 0]`` fixed."""
    import scipy.linalg as sla

    k2, k1 = terms.shape
    H, b = quadratic_form(terms)
    free = np.ones((k2, k1), dtype=bool)
    free[:, 0] = False
    f, z = free.ravel(), ~free.ravel()
    rhs = b[f] - H[np.ix_(f, z)] @ terms.col0  # column 0 of C (row-major: entries a*k1)
    try:
        x = sla.solve(H[np.ix_(f, f)], rhs, assume_a="pos")
    except (sla.LinAlgError, ValueError):
        x = sla.lstsq(H[np.ix_(f, f)], rhs)[0]
    C = np.empty((k2, k1))
    C[:, 0] = terms.col0
    C[:, 1:] = x.reshape(k2, k1 - 1)
    return C
