"""Which reading of each function family is the paper's? A study with the standard columns as the control.

Section 5.1 names its function families (heat kernels, HKS, WKS, random combinations of the
extended basis, indicators of random regions, SHOT, AWFT) without their parameters: times,
region sizes, coefficient laws, support radii. The standard transfer (``std``) uses no products,
so its published columns are a **control**: if our functions were the paper's, our ``std``
columns would match the published ones whatever the product methods do. This study runs the
ground-truth tables (1, 3, 5, 6) with every reading of every family
(:data:`prodmaps.experiments.shared.families.READINGS`), all readings on the same pairs with the same
random draws (a family's seed does not depend on its reading), and scores each by the published
cells it reproduces within ±0.02, ``std`` first, then Approach B (``our_B``).

**Choice rule** (:func:`choose`): per family, the reading with the most ``std`` cells within
±0.02, ties broken by the smaller mean ``|diff|`` of the ``std`` cells (at two decimals), then by
the closeness to the definition's text (the order of the readings). Families the text defines as
the same functions (:data:`~prodmaps.experiments.shared.families.TIED_READINGS`: hk k and hk K, one heat
kernel under two truncations) take one reading, chosen by their ``std`` cells together
(:func:`choose_all`). Approach B's cells never enter the choice; they are reported beside it.

Conventions: ``k_M``, ``k_N`` are the paper's counts (non-constant functions); the maps are the
ground truth ``C_12 = Φ2ᵀ A2 Φ1[p2p_21]``; errors are the paper's area-weighted relative L2,
averaged over a family's functions, then over pairs.
"""

from __future__ import annotations

import time

import numpy as np

from .shared import families as pfam
from .shared.protocol import PAPER_COLUMNS, ProtocolSettings, run_protocol, standard_error
from .shared.published import DRAW_Z, WITHIN, published_values, score_cells, within_draw_noise, within_published
from .shared.results import to_jsonable

__all__ = ["GROUPS", "family_readings_study", "choose", "choose_all", "score_table", "draw_noise",
           "reading_summary", "summary_rows", "summary_text", "report_blocks", "figure"]

# the ground-truth tables, grouped by the basis size of the basis-dependent families (the largest
# k_M of each table, as the tables compute them)
GROUPS = {"T1": [(9, 9)], "T3": [(6, 7), (27, 35)], "T5+T6": [(29, 29), (29, 39)]}
_TABLE_OF = {(9, 9): "T1", (6, 7): "T3", (27, 35): "T3", (29, 29): "T5", (29, 39): "T6"}
METHODS = ("std", "our_B")


def _published_cells(sizes) -> dict:
    """``{(k_M, k_N, stage, method, label): value}`` of the ground-truth tables at ``sizes``."""
    return {c: v for z in map(tuple, sizes) for c, v in published_values(_TABLE_OF[z], "ground_truth").items()
            if (c[0], c[1]) == z and c[3] in METHODS}


