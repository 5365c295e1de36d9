"""Evidence for the library's default extended transfer: std vs paper-B vs gain rule vs default.

Over the conditions that matter — maps (ground truth, NO17, ground truth plus noise), sizes
``(k_M, k_N)`` (9/9, 29/39, 27/35, 6/7), pair kinds (intra-, inter-subject, and targets remeshed
with another connectivity) — and the nine function families, the relative transfer error of:
the columns ``std`` (the standard transfer), ``our_B`` (the paper's Approach B, ``rtol = 1e-3``),
``our_B_gainrule`` (Approach B with the threshold of the gain rule) and ``our_default``
(``method="default"`` of :mod:`prodmaps.transfers`).
Each condition runs :func:`prodmaps.experiments.shared.protocol.run_protocol` on its pairs, with the
basis-dependent families (hk k, HKS, WKS, Random) built from that condition's own ``k_M + 1``
source eigenpairs (as in Figure 11, so HKS and WKS lie in the product span); errors are averaged
over a family's functions, then the pairs.
"""

from __future__ import annotations

import time

import numpy as np

from .. import datasets
from .shared import compare
from .shared import families as pfam
from .shared.protocol import PAPER_COLUMNS, ProtocolSettings, family_means, run_protocol
from .shared.results import setup_matplotlib
from .shared.store import ShapeStore

__all__ = ["METHODS", "condition_key", "variant_pairs", "default_transfer_study", "single_function_excess", "summary",
           "figure", "report_blocks", "REPORT_NAMES"]

METHODS = ("std", "our_B", "our_B_gainrule", "our_default")
"""The study's columns (:data:`prodmaps.experiments.shared.protocol.PAPER_COLUMNS`)."""


def condition_key(map_kind: str, size, kind: str) -> str:
    """The results key ``"<map_kind>/<k1>_<k2>/<kind>"`` of one condition of the study."""
    return f"{map_kind}/{size[0]}_{size[1]}/{kind}"


def variant_pairs(dataset: str, n: int | None = None) -> list:
    """The first ``n`` ``(source, variant)`` pairs: each variant from its base shape and another pose of it."""
    out = []
    for vid in datasets.variants(dataset):
        base = datasets.base_shape(dataset, vid)
        cls = datasets.shape_class(dataset, base)
        other = next(s for s in datasets.shape_ids(dataset) if datasets.shape_class(dataset, s) == cls and s != base)
        out += [(base, vid), (other, vid)]
    return out[:n] if n is not None else out


def default_transfer_study(store: ShapeStore, pairs_by_kind: dict, *, map_kinds, sizes, families,
                           variant_sizes=None, variant_maps=("gt",), noise: float = 0.25, no17_k_descr: int = 128,
                           seed: int = 0, progress: bool = True) -> dict:
    """Run every condition (module doc); returns ``{"results": ..., "seconds": ...}``.

    ``pairs_by_kind`` maps a kind (``"intra"``, ``"inter"``, ``"variant"``) to its pairs; the
    ``"variant"`` pairs run at ``variant_sizes`` (default ``sizes``) with ``variant_maps``.
    ``results["errors"][condition][family label][method label]`` is the mean relative transfer
    error; ``results["approx"]`` the same for the approximation on the source.
    """
    t0 = time.perf_counter()
    errors, approx, n_pairs, single = {}, {}, {}, {}
    for kind, pairs in pairs_by_kind.items():
        if not pairs:
            continue
        kind_sizes = variant_sizes if (kind == "variant" and variant_sizes) else sizes
        maps = variant_maps if kind == "variant" else map_kinds
        for mk in maps:
            for size in kind_sizes:
                st = ProtocolSettings(sizes=[tuple(size)], map_kind=mk, families=families,
                                      columns={m: PAPER_COLUMNS[m] for m in METHODS},
                                      no17_k_descr=no17_k_descr, seed=seed, noise=noise, k_M_family=int(size[0]))
                if progress:
                    print(f"== {kind} pairs, {mk} maps, k_M/k_N = {size[0]}/{size[1]}", flush=True)
                res = run_protocol(store, pairs, st, progress=False)
                means = family_means(res)
                z = st.sizes[0]
                key = condition_key(mk, z, kind)
                n_pairs[key] = len(pairs)
                single[key] = single_function_excess(res, pairs)
                for stage, out in (("transfer", errors), ("approx", approx)):
                    out[key] = {pfam.PAPER_LABELS[f]: {m: means[(z[0], z[1], stage, m, pfam.PAPER_LABELS[f])][0]
                                                      for m in METHODS} for f in st.families}
    return {"results": {"errors": errors, "approx": approx, "n_pairs": n_pairs, "single": single,
                        "pairs": {k: [list(p) for p in v] for k, v in pairs_by_kind.items()},
                        "summary": summary(errors, single)},
            "seconds": time.perf_counter() - t0}


