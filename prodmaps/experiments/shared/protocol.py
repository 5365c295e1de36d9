"""The paper's transfer protocol (Section 5.1, Tables 1–6, Figures 8 and 11): pairs x sizes x columns.

For every (source, target) pair and size ``(k_M, k_N)`` (the paper's counts: non-constant
functions; bases have ``k + 1`` columns), the function families are generated on the source
(:mod:`prodmaps.experiments.shared.families`, ground truth ``G = F[p2p_21]``), approximated on the
source and transferred to the target with a functional map ``C_12`` (ground truth, perturbed or
NO17, :mod:`prodmaps.experiments.shared.maps`) by every **column**: a label (the tables' column name,
``"our_B"``) and a transfer of the registry with its parameters, ``("svd", {"rtol": PAPER_RTOL})``
(:data:`prodmaps.transfers.REGISTRY`; :data:`PAPER_COLUMNS` are the paper's). Each column's
operator is built once per pair and size by :func:`prodmaps.transfer_operator`; its
``approximate(F)`` and ``op(F)`` are the two stages. Errors are the paper's relative errors, per
function column; :func:`family_means` averages the columns of each family, then the pairs.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from ... import datasets
from ...approx import PAPER_RTOL
from ...mapping import fmap_from_p2p
from ...metrics import relative_error
from ...products import product_basis
from ...transfers import REGISTRY, transfer_operator
from . import families as pfam
from .maps import no17_demo_map
from .parallel import map_by_source
from .store import ShapeStore

__all__ = ["ProtocolSettings", "ProtocolResult", "run_protocol", "family_means", "family_per_pair", "standard_error",
           "perturbed_map", "check_columns", "with_parameters", "approach_a_label", "PAPER_COLUMNS", "STAGES"]

STAGES = ("approx", "transfer")
PAPER_COLUMNS = {
    "std": ("std", {}),
    "our_l1": ("lasso", {"eps": 1e-4, "max_iter": 5000}),  # Approach A, p = 1 (Table 1)
    "our_l2": ("ridge", {"eps": 1e-6}),  # Approach A, p = 2 (Table 1's name)
    "our_A": ("ridge", {"eps": 1e-6}),  # the same, Tables 2–6's name
    "our_B": ("svd", {"rtol": PAPER_RTOL}),  # Approach B
    "our_B_gainrule": ("svd_gain", {"max_gain": 2.0}),  # beside the paper: rtol from the map's gains
    "our_default": ("default", {}),  # beside the paper: the library's default extended transfer
    "p2p_transfer": ("p2p", {}),  # Section 5.1's remark: the map converted to a point map first
}
"""The paper's columns (and the package's beside them): label -> (registry method, parameters).

Approach A's weights are not in the paper: ridge ``eps = 1e-6`` (relative to ``σ_max²``) and lasso
``1e-4`` (relative to ``||Bᵀ A f||_∞``), fixed before measuring."""


def approach_a_label(table: str | None) -> str:
    """The paper's name of its Approach A (ridge) column: ``our_l2`` in Table 1, ``our_A`` after it."""
    return "our_l2" if table in (None, "T1") else "our_A"


def check_columns(columns) -> dict:
    """``columns`` as ``{label: (method, parameters)}``, checked against the registry.

    A ``"std"`` column (the standard transfer, every comparison's reference) is required; every
    method must be a registry name and its parameters ones it takes.

    >>> check_columns({"std": ("std", {}), "our_B": ("svd", {"rtol": 1e-2})})["our_B"]
    ('svd', {'rtol': 0.01})
    """
    out = {}
    for label, spec in dict(columns).items():
        try:
            method, params = spec
            params = dict(params)
        except (TypeError, ValueError):
            raise ValueError(f"column {label!r} must be (method, parameters), got {spec!r}") from None
        if method not in REGISTRY:
            raise ValueError(f"column {label!r}: method must be one of {tuple(REGISTRY)}, got {method!r}")
        unknown = set(params) - set(REGISTRY[method].parameters)
        if unknown:
            raise ValueError(f"column {label!r}: method {method!r} takes no parameter {sorted(unknown)} "
                             f"(its parameters: {', '.join(REGISTRY[method].parameters) or 'none'})")
        out[str(label)] = (method, params)
    if out.get("std", (None,))[0] != "std":
        raise ValueError(f"columns must hold the standard transfer as 'std': ('std', {{}}); got {list(out)}")
    return out


