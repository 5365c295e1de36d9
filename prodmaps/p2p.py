"""Point-map recovery from a functional map: standard [OBCS*12] and extended (paper Sections 4.4, 5.3).

Conventions (``C_12`` ``(k2, k1)``, bases, the result ``p2p_21`` ``(n2,)`` pulling back):
:mod:`prodmaps.conventions`.

Standard conversion (``method="std"``)
    The delta function at ``x`` on shape 1 has coefficients ``Φ1[x]`` (times ``A1[x]``, a
    per-point scale dropped as in [OBCS*12]); its image has coefficients ``C_12 Φ1[x]ᵀ``.
    Each vertex ``y`` of shape 2 (coefficients ``Φ2[y]``) is matched to the ``x`` whose image
    is nearest: rows of ``Φ2[:, :k2]`` ``(n2, k2)`` against rows of ``Φ1[:, :k1] C_12ᵀ``
    ``(n1, k2)``.

Extended conversion (``method="extended"``, Sections 4.4 and 5.3)
    Each point is a *function on the mesh*: by default (``point="heat"``) the squared heat
    kernel ``h_t(x, ·)²`` with ``h_t(x, ·) = Σ_{i<n_eig} e^{−λ_i t} φ_i(x) φ_i`` built from as
    many eigenpairs as the given basis holds, up to ``n_eig = DEFAULT_KERNEL_EIG = 200`` (the
    experiments store's basis size, and the paper's "hk K" kernels; at the default ``t`` the
    weight of eigenpair 200 is ``e^{−λ_199/λ_{k1−1}}`` ≈ 1e-3 for ``k1 = 30``, so more eigenpairs
    change the kernel by about that much); ``point="delta"`` is the paper's literal Dirac
    ``δ_x`` (Section 4.4). The function of every point is fitted in the order-2 extended basis
    of its shape by Approach B (one operator per shape, reused for all points; the library's
    default reading: ``rtol = 1e-3``, ``normalization="euclidean"``), a source point's
    coefficients ``a`` ``(K1,)`` are transferred by ``C̃ = pm.extend_fmap(C_12)`` ``(K2, K1)``,
    and every function on the target is compared through its canonical coefficients
    ``ã = Σ Vᵀ a`` (SVD ``sqrt(A2) B2 D = U Σ Vᵀ`` truncated at ``rtol``; ``‖f‖_A = ‖ã‖₂``,
    Section 4.4). Each target vertex is matched to its exact nearest transferred source point.

    ``t`` (the paper gives none): default ``t_scale / λ_{k1−1}``, the eigenvalue of the source's
    last basis function (``t_scale = 1``). Shape 2 uses the same time relative to its area.

    Cost and memory: the point functions are evaluated ``KERNEL_BLOCK_BYTES`` (64 MB) of
    ``(n, b)`` columns at a time and reduced to ``(K, b)`` coefficients at once, so no ``n × n``
    kernel matrix is ever held beyond that size; the work is ``n1·n1·(n_eig + K1) +
    m·n2·(n_eig + K2)`` multiply-adds (``m`` evaluated target vertices). The source points'
    coefficients do not depend on the map and are kept in the source basis' cache (up to 256
    MB), so maps from one source reuse them.

    Precision: the two large products (the kernels ``Φ W Φ[x]ᵀ`` and their canonical
    coefficients ``Ψᵀ A f``) run in float32 by default (``dtype``), faster than float64;
    the embeddings then agree with the float64 ones to ~1e-6 relative (distances to 1e-5 in the
    tests). ``dtype="float64"`` is the exact computation. Canonical coefficients come from
    ``Ψ = B_s D V_r Σ_r⁻¹`` ``(n, r)``, the A-orthonormal functions of the operator's retained
    directions (``ã = Ψᵀ A f``, the same numbers as ``Σ Vᵀ a`` of the fit ``a``, with ``r``
    instead of ``K`` products per point).

    Units: the functions are those of the mesh scaled to unit area (``area·h`` and ``area·δ``
    are free of units) and the canonical coefficients are divided by ``sqrt(area_2)``; with the
    unit-free ``"euclidean"`` truncation the map does not change when a mesh is scaled.

Closed form (``method="extended_closed_form"``)
    The squared heat kernel from ``n_eig ≤ min(k1, k2)`` eigenpairs has closed-form
    coefficients in the extended basis of the same eigenpairs: with ``a_i = e^{−λ_i t} φ_i(x)``
    and the constant value ``c = φ0``::

        h² = a_0² c·φ0 + Σ_{j≥1} 2 a_0 c a_j·φ_j + Σ_{l,m≥1} a_l a_m·φ_l φ_m

    (``pairs="ordered"``: column ``(l, m)`` gets ``a_l a_m``; ``"unique"``: ``a_l²`` or
    ``2 a_l a_m``), transferred by ``C̃`` and compared through canonical coefficients as above
    (defaults ``t = t_scale / λ_{n_eig−1}``, ``n_eig = min(k1, k2)``). **Why it cannot beat the
    standard conversion**: that kernel is ``Σ_{l,m} a_l(x) a_m(x) φ_l φ_m``, a fixed quadratic
    function of the point's spectral embedding ``(φ_i(x))_{i<k}``; its image through ``C̃`` is the
    same quadratic function of the transferred embedding. The products therefore carry no
    information about the point that the standard embedding lacks: the nearest neighbour is
    decided by the same ``k`` numbers, compared with a distorted metric (it loses to ``"std"`` on
    FAUST and the embedded humans, ``docs/benchmarks.md``). Kept to measure that.

Nearest neighbours are exact with ties to the smallest index (:func:`nearest_neighbors`): a
kd-tree in low dimensions, blocked float32 matrix products with an exact float64 recheck of every
near tie in high ones (the extended embedding has up to ~2.5k dimensions).

Search at scale (``search=`` of :func:`from_fmap` and :func:`nearest_neighbors`)
    ``"exact"`` is the search above. ``"approximate"`` is an inverted-file index (faiss
    ``IndexIVFFlat``, the optional dependency ``faiss-cpu``, ``pip install 'prodmaps[fast]'``):
    the points are clustered by k-means into about ``n_p / IVF_LIST_SIZE`` lists (trained on
    ``IVF_TRAIN_PER_LIST`` seeded points per list), each query scans the ``IVF_NPROBE`` lists
    of the nearest centroids in float32 for its ``IVF_CANDIDATES`` nearest, and these are
    re-ranked by their exact float64 distances (ties to the smallest index), so a query whose
    exact neighbour was scanned gets the exact answer. ``"auto"`` (the default of
    :func:`from_fmap`) is approximate when the search compares more than
    ``APPROX_MIN_PAIRS`` = 1e11 query-point pairs and faiss is installed, exact otherwise:
    every mesh of the paper (and any pair up to ~300k vertices each) keeps the exact path and
    its numbers (recall against the exact answer: ``benchmarks/scale_1m.py``).
"""

