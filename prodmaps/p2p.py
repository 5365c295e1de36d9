"""Point-map recovery from a functional map: standard [OBCS*12] and extended (paper Sections 4.4, 5.3).

Conventions
-----------
* ``C_12`` ``(k2, k1)`` maps coefficients on shape 1 to shape 2 (``T f ≈ Φ2 C_12 Φ1ᵀ A1 f``);
  bases are A-orthonormal with the constant in column 0; ``k`` counts all columns.
* The result ``p2p_21`` ``(n2,)`` gives for every vertex ``y`` of shape 2 a vertex of shape 1
  (pull-back direction), the convention of :func:`prodmaps.fmap_from_p2p`.

Standard conversion (``method="std"``)
    The delta function at ``x`` on shape 1 has coefficients ``Φ1[x]`` (times ``A1[x]``, a
    per-point scale dropped as in [OBCS*12]); its image has coefficients ``C_12 Φ1[x]ᵀ``.
    Each vertex ``y`` of shape 2 (coefficients ``Φ2[y]``) is matched to the ``x`` whose image
    is nearest: rows of ``Φ2[:, :k2]`` ``(n2, k2)`` against rows of ``Φ1[:, :k1] C_12ᵀ``
    ``(n1, k2)``.

Extended conversion (``method="extended"``)
    Each point ``x`` is represented by the squared heat kernel ``h_t(x, ·)²`` built from the
    first ``n_eig`` eigenpairs, ``h_t(x, ·) = Σ_{i<n_eig} e^{−λ_i t} φ_i(x) φ_i``. Its
    coefficients in the order-2 extended basis ``[φ0, φ1..φk, φl φm]`` are closed form: with
    ``a_i = e^{−λ_i t} φ_i(x)`` and the constant value ``c = φ0``::

        h² = a_0² c·φ0 + Σ_{j≥1} 2 a_0 c a_j·φ_j + Σ_{l,m≥1} a_l a_m·φ_l φ_m

    (``φ0² = c φ0`` and ``φ0 φ_j = c φ_j`` because products never involve the constant). With
    ``pairs="ordered"`` the product column ``(l, m)`` gets ``a_l a_m``; with ``"unique"``
    (``l ≤ m``) it gets ``a_l²`` or ``2 a_l a_m``. The source points' coefficients
    ``(n1, K1)`` are transferred with the extended map ``C̃ = pm.extend_fmap(C_12)`` ``(K2, K1)``
    and turned into canonical coefficients of the target's extended basis
    (``ã = Σ Vᵀ a`` from the SVD ``sqrt(A2) B2 = U Σ Vᵀ`` truncated at ``rtol``, Section 4.4),
    so that Euclidean distances between canonical coefficients are area-L2 distances between
    the functions. The target points' own squared kernels get their canonical coefficients
    the same way, and each target vertex is matched to its exact nearest transferred source
    point. Parameters the paper leaves open: ``t`` (default ``t_scale / λ_max`` with
    ``λ_max`` the largest kernel eigenvalue on shape 1 and ``t_scale = 1``; the same absolute
    ``t`` is used on both shapes), ``n_eig`` (default ``min(k1, k2)``), ``rtol`` (1e-3),
    ``pairs`` (default ``"unique"``: same span and the same canonical coefficients as
    ``"ordered"``, fewer columns).

Nearest neighbours are exact with ties to the smallest index (:func:`nearest_neighbors`): a
kd-tree in low dimensions, blocked float32 matrix products with an exact float64 recheck of every
near tie in high ones (the extended embedding has up to ~2.5k dimensions).
"""

from __future__ import annotations

import time

import numpy as np

from .basis import Basis
from .mesh import check_vertex_indices

__all__ = ["nearest_neighbors", "effective_dimension", "from_fmap", "heat_square_coefficients", "extended_embeddings"]

METHODS = ("std", "extended")


_U64 = np.finfo(np.float64).eps / 2
_U32 = float(np.finfo(np.float32).eps) / 2
KDTREE_MAX_DIM = 32  # auto: kd-tree up to this dimension (or when a brute-force pass would be too large)
GEMM_MAX_PAIRS = 4e10  # auto: above n_q * n_p pairs the brute force is not attempted (kd-tree instead)
PRUNE_MIN_DIM = 128  # gemm: products on at least this many leading coordinates ...
PRUNE_SHARE = 0.995  # ... and on as many as hold this share of the points' spread
KDTREE_MAX_EFFECTIVE_DIM = 24  # auto: kd-tree above KDTREE_MAX_DIM when the points' effective dimension is this low
NN_METHODS = ("auto", "kdtree", "gemm")
PROBE_MIN_DIM = 8  # auto: a kd-tree pick above this dimension is checked against the products ...
PROBE_QUERIES = 256  # ... on this many queries each, when there are at least 4x as many (_nn_probe)
_clock = time.perf_counter  # the probe's clock (a test replaces it)


