"""The study of Approach B's truncation threshold (and Approach A's ε): why ``rtol = 1e-3`` hurts.

For each pair, size ``(k_M, k_N)`` and map (ground truth / NO17), every threshold ``rtol`` and
ridge weight ``ε`` is applied as filter factors on the singular directions ``v_i`` of
``sqrt(A1) B1`` (one eigendecomposition per source basis): truncation keeps ``σ_i > rtol·σ_max``,
ridge weights ``σ_i² / (σ_i² + ε σ_max²)``. Measured per family:

* ``approx`` / ``transfer``: relative errors of the approximation and of the transfer;
* ``map_part``: ``||B2 C~ a - (B1 a)∘p2p|| / ||g||`` — the transfer of the approximation against its
  exact pull-back (uses the ground truth: diagnosis only);
* ``coef_norm``: ``||a||₂`` in the ordered convention;
* the transfer gains ``||B2 C~ v_i|| / σ_i`` of the directions (no ground truth) and the median over
  pairs of the largest gain kept at each ``rtol``;
* the map's deviation from product preservation for the basis functions and their products;
* the thresholds chosen without ground truth (``select_rtol``: gain rule, hold-out CV, GCV) and the
  oracle (best candidate, uses the ground truth), with their transfer errors.
"""

from __future__ import annotations

import time

import numpy as np

from .. import datasets, truncation
from ..approx import PAPER_RTOL, column_weights
from ..metrics import relative_error
from ..p2p import fmap_from_p2p
from ..products import product_basis
from ..transfers import transfer_operator
from .shared import compare
from .shared import families as pfam
from .shared.maps import no17_demo_map
from .shared.parallel import map_by_source
from .shared.results import setup_matplotlib
from .shared.store import ShapeStore

__all__ = ["QUANTITIES", "CHOOSERS", "run", "report_blocks"]

QUANTITIES = ("approx", "transfer", "map_part", "coef_norm")
CHOOSERS = ("paper", "gain", "cv", "gcv", "oracle")


def _colnorm(X, mass):
    return np.sqrt(np.einsum("ij,ij->j", X, mass[:, None] * X))


