"""AWFT point descriptors [MRCB16]: anisotropic windowed Fourier transforms (see :func:`awft`).

References
----------
[MRCB16] Melzi, Rodolà, Castellani, Bronstein. Shape analysis with anisotropic windowed Fourier
transform. 3DV 2016.
[ACR14] Andreux, Rodolà, Aubry, Cremers. Anisotropic Laplace-Beltrami operators for shape
analysis. ECCV workshops 2014.
"""

from __future__ import annotations

import numpy as np

from ..curvature import principal_curvatures, shape_index
from ..eigensolver import smallest_eigenpairs
from ..mesh import Mesh, check_mesh
from ..operators import anisotropic_laplacian, laplacian
from .spectral import as_1d_finite

__all__ = ["awft", "geometry_vectors", "GEOVEC_BANDS"]


def _eigenpairs(W, A, k: int, weyl_area: float | None = None):
    """First ``k`` eigenpairs of ``W φ = λ A φ`` (eigenvalues clipped at 0; ``weyl_area`` of the solver)."""
    evals, vecs = smallest_eigenpairs(W, A, k, weyl_area=weyl_area)
    return np.maximum(evals, 0.0), vecs


_AWFT_FUNCTIONS = ("constant", "mean_curvature", "hks", "shape_index", "fiedler")  # and "geovec<j>"
_ISOTROPIC_FUNCTIONS = ("hks", "fiedler")  # signals computed from the isotropic eigenpairs (and geovec<j>)
GEOVEC_BANDS = 150  # spectral bands of the geometry vectors (the authors' release)


def _geovec_index(name: str) -> int | None:
    """``j`` of ``"geovec<j>"`` (1-based, as the authors' release names them), else ``None``."""
    if name.startswith("geovec") and name[6:].isdigit() and 1 <= int(name[6:]) <= GEOVEC_BANDS:
        return int(name[6:])
    return None


def _cubic_bspline(x: np.ndarray) -> np.ndarray:
    """The centred cubic B-spline ``β3`` (support ``[-2, 2]``, ``β3(0) = 2/3``, partition of unity)."""
    a = np.abs(x)
    return np.where(a < 1, 2.0 / 3.0 - a**2 + a**3 / 2.0, np.where(a < 2, (2.0 - a) ** 3 / 6.0, 0.0))


def geometry_vectors(evals: np.ndarray, evecs: np.ndarray, bands: int = GEOVEC_BANDS) -> np.ndarray:
    """Spectral band descriptors ``(n, bands)``: ``g_j = Σ_i β3((λ_i − c_j)/Δ) φ_i²``.

    Centres ``c_j = (j − 1) Δ``, ``Δ = λ_max / (bands − 1)`` over the given eigenvalues (``λ_max`` the
    largest), cubic B-spline bands of width ``Δ`` (the geometry vectors of the authors' AWFT release,
    column ``j`` there is ``g_j`` here, 1-based). Scale-free: ``c_j`` is relative to ``λ_max``;
    ``φ_i`` A-orthonormal (``(n, k)``), ``evals`` ``(k,)``.
    """
    lam = np.abs(np.asarray(evals, dtype=np.float64))
    delta = lam.max() / (bands - 1)
    B = _cubic_bspline((lam[:, None] - delta * np.arange(bands)[None, :]) / delta)  # (k, bands)
    return (evecs**2) @ B


