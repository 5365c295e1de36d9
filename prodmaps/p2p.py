"""Point maps and functional maps, both ways: ``p2p_21 -> C_12`` and ``C_12 -> p2p_21`` (Sections 4.4, 5.3).

Conventions (:mod:`prodmaps.conventions`): ``C_12`` is ``(k2, k1)``; ``p2p_21`` ``(n2,)`` gives for each
vertex of shape 2 a vertex of shape 1 (pull-back); bases are A-orthonormal with the constant first.

* :func:`fmap_from_p2p`: ``C_12 = Φ2ᵀ A2 Φ1[p2p_21]``, the functional map of a point map.
* :func:`from_fmap` ``(C_12, basis_1, basis_2, method)``: the point map of a functional map.

  - ``method="std"`` [OBCS*12]: each vertex ``y`` of shape 2 takes the vertex ``x`` of shape 1 whose
    transferred delta function is nearest, rows of ``Φ2[:, :k2]`` against rows of ``s·Φ1[:, :k1] C_12ᵀ``.
    ``convention="area"`` (default): ``s = area_1 / area_2``, the comparison of the two shapes scaled
    to unit area (exact for ground-truth maps whatever the areas; the map does not depend on units);
    ``convention="pyfm"``: ``s = 1``, pyFM's ``FM_to_p2p`` (the same map when the areas are equal).
  - ``method="extended"`` (the paper's Section 4.4): every point is a function on its mesh
    (``point="heat"``, default: the squared heat kernel ``(area·h_t(x, ·))²`` from up to
    ``DEFAULT_KERNEL_EIG`` eigenpairs of the given bases; ``"delta"``: ``area·δ_x``;
    ``"closed_form"``: the kernel from the map's own eigenpairs in closed form, which cannot beat
    ``"std"``), fitted in its shape's order-2 extended basis by Approach B (``rtol`` 1e-3, the
    ``"euclidean"`` reading), transferred by ``C̃`` and compared through canonical coefficients
    ``ã = Σ Vᵀ a`` (``‖f‖_A = ‖ã‖₂``). :func:`extended_embeddings` returns those coefficients,
    :func:`point_functions` the functions, :func:`heat_square_coefficients` the closed form's.

* Nearest neighbours are exact with ties to the smallest index (:mod:`prodmaps.neighbors`;
  ``search="approximate"`` or ``"auto"`` for millions of vertices).
* Precision: the extended conversion's large products run in float32 by default (``dtype``): its
  embeddings agree with the float64 ones to about 1e-6 relative; ``dtype="float64"`` is exact.
* Cost of ``"extended"``: per shape, the Gram matrix of its extended basis (``min(n, K)²``) and its
  eigenpairs above Approach B's threshold only (cached in the basis: maps from one source reuse
  them); ``C̃`` applied without being formed; point functions by blocks of ``KERNEL_BLOCK_BYTES``.
  ``progress=None`` shows a bar for long conversions on a terminal (:mod:`prodmaps.progress`).
* Units: both conversions give the same map when either mesh is scaled (``convention="pyfm"``
  excepted: its map depends on the area ratio).

Derivations, the choice of ``t``, why the closed form cannot win, the two conventions measured on
shapes of unequal area: ``docs/guide/point_maps.md``.
"""

from __future__ import annotations

import warnings

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp

from .approx import DEFAULT_NORMALIZATION, column_weights
from .basis import Basis
from .checks import check_fmap, check_p2p
from .mapping import extend_fmap
from .mesh import check_vertex_indices
from .neighbors import SEARCHES, nearest_neighbors
from .products import evaluate_products, multi_indices, n_columns, n_orderings, product_basis
from .progress import NullBar, progress_bar

__all__ = ["from_fmap", "fmap_from_p2p", "extended_embeddings", "point_functions", "heat_square_coefficients",
           "METHODS", "POINTS", "CONVENTIONS", "DEFAULT_KERNEL_EIG", "KERNEL_BLOCK_BYTES"]

METHODS = ("std", "extended")
POINTS = ("heat", "delta", "closed_form")  # a point's function in the extended conversion
SUBSPACE_MIN_SIZE = 2000
"""Gram matrices of at least this many rows take the subspace iteration for their kept eigenpairs (smaller: LAPACK)."""
SUBSPACE_BLOCK = 512
"""The subspace iteration's first block size (it grows as the kept directions need)."""
SUBSPACE_TOL = 1e-14
"""Largest residual ``|S v - θ v|`` of a converged Ritz pair, relative to ``w_max`` (LAPACK reaches about 1e-15)."""
CONVENTIONS = ("area", "pyfm")  # the standard conversion's scale of the transferred deltas
DEFAULT_KERNEL_EIG = 200  # eigenpairs of the squared heat kernel (the experiments store's basis size)
KERNEL_BLOCK_BYTES = 64 << 20  # point functions evaluated (n, b) float64 columns at a time, at most this size


def fmap_from_p2p(p2p_21, basis_1: Basis, basis_2: Basis) -> np.ndarray:
    """Functional map ``C_12 = Φ2ᵀ A2 Φ1[p2p_21]`` ``(k2, k1)`` induced by a point map.

    Parameters
    ----------
    p2p_21 : (n2,) array_like of int
        For each vertex of shape 2, its vertex on shape 1 (the pull-back direction).
    basis_1, basis_2 : Basis
        Bases on shape 1 (``n1`` points, ``k1`` columns) and shape 2 (``n2``, ``k2``).

    Returns
    -------
    (k2, k1) ndarray
        Maps coefficients on shape 1 to coefficients on shape 2.

    Raises
    ------
    ValueError
        If ``p2p_21`` is not ``(n2,)`` integer indices in ``[0, n1)``.
    TypeError
        If a basis is not a :class:`prodmaps.Basis`.

    Examples
    --------
    >>> import numpy as np
    >>> import prodmaps as pm
    >>> from prodmaps.mesh import ellipsoid
    >>> b1 = pm.eigenbasis(ellipsoid(2), 6)
    >>> b2 = pm.eigenbasis(ellipsoid(2), 4)
    >>> C = pm.fmap_from_p2p(np.arange(162), b1, b2)  # the identity point map
    >>> C.shape, bool(np.allclose(C, np.eye(4, 6)))
    ((4, 6), True)
    """
    p = check_p2p(p2p_21, basis_1.n, basis_2.n)
    return basis_2.project(basis_1.vecs[p])  # (k2, k1)


