"""Nearest neighbours in Euclidean space: exact (kd-tree, blocked products) and approximate (faiss IVF).

Contract of every exact backend: for each row ``q`` of ``queries`` ``(n_q, d)`` the index ``j`` of
``points`` ``(n_p, d)`` minimising ``Σ_i (q_i − p_i)²`` computed in float64, **ties to the smallest
index**; the answer does not depend on the backend, the block size or the machine's BLAS.

* :func:`nearest_neighbors` ``(queries, points, method=, search=)``: the one entry point, which picks
  a backend (``method="auto"``) or takes the one named (``"kdtree"``, ``"gemm"``).
* :func:`kdtree_neighbors`: ``scipy.spatial.cKDTree``, the two nearest per query; a query whose
  second neighbour is as close as the first up to rounding is decided by :func:`gemm_neighbors`.
* :func:`gemm_neighbors`: blocked float32 products ``[q, 1] · [−2p, ‖p‖²]`` on the leading
  coordinates (a lower bound of every distance), every candidate within the rounding bound of a
  row's minimum rechecked by its exact float64 distance.
* :func:`probe_neighbors`: both of the above on ``PROBE_QUERIES`` queries each, timed by ``clock``
  (a parameter), the faster one answering the rest; exact either way.
* :func:`ivf_neighbors`: approximate, a faiss inverted-file index (optional dependency
  ``faiss-cpu``, ``pip install 'prodmaps[fast]'``, :func:`have_faiss`) whose candidates are
  re-ranked by exact float64 distances: a query whose exact neighbour was scanned gets it.
* :func:`effective_dimension`: the participation ratio of the points' coordinate variances, which
  decides ``"auto"`` above ``KDTREE_MAX_DIM`` coordinates.

``method="auto"``: the kd-tree up to ``KDTREE_MAX_DIM`` dimensions, or above when the effective
dimension is at most ``KDTREE_MAX_EFFECTIVE_DIM`` or the products would compare more than
``GEMM_MAX_PAIRS`` pairs; the products otherwise. A kd-tree pick above ``PROBE_MIN_DIM`` dimensions
with at least ``4 · PROBE_QUERIES`` queries goes through :func:`probe_neighbors`.
``search="auto"`` is approximate above ``APPROX_MIN_PAIRS`` query-point pairs when faiss imports,
exact otherwise. The tuning constants below are module attributes; the reasoning behind them and
the measurements: ``docs/guide/point_maps.md`` and ``docs/benchmarks.md``.
"""

from __future__ import annotations

import time

import numpy as np

__all__ = ["nearest_neighbors", "kdtree_neighbors", "gemm_neighbors", "probe_neighbors", "ivf_neighbors",
           "effective_dimension", "have_faiss", "METHODS", "SEARCHES"]

METHODS = ("auto", "kdtree", "gemm")  # exact backends of nearest_neighbors
SEARCHES = ("auto", "exact", "approximate")
KDTREE_MAX_DIM = 32  # auto: kd-tree up to this dimension (or when a brute-force pass would be too large)
GEMM_MAX_PAIRS = 4e10  # auto: above n_q * n_p pairs the brute force is not attempted (kd-tree instead)
KDTREE_MAX_EFFECTIVE_DIM = 24  # auto: kd-tree above KDTREE_MAX_DIM when the points' effective dimension is this low
PRUNE_MIN_DIM = 128  # gemm: products on at least this many leading coordinates ...
PRUNE_SHARE = 0.995  # ... and on as many as hold this share of the points' spread
PROBE_MIN_DIM = 8  # auto: a kd-tree pick above this dimension is checked against the products ...
PROBE_QUERIES = 256  # ... on this many queries each, when there are at least 4x as many (probe_neighbors)
APPROX_MIN_PAIRS = 1e11  # search="auto": approximate above this many query-point pairs (faiss installed)
IVF_LIST_SIZE = 512  # approximate: about n_p / IVF_LIST_SIZE inverted lists ...
IVF_TRAIN_PER_LIST = 40  # ... trained by IVF_KMEANS_ITER k-means iterations on this many seeded points per list
IVF_KMEANS_ITER = 10
IVF_NPROBE = 4  # lists scanned per query
IVF_CANDIDATES = 16  # nearest per query (float32) from the scanned lists, re-ranked by exact float64 distances
IVF_SEED = 0

_U64 = np.finfo(np.float64).eps / 2
_U32 = float(np.finfo(np.float32).eps) / 2
_FAISS_HINT = "pip install faiss-cpu (or the extra: pip install 'prodmaps[fast]')"


