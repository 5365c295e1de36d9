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
  ``σ``, which converge faster than around 0. They are the ``k`` smallest exactly when the
  farthest of them is at least ``σ`` away from it (``W`` is semi-definite, so every eigenvalue
  below the largest returned one is then within that distance); this is checked, and otherwise
  the problem is solved again around the safe shift below 0.
* The Lanczos start vector is ``ones(n)`` (deterministic reruns) and the tolerance is machine
  precision (``tol=0``).
* ``solver`` (sparse route only): ``"superlu"`` factorises ``W - σM`` by SciPy's SuperLU (the
  route above); ``"cholesky"`` by a sparse Cholesky (CHOLMOD through the optional dependency
  ``cholespy``, ``pip install 'prodmaps[fast]'``) around the safe shift below 0 only (``W - σM``
  must be positive definite, so the shift inside the spectrum is not used); ``"auto"`` (default)
  takes the Cholesky route from ``CHOLESKY_MIN_N`` unknowns when ``cholespy`` is installed,
  SuperLU otherwise, so every problem below that size (all the paper's meshes) takes SuperLU. The
  two routes give the same eigenpairs up to the Lanczos tolerance (tested: eigenvalues to 1e-10
  relative, subspaces to 1e-8). The threshold is where the two routes cost the same (timings:
  ``docs/benchmarks.md``).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

__all__ = ["DENSE_MAX_N", "DENSE_FRACTION", "SHIFT_REL", "MID_SHIFT", "CHOLESKY_MIN_N", "SOLVERS", "shift",
           "smallest_eigenpairs", "have_cholesky"]

DENSE_MAX_N = 1500
DENSE_FRACTION = 3
SHIFT_REL = 1e-8
MID_SHIFT = 0.3
CHOLESKY_MIN_N = 100_000  # solver="auto": the sparse Cholesky route from this many unknowns (module doc)
SOLVERS = ("auto", "superlu", "cholesky")
_CHOLESKY_HINT = "pip install cholespy (or the extra: pip install 'prodmaps[fast]')"


def have_cholesky() -> bool:
    """Whether the optional sparse Cholesky (``cholespy``) can be imported."""
    try:
        import cholespy  # noqa: F401
    except ImportError:
        return False
    return True


def _cholesky_inverse(K):
    """``LinearOperator`` applying ``K⁻¹`` for a sparse symmetric positive definite ``K`` (sparse Cholesky).

    CHOLMOD with a fill-reducing ordering, via ``cholespy``. Raises ``ImportError`` without ``cholespy``
    and ``ValueError`` if ``K`` is not positive definite.
    """
    from scipy.sparse.linalg import LinearOperator

    try:
        import cholespy
    except ImportError as e:
        raise ImportError(f"solver='cholesky' needs the optional dependency cholespy: {_CHOLESKY_HINT}") from e
    K = sp.csc_matrix(K, dtype=np.float64)
    K.sort_indices()
    n = K.shape[0]
    factor = cholespy.CholeskySolverD(n, K.indptr.astype(np.int32), K.indices.astype(np.int32), K.data,
                                      cholespy.MatrixType.CSC)

    def solve(b):
        b = np.asarray(b, dtype=np.float64)
        rhs = np.ascontiguousarray(b.reshape(n, -1) if b.ndim == 2 else b)
        x = np.zeros_like(rhs)
        factor.solve(rhs, x)
        return x.reshape(b.shape)

    return LinearOperator((n, n), matvec=solve, matmat=solve, dtype=np.float64)


def _as_sparse_mass(M) -> sp.csc_matrix:
    if sp.issparse(M):
        return M.tocsc()
    m = np.asarray(M, dtype=np.float64)
    if m.ndim != 1:
        raise ValueError(f"mass must be a vector (n,) or a sparse (n, n) matrix; got shape {m.shape}")
    return sp.diags(m).tocsc()


def shift(W, M) -> float:
    """The shift-invert shift ``-SHIFT_REL · trace(W) / trace(M)`` (see the module doc)."""
    return -SHIFT_REL * float(W.diagonal().sum() / _as_sparse_mass(M).diagonal().sum())


def smallest_eigenpairs(W, M, k: int, *, operator=None, opinv=None, sigma: float | None = None,
                        tol: float = 0.0, weyl_area: float | None = None,
                        solver: str = "auto") -> tuple[np.ndarray, np.ndarray]:
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
    solver : ``"auto"`` (default), ``"superlu"`` or ``"cholesky"``: the factorisation of the
        shift-invert Lanczos route for a sparse ``W`` (module doc). ``"auto"`` is ``"cholesky"``
        from ``CHOLESKY_MIN_N`` unknowns when ``cholespy`` is installed (and falls back to SuperLU
        if the shifted matrix is not positive definite, e.g. for a given ``sigma > 0``).
        ``"cholesky"`` raises ``ImportError`` without ``cholespy`` and ``ValueError`` for a
        ``sigma`` that makes ``W - σM`` indefinite. Ignored by the dense route and with ``operator``.

    Eigenvectors are ``M``-orthonormal up to round-off and ``M``-normalised exactly; the
    solver route is chosen by ``DENSE_MAX_N`` / ``DENSE_FRACTION`` (module doc).
    """
    n = W.shape[0]
    if not 1 <= k < n:
        raise ValueError(f"k={k} eigenpairs requested for a problem of size {n}: need 1 <= k < {n}")
    if solver not in SOLVERS:
        raise ValueError(f"solver must be one of {SOLVERS}, got {solver!r}")
    Mm = _as_sparse_mass(M)
    dense = operator is None and (n <= DENSE_MAX_N or k > n // DENSE_FRACTION)
    fallback = solver == "auto"  # the route was not asked for: SuperLU when Cholesky fails
    if fallback:
        solver = "cholesky" if (operator is None and not dense and n >= CHOLESKY_MIN_N and have_cholesky()) \
            else "superlu"
    if dense:
        import scipy.linalg as sla

        evals, vecs = sla.eigh(W.toarray(), Mm.toarray(), subset_by_index=[0, k - 1])
    else:
        from scipy.sparse.linalg import eigsh

        A = W.tocsc() if operator is None else operator
        evals = None
        if operator is None and solver == "cholesky":  # around the safe shift only (module doc)
            sig = shift(W, Mm) if sigma is None else float(sigma)
            try:
                inv = _cholesky_inverse(A - sig * Mm)
            except ValueError as e:
                if not fallback:
                    raise ValueError(f"solver='cholesky' needs W - sigma*M positive definite (sigma = {sig:.3g}); "
                                     f"use solver='superlu' for this shift ({e})") from e
            else:
                evals, vecs = eigsh(A, k=k, M=Mm, sigma=sig, which="LM", OPinv=inv, v0=np.ones(n), tol=tol)
        if evals is None and operator is None and sigma is None:  # first inside the wanted spectrum (module doc)
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