def family_readings_study(store, pairs, *, readings: dict | None = None, groups: dict | None = None,
                          seed: int = 0, progress: bool = True) -> dict:
    """Run the ground-truth tables with every reading of every family; returns the results document.

    Parameters
    ----------
    store : :class:`prodmaps.experiments.shared.store.ShapeStore` of the dataset.
    pairs : list of ``(source id, target id)``.
    readings : ``{family: [reading name, ...]}`` (default: every reading of
        :data:`prodmaps.experiments.shared.families.READINGS`).
    groups : ``{name: [(k_M, k_N), ...]}`` sizes run together (default :data:`GROUPS`); a group's
        basis-dependent families use its largest ``k_M``.
    seed : the experiment seed (:func:`prodmaps.experiments.shared.families.family_seed`).

    Returns
    -------
    dict
        ``errors[family][reading]["k{k_M}_{k_N}"][stage][method]`` (means over pairs),
        ``standard_errors`` (the same keys: :func:`~prodmaps.experiments.shared.protocol.standard_error` of the
        per-pair means),
        ``scores[family][reading][method]`` (published cells, within ±0.02, mean and largest
        |diff|), ``chosen[family]`` (:func:`choose_all`), ``published_readings`` (the library's
        :data:`~prodmaps.experiments.shared.families.PUBLISHED_READINGS` with the textbook defaults),
        ``agrees`` (whether the study's choice is the library's), ``seconds``.
    """
    readings = {f: list(pfam.READINGS[f]) for f in pfam.FAMILIES} if readings is None else dict(readings)
    readings = {f: [r for r in pfam.READINGS[f] if r in readings[f]] for f in pfam.FAMILIES if f in readings}
    groups = dict(GROUPS if groups is None else groups)
    entries = [f"{fam}:{r}" for fam, names in readings.items() for r in names]
    t0 = time.perf_counter()
    errors: dict = {}
    sems: dict = {}
    for gname, sizes in groups.items():
        s = ProtocolSettings(sizes=[tuple(z) for z in sizes], map_kind="gt", families=entries,
                             columns={m: PAPER_COLUMNS[m] for m in ("std", "our_B")},
                             seed=seed, k_M_family=max(a for a, _ in sizes))
        res = run_protocol(store, pairs, s, progress=False)
        for z in s.sizes:
            key = f"k{z[0]}_{z[1]}"
            for st, by_m in res.errors[z].items():
                for lab, per_pair in by_m.items():
                    E = np.array(per_pair)  # (pairs, columns)
                    for entry, sl in res.cols.items():
                        fam, reading = pfam.split_entry(entry)
                        per_pair_means = E[:, sl].mean(axis=1)  # (pairs,)
                        (errors.setdefault(fam, {}).setdefault(reading, {}).setdefault(key, {})
                         .setdefault(st, {}))[lab] = float(per_pair_means.mean())
                        (sems.setdefault(fam, {}).setdefault(reading, {}).setdefault(key, {})
                         .setdefault(st, {}))[lab] = standard_error(per_pair_means)
        if progress:
            print(f"{gname}: {len(pairs)} pairs, {len(entries)} family readings, "
                  f"{time.perf_counter() - t0:.0f} s", flush=True)
    all_sizes = [tuple(z) for v in groups.values() for z in v]
    pub = _published_cells(all_sizes)
    errors = {fam: {r: errors[fam][r] for r in readings[fam] if r in errors.get(fam, {})}  # READINGS order
              for fam in pfam.FAMILIES if fam in errors}
    sems = {fam: {r: sems[fam][r] for r in by_r} for fam, by_r in errors.items()}
    scores = {fam: {r: score_table(errors[fam][r], pub, pfam.PAPER_LABELS[fam]) for r in errors[fam]}
              for fam in errors}
    chosen = choose_all(scores)
    library = {fam: pfam.PUBLISHED_READINGS.get(fam, "textbook") for fam in errors}
    return {"pairs": [list(p) for p in pairs], "groups": {g: [list(z) for z in v] for g, v in groups.items()},
            "readings": {fam: {r: to_jsonable(pfam.READINGS[fam][r]) for r in names}
                         for fam, names in readings.items()},
            "errors": errors, "standard_errors": sems, "scores": scores, "chosen": chosen,
            "published_readings": library,
            "agrees": {fam: chosen[fam] == library[fam] for fam in errors},
            "seconds": time.perf_counter() - t0}


def _cell_name(size_key: str, stage: str, method: str, label: str) -> str:
    a, b = map(int, size_key[1:].split("_"))
    return f"{label}, {_TABLE_OF.get((a, b), '?')} {a}/{b} {stage} {method}"


def draw_noise(results: dict) -> dict | None:
    """How much of the chosen readings' distance to the paper the draw of pairs and functions explains.

    Over the published ``std`` and ``our_B`` cells of the chosen readings (``results["chosen"]``):
    the standard errors ``SE`` of our cell means over the pairs (``results["standard_errors"]``),
    the cells missed (not :func:`~prodmaps.experiments.shared.published.within_published`), and which of
    those lie within the band of two independent draws
    (:func:`~prodmaps.experiments.shared.published.within_draw_noise`: ``0.02 + 2·√2·SE``).

    Returns ``{"n_pairs", "cells", "median_se", "max_se", "max_se_cell", "missed", "within_noise",
    "beyond": [(cell, diff, se), ...]}``, or None when the results carry no standard errors (one
    pair, or a results document written before they were kept).
    """
    sems = results.get("standard_errors")
    if not sems:
        return None
    sizes = [tuple(z) for v in results.get("groups", {}).values() for z in v]
    pub = _published_cells(sizes)
    ses, missed, beyond = [], 0, []
    for fam, reading in results["chosen"].items():
        label = pfam.PAPER_LABELS[fam]
        errs, se_r = results["errors"][fam][reading], sems.get(fam, {}).get(reading, {})
        for key, by_stage in errs.items():
            a, b = map(int, key[1:].split("_"))
            for st, by_m in by_stage.items():
                for m, ours in by_m.items():
                    p = pub.get((a, b, st, m, label))
                    se = se_r.get(key, {}).get(st, {}).get(m)
                    if p is None or se is None:
                        continue
                    ses.append((se, _cell_name(key, st, m, label)))
                    diff = ours - p
                    if not within_published(diff):
                        missed += 1
                        if not within_draw_noise(diff, se):
                            beyond.append((_cell_name(key, st, m, label), float(diff), float(se)))
    if not ses:
        return None
    top = max(ses)
    return {"n_pairs": len(results.get("pairs", [])), "cells": len(ses),
            "median_se": float(np.median([v for v, _ in ses])), "max_se": float(top[0]), "max_se_cell": top[1],
            "missed": missed, "within_noise": missed - len(beyond),
            "beyond": sorted(beyond, key=lambda c: -abs(c[1]))}


