"""Nearest neighbours (prodmaps.neighbors): every backend through its public name against the brute force."""

import sys

import numpy as np
import pytest
from scipy.spatial import cKDTree
from scipy.spatial.distance import cdist

import prodmaps as pm
from prodmaps import neighbors
from prodmaps.neighbors import (
    METHODS,
    effective_dimension,
    gemm_neighbors,
    have_faiss,
    ivf_neighbors,
    kdtree_neighbors,
    nearest_neighbors,
    probe_neighbors,
)


def _brute_force(Q, P):
    """Reference: squared distances by direct differences, first index of the minimum."""
    return np.argmin(cdist(Q, P, "sqeuclidean"), axis=1)


# every exact backend, called by its public name (the probe with few queries so that it finishes with one)
BACKENDS = {
    "nearest_neighbors": lambda Q, P, block=None: nearest_neighbors(Q, P, block=block),
    "kdtree_neighbors": lambda Q, P, block=None: kdtree_neighbors(Q, P, block=block),
    "gemm_neighbors": lambda Q, P, block=None: gemm_neighbors(Q, P, block=block),
    "probe_neighbors": lambda Q, P, block=None: probe_neighbors(Q, P, block=block, probe_queries=16),
}


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("dim", [3, 40, 2500])
@pytest.mark.parametrize("block", [1, 7, None])
def test_backends_equal_brute_force(backend, dim, block):
    rng = np.random.default_rng(dim)
    P = rng.normal(size=(300, dim))
    Q = rng.normal(size=(123, dim))
    idx = BACKENDS[backend](Q, P, block=block)
    assert idx.dtype == np.int64 and idx.shape == (123,)
    assert np.array_equal(idx, np.argmin(cdist(Q, P), axis=1))


def test_distances_returned():
    rng = np.random.default_rng(1)
    P, Q = rng.normal(size=(300, 5)), rng.normal(size=(50, 5))
    idx, dist = nearest_neighbors(Q, P, return_distance=True)
    D = cdist(Q, P)
    assert np.array_equal(idx, np.argmin(D, axis=1))
    assert np.allclose(dist, D.min(axis=1), rtol=1e-9)


@pytest.mark.parametrize("backend", BACKENDS)
def test_exact_hits_and_ties_go_to_the_smallest_index(backend):
    nn = BACKENDS[backend]
    P = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 0.0], [5.0, 5.0]])
    assert np.array_equal(nn(P, P), [0, 1, 1, 3])  # duplicates: smallest index
    # a query exactly half-way between two points goes to the smaller index, whatever the order
    Q = np.array([[0.5, 0.0], [3.0, 2.5]])
    assert np.array_equal(nn(Q, P), [0, 1])
    assert np.array_equal(nn(Q, P[::-1]), [1, 0])
    for method in METHODS:  # the same through nearest_neighbors' method names
        assert np.array_equal(nearest_neighbors(Q, P[::-1], method=method), [1, 0])


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("dim", [1, 2, 5, 30, 33, 64, 300])
def test_backends_equal_brute_force_with_exact_ties(backend, dim):
    """Grid points (many duplicates and equidistant neighbours, every distance exact in floating
    point) and half-integer queries: every backend returns the brute force's first minimiser."""
    nn = BACKENDS[backend]
    rng = np.random.default_rng(dim)
    P = rng.integers(-2, 3, size=(400, dim)).astype(float)
    Q = rng.integers(-2, 3, size=(250, dim)) + 0.5 * rng.integers(0, 2, size=(250, dim))
    D = cdist(Q, P, "sqeuclidean")
    assert np.sum(D == D.min(axis=1, keepdims=True)) > Q.shape[0]  # the data has exact ties
    for block in (1, 37, None):
        assert np.array_equal(nn(Q, P, block=block), _brute_force(Q, P))
    Pr, Qr = rng.normal(size=(500, dim)), rng.normal(size=(300, dim))  # generic data, one scale spread out
    Pr *= np.geomspace(1.0, 1e-3, dim)[None, :]
    Qr *= np.geomspace(1.0, 1e-3, dim)[None, :]
    assert np.array_equal(nn(Qr, Pr), _brute_force(Qr, Pr))


@pytest.mark.parametrize("backend", BACKENDS)
def test_near_ties_are_decided_exactly(backend):
    """Points whose distances differ below float32 resolution: the float32 stage must hand them
    to the exact recheck (a float32-only argmin would pick either)."""
    rng = np.random.default_rng(5)
    base = rng.normal(size=(1, 50))
    P = np.repeat(base, 40, axis=0) + 1e-9 * rng.normal(size=(40, 50))
    P = np.vstack([P, rng.normal(size=(200, 50))])
    Q = base + 1e-9 * rng.normal(size=(30, 50))
    assert np.array_equal(BACKENDS[backend](Q, P), _brute_force(Q, P))


