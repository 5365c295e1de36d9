"""Spectral point descriptors: HKS, WKS and heat kernels, as pure functions of eigenpairs.

Holds :func:`hks` and :func:`wks` (with their default samplings :func:`hks_times`,
:func:`wks_energies`, :func:`wks_energies_from_evals` and the filter :func:`wks_weights`),
:func:`heat_kernel`, and :func:`nonzero_eigenvalues` with its threshold :data:`ZERO_EIGENVALUE_REL`.

Conventions
-----------
* A :class:`prodmaps.Basis` holds ``vecs`` ``(n, k)`` orthonormal in the **area inner product**
  (``ΦᵀAΦ = I``), ``evals`` ascending, column 0 the constant ``1/sqrt(area)``; ``k`` counts the
  constant (see :mod:`prodmaps.conventions`). Descriptors use *all* the eigenpairs they are
  given; pass ``basis.truncate(k)`` to use fewer.
* Every descriptor returns an ``(n, d)`` array, one row per vertex, one column per time or energy.
* An eigenvalue counts as zero (the constant's) when ``|λ| <= ZERO_EIGENVALUE_REL · max |λ|``;
  WKS excludes those eigenpairs (its filter needs ``log λ``).
* ``hks(basis, times)``: ``h_t(x, x) = Σ_i exp(-λ_i t) φ_i(x)²`` [SOG09], the constant included;
  ``wks(basis, energies, sigma)``: ``Σ_{i≥1} f_e(λ_i)² φ_i(x)²``, log-normal filter [ASC11],
  ``scaled=True`` by default. Both lie exactly in the span of the products of the basis.

The definitions and scalings in full, the default samplings (SOG09's time range, ASC11's energies,
pyFM's ``auto_WKS``), the invariances to rigid motions and scaling, and the references:
``docs/guide/descriptors.md``.
"""
from __future__ import annotations

import numpy as np

from ..basis import Basis
from ..checks import check_basis

__all__ = ["ZERO_EIGENVALUE_REL", "nonzero_eigenvalues", "hks", "hks_times", "wks", "wks_weights",
           "wks_energies", "wks_energies_from_evals", "heat_kernel", "as_1d_finite"]

ZERO_EIGENVALUE_REL = 1e-8


def as_1d_finite(x, name: str, positive: bool = False) -> np.ndarray:
    """``x`` as a non-empty finite 1D float64 array (``> 0`` with ``positive``), else ``ValueError`` naming ``name``."""
    arr = np.atleast_1d(np.asarray(x, dtype=np.float64))
    if arr.ndim != 1 or arr.size == 0:
        raise ValueError(f"{name} must be a non-empty 1-D sequence of numbers, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} contains non-finite values")
    if positive and np.any(arr <= 0):
        raise ValueError(f"{name} must be > 0, got min {arr.min():g}")
    return arr


def nonzero_eigenvalues(evals) -> np.ndarray:
    """Boolean mask ``(k,)`` of the eigenvalues that are not zero (``|λ| > ZERO_EIGENVALUE_REL · max |λ|``)."""
    ev = np.abs(np.asarray(evals, dtype=np.float64))
    keep = ev > ZERO_EIGENVALUE_REL * max(float(ev.max()) if ev.size else 0.0, np.finfo(float).tiny)
    if not np.any(keep):
        raise ValueError(f"the spectrum has no non-zero eigenvalue ({ev.size} eigenvalues); use at least 2 eigenpairs")
    return keep


# ----------------------------------------------------------------------------- HKS
def hks(basis: Basis, times, *, scaled: bool = False) -> np.ndarray:
    """Heat kernel signature ``h_t(x,x) = Σ_i exp(-λ_i t) φ_i(x)²``, ``(n, len(times))``.

    Uses every eigenpair of ``basis`` (constant included). ``times`` must be > 0.
    ``scaled=True`` divides each column by the heat trace ``Σ_i exp(-λ_i t)``.
    """
    basis = check_basis(basis)
    t = as_1d_finite(times, "times", positive=True)
    coefs = np.exp(-np.outer(basis.evals, t))  # (k, T)
    out = (basis.vecs**2) @ coefs  # (n, T)
    if scaled:
        out = out / coefs.sum(axis=0)[None, :]
    return out


def hks_times(basis: Basis, num: int = 100, *, factor: float = 4.0 * np.log(10.0)) -> np.ndarray:
    """``num`` times log-spaced in ``[factor/λ_max, factor/λ_1]`` (SOG09: ``factor = 4 ln 10``)."""
    basis = check_basis(basis)
    if int(num) != num or num < 1:
        raise ValueError(f"num must be a positive integer, got {num!r}")
    if not np.isfinite(factor) or factor <= 0:
        raise ValueError(f"factor must be > 0, got {factor!r}")
    ev = basis.evals[nonzero_eigenvalues(basis.evals)]
    return np.geomspace(factor / ev.max(), factor / ev.min(), int(num))


