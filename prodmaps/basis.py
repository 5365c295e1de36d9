"""Functional bases: Laplace–Beltrami eigenbases of meshes and the 1D periodic Fourier basis.

Conventions
-----------
* A :class:`Basis` holds ``vecs`` ``(n, k)`` whose columns are functions on the ``n`` points,
  ``evals`` ``(k,)`` ascending, and the mass (``(n,)`` lumped diagonal, or a sparse ``(n, n)``
  FEM mass).
* Columns are orthonormal in the **area inner product**: ``vecs.T @ A @ vecs = I``.
* Column 0 is the constant function ``φ0 = 1/sqrt(total area)`` and is positive.
* ``k`` counts **all** columns, the constant included. The paper's ``k_M`` counts the
  non-constant ones: the paper's ``k_M = 9`` is ``eigenbasis(mesh, 10)``.
* Signs are deterministic: every non-constant column has its entry of largest magnitude
  positive (the first such entry if several tie), so reruns give identical bases.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from .laplacian import laplacian
from .mesh import Mesh

__all__ = ["Basis", "eigenbasis", "fourier_basis", "fix_signs"]


@dataclass(frozen=True, eq=False)
class Basis:
    """An A-orthonormal functional basis on ``n`` points.

    Attributes
    ----------
    vecs : (n, k) basis functions as columns, ``vecs[:, 0]`` constant.
    evals : (k,) eigenvalues (ascending; 0 for the constant).
    mass : (n,) lumped area weights, or sparse (n, n) mass matrix.
    name : label for messages.
    """

    vecs: np.ndarray
    evals: np.ndarray
    mass: np.ndarray | sp.spmatrix
    name: str = ""
    _cache: dict = field(default_factory=dict, repr=False, compare=False)

    def __post_init__(self):
        vecs = np.asarray(self.vecs, dtype=np.float64)
        evals = np.asarray(self.evals, dtype=np.float64)
        if vecs.ndim != 2:
            raise ValueError(f"vecs must be (n, k); got shape {vecs.shape}")
        if evals.shape != (vecs.shape[1],):
            raise ValueError(f"evals must have shape ({vecs.shape[1]},); got {evals.shape}")
        if not sp.issparse(self.mass):
            mass = np.asarray(self.mass, dtype=np.float64)
            if mass.shape != (vecs.shape[0],):
                raise ValueError(f"mass must be ({vecs.shape[0]},) or sparse (n, n); got {mass.shape}")
            if np.any(mass <= 0) or not np.all(np.isfinite(mass)):
                raise ValueError("mass must be finite and positive")
            object.__setattr__(self, "mass", mass)
        for name, arr in (("vecs", vecs), ("evals", evals)):
            if not np.all(np.isfinite(arr)):
                raise ValueError(f"basis {name} contain non-finite values")
        vecs.setflags(write=False)
        evals.setflags(write=False)
        object.__setattr__(self, "vecs", vecs)
        object.__setattr__(self, "evals", evals)

    # ------------------------------------------------------------------ basics
    @property
    def n(self) -> int:
        """Number of points."""
        return self.vecs.shape[0]

    @property
    def k(self) -> int:
        """Number of columns, the constant included (the paper's k_M + 1)."""
        return self.vecs.shape[1]

    @property
    def mass_is_diagonal(self) -> bool:
        return not sp.issparse(self.mass)

    @property
    def area(self) -> float:
        return float(self.mass.sum())

    @property
    def phi0(self) -> float:
        """Value of the constant basis function, ``1/sqrt(area)``."""
        return float(self.vecs[0, 0])

    def apply_mass(self, f: np.ndarray) -> np.ndarray:
        """``A @ f`` for ``f`` ``(n,)`` or ``(n, m)``."""
        if self.mass_is_diagonal:
            return self.mass[:, None] * f if f.ndim == 2 else self.mass * f
        return self.mass @ f

    def project(self, f: np.ndarray) -> np.ndarray:
        """Coefficients ``Φᵀ A f`` ``(k,)`` or ``(k, m)`` (the A-orthogonal projection)."""
        return self.vecs.T @ self.apply_mass(f)

    def reconstruct(self, coefs: np.ndarray) -> np.ndarray:
        """``Φ @ coefs``."""
        return self.vecs @ coefs

    def truncate(self, k: int) -> "Basis":
        """The first ``k`` columns (constant included); ``self`` when ``k == self.k`` (keeps caches)."""
        if not 1 <= k <= self.k:
            raise ValueError(f"k must be in [1, {self.k}], got {k}")
        if k == self.k:
            return self
        return Basis(self.vecs[:, :k], self.evals[:k], self.mass, name=self.name)

    def __repr__(self) -> str:
        label = f"{self.name!r}, " if self.name else ""
        return f"Basis({label}n={self.n}, k={self.k})"


def fix_signs(vecs: np.ndarray) -> np.ndarray:
    """Flip columns so the entry of largest magnitude of each column is positive."""
    idx = np.argmax(np.abs(vecs), axis=0)  # (k,)
    s = np.sign(vecs[idx, np.arange(vecs.shape[1])])
    s[s == 0] = 1.0
    return vecs * s


def eigenbasis(mesh: Mesh, k: int, kind: str = "cotan", mass: str = "lumped") -> Basis:
    """First ``k`` Laplace–Beltrami eigenpairs of ``mesh`` (constant included).

    Solves ``W φ = λ A φ`` (see :func:`prodmaps.laplacian`) by shift-invert Lanczos around a
    small negative shift (one sparse LU factorisation), or densely for small meshes.

    Parameters
    ----------
    k : number of columns including the constant; the paper's ``k_M = 9`` is ``k = 10``.
    kind, mass : passed to :func:`prodmaps.laplacian`.
    """
    if not isinstance(mesh, Mesh):
        raise TypeError(f"eigenbasis expects a prodmaps.Mesh, got {type(mesh).__name__}")
    n = mesh.n_vertices
    if not isinstance(k, (int, np.integer)) or isinstance(k, bool):
        raise TypeError(f"k must be an integer, got {type(k).__name__}")
    if not 1 <= k < n:
        raise ValueError(
            f"k={k} is out of range for a mesh with {n} vertices: need 1 <= k < {n} "
            "(k counts the constant; the paper's k_M = 9 is k = 10)"
        )
    W, A = laplacian(mesh, kind=kind, mass=mass)
    Am = sp.diags(A).tocsc() if not sp.issparse(A) else A.tocsc()
    if n <= 1500 or k > n // 3:
        import scipy.linalg as sla

        evals, vecs = sla.eigh(W.toarray(), Am.toarray(), subset_by_index=[0, k - 1])
    else:
        from scipy.sparse.linalg import eigsh

        # shift slightly below 0 so that W - σA is positive definite and factorises stably
        scale = float(W.diagonal().sum() / Am.diagonal().sum())
        sigma = -1e-8 * scale
        v0 = np.ones(n)  # deterministic start vector
        evals, vecs = eigsh(W.tocsc(), k=k, M=Am, sigma=sigma, which="LM", v0=v0, tol=0)
        order = np.argsort(evals)
        evals, vecs = evals[order], vecs[:, order]
    # A-normalise (eigsh already does up to round-off), fix the constant exactly, fix signs
    norms = np.sqrt(np.einsum("ij,ij->j", vecs, Am @ vecs))
    vecs = vecs / norms
    area = float(Am.diagonal().sum()) if not sp.issparse(A) else float(A.sum())
    evals = np.maximum(evals, 0.0)
    evals[0] = 0.0
    vecs[:, 0] = 1.0 / np.sqrt(area)
    vecs[:, 1:] = fix_signs(vecs[:, 1:])
    return Basis(vecs, evals, A, name=mesh.name)


def fourier_basis(n: int, k: int, period: float = 2 * np.pi) -> Basis:
    """The 1D periodic Fourier basis sampled at ``n`` equispaced points of ``[0, period)``.

    Columns: constant, then ``cos(ωx), sin(ωx), cos(2ωx), sin(2ωx), …`` with
    ``ω = 2π/period``, orthonormal for the quadrature weights ``period/n`` (exact for
    trigonometric polynomials of degree < n/2). Eigenvalues are those of ``-d²/dx²``.
    ``k`` counts all columns, the constant included.
    """
    if not 1 <= k <= n // 2:
        raise ValueError(f"k must be in [1, n//2] = [1, {n // 2}] for n={n} samples, got {k}")
    x = np.arange(n) * (period / n)
    w = np.full(n, period / n)
    omega = 2 * np.pi / period
    cols = [np.full(n, 1.0 / np.sqrt(period))]
    evals = [0.0]
    j = 1
    while len(cols) < k:
        for trig in (np.cos, np.sin):
            if len(cols) < k:
                cols.append(trig(j * omega * x) * np.sqrt(2.0 / period))
                evals.append((j * omega) ** 2)
        j += 1
    return Basis(np.stack(cols, axis=1), np.array(evals), w, name="fourier")