def run(store: ShapeStore, pairs, *, sizes, map_kinds, families, rtols, eps_list, paper_rtol=PAPER_RTOL,
                     max_gain=2.0, no17_k_descr=128, seed=0, progress=True, workers: int | None = None) -> dict:
    """Run the study (module doc) and return its results document plus the raw gains.

    ``sizes`` are ``(k_M, k_N)`` (paper's counts); ``map_kinds`` a subset of ``("gt", "computed")``;
    basis-dependent families use the largest ``k_M``. Returns ``{"results": ..., "gains": {case: [(K_u, 2)
    arrays of (σ_i/σ_max, gain_i) per pair]}}``. ``workers``: processes computing the pairs
    (:func:`prodmaps.experiments.shared.parallel.map_tasks`; the pairs of one source in one task; the same
    numbers for any number).
    """
    sizes = [tuple(int(v) for v in s) for s in sizes]
    families = [f for f in pfam.FAMILIES if f in families]
    RT = np.array(sorted(float(r) for r in rtols))
    EPS = np.array(sorted(float(e) for e in eps_list))
    k_M_family = max(s[0] for s in sizes)
    cases = [(s, mk) for s in sizes for mk in map_kinds]

    R = {_case_key(*c): {f: {"rtol": {q: [] for q in QUANTITIES}, "eps": {q: [] for q in QUANTITIES}, "std": [],
                        "chosen": {k: {"rtol": [], "err": []} for k in CHOOSERS}} for f in families} for c in cases}
    GAINS = {_case_key(*c): [] for c in cases}
    PRESERVE = {_case_key(*c): {"linear": [], "products": []} for c in cases}
    pairs = [tuple(p) for p in pairs]
    opts = dict(sizes=sizes, map_kinds=list(map_kinds), families=families, RT=RT, EPS=EPS, k_M_family=k_M_family,
                paper_rtol=paper_rtol, max_gain=max_gain, no17_k_descr=no17_k_descr, seed=seed)
    for ip, (rec, seconds) in map_by_source(_study_pair, store, pairs, workers=workers, **opts):
        for key, by in rec.items():  # appended in the pairs' order, as one after the other
            GAINS[key].append(by["gains"])
            PRESERVE[key]["linear"].append(by["preserve"][0])
            PRESERVE[key]["products"].append(by["preserve"][1])
            for fam in families:
                o, r = R[key][fam], by[fam]
                o["std"].append(r["std"])
                for axis in ("rtol", "eps"):
                    for q in QUANTITIES:
                        o[axis][q].append(r[axis][q])
                for k, (rt, err) in r["chosen"].items():
                    o["chosen"][k]["rtol"].append(rt)
                    o["chosen"][k]["err"].append(err)
        if progress:
            sid1, sid2 = pairs[ip]
            print(f"pair {ip + 1}/{len(pairs)} {sid1} -> {sid2}: {seconds:.1f} s", flush=True)

    summary = {key: {pfam.PAPER_LABELS[fam]: {
        "std_transfer": float(np.mean(o["std"])),
        **{axis: {q: np.mean(o[axis][q], axis=0).tolist() for q in QUANTITIES} for axis in ("rtol", "eps")},
        "chosen": {k: {"rtol_geomean": float(np.exp(np.mean(np.log(v["rtol"])))), "transfer": float(np.mean(v["err"]))}
                   for k, v in o["chosen"].items()},
    } for fam, o in by_fam.items()} for key, by_fam in R.items()}
    gain_at = {key: {f"{r:g}": float(np.median([g[g[:, 0] > r, 1].max() for g in lst])) for r in RT}
               for key, lst in GAINS.items()}
    preserve = {k: {q: float(np.mean(v[q])) for q in v} for k, v in PRESERVE.items()}
    results = {
        "rtols": RT, "eps": EPS, "paper_rtol": paper_rtol, "max_gain": max_gain,
        "pairs": [list(p) for p in pairs], "summary": summary,
        "median_max_gain_of_kept_directions": gain_at, "product_preservation_deviation": preserve,
        "notes": {
            "map_part": "||B2 C~ a - (B1 a) o p2p|| / ||g||: transfer of the approximation vs its exact pull-back "
                        "(uses ground truth, diagnosis only)",
            "gain": "||B2 C~ v_i||_A2 / sigma_i for the singular directions v_i of sqrt(A1) B1 (no ground truth)",
            "chosen": "rtol picked by each rule (geometric mean over pairs) and the resulting mean transfer error; "
                      "oracle uses ground truth",
        },
    }
    return {"results": results, "gains": GAINS}


