"""Tables 1–6 of the paper: settings, the protocol run, our values beside the published ones.

``TABLES`` holds the paper's settings (Section 5.1 and the appendix): which map (ground truth or
NO17), which sizes ``(k_M, k_N)`` (the paper's counts, non-constant functions) and which columns
(labels of :data:`prodmaps.experiments.shared.protocol.PAPER_COLUMNS`, each a transfer of the registry).
:func:`run_table` runs :func:`prodmaps.experiments.shared.protocol.run_protocol` and returns the
results document the tables notebook writes; :func:`write_table_files` writes the CSV/JSON
files; :func:`table_figure` draws ours beside the published values.
"""

from __future__ import annotations

import csv
import json
import time
from pathlib import Path

import numpy as np

from .. import datasets
from ..approx import DEFAULT_NORMALIZATION
from ..files import atomic_path
from .shared import families as pfam
from .shared.compare import count_outcomes, outcome
from .shared.maps import DEFAULT_RECIPE
from .shared.protocol import (
    ProtocolSettings,
    approach_a_label,
    family_means,
    family_per_pair,
    run_protocol,
    with_parameters,
)
from .shared.published import published_values, within_draw_noise, within_published
from .shared.results import to_jsonable

__all__ = ["TABLES", "FMAP_NAMES", "resolve_table", "table_columns", "run_table", "held_out_rows", "write_table_files",
           "table_figure"]

TABLES = {
    "T1": {"map_kind": "gt", "k_M": [9], "k_N": [9], "columns": ["std", "our_l1", "our_l2", "our_B"]},
    "T2": {"map_kind": "computed", "k_M": [29], "k_N": [39], "columns": ["std", "our_A", "our_B"]},
    "T3": {"map_kind": "gt", "k_M": [6, 27], "k_N": [7, 35], "columns": ["std", "our_B"]},
    "T4": {"map_kind": "computed", "k_M": [9], "k_N": [9], "columns": ["std", "our_A", "our_B"]},
    "T5": {"map_kind": "gt", "k_M": [29], "k_N": [29], "columns": ["std", "our_A", "our_B"]},
    "T6": {"map_kind": "gt", "k_M": [29], "k_N": [39], "columns": ["std", "our_A", "our_B"]},
}
FMAP_NAMES = {"gt": "ground_truth", "computed": "computed_NO17"}


def resolve_table(table: str | None, params: dict) -> dict:
    """The run's parameters: ``params`` (profile values and overrides) over the table's settings.

    Validates them (the knobs of the tables notebook: ``columns`` among the table's, ``k_M``,
    ``k_N``, ``families``, ``family_reading``, ``extra_rtol``).
    """
    if table is not None and table not in TABLES:
        raise ValueError(f"table must be one of {sorted(TABLES)} or None, got {table!r}")
    P = {**params, **{k: v for k, v in (TABLES[table] if table else {}).items() if params.get(k) is None}}
    for key in ("k_M", "k_N"):
        if P.get(key) is None:
            raise ValueError(f"{key} is required when table=None")
        P[key] = [int(v) for v in np.atleast_1d(P[key])]
    if len(P["k_M"]) != len(P["k_N"]):
        raise ValueError(f"k_M and k_N must have the same length, got {P['k_M']} and {P['k_N']}")
    P["families"] = pfam.sort_entries(P["families"])  # paper order; "name:reading" entries allowed
    P["family_reading"] = P.get("family_reading") or "published"
    if P["family_reading"] not in pfam.READING_SETS:
        raise ValueError(f"family_reading must be one of {pfam.READING_SETS}, got {P['family_reading']!r}")
    P["extra_rtol"] = [float(r) for r in (P.get("extra_rtol") or []) if float(r) != float(P["rtol"])]
    return P


def table_columns(P: dict, table: str | None) -> dict:
    """The columns the table runs, ``{label: (registry method, parameters)}``, from the knobs ``P``.

    The table's own (``P["columns"]``: ``std``, ``our_l1``, Approach A as ``our_l2`` in Table 1 and
    ``our_A`` after it, ``our_B``), then beside the paper: Approach B at the ``extra_rtol``
    thresholds (``our_B_rtol<r>``), with the gain rule (``our_B_gainrule``), the library's default
    (``our_default``) and the transfer through a point map (``p2p_transfer``); every extended
    column with ``pairs=P["pairs_convention"]``.
    """
    a = approach_a_label(table)
    specs = {"std": ("std", {}), "our_l1": ("lasso", {"eps": P["eps_lasso"], "max_iter": P["lasso_max_iter"]}),
             a: ("ridge", {"eps": P["eps_ridge"]}), "our_B": ("svd", {"rtol": P["rtol"]})}
    unknown = [c for c in P["columns"] if c not in specs]
    if unknown:
        raise ValueError(f"columns must be among {list(specs)} for table {table!r}, got {unknown}")
    cols = {lab: specs[lab] for lab in P["columns"]}
    cols |= {f"our_B_rtol{r:g}": ("svd", {"rtol": r}) for r in P["extra_rtol"]}
    if P.get("gain_rule"):
        cols["our_B_gainrule"] = ("svd_gain", {"max_gain": P["max_gain"]})
    for lab, method in (("our_default", "default"), ("p2p_transfer", "p2p")):
        if P.get(f"{method}_method", True):
            cols[lab] = (method, {})
    return with_parameters(cols, pairs=P["pairs_convention"])