def heat_square_coefficients(basis: Basis, t: float, n_eig: int, pairs: str = "unique", points=None) -> np.ndarray:
    """Closed-form coefficients ``(n_points, K)`` of ``h_t(x, ·)²`` in the order-2 extended basis of ``basis``.

    ``h_t(x, ·) = Σ_{i<n_eig} e^{−λ_i t} φ_i(x) φ_i`` (constant included in the count); one row per
    point ``x`` (all vertices, or ``points``). Column layout of
    ``prodmaps.product_basis(basis, order=2, pairs=pairs)`` (see module doc).
    """
    k = basis.k - 1  # non-constant functions of the extended basis
    if not 1 <= n_eig <= basis.k:
        raise ValueError(f"n_eig must be in [1, {basis.k}] (columns of the basis, constant included), got {n_eig}")
    if not t >= 0:
        raise ValueError(f"t must be >= 0, got {t}")
    Phi = basis.vecs if points is None else basis.vecs[np.asarray(points)]
    w = np.zeros(basis.k)
    w[:n_eig] = np.exp(-basis.evals[:n_eig] * t)
    a = Phi * w[None, :]  # (m, k+1) a_i(x)
    c = basis.phi0
    idx = multi_indices(k, 2, pairs)  # (K, 2)
    prod = idx[:, 1] > 0
    out = np.empty((a.shape[0], idx.shape[0]))
    out[:, 0] = a[:, 0] ** 2 * c
    out[:, 1 : k + 1] = 2.0 * c * a[:, :1] * a[:, 1:]
    l, m = idx[prod, 0], idx[prod, 1]
    factor = np.where((l != m) & (pairs == "unique"), 2.0, 1.0)  # (K - k - 1,)
    out[:, prod] = a[:, l] * a[:, m] * factor[None, :]
    return out


_HEAT_SQUARES_CACHE_BYTES = 2**28


def _heat_squares_of_source(basis: Basis, t: float, n_eig: int, pairs: str) -> np.ndarray:
    """:func:`heat_square_coefficients` of all vertices, in ``basis.cache`` (256 MB): every map from it reuses them."""
    if basis.n * n_columns(basis.k - 1, 2, pairs) * 8 > _HEAT_SQUARES_CACHE_BYTES:
        return heat_square_coefficients(basis, t, n_eig, pairs)
    key = ("heat_square_coefficients", basis.k, float(t), int(n_eig), pairs)
    return basis.cache.get(key, lambda: heat_square_coefficients(basis, t, n_eig, pairs))


def _closed_form_embeddings(C, b1: Basis, b2: Basis, *, t, t_scale, n_eig, rtol, normalization, pairs, vertices):
    """The closed form (module doc): ``(emb_1 (n1, r), emb_2 (n2 or m, r), info)``.

    Cost: the map and the canonical projection are composed first, ``(Σ_r V_rᵀ C~) a1ᵀ``
    (``r × K1`` times ``K1 × n1``), not ``Σ_r V_rᵀ (C~ a1ᵀ)``: the same product, ``K2/r``-fold
    fewer operations on the vertices.
    """
    k2, k1 = C.shape
    n_eig = min(k1, k2) if n_eig is None else int(n_eig)
    if not 2 <= n_eig <= min(k1, k2):
        raise ValueError(f"n_eig must be in [2, min(k1, k2) = {min(k1, k2)}] for the closed form, got {n_eig}")
    if t is None:
        t = float(t_scale) / float(b1.evals[n_eig - 1])
    if not (np.isfinite(t) and t >= 0):
        raise ValueError(f"t must be a finite number >= 0, got {t}")
    # Units: t is in shape 1's units (area a1); shape 2 uses the same time relative to its own area,
    # t·a2/a1, and h_t² scales as 1/area², so the transferred kernels are brought to shape 2's scale by
    # (a1/a2)². Equal areas change nothing; scaling either mesh changes no point of the result.
    ratio = b2.area / b1.area
    a1 = _heat_squares_of_source(b1, t, n_eig, pairs)  # (n1, K1)
    a2 = heat_square_coefficients(b2, t * ratio, n_eig, pairs, points=vertices)  # (n2 or m, K2)
    Ct = extend_fmap(C, b1, b2, order=2, pairs=pairs)  # (K2, K1)
    op = product_basis(b2, order=2, pairs=pairs).operator("svd", rtol=rtol, **normalization)
    emb_1 = a1 @ (np.asarray(op.canonical(Ct)).T / ratio**2)  # (n1, K1) @ (K1, r)
    emb_2 = np.asarray(op.canonical(a2.T)).T  # (n2 or m, r)
    return emb_1, emb_2, {"point": "closed_form", "t": t, "n_eig": n_eig, "rtol": rtol, "pairs": pairs,
                          "dim": emb_1.shape[1]}


