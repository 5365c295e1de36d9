"""Figures 12 and 13: point-to-point maps recovered from a functional map, standard vs extended.

A functional map ``C_12`` of shape ``(target_dim, source_dim)`` (the paper's 40×30: 40 columns of
the target basis, 30 of the source basis, constants included; in the paper's count ``k_N = 39``,
``k_M = 29``) is converted to ``p2p_21`` (for every
target vertex a source vertex) by :func:`prodmaps.p2p.from_fmap`, three conversions:

``"std"``                   nearest neighbours of ``Φ2`` among ``Φ1 C_12ᵀ`` [OBCS*12];
``"extended"``              Section 4.4: each point a squared heat kernel on the mesh from the store's
                            big basis (200 eigenpairs in the paper profile), fitted by the extended
                            basis' Approach B operator (rtol 1e-3, "euclidean"), sources through ``C̃``,
                            compared through canonical coefficients; ``t = 1/λ`` of the source's
                            last basis function;
``"extended_closed_form"``  the same kernel built in closed form from the map's own eigenpairs
                            (it cannot beat ``"std"``, see :mod:`prodmaps.p2p`).

Maps: ground truth (Figure 12) or NO17 (Figure 13,
:mod:`prodmaps.experiments.shared.maps`). Error (Kim et al. 2011): heat-method geodesic distance on the
source between ``p2p_21[y]`` and the true image, divided by ``sqrt(area)``, on ``n_eval`` seeded
random target vertices per pair (one draw per source shape, :func:`evaluation_vertices`).
"""

from __future__ import annotations

import time
import zlib

import numpy as np

from .. import datasets, geodesics
from ..mapping import fmap_from_p2p
from ..p2p import from_fmap
from .shared.compare import count_outcomes
from .shared.maps import no17_demo_map
from .shared.parallel import map_by_source
from .shared.store import ShapeStore

__all__ = ["subject_pairs", "point_map_recovery", "point_map_sweep", "reading_summary", "evaluation_vertices",
           "CONVERSIONS"]

CONVERSIONS = ("std", "extended", "extended_closed_form")


def subject_pairs(dataset: str, subject, n_pairs=None, seed: int = 0, *, both_directions: bool = True) -> list:
    """All pairs of poses of ``subject`` (or a seeded random subset of ``n_pairs``).

    ``both_directions``: each pair of shapes in both orders (``(a, b)`` and ``(b, a)``, two maps),
    else once (``a`` before ``b`` in the dataset's order: "all the possible pairs of shapes").
    """
    all_pairs = [p for p in datasets.pairs(dataset, "intra") if datasets.shape_class(dataset, p[0]) == str(subject)]
    if not both_directions:
        all_pairs = [p for p in all_pairs if p[0] < p[1]]
    if not all_pairs:
        raise ValueError(f"no pairs for subject {subject!r} in {dataset!r}")
    if n_pairs is None:
        return all_pairs
    sel = np.sort(np.random.default_rng(seed).choice(len(all_pairs), int(n_pairs), replace=False))
    return [all_pairs[i] for i in sel]