def have_faiss() -> bool:
    """Whether the optional approximate search (``faiss``) can be imported.

    Returns
    -------
    bool
        True when ``import faiss`` succeeds (:func:`ivf_neighbors` and ``search="approximate"`` work).

    Examples
    --------
    >>> isinstance(have_faiss(), bool)
    True
    """
    try:
        import faiss  # noqa: F401
    except ImportError:
        return False
    return True


def effective_dimension(points) -> float:
    """Participation ratio ``(Σ σ_i²)² / Σ σ_i⁴`` of the per-coordinate variances ``σ_i²`` of ``points``.

    Parameters
    ----------
    points : (n, d) array_like
        Rows are points.

    Returns
    -------
    float
        ``d`` for isotropic data, about the number of coordinates that carry the spread otherwise (the
        extended point-map embeddings: ~18 of 150; spectral embeddings of k eigenfunctions: ~0.8 k);
        0 when every coordinate is constant. A kd-tree's cost grows with it, not with ``d``.

    Examples
    --------
    >>> import numpy as np
    >>> P = np.c_[np.random.default_rng(0).normal(size=(100, 1)), np.zeros((100, 9))]
    >>> effective_dimension(P)  # one coordinate carries all the spread
    1.0
    """
    v = np.asarray(points, dtype=np.float64).var(axis=0)
    den = float(np.sum(v * v))
    return float(v.sum() ** 2 / den) if den > 0 else 0.0