def run_table(store, pairs, table: str | None, P: dict, *, seed: int = 0, progress: bool = True) -> dict:
    """Run the protocol of one table; returns ``{"results", "ours", "spread", "published", ...}``.

    ``results`` is the notebook's results document (errors per size/stage/method/family, the
    entries matched to the published table, per-pair map deviations, Approach B ranks, gain-rule
    thresholds, timings). ``errors_per_pair[size][stage][column][family]`` (and
    ``errors_per_pair_intra`` / ``_inter``) lists each pair's mean over the family's functions, in
    the order of ``pairs`` (restricted to the kind), for the ledger's paired comparisons;
    ``seconds["per_column"][size][column]`` each pair's wall time of every column.
    """
    t_start = time.perf_counter()
    columns = table_columns(P, table)
    settings = ProtocolSettings(
        sizes=list(zip(P["k_M"], P["k_N"])), map_kind=P["map_kind"], families=P["families"], columns=columns,
        no17_k_descr=P["no17_k_descr"], seed=seed, family_reading=P["family_reading"])
    res = run_protocol(store, pairs, settings, progress=progress)
    means = family_means(res)
    ours = {k: v[0] for k, v in means.items()}
    spread = {k: v[1] for k, v in means.items()}
    fmap = FMAP_NAMES[P["map_kind"]]
    pub = published_values(table, fmap) if table else {}
    sizes, rows = settings.sizes, [pfam.entry_label(f, settings.family_reading) for f in settings.families]
    prod_labels = [lab for lab in columns if lab != "std"]

    def skey(s):
        return f"k{s[0]}_{s[1]}"

    labels = list(columns)

    def nested(values):  # {size: {stage: {method: {family: value}}}}
        return {skey(s): {st: {lab: {r: values[(s[0], s[1], st, lab, r)] for r in rows} for lab in labels}
                          for st in ("approx", "transfer")} for s in sizes}

    kinds = np.array([datasets.shape_class(store.dataset, a) == datasets.shape_class(store.dataset, b)
                      for a, b in res.pairs])  # True: intra-subject pair
    by_kind, n_kind, per_pair = {}, {}, {"": nested(family_per_pair(res))}
    for kind, mask in (("intra", kinds), ("inter", ~kinds)):
        n_kind[kind] = int(mask.sum())
        if mask.any():
            by_kind[kind] = nested({k: v[0] for k, v in family_means(res, pairs_mask=mask).items()})
            per_pair[f"_{kind}"] = nested(family_per_pair(res, pairs_mask=mask))
    all_cols, pub_cols = _col_order(k[:4] for k in ours), _col_order(k[:4] for k in pub)
    shown = [c for c in pub_cols if c in all_cols] if pub_cols else all_cols  # the published table's, if any
    n_pairs = len(res.pairs)  # the mean's standard error from the population std (family_means)
    se = {k: float(v / np.sqrt(n_pairs - 1)) if n_pairs > 1 else None for k, v in spread.items()}
    entries = [{"table": int(table[1:]), "fmap": fmap, "k_M": c[0], "k_N": c[1], "function": r, "stage": c[2],
                "method": c[3], "value": ours[c + (r,)], "se": se[c + (r,)]}
               for c in shown for r in rows if table and c + (r,) in pub]
    better = {}
    for s, lab, r in ((s, lab, r) for s in sizes for lab in prod_labels for r in rows):
        o, st = ours[(s[0], s[1], "transfer", lab, r)], ours[(s[0], s[1], "transfer", "std", r)]
        better[f"k{s[0]}_{s[1]}/{lab}/{r}"] = {"ours": o, "std": st, "ratio": o / st, "outcome": outcome(o, st)}
    n_better = {lab: count_outcomes((v["ours"], v["std"]) for k, v in better.items() if f"/{lab}/" in k)
                for lab in prod_labels}  # {"better": n, "tie": n, "worse": n}; ties never count as wins
    results = {
        "table_name": table or "custom",
        "fmap": fmap,
        "settings": [list(s) for s in sizes],
        "pairs": [list(p) for p in res.pairs],
        "errors": nested(ours),
        "errors_std_over_pairs": nested(spread),
        **{f"errors_{kind}": e for kind, e in by_kind.items()},
        **{f"errors_per_pair{sub}": e for sub, e in per_pair.items()},  # the pairs' family means, pair order
        "n_pairs_by_kind": n_kind,
        "table": entries,
        "products_better_than_std": better,
        "n_products_better": n_better,
        "map_deviation_from_gt": {skey(s): {"mean": float(np.mean(res.map_deviation[s])),
                                            "per_pair": res.map_deviation[s]} for s in sizes},
        "approach_B_rank_kept": {skey(s): res.ranks[s].get("our_B", []) for s in sizes},
        "gain_rule_rtol": {skey(s): res.gain_rtol[s].get("our_B_gainrule", []) for s in sizes},
        "seconds": {"total": time.perf_counter() - t_start, "per_pair": res.seconds,
                    "per_column": {skey(s): res.column_seconds[s] for s in sizes}},  # {size: {label: per pair}}
    }
    return {"results": results, "ours": ours, "spread": spread, "published": pub, "rows": rows,
            "shown_columns": shown, "all_columns": all_cols, "protocol": res}


