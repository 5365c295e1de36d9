"""Million-vertex benchmark: a scale pair generated here (never stored), each step timed with its peak memory.

Usage::

    python benchmarks/scale_1m.py [--levels 4] [--k 40] [--functions 100] [--jobs 2] [--solver auto]
                                  [--search auto] [--p2p-sample 2000]

Two poses of the embedded humans (``anny_000`` and ``anny_013``, one triangulation) are
subdivided the same way (1-to-4 midpoint subdivision ``levels`` times: 5002 -> about 1.28M
vertices at 4 levels), so the pair keeps one triangulation and the identity ground truth
(``p2p_21 = arange(n)``). Steps, each in this one process, with the wall time and the growth
of the peak resident memory (``ru_maxrss``):

* ``eigenbasis(k)`` on both shapes, in ``--jobs`` worker processes (:func:`prodmaps.basis.eigenbases`:
  the sparse factorisation and its solves run on one core each; ``--jobs 1``: one after the other),
  with ``--solver`` (``auto``: the sparse Cholesky of the optional ``cholespy`` at this size, SuperLU
  without it);
* the ground-truth map ``C_12`` at ``k_M = 29`` / ``k_N = 39``; the default transfer
  ``pm.transfer(F, C, b1, b2, "default")`` and Approach B (``rtol=1e-3``, ordered pairs) of
  ``functions`` functions (the coordinates and seeded random functions);
* the full standard point map ``pm.p2p.from_fmap(C, b1, b2, "std", search=--search)`` of all ``n``
  target vertices (``auto``: faiss's inverted-file search with an exact re-ranking of its
  candidates at this size, when faiss is installed; the exact search would take hours).

``pipeline_s`` is the sum of those four steps (eigenbases, the two transfers, the point map): the
issue's budget (300 s, 16 GB). Not in it, the evaluation of the point map on ``--p2p-sample``
seeded target vertices (``0`` skips it):

* ``p2p_exact_sample``: the exact conversion of those vertices (``search="exact", vertices=...``,
  the exact answer the full map is compared with); ``p2p_recall`` is the share of them on which
  the full map gives the exact answer, with the time of an exact search of all ``n`` extrapolated
  (its cost is linear in the number of queries);
* ``p2p_geodesic_error``: the mean error of both maps against the ground truth (the identity) on
  those vertices, ``d_1(p2p[y], y) / sqrt(area_1)``, with ``d_1`` the edge-graph (Dijkstra)
  distance on the subdivided shape 1 (bounded searches around each ``y``): an upper bound of the
  geodesic distance, a few percent long on this regular subdivision, the same metric for both
  maps, so their difference is the approximate search's cost.

Prints one JSON line (the last line of stdout) and, for the extended point-map conversion, the
FLOP count of its brute force and the machine's measured GEMM rate instead of running it.
"""

from __future__ import annotations

import argparse
import json
import resource
import sys
import time

import numpy as np


def peak_gb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20


def peak_children_gb() -> float:
    """Peak resident memory of the largest finished worker process (the eigenbases' workers)."""
    return resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 2**20


def gemm_gflops(n: int = 2000, repeat: int = 3) -> float:
    a = np.random.default_rng(0).random((n, n))
    best = np.inf
    for _ in range(repeat):
        t = time.perf_counter()
        a @ a
        best = min(best, time.perf_counter() - t)
    return 2 * n**3 / best / 1e9


def graph_errors(mesh, sources, targets, batch: int = 64) -> np.ndarray:
    """Edge-graph (Dijkstra) distance on ``mesh`` from ``sources[i]`` to ``targets[i]`` ``(m,)``.

    Sources are processed in batches sorted by their Euclidean distance to their target, each batch
    bounded (``limit``) by twice its largest Euclidean distance plus one edge; a target beyond that
    bound (a path much longer than the straight line) is reached by an unbounded search."""
    from scipy.sparse.csgraph import dijkstra

    from prodmaps.geodesics import edge_graph

    G = edge_graph(mesh)
    h = float(np.max(G.data))
    eu = np.linalg.norm(mesh.vertices[sources] - mesh.vertices[targets], axis=1)
    out = np.empty(sources.shape[0])
    order = np.argsort(eu, kind="stable")
    for s in range(0, order.size, batch):
        sel = order[s : s + batch]
        src, inv = np.unique(sources[sel], return_inverse=True)
        D = dijkstra(G, indices=src, limit=2.0 * eu[sel].max() + h)  # (b, n)
        out[sel] = D[inv, targets[sel]]
    for i in np.flatnonzero(~np.isfinite(out)):
        out[i] = dijkstra(G, indices=int(sources[i]))[targets[i]]
    return out