def awft(mesh: Mesh, *, k: int = 100, angles_deg=(0.0, 45.0, 90.0, 135.0), alpha=10.0,
         include_isotropic: bool = True, taus=(0.002, 0.005, 0.02), freqs0=(0, 0, 0),
         functions=("mean_curvature", "hks"), curvature_smooth: int = 1, hks_t_rel: float = 0.01,
         cache=None) -> np.ndarray:
    """AWFT descriptor [MRCB16] at every vertex, ``(n, len(taus)·n_operators·len(functions))``.

    30 columns with the defaults: 3 windows x (4 angles + isotropic) x 2 functions.

    What is implemented (one column per window ``ℓ``, operator ``(α, θ)`` and function ``f``):

    1. Operators: the anisotropic Laplacians ``W_αθ`` of :func:`anisotropic_laplacian` for each
       ``α`` in ``alpha`` (a number or a sequence) and each ``θ`` in ``angles_deg`` (rotation of the
       maximal curvature direction; curvature directions from per-face shape-operator fitting,
       :func:`principal_curvatures`), plus the isotropic cotangent Laplacian once if
       ``include_isotropic`` (``n_operators = len(alpha)·len(angles) + 1``; the authors' release
       lists it once per ``α``, duplicate columns). For each, its first ``k`` eigenpairs
       ``(λ_j, φ_j)`` (A-orthonormal, constant included).
    2. Window (spectral, translated to every vertex ``x``):
       ``ĝ_j = exp(-τ · area · |λ_j - λ_{j0}|)`` with ``τ = taus[ℓ]``, ``j0 = freqs0[ℓ]``
       (``j0 = 0``: a heat-like low-pass window; ``τ·area`` makes it scale-invariant), and
       ``g_x = Σ_j c_j(x) φ_j`` with ``c(x) = ĝ ⊙ Φ(x) / ||ĝ ⊙ Φ(x)||_2`` (unit-energy windows).
    3. Windowed Fourier transform of ``f``:
       ``Sf(x, j) = sqrt(area) · <f φ_j, g_x>_A = sqrt(area) · Σ_l c_l(x) (Φᵀ A diag(f) Φ)_{jl}``,
       one ``(n, k) @ (k, k)`` product per operator -- no per-vertex loop.
    4. Descriptor (total weighted power, as in the authors' description):
       ``desc(x) = Σ_j (λ_j² / Σ_i λ_i²) Sf(x, j)²``, normalised to unit area-weighted RMS
       over the shape (``∫ desc² dA = area``; the authors normalise the vertex vector to unit
       Euclidean norm, which depends on the vertex count).

    ``functions`` (the signals being analysed, evaluated once on the mesh): ``"mean_curvature"``
    (per-vertex mean curvature, scaled by ``sqrt(area)`` to be scale-free), ``"hks"`` (the
    isotropic HKS at ``t = hks_t_rel · area``), ``"constant"`` (``f = 1``), ``"shape_index"``
    (:func:`prodmaps.curvature.shape_index` of the vertex principal curvatures),
    ``"fiedler"`` (the first non-constant isotropic eigenfunction), ``"geovec<j>"`` (band ``j``,
    1-based, of :func:`geometry_vectors` over the isotropic eigenpairs). ``Sf`` depends on the
    sign of ``f`` and of ``φ_j`` only through ``Sf²``, so the descriptor is sign-independent; it is
    invariant to rigid motions and to uniform scaling. Costs ``n_operators`` sparse eigensolves
    of size ``k``.

    ``cache`` (optional, a :class:`prodmaps.cache.Cache` of **this mesh**, owned by the caller):
    keeps the operators' eigenpairs, which depend only on ``k``, ``alpha``, the angle and
    ``curvature_smooth``; descriptors with other windows or functions on the same mesh then reuse
    them (the same numbers: they are what would be computed again).
    """
    mesh = check_mesh(mesh, "awft")
    if int(k) != k or not 2 <= k < mesh.n_vertices:
        raise ValueError(f"k must be an integer in [2, {mesh.n_vertices}), got {k!r}")
    taus = as_1d_finite(taus, "taus", positive=True)
    freqs0 = np.atleast_1d(np.asarray(freqs0))
    if (freqs0.shape != taus.shape or not np.issubdtype(freqs0.dtype, np.integer) or np.any(freqs0 < 0)
            or np.any(freqs0 >= k)):
        raise ValueError(f"freqs0 must be integers in [0, k) with one entry per tau; got {freqs0!r}")
    angles = as_1d_finite(angles_deg, "angles_deg") if len(np.atleast_1d(angles_deg)) else np.zeros(0)
    alphas = as_1d_finite(alpha, "alpha")  # non-empty
    if np.any(alphas < 0):
        raise ValueError(f"alpha must be one or more numbers >= 0, got {alpha!r}")
    functions = tuple(functions)
    bad = [f for f in functions if f not in _AWFT_FUNCTIONS and _geovec_index(f) is None]
    if bad or not functions:
        raise ValueError(f"functions must be a non-empty subset of {_AWFT_FUNCTIONS} or 'geovec<j>' "
                         f"(j in 1..{GEOVEC_BANDS}), got {functions!r}")
    if angles.size == 0 and not include_isotropic:
        raise ValueError("no operator: give angles_deg or include_isotropic=True")

    area = mesh.area
    k = int(k)

    def cached(key, compute):
        return compute() if cache is None else cache.get(("awft", *key), compute)

    curv = cached(("curvature", int(curvature_smooth)), lambda: principal_curvatures(mesh, smooth=curvature_smooth))

    def anisotropic(a, al):  # (evals (k,), vecs (n, k)) of the operator at angle a (degrees), anisotropy al
        W, A_ = anisotropic_laplacian(mesh, np.deg2rad(a), al, curvature=curv)
        # Weyl's law of -div(D ∇·) counts with ∫ det(D)^(-1/2) dA: D has eigenvalues 1 and 1/(1+α)
        return _eigenpairs(W, A_, k, float(np.sum(A_)) * np.sqrt(1.0 + al))

    W0, A = laplacian(mesh)  # A: the lumped mass of every operator
    eig = [cached(("eig", float(a), float(al), k, int(curvature_smooth)), lambda a=a, al=al: anisotropic(a, al))
           for al in alphas for a in angles]
    needs_iso = any(f in _ISOTROPIC_FUNCTIONS or _geovec_index(f) is not None for f in functions)
    if include_isotropic or needs_iso:
        iso = cached(("eig", "isotropic", k), lambda: _eigenpairs(W0, A, k))
        if include_isotropic:
            eig.append(iso)

    fvals, bands = [], None
    for name in functions:
        if name == "constant":
            fvals.append(np.ones(mesh.n_vertices))
        elif name == "mean_curvature":
            fvals.append(curv["mean"] * np.sqrt(area))
        elif name == "hks":  # from the isotropic eigenpairs
            ev0, vec0 = iso
            fvals.append(((vec0**2) @ np.exp(-ev0 * hks_t_rel * area)) * area)
        elif name == "shape_index":
            fvals.append(shape_index(curv["vertex_k_max"], curv["vertex_k_min"]))
        elif name == "fiedler":
            fvals.append(iso[1][:, 1] * np.sqrt(area))
        else:  # geovec<j>
            bands = geometry_vectors(*iso) if bands is None else bands  # (n, GEOVEC_BANDS), once
            fvals.append(bands[:, _geovec_index(name) - 1] * area)
    fmat = np.stack(fvals, axis=1)  # (n, F)

    # (k, k) Φᵀ A diag(f) Φ per operator and signal: independent of the window, computed once
    mod = [[vecs.T @ ((A * f)[:, None] * vecs) for f in fmat.T] for _, vecs in eig]
    cols = []
    rho = np.sqrt(area)
    for ell, tau in enumerate(taus):
        for (ev, vecs), Ms in zip(eig, mod):
            ghat = np.exp(-tau * area * np.abs(ev - ev[freqs0[ell]]))  # (k,)
            c = vecs * ghat[None, :]  # (n, k)
            c /= np.linalg.norm(c, axis=1, keepdims=True)
            lam2 = ev**2
            wpow = lam2 / lam2.sum()
            for M in Ms:
                Sf = rho * (c @ M.T)  # (n, k): Sf[x, j] = Σ_l c_l(x) M[j, l]
                d = (Sf**2) @ wpow  # (n,)
                cols.append(d / np.sqrt(np.sum(A * d * d) / area))  # unit area-RMS
    return np.stack(cols, axis=1)