def single_function_excess(result, pairs) -> dict:
    """Per method: the worst single-function excess over the standard transfer in one condition.

    Every (pair, function column) is a cell: ``excess = error(method) - error(std)``.
    Returns ``{method label: {"worst_excess", "worst_family", "worst_pair", "above_0.01",
    "functions"}}`` (``functions`` = pairs x columns).
    """
    (z,) = result.settings.sizes
    by_m = result.errors[z]["transfer"]
    S = np.array(by_m["std"])  # (pairs, m)
    fam_of = np.empty(S.shape[1], dtype=object)
    for f, sl in result.cols.items():
        fam_of[sl] = pfam.PAPER_LABELS[f]
    out = {}
    for m in METHODS[1:]:
        M = np.array(by_m[m])  # (pairs, m)
        E = np.where(compare.tie_mask(M, S), 0.0, M - S)  # ties: 0
        i, j = np.unravel_index(int(np.argmax(E)), E.shape)
        out[m] = {"worst_excess": float(E[i, j]), "worst_family": str(fam_of[j]),
                                "worst_pair": list(pairs[i]), "above_0.01": int((E > 0.01).sum()),
                                "functions": int(E.size)}
    return out


def summary(errors: dict, single: dict | None = None) -> dict:
    """Worst (method - std) over every condition x family, cells above std + 0.01, mean ratios.

    With ``single`` (:func:`single_function_excess` per condition) the same per single function.
    """
    out = {}
    for m in ("our_B", "our_B_gainrule", "our_default"):
        # an excess between errors that tie (compare.is_tie: equal up to rounding, e.g. a function in
        # the source's span) is 0, so the worst cell is never picked by rounding noise
        d = [(c, f, 0.0 if compare.is_tie(v[m], v["std"]) else float(v[m] - v["std"]), v[m] / v["std"])
             for c, fams in errors.items() for f, v in fams.items()]
        worst = max(d, key=lambda x: x[2])
        out[m] = {"worst_excess": worst[2], "worst_cell": f"{worst[0]}/{worst[1]}",
                  "cells_above_std_plus_0.01": int(sum(x[2] > 0.01 for x in d)), "cells": len(d),
                  "mean_ratio_to_std": float(np.mean([x[3] for x in d])),
                  "ratio_of_means": float(np.mean([errors[c][f][m] for c, f, _, _ in d])
                                          / np.mean([errors[c][f]["std"] for c, f, _, _ in d]))}
        if single:
            w = max(single, key=lambda c: single[c][m]["worst_excess"])
            out[m].update({"single_worst_excess": single[w][m]["worst_excess"],
                           "single_worst_cell": f"{w}/{single[w][m]['worst_family']}/"
                                                f"{'->'.join(single[w][m]['worst_pair'])}",
                           "single_above_std_plus_0.01": int(sum(v[m]["above_0.01"] for v in single.values())),
                           "single_functions": int(sum(v[m]["functions"] for v in single.values()))})
    return out