def with_parameters(columns: dict, **params) -> dict:
    """Every column whose method takes a parameter of ``params`` gets it (e.g. ``normalization``, ``pairs``).

    >>> with_parameters({"std": ("std", {}), "our_B": ("svd", {})}, pairs="unique")["our_B"]
    ('svd', {'pairs': 'unique'})
    """
    params = {k: v for k, v in params.items() if v is not None}
    return {lab: (m, {**p, **{k: v for k, v in params.items() if k in REGISTRY[m].parameters}})
            for lab, (m, p) in columns.items()}


@dataclass
class ProtocolSettings:
    """Parameters of :func:`run_protocol`.

    ``columns``: ``{label: (registry method, parameters)}`` (:data:`PAPER_COLUMNS`; default
    ``std`` and the paper's Approach B). ``map_kind``: ``"gt"``, ``"computed"`` (NO17) or
    ``"perturbed"`` (ground truth plus seeded noise of relative size ``noise``).
    """

    sizes: list  # [(k_M, k_N), ...] paper's counts
    map_kind: str = "gt"
    families: list = field(default_factory=lambda: list(pfam.FAMILIES))
    columns: dict = field(default_factory=lambda: {k: PAPER_COLUMNS[k] for k in ("std", "our_B")})
    no17_k_descr: int = 128
    seed: int = 0
    k_M_family: int | None = None  # basis size of the basis-dependent families (default: largest k_M)
    noise: float = 0.25
    family_reading: str = "published"  # as the paper computed them; "textbook": as defined (families.READINGS)

    def __post_init__(self):
        self.sizes = [(int(a), int(b)) for a, b in self.sizes]
        self.columns = check_columns(self.columns)
        self.families = pfam.sort_entries(self.families)  # paper order; "name:reading" entries allowed
        if self.family_reading not in pfam.READING_SETS:
            raise ValueError(f"family_reading must be one of {pfam.READING_SETS}, got {self.family_reading!r}")
        if self.map_kind not in ("gt", "computed", "perturbed"):
            raise ValueError(f"map_kind must be 'gt', 'computed' or 'perturbed', got {self.map_kind!r}")
        if self.k_M_family is None:
            self.k_M_family = max(a for a, _ in self.sizes)


@dataclass
class ProtocolResult:
    """Per-pair errors of :func:`run_protocol`.

    ``errors[(k_M, k_N)][stage][label]`` is a list (one entry per pair) of ``(m,)`` arrays of
    per-column relative errors; ``cols[family]`` the column slice of each family;
    ``ranks[(k_M, k_N)][label]`` the kept rank of every Approach B column and
    ``gain_rtol[(k_M, k_N)][label]`` the threshold of every gain-rule column, one entry per pair;
    ``column_seconds[(k_M, k_N)][label]`` the wall time of every column (building its operator,
    approximating and transferring the pair's functions), one entry per pair.
    """

    settings: ProtocolSettings
    pairs: list
    errors: dict
    cols: dict
    map_deviation: dict
    ranks: dict
    gain_rtol: dict
    seconds: list
    column_seconds: dict = field(default_factory=dict)