def _study_pair(store: ShapeStore, ip: int, sid1: str, sid2: str, *, sizes, map_kinds, families, RT, EPS,
                k_M_family, paper_rtol, max_gain, no17_k_descr, seed) -> tuple:
    """One pair of :func:`truncation_study`: ``({case: {"gains", "preserve", family: values}}, seconds)``."""
    t0 = time.perf_counter()
    out = {}
    gt = datasets.ground_truth(store.dataset, sid1, sid2)
    F, G, cols = store.family_functions(sid1, gt, ip, families, k_M=k_M_family, seed=seed)
    for s in sizes:
        kM, kN = s
        b1, b2 = store.basis(sid1, kM + 1), store.basis(sid2, kN + 1)
        ext1 = product_basis(b1)
        sig, V = truncation.singular_directions(b1)  # (K_u,), (K_u, K_u) of sqrt(A1) B_s D
        d = column_weights(ext1)  # the normalisation D (None: D = I)
        if d is not None:
            V = d[:, None] * V  # directions as solver coefficients: the function B_s D v_i
        rel, w = sig / sig[0], sig**2
        E = ext1.expand()  # (K, K_u) scaled-unique -> ordered
        BsV = ext1.solver_basis()[0] @ V  # (n1, K_u) the directions on the source
        EV = E @ V  # (K, K_u) their ordered coefficients
        coef = V.T @ ext1.solver_rmatmul(b1.apply_mass(F))  # (K_u, m) = sigma_i * (u_i^T sqrt(A) f)
        C_gt = fmap_from_p2p(gt, b1, b2)
        by_map = {}  # map kind -> (record, images of the directions (n2, K_u), std errors (m,), gain-rule rtol)
        for mk in map_kinds:
            rec = out[_case_key(s, mk)] = {}
            C = C_gt if mk == "gt" else no17_demo_map(store, sid1, sid2, gt, kM + 1, kN + 1, k_descr=no17_k_descr)
            op = transfer_operator(C, b1, b2, "svd", rtol=paper_rtol)  # the paper's B: C~ and the bases
            img = op.transfer_coefficients(EV)  # (n2, K_u) images B2 C~ of the directions (every filter is a mix)
            rec["gains"] = np.column_stack([rel, _colnorm(img, b2.mass) / np.maximum(sig, 1e-300)])
            Bo = ext1.matrix  # (n1, K1) product preservation of the basis functions and products
            imgs_o = op.transfer_coefficients(np.eye(ext1.K))  # (n2, K1) images of the basis and its products
            dev = _colnorm(imgs_o - Bo[gt], b2.mass) / np.maximum(_colnorm(Bo[gt], b2.mass), 1e-300)
            rec["preserve"] = (float(np.mean(dev[ext1.degree == 1])), float(np.mean(dev[ext1.degree == 2])))
            std_tr = relative_error(transfer_operator(C, b1, b2, "std")(F), G, b2.mass)
            r_gain = truncation.select_rtol(b1, method="gain", C_12=C, basis_2=b2, candidates=RT, max_gain=max_gain)
            by_map[mk] = (rec, img, std_tr, r_gain)
        for fam in families:
            sl = cols[fam]
            Fm, Gm, cf = F[:, sl], G[:, sl], coef[:, sl]
            m = cf.shape[1]

            def per_filter(v, nf):
                return v.reshape(nf, m).mean(axis=1)

            def source_side(filters):
                """Filter factors (nf, K_u) -> (X, approximations, approx errors, coef norms): no map."""
                nf = len(filters)
                X = cf[:, None, :] * (filters / np.maximum(w, 1e-300)).T[:, :, None]  # (K_u, nf, m)
                X = X.reshape(cf.shape[0], nf * m)  # one GEMM for all filters
                app = BsV @ X  # = B1 E V X (n1, nf*m)
                return (X, app, per_filter(relative_error(app, np.tile(Fm, nf), b1.mass), nf),
                        per_filter(np.linalg.norm(EV @ X, axis=0), nf))

            def evaluate(src, img):
                """-> [(approx, transfer, map part, coef norm)] family means, one per filter."""
                X, app, approx, cnorm = src
                nf = X.shape[1] // m
                trf, Gt = img @ X, np.tile(Gm, nf)  # B2 C~ E V X (Lemma 2); Gt filter-major like X
                q = (approx, per_filter(relative_error(trf, Gt, b2.mass), nf),
                     per_filter(_colnorm(trf - app[gt], b2.mass) / _colnorm(Gt, b2.mass), nf), cnorm)
                return [tuple(float(x[i]) for x in q) for i in range(nf)]

            # the approximations do not depend on the map, nor do the rules that see only the source
            rt_src = source_side(np.array([(rel > r).astype(float) for r in RT]))
            eps_src = source_side(np.array([w / (w + e * w[0]) for e in EPS]))
            source_picks = {"cv": truncation.select_rtol(b1, Fm, method="cv", candidates=RT, seed=seed),
                            "gcv": truncation.select_rtol(b1, Fm, method="gcv", candidates=RT)}
            for mk in map_kinds:
                rec, img, std_tr, r_gain = by_map[mk]
                rt_vals, eps_vals = evaluate(rt_src, img), evaluate(eps_src, img)
                tr_err = np.array([v[1] for v in rt_vals])
                picks = {"paper": float(paper_rtol), "gain": r_gain, **source_picks,
                         "oracle": float(RT[int(np.argmin(tr_err))])}
                chosen = evaluate(source_side(np.array([(rel > r).astype(float) for r in picks.values()])), img)
                rec[fam] = {"std": float(std_tr[sl].mean()),
                            "rtol": {q: list(vals) for q, vals in zip(QUANTITIES, zip(*rt_vals))},
                            "eps": {q: list(vals) for q, vals in zip(QUANTITIES, zip(*eps_vals))},
                            "chosen": {k: (r, vals[1]) for (k, r), vals in zip(picks.items(), chosen)}}
    return out, time.perf_counter() - t0