def reading_summary(results: dict) -> list[dict]:
    """Each family's reading as frozen in the library, scored on this run's data without choosing again.

    One row per family: ``reading`` (what was chosen: the family's parameters), ``alternatives``
    (readings scored), ``cells`` (the published ``std`` cells that judge it: the control),
    ``frozen`` (:data:`~prodmaps.experiments.shared.families.PUBLISHED_READINGS`, chosen on
    FAUST's eight registrations), its ``within`` / ``within_noise`` counts of those cells on this
    data (±0.02; ``0.02 + 2·√2·SE``), ``choice_here`` (what this data would choose) and
    ``agrees``. Run on a dataset the readings were not chosen on, this is their held-out check.
    """
    sems = results.get("standard_errors") or {}
    sizes = [tuple(z) for v in results.get("groups", {}).values() for z in v]
    pub = _published_cells(sizes)
    rows = []
    for fam, by_r in results.get("scores", {}).items():
        frozen = results["published_readings"][fam]
        if frozen not in by_r:
            continue
        label = pfam.PAPER_LABELS[fam]
        within = noise = cells = 0
        for key, by_stage in results["errors"][fam][frozen].items():
            a, b = map(int, key[1:].split("_"))
            for st, by_m in by_stage.items():
                p = pub.get((a, b, st, "std", label))
                if p is None or "std" not in by_m:
                    continue
                cells += 1
                diff = by_m["std"] - p
                se = sems.get(fam, {}).get(frozen, {}).get(key, {}).get(st, {}).get("std")
                within += int(within_published(diff))
                noise += int(within_published(diff) or (se is not None and within_draw_noise(diff, se)))
        rows.append({"reading": f"{label} parameters", "alternatives": len(by_r),
                     "cells": f"{cells} published std cells ({', '.join(sorted(set(_TABLE_OF[z] for z in sizes)))})",
                     "frozen": frozen, "cells_n": cells, "within": within, "within_noise": noise,
                     "choice_here": results["chosen"][fam], "agrees": bool(results["agrees"][fam])})
    return rows


def score_table(errors_by_size: dict, published: dict, label: str) -> dict:
    """Scores of one family reading: ``{method: {"cells", "within", "mean_abs", "max_abs"}}``.

    ``errors_by_size["k{k_M}_{k_N}"][stage][method]`` are our means; ``published`` the published
    cells ``{(k_M, k_N, stage, method, label): value}``; only the family's ``label`` counts.
    """
    ours = {(*map(int, key[1:].split("_")), st, m, label): v for key, by_stage in errors_by_size.items()
            for st, by_m in by_stage.items() for m, v in by_m.items()}
    return score_cells(ours, {c: v for c, v in published.items() if c[4] == label}, methods=METHODS)


def choose(scores_by_reading: dict, *tied: dict) -> str:
    """The reading with the most ``std`` cells within ±0.02; Approach B's cells are not used.

    Ties: the smaller mean |diff| of the ``std`` cells at the paper's two decimals (smaller differences
    are draw noise), then the order of :data:`~prodmaps.experiments.shared.families.READINGS` (the textbook
    first, then the readings closest to the definition's text). ``tied``: the score tables of
    families that take the same reading (:data:`~prodmaps.experiments.shared.families.TIED_READINGS`); the
    reading is then chosen among those they all have, by their ``std`` cells together (cells summed,
    mean |diff| over all of them).
    """
    tables = (scores_by_reading, *tied)
    order = [r for r in scores_by_reading if all(r in t for t in tied)]
    if not order:
        raise ValueError("choose: the tied families share no reading")

    def key(name):
        scs = [t[name].get("std") for t in tables]
        if any(sc is None or not sc["cells"] for sc in scs):
            return (0, np.inf, order.index(name))
        cells = sum(sc["cells"] for sc in scs)
        mean = sum(float(sc["mean_abs"]) * sc["cells"] for sc in scs) / cells
        return (-sum(sc["within"] for sc in scs), round(mean, 2), order.index(name))

    return min(order, key=key)


