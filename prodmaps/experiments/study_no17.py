"""Study ``study_no17``: the computed-map recipe that reproduces Table 2's standard transfer column.

Table 2 (computed NO17 maps, ``k_M/k_N = 29/39``) prints, for the standard transfer
``Φ_N C Φ_Mᵀ A_M f``, errors close to those of the ground-truth map (Table 6): hk k 0.13 vs 0.09,
XYZ 0.13 vs 0.12, WKS 0.14 vs 0.13. hk k lies in the source basis' span, so its error measures the
map itself. :func:`score_recipes` computes, for every recipe of
:data:`prodmaps.experiments.shared.maps.RECIPES` asked for and every (source, target) pair, the map
(:func:`prodmaps.experiments.shared.maps.no17_fit`, timed), the standard-transfer relative error of the
five families of the column (the tables' functions, :meth:`ShapeStore.family_functions`) and the
map's own error: the mean geodesic error of its nearest-neighbour point map
(:func:`prodmaps.p2p.from_fmap`) normalised by ``sqrt(area)`` of the source
(:func:`prodmaps.geodesics.map_error`); the ground-truth map is scored alongside as the floor.
:func:`compare_published` sets every cell beside the published one.

Conventions: ``C_12`` ``(k2, k1)``, ``p2p_21`` ``(n2,)`` pulls back, sizes are the paper's counts
(``k + 1`` basis columns).
"""

from __future__ import annotations

import time

import numpy as np

from ..geodesics import map_error
from ..mapping import fmap_from_p2p
from ..metrics import relative_error
from ..p2p import from_fmap
from ..transfers import transfer_operator
from .shared import families as pfam
from .shared.maps import landmark_pairs, no17_fit, recipe
from .shared.parallel import map_by_source
from .shared.published import published_values, within_published
from .shared.store import ShapeStore

__all__ = ["FAMILIES", "score_recipes", "compare_published", "best_recipe", "reading_summary", "format_table",
           "figure"]

FAMILIES = ("hk_k", "XYZ", "WKS", "Random", "Indicator")  # the column's families, paper order of the issue


def score_recipes(store: ShapeStore, pairs, recipes, *, k_M: int = 29, k_N: int = 39, families=FAMILIES,
                  seed: int = 0, n_eval: int | None = None, progress: bool = True, workers: int | None = None) -> dict:
    """Score computed-map recipes by the standard transfer column and the map's geodesic error.

    Parameters
    ----------
    store : the dataset's :class:`ShapeStore` (``n_eig`` at least every recipe's ``k_descr``;
        larger counts are clipped to it).
    pairs : ``[(source id, target id), ...]``.
    recipes : names in :data:`prodmaps.experiments.shared.maps.RECIPES`.
    k_M, k_N : the paper's sizes (bases of ``k_M + 1`` and ``k_N + 1`` columns).
    families : families of :mod:`prodmaps.experiments.shared.families`; basis-dependent ones use
        ``k_M`` (as the tables at their largest ``k_M``); seeds as the tables'.
    n_eval : geodesic error on this many seeded target vertices (None: all).
    workers : processes computing the pairs (:func:`prodmaps.experiments.shared.parallel.map_tasks`; the
        pairs of one source in one task; the same numbers for any number).

    Returns
    -------
    dict with ``transfer[recipe][family]`` and ``geo_error[recipe]``: per-pair lists (pair
    order); ``"gt"`` is the ground-truth map; ``fit_seconds[recipe]`` per-pair fit times
    (descriptors, solve, refinement); ``families``, ``recipes``, ``pairs``, ``sizes``.
    """
    names = ["gt"] + [r for r in recipes]
    for r in recipes:
        recipe(r)  # unknown names fail before any work
    fams = [f for f in pfam.FAMILIES if f in families]
    out = {"transfer": {r: {f: [] for f in fams} for r in names}, "geo_error": {r: [] for r in names},
           "fit_seconds": {r: [] for r in recipes}, "families": fams, "recipes": list(recipes),
           "pairs": [list(p) for p in pairs], "sizes": [int(k_M), int(k_N)]}
    pairs = [tuple(p) for p in pairs]
    opts = dict(recipes=list(recipes), k1=int(k_M) + 1, k2=int(k_N) + 1, fams=fams, seed=seed, n_eval=n_eval)
    for ip, (transfer, geo, fit_seconds) in map_by_source(_score_pair, store, pairs, workers=workers, **opts):
        for r in names:
            for f in fams:
                out["transfer"][r][f].append(transfer[r][f])
            out["geo_error"][r].append(geo[r])
        for r in recipes:
            out["fit_seconds"][r].append(fit_seconds[r])
        if progress:
            s1, s2 = pairs[ip]
            print(f"pair {ip + 1:2d}/{len(pairs)} {s1} -> {s2}: "
                  + "  ".join(f"{r} hk_k {out['transfer'][r]['hk_k'][-1]:.3f} geo {out['geo_error'][r][-1]:.3f}"
                              for r in names if "hk_k" in fams), flush=True)
    return out