from __future__ import annotations

import time
import warnings

import numpy as np

from .approx import column_weights
from .basis import Basis
from .checks import check_fmap
from .mapping import extend_fmap
from .mesh import check_vertex_indices
from .products import multi_indices, n_columns, product_basis

__all__ = ["nearest_neighbors", "effective_dimension", "from_fmap", "heat_square_coefficients", "extended_embeddings",
           "point_functions", "METHODS", "POINTS", "DEFAULT_KERNEL_EIG", "SEARCHES", "have_faiss"]

METHODS = ("std", "extended", "extended_closed_form")
POINTS = ("heat", "delta", "closed_form")  # a point's function in the extended conversion
DEFAULT_KERNEL_EIG = 200  # eigenpairs of the squared heat kernel (the experiments store's basis size)
KERNEL_BLOCK_BYTES = 64 << 20  # point functions evaluated (n, b) float64 columns at a time, at most this size


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
SEARCHES = ("auto", "exact", "approximate")
APPROX_MIN_PAIRS = 1e11  # search="auto": approximate above this many query-point pairs (faiss installed)
IVF_LIST_SIZE = 512  # approximate: about n_p / IVF_LIST_SIZE inverted lists ...
IVF_TRAIN_PER_LIST = 40  # ... trained by IVF_KMEANS_ITER k-means iterations on this many seeded points per list
IVF_KMEANS_ITER = 10
IVF_NPROBE = 4  # lists scanned per query
IVF_CANDIDATES = 16  # nearest per query (float32) from the scanned lists, re-ranked by exact float64 distances
IVF_SEED = 0
_FAISS_HINT = "pip install faiss-cpu (or the extra: pip install 'prodmaps[fast]')"