def choose_all(scores: dict) -> dict:
    """``{family: reading}`` by :func:`choose`; tied families are chosen together.

    The families of a :data:`~prodmaps.experiments.shared.families.TIED_READINGS` group (those scored)
    take the reading :func:`choose` gives for all of their ``std`` cells together.
    """
    chosen = {fam: choose(sc) for fam, sc in scores.items()}
    for group in pfam.TIED_READINGS:
        present = [f for f in group if f in scores]
        if len(present) > 1:
            reading = choose(*(scores[f] for f in present))
            chosen.update({f: reading for f in present})
    return chosen


def summary_rows(results: dict) -> list:
    """One row per family: textbook and chosen reading, with their ``std`` and ``our_B`` scores."""
    rows = []
    for fam, by_r in results["scores"].items():
        ch = results["chosen"][fam]

        def cell(r, m):
            v = by_r[r].get(m)
            return "—" if v is None else f"{v['within']}/{v['cells']} ({v['mean_abs']:.3f})"

        tb = "textbook" if "textbook" in by_r else next(iter(by_r))
        both_within = lambda r: sum(by_r[r][m]["within"] for m in METHODS if m in by_r[r])  # noqa: E731
        both_cells = lambda r: sum(by_r[r][m]["cells"] for m in METHODS if m in by_r[r])  # noqa: E731
        rows.append([pfam.PAPER_LABELS[fam], ch, cell(tb, "std"), cell(ch, "std"), cell(tb, "our_B"), cell(ch, "our_B"),
                     f"{both_within(tb)}/{both_cells(tb)} → {both_within(ch)}/{both_cells(ch)}",
                     "yes" if results["agrees"][fam] else f"no (library: {results['published_readings'][fam]})"])
    return rows


SUMMARY_HEADER = ["family", "chosen reading (std control)", "std textbook", "std chosen", "B textbook", "B chosen",
                  "cells within ±0.02", "library's reading"]


