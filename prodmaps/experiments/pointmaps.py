"""Figures 12 and 13: point-to-point maps recovered from a functional map, standard vs extended.

A functional map ``C_12`` of shape ``(k_target, k_source)`` (the paper's 40×30: 40 columns of the
target basis, 30 of the source basis, constants included) is converted to ``p2p_21`` (for every
target vertex a source vertex) by :func:`prodmaps.p2p.from_fmap`, ``"std"`` (nearest neighbours of
``Φ2`` among ``Φ1 C_12ᵀ``) or ``"extended"`` (squared heat kernels compared through canonical
coefficients of the extended basis). Maps: ground truth (Figure 12) or NO17 (Figure 13,
:mod:`prodmaps.experiments.maps`). Error (Kim et al. 2011): heat-method geodesic distance on the
source between ``p2p_21[y]`` and the true image, divided by ``sqrt(area)``, on ``n_eval`` seeded
random target vertices per pair.
"""

from __future__ import annotations

import time

import numpy as np

from .. import datasets, geodesics
from ..mapping import fmap_from_p2p
from ..p2p import from_fmap
from .compare import count_outcomes
from .maps import no17_demo_map
from .parallel import map_by_source
from .store import ShapeStore

__all__ = ["subject_pairs", "point_map_recovery", "CONVERSIONS"]

CONVERSIONS = ("std", "extended")


def subject_pairs(dataset: str, subject, n_pairs=None, seed: int = 0) -> list:
    """All ordered pairs of poses of ``subject`` (or a seeded random subset of ``n_pairs``)."""
    all_pairs = [p for p in datasets.pairs(dataset, "intra") if datasets.shape_class(dataset, p[0]) == str(subject)]
    if not all_pairs:
        raise ValueError(f"no pairs for subject {subject!r} in {dataset!r}")
    if n_pairs is None:
        return all_pairs
    sel = np.sort(np.random.default_rng(seed).choice(len(all_pairs), int(n_pairs), replace=False))
    return [all_pairs[i] for i in sel]


def point_map_recovery(store: ShapeStore, pairs, *, k_target: int, k_source: int, maps=("gt", "no17"),
                       n_eval=None, no17_k_descr: int = 128, thresholds_max: float = 0.25, seed: int = 0,
                       verbose: bool = True, workers: int | None = None) -> dict:
    """Run Figures 12/13 (module doc); returns ``{"results": ..., "timing": ...}``.

    ``workers``: processes computing the pairs (:func:`prodmaps.experiments.parallel.map_tasks`;
    the pairs of one source shape go to one worker, which keeps its geodesic rows); the evaluated
    vertices are drawn here in the pairs' order, so the numbers do not depend on ``workers``.
    """
    bad = set(maps) - {"gt", "no17"}
    if bad:
        raise ValueError(f"maps must be a subset of ['gt', 'no17'], got {list(maps)}")
    rng = np.random.default_rng(seed)
    errs = {m: {c: [] for c in CONVERSIONS} for m in maps}  # per pair: (n_eval,) arrays
    per_pair, timing = [], {"std": 0.0, "extended": 0.0, "no17": 0.0}
    items = []  # (source id, (target id, evaluated target vertices)) per pair, drawn here in the pairs' order
    for s1, s2 in pairs:
        n2 = store.mesh(s2).n_vertices
        ev = np.arange(n2) if n_eval is None else np.sort(rng.choice(n2, int(n_eval), replace=False))
        items.append((s1, (s2, ev)))
    for _, (row, E, t_pair, t_parts) in map_by_source(_recovery_pair, store, items, k_target, k_source, tuple(maps),
                                                      no17_k_descr, workers=workers):
        for (m, method), e in E.items():
            errs[m][method].append(e)
        for key, v in t_parts.items():
            timing[key] += v
        per_pair.append(row)
        if verbose:
            print(f"{row['pair']}: " + "  ".join(f"{k} {v:.4f}" for k, v in row.items() if k != "pair")
                  + f"   [{t_pair:.1f} s]")
    thr = np.linspace(0.0, float(thresholds_max), 101)
    curves, means, wins = {}, {}, {}
    for m in maps:
        curves[m], means[m] = {}, {}
        for method in CONVERSIONS:
            allv = np.concatenate(errs[m][method])
            curves[m][method] = geodesics.error_curve(allv, thr)
            means[m][method] = float(allv.mean())
        wins[m] = count_outcomes((r[f"{m}_extended"], r[f"{m}_std"]) for r in per_pair)  # extended vs std
    results = {
        "error_definition": "geodesic distance on the source between recovered and true image "
        "/ sqrt(area of source); heat method",
        "map_size": {"k_target": k_target, "k_source": k_source, "C_shape": [k_target, k_source]},
        "pairs": [r["pair"] for r in per_pair],
        "mean_error": means,
        "extended_vs_std_pairs": wins,
        "per_pair": per_pair,
        "curves": {m: {"thresholds": thr, **curves[m]} for m in curves},
    }
    return {"results": results, "timing": timing}


def _recovery_pair(store: ShapeStore, ip: int, s1: str, item, k_target: int, k_source: int, maps,
                   no17_k_descr: int) -> tuple:
    """One pair ``s1 -> item[0]``, evaluated at the target vertices ``item[1]``: ``(row,
    {(map, conversion): errors (n_eval,)}, seconds, {"std"|"extended"|"no17": seconds})``."""
    s2, ev = item
    t0 = time.perf_counter()
    timing = {"std": 0.0, "extended": 0.0, "no17": 0.0}
    b1, b2 = store.basis(s1, k_source), store.basis(s2, k_target)
    gt = datasets.ground_truth(store.dataset, s1, s2)  # (n2,) target vertex -> source vertex
    row, recovered = {"pair": f"{s1}->{s2}"}, {}
    for m in maps:
        if m == "gt":
            C = fmap_from_p2p(gt, b1, b2)  # (k_target, k_source)
        else:
            t1 = time.perf_counter()
            C = no17_demo_map(store, s1, s2, gt, k_source, k_target, k_descr=no17_k_descr)
            timing["no17"] += time.perf_counter() - t1
        for method in CONVERSIONS:
            t1 = time.perf_counter()
            recovered[m, method] = from_fmap(C, b1, b2, method, vertices=ev)  # (n_eval,) target -> source vertex
            timing[method] += time.perf_counter() - t1
    # all maps of the pair against the same truth: geodesics from the true images computed once
    E = geodesics.map_error(store.mesh(s1), np.stack(list(recovered.values())), gt[ev],
                           rows=store.distance_rows(s1))  # (maps, n_eval)
    for (m, method), e in zip(recovered, E):
        row[f"{m}_{method}"] = float(e.mean())
    return row, dict(zip(recovered, E)), time.perf_counter() - t0, timing