def run_protocol(store: ShapeStore, pairs, settings: ProtocolSettings, *, collect=None,
                 progress: bool = True, workers: int | None = None) -> ProtocolResult:
    """Run the protocol on ``pairs`` (list of ``(source id, target id)``) of ``store.dataset``.

    ``collect(pair_index, size, F, G, cols, b1, b2, outputs)`` (optional) receives, for every
    pair and size, the functions and ``outputs[label] = (approximation (n1, m), transfer (n2, m))``
    (e.g. for the area curves of Figure 8); it runs in this process, so the pairs are then
    computed here one after the other. A collector that splits its work into
    ``measure(pair_index, size, F, G, cols, b1, b2, outputs) -> record`` (pure, picklable, run
    with the pair, in a worker) and ``add(pair_index, size, record)`` (run here, in the pairs'
    order), as :class:`AreaCurves`, keeps the workers.

    ``workers``: processes computing the pairs (:func:`prodmaps.experiments.shared.parallel.map_tasks`;
    default ``$PRODMAPS_WORKERS`` or the CPUs). The pairs of one source shape go to one worker
    (they share its descriptors and extended-basis operators); every pair is computed with one
    BLAS thread, so the errors are the same for any number of workers.
    """
    s = settings
    pairs = [tuple(p) for p in pairs]
    errors = {z: {st: {lab: [] for lab in s.columns} for st in STAGES} for z in s.sizes}
    map_dev = {z: [] for z in s.sizes}
    ranks, gain_rtol, col_seconds = ({z: {} for z in s.sizes} for _ in range(3))
    cols, seconds = None, []
    split = _measures(collect)
    workers = 1 if collect is not None and not split else workers
    for ip, rec in map_by_source(_protocol_pair, store, pairs, s, collect, workers=workers):
        cols = rec["cols"]
        for z, by in rec["sizes"].items():
            if split:
                collect.add(ip, z, by.pop("collected"))
            map_dev[z].append(by["map_dev"])
            for key, acc in (("ranks", ranks), ("gain_rtol", gain_rtol), ("column_seconds", col_seconds)):
                for lab, v in by[key].items():
                    acc[z].setdefault(lab, []).append(v)
            for st in STAGES:
                for lab in s.columns:
                    errors[z][st][lab].append(by["errors"][st][lab])
        seconds.append(rec["seconds"])
        if progress:
            sid1, sid2 = pairs[ip]
            print(f"pair {ip + 1:2d}/{len(pairs)} {sid1} -> {sid2}: {seconds[-1]:5.1f} s"
                  + "".join(f"  [{kM}/{kN}] map dev {map_dev[(kM, kN)][-1]:.3f}" for kM, kN in s.sizes),
                  flush=True)
    return ProtocolResult(s, pairs, errors, cols, map_dev, ranks, gain_rtol, seconds, col_seconds)


def _measures(collect) -> bool:
    """Whether ``collect`` splits its work into ``measure`` (with the pair) and ``add`` (here)."""
    return collect is not None and callable(getattr(collect, "measure", None))


def _protocol_pair(store: ShapeStore, ip: int, sid1: str, sid2: str, s: ProtocolSettings, collect) -> dict:
    """One pair at every size: ``{"cols", "seconds", "sizes": {(k_M, k_N): {...}}}``.

    Each size holds ``"errors"`` (``errors[stage][label]`` the ``(m,)`` per-column errors),
    ``"map_dev"``, ``"ranks"``, ``"gain_rtol"`` and ``"column_seconds"`` (by column label).
    """
    t0 = time.perf_counter()
    gt = datasets.ground_truth(store.dataset, sid1, sid2)  # (n2,) target vertex -> source vertex
    F, G, cols = store.family_functions(sid1, gt, ip, s.families, k_M=s.k_M_family, seed=s.seed,
                                          reading_set=s.family_reading)
    sizes = {}
    for (kM, kN) in s.sizes:
        rec = {"errors": {st: {} for st in STAGES}, "ranks": {}, "gain_rtol": {}, "column_seconds": {}}
        b1, b2 = store.basis(sid1, kM + 1), store.basis(sid2, kN + 1)
        C_gt = fmap_from_p2p(gt, b1, b2)  # (kN+1, kM+1)
        if s.map_kind == "gt":
            C = C_gt
        elif s.map_kind == "perturbed":
            C = perturbed_map(C_gt, s.noise, seed=(s.seed, ip, kM, kN))
        else:
            C = no17_demo_map(store, sid1, sid2, gt, kM + 1, kN + 1, k_descr=s.no17_k_descr)
        rec["map_dev"] = float(np.linalg.norm(C - C_gt) / np.linalg.norm(C_gt))
        outputs = {}
        _warm_extended_basis(b1, s.columns)  # shared by the extended columns: not in any column's time
        for lab, (method, params) in s.columns.items():
            t_col = time.perf_counter()
            op = transfer_operator(C, b1, b2, method, **params)
            outputs[lab] = (op.approximate(F), op(F))  # (n1, m), (n2, m)
            rec["column_seconds"][lab] = time.perf_counter() - t_col
            if method in ("svd", "svd_gain"):
                rec["ranks"][lab] = op.rank
            if method == "svd_gain":
                rec["gain_rtol"][lab] = op.rtol
        for lab, (fa, ft) in outputs.items():
            rec["errors"]["approx"][lab] = relative_error(fa, F, b1.mass)
            rec["errors"]["transfer"][lab] = relative_error(ft, G, b2.mass)
        if _measures(collect):
            rec["collected"] = collect.measure(ip, (kM, kN), F, G, cols, b1, b2, outputs)
        elif collect is not None:
            collect(ip, (kM, kN), F, G, cols, b1, b2, outputs)
        sizes[(kM, kN)] = rec
    return {"cols": cols, "seconds": time.perf_counter() - t0, "sizes": sizes}