def point_functions(basis: Basis, points, *, point: str = "heat", t: float, n_eig: int | None = None,
                    dtype=np.float64) -> np.ndarray:
    """The functions on the mesh that represent ``points`` ``(m,)`` in the extended conversion, ``(n, m)``.

    ``point="heat"``: ``(area · h_t(x, ·))²`` with ``h_t(x, ·) = Σ_{i<n_eig} e^{−λ_i t} φ_i(x) φ_i``
    from the first ``n_eig`` columns of ``basis`` (default: all of them); ``point="delta"``:
    ``area · δ_x`` with ``δ_x = e_x / A[x]`` (so that ``∫ δ_x g = g(x)``, lumped mass). The factor
    ``area`` makes the values those of the mesh scaled to unit area (``t`` in this mesh's units),
    so they do not depend on the mesh's units. One column per point; memory ``n·m`` values of
    ``dtype`` (the kernel's product is computed in it).

    Examples
    --------
    >>> import prodmaps as pm
    >>> from prodmaps.mesh import ellipsoid
    >>> b = pm.eigenbasis(ellipsoid(2), 20)
    >>> point_functions(b, [0, 5], t=1.0 / b.evals[9]).shape
    (162, 2)
    """
    if point not in ("heat", "delta"):
        raise ValueError(f"point must be 'heat' or 'delta' for a function on the mesh, got {point!r}")
    if not basis.mass_is_diagonal:
        raise ValueError("point functions need a lumped (diagonal) mass")
    points = np.asarray(points, dtype=np.int64)
    if point == "delta":
        F = np.zeros((basis.n, points.shape[0]), dtype=dtype)
        F[points, np.arange(points.shape[0])] = basis.area / basis.mass[points]
        return F
    n_eig = basis.k if n_eig is None else int(n_eig)
    if not 1 <= n_eig <= basis.k:
        raise ValueError(f"n_eig must be in [1, {basis.k}] (columns of the basis, constant included), got {n_eig}")
    if not (np.isfinite(t) and t >= 0):
        raise ValueError(f"t must be a finite number >= 0, got {t}")
    w = np.exp(-basis.evals[:n_eig] * t) * basis.area  # (n_eig,)
    Phi = basis.vecs[:, :n_eig]
    if np.dtype(dtype) != Phi.dtype:
        Phi = basis.cache.get(("vecs_as", np.dtype(dtype).str, n_eig), lambda: Phi.astype(dtype))
    H = Phi @ (Phi[points] * w.astype(dtype)).T  # (n, m) area · h_t(x, ·)
    np.square(H, out=H)
    return H