def _score_pair(store: ShapeStore, ip: int, s1: str, s2: str, *, recipes, k1: int, k2: int, fams, seed: int,
                n_eval) -> tuple:
    """One pair of :func:`score_recipes`."""
    from .. import datasets

    names = ["gt"] + list(recipes)
    gt = datasets.ground_truth(store.dataset, s1, s2)  # (n2,)
    F, G, cols = store.family_functions(s1, gt, ip, fams, k_M=k1 - 1, seed=seed)
    full_1, full_2 = store.basis(s1), store.basis(s2)
    b1, b2 = full_1.truncate(k1), full_2.truncate(k2)
    lm_cache = {}
    maps = {"gt": fmap_from_p2p(gt, b1, b2)}
    fit_seconds = {}
    for r in recipes:
        rec = recipe(r)
        lm = lm_cache.setdefault(rec.n_landmarks, landmark_pairs(store.mesh(s1).vertices, gt, rec.n_landmarks))
        t0 = time.perf_counter()
        maps[r] = no17_fit(full_1, full_2, lm, k1, k2, rec)
        fit_seconds[r] = time.perf_counter() - t0
    errs = {r: relative_error(transfer_operator(maps[r], b1, b2, "std")(F), G, b2.mass) for r in names}  # (m,) each
    transfer = {r: {f: float(np.mean(e[cols[f]])) for f in fams} for r, e in errs.items()}
    idx = np.arange(b2.n)
    if n_eval is not None and n_eval < b2.n:
        idx = np.sort(np.random.default_rng([seed, ip]).choice(b2.n, int(n_eval), replace=False))
    p2p = np.stack([from_fmap(maps[r], b1, b2, "std", vertices=idx) for r in names])  # (len(names), n_eval)
    geo = map_error(store.mesh(s1), p2p, gt[idx], rows=store.distance_rows(s1)).mean(axis=1)  # (len(names),)
    return transfer, {r: float(g) for r, g in zip(names, geo)}, fit_seconds


def compare_published(scores: dict, table: str = "T2", fmap: str = "computed_NO17") -> dict:
    """Every recipe's mean per family beside the published standard-transfer value.

    Returns ``{"rows": [{recipe, family, ours, published, diff}], "summary": {recipe: {"mean_abs",
    "max_abs", "within_0.03", "cells", "geo_error", "fit_seconds"}}}``; ``mean_abs``/``max_abs``
    over the families with a published value, ``within_0.03`` counts cells within ±0.03.
    """
    k_M, k_N = scores["sizes"]
    pub = published_values(table, fmap)
    rows, summary = [], {}
    for r in scores["transfer"]:
        diffs = []
        for f in scores["families"]:
            ours = float(np.mean(scores["transfer"][r][f]))
            p = pub.get((k_M, k_N, "transfer", "std", pfam.PAPER_LABELS[f]))
            d = None if p is None else ours - p
            rows.append({"recipe": r, "family": f, "ours": ours, "published": p, "diff": d})
            if d is not None:
                diffs.append(abs(d))
        summary[r] = {"mean_abs": float(np.mean(diffs)) if diffs else None,
                      "max_abs": float(np.max(diffs)) if diffs else None,
                      "within_0.03": int(sum(d <= 0.03 + 1e-12 for d in diffs)), "cells": len(diffs),
                      "geo_error": float(np.mean(scores["geo_error"][r])),
                      "fit_mean_seconds": (float(np.mean(scores["fit_seconds"][r]))
                                           if r in scores["fit_seconds"] else None)}
    return {"rows": rows, "summary": summary}