_EXTENDED = ("lasso", "ridge", "svd", "svd_gain")  # registry methods fitting in the source's extended basis


def _warm_extended_basis(b1, columns: dict) -> None:
    """Build the Gram matrix of the source's extended basis that every extended column shares (cached on it)."""
    for order, pairs in sorted({(p.get("order", REGISTRY[m].parameters["order"]),
                                 p.get("pairs", REGISTRY[m].parameters["pairs"]))
                                for m, p in columns.values() if m in _EXTENDED}):
        product_basis(b1, order, pairs).solver_gram()


def perturbed_map(C_gt: np.ndarray, noise: float, seed) -> np.ndarray:
    """``C_gt`` plus seeded Gaussian noise of relative Frobenius norm ``noise`` on the free columns.

    Column 0 (the constant's image, fixed for any point map) is kept; ``seed`` may be a tuple.
    """
    rng = np.random.default_rng(np.random.SeedSequence(np.atleast_1d(seed).tolist()))
    E = rng.standard_normal(C_gt.shape)
    E[:, 0] = 0.0
    return C_gt + noise * np.linalg.norm(C_gt) / np.linalg.norm(E) * E


def family_per_pair(result: ProtocolResult, pairs_mask=None) -> dict:
    """``{(k_M, k_N, stage, column label, paper family label): (pairs,) array}``: each pair's mean over the family.

    The values :func:`family_means` averages; a paired comparison of two columns over pairs
    (the claims ledger's criterion) takes them pair by pair. ``pairs_mask`` as in :func:`family_means`.
    """
    out = {}
    for z, by_stage in result.errors.items():
        for st, by_method in by_stage.items():
            for lab, per_pair in by_method.items():
                E = np.array(per_pair)  # (pairs, m_functions)
                if pairs_mask is not None:
                    E = E[np.asarray(pairs_mask, dtype=bool)]
                for fam in result.settings.families:
                    label = pfam.entry_label(fam, result.settings.family_reading)
                    out[(z[0], z[1], st, lab, label)] = E[:, result.cols[fam]].mean(axis=1)  # (pairs,)
    return out


def family_means(result: ProtocolResult, pairs_mask=None) -> dict:
    """``{(k_M, k_N, stage, column label, paper family label): (mean over pairs, std over pairs)}``.

    The std is the population one (``ddof=0``); over ``n`` pairs the mean's :func:`standard_error`
    is ``std / sqrt(n - 1)``. Each pair contributes the mean over the family's columns;
    ``pairs_mask`` (boolean, one entry per pair) restricts the average to some pairs (e.g. the intra-subject ones).
    """
    return {key: (float(per.mean()), float(per.std())) for key, per in family_per_pair(result, pairs_mask).items()}


def standard_error(values) -> float | None:
    """Standard error of the mean of ``values`` ``(n,)``: ``std(ddof=1) / sqrt(n)``; None when ``n < 2``.

    >>> round(standard_error([0.1, 0.3]), 12)
    0.1
    """
    v = np.asarray(values, dtype=np.float64).ravel()
    if v.size < 2:
        return None
    return float(v.std(ddof=1) / np.sqrt(v.size))