def have_faiss() -> bool:
    """Whether the optional approximate search (``faiss``) can be imported."""
    try:
        import faiss  # noqa: F401
    except ImportError:
        return False
    return True


def effective_dimension(P: np.ndarray) -> float:
    """Participation ratio ``(Σ σ_i²)² / Σ σ_i⁴`` of the per-coordinate variances ``σ_i²`` of ``P``.

    ``P`` is ``(n, d)``: ``d`` for isotropic data, about the number of coordinates that carry the spread
    otherwise (the extended embeddings: ~18 of 150; spectral embeddings of k eigenfunctions: ~0.8 k).
    A kd-tree's cost grows with it, not with ``d``.
    """
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
    """Exact nearest neighbours by float32 products on the leading coordinates, candidates rechecked in float64."""
    d = Q.shape[1]
    # coordinates by decreasing spread of the points (a permutation: distances unchanged); the first
    # r of them give lower bounds ‖q_r − p_r‖² ≤ ‖q − p‖²
    spread = P.var(axis=0)
    order = np.argsort(-spread, kind="stable")
    share = np.cumsum(spread[order]) / max(spread.sum(), np.finfo(float).tiny)
    r = d if d <= PRUNE_MIN_DIM else int(min(d, max(PRUNE_MIN_DIM, np.searchsorted(share, PRUNE_SHARE) + 1)))
    lead = order[:r]
    Qr, Pr = np.ascontiguousarray(Q[:, lead]), np.ascontiguousarray(P[:, lead])
    gamma = 2.0 * (r + 8) * _U32  # |G − D'_r| ≤ γ (‖q_r‖² + 2‖p_r‖²) for the float32 product G
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
    """``"auto"`` between the kd-tree and the products when neither clearly wins, by timing both.

    The first ``PROBE_QUERIES`` queries by the kd-tree, the next as many by the products, and the rest
    by the one that was faster per query (exact either way: the choice never changes the result).
    """
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


def _rerank(Q, P, cand, block_rows: int = 1 << 18):
    """Among the candidates ``cand`` ``(n_q, c)`` (``-1``: none) of each query, the exact nearest.

    :func:`_exact_pick`: float64 distances, ties to the smallest index, by blocks of queries; ``-1`` for
    a row without any.
    """
    idx = np.full(cand.shape[0], -1, dtype=np.int64)
    for s in range(0, cand.shape[0], block_rows):
        cb = cand[s : s + block_rows].astype(np.int64)
        has = cb >= 0
        sub = np.flatnonzero(has.any(axis=1))  # rows with a candidate
        rows, cols = np.nonzero(has[sub])
        idx[s + sub] = _exact_pick(Q[s + sub], P, rows, cb[sub][rows, cols], sub.size)
    return idx


def _nn_approximate(Q, P, block, *, nprobe: int = IVF_NPROBE, candidates: int = IVF_CANDIDATES,
                    list_size: int = IVF_LIST_SIZE, seed: int = IVF_SEED):
    """Approximate nearest neighbours by a faiss inverted-file index, candidates re-ranked exactly.

    Module doc, "Search at scale". Deterministic for given inputs (seeded training sample, faiss'
    seeded k-means). Rows whose scanned lists hold no point are searched exactly.
    """
    try:
        import faiss
    except ImportError as e:
        raise ImportError(f"search='approximate' needs the optional dependency faiss: {_FAISS_HINT}") from e
    n_p, d = P.shape
    nlist = max(1, int(round(n_p / list_size)))
    P32 = np.ascontiguousarray(P, dtype=np.float32)
    index = faiss.IndexIVFFlat(faiss.IndexFlatL2(d), d, nlist)
    index.cp.seed = int(seed)
    index.cp.niter = IVF_KMEANS_ITER
    index.cp.min_points_per_centroid = 1  # small inputs: no warning (the training sample is all points)
    n_train = min(n_p, IVF_TRAIN_PER_LIST * nlist)
    sample = np.sort(np.random.default_rng(seed).choice(n_p, n_train, replace=False))
    index.train(P32[sample])
    index.add(P32)
    index.nprobe = int(min(nprobe, nlist))
    _, cand = index.search(np.ascontiguousarray(Q, dtype=np.float32), int(min(candidates, n_p)))  # (n_q, c)
    idx = _rerank(Q, P, cand)
    none = np.flatnonzero(idx < 0)
    if none.size:
        idx[none] = _nn_gemm(Q[none], P, block)
    return idx