def point_map_recovery(store: ShapeStore, pairs, *, target_dim: int, source_dim: int, maps=("gt", "no17"),
                       n_eval=None, no17_k_descr: int = 128, thresholds_max: float = 0.25, seed: int = 0,
                       verbose: bool = True, workers: int | None = None) -> dict:
    """Run Figures 12/13 (module doc); returns ``{"results": ..., "timing": ...}``.

    ``target_dim``, ``source_dim``: the rows and columns of ``C_12``, basis columns with the
    constant (the paper's ``k_N + 1``, ``k_M + 1``); the results keep them as
    ``map_size.k_target`` / ``map_size.k_source`` (the baselines' keys).
    ``workers``: processes computing the pairs (:func:`prodmaps.experiments.shared.parallel.map_tasks`;
    the pairs of one source shape go to one worker, which keeps its geodesic rows); the evaluated
    vertices are drawn here, one seeded draw per source shape (:func:`evaluation_vertices`), so the
    numbers depend neither on ``workers`` nor on the pairs' order.
    """
    if set(maps) - {"gt", "no17"}:
        raise ValueError(f"maps must be a subset of ['gt', 'no17'], got {list(maps)}")
    errs = {m: {c: [] for c in CONVERSIONS} for m in maps}  # per pair: (n_eval,) arrays
    per_pair, timing = [], {**dict.fromkeys(CONVERSIONS, 0.0), "no17": 0.0}
    items = _evaluated(store, pairs, n_eval, seed)
    for _, (row, E, t_pair, t_parts) in map_by_source(_recovery_pair, store, items, target_dim, source_dim, tuple(maps),
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
    curves, means, wins, wins_closed = {}, {}, {}, {}
    for m in maps:
        curves[m], means[m] = {}, {}
        for method in CONVERSIONS:
            allv = np.concatenate(errs[m][method])
            curves[m][method] = geodesics.error_curve(allv, thr)
            means[m][method] = float(allv.mean())
        wins[m] = count_outcomes((r[f"{m}_extended"], r[f"{m}_std"]) for r in per_pair)  # extended vs std
        wins_closed[m] = count_outcomes((r[f"{m}_extended_closed_form"], r[f"{m}_std"]) for r in per_pair)
    results = {
        "error_definition": "geodesic distance on the source between recovered and true image "
        "/ sqrt(area of source); heat method",
        "map_size": {"k_target": target_dim, "k_source": source_dim, "C_shape": [target_dim, source_dim]},
        "pairs": [r["pair"] for r in per_pair],
        "mean_error": means,
        "conversions": {"std": "nearest neighbours of Φ2 among Φ1 Cᵀ [OBCS*12]",
                        "extended": "Section 4.4: squared heat kernel on the mesh from the basis' eigenpairs "
                                    "(store n_eig), Approach B rtol 1e-3 'euclidean', C~, canonical coefficients, "
                                    "t = 1/λ of the source's last basis function",
                        "extended_closed_form": "closed-form squared heat kernel from min(k1, k2) eigenpairs "
                                                "(before issue 33)"},
        "kernel_eigenpairs": int(store.n_eig),
        "extended_vs_std_pairs": wins,
        "closed_form_vs_std_pairs": wins_closed,
        "per_pair": per_pair,
        "curves": {m: {"thresholds": thr, **curves[m]} for m in curves},
    }
    return {"results": results, "timing": timing}


def _evaluated(store: ShapeStore, pairs, n_eval, seed: int) -> list:
    """``[(source id, (target id, evaluated target vertices))]`` per pair.

    ``n_eval`` target vertices drawn uniformly without replacement (all of them when ``n_eval`` is
    None), one seeded draw per source shape and target size (:func:`evaluation_vertices`): the
    pairs of one source evaluate the same vertex indices. Where the shapes correspond by vertex
    index (the ground truth of FAUST's registrations and of the embedded humans is the identity),
    their true images, the sources of the geodesic rows, are then the same ``n_eval`` vertices of
    the source shape, solved once for all its pairs (:class:`prodmaps.geodesics.DistanceRows`).
    """
    items = []
    for s1, s2 in pairs:
        n2 = store.mesh(s2).n_vertices
        ev = np.arange(n2) if n_eval is None else evaluation_vertices(n2, n_eval, seed, s1)
        items.append((s1, (s2, ev)))
    return items


def evaluation_vertices(n: int, n_eval: int, seed: int, source: str) -> np.ndarray:
    """``n_eval`` sorted distinct vertex indices of ``range(n)``, a seeded draw keyed by ``source`` (its name).

    The same ``(n, n_eval, seed, source)`` give the same vertices in any process and pair order
    (the key is the CRC-32 of the name, not Python's salted ``hash``).
    """
    if not 0 < int(n_eval) <= n:
        raise ValueError(f"n_eval must be in [1, {n}] (the target's vertices), got {n_eval}")
    rng = np.random.default_rng([int(seed), zlib.crc32(str(source).encode()), int(n)])
    return np.sort(rng.choice(n, int(n_eval), replace=False))


def _recovery_pair(store: ShapeStore, ip: int, s1: str, item, target_dim: int, source_dim: int, maps,
                   no17_k_descr: int) -> tuple:
    """One pair ``s1 -> item[0]``, evaluated at the target vertices ``item[1]``.

    Returns ``(row, {(map, conversion): errors (n_eval,)}, seconds, {conversion|"no17": seconds})``.
    The conversions get the store's whole bases: ``C`` uses their first ``source_dim``/``target_dim``
    columns, the extended conversion's heat kernel all of them.
    """
    s2, ev = item
    t0 = time.perf_counter()
    timing = {**dict.fromkeys(CONVERSIONS, 0.0), "no17": 0.0}
    B1, B2 = store.basis(s1), store.basis(s2)  # (n, n_eig) each
    b1, b2 = B1.truncate(source_dim), B2.truncate(target_dim)
    gt = datasets.ground_truth(store.dataset, s1, s2)  # (n2,) target vertex -> source vertex
    row, recovered = {"pair": f"{s1}->{s2}"}, {}
    for m in maps:
        if m == "gt":
            C = fmap_from_p2p(gt, b1, b2)  # (target_dim, source_dim)
        else:
            t1 = time.perf_counter()
            C = no17_demo_map(store, s1, s2, gt, source_dim, target_dim, k_descr=no17_k_descr)
            timing["no17"] += time.perf_counter() - t1
        for method in CONVERSIONS:
            t1 = time.perf_counter()
            recovered[m, method] = from_fmap(C, B1, B2, method, vertices=ev)  # (n_eval,) target -> source vertex
            timing[method] += time.perf_counter() - t1
    # all maps of the pair against the same truth: geodesics from the true images computed once
    E = geodesics.map_error(store.mesh(s1), np.stack(list(recovered.values())), gt[ev],
                           rows=store.distance_rows(s1))  # (maps, n_eval)
    for (m, method), e in zip(recovered, E):
        row[f"{m}_{method}"] = float(e.mean())
    return row, dict(zip(recovered, E)), time.perf_counter() - t0, timing


def point_map_sweep(store: ShapeStore, pairs, *, sizes=((40, 30),), t_scales=(1.0,), rtols=(1e-3,), n_eval=None,
                    seed: int = 0, workers: int | None = None) -> dict:
    """How far the extended conversion's gain depends on ``t``, ``rtol`` and the map's size.

    Ground-truth maps only. For every size ``(target_dim, source_dim)`` (basis columns with the
    constant, as in :func:`point_map_recovery`) the standard conversion and
    the extended one at every ``t_scale`` (``t = t_scale / λ`` of the source's last basis
    function) with ``rtol`` 1e-3, and at every ``rtol`` with ``t_scale = 1``. Returns
    ``{"rows": [{"size", "setting", "mean_error", "better_than_std": {"better", "tie", "worse"}}],
    "pairs": [...]}`` (mean geodesic error / sqrt(area) over the pairs' evaluated vertices).
    """
    items = _evaluated(store, pairs, n_eval, seed)
    settings = [("std", "std", {})]
    settings += [(f"extended t x{ts:g}", "extended", {"t_scale": float(ts)}) for ts in t_scales]
    settings += [(f"extended rtol {r:g}", "extended", {"rtol": float(r)}) for r in rtols if float(r) != 1e-3]
    sizes = list(dict.fromkeys((int(dim_t), int(dim_s)) for dim_t, dim_s in sizes))  # each size once
    per = {z: {name: [] for name, _, _ in settings} for z in sizes}
    # one pass over the pairs, every size in it: a source's geodesic rows serve all its sizes
    for _, means in map_by_source(_sweep_pair, store, items, sizes, settings, workers=workers):
        for z in sizes:
            for name, v in means[z].items():
                per[z][name].append(v)
    rows = [{"size": list(z), "setting": name, "mean_error": float(np.mean(per[z][name])),
             "better_than_std": count_outcomes(zip(per[z][name], per[z]["std"]))}
            for z in sizes for name, _, _ in settings]
    return {"rows": rows, "pairs": [f"{a}->{b}" for a, b in pairs]}


def _sweep_pair(store: ShapeStore, ip: int, s1: str, item, sizes, settings) -> dict:
    """One pair of :func:`point_map_sweep`: ``{(target_dim, source_dim): {setting: mean error}}``."""
    s2, ev = item
    B1, B2 = store.basis(s1), store.basis(s2)
    gt = datasets.ground_truth(store.dataset, s1, s2)
    out = {}
    for target_dim, source_dim in sizes:
        C = fmap_from_p2p(gt, B1.truncate(source_dim), B2.truncate(target_dim))  # (target_dim, source_dim)
        P = np.stack([from_fmap(C, B1, B2, method, vertices=ev, **kw) for _, method, kw in settings])
        E = geodesics.map_error(store.mesh(s1), P, gt[ev], rows=store.distance_rows(s1))  # (settings, n_eval)
        out[(target_dim, source_dim)] = {name: float(e.mean()) for (name, _, _), e in zip(settings, E)}
    return out


def reading_summary(results: dict, frozen: str = "extended t x1") -> list[dict]:
    """Section 4.4's heat time as frozen in the library (``t_scale = 1``), scored on this run's sweep.

    One row (the fields of :func:`prodmaps.experiments.study_family_readings.reading_summary`): the
    sweep's extended settings at the map size of Figures 12/13 (the first size swept), the frozen
    one's mean geodesic error and the setting this data would choose (smallest mean error); no
    published cells judge it (``cells_n`` 0).
    """
    rows = (results.get("sweep") or {}).get("rows", [])
    if not rows:
        return []
    size = rows[0]["size"]
    ext = {r["setting"]: r["mean_error"] for r in rows if r["size"] == size and r["setting"].startswith("extended t")}
    if frozen not in ext:
        return []
    choice = min(ext, key=ext.get)
    return [{"reading": "Section 4.4's heat time", "alternatives": len(ext),
             "cells": f"mean geodesic error of the extended point map ({size[0]}x{size[1]})", "frozen": frozen,
             "cells_n": 0, "within": None, "within_noise": None, "frozen_error": ext[frozen],
             "choice_here": choice, "agrees": choice == frozen}]