GT_TABLES = ("T1", "T3", "T5", "T6")  # the ground-truth tables, whose std cells judge the function families
READING_CELLS = {"normalisation": ("our_B", GT_TABLES), "NO17 recipe": ("std", ("T2",))}


def held_out_rows(table_results: dict) -> list[dict]:
    """Every frozen reading scored by the tables of one dataset, as the library runs them (no choice made).

    ``table_results`` maps ``"T1"`` .. ``"T6"`` to the ``results`` of :func:`run_table` on one
    dataset (any subset). One row per reading, with the published cells that judge it: each
    function family's parameters (:data:`~prodmaps.experiments.shared.families.PUBLISHED_READINGS`)
    by its ``std`` cells of the ground-truth tables (the control no product method touches),
    Approach B's normalisation by the ``our_B`` cells of those tables, the NO17 recipe by Table
    2's ``std`` cells. Fields: ``reading``, ``frozen``, ``alternatives`` (readings the library
    scored; None for the normalisation and the recipe, whose studies list them), ``cells_n``,
    ``within`` (±0.02, as printed) and ``within_noise`` (within the draw noise of two independent
    draws, :func:`~prodmaps.experiments.shared.published.within_draw_noise`).
    Run on the data a reading was chosen on and on held-out data, the rows compare the two.
    """
    def score(method, tables, label=None):
        n = w = wn = 0
        for t in tables:
            res = table_results.get(t)
            if not res:
                continue
            pub = published_values(t, res["fmap"])
            for e in res["table"]:
                if e["method"] != method or (label is not None and e["function"] != label):
                    continue
                p = pub.get((e["k_M"], e["k_N"], e["stage"], e["method"], e["function"]))
                if p is None:
                    continue
                diff = e["value"] - p
                n += 1
                w += int(within_published(diff))
                wn += int(within_published(diff) or (e.get("se") is not None and within_draw_noise(diff, e["se"])))
        return n, w, wn

    rows = []
    for fam, reading in pfam.PUBLISHED_READINGS.items():
        n, w, wn = score("std", GT_TABLES, pfam.PAPER_LABELS[fam])
        if n:
            rows.append({"reading": f"{pfam.PAPER_LABELS[fam]} parameters", "frozen": reading,
                         "alternatives": len(pfam.READINGS[fam]), "cells_n": n, "within": w, "within_noise": wn})
    for name, (method, tables) in READING_CELLS.items():
        n, w, wn = score(method, tables)
        if n:  # the alternatives of these two are the studies' (their reading_summary)
            frozen = DEFAULT_NORMALIZATION if name == "normalisation" else DEFAULT_RECIPE
            rows.append({"reading": "Approach B's normalisation" if name == "normalisation" else name,
                         "frozen": frozen, "alternatives": None, "cells_n": n, "within": w, "within_noise": wn})
    return rows


def _col_order(keys) -> list:
    order = {"approx": 0, "transfer": 1}
    morder = {"std": 0, "our_l1": 1, "our_l2": 2, "our_A": 2, "our_B": 3}
    return sorted(set(keys), key=lambda c: (c[0], c[1], order[c[2]], morder.get(c[3], 4), c[3]))


def _col_name(c, multi: bool) -> str:
    return (f"k{c[0]}_{c[1]}_" if multi else "") + f"{c[2]}_{c[3]}"


def print_table(run: dict, name: str) -> None:
    """Ours with the published value in brackets, rows = functions."""
    ours, pub, shown = run["ours"], run["published"], run["shown_columns"]
    multi = len({c[:2] for c in shown}) > 1
    print(f"{'function':10s} " + " ".join(f"{_col_name(c, multi):>22s}" for c in shown))
    for r in run["rows"]:
        cells = [f"{ours.get(c + (r,)):8.3f}" + (f" [{pub[c + (r,)]:4.2f}]" if c + (r,) in pub else "       ") + " " * 7
                 for c in shown]
        print(f"{r:10s} " + " ".join(f"{x:>22s}" for x in cells))