def figure(results: dict):
    """Heat maps (paper B, gain rule, default) of log2(error / std's) per condition and family; blue below std."""
    import matplotlib.colors as mcolors

    plt = setup_matplotlib()
    errors = results["errors"]
    conds = list(errors)
    fams = list(next(iter(errors.values())))
    fig, axes = plt.subplots(1, 3, figsize=(15, 0.32 * len(conds) + 2.2), sharey=True)
    for ax, (m, title) in zip(axes, (("our_B", "paper's Approach B (rtol 1e-3)"),
                                     ("our_B_gainrule", "Approach B, gain-rule threshold"),
                                     ("our_default", "library default"))):
        R = np.array([[errors[c][f][m] / errors[c][f]["std"] for f in fams] for c in conds])
        ax.imshow(np.log2(R), cmap="RdBu_r", norm=mcolors.TwoSlopeNorm(vmin=-3, vcenter=0, vmax=3), aspect="auto")
        for i in range(len(conds)):
            for j in range(len(fams)):
                ax.text(j, i, f"{R[i, j]:.2f}", ha="center", va="center", fontsize=5.5,
                        color="white" if abs(np.log2(R[i, j])) > 2 else "black")
        ax.set_xticks(range(len(fams)), fams, fontsize=7, rotation=45)
        s = results["summary"][m]
        ax.set_title(f"{title}\nworst excess over std {s['worst_excess']:+.3f}, ratio of means "
                     f"{s['ratio_of_means']:.2f}", fontsize=8)
    axes[0].set_yticks(range(len(conds)), conds, fontsize=6.5)
    fig.suptitle("Transfer error / standard transfer's, per condition (map/k_M_k_N/pairs) and family", fontsize=9)
    fig.tight_layout()
    return fig


REPORT_NAMES = {"our_B": "paper B (rtol 1e-3)", "our_B_gainrule": "B with the gain rule", "our_default": "default"}
"""How the report names the extended methods of :func:`summary`."""


def report_blocks(results: dict, dataset: str, *, main: bool = True) -> list:
    """The study's section of the report, as ``(kind, *args)`` blocks, computed from ``results``.

    Blocks are ``("h", level, text)``, ``("p", text)``, ``("table", header, rows)``: per method, the cells
    and single functions worse than the standard transfer, and the conclusion on the default. ``dataset``
    is the display name, named in the heading of a per-dataset section (``main=False``); none without a
    summary.
    """
    summ = results.get("summary", {})
    if not summ:
        return []
    on = "" if main else f" on {dataset}"
    first = next(iter(summ.values()), {})
    n_cells = first.get("cells", 0)
    single = "single_functions" in first
    out = [("h", 2 if main else 3, f"Study: the library's default extended transfer against the standard one{on}"),
           ("p", f"Every condition (map kind, sizes, intra-/inter-subject or remeshed pairs) and family: {n_cells} "
                 "cells, each the mean error over its pairs (`study_default`)"
                 + (f"; and every single function of every pair: {first['single_functions']} functions"
                    if single else "")
                 + ". *Ratio of means*: mean error over all cells divided by the standard transfer's.")]
    rows = [[REPORT_NAMES.get(m, m), f"{v['cells_above_std_plus_0.01']} of {v['cells']}",
             f"{v['worst_excess']:+.4f} (`{v['worst_cell']}`)"]
            + ([f"{v['single_above_std_plus_0.01']} of {v['single_functions']}",
                f"{v['single_worst_excess']:+.4f} (`{v['single_worst_cell']}`)"] if single else [])
            + [f"{v['ratio_of_means']:.3f}", f"{v['mean_ratio_to_std']:.3f}"] for m, v in summ.items()]
    out.append(("table", ["method", "families worse than std + 0.01", "worst family excess over std"]
                + (["single functions worse than std + 0.01", "worst single function"] if single else [])
                + ["ratio of means", "mean ratio"], rows))
    dflt = summ.get("our_default")
    if dflt:
        n_bad = dflt["cells_above_std_plus_0.01"]
        where = "in no cell" if n_bad == 0 else f"in {n_bad} of {dflt['cells']} cells"
        text = (f"Conclusion, computed from the numbers: the default is worse than the standard transfer by more "
                f"than 0.01 {where} (worst {dflt['worst_excess']:+.4f})")
        if single:
            n1 = dflt["single_above_std_plus_0.01"]
            text += (", and for " + ("no single function" if n1 == 0 else f"{n1} of {dflt['single_functions']} "
                                     "single functions") + f" (worst {dflt['single_worst_excess']:+.4f})")
        out.append(("p", text + f"; its mean error is {dflt['ratio_of_means']:.2f} times the standard transfer's."))
    return out