def report_blocks(results: dict, dataset: str, *, main: bool = True) -> list:
    """The study's section of the report, as ``(kind, *args)`` blocks: what the study shows.

    Blocks are ``("h", level, text)``, ``("p", text)``, ``("table", header, rows)``. ``dataset`` is the
    display name; the section is the same in the main report and in a per-dataset one (``main``); none
    without scores.
    """
    if not results.get("scores"):
        return []
    rows = summary_rows(results)
    n_pairs = len(results.get("pairs", []))
    tot = {k: sum(int(r[6].split(" → ")[i].split("/")[0]) for r in rows) for i, k in enumerate(("tb", "ch"))}
    cells = sum(int(r[6].split(" → ")[0].split("/")[1]) for r in rows)
    agree = [r[0] for r, fam in zip(rows, results["scores"]) if not results["agrees"][fam]]
    text = (f"Every plausible reading of the function families of Section 5.1 run on the ground-truth tables "
            f"(1, 3, 5, 6) on {dataset}, {n_pairs} pairs, all readings with the same random draws "
            f"(`study_family_readings`). The standard transfer uses no products, so its published column is the "
            f"control: a reading is chosen by the `std` cells it reproduces within ±{WITHIN:g}, never by Approach B's. "
            f"Over the families, the chosen readings reproduce {tot['ch']} of {cells} published `std` and Approach B "
            f"cells, the textbook definitions {tot['tb']}. ")
    for group in pfam.TIED_READINGS:
        present = [pfam.PAPER_LABELS[f] for f in group if f in results["scores"]]
        if len(present) > 1:
            text += (f"{' and '.join(present)}, which the text defines as the same functions, take one reading, "
                     f"chosen by their `std` cells together ({results['chosen'][group[0]]}). ")
    text += ("The study's choice is the library's `PUBLISHED_READINGS` for every family." if not agree else
             f"The study's choice differs from the library's for {', '.join(agree)}.")
    hks = results["scores"].get("HKS", {})
    if "textbook" in hks and results["chosen"].get("HKS") != "textbook":
        tb, ch = hks["textbook"].get("std", {}), hks[results["chosen"]["HKS"]].get("std", {})
        if tb and ch:
            text += (f" HKS differs in kind: the textbook HKS (SOG09) gives a `std` error far from the published one "
                     f"(mean |diff| {tb['mean_abs']:.2f}); the published numbers fit only an HKS dominated by the "
                     f"squares of the highest eigenfunctions ({results['chosen']['HKS']}: mean |diff| "
                     f"{ch['mean_abs']:.3f}). "
                     "The tables carry both and every claim is judged under both readings.")
    gaps = "Gaps that stay: the paper's 20 pairs and its draws of functions are unknown."
    noise = draw_noise(results)
    if noise is not None:
        gaps += (f" Draw noise, computed from the per-pair errors: the standard error of a cell's mean over the "
                 f"{noise['n_pairs']} pairs is {noise['median_se']:.3f} in the median cell of the chosen readings "
                 f"(largest {noise['max_se']:.3f}: {noise['max_se_cell']}). Taking the paper's means to be as noisy "
                 f"as ours, a difference between the two has a standard error √2 times as large. Of the "
                 f"{noise['missed']} cells the chosen readings miss by more than ±{WITHIN:g}, "
                 f"{noise['within_noise']} lie within {WITHIN:g} + {DRAW_Z:g}·√2·SE of the published value (two "
                 f"independent draws, about 95 %)")
        if noise["beyond"]:
            gaps += ("; the others differ by more than the draw explains: " +
                     "; ".join(f"{c} ({d:+.3f}, SE {e:.3f})" for c, d, e in noise["beyond"]) + ".")
        else:
            gaps += "; none lies beyond it."
    chosen_std = {fam: by_r[results["chosen"][fam]].get("std", {}) for fam, by_r in results["scores"].items()}
    poor = [pfam.PAPER_LABELS[fam] for fam, sc in chosen_std.items() if 2 * sc.get("within", 0) < sc.get("cells", 0)]
    if poor:
        gaps += (f" No reading tried reproduces half of the `std` cells of {', '.join(poor)}: their definitions "
                 "leave more open than the readings cover.")
    return [("h", 2, f"Study: the function families as the paper computed them, judged on {dataset}"), ("p", text),
            ("table", SUMMARY_HEADER, rows), ("p", gaps)]


def summary_text(results: dict) -> str:
    """:func:`summary_rows` as a plain-text table (for the notebook)."""
    rows = [SUMMARY_HEADER] + summary_rows(results)
    w = [max(len(str(r[i])) for r in rows) for i in range(len(SUMMARY_HEADER))]
    return "\n".join("  ".join(f"{str(c):<{w[i]}}" for i, c in enumerate(r)) for r in rows)


def figure(results: dict):
    """Per family, ``std`` cells within ±0.02 per reading (bars, the chosen one marked; Approach B's hatched)."""
    import matplotlib.pyplot as plt

    fams = list(results["scores"])
    fig, axes = plt.subplots(1, len(fams), figsize=(2.1 * len(fams), 4.2), sharey=True)
    for ax, fam in zip(np.atleast_1d(axes), fams):
        by_r = results["scores"][fam]
        names = list(by_r)
        std = [by_r[r].get("std", {}).get("within", 0) / max(by_r[r].get("std", {}).get("cells", 1), 1) for r in names]
        b = [by_r[r].get("our_B", {}).get("within", 0) / max(by_r[r].get("our_B", {}).get("cells", 1), 1)
             for r in names]
        x = np.arange(len(names))
        cols = ["tab:green" if r == results["chosen"][fam] else "0.6" for r in names]
        ax.bar(x - 0.2, std, 0.4, color=cols, label="std (control)")
        ax.bar(x + 0.2, b, 0.4, color="none", edgecolor="tab:blue", hatch="//", label="B")
        ax.set_xticks(x, names, rotation=60, ha="right", fontsize=6)
        ax.set_title(pfam.PAPER_LABELS[fam], fontsize=9)
        ax.set_ylim(0, 1)
    np.atleast_1d(axes)[0].set_ylabel(f"published cells within ±{WITHIN:g}")
    np.atleast_1d(axes)[0].legend(fontsize=7, loc="upper left")
    fig.tight_layout()
    return fig
