"""The package's one generalized symmetric eigensolver: the smallest eigenpairs of ``W φ = λ M φ``.

Every spectral computation of the package goes through :func:`smallest_eigenpairs`
(Laplace–Beltrami bases, the anisotropic bases of AWFT, the localized harmonics of LMH), so
the constants that decide how eigenpairs are computed exist once:

* ``DENSE_MAX_N``: problems with at most this many unknowns, or asking for more than a third
  of the spectrum (``k > n // DENSE_FRACTION``), are solved densely by LAPACK
  (``scipy.linalg.eigh`` with ``subset_by_index``); larger ones by shift-invert Lanczos
  (ARPACK, ``scipy.sparse.linalg.eigsh``).
* ``SHIFT_REL``: the shift-invert shift is ``σ = -SHIFT_REL · trace(W) / trace(M)``, slightly
  below 0 in the units of the spectrum, so that ``W - σM`` is positive definite (``W`` is only
  semi-definite: the constants are in its kernel) and one sparse LU factorises it stably.
* ``MID_SHIFT``: for a sparse matrix and no shift given, the shift is first placed inside the
  wanted part of the spectrum, ``σ = MID_SHIFT · 4πk / trace(M)`` (Weyl's law for a surface puts
  ``λ_k`` near ``4πk / area``). Shift-invert Lanczos then returns the ``k`` eigenvalues nearest
  ``σ``, which converge faster than around 0 (no implicit restart for ``k = 200`` on 5k
  vertices against one or more). They are the ``k`` smallest exactly when the farthest of them
  is at least ``σ`` away from it (``W`` is semi-definite, so every eigenvalue below the largest
  returned one is then within that distance); this is checked, and otherwise the problem is
  solved again around the safe shift below 0.
* The Lanczos start vector is ``ones(n)`` (deterministic reruns) and the tolerance is machine
  precision (``tol=0``).

Results are sorted ascending and every eigenvector is ``M``-normalised (``φᵀ M φ = 1``); signs
are not fixed here (:func:`prodmaps.basis.fix_signs` does it for bases).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

__all__ = ["DENSE_MAX_N", "DENSE_FRACTION", "SHIFT_REL", "MID_SHIFT", "shift", "smallest_eigenpairs"]

DENSE_MAX_N = 1500
DENSE_FRACTION = 3
SHIFT_REL = 1e-8
MID_SHIFT = 0.3


def _as_sparse_mass(M) -> sp.csc_matrix:
    if sp.issparse(M):
        return M.tocsc()
    m = np.asarray(M, dtype=np.float64)
    if m.ndim != 1:
        raise ValueError(f"mass must be a vector (n,) or a sparse (n, n) matrix; got shape {m.shape}")
    return sp.diags(m).tocsc()


def shift(W, M) -> float:
    """The shift-invert shift ``-SHIFT_REL · trace(W) / trace(M)`` (see the module doc)."""
    Mm = _as_sparse_mass(M)
    scale = float(W.diagonal().sum() / Mm.diagonal().sum())
    return -SHIFT_REL * scale


def smallest_eigenpairs(W, M, k: int, *, operator=None, opinv=None, sigma: float | None = None,
                        tol: float = 0.0, weyl_area: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The ``k`` smallest eigenpairs of ``W φ = λ M φ``: ``(evals (k,) ascending, vecs (n, k))``.

    Parameters
    ----------
    W : sparse ``(n, n)`` symmetric positive semi-definite stiffness.
    M : mass, ``(n,)`` lumped diagonal or sparse ``(n, n)`` symmetric positive definite.
    k : number of eigenpairs.
    operator, opinv : for operators that are not sparse matrices (e.g. a sparse matrix plus a
        low-rank term, as in LMH): a ``LinearOperator`` applying the operator and one applying
        ``(operator - σM)⁻¹``. ``W`` then only sets the default shift. Always Lanczos.
    sigma : shift-invert shift (default: the checked shift inside the spectrum, ``MID_SHIFT``,
        for a sparse ``W``; :func:`shift` of ``W`` and ``M`` otherwise and as the fallback).
    tol : ARPACK tolerance (0: machine precision).
    weyl_area : the area of Weyl's law that places the first shift (default ``trace(M)``, right
        for the Laplace–Beltrami operator; see the module doc). A wrong value costs time only:
        the check then solves again around the safe shift.

    Eigenvectors are ``M``-orthonormal up to round-off and ``M``-normalised exactly; the
    solver route is chosen by ``DENSE_MAX_N`` / ``DENSE_FRACTION`` (module doc).
    """
    n = W.shape[0]
    if not 1 <= k < n:
        raise ValueError(f"k={k} eigenpairs requested for a problem of size {n}: need 1 <= k < {n}")
    Mm = _as_sparse_mass(M)
    if operator is None and (n <= DENSE_MAX_N or k > n // DENSE_FRACTION):
        import scipy.linalg as sla

        evals, vecs = sla.eigh(W.toarray(), Mm.toarray(), subset_by_index=[0, k - 1])
    else:
        from scipy.sparse.linalg import eigsh

        A = W.tocsc() if operator is None else operator
        evals = None
        if operator is None and sigma is None:  # first inside the wanted spectrum (module doc)
            area = float(Mm.diagonal().sum()) if weyl_area is None else float(weyl_area)
            if not (np.isfinite(area) and area > 0):
                raise ValueError(f"weyl_area must be a positive number, got {weyl_area!r}")
            mid = MID_SHIFT * 4.0 * np.pi * k / area
            evals, vecs = eigsh(A, k=k, M=Mm, sigma=mid, which="LM", v0=np.ones(n), tol=tol)
            if np.abs(evals - mid).max() < mid * (1.0 + 1e-6):  # maybe not the k smallest: redo safely
                evals = None
        if evals is None:
            sig = shift(W, Mm) if sigma is None else float(sigma)
            evals, vecs = eigsh(A, k=k, M=Mm, sigma=sig, which="LM", OPinv=opinv, v0=np.ones(n), tol=tol)
        order = np.argsort(evals)
        evals, vecs = evals[order], vecs[:, order]
    norms = np.sqrt(np.einsum("ij,ij->j", vecs, Mm @ vecs))  # (k,) M-norms
    return evals, vecs / norms