def main(argv=None) -> int:
    import prodmaps as pm
    from prodmaps.datasets import dataset_dir
    from prodmaps.mesh import subdivide_midpoint

    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--levels", type=int, default=4)
    ap.add_argument("--k", type=int, default=40, help="eigenpairs per shape (constant included)")
    ap.add_argument("--functions", type=int, default=100)
    ap.add_argument("--jobs", type=int, default=2, help="worker processes of the two eigenbases (1: serial)")
    ap.add_argument("--solver", default="auto", choices=("auto", "superlu", "cholesky"),
                    help="the eigensolver's sparse factorisation (auto: Cholesky with cholespy at this size)")
    ap.add_argument("--search", default="auto", choices=("auto", "exact", "approximate"),
                    help="the point map's nearest-neighbour search (auto: approximate with faiss at this size)")
    ap.add_argument("--p2p-sample", type=int, default=2000,
                    help="seeded target vertices on which the full point map is evaluated against the exact one")
    args = ap.parse_args(argv)
    shapes = dataset_dir("anny_humans") / "shapes"
    steps, t_all = {}, time.perf_counter()

    def step(name, fn):
        t = time.perf_counter()
        out = fn()
        steps[name] = {"s": round(time.perf_counter() - t, 2), "peak_gb": round(peak_gb(), 2)}
        print(f"[scale] {name}: {steps[name]}", file=sys.stderr, flush=True)
        return out

    def pose(name):
        m = pm.load_mesh(shapes / f"{name}.ply")
        v, f = subdivide_midpoint(m.vertices, m.faces, levels=args.levels)
        return pm.Mesh(v, f)

    m1, m2 = step("subdivide", lambda: (pose("anny_000"), pose("anny_013")))
    assert np.array_equal(m1.faces, m2.faces)  # one triangulation: identity ground truth
    n = m1.n_vertices
    b1, b2 = step("eigenbases", lambda: pm.basis.eigenbases([m1, m2], args.k, jobs=args.jobs, solver=args.solver))
    k1, k2 = min(30, args.k), min(40, args.k)
    c1, c2 = b1.truncate(k1), b2.truncate(k2)
    idn = np.arange(n)
    C = pm.fmap_from_p2p(idn, c1, c2)  # (k2, k1) ground truth
    rng = np.random.default_rng(0)
    F = np.column_stack([m1.vertices, rng.normal(size=(n, args.functions - 3))])  # (n, functions)
    G_def = step("transfer_default", lambda: pm.transfer(F, C, c1, c2, "default"))
    err_def = pm.relative_error(G_def[:, :3], m2.vertices, c2.mass)
    del G_def
    fresh1, fresh2 = pm.Basis(c1.vecs, c1.evals, c1.mass), pm.Basis(c2.vecs, c2.evals, c2.mass)  # nothing cached
    G_b = step("transfer_approach_b", lambda: pm.transfer(F, C, fresh1, fresh2, "svd", rtol=1e-3, pairs="ordered"))
    err_b = pm.relative_error(G_b[:, :3], m2.vertices, c2.mass)
    del G_b
    p2p = step("p2p_std", lambda: pm.p2p.from_fmap(C, c1, c2, "std", search=args.search))  # (n,) all vertices
    pipeline = ("eigenbases", "transfer_default", "transfer_approach_b", "p2p_std")
    from prodmaps.eigensolver import CHOLESKY_MIN_N, have_cholesky
    from prodmaps.neighbors import APPROX_MIN_PAIRS, have_faiss
    out = {"n": n, "k": args.k, "k_M": k1 - 1, "k_N": k2 - 1, "functions": args.functions, "jobs": args.jobs,
           "solver": args.solver if args.solver != "auto" else
           ("cholesky" if have_cholesky() and n >= CHOLESKY_MIN_N else "superlu"),
           "search": args.search if args.search != "auto" else
           ("approximate" if have_faiss() and float(n) * n > APPROX_MIN_PAIRS else "exact"),
           "pipeline_s": round(sum(steps[s]["s"] for s in pipeline), 1), "steps": steps,
           "xyz_error_default": [round(float(e), 4) for e in err_def],
           "xyz_error_approach_b": [round(float(e), 4) for e in err_b]}
    if args.p2p_sample:
        ev = np.sort(np.random.default_rng(1).choice(n, min(args.p2p_sample, n), replace=False))
        exact = step("p2p_exact_sample", lambda: pm.p2p.from_fmap(C, c1, c2, "std", vertices=ev, search="exact"))
        out["p2p_sample"] = int(ev.size)
        out["p2p_recall"] = round(float(np.mean(p2p[ev] == exact)), 4)
        out["p2p_identity_share"] = {"full": round(float(np.mean(p2p[ev] == ev)), 4),
                                     "exact": round(float(np.mean(exact == ev)), 4)}
        out["p2p_exact_all_s_extrapolated"] = round(steps["p2p_exact_sample"]["s"] * n / ev.size, 0)

        def geodesic():
            e_full = graph_errors(m1, ev, p2p[ev]) / np.sqrt(m1.area)
            e_exact = graph_errors(m1, ev, exact) / np.sqrt(m1.area)
            return e_full, e_exact

        e_full, e_exact = step("p2p_geodesic_eval", geodesic)
        out["p2p_geodesic_error"] = {"full": round(float(e_full.mean()), 6), "exact": round(float(e_exact.mean()), 6),
                                     "cost": round(float(e_full.mean() - e_exact.mean()), 6),
                                     "metric": "edge-graph distance on shape 1 / sqrt(area), vs the identity"}
    # the extended conversion: canonical dimension r ~ the product basis' retained singular values
    K2 = 1 + (k2 - 1) + (k2 - 1) * k2 // 2  # unique pairs of shape 2's extended basis
    r = min(K2, 800)
    out["extended_p2p_estimate"] = {
        "dim": r, "flop_brute_force": 2.0 * n * n * r, "gemm_gflops": round(gemm_gflops(), 1),
        "hours_at_gemm_rate": round(2.0 * n * n * r / (gemm_gflops() * 1e9) / 3600, 1)}
    out["total_s"] = round(time.perf_counter() - t_all, 1)
    out["peak_gb"] = round(peak_gb(), 2)
    # while the workers ran, the main process held the meshes only (its peak up to then): the
    # machine's peak is at most the larger of the main process's overall peak and that plus the
    # workers' (each at most the largest one's)
    out["peak_worker_gb"] = round(peak_children_gb(), 2)
    during = steps["eigenbases"]["peak_gb"] + args.jobs * peak_children_gb()
    bound = max(peak_gb(), during) if args.jobs > 1 else peak_gb()
    out["peak_machine_gb_bound"] = round(bound, 2)
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