def best_recipe(comparison: dict) -> str:
    """The computed recipe (not ``"gt"``) with the smallest mean |ours − published| (ties: the first)."""
    cands = [(v["mean_abs"], r) for r, v in comparison["summary"].items() if r != "gt" and v["mean_abs"] is not None]
    if not cands:
        raise ValueError("no computed recipe with published cells to compare")
    return min(cands, key=lambda t: t[0])[1]


def reading_summary(results: dict) -> list[dict]:
    """The NO17 recipe as frozen in the library, scored on this run's data without choosing again.

    One row (the fields of :func:`prodmaps.experiments.study_family_readings.reading_summary`): the
    paper profiles' recipe (:data:`~prodmaps.experiments.shared.maps.DEFAULT_RECIPE`, chosen on
    FAUST's eight registrations by Table 2's standard column, a control), its cells within ±0.02
    here, and the recipe this data would choose (:func:`best_recipe`).
    """
    comp, frozen = results.get("comparison"), results.get("default_recipe")
    if not comp or frozen not in comp.get("summary", {}):
        return []
    diffs = [abs(r["diff"]) for r in comp["rows"] if r["recipe"] == frozen and r["diff"] is not None]
    choice = best_recipe(comp)
    return [{"reading": "NO17 recipe", "alternatives": sum(r != "gt" for r in comp["summary"]),
             "cells": f"{len(diffs)} published std cells (T2)", "frozen": frozen, "cells_n": len(diffs),
             "within": int(sum(map(within_published, diffs))), "within_noise": None, "choice_here": choice,
             "agrees": choice == frozen}]


def format_table(comparison: dict) -> str:
    """One line per recipe: ``ours (published) diff`` per family, the geodesic error, the fit time."""
    fams = list(dict.fromkeys(row["family"] for row in comparison["rows"]))
    lines = [f"{'recipe':14s} " + " ".join(f"{pfam.PAPER_LABELS[f]:>18s}" for f in fams) + "  geo err  fit s"]
    for r, s in comparison["summary"].items():
        cells = {row["family"]: row for row in comparison["rows"] if row["recipe"] == r}
        parts = []
        for f in fams:
            c = cells[f]
            pub = "  - " if c["published"] is None else f"{c['published']:.2f}"
            diff = "     " if c["diff"] is None else f"{c['diff']:+.2f}"
            parts.append(f"{c['ours']:6.3f} ({pub}) {diff}")
        fit = "    -" if s["fit_mean_seconds"] is None else f"{s['fit_mean_seconds']:5.2f}"
        lines.append(f"{r:14s} " + " ".join(parts) + f"  {s['geo_error']:.4f}  {fit}")
    return "\n".join(lines)


def figure(scores: dict, comparison: dict, dataset: str):
    """Bars per family (recipes side by side, published as a line) and the maps' geodesic errors."""
    import matplotlib.pyplot as plt

    names = list(scores["transfer"])
    fams = scores["families"]
    fig, (ax, ax2) = plt.subplots(1, 2, figsize=(12, 4), gridspec_kw={"width_ratios": [3, 1]})
    w = 0.8 / len(names)
    x = np.arange(len(fams))
    for i, r in enumerate(names):
        ax.bar(x + i * w, [np.mean(scores["transfer"][r][f]) for f in fams], w, label=r)
    pub = {row["family"]: row["published"] for row in comparison["rows"] if row["recipe"] == names[0]}
    for j, f in enumerate(fams):
        if pub.get(f) is not None:
            ax.hlines(pub[f], x[j] - 0.1, x[j] + 0.9, colors="k", linestyles="--")
    ax.set_xticks(x + 0.4 - w / 2, [pfam.PAPER_LABELS[f] for f in fams])
    ax.set_ylabel("std transfer error (dashed: published T2)")
    ax.set_title(f"Table 2 standard column, k_M/k_N = {scores['sizes'][0]}/{scores['sizes'][1]} ({dataset})")
    ax.legend(fontsize=7)
    ax2.bar(range(len(names)), [np.mean(scores["geo_error"][r]) for r in names])
    ax2.set_xticks(range(len(names)), names, rotation=60, fontsize=7)
    ax2.set_ylabel("mean geodesic error / sqrt(area)")
    fig.tight_layout()
    return fig