def test_auto_agrees_with_kdtree_on_spectral_embeddings(human_0, human_13):
    """The standard conversion's embeddings in both regimes of ``auto`` (kd-tree, products)."""
    b1, b2 = pm.eigenbasis(human_0, 50), pm.eigenbasis(human_13, 50)
    C = np.random.default_rng(2).normal(size=(50, 50)) * 0.1 + np.eye(50)
    for k in (10, 50):
        P, Q = b1.vecs[:, :k] @ C[:k, :k].T, b2.vecs[:, :k]
        d_kd, i_kd = cKDTree(P).query(Q, k=2)
        assert np.all(d_kd[:, 1] > d_kd[:, 0])  # no near ties: the kd-tree's answer is the exact one
        assert np.array_equal(nearest_neighbors(Q, P), i_kd[:, 0])
        assert np.array_equal(gemm_neighbors(Q, P), i_kd[:, 0])


@pytest.mark.parametrize("backend", BACKENDS)
def test_bad_inputs(backend):
    nn = BACKENDS[backend]
    with pytest.raises(ValueError, match="dimension"):
        nn(np.zeros((3, 2)), np.zeros((4, 3)))
    with pytest.raises(ValueError, match="2D"):
        nn(np.zeros(3), np.zeros((4, 3)))
    with pytest.raises(ValueError, match="empty"):
        nn(np.zeros((3, 2)), np.zeros((0, 2)))
    with pytest.raises(ValueError, match="block"):
        nn(np.zeros((3, 2)), np.zeros((4, 2)), block=0)
    assert nn(np.zeros((0, 2)), np.zeros((4, 2))).shape == (0,)


def test_nearest_neighbors_names_its_choices():
    with pytest.raises(ValueError, match="method"):
        nearest_neighbors(np.zeros((3, 2)), np.zeros((4, 2)), method="ball")
    with pytest.raises(ValueError, match="search must be one of"):
        nearest_neighbors(np.zeros((3, 2)), np.zeros((4, 2)), search="fast")
    with pytest.raises(ValueError, match="probe_queries"):
        probe_neighbors(np.zeros((3, 2)), np.zeros((4, 2)), probe_queries=0)


def test_effective_dimension():
    rng = np.random.default_rng(4)
    assert effective_dimension(rng.normal(size=(4000, 50))) == pytest.approx(50, rel=0.05)
    assert effective_dimension(np.c_[rng.normal(size=(100, 1)), np.zeros((100, 9))]) == pytest.approx(1.0)
    assert effective_dimension(np.ones((5, 3))) == 0.0
    spread = rng.normal(size=(3000, 40)) * np.r_[np.ones(4), 1e-4 * np.ones(36)]  # 4 coordinates carry it
    assert effective_dimension(spread) == pytest.approx(4, rel=0.1)


def _spy(monkeypatch, name, calls):
    """Replace the public backend ``neighbors.<name>`` by a wrapper that records the queries' counts."""
    real = getattr(neighbors, name)

    def spy(Q, P, **kw):
        calls.append(len(Q))
        return real(Q, P, **kw)

    monkeypatch.setattr(neighbors, name, spy)


def test_auto_takes_the_kdtree_when_few_coordinates_carry_the_spread(monkeypatch):
    """Above KDTREE_MAX_DIM coordinates with a low effective dimension (as the extended conversion's
    embeddings) ``auto`` takes the kd-tree (alone or checked by the probe); isotropic data of the same
    width takes the products. The answer is the brute force's either way."""
    rng = np.random.default_rng(4)
    d = neighbors.KDTREE_MAX_DIM + 20
    w = np.r_[np.ones(5), 1e-3 * np.ones(d - 5)]
    P, Q = rng.normal(size=(2000, d)) * w, rng.normal(size=(1500, d)) * w
    assert effective_dimension(P) <= neighbors.KDTREE_MAX_EFFECTIVE_DIM
    kd, mm = [], []
    _spy(monkeypatch, "kdtree_neighbors", kd)
    _spy(monkeypatch, "gemm_neighbors", mm)
    assert np.array_equal(nearest_neighbors(Q, P), _brute_force(Q, P))
    assert sum(kd) >= neighbors.PROBE_QUERIES  # the kd-tree answered (the probe's share at least)
    kd.clear(), mm.clear()
    Qi, Pi = rng.normal(size=(50, 60)), rng.normal(size=(80, 60))  # isotropic: the products
    assert np.array_equal(nearest_neighbors(Qi, Pi), _brute_force(Qi, Pi))
    assert kd == [] and mm == [50]