def write_table_files(out_dir, run: dict, name: str) -> None:
    """``<name>_ours.csv`` (wide), ``<name>_vs_published.csv`` (long) and ``table.json``."""
    out = Path(out_dir)
    ours, spread, pub, rows = run["ours"], run["spread"], run["published"], run["rows"]
    all_cols = run["all_columns"]
    multi = len({c[:2] for c in all_cols}) > 1
    tnum = run["results"]["table_name"][1:] if run["results"]["table_name"] != "custom" else ""
    fmap = run["results"]["fmap"]
    with atomic_path(out / f"{name}_ours.csv") as tmp, open(tmp, "w", newline="") as fh:
        w = csv.writer(fh, lineterminator="\n")
        w.writerow(["function"] + [_col_name(c, multi) for c in all_cols])
        for r in rows:
            w.writerow([r] + [f"{ours[c + (r,)]:.6f}" for c in all_cols])
    long_rows = []
    for c in all_cols:
        for r in rows:
            p = pub.get(c + (r,))
            long_rows.append({"table": tnum, "fmap": fmap, "k_M": c[0], "k_N": c[1], "function": r,
                              "stage": c[2], "method": c[3], "ours": round(ours[c + (r,)], 6),
                              "ours_std_over_pairs": round(spread[c + (r,)], 6),
                              "published": "" if p is None else p,
                              "difference": "" if p is None else round(ours[c + (r,)] - p, 6)})
    with atomic_path(out / f"{name}_vs_published.csv") as tmp, open(tmp, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(long_rows[0]), lineterminator="\n")
        w.writeheader()
        w.writerows(long_rows)
    with atomic_path(out / "table.json") as tmp:
        tmp.write_text(json.dumps(to_jsonable(long_rows), indent=1) + "\n")


def table_figure(run: dict, name: str, dataset: str):
    """Heat map of ours (published in brackets); colour = ours - published; extra columns right."""
    import matplotlib.colors as mcolors

    from .shared.results import setup_matplotlib

    plt = setup_matplotlib()
    ours, pub, rows, shown = run["ours"], run["published"], run["rows"], run["shown_columns"]
    extra = [c for c in run["all_columns"]
             if c[2] == "transfer" and c[3] not in {s[3] for s in shown} and c[3] != "std"]
    plot_cols = shown + [c for c in extra if c not in shown]
    multi = len({c[:2] for c in plot_cols}) > 1
    vals = np.array([[ours[c + (r,)] for c in plot_cols] for r in rows])  # (rows, cols)
    pubv = np.array([[pub.get(c + (r,), np.nan) for c in plot_cols] for r in rows])

    def short(c):
        m = c[3].replace("our_", "").replace("_rtol", " rtol ").replace("_gainrule", " gain rule")
        return (f"{c[0]}/{c[1]}\n" if multi else "") + f"{c[2]}\n{m}"

    fig, ax = plt.subplots(figsize=(max(6.5, 0.95 * len(plot_cols) + 1.6), 0.36 * len(rows) + 1.7))
    diff = np.where(np.isnan(pubv), 0.0, vals - pubv)
    ax.imshow(np.clip(diff, -1.0, 1.0), cmap="RdBu_r", norm=mcolors.TwoSlopeNorm(vmin=-1.0, vcenter=0.0, vmax=1.0),
              aspect="auto", alpha=0.75)
    for i in range(len(rows)):
        for j in range(len(plot_cols)):
            txt = f"{vals[i, j]:.2f}" + ("" if np.isnan(pubv[i, j]) else f"\n({pubv[i, j]:.2f})")
            ax.text(j, i, txt, ha="center", va="center", fontsize=7,
                    color="white" if abs(diff[i, j]) > 0.7 else "black")
    if len(plot_cols) > len(shown):
        ax.axvline(len(shown) - 0.5, color="k", lw=1.5)
    ax.set_yticks(range(len(rows)), rows)
    ax.set_xticks(range(len(plot_cols)), [short(c) for c in plot_cols], fontsize=6.5)
    ax.xaxis.tick_top()
    sizes = run["results"]["settings"]
    ax.set_title(f"{name}: {run['results']['fmap']}, k_M/k_N = {', '.join(f'{a}/{b}' for a, b in sizes)}, "
                 f"{len(run['results']['pairs'])} pairs, {dataset}\n"
                 "ours (published); colour = ours - published; right of the bar: not in the paper", fontsize=8, pad=6)
    fig.tight_layout()
    return fig