# ----------------------------------------------------------------------------- WKS
def wks_energies_from_evals(evals, num: int = 100, *, variance: float = 7.0,
                            margin: float = 2.0) -> tuple[np.ndarray, float]:
    """Automatic WKS sampling [ASC11] from eigenvalues: ``(energies (num,), sigma)``.

    ``σ = variance · (log λ_max - log λ_1) / num`` over the non-zero eigenvalues and
    ``energies = linspace(log λ_1 + margin·σ, log λ_max - margin·σ, num)``. Raises ValueError when
    the margins leave no room (need ``num > 2·margin·variance``).
    """
    if int(num) != num or num < 1:
        raise ValueError(f"num must be a positive integer, got {num!r}")
    if not (np.isfinite(variance) and variance > 0 and np.isfinite(margin) and margin >= 0):
        raise ValueError(f"need variance > 0 and margin >= 0, got {variance!r}, {margin!r}")
    ev = np.abs(np.asarray(evals, dtype=np.float64))
    ev = ev[nonzero_eigenvalues(ev)]
    e_min, e_max = np.log(ev.min()), np.log(ev.max())
    if e_max <= e_min:
        raise ValueError("need at least two distinct non-zero eigenvalues for WKS energies")
    sigma = variance * (e_max - e_min) / num
    lo, hi = e_min + margin * sigma, e_max - margin * sigma
    if hi < lo or (num > 1 and hi == lo):
        raise ValueError(f"num={num} energies with variance={variance} and margin={margin} leave an empty "
                         f"energy range; use num > {2 * margin * variance:g}, or a smaller margin/variance")
    return np.linspace(lo, hi, int(num)), float(sigma)


def wks_energies(basis: Basis, num: int = 100, *, variance: float = 7.0,
                 margin: float = 2.0) -> tuple[np.ndarray, float]:
    """:func:`wks_energies_from_evals` of ``basis.evals``: ``(energies (num,), sigma)``."""
    return wks_energies_from_evals(check_basis(basis).evals, num, variance=variance, margin=margin)


def wks_weights(evals, energies, sigma: float, *, scaled: bool = True) -> np.ndarray:
    """The WKS spectral filter ``(len(energies), k)``: ``exp(-(e - log λ_i)²/(2σ²))``.

    Zero eigenvalues (the constant) get weight 0. With ``scaled`` (ASC11's normalisation) each
    row is divided by its sum, so every energy has unit total filter weight.
    """
    e = as_1d_finite(energies, "energies")
    if not np.isfinite(sigma) or sigma <= 0:
        raise ValueError(f"sigma must be finite and > 0, got {sigma!r}")
    ev = np.abs(np.asarray(evals, dtype=np.float64))
    keep = nonzero_eigenvalues(ev)
    logs = np.log(np.where(keep, ev, 1.0))
    w = np.exp(-((e[:, None] - logs[None, :]) ** 2) / (2.0 * sigma**2)) * keep[None, :]  # (E, k)
    if scaled:
        tot = w.sum(axis=1, keepdims=True)  # (E, 1)
        if np.any(tot <= np.finfo(float).tiny):
            raise ValueError("an energy lies so far outside the spectrum that its filter vanishes; "
                             "choose energies within [log λ_1, log λ_max] or a larger sigma")
        w = w / tot
    return w


def wks(basis: Basis, energies, sigma: float, *, scaled: bool = True) -> np.ndarray:
    """Wave kernel signature ``Σ_i w_e,i φ_i(x)²`` with the filter of :func:`wks_weights`, ``(n, E)``.

    ``energies`` are log-eigenvalue positions (any finite reals); ``sigma > 0``. The constant
    eigenpair (λ = 0) is excluded.
    """
    basis = check_basis(basis)
    w = wks_weights(basis.evals, energies, sigma, scaled=scaled)  # (E, k)
    return (basis.vecs**2) @ w.T  # (n, E)


# ----------------------------------------------------------------------------- heat kernels
def heat_kernel(basis: Basis, sources, t: float) -> np.ndarray:
    """Heat kernels ``h_t(x_s, ·) = Σ_i exp(-λ_i t) φ_i(x_s) φ_i(·)``, ``(n, len(sources))``.

    Built from all eigenpairs of ``basis`` (truncate the basis to use fewer). With the
    A-orthonormal basis, ``u = h_t(x_s, ·)`` is the (truncated) solution of the heat equation
    started from a unit-mass Dirac at ``x_s`` (``δ = 1/A_s`` at the vertex), and the matrix
    ``heat_kernel(basis, idx, t)[idx]`` is symmetric.
    """
    basis = check_basis(basis)
    if not np.isfinite(t) or t <= 0:
        raise ValueError(f"t must be finite and > 0, got {t!r}")
    src = np.atleast_1d(np.asarray(sources))
    if src.ndim != 1 or not np.issubdtype(src.dtype, np.integer):
        raise ValueError("sources must be a 1-D array of integer vertex indices")
    if src.size and (src.min() < 0 or src.max() >= basis.n):
        raise ValueError(f"sources must be vertex indices in [0, {basis.n}); got range [{src.min()}, {src.max()}]")
    w = np.exp(-basis.evals * t)  # (k,)
    return (basis.vecs * w[None, :]) @ basis.vecs[src].T  # (n, s)