@pytest.mark.parametrize("kd_faster", [True, False])
def test_probe_finishes_with_the_faster_backend(monkeypatch, kd_faster):
    """The probe times PROBE_QUERIES queries per backend with the clock it is given and lets the faster
    one answer the rest; the answer is the brute force's either way (a clock that decides the probe
    exercises both outcomes). ``auto`` goes through the probe for a kd-tree pick above PROBE_MIN_DIM."""
    rng = np.random.default_rng(7)
    w = np.r_[np.ones(3), 1e-3 * np.ones(9)]  # 12 coordinates, effective dimension ~3
    s = neighbors.PROBE_QUERIES
    P = rng.normal(size=(600, 12)) * w
    Q = rng.normal(size=(4 * s + 37, 12)) * w
    ticks = iter([0.0, 1.0 if kd_faster else 5.0, 3.0 if kd_faster else 6.0])  # t1, t2, t3
    used = {"kdtree": [], "gemm": []}
    _spy(monkeypatch, "kdtree_neighbors", used["kdtree"])
    _spy(monkeypatch, "gemm_neighbors", used["gemm"])
    assert np.array_equal(probe_neighbors(Q, P, clock=lambda: next(ticks)), _brute_force(Q, P))
    rest = len(Q) - 2 * s
    winner, loser = ("kdtree", "gemm") if kd_faster else ("gemm", "kdtree")
    assert used[winner] == [s, rest] and used[loser] == [s]
    probed = []
    _spy(monkeypatch, "probe_neighbors", probed)
    assert np.array_equal(nearest_neighbors(Q, P), _brute_force(Q, P)) and probed == [len(Q)]


def test_ivf_recall_against_exact(basis_0, basis_13):
    """ivf_neighbors (faiss inverted-file index, candidates re-ranked exactly): on the standard
    conversion of a computed-like map between the two humans (5002 vertices, 40 dimensions), with lists of
    ~32 points and 2 probed (the defaults would scan every list here), it agrees with the exact search on
    at least 99% of vertices (measured 99.7%), a miss is a farther point (never a closer one), and it is
    deterministic."""
    pytest.importorskip("faiss")  # an optional extra; `make venv` installs it ([fast] in the lock file)
    C = pm.fmap_from_p2p(np.arange(basis_13.n), basis_0, basis_13)  # (40, 40) ground truth
    C = C + 0.02 * np.random.default_rng(5).normal(size=C.shape)  # a computed map's kind of error
    Q, P = basis_13.vecs, (basis_0.area / basis_13.area) * (basis_0.vecs @ C.T)
    exact, d_ex = nearest_neighbors(Q, P, return_distance=True)
    approx = ivf_neighbors(Q, P, list_size=32, nprobe=2)
    recall = float(np.mean(approx == exact))
    assert recall >= 0.99, recall
    assert recall < 1.0  # the index is really approximate at these settings (else the test proves nothing)
    d_ap = np.linalg.norm(Q - P[approx], axis=1)
    assert np.all(d_ap >= d_ex * (1 - 1e-12))  # never closer than the exact nearest
    assert np.all(d_ap[approx != exact] > d_ex[approx != exact])  # a miss is a farther point, not a tie
    np.testing.assert_array_equal(ivf_neighbors(Q, P, list_size=32, nprobe=2), approx)
    # the defaults (lists of ~512 points: 10 lists here, 4 probed, 16 candidates re-ranked)
    default = nearest_neighbors(Q, P, search="approximate")
    assert np.mean(default == exact) >= 0.99
    np.testing.assert_array_equal(ivf_neighbors(Q, P), default)


def test_search_auto_and_a_missing_faiss(monkeypatch):
    """search="auto" is exact below APPROX_MIN_PAIRS and approximate above when faiss imports; without
    faiss, "auto" stays exact and "approximate" is an ImportError that names the package."""
    rng = np.random.default_rng(6)
    P, Q = rng.normal(size=(400, 6)), rng.normal(size=(300, 6))
    exact = _brute_force(Q, P)
    calls = []
    _spy(monkeypatch, "ivf_neighbors", calls)
    np.testing.assert_array_equal(nearest_neighbors(Q, P, search="auto"), exact)
    assert calls == []
    monkeypatch.setattr(neighbors, "APPROX_MIN_PAIRS", Q.shape[0] * P.shape[0] - 1)  # this search counts as large
    if have_faiss():
        assert np.mean(nearest_neighbors(Q, P, search="auto") == exact) >= 0.9 and calls == [300]
    calls.clear()
    monkeypatch.setitem(sys.modules, "faiss", None)  # not installed
    assert not have_faiss()
    np.testing.assert_array_equal(nearest_neighbors(Q, P, search="auto"), exact)
    assert calls == []
    with pytest.raises(ImportError, match="pip install faiss-cpu"):
        nearest_neighbors(Q, P, search="approximate")