def _check(queries, points, block):
    """``(Q, P, block)``: float64 C-contiguous 2D arrays of equal width, a positive block size."""
    Q = np.ascontiguousarray(queries, dtype=np.float64)
    P = np.ascontiguousarray(points, dtype=np.float64)
    if Q.ndim != 2 or P.ndim != 2:
        raise ValueError(f"queries and points must be 2D arrays (n, d); got {Q.shape} and {P.shape}")
    if Q.shape[1] != P.shape[1]:
        raise ValueError(f"queries have dimension {Q.shape[1]} but points have {P.shape[1]}; they must match")
    if P.shape[0] == 0:
        raise ValueError("points is empty: nothing to match to")
    if block is None:  # ~4e6 distances a block; at least 64 rows while a block holds <= 2.5e8 (1 GB)
        block = max(1, int(4_000_000 // P.shape[0]), min(64, int(250_000_000 // P.shape[0])))
    block = int(block)
    if block < 1:
        raise ValueError(f"block must be >= 1, got {block}")
    return Q, P, block


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


def gemm_neighbors(queries, points, *, block: int | None = None) -> np.ndarray:
    """Exact nearest neighbours by blocked float32 products, near ties rechecked in float64.

    Parameters
    ----------
    queries : (n_q, d) array_like
    points : (n_p, d) array_like
    block : int, optional
        Query rows per block (default about 4·10⁶ distances a block, at least 64 rows while a block
        stays under 2.5·10⁸ distances).

    Returns
    -------
    (n_q,) int64 ndarray
        The exact nearest point of every query, ties to the smallest index (module doc).

    Raises
    ------
    ValueError
        For arrays that are not 2D, of different widths, no points, or ``block < 1``.

    Examples
    --------
    >>> import numpy as np
    >>> P = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 0.0]])
    >>> gemm_neighbors([[0.9, 0.1], [0.5, 0.0]], P)  # the duplicate and the half-way tie: smallest index
    array([1, 0])
    """
    Q, P, block = _check(queries, points, block)
    if Q.shape[0] == 0:
        return np.zeros(0, dtype=np.int64)
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


def kdtree_neighbors(queries, points, *, block: int | None = None, tree=None) -> np.ndarray:
    """Exact nearest neighbours by a kd-tree (``scipy.spatial.cKDTree``, both cores), near ties rechecked.

    Parameters
    ----------
    queries : (n_q, d) array_like
    points : (n_p, d) array_like
    block : int, optional
        Block size of the recheck by :func:`gemm_neighbors`.
    tree : scipy.spatial.cKDTree, optional
        A tree of ``points`` built already (reused: queries in several calls).

    Returns
    -------
    (n_q,) int64 ndarray
        The exact nearest point of every query, ties to the smallest index (module doc): the tree's
        two nearest per query; a query whose second is as close as the first up to the tree's
        rounding is decided by :func:`gemm_neighbors`.

    Raises
    ------
    ValueError
        As :func:`gemm_neighbors`.

    Examples
    --------
    >>> import numpy as np
    >>> P = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 0.0]])
    >>> kdtree_neighbors([[0.9, 0.1], [0.5, 0.0]], P)
    array([1, 0])
    """
    from scipy.spatial import cKDTree

    Q, P, block = _check(queries, points, block)
    if Q.shape[0] == 0:
        return np.zeros(0, dtype=np.int64)
    if P.shape[0] == 1:
        return np.zeros(Q.shape[0], dtype=np.int64)
    tree = cKDTree(P) if tree is None else tree
    dist, nn = tree.query(Q, k=2, workers=-1)  # (n_q, 2) the two nearest
    idx = nn[:, 0].astype(np.int64)
    d = Q.shape[1]
    # the kd-tree's distances carry a relative rounding of about (d + 3) u: the first neighbour is
    # the exact answer unless the second one is as close up to four times that
    amb = np.flatnonzero(dist[:, 1] ** 2 <= dist[:, 0] ** 2 * (1.0 + 4.0 * (d + 8) * _U64))
    if amb.size:
        idx[amb] = gemm_neighbors(Q[amb], P, block=block)
    return idx


def probe_neighbors(queries, points, *, block: int | None = None, clock=time.perf_counter,
                    probe_queries: int = PROBE_QUERIES) -> np.ndarray:
    """Exact nearest neighbours by whichever of the kd-tree and the products is faster here, timed.

    The first ``probe_queries`` queries by :func:`kdtree_neighbors`, the next as many by
    :func:`gemm_neighbors`, each timed by ``clock``, and the rest by the one that was faster per
    query (a kd-tree's cost depends on how far the queries lie from the points). The answer is
    exact either way: the choice never changes it.

    Parameters
    ----------
    queries : (n_q, d) array_like
    points : (n_p, d) array_like
    block : int, optional
        Block size of :func:`gemm_neighbors`.
    clock : callable, optional
        Returns the time in seconds (default ``time.perf_counter``; pass another to decide the probe).
    probe_queries : int, optional
        Queries timed per backend (default ``PROBE_QUERIES``).

    Returns
    -------
    (n_q,) int64 ndarray
        The exact nearest point of every query, ties to the smallest index.

    Raises
    ------
    ValueError
        As :func:`gemm_neighbors`, or ``probe_queries < 1``.

    Examples
    --------
    >>> import numpy as np
    >>> rng = np.random.default_rng(0)
    >>> P, Q = rng.normal(size=(50, 3)), rng.normal(size=(40, 3))
    >>> bool(np.all(probe_neighbors(Q, P, probe_queries=8) == gemm_neighbors(Q, P)))
    True
    """
    from scipy.spatial import cKDTree

    Q, P, block = _check(queries, points, block)
    s = int(probe_queries)
    if s < 1:
        raise ValueError(f"probe_queries must be >= 1, got {probe_queries}")
    idx = np.empty(Q.shape[0], dtype=np.int64)
    tree = cKDTree(P)
    t1 = clock()
    idx[:s] = kdtree_neighbors(Q[:s], P, block=block, tree=tree)
    t2 = clock()
    idx[s:2 * s] = gemm_neighbors(Q[s:2 * s], P, block=block)
    t3 = clock()
    if Q.shape[0] <= 2 * s:
        return idx
    rest = Q.shape[0] - 2 * s
    kd = (t2 - t1) * rest / s  # per-query cost times the rest (the tree is built already)
    mm = (t3 - t2) * rest / s
    idx[2 * s:] = (kdtree_neighbors(Q[2 * s:], P, block=block, tree=tree) if kd <= mm
                   else gemm_neighbors(Q[2 * s:], P, block=block))
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


def ivf_neighbors(queries, points, *, list_size: int = IVF_LIST_SIZE, nprobe: int = IVF_NPROBE,
                  candidates: int = IVF_CANDIDATES, seed: int = IVF_SEED, block: int | None = None) -> np.ndarray:
    """Approximate nearest neighbours by a faiss inverted-file index, candidates re-ranked exactly.

    The points are clustered by k-means into about ``n_p / list_size`` lists (trained on
    ``IVF_TRAIN_PER_LIST`` seeded points per list, ``IVF_KMEANS_ITER`` iterations); each query scans
    the ``nprobe`` lists of its nearest centroids in float32 for its ``candidates`` nearest, which
    are re-ranked by their exact float64 distances (ties to the smallest index). Rows whose scanned
    lists hold no point are searched exactly (:func:`gemm_neighbors`). Deterministic for given inputs.

    Parameters
    ----------
    queries : (n_q, d) array_like
    points : (n_p, d) array_like
    list_size, nprobe, candidates, seed : int, optional
        The index's settings (defaults: the module's ``IVF_*`` constants).
    block : int, optional
        Block size of the exact fallback.

    Returns
    -------
    (n_q,) int64 ndarray
        A nearest point of every query; never closer than the exact one, and the exact one whenever
        it was among the scanned candidates.

    Raises
    ------
    ImportError
        Without faiss (the message names the package to install).
    ValueError
        As :func:`gemm_neighbors`.

    Examples
    --------
    >>> import numpy as np
    >>> rng = np.random.default_rng(0)
    >>> P, Q = rng.normal(size=(200, 4)), rng.normal(size=(30, 4))
    >>> idx = ivf_neighbors(Q, P, list_size=20) if have_faiss() else gemm_neighbors(Q, P)
    >>> idx.shape
    (30,)
    """
    try:
        import faiss
    except ImportError as e:
        raise ImportError(f"search='approximate' needs the optional dependency faiss: {_FAISS_HINT}") from e
    Q, P, block = _check(queries, points, block)
    if Q.shape[0] == 0:
        return np.zeros(0, dtype=np.int64)
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
        idx[none] = gemm_neighbors(Q[none], P, block=block)
    return idx


def nearest_neighbors(queries, points, *, method: str = "auto", search: str = "exact", block: int | None = None,
                      return_distance: bool = False):
    """Nearest neighbour in ``points`` ``(n_p, d)`` of every row of ``queries`` ``(n_q, d)``.

    Parameters
    ----------
    queries : (n_q, d) array_like
    points : (n_p, d) array_like
    method : ``"auto"`` (default), ``"kdtree"`` or ``"gemm"``
        The exact backend (module doc: ``"auto"`` picks :func:`kdtree_neighbors`,
        :func:`gemm_neighbors` or :func:`probe_neighbors`); the answer does not depend on it.
    search : ``"exact"`` (default), ``"approximate"`` or ``"auto"``
        ``"approximate"``: :func:`ivf_neighbors` (``method`` is then ignored); ``"auto"``:
        approximate above ``APPROX_MIN_PAIRS`` query-point pairs when faiss imports, exact otherwise.
    block : int, optional
        Query rows per block of the products.
    return_distance : bool
        Also return the Euclidean distances.

    Returns
    -------
    idx : (n_q,) int64 ndarray
        The nearest point of every query, ties to the smallest index (exact search).
    dist : (n_q,) ndarray
        Only with ``return_distance``: ``‖q − points[idx]‖``.

    Raises
    ------
    ValueError
        For arrays that are not 2D or of different widths, no points, ``block < 1``, an unknown
        ``method`` or ``search``.
    ImportError
        For ``search="approximate"`` without faiss.

    Examples
    --------
    >>> import numpy as np
    >>> P = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 0.0], [5.0, 5.0]])
    >>> nearest_neighbors(P, P)  # duplicates: the smallest index
    array([0, 1, 1, 3])
    >>> idx, dist = nearest_neighbors([[0.5, 0.0]], P, method="gemm", return_distance=True)
    >>> int(idx[0]), float(dist[0])  # half-way between 0 and 1
    (0, 0.5)
    """
    Q, P, block = _check(queries, points, block)
    if method not in METHODS:
        raise ValueError(f"method must be one of {METHODS}, got {method!r}")
    if search not in SEARCHES:
        raise ValueError(f"search must be one of {SEARCHES}, got {search!r}")
    if search == "auto":
        big = float(Q.shape[0]) * float(P.shape[0]) > APPROX_MIN_PAIRS
        search = "approximate" if big and have_faiss() else "exact"
    if search == "approximate":
        idx = ivf_neighbors(Q, P, block=block)
    elif Q.shape[0] == 0:
        idx = np.zeros(0, dtype=np.int64)
    else:
        if method == "auto":
            big = float(Q.shape[0]) * float(P.shape[0]) > GEMM_MAX_PAIRS
            low = Q.shape[1] <= KDTREE_MAX_DIM or effective_dimension(P) <= KDTREE_MAX_EFFECTIVE_DIM
            method = "kdtree" if (low or big) else "gemm"
            if method == "kdtree" and not big and Q.shape[1] > PROBE_MIN_DIM and Q.shape[0] >= 4 * PROBE_QUERIES:
                method = "probe"
        backend = {"probe": probe_neighbors, "kdtree": kdtree_neighbors, "gemm": gemm_neighbors}[method]
        idx = backend(Q, P, block=block)
    if not return_distance:
        return idx
    diff = Q - P[idx]
    return idx, np.sqrt(np.einsum("ij,ij->i", diff, diff))
