"""The paper's transfer protocol (Section 5.1, Tables 1–6, Figure 8): pairs x sizes x methods.

For every (source, target) pair and size ``(k_M, k_N)`` (the paper's counts: non-constant
functions; bases have ``k + 1`` columns), the nine function families are generated on the
source (:mod:`prodmaps.experiments.families`, ground truth ``G = F[p2p_21]``), approximated on
the source and transferred to the target with a functional map ``C_12`` (ground truth or NO17,
:mod:`prodmaps.experiments.maps`) by every method:

``std``        A-orthogonal projection ``Φ1ᵀ A1 F``, transfer ``Φ2 C Φ1ᵀ A1 F``;
``l1``, ``l2`` Approach A (lasso by FISTA, ridge) in the extended basis, transfer ``B2 C~ a``;
               ``l2@<e>`` Approach A (ridge) at ``eps = e`` (relative to ``σ_max²``); ``l2n@<e>``
               Equation 4 as printed (norms, not squares; ``penalty="norm"``, ``e`` relative to ``σ_max``);
``B``          Approach B at the paper's ``rtol``; ``B@<r>`` Approach B at ``rtol = r``;
``B_gain``     Approach B with ``rtol`` from the map-based gain rule
               (:func:`prodmaps.truncation.select_rtol`, no ground truth);
``default``    the library's default extended transfer (``pm.transfer(..., method="default")``,
               :mod:`prodmaps.transfers`);
``p2p``        the map converted to a point map first (nearest neighbours, :func:`prodmaps.p2p.from_fmap`)
               and ``f`` pulled back through it (Section 5.1's remark; its "approximation" is the
               standard one).

Errors are the paper's relative errors, per function column; :func:`family_means` averages the
columns of each family, then the pairs.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from .. import truncation
from ..mapping import extend_fmap
from ..metrics import relative_error
from ..p2p import fmap_from_p2p
from ..products import product_basis
from ..transfers import transfer_operator
from . import families as pfam
from .maps import no17_demo_map
from .parallel import map_by_source
from .store import ShapeStore

__all__ = ["ProtocolSettings", "ProtocolResult", "run_protocol", "method_label", "family_means", "standard_error",
           "area_curves", "AreaCurves", "perturbed_map", "AREA_CRITERIA", "METHODS", "STAGES"]

METHODS = ("std", "l1", "l2", "B", "B_gain", "default", "p2p")  # plus "B@<rtol>", "l2@<eps>" and "l2n@<eps>"
_AT_METHODS = ("B@", "l2@", "l2n@")  # at another threshold (B), weight (ridge), or Equation 4's norms at a weight
STAGES = ("approx", "transfer")


@dataclass
class ProtocolSettings:
    """Parameters of :func:`run_protocol` (the paper's values are the defaults)."""

    sizes: list  # [(k_M, k_N), ...] paper's counts
    map_kind: str = "gt"  # "gt" | "computed" | "perturbed" (ground truth plus seeded noise)
    families: list = field(default_factory=lambda: list(pfam.FAMILIES))
    methods: list = field(default_factory=lambda: ["std", "B"])
    rtol: float = 1e-3
    eps_ridge: float = 1e-6
    eps_lasso: float = 1e-4
    lasso_max_iter: int = 5000
    pairs_convention: str = "ordered"
    max_gain: float = 2.0
    no17_k_descr: int = 128
    seed: int = 0
    k_M_family: int | None = None  # basis size of the basis-dependent families (default: largest k_M)
    noise: float = 0.25  # "perturbed": relative Frobenius size of the noise added to the ground-truth C
    normalization: str | None = None  # Approaches A/B (prodmaps.approx); None: the library's default
    family_reading: str = "published"  # as the paper computed them; "textbook": as defined (families.READINGS)

    def __post_init__(self):
        self.sizes = [(int(a), int(b)) for a, b in self.sizes]
        bad = [m for m in self.methods if m not in METHODS and not _at_value(m)]
        if bad or "std" not in self.methods:
            raise ValueError(f"methods must contain 'std' and be among {METHODS}, 'B@<rtol>', 'l2@<eps>' or "
                             f"'l2n@<eps>' (a positive number); got {self.methods}")
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

    ``errors[(k_M, k_N)][stage][method]`` is a list (one entry per pair) of ``(m,)`` arrays of
    per-column relative errors; ``cols[family]`` the column slice of each family.
    """

    settings: ProtocolSettings
    pairs: list
    errors: dict
    cols: dict
    map_deviation: dict
    ranks: dict
    gain_rtol: dict
    seconds: list


def _at_value(method) -> float | None:
    """The number of a ``"B@<rtol>"`` / ``"l2@<eps>"`` / ``"l2n@<eps>"`` method (a positive float), else None."""
    m = str(method)
    if not m.startswith(_AT_METHODS):
        return None
    try:
        v = float(m.partition("@")[2])
    except ValueError:
        return None
    return v if np.isfinite(v) and v > 0 else None


def _operator(ext1, method: str, s: ProtocolSettings, rtol: float | None = None):
    norm = {} if s.normalization is None else {"normalization": s.normalization}
    if method == "l2" or method.startswith("l2@"):
        return ext1.operator("ridge", eps=s.eps_ridge if method == "l2" else _at_value(method), **norm)
    if method.startswith("l2n@"):  # Equation 4 as printed: norms, not squared (ε relative to σ_max)
        return ext1.operator("ridge", eps=_at_value(method), penalty="norm", **norm)
    if method == "l1":
        return ext1.operator("lasso", eps=s.eps_lasso, max_iter=s.lasso_max_iter, **norm)
    if rtol is None:  # "B", "B@<rtol>"; "B_gain" passes the gain rule's
        rtol = s.rtol if method == "B" else _at_value(method)
    return ext1.operator("svd", rtol=rtol, **norm)


def run_protocol(store: ShapeStore, pairs, settings: ProtocolSettings, *, collect=None,
                 progress: bool = True, workers: int | None = None) -> ProtocolResult:
    """Run the protocol on ``pairs`` (list of ``(source id, target id)``) of ``store.dataset``.

    ``collect(pair_index, size, F, G, cols, b1, b2, outputs)`` (optional) receives, for every
    pair and size, the functions and ``outputs[method] = (approximation (n1, m), transfer (n2, m))``
    (e.g. for the area curves of Figure 8); it runs in this process, so the pairs are then
    computed here one after the other. A collector that splits its work into
    ``measure(pair_index, size, F, G, cols, b1, b2, outputs) -> record`` (pure, picklable, run
    with the pair, in a worker) and ``add(pair_index, size, record)`` (run here, in the pairs'
    order), as :class:`AreaCurves`, keeps the workers.

    ``workers``: processes computing the pairs (:func:`prodmaps.experiments.parallel.map_tasks`;
    default ``$PRODMAPS_WORKERS`` or the CPUs). The pairs of one source shape go to one worker
    (they share its descriptors and extended-basis operators); every pair is computed with one
    BLAS thread, so the errors are the same for any number of workers.
    """
    s = settings
    pairs = [tuple(p) for p in pairs]
    errors = {z: {st: {m: [] for m in s.methods} for st in STAGES} for z in s.sizes}
    map_dev, ranks, gain_rtol = ({z: [] for z in s.sizes} for _ in range(3))
    cols, seconds = None, []
    split = _measures(collect)
    workers = 1 if collect is not None and not split else workers
    for ip, rec in map_by_source(_protocol_pair, store, pairs, s, collect, workers=workers):
        cols = rec["cols"]
        for z, by in rec["sizes"].items():
            if split:
                collect.add(ip, z, by.pop("collected"))
            map_dev[z].append(by["map_dev"])
            for key, acc in (("rank", ranks), ("gain_rtol", gain_rtol)):
                if by[key] is not None:
                    acc[z].append(by[key])
            for st in STAGES:
                for m in s.methods:
                    errors[z][st][m].append(by["errors"][st][m])
        seconds.append(rec["seconds"])
        if progress:
            sid1, sid2 = pairs[ip]
            print(f"pair {ip + 1:2d}/{len(pairs)} {sid1} -> {sid2}: {seconds[-1]:5.1f} s"
                  + "".join(f"  [{kM}/{kN}] map dev {map_dev[(kM, kN)][-1]:.3f}" for kM, kN in s.sizes),
                  flush=True)
    return ProtocolResult(s, pairs, errors, cols, map_dev, ranks, gain_rtol, seconds)


def _measures(collect) -> bool:
    """Whether ``collect`` splits its work into ``measure`` (with the pair) and ``add`` (here)."""
    return collect is not None and callable(getattr(collect, "measure", None))


def _protocol_pair(store: ShapeStore, ip: int, sid1: str, sid2: str, s: ProtocolSettings, collect) -> dict:
    """One pair at every size: ``{"cols", "seconds", "sizes": {(k_M, k_N): {...}}}``.

    Each size holds ``"errors"``, ``"map_dev"``, ``"rank"``, ``"gain_rtol"``, with
    ``errors[stage][method]`` the ``(m,)`` per-column errors.
    """
    from .. import datasets

    t0 = time.perf_counter()
    prod_methods = [m for m in s.methods if m != "std"]
    gt = datasets.ground_truth(store.dataset, sid1, sid2)  # (n2,) target vertex -> source vertex
    F, G, cols = store.family_functions(sid1, gt, ip, s.families, k_M=s.k_M_family, seed=s.seed,
                                          reading_set=s.family_reading)
    sizes = {}
    for (kM, kN) in s.sizes:
        rec = {"errors": {st: {} for st in STAGES}, "rank": None, "gain_rtol": None}
        b1, b2 = store.basis(sid1, kM + 1), store.basis(sid2, kN + 1)
        C_gt = fmap_from_p2p(gt, b1, b2)  # (kN+1, kM+1)
        if s.map_kind == "gt":
            C = C_gt
        elif s.map_kind == "perturbed":
            C = perturbed_map(C_gt, s.noise, seed=(s.seed, ip, kM, kN))
        else:
            C = no17_demo_map(store, sid1, sid2, gt, kM + 1, kN + 1, k_descr=s.no17_k_descr)
        rec["map_dev"] = float(np.linalg.norm(C - C_gt) / np.linalg.norm(C_gt))
        a_std = b1.project(F)  # (kM+1, m)
        outputs = {"std": (b1.vecs @ a_std, b2.vecs @ (C @ a_std))}
        if "p2p" in prod_methods:
            from ..p2p import from_fmap

            outputs["p2p"] = (outputs["std"][0], F[from_fmap(C, b1, b2, "std")])  # (n2, m) pulled back
        if [m for m in prod_methods if m != "p2p"]:
            ext1 = product_basis(b1, order=2, pairs=s.pairs_convention)
            ext2 = product_basis(b2, order=2, pairs=s.pairs_convention)
            Ct = extend_fmap(C, b1, b2, order=2, pairs=s.pairs_convention)  # (K2, K1)
            coefs = {}  # method -> (K1, m): evaluated together below, one pass over each extended basis
            for m in prod_methods:
                if m == "p2p":
                    continue
                if m == "default":
                    op = transfer_operator(C, b1, b2, "default")
                    outputs[m] = (op.approximate(F), op(F))
                    continue
                if m == "B_gain":
                    rec["gain_rtol"] = truncation.select_rtol(b1, method="gain", C_12=C, basis_2=b2,
                                                              max_gain=s.max_gain, normalization=s.normalization)
                rtol = rec["gain_rtol"] if m == "B_gain" else None
                coefs[m] = _operator(ext1, m, s, rtol).coefficients(F)  # (K1, m)
                outputs[m] = None  # keeps the methods' order
            if coefs:
                a = np.concatenate(list(coefs.values()), axis=1)  # (K1, m·methods)
                fa, ft = ext1.evaluate(a), ext2.evaluate(Ct @ a)  # (n1, ·), (n2, ·)
                for j, m in enumerate(coefs):
                    sl = slice(j * F.shape[1], (j + 1) * F.shape[1])
                    outputs[m] = (fa[:, sl], ft[:, sl])
            if "B" in prod_methods:
                rec["rank"] = int(_operator(ext1, "B", s).rank)
        for m, (fa, ft) in outputs.items():
            rec["errors"]["approx"][m] = relative_error(fa, F, b1.mass)
            rec["errors"]["transfer"][m] = relative_error(ft, G, b2.mass)
        if _measures(collect):
            rec["collected"] = collect.measure(ip, (kM, kN), F, G, cols, b1, b2, outputs)
        elif collect is not None:
            collect(ip, (kM, kN), F, G, cols, b1, b2, outputs)
        sizes[(kM, kN)] = rec
    return {"cols": cols, "seconds": time.perf_counter() - t0, "sizes": sizes}


def perturbed_map(C_gt: np.ndarray, noise: float, seed) -> np.ndarray:
    """``C_gt`` plus seeded Gaussian noise of relative Frobenius norm ``noise`` on the free columns.

    Column 0 (the constant's image, fixed for any point map) is kept; ``seed`` may be a tuple.
    """
    rng = np.random.default_rng(np.random.SeedSequence(np.atleast_1d(seed).tolist()))
    E = rng.standard_normal(C_gt.shape)
    E[:, 0] = 0.0
    return C_gt + noise * np.linalg.norm(C_gt) / np.linalg.norm(E) * E


def method_label(method: str, table: str | None = None) -> str:
    """Column name of a method in the paper's tables (``our_l2`` is ``our_A`` after Table 1).

    ``"B@<r>"`` is ``our_B_rtol<r>``; ``"l2@<e>"`` is ``our_l2_eps<e>`` (``our_A_eps<e>`` after Table 1),
    ``"l2n@<e>"`` ``our_l2_norm_eps<e>`` (``our_A_norm_eps<e>`` after Table 1).
    """
    if method.startswith("B@"):
        return f"our_B_rtol{method[2:]}"
    if method.startswith("l2@"):
        return f"{method_label('l2', table)}_eps{method[3:]}"
    if method.startswith("l2n@"):
        return f"{method_label('l2', table)}_norm_eps{method[4:]}"
    names = {"std": "std", "l1": "our_l1", "l2": "our_l2" if table in (None, "T1") else "our_A",
             "B": "our_B", "B_gain": "our_B_gainrule", "default": "our_default", "p2p": "p2p_transfer"}
    return names[method]


def family_means(result: ProtocolResult, table: str | None = None, pairs_mask=None) -> dict:
    """``{(k_M, k_N, stage, method label, paper family label): (mean over pairs, std over pairs)}``.

    The std is the population one (``ddof=0``); over ``n`` pairs the mean's :func:`standard_error`
    is ``std / sqrt(n - 1)``. Each pair contributes the mean over the family's columns;
    ``pairs_mask`` (boolean, one entry per pair) restricts the average to some pairs (e.g. the intra-subject ones).
    """
    out = {}
    for z, by_stage in result.errors.items():
        for st, by_method in by_stage.items():
            for m, per_pair in by_method.items():
                E = np.array(per_pair)  # (pairs, m_functions)
                if pairs_mask is not None:
                    E = E[np.asarray(pairs_mask, dtype=bool)]
                for fam in result.settings.families:
                    per = E[:, result.cols[fam]].mean(axis=1)  # (pairs,)
                    label = pfam.entry_label(fam, result.settings.family_reading)
                    out[(z[0], z[1], st, method_label(m, table), label)] = (float(per.mean()), float(per.std()))
    return out


def standard_error(values) -> float | None:
    """Standard error of the mean of ``values`` ``(n,)``: ``std(ddof=1) / sqrt(n)``; None when ``n < 2``.

    >>> round(standard_error([0.1, 0.3]), 12)
    0.1
    """
    v = np.asarray(values, dtype=np.float64).ravel()
    if v.size < 2:
        return None
    return float(v.std(ddof=1) / np.sqrt(v.size))


AREA_CRITERIA = ("paper", "scale_free")


def area_curves(f: np.ndarray, g: np.ndarray, mass: np.ndarray, gamma: np.ndarray) -> dict:
    """Figure 8's area fractions ``(len(gamma), m)`` under both criteria.

    ``"paper"``: area where ``(f-g)² < γ·sqrt(∫g²)`` (:func:`prodmaps.area_fraction_curve`);
    ``"scale_free"``: area where ``(f-g)² < γ·∫g²/area`` (squared error relative to the mean square
    of ``g``; the paper's criterion depends on the units of ``f`` and of the shape).
    """
    from ..metrics import area_fraction_curve

    paper = area_fraction_curve(f, g, mass, gamma)
    ms = np.einsum("i,ij->j", mass, g**2) / mass.sum()  # mean square of g, (m,)
    e = (f - g) ** 2 / ms[None, :]  # scale-free pointwise error
    sf = np.einsum("i,tij->tj", mass, (e[None] < gamma[:, None, None]).astype(float)) / mass.sum()
    return {"paper": paper, "scale_free": sf}


class AreaCurves:
    """Figure 8's accumulator: pass it as ``collect=`` to :func:`run_protocol`.

    For every pair it stores, per criterion, stage (approximation on the source, transfer to the
    target), method and family, the area-fraction curve averaged over the family's functions;
    :meth:`mean` averages over pairs and :meth:`auc` integrates over ``gamma`` (trapezoid).
    """

    def __init__(self, gamma, families, methods):
        self.gamma = np.asarray(gamma, float)  # (n_gamma,)
        self.families, self.methods = list(families), list(methods)
        self._curves = {c: {st: {m: [] for m in self.methods} for st in STAGES} for c in AREA_CRITERIA}

    def measure(self, ip, size, F, G, cols, b1, b2, outputs) -> dict:
        """One pair and size: ``{(criterion, stage, method): {family: (n_gamma,) curve}}`` (pure)."""
        out = {}
        for m, (fa, ft) in outputs.items():
            for st, f, g, mass in (("approx", fa, F, b1.mass), ("transfer", ft, G, b2.mass)):
                cv = area_curves(f, g, mass, self.gamma)
                for c in AREA_CRITERIA:
                    out[(c, st, m)] = {fam: cv[c][:, cols[fam]].mean(axis=1) for fam in self.families}
        return out

    def add(self, ip, size, record: dict) -> None:
        """Keep :meth:`measure`'s record (pairs in order)."""
        for (c, st, m), by_family in record.items():
            self._curves[c][st][m].append(by_family)

    def __call__(self, ip, size, F, G, cols, b1, b2, outputs):
        """Measure one pair and size and keep the record (:meth:`measure` then :meth:`add`)."""
        self.add(ip, size, self.measure(ip, size, F, G, cols, b1, b2, outputs))

    def __getstate__(self):  # a worker gets the settings; the curves stay with the caller
        return {"gamma": self.gamma, "families": self.families, "methods": self.methods}

    def __setstate__(self, state):
        self.__init__(state["gamma"], state["families"], state["methods"])

    def mean(self) -> dict:
        """``{criterion: {stage: {method: {family: (n_gamma,) curve}}}}`` averaged over pairs."""
        return {c: {st: {m: {f: np.mean([d[f] for d in per_pair], axis=0) for f in self.families}
                         for m, per_pair in by_m.items()} for st, by_m in by_st.items()}
                for c, by_st in self._curves.items()}

    def auc(self) -> dict:
        """Area under each mean curve over ``gamma``, same nesting as :meth:`mean`."""
        def integrate(by_f):
            return {f: float(np.trapezoid(v, self.gamma)) for f, v in by_f.items()}

        return {c: {st: {m: integrate(by_f) for m, by_f in by_m.items()} for st, by_m in by_st.items()}
                for c, by_st in self.mean().items()}