def _blocks(n_points: int, n_rows: int, block_bytes: int):
    """Slices of at most ``block_bytes / (8 n_rows)`` points (at least one)."""
    step = max(1, int(block_bytes) // (8 * max(1, n_rows)))
    for s in range(0, n_points, step):
        yield slice(s, min(n_points, s + step))


_SOURCE_COEF_CACHE_BYTES = 2**28  # per-basis results kept in its cache up to this size (source points, frames)
PROGRESS_MIN_WORK = 2e10  # progress=None: a bar when the conversion's multiply-adds exceed this (long runs)


def _solver_rows(pb, rows, d):
    """``X[rows]`` ``(b, K_u)`` of the scaled solver columns ``X = sqrt(A) B_s D`` (``d`` None: ``D = I``)."""
    B = evaluate_products(pb.base.vecs[rows], pb.unique_index)  # (b, K_u) unique products
    scale = pb.solver_scale()  # ordered pairs: sqrt(#orderings) per multiset
    if scale is not None:
        B *= scale
    B *= np.sqrt(pb.base.mass[rows])[:, None]
    if d is not None:
        B *= d
    return B


def _gram_upper(blocks, m: int, trans: int) -> np.ndarray:
    """The upper triangle of ``Σ XbᵀXb`` (``trans=1``) or ``Σ XbXbᵀ`` (``trans=0``) ``(m, m)``, accumulated in place."""
    G = np.zeros((m, m), order="F")
    for Xb in blocks:
        G = sla.blas.dsyrk(1.0, Xb, beta=1.0, c=G, trans=trans, lower=0, overwrite_c=1)
    return G


def _separable_gram(pb, normalization: str, sq: np.ndarray) -> np.ndarray | None:
    """The n-side Gram ``XXᵀ`` ``(n, n)`` of ``X = sqrt(A) B_s D`` in ``O(n² k)`` for order-2 products, or None.

    Every normalisation but ``"columns"`` weighs a product by its factors' weights, ``D = c_l c_m``, so
    the products' part is a Hadamard square: ``Σ_{l,m} c_l² c_m² (φ_l φ_m)(φ_l φ_m)ᵀ = K∘K`` with
    ``K = Φ₊ diag(c²) Φ₊ᵀ`` (``Φ₊`` the non-constant columns). Ordered pairs (the solver's
    ``sqrt(#orderings)``) give ``K∘K``; unique pairs count each multiset once, ``(K∘K + PPᵀ) / 2`` with
    ``P = Φ₊² diag(c²)``. The single factors add ``K``, the constant ``c_0² φ_0 φ_0ᵀ``. Both triangles are
    filled, the upper one equal to :func:`_gram_upper` of the solver columns to rounding (tested), at
    about ``k / K_u`` of its cost.
    """
    base = pb.base
    k = base.k
    if pb.order != 2 or normalization == "columns" or pb.unique_index.shape[0] != 1 + (k - 1) * (k + 2) // 2:
        return None
    c = column_weights(base, normalization)
    c2 = (np.ones(k) if c is None else np.asarray(c, dtype=float)) ** 2  # (k,)
    Phi = base.vecs  # (n, k)
    K = (Phi[:, 1:] * c2[1:]) @ Phi[:, 1:].T  # (n, n), symmetric
    G = K * K  # the products, ordered pairs
    sla.blas.dger(c2[0], Phi[:, 0], Phi[:, 0], a=K.T, overwrite_a=1)  # in place: the constant
    if pb.pairs == "unique":
        G *= 0.5
        P = (Phi[:, 1:] ** 2) * (c2[1:] * np.sqrt(0.5))  # (n, k - 1)
        sla.blas.dgemm(1.0, P, P, trans_b=1, beta=1.0, c=G.T, overwrite_c=1)  # in place (G.T: G, F-ordered)
    G += K  # the single factors
    del K
    G *= sq[:, None]
    G *= sq[None, :]
    return G


def _orthonormal(Z: np.ndarray) -> np.ndarray:
    """An orthonormal basis ``(m, l)`` of the columns of ``Z`` by Cholesky-QR.

    Repeated once unless ``R``'s diagonal spans less than a factor 100 (one pass is orthogonal to about
    ``eps·cond(Z)²``); Householder QR if Cholesky fails.
    """
    for _ in range(2):
        try:
            R = sla.cholesky(Z.T @ Z, lower=False, check_finite=False)
        except np.linalg.LinAlgError:
            return np.linalg.qr(Z)[0]
        Z = Z @ sla.solve_triangular(R, np.eye(R.shape[0]), lower=False, check_finite=False)  # Z R⁻¹
        d = np.abs(np.diag(R))
        if d.max() <= 100.0 * d.min():
            break
    return Z


def _symmetrized(G: np.ndarray) -> np.ndarray:
    """``G`` ``(m, m)`` in full from its upper triangle (a copy, by blocks of rows)."""
    m = G.shape[0]
    S = np.empty((m, m))
    for b in range(0, m, 1024):
        e = min(m, b + 1024)
        S[b:e, e:] = G[b:e, e:]
        S[e:, b:e] = G[b:e, e:].T
        S[b:e, b:e] = np.triu(G[b:e, b:e]) + np.triu(G[b:e, b:e], 1).T
    return S


def _subspace_eigenpairs(S: np.ndarray, rtol: float, *, seed: int = 0, max_iter: int = 30):
    """Eigenpairs ``(w, V)``, descending, of the symmetric PSD ``S`` above ``rtol² w_max / 2``; None if not found.

    Subspace iteration with Rayleigh–Ritz from a seeded random block (the largest Ritz value, a lower
    bound of ``w_max``, sets the floor), grown until at most 60 % of its Ritz values lie above the floor:
    the block then reaches well below the threshold, and the kept directions converge at the ratio of
    the block's last eigenvalue to theirs (about 1e-3 per step for the spectra of product bases). Each
    step orthonormalises ``S V θ⁻¹`` (the Ritz vectors' images, near orthonormal). Converged when every
    Ritz pair above a quarter of the floor has a residual below ``SUBSPACE_TOL · w_max``. None (the caller takes
    LAPACK) when the block would exceed half of ``S``'s size or ``max_iter`` steps do not converge.
    """
    m = S.shape[0]
    rng = np.random.default_rng(seed)
    ell = min(m, SUBSPACE_BLOCK)
    Q = _orthonormal(rng.standard_normal((m, ell)))  # (m, ell)
    for _ in range(max_iter):
        Y = S @ Q  # (m, ell)
        H = Q.T @ Y
        theta, W = np.linalg.eigh(0.5 * (H + H.T))
        theta, W = theta[::-1], W[:, ::-1]
        if not theta[0] > 0:
            return None
        floor = 0.5 * rtol**2 * theta[0]
        above = int(np.sum(theta > floor))
        V = Q @ W  # (m, ell) Ritz vectors
        if above > 0.6 * ell:  # grow the block: the Ritz vectors above the floor, then new random columns
            grow = max(2 * ell, int(1.7 * above) + 64)
            if grow > m // 2:
                return None
            Q = _orthonormal(np.hstack([V[:, :above], rng.standard_normal((m, grow - above))]))
            ell = grow
            continue
        SV = Y @ W  # (m, ell)
        check = int(np.sum(theta > 0.25 * floor))
        res = np.linalg.norm(SV[:, :check] - V[:, :check] * theta[:check], axis=0)
        if res.max() <= SUBSPACE_TOL * theta[0]:
            return theta[:above], V[:, :above]
        Q = _orthonormal(SV / np.where(theta > 0, theta, 1.0))
    return None


def _top_eigenpairs(G: np.ndarray, rtol: float, *, full: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Eigenpairs ``(w (r,), V (m, r))``, descending, of the PSD ``G`` with ``sqrt(w) > rtol·sqrt(w_max)``.

    ``G`` holds its upper triangle (:func:`_gram_upper`; ``full``: both, :func:`_separable_gram`) and is
    overwritten. Approach B's truncation rule on the Gram matrix of the scaled columns (its operator's
    ``route="gram"``), computed for the kept eigenpairs only: from ``SUBSPACE_MIN_SIZE`` rows on by
    :func:`_subspace_eigenpairs`; else, or if that does not converge, by LAPACK's MRRR on the interval
    above a lower bound of the threshold. Then the exact rule with the computed ``w_max``.
    """
    found = None
    if G.shape[0] >= SUBSPACE_MIN_SIZE:
        found = _subspace_eigenpairs(G if full else _symmetrized(G), rtol)
    if found is None:
        v = np.full(G.shape[0], 1.0 / np.sqrt(G.shape[0]))
        for _ in range(20):  # power steps: a Rayleigh quotient never exceeds w_max, so the interval holds every
            u = sla.blas.dsymv(1.0, G, v, lower=0)  # kept eigenvalue
            nu = float(np.linalg.norm(u))
            if nu == 0.0:
                break
            v = u / nu
        lam = float(v @ sla.blas.dsymv(1.0, G, v, lower=0))
        if not lam > 0:
            raise ValueError("the extended basis is zero on this mesh: no canonical coefficients")
        w, V = sla.eigh(G, lower=False, subset_by_value=(0.5 * rtol**2 * lam, np.inf), driver="evr",
                        overwrite_a=True, check_finite=False)
        found = w[::-1], V[:, ::-1]
    w, V = found
    s = np.sqrt(np.maximum(w, 0.0))
    r = int(np.sum(s > rtol * s[0]))
    return w[:r], V[:, :r]


def _canonical_frame(pb, rtol: float, normalization: str, block_bytes: int):
    """``(AΨ (n, r), X (K_u, r), ΣVᵀD⁻¹ (r, K_u))``: Approach B's retained directions on ``pb``.

    With ``sqrt(A) B_s D = U Σ Vᵀ`` truncated to the ``r`` singular values above ``rtol·σ_max`` (``B_s``
    the solver columns, ``D`` the normalisation's column weights), ``X = D V Σ⁻¹`` and ``Ψ = B_s X =
    U / sqrt(A)`` is A-orthonormal: the canonical coefficients of any function are ``ã = Ψᵀ A f``
    (Section 4.4: ``Σ Vᵀ a`` of its Approach B fit ``a``); ``ΣVᵀD⁻¹`` gives those of solver coefficients.
    The truncation is the operator's (:func:`prodmaps.approx.approximation_operator`: the Gram route,
    on the smaller of ``XᵀX`` and ``XXᵀ``, for ``rtol >= 1e-6``; the SVD of ``X`` below), computed for the
    kept directions only, with one Gram matrix held at a time. Cached in ``pb.cache`` up to 256 MB.
    """
    def compute():
        base, K_u = pb.base, pb.unique_index.shape[0]
        n, sq = base.n, np.sqrt(base.mass)
        step = max(1, int(block_bytes) // (8 * K_u))  # rows per block of solver columns
        if normalization == "columns":  # unit A-norm columns: the Gram's diagonal, by blocks
            g = sum(np.einsum("ij,ij->j", X, X) for X in (_solver_rows(pb, slice(i, min(n, i + step)), None)
                                                           for i in range(0, n, step)))
            d = 1.0 / np.sqrt(np.maximum(g, np.finfo(float).tiny))
        else:
            d = column_weights(pb, normalization)
        dd = np.ones(K_u) if d is None else d
        if rtol < 1e-6:  # the operator's SVD route: the Gram squares the condition number
            U, s, Vt = sla.svd(_solver_rows(pb, slice(0, n), d), full_matrices=False, lapack_driver="gesdd")
            r = int(np.sum(s > rtol * s[0]))
            U, s, V = U[:, :r], s[:r], Vt[:r].T
            VS = V * s
        elif K_u <= n:  # XᵀX (K_u x K_u), by blocks of rows
            G = _gram_upper((_solver_rows(pb, slice(i, min(n, i + step)), d) for i in range(0, n, step)), K_u, 1)
            w, V = _top_eigenpairs(G, rtol)
            del G
            s = np.sqrt(w)
            VS = V * s  # (K_u, r)
            U = pb.solver_matmul(dd[:, None] * V / s) * sq[:, None]  # (n, r) = X V Σ⁻¹
        else:  # XXᵀ (n x n) when the extended basis has more columns than the mesh has vertices
            cstep, sc = max(1, int(block_bytes) // (8 * n)), pb.solver_scale()

            def columns(j):  # X[:, j:j + cstep] (n, c)
                cols = slice(j, min(K_u, j + cstep))
                # evaluate_products makes its first column the constant φ0: lead with a product to drop
                Xc = evaluate_products(base.vecs, np.vstack([pb.unique_index[1:2], pb.unique_index[cols]]))[:, 1:]
                if j == 0:
                    Xc[:, 0] = base.vecs[:, 0]  # the constant column
                return Xc * ((1.0 if sc is None else sc[cols]) * dd[cols]) * sq[:, None]

            G = _separable_gram(pb, normalization, sq)
            full = G is not None
            if not full:
                G = _gram_upper((columns(j) for j in range(0, K_u, cstep)), n, 0)
            w, U = _top_eigenpairs(G, rtol, full=full)
            del G
            s = np.sqrt(w)
            VS = pb.solver_rmatmul(sq[:, None] * U) * dd[:, None]  # (K_u, r) = Xᵀ U = V Σ
        APsi = U * sq[:, None]  # (n, r) A Ψ = sqrt(A) U
        X = dd[:, None] * VS / (s * s)  # (K_u, r) = D V Σ⁻¹
        sV = VS.T / dd  # (r, K_u) = Σ Vᵀ D⁻¹
        return APsi, X, sV

    key = ("p2p_canonical_frame", float(rtol), normalization, int(block_bytes))
    if key in pb.cache:
        return pb.cache.get(key, compute)
    frame = compute()
    if sum(a.nbytes for a in frame) <= _SOURCE_COEF_CACHE_BYTES:  # else (a tiny rtol on a big basis) recomputed
        pb.cache.put(key, frame)
    return frame


def _extended_image(C: np.ndarray, phi0_2: float, Y: np.ndarray, index_1: np.ndarray, index_2: np.ndarray):
    """``C~ Y`` ``(K2_u, m)`` for unique-pair coefficients ``Y`` ``(K1_u, m)``, order 2, without forming ``C~``.

    Lemma 2 written per column: with ``T φ_l = a_l + Σ_i b_il ψ_i`` (``a = φ0_2 C[0, 1:]``, ``b = C[1:, 1:]``)
    and the products' coefficients as a symmetric ``Q`` (``y_lm / 2`` off the diagonal), the image of
    ``Σ Q_lm φ_l φ_m`` is ``aᵀQa + 2 (bQa)·ψ + ψᵀ (bQbᵀ) ψ``: ``2 m k³`` multiply-adds and ``m k²`` values
    instead of the ``K2 × K1`` matrix (:func:`prodmaps.extend_fmap`, equal to rounding).
    """
    k2, k1 = C.shape[0] - 1, C.shape[1] - 1
    m = Y.shape[1]
    a, b = phi0_2 * C[0, 1:], C[1:, 1:]  # (k1,), (k2, k1)
    y0, ylin = Y[0], Y[1 : k1 + 1]  # (m,), (k1, m)
    l, q = index_1[k1 + 1 :, 0] - 1, index_1[k1 + 1 :, 1] - 1  # 0-based factors of the product columns
    Q = np.zeros((m, k1, k1))
    Yq = Y[k1 + 1 :].T  # (m, K1_q)
    Q[:, l, q] = np.where(l == q, 1.0, 0.5) * Yq
    Q[:, q, l] += np.where(l == q, 0.0, 0.5) * Yq
    Qa = Q @ a  # (m, k1)
    out = np.empty((index_2.shape[0], m))
    out[0] = y0 * C[0, 0] + (a @ ylin + Qa @ a) / phi0_2  # the function 1 is the constant column over φ0
    out[1 : k2 + 1] = np.outer(C[1:, 0], y0) + b @ ylin + 2.0 * (b @ Qa.T)
    P = (b @ Q) @ b.T  # (m, k2, k2) symmetric
    i, j = index_2[k2 + 1 :, 0] - 1, index_2[k2 + 1 :, 1] - 1
    out[k2 + 1 :] = (P[:, i, j] * np.where(i == j, 1.0, 2.0)).T
    return out


def _source_embedding(b1: Basis, basis_1: Basis, APsi1, key, *, point, t, n_eig, block_bytes, dtype,
                      bar) -> np.ndarray:
    """Canonical coefficients ``(n1, r1)`` of every source point's function in its own extended basis.

    ``Ψ1ᵀ A1 f``, blocked; kept in the source basis' cache (up to 256 MB): they do not depend on the map.
    """
    def compute():
        APsi = APsi1.astype(dtype, copy=False)  # (n1, r1)
        out = np.empty((b1.n, APsi.shape[1]))
        for rows in _blocks(b1.n, b1.n, block_bytes):
            pts = np.arange(rows.start, rows.stop)
            out[rows] = point_functions(basis_1, pts, point=point, t=t, n_eig=n_eig, dtype=dtype).T @ APsi  # (b, r1)
            bar.update()
        return out

    if b1.n * APsi1.shape[1] * 8 > _SOURCE_COEF_CACHE_BYTES:
        return compute()
    if key in basis_1.cache:
        bar.update(len(range(0, b1.n, _block_step(b1.n, block_bytes))))
    return basis_1.cache.get(key, compute)


def _block_step(n_rows: int, block_bytes: int) -> int:
    return max(1, int(block_bytes) // (8 * max(1, n_rows)))


def _n_blocks(n_points: int, n_rows: int, block_bytes: int) -> int:
    return len(range(0, n_points, _block_step(n_rows, block_bytes)))


def extended_embeddings(C_12, basis_1: Basis, basis_2: Basis, *, point: str = "heat", t=None, t_scale: float = 1.0,
                        n_eig=None, rtol: float = 1e-3, normalization: str | None = None, pairs: str = "unique",
                        vertices=None, block_bytes: int = KERNEL_BLOCK_BYTES, dtype: str = "float32",
                        progress: bool | None = None):
    """Canonical coefficients used by the extended conversion (module doc).

    Parameters
    ----------
    C_12, basis_1, basis_2, point, t, t_scale, n_eig, rtol, normalization, pairs, block_bytes, dtype, progress
        As in :func:`from_fmap`. ``C_12`` uses the first ``k1``/``k2`` columns of the bases for the
        products; the heat kernel uses up to ``n_eig`` columns of the bases as given.
    vertices : (m,) array_like of int, optional
        Shape-2 vertices whose embedding is wanted (default: all).

    Returns
    -------
    emb_1 : (n1, r) ndarray
        The transferred functions of the vertices of shape 1 as canonical coefficients of shape 2's
        extended basis (``r`` retained singular values, divided by ``sqrt(area_2)``; the closed form
        keeps its historical scale).
    emb_2 : (n2, r) or (m, r) ndarray
        The functions of the vertices of shape 2, in the same coordinates.
    info : dict
        The parameters used (``point``, ``t``, ``n_eig``, ``rtol``, ``pairs``, ``normalization``, ``dim``).

    Raises
    ------
    ValueError
        As :func:`from_fmap`.

    Examples
    --------
    >>> import numpy as np
    >>> import prodmaps as pm
    >>> from prodmaps.mesh import ellipsoid
    >>> b = pm.eigenbasis(ellipsoid(2), 40)
    >>> e1, e2, info = extended_embeddings(np.eye(12, 10), b, b)
    >>> e1.shape == e2.shape == (b.n, info["dim"]), info["n_eig"]
    (True, 40)
    """
    emb_1, emb_2, info, bar = _extended_embeddings(
        C_12, basis_1, basis_2, point=point, t=t, t_scale=t_scale, n_eig=n_eig, rtol=rtol, normalization=normalization,
        pairs=pairs, vertices=vertices, block_bytes=block_bytes, dtype=dtype, progress=progress, extra_steps=0)
    bar.close()
    return emb_1, emb_2, info


def _extended_embeddings(C_12, basis_1: Basis, basis_2: Basis, *, point, t, t_scale, n_eig, rtol, normalization, pairs,
                         vertices, block_bytes, dtype, progress, extra_steps: int):
    """:func:`extended_embeddings` and its progress bar (with ``extra_steps`` left for the caller)."""
    if point not in POINTS:
        raise ValueError(f"point must be one of {POINTS}, got {point!r}")
    C = check_fmap(C_12, basis_1, basis_2, allow_truncation=True)
    k2, k1 = C.shape
    b1, b2 = basis_1.truncate(k1), basis_2.truncate(k2)
    if point == "closed_form":
        norm = {} if normalization is None else {"normalization": normalization}
        return (*_closed_form_embeddings(C, b1, b2, t=t, t_scale=t_scale, n_eig=n_eig, rtol=rtol, normalization=norm,
                                         pairs=pairs, vertices=vertices), NullBar())
    for i, b in ((1, basis_1), (2, basis_2)):
        if not b.mass_is_diagonal:
            raise ValueError(f"point={point!r} needs lumped (diagonal) masses, basis_{i} has a full mass matrix: "
                             "build the bases with mass='lumped' (the default), or use method='std' or "
                             "point='closed_form'")
    n_max = min(basis_1.k, basis_2.k)
    n_eig = min(DEFAULT_KERNEL_EIG, n_max) if n_eig is None else int(n_eig)
    if not 2 <= n_eig <= n_max:
        raise ValueError(f"n_eig must be in [2, {n_max}] (columns of both bases as given), got {n_eig}")
    if point == "heat" and n_eig <= max(k1, k2):
        warnings.warn(f"the squared heat kernel from {n_eig} eigenpairs lies in the span of the products of the "
                      f"map's {k1}/{k2} basis functions: the conversion is then the closed form's, which cannot "
                      f"beat the standard one; pass bases with more eigenpairs ({DEFAULT_KERNEL_EIG} by default)",
                      stacklevel=4)
    if t is None:
        t = float(t_scale) / float(b1.evals[k1 - 1])
    if not (np.isfinite(t) and t >= 0):
        raise ValueError(f"t must be a finite number >= 0, got {t}")
    if np.dtype(dtype) not in (np.float32, np.float64):
        raise ValueError(f"dtype must be 'float32' or 'float64', got {dtype!r}")
    if int(block_bytes) < 1:
        raise ValueError(f"block_bytes must be >= 1, got {block_bytes}")
    if isinstance(rtol, (str, bytes)) or not 0 <= rtol < 1:
        raise ValueError(f"rtol must be a number in [0, 1), got {rtol!r}")
    normalization = DEFAULT_NORMALIZATION if normalization is None else normalization
    column_weights(b1, normalization)  # an unknown normalisation fails here, before any work
    ratio = b2.area / b1.area  # shape 2 uses the same time relative to its area: t · a2 / a1
    pb1, pb2 = product_basis(b1, order=2, pairs=pairs), product_basis(b2, order=2, pairs=pairs)
    targets = np.arange(b2.n) if vertices is None else np.asarray(vertices, dtype=np.int64)
    K1, K2 = pb1.unique_index.shape[0], pb2.unique_index.shape[0]
    work = (min(K1, b1.n) ** 2 * (b1.n + min(K1, b1.n)) + min(K2, b2.n) ** 2 * (b2.n + min(K2, b2.n))
            + b1.n * b1.n * n_eig + targets.size * b2.n * n_eig)  # Grams and decompositions, point functions
    n_steps = 2 + _n_blocks(b1.n, b1.n, block_bytes) + _n_blocks(targets.size, b2.n, block_bytes) + extra_steps
    bar = progress_bar(n_steps, "point map (extended)", progress=progress, work=work, min_work=PROGRESS_MIN_WORK,
                       unit="step")
    try:
        APsi1, X1, _ = _canonical_frame(pb1, rtol, normalization, block_bytes)  # (n1, r1), (K1_u, r1)
        bar.update()
        APsi2, _, sV2 = _canonical_frame(pb2, rtol, normalization, block_bytes)  # (n2, r2), (r2, K2_u)
        bar.update()
        # a source function's fit is E1 X1 ã1 (ã1 its canonical coefficients on shape 1); its image's canonical
        # coefficients on shape 2 are Σ2 V2ᵀ D2⁻¹ E2ᵀ C~ E1 X1 ã1 (E: solver -> basis coefficients, I for unique)
        Y = pb1.expand() @ X1  # (K1, r1) in the basis' own columns
        if pairs == "ordered":  # C~ between ordered bases spreads the unique image over the orderings
            spread = pb2.fold().T @ sp.diags(1.0 / n_orderings(pb2.unique_index))  # (K2, K2_u)
            Y = spread @ _extended_image(C, b2.phi0, pb1.fold() @ Y, pb1.unique_index, pb2.unique_index)
        else:
            Y = _extended_image(C, b2.phi0, Y, pb1.unique_index, pb2.unique_index)  # (K2, r1) = C~ Y
        scale = 1.0 / np.sqrt(b2.area)  # ‖f‖ on the unit-area target
        R = (sV2 @ (pb2.expand().T @ Y)) * scale  # (r2, r1)
        key = ("p2p_source_canonical", b1.k, point, float(t), int(n_eig), float(rtol), normalization, pairs,
               int(block_bytes), np.dtype(dtype).str)
        e1 = _source_embedding(b1, basis_1, APsi1, key, point=point, t=t, n_eig=n_eig, block_bytes=block_bytes,
                               dtype=dtype, bar=bar)
        emb_1 = e1 @ R.T  # (n1, r2)
        APsi2 = APsi2.astype(dtype, copy=False)
        emb_2 = np.empty((targets.shape[0], APsi2.shape[1]))  # (n2 or m, r2)
        for rows in _blocks(targets.shape[0], b2.n, block_bytes):
            F = point_functions(basis_2, targets[rows], point=point, t=t * ratio, n_eig=n_eig, dtype=dtype)  # (n2, b)
            emb_2[rows] = F.T @ APsi2
            bar.update()
        emb_2 *= scale
    except BaseException:
        bar.close()
        raise
    info = {"point": point, "t": t, "n_eig": n_eig, "rtol": rtol, "pairs": pairs, "normalization": normalization,
            "dim": emb_1.shape[1]}
    return emb_1, emb_2, info, bar


def from_fmap(C_12, basis_1: Basis, basis_2: Basis, method: str = "std", *, convention: str = "area",
              block: int | None = None, vertices=None, search: str = "auto", progress: bool | None = None,
              **params) -> np.ndarray:
    """Point map ``p2p_21`` ``(n2,)`` (for each vertex of shape 2 a vertex of shape 1) from ``C_12`` ``(k2, k1)``.

    Parameters
    ----------
    C_12 : (k2, k1) array_like
        Functional map; uses the first ``k1`` columns of ``basis_1`` and the first ``k2`` of ``basis_2``.
    basis_1, basis_2 : Basis
        The shapes' bases. For ``"extended"`` pass the shapes' big bases (200 eigenpairs,
        ``DEFAULT_KERNEL_EIG``): the heat kernel that represents a point is built from all their
        columns (up to ``n_eig``), the products from the map's ``k1``/``k2``.
    method : ``"std"`` (default) or ``"extended"``
        ``"std"``: nearest neighbours between ``Φ2`` and the transferred deltas ``s·Φ1 C_12ᵀ``
        [OBCS*12]; ``"extended"``: Sections 4.4/5.3, points as functions on the mesh fitted in the
        extended basis by Approach B, transferred by ``C̃``, compared through canonical
        coefficients (module doc).
    convention : ``"area"`` (default) or ``"pyfm"``
        The standard conversion's scale ``s`` of the transferred deltas. ``"area"``: ``s = area_1 /
        area_2``, the comparison as on unit-area shapes: exact for a ground-truth ``C_12`` whatever the
        areas, and the map does not change when a mesh is scaled. ``"pyfm"``: ``s = 1``, exactly
        pyFM's ``FM_to_p2p`` / ``FunctionalMapping.get_p2p`` for the same bases and map (ties
        aside); wrong by the area ratio on shapes of unequal area (measured in
        ``docs/guide/coming_from.md``). Equal areas: the same map. ``"extended"`` is unit-free and
        takes only ``"area"``.
    block : int, optional
        Query rows per block of the exact nearest-neighbour search.
    vertices : (m,) array_like of int, optional
        Shape-2 vertices to map (default: all). The answer is then ``(m,)``, equal to
        ``from_fmap(...)[vertices]`` (the search is exact per query), at ``m/n2`` of the search's cost.
    search : ``"auto"`` (default), ``"exact"`` or ``"approximate"``
        The nearest-neighbour search (:func:`prodmaps.neighbors.nearest_neighbors`): ``"auto"`` is exact
        up to ``APPROX_MIN_PAIRS`` = 1e11 query-point pairs (every mesh of the paper, any pair up to
        ~300k vertices each) and approximate above when faiss is installed; ``"approximate"`` without
        faiss raises ``ImportError``; ``"exact"`` is always exact (hours at a million vertices).
    progress : bool, optional
        A progress bar on stderr: ``None`` (default) for long extended conversions on a terminal,
        ``True`` always, ``False`` never (:func:`prodmaps.progress.progress_bar`).
    **params
        For ``"extended"``: ``point`` (``"heat"`` default, ``"delta"``, ``"closed_form"``), ``t``
        (heat time in shape 1's units; default ``t_scale / λ_{k1−1}``, closed form
        ``t_scale / λ_{n_eig−1}``), ``t_scale`` (1.0), ``n_eig`` (eigenpairs in the kernel, constant
        included; default ``min(200, basis_1.k, basis_2.k)``, closed form ``min(k1, k2)``), ``rtol``
        (Approach B truncation, 1e-3), ``normalization`` (of Approach B, :mod:`prodmaps.approx`;
        default the library's ``"euclidean"``), ``pairs`` (``"unique"`` or ``"ordered"``),
        ``block_bytes`` (a block of point functions, 64 MB) and ``dtype`` (``"float32"``, default, or
        ``"float64"``: the precision of the large products).

    Returns
    -------
    (n2,) or (m,) int64 ndarray
        For each (given) vertex of shape 2 its vertex of shape 1.

    Raises
    ------
    ValueError
        For an unknown ``method``, ``convention``, ``search`` or ``point``, a map that does not fit the
        bases, out-of-range ``vertices``, a full mass matrix with a mesh ``point``, or parameters out of
        range.
    TypeError
        For parameters the method does not take, or a basis that is not a :class:`prodmaps.Basis`.
    ImportError
        For ``search="approximate"`` without faiss.

    Examples
    --------
    >>> import numpy as np
    >>> import prodmaps as pm
    >>> from prodmaps.mesh import ellipsoid
    >>> b = pm.eigenbasis(ellipsoid(2), 40)
    >>> C = pm.fmap_from_p2p(np.arange(b.n), b.truncate(10), b.truncate(12))  # (12, 10) identity map
    >>> bool(np.all(from_fmap(C, b, b) == np.arange(b.n)))
    True
    >>> bool(np.all(from_fmap(C, b, b, "extended") == np.arange(b.n)))
    True
    >>> big = b.scaled(0.5)  # shape 2: the same mesh at half the size (a quarter of the area)
    >>> C_half = pm.fmap_from_p2p(np.arange(b.n), b.truncate(10), big.truncate(12))
    >>> float(np.mean(from_fmap(C_half, b, big) == np.arange(b.n)))  # the area rule: exact
    1.0
    >>> float(np.mean(from_fmap(C_half, b, big, convention="pyfm") == np.arange(b.n))) < 1.0
    True
    """
    if method not in METHODS:
        raise ValueError(f"method must be one of {METHODS}, got {method!r} (the closed form is "
                         "method='extended', point='closed_form')")
    if convention not in CONVENTIONS:
        raise ValueError(f"convention must be one of {CONVENTIONS}, got {convention!r}")
    if search not in SEARCHES:
        raise ValueError(f"search must be one of {SEARCHES}, got {search!r}")
    C = check_fmap(C_12, basis_1, basis_2, allow_truncation=True)
    k2, k1 = C.shape
    if vertices is not None:
        if np.ndim(vertices) != 1:
            raise ValueError(f"vertices must be a 1D array of shape-2 vertices, got shape {np.shape(vertices)}")
        vertices = check_vertex_indices(vertices, basis_2.n, "vertices")
    if method == "std":
        if params:
            raise TypeError(f"method='std' takes no extra parameters, got {sorted(params)}")
        # "area": compared as on unit-area shapes (so the answer depends neither on units nor on the area
        # ratio): sqrt(a2) Φ2 against the unit-area map's images a1 / sqrt(a2) Φ1 Cᵀ, i.e. Φ2 against
        # (a1/a2) Φ1 Cᵀ; "pyfm": Φ2 against Φ1 Cᵀ as pyFM's FM_to_p2p
        scale = basis_1.area / basis_2.area if convention == "area" else 1.0
        emb_1 = basis_1.vecs[:, :k1] @ C.T  # (n1, k2) images of the source deltas
        if scale != 1.0:
            emb_1 *= scale
        emb_2 = basis_2.vecs[:, :k2] if vertices is None else basis_2.vecs[vertices, :k2]  # (n2 or m, k2)
    else:
        if convention != "area":
            raise ValueError(f"convention={convention!r} is the standard conversion's; method='extended' is free "
                             "of units and areas (leave convention at 'area')")
        allowed = {"point", "t", "t_scale", "n_eig", "rtol", "pairs", "normalization", "block_bytes", "dtype"}
        bad = set(params) - allowed
        if bad:
            raise TypeError(f"unknown parameters for method={method!r}: {sorted(bad)}; allowed: {sorted(allowed)}")
        kw = {"point": "heat", "t": None, "t_scale": 1.0, "n_eig": None, "rtol": 1e-3, "normalization": None,
              "pairs": "unique", "block_bytes": KERNEL_BLOCK_BYTES, "dtype": "float32"} | params
        emb_1, emb_2, _, bar = _extended_embeddings(C, basis_1, basis_2, vertices=vertices, progress=progress,
                                                    extra_steps=1, **kw)  # (n1, r), (m, r)
        with bar:
            p2p_21 = nearest_neighbors(emb_2, emb_1, block=block, search=search)
            bar.update()
        return p2p_21
    return nearest_neighbors(emb_2, emb_1, block=block, search=search)