def _case_key(s, mk) -> str:
    return f"k{s[0]}_{s[1]}/{mk}"


# ----------------------------------------------------------------------------- figures
def _figure_setup(summary: dict):
    """``(plt, {size: colour}, family labels)`` of the study's figures."""
    plt = setup_matplotlib()
    sizes = sorted({key.split("/")[0] for key in summary}, key=lambda s: [int(v) for v in s[1:].split("_")])
    cc = plt.cm.tab10(np.arange(len(sizes)))
    return plt, {s: cc[i] for i, s in enumerate(sizes)}, list(next(iter(summary.values())))


_LS = {"gt": "-", "computed": "--"}


def figure_error_vs_threshold(results: dict, axis_name: str, xlabel: str, mark: float):
    """Transfer error vs ``rtol`` or ridge ``ε`` (``axis_name``) per family; lines: std; stars: the gain rule."""
    summary = results["summary"]
    xs = results["rtols"] if axis_name == "rtol" else results["eps"]
    plt, color, labels = _figure_setup(summary)
    nc = min(3, len(labels))
    nr = int(np.ceil(len(labels) / nc))
    fig, axes = plt.subplots(nr, nc, figsize=(3.6 * nc, 2.7 * nr), squeeze=False)
    for i, lab in enumerate(labels):
        ax = axes[i // nc, i % nc]
        for key, by_fam in summary.items():
            d, mk, col = by_fam[lab], key.split("/")[1], color[key.split("/")[0]]
            ax.plot(xs, d[axis_name]["transfer"], _LS[mk], marker="o", ms=2.5, color=col, label=f"{key} products")
            ax.axhline(d["std_transfer"], ls=_LS[mk], color=col, lw=0.8, alpha=0.6)
            if axis_name == "rtol":
                g = d["chosen"]["gain"]
                ax.plot([g["rtol_geomean"]], [g["transfer"]], marker="*", ms=9, color=col, ls="none")
        ax.axvline(mark, color="k", lw=0.8, ls=":")
        ax.set(xscale="log", yscale="log")
        ax.set_title(lab, fontsize=8)
        ax.set_xlabel(xlabel, fontsize=7)
        ax.set_ylabel("transfer error", fontsize=7)
        if i == 0:
            ax.legend(fontsize=5.5)
    for j in range(len(labels), nr * nc):
        axes[j // nc, j % nc].axis("off")
    fig.suptitle(f"Transfer error vs {xlabel} (thin horizontal lines: standard transfer; dotted: paper's value; "
                 "star: 'gain' rule)", fontsize=8)
    fig.tight_layout()
    return fig


def figure_why(results: dict, gains: dict, families=("XYZ", "Indicator", "WKS")):
    """Left: transfer gains of the singular directions vs ``σ_i/σ_max``; right: the transfer error's split.

    The split is into its approximation and map parts vs ``rtol``, for two families.
    """
    summary, RT, paper_rtol = results["summary"], results["rtols"], results["paper_rtol"]
    plt, color, labels = _figure_setup(summary)
    fig, axes = plt.subplots(1, 3, figsize=(12, 3.4))
    ax = axes[0]
    for key in summary:
        g = np.vstack(gains[key])
        g = g[g[:, 0] > 1e-6]
        g[:, 1] = np.clip(g[:, 1], 0.1, 1e4)  # (zero singular values: infinite gain)
        ax.scatter(g[:, 0], g[:, 1], s=3 if "gt" in key else 9, alpha=0.4, color=color[key.split("/")[0]],
                   marker="o" if "gt" in key else "x", linewidths=0.6, label=key)
    ax.axvline(paper_rtol, color="k", ls=":", lw=0.8)
    ax.axvline(1e-2, color="grey", ls=":", lw=0.8)
    ax.axhline(1.0, color="k", lw=0.6)
    ax.axhline(results["max_gain"], color="tab:red", lw=0.6, ls="--")
    ax.set(xscale="log", yscale="log", xlim=(1e-5, 1.1), ylim=(0.3, 1.5e4), xlabel="σ_i / σ_max (source direction)",
           ylabel="transfer gain ||B2 C̃ v_i|| / σ_i")
    ax.set_title("transfer gain of singular directions", fontsize=8)
    ax.legend(fontsize=5.5, markerscale=3)
    for ax, lab in zip(axes[1:], [lb for lb in families if lb in labels][:2]):
        for key in summary:
            d, ls, col = summary[key][lab]["rtol"], _LS[key.split("/")[1]], color[key.split("/")[0]]
            ax.plot(RT, d["approx"], ls, color=col, lw=0.8, alpha=0.6)
            ax.plot(RT, d["map_part"], ls, color=col, marker="x", ms=3, lw=0.8)
            ax.plot(RT, d["transfer"], ls, color=col, marker="o", ms=3, label=key)
        ax.axvline(paper_rtol, color="k", ls=":", lw=0.8)
        ax.set(xscale="log", yscale="log", xlabel="rtol")
        ax.set_title(f"{lab}: total (o), map part (x), approximation (plain)", fontsize=8)
        ax.legend(fontsize=5.5)
    fig.tight_layout()
    return fig


def report_blocks(results: dict, dataset: str, *, main: bool = True) -> list:
    """The study's section of the report, as ``(kind, *args)`` blocks, computed from ``results``.

    Blocks are ``("h", level, text)``, ``("p", text)``, ``("ul", items)``: the transfer gains kept at the
    paper's threshold and how the gain rule compares with it. Shown once, with the report's own results
    (``main``); ``dataset`` (its display name) is not part of the text.
    """
    if not main:
        return []
    gains = results.get("median_max_gain_of_kept_directions", {})
    lines = [f"`{case}`: median over pairs of the largest transfer gain kept at rtol = 1e-3: "
             f"{g.get('0.001', float('nan')):.1f}; at 1e-2: {g.get('0.01', float('nan')):.1f}"
             for case, g in gains.items()]
    wins = {}
    for case, fams in results.get("summary", {}).items():
        for fam, v in fams.items():
            ch = v.get("chosen", {})
            if {"gain", "paper", "oracle"} <= set(ch):
                wins.setdefault(case, []).append((fam, ch["paper"]["transfer"], ch["gain"]["transfer"],
                                                  ch["oracle"]["transfer"], v["std_transfer"]))
    for case, rows in wins.items():
        better = sum(compare.not_higher(g, p) for _, p, g, _, _ in rows)
        near = sum(compare.not_higher(g, 1.1 * o) for _, _, g, o, _ in rows)
        below_std = sum(compare.not_higher(g, s) for _, _, g, _, s in rows)
        lines.append(f"`{case}`: the gain rule is at least as good as the paper's 1e-3 for {better} of {len(rows)} "
                     f"families, within 10 % of the oracle threshold for {near}, and below the standard transfer "
                     f"for {below_std}")
    return [("h", 2, "Study: Approach B's threshold, transfer gains, and a rule that does not need ground truth"),
            ("p", "Conclusion, computed from `study_truncation`'s numbers:"), ("ul", lines)]