def effective_dimension(P: np.ndarray) -> float:
    """Participation ratio ``(Σ σ_i²)² / Σ σ_i⁴`` of the per-coordinate variances ``σ_i²`` of the
    points ``(n, d)``: ``d`` for isotropic data, about the number of coordinates that carry the
    spread otherwise (the extended embeddings: ~18 of 150; spectral embeddings of k
    eigenfunctions: ~0.8 k). A kd-tree's cost grows with it, not with ``d``."""
    v = np.asarray(P, dtype=np.float64).var(axis=0)
    den = float(np.sum(v * v))
    return float(v.sum() ** 2 / den) if den > 0 else 0.0


def _exact_pick(Q, P, rows, cols, n_rows):
    """Among candidate pairs ``(rows, cols)`` the exact nearest per row (ties: smallest index).

    Distances are recomputed directly as ``Σ (q − p)²`` in float64 (in chunks of pairs); every
    row in ``range(n_rows)`` must have at least one candidate. Returns ``idx (n_rows,)``.
    """
    d2 = np.empty(rows.shape[0])
    step = max(1, 2_000_000 // max(1, Q.shape[1]))
    for s in range(0, rows.shape[0], step):  # chunks of candidate pairs, vectorised inside
        diff = Q[rows[s : s + step]] - P[cols[s : s + step]]
        d2[s : s + step] = np.einsum("ij,ij->i", diff, diff)
    order = np.lexsort((cols, d2, rows))  # by row, then distance, then index
    r, first = np.unique(rows[order], return_index=True)
    if r.shape[0] != n_rows:
        raise AssertionError("internal error: a row without candidates")
    return cols[order[first]]


def _nn_gemm(Q, P, block):
    """Exact nearest neighbours by blocked float32 products on the leading coordinates, then an
    exact float64 recheck of every candidate (see :func:`nearest_neighbors`)."""
    d = Q.shape[1]
    # coordinates by decreasing spread of the points (a permutation: distances unchanged); the first
    # r of them give lower bounds ‖q_r − p_r‖² ≤ ‖q − p‖²
    spread = P.var(axis=0)
    order = np.argsort(-spread, kind="stable")
    share = np.cumsum(spread[order]) / max(spread.sum(), np.finfo(float).tiny)
    r = d if d <= PRUNE_MIN_DIM else int(min(d, max(PRUNE_MIN_DIM, np.searchsorted(share, PRUNE_SHARE) + 1)))
    lead = order[:r]
    Qr, Pr = np.ascontiguousarray(Q[:, lead]), np.ascontiguousarray(P[:, lead])
    u = _U32
    gamma = 2.0 * (r + 8) * u  # |G − D'_r| ≤ γ (‖q_r‖² + 2‖p_r‖²) for the float32 product G
    pr_sq = np.einsum("ij,ij->i", Pr, Pr)
    qr_sq = np.einsum("ij,ij->i", Qr, Qr)
    Pa = np.empty((P.shape[0], r + 1), dtype=np.float32)  # (n_p, r + 1): [−2p_r, (1 − 2γ)‖p_r‖²]
    Pa[:, :r] = -2.0 * Pr
    Pa[:, r] = (1.0 - 2.0 * gamma) * pr_sq
    idx = np.empty(Q.shape[0], dtype=np.int64)
    Qa = np.empty((min(block, Q.shape[0]), r + 1), dtype=np.float32)
    slack = 1.0 + 4.0 * (d + 8) * _U64  # rounding of the float64 distances that define the answer
    for s in range(0, Q.shape[0], block):  # blocks of queries, vectorised inside
        b = min(block, Q.shape[0] - s)
        Qa[:b, :r] = Qr[s : s + b]
        Qa[:b, r] = 1.0
        low = Qa[:b] @ Pa.T  # (b, n_p): L ≤ ‖q_r − p_r‖² − ‖q_r‖² ≤ ‖q − p‖² − ‖q_r‖²
        j0 = np.argmin(low, axis=1)
        diff = Q[s : s + b] - P[j0]
        upper = np.einsum("ij,ij->i", diff, diff) * slack  # exact distance to one point, rounded up
        thr = upper - qr_sq[s : s + b] + gamma * qr_sq[s : s + b]
        thr = np.nextafter(thr.astype(np.float32), np.float32(np.inf))  # rounded up
        at = np.arange(b)
        first = low[at, j0].copy()
        low[at, j0] = np.inf
        amb = np.flatnonzero(low.min(axis=1) <= thr)  # a second candidate: recheck exactly
        idx[s : s + b] = j0
        if amb.size:
            low[amb, j0[amb]] = first[amb]
            rows, cols = np.nonzero(low[amb] <= thr[amb, None])
            idx[s + amb] = _exact_pick(Q[s + amb], P, rows, cols, amb.size)
    return idx


def _nn_kdtree(Q, P, block, tree=None):
    from scipy.spatial import cKDTree

    tree = cKDTree(P) if tree is None else tree
    if P.shape[0] == 1:
        return np.zeros(Q.shape[0], dtype=np.int64)
    dist, nn = tree.query(Q, k=2, workers=-1)  # (n_q, 2) the two nearest
    idx = nn[:, 0].astype(np.int64)
    d = Q.shape[1]
    # the kd-tree's distances carry a relative rounding of about (d + 3) u: the first neighbour is
    # the exact answer unless the second one is as close up to four times that
    amb = np.flatnonzero(dist[:, 1] ** 2 <= dist[:, 0] ** 2 * (1.0 + 4.0 * (d + 8) * _U64))
    if amb.size:
        idx[amb] = _nn_gemm(Q[amb], P, block)
    return idx


def _nn_probe(Q, P, block):
    """``"auto"`` between the kd-tree and the products when neither clearly wins: the first
    ``PROBE_QUERIES`` queries by the kd-tree, the next as many by the products, both timed, and
    the rest by the one that was faster per query. A kd-tree's cost depends on how far the
    queries lie from the points, not only on the dimension (measured on 5k vertices, one
    thread, 40 dimensions: 0.03 s for queries near the points, 0.2-0.3 s for the spectral
    embeddings of ICP's first iterations, where the products take 0.04 s). Every query gets the
    exact answer either way, so the choice never changes the result."""
    from scipy.spatial import cKDTree

    s = PROBE_QUERIES
    idx = np.empty(Q.shape[0], dtype=np.int64)
    tree = cKDTree(P)
    t1 = _clock()
    idx[:s] = _nn_kdtree(Q[:s], P, block, tree)
    t2 = _clock()
    idx[s:2 * s] = _nn_gemm(Q[s:2 * s], P, block)
    t3 = _clock()
    rest = Q.shape[0] - 2 * s
    kd = (t2 - t1) * rest / s  # per-query cost times the rest (the tree is built already)
    mm = (t3 - t2) * rest / s
    idx[2 * s:] = _nn_kdtree(Q[2 * s:], P, block, tree) if kd <= mm else _nn_gemm(Q[2 * s:], P, block)
    return idx


def nearest_neighbors(queries: np.ndarray, points: np.ndarray, block: int | None = None,
                      return_distance: bool = False, method: str = "auto"):
    """Exact Euclidean nearest neighbour in ``points`` ``(n_p, d)`` of every row of ``queries`` ``(n_q, d)``.

    The answer is the index minimising the squared distance ``Σ_i (q_i − p_i)²`` computed in
    float64; **ties go to the smallest index**. It does not depend on ``method`` or ``block``:

    * ``"gemm"``: blocked brute force (``block`` query rows at a time, default about 4·10⁶
      distances per block, and at least 64 rows while a block stays under 2.5·10⁸ distances: with a
      million points a block of 3 rows would stream all of them for every 3 queries, 3.2x slower)
      by one float32 matrix product of ``[q, 1]`` and ``[−2p, ‖p‖²]``;
      every point within the rounding bound of a row's minimum is a candidate, and rows with
      several candidates are decided by the exact float64 distances of their candidates.
    * ``"kdtree"``: ``scipy.spatial.cKDTree`` (both cores), the two nearest per query; a query
      whose second neighbour is as close as the first up to rounding is decided by ``"gemm"``.
    * ``"auto"`` (default): ``"kdtree"`` in up to ``KDTREE_MAX_DIM`` dimensions, above when the
      points' :func:`effective_dimension` is at most ``KDTREE_MAX_EFFECTIVE_DIM`` (measured:
      the extended embedding at 29/39, 150 coordinates of effective dimension 18, 0.19 s by
      kd-tree against 0.28 s by products) or when the brute force would compare more than
      ``GEMM_MAX_PAIRS`` pairs; ``"gemm"`` otherwise. A kd-tree pick above ``PROBE_MIN_DIM``
      dimensions with at least ``4 * PROBE_QUERIES`` queries is checked: both methods answer
      ``PROBE_QUERIES`` queries, timed, and the faster one answers the rest (a kd-tree's cost
      depends on how far the queries lie from the points).

    Returns ``idx (n_q,)`` int64 (and the Euclidean distances ``(n_q,)`` if ``return_distance``).
    """
    Q = np.ascontiguousarray(queries, dtype=np.float64)
    P = np.ascontiguousarray(points, dtype=np.float64)
    if Q.ndim != 2 or P.ndim != 2:
        raise ValueError(f"queries and points must be 2D arrays (n, d); got {Q.shape} and {P.shape}")
    if Q.shape[1] != P.shape[1]:
        raise ValueError(f"queries have dimension {Q.shape[1]} but points have {P.shape[1]}; they must match")
    if P.shape[0] == 0:
        raise ValueError("points is empty: nothing to match to")
    if method not in NN_METHODS:
        raise ValueError(f"method must be one of {NN_METHODS}, got {method!r}")
    if block is None:  # ~4e6 distances a block; at least 64 rows while a block holds <= 2.5e8 (1 GB)
        block = max(1, int(4_000_000 // P.shape[0]), min(64, int(250_000_000 // P.shape[0])))
    block = int(block)
    if block < 1:
        raise ValueError(f"block must be >= 1, got {block}")
    if method == "auto":
        big = float(Q.shape[0]) * float(P.shape[0]) > GEMM_MAX_PAIRS
        low = Q.shape[1] <= KDTREE_MAX_DIM or effective_dimension(P) <= KDTREE_MAX_EFFECTIVE_DIM
        method = "kdtree" if (low or big) else "gemm"
        if method == "kdtree" and not big and Q.shape[1] > PROBE_MIN_DIM and Q.shape[0] >= 4 * PROBE_QUERIES:
            method = "probe"
    if Q.shape[0] == 0:
        idx = np.zeros(0, dtype=np.int64)
    elif method == "probe":
        idx = _nn_probe(Q, P, block)
    else:
        idx = _nn_kdtree(Q, P, block) if method == "kdtree" else _nn_gemm(Q, P, block)
    if not return_distance:
        return idx
    diff = Q - P[idx]
    return idx, np.sqrt(np.einsum("ij,ij->i", diff, diff))


def _check_inputs(C_12, basis_1, basis_2) -> np.ndarray:
    from .mapping import check_fmap

    return check_fmap(C_12, basis_1, basis_2, allow_truncation=True)


def heat_square_coefficients(basis: Basis, t: float, n_eig: int, pairs: str = "unique", points=None) -> np.ndarray:
    """Closed-form coefficients ``(n_points, K)`` of ``h_t(x, ·)²`` in the order-2 extended basis of ``basis``.

    ``h_t(x, ·) = Σ_{i<n_eig} e^{−λ_i t} φ_i(x) φ_i`` (constant included in the count); one row per
    point ``x`` (all vertices, or ``points``). Column layout of
    ``prodmaps.product_basis(basis, order=2, pairs=pairs)`` (see module doc).
    """
    from .products import multi_indices

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
    """:func:`heat_square_coefficients` of all vertices, kept in ``basis.cache`` up to 256 MB: ``t``
    depends on the source basis only, so every map from the same source reuses them."""
    from .products import n_columns

    if basis.n * n_columns(basis.k - 1, 2, pairs) * 8 > _HEAT_SQUARES_CACHE_BYTES:
        return heat_square_coefficients(basis, t, n_eig, pairs)
    key = ("heat_square_coefficients", basis.k, float(t), int(n_eig), pairs)
    return basis.cache.get(key, lambda: heat_square_coefficients(basis, t, n_eig, pairs))


def extended_embeddings(
    C_12,
    basis_1: Basis,
    basis_2: Basis,
    *,
    t=None,
    t_scale: float = 1.0,
    n_eig=None,
    rtol: float = 1e-3,
    pairs: str = "unique",
    vertices=None,
):
    """Canonical coefficients used by the extended conversion.

    Returns ``(emb_1 (n1, r), emb_2 (n2, r), info)``: the transferred squared heat kernels of
    the vertices of shape 1 and the squared heat kernels of the vertices of shape 2, both as
    canonical coefficients of shape 2's extended basis (``r`` retained singular values), plus
    a dict of the parameters used. Arguments as in :func:`from_fmap`; ``vertices`` (optional
    ``(m,)`` shape-2 vertex indices) gives ``emb_2`` of those vertices only, ``(m, r)``.

    Cost: the map and the canonical projection are composed first, ``(Σ_r V_rᵀ C~) a1ᵀ``
    (``r × K1`` times ``K1 × n1``), not ``Σ_r V_rᵀ (C~ a1ᵀ)`` (``K2 × K1`` times ``K1 × n1``
    first): the same product, ``K2/r``-fold fewer operations on the vertices.
    """
    import prodmaps as pm

    C = _check_inputs(C_12, basis_1, basis_2)
    k2, k1 = C.shape
    b1, b2 = basis_1.truncate(k1), basis_2.truncate(k2)
    n_eig = min(k1, k2) if n_eig is None else int(n_eig)
    if not 2 <= n_eig <= min(k1, k2):
        raise ValueError(f"n_eig must be in [2, min(k1, k2) = {min(k1, k2)}], got {n_eig}")
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
    Ct = pm.extend_fmap(C, b1, b2, order=2, pairs=pairs)  # (K2, K1)
    op = pm.product_basis(b2, order=2, pairs=pairs).operator("svd", rtol=rtol)
    emb_1 = a1 @ (np.asarray(op.canonical(Ct)).T / ratio**2)  # (n1, K1) @ (K1, r)
    emb_2 = np.asarray(op.canonical(a2.T)).T  # (n2 or m, r)
    return emb_1, emb_2, {"t": t, "n_eig": n_eig, "rtol": rtol, "pairs": pairs, "dim": emb_1.shape[1]}


def from_fmap(
    C_12, basis_1: Basis, basis_2: Basis, method: str = "std", *, block: int | None = None, vertices=None,
    **params
) -> np.ndarray:
    """Point map ``p2p_21`` ``(n2,)`` (for each vertex of shape 2 a vertex of shape 1) from ``C_12`` ``(k2, k1)``.

    Parameters
    ----------
    C_12 : ``(k2, k1)`` functional map; uses the first ``k1`` columns of ``basis_1`` and the
        first ``k2`` of ``basis_2``.
    method : ``"std"`` (nearest neighbours between ``Φ2`` and ``Φ1 C_12ᵀ``, [OBCS*12]) or
        ``"extended"`` (squared heat kernels compared through canonical coefficients of the
        extended basis, Sections 4.4/5.3). See the module doc.
    block : query rows per block of the exact nearest-neighbour search.
    vertices : optional ``(m,)`` int array of shape-2 vertices to map (default: all). The answer
        is then ``(m,)``, equal to ``from_fmap(...)[vertices]`` (the search is exact per query), at
        ``m/n2`` of the search's cost: for evaluating a map on sampled vertices.
    **params : for ``"extended"``: ``t`` (heat time; default ``t_scale/λ_max``), ``t_scale``
        (1.0), ``n_eig`` (eigenpairs in the kernel, constant included; default ``min(k1, k2)``),
        ``rtol`` (SVD truncation, 1e-3), ``pairs`` (``"unique"`` or ``"ordered"``).
    """
    if method not in METHODS:
        raise ValueError(f"method must be one of {METHODS}, got {method!r}")
    C = _check_inputs(C_12, basis_1, basis_2)
    k2, k1 = C.shape
    if vertices is not None:
        if np.ndim(vertices) != 1:
            raise ValueError(f"vertices must be a 1D array of shape-2 vertices, got shape {np.shape(vertices)}")
        vertices = check_vertex_indices(vertices, basis_2.n, "vertices")
    if method == "std":
        if params:
            raise TypeError(f"method='std' takes no extra parameters, got {sorted(params)}")
        # compared as on unit-area shapes (so the answer does not depend on units or the area ratio):
        # sqrt(a2) Φ2 against the unit-area map's images a1 / sqrt(a2) Φ1 Cᵀ, i.e. Φ2 against (a1/a2) Φ1 Cᵀ
        emb_1 = (basis_1.area / basis_2.area) * (basis_1.vecs[:, :k1] @ C.T)  # (n1, k2) images of the source deltas
        emb_2 = basis_2.vecs[:, :k2] if vertices is None else basis_2.vecs[vertices, :k2]  # (n2 or m, k2)
    else:
        allowed = {"t", "t_scale", "n_eig", "rtol", "pairs"}
        bad = set(params) - allowed
        if bad:
            raise TypeError(f"unknown parameters for method='extended': {sorted(bad)}; allowed: {sorted(allowed)}")
        emb_1, emb_2, _ = extended_embeddings(C, basis_1, basis_2, vertices=vertices, **params)  # (n1, r), (m, r)
    return nearest_neighbors(emb_2, emb_1, block=block)