def nearest_neighbors(queries: np.ndarray, points: np.ndarray, block: int | None = None,
                      return_distance: bool = False, method: str = "auto", search: str = "exact"):
    """Exact Euclidean nearest neighbour in ``points`` ``(n_p, d)`` of every row of ``queries`` ``(n_q, d)``.

    With ``search="approximate"``, an approximate one.

    The answer is the index minimising the squared distance ``Σ_i (q_i − p_i)²`` computed in
    float64; **ties go to the smallest index**. It does not depend on ``method`` or ``block``:

    * ``"gemm"``: blocked brute force (``block`` query rows at a time, default about 4·10⁶
      distances per block, and at least 64 rows while a block stays under 2.5·10⁸ distances: with a
      million points a block of 3 rows would stream all of them for every 3 queries)
      by one float32 matrix product of ``[q, 1]`` and ``[−2p, ‖p‖²]``;
      every point within the rounding bound of a row's minimum is a candidate, and rows with
      several candidates are decided by the exact float64 distances of their candidates.
    * ``"kdtree"``: ``scipy.spatial.cKDTree`` (both cores), the two nearest per query; a query
      whose second neighbour is as close as the first up to rounding is decided by ``"gemm"``.
    * ``"auto"`` (default): ``"kdtree"`` in up to ``KDTREE_MAX_DIM`` dimensions, above when the
      points' :func:`effective_dimension` is at most ``KDTREE_MAX_EFFECTIVE_DIM`` (as the extended
      embedding's 150 coordinates at 29/39 are) or when the brute force would compare more than
      ``GEMM_MAX_PAIRS`` pairs; ``"gemm"`` otherwise. A kd-tree pick above ``PROBE_MIN_DIM``
      dimensions with at least ``4 * PROBE_QUERIES`` queries is checked: both methods answer
      ``PROBE_QUERIES`` queries, timed, and the faster one answers the rest (a kd-tree's cost
      depends on how far the queries lie from the points).

    ``search``: ``"exact"`` (default, all of the above), ``"approximate"`` (faiss inverted-file
    index with an exact re-ranking of its candidates, module doc "Search at scale"; ``method`` is
    then ignored; ``ImportError`` without faiss) or ``"auto"`` (approximate above
    ``APPROX_MIN_PAIRS`` query-point pairs when faiss is installed, exact otherwise).

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
    if search not in SEARCHES:
        raise ValueError(f"search must be one of {SEARCHES}, got {search!r}")
    if search == "auto":
        big = float(Q.shape[0]) * float(P.shape[0]) > APPROX_MIN_PAIRS
        search = "approximate" if big and have_faiss() else "exact"
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
    else:
        nn = {"probe": _nn_probe, "kdtree": _nn_kdtree, "gemm": _nn_gemm}[method]
        idx = (_nn_approximate if search == "approximate" else nn)(Q, P, block)
    if not return_distance:
        return idx
    diff = Q - P[idx]
    return idx, np.sqrt(np.einsum("ij,ij->i", diff, diff))


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


_SOURCE_COEF_CACHE_BYTES = 2**28


def _canonical_functions(pb, op) -> tuple[np.ndarray, np.ndarray]:
    """``(AΨ (n, r), X (K_u, r))`` of an Approach B operator ``op`` of the product basis ``pb``.

    With ``sqrt(A) B_s D = U Σ Vᵀ`` truncated to ``r`` (``B_s`` the solver columns, ``D`` the
    normalisation's column weights), ``X = D V_r Σ_r⁻¹`` and ``Ψ = B_s X`` is A-orthonormal:
    the canonical coefficients of any function are ``ã = Ψᵀ A f`` (Section 4.4: ``Σ Vᵀ a`` of its
    Approach B fit ``a = X Xᵀ B_sᵀ A f``). ``X`` comes from the operator's own ``Σ Vᵀ D⁻¹``
    (``op.canonical``), so the truncation is the operator's: ``X = D² (ΣVᵀD⁻¹)ᵀ Σ⁻²``, with
    ``Σ² = (ΣVᵀD⁻¹) D² (ΣVᵀD⁻¹)ᵀ`` solved rather than assumed diagonal.
    """
    def compute():
        E = pb.expand()  # (K, K_u): solver -> basis coefficients; Eᵀ E = I
        sV = np.asarray(op.canonical(E.toarray()))  # (r, K_u) = Σ Vᵀ D⁻¹ in the solver columns
        d = column_weights(pb, op.params["normalization"])
        d2 = np.ones(sV.shape[1]) if d is None else d * d
        S2 = (sV * d2) @ sV.T  # (r, r) = Σ²
        X = np.linalg.solve(0.5 * (S2 + S2.T), sV * d2).T  # (K_u, r)
        APsi = pb.solver_matmul(X)  # (n, r) Ψ
        APsi *= pb.base.mass[:, None]
        return APsi, X

    p = op.params
    return pb.cache.get(("p2p_canonical_functions", float(p["rtol"]), p["normalization"]), compute)


def _source_embedding(b1: Basis, basis_1: Basis, pb1, op1, *, point, t, n_eig, block_bytes, dtype) -> np.ndarray:
    """Canonical coefficients ``(n1, r1)`` of every source point's function in its own extended basis.

    ``Ψ1ᵀ A1 f``, blocked; kept in the source basis' cache (up to 256 MB): they do not depend on the map.
    """
    def compute():
        APsi = _canonical_functions(pb1, op1)[0].astype(dtype, copy=False)  # (n1, r1)
        out = np.empty((b1.n, APsi.shape[1]))
        for rows in _blocks(b1.n, b1.n, block_bytes):
            pts = np.arange(rows.start, rows.stop)
            out[rows] = point_functions(basis_1, pts, point=point, t=t, n_eig=n_eig, dtype=dtype).T @ APsi  # (b, r1)
        return out

    if b1.n * pb1.K * 8 > _SOURCE_COEF_CACHE_BYTES:
        return compute()
    p = op1.params
    key = ("p2p_source_canonical", b1.k, point, float(t), int(n_eig), float(p["rtol"]), p["normalization"],
           pb1.pairs, int(block_bytes), np.dtype(dtype).str)
    return basis_1.cache.get(key, compute)


def extended_embeddings(C_12, basis_1: Basis, basis_2: Basis, *, point: str = "heat", t=None, t_scale: float = 1.0,
                        n_eig=None, rtol: float = 1e-3, normalization: str | None = None, pairs: str = "unique",
                        vertices=None, block_bytes: int = KERNEL_BLOCK_BYTES, dtype: str = "float32"):
    """Canonical coefficients used by the extended conversion (module doc).

    Returns ``(emb_1 (n1, r), emb_2 (n2, r), info)``: the transferred functions of the vertices
    of shape 1 and the functions of the vertices of shape 2, both as canonical coefficients of
    shape 2's extended basis (``r`` retained singular values, divided by ``sqrt(area_2)``; the
    closed form keeps its historical scale), plus a dict of the parameters used. Arguments as in
    :func:`from_fmap`; ``vertices`` (optional ``(m,)`` shape-2 vertex indices) gives ``emb_2`` of
    those vertices only, ``(m, r)``. ``C_12`` uses the first ``k1``/``k2`` columns of the bases for
    the products; the heat kernel uses up to ``n_eig`` columns of the bases as given.
    """
    if point not in POINTS:
        raise ValueError(f"point must be one of {POINTS}, got {point!r}")
    C = check_fmap(C_12, basis_1, basis_2, allow_truncation=True)
    k2, k1 = C.shape
    b1, b2 = basis_1.truncate(k1), basis_2.truncate(k2)
    norm = {} if normalization is None else {"normalization": normalization}
    if point == "closed_form":
        return _closed_form_embeddings(C, b1, b2, t=t, t_scale=t_scale, n_eig=n_eig, rtol=rtol, normalization=norm,
                                       pairs=pairs, vertices=vertices)
    for i, b in ((1, basis_1), (2, basis_2)):
        if not b.mass_is_diagonal:
            raise ValueError(f"point={point!r} needs lumped (diagonal) masses, basis_{i} has a full mass matrix: "
                             "build the bases with mass='lumped' (the default), or use method='std' or "
                             "'extended_closed_form'")
    n_max = min(basis_1.k, basis_2.k)
    n_eig = min(DEFAULT_KERNEL_EIG, n_max) if n_eig is None else int(n_eig)
    if not 2 <= n_eig <= n_max:
        raise ValueError(f"n_eig must be in [2, {n_max}] (columns of both bases as given), got {n_eig}")
    if point == "heat" and n_eig <= max(k1, k2):
        warnings.warn(f"the squared heat kernel from {n_eig} eigenpairs lies in the span of the products of the "
                      f"map's {k1}/{k2} basis functions: the conversion is then the closed form's, which cannot "
                      f"beat the standard one; pass bases with more eigenpairs ({DEFAULT_KERNEL_EIG} by default)",
                      stacklevel=3)
    if t is None:
        t = float(t_scale) / float(b1.evals[k1 - 1])
    if not (np.isfinite(t) and t >= 0):
        raise ValueError(f"t must be a finite number >= 0, got {t}")
    if np.dtype(dtype) not in (np.float32, np.float64):
        raise ValueError(f"dtype must be 'float32' or 'float64', got {dtype!r}")
    if int(block_bytes) < 1:
        raise ValueError(f"block_bytes must be >= 1, got {block_bytes}")
    ratio = b2.area / b1.area  # shape 2 uses the same time relative to its area: t · a2 / a1
    pb1, pb2 = product_basis(b1, order=2, pairs=pairs), product_basis(b2, order=2, pairs=pairs)
    op1, op2 = pb1.operator("svd", rtol=rtol, **norm), pb2.operator("svd", rtol=rtol, **norm)
    Ct = extend_fmap(C, b1, b2, order=2, pairs=pairs)  # (K2, K1)
    scale = 1.0 / np.sqrt(b2.area)  # ‖f‖ on the unit-area target
    _, X1 = _canonical_functions(pb1, op1)  # (K1_u, r1)
    # a source function's fit is a1 = E1 X1 ã1 (ã1 its canonical coefficients on shape 1); its image's
    # canonical coefficients on shape 2 are Σ2 V2ᵀ D2⁻¹ C~ a1
    R = np.asarray(op2.canonical(Ct @ (pb1.expand() @ X1))) * scale  # (r2, r1)
    e1 = _source_embedding(b1, basis_1, pb1, op1, point=point, t=t, n_eig=n_eig, block_bytes=block_bytes,
                           dtype=dtype)
    emb_1 = e1 @ R.T  # (n1, r2)
    APsi2 = _canonical_functions(pb2, op2)[0].astype(dtype, copy=False)  # (n2, r2)
    targets = np.arange(b2.n) if vertices is None else np.asarray(vertices, dtype=np.int64)
    emb_2 = np.empty((targets.shape[0], APsi2.shape[1]))  # (n2 or m, r2)
    for rows in _blocks(targets.shape[0], b2.n, block_bytes):
        F = point_functions(basis_2, targets[rows], point=point, t=t * ratio, n_eig=n_eig, dtype=dtype)  # (n2, b)
        emb_2[rows] = F.T @ APsi2
    emb_2 *= scale
    return emb_1, emb_2, {"point": point, "t": t, "n_eig": n_eig, "rtol": rtol, "pairs": pairs,
                          "normalization": op2.params["normalization"], "dim": emb_1.shape[1]}


def from_fmap(C_12, basis_1: Basis, basis_2: Basis, method: str = "std", *, block: int | None = None, vertices=None,
              search: str = "auto", **params) -> np.ndarray:
    """Point map ``p2p_21`` ``(n2,)`` (for each vertex of shape 2 a vertex of shape 1) from ``C_12`` ``(k2, k1)``.

    Parameters
    ----------
    C_12 : ``(k2, k1)`` functional map; uses the first ``k1`` columns of ``basis_1`` and the
        first ``k2`` of ``basis_2``.
    basis_1, basis_2 : the shapes' bases. For ``"extended"`` pass the shapes' big bases (200
        eigenpairs, :data:`DEFAULT_KERNEL_EIG`): the heat kernel that represents a point is built
        from all their columns (up to ``n_eig``), the products from the map's ``k1``/``k2``.
    method : ``"std"`` (nearest neighbours between ``Φ2`` and ``Φ1 C_12ᵀ``, [OBCS*12]),
        ``"extended"`` (Sections 4.4/5.3: points as squared heat kernels on the mesh, fitted in the
        extended basis by Approach B, transferred by ``C̃``, compared through canonical
        coefficients) or ``"extended_closed_form"`` (the kernel from the map's own eigenpairs in
        closed form; cannot beat ``"std"``, see the module doc).
    block : query rows per block of the exact nearest-neighbour search.
    vertices : optional ``(m,)`` int array of shape-2 vertices to map (default: all). The answer
        is then ``(m,)``, equal to ``from_fmap(...)[vertices]`` (the search is exact per query), at
        ``m/n2`` of the search's cost: for evaluating a map on sampled vertices.
    search : ``"auto"`` (default), ``"exact"`` or ``"approximate"`` (the nearest-neighbour search,
        module doc "Search at scale"). ``"auto"`` is exact up to ``APPROX_MIN_PAIRS`` = 1e11
        query-point pairs (``m`` or ``n2`` times ``n1``: every mesh of the paper, any pair up to
        ~300k vertices each) and approximate above when faiss is installed (a faiss
        inverted-file index, candidates re-ranked by exact distances; recall against the exact
        answer measured in ``benchmarks/scale_1m.py``). ``"approximate"`` without faiss raises
        ``ImportError``; ``"exact"`` is always exact (hours at a million vertices).
    **params : for the extended methods: ``t`` (heat time in shape 1's units; default
        ``t_scale / λ_{k1−1}``, closed form ``t_scale / λ_{n_eig−1}``), ``t_scale`` (1.0),
        ``n_eig`` (eigenpairs in the kernel, constant included; default ``min(200, basis_1.k,
        basis_2.k)``, closed form ``min(k1, k2)``), ``rtol`` (Approach B truncation, 1e-3),
        ``normalization`` (of Approach B, :mod:`prodmaps.approx`; default the library's
        ``"euclidean"``), ``pairs`` (``"unique"`` or ``"ordered"``); ``"extended"`` also takes
        ``point`` (``"heat"`` default, ``"delta"``, or ``"closed_form"`` = the closed-form method)
        ``block_bytes`` (size of a block of point functions, 64 MB) and ``dtype`` (``"float32"``,
        default, or ``"float64"``: the precision of the two large products, see the module doc).

    Examples
    --------
    >>> import numpy as np
    >>> import prodmaps as pm
    >>> from prodmaps.mesh import ellipsoid
    >>> b = pm.eigenbasis(ellipsoid(2), 40)
    >>> C = pm.fmap_from_p2p(np.arange(b.n), b.truncate(10), b.truncate(12))  # (12, 10) identity map
    >>> bool(np.all(from_fmap(C, b, b, "extended") == np.arange(b.n)))
    True
    """
    if method not in METHODS:
        raise ValueError(f"method must be one of {METHODS}, got {method!r}")
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
        # compared as on unit-area shapes (so the answer does not depend on units or the area ratio):
        # sqrt(a2) Φ2 against the unit-area map's images a1 / sqrt(a2) Φ1 Cᵀ, i.e. Φ2 against (a1/a2) Φ1 Cᵀ
        emb_1 = (basis_1.area / basis_2.area) * (basis_1.vecs[:, :k1] @ C.T)  # (n1, k2) images of the source deltas
        emb_2 = basis_2.vecs[:, :k2] if vertices is None else basis_2.vecs[vertices, :k2]  # (n2 or m, k2)
    else:
        allowed = {"t", "t_scale", "n_eig", "rtol", "pairs", "normalization"}
        allowed |= {"point", "block_bytes", "dtype"} if method == "extended" else set()
        bad = set(params) - allowed
        if bad:
            raise TypeError(f"unknown parameters for method={method!r}: {sorted(bad)}; allowed: {sorted(allowed)}")
        if method == "extended_closed_form":
            params["point"] = "closed_form"
        emb_1, emb_2, _ = extended_embeddings(C, basis_1, basis_2, vertices=vertices, **params)  # (n1, r), (m, r)
    return nearest_neighbors(emb_2, emb_1, block=block, search=search)
